//! Feeds arbitrary bytes, in arbitrary chunkings, to the protocol decoder.
//!
//! Properties checked on every input: no panic, no hang; every message the
//! decoder accepts re-encodes to a frame that decodes to the same message; and
//! a valid frame sent after the garbage is always decoded intact (the link
//! recovers).
#![no_main]

use libfuzzer_sys::fuzz_target;
use shared::protocol::{encode_frame, FrameDecoder, Message, MAX_FRAME_LEN};

fn wire(message: &Message) -> Option<([u8; MAX_FRAME_LEN], usize)> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode_frame(message, &mut buf).ok()?;
    Some((buf, n))
}

fuzz_target!(|data: &[u8]| {
    let Some((&chunk_seed, bytes)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(chunk_seed % 17) + 1;
    let mut decoder = FrameDecoder::new();
    for piece in bytes.chunks(chunk) {
        decoder.push_slice(piece, |result| {
            if let Ok(message) = result {
                let (frame, n) = wire(&message).expect("an accepted message re-encodes");
                let mut check = FrameDecoder::new();
                let mut again = None;
                check.push_slice(&frame[..n], |r| again = Some(r));
                let again = again
                    .expect("re-encoded frame completes")
                    .expect("and decodes");
                let (frame2, n2) = wire(&again).expect("re-encodes");
                assert_eq!(
                    &frame[..n],
                    &frame2[..n2],
                    "decode/encode is not a fixed point"
                );
            }
        });
    }
    let probe = Message::StatusRequest;
    let (frame, n) = wire(&probe).expect("probe encodes");
    let mut last = None;
    decoder.push_slice(&frame[..n], |r| last = Some(r));
    assert_eq!(
        last,
        Some(Ok(probe)),
        "the link did not recover after garbage"
    );
});
