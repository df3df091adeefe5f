//! How far the controller's final estimate is from the maximum-likelihood limit
//! of the very data it saw (issue 20): the pick's own log up to its final
//! estimate, solved by the independent full batch solve ([`crate::batch_ml`],
//! every frame and every sighting, unbounded memory), both scored against the
//! world's truth. `host-sim montecarlo --ml-limit` does it for every trial.
//!
//! Beside it, the floor of the disc's frames alone: the same batch solve with
//! the robot-to-camera link made known (every sighting of the gripper's marks
//! exact and weighed [`KNOWN_LINK_COPIES`] times). No motion of the arm can
//! bring the part in the base frame closer than that with these frames:
//! what is left is the reference circle's size, which sets the camera's
//! height (H = f L / l).

use anyhow::{anyhow, Result};
use shared::observation::{EffectorSighting, ObservationFrame};

use super::own_log::{controller_estimate, truth_of, LoggedPick};
use crate::accuracy::metrics::{compare, ErrorMetrics};
use crate::batch_ml::batch_estimate;
use crate::log::ObservationLog;
use crate::world::Workcell;

/// How many times the known-link floor counts each (exact) sighting: enough
/// that the link's own uncertainty is a small part of the part's (at 50 the
/// part's height sigma in a logged 5 Hz cell, seed 1000411, is within 2 % of
/// its value at 500).
pub const KNOWN_LINK_COPIES: usize = 50;

/// The controller's final estimate and the batch solve of its data, each
/// against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitErrors {
    /// The controller's final estimate's errors.
    pub controller: ErrorMetrics,
    /// The batch solve's errors on the same frames.
    pub limit: ErrorMetrics,
    /// The batch solve's errors on the same frames with the robot-to-camera
    /// link known (see the module's doc): the disc frames' own floor.
    pub known_link: ErrorMetrics,
}

/// Solves the frames the controller's final estimate was made from in full
/// batch and scores both estimates. An error when the pick made no final
/// estimate (nothing to compare) or the solve fails.
pub fn limit_of(logged: &LoggedPick) -> Result<LimitErrors> {
    let estimate = controller_estimate(logged, &[])
        .ok_or_else(|| anyhow!("the pick made no final estimate"))?;
    let truth = truth_of(logged);
    let worker = &logged.worker;
    let frames = worker
        .frames
        .get(..estimate.controller.log_frames)
        .ok_or_else(|| anyhow!("the log is shorter than the final estimate's frames"))?;
    let log = ObservationLog {
        header: worker.header,
        frames: frames.to_vec(),
    };
    let batch = batch_estimate(&log, &worker.config, &estimate.result)
        .map_err(|error| anyhow!("batch solve: {error}"))?;
    let known_link_log = ObservationLog {
        header: worker.header,
        frames: with_known_link(frames, &logged.workcell),
    };
    let known_link = batch_estimate(&known_link_log, &worker.config, &estimate.result)
        .map_err(|error| anyhow!("batch solve with the link known: {error}"))?;
    Ok(LimitErrors {
        controller: compare(&estimate.result, &truth.result)?,
        limit: compare(&batch.result, &truth.result)?,
        known_link: compare(&known_link.result, &truth.result)?,
    })
}

/// `frames` with each sighting of the marks made exact (its logged base
/// positions projected through the true camera) and repeated
/// [`KNOWN_LINK_COPIES`] times in all, the copies showing nothing else.
/// A sighting the true camera cannot image is left out.
fn with_known_link(frames: &[ObservationFrame], workcell: &Workcell) -> Vec<ObservationFrame> {
    let mut out = Vec::with_capacity(frames.len() * 2);
    for frame in frames {
        let exact = frame
            .effector
            .as_ref()
            .and_then(|sighting| exact_sighting(sighting, workcell));
        out.push(ObservationFrame {
            effector: exact,
            ..frame.clone()
        });
        if let Some(sighting) = exact {
            out.extend((1..KNOWN_LINK_COPIES).map(|_| ObservationFrame {
                t_s: frame.t_s,
                conveyor_angle_rad: frame.conveyor_angle_rad,
                center_px: None,
                reference_px: None,
                part_px: None,
                effector: Some(sighting),
                rim: None,
            }));
        }
    }
    out
}

/// The images the true camera makes of the sighting's base positions.
fn exact_sighting(sighting: &EffectorSighting, workcell: &Workcell) -> Option<EffectorSighting> {
    let mut exact = *sighting;
    for (px, base_m) in exact.px.iter_mut().zip(&sighting.base_m) {
        let p_base = nalgebra::Vector3::from(*base_m);
        *px = workcell.camera.project(&workcell.disc_from_base(&p_base))?;
    }
    Some(exact)
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use rand::rngs::ChaCha8Rng;
    use rand::SeedableRng;

    use super::*;
    use crate::scenario::recording::Scenario;
    use crate::world::generator::random_workcell;

    fn frame(t_s: f64, effector: Option<EffectorSighting>) -> ObservationFrame {
        ObservationFrame {
            t_s,
            conveyor_angle_rad: 0.1 * t_s,
            center_px: Some([128.0, 128.0]),
            reference_px: Some([150.0, 140.0]),
            part_px: None,
            effector,
            rim: None,
        }
    }

    #[test]
    fn the_known_link_makes_each_sighting_exact_and_counts_it_fifty_times() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let (workcell, _) = random_workcell(&mut rng, &Scenario::paper()).unwrap();
        // Two marks 10 cm apart, 0.3 m above the disc's centre.
        let base_m = [[0.0, 0.0, 0.3], [0.1, 0.0, 0.3]]
            .map(|p| workcell.base_from_disc(&Vector3::from(p)).into());
        let noisy = EffectorSighting {
            px: [[1.0, 2.0], [3.0, 4.0]],
            base_m,
        };
        let frames = [frame(0.0, None), frame(0.2, Some(noisy)), frame(0.4, None)];
        let known = with_known_link(&frames, &workcell);
        assert_eq!(known.len(), 2 + KNOWN_LINK_COPIES);
        assert_eq!(known[0], frames[0]);
        assert_eq!(known[known.len() - 1], frames[2]);
        let sightings: Vec<&ObservationFrame> =
            known.iter().filter(|f| f.effector.is_some()).collect();
        assert_eq!(sightings.len(), KNOWN_LINK_COPIES);
        // The frame itself keeps its disc marks; its copies show only the marks.
        assert_eq!(sightings[0].reference_px, frames[1].reference_px);
        assert!(sightings[1..]
            .iter()
            .all(|f| f.reference_px.is_none() && f.center_px.is_none() && f.t_s == 0.2));
        for (k, p) in base_m.iter().enumerate() {
            let expected = workcell
                .camera
                .project(&workcell.disc_from_base(&Vector3::from(*p)))
                .unwrap();
            for sighting in &sightings {
                let px = sighting.effector.unwrap().px[k];
                assert!((px[0] - expected[0]).abs() < 1e-9 && (px[1] - expected[1]).abs() < 1e-9);
            }
        }
    }
}
