"""Pseudo-transient continuation: Newton globalized by the ADR mass as a shift.

One load (sub)step solves ``(K_T + Λ/τ) du = r`` at every iteration, with ``Λ`` the
fictitious density of adaptive dynamic relaxation (the Gershgorin bound of the elastic
tangent, :func:`~pdlin.solvers.adr_density`) and ``τ`` a pseudo time step that grows as the
residual falls (switched evolution relaxation, ``τ_{k+1} = τ_k ‖r_{k-1}‖ / ‖r_k‖``;
Kelley & Keyes 1998, "Convergence analysis of pseudo-transient continuation", SIAM J.
Numer. Anal. 35, Eq. 1.4 and Sec. 2).  Small ``τ`` is a damped explicit step along
``Λ⁻¹ r`` (an ADR-like iteration), large ``τ`` is Newton.  There is no line search: a step
is taken unless it raises ``‖r‖`` more than ``growth``-fold (or is not finite), in which
case ``τ`` is cut fourfold and the system solved again.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import ConvergenceError, ModelError, NonFiniteError
from .linear import solve_linear
from .newton_krylov import ForcingTerm, KrylovDirection
from .outcome import StepFailed, StepOutcome, _force_scale, _linear_solver, _residual, _respond

__all__ = ["ptc_step"]

log = logging.getLogger(__name__)

_TAU_MAX = 1e12  # past it the shift is below round-off of K_T: plain Newton
_REJECTS = 8  # τ cuts in a row before the (sub)step fails


def _shifted_direction(
    system: Any,
    K: Any,
    r: np.ndarray,
    shift: np.ndarray,
    tau: float,
    eta: float,
    krylov: KrylovDirection | None,
    solver: str,
    direct_cache: dict[str, Any] | None,
    it: int,
) -> np.ndarray:
    """Solve ``(K_T + Λ/τ) du = r`` on the free DOFs (``du = 0`` on prescribed ones)."""
    if K is None:
        raise ModelError(
            f"{type(system.model).__name__}.respond(tangent=True) returned no tangent; "
            "Newton needs one (use method='adr')"
        )
    A = system.eliminate_matrix(sp.bsr_array(K) if sp.issparse(K) else K)
    if math.isfinite(tau):
        A = sp.csr_array(A) + sp.diags_array(shift / tau)
    b = np.array(r)
    b[system.dofs] = 0.0
    try:
        if krylov is not None:
            du = krylov.solve(A, b, eta, tau=tau)[0]
        else:
            du = solve_linear(
                A,
                b,
                solver,
                rtol=1e-10,
                near_null=system.near_null() if solver.startswith("amg") else None,
                blocksize=system.dim,
                symmetric=False,
                direct_cache=direct_cache,
            ).x
    except (ConvergenceError, NonFiniteError) as exc:
        raise StepFailed(
            f"Newton (continuation): linear solve failed at iteration {it}: {exc}"
        ) from exc
    du[system.dofs] = 0.0
    return du


def ptc_step(
    system: Any,
    u0: np.ndarray,
    committed: dict[str, np.ndarray],
    *,
    factor: float,
    density: np.ndarray,
    rtol: float = 1e-8,
    maxiter: int = 25,
    tau0: float = 1.0,
    growth: float = 2.0,
    krylov: KrylovDirection | None = None,
    forcing: str = "eisenstat-walker",
    linear_solver: str = "auto",
    direct_cache: dict[str, Any] | None = None,
    progress: Callable[[str], None] | None = None,
    progress_every: float = 60.0,
) -> StepOutcome:
    """Run pseudo-transient continuation from ``u0`` to equilibrium.

    Each iteration solves ``(K_T + Λ/τ) du = r`` (``K_T`` the consistent tangent at
    ``u``, ``Λ = density`` on the free DOFs) and takes ``u + du`` unless ``‖r‖`` grows
    more than ``growth``-fold there or is not finite (then ``τ`` is cut fourfold and the
    shifted system solved again, at most 8 times in a row); after a taken step ``τ`` grows
    by ``‖r_old‖ / ‖r_new‖`` (switched evolution relaxation) up to 1e12, where the
    iteration is Newton's.

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system.
    u0 : (ndof,) ndarray
        Start displacement; its prescribed entries hold this step's values.
    committed : dict of str to ndarray
        The model's committed state.
    factor : float
        Load factor of the external force.
    density : (ndof,) ndarray
        The shift ``Λ`` (e.g. ADR's Gershgorin density of the elastic tangent).
    rtol : float
        Converged when ``‖r_free‖ <= rtol`` x the force scale.
    maxiter : int
        Linear solves per (sub)step (rejected steps included).
    tau0 : float
        ``τ`` of the first iteration (1: a stable explicit ADR step with Δt = 1).
    growth : float
        Largest ``‖r‖`` increase a step may bring.
    krylov : KrylovDirection, optional
        GMRES with the elastic AMG (else ``linear_solver``, a fresh solve each time).
    forcing : {'fixed', 'eisenstat-walker'}
        The Krylov tolerance with ``krylov`` (fixed: 1e-10).
    linear_solver : str
        Without ``krylov``: the linear solver ('auto': direct up to 2·10⁵ DOFs in 2D).
    direct_cache : dict, optional
        Keeps the direct factorization's ordering between solves.
    progress : callable, optional
        Receives a line every ``progress_every`` seconds.
    progress_every : float
        Seconds between progress lines.

    Returns
    -------
    StepOutcome
        The converged displacement, its response, linear solves, constitutive calls,
        relative residual and its history.

    Raises
    ------
    StepFailed
        No convergence in ``maxiter`` solves, 8 rejected steps in a row, a failed linear
        solve or a non-finite start.

    Examples
    --------
    A linear bar: the first iteration at ``τ = 1`` is a damped step, then ``τ`` grows and
    Newton's convergence takes over.

    >>> import numpy as np, pdlin
    >>> from pdlin.system import constrained_system
    >>> from pdlin.solvers import adr_density
    >>> cloud = pdlin.grid((20,), spacing=0.05)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.1,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3)])
    >>> system = constrained_system(prob)
    >>> st = system.initial_state()
    >>> u0 = np.zeros(system.ndof); u0[system.dofs] = system.values_at(1.0, 1.0)
    >>> out = ptc_step(system, u0, st, factor=1.0, density=adr_density(system, st),
    ...                maxiter=40)
    >>> bool(out.residual <= 1e-8), out.iterations > 1
    (True, True)
    """
    t_said = time.perf_counter()
    u = np.array(u0, dtype=float).reshape(-1)
    resp = _respond(system, u, committed, "Newton: start of the step", tangent=True)
    calls = int(resp.calls)
    r = _residual(system, resp, factor)
    scale0 = _force_scale(system, resp, factor)
    shift = np.where(system.free, np.asarray(density, dtype=float), 0.0)
    solver = _linear_solver(system, linear_solver)
    fterm = ForcingTerm(forcing if krylov is not None else "fixed", fixed=1e-10)
    tau, rejects, solves = float(tau0), 0, 0
    history: list[float] = []
    norm = float(np.linalg.norm(r))
    if not math.isfinite(norm):
        raise StepFailed("Newton (continuation): non-finite residual at the start")
    while True:
        scale = max(scale0, _force_scale(system, resp, factor))
        rel = norm / scale if scale > 0 else norm
        if not rejects:
            history.append(rel)
            log.debug(
                "continuation iteration %d: relative residual %.3e, tau %.3g", solves, rel, tau
            )
        if norm <= rtol * scale or norm == 0.0:
            return StepOutcome(u, resp, solves, calls, rel, history, line_search=0)
        if solves >= maxiter:
            break
        if progress is not None and time.perf_counter() - t_said >= progress_every:
            t_said = time.perf_counter()
            progress(
                f"continuation solve {solves}: |r|/scale = {rel:.2e} (target {rtol:.0e}), "
                f"tau {tau:.3g}"
            )
        eta = fterm.eta(rel, rtol)
        du = _shifted_direction(
            system, resp.tangent, r, shift, tau, eta, krylov, solver, direct_cache, solves
        )
        solves += 1
        trial_u = u + du
        try:
            trial = _respond(system, trial_u, committed, "Newton (continuation)", tangent=True)
            calls += int(trial.calls)
            rt = _residual(system, trial, factor)
            nt = float(np.linalg.norm(rt))
        except StepFailed:
            nt = math.inf
        if not (math.isfinite(nt) and nt <= growth * norm):
            rejects += 1
            if rejects > _REJECTS:
                raise StepFailed(
                    f"Newton (continuation): {_REJECTS} rejected steps in a row at solve "
                    f"{solves} (relative residual {rel:.3e}, tau {tau:.3g})",
                    StepOutcome(u, resp, solves, calls, rel, history),
                )
            tau *= 0.25
            fterm.reset()
            continue
        rejects = 0
        tau = min(_TAU_MAX, tau * norm / max(nt, 1e-300))
        u, resp, r, norm = trial_u, trial, rt, nt
    raise StepFailed(
        f"Newton (continuation): no convergence in {maxiter} solves (relative residual "
        f"{history[-1]:.3e} > {rtol:.1e})",
        StepOutcome(u, resp, maxiter, calls, history[-1], history),
    )
