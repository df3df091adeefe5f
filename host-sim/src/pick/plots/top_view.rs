//! The top view of the cell: robot base, disc, camera, drop-off, the part's
//! true and estimated paths, the tool's path and where the gripper closed.

use std::ops::Range;

use plotters::prelude::*;

use crate::pick::record::{PickRun, TickRecord};

use super::panel::{
    padded_range, segments, Area, DrawResult, ACTUAL_COLOUR, DISC_COLOUR, ESTIMATE_COLOUR,
    FONT_FAMILY, TOOL_COLOUR,
};

/// The cell from above in the base frame, X to the right and Y up at equal
/// scale: robot base at the origin, disc, camera, drop-off, the part's true
/// and estimated paths, the tool's path and where the gripper closed.
pub(super) fn draw_top_view<'a>(
    root: &Area<'a>,
    run: &PickRun,
    samples: &[TickRecord],
) -> DrawResult<'a> {
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
