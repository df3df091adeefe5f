//! The base-frame projection recovers a camera from its points; a point
//! turning with the disc is followed and predicted; identification of an
//! empty or non-finite frame gives nothing.

use super::projection::BaseProjection;
use super::track::Track;
use super::*;

/// A camera 2.4 m above base-frame points, tilted, f = 290 px.
fn true_pixel(p: [f64; 3]) -> [f64; 2] {
    let (x, y, z) = (p[0] - 0.6, p[1] + 0.1, 2.4 - p[2]);
    let (xr, zr) = (x * 0.96 + z * 0.28, -x * 0.28 + z * 0.96);
    [290.0 * xr / zr + 127.5, 290.0 * y / zr + 127.5]
}

#[test]
fn the_projection_is_recovered_from_spread_points() {
    let mut projection = BaseProjection::new([127.5, 127.5], 290.0);
    for k in 0..20 {
        let k = k as f64;
        let p = [
            0.4 + 0.03 * k % 0.3,
            -0.2 + 0.017 * k,
            0.1 + 0.05 * (k * 1.7).sin(),
        ];
        projection.add(p, true_pixel(p));
    }
    let rms = projection.refit().unwrap();
    assert!(rms < 1e-6, "{rms}");
    let q = [0.55, 0.05, 0.2];
    let [u, v] = projection.project(q).unwrap();
    let [tu, tv] = true_pixel(q);
    assert!((u - tu).abs() < 1e-5 && (v - tv).abs() < 1e-5);

    // Points in a plane do not make a trusted projection.
    let mut flat = BaseProjection::new([127.5, 127.5], 290.0);
    for k in 0..20 {
        let p = [0.4 + 0.01 * k as f64, -0.2 + 0.02 * (k % 5) as f64, 0.1];
        flat.add(p, true_pixel(p));
    }
    assert!(flat.refit().is_none());
}

#[test]
fn a_turning_point_is_predicted_from_its_path() {
    // An ellipse (a foreshortened circle) about (120, 130).
    let at = |theta: f64| {
        [
            120.0 + 50.0 * libm::cos(theta),
            130.0 - 40.0 * libm::sin(theta),
        ]
    };
    let mut track = Track::start(0.0, at(0.0), 9.0, 900.0);
    for k in 1..12 {
        let theta = 0.1 * k as f64;
        track.update(theta, at(theta), 9.0, 900.0);
    }
    let p = track.predict(1.2, 0.25, 0.35);
    let q = at(1.2);
    assert!(
        (p[0] - q[0]).abs() < 1e-6 && (p[1] - q[1]).abs() < 1e-6,
        "{p:?} {q:?}"
    );
    let model = track.fit.model(0.25).unwrap();
    // The residual comes from sums of squares of ~1e4 px^2: good to ~1e-3 px.
    assert!(
        (model.centre_px[0] - 120.0).abs() < 1e-6 && model.rms_px < 0.01,
        "{model:?}"
    );
}

#[test]
fn nothing_is_labelled_from_nothing() {
    let settings = IdentifySettings {
        lens: LensModel {
            f_px: 290.0,
            cx: 127.5,
            cy: 127.5,
            k1: -0.06,
            k2: 0.01,
        },
        reference_radius_m: 0.4,
        disc_radius_m: 0.45,
        part_feature_count: 3,
        diameters: MarkDiameters {
            disc_centre_m: 0.024,
            reference_m: 0.024,
            part_feature_m: 0.016,
            effector_m: [0.02, 0.02],
        },
        gate_px: 2.0,
        first_gate_px_per_rad: 77.0,
    };
    let mut identifier = Identifier::new(settings);
    let mut out = Vec::new();
    let report = identifier.identify(f64::NAN, &[], &[[0.0; 3]; 2], &mut out);
    assert!(out.is_empty() && report.labelled == 0);
    for k in 0..30 {
        identifier.identify(0.1 * k as f64, &[], &[[f64::NAN; 3]; 2], &mut out);
        assert!(out.is_empty());
    }
    eprintln!(
        "identifier working memory {} bytes",
        Identifier::WORKING_MEMORY_BYTES
    );
}
