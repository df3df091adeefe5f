//! Per-joint encoder and motor signs: how a board's wiring maps onto the
//! arm's joint directions.
//!
//! Why: a quadrature encoder with its A and B channels swapped counts
//! backwards, and a motor with its leads swapped turns backwards. Either one
//! alone turns every correction of the control law into a push the wrong way
//! (positive feedback): a runaway. Both are wiring facts of one cell, so they
//! belong in the board's configuration, set at commissioning, rather than
//! being "fixed" by swapping wires until the arm behaves. At commissioning
//! (the firmware's `commissioning` feature caps every torque, see
//! `InterlockSettings::with_commissioning_cap`) a wrong sign shows as the
//! interlock's `MotionDisagreement` on that joint within some 20 periods of
//! capped torque, before the joint has moved more than a few milliradians;
//! flipping that joint's entry here is the fix.

use super::JOINTS;

/// A wiring sign.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Sign {
    /// As the arm's joint convention.
    Positive,
    /// Reversed (a swapped A/B channel, or motor lead).
    Negative,
}

impl Sign {
    /// `value` in the joint's convention.
    pub fn apply(self, value: f32) -> f32 {
        match self {
            Sign::Positive => value,
            Sign::Negative => -value,
        }
    }

    /// An encoder count in the joint's convention; `None` where the negation
    /// overflows (`i64::MIN`, which no 16-bit counter unwraps to in practice).
    pub fn apply_count(self, count: i64) -> Option<i64> {
        match self {
            Sign::Positive => Some(count),
            Sign::Negative => count.checked_neg(),
        }
    }
}

/// The signs of one board's six joints, joint 1 first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JointSigns {
    /// Encoder counts: counts up in the joint's positive direction when
    /// [`Sign::Positive`].
    pub encoder: [Sign; JOINTS],
    /// Motor: a positive duty turns the joint positive when
    /// [`Sign::Positive`].
    pub motor: [Sign; JOINTS],
}

impl JointSigns {
    /// Every encoder and motor wired as the joint convention.
    pub const AS_WIRED: JointSigns = JointSigns {
        encoder: [Sign::Positive; JOINTS],
        motor: [Sign::Positive; JOINTS],
    };

    /// Joint `joint`'s encoder count in the joint convention (`None`: no such
    /// joint, or the count cannot be negated).
    pub fn encoder_count(&self, joint: usize, count: i64) -> Option<i64> {
        self.encoder.get(joint)?.apply_count(count)
    }

    /// The torque to hand joint `joint`'s amplifier for a joint torque
    /// `torque_nm` (zero for no such joint).
    pub fn motor_torque(&self, joint: usize, torque_nm: f32) -> f32 {
        self.motor
            .get(joint)
            .map_or(0.0, |sign| sign.apply(torque_nm))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::safety::{
        DriveInterlock, EncoderMotion, InterlockCheck, InterlockFault, InterlockLimits,
        InterlockSettings, PeriodInput,
    };

    #[test]
    fn signs_negate_counts_and_torques() {
        let mut signs = JointSigns::AS_WIRED;
        signs.encoder[2] = Sign::Negative;
        signs.motor[4] = Sign::Negative;
        assert_eq!(signs.encoder_count(2, 1234), Some(-1234));
        assert_eq!(signs.encoder_count(1, 1234), Some(1234));
        assert_eq!(signs.encoder_count(2, i64::MIN), None);
        assert_eq!(signs.encoder_count(JOINTS, 1), None);
        assert_eq!(signs.motor_torque(4, 3.0), -3.0);
        assert_eq!(signs.motor_torque(3, 3.0), 3.0);
        assert_eq!(signs.motor_torque(JOINTS, 3.0), 0.0);
    }

    /// How far the joint got (rad, true) and the interlock's fault after a
    /// commissioning move of joint 2 to 0.2 rad, 1 s at 1 kHz: a PD law on
    /// the configured encoder reading, its torque through the configured motor
    /// sign into a joint of 4 kg m^2 whose wiring has the signs `wired`.
    fn commission(wired: JointSigns, configured: JointSigns) -> (f32, Option<InterlockFault>) {
        const JOINT: usize = 1;
        const INERTIA_KG_M2: f32 = 4.0;
        const COUNTS_PER_RAD: f32 = 10_000.0;
        let settings = InterlockSettings::PUMA560.with_commissioning_cap(0.2);
        let mut lock = DriveInterlock::new(&settings);
        let mut encoders = EncoderMotion::new(&[COUNTS_PER_RAD; JOINTS]);
        let (mut q_true, mut qd_true) = (0.0f32, 0.0f32);
        let dt_s = 1e-3;
        for k in 0..1000u64 {
            let raw = (q_true * COUNTS_PER_RAD).floor() as i64;
            let raw = wired.encoder_count(JOINT, raw).unwrap_or(0);
            let count = configured.encoder_count(JOINT, raw).unwrap_or(0);
            let mut counts = [0i32; JOINTS];
            counts[JOINT] = i32::try_from(count).unwrap_or(0);
            let (q, qd) = encoders.update(&counts, k * 1_000);
            let qd_joint = qd.map_or(0.0, |v| v[JOINT]);
            let rated = InterlockLimits::PUMA560.torque_max_nm[JOINT];
            let tau_joint = (2000.0 * (0.2 - q[JOINT]) - 200.0 * qd_joint).clamp(-rated, rated);
            let mut tau = [0.0; JOINTS];
            tau[JOINT] = tau_joint;
            let out = lock.period(&PeriodInput {
                torque_nm: &tau,
                q_measured_rad: &q,
                qd_measured_rad_s: qd.as_ref(),
                braking: false,
            });
            if !out.enable {
                break;
            }
            let to_amplifier = configured.motor_torque(JOINT, out.torque_nm[JOINT]);
            let applied = wired.motor_torque(JOINT, to_amplifier);
            qd_true += applied / INERTIA_KG_M2 * dt_s;
            q_true += qd_true * dt_s;
        }
        (q_true, lock.fault())
    }

    /// A swapped A/B channel or motor lead is found at commissioning, as a
    /// motion disagreement on its joint before the joint has moved 10 mrad;
    /// configured, the same wiring moves the joint where it is told.
    #[test]
    fn a_wrong_sign_is_found_at_commissioning_not_by_a_runaway() {
        let mut swapped_encoder = JointSigns::AS_WIRED;
        swapped_encoder.encoder[1] = Sign::Negative;
        let mut swapped_motor = JointSigns::AS_WIRED;
        swapped_motor.motor[1] = Sign::Negative;
        let disagreement = Some(InterlockFault::Joint {
            joint: 1,
            check: InterlockCheck::MotionDisagreement,
        });
        for wired in [swapped_encoder, swapped_motor] {
            let (q, fault) = commission(wired, JointSigns::AS_WIRED);
            assert_eq!(fault, disagreement, "{wired:?}");
            assert!(q.abs() < 0.01, "moved {q} rad");
            let (q, fault) = commission(wired, wired);
            assert_eq!(fault, None, "{wired:?}");
            assert!((q - 0.2).abs() < 0.01, "reached {q} rad");
        }
        let (q, fault) = commission(JointSigns::AS_WIRED, JointSigns::AS_WIRED);
        assert_eq!(fault, None);
        assert!((q - 0.2).abs() < 0.01, "reached {q} rad");
    }
}
