"""What one load (sub)step returns or raises, and the system calls both step drivers share.

:class:`StepOutcome` and :class:`StepFailed` are the contract between the single-step
drivers (:func:`~pdlin.solvers.newton.newton_step`, :func:`~pdlin.solvers.adr.adr_step`)
and the load stepping of :func:`pdlin.solve_nonlinear`
(:mod:`pdlin.solvers.stepping`), which turns a failure into a cut-back or an ADR
fallback.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ConvergenceError, NonFiniteError

__all__ = ["StepOutcome", "StepFailed"]


@dataclass
class StepOutcome:
    """Result of one load (sub)step.

    Attributes
    ----------
    u : (ndof,) ndarray
        Converged displacement (prescribed values included).
    response : Response
        The model's response at ``u`` (force, trial state to commit, stress).
    iterations : int
        Newton iterations (linear solves) or ADR iterations.
    calls : int
        Constitutive evaluations (points x updates).
    residual : float
        Final ``‖r_free‖ / force scale``.
    history : list of float
        Relative residual per iteration.
    damping : (k,) ndarray, optional
        ADR damping coefficient per iteration.
    e1, e2 : float, optional
        ADR's final relative criteria (Luo, Ramazani & Sundararaghavan 2017, Eqs. 19-20).
    line_search : int
        Newton's backtracking steps.
    relaxation : int
        ADR iterations Newton ran at stalls (``relax`` of :func:`newton_step`).
    polish : int
        Newton iterations an ADR increment ran from its iterates (``polish`` of
        :func:`adr_step`), those of failed tries included; the outcome of a polished
        increment is Newton's (``e1``, ``e2`` None).
    """

    u: np.ndarray
    response: Any
    iterations: int
    calls: int
    residual: float
    history: list[float] = field(default_factory=list)
    damping: np.ndarray | None = None
    e1: float | None = None
    e2: float | None = None
    line_search: int = 0
    relaxation: int = 0
    polish: int = 0


class StepFailed(ConvergenceError):
    """A load step did not converge (the driver may cut back or fall back to ADR)."""

    def __init__(self, message: str, outcome: StepOutcome | None = None) -> None:
        super().__init__(message, outcome)
        self.outcome = outcome


def _respond(system: Any, u: np.ndarray, committed: Any, what: str, tangent: bool = False) -> Any:
    """Return ``system.respond``, a non-finite constitutive response failing the step.

    A material update that failed at a trial state (e.g. a return mapping diverging at
    an overshooting ADR iterate) raises :class:`StepFailed`, so that the driver cuts the
    increment back, instead of escaping.

    numpy's floating-point warnings (overflow, invalid, divide) are not issued for
    trial iterates: the overflow of a diverging iterate is not the user's concern, and
    every caller checks what it takes from the response (a non-finite residual fails the
    step or the line-search trial; a committed state is checked by the load-step
    driver), so nothing non-finite is kept.
    """
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return system.respond(u, committed, tangent=tangent)
    except NonFiniteError as exc:
        raise StepFailed(f"{what}: non-finite constitutive response ({exc})") from exc
    except StepFailed:
        raise
    except ConvergenceError as exc:  # e.g. a rate-dependent slip update that did not converge
        raise StepFailed(f"{what}: the constitutive update failed ({exc})") from exc


def _residual(system: Any, resp: Any, factor: float) -> np.ndarray:
    """Return the residual ``f_int + factor f_ext`` of a response (0 on prescribed DOFs)."""
    return system.residual(None, factor=factor, f_int=resp.force)


def _force_scale(system: Any, resp: Any, factor: float) -> float:
    """Force scale of a step: the larger of ‖λ f_ext‖ and ‖f_int‖ on the prescribed DOFs."""
    f = np.ravel(resp.force)
    ext = factor * float(np.linalg.norm(system.f_ext))
    reac = float(np.linalg.norm(f[system.dofs])) if system.dofs.size else 0.0
    return max(ext, reac)


def _linear_solver(system: Any, solver: str) -> str:
    """Resolve the inner linear solver ``'auto'``.

    Direct up to 2·10⁵ DOFs in 2D (3·10⁴ in 3D), then AMG-preconditioned CG
    (symmetric) or GMRES.
    """
    if solver != "auto":
        return solver
    limit = 200_000 if system.dim <= 2 else 30_000
    if system.ndof <= limit:
        return "direct"
    return "amg-cg" if system.symmetric else "amg-gmres"
