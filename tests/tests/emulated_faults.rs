//! Faults during a pick with the firmware in the loop (issue 7): the emulated
//! board's firmware is the controller, host-sim's world injects the fault, in
//! lock step over the emulated UART. Each fault strikes early in the run, so
//! the pick stops within seconds of simulated time and the test stays short;
//! the same fault run in process must end the same way, at the same time.
//! The faults run in one boot, one after the other: each after the first is
//! also the documented restart (a new session and configuration after a stop).

use std::time::Duration;

use host_sim::link::FramedLink;
use host_sim::pick::faults::violations;
use host_sim::pick::record::PickResult;
use host_sim::pick::runner::{run_pick, run_pick_in_process};
use host_sim::scenario::pick::{FaultWindow, MissedCounts, PickExperiment, PickScenarioFile};
use integration_tests::qemu::{firmware_elf_path, QemuBoard};
use integration_tests::stopping_at;
use shared::protocol::FaultCause;

const SEED: u64 = 1;

fn turning() -> PickExperiment {
    PickScenarioFile::embedded_default()
        .and_then(|file| file.experiment("turning").cloned())
        .unwrap_or_else(|e| panic!("{e:#}"))
}

#[test]
fn the_emulated_firmware_stops_safely_on_a_stall_a_counter_glitch_and_a_lost_camera() {
    let mut stall = turning();
    stall.faults.control_stall = Some(FaultWindow {
        at_s: 4.0,
        duration_s: 0.3,
    });
    let mut glitch = turning();
    glitch.faults.missed_counts = Some(MissedCounts {
        at_s: 3.0,
        counts: 120,
        instant: true,
    });
    let mut blind = turning();
    blind.faults.vision_outage = Some(FaultWindow {
        at_s: 3.0,
        duration_s: 3.0,
    });
    let cases = [
        (stall, FaultCause::ControlStall),
        (glitch, FaultCause::ConveyorEncoder),
        (blind, FaultCause::VisionStale),
    ];

    let elf = firmware_elf_path();
    let mut board = QemuBoard::start(&elf).unwrap_or_else(|e| panic!("{e}"));
    let tcp = board.connect_uart();
    let mut link = FramedLink::new(tcp);
    for (experiment, cause) in &cases {
        let emulated = run_pick(experiment, SEED, &mut link).unwrap_or_else(|e| {
            board.check_running().unwrap_or_else(|q| panic!("{q}"));
            panic!("{cause:?} against the emulated firmware: {e:#}")
        });
        let in_process = run_pick_in_process(experiment, SEED).unwrap_or_else(|e| panic!("{e:#}"));
        println!(
            "{cause:?}: emulated {:?}, stopping at {:.3} s, {:.1} s simulated; in process {:?} at {:.3} s",
            emulated.result,
            stopping_at(&emulated),
            emulated.duration_s,
            in_process.result,
            stopping_at(&in_process)
        );
        assert_eq!(emulated.result, PickResult::Fault(*cause));
        assert_eq!(in_process.result, emulated.result);
        let broken = violations(&emulated);
        assert!(broken.is_empty(), "{cause:?}: {broken:?}");
        assert!(
            (stopping_at(&emulated) - stopping_at(&in_process)).abs() < 0.05,
            "{cause:?}: stopped at {} s emulated, {} s in process",
            stopping_at(&emulated),
            stopping_at(&in_process)
        );
    }
    assert!(
        board.shutdown(Duration::from_secs(5)),
        "qemu-system-arm did not exit within 5 s of being killed"
    );
}
