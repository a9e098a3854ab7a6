//! Figure specifications: what each figure shows, checked and laid out before anything is
//! drawn (backend independent).

use super::PlotData;
use plotters::style::{BLACK, RGBColor};

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
pub(super) struct Figure {
    /// What made it (task, seed, build), printed in the lower right corner.
    pub(super) stamp: String,
    /// One unit is as long on both axes (the plot areas are made square by the drawing).
    pub(super) equal_aspect: bool,
    pub(super) name: &'static str,
    pub(super) size: (u32, u32),
    /// Title above all panels (multi-panel figures); single panels use their own caption.
    pub(super) title: Option<String>,
    pub(super) panels: Vec<Panel>,
}

/// How tick labels are written.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Ticks {
    /// Decimal, at most 6 decimals, trailing zeros trimmed.
    Plain,
    /// Scientific notation with `digits` decimals; values closer to zero than `zero` are
    /// printed as 0 (tick positions carry rounding noise).
    Sci { digits: usize, zero: f64 },
    /// Integers (generation counts).
    Integer,
}

/// One chart.
pub(super) struct Panel {
    pub(super) title: String,
    pub(super) x_label: &'static str,
    pub(super) y_label: &'static str,
    pub(super) x: (f64, f64),
    pub(super) y: (f64, f64),
    pub(super) y_log: bool,
    pub(super) x_ticks: Ticks,
    pub(super) y_ticks: Ticks,
    /// At most this many x labels (`None`: plotters' default).
    pub(super) x_label_count: Option<usize>,
    pub(super) lines: Vec<Line>,
    pub(super) markers: Vec<Marker>,
}

#[derive(Clone, Copy, PartialEq)]
pub(super) enum LineKind {
    Data,
    Limit,
}

/// A polyline, broken where samples were not finite.
pub(super) struct Line {
    pub(super) label: Option<String>,
    pub(super) colour: RGBColor,
    pub(super) kind: LineKind,
    /// Also mark every sample with a dot (a lone sample always gets one).
    pub(super) dots: bool,
    pub(super) segments: Vec<Vec<(f64, f64)>>,
}

#[derive(Clone, Copy)]
pub(super) enum Shape {
    Circle,
    Square,
    Cross,
}

pub(super) struct Marker {
    pub(super) label: &'static str,
    pub(super) colour: RGBColor,
    pub(super) shape: Shape,
    pub(super) at: (f64, f64),
}

/// Checks `data` and lays out every figure.
pub(super) fn figures(data: &PlotData) -> Result<Vec<Figure>, String> {
    check_shapes(data)?;
    let mut figs = vec![
        joints_figure(data)?,
        rates_figure(data)?,
        ee_figure(data)?,
        base_figure(data)?,
    ];
    if let Some(history) = &data.best_f_history {
        figs.push(convergence_figure(history, data)?);
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

/// Each joint's series as a fraction of its range: `(v − lo)/(hi − lo)` lies in [0, 1]
/// while the joint keeps its limits (drawn once, dashed, at 0 and 1), whatever the joint's
/// range, so that every joint is readable on one axis.
fn normalised_panel(
    d: &PlotData,
    rows: &[Vec<f64>],
    range: &dyn Fn(usize) -> (f64, f64),
    label: &dyn Fn(&str, (f64, f64)) -> String,
    what: &str,
    title: &str,
    y_label: &'static str,
) -> Result<Panel, String> {
    let (t0, t1) = time_range(d)?;
    let mut lines = Vec::new();
    let mut ys = vec![0.0, 1.0];
    for (j, name) in d.joint_names.iter().enumerate() {
        let (lo, hi) = range(j);
        let span = hi - lo;
        if !(span.is_finite() && span > 0.0) {
            // Nothing to normalise by: named in the legend, not drawn.
            lines.push(Line {
                label: Some(format!("{name} (no finite limits: not shown)")),
                colour: colour(j),
                kind: LineKind::Data,
                dots: false,
                segments: Vec::new(),
            });
            continue;
        }
        let segs = segments(d.t.iter().zip(rows).map(|(&t, r)| (t, (r[j] - lo) / span)));
        ys.extend(segs.iter().flatten().map(|p| p.1));
        lines.push(Line {
            label: Some(label(name, (lo, hi))),
            colour: colour(j),
            kind: LineKind::Data,
            dots: false,
            segments: segs,
        });
    }
    for (k, level) in [0.0, 1.0].into_iter().enumerate() {
        lines.push(Line {
            label: (k == 0).then(|| "limits".into()),
            colour: RGBColor(90, 90, 90),
            kind: LineKind::Limit,
            dots: false,
            segments: vec![vec![(t0, level), (t1, level)]],
        });
    }
    let y = finite_range(ys.into_iter()).ok_or(format!("{what} has no finite values"))?;
    let y = padded(what, y, 0.05)?;
    Ok(Panel {
        title: title.into(),
        x_label: "time (s)",
        y_label,
        x: (t0, t1),
        y,
        y_log: false,
        x_ticks: value_ticks((t0, t1)),
        y_ticks: Ticks::Plain,
        x_label_count: None,
        lines,
        markers: Vec::new(),
    })
}

fn joints_figure(d: &PlotData) -> Result<Figure, String> {
    let range = |j: usize| (d.lower[j], d.upper[j]);
    let label = |name: &str, (lo, hi): (f64, f64)| {
        format!("{name} [{:.0}°, {:.0}°]", lo.to_degrees(), hi.to_degrees())
    };
    let panel = normalised_panel(
        d,
        &d.q,
        &range,
        &label,
        "q",
        "Joint angles within their limits",
        "position in range (0 = lower, 1 = upper limit)",
    )?;
    Ok(single("joints", (1000, 600), panel, d))
}

fn rates_figure(d: &PlotData) -> Result<Figure, String> {
    let range = |j: usize| (-d.qd_limit[j].abs(), d.qd_limit[j].abs());
    let label = |name: &str, (_, hi): (f64, f64)| format!("{name} (±{:.1}°/s)", hi.to_degrees());
    let panel = normalised_panel(
        d,
        &d.qd,
        &range,
        &label,
        "qd",
        "Joint rates within their limits",
        "rate in range (0 = −limit, 0.5 = rest, 1 = +limit)",
    )?;
    Ok(single("joint_rates", (1000, 600), panel, d))
}

/// The figures of a re-timed trajectory: rates (`d.qd` against `d.qd_limit`) and
/// accelerations (`qdd` against `qdd_limit`), each as a fraction of `[−limit, +limit]`.
pub(super) fn retime_figures(
    d: &PlotData,
    qdd: &[Vec<f64>],
    qdd_limit: &[f64],
) -> Result<Vec<Figure>, String> {
    if qdd.len() != d.t.len() || qdd_limit.len() != d.joint_names.len() {
        return Err("accelerations do not match the setpoints".into());
    }
    let mut rates = rates_figure(d)?;
    rates.name = "retimed_rates";
    if let Some(p) = rates.panels.first_mut() {
        p.title = "Re-timed joint rates within their limits".into();
    }
    let range = |j: usize| (-qdd_limit[j].abs(), qdd_limit[j].abs());
    let label = |name: &str, (_, hi): (f64, f64)| format!("{name} (±{:.2}°/s²)", hi.to_degrees());
    let panel = normalised_panel(
        d,
        qdd,
        &range,
        &label,
        "qdd",
        "Re-timed joint accelerations within their limits",
        "acceleration in range (0 = −limit, 0.5 = 0, 1 = +limit)",
    )?;
    Ok(vec![
        rates,
        single("retimed_accelerations", (1000, 600), panel, d),
    ])
}

fn base_figure(d: &PlotData) -> Result<Figure, String> {
    let (t0, t1) = time_range(d)?;
    let segs = segments(d.t.iter().copied().zip(d.base_angle_deg.iter().copied()));
    let y = finite_range(segs.iter().flatten().map(|p| p.1))
        .ok_or("base_angle_deg has no finite values (at finite times)")?;
    let limit = d.base_limit_deg;
    let top = if limit.is_finite() && limit > 0.0 {
        y.1.max(limit)
    } else {
        y.1
    };
    let y = padded("base_angle_deg", (y.0.min(0.0), top), 0.05)?;
    let mut lines = vec![Line {
        label: Some("base rotation".into()),
        colour: colour(0),
        kind: LineKind::Data,
        dots: false,
        segments: segs,
    }];
    if limit.is_finite() && limit > 0.0 {
        lines.push(Line {
            label: Some(format!("requirement {limit}°")),
            colour: RGBColor(214, 39, 40),
            kind: LineKind::Limit,
            dots: false,
            segments: vec![vec![(t0, limit), (t1, limit)]],
        });
    }
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
            lines,
            markers: Vec::new(),
        },
        d,
    ))
}

fn convergence_figure(history: &[f64], d: &PlotData) -> Result<Figure, String> {
    // Rollout k + 1 produced history[k]; a log axis shows only positive values.
    let points = history
        .iter()
        .enumerate()
        .map(|(k, &f)| (k as f64 + 1.0, if f > 0.0 { f } else { f64::NAN }));
    let segs = segments(points);
    let sigma = d.tolerance;
    if !segs.iter().flatten().any(|p| p.1 > 0.0 && p.1.is_finite()) {
        return Err("best_f_history has no positive finite values".into());
    }
    let (lo, hi) = finite_range(
        segs.iter()
            .flatten()
            .map(|p| p.1)
            .chain((sigma > 0.0 && sigma.is_finite()).then_some(sigma)),
    )
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
            title: "Convergence: best f after each rollout".into(),
            x_label: "rollouts",
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
            lines: {
                let mut lines = vec![Line {
                    label: Some("best f so far".into()),
                    colour: colour(0),
                    kind: LineKind::Data,
                    dots: history.len() <= 60,
                    segments: segs,
                }];
                if sigma > 0.0 && sigma.is_finite() {
                    lines.push(Line {
                        label: Some(format!("σ_e = {sigma}")),
                        colour: RGBColor(214, 39, 40),
                        kind: LineKind::Limit,
                        dots: false,
                        segments: vec![vec![(1.0, sigma), (n as f64, sigma)]],
                    });
                }
                lines
            },
            markers: d
                .first_hit
                .and_then(|k| {
                    let f = *history.get((k as usize).checked_sub(1)?)?;
                    (f > 0.0).then_some(Marker {
                        label: "success",
                        colour: RGBColor(44, 160, 44),
                        shape: Shape::Circle,
                        at: (f64::from(k), f),
                    })
                })
                .into_iter()
                .collect(),
        },
        d,
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
        title: Some("End-effector path (planner model) and target, equal axis scales".into()),
        panels,
        stamp: d.stamp.clone(),
        equal_aspect: true,
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
#[allow(clippy::disallowed_methods)] // constant bounds 1 <= 6: clamp cannot panic here
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

fn single(name: &'static str, size: (u32, u32), panel: Panel, d: &PlotData) -> Figure {
    Figure {
        name,
        size,
        title: None,
        panels: vec![panel],
        stamp: d.stamp.clone(),
        equal_aspect: false,
    }
}

/// The empirical CDF of one Monte Carlo figure, with its limit as a vertical line.
pub(super) fn cdf_figure(c: &super::Cdf<'_>, stamp: &str) -> Result<Figure, String> {
    let mut v: Vec<f64> = c.values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return Err(format!("{}: no finite values", c.name));
    }
    v.sort_by(f64::total_cmp);
    let n = v.len() as f64;
    let mut points = Vec::with_capacity(2 * v.len());
    for (k, x) in v.iter().enumerate() {
        points.push((*x, k as f64 / n));
        points.push((*x, (k + 1) as f64 / n));
    }
    let (lo, hi) = finite_range(v.iter().copied().chain(c.limit))
        .ok_or_else(|| format!("{}: no finite values", c.name))?;
    let x = padded(c.name, (lo, hi), 0.05)?;
    let mut lines = vec![Line {
        label: Some(format!("{} samples", v.len())),
        colour: colour(0),
        kind: LineKind::Data,
        dots: false,
        segments: vec![points],
    }];
    if let Some(l) = c.limit {
        lines.push(Line {
            label: Some(format!("limit {l}")),
            colour: RGBColor(214, 39, 40),
            kind: LineKind::Limit,
            dots: false,
            segments: vec![vec![(l, 0.0), (l, 1.0)]],
        });
    }
    let (name, x_label): (&'static str, &'static str) = match c.name {
        "base_disturbance_deg" => ("cdf_base_disturbance_deg", "base disturbance (deg)"),
        "final_attitude_error_deg" => (
            "cdf_final_attitude_error_deg",
            "final base attitude error (deg)",
        ),
        "position_error_m" => ("cdf_position_error_m", "end-effector position error (m)"),
        "orientation_error_deg" => (
            "cdf_orientation_error_deg",
            "end-effector orientation error (deg)",
        ),
        "f" => ("cdf_f", "f = |e| (m, rad)"),
        _ => ("cdf", "value"),
    };
    Ok(Figure {
        name,
        size: (900, 600),
        title: None,
        panels: vec![Panel {
            title: format!("Cumulative distribution of {}", c.name),
            x_label,
            y_label: "fraction of samples",
            x,
            y: (0.0, 1.0),
            y_log: false,
            x_ticks: value_ticks(x),
            y_ticks: Ticks::Plain,
            x_label_count: Some(8),
            lines,
            markers: Vec::new(),
        }],
        stamp: stamp.to_string(),
        equal_aspect: false,
    })
}
