//! The reference scenario of spec §8: the chaser's start, the target and the paper's η̂.
//!
//! Owns the constants of `spec/tasks/paper.toml` for code that has no file system (the
//! flight image, benchmarks, tests). host-sim reads the same scenario from the task file.

use crate::error::Error;
use crate::geometry::Pose;
use crate::model::{CHASER7, Robot};
use crate::task::Task;
use crate::trajectory::Motion;

/// Start configuration q₀ (deg).
pub const Q0_DEG: [f64; 7] = [-90.0, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0];

/// The paper's published optimum η̂ as pairs `(a_i, b_i)`.
pub const ETA_HAT: [[f64; 2]; 4] = [
    [3.14771, 0.809316],
    [1.12249, 0.754006],
    [4.7352, 0.406031],
    [-4.1572, 4.29895],
];

/// The target: the pose η̂ reaches with the true base drift (inertial frame).
pub const TARGET: Pose = Pose {
    position: [2.0166710746921925, 0.13996636886034725, -1.43192511932475],
    quat_wxyz: [
        0.3874560731031927,
        0.2654610699800615,
        -0.37163840872581944,
        0.8008077827420479,
    ],
};

/// Motion duration (s), step (s) and time-law degree of the reference task.
pub const TF_S: f64 = 30.0;
/// Integration step (s).
pub const DT_S: f64 = 0.01;

/// The reference task: [`CHASER7`] from [`Q0_DEG`] to [`TARGET`] in 30 s at dt = 0.01 s.
///
/// # Errors
/// None for the constants as shipped; the `Result` carries the core's validation.
///
/// Verifies RL-GOLD-006.
///
/// ```
/// let task = reactionless::reference::paper_task().unwrap();
/// assert_eq!(task.motion().steps(), 3000);
/// ```
pub fn paper_task() -> Result<Task<7, 4>, Error> {
    let robot = Robot::new(&CHASER7)?;
    Task::new(
        robot,
        Q0_DEG.map(f64::to_radians),
        TARGET,
        Motion::new(TF_S, DT_S, 1)?,
    )
}
