//! What the flight image and C clients load: the task block of a task file, for the flight
//! robot (`reactionless::block`, CRC-32). `target` hands it to QEMU, `block` writes it to a
//! file for C clients (`reactionless-ffi`'s `rl_planner_load_block`).

use crate::error::{CliError, Context};
use crate::taskfile::{LoadedTask, Overrides};
use reactionless::Pose;
use reactionless::block::{TaskBlock, block_len, encode};

/// The flight robot's joint count (the image is built for it).
pub const FLIGHT_N: usize = 7;
/// Swarm capacity of the flight image.
pub const FLIGHT_P: usize = 64;

/// The task block of a task file, for the flight robot.
pub fn task_block(lt: &LoadedTask, overrides: &Overrides) -> Result<Vec<u8>, CliError> {
    if lt.chain.dof() != FLIGHT_N {
        return Err(CliError::input(format!(
            "{}: the flight image is built for {FLIGHT_N} joints; this robot has {}",
            lt.path.display(),
            lt.chain.dof()
        )));
    }
    // Validate everything the image will validate, with the host's messages.
    let task = lt.task::<7, 4>()?;
    let planner = lt.planner(FLIGHT_P, overrides)?;
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
        planner,
    };
    let mut buf = vec![0u8; block_len(7)];
    encode(&block, &mut buf).or_internal(|| "task block")?;
    Ok(buf)
}
