//! Speed of the self-calibration on the paper's setting (300 frames over one revolution,
//! 0.5 px noise, 5 % dropouts, 10 effector sightings): absorbing the frames (validation,
//! RLS conic update, thinning store), the refined estimate, and the paper's method.
//! Run: `cargo bench -p shared --bench calibration`.

#[path = "../tests/calibration_support/mod.rs"]
mod calibration_support;

use std::hint::black_box;

use calibration_support::{Rng, Scenario, Workcell};
use criterion::{criterion_group, criterion_main, Criterion};
use shared::calibration::{CalibrationConfig, FirmwareCalibrator, HostCalibrator};

fn paper_run() -> (Workcell, Vec<shared::observation::ObservationFrame>) {
    let mut rng = Rng::new(1234);
    let workcell = Workcell::random(&mut rng, 3, false);
    let frames = workcell.record(&mut rng, &Scenario::paper());
    (workcell, frames)
}

fn calibration(c: &mut Criterion) {
    let (workcell, frames) = paper_run();
    let header = workcell.header();
    let config = CalibrationConfig::default();
    c.bench_function("push 300 frames (HostCalibrator)", |b| {
        b.iter(|| {
            let mut calibrator = HostCalibrator::new(&header, config).unwrap();
            for frame in &frames {
                calibrator.push(black_box(frame)).unwrap();
            }
            calibrator
        })
    });
    let mut host = HostCalibrator::new(&header, config).unwrap();
    frames.iter().for_each(|frame| host.push(frame).unwrap());
    c.bench_function("estimate, 300 frames (HostCalibrator)", |b| {
        b.iter(|| host.estimate().unwrap())
    });
    c.bench_function("paper_estimate, 300 frames (HostCalibrator)", |b| {
        b.iter(|| host.paper_estimate().unwrap())
    });
    let mut firmware = FirmwareCalibrator::new(&header, config).unwrap();
    frames
        .iter()
        .for_each(|frame| firmware.push(frame).unwrap());
    c.bench_function(
        "estimate, 300 frames thinned to 96 (FirmwareCalibrator)",
        |b| b.iter(|| firmware.estimate().unwrap()),
    );
}

criterion_group!(benches, calibration);
criterion_main!(benches);
