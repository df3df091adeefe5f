//! Building the world of one experiment: the drawn workcell, the plant with
//! its true link masses, the encoders, the conveyor (its stop chosen so that the
//! part comes to rest in front of the robot), the camera, and the user's
//! measurement of the disc's height. The layout is drawn clear of the user's
//! drop-off.

use std::f64::consts::TAU;

use anyhow::{bail, Context, Result};
use nalgebra::Vector3;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use shared::app::pick::settings::PickSettings;
use shared::fusion::CounterWidth;
use shared::robot::JointVector;

use super::{
    mean, PartState, World, DROP_OFF_CLEARANCE_M, MAX_LAYOUT_DRAWS, STOP_REACH_M,
    STOP_SEARCH_STEP_S, TOOL_PAYLOAD_COM_FLANGE_M,
};
use crate::scenario::pick::{CameraSource, LayoutKind, PickExperiment};
use crate::scenario::recording::{DiscPlacement, FeatureHeights, Scenario};
use crate::world::conveyor::{Conveyor, ConveyorProfile, ConveyorStop, MissedBurst, SpeedRamp};
use crate::world::dimensions::DISC_RADIUS_M;
use crate::world::drive::PlantDrives;
use crate::world::generator::random_workcell;
use crate::world::gripper::GraspTolerance;
use crate::world::homing_sensors::HomingSensors;
use crate::world::image_vision::ImageVision;
use crate::world::plant::{JointEncoders, RobotPlant};
use crate::world::serve::{check_serve, grasp_reachable};
use crate::world::vision::CameraSim;
use crate::world::workcell::Workcell;

/// XORed into the world's seed to seed the drives' draws.
const DRIVE_STREAM: u64 = 0xD21E_D21E_D21E_D21E;
/// XORed into the world's seed to seed the homing sensors' draws (their own
/// stream: the rest of the world is drawn as before).
const HOMING_STREAM: u64 = 0x4803_1E55_4803_1E55;

/// The recorder's scenario with this experiment's part and camera tilt: the
/// workcell generator's ranges (Section 5's setup) do the rest.
fn workcell_scenario(experiment: &PickExperiment) -> Scenario {
    let [low, high] = experiment.camera.tilt_deg;
    Scenario {
        name: experiment.name.clone(),
        pixel_sigma_px: experiment.camera.pixel_sigma_px,
        dropout_probability: experiment.camera.dropout_probability,
        outlier_probability: experiment.camera.outlier_probability,
        part_feature_count: usize::from(experiment.part.feature_count),
        feature_heights: FeatureHeights::FlatTop {
            min_m: experiment.part.height_m,
            max_m: experiment.part.height_m,
        },
        camera_tilt_deg: (low, high),
        disc_placement: DiscPlacement {
            distance_from_base_axis_m: (
                experiment.cell.disc_distance_m[0],
                experiment.cell.disc_distance_m[1],
            ),
            below_shoulder_m: (
                experiment.cell.disc_below_shoulder_m[0],
                experiment.cell.disc_below_shoulder_m[1],
            ),
            azimuth_deg: (
                experiment.cell.disc_azimuth_deg[0],
                experiment.cell.disc_azimuth_deg[1],
            ),
        },
        ..Scenario::paper()
    }
}

/// The first instant at or after `after_s` from which decelerating at
/// `deceleration` leaves the disc at rest with angle `target` (mod 2 pi). The rest
/// angle grows monotonically while the ripple's acceleration stays below the
/// deceleration, so a scan for the crossing plus bisection finds it.
fn stop_instant_for_rest_angle(
    conveyor: &Conveyor,
    after_s: f64,
    deceleration: f64,
    target: f64,
    min_speed_rad_s: f64,
) -> Result<f64> {
    let turn_index =
        |t: f64| ((conveyor.rest_angle_if_stopped_at(t, deceleration) - target) / TAU).floor();
    let horizon_s = after_s + 2.0 * TAU / min_speed_rad_s + 1.0;
    let mut t0 = after_s;
    let k0 = turn_index(t0);
    let at_target = |t: f64| {
        let d = (conveyor.rest_angle_if_stopped_at(t, deceleration) - target).rem_euclid(TAU);
        d.min(TAU - d) < 1e-12
    };
    if at_target(t0) {
        return Ok(t0);
    }
    while t0 < horizon_s {
        let t1 = t0 + STOP_SEARCH_STEP_S;
        if turn_index(t1) != k0 {
            let (mut low, mut high) = (t0, t1);
            for _ in 0..80 {
                let mid = 0.5 * (low + high);
                if turn_index(mid) == k0 {
                    low = mid;
                } else {
                    high = mid;
                }
            }
            return Ok(high);
        }
        t0 = t1;
    }
    bail!("no conveyor stop instant within {horizon_s:.1} s puts the part in front of the robot")
}

/// Whether the disc's rim keeps [`DROP_OFF_CLEARANCE_M`] from `drop_off_base`
/// (horizontally, base frame).
pub(super) fn disc_clear_of(workcell: &Workcell, drop_off_base: &Vector3<f64>) -> bool {
    let gap = (workcell.base_from_disc_translation_m - drop_off_base)
        .xy()
        .norm();
    gap >= DISC_RADIUS_M + DROP_OFF_CLEARANCE_M
}

/// A workcell from the experiment's ranges with the disc clear of the user's
/// drop-off: the world adapts its layout to the bin, never the bin to the
/// layout (layouts too close are drawn again). Of those, it keeps the ones the
/// arm can serve (`world::serve`), or the others, as `cell.layouts` asks.
pub(super) fn clear_workcell(
    rng: &mut ChaCha8Rng,
    experiment: &PickExperiment,
) -> Result<Workcell> {
    let scenario = workcell_scenario(experiment);
    let drop_off_base = Vector3::from(experiment.drop_off_base_m);
    let settings = PickSettings::default();
    for _ in 0..MAX_LAYOUT_DRAWS {
        let (workcell, _) = random_workcell(rng, &scenario)?;
        if !disc_clear_of(&workcell, &drop_off_base) {
            continue;
        }
        // The disc's top speed during the grasp: a disc that stops with the
        // part in front of the robot (`conveyor.stop`) is still when grasped.
        let conveyor = &experiment.conveyor;
        let top_speed_rad_s = if conveyor.stop.is_some() {
            0.0
        } else {
            conveyor.speed_rad_s.abs() * (1.0 + conveyor.ripple_fraction)
        };
        let keep = match experiment.cell.layouts {
            LayoutKind::Any => true,
            LayoutKind::Servable => check_serve(&workcell, &settings, top_speed_rad_s).is_ok(),
            LayoutKind::Unservable => check_serve(&workcell, &settings, top_speed_rad_s).is_err(),
        };
        if keep {
            return Ok(workcell);
        }
    }
    bail!(
        "no layout of the cell ranges in {MAX_LAYOUT_DRAWS} draws keeps the disc \
         {DROP_OFF_CLEARANCE_M} m clear of drop_off_base_m = {:?} and is {:?}",
        experiment.drop_off_base_m,
        experiment.cell.layouts
    )
}

impl World {
    pub fn new(experiment: &PickExperiment, seed: u64) -> Result<Self> {
        experiment.validate().context("pick experiment")?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let workcell = clear_workcell(&mut rng, experiment)?;
        Self::with_workcell(experiment, workcell, rng, seed)
    }

    /// The world of `experiment` around `workcell`, the rest drawn from `rng`
    /// and the drives from their own stream of `seed`.
    pub(super) fn with_workcell(
        experiment: &PickExperiment,
        workcell: Workcell,
        mut rng: ChaCha8Rng,
        seed: u64,
    ) -> Result<Self> {
        let error = experiment.robot.link_mass_error;
        let link_mass_scale: [f64; 6] =
            core::array::from_fn(|_| 1.0 - error + 2.0 * error * rng.random::<f64>());
        let camera_seed: u64 = rng.random();
        let width = match experiment.conveyor.counter_bits {
            16 => CounterWidth::Bits16,
            _ => CounterWidth::Bits32,
        };
        let start_raw = match experiment.faults.counter_counts_before_wrap {
            // Still draw, so the fault changes nothing else of the world.
            Some(before_wrap) => {
                let _ = rng.random::<u32>();
                width.max().saturating_sub(before_wrap)
            }
            None => rng.random::<u32>() & width.max(),
        };

        // The drives from a stream of their own: their draws shift nothing else of the world.
        let mut drive_rng = ChaCha8Rng::seed_from_u64(seed ^ DRIVE_STREAM);
        let drives = PlantDrives::draw(&experiment.robot.drive, &mut drive_rng);
        let gear = shared::robot::Puma560::<f64>::new();
        let mut counts_per_rad = [0.0; 6];
        for (c, drive) in counts_per_rad.iter_mut().zip(gear.drive_params().iter()) {
            *c = experiment.robot.joint_counts_per_motor_rev * drive.gear_ratio.abs() / TAU;
        }
        let encoders = JointEncoders { counts_per_rad };
        let mut homing_sensors = HomingSensors::draw(
            &experiment.robot.homing,
            &counts_per_rad,
            experiment.faults.homing,
            seed ^ HOMING_STREAM,
        )?;
        let plant = RobotPlant::new(
            link_mass_scale,
            experiment.robot.payload_kg,
            Vector3::from(TOOL_PAYLOAD_COM_FLANGE_M),
            homing_sensors.power_on_posture(&shared::planning::ready_posture()),
            drives,
        )?;

        let settings = experiment.conveyor;
        let mut conveyor = Conveyor::new(
            ConveyorProfile {
                speed_rad_s: settings.speed_rad_s,
                ripple_fraction: settings.ripple_fraction,
                ripple_hz: settings.ripple_hz,
            },
            settings.counts_per_rev,
            width,
            start_raw,
        )?;
        // A disc that does not turn needs no stop: the setting is then moot.
        if let (Some(stop), true) = (settings.stop, settings.speed_rad_s != 0.0) {
            if settings.ripple_fraction * settings.speed_rad_s.abs() * TAU * settings.ripple_hz
                >= stop.deceleration_rad_s2
            {
                bail!("conveyor.stop.deceleration_rad_s2 must exceed the ripple's acceleration");
            }
            // The part's azimuth in the rotating frame, and the robot's in the disc frame.
            let part_rotating = mean(&workcell.features_rotating);
            let robot_disc = workcell.disc_from_base(&Vector3::new(
                0.0,
                0.0,
                workcell.base_from_disc_translation_m.z,
            ));
            // On the part's circle, the point at a comfortable reach from the base
            // axis (the nearest point when the circle stays further away) where
            // the arm reaches it: the operator stops the disc with the part in
            // front of the robot. Of the circle's two such points the first the
            // arm reaches (joint 1 ends behind the robot); when neither, the
            // reachable point of the circle nearest that reach.
            let (d, r) = (robot_disc.xy().norm(), part_rotating.xy().norm());
            let cos_off = ((d * d + r * r - STOP_REACH_M * STOP_REACH_M) / (2.0 * d * r.max(1e-9)))
                .clamp(-1.0, 1.0);
            let robot_angle = robot_disc.y.atan2(robot_disc.x);
            let part_angle = part_rotating.y.atan2(part_rotating.x);
            let pick_settings = PickSettings::default();
            let part_at = |theta: f64| {
                workcell.base_from_disc(&Workcell::disc_from_rotating(theta, &part_rotating))
            };
            let candidates = [
                robot_angle + cos_off.acos() - part_angle,
                robot_angle - cos_off.acos() - part_angle,
            ];
            let target = candidates
                .into_iter()
                .find(|&theta| grasp_reachable(&part_at(theta), &pick_settings))
                .or_else(|| {
                    (0..180)
                        .map(|k| f64::from(k) * TAU / 180.0)
                        .filter(|&theta| grasp_reachable(&part_at(theta), &pick_settings))
                        .min_by(|a, b| {
                            let off = |t: f64| (part_at(t).xy().norm() - STOP_REACH_M).abs();
                            off(*a).total_cmp(&off(*b))
                        })
                })
                .unwrap_or(candidates[0]);
            let min_speed = settings.speed_rad_s.abs() * (1.0 - settings.ripple_fraction);
            let start_s = stop_instant_for_rest_angle(
                &conveyor,
                stop.after_s,
                stop.deceleration_rad_s2,
                target,
                min_speed,
            )?;
            conveyor = conveyor.with_stop(ConveyorStop {
                start_s,
                deceleration_rad_s2: stop.deceleration_rad_s2,
            })?;
        }

        if let Some(change) = experiment.faults.conveyor_change {
            conveyor = conveyor.with_speed_change(SpeedRamp {
                start_s: change.at_s,
                target_rad_s: change.speed_rad_s,
                acceleration_rad_s2: change.acceleration_rad_s2,
            })?;
        }
        if let Some(missed) = experiment.faults.missed_counts {
            conveyor = conveyor.with_missed_counts(MissedBurst {
                at_s: missed.at_s,
                counts: missed.counts,
                instant: missed.instant,
            })?;
        }

        let camera = CameraSim::new(workcell.camera.clone(), &experiment.camera, camera_seed)?;
        // The user's measurement of the disc surface's height, within its
        // tolerance (drawn in every experiment, so the stream stays the same).
        let height_error = experiment.disc_height_tolerance_m * (2.0 * rng.random::<f64>() - 1.0);
        let disc_height_measured_m = experiment
            .disc_height_known
            .then_some(workcell.base_from_disc_translation_m.z + height_error);
        let drop_off_base = Vector3::from(experiment.drop_off_base_m);
        Ok(Self {
            experiment: experiment.clone(),
            tolerance: GraspTolerance::from_settings(&experiment.gripper),
            control_period_s: 1.0 / (experiment.robot.control_rate_hz),
            workcell,
            plant,
            encoders,
            homing_sensors,
            conveyor,
            camera,
            image_vision: (experiment.camera.source == CameraSource::Images)
                .then(|| ImageVision::new(experiment, seed)),
            ticks: 0,
            sensor_seq: 0,
            part: PartState::OnDisc,
            gripper_closed: false,
            grasp: None,
            placed_base: None,
            last_tau: JointVector::zeros(),
            drop_off_base,
            disc_height_measured_m,
            camera_bumped: false,
            unattended_ticks: 0,
        })
    }
}
