//! Instruction counts of the controller's pieces on the emulated Cortex-M4F.
//!
//! Run with `bench-m4/run.sh`: QEMU's `-icount shift=0` advances virtual time by
//! 1 ns per executed instruction, and the CMSDK dual timer (25 MHz) counts once
//! per 40 ns, i.e. once per 40 instructions. Each measurement runs `N` calls
//! between two timer reads, so the quantisation is 40 / N instructions.
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};

mod timer;

#[entry]
fn main() -> ! {
    let timer = timer::DualTimer::start();
    hprintln!("bench-m4: instructions per call (1 timer count = 40 instructions)");
    let overhead = timer.measure(1000, || black_box(()));
    hprintln!("  empty closure: {}", overhead);
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
