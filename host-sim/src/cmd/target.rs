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
//! Exit 0 only when bit-identical and within budgets; 1 otherwise; 2 for bad input.

use crate::args::PlanArgs;
use crate::error::{CliError, Context};
pub use crate::flight::{FLIGHT_N, FLIGHT_P, task_block};
use crate::flight::{retime_settings, task_block_retimed};
use crate::records::{Outputs, PoseBits, bits, first_difference, outputs_of};
use crate::taskfile;
use object::{Object, ObjectSection, ObjectSymbol};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Where QEMU's loader puts the task block (`TASK` in memory.x).
pub const TASK_ADDR: u32 = 0x203f_0000;
/// Stack budget (bytes).
pub const STACK_BUDGET: u64 = 16 * 1024;
/// Static RAM budget (bytes), the re-timing grid excepted.
pub const STATIC_RAM_BUDGET: u64 = 64 * 1024;
/// Static RAM budget of the re-timing grid (bytes): 3,000 points of 64 bytes fit.
pub const RETIME_STATIC_RAM_BUDGET: u64 = 192 * 1024;
/// Instruction budget of one re-timing (the path's two rollouts and the solve) at the
/// image's largest grid, 3,000 points: 0.12 s of a 400 MHz Cortex-M7 at one instruction
/// per cycle (measured: 37.0 M at 2,000 points, 40.0 M at 3,000 on the reference plan).
pub const RETIME_INSTRUCTION_BUDGET: u64 = 48_000_000;

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
const MARKERS: [&str; 10] = [
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
}

/// Instruction figures from the plugin's log: per step, per rollout, max and mean per call.
fn instruction_stats(log: &str) -> Result<Instructions, CliError> {
    let mut open: [Option<u64>; MARKERS.len() / 2] = [None; MARKERS.len() / 2];
    let (mut step, mut rollout, mut max_call, mut sum, mut calls, mut total) =
        (0, 0, 0, 0u64, 0u64, 0);
    let (mut retime, mut stream) = (None, None);
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
                _ => stream = Some(d),
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
    })
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

/// The host's re-timing of `eta` with the block's settings, as the image reports it.
fn host_retime(
    lt: &taskfile::LoadedTask,
    eta: &[f64],
    qdd_max_deg: &[f64; FLIGHT_N],
    grid: u32,
    margin: f64,
) -> Result<RetimeReport, CliError> {
    let task = lt.task::<7, 4>()?;
    let mut e = [[0.0; 2]; 4];
    for (slot, v) in e.iter_mut().flatten().zip(eta) {
        *slot = *v;
    }
    let r = crate::retiming::compute(&task, &e, qdd_max_deg, grid, margin)?;
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
    #[arg(long, default_value_t = 1800)]
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
    #[arg(long, requires = "retime")]
    grid: Option<u32>,
    #[command(flatten)]
    planning: PlanArgs,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        run(&self, !self.no_build)
    }
}

fn run(args: &Args, build_first: bool) -> Result<(), CliError> {
    let (json, timeout_s) = (args.json, args.timeout_s);
    let overrides = args.planning.overrides();
    let lt = taskfile::load(&args.task)?;
    let settings = if args.retime {
        Some(retime_settings(&lt, args.accel_deg_s2, args.grid)?)
    } else {
        None
    };
    let block = task_block_retimed(&lt, &overrides, settings)?;
    let root = repo_root();
    let elf_path = if build_first {
        build(&root)?
    } else {
        root.join("target/firmware/thumbv7em-none-eabihf/release/reactionless-firmware")
    };
    let plugin = root.join("target/qemu/libinsn.so");
    let elf_bytes = std::fs::read(&elf_path).map_err(|e| {
        CliError::input(format!(
            "{}: {e} (build it with scripts/build-firmware.sh)",
            elf_path.display()
        ))
    })?;
    let elf = read_elf(&elf_bytes)?;
    let work = tempfile::Builder::new()
        .prefix("host-sim-target-")
        .tempdir()
        .or_input(|| "cannot create a temporary directory")?;
    let block_path = work.path().join("task.bin");
    let log_path = work.path().join("insn.log");
    std::fs::write(&block_path, &block).or_input(|| block_path.display().to_string())?;
    let mut plugin_arg = format!("{},out={}", plugin.display(), log_path.display());
    for m in &elf.markers {
        plugin_arg.push_str(&format!(",mark={m:x}"));
    }
    let start = Instant::now();
    let bar = crate::drive::spinner(
        "running the flight image under QEMU (the reference task takes about 10 s of emulation, C-PSO about 35 s)",
    );
    let out = Command::new("timeout")
        .arg(timeout_s.to_string())
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
        .arg(&elf_path)
        .output()
        .or_input(|| "cannot run qemu-system-arm")?;
    let qemu_seconds = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let lines = decode_defmt(&elf_bytes, &out.stdout)?;
    if !out.status.success() {
        return Err(CliError::failed(format!(
            "QEMU exited with {} after {qemu_seconds:.0} s: {} {}",
            out.status,
            lines.join(" | "),
            String::from_utf8_lossy(&out.stderr)
        )));
    }
    let (on_target, stack, frames) = target_outputs(&lines)?;
    let size = |key: &str| -> Result<u64, CliError> {
        fields(&lines, "SIZES")
            .and_then(|f| {
                f.iter()
                    .find(|(k, _)| *k == key)
                    .and_then(|(_, v)| v.parse().ok())
            })
            .ok_or_else(|| CliError::failed(format!("the image reported no {key} size")))
    };
    let planner_bytes = size("planner")?;
    let grid_bytes = size("grid")?;
    let log = std::fs::read_to_string(&log_path).or_failed(|| "plugin log")?;
    let Instructions {
        step,
        rollout,
        max_call,
        mean_call,
        calls,
        total,
        retime,
        stream,
    } = instruction_stats(&log)?;
    // The same task on the host (its capacity differs from the image's 64: results do not
    // depend on it).
    let on_host = crate::with_dims!(lt.chain.dof(), outputs_of, &lt, &overrides)?.outputs;
    let mut diff = first_difference(&on_host, &on_target)
        .map(|d| format!("{}: host {}, target {}", d.what, d.first, d.second));
    let retimed = retime_report(&lines)?;
    if let Some(s) = &settings {
        let on_target = retimed
            .clone()
            .ok_or_else(|| CliError::failed("the image did not report its re-timing"))?;
        // The limits as the task gives them (deg/s²): the host converts them as the block did.
        let qdd_deg = lt
            .qdd_max_deg::<FLIGHT_N>(args.accel_deg_s2)?
            .ok_or_else(|| CliError::internal("re-timing settings without limits"))?;
        let on_host = host_retime(&lt, &on_host.eta, &qdd_deg, s.grid, s.margin)?;
        if diff.is_none() && on_host != on_target {
            diff = Some(format!("re-timing: host {on_host:?}, target {on_target:?}"));
        }
        if retime.is_none() || stream.is_none() {
            return Err(CliError::failed("the plugin logged no re-timing markers"));
        }
    }
    let within_retime = retime.is_none_or(|r| r <= RETIME_INSTRUCTION_BUDGET)
        && grid_bytes <= RETIME_STATIC_RAM_BUDGET;
    let within = stack <= STACK_BUDGET
        && elf.static_ram.saturating_sub(grid_bytes) <= STATIC_RAM_BUDGET
        && within_retime;
    let report = TargetJson {
        bit_identical: diff.is_none(),
        first_difference: diff.clone(),
        instructions_per_step: step,
        instructions_per_rollout: rollout,
        max_instructions_per_call: max_call,
        mean_instructions_per_call: mean_call,
        calls,
        frame_budget: lt.file.planner.frame_budget,
        total_instructions: total,
        stack_high_water_bytes: stack,
        flash_bytes: elf.flash,
        static_ram_bytes: elf.static_ram,
        planner_bytes,
        retime_static_ram_bytes: grid_bytes,
        retime_instructions: retime,
        stream_instructions: stream,
        retime_duration_s: retimed
            .as_ref()
            .map(|r| f64::from(r.steps) * lt.file.motion.dt_s),
        setpoint_digest: retimed.as_ref().map(|r| format!("{:016x}", r.digest)),
        converged: on_target.status == "converged",
        iterations: on_target.iterations,
        rollouts: on_target.rollouts,
        trajectory_digest: on_target.trajectory_digest.clone(),
        within_budgets: within,
        qemu_seconds,
        elf: elf_path.display().to_string(),
    };
    if calls != frames {
        return Err(CliError::failed(format!(
            "the plugin saw {calls} calls, the image reported {frames} frames"
        )));
    }
    if json {
        println!(
            "{}",
            serde_json::to_string(&report).or_internal(|| "report JSON")?
        );
    } else {
        println!(
            "bit-identical to the host  {}",
            if report.bit_identical { "yes" } else { "NO" }
        );
        println!("instructions per step      {step}");
        println!("instructions per rollout   {rollout}");
        println!(
            "instructions per call      {max_call} max, {mean_call:.0} mean over {calls} calls of {} steps",
            report.frame_budget
        );
        println!("stack high-water           {stack} bytes (budget {STACK_BUDGET})");
        println!(
            "static RAM                 {} bytes: {} re-timing grid (budget {RETIME_STATIC_RAM_BUDGET}), the rest within {STATIC_RAM_BUDGET} (planner {})",
            elf.static_ram, grid_bytes, report.planner_bytes
        );
        if let (Some(r), Some(s), Some(d)) = (retime, stream, &retimed) {
            println!(
                "re-timing                  {r} instructions (budget {RETIME_INSTRUCTION_BUDGET}), streaming {s} for {} setpoints; {:.2} s",
                d.setpoints,
                f64::from(d.steps) * lt.file.motion.dt_s
            );
        }
        println!("flash                      {} bytes", elf.flash);
        println!(
            "plan on target             {} in {} iterations, {} rollouts; emulation {qemu_seconds:.1} s",
            on_target.status, on_target.iterations, on_target.rollouts
        );
    }
    match (diff, within) {
        (Some(d), _) => Err(CliError::failed(format!("target and host differ: {d}"))),
        (None, false) => Err(CliError::failed(
            "the image exceeds its stack, static RAM or re-timing budget",
        )),
        (None, true) => Ok(()),
    }
}
