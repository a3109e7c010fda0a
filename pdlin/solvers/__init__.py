"""Solvers: direct, AMG-preconditioned Krylov, and the nonlinear step drivers (Newton, ADR)."""

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
