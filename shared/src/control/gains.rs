//! Outer-loop gains of the task-space law, chosen by natural frequency and damping.
//!
//! The linearising feedback turns the arm into six decoupled double integrators
//! (Eqs 21-22), and Eq 23's `F_i = [f_i2 f_i1]` (here `Kp`, `Kd`; the paper's
//! `Kv`) makes each error obey `e_ddot = -Kd e_dot - Kp e` (plus `- Ki int e`
//! with integral action), so the gains are chosen by pole placement rather
//! than tuned by hand: the error
//! polynomial is `(s^2 + 2 zeta wn s + wn^2)(s + p)` with `p` the integrator pole
//! (`p = 0` gives the paper's pure PD loop).

use nalgebra::RealField;

use super::error::ControlError;

/// PID gains of one group of task coordinates (all three axes share them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisGains<T> {
    /// Proportional gain `Kp` (1/s^2).
    pub kp: T,
    /// Derivative gain `Kd` (1/s).
    pub kd: T,
    /// Integral gain `Ki` (1/s^3); 0 for the paper's PD loop.
    pub ki: T,
}

impl<T: RealField + Copy> AxisGains<T> {
    /// Gains that place the error poles at `s^2 + 2 zeta wn s + wn^2 = 0` and
    /// `s = -integrator_pole`.
    ///
    /// Expanding `(s^2 + 2 zeta wn s + wn^2)(s + p)` gives `Kd = 2 zeta wn + p`,
    /// `Kp = wn^2 + 2 zeta wn p`, `Ki = wn^2 p`: the PD part keeps the chosen
    /// damping and the integrator only removes the constant error left by model
    /// mismatch (payload, friction), which pure PD cannot.
    pub fn from_poles(
        natural_frequency: T,
        damping_ratio: T,
        integrator_pole: T,
    ) -> Result<Self, ControlError> {
        let valid = |x: T| x.is_finite() && x >= T::zero();
        if !valid(natural_frequency) || natural_frequency <= T::zero() {
            return Err(ControlError::InvalidConfiguration(
                "natural frequency must be finite and > 0",
            ));
        }
        if !valid(damping_ratio) {
            return Err(ControlError::InvalidConfiguration(
                "damping ratio must be finite and >= 0",
            ));
        }
        if !valid(integrator_pole) {
            return Err(ControlError::InvalidConfiguration(
                "integrator pole must be finite and >= 0",
            ));
        }
        let wn = natural_frequency;
        let two_zeta_wn = (damping_ratio + damping_ratio) * wn;
        Ok(Self {
            kp: wn * wn + two_zeta_wn * integrator_pole,
            kd: two_zeta_wn + integrator_pole,
            ki: wn * wn * integrator_pole,
        })
    }

    /// The paper's PD loop (Eq 23): no integral action.
    pub fn pd(natural_frequency: T, damping_ratio: T) -> Result<Self, ControlError> {
        Self::from_poles(natural_frequency, damping_ratio, T::zero())
    }
}

/// Gains for the translational and rotational task coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskGains<T> {
    /// Gains on the flange position error (base frame).
    pub position: AxisGains<T>,
    /// Gains on the flange orientation error (log map, base frame).
    pub orientation: AxisGains<T>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed-loop characteristic polynomial s^3 + Kd s^2 + Kp s + Ki must
    /// vanish at the three placed poles.
    #[test]
    fn gains_place_the_requested_poles() {
        let (wn, zeta, p) = (25.0_f64, 0.9, 6.0);
        let g = AxisGains::from_poles(wn, zeta, p).unwrap();
        let poly_at = |re: f64, im: f64| {
            // evaluate s^3 + kd s^2 + kp s + ki at complex s = re + i im
            let (s2r, s2i) = (re * re - im * im, 2.0 * re * im);
            let (s3r, s3i) = (s2r * re - s2i * im, s2r * im + s2i * re);
            (
                s3r + g.kd * s2r + g.kp * re + g.ki,
                s3i + g.kd * s2i + g.kp * im,
            )
        };
        let wd = wn * (1.0 - zeta * zeta).sqrt();
        for (re, im) in [(-p, 0.0), (-zeta * wn, wd), (-zeta * wn, -wd)] {
            let (r, i) = poly_at(re, im);
            assert!(r.abs() < 1e-8 && i.abs() < 1e-8, "pole {re}+{im}i: {r} {i}");
        }
        let pd = AxisGains::pd(wn, zeta).unwrap();
        assert_eq!(pd.ki, 0.0);
        assert!((pd.kp - wn * wn).abs() < 1e-12);
        assert!((pd.kd - 2.0 * zeta * wn).abs() < 1e-12);
    }

    #[test]
    fn bad_gains_are_rejected() {
        assert!(AxisGains::pd(f64::NAN, 1.0).is_err());
        assert!(AxisGains::pd(0.0_f64, 1.0).is_err());
        assert!(AxisGains::pd(10.0_f64, -1.0).is_err());
        assert!(AxisGains::from_poles(10.0_f64, 1.0, f64::INFINITY).is_err());
    }
}
