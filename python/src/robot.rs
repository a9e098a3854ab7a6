//! `Robot`: a robot read from URDF (host-sim's reader: the same chain, the same bits as the
//! CLI's), with its joint names and limits as numpy arrays (rad, rad/s).

use host_sim::urdf::{self, Chain};
use numpy::PyArray1;
use pyo3::prelude::*;
use std::path::PathBuf;

/// A free-floating base with an N-joint serial arm, read from URDF.
#[pyclass(frozen, module = "reactionless")]
#[derive(Debug, Clone)]
pub struct Robot {
    pub(crate) chain: Chain,
    pub(crate) urdf_text: String,
    /// Where the URDF came from (a path, or `<string>`), for messages.
    pub(crate) origin: PathBuf,
}

#[pymethods]
impl Robot {
    /// Reads a robot from a URDF file path or a URDF document (a string holding `<robot`).
    /// `ee` names the end-effector link (default: the chain's last link).
    #[staticmethod]
    #[pyo3(signature = (path_or_string, ee = None))]
    fn from_urdf(py: Python<'_>, path_or_string: &str, ee: Option<&str>) -> PyResult<Self> {
        let (text, origin) = if path_or_string.contains("<robot") {
            (path_or_string.to_string(), PathBuf::from("<string>"))
        } else {
            let p = PathBuf::from(path_or_string);
            let text = std::fs::read_to_string(&p).map_err(|e| {
                crate::input_error(py, format!("{}: cannot read URDF: {e}", p.display()))
            })?;
            (text, p)
        };
        let chain = urdf::parse(&text, ee)
            .map_err(|m| crate::input_error(py, format!("{}: {m}", origin.display())))?;
        Ok(Self {
            chain,
            urdf_text: text,
            origin,
        })
    }

    /// The robot's name (URDF).
    #[getter]
    fn name(&self) -> String {
        self.chain.name.clone()
    }

    /// Number of revolute joints N.
    #[getter]
    fn n_joints(&self) -> usize {
        self.chain.dof()
    }

    /// Revolute joint names, base to tip.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.chain.joint_names.clone()
    }

    /// The end-effector link.
    #[getter]
    fn ee_link(&self) -> String {
        self.chain.ee_link.clone()
    }

    /// Lower joint limits (rad).
    #[getter]
    fn lower<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.chain.joints.iter().map(|j| j.lower).collect())
    }

    /// Upper joint limits (rad).
    #[getter]
    fn upper<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.chain.joints.iter().map(|j| j.upper).collect())
    }

    /// Joint velocity limits (rad/s).
    #[getter]
    fn velocity_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.chain.joints.iter().map(|j| j.velocity).collect())
    }

    /// The URDF document as read.
    #[getter]
    fn urdf(&self) -> String {
        self.urdf_text.clone()
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot({:?}, {} joints, ee {:?})",
            self.chain.name,
            self.chain.dof(),
            self.chain.ee_link
        )
    }
}
