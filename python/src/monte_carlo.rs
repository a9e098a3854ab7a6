//! `disperse` and `retime`: host-sim's own subcommands run in this process
//! (`cli::run_args`, the same code and the same bits as the binary) into a temporary
//! directory, their files read back as numpy columns and dicts, the directory removed.
//! Nothing is written where the caller looks: an interrupted or failed run leaves nothing.
//!
//! Ctrl-C: the subcommand runs on a worker thread while the calling thread, the GIL
//! released, checks for signals every 50 ms ([`crate::interruptibly`]); on
//! KeyboardInterrupt it asks the run to stop (`drive::cancel`: `disperse` stops at its
//! next sample), waits for it, and raises. The cancel flag is the process's, so in-process
//! runs take turns ([`RUN_LOCK`]).

use crate::planning::Plan;
use host_sim::drive;
use host_sim::error::CliError;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// One in-process CLI run at a time: `drive::cancel` is the process's, so runs from
/// several Python threads take turns (each already uses every core).
static RUN_LOCK: Mutex<()> = Mutex::new(());

/// Runs `args` (after `host-sim`) in this process, interruptibly (see the module doc).
fn run_cli(py: Python<'_>, args: Vec<String>) -> PyResult<()> {
    // Set once this call holds RUN_LOCK: only then may its Ctrl-C cancel the run in flight
    // (before, the run in flight is another thread's).
    let holding = AtomicBool::new(false);
    let holding = &holding;
    let on_interrupt = move || {
        if holding.load(Ordering::SeqCst) {
            drive::cancel();
        }
    };
    crate::interruptibly(py, on_interrupt, move |stop| {
        let _turn = RUN_LOCK
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        drive::reset_cancel();
        holding.store(true, Ordering::SeqCst);
        // Interrupted while waiting for the turn: do not start.
        let r = if stop.load(Ordering::SeqCst) {
            Err(CliError::failed("interrupted"))
        } else {
            host_sim::cli::run_args(std::iter::once("host-sim".to_string()).chain(args))
        };
        holding.store(false, Ordering::SeqCst);
        drive::reset_cancel();
        r
    })
}

/// The directory a `Plan` or a path names: a path as is, a `Plan` written into `tmp`.
fn source_dir(py: Python<'_>, source: &Bound<'_, PyAny>, tmp: &Path) -> PyResult<PathBuf> {
    if let Ok(plan) = source.cast::<Plan>() {
        let plan = plan.get().clone();
        let out = tmp.join("plan");
        py.detach(move || plan.write_to(&out))
            .map_err(|e| crate::to_py(py, &e))
    } else {
        source.extract()
    }
}

/// `--name value` flags from keyword arguments (`mass_rel_sigma=0.05` is
/// `--mass-rel-sigma 0.05`; `True` is the bare flag, `False` and `None` are left out; a
/// list is comma-separated).
fn flags(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<String>> {
    let mut out = Vec::new();
    let Some(kw) = kwargs else {
        return Ok(out);
    };
    for (k, v) in kw.iter() {
        let name = format!("--{}", k.extract::<String>()?.replace('_', "-"));
        if v.is_none() {
            continue;
        }
        if let Ok(b) = v.extract::<bool>() {
            if b {
                out.push(name);
            }
            continue;
        }
        let text = if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
            let parts: Vec<String> = v
                .try_iter()?
                .map(|x| x.and_then(|x| Ok(x.str()?.to_string())))
                .collect::<PyResult<_>>()?;
            parts.join(",")
        } else {
            v.str()?.to_string()
        };
        out.push(name);
        out.push(text);
    }
    Ok(out)
}

/// A CSV of numbers as a dict of numpy columns (float64; `sample` as int64).
fn columns<'py>(py: Python<'py>, path: &Path) -> PyResult<Bound<'py, PyDict>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| crate::to_py(py, &CliError::internal(format!("{}: {e}", path.display()))))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); header.len()];
    for (row, line) in lines.enumerate() {
        for (c, cell) in line.split(',').enumerate() {
            let v: f64 = cell.parse().map_err(|_| {
                crate::to_py(
                    py,
                    &CliError::internal(format!("{} row {}: {cell:?}", path.display(), row + 1)),
                )
            })?;
            if let Some(col) = cols.get_mut(c) {
                col.push(v);
            }
        }
    }
    let d = PyDict::new(py);
    for (name, col) in header.iter().zip(cols) {
        if *name == "sample" {
            #[allow(clippy::cast_possible_truncation)]
            let ints: Vec<i64> = col.iter().map(|v| *v as i64).collect();
            d.set_item(*name, PyArray1::from_vec(py, ints))?;
        } else {
            d.set_item(*name, PyArray1::from_vec(py, col))?;
        }
    }
    Ok(d)
}

/// A JSON file as Python objects.
fn json<'py>(py: Python<'py>, path: &Path) -> PyResult<Bound<'py, PyAny>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| crate::to_py(py, &CliError::internal(format!("{}: {e}", path.display()))))?;
    py.import("json")?.call_method1("loads", (text,))
}

fn tempdir(py: Python<'_>) -> PyResult<tempfile::TempDir> {
    tempfile::tempdir().map_err(|e| {
        crate::to_py(
            py,
            &CliError::internal(format!("a temporary directory: {e}")),
        )
    })
}

/// `host-sim disperse` of a `Plan` (or a plan, rollout or retime directory): `samples`
/// dispersed robots of the run seeded `seed` flown along the plan. Keyword arguments are
/// the CLI's flags (`mass_rel_sigma=0.05`, `inertia_rel_sigma=0.1`, `com_sigma_m=0.01`,
/// `closed_loop=True`, `jobs=2`, ...; docs/cli.md). Returns `(runs, summary)`: runs.csv as
/// a dict of numpy columns (one row per sample), summary.json as a dict. Ctrl-C stops it
/// at the next sample.
#[pyfunction]
#[pyo3(signature = (source, samples, seed, **kwargs))]
pub fn disperse<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    samples: usize,
    seed: u64,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
    let tmp = tempdir(py)?;
    let dir = source_dir(py, source, tmp.path())?;
    let out = tmp.path().join("disperse");
    let mut args = vec![
        "disperse".to_string(),
        dir.display().to_string(),
        "--samples".into(),
        samples.to_string(),
        "--seed".into(),
        seed.to_string(),
    ];
    args.extend(flags(kwargs)?);
    args.extend(["--out".to_string(), out.display().to_string()]);
    run_cli(py, args)?;
    Ok((
        columns(py, &out.join("runs.csv"))?,
        json(py, &out.join("summary.json"))?,
    ))
}

/// `host-sim retime` of a `Plan` (or a plan directory): the time-optimal re-timing along
/// the same path within the acceleration limit `accel_deg_s2` (deg/s², every joint;
/// default the task's `[limits] qdd_max_deg_s2`). Keyword arguments are the CLI's other
/// flags (`grid=4000`). Returns `(samples, summary)`: the re-timed trajectory.csv as a
/// dict of numpy columns (`t` in s, `q1..` rad, `qd1..` rad/s, `qdd1..` rad/s²) and its
/// summary.json as a dict.
#[pyfunction]
#[pyo3(signature = (source, accel_deg_s2 = None, **kwargs))]
pub fn retime<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    accel_deg_s2: Option<f64>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
    let tmp = tempdir(py)?;
    let dir = source_dir(py, source, tmp.path())?;
    let out = tmp.path().join("retimed");
    let mut args = vec!["retime".to_string(), dir.display().to_string()];
    if let Some(a) = accel_deg_s2 {
        args.extend(["--accel-deg-s2".to_string(), a.to_string()]);
    }
    args.extend(flags(kwargs)?);
    args.extend(["--out".to_string(), out.display().to_string()]);
    run_cli(py, args)?;
    Ok((
        columns(py, &out.join("trajectory.csv"))?,
        json(py, &out.join("summary.json"))?,
    ))
}
