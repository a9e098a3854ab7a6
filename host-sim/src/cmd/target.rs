//! `host-sim target`: the task on the flight target (the Cortex-M7 image under QEMU),
//! compared bit for bit with the host, with the target's measured budgets.
//!
//! Steps:
//! 1. encode the task as a task block (`reactionless::block`, CRC-32) for the flight robot's
//!    joint count (7);
//! 2. build the image and the instruction-counting plugin (`scripts/build-firmware.sh`);
//! 3. run `qemu-system-arm -machine mps2-an500 -cpu cortex-m7` with the block loaded at
//!    `0x203f0000`, `-icount shift=0` and the plugin marking the image's `rl_mark_*`
//!    functions (addresses from the ELF symbol table);
//! 4. decode the image's defmt output (semihosting stdout) with the ELF's defmt table;
//! 5. plan the same task on the host and compare status, counts, η, f, the end pose and the
//!    trajectory digest bit for bit;
//! 6. report instructions per integration step, per rollout and the most per `step` call
//!    over the whole plan at the task's frame budget, the painted-stack high-water mark and
//!    flash and static RAM from the ELF, and check them against the budgets;
//! 7. with `--retime`: the image also re-times the plan to minimum time (block `RLTASK03`)
//!    and streams its setpoints; their count, the optimal duration's bits and the setpoint
//!    digest are compared with the host's re-timing (`host-sim retime`), and the
//!    re-timing's instructions and static RAM are checked against their budgets.
//!
//! 8. a task with `[preshape]` is a two-phase block (`RLTASK04`, `RLTASK05` with
//!    `--retime`): the image plans both phases with the resumable search, one unit per
//!    call (`calls` frames, timed as single-phase frames are), and reports phase 2 as a plan,
//!    plus how the search ended, phase 1's digest, the wheels' demand and `q_s`; all are
//!    compared bit for bit with the host's two-phase plan
//!    (`crate::flight::flight_outputs`), and `--retime` re-times phase 2.
//!
//! Each step is one function, called in this order by `Args::run`: `task_block_retimed`
//! (1), `Image::read` (2), `emulate` (3), `parse` (4), the host's `outputs_of` and
//! `compare` (5, 7), `within_budgets` and `report` (6).
//!
//! Exit 0 only when bit-identical and within budgets; 1 otherwise; 2 for bad input.

use crate::args::PlanArgs;
use crate::error::{CliError, Context};
pub use crate::flight::{FLIGHT_N, FLIGHT_P, task_block};
use crate::flight::{retime_settings, task_block_retimed};
use crate::records::{Outputs, PoseBits, bits, first_difference, outputs_of};
use crate::taskfile;
use object::{Object, ObjectSection, ObjectSymbol};
use reactionless::block::RetimeSettings;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Where QEMU's loader puts the task block (`TASK` in memory.x).
pub const TASK_ADDR: u32 = 0x203f_0000;
/// Stack budget (bytes).
pub const STACK_BUDGET: u64 = 16 * 1024;
/// Static RAM budget (bytes), the re-timing grid excepted: 80 KiB since issue #33 (every
/// task the image keeps holds a collision set of fixed capacity, 3,584 bytes: the
/// planner's, the truth model's and the two-phase search's two; 64 KiB before).
pub const STATIC_RAM_BUDGET: u64 = 80 * 1024;
/// Static RAM budget of the re-timing grid (bytes): 3,000 points of 64 bytes fit.
pub const RETIME_STATIC_RAM_BUDGET: u64 = 192 * 1024;
/// Instruction budget of one re-timing (the path's two rollouts and the solve) at the
/// image's largest grid, 3,000 points: 0.12 s of a 400 MHz Cortex-M7 at one instruction
/// per cycle (measured: 37.0 M at 2,000 points, 40.0 M at 3,000 on the reference plan).
pub const RETIME_INSTRUCTION_BUDGET: u64 = 48_000_000;
/// Instruction budget of one frame of a two-phase plan (one search unit): half of a 10 Hz
/// frame of a 400 MHz Cortex-M7 at one instruction per cycle (measured: 14.6 M, a
/// planner-model rollout with its bookkeeping).
pub const TWO_PHASE_UNIT_BUDGET: u64 = 20_000_000;
/// Instruction budget of one closed-loop control cycle (`Executor::step`): 5 % of a
/// 400 MHz Cortex-M7 at 10 Hz (issue #31).
pub const LOOP_CYCLE_BUDGET: u64 = 2_000_000;

/// What `target` reports.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct TargetJson {
    /// Every output of the image equals the host's, bit for bit.
    pub bit_identical: bool,
    /// The first differing quantity, if any.
    pub first_difference: Option<String>,
    /// Instructions of one integration step (step 1500 of the plan's rollout).
    pub instructions_per_step: u64,
    /// Instructions of one full rollout of the plan's η.
    pub instructions_per_rollout: u64,
    /// Most instructions of one `Planner::step(frame_budget)` call over the whole plan.
    pub max_instructions_per_call: u64,
    /// Mean instructions per call.
    pub mean_instructions_per_call: f64,
    /// `step` calls (frames) until the planner finished.
    pub calls: u64,
    /// Integration steps per call.
    pub frame_budget: u32,
    /// All instructions of the run, boot to exit.
    pub total_instructions: u64,
    /// Deepest stack use (painted stack), bytes.
    pub stack_high_water_bytes: u64,
    /// Flash used: vector table, code and read-only data (bytes).
    pub flash_bytes: u64,
    /// Static RAM: data and bss (bytes).
    pub static_ram_bytes: u64,
    /// `size_of::<Planner<7, 4, 64>>()` on the target (bytes), part of the static RAM.
    pub planner_bytes: u64,
    /// Static RAM of the re-timing grid (bytes), part of `static_ram_bytes`; its budget is
    /// separate ([`RETIME_STATIC_RAM_BUDGET`]).
    pub retime_static_ram_bytes: u64,
    /// With `--retime`: instructions of one re-timing on the target (path from the plan's
    /// two rollouts, backward and forward pass).
    pub retime_instructions: Option<u64>,
    /// With `--retime`: instructions of streaming every setpoint into the digest.
    pub stream_instructions: Option<u64>,
    /// With `--retime`: the re-timed duration `K·dt` (s), on the target.
    pub retime_duration_s: Option<f64>,
    /// With `--retime`: the setpoint digest on the target (what `host-sim retime` writes
    /// as `setpoint_digest`).
    pub setpoint_digest: Option<String>,
    /// Image outputs: converged, iterations, rollouts.
    pub converged: bool,
    /// C-PSO iterations on the target.
    pub iterations: u32,
    /// Rollouts on the target.
    pub rollouts: u32,
    /// Trajectory digest on the target.
    pub trajectory_digest: String,
    /// Within the stack and static RAM budgets.
    pub within_budgets: bool,
    /// Wall time of the emulation (s).
    pub qemu_seconds: f64,
    /// The image.
    pub elf: String,
    /// A single-phase plan flown closed-loop on the image (`closed_loop::fly_ideal` on a
    /// robot whose link masses are 5 % off): its control cycles.
    pub closed_loop_cycles: Option<u64>,
    /// Most instructions of one closed-loop control cycle (`Executor::step`).
    pub max_instructions_per_cycle: Option<u64>,
    /// Mean instructions per closed-loop control cycle.
    pub mean_instructions_per_cycle: Option<f64>,
    /// A two-phase task: how the search ended on the target (`converged`, `exhausted`,
    /// `beyond_reach`, `preshape_bounds`); `calls` are then search units, one per frame.
    pub two_phase_stop: Option<String>,
}

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn build(root: &Path) -> Result<PathBuf, CliError> {
    eprintln!("building the flight image (scripts/build-firmware.sh; cargo's progress follows)");
    // Cargo's progress goes straight to the terminal: the first build takes minutes.
    let o = Command::new(root.join("scripts/build-firmware.sh"))
        .stderr(std::process::Stdio::inherit())
        .output()
        .or_input(|| "cannot run scripts/build-firmware.sh")?;
    if !o.status.success() {
        return Err(CliError::input(
            "building the flight image failed, see cargo's output above (it needs Debian's rustc-web, rust-web-src and lld; see .ci/run)",
        ));
    }
    let rel = String::from_utf8_lossy(&o.stdout).trim().to_string();
    Ok(root.join(rel))
}

/// Marker addresses (Thumb bit cleared), in the plugin's index order.
const MARKERS: [&str; 12] = [
    "rl_mark_call_begin",
    "rl_mark_call_end",
    "rl_mark_rollout_begin",
    "rl_mark_rollout_end",
    "rl_mark_step_begin",
    "rl_mark_step_end",
    "rl_mark_retime_begin",
    "rl_mark_retime_end",
    "rl_mark_stream_begin",
    "rl_mark_stream_end",
    "rl_mark_cycle_begin",
    "rl_mark_cycle_end",
];

struct Elf {
    markers: Vec<u64>,
    flash: u64,
    static_ram: u64,
}

fn read_elf(bytes: &[u8]) -> Result<Elf, CliError> {
    let file = object::File::parse(bytes).or_input(|| "ELF")?;
    let mut markers = Vec::new();
    for name in MARKERS {
        let sym = file
            .symbols()
            .find(|s| s.name() == Ok(name))
            .ok_or_else(|| CliError::input(format!("ELF: no symbol {name}")))?;
        markers.push(sym.address() & !1);
    }
    let (mut flash, mut static_ram) = (0, 0);
    for s in file.sections() {
        let name = s.name().unwrap_or("");
        match name {
            ".vector_table" | ".text" | ".rodata" => flash += s.size(),
            ".data" => {
                flash += s.size();
                static_ram += s.size();
            }
            ".bss" | ".uninit" => static_ram += s.size(),
            _ => {}
        }
    }
    Ok(Elf {
        markers,
        flash,
        static_ram,
    })
}

/// Decodes the image's defmt stream into text lines.
fn decode_defmt(elf: &[u8], stream: &[u8]) -> Result<Vec<String>, CliError> {
    let table = defmt_decoder::Table::parse(elf)
        .or_input(|| "defmt table")?
        .ok_or_else(|| CliError::input("the ELF has no defmt table"))?;
    let mut decoder = table.new_stream_decoder();
    decoder.received(stream);
    let mut lines = Vec::new();
    loop {
        match decoder.decode() {
            Ok(frame) => lines.push(frame.display_message().to_string()),
            Err(defmt_decoder::DecodeError::UnexpectedEof) => break,
            Err(defmt_decoder::DecodeError::Malformed) => {
                return Err(CliError::failed("the image's defmt stream is malformed"));
            }
        }
    }
    Ok(lines)
}

/// Fields `key=value` of the line starting with `tag`.
fn fields<'a>(lines: &'a [String], tag: &str) -> Option<Vec<(&'a str, &'a str)>> {
    let line = lines.iter().find(|l| l.starts_with(tag))?;
    Some(
        line.split_whitespace()
            .skip(1)
            .filter_map(|kv| kv.split_once('='))
            .collect(),
    )
}

fn field<'a>(f: &[(&'a str, &'a str)], key: &str) -> Result<&'a str, CliError> {
    f.iter()
        .find(|(k, _)| *k == key)
        .map(|(_, v)| *v)
        .ok_or_else(|| CliError::failed(format!("the image did not report {key}")))
}

fn hex(s: &str) -> Result<u64, CliError> {
    u64::from_str_radix(s.trim_start_matches("0x"), 16)
        .map_err(|_| CliError::failed(format!("the image reported {s:?}, not a hex number")))
}

/// Lines `TAG index 0x…` as bit-pattern strings, in index order.
fn indexed(lines: &[String], tag: &str) -> Result<Vec<String>, CliError> {
    let mut v: Vec<(usize, u64)> = Vec::new();
    for l in lines.iter().filter(|l| l.starts_with(tag)) {
        let mut it = l.split_whitespace().skip(1);
        let (Some(i), Some(b)) = (it.next(), it.next()) else {
            continue;
        };
        let i: usize = i
            .parse()
            .map_err(|_| CliError::failed(format!("bad line {l:?}")))?;
        v.push((i, hex(b)?));
    }
    v.sort_unstable();
    Ok(v.into_iter().map(|(_, b)| format!("{b:#018x}")).collect())
}

/// The image's outputs, in the form of a record's.
fn target_outputs(lines: &[String]) -> Result<(Outputs, u64, u64), CliError> {
    if let Some(e) = lines.iter().find(|l| l.starts_with("ERROR")) {
        return Err(CliError::failed(format!("the image reported: {e}")));
    }
    let r = fields(lines, "RESULT").ok_or_else(|| {
        CliError::failed(format!(
            "the image reported no result: {}",
            lines.join(" | ")
        ))
    })?;
    let num = |k: &str| -> Result<u32, CliError> {
        field(&r, k)?
            .parse()
            .map_err(|_| CliError::failed(format!("bad {k} in the image's report")))
    };
    let eta_bits = indexed(lines, "ETA")?;
    let pose = indexed(lines, "POSE")?;
    let f = f64::from_bits(hex(field(&r, "f")?)?);
    let outputs = Outputs {
        status: if field(&r, "converged")? == "true" {
            "converged"
        } else {
            "not_converged"
        }
        .into(),
        iterations: num("iterations")?,
        rollouts: num("rollouts")?,
        stagnation_events: num("stagnation")?,
        restarts: num("restarts")?,
        eta: eta_bits
            .iter()
            .map(|b| hex(b).map(f64::from_bits))
            .collect::<Result<_, _>>()?,
        eta_bits,
        f_bits: bits(f),
        f,
        end_pose_bits: PoseBits {
            position: pose.iter().take(3).cloned().collect(),
            quat_wxyz: pose.iter().skip(3).cloned().collect(),
        },
        trajectory_samples: num("samples")?,
        trajectory_digest: format!("{:#018x}", hex(field(&r, "digest")?)?),
        // A two-phase plan's other outputs are its TWOPHASE and QS lines
        // (`compare_two_phase`).
        two_phase: None,
    };
    let stack = lines
        .iter()
        .find(|l| l.starts_with("STACK"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| CliError::failed("the image reported no stack use"))?;
    if field(&r, "reproducible")? != "true" {
        return Err(CliError::failed(
            "the image's re-run rollout differed from its plan",
        ));
    }
    Ok((outputs, stack, u64::from(num("frames")?)))
}

/// Instruction figures from the plugin's log.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Instructions {
    /// One integration step.
    step: u64,
    /// One full rollout.
    rollout: u64,
    /// The most in one `step` call.
    max_call: u64,
    /// Mean per `step` call.
    mean_call: f64,
    /// `step` calls.
    calls: u64,
    /// The whole run, boot to exit.
    total: u64,
    /// One re-timing (path and solve), if the image re-timed.
    retime: Option<u64>,
    /// Streaming every setpoint, if the image re-timed.
    stream: Option<u64>,
    /// The closed loop's cycles: the most instructions of one, the mean, how many.
    cycle_max: u64,
    cycle_mean: f64,
    cycles: u64,
}

/// Instruction figures from the plugin's log: per step, per rollout, max and mean per call.
fn instruction_stats(log: &str) -> Result<Instructions, CliError> {
    let mut open: [Option<u64>; MARKERS.len() / 2] = [None; MARKERS.len() / 2];
    let (mut step, mut rollout, mut max_call, mut sum, mut calls, mut total) =
        (0, 0, 0, 0u64, 0u64, 0);
    let (mut retime, mut stream) = (None, None);
    let (mut cycle_max, mut cycle_sum, mut cycles) = (0, 0u64, 0u64);
    for l in log.lines() {
        let mut it = l.split_whitespace();
        let (Some(a), Some(b)) = (it.next(), it.next()) else {
            continue;
        };
        let count: u64 = b
            .parse()
            .map_err(|_| CliError::failed(format!("plugin log: {l:?}")))?;
        if a == "total" {
            total = count;
            continue;
        }
        let id: usize = a
            .parse()
            .map_err(|_| CliError::failed(format!("plugin log: {l:?}")))?;
        let region = id / 2;
        let slot = open
            .get_mut(region)
            .ok_or_else(|| CliError::failed(format!("plugin log: unknown mark {id}")))?;
        if id % 2 == 0 {
            *slot = Some(count);
        } else if let Some(start) = slot.take() {
            let d = count - start;
            match region {
                0 => {
                    max_call = max_call.max(d);
                    sum += d;
                    calls += 1;
                }
                1 => rollout = d,
                2 => step = d,
                3 => retime = Some(d),
                4 => stream = Some(d),
                _ => {
                    cycle_max = cycle_max.max(d);
                    cycle_sum += d;
                    cycles += 1;
                }
            }
        }
    }
    if total == 0 || calls == 0 {
        return Err(CliError::failed(
            "the instruction-counting plugin logged nothing",
        ));
    }
    Ok(Instructions {
        step,
        rollout,
        max_call,
        mean_call: sum as f64 / calls as f64,
        calls,
        total,
        retime,
        stream,
        cycle_max,
        cycle_mean: cycle_sum as f64 / cycles.max(1) as f64,
        cycles,
    })
}

/// The image's `LOOP` line against the host's closed-loop flight of the same plan
/// (`closed_loop::fly_ideal` on the mistaken robot): the first difference, if any.
fn compare_closed_loop(
    task: &reactionless::Task<FLIGHT_N, 4>,
    segments: u32,
    eta: &[f64],
    lines: &[String],
    on_target: &OnTarget,
) -> Result<Option<String>, CliError> {
    use reactionless::closed_loop::{LoopConfig, Mode, fly_ideal, mistaken};
    let l = fields(lines, "LOOP")
        .ok_or_else(|| CliError::failed("the image reported no closed-loop flight (LOOP)"))?;
    let eta = reactionless::eta_from_flat::<4>(eta, segments)
        .map_err(|e| CliError::internal(format!("the plan's eta: {e}")))?;
    let robot = reactionless::Robot::new(&mistaken(task.robot().desc()))
        .map_err(|e| CliError::internal(e.to_string()))?;
    let truth = reactionless::Task::new(robot, *task.start(), *task.target(), *task.motion())
        .map_err(|e| CliError::internal(e.to_string()))?;
    let f = fly_ideal(task, &truth, &eta, LoopConfig::DEFAULT, &mut |_| {})
        .map_err(|e| CliError::failed(format!("the host's closed-loop flight: {e}")))?;
    let host = format!(
        "cycles={} digest={:#018x} max_angle={:#018x} done={}",
        f.cycles,
        f.digest,
        f.max_angle.to_bits(),
        f.mode == Mode::Done
    );
    let target = format!(
        "cycles={} digest={} max_angle={} done={}",
        field(&l, "cycles")?,
        field(&l, "digest")?,
        field(&l, "max_angle")?,
        field(&l, "done")?
    );
    if on_target.instructions.cycles != u64::from(f.cycles) {
        return Err(CliError::failed(format!(
            "the plugin saw {} closed-loop cycles, the host flew {}",
            on_target.instructions.cycles, f.cycles
        )));
    }
    Ok((host != target).then(|| format!("closed loop: host {host}, target {target}")))
}

/// The image's `RETIME` line: steps, the optimal duration's bits, setpoints and digest.
#[derive(Debug, Clone, PartialEq)]
struct RetimeReport {
    steps: u32,
    optimal_bits: u64,
    setpoints: u32,
    digest: u64,
}

fn retime_report(lines: &[String]) -> Result<Option<RetimeReport>, CliError> {
    let Some(r) = fields(lines, "RETIME") else {
        return Ok(None);
    };
    let num = |k: &str| -> Result<u32, CliError> {
        field(&r, k)?
            .parse()
            .map_err(|_| CliError::failed(format!("bad {k} in the image's RETIME line")))
    };
    Ok(Some(RetimeReport {
        steps: num("steps")?,
        optimal_bits: hex(field(&r, "optimal")?)?,
        setpoints: num("setpoints")?,
        digest: hex(field(&r, "digest")?)?,
    }))
}

/// The image's `TWOPHASE` line and `QS` lines against the host's: the first difference.
fn compare_two_phase(
    host: &crate::flight::FlightTwoPhase,
    lines: &[String],
) -> Result<Option<String>, CliError> {
    let on_target = fields(lines, "TWOPHASE")
        .ok_or_else(|| CliError::failed("the image reported no TWOPHASE line"))?;
    for (k, want) in &host.line {
        let got = field(&on_target, k)?;
        if got != want {
            return Ok(Some(format!("two-phase {k}: host {want}, target {got}")));
        }
    }
    let q_s = indexed(lines, "QS")?;
    if q_s != host.q_s_bits {
        return Ok(Some(format!(
            "two-phase q_s: host {:?}, target {q_s:?}",
            host.q_s_bits
        )));
    }
    Ok(None)
}

/// The host's re-timing of `eta` from `task`'s start with the block's settings, as the
/// image reports it.
fn host_retime(
    task: &reactionless::Task<FLIGHT_N, 4>,
    eta: &[f64],
    qdd_max_deg: &[f64; FLIGHT_N],
    grid: u32,
    margin: f64,
) -> Result<RetimeReport, CliError> {
    let mut e = [[0.0; 2]; 4];
    for (slot, v) in e.iter_mut().flatten().zip(eta) {
        *slot = *v;
    }
    let r = crate::retiming::compute(
        task,
        &reactionless::one_segment(e),
        qdd_max_deg,
        grid,
        margin,
    )?;
    let last = r
        .setpoints
        .last()
        .ok_or_else(|| CliError::internal("no setpoints"))?;
    let digest = crate::retiming::digest(&r.setpoints);
    Ok(RetimeReport {
        steps: last.step,
        optimal_bits: r.optimal_duration_s.to_bits(),
        setpoints: r.setpoints.len() as u32,
        digest: u64::from_str_radix(&digest, 16).or_internal(|| "setpoint digest")?,
    })
}

/// Plan a task on the flight target (the Cortex-M7 image under QEMU) and compare bit for
/// bit with the host; report instructions per step, per rollout and per call, stack,
/// flash and static RAM. Exit 0 only when bit-identical and within budgets.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task file (TOML) for the flight robot (7 joints).
    task: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    /// Use the image already built instead of building it first.
    #[arg(long)]
    no_build: bool,
    /// Give up on the emulation after this many seconds.
    #[arg(long, default_value_t = 1800, value_parser = crate::args::parse_u64)]
    timeout_s: u64,
    /// Also re-time the finished plan to minimum time on the target and stream its
    /// setpoints, under `[limits] qdd_max_deg_s2` or `--accel-deg-s2` and `[retime]`
    /// (grid at most 3,000 points), compared bit for bit with `host-sim retime`.
    #[arg(long)]
    retime: bool,
    /// Acceleration limit of every joint for `--retime` (deg/s²).
    #[arg(long, requires = "retime")]
    accel_deg_s2: Option<f64>,
    /// Arc-length grid points for `--retime` (at most 3,000); default: the task's
    /// `[retime] grid` (2000).
    #[arg(long, requires = "retime", value_parser = crate::args::parse_u32)]
    grid: Option<u32>,
    #[command(flatten)]
    planning: PlanArgs,
}

impl Args {
    /// Runs the subcommand: one call per stage of the module's steps.
    pub fn run(self) -> Result<(), CliError> {
        let overrides = self.planning.overrides();
        let mut lt = taskfile::load(&self.task)?;
        lt.set_integrator(self.planning.integrator)?;
        let settings = self
            .retime
            .then(|| retime_settings(&lt, self.accel_deg_s2, self.grid))
            .transpose()?;
        let block = task_block_retimed(&lt, &overrides, settings)?;
        let image = Image::read(!self.no_build)?;
        let emulation = emulate(&image, &block, self.timeout_s)?;
        let on_target = parse(&emulation)?;
        // The same task on the host (its capacity differs from the image's 64: results do not
        // depend on it).
        let two_phase = match lt.file.preshape {
            Some(_) => Some(crate::flight::flight_outputs(&lt, &overrides)?),
            None => None,
        };
        let (on_host, retime_task) = match &two_phase {
            // Phase 2's plan here; the rest by `compare_two_phase`.
            Some(t) => (
                Outputs {
                    two_phase: None,
                    ..t.outputs.clone()
                },
                t.phase2.clone(),
            ),
            None => (
                crate::with_dims!(lt.chain.dof(), outputs_of, &lt, &overrides)?.outputs,
                lt.task::<FLIGHT_N, 4>()?,
            ),
        };
        let (mut diff, retimed) = compare(
            &lt,
            &retime_task,
            self.accel_deg_s2,
            settings.as_ref(),
            &on_host,
            &on_target,
            &emulation.lines,
        )?;
        if let (None, Some(t)) = (&diff, &two_phase) {
            diff = compare_two_phase(t, &emulation.lines)?;
        }
        if diff.is_none() && two_phase.is_none() {
            diff = compare_closed_loop(
                &retime_task,
                lt.file.motion.segments,
                &on_host.eta,
                &emulation.lines,
                &on_target,
            )?;
        }
        let within = within_budgets(&image.elf, &on_target, two_phase.is_some());
        let calls = on_target.instructions.calls;
        if calls != on_target.frames {
            return Err(CliError::failed(format!(
                "the plugin saw {calls} calls, the image reported {} frames",
                on_target.frames
            )));
        }
        let mut report = report(
            &lt,
            &image,
            &emulation,
            &on_target,
            retimed.as_ref(),
            diff,
            within,
        );
        report.two_phase_stop = two_phase.as_ref().and_then(|t| {
            t.line
                .iter()
                .find(|(k, _)| k == "stop")
                .map(|(_, v)| v.clone())
        });
        if self.json {
            println!(
                "{}",
                serde_json::to_string(&report).or_internal(|| "report JSON")?
            );
        } else {
            print_report(&report, retimed.as_ref().map(|r| r.setpoints));
        }
        verdict(report)
    }
}

/// The flight image: its path, its bytes and what its ELF says.
struct Image {
    path: PathBuf,
    bytes: Vec<u8>,
    elf: Elf,
}

impl Image {
    /// Builds the image first (`build_first`), or takes the one already built; reads it.
    fn read(build_first: bool) -> Result<Self, CliError> {
        let root = repo_root();
        let path = if build_first {
            build(&root)?
        } else {
            root.join("target/firmware/thumbv7em-none-eabihf/release/reactionless-firmware")
        };
        let bytes = std::fs::read(&path).map_err(|e| {
            CliError::input(format!(
                "{}: {e} (build it with scripts/build-firmware.sh)",
                path.display()
            ))
        })?;
        let elf = read_elf(&bytes)?;
        Ok(Self { path, bytes, elf })
    }
}

/// One run of the image under QEMU: its decoded output, the plugin's log and its wall time.
struct Emulation {
    /// The image's defmt output, one line per frame.
    lines: Vec<String>,
    /// Holds the task block and the plugin's log until the log is read.
    work: tempfile::TempDir,
    /// Wall time of the emulation (s).
    seconds: f64,
}

impl Emulation {
    /// The instruction-counting plugin's log.
    fn log_path(&self) -> PathBuf {
        self.work.path().join(PLUGIN_LOG)
    }
}

/// The plugin's log, in the emulation's temporary directory.
const PLUGIN_LOG: &str = "insn.log";

/// Runs the image with `block` at [`TASK_ADDR`] and the plugin marking its `rl_mark_*`
/// functions; gives up after `timeout_s`. A failed run is an error naming its output.
fn emulate(image: &Image, block: &[u8], timeout_s: u64) -> Result<Emulation, CliError> {
    let work = tempfile::Builder::new()
        .prefix("host-sim-target-")
        .tempdir()
        .or_input(|| "cannot create a temporary directory")?;
    let block_path = work.path().join("task.bin");
    std::fs::write(&block_path, block).or_input(|| block_path.display().to_string())?;
    let start = Instant::now();
    let bar = crate::drive::spinner(
        "running the flight image under QEMU (the reference task takes about 10 s of emulation, C-PSO about 35 s)",
    );
    let out = qemu(image, &block_path, &work.path().join(PLUGIN_LOG), timeout_s)
        .output()
        .or_input(|| "cannot run qemu-system-arm")?;
    let seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let lines = decode_defmt(&image.bytes, &out.stdout)?;
    if !out.status.success() {
        return Err(CliError::failed(format!(
            "QEMU exited with {} after {seconds:.0} s: {} {}",
            out.status,
            lines.join(" | "),
            String::from_utf8_lossy(&out.stderr)
        )));
    }
    Ok(Emulation {
        lines,
        work,
        seconds,
    })
}

/// `qemu-system-arm` for the image (mps2-an500, Cortex-M7, semihosting, one instruction
/// per tick) with the block at [`TASK_ADDR`] and the counting plugin logging to `log`,
/// under `timeout`.
fn qemu(image: &Image, block_path: &Path, log: &Path, timeout_s: u64) -> Command {
    let plugin = repo_root().join("target/qemu/libinsn.so");
    let mut plugin_arg = format!("{},out={}", plugin.display(), log.display());
    for m in &image.elf.markers {
        plugin_arg.push_str(&format!(",mark={m:x}"));
    }
    let mut cmd = Command::new("timeout");
    cmd.arg(timeout_s.to_string())
        .args([
            "qemu-system-arm",
            "-machine",
            "mps2-an500",
            "-cpu",
            "cortex-m7",
            "-nographic",
        ])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=0,align=off,sleep=off"])
        .arg("-device")
        .arg(format!(
            "loader,file={},addr={TASK_ADDR:#x}",
            block_path.display()
        ))
        .arg("-plugin")
        .arg(plugin_arg)
        .arg("-kernel")
        .arg(&image.path);
    cmd
}

/// What the image reported and the plugin counted.
struct OnTarget {
    /// The plan, in the form of a record's outputs.
    outputs: Outputs,
    /// Deepest stack use (bytes).
    stack: u64,
    /// `step` calls (frames) the image reported.
    frames: u64,
    /// `size_of` the planner (bytes).
    planner_bytes: u64,
    /// Static RAM of the re-timing grid (bytes).
    grid_bytes: u64,
    /// The plugin's instruction figures.
    instructions: Instructions,
}

/// Parses the image's report (result, stack, sizes) and the plugin's log.
fn parse(emulation: &Emulation) -> Result<OnTarget, CliError> {
    let lines = &emulation.lines;
    let (outputs, stack, frames) = target_outputs(lines)?;
    let size = |key: &str| -> Result<u64, CliError> {
        fields(lines, "SIZES")
            .and_then(|f| {
                f.iter()
                    .find(|(k, _)| *k == key)
                    .and_then(|(_, v)| v.parse().ok())
            })
            .ok_or_else(|| CliError::failed(format!("the image reported no {key} size")))
    };
    let planner_bytes = size("planner")?;
    let grid_bytes = size("grid")?;
    let log = std::fs::read_to_string(emulation.log_path()).or_failed(|| "plugin log")?;
    Ok(OnTarget {
        outputs,
        stack,
        frames,
        planner_bytes,
        grid_bytes,
        instructions: instruction_stats(&log)?,
    })
}

/// The first difference between host and target (the plan, then with `settings` the
/// re-timing of the image's `RETIME` line against the host's re-timing from `task`'s
/// start: the task's, or phase 2's for a two-phase plan), and that re-timing.
fn compare(
    lt: &taskfile::LoadedTask,
    task: &reactionless::Task<FLIGHT_N, 4>,
    accel_deg_s2: Option<f64>,
    settings: Option<&RetimeSettings<FLIGHT_N>>,
    on_host: &Outputs,
    on_target: &OnTarget,
    lines: &[String],
) -> Result<(Option<String>, Option<RetimeReport>), CliError> {
    let mut diff = first_difference(on_host, &on_target.outputs)
        .map(|d| format!("{}: host {}, target {}", d.what, d.first, d.second));
    let retimed = retime_report(lines)?;
    if let Some(s) = settings {
        let target_retime = retimed
            .clone()
            .ok_or_else(|| CliError::failed("the image did not report its re-timing"))?;
        // The limits as the task gives them (deg/s²): the host converts them as the block did.
        let qdd_deg = lt
            .qdd_max_deg::<FLIGHT_N>(accel_deg_s2)?
            .ok_or_else(|| CliError::internal("re-timing settings without limits"))?;
        let host_retime = host_retime(task, &on_host.eta, &qdd_deg, s.grid, s.margin)?;
        if diff.is_none() && host_retime != target_retime {
            diff = Some(format!(
                "re-timing: host {host_retime:?}, target {target_retime:?}"
            ));
        }
        let i = &on_target.instructions;
        if i.retime.is_none() || i.stream.is_none() {
            return Err(CliError::failed("the plugin logged no re-timing markers"));
        }
    }
    Ok((diff, retimed))
}

/// Within the stack, static RAM and re-timing budgets, and for a two-phase plan
/// ([`TWO_PHASE_UNIT_BUDGET`]) each frame's.
fn within_budgets(elf: &Elf, t: &OnTarget, two_phase: bool) -> bool {
    let within_frame = !two_phase || t.instructions.max_call <= TWO_PHASE_UNIT_BUDGET;
    let within_cycle = t.instructions.cycle_max <= LOOP_CYCLE_BUDGET;
    let within_retime = t
        .instructions
        .retime
        .is_none_or(|r| r <= RETIME_INSTRUCTION_BUDGET)
        && t.grid_bytes <= RETIME_STATIC_RAM_BUDGET;
    t.stack <= STACK_BUDGET
        && elf.static_ram.saturating_sub(t.grid_bytes) <= STATIC_RAM_BUDGET
        && within_retime
        && within_frame
        && within_cycle
}

/// What `target` reports (`--json`, or the text of [`print_report`]).
fn report(
    lt: &taskfile::LoadedTask,
    image: &Image,
    emulation: &Emulation,
    t: &OnTarget,
    retimed: Option<&RetimeReport>,
    diff: Option<String>,
    within: bool,
) -> TargetJson {
    let i = &t.instructions;
    TargetJson {
        bit_identical: diff.is_none(),
        first_difference: diff,
        instructions_per_step: i.step,
        instructions_per_rollout: i.rollout,
        max_instructions_per_call: i.max_call,
        mean_instructions_per_call: i.mean_call,
        calls: i.calls,
        frame_budget: lt.file.planner.frame_budget,
        total_instructions: i.total,
        stack_high_water_bytes: t.stack,
        flash_bytes: image.elf.flash,
        static_ram_bytes: image.elf.static_ram,
        planner_bytes: t.planner_bytes,
        retime_static_ram_bytes: t.grid_bytes,
        retime_instructions: i.retime,
        stream_instructions: i.stream,
        retime_duration_s: retimed.map(|r| f64::from(r.steps) * lt.file.motion.dt_s),
        setpoint_digest: retimed.map(|r| format!("{:016x}", r.digest)),
        converged: t.outputs.status == "converged",
        iterations: t.outputs.iterations,
        rollouts: t.outputs.rollouts,
        trajectory_digest: t.outputs.trajectory_digest.clone(),
        within_budgets: within,
        qemu_seconds: emulation.seconds,
        elf: image.path.display().to_string(),
        closed_loop_cycles: (i.cycles > 0).then_some(i.cycles),
        max_instructions_per_cycle: (i.cycles > 0).then_some(i.cycle_max),
        mean_instructions_per_cycle: (i.cycles > 0).then_some(i.cycle_mean),
        two_phase_stop: None,
    }
}

/// The report as text; `setpoints`: how many the image streamed, if it re-timed.
fn print_report(r: &TargetJson, setpoints: Option<u32>) {
    println!(
        "bit-identical to the host  {}",
        if r.bit_identical { "yes" } else { "NO" }
    );
    println!("instructions per step      {}", r.instructions_per_step);
    println!("instructions per rollout   {}", r.instructions_per_rollout);
    let slice = if r.two_phase_stop.is_some() {
        "1 search unit".to_owned()
    } else {
        format!("{} steps", r.frame_budget)
    };
    println!(
        "instructions per call      {} max, {:.0} mean over {} calls of {slice}",
        r.max_instructions_per_call, r.mean_instructions_per_call, r.calls
    );
    println!(
        "stack high-water           {} bytes (budget {STACK_BUDGET})",
        r.stack_high_water_bytes
    );
    println!(
        "static RAM                 {} bytes: {} re-timing grid (budget {RETIME_STATIC_RAM_BUDGET}), the rest within {STATIC_RAM_BUDGET} (planner {})",
        r.static_ram_bytes, r.retime_static_ram_bytes, r.planner_bytes
    );
    if let (Some(i), Some(s), Some(n), Some(d)) = (
        r.retime_instructions,
        r.stream_instructions,
        setpoints,
        r.retime_duration_s,
    ) {
        println!(
            "re-timing                  {i} instructions (budget {RETIME_INSTRUCTION_BUDGET}), streaming {s} for {n} setpoints; {d:.2} s"
        );
    }
    if let (Some(n), Some(max), Some(mean)) = (
        r.closed_loop_cycles,
        r.max_instructions_per_cycle,
        r.mean_instructions_per_cycle,
    ) {
        println!(
            "closed-loop cycle          {max} instructions max (budget {LOOP_CYCLE_BUDGET}), {mean:.0} mean over {n} cycles"
        );
    }
    println!("flash                      {} bytes", r.flash_bytes);
    if let Some(stop) = &r.two_phase_stop {
        println!(
            "two-phase plan             {stop}: both phases in {} calls of one search unit, {} instructions in all",
            r.calls,
            (r.mean_instructions_per_call * r.calls as f64).round()
        );
    }
    println!(
        "plan on target             {} in {} iterations, {} rollouts; emulation {:.1} s",
        if r.converged {
            "converged"
        } else {
            "not_converged"
        },
        r.iterations,
        r.rollouts,
        r.qemu_seconds
    );
}

/// Exit 0 only when bit-identical and within budgets.
fn verdict(r: TargetJson) -> Result<(), CliError> {
    match (r.first_difference, r.within_budgets) {
        (Some(d), _) => Err(CliError::failed(format!("target and host differ: {d}"))),
        (None, false) => Err(CliError::failed(
            "the image exceeds its stack, static RAM or re-timing budget",
        )),
        (None, true) => Ok(()),
    }
}
