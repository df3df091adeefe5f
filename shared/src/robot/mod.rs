//! PUMA 560 model: kinematics and rigid-body dynamics (paper Eq 16), with switchable motor
//! armature and joint friction for the simulated plant.
//!
//! One generic implementation serves the f64 plant (host simulator) and the f32 controller
//! (firmware): `Puma560<T: RealField + Copy>`. Conventions (standard DH, frame {6} flange, COM and
//! inertia in the distal frame {j}, gravity `[0, 0, -9.81]`) are those of `puma560-model.md`.
//!
//! Modules, one concept each: [`table`] (parameters and their sources), [`dh`] (link transforms),
//! [`model`] (the struct and builders), [`kinematics`] (FK, Jacobian, `Jdot qd`), [`rnea`]
//! (inverse dynamics), [`crba`] (inertia matrix), [`drive`] (armature, friction), [`dynamics`]
//! (the public Eq 16 terms and forward dynamics), [`error`].

pub mod crba;
pub mod dh;
pub mod drive;
pub mod dynamics;
pub mod error;
pub mod kinematics;
pub mod model;
pub mod rnea;
pub mod table;

use nalgebra::Vector6;

/// One value per joint, joints 1..6 in order.
pub type JointVector<T> = Vector6<T>;

pub use dh::{DhLink, JointTrig, SinCos, Twist};
pub use error::RobotError;
pub use kinematics::FrameChain;
pub use model::{
    BodyInertia, DriveOptions, DriveParams, JointLimits, LinkInertial, Payload, Puma560,
};
pub use rnea::LinkMotion;
