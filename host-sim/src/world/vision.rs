//! The overhead camera and its vision computer, as the controller meets them: a
//! frame is exposed when the controller triggers, and its detections (the images
//! of the disc centre, the reference mark, the part's features and the two
//! effector marks, paper Section 3) arrive after a jittered latency, possibly out
//! of order. The controller pairs each frame with the encoder values it latched
//! at the trigger, so the latency must not change what the frame shows: it is
//! rendered at the exposure instant.
//!
//! Imperfections, as the recorder's scenarios have them: Gaussian pixel noise;
//! each detection group (centre, reference, the part as a whole, the effector
//! pair) missing with the dropout probability; each point independently a gross
//! outlier uniform over the image; points outside the image (the contract's
//! rule) omitted. There is no occlusion model: the arm never hides a mark, and a
//! part held in the gripper is seen where it is.

use anyhow::{bail, Result};
use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;
use shared::observation::PixelPoint;
use shared::protocol::{CameraFeatureFrame, LabeledPoint, PointLabel};

use super::camera::PinholeCamera;
use crate::scenario::pick::CameraSettings;

/// Where the marks are at the exposure instant, all in the disc frame.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneMarks {
    pub centre_disc: Vector3<f64>,
    pub reference_disc: Vector3<f64>,
    /// The part's features in their fixed order.
    pub part_disc: Vec<Vector3<f64>>,
    /// The two effector marks.
    pub effector_disc: [Vector3<f64>; 2],
}

/// What the camera has injected so far (for checking rates).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CameraStats {
    pub frames: u64,
    /// Detection groups dropped, out of `groups` rendered.
    pub groups: u64,
    pub groups_dropped: u64,
    /// Points made gross outliers, out of `points` rendered (not dropped).
    pub points: u64,
    pub outliers: u64,
}

/// The simulated camera.
#[derive(Debug)]
pub struct CameraSim {
    camera: PinholeCamera,
    settings: CameraSettings,
    rng: ChaCha8Rng,
    /// Frames in flight: arrival time, frame.
    in_flight: Vec<(f64, CameraFeatureFrame)>,
    stats: CameraStats,
}

impl CameraSim {
    pub fn new(camera: PinholeCamera, settings: &CameraSettings, seed: u64) -> Result<Self> {
        let ok = settings.pixel_sigma_px.is_finite()
            && settings.pixel_sigma_px >= 0.0
            && (0.0..1.0).contains(&settings.dropout_probability)
            && (0.0..1.0).contains(&settings.outlier_probability)
            && settings.latency_ms.is_finite()
            && settings.latency_jitter_ms.is_finite()
            && (0.0..=settings.latency_ms).contains(&settings.latency_jitter_ms);
        if !ok {
            bail!("camera settings out of range: {settings:?}");
        }
        Ok(Self {
            camera,
            settings: *settings,
            rng: ChaCha8Rng::seed_from_u64(seed),
            in_flight: Vec::new(),
            stats: CameraStats::default(),
        })
    }

    pub fn camera(&self) -> &PinholeCamera {
        &self.camera
    }

    /// The camera was knocked: from now on it sees from `camera`.
    pub fn move_to(&mut self, camera: PinholeCamera) {
        self.camera = camera;
    }

    pub fn stats(&self) -> CameraStats {
        self.stats
    }

    /// Exposes frame `trigger_id` at `time_s` and sends it on its way; it arrives
    /// after the latency plus uniform jitter.
    pub fn expose(&mut self, trigger_id: u32, time_s: f64, scene: &SceneMarks) {
        if self.blacked_out(time_s) {
            return;
        }
        let frame = self.render(trigger_id, time_s, scene);
        self.send(time_s, frame);
    }

    /// Sends a frame exposed at `time_s` that the vision computer labelled
    /// from its image (`camera.source = "images"`): it arrives after the
    /// latency like the others, and not at all after a blackout.
    pub fn deliver(&mut self, time_s: f64, frame: CameraFeatureFrame) {
        if self.blacked_out(time_s) {
            return;
        }
        self.stats.frames += 1;
        self.send(time_s, frame);
    }

    /// The blackout fault has begun by `time_s`: no frame leaves the camera.
    fn blacked_out(&self, time_s: f64) -> bool {
        self.settings
            .faults
            .blackout_after_s
            .is_some_and(|after| time_s >= after)
    }

    fn send(&mut self, time_s: f64, frame: CameraFeatureFrame) {
        let jitter_ms = self.settings.latency_jitter_ms * (2.0 * self.rng.random::<f64>() - 1.0);
        let arrival_s = time_s + (self.settings.latency_ms + jitter_ms) / 1000.0;
        self.in_flight.push((arrival_s, frame));
    }

    /// The frames that have arrived by `now_s`, in order of arrival (which need
    /// not be the order of exposure).
    pub fn due_frames(&mut self, now_s: f64) -> Vec<CameraFeatureFrame> {
        let mut due: Vec<(f64, CameraFeatureFrame)> = Vec::new();
        let mut index = 0;
        while index < self.in_flight.len() {
            if self.in_flight.get(index).is_some_and(|(t, _)| *t <= now_s) {
                due.push(self.in_flight.swap_remove(index));
            } else {
                index += 1;
            }
        }
        due.sort_by(|a, b| a.0.total_cmp(&b.0));
        due.into_iter().map(|(_, frame)| frame).collect()
    }

    /// Frames exposed but not yet arrived.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// The detections of one frame exposed at `time_s`.
    pub fn render(
        &mut self,
        trigger_id: u32,
        time_s: f64,
        scene: &SceneMarks,
    ) -> CameraFeatureFrame {
        self.stats.frames += 1;
        let mut frame = CameraFeatureFrame {
            trigger_id,
            capture_time_us: (time_s.max(0.0) * 1e6).round() as u64,
            points: heapless::Vec::new(),
            // Ideal points have no image, so no rim.
            rim: None,
        };
        self.render_group(&mut frame, &[(PointLabel::DiscCenter, scene.centre_disc)]);
        self.render_group(&mut frame, &[(PointLabel::Reference, scene.reference_disc)]);
        let part: Vec<(PointLabel, Vector3<f64>)> = scene
            .part_disc
            .iter()
            .enumerate()
            .map(|(i, p)| (PointLabel::Part(u8::try_from(i).unwrap_or(u8::MAX)), *p))
            .collect();
        self.render_group(&mut frame, &part);
        let [first, second] = scene.effector_disc;
        if !self.settings.faults.effector_hidden {
            self.render_group(
                &mut frame,
                &[
                    (PointLabel::Effector(0), first),
                    (PointLabel::Effector(1), second),
                ],
            );
        }
        frame
    }

    fn render_group(
        &mut self,
        frame: &mut CameraFeatureFrame,
        group: &[(PointLabel, Vector3<f64>)],
    ) {
        self.stats.groups += 1;
        if self.rng.random::<f64>() < self.settings.dropout_probability {
            self.stats.groups_dropped += 1;
            return;
        }
        for (label, p_disc) in group {
            self.stats.points += 1;
            if let Some(pixel) = self.detect(p_disc) {
                let [u, v] = pixel;
                // A full frame (more points than the protocol carries) cannot
                // happen with <= 8 features; a point that does not fit is omitted.
                let _ = frame.points.push(LabeledPoint {
                    label: *label,
                    u_px: u as f32,
                    v_px: v as f32,
                });
            }
        }
    }

    /// The detected image of one point: an outlier, or the projection plus noise,
    /// or nothing when behind the camera or outside the image.
    fn detect(&mut self, p_disc: &Vector3<f64>) -> Option<PixelPoint> {
        let intrinsics = self.camera.intrinsics;
        if self.rng.random::<f64>() < self.settings.outlier_probability {
            self.stats.outliers += 1;
            return Some([
                -0.5 + f64::from(intrinsics.width) * self.rng.random::<f64>(),
                -0.5 + f64::from(intrinsics.height) * self.rng.random::<f64>(),
            ]);
        }
        let [u, v] = self.camera.project(p_disc)?;
        let du: f64 = self.rng.sample(StandardNormal);
        let dv: f64 = self.rng.sample(StandardNormal);
        let sigma = self.settings.pixel_sigma_px;
        let noisy = [u + sigma * du, v + sigma * dv];
        intrinsics.contains(noisy).then_some(noisy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::pick::PickScenarioFile;
    use crate::scenario::recording::Scenario;
    use crate::world::generator::random_workcell;

    fn settings() -> CameraSettings {
        PickScenarioFile::embedded_default()
            .unwrap()
            .experiment
            .first()
            .unwrap()
            .camera
    }

    fn scene_and_camera(seed: u64) -> (SceneMarks, PinholeCamera) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (workcell, _) = random_workcell(&mut rng, &Scenario::paper()).unwrap();
        let theta = 0.7;
        let scene = SceneMarks {
            centre_disc: Vector3::zeros(),
            reference_disc: workcell.reference_disc(theta),
            part_disc: workcell
                .features_rotating
                .iter()
                .map(|p| crate::world::Workcell::disc_from_rotating(theta, p))
                .collect(),
            effector_disc: [Vector3::new(0.1, 0.0, 0.3), Vector3::new(0.0, 0.1, 0.3)],
        };
        (scene, workcell.camera)
    }

    #[test]
    fn noise_free_frames_reproject_exactly() {
        let clean = CameraSettings {
            pixel_sigma_px: 0.0,
            dropout_probability: 0.0,
            outlier_probability: 0.0,
            ..settings()
        };
        for seed in 0..10 {
            let (scene, camera) = scene_and_camera(seed);
            let mut sim = CameraSim::new(camera.clone(), &clean, seed).unwrap();
            let frame = sim.render(7, 1.25, &scene);
            assert_eq!(frame.trigger_id, 7);
            assert_eq!(frame.capture_time_us, 1_250_000);
            let expected: Vec<(PointLabel, Vector3<f64>)> = [
                (PointLabel::DiscCenter, scene.centre_disc),
                (PointLabel::Reference, scene.reference_disc),
            ]
            .into_iter()
            .chain(
                scene
                    .part_disc
                    .iter()
                    .enumerate()
                    .map(|(i, p)| (PointLabel::Part(i as u8), *p)),
            )
            .chain([
                (PointLabel::Effector(0), scene.effector_disc[0]),
                (PointLabel::Effector(1), scene.effector_disc[1]),
            ])
            .filter(|(_, p)| {
                camera
                    .project(p)
                    .is_some_and(|px| camera.intrinsics.contains(px))
            })
            .collect();
            assert!(expected.len() >= 5, "centre, reference and part in view");
            assert_eq!(frame.points.len(), expected.len());
            for (point, (label, p)) in frame.points.iter().zip(expected) {
                let [u, v] = camera.project(&p).unwrap();
                assert_eq!(point.label, label);
                assert!((f64::from(point.u_px) - u).abs() < 1e-4 * u.abs().max(1.0));
                assert!((f64::from(point.v_px) - v).abs() < 1e-4 * v.abs().max(1.0));
            }
        }
    }

    #[test]
    fn dropouts_and_outliers_occur_at_their_rates() {
        let noisy = CameraSettings {
            dropout_probability: 0.1,
            outlier_probability: 0.05,
            ..settings()
        };
        let (scene, camera) = scene_and_camera(4);
        let mut sim = CameraSim::new(camera.clone(), &noisy, 99).unwrap();
        let mut part_frames_complete = 0;
        for k in 0..2000 {
            let frame = sim.render(k, f64::from(k) * 0.2, &scene);
            let part_points = frame
                .points
                .iter()
                .filter(|p| matches!(p.label, PointLabel::Part(_)))
                .count();
            if part_points == scene.part_disc.len() {
                part_frames_complete += 1;
            }
            for p in &frame.points {
                assert!(camera
                    .intrinsics
                    .contains([f64::from(p.u_px), f64::from(p.v_px)]));
            }
        }
        let stats = sim.stats();
        assert_eq!(stats.frames, 2000);
        assert_eq!(stats.groups, 8000);
        let dropout_rate = stats.groups_dropped as f64 / stats.groups as f64;
        let outlier_rate = stats.outliers as f64 / stats.points as f64;
        assert!((0.08..0.12).contains(&dropout_rate), "{dropout_rate}");
        assert!((0.04..0.06).contains(&outlier_rate), "{outlier_rate}");
        // The part is dropped as a whole about 10 % of the time.
        let complete = f64::from(part_frames_complete) / 2000.0;
        assert!((0.85..0.95).contains(&complete), "{complete}");
    }

    #[test]
    fn pixel_noise_has_the_configured_sigma() {
        let (scene, camera) = scene_and_camera(5);
        let only_noise = CameraSettings {
            dropout_probability: 0.0,
            outlier_probability: 0.0,
            pixel_sigma_px: 0.5,
            ..settings()
        };
        let mut sim = CameraSim::new(camera.clone(), &only_noise, 3).unwrap();
        let [u0, v0] = camera.project(&scene.reference_disc).unwrap();
        let mut sum_sq = 0.0;
        let n = 2000;
        for k in 0..n {
            let frame = sim.render(k, 0.0, &scene);
            let p = frame
                .points
                .iter()
                .find(|p| p.label == PointLabel::Reference)
                .unwrap();
            sum_sq += (f64::from(p.u_px) - u0).powi(2) + (f64::from(p.v_px) - v0).powi(2);
        }
        let sigma = (sum_sq / (2.0 * f64::from(n))).sqrt();
        assert!((0.45..0.55).contains(&sigma), "{sigma}");
    }

    #[test]
    fn frames_arrive_after_their_latency_possibly_out_of_order() {
        let (scene, camera) = scene_and_camera(6);
        // 80 +- 20 ms, triggered every 10 ms: later exposures may overtake.
        let mut sim = CameraSim::new(camera, &settings(), 11).unwrap();
        let mut arrived: Vec<(u32, f64)> = Vec::new();
        let mut next_trigger = 0;
        for tick in 0..=2000u32 {
            let now = f64::from(tick) * 1e-3;
            if tick % 10 == 0 && tick < 1500 {
                sim.expose(next_trigger, now, &scene);
                next_trigger += 1;
            }
            for frame in sim.due_frames(now) {
                let exposed = frame.capture_time_us as f64 * 1e-6;
                let latency = now - exposed;
                assert!((0.060 - 1e-9..=0.101).contains(&latency), "{latency}");
                arrived.push((frame.trigger_id, latency));
            }
        }
        assert_eq!(arrived.len(), next_trigger as usize);
        assert_eq!(sim.in_flight(), 0);
        let out_of_order = arrived.windows(2).filter(|w| w[1].0 < w[0].0).count();
        assert!(out_of_order > 5, "{out_of_order}");
        let mean = arrived.iter().map(|a| a.1).sum::<f64>() / arrived.len() as f64;
        assert!((0.075..0.086).contains(&mean), "{mean}");
        // Nothing arrives before it is due.
        sim.expose(999, 5.0, &scene);
        assert!(sim.due_frames(5.059).is_empty());
        assert_eq!(sim.due_frames(5.2).len(), 1);
    }
}
