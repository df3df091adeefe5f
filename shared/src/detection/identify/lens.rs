//! From a blob's pixel to the pinhole pixel the observation log wants: the
//! contract's radial distortion (`recording.md`: `s = 1 + k1 r^2 + k2 r^4`
//! on normalised coordinates) undone by fixed-point iteration.

use crate::observation::PixelPoint;

/// The camera's known intrinsics and lens.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LensModel {
    /// Focal length, px.
    pub f_px: f64,
    /// Principal point, px.
    pub cx: f64,
    /// Principal point, px.
    pub cy: f64,
    /// Radial distortion coefficients.
    pub k1: f64,
    /// Radial distortion coefficients.
    pub k2: f64,
}

/// Iterations of the inversion; each gains about `|k1| r^2` in relative
/// error (under 0.1 at this lens' image corners), so 20 are far more than
/// enough for 1e-9 px.
const UNDISTORT_ITERATIONS: usize = 20;

impl LensModel {
    /// The pinhole pixel whose distorted image is `distorted`, or `None`
    /// when the iteration does not settle (a lens that folds over there).
    pub fn undistort(&self, distorted: PixelPoint) -> Option<PixelPoint> {
        if self.f_px.is_nan() || self.f_px <= 0.0 {
            return None;
        }
        let [u, v] = distorted;
        let xd = (u - self.cx) / self.f_px;
        let yd = (v - self.cy) / self.f_px;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..UNDISTORT_ITERATIONS {
            let r2 = x * x + y * y;
            let s = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
            if s.is_nan() || s <= 0.1 {
                return None;
            }
            x = xd / s;
            y = yd / s;
        }
        let r2 = x * x + y * y;
        let s = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
        let residual = ((x * s - xd).abs() + (y * s - yd).abs()) * self.f_px;
        let out = [x * self.f_px + self.cx, y * self.f_px + self.cy];
        (residual < 1e-6 && out.iter().all(|c| c.is_finite())).then_some(out)
    }

    /// The distorted pixel of a pinhole pixel (the contract's forward model).
    pub fn distort(&self, pinhole: PixelPoint) -> PixelPoint {
        let x = (pinhole[0] - self.cx) / self.f_px;
        let y = (pinhole[1] - self.cy) / self.f_px;
        let r2 = x * x + y * y;
        let s = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
        [x * s * self.f_px + self.cx, y * s * self.f_px + self.cy]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undistortion_inverts_the_contract_model() {
        let lens = LensModel {
            f_px: 290.0,
            cx: 127.5,
            cy: 127.5,
            k1: -0.06,
            k2: 0.01,
        };
        for p in [[0.0, 0.0], [255.0, 255.0], [127.5, 10.0], [30.0, 200.0]] {
            let back = lens.undistort(lens.distort(p)).unwrap();
            assert!(
                (back[0] - p[0]).abs() < 1e-7 && (back[1] - p[1]).abs() < 1e-7,
                "{p:?} {back:?}"
            );
        }
        // Barrel distortion pulls the corners in: undistorting pushes them out.
        let corner = lens.undistort([0.0, 0.0]).unwrap();
        assert!(corner[0] < -0.5 && corner[1] < -0.5, "{corner:?}");
    }
}
