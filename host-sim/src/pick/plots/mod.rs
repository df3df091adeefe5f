//! The pick's PNG figures, after the paper's Section 5: the part's estimated
//! and actual pose in the base frame (Figs 4, 6, 8), the estimation errors
//! (Figs 5, 7, 9), the gripper's tracking error and a top view of the cell.
//!
//! Text is drawn through plotters' `ab_glyph` feature with the Liberation Sans
//! font shipped in `host-sim/assets/fonts` (SIL Open Font Licence 1.1): no
//! system font library (fontconfig, freetype) is needed on a fresh machine,
//! which plotters' `ttf` feature would require. Series are decimated to about
//! [`MAX_POINTS`] samples so that a long run still draws well under a second;
//! missing and non-finite samples break a line instead of being drawn.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{bail, Context, Result};
use plotters::prelude::*;
use plotters::style::register_font;

use super::record::{PickRun, TickRecord};

mod panel;
mod part;
mod top_view;
mod tracking;

use panel::{Area, DrawResult, FONT_FAMILY};
use part::{draw_part_pose, draw_part_pose_error};
use top_view::draw_top_view;
use tracking::draw_tracking_error;

/// Samples drawn per series at most (every n-th record beyond that).
pub const MAX_POINTS: usize = 2000;
/// Pixel sizes of the four figures (width, height).
pub const PART_POSE_SIZE: (u32, u32) = (1400, 1000);
pub const PART_POSE_ERROR_SIZE: (u32, u32) = (1400, 1000);
pub const TRACKING_ERROR_SIZE: (u32, u32) = (1400, 1100);
pub const TOP_VIEW_SIZE: (u32, u32) = (1000, 1000);

const FONT_TTF: &[u8] = include_bytes!("../../../assets/fonts/LiberationSans-Regular.ttf");

/// Writes `part_pose.png`, `part_pose_error.png`, `tracking_error.png` and
/// `top_view.png` into `dir` (which must exist) and returns their paths.
pub fn write_run_plots(run: &PickRun, dir: &Path) -> Result<Vec<PathBuf>> {
    register_embedded_font()?;
    let samples = decimate(&run.records);
    let part_pose = dir.join("part_pose.png");
    draw_png(&part_pose, PART_POSE_SIZE, |root| {
        draw_part_pose(root, run, &samples)
    })?;
    let part_pose_error = dir.join("part_pose_error.png");
    draw_png(&part_pose_error, PART_POSE_ERROR_SIZE, |root| {
        draw_part_pose_error(root, run, &samples)
    })?;
    let tracking_error = dir.join("tracking_error.png");
    draw_png(&tracking_error, TRACKING_ERROR_SIZE, |root| {
        draw_tracking_error(root, run, &samples)
    })?;
    let top_view = dir.join("top_view.png");
    draw_png(&top_view, TOP_VIEW_SIZE, |root| {
        draw_top_view(root, run, &samples)
    })?;
    Ok(vec![part_pose, part_pose_error, tracking_error, top_view])
}

fn draw_png<F>(path: &Path, size: (u32, u32), draw: F) -> Result<()>
where
    F: for<'a> FnOnce(&Area<'a>) -> DrawResult<'a>,
{
    let root = BitMapBackend::new(path, size).into_drawing_area();
    let drawing = || format!("drawing {}", path.display());
    root.fill(&WHITE).with_context(drawing)?;
    draw(&root).with_context(drawing)?;
    root.present().with_context(drawing)?;
    Ok(())
}

fn register_embedded_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let registered =
        *REGISTERED.get_or_init(|| register_font(FONT_FAMILY, FontStyle::Normal, FONT_TTF).is_ok());
    if !registered {
        bail!("the embedded font assets/fonts/LiberationSans-Regular.ttf is not a usable TrueType font");
    }
    Ok(())
}

/// Every n-th record so that at most about [`MAX_POINTS`] remain, and the last.
fn decimate(records: &[TickRecord]) -> Vec<TickRecord> {
    let stride = records.len().div_ceil(MAX_POINTS).max(1);
    let mut kept: Vec<TickRecord> = records.iter().step_by(stride).copied().collect();
    let last_was_kept = records.len().saturating_sub(1).is_multiple_of(stride);
    if let (Some(last), false) = (records.last(), last_was_kept) {
        kept.push(*last);
    }
    kept
}

#[cfg(test)]
mod tests {
    use shared::protocol::PickPhase;

    use super::tracking::{is_approach_phase, is_pick_phase};
    use super::*;
    use crate::pick::synthetic::synthetic_run;

    #[test]
    fn decimation_keeps_at_most_about_max_points_and_the_last_record() {
        for count in [0, 1, 5, MAX_POINTS, MAX_POINTS + 1, 3 * MAX_POINTS + 17] {
            let run = synthetic_run("decimate", count);
            let kept = decimate(&run.records);
            assert!(kept.len() <= MAX_POINTS + 1, "{count}: kept {}", kept.len());
            assert_eq!(kept.len().min(1), count.min(1));
            assert_eq!(kept.first(), run.records.first(), "{count}");
            assert_eq!(kept.last(), run.records.last(), "{count}");
            assert!(kept.windows(2).all(|w| w[0].t_s < w[1].t_s), "{count}");
        }
        assert_eq!(
            decimate(&synthetic_run("all", MAX_POINTS).records).len(),
            MAX_POINTS
        );
    }

    #[test]
    fn pick_phases_run_from_intercept_to_return() {
        let pick: Vec<bool> = [
            PickPhase::Locate,
            PickPhase::Intercept,
            PickPhase::Return,
            PickPhase::Done,
        ]
        .map(is_pick_phase)
        .to_vec();
        assert_eq!(pick, vec![false, true, true, false]);
        assert!(is_approach_phase(PickPhase::Descend) && !is_approach_phase(PickPhase::Lift));
    }
}
