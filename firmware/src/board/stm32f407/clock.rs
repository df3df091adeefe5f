//! Core clock: 168 MHz from the internal 16 MHz HSI through the main PLL, so
//! the firmware runs on any STM32F407 board whatever crystal (if any) it has.
//!
//! | stage | setting | result |
//! | --- | --- | --- |
//! | PLL input | HSI / M, M = 8 | 2 MHz (the reference manual's 1 to 2 MHz VCO input; 2 MHz for least jitter) |
//! | VCO | x N, N = 168 | 336 MHz (100 to 432 MHz allowed) |
//! | SYSCLK = HCLK | VCO / P, P = 2 | 168 MHz (the F407's maximum) |
//! | PLL48CK | VCO / Q, Q = 7 | 48 MHz (USB/SDIO/RNG clock; unused, kept valid) |
//! | APB1 | HCLK / 4 | 42 MHz (max 42); its timers (TIM2-5, 12-14) at 84 MHz |
//! | APB2 | HCLK / 2 | 84 MHz (max 84); its timers (TIM1, 8-11) at 168 MHz |
//!
//! The price of no crystal is accuracy: the HSI is factory-trimmed to 1 % at
//! 25 degC and drifts by a few per cent over the full temperature range
//! (datasheet, HSI accuracy). That is inside what the UART receiver tolerates
//! (about 3.75 % at 16x oversampling, against a host adapter with a crystal)
//! and what a control period needs, but it is not a wall clock: timestamps
//! drift by up to that much against the host's. A board with an 8 MHz HSE can
//! switch `pll_src` to it with M = 4 and keep everything else.
//! embassy-stm32 sets the voltage scale (scale 1) and the flash wait states
//! (5 at 168 MHz and 3.3 V) from this configuration.

use embassy_stm32::rcc::{
    AHBPrescaler, APBPrescaler, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv, PllSource, Sysclk,
};
use embassy_stm32::Config;

/// Core clock (HCLK), Hz: also the DWT cycle counter's rate.
pub const SYSCLK_HZ: u32 = 168_000_000;

/// The embassy-stm32 configuration for the clock tree above.
pub fn config() -> Config {
    let mut config = Config::default();
    let rcc = &mut config.rcc;
    rcc.hsi = true;
    rcc.hse = None;
    rcc.pll_src = PllSource::HSI;
    rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV8,
        mul: PllMul::MUL168,
        divp: Some(PllPDiv::DIV2),
        divq: Some(PllQDiv::DIV7),
        divr: None,
    });
    rcc.sys = Sysclk::PLL1_P;
    rcc.ahb_pre = AHBPrescaler::DIV1;
    rcc.apb1_pre = APBPrescaler::DIV4;
    rcc.apb2_pre = APBPrescaler::DIV2;
    config
}
