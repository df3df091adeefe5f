//! `host-sim vision-live`: grabs frames from a V4L2 camera (built with the
//! `v4l2` feature) into a recording folder (see [`crate::live_camera`]);
//! with a latches CSV the folder is a complete recording, and with `--log`
//! the front end runs on it at once.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::camera_recording::{Recording, RecordingHeader};
use crate::live_camera::latches::parse_latches;
use crate::live_camera::{check_latch_count, LiveRecording, CAPTURES_FILE};

/// Options of `host-sim vision-live`.
#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The V4L2 capture device.
    #[arg(long, default_value = "/dev/video0")]
    pub device: PathBuf,
    /// A recording header (recording.json): the camera's size, intrinsics
    /// and lens, the marks' sizes; a camera cannot tell them.
    #[arg(long)]
    pub header: PathBuf,
    /// The folder to write (images/, captures.csv, recording.json, and
    /// frames.csv with --latches).
    #[arg(long)]
    pub out: PathBuf,
    /// Frames to grab.
    #[arg(long, default_value_t = 100)]
    pub frames: usize,
    /// The encoder values latched at each trigger, one row a trigger in
    /// order (conveyor_angle_rad, e{i}_base_{x,y,z}_m; optional trigger_id,
    /// capture_time_us).
    #[arg(long)]
    pub latches: Option<PathBuf>,
    /// Run the front end on the recording and write its observation log
    /// here (needs --latches).
    #[arg(long, requires = "latches")]
    pub log: Option<PathBuf>,
}

/// Opens the camera, then creates the folder and fills it.
#[cfg(feature = "v4l2")]
fn grab_into(args: &Args, header: &RecordingHeader) -> Result<LiveRecording> {
    let camera = &header.camera;
    let mut device =
        crate::live_camera::device::Camera::open(&args.device, camera.width, camera.height)?;
    eprintln!(
        "{}: {} x {} {:?}",
        args.device.display(),
        camera.width,
        camera.height,
        device.layout()
    );
    let mut live = LiveRecording::create(&args.out, header)?;
    let mut grey = Vec::new();
    for k in 0..args.frames {
        let t_us = device
            .grab(&mut grey)
            .with_context(|| format!("frame {k}"))?;
        live.push(t_us, &grey)?;
    }
    Ok(live)
}

#[cfg(not(feature = "v4l2"))]
fn grab_into(_: &Args, _: &RecordingHeader) -> Result<LiveRecording> {
    anyhow::bail!(
        "this host-sim is built without a camera: build it with \
         `cargo build --release -p host-sim --features v4l2`"
    )
}

pub fn run(args: &Args) -> Result<()> {
    let text = std::fs::read_to_string(&args.header)
        .with_context(|| format!("cannot read {}", args.header.display()))?;
    let header = RecordingHeader::parse(&text)
        .with_context(|| format!("header {}", args.header.display()))?;
    // The latches are read first: a bad file is refused before the camera runs.
    let latches = match &args.latches {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            let latches = parse_latches(&text, header.effector.len())
                .with_context(|| path.display().to_string())?;
            check_latch_count(&latches, args.frames)?;
            Some(latches)
        }
        None => None,
    };
    let live = grab_into(args, &header)?;
    let written = live.finish(latches.as_deref())?;
    if !written.complete {
        eprintln!(
            "{} frames in {} with {CAPTURES_FILE}; not yet a recording: frames.csv needs the \
             encoder values latched at each trigger (conveyor_angle_rad, e{{i}}_base_{{x,y,z}}_m; \
             docs/reference/recording.md), which a camera cannot give: pass them with --latches",
            written.frames,
            args.out.display()
        );
        return Ok(());
    }
    eprintln!(
        "{} frames: a recording in {}",
        written.frames,
        args.out.display()
    );
    if let Some(log) = &args.log {
        let recording = Recording::open(&args.out)?;
        let outcome = crate::front_end::run(&recording, false)?;
        crate::log::write_log_file(log, &outcome.log)?;
        eprintln!("observation log: {}", log.display());
    }
    Ok(())
}
