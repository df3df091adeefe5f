//! Beyond the paper: the disc's rim as an observation of the camera's pose.
//!
//! The paper reads the camera's tilt and height from the ellipse one
//! reference point traces (Section 2, `H = f L / l`); a mark's centre read a
//! tenth of a pixel off in every frame biases `l`, and no number of frames
//! averages that away. The rim is a circle of known radius on the same plane,
//! measured each frame from hundreds of pixels ([`crate::detection::rim`]),
//! so it pins the same tilt and scale from its own light.
//!
//! The frames' rims are averaged in fixed memory ([`RimAccumulator`]: the
//! mean of each frame's ellipse as `(centre, Q)`, smooth where the ellipse's
//! axes and angle are not, for a near-circle). The refinement
//! ([`super::refine`]) then asks of the camera that it project the circle of
//! radius `disc_radius_m` onto that mean ellipse: [`RIM_POINTS`] points of it,
//! each's signed distance from the predicted ellipse a residual on the camera
//! alone, weighed by the mean's own spread with a floor
//! ([`RIM_FLOOR_PX`]) for what averaging cannot remove.

use nalgebra::{Matrix3, SMatrix, Vector2, Vector3};

use super::model::OtherBlock;
use super::model::WorkcellModel;
use super::normal_blocks::{Increment, NormalBlocks, CAMERA_PARAMETERS};
use super::pinhole::Pinhole;
use crate::detection::rim::Ellipse;
use crate::observation::RimObservation;

/// Points of the mean ellipse the refinement asks the camera to explain:
/// more than its five parameters, evenly round it.
pub const RIM_POINTS: usize = 16;
/// Error of the mean rim that no number of frames averages away, px: the
/// measured bias of the rim's fit is about a thousandth of a pixel
/// (docs/vision.md), three times that is taken.
pub const RIM_FLOOR_PX: f64 = 0.003;
/// A frame's rim farther than this from the mean so far is not averaged
/// (the camera bumped, a wrong band), px.
pub const RIM_GATE_PX: f64 = 0.3;
/// Frames averaged before the gate applies.
const GATE_AFTER: u32 = 5;
/// Finite-difference steps of the camera's rotation (rad) and centre (m).
const ROTATION_STEP: f64 = 1e-7;
const CENTRE_STEP_M: f64 = 1e-7;
/// Cost of a camera that does not see the rim as an ellipse (the circle
/// reaching behind it): far above any fit's.
const UNSEEN_COST: f64 = 1e12;

/// `(centre u, centre v, q_uu, q_uv, q_vv)`, the ellipse
/// `(p - c)^T Q (p - c) = 1`.
type Smooth = [f64; 5];

fn smooth(ellipse: &Ellipse) -> Smooth {
    let m = ellipse.matrix();
    [
        ellipse.centre_px[0],
        ellipse.centre_px[1],
        m.m11,
        m.m12,
        m.m22,
    ]
}

fn ellipse_of(z: &Smooth) -> Option<Ellipse> {
    let [cx, cy, quu, quv, qvv] = *z;
    let lu = -(quu * cx + quv * cy);
    let lv = -(quv * cx + qvv * cy);
    let g = quu * cx * cx + 2.0 * quv * cx * cy + qvv * cy * cy - 1.0;
    Ellipse::from_matrix(&Matrix3::new(quu, quv, lu, quv, qvv, lv, lu, lv, g))
}

/// Why a frame's rim was not taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RimRefusal {
    /// A number is not finite, an axis or the sigma not positive.
    Invalid,
    /// Farther than [`RIM_GATE_PX`] from the mean so far.
    Gated,
}

/// The mean of the frames' rims, in fixed memory.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RimAccumulator {
    sum: Smooth,
    sum_variance: f64,
    count: u32,
    gated: u32,
}

impl RimAccumulator {
    /// Frames averaged.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Frames gated away.
    pub fn gated(&self) -> u32 {
        self.gated
    }

    /// The mean ellipse so far.
    pub fn mean(&self) -> Option<Ellipse> {
        if self.count == 0 {
            return None;
        }
        let n = f64::from(self.count);
        ellipse_of(&self.sum.map(|s| s / n))
    }

    /// Takes one frame's rim, or says why not.
    pub fn add(&mut self, rim: &RimObservation) -> Result<(), RimRefusal> {
        let ellipse = Ellipse {
            centre_px: rim.centre_px,
            semi_axes_px: rim.semi_axes_px,
            angle_rad: rim.angle_rad,
        };
        if !ellipse.is_valid() || !rim.sigma_px.is_finite() || rim.sigma_px <= 0.0 {
            return Err(RimRefusal::Invalid);
        }
        if self.count >= GATE_AFTER {
            let mean = self.mean().ok_or(RimRefusal::Invalid)?;
            let far = (0..8).any(|k| {
                let p = ellipse.point_at(core::f64::consts::TAU * f64::from(k) / 8.0);
                mean.locate(p)
                    .is_none_or(|q| q.distance_px(1.0).abs() > RIM_GATE_PX)
            });
            if far {
                self.gated = self.gated.saturating_add(1);
                return Err(RimRefusal::Gated);
            }
        }
        for (s, z) in self.sum.iter_mut().zip(smooth(&ellipse)) {
            *s += z;
        }
        self.sum_variance += rim.sigma_px * rim.sigma_px;
        self.count = self.count.saturating_add(1);
        Ok(())
    }

    /// What the refinement needs: the mean's points and their weight, for a
    /// rim of radius `disc_radius_m`.
    pub fn summary(&self, disc_radius_m: f64) -> Option<RimSummary> {
        let mean = self.mean()?;
        let n = f64::from(self.count);
        // Each point's distance carries the mean radius's variance spread
        // over the ellipse's five parameters: RIM_POINTS / 5 of it a point.
        let variance =
            (RIM_POINTS as f64 / 5.0) * (self.sum_variance / n) / n + RIM_FLOOR_PX * RIM_FLOOR_PX;
        let points = core::array::from_fn(|k| {
            mean.point_at(core::f64::consts::TAU * k as f64 / RIM_POINTS as f64)
        });
        (disc_radius_m.is_finite() && disc_radius_m > 0.0).then_some(RimSummary {
            points,
            weight_per_px2: 1.0 / variance,
            disc_radius_m,
        })
    }
}

/// The mean rim as the refinement weighs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RimSummary {
    /// Points of the mean ellipse, undistorted px.
    pub points: [[f64; 2]; RIM_POINTS],
    /// Inverse variance of each point's distance, 1/px^2.
    pub weight_per_px2: f64,
    /// The rim's radius, m.
    pub disc_radius_m: f64,
}

/// The image of the circle of `radius_m` about the disc's centre on its top
/// (`z = 0`) under `model`'s camera: `C = H^-T diag(1, 1, -r^2) H^-1`, `H`
/// the plane's homography `K [r1 r2 t]` (camera from disc).
pub fn predicted_rim(model: &WorkcellModel, pinhole: &Pinhole, radius_m: f64) -> Option<Ellipse> {
    let camera_from_disc = model.disc_from_camera.inverse();
    let rotation = camera_from_disc.matrix();
    let t = -(rotation * model.camera_centre_disc);
    let k = Matrix3::new(
        pinhole.f_px,
        0.0,
        pinhole.cx,
        0.0,
        pinhole.f_px,
        pinhole.cy,
        0.0,
        0.0,
        1.0,
    );
    let mut plane = Matrix3::zeros();
    plane.set_column(0, &rotation.column(0));
    plane.set_column(1, &rotation.column(1));
    plane.set_column(2, &t);
    let inverse = (k * plane).try_inverse()?;
    let circle = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -radius_m * radius_m));
    Ellipse::from_matrix(&(inverse.transpose() * circle * inverse))
}

impl RimSummary {
    /// Each point's signed distance from the predicted rim, px.
    pub fn residuals(&self, model: &WorkcellModel, pinhole: &Pinhole) -> Option<[f64; RIM_POINTS]> {
        let predicted = predicted_rim(model, pinhole, self.disc_radius_m)?;
        let mut out = [0.0; RIM_POINTS];
        for (slot, point) in out.iter_mut().zip(&self.points) {
            *slot = predicted.locate(*point)?.distance_px(1.0);
        }
        Some(out)
    }

    /// Its share of the refinement's cost, in the units of a pixel residual
    /// of per-axis noise `sigma_px` (`|r|^2 / 2` for each point).
    pub fn cost(&self, model: &WorkcellModel, pinhole: &Pinhole, sigma_px: f64) -> f64 {
        match self.residuals(model, pinhole) {
            Some(r) => {
                0.5 * self.weight_per_px2
                    * sigma_px
                    * sigma_px
                    * r.iter().map(|v| v * v).sum::<f64>()
            }
            None => UNSEEN_COST,
        }
    }

    /// Adds its Gauss-Newton terms (camera block only) to `blocks`.
    pub fn add_to(
        &self,
        blocks: &mut NormalBlocks,
        model: &WorkcellModel,
        pinhole: &Pinhole,
        sigma_px: f64,
    ) {
        let Some(at) = self.residuals(model, pinhole) else {
            return;
        };
        let mut jacobian = SMatrix::<f64, RIM_POINTS, CAMERA_PARAMETERS>::zeros();
        for j in 0..CAMERA_PARAMETERS {
            let step = if j < 3 { ROTATION_STEP } else { CENTRE_STEP_M };
            let mut increment = Increment::zeros();
            if let Some(slot) = increment.get_mut(j) {
                *slot = step;
            }
            let Some(moved) = self.residuals(&model.retract(&increment), pinhole) else {
                return;
            };
            for (k, (m, a)) in moved.iter().zip(&at).enumerate() {
                if let Some(slot) = jacobian.get_mut((k, j)) {
                    *slot = (m - a) / step;
                }
            }
        }
        let weight = self.weight_per_px2 * sigma_px * sigma_px;
        for (k, residual) in at.iter().enumerate() {
            let mut camera = SMatrix::<f64, 2, CAMERA_PARAMETERS>::zeros();
            camera.set_row(0, &jacobian.row(k));
            blocks.accumulate(
                &camera,
                &OtherBlock::None,
                &Vector2::new(*residual, 0.0),
                weight,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn model() -> WorkcellModel {
        WorkcellModel {
            disc_from_camera: Rotation3::from_euler_angles(
                core::f64::consts::PI + 0.05,
                -0.08,
                0.3,
            ),
            camera_centre_disc: Vector3::new(0.1, -0.05, 2.8),
            features_rotating: [Vector3::zeros(); crate::observation::MAX_PART_FEATURES],
            feature_count: 3,
            base_yaw: 0.0,
            base_translation: Vector3::zeros(),
        }
    }

    fn pinhole() -> Pinhole {
        Pinhole {
            f_px: 290.0,
            cx: 127.5,
            cy: 127.5,
        }
    }

    fn observation(ellipse: &Ellipse, sigma_px: f64) -> RimObservation {
        RimObservation {
            centre_px: ellipse.centre_px,
            semi_axes_px: ellipse.semi_axes_px,
            angle_rad: ellipse.angle_rad,
            sigma_px,
        }
    }

    #[test]
    fn the_predicted_rim_holds_the_projected_circle() {
        let m = model();
        let rim = predicted_rim(&m, &pinhole(), 0.45).unwrap();
        let camera_from_disc = m.disc_from_camera.inverse();
        for k in 0..12 {
            let phi = k as f64 * 0.5;
            let p = camera_from_disc
                * (Vector3::new(0.45 * phi.cos(), 0.45 * phi.sin(), 0.0) - m.camera_centre_disc);
            let px = [290.0 * p.x / p.z + 127.5, 290.0 * p.y / p.z + 127.5];
            assert!(rim.locate(px).unwrap().distance_px(1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn the_mean_rim_averages_frames_and_gates_a_stray_one() {
        let rim = predicted_rim(&model(), &pinhole(), 0.45).unwrap();
        let mut accumulator = RimAccumulator::default();
        for k in 0..10 {
            let wobble = if k % 2 == 0 { 0.01 } else { -0.01 };
            let moved = Ellipse {
                centre_px: [rim.centre_px[0] + wobble, rim.centre_px[1]],
                ..rim
            };
            accumulator.add(&observation(&moved, 0.006)).unwrap();
        }
        let stray = Ellipse {
            semi_axes_px: rim.semi_axes_px.map(|a| a + 1.0),
            ..rim
        };
        assert_eq!(
            accumulator.add(&observation(&stray, 0.006)),
            Err(RimRefusal::Gated)
        );
        assert_eq!(
            accumulator.add(&observation(&rim, f64::NAN)),
            Err(RimRefusal::Invalid)
        );
        let mean = accumulator.mean().unwrap();
        for k in 0..8 {
            let d = mean
                .locate(rim.point_at(k as f64))
                .unwrap()
                .distance_px(1.0);
            assert!(d.abs() < 1e-9, "{d}");
        }
        assert_eq!((accumulator.count(), accumulator.gated()), (10, 1));
    }

    #[test]
    fn the_rims_normal_equations_step_a_camera_onto_it() {
        let truth = model();
        let rim = predicted_rim(&truth, &pinhole(), 0.45).unwrap();
        let mut accumulator = RimAccumulator::default();
        accumulator.add(&observation(&rim, 0.001)).unwrap();
        let summary = accumulator.summary(0.45).unwrap();
        // A camera 5 mm too high: the rim's scale says so.
        let mut wrong = truth;
        wrong.camera_centre_disc.z += 0.005;
        assert!(summary.cost(&wrong, &pinhole(), 0.1) > 1.0);
        let mut blocks = NormalBlocks::zeros();
        summary.add_to(&mut blocks, &wrong, &pinhole(), 0.1);
        // The gradient points the height down.
        let gradient = blocks.gradient();
        assert!(gradient.iter().any(|g| g.abs() > 0.0));
        assert!(summary.cost(&truth, &pinhole(), 0.1) < 1e-12);
    }
}
