//! What homing reads of the arm at power-on: joint counters that start at
//! an unknown count, a potentiometer per joint and an index pulse per motor
//! turn (a PUMA 560's incremental encoders).
//!
//! - *Counters.* Each joint's counter reads `floor(q * counts_per_rad) +
//!   offset`, the offset a whole number of counts drawn at power-on (the
//!   counter started at zero wherever the arm stood). The controller never
//!   sees it; the scoring compares homing's result with it.
//! - *Potentiometers.* `q + bias + noise`, through an ADC of
//!   [`HomingSensorSettings::adc_bits`] over the joint's travel: the bias is
//!   drawn per cell within its bound (the commissioning's scale is that
//!   good), the noise is Gaussian per reading.
//! - *Index pulses.* Joint `j` meets an index at every angle of its grid
//!   (`shared::app::power_on_homing::INDEX_PHASE_RAD`, a motor turn apart:
//!   the commissioning data the controller holds). The pulse sits on a
//!   count edge: the counter, less its offset, reads
//!   `round(index_rad * counts_per_rad)` there, and the board latches that
//!   count plus the offset when the joint passes it, either way, and holds
//!   it until the next pulse (a capture register).
//!
//! Faults ([`HomingFault`]) break one joint's channel for the tests.

use anyhow::{bail, Result};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use shared::app::homing::IndexGrid;
use shared::app::power_on_homing::puma_homing_specs;
use shared::protocol::JOINTS;
use shared::robot::JointVector;

/// The homing sensors' settings (the scenario's `robot.homing`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HomingSensorSettings {
    /// The counters start at a random count at power-on (the arm must be
    /// homed); false: they read zero at q = 0 (no homing).
    #[serde(default = "yes")]
    pub counters_start_anywhere: bool,
    /// The drawn counter offsets are within +-this, counts.
    #[serde(default = "default_offset_max")]
    pub counter_offset_max_counts: i32,
    /// Each potentiometer's bias is drawn within +-this, rad.
    #[serde(default = "default_bias_max")]
    pub pot_bias_max_rad: f64,
    /// 1-sigma of a potentiometer reading's noise, rad.
    #[serde(default = "default_noise")]
    pub pot_noise_sigma_rad: f64,
    /// The potentiometers' ADC resolution over the joint's travel, bits.
    #[serde(default = "default_adc_bits")]
    pub adc_bits: u8,
    /// Where the arm stands at power-on: the ready posture with each joint
    /// moved by a uniform draw within +-this, rad (0: the ready posture).
    #[serde(default)]
    pub power_on_spread_rad: f64,
}

fn yes() -> bool {
    true
}
fn default_offset_max() -> i32 {
    1_000_000
}
/// 5 mrad: a quarter of joint 2's tolerance (20 mrad, its pitch's 0.35).
fn default_bias_max() -> f64 {
    0.005
}
/// 2 mrad: a conductive-plastic potentiometer on a 12-bit ADC.
fn default_noise() -> f64 {
    0.002
}
fn default_adc_bits() -> u8 {
    12
}

impl Default for HomingSensorSettings {
    fn default() -> Self {
        Self {
            counters_start_anywhere: true,
            counter_offset_max_counts: default_offset_max(),
            pot_bias_max_rad: default_bias_max(),
            pot_noise_sigma_rad: default_noise(),
            adc_bits: default_adc_bits(),
            power_on_spread_rad: 0.0,
        }
    }
}

/// One joint's homing channel broken (the fault tests).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum HomingFault {
    /// The joint's index pulses never reach the board.
    DeadIndex { joint: usize },
    /// The joint's potentiometer reads no number (NaN).
    PotNotANumber { joint: usize },
    /// The joint's potentiometer is off by `offset_rad` (a slipped coupling).
    PotOffset { joint: usize, offset_rad: f64 },
}

/// The joint travel the potentiometers' ADC spans, rad (about the PUMA's
/// widest range, joint 4's and 6's).
const POT_SPAN_RAD: f64 = 10.0;

/// The homing sensors of one cell.
#[derive(Debug)]
pub struct HomingSensors {
    counter_offset_counts: [i32; JOINTS],
    pot_bias_rad: [f64; JOINTS],
    noise: Normal<f64>,
    adc_step_rad: f64,
    grids: [IndexGrid; JOINTS],
    /// The counts per radian the controller is told (f32, as configured):
    /// the index counts are computed with them, as homing computes them.
    counts_per_rad_f32: [f32; JOINTS],
    counts_per_rad: [f64; JOINTS],
    /// Each joint's count (less its offset) at the last step.
    last_raw: Option<[i64; JOINTS]>,
    latched: [Option<i32>; JOINTS],
    fault: Option<HomingFault>,
    power_on_spread_rad: f64,
    rng: ChaCha8Rng,
}

impl HomingSensors {
    /// The sensors of a cell drawn from `seed`, for counters of
    /// `counts_per_rad`.
    pub fn draw(
        settings: &HomingSensorSettings,
        counts_per_rad: &[f64; JOINTS],
        fault: Option<HomingFault>,
        seed: u64,
    ) -> Result<Self> {
        if !(settings.pot_bias_max_rad.is_finite()
            && settings.pot_bias_max_rad >= 0.0
            && settings.pot_noise_sigma_rad.is_finite()
            && settings.pot_noise_sigma_rad >= 0.0
            && settings.counter_offset_max_counts >= 0
            && (1..=24).contains(&settings.adc_bits)
            && settings.power_on_spread_rad.is_finite()
            && settings.power_on_spread_rad >= 0.0)
        {
            bail!("robot.homing: settings out of range: {settings:?}");
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let max = settings.counter_offset_max_counts;
        let counter_offset_counts: [i32; JOINTS] = core::array::from_fn(|_| {
            if settings.counters_start_anywhere && max > 0 {
                rng.random_range(-max..=max)
            } else {
                0
            }
        });
        let bias = settings.pot_bias_max_rad;
        let pot_bias_rad = core::array::from_fn(|_| bias * (2.0 * rng.random::<f64>() - 1.0));
        let noise = Normal::new(0.0, settings.pot_noise_sigma_rad)?;
        let counts_per_rad_f32 = counts_per_rad.map(|c| c as f32);
        let grids = puma_homing_specs(&counts_per_rad_f32).map(|spec| spec.grid);
        Ok(Self {
            counter_offset_counts,
            pot_bias_rad,
            noise,
            adc_step_rad: POT_SPAN_RAD / f64::from(1u32 << settings.adc_bits),
            grids,
            counts_per_rad_f32,
            counts_per_rad: *counts_per_rad,
            last_raw: None,
            latched: [None; JOINTS],
            fault,
            power_on_spread_rad: settings.power_on_spread_rad,
            rng,
        })
    }

    /// Where the arm stands at power-on: `ready` moved by the drawn spread.
    pub fn power_on_posture(&mut self, ready: &JointVector<f64>) -> JointVector<f64> {
        let spread = self.power_on_spread_rad;
        ready.map(|q| q + spread * (2.0 * self.rng.random::<f64>() - 1.0))
    }

    /// The counter offsets drawn at power-on (truth: for scoring only).
    pub fn counter_offsets(&self) -> [i32; JOINTS] {
        self.counter_offset_counts
    }

    /// The counts of `q`, less the offsets: `floor(q * counts_per_rad)`.
    fn raw_counts(&self, q: &JointVector<f64>) -> [i64; JOINTS] {
        core::array::from_fn(|j| {
            (q.get(j).copied().unwrap_or(0.0) * self.counts_per_rad[j]).floor() as i64
        })
    }

    /// The counter (less its offset) at joint `j`'s index `k`.
    fn index_count(&self, j: usize, k: i64) -> i64 {
        let grid = self.grids[j];
        // In f32 as homing computes the index's angle, then rounded in f64.
        let index_rad = grid.phase_rad + k as f32 * grid.pitch_rad;
        (f64::from(index_rad) * f64::from(self.counts_per_rad_f32[j])).round() as i64
    }

    /// The arm after a plant step: an index passed since the last step
    /// latches its joint's counter.
    pub fn track(&mut self, q: &JointVector<f64>) {
        let raw = self.raw_counts(q);
        let Some(last) = self.last_raw.replace(raw) else {
            return;
        };
        for j in 0..JOINTS {
            if self.fault == Some(HomingFault::DeadIndex { joint: j }) {
                continue;
            }
            let (low, high) = (last[j].min(raw[j]), last[j].max(raw[j]));
            if low == high {
                continue;
            }
            // The indexes near the travelled counts; an index is passed
            // when the count steps onto or off its count.
            let grid = self.grids[j];
            let per_rad = self.counts_per_rad[j];
            let k_of = |count: i64| {
                ((count as f64 / per_rad - f64::from(grid.phase_rad)) / f64::from(grid.pitch_rad))
                    .floor() as i64
            };
            for k in k_of(low) - 1..=k_of(high) + 1 {
                let index = self.index_count(j, k);
                let passed = if raw[j] > last[j] {
                    last[j] < index && index <= raw[j]
                } else {
                    raw[j] < index && index <= last[j]
                };
                if passed {
                    self.latched[j] =
                        Some((index as i32).wrapping_add(self.counter_offset_counts[j]));
                }
            }
        }
    }

    /// The counters the board reads at `q`.
    pub fn counters(&self, q: &JointVector<f64>) -> [i32; JOINTS] {
        let raw = self.raw_counts(q);
        core::array::from_fn(|j| (raw[j] as i32).wrapping_add(self.counter_offset_counts[j]))
    }

    /// The potentiometers at `q`, rad (one reading each: fresh noise).
    pub fn potentiometers(&mut self, q: &JointVector<f64>) -> [f32; JOINTS] {
        core::array::from_fn(|j| {
            let truth = q.get(j).copied().unwrap_or(0.0);
            let mut reading = truth + self.pot_bias_rad[j] + self.noise.sample(&mut self.rng);
            match self.fault {
                Some(HomingFault::PotNotANumber { joint }) if joint == j => return f32::NAN,
                Some(HomingFault::PotOffset { joint, offset_rad }) if joint == j => {
                    reading += offset_rad;
                }
                _ => {}
            }
            ((reading / self.adc_step_rad).round() * self.adc_step_rad) as f32
        })
    }

    /// Each joint's count at its last index pulse (held until the next),
    /// `None` before the first.
    pub fn latched(&self) -> [Option<i32>; JOINTS] {
        self.latched
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sensors(fault: Option<HomingFault>) -> HomingSensors {
        let counts_per_rad = [10_000.0, 17_000.0, 8_500.0, 12_000.0, 11_400.0, 12_200.0];
        HomingSensors::draw(&HomingSensorSettings::default(), &counts_per_rad, fault, 5).unwrap()
    }

    #[test]
    fn an_index_latches_its_count_plus_the_offset_both_ways() {
        let mut s = sensors(None);
        let grid = s.grids[1];
        let index_rad = f64::from(grid.phase_rad + 3.0 * grid.pitch_rad);
        let mut q = JointVector::repeat(0.0);
        q[1] = index_rad - 0.001;
        s.track(&q);
        q[1] = index_rad + 0.001;
        s.track(&q);
        let expected = (s.index_count(1, 3) as i32).wrapping_add(s.counter_offsets()[1]);
        assert_eq!(s.latched()[1], Some(expected));
        // Held until the next pulse; back through the same index, the same count.
        q[1] = index_rad + 0.002;
        s.track(&q);
        assert_eq!(s.latched()[1], Some(expected));
        q[1] = index_rad - 0.001;
        s.track(&q);
        assert_eq!(s.latched()[1], Some(expected));
    }

    #[test]
    fn a_dead_index_latches_nothing_and_a_broken_pot_reads_nan() {
        let mut s = sensors(Some(HomingFault::DeadIndex { joint: 2 }));
        let mut q = JointVector::repeat(0.0);
        s.track(&q);
        q[2] = 1.0;
        s.track(&q);
        assert_eq!(s.latched()[2], None);
        let mut s = sensors(Some(HomingFault::PotNotANumber { joint: 4 }));
        assert!(s.potentiometers(&q)[4].is_nan());
    }

    #[test]
    fn the_counters_start_at_a_drawn_offset() {
        let s = sensors(None);
        let q = JointVector::repeat(0.25);
        let counters = s.counters(&q);
        for (j, counter) in counters.iter().enumerate() {
            let raw = (0.25 * s.counts_per_rad[j]).floor() as i32;
            assert_eq!(*counter, raw.wrapping_add(s.counter_offsets()[j]));
        }
        assert!(s.counter_offsets().iter().any(|o| *o != 0));
    }
}
