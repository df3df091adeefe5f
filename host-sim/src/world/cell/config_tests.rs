//! The cell configuration carries nothing read off the world's truth: worlds
//! that differ only in what the controller must find tell it the same thing,
//! the drop-off is the user's and the world's disc keeps clear of it, and a
//! known disc height is a measurement within its stated tolerance.

use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;

use super::build::{clear_workcell, disc_clear_of};
use super::World;
use crate::scenario::pick::{PickExperiment, PickScenarioFile};

fn experiment(name: &str) -> PickExperiment {
    PickScenarioFile::default_experiment(name).unwrap()
}

/// A world of `experiment` drawn from `seed` but with what the user knows of
/// `reference`'s cell (the lens, the reference mark's radius): it differs from
/// `reference` only in what is unknown (camera pose, disc pose relative to the
/// base, the part on the disc, link masses, the conveyor counter's start).
fn same_user_knowledge(experiment: &PickExperiment, reference: &World, seed: u64) -> World {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut workcell = clear_workcell(&mut rng, experiment).unwrap();
    workcell.camera.intrinsics = reference.workcell().camera.intrinsics;
    workcell.reference_radius_m = reference.workcell().reference_radius_m;
    World::with_workcell(experiment, workcell, rng, seed).unwrap()
}

#[test]
fn worlds_that_differ_only_in_the_unknown_poses_send_the_same_config() {
    for name in ["experiment-1", "turning"] {
        let experiment = experiment(name);
        let reference = World::new(&experiment, 1).unwrap();
        for seed in 2..8 {
            let other = same_user_knowledge(&experiment, &reference, seed);
            let (a, b) = (reference.workcell(), other.workcell());
            // The truths differ: the camera, the disc's place and the part.
            assert!(
                (a.base_from_disc_translation_m - b.base_from_disc_translation_m).norm() > 1e-3
            );
            assert!((a.camera.optical_centre_disc - b.camera.optical_centre_disc).norm() > 1e-3);
            assert_ne!(a.features_rotating, b.features_rotating);
            assert_eq!(
                reference.cell_config(),
                other.cell_config(),
                "{name}, seed {seed}: a configuration field follows the world's truth"
            );
        }
    }
}

#[test]
fn a_known_disc_height_is_a_measurement_within_its_tolerance() {
    let experiment = experiment("experiment-2-4cm");
    let tolerance = experiment.disc_height_tolerance_m;
    assert!((tolerance - 0.003).abs() < 1e-12);
    let reference = World::new(&experiment, 1).unwrap();
    let mut largest_error: f64 = 0.0;
    for seed in 1..40 {
        let world = same_user_knowledge(&experiment, &reference, seed);
        let mut config = world.cell_config();
        let told = f64::from(config.disc_height_in_base_m.unwrap());
        let error = told - world.workcell().base_from_disc_translation_m.z;
        assert!(error.abs() <= tolerance + 1e-6, "seed {seed}: {error}");
        largest_error = largest_error.max(error.abs());
        // Everything else is what the reference world is told.
        config.disc_height_in_base_m = reference.cell_config().disc_height_in_base_m;
        assert_eq!(config, reference.cell_config(), "seed {seed}");
    }
    // Not the truth: over 39 draws the error reaches well into the tolerance.
    assert!(largest_error > 0.5 * tolerance, "{largest_error}");
}

#[test]
fn the_world_keeps_its_disc_clear_of_the_users_drop_off() {
    let mut experiment = experiment("turning");
    // A bin at the robot's front-left, where many of the ranges' discs would stand.
    experiment.drop_off_base_m = [0.2, 0.5, 0.3];
    let drop_off = Vector3::from(experiment.drop_off_base_m);
    for seed in 1..30 {
        let world = World::new(&experiment, seed).unwrap();
        assert!(disc_clear_of(world.workcell(), &drop_off), "seed {seed}");
        assert_eq!(world.drop_off_base(), experiment.drop_off_base_m);
    }
    // A bin no layout can keep clear of is refused, by name.
    experiment.drop_off_base_m = [0.7, 0.0, 0.3];
    experiment.cell.disc_azimuth_deg = [-5.0, 5.0];
    let error = World::new(&experiment, 1).unwrap_err();
    assert!(
        format!("{error:#}").contains("drop_off_base_m"),
        "{error:#}"
    );
}
