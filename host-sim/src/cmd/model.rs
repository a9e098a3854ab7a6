//! `host-sim model`: the model quantities at one configuration, as JSON on stdout.
//!
//! Base at the origin with identity attitude (the base frame). Matrices are arrays of rows.

use crate::args::{List, RobotArgs, parse_list};
use crate::error::{CliError, Context};
use crate::urdf::Chain;
use crate::with_dims;
use nalgebra::SMatrix;
use reactionless::{Basis, Frames, Momentum, generalized_jacobian};
use serde::Serialize;
use std::path::Path;

/// Model quantities at one configuration, as JSON on stdout: com, hb, hbm, rns_basis, jg,
/// ee (base at the origin, identity attitude).
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    robot: RobotArgs,
    /// Joint angles (deg), comma-separated.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_list)]
    q_deg: List,
}

#[derive(Serialize, schemars::JsonSchema)]
/// The end-effector pose in the base frame.
pub struct EePose {
    /// Position (m).
    pub position: [f64; 3],
    /// Unit quaternion `[w, x, y, z]`.
    pub quat_wxyz: [f64; 4],
}

#[derive(Serialize, schemars::JsonSchema)]
/// The model report.
pub struct ModelReport {
    /// Robot name (URDF).
    pub robot: String,
    /// Revolute joint names, base to tip.
    pub joints: Vec<String>,
    /// The configuration (deg).
    pub q_deg: Vec<f64>,
    /// System CoM (m).
    pub com: [f64; 3],
    /// H~b (kg m²).
    pub hb: Vec<Vec<f64>>,
    /// H~bm (kg m²), 3×N.
    pub hbm: Vec<Vec<f64>>,
    /// Singular values of H~bm, largest first (host-side SVD, reporting only).
    pub hbm_singular_values: Vec<f64>,
    /// σ_max/σ_min of H~bm.
    pub hbm_condition: f64,
    /// Initial RNS basis MGS(P·E), N×K.
    pub rns_basis: Vec<Vec<f64>>,
    /// Generalized Jacobian, 6×N (m/rad, rad/rad).
    pub jg: Vec<Vec<f64>>,
    /// End-effector pose (base at the origin, identity attitude).
    pub ee: EePose,
}

fn rows<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let chain = self.robot.load()?;
        let report = with_dims!(chain.dof(), report, &chain, &self.robot.urdf, &self.q_deg.0)?;
        let text = serde_json::to_string_pretty(&report).or_internal(|| "JSON")?;
        println!("{text}");
        Ok(())
    }
}

fn report<const N: usize, const K: usize>(
    chain: &Chain,
    urdf_path: &Path,
    q_deg: &[f64],
) -> Result<ModelReport, CliError> {
    let robot = chain.robot::<N>(urdf_path)?;
    if q_deg.len() != N {
        return Err(CliError::input(format!(
            "--q-deg has {} values; the robot has {N} joints ({})",
            q_deg.len(),
            chain.joint_names.join(", ")
        )));
    }
    if let Some((i, v)) = q_deg.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(CliError::input(format!(
            "--q-deg[{i}] = {v} is not a finite number"
        )));
    }
    let mut q = [0.0; N];
    for (o, v) in q.iter_mut().zip(q_deg) {
        *o = v.to_radians();
    }
    report_at::<N, K>(chain, &robot, &q, q_deg.to_vec())
}

/// The model report of `robot` (read from `chain`) at `q` (rad; `q_deg` is what the
/// report echoes): the same numbers `host-sim model` prints (the Python binding's
/// `model()`).
///
/// # Errors
/// Bad input when there is no reaction null-space basis at `q`, or no generalized Jacobian.
pub fn report_at<const N: usize, const K: usize>(
    chain: &Chain,
    robot: &reactionless::Robot<N>,
    q: &[f64; N],
    q_deg: Vec<f64>,
) -> Result<ModelReport, CliError> {
    let frames = Frames::new(robot, q);
    let m = Momentum::new(robot, &frames);
    let basis = Basis::<N, K>::initial(&m.hbm).map_err(|cause| {
        CliError::input(format!(
            "configuration {q_deg:?} (deg): no reaction null-space basis there ({})",
            reactionless::Error::RankLoss { step: 0, cause }
        ))
    })?;
    let jg = generalized_jacobian(robot, &frames).or_input(|| "generalized Jacobian")?;
    let hbm = SMatrix::<f64, 3, N>::from_columns(&m.hbm);
    // σ_i(H~bm) = √λ_i(H~bm H~bmᵀ): a 3×3 symmetric eigenproblem (host-side reporting).
    let gram = hbm * hbm.transpose();
    let eig = nalgebra::SymmetricEigen::new(gram);
    let mut svs: Vec<f64> = eig.eigenvalues.iter().map(|l| l.max(0.0).sqrt()).collect();
    svs.sort_by(|a, b| b.total_cmp(a));
    let cond = match (svs.first(), svs.last()) {
        (Some(a), Some(b)) if *b > 0.0 => a / b,
        _ => f64::INFINITY,
    };
    let cols = basis.columns();
    let rns: Vec<Vec<f64>> = (0..N)
        .map(|r| {
            cols.iter()
                .map(|c| c.get(r).copied().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    let ee = frames.ee_pose();
    Ok(ModelReport {
        robot: chain.name.clone(),
        joints: chain.joint_names.clone(),
        q_deg,
        com: [frames.com.x, frames.com.y, frames.com.z],
        hb: rows(&m.hb.to_matrix()),
        hbm: rows(&hbm),
        hbm_singular_values: svs,
        hbm_condition: cond,
        rns_basis: rns,
        jg: rows(&jg),
        ee: EePose {
            position: ee.position,
            quat_wxyz: ee.quat_wxyz,
        },
    })
}
