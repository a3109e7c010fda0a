"""Exception classes of pdlin.

Every class subclasses a builtin (``ValueError``, ``TypeError``, ``OSError``, ``ImportError`` or
``RuntimeError``) so callers can catch either the specific pdlin error or the
builtin one.  Messages name the argument, what was expected and what was
received.
"""

from __future__ import annotations

__all__ = [
    "PdlinError",
    "InputError",
    "InputTypeError",
    "ShapeError",
    "NonFiniteError",
    "DuplicatePointError",
    "NoNeighborsError",
    "FloatingBodyError",
    "ConvergenceError",
    "CheckpointError",
    "CheckpointWriteError",
    "MissingDependencyError",
    "WriteError",
    "InsufficientMemoryError",
    "SceneError",
    "ModelError",
    "TrialStateWarning",
    "ActiveSetWarning",
    "AccuracyWarning",
    "SlowRunWarning",
    "InstabilityError",
    "TimeStepWarning",
]


class PdlinError(Exception):
    """Base class of every pdlin exception."""


class InputError(PdlinError, ValueError):
    """An argument has an invalid value."""


class InputTypeError(PdlinError, TypeError):
    """An argument has an invalid type."""


class ShapeError(InputError):
    """An array argument has the wrong shape."""


class NonFiniteError(InputError):
    """An array argument holds NaN or infinity."""


class DuplicatePointError(InputError):
    """Two points of a cloud coincide."""

    def __init__(self, message: str, first: int, second: int) -> None:
        super().__init__(message)
        self.first = int(first)
        self.second = int(second)


class NoNeighborsError(InputError):
    """A point has no bonds, so its equilibrium equation is empty."""


class FloatingBodyError(InputError):
    """Boundary conditions leave rigid-body motions free (singular stiffness)."""


class ModelError(InputError):
    """A model was asked for something it cannot represent."""


class SceneError(InputError):
    """A scene file is invalid; the message names the offending key."""


class ConvergenceError(PdlinError, RuntimeError):
    """An iterative solver did not reach its tolerance."""

    def __init__(self, message: str, result: object | None = None) -> None:
        super().__init__(message)
        self.result = result


class CheckpointError(InputError):
    """A checkpoint cannot be resumed: unreadable, or written for another problem.

    Raised by :func:`pdlin.solve_nonlinear` with ``resume=True``; the message names the
    file and, for another problem, which parts of it differ.
    """


class InstabilityError(ConvergenceError):
    """An explicit time integration became unstable (non-finite or exploding fields).

    Raised by ``pdlin.dynamics.solve_explicit`` before a NaN or an infinity can
    reach a result; the message names the step, the time, the time step and its estimate.
    """


class MissingDependencyError(PdlinError, ImportError):
    """An optional dependency is not installed; the message names the extra to install."""


class WriteError(PdlinError, OSError):
    """An output file could not be written (full disk, file-size limit, no permission).

    The message names the file and the reason; the file's previous version, if any,
    is left as it was.
    """


class CheckpointWriteError(WriteError):
    """Writing a checkpoint or an ADR snapshot failed (e.g. a full disk).

    The message names the file; the previous checkpoint is left as it was and no
    temporary file is left behind.
    """


class InsufficientMemoryError(PdlinError, MemoryError):
    """A stage would need more memory than is available (estimated before allocating).

    Attributes
    ----------
    need, available : int
        Estimated bytes of the stage and the bytes available when it was checked.
    hints : tuple of str
        What would fit instead (a coarser grid, an iterative solver, ...).
    """

    def __init__(self, message: str, need: int = 0, available: int = 0, hints: object = ()) -> None:
        super().__init__(message)
        self.need = int(need)
        self.available = int(available)
        self.hints = tuple(hints) if isinstance(hints, list | tuple) else ()


class TrialStateWarning(RuntimeWarning):
    """A material's state update is questionable at some points.

    The nonlinear drivers ignore it on trial iterates (Newton trials, line-search and ADR
    states are discarded) and re-issue what :meth:`pdlin.models.Model.committed_issues`
    reports on each committed state.  Subclasses name the cause.
    """


class ActiveSetWarning(TrialStateWarning):
    """A crystal-plasticity active-set search did not settle at some points.

    Issued by :meth:`pdlin.CrystalPlasticity.update` (``active_set="reactivate"``) when
    points still violate the yield condition on an inactive system after ``max_passes``
    re-activation passes or cycle between active sets; the message gives their number.
    Promote it to an error with ``warnings.simplefilter("error", ActiveSetWarning)``.
    """


class AccuracyWarning(UserWarning):
    """A result is computed but pdlin measured a cause that makes it inaccurate.

    Raised for example by :class:`pdlin.LPS` near incompressibility, where
    the bulk modulus amplifies the dilatation error of truncated families
    (``docs/solvers.md``, "Numerical extremes").
    """


class SlowRunWarning(UserWarning):
    """A run is estimated, before it starts, to take longer than a long-run limit.

    The limit is ``pdlin.resources.LONG_RUN_SECONDS``; the message gives the estimate
    and its sizes (points, bonds, nonzeros).
    """


class TimeStepWarning(UserWarning):
    """A given explicit time step exceeds the estimated stable one.

    Issued by ``pdlin.dynamics.solve_explicit``; the message gives both steps and the
    estimate's method.  Promote it to an error with
    ``warnings.simplefilter("error", TimeStepWarning)``.
    """
