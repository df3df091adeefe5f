//! Motor armature inertia and joint friction, referred to the joint side.
//!
//! The table gives Jm, B and Tc on the motor side. A motor turning `G` times faster than its joint
//! reflects its inertia and viscous friction to the joint by `G^2` and its Coulomb torque by `|G|`
//! (the Corke toolbox convention): `tau_drive = G^2 Jm qdd + G^2 B qd + |G| Tc(qd)`. These are the
//! non-rigid parts of `D(q)` and `C(q, qd)` in Eq 16 that the reference vectors leave out.

use nalgebra::RealField;

/// Suggested Coulomb smoothing width for the simulated plant (rad/s), for
/// [`Puma560::try_with_coulomb_smoothing`].
///
/// Why 0.01: near `qd = 0` the tanh law acts as a viscous damper of slope `|G| Tc / w`. Divided
/// by the joint's inertia with armature on (at least 0.17 kg m^2 for the wrist, 0.9 to 4.4 for
/// the arm joints) this gives decay rates up to ~760 1/s (joint 1: 62.6 * 0.435 / 0.01 / 3.6;
/// joint 3: 53.7 * 0.132 / 0.01 / 0.94). RK4 at 1 kHz is stable for `h * lambda < 2.78`, so
/// `h * lambda <= 0.8` leaves margin, while the law still reaches 76% of the full Coulomb torque
/// at 0.01 rad/s and 99.9% at 0.04 rad/s.
pub const SIMULATOR_COULOMB_WIDTH: f64 = 0.01;

use super::model::Puma560;
use super::JointVector;

impl<T: RealField + Copy> Puma560<T> {
    /// `G^2 Jm` per joint, or zeros with armature off: added to the diagonal of `D(q)`.
    pub fn armature_inertia(&self) -> JointVector<T> {
        if self.options.armature {
            JointVector::from(self.joint_drives.map(|drive| drive.armature))
        } else {
            JointVector::zeros()
        }
    }

    /// Joint friction torque that the motors must overcome (same sign as `qd`), or zeros with
    /// friction off: `G^2 B qd + |G| Tc`, with `Tc+` for `qd > 0`, `Tc-` for `qd < 0`, 0 at rest;
    /// or, with Coulomb smoothing of width `w`, `|G| Tc(sign) tanh(qd / w)` (continuous through 0).
    pub fn friction_torque(&self, qd: &JointVector<T>) -> JointVector<T> {
        if !self.options.friction {
            return JointVector::zeros();
        }
        let rates: [T; 6] = (*qd).into();
        let mut torque = [T::zero(); 6];
        for ((out, drive), rate) in torque.iter_mut().zip(self.joint_drives.iter()).zip(rates) {
            let coulomb = match self.coulomb_smoothing {
                None => {
                    if rate > T::zero() {
                        drive.coulomb_positive
                    } else if rate < T::zero() {
                        drive.coulomb_negative
                    } else {
                        T::zero()
                    }
                }
                Some(width) => {
                    let blend = (rate / width).tanh();
                    if rate >= T::zero() {
                        drive.coulomb_positive * blend
                    } else {
                        -drive.coulomb_negative * blend
                    }
                }
            };
            *out = drive.viscous * rate + coulomb;
        }
        JointVector::from(torque)
    }
}
