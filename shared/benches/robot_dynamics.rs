//! Host timings of the PUMA 560 model: RNEA, CRBA mass matrix, Jacobian + `Jdot qd`, forward
//! dynamics, in f64 (simulator plant) and f32 (controller). Goal: f64 RNEA under 0.5 us.
//!
//! `cargo bench -p shared --bench robot_dynamics -- --warm-up-time 1 --measurement-time 3`
//!
//! On a shared, loaded machine the wall-clock means are inflated by preemption; the fastest
//! sample in `target/criterion/<name>/new/sample.json` (time / iters) is the uncontended figure.
//! A load-independent count: `valgrind --tool=callgrind <bench binary> --bench --profile-time 1
//! '^rnea_f64$'`, then inclusive instructions of `inverse_dynamics_with` per call.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::RealField;
use shared::robot::{DriveOptions, JointTrig, JointVector, Puma560};

fn state<T: RealField + Copy>() -> (JointVector<T>, JointVector<T>, JointVector<T>) {
    let convert = |values: [f64; 6]| JointVector::from(values.map(nalgebra::convert::<f64, T>));
    (
        convert([0.3, 0.9, -1.4, 0.5, -0.7, 1.1]),
        convert([0.4, -0.6, 0.8, 1.2, -0.9, 0.7]),
        convert([1.5, -0.8, 2.0, -1.1, 0.6, -1.7]),
    )
}

fn bench_scalar<T: RealField + Copy>(c: &mut Criterion, name: &str) {
    let rigid = Puma560::<f64>::new().cast::<T>();
    let plant = rigid.with_drive(DriveOptions {
        armature: true,
        friction: true,
    });
    let (q, qd, qdd) = state::<T>();
    c.bench_function(&format!("joint_trig_{name}"), |b| {
        b.iter(|| JointTrig::new(black_box(&q)))
    });
    c.bench_function(&format!("rnea_{name}"), |b| {
        b.iter(|| rigid.inverse_dynamics(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    c.bench_function(&format!("rnea_drive_{name}"), |b| {
        b.iter(|| plant.inverse_dynamics(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    c.bench_function(&format!("mass_matrix_{name}"), |b| {
        b.iter(|| rigid.mass_matrix(black_box(&q)))
    });
    c.bench_function(&format!("jacobian_and_bias_{name}"), |b| {
        b.iter(|| rigid.jacobian_and_bias(black_box(&q), black_box(&qd)))
    });
    c.bench_function(&format!("forward_kinematics_{name}"), |b| {
        b.iter(|| rigid.forward_kinematics(black_box(&q)))
    });
    c.bench_function(&format!("forward_dynamics_{name}"), |b| {
        b.iter(|| plant.forward_dynamics(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
}

fn robot_dynamics(c: &mut Criterion) {
    bench_scalar::<f64>(c, "f64");
    bench_scalar::<f32>(c, "f32");
}

criterion_group!(benches, robot_dynamics);
criterion_main!(benches);
