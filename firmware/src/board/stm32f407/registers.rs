//! Register values the board writes itself, past what embassy-stm32 sets up,
//! as pure functions of `core` integers so that they carry their own unit
//! tests on the host (like `quadrature.rs`):
//!
//! ```sh
//! cd firmware/src/board/stm32f407
//! rustc --edition 2021 --test registers.rs -o /tmp/registers && /tmp/registers
//! ```
//!
//! - FLASH_ACR: the flash accelerator (ART: prefetch, instruction and data
//!   caches). embassy-stm32 0.6 sets the wait states with a plain write
//!   (`FLASH.acr().write(|w| w.set_latency(..))` in `rcc/f247.rs`), which
//!   clears PRFTEN, ICEN and DCEN: at 168 MHz and 5 wait states every
//!   instruction fetch from flash would then wait, a fraction of the core's
//!   speed for the control period.
//! - TIMx_CCMR1: the quadrature timers' input filters (IC1F, IC2F), which
//!   embassy's `Qei::new` leaves at 0 (no filter): a glitch on a long
//!   encoder cable would be counted as a step.
//! - MPU: a no-access region at the bottom of the stack, so that an
//!   overflow faults when it reaches the guard (MemManage), not when it
//!   leaves SRAM.

#![allow(dead_code)]

/// FLASH_ACR bits (RM0090 3.9.1).
pub const ACR_LATENCY_MASK: u32 = 0x7;
pub const ACR_PRFTEN: u32 = 1 << 8;
pub const ACR_ICEN: u32 = 1 << 9;
pub const ACR_DCEN: u32 = 1 << 10;
pub const ACR_ICRST: u32 = 1 << 11;
pub const ACR_DCRST: u32 = 1 << 12;

/// The two FLASH_ACR writes that turn the accelerator on, keeping the wait
/// states in `acr`: first the caches reset (allowed only while they are
/// disabled, which is how the HAL left them), then prefetch and both caches
/// on.
pub const fn flash_acr_accelerated(acr: u32) -> [u32; 2] {
    let latency = acr & ACR_LATENCY_MASK;
    [
        latency | ACR_ICRST | ACR_DCRST,
        latency | ACR_PRFTEN | ACR_ICEN | ACR_DCEN,
    ]
}

/// The input filter for the joint encoders' timers, ICxF = 0b1100:
/// sampling at f_DTS / 16 with 8 equal samples needed for an edge. With
/// CKD = 0 (f_DTS = the timer clock) a level must hold 8 x 16 / 84 MHz =
/// 1.5 us on TIM2-5 and 0.76 us on TIM1/8 (168 MHz): glitches shorter than
/// that are not counted, and encoder edges may come up to about 600 k a
/// second, far above what the arm's joints reach.
pub const ENCODER_INPUT_FILTER: u32 = 0b1100;
/// TIMx_CCMR1 input-capture filter fields: IC1F bits 7:4, IC2F bits 15:12.
const CCMR1_IC1F_SHIFT: u32 = 4;
const CCMR1_IC2F_SHIFT: u32 = 12;
const CCMR1_ICF_MASK: u32 = 0xF;

/// TIMx_CCMR1 with both input filters set to `filter` (low 4 bits), every
/// other bit (the capture selections the HAL chose) kept.
pub const fn ccmr1_with_input_filters(ccmr1: u32, filter: u32) -> u32 {
    let filter = filter & CCMR1_ICF_MASK;
    let cleared =
        ccmr1 & !((CCMR1_ICF_MASK << CCMR1_IC1F_SHIFT) | (CCMR1_ICF_MASK << CCMR1_IC2F_SHIFT));
    cleared | (filter << CCMR1_IC1F_SHIFT) | (filter << CCMR1_IC2F_SHIFT)
}

/// The stack guard's size: 256 bytes, the smallest region that holds an
/// exception frame with the FPU's registers (104 bytes) twice over, so a
/// frame being stacked as the stack overflows lands in it whole.
pub const STACK_GUARD_BYTES: u32 = 256;

/// MPU_RBAR for region 0 at `base` (aligned to the region's size).
pub const fn mpu_guard_rbar(base: u32) -> u32 {
    const VALID: u32 = 1 << 4;
    (base & !(STACK_GUARD_BYTES - 1)) | VALID
}

/// MPU_RASR for the guard: enabled, `STACK_GUARD_BYTES` long, no access at
/// any privilege (AP = 000), never executed (XN), normal memory.
pub const fn mpu_guard_rasr() -> u32 {
    const ENABLE: u32 = 1;
    const XN: u32 = 1 << 28;
    // SIZE: the region is 2^(SIZE + 1) bytes.
    let size = STACK_GUARD_BYTES.trailing_zeros() - 1;
    XN | (size << 1) | ENABLE
}

/// MPU_CTRL: on, with the default memory map for everything else
/// (PRIVDEFENA), and off during HardFault and NMI (HFNMIENA clear) so that
/// their handlers run whatever the guard holds.
pub const MPU_CTRL_GUARD: u32 = 0b101;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_accelerator_keeps_the_wait_states_and_turns_everything_on() {
        // What embassy-stm32 leaves at 168 MHz: 5 wait states, all else off.
        let [reset, on] = flash_acr_accelerated(5);
        assert_eq!(reset, 5 | ACR_ICRST | ACR_DCRST);
        assert_eq!(on & ACR_LATENCY_MASK, 5);
        assert_eq!(
            on & (ACR_PRFTEN | ACR_ICEN | ACR_DCEN),
            ACR_PRFTEN | ACR_ICEN | ACR_DCEN
        );
        // The caches are not held in reset once enabled.
        assert_eq!(on & (ACR_ICRST | ACR_DCRST), 0);
        // Whatever else the register held is not carried over.
        let [_, on] = flash_acr_accelerated(0xFFFF_FFFD);
        assert_eq!(on, 5 | ACR_PRFTEN | ACR_ICEN | ACR_DCEN);
    }

    #[test]
    fn input_filters_keep_the_capture_selection() {
        // Qei::new: CC1S = 01, CC2S = 01 (TI1, TI2), no filter.
        let hal = 0x0101;
        let filtered = ccmr1_with_input_filters(hal, ENCODER_INPUT_FILTER);
        assert_eq!(filtered, 0xC1C1);
        assert_eq!(filtered & 0x0303, hal & 0x0303);
        // Setting it twice, or over another filter, is the same.
        assert_eq!(
            ccmr1_with_input_filters(filtered, ENCODER_INPUT_FILTER),
            filtered
        );
        assert_eq!(ccmr1_with_input_filters(0xFFFF, 0), 0x0F0F);
    }

    #[test]
    fn the_guard_is_a_small_no_access_region_at_the_stack_bottom() {
        assert_eq!(mpu_guard_rbar(0x2000_0000), 0x2000_0010);
        // A base inside the region is rounded down to its alignment.
        assert_eq!(mpu_guard_rbar(0x2000_00FF), 0x2000_0010);
        let rasr = mpu_guard_rasr();
        assert_eq!(rasr & 1, 1, "enabled");
        assert_eq!((rasr >> 1) & 0x1F, 7, "2^(7+1) = 256 bytes");
        assert_eq!((rasr >> 24) & 0x7, 0, "no access");
        assert_ne!(rasr & (1 << 28), 0, "execute never");
        assert!(STACK_GUARD_BYTES >= 2 * 104);
    }
}
