//! `check`: `host-sim check` of an output directory (a plan's, a rollout's, a re-timed
//! bundle's) or of a `Plan` (written to a temporary directory first), the same verdict
//! rows.

use crate::planning::Plan;
use host_sim::error::CliError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// `host-sim check DIR` of a directory, or of a `Plan` (written as `Plan.write` does, to a
/// temporary directory removed afterwards): one dict per verdict row, `check` (what was
/// checked), `value` (what was found), `limit` (what is allowed) and `passed` (bool).
/// Raises `InputError` for a directory that is not a plan's or rollout's output.
#[pyfunction]
pub fn check<'py>(
    py: Python<'py>,
    target: &Bound<'py, PyAny>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let lines = if let Ok(plan) = target.cast::<Plan>() {
        let plan = plan.get().clone();
        py.detach(move || {
            let tmp = tempfile::tempdir()
                .map_err(|e| CliError::internal(format!("a temporary directory: {e}")))?;
            let dir = plan.write_to(&tmp.path().join("plan"))?;
            host_sim::cmd::check::verify(&dir)
        })
    } else {
        let dir: PathBuf = target.extract()?;
        py.detach(move || host_sim::cmd::check::verify(&dir))
    }
    .map_err(|e| crate::to_py(py, &e))?;
    lines
        .iter()
        .map(|l| {
            let d = PyDict::new(py);
            d.set_item("check", &l.check)?;
            d.set_item("value", &l.value)?;
            d.set_item("limit", &l.limit)?;
            d.set_item("passed", l.pass)?;
            Ok(d)
        })
        .collect()
}
