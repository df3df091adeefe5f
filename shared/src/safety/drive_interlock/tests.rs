//! The drive interlock's checks, trips and latching.

use super::*;
use crate::robot::Puma560;

const REST: [f32; JOINTS] = [0.0; JOINTS];

fn input<'a>(
    torque: &'a [f32; JOINTS],
    q: &'a [f32; JOINTS],
    qd: Option<&'a [f32; JOINTS]>,
) -> PeriodInput<'a> {
    PeriodInput {
        torque_nm: torque,
        q_measured_rad: q,
        qd_measured_rad_s: qd,
        braking: false,
    }
}

fn interlock() -> DriveInterlock<'static> {
    DriveInterlock::new(&InterlockSettings::PUMA560)
}

#[test]
fn the_constant_limits_are_the_models() {
    let model = Puma560::<f64>::new().cast::<f32>();
    assert_eq!(
        InterlockLimits::from_joint_limits(model.joint_limits()),
        InterlockLimits::PUMA560
    );
}

#[test]
fn a_sane_period_passes_its_torques() {
    let mut lock = interlock();
    let tau = [10.0, -40.0, 5.0, 1.0, -1.0, 0.5];
    let out = lock.period(&input(&tau, &REST, Some(&REST)));
    assert_eq!(
        out,
        InterlockOutput {
            enable: true,
            torque_nm: tau
        }
    );
    // At the rating exactly (the controller saturates there).
    let rated = InterlockLimits::PUMA560.torque_max_nm;
    assert!(lock.period(&input(&rated, &REST, None)).enable);
    assert_eq!(lock.fault(), None);
}

/// A non-finite or out-of-range torque disables the drives and latches:
/// the next, perfectly good period does not enable them again; only the
/// acknowledgement does.
#[test]
fn a_bad_torque_latches_until_acknowledged() {
    let good = [1.0; JOINTS];
    for (joint, bad) in [
        (2usize, f32::NAN),
        (0, f32::INFINITY),
        (5, f32::NEG_INFINITY),
        (1, 187.0),
        (3, -25.0),
    ] {
        let mut lock = interlock();
        let mut tau = good;
        tau[joint] = bad;
        let out = lock.period(&input(&tau, &REST, Some(&REST)));
        assert_eq!(out, InterlockOutput::OFF, "{joint} {bad}");
        let check = if bad.is_finite() {
            InterlockCheck::TorqueOutOfRange
        } else {
            InterlockCheck::TorqueNotFinite
        };
        let expected = joint_fault(joint, check);
        assert_eq!(lock.fault(), Some(expected));
        for _ in 0..5 {
            assert_eq!(
                lock.period(&input(&good, &REST, Some(&REST))),
                InterlockOutput::OFF
            );
            assert_eq!(lock.hold(&good), InterlockOutput::OFF);
        }
        assert_eq!(lock.fault(), Some(expected));
        lock.acknowledge();
        assert!(lock.period(&input(&good, &REST, Some(&REST))).enable);
    }
}

#[test]
fn the_first_fault_is_kept() {
    let mut lock = interlock();
    lock.trip(InterlockFault::Board(BoardFault::Panic));
    lock.trip(InterlockFault::Board(BoardFault::HardFault));
    let tau = [f32::NAN; JOINTS];
    assert_eq!(lock.period(&input(&tau, &REST, None)), InterlockOutput::OFF);
    assert_eq!(lock.fault(), Some(InterlockFault::Board(BoardFault::Panic)));
}

#[test]
fn soft_limits_are_the_arms_ranges() {
    let limits = InterlockLimits::PUMA560;
    let margin = InterlockSettings::PUMA560.soft_limit_margin_rad;
    for joint in 0..JOINTS {
        for (q, inside) in [
            (limits.position_max_rad[joint], true),
            (limits.position_max_rad[joint] + 0.9 * margin, true),
            (limits.position_max_rad[joint] + 1.1 * margin, false),
            (limits.position_min_rad[joint] - 0.9 * margin, true),
            (limits.position_min_rad[joint] - 1.1 * margin, false),
            (f32::NAN, false),
        ] {
            let mut lock = interlock();
            let mut position = REST;
            position[joint] = q;
            let out = lock.period(&input(&REST, &position, None));
            assert_eq!(out.enable, inside, "joint {joint} at {q}");
            if !inside {
                let check = if q.is_finite() {
                    InterlockCheck::SoftLimit
                } else {
                    InterlockCheck::MeasurementNotFinite
                };
                assert_eq!(lock.fault(), Some(joint_fault(joint, check)));
            }
        }
    }
}

/// Overspeed: the pick's own brake engages at 1.1 of a limit; while it
/// brakes, 1.25 trips; 1.3 outside a stop is left to the pick, 1.5 is not.
#[test]
fn overspeed_trips_harder_while_braking() {
    let vmax = InterlockLimits::PUMA560.speed_max_rad_s;
    for joint in 0..JOINTS {
        let speed = |factor: f32| {
            let mut qd = REST;
            qd[joint] = -factor * vmax[joint];
            qd
        };
        let run = |factor: f32, braking: bool| {
            let mut lock = interlock();
            let qd = speed(factor);
            let mut period = input(&REST, &REST, Some(&qd));
            period.braking = braking;
            (lock.period(&period).enable, lock.fault())
        };
        assert_eq!(run(1.2, true), (true, None));
        assert_eq!(
            run(1.3, true),
            (false, Some(joint_fault(joint, InterlockCheck::Overspeed)))
        );
        assert_eq!(run(1.3, false), (true, None));
        assert_eq!(
            run(1.6, false),
            (false, Some(joint_fault(joint, InterlockCheck::Overspeed)))
        );
    }
}

/// A joint that speeds up against a large opposing torque for 20 periods
/// trips; one that slows down under it (a correct drive) does not, nor a
/// joint pushed along its motion.
#[test]
fn motion_against_the_torque_trips() {
    let rated = InterlockLimits::PUMA560.torque_max_nm;
    let vmax = InterlockLimits::PUMA560.speed_max_rad_s;
    let joint = 1;
    let mut tau = REST;
    tau[joint] = -0.8 * rated[joint];
    let run = |speeds: &mut dyn FnMut(u16) -> f32, tau: &[f32; JOINTS]| {
        let mut lock = interlock();
        for period in 0..40u16 {
            let mut qd = REST;
            qd[joint] = speeds(period);
            if !lock.period(&input(tau, &REST, Some(&qd))).enable {
                return Some((period, lock.fault()));
            }
        }
        None
    };
    // Speeding up against the torque: tripped on the 20th period.
    let tripped = run(&mut |k| 0.1 * vmax[joint] + 0.01 * f32::from(k), &tau);
    assert_eq!(
        tripped,
        Some((
            19,
            Some(joint_fault(joint, InterlockCheck::MotionDisagreement))
        ))
    );
    // Slowing down under it: a drive that works.
    assert_eq!(
        run(&mut |k| 0.5 * vmax[joint] - 0.01 * f32::from(k), &tau),
        None
    );
    // The torque along the motion.
    let along = tau.map(|t| -t);
    assert_eq!(
        run(&mut |k| 0.1 * vmax[joint] + 0.01 * f32::from(k), &along),
        None
    );
    // A small torque (under half the rating) against it: gravity or
    // friction, not the drive's command.
    let small = tau.map(|t| 0.5 * t);
    assert_eq!(
        run(&mut |k| 0.1 * vmax[joint] + 0.01 * f32::from(k), &small),
        None
    );
}

#[test]
fn the_commissioning_cap_clips_every_torque() {
    let settings = InterlockSettings::PUMA560.with_commissioning_cap(0.2);
    let mut lock = DriveInterlock::new(&settings);
    let rated = InterlockLimits::PUMA560.torque_max_nm;
    let tau = rated.map(|t| -t);
    let out = lock.period(&input(&tau, &REST, Some(&REST)));
    assert!(out.enable);
    for (out, rated) in out.torque_nm.iter().zip(rated) {
        assert!((out + 0.2 * rated).abs() < 1e-4, "{out} {rated}");
    }
    // A bad cap allows no torque, never more.
    let nan_cap = InterlockSettings::PUMA560.with_commissioning_cap(f32::NAN);
    let mut lock = DriveInterlock::new(&nan_cap);
    assert_eq!(lock.period(&input(&tau, &REST, None)).torque_nm, REST);
    // Still checked against the rating before clipping.
    let mut lock = DriveInterlock::new(&settings);
    let mut over = REST;
    over[0] = 2.0 * rated[0];
    assert!(!lock.period(&input(&over, &REST, None)).enable);
}

#[test]
fn encoder_motion_scales_and_differences_counts() {
    let per_rad = [1000.0; JOINTS];
    let mut motion = EncoderMotion::new(&per_rad);
    let mut last = None;
    for k in 0..WINDOW as i32 {
        // Joint 3 at 2 rad/s: 2 counts per 1 ms period.
        let counts = [0, 0, 2 * k, 0, 0, 0];
        let (q, qd) = motion.update(&counts, 1_000 * k as u64);
        assert!((q[2] - (2 * k) as f32 / 1000.0 - 0.0005).abs() < 1e-6);
        last = qd;
    }
    let qd = last.unwrap_or([f32::NAN; JOINTS]);
    assert!((qd[2] - 2.0).abs() < 1e-3, "{qd:?}");
    assert!(qd[0].abs() < 1e-6);
    let mut bad = EncoderMotion::new(&[0.0; JOINTS]);
    let (q, _) = bad.update(&[1; JOINTS], 0);
    let mut lock = interlock();
    assert!(!lock.period(&input(&REST, &q, None)).enable);
}
