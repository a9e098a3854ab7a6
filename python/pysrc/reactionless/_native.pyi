"""Type stubs of the extension module (units: SI and radians; ``_deg`` names are degrees)."""

from os import PathLike
from pathlib import Path
from typing import Any, Dict, List, Optional, Union

import numpy as np
import numpy.typing as npt

__build__: str

_Path = Union[str, "PathLike[str]"]
_F64 = npt.NDArray[np.float64]

class Robot:
    """A free-floating base with an N-joint serial arm, read from URDF."""

    @staticmethod
    def from_urdf(path_or_string: str, ee: Optional[str] = None) -> "Robot":
        """A URDF file path, or a URDF document (a string holding ``<robot``); ``ee`` the
        end-effector link (default: the chain's last link)."""
    @property
    def name(self) -> str: ...
    @property
    def n_joints(self) -> int: ...
    @property
    def joint_names(self) -> List[str]: ...
    @property
    def ee_link(self) -> str: ...
    @property
    def lower(self) -> _F64:
        """Lower joint limits (rad)."""
    @property
    def upper(self) -> _F64:
        """Upper joint limits (rad)."""
    @property
    def velocity_limits(self) -> _F64:
        """Joint velocity limits (rad/s)."""
    @property
    def urdf(self) -> str: ...

class Task:
    """A planning task (docs/task-format.md): robot, start, target, motion, planner."""

    @staticmethod
    def from_toml(path: _Path) -> "Task":
        """Reads a task file; its ``[robot] urdf`` is relative to the file."""
    @staticmethod
    def from_toml_str(text: str, robot: Robot, origin: Optional[_Path] = None) -> "Task": ...
    @staticmethod
    def from_dict(tables: Dict[str, Any], robot: Robot) -> "Task":
        """A dict of the task file's tables (``start``, ``target``, ``motion``, ``planner``,
        ...); unknown keys raise ``InputError`` as the CLI refuses them."""
    @property
    def toml(self) -> str: ...
    @property
    def path(self) -> Path: ...
    @property
    def robot(self) -> Robot: ...
    @property
    def n_joints(self) -> int: ...
    @property
    def start(self) -> _F64:
        """Start configuration q0 (rad)."""
    @property
    def target_position(self) -> _F64:
        """Target end-effector position (m, inertial frame)."""
    @property
    def target_quat_wxyz(self) -> _F64: ...
    @property
    def tf_s(self) -> float: ...
    @property
    def dt_s(self) -> float: ...
    @property
    def two_phase(self) -> bool: ...

class Trajectory:
    """The samples of a rollout (s, rad, rad/s) and what the core and the truth model made of them."""

    @property
    def t(self) -> _F64:
        """Sample times (s), 0 ... t_f."""
    @property
    def q(self) -> _F64:
        """Joint positions (rad), (S+1) x N."""
    @property
    def qd(self) -> _F64:
        """Joint rates (rad/s), (S+1) x N, constant over each step."""
    @property
    def f(self) -> float:
        """f = |e| of the planner-model end pose against the target."""
    @property
    def phi(self) -> float:
        """Constraint violation Phi (rad); 0 when every joint limit holds."""
    @property
    def truth_f(self) -> float:
        """f of the truth-model end pose (base attitude integrated)."""
    @property
    def base_disturbance_deg(self) -> float:
        """Largest base rotation over the motion (deg, truth model)."""
    @property
    def position_error_m(self) -> float: ...
    @property
    def orientation_error_deg(self) -> float: ...
    @property
    def trajectory_digest(self) -> str:
        """FNV-1a-64 of every sample's bits, as host-sim record's trajectory_digest."""
    @property
    def end_position(self) -> _F64: ...
    @property
    def end_quat_wxyz(self) -> _F64: ...
    def __len__(self) -> int: ...

class Plan:
    """A finished plan: eta, how the search ended, and its trajectory."""

    @property
    def status(self) -> str:
        """'converged' (what was asked is met) or 'not_converged'."""
    @property
    def stop(self) -> str:
        """How the search stopped: 'converged', 'exhausted' or 'stalled'."""
    @property
    def strategy(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def rollouts(self) -> int: ...
    @property
    def iterations(self) -> int: ...
    @property
    def restarts(self) -> int: ...
    @property
    def stagnation_events(self) -> int: ...
    @property
    def trajectory(self) -> Trajectory: ...
    @property
    def wall_time_s(self) -> float:
        """Wall time of the search (s)."""
    @property
    def rust_seconds(self) -> float:
        """Wall time of the whole Rust call (s): search and trajectory."""
    @property
    def eta(self) -> _F64: ...
    @property
    def converged(self) -> bool: ...
    @property
    def f(self) -> float: ...
    @property
    def truth_f(self) -> float: ...
    @property
    def phi(self) -> float: ...
    @property
    def t(self) -> _F64: ...
    @property
    def q(self) -> _F64: ...
    @property
    def qd(self) -> _F64: ...
    def write(self, dir: _Path) -> Path:
        """Writes the plan as ``host-sim plan --out DIR`` does (task.toml, robot.urdf,
        trajectory.csv, summary.json; not plan.json or figures); returns the directory."""

def plan(
    task: Task,
    seed: Optional[int] = None,
    strategy: Optional[str] = None,
    refine_tolerance: Optional[float] = None,
    max_rollouts: Optional[int] = None,
    refine_against: Optional[str] = None,
    paper: bool = False,
    threads: Optional[int] = None,
) -> Plan:
    """Plans ``task`` as ``host-sim plan`` does, bit for bit (``paper=True``: the paper's
    goal f <= sigma_e, as ``host-sim record``; ``threads``: the planner's own worker threads,
    default every core); releases the GIL; Ctrl-C raises KeyboardInterrupt."""

def rollout(task: Task, eta: Union[List[float], _F64]) -> Trajectory:
    """The rollout of eta (2K values per segment: a1, b1, ...) on ``task``."""

def model(robot: Robot, q: Union[List[float], _F64]) -> Dict[str, _F64]:
    """H~b (3x3), H~bm (3xN), the generalized Jacobian (6xN), CoM, RNS basis, EE pose at q (rad)."""

def check(target: Union[_Path, Plan]) -> List[Dict[str, Any]]:
    """``host-sim check``'s verdict rows (check, value, limit, passed) of an output
    directory, or of a Plan (written to a temporary directory first)."""

def disperse(source: Union[Plan, _Path], samples: int, seed: int, **flags: Any) -> Any: ...
def retime(source: Union[Plan, _Path], accel_deg_s2: Optional[float] = None, **flags: Any) -> Any: ...
