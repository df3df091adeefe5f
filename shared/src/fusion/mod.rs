//! Multisensor fusion (paper Section 2, Eq 1): the slow vision estimate of the part
//! in the rotating frame plus the fast conveyor encoder angle give the part's pose,
//! velocity and acceleration in the robot's base frame at control rate.
//!
//! - [`encoder`]: unwrapping a 16- or 32-bit conveyor counter into an unbounded count.
//! - [`conveyor`]: a Kalman filter for the conveyor's angle, speed and acceleration
//!   from quantised counts, with its uncertainty.
//! - [`trigger`]: encoder values latched at each camera trigger, paired with the
//!   frame that comes back, so vision latency never biases theta.
//! - [`part_motion`]: Eq 1 and its first two time derivatives.

pub mod conveyor;
pub mod encoder;
pub mod mean_speed;
pub mod part_motion;
pub mod trigger;

mod error;

pub use conveyor::{ConveyorFilter, ConveyorState};
pub use encoder::{CounterWidth, EncoderUnwrapper};
pub use error::FusionError;
pub use mean_speed::ConveyorMeanSpeed;
pub use part_motion::{part_motion_in_base, PartMotion};
pub use trigger::{LatchedSample, TriggerLatch, Triggered};
