//! Measurement (fixed start, no pre-shaping): does a motion made of S consecutive
//! reactionless segments reach targets that one segment cannot?
//!
//! ```sh
//! cargo run --release -p host-sim --features research --example segments -- --segments 1,2,3 --seeds 1..3 \
//!     tests/tasks/fixed/ref/1cm/*.toml
//! ```
//!
//! Options: `--segments 1,2,3` (S values), `--seeds 1..3`, `--budget 8040` (units),
//! `--split 0.3,0.7` (unequal segment durations, fractions of t_f), `--no-broyden`,
//! `--paper` (paper family for every segment instead of the free amplitude), `--sv`
//! (misses: singular values of the 6 × S·2K pose Jacobian at the best point, not counted in
//! the budget), `--truth` (converged runs: the chained motion through the truth model: base
//! rotation and truth pose error), `--svrand M` (only: σ₅/σ₁, σ₆/σ₁ of the pose Jacobian at M
//! random screening points per task and S).
//!
//! **Chain.** The task's `[0, t_f]` is cut into S segments (durations multiples of `dt`,
//! equal unless `--split`), each its own [`Task`] (the task's robot, target and family, the
//! segment's duration). Segment 1 starts at the task's `q0`; segment `k + 1` is the
//! segment task with [`Task::move_start`] to segment `k`'s `q_final`, which keeps the system
//! CoM of `t = 0` (exact in the planner model: the base never rotates and its position
//! follows from the CoM) and the target. Every segment is at rest at both ends (β vanishes
//! at 0 and its `t_f`), so the chain is continuous in `q` and `q̇`. The unknowns are the S
//! segments' η side by side (`S·2K`); the pose error is the last segment's against the
//! target; Φ is the violation of the extrema over all segments.
//!
//! **Search.** The planner's multistart LM (src/search/multistart.rs), re-done with dense
//! host maths on `S·2K` ambient unknowns: residual `[e; w·p]` (w = 1, margin 0.005 rad),
//! forward-difference Jacobian (h = 1e-7), Nielsen damping, Broyden rank-1 updates with a
//! rebuild after 2 rejections (`--no-broyden`: rebuild after every accepted step), screening
//! batches of 8 random points (each segment's 2K components uniform in [−1, 1], normalised
//! per segment) of which the best 2 are started, patience `2·C + 8` units while ‖r‖ > 0.05
//! and `4·C + 8` after (C = the cost of one Jacobian). Random numbers: splitmix64 seeded
//! with the run seed (not the planner's stream, so S = 1 is not bit-identical to `host-sim
//! plan`). Stops at the first evaluated chain (any kind) with f ≤ 1e-6 and Φ = 0.
//!
//! **Cost** in full-rollout units: rolling out a segment costs its share of the task's
//! steps. A difference along segment k's η re-rolls segments k..S only (the earlier ones are
//! those of the base point), so a Jacobian costs `2K·Σ_k (steps of k..S)/steps`
//! (`2K(S+1)/2` for equal segments).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    clippy::too_many_lines,
    clippy::cast_possible_truncation,
    clippy::cast_precision_loss,
    clippy::cast_sign_loss,
    missing_docs
)]

use host_sim::args::parse_seeds;
use host_sim::taskfile;
use nalgebra::SMatrix;
use reactionless::{Family, Motion, Outcome, Sample, Sink, TRUTH_SUBSTEPS, Task, TruthState};
use std::path::PathBuf;
use std::time::Instant;

const N: usize = 7;
const K: usize = 4;
const P: usize = 2 * K;
const TOL: f64 = 1e-6;
const SIGMA_E: f64 = 0.05;
const FD_STEP: f64 = 1e-7;
const LAMBDA0: f64 = 1e-3;
const LAMBDA_MAX: f64 = 1e10;
const LAMBDA_MIN: f64 = 1e-15;
const PENALTY_W: f64 = 1.0;
const MARGIN: f64 = 0.005;
const SCREEN: usize = 8;
const STARTS_PER_SCREEN: usize = 2;
const SHRINK: f64 = 0.5;

/// splitmix64.
struct Rng(u64);
impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn pairs(x: &[f64]) -> [[f64; 2]; K] {
    let mut e = [[0.0; 2]; K];
    for (p, c) in e.iter_mut().zip(x.chunks_exact(2)) {
        *p = [c[0], c[1]];
    }
    e
}

/// Feeds one segment's samples (time shifted by the segment's start) into a truth model
/// state shared by the whole chain; the first sample of a later segment repeats the last
/// one of the previous segment and is skipped.
struct ChainTruth<'a> {
    state: &'a mut TruthState<N>,
    task: &'a Task<N, K>,
    offset: f64,
    skip_first: bool,
}

impl Sink<N> for ChainTruth<'_> {
    fn sample(&mut self, s: &Sample<N>) {
        if self.skip_first && s.step == 0 {
            return;
        }
        self.state.push(self.task, &s.q, s.t + self.offset);
    }
}

/// The chain of `x` through the truth model: (largest base rotation (deg), truth pose
/// error position (m), orientation (deg)).
fn truth_check(segs: &[Task<N, K>], x: &[f64]) -> Option<(f64, f64, f64)> {
    let mut state = TruthState::<N>::new(TRUTH_SUBSTEPS);
    let mut q = *segs[0].start();
    let mut offset = 0.0;
    for (k, seg) in segs.iter().enumerate() {
        let mut t = seg.clone();
        if k > 0 {
            t.move_start(&q).ok()?;
        }
        let mut sink = ChainTruth {
            state: &mut state,
            task: &t,
            offset,
            skip_first: k > 0,
        };
        let o = t.rollout(&pairs(&x[P * k..P * (k + 1)]), &mut sink).ok()?;
        q = o.q_final;
        offset += t.motion().tf();
    }
    let end = state.end_pose(&segs[0])?;
    let e = end.error_to(segs[0].target());
    Some((
        state.max_angle().to_degrees(),
        e.position_m(),
        e.orientation_deg(),
    ))
}

/// One evaluated chain.
#[derive(Clone)]
struct Eval {
    outs: Vec<Outcome<N>>,
    r: Vec<f64>,
    merit: f64,
    f: f64,
    phi: f64,
}

impl Eval {
    fn last(&self) -> &Outcome<N> {
        self.outs.last().unwrap()
    }
}

struct Chain {
    segs: Vec<Task<N, K>>,
    /// Cost of rolling out segments `k..S`, in full-rollout units.
    tail_cost: Vec<f64>,
    lower: [f64; N],
    upper: [f64; N],
    units: f64,
    budget: f64,
    converged_at: Option<f64>,
    best: Option<(Vec<f64>, Eval)>,
    starts: u32,
    jacobians: u32,
    failed: u32,
}

impl Chain {
    fn s(&self) -> usize {
        self.segs.len()
    }
    fn dim(&self) -> usize {
        P * self.s()
    }
    fn done(&self) -> bool {
        self.converged_at.is_some() || self.units >= self.budget
    }

    /// Evaluates `x`, re-using segments `0..from` of `base`.
    fn eval(&mut self, x: &[f64], base: Option<&Eval>, from: usize) -> Option<Eval> {
        let s = self.s();
        let mut outs: Vec<Outcome<N>> = match base {
            Some(b) => b.outs[..from].to_vec(),
            None => Vec::new(),
        };
        let from = outs.len();
        self.units += self.tail_cost[from];
        for k in from..s {
            let mut t = self.segs[k].clone();
            if k > 0 && t.move_start(&outs[k - 1].q_final).is_err() {
                self.failed += 1;
                return None;
            }
            match t.rollout(&pairs(&x[P * k..P * (k + 1)]), &mut ()) {
                Ok(o) => outs.push(o),
                Err(_) => {
                    self.failed += 1;
                    return None;
                }
            }
        }
        let mut mn = self.lower.map(|_| f64::INFINITY);
        let mut mx = self.lower.map(|_| f64::NEG_INFINITY);
        for o in &outs {
            for j in 0..N {
                mn[j] = mn[j].min(o.joint_min[j]);
                mx[j] = mx[j].max(o.joint_max[j]);
            }
        }
        let phi = self.segs[0].robot().violation(&mn, &mx);
        let last = outs.last().unwrap();
        let mut r: Vec<f64> = last.error.to_array().to_vec();
        for j in 0..N {
            r.push(
                PENALTY_W
                    * ((mx[j] - (self.upper[j] - MARGIN)).max(0.0)
                        + ((self.lower[j] + MARGIN) - mn[j]).max(0.0)),
            );
        }
        let merit = r.iter().map(|v| v * v).sum();
        let e = Eval {
            f: last.f,
            outs,
            r,
            merit,
            phi,
        };
        if !e.f.is_finite() {
            return None;
        }
        let better = match &self.best {
            None => true,
            Some((_, b)) => match (phi == 0.0, b.phi == 0.0) {
                (true, true) => e.f < b.f,
                (true, false) => true,
                (false, true) => false,
                (false, false) => phi < b.phi,
            },
        };
        if better {
            self.best = Some((x.to_vec(), e.clone()));
        }
        if phi == 0.0 && e.f <= TOL && self.converged_at.is_none() {
            self.converged_at = Some(self.units);
        }
        Some(e)
    }

    /// Forward-difference Jacobian of the residual at `x` (rows × dim, row-major).
    fn jacobian(&mut self, x: &[f64], e: &Eval) -> Vec<Vec<f64>> {
        let d = self.dim();
        let rows = e.r.len();
        let mut j = vec![vec![0.0; d]; rows];
        self.jacobians += 1;
        for c in 0..d {
            if self.done() {
                break;
            }
            let mut xp = x.to_vec();
            xp[c] += FD_STEP;
            if let Some(ep) = self.eval(&xp, Some(e), c / P) {
                for (row, (a, b)) in j.iter_mut().zip(ep.r.iter().zip(e.r.iter())) {
                    row[c] = (a - b) / FD_STEP;
                }
            }
        }
        j
    }

    fn jac_cost(&self) -> f64 {
        (0..self.s())
            .map(|k| P as f64 * (self.tail_cost[k] - self.tail_cost[k + 1]) * (k + 1) as f64)
            .sum()
    }

    /// One LM start from `(x, e)`; returns when it stalls, the goal is met, or the budget is spent.
    fn lm(&mut self, mut x: Vec<f64>, mut e: Eval, broyden: bool) {
        self.starts += 1;
        let d = self.dim();
        let c = self.jac_cost();
        let patience = 2.0 * c + 8.0;
        let refine_patience = 4.0 * c + 8.0;
        let mut lambda = LAMBDA0;
        let mut nu = 2.0;
        let mut jac = self.jacobian(&x, &e);
        let mut stale = 0u32;
        let mut rejects = 0u32;
        let mut ref_merit = e.merit;
        let mut ref_units = self.units;
        loop {
            if self.done() {
                return;
            }
            let limit = if e.merit <= SIGMA_E * SIGMA_E {
                refine_patience
            } else {
                patience
            };
            if self.units - ref_units > limit {
                return;
            }
            // Step.
            let step = if lambda > LAMBDA_MAX {
                None
            } else {
                lm_step(&jac, &e.r, lambda, d)
            };
            let Some((delta, predicted)) = step else {
                if stale > 0 {
                    lambda = LAMBDA0;
                    nu = 2.0;
                    jac = self.jacobian(&x, &e);
                    stale = 0;
                    rejects = 0;
                    continue;
                }
                return;
            };
            let trial: Vec<f64> = x.iter().zip(&delta).map(|(a, b)| a + b).collect();
            let et = self.eval(&trial, None, 0);
            if self.done() {
                return;
            }
            let mut accepted = false;
            if let Some(et) = et {
                if broyden {
                    let ss: f64 = delta.iter().map(|v| v * v).sum();
                    if ss > 0.0 {
                        for (row, (a, b)) in jac.iter_mut().zip(et.r.iter().zip(e.r.iter())) {
                            let js: f64 = row.iter().zip(&delta).map(|(p, q)| p * q).sum();
                            let k = ((a - b) - js) / ss;
                            for (jv, dv) in row.iter_mut().zip(&delta) {
                                *jv += k * dv;
                            }
                        }
                    }
                    stale += 1;
                }
                if et.merit < e.merit {
                    accepted = true;
                    let pred = e.merit - predicted;
                    let rho = if pred > 0.0 {
                        (e.merit - et.merit) / pred
                    } else {
                        0.0
                    };
                    let t = 2.0 * rho - 1.0;
                    lambda = (lambda * (1.0 - t * t * t).max(1.0 / 3.0)).max(LAMBDA_MIN);
                    nu = 2.0;
                    rejects = 0;
                    x = trial;
                    e = et;
                    if e.merit.sqrt() <= SHRINK * ref_merit.sqrt() {
                        ref_merit = e.merit;
                        ref_units = self.units;
                    }
                }
            }
            if accepted {
                if !broyden {
                    jac = self.jacobian(&x, &e);
                }
                continue;
            }
            lambda *= nu;
            nu *= 2.0;
            rejects += 1;
            if broyden && stale > 0 && rejects >= 2 {
                jac = self.jacobian(&x, &e);
                stale = 0;
                rejects = 0;
            }
        }
    }

    fn solve(&mut self, rng: &mut Rng, broyden: bool) {
        let d = self.dim();
        let s = self.s();
        while !self.done() {
            let mut pool: Vec<(f64, Vec<f64>, Eval)> = Vec::new();
            for _ in 0..SCREEN {
                let mut x: Vec<f64> = (0..d).map(|_| 2.0 * rng.uniform() - 1.0).collect();
                for k in 0..s {
                    let seg = &mut x[P * k..P * (k + 1)];
                    let n = seg.iter().map(|v| v * v).sum::<f64>().sqrt();
                    seg.iter_mut().for_each(|v| *v /= n);
                }
                if let Some(e) = self.eval(&x, None, 0) {
                    pool.push((e.merit, x, e));
                }
                if self.done() {
                    return;
                }
            }
            pool.sort_by(|a, b| a.0.total_cmp(&b.0));
            for (_, x, e) in pool.into_iter().take(STARTS_PER_SCREEN) {
                self.lm(x, e, broyden);
                if self.done() {
                    return;
                }
            }
        }
    }
}

/// LM step `(JᵀJ + λ d_max I) δ = −Jᵀ r`; returns δ and the predicted ‖r + Jδ‖².
fn lm_step(j: &[Vec<f64>], r: &[f64], lambda: f64, d: usize) -> Option<(Vec<f64>, f64)> {
    let mut a = vec![vec![0.0; d]; d];
    let mut g = vec![0.0; d];
    for (row, ri) in j.iter().zip(r) {
        for i in 0..d {
            g[i] -= row[i] * ri;
            for k in 0..d {
                a[i][k] += row[i] * row[k];
            }
        }
    }
    let dmax = (0..d).map(|i| a[i][i]).fold(0.0f64, f64::max);
    if !(dmax > 0.0 && dmax.is_finite()) {
        return None;
    }
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += lambda * dmax;
    }
    let delta = cholesky_solve(a, g)?;
    let norm = delta.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(norm >= 1e-15 && norm.is_finite()) {
        return None;
    }
    let predicted = j
        .iter()
        .zip(r)
        .map(|(row, ri)| {
            let v = ri + row.iter().zip(&delta).map(|(p, q)| p * q).sum::<f64>();
            v * v
        })
        .sum();
    Some((delta, predicted))
}

fn cholesky_solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for i in 0..n {
        for k in 0..i {
            let s: f64 = (0..k).map(|m| a[i][m] * a[k][m]).sum();
            a[i][k] = (a[i][k] - s) / a[k][k];
        }
        let s: f64 = (0..i).map(|m| a[i][m] * a[i][m]).sum();
        let v = a[i][i] - s;
        if !(v > 0.0 && v.is_finite()) {
            return None;
        }
        a[i][i] = v.sqrt();
    }
    for i in 0..n {
        let s: f64 = (0..i).map(|m| a[i][m] * b[m]).sum();
        b[i] = (b[i] - s) / a[i][i];
    }
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|m| a[m][i] * b[m]).sum();
        b[i] = (b[i] - s) / a[i][i];
    }
    Some(b)
}

struct Opts {
    segments: Vec<usize>,
    seeds: Vec<u64>,
    budget: f64,
    broyden: bool,
    split: Option<Vec<f64>>,
    family: Family,
    sv: bool,
    truth: bool,
    svrand: usize,
    tasks: Vec<PathBuf>,
}

fn parse() -> Opts {
    let mut o = Opts {
        segments: vec![1, 2, 3],
        seeds: vec![1, 2, 3],
        budget: 8040.0,
        broyden: true,
        split: None,
        family: Family::FreeAmplitude,
        sv: false,
        truth: false,
        svrand: 0,
        tasks: Vec::new(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--segments" => {
                o.segments = it
                    .next()
                    .unwrap()
                    .split(',')
                    .map(|s| s.parse().unwrap())
                    .collect();
            }
            "--seeds" => o.seeds = parse_seeds(&it.next().unwrap()).unwrap(),
            "--budget" => o.budget = it.next().unwrap().parse().unwrap(),
            "--no-broyden" => o.broyden = false,
            "--paper" => o.family = Family::Paper,
            "--sv" => o.sv = true,
            "--truth" => o.truth = true,
            "--svrand" => o.svrand = it.next().unwrap().parse().unwrap(),
            "--split" => {
                o.split = Some(
                    it.next()
                        .unwrap()
                        .split(',')
                        .map(|s| s.parse().unwrap())
                        .collect(),
                );
            }
            _ => o.tasks.push(PathBuf::from(a)),
        }
    }
    o
}

/// Segment step counts: equal shares (or `split`'s fractions) of `steps`, summing to it.
fn segment_steps(steps: u32, s: usize, split: Option<&Vec<f64>>) -> Vec<u32> {
    let fr: Vec<f64> = match split {
        Some(v) if v.len() == s => {
            let t: f64 = v.iter().sum();
            v.iter().map(|x| x / t).collect()
        }
        _ => vec![1.0 / s as f64; s],
    };
    let mut out = Vec::new();
    let mut acc = 0.0;
    let mut used = 0u32;
    for f in &fr {
        acc += f;
        let end = (acc * f64::from(steps)).round() as u32;
        out.push(end - used);
        used = end;
    }
    out
}

struct Run {
    task: String,
    seed: u64,
    converged_at: Option<f64>,
    pos_m: f64,
    deg: f64,
    f: f64,
    phi: f64,
    detail: String,
}

fn build_chain(task: &Task<N, K>, s: usize, opts: &Opts) -> Chain {
    let m = task.motion();
    let steps = segment_steps(m.steps(), s, opts.split.as_ref());
    let mut segs = Vec::new();
    for &st in &steps {
        let motion = Motion::new(f64::from(st) * m.dt(), m.dt(), m.degree())
            .unwrap()
            .with_family(opts.family);
        let t = Task::new(task.robot().clone(), *task.start(), *task.target(), motion).unwrap();
        assert_eq!(t.target(), task.target());
        assert_eq!(t.com0(), task.com0());
        segs.push(t);
    }
    let total = f64::from(m.steps());
    let mut tail_cost = vec![0.0; s + 1];
    for k in (0..s).rev() {
        tail_cost[k] = tail_cost[k + 1] + f64::from(steps[k]) / total;
    }
    Chain {
        lower: *task.robot().lower(),
        upper: *task.robot().upper(),
        segs,
        tail_cost,
        units: 0.0,
        budget: opts.budget,
        converged_at: None,
        best: None,
        starts: 0,
        jacobians: 0,
        failed: 0,
    }
}

/// Singular values (descending) of the 6 × S·2K pose Jacobian at `x`, and the residual's
/// Jacobian.
fn pose_svs(chain: &mut Chain, x: &[f64], e: &Eval) -> (Vec<f64>, Vec<Vec<f64>>) {
    let j = chain.jacobian(x, e);
    let mut jjt = SMatrix::<f64, 6, 6>::zeros();
    for a in 0..6 {
        for b in 0..6 {
            jjt[(a, b)] = j[a].iter().zip(&j[b]).map(|(p, q)| p * q).sum();
        }
    }
    let mut ev: Vec<f64> = jjt
        .symmetric_eigenvalues()
        .iter()
        .map(|v| v.max(0.0).sqrt())
        .collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    (ev, j)
}

/// `--svrand M`: σ₅/σ₁ and σ₆/σ₁ of the pose Jacobian at M random screening points.
fn svrand(task: &Task<N, K>, s: usize, opts: &Opts) -> Vec<[f64; 2]> {
    let mut chain = build_chain(task, s, opts);
    chain.budget = f64::INFINITY;
    let mut rng = Rng(12345);
    let d = chain.dim();
    let mut out = Vec::new();
    while out.len() < opts.svrand {
        let mut x: Vec<f64> = (0..d).map(|_| 2.0 * rng.uniform() - 1.0).collect();
        for k in 0..s {
            let seg = &mut x[P * k..P * (k + 1)];
            let n = seg.iter().map(|v| v * v).sum::<f64>().sqrt();
            seg.iter_mut().for_each(|v| *v /= n);
        }
        let Some(e) = chain.eval(&x, None, 0) else {
            continue;
        };
        let (sv, _) = pose_svs(&mut chain, &x, &e);
        out.push([sv[4] / sv[0], sv[5] / sv[0]]);
    }
    out
}

fn run_one(task: &Task<N, K>, name: &str, s: usize, seed: u64, opts: &Opts) -> Run {
    let m = task.motion();
    let mut chain = build_chain(task, s, opts);
    let mut rng = Rng(seed);
    chain.solve(&mut rng, opts.broyden);
    let (bx, be) = chain.best.clone().expect("no evaluated chain");
    let last = be.last();
    let qd_max = task.robot().qd_max();
    // Per segment: g/G₀ (> 1: the rate bound binds) and max|q̇|/q̇max.
    let mut seg_info = Vec::new();
    for (k, o) in be.outs.iter().enumerate() {
        let tf = chain.segs[k].motion().tf();
        let g0 = tf.powi(m.degree() as i32 + 2) / (4.0 * qd_max);
        let amp: f64 = bx[P * k..P * (k + 1)]
            .iter()
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt();
        seg_info.push(format!(
            "g/G0 {:.2} qd {:.0}% |eta| {:.2}",
            o.g / g0,
            100.0 * o.max_abs_qd / qd_max,
            amp
        ));
    }
    let mut margin = f64::INFINITY;
    for o in &be.outs {
        for j in 0..N {
            margin = margin
                .min(o.joint_min[j] - chain.lower[j])
                .min(chain.upper[j] - o.joint_max[j]);
        }
    }
    let mut detail = format!(
        "starts {} jac {} fail {} | margin {:.2} deg | {}",
        chain.starts,
        chain.jacobians,
        chain.failed,
        margin.to_degrees(),
        seg_info.join("; ")
    );
    if chain.converged_at.is_some() && opts.truth {
        if let Some((base, pm, deg)) = truth_check(&chain.segs, &bx) {
            detail.push_str(&format!(
                " | truth: base {base:.2e} deg, pose {pm:.1e} m {deg:.1e} deg"
            ));
        }
    }
    if opts.sv && chain.converged_at.is_none() {
        // Singular values of the 6 × S·2K pose Jacobian at the best point (not counted).
        chain.budget = f64::INFINITY;
        let (ev, j) = pose_svs(&mut chain, &bx, &be);
        let evs: Vec<String> = ev.iter().map(|v| format!("{v:.1e}")).collect();
        // Gradient norm ‖Jᵀe‖ relative to ‖J‖‖e‖: ~0 at a stationary point of f.
        let e6 = &be.r[..6];
        let g: f64 = (0..chain.dim())
            .map(|c| (0..6).map(|a| j[a][c] * e6[a]).sum::<f64>().powi(2))
            .sum::<f64>()
            .sqrt();
        let en: f64 = e6.iter().map(|v| v * v).sum::<f64>().sqrt();
        detail.push_str(&format!(
            " | sv [{}] |J^T e|/(s1|e|) {:.1e}",
            evs.join(" "),
            g / (ev[0] * en)
        ));
    }
    Run {
        task: name.to_string(),
        seed,
        converged_at: chain.converged_at,
        pos_m: last.error.position_m(),
        deg: last.error.orientation_deg(),
        f: be.f,
        phi: be.phi,
        detail,
    }
}

fn main() {
    let opts = parse();
    let loaded: Vec<(String, Task<N, K>)> = opts
        .tasks
        .iter()
        .map(|p| {
            let lt = taskfile::load(p).unwrap();
            let name = format!(
                "{}/{}",
                p.parent()
                    .and_then(|d| d.file_name())
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                p.file_stem().unwrap().to_string_lossy()
            );
            (name, lt.task::<N, K>().unwrap())
        })
        .collect();
    println!(
        "family {:?}, broyden {}, budget {}, split {:?}",
        opts.family, opts.broyden, opts.budget, opts.split
    );
    if opts.svrand > 0 {
        for &s in &opts.segments {
            let mut all: Vec<[f64; 2]> = Vec::new();
            for (name, task) in &loaded {
                let v = svrand(task, s, &opts);
                let mut a: Vec<f64> = v.iter().map(|p| p[0]).collect();
                let mut b: Vec<f64> = v.iter().map(|p| p[1]).collect();
                a.sort_by(f64::total_cmp);
                b.sort_by(f64::total_cmp);
                println!(
                    "S={s} {name:<10} random points: median s5/s1 {:.1e} s6/s1 {:.1e} (min s6/s1 {:.1e}, max {:.1e})",
                    a[a.len() / 2],
                    b[b.len() / 2],
                    b[0],
                    b[b.len() - 1]
                );
                all.extend(v);
            }
            let mut a: Vec<f64> = all.iter().map(|p| p[0]).collect();
            let mut b: Vec<f64> = all.iter().map(|p| p[1]).collect();
            a.sort_by(f64::total_cmp);
            b.sort_by(f64::total_cmp);
            println!(
                "S={s} all: median s5/s1 {:.1e} s6/s1 {:.1e}",
                a[a.len() / 2],
                b[b.len() / 2]
            );
        }
        return;
    }
    let mut summary = Vec::new();
    for &s in &opts.segments {
        let t0 = Instant::now();
        let mut runs = Vec::new();
        for (name, task) in &loaded {
            for &seed in &opts.seeds {
                let t1 = Instant::now();
                let r = run_one(task, name, s, seed, &opts);
                println!(
                    "S={s} {:<10} seed {} {:>9} f {:.2e} pos {:.3e} m {:.2e} deg phi {:.1e} | {} | {:.1} s",
                    r.task,
                    r.seed,
                    match r.converged_at {
                        Some(u) => format!("{u:.0}"),
                        None => "miss".into(),
                    },
                    r.f,
                    r.pos_m,
                    r.deg,
                    r.phi,
                    r.detail,
                    t1.elapsed().as_secs_f64()
                );
                runs.push(r);
            }
        }
        let mut conv: Vec<f64> = runs.iter().filter_map(|r| r.converged_at).collect();
        conv.sort_by(f64::total_cmp);
        let med = if conv.is_empty() {
            f64::NAN
        } else if conv.len() % 2 == 1 {
            conv[conv.len() / 2]
        } else {
            0.5 * (conv[conv.len() / 2 - 1] + conv[conv.len() / 2])
        };
        let misses: Vec<String> = runs
            .iter()
            .filter(|r| r.converged_at.is_none())
            .map(|r| {
                format!(
                    "{}#{} {:.2} mm {:.3} deg",
                    r.task,
                    r.seed,
                    r.pos_m * 1e3,
                    r.deg
                )
            })
            .collect();
        let line = format!(
            "S={s}: {}/{} converged; units median {:.0}, range {:.0}..{:.0}; {:.0} s; misses: {}",
            conv.len(),
            runs.len(),
            med,
            conv.first().copied().unwrap_or(f64::NAN),
            conv.last().copied().unwrap_or(f64::NAN),
            t0.elapsed().as_secs_f64(),
            if misses.is_empty() {
                "none".into()
            } else {
                misses.join(", ")
            }
        );
        println!("{line}");
        summary.push(line);
    }
    println!("\n== summary ==");
    for l in summary {
        println!("{l}");
    }
}
