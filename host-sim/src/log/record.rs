//! Decoding of the two record kinds of a version-1 log (header, frame) from one
//! parsed JSON line, validating every rule of the contract `frames-and-log.md`.

use serde_json::Value;
use shared::observation::{
    CameraIntrinsics, EffectorSighting, LogHeader, ObservationFrame, PixelPoint, Point3,
    RimObservation, EFFECTOR_POINTS, LOG_VERSION, MAX_PART_FEATURES,
};

use super::error::{describe_value, LogError, LogProblem};
use super::fields::{self, Record};

fn expect_record_type(record: &Record<'_>, expected: &'static str) -> Result<(), LogError> {
    let record_type = record.required("type", "type")?;
    match record_type.as_str() {
        Some(name) if name == expected => Ok(()),
        Some(_) => Err(LogError::at_field(
            record.line,
            "type",
            LogProblem::WrongRecordType {
                expected,
                got: describe_value(record_type),
            },
        )),
        None => Err(record.wrong_type("type", "a string", record_type)),
    }
}

/// Line 1: the header.
pub fn parse_header(line: usize, value: &Value) -> Result<LogHeader, LogError> {
    let record = Record::from_value(line, value)?;
    expect_record_type(&record, "header")?;

    let version_value = record.required("version", "version")?;
    let version = record.unsigned("version", "version")?;
    if version != u64::from(LOG_VERSION) {
        return Err(LogError::at_field(
            line,
            "version",
            LogProblem::UnsupportedVersion {
                got: describe_value(version_value),
            },
        ));
    }

    let camera_record = record.object("camera", "camera")?;
    let image_side = |key: &str, path: &str| -> Result<u32, LogError> {
        let side = camera_record.unsigned(key, path)?;
        match u32::try_from(side) {
            Ok(side) if side > 0 => Ok(side),
            _ => Err(LogError::at_field(
                line,
                path,
                LogProblem::OutOfRange {
                    expected: "an image size in pixels between 1 and 4294967295",
                    got: side.to_string(),
                },
            )),
        }
    };
    let camera = CameraIntrinsics {
        width: image_side("width", "camera.width")?,
        height: image_side("height", "camera.height")?,
        f_px: camera_record.positive("f_px", "camera.f_px")?,
        cx: camera_record.finite("cx", "camera.cx")?,
        cy: camera_record.finite("cy", "camera.cy")?,
    };

    let reference_radius_m = record.positive("reference_radius_m", "reference_radius_m")?;

    let feature_count = record.unsigned("part_feature_count", "part_feature_count")?;
    let part_feature_count = usize::try_from(feature_count)
        .ok()
        .filter(|count| (2..=MAX_PART_FEATURES).contains(count))
        .ok_or_else(|| {
            LogError::at_field(
                line,
                "part_feature_count",
                LogProblem::OutOfRange {
                    expected: "an integer from 2 to 8 (MAX_PART_FEATURES)",
                    got: feature_count.to_string(),
                },
            )
        })?;

    // This project's addition: optional, positive where given.
    let disc_radius_m = match record.object.get("disc_radius_m") {
        None | Some(Value::Null) => None,
        Some(_) => Some(record.positive("disc_radius_m", "disc_radius_m")?),
    };

    Ok(LogHeader {
        version: LOG_VERSION,
        camera,
        reference_radius_m,
        part_feature_count,
        disc_radius_m,
    })
}

/// A frame line. `previous_t_s` is the last accepted frame's time (for the ordering rule).
pub fn parse_frame(
    line: usize,
    value: &Value,
    header: &LogHeader,
    previous_t_s: Option<f64>,
) -> Result<ObservationFrame, LogError> {
    let record = Record::from_value(line, value)?;
    expect_record_type(&record, "frame")?;

    let t_s = record.finite("t_s", "t_s")?;
    if let Some(previous_t_s) = previous_t_s {
        if t_s < previous_t_s {
            return Err(LogError::at_field(
                line,
                "t_s",
                LogProblem::TimeWentBackwards { t_s, previous_t_s },
            ));
        }
    }
    let conveyor_angle_rad = record.finite("conveyor_angle_rad", "conveyor_angle_rad")?;
    let center_px = fields::optional_pixel(
        line,
        "center_px",
        record.required("center_px", "center_px")?,
    )?;
    let reference_px = fields::optional_pixel(
        line,
        "reference_px",
        record.required("reference_px", "reference_px")?,
    )?;
    let part_px = parse_part(&record, header.part_feature_count)?;
    let effector = parse_effector(&record)?;
    let rim = parse_rim(&record)?;

    Ok(ObservationFrame {
        t_s,
        conveyor_angle_rad,
        center_px,
        reference_px,
        part_px,
        effector,
        rim,
    })
}

/// The optional `rim` (this project's addition): an object of the ellipse's
/// centre, semi-axes (positive), angle and sigma (positive).
fn parse_rim(record: &Record<'_>) -> Result<Option<RimObservation>, LogError> {
    match record.object.get("rim") {
        None | Some(Value::Null) => return Ok(None),
        Some(_) => {}
    }
    let line = record.line;
    let rim = record.object("rim", "rim")?;
    let centre_px = fields::pixel(
        line,
        "rim.centre_px",
        rim.required("centre_px", "rim.centre_px")?,
    )?;
    let semi_axes_px = fields::pixel(
        line,
        "rim.semi_axes_px",
        rim.required("semi_axes_px", "rim.semi_axes_px")?,
    )?;
    if !semi_axes_px.iter().all(|&a| a > 0.0) {
        return Err(LogError::at_field(
            line,
            "rim.semi_axes_px",
            LogProblem::OutOfRange {
                expected: "two semi-axes greater than 0",
                got: format!("{semi_axes_px:?}"),
            },
        ));
    }
    Ok(Some(RimObservation {
        centre_px,
        semi_axes_px,
        angle_rad: rim.finite("angle_rad", "rim.angle_rad")?,
        sigma_px: rim.positive("sigma_px", "rim.sigma_px")?,
    }))
}

/// Checks the length of a JSON array before its items are decoded (so a huge
/// array costs nothing beyond its parse).
fn check_count(line: usize, path: &str, value: &Value, expected: usize) -> Result<(), LogError> {
    match value.as_array() {
        Some(items) if items.len() != expected => Err(LogError::at_field(
            line,
            path,
            LogProblem::FeatureCount {
                expected,
                got: items.len(),
            },
        )),
        _ => Ok(()),
    }
}

fn parse_part(
    record: &Record<'_>,
    feature_count: usize,
) -> Result<Option<heapless::Vec<PixelPoint, MAX_PART_FEATURES>>, LogError> {
    let line = record.line;
    let value = record.required("part_px", "part_px")?;
    check_count(line, "part_px", value, feature_count)?;
    let points = fields::optional_list(
        line,
        "part_px",
        value,
        "null or a list of [u, v] points",
        |path, item| fields::pixel(line, path, item),
    )?;
    points
        .map(|points| {
            heapless::Vec::from_slice(&points).map_err(|_| {
                LogError::at_field(
                    line,
                    "part_px",
                    LogProblem::FeatureCount {
                        expected: feature_count,
                        got: points.len(),
                    },
                )
            })
        })
        .transpose()
}

/// Converts a list already checked to hold [`EFFECTOR_POINTS`] items into an array.
fn effector_array<T: Copy>(
    line: usize,
    path: &str,
    items: Vec<T>,
) -> Result<[T; EFFECTOR_POINTS], LogError> {
    let count = items.len();
    <[T; EFFECTOR_POINTS]>::try_from(items).map_err(|_| {
        LogError::at_field(
            line,
            path,
            LogProblem::FeatureCount {
                expected: EFFECTOR_POINTS,
                got: count,
            },
        )
    })
}

fn parse_effector(record: &Record<'_>) -> Result<Option<EffectorSighting>, LogError> {
    let line = record.line;
    let px_value = record.required("effector_px", "effector_px")?;
    let base_value = record.required("effector_base_m", "effector_base_m")?;
    check_count(line, "effector_px", px_value, EFFECTOR_POINTS)?;
    check_count(line, "effector_base_m", base_value, EFFECTOR_POINTS)?;
    let px = fields::optional_list(
        line,
        "effector_px",
        px_value,
        "null or a list of 2 [u, v] points",
        |path, item| fields::pixel(line, path, item),
    )?;
    let base_m: Option<Vec<Point3>> = fields::optional_list(
        line,
        "effector_base_m",
        base_value,
        "null or a list of 2 [x, y, z] points",
        |path, item| fields::point3(line, path, item),
    )?;
    match (px, base_m) {
        (None, None) => Ok(None),
        (Some(px), Some(base_m)) => Ok(Some(EffectorSighting {
            px: effector_array(line, "effector_px", px)?,
            base_m: effector_array(line, "effector_base_m", base_m)?,
        })),
        (px, base_m) => Err(LogError::at_field(
            line,
            if px.is_some() {
                "effector_base_m"
            } else {
                "effector_px"
            },
            LogProblem::EffectorPairing {
                px_present: px.is_some(),
                base_present: base_m.is_some(),
            },
        )),
    }
}
