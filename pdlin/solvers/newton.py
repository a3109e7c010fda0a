"""Newton-Raphson for one load (sub)step: consistent tangent, backtracking line search.

Works on a :class:`~pdlin.system.ConstrainedSystem` and the model's
:meth:`~pdlin.models.Model.respond` (force, trial state and tangent at ``u`` from the committed
state).  A step returns a :class:`~pdlin.solvers.outcome.StepOutcome` or raises
:class:`~pdlin.solvers.outcome.StepFailed`, which the load stepping of
:func:`pdlin.solve_nonlinear` turns into a cut-back or an ADR fallback.  Newton with
line search, cut-back and ADR fallback is pdlin's implicit comparator for the ADR
method of Luo, Ramazani & Sundararaghavan (2017); the paper itself compares against
the implicit scheme of Sun & Sundararaghavan (2014).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from .._progress import linear_progress
from ..errors import ConvergenceError, ModelError, NonFiniteError
from .adr import _adr_run, _gershgorin
from .linear import solve_linear
from .newton_krylov import ForcingTerm, KrylovDirection
from .outcome import StepFailed, StepOutcome, _force_scale, _linear_solver, _residual, _respond

__all__ = ["newton_step"]

log = logging.getLogger(__name__)

_STALL_WINDOW = 5  # Newton iterations over which a stall is judged


def _direction(
    system: Any,
    K: Any,
    r: np.ndarray,
    solver: str,
    linear_rtol: float,
    direct_cache: dict[str, Any] | None,
    progress: Callable[[str], None] | None,
    it: int,
    krylov: KrylovDirection | None = None,
) -> np.ndarray:
    """Solve ``K_T du = r`` for the Newton direction (``du = 0`` on prescribed DOFs).

    With ``krylov``, by its GMRES to ``linear_rtol`` (the forcing term) instead of
    ``solver``.
    """
    if K is None:
        raise ModelError(
            f"{type(system.model).__name__}.respond(tangent=True) returned no tangent; "
            "Newton needs one (use method='adr')"
        )
    A = system.eliminate_matrix(sp.bsr_array(K) if sp.issparse(K) else K)
    b = np.array(r)
    b[system.dofs] = 0.0
    if krylov is not None:
        try:
            du = krylov.solve(A, b, linear_rtol)[0]
        except (ConvergenceError, NonFiniteError) as exc:
            raise StepFailed(f"Newton: linear solve failed at iteration {it}: {exc}") from exc
        du[system.dofs] = 0.0
        return du
    try:
        lin = solve_linear(
            A,
            b,
            solver,
            rtol=linear_rtol,
            near_null=system.near_null() if solver.startswith("amg") else None,
            blocksize=system.dim,
            symmetric=system.symmetric,
            direct_cache=direct_cache,
            progress=None
            if progress is None
            else linear_progress(progress, f"Newton iteration {it}, linear solve"),
        )
    except (ConvergenceError, NonFiniteError) as exc:  # NonFinite: a non-finite K_T
        raise StepFailed(f"Newton: linear solve failed at iteration {it}: {exc}") from exc
    du = lin.x
    du[system.dofs] = 0.0
    return du


def _backtrack(
    system: Any,
    u: np.ndarray,
    du: np.ndarray,
    committed: dict[str, np.ndarray],
    factor: float,
    norm: float,
    line_search: bool,
    max_backtracks: int,
    want_tangent: bool,
) -> tuple[bool, Any, np.ndarray, Any, np.ndarray, float, int, int]:
    """Backtrack ``u + α du`` (α = 1, ½, ...) until the Armijo decrease of ``‖r‖``.

    Returns whether a trial was accepted, the best finite trial ``(‖r‖, u, response, r,
    α)`` (None if none), the last trial's ``u``, response and residual, its α, the
    backtracking steps and the constitutive calls.
    """
    alpha = 1.0
    accepted = False
    backtracks = calls = 0
    best: tuple[float, np.ndarray, Any, np.ndarray, float] | None = None
    trial_u = u
    trial: Any = None
    rt = np.zeros(0)
    for _ls in range(max_backtracks + 1 if line_search else 1):
        trial_u = u + alpha * du
        try:
            trial = _respond(
                system, trial_u, committed, "Newton", tangent=alpha == 1.0 and want_tangent
            )
        except StepFailed:  # a non-finite material response: backtrack like a NaN ‖r‖
            alpha *= 0.5
            backtracks += 1
            continue
        calls += int(trial.calls)
        rt = _residual(system, trial, factor)
        nt = float(np.linalg.norm(rt))
        if math.isfinite(nt) and (nt <= (1.0 - 1e-4 * alpha) * norm or not line_search):
            accepted = True
            break
        if math.isfinite(nt) and (best is None or nt < best[0]):
            best = (nt, trial_u, trial, rt, alpha)
        alpha *= 0.5
        backtracks += 1
    return accepted, best, trial_u, trial, rt, alpha, backtracks, calls


def _relax_stall(
    system: Any,
    K: Any,
    u: np.ndarray,
    trial: Any,
    rt: np.ndarray,
    committed: dict[str, np.ndarray],
    factor: float,
    relax: int,
    relax_density: np.ndarray | None,
    rtol: float,
    scale0: float,
) -> tuple[np.ndarray, Any, np.ndarray, int, int, float]:
    """``relax`` ADR iterations from a stalled iterate ``u`` (response ``trial``) at rest.

    Returns the last iterate, its response and residual, the constitutive calls added
    (the start's response not counted twice), the relaxation iterations and the
    relative residual they reached.
    """
    lam = _gershgorin(K, 1.0, 1.1)
    if relax_density is not None:
        lam = np.maximum(lam, relax_density)
    lam[~system.free] = 1.0
    scale_t = max(scale0, _force_scale(system, trial, factor))
    run = _adr_run(
        system,
        u,
        trial,
        rt,
        committed,
        factor=factor,
        density=lam,
        dt=1.0,
        e_l=0.0,
        maxiter=relax,
        c0=1.0,
        damping=None,
        floor=rtol,
        scale=scale_t,
    )
    out = run.outcome
    calls = out.calls - int(trial.calls)
    return (
        out.u,
        out.response,
        _residual(system, out.response, factor),
        calls,
        out.iterations,
        out.residual,
    )


def newton_step(
    system: Any,
    u0: np.ndarray,
    committed: dict[str, np.ndarray],
    *,
    factor: float,
    rtol: float = 1e-8,
    maxiter: int = 25,
    line_search: bool = True,
    max_backtracks: int = 16,
    linear_solver: str = "auto",
    linear_rtol: float = 1e-10,
    nonmonotone: int = 3,
    direct_cache: dict[str, Any] | None = None,
    relax: int = 0,
    relax_density: np.ndarray | None = None,
    stall: float = 0.5,
    progress: Callable[[str], None] | None = None,
    progress_every: float = 60.0,
    krylov: KrylovDirection | None = None,
    forcing: str = "fixed",
) -> StepOutcome:
    """Run Newton-Raphson with a consistent tangent and backtracking line search.

    Solves ``f_int(u) + factor f_ext = 0`` on the free DOFs from ``u0``
    (whose prescribed entries hold this step's values).  Each iteration
    solves ``K_T du = r`` with the Dirichlet elimination of the system
    (``du = 0`` on prescribed DOFs), then backtracks ``u + α du`` (α = 1,
    ½, ...) until ``‖r‖`` decreases by the Armijo factor ``1 - 1e-4 α``.  When
    no α decreases ``‖r‖`` (the tangent of an active-set model is only piecewise
    smooth), the best trial is taken anyway, at most ``nonmonotone`` times per
    step and only if it does not raise ``‖r‖`` tenfold.

    With ``relax > 0``, a stall (five iterations that together reduced
    ``‖r‖`` by less than the factor ``stall``, or a failed line search after the
    ``nonmonotone`` budget) is followed by ``relax`` ADR iterations from that iterate at
    rest (density: the Gershgorin bound ``1.1 · ¼ Σ_j |K_ij|`` of the current tangent,
    at least ``relax_density``; Δt = 1).  Newton stalls where points of an active-set
    model sit on a switch (a kink of ``r(u)``) at equilibrium: its iterates jump across
    the kink, each side's linearization pointing past it; a few explicit relaxation
    sweeps settle such local errors (they are high-frequency), and Newton resumes with
    the right linearization.

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system (DOF maps, prescribed DOFs, loads, ``respond``).
    u0 : (ndof,) ndarray
        Start displacement; its prescribed entries hold this step's values.
    committed : dict of str to ndarray
        The model's committed state (every response starts from it).
    factor : float
        Load factor ``λ`` of the external force ``λ f_ext``.
    rtol : float
        Converged when ``‖r_free‖ <= rtol * scale`` (``scale`` the larger of
        ``‖λ f_ext‖`` and the reaction force norm).
    maxiter : int
        Iteration budget (linear solves).
    line_search : bool
        Backtrack (True) or take every full step (False).
    max_backtracks : int
        Halvings of α per iteration.
    linear_solver : str
        Inner linear solver of :func:`~pdlin.solvers.solve_linear` ('auto': direct up
        to 2·10⁵ DOFs in 2D / 3·10⁴ in 3D, then AMG-Krylov).
    linear_rtol : float
        Relative tolerance of an iterative inner solve.
    nonmonotone : int
        Best trials taken without a decrease of ``‖r‖`` per step (the watchdog).
    direct_cache : dict, optional
        Shared between calls, keeps the direct factorization, so that successive
        tangents of one pattern reuse its ordering and symbolic analysis.
    relax : int
        ADR iterations at a stall (0: off).
    relax_density : (ndof,) ndarray, optional
        Lower bound of the relaxation's density (e.g. the elastic tangent's bound).
    stall : float
        Reduction factor of ``‖r‖`` over five iterations below which Newton stalls.
    progress : callable, optional
        Called every ``progress_every`` seconds with the iteration, the relative
        residual and the last step length (a Newton iteration at 10⁵ points takes
        seconds, a failing try minutes).
    progress_every : float
        Seconds between progress lines.
    krylov : KrylovDirection, optional
        Solve each Newton system by its GMRES (AMG of the elastic tangent, reused)
        instead of ``linear_solver``.
    forcing : {'fixed', 'eisenstat-walker'}
        The Krylov tolerance with ``krylov``: ``linear_rtol``, or Eisenstat & Walker's
        (1996) choice 2 (``pdlin.solvers.newton_krylov.ForcingTerm``).

    Returns
    -------
    StepOutcome
        The converged displacement, its response, iterations, constitutive calls,
        relative residual and history, backtracking and relaxation counts.

    Raises
    ------
    StepFailed
        On ``maxiter`` iterations, a failed line search or a non-finite force.
    """
    t_said = time.perf_counter()
    alpha = 1.0
    u = np.array(u0, dtype=float).reshape(-1)
    resp = _respond(system, u, committed, "Newton: start of the step", tangent=True)
    calls = int(resp.calls)
    r = _residual(system, resp, factor)
    scale0 = _force_scale(system, resp, factor)
    history: list[float] = []
    solver = _linear_solver(system, linear_solver)
    backtracks = 0
    relaxed = 0
    last_relax = 0
    nonmonotone_left = int(nonmonotone)
    eta = ForcingTerm(forcing if krylov is not None else "fixed", fixed=linear_rtol)
    for it in range(maxiter + 1):
        norm = float(np.linalg.norm(r))
        if not math.isfinite(norm):
            raise StepFailed(f"Newton: non-finite residual at iteration {it}")
        scale = max(scale0, _force_scale(system, resp, factor))
        rel = norm / scale if scale > 0 else norm
        history.append(rel)
        log.debug("Newton iteration %d: relative residual %.3e", it, rel)
        if progress is not None and it and time.perf_counter() - t_said >= progress_every:
            t_said = time.perf_counter()
            progress(
                f"Newton iteration {it}: |r|/scale = {rel:.2e} (target {rtol:.0e}), "
                f"step length {alpha:.3g}"
            )
        if norm <= rtol * scale or norm == 0.0:
            return StepOutcome(
                u, resp, it, calls, rel, history, line_search=backtracks, relaxation=relaxed
            )
        if it == maxiter:
            break
        K = resp.tangent
        lin_rtol = eta.eta(rel, rtol)
        du = _direction(system, K, r, solver, lin_rtol, direct_cache, progress, it, krylov)
        stalled = False
        how = "accepted"
        # the full step's tangent is wanted unless it is likely the last iteration
        # (quadratic convergence from here would end below rtol)
        want_tangent = rel * rel > 0.1 * rtol
        accepted, best, trial_u, trial, rt, alpha, n_back, n_calls = _backtrack(
            system, u, du, committed, factor, norm, line_search, max_backtracks, want_tangent
        )
        backtracks += n_back
        calls += n_calls
        if not accepted and best is not None and nonmonotone_left > 0 and best[0] < 10.0 * norm:
            # watchdog: at active-set switches the consistent tangent is only piecewise
            # smooth and the Newton direction need not decrease ‖r‖; take the best trial a
            # few times per step rather than give up at once (maxiter still bounds the step)
            nonmonotone_left -= 1
            _, trial_u, trial, rt, alpha = best
            accepted = True
            how = "watchdog"
        if not accepted and relax > 0:
            trial_u, trial, rt = u, resp, r  # relax from here rather than give up
            accepted = stalled = True
            alpha, how = 0.0, "line search failed"
        if not accepted:
            raise StepFailed(
                f"Newton: line search failed at iteration {it} (‖r‖ = {norm:.3e}, no decrease "
                f"down to α = {2 * alpha:.2e})",
                StepOutcome(
                    u, resp, it, calls, rel, history, line_search=backtracks, relaxation=relaxed
                ),
            )
        log.debug("Newton iteration %d: step length %.3g (%s)", it, alpha, how)
        u = trial_u
        if relax > 0 and not stalled and it - last_relax >= _STALL_WINDOW:
            # the last iterations did not reduce ‖r‖ by the factor ``stall``
            stalled = float(np.linalg.norm(rt)) / scale > stall * history[-_STALL_WINDOW]
        if stalled and relax > 0:
            last_relax = it
            u, trial, rt, n_calls, n_relax, rel_relax = _relax_stall(
                system, K, u, trial, rt, committed, factor, relax, relax_density, rtol, scale0
            )
            calls += n_calls
            relaxed += n_relax
            log.debug(
                "Newton iteration %d: stalled; %d relaxation iterations -> relative residual %.3e",
                it,
                n_relax,
                rel_relax,
            )
        if trial.tangent is None:
            nt = float(np.linalg.norm(rt))
            scale_t = max(scale0, _force_scale(system, trial, factor))
            if not (nt <= rtol * scale_t or nt == 0.0):  # another iteration needs K_T
                trial = _respond(system, u, committed, f"Newton iteration {it}", tangent=True)
                calls += int(trial.calls)
                rt = _residual(system, trial, factor)
        resp, r = trial, rt
    raise StepFailed(
        f"Newton: no convergence in {maxiter} iterations (relative residual {history[-1]:.3e} "
        f"> {rtol:.1e})",
        StepOutcome(
            u,
            resp,
            maxiter,
            calls,
            history[-1],
            history,
            line_search=backtracks,
            relaxation=relaxed,
        ),
    )
