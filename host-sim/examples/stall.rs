//! Diagnosis of the truth-refinement stalls (issue #28): what does the refinement against
//! the truth model do on a (task, seed), and why does it stop?
//!
//! ```sh
//! cargo run --release -p host-sim --features research --example stall -- --seeds 1..5 tests/tasks/b/chaser7/task_006.toml
//! ```
//! For each (task, seed) the planner runs as `plan --refine-tolerance 1e-9 --refine-against
//! truth` does and the example prints: the search (rollouts, f), the refinement (stop,
//! accepted steps, rollouts, truth_f start → end), per accepted step the ratio
//! `truth_f_new / truth_f_old` (median, last), λ's range. Then, at the plan's η:
//! - `sv_p`, `sv_t`: singular values of the planner-model and truth-model Jacobians of `e`
//!   (6 × 2K, forward differences with the Refiner's step);
//! - `rho`: the spectral radius of `I − J_t J_p⁺`, the linear rate at which the Refiner's
//!   undamped step (planner Jacobian, truth residual) shrinks the truth residual
//!   (`rho ≥ 1`: it cannot converge; `rho` near 1: it creeps);
//! - `gn_t`: where a dense Gauss–Newton with the *truth* Jacobian (SVD pseudo-inverse,
//!   step halving, 15 iterations) takes truth_f from the plan's η: a floor of the basin
//!   (`gn_t` stays up) or a method limit (`gn_t` falls to rounding level).
//!
//! With `--trace` every trial's (truth_f, λ) is printed.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    clippy::too_many_lines,
    missing_docs
)]

use host_sim::args::parse_seeds;
use host_sim::drive::{HOST_CAPACITY, HostPlanner};
use host_sim::taskfile::{self, LoadedTask, Overrides};
use host_sim::with_dims;
use nalgebra::{SMatrix, SVector};

type DVector<T> = SVector<T, 6>;
type DMatrix<T> = SMatrix<T, 6, 18>;
use reactionless::TRUTH_SUBSTEPS;
use reactionless::{Event, Planner, RefineAgainst, Status, Task, TruthModel};

fn generating_eta(text: &str) -> Vec<f64> {
    let start = text
        .find("eta = [")
        .expect("no generating eta in the header")
        + 7;
    let end = start + text[start..].find(']').unwrap();
    text[start..end]
        .split(',')
        .map(|s| s.trim().trim_start_matches('#').trim().parse().unwrap())
        .collect()
}

fn pairs<const K: usize>(x: &[f64]) -> [[f64; 2]; K] {
    let mut e = [[0.0; 2]; K];
    for (p, c) in e.iter_mut().zip(x.chunks_exact(2)) {
        *p = [c[0], c[1]];
    }
    e
}

/// Planner-model error `e` (6).
fn e_planner<const N: usize, const K: usize>(task: &Task<N, K>, x: &[f64]) -> DVector<f64> {
    let o = task.rollout(&pairs::<K>(x), &mut ()).unwrap();
    DVector::from_row_slice(&o.error.to_array())
}

/// Truth-model error `e` (6) and Φ.
fn e_truth<const N: usize, const K: usize>(task: &Task<N, K>, x: &[f64]) -> (DVector<f64>, f64) {
    let mut truth = TruthModel::new(task, TRUTH_SUBSTEPS);
    let o = task.rollout(&pairs::<K>(x), &mut truth).unwrap();
    let end = truth.end_pose().unwrap();
    (
        DVector::from_row_slice(&end.error_to(task.target()).to_array()),
        o.phi,
    )
}

fn jacobian(
    x: &[f64],
    h: f64,
    e0: &DVector<f64>,
    f: &dyn Fn(&[f64]) -> DVector<f64>,
) -> DMatrix<f64> {
    let mut j = DMatrix::zeros();
    for c in 0..x.len() {
        let mut xp = x.to_vec();
        xp[c] += h;
        let d = (f(&xp) - e0) / h;
        j.set_column(c, &d);
    }
    j
}

fn svs(j: &DMatrix<f64>) -> Vec<f64> {
    let mut s: Vec<f64> = j
        .svd(false, false)
        .singular_values
        .iter()
        .copied()
        .collect();
    s.sort_by(|a, b| b.partial_cmp(a).unwrap());
    s.truncate(6);
    s
}

fn fmt(v: &[f64]) -> String {
    v.iter()
        .map(|s| format!("{s:.1e}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn diagnose<const N: usize, const K: usize>(
    lt: &LoadedTask,
    seed: u64,
    trace: bool,
) -> Result<(), host_sim::error::CliError> {
    let overrides = Overrides {
        seed: Some(seed),
        refine_tolerance: Some(1e-9),
        strategy: None,
        refine_against: Some(RefineAgainst::Truth),
        paper: true,
        integrator: None,
    };
    let config = lt.planner(HOST_CAPACITY, &overrides)?;
    let task = lt.task::<N, K>()?;
    let mut planner: Box<HostPlanner<N, K>> = Box::new(Planner::new(task.clone(), config).unwrap());
    let mut trials: Vec<(f64, f64)> = Vec::new();
    let mut observer = |e: &Event| {
        if let Event::RefineTrial { f, lambda } = e {
            trials.push((*f, *lambda));
        }
    };
    let plan = loop {
        if let Status::Finished(p) = planner.step(24_000, &mut observer).unwrap() {
            break p;
        }
    };
    let name = lt.path.display().to_string();
    let Some(r) = plan.refine else {
        println!("{name} seed {seed}: no refinement");
        return Ok(());
    };
    // Accepted steps: the best f fell.
    let mut ratios = Vec::new();
    let mut prev = r.f_start;
    let (mut lmin, mut lmax) = (f64::INFINITY, 0.0f64);
    for (i, (f, l)) in trials.iter().enumerate() {
        if trace {
            println!(
                "  trial {i:4} f {f:.4e} lambda {l:.2e}{}",
                if *f < prev { "  acc" } else { "" }
            );
        }
        if *f < prev {
            ratios.push(f / prev);
            prev = *f;
        }
        lmin = lmin.min(*l);
        lmax = lmax.max(*l);
    }
    let last_ratios: Vec<f64> = ratios.iter().rev().take(10).copied().collect();
    println!(
        "{name} seed {seed}: rollouts {} (search {}, search_f {:.2e}) | refine {:?} acc {} rollouts {} trials {} truth_f {:.2e} -> {:.2e} | acc ratio median {:.3} last10 median {:.3} | lambda {:.1e}..{:.1e} last {:.1e}",
        plan.rollouts,
        plan.search_rollouts,
        plan.search_f,
        r.stop,
        r.iterations,
        r.rollouts,
        trials.len(),
        r.f_start,
        r.truth_f.unwrap_or(f64::NAN),
        median(ratios.clone()),
        median(last_ratios),
        lmin,
        lmax,
        trials.last().map_or(f64::NAN, |t| t.1),
    );
    // Jacobians at the plan's η (the Refiner's step).
    let x: Vec<f64> = plan.eta[0].iter().flatten().copied().collect();
    let h = 1e-7 * x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let ep = e_planner(&task, &x);
    let (et, _) = e_truth(&task, &x);
    let jp = jacobian(&x, h, &ep, &|y| e_planner(&task, y));
    let jt = jacobian(&x, h, &et, &|y| e_truth(&task, y).0);
    let jp_pinv = jp.pseudo_inverse(1e-14).unwrap();
    let m = SMatrix::<f64, 6, 6>::identity() - jt * jp_pinv;
    let rho = m
        .complex_eigenvalues()
        .iter()
        .fold(0.0f64, |a, z| a.max(z.norm()));
    // e_t decomposed on J_p's left singular vectors: how much of the residual lies along
    // the weakest direction.
    let svd = jp.svd(true, false);
    let u = svd.u.unwrap();
    let mut idx: Vec<usize> = (0..6).collect();
    idx.sort_by(|a, b| {
        svd.singular_values[*b]
            .partial_cmp(&svd.singular_values[*a])
            .unwrap()
    });
    let comps: Vec<f64> = idx
        .iter()
        .map(|i| (u.column(*i).dot(&et)).abs() / et.norm())
        .collect();
    let dj = (jt - jp).norm() / jp.norm();
    // Dense GN with the truth Jacobian.
    let mut xg = x.clone();
    let (mut eg, _) = e_truth(&task, &xg);
    let f0 = eg.norm();
    let mut its = 0;
    for _ in 0..15 {
        let hh = 1e-7 * xg.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let j = jacobian(&xg, hh, &eg, &|y| e_truth(&task, y).0);
        let d = -(j.pseudo_inverse(1e-14).unwrap() * eg);
        let mut t = 1.0;
        let mut moved = false;
        for _ in 0..20 {
            let xn: Vec<f64> = xg.iter().zip(d.iter()).map(|(a, b)| a + t * b).collect();
            let (en, phi) = e_truth(&task, &xn);
            if phi == 0.0 && en.norm() < eg.norm() {
                xg = xn;
                eg = en;
                moved = true;
                break;
            }
            t *= 0.5;
        }
        its += 1;
        if !moved || eg.norm() < 1e-13 {
            break;
        }
    }
    // The generating η (the task file's header): its truth_f, its Jacobians, its distance.
    let mut g = generating_eta(&lt.text);
    let gn = g.iter().map(|v| v * v).sum::<f64>().sqrt();
    g.iter_mut().for_each(|v| *v /= gn);
    let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    let dist = g
        .iter()
        .zip(x.iter())
        .map(|(a, b)| (a - b / xn).powi(2))
        .sum::<f64>()
        .sqrt()
        .min(
            g.iter()
                .zip(x.iter())
                .map(|(a, b)| (a + b / xn).powi(2))
                .sum::<f64>()
                .sqrt(),
        );
    let hg = 1e-7 * g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (etg, _) = e_truth(&task, &g);
    let jtg = jacobian(&g, hg, &etg, &|y| e_truth(&task, y).0);
    let epg = e_planner(&task, &g);
    let jpg = jacobian(&g, hg, &epg, &|y| e_planner(&task, y));
    println!(
        "    generating eta: |x - x_gen| {dist:.2e} truth_f {:.1e} f {:.1e} sv_t [{}] sv_p [{}]",
        etg.norm(),
        epg.norm(),
        fmt(&svs(&jtg)),
        fmt(&svs(&jpg))
    );
    println!(
        "    sv_p [{}] sv_t [{}] |Jt-Jp|/|Jp| {:.1e} rho(I-Jt Jp+) {:.4} | e_t on J_p's left sv (strong..weak) [{}] | GN(truth J) {:.2e} -> {:.2e} in {its}",
        fmt(&svs(&jp)),
        fmt(&svs(&jt)),
        dj,
        rho,
        fmt(&comps),
        f0,
        eg.norm()
    );
    Ok(())
}

fn main() {
    let mut seeds = vec![1];
    let mut trace = false;
    let mut tasks = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seeds" => seeds = parse_seeds(&args.next().unwrap()).unwrap(),
            "--trace" => trace = true,
            _ => tasks.push(a),
        }
    }
    for t in tasks {
        let lt = taskfile::load(std::path::Path::new(&t)).unwrap();
        for &s in &seeds {
            with_dims!(lt.chain.dof(), diagnose, &lt, s, trace).unwrap();
        }
    }
}
