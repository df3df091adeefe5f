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

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use anyhow::{anyhow, bail, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::register_font;
use shared::protocol::PickPhase;

use super::record::{PhaseEvent, PickRun, TickRecord};
use super::report::{phase_name, wrap_angle_rad};

/// Samples drawn per series at most (every n-th record beyond that).
pub const MAX_POINTS: usize = 2000;
/// Pixel sizes of the four figures (width, height).
pub const PART_POSE_SIZE: (u32, u32) = (1400, 1000);
pub const PART_POSE_ERROR_SIZE: (u32, u32) = (1400, 1000);
pub const TRACKING_ERROR_SIZE: (u32, u32) = (1400, 1100);
pub const TOP_VIEW_SIZE: (u32, u32) = (1000, 1000);

const FONT_FAMILY: &str = "sans-serif";
const FONT_TTF: &[u8] = include_bytes!("../../assets/fonts/LiberationSans-Regular.ttf");

const ESTIMATE_COLOUR: RGBColor = RGBColor(31, 90, 200);
const ACTUAL_COLOUR: RGBColor = RGBColor(210, 50, 40);
const TOOL_COLOUR: RGBColor = RGBColor(30, 150, 60);
const PHASE_COLOUR: RGBColor = RGBColor(235, 170, 90);
const PHASE_TEXT_COLOUR: RGBColor = RGBColor(170, 100, 20);
const DISC_COLOUR: RGBColor = RGBColor(110, 110, 110);

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

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
type DrawResult<'a> =
    Result<(), DrawingAreaErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>>;

fn draw_png<F>(path: &Path, size: (u32, u32), draw: F) -> Result<()>
where
    F: for<'a> FnOnce(&Area<'a>) -> DrawResult<'a>,
{
    let root = BitMapBackend::new(path, size).into_drawing_area();
    let fail = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    draw(&root).map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))?;
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

/// One line of a panel, as pieces that are drawn unbroken.
struct Series {
    label: &'static str,
    colour: RGBColor,
    dashed: bool,
    segments: Vec<Vec<(f64, f64)>>,
}

/// A panel of a time figure, with an optional shaded band (t, low, high).
struct Panel {
    title: &'static str,
    y_desc: &'static str,
    series: Vec<Series>,
    band: Vec<Vec<(f64, f64, f64)>>,
}

/// Cuts `(x, y)` samples into drawable pieces: a missing or non-finite value
/// ends a piece, and so does a jump larger than `max_jump` (an angle wrapping
/// from +180 to -180 degrees must not draw a vertical line across the panel).
fn segments<I>(points: I, max_jump: Option<f64>) -> Vec<Vec<(f64, f64)>>
where
    I: IntoIterator<Item = (f64, Option<f64>)>,
{
    let mut pieces: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    for (x, y) in points {
        match y {
            Some(y) if x.is_finite() && y.is_finite() => {
                let jumps = match (current.last(), max_jump) {
                    (Some(&(_, previous)), Some(limit)) => (y - previous).abs() > limit,
                    _ => false,
                };
                if jumps {
                    pieces.push(std::mem::take(&mut current));
                }
                current.push((x, y));
            }
            _ => {
                if !current.is_empty() {
                    pieces.push(std::mem::take(&mut current));
                }
            }
        }
    }
    if !current.is_empty() {
        pieces.push(current);
    }
    pieces
}

/// Like [`segments`] for a band: a piece ends where the band is absent.
fn band_segments<I>(points: I) -> Vec<Vec<(f64, f64, f64)>>
where
    I: IntoIterator<Item = (f64, Option<(f64, f64)>)>,
{
    let mut pieces = Vec::new();
    let mut current = Vec::new();
    for (x, band) in points {
        match band {
            Some((low, high)) if x.is_finite() && low.is_finite() && high.is_finite() => {
                current.push((x, low, high));
            }
            _ => {
                if !current.is_empty() {
                    pieces.push(std::mem::take(&mut current));
                }
            }
        }
    }
    if !current.is_empty() {
        pieces.push(current);
    }
    pieces
}

/// A range that plotters can map: finite, non-empty, padded by 5 %.
fn padded_range<I: IntoIterator<Item = f64>>(values: I, fallback: Range<f64>) -> Range<f64> {
    let (low, high) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !low.is_finite() || !high.is_finite() {
        return fallback;
    }
    // A flat or nearly flat series gets a span of at least 1 % of its size
    // (and 0.001 units), so that the tick labels stay distinct.
    let min_span = (low.abs().max(high.abs()) * 0.01).max(1e-3);
    let (low, high) = if high - low < min_span {
        let middle = (low + high) / 2.0;
        (middle - min_span / 2.0, middle + min_span / 2.0)
    } else {
        (low, high)
    };
    let pad = (high - low) * 0.05;
    (low - pad)..(high + pad)
}

fn time_range(samples: &[TickRecord], phases: &[PhaseEvent]) -> Range<f64> {
    let times = samples
        .iter()
        .map(|r| r.t_s)
        .chain(phases.iter().map(|p| p.t_s));
    padded_range(times, 0.0..1.0)
}

fn panel_values(panel: &Panel) -> impl Iterator<Item = f64> + '_ {
    let lines = panel
        .series
        .iter()
        .flat_map(|s| s.segments.iter().flatten().map(|&(_, y)| y));
    let band = panel
        .band
        .iter()
        .flatten()
        .flat_map(|&(_, low, high)| [low, high]);
    lines.chain(band)
}

/// Draws one time panel: the band, the series, the phase boundaries as light
/// vertical lines (named on `name_phases` panels), axis titles and legend.
fn draw_time_panel<'a>(
    area: &Area<'a>,
    panel: &Panel,
    x_range: Range<f64>,
    phases: &[PhaseEvent],
    name_phases: bool,
) -> DrawResult<'a> {
    let y_range = padded_range(panel_values(panel), -1.0..1.0);
    let (y_low, y_high) = (y_range.start, y_range.end);
    let mut chart = ChartBuilder::on(area)
        .caption(panel.title, (FONT_FAMILY, 20))
        .margin(10)
        .x_label_area_size(45)
        .y_label_area_size(75)
        .build_cartesian_2d(x_range.clone(), y_range)?;
    chart
        .configure_mesh()
        .max_light_lines(2)
        .light_line_style(RGBColor(242, 242, 242))
        .x_desc("time (s)")
        .y_desc(panel.y_desc)
        .label_style((FONT_FAMILY, 14))
        .axis_desc_style((FONT_FAMILY, 15))
        .draw()?;

    let span = y_high - y_low;
    for (index, event) in phases.iter().enumerate() {
        if !(x_range.start..=x_range.end).contains(&event.t_s) {
            continue;
        }
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(event.t_s, y_low), (event.t_s, y_high)],
            PHASE_COLOUR,
        )))?;
        if name_phases {
            let row = (index % 3) as f64;
            let anchor = (event.t_s, y_high - span * (0.01 + 0.06 * row));
            chart.draw_series(std::iter::once(
                EmptyElement::at(anchor)
                    + Text::new(
                        phase_name(event.phase),
                        (4, 0),
                        (FONT_FAMILY, 12).into_font().color(&PHASE_TEXT_COLOUR),
                    ),
            ))?;
        }
    }

    let mut labelled = false;
    let band_colour = ESTIMATE_COLOUR.mix(0.18);
    for (index, piece) in panel.band.iter().enumerate() {
        let mut outline: Vec<(f64, f64)> = piece.iter().map(|&(x, low, _)| (x, low)).collect();
        outline.extend(piece.iter().rev().map(|&(x, _, high)| (x, high)));
        let drawn =
            chart.draw_series(std::iter::once(Polygon::new(outline, band_colour.filled())))?;
        if index == 0 {
            drawn.label("estimator 1-sigma").legend(move |(x, y)| {
                Rectangle::new([(x, y - 6), (x + 20, y + 6)], band_colour.filled())
            });
            labelled = true;
        }
    }

    for series in &panel.series {
        let mut first = true;
        for piece in series.segments.iter().filter(|piece| piece.len() >= 2) {
            let style = series.colour.stroke_width(2);
            let drawn = if series.dashed {
                chart.draw_series(DashedLineSeries::new(piece.clone(), 8, 5, style))?
            } else {
                chart.draw_series(LineSeries::new(piece.iter().copied(), style))?
            };
            if first {
                let colour = series.colour;
                drawn.label(series.label).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
                first = false;
                labelled = true;
            }
        }
    }

    if panel.series.iter().all(|s| s.segments.is_empty()) {
        chart.draw_series(std::iter::once(Text::new(
            "no data",
            (
                x_range.start + (x_range.end - x_range.start) * 0.45,
                (y_low + y_high) / 2.0,
            ),
            (FONT_FAMILY, 18),
        )))?;
    }
    if labelled {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT_FAMILY, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()?;
    }
    Ok(())
}

const YAW_JUMP_DEG: f64 = 180.0;

/// Fig 4/6/8: estimated (solid) and actual (dashed) part X, Y, Z and yaw.
fn draw_part_pose<'a>(root: &Area<'a>, run: &PickRun, samples: &[TickRecord]) -> DrawResult<'a> {
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
fn draw_part_pose_error<'a>(
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

/// The phases in which the gripper follows a reference toward the part and away.
fn is_pick_phase(phase: PickPhase) -> bool {
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
fn is_approach_phase(phase: PickPhase) -> bool {
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
fn draw_tracking_error<'a>(
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

/// The cell from above in the base frame, X to the right and Y up at equal
/// scale: robot base at the origin, disc, camera, drop-off, the part's true
/// and estimated paths, the tool's path and where the gripper closed.
fn draw_top_view<'a>(root: &Area<'a>, run: &PickRun, samples: &[TickRecord]) -> DrawResult<'a> {
    const MARGIN: u32 = 15;
    const X_LABELS: u32 = 50;
    const Y_LABELS: u32 = 80;
    let area = root.titled(
        &format!("{}: top view of the cell, base frame", run.experiment),
        (FONT_FAMILY, 24),
    )?;
    let layout = &run.layout;
    let [disc_x, disc_y, _] = layout.disc_centre_base_m;
    let disc_outline: Vec<(f64, f64)> = (0..=180)
        .map(|i| {
            let angle = f64::from(i) * std::f64::consts::TAU / 180.0;
            (
                disc_x + layout.disc_radius_m * angle.cos(),
                disc_y + layout.disc_radius_m * angle.sin(),
            )
        })
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    let [camera_x, camera_y, _] = layout.camera_centre_base_m;
    let [drop_x, drop_y, _] = layout.drop_off_base_m;
    let xy = |p: [f64; 3]| {
        let [x, y, _] = p;
        (x, Some(y))
    };
    let part_true = segments(samples.iter().map(|r| xy(r.part_true_base_m)), None);
    let part_estimate = segments(
        samples
            .iter()
            .map(|r| r.part_est_base_m.map_or((f64::NAN, None), xy)),
        None,
    );
    let tool = segments(samples.iter().map(|r| xy(r.tool_true_base_m)), None);
    let grasp_point = run.grasp.as_ref().and_then(|grasp| {
        run.records
            .iter()
            .min_by(|a, b| {
                (a.t_s - grasp.t_s)
                    .abs()
                    .total_cmp(&(b.t_s - grasp.t_s).abs())
            })
            .map(|r| {
                let [x, y, _] = r.tool_true_base_m;
                (x, y)
            })
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    });

    let markers = [(0.0, 0.0), (camera_x, camera_y), (drop_x, drop_y)];
    let all_points: Vec<(f64, f64)> = disc_outline
        .iter()
        .copied()
        .chain(markers)
        .chain(part_true.iter().flatten().copied())
        .chain(part_estimate.iter().flatten().copied())
        .chain(tool.iter().flatten().copied())
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    let x_span = padded_range(all_points.iter().map(|p| p.0), -1.0..1.0);
    let y_span = padded_range(all_points.iter().map(|p| p.1), -1.0..1.0);
    // Equal scale: stretch the shorter span to the plotting area's aspect.
    let (width_px, height_px) = area.dim_in_pixel();
    let plot_w = f64::from(width_px.saturating_sub(2 * MARGIN + Y_LABELS).max(1));
    let plot_h = f64::from(height_px.saturating_sub(2 * MARGIN + X_LABELS).max(1));
    let metres_per_px =
        ((x_span.end - x_span.start) / plot_w).max((y_span.end - y_span.start) / plot_h);
    let centred = |span: Range<f64>, px: f64| {
        let middle = (span.start + span.end) / 2.0;
        let half = metres_per_px * px / 2.0;
        (middle - half)..(middle + half)
    };
    let mut chart = ChartBuilder::on(&area)
        .margin(MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(Y_LABELS)
        .build_cartesian_2d(centred(x_span, plot_w), centred(y_span, plot_h))?;
    chart
        .configure_mesh()
        .max_light_lines(2)
        .light_line_style(RGBColor(242, 242, 242))
        .x_desc("X base (m)")
        .y_desc("Y base (m)")
        .label_style((FONT_FAMILY, 14))
        .axis_desc_style((FONT_FAMILY, 15))
        .draw()?;

    if disc_outline.len() >= 2 {
        chart
            .draw_series(LineSeries::new(disc_outline, DISC_COLOUR.stroke_width(2)))?
            .label("disc outline")
            .legend(|(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], DISC_COLOUR.stroke_width(2))
            });
    }
    let paths = [
        ("part path (actual)", ACTUAL_COLOUR, true, &part_true),
        (
            "part path (estimated)",
            ESTIMATE_COLOUR,
            false,
            &part_estimate,
        ),
        ("tool path (actual)", TOOL_COLOUR, false, &tool),
    ];
    for (label, colour, dashed, pieces) in paths {
        let mut first = true;
        for piece in pieces.iter().filter(|piece| piece.len() >= 2) {
            let style = colour.stroke_width(2);
            let drawn = if dashed {
                chart.draw_series(DashedLineSeries::new(piece.clone(), 8, 5, style))?
            } else {
                chart.draw_series(LineSeries::new(piece.iter().copied(), style))?
            };
            if first {
                drawn.label(label).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
                first = false;
            }
        }
    }
    chart
        .draw_series(std::iter::once(TriangleMarker::new(
            (0.0, 0.0),
            9,
            BLACK.filled(),
        )))?
        .label("robot base")
        .legend(|(x, y)| TriangleMarker::new((x + 10, y), 6, BLACK.filled()));
    if camera_x.is_finite() && camera_y.is_finite() {
        chart
            .draw_series(std::iter::once(Cross::new(
                (camera_x, camera_y),
                8,
                MAGENTA.stroke_width(3),
            )))?
            .label("camera")
            .legend(|(x, y)| Cross::new((x + 10, y), 5, MAGENTA.stroke_width(2)));
    }
    if drop_x.is_finite() && drop_y.is_finite() {
        let drop_colour = RGBColor(230, 140, 0);
        chart
            .draw_series(std::iter::once(Circle::new(
                (drop_x, drop_y),
                7,
                drop_colour.filled(),
            )))?
            .label("drop-off")
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, drop_colour.filled()));
    }
    if let Some(point) = grasp_point {
        chart
            .draw_series(std::iter::once(Circle::new(
                point,
                9,
                BLACK.stroke_width(3),
            )))?
            .label("grasp (tool)")
            .legend(|(x, y)| Circle::new((x + 10, y), 6, BLACK.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT_FAMILY, 14))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pick::report::synthetic_run;

    #[test]
    fn segments_break_on_missing_non_finite_and_wrap_jumps() {
        let points = [
            (0.0, Some(170.0)),
            (1.0, Some(179.0)),
            (2.0, Some(-179.0)), // wrapped: a new piece
            (3.0, Some(-170.0)),
            (4.0, None), // no estimate yet: a gap
            (5.0, Some(f64::NAN)),
            (6.0, Some(1.0)),
            (f64::INFINITY, Some(2.0)),
            (8.0, Some(3.0)),
        ];
        let pieces = segments(points, Some(YAW_JUMP_DEG));
        assert_eq!(
            pieces,
            vec![
                vec![(0.0, 170.0), (1.0, 179.0)],
                vec![(2.0, -179.0), (3.0, -170.0)],
                vec![(6.0, 1.0)],
                vec![(8.0, 3.0)],
            ]
        );
        // Without a jump limit the wrap stays one piece.
        assert_eq!(segments(points, None).first().map(Vec::len), Some(4));
        assert!(segments(std::iter::empty(), None).is_empty());
    }

    #[test]
    fn band_segments_end_where_the_band_is_absent() {
        let pieces = band_segments([
            (0.0, None),
            (1.0, Some((-1.0, 1.0))),
            (2.0, Some((-2.0, 2.0))),
            (3.0, Some((f64::NAN, 2.0))),
            (4.0, Some((-3.0, 3.0))),
        ]);
        assert_eq!(
            pieces,
            vec![
                vec![(1.0, -1.0, 1.0), (2.0, -2.0, 2.0)],
                vec![(4.0, -3.0, 3.0)]
            ]
        );
    }

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
    fn padded_range_is_finite_and_open_for_any_input() {
        assert_eq!(padded_range([], -1.0..1.0), -1.0..1.0);
        assert_eq!(padded_range([f64::NAN, f64::INFINITY], 0.0..1.0), 0.0..1.0);
        let range = padded_range([0.0, 10.0, f64::NAN], 0.0..1.0);
        assert!((range.start + 0.5).abs() < 1e-12 && (range.end - 10.5).abs() < 1e-12);
        // A flat series gets 1 % of its size (at least 0.001) around it.
        let flat = padded_range([100.0, 100.0], 0.0..1.0);
        assert!(flat.start < 99.5 && flat.end > 100.5 && flat.end - flat.start < 1.2);
        let zero = padded_range([0.0], 0.0..1.0);
        assert!(zero.start < 0.0 && zero.end > 0.0);
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
