//! The view monitor: after the final self-calibration the pick runs on the
//! encoders alone (Eq 1 with the conveyor angle), so nothing else would notice
//! a camera knocked out of place or an encoder that missed counts. The camera
//! keeps watching the disc; each frame's centre and reference mark are
//! predicted from the calibrated camera at the conveyor angle latched at the
//! frame's trigger and compared with what the camera saw.
//!
//! - Camera moved: the centre, or the reference mark across its circle, is
//!   off by more than the residual limit in `strikes` frames in a row (one gross
//!   outlier is one strike, not a fault).
//! - Conveyor slip: the reference mark's offset along its circle, as a
//!   conveyor angle, exceeds what a grasp tolerates, in the median of the last
//!   few frames (robust to an outlier), twice in a row. The offset is absolute:
//!   counts missed while the calibrator gathered its frames leave the fit a
//!   compromise between the angles before and after, and that shows too.

use nalgebra::{Matrix3, Vector3};

use super::estimate::CellEstimate;
use super::handoff::DiscView;
use crate::observation::CameraIntrinsics;
use crate::protocol::FaultCause;

/// Frames in the median of the angle offsets.
const SLIP_WINDOW: usize = 5;
/// Angle step for the reference mark's image tangent, rad.
const TANGENT_STEP_RAD: f32 = 1e-3;

/// When the monitor calls a frame inconsistent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewLimits {
    /// Largest distance of the centre (or of the reference across its circle)
    /// from its prediction, px.
    pub residual_px: f32,
    /// Consecutive inconsistent frames that mean the camera moved.
    pub strikes: u8,
    /// Largest movement of the part along its circle a slip may cause, m.
    pub slip_tolerance_m: f32,
}

/// The camera model the monitor predicts with, in the control loop's f32.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Projector {
    camera_from_disc: Matrix3<f32>,
    camera_centre_disc: Vector3<f32>,
    f_px: f32,
    cx: f32,
    cy: f32,
    reference_radius_m: f32,
}

impl Projector {
    fn project(&self, p_disc: &Vector3<f32>) -> Option<[f32; 2]> {
        let p_camera = self.camera_from_disc * (p_disc - self.camera_centre_disc);
        (p_camera.z > 1e-3).then(|| {
            [
                self.f_px * p_camera.x / p_camera.z + self.cx,
                self.f_px * p_camera.y / p_camera.z + self.cy,
            ]
        })
    }

    /// The reference mark at conveyor angle `theta` (disc_from_rotating = Rz(theta)).
    fn reference(&self, theta: f32) -> Option<[f32; 2]> {
        let (s, c) = crate::control::trig::sin_cos(theta);
        let r = self.reference_radius_m;
        self.project(&Vector3::new(r * c, r * s, 0.0))
    }
}

/// What the last checked frame showed (for telemetry and tests).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ViewResiduals {
    /// How far the disc's centre was from where the calibration puts it, pixels.
    pub centre_px: f32,
    /// Across the reference mark's circle.
    pub reference_normal_px: f32,
    /// Along it, as a conveyor angle (median of the last frames).
    pub slip_rad: f32,
}

/// The monitor's state: armed with a calibrated camera, or idle.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewMonitor {
    limits: ViewLimits,
    projector: Option<Projector>,
    slip_limit_rad: f32,
    /// Image noise (1-sigma, px) the calibration measured from its residuals:
    /// the slip limit never goes below what noise alone could reach.
    pixel_sigma_px: f32,
    camera_strikes: u8,
    slip_strikes: u8,
    recent: [f32; SLIP_WINDOW],
    recent_count: usize,
    last: ViewResiduals,
    frames_checked: u32,
}

impl ViewMonitor {
    /// A monitor with `limits`, not armed yet.
    pub fn new(limits: ViewLimits) -> Self {
        Self {
            limits,
            projector: None,
            slip_limit_rad: f32::INFINITY,
            pixel_sigma_px: 0.0,
            camera_strikes: 0,
            slip_strikes: 0,
            recent: [0.0; SLIP_WINDOW],
            recent_count: 0,
            last: ViewResiduals::default(),
            frames_checked: 0,
        }
    }

    /// Starts watching with the final calibration (and forgets any earlier one).
    pub fn arm(
        &mut self,
        estimate: &CellEstimate,
        camera: &CameraIntrinsics,
        reference_radius_m: f32,
    ) {
        let limits = self.limits;
        *self = Self::new(limits);
        let part_radius_m = estimate.part_rotating.xy().norm().max(0.05);
        self.slip_limit_rad = limits.slip_tolerance_m / part_radius_m;
        self.pixel_sigma_px = estimate.pixel_sigma_px;
        self.projector = Some(Projector {
            camera_from_disc: estimate.disc_from_camera.transpose().cast::<f32>(),
            camera_centre_disc: estimate.camera_centre_disc.cast::<f32>(),
            f_px: camera.f_px as f32,
            cx: camera.cx as f32,
            cy: camera.cy as f32,
            reference_radius_m,
        });
    }

    /// What the last checked frame showed.
    pub fn last(&self) -> ViewResiduals {
        self.last
    }

    /// Frames checked since it was armed.
    pub fn frames_checked(&self) -> u32 {
        self.frames_checked
    }

    /// Checks one frame; a fault once the evidence is conclusive.
    pub fn check(&mut self, view: &DiscView) -> Option<FaultCause> {
        let projector = self.projector?;
        self.frames_checked = self.frames_checked.saturating_add(1);
        let distance = |a: [f32; 2], b: [f32; 2]| libm::hypotf(a[0] - b[0], a[1] - b[1]);
        let mut checked = false;
        let mut inconsistent = false;
        if let (Some(seen), Some(predicted)) =
            (view.centre_px, projector.project(&Vector3::zeros()))
        {
            let residual = distance(seen, predicted);
            self.last.centre_px = residual;
            checked = true;
            inconsistent |= residual > self.limits.residual_px;
        }
        let along = view.reference_px.and_then(|seen| {
            let predicted = projector.reference(view.theta)?;
            let ahead = projector.reference(view.theta + TANGENT_STEP_RAD)?;
            let tangent = [
                (ahead[0] - predicted[0]) / TANGENT_STEP_RAD,
                (ahead[1] - predicted[1]) / TANGENT_STEP_RAD,
            ];
            let tangent_sq = tangent[0] * tangent[0] + tangent[1] * tangent[1];
            if tangent_sq.is_nan() || tangent_sq <= 1e-6 {
                return None;
            }
            let error = [seen[0] - predicted[0], seen[1] - predicted[1]];
            let along_rad = (error[0] * tangent[0] + error[1] * tangent[1]) / tangent_sq;
            let normal_px = libm::fabsf(error[0] * tangent[1] - error[1] * tangent[0])
                / libm::sqrtf(tangent_sq);
            Some((along_rad, normal_px, libm::sqrtf(tangent_sq)))
        });
        let mut slip_evidence = None;
        if let Some((along_rad, normal_px, tangent_px_per_rad)) = along {
            self.last.reference_normal_px = normal_px;
            checked = true;
            if normal_px > self.limits.residual_px {
                inconsistent = true;
            } else {
                // Noise alone moves one offset by sigma / |tangent|; the median of
                // five has about 0.55 of that spread, and stays within 3 (over 5
                // of its own sigmas).
                let noise_floor = 3.0 * self.pixel_sigma_px / tangent_px_per_rad;
                slip_evidence = Some((along_rad, noise_floor));
            }
        }
        if !checked {
            return None;
        }
        self.camera_strikes = if inconsistent {
            self.camera_strikes.saturating_add(1)
        } else {
            0
        };
        if self.camera_strikes >= self.limits.strikes.max(1) {
            return Some(FaultCause::CameraMoved);
        }
        let (along_rad, noise_floor) = slip_evidence?;
        if let Some(slot) = self.recent.get_mut(self.recent_count % SLIP_WINDOW) {
            *slot = along_rad;
        }
        self.recent_count = self.recent_count.saturating_add(1);
        if self.recent_count < SLIP_WINDOW {
            return None;
        }
        let mut window = self.recent;
        window.sort_unstable_by(f32::total_cmp);
        let median = window.get(SLIP_WINDOW / 2).copied().unwrap_or(0.0);
        self.last.slip_rad = median;
        let limit = self.slip_limit_rad.max(noise_floor);
        self.slip_strikes = if libm::fabsf(median) > limit {
            self.slip_strikes.saturating_add(1)
        } else {
            0
        };
        (self.slip_strikes >= 2).then_some(FaultCause::ConveyorSlip)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::EstimateUncertainty;
    use crate::observation::{
        BaseFromDisc, CalibrationQuality, CalibrationResult, CameraEstimate, PartEstimate,
        RigidTransform,
    };

    const L: f32 = 0.4;

    fn camera() -> CameraIntrinsics {
        CameraIntrinsics {
            width: 256,
            height: 256,
            f_px: 300.0,
            cx: 128.0,
            cy: 128.0,
        }
    }

    /// A camera 2 m straight above the disc centre, looking down.
    fn estimate() -> CellEstimate {
        let result = CalibrationResult {
            camera: CameraEstimate {
                height_m: 2.0,
                disc_from_camera: RigidTransform {
                    rotation: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
                    translation_m: [0.0, 0.0, 2.0],
                },
            },
            base_from_disc: BaseFromDisc {
                yaw_rad: 0.0,
                translation_m: [0.7, 0.0, -0.3],
            },
            part: PartEstimate {
                position_m: [0.3, 0.0, 0.04],
                yaw_rad: 0.0,
                features_m: Default::default(),
            },
            quality: CalibrationQuality {
                frames_used: 100,
                rms_reprojection_px: 0.5,
                effector_frames_used: 8,
                outliers_rejected: 0,
                pixel_sigma_px: 0.5,
            },
        };
        CellEstimate::new(&result, &EstimateUncertainty::default(), 0)
    }

    fn monitor() -> ViewMonitor {
        let mut monitor = ViewMonitor::new(ViewLimits {
            residual_px: 6.0,
            strikes: 4,
            slip_tolerance_m: 0.003,
        });
        monitor.arm(&estimate(), &camera(), L);
        monitor
    }

    /// What the camera sees at true angle `theta_true` (the encoder says `theta`).
    fn view(theta: f32, theta_true: f32, shift_px: f32) -> DiscView {
        let c = 128.0;
        let k = 300.0 / 2.0 * L;
        DiscView {
            theta,
            centre_px: Some([c + shift_px, c]),
            reference_px: Some([
                c + k * theta_true.cos() + shift_px,
                c - k * theta_true.sin(),
            ]),
            part_seen: true,
        }
    }

    #[test]
    fn a_consistent_view_never_faults_and_reads_zero() {
        let mut monitor = monitor();
        for k in 0..200 {
            let theta = k as f32 * 0.1;
            assert_eq!(monitor.check(&view(theta, theta, 0.0)), None);
        }
        let last = monitor.last();
        assert!(
            last.centre_px < 1e-3 && last.reference_normal_px < 1e-2,
            "{last:?}"
        );
        assert!(last.slip_rad.abs() < 1e-4, "{last:?}");
    }

    #[test]
    fn a_moved_camera_faults_after_the_strikes_and_one_outlier_does_not() {
        let mut monitor = monitor();
        assert_eq!(monitor.check(&view(0.0, 0.0, 0.0)), None);
        assert_eq!(monitor.check(&view(0.1, 0.1, 30.0)), None, "one outlier");
        assert_eq!(monitor.check(&view(0.2, 0.2, 0.0)), None);
        let faults: Vec<_> = (0..4)
            .map(|k| monitor.check(&view(0.3 + 0.1 * k as f32, 0.3 + 0.1 * k as f32, 20.0)))
            .collect();
        assert_eq!(faults, [None, None, None, Some(FaultCause::CameraMoved)]);
    }

    #[test]
    fn missed_counts_show_as_a_slip_and_a_small_bias_does_not() {
        let mut monitor = monitor();
        // A calibration's small angle bias (0.005 rad, 1.5 mm at the part) is no slip.
        for k in 0..20 {
            let theta = k as f32 * 0.1;
            assert_eq!(monitor.check(&view(theta, theta + 0.005, 0.0)), None);
        }
        // The encoder then loses 0.04 rad (26 counts of 4096): 12 mm at the part.
        let mut fault = None;
        for k in 20..40 {
            let theta = k as f32 * 0.1;
            fault = fault.or(monitor.check(&view(theta - 0.04, theta + 0.005, 0.0)));
        }
        assert_eq!(fault, Some(FaultCause::ConveyorSlip));
    }

    #[test]
    fn an_idle_monitor_checks_nothing() {
        let mut monitor = ViewMonitor::new(ViewLimits {
            residual_px: 6.0,
            strikes: 1,
            slip_tolerance_m: 0.003,
        });
        assert_eq!(monitor.check(&view(0.0, 1.0, 50.0)), None);
        assert_eq!(monitor.frames_checked(), 0);
    }
}
