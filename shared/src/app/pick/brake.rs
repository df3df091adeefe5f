//! The last-resort stop, in joint space. Eq 23 stops the arm along a planned
//! task-space path, which needs a sane reference and a sane model of where the
//! arm is. When those cannot be trusted (a joint over its speed limit, Eq 23
//! failing, a stop that is not converging) the pick stops trusting the task
//! space: each joint is pulled back to where it was when the brake engaged,
//! well damped, with the model's gravity torque (Eq 23's G term) holding the
//! arm up. The spring bounds the sag a wrong gravity model (an unknown
//! payload, link masses off) would otherwise let the arm fall by.
//! Nothing here depends on the camera, the conveyor or a reference.

use crate::control::puma::DRIVE_TORQUE_HEADROOM;
use crate::robot::{JointVector, Puma560};

/// Damping of each joint, N m s/rad (arm joints, then the wrist's).
const DAMPING_NM_S: [f32; 6] = [40.0, 60.0, 60.0, 2.0, 2.0, 2.0];
/// Stiffness of the hold, N m/rad: a gravity error of 10 N m sags the
/// shoulder 0.017 rad.
const STIFFNESS_NM: [f32; 6] = [300.0, 600.0, 600.0, 20.0, 20.0, 20.0];

/// The brake's state: where it holds the arm, from its first period on.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointBrake {
    hold_q: Option<JointVector<f32>>,
}

impl JointBrake {
    /// A brake not yet started.
    pub fn new() -> Self {
        Self::default()
    }

    /// Where the brake holds the arm (where it was when it engaged).
    pub fn hold(&self) -> Option<JointVector<f32>> {
        self.hold_q
    }

    /// The torque this period, within the drives' limits.
    pub fn torque(
        &mut self,
        model: &Puma560<f32>,
        q: &JointVector<f32>,
        qd: &JointVector<f32>,
    ) -> [f32; 6] {
        if self.hold_q.is_none() && q.iter().all(|v| v.is_finite()) {
            self.hold_q = Some(*q);
        }
        let gravity = model.gravity_torque(q);
        let limits = model.joint_limits();
        let mut tau = [0.0_f32; 6];
        for (j, slot) in tau.iter_mut().enumerate() {
            let at = |v: &JointVector<f32>| v.get(j).copied().unwrap_or(0.0);
            let spring = self.hold_q.map_or(0.0, |hold| {
                STIFFNESS_NM.get(j).copied().unwrap_or(0.0) * (at(&hold) - at(q))
            });
            let damping = DAMPING_NM_S.get(j).copied().unwrap_or(0.0) * at(qd);
            let value = at(&gravity) + spring - damping;
            // Not `clamp`: it panics on a NaN or negative limit. A limit that
            // is not a finite number allows no torque.
            let max = at(&limits.torque_max) * DRIVE_TORQUE_HEADROOM;
            let max = if max.is_finite() { max.abs() } else { 0.0 };
            *slot = if value.is_finite() {
                value.max(-max).min(max)
            } else {
                0.0
            };
        }
        tau
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn it_damps_a_moving_arm_and_holds_it_where_it_engaged() {
        let model = Puma560::<f64>::new().cast::<f32>();
        let q = JointVector::from_column_slice(&[0.3, -0.5, 0.8, 0.1, 0.4, 0.0]);
        let mut brake = JointBrake::new();
        let moving = JointVector::from_column_slice(&[1.0, -1.0, 0.5, 2.0, -2.0, 1.0]);
        let tau = brake.torque(&model, &q, &moving);
        let gravity = model.gravity_torque(&q);
        for j in 0..6 {
            // Opposes the motion, about gravity.
            assert!(
                (tau[j] - gravity[j]) * moving[j] < 0.0,
                "joint {j}: {tau:?}"
            );
        }
        assert_eq!(brake.hold(), Some(q));
        let still = JointVector::zeros();
        // Pushed off the hold, it pushes back.
        let sagged = q + JointVector::from_column_slice(&[0.0, 0.01, 0.0, 0.0, 0.0, 0.0]);
        let tau = brake.torque(&model, &sagged, &still);
        assert!(tau[1] < model.gravity_torque(&sagged)[1]);
    }

    #[test]
    fn a_nan_reading_gives_zero_torque_not_nan() {
        let model = Puma560::<f64>::new().cast::<f32>();
        let q = JointVector::repeat(f32::NAN);
        let tau = JointBrake::new().torque(&model, &q, &JointVector::zeros());
        assert!(tau.iter().all(|t| t.is_finite()));
    }
}
