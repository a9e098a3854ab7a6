//! Prototype (issue #28): variants of the truth refinement's LM from the search's hand-over
//! point, counted in rollouts to truth_f ≤ 1e-9 (dense host maths, not flight code).
//!
//! ```sh
//! cargo run --release -p host-sim --features research --example lmproto -- --seeds 1..5 tests/tasks/b/chaser7/task_006.toml
//! ```
//! Variants: `base` (the Refiner: planner-model difference Jacobian rebuilt after every
//! accepted step, λ/10 on accept, 10λ on reject), `nielsen` (Nielsen's λ update),
//! `geo` (`base` plus geodesic acceleration: the second directional derivative of the
//! planner-model error along the step, one more planner rollout per trial), `broyden`
//! (rank-1 update of J by the truth residual after every trial, rebuild after 2 rejections).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    clippy::too_many_lines,
    clippy::too_many_arguments,
    missing_docs
)]

use host_sim::args::parse_seeds;
use host_sim::drive::{HOST_CAPACITY, HostPlanner};
use host_sim::taskfile::{self, LoadedTask, Overrides};
use host_sim::with_dims;
use nalgebra::{SMatrix, SVector};
use reactionless::TRUTH_SUBSTEPS;
use reactionless::{Planner, RefineAgainst, Status, Task, TruthModel};

type V6 = SVector<f64, 6>;
type J = SMatrix<f64, 6, 18>;
type X = SVector<f64, 18>;

fn pairs<const K: usize>(x: &X) -> [[f64; 2]; K] {
    let mut e = [[0.0; 2]; K];
    for (i, p) in e.iter_mut().enumerate() {
        *p = [x[2 * i], x[2 * i + 1]];
    }
    e
}

struct Eval<'a, const N: usize, const K: usize> {
    task: &'a Task<N, K>,
    rollouts: u32,
}

impl<const N: usize, const K: usize> Eval<'_, N, K> {
    fn planner(&mut self, x: &X) -> Option<V6> {
        self.rollouts += 1;
        let o = self.task.rollout(&pairs::<K>(x), &mut ()).ok()?;
        Some(V6::from_row_slice(&o.error.to_array()))
    }
    /// (truth e, planner e, Φ)
    fn truth(&mut self, x: &X) -> Option<(V6, V6, f64)> {
        self.rollouts += 1;
        let mut t = TruthModel::new(self.task, TRUTH_SUBSTEPS);
        let o = self.task.rollout(&pairs::<K>(x), &mut t).ok()?;
        let end = t.end_pose()?;
        Some((
            V6::from_row_slice(&end.error_to(self.task.target()).to_array()),
            V6::from_row_slice(&o.error.to_array()),
            o.phi,
        ))
    }
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Variant {
    Base,
    Nielsen,
    Geo,
    Broyden,
    GeoBroyden,
    /// `base` with the damping floor 1e-15 (the multistart's) instead of 1e-12.
    Base15,
    /// `nielsen` with the floor 1e-12.
    Nielsen12,
    /// `broyden` with ÷10/×10 and floor 1e-12 (only the Jacobian policy changed).
    BroydenBase,
}

fn solve(j: &J, lm: f64, r: &V6) -> X {
    // −Jᵀ(JJᵀ + lm I)⁻¹ r
    let a = j * j.transpose() + SMatrix::<f64, 6, 6>::identity() * lm;
    let y = a.cholesky().map_or(V6::zeros(), |c| c.solve(r));
    -(j.transpose() * y)
}

fn floor(v: Variant) -> f64 {
    match v {
        Variant::Base | Variant::Geo | Variant::Nielsen12 | Variant::BroydenBase => 1e-12,
        _ => 1e-15,
    }
}

fn nielsen(v: Variant) -> bool {
    matches!(
        v,
        Variant::Nielsen | Variant::Nielsen12 | Variant::Broyden | Variant::GeoBroyden
    )
}

fn broyden(v: Variant) -> bool {
    matches!(
        v,
        Variant::Broyden | Variant::GeoBroyden | Variant::BroydenBase
    )
}

fn run<const N: usize, const K: usize>(
    task: &Task<N, K>,
    x0: &X,
    variant: Variant,
    budget: u32,
    tol: f64,
    trace: bool,
) -> (u32, f64, u32) {
    let d = 2 * K;
    let mut ev = Eval { task, rollouts: 0 };
    let (mut r, mut rp, _) = ev.truth(x0).unwrap();
    let mut x = *x0;
    let mut lambda = 1e-3f64;
    let mut nu = 2.0;
    let mut jac = J::zeros();
    let mut need_jac = true;
    let mut stale = false;
    let mut rejects = 0;
    let mut accepted = 0;
    while ev.rollouts < budget && r.norm() > tol {
        if need_jac {
            let h = 1e-7 * x.iter().take(d).fold(0.0f64, |m, v| m.max(v.abs()));
            jac = J::zeros();
            for c in 0..d {
                let mut xp = x;
                xp[c] += h;
                if let Some(e) = ev.planner(&xp) {
                    jac.set_column(c, &((e - rp) / h));
                }
            }
            need_jac = false;
            stale = false;
            rejects = 0;
        }
        let mu = (jac * jac.transpose()).trace() / 6.0;
        let lm = lambda * mu;
        let v = solve(&jac, lm, &r);
        let mut step = v;
        let mut geo_ok = true;
        if matches!(variant, Variant::Geo | Variant::GeoBroyden) {
            let hg = 0.1;
            let Some(ep) = ev.planner(&(x + v * hg)) else {
                lambda *= 10.0;
                continue;
            };
            let rvv = ((ep - rp) / hg - jac * v) * (2.0 / hg);
            let a = solve(&jac, lm, &rvv);
            step = v + a * 0.5;
            geo_ok = 2.0 * a.norm() <= 0.75 * v.norm();
        }
        let xt = x + step;
        let res = if geo_ok { ev.truth(&xt) } else { None };
        let ok = res.is_some_and(|(rt, _, phi)| phi == 0.0 && rt.norm() < r.norm());
        let pred = r.norm_squared() - (r + jac * v).norm_squared();
        if broyden(variant) {
            if let Some((rt, _, _)) = res {
                // Broyden on the truth residual (J then models the truth map along s).
                let s = step;
                let y = rt - r;
                jac += (y - jac * s) * s.transpose() / s.norm_squared();
                stale = true;
            }
        }
        if ok {
            let (rt, rpt, _) = res.unwrap();
            let rho = (r.norm_squared() - rt.norm_squared()) / pred;
            x = xt;
            r = rt;
            rp = rpt;
            accepted += 1;
            if nielsen(variant) {
                let t = 2.0 * rho - 1.0;
                lambda = (lambda * (1.0 - t * t * t).max(1.0 / 3.0)).max(floor(variant));
                nu = 2.0;
            } else {
                lambda = (lambda * 0.1).max(floor(variant));
            }
            if !broyden(variant) {
                need_jac = true;
            }
            if trace {
                println!(
                    "    {:5} f {:.4e} lambda {lambda:.1e} rho {rho:.3}",
                    ev.rollouts,
                    r.norm()
                );
            }
        } else {
            if nielsen(variant) {
                lambda *= nu;
                nu *= 2.0;
            } else {
                lambda *= 10.0;
            }
            rejects += 1;
            if broyden(variant) && stale && rejects >= 2 {
                need_jac = true;
                lambda = lambda.min(1e-3);
                nu = 2.0;
            }
            if lambda > 1e10 {
                break;
            }
        }
    }
    (ev.rollouts, r.norm(), accepted)
}

fn proto<const N: usize, const K: usize>(
    lt: &LoadedTask,
    seed: u64,
    variants: &[Variant],
    budget: u32,
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
    let mut config = lt.planner(HOST_CAPACITY, &overrides)?;
    config.refine_max_rollouts = 1;
    let task = lt.task::<N, K>()?;
    let mut planner: Box<HostPlanner<N, K>> = Box::new(Planner::new(task.clone(), config).unwrap());
    let plan = loop {
        if let Status::Finished(p) = planner.step(24_000, &mut ()).unwrap() {
            break p;
        }
    };
    let mut x0 = X::zeros();
    for (i, v) in plan.eta[0].iter().flatten().enumerate() {
        x0[i] = *v;
    }
    let mut line = format!(
        "{} seed {seed}: search {} f {:.1e} truth_f {:.2e} |",
        lt.path.display(),
        plan.search_rollouts,
        plan.search_f,
        plan.refine.and_then(|r| r.truth_f).unwrap_or(f64::NAN)
    );
    for v in variants {
        let (n, f, acc) = run(&task, &x0, *v, budget, 1e-9, trace);
        line += &format!(" {v:?} {n} ({f:.1e}, {acc} acc) |");
    }
    println!("{line}");
    Ok(())
}

fn main() {
    let mut seeds = vec![1];
    let mut trace = false;
    let mut budget = 1000;
    let mut variants = vec![
        Variant::Base,
        Variant::Nielsen,
        Variant::Geo,
        Variant::Broyden,
        Variant::GeoBroyden,
    ];
    let mut tasks = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seeds" => seeds = parse_seeds(&args.next().unwrap()).unwrap(),
            "--trace" => trace = true,
            "--budget" => budget = args.next().unwrap().parse().unwrap(),
            "--variants" => {
                variants = args
                    .next()
                    .unwrap()
                    .split(',')
                    .map(|s| match s {
                        "base" => Variant::Base,
                        "nielsen" => Variant::Nielsen,
                        "geo" => Variant::Geo,
                        "broyden" => Variant::Broyden,
                        "geobroyden" => Variant::GeoBroyden,
                        "base15" => Variant::Base15,
                        "nielsen12" => Variant::Nielsen12,
                        "broydenbase" => Variant::BroydenBase,
                        _ => panic!("variant {s}"),
                    })
                    .collect();
            }
            _ => tasks.push(a),
        }
    }
    for t in tasks {
        let lt = taskfile::load(std::path::Path::new(&t)).unwrap();
        for &s in &seeds {
            with_dims!(lt.chain.dof(), proto, &lt, s, &variants, budget, trace).unwrap();
        }
    }
}
