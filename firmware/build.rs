//! Selects the board's memory map and linker scripts, and the control rate.
//!
//! The control loop's rate is a build setting: `FIRMWARE_CONTROL_RATE_HZ`
//! (1,000 to 10,000 Hz, 1,000 when unset; with the `free-run` feature 100 to
//! 10,000 Hz, 250 when unset), written into `OUT_DIR/control_rate.rs`.
//!
//! The top-level `memory.x` only says `INCLUDE board-memory.x`; this script
//! writes the selected board's map under that name into `OUT_DIR` and puts
//! `OUT_DIR` on the link search path, so each board links with its own map.

use std::{env, fs, path::PathBuf};

/// The control rate's bounds: the pick's timing (observer, speed window,
/// stall limit) is in seconds and was run at 1, 2 and 10 kHz in the
/// simulator; below 1 kHz the stall limit (20 ms) and the watchdog (over 21
/// periods at 1 kHz) leave too few periods.
const CONTROL_RATE_RANGE_HZ: std::ops::RangeInclusive<u32> = 1_000..=10_000;

/// The emulated board running free (`free-run`): every period moves a plant
/// state (about 45 bytes) in and a command (about 40) out over QEMU's UART,
/// which carries 15 to 25 KB/s, so 1 kHz does not fit; 250 Hz uses about half
/// of it each way. The firmware gives the pick a longer stall limit in this
/// build (`control_loop::FREE_RUN_STALL_LIMIT_S`), so 100 Hz is the floor.
const FREE_RUN_RATE_RANGE_HZ: std::ops::RangeInclusive<u32> = 100..=10_000;
const FREE_RUN_DEFAULT_RATE_HZ: u32 = 250;

/// `FIRMWARE_CONTROL_RATE_HZ` checked, or the reason it is refused.
fn control_rate_hz() -> Result<u32, String> {
    let free_run = env::var_os("CARGO_FEATURE_FREE_RUN").is_some();
    let (range, default) = if free_run {
        (FREE_RUN_RATE_RANGE_HZ, FREE_RUN_DEFAULT_RATE_HZ)
    } else {
        (CONTROL_RATE_RANGE_HZ, 1_000)
    };
    let Some(text) = env::var_os("FIRMWARE_CONTROL_RATE_HZ") else {
        return Ok(default);
    };
    let text = text.to_string_lossy();
    let rate: u32 = text.trim().parse().map_err(|e| {
        format!("FIRMWARE_CONTROL_RATE_HZ={text:?} is not a whole number of hertz: {e}")
    })?;
    if !range.contains(&rate) {
        return Err(format!(
            "FIRMWARE_CONTROL_RATE_HZ={rate} is outside {} to {} Hz",
            range.start(),
            range.end()
        ));
    }
    Ok(rate)
}

fn main() {
    println!("cargo:rerun-if-env-changed=FIRMWARE_CONTROL_RATE_HZ");
    let rate = match control_rate_hz() {
        Ok(rate) => rate,
        Err(e) => {
            println!("cargo:warning={e}");
            std::process::exit(1);
        }
    };
    let out_dir = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    let source = format!(
        "/// Control-loop rate, Hz (`FIRMWARE_CONTROL_RATE_HZ` at build time).\npub const CONTROL_RATE_HZ: u32 = {rate};\n"
    );
    if let Err(e) = fs::write(out_dir.join("control_rate.rs"), source) {
        println!("cargo:warning=cannot write control_rate.rs into OUT_DIR: {e}");
        std::process::exit(1);
    }

    let qemu = env::var_os("CARGO_FEATURE_BOARD_QEMU").is_some();
    let stm32 = env::var_os("CARGO_FEATURE_BOARD_STM32F407").is_some();
    let board_dir = match (qemu, stm32) {
        (true, false) => "qemu",
        (false, true) => "stm32f407",
        (true, true) => {
            // Cargo unified both board features (e.g. `--features board-qemu`
            // without `--no-default-features`); main.rs reports it with
            // compile_error!, so stop here without a confusing link error.
            println!("cargo:warning=both board features are enabled; build one board with --no-default-features --features board-<name>");
            return;
        }
        (false, false) => {
            println!("cargo:warning=no board feature enabled; use --features board-qemu or board-stm32f407");
            return;
        }
    };

    let manifest_dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let map = manifest_dir
        .join("src/board")
        .join(board_dir)
        .join("memory.x");
    let text = match fs::read_to_string(&map) {
        Ok(text) => text,
        Err(e) => {
            println!(
                "cargo:warning=cannot read board memory map {}: {e}",
                map.display()
            );
            std::process::exit(1);
        }
    };
    if let Err(e) = fs::write(out_dir.join("board-memory.x"), text) {
        println!("cargo:warning=cannot write board-memory.x into OUT_DIR: {e}");
        std::process::exit(1);
    }

    println!("cargo:rustc-link-search={}", out_dir.display());
    println!("cargo:rerun-if-changed={}", map.display());
    println!(
        "cargo:rerun-if-changed={}",
        manifest_dir.join("../memory.x").display()
    );
    println!("cargo:rerun-if-changed=build.rs");

    // Only the thumb target links a firmware image.
    if env::var("TARGET").is_ok_and(|t| t.starts_with("thumb")) {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
