"""Solvers: direct, AMG-preconditioned Krylov, and the nonlinear step drivers.

The linear solvers live in :mod:`~pdlin.solvers.linear` and :mod:`~pdlin.solvers.direct`;
one load (sub)step of Newton in :mod:`~pdlin.solvers.newton` and of adaptive dynamic
relaxation in :mod:`~pdlin.solvers.adr` (their outcome in :mod:`~pdlin.solvers.outcome`);
the load stepping of :func:`pdlin.solve_nonlinear` in :mod:`~pdlin.solvers.stepping`,
its options in :mod:`~pdlin.solvers.options` and its checkpoints in
:mod:`~pdlin.solvers.checkpoint`.
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
    "amg_hierarchy",
    "solve_linear",
    "StepFailed",
    "StepOutcome",
    "adr_density",
    "adr_step",
    "adr_time_step",
    "newton_step",
]
