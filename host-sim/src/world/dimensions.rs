//! Fixed dimensions of the simulated workcell that both the workcell generator
//! and the end-effector sampler use.

/// Radius of the disc conveyor, m (the paper's 0.9 m disc).
pub const DISC_RADIUS_M: f64 = 0.45;
/// PUMA 560 shoulder height in the base frame: d1 of `puma560-model.md`.
pub const SHOULDER_HEIGHT_M: f64 = 0.67183;
