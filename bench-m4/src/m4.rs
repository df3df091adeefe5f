//! Bare-metal entry point and measurements (see the crate docs).

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use nalgebra::{UnitQuaternion, Vector3};
use shared::control::{
    orientation_error, solve_damped, CircleTrajectory, ControllerConfig, DampingConfig, Joints,
    TaskReference, TaskSpaceController, TaskSpaceModel,
};
use shared::planning::{solve_ik, ArcLimits, ArcMove, ArcPoint, IkConfig};
use shared::robot::drive::SIMULATOR_COULOMB_WIDTH;
use shared::robot::{DriveOptions, Puma560};

use super::timer;

const CALLS: u32 = 200;

fn config() -> Option<ControllerConfig<f32>> {
    ControllerConfig::puma560().ok()
}

#[entry]
fn main() -> ! {
    let code = match run() {
        Some(()) => debug::EXIT_SUCCESS,
        None => {
            hprintln!("bench-m4: setup failed");
            debug::EXIT_FAILURE
        }
    };
    debug::exit(code);
    loop {
        cortex_m::asm::wfi();
    }
}

fn run() -> Option<()> {
    let timer = timer::DualTimer::start();
    // Controller model as in the closed-loop tests: f64 table with armature and
    // friction (tanh Coulomb law), cast to f32.
    let model = Puma560::<f64>::new()
        .with_drive(DriveOptions {
            armature: true,
            friction: true,
        })
        .try_with_coulomb_smoothing(SIMULATOR_COULOMB_WIDTH)
        .ok()?
        .cast::<f32>();
    let circle = CircleTrajectory {
        centre: Vector3::new(0.5_f32, 0.0, 0.4),
        radius: 0.3,
        angular_rate: 1.0,
        orientation: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f32::consts::PI),
    };
    let reference: TaskReference<f32> = circle.reference(0.3);
    let seed = Joints::new(0.2_f32, 0.0, -2.1, 0.0, -1.0, -2.9);
    let q = solve_ik(
        &model,
        &reference.base_from_flange,
        &seed,
        &IkConfig::default(),
    )
    .ok()?
        + Joints::repeat(1e-3);
    let qd = Joints::new(0.3_f32, -0.2, 0.4, 0.01, -0.3, 0.2);
    let mut controller = TaskSpaceController::new(config()?).ok()?;

    // `BENCH_M4_ONLY=pick` at build time (bench-m4/profile.sh): only the pick's
    // control period, so that an execution trace profiles nothing else.
    if option_env!("BENCH_M4_ONLY") == Some("pick") {
        pick_tick(&timer, &model, &q);
        return Some(());
    }
    // `BENCH_M4_ONLY=detect`: only the mark detection of one frame.
    if option_env!("BENCH_M4_ONLY") == Some("detect") {
        return detect_frame(&timer).map(|_| ());
    }
    // `BENCH_M4_ONLY=rim`: only the disc's rim in one frame.
    if option_env!("BENCH_M4_ONLY") == Some("rim") {
        return rim_frame(&timer).map(|_| ());
    }
    // `BENCH_M4_ONLY=estimate`: only the pick calibrator's two estimates.
    if option_env!("BENCH_M4_ONLY") == Some("estimate") {
        return super::estimate::estimates(&timer);
    }
    // `BENCH_M4_ONLY=interlock`: only the drive interlock's period.
    if option_env!("BENCH_M4_ONLY") == Some("interlock") {
        interlock_period(&timer);
        return Some(());
    }

    hprintln!(
        "bench-m4: instructions per call on mps2-an386 (Cortex-M4F), {} calls each",
        CALLS
    );
    let empty = timer.measure(CALLS, || black_box(()));
    hprintln!("  timer/loop overhead             {:>6}", empty);

    let step = timer.measure(CALLS, || {
        controller.step(
            &model,
            black_box(&q),
            black_box(&qd),
            black_box(&reference),
            1e-3,
        )
    });
    let out = controller.step(&model, &q, &qd, &reference, 1e-3);
    hprintln!(
        "  full f32 control step           {:>6}   (fallback {:?}, damping {}, |e_p| {} m)",
        step,
        out.fallback,
        out.damping_squared,
        out.position_error.norm()
    );

    // worst case: near the wrist singularity the damped branch (second Cholesky) runs
    let mut q_singular = q;
    q_singular[4] = 0.002;
    let reference_singular = TaskReference {
        base_from_flange: model.forward_kinematics(&q_singular),
        ..reference
    };
    let mut controller_singular = TaskSpaceController::new(config()?).ok()?;
    let step_singular = timer.measure(CALLS, || {
        controller_singular.step(
            &model,
            black_box(&q_singular),
            black_box(&qd),
            black_box(&reference_singular),
            1e-3,
        )
    });
    let out = controller_singular.step(&model, &q_singular, &qd, &reference_singular, 1e-3);
    hprintln!(
        "  full step near q5 = 0 (damped)  {:>6}   (fallback {:?}, damping {})",
        step_singular,
        out.fallback,
        out.damping_squared
    );

    let trig = model.configuration(&q);
    let kin = model.task_kinematics(&trig, &qd);
    let parts = [
        (
            "  6 x sin_cos (JointTrig)        ",
            timer.measure(CALLS, || model.configuration(black_box(&q))),
        ),
        (
            "  frame chain + J + Jdot qd      ",
            timer.measure(CALLS, || {
                model.task_kinematics(black_box(&trig), black_box(&qd))
            }),
        ),
        (
            "  orientation error (log map)    ",
            timer.measure(CALLS, || {
                orientation_error(
                    black_box(&reference.base_from_flange.rotation),
                    black_box(&kin.base_from_flange.rotation),
                )
            }),
        ),
        (
            "  solve, undamped (1 Cholesky)   ",
            timer.measure(CALLS, || {
                solve_damped(
                    black_box(&kin.jacobian),
                    black_box(&kin.jacobian_dot_qd),
                    &DampingConfig {
                        manipulability_threshold: 0.0,
                        max_damping: 0.0,
                    },
                )
            }),
        ),
        (
            "  solve, damped (2 Cholesky)     ",
            timer.measure(CALLS, || {
                solve_damped(
                    black_box(&kin.jacobian),
                    black_box(&kin.jacobian_dot_qd),
                    &DampingConfig {
                        manipulability_threshold: 1.0,
                        max_damping: 0.05,
                    },
                )
            }),
        ),
        (
            "  RNEA + armature + friction     ",
            timer.measure(CALLS, || {
                TaskSpaceModel::inverse_dynamics(
                    &model,
                    black_box(&trig),
                    black_box(&qd),
                    black_box(&qd),
                )
            }),
        ),
        (
            "  gravity torque (hold fallback) ",
            timer.measure(CALLS, || {
                TaskSpaceModel::gravity_torque(&model, black_box(&q))
            }),
        ),
    ];
    for (name, count) in parts {
        hprintln!("{} {:>6}", name, count);
    }

    pick_tick(&timer, &model, &q);
    // A frame's vision on a smart camera: the marks, and the rim from the
    // last frame's fit.
    let vision = detect_frame(&timer)? + rim_frame(&timer)?;
    hprintln!(
        "  a frame's marks and rim together {:>8}   (budget {})",
        vision,
        VISION_BUDGET
    );
    if vision > VISION_BUDGET {
        hprintln!("  a frame's vision over its budget");
        return None;
    }
    super::estimate::estimates(&timer)?;

    let x = 0.7_f32;
    let math = [
        (
            "  libm sinf + cosf (sin_cos)     ",
            timer.measure(CALLS, || libm::sincosf(black_box(x))),
        ),
        (
            "  micromath sin_cos              ",
            timer.measure(CALLS, || micromath::F32(black_box(x)).sin_cos()),
        ),
        (
            "  libm atan2f                    ",
            timer.measure(CALLS, || libm::atan2f(black_box(x), black_box(0.9))),
        ),
        (
            "  micromath atan2                ",
            timer.measure(CALLS, || {
                micromath::F32(black_box(x)).atan2(micromath::F32(black_box(0.9)))
            }),
        ),
        (
            "  libm sqrtf                     ",
            timer.measure(CALLS, || libm::sqrtf(black_box(x))),
        ),
        (
            "  micromath sqrt                 ",
            timer.measure(CALLS, || micromath::F32(black_box(x)).sqrt()),
        ),
    ];
    for (name, count) in math {
        hprintln!("{} {:>6}", name, count);
    }
    Some(())
}

/// The whole control period of the pick (`PickController::on_sensor_sample`:
/// observer, conveyor filter, state machine, motion reference, Eq 23,
/// telemetry) during the search arc, and the forward kinematics it runs.
fn pick_tick(timer: &timer::DualTimer, model: &Puma560<f32>, q: &Joints<f32>) {
    use shared::app::pick::settings::PickSettings;
    use shared::app::pick::{PickController, MAX_TICK_MESSAGES};
    use shared::protocol::{CellConfig, SensorSample};
    let config = CellConfig {
        image_width_px: 256,
        image_height_px: 256,
        f_px: 300.0,
        cx_px: 128.0,
        cy_px: 128.0,
        reference_radius_m: 0.4,
        part_feature_count: 4,
        conveyor_counts_per_rev: 4096,
        conveyor_counter_bits: 16,
        joint_counts_per_rad: [10_000.0; 6],
        disc_height_in_base_m: None,
        drop_off_base_m: [0.0, 0.55, 0.3],
        camera_period_ms: 200,
        telemetry_period_ticks: 20,
        home_at_power_on: false,
        grasp_capture_m: [0.005, 0.010],
        grasp_capture_yaw_rad: 0.052,
        disc_radius_m: None,
    };
    let Ok(mut pick) = PickController::new(&config, PickSettings::default(), 1) else {
        hprintln!("  pick tick: configuration refused");
        return;
    };
    let counts = q.map(|angle| (angle * 10_000.0) as i32);
    let mut seq = 0u32;
    let mut sample = move || {
        seq += 1;
        SensorSample {
            seq,
            time_us: u64::from(seq) * 1_000,
            joint_counts: [
                counts[0], counts[1], counts[2], counts[3], counts[4], counts[5],
            ],
            conveyor_counts: seq / 4,
            part_in_gripper: false,
            joint_pots_rad: [0.0; 6],
            joint_index_counts: SensorSample::NO_INDEX,
        }
    };
    // Into the search arc (the first sample starts it).
    for _ in 0..300 {
        let mut out = heapless::Vec::<_, MAX_TICK_MESSAGES>::new();
        let _ = pick.on_sensor_sample(&sample(), &mut out);
        while pick.pop_event().is_some() {}
    }
    let tick = timer.measure(CALLS, || {
        let mut out = heapless::Vec::<_, MAX_TICK_MESSAGES>::new();
        let command = pick.on_sensor_sample(&sample(), &mut out);
        while pick.pop_event().is_some() {}
        // The messages by reference: copying the whole queue out would
        // count a memcpy the firmware does not do.
        black_box(&out);
        black_box(command)
    });
    hprintln!(
        "  pick control period (search arc) {:>6}   (phase {:?})",
        tick,
        pick.phase()
    );
    if option_env!("BENCH_M4_ONLY").is_some() {
        return;
    }
    // What a phase change adds to its period: planning the next arc.
    let from = ArcPoint {
        radius_m: 0.55_f32,
        azimuth_rad: 0.3,
        z_m: 0.45,
        yaw_rad: 0.1,
    };
    let to = ArcPoint {
        radius_m: 0.62_f32,
        azimuth_rad: -0.4,
        z_m: 0.3,
        yaw_rad: -0.2,
    };
    hprintln!(
        "  arc plan (ArcMove::new)         {:>6}",
        timer.measure(CALLS, || ArcMove::new(
            black_box(&from),
            black_box(&to),
            &ArcLimits::default()
        )
        .is_ok())
    );
    hprintln!(
        "  forward kinematics (f32)        {:>6}",
        timer.measure(CALLS, || model.forward_kinematics(black_box(q)))
    );
}

/// Instructions a 256 x 256 frame's vision may take on a smart camera's
/// MCU: the marks, and the rim tracked from the last frame's fit.
const VISION_BUDGET: u64 = 5_000_000;

/// Mark detection of one 256 x 256 frame (`shared::detection`): light
/// falling across the frame, a faint texture and twelve bright discs of
/// radius 3 to 6 px, as in the host's criterion bench. Five calls: a frame
/// is millions of instructions. `None` (the bench fails) over the vision's
/// budget; the frame's cost otherwise.
fn detect_frame(timer: &timer::DualTimer) -> Option<u64> {
    const BUDGET: u64 = VISION_BUDGET;
    use shared::detection::{Detector, DetectorSettings, GrayImage, MAX_BLOBS};
    const SIDE: usize = 256;
    let mut pixels = [0u8; SIDE * SIDE];
    for (i, pixel) in pixels.iter_mut().enumerate() {
        let (x, y) = ((i % SIDE) as i32, (i / SIDE) as i32);
        // Ramp 60..100, a +-3 texture from a cheap hash, discs of +120.
        let texture = ((x * 7 + y * 13) ^ (x * y)) % 7 - 3;
        let mut value = 60 + 40 * (x + y) / (2 * SIDE as i32) + texture;
        for k in 0..12i32 {
            let (cx, cy, r) = (30 + 60 * (k % 4), 40 + 80 * (k / 4), 3 + k % 4);
            if (x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r {
                value += 120;
            }
        }
        *pixel = value.clamp(0, 255) as u8;
    }
    let Ok(image) = GrayImage::packed(SIDE, SIDE, &pixels) else {
        hprintln!("  detect: frame refused");
        return None;
    };
    let mut detector = Detector::new(DetectorSettings::default());
    let mut out = heapless::Vec::<_, MAX_BLOBS>::new();
    let found = detector.detect(&image, &mut out).map(|r| r.accepted);
    let cost = timer.measure(5, || {
        black_box(detector.detect(black_box(&image), &mut out).is_ok())
    });
    hprintln!(
        "  mark detection, 256 x 256 frame {:>8}   ({:?} marks; {} B working memory)",
        cost,
        found,
        Detector::WORKING_MEMORY_BYTES
    );
    if cost > BUDGET {
        hprintln!(
            "  mark detection over its budget of {} instructions",
            BUDGET
        );
        return None;
    }
    Some(cost)
}

/// The disc's rim in one 256 x 256 frame (`shared::detection::rim`): a disc
/// seen at a slant (an ellipse of 47 by 42 px), its surface at 60 grey, a
/// dark band 1.6 px wide at its edge (24) and the floor (50), by 4 x 4
/// sub-pixels, as the host's criterion bench draws it, with noise of about
/// 2 grey levels. The rim found from the disc centre (the first frame) and
/// from the last frame's fit in the next frame (a second draw of noise added), as
/// every later frame is. `None` (the bench fails) when it is not found.
fn rim_frame(timer: &timer::DualTimer) -> Option<u64> {
    use shared::detection::identify::lens::LensModel;
    use shared::detection::rim::{RimFinder, RimSettings};
    use shared::detection::GrayImage;
    const SIDE: usize = 256;
    const LENS: LensModel = LensModel {
        f_px: 290.0,
        cx: 127.5,
        cy: 127.5,
        k1: 0.0,
        k2: 0.0,
    };
    let (cx, cy, a, b) = (131.0f32, 124.0f32, 47.0f32, 42.0f32);
    let inner = 1.0 - 1.6 / 45.0;
    let mut pixels = [0u8; SIDE * SIDE];
    for (i, pixel) in pixels.iter_mut().enumerate() {
        let (x, y) = ((i % SIDE) as f32, (i / SIDE) as f32);
        let mut sum = 0.0f32;
        for k in 0..16 {
            let (dx, dy) = (0.25 * (k % 4) as f32 - 0.375, 0.25 * (k / 4) as f32 - 0.375);
            let (u, v) = ((x + dx - cx) / a, (y + dy - cy) / b);
            let s2 = u * u + v * v;
            sum += if s2 < inner * inner {
                60.0
            } else if s2 < 1.0 {
                24.0
            } else {
                50.0
            };
        }
        let light = 1.0 + 0.1 * (x - 128.0) / 128.0;
        *pixel = (light * sum / 16.0) as u8;
    }
    add_noise(&mut pixels, 0x9e37_79b9, 3);
    let mut finder = RimFinder::new(RimSettings::default());
    let centre = [f64::from(cx), f64::from(cy)];
    let first = {
        let Ok(image) = GrayImage::packed(SIDE, SIDE, &pixels) else {
            hprintln!("  rim: frame refused");
            return None;
        };
        match finder.find_from_centre(&image, &LENS, &[], centre) {
            Ok(fit) => fit,
            Err(error) => {
                hprintln!("  rim: not found ({:?})", error);
                return None;
            }
        }
    };
    // The next frame: a second draw of noise added to the first.
    add_noise(&mut pixels, 0x85eb_ca6b, 2);
    let Ok(image) = GrayImage::packed(SIDE, SIDE, &pixels) else {
        hprintln!("  rim: frame refused");
        return None;
    };
    // The next frame from the last one's fit first (the finder carries
    // that fit's levels), then the same frame from the centre.
    let mut next_iterations = 0;
    let near = timer.measure(1, || {
        next_iterations = finder
            .find_near(black_box(&image), &LENS, &[], &first, None)
            .map_or(0, |fit| fit.iterations);
    });
    let cold = timer.measure(1, || {
        black_box(
            finder
                .find_from_centre(black_box(&image), &LENS, &[], centre)
                .is_ok(),
        )
    });
    if next_iterations == 0 {
        hprintln!("  rim: not found in the next frame");
        return None;
    }
    hprintln!(
        "  rim from the centre / from the last frame {:>9} / {:>9}   ({} px, {} / {} iterations; {} B working memory)",
        cold,
        near,
        first.pixels,
        first.iterations,
        next_iterations,
        RimFinder::WORKING_MEMORY_BYTES
    );
    Some(near)
}

/// Adds uniform noise of `-amplitude..=amplitude` grey levels (xorshift
/// from `seed`), clamped to the 8 bits.
fn add_noise(pixels: &mut [u8], seed: u32, amplitude: i32) {
    let mut state = seed.max(1);
    for pixel in pixels.iter_mut() {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let draw = (state % (2 * amplitude as u32 + 1)) as i32 - amplitude;
        *pixel = (i32::from(*pixel) + draw).clamp(0, 255) as u8;
    }
}

/// What the drive interlock adds to every control period: the encoder
/// motion (positions, windowed speeds) and the checks, on a healthy arm.
fn interlock_period(timer: &timer::DualTimer) {
    use shared::safety::{DriveInterlock, EncoderMotion, InterlockSettings, PeriodInput};
    static SETTINGS: InterlockSettings = InterlockSettings::PUMA560;
    let mut lock = DriveInterlock::new(&SETTINGS);
    let mut motion = EncoderMotion::new(&[10_000.0; 6]);
    let tau = [10.0_f32, -40.0, 5.0, 1.0, -1.0, 0.5];
    let mut k = 0_i32;
    let mut period = || {
        k += 1;
        let counts = [k, -k, 2 * k, 0, 3, k / 2];
        let (q, qd) = motion.update(black_box(&counts), k as u64 * 1_000);
        lock.period(&PeriodInput {
            torque_nm: black_box(&tau),
            q_measured_rad: &q,
            qd_measured_rad_s: qd.as_ref(),
            braking: false,
        })
    };
    for _ in 0..20 {
        let _ = period();
    }
    let cost = timer.measure(CALLS, || black_box(period()));
    hprintln!(
        "  drive interlock period          {:>6}   (fault: {:?})",
        cost,
        lock.fault()
    );
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
