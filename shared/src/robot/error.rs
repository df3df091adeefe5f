//! Typed errors of the PUMA 560 model.

use core::fmt;

/// What went wrong in the robot model, and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RobotError {
    /// An input vector holds NaN or an infinity (`quantity` names it: "q", "qd", "tau", ...;
    /// `joint` is 1-based).
    NonFiniteInput {
        /// Which input argument.
        quantity: &'static str,
        /// 1-based joint index of the first bad entry.
        joint: usize,
    },
    /// A model parameter given to a builder is NaN, infinite or negative where it must not be.
    InvalidParameter {
        /// Which parameter ("payload mass", "link mass scale", ...).
        parameter: &'static str,
    },
    /// The joint-space inertia matrix failed its Cholesky factorisation: it is not
    /// symmetric positive definite (degenerate inertial parameters, e.g. all link masses scaled to 0).
    MassMatrixNotPositiveDefinite,
    /// The forward dynamics produced a non-finite acceleration (overflow from huge inputs).
    NonFiniteResult {
        /// 1-based joint index of the first bad entry.
        joint: usize,
    },
}

impl fmt::Display for RobotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RobotError::NonFiniteInput { quantity, joint } => write!(
                f,
                "robot model: input `{quantity}` is not finite at joint {joint}"
            ),
            RobotError::InvalidParameter { parameter } => write!(
                f,
                "robot model: parameter `{parameter}` must be finite and non-negative"
            ),
            RobotError::MassMatrixNotPositiveDefinite => write!(
                f,
                "robot model: joint-space inertia matrix is not symmetric positive definite"
            ),
            RobotError::NonFiniteResult { joint } => write!(
                f,
                "robot model: forward dynamics gave a non-finite acceleration at joint {joint}"
            ),
        }
    }
}

impl core::error::Error for RobotError {}
