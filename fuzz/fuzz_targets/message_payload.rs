//! Frames arbitrary payloads with a correct CRC, so the fuzzer gets past the
//! CRC (random bytes never do) and explores message decoding itself, then
//! hands every accepted message to the controller application.
//!
//! Input: payloads separated by the byte pair `0xFF 0xFE`; each one is sent as
//! `0x00, COBS(payload ++ crc32), 0x00`. The session is opened with a valid
//! `Hello` first, so cell configurations (`Configure`), camera frames and
//! sensor samples reach the pick controller.
//!
//! Properties, on every input:
//! - the decoder's verdict matches postcard's: it accepts a payload exactly when
//!   the payload is one whole message no longer than `MAX_MESSAGE_LEN`, and then
//!   returns that message;
//! - the controller never panics on any sequence of messages (including
//!   configurations with NaN, infinite, zero or huge values), and answers a
//!   status request afterwards.
#![no_main]

use heapless::{String, Vec as HVec};
use libfuzzer_sys::fuzz_target;
use shared::app::{ControllerApp, MAX_REPLIES};
use shared::protocol::{DecodeError, FrameDecoder, Message, MAX_MESSAGE_LEN, PROTOCOL_VERSION};

const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// COBS stuffing (Cheshire and Baker 1999): each zero byte is replaced by the
/// distance to the next one; a code of 0xFF means 254 data bytes and no zero.
fn cobs_encode(raw: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8];
    let mut code_at = 0usize;
    for &byte in raw {
        if byte == 0 {
            out[code_at] = (out.len() - code_at) as u8;
            code_at = out.len();
            out.push(0);
        } else {
            out.push(byte);
            if out.len() - code_at == 0xFF {
                out[code_at] = 0xFF;
                code_at = out.len();
                out.push(0);
            }
        }
    }
    out[code_at] = (out.len() - code_at) as u8;
    out
}

fn frame(payload: &[u8]) -> Vec<u8> {
    let mut raw = payload.to_vec();
    raw.extend_from_slice(&CRC32.checksum(payload).to_le_bytes());
    let mut wire = vec![0u8];
    wire.extend(cobs_encode(&raw));
    wire.push(0);
    wire
}

fn decode_one(decoder: &mut FrameDecoder, wire: &[u8]) -> Option<Result<Message, DecodeError>> {
    let mut last = None;
    decoder.push_slice(wire, |r| last = Some(r));
    last
}

fn reencode(message: &Message) -> std::vec::Vec<u8> {
    let mut buf = [0u8; MAX_MESSAGE_LEN];
    postcard::to_slice(message, &mut buf)
        .expect("an accepted message serialises")
        .to_vec()
}

fuzz_target!(|data: &[u8]| {
    let mut app = ControllerApp::new("fuzz", 1000);
    let mut replies: HVec<Message, MAX_REPLIES> = HVec::new();
    let hello = Message::Hello {
        protocol_version: PROTOCOL_VERSION,
        peer_name: String::try_from("fuzzer").expect("short name"),
    };
    app.on_message(&hello, &mut replies);

    let mut decoder = FrameDecoder::new();
    let mut start = 0usize;
    let mut payloads = std::vec::Vec::new();
    let mut i = 0usize;
    while i + 1 < data.len() {
        if data[i] == 0xFF && data[i + 1] == 0xFE {
            payloads.push(&data[start..i]);
            start = i + 2;
            i += 2;
        } else {
            i += 1;
        }
    }
    payloads.push(&data[start..]);

    for payload in payloads.into_iter().take(64) {
        let result = decode_one(&mut decoder, &frame(payload));
        let oracle = match postcard::take_from_bytes::<Message>(payload) {
            Ok((message, [])) if payload.len() <= MAX_MESSAGE_LEN => Some(message),
            _ => None,
        };
        match (result, oracle) {
            // Every frame carries at least its CRC, so a closed frame always has a verdict.
            (None, _) => panic!("a complete frame produced no result"),
            (Some(Ok(decoded)), Some(expected)) => {
                assert_eq!(
                    reencode(&decoded),
                    reencode(&expected),
                    "decoded a different message"
                );
                replies.clear();
                app.on_message(&decoded, &mut replies);
                app.run_background();
            }
            (Some(Ok(decoded)), None) => {
                panic!("accepted a payload postcard refuses: {payload:02x?} -> {decoded:?}")
            }
            (Some(Err(error)), Some(expected)) => {
                panic!("refused a valid message {expected:?} ({error:?})")
            }
            (Some(Err(error)), None) => {
                replies.clear();
                let _ = app.on_decode_error(&error);
            }
        }
    }

    replies.clear();
    app.on_message(&Message::StatusRequest, &mut replies);
    assert!(
        replies.iter().any(|m| matches!(m, Message::Status(_))),
        "no status after the session: {replies:?}"
    );
});
