//! The part's figures (the paper's Figs 4 to 9): its estimated and actual pose
//! in the base frame, and the estimation errors.

use super::panel::{
    band_segments, draw_time_panel, segments, time_range, Area, DrawResult, Panel, Series,
    ACTUAL_COLOUR, ESTIMATE_COLOUR, FONT_FAMILY, YAW_JUMP_DEG,
};
use crate::pick::record::{PickRun, TickRecord};
use crate::pick::report::wrap_angle_rad;

/// Fig 4/6/8: estimated (solid) and actual (dashed) part X, Y, Z and yaw.
pub(super) fn draw_part_pose<'a>(
    root: &Area<'a>,
    run: &PickRun,
    samples: &[TickRecord],
) -> DrawResult<'a> {
    let titled = root.titled(
        &format!(
            "{}: estimated and actual part pose, base frame",
            run.experiment
        ),
        (FONT_FAMILY, 24),
    )?;
    let areas = titled.split_evenly((2, 2));
    let axis = |index: usize, title, y_desc| {
        let estimate = segments(
            samples
                .iter()
                .map(|r| (r.t_s, r.part_est_base_m.and_then(|p| p.get(index).copied()))),
            None,
        );
        let actual = segments(
            samples
                .iter()
                .map(|r| (r.t_s, r.part_true_base_m.get(index).copied())),
            None,
        );
        pose_panel(title, y_desc, estimate, actual)
    };
    let yaw = pose_panel(
        "(d) yaw",
        "yaw (deg)",
        segments(
            samples.iter().map(|r| {
                (
                    r.t_s,
                    r.part_est_yaw_rad.map(|y| wrap_angle_rad(y).to_degrees()),
                )
            }),
            Some(YAW_JUMP_DEG),
        ),
        segments(
            samples.iter().map(|r| {
                (
                    r.t_s,
                    Some(wrap_angle_rad(r.part_true_yaw_rad).to_degrees()),
                )
            }),
            Some(YAW_JUMP_DEG),
        ),
    );
    let panels = [
        axis(0, "(a) X", "X (m)"),
        axis(1, "(b) Y", "Y (m)"),
        axis(2, "(c) Z", "Z (m)"),
        yaw,
    ];
    let x_range = time_range(samples, &run.phases);
    for (index, (area, panel)) in areas.iter().zip(&panels).enumerate() {
        draw_time_panel(area, panel, x_range.clone(), &run.phases, index == 0)?;
    }
    Ok(())
}

fn pose_panel(
    title: &'static str,
    y_desc: &'static str,
    estimate: Vec<Vec<(f64, f64)>>,
    actual: Vec<Vec<(f64, f64)>>,
) -> Panel {
    Panel {
        title,
        y_desc,
        series: vec![
            Series {
                label: "estimated",
                colour: ESTIMATE_COLOUR,
                dashed: false,
                segments: estimate,
            },
            Series {
                label: "actual",
                colour: ACTUAL_COLOUR,
                dashed: true,
                segments: actual,
            },
        ],
        band: Vec::new(),
    }
}

/// Fig 5/7/9: estimate minus truth in X, Y, Z (mm) and yaw (deg), with the
/// estimator's 1-sigma band around zero where it reports one, until the
/// gripper closes (from then on the part rides in the gripper, off the disc,
/// and the estimate of a part on the disc has nothing to match).
pub(super) fn draw_part_pose_error<'a>(
    root: &Area<'a>,
    run: &PickRun,
    samples: &[TickRecord],
) -> DrawResult<'a> {
    let until_s = run.grasp.as_ref().map_or(f64::INFINITY, |g| g.t_s);
    let on_disc: Vec<TickRecord> = samples
        .iter()
        .filter(|r| r.t_s <= until_s)
        .copied()
        .collect();
    let samples = on_disc.as_slice();
    let titled = root.titled(
        &format!(
            "{}: part pose estimation error (estimate - actual)",
            run.experiment
        ),
        (FONT_FAMILY, 24),
    )?;
    let areas = titled.split_evenly((2, 2));
    let axis = |index: usize, title: &'static str, y_desc: &'static str| {
        let error = segments(
            samples.iter().map(|r| {
                let estimate = r.part_est_base_m.and_then(|p| p.get(index).copied());
                let truth = r.part_true_base_m.get(index).copied();
                (r.t_s, estimate.zip(truth).map(|(e, t)| (e - t) * 1000.0))
            }),
            None,
        );
        let band = band_segments(samples.iter().map(|r| {
            let sigma_mm = r.part_sigma_m * 1000.0;
            let shown = r.part_est_base_m.is_some() && sigma_mm > 0.0;
            (r.t_s, shown.then_some((-sigma_mm, sigma_mm)))
        }));
        error_panel(title, y_desc, error, band)
    };
    let yaw_error = segments(
        samples.iter().map(|r| {
            let error = r
                .part_est_yaw_rad
                .map(|y| wrap_angle_rad(y - r.part_true_yaw_rad).to_degrees());
            (r.t_s, error)
        }),
        Some(YAW_JUMP_DEG),
    );
    let panels = [
        axis(0, "(a) X error", "X error (mm)"),
        axis(1, "(b) Y error", "Y error (mm)"),
        axis(2, "(c) Z error", "Z error (mm)"),
        error_panel("(d) yaw error", "yaw error (deg)", yaw_error, Vec::new()),
    ];
    let x_range = time_range(samples, &run.phases);
    for (index, (area, panel)) in areas.iter().zip(&panels).enumerate() {
        draw_time_panel(area, panel, x_range.clone(), &run.phases, index == 0)?;
    }
    Ok(())
}

fn error_panel(
    title: &'static str,
    y_desc: &'static str,
    error: Vec<Vec<(f64, f64)>>,
    band: Vec<Vec<(f64, f64, f64)>>,
) -> Panel {
    Panel {
        title,
        y_desc,
        series: vec![Series {
            label: "estimate - actual",
            colour: ESTIMATE_COLOUR,
            dashed: false,
            segments: error,
        }],
        band,
    }
}
