//! `host-sim link-check`: connects one of the three ways, handshakes,
//! exchanges frames, optionally injects corruption, and prints a summary.

use std::time::Duration;

use anyhow::Context;
use clap::ArgGroup;

use crate::link::check::{CheckError, Session};
use crate::link::{ByteLink, InProcessLink, SerialPortLink, TcpLink};

#[derive(clap::Args, Debug, Clone)]
#[command(group(ArgGroup::new("target").required(true).args(["in_process", "tcp", "serial"])))]
pub struct Args {
    /// The controller logic linked into this process (no emulator, no board).
    #[arg(long)]
    pub in_process: bool,
    /// The emulator's UART socket, e.g. 127.0.0.1:4321 (see scripts/qemu-run).
    #[arg(long, value_name = "HOST:PORT")]
    pub tcp: Option<String>,
    /// A serial device, e.g. /dev/ttyACM0.
    #[arg(long, value_name = "PATH")]
    pub serial: Option<String>,
    /// Serial baud rate (the STM32F407 firmware uses 115200).
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Frames to exchange after the handshake.
    #[arg(long, default_value_t = 1_000)]
    pub frames: u64,
    /// Frames in flight at most (pipelining window).
    #[arg(long, default_value_t = 8)]
    pub window: usize,
    /// Corruption rounds to inject after the exchange (3 bad frames each).
    #[arg(long, default_value_t = 0)]
    pub corrupt: u32,
    /// Seed of the generated traffic.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Longest wait for one reply, milliseconds.
    #[arg(long, default_value_t = 2_000)]
    pub reply_timeout_ms: u64,
}

/// Runs the check; the error says what went wrong and where.
pub fn run(args: &Args) -> anyhow::Result<()> {
    check(args).context("link-check failed")
}

fn check(args: &Args) -> Result<(), CheckError> {
    let timeout = Duration::from_millis(args.reply_timeout_ms);
    if args.in_process {
        run_on(InProcessLink::new(), args, timeout)
    } else if let Some(addr) = &args.tcp {
        run_on(TcpLink::connect(addr, timeout)?, args, timeout)
    } else if let Some(path) = &args.serial {
        run_on(SerialPortLink::open(path, args.baud)?, args, timeout)
    } else {
        Err(CheckError::Config(
            "choose --in-process, --tcp HOST:PORT or --serial PATH".into(),
        ))
    }
}

fn run_on<L: ByteLink>(link: L, args: &Args, timeout: Duration) -> Result<(), CheckError> {
    let mut session = Session::open(link, timeout)?;
    let h = &session.handshake;
    println!(
        "link: {}\nhandshake: board {:?}, firmware {}, protocol v{}, control {} Hz, max frame {} B",
        session.describe(),
        h.board_name,
        h.firmware_version,
        h.protocol_version,
        h.control_rate_hz,
        h.max_frame_len
    );
    let before = session.status()?;
    let summary = session.exchange(args.frames, args.window, args.seed)?;
    println!(
        "exchange: {} frames ({} camera, {} sensor, {} actuator, {} status) all acknowledged in order \
         in {:.3} s ({:.0} frames/s, window {}); {} B sent, {} B received; \
         round trip p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
        summary.data_frames + summary.status_requests,
        summary.camera_frames,
        summary.sensor_samples,
        summary.actuator_commands,
        summary.status_requests,
        summary.elapsed.as_secs_f64(),
        summary.frames_per_second(),
        args.window,
        summary.bytes_sent,
        summary.bytes_received,
        summary.round_trip_p50.as_secs_f64() * 1e3,
        summary.round_trip_p99.as_secs_f64() * 1e3,
        summary.round_trip_max.as_secs_f64() * 1e3
    );
    if args.corrupt > 0 {
        let c = session.inject_corruption(args.corrupt, args.seed ^ 0x5EED)?;
        println!(
            "corruption: {} garbage runs, {} flipped-bit frames and {} oversized runs rejected and \
             reported (frames_rejected {} -> {}), link recovered ({} acks after injections)",
            c.garbage_runs,
            c.flipped_frames,
            c.oversized_runs,
            c.rejected_before,
            c.rejected_after,
            c.recovered_acks
        );
    }
    let after = session.status()?;
    println!(
        "status: control_ticks {} -> {}, frames_received {}, frames_rejected {}, frames_unexpected {}, mode {:?}",
        before.control_ticks,
        after.control_ticks,
        after.frames_received,
        after.frames_rejected,
        after.frames_unexpected,
        after.mode
    );
    println!("link-check: OK");
    Ok(())
}
