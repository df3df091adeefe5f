//! Framing: `0x00, COBS(postcard(message) ++ crc32_le), 0x00`.
//!
//! The leading delimiter closes whatever garbage preceded the frame on the line,
//! so garbage costs at most itself, never the next good frame. The CRC-32
//! (ISO-HDLC) is what makes "never yields a wrong message" hold against flipped,
//! dropped and inserted bytes; postcard must then consume the payload exactly.

use core::fmt;

use super::cobs::{self, CobsError};
use super::messages::Message;

/// Largest postcard payload of one message, in bytes.
pub const MAX_MESSAGE_LEN: usize = 320;
/// Bytes of the CRC-32 trailer.
pub const CRC_LEN: usize = 4;
/// Largest COBS body (payload plus CRC, stuffed).
pub const MAX_BODY_LEN: usize = cobs::max_encoded_len(MAX_MESSAGE_LEN + CRC_LEN);
/// Largest frame on the wire, both delimiters included.
pub const MAX_FRAME_LEN: usize = MAX_BODY_LEN + 2;

const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Why a message could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The message's payload exceeds [`MAX_MESSAGE_LEN`].
    MessageTooLarge,
    /// The output buffer is shorter than the frame.
    OutputTooSmall,
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::MessageTooLarge => write!(f, "message exceeds {MAX_MESSAGE_LEN} payload bytes"),
            Self::OutputTooSmall => write!(
                f,
                "output buffer shorter than the frame (use MAX_FRAME_LEN)"
            ),
        }
    }
}

impl core::error::Error for EncodeError {}

/// Why a received frame was rejected. The decoder has already resynchronised.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DecodeError {
    /// More than [`MAX_BODY_LEN`] bytes arrived without a delimiter; `discarded` bytes were dropped.
    Oversized {
        /// Bytes dropped.
        discarded: usize,
    },
    /// The COBS body was malformed.
    Corrupt,
    /// Shorter than a CRC.
    TooShort {
        /// The frame's length, bytes.
        len: usize,
    },
    /// The CRC did not match.
    BadCrc {
        /// The CRC the frame carries.
        expected: u32,
        /// The CRC of its payload.
        found: u32,
    },
    /// The CRC matched but the payload was not exactly one valid message.
    BadMessage,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Oversized { discarded } => {
                write!(
                    f,
                    "frame longer than {MAX_BODY_LEN} bytes ({discarded} bytes discarded)"
                )
            }
            Self::Corrupt => write!(f, "malformed COBS frame body"),
            Self::TooShort { len } => write!(f, "frame of {len} bytes is shorter than its CRC"),
            Self::BadCrc { expected, found } => {
                write!(
                    f,
                    "CRC mismatch: frame says {expected:#010x}, payload gives {found:#010x}"
                )
            }
            Self::BadMessage => write!(f, "CRC-valid frame does not hold one valid message"),
        }
    }
}

impl core::error::Error for DecodeError {}

/// Encodes `message` as one complete frame into `out`; returns the frame's length.
pub fn encode_frame(message: &Message, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut raw = [0u8; MAX_MESSAGE_LEN + CRC_LEN];
    let payload_len = {
        let (payload, _) = raw.split_at_mut(MAX_MESSAGE_LEN);
        postcard::to_slice(message, payload)
            .map_err(|_| EncodeError::MessageTooLarge)?
            .len()
    };
    let crc = CRC32.checksum(raw.get(..payload_len).ok_or(EncodeError::MessageTooLarge)?);
    raw.get_mut(payload_len..payload_len + CRC_LEN)
        .ok_or(EncodeError::MessageTooLarge)?
        .copy_from_slice(&crc.to_le_bytes());
    let raw = raw
        .get(..payload_len + CRC_LEN)
        .ok_or(EncodeError::MessageTooLarge)?;

    *out.first_mut().ok_or(EncodeError::OutputTooSmall)? = 0;
    let body = out.get_mut(1..).ok_or(EncodeError::OutputTooSmall)?;
    let body_len = cobs::encode(raw, body).map_err(|_| EncodeError::OutputTooSmall)?;
    *out.get_mut(body_len + 1)
        .ok_or(EncodeError::OutputTooSmall)? = 0;
    Ok(body_len + 2)
}

/// Streaming frame decoder: feed it bytes as they arrive, in chunks of any size.
///
/// Memory is fixed ([`MAX_BODY_LEN`] bytes). It never panics and never stalls:
/// every delimiter ends the current frame, so a corrupt or truncated frame costs
/// only itself.
#[derive(Clone)]
pub struct FrameDecoder {
    body: [u8; MAX_BODY_LEN],
    len: usize,
    discarded: usize,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// A decoder waiting for the first delimiter.
    pub const fn new() -> Self {
        Self {
            body: [0; MAX_BODY_LEN],
            len: 0,
            discarded: 0,
        }
    }

    /// Bytes buffered towards the frame in progress.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Takes one byte; returns a result when it completed a non-empty frame.
    pub fn push(&mut self, byte: u8) -> Option<Result<Message, DecodeError>> {
        if byte != 0 {
            match self.body.get_mut(self.len) {
                Some(slot) if self.discarded == 0 => {
                    *slot = byte;
                    self.len += 1;
                }
                _ => self.discarded = self.discarded.saturating_add(1),
            }
            return None;
        }
        let len = core::mem::take(&mut self.len);
        let discarded = core::mem::take(&mut self.discarded);
        if discarded > 0 {
            return Some(Err(DecodeError::Oversized {
                discarded: discarded.saturating_add(len),
            }));
        }
        if len == 0 {
            return None;
        }
        Some(
            self.body
                .get(..len)
                .map_or(Err(DecodeError::Corrupt), decode_body),
        )
    }

    /// Feeds a chunk, calling `on_frame` for each completed frame.
    pub fn push_slice(
        &mut self,
        bytes: &[u8],
        mut on_frame: impl FnMut(Result<Message, DecodeError>),
    ) {
        for &byte in bytes {
            if let Some(result) = self.push(byte) {
                on_frame(result);
            }
        }
    }
}

fn decode_body(body: &[u8]) -> Result<Message, DecodeError> {
    let mut raw = [0u8; MAX_MESSAGE_LEN + CRC_LEN];
    let len = cobs::decode(body, &mut raw).map_err(|e| match e {
        CobsError::Malformed | CobsError::OutputFull => DecodeError::Corrupt,
    })?;
    let payload_len = len
        .checked_sub(CRC_LEN)
        .ok_or(DecodeError::TooShort { len })?;
    let (payload, rest) = raw.split_at(payload_len);
    let crc_bytes: [u8; CRC_LEN] = rest
        .get(..CRC_LEN)
        .and_then(|b| b.try_into().ok())
        .ok_or(DecodeError::TooShort { len })?;
    let expected = u32::from_le_bytes(crc_bytes);
    let found = CRC32.checksum(payload);
    if expected != found {
        return Err(DecodeError::BadCrc { expected, found });
    }
    match postcard::take_from_bytes::<Message>(payload) {
        Ok((message, [])) => Ok(message),
        _ => Err(DecodeError::BadMessage),
    }
}
