//! Errors of a calibration result against the ground truth, in the units the
//! accuracy targets use (millimetres and degrees).

use std::fmt;

use serde::{Deserialize, Serialize};
use shared::observation::CalibrationResult;

use crate::geometry::{angle_distance, from_array, from_rows, rotation_z};

/// One calibration's errors. Distances are 3-D Euclidean.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ErrorMetrics {
    /// The largest error over the part's feature points (rotating frame), mm.
    pub feature_mm: f64,
    /// Error of the part position (mean of the features), mm.
    pub part_position_mm: f64,
    /// Error of the part yaw (feature 0 -> 1), degrees.
    pub part_yaw_deg: f64,
    /// Error of the optical centre's height above the disc, mm.
    pub camera_height_mm: f64,
    /// Angle of the rotation between estimated and true `disc_from_camera`, degrees.
    pub camera_rotation_deg: f64,
    /// Error of `base_from_disc.translation_m` (the disc centre in the base frame), mm.
    pub base_translation_mm: f64,
    /// Error of `base_from_disc.yaw_rad`, degrees.
    pub base_yaw_deg: f64,
    /// Error of the part's position in the robot's base frame (Eq 1, what the
    /// gripper is sent to), worst over one revolution of the disc, mm. Camera,
    /// part and base errors are correlated, so this is usually far smaller than
    /// `base_translation_mm`.
    #[serde(default)]
    pub part_in_base_mm: f64,
}

/// A metric's column: name, unit, accessor.
pub struct MetricColumn {
    pub name: &'static str,
    pub unit: &'static str,
    pub value: fn(&ErrorMetrics) -> f64,
}

pub const METRIC_COLUMNS: [MetricColumn; 8] = [
    MetricColumn {
        name: "feature_mm",
        unit: "mm",
        value: |m| m.feature_mm,
    },
    MetricColumn {
        name: "part_position_mm",
        unit: "mm",
        value: |m| m.part_position_mm,
    },
    MetricColumn {
        name: "part_yaw_deg",
        unit: "deg",
        value: |m| m.part_yaw_deg,
    },
    MetricColumn {
        name: "camera_height_mm",
        unit: "mm",
        value: |m| m.camera_height_mm,
    },
    MetricColumn {
        name: "camera_rotation_deg",
        unit: "deg",
        value: |m| m.camera_rotation_deg,
    },
    MetricColumn {
        name: "base_translation_mm",
        unit: "mm",
        value: |m| m.base_translation_mm,
    },
    MetricColumn {
        name: "base_yaw_deg",
        unit: "deg",
        value: |m| m.base_yaw_deg,
    },
    MetricColumn {
        name: "part_in_base_mm",
        unit: "mm",
        value: |m| m.part_in_base_mm,
    },
];

/// The estimate cannot be compared with the truth.
#[derive(Debug, Clone, PartialEq)]
pub enum MetricsError {
    FeatureCount { estimate: usize, truth: usize },
}

impl fmt::Display for MetricsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::FeatureCount { estimate, truth } => write!(
                f,
                "the estimate has {estimate} part features, the truth {truth}"
            ),
        }
    }
}

impl std::error::Error for MetricsError {}

const MM_PER_M: f64 = 1000.0;

fn distance_mm(a: [f64; 3], b: [f64; 3]) -> f64 {
    (from_array(a) - from_array(b)).norm() * MM_PER_M
}

pub fn compare(
    estimate: &CalibrationResult,
    truth: &CalibrationResult,
) -> Result<ErrorMetrics, MetricsError> {
    let (estimated_features, true_features) = (&estimate.part.features_m, &truth.part.features_m);
    if estimated_features.len() != true_features.len() {
        return Err(MetricsError::FeatureCount {
            estimate: estimated_features.len(),
            truth: true_features.len(),
        });
    }
    let feature_mm = estimated_features
        .iter()
        .zip(true_features.iter())
        .map(|(e, t)| distance_mm(*e, *t))
        .fold(0.0, f64::max);
    let relative_rotation = from_rows(&estimate.camera.disc_from_camera.rotation).transpose()
        * from_rows(&truth.camera.disc_from_camera.rotation);
    let cos_angle = ((relative_rotation.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    Ok(ErrorMetrics {
        feature_mm,
        part_position_mm: distance_mm(estimate.part.position_m, truth.part.position_m),
        part_yaw_deg: angle_distance(estimate.part.yaw_rad, truth.part.yaw_rad).to_degrees(),
        camera_height_mm: (estimate.camera.height_m - truth.camera.height_m).abs() * MM_PER_M,
        camera_rotation_deg: cos_angle.acos().to_degrees(),
        base_translation_mm: distance_mm(
            estimate.base_from_disc.translation_m,
            truth.base_from_disc.translation_m,
        ),
        base_yaw_deg: angle_distance(
            estimate.base_from_disc.yaw_rad,
            truth.base_from_disc.yaw_rad,
        )
        .to_degrees(),
        part_in_base_mm: part_in_base_mm(estimate, truth),
    })
}

/// Eq 1 for the part's position at conveyor angle `theta`.
fn part_base_at(result: &CalibrationResult, theta: f64) -> nalgebra::Vector3<f64> {
    let rotation = rotation_z(result.base_from_disc.yaw_rad + theta);
    rotation * from_array(result.part.position_m) + from_array(result.base_from_disc.translation_m)
}

/// Worst distance between the estimated and true part position in the base frame
/// over one revolution (72 angles), mm.
fn part_in_base_mm(estimate: &CalibrationResult, truth: &CalibrationResult) -> f64 {
    (0..72)
        .map(|step| {
            let theta = f64::from(step) * std::f64::consts::TAU / 72.0;
            (part_base_at(estimate, theta) - part_base_at(truth, theta)).norm() * MM_PER_M
        })
        .fold(0.0, f64::max)
}

impl fmt::Display for ErrorMetrics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (index, column) in METRIC_COLUMNS.iter().enumerate() {
            if index > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{} {:.4}", column.name, (column.value)(self))?;
        }
        Ok(())
    }
}
