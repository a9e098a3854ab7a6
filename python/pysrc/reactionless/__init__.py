"""reactionless: reactionless motion planning of a free-floating space robot, from Python.

The planner, rollout, checker and model of ``host-sim``, the same code and the same bits
(docs/python.md). Units: SI and radians in every array and attribute; a name ending in
``_deg`` is in degrees.

>>> import reactionless as rl
>>> task = rl.Task.from_toml("spec/tasks/paper.toml")
>>> plan = rl.plan(task, seed=1)
>>> plan.status, plan.f, plan.q.shape        # doctest: +SKIP
('converged', 9.1e-10, (3001, 7))
"""

from ._errors import InputError, PlanningError, ReactionlessError
from . import _native
from ._native import (
    Plan,
    Robot,
    Task,
    Trajectory,
    __build__,
    check,
    model,
    plan,
    rollout,
)


def _table(columns):
    """A pandas DataFrame of the columns when pandas is installed, else the dict."""
    try:
        import pandas
    except ImportError:
        return columns
    return pandas.DataFrame(columns)


def disperse(source, samples, seed, **flags):
    """``host-sim disperse`` of a Plan (or a plan/rollout/retime directory): ``samples``
    dispersed robots of the run seeded ``seed`` flown along the plan.

    ``flags`` are the CLI's, underscores for hyphens: ``mass_rel_sigma=0.05``,
    ``inertia_rel_sigma=0.1``, ``com_sigma_m=0.01``, ``closed_loop=True``, ``jobs=2``...
    (docs/cli.md). Returns ``(runs, summary)``: runs.csv's columns (a pandas DataFrame when
    pandas is installed, else a dict of numpy arrays; one row per sample, units in the
    column names) and summary.json as a dict. Ctrl-C stops the run at its next sample.
    """
    runs, summary = _native.disperse(source, samples, seed, **flags)
    return _table(runs), summary


def retime(source, accel_deg_s2=None, **flags):
    """``host-sim retime`` of a Plan (or a plan directory): the time-optimal re-timing of
    the same path within ``accel_deg_s2`` (deg/s^2, every joint; default the task's
    ``[limits] qdd_max_deg_s2``). Returns ``(samples, summary)``: the re-timed
    trajectory's columns (``t`` s, ``q1..`` rad, ``qd1..`` rad/s, ``qdd1..`` rad/s^2; a
    DataFrame when pandas is installed) and summary.json as a dict.
    """
    samples, summary = _native.retime(source, accel_deg_s2, **flags)
    return _table(samples), summary

__all__ = [
    "InputError",
    "Plan",
    "PlanningError",
    "ReactionlessError",
    "Robot",
    "Task",
    "Trajectory",
    "__build__",
    "check",
    "disperse",
    "model",
    "plan",
    "retime",
    "rollout",
]
