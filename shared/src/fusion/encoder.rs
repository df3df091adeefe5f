//! Unwrapping a hardware encoder counter.
//!
//! Quadrature timers count in 16 or 32 bits and wrap. The angle theta of the
//! spec is unwrapped (continuous past 2 pi, either sign), so the controller keeps
//! an unbounded 64-bit count. A reading is interpreted as the smallest signed step
//! from the previous one, which is right as long as the conveyor turns less than
//! half the counter range between two reads (32,768 counts at 16 bits: orders of
//! magnitude more than one control period ever sees).

use super::FusionError;

/// The width of the hardware counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CounterWidth {
    /// A 16-bit counter.
    Bits16,
    /// A 32-bit counter.
    Bits32,
}

impl CounterWidth {
    /// The counter's width in bits.
    pub const fn bits(self) -> u8 {
        match self {
            Self::Bits16 => 16,
            Self::Bits32 => 32,
        }
    }

    /// The counter's modulus minus one.
    pub const fn max(self) -> u32 {
        match self {
            Self::Bits16 => u16::MAX as u32,
            Self::Bits32 => u32::MAX,
        }
    }
}

/// Turns successive raw counter readings into an unbounded count, 0 at the first reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncoderUnwrapper {
    width: CounterWidth,
    last_raw: Option<u32>,
    total: i64,
}

impl EncoderUnwrapper {
    /// An unwrapper for a counter of `width`, before its first reading.
    pub const fn new(width: CounterWidth) -> Self {
        Self {
            width,
            last_raw: None,
            total: 0,
        }
    }

    /// Counts since the first reading (0 before any).
    pub fn total(&self) -> i64 {
        self.total
    }

    /// Absorbs one reading; returns the unwrapped count.
    pub fn update(&mut self, raw: u32) -> Result<i64, FusionError> {
        if raw > self.width.max() {
            return Err(FusionError::CounterOutOfRange {
                raw,
                bits: self.width.bits(),
            });
        }
        if let Some(last) = self.last_raw {
            self.total = self.total.wrapping_add(self.signed_step(last, raw));
        }
        self.last_raw = Some(raw);
        Ok(self.total)
    }

    /// The count that `raw` would unwrap to now, without absorbing it (for
    /// readings latched slightly before or after the last update, e.g. at a
    /// camera trigger).
    pub fn peek(&self, raw: u32) -> Result<i64, FusionError> {
        if raw > self.width.max() {
            return Err(FusionError::CounterOutOfRange {
                raw,
                bits: self.width.bits(),
            });
        }
        Ok(match self.last_raw {
            Some(last) => self.total.wrapping_add(self.signed_step(last, raw)),
            None => 0,
        })
    }

    fn signed_step(&self, from: u32, to: u32) -> i64 {
        match self.width {
            CounterWidth::Bits16 => i64::from(to.wrapping_sub(from) as u16 as i16),
            CounterWidth::Bits32 => i64::from(to.wrapping_sub(from) as i32),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwraps_forward_and_backward_across_16_bit_wrap() {
        let mut e = EncoderUnwrapper::new(CounterWidth::Bits16);
        assert_eq!(e.update(65_530).unwrap(), 0);
        assert_eq!(e.update(4).unwrap(), 10);
        assert_eq!(e.update(65_535).unwrap(), 5);
        assert_eq!(e.update(65_000).unwrap(), -530);
        assert_eq!(e.peek(65_010).unwrap(), -520);
        assert_eq!(e.total(), -530);
    }

    #[test]
    fn unwraps_across_32_bit_wrap_many_times() {
        let mut e = EncoderUnwrapper::new(CounterWidth::Bits32);
        let mut raw: u32 = u32::MAX - 100;
        e.update(raw).unwrap();
        let step = 1_000_000_007u32;
        for i in 1..=50i64 {
            raw = raw.wrapping_add(step);
            assert_eq!(e.update(raw).unwrap(), i * i64::from(step));
        }
    }

    #[test]
    fn rejects_readings_wider_than_the_counter_without_changing_state() {
        let mut e = EncoderUnwrapper::new(CounterWidth::Bits16);
        e.update(10).unwrap();
        assert_eq!(
            e.update(70_000),
            Err(FusionError::CounterOutOfRange {
                raw: 70_000,
                bits: 16
            })
        );
        assert_eq!(e.update(12).unwrap(), 2);
    }
}
