//! The simulator's runs as recordings: the pick of one seeded workcell with
//! the controller in process (as `host-sim vision-check` runs it), every
//! triggered frame rendered with the scenario's light, lens and noise and
//! written as a PNG with what a real cell latches at the trigger: the
//! encoder angle (quantised to the conveyor's counts, 0 at the first frame)
//! and the gripper marks' base-frame centres from the joint angles quantised
//! to the joint encoders' counts through the arm's kinematics.
//!
//! Beside the recording, for scoring only (a front end never reads them):
//! `truth.jsonl`, each frame's marks where they truly are, and
//! `ideal.jsonl`, the observation log of the same frames from the true
//! projections of the marks that are in view and unhidden.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{Context, Result};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use serde::{Deserialize, Serialize};
use shared::observation::{EffectorSighting, ObservationFrame, PixelPoint};

use super::{FrameRow, MarkSpec, Polarity, RecordingHeader, RecordingWriter};
use crate::link::{FramedLink, InProcessLink};
use crate::log::LogWriter;
use crate::pick::runner::run_pick_observed;
use crate::scenario::pick::PickExperiment;
use crate::vision_check::VIEW_MARGIN_PX;
use crate::world::render::scene::{MarkKind, MID};
use crate::world::render::truth::mark_images;
use crate::world::render::{build_scene, FrameState, GrayFrame, Renderer};
use crate::world::World;

/// The truth file's name.
pub const TRUTH_FILE: &str = "truth.jsonl";
/// The ideal labelled log's name.
pub const IDEAL_LOG_FILE: &str = "ideal.jsonl";

/// Points of the true rim kept to score its measurement.
const TRUE_RIM_POINTS: usize = 180;

/// One mark of one frame, where it truly is.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct TrueMark {
    /// `disc_center`, `reference`, `part_feature`, `effector` or `distractor`.
    pub kind: String,
    /// Feature, effector or distractor index (0 otherwise).
    pub index: usize,
    /// The projection of its centre through the lens, px (what a detector sees).
    pub image_px: [f64; 2],
    /// The same through the pinhole (the observation log's pixels), px.
    pub pinhole_px: [f64; 2],
    /// In view, facing the camera, unhidden and alone: a detector should find it.
    pub visible: bool,
    /// Something of it may show (facing, not wholly hidden).
    pub shows: bool,
}

/// One frame of the truth file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct TrueFrame {
    pub trigger_id: u64,
    pub marks: Vec<TrueMark>,
    /// Points of the disc's rim through the pinhole, px (to score the rim's
    /// measurement; not written to the truth file).
    #[serde(skip)]
    pub rim_pinhole_px: Vec<[f64; 2]>,
}

/// What was written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordedRun {
    pub frames: usize,
}

fn kind_name(kind: MarkKind) -> (&'static str, usize) {
    match kind {
        MarkKind::DiscCentre => ("disc_center", 0),
        MarkKind::Reference => ("reference", 0),
        MarkKind::Feature(i) => ("part_feature", usize::from(i)),
        MarkKind::Effector(i) => ("effector", usize::from(i)),
        MarkKind::Distractor(i) => ("distractor", usize::from(i)),
    }
}

fn quantise(x: f64, per_unit: f64) -> f64 {
    if per_unit > 0.0 {
        (x * per_unit).round() / per_unit
    } else {
        x
    }
}

/// The header of a recording of `world`'s camera with `renderer`'s lens.
fn header_of(world: &World, renderer: &Renderer) -> RecordingHeader {
    let settings = renderer.settings();
    let bright = |radius_m: f64| MarkSpec {
        diameter_m: 2.0 * radius_m,
        polarity: Polarity::Bright,
    };
    let workcell = world.workcell();
    RecordingHeader {
        camera: renderer.camera().pinhole.intrinsics,
        k1: renderer.camera().lens.k1,
        k2: renderer.camera().lens.k2,
        reference_radius_m: workcell.reference_radius_m,
        part_feature_count: workcell.features_rotating.len(),
        disc_center: bright(settings.centre_mark_radius_m),
        reference: bright(settings.reference_mark_radius_m),
        part_feature: bright(settings.feature_mark_radius_m),
        part_key: (settings.key_feature_mark_radius_m > 0.0)
            .then(|| bright(settings.key_feature_mark_radius_m)),
        effector: settings
            .effector_mark_radii_m
            .iter()
            .map(|&r| bright(r))
            .collect(),
        disc_radius_m: crate::world::dimensions::DISC_RADIUS_M,
    }
}

/// The gripper marks' base-frame centres from the joint encoders' counts.
fn effector_base_from_encoders(world: &World) -> Vec<[f64; 3]> {
    let counts_per_rad = world.cell_config().joint_counts_per_rad;
    let q = world.plant().state().q;
    let q_measured = shared::robot::JointVector::from_iterator(
        q.iter()
            .zip(counts_per_rad.iter())
            .map(|(&q, &c)| quantise(q, f64::from(c))),
    );
    let flange = world.plant().model().forward_kinematics(&q_measured);
    shared::app::tool::effector_marks_base(&flange)
        .iter()
        .map(|p| [p.x, p.y, p.z])
        .collect()
}

#[derive(Debug)]
struct EnoughFrames;

impl std::fmt::Display for EnoughFrames {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "enough frames recorded")
    }
}

impl std::error::Error for EnoughFrames {}

/// One simulated frame as a recording has it, with its truth and its ideal
/// labelled frame beside it.
pub struct SimulatedFrame<'a> {
    /// The recording's header (the same every frame).
    pub header: &'a RecordingHeader,
    /// The observation log's header of the workcell (for the ideal log).
    pub log_header: &'a shared::observation::LogHeader,
    /// What the cell latched at the trigger (`image` left empty).
    pub row: FrameRow,
    /// The 8-bit grey image, rows top to bottom.
    pub pixels: &'a [u8],
    /// Every mark where it truly is (scoring only).
    pub truth: TrueFrame,
    /// The observation log's frame from the true projections of the marks in view.
    pub ideal: ObservationFrame,
}

/// Renders the world's camera frame at a trigger as a recording has it: the
/// image through the lens with light and noise, what the cell latches (the
/// encoder angle, the gripper marks from the joint encoders), and beside them,
/// for scoring only, the truth and the ideal labelled frame. One per run: the
/// latched angle counts from the first frame it renders.
pub struct FrameRenderer {
    settings: crate::scenario::pick::ImageSettings,
    renderer: Option<Renderer>,
    headers: Option<(RecordingHeader, shared::observation::LogHeader)>,
    noise_rng: ChaCha8Rng,
    frame: GrayFrame,
    origin: Option<(f64, f64)>,
}

impl FrameRenderer {
    /// A renderer for the runs of `experiment` on the workcell of `seed`
    /// (the image noise is seeded from it).
    pub fn new(experiment: &PickExperiment, seed: u64) -> Self {
        Self {
            settings: experiment.image,
            renderer: None,
            headers: None,
            noise_rng: ChaCha8Rng::seed_from_u64(seed ^ 0x7ec0_4d1e),
            frame: GrayFrame {
                width: 0,
                height: 0,
                pixels: Vec::new(),
            },
            origin: None,
        }
    }

    /// Frame `trigger_id`, exposed now (centred on the world's instant).
    pub fn render(&mut self, world: &World, trigger_id: u64) -> Result<SimulatedFrame<'_>> {
        let settings = self.settings;
        let exposure_s = settings.exposure_ms / 1000.0;
        let camera = world.camera().camera();
        let renderer = Renderer::ready(&mut self.renderer, camera, &settings)?;
        let scene = build_scene(
            world.workcell(),
            &FrameState::from_world(world, exposure_s),
            &settings,
        );
        renderer.render(&scene);
        let marks = mark_images(renderer, &scene, VIEW_MARGIN_PX);
        renderer.expose(scene.time_s, false, &mut self.noise_rng, &mut self.frame);

        let counts_per_rev = f64::from(world.conveyor().counts_per_rev());
        let theta = quantise(
            world.conveyor().theta(scene.time_s),
            counts_per_rev / std::f64::consts::TAU,
        );
        let (t0, theta0) = *self.origin.get_or_insert((scene.time_s, theta));
        let row = FrameRow {
            line: 0,
            trigger_id,
            capture_time_us: ((scene.time_s - t0) * 1e6).round().max(0.0) as u64,
            conveyor_angle_rad: theta - theta0,
            image: String::new(),
            effector_base_m: effector_base_from_encoders(world),
        };
        let (header, log_header) = self
            .headers
            .get_or_insert_with(|| (header_of(world, renderer), world.workcell().header()));

        // The truth and the ideal labelled frame.
        let pinhole = &renderer.camera().pinhole;
        let mut true_marks = Vec::new();
        let mut ideal = ObservationFrame {
            t_s: row.capture_time_us as f64 * 1e-6,
            conveyor_angle_rad: row.conveyor_angle_rad,
            center_px: None,
            reference_px: None,
            part_px: None,
            effector: None,
            rim: None,
        };
        let mut part: Vec<Option<PixelPoint>> =
            vec![None; world.workcell().features_rotating.len()];
        let mut effector: [Option<PixelPoint>; 2] = [None; 2];
        for (image, mark) in marks.iter().zip(&scene.marks) {
            let (kind, index) = kind_name(image.kind);
            let pinhole_px = pinhole
                .project(&mark.centre_disc[MID])
                .unwrap_or([f64::NAN, f64::NAN]);
            true_marks.push(TrueMark {
                kind: kind.to_string(),
                index,
                image_px: image.centre_px,
                pinhole_px,
                visible: image.visible(),
                shows: image.shows(),
            });
            let inside = pinhole_px.iter().all(|x| x.is_finite())
                && world.workcell().camera.intrinsics.contains(pinhole_px);
            if !image.visible() || !inside {
                continue;
            }
            match image.kind {
                MarkKind::DiscCentre => ideal.center_px = Some(pinhole_px),
                MarkKind::Reference => ideal.reference_px = Some(pinhole_px),
                MarkKind::Feature(i) => {
                    if let Some(slot) = part.get_mut(usize::from(i)) {
                        *slot = Some(pinhole_px);
                    }
                }
                MarkKind::Effector(i) => {
                    if let Some(slot) = effector.get_mut(usize::from(i)) {
                        *slot = Some(pinhole_px);
                    }
                }
                MarkKind::Distractor(_) => {}
            }
        }
        if part.iter().all(Option::is_some) {
            ideal.part_px = Some(part.iter().flatten().copied().collect());
        }
        if let ([Some(a), Some(b)], [pa, pb]) = (effector, row.effector_base_m.as_slice()) {
            ideal.effector = Some(EffectorSighting {
                px: [a, b],
                base_m: [*pa, *pb],
            });
        }
        Ok(SimulatedFrame {
            header,
            log_header,
            row,
            pixels: &self.frame.pixels,
            truth: TrueFrame {
                trigger_id,
                marks: true_marks,
                rim_pinhole_px: (0..TRUE_RIM_POINTS)
                    .filter_map(|k| {
                        let phi = std::f64::consts::TAU * k as f64 / TRUE_RIM_POINTS as f64;
                        let r = scene.disc_radius_m;
                        pinhole.project(&nalgebra::Vector3::new(r * phi.cos(), r * phi.sin(), 0.0))
                    })
                    .collect(),
            },
            ideal,
        })
    }
}

/// Runs the pick of `experiment` on the workcell of `seed` and hands each
/// rendered frame (at most `max_frames`, every `stride`-th trigger) to
/// `sink`, in order: what [`record_pick`] writes and what
/// `host-sim vision-campaign` feeds to the front end without a disk.
pub fn simulate_pick(
    experiment: &PickExperiment,
    seed: u64,
    max_frames: usize,
    stride: usize,
    sink: &mut dyn FnMut(SimulatedFrame<'_>) -> Result<()>,
) -> Result<RecordedRun> {
    let mut renderer = FrameRenderer::new(experiment, seed);
    let mut triggers = 0usize;
    let mut frames = 0usize;
    let mut link = FramedLink::new(InProcessLink::new());
    let mut observe = |world: &World, command: &shared::protocol::ActuatorCommand| -> Result<()> {
        if command.camera_trigger.is_none() {
            return Ok(());
        }
        triggers += 1;
        if stride > 1 && !(triggers - 1).is_multiple_of(stride) {
            return Ok(());
        }
        if frames >= max_frames {
            return Err(EnoughFrames.into());
        }
        sink(renderer.render(world, triggers as u64 - 1)?)?;
        frames += 1;
        Ok(())
    };
    match run_pick_observed(experiment, seed, &mut link, &mut observe) {
        Ok(_) => {}
        Err(e) if e.downcast_ref::<EnoughFrames>().is_some() => {}
        Err(e) => return Err(e.context(format!("the pick of seed {seed}"))),
    }
    Ok(RecordedRun { frames })
}

/// Records the pick of `experiment` on the workcell of `seed` into `folder`:
/// at most `max_frames` frames (every `stride`-th trigger), with the truth
/// file and the ideal log beside them.
pub fn record_pick(
    experiment: &PickExperiment,
    seed: u64,
    folder: &Path,
    max_frames: usize,
    stride: usize,
) -> Result<RecordedRun> {
    let mut writer: Option<(RecordingWriter, LogWriter<BufWriter<File>>)> = None;
    let mut truth = BufWriter::new(File::create(folder.join(TRUTH_FILE)).or_else(|_| {
        std::fs::create_dir_all(folder)?;
        File::create(folder.join(TRUTH_FILE))
    })?);
    let mut sink = |frame: SimulatedFrame<'_>| -> Result<()> {
        if writer.is_none() {
            let recording = RecordingWriter::create(folder, frame.header)?;
            let log_path = folder.join(IDEAL_LOG_FILE);
            let log = LogWriter::new(
                BufWriter::new(
                    File::create(&log_path).with_context(|| log_path.display().to_string())?,
                ),
                frame.log_header,
            )?;
            writer = Some((recording, log));
        }
        let Some((recording, log)) = writer.as_mut() else {
            return Ok(());
        };
        log.write_frame(&frame.ideal)?;
        serde_json::to_writer(&mut truth, &frame.truth)?;
        truth.write_all(b"\n")?;
        recording.push(frame.row, frame.pixels)?;
        Ok(())
    };
    let recorded = simulate_pick(experiment, seed, max_frames, stride, &mut sink)?;
    if let Some((recording, log)) = writer {
        recording.finish()?;
        log.finish()?;
    }
    truth.flush()?;
    Ok(recorded)
}

/// Reads `truth.jsonl`.
pub fn read_truth(folder: &Path) -> Result<Vec<TrueFrame>> {
    let path = folder.join(TRUTH_FILE);
    let text = std::fs::read_to_string(&path).with_context(|| path.display().to_string())?;
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .enumerate()
        .map(|(i, l)| {
            serde_json::from_str(l).with_context(|| format!("{} line {}", path.display(), i + 1))
        })
        .collect()
}
