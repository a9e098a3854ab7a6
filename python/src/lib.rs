//! `reactionless._native`: the Python extension module behind the `reactionless` package
//! (docs/python.md). It wraps host-sim's library and the core, never a second
//! implementation: a plan from Python is `host-sim plan`'s, bit for bit.
//!
//! Owns the module's registration and the mapping of host-sim's errors to the Python
//! exception hierarchy of `reactionless._errors` ([`to_py`]). The concepts live in one
//! module each: [`robot`] (`Robot`), [`task`] (`Task`), [`planning`] (`plan`, `rollout`,
//! `Plan`, `Trajectory`), [`model`] (`model`), [`checking`] (`check`), [`monte_carlo`]
//! (`disperse`, `retime`: host-sim's subcommands run in this process).
//!
//! Long calls release the GIL and check for signals (`plan` between slices of planning,
//! `disperse` between samples), so Ctrl-C raises `KeyboardInterrupt` and nothing is left
//! half-written.

use host_sim::error::{CliError, EXIT_BAD_INPUT, EXIT_FAILED};
use pyo3::prelude::*;

pub mod checking;
pub mod model;
pub mod monte_carlo;
pub mod planning;
pub mod robot;
pub mod task;

/// The Python exception for a host-sim error: `InputError` (a `ValueError`) for bad input
/// (the CLI's exit code 2), `PlanningError` (a `RuntimeError`) for a result that does not
/// pass or a failed computation (exit code 1), `ReactionlessError` otherwise. The message
/// is the CLI's, naming the key or argument.
pub fn to_py(py: Python<'_>, e: &CliError) -> PyErr {
    let class = match e.code {
        EXIT_BAD_INPUT => "InputError",
        EXIT_FAILED => "PlanningError",
        _ => "ReactionlessError",
    };
    let made = py
        .import("reactionless._errors")
        .and_then(|m| m.getattr(class))
        .and_then(|c| c.call1((e.message.clone(),)));
    match made {
        Ok(obj) => PyErr::from_value(obj),
        Err(err) => err,
    }
}

/// A bad argument of a Python call: `InputError` with `message`.
pub fn input_error(py: Python<'_>, message: impl Into<String>) -> PyErr {
    to_py(py, &CliError::input(message))
}

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<robot::Robot>()?;
    m.add_class::<task::Task>()?;
    m.add_class::<planning::Plan>()?;
    m.add_class::<planning::Trajectory>()?;
    m.add_function(wrap_pyfunction!(planning::plan, m)?)?;
    m.add_function(wrap_pyfunction!(planning::rollout, m)?)?;
    m.add_function(wrap_pyfunction!(model::model, m)?)?;
    m.add_function(wrap_pyfunction!(checking::check, m)?)?;
    m.add_function(wrap_pyfunction!(monte_carlo::disperse, m)?)?;
    m.add_function(wrap_pyfunction!(monte_carlo::retime, m)?)?;
    m.add("__build__", host_sim::version::Build::current().stamp())?;
    Ok(())
}
