"""Solvers: direct, AMG-preconditioned Krylov, and the nonlinear step drivers.

The linear solvers live in the modules ``pdlin.solvers.linear`` and
``pdlin.solvers.direct``; one load (sub)step of Newton in ``pdlin.solvers.newton``
and of adaptive dynamic relaxation in ``pdlin.solvers.adr`` (their outcome in
``pdlin.solvers.outcome``); the load stepping of :func:`pdlin.solve_nonlinear` in
``pdlin.solvers.stepping``, its options in ``pdlin.solvers.options`` and its
checkpoints in ``pdlin.solvers.checkpoint``.
"""

from .adr import adr_density, adr_step, adr_time_step
from .conditioning import (
    CONDITION_AUTO_MAX,
    CONDITION_WARN,
    condition_estimate,
    warn_if_ill_conditioned,
)
from .direct import AUTO_MIN, DIRECT_BACKENDS, available_direct_backends
from .linear import (
    AMG_DEFAULTS,
    SOLVERS,
    DirectSolver,
    LinearSolveInfo,
    SolverSetup,
    amg_hierarchy,
    solve_linear,
)
from .newton import newton_step
from .outcome import StepFailed, StepOutcome

__all__ = [
    "AUTO_MIN",
    "DIRECT_BACKENDS",
    "available_direct_backends",
    "CONDITION_AUTO_MAX",
    "CONDITION_WARN",
    "condition_estimate",
    "warn_if_ill_conditioned",
    "AMG_DEFAULTS",
    "SOLVERS",
    "DirectSolver",
    "LinearSolveInfo",
    "SolverSetup",
    "amg_hierarchy",
    "solve_linear",
    "StepFailed",
    "StepOutcome",
    "adr_density",
    "adr_step",
    "adr_time_step",
    "newton_step",
]
