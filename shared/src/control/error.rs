//! Typed errors of the task-space controller.

use core::fmt;

/// Which input of a control step was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlInput {
    /// Measured joint positions `q`.
    JointPosition,
    /// Measured joint velocities `qd`.
    JointVelocity,
    /// Desired pose `base_from_flange_desired`.
    DesiredPose,
    /// Desired twist of the flange in the base frame.
    DesiredTwist,
    /// Desired classical acceleration of the flange in the base frame.
    DesiredAcceleration,
    /// Control period `dt`.
    Period,
}

/// Which stage of the control law produced a non-finite value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlStage {
    /// Forward kinematics of the controller's model.
    ForwardKinematics,
    /// Geometric Jacobian or `Jdot qd` of the controller's model.
    Jacobian,
    /// Damped least-squares solve for the joint accelerations (Eq 23).
    JointAccelerationSolve,
    /// Recursive Newton-Euler pass for the joint torques.
    InverseDynamics,
    /// Gravity torque used by the hold fallback.
    GravityHold,
}

/// Why a control step or a configuration was rejected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ControlError {
    /// An input held NaN or an infinity.
    NonFiniteInput(ControlInput),
    /// The control period was zero or negative.
    NonPositivePeriod,
    /// A stage of the control law produced NaN or an infinity.
    NonFiniteResult(ControlStage),
    /// `J J^T + lambda^2 I` could not be factorised although it should be positive definite.
    SolveFailed,
    /// A gain or limit of the configuration was negative, NaN or infinite.
    InvalidConfiguration(&'static str),
    /// Numerical inverse kinematics did not reach the target pose (unreachable or bad seed).
    InverseKinematicsDidNotConverge,
}

impl fmt::Display for ControlInput {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            ControlInput::JointPosition => "joint position q",
            ControlInput::JointVelocity => "joint velocity qd",
            ControlInput::DesiredPose => "desired pose base_from_flange",
            ControlInput::DesiredTwist => "desired flange twist",
            ControlInput::DesiredAcceleration => "desired flange acceleration",
            ControlInput::Period => "control period dt",
        };
        f.write_str(name)
    }
}

impl fmt::Display for ControlStage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            ControlStage::ForwardKinematics => "forward kinematics",
            ControlStage::Jacobian => "Jacobian / Jdot qd",
            ControlStage::JointAccelerationSolve => "damped least-squares joint acceleration solve",
            ControlStage::InverseDynamics => "RNEA inverse dynamics",
            ControlStage::GravityHold => "gravity hold torque",
        };
        f.write_str(name)
    }
}

impl fmt::Display for ControlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ControlError::NonFiniteInput(input) => {
                write!(f, "control: {input} contains NaN or infinity")
            }
            ControlError::NonPositivePeriod => f.write_str("control: period dt must be > 0"),
            ControlError::NonFiniteResult(stage) => {
                write!(f, "control: {stage} produced NaN or infinity")
            }
            ControlError::SolveFailed => {
                f.write_str("control: damped J J^T is not positive definite")
            }
            ControlError::InvalidConfiguration(what) => {
                write!(f, "control: invalid configuration: {what}")
            }
            ControlError::InverseKinematicsDidNotConverge => {
                f.write_str("control: inverse kinematics did not converge to the target pose")
            }
        }
    }
}

impl core::error::Error for ControlError {}
