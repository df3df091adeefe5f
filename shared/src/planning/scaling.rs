//! The time scaling of a rest-to-rest move: how far along its path (0 to 1) a
//! move is at each instant, with the rate and acceleration of that progress.
//!
//! A short move is the rest-to-rest quintic, the fastest smooth profile when
//! the speed limit is reached only at its middle. A long one (the search's
//! sweeps over joint 1's whole range, the carry round the base) would crawl
//! under the quintic: it reaches its top speed at one instant only, and
//! averages 8/15 of it. It blends up to the top speed, cruises there and blends
//! down, each blend a quintic in speed (the acceleration stays continuous, as
//! Eq 23's feed-forward needs): a sweep of 3.3 m at 0.5 m/s takes 7.2 s
//! instead of 12.3 s.

use nalgebra::{convert, RealField};

/// A rest-to-rest quintic peaks at `15/8 D/T` in speed and `10/sqrt(3) D/T^2` in
/// acceleration for a distance `D` over `T`.
const QUINTIC_PEAK_SPEED: f64 = 1.875;
const QUINTIC_PEAK_ACCELERATION: f64 = 5.773_502_691_896_258;

/// A blend that raises the speed from 0 to `V` over `T_b` (speed `V g(t/T_b)`,
/// `g(u) = 10u^3 - 15u^4 + 6u^5`) peaks at `15/8 V / T_b` in acceleration.
const BLEND_PEAK_ACCELERATION: f64 = 1.875;

/// The progress `s(t)` of a rest-to-rest move, `s(0) = 0` to `s(T) = 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeScaling<T> {
    duration_s: T,
    /// The blends' length; zero for the quintic.
    blend_s: T,
    /// The cruise's rate of progress, 1/s (`1 / (T - T_b)`).
    cruise_rate: T,
}

/// The progress, its rate and its acceleration at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress<T> {
    /// Fraction of the path covered, 0 to 1.
    pub s: T,
    /// Its rate, 1/s.
    pub rate: T,
    /// Its acceleration, 1/s^2.
    pub acceleration: T,
}

impl<T: RealField + Copy> TimeScaling<T> {
    /// The shortest move whose progress rate stays within `max_rate` (1/s)
    /// and whose acceleration within `max_acceleration` (1/s^2), lasting at
    /// least `min_duration_s`. Both limits must be positive (callers check;
    /// a non-positive one gives the `min_duration_s` quintic).
    pub fn shortest(max_rate: T, max_acceleration: T, min_duration_s: T) -> Self {
        let peak_speed: T = convert(QUINTIC_PEAK_SPEED);
        let peak_acceleration: T = convert(QUINTIC_PEAK_ACCELERATION);
        let floor = min_duration_s.max(convert(1e-3));
        let positive = max_rate > T::zero() && max_acceleration > T::zero();
        let quintic = if positive {
            (peak_speed / max_rate)
                .max((peak_acceleration / max_acceleration).sqrt())
                .max(floor)
        } else {
            floor
        };
        let quintic_scaling = Self {
            duration_s: quintic,
            blend_s: T::zero(),
            cruise_rate: T::zero(),
        };
        if !positive {
            return quintic_scaling;
        }
        // Cruise at the top rate, blends as short as the acceleration allows.
        let blend_peak: T = convert(BLEND_PEAK_ACCELERATION);
        let blend = blend_peak * max_rate / max_acceleration;
        let cruise_duration = T::one() / max_rate + blend;
        let has_cruise = cruise_duration >= blend + blend;
        if has_cruise && cruise_duration < quintic && cruise_duration >= floor {
            Self {
                duration_s: cruise_duration,
                blend_s: blend,
                cruise_rate: max_rate,
            }
        } else {
            quintic_scaling
        }
    }

    /// The move's duration, s.
    pub fn duration(&self) -> T {
        self.duration_s
    }

    /// The progress at `t` (clamped to the move).
    pub fn at(&self, t: T) -> Progress<T> {
        let t = t.max(T::zero()).min(self.duration_s);
        if self.blend_s <= T::zero() {
            return rest_to_rest(t / self.duration_s, self.duration_s);
        }
        let rate = self.cruise_rate;
        let blend = self.blend_s;
        let half: T = convert(0.5);
        if t <= blend {
            self.blend_up(t)
        } else if t >= self.duration_s - blend {
            let mirrored = self.blend_up(self.duration_s - t);
            Progress {
                s: T::one() - mirrored.s,
                rate: mirrored.rate,
                acceleration: -mirrored.acceleration,
            }
        } else {
            Progress {
                s: rate * blend * half + rate * (t - blend),
                rate,
                acceleration: T::zero(),
            }
        }
    }

    /// The first blend at `t` (`0 <= t <= T_b`): speed `V g(u)`, `u = t / T_b`.
    fn blend_up(&self, t: T) -> Progress<T> {
        let u = t / self.blend_s;
        let (u2, u3) = (u * u, u * u * u);
        let c = |x: f64| -> T { convert(x) };
        let g = u3 * (c(10.0) - c(15.0) * u + c(6.0) * u2);
        let g_integral = u3 * u * (c(2.5) - c(3.0) * u + u2);
        let one_less = T::one() - u;
        let g_rate = c(30.0) * u2 * one_less * one_less;
        let rate = self.cruise_rate;
        Progress {
            s: rate * self.blend_s * g_integral,
            rate: rate * g,
            acceleration: rate * g_rate / self.blend_s,
        }
    }
}

/// The rest-to-rest quintic `10 tau^3 - 15 tau^4 + 6 tau^5` at `tau` (0 to 1)
/// of a move lasting `duration`.
pub fn rest_to_rest<T: RealField + Copy>(tau: T, duration: T) -> Progress<T> {
    let c = |x: f64| -> T { convert(x) };
    let (tau2, tau3) = (tau * tau, tau * tau * tau);
    let one_less = T::one() - tau;
    Progress {
        s: tau3 * (c(10.0) - c(15.0) * tau + c(6.0) * tau2),
        rate: c(30.0) * tau2 * one_less * one_less / duration,
        acceleration: c(60.0) * tau * one_less * (T::one() - tau - tau) / (duration * duration),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_derivatives(scaling: &TimeScaling<f64>) {
        let h = 1e-6;
        let d = scaling.duration();
        for k in 1..200 {
            let t = d * f64::from(k) / 200.0;
            let (m, p, at) = (scaling.at(t - h), scaling.at(t + h), scaling.at(t));
            assert!(
                ((p.s - m.s) / (2.0 * h) - at.rate).abs() < 1e-6,
                "rate at {t}"
            );
            assert!(
                ((p.rate - m.rate) / (2.0 * h) - at.acceleration).abs() < 1e-4,
                "acceleration at {t}"
            );
        }
    }

    #[test]
    fn a_long_move_cruises_at_its_top_rate_and_is_faster_than_the_quintic() {
        // A 3.3 m sweep at 0.5 m/s and 1.5 m/s^2, as a fraction of the path.
        let (rate, acceleration) = (0.5 / 3.3, 1.5 / 3.3);
        let scaling = TimeScaling::<f64>::shortest(rate, acceleration, 0.5);
        assert!(scaling.blend_s > 0.0, "cruises");
        let quintic = 1.875 / rate;
        assert!(
            scaling.duration() < 0.6 * quintic,
            "{} vs {quintic}",
            scaling.duration()
        );
        check_derivatives(&scaling);
        let d = scaling.duration();
        let (mut top_rate, mut top_acceleration) = (0.0_f64, 0.0_f64);
        for k in 0..=2000 {
            let p = scaling.at(d * f64::from(k) / 2000.0);
            top_rate = top_rate.max(p.rate);
            top_acceleration = top_acceleration.max(p.acceleration.abs());
        }
        assert!(top_rate <= rate * (1.0 + 1e-12));
        assert!(top_acceleration <= acceleration * (1.0 + 1e-9));
        let (start, end) = (scaling.at(0.0), scaling.at(d));
        assert!(start.s.abs() < 1e-15 && start.rate.abs() < 1e-15);
        assert!((end.s - 1.0).abs() < 1e-12 && end.rate.abs() < 1e-12);
        assert!(end.acceleration.abs() < 1e-12);
    }

    #[test]
    fn a_short_move_is_the_quintic() {
        let scaling = TimeScaling::<f64>::shortest(0.5 / 0.2, 1.5 / 0.2, 0.5);
        assert_eq!(scaling.blend_s, 0.0);
        let quintic = (1.875_f64 / 2.5).max((5.773_502_691_896_258_f64 / 7.5).sqrt());
        assert!((scaling.duration() - quintic).abs() < 1e-12);
        check_derivatives(&scaling);
        assert!((scaling.at(scaling.duration()).s - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_shortest_duration_is_kept_and_bad_limits_give_it() {
        let scaling = TimeScaling::<f64>::shortest(100.0, 1000.0, 0.5);
        assert!((scaling.duration() - 0.5).abs() < 1e-12);
        let scaling = TimeScaling::<f64>::shortest(f64::NAN, 1.0, 0.5);
        assert!((scaling.duration() - 0.5).abs() < 1e-12);
        assert!((scaling.at(0.5).s - 1.0).abs() < 1e-12);
    }
}
