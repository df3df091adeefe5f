//! Builds a valid frame from the fuzz input, corrupts it, and asserts that the
//! decoder never accepts the corrupt frame as a different message.
//!
//! Input layout: `[chunk, op_count, ops (4 bytes each)..., message bytes...]`.
//! The message is whatever postcard decodes from the message bytes (or, when
//! they are not a message, a sensor sample built from them), so the fuzzer
//! explores every message type. Each op flips a bit, deletes, inserts,
//! replaces or truncates at a fuzz-chosen position of the wire frame.
//!
//! Properties, on every input:
//! - an untouched frame decodes exactly once, to the original message;
//! - a corrupted frame is rejected, or decodes to a message whose encoding is
//!   byte-identical to the original's (a no-op corruption, e.g. an inserted
//!   delimiter before the frame); the CRC-32 is what guarantees this;
//! - a valid frame sent afterwards decodes intact (the decoder resynchronises).
#![no_main]

use libfuzzer_sys::fuzz_target;
use shared::protocol::{
    encode_frame, FrameDecoder, Message, SensorSample, MAX_FRAME_LEN, MAX_MESSAGE_LEN,
};

const OP_LEN: usize = 4;
const MAX_OPS: u8 = 6;

fn payload(message: &Message) -> Vec<u8> {
    let mut buf = [0u8; MAX_MESSAGE_LEN];
    postcard::to_slice(message, &mut buf)
        .expect("a message that framed also serialises")
        .to_vec()
}

/// A message that always exists: the fuzzer's bytes as a sensor sample.
fn fallback_message(bytes: &[u8]) -> Message {
    let mut word = [0u8; 4];
    for (slot, byte) in word.iter_mut().zip(bytes) {
        *slot = *byte;
    }
    let value = u32::from_le_bytes(word);
    Message::SensorSample(SensorSample {
        seq: value,
        time_us: u64::from(value) << 7,
        joint_counts: [value as i32, -(value as i32 >> 1), 3, 0, -7, 1 << 20],
        conveyor_counts: value.rotate_left(9),
        part_in_gripper: value & 1 == 1,
        joint_pots_rad: [0.0; 6],
        joint_index_counts: SensorSample::NO_INDEX,
    })
}

fn apply(op: &[u8], wire: &mut Vec<u8>) {
    let [kind, lo, hi, value] = [op[0], op[1], op[2], op[3]];
    if wire.is_empty() {
        return;
    }
    let at = usize::from(u16::from_le_bytes([lo, hi])) % wire.len();
    match kind % 5 {
        0 => wire[at] ^= 1 << (value % 8),
        1 => {
            wire.remove(at);
        }
        2 => wire.insert(at, value),
        3 => wire.truncate(at),
        _ => wire[at] = value,
    }
}

fuzz_target!(|data: &[u8]| {
    let [chunk_seed, op_seed, rest @ ..] = data else {
        return;
    };
    let op_count = usize::from(op_seed % (MAX_OPS + 1));
    let Some((ops, message_bytes)) = rest.split_at_checked(op_count * OP_LEN) else {
        return;
    };
    let message = match postcard::take_from_bytes::<Message>(message_bytes) {
        Ok((message, _)) => message,
        Err(_) => fallback_message(message_bytes),
    };
    let mut frame = [0u8; MAX_FRAME_LEN];
    let Ok(n) = encode_frame(&message, &mut frame) else {
        return; // too large for one frame: the encoder refuses it, nothing to send
    };
    let original_wire = frame[..n].to_vec();
    let original_payload = payload(&message);

    let mut wire = original_wire.clone();
    for op in ops.chunks_exact(OP_LEN) {
        apply(op, &mut wire);
    }
    let intact = wire == original_wire;

    let chunk = usize::from(chunk_seed % 13) + 1;
    let mut decoder = FrameDecoder::new();
    let mut accepted = 0usize;
    for piece in wire.chunks(chunk) {
        decoder.push_slice(piece, |result| {
            if let Ok(decoded) = result {
                accepted += 1;
                assert_eq!(
                    payload(&decoded),
                    original_payload,
                    "a corrupted frame was accepted as a different message \
                     (original {message:?}, decoded {decoded:?}, wire {wire:02x?})"
                );
            }
        });
    }
    // Close any frame left open by a truncation, as the next frame's leading delimiter would.
    if let Some(Ok(decoded)) = decoder.push(0) {
        accepted += 1;
        assert_eq!(
            payload(&decoded),
            original_payload,
            "a truncated frame was accepted as a different message"
        );
    }
    if intact {
        assert_eq!(accepted, 1, "an intact frame was not decoded exactly once");
    }
    assert!(accepted <= 1, "one frame decoded {accepted} times");

    let probe = Message::StatusRequest;
    let n = encode_frame(&probe, &mut frame).expect("probe encodes");
    let mut last = None;
    decoder.push_slice(&frame[..n], |r| last = Some(r));
    assert_eq!(
        last,
        Some(Ok(probe)),
        "the link did not recover after a corrupted frame"
    );
});
