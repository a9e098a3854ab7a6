"""Type stubs of the reactionless package (units: SI and radians; ``_deg`` names are degrees)."""

from os import PathLike
from typing import Any, Dict, Optional, Tuple, Union

from ._errors import InputError as InputError
from ._errors import PlanningError as PlanningError
from ._errors import ReactionlessError as ReactionlessError
from ._native import Plan as Plan
from ._native import Robot as Robot
from ._native import Task as Task
from ._native import Trajectory as Trajectory
from ._native import __build__ as __build__
from ._native import check as check
from ._native import model as model
from ._native import plan as plan
from ._native import rollout as rollout

_Source = Union[Plan, str, "PathLike[str]"]

def disperse(source: _Source, samples: int, seed: int, **flags: Any) -> Tuple[Any, Dict[str, Any]]:
    """host-sim disperse: (runs.csv as a DataFrame or dict of numpy columns, summary.json)."""

def retime(source: _Source, accel_deg_s2: Optional[float] = None, **flags: Any) -> Tuple[Any, Dict[str, Any]]:
    """host-sim retime: (the re-timed samples as a DataFrame or dict of numpy columns, summary.json)."""
