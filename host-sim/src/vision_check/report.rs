//! The figures of `host-sim vision-check`: a markdown report and its JSON.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::Serialize;

use super::{Condition, Tally};

/// Radial RMS and 99th percentile (nearest rank) of 2-D errors, px.
pub fn rms_p99(errors: &[[f64; 2]]) -> (f64, f64) {
    if errors.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let mut norms: Vec<f64> = errors.iter().map(|[x, y]| x.hypot(*y)).collect();
    let rms = (norms.iter().map(|n| n * n).sum::<f64>() / norms.len() as f64).sqrt();
    norms.sort_by(f64::total_cmp);
    let rank = ((0.99 * norms.len() as f64).ceil() as usize).clamp(1, norms.len());
    (rms, norms.get(rank - 1).copied().unwrap_or(f64::NAN))
}

/// One row of the summary.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub condition: String,
    pub marks: usize,
    pub found: usize,
    pub missed: usize,
    pub spurious: usize,
    pub rms_px: f64,
    pub p99_px: f64,
}

fn row(name: &str, c: &Condition) -> Row {
    let marks: usize = c.visible.values().sum();
    let missed: usize = c.missed.values().sum();
    let (rms_px, p99_px) = rms_p99(&c.all_errors());
    Row {
        condition: name.to_string(),
        marks,
        found: marks - missed.min(marks),
        missed,
        spurious: c.spurious,
        rms_px,
        p99_px,
    }
}

/// The measured figures, for JSON.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub experiment: String,
    pub seed: u64,
    pub trials: usize,
    pub frames: usize,
    pub conditions: Vec<Row>,
    /// By class at the default noise.
    pub classes: Vec<Row>,
    pub still_to_centre_rms_px: f64,
    pub still_to_centre_p99_px: f64,
    pub still_to_region_rms_px: f64,
    pub still_to_region_p99_px: f64,
    pub still_marks: usize,
    /// Perspective bias of the visible marks, px: RMS, 99th percentile, largest.
    pub bias_marks: usize,
    pub bias_rms_px: f64,
    pub bias_p99_px: f64,
    pub bias_max_px: f64,
    pub bias_by_class: Vec<(String, f64, f64)>,
    /// Error away from the partner mark at the default noise, by class:
    /// mean (what every frame shares), standard deviation, count, px.
    pub outward_by_class: Vec<(String, f64, f64, usize)>,
    pub partly_hidden: usize,
    pub wholly_hidden: usize,
    pub crowded: usize,
    pub render_ms_per_frame: f64,
    pub detect_ms_per_frame: f64,
    /// The disc's rim at the default noise: frames looked at, frames measured.
    pub rim_frames: usize,
    pub rim_found: usize,
    /// Over the measured frames, px: the mean of the frames' mean distance
    /// of the true rim from the fit (what every frame shares), the deviation
    /// of that mean from frame to frame, the fit's own sigma of its mean
    /// radius (median), and the RMS and 99th percentile of each frame's RMS
    /// distance.
    pub rim_shared_px: f64,
    pub rim_mean_deviation_px: f64,
    pub rim_sigma_median_px: f64,
    pub rim_rms_px: f64,
    pub rim_rms_p99_px: f64,
    pub rim_ms_per_frame: f64,
}

pub fn summarise(experiment: &str, seed: u64, tally: &Tally) -> Summary {
    let classes = tally
        .noisy
        .visible
        .keys()
        .map(|class| {
            let only = Condition {
                errors: tally
                    .noisy
                    .errors
                    .iter()
                    .filter(|(k, _)| *k == class)
                    .map(|(k, v)| (*k, v.clone()))
                    .collect(),
                visible: tally
                    .noisy
                    .visible
                    .iter()
                    .filter(|(k, _)| *k == class)
                    .map(|(k, v)| (*k, *v))
                    .collect(),
                missed: tally
                    .noisy
                    .missed
                    .iter()
                    .filter(|(k, _)| *k == class)
                    .map(|(k, v)| (*k, *v))
                    .collect(),
                outward: BTreeMap::new(),
                spurious: 0,
                frames_with_spurious: 0,
            };
            row(class, &only)
        })
        .collect();
    let all_bias: Vec<[f64; 2]> = tally.bias.values().flatten().copied().collect();
    let (bias_rms_px, bias_p99_px) = rms_p99(&all_bias);
    let bias_max_px = all_bias
        .iter()
        .map(|[x, y]| x.hypot(*y))
        .fold(0.0, f64::max);
    let (sc_rms, sc_p99) = rms_p99(&tally.still_to_centre);
    let (sr_rms, sr_p99) = rms_p99(&tally.still_to_region);
    Summary {
        experiment: experiment.to_string(),
        seed,
        trials: tally.trials,
        frames: tally.frames,
        conditions: vec![
            row("noise-free", &tally.noise_free),
            row("default noise", &tally.noisy),
        ],
        classes,
        still_to_centre_rms_px: sc_rms,
        still_to_centre_p99_px: sc_p99,
        still_to_region_rms_px: sr_rms,
        still_to_region_p99_px: sr_p99,
        still_marks: tally.still_to_centre.len(),
        bias_marks: all_bias.len(),
        bias_rms_px,
        bias_p99_px,
        bias_max_px,
        bias_by_class: tally
            .bias
            .iter()
            .map(|(class, b)| {
                let (rms, p99) = rms_p99(b);
                (class.to_string(), rms, p99)
            })
            .collect(),
        outward_by_class: tally
            .noisy
            .outward
            .iter()
            .map(|(class, e)| {
                let n = e.len().max(1) as f64;
                let mean = e.iter().sum::<f64>() / n;
                let variance = e.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n;
                (class.to_string(), mean, variance.sqrt(), e.len())
            })
            .collect(),
        partly_hidden: tally.partly_hidden,
        wholly_hidden: tally.wholly_hidden,
        crowded: tally.crowded,
        render_ms_per_frame: 1e3 * tally.render_s / tally.renders.max(1) as f64,
        detect_ms_per_frame: 1e3 * tally.detect_s / tally.detections.max(1) as f64,
        rim_frames: tally.rim_frames,
        rim_found: tally.rim.len(),
        rim_shared_px: mean(tally.rim.iter().map(|r| r.mean_px)),
        rim_mean_deviation_px: {
            let m = mean(tally.rim.iter().map(|r| r.mean_px));
            mean(tally.rim.iter().map(|r| (r.mean_px - m) * (r.mean_px - m))).sqrt()
        },
        rim_sigma_median_px: percentile(tally.rim.iter().map(|r| r.sigma_px).collect(), 0.5),
        rim_rms_px: mean(tally.rim.iter().map(|r| r.rms_px * r.rms_px)).sqrt(),
        rim_rms_p99_px: percentile(tally.rim.iter().map(|r| r.rms_px).collect(), 0.99),
        rim_ms_per_frame: 1e3 * tally.rim_s / tally.rim_frames.max(1) as f64,
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    sum / n.max(1) as f64
}

fn percentile(mut values: Vec<f64>, q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    let index = ((values.len() as f64 - 1.0) * q).round().max(0.0) as usize;
    values.get(index).copied().unwrap_or(f64::NAN)
}

/// The summary as markdown.
pub fn markdown(summary: &Summary) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "vision check: {} trials of {} (seed {}), {} frames rendered at 256 x 256\n",
        summary.trials, summary.experiment, summary.seed, summary.frames
    );
    let _ = writeln!(out, "| condition | marks to find | found | missed | spurious | centroid error RMS (px) | 99th pct (px) |");
    let _ = writeln!(out, "|---|---|---|---|---|---|---|");
    for r in summary.conditions.iter().chain(&summary.classes) {
        let name = if summary.classes.iter().any(|c| std::ptr::eq(c, r)) {
            format!("default noise: {}", r.condition)
        } else {
            r.condition.clone()
        };
        let spurious = if summary.classes.iter().any(|c| std::ptr::eq(c, r)) {
            "-".to_string()
        } else {
            r.spurious.to_string()
        };
        let _ = writeln!(
            out,
            "| {name} | {} | {} | {} | {spurious} | {:.3} | {:.3} |",
            r.marks, r.found, r.missed, r.rms_px, r.p99_px
        );
    }
    let _ = writeln!(
        out,
        "\nerror away from the partner mark (the reference from the disc centre, a gripper mark from the other), default noise: a mean that every frame shares scales the pair's image"
    );
    for (class, mean, deviation, n) in &summary.outward_by_class {
        let _ = writeln!(
            out,
            "  {class}: mean {mean:+.4} px, deviation {deviation:.4} px ({n} marks)"
        );
    }
    let _ = writeln!(
        out,
        "\nperspective bias (centroid of a mark's image minus the image of its centre), {} visible marks: RMS {:.4} px, 99th pct {:.4} px, largest {:.4} px",
        summary.bias_marks,
        summary.bias_rms_px, summary.bias_p99_px, summary.bias_max_px
    );
    for (class, rms, p99) in &summary.bias_by_class {
        let _ = writeln!(out, "  {class}: RMS {rms:.4} px, 99th pct {p99:.4} px");
    }
    let _ = writeln!(
        out,
        "noise-free, blur-free frames ({} marks found): error against the projected centre RMS {:.4} px (99th pct {:.4}), against the image's centroid RMS {:.4} px (99th pct {:.4})",
        summary.still_marks,
        summary.still_to_centre_rms_px,
        summary.still_to_centre_p99_px,
        summary.still_to_region_rms_px,
        summary.still_to_region_p99_px
    );
    let _ = writeln!(
        out,
        "marks in view not scored: {} partly and {} wholly hidden by the arm or the part, {} crowded by another mark (images within {} px)",
        summary.partly_hidden,
        summary.wholly_hidden,
        summary.crowded,
        crate::world::render::truth::CROWDING_GAP_PX
    );
    let _ = writeln!(
        out,
        "the disc's rim, default noise: measured in {} of {} frames; the true rim's distance from the fit: shared by every frame {:+.4} px, frame to frame {:.4} px (the fit's own sigma {:.4} px, median), RMS round the rim {:.4} px (99th pct {:.4} px)",
        summary.rim_found,
        summary.rim_frames,
        summary.rim_shared_px,
        summary.rim_mean_deviation_px,
        summary.rim_sigma_median_px,
        summary.rim_rms_px,
        summary.rim_rms_p99_px
    );
    let _ = writeln!(
        out,
        "CPU time per frame (one thread): render {:.2} ms (scene, raster, light, noise), detect {:.3} ms, rim {:.3} ms",
        summary.render_ms_per_frame, summary.detect_ms_per_frame, summary.rim_ms_per_frame
    );
    out
}
