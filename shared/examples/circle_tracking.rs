//! Tracks the task circle (0.3 m radius, 1 rad/s, flange down, centre 0.5 m in
//! front at z = 0.4 m) with the f32 controller on a mismatched f64 plant (link
//! masses +/-10 %, unknown 1 kg payload, friction known within +/-30 %), and
//! prints the tracking error of the paper's PD loop beside the PID loop.
//!
//! `cargo run --release -p shared --example circle_tracking`

#[path = "../tests/control_support/mod.rs"]
mod control_support;

use control_support::{track_circle, SplitMix};

fn table(switched_coulomb: bool) {
    let duration = 4.0 * core::f64::consts::PI; // two turns
    let settle = 1.5;
    println!(
        "\nplant Coulomb friction: {}",
        if switched_coulomb {
            "switched sign law (discontinuous, chatters under RK4)"
        } else {
            "tanh law, width 0.01 rad/s (robot::drive::SIMULATOR_COULOMB_WIDTH)"
        }
    );
    println!("errors after {settle} s of 2 turns; 1 kHz control, RK4 plant at 1 kHz");
    println!("seed  friction_known | PD max [mm]  PD rms [mm] | PID max [mm] PID rms [mm] PID max rot [mrad] | max|tau| [N m]");
    let mut rng = SplitMix(0xC1_4C1E);
    let (mut worst_pd, mut worst_pid) = (0.0_f64, 0.0_f64);
    for seed in 1..=8_u64 {
        let friction_scale = rng.uniform(0.7, 1.3);
        let pd = track_circle(
            seed,
            friction_scale,
            false,
            switched_coulomb,
            duration,
            settle,
        );
        let pid = track_circle(
            seed,
            friction_scale,
            true,
            switched_coulomb,
            duration,
            settle,
        );
        worst_pd = worst_pd.max(pd.max_error_m);
        worst_pid = worst_pid.max(pid.max_error_m);
        let flags = if pid.fallback_steps + pid.saturated_steps > 0 {
            "  (saturated/fallback steps!)"
        } else {
            ""
        };
        println!(
            "{seed:>4}  x{friction_scale:<12.3} | {:>11.3}  {:>11.3} | {:>12.3} {:>12.3} {:>18.3} | {:>8.1}{flags}",
            pd.max_error_m * 1e3,
            pd.rms_error_m * 1e3,
            pid.max_error_m * 1e3,
            pid.rms_error_m * 1e3,
            pid.max_orientation_error_rad * 1e3,
            pid.max_abs_tau,
        );
    }
    println!(
        "worst max error: PD {:.3} mm, PID {:.3} mm (goal < 2 mm)",
        worst_pd * 1e3,
        worst_pid * 1e3
    );
}

fn main() {
    table(false);
    table(true);
}
