//! `host-sim disperse`: Monte Carlo over dispersed truth models of one planned path.
//!
//! A two-phase plan (docs/twophase.md) is dispersed whole: phase 2's path (`phase2/`) is
//! flown from where phase 1, attitude controlled, moved each dispersed robot's base
//! ([`crate::dispersion::JointPath::preshaped_from`]), so the end-pose figures are the
//! whole plan's against the task's target; the base disturbance is phase 2's (phase 1's
//! attitude is held), and a drawn initial base rate is the rate the attitude control
//! leaves when it lets go.
//!
//! The joint path of a plan, rollout or re-timed directory is flown open-loop, exactly as
//! its setpoints command it, through `--samples` truth models whose masses, CoMs, inertia
//! tensors, joint axes and initial base rate are drawn by `crate::dispersion` (settings:
//! the task's `[dispersion]` table, overridden by the flags). Samples run on `--jobs`
//! threads; each sample's draws depend only on `(seed, sample)`, so the output is the same
//! for any number of jobs and any sharding (`--shard I/M`, put back by `host-sim merge`).
//! Writes `runs.csv`, `summary.json`, `summary.md`, `sensitivity.csv`, `manifest.json`
//! and with `--plots` the CDFs. `--export-sample K --out FILE.urdf` writes one sample's
//! dispersed robot instead.

use crate::artifacts::{read_bundle, read_output_file};
use crate::closed_loop;
use crate::dispersion::{self, Draw, Figures, JointPath, Settings};
use crate::dispersion_report::{
    self as report, ClosedLoopSummary, DirSummary, LoopStatistics, Report, Row, Statistics,
};
use crate::drive;
use crate::error::{CliError, Context};
use crate::goal::number;
use crate::output::{FileKind, OutDir, write_file};
use crate::sensors::Settings as SensorSettings;
use crate::shards::{self, Manifest, Shard, parse_shard};
use crate::taskfile::{DispersionKey, LoadedTask};
use crate::urdf;
use crate::with_dims;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Most samples one run may have.
pub const MAX_SAMPLES: usize = 10_000_000;

/// Fly a planned path through dispersed truth models: OUT/runs.csv, summary.json,
/// summary.md, sensitivity.csv (or one sample's robot as URDF with --export-sample).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory of `plan`, `rollout` or `retime`.
    dir: PathBuf,
    /// Samples of the run (required unless --export-sample).
    #[arg(long, required_unless_present = "export_sample", value_parser = crate::args::parse_usize)]
    samples: Option<usize>,
    /// Seed of the draws.
    #[arg(long, value_parser = crate::args::parse_seed)]
    seed: u64,
    /// The `[dispersion]` keys as flags, each replacing its key when given.
    #[command(flatten)]
    dispersion: DispersionFlags,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = crate::args::parse_usize)]
    jobs: Option<usize>,
    /// Run only the I-th of M deterministic slices of the samples, I from 1 to M (as a Slurm
    /// array index); `host-sim merge` puts them back together.
    #[arg(long, value_parser = parse_shard, value_name = "I/M", conflicts_with = "export_sample")]
    shard: Option<Shard>,
    /// Also write CDF figures of the figures (PNG and SVG); with --closed-loop
    /// --export-sample, the flight's figures (joints, rates, end-effector path, base
    /// attitude).
    #[arg(long)]
    plots: bool,
    /// Fly each sample closed-loop: the core's executor (the task's `[closed_loop]`) on the
    /// truth model's sensors (`[sensors]`), the same robots as the open-loop run of the same
    /// seed. runs.csv gains the closed-loop columns, summary.json `mode` and `closed_loop`.
    /// With --export-sample K, --out is a directory: the sample's robot.urdf, its flown
    /// joint path (trajectory.csv) and task.toml, for scripts/disperse-check.py, and
    /// cycles.csv (per cycle: the base rotation and its estimate, the commands).
    #[arg(long)]
    closed_loop: bool,
    /// Write sample K's dispersed robot as URDF to --out instead; K as in runs.csv's
    /// `sample` column, 0 for the first sample.
    #[arg(long, value_name = "K", value_parser = crate::args::parse_u64)]
    export_sample: Option<u64>,
    /// Output directory (replaced atomically), or the URDF file with --export-sample.
    #[arg(long)]
    out: PathBuf,
}

impl Args {
    /// The settings: the task's `[dispersion]`, each flag given replacing its key.
    fn settings(&self, lt: &LoadedTask) -> Result<Settings, CliError> {
        let mut s = lt.file.dispersion;
        let given = self.dispersion.apply(&mut s);
        s.validate(|key| match given.iter().find(|k| k.name == key) {
            Some(k) => format!("--{}", k.long()),
            None => format!("{}: [dispersion] {key}", lt.path.display()),
        })?;
        Ok(s)
    }

    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let started = std::time::Instant::now();
        // A two-phase plan: phase 2's bundle and path, after phase 1 from the task's start.
        let (lt, data, top) = if crate::artifacts::is_two_phase(&self.dir) {
            let p2 = crate::artifacts::phase2_dir(&self.dir);
            (read_bundle(&p2)?, p2, Some(read_bundle(&self.dir)?))
        } else {
            (read_bundle(&self.dir)?, self.dir.clone(), None)
        };
        let settings = self.settings(&lt)?;
        if self.closed_loop && top.is_some() {
            return Err(CliError::input(format!(
                "--closed-loop: {} is a two-phase plan; the closed loop flies single-phase plans so far",
                self.dir.display()
            )));
        }
        if self.closed_loop && lt.file.sensors.latency_cycles != 1 {
            return Err(CliError::input(format!(
                "--closed-loop: {}: [sensors] latency_cycles = {}: the executor is built for one period of latency (spec §12)",
                lt.path.display(),
                lt.file.sensors.latency_cycles
            )));
        }
        if let Some(k) = self.export_sample {
            if self.plots && !self.closed_loop {
                return Err(CliError::input(
                    "--plots with --export-sample needs --closed-loop (an exported robot has no figures)",
                ));
            }
            if self.closed_loop {
                return with_dims!(
                    lt.chain.dof(),
                    export_flight,
                    &lt,
                    &data,
                    &settings,
                    self.seed,
                    k,
                    self.plots,
                    &self.out
                );
            }
            return with_dims!(
                lt.chain.dof(),
                export,
                &lt,
                &settings,
                self.seed,
                k,
                &self.out
            );
        }
        let samples = self.samples.unwrap_or(0);
        let spread = settings
            .entries()
            .iter()
            .any(|(key, v)| *key != "truncation_sigmas" && *v > 0.0);
        if !spread && samples > 0 {
            eprintln!(
                "note: every dispersion is 0 (no flag such as --mass-rel-sigma, no [dispersion] table in {}): the {samples} samples are all the nominal robot",
                lt.path.display()
            );
        }
        if samples == 0 || samples > MAX_SAMPLES {
            return Err(CliError::input(format!(
                "--samples {samples}: must be in 1..={MAX_SAMPLES}"
            )));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(self.jobs.unwrap_or(0))
            .build()
            .or_input(|| "--jobs")?;
        let run = Run {
            dir: &self.dir,
            data: &data,
            top: top.as_ref(),
            lt: &lt,
            settings,
            seed: self.seed,
            samples,
            shard: self.shard.unwrap_or(Shard::WHOLE),
            plots: self.plots,
            closed_loop: self.closed_loop,
            out: &self.out,
            started,
        };
        pool.install(|| with_dims!(lt.chain.dof(), disperse, &run))
    }
}

/// `--KEY` for every `[dispersion]` key ([`Settings::KEYS`]: `--mass-rel-sigma` …), in
/// table order; a value given replaces the task file's.
#[derive(Debug, Clone, Default)]
struct DispersionFlags([Option<f64>; Settings::KEYS.len()]);

impl DispersionFlags {
    /// Writes every flag given into `s`; returns the keys it replaced.
    fn apply(&self, s: &mut Settings) -> Vec<DispersionKey> {
        let mut given = Vec::new();
        for (key, flag) in Settings::KEYS.into_iter().zip(self.0) {
            if let Some(v) = flag {
                key.set(s, v);
                given.push(key);
            }
        }
        given
    }
}

impl clap::Args for DispersionFlags {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        Settings::KEYS.iter().fold(cmd, |cmd, key| {
            cmd.arg(
                clap::Arg::new(key.name)
                    .long(key.long())
                    .value_name(key.name.to_uppercase())
                    .value_parser(clap::value_parser!(f64))
                    .action(clap::ArgAction::Set)
                    .allow_negative_numbers(true)
                    .help(key.help),
            )
        })
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

impl clap::FromArgMatches for DispersionFlags {
    fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
        let mut flags = Self::default();
        flags.update_from_arg_matches(matches)?;
        Ok(flags)
    }

    fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
        for (key, flag) in Settings::KEYS.iter().zip(&mut self.0) {
            if let Some(v) = matches.get_one::<f64>(key.name) {
                *flag = Some(*v);
            }
        }
        Ok(())
    }
}

/// One disperse run's inputs.
struct Run<'a> {
    /// The directory asked for.
    dir: &'a Path,
    /// Where the path and its summary are: `dir`, or its `phase2/` for a two-phase plan.
    data: &'a Path,
    /// A two-phase plan: the task as given (phase 1 from its start).
    top: Option<&'a LoadedTask>,
    lt: &'a LoadedTask,
    settings: Settings,
    seed: u64,
    samples: usize,
    shard: Shard,
    plots: bool,
    closed_loop: bool,
    out: &'a Path,
    started: std::time::Instant,
}

fn read_path<const N: usize>(dir: &Path) -> Result<(JointPath<N>, String), CliError> {
    let csv = read_output_file(dir, "trajectory.csv")?;
    let path = JointPath::parse(dir, &csv)?;
    Ok((path, csv))
}

fn export<const N: usize, const K: usize>(
    lt: &LoadedTask,
    settings: &Settings,
    seed: u64,
    sample: u64,
    out: &Path,
) -> Result<(), CliError> {
    let draw = Draw::sample(&lt.chain, settings, seed, sample)?;
    let mut dispersed = lt.clone();
    dispersed.chain = draw.apply(&lt.chain);
    // The dispersed robot must be a valid model before anyone re-checks it.
    dispersed.task::<N, K>()?;
    write_file(
        out,
        urdf::write(&dispersed.chain).as_bytes(),
        FileKind::Urdf,
    )?;
    let w = draw.base_rate.map(f64::to_degrees);
    eprintln!(
        "disperse: sample {sample} of seed {seed} -> {} (initial base rate {:?} deg/s, not in the URDF)",
        out.display(),
        w
    );
    Ok(())
}

/// Sample `sample`'s closed-loop flight as a directory: the dispersed robot (robot.urdf),
/// the flown joint path (trajectory.csv: `t,q1..qN,qd1..qdN`), the task (task.toml), the
/// per-cycle trace (cycles.csv) and the flight's summary.json
/// ([`closed_loop::FlightSummary`]); `scripts/disperse-check.py --dir OUT --urdf
/// OUT/robot.urdf --runs RUNS --sample K` re-flies it with Pinocchio and `host-sim view
/// OUT` draws it.
#[allow(clippy::too_many_arguments)]
fn export_flight<const N: usize, const K: usize>(
    lt: &LoadedTask,
    data: &Path,
    settings: &Settings,
    seed: u64,
    sample: u64,
    plots: bool,
    out: &Path,
) -> Result<(), CliError> {
    let (path, _) = read_path::<N>(data)?;
    let draw = Draw::sample(&lt.chain, settings, seed, sample)?;
    let mut dispersed = lt.clone();
    dispersed.chain = draw.apply(&lt.chain);
    dispersed.task::<N, K>()?;
    let config = lt.loop_config()?;
    let mut trace = closed_loop::Trace::default();
    let flight = closed_loop::fly::<N, K>(
        lt,
        &path,
        &draw,
        &lt.file.sensors,
        &config,
        seed,
        sample,
        Some(&mut trace),
    )?;
    let task = dispersed.task::<N, K>()?;
    let last: [f64; N] = trace
        .flown_q
        .last()
        .map(|q| core::array::from_fn(|i| q[i]))
        .ok_or_else(|| CliError::internal("the flight has no samples"))?;
    let end = task.end_pose(&last, reactionless::kinematics::IDENTITY_WXYZ);
    let summary = closed_loop::FlightSummary {
        kind: closed_loop::FLIGHT_KIND.into(),
        seed,
        sample,
        end_pose: crate::artifacts::PoseJson {
            position: end.position,
            quat_wxyz: end.quat_wxyz,
        },
        figures: flight.figures,
        loop_figures: flight.loop_figures,
        fault: flight.fault.map(|f| format!("{f:?}")),
        initial_momentum: draw.initial_momentum(&task),
        cycles: trace.t.len(),
    };
    let dir = OutDir::create(out)?;
    dir.write("robot.urdf", urdf::write(&dispersed.chain).as_bytes())?;
    dir.write("trajectory.csv", trace.flown_csv().as_bytes())?;
    dir.write("task.toml", lt.text.as_bytes())?;
    dir.write("cycles.csv", trace.cycles_csv().as_bytes())?;
    dir.write(
        "summary.json",
        (serde_json::to_string_pretty(&summary).or_internal(|| "summary.json")? + "\n").as_bytes(),
    )?;
    if plots {
        flight_figures::<N, K>(&dispersed, &trace, &path, config.period, seed, sample, &dir)?;
    }
    let written = dir.commit()?;
    eprintln!(
        "disperse: sample {sample} of seed {seed} flown closed-loop -> {} (base disturbance {} deg, {} samples)",
        written.display(),
        number(flight.figures.base_disturbance_deg),
        trace.flown_t.len()
    );
    Ok(())
}

/// The closed-loop flight's figures (crate::plots' joints, joint rates, end-effector path
/// and base attitude, on the dispersed robot it flew) and the loop's own: the true base
/// rotation against the estimate, the commands less the plan's rates, the end effector's
/// distance to the target.
fn flight_figures<const N: usize, const K: usize>(
    dispersed: &LoadedTask,
    trace: &closed_loop::Trace,
    path: &JointPath<N>,
    period: f64,
    seed: u64,
    sample: u64,
    dir: &OutDir,
) -> Result<(), CliError> {
    let task = dispersed.task::<N, K>()?;
    let robot = task.robot();
    let com0 = task.com0();
    let ee = trace
        .flown_q
        .iter()
        .zip(&trace.flown_base)
        .map(|(q, b)| {
            let q: [f64; N] = core::array::from_fn(|i| q[i]);
            reactionless::Frames::new(robot, &q)
                .end_pose(&com0, *b)
                .position
        })
        .collect();
    let data = crate::plots::PlotData {
        joint_names: dispersed.chain.joint_names.clone(),
        t: trace.flown_t.clone(),
        q: trace.flown_q.clone(),
        qd: trace.flown_qd.clone(),
        lower: robot.lower().to_vec(),
        upper: robot.upper().to_vec(),
        qd_limit: dispersed.chain.joints.iter().map(|j| j.velocity).collect(),
        ee,
        target: task.target().position,
        base_angle_deg: trace
            .flown_base
            .iter()
            .map(|b| reactionless::geometry::quat_angle(*b).to_degrees())
            .collect(),
        base_wxyz: trace.flown_base.clone(),
        best_f_history: None,
        tolerance: dispersed.file.planner.tolerance,
        first_hit: None,
        base_limit_deg: dispersed.max_base_disturbance_deg(),
        stamp: format!(
            "{} · closed loop · sample {sample} of seed {seed} · {}",
            dispersed.path.display(),
            crate::version::Build::current().stamp()
        ),
    };
    crate::plots::write_plots(&dir.path(""), &data)?;
    // The plan's rate over the cycle each command is flown in (cycle k + 1).
    let (per, _) = closed_loop::cycle_steps(path, period)?;
    let last = path.q.len() - 1;
    let at = |k: usize| path.q[(k * per).min(last)];
    let correction = trace
        .command
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let (a, b) = (at(k + 1), at(k + 2));
            c.iter()
                .enumerate()
                .map(|(j, v)| v - (b[j] - a[j]) / period)
                .collect()
        })
        .collect();
    let norm_deg = |v: &[f64; 3]| {
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
            .sqrt()
            .to_degrees()
    };
    let target = task.target().position;
    let loop_data = crate::plots::LoopPlotData {
        joint_names: dispersed.chain.joint_names.clone(),
        t_cycle: trace.t.clone(),
        truth_deg: trace.theta.iter().map(norm_deg).collect(),
        estimate_deg: trace.theta_estimate.iter().map(norm_deg).collect(),
        correction,
        t: trace.flown_t.clone(),
        ee_distance_m: data
            .ee
            .iter()
            .map(|p| {
                let d = [p[0] - target[0], p[1] - target[1], p[2] - target[2]];
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
            })
            .collect(),
        base_limit_deg: data.base_limit_deg,
        stamp: data.stamp.clone(),
    };
    crate::plots::write_loop_plots(&dir.path(""), &loop_data)?;
    Ok(())
}

/// The figures `summary.json` of the directory gives for the nominal model.
fn dir_summary(dir: &Path) -> Result<DirSummary, CliError> {
    let text = read_output_file(dir, "summary.json")?;
    let v: serde_json::Value =
        serde_json::from_str(&text).or_input(|| format!("{}/summary.json", dir.display()))?;
    Ok(DirSummary {
        base_disturbance_deg: v["base_disturbance_deg"].as_f64(),
        truth_f: v["truth_f"].as_f64(),
    })
}

fn disperse<const N: usize, const K: usize>(run: &Run<'_>) -> Result<(), CliError> {
    let (mut path, csv) = read_path::<N>(run.data)?;
    path.preshaped_from = run.top.map(LoadedTask::start::<N>).transpose()?;
    let lt = run.lt;
    let nominal_draw = Draw::nominal(&lt.chain);
    let (mut nominal, _) = dispersion::fly::<N, K>(lt, &path, &nominal_draw)?;
    // The closed loop: its settings, and the nominal robot flown with noise-free sensors.
    let loop_setup = if run.closed_loop {
        let config = lt.loop_config()?;
        let sensors = lt.file.sensors;
        closed_loop::cycle_steps(&path, config.period)?;
        let quiet = SensorSettings {
            star_tracker_arcsec: 0.0,
            gyro_arw_deg_rt_h: 0.0,
            gyro_bias_deg_h: 0.0,
            dropout_probability: 0.0,
            ..sensors
        };
        let flight =
            closed_loop::fly::<N, K>(lt, &path, &nominal_draw, &quiet, &config, run.seed, 0, None)?;
        nominal = flight.figures;
        Some((config, sensors, flight))
    } else {
        None
    };
    let sensitivity = if run.closed_loop {
        Vec::new()
    } else {
        dispersion::sensitivity::<N, K>(lt, &path, &run.settings, &nominal)?
    };
    let range = run.shard.items(run.samples, "samples")?;
    let bar = drive::Progress::new("disperse", range.len() as u64, "samples");
    let rows: Vec<Result<Row, CliError>> = range
        .clone()
        .into_par_iter()
        .map(|k| {
            let sample = k as u64;
            let named = |e: CliError| CliError {
                message: format!("sample {sample}: {}", e.message),
                ..e
            };
            if drive::cancelled() {
                return Err(CliError::failed("interrupted"));
            }
            let r = Draw::sample(&lt.chain, &run.settings, run.seed, sample).and_then(|draw| {
                let (figures, loop_figures) = match &loop_setup {
                    Some((config, sensors, _)) => {
                        let f = closed_loop::fly::<N, K>(
                            lt, &path, &draw, sensors, config, run.seed, sample, None,
                        )
                        .map_err(named)?;
                        (f.figures, Some(f.loop_figures))
                    }
                    None => (
                        dispersion::fly::<N, K>(lt, &path, &draw).map_err(named)?.0,
                        None,
                    ),
                };
                Ok(Row {
                    sample,
                    figures,
                    draw,
                    loop_figures,
                })
            });
            bar.inc();
            r
        })
        .collect();
    bar.finish();
    let rows: Vec<Row> = rows.into_iter().collect::<Result<_, _>>()?;
    let figures: Vec<Figures> = rows.iter().map(|r| r.figures).collect();
    let rep = Report {
        dir: run.dir.display().to_string(),
        robot: lt.chain.name.clone(),
        seed: run.seed,
        samples: run.samples,
        rows: rows.len(),
        settings: run.settings,
        nominal,
        dir_summary: dir_summary(run.data)?,
        statistics: Statistics::of(&figures),
        sensitivity,
        mode: if run.closed_loop {
            "closed_loop"
        } else {
            "open_loop"
        }
        .into(),
        closed_loop: loop_setup.map(|(config, sensors, flight)| {
            let _ = config;
            let loops: Vec<_> = rows.iter().filter_map(|r| r.loop_figures).collect();
            ClosedLoopSummary {
                sensors,
                settings: lt.file.closed_loop,
                nominal_noise_free: flight.figures,
                nominal_loop: flight.loop_figures,
                statistics: LoopStatistics::of(&loops),
            }
        }),
    };
    let out = OutDir::create(run.out)?;
    out.write("runs.csv", &report::runs_csv(&lt.chain, &rows)?)?;
    report::write_report(&out, &rep, run.plots, &figures)?;
    let mut bits = Vec::new();
    for (_, v) in run.settings.entries() {
        bits.extend(v.to_bits().to_le_bytes());
    }
    let mode = if run.closed_loop {
        // The closed loop's inputs: the sensors and the executor's settings.
        format!(
            "closed_loop {:?} {:?}",
            lt.file.sensors, lt.file.closed_loop
        )
    } else {
        String::new()
    };
    let (seed, samples) = (run.seed.to_le_bytes(), (run.samples as u64).to_le_bytes());
    let mut parts: Vec<&[u8]> = vec![
        b"disperse",
        lt.text.as_bytes(),
        lt.urdf_text.as_bytes(),
        csv.as_bytes(),
        &seed,
        &samples,
        &bits,
        rep.dir.as_bytes(),
    ];
    if run.closed_loop {
        parts.push(mode.as_bytes());
    }
    let id = shards::run_id(&parts);
    out.write_json(
        shards::MANIFEST,
        &Manifest {
            kind: "disperse".into(),
            run_id: id,
            shard: run.shard.index,
            shards: run.shard.count,
            first: range.start,
            end: range.end,
            total: run.samples,
            build: shards::build(),
            plots: run.plots,
            context: serde_json::Value::Null,
            wall_time_s: run.started.elapsed().as_secs_f64(),
        },
    )?;
    let path = out.commit()?;
    let s = &rep.statistics;
    let part = if run.shard == Shard::WHOLE {
        String::new()
    } else {
        format!(
            " (shard {}: samples {}..{})",
            run.shard, range.start, range.end
        )
    };
    eprintln!(
        "disperse: {} samples{part}: base disturbance p99 {} deg (nominal {}), position error p99 {} m, in {:.1} s -> {}",
        rows.len(),
        number(s.base_disturbance_deg.p99),
        number(nominal.base_disturbance_deg),
        number(s.position_error_m.p99),
        run.started.elapsed().as_secs_f64(),
        path.display()
    );
    Ok(())
}
