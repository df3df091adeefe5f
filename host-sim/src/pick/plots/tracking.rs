//! The gripper's tracking figure: its error against the reference during the
//! pick, and its distance to the part while it closes in.

use shared::protocol::PickPhase;

use super::panel::{
    draw_time_panel, segments, time_range, Area, DrawResult, Panel, Series, ACTUAL_COLOUR,
    FONT_FAMILY, TOOL_COLOUR, YAW_JUMP_DEG,
};
use crate::pick::record::{PhaseEvent, PickRun, TickRecord};
use crate::pick::report::wrap_angle_rad;

/// The phases in which the gripper follows a reference toward the part and away.
pub(super) fn is_pick_phase(phase: PickPhase) -> bool {
    matches!(
        phase,
        PickPhase::Intercept
            | PickPhase::Track
            | PickPhase::Descend
            | PickPhase::Grasp
            | PickPhase::Lift
            | PickPhase::Place
            | PickPhase::Release
            | PickPhase::Return
    )
}

/// The phases in which the gripper is meant to close in on the part.
pub(super) fn is_approach_phase(phase: PickPhase) -> bool {
    matches!(
        phase,
        PickPhase::Track | PickPhase::Descend | PickPhase::Grasp
    )
}

fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    a.iter()
        .zip(b.iter())
        .map(|(p, q)| (p - q) * (p - q))
        .sum::<f64>()
        .sqrt()
}

/// The gripper's tracking error during Intercept .. Return, and the true
/// tool-to-part distance while it closes in (Track, Descend, Grasp).
pub(super) fn draw_tracking_error<'a>(
    root: &Area<'a>,
    run: &PickRun,
    samples: &[TickRecord],
) -> DrawResult<'a> {
    let titled = root.titled(
        &format!("{}: gripper tracking during the pick", run.experiment),
        (FONT_FAMILY, 24),
    )?;
    let areas = titled.split_evenly((3, 1));
    let position = segments(
        samples.iter().map(|r| {
            let error = is_pick_phase(r.phase)
                .then(|| distance_m(r.tool_ref_base_m, r.tool_true_base_m) * 1000.0);
            (r.t_s, error)
        }),
        None,
    );
    let yaw = segments(
        samples.iter().map(|r| {
            let error = is_pick_phase(r.phase)
                .then(|| wrap_angle_rad(r.tool_ref_yaw_rad - r.tool_true_yaw_rad).to_degrees());
            (r.t_s, error)
        }),
        Some(YAW_JUMP_DEG),
    );
    let to_part = segments(
        samples.iter().map(|r| {
            let distance = is_approach_phase(r.phase)
                .then(|| distance_m(r.tool_true_base_m, r.part_true_base_m) * 1000.0);
            (r.t_s, distance)
        }),
        None,
    );
    let single = |title, y_desc, label, colour, segments| Panel {
        title,
        y_desc,
        series: vec![Series {
            label,
            colour,
            dashed: false,
            segments,
        }],
        band: Vec::new(),
    };
    let panels = [
        single(
            "(a) position tracking error |reference - actual|",
            "error (mm)",
            "|tool_ref - tool_true|",
            TOOL_COLOUR,
            position,
        ),
        single(
            "(b) yaw tracking error",
            "error (deg)",
            "tool_ref yaw - tool_true yaw",
            TOOL_COLOUR,
            yaw,
        ),
        single(
            "(c) tool to part distance (true), Track / Descend / Grasp",
            "distance (mm)",
            "|tool_true - part_true|",
            ACTUAL_COLOUR,
            to_part,
        ),
    ];
    let pick_samples: Vec<TickRecord> = samples
        .iter()
        .filter(|r| is_pick_phase(r.phase))
        .copied()
        .collect();
    let pick_phases: Vec<PhaseEvent> = run
        .phases
        .iter()
        .filter(|p| is_pick_phase(p.phase))
        .copied()
        .collect();
    let x_range = if pick_samples.is_empty() {
        time_range(samples, &run.phases)
    } else {
        time_range(&pick_samples, &pick_phases)
    };
    for (index, (area, panel)) in areas.iter().zip(&panels).enumerate() {
        draw_time_panel(area, panel, x_range.clone(), &run.phases, index == 0)?;
    }
    Ok(())
}
