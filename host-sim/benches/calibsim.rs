//! Speed of the host-side pieces per log of the paper scenario (300 frames):
//! recording a synthetic log, writing and reading it as JSON Lines, and the full
//! calibration (refined + paper estimates) that one Monte-Carlo trial runs.

use std::hint::black_box;
use std::io::Cursor;

use criterion::{criterion_group, criterion_main, Criterion};
use host_sim::calibration::calibrate_log;
use host_sim::log::{read_log, write_log};
use host_sim::recording::simulate;
use host_sim::scenario::Scenario;
use shared::calibration::CalibrationConfig;

fn benches(c: &mut Criterion) {
    let scenario = Scenario::paper();
    let run = simulate(&scenario, 1).expect("workcell");
    let bytes = write_log(Vec::new(), &run.log).expect("write");

    c.bench_function("simulate paper log (300 frames)", |b| {
        b.iter(|| simulate(black_box(&scenario), black_box(1)))
    });
    c.bench_function("write paper log as JSON Lines", |b| {
        b.iter(|| write_log(Vec::with_capacity(bytes.len()), black_box(&run.log)))
    });
    c.bench_function("read paper log from JSON Lines", |b| {
        b.iter(|| read_log(Cursor::new(black_box(&bytes))))
    });
    c.bench_function("calibrate paper log (refined + paper estimate)", |b| {
        b.iter(|| calibrate_log(black_box(&run.log), CalibrationConfig::default()))
    });
}

criterion_group!(calibsim, benches);
criterion_main!(calibsim);
