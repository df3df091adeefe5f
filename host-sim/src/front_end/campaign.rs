//! A campaign of the vision front end over many seeded picks, with no disk:
//! each pick is rendered ([`simulate_pick`]), its frames fed straight to the
//! front end ([`FrontEnd`]), its labels scored against the truth and both
//! its logs (the front end's and the ideal one of the same frames)
//! calibrated. What `host-sim vision-campaign` prints. For diagnosis,
//! `EFFECTOR_REFUSALS` in the environment prints why each pick's gripper
//! marks went unlabelled in the projection's stage, `EFFECTOR_GAINS` each
//! pair's blobs (named from the truth) and their lights against the disc's
//! yardstick.

use std::collections::BTreeMap;

use anyhow::Result;
use rayon::prelude::*;
use serde::Serialize;
use shared::calibration::CalibrationConfig;
use shared::observation::CalibrationResult;

use super::score::{score, LabelScore};
use super::FrontEnd;
use crate::calibration::calibrate_log;
use crate::camera_recording::simulate::{simulate_pick, TrueFrame};
use crate::log::ObservationLog;
use crate::scenario::pick::PickExperiment;
use crate::vision_check::trial_seed;

/// One pick of a campaign.
#[derive(Debug, Clone, Serialize)]
pub struct PickOutcome {
    pub trial: usize,
    pub seed: u64,
    pub frames: usize,
    pub score: LabelScore,
    /// Frames with both effector points in the front end's log and in the ideal log.
    pub effector_frames: usize,
    pub ideal_effector_frames: usize,
    /// Whether each log calibrates (the refined estimate).
    pub calibrates: bool,
    pub ideal_calibrates: bool,
    /// Where both calibrate: camera height, base translation (m) and base
    /// yaw (rad) apart.
    pub difference: Option<CalibrationDifference>,
}

/// Two calibrations of the same frames, apart.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct CalibrationDifference {
    pub camera_height_m: f64,
    pub base_translation_m: f64,
    pub base_yaw_rad: f64,
}

fn difference(a: &CalibrationResult, b: &CalibrationResult) -> CalibrationDifference {
    let [p, q] = [a, b].map(|r| r.base_from_disc.translation_m);
    let yaw = (a.base_from_disc.yaw_rad - b.base_from_disc.yaw_rad + std::f64::consts::PI)
        .rem_euclid(std::f64::consts::TAU)
        - std::f64::consts::PI;
    CalibrationDifference {
        camera_height_m: (a.camera.height_m - b.camera.height_m).abs(),
        base_translation_m: ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2))
            .sqrt(),
        base_yaw_rad: yaw.abs(),
    }
}

fn refined(log: &ObservationLog) -> Option<CalibrationResult> {
    calibrate_log(log, CalibrationConfig::default())
        .ok()
        .and_then(|c| c.refined.ok())
}

/// Renders, labels, scores and calibrates the pick of `trial` of `seed`.
pub fn run_pick(
    experiment: &PickExperiment,
    seed: u64,
    trial: usize,
    max_frames: usize,
) -> Result<PickOutcome> {
    let workcell_seed = trial_seed(seed, trial);
    let mut front_end: Option<FrontEnd> = None;
    let mut truth: Vec<TrueFrame> = Vec::new();
    let mut ideal: Option<ObservationLog> = None;
    let mut sink = |frame: crate::camera_recording::simulate::SimulatedFrame<'_>| -> Result<()> {
        if front_end.is_none() {
            front_end = Some(FrontEnd::new(frame.header)?);
        }
        if let Some(front_end) = front_end.as_mut() {
            front_end.push(&frame.row, frame.pixels)?;
            if std::env::var_os("EFFECTOR_GAINS").is_some() {
                if let Some((pixels, gains)) = front_end.effector_pair() {
                    let name = |p: [f64; 2]| {
                        frame
                            .truth
                            .marks
                            .iter()
                            .filter(|m| m.shows)
                            .map(|m| (m, (m.pinhole_px[0] - p[0]).hypot(m.pinhole_px[1] - p[1])))
                            .min_by(|a, b| a.1.total_cmp(&b.1))
                            .map(|(m, d)| {
                                format!(
                                    "{}{}{}",
                                    m.kind,
                                    m.index,
                                    if d < 1.5 && m.visible { "" } else { "~" }
                                )
                            })
                            .unwrap_or_default()
                    };
                    eprintln!(
                        "GAIN {} {} {:.2} {:.2}",
                        name(pixels[0]),
                        name(pixels[1]),
                        gains[0],
                        gains[1]
                    );
                }
            }
        }
        ideal
            .get_or_insert_with(|| ObservationLog {
                header: *frame.log_header,
                frames: Vec::new(),
            })
            .frames
            .push(frame.ideal);
        truth.push(frame.truth);
        Ok(())
    };
    let recorded = simulate_pick(experiment, workcell_seed, max_frames, 1, &mut sink)?;
    let (Some(front_end), Some(ideal)) = (front_end, ideal) else {
        anyhow::bail!("the pick of seed {workcell_seed} triggered no frame");
    };
    if std::env::var_os("EFFECTOR_REFUSALS").is_some() {
        eprintln!("trial {trial} refusals {:?}", front_end.effector_refusals());
    }
    let run = front_end.run;
    let tally = score(&run.frames, &truth);
    let from_images = refined(&run.log);
    let from_ideal = refined(&ideal);
    let both = |log: &ObservationLog| log.frames.iter().filter(|f| f.effector.is_some()).count();
    Ok(PickOutcome {
        trial,
        seed: workcell_seed,
        frames: recorded.frames,
        effector_frames: both(&run.log),
        ideal_effector_frames: both(&ideal),
        calibrates: from_images.is_some(),
        ideal_calibrates: from_ideal.is_some(),
        difference: from_images
            .as_ref()
            .zip(from_ideal.as_ref())
            .map(|(a, b)| difference(a, b)),
        score: tally,
    })
}

/// The campaign's totals.
#[derive(Debug, Clone, Default, Serialize)]
pub struct CampaignTotals {
    pub picks: usize,
    pub failed_picks: usize,
    pub frames: usize,
    pub labels: usize,
    pub mislabelled: usize,
    pub right_but_off: usize,
    pub right_by_class: BTreeMap<String, usize>,
    pub visible: BTreeMap<String, usize>,
    pub effector_frames: usize,
    pub ideal_effector_frames: usize,
    pub ideal_calibrates: usize,
    pub both_calibrate: usize,
    /// Picks whose image log calibrates and ideal log does not.
    pub only_images_calibrate: usize,
    /// Largest differences where both calibrate.
    pub worst_camera_height_m: f64,
    pub worst_base_translation_m: f64,
    pub worst_base_yaw_rad: f64,
    /// Medians of the same.
    pub median_base_translation_m: f64,
    pub median_camera_height_m: f64,
    /// Picks with a mislabel, and their first examples.
    pub mislabelled_picks: Vec<(usize, Vec<String>)>,
}

/// Adds up the outcomes.
pub fn totals(outcomes: &[Result<PickOutcome>]) -> CampaignTotals {
    let mut t = CampaignTotals::default();
    let mut translations = Vec::new();
    let mut heights = Vec::new();
    for outcome in outcomes {
        let Ok(o) = outcome else {
            t.failed_picks += 1;
            continue;
        };
        t.picks += 1;
        t.frames += o.frames;
        t.labels += o.score.labels;
        t.mislabelled += o.score.mislabelled;
        t.right_but_off += o.score.right_but_off;
        for (k, v) in &o.score.right_by_class {
            *t.right_by_class.entry(k.clone()).or_default() += v;
        }
        for (k, v) in &o.score.visible {
            *t.visible.entry(k.clone()).or_default() += v;
        }
        t.effector_frames += o.effector_frames;
        t.ideal_effector_frames += o.ideal_effector_frames;
        t.ideal_calibrates += usize::from(o.ideal_calibrates);
        t.both_calibrate += usize::from(o.ideal_calibrates && o.calibrates);
        t.only_images_calibrate += usize::from(o.calibrates && !o.ideal_calibrates);
        if let Some(d) = o.difference {
            t.worst_camera_height_m = t.worst_camera_height_m.max(d.camera_height_m);
            t.worst_base_translation_m = t.worst_base_translation_m.max(d.base_translation_m);
            t.worst_base_yaw_rad = t.worst_base_yaw_rad.max(d.base_yaw_rad);
            translations.push(d.base_translation_m);
            heights.push(d.camera_height_m);
        }
        if o.score.mislabelled > 0 {
            t.mislabelled_picks
                .push((o.trial, o.score.examples.iter().take(3).cloned().collect()));
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    t.median_base_translation_m = median(&mut translations);
    t.median_camera_height_m = median(&mut heights);
    t
}

/// Runs trials `first..first + count` of `seed` in parallel.
pub fn run_campaign(
    experiment: &PickExperiment,
    seed: u64,
    first: usize,
    count: usize,
    max_frames: usize,
    on_pick: &(dyn Fn(&Result<PickOutcome>) + Sync),
) -> Vec<Result<PickOutcome>> {
    (first..first + count)
        .into_par_iter()
        .map(|trial| {
            let outcome = run_pick(experiment, seed, trial, max_frames);
            on_pick(&outcome);
            outcome
        })
        .collect()
}
