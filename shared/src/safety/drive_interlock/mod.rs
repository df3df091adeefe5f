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
    Joint {
        /// The joint, 0-based.
        joint: u8,
        /// The check it failed.
        check: InterlockCheck,
    },
    /// A fault handler or a reset cause.
    Board(BoardFault),
}

/// The arm's limits as the interlock sees them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterlockLimits {
    /// Lowest joint angles, rad.
    pub position_min_rad: [f32; JOINTS],
    /// Highest joint angles, rad.
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
    /// The arm's limits.
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
    /// An interlock with `settings`, no fault latched.
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

    /// The settings it checks against.
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
mod tests;
