//! What micromath's approximations would cost in the f32 control step,
//! measured against the reference vectors (`shared/tests/vectors/puma560-public.json`).
//!
//! The controller's model evaluates `sin`/`cos` of the six joints once per step
//! (`JointTrig`), and everything else (frame chain, Jacobian, `Jdot qd`, RNEA)
//! is built from them; the orientation error uses one `atan2` and one `sqrt`.
//! This test replaces the trig with micromath's and reports the error it
//! causes, next to the exact (libm) f32 evaluation. Cost per call on the
//! Cortex-M4F is measured by `bench-m4` (see its README section in the report).

use nalgebra::{Matrix4, Matrix6, Vector6};
use shared::control::{Joints, TaskSpaceModel};
use shared::robot::{JointTrig, Puma560, SinCos};

const VECTORS: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/vectors/puma560-public.json"
));

fn vec6(v: &serde_json::Value) -> Vector6<f64> {
    Vector6::from_iterator(v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
}

fn rows<const R: usize, const C: usize>(v: &serde_json::Value) -> nalgebra::SMatrix<f64, R, C> {
    let flat: Vec<f64> = v
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|row| row.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
        .collect();
    nalgebra::SMatrix::<f64, R, C>::from_row_slice(&flat)
}

fn micromath_trig(q: &Joints<f32>) -> JointTrig<f32> {
    JointTrig {
        joints: core::array::from_fn(|i| {
            let (sin, cos) = micromath::F32(q[i]).sin_cos();
            SinCos {
                sin: sin.0,
                cos: cos.0,
            }
        }),
    }
}

#[derive(Default, Debug)]
struct Errors {
    fk_position_m: f64,
    fk_rotation: f64,
    jacobian: f64,
    jdot_qd: f64,
    tau_nm: f64,
}

fn measure(trig_of: impl Fn(&Joints<f32>) -> JointTrig<f32>) -> Errors {
    let model = Puma560::<f64>::new().cast::<f32>();
    let json: serde_json::Value = serde_json::from_str(VECTORS).unwrap();
    let mut e = Errors::default();
    for case in json["cases"].as_array().unwrap() {
        let q = vec6(&case["q"]).cast::<f32>();
        let qd = vec6(&case["qd"]).cast::<f32>();
        let qdd = vec6(&case["qdd"]).cast::<f32>();
        let trig = trig_of(&q);
        let kin = model.task_kinematics(&trig, &qd);
        let fk: Matrix4<f64> = rows(&case["fk"]);
        let position = kin.base_from_flange.translation.vector.cast::<f64>();
        e.fk_position_m = e
            .fk_position_m
            .max((position - fk.fixed_view::<3, 1>(0, 3)).amax());
        let rotation = kin
            .base_from_flange
            .rotation
            .to_rotation_matrix()
            .into_inner()
            .cast::<f64>();
        e.fk_rotation = e
            .fk_rotation
            .max((rotation - fk.fixed_view::<3, 3>(0, 0)).amax());
        let jacobian: Matrix6<f64> = rows(&case["jacob0"]);
        e.jacobian = e
            .jacobian
            .max((kin.jacobian.cast::<f64>() - jacobian).amax());
        e.jdot_qd = e
            .jdot_qd
            .max((kin.jacobian_dot_qd.cast::<f64>() - vec6(&case["jdot_qd"])).amax());
        let tau = TaskSpaceModel::inverse_dynamics(&model, &trig, &qd, &qdd).cast::<f64>();
        e.tau_nm = e.tau_nm.max((tau - vec6(&case["tau"])).amax());
    }
    e
}

#[test]
fn micromath_trig_breaks_the_kinematic_budget_libm_does_not() {
    let exact = measure(JointTrig::new);
    let approx = measure(micromath_trig);
    let model = Puma560::<f32>::new();
    let ours = measure(|q| model.configuration(q));
    println!("f32 with libm sin/cos:      {exact:?}");
    println!("f32 with control::trig:     {ours:?}");
    println!("f32 with micromath sin/cos: {approx:?}");
    // the controller's own full-precision trig is as good as libm's
    assert!(ours.fk_position_m < 1e-5 && ours.jacobian < 1e-5 && ours.tau_nm < 1e-3);
    // exact f32 evaluation: errors at f32 rounding level
    assert!(exact.fk_position_m < 1e-5 && exact.jacobian < 1e-5 && exact.tau_nm < 1e-3);
    // micromath: millimetre-level pose error, far above the 2 mm tracking goal's budget
    assert!(approx.fk_position_m > 100.0 * exact.fk_position_m);
    assert!(approx.fk_position_m > 2e-4);
}

/// The orientation error's atan2/sqrt: relative error of micromath on the
/// small angles the tracking loop sees (1e-4 .. 1e-1 rad).
#[test]
fn micromath_atan2_sqrt_relative_error_on_small_angles() {
    let mut worst_atan2 = 0.0_f64;
    let mut worst_sqrt = 0.0_f64;
    for k in 0..400 {
        let half_angle = 1e-4_f64 * 1.02_f64.powi(k); // 1e-4 .. ~0.27
        let (s, w) = (half_angle.sin() as f32, half_angle.cos() as f32);
        let exact = f64::from(s).atan2(f64::from(w));
        let approx = f64::from(micromath::F32(s).atan2(micromath::F32(w)).0);
        worst_atan2 = worst_atan2.max(((approx - exact) / exact).abs());
        let x = (s * s) as f64;
        let approx_sqrt = f64::from(micromath::F32(s * s).sqrt().0);
        worst_sqrt = worst_sqrt.max(((approx_sqrt - x.sqrt()) / x.sqrt()).abs());
    }
    println!("micromath relative error on small orientation errors: atan2 {worst_atan2:.2e}, sqrt {worst_sqrt:.2e}");
    // several percent of gain error on the orientation loop: measurable, and
    // not worth the ~100 instructions it would save per step
    assert!(worst_atan2 > 1e-4 || worst_sqrt > 1e-4);
}
