//! The disc conveyor as the world has it: a set speed with optional sinusoidal
//! ripple, integrated exactly, read through a quadrature encoder whose hardware
//! counter wraps at 16 or 32 bits and starts at an arbitrary value.
//!
//! The disc may be stopped (the paper's Section 5: the conveyor turned the part
//! into the robot's workspace and stopped, then the part's pose was computed):
//! from the stop instant it decelerates at a constant rate to rest and stays
//! there. `theta`, `omega` and `alpha` are the exact integral and derivatives of
//! one piecewise profile, so the encoder (read from `theta`) agrees with them.

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

/// A stop: from `start_s` the disc decelerates at `deceleration_rad_s2` to rest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConveyorStop {
    pub start_s: f64,
    pub deceleration_rad_s2: f64,
}

/// A speed change (a fault): from `start_s` the speed ramps at
/// `acceleration_rad_s2` to `target_rad_s` and stays there, without ripple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedRamp {
    pub start_s: f64,
    pub target_rad_s: f64,
    pub acceleration_rad_s2: f64,
}

/// A burst of counts the encoder missed (a fault): from `at_s` the counter
/// stops counting until it has missed `counts` edges (then it reads that many
/// fewer in the direction the disc turns), or, `instant`, its value jumps back
/// by `counts` at once (a glitch of the counter itself).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissedBurst {
    pub at_s: f64,
    pub counts: u32,
    pub instant: bool,
}

/// The disc and its encoder.
#[derive(Debug, Clone)]
pub struct Conveyor {
    profile: ConveyorProfile,
    counts_per_rev: u32,
    width: CounterWidth,
    start_raw: u32,
    theta0: f64,
    stop: Option<ConveyorStop>,
    change: Option<SpeedRamp>,
    missed: Option<MissedBurst>,
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
            stop: None,
            change: None,
            missed: None,
        })
    }

    /// The same conveyor, stopped as `stop` says (replaces any earlier stop).
    pub fn with_stop(mut self, stop: ConveyorStop) -> Result<Self> {
        if !(stop.start_s.is_finite() && stop.start_s >= 0.0) {
            bail!(
                "conveyor stop instant must be finite and >= 0 s, got {}",
                stop.start_s
            );
        }
        if !(stop.deceleration_rad_s2.is_finite() && stop.deceleration_rad_s2 > 0.0) {
            bail!(
                "conveyor deceleration must be finite and positive, got {} rad/s^2",
                stop.deceleration_rad_s2
            );
        }
        self.stop = Some(stop);
        Ok(self)
    }

    pub fn stop(&self) -> Option<ConveyorStop> {
        self.stop
    }

    /// The same conveyor, changing speed as `ramp` says (replaces a stop).
    pub fn with_speed_change(mut self, ramp: SpeedRamp) -> Result<Self> {
        let ok = ramp.start_s.is_finite()
            && ramp.start_s >= 0.0
            && ramp.target_rad_s.is_finite()
            && ramp.acceleration_rad_s2.is_finite()
            && ramp.acceleration_rad_s2 > 0.0;
        if !ok {
            bail!("conveyor speed change out of range: {ramp:?}");
        }
        self.stop = None;
        self.change = Some(ramp);
        Ok(self)
    }

    /// The same conveyor, its encoder missing `burst`.
    pub fn with_missed_counts(mut self, burst: MissedBurst) -> Result<Self> {
        if !(burst.at_s.is_finite() && burst.at_s >= 0.0) {
            bail!("missed-count burst time out of range: {}", burst.at_s);
        }
        self.missed = Some(burst);
        Ok(self)
    }

    /// The ramp in force: a speed change, or a stop (a ramp to rest).
    fn ramp(&self) -> Option<SpeedRamp> {
        self.change.or(self.stop.map(|stop| SpeedRamp {
            start_s: stop.start_s,
            target_rad_s: 0.0,
            acceleration_rad_s2: stop.deceleration_rad_s2,
        }))
    }

    /// Where the disc comes to rest if it starts stopping at `start_s` with
    /// `deceleration_rad_s2`: the angle then plus `omega^2 / (2 a)` in the
    /// direction it turns. (Ignores any stop already set.)
    pub fn rest_angle_if_stopped_at(&self, start_s: f64, deceleration_rad_s2: f64) -> f64 {
        let omega = self.running_omega(start_s);
        self.running_theta(start_s) + omega.signum() * omega * omega / (2.0 * deceleration_rad_s2)
    }

    /// The ramp, the speed at its start, the sign of its acceleration and the
    /// instant it reaches its target speed.
    fn ramp_phase(&self) -> Option<(SpeedRamp, f64, f64, f64)> {
        self.ramp().map(|ramp| {
            let omega_start = self.running_omega(ramp.start_s);
            let direction = (ramp.target_rad_s - omega_start).signum();
            let end_s =
                ramp.start_s + (ramp.target_rad_s - omega_start).abs() / ramp.acceleration_rad_s2;
            (ramp, omega_start, direction, end_s)
        })
    }

    /// The disc's angle at `t_s` (0 at t = 0): the exact integral of the speed profile.
    pub fn theta(&self, t_s: f64) -> f64 {
        match self.ramp_phase() {
            Some((ramp, omega_start, direction, end_s)) if t_s > ramp.start_s => {
                let tau = t_s.min(end_s) - ramp.start_s;
                let after = if t_s > end_s {
                    ramp.target_rad_s * (t_s - end_s)
                } else {
                    0.0
                };
                self.running_theta(ramp.start_s)
                    + omega_start * tau
                    + direction * ramp.acceleration_rad_s2 * tau * tau / 2.0
                    + after
            }
            _ => self.running_theta(t_s),
        }
    }

    /// The disc's speed at `t_s`.
    pub fn omega(&self, t_s: f64) -> f64 {
        match self.ramp_phase() {
            // Exactly the target once reached (no rounding residue of the ramp).
            Some((ramp, _, _, end_s)) if t_s >= end_s => ramp.target_rad_s,
            Some((ramp, omega_start, direction, _)) if t_s > ramp.start_s => {
                omega_start + direction * ramp.acceleration_rad_s2 * (t_s - ramp.start_s)
            }
            _ => self.running_omega(t_s),
        }
    }

    /// The disc's angular acceleration at `t_s`.
    pub fn alpha(&self, t_s: f64) -> f64 {
        match self.ramp_phase() {
            Some((ramp, _, direction, end_s)) if t_s > ramp.start_s => {
                if t_s < end_s {
                    direction * ramp.acceleration_rad_s2
                } else {
                    0.0
                }
            }
            _ => {
                let p = self.profile;
                let w = core::f64::consts::TAU * p.ripple_hz;
                p.speed_rad_s * p.ripple_fraction * w * (w * t_s).cos()
            }
        }
    }

    /// The angle of the turning disc, as if never stopped.
    fn running_theta(&self, t_s: f64) -> f64 {
        let p = self.profile;
        let ripple = if p.ripple_hz > 0.0 {
            let w = core::f64::consts::TAU * p.ripple_hz;
            p.speed_rad_s * p.ripple_fraction * (1.0 - (w * t_s).cos()) / w
        } else {
            0.0
        };
        self.theta0 + p.speed_rad_s * t_s + ripple
    }

    /// The speed of the turning disc, as if never stopped.
    fn running_omega(&self, t_s: f64) -> f64 {
        let p = self.profile;
        p.speed_rad_s
            * (1.0 + p.ripple_fraction * (core::f64::consts::TAU * p.ripple_hz * t_s).sin())
    }

    /// What the hardware counter reads at `t_s`.
    pub fn encoder_raw(&self, t_s: f64) -> u32 {
        let counts_at = |t: f64| {
            (self.theta(t) / core::f64::consts::TAU * f64::from(self.counts_per_rev)).floor() as i64
        };
        let mut counts = counts_at(t_s);
        if let Some(burst) = self.missed.filter(|burst| t_s >= burst.at_s) {
            let missed = i64::from(burst.counts);
            counts -= if burst.instant {
                if self.omega(burst.at_s) < 0.0 {
                    -missed
                } else {
                    missed
                }
            } else {
                // Each edge since the burst began is lost, up to `counts` of them.
                let moved = counts - counts_at(burst.at_s);
                moved.clamp(-missed, missed)
            };
        }
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

    fn stopping_conveyor(speed_rad_s: f64) -> Conveyor {
        Conveyor::new(
            ConveyorProfile {
                speed_rad_s,
                ripple_fraction: 0.05,
                ripple_hz: 0.3,
            },
            4096,
            CounterWidth::Bits16,
            5,
        )
        .unwrap()
        .with_stop(ConveyorStop {
            start_s: 3.3,
            deceleration_rad_s2: 0.4,
        })
        .unwrap()
    }

    #[test]
    fn a_stopping_disc_has_consistent_angle_speed_and_acceleration() {
        for speed in [0.5, -0.5] {
            let conveyor = stopping_conveyor(speed);
            let h = 1e-6;
            // Before, during and after the ramp (rest at about 3.3 + 1.25 s).
            for &t in &[0.5, 3.0, 3.4, 4.0, 4.5, 6.0, 20.0] {
                let fd_omega = (conveyor.theta(t + h) - conveyor.theta(t - h)) / (2.0 * h);
                let fd_alpha = (conveyor.omega(t + h) - conveyor.omega(t - h)) / (2.0 * h);
                assert!((fd_omega - conveyor.omega(t)).abs() < 1e-6, "omega at {t}");
                assert!((fd_alpha - conveyor.alpha(t)).abs() < 1e-5, "alpha at {t}");
            }
            // Continuous at the stop and at rest; still after.
            let stop = 3.3;
            assert!((conveyor.theta(stop + 1e-9) - conveyor.theta(stop - 1e-9)).abs() < 1e-8);
            assert_eq!(conveyor.omega(10.0), 0.0);
            assert_eq!(conveyor.alpha(10.0), 0.0);
            assert_eq!(conveyor.theta(10.0), conveyor.theta(30.0));
            let rest = conveyor.rest_angle_if_stopped_at(3.3, 0.4);
            assert!((conveyor.theta(30.0) - rest).abs() < 1e-12);
            // It kept turning the same way while it stopped.
            assert!((conveyor.theta(30.0) - conveyor.theta(stop)) * speed > 0.0);
        }
    }

    #[test]
    fn a_stopped_disc_still_reads_through_its_wrapping_encoder() {
        let conveyor = stopping_conveyor(-0.5);
        let mut unwrap = EncoderUnwrapper::new(CounterWidth::Bits16);
        let one_count = core::f64::consts::TAU / 4096.0;
        let start = conveyor.theta(0.0);
        for k in 0..10_000 {
            let t = k as f64 * 1e-3;
            let counts = unwrap.update(conveyor.encoder_raw(t)).unwrap();
            let theta = counts as f64 * one_count;
            assert!((theta - (conveyor.theta(t) - start)).abs() <= one_count + 1e-9);
        }
        // Started at 5, about 1 300 counts backwards: the counter wrapped below zero.
        assert!(conveyor.encoder_raw(0.0) == 5);
        assert!(conveyor.encoder_raw(20.0) > 60_000);
        assert_eq!(conveyor.encoder_raw(9.0), conveyor.encoder_raw(20.0));
    }

    #[test]
    fn a_reversal_ramps_the_speed_through_zero_with_a_continuous_angle() {
        let profile = ConveyorProfile {
            speed_rad_s: 0.5,
            ripple_fraction: 0.0,
            ripple_hz: 0.0,
        };
        let conveyor = Conveyor::new(profile, 4096, CounterWidth::Bits16, 0)
            .unwrap()
            .with_speed_change(SpeedRamp {
                start_s: 10.0,
                target_rad_s: -0.4,
                acceleration_rad_s2: 1.0,
            })
            .unwrap();
        let h = 1e-5;
        for k in 0..3000 {
            let t = 9.0 + k as f64 * 1e-3;
            // Speed is the angle's derivative everywhere but at the ramp's two
            // corners (0.5 to -0.4 rad/s at 1 rad/s^2: from 10 s to 10.9 s).
            let near_corner = (t - 10.0).abs() < 2e-3 || (t - 10.9).abs() < 2e-3;
            if !near_corner {
                let omega = (conveyor.theta(t + h) - conveyor.theta(t - h)) / (2.0 * h);
                assert!((omega - conveyor.omega(t)).abs() < 1e-6, "at {t}");
            }
            assert!((conveyor.theta(t + 1e-4) - conveyor.theta(t)).abs() < 1e-4);
        }
        assert_eq!(conveyor.omega(20.0), -0.4);
        assert_eq!(conveyor.alpha(10.5), -1.0);
        assert_eq!(conveyor.alpha(20.0), 0.0);
    }

    #[test]
    fn missed_counts_freeze_the_counter_and_a_glitch_jumps_it() {
        let profile = ConveyorProfile {
            speed_rad_s: 0.5,
            ripple_fraction: 0.0,
            ripple_hz: 0.0,
        };
        let plain = Conveyor::new(profile, 4096, CounterWidth::Bits32, 1000).unwrap();
        let burst = |instant| {
            plain
                .clone()
                .with_missed_counts(MissedBurst {
                    at_s: 5.0,
                    counts: 40,
                    instant,
                })
                .unwrap()
        };
        let (slow, jump) = (burst(false), burst(true));
        let read = |c: &Conveyor, t: f64| i64::from(c.encoder_raw(t));
        assert_eq!(read(&slow, 4.9), read(&plain, 4.9));
        // 40 counts at 326 counts/s: frozen for 0.12 s, then 40 behind for good.
        assert_eq!(read(&slow, 5.1), read(&slow, 5.0));
        assert_eq!(read(&plain, 6.0) - read(&slow, 6.0), 40);
        assert_eq!(read(&plain, 30.0) - read(&slow, 30.0), 40);
        assert_eq!(read(&plain, 5.0) - read(&jump, 5.0), 40);
        assert_eq!(read(&plain, 4.999) - read(&jump, 4.999), 0);
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
        let conveyor = Conveyor::new(ok, 100, CounterWidth::Bits16, 0).unwrap();
        let stop = |start_s, deceleration_rad_s2| ConveyorStop {
            start_s,
            deceleration_rad_s2,
        };
        assert!(conveyor.clone().with_stop(stop(1.0, 0.0)).is_err());
        assert!(conveyor.clone().with_stop(stop(f64::NAN, 1.0)).is_err());
        assert!(conveyor.with_stop(stop(1.0, 1.0)).is_ok());
    }
}
