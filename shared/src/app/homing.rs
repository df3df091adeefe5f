//! Homing at power-on: from counters that start at zero wherever the arm
//! stands to joint angles, exactly.
//!
//! A PUMA 560's joint encoders are incremental, with an index pulse once per
//! motor turn: a joint meets an index every `2 pi / |G|` radians (`G` its
//! gear ratio), at angles fixed by the arm and measured once at
//! commissioning. Each joint also has a potentiometer, good to a fraction of
//! that pitch. Homing takes the coarse angle from the potentiometer (averaged
//! at rest), turns the joint slowly until an index pulse latches its counter,
//! and takes for that count the exact angle of the index the potentiometer
//! points to. The counter's offset follows, and with it every angle.
//!
//! What stops homing, with its cause: a potentiometer that is not a number
//! or moves while the joint is at rest, one that points between two indexes
//! (farther from the nearest than its tolerance: a potentiometer or a
//! commissioning that is off), and a joint that travels its search span
//! without meeting an index (a dead index channel or a stalled joint).

use core::fmt;

/// Joints homed.
pub const JOINTS: usize = 6;

/// Samples of the potentiometer averaged at rest before the search.
pub const COARSE_SAMPLES: u32 = 32;

/// Where a joint's index pulses are: `phase_rad + k * pitch_rad`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexGrid {
    /// Joint angle between two index pulses (one motor turn), radians.
    pub pitch_rad: f32,
    /// Joint angle of index 0, radians (commissioning).
    pub phase_rad: f32,
}

impl IndexGrid {
    /// The grid of a joint whose motor turns `gear_ratio` times per joint turn.
    pub fn of_gear(gear_ratio: f32, phase_rad: f32) -> Self {
        Self {
            pitch_rad: core::f32::consts::TAU / gear_ratio.abs(),
            phase_rad,
        }
    }

    /// The angle of the index nearest `angle_rad`, and how far `angle_rad` is from it.
    pub fn nearest(&self, angle_rad: f32) -> (f32, f32) {
        let k = libm::roundf((angle_rad - self.phase_rad) / self.pitch_rad);
        let index = self.phase_rad + k * self.pitch_rad;
        (index, angle_rad - index)
    }
}

/// One joint's homing data (commissioning).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointHomingSpec {
    /// Where the index pulses are.
    pub grid: IndexGrid,
    /// The potentiometer's worst error, radians: under half the pitch, or an
    /// index could be taken for its neighbour.
    pub pot_tolerance_rad: f32,
    /// Counts per joint radian (signed: the encoder's direction).
    pub counts_per_rad: f32,
    /// Farthest the search turns the joint, radians: more than one pitch.
    pub search_span_rad: f32,
}

/// Why homing stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HomingError {
    /// The joint's specification cannot home it (tolerance not under half
    /// the pitch, search span not over one pitch, or not finite).
    BadSpec {
        /// Joint, 0-based.
        joint: usize,
    },
    /// The potentiometer read NaN or infinity.
    PotentiometerNotFinite {
        /// Joint, 0-based.
        joint: usize,
    },
    /// The potentiometer moved by more than its tolerance while the encoder
    /// said the joint was at rest.
    PotentiometerUnsteady {
        /// Joint, 0-based.
        joint: usize,
        /// Spread seen, radians.
        spread_rad: f32,
    },
    /// At the index, the potentiometer pointed between two indexes.
    PotentiometerDisagrees {
        /// Joint, 0-based.
        joint: usize,
        /// Potentiometer angle minus the nearest index's, radians.
        disagreement_rad: f32,
    },
    /// The joint travelled its search span and met no index.
    IndexNotSeen {
        /// Joint, 0-based.
        joint: usize,
        /// Travel, radians.
        travelled_rad: f32,
    },
}

impl fmt::Display for HomingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::BadSpec { joint } => write!(
                f,
                "joint {}: homing data unusable (tolerance must be under half the index pitch, the search span over one pitch)",
                joint + 1
            ),
            Self::PotentiometerNotFinite { joint } => {
                write!(f, "joint {}: potentiometer reads no number", joint + 1)
            }
            Self::PotentiometerUnsteady { joint, spread_rad } => write!(
                f,
                "joint {}: potentiometer moved {spread_rad} rad with the joint at rest",
                joint + 1
            ),
            Self::PotentiometerDisagrees {
                joint,
                disagreement_rad,
            } => write!(
                f,
                "joint {}: at the index the potentiometer is {disagreement_rad} rad from the nearest index, beyond its tolerance",
                joint + 1
            ),
            Self::IndexNotSeen {
                joint,
                travelled_rad,
            } => write!(
                f,
                "joint {}: no index pulse in {travelled_rad} rad of travel",
                joint + 1
            ),
        }
    }
}

impl core::error::Error for HomingError {}

/// Where one joint's homing stands.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Stage {
    /// Averaging the potentiometer at rest.
    Coarse {
        samples: u32,
        sum_rad: f32,
        low_rad: f32,
        high_rad: f32,
        count: i32,
    },
    /// Turning towards an index; `pot_rad` is the coarse angle at `count`.
    Seeking { pot_rad: f32, count: i32 },
    /// Done: angle = (count - offset) / counts_per_rad.
    Homed { offset_counts: i64 },
}

/// One joint's homing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointHoming {
    joint: usize,
    spec: JointHomingSpec,
    stage: Stage,
}

impl JointHoming {
    /// Homing of `joint` (0-based) with its commissioning data.
    pub fn new(joint: usize, spec: JointHomingSpec) -> Result<Self, HomingError> {
        let pitch = spec.grid.pitch_rad;
        let usable = pitch.is_finite()
            && pitch > 0.0
            && spec.grid.phase_rad.is_finite()
            && spec.pot_tolerance_rad.is_finite()
            && spec.pot_tolerance_rad > 0.0
            && spec.pot_tolerance_rad < 0.5 * pitch
            && spec.search_span_rad.is_finite()
            && spec.search_span_rad > pitch
            && spec.counts_per_rad.is_finite()
            && spec.counts_per_rad != 0.0;
        if !usable {
            return Err(HomingError::BadSpec { joint });
        }
        Ok(Self {
            joint,
            spec,
            stage: Stage::Coarse {
                samples: 0,
                sum_rad: 0.0,
                low_rad: f32::INFINITY,
                high_rad: f32::NEG_INFINITY,
                count: 0,
            },
        })
    }

    /// One potentiometer reading with the joint at rest at counter `count`.
    /// True when the coarse angle is known and the search may start.
    pub fn at_rest(&mut self, pot_rad: f32, count: i32) -> Result<bool, HomingError> {
        let joint = self.joint;
        if !pot_rad.is_finite() {
            return Err(HomingError::PotentiometerNotFinite { joint });
        }
        let Stage::Coarse {
            samples,
            sum_rad,
            low_rad,
            high_rad,
            ..
        } = self.stage
        else {
            return Ok(!matches!(self.stage, Stage::Coarse { .. }));
        };
        let (low, high) = (low_rad.min(pot_rad), high_rad.max(pot_rad));
        if high - low > 2.0 * self.spec.pot_tolerance_rad {
            return Err(HomingError::PotentiometerUnsteady {
                joint,
                spread_rad: high - low,
            });
        }
        let samples = samples + 1;
        let sum = sum_rad + pot_rad;
        self.stage = if samples >= COARSE_SAMPLES {
            Stage::Seeking {
                pot_rad: sum / samples as f32,
                count,
            }
        } else {
            Stage::Coarse {
                samples,
                sum_rad: sum,
                low_rad: low,
                high_rad: high,
                count,
            }
        };
        Ok(matches!(self.stage, Stage::Seeking { .. }))
    }

    /// The coarse angle at counter `count`, while seeking: the averaged
    /// potentiometer carried along by the counter.
    pub fn coarse_angle(&self, count: i32) -> Option<f32> {
        match self.stage {
            Stage::Seeking { pot_rad, count: at } => {
                Some(pot_rad + (count - at) as f32 / self.spec.counts_per_rad)
            }
            Stage::Homed { .. } => self.angle(count),
            Stage::Coarse { .. } => None,
        }
    }

    /// During the search: the counter at this sample, and the counter latched
    /// by an index pulse since the last sample, if one came. An index homes
    /// the joint; travel beyond the search span without one is an error.
    pub fn seeking(&mut self, count: i32, index_count: Option<i32>) -> Result<bool, HomingError> {
        let joint = self.joint;
        let Stage::Seeking { pot_rad, count: at } = self.stage else {
            return Ok(matches!(self.stage, Stage::Homed { .. }));
        };
        let per_rad = self.spec.counts_per_rad;
        if let Some(latched) = index_count {
            let pot_at_index = pot_rad + (latched - at) as f32 / per_rad;
            let (index_rad, disagreement_rad) = self.spec.grid.nearest(pot_at_index);
            if disagreement_rad.abs() > self.spec.pot_tolerance_rad {
                return Err(HomingError::PotentiometerDisagrees {
                    joint,
                    disagreement_rad,
                });
            }
            let offset_counts =
                i64::from(latched) - libm::round(f64::from(index_rad) * f64::from(per_rad)) as i64;
            self.stage = Stage::Homed { offset_counts };
            return Ok(true);
        }
        let travelled_rad = ((count - at) as f32 / per_rad).abs();
        if travelled_rad > self.spec.search_span_rad {
            return Err(HomingError::IndexNotSeen {
                joint,
                travelled_rad,
            });
        }
        Ok(false)
    }

    /// The joint angle at counter `count`, once homed.
    pub fn angle(&self, count: i32) -> Option<f32> {
        match self.stage {
            Stage::Homed { offset_counts } => Some(
                ((i64::from(count) - offset_counts) as f64 / f64::from(self.spec.counts_per_rad))
                    as f32,
            ),
            _ => None,
        }
    }

    /// The counter's offset, once homed: angle = (count - offset) / counts_per_rad.
    pub fn offset_counts(&self) -> Option<i64> {
        match self.stage {
            Stage::Homed { offset_counts } => Some(offset_counts),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::splitmix;

    const COUNTS_PER_RAD: f32 = 40_000.0;

    fn spec(gear: f32) -> JointHomingSpec {
        let grid = IndexGrid::of_gear(gear, 0.013);
        JointHomingSpec {
            grid,
            pot_tolerance_rad: 0.35 * grid.pitch_rad,
            counts_per_rad: COUNTS_PER_RAD,
            search_span_rad: 1.5 * grid.pitch_rad,
        }
    }

    /// A joint at `q_true` whose counter started at zero there: it turns up
    /// at `step` rad a sample; the index latches when it crosses an index
    /// angle. Returns the homed joint or its error.
    fn home(
        q_true: f32,
        pot_bias: f32,
        pot_noise: f32,
        seed: u64,
        index_dead: bool,
    ) -> Result<(JointHoming, f32), HomingError> {
        let mut homing = JointHoming::new(1, spec(107.815))?;
        let mut state = seed;
        let per_rad = COUNTS_PER_RAD;
        let count_at = |q: f32| ((q - q_true) * per_rad) as i32;
        while !homing.at_rest(
            q_true + pot_bias + pot_noise * (splitmix(&mut state) as f32 - 0.5),
            0,
        )? {}
        let grid = spec(107.815).grid;
        let step = 0.0005;
        let mut q = q_true;
        loop {
            let next = q + step;
            let crossed = libm::floorf((next - grid.phase_rad) / grid.pitch_rad)
                > libm::floorf((q - grid.phase_rad) / grid.pitch_rad);
            let index_count = (crossed && !index_dead).then(|| {
                let k = libm::floorf((next - grid.phase_rad) / grid.pitch_rad);
                count_at(grid.phase_rad + k * grid.pitch_rad)
            });
            q = next;
            if homing.seeking(count_at(q), index_count)? {
                return Ok((homing, q));
            }
        }
    }

    #[test]
    fn every_start_homes_to_the_exact_angle() {
        let mut state = 7;
        for trial in 0..1000 {
            let q_true = -2.0 + 4.0 * splitmix(&mut state) as f32;
            let bias = 0.2 * spec(107.815).pot_tolerance_rad * (splitmix(&mut state) as f32 - 0.5);
            let (homing, q_end) = home(q_true, bias, 0.004, trial, false).unwrap();
            let count = ((q_end - q_true) * COUNTS_PER_RAD) as i32;
            let angle = homing.angle(count).unwrap();
            // Exact to the counter's quantisation (and f32 at 2 rad).
            assert!(
                (angle - q_end).abs() < 2.0 / COUNTS_PER_RAD + 4e-7,
                "trial {trial}: {angle} vs {q_end}"
            );
        }
    }

    #[test]
    fn a_potentiometer_off_by_half_a_pitch_is_refused() {
        let pitch = spec(107.815).grid.pitch_rad;
        let error = home(0.3, 0.5 * pitch, 0.0, 1, false).err();
        assert!(
            matches!(
                error,
                Some(HomingError::PotentiometerDisagrees { joint: 1, .. })
            ),
            "{error:?}"
        );
    }

    #[test]
    fn a_dead_index_channel_stops_after_the_search_span() {
        let error = home(0.3, 0.0, 0.0, 1, true).err();
        assert!(
            matches!(error, Some(HomingError::IndexNotSeen { joint: 1, .. })),
            "{error:?}"
        );
    }

    #[test]
    fn an_unsteady_or_missing_potentiometer_is_refused() {
        let mut homing = JointHoming::new(0, spec(62.6111)).unwrap();
        assert!(matches!(
            homing.at_rest(f32::NAN, 0),
            Err(HomingError::PotentiometerNotFinite { joint: 0 })
        ));
        let tolerance = spec(62.6111).pot_tolerance_rad;
        assert_eq!(homing.at_rest(0.1, 0), Ok(false));
        assert!(matches!(
            homing.at_rest(0.1 + 3.0 * tolerance, 0),
            Err(HomingError::PotentiometerUnsteady { joint: 0, .. })
        ));
    }

    #[test]
    fn a_spec_that_cannot_tell_indexes_apart_is_refused() {
        let mut bad = spec(76.0364);
        bad.pot_tolerance_rad = 0.6 * bad.grid.pitch_rad;
        assert_eq!(
            JointHoming::new(3, bad).err(),
            Some(HomingError::BadSpec { joint: 3 })
        );
        let mut short = spec(76.0364);
        short.search_span_rad = 0.9 * short.grid.pitch_rad;
        assert_eq!(
            JointHoming::new(3, short).err(),
            Some(HomingError::BadSpec { joint: 3 })
        );
    }
}
