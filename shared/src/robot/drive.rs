//! Motor armature inertia and joint friction, referred to the joint side.
//!
//! The table gives Jm, B and Tc on the motor side. A motor turning `G` times faster than its joint
//! reflects its inertia and viscous friction to the joint by `G^2` and its Coulomb torque by `|G|`
//! (the Corke toolbox convention): `tau_drive = G^2 Jm qdd + G^2 B qd + |G| Tc(qd)`. These are the
//! non-rigid parts of `D(q)` and `C(q, qd)` in Eq 16 that the reference vectors leave out.

use nalgebra::RealField;

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
