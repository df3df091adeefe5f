//! The camera's projection with its known radial lens distortion, and the
//! table of each pixel's viewing ray.
//!
//! Model (the one `host-sim vision-check` scores against): a disc-frame point
//! `p` goes to the camera frame, `P = R^T (p - c)` (`R` is
//! `disc_from_camera_rotation`, `c` the optical centre); its normalised
//! coordinates `x = P_x / P_z`, `y = P_y / P_z` are distorted radially,
//! `(x_d, y_d) = (x, y) (1 + k1 r^2 + k2 r^4)` with `r^2 = x^2 + y^2`; the pixel
//! is `u = f x_d + cx`, `v = f y_d + cy`. Pixel `(i, j)` covers
//! `[i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]`, so its centre is at `(i, j)`: the
//! convention of the contract and of `shared::detection`. With `k1 = k2 = 0`
//! this is [`PinholeCamera::project`].

use anyhow::{bail, Result};
use nalgebra::Vector3;

use crate::world::camera::PinholeCamera;

/// Depth below which a point counts as behind the camera.
const MIN_DEPTH_M: f64 = 1e-3;
/// Fixed-point iterations of the undistortion, and the residual it must reach.
const UNDISTORT_ITERATIONS: usize = 30;
const UNDISTORT_TOLERANCE: f64 = 1e-12;

/// Radial distortion `r_d = r (1 + k1 r^2 + k2 r^4)`, normalised coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LensDistortion {
    pub k1: f64,
    pub k2: f64,
}

impl LensDistortion {
    fn factor(&self, r2: f64) -> f64 {
        1.0 + self.k1 * r2 + self.k2 * r2 * r2
    }

    /// Distorted normalised coordinates of undistorted ones.
    pub fn distort(&self, [x, y]: [f64; 2]) -> [f64; 2] {
        let k = self.factor(x * x + y * y);
        [x * k, y * k]
    }

    /// Undistorted normalised coordinates of distorted ones (fixed point
    /// `x = x_d / factor(|x|^2)`), or `None` if it does not converge (the
    /// distortion folds over at that radius).
    pub fn undistort(&self, [xd, yd]: [f64; 2]) -> Option<[f64; 2]> {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..UNDISTORT_ITERATIONS {
            let k = self.factor(x * x + y * y);
            if k <= 0.0 {
                return None;
            }
            (x, y) = (xd / k, yd / k);
        }
        let [rx, ry] = self.distort([x, y]);
        ((rx - xd).hypot(ry - yd) < UNDISTORT_TOLERANCE).then_some([x, y])
    }

    /// Whether `r_d(r)` increases for every undistorted radius up to `r_max`
    /// (otherwise two points of the scene land on one pixel).
    pub fn monotonic_up_to(&self, r_max: f64) -> bool {
        (0..=200).all(|step| {
            let r2 = (r_max * f64::from(step) / 200.0).powi(2);
            1.0 + 3.0 * self.k1 * r2 + 5.0 * self.k2 * r2 * r2 > 0.0
        })
    }
}

/// The world's camera with its lens.
#[derive(Debug, Clone, PartialEq)]
pub struct LensCamera {
    pub pinhole: PinholeCamera,
    pub lens: LensDistortion,
}

impl LensCamera {
    /// A disc-frame point in the camera frame.
    pub fn camera_from_disc(&self, p_disc: &Vector3<f64>) -> Vector3<f64> {
        self.pinhole.disc_from_camera_rotation.transpose()
            * (p_disc - self.pinhole.optical_centre_disc)
    }

    /// The pixel of a disc-frame point and its depth (camera z), or `None`
    /// when it is behind the camera.
    pub fn project_with_depth(&self, p_disc: &Vector3<f64>) -> Option<([f64; 2], f64)> {
        let p = self.camera_from_disc(p_disc);
        if p.z < MIN_DEPTH_M {
            return None;
        }
        let [xd, yd] = self.lens.distort([p.x / p.z, p.y / p.z]);
        let i = &self.pinhole.intrinsics;
        Some(([i.f_px * xd + i.cx, i.f_px * yd + i.cy], p.z))
    }

    /// The pixel of a disc-frame point (see the module's model).
    pub fn project(&self, p_disc: &Vector3<f64>) -> Option<[f64; 2]> {
        self.project_with_depth(p_disc).map(|(pixel, _)| pixel)
    }

    /// The viewing ray of pixel coordinates `(u, v)` in the disc frame,
    /// scaled so that its camera-z component is 1 (so `c + t d` is at depth
    /// `t`), or `None` where the distortion cannot be inverted.
    pub fn ray_disc(&self, [u, v]: [f64; 2]) -> Option<Vector3<f64>> {
        let i = &self.pinhole.intrinsics;
        let [x, y] = self
            .lens
            .undistort([(u - i.cx) / i.f_px, (v - i.cy) / i.f_px])?;
        Some(self.pinhole.disc_from_camera_rotation * Vector3::new(x, y, 1.0))
    }
}

/// Every pixel's viewing ray (disc frame, unit camera z), row by row, for one
/// camera pose; rebuilt only when the camera moves.
#[derive(Debug, Clone)]
pub struct RayTable {
    camera: LensCamera,
    width: usize,
    height: usize,
    rays: Vec<[f64; 3]>,
}

impl RayTable {
    /// The table of `camera`, or an error if its distortion folds over inside
    /// the image.
    pub fn new(camera: &LensCamera) -> Result<Self> {
        let i = camera.pinhole.intrinsics;
        let (width, height) = (i.width as usize, i.height as usize);
        // Normalised radius of the farthest image corner, undistorted, with margin.
        let corner = [(-0.5, -0.5), (width as f64 - 0.5, height as f64 - 0.5)]
            .iter()
            .flat_map(|&(u, _)| [(u, -0.5), (u, height as f64 - 0.5)])
            .map(|(u, v)| ((u - i.cx) / i.f_px).hypot((v - i.cy) / i.f_px))
            .fold(0.0, f64::max);
        if !camera.lens.monotonic_up_to(1.5 * corner) {
            bail!(
                "lens distortion k1 = {}, k2 = {} folds over inside the image (f = {:.1} px)",
                camera.lens.k1,
                camera.lens.k2,
                i.f_px
            );
        }
        let mut rays = Vec::with_capacity(width * height);
        for v in 0..height {
            for u in 0..width {
                let Some(ray) = camera.ray_disc([u as f64, v as f64]) else {
                    bail!("pixel ({u}, {v}) cannot be undistorted");
                };
                rays.push([ray.x, ray.y, ray.z]);
            }
        }
        Ok(Self {
            camera: camera.clone(),
            width,
            height,
            rays,
        })
    }

    pub fn camera(&self) -> &LensCamera {
        &self.camera
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The ray of pixel `(u, v)` (zero outside the image).
    #[inline]
    pub fn ray(&self, u: usize, v: usize) -> [f64; 3] {
        self.rays
            .get(v * self.width + u)
            .copied()
            .unwrap_or([0.0; 3])
    }
}
