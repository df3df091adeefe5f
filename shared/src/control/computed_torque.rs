//! The task-space computed-torque step (paper Eq 23).
//!
//! Eq 23 resolves a commanded flange acceleration into joint accelerations,
//! `qdd = J^-1 (a_d + Kd e_dot + Kp e - Jdot qd)`, and feeds them through the
//! inverse dynamics, `tau = D(q) qdd + h(q, qd)`. Here the inverse dynamics is
//! one RNEA pass (`D` is never formed nor inverted), `J^-1` is the damped
//! least-squares solve of [`super::dls`], and an integral term with
//! anti-windup removes the steady error that model mismatch (unknown payload,
//! friction) leaves under the paper's pure PD outer loop.
//!
//! The friction part of `h` is taken at the joint speeds the reference asks
//! for, `qd_ref = J^+ Yd_dot`, not at the measured `qd`: `tau = D(q) qdd +
//! C(q, qd) qd + G(q) + F(qd_ref)`. A joint that the reference moves slowly or
//! turns round (joint 1 following a part across the disc) has a measured speed
//! inside the Coulomb law's smoothing width; friction fed forward from it
//! comes only after the joint has broken away, so the joint sticks, the error
//! winds up the PD torque until it slips, and it overshoots (stick-slip, the
//! gripper's speed against the part jumping by 20 mm/s). The reference's speed
//! has the sign the joint must move in before it moves, and is free of the
//! encoders' noise, so its Coulomb law can be narrow without hunting: at rest
//! the reference asks for no speed and no friction torque is fed forward.

use nalgebra::{convert, Isometry3, RealField, Vector3, Vector6};

use super::dls::{DampedFactor, DampedSolution, DampingConfig};
use super::error::{ControlError, ControlInput, ControlStage};
use super::gains::{AxisGains, TaskGains};
use super::model::{Joints, TaskKinematics, TaskSpaceModel};
use super::orientation::orientation_error;
use crate::kernels::{all_finite, clamp_symmetric, mul6};

/// Desired motion of the flange (frame {6}), all in the base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskReference<T: RealField + Copy> {
    /// Desired `base_from_flange`.
    pub base_from_flange: Isometry3<T>,
    /// Desired twist `[v; omega]` of the flange origin (m/s; rad/s).
    pub twist: Vector6<T>,
    /// Desired classical acceleration `[a; alpha]` (m/s^2; rad/s^2).
    pub acceleration: Vector6<T>,
}

/// Tuning of the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerConfig<T> {
    /// Outer-loop gains (Eq 23's `Kp`, `Kd`, plus `Ki`).
    pub gains: TaskGains<T>,
    /// Anti-windup clamp on each component of the integrated position error (m s).
    pub position_integral_limit: T,
    /// Anti-windup clamp on each component of the integrated orientation error (rad s).
    pub orientation_integral_limit: T,
    /// Singularity damping of the Jacobian solve.
    pub damping: DampingConfig<T>,
}

impl<T: RealField + Copy> ControllerConfig<T> {
    /// The tuning the pick (and the Cortex-M4F benchmark) uses for the PUMA 560:
    /// error poles at 40 rad/s, critically damped, an integrator at 10 rad/s for
    /// the unknown payload; anti-windup at 5 mm s and 0.02 rad s; damping below
    /// `|det J|` = 0.01.
    pub fn puma560() -> Result<Self, ControlError> {
        let gains = AxisGains::from_poles(convert(40.0), T::one(), convert(10.0))?;
        Ok(Self {
            gains: TaskGains {
                position: gains,
                orientation: gains,
            },
            position_integral_limit: convert(0.005),
            orientation_integral_limit: convert(0.02),
            damping: DampingConfig {
                manipulability_threshold: convert(0.01),
                max_damping: convert(0.05),
            },
        })
    }

    /// Rejects negative or non-finite gains and limits.
    pub fn validate(&self) -> Result<(), ControlError> {
        let ok = |x: T| x.is_finite() && x >= T::zero();
        let gains_ok = |g: &AxisGains<T>| ok(g.kp) && ok(g.kd) && ok(g.ki);
        if !gains_ok(&self.gains.position) || !gains_ok(&self.gains.orientation) {
            return Err(ControlError::InvalidConfiguration(
                "gains must be finite and >= 0",
            ));
        }
        if !ok(self.position_integral_limit) || !ok(self.orientation_integral_limit) {
            return Err(ControlError::InvalidConfiguration(
                "integral limits must be finite and >= 0",
            ));
        }
        self.damping.validate()
    }
}

/// What one control step produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlOutput<T> {
    /// Joint torques to apply, always finite and within the torque limits.
    pub tau: Joints<T>,
    /// Joint accelerations commanded to the RNEA pass (zero in a hold).
    pub qdd: Joints<T>,
    /// `J^+ Yd_dot`: the joint speeds the reference's twist asks for at the
    /// measured configuration (damped like the acceleration solve; zero in a
    /// hold). A reference that asks a joint for more than its limit is a
    /// reference no plan should have made.
    pub reference_joint_speed: Joints<T>,
    /// `p_d - p` in the base frame (m) (zero in a hold: not evaluated).
    pub position_error: Vector3<T>,
    /// `log(R_d R^T)` in the base frame (rad) (zero in a hold).
    pub orientation_error: Vector3<T>,
    /// `|det J|` at this step (zero in a hold).
    pub manipulability: T,
    /// Damping `lambda^2` used in the Jacobian solve (0 away from singularities).
    pub damping_squared: T,
    /// True if at least one torque was clipped to its limit.
    pub saturated: bool,
    /// `Some(error)` if the law could not be evaluated and the output is the
    /// gravity-compensating hold instead.
    pub fallback: Option<ControlError>,
}

/// Task-space computed-torque controller with integral action.
///
/// State: the integrated task error (for `Ki`) and the last joint position
/// that was finite (so the gravity hold has a configuration to hold even when
/// the measurement itself is NaN).
#[derive(Debug, Clone, PartialEq)]
pub struct TaskSpaceController<T: RealField + Copy> {
    config: ControllerConfig<T>,
    error_integral: Vector6<T>,
    last_finite_q: Option<Joints<T>>,
    integral_frozen: bool,
}

fn pose_is_finite<T: RealField + Copy>(pose: &Isometry3<T>) -> bool {
    all_finite(&pose.translation.vector) && all_finite(&pose.rotation.coords)
}

impl<T: RealField + Copy> TaskSpaceController<T> {
    /// A controller with zero integral state; the configuration is validated.
    pub fn new(config: ControllerConfig<T>) -> Result<Self, ControlError> {
        config.validate()?;
        Ok(Self {
            config,
            error_integral: Vector6::zeros(),
            last_finite_q: None,
            integral_frozen: false,
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &ControllerConfig<T> {
        &self.config
    }

    /// Integrated task error `[int e_p; int e_o]`.
    pub fn error_integral(&self) -> &Vector6<T> {
        &self.error_integral
    }

    /// Clears the integral state (e.g. when a new trajectory starts).
    pub fn reset(&mut self) {
        self.error_integral = Vector6::zeros();
    }

    /// Keeps the integral where it is (`true`) or integrates again. Holding a
    /// pose still against Coulomb friction, a live integral winds up in the
    /// joints' dead band until they break away and slip (stick-slip hunting);
    /// frozen, it keeps compensating the model error it has learnt (payload,
    /// masses) and the hold settles.
    pub fn freeze_integral(&mut self, frozen: bool) {
        self.integral_frozen = frozen;
    }

    /// One control step: never returns NaN torques.
    ///
    /// If the law cannot be evaluated (NaN input, non-finite model output),
    /// the output is the saturated gravity torque at the last finite `q`
    /// (zero torque if there never was one), the integral is left untouched
    /// and [`ControlOutput::fallback`] says why.
    pub fn step<M: TaskSpaceModel<T>>(
        &mut self,
        model: &M,
        q: &Joints<T>,
        qd: &Joints<T>,
        reference: &TaskReference<T>,
        dt: T,
    ) -> ControlOutput<T> {
        let configuration = model.configuration(q);
        let kinematics = model.task_kinematics(&configuration, qd);
        self.step_with(model, q, qd, &configuration, &kinematics, reference, dt)
    }

    /// [`Self::step`] with the configuration and the flange kinematics at
    /// `(q, qd)` already computed by the caller: a control loop that needs the
    /// flange pose anyway (the pick measures its tool point every period)
    /// evaluates the sines, cosines and frame chain once, not twice.
    #[allow(clippy::too_many_arguments)]
    pub fn step_with<M: TaskSpaceModel<T>>(
        &mut self,
        model: &M,
        q: &Joints<T>,
        qd: &Joints<T>,
        configuration: &M::Configuration,
        kinematics: &TaskKinematics<T>,
        reference: &TaskReference<T>,
        dt: T,
    ) -> ControlOutput<T> {
        match self.track(model, q, qd, configuration, kinematics, reference, dt) {
            Ok(output) => output,
            Err(error) => self.hold(model, q, error),
        }
    }

    /// Eq 23 with integral action. On failure the integral is untouched; the
    /// (already checked finite) `q` is kept as the last finite configuration
    /// for the gravity hold.
    #[allow(clippy::too_many_arguments)]
    fn track<M: TaskSpaceModel<T>>(
        &mut self,
        model: &M,
        q: &Joints<T>,
        qd: &Joints<T>,
        configuration: &M::Configuration,
        kinematics: &TaskKinematics<T>,
        reference: &TaskReference<T>,
        dt: T,
    ) -> Result<ControlOutput<T>, ControlError> {
        check_inputs(q, qd, reference, dt)?;
        self.last_finite_q = Some(*q);

        let TaskKinematics {
            base_from_flange,
            jacobian,
            jacobian_dot_qd: jdot_qd,
        } = *kinematics;
        if !pose_is_finite(&base_from_flange) {
            return Err(ControlError::NonFiniteResult(
                ControlStage::ForwardKinematics,
            ));
        }
        if !all_finite(&jacobian) || !all_finite(&jdot_qd) {
            return Err(ControlError::NonFiniteResult(ControlStage::Jacobian));
        }

        let position_error =
            reference.base_from_flange.translation.vector - base_from_flange.translation.vector;
        let orientation_error = orientation_error(
            &reference.base_from_flange.rotation,
            &base_from_flange.rotation,
        );
        let error = Vector6::new(
            position_error.x,
            position_error.y,
            position_error.z,
            orientation_error.x,
            orientation_error.y,
            orientation_error.z,
        );
        let error_rate = reference.twist - mul6(&jacobian, qd);
        let integral = self.integrate(&error, dt);

        // Eq 23's outer loop, `a = Yd_ddot + Kv e_dot + Kp e (+ Ki int e)`,
        // with one gain set for the position rows and one for the orientation rows.
        let (gp, go) = (&self.config.gains.position, &self.config.gains.orientation);
        let kp = per_row(gp.kp, go.kp);
        let kd = per_row(gp.kd, go.kd);
        let ki = per_row(gp.ki, go.ki);
        let commanded_acceleration = reference.acceleration
            + kd.component_mul(&error_rate)
            + kp.component_mul(&error)
            + ki.component_mul(&integral);

        let factor = DampedFactor::new(&jacobian, &self.config.damping)?;
        let solution = DampedSolution {
            x: factor.solve(&(commanded_acceleration - jdot_qd)),
            manipulability: factor.manipulability,
            damping_squared: factor.damping_squared,
        };
        // The joint speeds the reference itself asks for, on the same factor:
        // the caller's guard that no reference exceeds a joint's limit.
        let reference_joint_speed = factor.solve(&reference.twist);
        if !all_finite(&solution.x) {
            return Err(ControlError::NonFiniteResult(
                ControlStage::JointAccelerationSolve,
            ));
        }
        // Friction from the reference's joint speeds (see the module's doc).
        let tau_unsaturated = model.inverse_dynamics(configuration, qd, &solution.x)
            + model.friction_torque(&reference_joint_speed);
        if !all_finite(&tau_unsaturated) {
            return Err(ControlError::NonFiniteResult(ControlStage::InverseDynamics));
        }
        let (tau, saturated) = saturate(&tau_unsaturated, &model.torque_limits());

        // Anti-windup by conditional integration: while a torque is clipped the
        // integrator would only wind up, so its state is frozen.
        if !saturated {
            self.error_integral = integral;
        }
        Ok(ControlOutput {
            tau,
            qdd: solution.x,
            reference_joint_speed,
            position_error,
            orientation_error,
            manipulability: solution.manipulability,
            damping_squared: solution.damping_squared,
            saturated,
            fallback: None,
        })
    }

    /// The integral after this step, clamped per component (anti-windup).
    fn integrate(&self, error: &Vector6<T>, dt: T) -> Vector6<T> {
        let (gp, go) = (&self.config.gains.position, &self.config.gains.orientation);
        if self.integral_frozen || (gp.ki == T::zero() && go.ki == T::zero()) {
            return self.error_integral;
        }
        let (lp, lo) = (
            self.config.position_integral_limit,
            self.config.orientation_integral_limit,
        );
        Vector6::from_fn(|row, _| {
            let limit = if row < 3 { lp } else { lo };
            let previous = self
                .error_integral
                .get(row)
                .copied()
                .unwrap_or_else(T::zero);
            let increment = error.get(row).copied().unwrap_or_else(T::zero) * dt;
            clamp_symmetric(previous + increment, limit)
        })
    }

    /// Gravity-compensating hold at the last finite configuration.
    fn hold<M: TaskSpaceModel<T>>(
        &self,
        model: &M,
        q: &Joints<T>,
        cause: ControlError,
    ) -> ControlOutput<T> {
        let hold_q = if all_finite(q) {
            Some(*q)
        } else {
            self.last_finite_q
        };
        let gravity = hold_q
            .map(|q| model.gravity_torque(&q))
            .filter(all_finite)
            .unwrap_or_else(Joints::zeros);
        let (tau, saturated) = saturate(&gravity, &model.torque_limits());
        ControlOutput {
            tau,
            qdd: Joints::zeros(),
            reference_joint_speed: Joints::zeros(),
            position_error: Vector3::zeros(),
            orientation_error: Vector3::zeros(),
            manipulability: T::zero(),
            damping_squared: T::zero(),
            saturated,
            fallback: Some(cause),
        }
    }
}

/// `[position; position; position; orientation; orientation; orientation]`.
fn per_row<T: RealField + Copy>(position: T, orientation: T) -> Vector6<T> {
    Vector6::new(
        position,
        position,
        position,
        orientation,
        orientation,
        orientation,
    )
}

fn check_inputs<T: RealField + Copy>(
    q: &Joints<T>,
    qd: &Joints<T>,
    reference: &TaskReference<T>,
    dt: T,
) -> Result<(), ControlError> {
    let fail = |input| Err(ControlError::NonFiniteInput(input));
    if !dt.is_finite() {
        return fail(ControlInput::Period);
    }
    if dt <= T::zero() {
        return Err(ControlError::NonPositivePeriod);
    }
    if !all_finite(q) {
        return fail(ControlInput::JointPosition);
    }
    if !all_finite(qd) {
        return fail(ControlInput::JointVelocity);
    }
    if !pose_is_finite(&reference.base_from_flange) {
        return fail(ControlInput::DesiredPose);
    }
    if !all_finite(&reference.twist) {
        return fail(ControlInput::DesiredTwist);
    }
    if !all_finite(&reference.acceleration) {
        return fail(ControlInput::DesiredAcceleration);
    }
    Ok(())
}

/// Clips each torque to `[-limit, limit]`; a non-finite limit clips to zero.
fn saturate<T: RealField + Copy>(tau: &Joints<T>, limits: &Joints<T>) -> (Joints<T>, bool) {
    let mut saturated = false;
    let clipped = tau.zip_map(limits, |t, limit| {
        let limit = if limit.is_finite() {
            limit.abs()
        } else {
            T::zero()
        };
        let c = clamp_symmetric(t, limit);
        if c != t {
            saturated = true;
        }
        c
    });
    (clipped, saturated)
}
