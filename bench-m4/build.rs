//! Memory map of the emulated mps2-an386 board (code 4 MiB at 0x0, RAM 4 MiB at
//! 0x2000_0000). Written to OUT_DIR both as `memory.x` (used when the workspace
//! root has none) and as `board-memory.x` (used when the root `memory.x` is the
//! shared `INCLUDE board-memory.x` stub, see shared/notes/embedded-toolchain.md).
use std::{env, fs, path::PathBuf};

const MEMORY: &str = "MEMORY\n{\n  FLASH : ORIGIN = 0x00000000, LENGTH = 4M\n  RAM : ORIGIN = 0x20000000, LENGTH = 4M\n}\n";

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(out.join("memory.x"), MEMORY).expect("write memory.x");
    fs::write(out.join("board-memory.x"), MEMORY).expect("write board-memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    let target = env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumb") {
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
