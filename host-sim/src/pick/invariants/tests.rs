//! Each invariant fed a trajectory that breaks it, and a safe one that does not.

use super::*;

const CAMERA: [f64; 3] = [0.6, -0.2, 2.4];
const DISC_CENTRE: [f64; 3] = [0.0, 0.75, 0.25];
const DISC_RADIUS: f64 = 0.45;

fn model() -> Puma560<f64> {
    Puma560::<f64>::new()
}

fn ready() -> JointVector<f64> {
    shared::planning::ready_posture()
}

fn tool(q: &JointVector<f64>) -> Vector3<f64> {
    shared::app::tool::tool_point_base(&model().forward_kinematics(q))
}

/// The arm at `q` at rest, the part far away, a modest torque.
fn at_rest(q: JointVector<f64>) -> PeriodTruth {
    PeriodTruth {
        q,
        qd: JointVector::zeros(),
        part_base_m: Vector3::new(-1.0, -1.0, 0.3),
        part_velocity_base_m_s: Vector3::zeros(),
        part_held: false,
        applied_torque_ratio: 0.4,
    }
}

/// The violations of `trajectory` in the standard cell (or `camera`, `disc`).
fn run(trajectory: &[PeriodTruth], camera: [f64; 3], disc: [f64; 3]) -> Vec<String> {
    let mut monitor = SafetyMonitor::new(&model(), camera, disc, DISC_RADIUS);
    for truth in trajectory {
        monitor.observe(truth);
    }
    monitor.worst().violations()
}

/// A move from the ready posture to `end` in 100 periods.
fn move_to(end: JointVector<f64>) -> Vec<PeriodTruth> {
    (0..=100)
        .map(|k| at_rest(ready() + (end - ready()) * (f64::from(k) / 100.0)))
        .collect()
}

fn only(found: &[String], expected: &str) {
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].contains(expected), "{found:?}");
}

#[test]
fn a_safe_trajectory_breaks_nothing() {
    let mut end = ready();
    end[0] = 0.5;
    let found = run(&move_to(end), CAMERA, DISC_CENTRE);
    assert!(found.is_empty(), "{found:?}");
}

#[test]
fn a_joint_past_its_range_is_caught() {
    let mut end = ready();
    end[0] = 161_f64.to_radians();
    only(
        &run(&move_to(end), CAMERA, DISC_CENTRE),
        "past the end of its range",
    );
}

#[test]
fn a_joint_over_its_speed_is_caught() {
    let mut truth = at_rest(ready());
    truth.qd[3] = 1.05 * model().joint_limits().velocity_max[3];
    only(&run(&[truth], CAMERA, DISC_CENTRE), "joint speed");
}

#[test]
fn a_gripper_low_over_the_disc_is_caught() {
    let p = tool(&ready());
    let disc = [p.x + 0.2, p.y, p.z - 0.015];
    only(&run(&move_to(ready()), CAMERA, disc), "above the disc");
    // Holding the part, the same height is no strike.
    let held: Vec<PeriodTruth> = move_to(ready())
        .into_iter()
        .map(|mut t| {
            t.part_held = true;
            t
        })
        .collect();
    assert!(run(&held, CAMERA, disc).is_empty());
}

#[test]
fn an_arm_into_the_camera_is_caught() {
    let p = tool(&ready());
    let camera = [p.x + 0.12, p.y, p.z + 0.05];
    only(
        &run(&move_to(ready()), camera, DISC_CENTRE),
        "from the camera",
    );
}

#[test]
fn links_folded_into_each_other_are_caught() {
    let limits = *model().joint_limits();
    // The first posture on a grid of joints 2, 3 and 5 whose links overlap.
    let mut folded = None;
    'search: for i in 0..=20 {
        for k in 0..=20 {
            for m in 0..=10 {
                let mut q = ready();
                let at = |j: usize, n: f64, of: f64| {
                    limits.position_min[j]
                        + (limits.position_max[j] - limits.position_min[j]) * n / of
                };
                q[1] = at(1, f64::from(i), 20.0);
                q[2] = at(2, f64::from(k), 20.0);
                q[4] = at(4, f64::from(m), 10.0);
                if self_clearance(&arm_capsules(&model(), &q)) < 0.0
                    && joint_limit_margin(&model(), &q) > 0.0
                {
                    folded = Some(q);
                    break 'search;
                }
            }
        }
    }
    let folded = folded.expect("some posture folds the arm into itself");
    let trajectory = [at_rest(ready()), at_rest(folded)];
    let found = run(&trajectory, [5.0, 5.0, 2.4], [5.0, -5.0, 0.25]);
    assert!(
        found.iter().any(|v| v.contains("from each other")),
        "{found:?}"
    );
}

#[test]
fn a_gripper_fast_near_the_part_is_caught() {
    let q = ready();
    let p = tool(&q);
    let mut truth = at_rest(q);
    // Joint 1 turning at 1 rad/s moves the gripper at its distance from the
    // axis; the part 3 cm ahead of it.
    truth.qd[0] = 1.0;
    assert!(p.xy().norm() > 0.3);
    let ahead = Vector3::new(0.0, 0.0, 1.0).cross(&p).normalize();
    truth.part_base_m = p + ahead * 0.03;
    only(&run(&[truth], CAMERA, DISC_CENTRE), "of the part");
    // The part 3 cm behind: the gripper moves away from it.
    let mut behind = truth;
    behind.part_base_m = p - ahead * 0.03;
    assert!(run(&[behind], CAMERA, DISC_CENTRE).is_empty());
    // The part moving with the gripper: no relative speed, nothing to catch.
    truth.part_velocity_base_m_s = Vector3::new(0.0, 0.0, 1.0).cross(&p);
    assert!(run(&[truth], CAMERA, DISC_CENTRE).is_empty());
    // Holding it, the gripper may move the part at any speed its joints allow.
    truth.part_velocity_base_m_s = Vector3::zeros();
    truth.part_held = true;
    assert!(run(&[truth], CAMERA, DISC_CENTRE).is_empty());
}

#[test]
fn an_applied_torque_over_its_limit_is_caught() {
    let mut trajectory = move_to(ready());
    trajectory[50].applied_torque_ratio = 1.02;
    only(&run(&trajectory, CAMERA, DISC_CENTRE), "applied torque");
}

#[test]
fn segment_distances_match_the_geometry() {
    let z = Vector3::zeros();
    let x = Vector3::x();
    // Crossing segments, parallel segments, a point and a segment.
    let d = segment_distance(
        &z,
        &x,
        &Vector3::new(0.5, -1.0, 0.3),
        &Vector3::new(0.5, 1.0, 0.3),
    );
    assert!((d - 0.3).abs() < 1e-12);
    let d = segment_distance(
        &z,
        &x,
        &Vector3::new(2.0, 0.4, 0.0),
        &Vector3::new(3.0, 0.4, 0.0),
    );
    assert!((d - (1.0_f64 + 0.16).sqrt()).abs() < 1e-12);
    let d = segment_distance(
        &z,
        &x,
        &Vector3::new(0.5, 0.2, 0.0),
        &Vector3::new(0.5, 0.2, 0.0),
    );
    assert!((d - 0.2).abs() < 1e-12);
}
