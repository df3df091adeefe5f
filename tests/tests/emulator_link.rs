//! The link between host and controller, end to end: the emulated-board
//! firmware in qemu-system-arm over its UART socket, and the same exchange
//! through host-sim's in-process link.

use std::time::Duration;

use integration_tests::link::check::Session;
use integration_tests::link::{ByteLink, InProcessLink};
use integration_tests::qemu::{firmware_elf_path, QemuBoard};

/// Frames exchanged (the issue asks for at least 10 000).
const FRAMES: u64 = 10_000;
/// Frames in flight at most.
const WINDOW: usize = 16;
/// Corruption rounds (each injects a garbage run, a flipped-bit frame and an
/// oversized run).
const CORRUPTION_ROUNDS: u32 = 15;
const SEED: u64 = 0x00C0_FFEE;
const REPLY_TIMEOUT: Duration = Duration::from_secs(10);

/// Handshake, long exchange, corruption, recovery; returns the session for
/// link-specific checks.
fn exercise<L: ByteLink>(link: L, expected_board: &str) -> Session<L> {
    let mut session =
        Session::open(link, REPLY_TIMEOUT).unwrap_or_else(|e| panic!("handshake failed: {e}"));
    assert_eq!(session.handshake.board_name, expected_board);
    assert_eq!(session.handshake.control_rate_hz, 1_000);
    assert_eq!(
        session.handshake.protocol_version,
        shared::protocol::PROTOCOL_VERSION
    );

    let before = session.status().unwrap_or_else(|e| panic!("status: {e}"));
    let summary = session
        .exchange(FRAMES, WINDOW, SEED)
        .unwrap_or_else(|e| panic!("exchange over {}: {e}", session.describe()));
    assert_eq!(summary.data_frames + summary.status_requests, FRAMES);
    for (kind, count) in [
        ("camera", summary.camera_frames),
        ("sensor", summary.sensor_samples),
        ("actuator", summary.actuator_commands),
        ("status", summary.status_requests),
    ] {
        assert!(count > 100, "too few {kind} frames in the mix: {count}");
    }
    eprintln!(
        "{}: {FRAMES} frames in {:.2} s ({:.0} frames/s), {} B sent, {} B received, \
         round trip p50 {:?} p99 {:?} max {:?}",
        session.describe(),
        summary.elapsed.as_secs_f64(),
        summary.frames_per_second(),
        summary.bytes_sent,
        summary.bytes_received,
        summary.round_trip_p50,
        summary.round_trip_p99,
        summary.round_trip_max
    );

    let corruption = session
        .inject_corruption(CORRUPTION_ROUNDS, SEED ^ 0xBAD)
        .unwrap_or_else(|e| panic!("corruption over {}: {e}", session.describe()));
    assert_eq!(corruption.garbage_runs, CORRUPTION_ROUNDS);
    assert_eq!(corruption.flipped_frames, CORRUPTION_ROUNDS);
    assert_eq!(corruption.oversized_runs, CORRUPTION_ROUNDS);
    assert_eq!(
        corruption.rejected_after,
        before.frames_rejected + 3 * CORRUPTION_ROUNDS
    );

    // The link carries on normally after the injections.
    session
        .exchange(500, WINDOW, SEED + 1)
        .unwrap_or_else(|e| panic!("exchange after corruption: {e}"));
    let after = session.status().unwrap_or_else(|e| panic!("status: {e}"));
    assert_eq!(after.frames_rejected, corruption.rejected_after);
    assert_eq!(after.frames_unexpected, before.frames_unexpected);
    assert!(
        after.frames_received > before.frames_received + FRAMES as u32,
        "frames_received {} -> {}",
        before.frames_received,
        after.frames_received
    );
    session
}

#[test]
fn emulated_firmware_exchanges_frames_and_recovers_from_corruption() {
    let elf = firmware_elf_path();
    let mut board = QemuBoard::start(&elf).unwrap_or_else(|e| panic!("{e}"));
    let link = board.connect_uart();
    board.check_running().unwrap_or_else(|e| panic!("{e}"));

    let started = std::time::Instant::now();
    let mut session = exercise(link, "mps2-an386");
    // The board's time driver (embassy-time on the CMSDK dual timer) has a
    // 32-bit timebase that first wraps 2 s after boot, well inside this test.
    // QEMU's virtual clock follows the host clock without icount and starts
    // when the link connects, so the firmware's uptime must track the wall
    // time since then: a lost wrap would stall it, a doubled one would jump
    // it by ~171 s. The lower bound is loose because the host may be loaded.
    let uptime_ms = session
        .runtime_report()
        .unwrap_or_else(|e| panic!("runtime report: {e}"))
        .uptime_us
        / 1_000;
    let wall_ms = started.elapsed().as_millis() as u64;
    eprintln!("firmware uptime {uptime_ms} ms over {wall_ms} ms of wall time");
    assert!(
        wall_ms > 2_500,
        "the test ended before the timebase's first wrap"
    );
    assert!(
        uptime_ms >= wall_ms / 4,
        "uptime {uptime_ms} ms after {wall_ms} ms"
    );
    assert!(
        uptime_ms <= wall_ms + 2_000,
        "uptime {uptime_ms} ms after {wall_ms} ms: the timebase jumped"
    );

    board.check_running().unwrap_or_else(|e| panic!("{e}"));
    drop(session);
    assert!(
        board.shutdown(Duration::from_secs(5)),
        "qemu-system-arm did not exit within 5 s of being killed"
    );
}

#[test]
fn in_process_link_runs_the_same_exchange() {
    exercise(InProcessLink::new(), "in-process");
}

#[test]
fn missing_firmware_elf_is_reported_with_build_instructions() {
    let missing = std::env::temp_dir().join("no-such-firmware.elf");
    let err = match QemuBoard::start(&missing) {
        Ok(_) => panic!("booting a missing ELF must fail"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("not found"), "{err}");
    assert!(err.contains("--features board-qemu"), "{err}");
}
