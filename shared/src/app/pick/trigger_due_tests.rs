//! [`PickController::camera_trigger_due`] against the period itself: a board
//! that latches its encoders at the trigger edge decides before it reads them,
//! so the answer must be the period's own decision for every sample time.

use heapless::Vec;

use super::settings::PickSettings;
use super::PickController;
use crate::protocol::SensorSample;

#[test]
fn the_trigger_asked_for_before_a_period_is_the_one_the_period_fires() {
    let config = crate::test_cell::test_cell_config(4096, 4);
    let mut controller = PickController::new(&config, PickSettings::default(), 1)
        .unwrap_or_else(|e| panic!("{}", e.field));
    // Irregular periods (a ticker on a loaded emulator): 1 to 9 ms, from a
    // start that is not a multiple of anything, for about 5 s.
    let mut time_us = 1_234_567_u64;
    let mut fired = 0;
    for seq in 0..1_000u32 {
        let due = controller.camera_trigger_due(time_us);
        let sample = SensorSample {
            seq,
            time_us,
            joint_counts: [0; 6],
            conveyor_counts: seq.wrapping_mul(3),
            part_in_gripper: false,
            joint_pots_rad: [0.0; 6],
            joint_index_counts: SensorSample::NO_INDEX,
        };
        let mut out = Vec::new();
        let command = controller.on_sensor_sample(&sample, &mut out);
        assert_eq!(
            due,
            command.camera_trigger.is_some(),
            "sample {seq} at {time_us} us"
        );
        fired += usize::from(due);
        time_us += 1_000 + u64::from(seq.wrapping_mul(2_654_435_761) % 8_000);
    }
    // About 5 s at 5 Hz: the rule fired, not just agreed on "never".
    let camera_hz = 1_000.0 / f64::from(config.camera_period_ms);
    assert!(fired as f64 > 0.8 * camera_hz * 4.0, "{fired} triggers");
}
