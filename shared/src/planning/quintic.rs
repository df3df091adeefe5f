//! Quintic boundary-value segments.
//!
//! Eq 23 feeds the desired acceleration straight into the torques, so a path whose
//! acceleration jumps makes the torques jump. A quintic meets position, velocity
//! and acceleration at both ends: the gripper leaves its current motion and
//! arrives matching the part's (velocity and acceleration included) without a
//! step anywhere.

use nalgebra::{convert, RealField, SVector};

use super::PlanError;

/// `p(t) = c0 + c1 t + ... + c5 t^5` on `[0, duration]`, in `D` dimensions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quintic<T: RealField + Copy, const D: usize> {
    coefficients: [SVector<T, D>; 6],
    duration: T,
}

impl<T: RealField + Copy, const D: usize> Quintic<T, D> {
    /// The segment from `(p0, v0, a0)` at 0 to `(p1, v1, a1)` at `duration`.
    pub fn new(
        start: [SVector<T, D>; 3],
        end: [SVector<T, D>; 3],
        duration: T,
    ) -> Result<Self, PlanError> {
        if !(duration.is_finite() && duration > T::zero()) {
            return Err(PlanError::InvalidDuration);
        }
        let finite = start
            .iter()
            .chain(end.iter())
            .all(|v| v.iter().all(|x| x.is_finite()));
        if !finite {
            return Err(PlanError::NonFinite {
                what: "quintic boundary state",
            });
        }
        let [p0, v0, a0] = start;
        let [p1, v1, a1] = end;
        let c = |k: f64| -> T { convert(k) };
        let t1 = duration;
        let t2 = t1 * t1;
        let t3 = t2 * t1;
        let t4 = t3 * t1;
        let t5 = t4 * t1;
        let dp = p1 - p0;
        let c3 = (dp * c(20.0) - (v1 * c(8.0) + v0 * c(12.0)) * t1 - (a0 * c(3.0) - a1) * t2)
            / (c(2.0) * t3);
        let c4 =
            (dp * c(-30.0) + (v1 * c(14.0) + v0 * c(16.0)) * t1 + (a0 * c(3.0) - a1 * c(2.0)) * t2)
                / (c(2.0) * t4);
        let c5 = (dp * c(12.0) - (v1 + v0) * (c(6.0) * t1) + (a1 - a0) * t2) / (c(2.0) * t5);
        Ok(Self {
            coefficients: [p0, v0, a0 * c(0.5), c3, c4, c5],
            duration,
        })
    }

    /// The segment's duration, s.
    pub fn duration(&self) -> T {
        self.duration
    }

    /// Position, velocity and acceleration at `t`, clamped to the segment.
    ///
    /// Component by component (the same Horner forms, so the same bits as the
    /// vector expressions): sampled every control period, and nalgebra's
    /// element loops are not unrolled in the firmware's size-tuned build.
    pub fn sample(&self, t: T) -> [SVector<T, D>; 3] {
        let t = t.max(T::zero()).min(self.duration);
        let [c0, c1, c2, c3, c4, c5] = &self.coefficients;
        let k = |x: f64| -> T { convert(x) };
        let (two, three, four, five) = (k(2.0), k(3.0), k(4.0), k(5.0));
        let (six, twelve, twenty) = (k(6.0), k(12.0), k(20.0));
        let (mut p, mut v, mut a) = (
            SVector::<T, D>::zeros(),
            SVector::<T, D>::zeros(),
            SVector::<T, D>::zeros(),
        );
        let outputs = p.iter_mut().zip(v.iter_mut()).zip(a.iter_mut());
        let inputs = c0.iter().zip(c1.iter()).zip(c2.iter()).zip(c3.iter());
        for (((((p, v), a), (((&k0, &k1), &k2), &k3)), &k4), &k5) in
            outputs.zip(inputs).zip(c4.iter()).zip(c5.iter())
        {
            *p = k0 + (k1 + (k2 + (k3 + (k4 + k5 * t) * t) * t) * t) * t;
            *v = k1 + (k2 * two + (k3 * three + (k4 * four + k5 * (five * t)) * t) * t) * t;
            *a = k2 * two + (k3 * six + (k4 * twelve + k5 * (twenty * t)) * t) * t;
        }
        [p, v, a]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn meets_both_boundary_states_and_is_smooth() {
        let start = [
            Vector3::new(0.1, -0.2, 0.5),
            Vector3::new(0.3, 0.0, -0.1),
            Vector3::new(0.0, 1.0, 0.0),
        ];
        let end = [
            Vector3::new(0.6, 0.4, 0.2),
            Vector3::new(-0.2, 0.25, 0.0),
            Vector3::new(-0.1, 0.0, 0.3),
        ];
        let q = Quintic::new(start, end, 1.7).unwrap();
        let s0 = q.sample(0.0);
        let s1 = q.sample(1.7);
        for i in 0..3 {
            assert!((s0[i] - start[i]).norm() < 1e-12, "start {i}");
            assert!((s1[i] - end[i]).norm() < 1e-12, "end {i}");
        }
        // Velocity and acceleration are the derivatives of position.
        let h = 1e-5;
        for &t in &[0.2, 0.85, 1.4] {
            let [p_minus, _, _]: [Vector3<f64>; 3] = q.sample(t - h);
            let [p, v, a]: [Vector3<f64>; 3] = q.sample(t);
            let [p_plus, _, _]: [Vector3<f64>; 3] = q.sample(t + h);
            assert!((v - (p_plus - p_minus) / (2.0 * h)).norm() < 1e-8);
            assert!((a - (p_plus - 2.0 * p + p_minus) / (h * h)).norm() < 1e-4);
        }
        // Clamped outside the segment.
        assert_eq!(q.sample(5.0)[0], s1[0]);
    }

    #[test]
    fn refuses_bad_durations_and_nan() {
        let z: [Vector3<f64>; 3] = [Vector3::zeros(); 3];
        assert_eq!(Quintic::new(z, z, 0.0), Err(PlanError::InvalidDuration));
        assert_eq!(
            Quintic::new(z, z, f64::NAN),
            Err(PlanError::InvalidDuration)
        );
        let mut bad = z;
        bad[1].x = f64::INFINITY;
        assert!(matches!(
            Quintic::new(bad, z, 1.0),
            Err(PlanError::NonFinite { .. })
        ));
    }
}
