use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use shared::detection::{Detector, DetectorSettings};
use shared::planning::{gripper_down_rotation, ready_posture, solve_ik, IkConfig};
use shared::robot::Puma560;

use super::lens::{LensCamera, LensDistortion};
use super::scene::{Capsule, Mark, MarkKind, Scene, MID};
use super::truth::mark_images;
use super::*;
use crate::scenario::pick::{ImageSettings, PickScenarioFile};
use crate::scenario::recording::Scenario;
use crate::world::generator::random_workcell;
use crate::world::workcell::Workcell;
use crate::world::World;

fn workcell(seed: u64) -> Workcell {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    random_workcell(&mut rng, &Scenario::paper()).unwrap().0
}

/// Flat light, flat disc: the reflectance image is what the raster drew.
fn flat() -> ImageSettings {
    ImageSettings {
        disc_texture: 0.0,
        light_gradient: 0.0,
        light_drift: 0.0,
        vignetting: 0.0,
        ..ImageSettings::default()
    }
}

/// A scene of the disc and one still mark at `centre` (normal up).
fn one_mark(centre: Vector3<f64>, radius_m: f64) -> Scene {
    Scene {
        time_s: 0.0,
        theta_rad: [0.0; 3],
        disc_radius_m: crate::world::dimensions::DISC_RADIUS_M,
        disc_above_floor_m: 0.3,
        marks: vec![Mark {
            kind: MarkKind::Reference,
            centre_disc: [centre; 3],
            normal_disc: [Vector3::z(); 3],
            radius_m,
        }],
        part: None,
        arm: Vec::new(),
    }
}

#[test]
fn distortion_inverts_and_vanishes_without_coefficients() {
    let lens = LensDistortion {
        k1: -0.06,
        k2: 0.01,
    };
    for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.45, 0.41), (0.05, 0.6)] {
        let [u, v] = lens.undistort(lens.distort([x, y])).unwrap();
        assert!((u - x).abs() < 1e-12 && (v - y).abs() < 1e-12);
    }
    let cell = workcell(2);
    let plain = LensCamera {
        pinhole: cell.camera.clone(),
        lens: LensDistortion::default(),
    };
    let p = cell.reference_disc(0.4);
    let [u, v] = plain.project(&p).unwrap();
    let [u0, v0] = cell.camera.project(&p).unwrap();
    assert!((u - u0).abs() < 1e-9 && (v - v0).abs() < 1e-9);
    // Every pixel's ray goes back to that pixel.
    let lensed = LensCamera {
        pinhole: cell.camera.clone(),
        lens,
    };
    for (u, v) in [(0.0, 0.0), (255.0, 0.0), (100.3, 200.7), (127.5, 127.5)] {
        let ray = lensed.ray_disc([u, v]).unwrap();
        let point = cell.camera.optical_centre_disc + ray * 2.0;
        let [pu, pv] = lensed.project(&point).unwrap();
        assert!((pu - u).abs() < 1e-9 && (pv - v).abs() < 1e-9, "{pu} {pv}");
    }
}

#[test]
fn a_mark_is_drawn_where_its_image_is() {
    // The reflectance-weighted centroid of the drawn mark against the
    // centroid of its exact image region, over many sub-pixel positions.
    let settings = flat();
    let mut worst: f64 = 0.0;
    for seed in 0..6 {
        let cell = workcell(seed);
        let mut renderer = Renderer::new(&cell.camera, &settings).unwrap();
        for k in 0..8 {
            let angle = 0.7 * f64::from(k) + 0.1 * seed as f64;
            let centre = Vector3::new(0.3 * angle.cos(), 0.3 * angle.sin(), 0.0);
            let scene = one_mark(centre, 0.012);
            renderer.render(&scene);
            let truth = mark_images(&renderer, &scene, 2.0)[0];
            let buffer = renderer.buffer();
            let [cu, cv] = truth.centre_px;
            let (mut sw, mut su, mut sv) = (0.0, 0.0, 0.0);
            for v in (cv as usize - 8)..=(cv as usize + 8) {
                for u in (cu as usize - 8)..=(cu as usize + 8) {
                    let w =
                        f64::from(buffer.albedo[v * buffer.width + u]) - settings.disc_reflectance;
                    sw += w;
                    su += w * u as f64;
                    sv += w * v as f64;
                }
            }
            let area = sw / (settings.mark_reflectance - settings.disc_reflectance);
            let [ru, rv] = truth.region_centroid_px;
            let error = (su / sw - ru).hypot(sv / sw - rv);
            worst = worst.max(error);
            // The drawn area is the image's area, within what the linear
            // coverage ramp adds or takes along a curved outline (about
            // pi / 12 px^2 for a circle, depending on its sub-pixel place;
            // measured within 2.2 %).
            let expected = std::f64::consts::PI * truth.radius_px * truth.radius_px;
            assert!(
                (area - expected).abs() < 0.04 * expected,
                "{area} vs {expected}"
            );
        }
    }
    eprintln!("drawn centroid off by {worst} px at worst");
    // Measured 0.016 px at worst: the pixel grid's own sampling of a 2 px
    // mark, and the 3 x 3 sub-pixels of its edge.
    assert!(worst < 0.03, "drawn centroid off by {worst} px");
}

#[test]
fn the_arm_hides_what_it_stands_in_front_of() {
    let cell = workcell(3);
    let mut renderer = Renderer::new(&cell.camera, &flat()).unwrap();
    let centre = Vector3::new(0.2, -0.1, 0.0);
    let mut scene = one_mark(centre, 0.012);
    // A bar halfway between the camera and the mark, across the line of sight.
    let middle = centre + (cell.camera.optical_centre_disc - centre) * 0.5;
    let across = (cell.camera.optical_centre_disc - centre)
        .cross(&Vector3::z())
        .normalize();
    let ends = [middle - across * 0.2, middle + across * 0.2];
    scene.arm.push(Capsule {
        ends_disc: [ends, ends],
        radius_m: 0.05,
        carries_marks: false,
    });
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let frame = renderer.frame(&scene, true, &mut rng);
    let truth = mark_images(&renderer, &scene, 2.0)[0];
    assert_eq!(truth.hidden_fraction, 1.0);
    assert!(!truth.visible());
    let mut detector = Detector::new(DetectorSettings::default());
    let mut blobs = heapless::Vec::new();
    detector
        .detect(&frame.as_image().unwrap(), &mut blobs)
        .unwrap();
    let near = blobs.iter().any(|b| {
        (f64::from(b.x_px) - truth.centre_px[0]).hypot(f64::from(b.y_px) - truth.centre_px[1]) < 5.0
    });
    assert!(!near, "a hidden mark was detected");
    // Without the bar it is found.
    scene.arm.clear();
    let frame = renderer.frame(&scene, true, &mut rng);
    let truth = mark_images(&renderer, &scene, 2.0)[0];
    assert!(truth.visible());
    detector
        .detect(&frame.as_image().unwrap(), &mut blobs)
        .unwrap();
    assert!(blobs.iter().any(|b| {
        (f64::from(b.x_px) - truth.centre_px[0]).hypot(f64::from(b.y_px) - truth.centre_px[1]) < 0.3
    }));
}

#[test]
fn motion_blur_spreads_a_moving_mark_about_its_middle_position() {
    let cell = workcell(4);
    let settings = flat();
    let mut renderer = Renderer::new(&cell.camera, &settings).unwrap();
    let centre = Vector3::new(0.1, 0.15, 0.0);
    let step = Vector3::new(0.02, 0.0, 0.0);
    let mut scene = one_mark(centre, 0.012);
    scene.marks[0].centre_disc = [centre - step, centre, centre + step];
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let frame = renderer.frame(&scene, true, &mut rng);
    let truth = mark_images(&renderer, &scene, 2.0)[0];
    let mut detector = Detector::new(DetectorSettings::default());
    let mut blobs = heapless::Vec::new();
    detector
        .detect(&frame.as_image().unwrap(), &mut blobs)
        .unwrap();
    assert_eq!(blobs.len(), 1, "{blobs:?}");
    let blob = blobs[0];
    // Elongated along the motion (4 cm of travel, several pixels) ...
    assert!(blob.semi_major_px > 1.5 * blob.semi_minor_px, "{blob:?}");
    // ... and centred where the mark is at the trigger.
    let error = (f64::from(blob.x_px) - truth.centre_px[0])
        .hypot(f64::from(blob.y_px) - truth.centre_px[1]);
    assert!(error < 0.1, "{error}");
}

#[test]
fn noise_has_the_shot_and_read_variance() {
    let cell = workcell(5);
    let settings = flat();
    let mut renderer = Renderer::new(&cell.camera, &settings).unwrap();
    let scene = one_mark(Vector3::new(0.0, 0.0, 0.0), 0.012);
    renderer.render(&scene);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut clean = GrayFrame {
        width: 0,
        height: 0,
        pixels: Vec::new(),
    };
    let mut noisy = clean.clone();
    renderer.expose(0.0, true, &mut rng, &mut clean);
    let (mut n, mut sum2, mut level) = (0.0, 0.0, 0.0);
    for _ in 0..4 {
        renderer.expose(0.0, false, &mut rng, &mut noisy);
        // The disc's flat surface: grey = 0.3 * 200 = 60.
        for (c, p) in clean.pixels.iter().zip(&noisy.pixels) {
            if *c == 60 {
                let d = f64::from(*p) - 60.0;
                sum2 += d * d;
                n += 1.0;
                level = f64::from(*c);
            }
        }
    }
    assert!(n > 10_000.0, "{n}");
    let sigma = (sum2 / n).sqrt();
    let expected = (settings.read_noise_grey.powi(2) + level / settings.electrons_per_grey).sqrt();
    // Rounding to whole grey levels adds 1/12 to the variance.
    let expected = (expected * expected + 1.0 / 12.0).sqrt();
    assert!(
        (sigma - expected).abs() < 0.05 * expected,
        "{sigma} vs {expected}"
    );
}

/// Joint angles that put the gripper, pointing down, over disc point `p`.
fn gripper_over(
    cell: &Workcell,
    p_disc: Vector3<f64>,
    yaw: f64,
) -> Option<shared::robot::JointVector<f64>> {
    let robot = Puma560::<f64>::new();
    let flange = cell.base_from_disc(&p_disc);
    let target = Isometry3::from_parts(
        Translation3::from(flange),
        UnitQuaternion::from_rotation_matrix(&gripper_down_rotation(yaw)),
    );
    solve_ik(&robot, &target, &ready_posture(), &IkConfig::default()).ok()
}

#[test]
fn the_detector_finds_every_visible_mark_of_the_world() {
    // Frames of real workcells: the disc at many angles, the gripper over
    // the disc at several places; noise-free, with motion blur. Layouts in
    // front of the robot and near it (the ranges before the wide ones), so
    // that the gripper reaches over the disc in most frames.
    let mut experiment = PickScenarioFile::default_experiment("turning").unwrap();
    experiment.cell.disc_distance_m = [0.65, 0.78];
    experiment.cell.disc_below_shoulder_m = [0.30, 0.45];
    experiment.cell.disc_azimuth_deg = [-90.0, 90.0];
    let settings = experiment.image;
    let mut detector = Detector::new(DetectorSettings::default());
    let mut blobs = heapless::Vec::new();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (mut visible, mut errors, mut effector_found) = (0, Vec::new(), 0);
    for seed in 0..6 {
        let world = World::new(&experiment, seed).unwrap();
        let cell = world.workcell().clone();
        let mut renderer = Renderer::new(&cell.camera, &settings).unwrap();
        for k in 0..6 {
            let mut state = FrameState::from_world(&world, settings.exposure_ms / 1000.0);
            let theta = 1.1 * f64::from(k);
            state.theta_rad = [theta - 0.002, theta, theta + 0.002];
            let place = Vector3::new(0.25 * (2.0 * theta).cos(), 0.25 * (2.0 * theta).sin(), 0.3);
            if let Some(q) = gripper_over(&cell, place, theta) {
                let qd = shared::robot::JointVector::from_element(0.05);
                state.q_rad = [q - qd * 0.004, q, q + qd * 0.004];
            }
            let scene = build_scene(&cell, &state, &settings);
            let frame = renderer.frame(&scene, true, &mut rng);
            let marks = mark_images(&renderer, &scene, 2.0);
            detector
                .detect(&frame.as_image().unwrap(), &mut blobs)
                .unwrap();
            let outcome = crate::vision_check::matching::match_frame(&marks, &blobs);
            assert!(
                outcome.missed.is_empty(),
                "seed {seed} frame {k}: missed {:?} of {marks:?}",
                outcome.missed
            );
            visible += outcome.visible;
            effector_found += outcome
                .found
                .iter()
                .filter(|f| matches!(marks[f.mark].kind, MarkKind::Effector(_)))
                .count();
            errors.extend(outcome.found.iter().map(|f| f.error_px));
        }
    }
    assert!(visible > 100, "{visible}");
    assert!(effector_found > 10, "{effector_found}");
    let (rms, p99) = crate::vision_check::report::rms_p99(&errors);
    eprintln!("{visible} visible marks, {effector_found} gripper marks found; noise-free RMS {rms} px, 99th pct {p99} px");
    assert!(
        rms < 0.1 && p99 < 0.3,
        "noise-free RMS {rms} px, 99th pct {p99} px"
    );
    let _ = MID;
}
