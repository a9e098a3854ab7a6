//! `Task`: a planning task, read by host-sim's task reader from a TOML file, from TOML
//! text, or from a Python dict of the same tables (docs/task-format.md). Every route goes
//! through the same parser, so unknown keys and bad values are refused with the CLI's
//! message naming the key.

use crate::robot::Robot;
use host_sim::taskfile::{self, LoadedTask};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use std::path::{Path, PathBuf};

/// A task: robot, start, target, motion and planner settings (SI units and radians in
/// every attribute; the TOML's own keys carry their units, e.g. `q_deg`).
#[pyclass(frozen, module = "reactionless")]
#[derive(Debug, Clone)]
pub struct Task {
    pub(crate) lt: LoadedTask,
}

/// Python values as TOML: bool, int, float, str, list/tuple and dict (string keys), nested;
/// numpy scalars and arrays through their `tolist()`.
fn to_toml(py: Python<'_>, key: &str, v: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    let bad = |what: &str| crate::input_error(py, format!("task key {key:?}: {what}"));
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(
            v.extract().map_err(|_| bad("integer out of range"))?,
        ));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::map::Map::new();
        for (k, item) in d.iter() {
            let k: String = k
                .extract()
                .map_err(|_| bad("a table's keys must be strings"))?;
            let full = if key.is_empty() {
                k.clone()
            } else {
                format!("{key}.{k}")
            };
            t.insert(k, to_toml(py, &full, &item)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut out = Vec::new();
        for item in v.try_iter()? {
            out.push(to_toml(py, key, &item?)?);
        }
        return Ok(toml::Value::Array(out));
    }
    if v.hasattr("tolist")? {
        return to_toml(py, key, &v.call_method0("tolist")?);
    }
    Err(bad(&format!(
        "{} is not a TOML value (bool, int, float, str, list, dict)",
        v.get_type().name()?
    )))
}

#[pymethods]
impl Task {
    /// Reads a task file (TOML); its `[robot] urdf` is relative to the file.
    #[staticmethod]
    fn from_toml(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        taskfile::load(&path)
            .map(|lt| Self { lt })
            .map_err(|e| crate::to_py(py, &e))
    }

    /// A task from TOML text and its robot (`[robot] urdf` is then only a name).
    #[staticmethod]
    #[pyo3(signature = (text, robot, origin = None))]
    fn from_toml_str(
        py: Python<'_>,
        text: &str,
        robot: &Robot,
        origin: Option<PathBuf>,
    ) -> PyResult<Self> {
        let origin = origin.unwrap_or_else(|| PathBuf::from("<python>"));
        taskfile::from_texts(&origin, text, &robot.urdf_text)
            .map(|lt| Self { lt })
            .map_err(|e| crate::to_py(py, &e))
    }

    /// A task from a dict of the task file's tables (`start`, `target`, `motion`,
    /// `planner`, ...; docs/task-format.md) and its robot. `robot.urdf` and
    /// `robot.ee_link` default to the robot's. Unknown keys are refused.
    #[staticmethod]
    fn from_dict(py: Python<'_>, tables: &Bound<'_, PyDict>, robot: &Robot) -> PyResult<Self> {
        let toml::Value::Table(mut t) = to_toml(py, "", tables.as_any())? else {
            return Err(crate::input_error(py, "a task is a dict of tables"));
        };
        let section = t
            .entry("robot")
            .or_insert_with(|| toml::Value::Table(toml::map::Map::new()));
        if let toml::Value::Table(r) = section {
            r.entry("urdf")
                .or_insert_with(|| toml::Value::String(robot.origin.display().to_string()));
            r.entry("ee_link")
                .or_insert_with(|| toml::Value::String(robot.chain.ee_link.clone()));
        }
        let text = toml::to_string(&toml::Value::Table(t))
            .map_err(|e| crate::input_error(py, format!("task: {e}")))?;
        Self::from_toml_str(py, &text, robot, None)
    }

    /// The task file's text (for a dict, the TOML it became).
    #[getter]
    fn toml(&self) -> String {
        self.lt.text.clone()
    }

    /// Where the task came from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.lt.path.clone()
    }

    /// The robot.
    #[getter]
    fn robot(&self) -> Robot {
        Robot {
            chain: self.lt.chain.clone(),
            urdf_text: self.lt.urdf_text.clone(),
            origin: self.lt.urdf_path.clone(),
        }
    }

    /// Number of joints N.
    #[getter]
    fn n_joints(&self) -> usize {
        self.lt.chain.dof()
    }

    /// Start configuration q₀ (rad).
    #[getter]
    fn start<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.lt.start_rad())
    }

    /// Target end-effector position (m, inertial frame).
    #[getter]
    fn target_position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.lt.file.target.position_m.clone())
    }

    /// Target end-effector attitude, unit quaternion `[w, x, y, z]`.
    #[getter]
    fn target_quat_wxyz<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.lt.file.target.quat_wxyz.clone())
    }

    /// Duration t_f (s).
    #[getter]
    fn tf_s(&self) -> f64 {
        self.lt.file.motion.tf_s
    }

    /// Integration step dt (s).
    #[getter]
    fn dt_s(&self) -> f64 {
        self.lt.file.motion.dt_s
    }

    /// Whether the task plans in two phases (`[preshape]`).
    #[getter]
    fn two_phase(&self) -> bool {
        self.lt.file.preshape.is_some()
    }

    fn __repr__(&self) -> String {
        format!(
            "Task({}, {} joints, t_f {} s)",
            Path::new(&self.lt.path).display(),
            self.lt.chain.dof(),
            self.lt.file.motion.tf_s
        )
    }
}
