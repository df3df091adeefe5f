//! [`PickController::on_brakes`]: an arm that the board's holding brakes
//! hold does not follow Eq 23, and the controller must not expect it to.

use heapless::Vec;

use super::settings::PickSettings;
use super::PickController;
use crate::protocol::{FaultCause, SensorSample};

/// Ten seconds of 1 ms periods with the encoders still (the arm braked where
/// it stood), `braked_from` periods in; the fault the pick reports.
fn braked_run(braked_from: Option<u32>) -> Option<FaultCause> {
    let config = crate::test_cell::test_cell_config(4096, 4);
    let mut controller = PickController::new(&config, PickSettings::default(), 1)
        .unwrap_or_else(|e| panic!("{}", e.field));
    for seq in 0..10_000u32 {
        if braked_from.is_some_and(|from| seq >= from) {
            controller.on_brakes();
        }
        let sample = SensorSample {
            seq,
            time_us: 1_000_000 + u64::from(seq) * 1_000,
            joint_counts: [0; 6],
            conveyor_counts: 0,
            part_in_gripper: false,
            joint_pots_rad: [0.0; 6],
            joint_index_counts: SensorSample::NO_INDEX,
        };
        let mut out = Vec::new();
        let _ = controller.on_sensor_sample(&sample, &mut out);
    }
    controller.fault()
}

#[test]
fn a_braked_arm_is_not_taken_for_a_faulty_encoder() {
    // Told nothing, the controller drives the search, the arm stays where
    // the brakes hold it, and the observer, expecting the commanded motion,
    // ends up refusing the encoders.
    assert_eq!(braked_run(None), Some(FaultCause::JointEncoder));
    // On the brakes from the first period the encoders agree with what the
    // controller expects of a braked arm.
    let aware = braked_run(Some(0));
    // (It stops on its tracking check: the search's reference left an arm
    // that did not move.)
    assert_ne!(aware, Some(FaultCause::JointEncoder), "told of the brakes");
}
