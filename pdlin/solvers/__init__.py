"""Solvers: direct, AMG-preconditioned Krylov, and the nonlinear step drivers (Newton, ADR)."""

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
from .nonlinear import (
    StepFailed,
    StepOutcome,
    adr_density,
    adr_step,
    adr_time_step,
    newton_step,
)

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
