//! Two-phase plans on generic targets of the reference robot and start (issue #30): end
//! poses at random configurations `d`° per joint away, and the reference target moved.
//!
//! `cargo run --release --example generic -- [TARGETS] [SEEDS]`
#![allow(clippy::expect_used, clippy::unwrap_used, clippy::indexing_slicing)]

use reactionless::geometry::Pose;
use reactionless::random::{Purpose, Stream};
use reactionless::reference::paper_task;
use reactionless::twophase::{TwoPhaseConfig, plan};
use reactionless::{IDENTITY_WXYZ, Task};

fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

fn unit(s: &mut Stream) -> [f64; 3] {
    loop {
        let v = [0, 1, 2].map(|_| 2.0 * s.uniform() - 1.0);
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n > 0.1 && n <= 1.0 {
            return v.map(|x| x / n);
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let per: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(4);
    let seeds: u64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(1);
    let base = paper_task().expect("reference task");
    let robot = base.robot().clone();
    let q0 = *base.start();
    let mut draws = Stream::for_purpose(2026, Purpose::Generator);
    let mut targets: Vec<(String, Pose)> = Vec::new();
    for d in [5.0f64, 10.0, 20.0, 30.0, 40.0] {
        let mut made = 0;
        while made < per {
            let mut q = q0;
            for (j, v) in q.iter_mut().enumerate() {
                let sign = if draws.uniform() < 0.5 { -1.0 } else { 1.0 };
                *v += sign * d.to_radians() * (0.5 + 0.5 * draws.uniform());
                let (lo, hi) = (robot.lower()[j], robot.upper()[j]);
                if *v < lo + 0.01 || *v > hi - 0.01 {
                    *v = q0[j] - (*v - q0[j]);
                }
            }
            let inside = q
                .iter()
                .enumerate()
                .all(|(j, v)| *v > robot.lower()[j] && *v < robot.upper()[j]);
            if inside {
                targets.push((format!("joint {d}°"), base.end_pose(&q, IDENTITY_WXYZ)));
                made += 1;
            }
        }
    }
    for (cm, deg) in [(0.01f64, 0.5f64), (0.05, 2.0)] {
        for _ in 0..per {
            let t = *base.target();
            let u = unit(&mut draws);
            let a = unit(&mut draws);
            let h = (deg.to_radians() / 2.0).sin();
            let dq = [(deg.to_radians() / 2.0).cos(), a[0] * h, a[1] * h, a[2] * h];
            let pose = Pose {
                position: [0, 1, 2].map(|i| t.position[i] + cm * u[i]),
                quat_wxyz: quat_mul(dq, t.quat_wxyz),
            };
            targets.push((format!("moved {cm} m {deg}°"), pose));
        }
    }
    let config = TwoPhaseConfig::reference();
    println!(
        "target\tseed\treach_f\tstop\trollouts\tstarts\tf\tT1_s\th_Nms\ttau_Nm\tmax_dq_deg\twall_s"
    );
    let mut rollouts = Vec::new();
    let (mut ok, mut n) = (0, 0);
    for (name, target) in &targets {
        let task: Task<7, 4> = Task::new(robot.clone(), q0, *target, *base.motion()).expect("task");
        for seed in 1..=seeds {
            let t = std::time::Instant::now();
            let p = plan(&task, &config, seed).expect("plan");
            let wall = t.elapsed().as_secs_f64();
            // Phase 2 flown on the truth model: its base disturbance.
            let mut base_deg = f64::NAN;
            if p.converged() {
                let mut phase2 = task.clone();
                phase2.move_start(&p.q_s).expect("q_s");
                let mut truth = reactionless::TruthModel::new(&phase2, 10);
                phase2.rollout(&p.eta, &mut truth).expect("phase 2");
                base_deg = truth.max_angle().to_degrees();
            }
            let dq = p
                .q_s
                .iter()
                .zip(q0.iter())
                .map(|(a, b)| (a - b).abs().to_degrees())
                .fold(0.0, f64::max);
            println!(
                "{name}\t{seed}\t{:.1e}\t{:?}\t{}\t{}\t{:.2e}\t{:.2}\t{:.3}\t{:.3}\t{:.1}\t{:.2}\t{:.2e}",
                p.reach_f,
                p.stop,
                p.rollouts,
                p.starts,
                p.outcome.map_or(f64::NAN, |o| o.f),
                p.preshape.duration(),
                p.demand.momentum_nms,
                p.demand.torque_nm,
                dq,
                wall,
                base_deg
            );
            if p.stop == reactionless::TwoPhaseStop::BeyondReach {
                let o = base
                    .rollout(&reactionless::reference::ETA_HAT, &mut ())
                    .unwrap();
                let mut st = Stream::new(9);
                let (q, f) = reactionless::twophase::inverse(&task, 0.005, &o.q_final, 1, &mut st);
                let margins: Vec<f64> = q
                    .iter()
                    .enumerate()
                    .map(|(j, v)| ((v - robot.lower()[j]).min(robot.upper()[j] - v)).to_degrees())
                    .collect();
                println!("  inverse from eta-hat's end: f = {f:.2e}, margins deg {margins:.1?}");
            }
            n += 1;
            if p.converged() {
                ok += 1;
            }
            rollouts.push(p.rollouts);
        }
    }
    rollouts.sort_unstable();
    println!(
        "converged {ok}/{n}; median rollouts {}",
        rollouts.get(rollouts.len() / 2).copied().unwrap_or(0)
    );
}
