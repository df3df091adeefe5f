//! The vision computer on images (`camera.source = "images"`): at each
//! trigger the world renders the camera's 8-bit frame (lens, light, noise,
//! blur, the arm hiding what it stands in front of), and the project's own
//! detector and identifier (`shared::detection`, through
//! [`crate::front_end::FrontEnd`]) turn it into the labelled points the
//! controller receives, as a separate vision computer would. The identifier
//! gets only what such a computer is given: the image, the conveyor angle
//! latched at the trigger and the gripper marks' base-frame centres from the
//! joint encoders.
//!
//! The truth of each frame (where every mark really is) is kept beside it
//! only to score the labels: [`ImageVisionStats`].

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use shared::detection::identify::MarkLabel;
use shared::protocol::{CameraFeatureFrame, LabeledPoint, PointLabel, RimEllipse};

use super::World;
use crate::camera_recording::simulate::{FrameRenderer, TrueFrame};
use crate::front_end::score::{Judge, Verdict};
use crate::front_end::FrontEnd;
use crate::scenario::pick::PickExperiment;

/// What the front end labelled over a run, scored against the truth.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ImageVisionStats {
    /// Frames rendered and labelled.
    pub frames: u64,
    /// Frames whose detections the detector refused (too many blobs).
    pub refused_frames: u64,
    /// Labels sent to the controller.
    pub labels: u64,
    /// Labels naming another mark than the one under them (part features by
    /// the part's own order: a feature given another's index is wrong).
    pub wrong_labels: u64,
    /// Labels on the right mark, their point displaced (a mark partly hidden).
    pub off_labels: u64,
}

/// The in-loop vision computer of one world.
pub struct ImageVision {
    frames: FrameRenderer,
    front_end: Option<FrontEnd>,
    stats: ImageVisionStats,
}

impl std::fmt::Debug for ImageVision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImageVision")
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

/// The label the link carries for the identifier's label.
pub fn point_label(label: MarkLabel) -> PointLabel {
    match label {
        MarkLabel::DiscCentre => PointLabel::DiscCenter,
        MarkLabel::Reference => PointLabel::Reference,
        MarkLabel::PartFeature(i) => PointLabel::Part(i),
        MarkLabel::Effector(i) => PointLabel::Effector(i),
    }
}

impl ImageVision {
    /// The vision computer of the world of `experiment` drawn from `seed`.
    pub fn new(experiment: &PickExperiment, seed: u64) -> Self {
        Self {
            frames: FrameRenderer::new(experiment, seed),
            front_end: None,
            stats: ImageVisionStats::default(),
        }
    }

    pub fn stats(&self) -> ImageVisionStats {
        self.stats
    }

    /// Frame `trigger_id` of `world` now: rendered, detected, labelled; the
    /// labelled points inside the image, undistorted (the controller's camera
    /// is a pinhole).
    pub fn see(&mut self, world: &World, trigger_id: u32) -> Result<CameraFeatureFrame> {
        let frame = self
            .frames
            .render(world, u64::from(trigger_id))
            .with_context(|| format!("rendering frame {trigger_id}"))?;
        let front_end = match self.front_end.as_mut() {
            Some(front_end) => front_end,
            None => self.front_end.insert(FrontEnd::new(frame.header)?),
        };
        let refused_before = front_end.run.refused_frames;
        front_end.push(&frame.row, frame.pixels)?;
        self.stats.frames += 1;
        self.stats.refused_frames += (front_end.run.refused_frames - refused_before) as u64;
        let mut out = CameraFeatureFrame {
            trigger_id,
            capture_time_us: (world.time_s().max(0.0) * 1e6).round() as u64,
            points: heapless::Vec::new(),
            rim: front_end
                .run
                .frames
                .last()
                .and_then(|f| f.rim.as_ref())
                .map(|fit| RimEllipse {
                    centre_px: fit.ellipse.centre_px.map(|c| c as f32),
                    semi_axes_px: fit.ellipse.semi_axes_px.map(|a| a as f32),
                    angle_rad: fit.ellipse.angle_rad as f32,
                    sigma_px: fit.sigma_mean_radius_px as f32,
                }),
        };
        // Diagnosis only: where the gripper's marks truly are, beside what
        // `EFFECTOR_DEBUG` says the front end made of them (printed, never
        // given to the controller).
        if std::env::var_os("TRUTH_DEBUG").is_some() {
            for m in frame
                .truth
                .marks
                .iter()
                .filter(|m| m.kind == "effector" && m.shows)
            {
                eprintln!(
                    "true eff {} frame {trigger_id} at {:.1?} visible {}",
                    m.index, m.image_px, m.visible
                );
            }
        }
        if std::env::var_os("RIM_DEBUG").is_some() {
            print_rim(front_end, &frame.truth, trigger_id);
        }
        let truth = std::slice::from_ref(&frame.truth);
        let judge = Judge::in_fixed_order(truth);
        let camera = &front_end.run.log.header.camera;
        if let Some(labels) = front_end.run.frames.last() {
            for point in labels.points.iter().filter(|p| camera.contains(p.pixel)) {
                self.stats.labels += 1;
                let verdict = judge.verdict(labels.trigger_id, point);
                let debug = match verdict {
                    Some(Verdict::Wrong) => {
                        self.stats.wrong_labels += 1;
                        Some(("wrong label", "EFFECTOR_DEBUG"))
                    }
                    Some(Verdict::Off) => {
                        self.stats.off_labels += 1;
                        Some(("off label", "EFFECTOR_DEBUG"))
                    }
                    _ => None,
                };
                for (what, variable) in debug.into_iter().chain([("label", "LABEL_DEBUG")]) {
                    if std::env::var_os(variable).is_some() {
                        let blob = labels.blobs.get(point.blob);
                        eprintln!(
                            "{what} {:?} frame {trigger_id} at {:.4?} (blob of {} px, lopsided {:.3}); nearest true mark {}",
                            point.label,
                            point.pixel,
                            blob.map_or(0, |b| b.area_px),
                            blob.map_or(0.0, |b| b.lopsidedness),
                            nearest_mark(&frame.truth, point.pixel)
                        );
                    }
                }
                // More points than a frame carries cannot come from <= 8
                // features; one that does not fit is left out.
                let _ = out.points.push(LabeledPoint {
                    label: point_label(point.label),
                    u_px: point.pixel[0] as f32,
                    v_px: point.pixel[1] as f32,
                });
            }
        }
        // The run's own log and labels are not kept: memory stays flat
        // however long the pick runs.
        front_end.run.frames.clear();
        front_end.run.log.frames.clear();
        Ok(out)
    }
}

/// Diagnosis only: the rim the front end measured against the true rim's
/// projection (mean and RMS distance, px; positive: the truth lies outside).
fn print_rim(front_end: &FrontEnd, truth: &TrueFrame, trigger_id: u32) {
    let Some(fit) = front_end.run.frames.last().and_then(|f| f.rim) else {
        eprintln!("rim frame {trigger_id} none");
        return;
    };
    let distances: Vec<f64> = truth
        .rim_pinhole_px
        .iter()
        .filter_map(|p| fit.ellipse.locate(*p).map(|q| q.distance_px(1.0)))
        .collect();
    let n = distances.len().max(1) as f64;
    let mean = distances.iter().sum::<f64>() / n;
    let rms = (distances.iter().map(|d| d * d).sum::<f64>() / n).sqrt();
    eprintln!(
        "rim frame {trigger_id} mean {mean:+.4} rms {rms:.4} sigma_r {:.4} pixels {} sectors {} noise {:.2} contrast {:.1} iterations {} band {:.4}",
        fit.sigma_mean_radius_px, fit.pixels, fit.sectors, fit.noise_grey, fit.contrast_grey, fit.iterations, fit.band_fraction
    );
}

/// The true mark whose pinhole pixel is nearest `pixel`, described (what a
/// wrong label's debug line says it really was).
fn nearest_mark(truth: &TrueFrame, pixel: [f64; 2]) -> String {
    truth
        .marks
        .iter()
        .map(|mark| {
            let d = (mark.pinhole_px[0] - pixel[0]).hypot(mark.pinhole_px[1] - pixel[1]);
            (d, mark)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or_else(
            || "none".to_string(),
            |(d, mark)| {
                format!(
                    "{} {} {d:.2} px away (visible {}, shows {}) true {:.4?}",
                    mark.kind, mark.index, mark.visible, mark.shows, mark.pinhole_px
                )
            },
        )
}
