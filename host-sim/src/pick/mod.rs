//! The full pick in the simulated workcell: the world (plant, conveyor, camera,
//! gripper) against the controller application over the serial protocol.

pub mod record;
