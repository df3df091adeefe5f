//! A Rerun recording of a simulated pick (`host-sim run --rerun FILE.rrd`,
//! the `rerun` feature): what the cell does and what its camera sees, for
//! the Rerun viewer (`rerun FILE.rrd`, installed separately).
//!
//! - [`cell`]: the 3-D cell in the base frame from the world's truth: disc,
//!   arm, tool frame, gripper marks, camera frustum, the true part.
//! - [`camera`]: the camera's images with the vision computer's labels, and
//!   the labelled points the controller was sent.
//! - [`estimate`]: the controller's part estimate, its tool reference and
//!   phases from its telemetry, and the estimate's error against the truth.
//! - [`names`]: entity paths, timelines, label names, colours.
//!
//! A [`RerunView`] is a [`PickWatcher`]: it only looks. Everything is on two
//! timelines, `sim_time` (simulated seconds) and `frame` (the last camera
//! trigger). The truth is drawn, never sent anywhere.

pub mod camera;
pub mod cell;
pub mod estimate;
pub mod names;

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rerun::{RecordingStream, RecordingStreamBuilder};
use shared::protocol::{ActuatorCommand, CameraFeatureFrame, PickTelemetry};

use self::camera::{log_received, ImageLabeller};
use self::estimate::EstimateLog;
use crate::pick::watch::PickWatcher;
use crate::scenario::pick::{CameraSource, PickExperiment};
use crate::world::camera::PinholeCamera;
use crate::world::{World, WorldTruth};

/// The 3-D cell is logged this often, simulated seconds (the controller's
/// telemetry rate): a 1 kHz world logged every period would make the
/// recording twenty times larger for nothing the eye sees.
pub const SCENE_PERIOD_S: f64 = 0.02;

/// The recording's application id in the viewer.
pub const APPLICATION_ID: &str = "host-sim";

/// Where the recording of `experiment` goes when `experiments` are run
/// with `--rerun path`: `path` itself for one experiment, else one file each,
/// `<stem>-<experiment>.rrd` beside it.
pub fn recording_path(path: &Path, experiment: &str, experiments: usize) -> PathBuf {
    if experiments <= 1 {
        return path.to_path_buf();
    }
    let stem = path
        .file_stem()
        .map_or_else(|| "pick".into(), |s| s.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}-{experiment}.rrd"))
}

/// A pick's Rerun recording, written to a file as the run goes.
pub struct RerunView {
    rec: RecordingStream,
    path: PathBuf,
    /// The run renders images: draw them with their labels.
    images: Option<ImageLabeller>,
    estimate: EstimateLog,
    /// The fixed scene was logged.
    started: bool,
    /// The camera pose last logged (a bumped camera moves).
    camera: Option<PinholeCamera>,
    next_scene_s: f64,
    /// The last camera trigger.
    frame: Option<u32>,
}

impl RerunView {
    /// A recording of the pick of `experiment` on the workcell of `seed`,
    /// written to `path`.
    pub fn create(path: &Path, experiment: &PickExperiment, seed: u64) -> Result<Self> {
        let rec = RecordingStreamBuilder::new(APPLICATION_ID)
            .recording_name(format!("{} (seed {seed})", experiment.name))
            .default_enabled(true)
            .save(path)
            .with_context(|| format!("cannot create the Rerun recording {}", path.display()))?;
        let images = (experiment.camera.source == CameraSource::Images)
            .then(|| ImageLabeller::new(experiment, seed));
        Ok(Self {
            rec,
            path: path.to_path_buf(),
            images,
            estimate: EstimateLog::default(),
            started: false,
            camera: None,
            next_scene_s: 0.0,
            frame: None,
        })
    }

    /// Everything logged from now on is at `time_s` and the last frame.
    fn at(&self, time_s: f64) {
        self.rec.set_duration_secs(names::SIM_TIME, time_s);
        if let Some(frame) = self.frame {
            self.rec.set_time_sequence(names::FRAME, i64::from(frame));
        }
    }

    /// Writes what is still buffered; returns the file and its size, bytes.
    pub fn finish(self) -> Result<(PathBuf, u64)> {
        self.rec
            .flush_blocking()
            .with_context(|| format!("writing the Rerun recording {}", self.path.display()))?;
        self.rec.disconnect();
        let bytes = std::fs::metadata(&self.path)
            .with_context(|| format!("reading {}", self.path.display()))?
            .len();
        Ok((self.path, bytes))
    }
}

impl PickWatcher for RerunView {
    fn period(&mut self, world: &World, command: &ActuatorCommand) -> Result<()> {
        let now = world.time_s();
        if !self.started {
            self.started = true;
            cell::log_fixed(&self.rec, world)?;
        }
        if let Some(trigger_id) = command.camera_trigger {
            self.frame = Some(trigger_id);
            self.at(now);
            if let Some(images) = self.images.as_mut() {
                images.log_frame(&self.rec, world, trigger_id)?;
            }
        }
        if now + 1e-9 >= self.next_scene_s {
            self.next_scene_s = now + SCENE_PERIOD_S;
            self.at(now);
            let camera = world.camera().camera();
            if self.camera.as_ref() != Some(camera) {
                cell::log_camera(&self.rec, world, camera)?;
                self.camera = Some(camera.clone());
            }
            cell::log_moving(&self.rec, world, &world.truth())?;
        }
        Ok(())
    }

    fn frames_sent(&mut self, _world: &World, frames: &[CameraFeatureFrame]) -> Result<()> {
        for frame in frames {
            // At the frame's exposure, beside its image.
            self.rec
                .set_duration_secs(names::SIM_TIME, frame.capture_time_us as f64 * 1e-6);
            self.rec
                .set_time_sequence(names::FRAME, i64::from(frame.trigger_id));
            log_received(&self.rec, frame, self.images.is_none())?;
        }
        Ok(())
    }

    fn telemetry(&mut self, telemetry: &PickTelemetry, truth: &WorldTruth) -> Result<()> {
        self.at(truth.time_s);
        self.estimate.log(&self.rec, telemetry, truth)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn several_experiments_go_to_a_file_each_beside_the_one_named() {
        let path = Path::new("out/pick.rrd");
        assert_eq!(recording_path(path, "turning", 1), path);
        assert_eq!(
            recording_path(path, "turning", 5),
            Path::new("out/pick-turning.rrd")
        );
        assert_eq!(
            recording_path(Path::new("pick"), "experiment-1", 2),
            Path::new("pick-experiment-1.rrd")
        );
    }
}
