use core::fmt;

/// Why a plan or an inverse kinematics solve failed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlanError {
    /// A non-finite number in the named input.
    NonFinite {
        /// The input holding it.
        what: &'static str,
    },
    /// A segment duration must be positive and finite.
    InvalidDuration,
    /// A limit or configuration value is out of range.
    InvalidLimits {
        /// The limit or value.
        what: &'static str,
    },
    /// The pose could not be reached: the residual after the last iteration.
    IkDidNotConverge {
        /// Position residual, m.
        position_error_m: f64,
        /// Orientation residual, rad.
        orientation_error_rad: f64,
    },
    /// The solution breaks joint `joint`'s position limit.
    JointPositionLimit {
        /// The joint, 0-based.
        joint: usize,
    },
    /// Following the plan would exceed joint `joint`'s speed limit at `time_s`.
    JointVelocityLimit {
        /// The joint, 0-based.
        joint: usize,
        /// When along the plan, s.
        time_s: f64,
    },
    /// Following the plan would exceed joint `joint`'s torque limit at `time_s`.
    JointTorqueLimit {
        /// The joint, 0-based.
        joint: usize,
        /// When along the plan, s.
        time_s: f64,
    },
    /// The Jacobian is singular along the plan at `time_s`.
    Singular {
        /// When along the plan, s.
        time_s: f64,
    },
    /// No duration up to the maximum meets the part within the limits.
    NoFeasibleIntercept,
    /// Over a whole turn of the disc the part never stays within reach for
    /// the grasp's window: at this conveyor speed no intercept ever can.
    NoGraspWindow,
}

impl fmt::Display for PlanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite { what } => write!(f, "non-finite value in {what}"),
            Self::InvalidDuration => write!(f, "segment duration must be positive and finite"),
            Self::NoGraspWindow => write!(
                f,
                "the part stays within reach for less than the grasp's window on every turn"
            ),
            Self::InvalidLimits { what } => write!(f, "invalid planning limit: {what}"),
            Self::IkDidNotConverge {
                position_error_m,
                orientation_error_rad,
            } => write!(
                f,
                "inverse kinematics did not converge (residual {position_error_m:.2e} m, {orientation_error_rad:.2e} rad): pose out of reach"
            ),
            Self::JointPositionLimit { joint } => write!(f, "joint {} position limit", joint + 1),
            Self::JointVelocityLimit { joint, time_s } => {
                write!(f, "joint {} speed limit exceeded at t = {time_s:.3} s", joint + 1)
            }
            Self::JointTorqueLimit { joint, time_s } => {
                write!(f, "joint {} torque limit exceeded at t = {time_s:.3} s", joint + 1)
            }
            Self::Singular { time_s } => write!(f, "singular Jacobian along the plan at t = {time_s:.3} s"),
            Self::NoFeasibleIntercept => write!(f, "no feasible intercept within the maximum duration"),
        }
    }
}

impl core::error::Error for PlanError {}
