//! The terms of Eq 16, `tau = D(q) qdd + C(q, qd) + G(q)`, and its solution for `qdd` (the
//! simulator's plant), with the armature and friction switches of [`super::DriveOptions`].

use nalgebra::{Cholesky, Matrix6, RealField, Vector3};

use super::dh::JointTrig;
use super::error::RobotError;
use super::model::Puma560;
use super::JointVector;

/// Checks every entry of `values`, naming the argument and the 1-based joint in the error.
fn require_finite<T: RealField + Copy>(
    quantity: &'static str,
    values: &JointVector<T>,
) -> Result<(), RobotError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(RobotError::NonFiniteInput {
            quantity,
            joint: index + 1,
        }),
        None => Ok(()),
    }
}

impl<T: RealField + Copy> Puma560<T> {
    /// Full inverse dynamics, Eq 16 solved for `tau`: rigid-body RNEA with gravity, plus
    /// `G^2 Jm qdd` if armature is on and joint friction if friction is on.
    pub fn inverse_dynamics(
        &self,
        q: &JointVector<T>,
        qd: &JointVector<T>,
        qdd: &JointVector<T>,
    ) -> JointVector<T> {
        let trig = JointTrig::new(q);
        self.inverse_dynamics_with(&trig, qd, qdd)
    }

    /// [`Self::inverse_dynamics`] for untrusted input: rejects non-finite `q`, `qd`, `qdd` with
    /// an error naming the argument and joint, instead of propagating NaN into a torque command.
    pub fn try_inverse_dynamics(
        &self,
        q: &JointVector<T>,
        qd: &JointVector<T>,
        qdd: &JointVector<T>,
    ) -> Result<JointVector<T>, RobotError> {
        require_finite("q", q)?;
        require_finite("qd", qd)?;
        require_finite("qdd", qdd)?;
        Ok(self.inverse_dynamics(q, qd, qdd))
    }

    /// [`Self::inverse_dynamics`] with the joint trig computed by the caller (reuse across terms).
    pub fn inverse_dynamics_with(
        &self,
        trig: &JointTrig<T>,
        qd: &JointVector<T>,
        qdd: &JointVector<T>,
    ) -> JointVector<T> {
        let rigid = self.rigid_inverse_dynamics_with(trig, qd, qdd, &(-self.gravity));
        rigid + self.armature_inertia().component_mul(qdd) + self.friction_torque(qd)
    }

    /// Joint-space inertia matrix `D(q)` by CRBA, plus `G^2 Jm` on the diagonal if armature is on.
    pub fn mass_matrix(&self, q: &JointVector<T>) -> Matrix6<T> {
        self.mass_matrix_with(&JointTrig::new(q))
    }

    /// [`Self::mass_matrix`] with the joint trig computed by the caller.
    pub fn mass_matrix_with(&self, trig: &JointTrig<T>) -> Matrix6<T> {
        let mut mass_matrix = self.rigid_mass_matrix_with(trig);
        if self.options.armature {
            mass_matrix.set_diagonal(&(mass_matrix.diagonal() + self.armature_inertia()));
        }
        mass_matrix
    }

    /// Gravity torque `G(q) = rne(q, 0, 0)`: the torque that holds the arm still.
    pub fn gravity_torque(&self, q: &JointVector<T>) -> JointVector<T> {
        let zero = JointVector::zeros();
        self.rigid_inverse_dynamics_with(&JointTrig::new(q), &zero, &zero, &(-self.gravity))
    }

    /// Coriolis and centripetal torque `C(q, qd) qd` (rigid body, no gravity, no friction).
    pub fn coriolis_torque(&self, q: &JointVector<T>, qd: &JointVector<T>) -> JointVector<T> {
        let zero = JointVector::zeros();
        self.rigid_inverse_dynamics_with(&JointTrig::new(q), qd, &zero, &Vector3::zeros())
    }

    /// Forward dynamics: `qdd = D(q)^{-1} (tau - C(q, qd) - G(q) - friction)` by a Cholesky
    /// factorisation of `D` (symmetric positive definite for any physical parameter set).
    ///
    /// Errors: non-finite `q`, `qd` or `tau`; `D` not positive definite (e.g. all masses scaled to
    /// zero); a non-finite result (overflow).
    pub fn forward_dynamics(
        &self,
        q: &JointVector<T>,
        qd: &JointVector<T>,
        tau: &JointVector<T>,
    ) -> Result<JointVector<T>, RobotError> {
        require_finite("q", q)?;
        require_finite("qd", qd)?;
        require_finite("tau", tau)?;
        let trig = JointTrig::new(q);
        let mass_matrix = self.mass_matrix_with(&trig);
        let bias = self.inverse_dynamics_with(&trig, qd, &JointVector::zeros());
        let factor = Cholesky::new(mass_matrix).ok_or(RobotError::MassMatrixNotPositiveDefinite)?;
        let qdd = factor.solve(&(tau - bias));
        match qdd.iter().position(|v| !v.is_finite()) {
            Some(index) => Err(RobotError::NonFiniteResult { joint: index + 1 }),
            None => Ok(qdd),
        }
    }
}
