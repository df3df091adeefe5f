//! The robot as the world has it: a `Puma560<f64>` with motor armature and joint
//! friction (Coulomb smoothed over a small speed band so RK4 stays accurate),
//! integrated by classical Runge-Kutta at the plant's own step. The controller
//! only sees it through [`JointEncoders`], and only moves it through torques,
//! which the drives saturate at their limits.

use anyhow::{bail, Context, Result};
use shared::robot::{DriveOptions, JointVector, Puma560};

/// Joint positions and speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointState {
    pub q: JointVector<f64>,
    pub qd: JointVector<f64>,
}

/// The simulated arm.
#[derive(Debug, Clone)]
pub struct RobotPlant {
    model: Puma560<f64>,
    state: JointState,
    time_s: f64,
    /// Commands beyond a joint's torque limit are clipped by the drive.
    saturations: u64,
}

impl RobotPlant {
    /// The true arm: the table's model with drives on, `link_mass_scale` as the
    /// truth differs from the table, and a payload in the gripper.
    pub fn new(
        link_mass_scale: [f64; 6],
        payload_kg: f64,
        payload_com_flange_m: nalgebra::Vector3<f64>,
        q0: JointVector<f64>,
    ) -> Result<Self> {
        // `shared`'s RobotError is not a `std::error::Error` yet, so it is
        // formatted into the error here and below, then given its context.
        let model = Puma560::<f64>::new()
            .with_drive(DriveOptions {
                armature: true,
                friction: true,
            })
            .try_with_coulomb_smoothing(1e-3)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .context("plant Coulomb smoothing")?
            .try_with_link_mass_scale(link_mass_scale)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .context("plant link masses")?;
        let model = if payload_kg > 0.0 {
            model
                .try_with_payload(payload_kg, payload_com_flange_m)
                .map_err(|e| anyhow::anyhow!("{e}"))
                .context("plant payload")?
        } else {
            model
        };
        if !q0.iter().all(|x| x.is_finite()) {
            bail!("initial joint angles must be finite");
        }
        Ok(Self {
            model,
            state: JointState {
                q: q0,
                qd: JointVector::zeros(),
            },
            time_s: 0.0,
            saturations: 0,
        })
    }

    pub fn model(&self) -> &Puma560<f64> {
        &self.model
    }

    pub fn state(&self) -> JointState {
        self.state
    }

    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Replaces the payload the arm carries (the part grasped or released): a
    /// point mass at `com_flange_m` in frame {6}. The state is unchanged.
    pub fn set_payload(
        &mut self,
        payload_kg: f64,
        com_flange_m: nalgebra::Vector3<f64>,
    ) -> Result<()> {
        self.model = self
            .model
            .try_with_payload(payload_kg, com_flange_m)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .context("plant payload change")?;
        Ok(())
    }

    /// Puts the arm at `state` (tests that need the gripper at a given place).
    #[cfg(test)]
    pub(crate) fn set_state(&mut self, state: JointState) {
        self.state = state;
    }

    /// Torque commands the drives had to clip so far.
    pub fn saturations(&self) -> u64 {
        self.saturations
    }

    /// The torque the drives deliver for `command`: clipped to the joint limits.
    pub fn delivered_torque(&mut self, command: &JointVector<f64>) -> JointVector<f64> {
        let limit = self.model.joint_limits().torque_max;
        let mut tau = *command;
        for (t, max) in tau.iter_mut().zip(limit.iter()) {
            let clipped = if t.is_finite() {
                t.clamp(-*max, *max)
            } else {
                0.0
            };
            if clipped != *t {
                self.saturations += 1;
            }
            *t = clipped;
        }
        tau
    }

    /// Advances by `dt_s` under the torque `command` (held constant over the step), RK4.
    pub fn step(&mut self, command: &JointVector<f64>, dt_s: f64) -> Result<()> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            bail!("plant step must be positive, got {dt_s}");
        }
        let tau = self.delivered_torque(command);
        let f = |s: &JointState| -> Result<JointState> {
            let qdd = self
                .model
                .forward_dynamics(&s.q, &s.qd, &tau)
                .map_err(|e| anyhow::anyhow!("plant forward dynamics: {e}"))?;
            Ok(JointState { q: s.qd, qd: qdd })
        };
        let add = |s: &JointState, k: &JointState, h: f64| JointState {
            q: s.q + k.q * h,
            qd: s.qd + k.qd * h,
        };
        let s0 = self.state;
        let k1 = f(&s0)?;
        let k2 = f(&add(&s0, &k1, dt_s / 2.0))?;
        let k3 = f(&add(&s0, &k2, dt_s / 2.0))?;
        let k4 = f(&add(&s0, &k3, dt_s))?;
        self.state = JointState {
            q: s0.q + (k1.q + k2.q * 2.0 + k3.q * 2.0 + k4.q) * (dt_s / 6.0),
            qd: s0.qd + (k1.qd + k2.qd * 2.0 + k3.qd * 2.0 + k4.qd) * (dt_s / 6.0),
        };
        self.time_s += dt_s;
        Ok(())
    }
}

/// Incremental joint encoders: what the controller reads of the arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointEncoders {
    /// Counts per radian at the joint (motor-side lines x 4 x gear ratio / 2 pi).
    pub counts_per_rad: [f64; 6],
}

impl JointEncoders {
    /// PUMA 560-like resolution: 250-line motor encoders read in quadrature (1,000
    /// counts per motor turn) through each joint's gear ratio.
    pub fn puma560() -> Self {
        let model = Puma560::<f64>::new();
        let mut counts_per_rad = [0.0; 6];
        for (c, drive) in counts_per_rad.iter_mut().zip(model.drive_params().iter()) {
            *c = 1000.0 * drive.gear_ratio.abs() / core::f64::consts::TAU;
        }
        Self { counts_per_rad }
    }

    /// The counts for joint angles `q` (truncated towards minus infinity, as a counter does).
    pub fn read(&self, q: &JointVector<f64>) -> [i32; 6] {
        let mut counts = [0i32; 6];
        for ((c, angle), per_rad) in counts
            .iter_mut()
            .zip(q.iter())
            .zip(self.counts_per_rad.iter())
        {
            *c = (angle * per_rad).floor() as i32;
        }
        counts
    }

    /// The joint angles the controller infers from counts (centre of the count).
    pub fn angles(&self, counts: &[i32; 6]) -> JointVector<f64> {
        JointVector::from_fn(|i, _| {
            let c = counts.get(i).copied().unwrap_or(0);
            let per_rad = self.counts_per_rad.get(i).copied().unwrap_or(1.0);
            (f64::from(c) + 0.5) / per_rad
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn a_held_arm_stays_put_under_gravity_compensation() {
        let q0 = shared::planning::ready_posture::<f64>();
        let mut plant = RobotPlant::new([1.0; 6], 0.0, Vector3::zeros(), q0).unwrap();
        for _ in 0..1000 {
            let tau = plant.model().gravity_torque(&plant.state().q);
            plant.step(&tau, 1e-3).unwrap();
        }
        assert!((plant.state().q - q0).amax() < 1e-6);
        assert_eq!(plant.saturations(), 0);
    }

    #[test]
    fn an_unpowered_arm_falls_and_the_drives_clip_excess_torque() {
        let q0 = shared::planning::ready_posture::<f64>();
        let mut plant = RobotPlant::new([1.0; 6], 1.0, Vector3::new(0.0, 0.0, 0.1), q0).unwrap();
        for _ in 0..200 {
            plant.step(&JointVector::zeros(), 1e-3).unwrap();
        }
        assert!(
            (plant.state().q - q0).amax() > 1e-3,
            "gravity must move an unpowered arm"
        );
        plant.step(&JointVector::repeat(1e6), 1e-3).unwrap();
        // A heavier payload changes the gravity load but not the state.
        let before = plant.state();
        let load = plant.model().gravity_torque(&before.q);
        plant
            .set_payload(2.5, Vector3::new(0.0, 0.0, 0.15))
            .unwrap();
        assert_eq!(plant.state(), before);
        assert!((plant.model().gravity_torque(&before.q) - load).amax() > 0.1);
        assert!(plant.set_payload(f64::NAN, Vector3::zeros()).is_err());
        assert_eq!(plant.saturations(), 6);
        assert!(plant.step(&JointVector::zeros(), 0.0).is_err());
    }

    #[test]
    fn encoders_quantise_to_their_resolution() {
        let enc = JointEncoders::puma560();
        let q = JointVector::new(0.3, -1.2, 2.0, 0.01, -0.5, 4.0);
        let back = enc.angles(&enc.read(&q));
        for i in 0..6 {
            assert!((back[i] - q[i]).abs() <= 0.5 / enc.counts_per_rad[i] + 1e-12);
        }
    }
}
