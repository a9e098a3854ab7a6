//! Plots of a trajectory and a plan (plotters; PNG and SVG): the paper's Figs. 3–6 and more.
//!
//! Owns the figures' inputs as plain data, in SI units as computed: [`PlotData`] (a
//! rollout or a plan), [`RetimePlotData`] (a re-timed trajectory), [`LoopPlotData`] (a
//! closed-loop flight) and [`Cdf`] (one dispersion figure); and their writers
//! [`write_plots`], [`write_retime_data`], [`write_loop_plots`] and [`write_cdfs`]. It reads no host-sim module but `error` and `goal` (for
//! [`crate::goal::number`], the one way numbers are written for a reader): the callers
//! (`artifacts`, `retiming`, `dispersion_report`) fill the data, the stamp included.
//!
//! What is drawn is what a GNC engineer reads off: angles in degrees and rates in deg/s on
//! the axes, one panel per joint with that joint's limits as dashed lines, the base
//! attitude as its rotation vector's three components and its magnitude, limits and
//! requirements labelled with their values and units.
//!
//! Text needs no system fonts: plotters draws it with `ab_glyph` from a font embedded in the
//! binary (a subset of DejaVu Sans, `host-sim/assets/`), registered on first use. The SVGs
//! carry their text as `<text>` elements (family `sans-serif`); the embedded font only sizes it.
//!
//! Every figure is checked and laid out before any file is written, so bad input writes
//! nothing. Non-finite samples are left out (the line breaks there); empty or mismatched
//! vectors are an error.
//!
//! Two steps: [`figures`] turns the data into backend-independent figure specifications
//! (panels, lines, limits, markers, ranges, ticks); [`draw`] renders a specification with
//! plotters, once for PNG and once for SVG.

mod draw;
mod figures;

use crate::error::CliError;
use draw::draw_figure;
use figures::figures;
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
    /// Base attitude per sample, truth model (unit quaternion `[w, x, y, z]`, base →
    /// inertial): drawn as its rotation vector's components.
    pub base_wxyz: Vec<[f64; 4]>,
    /// The best f after each rollout (only for plans).
    pub best_f_history: Option<Vec<f64>>,
    /// σ_e, drawn on the convergence plot.
    pub tolerance: f64,
    /// The rollout (1-based) that first met σ_e, marked on the convergence plot.
    pub first_hit: Option<u32>,
    /// The base-disturbance requirement (deg), drawn on the base attitude plot.
    pub base_limit_deg: f64,
    /// What made the figure (task, seed, strategy, build), printed in a corner of each.
    pub stamp: String,
}

/// Writes the figures into `dir` as PNG and SVG; returns the file names written.
///
/// Figures: `joints` (deg) and `joint_rates` (deg/s), one panel per joint with its limits;
/// `ee_path`; `base_attitude` (the rotation vector's components and magnitude, deg, and the
/// magnitude against the requirement on a log axis); and `convergence` when
/// [`PlotData::best_f_history`] is present; each as `NAME.png` and `NAME.svg`. `dir` must
/// exist. Bad input (empty or mismatched vectors, nothing finite to plot) and write
/// failures are [`CliError::input`] errors; input is checked before any file is written.
pub fn write_plots(dir: &Path, data: &PlotData) -> Result<Vec<String>, CliError> {
    let err = |e: String| CliError::input(format!("writing plots: {e}"));
    ensure_font().map_err(err)?;
    let figures = figures(data).map_err(err)?;
    render(dir, &figures)
}

/// What the figures of a re-timed trajectory need (SI units, radians).
#[derive(Debug, Clone, PartialEq)]
pub struct RetimePlotData {
    /// Joint names (URDF), one per joint.
    pub joint_names: Vec<String>,
    /// Setpoint times (s).
    pub t: Vec<f64>,
    /// Joint rates per setpoint (rad/s).
    pub qd: Vec<Vec<f64>>,
    /// Joint accelerations per setpoint (rad/s²).
    pub qdd: Vec<Vec<f64>>,
    /// Rate limit per joint, as used (rad/s).
    pub qd_limit: Vec<f64>,
    /// Acceleration limit per joint, as used (rad/s²).
    pub qdd_limit: Vec<f64>,
    /// What made the figure.
    pub stamp: String,
}

/// Writes `retimed_rates` (deg/s) and `retimed_accelerations` (deg/s²) (PNG and SVG) into
/// `dir`: one panel per joint with its limits `±limit` as dashed lines.
pub fn write_retime_data(dir: &Path, data: &RetimePlotData) -> Result<Vec<String>, CliError> {
    let err = |e: String| CliError::input(format!("writing plots: {e}"));
    ensure_font().map_err(err)?;
    let figures = figures::retime_figures(data).map_err(err)?;
    render(dir, &figures)
}

/// What the figure of a closed-loop flight needs (SI units, radians; degrees where named).
#[derive(Debug, Clone, PartialEq)]
pub struct LoopPlotData {
    /// Joint names (URDF), one per joint.
    pub joint_names: Vec<String>,
    /// Time of each control cycle's measurement (s).
    pub t_cycle: Vec<f64>,
    /// The true base rotation's angle at each cycle (deg).
    pub truth_deg: Vec<f64>,
    /// The loop's estimate of it at each cycle (deg).
    pub estimate_deg: Vec<f64>,
    /// Each cycle's command less the plan's rate over the cycle it is flown in (rad/s):
    /// `correction[cycle][joint]`.
    pub correction: Vec<Vec<f64>>,
    /// Sample times of the flown path (s).
    pub t: Vec<f64>,
    /// The end effector's distance to the target at each sample (m, truth model).
    pub ee_distance_m: Vec<f64>,
    /// The base-disturbance requirement (deg).
    pub base_limit_deg: f64,
    /// What made the figure.
    pub stamp: String,
}

/// Writes `closed_loop` (PNG and SVG) into `dir`: the base rotation and the loop's
/// estimate against the requirement, the commands less the plan's rates, and the end
/// effector's distance to the target.
pub fn write_loop_plots(dir: &Path, data: &LoopPlotData) -> Result<Vec<String>, CliError> {
    let err = |e: String| CliError::input(format!("writing plots: {e}"));
    ensure_font().map_err(err)?;
    let figure = figures::loop_figure(data).map_err(err)?;
    render(dir, &[figure])
}

/// One figure's values for [`write_cdfs`].
pub struct Cdf<'a> {
    /// The figure's name with its unit, e.g. `base_disturbance_deg`: the file name is
    /// `cdf_NAME` (letters, digits and `_` only).
    pub name: &'a str,
    /// What it is, for a reader: `Base disturbance`; the title and the axis add the unit.
    pub title: &'a str,
    /// The unit of the values, e.g. `deg` or `m`.
    pub unit: &'a str,
    /// The values, any order.
    pub values: Vec<f64>,
    /// A limit drawn as a vertical line (the paper's 0.01° on the base disturbance).
    pub limit: Option<f64>,
    /// The nominal (undispersed) value, drawn as a vertical line.
    pub nominal: Option<f64>,
}

/// Writes one empirical CDF per series (`cdf_NAME.png` and `.svg`) into `dir`, stamped
/// with `stamp`; returns the file names written.
pub fn write_cdfs(dir: &Path, series: &[Cdf<'_>], stamp: &str) -> Result<Vec<String>, CliError> {
    let err = |e: String| CliError::input(format!("writing plots: {e}"));
    ensure_font().map_err(err)?;
    let figures = series
        .iter()
        .map(|c| figures::cdf_figure(c, stamp))
        .collect::<Result<Vec<_>, _>>()
        .map_err(err)?;
    render(dir, &figures)
}

fn render(dir: &Path, figures: &[figures::Figure]) -> Result<Vec<String>, CliError> {
    let err = |e: String| CliError::input(format!("writing plots: {e}"));
    let mut written = Vec::with_capacity(2 * figures.len());
    for fig in figures {
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
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans-subset.ttf");

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
