//! What the flight image and C clients load: the task block of a task file, for the flight
//! robot (`reactionless::block`, CRC-32). `target` hands it to QEMU, `block` writes it to a
//! file for C clients (`reactionless-ffi`'s `rl_planner_load_block`). With re-timing
//! settings ([`retime_settings`]) the block is `RLTASK03` and the image also re-times the
//! plan; a task with `[preshape]` gives a two-phase block (`RLTASK04`, with re-timing
//! `RLTASK05`) and the image plans in two phases (spec §15); [`flight_outputs`] is what
//! the image then reports, computed on the host for `target` to compare.

use crate::error::{CliError, Context};
use crate::records::{Outputs, two_phase_outputs_of};
use crate::taskfile::{LoadedTask, Overrides};
use reactionless::Pose;
use reactionless::block::{RetimeSettings, TaskBlock, encode, sectioned_block_len};

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
        segments: lt.file.motion.segments,
        integrator: lt.motion()?.integrator(),
        stride: block_stride(lt)?,
        planner,
        retime,
        two_phase,
    };
    let mut buf = vec![0u8; sectioned_block_len(7, true, true)];
    let len = encode(&block, &mut buf).or_internal(|| "task block")?;
    buf.truncate(len);
    Ok(buf)
}

/// The block's stride field ([`TaskBlock::stride`]): 0 for Euler, else the samples per
/// integrator step, at most 255 in a block.
fn block_stride(lt: &LoadedTask) -> Result<u32, CliError> {
    let motion = lt.motion()?;
    match motion.integrator() {
        reactionless::Integrator::Euler => Ok(0),
        _ if motion.stride() <= 0xFF => Ok(motion.stride()),
        _ => Err(CliError::input(format!(
            "{}: [motion] integrator_step_s = {} s is {} steps of dt; a task block carries at most 255",
            lt.path.display(),
            f64::from(motion.stride()) * motion.dt(),
            motion.stride()
        ))),
    }
}

/// What the flight image reports for a two-phase block of `lt` (firmware/src/main.rs,
/// `plan_two_phase`), computed on the host: [`crate::records::two_phase_outputs_of`] with the
/// flight image's swarm capacity; the `TWOPHASE` line's fields in order and `q_s`'s bit
/// patterns; and phase 2's task.
pub fn flight_outputs(lt: &LoadedTask, overrides: &Overrides) -> Result<FlightTwoPhase, CliError> {
    let run = two_phase_outputs_of::<FLIGHT_N, 4>(lt, overrides, FLIGHT_P)?;
    let two = run
        .outputs
        .two_phase
        .clone()
        .ok_or_else(|| CliError::internal("a two-phase run without its outputs"))?;
    Ok(FlightTwoPhase {
        outputs: run.outputs,
        line: two.fields(),
        q_s_bits: two.q_s_bits,
        phase2: run.phase2,
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
