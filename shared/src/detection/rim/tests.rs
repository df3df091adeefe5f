//! The rim on images rendered here by exact area sampling (8 x 8 sub-pixels
//! a pixel, through the lens) of a tilted disc: a surface with a texture, a
//! dark band at its edge and the floor beyond, light falling across the
//! image and noise; scored against the rim's true projection.

use std::vec;
use std::vec::Vec as StdVec;

use nalgebra::{Rotation3, Vector3};

use super::*;
use crate::detection::identify::lens::LensModel;
use crate::detection::{Blob, GrayImage};
use crate::test_rng::splitmix;

const SIZE: usize = 256;
const LENS: LensModel = LensModel {
    f_px: 290.0,
    cx: 127.5,
    cy: 127.5,
    k1: -0.06,
    k2: 0.01,
};

/// A camera over the disc: its centre in the disc frame and its axes.
#[derive(Clone)]
struct Camera {
    centre: Vector3<f64>,
    disc_from_camera: Rotation3<f64>,
}

impl Camera {
    fn new(centre: [f64; 3], tilt: [f64; 2]) -> Self {
        // Looking down (-z of the disc), tilted about x and y.
        let down = Rotation3::from_euler_angles(core::f64::consts::PI, 0.0, 0.3);
        Self {
            centre: Vector3::from(centre),
            disc_from_camera: Rotation3::from_euler_angles(tilt[0], tilt[1], 0.0) * down,
        }
    }

    /// The undistorted pixel of a disc point.
    fn project(&self, p: Vector3<f64>) -> [f64; 2] {
        let c = self.disc_from_camera.inverse() * (p - self.centre);
        [
            LENS.f_px * c.x / c.z + LENS.cx,
            LENS.f_px * c.y / c.z + LENS.cy,
        ]
    }

    /// Where the ray through undistorted pixel `p` meets the disc plane.
    fn on_plane(&self, p: [f64; 2]) -> Option<(f64, f64)> {
        let ray = self.disc_from_camera
            * Vector3::new(
                (p[0] - LENS.cx) / LENS.f_px,
                (p[1] - LENS.cy) / LENS.f_px,
                1.0,
            );
        if ray.z >= 0.0 {
            return None;
        }
        let t = -self.centre.z / ray.z;
        Some((self.centre.x + t * ray.x, self.centre.y + t * ray.y))
    }
}

#[derive(Clone)]
struct Scene {
    camera: Camera,
    radius_m: f64,
    band_m: f64,
    noise: f64,
    /// Something dark in front of the rim: (x, y, radius) in px.
    blocker: Option<(f64, f64, f64)>,
}

fn render(scene: &Scene, seed: u64) -> StdVec<u8> {
    const SUB: usize = 8;
    let mut state = seed;
    let mut pixels = vec![0u8; SIZE * SIZE];
    for v in 0..SIZE {
        for u in 0..SIZE {
            let mut sum = 0.0;
            for sy in 0..SUB {
                for sx in 0..SUB {
                    let du = u as f64 - 0.5 + (sx as f64 + 0.5) / SUB as f64;
                    let dv = v as f64 - 0.5 + (sy as f64 + 0.5) / SUB as f64;
                    let p = LENS.undistort([du, dv]).unwrap();
                    let albedo = match scene.camera.on_plane(p) {
                        Some((x, y)) => {
                            let r = x.hypot(y);
                            let phi = y.atan2(x);
                            if r < scene.radius_m - scene.band_m {
                                0.3 * (1.0
                                    + 0.05 * (r * 105.0).cos()
                                    + 0.05 * (8.0 * phi).cos()
                                    + 0.02 * (64.0 * phi).cos())
                            } else if r < scene.radius_m {
                                0.12
                            } else {
                                0.25
                            }
                        }
                        None => 0.25,
                    };
                    sum += albedo;
                }
            }
            let light = 200.0
                * (1.0 + 0.15 * (u as f64 - 128.0) / 128.0 - 0.05 * (v as f64 - 128.0) / 128.0);
            let (u1, u2) = (splitmix(&mut state).max(1e-12), splitmix(&mut state));
            let noise = scene.noise * (-2.0 * u1.ln()).sqrt() * (core::f64::consts::TAU * u2).cos();
            let mut value = light * sum / (SUB * SUB) as f64 + noise;
            if let Some((bx, by, br)) = scene.blocker {
                if (u as f64 - bx).hypot(v as f64 - by) < br {
                    value = 40.0 + noise;
                }
            }
            pixels[v * SIZE + u] = value.round().clamp(0.0, 255.0) as u8;
        }
    }
    pixels
}

/// The fitted rim's distance from the true rim at 360 points: mean and RMS, px.
fn score(scene: &Scene, fit: &RimFit) -> (f64, f64) {
    let (mut sum, mut sum2) = (0.0, 0.0);
    for k in 0..360 {
        let phi = (k as f64).to_radians();
        let p = scene.camera.project(Vector3::new(
            scene.radius_m * phi.cos(),
            scene.radius_m * phi.sin(),
            0.0,
        ));
        // Positive: the true rim lies outside the fit.
        let d = fit.ellipse.locate(p).unwrap().distance_px(1.0);
        sum += d;
        sum2 += d * d;
    }
    (sum / 360.0, (sum2 / 360.0).sqrt())
}

fn centre_px(scene: &Scene) -> [f64; 2] {
    LENS.distort(scene.camera.project(Vector3::zeros()))
}

fn measure(scene: &Scene, seed: u64) -> Result<RimFit, RimError> {
    let pixels = render(scene, seed);
    let image = GrayImage::packed(SIZE, SIZE, &pixels).unwrap();
    let mut finder = RimFinder::new(RimSettings::default());
    finder.find_from_centre(&image, &LENS, &[], centre_px(scene))
}

fn scene(centre: [f64; 3], tilt: [f64; 2], noise: f64) -> Scene {
    Scene {
        camera: Camera::new(centre, tilt),
        radius_m: 0.45,
        band_m: 0.015,
        noise,
        blocker: None,
    }
}

#[test]
fn the_rim_is_found_to_a_hundredth_of_a_pixel_without_noise() {
    for (centre, tilt) in [
        ([0.1, -0.05, 2.8], [0.05, -0.08]),
        ([-0.2, 0.15, 2.6], [-0.12, 0.06]),
        ([0.0, 0.1, 3.2], [0.15, 0.1]),
    ] {
        let scene = scene(centre, tilt, 0.0);
        let fit = measure(&scene, 1).unwrap();
        let (bias, rms) = score(&scene, &fit);
        assert!(
            bias.abs() < 0.01 && rms < 0.02,
            "{centre:?}: bias {bias:.4} rms {rms:.4} {fit:?}"
        );
        assert!(fit.sectors == fit::RIM_SECTORS, "{fit:?}");
    }
}

#[test]
fn with_noise_the_rim_is_unbiased_and_its_sigma_is_honest() {
    let scene = scene([0.1, -0.05, 2.8], [0.05, -0.08], 2.5);
    let truth_radius = {
        let noiseless = measure(
            &Scene {
                noise: 0.0,
                ..scene.clone()
            },
            1,
        )
        .unwrap();
        noiseless.ellipse.mean_radius_px()
    };
    let mut errors = StdVec::new();
    let mut sigmas = StdVec::new();
    for seed in 0..8 {
        let fit = measure(&scene, 100 + seed).unwrap();
        let (bias, _) = score(&scene, &fit);
        assert!(bias.abs() < 0.03, "seed {seed}: bias {bias:.4}");
        errors.push(fit.ellipse.mean_radius_px() - truth_radius);
        sigmas.push(fit.sigma_mean_radius_px);
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let sigma = sigmas.iter().sum::<f64>() / sigmas.len() as f64;
    // Eight draws: the ratio is loose, but a wrong sigma is off by far more.
    assert!(
        rms < 3.0 * sigma && rms > sigma / 4.0,
        "rms {rms:.4} sigma {sigma:.4}"
    );
}

#[test]
fn something_in_front_of_part_of_the_rim_is_left_out() {
    let mut scene = scene([0.1, -0.05, 2.8], [0.05, -0.08], 2.0);
    let rim_point = LENS.distort(scene.camera.project(Vector3::new(0.45, 0.0, 0.0)));
    scene.blocker = Some((rim_point[0], rim_point[1], 9.0));
    let fit = measure(&scene, 7).unwrap();
    let (bias, rms) = score(&scene, &fit);
    assert!(
        bias.abs() < 0.03 && rms < 0.06,
        "bias {bias:.4} rms {rms:.4}"
    );
}

#[test]
fn a_frame_without_a_rim_is_an_error_not_a_guess() {
    let flat = vec![90u8; SIZE * SIZE];
    let image = GrayImage::packed(SIZE, SIZE, &flat).unwrap();
    let mut finder = RimFinder::new(RimSettings::default());
    let got = finder.find_from_centre(&image, &LENS, &[], [128.0, 128.0]);
    assert!(matches!(got, Err(RimError::TooFewDips { .. })), "{got:?}");
    let got = finder.find_from_centre(&image, &LENS, &[], [f64::NAN, 3.0]);
    assert!(got.is_err(), "{got:?}");
}

#[test]
fn the_marks_pixels_are_not_the_bands() {
    let scene = scene([0.1, -0.05, 2.8], [0.05, -0.08], 0.0);
    let mut pixels = render(&scene, 3);
    // A bright mark straddling the band.
    let at = LENS.distort(scene.camera.project(Vector3::new(0.0, 0.44, 0.0)));
    for v in 0..SIZE {
        for u in 0..SIZE {
            if (u as f64 - at[0]).hypot(v as f64 - at[1]) < 2.5 {
                pixels[v * SIZE + u] = 220;
            }
        }
    }
    let image = GrayImage::packed(SIZE, SIZE, &pixels).unwrap();
    let mark = Blob {
        x_px: at[0] as f32,
        y_px: at[1] as f32,
        semi_major_px: 2.5,
        semi_minor_px: 2.5,
        area_px: 20,
        orientation_rad: 0.0,
        peak_contrast: 150,
        mean_contrast: 120.0,
        lopsidedness: 0.0,
    };
    let mut finder = RimFinder::new(RimSettings::default());
    let fit = finder
        .find_from_centre(&image, &LENS, &[mark], centre_px(&scene))
        .unwrap();
    let (bias, rms) = score(&scene, &fit);
    assert!(
        bias.abs() < 0.01 && rms < 0.02,
        "bias {bias:.4} rms {rms:.4}"
    );
}

#[test]
fn the_next_frame_starts_from_the_last_fit_and_a_moved_rim_is_refused() {
    let scene = scene([0.1, -0.05, 2.8], [0.05, -0.08], 2.5);
    let first = measure(&scene, 1).unwrap();
    let pixels = render(&scene, 2);
    let image = GrayImage::packed(SIZE, SIZE, &pixels).unwrap();
    let mut finder = RimFinder::new(RimSettings::default());
    // The next frame: a few steps from the last fit, and as good.
    let next = finder.find_near(&image, &LENS, &[], &first, None).unwrap();
    assert!(next.iterations <= 4, "{next:?}");
    let (bias, rms) = score(&scene, &next);
    assert!(
        bias.abs() < 0.03 && rms < 0.05,
        "bias {bias:.4} rms {rms:.4}"
    );
    // A rim a pixel away from the last fit (the camera knocked): an error,
    // never a fit pulled part way.
    let mut knocked = first;
    knocked.ellipse.centre_px[0] += 1.0;
    assert_eq!(
        finder.find_near(&image, &LENS, &[], &knocked, None),
        Err(RimError::Diverged)
    );
    // From the centre it is found again.
    assert!(finder
        .find_from_centre(&image, &LENS, &[], centre_px(&scene))
        .is_ok());
}

#[test]
fn frame_after_frame_the_last_fit_carries_over_and_a_jump_in_the_light_is_taken() {
    let scene = scene([-0.2, 0.15, 2.6], [-0.12, 0.06], 2.5);
    let mut finder = RimFinder::new(RimSettings::default());
    let first = {
        let pixels = render(&scene, 11);
        let image = GrayImage::packed(SIZE, SIZE, &pixels).unwrap();
        finder
            .find_from_centre(&image, &LENS, &[], centre_px(&scene))
            .unwrap()
    };
    // Ten frames, each from the last one's fit (its levels and scale
    // carried), every one as good as a fit from scratch.
    let mut last = first;
    for seed in 12..22 {
        let pixels = render(&scene, seed);
        let image = GrayImage::packed(SIZE, SIZE, &pixels).unwrap();
        last = finder.find_near(&image, &LENS, &[], &last, None).unwrap();
        let (bias, rms) = score(&scene, &last);
        assert!(
            bias.abs() < 0.03 && rms < 0.05,
            "{seed}: bias {bias:.4} rms {rms:.4}"
        );
        assert!(last.iterations <= 4, "{last:?}");
    }
    // The light jumps by 40 grey levels, far past the carried levels'
    // cutoff: the frame is measured all the same.
    let mut pixels = render(&scene, 30);
    for p in pixels.iter_mut() {
        *p = p.saturating_add(40);
    }
    let image = GrayImage::packed(SIZE, SIZE, &pixels).unwrap();
    let lit = finder.find_near(&image, &LENS, &[], &last, None).unwrap();
    let (bias, rms) = score(&scene, &lit);
    assert!(
        bias.abs() < 0.03 && rms < 0.05,
        "bias {bias:.4} rms {rms:.4}"
    );
}
