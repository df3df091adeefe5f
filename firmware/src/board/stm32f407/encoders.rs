//! Joint encoders on the STM32F407's timers in quadrature-encoder mode (x4:
//! both edges of both channels).
//!
//! | joint | timer | A (CH1) | B (CH2) |
//! | --- | --- | --- | --- |
//! | 1 | TIM1 | PE9 | PE11 |
//! | 2 | TIM8 | PC6 | PC7 |
//! | 3 | TIM2 | PA15 | PB3 |
//! | 4 | TIM5 | PA0 | PA1 |
//! | 5 | TIM3 | PB4 | PB5 |
//! | 6 | TIM4 | PB6 | PB7 |
//!
//! (PA15, PB3 and PB4 are JTAG pins: debug over SWD, without SWO trace.)

use embassy_stm32::peripherals::{TIM1, TIM2, TIM3, TIM4, TIM5, TIM8};
use embassy_stm32::timer::qei::{Config as QeiConfig, Qei};

use shared::fusion::{CounterWidth, EncoderUnwrapper};

use super::JOINT_SIGNS;
use crate::board::{BoardError, JointCounts};

/// The six quadrature decoders, joint 1 first.
pub struct QuadratureEncoders {
    joint1: Qei<'static, TIM1>,
    joint2: Qei<'static, TIM8>,
    joint3: Qei<'static, TIM2>,
    joint4: Qei<'static, TIM5>,
    joint5: Qei<'static, TIM3>,
    joint6: Qei<'static, TIM4>,
    /// The 16-bit hardware counts unwrapped (exact while a joint moves less
    /// than 2^15 counts between two reads: one control period).
    counts: [EncoderUnwrapper; 6],
}

/// The peripherals the encoders take.
pub struct EncoderPeripherals {
    pub joint1: Qei<'static, TIM1>,
    pub joint2: Qei<'static, TIM8>,
    pub joint3: Qei<'static, TIM2>,
    pub joint4: Qei<'static, TIM5>,
    pub joint5: Qei<'static, TIM3>,
    pub joint6: Qei<'static, TIM4>,
}

impl QuadratureEncoders {
    pub fn new(p: EncoderPeripherals) -> Self {
        let mut encoders = QuadratureEncoders {
            joint1: p.joint1,
            joint2: p.joint2,
            joint3: p.joint3,
            joint4: p.joint4,
            joint5: p.joint5,
            joint6: p.joint6,
            counts: [EncoderUnwrapper::new(CounterWidth::Bits16); 6],
        };
        // Counts start at zero wherever the timers happen to stand.
        let raw = encoders.raw();
        for (count, raw) in encoders.counts.iter_mut().zip(raw) {
            // A u16 is always within the 16-bit counter's range.
            let _ = count.update(u32::from(raw));
        }
        encoders
    }

    /// The six timers' 16-bit counters, joint 1 first, read back to back
    /// (the latch reads them here, inside its critical section).
    #[inline(always)]
    pub(super) fn raw(&self) -> [u16; 6] {
        [
            self.joint1.count(),
            self.joint2.count(),
            self.joint3.count(),
            self.joint4.count(),
            self.joint5.count(),
            self.joint6.count(),
        ]
    }
}

/// Quadrature decoder settings shared by all joints. The input filters are
/// set after `Qei::new` (`super::filter_encoder_inputs`): its configuration
/// has no field for them.
pub fn qei_config() -> QeiConfig {
    QeiConfig::default()
}

impl QuadratureEncoders {
    /// The joint counts since boot from the timers' counters `raw` (read by
    /// [`Self::raw`] at the latch), unwrapped from 16 bits, in each joint's
    /// direction (its encoder sign, `super::JOINT_SIGNS`).
    pub fn unwrap_counts(&mut self, raw: [u16; 6]) -> Result<JointCounts, BoardError> {
        let mut out = [0i32; 6];
        for (joint, ((out, count), raw)) in out
            .iter_mut()
            .zip(self.counts.iter_mut())
            .zip(raw)
            .enumerate()
        {
            let total = count
                .update(u32::from(raw))
                .map_err(|_| BoardError::EncoderOutOfRange { joint })?;
            let total = JOINT_SIGNS
                .encoder_count(joint, total)
                .ok_or(BoardError::EncoderOutOfRange { joint })?;
            *out = i32::try_from(total).map_err(|_| BoardError::EncoderOutOfRange { joint })?;
        }
        Ok(out)
    }
}
