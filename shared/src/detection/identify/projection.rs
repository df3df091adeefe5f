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

use nalgebra::{SMatrix, SVector, SymmetricEigen, Vector3};

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

type Matrix12 = SMatrix<f64, 12, 12>;
type Vector12 = SVector<f64, 12>;

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
    /// The held points' principal directions (columns) and RMS spreads
    /// along them, m, at the last fit.
    axes: nalgebra::Matrix3<f64>,
    spreads_m: [f64; 3],
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
            axes: nalgebra::Matrix3::identity(),
            spreads_m: [0.0; 3],
        }
    }

    /// Forgets every correspondence.
    pub fn clear(&mut self) {
        self.count = 0;
        self.next = 0;
        self.fit = None;
        self.rms_px = f64::INFINITY;
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
        self.fit = None;
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
        if spread.eigenvalues.min() < MIN_SPREAD_M * MIN_SPREAD_M {
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
        let mut sum = 0.0;
        let mut projected_all = true;
        for (p, px) in self.held() {
            match self.project(*p) {
                Some(q) => {
                    let (du, dv) = (q[0] - px[0], q[1] - px[1]);
                    sum += du * du + dv * dv;
                }
                None => projected_all = false,
            }
        }
        if !projected_all {
            self.fit = None;
            return None;
        }
        self.rms_px = libm::sqrt(sum / n);
        Some(self.rms_px)
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
