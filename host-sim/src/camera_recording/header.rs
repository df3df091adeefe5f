//! `recording.json` (docs/reference/recording.md): the camera with its lens,
//! the marks' sizes and polarities, L, the part's feature count and the
//! disc's radius. Unknown keys are ignored; every other fault names its key.

use serde_json::{json, Map, Value};
use shared::observation::{CameraIntrinsics, MAX_PART_FEATURES};

use super::error::RecordingError;

/// The contract's version.
pub const RECORDING_VERSION: u64 = 1;

/// Whether a mark is darker or brighter than what surrounds it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Polarity {
    Dark,
    Bright,
}

impl Polarity {
    fn name(self) -> &'static str {
        match self {
            Self::Dark => "dark",
            Self::Bright => "bright",
        }
    }
}

/// A round mark: its diameter and polarity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkSpec {
    pub diameter_m: f64,
    pub polarity: Polarity,
}

/// The recording's header.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingHeader {
    /// Pinhole intrinsics (the observation log's camera).
    pub camera: CameraIntrinsics,
    /// Radial distortion of normalised coordinates (absent: 0).
    pub k1: f64,
    pub k2: f64,
    pub reference_radius_m: f64,
    pub part_feature_count: usize,
    pub disc_center: MarkSpec,
    pub reference: MarkSpec,
    pub part_feature: MarkSpec,
    /// Part feature 0's mark when it differs from the others (`marks.part_key`,
    /// optional): the key from which the features are numbered, counter-
    /// clockwise seen from the camera's side of the disc.
    pub part_key: Option<MarkSpec>,
    /// The gripper's marks, two or more; mark `i` is columns `e{i}_base_*`.
    pub effector: Vec<MarkSpec>,
    pub disc_radius_m: f64,
}

struct Object<'a> {
    path: String,
    map: &'a Map<String, Value>,
}

impl<'a> Object<'a> {
    fn key(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_string()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    fn value(&self, key: &str) -> Result<&'a Value, RecordingError> {
        self.map
            .get(key)
            .ok_or_else(|| RecordingError::header(&self.key(key), "missing"))
    }

    fn object(&self, key: &str) -> Result<Object<'a>, RecordingError> {
        let map = self
            .value(key)?
            .as_object()
            .ok_or_else(|| RecordingError::header(&self.key(key), "not an object"))?;
        Ok(Object {
            path: self.key(key),
            map,
        })
    }

    fn number(&self, key: &str) -> Result<f64, RecordingError> {
        let value = self.value(key)?;
        let number = value.as_f64().ok_or_else(|| {
            RecordingError::header(&self.key(key), format!("not a number: {value}"))
        })?;
        if number.is_finite() {
            Ok(number)
        } else {
            Err(RecordingError::header(&self.key(key), "not finite"))
        }
    }

    fn optional_number(&self, key: &str) -> Result<f64, RecordingError> {
        if self.map.contains_key(key) {
            self.number(key)
        } else {
            Ok(0.0)
        }
    }

    fn positive(&self, key: &str) -> Result<f64, RecordingError> {
        let number = self.number(key)?;
        if number > 0.0 {
            Ok(number)
        } else {
            Err(RecordingError::header(
                &self.key(key),
                format!("must be positive, got {number}"),
            ))
        }
    }

    fn unsigned(&self, key: &str) -> Result<u64, RecordingError> {
        let value = self.value(key)?;
        value.as_u64().ok_or_else(|| {
            RecordingError::header(
                &self.key(key),
                format!("not a non-negative integer: {value}"),
            )
        })
    }

    fn mark(&self, key: &str) -> Result<MarkSpec, RecordingError> {
        mark_of(&self.object(key)?)
    }
}

fn mark_of(object: &Object<'_>) -> Result<MarkSpec, RecordingError> {
    let diameter_m = object.positive("diameter_m")?;
    let polarity = match object.value("polarity")?.as_str() {
        Some("dark") => Polarity::Dark,
        Some("bright") => Polarity::Bright,
        _ => {
            return Err(RecordingError::header(
                &object.key("polarity"),
                "must be \"dark\" or \"bright\"",
            ))
        }
    };
    Ok(MarkSpec {
        diameter_m,
        polarity,
    })
}

impl RecordingHeader {
    /// Decodes the header from the text of `recording.json`.
    pub fn parse(text: &str) -> Result<Self, RecordingError> {
        let value: Value = serde_json::from_str(text)
            .map_err(|e| RecordingError::header("(document)", format!("invalid JSON: {e}")))?;
        let map = value
            .as_object()
            .ok_or_else(|| RecordingError::header("(document)", "not a JSON object"))?;
        let root = Object {
            path: String::new(),
            map,
        };
        if root.value("type")?.as_str() != Some("recording") {
            return Err(RecordingError::header("type", "must be \"recording\""));
        }
        let version = root.unsigned("version")?;
        if version != RECORDING_VERSION {
            return Err(RecordingError::header(
                "version",
                format!("version {version} is not supported (only {RECORDING_VERSION})"),
            ));
        }
        let camera = root.object("camera")?;
        let side = |key: &str| -> Result<u32, RecordingError> {
            let side = camera.unsigned(key)?;
            u32::try_from(side)
                .ok()
                .filter(|&s| s > 0)
                .ok_or_else(|| RecordingError::header(&camera.key(key), "must be from 1 to 2^32-1"))
        };
        let intrinsics = CameraIntrinsics {
            width: side("width")?,
            height: side("height")?,
            f_px: camera.positive("f_px")?,
            cx: camera.number("cx")?,
            cy: camera.number("cy")?,
        };
        let k1 = camera.optional_number("k1")?;
        let k2 = camera.optional_number("k2")?;
        let part_feature_count = usize::try_from(root.unsigned("part_feature_count")?)
            .ok()
            .filter(|n| (2..=MAX_PART_FEATURES).contains(n))
            .ok_or_else(|| {
                RecordingError::header(
                    "part_feature_count",
                    "must be from 2 to 8 (MAX_PART_FEATURES)",
                )
            })?;
        let marks = root.object("marks")?;
        let effector_list = marks
            .value("effector")?
            .as_array()
            .ok_or_else(|| RecordingError::header("marks.effector", "not a list"))?;
        if effector_list.len() < 2 {
            return Err(RecordingError::header(
                "marks.effector",
                format!("needs two or more marks, got {}", effector_list.len()),
            ));
        }
        let mut effector = Vec::with_capacity(effector_list.len());
        for (i, mark) in effector_list.iter().enumerate() {
            let path = format!("marks.effector[{i}]");
            let map = mark
                .as_object()
                .ok_or_else(|| RecordingError::header(&path, "not an object"))?;
            effector.push(mark_of(&Object { path, map })?);
        }
        Ok(Self {
            camera: intrinsics,
            k1,
            k2,
            reference_radius_m: root.positive("reference_radius_m")?,
            part_feature_count,
            disc_center: marks.mark("disc_center")?,
            reference: marks.mark("reference")?,
            part_feature: marks.mark("part_feature")?,
            part_key: if marks.map.contains_key("part_key") {
                Some(marks.mark("part_key")?)
            } else {
                None
            },
            effector,
            disc_radius_m: root.positive("disc_radius_m")?,
        })
    }

    /// The header as the text of `recording.json` (one line).
    pub fn to_json(&self) -> String {
        let mark =
            |m: &MarkSpec| json!({"diameter_m": m.diameter_m, "polarity": m.polarity.name()});
        let mut value = json!({
            "type": "recording",
            "version": RECORDING_VERSION,
            "camera": {
                "width": self.camera.width, "height": self.camera.height,
                "f_px": self.camera.f_px, "cx": self.camera.cx, "cy": self.camera.cy,
                "k1": self.k1, "k2": self.k2,
            },
            "reference_radius_m": self.reference_radius_m,
            "part_feature_count": self.part_feature_count,
            "marks": {
                "disc_center": mark(&self.disc_center),
                "reference": mark(&self.reference),
                "part_feature": mark(&self.part_feature),
                "effector": self.effector.iter().map(mark).collect::<Vec<_>>(),
            },
            "disc_radius_m": self.disc_radius_m,
        });
        if let (Some(key), Some(marks)) = (&self.part_key, value.get_mut("marks")) {
            marks["part_key"] = mark(key);
        }
        value.to_string()
    }
}
