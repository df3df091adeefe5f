//! The f32 controller model against the f64 plant model on seeded random states (beyond the 32
//! reference cases), including the f32 forward dynamics with a perturbation-theory bound.

use nalgebra::{Matrix6, Vector6};
use shared::robot::{DriveOptions, JointVector, Puma560};

/// SplitMix64, uniform in [lo, hi).
struct Rng(u64);

impl Rng {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        lo + (hi - lo) * ((z >> 11) as f64 / (1u64 << 53) as f64)
    }

    fn vector(&mut self, lo: &JointVector<f64>, hi: &JointVector<f64>) -> JointVector<f64> {
        JointVector::from_fn(|i, _| self.uniform(lo[i], hi[i]))
    }
}

/// The per-entry f32 bound of `puma560_reference.rs`: `128 * eps * (S + 1e-3)` for a quantity of
/// magnitude `S` (derivation there: ~120 dependent roundings on the deepest RNEA path plus the
/// sensitivity to the rounded inputs).
fn entry_bound(scale: f64) -> f64 {
    128.0 * f64::from(f32::EPSILON) * (scale + 1e-3)
}

fn narrow(v: &JointVector<f64>) -> JointVector<f32> {
    v.map(|x| x as f32)
}

fn widen(v: &JointVector<f32>) -> JointVector<f64> {
    v.map(f64::from)
}

fn widen_matrix(m: &Matrix6<f32>) -> Matrix6<f64> {
    m.map(f64::from)
}

fn plant() -> Puma560<f64> {
    Puma560::new().with_drive(DriveOptions {
        armature: true,
        friction: true,
    })
}

#[test]
fn f32_dynamics_terms_stay_within_the_derived_bound_on_random_states() {
    let model64 = plant();
    let model32: Puma560<f32> = model64.cast();
    let limits = *model64.joint_limits();
    let mut rng = Rng(101);
    let mut worst_ratio: f64 = 0.0;
    for _ in 0..500 {
        // Round the state first so both models see the same inputs; what remains is arithmetic.
        let q = widen(&narrow(
            &rng.vector(&limits.position_min, &limits.position_max),
        ));
        let qd = widen(&narrow(
            &rng.vector(&(-limits.velocity_max), &limits.velocity_max),
        ));
        let qdd = widen(&narrow(&JointVector::from_fn(|_, _| {
            rng.uniform(-5.0, 5.0)
        })));
        let tau64 = model64.inverse_dynamics(&q, &qd, &qdd);
        let tau32 = widen(&model32.inverse_dynamics(&narrow(&q), &narrow(&qd), &narrow(&qdd)));
        let mass64 = model64.mass_matrix(&q);
        let mass32 = widen_matrix(&model32.mass_matrix(&narrow(&q)));
        for (error, bound) in [
            ((tau32 - tau64).abs().max(), entry_bound(tau64.abs().max())),
            (
                (mass32 - mass64).abs().max(),
                entry_bound(mass64.abs().max()),
            ),
        ] {
            worst_ratio = worst_ratio.max(error / bound);
            assert!(
                error <= bound,
                "f32 error {error:e} > bound {bound:e} at q = {q}"
            );
        }
    }
    println!("f32 vs f64 on random states: worst error / bound = {worst_ratio:.4}");
}

/// Forward dynamics solves `M qdd = r`. Normwise perturbation theory for a linear system: with
/// `||dM|| <= e_M` and `||dr|| <= e_r` (2-norms), `||dqdd|| <= ||M^-1|| (e_M ||qdd|| + e_r) /
/// (1 - ||M^-1|| e_M)`. The entries of M and r carry the per-entry bound above, so
/// `e_M <= 6 * entry_bound(max|M|)` (2-norm <= n * max entry) and
/// `e_r <= sqrt(6) * entry_bound(max|tau| + max|b|)`; the f32 Cholesky solve is backward stable
/// with an error of a few `6 eps ||M||`, far inside `e_M`. With the armature on (the plant and
/// controller models), `||M^-1|| <= 1 / 0.17 kg m^2`. The bound is worst-case and loose (the
/// measured errors use about 1e-4 of it, printed below); what it guarantees is that the f32
/// solve never loses more than ~0.3% of `||qdd||` plus the rounding of r, i.e. the f32 plant
/// model is well conditioned with armature on. (Without armature M's smallest eigenvalue drops
/// to ~4e-5 kg m^2 and this guarantee no longer holds in f32: use f64 for the rigid plant.)
#[test]
fn f32_forward_dynamics_stays_within_the_perturbation_bound() {
    let model64 = plant();
    let model32: Puma560<f32> = model64.cast();
    let limits = *model64.joint_limits();
    let mut rng = Rng(103);
    let mut worst_ratio: f64 = 0.0;
    for _ in 0..500 {
        let q = widen(&narrow(
            &rng.vector(&limits.position_min, &limits.position_max),
        ));
        let qd = widen(&narrow(
            &rng.vector(&(-limits.velocity_max), &limits.velocity_max),
        ));
        let tau = widen(&narrow(
            &rng.vector(&(-limits.torque_max), &limits.torque_max),
        ));
        let qdd64 = model64.forward_dynamics(&q, &qd, &tau).expect("SPD");
        let qdd32 = widen(
            &model32
                .forward_dynamics(&narrow(&q), &narrow(&qd), &narrow(&tau))
                .expect("SPD in f32"),
        );
        let mass = model64.mass_matrix(&q);
        let bias = model64.inverse_dynamics(&q, &qd, &JointVector::zeros());
        let inverse_norm = 1.0 / mass.symmetric_eigenvalues().min();
        let e_mass = 6.0 * entry_bound(mass.abs().max());
        let e_rhs = 6f64.sqrt() * entry_bound(tau.abs().max() + bias.abs().max());
        let denominator = 1.0 - inverse_norm * e_mass;
        assert!(denominator > 0.5, "perturbation bound not applicable");
        let bound = inverse_norm * (e_mass * qdd64.norm() + e_rhs) / denominator;
        let error = (qdd32 - qdd64).norm();
        worst_ratio = worst_ratio.max(error / bound);
        assert!(
            error <= bound,
            "f32 qdd error {error:e} > bound {bound:e} at q = {q}"
        );
    }
    println!("f32 forward dynamics: worst error / perturbation bound = {worst_ratio:.4}");
    assert!(
        worst_ratio > 1e-7,
        "f32 path not exercised (identical to f64)"
    );
}

#[test]
fn f32_jacobian_and_bias_track_f64() {
    let model64 = Puma560::<f64>::new();
    let model32: Puma560<f32> = model64.cast();
    let limits = *model64.joint_limits();
    let mut rng = Rng(107);
    for _ in 0..500 {
        let q = widen(&narrow(
            &rng.vector(&limits.position_min, &limits.position_max),
        ));
        let qd = widen(&narrow(
            &rng.vector(&(-limits.velocity_max), &limits.velocity_max),
        ));
        let (jacobian64, bias64) = model64.jacobian_and_bias(&q, &qd);
        let (jacobian32, bias32) = model32.jacobian_and_bias(&narrow(&q), &narrow(&qd));
        let jacobian_error = (widen_matrix(&jacobian32) - jacobian64).abs().max();
        let bias_error = (bias32.map(f64::from) - bias64).abs().max();
        assert!(jacobian_error <= entry_bound(jacobian64.abs().max()));
        assert!(bias_error <= entry_bound(Vector6::abs(&bias64).max()));
    }
}
