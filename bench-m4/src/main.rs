//! Instruction counts of the f32 control step on the emulated Cortex-M4F.
//!
//! Run with `bench-m4/run.sh`: QEMU's `-icount shift=0` advances virtual time by
//! 1 ns per executed instruction, and the CMSDK dual timer (25 MHz) counts once
//! per 40 ns, i.e. once per 40 instructions. Each measurement runs `CALLS`
//! calls between two timer reads, so the quantisation is 40 / CALLS instructions.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "bench-m4 runs on the Cortex-M4F: use bench-m4/run.sh (thumbv7em-none-eabihf under QEMU)"
    );
    std::process::exit(2);
}

#[cfg(target_os = "none")]
mod estimate;
#[cfg(target_os = "none")]
mod m4;
#[cfg(target_os = "none")]
mod timer;
