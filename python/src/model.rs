//! `model`: the reduced momentum matrices and the generalized Jacobian of a robot at a
//! configuration, as `host-sim model` reports them (`cmd::model::report_at`), for
//! cross-checks against Pinocchio or a GNC engineer's own model.

use crate::robot::Robot;
use host_sim::cmd::model::{ModelReport, report_at};
use host_sim::error::CliError;
use host_sim::urdf::Chain;
use host_sim::with_dims;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn report_n<const N: usize, const K: usize>(
    chain: &Chain,
    origin: &std::path::Path,
    q: &[f64],
) -> Result<ModelReport, CliError> {
    let robot = chain.robot::<N>(origin)?;
    let q: [f64; N] = q.try_into().map_err(|_| {
        CliError::input(format!(
            "q has {} values; the robot has {N} joints ({})",
            q.len(),
            chain.joint_names.join(", ")
        ))
    })?;
    if let Some((i, v)) = q.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(CliError::input(format!(
            "q[{i}] = {v} is not a finite number"
        )));
    }
    report_at::<N, K>(
        chain,
        &robot,
        &q,
        q.iter().map(|v| v.to_degrees()).collect(),
    )
}

/// The model of `robot` at `q` (rad), a dict of numpy arrays: `hb` H̃b (3×3, kg m²), `hbm`
/// H̃bm (3×N, kg m²), `jacobian` the generalized Jacobian (6×N: m/rad over rad/rad, linear
/// rows first), `com` the system CoM (m), `rns_basis` the initial reaction null-space
/// basis MGS(P·E) (N×K), `ee_position` (m) and `ee_quat_wxyz` (base at the origin with the
/// identity attitude), `hbm_singular_values`.
#[pyfunction]
pub fn model<'py>(py: Python<'py>, robot: &Robot, q: Vec<f64>) -> PyResult<Bound<'py, PyDict>> {
    let r = with_dims!(robot.chain.dof(), report_n, &robot.chain, &robot.origin, &q)
        .map_err(|e| crate::to_py(py, &e))?;
    let d = PyDict::new(py);
    d.set_item("hb", PyArray2::from_vec2(py, &r.hb)?)?;
    d.set_item("hbm", PyArray2::from_vec2(py, &r.hbm)?)?;
    d.set_item("jacobian", PyArray2::from_vec2(py, &r.jg)?)?;
    d.set_item("com", PyArray1::from_slice(py, &r.com))?;
    d.set_item("rns_basis", PyArray2::from_vec2(py, &r.rns_basis)?)?;
    d.set_item("ee_position", PyArray1::from_slice(py, &r.ee.position))?;
    d.set_item("ee_quat_wxyz", PyArray1::from_slice(py, &r.ee.quat_wxyz))?;
    d.set_item(
        "hbm_singular_values",
        PyArray1::from_vec(py, r.hbm_singular_values),
    )?;
    Ok(d)
}
