//! Task-space computed-torque control of the PUMA 560 (paper Eq 23).
//!
//! One concept per module:
//! - [`gains`]: PD(+I) gains from natural frequency, damping ratio and integrator pole.
//! - [`orientation`]: orientation error as the log map of `R_d R^T`.
//! - [`dls`]: damped least-squares Jacobian solve, bounded at singularities.
//! - [`model`]: the model terms the law uses ([`TaskSpaceModel`]).
//! - [`puma`]: that trait for [`crate::robot::Puma560`], sharing trig and frame chain.
//! - [`computed_torque`]: the control step itself, with anti-windup integral
//!   action, torque saturation and the gravity-hold fallback.
//! - [`trig`]: full-precision sin/cos without f64 (libm's f32 routines run f64 inside).
//! - [`trajectory`]: the circle reference (a part riding the disc).
//! - [`error`]: typed errors.

pub mod computed_torque;
pub mod dls;
pub mod error;
pub mod gains;
pub mod model;
pub mod orientation;
pub mod puma;
pub mod trajectory;
pub mod trig;

pub use computed_torque::{ControlOutput, ControllerConfig, TaskReference, TaskSpaceController};
pub use dls::{solve_damped, DampedFactor, DampedSolution, DampingConfig};
pub use error::{ControlError, ControlInput, ControlStage};
pub use gains::{AxisGains, TaskGains};
pub use model::{Joints, TaskKinematics, TaskSpaceModel};
pub use orientation::orientation_error;
pub use trajectory::CircleTrajectory;
