//! The PUMA 560 parameter table of `docs/reference/puma560-model.md` (f64, SI), plus the joint speed (Corke 1996) and torque (AKB86) limits.
//!
//! Source of the kinematic and dynamic rows (as the model file states): Robotics Toolbox for
//! Python 1.5.0, `models.DH.Puma560()`, which cites P. Corke and B. Armstrong-Helouvry, "A search
//! for consensus among model parameters reported for the PUMA 560 robot", ICRA 1994, and
//! B. Armstrong, O. Khatib and J. Burdick, "The explicit dynamic model and inertial parameters of
//! the PUMA 560 arm", ICRA 1986 (AKB86). Position limits: Wang and Chen, IEEE T-RA 7(4), 1991.

use super::dh::Twist;

/// Standard DH rows `(a (m), d (m), twist)`, joints 1..6 (all offsets 0).
pub const DH_ROWS: [(f64, f64, Twist); 6] = [
    (0.0, 0.67183, Twist::PlusHalfPi),
    (0.4318, 0.0, Twist::Zero),
    (0.0203, 0.15005, Twist::MinusHalfPi),
    (0.0, 0.4318, Twist::PlusHalfPi),
    (0.0, 0.0, Twist::MinusHalfPi),
    (0.0, 0.0, Twist::Zero),
];

/// Link masses (kg). Link 1 has mass 0 (AKB86 found none) but a non-zero Iyy: it is not skipped.
pub const MASS: [f64; 6] = [0.0, 17.4, 4.8, 0.82, 0.34, 0.09];

/// Centres of mass in link frame {j}, relative to its origin (m).
pub const COM: [[f64; 3]; 6] = [
    [0.0, 0.0, 0.0],
    [-0.3638, 0.006, 0.2275],
    [-0.0203, -0.0141, 0.070],
    [0.0, 0.019, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 0.032],
];

/// Principal inertias `[Ixx, Iyy, Izz]` about the COM, axes parallel to frame {j} (kg m^2)
/// (all products of inertia are 0 in the table).
pub const INERTIA_DIAGONAL: [[f64; 3]; 6] = [
    [0.0, 0.35, 0.0],
    [0.13, 0.524, 0.539],
    [0.066, 0.086, 0.0125],
    [1.8e-3, 1.3e-3, 1.8e-3],
    [0.3e-3, 0.4e-3, 0.3e-3],
    [0.15e-3, 0.15e-3, 0.04e-3],
];

/// Motor (armature) inertia `Jm`, motor side (kg m^2).
pub const MOTOR_INERTIA: [f64; 6] = [200e-6, 200e-6, 200e-6, 33e-6, 33e-6, 33e-6];

/// Gear ratio `G` (signed, as in the toolbox).
pub const GEAR_RATIO: [f64; 6] = [-62.6111, 107.815, -53.7063, 76.0364, 71.923, 76.686];

/// Viscous friction `B`, motor side (N m s/rad).
pub const VISCOUS_FRICTION: [f64; 6] = [1.48e-3, 0.817e-3, 1.38e-3, 71.2e-6, 82.6e-6, 36.7e-6];

/// Coulomb friction `Tc+` (applied for qd > 0), motor side (N m).
pub const COULOMB_POSITIVE: [f64; 6] = [0.395, 0.126, 0.132, 11.2e-3, 9.26e-3, 3.96e-3];

/// Coulomb friction `Tc-` (applied for qd < 0, negative), motor side (N m).
pub const COULOMB_NEGATIVE: [f64; 6] = [-0.435, -0.071, -0.105, -16.9e-3, -14.5e-3, -10.5e-3];

/// One degree in radians: the table's position limits are whole degrees.
const DEGREE: f64 = core::f64::consts::PI / 180.0;

/// Joint position limits (rad) (Wang and Chen 1991, via the toolbox): lower bounds,
/// -160, -45, -225, -110, -100, -266 degrees.
pub const POSITION_MIN: [f64; 6] = [
    -160.0 * DEGREE,
    -45.0 * DEGREE,
    -225.0 * DEGREE,
    -110.0 * DEGREE,
    -100.0 * DEGREE,
    -266.0 * DEGREE,
];

/// Joint position limits (rad): upper bounds, 160, 225, 45, 170, 100, 266 degrees.
pub const POSITION_MAX: [f64; 6] = [
    160.0 * DEGREE,
    225.0 * DEGREE,
    45.0 * DEGREE,
    170.0 * DEGREE,
    100.0 * DEGREE,
    266.0 * DEGREE,
];

/// Joint speed limits (rad/s), load side.
///
/// Source: P. I. Corke, *Visual Control of Robots: High-Performance Visual Servoing*, Research
/// Studies Press, 1996, Table 2.21 ("load referenced" maximum joint velocity: 1.92, 1.51, 2.40,
/// 5.34, 5.09, 5.74 rad/s), which divides the motor voltage-saturation speeds measured in his
/// Table 2.18 (120, 163, 129, 406, 366, 440 rad/s, motor side) by the gear ratios `|G|` of the
/// table above. The values below are those quotients. They were taken as quoted from the book's
/// tables by another public robotics library; this project has not checked the printed book.
pub const VELOCITY_MAX: [f64; 6] = [
    120.0 / 62.6111,
    163.0 / 107.815,
    129.0 / 53.7063,
    406.0 / 76.0364,
    366.0 / 71.923,
    440.0 / 76.686,
];

/// Joint torque limits (N m).
///
/// Source: B. Armstrong, O. Khatib and J. Burdick, "The explicit dynamic model and inertial
/// parameters of the PUMA 560 arm", Proc. IEEE ICRA 1986 (AKB86, one of the sources of this
/// model's table), Table 7 "Maximum Torque (N-m)": 97.6, 186.4, 89.4, 24.2, 20.1, 21.3. Taken
/// as quoted by another public robotics library; this project has not checked the printed paper.
/// The unit tests check the property the controller relies on: every limit exceeds the largest
/// static gravity torque of the rigid model over the joint range (at most about 46 N m at joint 2
/// and 8.8 N m at joint 3, sampled), so the arm can always hold itself.
pub const TORQUE_MAX: [f64; 6] = [97.6, 186.4, 89.4, 24.2, 20.1, 21.3];

/// Standard gravity of the model, base frame (m/s^2) (toolbox and Pinocchio default).
pub const GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];
