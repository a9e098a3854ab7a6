//! Drawing a figure specification with plotters (generic over the backend: PNG and SVG).

use super::figures::{Figure, LineKind, Panel, Shape, Ticks};
use plotters::coord::Shift;
use plotters::coord::ranged1d::{Ranged, ValueFormatter};
use plotters::element::DashedPathElement;
use plotters::prelude::*;

pub(super) fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &Figure,
) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    // A footer band for the stamp, below everything else.
    let (_, h) = root.dim_in_pixel();
    let (body, footer) = root.split_vertically(h.saturating_sub(18));
    let area = match &fig.title {
        Some(title) => body
            .titled(title, ("sans-serif", 26).into_font())
            .map_err(e)?,
        None => body.clone(),
    };
    let columns = fig.columns.clamp(1, fig.panels.len().max(1));
    let rows = fig.panels.len().div_ceil(columns).max(1);
    let areas = area.split_evenly((rows, columns));
    for (panel, a) in fig.panels.iter().zip(&areas) {
        draw_panel(a, panel, fig.equal_aspect)?;
    }
    if !fig.stamp.is_empty() {
        let (w, h) = footer.dim_in_pixel();
        let style = ("sans-serif", 12)
            .into_font()
            .color(&RGBColor(110, 110, 110))
            .pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Right,
                plotters::style::text_anchor::VPos::Bottom,
            ));
        footer
            .draw_text(&fig.stamp, &style, (w as i32 - 6, h as i32 - 3))
            .map_err(e)?;
    }
    Ok(())
}

/// Pixels the chart decorations take: margin, caption, axis label areas.
const MARGIN: u32 = 12;
const CAPTION: u32 = 32;
const X_LABELS: u32 = 50;

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &Panel,
    equal_aspect: bool,
) -> Result<(), String> {
    let y_labels = match p.y_ticks {
        Ticks::Sci { .. } => 95,
        _ => 75,
    };
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, ("sans-serif", 22).into_font())
        .margin(MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(y_labels);
    let (mut x, mut y) = (p.x, p.y);
    if equal_aspect {
        // Widen one range so that a metre spans as many pixels on both axes.
        let (w, h) = area.dim_in_pixel();
        let pw = f64::from(w.saturating_sub(y_labels + 2 * MARGIN).max(1));
        let ph = f64::from(h.saturating_sub(X_LABELS + CAPTION + 2 * MARGIN).max(1));
        let (sx, sy) = ((x.1 - x.0) / pw, (y.1 - y.0) / ph);
        if sx > sy {
            let half = 0.5 * sx * ph;
            let c = 0.5 * (y.0 + y.1);
            y = (c - half, c + half);
        } else {
            let half = 0.5 * sy * pw;
            let c = 0.5 * (x.0 + x.1);
            x = (c - half, c + half);
        }
    }
    let x = x.0..x.1;
    let y = y.0..y.1;
    if p.y_log {
        let chart = builder
            .build_cartesian_2d(x, y.log_scale())
            .map_err(|e| e.to_string())?;
        fill_chart(chart, p)
    } else {
        let chart = builder
            .build_cartesian_2d(x, y)
            .map_err(|e| e.to_string())?;
        fill_chart(chart, p)
    }
}

fn tick_label(ticks: Ticks, v: f64) -> String {
    match ticks {
        Ticks::Plain => {
            // Like plotters' default, but without float noise such as 0.30000000000000004.
            let s = format!("{v:.6}");
            let s = s.trim_end_matches('0').trim_end_matches('.');
            if s == "-0" { "0".into() } else { s.into() }
        }
        Ticks::Sci { zero, .. } if v.abs() <= zero => "0".into(),
        Ticks::Sci { digits, .. } => format!("{v:.digits$e}"),
        Ticks::Integer => format!("{v:.0}"),
    }
}

fn fill_chart<'a, DB, X, Y>(
    mut chart: ChartContext<'a, DB, Cartesian2d<X, Y>>,
    p: &Panel,
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let x_fmt = |v: &f64| tick_label(p.x_ticks, *v);
    let y_fmt = |v: &f64| tick_label(p.y_ticks, *v);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .axis_desc_style(("sans-serif", 18))
        .label_style(("sans-serif", 14))
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(244, 244, 244));
    if let Some(n) = p.x_label_count {
        mesh.x_labels(n);
    }
    if let Some(n) = p.y_label_count {
        mesh.y_labels(n);
    }
    mesh.draw().map_err(e)?;

    let mut legend = false;
    for line in &p.lines {
        let style = match line.kind {
            LineKind::Data => line.colour.stroke_width(2),
            LineKind::Limit => line.colour.mix(0.8).stroke_width(1),
            LineKind::Reference => line.colour.stroke_width(2),
        };
        let mut annotated = false;
        // An empty segment list still gets its legend entry.
        let segs: &[Vec<(f64, f64)>] = if line.segments.is_empty() {
            &[Vec::new()]
        } else {
            &line.segments
        };
        for seg in segs {
            let ann = match line.kind {
                LineKind::Data => chart
                    .draw_series(LineSeries::new(seg.iter().copied(), style))
                    .map_err(e)?,
                LineKind::Limit => chart
                    .draw_series(DashedLineSeries::new(seg.iter().copied(), 8, 5, style))
                    .map_err(e)?,
                LineKind::Reference => chart
                    .draw_series(DashedLineSeries::new(seg.iter().copied(), 2, 4, style))
                    .map_err(e)?,
            };
            if let (Some(label), false) = (&line.label, annotated) {
                annotated = true;
                legend = true;
                let kind = line.kind;
                ann.label(label.as_str()).legend(move |(x, y)| {
                    let pts = vec![(x, y), (x + 24, y)];
                    match kind {
                        LineKind::Data => PathElement::new(pts, style).into_dyn(),
                        LineKind::Limit => DashedPathElement::new(pts, 5, 3, style).into_dyn(),
                        LineKind::Reference => DashedPathElement::new(pts, 2, 3, style).into_dyn(),
                    }
                });
            }
            if line.dots || seg.len() == 1 {
                let dot = line.colour.filled();
                chart
                    .draw_series(seg.iter().map(|&at| Circle::new(at, 3, dot)))
                    .map_err(e)?;
            }
        }
    }
    for m in &p.markers {
        let style = m.colour.filled();
        let ann = match m.shape {
            Shape::Circle => chart
                .draw_series(std::iter::once(Circle::new(m.at, 7, style)))
                .map_err(e)?,
            Shape::Square => chart
                .draw_series(std::iter::once(
                    EmptyElement::at(m.at) + Rectangle::new([(-7, -7), (7, 7)], style),
                ))
                .map_err(e)?,
            Shape::Cross => chart
                .draw_series(std::iter::once(Cross::new(
                    m.at,
                    8,
                    m.colour.stroke_width(3),
                )))
                .map_err(e)?,
        };
        let shape = m.shape;
        let colour = m.colour;
        ann.label(m.label.as_str())
            .legend(move |(x, y)| match shape {
                Shape::Circle => Circle::new((x + 12, y), 6, style).into_dyn(),
                Shape::Square => {
                    Rectangle::new([(x + 6, y - 6), (x + 18, y + 6)], style).into_dyn()
                }
                Shape::Cross => Cross::new((x + 12, y), 7, colour.stroke_width(3)).into_dyn(),
            });
        legend = true;
    }
    if legend {
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(legend_corner(p))
            .draw()
            .map_err(e)?;
    }
    Ok(())
}

/// The corner whose neighbourhood (about a third of each axis) holds the fewest points of
/// data and reference lines and markers (limits are not counted), so that the legend hides
/// as little as possible.
fn legend_corner(p: &Panel) -> SeriesLabelPosition {
    let frac = |v: f64, (lo, hi): (f64, f64), log: bool| {
        if log {
            (v.ln() - lo.ln()) / (hi.ln() - lo.ln())
        } else {
            (v - lo) / (hi - lo)
        }
    };
    let points = p
        .lines
        .iter()
        .filter(|l| l.kind != LineKind::Limit)
        .flat_map(|l| l.segments.iter().flatten())
        .chain(p.markers.iter().map(|m| &m.at))
        .map(|&(x, y)| (frac(x, p.x, false), frac(y, p.y, p.y_log)));
    // Upper right, upper left, lower right, lower left: (right?, upper?).
    let corners = [(true, true), (false, true), (true, false), (false, false)];
    let mut counts = [0usize; 4];
    for (fx, fy) in points {
        for (count, &(right, upper)) in counts.iter_mut().zip(&corners) {
            let in_x = if right { fx > 0.62 } else { fx < 0.38 };
            let in_y = if upper { fy > 0.62 } else { fy < 0.38 };
            if in_x && in_y {
                *count += 1;
            }
        }
    }
    let best = (0..4).min_by_key(|&i| counts[i]).unwrap_or(0);
    match best {
        1 => SeriesLabelPosition::UpperLeft,
        2 => SeriesLabelPosition::LowerRight,
        3 => SeriesLabelPosition::LowerLeft,
        _ => SeriesLabelPosition::UpperRight,
    }
}
