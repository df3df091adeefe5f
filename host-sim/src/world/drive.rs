//! The arm's drives as the world has them, drawn per cell: how far the true
//! friction, armature and motor torque constants are from the table the
//! controller uses, and the amplifier between a torque command and the torque
//! a joint feels.
//!
//! A command `u` (N m, in the controller's nominal units) is clipped by the
//! amplifier to the joint's limit and sets the current reference. The current
//! loop follows it with a first-order lag of time constant `T`
//! (`di/dt = (u - i) / T`, `i` in nominal N m), and the motor turns the
//! current into torque with its true constant and its commutation ripple:
//!
//! `tau = (k_true / k_nominal) * i * (1 + r sin(N G q + phi))`
//!
//! with `G` the joint's gear ratio (so `G q` is the motor's angle), `N` ripple
//! cycles per motor turn and `phi` a phase drawn per joint.
//!
//! Why these values (the scenario's defaults, `robot.drive`, [`DriveSettings`]):
//! - `T` = 0.5 ms. The PUMA 560's motors are brushed permanent-magnet DC
//!   motors driven by analog current-mode amplifiers. A brushed motor's
//!   winding alone has an electrical time constant `L / R` of about 1 ms at
//!   this size (a few mH over a few ohms); the current loop closed round it
//!   typically brings that to a bandwidth of a few hundred hertz. 0.5 ms
//!   (320 Hz) is that reasoning, not a measured PUMA figure; it is half a
//!   control period at 1 kHz, so the lag is felt in every period.
//! - ripple 3 % at 16 cycles per motor turn: a brushed motor's torque dips as
//!   the brushes pass from one commutator segment to the next; a few percent
//!   at a few tens of cycles per turn is typical of small servo motors. The
//!   figure is an assumption stated here, not a PUMA measurement.
//! - torque constant within +-5 %: a motor catalogue's usual tolerance.
//! - friction and armature within +-30 %: the spread between published PUMA
//!   560 parameter sets (Corke and Armstrong-Helouvry 1994 compare them) is of
//!   that order for the drive terms.

use std::f64::consts::TAU;

use rand::{Rng, RngExt};
use serde::Serialize;
use shared::robot::{JointVector, Puma560};

use crate::scenario::pick::DriveSettings;

/// One cell's true drives.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlantDrives {
    /// True friction over the table's, per joint.
    pub friction_scale: [f64; 6],
    /// True armature inertia over the table's, per joint.
    pub armature_scale: [f64; 6],
    /// `k_true / k_nominal`, per joint.
    pub torque_constant_ratio: [f64; 6],
    /// The current loop's time constant, s.
    pub time_constant_s: f64,
    /// Ripple amplitude (fraction of the torque), cycles per motor turn, and
    /// each joint's phase.
    pub ripple_fraction: f64,
    pub ripple_cycles_per_motor_rev: f64,
    pub ripple_phase_rad: [f64; 6],
    /// The gear ratios (motor turns per joint turn, signed).
    gear_ratio: [f64; 6],
}

impl PlantDrives {
    /// The drives drawn from `rng` within `settings`' spreads.
    pub fn draw(settings: &DriveSettings, rng: &mut impl Rng) -> Self {
        let mut spread = |e: f64| -> [f64; 6] {
            core::array::from_fn(|_| 1.0 - e + 2.0 * e * rng.random::<f64>())
        };
        let friction_scale = spread(settings.friction_error);
        let armature_scale = spread(settings.armature_error);
        let torque_constant_ratio = spread(settings.torque_constant_error);
        let ripple_phase_rad = core::array::from_fn(|_| TAU * rng.random::<f64>());
        let table = Puma560::<f64>::new();
        Self {
            friction_scale,
            armature_scale,
            torque_constant_ratio,
            time_constant_s: settings.current_loop_time_constant_ms * 1e-3,
            ripple_fraction: settings.torque_ripple_fraction,
            ripple_cycles_per_motor_rev: settings.torque_ripple_cycles_per_motor_rev,
            ripple_phase_rad,
            gear_ratio: table.drive_params().map(|d| d.gear_ratio),
        }
    }

    /// The table's drives and an ideal amplifier.
    pub fn exact() -> Self {
        Self {
            friction_scale: [1.0; 6],
            armature_scale: [1.0; 6],
            torque_constant_ratio: [1.0; 6],
            time_constant_s: 0.0,
            ripple_fraction: 0.0,
            ripple_cycles_per_motor_rev: 0.0,
            ripple_phase_rad: [0.0; 6],
            gear_ratio: Puma560::<f64>::new().drive_params().map(|d| d.gear_ratio),
        }
    }

    /// The current (nominal N m) `elapsed_s` after it was `start` under the
    /// reference `reference`: the first-order lag solved exactly (the
    /// reference is held over a plant step).
    pub fn current_at(
        &self,
        start: &JointVector<f64>,
        reference: &JointVector<f64>,
        elapsed_s: f64,
    ) -> JointVector<f64> {
        if self.time_constant_s <= 0.0 {
            return *reference;
        }
        let decay = (-elapsed_s / self.time_constant_s).exp();
        reference + (start - reference) * decay
    }

    /// The torque the motors deliver at joint angles `q` for the current
    /// `current` (nominal N m): the true torque constant and the ripple.
    pub fn torque(&self, current: &JointVector<f64>, q: &JointVector<f64>) -> JointVector<f64> {
        JointVector::from_fn(|j, _| {
            let motor_angle = self.gear_ratio[j] * q[j];
            let ripple = self.ripple_fraction
                * (self.ripple_cycles_per_motor_rev * motor_angle + self.ripple_phase_rad[j]).sin();
            self.torque_constant_ratio[j] * current[j] * (1.0 + ripple)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn the_draws_stay_within_their_spreads_and_zero_spreads_are_the_table() {
        let settings = DriveSettings::default();
        settings.validate().unwrap();
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..100 {
            let drives = PlantDrives::draw(&settings, &mut rng);
            for j in 0..6 {
                assert!((drives.friction_scale[j] - 1.0).abs() <= 0.3);
                assert!((drives.armature_scale[j] - 1.0).abs() <= 0.3);
                assert!((drives.torque_constant_ratio[j] - 1.0).abs() <= 0.05);
            }
        }
        let exact = PlantDrives::exact();
        let q = JointVector::new(0.1, 0.2, 0.3, 0.4, 0.5, 0.6);
        let u = JointVector::new(10.0, -20.0, 5.0, 1.0, -1.0, 0.5);
        assert_eq!(exact.torque(&u, &q), u);
        assert_eq!(exact.current_at(&JointVector::zeros(), &u, 1e-4), u);
        let mut bad = settings;
        bad.friction_error = 1.2;
        assert!(bad.validate().is_err());
    }

    #[test]
    fn the_current_lags_its_reference_by_the_time_constant() {
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(4);
        let drives = PlantDrives::draw(&DriveSettings::default(), &mut rng);
        let u = JointVector::repeat(10.0);
        let one_tau = drives.current_at(&JointVector::zeros(), &u, drives.time_constant_s);
        assert!((one_tau[0] - 10.0 * (1.0 - (-1.0_f64).exp())).abs() < 1e-12);
        // The ripple moves the torque by at most its fraction, the constant by its ratio.
        for step in 0..1000 {
            let q = JointVector::repeat(f64::from(step) * 1e-3);
            let tau = drives.torque(&u, &q);
            for j in 0..6 {
                let ideal = drives.torque_constant_ratio[j] * 10.0;
                assert!((tau[j] - ideal).abs() <= 0.03 * ideal + 1e-12);
            }
        }
    }
}
