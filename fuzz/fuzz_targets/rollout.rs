//! Fuzz target: a rollout of the reference robot with an arbitrary η (any bit patterns),
//! an arbitrary budget slicing, a perturbed start and an optional violation cap. Must never
//! panic; a finished rollout has finite outputs and respects |q̇| ≤ q̇_max; an abandoned one
//! reports a finite Φ above its cap; failures are typed errors.
//!
//! Verifies RL-LAW-005, RL-ROLL-007, RL-CORE-006, RL-ROB-004, RL-ROB-005.
#![no_main]

use libfuzzer_sys::fuzz_target;
use reactionless::reference::{Q0_DEG, TARGET};
use reactionless::{CHASER7, Error, Motion, Progress, Robot, Rollout, Task};

fn f64_at(data: &[u8], i: usize) -> f64 {
    let mut b = [0u8; 8];
    for (k, v) in b.iter_mut().enumerate() {
        *v = data.get(i * 8 + k).copied().unwrap_or(0);
    }
    f64::from_bits(u64::from_le_bytes(b))
}

fuzz_target!(|data: &[u8]| {
    let eta = [
        [f64_at(data, 0), f64_at(data, 1)],
        [f64_at(data, 2), f64_at(data, 3)],
        [f64_at(data, 4), f64_at(data, 5)],
        [f64_at(data, 6), f64_at(data, 7)],
    ];
    let budget = u32::from(data.get(64).copied().unwrap_or(255)).max(1) * 7;
    let nudge = f64::from(data.get(65).copied().unwrap_or(0)) * 1e-3;
    let mut q0 = Q0_DEG.map(f64::to_radians);
    q0[1] += nudge;
    let Ok(robot) = Robot::new(&CHASER7) else {
        return;
    };
    let Ok(motion) = Motion::new(
        2.0,
        0.01,
        1 + u32::from(data.get(66).copied().unwrap_or(0) % 3),
    ) else {
        return;
    };
    let task: Task<7, 4> = match Task::new(robot, q0, TARGET, motion) {
        Ok(t) => t,
        Err(_) => return,
    };
    // Odd byte 67: a violation cap of (byte / 1000) rad.
    let cap = match data.get(67).copied().unwrap_or(0) {
        b if b % 2 == 1 => f64::from(b) * 1e-3,
        _ => f64::INFINITY,
    };
    let mut r = match Rollout::new(&task, &eta) {
        Ok(r) => r.with_violation_cap(cap),
        Err(e) => {
            assert!(
                matches!(e, Error::NotFinite(_) | Error::EtaZero | Error::EtaTooLarge),
                "{e:?}"
            );
            return;
        }
    };
    loop {
        match r.advance(&task, budget, &mut ()) {
            Ok(Progress::Running { .. }) => {}
            Ok(Progress::Abandoned { phi, .. }) => {
                assert!(phi.is_finite() && phi > cap, "{phi} {cap}");
                return;
            }
            Ok(Progress::Done(o)) => {
                for v in o.q_final.iter().chain(&o.end_pose.position).chain(&[
                    o.f,
                    o.phi,
                    o.g,
                    o.max_abs_qd,
                ]) {
                    assert!(v.is_finite());
                }
                assert!(o.max_abs_qd <= task.robot().qd_max());
                return;
            }
            Err(e) => {
                assert!(
                    matches!(e, Error::RankLoss { .. } | Error::NonFiniteState { .. }),
                    "{e:?}"
                );
                return;
            }
        }
    }
});
