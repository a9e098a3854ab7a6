//! `plan` and `rollout`: host-sim's planner (`drive::plan_with`, the settings `host-sim
//! plan` resolves from the task and its flags) and its written rollout
//! (`artifacts::write_rollout`: the samples, the truth model, the trajectory digest), with
//! the GIL released and Ctrl-C checked between slices of planning. Owns `Plan` and
//! `Trajectory`, whose arrays are numpy copies (seconds, radians, rad/s).

use crate::task::Task;
use host_sim::args::{eta_error, parse_eta, parse_refine_against, parse_strategy};
use host_sim::artifacts::{summary, write_bundle, write_rollout};
use host_sim::drive::{self, HOST_CAPACITY};
use host_sim::error::CliError;
use host_sim::goal::Asked as Goal;
use host_sim::goal::status_name;
use host_sim::output::OutDir;
use host_sim::taskfile::{LoadedTask, Overrides};
use host_sim::with_dims;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use reactionless::{PlannerConfig, Rollout, eta_flat};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

/// The samples of a rollout and what the core and the truth model made of them.
#[pyclass(frozen, module = "reactionless")]
#[derive(Debug, Clone)]
pub struct Trajectory {
    t: Vec<f64>,
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    /// f = ‖e‖ of the planner-model end pose against the target.
    #[pyo3(get)]
    f: f64,
    /// Constraint violation Φ (rad); 0 when every joint limit holds.
    #[pyo3(get)]
    phi: f64,
    /// f of the truth-model end pose (base attitude integrated) against the target.
    #[pyo3(get)]
    truth_f: f64,
    /// Largest base rotation over the motion (deg, truth model).
    #[pyo3(get)]
    base_disturbance_deg: f64,
    /// End-effector position error ‖p_des − p‖ (m), planner model.
    #[pyo3(get)]
    position_error_m: f64,
    /// End-effector orientation error (deg), planner model.
    #[pyo3(get)]
    orientation_error_deg: f64,
    end_position: [f64; 3],
    end_quat_wxyz: [f64; 4],
    /// FNV-1a-64 digest of every sample's bits, `0x` and 16 hex digits (as `host-sim
    /// record`'s `trajectory_digest`).
    #[pyo3(get)]
    trajectory_digest: String,
}

#[pymethods]
impl Trajectory {
    /// Sample times (s), 0 … t_f.
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.t)
    }

    /// Joint positions (rad), one row per sample (S+1 × N).
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Ok(PyArray2::from_vec2(py, &self.q)?)
    }

    /// Joint rates (rad/s), one row per sample (S+1 × N), constant over each step.
    #[getter]
    fn qd<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        Ok(PyArray2::from_vec2(py, &self.qd)?)
    }

    /// End-effector position at t_f (m, inertial frame), planner model.
    #[getter]
    fn end_position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.end_position)
    }

    /// End-effector attitude at t_f, unit quaternion `[w, x, y, z]`, planner model.
    #[getter]
    fn end_quat_wxyz<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.end_quat_wxyz)
    }

    /// Number of samples S+1.
    fn __len__(&self) -> usize {
        self.t.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Trajectory({} samples, f {:.3e}, base disturbance {:.3e} deg)",
            self.t.len(),
            self.f,
            self.base_disturbance_deg
        )
    }
}

/// A finished plan: η, how the search ended, and its trajectory.
#[pyclass(frozen, module = "reactionless")]
#[derive(Debug, Clone)]
pub struct Plan {
    eta: Vec<f64>,
    /// `converged` (what was asked is met) or `not_converged`.
    #[pyo3(get)]
    status: String,
    /// How the search stopped: `converged`, `exhausted` or `stalled`.
    #[pyo3(get)]
    stop: String,
    /// The strategy: `multistart` or `cpso`.
    #[pyo3(get)]
    strategy: String,
    /// The seed the search used.
    #[pyo3(get)]
    seed: u64,
    /// Rollouts, search and refinement.
    #[pyo3(get)]
    rollouts: u32,
    /// Multistart: accepted LM steps; C-PSO: generations after the first.
    #[pyo3(get)]
    iterations: u32,
    /// Multistart restarts (0 for C-PSO).
    #[pyo3(get)]
    restarts: u32,
    /// C-PSO stagnation alarms (0 for the multistart).
    #[pyo3(get)]
    stagnation_events: u32,
    /// The plan's rollout.
    #[pyo3(get)]
    trajectory: Trajectory,
    /// Wall time of the search (s).
    #[pyo3(get)]
    wall_time_s: f64,
    /// Wall time of the whole Rust call (s): the search and the plan's trajectory, without
    /// the binding's own work (what `plan()`'s overhead is measured against).
    #[pyo3(get)]
    rust_seconds: f64,
    /// The task, the settings and the goal it was planned with (for [`Plan::write`]).
    lt: LoadedTask,
    config: PlannerConfig,
    goal: Goal,
}

/// Writes `p`'s bundle into `out` as `host-sim plan --out` does (task.toml and robot.urdf
/// with the settings used, trajectory.csv, summary.json).
fn write_n<const N: usize, const K: usize>(p: &Plan, out: &Path) -> Result<PathBuf, CliError> {
    let task = p.lt.task::<N, K>()?;
    let eta = parse_eta::<K>(&p.eta, task.motion().segments())?;
    let dir = OutDir::create(out)?;
    let run = write_rollout(&task, &eta, Some(&dir), false)?;
    dir.write_json(
        "summary.json",
        &summary(&task, &eta, &run.outcome, &run.truth),
    )?;
    write_bundle(&p.lt, &dir, Some((&p.config, &p.goal)))?;
    dir.commit()
}

impl Plan {
    /// [`write_n`] for the plan's joint count.
    pub(crate) fn write_to(&self, out: &Path) -> Result<PathBuf, CliError> {
        with_dims!(self.lt.chain.dof(), write_n, self, out)
    }
}

#[pymethods]
impl Plan {
    /// η, `a1, b1, …, aK, bK` of each segment in turn.
    #[getter]
    fn eta<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.eta)
    }

    /// Whether the plan meets what was asked.
    #[getter]
    fn converged(&self) -> bool {
        self.status == "converged"
    }

    /// f of the plan's rollout (planner model).
    #[getter]
    fn f(&self) -> f64 {
        self.trajectory.f
    }

    /// f of the truth-model end pose.
    #[getter]
    fn truth_f(&self) -> f64 {
        self.trajectory.truth_f
    }

    /// Constraint violation Φ (rad).
    #[getter]
    fn phi(&self) -> f64 {
        self.trajectory.phi
    }

    /// Sample times (s) of the plan's trajectory.
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.trajectory.t(py)
    }

    /// Joint positions (rad) of the plan's trajectory (S+1 × N).
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.trajectory.q(py)
    }

    /// Joint rates (rad/s) of the plan's trajectory (S+1 × N).
    #[getter]
    fn qd<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.trajectory.qd(py)
    }

    /// Writes the plan as `host-sim plan --out DIR` does, the same bytes: `task.toml` and
    /// `robot.urdf` (with the settings used), `trajectory.csv` and `summary.json`, which
    /// `check`, `view`, `retime` and `disperse` read (not `plan.json` or the figures).
    /// A directory that exists must be empty or an earlier host-sim output. Returns the
    /// directory.
    fn write(&self, py: Python<'_>, dir: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| self.write_to(&dir))
            .map_err(|e| crate::to_py(py, &e))
    }

    fn __repr__(&self) -> String {
        format!(
            "Plan({}, f {:.3e}, {} rollouts, {})",
            self.status, self.trajectory.f, self.rollouts, self.strategy
        )
    }
}

/// The rollout of `eta` on `task` as a [`Trajectory`].
fn trajectory_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    eta: &reactionless::Eta<K>,
) -> Result<Trajectory, CliError> {
    let task = lt.task::<N, K>()?;
    let run = write_rollout(&task, eta, None, true)?;
    let trace = run
        .trace
        .ok_or_else(|| CliError::internal("the rollout kept no samples"))?;
    let o = &run.outcome;
    Ok(Trajectory {
        t: trace.t,
        q: trace.q,
        qd: trace.qd,
        f: o.f,
        phi: o.phi,
        truth_f: run.truth.f,
        base_disturbance_deg: run.truth.base_disturbance_deg,
        position_error_m: o.error.position_m(),
        orientation_error_deg: o.error.orientation_deg(),
        end_position: o.end_pose.position,
        end_quat_wxyz: o.end_pose.quat_wxyz,
        trajectory_digest: format!("{:#018x}", run.digest.value()),
    })
}

fn rollout_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    eta: &[f64],
) -> Result<Trajectory, CliError> {
    let task = lt.task::<N, K>()?;
    let eta = parse_eta::<K>(eta, task.motion().segments())?;
    Rollout::of(&task, &eta).map_err(eta_error)?;
    trajectory_n::<N, K>(lt, &eta)
}

/// What `plan` was asked, beyond the task file.
#[derive(Debug, Clone, Copy)]
struct Asked {
    overrides: Overrides,
    max_rollouts: Option<u32>,
}

fn plan_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    asked: Asked,
    between: &mut dyn FnMut() -> Result<(), CliError>,
) -> Result<Plan, CliError> {
    if lt.file.preshape.is_some() {
        return Err(CliError::input(format!(
            "{}: a two-phase task ([preshape]) is planned by `host-sim plan`; the Python \
             binding plans single-phase tasks",
            lt.path.display()
        )));
    }
    let (mut config, goal) = lt.plan_settings(HOST_CAPACITY, &asked.overrides)?;
    if let Some(m) = asked.max_rollouts {
        config.max_rollouts = m;
        config
            .validate(HOST_CAPACITY)
            .map_err(|e| CliError::input(format!("max_rollouts = {m}: {e}")))?;
    }
    let task = lt.task::<N, K>()?;
    let done = drive::plan_with::<N, K>(lt, config, false, between)?;
    let p = done.plan;
    let trajectory = trajectory_n::<N, K>(lt, &p.eta)?;
    Ok(Plan {
        eta: eta_flat(&p.eta, task.motion().segments()).collect(),
        status: status_name(p.converged()).into(),
        stop: p.stop.name().into(),
        strategy: p.strategy.name().into(),
        seed: config.seed,
        rollouts: p.rollouts,
        iterations: p.iterations,
        restarts: p.restarts,
        stagnation_events: p.stagnation_events,
        trajectory,
        wall_time_s: done.seconds,
        rust_seconds: 0.0,
        lt: lt.clone(),
        config,
        goal,
    })
}

/// Plans `task` as `host-sim plan` does, bit for bit: the task's `[planner]` settings and
/// goal, with `seed`, `strategy` (`"multistart"` or `"cpso"`), `refine_tolerance`,
/// `refine_against` (`"planner"` or `"truth"`) and `max_rollouts` replacing the task's when
/// given, and `paper=True` for the paper's goal `f ≤ σ_e` instead of the pose tolerances
/// (the CLI's `--paper`, as `host-sim record` plans). `threads` sets the planner's own
/// worker threads (default: rayon's shared pool, every core); one per plan lets plans in
/// several Python threads run side by side. The bits do not depend on it. Releases the GIL
/// while planning; Ctrl-C raises `KeyboardInterrupt` (the planner stops after its current
/// slice). A plan that does not converge is returned (see `Plan.status`), not raised.
#[pyfunction]
#[pyo3(signature = (task, seed = None, strategy = None, refine_tolerance = None, max_rollouts = None, refine_against = None, paper = false, threads = None))]
#[allow(clippy::too_many_arguments)]
pub fn plan(
    py: Python<'_>,
    task: &Task,
    seed: Option<u64>,
    strategy: Option<&str>,
    refine_tolerance: Option<f64>,
    max_rollouts: Option<u32>,
    refine_against: Option<&str>,
    paper: bool,
    threads: Option<usize>,
) -> PyResult<Plan> {
    let strategy = strategy
        .map(parse_strategy)
        .transpose()
        .map_err(|m| crate::input_error(py, format!("strategy: {m}")))?;
    let refine_against = refine_against
        .map(parse_refine_against)
        .transpose()
        .map_err(|m| crate::input_error(py, format!("refine_against: {m}")))?;
    let asked = Asked {
        overrides: Overrides {
            seed,
            refine_tolerance,
            strategy,
            refine_against,
            paper,
            integrator: None,
        },
        max_rollouts,
    };
    let pool = match threads {
        None => None,
        Some(0) => return Err(crate::input_error(py, "threads = 0: give at least 1")),
        Some(t) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .map_err(|e| crate::input_error(py, format!("threads = {t}: {e}")))?,
        ),
    };
    let lt = &task.lt;
    crate::interruptibly(
        py,
        || {},
        |stop| {
            let mut between = || -> Result<(), CliError> {
                if stop.load(Ordering::SeqCst) {
                    Err(CliError::failed("interrupted"))
                } else {
                    Ok(())
                }
            };
            let mut run = || {
                let start = std::time::Instant::now();
                let mut p = with_dims!(lt.chain.dof(), plan_n, lt, asked, &mut between)?;
                p.rust_seconds = start.elapsed().as_secs_f64();
                Ok(p)
            };
            match &pool {
                Some(p) => p.install(run),
                None => run(),
            }
        },
    )
}

/// The rollout of `eta` (`2K·segments` values, `a1, b1, …`) on `task`, as `host-sim
/// rollout` writes it. Releases the GIL.
#[pyfunction]
pub fn rollout(py: Python<'_>, task: &Task, eta: Vec<f64>) -> PyResult<Trajectory> {
    let lt = &task.lt;
    py.detach(|| with_dims!(lt.chain.dof(), rollout_n, lt, &eta))
        .map_err(|e| crate::to_py(py, &e))
}
