"""Load stepping of :func:`pdlin.solve_nonlinear`.

Predictors, automatic increments, cut-backs, the Newton -> ADR fallback, Newton's
backoff and ADR's polish.

Each load step runs Newton (:func:`~pdlin.solvers.newton.newton_step`) and/or adaptive
dynamic relaxation (:func:`~pdlin.solvers.adr.adr_step`) in automatic increments from
the committed state, commits the model's trial state when the step converges, records
one :class:`StepRecord` and writes the checkpoint (:mod:`pdlin.solvers.checkpoint`).
The driver knows no material: a model reports the warnings of its committed state
through :meth:`pdlin.models.Model.committed_issues`, and trial iterates may leave a state
questionable (:class:`~pdlin.errors.TrialStateWarning`, not issued here).
"""

from __future__ import annotations

import logging
import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ..constraints import eliminate_dirichlet
from ..errors import ConvergenceError, InputError, NonFiniteError, TrialStateWarning
from ..operators.bc import TimePath
from ..system import ConstrainedSystem
from .adr import adr_density, adr_step
from .checkpoint import (
    _adr_key,
    _check_checkpoint,
    _checkpoint_arrays,
    _checkpoint_states,
    _checkpoint_steps,
    _load_digest,
    _read_checkpoint,
    _read_snapshots,
    _write_atomic_npz,
    _write_snapshots,
)
from .linear import SolverSetup, solve_linear
from .newton import newton_step
from .newton_krylov import KrylovDirection
from .options import KRYLOV, PREDICTORS, ADROptions, NewtonOptions, StepControl
from .outcome import StepFailed, StepOutcome, _linear_solver
from .ptc import ptc_step

__all__ = [
    "FELL_BACK",
    "SKIPPED",
    "LoadStepper",
    "StepRecord",
    "history_arrays",
    "homogenize_weights",
    "make_predictor",
    "step_times",
]

log = logging.getLogger(__name__)

#: failed tries in a row after which the tangent predictor restarts from the committed
#: state (measured, benchmarks/README.md: 1 doubled the 100² shear run, 3 or more left a
#: 50² compression path stalling at one kink through 15 cut-backs)
_RESTART_ELASTIC = 2
#: the largest ``‖r(u₁)‖`` of the first-order tangent predictor, relative to the force
#: increment it predicted, at which the second-order predictor adds its term (measured,
#: benchmarks/README.md: the elastic step 1 of the polycrystal leaves 3e-3; in plastic
#: increments the term, a chord step, did not help)
_SECOND_ORDER_MAX = 1e-2
#: ``result.methods`` entry of a load step that Newton failed and ADR finished
FELL_BACK = "adr (newton failed)"
#: ``result.methods`` entry of a load step that ``auto`` gave to ADR without trying Newton
#: (``newton_backoff``)
SKIPPED = "adr (newton skipped)"
_FELL_BACK, _SKIPPED = FELL_BACK, SKIPPED


@dataclass
class _Counts:
    """A load step's counts, summed over the increments it tried (failed ones included)."""

    iterations: int = 0
    calls: int = 0
    cutbacks: int = 0
    relaxation: int = 0  # Newton's ADR iterations at stalls
    polish: int = 0  # Newton iterations from ADR iterates

    def add(self, out: StepOutcome | None) -> None:
        """Add an increment's outcome (None: a failure that reported none)."""
        if out is not None:
            self.iterations += out.iterations
            self.calls += out.calls
            self.relaxation += out.relaxation
            self.polish += out.polish

    def merge(self, other: _Counts) -> None:
        """Add another driver's counts of the same load step."""
        self.iterations += other.iterations
        self.calls += other.calls
        self.cutbacks += other.cutbacks
        self.relaxation += other.relaxation
        self.polish += other.polish


def step_times(steps: int, t_end: float | None, times: Sequence[float] | None) -> np.ndarray:
    """Return the load-step times of :func:`pdlin.solve_nonlinear`.

    Parameters
    ----------
    steps : int
        Number of equal steps up to ``t_end`` (ignored with ``times``).
    t_end : float or None
        Time of the full load (default 1).
    times : sequence of float, optional
        Explicit step times (increasing, > 0).

    Returns
    -------
    (K,) ndarray
        The step times.

    Raises
    ------
    InputError
        ``times`` not increasing and positive, ``steps`` not an integer >= 1 or
        ``t_end`` not positive.
    """
    if times is not None:
        arr = np.asarray(times, dtype=float).reshape(-1)
        if (
            arr.size == 0
            or not np.all(np.isfinite(arr))
            or np.any(np.diff(arr) <= 0)
            or arr[0] <= 0
        ):
            raise InputError(
                f"times must be a non-empty increasing sequence of positive numbers, got {times!r}"
            )
        return arr
    if isinstance(steps, bool) or not isinstance(steps, int | np.integer) or steps < 1:
        raise InputError(f"steps must be an integer >= 1, got {steps!r}")
    te = 1.0 if t_end is None else float(t_end)
    if not (math.isfinite(te) and te > 0):
        raise InputError(f"t_end must be a positive number, got {t_end!r}")
    return te * np.arange(1, int(steps) + 1) / int(steps)


def _affine_path(system: ConstrainedSystem) -> tuple[np.ndarray, np.ndarray] | None:
    """Return the (L, center) shared by every TimePath of the system, if there is one."""
    found = None
    for bc in system.paths:
        v = bc.value
        if not isinstance(v, TimePath) or v.L is None:
            return None
        cur = (np.asarray(v.L, dtype=float), np.asarray(v.center, dtype=float))
        if found is not None and not (
            np.array_equal(found[0], cur[0]) and np.array_equal(found[1], cur[1])
        ):
            return None
        found = cur
    return found


class _Predictor:
    """Start of a load step (``kind`` resolved from 'auto' once)."""

    def __init__(self, system: ConstrainedSystem, kind: str, linear_solver: str) -> None:
        if kind not in PREDICTORS:
            raise InputError(f"predictor must be one of {PREDICTORS}, got {kind!r}")
        self.system = system
        self.linear_solver = linear_solver
        path = _affine_path(system)
        if kind == "affine" and path is None:
            raise InputError(
                "predictor='affine' needs Dirichlet.velocity_gradient conditions sharing one L "
                "and centre, got none or several"
            )
        self.kind = kind
        self.path = path
        self.calls = 0
        # the GMRES of linear_solver='krylov' (set by the load stepping)
        self.krylov: KrylovDirection | None = None
        # the state at the start of the last converged increment, whose end is the
        # committed solution: the continuation tangent's state (None before the first)
        self.prev_state: dict[str, np.ndarray] | None = None
        self._fails = 0  # failed tries since the last converged increment

    def converged(self, start_state: dict[str, np.ndarray]) -> None:
        """Note a converged increment from ``start_state`` (the continuation tangent's)."""
        self.prev_state = start_state
        self._fails = 0

    def failed(self) -> None:
        """Note a failed try.

        After ``_RESTART_ELASTIC`` in a row the retries start from the committed-state
        (elastic) tangent until an increment converges again.
        """
        self._fails += 1
        if self._fails >= _RESTART_ELASTIC:
            self.prev_state = None

    def resolved(self, driver: str) -> str:
        """Return the predictor a driver uses.

        'auto' is the second-order tangent one for Newton (the tangent predictor, half
        the iterations of the affine map on plastic polycrystals, plus its second-order
        term where the first-order one leaves a nearly linear residual: elastic steps
        in one iteration) and, for ADR when the paths share a velocity gradient,
        the incremental affine map ``u⁰ = exp(L Δt)(X + u) - X`` (pdlin's default: the
        paper of Luo, Ramazani & Sundararaghavan 2017 does not state its start).
        """
        if self.kind != "auto":
            return self.kind
        if driver == "adr" and self.path is not None:
            return "affine"
        return "tangent" if driver == "adr" else "second-order"

    def __call__(
        self,
        u_c: np.ndarray,
        state: dict[str, np.ndarray],
        t_c: float,
        u_p: np.ndarray | None,
        t_p: float | None,
        t_new: float,
        factor: float,
        values: np.ndarray,
        driver: str = "newton",
    ) -> np.ndarray:
        sysm = self.system
        kind = self.resolved(driver)
        if kind == "affine" and self.path is not None:
            L, c = self.path
            X = sysm.cloud.points - c
            E = scipy.linalg.expm(L * (t_new - t_c))
            u0 = ((X + u_c.reshape(X.shape)) @ E.T - X).reshape(-1)
        elif kind == "tangent":
            u0 = self._tangent(u_c, self.prev_state or state, factor, values)
        elif kind == "second-order":
            u0 = self._tangent(u_c, self.prev_state or state, factor, values, state)
        elif kind == "committed-tangent":
            u0 = self._tangent(u_c, state, factor, values)
        elif kind == "extrapolate" and u_p is not None and t_p is not None and t_c > t_p:
            u0 = u_c + (t_new - t_c) / (t_c - t_p) * (u_c - u_p)
        else:
            u0 = u_c.copy()
        u0[sysm.dofs] = values
        return u0

    def _tangent(
        self,
        u_c: np.ndarray,
        state: dict[str, np.ndarray],
        factor: float,
        values: np.ndarray,
        second: dict[str, np.ndarray] | None = None,
    ) -> np.ndarray:
        """``u_c + Δu`` with ``K_T(u_c) Δu = r(u_c)`` and the prescribed increment imposed.

        ``K_T`` and ``f_int`` are ``respond(u_c, state)``: from the committed state (the
        response at ``u_c`` of a zero increment: for crystal plasticity the elastic
        tangent), or from the state at the start of the last converged increment (the
        consistent tangent at that increment's end, which carries its active sets on
        into the next step; the force is the committed one up to the step tolerance).

        With ``second`` (the committed state of the increment), the second-order term
        is added: ``u₁ = u_c + Δu`` leaves ``r(u₁) = ½ f''[Δu, Δu] + O(|Δu|³)`` (the
        linear part cancels), and ``K_T Δu₂ = r(u₁)`` with the same matrix (one force
        evaluation without tangent and one more solve with the kept factorization or
        preconditioner) gives ``u₁ + Δu₂``, the start of the quadratic Taylor expansion
        of the load path; only where the increment is nearly linear, ``‖r(u₁)‖`` at most
        1e-2 of the force increment (the largest change of the reactions or of the free
        forces between ``u_c`` and ``u₁``).
        """
        sysm = self.system
        try:
            resp = sysm.respond(u_c, state, tangent=True)
        except (NonFiniteError, ConvergenceError) as exc:
            log.info("tangent predictor failed (%s); starting from the last solution", exc)
            return u_c.copy()
        self.calls += int(resp.calls)
        if resp.tangent is None:  # a model without a tangent: keep the last solution
            return u_c.copy()
        r = sysm.residual(None, factor=factor, f_int=resp.force)
        A, b = eliminate_dirichlet(
            sp.bsr_array(resp.tangent), r, sysm.dofs, values - u_c[sysm.dofs], inplace=True
        )
        b[sysm.dofs] = 0.0
        setup = SolverSetup()
        try:
            u1 = u_c + self._solve(A, b, setup)
        except ConvergenceError as exc:
            log.info("tangent predictor failed (%s); starting from the last solution", exc)
            return u_c.copy()
        if second is None:
            return u1
        u1[sysm.dofs] = values
        try:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                at = sysm.respond(u1, second)
        except (NonFiniteError, ConvergenceError):
            # the response at the first-order point failed (a non-finite stress, a
            # constitutive update that did not converge there): keep the first order, from
            # which Newton's own evaluation fails the increment if it must (a cut-back)
            return u1
        self.calls += int(at.calls)
        r1 = sysm.residual(None, factor=factor, f_int=at.force)
        r1[sysm.dofs] = 0.0
        # how far from linear the increment is: the residual left against the force
        # increment the linear solve predicted (its reactions' change, and the load's)
        df = np.ravel(at.force) - np.ravel(resp.force)
        increment = max(
            float(np.linalg.norm(df[sysm.dofs])) if sysm.dofs.size else 0.0,
            float(np.linalg.norm(df[sysm.free])),
        )
        if not (np.linalg.norm(r1) <= _SECOND_ORDER_MAX * increment):  # also NaN
            return u1
        try:
            return u1 + self._solve(A, r1, setup)
        except ConvergenceError as exc:
            log.info("second-order predictor term failed (%s); first order kept", exc)
            return u1

    def _solve(self, A: Any, b: np.ndarray, setup: SolverSetup) -> np.ndarray:
        """Solve the predictor's system (``setup`` keeps the factorization for a second)."""
        sysm = self.system
        if self.linear_solver == KRYLOV and self.krylov is not None:
            return self.krylov.solve(A, b, 1e-8)[0]
        solver = _linear_solver(sysm, self.linear_solver)
        return solve_linear(
            A,
            b,
            solver,
            rtol=1e-10,
            near_null=sysm.near_null() if solver.startswith("amg") else None,
            blocksize=sysm.dim,
            symmetric=sysm.symmetric,
            setup=setup,
        ).x


def _check_committed(u: np.ndarray, state: Any, k: int, t: float) -> None:
    """Refuse to commit a non-finite displacement or state variable.

    Trial iterates may overflow; their floating-point warnings are not issued, so this
    is where nothing may pass (raises :class:`~pdlin.errors.ConvergenceError`).
    """
    where = f"load step {k + 1} (t = {t:.6g})"
    if not np.all(np.isfinite(u)):
        raise ConvergenceError(f"{where}: the converged displacement is not finite")
    for key, val in (state or {}).items():
        arr = np.atleast_1d(np.asarray(val))
        if arr.dtype.kind in "fc" and not np.all(np.isfinite(arr)):
            bad = int(np.flatnonzero(~np.isfinite(arr.reshape(arr.shape[0], -1)).any(1))[0])
            raise ConvergenceError(
                f"{where}: the converged state variable {key!r} is not finite "
                f"(first at gradient point {bad})"
            )


@dataclass
class StepRecord:
    """One converged load step: its results and what it cost.

    Attributes
    ----------
    u, reactions : (n, dim) ndarray
        Converged displacement and nodal reactions.
    stress : (n, dim, dim) ndarray or None
        Cauchy stress per point (None: the model has none).
    homogenized_stress : (dim, dim) ndarray or None
        Volume average of ``stress`` over the homogenized points.
    iterations, calls, cutbacks, relaxations, polishes : int
        Iterations, constitutive evaluations, failed increments, Newton's relaxation
        iterations and ADR's polish iterations (summed over the increments tried).
    e1, e2 : float
        ADR's final relative criteria (NaN for Newton steps).
    residual : float
        Final relative residual.
    method, message : str
        Driver that converged the step, and why Newton failed or was skipped.
    damping : ndarray
        ADR damping coefficient per iteration (empty for Newton).
    step_time : float
        Wall seconds of the step (NaN: not recorded).
    load_digest : str
        The checkpoint's digest of the step's loads (empty without a checkpoint).
    """

    u: np.ndarray
    reactions: np.ndarray
    stress: np.ndarray | None
    homogenized_stress: np.ndarray | None
    iterations: int
    calls: int
    cutbacks: int
    relaxations: int = 0
    polishes: int = 0
    e1: float = math.nan
    e2: float = math.nan
    residual: float = 0.0
    method: str = ""
    message: str = ""
    damping: np.ndarray = field(default_factory=lambda: np.zeros(0))
    step_time: float = 0.0
    load_digest: str = ""


def history_arrays(records: Sequence[StepRecord]) -> dict[str, Any]:
    """Stack step records into per-step arrays (the columns of a ``NonlinearResult``).

    Parameters
    ----------
    records : sequence of StepRecord
        The load steps in order (at least one).

    Returns
    -------
    dict
        ``u``, ``reactions`` (k, n, dim); ``stress`` (k, n, dim, dim) and
        ``homogenized_stress`` (k, dim, dim), NaN for steps without, or None when no
        step has one; int64 ``iterations``, ``calls``, ``cutbacks``, ``relaxations``,
        ``polishes``; float ``e1``, ``e2``, ``residuals``, ``step_time``; lists
        ``methods``, ``messages``, ``damping``.
    """
    k = len(records)
    n, d = records[0].u.shape
    out: dict[str, Any] = {
        "u": np.stack([r.u for r in records]).astype(float, copy=False),
        "reactions": np.stack([r.reactions for r in records]).astype(float, copy=False),
        "stress": None,
        "homogenized_stress": None,
    }
    if any(r.stress is not None for r in records):
        stress = np.full((k, n, d, d), np.nan)
        hom = np.full((k, d, d), np.nan)
        for i, r in enumerate(records):
            if r.stress is not None:
                stress[i] = r.stress
                hom[i] = r.homogenized_stress
        out["stress"], out["homogenized_stress"] = stress, hom
    for name in ("iterations", "calls", "cutbacks", "relaxations", "polishes"):
        out[name] = np.array([getattr(r, name) for r in records], dtype=np.int64)
    out["e1"] = np.array([r.e1 for r in records], dtype=float)
    out["e2"] = np.array([r.e2 for r in records], dtype=float)
    out["residuals"] = np.array([r.residual for r in records], dtype=float)
    out["step_time"] = np.array([r.step_time for r in records], dtype=float)
    out["methods"] = [r.method for r in records]
    out["messages"] = [r.message for r in records]
    out["damping"] = [r.damping for r in records]
    return out


class LoadStepper:
    """The load steps of one :func:`pdlin.solve_nonlinear` call.

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system.
    times : (K,) ndarray
        Load-step times.
    t_end : float
        Time of the full load (plain values and loads scale with ``t / t_end``).
    control, newton, adr : StepControl, NewtonOptions, ADROptions
        The options.
    predictor : callable
        The start of each increment (:func:`make_predictor`).
    state0 : dict of str to ndarray
        The model's initial state.
    hom_w : (n,) ndarray
        Point weights of the homogenized stress (volumes, zero off the selection).
    keep_states : bool
        Keep every committed state (else the last).
    checkpoint : Path, optional
        The checkpoint file.
    fingerprint : dict of str to str
        The checkpoint's problem digests.
    progress : callable, optional
        Receives the progress lines.
    progress_every, snapshot_every : float
        Seconds between in-step progress lines and between ADR snapshots.
    """

    def __init__(
        self,
        system: ConstrainedSystem,
        times: np.ndarray,
        t_end: float,
        control: StepControl,
        newton: NewtonOptions,
        adr: ADROptions,
        predictor: _Predictor,
        state0: dict[str, np.ndarray],
        hom_w: np.ndarray,
        keep_states: bool,
        checkpoint: Path | None,
        fingerprint: dict[str, str],
        progress: Callable[[str], None] | None,
        progress_every: float,
        snapshot_every: float,
    ) -> None:
        self.system, self.tt, self.te = system, times, t_end
        material = getattr(getattr(system, "model", None), "material", None)
        self.rate_dependent = bool(getattr(material, "rate_dependent", False))
        self.control, self.newton, self.adr = control, newton, adr
        self.pred = predictor
        self.state0 = state0
        self.hom_w = hom_w
        self.keep_states = keep_states
        self.ckpt, self.fingerprint = checkpoint, fingerprint
        self.progress, self.progress_every = progress, progress_every
        self.snapshot_every = snapshot_every
        self.say: Callable[[str], None] = progress or (lambda msg: None)
        self.records: list[StepRecord] = []
        self.states: list[dict[str, np.ndarray]] = []
        self.state_steps: list[int] = []
        self.start = 0
        # the committed solution, its time, and the one before it
        self.u_c = np.zeros(system.ndof)
        self.state_c = dict(self.state0)
        self.t_c: float = 0.0
        self.u_p: np.ndarray | None = None
        self.t_p: float | None = None
        # the sub-step state read by the predictor
        self.t_cur: float = 0.0
        self.u_prev: np.ndarray | None = None
        self.t_prev: float | None = None
        self.k = 0  # the running load step
        # automatic incrementation: the last converged increment of each driver, as a
        # fraction of its load step, starts the next step (grown after easy convergence)
        self.inc_frac = {"newton": 1.0, "adr": 1.0}
        # ADR's backoff (any ADR increment is grown, so without it a size that fails would
        # be tried again at every step, each time for a whole iteration budget: ≈ 11 min
        # per load step at 10⁵ crystal-plasticity points): the held size `frac` (a
        # fraction of its load step; the last that failed) caps the increments at half of
        # it until load step `until`, which starts with that size again; `hold` load steps
        # in between, doubled when the retry fails; when it converges, the next larger
        # size is held (the same number of steps), up to the whole step, then it ends
        self.backoff: dict[str, Any] = {"frac": 1.0, "until": -1, "hold": 0}
        self.lam0: dict[str, np.ndarray] = {}
        self.direct_cache: dict[str, Any] = {}  # the tangent's factorization, reused
        # linear_solver='krylov': one AMG hierarchy of the elastic tangent for the run
        self.krylov = KrylovDirection(system, state0) if newton.linear_solver == KRYLOV else None
        predictor.krylov = self.krylov
        self.snap_path = (
            None
            if checkpoint is None
            else checkpoint.with_name(f"{checkpoint.stem}.adr{checkpoint.suffix}")
        )
        # the running load step's ADR snapshots (snapshot_every), one per increment tried
        # (keyed by _adr_key), all in one file: a resumed run continues every increment it
        # tries again from its snapshot, a failed whole step (which then fails again
        # within a snapshot interval, bit for bit) as well as the half it was cut back to
        self.snaps: dict[str, dict[str, np.ndarray]] = {}
        self.saved: dict[str, dict[str, np.ndarray]] = {}  # the killed run's, each used once
        # the interrupted run's time in the running step up to its last snapshot (added to
        # the step's wall time) and the step's start (read by the snapshots)
        self.step_clock = {"t0": 0.0, "before": 0.0}

    # -- resume -----------------------------------------------------------------------

    def resume(self, branch: bool) -> None:
        """Continue from the checkpoint file (if there is one) after its last step.

        Parameters
        ----------
        branch : bool
            Accept a checkpoint written with other solver options.

        Raises
        ------
        CheckpointError
            The checkpoint is unreadable or was written for another problem.
        """
        ckpt, say, tt = self.ckpt, self.say, self.tt
        assert ckpt is not None
        if not ckpt.exists():
            say(f"no checkpoint {ckpt} to resume: starting from step 1")
            log.info("no checkpoint %s to resume: starting from step 1", ckpt)
        else:
            data = _read_checkpoint(ckpt)
            _check_checkpoint(ckpt, data, self.system, tt, self.te, self.fingerprint, branch)
            self._restore(data)
            say(f"resuming from {ckpt} after step {self.start} of {tt.size}")
        assert self.snap_path is not None
        if self.snap_path.exists():
            self.saved = _read_snapshots(self.snap_path, say)

    def _restore(self, data: dict[str, np.ndarray]) -> None:
        """Restore the records, committed state and incrementation of a checkpoint."""
        self.records = [StepRecord(**kw) for kw in _checkpoint_steps(data)]
        start = self.start = len(self.records)
        tt = self.tt
        self.state_c, prev, history = _checkpoint_states(data)
        if start:
            self.u_c = self.records[start - 1].u.reshape(-1).copy()
            self.t_c = float(tt[start - 1])
        if start >= 2:
            self.u_p, self.t_p = self.records[start - 2].u.reshape(-1).copy(), float(tt[start - 2])
        self.pred.prev_state = prev or None  # absent from checkpoints of earlier versions
        if "increments" in data:  # idem: a resumed run continues the same increments
            inc_n, inc_a, b_frac, b_until, b_hold = (float(v) for v in data["increments"])
            self.inc_frac = {"newton": inc_n, "adr": inc_a}
            self.backoff = {"frac": b_frac, "until": int(b_until), "hold": int(b_hold)}
        if self.keep_states and history and all(v.shape[:1] == (start,) for v in history.values()):
            # the committed states of every step, as an uninterrupted run keeps them
            self.states = [{key: v[i] for key, v in history.items()} for i in range(start - 1)]
            self.states.append(dict(self.state_c))
            self.state_steps = list(range(start))
        else:
            self.states = [dict(self.state_c)] if start else []
            self.state_steps = [start - 1] if start else []

    # -- one increment of each driver -------------------------------------------------

    def _values(self, t: float) -> np.ndarray:
        return self.system.values_at(t, t / self.te)

    def _in_step(self, t_new: float) -> Callable[[str], None] | None:
        """Return the in-step progress callback of an increment to ``t_new``."""
        if self.progress is None:
            return None
        say = self.say
        return lambda m: say(f"  t = {t_new:g}: {m}")

    def _relax_density(self) -> np.ndarray | None:
        """Newton's relaxation density at stalls: at least the elastic tangent's bound."""
        if self.newton.relax == 0:
            return None
        if "relax" not in self.lam0:
            self.lam0["relax"] = adr_density(self.system, self.state0, None, dt=1.0, safety=1.1)
        return self.lam0["relax"]

    def _newton_to(
        self, t_new: float, u_from: np.ndarray, st: dict[str, np.ndarray]
    ) -> StepOutcome:
        u0 = self.pred(
            u_from,
            st,
            self.t_cur,
            self.u_prev,
            self.t_prev,
            t_new,
            t_new / self.te,
            self._values(t_new),
        )
        return self._newton_from(t_new, u0, st)

    def _newton_from(self, t_new: float, u0: np.ndarray, st: dict[str, np.ndarray]) -> StepOutcome:
        """Run Newton from ``u0`` to ``t_new``.

        ``u0`` is a predictor, or an ADR iterate for ``polish``; its prescribed entries
        are this increment's.
        """
        opts = self.newton
        if opts.globalization == "ptc":
            if "ptc" not in self.lam0:
                self.lam0["ptc"] = adr_density(self.system, self.state0, None, dt=1.0, safety=1.1)
            return ptc_step(
                self.system,
                u0,
                st,
                factor=t_new / self.te,
                density=self.lam0["ptc"],
                rtol=opts.rtol,
                maxiter=opts.maxiter,
                krylov=self.krylov,
                forcing=opts.forcing,
                linear_solver=opts.linear_solver,
                direct_cache=self.direct_cache,
                progress=self._in_step(t_new),
                progress_every=self.progress_every,
            )
        return newton_step(
            self.system,
            u0,
            st,
            factor=t_new / self.te,
            rtol=opts.rtol,
            maxiter=opts.maxiter,
            line_search=opts.line_search,
            linear_solver=opts.linear_solver,
            direct_cache=self.direct_cache,
            relax=opts.relax,
            relax_density=self._relax_density(),
            progress=self._in_step(t_new),
            progress_every=self.progress_every,
            krylov=self.krylov,
            forcing=opts.forcing,
        )

    def _adr_density(self, st: dict[str, np.ndarray], u0: np.ndarray) -> np.ndarray:
        """Return the ADR density of an increment.

        The explicit density, or the Gershgorin density of the tangent at the step's
        start (hardening raises it), never below that of the initial, elastic tangent
        (softening or plastic tangents would under-estimate the stiffness of elastic
        unloading).
        """
        opts = self.adr
        if opts.density is not None:
            return opts.density
        if "elastic" not in self.lam0:
            self.lam0["elastic"] = adr_density(
                self.system, self.state0, None, dt=opts.dt, safety=opts.density_safety
            )
        return np.maximum(
            self.lam0["elastic"],
            adr_density(self.system, st, u0, dt=opts.dt, safety=opts.density_safety),
        )

    def _snapshots(
        self, t_new: float, u0: np.ndarray, st: dict[str, np.ndarray], dens: np.ndarray
    ) -> tuple[Callable[[dict[str, Any]], None] | None, dict[str, Any] | None]:
        """Return the snapshot writer of an ADR increment and a killed run's snapshot."""
        snap_path = self.snap_path
        if snap_path is None:
            return None, None
        opts = self.adr
        budget = (
            opts.dt,
            -1.0 if opts.damping is None else float(opts.damping),
            float(opts.maxiter),
        )
        key = _adr_key(t_new, u0, st, dens, budget)
        restart = self.saved.pop(key, None)
        clock, snaps = self.step_clock, self.snaps
        if restart is not None:
            snaps[key] = restart  # kept in the file until this run snapshots it anew
            clock["before"] = max(clock["before"], float(restart.get("step_elapsed", 0.0)))
            self.say(
                f"  t = {t_new:g}: ADR continues from its snapshot after iteration "
                f"{int(restart['iteration']):,} ({snap_path})"
            )

        def snapshot(loop: dict[str, Any]) -> None:
            entry = {k: np.array(v) for k, v in loop.items()}  # copies: buffers rotate
            entry["step_elapsed"] = np.array(clock["before"] + time.perf_counter() - clock["t0"])
            snaps[key] = entry
            _write_snapshots(snap_path, snaps)

        return snapshot, restart

    def _adr_to(self, t_new: float, u_from: np.ndarray, st: dict[str, np.ndarray]) -> StepOutcome:
        u0 = self.pred(
            u_from,
            st,
            self.t_cur,
            self.u_prev,
            self.t_prev,
            t_new,
            t_new / self.te,
            self._values(t_new),
            "adr",
        )
        dens = self._adr_density(st, u0)
        snapshot, restart = self._snapshots(t_new, u0, st, dens)
        opts = self.adr
        polish_on = self.control.polish
        return adr_step(
            self.system,
            u0,
            st,
            factor=t_new / self.te,
            density=dens,
            dt=opts.dt,
            e_l=opts.e_l,
            maxiter=opts.maxiter,
            c0=opts.c0,
            damping=opts.damping,
            floor=opts.floor,
            progress=self._in_step(t_new),
            progress_every=self.progress_every,
            snapshot=snapshot,
            snapshot_every=float(self.snapshot_every),
            restart=restart,
            polish=(lambda u: self._newton_from(t_new, u, st)) if polish_on else None,
            stall=opts.stall,
        )

    # -- automatic increments ---------------------------------------------------------

    def _substeps(
        self,
        step_fn: Callable[[float, np.ndarray, dict[str, np.ndarray]], StepOutcome],
        driver: str,
        t_target: float,
        u_start: np.ndarray,
        st_start: dict[str, np.ndarray],
        damp: list[np.ndarray] | None,
        cutbacks: int,
    ) -> tuple[StepOutcome | None, str, _Counts, tuple[np.ndarray, dict[str, Any]]]:
        """Reach ``t_target`` from ``t_cur`` with ``step_fn`` in automatic increments.

        The first increment is the driver's last converged one (a fraction of the
        step); a failed increment is halved (a cut-back) down to ``1 / 2**cutbacks``
        of the step, a converged one commits its sub-step state and is doubled (up to
        the whole step) when it was easy: a Newton increment in at most ``maxiter // 4``
        iterations, any ADR increment (ADR's iterations per increment hardly depend on
        its size).  Returns the outcome of the last sub-step (None when an increment
        fails at the smallest size), why it failed, the counts and the last converged
        (u, state), from which a fallback driver continues.
        """
        backoff, k, pred = self.backoff, self.k, self.pred
        span = t_target - self.t_cur
        smallest = span / 2.0**cutbacks
        frac = min(1.0, self.inc_frac[driver])
        held = driver == "adr" and k < backoff["until"]
        if driver == "adr" and backoff["hold"] > 0:
            # below the failed size while it is held, that size again when the hold ends
            frac = min(frac, 0.5 * backoff["frac"]) if held else max(frac, backoff["frac"])
        inc = max(min(1.0, frac) * span, smallest)
        cur_u, cur_state = u_start, st_start
        cnt = _Counts()
        out: StepOutcome | None = None
        easy = max(2, self.newton.maxiter // 4)
        while t_target - self.t_cur > 1e-12 * span:
            last = t_target - self.t_cur <= inc * (1.0 + 1e-9)
            target = t_target if last else self.t_cur + inc
            st_in = self._timed(cur_state, target - self.t_cur)
            try:
                out = step_fn(target, cur_u, st_in)
            except StepFailed as exc:
                cnt.add(exc.outcome)
                cnt.cutbacks += 1
                pred.failed()
                if driver == "adr":
                    f = inc / span
                    # a retry of the held size (or larger) fails: hold it twice as long
                    again = backoff["hold"] > 0 and f >= backoff["frac"] * (1.0 - 1e-9)
                    hold = 2 * int(backoff["hold"]) if again else 1
                    backoff.update(frac=f, until=k + 1 + hold, hold=hold)
                    held = True
                if 0.5 * min(inc, t_target - self.t_cur) < smallest * (1.0 - 1e-9):
                    self.inc_frac[driver] = inc / span
                    return None, str(exc), cnt, (cur_u, cur_state)
                inc = 0.5 * min(inc, t_target - self.t_cur)
                t_back = self.t_cur + inc
                log.info("t = %.6g: %s; cutting back to t = %.6g", target, exc, t_back)
                self.say(f"  t = {target:g}: {exc}; cutting back to t = {t_back:g}")
                continue
            cnt.add(out)
            if damp is not None and out.damping is not None:
                damp.append(out.damping)
            self.u_prev, self.t_prev = cur_u, self.t_cur
            pred.converged(st_in)
            cur_u, cur_state, self.t_cur = out.u, out.response.state, target
            if (
                driver == "adr"
                and backoff["hold"] > 0
                and inc >= span * backoff["frac"] * (1.0 - 1e-9)
            ):
                # the held size converged: the next larger one is held next, as long
                if backoff["frac"] >= 1.0 - 1e-9:
                    backoff.update(frac=1.0, until=-1, hold=0)
                    held = False
                else:
                    backoff.update(frac=min(1.0, 2.0 * backoff["frac"]))
                    backoff.update(until=k + 1 + int(backoff["hold"]))
                    held = True
            if driver == "adr" or out.iterations <= easy:
                inc = min(span, 2.0 * inc)
            if held:
                inc = min(inc, max(0.5 * backoff["frac"] * span, smallest))
        self.inc_frac[driver] = inc / span
        return out, "", cnt, (cur_u, cur_state)

    def _timed(self, state: dict[str, np.ndarray], dt: float) -> dict[str, np.ndarray]:
        """Return ``state`` with the increment's time step ``state["dt"]`` (rate-dependent).

        A material with ``rate_dependent = True`` (``CrystalPlasticity(rate_exponent=...)``)
        reads the time increment of the update from its committed state; the driver adds
        it per increment (cut-backs included), never to a committed state.
        """
        if not self.rate_dependent:
            return state
        return {**state, "dt": np.asarray(float(dt))}

    # -- one load step ----------------------------------------------------------------

    def _newton_streak(self) -> int:
        """Load steps just before the running one without Newton (failed or skipped)."""
        k, streak = self.k, 0
        while streak < k and self.records[k - 1 - streak].method in (FELL_BACK, SKIPPED):
            streak += 1
        return streak

    def _solve_step(
        self, t_target: float, damp: list[np.ndarray]
    ) -> tuple[StepOutcome, str, str, _Counts]:
        """Newton, ADR or Newton then ADR to ``t_target`` from the committed state.

        Returns the outcome, the driver's name (``result.methods``), why Newton failed
        or was skipped, and the counts.
        """
        method = self.control.method
        max_cutbacks = self.control.max_cutbacks
        fallback_cutbacks = self.control.fallback_cutbacks
        step_u, step_state = self.u_c, self.state_c
        cnt = _Counts()
        out: StepOutcome | None = None
        used, why = method, ""
        if method in ("newton", "auto"):
            cut_n = max_cutbacks
            streak = self._newton_streak() if method == "auto" else 0
            if streak:
                # one halving fewer per further failed step, down to the whole step alone
                cut_n = min(max_cutbacks, max(0, fallback_cutbacks - (streak - 1)))
                self.inc_frac["newton"] = 1.0
            skip = (
                self.control.newton_backoff
                and streak > fallback_cutbacks + 1
                and streak & (streak - 1) != 0  # not a power of two
            )
            if skip:
                used = SKIPPED
                why = (
                    f"Newton skipped: no Newton in the last {streak} load steps "
                    "(newton_backoff: tried again when that count is a power of two)"
                )
            else:
                out, why, cnt, (step_u, step_state) = self._substeps(
                    self._newton_to, "newton", t_target, step_u, step_state, None, cut_n
                )
                if out is None and method == "newton":
                    raise ConvergenceError(
                        f"Newton failed at load step {self.k + 1} (t = {t_target:.6g}) after "
                        f"{cnt.cutbacks} cut-back(s): {why}"
                    )
                # with 'auto', ADR continues from Newton's last converged increment
                used = FELL_BACK if out is None else "newton"
        if method == "adr" or out is None:
            out, adr_why, adr_cnt, _ = self._substeps(
                self._adr_to, "adr", t_target, step_u, step_state, damp, max_cutbacks
            )
            cnt.merge(adr_cnt)
            if out is None:
                if used == SKIPPED:
                    prefix = f"{why}; "
                else:
                    prefix = f"Newton failed ({why}); " if why else ""
                raise ConvergenceError(
                    f"{prefix}ADR failed at load step {self.k + 1} (t = {t_target:.6g}) after "
                    f"{adr_cnt.cutbacks} cut-back(s): {adr_why}"
                )
        return out, used, why, cnt

    def _record(
        self, out: StepOutcome, used: str, why: str, cnt: _Counts, damp: list[np.ndarray]
    ) -> StepRecord:
        """Record a converged step (its stress from the response or the model)."""
        system, n, d = self.system, self.system.n, self.system.dim
        resp, u_new = out.response, out.u
        factor = float(self.tt[self.k]) / self.te
        sig = resp.stress
        if sig is None:
            try:
                sig = system.disc.stress(u_new.reshape(n, d))
            except Exception:  # noqa: BLE001 - models without a stress: record none
                sig = None
        hom = None
        if sig is not None:
            hom = np.einsum("i,iab->ab", self.hom_w, sig) / self.hom_w.sum()
        adr_ran = self.control.method == "adr" or used == FELL_BACK or used == SKIPPED
        return StepRecord(
            u=np.array(u_new.reshape(n, d), dtype=float),
            reactions=system.reactions(u_new, factor=factor, f_int=resp.force),
            stress=sig,
            homogenized_stress=hom,
            iterations=cnt.iterations,
            calls=cnt.calls + self.pred.calls,
            cutbacks=cnt.cutbacks,
            relaxations=cnt.relaxation,
            polishes=cnt.polish,
            e1=(np.nan if out.e1 is None else out.e1) if adr_ran else np.nan,
            e2=(np.nan if out.e2 is None else out.e2) if adr_ran else np.nan,
            residual=out.residual,
            method=used,
            message=why,
            damping=np.concatenate(damp) if damp else np.zeros(0),
        )

    def _commit(self, u_new: np.ndarray, state: dict[str, np.ndarray], t_target: float) -> None:
        """Commit a converged step: the solution, the state and its warnings."""
        k = self.k
        self.u_p, self.t_p = self.u_c, self.t_c
        self.u_c, self.state_c, self.t_c = u_new, dict(state), t_target
        for category, message in self.system.model.committed_issues(self.state_c):
            # stacklevel 4: the caller of solve_nonlinear (_commit <- step <- solve_nonlinear)
            warnings.warn(
                f"load step {k + 1} (t = {t_target:.6g}): {message}", category, stacklevel=4
            )
        if self.keep_states:
            self.states.append(self.state_c)
            self.state_steps.append(k)
        else:
            self.states = [self.state_c]
            self.state_steps = [k]

    def _write_checkpoint(self) -> None:
        """Write the checkpoint after the running step and drop its ADR snapshots."""
        assert self.ckpt is not None
        every = self.keep_states and self.state_steps == list(range(self.k + 1))
        arrays = _checkpoint_arrays(
            history_arrays(self.records),
            times=self.tt,
            shape=(self.system.n, self.system.dim),
            fingerprint=self.fingerprint,
            load_digests=[r.load_digest for r in self.records],
            increments=[
                self.inc_frac["newton"],
                self.inc_frac["adr"],
                self.backoff["frac"],
                self.backoff["until"],
                self.backoff["hold"],
            ],
            state=self.state_c,
            states=self.states if every else None,
            prev_state=self.pred.prev_state,
        )
        _write_atomic_npz(self.ckpt, arrays)
        self.snaps.clear()  # the step's increments are committed
        self.saved.clear()  # (a killed run's snapshots belong to this step or none)
        if self.snap_path is not None and self.snap_path.exists():
            self.snap_path.unlink()

    def step(self, k: int) -> None:
        """Solve, record, commit and checkpoint load step ``k`` (0-based).

        Parameters
        ----------
        k : int
            The load step; the steps before it are committed.

        Raises
        ------
        ConvergenceError
            The step fails with the chosen method, or would commit a non-finite
            displacement or state.
        """
        self.k = k
        with warnings.catch_warnings():
            # trial iterates may leave a material's state questionable (e.g. a crystal's
            # active set unsettled); only the committed state matters (checked below)
            warnings.simplefilter("ignore", TrialStateWarning)
            t0 = time.perf_counter()
            self.step_clock["t0"], self.step_clock["before"] = t0, 0.0
            t_target = float(self.tt[k])
            self.pred.calls = 0
            damp: list[np.ndarray] = []
            # the sub-step loop shares these with the predictor
            self.t_cur, self.u_prev, self.t_prev = self.t_c, self.u_p, self.t_p
            out, used, why, cnt = self._solve_step(t_target, damp)
            rec = self._record(out, used, why, cnt, damp)
        _check_committed(out.u, out.response.state, k, t_target)
        if self.ckpt is not None:
            rec.load_digest = _load_digest(self.system, t_target, self.te)
        self.records.append(rec)
        self._commit(out.u, out.response.state, t_target)
        # with the interrupted run's time in this step up to its last snapshot, if resumed
        rec.step_time = time.perf_counter() - t0 + self.step_clock["before"]
        if self.ckpt is not None:
            self._write_checkpoint()
        self.say(
            f"step {k + 1}/{self.tt.size} t = {t_target:.6g}: {used}, {cnt.iterations} "
            f"iteration(s), {cnt.cutbacks} cut-back(s), "
            + (f"{cnt.relaxation} relaxation iteration(s), " if cnt.relaxation else "")
            + (f"{cnt.polish} Newton polish iteration(s), " if cnt.polish else "")
            + f"residual {out.residual:.2e}, {rec.step_time:.2f} s"
        )


def make_predictor(system: ConstrainedSystem, kind: str, linear_solver: str) -> _Predictor:
    """Return the start of each increment of a run.

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system.
    kind : str
        One of ``PREDICTORS`` ('auto' is resolved per driver).
    linear_solver : str
        The inner linear solver of the tangent predictor.

    Returns
    -------
    _Predictor
        A callable ``(u_c, state, t_c, u_p, t_p, t_new, factor, values, driver)`` that
        returns the start displacement of an increment.

    Raises
    ------
    InputError
        An unknown kind, or 'affine' without velocity-gradient paths sharing one L.
    """
    return _Predictor(system, kind, linear_solver)


def homogenize_weights(system: ConstrainedSystem, homogenize: Any) -> np.ndarray:
    """Return the point weights of the homogenized stress.

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system.
    homogenize : index array, mask or None
        The points of the volume average (None: all).

    Returns
    -------
    (n,) ndarray
        The point volumes, zero off the selection.

    Raises
    ------
    InputError
        The selection has no points with positive volume.
    """
    hom_w = np.asarray(system.cloud.volumes, dtype=float).copy()
    if homogenize is not None:
        idx = system.cloud.select(homogenize)
        mask = np.zeros(system.n, dtype=bool)
        mask[idx] = True
        hom_w[~mask] = 0.0
    if hom_w.sum() <= 0:
        raise InputError("homogenize selects no points with positive volume")
    return hom_w
