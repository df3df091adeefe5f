//! The noisy line with the firmware in the loop (issue 7): 1e-3 of the bytes
//! flipped, dropped or inserted both ways between host-sim's world and the
//! emulated board, in lock step over the emulated UART. A lost command costs
//! the firmware nothing (it answers a sample sent again with the same command
//! and runs no second period), so the run must end as the same run in process
//! does: a vision outage stops the pick at the same period. No damaged frame
//! is taken for a message, and the firmware's telemetry counts every frame it
//! refused.

use std::time::Duration;

use host_sim::link::{FramedLink, NoiseConfig, NoisyLink};
use host_sim::pick::faults::{violations, NOISY_LINK_BYTE_ERROR_RATE};
use host_sim::pick::record::PickResult;
use host_sim::pick::runner::{run_pick, run_pick_in_process_noisy};
use host_sim::scenario::pick::{FaultWindow, PickScenarioFile};
use integration_tests::qemu::{firmware_elf_path, QemuBoard};
use integration_tests::stopping_at;
use shared::protocol::FaultCause;

const SEED: u64 = 1;

#[test]
fn the_emulated_firmware_rides_a_noisy_line_and_counts_every_refusal() {
    let mut blind =
        PickScenarioFile::default_experiment("turning").unwrap_or_else(|e| panic!("{e:#}"));
    // Short: the camera goes dark at 3 s and the pick stops for VisionStale.
    blind.faults.vision_outage = Some(FaultWindow {
        at_s: 3.0,
        duration_s: 3.0,
    });
    let noise = NoiseConfig {
        byte_error_rate: NOISY_LINK_BYTE_ERROR_RATE,
        seed: 7,
    };

    let elf = firmware_elf_path();
    let mut board = QemuBoard::start(&elf).unwrap_or_else(|e| panic!("{e}"));
    let tcp = board.connect_uart();
    let mut link = FramedLink::new(NoisyLink::new(tcp, noise));
    let emulated = run_pick(&blind, SEED, &mut link).unwrap_or_else(|e| {
        board.check_running().unwrap_or_else(|q| panic!("{q}"));
        panic!("the noisy pick against the emulated firmware: {e:#}")
    });
    let in_process =
        run_pick_in_process_noisy(&blind, SEED, noise).unwrap_or_else(|e| panic!("{e:#}"));
    let counts = emulated.link.noise.unwrap_or_default();
    println!(
        "emulated: {:?}, stopping at {:.3} s; in process {:?} at {:.3} s; link {:?}",
        emulated.result,
        stopping_at(&emulated),
        in_process.result,
        stopping_at(&in_process),
        emulated.link
    );
    assert_eq!(emulated.result, PickResult::Fault(FaultCause::VisionStale));
    assert_eq!(in_process.result, emulated.result);
    assert!(
        (stopping_at(&emulated) - stopping_at(&in_process)).abs() < 0.05,
        "stopped at {} s emulated, {} s in process",
        stopping_at(&emulated),
        stopping_at(&in_process)
    );
    let broken = violations(&emulated);
    assert!(broken.is_empty(), "{broken:?}");
    // The line was noisy both ways, and nothing damaged got through.
    for direction in [counts.to_controller, counts.to_host] {
        assert!(direction.frames_rejected > 50, "{direction:?}");
        assert_eq!(direction.forged, 0, "{direction:?}");
    }
    assert!(counts.telemetry.checked > 100, "{counts:?}");
    assert_eq!(counts.telemetry.undercounted, 0, "{counts:?}");
    assert!(emulated.link.samples_resent > 50, "{:?}", emulated.link);
    assert!(
        board.shutdown(Duration::from_secs(5)),
        "qemu-system-arm did not exit within 5 s of being killed"
    );
}
