//! Closed-loop flight, a measurement before a design (issue #31): how far can feedback alone
//! (star tracker, gyro and encoders of spec §12, 10 Hz, one period of latency) keep the
//! base still and bring the end effector to the target, when the plan is flown on a robot
//! whose mass properties differ from the planner's model?
//!
//! ```sh
//! cargo run --release -p host-sim --features research --example closedloop -- \
//!     out/paper --samples 200 --seed 1 [--extend-s 3] [--theta-scale-deg 0.0005] \
//!     [--dq-scale-deg 1] [--rate-scale-deg-s 0.1] [--noise 1]
//! ```
//! The directory is a plan's (`host-sim plan`). The robots are `disperse`'s for the same
//! seed (5 % mass, 10 % inertia, 1 cm CoM, 1σ: the README's dispersion), the sensors
//! `[sensors]`' defaults, scaled by `--noise`. Three laws fly each sample, the plan's own
//! 100 Hz setpoints plus a correction rate held over each control cycle:
//!
//! - `open`: no correction (the open-loop flight of `disperse`);
//! - `base`: base-attitude feedback through the arm, `c = k B⁺ θ̂` with `B = H̃b⁻¹H̃bm`
//!   (the issue's first prototype law), k = 2 s⁻¹;
//! - `lqr`: a time-varying LQR along the plan on the planner's (nominal) model. State: the
//!   joint deviation from the plan δq, the base attitude θ and the pending command (the
//!   latency), input: the next cycle's correction. Its linearisation keeps the term that
//!   makes the system controllable beyond the instantaneous range of `B`: how a deviation
//!   δq changes what the plan's own motion does to the base (`G_k`, finite differences of
//!   `∫ B(q_p + δq) q̇_p dt` over the cycle). Running cost on θ, δq and the input; terminal
//!   cost on the end-effector pose error (linearised), θ, and the command (at rest), after
//!   `--extend-s` of correction beyond t_f (the plan at rest).
//!
//! The attitude estimate: the gyro's increments, pulled toward each star-tracker reading by
//! a gain of 0.05 per cycle. Joint deviations come from the encoders. Commands are clipped
//! so that plan + correction stays within every joint's rate limit.
//!
//! Prints, per law: p50 / p95 / p99 / max of the base disturbance (deg, truth model, the
//! whole flight), the end-effector position (mm) and orientation (deg) errors at the end
//! of the flight, the extra joint travel (deg) and the largest correction (deg/s).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    clippy::too_many_lines,
    clippy::many_single_char_names,
    clippy::needless_range_loop,
    missing_docs
)]

use host_sim::artifacts::{read_bundle, read_output_file};
use host_sim::dispersion::{Draw, JointPath, Settings as Dispersion};
use host_sim::error::CliError;
use host_sim::sensors::{Sensors, Settings as SensorSettings};
use host_sim::taskfile::LoadedTask;
use host_sim::with_dims;
use reactionless::geometry::{Vec3, normalized, quat_exp, quat_log, quat_mul};
use reactionless::{Frames, Momentum, Robot};
use std::path::PathBuf;

struct Opts {
    dir: PathBuf,
    samples: u64,
    seed: u64,
    extend_s: f64,
    theta_scale: f64,
    dq_scale: f64,
    rate_scale: f64,
    noise: f64,
    base_gain: f64,
    alpha: f64,
    disp_scale: f64,
}

fn parse() -> Opts {
    let mut o = Opts {
        dir: PathBuf::new(),
        samples: 100,
        seed: 1,
        extend_s: 3.0,
        theta_scale: 0.0005f64.to_radians(),
        dq_scale: 1.0f64.to_radians(),
        rate_scale: 0.1f64.to_radians(),
        noise: 1.0,
        base_gain: 2.0,
        alpha: 0.05,
        disp_scale: 1.0,
    };
    let a: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < a.len() {
        let v = || a[i + 1].parse::<f64>().unwrap();
        match a[i].as_str() {
            "--samples" => o.samples = a[i + 1].parse().unwrap(),
            "--seed" => o.seed = a[i + 1].parse().unwrap(),
            "--extend-s" => o.extend_s = v(),
            "--theta-scale-deg" => o.theta_scale = v().to_radians(),
            "--dq-scale-deg" => o.dq_scale = v().to_radians(),
            "--rate-scale-deg-s" => o.rate_scale = v().to_radians(),
            "--noise" => o.noise = v(),
            "--base-gain" => o.base_gain = v(),
            "--alpha" => o.alpha = v(),
            "--dispersion" => o.disp_scale = v(),
            d => {
                o.dir = PathBuf::from(d);
                i += 1;
                continue;
            }
        }
        i += 2;
    }
    o
}

/// Row-major dense matrix.
#[derive(Clone, Debug)]
struct M {
    r: usize,
    c: usize,
    v: Vec<f64>,
}

impl M {
    fn zeros(r: usize, c: usize) -> Self {
        Self {
            r,
            c,
            v: vec![0.0; r * c],
        }
    }
    fn eye(n: usize) -> Self {
        let mut m = Self::zeros(n, n);
        for i in 0..n {
            m.v[i * n + i] = 1.0;
        }
        m
    }
    fn at(&self, i: usize, j: usize) -> f64 {
        self.v[i * self.c + j]
    }
    fn set(&mut self, i: usize, j: usize, x: f64) {
        self.v[i * self.c + j] = x;
    }
    fn mul(&self, b: &M) -> M {
        assert_eq!(self.c, b.r);
        let mut m = M::zeros(self.r, b.c);
        for i in 0..self.r {
            for k in 0..self.c {
                let a = self.at(i, k);
                if a == 0.0 {
                    continue;
                }
                for j in 0..b.c {
                    m.v[i * b.c + j] += a * b.v[k * b.c + j];
                }
            }
        }
        m
    }
    fn t(&self) -> M {
        let mut m = M::zeros(self.c, self.r);
        for i in 0..self.r {
            for j in 0..self.c {
                m.set(j, i, self.at(i, j));
            }
        }
        m
    }
    fn add(&self, b: &M) -> M {
        let mut m = self.clone();
        for (x, y) in m.v.iter_mut().zip(&b.v) {
            *x += y;
        }
        m
    }
    fn sub(&self, b: &M) -> M {
        let mut m = self.clone();
        for (x, y) in m.v.iter_mut().zip(&b.v) {
            *x -= y;
        }
        m
    }
    fn scale(&self, s: f64) -> M {
        let mut m = self.clone();
        m.v.iter_mut().for_each(|x| *x *= s);
        m
    }
    fn sym(&self) -> M {
        self.add(&self.t()).scale(0.5)
    }
    /// Solves self · X = b (Gaussian elimination with partial pivoting).
    fn solve(&self, b: &M) -> M {
        let n = self.r;
        let mut a = self.clone();
        let mut x = b.clone();
        for col in 0..n {
            let p = (col..n)
                .max_by(|&i, &j| a.at(i, col).abs().total_cmp(&a.at(j, col).abs()))
                .unwrap();
            for j in 0..n {
                a.v.swap(col * n + j, p * n + j);
            }
            for j in 0..x.c {
                x.v.swap(col * x.c + j, p * x.c + j);
            }
            let d = a.at(col, col);
            for i in col + 1..n {
                let f = a.at(i, col) / d;
                if f == 0.0 {
                    continue;
                }
                for j in col..n {
                    let v = a.at(i, j) - f * a.at(col, j);
                    a.set(i, j, v);
                }
                for j in 0..x.c {
                    let v = x.at(i, j) - f * x.at(col, j);
                    x.set(i, j, v);
                }
            }
        }
        for col in (0..n).rev() {
            let d = a.at(col, col);
            for j in 0..x.c {
                let mut s = x.at(col, j);
                for k in col + 1..n {
                    s -= a.at(col, k) * x.at(k, j);
                }
                x.set(col, j, s / d);
            }
        }
        x
    }
}

/// `B = H̃b⁻¹ H̃bm` at q (3 × N): the base rate per joint rate, θ̇ = −B q̇.
fn coupling<const N: usize>(robot: &Robot<N>, q: &[f64; N]) -> M {
    let m = Momentum::new(robot, &Frames::new(robot, q));
    let inv = m.hb.to_matrix().try_inverse().unwrap();
    let mut b = M::zeros(3, N);
    for (j, h) in m.hbm.iter().enumerate() {
        let col = inv * h;
        for i in 0..3 {
            b.set(i, j, col[i]);
        }
    }
    b
}

fn add<const N: usize>(a: &[f64; N], b: &[f64; N], s: f64) -> [f64; N] {
    core::array::from_fn(|i| a[i] + s * b[i])
}

/// End-effector pose error (position m, rotation vector rad) of configuration `q` with base
/// attitude `theta` against the pose at (q_ref, 0), base placed by CoM conservation.
fn ee_error<const N: usize>(
    robot: &Robot<N>,
    com0: &Vec3,
    q: &[f64; N],
    theta: &[f64; 3],
    reference: &reactionless::Pose,
) -> [f64; 6] {
    let p =
        Frames::new(robot, q).end_pose(com0, quat_exp(&Vec3::new(theta[0], theta[1], theta[2])));
    let e = p.error_to(reference);
    let (d, r) = (e.position, e.rotation);
    [d[0], d[1], d[2], r[0], r[1], r[2]]
}

/// The law's gains along the plan: K_k (N × (2N+3)) for every cycle.
#[allow(clippy::too_many_arguments)]
fn lqr<const N: usize>(
    robot: &Robot<N>,
    q0: &[f64; N],
    path: &[[f64; N]],
    per: usize,
    cycles: usize,
    tc: f64,
    o: &Opts,
) -> Lqr {
    let nz = 2 * N + 3;
    let (iq, it, ic) = (0, N, N + 3);
    let plan_cycles = (path.len() - 1) / per;
    let qf = path[path.len() - 1];
    let mut a_s = Vec::with_capacity(cycles);
    for k in 0..cycles {
        // G_k = ∂/∂δq ∫_cycle B(q_p + δq) q̇_p dt and the cycle's mean B.
        let (g, bbar) = if k < plan_cycles {
            let seg = &path[k * per..=(k + 1) * per];
            let integral = |d: &[f64; N]| {
                let mut s = [0.0; 3];
                for w in seg.windows(2) {
                    let mid: [f64; N] = core::array::from_fn(|i| 0.5 * (w[0][i] + w[1][i]) + d[i]);
                    let b = coupling(robot, &mid);
                    for i in 0..3 {
                        for j in 0..N {
                            s[i] += b.at(i, j) * (w[1][j] - w[0][j]);
                        }
                    }
                }
                s
            };
            let eps = 1e-6;
            let mut g = M::zeros(3, N);
            for j in 0..N {
                let mut e = [0.0; N];
                e[j] = eps;
                let p = integral(&e);
                e[j] = -eps;
                let m = integral(&e);
                for i in 0..3 {
                    g.set(i, j, (p[i] - m[i]) / (2.0 * eps));
                }
            }
            let mut bbar = M::zeros(3, N);
            for w in seg.windows(2) {
                let mid: [f64; N] = core::array::from_fn(|i| 0.5 * (w[0][i] + w[1][i]));
                bbar = bbar.add(&coupling(robot, &mid).scale(1.0 / per as f64));
            }
            (g, bbar)
        } else {
            (M::zeros(3, N), coupling(robot, &qf))
        };
        let mut a = M::eye(nz);
        for i in 0..N {
            a.set(iq + i, ic + i, tc);
            a.set(ic + i, ic + i, 0.0);
        }
        for i in 0..3 {
            for j in 0..N {
                a.set(it + i, iq + j, -g.at(i, j));
                a.set(it + i, ic + j, -tc * bbar.at(i, j));
            }
        }
        a_s.push(a);
    }
    // Costs, normalised per cycle.
    let mut q = M::zeros(nz, nz);
    for i in 0..N {
        q.set(
            iq + i,
            iq + i,
            1.0 / (o.dq_scale * o.dq_scale) / cycles as f64,
        );
    }
    for i in 0..3 {
        q.set(it + i, it + i, 1.0 / (o.theta_scale * o.theta_scale));
    }
    let r = M::eye(N).scale(1.0 / (o.rate_scale * o.rate_scale) / cycles as f64);
    // Terminal: the end-effector pose, linearised in (δq, θ) at the plan's end.
    let com0 = Frames::new(robot, q0).com;
    let reference = Frames::new(robot, &qf).end_pose(&com0, [1.0, 0.0, 0.0, 0.0]);
    let mut j = M::zeros(6, nz);
    let h = 1e-7;
    for c in 0..N + 3 {
        let mut dq = [0.0; N];
        let mut th = [0.0; 3];
        let eval = |dq: &[f64; N], th: &[f64; 3]| {
            ee_error(robot, &com0, &add(&qf, dq, 1.0), th, &reference)
        };
        if c < N {
            dq[c] = h;
        } else {
            th[c - N] = h;
        }
        let p = eval(&dq, &th);
        if c < N {
            dq[c] = -h;
        } else {
            th[c - N] = -h;
        }
        let m = eval(&dq, &th);
        for i in 0..6 {
            j.set(i, c, (p[i] - m[i]) / (2.0 * h));
        }
    }
    let mut w = M::zeros(6, 6);
    for i in 0..3 {
        w.set(i, i, 1.0 / (1e-3f64 * 1e-3));
        w.set(i + 3, i + 3, 1.0 / (2e-4f64 * 2e-4));
    }
    let mut p = j.t().mul(&w).mul(&j);
    for i in 0..3 {
        let v = p.at(it + i, it + i) + 1.0 / (o.theta_scale * o.theta_scale);
        p.set(it + i, it + i, v);
    }
    for i in 0..N {
        let v = p.at(ic + i, ic + i) + 1.0 / (1e-5f64 * 1e-5);
        p.set(ic + i, ic + i, v);
    }
    // B = [0; 0; I]: BᵀPB = P_cc, BᵀPA = P_c· A.
    let mut gains = vec![M::zeros(N, nz); cycles];
    let mut next_p = vec![M::zeros(nz, nz); cycles];
    for k in (0..cycles).rev() {
        next_p[k] = p.clone();
        let a = &a_s[k];
        let pa = p.mul(a);
        let mut pcc = M::zeros(N, N);
        let mut bpa = M::zeros(N, nz);
        for i in 0..N {
            for jj in 0..N {
                pcc.set(i, jj, p.at(ic + i, ic + jj));
            }
            for jj in 0..nz {
                bpa.set(i, jj, pa.at(ic + i, jj));
            }
        }
        let kk = r.add(&pcc).solve(&bpa);
        // P = Q + AᵀPA − AᵀPB K = Q + Aᵀ(PA − PB K).
        let mut pbk = M::zeros(nz, nz);
        for i in 0..nz {
            for jj in 0..nz {
                let mut s = 0.0;
                for l in 0..N {
                    s += p.at(i, ic + l) * kk.at(l, jj);
                }
                pbk.set(i, jj, s);
            }
        }
        p = q.add(&a.t().mul(&pa.sub(&pbk))).sym();
        gains[k] = kk;
    }
    Lqr {
        gains,
        next_p,
        a: a_s,
    }
}

/// The gains, `P_{k+1}` and `A_k` of every cycle.
struct Lqr {
    gains: Vec<M>,
    next_p: Vec<M>,
    a: Vec<M>,
}

/// The affine term of the LQR for a known drift `d_k` (rad per cycle, the base rotation
/// the plan's own motion makes on the true robot): `v = −K z − k`, `k_k = (R + P_cc)⁻¹
/// Bᵀ(P w + s)`, `s_k = (A − BK)ᵀ(P w + s)`, `w = [0; −d; 0]`.
fn affine<const N: usize>(l: &Lqr, d: &[[f64; 3]], o: &Opts, cycles: usize) -> Vec<[f64; N]> {
    let nz = 2 * N + 3;
    let ic = N + 3;
    let r = 1.0 / (o.rate_scale * o.rate_scale) / cycles as f64;
    let mut s = vec![0.0; nz];
    let mut out = vec![[0.0; N]; cycles];
    for k in (0..cycles).rev() {
        let p = &l.next_p[k];
        let mut w = vec![0.0; nz];
        if let Some(dk) = d.get(k) {
            for i in 0..3 {
                w[N + i] = -dk[i];
            }
        }
        // y = P w + s
        let mut y = s.clone();
        for i in 0..nz {
            for j in 0..nz {
                y[i] += p.at(i, j) * w[j];
            }
        }
        let mut a = M::zeros(N, N);
        let mut b = M::zeros(N, 1);
        for i in 0..N {
            for j in 0..N {
                a.set(i, j, p.at(ic + i, ic + j) + if i == j { r } else { 0.0 });
            }
            b.set(i, 0, y[ic + i]);
        }
        let kk = a.solve(&b);
        out[k] = core::array::from_fn(|i| kk.at(i, 0));
        // s = (A − B K)ᵀ y
        let g = &l.gains[k];
        let mut abk = l.a[k].clone();
        for i in 0..N {
            for j in 0..nz {
                let v = abk.at(ic + i, j) - g.at(i, j);
                abk.set(ic + i, j, v);
            }
        }
        let mut ns = vec![0.0; nz];
        for i in 0..nz {
            for j in 0..nz {
                ns[i] += abk.at(j, i) * y[j];
            }
        }
        s = ns;
    }
    out
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Law {
    Open,
    Base,
    Lqr,
    Oracle,
}

#[derive(Default, Clone, Copy)]
struct Flown {
    base_deg: f64,
    pos_mm: f64,
    ori_deg: f64,
    travel_deg: f64,
    max_c_deg_s: f64,
    clipped: u32,
    /// The end-effector position error (mm) of the plan's last configuration on this robot
    /// with the base not rotated: the base placed by this robot's CoM conservation.
    floor_mm: f64,
}

#[allow(clippy::too_many_arguments)]
fn fly<const N: usize, const K: usize>(
    lt: &LoadedTask,
    nominal: &Robot<N>,
    path: &JointPath<N>,
    draw: &Draw,
    sensors: &mut Sensors,
    law: Law,
    lq: &Lqr,
    per: usize,
    cycles: usize,
    tc: f64,
    o: &Opts,
) -> Flown {
    let mut dispersed = lt.clone();
    dispersed.chain = draw.apply(&lt.chain);
    let task: reactionless::Task<N, K> = dispersed.task::<N, K>().unwrap();
    let mut state = draw.truth_state(&task);
    let qmax: [f64; N] = core::array::from_fn(|i| task.robot().desc().joints[i].velocity);
    // The oracle: the drift the plan makes on this robot, known in advance.
    let feed = if law == Law::Oracle {
        let n = path.q.len();
        let plan_cycles = (n - 1) / per;
        let d: Vec<[f64; 3]> = (0..plan_cycles)
            .map(|k| {
                let mut s = [0.0; 3];
                for w in path.q[k * per..=(k + 1) * per].windows(2) {
                    let mid: [f64; N] = core::array::from_fn(|i| 0.5 * (w[0][i] + w[1][i]));
                    let b = coupling(task.robot(), &mid);
                    for i in 0..3 {
                        for j in 0..N {
                            s[i] += b.at(i, j) * (w[1][j] - w[0][j]);
                        }
                    }
                }
                s
            })
            .collect();
        affine::<N>(lq, &d, o, lq.gains.len())
    } else {
        Vec::new()
    };
    let dt = path.t[1] - path.t[0];
    let n = path.q.len();
    let qf = path.q[n - 1];
    let plan_at = |s: usize| if s < n { path.q[s] } else { qf };
    let mut q = path.q[0];
    state.push(&task, &q, 0.0);
    let mut est = [1.0, 0.0, 0.0, 0.0];
    let mut c = [0.0; N]; // the correction applied in the current cycle
    let mut prev_att = state.attitude();
    let mut travel = 0.0;
    let mut plan_travel = 0.0;
    let mut out = Flown::default();
    let mut first = true;
    for k in 0..cycles {
        // Measure at t_k: the gyro's mean rate over the last cycle propagates the estimate,
        // the star tracker pulls it (its first reading sets it).
        let att = state.attitude();
        let st = sensors.star_tracker(att);
        if k > 0 {
            let d = quat_log(quat_mul(
                [prev_att[0], -prev_att[1], -prev_att[2], -prev_att[3]],
                att,
            ));
            if let Some(g) = sensors.gyro([d[0] / tc, d[1] / tc, d[2] / tc]) {
                est = normalized(quat_mul(
                    est,
                    quat_exp(&Vec3::new(g[0] * tc, g[1] * tc, g[2] * tc)),
                ));
            }
        }
        match (first, st) {
            (true, Some(m)) => {
                est = m;
                first = false;
            }
            (false, Some(m)) => {
                let e = quat_log(quat_mul([est[0], -est[1], -est[2], -est[3]], m));
                est = normalized(quat_mul(est, quat_exp(&(e * o.alpha))));
            }
            _ => {}
        }
        prev_att = att;
        let theta = quat_log(est);
        let qm = sensors.encoders(&q).unwrap_or(q);
        let dq: [f64; N] = core::array::from_fn(|i| qm[i] - plan_at(k * per)[i]);
        // The next cycle's correction.
        let mut next = [0.0; N];
        match law {
            Law::Open => {}
            Law::Base => {
                let b = coupling(nominal, &qm);
                // B⁺ = Bᵀ(BBᵀ)⁻¹; θ̇ = −B c = k θ̂ drives θ to 0.
                let bbt = b.mul(&b.t());
                let mut th = M::zeros(3, 1);
                for i in 0..3 {
                    th.set(i, 0, o.base_gain * theta[i]);
                }
                let y = b.t().mul(&bbt.solve(&th));
                for i in 0..N {
                    next[i] = y.at(i, 0);
                }
            }
            Law::Lqr | Law::Oracle => {
                let g = &lq.gains[k];
                for i in 0..N {
                    let mut s = 0.0;
                    for j in 0..N {
                        s += g.at(i, j) * dq[j] + g.at(i, N + 3 + j) * c[j];
                    }
                    for j in 0..3 {
                        s += g.at(i, N + j) * theta[j];
                    }
                    next[i] = -s - feed.get(k).map_or(0.0, |f| f[i]);
                }
            }
        }
        // Fly cycle k: the plan's setpoints plus c (decided one cycle ago).
        for s in 0..per {
            let a = plan_at(k * per + s);
            let b = plan_at(k * per + s + 1);
            let qn: [f64; N] = core::array::from_fn(|i| q[i] + (b[i] - a[i]) + c[i] * dt);
            for i in 0..N {
                travel += (qn[i] - q[i]).abs();
                plan_travel += (b[i] - a[i]).abs();
            }
            q = qn;
            state.push(&task, &q, (k * per + s + 1) as f64 * dt);
        }
        // Clip next against the next cycle's plan rates.
        for i in 0..N {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for s in 0..per {
                let r = (plan_at((k + 1) * per + s + 1)[i] - plan_at((k + 1) * per + s)[i]) / dt;
                lo = lo.min(r);
                hi = hi.max(r);
            }
            let up = qmax[i] - hi;
            let down = -qmax[i] - lo;
            let v = next[i].max(down.min(0.0)).min(up.max(0.0));
            if v != next[i] {
                out.clipped += 1;
            }
            next[i] = v;
            out.max_c_deg_s = out.max_c_deg_s.max(v.abs().to_degrees());
        }
        c = next;
    }
    if std::env::var("CL_DEBUG").is_ok() && law == Law::Lqr {
        let th = quat_log(state.attitude());
        let dq: Vec<f64> = (0..N).map(|i| (q[i] - qf[i]).to_degrees()).collect();
        let en = Frames::new(nominal, &q)
            .end_pose(&Frames::new(nominal, task.start()).com, state.attitude());
        let plan_end = Frames::new(nominal, &qf).end_pose(
            &Frames::new(nominal, task.start()).com,
            [1.0, 0.0, 0.0, 0.0],
        );
        eprintln!(
            "dq_end_deg {dq:.3?} theta_end_deg {:.2e} {:.2e} {:.2e} c_end {:.2e}; nominal robot at the flown end: {:.2} mm from the plan's end",
            th[0].to_degrees(),
            th[1].to_degrees(),
            th[2].to_degrees(),
            c.iter().map(|v| v.abs()).fold(0.0, f64::max),
            en.error_to(&plan_end).position_m() * 1e3
        );
    }
    let end = state.end_pose(&task).unwrap();
    let e = end.error_to(task.target());
    let com0 = Frames::new(task.robot(), task.start()).com;
    let held = Frames::new(task.robot(), &qf).end_pose(&com0, [1.0, 0.0, 0.0, 0.0]);
    out.floor_mm = held.error_to(task.target()).position_m() * 1e3;
    out.base_deg = state.max_angle().to_degrees();
    out.pos_mm = e.position_m() * 1e3;
    out.ori_deg = e.orientation_deg();
    out.travel_deg = (travel - plan_travel).to_degrees();
    out
}

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    let i = ((p * (v.len() - 1) as f64).round() as usize).min(v.len() - 1);
    v[i]
}

fn run<const N: usize, const K: usize>(lt: &LoadedTask, o: &Opts) -> Result<(), CliError> {
    let csv = read_output_file(&o.dir, "trajectory.csv")?;
    let path = JointPath::<N>::parse(&o.dir, &csv)?;
    let nominal_task: reactionless::Task<N, K> = lt.task::<N, K>()?;
    let nominal = nominal_task.robot();
    let mut sens: SensorSettings = lt.file.sensors;
    sens.star_tracker_arcsec *= o.noise;
    sens.gyro_arw_deg_rt_h *= o.noise;
    sens.gyro_bias_deg_h *= o.noise;
    let tc = sens.control_period_s;
    let dt = path.t[1] - path.t[0];
    let per = (tc / dt).round() as usize;
    let plan_cycles = (path.q.len() - 1) / per;
    let cycles = plan_cycles + (o.extend_s / tc).round() as usize;
    let started = std::time::Instant::now();
    let lq = lqr(nominal, nominal_task.start(), &path.q, per, cycles, tc, o);
    eprintln!(
        "LQR gains along {cycles} cycles in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let disp = Dispersion {
        mass_rel_sigma: 0.05 * o.disp_scale,
        inertia_rel_sigma: 0.1 * o.disp_scale,
        com_sigma_m: 0.01 * o.disp_scale,
        ..Dispersion::default()
    };
    println!(
        "{} samples, seed {}, sensors ×{} (star tracker {}″), {} Hz, extension {} s",
        o.samples,
        o.seed,
        o.noise,
        sens.star_tracker_arcsec,
        1.0 / tc,
        o.extend_s
    );
    println!(
        "law   | base deg p50 p95 p99 max | EE mm p50 p95 p99 max | EE deg p50 p95 p99 max | travel deg p99 | max c deg/s | clipped | held mm p50 p99"
    );
    for law in [Law::Open, Law::Base, Law::Lqr, Law::Oracle] {
        let flights: Vec<Flown> = (0..o.samples)
            .map(|s| {
                let draw = Draw::sample(&lt.chain, &disp, o.seed, s).unwrap();
                let mut sensors = Sensors::new(&sens, o.seed, s);
                fly::<N, K>(
                    lt,
                    nominal,
                    &path,
                    &draw,
                    &mut sensors,
                    law,
                    &lq,
                    per,
                    if law == Law::Open {
                        plan_cycles
                    } else {
                        cycles
                    },
                    tc,
                    o,
                )
            })
            .collect();
        let col = |f: fn(&Flown) -> f64| {
            let mut v: Vec<f64> = flights.iter().map(f).collect();
            [
                pct(&mut v, 0.5),
                pct(&mut v, 0.95),
                pct(&mut v, 0.99),
                pct(&mut v, 1.0),
            ]
        };
        let b = col(|f| f.base_deg);
        let p = col(|f| f.pos_mm);
        let r = col(|f| f.ori_deg);
        let t = col(|f| f.travel_deg);
        let m = col(|f| f.max_c_deg_s);
        let fl = col(|f| f.floor_mm);
        let clipped: u32 = flights.iter().map(|f| f.clipped).sum();
        println!(
            "{:5} | {:.2e} {:.2e} {:.2e} {:.2e} | {:.2} {:.2} {:.2} {:.2} | {:.3} {:.3} {:.3} {:.3} | {:.1} | {:.3} | {} | {:.2} {:.2}",
            format!("{law:?}").to_lowercase(),
            b[0],
            b[1],
            b[2],
            b[3],
            p[0],
            p[1],
            p[2],
            p[3],
            r[0],
            r[1],
            r[2],
            r[3],
            t[2],
            m[3],
            clipped,
            fl[0],
            fl[2]
        );
    }
    Ok(())
}

fn main() {
    let o = parse();
    let lt = read_bundle(&o.dir).unwrap();
    let n = lt.chain.dof();
    let r: Result<(), CliError> = with_dims!(n, run, &lt, &o);
    r.unwrap();
}
