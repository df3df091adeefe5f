//! Part localisation (paper Eqs 3 to 8): in the virtual camera a feature point's
//! rotating-frame coordinates are an affine function of its unknown height `h` (Eqs 3, 4
//! and 7); every frame gives one such line, and because the point is fixed on the disc all
//! lines meet at the point (Eq 8). Solving Eq 8 by least squares over all frames, not only
//! two, averages the pixel noise over the whole revolution.

use super::exceeds;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

use super::error::CalibrationError;
use super::virtual_rotation::VirtualRotation;

/// The geometry that maps virtual-image points to the rotating frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VirtualGeometry {
    /// The virtual rotation (Steps 1, 3 and 4).
    pub rotation: VirtualRotation,
    /// Image angle of the disc X axis in the virtual image (theta = 0).
    pub gamma: f64,
}

impl VirtualGeometry {
    /// The line of Eq 7 for a virtual image point `m` seen at angle `theta`:
    /// `p_rotating.xy = a - b h`. In the virtual camera the point is at depth `H - h`,
    /// so `p_virtual = (H - h)(m, 1)`; the disc frame follows by the reflection
    /// `V(gamma)` about the disc centre and the rotating frame by `Rz(-theta)`.
    /// Eqs 3 to 6 write the same affine line with `a`, `b` from the frame's own image of the
    /// reference point; taking the frame's orientation from the encoder angle instead is
    /// equivalent for exact data, less noisy, and works in frames where the reference point
    /// was not detected.
    pub fn affine_line(&self, theta: f64, m_virtual: Vector2<f64>) -> (Vector2<f64>, Vector2<f64>) {
        self.affine_line_through(&Self::rotating_map(&self.reflection(), theta), m_virtual)
    }

    /// `V(gamma)`, the reflection about the disc centre between the virtual
    /// image's axes and the disc's: the same for every frame.
    pub fn reflection(&self) -> Matrix2<f64> {
        let (s, c) = libm::sincos(self.gamma);
        Matrix2::new(c, s, s, -c)
    }

    /// `Rz(-theta) V(gamma)`, the map of Eq 7 from the virtual image to the
    /// rotating frame for a frame seen at `theta`: one a frame, shared by all
    /// its features (a software sincos is thousands of instructions on the
    /// Cortex-M4F).
    pub fn rotating_map(reflection: &Matrix2<f64>, theta: f64) -> Matrix2<f64> {
        let (st, ct) = libm::sincos(theta);
        Matrix2::new(ct, st, -st, ct) * reflection
    }

    /// [`VirtualGeometry::affine_line`] with the frame's [`VirtualGeometry::rotating_map`].
    pub fn affine_line_through(
        &self,
        map: &Matrix2<f64>,
        m_virtual: Vector2<f64>,
    ) -> (Vector2<f64>, Vector2<f64>) {
        let h = self.rotation.height_m;
        let a = map * (m_virtual - self.rotation.centre_virtual) * h;
        let b = map * m_virtual;
        (a, b)
    }

    /// A point seen at depth `depth` along virtual ray `m`, in the disc frame.
    pub fn disc_point(&self, m_virtual: Vector2<f64>, depth: f64) -> Vector3<f64> {
        let p_virtual = Vector3::new(m_virtual.x, m_virtual.y, 1.0) * depth;
        super::virtual_rotation::virtual_from_disc_rotation(self.gamma).transpose()
            * (p_virtual - self.rotation.disc_origin_virtual())
    }
}

/// Normal equations of Eq 8 for one feature point: unknowns `(x, y, h)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FeatureSystem {
    normal: Matrix3<f64>,
    rhs: Vector3<f64>,
    count: u32,
}

impl FeatureSystem {
    /// Adds one frame's line `(x, y) + b h = a` with weight `weight`.
    pub fn add(&mut self, line: (Vector2<f64>, Vector2<f64>), weight: f64) {
        let (a, b) = line;
        let rows = nalgebra::Matrix2x3::new(1.0, 0.0, b.x, 0.0, 1.0, b.y);
        self.normal += rows.transpose() * rows * weight;
        self.rhs += rows.transpose() * a * weight;
        self.count = self.count.saturating_add(1);
    }

    /// The least-squares point `(x, y, h)` where the lines meet.
    pub fn solve(&self) -> Result<Vector3<f64>, CalibrationError> {
        if self.count < 2 {
            return Err(CalibrationError::TooFewObservations {
                what: "frames showing the part",
                needed: 2,
                found: self.count,
            });
        }
        // The lines must not be parallel: the h column must be independent of x and y.
        let cholesky = self
            .normal
            .cholesky()
            .ok_or(CalibrationError::NumericalFailure {
                stage: "part localisation (Eq 8)",
            })?;
        let diagonal_ratio =
            cholesky.l().m33 * cholesky.l().m33 / self.normal.m33.max(f64::MIN_POSITIVE);
        if !exceeds(diagonal_ratio, 1e-10) {
            return Err(CalibrationError::NumericalFailure {
                stage: "part localisation (Eq 8)",
            });
        }
        let point = cholesky.solve(&self.rhs);
        if point.iter().all(|v| v.is_finite()) {
            Ok(point)
        } else {
            Err(CalibrationError::NumericalFailure {
                stage: "part localisation (Eq 8)",
            })
        }
    }
}

/// Eq 8 for two frames exactly as the paper writes it: the `h` that best equates the two
/// lines, then the mean of the two lines' points at that height.
pub fn intersect_two_lines(
    first: (Vector2<f64>, Vector2<f64>),
    second: (Vector2<f64>, Vector2<f64>),
) -> Result<Vector3<f64>, CalibrationError> {
    let (a1, b1) = first;
    let (a2, b2) = second;
    let db = b1 - b2;
    let da = a1 - a2;
    let denominator = db.norm_squared();
    if !exceeds(denominator, 1e-18) {
        return Err(CalibrationError::NumericalFailure {
            stage: "part localisation (Eq 8, two frames)",
        });
    }
    let h = db.dot(&da) / denominator;
    let xy = ((a1 - b1 * h) + (a2 - b2 * h)) / 2.0;
    Ok(Vector3::new(xy.x, xy.y, h))
}

/// Squared distance (m^2) of a point's xy from one frame's line at the point's
/// height: what a gate compares, without the root.
pub fn line_miss_squared(point: &Vector3<f64>, line: (Vector2<f64>, Vector2<f64>)) -> f64 {
    let (a, b) = line;
    (Vector2::new(point.x, point.y) + b * point.z - a).norm_squared()
}
