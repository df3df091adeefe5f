//! The pick with the vision stage in the loop (`camera.source = "images"`):
//! every frame the controller receives is rendered and labelled by the
//! project's detector and identifier; the truth only scores.

use host_sim::pick::record::{PickResult, PickRun};
use host_sim::pick::runner::run_pick_in_process;
use host_sim::scenario::pick::{CameraSource, PickExperiment, PickScenarioFile};
use shared::protocol::FaultCause;

/// The default `turning` experiment, its frames made from camera images.
fn turning_through_images() -> PickExperiment {
    let mut experiment = PickScenarioFile::default_experiment("turning").unwrap();
    experiment.camera.source = CameraSource::Images;
    experiment
}

fn pick_through_images(seed: u64) -> PickRun {
    run_pick_in_process(&turning_through_images(), seed).unwrap()
}

/// How far the part's estimate was from the truth at the grasp, m.
fn grasp_estimate_error_m(run: &PickRun) -> f64 {
    let grasp = run.grasp.as_ref().expect("a grasp");
    let [x, y, z] = grasp.estimate_error_m.expect("an estimate at the grasp");
    (x * x + y * y + z * z).sqrt()
}

/// The picks of workcells `seeds` through images succeed with the part's
/// estimate at the grasp within `limit_m` of the truth.
fn assert_part_within(seeds: &[u64], limit_m: f64) {
    for &seed in seeds {
        let run = pick_through_images(seed);
        assert_eq!(run.result, PickResult::Success, "seed {seed}");
        let error_m = grasp_estimate_error_m(&run);
        assert!(
            error_m < limit_m,
            "seed {seed}: part estimate off by {error_m} m"
        );
    }
}

/// The pick of workcell `seed` through images succeeds with a grasp.
fn assert_grasps_through_images(seed: u64) {
    let run = pick_through_images(seed);
    assert_eq!(
        run.result,
        PickResult::Success,
        "seed {seed}: {:?}",
        run.phases
    );
    assert!(run.grasp.is_some(), "seed {seed}: no grasp");
}

#[test]
fn a_pick_fed_from_images_grasps_with_every_label_right() {
    // Seeds 1 and 3 of `host-sim run --camera-source images` (not tuned on:
    // the identifier was tuned on the vision campaign's seed 2).
    for seed in [1, 3] {
        let run = pick_through_images(seed);
        let vision = run.vision.expect("the run went through images");
        assert!(vision.frames > 100, "seed {seed}: {vision:?}");
        assert!(
            vision.labels > 3 * vision.frames,
            "seed {seed}: the marks were labelled: {vision:?}"
        );
        assert_eq!(vision.wrong_labels, 0, "seed {seed}: {vision:?}");
        assert_eq!(run.result, PickResult::Success, "seed {seed}");
        let error_m = grasp_estimate_error_m(&run);
        assert!(
            error_m < 6e-3,
            "seed {seed}: part estimate off by {error_m} m"
        );
        let grasp = run.grasp.expect("a grasp");
        let yaw = grasp.estimate_yaw_error_rad.expect("a yaw at the grasp");
        assert!(
            yaw < 0.5f64.to_radians(),
            "seed {seed}: yaw off by {yaw} rad"
        );
    }
}

#[test]
fn a_search_under_a_tilted_camera_sees_the_gripper() {
    // Cells 9 and 19 of `host-sim montecarlo --camera-source images --seed 4`
    // (workcells 4_000_009 and 4_000_019, the camera tilted): they stopped
    // with `EffectorNotSeen` while the pair stage took the marks' depth from
    // their separation as if the camera looked square at them, so pairs that
    // turned with the waist failed the rigidity check (53 and 67 times).
    // With the tilt undone by the disc's image they calibrate and grasp.
    for seed in [4_000_009, 4_000_019] {
        let run = pick_through_images(seed);
        let vision = run.vision.expect("the run went through images");
        assert_eq!(vision.wrong_labels, 0, "seed {seed}: {vision:?}");
        assert_eq!(run.result, PickResult::Success, "seed {seed}");
        assert!(run.grasp.is_some(), "seed {seed}: no grasp");
    }
}

#[test]
fn the_search_sweeps_on_until_the_camera_has_shown_the_part() {
    // Cells 93 and 145 of `host-sim montecarlo --camera-source images --seed
    // 11`: the marks crossed the view 4 to 6 s in, before the front end had
    // labelled the part (it follows it round with the disc first). Halting
    // there, the first estimate had no frame of the part (CalibrationFailed);
    // holding over the disc for it, the arm hid the disc from the camera.
    // The search sweeps on, clear of the disc, until the part has been shown.
    for seed in [11_000_093, 11_000_145] {
        assert_grasps_through_images(seed);
    }
}

#[test]
fn a_reference_mark_that_lost_its_label_is_never_taken_for_a_feature() {
    // Cell 803 of `host-sim montecarlo --camera-source images --seed 10`
    // (workcell 10_000_803): the arm hid the reference mark at frame 23 and
    // its new track turned long enough to be a feature candidate before it
    // could be taken back as the reference; with the key feature hidden at
    // frame 42 the reference, two features and the key's rank made a set of
    // three, and all the part's labels were wrong from then on (296 wrong
    // labels, the part 167 mm off, the grasp missed). The features are now
    // numbered only while the reference is labelled and seen.
    let run = pick_through_images(10_000_803);
    let vision = run.vision.expect("the run went through images");
    assert_eq!(vision.wrong_labels, 0, "{vision:?}");
    assert_eq!(run.result, PickResult::Success);
    let error_m = grasp_estimate_error_m(&run);
    assert!(error_m < 15e-3, "part estimate off by {error_m} m");
}

#[test]
fn a_gripper_mark_in_a_disc_marks_place_is_never_given_its_label() {
    // Cells of `host-sim montecarlo --camera-source images --seed 11` where
    // a gripper mark took a disc mark's place within a pixel of its
    // prediction before the projection labelled the marks: sliding over
    // the reference mark during the search (172), resting half over it at
    // a calibration pose (274), half hiding the centre mark below where the
    // projection was fitted (853), riding with the part over feature 0
    // once the ride's flat points had unfitted the projection (416). Each
    // gave 1 to 4 wrong labels.
    for seed in [11_000_172, 11_000_274, 11_000_853, 11_000_416] {
        let run = pick_through_images(seed);
        let vision = run.vision.expect("the run went through images");
        assert_eq!(vision.wrong_labels, 0, "seed {seed}: {vision:?}");
        assert_eq!(run.result, PickResult::Success, "seed {seed}");
    }
}

#[test]
fn marks_seen_only_in_passing_are_looked_for_slowly_where_they_were() {
    // Cells 229 and 688 of `host-sim montecarlo --camera-source images
    // --seed 11`: a narrow view at the band's edge showed the marks in 3
    // labelled frames of the search, and held over where they were seen
    // the arm showed them no more (`EffectorNotSeen`). Slow passes to and
    // fro over where the flange was when they were seen label them.
    for seed in [11_000_229, 11_000_688] {
        assert_grasps_through_images(seed);
    }
}

#[test]
fn two_disc_objects_are_never_taken_for_the_grippers_pair() {
    // Trial 56 of `host-sim vision-campaign --seed 7 --distractors 6`: at
    // trigger 29 a part feature and a distractor, whose tracks were too
    // young to be known as turning with the disc, made the pair stage's one
    // pair of free blobs; no gripper mark was labelled right after it. A
    // young track that holds still in the disc's rotating frame as the disc
    // turns is now no pair blob.
    let mut experiment = PickScenarioFile::default_experiment("turning").unwrap();
    experiment.image.distractors = 6;
    let outcome = host_sim::front_end::campaign::run_pick(&experiment, 7, 56, 2000).unwrap();
    assert_eq!(outcome.score.mislabelled, 0, "{:?}", outcome.score);
    let right = outcome
        .score
        .right_by_class
        .get("effector")
        .copied()
        .unwrap_or(0);
    assert!(right > 100, "gripper marks right in {right} frames");
    assert!(outcome.calibrates);
}

#[test]
fn a_calibration_move_from_the_looks_end_keeps_the_joints_within_their_speed() {
    // Images seed 11, cell 701: the first calibration move, from where the
    // search's look ended at the inner radius, asked joint 2 for 0.95 of its
    // speed limit at the arcs' default pace, and the supervisor stopped the
    // pick (JointOverspeed). The worker now proves each move's pace.
    assert_grasps_through_images(11_000_701);
}

#[test]
fn a_search_that_never_saw_the_discs_reference_says_so() {
    // Images seed 11, cell 460: the part's features crowd the reference
    // mark at a small image scale and the disc is never identified, in any
    // of the search's three rounds, so no frame carries the reference (nor,
    // labelled against the disc, the gripper's pair). The stop names the
    // disc. (Cell 264 of seed 11, the disc's other such cell, identifies it
    // in the third round and picks.)
    let run = pick_through_images(11_000_460);
    assert_eq!(run.result, PickResult::Fault(FaultCause::DiscNotSeen));
    // A cell whose disc is seen and whose gripper's marks never are (marks
    // too small for the camera to resolve, with the wrist turned every way)
    // keeps `EffectorNotSeen`, after the search's last round.
    let mut experiment = turning_through_images();
    experiment.image.effector_mark_radii_m = [0.0008, 0.0006];
    let run = run_pick_in_process(&experiment, 1).unwrap();
    assert_eq!(run.result, PickResult::Fault(FaultCause::EffectorNotSeen));
    let vision = run.vision.expect("the run went through images");
    assert!(
        vision.labels > vision.frames,
        "the disc was seen: {vision:?}"
    );
    assert!(
        run.duration_s > 90.0,
        "{} s: the three rounds",
        run.duration_s
    );
}

#[test]
fn a_gripper_mark_the_forearm_cuts_is_not_taken_for_a_sighting() {
    // Cells 35 and 205 of `host-sim montecarlo --camera-source images
    // --seed 11`: the forearm hid the rim of gripper mark 0 in a third of
    // its sightings, for frames on end while the arm rested, and those
    // blobs read 0.3 to 0.8 px off its centre. The base came 3.5 to 6 mm
    // off and the part at the grasp 4.1 and 6.3 mm; with the cut blobs
    // left unlabelled, under 2 mm. In cell 563 the cut blobs shrank
    // to 16 to 19 px: 4.0 mm, 2.2 mm once blobs of that size are judged.
    assert_part_within(&[11_000_035, 11_000_205, 11_000_563], 3e-3);
}

#[test]
fn the_discs_rim_sets_the_cameras_height_where_the_reference_reads_off() {
    // Cells 747 and 489 of `host-sim montecarlo --camera-source images
    // --seed 11`: the reference mark lies within a pixel of the disc's dark
    // rim band and reads 0.05 to 0.09 px off in every frame; through it
    // alone the camera's height came off and the part at the grasp 3.6
    // and 3.0 mm. The rim, measured over its band in every frame, gives
    // the height: 0.1 and 1.4 mm.
    assert_part_within(&[11_000_747, 11_000_489], 2e-3);
}

/// How long the pick spent showing the marks at the calibration poses, s.
fn calibrating_s(run: &PickRun) -> f64 {
    let phases = &run.phases;
    phases
        .iter()
        .zip(phases.iter().skip(1))
        .filter(|(phase, _)| phase.phase == shared::protocol::PickPhase::CalibrateBase)
        .map(|(phase, next)| next.t_s - phase.t_s)
        .sum()
}

#[test]
fn a_cell_that_knows_the_part_well_enough_ends_its_calibration_early() {
    // Seed 1: through images the rim pins the camera and the estimate after
    // the third pose (one per height) meets `calibrated_sigma_*`; the
    // calibration ends there, about 5 s of poses instead of 14, and the
    // part is still known to a millimetre at the grasp. Through points
    // (0.5 px) the same cell never knows it that well and shows every pose.
    let run = pick_through_images(1);
    assert_eq!(run.result, PickResult::Success, "{:?}", run.phases);
    let early_s = calibrating_s(&run);
    assert!(
        early_s < 8.0,
        "calibrated for {early_s} s: {:?}",
        run.phases
    );
    let error_m = grasp_estimate_error_m(&run);
    assert!(error_m < 0.002, "part estimate off by {error_m} m");

    let points = PickScenarioFile::default_experiment("turning").unwrap();
    let run = run_pick_in_process(&points, 1).unwrap();
    assert_eq!(run.result, PickResult::Success, "{:?}", run.phases);
    let full_s = calibrating_s(&run);
    assert!(full_s > 12.0, "calibrated for {full_s} s: {:?}", run.phases);
}

#[test]
fn a_search_that_never_saw_both_marks_sweeps_again_with_the_wrist_turned() {
    // Cells 256 and 817 of `host-sim montecarlo --camera-source images
    // --seed 13`: the wrist hid one of the gripper's marks from the camera
    // wherever the first round of sweeps crossed its view, and the vision
    // stage, which learns the marks from frames that show both, never
    // labelled one (`EffectorNotSeen` after 39 s; through ideal points, which
    // label each mark alone, both cells picked). The sweeps run again with
    // the wrist turned a quarter turn, and the camera sees both. Cell 264 of
    // seed 11 identifies the disc only in the third round, with the wrist
    // half a turn round, and its calibration poses are found from there
    // (`DiscOutOfReach` while joint 6 seeded their inverse kinematics as
    // the search left it).
    for seed in [13_000_256, 13_000_817, 11_000_264] {
        let run = pick_through_images(seed);
        let vision = run.vision.expect("the run went through images");
        assert_eq!(vision.wrong_labels, 0, "seed {seed}: {vision:?}");
        assert_eq!(run.result, PickResult::Success, "seed {seed}");
        let calibrated_s = run.calibrated_after_s.expect("calibrated");
        assert!(
            calibrated_s > 39.0,
            "seed {seed}: calibrated after {calibrated_s} s, in the first round"
        );
    }
}

#[test]
fn a_part_the_camera_never_shows_is_named() {
    // Images seed 14, cell 92: the disc and the gripper's marks were seen,
    // the part's features never labelled; after the search's wait for the
    // part the stop said `CalibrationFailed`. Likewise a part whose marks
    // are too small to resolve. The stop names the part, under control.
    let run = pick_through_images(14_000_092);
    assert_eq!(run.result, PickResult::Fault(FaultCause::PartNotSeen));
    let mut experiment = turning_through_images();
    experiment.image.feature_mark_radius_m = 0.0006;
    experiment.image.key_feature_mark_radius_m = 0.0008;
    let run = run_pick_in_process(&experiment, 1).unwrap();
    assert_eq!(run.result, PickResult::Fault(FaultCause::PartNotSeen));
    assert!(run.grasp.is_none(), "a grasp was tried");
}

#[test]
fn the_calibration_poses_keep_the_wrist_the_marks_were_seen_with() {
    // Cell 181 of `host-sim montecarlo --camera-source images --seed 14`:
    // the camera was shown both marks only in the search's third round,
    // the wrist half a turn round. The calibration poses kept the wrist as
    // it started, which hid a mark at every one of them: the final
    // estimate had the search's 13 sightings alone, put the part 6.9 mm
    // too low (4.6 of its own sigmas) and the grasp missed.
    let run = pick_through_images(14_000_181);
    assert_eq!(run.result, PickResult::Success, "{:?}", run.phases);
    let sightings: Vec<u16> = run
        .calibrations
        .iter()
        .map(|c| c.report.effector_frames_used)
        .collect();
    let (first, last) = (sightings[0], sightings[sightings.len() - 1]);
    assert!(
        last >= first + 5,
        "the poses added {} sightings: {sightings:?}",
        last - first
    );
    // Cell 882: its wrist, half a turn round after the calibration, is the
    // wrist the intercept starts from; every grasp window was checked at
    // the gripper's other equivalent yaw, a half turn of joint 6 away, and
    // the pick stopped with `PartOutOfReach`.
    let run = pick_through_images(14_000_882);
    assert_eq!(run.result, PickResult::Success, "{:?}", run.phases);
}

#[test]
fn the_key_feature_is_no_reference_while_its_neighbours_have_no_track() {
    // Cell 955 of `host-sim montecarlo --camera-source images --seed 13`:
    // the part's two plain features, 12 px apart and moving 6 px a frame,
    // started new tracks frame after frame, and the key feature among them,
    // of the reference's size and light, looked alone: it was taken for the
    // reference in 6 frames. The neighbours' blobs count, tracked or not.
    // Cell 382 of seed 12: blobs of the reference's own light do not (a
    // gripper mark not yet known passing the true reference kept it out,
    // until the arm hid the key's neighbours and the key was taken).
    for seed in [13_000_955, 12_000_382] {
        let run = pick_through_images(seed);
        let vision = run.vision.expect("the run went through images");
        assert_eq!(vision.wrong_labels, 0, "seed {seed}: {vision:?}");
        assert!(vision.labels > vision.frames, "seed {seed}: {vision:?}");
    }
}
