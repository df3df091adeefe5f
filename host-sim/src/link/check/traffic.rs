//! The traffic of the link check: seeded random data frames (camera features,
//! sensor samples, actuator commands) and the corruptions injected between them.

use heapless::{String as HString, Vec as HVec};
use shared::protocol::{
    ActuatorCommand, CameraFeatureFrame, GripperCommand, LabeledPoint, Message, MessageKind,
    PointLabel, RimEllipse, SensorSample, JOINTS, MAX_FEATURE_POINTS, MAX_FRAME_LEN,
};

use super::outcome::{CheckError, ExchangeSummary};
use crate::link::LinkError;

/// A random data frame with token `token`, counted in `summary`.
pub(super) fn data_frame(
    token: u32,
    rng: &mut SplitMix64,
    summary: &mut ExchangeSummary,
) -> Message {
    summary.data_frames += 1;
    match rng.next() % 3 {
        0 => {
            summary.camera_frames += 1;
            Message::CameraFeatures(camera_frame(token, rng))
        }
        1 => {
            summary.sensor_samples += 1;
            // Encoder counts of a PUMA 560 joint stay within about +-2^17.
            let mut joint_counts = [0i32; JOINTS];
            for c in joint_counts.iter_mut() {
                *c = (rng.next() % (1 << 18)) as i32 - (1 << 17);
            }
            Message::SensorSample(SensorSample {
                seq: token,
                time_us: rng.next() >> 20,
                joint_counts,
                conveyor_counts: rng.next() as u32,
                part_in_gripper: false,
                joint_pots_rad: [0.0; 6],
                joint_index_counts: SensorSample::NO_INDEX,
            })
        }
        _ => {
            summary.actuator_commands += 1;
            let mut joint_torque_nm = [0f32; JOINTS];
            for t in joint_torque_nm.iter_mut() {
                *t = rng.unit() * 100.0 - 50.0;
            }
            Message::ActuatorCommand(ActuatorCommand {
                seq: token,
                joint_torque_nm,
                gripper: if rng.next() & 1 == 0 {
                    GripperCommand::Open
                } else {
                    GripperCommand::Close
                },
                camera_trigger: (rng.next() & 3 == 0).then_some(token),
            })
        }
    }
}

/// A camera frame of 1 to 6 points (disc centre, reference, effector and part
/// points), or with probability 1/16 a full one of [`MAX_FEATURE_POINTS`] so
/// frames near the protocol's maximum length are exercised too.
fn camera_frame(trigger_id: u32, rng: &mut SplitMix64) -> CameraFeatureFrame {
    let mut points: HVec<LabeledPoint, MAX_FEATURE_POINTS> = HVec::new();
    let count = if rng.next() & 15 == 0 {
        MAX_FEATURE_POINTS
    } else {
        1 + (rng.next() % 6) as usize
    };
    for i in 0..count {
        let label = match i {
            0 => PointLabel::DiscCenter,
            1 => PointLabel::Reference,
            2 | 3 => PointLabel::Effector((i - 2) as u8),
            _ => PointLabel::Part((i - 4) as u8),
        };
        let point = LabeledPoint {
            label,
            u_px: rng.unit() * 640.0,
            v_px: rng.unit() * 480.0,
        };
        if points.push(point).is_err() {
            break;
        }
    }
    // Every other frame carries a rim, so that both shapes cross the link.
    let rim = trigger_id.is_multiple_of(2).then(|| RimEllipse {
        centre_px: [rng.unit() * 640.0, rng.unit() * 480.0],
        semi_axes_px: [40.0 + rng.unit(), 30.0 + rng.unit()],
        angle_rad: rng.unit(),
        sigma_px: 0.01,
    });
    CameraFeatureFrame {
        trigger_id,
        capture_time_us: rng.next() >> 16,
        points,
        rim,
    }
}

pub(super) fn data_kind_token(message: &Message) -> (MessageKind, u32) {
    match message {
        Message::CameraFeatures(f) => (MessageKind::CameraFeatures, f.trigger_id),
        Message::SensorSample(s) => (MessageKind::SensorSample, s.seq),
        Message::ActuatorCommand(c) => (MessageKind::ActuatorCommand, c.seq),
        // `data_frame` makes only the three data kinds.
        _ => (MessageKind::SensorSample, 0),
    }
}

pub(super) fn encode(message: &Message) -> Result<Vec<u8>, CheckError> {
    let mut frame = [0u8; MAX_FRAME_LEN];
    let len = shared::protocol::encode_frame(message, &mut frame)
        .map_err(|e| CheckError::Link(LinkError::Encode(e.to_string())))?;
    Ok(frame.iter().take(len).copied().collect())
}

/// Flips one bit strictly inside the frame (not its delimiters), choosing a
/// bit whose flip does not make a zero byte, which would split the frame in two.
pub(super) fn flip_one_bit(frame: &mut [u8], rng: &mut SplitMix64) {
    let inner = frame.len().saturating_sub(2);
    if inner == 0 {
        return;
    }
    loop {
        let at = 1 + (rng.next() as usize) % inner;
        let bit = 1u8 << (rng.next() % 8);
        if let Some(byte) = frame.get_mut(at) {
            if *byte ^ bit != 0 {
                *byte ^= bit;
                return;
            }
        }
    }
}

pub(super) fn bounded_string<const N: usize>(text: &str) -> HString<N> {
    let mut s = HString::new();
    for c in text.chars() {
        if s.push(c).is_err() {
            break;
        }
    }
    s
}

/// SplitMix64: a small seeded generator, so every run sends the same traffic.
pub(super) struct SplitMix64(pub(super) u64);

impl SplitMix64 {
    pub(super) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub(super) fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flipping_one_bit_never_makes_a_delimiter() {
        let mut rng = SplitMix64(3);
        for _ in 0..2_000 {
            let mut frame = vec![0u8, 1, 1, 1, 2, 0x80, 0];
            flip_one_bit(&mut frame, &mut rng);
            assert_eq!(frame.first(), Some(&0));
            assert_eq!(frame.last(), Some(&0));
            assert!(frame.iter().skip(1).take(5).all(|&b| b != 0));
        }
    }
}
