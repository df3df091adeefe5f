//! How long a board's worker takes over each job: the instructions the
//! emulated firmware counted for it (`RuntimeReport::job_worst`, the
//! emulated pick), turned into time on a 168 MHz STM32F407 by the cycle
//! model of `bench-m4/cycles.py` and shared with the control loop, which
//! preempts the worker every period.
//!
//! The figures are measured, not derived: `cargo test --release -p
//! integration-tests --test emulated_pick -- --nocapture` writes them to
//! `target/emulated-pick.json`, and `tests/tests/emulated_pick.rs` fails if
//! the firmware's jobs grow past them (so this model cannot go stale
//! quietly). A job's cost depends on the data it has; each kind is charged
//! its worst.

use shared::app::pick::handoff::JobRequest;

/// A board's clock and the instructions each kind of job takes on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardTiming {
    /// The core clock, Hz.
    pub clock_hz: f64,
    /// Cycles an instruction takes on average (flash wait states behind the
    /// ART accelerator, FPU and load latencies).
    pub cycles_per_instruction: f64,
    /// The share of the core the control loop leaves the worker.
    pub worker_share: f64,
    /// Instructions of a preliminary estimate (worst measured).
    pub estimate_preliminary_instructions: u64,
    /// Instructions of a final estimate (worst measured).
    pub estimate_final_instructions: u64,
    /// Instructions of an intercept plan (worst measured).
    pub plan_instructions: u64,
}

/// The emulated firmware's worst jobs, experiment-2-7cm seed 1 (the
/// emulated pick's run; see the module's doc for the command): each job's
/// own instructions, the interrupt handlers that preempt it excluded
/// (`firmware::board::interrupt_time`; the control loop's share of the core
/// is [`BoardTiming::worker_share`]). Counted with the handlers, as before,
/// they followed the host's timing: 244 to 256 million for the preliminary
/// estimate, 479 to 499 million for the final one over runs of the same
/// firmware on the same data; without them two runs agree within 0.8 %.
/// History of the figures: 535 and 994 million before the normal equations
/// were summed in f32 with iterations stopped when the Gauss-Newton model
/// promises no progress, 256 and 442 million after, 254 and 484 million
/// with the gripper's marks 8 cm out (handlers included), 241 and 466 million
/// without the handlers, 196 and 370 million with iterations that stop at a
/// chi-square progress of 1e-6 and each phase's starting cost taken from its
/// first pass, 194 and 362 million with the fit's statistics taken from the
/// covariance's pass, 62 and 121 million with the start's homography from
/// moment sums, passes over the points made in f32 where no cost is compared,
/// and the start's robust loops stopped once their inlier sets repeat; 47
/// and 97 million since the search halts once the marks have crossed the
/// view (the estimates come 15 s sooner, over fewer frames; the bench's
/// 656-frame cell, `BENCH_M4_ONLY=estimate bench-m4/run.sh`, costs 138 and
/// 147 million); 55 million for the preliminary estimate since the worker
/// proves each calibration move's joint speeds (`pick::pace`, 8.3 million);
/// 50, 110 and 47 million (preliminary, final, plan) since the preliminary
/// estimate is made on the search's way back, from fewer sightings, and the
/// poses are the widest of 30 candidates.
pub const MEASURED_ESTIMATE_PRELIMINARY_INSTRUCTIONS: u64 = 50_086_480;
/// See [`MEASURED_ESTIMATE_PRELIMINARY_INSTRUCTIONS`].
pub const MEASURED_ESTIMATE_FINAL_INSTRUCTIONS: u64 = 109_879_320;
/// See [`MEASURED_ESTIMATE_PRELIMINARY_INSTRUCTIONS`].
pub const MEASURED_PLAN_INSTRUCTIONS: u64 = 47_471_040;

/// Cycles an instruction, the pick period's on the cycle model
/// (docs/performance.md, "Cycles on the STM32F407"): 2.03. The jobs' soft
/// double precision is mostly integer work and probably runs nearer 1.5, so
/// this errs on the slow side.
const CYCLES_PER_INSTRUCTION: f64 = 2.03;

/// The control loop at 1 kHz: 10,626 instructions a period on average
/// (the emulated pick) at 2.03 cycles each, out of 168,000 cycles.
const CONTROL_LOAD: f64 = 10_626.0 * CYCLES_PER_INSTRUCTION / 168_000.0;

impl BoardTiming {
    /// The STM32F407 at 168 MHz running the firmware at 1 kHz.
    pub fn stm32f407() -> Self {
        Self {
            clock_hz: 168e6,
            cycles_per_instruction: CYCLES_PER_INSTRUCTION,
            worker_share: 1.0 - CONTROL_LOAD,
            estimate_preliminary_instructions: MEASURED_ESTIMATE_PRELIMINARY_INSTRUCTIONS,
            estimate_final_instructions: MEASURED_ESTIMATE_FINAL_INSTRUCTIONS,
            plan_instructions: MEASURED_PLAN_INSTRUCTIONS,
        }
    }

    /// The instructions of the job that `request` asks for.
    pub fn job_instructions(&self, request: &JobRequest) -> u64 {
        match request {
            JobRequest::Estimate {
                preliminary: true, ..
            } => self.estimate_preliminary_instructions,
            JobRequest::Estimate { .. } => self.estimate_final_instructions,
            JobRequest::Plan { .. } => self.plan_instructions,
        }
    }

    /// How long the worker takes over `request`, microseconds.
    pub fn job_us(&self, request: &JobRequest) -> u64 {
        let seconds = self.job_instructions(request) as f64 * self.cycles_per_instruction
            / self.clock_hz
            / self.worker_share;
        (seconds * 1e6).round() as u64
    }

    /// For messages.
    pub fn describe(&self) -> String {
        format!(
            "a {:.0} MHz Cortex-M4F ({:.2} cycles an instruction, {:.0} % of the core left to the worker)",
            self.clock_hz / 1e6,
            self.cycles_per_instruction,
            self.worker_share * 100.0
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stm32f407_takes_seconds_over_an_estimate_and_more_than_its_budget_over_a_plan() {
        let timing = BoardTiming::stm32f407();
        let final_estimate = JobRequest::Estimate {
            preliminary: false,
            time_us: 0,
            start_pose: shared::planning::ArcPoint {
                radius_m: 0.6,
                azimuth_rad: 0.0,
                z_m: 0.5,
                yaw_rad: 0.0,
            },
            q_now: nalgebra::SVector::zeros(),
            from: shared::planning::ArcPoint {
                radius_m: 0.6,
                azimuth_rad: 0.0,
                z_m: 0.5,
                yaw_rad: 0.0,
            },
            waist_centre_azimuth: 0.0,
        };
        let seconds = timing.job_us(&final_estimate) as f64 * 1e-6;
        // 109.9 M instructions x 2.03 / 168 MHz / 0.87 of the core: 1.52 s.
        assert!((1.42..1.62).contains(&seconds), "{seconds} s");
        assert!(timing.describe().contains("168 MHz"));
    }
}
