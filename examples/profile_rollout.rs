//! Runs 300 rollouts of the reference task (for profilers).
#![allow(missing_docs, clippy::unwrap_used)]
use reactionless::{CHASER7, Motion, Pose, Robot, Task};
fn main() {
    let q0 = [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians);
    let target = Pose {
        position: [2.0, 0.1, -1.4],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    let task: Task<7, 4> = Task::new(
        Robot::new(&CHASER7).unwrap(),
        q0,
        target,
        Motion::new(30.0, 0.01, 1).unwrap(),
    )
    .unwrap();
    let eta = [
        [3.14771, 0.809316],
        [1.12249, 0.754006],
        [4.7352, 0.406031],
        [-4.1572, 4.29895],
    ];
    let mut f = 0.0;
    for _ in 0..300 {
        f += task.rollout(std::hint::black_box(&eta), &mut ()).unwrap().f;
    }
    println!("{f}");
}
