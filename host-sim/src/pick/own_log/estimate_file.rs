//! The controller's final calibration estimate (`controller_estimate.json`):
//! the contract's calibration result at the top level (so the file reads as
//! one, e.g. as `host-sim calibrate --truth`), its one-sigma uncertainties,
//! and where it came from: the calibrator, its configuration, how many of the
//! log's frames it was made from, and whether the controller's own estimate
//! of that job matched it in every field it carries.

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Serialize};
use shared::calibration::{CalibrationConfig, EstimateUncertainty};
use shared::observation::CalibrationResult;

/// Which calibrator the controller runs, for the file's readers.
pub const PICK_CALIBRATOR_NAME: &str =
    "shared::app::pick::PickCalibrator (SelfCalibrator<256, 128, 5>)";

/// Where the estimate came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EstimateProvenance {
    pub experiment: String,
    pub seed: u64,
    /// The calibrator's type ([`PICK_CALIBRATOR_NAME`]).
    pub calibrator: String,
    /// Its configuration, as the controller built it from the cell's.
    pub config: CalibrationConfig,
    /// The estimate was made from the log's first `log_frames` frames
    /// (`host-sim calibrate --frames`); the log goes on to the grasp.
    pub log_frames: usize,
    /// Of those, the frames the calibrator refused (passed over).
    pub frames_refused: usize,
    /// Where the controller adopted its earlier estimates, in the log's
    /// frames: after this many, its calibrator folded what it had no room for
    /// at that estimate (`host-sim calibrate --adopt-after-frames`).
    #[serde(default)]
    pub adopted_after_frames: Vec<usize>,
    /// Frames the worker was given that the log writer refused (not in the
    /// log; 0 unless a frame breaks the contract).
    pub frames_not_logged: usize,
    /// The controller's time of the estimate's request, microseconds.
    pub time_us: u64,
    /// `accepted`, or why the controller refused the estimate.
    pub outcome: String,
    /// The controller's own estimate of the job (its f32 and f64 fields)
    /// equals this result's; `None` when it refused it.
    pub matches_controller: Option<bool>,
}

/// The file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControllerEstimateFile {
    #[serde(flatten)]
    pub result: CalibrationResult,
    pub uncertainty_1sigma: EstimateUncertainty,
    pub controller: EstimateProvenance,
}

pub fn write_estimate_file(path: &Path, file: &ControllerEstimateFile) -> anyhow::Result<()> {
    let out = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut writer = BufWriter::new(out);
    serde_json::to_writer_pretty(&mut writer, file)
        .with_context(|| format!("writing {}", path.display()))?;
    writer
        .write_all(b"\n")
        .and_then(|()| writer.flush())
        .with_context(|| format!("writing {}", path.display()))
}

pub fn read_estimate_file(path: &Path) -> anyhow::Result<ControllerEstimateFile> {
    let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    serde_json::from_reader(BufReader::new(file))
        .with_context(|| format!("{} is not a controller estimate file", path.display()))
}
