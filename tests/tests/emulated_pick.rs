//! The pick with the firmware in the loop: the emulated-board firmware in
//! qemu-system-arm (`-icount shift=0`, so it counts instructions) is the
//! controller, host-sim's world is the plant, in lock step over the emulated
//! UART. The same seed run against the in-process controller must give the
//! same outcome, and the firmware's own report gives the control cycle's
//! worst cost, the worker's jobs and the stack's high-water mark.

use std::time::{Duration, Instant};

use host_sim::link::{board_timing, FramedLink};
use host_sim::pick::record::{PickResult, PickRun};
use host_sim::pick::runner::{run_pick, run_pick_in_process};
use host_sim::scenario::pick::PickScenarioFile;
use integration_tests::qemu::{firmware_elf_path, QemuBoard};
use shared::protocol::{CostUnit, Message, RuntimeReport};

/// The emulated run's experiment: the paper's experiment 2 with the 7 cm part
/// (the shortest of the four; the conveyor stops before the pick).
const EXPERIMENT: &str = "experiment-2-7cm";
const SEED: u64 = 1;

/// What the firmware is held to here: the control-period goal, 15,000
/// instructions (the worst period must fit 10 kHz at 168 MHz with room for
/// the interrupts). Measured in this run with the firmware built at opt-level
/// 3: worst 14,360 (the pick's first period, which plans the search's first
/// arc, after 2,810 periods of homing), mean 10,263 (homing's periods
/// included).
const CONTROL_CYCLE_LIMIT: u32 = 15_000;
/// The RAM budget is 128 KiB of static data and stack; the STM32 image's
/// static RAM is 38,440 bytes (`scripts/build-firmware`), which leaves 90 KiB
/// of stack. The deepest stack seen is the worker's final estimate (the
/// bundle adjustment over the 256-frame store) preempted by the link and the
/// control loop, 23,192 bytes in this run (how deep a run gets depends on
/// where the interrupts land in the bundle adjustment); the limit catches a
/// regression well before the budget.
const STACK_LIMIT_BYTES: u32 = 32 * 1024;
/// The calibrator's per-frame update on the M4F: validation, the conic's
/// recursive least squares and, once its stores are full, folding one frame
/// (and a sighting) into its normal equations: issue 20's goal. This run
/// measures 128,120, the update's own instructions; the interrupt handlers
/// that preempt it are charged to themselves (`board::interrupt_time`):
/// counted with them, the figure followed the host's timing and ranged from
/// 234,240 to 317,600 over runs of the same firmware on the same data.
const OBSERVATION_LIMIT: u32 = 200_000;

/// The most expensive estimate update allowed, instructions: under one second
/// at 168 MHz (issue 20's goal). This run measures 61.7 million for the
/// preliminary estimate and 120.7 million for the final one.
const ESTIMATE_LIMIT: u32 = 150_000_000;

fn runtime_report<L: host_sim::link::ByteLink>(link: &mut FramedLink<L>) -> RuntimeReport {
    link.send(&Message::RuntimeReportRequest)
        .unwrap_or_else(|e| panic!("runtime report request: {e}"));
    loop {
        match link.recv(Duration::from_secs(30), "RuntimeReport") {
            Ok(Message::RuntimeReport(report)) => return report,
            // What the last control period queued behind its command.
            Ok(Message::Telemetry(_) | Message::CalibrationReport(_)) => continue,
            Ok(other) => panic!("expected a RuntimeReport, got {other:?}"),
            Err(e) => panic!("runtime report: {e}"),
        }
    }
}

fn norm(e: [f64; 3]) -> f64 {
    (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()
}

fn summary(run: &PickRun) -> String {
    let grasp = run.grasp.as_ref();
    format!(
        "{:?} after {:.1} s, calibrated at {:?} s, grasp error {:?} m, estimate error {:?} m",
        run.result,
        run.duration_s,
        run.calibrated_after_s,
        grasp.map(|g| g.position_error_m),
        grasp.and_then(|g| g.estimate_error_m)
    )
}

#[test]
fn the_emulated_firmware_picks_the_part_as_the_in_process_controller_does() {
    let experiment = PickScenarioFile::embedded_default()
        .and_then(|file| file.experiment(EXPERIMENT).cloned())
        .unwrap_or_else(|e| panic!("{e:#}"));
    let elf = firmware_elf_path();
    let mut board = QemuBoard::start_counting_instructions(&elf).unwrap_or_else(|e| panic!("{e}"));
    let tcp = board.connect_uart();
    let mut link = FramedLink::new(tcp);
    let started = Instant::now();
    let emulated = run_pick(&experiment, SEED, &mut link).unwrap_or_else(|e| {
        board.check_running().unwrap_or_else(|q| panic!("{q}"));
        panic!("the pick against the emulated firmware: {e:#}")
    });
    let wall = started.elapsed();
    let report = runtime_report(&mut link);
    board.check_running().unwrap_or_else(|e| panic!("{e}"));

    let in_process = run_pick_in_process(&experiment, SEED).unwrap_or_else(|e| panic!("{e:#}"));
    eprintln!(
        "emulated firmware: {} [{:.0} s wall]",
        summary(&emulated),
        wall.as_secs_f64()
    );
    eprintln!("in process:        {}", summary(&in_process));
    eprintln!("firmware report: {report:?}");

    assert_eq!(
        emulated.result,
        PickResult::Success,
        "{}",
        summary(&emulated)
    );
    let grasp = emulated
        .grasp
        .as_ref()
        .unwrap_or_else(|| panic!("no grasp"));
    // Within the gripper's capture (5 mm horizontally, 10 mm vertically),
    // with room: the disc's height told to 3 mm puts 4 to 5 mm in the height.
    let [x, y, z] = grasp.estimate_error_m.unwrap_or([f64::INFINITY; 3]);
    assert!(
        x.hypot(y) < 0.004 && z.abs() < 0.008,
        "estimate error {x}, {y}, {z} m"
    );
    let [x, y, z] = grasp.position_error_m;
    assert!(
        x.hypot(y) < 0.004 && z.abs() < 0.008,
        "grasp error {x}, {y}, {z} m"
    );

    // The same code on the same inputs, and every job result applied at its
    // fixed due time: the same run, up to rounding. The M4's arithmetic and
    // the host's differ in the last bit of some f32 results (seen from the
    // first control period on), and the closed loop carries that on, so the
    // comparison is of outcomes, with tolerances far below what matters to
    // a pick: the same phases within 50 ms, the same calibrations within
    // 0.1 mm and 0.1 mrad, the same grasp within 5 mm.
    assert_eq!(emulated.result, in_process.result);
    // A clean link: nothing refused either way. (Samples may be sent again
    // while the firmware waits for a job's result in lock step; the copies
    // are coalesced or answered with the same command.)
    assert_eq!(emulated.link.replies_refused, 0, "{:?}", emulated.link);
    assert_eq!(emulated.link.refusals_reported, 0, "{:?}", emulated.link);
    assert_eq!(
        emulated.link.controller_frames_rejected, 0,
        "{:?}",
        emulated.link
    );
    assert_eq!(
        emulated.phases.len(),
        in_process.phases.len(),
        "phase sequences differ"
    );
    for (a, b) in emulated.phases.iter().zip(&in_process.phases) {
        assert_eq!(a.phase, b.phase, "phase sequences differ");
        assert!((a.t_s - b.t_s).abs() <= 0.05, "{a:?} vs {b:?}");
    }
    assert_eq!(emulated.calibrations.len(), in_process.calibrations.len());
    for (a, b) in emulated.calibrations.iter().zip(&in_process.calibrations) {
        let (a, b) = (&a.report, &b.report);
        assert_eq!(a.time_us, b.time_us);
        assert_eq!(a.frames_used, b.frames_used);
        assert_eq!(a.effector_frames_used, b.effector_frames_used);
        for (x, y) in a.base_translation_m.iter().zip(&b.base_translation_m) {
            assert!((x - y).abs() < 1e-4, "base translation {a:?} vs {b:?}");
        }
        for (x, y) in a.part_rotating_m.iter().zip(&b.part_rotating_m) {
            assert!((x - y).abs() < 1e-4, "part {a:?} vs {b:?}");
        }
        assert!((a.base_yaw_rad - b.base_yaw_rad).abs() < 1e-4);
        assert!((a.part_yaw_rotating_rad - b.part_yaw_rotating_rad).abs() < 1e-4);
    }
    let in_process_grasp = in_process
        .grasp
        .as_ref()
        .unwrap_or_else(|| panic!("no grasp"));
    assert_eq!(grasp.succeeded, in_process_grasp.succeeded);
    let gap = norm([
        grasp.position_error_m[0] - in_process_grasp.position_error_m[0],
        grasp.position_error_m[1] - in_process_grasp.position_error_m[1],
        grasp.position_error_m[2] - in_process_grasp.position_error_m[2],
    ]);
    assert!(gap < 0.005, "grasps {gap} m apart");

    assert_eq!(report.unit, CostUnit::Instructions);
    // 47,751 periods since the search halts once the marks have crossed the view.
    assert!(report.control_ticks > 40_000, "{report:?}");
    assert!(report.jobs_run >= 3, "{report:?}");
    assert!(
        report.control_worst >= report.control_mean && report.control_mean > 1_000,
        "{report:?}"
    );
    assert!(
        report.control_worst <= CONTROL_CYCLE_LIMIT,
        "worst control cycle {} instructions",
        report.control_worst
    );
    assert!(
        report.stack_used_bytes > 1_024 && report.stack_used_bytes < report.stack_size_bytes,
        "stack {} of {} bytes",
        report.stack_used_bytes,
        report.stack_size_bytes
    );
    assert!(report.stack_used_bytes <= STACK_LIMIT_BYTES, "{report:?}");
    // The jobs' costs that `host-sim run --link in-process:stm32f407` delays
    // results by (host_sim::link::board_timing): within 10 % of this run's,
    // so that model is re-measured when the jobs change.
    for (kind, measured, model) in [
        (
            "preliminary estimate",
            report.job_worst.estimate_preliminary,
            board_timing::MEASURED_ESTIMATE_PRELIMINARY_INSTRUCTIONS,
        ),
        (
            "final estimate",
            report.job_worst.estimate_final,
            board_timing::MEASURED_ESTIMATE_FINAL_INSTRUCTIONS,
        ),
        (
            "plan",
            report.job_worst.plan,
            board_timing::MEASURED_PLAN_INSTRUCTIONS,
        ),
    ] {
        let ratio = f64::from(measured) / model as f64;
        assert!(
            (0.9..=1.1).contains(&ratio),
            "{kind}: {measured} instructions, the board-timing model says {model}: update it"
        );
    }
    for (kind, measured) in [
        (
            "preliminary estimate",
            report.job_worst.estimate_preliminary,
        ),
        ("final estimate", report.job_worst.estimate_final),
    ] {
        assert!(
            measured > 0 && measured <= ESTIMATE_LIMIT,
            "{kind}: {measured} instructions, over the budget of {ESTIMATE_LIMIT}"
        );
    }
    // The calibrator's per-frame update, folding included once its stores
    // are full (issue 20's budget: 200,000 instructions a frame).
    assert!(
        report.job_worst.observation > 0 && report.job_worst.observation <= OBSERVATION_LIMIT,
        "worst observation {} instructions",
        report.job_worst.observation
    );
    // Lock step: the loop waits for a due result instead of missing a deadline.
    assert_eq!(report.late_results, 0, "{report:?}");
    assert_eq!(report.messages_dropped, 0, "{report:?}");
    assert_eq!(report.handoffs_dropped, 0, "{report:?}");
    let figures = format!(
        "{{\"experiment\":\"{EXPERIMENT}\",\"seed\":{SEED},\"wall_s\":{:.1},\"control_ticks\":{},\
         \"control_worst_instructions\":{},\"control_mean_instructions\":{},\"jobs_run\":{},\
         \"job_worst_instructions\":{},\"estimate_preliminary_instructions\":{},\"estimate_final_instructions\":{},\"plan_instructions\":{},\"observation_instructions\":{},\"stack_used_bytes\":{},\"deadline_misses_at_168mhz\":{}}}\n",
        wall.as_secs_f64(),
        report.control_ticks,
        report.control_worst,
        report.control_mean,
        report.jobs_run,
        report.job_worst.worst(),
        report.job_worst.estimate_preliminary,
        report.job_worst.estimate_final,
        report.job_worst.plan,
        report.job_worst.observation,
        report.stack_used_bytes,
        report.deadline_misses
    );
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/emulated-pick.json");
    if let Err(e) = std::fs::write(&out, figures) {
        eprintln!("cannot write {}: {e}", out.display());
    }
}
