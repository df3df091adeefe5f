//! The disc conveyor as the world has it: a set speed with optional sinusoidal
//! ripple, integrated exactly, read through a quadrature encoder whose hardware
//! counter wraps at 16 or 32 bits and starts at an arbitrary value.

use anyhow::{bail, Result};
use shared::fusion::CounterWidth;

/// How the disc turns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConveyorProfile {
    /// Mean speed, rad/s (negative turns clockwise).
    pub speed_rad_s: f64,
    /// Speed ripple amplitude as a fraction of the mean speed.
    pub ripple_fraction: f64,
    /// Ripple frequency, Hz.
    pub ripple_hz: f64,
}

/// The disc and its encoder.
#[derive(Debug, Clone)]
pub struct Conveyor {
    profile: ConveyorProfile,
    counts_per_rev: u32,
    width: CounterWidth,
    start_raw: u32,
    theta0: f64,
}

impl Conveyor {
    pub fn new(
        profile: ConveyorProfile,
        counts_per_rev: u32,
        width: CounterWidth,
        start_raw: u32,
    ) -> Result<Self> {
        if counts_per_rev == 0 {
            bail!("conveyor encoder counts per revolution must be positive");
        }
        let finite = profile.speed_rad_s.is_finite()
            && profile.ripple_fraction.is_finite()
            && profile.ripple_hz.is_finite();
        if !finite || profile.ripple_hz < 0.0 || profile.ripple_fraction.abs() >= 1.0 {
            bail!("conveyor profile must be finite with |ripple| < 1 and ripple_hz >= 0");
        }
        if start_raw > width.max() {
            bail!(
                "encoder start value {start_raw} does not fit a {}-bit counter",
                width.bits()
            );
        }
        Ok(Self {
            profile,
            counts_per_rev,
            width,
            start_raw,
            theta0: 0.0,
        })
    }

    /// The disc's angle at `t_s` (0 at t = 0): the exact integral of the speed profile.
    pub fn theta(&self, t_s: f64) -> f64 {
        let p = self.profile;
        let ripple = if p.ripple_hz > 0.0 {
            let w = core::f64::consts::TAU * p.ripple_hz;
            p.speed_rad_s * p.ripple_fraction * (1.0 - (w * t_s).cos()) / w
        } else {
            0.0
        };
        self.theta0 + p.speed_rad_s * t_s + ripple
    }

    /// The disc's speed at `t_s`.
    pub fn omega(&self, t_s: f64) -> f64 {
        let p = self.profile;
        p.speed_rad_s
            * (1.0 + p.ripple_fraction * (core::f64::consts::TAU * p.ripple_hz * t_s).sin())
    }

    /// What the hardware counter reads at `t_s`.
    pub fn encoder_raw(&self, t_s: f64) -> u32 {
        let counts = (self.theta(t_s) / core::f64::consts::TAU * f64::from(self.counts_per_rev))
            .floor() as i64;
        let modulus = i64::from(self.width.max()) + 1;
        (i64::from(self.start_raw) + counts).rem_euclid(modulus) as u32
    }

    pub fn counts_per_rev(&self) -> u32 {
        self.counts_per_rev
    }

    pub fn width(&self) -> CounterWidth {
        self.width
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared::fusion::EncoderUnwrapper;

    #[test]
    fn the_encoder_through_an_unwrapper_gives_back_theta() {
        let profile = ConveyorProfile {
            speed_rad_s: 2.0,
            ripple_fraction: 0.05,
            ripple_hz: 1.0,
        };
        let conveyor = Conveyor::new(profile, 4096, CounterWidth::Bits16, 65_000).unwrap();
        let mut unwrap = EncoderUnwrapper::new(CounterWidth::Bits16);
        let one_count = core::f64::consts::TAU / 4096.0;
        for k in 0..200_000 {
            let t = k as f64 * 1e-3;
            let counts = unwrap.update(conveyor.encoder_raw(t)).unwrap();
            let theta = counts as f64 * one_count;
            assert!(
                (theta - conveyor.theta(t)).abs() <= one_count + 1e-9,
                "at t = {t}"
            );
        }
        // 200 s at 2 rad/s: many wraps of the 16-bit counter.
        assert!(conveyor.theta(200.0) / core::f64::consts::TAU * 4096.0 > 65_536.0 * 3.0);
    }

    #[test]
    fn speed_is_the_derivative_of_angle() {
        let conveyor = Conveyor::new(
            ConveyorProfile {
                speed_rad_s: 0.5,
                ripple_fraction: 0.1,
                ripple_hz: 0.7,
            },
            1000,
            CounterWidth::Bits32,
            0,
        )
        .unwrap();
        let h = 1e-6;
        for &t in &[0.0, 0.3, 5.0] {
            let fd = (conveyor.theta(t + h) - conveyor.theta(t - h)) / (2.0 * h);
            assert!((fd - conveyor.omega(t)).abs() < 1e-6);
        }
    }

    #[test]
    fn refuses_bad_settings() {
        let ok = ConveyorProfile {
            speed_rad_s: 0.5,
            ripple_fraction: 0.0,
            ripple_hz: 0.0,
        };
        assert!(Conveyor::new(ok, 0, CounterWidth::Bits16, 0).is_err());
        assert!(Conveyor::new(ok, 100, CounterWidth::Bits16, 70_000).is_err());
        let bad = ConveyorProfile {
            speed_rad_s: f64::NAN,
            ..ok
        };
        assert!(Conveyor::new(bad, 100, CounterWidth::Bits16, 0).is_err());
    }
}
