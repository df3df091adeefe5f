//! Beyond the paper: a start for the refinement that also works on short arcs. Each frame's
//! reference point is a known disc point `(L cos theta, L sin theta, 0)` and the centre mark
//! is `(0, 0, 0)`, so the disc-plane-to-image homography follows linearly (DLT), and with
//! the intrinsics known it factors into `disc_from_camera`. Unlike the conic of Step 2 it
//! uses theta, so a quarter revolution (where an ellipse fit to the bare arc is poorly
//! conditioned) still fixes the pose. Gross outliers are removed by iterated gating.

use super::exceeds;
use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, SymmetricEigen, Vector2, Vector3};

use super::error::CalibrationError;

type Matrix9 = SMatrix<f64, 9, 9>;
type Vector9 = SVector<f64, 9>;

/// One correspondence: a disc-plane point (m) and its ray-coordinate image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanePoint {
    /// The point on the disc plane, m.
    pub disc_xy: Vector2<f64>,
    /// Its image in ray coordinates.
    pub ray: Vector2<f64>,
}

/// `disc_from_camera` and the camera centre in the disc frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanePose {
    /// The camera's orientation in the disc frame.
    pub disc_from_camera: Rotation3<f64>,
    /// The camera's centre in the disc frame, m.
    pub camera_centre_disc: Vector3<f64>,
}

/// The moments of a set of correspondences from which the normalised DLT's
/// scatter matrix follows in closed form: with `p = (x, y, 1)` the disc point
/// and `(u, v)` its ray, the sums of `p p^T` weighted by 1, `u`, `v` and
/// `u^2 + v^2` (each symmetric, six entries). One pass over the points gives
/// both normalisations and the scatter, where summing the 9 x 9 scatter point
/// by point took a pass for each normaliser and 162 products a point (on the
/// Cortex-M4F, whose FPU has no f64, the homography was a third of an
/// estimate's instructions).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct PlaneMoments {
    count: u32,
    /// Entries `xx, xy, x, yy, y, 1` of the four sums, in the order of [`Weight`].
    sums: [[f64; 6]; 4],
}

/// The weights of [`PlaneMoments::sums`].
#[derive(Clone, Copy)]
enum Weight {
    One = 0,
    U = 1,
    V = 2,
    Squared = 3,
}

impl PlaneMoments {
    fn add(&mut self, point: &PlanePoint) {
        let (x, y) = (point.disc_xy.x, point.disc_xy.y);
        let (u, v) = (point.ray.x, point.ray.y);
        let entries = [x * x, x * y, x, y * y, y, 1.0];
        let weights = [1.0, u, v, u * u + v * v];
        for (sum, weight) in self.sums.iter_mut().zip(weights) {
            for (total, entry) in sum.iter_mut().zip(entries) {
                *total += weight * entry;
            }
        }
        self.count = self.count.saturating_add(1);
    }

    /// `sum w p p^T` as a matrix.
    fn matrix(&self, weight: Weight) -> Matrix3<f64> {
        let [xx, xy, x, yy, y, one] = self.sums.get(weight as usize).copied().unwrap_or_default();
        Matrix3::new(xx, xy, x, xy, yy, y, x, y, one)
    }

    /// Similarity normalisations (centre, unit RMS radius / sqrt 2) of the disc
    /// points and of the rays: `(scale, mean)` each.
    fn normalisers(&self) -> Option<[(f64, Vector2<f64>); 2]> {
        let count = f64::from(self.count);
        if count < 1.0 {
            return None;
        }
        let disc = self.matrix(Weight::One);
        let disc_mean = Vector2::new(disc.m13, disc.m23) / count;
        let disc_spread = (disc.m11 + disc.m22) / count - disc_mean.norm_squared();
        // The "1" entries of the weighted sums: the sums of u, v and u^2 + v^2.
        let ray_mean = Vector2::new(self.matrix(Weight::U).m33, self.matrix(Weight::V).m33) / count;
        let ray_spread = self.matrix(Weight::Squared).m33 / count - ray_mean.norm_squared();
        if !exceeds(disc_spread, 1e-24) || !exceeds(ray_spread, 1e-24) {
            return None;
        }
        Some([
            (libm::sqrt(2.0 / disc_spread), disc_mean),
            (libm::sqrt(2.0 / ray_spread), ray_mean),
        ])
    }
}

/// `[[s, 0, -s mx], [0, s, -s my], [0, 0, 1]]`.
fn similarity((scale, mean): (f64, Vector2<f64>)) -> Matrix3<f64> {
    Matrix3::new(
        scale,
        0.0,
        -scale * mean.x,
        0.0,
        scale,
        -scale * mean.y,
        0.0,
        0.0,
        1.0,
    )
}

fn apply(h: &Matrix3<f64>, p: Vector2<f64>) -> Option<Vector2<f64>> {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    (libm::fabs(q.z) > 1e-12).then(|| Vector2::new(q.x / q.z, q.y / q.z))
}

/// Normalised DLT over the points summed in `moments`: ray = H disc (homogeneous).
/// The normalised points are `d = N_d p` and `r = t (ray - m)`; each gives the
/// rows `[d, 0, -r_x d]` and `[0, d, -r_y d]`, so the scatter's blocks are
/// `sum d d^T` weighted by 1, `r_x`, `r_y` and `r_x^2 + r_y^2`, each `N_d`
/// times a moment sum times `N_d^T`.
fn fit(moments: &PlaneMoments) -> Result<Matrix3<f64>, CalibrationError> {
    let failure = CalibrationError::NumericalFailure {
        stage: "disc-plane homography",
    };
    if moments.count < 4 {
        return Err(CalibrationError::TooFewObservations {
            what: "reference and centre images (homography)",
            needed: 4,
            found: moments.count,
        });
    }
    let [disc, ray] = moments.normalisers().ok_or(failure)?;
    let disc_norm = similarity(disc);
    let ray_norm = similarity(ray);
    let normalised = |weight| disc_norm * moments.matrix(weight) * disc_norm.transpose();
    let (t, m) = ray;
    let one = normalised(Weight::One);
    let (u, v) = (normalised(Weight::U), normalised(Weight::V));
    let by_x = (u - one * m.x) * t;
    let by_y = (v - one * m.y) * t;
    let squared = (normalised(Weight::Squared) - u * (2.0 * m.x) - v * (2.0 * m.y)
        + one * m.norm_squared())
        * (t * t);
    let mut scatter = Matrix9::zeros();
    scatter.fixed_view_mut::<3, 3>(0, 0).copy_from(&one);
    scatter.fixed_view_mut::<3, 3>(3, 3).copy_from(&one);
    scatter.fixed_view_mut::<3, 3>(0, 6).copy_from(&-by_x);
    scatter.fixed_view_mut::<3, 3>(6, 0).copy_from(&-by_x);
    scatter.fixed_view_mut::<3, 3>(3, 6).copy_from(&-by_y);
    scatter.fixed_view_mut::<3, 3>(6, 3).copy_from(&-by_y);
    scatter.fixed_view_mut::<3, 3>(6, 6).copy_from(&squared);
    let eigen = SymmetricEigen::try_new(scatter, 1e-15, 1000).ok_or(failure)?;
    let values: [f64; 9] = eigen.eigenvalues.into();
    let (smallest, _) = values
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .ok_or(failure)?;
    let h: Vector9 = eigen.eigenvectors.column(smallest).into_owned();
    let normalised = Matrix3::from_row_slice(h.as_slice());
    // A camera off the disc plane sees it through a non-singular homography; a (near)
    // singular one maps the disc onto a line (collinear or inconsistent detections).
    if !exceeds(
        libm::fabs(normalised.determinant()),
        1e-6 * libm::pow(normalised.norm(), 3.0),
    ) {
        return Err(failure);
    }
    let ray_denorm = ray_norm.try_inverse().ok_or(failure)?;
    let homography = ray_denorm * normalised * disc_norm;
    if homography.iter().all(|v| v.is_finite()) {
        Ok(homography)
    } else {
        Err(failure)
    }
}

/// Robust homography and its factorisation into the camera pose.
/// `points` yields the correspondences afresh on every call (they are not copied).
pub fn pose_from_plane<I: Iterator<Item = PlanePoint> + Clone>(
    points: impl Fn() -> I,
    f_px: f64,
    floor_px: f64,
) -> Result<PlanePose, CalibrationError> {
    let failure = CalibrationError::NumericalFailure {
        stage: "disc-plane homography",
    };
    let f_squared = f_px * f_px;
    // Squared image distance (px^2) of a point from the disc point's image.
    let miss_squared = |homography: &Matrix3<f64>, p: &PlanePoint| {
        apply(homography, p.disc_xy).map_or(f64::INFINITY, |q| (q - p.ray).norm_squared())
            * f_squared
    };
    let within = |homography: &Matrix3<f64>, gate_squared: f64| {
        let mut moments = PlaneMoments::default();
        points()
            .filter(|p| miss_squared(homography, p) <= gate_squared)
            .for_each(|p| moments.add(&p));
        moments
    };
    let mut all = PlaneMoments::default();
    points().for_each(|p| all.add(&p));
    let mut homography = fit(&all)?;
    let mut fitted = all;
    let mut gate_squared = f64::INFINITY;
    for _ in 0..5 {
        let (mut squares, mut count) = (0.0, 0u32);
        for point in points() {
            let miss = miss_squared(&homography, &point);
            if miss <= gate_squared {
                squares += miss;
                count += 1;
            }
        }
        if count < 4 {
            return Err(failure);
        }
        // 3.5 RMS misses, and never below the floor.
        gate_squared = (12.25 * squares / f64::from(count)).max(floor_px * floor_px);
        let gated = within(&homography, gate_squared);
        // The same points as the last fit (their sums agree to the last bit):
        // the same homography, and every further round would repeat it.
        if gated == fitted {
            break;
        }
        homography = fit(&gated)?;
        fitted = gated;
    }
    // Most correspondences must agree, or this is not the image of the disc plane;
    // and every disc point seen must lie in front of the camera, on the same side
    // of the homography's vanishing line as the disc centre.
    let centre_depth = homography.m33;
    let (mut total, mut inliers) = (0usize, 0usize);
    for point in points() {
        let depth = (homography * Vector3::new(point.disc_xy.x, point.disc_xy.y, 1.0)).z;
        if depth * centre_depth <= 0.0 {
            return Err(failure);
        }
        total += 1;
        if miss_squared(&homography, &point) <= gate_squared {
            inliers += 1;
        }
    }
    if inliers * 4 < total * 3 {
        return Err(failure);
    }
    pose_from_homography(&homography)
}

/// The camera's pose from the homography of a plane (its `(x, y)`, m, to
/// rays): the intrinsics known, `ray ~ [r1 r2 t] (x, y, 1)` gives the
/// rotation's first two columns and the plane origin's place in the
/// camera frame, up to one scale (the columns' mean norm; the origin lies
/// in front of the camera).
pub fn pose_from_homography(homography: &Matrix3<f64>) -> Result<PlanePose, CalibrationError> {
    let failure = CalibrationError::NumericalFailure {
        stage: "disc-plane homography",
    };
    let h1: Vector3<f64> = homography.column(0).into_owned();
    let h2: Vector3<f64> = homography.column(1).into_owned();
    let h3: Vector3<f64> = homography.column(2).into_owned();
    let norm = (h1.norm() + h2.norm()) / 2.0;
    if !exceeds(norm, 0.0) {
        return Err(failure);
    }
    // The disc centre is in front of the camera: t.z > 0.
    let sign = if h3.z >= 0.0 { 1.0 } else { -1.0 };
    let scale = sign / norm;
    let (r1, r2, t) = (h1 * scale, h2 * scale, h3 * scale);
    let approximate = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    let camera_from_disc =
        Rotation3::from_matrix_eps(&approximate, 1e-12, 100, Rotation3::identity());
    let disc_from_camera = camera_from_disc.inverse();
    let camera_centre_disc = -(disc_from_camera * t);
    if !camera_centre_disc.iter().all(|v| v.is_finite()) {
        return Err(failure);
    }
    if camera_centre_disc.z <= 0.0 {
        return Err(CalibrationError::CameraBelowDisc);
    }
    Ok(PlanePose {
        disc_from_camera,
        camera_centre_disc,
    })
}
