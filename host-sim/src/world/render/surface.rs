//! The disc and the floor, one pass over every pixel through its viewing ray:
//! the disc's top at `z = 0` (disc frame) out to its radius, with a darker
//! rim band and a texture in the rotating frame, and the floor below it.
//!
//! The texture is a function of the radius and the angle in the rotating
//! frame: rings `cos(2 pi r / 6 cm)` and two angular harmonics `cos(8 phi)`
//! and `cos(64 phi)`, whose average over the disc's turn during the exposure
//! is exact (`sinc(k dtheta / 2)` times the harmonic at the middle), so the
//! texture's motion blur costs nothing. The harmonics come from powers of
//! the unit complex number `e^(i phi)`, with no trigonometric call per pixel.

use super::lens::RayTable;
use super::raster::{coverage, FrameBuffer};
use super::scene::{Scene, END, MID, START};
use crate::scenario::pick::ImageSettings;

/// Wavelength of the disc's rings, m.
const RING_WAVELENGTH_M: f64 = 0.06;
/// Shares of the texture's amplitude: rings, 8 sectors, 64 fine sectors.
const TEXTURE_SHARES: [f64; 3] = [0.4, 0.4, 0.2];

fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-9 {
        1.0
    } else {
        x.sin() / x
    }
}

/// Paints the floor and the disc into `buffer` (every pixel).
pub fn paint_surfaces(
    buffer: &mut FrameBuffer,
    rays: &RayTable,
    scene: &Scene,
    settings: &ImageSettings,
) {
    let camera = &rays.camera().pinhole;
    let o = camera.optical_centre_disc;
    let rotation = camera.disc_from_camera_rotation;
    let (ax, bx) = (
        rotation.column(0).into_owned(),
        rotation.column(1).into_owned(),
    );
    let f_px = camera.intrinsics.f_px;
    let radius = scene.disc_radius_m;
    let inner = radius - settings.rim_width_m;
    let floor_z = -scene.disc_above_floor_m;
    let theta_mid = scene.theta_rad[MID];
    let (cos_mid, sin_mid) = (theta_mid.cos(), theta_mid.sin());
    let turn = scene.theta_rad[END] - scene.theta_rad[START];
    let blur8 = sinc(8.0 * turn / 2.0);
    let blur64 = sinc(64.0 * turn / 2.0);
    let [ring_share, sector_share, fine_share] = TEXTURE_SHARES.map(|s| s * settings.disc_texture);
    let disc_albedo = settings.disc_reflectance;
    let rim_albedo = settings.rim_reflectance;
    let floor_albedo = settings.floor_reflectance as f32;
    let ring_k = std::f64::consts::TAU / RING_WAVELENGTH_M;
    for v in 0..buffer.height {
        for u in 0..buffer.width {
            let [dx, dy, dz] = rays.ray(u, v);
            let index = v * buffer.width + u;
            // The floor (always behind the disc).
            let (mut albedo, mut depth) = if dz < 0.0 {
                ((floor_albedo), ((floor_z - o.z) / dz) as f32)
            } else {
                (floor_albedo, f32::INFINITY)
            };
            if dz < 0.0 && o.z > 0.0 {
                let t = -o.z / dz;
                let (px, py) = (o.x + t * dx, o.y + t * dy);
                let r = px.hypot(py);
                if r < radius + 0.05 {
                    // Pixels per metre along the radius here: the change of r
                    // with the image coordinates (module docs of `raster`).
                    let (qx, qy) = if r > 1e-9 {
                        (px / r, py / r)
                    } else {
                        (1.0, 0.0)
                    };
                    let q_dot_d = qx * dx + qy * dy;
                    let gx = qx * ax.x + qy * ax.y - q_dot_d * ax.z / dz;
                    let gy = qx * bx.x + qy * bx.y - q_dot_d * bx.z / dz;
                    let metres_per_px = (t / f_px * gx.hypot(gy)).max(1e-9);
                    let on_disc = coverage((r - radius) / metres_per_px);
                    if on_disc > 0.0 {
                        let on_surface = coverage((r - inner) / metres_per_px);
                        // e^(i phi) in the rotating frame at the exposure's middle.
                        let (c, s) = (qx * cos_mid + qy * sin_mid, qy * cos_mid - qx * sin_mid);
                        let (mut re, mut im) = (c, s);
                        for _ in 0..3 {
                            (re, im) = (re * re - im * im, 2.0 * re * im);
                        }
                        let cos8 = re;
                        for _ in 0..3 {
                            (re, im) = (re * re - im * im, 2.0 * re * im);
                        }
                        let cos64 = re;
                        let texture = disc_albedo
                            * (1.0
                                + ring_share * (ring_k * r).cos()
                                + sector_share * blur8 * cos8
                                + fine_share * blur64 * cos64);
                        let disc = on_surface * texture + (1.0 - on_surface) * rim_albedo;
                        albedo =
                            (on_disc * disc + (1.0 - on_disc) * f64::from(floor_albedo)) as f32;
                        if on_disc >= 0.5 {
                            depth = t as f32;
                        }
                    }
                }
            }
            if let (Some(a), Some(d)) = (buffer.albedo.get_mut(index), buffer.depth.get_mut(index))
            {
                *a = albedo;
                *d = depth;
            }
        }
    }
}
