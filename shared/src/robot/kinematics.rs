//! Forward kinematics, geometric Jacobian and its bias `Jdot qd` (the `h(q)` of Eq 17 and the
//! `J_h` and `J_h qd` terms of the linearising feedback, Eq 19).

use nalgebra::{
    Isometry3, Matrix3, Matrix4, Matrix6, RealField, Rotation3, Translation3, UnitQuaternion,
    Vector3, Vector6,
};

use super::dh::JointTrig;
use super::model::Puma560;
use super::JointVector;
use crate::kernels::{add3, cross3, mul3, scale3, sub3};

/// Poses of the DH frames {0}..{6} in the base frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameChain<T> {
    /// `[x, y, z]` axes of frame {i} in base coordinates, i = 0..6.
    pub axes: [[Vector3<T>; 3]; 7],
    /// Origin of frame {i} in base coordinates, i = 0..6.
    pub origins: [Vector3<T>; 7],
}

impl<T: RealField + Copy> FrameChain<T> {
    /// Rotation `base_from_flange` as a matrix (columns are the frame-{6} axes).
    pub fn base_from_flange_rotation(&self) -> Matrix3<T> {
        let [_, _, _, _, _, _, [x, y, z]] = self.axes;
        Matrix3::from_columns(&[x, y, z])
    }

    /// Origin of frame {6} in the base frame.
    pub fn flange_origin(&self) -> Vector3<T> {
        let [_, _, _, _, _, _, origin] = self.origins;
        origin
    }
}

impl<T: RealField + Copy> Puma560<T> {
    /// All DH frames in the base frame: `T_0^i = A_1 ... A_i` built axis by axis, each step one
    /// planar rotation plus the signed permutation of the twist.
    pub fn frame_chain_with(&self, trig: &JointTrig<T>) -> FrameChain<T> {
        let base_axes = [Vector3::x(), Vector3::y(), Vector3::z()];
        let mut axes = [base_axes; 7];
        let mut origins = [Vector3::zeros(); 7];
        let mut parent_axes = base_axes;
        let mut parent_origin = Vector3::zeros();
        let steps = axes
            .iter_mut()
            .skip(1)
            .zip(origins.iter_mut().skip(1))
            .zip(self.dh.iter().zip(trig.joints.iter()));
        for ((axes_out, origin_out), (link, joint_trig)) in steps {
            let child_axes = link.child_axes(joint_trig, &parent_axes);
            let [x_child, _, _] = child_axes;
            let [_, _, z_parent] = parent_axes;
            // A_i = Rz(q) Tz(d) Tx(a) Rx(alpha): d along z_{i-1}, a along the new x_i.
            let origin = add3(
                &add3(&parent_origin, &scale3(&z_parent, link.d)),
                &scale3(&x_child, link.a),
            );
            *axes_out = child_axes;
            *origin_out = origin;
            parent_axes = child_axes;
            parent_origin = origin;
        }
        FrameChain { axes, origins }
    }

    /// `base_from_flange` as a 4x4 homogeneous matrix (exact: no quaternion round trip).
    pub fn forward_kinematics_matrix(&self, q: &JointVector<T>) -> Matrix4<T> {
        let chain = self.frame_chain_with(&JointTrig::new(q));
        let rotation = chain.base_from_flange_rotation();
        let origin = chain.flange_origin();
        let mut pose = Matrix4::identity();
        pose.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation);
        pose.fixed_view_mut::<3, 1>(0, 3).copy_from(&origin);
        pose
    }

    /// `base_from_flange`: pose of frame {6} in the base frame (Eq 17's `h(q)` before the
    /// choice of orientation coordinates).
    pub fn forward_kinematics(&self, q: &JointVector<T>) -> Isometry3<T> {
        self.forward_kinematics_with(&JointTrig::new(q))
    }

    /// [`Self::forward_kinematics`] from the joints' sines and cosines, so a
    /// caller with cheaper ones (the control loop's `control::trig`, 60
    /// instructions per joint on the M4F instead of libm's 2,100) can use them.
    pub fn forward_kinematics_with(&self, trig: &JointTrig<T>) -> Isometry3<T> {
        let chain = self.frame_chain_with(trig);
        let rotation = Rotation3::from_matrix_unchecked(chain.base_from_flange_rotation());
        Isometry3::from_parts(
            Translation3::from(chain.flange_origin()),
            UnitQuaternion::from_rotation_matrix(&rotation),
        )
    }

    /// Geometric Jacobian in the base frame from a precomputed frame chain: column i is
    /// `[z_{i-1} x (o_6 - o_{i-1}); z_{i-1}]` (revolute joint i turns about `z_{i-1}`).
    pub fn jacobian_from_chain(&self, chain: &FrameChain<T>) -> Matrix6<T> {
        let flange = chain.flange_origin();
        let mut jacobian = Matrix6::zeros();
        for ((mut column, axes), origin) in jacobian
            .column_iter_mut()
            .zip(chain.axes.iter())
            .zip(chain.origins.iter())
        {
            let [_, _, z] = axes;
            let linear = cross3(z, &sub3(&flange, origin));
            column.fixed_rows_mut::<3>(0).copy_from(&linear);
            column.fixed_rows_mut::<3>(3).copy_from(z);
        }
        jacobian
    }

    /// Geometric Jacobian in the base frame; rows 0-2 linear velocity of the frame-{6} origin,
    /// rows 3-5 angular velocity.
    pub fn jacobian(&self, q: &JointVector<T>) -> Matrix6<T> {
        self.jacobian_from_chain(&self.frame_chain_with(&JointTrig::new(q)))
    }

    /// `Jdot qd`: the classical acceleration `[a; alpha]` of the frame-{6} origin at `qdd = 0`,
    /// base coordinates (Eq 19's `J_h qd` drift term, `L_f^2 h` with the `D^{-1} E` part
    /// removed). Computed by the velocity/acceleration half of the Newton-Euler recursion with
    /// zero joint accelerations and no gravity, in link frames, then rotated to the base.
    pub fn jacobian_dot_qd(&self, q: &JointVector<T>, qd: &JointVector<T>) -> Vector6<T> {
        let trig = JointTrig::new(q);
        self.jacobian_dot_qd_with(&trig, &self.frame_chain_with(&trig), qd)
    }

    /// [`Self::jacobian_dot_qd`] from a precomputed joint trig and frame chain.
    pub fn jacobian_dot_qd_with(
        &self,
        trig: &JointTrig<T>,
        chain: &FrameChain<T>,
        qd: &JointVector<T>,
    ) -> Vector6<T> {
        let zero = JointVector::zeros();
        let flange = self.flange_motion(trig, qd, &zero, &Vector3::zeros());
        let rotation = chain.base_from_flange_rotation();
        let linear = mul3(&rotation, &flange.linear_acceleration);
        let angular = mul3(&rotation, &flange.angular_acceleration);
        Vector6::new(
            linear.x, linear.y, linear.z, angular.x, angular.y, angular.z,
        )
    }

    /// The Jacobian and its bias `Jdot qd` together, sharing one evaluation of the joint trig and
    /// of the frame chain: what the task-space controller (Eq 19-20) needs every tick.
    pub fn jacobian_and_bias(
        &self,
        q: &JointVector<T>,
        qd: &JointVector<T>,
    ) -> (Matrix6<T>, Vector6<T>) {
        let trig = JointTrig::new(q);
        let chain = self.frame_chain_with(&trig);
        (
            self.jacobian_from_chain(&chain),
            self.jacobian_dot_qd_with(&trig, &chain, qd),
        )
    }
}
