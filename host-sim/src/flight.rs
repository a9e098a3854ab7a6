//! What the flight image and C clients load: the task block of a task file, for the flight
//! robot (`reactionless::block`, CRC-32). `target` hands it to QEMU, `block` writes it to a
//! file for C clients (`reactionless-ffi`'s `rl_planner_load_block`). With re-timing
//! settings ([`retime_settings`]) the block is `RLTASK03` and the image also re-times the
//! plan; a task with `[preshape]` gives a two-phase block (`RLTASK04`, with re-timing
//! `RLTASK05`) and the image plans in two phases (spec §15); [`flight_outputs`] is what
//! the image then reports, computed on the host for `target` to compare.

use crate::error::{CliError, Context};
use crate::goal::status_name;
use crate::records::{Outputs, PoseBits, bits};
use crate::taskfile::{LoadedTask, Overrides};
use reactionless::block::{RetimeSettings, TaskBlock, encode, sectioned_block_len};
use reactionless::{Pose, TrajectoryDigest};

/// The flight robot's joint count (the image is built for it).
pub const FLIGHT_N: usize = 7;
/// Swarm capacity of the flight image.
pub const FLIGHT_P: usize = 64;
/// Re-timing grid capacity of the flight image (points; `RETIME_GRID_CAPACITY` in
/// firmware/src/main.rs).
pub const FLIGHT_RETIME_GRID: u32 = 3000;

/// The task block of a task file, for the flight robot.
pub fn task_block(lt: &LoadedTask, overrides: &Overrides) -> Result<Vec<u8>, CliError> {
    task_block_retimed(lt, overrides, None)
}

/// The re-timing settings of a task file for the flight robot: `[limits] qdd_max_deg_s2`
/// (or `accel_deg_s2` for every joint) in rad/s², `[retime] grid` (or `grid`) and `margin`.
pub fn retime_settings(
    lt: &LoadedTask,
    accel_deg_s2: Option<f64>,
    grid: Option<u32>,
) -> Result<RetimeSettings<FLIGHT_N>, CliError> {
    let qdd = lt.qdd_max_deg::<FLIGHT_N>(accel_deg_s2)?.ok_or_else(|| {
        CliError::input(format!(
            "{}: --retime needs acceleration limits: give --accel-deg-s2 or set [limits] qdd_max_deg_s2",
            lt.path.display()
        ))
    })?;
    let from_flag = grid.is_some();
    let grid = grid.unwrap_or(lt.file.retime.grid);
    if grid > FLIGHT_RETIME_GRID {
        let what = if from_flag {
            format!("--grid {grid}")
        } else {
            format!("{}: [retime] grid = {grid}", lt.path.display())
        };
        return Err(CliError::input(format!(
            "{what}: the flight image holds at most {FLIGHT_RETIME_GRID} points"
        )));
    }
    let settings = RetimeSettings {
        grid,
        margin: lt.file.retime.margin,
        qdd_max: qdd.map(f64::to_radians),
    };
    // Validate what the image will validate, with the host's messages.
    let qd = lt.chain.desc::<FLIGHT_N>()?.joints.map(|j| j.velocity);
    reactionless::retime::Limits::new(qd, settings.qdd_max, settings.margin)
        .map_err(|e| CliError::input(format!("{}: re-timing limits: {e}", lt.path.display())))?;
    Ok(settings)
}

/// The task block of a task file, for the flight robot, with re-timing settings or not.
pub fn task_block_retimed(
    lt: &LoadedTask,
    overrides: &Overrides,
    retime: Option<RetimeSettings<FLIGHT_N>>,
) -> Result<Vec<u8>, CliError> {
    if lt.chain.dof() != FLIGHT_N {
        return Err(CliError::input(format!(
            "{}: the flight image is built for {FLIGHT_N} joints; this robot has {}",
            lt.path.display(),
            lt.chain.dof()
        )));
    }
    // Validate everything the image will validate, with the host's messages.
    let task = lt.task::<7, 4>()?;
    let (planner, asked) = lt.plan_settings(FLIGHT_P, overrides)?;
    let two_phase = lt
        .file
        .preshape
        .map(|section| crate::preshaping::two_phase_config(lt, &section, &planner, &asked));
    let block = TaskBlock::<7> {
        robot: lt.chain.desc::<7>()?,
        q0: *task.start(),
        target: Pose {
            position: lt.target()?.position,
            quat_wxyz: lt.target()?.quat_wxyz,
        },
        tf_s: lt.file.motion.tf_s,
        dt_s: lt.file.motion.dt_s,
        n: lt.file.motion.n,
        family: lt.file.motion.family,
        planner,
        retime,
        two_phase,
    };
    let mut buf = vec![0u8; sectioned_block_len(7, true, true)];
    let len = encode(&block, &mut buf).or_internal(|| "task block")?;
    buf.truncate(len);
    Ok(buf)
}

/// What the flight image reports for a two-phase block of `lt` (firmware/src/main.rs,
/// `plan_two_phase`), computed on the host: phase 2's plan as a record's outputs (from the
/// task moved to `q_s`; no rollout when the target is beyond reach: `f` NaN, no pose, the
/// empty digest), the `TWOPHASE` line's fields in order and `q_s`'s bit patterns; and
/// phase 2's task.
pub fn flight_outputs(lt: &LoadedTask, overrides: &Overrides) -> Result<FlightTwoPhase, CliError> {
    let section = lt
        .file
        .preshape
        .ok_or_else(|| CliError::input(format!("{}: no [preshape] section", lt.path.display())))?;
    let (config, asked) = lt.plan_settings(FLIGHT_P, overrides)?;
    let (mut task, _, p, _) = crate::preshaping::solve::<7, 4>(lt, &section, &config, &asked)?;
    task.move_start(&p.q_s)
        .map_err(|e| CliError::internal(format!("phase 2's start: {e}")))?;
    let mut digest = TrajectoryDigest::new();
    let (f, pose) = match &p.outcome {
        Some(o) => {
            task.rollout(&p.eta, &mut digest)
                .map_err(|e| CliError::internal(format!("phase 2's rollout: {e}")))?;
            (o.f, Some(o.end_pose))
        }
        None => (f64::NAN, None),
    };
    let eta: Vec<f64> = p.eta.iter().flatten().copied().collect();
    let outputs = Outputs {
        status: status_name(p.converged()).into(),
        iterations: 0,
        rollouts: p.rollouts,
        stagnation_events: 0,
        restarts: 0,
        eta_bits: eta.iter().map(|v| bits(*v)).collect(),
        eta,
        f_bits: bits(f),
        f,
        end_pose_bits: PoseBits {
            position: pose.map_or(vec![], |q| q.position.iter().map(|v| bits(*v)).collect()),
            quat_wxyz: pose.map_or(vec![], |q| q.quat_wxyz.iter().map(|v| bits(*v)).collect()),
        },
        trajectory_samples: digest.samples(),
        trajectory_digest: format!("{:#018x}", digest.value()),
    };
    let mut phase1 = TrajectoryDigest::new();
    p.preshape.write(&mut phase1);
    let d = &p.demand;
    let line = vec![
        ("stop", p.stop.name().to_string()),
        ("starts", p.starts.to_string()),
        ("reach_f", bits(p.reach_f)),
        ("base", bits(p.base_disturbance)),
        ("steps1", p.preshape.steps().to_string()),
        ("samples1", phase1.samples().to_string()),
        ("digest1", format!("{:#018x}", phase1.value())),
        ("momentum", bits(d.momentum_nms)),
        ("torque", bits(d.torque_nm)),
        ("shift_x", bits(d.base_shift_m[0])),
        ("shift_y", bits(d.base_shift_m[1])),
        ("shift_z", bits(d.base_shift_m[2])),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    Ok(FlightTwoPhase {
        outputs,
        line,
        q_s_bits: p.q_s.iter().map(|v| bits(*v)).collect(),
        phase2: task,
    })
}

/// [`flight_outputs`]: what the image reports for a two-phase block, on the host.
pub struct FlightTwoPhase {
    /// Phase 2's plan as a record's outputs.
    pub outputs: Outputs,
    /// The `TWOPHASE` line's fields, in order.
    pub line: Vec<(String, String)>,
    /// `q_s`, bit patterns.
    pub q_s_bits: Vec<String>,
    /// Phase 2's task (the task from `q_s`).
    pub phase2: reactionless::Task<7, 4>,
}
