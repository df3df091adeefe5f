//! Homing's inputs on the STM32F407: a potentiometer per joint on ADC1 and
//! an index pulse per joint on an EXTI line.
//!
//! | joint | potentiometer (ADC1) | index pulse (EXTI, rising edge, pull-down) |
//! | --- | --- | --- |
//! | 1 | PC1 (IN11) | PE4 (line 4) |
//! | 2 | PC2 (IN12) | PB11 (line 11) |
//! | 3 | PC4 (IN14) | PB12 (line 12) |
//! | 4 | PC5 (IN15) | PB13 (line 13) |
//! | 5 | PB0 (IN8) | PB14 (line 14) |
//! | 6 | PB1 (IN9) | PB15 (line 15) |
//!
//! *Index pulses.* The exact way would be each encoder timer's third
//! channel capturing its counter on the pulse, but on the 100-pin package
//! those pins are taken (PE13 drives joint 5's direction, PA2/PA3 are the
//! link, PB8 drives joint 3's PWM) or missing. So the pulse interrupts on
//! an EXTI line (lines 4 and 10-15 are free: the conveyor has 2 and 3, the
//! other inputs are polled) and the handler reads that joint's timer
//! counter. At the homing speed (0.08 rad/s: one count every 0.4 ms on the
//! finest joint) the handler's latency (well under a microsecond, at the
//! reset priority like the conveyor's) cannot miss a count. The handler
//! stores the 16-bit counter and a sequence number per joint; the control
//! loop turns a new latch into the unwrapped count against the counter it
//! read in the same period ([`super::encoders::QuadratureEncoders`]).
//!
//! *Potentiometers.* Wiper to the pin through an RC filter, across 3.3 V:
//! six 12-bit conversions of 84 cycles at 21 MHz (about 30 us), read only
//! while homing. Commissioning scale: [`POT_ZERO_COUNTS`] and
//! [`POT_RAD_PER_COUNT`] (10 rad over the ADC's range, as the simulator's).

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::adc::{Adc, AdcChannel, AnyAdcChannel, SampleTime};
use embassy_stm32::exti::{ExtiInput, TriggerEdge};
use embassy_stm32::gpio::Pull;
use embassy_stm32::interrupt::typelevel::{Handler, Interrupt, EXTI15_10, EXTI4};
use embassy_stm32::mode::Blocking;
use embassy_stm32::pac;
use embassy_stm32::peripherals::{
    ADC1, EXTI11, EXTI12, EXTI13, EXTI14, EXTI15, EXTI4 as EXTI4_CH, PB0, PB1, PB11, PB12, PB13,
    PB14, PB15, PC1, PC2, PC4, PC5, PE4,
};
use embassy_stm32::Peri;

use crate::board::JOINTS;

/// Commissioning: the ADC reading at q = 0 of each joint.
pub const POT_ZERO_COUNTS: [f32; JOINTS] = [2048.0; JOINTS];
/// Commissioning: radians per ADC count of each joint (10 rad over 4,096).
pub const POT_RAD_PER_COUNT: [f32; JOINTS] = [10.0 / 4096.0; JOINTS];

/// EXTI line of each joint's index input.
const INDEX_LINES: [usize; JOINTS] = [4, 11, 12, 13, 14, 15];

/// Each joint's timer counter at its last index pulse (low 16 bits).
static LATCHED_RAW: [AtomicU32; JOINTS] = [const { AtomicU32::new(0) }; JOINTS];
/// Index pulses seen per joint (a new one changes it).
static LATCHES: [AtomicU32; JOINTS] = [const { AtomicU32::new(0) }; JOINTS];

/// The joint timers' 16-bit counters (TIM1, 8, 2, 5, 3, 4: see `encoders`).
#[inline(always)]
fn timer_counter(joint: usize) -> u16 {
    match joint {
        0 => pac::TIM1.cnt().read().cnt(),
        1 => pac::TIM8.cnt().read().cnt(),
        2 => pac::TIM2.cnt().read() as u16,
        3 => pac::TIM5.cnt().read() as u16,
        4 => pac::TIM3.cnt().read().cnt(),
        _ => pac::TIM4.cnt().read().cnt(),
    }
}

/// The handler of the index lines' vectors (bound in `mod.rs`).
pub struct IndexHandler;

impl Handler<EXTI4> for IndexHandler {
    unsafe fn on_interrupt() {
        on_index();
    }
}

impl Handler<EXTI15_10> for IndexHandler {
    unsafe fn on_interrupt() {
        on_index();
    }
}

/// Latches the counter of every joint whose index line is pending.
fn on_index() {
    let pending = pac::EXTI.pr(0).read();
    for (joint, line) in INDEX_LINES.iter().enumerate() {
        if !pending.line(*line) {
            continue;
        }
        let raw = timer_counter(joint);
        pac::EXTI.pr(0).write(|w| w.set_line(*line, true));
        if let (Some(latched), Some(count)) = (LATCHED_RAW.get(joint), LATCHES.get(joint)) {
            latched.store(u32::from(raw), Ordering::Relaxed);
            count.fetch_add(1, Ordering::Release);
        }
    }
}

/// The pins and the ADC homing reads.
pub struct HomingPeripherals {
    pub adc: Peri<'static, ADC1>,
    pub pot1: Peri<'static, PC1>,
    pub pot2: Peri<'static, PC2>,
    pub pot3: Peri<'static, PC4>,
    pub pot4: Peri<'static, PC5>,
    pub pot5: Peri<'static, PB0>,
    pub pot6: Peri<'static, PB1>,
    pub index1: (Peri<'static, PE4>, Peri<'static, EXTI4_CH>),
    pub index2: (Peri<'static, PB11>, Peri<'static, EXTI11>),
    pub index3: (Peri<'static, PB12>, Peri<'static, EXTI12>),
    pub index4: (Peri<'static, PB13>, Peri<'static, EXTI13>),
    pub index5: (Peri<'static, PB14>, Peri<'static, EXTI14>),
    pub index6: (Peri<'static, PB15>, Peri<'static, EXTI15>),
}

/// Homing's inputs.
pub struct HomingSensors {
    adc: Adc<'static, ADC1>,
    pots: [AnyAdcChannel<'static, ADC1>; JOINTS],
    /// Kept so the lines stay configured.
    _index: [ExtiInput<'static, Blocking>; JOINTS],
    /// The latch count last turned into a count, per joint.
    seen: [u32; JOINTS],
    /// Each joint's count at its last index pulse (held).
    latched: [Option<i32>; JOINTS],
}

impl HomingSensors {
    pub fn new(p: HomingPeripherals) -> Self {
        let sensors = Self {
            adc: Adc::new(p.adc),
            pots: [
                AdcChannel::<ADC1>::degrade_adc(p.pot1),
                AdcChannel::<ADC1>::degrade_adc(p.pot2),
                AdcChannel::<ADC1>::degrade_adc(p.pot3),
                AdcChannel::<ADC1>::degrade_adc(p.pot4),
                AdcChannel::<ADC1>::degrade_adc(p.pot5),
                AdcChannel::<ADC1>::degrade_adc(p.pot6),
            ],
            _index: [
                ExtiInput::new_blocking(p.index1.0, p.index1.1, Pull::Down, TriggerEdge::Rising),
                ExtiInput::new_blocking(p.index2.0, p.index2.1, Pull::Down, TriggerEdge::Rising),
                ExtiInput::new_blocking(p.index3.0, p.index3.1, Pull::Down, TriggerEdge::Rising),
                ExtiInput::new_blocking(p.index4.0, p.index4.1, Pull::Down, TriggerEdge::Rising),
                ExtiInput::new_blocking(p.index5.0, p.index5.1, Pull::Down, TriggerEdge::Rising),
                ExtiInput::new_blocking(p.index6.0, p.index6.1, Pull::Down, TriggerEdge::Rising),
            ],
            seen: [0; JOINTS],
            latched: [None; JOINTS],
        };
        // SAFETY: the handlers are bound (`bind_interrupts!` in mod.rs) and
        // touch only the EXTI pending register, the timers' counters (read)
        // and the atomics above.
        unsafe {
            EXTI4::enable();
            EXTI15_10::enable();
        }
        sensors
    }

    /// The potentiometers, rad.
    pub fn potentiometers(&mut self) -> [f32; JOINTS] {
        let mut out = [f32::NAN; JOINTS];
        for (j, (slot, pot)) in out.iter_mut().zip(self.pots.iter_mut()).enumerate() {
            let counts = f32::from(self.adc.blocking_read(pot, SampleTime::CYCLES84));
            let zero = POT_ZERO_COUNTS.get(j).copied().unwrap_or(f32::NAN);
            let scale = POT_RAD_PER_COUNT.get(j).copied().unwrap_or(f32::NAN);
            *slot = (counts - zero) * scale;
        }
        out
    }

    /// Each joint's count at its last index pulse, given the counters
    /// `raw` and their unwrapped `counts` read this period (a latch is
    /// within a period's travel of them). `to_count` turns a raw delta
    /// into a count on the joint's sign convention.
    pub fn index_counts(
        &mut self,
        raw: &[u16; JOINTS],
        counts: &[i32; JOINTS],
        signs: &[i32; JOINTS],
    ) -> [Option<i32>; JOINTS] {
        for j in 0..JOINTS {
            let (Some(latches), Some(latched_raw)) = (LATCHES.get(j), LATCHED_RAW.get(j)) else {
                continue;
            };
            let seen = latches.load(Ordering::Acquire);
            let (Some(last), Some(slot)) = (self.seen.get_mut(j), self.latched.get_mut(j)) else {
                continue;
            };
            if seen == *last {
                continue;
            }
            *last = seen;
            let latched = latched_raw.load(Ordering::Relaxed) as u16;
            let (Some(now_raw), Some(now), Some(sign)) = (raw.get(j), counts.get(j), signs.get(j))
            else {
                continue;
            };
            // The 16-bit difference, signed: the joint moved less than
            // 2^15 counts since the pulse.
            let delta = i32::from(latched.wrapping_sub(*now_raw) as i16);
            *slot = Some(now.wrapping_add(sign * delta));
        }
        self.latched
    }
}
