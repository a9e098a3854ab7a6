//! What `disperse` (and `merge` of its shards) writes: `runs.csv`, `summary.json`,
//! `summary.md` and `sensitivity.csv`.
//!
//! Owns the column layout of `runs.csv` ([`header`], [`record`]: the figures, then every
//! drawn parameter, each number in its shortest round-trip form), reading the figures
//! back ([`read_figures`], bit for bit), the statistics ([`Statistics`]: nearest-rank
//! p50/p95/p99, max, and the mean summed in sample order) and the report
//! ([`Report`], [`markdown`]). Everything here is a function of the rows and the run's
//! settings, so shards merged give what one machine writes.

use crate::closed_loop::{LoopFigures, LoopSection};
use crate::dispersion::{Draw, Figures, Sensitivity, Settings, body_label};
use crate::error::{CliError, Context};
use crate::goal::number;
use crate::output::OutDir;
use crate::plots;
use crate::sensors::Settings as SensorSettings;
use crate::stats::{max, percentile};
use crate::urdf::Chain;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;

/// One sample: its index, what it gave and what was drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Sample index (0-based).
    pub sample: u64,
    /// Flown figures.
    pub figures: Figures,
    /// Drawn parameters.
    pub draw: Draw,
    /// The closed loop's figures (a `--closed-loop` run only).
    pub loop_figures: Option<LoopFigures>,
}

/// How to read one figure from [`Figures`].
pub type Getter = fn(&Figures) -> f64;

/// One figure of a dispersion: its column, what it is for a reader, and how to read it.
pub struct FigureColumn {
    /// The column of `runs.csv` and the field of [`Statistics`] (unit included).
    pub name: &'static str,
    /// What it is, for a reader (the tables of `summary.md`, the CDFs' titles).
    pub title: &'static str,
    /// Its unit.
    pub unit: &'static str,
    /// Its value in [`Figures`].
    pub get: Getter,
}

/// The figures' columns, in order.
pub const FIGURES: [FigureColumn; 5] = [
    FigureColumn {
        name: "base_disturbance_deg",
        title: "Base disturbance",
        unit: "deg",
        get: |f| f.base_disturbance_deg,
    },
    FigureColumn {
        name: "final_attitude_error_deg",
        title: "Final base attitude error",
        unit: "deg",
        get: |f| f.final_attitude_error_deg,
    },
    FigureColumn {
        name: "position_error_m",
        title: "End-effector position error",
        unit: "m",
        get: |f| f.position_error_m,
    },
    FigureColumn {
        name: "orientation_error_deg",
        title: "End-effector orientation error",
        unit: "deg",
        get: |f| f.orientation_error_deg,
    },
    FigureColumn {
        name: "f",
        title: "Pose error f",
        unit: "m, rad",
        get: |f| f.f,
    },
];

/// How to read one closed-loop figure.
pub type LoopGetter = fn(&LoopFigures) -> f64;

/// The closed loop's columns of `runs.csv` (after the figures, `--closed-loop` only): name
/// (unit included) and how to read it.
pub const LOOP_COLUMNS: [(&str, LoopGetter); 7] = [
    ("extra_time_s", |f| f.extra_time_s),
    ("extra_travel_deg", |f| f.extra_travel_deg),
    ("largest_command_deg_s", |f| f.largest_command_deg_s),
    ("largest_rate_fraction", |f| f.largest_rate_fraction),
    ("limited_cycles", |f| f64::from(f.limited_cycles)),
    ("rate_violations", |f| f64::from(f.rate_violations)),
    ("safe_stop", |f| if f.safe_stop { 1.0 } else { 0.0 }),
];

/// The header of `runs.csv` for `chain`, with the closed loop's columns if `closed`.
pub fn header(chain: &Chain, closed: bool) -> Vec<String> {
    let mut h = vec!["sample".to_string()];
    h.extend(FIGURES.iter().map(|c| c.name.to_string()));
    if closed {
        h.extend(LOOP_COLUMNS.iter().map(|(n, _)| n.to_string()));
    }
    h.extend(
        [
            "base_rate_x_deg_s",
            "base_rate_y_deg_s",
            "base_rate_z_deg_s",
        ]
        .map(String::from),
    );
    for b in 0..=chain.links.len() {
        let n = body_label(chain, b);
        h.push(format!("{n}.mass_kg"));
        for a in ["x", "y", "z"] {
            h.push(format!("{n}.com_{a}_m"));
        }
        for e in ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"] {
            h.push(format!("{n}.{e}_kg_m2"));
        }
    }
    for j in &chain.joint_names {
        for a in ["x", "y", "z"] {
            h.push(format!("{j}.axis_{a}"));
        }
    }
    h
}

fn num(v: f64) -> String {
    ryu::Buffer::new().format(v).to_string()
}

/// One row of `runs.csv`, in [`header`]'s order.
pub fn record(r: &Row) -> Vec<String> {
    let mut out = vec![r.sample.to_string()];
    out.extend(FIGURES.iter().map(|c| num((c.get)(&r.figures))));
    if let Some(l) = &r.loop_figures {
        out.extend(LOOP_COLUMNS.iter().map(|(_, get)| num(get(l))));
    }
    out.extend(r.draw.base_rate.iter().map(|w| num(w.to_degrees())));
    for ((m, c), i) in r.draw.mass.iter().zip(&r.draw.com).zip(&r.draw.inertia) {
        out.push(num(*m));
        out.extend(c.iter().map(|v| num(*v)));
        out.extend([i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz].map(num));
    }
    for a in &r.draw.axis {
        out.extend(a.iter().map(|v| num(*v)));
    }
    out
}

/// `runs.csv` as text: the header, then the rows in the order given.
pub fn runs_csv(chain: &Chain, rows: &[Row]) -> Result<Vec<u8>, CliError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let closed = rows.first().is_some_and(|r| r.loop_figures.is_some());
    w.write_record(header(chain, closed))
        .or_internal(|| "runs.csv")?;
    for r in rows {
        w.write_record(record(r)).or_internal(|| "runs.csv")?;
    }
    w.into_inner().or_internal(|| "runs.csv")
}

/// The sample index and figures of every row of a `runs.csv` text (`origin` names it).
pub fn read_figures(origin: &str, text: &str) -> Result<Vec<(u64, Figures)>, CliError> {
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let head = r.headers().or_input(|| origin)?.clone();
    let col = |name: &str| {
        head.iter()
            .position(|h| h == name)
            .ok_or_else(|| CliError::input(format!("{origin}: no column {name}")))
    };
    let sample = col("sample")?;
    let cols: Vec<usize> = FIGURES
        .iter()
        .map(|c| col(c.name))
        .collect::<Result<_, _>>()?;
    let mut out = Vec::new();
    for (k, rec) in r.records().enumerate() {
        let rec = rec.or_input(|| format!("{origin}: row {}", k + 1))?;
        let get = |c: usize| -> Result<f64, CliError> {
            rec.get(c)
                .unwrap_or("")
                .parse::<f64>()
                .or_input(|| format!("{origin}: row {}, column {}", k + 1, &head[c]))
        };
        let s: u64 = rec
            .get(sample)
            .unwrap_or("")
            .parse()
            .or_input(|| format!("{origin}: row {}: sample", k + 1))?;
        out.push((
            s,
            Figures {
                base_disturbance_deg: get(cols[0])?,
                final_attitude_error_deg: get(cols[1])?,
                position_error_m: get(cols[2])?,
                orientation_error_deg: get(cols[3])?,
                f: get(cols[4])?,
            },
        ));
    }
    Ok(out)
}

/// The closed loop's figures of every row of a `runs.csv` text, `None` if it has no
/// closed-loop columns (an open-loop run).
pub fn read_loop_figures(origin: &str, text: &str) -> Result<Option<Vec<LoopFigures>>, CliError> {
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let head = r.headers().or_input(|| origin)?.clone();
    let cols: Option<Vec<usize>> = LOOP_COLUMNS
        .iter()
        .map(|(n, _)| head.iter().position(|h| h == *n))
        .collect();
    let Some(cols) = cols else {
        return Ok(None);
    };
    let mut out = Vec::new();
    for (k, rec) in r.records().enumerate() {
        let rec = rec.or_input(|| format!("{origin}: row {}", k + 1))?;
        let get = |i: usize| -> Result<f64, CliError> {
            rec.get(cols[i])
                .unwrap_or("")
                .parse::<f64>()
                .or_input(|| format!("{origin}: row {}, column {}", k + 1, LOOP_COLUMNS[i].0))
        };
        out.push(LoopFigures {
            extra_time_s: get(0)?,
            extra_travel_deg: get(1)?,
            largest_command_deg_s: get(2)?,
            largest_rate_fraction: get(3)?,
            limited_cycles: get(4)? as u32,
            rate_violations: get(5)? as u32,
            safe_stop: get(6)? != 0.0,
        });
    }
    Ok(Some(out))
}

/// The statistics of one figure.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Stat {
    /// Median (nearest rank).
    pub p50: f64,
    /// 95th percentile (nearest rank).
    pub p95: f64,
    /// 99th percentile (nearest rank).
    pub p99: f64,
    /// Largest value.
    pub max: f64,
    /// Mean (summed in sample order).
    pub mean: f64,
}

impl Stat {
    fn of(v: &[f64]) -> Self {
        let mut sum = 0.0;
        for x in v {
            sum += x;
        }
        Self {
            p50: percentile(v, 50.0),
            p95: percentile(v, 95.0),
            p99: percentile(v, 99.0),
            max: max(v),
            mean: sum / v.len().max(1) as f64,
        }
    }
}

/// The statistics of every figure over the samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Statistics {
    /// Largest base rotation (deg).
    pub base_disturbance_deg: Stat,
    /// Base rotation at the end (deg).
    pub final_attitude_error_deg: Stat,
    /// End-effector position error (m).
    pub position_error_m: Stat,
    /// End-effector orientation error (deg).
    pub orientation_error_deg: Stat,
    /// f.
    pub f: Stat,
}

impl Statistics {
    /// Over `figures`, in sample order.
    pub fn of(figures: &[Figures]) -> Self {
        let col = |k: usize| -> Stat {
            let v: Vec<f64> = figures.iter().map(|f| (FIGURES[k].get)(f)).collect();
            Stat::of(&v)
        };
        Self {
            base_disturbance_deg: col(0),
            final_attitude_error_deg: col(1),
            position_error_m: col(2),
            orientation_error_deg: col(3),
            f: col(4),
        }
    }

    fn get(&self, k: usize) -> &Stat {
        match k {
            0 => &self.base_disturbance_deg,
            1 => &self.final_attitude_error_deg,
            2 => &self.position_error_m,
            3 => &self.orientation_error_deg,
            _ => &self.f,
        }
    }
}

/// The statistics of the closed loop's figures over the samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct LoopStatistics {
    /// End of flight − t_f (s).
    pub extra_time_s: Stat,
    /// Extra joint travel (deg).
    pub extra_travel_deg: Stat,
    /// Largest commanded joint rate (deg/s).
    pub largest_command_deg_s: Stat,
    /// Largest commanded rate over the joint's limit.
    pub largest_rate_fraction: Stat,
    /// Commands beyond a rate limit, over every sample.
    pub rate_violations: u64,
    /// Samples that ended in the safe state.
    pub safe_stops: u64,
    /// Cycles whose command a limit changed, over every sample.
    pub limited_cycles: u64,
}

impl LoopStatistics {
    /// Over `figures`, in sample order.
    pub fn of(figures: &[LoopFigures]) -> Self {
        let col = |k: usize| -> Stat {
            let v: Vec<f64> = figures.iter().map(|f| (LOOP_COLUMNS[k].1)(f)).collect();
            Stat::of(&v)
        };
        Self {
            extra_time_s: col(0),
            extra_travel_deg: col(1),
            largest_command_deg_s: col(2),
            largest_rate_fraction: col(3),
            rate_violations: figures.iter().map(|f| u64::from(f.rate_violations)).sum(),
            safe_stops: figures.iter().filter(|f| f.safe_stop).count() as u64,
            limited_cycles: figures.iter().map(|f| u64::from(f.limited_cycles)).sum(),
        }
    }
}

/// What a `--closed-loop` run adds to `summary.json`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ClosedLoopSummary {
    /// The sensors (the task's `[sensors]`).
    pub sensors: SensorSettings,
    /// The executor's settings (the task's `[closed_loop]`).
    pub settings: LoopSection,
    /// The nominal robot flown closed-loop with noise-free sensors (20-bit encoders still
    /// quantise): what the loop does where nothing is wrong.
    pub nominal_noise_free: Figures,
    /// The closed loop's figures of that flight.
    pub nominal_loop: LoopFigures,
    /// Statistics of the closed loop's figures over the samples.
    pub statistics: LoopStatistics,
}

fn open_loop() -> String {
    "open_loop".into()
}

/// What the directory's own `summary.json` says (plan and rollout: the nominal truth
/// model's figures; a re-timed bundle: its base disturbance only).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct DirSummary {
    /// `base_disturbance_deg`.
    pub base_disturbance_deg: Option<f64>,
    /// `truth_f`.
    pub truth_f: Option<f64>,
}

/// `summary.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Report {
    /// The plan, rollout or re-timed directory flown.
    pub dir: String,
    /// The robot's name.
    pub robot: String,
    /// Seed of the draws.
    pub seed: u64,
    /// Samples of the run.
    pub samples: usize,
    /// Samples these statistics cover (all of them, unless this is one shard).
    pub rows: usize,
    /// The dispersion.
    pub settings: Settings,
    /// The nominal truth model's figures (every σ = 0).
    pub nominal: Figures,
    /// The same figures from the directory's `summary.json`.
    pub dir_summary: DirSummary,
    /// Statistics over the samples.
    pub statistics: Statistics,
    /// One-at-a-time sensitivity (+1σ of each dispersed parameter) of the open-loop
    /// flight (empty for a closed-loop run).
    pub sensitivity: Vec<Sensitivity>,
    /// `open_loop`: the path flown as written; `closed_loop`: flown by the core's executor
    /// on the truth model's sensors (`closed_loop` then holds its settings and figures).
    #[serde(default = "open_loop")]
    pub mode: String,
    /// The closed loop's settings and figures (`mode` = `closed_loop`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub closed_loop: Option<ClosedLoopSummary>,
}

/// `sensitivity.csv` as text.
pub fn sensitivity_csv(rows: &[Sensitivity]) -> Result<Vec<u8>, CliError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in rows {
        w.serialize(r).or_internal(|| "sensitivity.csv")?;
    }
    if rows.is_empty() {
        w.write_record([
            "parameter",
            "step",
            "d_base_disturbance_deg",
            "d_position_error_m",
            "d_orientation_error_deg",
        ])
        .or_internal(|| "sensitivity.csv")?;
    }
    w.into_inner().or_internal(|| "sensitivity.csv")
}

/// `summary.md`.
pub fn markdown(r: &Report) -> String {
    let mut out = format!(
        "# Dispersion summary\n\n`{}` ({}), {} samples, seed {}{}.\n\nDispersion:",
        r.dir,
        r.robot,
        r.samples,
        r.seed,
        if r.rows == r.samples {
            String::new()
        } else {
            format!(" (this shard: {} of them)", r.rows)
        }
    );
    let entries = r.settings.entries();
    for (i, (k, v)) in entries.iter().enumerate() {
        let end = if i + 1 == entries.len() { "." } else { "," };
        let _ = write!(out, " {k} = {v}{end}");
    }
    let _ = writeln!(
        out,
        "\n\n| figure | nominal | p50 | p95 | p99 | max | mean |\n|---|---|---|---|---|---|---|"
    );
    for (k, c) in FIGURES.iter().enumerate() {
        let s = r.statistics.get(k);
        let _ = writeln!(
            out,
            "| {} ({}) | {} | {} | {} | {} | {} | {} |",
            c.title,
            c.unit,
            number((c.get)(&r.nominal)),
            number(s.p50),
            number(s.p95),
            number(s.p99),
            number(s.max),
            number(s.mean)
        );
    }
    if let Some(c) = &r.closed_loop {
        let _ = writeln!(
            out,
            "\nFlown closed-loop: the core's executor at {} Hz on the truth model's sensors (star tracker {}″, gyro {} °/√h and {} °/h, {}-bit encoders, dropout probability {}). The nominal column is the nominal robot with noise-free sensors.\n\n| closed loop | nominal | p50 | p95 | p99 | max | mean |\n|---|---|---|---|---|---|---|",
            number(1.0 / c.sensors.control_period_s),
            number(c.sensors.star_tracker_arcsec),
            number(c.sensors.gyro_arw_deg_rt_h),
            number(c.sensors.gyro_bias_deg_h),
            c.sensors.encoder_bits,
            number(c.sensors.dropout_probability),
        );
        let stats = [
            &c.statistics.extra_time_s,
            &c.statistics.extra_travel_deg,
            &c.statistics.largest_command_deg_s,
            &c.statistics.largest_rate_fraction,
        ];
        for ((name, get), s) in LOOP_COLUMNS.iter().zip(stats) {
            let _ = writeln!(
                out,
                "| {name} | {} | {} | {} | {} | {} | {} |",
                number(get(&c.nominal_loop)),
                number(s.p50),
                number(s.p95),
                number(s.p99),
                number(s.max),
                number(s.mean)
            );
        }
        let _ = writeln!(
            out,
            "\nCommands beyond a rate limit: {}. Samples ended in the safe state: {}. Cycles whose command a limit changed: {}.\n\nThe nominal robot, noise-free sensors: base disturbance {} deg, end effector {} m and {} deg off.",
            c.statistics.rate_violations,
            c.statistics.safe_stops,
            c.statistics.limited_cycles,
            number(c.nominal_noise_free.base_disturbance_deg),
            number(c.nominal_noise_free.position_error_m),
            number(c.nominal_noise_free.orientation_error_deg),
        );
    }
    let limit = BASE_LIMIT_DEG;
    let _ = writeln!(
        out,
        "\nThe paper's limit on the base disturbance is {} deg: the nominal flight {} it; p99 {} it.",
        number(limit),
        if r.nominal.base_disturbance_deg <= limit {
            "meets"
        } else {
            "exceeds"
        },
        if r.statistics.base_disturbance_deg.p99 <= limit {
            "meets"
        } else {
            "exceeds"
        },
    );
    if !r.sensitivity.is_empty() {
        let _ = writeln!(
            out,
            "\n## Sensitivity (one at a time, +1σ from nominal)\n\nThe five parameters that move each figure most; all of them in `sensitivity.csv`.\n"
        );
        type Get = fn(&Sensitivity) -> f64;
        let cols: [(&str, Get); 3] = [
            ("base disturbance (deg)", |s| s.d_base_disturbance_deg),
            ("position error (m)", |s| s.d_position_error_m),
            ("orientation error (deg)", |s| s.d_orientation_error_deg),
        ];
        for (name, get) in cols {
            let mut v: Vec<&Sensitivity> = r.sensitivity.iter().collect();
            // Largest |change| first; ties keep table order (stable sort).
            v.sort_by(|a, b| get(b).abs().total_cmp(&get(a).abs()));
            let _ = writeln!(out, "| change of {name} | step | change |\n|---|---|---|");
            for s in v.iter().take(5) {
                let _ = writeln!(out, "| {} | {} | {} |", s.parameter, s.step, signed(get(s)));
            }
            out.push('\n');
        }
    }
    out
}

/// `v` as [`number`] writes it, with its sign: `+1.44e-3`, `-0.05`, `0`.
fn signed(v: f64) -> String {
    if v > 0.0 {
        format!("+{}", number(v))
    } else if v == 0.0 {
        "0".into()
    } else {
        number(v)
    }
}

/// The paper's limit on the base disturbance (deg): drawn on its CDF and judged in
/// `summary.md`.
const BASE_LIMIT_DEG: f64 = 0.01;

/// Writes `summary.json`, `summary.md`, `sensitivity.csv` and the CDFs (`merge` too).
pub fn write_report(
    out: &OutDir,
    rep: &Report,
    with_plots: bool,
    figures: &[Figures],
) -> Result<(), CliError> {
    out.write_json("summary.json", rep)?;
    out.write("summary.md", markdown(rep).as_bytes())?;
    out.write("sensitivity.csv", &sensitivity_csv(&rep.sensitivity)?)?;
    if with_plots {
        let series: Vec<plots::Cdf> = FIGURES
            .iter()
            .map(|c| plots::Cdf {
                name: c.name,
                title: c.title,
                unit: c.unit,
                values: figures.iter().map(c.get).collect(),
                limit: (c.name == "base_disturbance_deg").then_some(BASE_LIMIT_DEG),
                nominal: Some((c.get)(&rep.nominal)),
            })
            .collect();
        plots::write_cdfs(
            &out.path(""),
            &series,
            &format!("{} · {} samples · seed {}", rep.dir, rep.samples, rep.seed),
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn figures(scale: f64) -> Figures {
        Figures {
            base_disturbance_deg: 1.44 * scale,
            final_attitude_error_deg: 97.57 * scale,
            position_error_m: 3.254e-5 * scale,
            orientation_error_deg: 0.05 * scale,
            f: 2.0 * scale,
        }
    }

    /// summary.md names each figure for a reader with its unit and writes numbers plainly
    /// where that is short (`1.44`, `97.57`), scientifically where not (`3.254e-5`), and
    /// sensitivities with their sign.
    /// Verifies RL-SIM-CAMP-004.
    #[test]
    fn summary_md_reads_plainly() {
        let samples: Vec<Figures> = [1.0, 1.0, 1.0].map(figures).to_vec();
        let report = Report {
            dir: "out/plan".into(),
            robot: "chaser7".into(),
            seed: 7,
            samples: 3,
            rows: 3,
            settings: Settings::default(),
            nominal: figures(0.25),
            dir_summary: DirSummary {
                base_disturbance_deg: None,
                truth_f: None,
            },
            statistics: Statistics::of(&samples),
            sensitivity: vec![Sensitivity {
                parameter: "link6 mass".into(),
                step: "+5% (0.5 kg)".into(),
                d_base_disturbance_deg: 0.03439,
                d_position_error_m: -7.582e-4,
                d_orientation_error_deg: 0.0,
            }],
            mode: "open_loop".into(),
            closed_loop: None,
        };
        let md = markdown(&report);
        for want in [
            "| Base disturbance (deg) | 0.36 | 1.44 | 1.44 | 1.44 | 1.44 | 1.44 |",
            "| Final base attitude error (deg) | 24.39 | 97.57 |",
            "| End-effector position error (m) | 8.135e-6 | 3.254e-5 |",
            "| Pose error f (m, rad) | 0.5 | 2 | 2 |",
            "The paper's limit on the base disturbance is 0.01 deg",
            "| link6 mass | +5% (0.5 kg) | +0.03439 |",
            "| link6 mass | +5% (0.5 kg) | -7.582e-4 |",
            "| link6 mass | +5% (0.5 kg) | 0 |",
        ] {
            assert!(md.contains(want), "lacks {want:?}:\n{md}");
        }
        assert!(!md.contains("e0 ") && !md.contains("e1 "), "{md}");
    }
}
