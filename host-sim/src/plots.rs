//! Plots of a trajectory and a plan (plotters; PNG and SVG): the paper's Figs. 3–6 and more.
//!
//! Owns [`PlotData`] (everything a figure needs, in SI units as computed) and
//! [`write_plots`]. Angles are shown in degrees on the axes (a report), labelled with units.
//!
//! Text needs no system fonts: plotters draws it with `ab_glyph` from a font embedded in the
//! binary (a subset of DejaVu Sans, `host-sim/assets/`), registered on first use. The SVGs
//! carry their text as `<text>` elements (family `sans-serif`); the embedded font only sizes it.
//!
//! Every figure is checked and laid out before any file is written, so bad input writes
//! nothing. Non-finite samples are left out (the line breaks there); empty or mismatched
//! vectors are an error.

use crate::error::CliError;
use plotters::coord::Shift;
use plotters::coord::ranged1d::{Ranged, ValueFormatter};
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// Everything the figures need, as computed by host-sim (SI units, radians).
#[derive(Debug, Clone, PartialEq)]
pub struct PlotData {
    /// Joint names (URDF), one per joint.
    pub joint_names: Vec<String>,
    /// Sample times (s), `t[0] = 0`, last = t_f.
    pub t: Vec<f64>,
    /// Joint positions per sample (rad): `q[sample][joint]`.
    pub q: Vec<Vec<f64>>,
    /// Joint rates per sample (rad/s): `qd[sample][joint]`.
    pub qd: Vec<Vec<f64>>,
    /// Lower joint limits (rad).
    pub lower: Vec<f64>,
    /// Upper joint limits (rad).
    pub upper: Vec<f64>,
    /// Joint rate limit per joint (rad/s).
    pub qd_limit: Vec<f64>,
    /// End-effector position per sample, planner model (m, inertial frame).
    pub ee: Vec<[f64; 3]>,
    /// Target position (m, inertial frame).
    pub target: [f64; 3],
    /// Base rotation angle per sample, truth model (deg).
    pub base_angle_deg: Vec<f64>,
    /// gbest's f after each C-PSO generation (only for plans).
    pub best_f_history: Option<Vec<f64>>,
}

/// Writes the figures into `dir` as PNG and SVG; returns the file names written.
///
/// Figures: `joints`, `joint_rates`, `ee_path`, `base_attitude`, and `convergence` when
/// [`PlotData::best_f_history`] is present; each as `NAME.png` and `NAME.svg`. `dir` must
/// exist. Bad input (empty or mismatched vectors, nothing finite to plot) and write
/// failures are [`CliError::input`] errors; input is checked before any file is written.
pub fn write_plots(dir: &Path, data: &PlotData) -> Result<Vec<String>, CliError> {
    let err = |e: String| CliError::input(format!("writing plots: {e}"));
    ensure_font().map_err(err)?;
    let figures = figures(data).map_err(err)?;
    let mut written = Vec::with_capacity(2 * figures.len());
    for fig in &figures {
        let png = format!("{}.png", fig.name);
        {
            let path = dir.join(&png);
            let root = BitMapBackend::new(&path, fig.size).into_drawing_area();
            draw_figure(&root, fig)
                .and_then(|()| root.present().map_err(|e| e.to_string()))
                .map_err(|e| err(format!("{png}: {e}")))?;
        }
        written.push(png);
        let svg = format!("{}.svg", fig.name);
        {
            let path = dir.join(&svg);
            let root = SVGBackend::new(&path, fig.size).into_drawing_area();
            draw_figure(&root, fig)
                .and_then(|()| root.present().map_err(|e| e.to_string()))
                .map_err(|e| err(format!("{svg}: {e}")))?;
        }
        written.push(svg);
    }
    Ok(written)
}

// ---------------------------------------------------------------------------------------
// Font

/// A subset of DejaVu Sans (Latin-1, Greek, a few symbols); licence next to it.
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans-subset.ttf");

/// Registers [`FONT`] with plotters once, under every generic family name plotters uses.
fn ensure_font() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        for family in ["sans-serif", "serif", "monospace"] {
            plotters::style::register_font(family, FontStyle::Normal, FONT)
                .map_err(|_| "the embedded font does not parse".to_string())?;
        }
        Ok(())
    })
    .clone()
}

// ---------------------------------------------------------------------------------------
// Figure descriptions (backend independent, checked before drawing)

/// Tab10 colours, one per joint (cycled).
const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

fn colour(i: usize) -> RGBColor {
    COLOURS[i % COLOURS.len()]
}

/// One image file (pair): a title and one or more panels side by side.
struct Figure {
    name: &'static str,
    size: (u32, u32),
    /// Title above all panels (multi-panel figures); single panels use their own caption.
    title: Option<String>,
    panels: Vec<Panel>,
}

/// How tick labels are written.
#[derive(Clone, Copy, PartialEq)]
enum Ticks {
    /// Decimal, at most 6 decimals, trailing zeros trimmed.
    Plain,
    /// Scientific notation with `digits` decimals; values closer to zero than `zero` are
    /// printed as 0 (tick positions carry rounding noise).
    Sci { digits: usize, zero: f64 },
    /// Integers (generation counts).
    Integer,
}

/// One chart.
struct Panel {
    title: String,
    x_label: &'static str,
    y_label: &'static str,
    x: (f64, f64),
    y: (f64, f64),
    y_log: bool,
    x_ticks: Ticks,
    y_ticks: Ticks,
    /// At most this many x labels (`None`: plotters' default).
    x_label_count: Option<usize>,
    lines: Vec<Line>,
    markers: Vec<Marker>,
}

#[derive(Clone, Copy, PartialEq)]
enum LineKind {
    Data,
    Limit,
}

/// A polyline, broken where samples were not finite.
struct Line {
    label: Option<String>,
    colour: RGBColor,
    kind: LineKind,
    /// Also mark every sample with a dot (a lone sample always gets one).
    dots: bool,
    segments: Vec<Vec<(f64, f64)>>,
}

#[derive(Clone, Copy)]
enum Shape {
    Circle,
    Square,
    Cross,
}

struct Marker {
    label: &'static str,
    colour: RGBColor,
    shape: Shape,
    at: (f64, f64),
}

/// Checks `data` and lays out every figure.
fn figures(data: &PlotData) -> Result<Vec<Figure>, String> {
    check_shapes(data)?;
    let mut figs = vec![
        joints_figure(data)?,
        rates_figure(data)?,
        ee_figure(data)?,
        base_figure(data)?,
    ];
    if let Some(history) = &data.best_f_history {
        figs.push(convergence_figure(history)?);
    }
    Ok(figs)
}

fn check_shapes(d: &PlotData) -> Result<(), String> {
    let n = d.t.len();
    if n == 0 {
        return Err("no samples (t is empty)".into());
    }
    let nj = d.joint_names.len();
    if nj == 0 {
        return Err("no joints (joint_names is empty)".into());
    }
    let per_sample = [
        ("q", d.q.len()),
        ("qd", d.qd.len()),
        ("ee", d.ee.len()),
        ("base_angle_deg", d.base_angle_deg.len()),
    ];
    for (name, len) in per_sample {
        if len != n {
            return Err(format!("{name} has {len} samples, t has {n}"));
        }
    }
    let per_joint = [
        ("lower", d.lower.len()),
        ("upper", d.upper.len()),
        ("qd_limit", d.qd_limit.len()),
    ];
    for (name, len) in per_joint {
        if len != nj {
            return Err(format!("{name} has {len} entries, there are {nj} joints"));
        }
    }
    for (name, rows) in [("q", &d.q), ("qd", &d.qd)] {
        if let Some((i, row)) = rows.iter().enumerate().find(|(_, r)| r.len() != nj) {
            return Err(format!(
                "{name}[{i}] has {} values, there are {nj} joints",
                row.len()
            ));
        }
    }
    if d.best_f_history.as_ref().is_some_and(Vec::is_empty) {
        return Err("best_f_history is empty".into());
    }
    Ok(())
}

/// Splits `(x, y)` points into runs of finite points.
fn segments(points: impl Iterator<Item = (f64, f64)>) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut current = Vec::new();
    for (x, y) in points {
        if x.is_finite() && y.is_finite() {
            current.push((x, y));
        } else if !current.is_empty() {
            out.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// Min and max of the finite values, `None` if there are none.
fn finite_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// Widens `[lo, hi]` by `margin` of its span on each side; a degenerate range gets a
/// width of its own (10 % of its magnitude, or ±1 around zero).
fn padded(what: &str, (lo, hi): (f64, f64), margin: f64) -> Result<(f64, f64), String> {
    let span = hi - lo;
    let scale = lo.abs().max(hi.abs());
    if !span.is_finite() || !scale.is_finite() {
        return Err(format!("{what}: values too large to plot"));
    }
    if span <= scale * 1e-12 {
        let d = if scale > 0.0 { 0.1 * scale } else { 1.0 };
        return Ok((lo - d, hi + d));
    }
    Ok((lo - margin * span, hi + margin * span))
}

/// The time axis: the finite sample times.
fn time_range(d: &PlotData) -> Result<(f64, f64), String> {
    let r = finite_range(d.t.iter().copied()).ok_or("t has no finite values")?;
    padded("t", r, 0.0)
}

/// Joint-indexed time series (degrees) with each joint's limits as horizontal lines.
fn joint_panel(
    d: &PlotData,
    rows: &[Vec<f64>],
    limits: &dyn Fn(usize) -> [f64; 2],
    what: &str,
    title: &str,
    y_label: &'static str,
) -> Result<Panel, String> {
    let (t0, t1) = time_range(d)?;
    let mut lines = Vec::new();
    let mut ys = Vec::new();
    for (j, name) in d.joint_names.iter().enumerate() {
        let c = colour(j);
        let segs = segments(d.t.iter().zip(rows).map(|(&t, r)| (t, r[j].to_degrees())));
        ys.extend(segs.iter().flatten().map(|p| p.1));
        lines.push(Line {
            label: Some(name.clone()),
            colour: c,
            kind: LineKind::Data,
            dots: false,
            segments: segs,
        });
        for lim in limits(j) {
            let deg = lim.to_degrees();
            if deg.is_finite() {
                ys.push(deg);
                lines.push(Line {
                    label: None,
                    colour: c,
                    kind: LineKind::Limit,
                    dots: false,
                    segments: vec![vec![(t0, deg), (t1, deg)]],
                });
            }
        }
    }
    let y = finite_range(ys.into_iter()).ok_or(format!("{what} has no finite values"))?;
    let y = padded(what, y, 0.05)?;
    // A legend entry for the dashed lines, drawn in grey.
    lines.push(Line {
        label: Some("limits (dashed)".into()),
        colour: RGBColor(90, 90, 90),
        kind: LineKind::Limit,
        dots: false,
        segments: Vec::new(),
    });
    Ok(Panel {
        title: title.into(),
        x_label: "time (s)",
        y_label,
        x: (t0, t1),
        y,
        y_log: false,
        x_ticks: value_ticks((t0, t1)),
        y_ticks: value_ticks(y),
        x_label_count: None,
        lines,
        markers: Vec::new(),
    })
}

fn joints_figure(d: &PlotData) -> Result<Figure, String> {
    let limits = |j: usize| [d.lower[j], d.upper[j]];
    let panel = joint_panel(
        d,
        &d.q,
        &limits,
        "q",
        "Joint angles (dashed: limits)",
        "joint angle (deg)",
    )?;
    Ok(single("joints", (1000, 600), panel))
}

fn rates_figure(d: &PlotData) -> Result<Figure, String> {
    let limits = |j: usize| [-d.qd_limit[j].abs(), d.qd_limit[j].abs()];
    let panel = joint_panel(
        d,
        &d.qd,
        &limits,
        "qd",
        "Joint rates (dashed: ± rate limits)",
        "joint rate (deg/s)",
    )?;
    Ok(single("joint_rates", (1000, 600), panel))
}

fn base_figure(d: &PlotData) -> Result<Figure, String> {
    let (t0, t1) = time_range(d)?;
    let segs = segments(d.t.iter().copied().zip(d.base_angle_deg.iter().copied()));
    let y = finite_range(segs.iter().flatten().map(|p| p.1))
        .ok_or("base_angle_deg has no finite values (at finite times)")?;
    let y = padded("base_angle_deg", y, 0.05)?;
    Ok(single(
        "base_attitude",
        (1000, 600),
        Panel {
            title: "Base attitude disturbance (truth model)".into(),
            x_label: "time (s)",
            y_label: "base rotation (deg)",
            x: (t0, t1),
            y,
            y_log: false,
            x_ticks: value_ticks((t0, t1)),
            y_ticks: value_ticks(y),
            x_label_count: None,
            lines: vec![Line {
                label: None,
                colour: colour(0),
                kind: LineKind::Data,
                dots: false,
                segments: segs,
            }],
            markers: Vec::new(),
        },
    ))
}

fn convergence_figure(history: &[f64]) -> Result<Figure, String> {
    // Generation k + 1 produced history[k]; a log axis shows only positive values.
    let points = history
        .iter()
        .enumerate()
        .map(|(k, &f)| (k as f64 + 1.0, if f > 0.0 { f } else { f64::NAN }));
    let segs = segments(points);
    let (lo, hi) = finite_range(segs.iter().flatten().map(|p| p.1))
        .ok_or("best_f_history has no positive finite values")?;
    // Whole decades, at least one, so that the log axis always has labelled ticks.
    // (Nudged outwards: plotters computes the first tick as 10^ceil(log10(lo)), which
    // rounding can push one decade too far.)
    let lo = 10f64.powf(lo.log10().floor());
    let mut hi = 10f64.powf(hi.log10().ceil());
    if hi <= lo {
        hi = lo * 10.0;
    }
    let (lo, hi) = (lo * (1.0 - 1e-9), hi * (1.0 + 1e-9));
    if !(lo > 0.0 && hi.is_finite()) {
        return Err("best_f_history: values out of range for a log axis".into());
    }
    let n = history.len().max(2);
    Ok(single(
        "convergence",
        (1000, 600),
        Panel {
            title: "C-PSO convergence: best f per generation".into(),
            x_label: "generation",
            y_label: "best f (m, rad)",
            x: (1.0, n as f64),
            y: (lo, hi),
            y_log: true,
            x_ticks: Ticks::Integer,
            y_ticks: Ticks::Sci {
                digits: 0,
                zero: 0.0,
            },
            x_label_count: Some(n.min(10)),
            lines: vec![Line {
                label: None,
                colour: colour(0),
                kind: LineKind::Data,
                dots: history.len() <= 60,
                segments: segs,
            }],
            markers: Vec::new(),
        },
    ))
}

fn ee_figure(d: &PlotData) -> Result<Figure, String> {
    const AXES: [&str; 3] = ["x (m)", "y (m)", "z (m)"];
    const NAMES: [&str; 3] = ["x", "y", "z"];
    let mut panels = Vec::with_capacity(3);
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let segs = segments(d.ee.iter().map(|p| (p[a], p[b])));
        let first = segs.first().and_then(|s| s.first()).copied();
        let last = segs.last().and_then(|s| s.last()).copied();
        let (Some(start), Some(end)) = (first, last) else {
            return Err("ee has no finite positions".into());
        };
        let target = (d.target[a], d.target[b]);
        let mut markers = vec![
            Marker {
                label: "start",
                colour: RGBColor(44, 160, 44),
                shape: Shape::Circle,
                at: start,
            },
            Marker {
                label: "end",
                colour: RGBColor(214, 39, 40),
                shape: Shape::Square,
                at: end,
            },
        ];
        if target.0.is_finite() && target.1.is_finite() {
            markers.push(Marker {
                label: "target",
                colour: BLACK,
                shape: Shape::Cross,
                at: target,
            });
        }
        let pts = || segs.iter().flatten().chain(markers.iter().map(|m| &m.at));
        let xr = finite_range(pts().map(|p| p.0)).ok_or("ee has no finite positions")?;
        let yr = finite_range(pts().map(|p| p.1)).ok_or("ee has no finite positions")?;
        let (x, y) = equal_spans(xr, yr)?;
        panels.push(Panel {
            title: format!("{}–{} projection", NAMES[a], NAMES[b]),
            x_label: AXES[a],
            y_label: AXES[b],
            x,
            y,
            y_log: false,
            x_ticks: value_ticks(x),
            y_ticks: value_ticks(y),
            x_label_count: Some(6),
            lines: vec![Line {
                label: Some("path".into()),
                colour: colour(0),
                kind: LineKind::Data,
                dots: false,
                segments: segs,
            }],
            markers,
        });
    }
    Ok(Figure {
        name: "ee_path",
        size: (1500, 540),
        title: Some("End-effector path (planner model) and target".into()),
        panels,
    })
}

/// An axis range `(low, high)`.
type Interval = (f64, f64);

/// Two ranges with the same (padded) span, centred on their data, so that a path's shape
/// is not distorted much.
fn equal_spans(a: Interval, b: Interval) -> Result<(Interval, Interval), String> {
    let span = (a.1 - a.0).max(b.1 - b.0);
    let scale = [a.0, a.1, b.0, b.1]
        .iter()
        .fold(0f64, |m, v| m.max(v.abs()));
    if !span.is_finite() || !scale.is_finite() {
        return Err("ee: values too large to plot".into());
    }
    let half = if span <= scale * 1e-12 {
        if scale > 0.0 { 0.1 * scale } else { 0.1 }
    } else {
        0.55 * span
    };
    let centre = |r: (f64, f64)| 0.5 * (r.0 + r.1);
    let (ca, cb) = (centre(a), centre(b));
    Ok(((ca - half, ca + half), (cb - half, cb + half)))
}

/// Scientific tick labels for tiny or huge values, plain ones otherwise.
fn value_ticks((lo, hi): (f64, f64)) -> Ticks {
    let mag = lo.abs().max(hi.abs());
    if mag > 0.0 && !(1e-2..1e5).contains(&mag) {
        // Decimals enough to tell ticks about a tenth of the range apart.
        let step = (hi - lo) / 10.0;
        let digits = (mag / step).log10().ceil();
        let digits = if digits.is_finite() {
            digits.clamp(1.0, 6.0) as usize
        } else {
            2
        };
        Ticks::Sci {
            digits,
            zero: 1e-6 * (hi - lo),
        }
    } else {
        Ticks::Plain
    }
}

fn single(name: &'static str, size: (u32, u32), panel: Panel) -> Figure {
    Figure {
        name,
        size,
        title: None,
        panels: vec![panel],
    }
}

// ---------------------------------------------------------------------------------------
// Drawing (generic over the backend)

fn draw_figure<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    fig: &Figure,
) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let area = match &fig.title {
        Some(title) => root
            .titled(title, ("sans-serif", 26).into_font())
            .map_err(e)?,
        None => root.clone(),
    };
    let areas = area.split_evenly((1, fig.panels.len().max(1)));
    for (panel, a) in fig.panels.iter().zip(&areas) {
        draw_panel(a, panel)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<(), String> {
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&p.title, ("sans-serif", 22).into_font())
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(match p.y_ticks {
            Ticks::Sci { .. } => 95,
            _ => 75,
        });
    let x = p.x.0..p.x.1;
    let y = p.y.0..p.y.1;
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
    mesh.x_desc(p.x_label)
        .y_desc(p.y_label)
        .axis_desc_style(("sans-serif", 18))
        .label_style(("sans-serif", 14))
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(244, 244, 244));
    if let Some(n) = p.x_label_count {
        mesh.x_labels(n);
    }
    mesh.draw().map_err(e)?;

    let mut legend = false;
    for line in &p.lines {
        let style = match line.kind {
            LineKind::Data => line.colour.stroke_width(2),
            LineKind::Limit => line.colour.mix(0.8).stroke_width(1),
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
        ann.label(m.label).legend(move |(x, y)| match shape {
            Shape::Circle => Circle::new((x + 12, y), 6, style).into_dyn(),
            Shape::Square => Rectangle::new([(x + 6, y - 6), (x + 18, y + 6)], style).into_dyn(),
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

/// The corner whose neighbourhood (about a third of each axis) holds the fewest data
/// points and markers, so that the legend hides as little as possible.
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
        .filter(|l| l.kind == LineKind::Data)
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
