//! The truth beside the pick's own log (`observations.truth.json`): the drawn
//! workcell in the calibration-result format of the contract (camera pose,
//! the part's features in the rotating frame, `base_from_disc`), keys at the
//! top level as `host-sim record` writes them, so that the file also reads as
//! a calibration result (`host-sim calibrate --truth`). The world's
//! workcell is the one drawn at the start: a camera bump (a fault
//! experiment) moves the camera away from it, and the frames after the bump
//! then miss the truth, which the `quality` below shows.
//!
//! The contract's disc frame has its X axis towards the reference mark at
//! the log's conveyor angle 0: the pick's first sensor sample, after homing,
//! when the world's disc has already turned by some angle `phi`. The truth is
//! the world's workcell turned into that frame ([`in_log_frames`]).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use shared::observation::{CalibrationQuality, CalibrationResult, ObservationFrame, PixelPoint};

use crate::geometry::{from_array, rotation_z, wrap_angle};
use crate::world::workcell::Workcell;

/// Pixels beyond which a logged detection counts as an outlier against the
/// truth (outside the pixel noise's reach at any of the scenarios' sigmas).
pub const TRUTH_OUTLIER_GATE_PX: f64 = 5.0;

/// The pick's truth file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PickTruthFile {
    /// The drawn workcell; `quality` describes the log against it: frames
    /// with a detection, with the marks, the RMS of the detections' distance
    /// to the truth's images within [`TRUTH_OUTLIER_GATE_PX`] (the logged
    /// conveyor angles and mark positions taken as exact), the detections
    /// beyond it, the camera's pixel noise as simulated.
    #[serde(flatten)]
    pub result: CalibrationResult,
    /// The experiment and the world's seed (`host-sim run --experiment E --seed S`).
    pub experiment: String,
    pub seed: u64,
}

/// Distance from the detection `px` to the image of `p_disc`, if imaged.
fn residual_px(workcell: &Workcell, px: &PixelPoint, p_disc: &Vector3<f64>) -> Option<f64> {
    let [u, v] = workcell.camera.project(p_disc)?;
    Some((px[0] - u).hypot(px[1] - v))
}

/// Every detection of `frame` against the truth: the distances in pixels.
fn frame_residuals_px(workcell: &Workcell, frame: &ObservationFrame) -> Vec<f64> {
    let theta = frame.conveyor_angle_rad;
    let mut pairs: Vec<(PixelPoint, Vector3<f64>)> = Vec::new();
    if let Some(px) = frame.center_px {
        pairs.push((px, Vector3::zeros()));
    }
    if let Some(px) = frame.reference_px {
        pairs.push((px, workcell.reference_disc(theta)));
    }
    if let Some(part) = &frame.part_px {
        for (px, p_rotating) in part.iter().zip(&workcell.features_rotating) {
            pairs.push((*px, Workcell::disc_from_rotating(theta, p_rotating)));
        }
    }
    if let Some(effector) = &frame.effector {
        for (px, base_m) in effector.px.iter().zip(&effector.base_m) {
            pairs.push((*px, workcell.disc_from_base(&from_array(*base_m))));
        }
    }
    pairs
        .iter()
        .map(|(px, p_disc)| residual_px(workcell, px, p_disc).unwrap_or(f64::INFINITY))
        .collect()
}

/// The log's frames against the truth (see [`PickTruthFile::result`]).
pub fn log_quality(
    workcell: &Workcell,
    frames: &[ObservationFrame],
    pixel_sigma_px: f64,
) -> CalibrationQuality {
    let mut frames_used = 0_u32;
    let mut effector_frames_used = 0_u32;
    let mut squared = 0.0;
    let mut inliers = 0_u64;
    let mut outliers = 0_u32;
    for frame in frames {
        let residuals = frame_residuals_px(workcell, frame);
        if !residuals.is_empty() {
            frames_used += 1;
        }
        if frame.effector.is_some() {
            effector_frames_used += 1;
        }
        for r in residuals {
            if r <= TRUTH_OUTLIER_GATE_PX {
                squared += r * r;
                inliers += 1;
            } else {
                outliers += 1;
            }
        }
    }
    CalibrationQuality {
        frames_used,
        rms_reprojection_px: if inliers > 0 {
            (squared / inliers as f64).sqrt()
        } else {
            0.0
        },
        effector_frames_used,
        outliers_rejected: outliers,
        pixel_sigma_px,
    }
}

/// `workcell` in the frames of a log whose conveyor angle 0 is the world's
/// disc angle `phi_rad`: the disc frame turned by `phi` about its Z axis
/// (`p_disc_world = Rz(phi) p_disc_log`), so the camera's pose is turned by
/// `-phi` and `base_from_disc`'s yaw grows by `phi`; the rotating frame, the
/// part in it, and the base frame are the same.
pub fn in_log_frames(workcell: &Workcell, phi_rad: f64) -> Workcell {
    let log_from_world = rotation_z(-phi_rad);
    let mut turned = workcell.clone();
    turned.camera.disc_from_camera_rotation =
        log_from_world * workcell.camera.disc_from_camera_rotation;
    turned.camera.optical_centre_disc = log_from_world * workcell.camera.optical_centre_disc;
    turned.base_from_disc_yaw_rad = wrap_angle(workcell.base_from_disc_yaw_rad + phi_rad);
    turned
}

/// The truth file of a pick of `experiment` with seed `seed` in `workcell`
/// (its disc at angle `phi_rad` at the log's angle 0), whose worker was
/// given `frames`.
pub fn pick_truth(
    workcell: &Workcell,
    phi_rad: f64,
    frames: &[ObservationFrame],
    pixel_sigma_px: f64,
    experiment: &str,
    seed: u64,
) -> PickTruthFile {
    let workcell = in_log_frames(workcell, phi_rad);
    PickTruthFile {
        result: workcell.truth(log_quality(&workcell, frames, pixel_sigma_px)),
        experiment: experiment.to_string(),
        seed,
    }
}
