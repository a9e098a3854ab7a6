//! Diagnosis of the basin floors (issue #11): why do 6-joint arms stall near f ≈ 1e-7?
//!
//! ```sh
//! cargo run --release -p host-sim --features research --example floor -- tests/tasks/a/arm6/task_*.toml [--planner-target]
//! ```
//! For each task: the generating η (from the task file's header comment) is rolled out with
//! the planner model (base attitude identity) — `f_gen` is its f against the task target,
//! which was made with the truth model (base drift included). Then a dense Gauss–Newton on
//! the unit sphere (host maths: SVD pseudo-inverse of the tangent Jacobian, step halving)
//! runs from the generating η for up to 40 iterations; `f_floor` is where it ends, `sv` the
//! singular values of the 6 × 2K Jacobian restricted to the tangent space, `gn_floor` the
//! Gauss–Newton prediction ‖(I − J J⁺) e‖ at the end point. `kink` is, over the K
//! polynomials, the smallest relative gap between the two |β_i| values at interior
//! critical points (0: exactly on the switch of β_max in eq. 14; 1: far from it, or only
//! one interior critical point). With `--planner-target` the target is replaced by the
//! planner-model end pose of a perturbed generating η (so a zero-f solution exists in
//! the planner model) and the same Gauss–Newton runs from the unperturbed η.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    missing_docs
)]

use host_sim::error::CliError;
use host_sim::taskfile::{self, LoadedTask};
use host_sim::with_dims;
use nalgebra::{SMatrix, SVector};
use reactionless::{Outcome, Task};

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

fn roll<const N: usize, const K: usize>(task: &Task<N, K>, x: &[f64]) -> Outcome<N> {
    task.rollout(&pairs::<K>(x), &mut ()).unwrap()
}

/// Smallest relative gap between |β| at the two interior critical points (n = 1).
fn kink_gap(x: &[f64], tf: f64) -> f64 {
    let mut gap = 1.0f64;
    for c in x.chunks_exact(2) {
        let (a, b) = (c[0], c[1]);
        let cc = -(a * tf * tf + b * tf);
        let (qa, qb, qc) = (3.0 * a, 2.0 * b, cc);
        let disc = qb * qb - 4.0 * qa * qc;
        if disc < 0.0 || qa == 0.0 {
            continue;
        }
        let beta = |t: f64| (t * (t - tf) * (a * (t + tf) + b)).abs();
        let roots = [
            (-qb + disc.sqrt()) / (2.0 * qa),
            (-qb - disc.sqrt()) / (2.0 * qa),
        ];
        let inside: Vec<f64> = roots
            .iter()
            .copied()
            .filter(|r| (0.0..=tf).contains(r))
            .collect();
        if inside.len() == 2 {
            let (u, v) = (beta(inside[0]), beta(inside[1]));
            gap = gap.min((u - v).abs() / u.max(v));
        }
    }
    gap
}

fn normalise(x: &mut [f64]) {
    let n = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    x.iter_mut().for_each(|v| *v /= n);
}

fn diagnose<const N: usize, const K: usize>(
    lt: &LoadedTask,
    planner_target: bool,
) -> Result<(), CliError> {
    let mut task = lt.task::<N, K>()?;
    let mut x = generating_eta(&lt.text);
    assert_eq!(x.len(), 2 * K);
    normalise(&mut x);
    let g0 = roll(&task, &x);
    let f_gen = g0.f;
    let robot = task.robot();
    let margin = (0..N)
        .map(|j| (g0.joint_min[j] - robot.lower()[j]).min(robot.upper()[j] - g0.joint_max[j]))
        .fold(f64::INFINITY, f64::min);
    if planner_target {
        let mut xp = x.clone();
        for (i, v) in xp.iter_mut().enumerate() {
            *v += 1e-3 * ((i as f64) * 0.7).sin();
        }
        let o = roll(&task, &xp);
        task = Task::new(
            task.robot().clone(),
            *task.start(),
            o.end_pose,
            *task.motion(),
        )
        .unwrap();
    }
    let tf = task.motion().tf();
    let d = 2 * K;
    let mut out = roll(&task, &x);
    let f_start = out.f;
    let mut sv = Vec::new();
    let mut gn_floor = f64::NAN;
    for _ in 0..40 {
        let e = SVector::<f64, 6>::from_row_slice(&out.error.to_array());
        let h: f64 = std::env::var("FLOOR_H")
            .ok()
            .map_or(1e-7, |v| v.parse().unwrap());
        let mut j = SMatrix::<f64, 6, 18>::zeros();
        for c in 0..d {
            let mut xp = x.clone();
            xp[c] += h;
            let o = roll(&task, &xp);
            for (r, (a, b)) in o
                .error
                .to_array()
                .iter()
                .zip(out.error.to_array())
                .enumerate()
            {
                j[(r, c)] = (a - b) / h;
            }
        }
        let mut xv = SVector::<f64, 18>::zeros();
        for (i, v) in x.iter().enumerate() {
            xv[i] = *v;
        }
        let p = SMatrix::<f64, 18, 18>::identity() - xv * xv.transpose();
        let jt = j * p;
        let svd = jt.svd(true, true);
        sv = svd.singular_values.iter().copied().take(d - 1).collect();
        let pinv = svd.pseudo_inverse(1e-12 * sv[0]).unwrap();
        let delta = -(pinv * e);
        gn_floor = (e + jt * delta).norm();
        let mut t = 1.0;
        let mut improved = false;
        for _ in 0..30 {
            let mut xn: Vec<f64> = x.iter().zip(delta.iter()).map(|(a, b)| a + t * b).collect();
            normalise(&mut xn);
            let o = roll(&task, &xn);
            if o.f < out.f {
                x = xn;
                out = o;
                improved = true;
                break;
            }
            t *= 0.5;
        }
        if std::env::var("FLOOR_TRACE").is_ok() {
            let o = &out;
            let rb = task.robot();
            let m = (0..N)
                .map(|j| (o.joint_min[j] - rb.lower()[j]).min(rb.upper()[j] - o.joint_max[j]))
                .fold(f64::INFINITY, f64::min);
            eprintln!(
                "  f {:.3e} gn {:.3e} t {t:.1e} margin {m:.4} phi {:.1e} g {:.6e} kink {:.2e}",
                o.f,
                gn_floor,
                o.phi,
                o.g,
                kink_gap(&x, tf)
            );
        }
        if !improved || out.f < 1e-13 {
            break;
        }
    }
    let svs: Vec<String> = sv.iter().map(|v| format!("{v:.2e}")).collect();
    println!(
        "{:<40} f_gen {:9.3e} margin {:7.4} | f_start {:9.3e} -> f_floor {:9.3e} gn_floor {:9.3e} kink {:7.1e} | sv [{}]",
        lt.path.display(),
        f_gen,
        margin,
        f_start,
        out.f,
        gn_floor,
        kink_gap(&x, tf),
        svs.join(" ")
    );
    Ok(())
}

fn main() {
    let mut planner_target = false;
    let mut tasks = Vec::new();
    for a in std::env::args().skip(1) {
        if a == "--planner-target" {
            planner_target = true;
        } else {
            tasks.push(a);
        }
    }
    for t in tasks {
        let lt = taskfile::load(std::path::Path::new(&t)).unwrap();
        with_dims!(lt.chain.dof(), diagnose, &lt, planner_target).unwrap();
    }
}
