//! Re-timing ([`reactionless::retime`]): the reference plan re-timed under rate and
//! acceleration limits keeps every limit at every written setpoint, rests at both ends,
//! ends at the same configuration and keeps the base still (truth model); property tests
//! over random paths and limits.
//!
//! Requirements: RL-RETIME (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use reactionless::retime::{self, ArcLength, GridPoint, Limits, PathBuilder, Stream};
use reactionless::{TruthModel, reference};

const TOL: f64 = 1.005;

struct Written {
    duration: f64,
    optimal: f64,
    max_qd_ratio: f64,
    max_qdd_ratio: f64,
    first_qd: f64,
    last_qd: f64,
    last_q: [f64; 7],
    base_deg: f64,
    rows: u32,
}

fn retime_reference(accel_deg: f64, m: u32) -> Written {
    let task = reference::paper_task().unwrap();
    let mut grid = vec![GridPoint::<7>::ZERO; m as usize];
    let path = retime::path_of_rollout(&task, &reference::ETA_HAT, &mut grid, m).unwrap();
    let qd = task.robot().desc().joints.map(|j| j.velocity);
    let limits = Limits::new(qd, [accel_deg.to_radians(); 7], 1.0).unwrap();
    let profile = retime::solve(&mut grid, &path, &limits).unwrap();
    let mut stream = Stream::new(&profile, task.motion().dt()).unwrap();
    let mut truth = TruthModel::new(&task, 10);
    let mut w = Written {
        duration: stream.duration(),
        optimal: profile.duration(),
        max_qd_ratio: 0.0,
        max_qdd_ratio: 0.0,
        first_qd: f64::NAN,
        last_qd: f64::NAN,
        last_q: [0.0; 7],
        base_deg: 0.0,
        rows: 0,
    };
    while let Some(sp) = stream.next(&grid) {
        for j in 0..7 {
            w.max_qd_ratio = w.max_qd_ratio.max(sp.qd[j].abs() / limits.qd_max()[j]);
            w.max_qdd_ratio = w.max_qdd_ratio.max(sp.qdd[j].abs() / limits.qdd_max()[j]);
        }
        let speed = sp.qd.iter().map(|v| v.abs()).fold(0.0, f64::max);
        if sp.step == 0 {
            w.first_qd = speed;
        }
        w.last_qd = speed;
        w.last_q = sp.q;
        truth.push(&sp.q, sp.t);
        w.rows += 1;
    }
    w.base_deg = truth.max_angle().to_degrees();
    w
}

/// The reference plan re-timed at 15 °/s and 5 or 1 °/s²: far shorter than 30 s, no limit
/// exceeded by more than 0.5 % at any written setpoint, at rest at both ends, the same end
/// configuration bit for bit, base disturbance below 0.01° (truth model).
/// Verifies RL-RETIME-001, RL-RETIME-002, RL-RETIME-003.
#[test]
fn reference_plan_retimed_keeps_limits_pose_and_base() {
    let task = reference::paper_task().unwrap();
    let end = task.rollout(&reference::ETA_HAT, &mut ()).unwrap().q_final;
    for (accel, lo, hi) in [(5.0, 5.0, 15.0), (1.0, 12.0, 30.0)] {
        let w = retime_reference(accel, retime::DEFAULT_GRID);
        println!(
            "accel {accel} deg/s^2: T* = {:.4} s, written {:.2} s, qd {:.4}, qdd {:.4}, base {:.2e} deg",
            w.optimal, w.duration, w.max_qd_ratio, w.max_qdd_ratio, w.base_deg
        );
        assert!(w.optimal > lo && w.optimal < hi, "{}", w.optimal);
        assert!(w.duration >= w.optimal && w.duration < w.optimal + 0.01 + 1e-9);
        assert_eq!(w.rows, (w.duration / 0.01).round() as u32 + 1);
        assert!(w.max_qd_ratio <= TOL, "rate ratio {}", w.max_qd_ratio);
        assert!(
            w.max_qdd_ratio <= TOL,
            "acceleration ratio {}",
            w.max_qdd_ratio
        );
        assert!(w.max_qdd_ratio > 0.99, "an acceleration limit binds");
        assert_eq!(w.first_qd, 0.0);
        assert_eq!(w.last_qd, 0.0);
        assert_eq!(w.last_q, end);
        assert!(w.base_deg < 0.01, "{}", w.base_deg);
    }
}

/// The grid converges: 1000 and 2000 points agree with 4000 to 0.3 % and 0.1 %.
/// Verifies RL-RETIME-001.
#[test]
fn duration_converges_with_the_grid() {
    let fine = retime_reference(2.0, 4000).optimal;
    for (m, tol) in [(1000, 3e-3), (2000, 1e-3)] {
        let t = retime_reference(2.0, m).optimal;
        println!("M = {m}: {t:.5} s (4000: {fine:.5} s)");
        assert!((t - fine).abs() <= tol * fine, "{m}: {t} vs {fine}");
    }
}

/// A random smooth path in 4 joints, monotone in joint 1 (so it never turns back),
/// sampled densely near its ends like a rest-to-rest rollout.
fn random_path(c: &[f64; 9], samples: usize) -> Vec<[f64; 4]> {
    (0..=samples)
        .map(|k| {
            let u = k as f64 / samples as f64;
            let t = u * u * (3.0 - 2.0 * u);
            [
                t,
                c[0] * t + c[1] * t * t + c[2] * t * t * t,
                c[3] * t + c[4] * (3.0 * t).sin(),
                c[5] * t * t + c[6] * (2.0 * t).cos() + c[7] * t * c[8],
            ]
        })
        .collect()
}

fn solve_path(
    samples: &[[f64; 4]],
    grid: &mut [GridPoint<4>],
    qd: [f64; 4],
    qdd: [f64; 4],
) -> (f64, f64, f64) {
    let mut arc = ArcLength::new();
    samples.iter().for_each(|q| arc.push(q));
    let m = grid.len() as u32;
    let mut b = PathBuilder::new(grid, m, arc.length()).unwrap();
    samples.iter().for_each(|q| b.push(q));
    let path = b.finish().unwrap();
    let limits = Limits::new(qd, qdd, 1.0).unwrap();
    let profile = retime::solve(grid, &path, &limits).unwrap();
    let mut stream = Stream::new(&profile, 0.01).unwrap();
    let (mut rq, mut ra) = (0.0f64, 0.0f64);
    while let Some(sp) = stream.next(grid) {
        for j in 0..4 {
            rq = rq.max(sp.qd[j].abs() / qd[j]);
            ra = ra.max(sp.qdd[j].abs() / qdd[j]);
        }
    }
    (profile.duration(), rq, ra)
}

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(20_261_202),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config(256))]

    /// Any valid path and limits: no written setpoint exceeds a limit by more than 0.5 %,
    /// and loosening the limits never lengthens the motion.
    /// Verifies RL-RETIME-004.
    #[test]
    fn looser_limits_never_slower_and_limits_hold(
        c in prop::array::uniform9(-1.5f64..1.5),
        qd in prop::array::uniform4(0.05f64..2.0),
        qdd in prop::array::uniform4(0.02f64..5.0),
        loosen_v in 1.0f64..3.0,
        loosen_a in 1.0f64..3.0,
    ) {
        let samples = random_path(&c, 400);
        let mut grid = vec![GridPoint::<4>::ZERO; 800];
        let (t, rq, ra) = solve_path(&samples, &mut grid, qd, qdd);
        prop_assert!(rq <= TOL, "rate ratio {}", rq);
        prop_assert!(ra <= TOL, "acceleration ratio {}", ra);
        let (t_loose, rq2, ra2) = solve_path(
            &samples,
            &mut grid,
            qd.map(|v| v * loosen_v),
            qdd.map(|a| a * loosen_a),
        );
        prop_assert!(t_loose <= t * (1.0 + 1e-12), "{} > {}", t_loose, t);
        prop_assert!(rq2 <= TOL && ra2 <= TOL);
    }
}

/// Spec §11's limits on what is written: the largest `|q(τ+1) − q(τ)|/dt` and
/// `|q(τ+1) − 2q(τ) + q(τ−1)|/dt²` over their limits, computed here from the written q
/// alone, independently of `retime::WrittenCheck`.
fn written_ratios<const N: usize>(qs: &[[f64; N]], dt: f64, limits: &Limits<N>) -> (f64, f64) {
    let (mut rv, mut ra) = (0.0f64, 0.0f64);
    for w in qs.windows(2) {
        for (j, v) in limits.qd_max().iter().enumerate() {
            rv = rv.max((w[1][j] - w[0][j]).abs() / dt / v);
        }
    }
    for w in qs.windows(3) {
        for (j, a) in limits.qdd_max().iter().enumerate() {
            ra = ra.max((w[2][j] - 2.0 * w[1][j] + w[0][j]).abs() / (dt * dt) / a);
        }
    }
    (rv, ra)
}

/// The reference plan at 0.5 … 10 °/s²: what is written keeps every limit by spec §11's
/// definition, and the motion is as long as the continuous optimum (no tightening was
/// needed), within 1 % in any case.
/// Verifies RL-RETIME-006.
#[test]
fn the_reference_plan_writes_within_its_limits_at_no_cost() {
    let task = reference::paper_task().unwrap();
    let qd = task.robot().desc().joints.map(|j| j.velocity);
    for accel in [0.5, 1.0, 2.0, 5.0, 10.0] {
        let mut grid = vec![GridPoint::<7>::ZERO; retime::DEFAULT_GRID as usize];
        let path =
            retime::path_of_rollout(&task, &reference::ETA_HAT, &mut grid, retime::DEFAULT_GRID)
                .unwrap();
        let limits = Limits::new(qd, [f64::to_radians(accel); 7], 1.0).unwrap();
        let continuous = retime::solve(&mut grid, &path, &limits).unwrap().duration();
        let (profile, w) = retime::solve_written(&mut grid, &path, &limits, 0.01).unwrap();
        println!(
            "{accel} deg/s^2: {:.4} s (continuous {continuous:.4} s), written rate {:.5}, acceleration {:.6}",
            profile.duration(),
            w.rate,
            w.accel
        );
        assert!(w.within(), "{w:?}");
        assert!(profile.duration() <= continuous * 1.01);
    }
}

proptest! {
    #![proptest_config(config(24))]

    /// Random plans (any η of the reference task, its rollout as the path) under random
    /// acceleration limits, margins and grids: the setpoints `solve_written` streams keep
    /// every rate and acceleration limit on the written q by spec §11's definition,
    /// exactly (≤ 1, not within a tolerance), and the ratios it reports are those.
    /// Verifies RL-RETIME-006.
    #[test]
    fn written_samples_keep_the_limits(
        eta in prop::array::uniform8(-1.0f64..1.0),
        accel_deg in 0.3f64..20.0,
        margin in 0.5f64..1.0,
        m in 300u32..2500,
    ) {
        let task = reference::paper_task().unwrap();
        let eta = [[eta[0], eta[1]], [eta[2], eta[3]], [eta[4], eta[5]], [eta[6], eta[7]]];
        prop_assume!(eta.iter().flatten().any(|v| v.abs() > 1e-3));
        let mut grid = vec![GridPoint::<7>::ZERO; m as usize];
        let path = retime::path_of_rollout(&task, &eta, &mut grid, m).unwrap();
        let qd = task.robot().desc().joints.map(|j| j.velocity);
        let limits = Limits::new(qd, [accel_deg.to_radians(); 7], margin).unwrap();
        let (profile, measured) = retime::solve_written(&mut grid, &path, &limits, 0.01).unwrap();
        let mut stream = Stream::new(&profile, 0.01).unwrap();
        let mut qs = Vec::new();
        while let Some(sp) = stream.next(&grid) {
            qs.push(sp.q);
        }
        let (rv, ra) = written_ratios(&qs, 0.01, &limits);
        prop_assert!(rv <= 1.0, "rate ratio {}", rv);
        prop_assert!(ra <= 1.0, "acceleration ratio {}", ra);
        prop_assert_eq!((rv, ra), (measured.rate, measured.accel));
    }

    /// The same on random smooth 4-joint paths under random rate and acceleration limits.
    /// Verifies RL-RETIME-006.
    #[test]
    fn written_samples_keep_the_limits_on_random_paths(
        c in prop::array::uniform9(-1.5f64..1.5),
        qd in prop::array::uniform4(0.05f64..2.0),
        qdd in prop::array::uniform4(0.02f64..5.0),
    ) {
        let samples = random_path(&c, 400);
        let mut grid = vec![GridPoint::<4>::ZERO; 800];
        let mut arc = ArcLength::new();
        samples.iter().for_each(|q| arc.push(q));
        let mut b = PathBuilder::new(&mut grid, 800, arc.length()).unwrap();
        samples.iter().for_each(|q| b.push(q));
        let path = b.finish().unwrap();
        let limits = Limits::new(qd, qdd, 1.0).unwrap();
        let (profile, _) = retime::solve_written(&mut grid, &path, &limits, 0.01).unwrap();
        let mut stream = Stream::new(&profile, 0.01).unwrap();
        let mut qs = Vec::new();
        while let Some(sp) = stream.next(&grid) {
            qs.push(sp.q);
        }
        let (rv, ra) = written_ratios(&qs, 0.01, &limits);
        prop_assert!(rv <= 1.0 && ra <= 1.0, "rate {} acceleration {}", rv, ra);
    }
}
