//! The camera's 2-D view: each frame's image with the vision computer's
//! labels on it (runs through images), and in every run the labelled points
//! the controller was sent.
//!
//! The image is rendered again here from the same world, at the same
//! trigger, with a renderer and a front end of its own seeded as the
//! world's vision computer's: their frames and labels are the same as the
//! ones the controller was sent (rendering and labelling are deterministic
//! given the sequence of frames). The world is not asked to keep its frames.
//! The labels are drawn where the detector found the blobs (through the
//! lens), the points sent at their undistorted (pinhole) pixels, so the two
//! differ by the lens' distortion (1 to 2 px at the corners).

use anyhow::Result;
use rerun::{Image, Points2D, RecordingStream};
use shared::protocol::{CameraFeatureFrame, PointLabel};

use super::names::{self, point_label_colour, point_label_name};
use crate::camera_recording::simulate::FrameRenderer;
use crate::front_end::FrontEnd;
use crate::scenario::pick::PickExperiment;
use crate::world::image_vision::point_label;
use crate::world::World;

/// The drawn points' radius, px.
const POINT_RADIUS_PX: f32 = 2.0;

/// One frame as the vision computer saw it.
#[derive(Debug, Clone, PartialEq)]
pub struct SeenFrame {
    pub width: u32,
    pub height: u32,
    /// 8-bit grey, rows top to bottom.
    pub pixels: Vec<u8>,
    /// Each label with its blob's centre (through the lens) and its
    /// undistorted (pinhole) pixel, the one sent to the controller when it
    /// lies inside the image.
    pub labels: Vec<(PointLabel, [f32; 2], [f64; 2])>,
    /// The blobs no label was given.
    pub unlabelled: Vec<[f32; 2]>,
}

/// The vision computer of a run through images, as the world's.
pub struct ImageLabeller {
    frames: FrameRenderer,
    front_end: Option<FrontEnd>,
}

impl ImageLabeller {
    /// The same renderer and noise as the world's vision computer of
    /// `experiment` on the workcell of `seed`.
    pub fn new(experiment: &PickExperiment, seed: u64) -> Self {
        Self {
            frames: FrameRenderer::new(experiment, seed),
            front_end: None,
        }
    }

    /// Renders and labels frame `trigger_id` of `world` now.
    pub fn see(&mut self, world: &World, trigger_id: u32) -> Result<SeenFrame> {
        let frame = self.frames.render(world, u64::from(trigger_id))?;
        let front_end = match self.front_end.as_mut() {
            Some(front_end) => front_end,
            None => self.front_end.insert(FrontEnd::new(frame.header)?),
        };
        front_end.push(&frame.row, frame.pixels)?;
        let intrinsics = frame.header.camera;
        let mut seen = SeenFrame {
            width: intrinsics.width,
            height: intrinsics.height,
            pixels: frame.pixels.to_vec(),
            labels: Vec::new(),
            unlabelled: Vec::new(),
        };
        if let Some(labels) = front_end.run.frames.last() {
            let blob_at = |index: usize| labels.blobs.get(index).map(|b| [b.x_px, b.y_px]);
            seen.labels = labels
                .points
                .iter()
                .filter_map(|p| blob_at(p.blob).map(|at| (point_label(p.label), at, p.pixel)))
                .collect();
            seen.unlabelled = labels
                .blobs
                .iter()
                .enumerate()
                .filter(|(index, _)| labels.points.iter().all(|p| p.blob != *index))
                .map(|(_, blob)| [blob.x_px, blob.y_px])
                .collect();
        }
        // Only the last frame is read: memory stays flat however long the run.
        front_end.run.frames.clear();
        front_end.run.log.frames.clear();
        Ok(seen)
    }

    /// Renders and labels frame `trigger_id` of `world` now and logs the
    /// image with its labels and unlabelled blobs.
    pub fn log_frame(
        &mut self,
        rec: &RecordingStream,
        world: &World,
        trigger_id: u32,
    ) -> Result<()> {
        let seen = self.see(world, trigger_id)?;
        let labels = &seen.labels;
        rec.log(
            names::CAMERA_IMAGE,
            &Image::from_l8(seen.pixels, [seen.width, seen.height]),
        )?;
        rec.log(
            names::CAMERA_LABELS,
            &Points2D::new(labels.iter().map(|(_, at, _)| *at))
                .with_labels(labels.iter().map(|(label, _, _)| point_label_name(*label)))
                .with_colors(
                    labels
                        .iter()
                        .map(|(label, _, _)| point_label_colour(*label)),
                )
                .with_radii([POINT_RADIUS_PX]),
        )?;
        rec.log(
            names::CAMERA_BLOBS,
            &Points2D::new(seen.unlabelled)
                .with_colors([names::unlabelled_colour()])
                .with_radii([POINT_RADIUS_PX]),
        )?;
        Ok(())
    }
}

/// The labelled points of `frame` as the controller was sent them; their
/// names written beside them when `named` (on an image the labeller's
/// names are already there).
pub fn log_received(rec: &RecordingStream, frame: &CameraFeatureFrame, named: bool) -> Result<()> {
    let points = &frame.points;
    let mut drawn = Points2D::new(points.iter().map(|p| [p.u_px, p.v_px]))
        .with_colors(points.iter().map(|p| point_label_colour(p.label)))
        .with_radii([POINT_RADIUS_PX / 2.0]);
    if named {
        drawn = drawn.with_labels(points.iter().map(|p| point_label_name(p.label)));
    }
    rec.log(names::CAMERA_RECEIVED, &drawn)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::link::{FramedLink, InProcessLink};
    use crate::pick::runner::run_pick_watched;
    use crate::pick::watch::PickWatcher;
    use crate::scenario::pick::{CameraSource, PickScenarioFile};
    use shared::protocol::ActuatorCommand;

    /// Labels seen here at each trigger, and the ones the controller was sent.
    struct Compare {
        labeller: ImageLabeller,
        seen: BTreeMap<u32, Vec<(PointLabel, [f32; 2])>>,
        sent: BTreeMap<u32, Vec<(PointLabel, [f32; 2])>>,
    }

    impl PickWatcher for Compare {
        fn period(&mut self, world: &World, command: &ActuatorCommand) -> Result<()> {
            if let Some(trigger_id) = command.camera_trigger {
                let camera = world.workcell().camera.intrinsics;
                let seen = self.labeller.see(world, trigger_id)?;
                let inside = seen
                    .labels
                    .iter()
                    .filter(|(_, _, pixel)| camera.contains(*pixel))
                    .map(|(label, _, [u, v])| (*label, [*u as f32, *v as f32]))
                    .collect();
                self.seen.insert(trigger_id, inside);
            }
            Ok(())
        }

        fn frames_sent(&mut self, _: &World, frames: &[CameraFeatureFrame]) -> Result<()> {
            for frame in frames {
                let points = frame.points.iter().map(|p| (p.label, [p.u_px, p.v_px]));
                self.sent.insert(frame.trigger_id, points.collect());
            }
            Ok(())
        }
    }

    #[test]
    fn the_frames_drawn_are_labelled_as_the_controller_was_sent_them() {
        let mut experiment = PickScenarioFile::default_experiment("turning").unwrap();
        experiment.camera.source = CameraSource::Images;
        experiment.time_limit_s = 20.0;
        let mut compare = Compare {
            labeller: ImageLabeller::new(&experiment, 1),
            seen: BTreeMap::new(),
            sent: BTreeMap::new(),
        };
        let mut link = FramedLink::new(InProcessLink::new());
        run_pick_watched(&experiment, 1, &mut link, &mut compare).unwrap();
        assert!(
            compare.sent.len() > 50,
            "{} frames sent",
            compare.sent.len()
        );
        for (trigger_id, sent) in &compare.sent {
            assert_eq!(
                compare.seen.get(trigger_id),
                Some(sent),
                "frame {trigger_id}"
            );
        }
    }
}
