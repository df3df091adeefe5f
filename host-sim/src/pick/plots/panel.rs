//! What the time figures share: the colours and font, the drawing area, a
//! panel of series over time with the phases shaded, and the cutting of samples
//! into drawable pieces.

use std::ops::Range;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::pick::record::{PhaseEvent, TickRecord};
use crate::pick::report::phase_name;

pub(super) const FONT_FAMILY: &str = "sans-serif";

pub(super) const ESTIMATE_COLOUR: RGBColor = RGBColor(31, 90, 200);
pub(super) const ACTUAL_COLOUR: RGBColor = RGBColor(210, 50, 40);
pub(super) const TOOL_COLOUR: RGBColor = RGBColor(30, 150, 60);
pub(super) const PHASE_COLOUR: RGBColor = RGBColor(235, 170, 90);
pub(super) const PHASE_TEXT_COLOUR: RGBColor = RGBColor(170, 100, 20);
pub(super) const DISC_COLOUR: RGBColor = RGBColor(110, 110, 110);

/// A jump in degrees that ends a piece of an angle's line (a wrap).
pub(super) const YAW_JUMP_DEG: f64 = 180.0;

pub(super) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
pub(super) type DrawResult<'a> =
    Result<(), DrawingAreaErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>>;

/// One line of a panel, as pieces that are drawn unbroken.
pub(super) struct Series {
    pub(super) label: &'static str,
    pub(super) colour: RGBColor,
    pub(super) dashed: bool,
    pub(super) segments: Vec<Vec<(f64, f64)>>,
}

/// A panel of a time figure, with an optional shaded band (t, low, high).
pub(super) struct Panel {
    pub(super) title: &'static str,
    pub(super) y_desc: &'static str,
    pub(super) series: Vec<Series>,
    pub(super) band: Vec<Vec<(f64, f64, f64)>>,
}

/// Cuts `(x, y)` samples into drawable pieces: a missing or non-finite value
/// ends a piece, and so does a jump larger than `max_jump` (an angle wrapping
/// from +180 to -180 degrees must not draw a vertical line across the panel).
pub(super) fn segments<I>(points: I, max_jump: Option<f64>) -> Vec<Vec<(f64, f64)>>
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
pub(super) fn band_segments<I>(points: I) -> Vec<Vec<(f64, f64, f64)>>
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
pub(super) fn padded_range<I: IntoIterator<Item = f64>>(
    values: I,
    fallback: Range<f64>,
) -> Range<f64> {
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

pub(super) fn time_range(samples: &[TickRecord], phases: &[PhaseEvent]) -> Range<f64> {
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
pub(super) fn draw_time_panel<'a>(
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
