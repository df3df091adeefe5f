//! Steps 1, 3 and 4 of the virtual rotation (paper Section 2.1): rotate the camera about
//! its optical centre, in software, until the disc plane is parallel to the image plane.
//!
//! After the rotation `R = R_y R_z R_k` the reference circle images as a circle of radius
//! `l` (in ray units, `f = 1`), so the camera height is `H = L / l` (the paper's
//! `H = f L / l` with `l` in pixels), and a point at height `h` above the disc lies at depth
//! `H - h` in the virtual camera (Eq 12).

use super::exceeds;
use nalgebra::{Matrix3, Rotation3, Vector2, Vector3};

use super::conic::Conic;
use super::error::CalibrationError;

/// The rotated ("virtual") camera: optical axis along the disc's -Z, image plane parallel
/// to the disc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VirtualRotation {
    /// `R_y R_z R_k`: maps camera-frame vectors to virtual-camera-frame vectors.
    pub virtual_from_camera: Rotation3<f64>,
    /// Image of the disc centre in the virtual camera (ray units): the circle's centre.
    pub centre_virtual: Vector2<f64>,
    /// Radius `l` of the reference circle's image in the virtual camera (ray units).
    pub radius: f64,
    /// Height of the optical centre above the disc plane, `H = L / l`.
    pub height_m: f64,
}

impl VirtualRotation {
    /// Builds the rotation from the fitted ellipse and the image of the disc centre
    /// (both in ray coordinates of the real camera).
    pub fn from_conic(
        conic: &Conic,
        centre_ray: Vector2<f64>,
        reference_radius_m: f64,
    ) -> Result<Self, CalibrationError> {
        // Step 1: R_k turns the ray through the disc centre onto the optical axis.
        let centre_direction = Vector3::new(centre_ray.x, centre_ray.y, 1.0);
        let rotation_k = Rotation3::rotation_between(&centre_direction, &Vector3::z())
            .unwrap_or_else(Rotation3::identity);
        // Rays transform as m' = R m, so the conic matrix transforms as Q' = R Q R^T.
        let conic_k = rotate_conic(&conic.matrix(), &rotation_k);
        // Step 3: R_z about the optical axis. With the centre on the axis the configuration is
        // mirror-symmetric about the plane through the axis and the disc normal, so the
        // ellipse's minor axis and the conic's linear term (d, e) both lie along that plane.
        // Turning (d, e) onto +X puts the major axis along Y; unlike the quadratic form's
        // eigenvectors this stays well defined as the ellipse becomes a circle.
        let (d, e) = (2.0 * conic_k.m13, 2.0 * conic_k.m23);
        let phi = libm::atan2(e, d);
        let rotation_z = Rotation3::from_axis_angle(&Vector3::z_axis(), -phi);
        let conic_z = rotate_conic(&conic_k, &rotation_z);
        // Step 4: R_y about the image Y axis by the tilt alpha. For a circle of radius L at
        // depth D along the axis, tilted by alpha about Y, the conic's X-intercepts x+ and x-
        // satisfy 1/x+ + 1/x- = -2 tan(alpha); with x^2 coefficient a, linear d', constant g
        // that sum is -d'/g, hence tan(alpha) = d' / (2 g) (independent of the conic's scale).
        let d_aligned = 2.0 * conic_z.m13;
        let g = conic_z.m33;
        if g == 0.0 || !g.is_finite() {
            return Err(CalibrationError::NumericalFailure {
                stage:
                    "virtual rotation (Step 4: the conic passes through the disc centre's image)",
            });
        }
        let alpha_from_centre = libm::atan(d_aligned / (2.0 * g));
        // The same tilt from the quadratic terms, which a long arc determines best: after
        // R_y(beta) the x^2 and y^2 coefficients must be equal (a circle):
        // (g - c) t^2 + d' t + (a - c) = 0 with t = tan(beta). Its two roots are the cone's
        // two circular sections; the one nearer the centre-based tilt is the disc.
        let (a, c) = (conic_z.m11, conic_z.m22);
        let alpha = closest_root(g - c, d_aligned, a - c, -alpha_from_centre)
            .map_or(alpha_from_centre, |t| -libm::atan(t));
        let rotation_y = Rotation3::from_axis_angle(&Vector3::y_axis(), -alpha);
        let virtual_from_camera = rotation_y * rotation_z * rotation_k;
        // The image is now a circle: a (x^2 + y^2) + d x + e y + g = 0.
        let circle = rotate_conic(&conic.matrix(), &virtual_from_camera);
        let a = (circle.m11 + circle.m22) / 2.0;
        let not_a_circle = CalibrationError::NumericalFailure {
            stage: "virtual rotation (Step 4: the rotated conic is not a real circle; arc too short or too noisy)",
        };
        if a == 0.0 || !a.is_finite() {
            return Err(not_a_circle);
        }
        let centre_virtual = Vector2::new(-circle.m13 / a, -circle.m23 / a);
        let radius_squared = centre_virtual.norm_squared() - circle.m33 / a;
        if !exceeds(radius_squared, 0.0) {
            return Err(not_a_circle);
        }
        let radius = libm::sqrt(radius_squared);
        let height_m = reference_radius_m / radius;
        if !height_m.is_finite() {
            return Err(not_a_circle);
        }
        Ok(Self {
            virtual_from_camera,
            centre_virtual,
            radius,
            height_m,
        })
    }

    /// The virtual rotation of a camera whose pose in the disc frame is known (with the disc X
    /// axis along the virtual image's X, i.e. `gamma = 0` in [`disc_from_virtual`]):
    /// `R = V(0) disc_from_camera`, `O_V = -V(0) c`.
    pub fn from_pose(
        disc_from_camera: &Rotation3<f64>,
        camera_centre_disc: &Vector3<f64>,
        reference_radius_m: f64,
    ) -> Result<Self, CalibrationError> {
        let axes = virtual_from_disc_rotation(0.0);
        let virtual_from_camera =
            Rotation3::from_matrix_unchecked(axes * disc_from_camera.matrix());
        let origin_virtual = -(axes * camera_centre_disc);
        let height_m = origin_virtual.z;
        if !(height_m > 0.0 && height_m.is_finite()) {
            return Err(CalibrationError::CameraBelowDisc);
        }
        let centre_virtual = Vector2::new(origin_virtual.x / height_m, origin_virtual.y / height_m);
        Ok(Self {
            virtual_from_camera,
            centre_virtual,
            radius: reference_radius_m / height_m,
            height_m,
        })
    }

    /// A real-camera ray point mapped into the virtual image (ray units), or `None` when the
    /// rotated ray does not cross the virtual image plane.
    pub fn to_virtual(&self, ray: Vector2<f64>) -> Option<Vector2<f64>> {
        let rotated = self.virtual_from_camera * Vector3::new(ray.x, ray.y, 1.0);
        if rotated.z > 1e-9 {
            Some(Vector2::new(rotated.x / rotated.z, rotated.y / rotated.z))
        } else {
            None
        }
    }

    /// The disc centre in the virtual camera frame, `O_V = H (c_V, 1)`.
    pub fn disc_origin_virtual(&self) -> Vector3<f64> {
        Vector3::new(self.centre_virtual.x, self.centre_virtual.y, 1.0) * self.height_m
    }
}

/// The root of `p t^2 + q t + r = 0` whose arctangent is nearest `target` (radians).
fn closest_root(p: f64, q: f64, r: f64, target: f64) -> Option<f64> {
    let discriminant = q * q - 4.0 * p * r;
    if discriminant.is_nan() || discriminant < 0.0 || p == 0.0 {
        return None;
    }
    let root = libm::sqrt(discriminant);
    let w = -(q + if q >= 0.0 { root } else { -root }) / 2.0;
    let first = w / p;
    let second = if w != 0.0 { r / w } else { first };
    let miss = |t: f64| libm::fabs(libm::atan(t) - target);
    let best = if miss(first) <= miss(second) {
        first
    } else {
        second
    };
    best.is_finite().then_some(best)
}

/// `R Q R^T`: the conic matrix seen through rays rotated by `R`.
fn rotate_conic(conic: &Matrix3<f64>, rotation: &Rotation3<f64>) -> Matrix3<f64> {
    let r = rotation.matrix();
    r * conic * r.transpose()
}

/// The virtual camera's axes in the disc frame for disc-X image angle `gamma` (see
/// [`disc_from_virtual`]): the disc's Z is the virtual camera's -z, so the 2-D map between
/// the virtual image and the disc plane is a reflection.
pub fn virtual_from_disc_rotation(gamma: f64) -> Matrix3<f64> {
    let (s, c) = libm::sincos(gamma);
    Matrix3::new(c, s, 0.0, s, -c, 0.0, 0.0, 0.0, -1.0)
}

/// `disc_from_camera` (rotation, camera centre in the disc frame) from the virtual rotation and
/// the image angle `gamma` of the disc X axis in the virtual image. A disc point `p_d` lies at
/// `p_V = V(gamma) p_d + O_V` in the virtual camera, so `p_d = V^T (R p_cam - O_V)`.
pub fn disc_from_virtual(rotation: &VirtualRotation, gamma: f64) -> (Rotation3<f64>, Vector3<f64>) {
    let disc_from_virtual = virtual_from_disc_rotation(gamma).transpose();
    let rotation_matrix = disc_from_virtual * rotation.virtual_from_camera.matrix();
    let camera_centre_disc = -(disc_from_virtual * rotation.disc_origin_virtual());
    (
        Rotation3::from_matrix_unchecked(rotation_matrix),
        camera_centre_disc,
    )
}
