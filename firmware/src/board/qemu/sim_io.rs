//! Encoders and servo outputs of the emulated board. There are no motors: the
//! host simulator sends joint encoder counts over the link (the link task calls
//! [`feed_encoder_counts`]) and reads back the servo duties the controller last
//! commanded ([`last_servo_duties`]).

use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, Ordering};

use crate::board::{
    validate_duties, BoardError, JointCounts, JointDuties, JointEncoders, ServoOutputs, JOINTS,
};

static ENCODER_COUNTS: [AtomicI32; JOINTS] = [const { AtomicI32::new(0) }; JOINTS];
/// Duties as `f32` bit patterns.
static SERVO_DUTIES: [AtomicU32; JOINTS] = [const { AtomicU32::new(0) }; JOINTS];
static SERVOS_ENABLED: AtomicBool = AtomicBool::new(false);

/// Stores the simulator's latest encoder counts.
pub fn feed_encoder_counts(counts: JointCounts) {
    for (slot, count) in ENCODER_COUNTS.iter().zip(counts) {
        slot.store(count, Ordering::Relaxed);
    }
}

/// The duties last commanded, or `None` while the servos are disabled.
#[allow(
    dead_code,
    reason = "the servo path is driven by the control issue (Eq 23 torques to duties)"
)]
pub fn last_servo_duties() -> Option<JointDuties> {
    if !SERVOS_ENABLED.load(Ordering::Acquire) {
        return None;
    }
    let mut duties = [0.0; JOINTS];
    for (duty, slot) in duties.iter_mut().zip(SERVO_DUTIES.iter()) {
        *duty = f32::from_bits(slot.load(Ordering::Relaxed));
    }
    Some(duties)
}

/// Encoders read from the counts the simulator fed.
pub struct SimulatedEncoders {
    _owned: (),
}

impl SimulatedEncoders {
    pub(super) fn take() -> Self {
        SimulatedEncoders { _owned: () }
    }
}

impl JointEncoders for SimulatedEncoders {
    fn read_counts(&mut self) -> Result<JointCounts, BoardError> {
        let mut counts = [0; JOINTS];
        for (count, slot) in counts.iter_mut().zip(ENCODER_COUNTS.iter()) {
            *count = slot.load(Ordering::Relaxed);
        }
        Ok(counts)
    }
}

/// Servo outputs recorded for the simulator to read back.
pub struct SimulatedServos {
    _owned: (),
}

impl SimulatedServos {
    pub(super) fn take() -> Self {
        SimulatedServos { _owned: () }
    }
}

impl ServoOutputs for SimulatedServos {
    fn set_duties(&mut self, duties: JointDuties) -> Result<(), BoardError> {
        validate_duties(&duties)?;
        for (slot, duty) in SERVO_DUTIES.iter().zip(duties) {
            slot.store(duty.to_bits(), Ordering::Relaxed);
        }
        SERVOS_ENABLED.store(true, Ordering::Release);
        Ok(())
    }

    fn disable(&mut self) {
        SERVOS_ENABLED.store(false, Ordering::Release);
        for slot in SERVO_DUTIES.iter() {
            slot.store(0.0f32.to_bits(), Ordering::Relaxed);
        }
    }
}
