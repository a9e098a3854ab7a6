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
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

pub mod checking;
pub mod model;
pub mod monte_carlo;
pub mod planning;
pub mod robot;
pub mod task;

/// The Python exception for a host-sim error: `InputError` (a `ValueError`) for bad input
/// (the CLI's exit code 2), `PlanningError` (a `RuntimeError`) for a result that does not
/// pass or a failed computation (exit code 1), `ReactionlessError` for a broken invariant
/// (`CliError::internal`, a bug: not the caller's input) and anything else. The message is
/// the CLI's, naming the key or argument.
pub fn to_py(py: Python<'_>, e: &CliError) -> PyErr {
    let class = match e.code {
        _ if e.message.starts_with("internal error:") => "ReactionlessError",
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

/// Runs `work` with the GIL released on a worker thread while the calling thread checks
/// for signals every 50 ms (Python handles them on the main thread only, so the check must
/// stay on the caller's). On one (Ctrl-C's `KeyboardInterrupt`), it sets the flag `work`
/// is given and calls `on_interrupt`, waits for `work` to return, and raises the signal's
/// exception; otherwise it returns what `work` returned.
pub fn interruptibly<T: Send>(
    py: Python<'_>,
    on_interrupt: impl Fn() + Send + Sync,
    work: impl FnOnce(&AtomicBool) -> Result<T, CliError> + Send,
) -> PyResult<T> {
    let stop = AtomicBool::new(false);
    let mut interrupt: Option<PyErr> = None;
    let slot = &mut interrupt;
    let result = py.detach(|| {
        std::thread::scope(|scope| {
            let (tx, rx) = mpsc::channel::<()>();
            let stop = &stop;
            let worker = scope.spawn(move || {
                let r = work(stop);
                drop(tx);
                r
            });
            // Until the worker says it is done (it drops its sender, or panics).
            while let Err(mpsc::RecvTimeoutError::Timeout) =
                rx.recv_timeout(Duration::from_millis(50))
            {
                if let Err(e) = Python::attach(|py| py.check_signals()) {
                    *slot = Some(e);
                    stop.store(true, Ordering::SeqCst);
                    on_interrupt();
                }
            }
            worker
                .join()
                .unwrap_or_else(|_| Err(CliError::internal("the run panicked")))
        })
    });
    if let Some(e) = interrupt {
        return Err(e);
    }
    result.map_err(|e| to_py(py, &e))
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
