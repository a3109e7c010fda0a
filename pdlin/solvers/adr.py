"""Adaptive dynamic relaxation (ADR) for one load (sub)step.

Central differences on ``Λ ü + c Λ u̇ = r(u)`` with the fictitious diagonal density
``Λ`` of Kilic & Madenci (2010) (Gershgorin bound of the tangent) and Rayleigh-quotient
damping, the method of Luo, Ramazani & Sundararaghavan (2017), Section 2.2 (Eqs. 8-14:
update, time step, damping, local stiffness; Eqs. 19-20: the relative criteria e₁, e₂).
A step returns a :class:`~pdlin.solvers.outcome.StepOutcome` or raises
:class:`~pdlin.solvers.outcome.StepFailed`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, ModelError
from .outcome import StepFailed, StepOutcome, _force_scale, _residual, _respond

__all__ = ["adr_step", "adr_density", "adr_time_step"]


def adr_time_step(spacing: float, E_max: float, density: float = 1.0) -> float:
    """Return the ADR time step ``Δt = Δx sqrt(Λ / E_max)``.

    Eq. 12 of Luo, Ramazani & Sundararaghavan (2017).  With the fictitious density
    ``Λ`` per unit volume (``Λ = 1`` in mm-MPa units, pdlin's reading of the paper) pass
    the nodal density ``Λ V`` to :func:`pdlin.solve_nonlinear` (``density=Λ * V``).
    Derived (pdlin's eigenvalue computations): for δ = h the step sits at about
    0.88-0.95 of the true stability limit ``2/sqrt(λ_max)``.

    Parameters
    ----------
    spacing : float
        Grid spacing ``Δx`` (> 0).
    E_max : float
        Largest elastic modulus (> 0, the units of the stress).
    density : float
        Fictitious density ``Λ`` per unit volume (> 0).

    Returns
    -------
    float
        The time step ``Δt``.

    Raises
    ------
    InputError
        An argument is not a positive finite number.

    Examples
    --------
    Eq. 12 at E_max = 2000 MPa, Λ = 1 on the paper's 15², 25² and 50² grids:

    >>> [round(adr_time_step(1 / n, 2000.0), 7) for n in (15, 25, 50)]
    [0.0014907, 0.0008944, 0.0004472]
    """
    for name, v in (("spacing", spacing), ("E_max", E_max), ("density", density)):
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    return float(spacing) * math.sqrt(float(density) / float(E_max))


def _gershgorin(K: Any, dt: float, safety: float) -> np.ndarray:
    """``safety · ¼ Δt² Σ_j |K_ij|`` per row: the stable central-difference density."""
    rows = np.asarray(abs(sp.csr_array(K)).sum(axis=1)).ravel()
    return np.asarray(safety * 0.25 * dt * dt * rows)


def adr_density(
    system: Any,
    committed: dict[str, np.ndarray],
    u: np.ndarray | None = None,
    *,
    dt: float = 1.0,
    safety: float = 1.0,
) -> np.ndarray:
    """Return the fictitious diagonal density from the Gershgorin bound of the tangent.

    ``Λ_ii = safety · ¼ Δt² Σ_j |K_ij|`` (Kilic & Madenci 2010) over the eliminated
    tangent at ``u``, so that ``ω_max Δt <= 2`` for every eigenvalue of ``Λ⁻¹ K``: the
    central-difference update is stable for any damping ``c >= 0``.

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system.
    committed : dict of str to ndarray
        The committed state the tangent starts from.
    u : (ndof,) ndarray, optional
        Where the tangent is taken (default: zero displacement).
    dt : float
        ADR time step (> 0).
    safety : float
        Factor on the bound (>= 1).

    Returns
    -------
    (ndof,) ndarray
        Positive density per DOF (1 on prescribed DOFs).

    Raises
    ------
    InputError
        ``dt <= 0`` or ``safety < 1``.
    ModelError
        The model returns no tangent, or a free DOF has an empty tangent row.
    StepFailed
        The tangent has a non-finite row at a free DOF.
    """
    if not (dt > 0 and safety >= 1.0):
        raise InputError(f"dt must be > 0 and safety >= 1, got dt = {dt}, safety = {safety}")
    x = np.zeros(system.ndof) if u is None else np.asarray(u, dtype=float).reshape(-1)
    resp = _respond(system, x, committed, "ADR density", tangent=True)
    if resp.tangent is None:
        raise ModelError(
            f"{type(system.model).__name__}.respond(tangent=True) returned no tangent; "
            "pass the ADR density explicitly"
        )
    lam = _gershgorin(resp.tangent, dt, safety)
    free = system.free
    if not np.all(np.isfinite(lam[free])):
        bad = int(np.flatnonzero(free & ~np.isfinite(lam))[0])
        raise StepFailed(
            f"ADR density: the tangent at u has a non-finite row at free dof {bad} "
            f"(point {bad // system.dim})"
        )
    if np.any(lam[free] <= 0):
        bad = int(np.flatnonzero(free & (lam <= 0))[0])
        raise ModelError(
            f"the tangent has an empty row at free dof {bad} (point {bad // system.dim}): "
            "no Gershgorin density; is the point connected?"
        )
    lam[~free] = 1.0
    return lam


def adr_step(
    system: Any,
    u0: np.ndarray,
    committed: dict[str, np.ndarray],
    *,
    factor: float,
    density: np.ndarray,
    dt: float,
    e_l: float = 1e-6,
    maxiter: int = 20_000,
    c0: float = 1.0,
    damping: float | None = None,
    floor: float = 1e-12,
    progress: Callable[[str], None] | None = None,
    progress_every: float = 60.0,
    snapshot: Callable[[dict[str, Any]], None] | None = None,
    snapshot_every: float = 300.0,
    restart: dict[str, Any] | None = None,
    polish: Callable[[np.ndarray], StepOutcome] | None = None,
    stall: int = 0,
) -> StepOutcome:
    """Run adaptive dynamic relaxation for one load step.

    The method of Luo, Ramazani & Sundararaghavan (2017), Section 2.2: central
    differences on ``Λ ü + c Λ u̇ = r(u)`` (update Eq. 8), ``u⁻¹ = u⁰``;
    damping ``cⁿ = 2 sqrt(uⁿᵀ kⁿ uⁿ / uⁿᵀ uⁿ)`` with the diagonal local
    stiffness ``k_ii = -(r_iⁿ - r_iⁿ⁻¹)/(Λ_ii (u_iⁿ - u_iⁿ⁻¹))`` over free
    DOFs (``c = 0`` when the quotient is <= 0), unless a constant
    ``damping`` is given (Eqs. 13-14).  Stops when ``e₁ = ε₁/ε₁⁰ < e_l`` and
    ``e₂ = ε₂/ε₂⁰ < e_l`` (Eqs. 19-20: ``ε₁ = ‖r‖/N``, ``ε₂ = ‖δu‖/N``, ``ε⁰`` of
    the first iteration), or when ``‖r‖ <= floor`` x the force scale (the
    relative criteria degenerate when ``u⁰`` is already the solution).
    ``progress`` (if given) is called every ``progress_every`` seconds with the
    iteration, e₁, e₂, the damping and ‖r‖ relative to the force scale.

    ``snapshot`` (if given) is called every ``snapshot_every`` seconds (checked every 64
    iterations; 0: every 64 iterations) with the loop's state after an iteration (a dict
    of arrays and numbers: the iterates ``u``, ``u_prev``, the damping, ``ε⁰``, the
    histories, ...); ``restart=`` such a dict continues the iteration from there, from
    the same ``u0``, ``committed``, ``factor``, ``density`` and ``dt``: the iterates,
    criteria and histories are then those of an uninterrupted run, bit for bit (the
    responses at ``u0`` and at the snapshot are recomputed: two more constitutive sweeps
    in ``calls``).

    ``polish`` (if given) finishes a stalled iteration: a callable that runs Newton
    from an iterate (e.g. :func:`newton_step` at this step's ``factor`` and
    ``committed`` state) and returns its outcome or raises :class:`StepFailed`.  It is
    tried when ``stall > 0`` and the best ``‖r‖`` of the last ``stall`` iterations is
    not below half the best before them (checked at iterations ``2 stall``, ``3 stall``,
    ...), and once more from the last iterate when the budget runs out.  A converged
    try ends the increment with Newton's outcome (its residual criterion, ``polish``
    counting its iterations); a failed one leaves the ADR iteration as it was (its
    iterates do not depend on the tries, so a ``restart`` stays bit for bit).  ADR's
    damped dynamics can stall near an equilibrium that Newton reaches in a few
    iterations (10⁵ crystal-plasticity points, docs/nonlinear.md: ``‖r‖`` at 1e-7 of
    the force scale, then a plateau at 1e-6 for 40,000 iterations; Newton from the
    plateau converged in 2).

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system.
    u0 : (ndof,) ndarray
        Start displacement; its prescribed entries hold this step's values.
    committed : dict of str to ndarray
        The model's committed state (every response starts from it).
    factor : float
        Load factor ``λ`` of the external force ``λ f_ext``.
    density : (ndof,) ndarray
        Fictitious diagonal density ``Λ`` (positive, e.g. :func:`adr_density`).
    dt : float
        Time step (> 0).
    e_l : float
        Target of the relative criteria e₁, e₂.
    maxiter : int
        Iteration budget.
    c0 : float
        Initial damping of the adaptive damping.
    damping : float, optional
        Constant damping instead of the Rayleigh quotient.
    floor : float
        Absolute floor on ``‖r‖`` relative to the force scale.
    progress : callable, optional
        Receives a progress line every ``progress_every`` seconds.
    progress_every : float
        Seconds between progress lines.
    snapshot : callable, optional
        Receives the loop's state every ``snapshot_every`` seconds.
    snapshot_every : float
        Seconds between snapshots (checked every 64 iterations).
    restart : dict, optional
        A ``snapshot`` of an earlier run from the same start, continued.
    polish : callable, optional
        Newton from an iterate, tried at stalls and when the budget runs out.
    stall : int
        Stall window of ``polish`` in iterations (0: only at the end of the budget).

    Returns
    -------
    StepOutcome
        The converged displacement and response, iterations, constitutive calls,
        residual history, damping per iteration and the final e₁, e₂ (None, with
        Newton's residual, for a polished increment).

    Raises
    ------
    InputError
        ``stall``, ``density`` or ``dt`` out of range.
    StepFailed
        After ``maxiter`` iterations (and a failed ``polish``) or on a non-finite force.
    """
    if isinstance(stall, bool) or not isinstance(stall, int) or stall < 0:
        raise InputError(f"stall must be an integer >= 0 (iterations), got {stall!r}")
    lam = np.asarray(density, dtype=float).reshape(-1)
    if lam.shape != (system.ndof,) or np.any(lam <= 0) or not np.all(np.isfinite(lam)):
        raise InputError(f"density must be {system.ndof} positive finite numbers")
    if not (dt > 0 and math.isfinite(dt)):
        raise InputError(f"dt must be a positive number, got {dt}")
    u = np.array(u0, dtype=float).reshape(-1)
    resp = _respond(system, u, committed, "ADR: start of the step")
    r = _residual(system, resp, factor)
    scale = _force_scale(system, resp, factor)
    if float(np.linalg.norm(r)) <= floor * scale:
        return StepOutcome(u, resp, 0, int(resp.calls), 0.0, [0.0], np.zeros(0), 0.0, 0.0)
    run = _adr_run(
        system,
        u,
        resp,
        r,
        committed,
        factor=factor,
        density=lam,
        dt=dt,
        e_l=e_l,
        maxiter=maxiter,
        c0=c0,
        damping=damping,
        floor=floor,
        scale=scale,
        progress=progress,
        progress_every=progress_every,
        snapshot=snapshot,
        snapshot_every=snapshot_every,
        restart=restart,
        polish=polish,
        stall=stall,
    )
    out = run.outcome
    if run.converged:
        return out
    e1, e2 = out.e1, out.e2
    tried = f"; Newton from its last iterate failed ({run.why})" if run.why else ""
    raise StepFailed(
        f"ADR: no convergence in {maxiter} iterations (e1 = {e1:.3e}, e2 = {e2:.3e}, "
        f"target {e_l:.1e}){tried}",
        out,
    )


def _runaway_message(
    system: Any, it: int, u_start: np.ndarray, u: np.ndarray, r_new: np.ndarray
) -> str:
    """Say why ADR stopped on a non-finite force.

    Names where it appeared and where the last finite iterate had moved farthest from
    the start of the increment (the runaway's seat).
    """
    d = system.dim
    bad = np.flatnonzero(~np.isfinite(r_new))
    first = int(bad[0]) // d if bad.size else -1
    with np.errstate(over="ignore", invalid="ignore"):
        move = np.linalg.norm((u - u_start).reshape(-1, d), axis=1)
    move = np.where(np.isfinite(move), move, np.inf)
    p = int(np.argmax(move))
    pts = getattr(getattr(system, "cloud", None), "points", None)
    where = "" if pts is None else f" (x = {np.round(np.asarray(pts[p]), 6).tolist()})"
    return (
        f"ADR: non-finite force at iteration {it} (first at point {first}); the last finite "
        f"iterate had moved farthest from the increment's start at point {p}{where}, "
        f"|Δu| = {move[p]:.3g} against a median of {float(np.median(move)):.3g}. A density "
        "too small for the stiffness along the iteration (dt too large; raise "
        "density_safety), or a local mode without stiffness running away (e.g. a "
        "zero-energy mode of an uncontrolled correspondence model softened by plasticity: "
        "try a control, Correspondence(control=...))"
    )


#: DOFs per chunk of the compiled ADR update (fixed: the bits do not depend on threads)
_ADR_CHUNK = 1 << 16


def _adr_kernels(ndof: int) -> Any:
    """Return the compiled kernels for an ADR loop over ``ndof`` DOFs, or None (numpy)."""
    from .._kernels import compiled_kernels, use_numba

    return compiled_kernels() if use_numba(ndof) else None


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """Return ``a · b`` of two vectors without BLAS (numpy's own loop in ``einsum``).

    OpenBLAS runs ``ddot`` (and so ``np.linalg.norm``) of long vectors on its own
    threads, which then spin for a while after the call: in the ADR loop they took the
    second core from pdlin's thread pool in the constitutive update that follows, which
    then ran at the speed of one thread (9.6 against 5.9 ms per update at 10⁵ points on
    two cores, 18.7 against 14.0 ms per ADR iteration; benchmarks/bench_adr_iteration.py).
    """
    return float(np.einsum("i,i->", a, b))


def _adr_restart(
    snap: dict[str, Any], ndof: int, calls: int
) -> tuple[
    np.ndarray, np.ndarray, np.ndarray, int, float, float, float, int, list[float], list[float]
]:
    """Return the loop state of an ADR ``snapshot`` (checked).

    The iterates ``u``, ``u_prev``, ``u_start``, the first iteration to run, the
    damping, ``ε⁰``, the constitutive calls so far (those of the interrupted run, plus
    ``calls`` of the restart's start) and the residual and damping histories.
    """
    try:
        vecs = [np.array(snap[k], dtype=float).reshape(-1) for k in ("u", "u_prev", "u_start")]
        it = int(snap["iteration"])
        c, e10, e20 = (float(snap[k]) for k in ("c", "eps1_0", "eps2_0"))
        hist = [float(x) for x in np.asarray(snap["history"], dtype=float).reshape(-1)]
        damp = [float(x) for x in np.asarray(snap["damping"], dtype=float).reshape(-1)]
        n_calls = int(snap["calls"])
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"restart must be a snapshot of an ADR run, got {exc!r}") from exc
    if any(v.size != ndof for v in vecs) or it < 1 or len(hist) != it or len(damp) != it:
        raise InputError(
            f"restart must be a snapshot of an ADR run on {ndof} DOFs, got vectors of "
            f"{[v.size for v in vecs]} and {len(hist)} / {len(damp)} history entries at "
            f"iteration {it}"
        )
    return vecs[0], vecs[1], vecs[2], it + 1, c, e10, e20, n_calls + calls, hist, damp


@dataclass
class _AdrRun:
    outcome: StepOutcome
    converged: bool
    why: str = ""  # why the last polish try failed (empty: none tried or none failed)


def _stalled(history: list[float], it: int, stall: int) -> bool:
    """Tell whether ADR stalls at iteration ``it`` (a multiple of ``stall``, >= ``2 stall``).

    It does when the best residual of the last ``stall`` iterations is not below half
    the best before them (``history[j]`` is iteration ``j + 1``'s).
    """
    return min(history[it - stall : it]) > 0.5 * min(history[: it - stall])


class _Sweeps:
    """The vector work of an ADR iteration: the update and ``δu`` / the local stiffness.

    In place, without masked gathers (6 -> 3 ms per iteration at 2·10⁵ DOFs): r = 0 on
    the prescribed DOFs, so r / Λ there is dropped by a zero inverse density; the local
    stiffness k = (rⁿ⁻¹ - rⁿ)/(Λ δu) is 0 where δu = 0 (the prescribed DOFs among them)
    through an infinite denominator.  With numba, the update and δu / k each run in one
    pass over DOF chunks on pdlin's threads (the same arithmetic in the same order: the
    same bits as the numpy steps).
    """

    def __init__(
        self, system: Any, lam: np.ndarray, dt: float, damping: float | None, u: np.ndarray
    ) -> None:
        free = system.free
        self.lam = lam
        self.fixed = np.flatnonzero(~free)
        self.inv_lam = np.where(free, 1.0 / lam, 0.0)
        self.local = damping is None
        self.du, self.tmp, self.k = np.empty_like(u), np.empty_like(u), np.empty_like(u)
        self.h2 = 2.0 * dt * dt
        self.kern = _adr_kernels(u.size)
        if self.kern is not None:
            from .._threads import even_chunks, thread_map

            self.thread_map = thread_map
            self.chunks = even_chunks(u.size, _ADR_CHUNK)
            self.lam_c = np.ascontiguousarray(lam, dtype=float)
            self.fixed_mask = np.ascontiguousarray(~free)

    def update(
        self, r: np.ndarray, u: np.ndarray, u_prev: np.ndarray, out: np.ndarray, cdt: float
    ) -> None:
        """``uⁿ⁺¹ = [2Δt² Λ⁻¹rⁿ + 4uⁿ + (cΔt − 2) uⁿ⁻¹] / (2 + cΔt)`` on the free DOFs."""
        kern = self.kern
        if kern is not None:
            r = np.ascontiguousarray(r)
            inv_lam, fixed_mask, h2 = self.inv_lam, self.fixed_mask, self.h2
            self.thread_map(
                lambda ch: kern.adr_update_fill(
                    ch[0], ch[1], r, inv_lam, u, u_prev, fixed_mask, h2, cdt, out
                ),
                self.chunks,
            )
            return
        tmp = self.tmp
        np.multiply(r, self.inv_lam, out=out)
        out *= self.h2
        np.multiply(u, 4.0, out=tmp)
        out += tmp
        np.multiply(u_prev, cdt - 2.0, out=tmp)
        out += tmp
        out /= 2.0 + cdt
        out[self.fixed] = u[self.fixed]

    def local_stiffness(
        self, r: np.ndarray, r_new: np.ndarray, u_new: np.ndarray, u: np.ndarray
    ) -> None:
        """``δu = uⁿ⁺¹ - uⁿ`` and (adaptive damping) ``k = (rⁿ - rⁿ⁺¹) / (Λ δu)``."""
        kern = self.kern
        if kern is not None:
            r, r_new = np.ascontiguousarray(r), np.ascontiguousarray(r_new)
            lam_c, du, k, local = self.lam_c, self.du, self.k, self.local
            self.thread_map(
                lambda ch: kern.adr_local_fill(
                    ch[0], ch[1], r, r_new, lam_c, u_new, u, du, k, local
                ),
                self.chunks,
            )
            return
        du, tmp, k = self.du, self.tmp, self.k
        np.subtract(u_new, u, out=du)
        if self.local:
            np.subtract(r, r_new, out=tmp)
            np.multiply(self.lam, du, out=k)
            k[du == 0.0] = np.inf
            np.divide(tmp, k, out=k)


def _try_polish(
    polish: Callable[[np.ndarray], StepOutcome],
    u: np.ndarray,
    it: int,
    last: bool,
    stall: int,
    criteria: tuple[float, float, float],
    progress: Callable[[str], None] | None,
) -> tuple[StepOutcome | None, StepFailed | None]:
    """Newton from ADR's iterate ``u`` (``criteria``: e₁, e₂ and the relative residual).

    Returns Newton's outcome, or None and the failure.
    """
    e1, e2, rel = criteria
    if progress is not None:
        why_now = "budget spent" if last else f"no twofold drop of |r| in {stall:,} iterations"
        progress(
            f"ADR iteration {it:,}: {why_now}"
            + f" (e1 = {e1:.2e}, e2 = {e2:.2e}, |r|/scale = {rel:.2e}); "
            "Newton from this iterate"
        )
    try:
        done = polish(u.copy())
    except StepFailed as exc:
        if progress is not None:
            progress(f"ADR iteration {it:,}: {exc}" + ("" if last else "; ADR goes on"))
        return None, exc
    if progress is not None:
        progress(
            f"ADR iteration {it:,}: Newton from this iterate converged in "
            f"{done.iterations} iteration(s), |r|/scale = {done.residual:.2e}"
        )
    return done, None


def _adr_run(
    system: Any,
    u: np.ndarray,
    resp: Any,
    r: np.ndarray,
    committed: dict[str, np.ndarray],
    *,
    factor: float,
    density: np.ndarray,
    dt: float,
    e_l: float,
    maxiter: int,
    c0: float,
    damping: float | None,
    floor: float,
    scale: float,
    progress: Callable[[str], None] | None = None,
    progress_every: float = 60.0,
    snapshot: Callable[[dict[str, Any]], None] | None = None,
    snapshot_every: float = 300.0,
    restart: dict[str, Any] | None = None,
    polish: Callable[[np.ndarray], StepOutcome] | None = None,
    stall: int = 0,
) -> _AdrRun:
    """Run the ADR iterations of :func:`adr_step` from ``u`` at rest (``u⁻¹ = u⁰``).

    ``resp`` and ``r`` are the response and residual at ``u``.  Stops on the criteria,
    on a converged ``polish`` or after ``maxiter`` iterations (not converged: the
    outcome holds the last iterate).  ``restart``: a ``snapshot`` of an earlier run from
    the same start, continued after its iteration.
    """
    npts = system.n
    u = np.array(u, dtype=float)  # the iterates rotate through three buffers
    u_start = u.copy()
    u_prev = u.copy()
    spare = np.empty_like(u)
    sweeps = _Sweeps(system, density, dt, damping, u)
    du, k = sweeps.du, sweeps.k
    free_w = system.free.astype(float)
    calls = int(resp.calls)
    history: list[float] = []
    cs: list[float] = []
    c = float(c0) if damping is None else float(damping)
    eps1_0: float | None = None
    eps2_0: float | None = None
    e1 = e2 = float("nan")
    first = 1
    polished = 0  # Newton iterations of failed polish tries
    why = ""
    if restart is not None:
        u, u_prev, u_start, first, c, eps1_0, eps2_0, calls, history, cs = _adr_restart(
            restart, u.size, calls
        )
        polished = int(restart.get("polish", 0))  # absent from earlier snapshots
        resp = _respond(system, u, committed, f"ADR: restart after iteration {first - 1}")
        calls += int(resp.calls)
        r = _residual(system, resp, factor)
        e1, e2 = float(restart["e1"]), float(restart["e2"])
    t_said = t_snap = time.perf_counter()
    for it in range(first, maxiter + 1):
        cdt = c * dt
        u_new = spare
        sweeps.update(r, u, u_prev, u_new, cdt)
        resp_new = _respond(system, u_new, committed, f"ADR iteration {it}")
        calls += int(resp_new.calls)
        r_new = _residual(system, resp_new, factor)
        with np.errstate(over="ignore", invalid="ignore"):
            n1 = math.sqrt(_dot(r_new, r_new))
        if not math.isfinite(n1):
            raise StepFailed(_runaway_message(system, it, u_start, u, r_new))
        sweeps.local_stiffness(r, r_new, u_new, u)
        if damping is None:
            den = float(np.einsum("i,i,i->", u_new, u_new, free_w))
            q = float(np.einsum("i,i,i->", u_new, u_new, k)) / den if den > 0 else 0.0
            c = 2.0 * math.sqrt(q) if q > 0 else 0.0
        cs.append(c)
        eps1 = n1 / npts
        eps2 = math.sqrt(_dot(du, du)) / npts
        if eps1_0 is None:
            eps1_0, eps2_0 = max(eps1, 1e-300), max(eps2, 1e-300)
        assert eps2_0 is not None
        e1, e2 = eps1 / eps1_0, eps2 / eps2_0
        history.append(n1 / scale if scale > 0 else n1)
        spare, u_prev, u, r, resp = u_prev, u, u_new, r_new, resp_new
        if snapshot is not None and it % 64 == 0 and time.perf_counter() - t_snap >= snapshot_every:
            snapshot(
                {
                    "iteration": it,
                    "u": u,
                    "u_prev": u_prev,
                    "u_start": u_start,
                    "c": c,
                    "eps1_0": eps1_0,
                    "eps2_0": eps2_0,
                    "calls": calls,
                    "history": np.asarray(history),
                    "damping": np.asarray(cs),
                    "e1": e1,
                    "e2": e2,
                    "polish": polished,
                }
            )
            t_snap = time.perf_counter()
        if progress is not None and it % 64 == 0 and time.perf_counter() - t_said >= progress_every:
            t_said = time.perf_counter()
            progress(
                f"ADR iteration {it:,}: e1 = {e1:.2e}, e2 = {e2:.2e} (target {e_l:.0e}), "
                f"c = {c:.3g}, |r|/scale = {history[-1]:.2e}"
            )
        if (e1 < e_l and e2 < e_l) or n1 <= floor * scale:
            out = StepOutcome(u, resp, it, calls, history[-1], history, np.array(cs), e1, e2)
            out.polish = polished
            return _AdrRun(out, True)
        last = it == maxiter
        check = stall > 0 and it % stall == 0 and it >= 2 * stall
        if polish is not None and (last or (check and _stalled(history, it, stall))):
            done, failed = _try_polish(polish, u, it, last, stall, (e1, e2, history[-1]), progress)
            if done is not None:
                out = StepOutcome(
                    done.u,
                    done.response,
                    it,
                    calls + int(done.calls),
                    done.residual,
                    history,
                    np.array(cs),
                    relaxation=done.relaxation,
                    polish=polished + int(done.iterations),
                )
                return _AdrRun(out, True)
            assert failed is not None
            if failed.outcome is not None:
                calls += int(failed.outcome.calls)
                polished += int(failed.outcome.iterations)
            why = str(failed)
    out = StepOutcome(u, resp, maxiter, calls, history[-1], history, np.array(cs), e1, e2)
    out.polish = polished
    return _AdrRun(out, False, why)
