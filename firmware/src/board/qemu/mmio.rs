//! Volatile access to the MPS2 AN386 peripheral registers.

/// A 32-bit memory-mapped register at a fixed address.
#[derive(Clone, Copy)]
pub struct Reg(pub usize);

impl Reg {
    /// The register `offset` bytes after this one (registers of one block).
    pub const fn at(self, offset: usize) -> Reg {
        Reg(self.0 + offset)
    }

    pub fn read(self) -> u32 {
        // SAFETY: `Reg` is only built from the fixed, aligned register
        // addresses of the emulated board's peripherals (see `uart` and
        // `time_driver`), which are always mapped.
        unsafe { core::ptr::read_volatile(self.0 as *const u32) }
    }

    pub fn write(self, value: u32) {
        // SAFETY: as for `read`.
        unsafe { core::ptr::write_volatile(self.0 as *mut u32, value) }
    }

    pub fn modify(self, f: impl FnOnce(u32) -> u32) {
        self.write(f(self.read()));
    }
}

/// External interrupt lines of the AN386 that this firmware uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u16)]
pub enum Irq {
    Uart0Rx = 0,
    Uart0Tx = 1,
    DualTimer = 10,
}

// SAFETY: the discriminants are the AN386 NVIC line numbers.
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self as u16
    }
}

/// Unmasks `irq` in the NVIC.
pub fn unmask(irq: Irq) {
    // SAFETY: the handlers for these lines (`board::qemu::DefaultHandler`
    // dispatch) only touch state guarded by critical sections or atomics.
    unsafe { cortex_m::peripheral::NVIC::unmask(irq) };
}
