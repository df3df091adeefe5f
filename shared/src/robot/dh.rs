//! Standard (distal) Denavit-Hartenberg link transforms, specialised to the twists of the PUMA 560.
//!
//! `A_i(q_i) = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)` (`docs/reference/puma560-model.md`, "Conventions"). Every PUMA
//! twist is 0 or ±pi/2, so `Rx(alpha_i)` is a signed permutation: applying it costs sign flips and
//! swaps instead of a 3x3 product. Only `Rz(q_i)` needs the joint's sine and cosine, computed once
//! per call in [`JointTrig`]. This is what keeps the recursive algorithms fast (the brief's 0.5 us
//! RNEA goal) without a second, hand-expanded copy of the model.

use nalgebra::{RealField, Vector3};

use super::JointVector;
use crate::kernels::{combine3, scale3};

/// The DH twist `alpha_i` of a link; the PUMA 560 only has these three values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Twist {
    /// `alpha = 0`.
    Zero,
    /// `alpha = +pi/2`.
    PlusHalfPi,
    /// `alpha = -pi/2`.
    MinusHalfPi,
}

impl Twist {
    /// `(sin alpha, cos alpha)` as exact small integers.
    pub fn sin_cos(self) -> (i8, i8) {
        match self {
            Twist::Zero => (0, 1),
            Twist::PlusHalfPi => (1, 0),
            Twist::MinusHalfPi => (-1, 0),
        }
    }

    /// The twist angle in radians.
    pub fn radians<T: RealField + Copy>(self) -> T {
        match self {
            Twist::Zero => T::zero(),
            Twist::PlusHalfPi => T::frac_pi_2(),
            Twist::MinusHalfPi => -T::frac_pi_2(),
        }
    }
}

/// One row of the standard DH table (all PUMA offsets are 0, so there is no offset field).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DhLink<T> {
    /// Link length `a_i` along `x_i` (m).
    pub a: T,
    /// Link offset `d_i` along `z_{i-1}` (m).
    pub d: T,
    /// Link twist `alpha_i` about `x_i`.
    pub twist: Twist,
}

impl<T: RealField + Copy> DhLink<T> {
    /// `p*_i`: the origin of frame {i} seen from the origin of frame {i-1}, in frame-{i}
    /// coordinates, `[a, d sin(alpha), d cos(alpha)]` (Luh-Walker-Paul recursive Newton-Euler).
    pub fn origin_in_child(&self) -> Vector3<T> {
        match self.twist {
            Twist::Zero => Vector3::new(self.a, T::zero(), self.d),
            Twist::PlusHalfPi => Vector3::new(self.a, self.d, T::zero()),
            Twist::MinusHalfPi => Vector3::new(self.a, -self.d, T::zero()),
        }
    }

    /// Component of a frame-{i} vector along the joint axis `z_{i-1}`, which is
    /// `[0, sin(alpha), cos(alpha)]` in frame {i}.
    #[inline(always)]
    pub fn along_joint_axis(&self, v_child: &Vector3<T>) -> T {
        match self.twist {
            Twist::Zero => v_child.z,
            Twist::PlusHalfPi => v_child.y,
            Twist::MinusHalfPi => -v_child.y,
        }
    }

    /// `R_i^T v`: re-expresses a frame-{i-1} vector in frame {i}.
    #[inline(always)]
    pub fn to_child(&self, trig: &SinCos<T>, v_parent: &Vector3<T>) -> Vector3<T> {
        let u0 = trig.cos * v_parent.x + trig.sin * v_parent.y;
        let u1 = trig.cos * v_parent.y - trig.sin * v_parent.x;
        let u2 = v_parent.z;
        match self.twist {
            Twist::Zero => Vector3::new(u0, u1, u2),
            Twist::PlusHalfPi => Vector3::new(u0, u2, -u1),
            Twist::MinusHalfPi => Vector3::new(u0, -u2, u1),
        }
    }

    /// `R_i v`: re-expresses a frame-{i} vector in frame {i-1}.
    #[inline(always)]
    pub fn to_parent(&self, trig: &SinCos<T>, v_child: &Vector3<T>) -> Vector3<T> {
        let (w0, w1, w2) = match self.twist {
            Twist::Zero => (v_child.x, v_child.y, v_child.z),
            Twist::PlusHalfPi => (v_child.x, -v_child.z, v_child.y),
            Twist::MinusHalfPi => (v_child.x, v_child.z, -v_child.y),
        };
        Vector3::new(
            trig.cos * w0 - trig.sin * w1,
            trig.sin * w0 + trig.cos * w1,
            w2,
        )
    }

    /// Axes of frame {i} in some outer frame (here the base), given the axes `x, y, z` of frame
    /// {i-1} in that frame: `x_i = c x + s y`, and `y_i`, `z_i` follow from `Rx(alpha_i)`.
    #[inline(always)]
    pub fn child_axes(&self, trig: &SinCos<T>, parent_axes: &[Vector3<T>; 3]) -> [Vector3<T>; 3] {
        let [x, y, z] = parent_axes;
        let x_child = combine3(x, trig.cos, y, trig.sin);
        let y_turned = combine3(y, trig.cos, x, -trig.sin);
        match self.twist {
            Twist::Zero => [x_child, y_turned, *z],
            Twist::PlusHalfPi => [x_child, *z, scale3(&y_turned, -T::one())],
            Twist::MinusHalfPi => [x_child, scale3(z, -T::one()), y_turned],
        }
    }
}

/// Sine and cosine of one joint angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SinCos<T> {
    /// `sin(q_i)`.
    pub sin: T,
    /// `cos(q_i)`.
    pub cos: T,
}

/// Sines and cosines of all six joint angles, computed once per call with libm's correctly
/// rounded-to-1-ulp `sincos` through nalgebra's `RealField` (never micromath's approximations).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointTrig<T> {
    /// Per joint, in order 1..6.
    pub joints: [SinCos<T>; 6],
}

impl<T: RealField + Copy> JointTrig<T> {
    /// Evaluates `sin(q_i)` and `cos(q_i)` for the six joints.
    pub fn new(q: &JointVector<T>) -> Self {
        let joints = core::array::from_fn(|i| {
            let angle = q.get(i).copied().unwrap_or_else(T::zero);
            let (sin, cos) = angle.sin_cos();
            SinCos { sin, cos }
        });
        JointTrig { joints }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3};

    /// The full `R_i = Rz(q) Rx(alpha)` as a matrix, the slow obvious way.
    fn rotation(q: f64, twist: Twist) -> Matrix3<f64> {
        (Rotation3::from_axis_angle(&Vector3::z_axis(), q)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), twist.radians::<f64>()))
        .into_inner()
    }

    #[test]
    fn structured_rotations_match_the_full_matrices() {
        let v = Vector3::new(0.3, -1.7, 2.9);
        for twist in [Twist::Zero, Twist::PlusHalfPi, Twist::MinusHalfPi] {
            let link = DhLink {
                a: 0.2,
                d: 0.4,
                twist,
            };
            for q in [-2.5, -0.3, 0.0, 1.1, 3.0] {
                let (sin, cos) = f64::sin_cos(q);
                let trig = SinCos { sin, cos };
                let full = rotation(q, twist);
                assert!((link.to_parent(&trig, &v) - full * v).abs().max() < 1e-15);
                assert!(
                    (link.to_child(&trig, &v) - full.transpose() * v)
                        .abs()
                        .max()
                        < 1e-15
                );
                let axes = link.child_axes(&trig, &[Vector3::x(), Vector3::y(), Vector3::z()]);
                for (axis, column) in axes.iter().zip(full.column_iter()) {
                    assert!((axis - column).abs().max() < 1e-15);
                }
                // z_{i-1} in frame {i} is the third row of R_i.
                let z_parent_in_child = full.transpose() * Vector3::z();
                assert!((link.along_joint_axis(&v) - z_parent_in_child.dot(&v)).abs() < 1e-15);
            }
            // p*_i = R_i^T (d z + a x_i) at q = 0: the offset of {i} from {i-1} in frame {i}.
            let full = rotation(0.0, twist);
            let offset_parent = Vector3::new(link.a, 0.0, link.d);
            let expected = full.transpose() * offset_parent;
            assert!((link.origin_in_child() - expected).abs().max() < 1e-15);
        }
    }

    #[test]
    fn twist_sin_cos_are_exact() {
        for twist in [Twist::Zero, Twist::PlusHalfPi, Twist::MinusHalfPi] {
            let (s, c) = twist.sin_cos();
            let angle = twist.radians::<f64>();
            assert!((f64::from(s) - angle.sin()).abs() < 1e-15);
            assert!((f64::from(c) - angle.cos()).abs() < 1e-15);
        }
    }
}
