//! Core clock: 168 MHz from the board's 8 MHz crystal (HSE; X2 on the
//! STM32F4-Discovery, on PH0/PH1) through the main PLL.
//!
//! | stage | setting | result |
//! | --- | --- | --- |
//! | PLL input | HSE / M, M = 4 | 2 MHz (the reference manual's 1 to 2 MHz VCO input; 2 MHz for least jitter) |
//! | VCO | x N, N = 168 | 336 MHz (100 to 432 MHz allowed) |
//! | SYSCLK = HCLK | VCO / P, P = 2 | 168 MHz (the F407's maximum) |
//! | PLL48CK | VCO / Q, Q = 7 | 48 MHz (USB/SDIO/RNG clock; unused, kept valid) |
//! | APB1 | HCLK / 4 | 42 MHz (max 42); its timers (TIM2-5, 12-14) at 84 MHz |
//! | APB2 | HCLK / 2 | 84 MHz (max 84); its timers (TIM1, 8-11) at 168 MHz |
//!
//! Why the crystal: the internal HSI is trimmed to 1 % at 25 degC and drifts
//! by a few per cent over temperature, so the control period, the PWM
//! carrier and the time stamps the host pairs camera frames with would drift
//! by as much; a crystal holds tens of ppm. A board without an 8 MHz crystal
//! does not come up: embassy-stm32 waits for HSERDY (with the amplifier
//! enable low since `__pre_init`, and before the watchdog is started), so
//! such a board needs `HSE_HZ` changed, or the HSI configuration of the
//! earlier firmware (`pll_src = HSI`, M = 8).
//! embassy-stm32 sets the voltage scale (scale 1) and the flash wait states
//! (5 at 168 MHz and 3.3 V) from this configuration; it also clears the
//! flash accelerator, which `init` turns back on afterwards
//! (`super::registers::flash_acr_accelerated`).

use embassy_stm32::rcc::{
    AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv, PllSource,
    Sysclk,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::Config;

/// The board's crystal (the STM32F4-Discovery's X2).
pub const HSE_HZ: u32 = 8_000_000;

/// Core clock (HCLK), Hz: also the DWT cycle counter's rate.
pub const SYSCLK_HZ: u32 = 168_000_000;

/// The embassy-stm32 configuration for the clock tree above.
pub fn config() -> Config {
    let mut config = Config::default();
    let rcc = &mut config.rcc;
    // The HSI stays on: the core runs from it until the PLL locks.
    rcc.hsi = true;
    rcc.hse = Some(Hse {
        freq: Hertz(HSE_HZ),
        mode: HseMode::Oscillator,
    });
    rcc.pll_src = PllSource::HSE;
    rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV4,
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
