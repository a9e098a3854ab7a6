"""The exceptions of the reactionless package.

Every error the library raises is a ``ReactionlessError``. Bad input (a task key, a URDF,
an argument: what the CLI refuses with exit code 2) is an ``InputError``, also a
``ValueError``; a computation that failed or a result that does not pass (exit code 1) is
a ``PlanningError``, also a ``RuntimeError``. The message is the CLI's, naming the key or
argument.
"""


class ReactionlessError(Exception):
    """Any error of the reactionless package."""


class InputError(ReactionlessError, ValueError):
    """Bad input: a task key, a URDF, an argument (the CLI's exit code 2)."""


class PlanningError(ReactionlessError, RuntimeError):
    """A computation that failed, or a result that does not pass (the CLI's exit code 1)."""
