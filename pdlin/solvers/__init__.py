"""Solvers: direct, AMG-preconditioned Krylov, and (later) ADR / Newton."""

from .linear import (
    AMG_DEFAULTS,
    SOLVERS,
    DirectSolver,
    LinearSolveInfo,
    amg_hierarchy,
    solve_linear,
)

__all__ = [
    "AMG_DEFAULTS",
    "SOLVERS",
    "DirectSolver",
    "LinearSolveInfo",
    "amg_hierarchy",
    "solve_linear",
]
