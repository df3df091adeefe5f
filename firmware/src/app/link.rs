//! The host link: bytes arrive in arbitrary chunks, `shared::protocol`'s
//! `FrameDecoder` turns them into messages, `shared::app::LinkResponder`
//! answers each (or reports and counts a rejected frame), and the replies go
//! back framed. The same responder runs in host-sim's in-process link, so the
//! emulator test and the in-process test check the same logic.

use embedded_io_async::{Read, Write};
use shared::app::LinkResponder;
use shared::protocol::{encode_frame, FrameDecoder, Message, MAX_FRAME_LEN};

use super::control_tick::{TickReader, CONTROL_RATE_HZ};
use crate::board::active;

/// Bytes taken from the UART per `read` at most.
const READ_CHUNK: usize = 64;

#[embassy_executor::task]
pub async fn link_task(board_name: &'static str, mut serial: active::Serial) {
    let mut decoder = FrameDecoder::new();
    let mut responder = LinkResponder::new(board_name, CONTROL_RATE_HZ);
    let mut ticks = TickReader::new();
    let mut chunk = [0u8; READ_CHUNK];
    let mut frame = [0u8; MAX_FRAME_LEN];
    defmt::info!("link up on {}", board_name);
    loop {
        let n = match serial.read(&mut chunk).await {
            Ok(n) => n,
            Err(e) => {
                defmt::warn!("link read error {}", defmt::Debug2Format(&e));
                continue;
            }
        };
        for &byte in chunk.iter().take(n) {
            let Some(decoded) = decoder.push(byte) else {
                continue;
            };
            let reply = match decoded {
                Ok(message) => {
                    responder.set_control_ticks(ticks.control_ticks());
                    let reply = responder.handle(&message);
                    // Only an acknowledged sample (open session) reaches the encoders:
                    // a refused frame changes nothing.
                    if let (Message::SensorSample(sample), Some(Message::Ack { .. })) =
                        (&message, &reply)
                    {
                        active::on_host_sensor_sample(&sample.joint_counts);
                    }
                    reply
                }
                Err(e) => {
                    defmt::warn!("link: frame rejected: {}", defmt::Display2Format(&e));
                    Some(responder.on_decode_error(&e))
                }
            };
            let Some(reply) = reply else { continue };
            let written = match encode_frame(&reply, &mut frame) {
                Ok(len) => frame.get(..len),
                Err(e) => {
                    defmt::error!("link: cannot encode reply: {}", defmt::Display2Format(&e));
                    None
                }
            };
            if let Some(bytes) = written {
                if let Err(e) = serial.write_all(bytes).await {
                    defmt::warn!("link write error {}", defmt::Debug2Format(&e));
                }
            }
        }
    }
}
