//! Closed-loop simulation shared by the control tests, benches and the
//! `circle_tracking` example: f64 PUMA 560 plant (armature, friction, mass
//! mismatch, unknown payload) integrated by RK4, driven by the f32 controller.
#![allow(dead_code)]

use nalgebra::{UnitQuaternion, Vector3};
use shared::control::{
    orientation_error, AxisGains, CircleTrajectory, ControlOutput, ControllerConfig, DampingConfig,
    Joints, TaskGains, TaskReference, TaskSpaceController,
};
use shared::planning::{solve_ik, IkConfig};
use shared::robot::drive::SIMULATOR_COULOMB_WIDTH;
use shared::robot::{DriveOptions, Puma560};

/// Deterministic uniform numbers in [0, 1) (splitmix64), so every run is reproducible.
pub struct SplitMix(pub u64);

impl SplitMix {
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

pub const BOTH_DRIVE_TERMS: DriveOptions = DriveOptions {
    armature: true,
    friction: true,
};

/// Flange pointing down: `base_from_flange` rotation = pi about base X.
pub fn flange_down() -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f64::consts::PI)
}

/// The task's circle: radius 0.3 m at 1 rad/s, horizontal, centred 0.5 m in
/// front of the base axis, 0.4 m above the base plane. With the flange pointing
/// down and the elbow up, the forearm is vertical where the wrist centre is
/// about 0.4 m from the base axis, so the path crosses the wrist singularity
/// (q5 = 0) twice per turn while staying inside the joint limits (margin 0.41 rad).
pub fn task_circle() -> CircleTrajectory<f64> {
    CircleTrajectory {
        centre: Vector3::new(0.5, 0.0, 0.4),
        radius: 0.3,
        angular_rate: 1.0,
        orientation: flange_down(),
    }
}

/// Elbow-up seed near the circle's start (IK converges to q ~ [0.19, -0.06, -2.07, 0, -1.01, -2.95]).
pub const IK_SEED: [f64; 6] = [0.2, 0.0, -2.1, 0.0, -1.0, -2.9];

/// Plant with model mismatch: each link mass (and inertia) scaled by 1 +/- 10 %
/// (seeded), a 1 kg payload 5 cm below the flange, armature and friction on.
/// Coulomb friction is the robot model's tanh law of the suggested width
/// (0.01 rad/s, stable under RK4 at 1 kHz) unless `switched_coulomb`, which
/// keeps the discontinuous sign law (a harsher, chattering plant).
pub fn mismatched_plant(rng: &mut SplitMix, switched_coulomb: bool) -> (Puma560<f64>, [f64; 6]) {
    let scales: [f64; 6] = core::array::from_fn(|_| rng.uniform(0.9, 1.1));
    let plant = Puma560::<f64>::new()
        .with_drive(BOTH_DRIVE_TERMS)
        .with_link_mass_scale(scales)
        .with_payload(1.0, Vector3::new(0.0, 0.0, 0.05));
    let plant = if switched_coulomb {
        plant
    } else {
        plant
            .try_with_coulomb_smoothing(SIMULATOR_COULOMB_WIDTH)
            .expect("width")
    };
    (plant, scales)
}

/// The controller's model: nominal masses, no payload, friction known within
/// `friction_scale`, Coulomb term smoothed like the plant's (a sign law on a
/// measured velocity near zero would only inject chatter).
pub fn controller_model(friction_scale: f64) -> Puma560<f32> {
    let model = Puma560::<f64>::new()
        .with_drive(BOTH_DRIVE_TERMS)
        .with_friction_scale(friction_scale);
    model
        .try_with_coulomb_smoothing(SIMULATOR_COULOMB_WIDTH)
        .expect("width")
        .cast::<f32>()
}

/// Gains used throughout: wn = 40 rad/s, critically damped, integrator pole at
/// 10 rad/s (or none for the paper's PD loop).
pub fn controller_config(integral: bool) -> ControllerConfig<f32> {
    controller_config_with(integral, 0.01)
}

pub fn controller_config_with(
    integral: bool,
    manipulability_threshold: f32,
) -> ControllerConfig<f32> {
    let pole = if integral { 10.0 } else { 0.0 };
    let gains = AxisGains::from_poles(40.0_f32, 1.0, pole).expect("valid gains");
    ControllerConfig {
        gains: TaskGains {
            position: gains,
            orientation: gains,
        },
        position_integral_limit: 0.005,
        orientation_integral_limit: 0.02,
        damping: DampingConfig {
            manipulability_threshold,
            max_damping: 0.05,
        },
    }
}

pub fn cast_reference(reference: &TaskReference<f64>) -> TaskReference<f32> {
    TaskReference {
        base_from_flange: reference.base_from_flange.cast::<f32>(),
        twist: reference.twist.cast::<f32>(),
        acceleration: reference.acceleration.cast::<f32>(),
    }
}

/// Plant state on the reference at t = 0: IK for the pose, `J^-1` for the twist.
pub fn start_on(
    plant: &Puma560<f64>,
    reference: &TaskReference<f64>,
) -> (Joints<f64>, Joints<f64>) {
    let q = solve_ik(
        plant,
        &reference.base_from_flange,
        &Joints::from(IK_SEED),
        &IkConfig {
            position_tolerance_m: 1e-12,
            orientation_tolerance_rad: 1e-12,
            ..IkConfig::default()
        },
    )
    .expect("circle start is reachable");
    let qd = plant
        .jacobian(&q)
        .lu()
        .solve(&reference.twist)
        .expect("start is not singular");
    (q, qd)
}

/// One RK4 step of the plant with the torque held over `dt`.
pub fn rk4_step(
    plant: &Puma560<f64>,
    q: &Joints<f64>,
    qd: &Joints<f64>,
    tau: &Joints<f64>,
    dt: f64,
) -> (Joints<f64>, Joints<f64>) {
    let accel = |q: &Joints<f64>, qd: &Joints<f64>| {
        plant
            .forward_dynamics(q, qd, tau)
            .expect("plant forward dynamics")
    };
    let k1v = *qd;
    let k1a = accel(q, qd);
    let k2v = qd + k1a * (dt / 2.0);
    let k2a = accel(&(q + k1v * (dt / 2.0)), &k2v);
    let k3v = qd + k2a * (dt / 2.0);
    let k3a = accel(&(q + k2v * (dt / 2.0)), &k3v);
    let k4v = qd + k3a * dt;
    let k4a = accel(&(q + k3v * dt), &k4v);
    (
        q + (k1v + k2v * 2.0 + k3v * 2.0 + k4v) * (dt / 6.0),
        qd + (k1a + k2a * 2.0 + k3a * 2.0 + k4a) * (dt / 6.0),
    )
}

/// Per-step record of a closed-loop run.
pub struct Sample {
    pub t: f64,
    pub q: Joints<f64>,
    /// True flange position error |p_d - p| of the plant (m) (f64 kinematics).
    pub position_error: f64,
    /// True flange orientation error |log(R_d R^T)| of the plant (rad).
    pub orientation_error: f64,
    pub output: ControlOutput<f32>,
}

/// Control period and run length (s).
pub struct Timing {
    pub dt: f64,
    pub duration: f64,
}

/// Runs the controller at `1/dt` against the plant on `reference(t)` for `duration` s.
pub fn run_closed_loop(
    plant: &Puma560<f64>,
    model: &Puma560<f32>,
    controller: &mut TaskSpaceController<f32>,
    reference: impl Fn(f64) -> TaskReference<f64>,
    start: (Joints<f64>, Joints<f64>),
    timing: Timing,
    mut record: impl FnMut(&Sample),
) {
    let Timing { dt, duration } = timing;
    let (mut q, mut qd) = start;
    let steps = (duration / dt).round() as usize;
    for k in 0..steps {
        let t = k as f64 * dt;
        let desired = reference(t);
        let output = controller.step(
            model,
            &q.cast::<f32>(),
            &qd.cast::<f32>(),
            &cast_reference(&desired),
            dt as f32,
        );
        let flange = plant.forward_kinematics(&q);
        record(&Sample {
            t,
            q,
            position_error: (desired.base_from_flange.translation.vector
                - flange.translation.vector)
                .norm(),
            orientation_error: orientation_error(
                &desired.base_from_flange.rotation,
                &flange.rotation,
            )
            .norm(),
            output,
        });
        (q, qd) = rk4_step(plant, &q, &qd, &output.tau.cast::<f64>(), dt);
    }
}

/// Tracking error statistics after the transient.
#[derive(Debug, Default, Clone, Copy)]
pub struct TrackingStats {
    pub max_error_m: f64,
    pub rms_error_m: f64,
    pub max_orientation_error_rad: f64,
    pub samples: usize,
    pub saturated_steps: usize,
    pub fallback_steps: usize,
    pub max_abs_tau: f64,
}

/// Tracks the task circle for `duration` s and reports errors for t >= `settle` s.
pub fn track_circle(
    seed: u64,
    friction_scale: f64,
    integral: bool,
    switched_coulomb: bool,
    duration: f64,
    settle: f64,
) -> TrackingStats {
    let mut rng = SplitMix(seed);
    let (plant, _) = mismatched_plant(&mut rng, switched_coulomb);
    let model = controller_model(friction_scale);
    let circle = task_circle();
    let start = start_on(&plant, &circle.reference(0.0));
    let mut controller =
        TaskSpaceController::new(controller_config(integral)).expect("valid config");
    let mut stats = TrackingStats::default();
    let mut sum_sq = 0.0;
    run_closed_loop(
        &plant,
        &model,
        &mut controller,
        |t| circle.reference(t),
        start,
        Timing { dt: 1e-3, duration },
        |s| {
            stats.saturated_steps += usize::from(s.output.saturated);
            stats.fallback_steps += usize::from(s.output.fallback.is_some());
            stats.max_abs_tau = stats.max_abs_tau.max(s.output.tau.amax() as f64);
            if s.t >= settle {
                stats.max_error_m = stats.max_error_m.max(s.position_error);
                stats.max_orientation_error_rad =
                    stats.max_orientation_error_rad.max(s.orientation_error);
                sum_sq += s.position_error * s.position_error;
                stats.samples += 1;
            }
        },
    );
    stats.rms_error_m = (sum_sq / stats.samples.max(1) as f64).sqrt();
    stats
}
