//! The cell configuration, checked once when it arrives: every later step may
//! rely on it (positive scales, a known counter width, a feature count the
//! calibrator accepts).

use nalgebra::Vector3;

use crate::calibration::CalibrationConfig;
use crate::fusion::CounterWidth;
use crate::observation::{CameraIntrinsics, LogHeader, LOG_VERSION, MAX_PART_FEATURES};
use crate::protocol::CellConfig;

/// A configuration value out of range; `field` names it as in [`CellConfig`]
/// and `reason` says why.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConfigError {
    /// The [`CellConfig`] field out of range.
    pub field: &'static str,
    /// Why it is refused.
    pub reason: &'static str,
}

impl ConfigError {
    /// `field` refused because of `reason`.
    pub const fn new(field: &'static str, reason: &'static str) -> Self {
        Self { field, reason }
    }
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "cell configuration: {} {}", self.field, self.reason)
    }
}

impl core::error::Error for ConfigError {}

/// A [`CellConfig`] that passed its checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// The configuration as given.
    pub config: CellConfig,
    /// The conveyor counter's width.
    pub counter_width: CounterWidth,
    /// The drop-off's grasp point, base frame.
    pub drop_off_base: Vector3<f32>,
}

fn check(ok: bool, field: &'static str) -> Result<(), ConfigError> {
    if ok {
        Ok(())
    } else {
        Err(ConfigError::new(field, "is out of range"))
    }
}

fn positive(x: f32) -> bool {
    x.is_finite() && x > 0.0
}

impl Cell {
    /// Checks `config`.
    pub fn new(config: &CellConfig) -> Result<Self, ConfigError> {
        check(config.image_width_px > 0, "image_width_px")?;
        check(config.image_height_px > 0, "image_height_px")?;
        check(positive(config.f_px), "f_px")?;
        check(config.cx_px.is_finite(), "cx_px")?;
        check(config.cy_px.is_finite(), "cy_px")?;
        check(positive(config.reference_radius_m), "reference_radius_m")?;
        if let Some(radius) = config.disc_radius_m {
            check(positive(radius), "disc_radius_m")?;
        }
        check(
            (2..=MAX_PART_FEATURES).contains(&usize::from(config.part_feature_count)),
            "part_feature_count",
        )?;
        check(
            config.conveyor_counts_per_rev > 0,
            "conveyor_counts_per_rev",
        )?;
        let counter_width = match config.conveyor_counter_bits {
            16 => CounterWidth::Bits16,
            32 => CounterWidth::Bits32,
            _ => {
                return Err(ConfigError::new(
                    "conveyor_counter_bits",
                    "is neither 16 nor 32",
                ))
            }
        };
        check(
            config.joint_counts_per_rad.iter().all(|c| positive(*c)),
            "joint_counts_per_rad",
        )?;
        check(
            config.disc_height_in_base_m.is_none_or(f32::is_finite),
            "disc_height_in_base_m",
        )?;
        check(
            config.drop_off_base_m.iter().all(|x| x.is_finite()),
            "drop_off_base_m",
        )?;
        check(config.camera_period_ms > 0, "camera_period_ms")?;
        check(
            config.grasp_capture_m.iter().all(|x| positive(*x)),
            "grasp_capture_m",
        )?;
        check(
            positive(config.grasp_capture_yaw_rad),
            "grasp_capture_yaw_rad",
        )?;
        let [x, y, z] = config.drop_off_base_m;
        Ok(Self {
            config: *config,
            counter_width,
            drop_off_base: Vector3::new(x, y, z),
        })
    }

    /// The log header the calibrator is built on.
    pub fn log_header(&self) -> LogHeader {
        let c = &self.config;
        LogHeader {
            version: LOG_VERSION,
            camera: CameraIntrinsics {
                width: u32::from(c.image_width_px),
                height: u32::from(c.image_height_px),
                f_px: f64::from(c.f_px),
                cx: f64::from(c.cx_px),
                cy: f64::from(c.cy_px),
            },
            reference_radius_m: f64::from(c.reference_radius_m),
            part_feature_count: usize::from(c.part_feature_count),
            disc_radius_m: c.disc_radius_m.map(f64::from),
        }
    }

    /// The calibrator's configuration for this cell.
    pub fn calibration_config(&self) -> CalibrationConfig {
        CalibrationConfig {
            disc_height_in_base_m: self.config.disc_height_in_base_m.map(f64::from),
            ..CalibrationConfig::default()
        }
    }

    /// Joint angles from encoder counts (0 counts at q = 0; a count stands for
    /// the middle of its interval).
    pub fn joint_angles(&self, counts: &[i32; 6]) -> crate::robot::JointVector<f32> {
        crate::robot::JointVector::from_fn(|i, _| {
            let count = counts.get(i).copied().unwrap_or(0);
            let per_rad = self
                .config
                .joint_counts_per_rad
                .get(i)
                .copied()
                .unwrap_or(1.0);
            (count as f32 + 0.5) / per_rad
        })
    }
}
