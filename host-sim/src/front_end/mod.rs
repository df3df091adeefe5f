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

pub mod pictures;
pub mod score;

use anyhow::{Context, Result};
use heapless::Vec as HVec;
use shared::detection::identify::lens::LensModel;
use shared::detection::identify::{
    Identifier, IdentifySettings, LabelledPoint, MarkDiameters, MarkLabel, MAX_LABELS,
};
use shared::detection::{Blob, Detector, DetectorSettings, GrayImage, MAX_BLOBS};
use shared::observation::{EffectorSighting, LogHeader, ObservationFrame, LOG_VERSION};

use crate::camera_recording::{Polarity, Recording, RecordingHeader};
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
        reference_radius_m: header.reference_radius_m,
        disc_radius_m: header.disc_radius_m,
        part_feature_count: header.part_feature_count,
        diameters: MarkDiameters {
            disc_centre_m: header.disc_center.diameter_m,
            reference_m: header.reference.diameter_m,
            part_feature_m: header.part_feature.diameter_m,
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
    }
}

/// Runs the front end over `recording`: with `skip_bad_images`, frames whose
/// image is bad are skipped and counted, else they are an error.
pub fn run(recording: &Recording, skip_bad_images: bool) -> Result<FrontEndRun> {
    let header = &recording.header;
    let settings = identify_settings(header)?;
    let log_header = LogHeader {
        version: LOG_VERSION,
        camera: header.camera,
        reference_radius_m: header.reference_radius_m,
        part_feature_count: header.part_feature_count,
    };
    let mut detector = Box::new(Detector::new(DetectorSettings::default()));
    let mut identifier = Box::new(Identifier::new(settings));
    let mut blobs: HVec<Blob, MAX_BLOBS> = HVec::new();
    let mut points: HVec<LabelledPoint, MAX_LABELS> = HVec::new();
    let mut run = FrontEndRun {
        log: ObservationLog {
            header: log_header,
            frames: Vec::new(),
        },
        frames: Vec::new(),
        skipped_images: 0,
        refused_frames: 0,
        ambiguous: 0,
    };
    let (width, height) = (header.camera.width as usize, header.camera.height as usize);
    for row in &recording.rows {
        let pixels = match recording.image(row) {
            Ok(pixels) => pixels,
            Err(e @ crate::camera_recording::RecordingError::Image { .. }) => {
                if skip_bad_images {
                    run.skipped_images += 1;
                    continue;
                }
                return Err(e).context(format!("frames.csv line {}", row.line));
            }
            Err(e) => return Err(e.into()),
        };
        let image = GrayImage::new(width, height, width, &pixels)
            .map_err(|e| anyhow::anyhow!("image {}: {e}", row.image))?;
        if detector.detect(&image, &mut blobs).is_err() {
            run.refused_frames += 1;
            blobs.clear();
        }
        let effector_base_m = match row.effector_base_m.as_slice() {
            [a, b, ..] => [*a, *b],
            _ => anyhow::bail!("frames.csv line {}: two effector marks expected", row.line),
        };
        let report = identifier.identify(
            row.conveyor_angle_rad,
            &blobs,
            &effector_base_m,
            &mut points,
        );
        run.ambiguous += u64::from(report.ambiguous);
        if std::env::var_os("FRONT_END_DEBUG").is_some() {
            eprintln!(
                "frame {} theta {:.3} blobs {} labelled {} disc {:?} projection {:?}",
                row.trigger_id,
                row.conveyor_angle_rad,
                blobs.len(),
                points.len(),
                identifier.disc_image(),
                identifier.projection_state()
            );
            for (t, label) in identifier.tracks() {
                let m = t.fit.model(0.25);
                let w = t.whole.model(0.8);
                eprintln!(
                    "  {:?} hits {} miss {} at ({:.1},{:.1}) area {:.1} recent {:?} whole {:?}",
                    label,
                    t.hits,
                    t.misses,
                    t.latest.1[0],
                    t.latest.1[1],
                    t.mean_area_px(),
                    m.map(|m| (m.rms_px, m.radius_px())),
                    w.map(|m| (m.rms_px, m.radius_px(), m.centre_px))
                );
            }
        }
        let t_s = row.capture_time_us as f64 * 1e-6;
        run.log.frames.push(log_frame(
            &run.log.header,
            t_s,
            row.conveyor_angle_rad,
            &points,
            &effector_base_m,
        ));
        run.frames.push(FrameLabels {
            trigger_id: row.trigger_id,
            blobs: blobs.to_vec(),
            points: points.to_vec(),
        });
    }
    Ok(run)
}

#[cfg(test)]
mod tests;
