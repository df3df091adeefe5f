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

/// Similarity normalisation (centre, unit RMS radius / sqrt 2) of a point set.
fn normaliser(points: impl Iterator<Item = Vector2<f64>> + Clone) -> Option<Matrix3<f64>> {
    let (mut sum, mut count) = (Vector2::zeros(), 0.0);
    for p in points.clone() {
        sum += p;
        count += 1.0;
    }
    if count < 1.0 {
        return None;
    }
    let mean = sum / count;
    let spread = points.map(|p| (p - mean).norm_squared()).sum::<f64>() / count;
    if !exceeds(spread, 1e-24) {
        return None;
    }
    let scale = libm::sqrt(2.0 / spread);
    Some(Matrix3::new(
        scale,
        0.0,
        -scale * mean.x,
        0.0,
        scale,
        -scale * mean.y,
        0.0,
        0.0,
        1.0,
    ))
}

fn apply(h: &Matrix3<f64>, p: Vector2<f64>) -> Option<Vector2<f64>> {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    (libm::fabs(q.z) > 1e-12).then(|| Vector2::new(q.x / q.z, q.y / q.z))
}

/// Normalised DLT over the points `keep` accepts: ray = H disc (homogeneous).
fn fit<I: Iterator<Item = PlanePoint> + Clone>(
    points: &impl Fn() -> I,
    keep: impl Fn(&PlanePoint) -> bool,
) -> Result<Matrix3<f64>, CalibrationError> {
    let failure = CalibrationError::NumericalFailure {
        stage: "disc-plane homography",
    };
    let kept = || points().filter(|p| keep(p));
    let count = kept().count();
    if count < 4 {
        return Err(CalibrationError::TooFewObservations {
            what: "reference and centre images (homography)",
            needed: 4,
            found: u32::try_from(count).unwrap_or(u32::MAX),
        });
    }
    let disc_norm = normaliser(kept().map(|p| p.disc_xy)).ok_or(failure)?;
    let ray_norm = normaliser(kept().map(|p| p.ray)).ok_or(failure)?;
    let mut scatter = Matrix9::zeros();
    for point in kept() {
        let d = disc_norm * Vector3::new(point.disc_xy.x, point.disc_xy.y, 1.0);
        let r = ray_norm * Vector3::new(point.ray.x, point.ray.y, 1.0);
        let row_x = Vector9::from_column_slice(&[
            d.x,
            d.y,
            d.z,
            0.0,
            0.0,
            0.0,
            -r.x * d.x,
            -r.x * d.y,
            -r.x * d.z,
        ]);
        let row_y = Vector9::from_column_slice(&[
            0.0,
            0.0,
            0.0,
            d.x,
            d.y,
            d.z,
            -r.y * d.x,
            -r.y * d.y,
            -r.y * d.z,
        ]);
        scatter += row_x * row_x.transpose() + row_y * row_y.transpose();
    }
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
    let mut homography = fit(&points, |_| true)?;
    let mut gate_px = f64::INFINITY;
    for _ in 0..5 {
        let miss = |p: &PlanePoint| {
            apply(&homography, p.disc_xy).map_or(f64::INFINITY, |q| (q - p.ray).norm() * f_px)
        };
        let (mut squares, mut count) = (0.0, 0.0);
        for point in points().filter(|p| miss(p) <= gate_px) {
            let m = miss(&point);
            squares += m * m;
            count += 1.0;
        }
        if count < 4.0 {
            return Err(failure);
        }
        gate_px = (3.5 * libm::sqrt(squares / count)).max(floor_px);
        let next = fit(&points, |p| miss(p) <= gate_px)?;
        homography = next;
    }
    // Most correspondences must agree, or this is not the image of the disc plane.
    let total = points().count();
    let inliers = points()
        .filter(|p| {
            apply(&homography, p.disc_xy).is_some_and(|q| (q - p.ray).norm() * f_px <= gate_px)
        })
        .count();
    if inliers * 4 < total * 3 {
        return Err(failure);
    }
    // Every disc point seen must lie in front of the camera, on the same side of the
    // homography's vanishing line as the disc centre.
    let depth = |p: &PlanePoint| (homography * Vector3::new(p.disc_xy.x, p.disc_xy.y, 1.0)).z;
    let centre_depth = homography.m33;
    if points().any(|p| depth(&p) * centre_depth <= 0.0) {
        return Err(failure);
    }
    // ray ~ [r1 r2 t] (X, Y, 1): columns of camera_from_disc and its translation, up to scale.
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
