//! The drive interlock: once per control period it decides whether the
//! amplifier enable may be high and which torques reach the drives.
//!
//! Why a second line of defence beside the pick's own supervision (tracking,
//! speed, the joint brake): the pick's checks run on its model of the arm
//! (the joint observer, Eq 23) and end in a controlled stop that still drives
//! the motors. When that model is wrong (a swapped encoder channel or motor
//! lead makes every correction push the arm further away) or the stop does
//! not work, more torque is not the answer: the drives must go off and stay
//! off. So this module trusts neither the controller nor the encoders alone:
//! - every torque is checked before it goes out (finite, within the joint's
//!   rating): a bad value disables the drives instead of being clipped;
//! - joint soft limits: the encoder-derived position must stay inside the
//!   arm's ranges (`Puma560::joint_limits`, plus a margin);
//! - overspeed: above [`InterlockSettings::overspeed_braking_factor`] of a
//!   joint's speed limit while the pick is braking (its stop or brake is not
//!   working), above [`InterlockSettings::overspeed_factor`] at any time;
//! - motion disagreement: the commanded motion (the direction the torque
//!   drives the joint) against the measured one. A joint that keeps speeding
//!   up against a large opposing torque is not doing what it is told: the
//!   signature of a sign error (positive feedback) or a failed drive, which
//!   the encoders alone cannot show (with a swapped channel they report a
//!   perfectly plausible, wrong motion).
//!
//! A trip latches an [`InterlockFault`] (which joint, which check; or a board
//! fault: a panic, a HardFault, an unexpected interrupt) and from then on
//! every period answers "enable low, zero torque" until
//! [`DriveInterlock::acknowledge`]: a fault is not cleared by the next period
//! looking fine.
//!
//! Units: radians, rad/s, N m, joint side; joint 1 first.

use crate::robot::table::{POSITION_MAX, POSITION_MIN, TORQUE_MAX, VELOCITY_MAX};
use crate::robot::{JointLimits, JointVector};

use super::JOINTS;

/// Which check tripped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InterlockCheck {
    /// A commanded torque was NaN or infinite.
    TorqueNotFinite,
    /// A commanded torque exceeded the joint's rating.
    TorqueOutOfRange,
    /// The encoder-derived position or speed was not a finite number.
    MeasurementNotFinite,
    /// The joint left its range (plus the soft-limit margin).
    SoftLimit,
    /// The joint ran over its speed limit times the factor in force.
    Overspeed,
    /// The joint sped up against a large opposing torque for too long.
    MotionDisagreement,
}

/// Faults the board reports from outside the control period: its handlers
/// run when nothing else can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BoardFault {
    /// The firmware panicked (this run, or the run before a reset).
    Panic,
    /// A HardFault (or another fault exception).
    HardFault,
    /// An interrupt with no handler of its own reached the default handler.
    UnexpectedInterrupt,
    /// The independent watchdog reset the board: the last run hung.
    WatchdogReset,
    /// The emergency-stop input opened (pressed, or its wiring broken).
    EmergencyStop,
    /// A servo amplifier signalled a fault on its fault output.
    DriveFault,
    /// The control period overran its deadline
    /// (`crate::safety::deadline::DEADLINE_MISSES_TO_STOP`) times in a row:
    /// the loop cannot keep its rate, so the arm is no longer controlled.
    DeadlineMissed,
    /// The stack reached its guard region (MPU): a stack overflow, caught
    /// before it overwrote the static data below it.
    StackOverflow,
}

/// Why the drives are off.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InterlockFault {
    /// A per-period check on one joint (0-based index).
    Joint { joint: u8, check: InterlockCheck },
    /// A fault handler or a reset cause.
    Board(BoardFault),
}

/// The arm's limits as the interlock sees them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterlockLimits {
    pub position_min_rad: [f32; JOINTS],
    pub position_max_rad: [f32; JOINTS],
    /// Symmetric speed limit (rad/s).
    pub speed_max_rad_s: [f32; JOINTS],
    /// Symmetric torque rating (N m): the drives' torque at full duty.
    pub torque_max_nm: [f32; JOINTS],
}

const fn to_f32(table: [f64; JOINTS]) -> [f32; JOINTS] {
    let mut out = [0.0f32; JOINTS];
    let mut joint = 0;
    while joint < JOINTS {
        // Indexing in a const fn: a bad index is a compile error, not a panic.
        #[allow(clippy::indexing_slicing)]
        {
            out[joint] = table[joint] as f32;
        }
        joint += 1;
    }
    out
}

impl InterlockLimits {
    /// The PUMA 560's tables, the same numbers `Puma560::joint_limits()` is
    /// built from (a unit test checks it), as constants: the firmware does not
    /// build the 2.7 KB model for them.
    pub const PUMA560: InterlockLimits = InterlockLimits {
        position_min_rad: to_f32(POSITION_MIN),
        position_max_rad: to_f32(POSITION_MAX),
        speed_max_rad_s: to_f32(VELOCITY_MAX),
        torque_max_nm: to_f32(TORQUE_MAX),
    };

    /// The limits of a model (e.g. `Puma560::joint_limits()`).
    pub fn from_joint_limits(limits: &JointLimits<f32>) -> Self {
        let array = |v: &JointVector<f32>| {
            let mut out = [0.0f32; JOINTS];
            for (slot, value) in out.iter_mut().zip(v.iter()) {
                *slot = *value;
            }
            out
        };
        InterlockLimits {
            position_min_rad: array(&limits.position_min),
            position_max_rad: array(&limits.position_max),
            speed_max_rad_s: array(&limits.velocity_max),
            torque_max_nm: array(&limits.torque_max),
        }
    }
}

/// How strict the interlock is. The defaults sit outside everything the pick
/// does on purpose (its own speed stop at 0.97 and brake at 1.1 of the limit,
/// torques saturated at the rating, moves inside the ranges), so the
/// interlock acts only when the pick's supervision has failed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterlockSettings {
    pub limits: InterlockLimits,
    /// Allowed travel beyond each end of a joint's range (rad): encoder
    /// quantisation and the controller's overshoot at a range end.
    pub soft_limit_margin_rad: f32,
    /// While the pick brakes (phase Stopping or Faulted), a joint faster than
    /// this times its limit trips: the pick's joint brake takes over at 1.1,
    /// so a joint still above 1.25 while braking is not being stopped.
    pub overspeed_braking_factor: f32,
    /// At any time, a joint faster than this times its limit trips.
    pub overspeed_factor: f32,
    /// Relative slack on the torque rating: the controller saturates at the
    /// rating in f32, so only a value clearly beyond it is out of range.
    pub torque_tolerance: f32,
    /// Motion disagreement: the opposing torque must be at least this
    /// fraction of the joint's torque in force (rating or cap) ...
    pub disagreement_torque_fraction: f32,
    /// ... the joint at least this fraction of its speed limit ...
    pub disagreement_speed_fraction: f32,
    /// ... for this many consecutive periods, faster at the end than at the
    /// start: 20 ms at 1 kHz, long against the few milliseconds a rated
    /// torque needs to turn a joint round, short against a runaway.
    pub disagreement_periods: u16,
    /// Commissioning: every torque is clipped to this (N m, per joint) before
    /// it goes out, so a first run with an unverified sign or gain moves the
    /// arm gently while the checks above find the fault. `None` in service.
    pub torque_cap_nm: Option<[f32; JOINTS]>,
}

impl InterlockSettings {
    /// The PUMA 560 in service: no torque cap.
    pub const PUMA560: InterlockSettings = InterlockSettings {
        limits: InterlockLimits::PUMA560,
        soft_limit_margin_rad: 0.05,
        overspeed_braking_factor: 1.25,
        overspeed_factor: 1.5,
        torque_tolerance: 1e-3,
        disagreement_torque_fraction: 0.5,
        disagreement_speed_fraction: 0.05,
        disagreement_periods: 20,
        torque_cap_nm: None,
    };

    /// The same with every torque capped at `fraction` of the joint's rating
    /// (commissioning). A fraction that is not in (0, 1] caps at zero torque.
    /// A `const fn`, so a board keeps its settings in flash.
    pub const fn with_commissioning_cap(mut self, fraction: f32) -> Self {
        let fraction = if fraction > 0.0 && fraction <= 1.0 {
            fraction
        } else {
            0.0
        };
        let mut cap = self.limits.torque_max_nm;
        let mut joint = 0;
        while joint < JOINTS {
            // Indexing in a const fn: a bad index is a compile error, not a panic.
            #[allow(clippy::indexing_slicing)]
            {
                cap[joint] *= fraction;
            }
            joint += 1;
        }
        self.torque_cap_nm = Some(cap);
        self
    }
}

/// One period's inputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeriodInput<'a> {
    /// The torques the controller commands (N m): the commanded motion's
    /// direction, too.
    pub torque_nm: &'a [f32; JOINTS],
    /// Joint positions from the encoders (rad).
    pub q_measured_rad: &'a [f32; JOINTS],
    /// Joint speeds differenced from the encoders (rad/s); `None` until the
    /// window behind them is full.
    pub qd_measured_rad_s: Option<&'a [f32; JOINTS]>,
    /// The pick is stopping or holding after a fault.
    pub braking: bool,
}

/// The period's answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterlockOutput {
    /// Whether the amplifier enable may be high this period.
    pub enable: bool,
    /// The torques to drive (N m): all zero when `enable` is false.
    pub torque_nm: [f32; JOINTS],
}

impl InterlockOutput {
    const OFF: InterlockOutput = InterlockOutput {
        enable: false,
        torque_nm: [0.0; JOINTS],
    };
}

/// The latched cut-out. It borrows its settings: the firmware keeps them in
/// flash (a `static`), not in the control task's RAM.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveInterlock<'s> {
    settings: &'s InterlockSettings,
    fault: Option<InterlockFault>,
    /// Consecutive periods each joint has moved against a large torque.
    opposed_periods: [u16; JOINTS],
    /// Each joint's speed (rad/s, magnitude) when its opposition began.
    opposed_from_rad_s: [f32; JOINTS],
}

/// `value <= bound`, false when either is NaN (so a NaN fails every check).
fn at_most(value: f32, bound: f32) -> bool {
    matches!(
        value.partial_cmp(&bound),
        Some(core::cmp::Ordering::Less | core::cmp::Ordering::Equal)
    )
}

fn joint_fault(joint: usize, check: InterlockCheck) -> InterlockFault {
    InterlockFault::Joint {
        joint: u8::try_from(joint).unwrap_or(u8::MAX),
        check,
    }
}

impl<'s> DriveInterlock<'s> {
    pub fn new(settings: &'s InterlockSettings) -> Self {
        DriveInterlock {
            settings,
            fault: None,
            opposed_periods: [0; JOINTS],
            opposed_from_rad_s: [0.0; JOINTS],
        }
    }

    /// The latched fault, if any (the first one: later trips do not replace it).
    pub fn fault(&self) -> Option<InterlockFault> {
        self.fault
    }

    pub fn settings(&self) -> &'s InterlockSettings {
        self.settings
    }

    /// Latches `fault` (a board handler's, or a check the caller made);
    /// keeps an earlier fault if one is latched already.
    pub fn trip(&mut self, fault: InterlockFault) {
        if self.fault.is_none() {
            self.fault = Some(fault);
        }
    }

    /// The host has seen the fault: the next period may enable the drives
    /// again if its checks pass. Forgets the motion history too, so a new
    /// start is judged on its own periods.
    pub fn acknowledge(&mut self) {
        self.fault = None;
        self.opposed_periods = [0; JOINTS];
        self.opposed_from_rad_s = [0.0; JOINTS];
    }

    /// The answer for a period that runs no checks (a repeated sample whose
    /// torques were checked when first computed): off when latched.
    pub fn hold(&self, torque_nm: &[f32; JOINTS]) -> InterlockOutput {
        if self.fault.is_some() {
            return InterlockOutput::OFF;
        }
        InterlockOutput {
            enable: true,
            torque_nm: self.capped(torque_nm),
        }
    }

    /// One control period: checks, then the enable and the torques to drive.
    pub fn period(&mut self, input: &PeriodInput<'_>) -> InterlockOutput {
        if self.fault.is_none() {
            if let Err(fault) = self.check(input) {
                self.fault = Some(fault);
            }
        }
        self.hold(input.torque_nm)
    }

    /// All checks in one pass over the joints, without an early exit: each
    /// failed check sets a bit (`check * 8 + joint`), and only a failure is
    /// decoded (the lowest bit: torques first, then positions, then speeds,
    /// then motion, joint 1 first in each). The control period runs this
    /// every time at opt-level "z" on the M4F: a comparison that also rejects
    /// NaN (`!(x <= limit)`) costs one compare where `is_finite` plus a
    /// branch per value cost tens of instructions an entry.
    fn check(&mut self, input: &PeriodInput<'_>) -> Result<(), InterlockFault> {
        const TORQUE: u32 = 0;
        const POSITION: u32 = 8;
        const SPEED: u32 = 16;
        const MOTION: u32 = 24;
        let s = self.settings;
        let limits = &s.limits;
        let margin = s.soft_limit_margin_rad;
        let speed_factor = if input.braking {
            s.overspeed_braking_factor
        } else {
            s.overspeed_factor
        };
        let mut failed: u32 = 0;
        for joint in 0..JOINTS {
            let at = |values: &[f32; JOINTS]| values.get(joint).copied().unwrap_or(f32::NAN);
            let bit = |check: u32, fails: bool| u32::from(fails) << (check + joint as u32);
            let tau = at(input.torque_nm);
            let rating = at(&limits.torque_max_nm);
            failed |= bit(
                TORQUE,
                !at_most(tau.abs(), rating * (1.0 + s.torque_tolerance)),
            );
            let q = at(input.q_measured_rad);
            let inside = q >= at(&limits.position_min_rad) - margin
                && q <= at(&limits.position_max_rad) + margin;
            failed |= bit(POSITION, !inside);
            let Some(qd) = input.qd_measured_rad_s else {
                continue;
            };
            let speed = at(qd);
            let speed_max = at(&limits.speed_max_rad_s);
            failed |= bit(SPEED, !at_most(speed.abs(), speed_factor * speed_max));
            let in_force = s.torque_cap_nm.map_or(rating, |cap| at(&cap).min(rating));
            let opposed = tau * speed < 0.0
                && tau.abs() >= s.disagreement_torque_fraction * in_force
                && speed.abs() >= s.disagreement_speed_fraction * speed_max;
            if let (Some(periods), Some(from)) = (
                self.opposed_periods.get_mut(joint),
                self.opposed_from_rad_s.get_mut(joint),
            ) {
                if opposed {
                    if *periods == 0 {
                        *from = speed.abs();
                    }
                    *periods = periods.saturating_add(1);
                    failed |= bit(
                        MOTION,
                        *periods >= s.disagreement_periods && speed.abs() > *from,
                    );
                } else {
                    *periods = 0;
                }
            }
        }
        if failed == 0 {
            return Ok(());
        }
        let first = failed.trailing_zeros();
        let joint = (first % 8) as usize;
        let finite = |values: Option<&[f32; JOINTS]>| {
            values
                .and_then(|v| v.get(joint))
                .is_some_and(|x| x.is_finite())
        };
        let check = match first - first % 8 {
            TORQUE if !finite(Some(input.torque_nm)) => InterlockCheck::TorqueNotFinite,
            TORQUE => InterlockCheck::TorqueOutOfRange,
            POSITION if !finite(Some(input.q_measured_rad)) => InterlockCheck::MeasurementNotFinite,
            POSITION => InterlockCheck::SoftLimit,
            SPEED if !finite(input.qd_measured_rad_s) => InterlockCheck::MeasurementNotFinite,
            SPEED => InterlockCheck::Overspeed,
            _ => InterlockCheck::MotionDisagreement,
        };
        Err(joint_fault(joint, check))
    }

    /// The torques clipped to the commissioning cap (unchanged in service).
    fn capped(&self, torque_nm: &[f32; JOINTS]) -> [f32; JOINTS] {
        let mut out = *torque_nm;
        if let Some(cap) = self.settings.torque_cap_nm {
            for (tau, &max) in out.iter_mut().zip(cap.iter()) {
                // Not `clamp`: it panics on a NaN or negative bound.
                let max = if max.is_finite() { max.abs() } else { 0.0 };
                *tau = tau.max(-max).min(max);
            }
        }
        out
    }
}

/// Joint positions and speeds from the encoders alone, for the interlock:
/// counts scaled by the cell's counts per radian (0 counts at q = 0, a count
/// standing for the middle of its interval, as the pick reads them) and
/// differenced over [`WINDOW`] readings (ten periods: one count of
/// quantisation is then a tenth of a count a period in speed, as in the
/// pick's own speed supervisor). Integer counts in a ring, no nalgebra: this
/// runs every control period.
#[derive(Debug, Clone, PartialEq)]
pub struct EncoderMotion {
    rad_per_count: [f32; JOINTS],
    counts: [[i32; JOINTS]; WINDOW],
    time_us: [u64; WINDOW],
    /// The slot the next reading goes to.
    next: usize,
    /// Readings held (at most [`WINDOW`]).
    filled: usize,
}

/// Readings the speeds span (`WINDOW - 1` periods apart).
pub const WINDOW: usize = crate::app::joint_speed::WINDOW;

impl EncoderMotion {
    /// A scale that is not a positive finite number gives NaN positions
    /// and speeds, which the interlock trips on.
    pub fn new(counts_per_rad: &[f32; JOINTS]) -> Self {
        let mut rad_per_count = [f32::NAN; JOINTS];
        for (out, &per_rad) in rad_per_count.iter_mut().zip(counts_per_rad.iter()) {
            if per_rad > 0.0 && per_rad.is_finite() {
                *out = 1.0 / per_rad;
            }
        }
        EncoderMotion {
            rad_per_count,
            counts: [[0; JOINTS]; WINDOW],
            time_us: [0; WINDOW],
            next: 0,
            filled: 0,
        }
    }

    /// Positions (rad) and, once the window is full, speeds (rad/s).
    pub fn update(
        &mut self,
        joint_counts: &[i32; JOINTS],
        time_us: u64,
    ) -> ([f32; JOINTS], Option<[f32; JOINTS]>) {
        let mut q = [0.0f32; JOINTS];
        for ((q, &count), &scale) in q
            .iter_mut()
            .zip(joint_counts.iter())
            .zip(self.rad_per_count.iter())
        {
            *q = (count as f32 + 0.5) * scale;
        }
        let slot = self.next % WINDOW;
        let oldest = (slot + 1) % WINDOW;
        if let (Some(counts), Some(time)) = (self.counts.get_mut(slot), self.time_us.get_mut(slot))
        {
            *counts = *joint_counts;
            *time = time_us;
        }
        self.next = oldest;
        self.filled = (self.filled + 1).min(WINDOW);
        if self.filled < WINDOW {
            return (q, None);
        }
        let (Some(old_counts), Some(&old_time)) =
            (self.counts.get(oldest), self.time_us.get(oldest))
        else {
            return (q, None);
        };
        let dt_s = match time_us.checked_sub(old_time) {
            Some(us) if us > 0 => crate::kernels::micros_to_seconds(us),
            _ => return (q, None),
        };
        let per_second = 1.0 / dt_s;
        let mut qd = [0.0f32; JOINTS];
        for (((qd, &now), &then), &scale) in qd
            .iter_mut()
            .zip(joint_counts.iter())
            .zip(old_counts.iter())
            .zip(self.rad_per_count.iter())
        {
            *qd = now.wrapping_sub(then) as f32 * scale * per_second;
        }
        (q, Some(qd))
    }
}

#[cfg(test)]
mod tests {
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
}
