//! Serial protocol v3 between the vision computer / simulator and the controller.
//!
//! - Messages ([`Message`]) are postcard-encoded (varints, compact enums).
//! - Each is followed by a CRC-32 (ISO-HDLC, little-endian) of its payload.
//! - Payload and CRC are COBS-stuffed and framed by 0x00 on both sides:
//!   `0x00, COBS(payload ++ crc), 0x00`.
//! - A payload is at most [`MAX_MESSAGE_LEN`] bytes, so a frame is at most
//!   [`MAX_FRAME_LEN`] bytes on the wire.
//! - A session opens with [`Message::Hello`] carrying [`PROTOCOL_VERSION`]; the
//!   controller answers [`Message::HelloAck`] or an error report.
//!
//! The decoder ([`FrameDecoder`]) takes bytes in arbitrary chunks, rejects corrupt
//! or oversized frames with a typed [`DecodeError`] and resynchronises on the next
//! delimiter.

mod cobs;
mod frame;
mod messages;
mod pick;

pub use frame::{
    encode_frame, DecodeError, EncodeError, FrameDecoder, CRC_LEN, MAX_BODY_LEN, MAX_FRAME_LEN,
    MAX_MESSAGE_LEN,
};
pub use messages::*;

/// The protocol version this code speaks. Messages and fields are only ever
/// appended, so an older peer's messages keep their encoding; the version
/// goes up when a peer of the previous version could not decode what this
/// one sends unasked. v2: `Message::TriggerEvent` (the controller sends it
/// on every camera trigger of its ticker, which a v1 host would refuse as a
/// bad frame five times a second) and `CostUnit::Nanoseconds`.
/// v3: `CellConfig` without `pixel_sigma_px` (the controller measures the
/// pixel noise from its residuals).
/// v4: `RuntimeReport::job_worst` per kind of job ([`JobCosts`]);
/// `FaultCause::DiscOutOfReach` and `FaultCause::PartOutOfReach` (a layout
/// the arm cannot serve stops with why; a v3 host could not decode them).
/// v5: homing at power-on: `SensorSample::joint_pots_rad` and
/// `SensorSample::joint_index_counts`, `CellConfig::home_at_power_on`,
/// `FaultCause::HomingPotentiometer` and `FaultCause::HomingIndexNotSeen`.
/// v6: `JobCosts::observation`, the worst per-frame update of the
/// self-calibrator (which now folds what its stores have no room for).
/// v7: `CalibrationReport::sigma_grasp_*`, the part's uncertainty in the
/// base frame (what decides whether the pick shows its marks once more).
/// v8: `FaultCause::DiscNotSeen` (a search that ends without the marks and
/// without a frame of the disc's reference mark says so).
/// v9: `CameraFeatureFrame::rim` and `CellConfig::disc_radius_m`: the disc's
/// rim measured in each frame, an observation of the camera's pose.
/// v10: `FaultCause::PartNotSeen` (no frame showed the part by the end of
/// the search's wait for it).
/// The handshake
/// refuses any other version with `UnsupportedVersion` (detail: this one).
pub const PROTOCOL_VERSION: u16 = 10;

#[cfg(test)]
mod tests;
