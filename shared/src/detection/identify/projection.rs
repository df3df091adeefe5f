//! The camera's projection of base-frame points, fitted from the gripper's
//! sightings (the direct linear transform, 3 x 4, up to scale): what tells
//! the effector marks apart. Their base-frame centres come with every frame
//! (joint encoders and kinematics); once the projection is known, each mark
//! is looked for where it projects.
//!
//! The fit keeps the last [`RING`] correspondences (base point, pinhole
//! pixel) in fixed memory and solves the 12 x 12 normal equations'
//! smallest eigenvector; it is trusted only when the points span all three
//! dimensions and the fit explains every one of them.

use nalgebra::{Matrix3, SMatrix, SVector, SymmetricEigen, Vector3};

use crate::calibration::homography::{pose_from_homography, PlanePose};
use crate::observation::PixelPoint;

/// Correspondences kept.
pub const RING: usize = 48;
/// Fewest correspondences for a fit.
const MIN_POINTS: usize = 12;
/// Least spread of the base points along their thinnest direction, m (RMS).
const MIN_SPREAD_M: f64 = 0.01;
/// The fit is used only near where it was fitted: along each principal
/// direction of the held points, within this many of their RMS spreads
/// plus [`COVER_MARGIN_M`] of their mean. Outside, a DLT of eleven
/// parameters fitted over a thin volume extrapolates badly (5 to 7 px off
/// where the gripper lifted the part away, seeds 5 and 6), enough to put a
/// carried part's feature in a hidden mark's gate.
const COVER_SPREADS: f64 = 4.0;
const COVER_MARGIN_M: f64 = 0.04;

/// Held points whose heights spread less than this (RMS, m) lie on one
/// level plane (the search shows the marks at its travel height only): the
/// DLT is degenerate there, and the plane's homography stands in for it.
const PLANE_Z_SPREAD_M: f64 = 0.005;
/// A base point within this of the plane's height is on it, m.
const PLANE_TOLERANCE_M: f64 = 0.01;
/// The plane's map is used this far beyond its points, m: it only keeps
/// disc labels off where a gripper mark may be, and a far one that misses
/// by more than the veto's radius costs nothing (the search's sightings
/// cluster where the view is, the arm passes on).
const PLANE_COVER_MARGIN_M: f64 = 0.3;
/// Off the plane, the camera's pose from its map says where a point
/// projects up to this far above or below it, m: the calibration's poses
/// lie within 0.4 m of the search's height. Before the DLT is fitted the
/// poses may show one mark at a time (the arm hides the other), which the
/// pair stage cannot take, and the gripper's mark lowered over the part
/// stood in a hidden feature's place (images seed 12, cell 346).
const PLANE_LIFT_M: f64 = 0.5;
/// ... and up to this far beyond the held points' reach, m: a camera's pose
/// extrapolates as a camera does (the arm lowered the marks over the part
/// 0.8 m from where the search had seen them in that cell).
const POSE_COVER_MARGIN_M: f64 = 1.2;
/// Fewest held points for the plane's map (five sightings of two marks:
/// eight unknowns).
const MIN_PLANE_POINTS: usize = 10;
/// The plane's map is used when it explains its points within this, px
/// (the marks' heights differ by a few millimetres).
const PLANE_RMS_PX: f64 = 1.0;

type Matrix12 = SMatrix<f64, 12, 12>;
type Vector12 = SVector<f64, 12>;
type Matrix8 = SMatrix<f64, 8, 8>;
type Vector8 = SVector<f64, 8>;

/// The homography of held points on one level plane, from their `(x, y)`
/// to their pinhole pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PlaneMap {
    /// The plane's height, m.
    z_m: f64,
    /// The held points' mean `(x, y)`, m (the map's origin).
    origin_m: [f64; 2],
    /// Their largest distance from it, m (the map is used no further out
    /// than this plus [`PLANE_COVER_MARGIN_M`]).
    reach_m: f64,
    /// The homography `[h11 h12 h13 h21 h22 h23 h31 h32]` (`h33 = 1`) from
    /// `(x, y)` about the origin, over `reach_m`, to the pixel less the
    /// principal point over the focal length.
    h: [f64; 8],
    /// The pixel normalisation: principal point and focal length, px.
    centre: PixelPoint,
    scale: f64,
    /// The camera's pose against the plane (its axes the base's, its
    /// origin at `origin_m` and `z_m`), from the map and the intrinsics.
    pose: Option<PlanePose>,
}

impl PlaneMap {
    /// The pixel of `(x, y)` on the plane (`None` where the map sends it
    /// to infinity).
    fn at(&self, x: f64, y: f64) -> Option<PixelPoint> {
        let reach = self.reach_m.max(1e-6);
        let (dx, dy) = (
            (x - self.origin_m[0]) / reach,
            (y - self.origin_m[1]) / reach,
        );
        let [h11, h12, h13, h21, h22, h23, h31, h32] = self.h;
        let w = h31 * dx + h32 * dy + 1.0;
        if libm::fabs(w) < 1e-9 {
            return None;
        }
        let u = (h11 * dx + h12 * dy + h13) / w * self.scale + self.centre[0];
        let v = (h21 * dx + h22 * dy + h23) / w * self.scale + self.centre[1];
        (u.is_finite() && v.is_finite()).then_some([u, v])
    }

    /// The camera's pose against the plane from the map (metric about the
    /// origin) and the intrinsics.
    fn pose(&self) -> Option<PlanePose> {
        let reach = self.reach_m.max(1e-6);
        let [h11, h12, h13, h21, h22, h23, h31, h32] = self.h;
        let metric = Matrix3::new(
            h11 / reach,
            h12 / reach,
            h13,
            h21 / reach,
            h22 / reach,
            h23,
            h31 / reach,
            h32 / reach,
            1.0,
        );
        pose_from_homography(&metric).ok()
    }

    /// The pixel of a base-frame point off the plane, by the camera's pose
    /// (`None` without one, or behind the camera).
    fn through_pose(&self, base_m: [f64; 3]) -> Option<PixelPoint> {
        let pose = self.pose.as_ref()?;
        let on_plane = Vector3::new(
            base_m[0] - self.origin_m[0],
            base_m[1] - self.origin_m[1],
            base_m[2] - self.z_m,
        );
        let camera = pose.disc_from_camera.inverse() * (on_plane - pose.camera_centre_disc);
        if camera.z.is_nan() || camera.z <= 1e-6 {
            return None;
        }
        let u = camera.x / camera.z * self.scale + self.centre[0];
        let v = camera.y / camera.z * self.scale + self.centre[1];
        (u.is_finite() && v.is_finite()).then_some([u, v])
    }
}

/// The correspondences and the current fit.
#[derive(Debug, Clone)]
pub struct BaseProjection {
    points: [([f64; 3], PixelPoint); RING],
    count: usize,
    next: usize,
    /// Normalisation of the image: principal point and focal length.
    centre: PixelPoint,
    scale: f64,
    fit: Option<(Vector12, [f64; 3])>,
    rms_px: f64,
    /// The RMS when the DLT was last solved (not a kept fit's over newer
    /// points, see [`Self::solved_rms_px`]), px.
    solved_rms_px: f64,
    /// The held points' principal directions (columns) and RMS spreads
    /// along them, m, at the last fit.
    axes: nalgebra::Matrix3<f64>,
    spreads_m: [f64; 3],
    /// The held points' level-plane map, when they all lie on one.
    plane: Option<PlaneMap>,
}

impl BaseProjection {
    /// An empty fit for a camera of focal length `f_px` and principal point `centre`.
    pub fn new(centre: PixelPoint, f_px: f64) -> Self {
        Self {
            points: [([0.0; 3], [0.0; 2]); RING],
            count: 0,
            next: 0,
            centre,
            scale: if f_px > 0.0 { f_px } else { 1.0 },
            fit: None,
            rms_px: f64::INFINITY,
            solved_rms_px: f64::INFINITY,
            axes: nalgebra::Matrix3::identity(),
            spreads_m: [0.0; 3],
            plane: None,
        }
    }

    /// Forgets every correspondence.
    pub fn clear(&mut self) {
        self.count = 0;
        self.next = 0;
        self.fit = None;
        self.rms_px = f64::INFINITY;
        self.solved_rms_px = f64::INFINITY;
        self.plane = None;
    }

    /// Correspondences held.
    pub fn len(&self) -> usize {
        self.count
    }

    /// No correspondence held.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// RMS reprojection error of the held points under the fit, px.
    pub fn rms_px(&self) -> f64 {
        self.rms_px
    }

    /// The RMS of the held points when the DLT was last solved, px. Where a
    /// refit too thin to solve keeps the last fit, [`Self::rms_px`] is that
    /// fit's over the newer points: it grows as the arm leaves where the
    /// fit holds, and a gate scaled by it would grow with it (30 Hz, images
    /// seed 11, cell 4: the approach's sightings 0.5 to 1.2 px off the kept
    /// fit were taken, the RMS crept from 0.04 to 3 px, and the pair stage
    /// that took over paired mark 0 with the part's feature 0 the gripper
    /// tracked).
    pub fn solved_rms_px(&self) -> f64 {
        self.solved_rms_px
    }

    /// Adds a correspondence (the oldest goes when full).
    pub fn add(&mut self, base_m: [f64; 3], pixel: PixelPoint) {
        if let Some(slot) = self.points.get_mut(self.next) {
            *slot = (base_m, pixel);
        }
        self.next = (self.next + 1) % RING;
        self.count = (self.count + 1).min(RING);
    }

    fn held(&self) -> impl Iterator<Item = &([f64; 3], PixelPoint)> {
        self.points.iter().take(self.count)
    }

    /// Refits from the held correspondences; `None` when they are too few,
    /// too flat or inconsistent.
    pub fn refit(&mut self) -> Option<f64> {
        let last_fit = self.fit.take();
        self.rms_px = f64::INFINITY;
        if self.count < MIN_POINTS {
            return None;
        }
        let n = self.count as f64;
        let mut mean = Vector3::zeros();
        for (p, _) in self.held() {
            mean += Vector3::from(*p);
        }
        mean /= n;
        let mut scatter = nalgebra::Matrix3::zeros();
        for (p, _) in self.held() {
            let d = Vector3::from(*p) - mean;
            scatter += d * d.transpose();
        }
        let spread = SymmetricEigen::try_new(scatter / n, 1e-15, 200)?;
        self.plane = if libm::sqrt((scatter.m33 / n).max(0.0)) <= PLANE_Z_SPREAD_M {
            self.plane_map(mean)
        } else {
            None
        };
        if spread.eigenvalues.min() < MIN_SPREAD_M * MIN_SPREAD_M {
            // Points gathered in a thin region (the gripper riding with the
            // part at one height) cannot refit the DLT, nor do they unfit
            // it: the last fit stands while it explains them.
            self.fit = last_fit;
            let rms = self.held_rms_px()?;
            if rms.is_finite() {
                self.rms_px = rms;
                return Some(rms);
            }
            self.fit = None;
            return None;
        }
        self.axes = spread.eigenvectors;
        self.spreads_m = [0, 1, 2]
            .map(|k| libm::sqrt(spread.eigenvalues.get(k).copied().unwrap_or(0.0).max(0.0)));
        let origin = [mean.x, mean.y, mean.z];
        let mut normal = Matrix12::zeros();
        for (p, px) in self.held() {
            let [x, y, z] = [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]];
            let u = (px[0] - self.centre[0]) / self.scale;
            let v = (px[1] - self.centre[1]) / self.scale;
            let row_u = Vector12::from_column_slice(&[
                x,
                y,
                z,
                1.0,
                0.0,
                0.0,
                0.0,
                0.0,
                -u * x,
                -u * y,
                -u * z,
                -u,
            ]);
            let row_v = Vector12::from_column_slice(&[
                0.0,
                0.0,
                0.0,
                0.0,
                x,
                y,
                z,
                1.0,
                -v * x,
                -v * y,
                -v * z,
                -v,
            ]);
            normal += row_u * row_u.transpose() + row_v * row_v.transpose();
        }
        let eigen = SymmetricEigen::try_new(normal, 1e-15, 500)?;
        let smallest = eigen.eigenvalues.imin();
        let solution: Vector12 = eigen.eigenvectors.column(smallest).into_owned();
        self.fit = Some((solution, origin));
        let Some(rms) = self.held_rms_px() else {
            self.fit = None;
            return None;
        };
        self.rms_px = rms;
        self.solved_rms_px = rms;
        Some(rms)
    }

    /// The RMS reprojection error of the held points under the fit, px
    /// (`None` without a fit or when a point projects nowhere).
    fn held_rms_px(&self) -> Option<f64> {
        self.fit.as_ref()?;
        let mut sum = 0.0;
        for (p, px) in self.held() {
            let q = self.project(*p)?;
            let (du, dv) = (q[0] - px[0], q[1] - px[1]);
            sum += du * du + dv * dv;
        }
        Some(libm::sqrt(sum / self.count.max(1) as f64))
    }

    /// The homography of the held points, all at the height of `mean`,
    /// from their `(x, y)` to their pixels (least squares with `h33 = 1`,
    /// about their mean and over their reach), if they are enough, spread
    /// in the plane and explained by it.
    fn plane_map(&self, mean: Vector3<f64>) -> Option<PlaneMap> {
        if self.count < MIN_PLANE_POINTS {
            return None;
        }
        let origin = [mean.x, mean.y];
        let reach = self
            .held()
            .map(|(p, _)| libm::hypot(p[0] - origin[0], p[1] - origin[1]))
            .fold(0.0, f64::max);
        if !reach.is_finite() || reach <= 1e-3 {
            return None;
        }
        let mut normal = Matrix8::zeros();
        let mut rhs = Vector8::zeros();
        for (p, px) in self.held() {
            let (x, y) = ((p[0] - origin[0]) / reach, (p[1] - origin[1]) / reach);
            let u = (px[0] - self.centre[0]) / self.scale;
            let v = (px[1] - self.centre[1]) / self.scale;
            let row_u = Vector8::from_column_slice(&[x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y]);
            let row_v = Vector8::from_column_slice(&[0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y]);
            normal += row_u * row_u.transpose() + row_v * row_v.transpose();
            rhs += row_u * u + row_v * v;
        }
        let solution = normal.cholesky()?.solve(&rhs);
        let mut h = [0.0; 8];
        for (slot, value) in h.iter_mut().zip(solution.iter()) {
            *slot = *value;
        }
        let mut map = PlaneMap {
            z_m: mean.z,
            origin_m: origin,
            reach_m: reach,
            h,
            centre: self.centre,
            scale: self.scale,
            pose: None,
        };
        map.pose = map.pose();
        // The pose must place the held points where they were seen, as the
        // map does: from points along a line, say, the map's columns are
        // not a rotation's, and the pose sent the marks 600 px off.
        if let Some(pose_rms) = self.rms_through_pose(&map) {
            if pose_rms.is_nan() || pose_rms > PLANE_RMS_PX {
                map.pose = None;
            }
        }
        let mut sum = 0.0;
        for (p, px) in self.held() {
            let q = map.at(p[0], p[1])?;
            sum += (q[0] - px[0]) * (q[0] - px[0]) + (q[1] - px[1]) * (q[1] - px[1]);
        }
        let rms = libm::sqrt(sum / self.count as f64);
        (rms.is_finite() && rms <= PLANE_RMS_PX).then_some(map)
    }

    /// The RMS of the held points through `map`'s camera pose, px (`None`
    /// without a pose; infinite when one projects nowhere).
    fn rms_through_pose(&self, map: &PlaneMap) -> Option<f64> {
        map.pose.as_ref()?;
        let mut sum = 0.0;
        for (p, px) in self.held() {
            let Some(q) = map.through_pose(*p) else {
                return Some(f64::INFINITY);
            };
            sum += (q[0] - px[0]) * (q[0] - px[0]) + (q[1] - px[1]) * (q[1] - px[1]);
        }
        Some(libm::sqrt(sum / self.count.max(1) as f64))
    }

    /// Where a base-frame point projects by the map of the level plane the
    /// held points lie on: on the plane by its homography, within
    /// [`PLANE_LIFT_M`] above or below it by the camera's pose the map
    /// gives. `None` when they lie on no plane, or the point is beyond the
    /// held points' reach (by [`PLANE_COVER_MARGIN_M`] on the plane,
    /// [`POSE_COVER_MARGIN_M`] off it) or too far off the plane. Before the DLT can be fitted this still says where the
    /// gripper's marks are, less sharply than the DLT.
    pub fn plane_px(&self, base_m: [f64; 3]) -> Option<PixelPoint> {
        let map = self.plane.as_ref()?;
        let [dx, dy] = [base_m[0] - map.origin_m[0], base_m[1] - map.origin_m[1]];
        let out = libm::hypot(dx, dy) - map.reach_m;
        let off = libm::fabs(base_m[2] - map.z_m);
        if off <= PLANE_TOLERANCE_M && out <= PLANE_COVER_MARGIN_M {
            map.at(base_m[0], base_m[1])
        } else if off <= PLANE_LIFT_M && out <= POSE_COVER_MARGIN_M {
            map.through_pose(base_m)
        } else {
            None
        }
    }

    /// The pinhole pixel of a base-frame point under the fit (`None`
    /// without a fit or behind the camera).
    pub fn project(&self, base_m: [f64; 3]) -> Option<PixelPoint> {
        let (m, origin) = self.fit.as_ref()?;
        let x = [
            base_m[0] - origin[0],
            base_m[1] - origin[1],
            base_m[2] - origin[2],
            1.0,
        ];
        let row = |r: usize| -> f64 {
            (0..4)
                .map(|k| {
                    m.get(4 * r + k).copied().unwrap_or(0.0) * x.get(k).copied().unwrap_or(0.0)
                })
                .sum()
        };
        let w = row(2);
        if w.abs() < 1e-12 {
            return None;
        }
        let out = [
            row(0) / w * self.scale + self.centre[0],
            row(1) / w * self.scale + self.centre[1],
        ];
        out.iter().all(|c| c.is_finite()).then_some(out)
    }

    /// The base-frame point lies where the fit was fitted (see
    /// [`COVER_SPREADS`]).
    pub fn covers(&self, base_m: [f64; 3]) -> bool {
        let Some((_, origin)) = self.fit.as_ref() else {
            return false;
        };
        let d = Vector3::new(
            base_m[0] - origin[0],
            base_m[1] - origin[1],
            base_m[2] - origin[2],
        );
        (0..3).all(|k| {
            let along = self.axes.column(k).dot(&d);
            let spread = self.spreads_m.get(k).copied().unwrap_or(0.0);
            along.is_finite() && libm::fabs(along) <= COVER_SPREADS * spread + COVER_MARGIN_M
        })
    }

    /// A fit is held and explains its points within `max_rms_px`.
    pub fn trusted(&self, max_rms_px: f64) -> bool {
        self.fit.is_some() && self.rms_px <= max_rms_px
    }
}
