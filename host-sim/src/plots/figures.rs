//! Figure specifications: what each figure shows, checked and laid out before anything is
//! drawn (backend independent).

use super::{Cdf, LoopPlotData, PlotData, RetimePlotData};
use crate::goal::number;
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

/// One image file (pair): a title and one or more panels in a grid.
pub(super) struct Figure {
    /// What made it (task, seed, build), printed in the lower right corner.
    pub(super) stamp: String,
    /// One unit is as long on both axes (the plot areas are made square by the drawing).
    pub(super) equal_aspect: bool,
    /// The file name without its extension.
    pub(super) name: String,
    pub(super) size: (u32, u32),
    /// Title above all panels (multi-panel figures); single panels use their own caption.
    pub(super) title: Option<String>,
    /// Panels per row; the panels fill the rows in order, left to right.
    pub(super) columns: usize,
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
    pub(super) x_label: String,
    pub(super) y_label: String,
    pub(super) x: (f64, f64),
    pub(super) y: (f64, f64),
    pub(super) y_log: bool,
    pub(super) x_ticks: Ticks,
    pub(super) y_ticks: Ticks,
    /// At most this many x labels (`None`: plotters' default).
    pub(super) x_label_count: Option<usize>,
    /// At most this many y labels (`None`: plotters' default).
    pub(super) y_label_count: Option<usize>,
    pub(super) lines: Vec<Line>,
    pub(super) markers: Vec<Marker>,
}

#[derive(Clone, Copy, PartialEq)]
pub(super) enum LineKind {
    /// Measured or computed values: solid.
    Data,
    /// A limit or a requirement: dashed.
    Limit,
    /// A reference value (the nominal of a dispersion), or a line drawn over another: dotted.
    Reference,
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
    pub(super) label: String,
    pub(super) colour: RGBColor,
    pub(super) shape: Shape,
    pub(super) at: (f64, f64),
}

/// The colour of limits and requirements.
const RED: RGBColor = RGBColor(214, 39, 40);
/// The colour of start points and nominal values.
const GREEN: RGBColor = RGBColor(44, 160, 44);

/// Checks `data` and lays out every figure.
pub(super) fn figures(data: &PlotData) -> Result<Vec<Figure>, String> {
    check_shapes(data)?;
    let angles = JointSeries {
        name: "joints",
        title: "Joint angles (deg) and their limits (URDF)",
        quantity: "angle",
        unit: "deg",
        rows: &data.q,
        limits: data
            .lower
            .iter()
            .copied()
            .zip(data.upper.iter().copied())
            .collect(),
        peak_in_title: false,
    };
    let rates = JointSeries {
        name: "joint_rates",
        title: "Joint rates (deg/s) and their limits (URDF velocity)",
        quantity: "rate",
        unit: "deg/s",
        rows: &data.qd,
        limits: symmetric(&data.qd_limit),
        peak_in_title: true,
    };
    let mut figs = vec![
        joint_figure(&data.joint_names, &data.t, &angles, &data.stamp)?,
        joint_figure(&data.joint_names, &data.t, &rates, &data.stamp)?,
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
        ("base_wxyz", d.base_wxyz.len()),
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
    check_rows(&[("q", &d.q), ("qd", &d.qd)], nj)?;
    if d.best_f_history.as_ref().is_some_and(Vec::is_empty) {
        return Err("best_f_history is empty".into());
    }
    Ok(())
}

/// Every row of every named table has `nj` values.
fn check_rows(tables: &[(&str, &Vec<Vec<f64>>)], nj: usize) -> Result<(), String> {
    for (name, rows) in tables {
        if let Some((i, row)) = rows.iter().enumerate().find(|(_, r)| r.len() != nj) {
            return Err(format!(
                "{name}[{i}] has {} values, there are {nj} joints",
                row.len()
            ));
        }
    }
    Ok(())
}

/// A ratio as a percentage: `36%`, `7.3%`, `0.5%`; near 100 % with a decimal, so that
/// 99.7 % does not read as the limit reached.
fn percent(ratio: f64) -> String {
    let p = 100.0 * ratio;
    if p.abs() < 10.0 || (p.abs() - 100.0).abs() < 0.5 {
        format!("{p:.1}%")
    } else {
        format!("{p:.0}%")
    }
}

/// `[−limit, +limit]` per joint.
fn symmetric(limits: &[f64]) -> Vec<(f64, f64)> {
    limits.iter().map(|v| (-v.abs(), v.abs())).collect()
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
fn time_range(t: &[f64]) -> Result<(f64, f64), String> {
    let r = finite_range(t.iter().copied()).ok_or("t has no finite values")?;
    padded("t", r, 0.0)
}

/// A per-joint quantity for [`joint_figure`], in SI units (rad, rad/s, rad/s²): drawn in
/// degrees.
struct JointSeries<'a> {
    /// The file name.
    name: &'static str,
    /// The figure's title, unit included.
    title: &'a str,
    /// What is on the y axis, e.g. `angle`.
    quantity: &'static str,
    /// Its unit once converted to degrees, e.g. `deg/s`.
    unit: &'static str,
    /// `rows[sample][joint]` (rad, rad/s or rad/s²).
    rows: &'a [Vec<f64>],
    /// `(lower, upper)` limit per joint, same unit as `rows`; a non-finite one is not drawn.
    limits: Vec<(f64, f64)>,
    /// Each panel's title gives the joint's peak against its (symmetric) limit; otherwise
    /// the span it moved over.
    peak_in_title: bool,
}

/// Size of one joint panel (px).
const JOINT_PANEL: (u32, u32) = (480, 300);

/// One panel per joint: the joint's series in degrees against time, its limits as dashed
/// lines labelled with their values, the y range set by the data and the limits. The
/// panels fill a near-square grid (3 joints: 2 × 2; 7 joints: 3 × 3).
fn joint_figure(
    names: &[String],
    t: &[f64],
    s: &JointSeries<'_>,
    stamp: &str,
) -> Result<Figure, String> {
    let (t0, t1) = time_range(t)?;
    let mut panels = Vec::with_capacity(names.len());
    for (j, name) in names.iter().enumerate() {
        let (lo, hi) = s.limits.get(j).copied().unwrap_or((f64::NAN, f64::NAN));
        let (lo, hi) = (lo.to_degrees(), hi.to_degrees());
        let segs = segments(
            t.iter()
                .zip(s.rows)
                .map(|(&t, r)| (t, r.get(j).map_or(f64::NAN, |v| v.to_degrees()))),
        );
        let finite_limits: Vec<f64> = [lo, hi].into_iter().filter(|v| v.is_finite()).collect();
        let y = finite_range(
            segs.iter()
                .flatten()
                .map(|p| p.1)
                .chain(finite_limits.iter().copied()),
        );
        let y = match y {
            Some(y) => padded(&format!("{} of {name}", s.quantity), y, 0.08)?,
            None => (-1.0, 1.0),
        };
        let symmetric = lo.is_finite() && hi.is_finite() && (lo + hi).abs() <= 1e-9 * hi.abs();
        let limit_label = match (lo.is_finite(), hi.is_finite()) {
            (true, true) if symmetric => {
                format!("limits ±{} {}", number(hi), s.unit)
            }
            (true, true) => format!("limits {} to {} {}", number(lo), number(hi), s.unit),
            (true, false) => format!("lower limit {} {} (no upper)", number(lo), s.unit),
            (false, true) => format!("upper limit {} {} (no lower)", number(hi), s.unit),
            (false, false) => "no finite limits".into(),
        };
        // What the joint did, in the title: its span, or its peak against a symmetric limit.
        let span = finite_range(segs.iter().flatten().map(|p| p.1));
        let peak = span.map(|(a, b)| a.abs().max(b.abs()));
        let title = match (span, peak) {
            (Some(_), Some(p)) if s.peak_in_title && symmetric && hi > 0.0 => format!(
                "{name}: peak {} {} ({} of its limit)",
                number(p),
                s.unit,
                percent(p / hi)
            ),
            (Some((a, b)), _) => {
                format!("{name}: between {} and {} {}", number(a), number(b), s.unit)
            }
            _ => name.clone(),
        };
        let lines = vec![
            Line {
                label: segs.is_empty().then(|| "no finite samples".into()),
                colour: colour(j),
                kind: LineKind::Data,
                dots: false,
                segments: segs,
            },
            Line {
                label: Some(limit_label),
                colour: RED,
                kind: LineKind::Limit,
                dots: false,
                segments: finite_limits
                    .iter()
                    .map(|&v| vec![(t0, v), (t1, v)])
                    .collect(),
            },
        ];
        panels.push(Panel {
            title,
            x_label: "time (s)".into(),
            y_label: format!("{} ({})", s.quantity, s.unit),
            x: (t0, t1),
            y,
            y_log: false,
            x_ticks: value_ticks((t0, t1)),
            y_ticks: value_ticks(y),
            x_label_count: Some(6),
            y_label_count: Some(6),
            lines,
            markers: Vec::new(),
        });
    }
    let n = panels.len().max(1);
    let columns = (1..=n).find(|c| c * c >= n).unwrap_or(1);
    let rows = n.div_ceil(columns);
    let (w, h) = JOINT_PANEL;
    Ok(Figure {
        stamp: stamp.to_string(),
        equal_aspect: false,
        name: s.name.into(),
        size: ((w * columns as u32).max(960), h * rows as u32 + 60),
        title: Some(s.title.to_string()),
        columns,
        panels,
    })
}

/// The figures of a re-timed trajectory: each joint's rate (deg/s) and acceleration
/// (deg/s²) against the limits used, one panel per joint.
pub(super) fn retime_figures(d: &RetimePlotData) -> Result<Vec<Figure>, String> {
    let n = d.t.len();
    if n == 0 {
        return Err("no setpoints (t is empty)".into());
    }
    let nj = d.joint_names.len();
    if nj == 0 {
        return Err("no joints (joint_names is empty)".into());
    }
    if d.qd.len() != n || d.qdd.len() != n {
        return Err(format!(
            "qd has {} and qdd {} setpoints, t has {n}",
            d.qd.len(),
            d.qdd.len()
        ));
    }
    if d.qd_limit.len() != nj || d.qdd_limit.len() != nj {
        return Err(format!(
            "qd_limit has {} and qdd_limit {} entries, there are {nj} joints",
            d.qd_limit.len(),
            d.qdd_limit.len()
        ));
    }
    check_rows(&[("qd", &d.qd), ("qdd", &d.qdd)], nj)?;
    let rates = JointSeries {
        name: "retimed_rates",
        title: "Re-timed joint rates (deg/s) and the limits used",
        quantity: "rate",
        unit: "deg/s",
        rows: &d.qd,
        limits: symmetric(&d.qd_limit),
        peak_in_title: true,
    };
    let accelerations = JointSeries {
        name: "retimed_accelerations",
        title: "Re-timed joint accelerations (deg/s²) and the limits used",
        quantity: "acceleration",
        unit: "deg/s²",
        rows: &d.qdd,
        limits: symmetric(&d.qdd_limit),
        peak_in_title: true,
    };
    Ok(vec![
        joint_figure(&d.joint_names, &d.t, &rates, &d.stamp)?,
        joint_figure(&d.joint_names, &d.t, &accelerations, &d.stamp)?,
    ])
}

/// The rotation vector θ = angle · axis (deg) of the unit quaternion `[w, x, y, z]`, the
/// shorter of its two rotations. Its components are the same in both frames the rotation
/// relates (the axis is fixed by it). A zero quaternion gives NaN.
fn rotation_vector_deg(q: [f64; 4]) -> [f64; 3] {
    let [w, x, y, z] = if q[0] < 0.0 { q.map(|c| -c) } else { q };
    let s = (x * x + y * y + z * z).sqrt();
    // angle / sin(angle/2) · (1/|q|) = 2·atan2(s, w)/s; at s = 0 its limit is 2/w.
    let k = if s > 0.0 {
        2.0 * s.atan2(w) / s
    } else {
        2.0 / w
    };
    [x, y, z].map(|c| (k * c).to_degrees())
}

/// The base attitude figure: on the left the truth-model base rotation vector's three
/// components and its magnitude (deg, linear, the y range set by the data, and by the
/// requirement when that is at most twice the largest value); on the right the magnitude
/// against the requirement on a log axis, whose range spans both.
fn base_figure(d: &PlotData) -> Result<Figure, String> {
    let (t0, t1) = time_range(&d.t)?;
    let magnitude = segments(d.t.iter().copied().zip(d.base_angle_deg.iter().copied()));
    if magnitude.is_empty() {
        return Err("base_angle_deg has no finite values (at finite times)".into());
    }
    let theta: Vec<[f64; 3]> = d
        .base_wxyz
        .iter()
        .map(|&q| rotation_vector_deg(q))
        .collect();
    let components: Vec<Vec<Vec<(f64, f64)>>> = (0..3)
        .map(|k| segments(d.t.iter().zip(&theta).map(|(&t, v)| (t, v[k]))))
        .collect();
    let limit = d.base_limit_deg;
    let has_limit = limit.is_finite() && limit > 0.0;
    // The largest magnitude and when.
    let (t_peak, peak) = magnitude
        .iter()
        .flatten()
        .copied()
        .fold((t0, 0.0f64), |best, p| if p.1 > best.1 { p } else { best });
    let requirement = |segs: Vec<Vec<(f64, f64)>>| Line {
        label: Some(format!("requirement ≤ {} deg", number(limit))),
        colour: RED,
        kind: LineKind::Limit,
        dots: false,
        segments: segs,
    };

    // Left: linear, fitted to the data.
    let y = finite_range(
        magnitude
            .iter()
            .chain(components.iter().flatten())
            .flatten()
            .map(|p| p.1),
    )
    .ok_or("base_angle_deg has no finite values")?;
    let limit_on_left = has_limit && limit <= 2.0 * y.1.max(-y.0);
    let y = if limit_on_left {
        (y.0, y.1.max(limit))
    } else {
        y
    };
    let y = padded("base rotation", (y.0.min(0.0), y.1), 0.06)?;
    let mut lines: Vec<Line> = components
        .into_iter()
        .zip(["θx", "θy", "θz"])
        .enumerate()
        .map(|(k, (segs, name))| Line {
            label: Some(name.into()),
            colour: colour(k),
            kind: LineKind::Data,
            dots: false,
            segments: segs,
        })
        .collect();
    // Dotted and on top: one component can lie on the magnitude.
    lines.push(Line {
        label: Some("|θ|".into()),
        colour: BLACK,
        kind: LineKind::Reference,
        dots: false,
        segments: magnitude.clone(),
    });
    if limit_on_left {
        lines.push(requirement(vec![vec![(t0, limit), (t1, limit)]]));
    }
    let left = Panel {
        title: if has_limit && !limit_on_left {
            format!(
                "Components and magnitude (requirement {} deg: off this scale)",
                number(limit)
            )
        } else {
            "Components and magnitude".into()
        },
        x_label: "time (s)".into(),
        y_label: "base rotation (deg)".into(),
        x: (t0, t1),
        y,
        y_log: false,
        x_ticks: value_ticks((t0, t1)),
        y_ticks: value_ticks(y),
        x_label_count: Some(8),
        y_label_count: Some(8),
        lines,
        markers: Vec::new(),
    };

    // Right: |θ| on a log axis from two decades below the smaller of the largest value and
    // the requirement to above the larger; smaller values are left out.
    let (small, large) = match (peak > 0.0, has_limit) {
        (true, true) => (peak.min(limit), peak.max(limit)),
        (true, false) => (peak, peak),
        (false, true) => (limit, limit),
        (false, false) => (1e-4, 1e-2),
    };
    let lo = 10f64.powf((small / 100.0).log10().floor()) * (1.0 - 1e-9);
    let hi = 10f64.powf((large * 1.5).log10().ceil()) * (1.0 + 1e-9);
    if !(lo > 0.0 && hi.is_finite() && hi > lo) {
        return Err("base_angle_deg: values out of range for a log axis".into());
    }
    let above = |segs: &[Vec<(f64, f64)>]| {
        segments(
            segs.iter()
                .flat_map(|s| s.iter().copied().chain([(f64::NAN, f64::NAN)]))
                .map(|(t, v)| (t, if v >= lo { v } else { f64::NAN })),
        )
    };
    let mut lines = vec![Line {
        label: Some("|θ|".into()),
        colour: BLACK,
        kind: LineKind::Data,
        dots: false,
        segments: above(&magnitude),
    }];
    if has_limit {
        lines.push(requirement(vec![vec![(t0, limit), (t1, limit)]]));
    }
    let markers = (peak > 0.0)
        .then(|| Marker {
            label: if has_limit {
                format!(
                    "largest {} deg ({} of the requirement)",
                    number(peak),
                    percent(peak / limit)
                )
            } else {
                format!("largest {} deg", number(peak))
            },
            colour: RED,
            shape: Shape::Circle,
            at: (t_peak, peak),
        })
        .into_iter()
        .collect();
    let right = Panel {
        title: "Magnitude against the requirement (log scale)".into(),
        x_label: "time (s)".into(),
        y_label: "|θ| (deg)".into(),
        x: (t0, t1),
        y: (lo, hi),
        y_log: true,
        x_ticks: value_ticks((t0, t1)),
        y_ticks: Ticks::Sci {
            digits: 0,
            zero: 0.0,
        },
        x_label_count: Some(8),
        y_label_count: None,
        lines,
        markers,
    };
    Ok(Figure {
        stamp: d.stamp.clone(),
        equal_aspect: false,
        name: "base_attitude".into(),
        size: (1500, 600),
        title: Some(
            "Base attitude, truth model: rotation vector θ = angle · axis, components along the inertial x, y, z axes (deg)"
                .into(),
        ),
        columns: 2,
        panels: vec![left, right],
    })
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
            x_label: "rollouts".into(),
            y_label: "best f (m, rad)".into(),
            x: (1.0, n as f64),
            y: (lo, hi),
            y_log: true,
            x_ticks: Ticks::Integer,
            y_ticks: Ticks::Sci {
                digits: 0,
                zero: 0.0,
            },
            x_label_count: Some(n.min(10)),
            y_label_count: None,
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
                        label: Some(format!("σ_e = {}", number(sigma))),
                        colour: RED,
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
                        label: format!("success (rollout {k})"),
                        colour: GREEN,
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
                label: "start".into(),
                colour: GREEN,
                shape: Shape::Circle,
                at: start,
            },
            Marker {
                label: "end".into(),
                colour: RED,
                shape: Shape::Square,
                at: end,
            },
        ];
        if target.0.is_finite() && target.1.is_finite() {
            markers.push(Marker {
                label: "target".into(),
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
            x_label: AXES[a].into(),
            y_label: AXES[b].into(),
            x,
            y,
            y_log: false,
            x_ticks: value_ticks(x),
            y_ticks: value_ticks(y),
            x_label_count: Some(6),
            y_label_count: None,
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
        name: "ee_path".into(),
        size: (1500, 540),
        title: Some("End-effector path (planner model) and target, equal axis scales".into()),
        columns: 3,
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
        name: name.into(),
        size,
        title: None,
        columns: 1,
        panels: vec![panel],
        stamp: d.stamp.clone(),
        equal_aspect: false,
    }
}

/// The empirical CDF of one Monte Carlo figure, with its limit and its nominal value as
/// vertical lines, titled and labelled for a reader with the figure's unit.
pub(super) fn cdf_figure(c: &Cdf<'_>, stamp: &str) -> Result<Figure, String> {
    if c.name.is_empty()
        || !c
            .name
            .chars()
            .all(|ch| ch.is_ascii_alphanumeric() || ch == '_')
    {
        return Err(format!(
            "{:?}: not a figure name (letters, digits, _)",
            c.name
        ));
    }
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
    let limit = c.limit.filter(|l| l.is_finite());
    let nominal = c.nominal.filter(|l| l.is_finite());
    let (lo, hi) = finite_range(v.iter().copied().chain(limit).chain(nominal))
        .ok_or_else(|| format!("{}: no finite values", c.name))?;
    let x = padded(c.name, (lo, hi), 0.05)?;
    let mut lines = vec![Line {
        label: Some(format!("{} samples", v.len())),
        colour: colour(0),
        kind: LineKind::Data,
        dots: false,
        segments: vec![points],
    }];
    if let Some(l) = limit {
        lines.push(Line {
            label: Some(format!(
                "requirement ≤ {} {}: {} of samples meet it",
                number(l),
                c.unit,
                percent(v.iter().filter(|&&x| x <= l).count() as f64 / n)
            )),
            colour: RED,
            kind: LineKind::Limit,
            dots: false,
            segments: vec![vec![(l, 0.0), (l, 1.0)]],
        });
    }
    if let Some(m) = nominal {
        lines.push(Line {
            label: Some(format!("nominal (undispersed) {} {}", number(m), c.unit)),
            colour: GREEN,
            kind: LineKind::Reference,
            dots: false,
            segments: vec![vec![(m, 0.0), (m, 1.0)]],
        });
    }
    let mut lower = c.title.to_string();
    if let Some(first) = lower.get(..1) {
        // "Base disturbance" on the axis reads "base disturbance"; an initialism stays.
        if lower.get(1..2).is_some_and(|s| s == s.to_lowercase()) {
            lower = first.to_lowercase() + &lower[1..];
        }
    }
    Ok(Figure {
        name: format!("cdf_{}", c.name),
        size: (900, 600),
        title: None,
        columns: 1,
        panels: vec![Panel {
            title: format!("{} ({}): cumulative distribution", c.title, c.unit),
            x_label: format!("{lower} ({})", c.unit),
            y_label: "fraction of samples ≤ x".into(),
            x,
            y: (0.0, 1.0),
            y_log: false,
            x_ticks: value_ticks(x),
            y_ticks: Ticks::Plain,
            x_label_count: Some(8),
            y_label_count: None,
            lines,
            markers: Vec::new(),
        }],
        stamp: stamp.to_string(),
        equal_aspect: false,
    })
}

/// A closed-loop flight (issue #31's `fly` plots): the true base rotation and the loop's
/// estimate of it against the requirement, each joint's command less the plan's rate
/// (what the loop adds), and the end effector's distance to the target (log scale).
pub(super) fn loop_figure(d: &LoopPlotData) -> Result<Figure, String> {
    let nc = d.t_cycle.len();
    if nc == 0 || d.truth_deg.len() != nc || d.estimate_deg.len() != nc || d.correction.len() != nc
    {
        return Err(format!(
            "closed loop: {nc} cycles, {} true angles, {} estimates, {} commands",
            d.truth_deg.len(),
            d.estimate_deg.len(),
            d.correction.len()
        ));
    }
    let nj = d.joint_names.len();
    check_rows(&[("correction", &d.correction)], nj)?;
    if d.t.len() != d.ee_distance_m.len() {
        return Err(format!(
            "closed loop: {} sample times, {} end-effector distances",
            d.t.len(),
            d.ee_distance_m.len()
        ));
    }
    let (t0, t1) = time_range(&d.t)?;
    let limit = d.base_limit_deg;
    let has_limit = limit.is_finite() && limit > 0.0;

    // Top: the base rotation, truth and estimate.
    let truth = segments(d.t_cycle.iter().copied().zip(d.truth_deg.iter().copied()));
    let estimate = segments(
        d.t_cycle
            .iter()
            .copied()
            .zip(d.estimate_deg.iter().copied()),
    );
    let y = finite_range(
        d.truth_deg
            .iter()
            .chain(&d.estimate_deg)
            .copied()
            .chain(has_limit.then_some(limit)),
    )
    .ok_or("closed loop: no finite base rotation")?;
    let y = padded("base rotation", (0.0, y.1), 0.06)?;
    let mut lines = vec![
        Line {
            label: Some("|θ| true".into()),
            colour: BLACK,
            kind: LineKind::Data,
            dots: false,
            segments: truth,
        },
        Line {
            label: Some("the loop's estimate of |θ|".into()),
            colour: colour(0),
            kind: LineKind::Data,
            dots: false,
            segments: estimate,
        },
    ];
    if has_limit {
        lines.push(Line {
            label: Some(format!("requirement ≤ {} deg", number(limit))),
            colour: RED,
            kind: LineKind::Limit,
            dots: false,
            segments: vec![vec![(t0, limit), (t1, limit)]],
        });
    }
    let base = Panel {
        title: "Base rotation since t = 0 (deg): the truth and the loop's estimate".into(),
        x_label: "time (s)".into(),
        y_label: "|θ| (deg)".into(),
        x: (t0, t1),
        y,
        y_log: false,
        x_ticks: value_ticks((t0, t1)),
        y_ticks: value_ticks(y),
        x_label_count: Some(8),
        y_label_count: Some(6),
        lines,
        markers: Vec::new(),
    };

    // Middle: each joint's command less the plan's rate over the same cycle.
    let per_joint: Vec<Vec<Vec<(f64, f64)>>> = (0..nj)
        .map(|j| {
            segments(
                d.t_cycle
                    .iter()
                    .zip(&d.correction)
                    .map(|(&t, row)| (t, row[j].to_degrees())),
            )
        })
        .collect();
    let y = finite_range(per_joint.iter().flatten().flatten().map(|p| p.1))
        .ok_or("closed loop: no finite command")?;
    let y = padded("command less plan", y, 0.06)?;
    let corrections = Panel {
        title: "Commands less the plan's rates (deg/s): what the loop adds".into(),
        x_label: "time (s)".into(),
        y_label: "rate (deg/s)".into(),
        x: (t0, t1),
        y,
        y_log: false,
        x_ticks: value_ticks((t0, t1)),
        y_ticks: value_ticks(y),
        x_label_count: Some(8),
        y_label_count: Some(6),
        lines: per_joint
            .into_iter()
            .enumerate()
            .map(|(j, segs)| Line {
                label: Some(d.joint_names[j].clone()),
                colour: colour(j),
                kind: LineKind::Data,
                dots: false,
                segments: segs,
            })
            .collect(),
        markers: Vec::new(),
    };

    // Bottom: the end effector's distance to the target, log scale.
    let (small, large) = finite_range(d.ee_distance_m.iter().copied().filter(|v| *v > 0.0))
        .ok_or("closed loop: no positive end-effector distance")?;
    let lo = 10f64.powf(small.log10().floor()) * (1.0 - 1e-9);
    let hi = 10f64.powf((large * 1.5).log10().ceil()) * (1.0 + 1e-9);
    let last = d.ee_distance_m.last().copied().unwrap_or(f64::NAN);
    let ee = Panel {
        title: format!(
            "End effector's distance to the target (m, truth model; {} m at the end)",
            number(last)
        ),
        x_label: "time (s)".into(),
        y_label: "distance (m)".into(),
        x: (t0, t1),
        y: (lo, hi),
        y_log: true,
        x_ticks: value_ticks((t0, t1)),
        y_ticks: Ticks::Sci {
            digits: 0,
            zero: 0.0,
        },
        x_label_count: Some(8),
        y_label_count: None,
        lines: vec![Line {
            label: None,
            colour: colour(1),
            kind: LineKind::Data,
            dots: false,
            segments: segments(
                d.t.iter()
                    .zip(&d.ee_distance_m)
                    .map(|(&t, &v)| (t, if v >= lo { v } else { f64::NAN })),
            ),
        }],
        markers: Vec::new(),
    };
    Ok(Figure {
        stamp: d.stamp.clone(),
        equal_aspect: false,
        name: "closed_loop".into(),
        size: (1200, 1100),
        title: Some("Closed-loop flight: base attitude, commands, end effector".into()),
        columns: 1,
        panels: vec![base, corrections, ee],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rotation vector of a rotation by θ about a unit axis is θ·axis, for q and −q
    /// alike, and a non-unit quaternion gives the same vector; the identity gives zero.
    #[test]
    fn rotation_vector_is_angle_times_axis() {
        let axis = [0.48, -0.6, 0.64];
        for deg in [1e-6, 7.27e-4, 0.01, 30.0, 179.0] {
            let h = 0.5 * f64::to_radians(deg);
            let q = [
                h.cos(),
                axis[0] * h.sin(),
                axis[1] * h.sin(),
                axis[2] * h.sin(),
            ];
            for q in [q, q.map(|c| -c), q.map(|c| 3.0 * c)] {
                let v = rotation_vector_deg(q);
                for (vk, ak) in v.iter().zip(axis) {
                    assert!((vk - deg * ak).abs() <= 1e-12 * deg, "{deg}: {v:?}");
                }
            }
        }
        assert_eq!(rotation_vector_deg([1.0, 0.0, 0.0, 0.0]), [0.0; 3]);
        assert!(rotation_vector_deg([0.0; 4]).iter().all(|v| v.is_nan()));
    }
}
