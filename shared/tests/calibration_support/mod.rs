//! Synthetic workcell for the calibration tests: a seeded random camera above the disc,
//! a part, a robot base, and a pinhole projector that follows the spec's conventions.
#![allow(dead_code)]

use nalgebra::{Matrix3, Rotation3, Vector2, Vector3};
use shared::observation::{
    CalibrationResult, CameraIntrinsics, EffectorSighting, LogHeader, ObservationFrame, PixelPoint,
    LOG_VERSION, MAX_PART_FEATURES,
};

/// SplitMix64: small, seedable, good enough for test scenarios.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn uniform(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.unit()
    }
    pub fn gaussian(&mut self) -> f64 {
        let u1 = self.unit().max(1e-300);
        let u2 = self.unit();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
    pub fn chance(&mut self, probability: f64) -> bool {
        self.unit() < probability
    }
}

pub fn rz(angle: f64) -> Matrix3<f64> {
    let (s, c) = angle.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// The true workcell.
#[derive(Debug, Clone)]
pub struct Workcell {
    pub intrinsics: CameraIntrinsics,
    pub disc_from_camera: Rotation3<f64>,
    pub camera_centre_disc: Vector3<f64>,
    pub reference_radius_m: f64,
    pub features_rotating: Vec<Vector3<f64>>,
    pub base_yaw: f64,
    pub base_translation: Vector3<f64>,
}

/// How the observations are corrupted and how much is recorded.
#[derive(Debug, Clone, Copy)]
pub struct Scenario {
    pub frames: usize,
    /// Total conveyor rotation over the run (rad).
    pub rotation_rad: f64,
    pub pixel_sigma: f64,
    pub dropout: f64,
    pub outlier: f64,
    pub effector_frames: usize,
    pub feature_count: usize,
    /// Different heights per feature.
    pub non_planar: bool,
    /// The calibration is told the disc's height in the base frame (experiment 2).
    pub known_height: bool,
}

impl Scenario {
    pub fn exact() -> Self {
        Self {
            frames: 300,
            rotation_rad: 2.0 * std::f64::consts::PI,
            pixel_sigma: 0.0,
            dropout: 0.0,
            outlier: 0.0,
            effector_frames: 10,
            feature_count: 3,
            non_planar: false,
            known_height: false,
        }
    }
    /// The paper's setting: 0.5 px, 256x256, 300 frames over one revolution, 5 % dropouts.
    pub fn paper() -> Self {
        Self {
            pixel_sigma: 0.5,
            dropout: 0.05,
            ..Self::exact()
        }
    }
}

impl Workcell {
    pub fn random(rng: &mut Rng, feature_count: usize, non_planar: bool) -> Self {
        let f_px = rng.uniform(200.0, 300.0);
        let intrinsics = CameraIntrinsics {
            width: 256,
            height: 256,
            f_px,
            cx: 127.5,
            cy: 127.5,
        };
        let height = rng.uniform(1.8, 3.0);
        let tilt = rng.uniform(0.0, 35f64.to_radians());
        let azimuth = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        let look_at = Vector3::new(rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), 0.0);
        let direction = Vector3::new(
            tilt.sin() * azimuth.cos(),
            tilt.sin() * azimuth.sin(),
            tilt.cos(),
        );
        let camera_centre_disc = look_at + direction * (height / tilt.cos());
        let z_axis = (look_at - camera_centre_disc).normalize();
        let helper = if z_axis.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let x0 = helper.cross(&z_axis).normalize();
        let y0 = z_axis.cross(&x0);
        let roll = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        let x_axis = x0 * roll.cos() + y0 * roll.sin();
        let y_axis = z_axis.cross(&x_axis);
        let disc_from_camera =
            Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x_axis, y_axis, z_axis]));
        let centre_r = rng.uniform(0.15, 0.33);
        let centre_a = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        let centre = Vector3::new(centre_r * centre_a.cos(), centre_r * centre_a.sin(), 0.0);
        let base_height = rng.uniform(0.02, 0.1);
        let mut features_rotating = Vec::new();
        let part_yaw = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        for i in 0..feature_count {
            let angle = part_yaw + i as f64 * 2.0 * std::f64::consts::PI / feature_count as f64;
            let radius = rng.uniform(0.03, 0.06);
            let h = if non_planar {
                rng.uniform(0.02, 0.1)
            } else {
                base_height
            };
            features_rotating
                .push(centre + Vector3::new(radius * angle.cos(), radius * angle.sin(), h));
        }
        let base_yaw = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        let base_bearing = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        let base_distance = rng.uniform(0.8, 1.2);
        let base_translation = Vector3::new(
            base_distance * base_bearing.cos(),
            base_distance * base_bearing.sin(),
            rng.uniform(-0.3, 0.3),
        );
        Self {
            intrinsics,
            disc_from_camera,
            camera_centre_disc,
            reference_radius_m: 0.4,
            features_rotating,
            base_yaw,
            base_translation,
        }
    }

    pub fn header(&self) -> LogHeader {
        LogHeader {
            version: LOG_VERSION,
            camera: self.intrinsics,
            reference_radius_m: self.reference_radius_m,
            part_feature_count: self.features_rotating.len(),
            disc_radius_m: None,
        }
    }

    /// Exact pixel of a disc-frame point, `None` behind the camera or outside the image.
    pub fn project(&self, p_disc: &Vector3<f64>) -> Option<Vector2<f64>> {
        let p_camera = self.disc_from_camera.inverse() * (p_disc - self.camera_centre_disc);
        if p_camera.z <= 1e-6 {
            return None;
        }
        let k = &self.intrinsics;
        let pixel = Vector2::new(
            k.f_px * p_camera.x / p_camera.z + k.cx,
            k.f_px * p_camera.y / p_camera.z + k.cy,
        );
        k.contains([pixel.x, pixel.y]).then_some(pixel)
    }

    pub fn disc_from_base(&self, p_base: &Vector3<f64>) -> Vector3<f64> {
        rz(-self.base_yaw) * (p_base - self.base_translation)
    }

    pub fn base_from_disc(&self, p_disc: &Vector3<f64>) -> Vector3<f64> {
        rz(self.base_yaw) * p_disc + self.base_translation
    }

    /// Records a run: `scenario.frames` frames with theta growing over `rotation_rad`.
    pub fn record(&self, rng: &mut Rng, scenario: &Scenario) -> Vec<ObservationFrame> {
        // Effector sightings spread over the run.
        let mut effector_frames = Vec::new();
        while effector_frames.len() < scenario.effector_frames.min(scenario.frames) {
            let k = (rng.unit() * scenario.frames as f64) as usize;
            if !effector_frames.contains(&k) {
                effector_frames.push(k);
            }
        }
        let mut frames = Vec::new();
        for k in 0..scenario.frames {
            let theta = scenario.rotation_rad * k as f64 / scenario.frames as f64;
            let mut frame = self.frame_at(rng, scenario, theta, effector_frames.contains(&k));
            frame.t_s = k as f64 * 0.1;
            frames.push(frame);
        }
        frames
    }

    /// One frame at conveyor angle `theta` (t_s 0), with a sighting when
    /// `scenario.effector_frames` is not zero.
    pub fn record_at(&self, rng: &mut Rng, scenario: &Scenario, theta: f64) -> ObservationFrame {
        self.frame_at(rng, scenario, theta, scenario.effector_frames > 0)
    }

    fn frame_at(
        &self,
        rng: &mut Rng,
        scenario: &Scenario,
        theta: f64,
        with_effector: bool,
    ) -> ObservationFrame {
        let detect = |rng: &mut Rng, pixel: Option<Vector2<f64>>| -> Option<PixelPoint> {
            let pixel = pixel?;
            if rng.chance(scenario.dropout) {
                return None;
            }
            if rng.chance(scenario.outlier) {
                return Some([rng.uniform(0.0, 255.0), rng.uniform(0.0, 255.0)]);
            }
            let noisy = [
                pixel.x + scenario.pixel_sigma * rng.gaussian(),
                pixel.y + scenario.pixel_sigma * rng.gaussian(),
            ];
            self.intrinsics.contains(noisy).then_some(noisy)
        };
        {
            let (s, c) = theta.sin_cos();
            let center_px = detect(rng, self.project(&Vector3::zeros()));
            let reference_px = detect(
                rng,
                self.project(&Vector3::new(
                    self.reference_radius_m * c,
                    self.reference_radius_m * s,
                    0.0,
                )),
            );
            let mut part: heapless::Vec<PixelPoint, MAX_PART_FEATURES> = heapless::Vec::new();
            let mut all_seen = !rng.chance(scenario.dropout);
            for feature in &self.features_rotating {
                let exact = self.project(&(rz(theta) * feature));
                let seen = detect(rng, exact).or_else(|| {
                    all_seen = false;
                    None
                });
                if let Some(p) = seen {
                    let _ = part.push(p);
                }
            }
            let part_px = (all_seen && part.len() == self.features_rotating.len()).then_some(part);
            let effector = if with_effector {
                self.effector_sighting(rng, scenario)
            } else {
                None
            };
            ObservationFrame {
                t_s: 0.0,
                conveyor_angle_rad: theta,
                center_px,
                reference_px,
                part_px,
                effector,
                rim: None,
            }
        }
    }

    /// Two points 0.1 m apart, 0.05-0.5 m above the disc, in view.
    pub fn effector_sighting(
        &self,
        rng: &mut Rng,
        scenario: &Scenario,
    ) -> Option<EffectorSighting> {
        for _ in 0..1000 {
            let r = rng.uniform(0.0, 0.45);
            let a = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
            let p0 = Vector3::new(r * a.cos(), r * a.sin(), rng.uniform(0.05, 0.5));
            let direction =
                Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()).normalize();
            let p1 = p0 + direction * 0.1;
            if !(0.05..=0.5).contains(&p1.z) {
                continue;
            }
            let (Some(q0), Some(q1)) = (self.project(&p0), self.project(&p1)) else {
                continue;
            };
            let noisy = |rng: &mut Rng, q: Vector2<f64>| {
                [
                    q.x + scenario.pixel_sigma * rng.gaussian(),
                    q.y + scenario.pixel_sigma * rng.gaussian(),
                ]
            };
            let b0 = self.base_from_disc(&p0);
            let b1 = self.base_from_disc(&p1);
            return Some(EffectorSighting {
                px: [noisy(rng, q0), noisy(rng, q1)],
                base_m: [[b0.x, b0.y, b0.z], [b1.x, b1.y, b1.z]],
            });
        }
        None
    }
}

/// Errors of an estimate against the truth.
#[derive(Debug, Clone, Copy, Default)]
pub struct Errors {
    pub camera_height_m: f64,
    pub camera_position_m: f64,
    pub camera_rotation_rad: f64,
    pub feature_m: f64,
    pub part_position_m: f64,
    pub part_yaw_rad: f64,
    pub base_translation_m: f64,
    pub base_yaw_rad: f64,
}

fn angle_difference(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * std::f64::consts::PI);
    d.min(2.0 * std::f64::consts::PI - d)
}

impl Errors {
    pub fn of(result: &CalibrationResult, truth: &Workcell) -> Self {
        let t = result.camera.disc_from_camera.translation_m;
        let r = result.camera.disc_from_camera.rotation;
        let rotation = Matrix3::from_fn(|i, j| r[i][j]);
        let relative = rotation.transpose() * truth.disc_from_camera.matrix();
        let camera_rotation_rad = Rotation3::from_matrix_unchecked(relative).angle();
        let mut feature_m: f64 = 0.0;
        let mut mean = Vector3::zeros();
        for (estimate, true_point) in result.part.features_m.iter().zip(&truth.features_rotating) {
            let e = Vector3::new(estimate[0], estimate[1], estimate[2]);
            feature_m = feature_m.max((e - true_point).norm());
            mean += true_point;
        }
        mean /= truth.features_rotating.len() as f64;
        let p = result.part.position_m;
        let f0 = truth.features_rotating[0];
        let f1 = truth.features_rotating[1];
        let true_yaw = (f1.y - f0.y).atan2(f1.x - f0.x);
        let bt = result.base_from_disc.translation_m;
        Self {
            camera_height_m: (result.camera.height_m - truth.camera_centre_disc.z).abs(),
            camera_position_m: (Vector3::new(t[0], t[1], t[2]) - truth.camera_centre_disc).norm(),
            camera_rotation_rad,
            feature_m,
            part_position_m: (Vector3::new(p[0], p[1], p[2]) - mean).norm(),
            part_yaw_rad: angle_difference(result.part.yaw_rad, true_yaw),
            base_translation_m: (Vector3::new(bt[0], bt[1], bt[2]) - truth.base_translation).norm(),
            base_yaw_rad: angle_difference(result.base_from_disc.yaw_rad, truth.base_yaw),
        }
    }

    pub fn max_metres(&self) -> f64 {
        self.camera_height_m
            .max(self.camera_position_m)
            .max(self.feature_m)
            .max(self.part_position_m)
            .max(self.base_translation_m)
    }

    pub fn max_radians(&self) -> f64 {
        self.camera_rotation_rad
            .max(self.part_yaw_rad)
            .max(self.base_yaw_rad)
    }
}
