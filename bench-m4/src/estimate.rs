//! The pick's self-calibration estimates on a synthetic cell: a camera 1.5 m
//! over the disc and tilted 20 degrees, a three-feature part turning with the
//! disc at 5 Hz frames, the gripper's two marks seen at known base points,
//! pixel noise of 0.3 px. The calibrator is the pick's (`PickCalibrator`, 256
//! frames and 128 sightings) and is fed as the pick feeds it: frames until its
//! stores are full, an estimate adopted (the preliminary one), then as many
//! frames and sightings again, folded where they do not fit, and the final
//! estimate. `BENCH_M4_ONLY=estimate` runs only this, for the profile.

use cortex_m_semihosting::hprintln;
use heapless::Vec as HVec;
use nalgebra::{Rotation3, Vector3};
use shared::app::pick::PickCalibrator;
use shared::calibration::{CalibrationConfig, CalibrationError};
use shared::observation::{
    CameraIntrinsics, EffectorSighting, LogHeader, ObservationFrame, PixelPoint, LOG_VERSION,
};

use super::timer::DualTimer;

const FEATURES: [[f64; 3]; 3] = [[0.22, 0.05, 0.03], [0.28, 0.06, 0.03], [0.25, 0.11, 0.05]];
const F_PX: f64 = 300.0;
const CENTRE_PX: f64 = 128.0;
const REFERENCE_RADIUS_M: f64 = 0.4;
const NOISE_PX: f64 = 0.3;
/// 20 degrees: the pick's cells tilt their cameras 10 to 35 degrees (a
/// camera within a few degrees of the disc's axis leaves the f32 sums too
/// weak a pivot, and the refinement sums in f64: `refine::Sums`).
const TILT_RAD: f64 = 0.35;
const BASE_YAW: f64 = 0.3;
const BASE_TRANSLATION: [f64; 3] = [0.65, 0.1, -0.25];

/// The synthetic world: where the camera is, and noise.
struct World {
    camera_from_disc: Rotation3<f64>,
    camera_centre_disc: Vector3<f64>,
    state: u32,
}

impl World {
    fn new() -> Self {
        // Looking down (z of the camera along -z of the disc), tilted by
        // TILT_RAD about its y axis towards the disc's centre, 1.5 m above it.
        let disc_from_camera =
            Rotation3::from_axis_angle(&Vector3::x_axis(), core::f64::consts::PI)
                * Rotation3::from_axis_angle(&Vector3::y_axis(), TILT_RAD);
        Self {
            camera_from_disc: disc_from_camera.inverse(),
            camera_centre_disc: Vector3::new(0.02 - 1.5 * libm::tan(TILT_RAD), -0.03, 1.5),
            state: 0x1234_5678,
        }
    }

    /// Roughly normal noise of `NOISE_PX` (a sum of four uniforms).
    fn noise(&mut self) -> f64 {
        let mut sum = 0.0;
        for _ in 0..4 {
            self.state ^= self.state << 13;
            self.state ^= self.state >> 17;
            self.state ^= self.state << 5;
            sum += f64::from(self.state) / f64::from(u32::MAX) - 0.5;
        }
        sum * NOISE_PX * 1.732
    }

    fn pixel(&mut self, p_disc: Vector3<f64>) -> PixelPoint {
        let p_camera = self.camera_from_disc * (p_disc - self.camera_centre_disc);
        [
            F_PX * p_camera.x / p_camera.z + CENTRE_PX + self.noise(),
            F_PX * p_camera.y / p_camera.z + CENTRE_PX + self.noise(),
        ]
    }

    /// Frame `k` at 5 Hz, the disc turning at 0.5 rad/s; every other frame
    /// from `sightings_from` on shows the gripper.
    fn frame(&mut self, k: u32, sightings_from: u32) -> ObservationFrame {
        let theta = 0.1 * f64::from(k);
        let (s, c) = libm::sincos(theta);
        let rotate = |p: [f64; 3]| Vector3::new(c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]);
        let mut part = HVec::new();
        for feature in FEATURES {
            let pixel = self.pixel(rotate(feature));
            let _ = part.push(pixel);
        }
        let effector = (k >= sightings_from && k.is_multiple_of(2)).then(|| self.sighting(k));
        ObservationFrame {
            t_s: 0.2 * f64::from(k),
            conveyor_angle_rad: theta,
            center_px: Some(self.pixel(Vector3::zeros())),
            reference_px: Some(self.pixel(Vector3::new(
                REFERENCE_RADIUS_M * c,
                REFERENCE_RADIUS_M * s,
                0.0,
            ))),
            part_px: Some(part),
            effector,
            rim: None,
        }
    }

    /// The gripper's two marks, 8 cm apart, somewhere over the disc.
    fn sighting(&mut self, k: u32) -> EffectorSighting {
        let phase = 0.37 * f64::from(k);
        let (s, c) = libm::sincos(phase);
        let height = 0.1 + 0.05 * f64::from(k % 5);
        let first_disc = Vector3::new(0.2 * c, 0.2 * s, height);
        let second_disc = first_disc + Vector3::new(0.08 * s, -0.08 * c, 0.0);
        let base_from_disc = Rotation3::from_axis_angle(&Vector3::z_axis(), BASE_YAW);
        let translation = Vector3::from(BASE_TRANSLATION);
        let to_base = |p: Vector3<f64>| {
            let p = base_from_disc * p + translation;
            [p.x, p.y, p.z]
        };
        EffectorSighting {
            px: [self.pixel(first_disc), self.pixel(second_disc)],
            base_m: [to_base(first_disc), to_base(second_disc)],
        }
    }
}

/// Instructions of the preliminary and the final estimate (printed); `None`
/// when the calibrator refuses the synthetic cell.
pub fn estimates(timer: &DualTimer) -> Option<()> {
    let header = LogHeader {
        version: LOG_VERSION,
        camera: CameraIntrinsics {
            width: 256,
            height: 256,
            f_px: F_PX,
            cx: CENTRE_PX,
            cy: CENTRE_PX,
        },
        reference_radius_m: REFERENCE_RADIUS_M,
        part_feature_count: FEATURES.len(),
        disc_radius_m: None,
    };
    let mut world = World::new();
    let mut calibrator = reported(
        PickCalibrator::new(&header, CalibrationConfig::default()),
        "the calibrator refused the cell",
    )?;
    let mut k = 0;
    while !calibrator.about_to_thin() {
        let frame = world.frame(k, 100);
        reported(calibrator.push(&frame), "a frame was refused")?;
        k += 1;
    }
    let mut adopted = false;
    let preliminary = timer.measure(1, || adopted = calibrator.estimate_and_adopt());
    if !adopted {
        hprintln!("  estimate: the preliminary estimate failed");
        return None;
    }
    for _ in 0..400 {
        let frame = world.frame(k, 0);
        reported(calibrator.push(&frame), "a frame was refused")?;
        k += 1;
    }
    let mut outcome = None;
    let last = timer.measure(1, || outcome = Some(calibrator.estimate()));
    let result = reported(outcome?, "the final estimate failed")?;
    let camera = result.camera.disc_from_camera.translation_m;
    let part = result.part.position_m;
    hprintln!(
        "  pick calibrator, {} frames: preliminary estimate {:>10}, final {:>10}",
        k,
        preliminary,
        last
    );
    hprintln!(
        "    camera centre ({:.4}, {:.4}, {:.4}) m, part mean ({:.4}, {:.4}, {:.4}) m, rms {:.3} px",
        camera[0],
        camera[1],
        camera[2],
        part[0],
        part[1],
        part[2],
        result.quality.rms_reprojection_px
    );
    Some(())
}

/// The value, or `None` with `what` and the error printed.
fn reported<T>(result: Result<T, CalibrationError>, what: &str) -> Option<T> {
    result
        .map_err(|error| hprintln!("  estimate: {}: {:?}", what, error))
        .ok()
}
