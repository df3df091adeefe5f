//! The world's own tests: the conveyor's stop, gravity compensation over the
//! wire, the cell configuration, and grasps that miss or hold.

use std::f64::consts::TAU;

use nalgebra::{Isometry3, Vector3};
use shared::planning::{gripper_down_rotation, solve_ik, IkConfig};
use shared::protocol::{ActuatorCommand, GripperCommand};
use shared::robot::JointVector;

use super::*;
use crate::scenario::pick::{PickScenarioFile, StopSettings};

fn experiment(name: &str) -> PickExperiment {
    PickScenarioFile::default_experiment(name).unwrap()
}

/// A quick stop: the part is in front of the robot within a few seconds.
fn quick_stop() -> PickExperiment {
    let mut e = experiment("experiment-1");
    e.conveyor.speed_rad_s = 2.0;
    e.conveyor.stop = Some(StopSettings {
        after_s: 0.0,
        deceleration_rad_s2: 4.0,
    });
    e
}

fn command(tau: &JointVector<f64>, gripper: GripperCommand) -> ActuatorCommand {
    ActuatorCommand {
        seq: 0,
        joint_torque_nm: core::array::from_fn(|i| tau[i] as f32),
        gripper,
        camera_trigger: None,
    }
}

fn hold(world: &World) -> ActuatorCommand {
    let tau = world
        .plant()
        .model()
        .gravity_torque(&world.plant().state().q);
    command(&tau, GripperCommand::Open)
}

#[test]
fn the_disc_stops_with_the_part_in_front_of_the_robot() {
    for (seed, speed) in [(1, 2.0), (2, -2.0), (3, 0.5)] {
        let mut e = quick_stop();
        e.conveyor.speed_rad_s = speed;
        let mut world = World::new(&e, seed).unwrap();
        let stop = world.conveyor().stop().unwrap();
        assert!(stop.start_s >= 0.0 && stop.start_s < 2.0 * TAU / speed.abs() + 1.0);
        world.set_ticks(40_000);
        let part = Vector3::from(world.truth().part_base_m);
        let disc = world.workcell().base_from_disc_translation_m;
        // At the comfortable reach, or as near it as the part's circle comes.
        let (d, r) = (disc.xy().norm(), (part - disc).xy().norm());
        let wanted = STOP_REACH_M.clamp((d - r).abs(), d + r);
        let quantum = TAU / f64::from(e.conveyor.counts_per_rev);
        assert!(
            (part.xy().norm() - wanted).abs() < 2.0 * r * quantum + 1e-9,
            "seed {seed}: part {} m from the base axis, wanted {wanted}",
            part.xy().norm()
        );
        assert_eq!(world.truth().omega_rad_s, 0.0);
        assert!(Vector3::from(world.truth().part_velocity_base_m_s).norm() < 1e-12);
    }
}

#[test]
fn every_default_experiment_builds_and_stops_after_calibration() {
    let file = PickScenarioFile::embedded_default().unwrap();
    for e in &file.experiment {
        for seed in 0..4 {
            let world = World::new(e, seed).unwrap();
            match (e.conveyor.stop, world.conveyor().stop()) {
                (Some(asked), Some(chosen)) => {
                    // Within one revolution (plus margin) of the earliest instant.
                    assert!(chosen.start_s >= asked.after_s);
                    assert!(chosen.start_s < asked.after_s + TAU / 0.5 + 0.1);
                }
                (None, None) => {}
                other => panic!("{}: stop {other:?}", e.name),
            }
        }
    }
    // Same seed, same world.
    let e = experiment("turning");
    let (a, b) = (World::new(&e, 9).unwrap(), World::new(&e, 9).unwrap());
    assert_eq!(a.workcell(), b.workcell());
    assert_eq!(a.cell_config(), b.cell_config());
}

#[test]
fn gravity_compensation_holds_the_arm_still_for_two_seconds() {
    // The wire carries f32 torques: their rounding (1e-7 relative), with no
    // static friction at rest (Coulomb is smoothed), lets the arm creep by
    // about 1e-3 rad in 2 s; f64 commands hold it to 1e-6 (plant's own test).
    let mut world = World::new(&experiment("experiment-1"), 5).unwrap();
    let q0 = world.truth().q_rad;
    let tool0 = Vector3::from(world.truth().tool_base_m);
    for _ in 0..2000 {
        let c = hold(&world);
        world.apply(&c).unwrap();
    }
    let q = world.truth().q_rad;
    for (a, b) in q.iter().zip(q0.iter()) {
        assert!((a - b).abs() < 4e-3, "{q:?} vs {q0:?}");
    }
    let tool_drift = (Vector3::from(world.truth().tool_base_m) - tool0).norm();
    assert!(tool_drift < 2e-3, "{tool_drift}");
    // Without compensation the same arm falls by far more.
    let mut falling = World::new(&experiment("experiment-1"), 5).unwrap();
    for _ in 0..200 {
        falling
            .apply(&command(&JointVector::zeros(), GripperCommand::Open))
            .unwrap();
    }
    let fall = Vector3::from(falling.truth().tool_base_m) - tool0;
    assert!(fall.norm() > 0.01, "{fall}");
    assert!((world.time_s() - 2.0).abs() < 1e-9);
    assert_eq!(world.plant().saturations(), 0);
    let sample = world.sensor_sample();
    assert_eq!(sample.seq, 0);
    assert_eq!(world.sensor_sample().seq, 1);
    assert_eq!(sample.time_us, 2_000_000);
}

#[test]
fn the_cell_config_carries_nothing_calibrated() {
    let world = World::new(&experiment("experiment-1"), 6).unwrap();
    let config = world.cell_config();
    assert_eq!(config.disc_height_in_base_m, None);
    assert_eq!(config.conveyor_counter_bits, 16);
    assert_eq!(config.part_feature_count, 3);
    assert_eq!(config.camera_period_ms, 200);
    // The encoders: less the counters' power-on offsets (what homing
    // finds), the controller's (count + 0.5) / counts_per_rad recovers q.
    let mut world = world;
    let sample = world.sensor_sample();
    let q = world.truth().q_rad;
    let offsets = world.homing_sensors().counter_offsets();
    assert!(config.home_at_power_on);
    for (((count, offset), per_rad), angle) in sample
        .joint_counts
        .iter()
        .zip(offsets)
        .zip(config.joint_counts_per_rad.iter())
        .zip(q.iter())
    {
        let back = (f64::from(count.wrapping_sub(offset)) + 0.5) / f64::from(*per_rad);
        assert!((back - angle).abs() <= 0.5 / f64::from(*per_rad) + 1e-6);
    }
    // The drop-off is the user's, as the scenario sets it.
    let drop_off = config.drop_off_base_m.map(f64::from);
    for (told, set) in drop_off.iter().zip(world.experiment().drop_off_base_m) {
        assert!((told - set).abs() < 1e-6);
    }
}

#[test]
fn a_close_far_from_the_part_misses_and_is_final() {
    let mut world = World::new(&experiment("experiment-1"), 7).unwrap();
    let mut c = hold(&world);
    c.gripper = GripperCommand::Close;
    world.apply(&c).unwrap();
    let attempt = world.grasp().unwrap();
    assert!(!attempt.succeeded);
    assert!(attempt.horizontal_error_m > 0.05 || attempt.vertical_error_m > 0.05);
    assert!(!world.truth().part_held);
    // Open and close again: the knocked part is not grasped later.
    world.apply(&hold(&world)).unwrap();
    world.apply(&c).unwrap();
    assert_eq!(world.grasp(), Some(attempt));
}

#[test]
fn a_close_on_the_part_grasps_it_and_it_moves_with_the_gripper() {
    let mut grasped = 0;
    for seed in 0..8 {
        let mut world = World::new(&quick_stop(), seed).unwrap();
        world.set_ticks(10_000);
        let truth = world.truth();
        let part = Vector3::from(truth.part_base_m);
        let target = Isometry3::from_parts(
            shared::app::tool::flange_for_tool_down(&part).into(),
            gripper_down_rotation(truth.part_yaw_rad).into(),
        );
        let model = *world.plant().model();
        let Ok(q) = solve_ik(
            &model,
            &target,
            &world.plant().state().q,
            &IkConfig::default(),
        ) else {
            continue; // This draw's part is out of reach: try the next workcell.
        };
        world.set_arm(q, JointVector::zeros());
        let before = world.truth();
        assert!((Vector3::from(before.tool_base_m) - part).norm() < 1e-4);
        let mut c = hold(&world);
        c.gripper = GripperCommand::Close;
        c.camera_trigger = Some(3);
        world.apply(&c).unwrap();
        let attempt = world.grasp().unwrap();
        assert!(attempt.succeeded, "seed {seed}: {attempt:?}");
        assert!(world.truth().part_held);
        let offset =
            Vector3::from(world.truth().part_base_m) - Vector3::from(world.truth().tool_base_m);
        // Move the arm elsewhere: the part keeps its place in the gripper.
        let mut moved = q;
        moved[0] += 0.3;
        moved[2] += 0.1;
        world.set_arm(moved, JointVector::zeros());
        let after = world.truth();
        let new_offset = Vector3::from(after.part_base_m) - Vector3::from(after.tool_base_m);
        // Fixed in the flange: the base-frame offset only turns with it.
        assert!((new_offset.norm() - offset.norm()).abs() < 1e-9);
        assert!(new_offset.norm() < 1e-4);
        assert!((Vector3::from(after.part_base_m) - part).norm() > 0.1);
        // The camera sees the part where the gripper holds it.
        world.set_ticks(world.ticks + 500);
        let frames = world.due_camera_frames();
        assert_eq!(frames.len(), 1);
        // Releasing puts it down where it is.
        let mut open = hold(&world);
        open.gripper = GripperCommand::Open;
        world.apply(&open).unwrap();
        let placed = Vector3::from(world.placed_position_base().unwrap());
        assert!((placed - Vector3::from(after.part_base_m)).norm() < 0.05);
        assert!(!world.truth().part_held);
        grasped += 1;
    }
    assert!(grasped >= 2, "only {grasped} reachable workcells in 8");
}
