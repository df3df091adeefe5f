//! The robot as the world has it: the rigid PUMA 560 (`Puma560<f64>`, link
//! masses as drawn) plus the true drives of [`PlantDrives`] (friction and
//! armature off the table by the cell's draw, Coulomb smoothed over a small
//! speed band so RK4 stays accurate; the amplifier's current lag, torque
//! constants and ripple). The controller only sees it through
//! [`JointEncoders`], and only moves it through torque commands, which the
//! amplifiers clip at the joints' limits.
//!
//! Integration: classical Runge-Kutta on the joint state at the plant's own
//! step. The amplifier's current is a state of its own: over a step the
//! command is held, so its first-order lag is solved exactly
//! ([`PlantDrives::current_at`]) and each RK4 stage sees the current at its
//! own instant; the ripple follows the stage's joint angles.

use anyhow::{bail, Context, Result};
use nalgebra::Cholesky;
use shared::robot::{DriveOptions, JointVector, Puma560};

use super::drive::PlantDrives;

/// Joint positions and speeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointState {
    pub q: JointVector<f64>,
    pub qd: JointVector<f64>,
}

/// The simulated arm.
#[derive(Debug, Clone)]
pub struct RobotPlant {
    /// The rigid-body arm (link masses and payload as they truly are).
    model: Puma560<f64>,
    /// The table's drive terms (armature, smoothed friction), which the
    /// drawn scales multiply.
    table_drives: Puma560<f64>,
    drives: PlantDrives,
    state: JointState,
    /// The amplifiers' current, nominal N m.
    current: JointVector<f64>,
    /// The torque the motors deliver at the end of the last step.
    applied: JointVector<f64>,
    /// The largest |applied torque| / limit of any joint, at any RK4 stage,
    /// so far.
    peak_torque_ratio: f64,
    time_s: f64,
    /// Commands beyond a joint's torque limit are clipped by the drive.
    saturations: u64,
}

impl RobotPlant {
    /// The true arm: the table's rigid model with `link_mass_scale` as the
    /// truth differs from the table, a payload in the gripper, and the true
    /// `drives`.
    pub fn new(
        link_mass_scale: [f64; 6],
        payload_kg: f64,
        payload_com_flange_m: nalgebra::Vector3<f64>,
        q0: JointVector<f64>,
        drives: PlantDrives,
    ) -> Result<Self> {
        // `shared`'s RobotError is not a `std::error::Error` yet, so it is
        // formatted into the error here and below, then given its context.
        let model = Puma560::<f64>::new()
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
        let table_drives = Puma560::<f64>::new()
            .with_drive(DriveOptions {
                armature: true,
                friction: true,
            })
            .try_with_coulomb_smoothing(1e-3)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .context("plant Coulomb smoothing")?;
        if !q0.iter().all(|x| x.is_finite()) {
            bail!("initial joint angles must be finite");
        }
        Ok(Self {
            model,
            table_drives,
            drives,
            state: JointState {
                q: q0,
                qd: JointVector::zeros(),
            },
            current: JointVector::zeros(),
            applied: JointVector::zeros(),
            peak_torque_ratio: 0.0,
            time_s: 0.0,
            saturations: 0,
        })
    }

    /// The rigid-body arm as it truly is (link masses, payload; no drives).
    pub fn model(&self) -> &Puma560<f64> {
        &self.model
    }

    /// The cell's true drives.
    pub fn drives(&self) -> &PlantDrives {
        &self.drives
    }

    pub fn state(&self) -> JointState {
        self.state
    }

    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The torque the motors delivered at the end of the last step, N m.
    pub fn applied_torque(&self) -> JointVector<f64> {
        self.applied
    }

    /// The largest |applied torque| / limit over the joints and the RK4
    /// stages of every step so far.
    pub fn peak_torque_ratio(&self) -> f64 {
        self.peak_torque_ratio
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

    /// The current reference the amplifiers take from `command`: clipped to
    /// the joint limits (a non-finite command is no current).
    pub fn current_reference(&mut self, command: &JointVector<f64>) -> JointVector<f64> {
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

    /// Joint accelerations under the applied torque `tau`: the rigid arm plus
    /// the true armature on the diagonal of `D(q)` and the true friction.
    fn acceleration(&self, s: &JointState, tau: &JointVector<f64>) -> Result<JointVector<f64>> {
        if !(s.q.iter().chain(s.qd.iter()).chain(tau.iter())).all(|v| v.is_finite()) {
            bail!("plant forward dynamics: a non-finite state or torque");
        }
        let armature = self
            .table_drives
            .armature_inertia()
            .component_mul(&JointVector::from(self.drives.armature_scale));
        let friction = self
            .table_drives
            .friction_torque(&s.qd)
            .component_mul(&JointVector::from(self.drives.friction_scale));
        let mass = self.model.mass_matrix(&s.q) + nalgebra::Matrix6::from_diagonal(&armature);
        let bias = self
            .model
            .try_inverse_dynamics(&s.q, &s.qd, &JointVector::zeros())
            .map_err(|e| anyhow::anyhow!("plant inverse dynamics: {e}"))?;
        let factor = Cholesky::new(mass).context("plant mass matrix not positive definite")?;
        let qdd = factor.solve(&(tau - bias - friction));
        if !qdd.iter().all(|v| v.is_finite()) {
            bail!("plant forward dynamics: a non-finite acceleration");
        }
        Ok(qdd)
    }

    /// Advances by `dt_s` under the torque `command` (held constant over the
    /// step): the current lags it, the motors turn the current into torque,
    /// RK4 integrates the arm.
    pub fn step(&mut self, command: &JointVector<f64>, dt_s: f64) -> Result<()> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            bail!("plant step must be positive, got {dt_s}");
        }
        let reference = self.current_reference(command);
        let start = self.current;
        let limit = self.model.joint_limits().torque_max;
        let mut peak = self.peak_torque_ratio;
        let mut f = |s: &JointState, h: f64| -> Result<JointState> {
            let current = self.drives.current_at(&start, &reference, h);
            let tau = self.drives.torque(&current, &s.q);
            for (t, max) in tau.iter().zip(limit.iter()) {
                peak = peak.max(t.abs() / max);
            }
            let qdd = self.acceleration(s, &tau)?;
            Ok(JointState { q: s.qd, qd: qdd })
        };
        let add = |s: &JointState, k: &JointState, h: f64| JointState {
            q: s.q + k.q * h,
            qd: s.qd + k.qd * h,
        };
        let s0 = self.state;
        let k1 = f(&s0, 0.0)?;
        let k2 = f(&add(&s0, &k1, dt_s / 2.0), dt_s / 2.0)?;
        let k3 = f(&add(&s0, &k2, dt_s / 2.0), dt_s / 2.0)?;
        let k4 = f(&add(&s0, &k3, dt_s), dt_s)?;
        self.state = JointState {
            q: s0.q + (k1.q + k2.q * 2.0 + k3.q * 2.0 + k4.q) * (dt_s / 6.0),
            qd: s0.qd + (k1.qd + k2.qd * 2.0 + k3.qd * 2.0 + k4.qd) * (dt_s / 6.0),
        };
        self.peak_torque_ratio = peak;
        self.current = self.drives.current_at(&start, &reference, dt_s);
        self.applied = self.drives.torque(&self.current, &self.state.q);
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
    use crate::scenario::pick::DriveSettings;
    use crate::world::drive::PlantDrives;
    use nalgebra::Vector3;
    use rand::SeedableRng;

    #[test]
    fn a_held_arm_stays_put_under_gravity_compensation() {
        let q0 = shared::planning::ready_posture::<f64>();
        let mut plant =
            RobotPlant::new([1.0; 6], 0.0, Vector3::zeros(), q0, PlantDrives::exact()).unwrap();
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
        let mut plant = RobotPlant::new(
            [1.0; 6],
            1.0,
            Vector3::new(0.0, 0.0, 0.1),
            q0,
            PlantDrives::exact(),
        )
        .unwrap();
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
    fn the_drawn_drives_reach_the_joints_through_the_lag_and_the_torque_constant() {
        let q0 = shared::planning::ready_posture::<f64>();
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(5);
        let drives = PlantDrives::draw(&DriveSettings::default(), &mut rng);
        let mut plant = RobotPlant::new([1.0; 6], 0.0, Vector3::zeros(), q0, drives).unwrap();
        let gravity = plant.model().gravity_torque(&q0);
        // One time constant after a step from zero: 63 % of the command.
        plant.step(&gravity, drives.time_constant_s).unwrap();
        let tau = plant.applied_torque();
        let expected = 1.0 - (-1.0_f64).exp();
        for j in 1..3 {
            let ratio = tau[j] / (gravity[j] * drives.torque_constant_ratio[j]);
            assert!((ratio - expected).abs() < 0.035, "joint {j}: {ratio}");
        }
        // A command at the limit on a motor stronger than the table's goes over it.
        let strong = (0..6)
            .max_by(|a, b| {
                drives.torque_constant_ratio[*a].total_cmp(&drives.torque_constant_ratio[*b])
            })
            .unwrap();
        let before = plant.peak_torque_ratio();
        assert!(before < 1.0, "{before}");
        let mut command = JointVector::zeros();
        command[strong] = 1e6;
        for _ in 0..20 {
            plant.step(&command, 1e-3).unwrap();
        }
        let peak = plant.peak_torque_ratio();
        assert!(
            peak > 1.0 + 0.5 * (drives.torque_constant_ratio[strong] - 1.0),
            "{peak}"
        );
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
