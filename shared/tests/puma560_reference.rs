//! The PUMA 560 model against the 32 public reference cases (Robotics Toolbox for Python,
//! cross-checked with Pinocchio), in f64 and f32, plus the sanity anchors of puma560-model.md.

use nalgebra::{Matrix4, Matrix6, RealField, Vector6};
use serde_json::Value;
use shared::robot::{JointVector, Puma560};

const VECTORS: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/vectors/puma560-public.json"
);

/// One reference case, all quantities in f64.
struct Case {
    q: Vector6<f64>,
    qd: Vector6<f64>,
    qdd: Vector6<f64>,
    fk: Matrix4<f64>,
    jacob0: Matrix6<f64>,
    jdot_qd: Vector6<f64>,
    mass: Matrix6<f64>,
    gravity: Vector6<f64>,
    coriolis: Vector6<f64>,
    tau: Vector6<f64>,
}

fn numbers(value: &Value) -> Vec<f64> {
    match value {
        Value::Array(items) => items.iter().flat_map(numbers).collect(),
        Value::Number(n) => vec![n.as_f64().expect("number")],
        other => panic!("unexpected JSON value {other}"),
    }
}

fn vector6(value: &Value) -> Vector6<f64> {
    let v = numbers(value);
    assert_eq!(v.len(), 6);
    Vector6::from_column_slice(&v)
}

fn load_cases() -> Vec<Case> {
    let text = std::fs::read_to_string(VECTORS).expect("reference vectors readable");
    let root: Value = serde_json::from_str(&text).expect("valid JSON");
    let cases = root["cases"].as_array().expect("cases array");
    assert_eq!(cases.len(), 32);
    cases
        .iter()
        .map(|c| Case {
            q: vector6(&c["q"]),
            qd: vector6(&c["qd"]),
            qdd: vector6(&c["qdd"]),
            // Row-major lists of rows.
            fk: Matrix4::from_row_slice(&numbers(&c["fk"])),
            jacob0: Matrix6::from_row_slice(&numbers(&c["jacob0"])),
            jdot_qd: vector6(&c["jdot_qd"]),
            mass: Matrix6::from_row_slice(&numbers(&c["M"])),
            gravity: vector6(&c["G"]),
            coriolis: vector6(&c["Cqd"]),
            tau: vector6(&c["tau"]),
        })
        .collect()
}

/// Largest `|got - want| - (abs + rel |want|)` over all entries; <= 0 means within tolerance.
fn worst_excess<'a>(
    got: impl IntoIterator<Item = f64>,
    want: impl IntoIterator<Item = &'a f64>,
    abs: f64,
    rel: f64,
) -> f64 {
    got.into_iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs() - (abs + rel * w.abs()))
        .fold(f64::NEG_INFINITY, f64::max)
}

fn max_abs_error<'a>(
    got: impl IntoIterator<Item = f64>,
    want: impl IntoIterator<Item = &'a f64>,
) -> f64 {
    got.into_iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs())
        .fold(0.0, f64::max)
}

fn max_abs<'a>(values: impl IntoIterator<Item = &'a f64>) -> f64 {
    values.into_iter().fold(0.0, |m, v| m.max(v.abs()))
}

#[test]
fn f64_matches_every_reference_quantity() {
    let robot = Puma560::<f64>::new();
    let (abs, rel) = (1e-9, 1e-9);
    let mut worst_error: f64 = 0.0;
    for (index, case) in load_cases().iter().enumerate() {
        let checks: [(&str, Vec<f64>, Vec<f64>); 8] = [
            (
                "fk",
                robot
                    .forward_kinematics_matrix(&case.q)
                    .iter()
                    .copied()
                    .collect(),
                case.fk.iter().copied().collect(),
            ),
            (
                "fk isometry",
                robot
                    .forward_kinematics(&case.q)
                    .to_homogeneous()
                    .iter()
                    .copied()
                    .collect(),
                case.fk.iter().copied().collect(),
            ),
            (
                "jacob0",
                robot.jacobian(&case.q).iter().copied().collect(),
                case.jacob0.iter().copied().collect(),
            ),
            (
                "jdot_qd",
                robot
                    .jacobian_dot_qd(&case.q, &case.qd)
                    .iter()
                    .copied()
                    .collect(),
                case.jdot_qd.iter().copied().collect(),
            ),
            (
                "M",
                robot.mass_matrix(&case.q).iter().copied().collect(),
                case.mass.iter().copied().collect(),
            ),
            (
                "G",
                robot.gravity_torque(&case.q).iter().copied().collect(),
                case.gravity.iter().copied().collect(),
            ),
            (
                "Cqd",
                robot
                    .coriolis_torque(&case.q, &case.qd)
                    .iter()
                    .copied()
                    .collect(),
                case.coriolis.iter().copied().collect(),
            ),
            (
                "tau",
                robot
                    .inverse_dynamics(&case.q, &case.qd, &case.qdd)
                    .iter()
                    .copied()
                    .collect(),
                case.tau.iter().copied().collect(),
            ),
        ];
        for (name, got, want) in checks {
            let excess = worst_excess(got.iter().copied(), want.iter(), abs, rel);
            worst_error = worst_error.max(max_abs_error(got.iter().copied(), want.iter()));
            assert!(
                excess <= 0.0,
                "case {index}: {name} off by {excess:e} beyond 1e-9 abs + 1e-9 rel\n got {got:?}\nwant {want:?}"
            );
        }
    }
    println!("f64: worst absolute error over all quantities and cases = {worst_error:.3e}");
}

fn to_f32(v: &Vector6<f64>) -> JointVector<f32> {
    v.map(|x| x as f32)
}

fn widen<R: RealField + Copy + Into<f64>>(values: impl IntoIterator<Item = R>) -> Vec<f64> {
    values.into_iter().map(Into::into).collect()
}

/// f32 bound, derived: every quantity here is a sum of products formed along the chain, each
/// operation adding at most one rounding of `eps = 2^-23 ~ 1.19e-7` relative to the magnitude it
/// carries, and the inputs q, qd, qdd and the parameters themselves are rounded to f32
/// (relative `eps / 2`). A quantity whose entries are at most `S` in size then errs by at most
/// about `K * eps * S`, where `K` counts the roundings that accumulate on one path plus the
/// sensitivity of the result to the rounded inputs. The deepest path is the RNEA: 6 links out
/// and 6 back, about 10 dependent roundings per link per sweep (rotation, two cross products,
/// inertia product, sums): `K <= 2 * 6 * 10 = 120`; the joint angles enter through sin/cos with
/// a lever arm of at most ~1 m (reach) times |q| <= 4.7 rad, which adds at most about 5 to the
/// factor. We take `K = 128`, i.e. `tol = 128 * eps * (S + 1e-3)` per quantity per case (the
/// 1e-3 floor covers quantities whose scale collapses, like a near-zero column). The worst
/// measured error is reported by the test and sits well below this (see the assertion message).
fn f32_tolerance(scale: f64) -> f64 {
    128.0 * f64::from(f32::EPSILON) * (scale + 1e-3)
}

#[test]
fn f32_matches_every_reference_quantity_within_derived_bound() {
    let robot = Puma560::<f64>::new().cast::<f32>();
    let mut worst_ratio: f64 = 0.0;
    let mut worst_by_quantity = std::collections::BTreeMap::<&str, (f64, f64)>::new();
    for (index, case) in load_cases().iter().enumerate() {
        let (q, qd, qdd) = (to_f32(&case.q), to_f32(&case.qd), to_f32(&case.qdd));
        let checks: [(&str, Vec<f64>, Vec<f64>); 7] = [
            (
                "fk",
                widen(robot.forward_kinematics_matrix(&q).iter().copied()),
                case.fk.iter().copied().collect(),
            ),
            (
                "jacob0",
                widen(robot.jacobian(&q).iter().copied()),
                case.jacob0.iter().copied().collect(),
            ),
            (
                "jdot_qd",
                widen(robot.jacobian_dot_qd(&q, &qd).iter().copied()),
                case.jdot_qd.iter().copied().collect(),
            ),
            (
                "M",
                widen(robot.mass_matrix(&q).iter().copied()),
                case.mass.iter().copied().collect(),
            ),
            (
                "G",
                widen(robot.gravity_torque(&q).iter().copied()),
                case.gravity.iter().copied().collect(),
            ),
            (
                "Cqd",
                widen(robot.coriolis_torque(&q, &qd).iter().copied()),
                case.coriolis.iter().copied().collect(),
            ),
            (
                "tau",
                widen(robot.inverse_dynamics(&q, &qd, &qdd).iter().copied()),
                case.tau.iter().copied().collect(),
            ),
        ];
        for (name, got, want) in checks {
            let tolerance = f32_tolerance(max_abs(want.iter()));
            let error = max_abs_error(got.iter().copied(), want.iter());
            worst_ratio = worst_ratio.max(error / tolerance);
            let entry = worst_by_quantity.entry(name).or_insert((0.0, 0.0));
            *entry = (entry.0.max(error), entry.1.max(error / tolerance));
            assert!(
                error <= tolerance,
                "case {index}: f32 {name} off by {error:e} > derived bound {tolerance:e}"
            );
        }
    }
    for (name, (error, ratio)) in &worst_by_quantity {
        println!("f32 {name}: worst abs error {error:.3e}, worst error / bound {ratio:.4}");
    }
    println!("f32: worst error / derived bound = {worst_ratio:.4}");
    // The bound must not be vacuous: the f32 model really is less accurate than f64 here.
    assert!(
        worst_ratio > 1e-4,
        "f32 errors suspiciously small: {worst_ratio:e}"
    );
}

#[test]
fn anchor_fk_at_zero_is_identity_rotation_at_known_point() {
    let robot = Puma560::<f64>::new();
    let pose = robot.forward_kinematics_matrix(&JointVector::zeros());
    let mut expected = Matrix4::identity();
    expected[(0, 3)] = 0.4318 + 0.0203;
    expected[(1, 3)] = -0.15005;
    expected[(2, 3)] = 0.67183 + 0.4318;
    assert!((pose - expected).abs().max() < 1e-12, "fk(qz) = {pose}");
}

fn nominal() -> JointVector<f64> {
    use std::f64::consts::PI;
    JointVector::from([0.0, PI / 4.0, -PI, 0.0, PI / 4.0, 0.0])
}

#[test]
fn anchor_gravity_and_mass_diagonal_at_qn() {
    let robot = Puma560::<f64>::new();
    let gravity = robot.gravity_torque(&nominal());
    let expected_gravity = [0.0, 31.63988, 6.03514, 0.0, 0.02825, 0.0];
    for (got, want) in gravity.iter().zip(expected_gravity) {
        assert!((got - want).abs() < 1e-5, "G(qn) = {gravity}");
    }
    let diagonal = robot.mass_matrix(&nominal()).diagonal();
    let expected_diagonal = [2.87535, 2.08893, 0.36097, 0.00174, 0.00064, 0.00004];
    for (got, want) in diagonal.iter().zip(expected_diagonal) {
        assert!((got - want).abs() < 1e-5, "diag M(qn) = {diagonal}");
    }
}
