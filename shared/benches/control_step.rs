//! Criterion benches of one task-space computed-torque step (Eq 23: errors,
//! damped Jacobian solve, one RNEA pass) in f32 and f64, and of its parts.
//!
//! `cargo bench -p shared --bench control_step`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{RealField, UnitQuaternion, Vector3};
use shared::control::{
    solve_damped, AxisGains, CircleTrajectory, ControllerConfig, DampingConfig, Joints, TaskGains,
    TaskReference, TaskSpaceController, TaskSpaceModel,
};
use shared::planning::{solve_ik, IkConfig};
use shared::robot::drive::SIMULATOR_COULOMB_WIDTH;
use shared::robot::{DriveOptions, Puma560};

/// Converged to round-off, so the benches start exactly on the reference.
fn tight_ik<T: RealField + Copy>() -> IkConfig<T> {
    IkConfig {
        position_tolerance_m: nalgebra::convert(1e-12),
        orientation_tolerance_rad: nalgebra::convert(1e-12),
        ..IkConfig::default()
    }
}

fn config<T: RealField + Copy>() -> ControllerConfig<T> {
    let gains = AxisGains::from_poles(nalgebra::convert(40.0), T::one(), nalgebra::convert(10.0))
        .expect("valid gains");
    ControllerConfig {
        gains: TaskGains {
            position: gains,
            orientation: gains,
        },
        position_integral_limit: nalgebra::convert(0.005),
        orientation_integral_limit: nalgebra::convert(0.02),
        damping: DampingConfig {
            manipulability_threshold: nalgebra::convert(0.01),
            max_damping: nalgebra::convert(0.05),
        },
    }
}

/// A state on the task circle with a small tracking error.
fn state() -> (Puma560<f64>, Joints<f64>, Joints<f64>, TaskReference<f64>) {
    let model = Puma560::<f64>::new()
        .with_drive(DriveOptions {
            armature: true,
            friction: true,
        })
        .try_with_coulomb_smoothing(SIMULATOR_COULOMB_WIDTH)
        .expect("positive width");
    let circle = CircleTrajectory {
        centre: Vector3::new(0.5, 0.0, 0.4),
        radius: 0.3,
        angular_rate: 1.0,
        orientation: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f64::consts::PI),
    };
    let reference = circle.reference(0.3);
    let q = solve_ik(
        &model,
        &reference.base_from_flange,
        &Joints::new(0.2, 0.0, -2.1, 0.0, -1.0, -2.9),
        &tight_ik(),
    )
    .expect("reachable");
    let q = q + Joints::repeat(1e-3);
    let qd = Joints::new(0.3, -0.2, 0.4, 0.01, -0.3, 0.2);
    (model, q, qd, reference)
}

fn bench_step(c: &mut Criterion) {
    let (model64, q64, qd64, reference64) = state();
    let model32 = model64.cast::<f32>();
    let (q32, qd32) = (q64.cast::<f32>(), qd64.cast::<f32>());
    let reference32 = TaskReference {
        base_from_flange: reference64.base_from_flange.cast::<f32>(),
        twist: reference64.twist.cast::<f32>(),
        acceleration: reference64.acceleration.cast::<f32>(),
    };
    let mut c32 = TaskSpaceController::new(config::<f32>()).expect("config");
    let mut c64 = TaskSpaceController::new(config::<f64>()).expect("config");
    c.bench_function("control_step_f32", |b| {
        b.iter(|| {
            c32.step(
                &model32,
                black_box(&q32),
                black_box(&qd32),
                black_box(&reference32),
                1e-3,
            )
        })
    });
    c.bench_function("control_step_f64", |b| {
        b.iter(|| {
            c64.step(
                &model64,
                black_box(&q64),
                black_box(&qd64),
                black_box(&reference64),
                1e-3,
            )
        })
    });

    let trig = model32.configuration(&q32);
    c.bench_function("part_f32_trig", |b| {
        b.iter(|| model32.configuration(black_box(&q32)))
    });
    c.bench_function("part_f32_task_kinematics", |b| {
        b.iter(|| model32.task_kinematics(black_box(&trig), black_box(&qd32)))
    });
    let kin = model32.task_kinematics(&trig, &qd32);
    let rhs = kin.jacobian_dot_qd;
    c.bench_function("part_f32_damped_solve", |b| {
        b.iter(|| {
            solve_damped(
                black_box(&kin.jacobian),
                black_box(&rhs),
                &config::<f32>().damping,
            )
        })
    });
    c.bench_function("part_f32_rnea", |b| {
        b.iter(|| {
            TaskSpaceModel::inverse_dynamics(
                &model32,
                black_box(&trig),
                black_box(&qd32),
                black_box(&qd32),
            )
        })
    });
}

criterion_group!(benches, bench_step);
criterion_main!(benches);
