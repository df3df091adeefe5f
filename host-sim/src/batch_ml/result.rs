//! Between the contract's calibration result and the batch model: the start
//! (read from any result, usually the calibrator's) and the answer.

use nalgebra::{Rotation3, Vector3};
use shared::observation::{
    BaseFromDisc, CalibrationQuality, CalibrationResult, CameraEstimate, PartEstimate,
    RigidTransform, MAX_PART_FEATURES,
};

use super::model::BatchModel;
use crate::geometry::{from_array, from_rows, rows, to_array, wrap_angle};

/// The model a result describes; `disc_height_in_base_m`, when known, replaces
/// the base translation's z (it is then held).
pub fn model_from_result(
    result: &CalibrationResult,
    disc_height_in_base_m: Option<f64>,
) -> BatchModel {
    let disc_from_camera =
        Rotation3::from_matrix(&from_rows(&result.camera.disc_from_camera.rotation));
    let camera_from_disc = disc_from_camera.inverse();
    let centre_disc = from_array(result.camera.disc_from_camera.translation_m);
    let mut base_translation = from_array(result.base_from_disc.translation_m);
    if let Some(height) = disc_height_in_base_m {
        base_translation.z = height;
    }
    BatchModel {
        camera_translation: -(camera_from_disc * centre_disc),
        camera_from_disc,
        features_rotating: result
            .part
            .features_m
            .iter()
            .copied()
            .map(from_array)
            .collect(),
        base_yaw_rad: result.base_from_disc.yaw_rad,
        base_translation,
    }
}

/// The contract's result for `model`, with `quality` as measured by the caller.
pub fn result_from_model(model: &BatchModel, quality: CalibrationQuality) -> CalibrationResult {
    let centre = model.camera_centre_disc();
    let features: Vec<[f64; 3]> = model.features_rotating.iter().map(to_array).collect();
    let sum: Vector3<f64> = model.features_rotating.iter().sum();
    let position = sum / model.features_rotating.len().max(1) as f64;
    let yaw_rad = match (
        model.features_rotating.first(),
        model.features_rotating.get(1),
    ) {
        (Some(f0), Some(f1)) => (f1.y - f0.y).atan2(f1.x - f0.x),
        _ => 0.0,
    };
    let mut features_m = heapless::Vec::<[f64; 3], MAX_PART_FEATURES>::new();
    for feature in features.into_iter().take(MAX_PART_FEATURES) {
        // Cannot fail: at most MAX_PART_FEATURES are pushed.
        let _ = features_m.push(feature);
    }
    CalibrationResult {
        camera: CameraEstimate {
            height_m: centre.z,
            disc_from_camera: RigidTransform {
                rotation: rows(model.camera_from_disc.inverse().matrix()),
                translation_m: to_array(&centre),
            },
        },
        part: PartEstimate {
            features_m,
            position_m: to_array(&position),
            yaw_rad,
        },
        base_from_disc: BaseFromDisc {
            yaw_rad: wrap_angle(model.base_yaw_rad),
            translation_m: to_array(&model.base_translation),
        },
        quality,
    }
}
