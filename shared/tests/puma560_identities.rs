//! Structural identities of the PUMA 560 model on seeded random states: symmetry and positive
//! definiteness of M, `tau = M qdd + C qd + G`, `Jdot qd` against a finite difference, energy
//! conservation of the free forward dynamics, and the exact effect of each drive switch.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use shared::robot::{DriveOptions, JointVector, Puma560, RobotError, SIMULATOR_COULOMB_WIDTH};

/// SplitMix64: a tiny deterministic generator so every run sees the same states.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [lo, hi).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let unit = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * unit
    }

    fn joint_vector(&mut self, lo: &JointVector<f64>, hi: &JointVector<f64>) -> JointVector<f64> {
        JointVector::from_fn(|i, _| self.uniform(lo[i], hi[i]))
    }

    fn symmetric(&mut self, bound: f64) -> JointVector<f64> {
        JointVector::from_fn(|_, _| self.uniform(-bound, bound))
    }

    /// A configuration inside the table's joint limits.
    fn configuration(&mut self, robot: &Puma560<f64>) -> JointVector<f64> {
        let limits = robot.joint_limits();
        self.joint_vector(&limits.position_min, &limits.position_max)
    }
}

const SAMPLES: usize = 200;

fn plant_options() -> DriveOptions {
    DriveOptions {
        armature: true,
        friction: true,
    }
}

#[test]
fn mass_matrix_is_symmetric_positive_definite() {
    let mut rng = Rng(7);
    for model in [
        Puma560::<f64>::new(),
        Puma560::new().with_drive(plant_options()),
        Puma560::new().with_payload(2.5, Vector3::new(0.01, -0.02, 0.1)),
    ] {
        let mut smallest_seen = f64::INFINITY;
        for _ in 0..SAMPLES {
            let q = rng.configuration(&model);
            let mass = model.mass_matrix(&q);
            // CRBA writes both triangles from one value: symmetry is exact.
            assert_eq!(mass, mass.transpose(), "M not symmetric at q = {q}");
            let eigenvalues = mass.symmetric_eigenvalues();
            let smallest = eigenvalues.min();
            smallest_seen = smallest_seen.min(smallest);
            // Smallest eigenvalue of the rigid PUMA is about 4e-5 kg m^2 (wrist roll with the
            // small link-6 Izz = 4e-5): demand a clear positive value, far above round-off.
            assert!(
                smallest > 1e-6,
                "M not positive definite at q = {q}: {eigenvalues}"
            );
        }
        println!("smallest eigenvalue of M seen: {smallest_seen:.3e} kg m^2");
    }
}

#[test]
fn inverse_dynamics_equals_mass_times_accel_plus_coriolis_plus_gravity() {
    let mut rng = Rng(11);
    let model = Puma560::<f64>::new();
    for _ in 0..SAMPLES {
        let q = rng.configuration(&model);
        let qd = rng.symmetric(2.0);
        let qdd = rng.symmetric(5.0);
        let tau = model.inverse_dynamics(&q, &qd, &qdd);
        let assembled =
            model.mass_matrix(&q) * qdd + model.coriolis_torque(&q, &qd) + model.gravity_torque(&q);
        // Two different algorithms (CRBA vs RNEA), |tau| up to ~100 N m: agree to round-off.
        let error = (tau - assembled).abs().max();
        assert!(
            error < 1e-11 * (1.0 + tau.abs().max()),
            "error {error:e} at q = {q}"
        );
    }
}

#[test]
fn coriolis_torque_is_quadratic_in_velocity() {
    // C(q, qd) qd is a quadratic form in qd: scaling qd by s scales it by s^2.
    let mut rng = Rng(12);
    let model = Puma560::<f64>::new();
    for _ in 0..SAMPLES {
        let q = rng.configuration(&model);
        let qd = rng.symmetric(2.0);
        let base = model.coriolis_torque(&q, &qd);
        let scaled = model.coriolis_torque(&q, &(qd * 3.0));
        assert!((scaled - base * 9.0).abs().max() < 1e-11 * (1.0 + scaled.abs().max()));
    }
}

#[test]
fn jacobian_dot_qd_matches_central_difference() {
    let mut rng = Rng(13);
    let model = Puma560::<f64>::new();
    let step = 1e-5;
    for _ in 0..SAMPLES {
        let q = rng.configuration(&model);
        let qd = rng.symmetric(1.0);
        let forward = model.jacobian(&(q + qd * step));
        let backward = model.jacobian(&(q - qd * step));
        let finite_difference = (forward - backward) / (2.0 * step) * qd;
        let analytic = model.jacobian_dot_qd(&q, &qd);
        let (jacobian, bias) = model.jacobian_and_bias(&q, &qd);
        assert_eq!(jacobian, model.jacobian(&q));
        assert_eq!(bias, analytic);
        // Central difference truncation ~ step^2 |J'''| ~ 1e-10, round-off ~ eps / step ~ 1e-11.
        let error = (finite_difference - analytic).abs().max();
        assert!(error < 1e-7, "Jdot qd off by {error:e} at q = {q}");
    }
}

#[test]
fn jacobian_matches_finite_difference_of_forward_kinematics() {
    let mut rng = Rng(14);
    let model = Puma560::<f64>::new();
    let step = 1e-6;
    for _ in 0..50 {
        let q = rng.configuration(&model);
        let jacobian = model.jacobian(&q);
        for joint in 0..6 {
            let mut delta = JointVector::zeros();
            delta[joint] = step;
            let plus = model.forward_kinematics_matrix(&(q + delta));
            let minus = model.forward_kinematics_matrix(&(q - delta));
            let linear =
                (plus.fixed_view::<3, 1>(0, 3) - minus.fixed_view::<3, 1>(0, 3)) / (2.0 * step);
            // Angular velocity from the skew part of Rdot R^T.
            let rotation = model
                .forward_kinematics_matrix(&q)
                .fixed_view::<3, 3>(0, 0)
                .into_owned();
            let rotation_rate: Matrix3<f64> =
                (plus.fixed_view::<3, 3>(0, 0) - minus.fixed_view::<3, 3>(0, 0)) / (2.0 * step);
            let skew = rotation_rate * rotation.transpose();
            let angular = Vector3::new(skew[(2, 1)], skew[(0, 2)], skew[(1, 0)]);
            let column = jacobian.column(joint);
            assert!((column.fixed_rows::<3>(0) - linear).abs().max() < 1e-8);
            assert!((column.fixed_rows::<3>(3) - angular).abs().max() < 1e-8);
        }
    }
}

fn kinetic_energy(model: &Puma560<f64>, q: &JointVector<f64>, qd: &JointVector<f64>) -> f64 {
    0.5 * qd.dot(&(model.mass_matrix(q) * qd))
}

/// One RK4 step of `x' = (qd, FD(q, qd, 0))`.
fn rk4_step(model: &Puma560<f64>, q: &mut JointVector<f64>, qd: &mut JointVector<f64>, h: f64) {
    let zero = JointVector::zeros();
    let accel = |q: &JointVector<f64>, qd: &JointVector<f64>| {
        model.forward_dynamics(q, qd, &zero).expect("finite, SPD")
    };
    let (q0, v0) = (*q, *qd);
    let a1 = accel(&q0, &v0);
    let (q1, v1) = (q0 + v0 * (h / 2.0), v0 + a1 * (h / 2.0));
    let a2 = accel(&q1, &v1);
    let (q2, v2) = (q0 + v1 * (h / 2.0), v0 + a2 * (h / 2.0));
    let a3 = accel(&q2, &v2);
    let (q3, v3) = (q0 + v2 * h, v0 + a3 * h);
    let a4 = accel(&q3, &v3);
    *q = q0 + (v0 + v1 * 2.0 + v2 * 2.0 + v3) * (h / 6.0);
    *qd = v0 + (a1 + a2 * 2.0 + a3 * 2.0 + a4) * (h / 6.0);
}

/// With zero torque, zero gravity and no friction the arm is a free conservative system, so
/// `E = qd^T M qd / 2` must stay constant. RK4's energy error over time T is about
/// `T * w * (w h)^4` relative, with `w` the fastest rate of the free motion. Starting from
/// |qd_i| <= 1 rad/s, energy conservation keeps every joint rate within a few rad/s (the kinetic
/// energy can only move between joints), so `w <= 5 rad/s` gives 3 s * 5 * (5e-3)^4 = 1e-8 as a
/// pessimistic bound; measured drifts are ~1e-14. We allow 1e-8 relative drift over 3 s at 1 kHz.
/// A wrong Coriolis or inertia term breaks conservation at the percent level and fails this by
/// orders of magnitude.
#[test]
fn free_motion_conserves_energy_under_rk4() {
    let mut rng = Rng(17);
    let zero_gravity =
        |model: Puma560<f64>| model.try_with_gravity(Vector3::zeros()).expect("finite");
    let models = [
        zero_gravity(Puma560::new()),
        zero_gravity(Puma560::new().with_drive(DriveOptions {
            armature: true,
            friction: false,
        })),
    ];
    for model in models {
        for _ in 0..3 {
            let mut q = rng.configuration(&model);
            let mut qd = rng.symmetric(1.0);
            let initial = kinetic_energy(&model, &q, &qd);
            let h = 1e-3;
            let mut worst: f64 = 0.0;
            for _ in 0..3000 {
                rk4_step(&model, &mut q, &mut qd, h);
                let drift = (kinetic_energy(&model, &q, &qd) - initial).abs() / initial;
                worst = worst.max(drift);
            }
            println!(
                "energy drift over 3 s: {worst:e} (armature {})",
                model.drive_options().armature
            );
            assert!(worst < 1e-8, "relative energy drift {worst:e}");
        }
    }
}

/// With friction on (smoothed Coulomb of the suggested width), zero torque and zero gravity the
/// plant can only lose energy: `dE/dt = -qd . friction(qd) <= 0` for every joint. RK4 at 1 kHz
/// must therefore show a non-increasing energy (up to its own ~1e-14 relative error) and no
/// blow-up from the stiff friction law near `qd = 0`; after 3 s the arm has nearly stopped.
#[test]
fn friction_only_dissipates_and_rk4_stays_stable_at_1khz() {
    let model = Puma560::<f64>::new()
        .with_drive(plant_options())
        .try_with_coulomb_smoothing(SIMULATOR_COULOMB_WIDTH)
        .and_then(|m| m.try_with_gravity(Vector3::zeros()))
        .expect("valid");
    let mut rng = Rng(43);
    for _ in 0..3 {
        let mut q = rng.configuration(&model);
        let mut qd = rng.symmetric(1.0);
        let initial = kinetic_energy(&model, &q, &qd);
        let mut previous = initial;
        for _ in 0..3000 {
            rk4_step(&model, &mut q, &mut qd, 1e-3);
            let energy = kinetic_energy(&model, &q, &qd);
            assert!(energy.is_finite());
            assert!(
                energy <= previous * (1.0 + 1e-12),
                "energy rose: {previous:e} -> {energy:e}"
            );
            previous = energy;
        }
        println!("friction: energy {initial:.3e} J -> {previous:.3e} J after 3 s");
        assert!(previous < 1e-3 * initial, "arm did not come to rest");
        assert!(qd.abs().max() < 0.05, "residual speed {qd}");
    }
}

#[test]
fn armature_switch_adds_exactly_the_reflected_motor_inertia() {
    use std::f64::consts::PI;
    let rigid = Puma560::<f64>::new();
    let armature = Puma560::new().with_drive(DriveOptions {
        armature: true,
        friction: false,
    });
    let qn = JointVector::from([0.0, PI / 4.0, -PI, 0.0, PI / 4.0, 0.0]);
    let diagonal = armature.mass_matrix(&qn).diagonal();
    let anchor = [3.659, 4.414, 0.938, 0.193, 0.171, 0.194];
    for (got, want) in diagonal.iter().zip(anchor) {
        assert!(
            (got - want).abs() < 1e-3,
            "diag M(qn) with armature = {diagonal}"
        );
    }
    let mut rng = Rng(19);
    for _ in 0..SAMPLES {
        let q = rng.configuration(&rigid);
        let qd = rng.symmetric(2.0);
        let qdd = rng.symmetric(5.0);
        let reflected = armature.armature_inertia();
        let difference = armature.mass_matrix(&q) - rigid.mass_matrix(&q);
        assert!(
            (difference - Matrix6::from_diagonal(&reflected))
                .abs()
                .max()
                < 1e-12
        );
        let tau_difference =
            armature.inverse_dynamics(&q, &qd, &qdd) - rigid.inverse_dynamics(&q, &qd, &qdd);
        assert!((tau_difference - reflected.component_mul(&qdd)).abs().max() < 1e-12);
        // Armature is inertia only: gravity and Coriolis are untouched.
        assert_eq!(armature.gravity_torque(&q), rigid.gravity_torque(&q));
        assert_eq!(
            armature.coriolis_torque(&q, &qd),
            rigid.coriolis_torque(&q, &qd)
        );
    }
}

#[test]
fn friction_switch_adds_exactly_viscous_and_coulomb_terms() {
    let rigid = Puma560::<f64>::new();
    let friction = Puma560::new().with_drive(DriveOptions {
        armature: false,
        friction: true,
    });
    let params = rigid.drive_params();
    let mut rng = Rng(23);
    for _ in 0..SAMPLES {
        let q = rng.configuration(&rigid);
        let qd = rng.symmetric(2.0);
        let qdd = rng.symmetric(5.0);
        let difference =
            friction.inverse_dynamics(&q, &qd, &qdd) - rigid.inverse_dynamics(&q, &qd, &qdd);
        let expected = Vector6::from_fn(|j, _| {
            let p = params[j];
            let coulomb = if qd[j] > 0.0 {
                p.coulomb_positive
            } else {
                p.coulomb_negative
            };
            p.gear_ratio * p.gear_ratio * p.viscous * qd[j] + p.gear_ratio.abs() * coulomb
        });
        assert!(
            (difference - expected).abs().max() < 1e-12,
            "{difference} vs {expected}"
        );
        // Friction is no inertia.
        assert_eq!(friction.mass_matrix(&q), rigid.mass_matrix(&q));
    }
    // At rest the Coulomb term is zero (no stiction force is invented).
    assert_eq!(
        friction.friction_torque(&JointVector::zeros()),
        JointVector::zeros()
    );
    // Joint 1 anchor: G = -62.6111, B = 1.48e-3, Tc+ = 0.395 at qd = 1 rad/s.
    let unit = JointVector::from([1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let expected_joint1 = 62.6111f64.powi(2) * 1.48e-3 + 62.6111 * 0.395;
    assert!((friction.friction_torque(&unit)[0] - expected_joint1).abs() < 1e-9);
    // Friction scale multiplies both B and Tc.
    let half = friction.with_friction_scale(0.5);
    assert!((half.friction_torque(&unit)[0] - 0.5 * expected_joint1).abs() < 1e-9);
}

#[test]
fn smoothed_coulomb_is_continuous_and_converges_to_the_switch() {
    let width = 0.01;
    let smooth = Puma560::<f64>::new()
        .with_drive(DriveOptions {
            armature: false,
            friction: true,
        })
        .try_with_coulomb_smoothing(width)
        .expect("positive width");
    let sharp = Puma560::<f64>::new().with_drive(DriveOptions {
        armature: false,
        friction: true,
    });
    let tiny = JointVector::repeat(1e-9);
    assert!(
        smooth.friction_torque(&tiny).abs().max() < 1e-4,
        "continuous through 0"
    );
    assert_eq!(
        smooth.friction_torque(&JointVector::zeros()),
        JointVector::zeros()
    );
    // Far beyond the width tanh -> 1: the smooth law equals the switched one.
    for rate in [0.5, -0.5] {
        let qd = JointVector::repeat(rate);
        let gap = (smooth.friction_torque(&qd) - sharp.friction_torque(&qd))
            .abs()
            .max();
        assert!(gap < 1e-9, "gap {gap:e} at qd = {rate}");
    }
    assert!(Puma560::<f64>::new()
        .try_with_coulomb_smoothing(0.0)
        .is_err());
}

/// Jacobian of a point fixed in frame {6} at `offset_flange`: `J_p = J_v - [R c]x J_w`.
fn point_jacobian(
    model: &Puma560<f64>,
    q: &JointVector<f64>,
    offset_flange: &Vector3<f64>,
) -> nalgebra::Matrix3x6<f64> {
    let jacobian = model.jacobian(q);
    let pose = model.forward_kinematics_matrix(q);
    let offset_base = pose.fixed_view::<3, 3>(0, 0) * offset_flange;
    let angular = jacobian.fixed_rows::<3>(3);
    jacobian.fixed_rows::<3>(0) - offset_base.cross_matrix() * angular
}

#[test]
fn payload_adds_point_mass_gravity_and_inertia() {
    let mass = 2.0;
    let offset = Vector3::new(0.02, -0.03, 0.12);
    let bare = Puma560::<f64>::new();
    let loaded = Puma560::<f64>::new().with_payload(mass, offset);
    let mut rng = Rng(29);
    for _ in 0..SAMPLES {
        let q = rng.configuration(&bare);
        let jp = point_jacobian(&bare, &q, &offset);
        // Virtual work: holding a point mass needs tau = J_p^T m (-g).
        let gravity_expected = jp.transpose() * Vector3::new(0.0, 0.0, 9.81 * mass);
        let gravity_difference = loaded.gravity_torque(&q) - bare.gravity_torque(&q);
        assert!((gravity_difference - gravity_expected).abs().max() < 1e-10);
        // Kinetic energy of a point: M gains m J_p^T J_p.
        let inertia_difference = loaded.mass_matrix(&q) - bare.mass_matrix(&q);
        assert!(
            (inertia_difference - jp.transpose() * jp * mass)
                .abs()
                .max()
                < 1e-10
        );
    }
    // Invalid payloads are rejected and leave the model as it was.
    assert_eq!(
        bare.try_with_payload(f64::NAN, offset),
        Err(RobotError::InvalidParameter {
            parameter: "payload mass"
        })
    );
    assert_eq!(bare.with_payload(-1.0, offset), bare);
}

#[test]
fn link_mass_scale_scales_rigid_dynamics_linearly() {
    let bare = Puma560::<f64>::new();
    let doubled = Puma560::<f64>::new().with_link_mass_scale([2.0; 6]);
    let mut rng = Rng(31);
    for _ in 0..SAMPLES {
        let q = rng.configuration(&bare);
        let qd = rng.symmetric(2.0);
        let qdd = rng.symmetric(5.0);
        let tau = bare.inverse_dynamics(&q, &qd, &qdd);
        assert!(
            (doubled.inverse_dynamics(&q, &qd, &qdd) - tau * 2.0)
                .abs()
                .max()
                < 1e-11 * (1.0 + tau.abs().max())
        );
    }
    // Scaling only link 2 changes the torques of joints 1-2 but not the wrist's.
    let link2 = Puma560::<f64>::new().with_link_mass_scale([1.0, 1.5, 1.0, 1.0, 1.0, 1.0]);
    let q = JointVector::from([0.3, 0.4, -0.5, 0.6, 0.7, 0.8]);
    let difference = link2.gravity_torque(&q) - bare.gravity_torque(&q);
    assert!(difference[1].abs() > 1.0);
    assert!(difference.fixed_rows::<3>(3).abs().max() < 1e-12);
    assert!(bare
        .try_with_link_mass_scale([1.0, f64::NAN, 1.0, 1.0, 1.0, 1.0])
        .is_err());
}

#[test]
fn forward_dynamics_inverts_inverse_dynamics_with_drive_terms() {
    let plant = Puma560::<f64>::new()
        .with_drive(plant_options())
        .with_payload(1.0, Vector3::new(0.0, 0.0, 0.1));
    let mut rng = Rng(37);
    for _ in 0..SAMPLES {
        let q = rng.configuration(&plant);
        let qd = rng.symmetric(2.0);
        let tau = rng.symmetric(20.0);
        let qdd = plant.forward_dynamics(&q, &qd, &tau).expect("SPD");
        let tau_back = plant.inverse_dynamics(&q, &qd, &qdd);
        assert!((tau_back - tau).abs().max() < 1e-9, "{tau_back} vs {tau}");
    }
}

#[test]
fn forward_dynamics_reports_bad_input_and_degenerate_models() {
    let model = Puma560::<f64>::new();
    let ok = JointVector::zeros();
    let mut bad = JointVector::zeros();
    bad[3] = f64::NAN;
    assert_eq!(
        model.forward_dynamics(&bad, &ok, &ok),
        Err(RobotError::NonFiniteInput {
            quantity: "q",
            joint: 4
        })
    );
    bad[3] = f64::INFINITY;
    assert_eq!(
        model.forward_dynamics(&ok, &ok, &bad),
        Err(RobotError::NonFiniteInput {
            quantity: "tau",
            joint: 4
        })
    );
    let massless = Puma560::<f64>::new().with_link_mass_scale([0.0; 6]);
    assert_eq!(
        massless.forward_dynamics(&ok, &ok, &ok),
        Err(RobotError::MassMatrixNotPositiveDefinite)
    );
    // The same massless arm with motor armature is still a valid plant.
    let driven = massless.with_drive(DriveOptions {
        armature: true,
        friction: false,
    });
    assert!(driven.forward_dynamics(&ok, &ok, &ok).is_ok());
    bad[3] = f64::NAN;
    assert_eq!(
        model.try_inverse_dynamics(&ok, &bad, &ok),
        Err(RobotError::NonFiniteInput {
            quantity: "qd",
            joint: 4
        })
    );
    assert_eq!(
        model.try_inverse_dynamics(&ok, &ok, &ok),
        Ok(model.gravity_torque(&ok))
    );
    // Errors render a message that says what and where.
    let message = format!(
        "{}",
        RobotError::NonFiniteInput {
            quantity: "qd",
            joint: 2
        }
    );
    assert!(message.contains("qd") && message.contains('2'), "{message}");
}

#[test]
fn cast_to_f32_and_back_preserves_the_model() {
    let plant = Puma560::<f64>::new()
        .with_drive(plant_options())
        .with_payload(1.5, Vector3::new(0.0, 0.01, 0.05))
        .with_link_mass_scale([1.0, 1.1, 0.9, 1.0, 1.0, 1.2])
        .with_friction_scale(0.8);
    let controller: Puma560<f32> = plant.cast();
    let back: Puma560<f64> = controller.cast();
    let q = JointVector::from([0.1, 0.7, -1.2, 0.3, -0.4, 0.5]);
    let qd = JointVector::from([0.2, -0.1, 0.3, 0.5, -0.6, 0.7]);
    let qdd = JointVector::from([1.0, -2.0, 0.5, 1.5, -1.0, 2.0]);
    let tau = plant.inverse_dynamics(&q, &qd, &qdd);
    let tau_back = back.inverse_dynamics(&q, &qd, &qdd);
    // Only the f32 rounding of the parameters separates them: relative ~1e-7.
    assert!((tau - tau_back).abs().max() < 1e-5 * (1.0 + tau.abs().max()));
    assert_eq!(back.drive_options(), plant.drive_options());
}

#[test]
fn torque_limits_hold_the_arm_and_speed_limits_are_positive() {
    let model = Puma560::<f64>::new();
    let limits = *model.joint_limits();
    let mut rng = Rng(41);
    let mut worst_gravity = JointVector::<f64>::zeros();
    for _ in 0..2000 {
        let q = rng.configuration(&model);
        worst_gravity = worst_gravity.sup(&model.gravity_torque(&q).abs());
    }
    println!("largest static gravity torque over the range: {worst_gravity}");
    for j in 0..6 {
        assert!(
            limits.torque_max[j] > 1.2 * worst_gravity[j],
            "joint {}",
            j + 1
        );
        assert!(limits.velocity_max[j] > 1.0 && limits.velocity_max[j] < 10.0);
        assert!(limits.position_min[j] < limits.position_max[j]);
    }
}
