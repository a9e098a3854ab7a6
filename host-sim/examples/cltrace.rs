//! One closed-loop flight, cycle by cycle (issue #31): the true base rotation, the
//! executor's estimate and the largest command, to see where the base error comes from.
//!
//! ```sh
//! cargo run --profile test -p host-sim --features research --example cltrace -- \
//!     DIR SAMPLE [SEED]
//! ```
//! `DIR` is a plan's directory; its task's `[sensors]` and `[closed_loop]` are used, the
//! dispersion is the README's (5 % mass, 10 % inertia, 1 cm CoM).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use host_sim::artifacts::{read_bundle, read_output_file};
use host_sim::closed_loop::{Trace, fly};
use host_sim::dispersion::{Draw, JointPath, Settings};
use host_sim::error::CliError;
use host_sim::taskfile::LoadedTask;
use host_sim::with_dims;
use std::path::{Path, PathBuf};

fn run<const N: usize, const K: usize>(
    lt: &LoadedTask,
    dir: &Path,
    sample: u64,
    seed: u64,
) -> Result<(), CliError> {
    let csv = read_output_file(dir, "trajectory.csv")?;
    let path = JointPath::<N>::parse(dir, &csv)?;
    let disp = Settings {
        mass_rel_sigma: 0.05,
        inertia_rel_sigma: 0.1,
        com_sigma_m: 0.01,
        ..Settings::default()
    };
    let draw = Draw::sample(&lt.chain, &disp, seed, sample)?;
    let cfg = lt.loop_config()?;
    let mut tr = Trace::default();
    let f = fly::<N, K>(
        lt,
        &path,
        &draw,
        &lt.file.sensors,
        &cfg,
        seed,
        sample,
        Some(&mut tr),
    )?;
    println!("t_s theta_deg estimate_deg error_deg max_cmd_deg_s");
    for i in 0..tr.t.len() {
        let n = |v: &[f64; 3]| {
            (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                .sqrt()
                .to_degrees()
        };
        let d = [
            tr.theta[i][0] - tr.theta_estimate[i][0],
            tr.theta[i][1] - tr.theta_estimate[i][1],
            tr.theta[i][2] - tr.theta_estimate[i][2],
        ];
        let c = tr.command[i]
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .to_degrees();
        println!(
            "{:.1} {:.5} {:.5} {:.5} {:.3}",
            tr.t[i],
            n(&tr.theta[i]),
            n(&tr.theta_estimate[i]),
            n(&d),
            c
        );
    }
    eprintln!("{f:?}");
    Ok(())
}

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(&a[0]);
    let sample: u64 = a[1].parse().unwrap();
    let seed: u64 = a.get(2).map_or(1, |s| s.parse().unwrap());
    let lt = read_bundle(&dir).unwrap();
    let r: Result<(), CliError> = with_dims!(lt.chain.dof(), run, &lt, &dir, sample, seed);
    r.unwrap();
}
