//! Recording a synthetic observation log from a random workcell: the images of
//! the disc centre, the reference mark, the part's features and (in a few frames)
//! two end-effector marks, with pixel noise, dropouts and gross outliers as the
//! scenario says. Detections outside the image (contract rule) are null. The
//! ground truth goes beside the log ([`truth`]).

use std::f64::consts::TAU;

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{Rng, RngExt, SeedableRng};
use rand_distr::StandardNormal;
use shared::observation::{
    CalibrationQuality, EffectorSighting, ObservationFrame, PixelPoint, MAX_PART_FEATURES,
};

use crate::geometry::to_array;
use crate::log::ObservationLog;
use crate::scenario::recording::Scenario;
use crate::world::camera::PinholeCamera;
use crate::world::effector::{EffectorPose, EffectorSampler};
use crate::world::generator::{random_workcell, GenerationError};
use crate::world::workcell::Workcell;

pub mod truth;

pub use truth::{
    read_truth_file, read_truth_result, truth_path_for, write_truth_file, write_truth_file_of,
    TruthFile,
};

/// Attempts at a tool pose whose noisy marks both land in the image.
const EFFECTOR_POSE_ATTEMPTS: usize = 100;

/// A recorded log with the workcell that produced it and its ground truth.
#[derive(Debug, Clone)]
pub struct SimulatedRun {
    pub log: ObservationLog,
    pub workcell: Workcell,
    pub truth: TruthFile,
}

/// Counts what the detector did, for the truth file's `quality`.
#[derive(Debug, Default)]
struct DetectionStats {
    inlier_squared_px: f64,
    inlier_points: u64,
    outliers: u32,
}

/// Turns true image points into detections per the scenario's noise model.
struct Detector<'s, R> {
    scenario: &'s Scenario,
    camera: &'s PinholeCamera,
    rng: R,
    stats: DetectionStats,
}

impl<R: Rng> Detector<'_, R> {
    fn dropped(&mut self) -> bool {
        self.scenario.dropout_probability > 0.0
            && self.rng.random::<f64>() < self.scenario.dropout_probability
    }

    /// The reported image of `p_disc`, or `None` when behind the camera or outside the image.
    fn detect_point(&mut self, p_disc: &Vector3<f64>) -> Option<PixelPoint> {
        let [u, v] = self.camera.project(p_disc)?;
        let intrinsics = &self.camera.intrinsics;
        let is_outlier = self.scenario.outlier_probability > 0.0
            && self.rng.random::<f64>() < self.scenario.outlier_probability;
        let reported = if is_outlier {
            [
                -0.5 + f64::from(intrinsics.width) * self.rng.random::<f64>(),
                -0.5 + f64::from(intrinsics.height) * self.rng.random::<f64>(),
            ]
        } else {
            let sigma = self.scenario.pixel_sigma_px;
            let du: f64 = self.rng.sample(StandardNormal);
            let dv: f64 = self.rng.sample(StandardNormal);
            [u + sigma * du, v + sigma * dv]
        };
        if !intrinsics.contains(reported) {
            return None;
        }
        if is_outlier {
            self.stats.outliers += 1;
        } else {
            let [ru, rv] = reported;
            self.stats.inlier_squared_px += (ru - u).powi(2) + (rv - v).powi(2);
            self.stats.inlier_points += 1;
        }
        Some(reported)
    }

    /// A single mark (disc centre or reference point), subject to dropout.
    fn detect_mark(&mut self, p_disc: &Vector3<f64>) -> Option<PixelPoint> {
        if self.dropped() {
            None
        } else {
            self.detect_point(p_disc)
        }
    }

    /// The part: all features or nothing (contract rule for `part_px`).
    fn detect_part(
        &mut self,
        features_disc: &[Vector3<f64>],
    ) -> Option<heapless::Vec<PixelPoint, MAX_PART_FEATURES>> {
        if self.dropped() {
            return None;
        }
        let points: Option<Vec<PixelPoint>> =
            features_disc.iter().map(|p| self.detect_point(p)).collect();
        heapless::Vec::from_slice(&points?).ok()
    }

    fn detect_effector(&mut self, pose: &EffectorPose) -> Option<EffectorSighting> {
        let [first_disc, second_disc] = &pose.marks_disc;
        let [first_base, second_base] = &pose.marks_base;
        let first_px = self.detect_point(first_disc)?;
        let second_px = self.detect_point(second_disc)?;
        Some(EffectorSighting {
            px: [first_px, second_px],
            base_m: [to_array(first_base), to_array(second_base)],
        })
    }
}

/// Frame indices that show the end effector: a count drawn from the scenario's range.
fn effector_frame_mask(rng: &mut impl Rng, scenario: &Scenario) -> Vec<bool> {
    let low = scenario.effector_frames_min.min(scenario.frames);
    let high = scenario.effector_frames_max.clamp(low, scenario.frames);
    let count = rng.random_range(low..=high);
    let mut mask = vec![false; scenario.frames];
    for index in rand::seq::index::sample(rng, scenario.frames, count) {
        if let Some(slot) = mask.get_mut(index) {
            *slot = true;
        }
    }
    mask
}

/// Records one log for `scenario` from the workcell drawn with `seed`.
pub fn simulate(scenario: &Scenario, seed: u64) -> Result<SimulatedRun, GenerationError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (workcell, parameters) = random_workcell(&mut rng, scenario)?;
    let effector_mask = effector_frame_mask(&mut rng, scenario);
    let sampler = EffectorSampler::new(&workcell);
    let mut detector = Detector {
        scenario,
        camera: &workcell.camera,
        rng,
        stats: DetectionStats::default(),
    };

    let mut frames = Vec::with_capacity(scenario.frames);
    let mut frames_with_detections = 0_u32;
    let mut effector_frames = 0_u32;
    for (index, shows_effector) in effector_mask.iter().copied().enumerate() {
        let step = index as f64;
        let theta_rad = TAU * scenario.revolutions * step / scenario.frames as f64;
        let features_disc: Vec<Vector3<f64>> = workcell
            .features_rotating
            .iter()
            .map(|p| Workcell::disc_from_rotating(theta_rad, p))
            .collect();
        let center_px = detector.detect_mark(&Vector3::zeros());
        let reference_px = detector.detect_mark(&workcell.reference_disc(theta_rad));
        let part_px = detector.detect_part(&features_disc);
        let effector = if shows_effector {
            (0..EFFECTOR_POSE_ATTEMPTS).find_map(|_| {
                let pose = sampler.sample(&mut detector.rng)?;
                detector.detect_effector(&pose)
            })
        } else {
            None
        };
        if effector.is_some() {
            effector_frames += 1;
        }
        if center_px.is_some() || reference_px.is_some() || part_px.is_some() || effector.is_some()
        {
            frames_with_detections += 1;
        }
        frames.push(ObservationFrame {
            t_s: step / scenario.frame_rate_hz,
            conveyor_angle_rad: theta_rad,
            center_px,
            reference_px,
            part_px,
            effector,
            rim: None,
        });
    }

    let stats = &detector.stats;
    let rms_reprojection_px = if stats.inlier_points > 0 {
        (stats.inlier_squared_px / stats.inlier_points as f64).sqrt()
    } else {
        0.0
    };
    let quality = CalibrationQuality {
        frames_used: frames_with_detections,
        rms_reprojection_px,
        effector_frames_used: effector_frames,
        outliers_rejected: stats.outliers,
        pixel_sigma_px: scenario.pixel_sigma_px,
    };
    let truth = TruthFile {
        result: workcell.truth(quality),
        seed,
        scenario: scenario.clone(),
        workcell: parameters,
    };
    Ok(SimulatedRun {
        log: ObservationLog {
            header: workcell.header(),
            frames,
        },
        workcell,
        truth,
    })
}
