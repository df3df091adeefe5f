//! PUMA 560 model: kinematics and rigid-body dynamics (paper Eq 16), with switchable motor
//! armature and joint friction for the simulated plant.
//!
//! One generic implementation serves the f64 plant (host simulator) and the f32 controller
//! (firmware): `Puma560<T: RealField + Copy>`. Conventions (standard DH, frame {6} flange, COM and
//! inertia in the distal frame {j}, gravity `[0, 0, -9.81]`) are those of `docs/reference/puma560-model.md`.
//!
//! Modules, one concept each: [`table`] (parameters and their sources), [`dh`] (link transforms),
//! [`model`] (the struct and builders), [`kinematics`] (FK, Jacobian, `Jdot qd`), [`rnea`]
//! (inverse dynamics), [`crba`] (inertia matrix), [`drive`] (armature, friction), [`dynamics`]
//! (the public Eq 16 terms and forward dynamics), [`error`].
//!
//! API beyond the agreed one (all additive; the agreed names and signatures are unchanged):
//! - `try_with_payload`, `try_with_link_mass_scale`, `try_with_friction_scale` return the error
//!   for NaN/negative input; the agreed `with_*` builders leave the model unchanged on such input.
//! - `try_with_gravity` (e.g. zero gravity), `try_with_coulomb_smoothing(width)` (tanh Coulomb law
//!   for the simulator; the default is the switched law, 0 at `qd = 0`).
//! - `jacobian_and_bias(q, qd)`: J and `Jdot qd` sharing one trig/frame evaluation.
//! - `JointTrig::new(q)` plus `inverse_dynamics_with`, `mass_matrix_with`, `frame_chain_with`,
//!   `jacobian_from_chain`, `jacobian_dot_qd_with`: reuse sin/cos across terms in one tick.
//! - `try_inverse_dynamics` (rejects non-finite input), `forward_kinematics_matrix` (4x4),
//!   `armature_inertia()`, `friction_torque(qd)`, read-only accessors of the tables.
//!
//! The plain (non-`Result`) functions take any input and propagate NaN as IEEE arithmetic does;
//! they hold no state, so nothing is corrupted. Validate untrusted measurements with the
//! `try_*`/`forward_dynamics` entry points.

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
pub use drive::SIMULATOR_COULOMB_WIDTH;
pub use error::RobotError;
pub use kinematics::FrameChain;
pub use model::{
    BodyInertia, DriveOptions, DriveParams, JointLimits, LinkInertial, Payload, Puma560,
};
pub use rnea::LinkMotion;
