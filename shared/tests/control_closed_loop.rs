//! Closed-loop tests of the task-space computed-torque controller (Eq 23):
//! f32 controller on a mismatched f64 plant integrated by RK4 at 1 kHz.

mod control_support;

use control_support::*;
use nalgebra::Vector6;
use shared::control::{
    ControlError, ControlInput, DampingConfig, Joints, TaskReference, TaskSpaceController,
    TaskSpaceModel,
};
use shared::robot::Puma560;

/// Two turns of the circle (4 pi s); errors counted after 1.5 s.
const DURATION_S: f64 = 4.0 * core::f64::consts::PI;
const SETTLE_S: f64 = 1.5;

/// Goal is 2 mm; a correct implementation measures about 0.8 mm max, 0.2 mm RMS,
/// and at most about 2.5 mrad of orientation error.
#[test]
fn circle_tracking_with_integral_action_stays_below_goal() {
    let mut rng = SplitMix(0x00C0_1720);
    for seed in [1_u64, 2, 3] {
        let friction_scale = rng.uniform(0.7, 1.3);
        let stats = track_circle(seed, friction_scale, true, false, DURATION_S, SETTLE_S);
        println!("seed {seed}, friction known x{friction_scale:.3}: PID {stats:?}");
        assert_eq!(stats.fallback_steps, 0);
        assert!(stats.max_abs_tau.is_finite());
        assert!(
            stats.max_error_m < 1.3e-3,
            "max error {} m",
            stats.max_error_m
        );
        assert!(
            stats.rms_error_m < 0.5e-3,
            "rms error {} m",
            stats.rms_error_m
        );
        assert!(
            stats.max_orientation_error_rad < 5e-3,
            "orientation error {} rad",
            stats.max_orientation_error_rad
        );
    }
}

/// The paper's pure PD loop leaves a mismatch-driven error that integral action removes.
#[test]
fn pd_only_leaves_a_larger_error_than_pid() {
    for (seed, friction_scale) in [(4_u64, 0.7), (5, 1.3)] {
        let pd = track_circle(seed, friction_scale, false, false, DURATION_S, SETTLE_S);
        let pid = track_circle(seed, friction_scale, true, false, DURATION_S, SETTLE_S);
        println!(
            "seed {seed} friction x{friction_scale}: PD max {:.3} mm rms {:.3} mm | PID max {:.3} mm rms {:.3} mm",
            pd.max_error_m * 1e3,
            pd.rms_error_m * 1e3,
            pid.max_error_m * 1e3,
            pid.rms_error_m * 1e3
        );
        assert!(pd.rms_error_m > 3.0 * pid.rms_error_m);
        assert!(pd.max_error_m > 1.5 * pid.max_error_m);
    }
}

/// Joint-space path that takes the wrist through q5 = 0 while q4 and q6 move:
/// at the crossing the reference asks for a rotation the arm cannot produce
/// instantaneously. Torques and accelerations must stay finite and bounded,
/// and the error must recover afterwards.
#[test]
fn wrist_singularity_crossing_stays_bounded() {
    let plant = Puma560::<f64>::new().with_drive(BOTH_DRIVE_TERMS);
    let model = controller_model(1.0);
    let q_a = Joints::new(0.1, 0.3, -2.2, -0.4, 0.5, -0.3);
    let q_b = Joints::new(0.3, 0.2, -2.4, 0.6, -0.5, 0.7);
    let period = 3.0;
    // smooth 0 -> 1 -> 0 blend: s = (1 - cos(2 pi t / T)) / 2
    let joint_reference = |t: f64| {
        let w = 2.0 * core::f64::consts::PI / period;
        let (s, sd, sdd) = (
            (1.0 - (w * t).cos()) / 2.0,
            w * (w * t).sin() / 2.0,
            w * w * (w * t).cos() / 2.0,
        );
        let delta = q_b - q_a;
        (q_a + delta * s, delta * sd, delta * sdd)
    };
    let task_reference = |t: f64| {
        let (q, qd, qdd) = joint_reference(t);
        let jacobian = plant.jacobian(&q);
        TaskReference {
            base_from_flange: plant.forward_kinematics(&q),
            twist: jacobian * qd,
            acceleration: jacobian * qdd + plant.jacobian_dot_qd(&q, &qd),
        }
    };
    let mut controller = TaskSpaceController::new(controller_config(true)).unwrap();
    let (mut max_qdd, mut max_damping, mut min_abs_q5) = (0.0_f64, 0.0_f64, f64::MAX);
    let mut final_error = 0.0;
    let limits = plant.joint_limits().torque_max;
    run_closed_loop(
        &plant,
        &model,
        &mut controller,
        task_reference,
        (q_a, Joints::zeros()),
        Timing {
            dt: 1e-3,
            duration: period,
        },
        |s| {
            assert!(s.output.fallback.is_none(), "fallback at t={}", s.t);
            assert!(s.output.tau.iter().all(|x| x.is_finite()));
            assert!(s.output.qdd.iter().all(|x| x.is_finite()));
            for (tau, limit) in s.output.tau.iter().zip(limits.iter()) {
                assert!(f64::from(tau.abs()) <= limit + 1e-3);
            }
            max_qdd = max_qdd.max(f64::from(s.output.qdd.amax()));
            max_damping = max_damping.max(f64::from(s.output.damping_squared));
            min_abs_q5 = min_abs_q5.min(s.q[4].abs());
            final_error = s.position_error;
        },
    );
    println!(
        "min |q5| {min_abs_q5:.2e} rad, max lambda^2 {max_damping:.2e}, max |qdd| {max_qdd:.1} rad/s^2, final error {:.3} mm",
        final_error * 1e3
    );
    assert!(min_abs_q5 < 0.01, "the path must really cross q5 = 0");
    assert!(max_damping > 0.0, "damping must have been active");
    assert!(max_qdd < 100.0);
    assert!(final_error < 1e-3);
}

/// Evaluated exactly at q5 = 0 with a large orientation error along the lost
/// direction: the damped solve stays bounded; the undamped one falls back to the hold.
#[test]
fn exact_singularity_is_bounded_or_held() {
    let model = controller_model(1.0);
    let q = Joints::new(0.2_f32, 0.3, -2.3, 0.7, 0.0, -0.4);
    let qd = Joints::zeros();
    let pose = model.forward_kinematics(&q);
    let twist_bad = Vector6::new(0.0_f32, 0.0, 0.0, 0.0, 0.0, 0.0);
    let kin = model.task_kinematics(&model.configuration(&q), &qd);
    // ask for a rotation about the axis orthogonal to z4 and z5/z6: the singular direction
    let z = kin.jacobian.fixed_view::<3, 1>(3, 3).into_owned();
    let x = kin.jacobian.fixed_view::<3, 1>(3, 4).into_owned();
    let lost = z.cross(&x).normalize();
    let target = nalgebra::UnitQuaternion::from_scaled_axis(lost * 0.2) * pose.rotation;
    let reference = TaskReference {
        base_from_flange: nalgebra::Isometry3::from_parts(pose.translation, target),
        twist: twist_bad,
        acceleration: Vector6::zeros(),
    };
    let mut damped = TaskSpaceController::new(controller_config(false)).unwrap();
    let out = damped.step(&model, &q, &qd, &reference, 1e-3);
    assert!(out.fallback.is_none());
    assert!(out.damping_squared > 0.0);
    assert!(out.qdd.iter().all(|v| v.is_finite()) && out.qdd.amax() < 1e3);
    assert!(out.tau.iter().all(|v| v.is_finite()));

    let mut config = controller_config(false);
    config.damping = DampingConfig {
        manipulability_threshold: 0.0,
        max_damping: 0.0,
    };
    let mut undamped = TaskSpaceController::new(config).unwrap();
    let out = undamped.step(&model, &q, &qd, &reference, 1e-3);
    match out.fallback {
        // exact singularity: Cholesky rejects J J^T; rounding may instead give a huge qdd
        Some(ControlError::SolveFailed) => {
            let gravity = TaskSpaceModel::gravity_torque(&model, &q);
            assert!((out.tau - gravity).amax() < 1e-4);
        }
        Some(other) => panic!("unexpected fallback {other}"),
        None => assert!(out.tau.iter().all(|v| v.is_finite())),
    }
}

/// NaN inputs never produce NaN torques: the output is the gravity hold at the
/// last finite configuration and the error says which input was bad.
#[test]
fn nan_inputs_fall_back_to_gravity_hold() {
    let model = controller_model(1.0);
    let circle = task_circle();
    let reference = cast_reference(&circle.reference(0.0));
    let (q0, qd0) = start_on(&Puma560::<f64>::new(), &circle.reference(0.0));
    let (q, qd) = (q0.cast::<f32>(), qd0.cast::<f32>());
    let mut controller = TaskSpaceController::new(controller_config(true)).unwrap();
    let good = controller.step(&model, &q, &qd, &reference, 1e-3);
    assert!(good.fallback.is_none());
    let integral = *controller.error_integral();
    let gravity = TaskSpaceModel::gravity_torque(&model, &q);

    let mut q_nan = q;
    q_nan[2] = f32::NAN;
    let out = controller.step(&model, &q_nan, &qd, &reference, 1e-3);
    assert_eq!(
        out.fallback,
        Some(ControlError::NonFiniteInput(ControlInput::JointPosition))
    );
    assert!(
        (out.tau - gravity).amax() < 1e-5,
        "hold at the last finite q"
    );

    let mut qd_inf = qd;
    qd_inf[0] = f32::INFINITY;
    let out = controller.step(&model, &q, &qd_inf, &reference, 1e-3);
    assert_eq!(
        out.fallback,
        Some(ControlError::NonFiniteInput(ControlInput::JointVelocity))
    );
    assert!((out.tau - gravity).amax() < 1e-5);

    let mut bad_reference = reference;
    bad_reference.acceleration[4] = f32::NAN;
    let out = controller.step(&model, &q, &qd, &bad_reference, 1e-3);
    assert_eq!(
        out.fallback,
        Some(ControlError::NonFiniteInput(
            ControlInput::DesiredAcceleration
        ))
    );
    let out = controller.step(&model, &q, &qd, &reference, 0.0);
    assert_eq!(out.fallback, Some(ControlError::NonPositivePeriod));
    assert!(out.tau.iter().all(|v| v.is_finite()));
    assert_eq!(
        *controller.error_integral(),
        integral,
        "state untouched by bad steps"
    );

    // a fresh controller that never saw a finite q holds with zero torque
    let mut fresh = TaskSpaceController::new(controller_config(true)).unwrap();
    let out = fresh.step(&model, &q_nan, &qd, &reference, 1e-3);
    assert_eq!(out.tau, Joints::zeros());
}

/// A far-away target saturates the torques; the integrator must not wind up.
#[test]
fn saturation_clips_torques_and_freezes_the_integral() {
    let model = controller_model(1.0);
    let circle = task_circle();
    let (q0, qd0) = start_on(&Puma560::<f64>::new(), &circle.reference(0.0));
    let (q, qd) = (q0.cast::<f32>(), qd0.cast::<f32>());
    let mut far = cast_reference(&circle.reference(0.0));
    far.base_from_flange.translation.vector.z -= 0.3;
    let mut controller = TaskSpaceController::new(controller_config(true)).unwrap();
    let limits = TaskSpaceModel::torque_limits(&model);
    for _ in 0..50 {
        let out = controller.step(&model, &q, &qd, &far, 1e-3);
        assert!(out.saturated);
        for (tau, limit) in out.tau.iter().zip(limits.iter()) {
            assert!(tau.abs() <= *limit);
        }
        assert!(out
            .tau
            .iter()
            .zip(limits.iter())
            .any(|(t, l)| t.abs() == *l));
    }
    assert_eq!(*controller.error_integral(), Vector6::zeros());
}

/// The f32 controller computes the same torques as an f64 one to well within
/// the friction and mass uncertainty (relative 1e-3 of the torque scale).
#[test]
fn f32_step_agrees_with_f64_step() {
    let model64 = Puma560::<f64>::new().with_drive(BOTH_DRIVE_TERMS);
    let model32 = model64.cast::<f32>();
    let circle = task_circle();
    let config64 = shared::control::ControllerConfig {
        gains: shared::control::TaskGains {
            position: shared::control::AxisGains::from_poles(40.0, 1.0, 10.0).unwrap(),
            orientation: shared::control::AxisGains::from_poles(40.0, 1.0, 10.0).unwrap(),
        },
        position_integral_limit: 0.005,
        orientation_integral_limit: 0.02,
        damping: DampingConfig {
            manipulability_threshold: 0.01,
            max_damping: 0.05,
        },
    };
    let mut rng = SplitMix(99);
    let (q_start, _) = start_on(&model64, &circle.reference(0.0));
    let (mut worst, mut compared) = (0.0_f64, 0);
    for _ in 0..300 {
        let q = q_start + Joints::from_fn(|_, _| rng.uniform(-0.3, 0.3));
        let qd = Joints::from_fn(|_, _| rng.uniform(-0.5, 0.5));
        // a reference a few mm / mrad away from the current pose, as in tracking
        let pose = model64.forward_kinematics(&q);
        let offset = nalgebra::Vector3::from_fn(|_, _| rng.uniform(-5e-3, 5e-3));
        let spin = nalgebra::Vector3::from_fn(|_, _| rng.uniform(-5e-3, 5e-3));
        let reference = TaskReference {
            base_from_flange: nalgebra::Isometry3::from_parts(
                (pose.translation.vector + offset).into(),
                nalgebra::UnitQuaternion::from_scaled_axis(spin) * pose.rotation,
            ),
            twist: model64.jacobian(&q) * qd + Vector6::from_fn(|_, _| rng.uniform(-0.01, 0.01)),
            acceleration: Vector6::from_fn(|_, _| rng.uniform(-1.0, 1.0)),
        };
        let mut c64 = TaskSpaceController::new(config64).unwrap();
        let mut c32 = TaskSpaceController::new(controller_config(true)).unwrap();
        let t64 = c64.step(&model64, &q, &qd, &reference, 1e-3);
        let t32 = c32.step(
            &model32,
            &q.cast(),
            &qd.cast(),
            &cast_reference(&reference),
            1e-3,
        );
        if t64.saturated || t32.saturated {
            continue;
        }
        compared += 1;
        let scale = 1.0 + t64.tau.amax();
        worst = worst.max((t64.tau - t32.tau.cast::<f64>()).amax() / scale);
    }
    println!("worst relative f32/f64 torque difference {worst:.2e} over {compared} states");
    assert!(compared >= 200);
    assert!(worst < 1e-3);
}

/// PUMA 560 singular configurations (this DH table): `det J ~ a2 (a3 s3 + d4 c3)(a2 c2 + a3 c23 - d4 s23) s5`
/// vanishes at the wrist (`s5 = 0`), elbow (arm stretched, `a3 s3 + d4 c3 = 0`) and
/// shoulder (wrist centre in the plane through `z0` normal to the arm) singularities. At each, a step asked to move
/// 5 cm and 0.1 rad in every task direction stays finite and bounded.
#[test]
fn wrist_elbow_and_shoulder_singularities_stay_bounded() {
    let (a2, a3, d4): (f64, f64, f64) = (0.4318, 0.0203, 0.4318);
    let elbow_q3 = (-d4).atan2(a3); // a3 s3 + d4 c3 = 0: forearm along the upper arm
                                    // shoulder: a2 c2 + a3 c23 - d4 s23 = 0 for q3 = -2.0, by bisection in q2
    let q3 = -2.0_f64;
    let shoulder = |q2: f64| a2 * q2.cos() + a3 * (q2 + q3).cos() - d4 * (q2 + q3).sin();
    let (mut lo, mut hi) = (0.0_f64, 3.0_f64);
    assert!(shoulder(lo) * shoulder(hi) < 0.0);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if shoulder(lo) * shoulder(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let cases = [
        ("wrist", Joints::new(0.2, 0.3, -2.3, 0.7, 0.0, -0.4)),
        ("elbow", Joints::new(0.2, 0.3, elbow_q3, 0.7, 0.8, -0.4)),
        ("shoulder", Joints::new(0.2, lo, q3, 0.7, 0.8, -0.4)),
    ];
    let plant = Puma560::<f64>::new().with_drive(BOTH_DRIVE_TERMS);
    let model = controller_model(1.0);
    let limits = plant.joint_limits().torque_max;
    for (name, q) in cases {
        let det = plant.jacobian(&q).determinant();
        assert!(det.abs() < 1e-9, "{name}: det J = {det}");
        let pose = plant.forward_kinematics(&q);
        let mut worst_qdd = 0.0_f32;
        for direction in 0..6 {
            let mut offset = Vector6::zeros();
            offset[direction] = if direction < 3 { 0.05 } else { 0.1 };
            let reference = TaskReference {
                base_from_flange: nalgebra::Isometry3::from_parts(
                    (pose.translation.vector + offset.fixed_rows::<3>(0)).into(),
                    nalgebra::UnitQuaternion::from_scaled_axis(
                        offset.fixed_rows::<3>(3).into_owned(),
                    ) * pose.rotation,
                ),
                twist: Vector6::zeros(),
                acceleration: Vector6::zeros(),
            };
            let mut controller = TaskSpaceController::new(controller_config(false)).unwrap();
            let out = controller.step(
                &model,
                &q.cast(),
                &Joints::zeros(),
                &cast_reference(&reference),
                1e-3,
            );
            assert!(out.fallback.is_none(), "{name}: {:?}", out.fallback);
            assert!(out.damping_squared > 0.0, "{name}: damping must be active");
            assert!(out.qdd.iter().all(|v| v.is_finite()));
            for (tau, limit) in out.tau.iter().zip(limits.iter()) {
                assert!(tau.is_finite() && f64::from(tau.abs()) <= limit + 1e-3);
            }
            // DLS bound |qdd| <= |a| / (2 lambda), with |a| = Kp |offset| here
            let bound = 1600.0 * 0.1 / (2.0 * out.damping_squared.sqrt());
            assert!(out.qdd.norm() <= bound * 1.01, "{name}: {}", out.qdd.norm());
            worst_qdd = worst_qdd.max(out.qdd.amax());
        }
        println!("{name} singularity (det J = {det:.1e}): max |qdd| {worst_qdd:.1} rad/s^2");
    }
}

#[test]
fn a_step_with_precomputed_kinematics_is_the_same_step() {
    // The pick computes the configuration and the flange kinematics once per
    // period and hands them to Eq 23: the result must not change by a bit.
    let model = controller_model(1.0);
    let circle = task_circle();
    let (q0, qd0) = start_on(&Puma560::<f64>::new(), &circle.reference(0.0));
    let (q, qd) = (q0.cast::<f32>(), qd0.cast::<f32>());
    let mut plain = TaskSpaceController::new(controller_config(true)).unwrap();
    let mut shared_work = plain.clone();
    for k in 0..50 {
        let reference = cast_reference(&circle.reference(k as f64 * 1e-3));
        let configuration = TaskSpaceModel::configuration(&model, &q);
        let kinematics = TaskSpaceModel::task_kinematics(&model, &configuration, &qd);
        let a = plain.step(&model, &q, &qd, &reference, 1e-3);
        let b = shared_work.step_with(
            &model,
            &q,
            &qd,
            &configuration,
            &kinematics,
            &reference,
            1e-3,
        );
        assert_eq!(a, b, "period {k}");
    }
}

/// A frozen integral keeps its value (and its torque) while the error stays;
/// released, it integrates again.
#[test]
fn a_frozen_integral_keeps_what_it_learnt() {
    let model = controller_model(1.0);
    let circle = task_circle();
    let mut reference = cast_reference(&circle.reference(0.0));
    let (q0, qd0) = start_on(&Puma560::<f64>::new(), &circle.reference(0.0));
    let (q, qd) = (q0.cast::<f32>(), qd0.cast::<f32>());
    // A reference 2 mm off the arm: a steady position error to integrate.
    reference.base_from_flange.translation.vector.x += 0.002;
    let mut controller = TaskSpaceController::new(controller_config(true)).unwrap();
    for _ in 0..100 {
        controller.step(&model, &q, &qd, &reference, 1e-3);
    }
    let learnt = *controller.error_integral();
    assert!(learnt.x.abs() > 1e-4, "{learnt:?}");
    controller.freeze_integral(true);
    let first = controller.step(&model, &q, &qd, &reference, 1e-3);
    for _ in 0..100 {
        let out = controller.step(&model, &q, &qd, &reference, 1e-3);
        assert_eq!(out.tau, first.tau);
    }
    assert_eq!(*controller.error_integral(), learnt);
    controller.freeze_integral(false);
    controller.step(&model, &q, &qd, &reference, 1e-3);
    assert!(controller.error_integral().x.abs() > learnt.x.abs());
}

/// The joint speeds a reference asks for (`ControlOutput::reference_joint_speed`,
/// the pick's speed guard) are the ones that produce its twist: `J qd_ref`
/// equals the reference twist away from singularities, and scale with it.
#[test]
fn the_reference_joint_speed_produces_the_reference_twist() {
    let model = controller_model(1.0);
    let circle = task_circle();
    let (q0, qd0) = start_on(&Puma560::<f64>::new(), &circle.reference(0.0));
    let (q, qd) = (q0.cast::<f32>(), qd0.cast::<f32>());
    let mut controller = TaskSpaceController::new(controller_config(true)).unwrap();
    let reference = cast_reference(&circle.reference(0.3));
    let output = controller.step(&model, &q, &qd, &reference, 1e-3);
    assert!(output.fallback.is_none());
    let configuration = TaskSpaceModel::configuration(&model, &q);
    let kinematics = TaskSpaceModel::task_kinematics(&model, &configuration, &qd);
    let twist = kinematics.jacobian * output.reference_joint_speed;
    assert!(
        (twist - reference.twist).norm() < 1e-4 * (1.0 + reference.twist.norm()),
        "{twist:?} vs {:?}",
        reference.twist
    );
    let mut faster = reference;
    faster.twist *= 3.0;
    let fast = controller.step(&model, &q, &qd, &faster, 1e-3);
    assert!(
        (fast.reference_joint_speed - output.reference_joint_speed * 3.0).norm()
            < 1e-4 * (1.0 + fast.reference_joint_speed.norm())
    );
    // A hold (NaN input) asks for nothing.
    let held = controller.step(&model, &q.map(|_| f32::NAN), &qd, &reference, 1e-3);
    assert_eq!(held.reference_joint_speed, Joints::zeros());
}
