//! The ground-truth file written beside a synthetic log (`LOG.truth.json`): the
//! true values in the calibration-result format of the contract, plus the seed,
//! the scenario and the drawn workcell's parameters. Because the result's keys
//! sit at the top level, a truth file also reads as a calibration result.

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use shared::observation::CalibrationResult;

use crate::scenario::recording::Scenario;
use crate::world::generator::WorkcellParameters;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthFile {
    /// The true camera pose, part, and base pose; `quality` describes the log as
    /// recorded (frames with a detection, RMS of the injected inlier noise,
    /// effector frames, injected outliers).
    #[serde(flatten)]
    pub result: CalibrationResult,
    pub seed: u64,
    pub scenario: Scenario,
    pub workcell: WorkcellParameters,
}

/// `run.jsonl` -> `run.truth.json`, beside the log.
pub fn truth_path_for(log_path: &Path) -> PathBuf {
    log_path.with_extension("truth.json")
}

pub fn write_truth_file(path: &Path, truth: &TruthFile) -> anyhow::Result<()> {
    write_truth_file_of(path, truth)
}

/// Writes any truth whose calibration result sits at the top level (the
/// pick's own log's too: `crate::pick::own_log::truth`).
pub fn write_truth_file_of<T: Serialize>(path: &Path, truth: &T) -> anyhow::Result<()> {
    let file = File::create(path)
        .with_context(|| format!("cannot create truth file {}", path.display()))?;
    let mut writer = BufWriter::new(file);
    serde_json::to_writer_pretty(&mut writer, truth)
        .with_context(|| format!("writing truth file {}", path.display()))?;
    writer
        .write_all(b"\n")
        .and_then(|()| writer.flush())
        .with_context(|| format!("writing truth file {}", path.display()))
}

pub fn read_truth_file(path: &Path) -> anyhow::Result<TruthFile> {
    let file =
        File::open(path).with_context(|| format!("cannot open truth file {}", path.display()))?;
    serde_json::from_reader(BufReader::new(file))
        .with_context(|| format!("truth file {} is not a valid truth file", path.display()))
}

/// The calibration result of any truth file (this module's, the pick's own
/// log's) or of anything else whose result sits at the top level (a
/// `controller_estimate.json`): other keys are ignored.
pub fn read_truth_result(path: &Path) -> anyhow::Result<CalibrationResult> {
    #[derive(Deserialize)]
    struct TopLevel {
        #[serde(flatten)]
        result: CalibrationResult,
    }
    let file =
        File::open(path).with_context(|| format!("cannot open truth file {}", path.display()))?;
    serde_json::from_reader::<_, TopLevel>(BufReader::new(file))
        .map(|top| top.result)
        .with_context(|| {
            format!(
                "{} holds no calibration result at its top level",
                path.display()
            )
        })
}
