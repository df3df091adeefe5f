//! The conveyor's angle, speed and acceleration from its encoder.
//!
//! Eq 1 needs theta(t) at control rate, and the interception needs its first two
//! derivatives; counts are quantised (one count = 2 pi / counts-per-revolution),
//! so differencing them is noisy. A constant-acceleration Kalman filter (white
//! jerk) smooths them and reports its uncertainty. Quantisation is modelled as
//! uniform noise of variance q^2 / 12.
//!
//! The state is kept relative to a whole-count origin that moves with the disc,
//! so the filter stays exact in `f32` however many turns the conveyor makes.

use nalgebra::{convert, Matrix3, RealField, Vector3};

use crate::angle::{wrap_pi, WrapPi};
use crate::kernels::{add3, all_finite, scale3};

use super::{CounterWidth, EncoderUnwrapper, FusionError};

/// The filter's estimate at its last update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConveyorState<T> {
    /// theta wrapped to (-pi, pi] (for Eq 2's sin and cos; exact in `f32`).
    pub theta_wrapped: T,
    /// d theta / dt, rad/s.
    pub omega: T,
    /// d^2 theta / dt^2, rad/s^2.
    pub alpha: T,
    /// Variances of theta, omega, alpha (the filter's covariance diagonal;
    /// the one-sigma values are methods: the control period does not need
    /// their square roots, telemetry does).
    pub variance_theta: T,
    /// The variance of omega (see `variance_theta`).
    pub variance_omega: T,
    /// The variance of alpha (see `variance_theta`).
    pub variance_alpha: T,
}

impl<T: RealField + Copy> ConveyorState<T> {
    /// One-sigma uncertainty of theta (rad).
    pub fn sigma_theta(&self) -> T {
        self.variance_theta.sqrt()
    }

    /// One-sigma uncertainty of omega (rad/s).
    pub fn sigma_omega(&self) -> T {
        self.variance_omega.sqrt()
    }

    /// One-sigma uncertainty of alpha (rad/s^2).
    pub fn sigma_alpha(&self) -> T {
        self.variance_alpha.sqrt()
    }
}

/// Kalman filter on the unwrapped conveyor angle.
#[derive(Debug, Clone)]
pub struct ConveyorFilter<T: RealField + Copy> {
    unwrapper: EncoderUnwrapper,
    counts_per_rev: i64,
    rad_per_count: T,
    /// The state's angle is `(origin_counts * rad_per_count) + x[0]`.
    origin_counts: i64,
    x: Vector3<T>,
    p: Matrix3<T>,
    last_time_us: Option<u64>,
    jerk_psd: T,
    measurement_var: T,
}

impl<T: RealField + Copy + WrapPi> ConveyorFilter<T> {
    /// `jerk_psd` (rad^2/s^5) sets how quickly the speed may change: about 1 tracks a
    /// few per cent of speed ripple at 1 Hz; smaller smooths more.
    pub fn new(counts_per_rev: u32, width: CounterWidth, jerk_psd: T) -> Result<Self, FusionError> {
        if counts_per_rev == 0 {
            return Err(FusionError::ZeroCountsPerRevolution);
        }
        if !(jerk_psd.is_finite() && jerk_psd > T::zero()) {
            return Err(FusionError::InvalidParameter {
                what: "jerk_psd must be finite and positive",
            });
        }
        let rad_per_count: T = convert(core::f64::consts::TAU / f64::from(counts_per_rev));
        let twelve: T = convert(12.0);
        Ok(Self {
            unwrapper: EncoderUnwrapper::new(width),
            counts_per_rev: i64::from(counts_per_rev),
            rad_per_count,
            origin_counts: 0,
            x: Vector3::zeros(),
            p: Matrix3::zeros(),
            last_time_us: None,
            jerk_psd,
            measurement_var: rad_per_count * rad_per_count / twelve,
        })
    }

    /// Radians per encoder count.
    pub fn rad_per_count(&self) -> T {
        self.rad_per_count
    }

    /// Unwrapped count of the last update (0 at the first reading).
    pub fn total_counts(&self) -> i64 {
        self.unwrapper.total()
    }

    /// The unwrapped theta of an unwrapped count, in `f64` (the log's `conveyor_angle_rad`).
    pub fn theta_of_counts(&self, counts: i64) -> f64 {
        counts as f64 * core::f64::consts::TAU / self.counts_per_rev as f64
    }

    /// The unwrapped count a raw reading latched near the last update stands for.
    pub fn unwrap_latched(&self, raw: u32) -> Result<i64, FusionError> {
        self.unwrapper.peek(raw)
    }

    /// Absorbs one reading taken at `time_us`. On error nothing changes.
    pub fn update(&mut self, raw: u32, time_us: u64) -> Result<ConveyorState<T>, FusionError> {
        let counts = self.unwrapper.peek(raw)?;
        let Some(last) = self.last_time_us else {
            self.unwrapper.update(raw)?;
            self.origin_counts = counts;
            self.x = Vector3::zeros();
            // Speed and acceleration are unknown at start: a wide prior.
            let speed_var: T = convert(100.0);
            self.p =
                Matrix3::from_diagonal(&Vector3::new(self.measurement_var, speed_var, speed_var));
            self.last_time_us = Some(time_us);
            return Ok(self.state());
        };
        if time_us <= last {
            return Err(FusionError::TimeNotIncreasing {
                dt_s: (time_us as f64 - last as f64) * 1e-6,
            });
        }
        // Through T's own conversion from an integer, not f64 arithmetic
        // (software on the M4F).
        let elapsed_us = time_us - last;
        let elapsed = match u32::try_from(elapsed_us) {
            Ok(small) => T::from_u32(small),
            Err(_) => T::from_u64(elapsed_us),
        };
        let dt = elapsed.unwrap_or_else(T::zero) * convert(1e-6);
        let (x, p) = self.predicted(dt);
        let z: T = convert((counts - self.origin_counts) as f64);
        let z = z * self.rad_per_count;
        let innovation = z - x.x;
        let s = p.m11 + self.measurement_var;
        // A disc cannot jump: a reading beyond 10 sigmas of the prediction, 16
        // counts and 0.01 rad (room for quantisation and for a speed step the
        // filter has not followed yet: an instant reversal at 0.8 rad/s strays
        // 0.0033 rad) is a glitch, refused before it throws Eq 1's part across
        // the disc. Smaller losses are the view monitor's to find.
        let gate = (convert::<f64, T>(10.0) * s.sqrt())
            .max(convert::<f64, T>(16.0) * self.rad_per_count)
            .max(convert::<f64, T>(0.01));
        if innovation.abs() > gate {
            return Err(FusionError::Implausible {
                innovation_rad: innovation.to_subset().unwrap_or(f64::NAN),
                gate_rad: gate.to_subset().unwrap_or(f64::NAN),
            });
        }
        // The Kalman update written out (every period on the M4F, where
        // nalgebra's element loops are not unrolled); the same operations in
        // the same order as `x + K e`, `P - K P_row0`, `(P + P^T) / 2`.
        let gain = Vector3::new(p.m11 / s, p.m21 / s, p.m31 / s);
        let x = add3(&x, &scale3(&gain, innovation));
        let row0 = [p.m11, p.m12, p.m13];
        let updated = Matrix3::from_fn(|i, j| {
            let g = gain.get(i).copied().unwrap_or_else(T::zero);
            let r = row0.get(j).copied().unwrap_or_else(T::zero);
            p.get((i, j)).copied().unwrap_or_else(T::zero) - g * r
        });
        let half: T = convert(0.5);
        let p = Matrix3::from_fn(|i, j| {
            let upper = updated.get((i, j)).copied().unwrap_or_else(T::zero);
            let lower = updated.get((j, i)).copied().unwrap_or_else(T::zero);
            (upper + lower) * half
        });
        if !(all_finite(&x) && all_finite(&p)) {
            return Err(FusionError::NonFinite {
                what: "conveyor filter state",
            });
        }
        self.unwrapper.update(raw)?;
        self.x = x;
        self.p = p;
        self.last_time_us = Some(time_us);
        self.rebase();
        Ok(self.state())
    }

    /// The estimate at the last update.
    pub fn state(&self) -> ConveyorState<T> {
        self.state_of(&self.x, &self.p)
    }

    /// The estimate extrapolated `dt_s` past the last update (e.g. to a control tick
    /// between encoder samples).
    pub fn predict(&self, dt_s: T) -> ConveyorState<T> {
        let (x, p) = self.predicted(dt_s);
        self.state_of(&x, &p)
    }

    /// The constant-acceleration model's prediction `F x`, `F P F^T + Q` over
    /// `dt`, with `F = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]` written out
    /// (every period on the M4F; the 3x3 products through nalgebra cost 900
    /// instructions there). Only `F`'s zero and unit terms are dropped, so the
    /// result is the matrix product's to the bit.
    fn predicted(&self, dt: T) -> (Vector3<T>, Matrix3<T>) {
        let half: T = convert(0.5);
        let dt2 = dt * dt;
        let h = half * dt2;
        let x = &self.x;
        let predicted_x = Vector3::new(x.x + dt * x.y + h * x.z, x.y + dt * x.z, x.z);
        let p = &self.p;
        // A = F P, row by row.
        let a0 = [
            p.m11 + dt * p.m21 + h * p.m31,
            p.m12 + dt * p.m22 + h * p.m32,
            p.m13 + dt * p.m23 + h * p.m33,
        ];
        let a1 = [p.m21 + dt * p.m31, p.m22 + dt * p.m32, p.m23 + dt * p.m33];
        let a2 = [p.m31, p.m32, p.m33];
        // (A F^T)_ij = A_i . F_j.
        let times_ft = |[r0, r1, r2]: [T; 3]| [r0 + r1 * dt + r2 * h, r1 + r2 * dt, r2];
        let [b0, b1, b2] = [times_ft(a0), times_ft(a1), times_ft(a2)];
        let q = self.jerk_psd;
        let dt3 = dt2 * dt;
        let dt4 = dt3 * dt;
        let dt5 = dt4 * dt;
        let c = |k: f64| -> T { convert(k) };
        let (q11, q12, q13) = (dt5 / c(20.0) * q, dt4 / c(8.0) * q, dt3 / c(6.0) * q);
        let (q22, q23, q33) = (dt3 / c(3.0) * q, dt2 / c(2.0) * q, dt * q);
        let predicted_p = Matrix3::new(
            b0[0] + q11,
            b0[1] + q12,
            b0[2] + q13,
            b1[0] + q12,
            b1[1] + q22,
            b1[2] + q23,
            b2[0] + q13,
            b2[1] + q23,
            b2[2] + q33,
        );
        (predicted_x, predicted_p)
    }

    /// Moves whole counts from the state into the
    /// integer origin, keeping `x[0]` small so `f32` keeps its resolution.
    fn rebase(&mut self) {
        let limit: T = convert(core::f64::consts::PI);
        if self.x.x.abs() <= limit {
            return;
        }
        let shift_f = (self.x.x / self.rad_per_count).round();
        let Some(shift) = nalgebra::try_convert::<T, f64>(shift_f) else {
            return;
        };
        let shift = shift as i64;
        self.origin_counts = self.origin_counts.wrapping_add(shift);
        self.x.x -= convert::<f64, T>(shift as f64) * self.rad_per_count;
    }

    fn state_of(&self, x: &Vector3<T>, p: &Matrix3<T>) -> ConveyorState<T> {
        let origin_mod = self.origin_counts.rem_euclid(self.counts_per_rev);
        let origin_angle: T = convert(origin_mod as f64);
        let theta = wrap_pi(origin_angle * self.rad_per_count + x.x);
        ConveyorState {
            theta_wrapped: theta,
            omega: x.y,
            alpha: x.z,
            variance_theta: p.m11.max(T::zero()),
            variance_omega: p.m22.max(T::zero()),
            variance_alpha: p.m33.max(T::zero()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The written-out prediction is the matrix product `F P F^T + Q` to the bit.
    #[test]
    fn prediction_equals_the_matrix_products() {
        let mut seed = 3_u64;
        for _ in 0..500 {
            let mut filter = ConveyorFilter::<f32>::new(4096, CounterWidth::Bits16, 0.7).unwrap();
            let mut random = || (crate::test_rng::splitmix(&mut seed) * 2.0 - 1.0) as f32;
            filter.x = Vector3::new(random(), random(), random());
            let m = Matrix3::from_fn(|_, _| random());
            filter.p = m * m.transpose();
            let dt = (random() + 1.5) * 1e-3;
            let (x, p) = filter.predicted(dt);
            let f = Matrix3::new(1.0, dt, 0.5 * dt * dt, 0.0, 1.0, dt, 0.0, 0.0, 1.0);
            let (dt2, q) = (dt * dt, filter.jerk_psd);
            let (dt3, dt4, dt5) = (dt2 * dt, dt2 * dt * dt, dt2 * dt * dt * dt);
            let process = Matrix3::new(
                dt5 / 20.0,
                dt4 / 8.0,
                dt3 / 6.0,
                dt4 / 8.0,
                dt3 / 3.0,
                dt2 / 2.0,
                dt3 / 6.0,
                dt2 / 2.0,
                dt,
            ) * q;
            assert_eq!(x, f * filter.x);
            assert_eq!(p, f * filter.p * f.transpose() + process);
        }
    }

    const CPR: u32 = 16_384;

    fn quantised(theta: f64, width: CounterWidth, start_raw: u32) -> u32 {
        let counts = (theta / core::f64::consts::TAU * f64::from(CPR)).floor() as i64;
        let modulus = i64::from(width.max()) + 1;
        ((i64::from(start_raw) + counts).rem_euclid(modulus)) as u32
    }

    fn angle_error(a: f64, b: f64) -> f64 {
        wrap_pi(a - b).abs()
    }

    /// Speed ripple, a reversal and a standstill, through a wrapping 16-bit counter.
    fn run<T: RealField + Copy + WrapPi>(tol_theta: f64, tol_omega: f64) {
        let mut filter = ConveyorFilter::<T>::new(CPR, CounterWidth::Bits16, convert(1.0)).unwrap();
        let profile = |t: f64| -> (f64, f64) {
            // omega(t): 0.5 rad/s with 5 % ripple at 1 Hz for 20 s, then -0.3 rad/s, then 0.
            let omega = if t < 20.0 {
                0.5 + 0.025 * (core::f64::consts::TAU * t).sin()
            } else if t < 30.0 {
                -0.3
            } else {
                0.0
            };
            let theta = if t < 20.0 {
                0.5 * t
                    + 0.025 / core::f64::consts::TAU * (1.0 - (core::f64::consts::TAU * t).cos())
            } else if t < 30.0 {
                10.0 + 0.025 / core::f64::consts::TAU
                    * (1.0 - (core::f64::consts::TAU * 20.0).cos())
                    - 0.3 * (t - 20.0)
            } else {
                10.0 - 3.0
            };
            (theta, omega)
        };
        let mut worst_theta: f64 = 0.0;
        let mut worst_omega: f64 = 0.0;
        for k in 0..40_000u64 {
            let t = k as f64 * 1e-3;
            let (theta, omega) = profile(t);
            let raw = quantised(theta, CounterWidth::Bits16, 65_000);
            let s = filter.update(raw, k * 1000).unwrap();
            let settled = (1.0..19.5).contains(&t) || (21.0..29.5).contains(&t) || t > 31.0;
            if settled {
                let th: f64 = nalgebra::try_convert(s.theta_wrapped).unwrap();
                let om: f64 = nalgebra::try_convert(s.omega).unwrap();
                worst_theta = worst_theta.max(angle_error(th, theta));
                worst_omega = worst_omega.max((om - omega).abs());
            }
        }
        let one_count = core::f64::consts::TAU / f64::from(CPR);
        assert!(
            worst_theta < tol_theta * one_count,
            "theta error {} counts",
            worst_theta / one_count
        );
        assert!(worst_omega < tol_omega, "omega error {worst_omega} rad/s");
        // The unwrapped count ends where the disc is (10 - 3 rad).
        let expected = (7.0 / core::f64::consts::TAU * f64::from(CPR)).floor();
        assert!((filter.total_counts() as f64 - (expected - 0.0)).abs() <= 1.0);
    }

    #[test]
    fn a_counter_glitch_is_refused_and_leaves_the_state_unchanged() {
        let mut filter = ConveyorFilter::<f32>::new(CPR, CounterWidth::Bits16, 1.0).unwrap();
        let mut raw = 1_000u32;
        for k in 0..2_000u64 {
            // 0.5 rad/s is about a count every 0.77 ms at 16384 counts a turn.
            raw = 1_000 + (k as f64 * 1e-3 * 0.5 / core::f64::consts::TAU * f64::from(CPR)) as u32;
            filter.update(raw, k * 1000).unwrap();
        }
        let before = filter.state();
        let error = filter.update(raw - 100, 2_000_000).unwrap_err();
        assert!(
            matches!(error, FusionError::Implausible { .. }),
            "{error:?}"
        );
        assert_eq!(filter.state(), before);
        // The next good reading is taken as usual.
        assert!(filter.update(raw + 1, 2_001_000).is_ok());
    }

    #[test]
    fn tracks_ripple_reversal_and_standstill_in_f64() {
        run::<f64>(2.0, 0.01);
    }

    #[test]
    fn tracks_ripple_reversal_and_standstill_in_f32() {
        run::<f32>(2.0, 0.01);
    }

    #[test]
    fn refuses_time_going_backwards_and_keeps_its_state() {
        let mut filter = ConveyorFilter::<f64>::new(CPR, CounterWidth::Bits32, 1.0).unwrap();
        filter.update(0, 1_000).unwrap();
        let before = filter.update(10, 2_000).unwrap();
        assert!(matches!(
            filter.update(20, 2_000),
            Err(FusionError::TimeNotIncreasing { .. })
        ));
        assert_eq!(filter.state(), before);
        assert_eq!(filter.total_counts(), 10);
    }

    #[test]
    fn refuses_bad_parameters() {
        assert!(ConveyorFilter::<f32>::new(0, CounterWidth::Bits16, 1.0).is_err());
        assert!(ConveyorFilter::<f32>::new(100, CounterWidth::Bits16, f32::NAN).is_err());
        assert!(ConveyorFilter::<f32>::new(100, CounterWidth::Bits16, -1.0).is_err());
    }
}
