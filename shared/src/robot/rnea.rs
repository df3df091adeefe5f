//! Inverse dynamics by the recursive Newton-Euler algorithm (Luh, Walker and Paul), in link
//! frames: the right-hand side of Eq 16, `tau = D(q) qdd + C(q, qd) + G(q)`, without forming D.
//!
//! Everything is expressed in the moving DH frame {i} so that the inertias are constants and each
//! frame change is one planar rotation plus a signed permutation (see [`super::dh`]). Moments are
//! taken about frame origins with the link's first moment `h = m c`, which keeps the equations
//! linear in the stored [`super::model::BodyInertia`] (payload and mass scaling are sums and
//! products of it).

use nalgebra::{RealField, Vector3};

use super::dh::{DhLink, JointTrig, SinCos};
use super::model::Puma560;
use super::JointVector;
use crate::kernels::{add3, cross3, mul3, scale3};

/// Motion of link frame {i}, in frame-{i} coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkMotion<T> {
    /// Angular velocity.
    pub angular_velocity: Vector3<T>,
    /// Angular acceleration.
    pub angular_acceleration: Vector3<T>,
    /// Classical linear acceleration of the frame origin (including the fictitious base
    /// acceleration `-g` when gravity is folded in).
    pub linear_acceleration: Vector3<T>,
}

impl<T: RealField + Copy> LinkMotion<T> {
    /// The base frame's motion: still, accelerating at `linear_acceleration`.
    fn at_rest(linear_acceleration: &Vector3<T>) -> Self {
        Self {
            angular_velocity: Vector3::zeros(),
            angular_acceleration: Vector3::zeros(),
            linear_acceleration: *linear_acceleration,
        }
    }
}

impl<T: RealField + Copy> Puma560<T> {
    /// Outward recursion: velocities and accelerations of frames {1}..{6} from the base, which
    /// moves with linear acceleration `base_acceleration` (`-g` to fold gravity in).
    ///
    /// `w_i = R_i^T (w_{i-1} + z qd_i)`,
    /// `wd_i = R_i^T (wd_{i-1} + z qdd_i + w_{i-1} x z qd_i)`,
    /// `vd_i = wd_i x p*_i + w_i x (w_i x p*_i) + R_i^T vd_{i-1}`.
    pub fn forward_motion(
        &self,
        trig: &JointTrig<T>,
        qd: &JointVector<T>,
        qdd: &JointVector<T>,
        base_acceleration: &Vector3<T>,
    ) -> [LinkMotion<T>; 6] {
        let mut motion = [LinkMotion::at_rest(base_acceleration); 6];
        self.forward_motion_into(trig, qd, qdd, base_acceleration, &mut motion);
        motion
    }

    /// [`Self::forward_motion`] into the caller's storage.
    #[inline(always)]
    fn forward_motion_into(
        &self,
        trig: &JointTrig<T>,
        qd: &JointVector<T>,
        qdd: &JointVector<T>,
        base_acceleration: &Vector3<T>,
        motion: &mut [LinkMotion<T>; 6],
    ) {
        self.outward(trig, qd, qdd, base_acceleration, |i, link_motion| {
            if let Some(slot) = motion.get_mut(i) {
                *slot = link_motion;
            }
        });
    }

    /// The motion of frame {6} alone ([`Self::forward_motion`]'s last entry,
    /// without keeping the others: `Jdot qd` needs only the flange).
    pub fn flange_motion(
        &self,
        trig: &JointTrig<T>,
        qd: &JointVector<T>,
        qdd: &JointVector<T>,
        base_acceleration: &Vector3<T>,
    ) -> LinkMotion<T> {
        self.outward(trig, qd, qdd, base_acceleration, |_, _| {})
    }

    /// The outward recursion, handing each link's motion to `visit` as it
    /// is found (into the caller's storage: returning the six by value costs
    /// a 216-byte copy a call on the firmware); returns the flange's.
    #[inline(always)]
    fn outward(
        &self,
        trig: &JointTrig<T>,
        qd: &JointVector<T>,
        qdd: &JointVector<T>,
        base_acceleration: &Vector3<T>,
        mut visit: impl FnMut(usize, LinkMotion<T>),
    ) -> LinkMotion<T> {
        let qd_joints: [T; 6] = (*qd).into();
        let qdd_joints: [T; 6] = (*qdd).into();
        let mut current = LinkMotion::at_rest(base_acceleration);
        let per_link = self
            .dh
            .iter()
            .zip(self.origins_in_child.iter())
            .zip(trig.joints.iter())
            .zip(qd_joints.iter().zip(qdd_joints.iter()))
            .enumerate();
        for (i, (((link, origin), joint_trig), (&rate, &accel))) in per_link {
            let LinkMotion {
                angular_velocity: w_parent,
                angular_acceleration: wd_parent,
                linear_acceleration: vd_parent,
            } = current;
            let w_joint = Vector3::new(w_parent.x, w_parent.y, w_parent.z + rate);
            // w_{i-1} x (z qd_i) = qd_i (w_y, -w_x, 0)
            let wd_joint = Vector3::new(
                wd_parent.x + w_parent.y * rate,
                wd_parent.y - w_parent.x * rate,
                wd_parent.z + accel,
            );
            let angular_velocity = link.to_child(joint_trig, &w_joint);
            let angular_acceleration = link.to_child(joint_trig, &wd_joint);
            let linear_acceleration = add3(
                &add3(
                    &cross3(&angular_acceleration, origin),
                    &cross3(&angular_velocity, &cross3(&angular_velocity, origin)),
                ),
                &link.to_child(joint_trig, &vd_parent),
            );
            current = LinkMotion {
                angular_velocity,
                angular_acceleration,
                linear_acceleration,
            };
            visit(i, current);
        }
        current
    }

    /// Rigid-body RNEA with a chosen base acceleration; no armature, no friction.
    ///
    /// Per link, about its frame origin: `F_i = m vd_i + wd_i x h + w_i x (w_i x h)` and
    /// `N_i = I_O wd_i + w_i x (I_O w_i) + h x vd_i`. Inward: `f_i = R_{i+1} f_{i+1} + F_i`,
    /// `n_i = R_{i+1} n_{i+1} + N_i + p*_i x f_i` (moment about the joint-i axis point), and
    /// `tau_i = n_i . z_{i-1}`.
    pub fn rigid_inverse_dynamics_with(
        &self,
        trig: &JointTrig<T>,
        qd: &JointVector<T>,
        qdd: &JointVector<T>,
        base_acceleration: &Vector3<T>,
    ) -> JointVector<T> {
        let mut motion = [LinkMotion::at_rest(base_acceleration); 6];
        self.forward_motion_into(trig, qd, qdd, base_acceleration, &mut motion);
        let mut tau = [T::zero(); 6];
        let mut force = Vector3::zeros();
        let mut moment = Vector3::zeros();
        let per_link = tau
            .iter_mut()
            .zip(motion.iter())
            .zip(self.bodies.iter())
            .zip(self.dh.iter().zip(self.origins_in_child.iter()))
            .zip(trig.joints.iter())
            .rev();
        // The wrench of link i+1 is rotated into frame {i} with link i+1's transform.
        let mut outboard_link: Option<(&DhLink<T>, &SinCos<T>)> = None;
        for ((((tau_out, link_motion), body), (link, origin)), joint_trig) in per_link {
            let LinkMotion {
                angular_velocity: w,
                angular_acceleration: wd,
                linear_acceleration: vd,
            } = *link_motion;
            let h = body.first_moment;
            let inertia_force = add3(
                &add3(&scale3(&vd, body.mass), &cross3(&wd, &h)),
                &cross3(&w, &cross3(&w, &h)),
            );
            let inertia_moment = add3(
                &add3(
                    &mul3(&body.inertia_origin, &wd),
                    &cross3(&w, &mul3(&body.inertia_origin, &w)),
                ),
                &cross3(&h, &vd),
            );
            let (force_from_outboard, moment_from_outboard) = match outboard_link {
                Some((outer_link, outer_trig)) => (
                    outer_link.to_parent(outer_trig, &force),
                    outer_link.to_parent(outer_trig, &moment),
                ),
                None => (Vector3::zeros(), Vector3::zeros()),
            };
            force = add3(&force_from_outboard, &inertia_force);
            moment = add3(
                &add3(&moment_from_outboard, &inertia_moment),
                &cross3(origin, &force),
            );
            *tau_out = link.along_joint_axis(&moment);
            outboard_link = Some((link, joint_trig));
        }
        JointVector::from(tau)
    }
}
