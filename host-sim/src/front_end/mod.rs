//! The offline vision front end: a camera recording in, the observation log
//! that `host-sim calibrate` reads out. Each frame is detected
//! (`shared::detection::Detector`), its blobs labelled
//! (`shared::detection::identify`) from the encoder angle, the marks' sizes
//! and the gripper's base-frame marks latched with it, and the labelled
//! points written undistorted (the log's camera is a pinhole).
//!
//! [`score`] compares the labels with a simulated recording's truth file;
//! the front end itself never reads it. With `FRONT_END_DEBUG` set in the
//! environment, each frame's tracks and labels are printed to stderr.

pub mod campaign;
pub mod pictures;
pub mod score;

use anyhow::{Context, Result};
use heapless::Vec as HVec;
use shared::detection::identify::lens::LensModel;
use shared::detection::identify::{
    Identifier, IdentifySettings, LabelledPoint, MarkDiameters, MarkLabel, MAX_LABELS,
};
use shared::detection::rim::{RimFinder, RimFit, RimSettings};
use shared::detection::{Blob, Detector, DetectorSettings, GrayImage, MAX_BLOBS};
use shared::observation::{
    EffectorSighting, LogHeader, ObservationFrame, RimObservation, LOG_VERSION,
};

use crate::camera_recording::{FrameRow, Polarity, Recording, RecordingHeader};
use crate::log::ObservationLog;

/// Gate around a track's predicted position, px.
pub const TRACK_GATE_PX: f64 = 2.0;

/// One frame's labels.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameLabels {
    pub trigger_id: u64,
    /// The frame's detections (a point's `blob` indexes them).
    pub blobs: Vec<Blob>,
    pub points: Vec<LabelledPoint>,
    /// The disc's rim measured in this frame (undistorted px), if it was.
    pub rim: Option<RimFit>,
}

/// What a front end run gave.
#[derive(Debug, Clone)]
pub struct FrontEndRun {
    pub log: ObservationLog,
    pub frames: Vec<FrameLabels>,
    /// Frames whose image was bad and skipped.
    pub skipped_images: usize,
    /// Frames the detector refused (too many blobs at once).
    pub refused_frames: usize,
    /// Blobs left unlabelled as ambiguous (summed over frames).
    pub ambiguous: u64,
}

/// The identification settings a recording's header gives.
pub fn identify_settings(header: &RecordingHeader) -> Result<IdentifySettings> {
    let bright = [
        ("marks.disc_center", header.disc_center.polarity),
        ("marks.reference", header.reference.polarity),
        ("marks.part_feature", header.part_feature.polarity),
        (
            "marks.part_key",
            header.part_key.map_or(Polarity::Bright, |m| m.polarity),
        ),
    ]
    .into_iter()
    .chain(
        header
            .effector
            .iter()
            .map(|m| ("marks.effector", m.polarity)),
    );
    for (key, polarity) in bright {
        if polarity != Polarity::Bright {
            anyhow::bail!(
                "{key}: the detector finds bright marks only; a dark mark needs an inverted image (not supported yet)"
            );
        }
    }
    if header.effector.len() != 2 {
        anyhow::bail!(
            "marks.effector: the observation log carries two effector points, the recording has {}",
            header.effector.len()
        );
    }
    Ok(IdentifySettings {
        lens: LensModel {
            f_px: header.camera.f_px,
            cx: header.camera.cx,
            cy: header.camera.cy,
            k1: header.k1,
            k2: header.k2,
        },
        image_size_px: [header.camera.width, header.camera.height],
        reference_radius_m: header.reference_radius_m,
        disc_radius_m: header.disc_radius_m,
        part_feature_count: header.part_feature_count,
        diameters: MarkDiameters {
            disc_centre_m: header.disc_center.diameter_m,
            reference_m: header.reference.diameter_m,
            part_feature_m: header.part_feature.diameter_m,
            part_key_m: header.part_key.map(|m| m.diameter_m),
            effector_m: [header.effector[0].diameter_m, header.effector[1].diameter_m],
        },
        gate_px: TRACK_GATE_PX,
        // A disc point's image moves at most about a third of the image
        // width per radian (the disc fills less than two thirds of it).
        first_gate_px_per_rad: 0.3 * f64::from(header.camera.width.min(header.camera.height)),
    })
}

/// The observation log's frame from one frame's labels (points outside the
/// image, which the log refuses, are left out).
fn log_frame(
    header: &LogHeader,
    t_s: f64,
    theta: f64,
    points: &[LabelledPoint],
    effector_base_m: &[[f64; 3]; 2],
) -> ObservationFrame {
    let inside = |p: &LabelledPoint| header.camera.contains(p.pixel);
    let of = |label: MarkLabel| {
        points
            .iter()
            .find(|p| p.label == label && inside(p))
            .map(|p| p.pixel)
    };
    let part: Option<heapless::Vec<[f64; 2], { shared::observation::MAX_PART_FEATURES }>> = (0
        ..header.part_feature_count)
        .map(|k| of(MarkLabel::PartFeature(k as u8)))
        .collect::<Option<Vec<_>>>()
        .map(|v| v.into_iter().collect());
    let effector = match (of(MarkLabel::Effector(0)), of(MarkLabel::Effector(1))) {
        (Some(a), Some(b)) => Some(EffectorSighting {
            px: [a, b],
            base_m: *effector_base_m,
        }),
        _ => None,
    };
    ObservationFrame {
        t_s,
        conveyor_angle_rad: theta,
        center_px: of(MarkLabel::DiscCentre),
        reference_px: of(MarkLabel::Reference),
        part_px: part,
        effector,
        rim: None,
    }
}

/// The log's record of a rim the front end measured.
pub fn rim_observation(fit: &RimFit) -> RimObservation {
    RimObservation {
        centre_px: fit.ellipse.centre_px,
        semi_axes_px: fit.ellipse.semi_axes_px,
        angle_rad: fit.ellipse.angle_rad,
        sigma_px: fit.sigma_mean_radius_px,
    }
}

/// The front end's state over one run, fed frame by frame (a recording's,
/// or a simulated pick's straight from the renderer).
pub struct FrontEnd {
    detector: Box<Detector>,
    identifier: Box<Identifier>,
    blobs: HVec<Blob, MAX_BLOBS>,
    points: HVec<LabelledPoint, MAX_LABELS>,
    rim_finder: Box<RimFinder>,
    lens: LensModel,
    /// The last frame's rim, the start of this frame's.
    last_rim: Option<RimFit>,
    width: usize,
    height: usize,
    /// What it gave so far.
    pub run: FrontEndRun,
}

impl FrontEnd {
    /// A front end for the recording of `header`.
    pub fn new(header: &RecordingHeader) -> Result<Self> {
        let settings = identify_settings(header)?;
        let lens = settings.lens;
        let log_header = LogHeader {
            version: LOG_VERSION,
            camera: header.camera,
            reference_radius_m: header.reference_radius_m,
            part_feature_count: header.part_feature_count,
            disc_radius_m: Some(header.disc_radius_m),
        };
        Ok(Self {
            detector: Box::new(Detector::new(DetectorSettings::default())),
            identifier: Box::new(Identifier::new(settings)),
            blobs: HVec::new(),
            points: HVec::new(),
            rim_finder: Box::new(RimFinder::new(RimSettings::default())),
            lens,
            last_rim: None,
            width: header.camera.width as usize,
            height: header.camera.height as usize,
            run: FrontEndRun {
                log: ObservationLog {
                    header: log_header,
                    frames: Vec::new(),
                },
                frames: Vec::new(),
                skipped_images: 0,
                refused_frames: 0,
                ambiguous: 0,
            },
        })
    }

    /// Detects and labels one frame (`pixels` rows top to bottom) and adds
    /// it to the log.
    pub fn push(&mut self, row: &FrameRow, pixels: &[u8]) -> Result<()> {
        let image = GrayImage::new(self.width, self.height, self.width, pixels)
            .map_err(|e| anyhow::anyhow!("image {}: {e}", row.image))?;
        if self.detector.detect(&image, &mut self.blobs).is_err() {
            self.run.refused_frames += 1;
            self.blobs.clear();
        }
        let effector_base_m = match row.effector_base_m.as_slice() {
            [a, b, ..] => [*a, *b],
            _ => anyhow::bail!("frames.csv line {}: two effector marks expected", row.line),
        };
        let report = self.identifier.identify(
            row.conveyor_angle_rad,
            &self.blobs,
            &effector_base_m,
            &mut self.points,
        );
        self.run.ambiguous += u64::from(report.ambiguous);
        let rim = self.measure_rim(&image);
        if std::env::var_os("FRONT_END_DEBUG").is_some() {
            self.print_debug(row);
        }
        if std::env::var_os("EFFECTOR_DEBUG").is_some() {
            let labelled = self
                .points
                .iter()
                .filter(|p| matches!(p.label, MarkLabel::Effector(_)))
                .count();
            eprintln!(
                "eff frame {} base0 {:.3?} base1 {:.3?} pair {:?} sig {:?} proj {:?} rough {:.1?} labelled {}",
                row.trigger_id,
                effector_base_m[0],
                effector_base_m[1],
                self.identifier.effector_pair(),
                self.identifier.effector_signature(),
                self.identifier.projection_state(),
                self.identifier.gripper_rough_px(&effector_base_m),
                labelled
            );
        }
        let t_s = row.capture_time_us as f64 * 1e-6;
        let mut frame = log_frame(
            &self.run.log.header,
            t_s,
            row.conveyor_angle_rad,
            &self.points,
            &effector_base_m,
        );
        frame.rim = rim.as_ref().map(rim_observation);
        self.run.log.frames.push(frame);
        self.run.frames.push(FrameLabels {
            trigger_id: row.trigger_id,
            blobs: self.blobs.to_vec(),
            points: self.points.to_vec(),
            rim,
        });
        Ok(())
    }

    /// The rim of this frame: from the last frame's where there is one,
    /// else from rays out of the disc centre's label; `None` when neither
    /// gives it (then the next frame starts from the centre again).
    fn measure_rim(&mut self, image: &GrayImage<'_>) -> Option<RimFit> {
        let centre = self
            .points
            .iter()
            .find(|p| p.label == MarkLabel::DiscCentre)
            .and_then(|p| self.blobs.get(p.blob))
            .map(|b| [f64::from(b.x_px), f64::from(b.y_px)]);
        let near = self.last_rim.as_ref().and_then(|last| {
            self.rim_finder
                .find_near(image, &self.lens, &self.blobs, last, centre)
                .ok()
        });
        let fit = near.or_else(|| {
            centre.and_then(|c| {
                self.rim_finder
                    .find_from_centre(image, &self.lens, &self.blobs, c)
                    .ok()
            })
        });
        self.last_rim = fit;
        fit
    }

    /// This frame's pair of free blobs and their lights against the yardstick.
    pub fn effector_pair(&self) -> Option<([[f64; 2]; 2], [f64; 2])> {
        self.identifier.effector_pair()
    }

    /// Why the gripper's marks went unlabelled once the projection was known.
    pub fn effector_refusals(&self) -> [[u32; 9]; 2] {
        self.identifier.effector_refusals()
    }

    fn print_debug(&self, row: &FrameRow) {
        let identifier = &self.identifier;
        eprintln!(
            "frame {} theta {:.3} blobs {} labelled {} disc {:?} projection {:?}",
            row.trigger_id,
            row.conveyor_angle_rad,
            self.blobs.len(),
            self.points.len(),
            identifier.disc_image(),
            identifier.projection_state()
        );
        for b in &self.blobs {
            eprintln!(
                "  blob ({:.1},{:.1}) area {} contrast {:.1}",
                b.x_px, b.y_px, b.area_px, b.mean_contrast
            );
        }
        for p in &self.points {
            eprintln!(
                "  label {:?} at ({:.1},{:.1})",
                p.label, p.pixel[0], p.pixel[1]
            );
        }
        for (t, label) in identifier.tracks() {
            let m = t.fit.model(0.25);
            let w = t.whole.model(0.8);
            eprintln!(
                "  {:?} hits {} miss {} at ({:.1},{:.1}) area {:.1} flux {:.0} recent {:?} whole {:?}",
                label,
                t.hits,
                t.misses,
                t.latest.1[0],
                t.latest.1[1],
                t.mean_area_px(),
                t.mean_flux(),
                m.map(|m| (m.rms_px, m.radius_px())),
                w.map(|m| (m.rms_px, m.radius_px(), m.centre_px))
            );
        }
    }
}

/// Runs the front end over `recording`: with `skip_bad_images`, frames whose
/// image is bad are skipped and counted, else they are an error.
pub fn run(recording: &Recording, skip_bad_images: bool) -> Result<FrontEndRun> {
    let mut front_end = FrontEnd::new(&recording.header)?;
    for row in &recording.rows {
        let pixels = match recording.image(row) {
            Ok(pixels) => pixels,
            Err(e @ crate::camera_recording::RecordingError::Image { .. }) => {
                if skip_bad_images {
                    front_end.run.skipped_images += 1;
                    continue;
                }
                return Err(e).context(format!("frames.csv line {}", row.line));
            }
            Err(e) => return Err(e.into()),
        };
        front_end.push(row, &pixels)?;
    }
    Ok(front_end.run)
}

#[cfg(test)]
mod tests;
