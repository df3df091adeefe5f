//! Selects the board's memory map and linker scripts.
//!
//! The top-level `memory.x` only says `INCLUDE board-memory.x`; this script
//! writes the selected board's map under that name into `OUT_DIR` and puts
//! `OUT_DIR` on the link search path, so each board links with its own map.

use std::{env, fs, path::PathBuf};

fn main() {
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
    let out_dir = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
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
