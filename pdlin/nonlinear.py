"""Load-stepped nonlinear static solves: ``pdlin.solve_nonlinear``.

A problem is transformed once into its :class:`~pdlin.system.ConstrainedSystem`;
each load step then runs a driver from :mod:`pdlin.solvers.nonlinear` (Newton
with line search and cut-back, adaptive dynamic relaxation, or Newton with an
ADR fallback) and commits the model's trial state when it converges.
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import time
import warnings
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ._fingerprint import digest
from ._repr import compact_repr, html_table, time_span
from ._validation import as_float_array, integer
from .constraints import eliminate_dirichlet
from .errors import (
    CheckpointError,
    CheckpointWriteError,
    ConvergenceError,
    InputError,
    InputTypeError,
    ShapeError,
    TrialStateWarning,
)
from .operators.bc import TimePath
from .problem import StaticProblem
from .solvers.linear import solve_linear
from .solvers.nonlinear import (
    StepFailed,
    StepOutcome,
    _linear_solver,
    adr_density,
    adr_step,
    newton_step,
)
from .system import ConstrainedSystem, constrained_system

__all__ = ["NonlinearResult", "solve_nonlinear", "METHODS", "PREDICTORS"]

log = logging.getLogger(__name__)

METHODS = ("newton", "adr", "auto")
#: failed tries in a row after which the tangent predictor restarts from the committed
#: state (measured 2026-11-25, docs/nonlinear.md: 1 doubled the 100² shear run, 3 or more
#: left a 50² compression path stalling at one kink through 15 cut-backs)
_RESTART_ELASTIC = 2

PREDICTORS = ("auto", "affine", "tangent", "committed-tangent", "extrapolate", "previous")
#: 2: with the problem's fingerprint (``fp__*``) and, with ``keep_states``, every committed
#: state (``states__*``); 1 (before 2026-11-28): neither
_CHECKPOINT_VERSION = 2
#: the parts of a checkpoint's fingerprint (one SHA-256 digest each, ``fp__<part>``) and
#: how a refused resume names them; ``loads`` holds one digest per committed step
_PARTS = {
    "points": "points (coordinates, volumes)",
    "bonds": "bonds (horizon, influence)",
    "model": "model and material parameters",
    "homogenize": "homogenized points",
    "solver": "solver options",
    "loads": "boundary conditions and loads",
}
#: errors of reading a damaged NPZ file (truncated: BadZipFile or EOFError; garbage:
#: numpy's "pickled data" ValueError; a missing array: KeyError)
_UNREADABLE = (OSError, ValueError, KeyError, IndexError, EOFError, zipfile.BadZipFile)
#: what ``resume`` accepts
_RESUME = (False, True, "branch")


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


@dataclass
class NonlinearResult:
    """Per-step results of :func:`solve_nonlinear`.

    Attributes
    ----------
    times, factors : (k,) ndarray
        Time and proportional load factor ``t / t_end`` of each load step.
    u : (k, n, dim) ndarray
        Converged displacement per step.
    stress : (k, n, dim, dim) ndarray or None
        Cauchy stress per point (the model's response, or its linear stress).
    homogenized_stress : (k, dim, dim) ndarray or None
        Volume average of ``stress`` over the homogenized points.
    reactions : (k, n, dim) ndarray
        Nodal reactions on the prescribed DOFs.
    states : list of dict
        Committed states (every step, also after a resume; only the last with
        ``keep_states=False``, or after a resume from a checkpoint written with it):
        ``state_steps`` gives their step indices and :meth:`state_at` looks one up.
    iterations, calls, cutbacks : (k,) ndarray of int
        Newton iterations or ADR iterations, constitutive evaluations and
        failed increments (cut-backs) per step (summed over sub-steps).
    methods : list of str
        Driver that converged each step: ``'newton'``, ``'adr'``,
        ``'adr (newton failed)'`` (``method='auto'`` fell back) or ``'adr (newton
        skipped)'`` (``auto`` did not try Newton, ``newton_backoff``).
    messages : list of str
        Why Newton failed on a step that fell back, or why it was skipped (empty
        otherwise).
    damping : list of ndarray
        ADR damping coefficient per iteration of each step (empty for Newton).
    e1, e2 : (k,) ndarray
        ADR's final relative criteria (NaN for Newton steps).
    residuals : (k,) ndarray
        Final relative residual ``‖r_free‖ / force scale`` per step.
    timings : dict
        ``'setup'``, ``'total'`` seconds (of this call) and ``'steps'`` (k,) wall seconds
        per step; a resumed run's steps from the checkpoint carry the times measured by
        the run that solved them (NaN from a checkpoint that recorded none).
    """

    problem: StaticProblem
    system: ConstrainedSystem
    times: np.ndarray
    factors: np.ndarray
    u: np.ndarray
    stress: np.ndarray | None
    homogenized_stress: np.ndarray | None
    reactions: np.ndarray
    states: list[dict[str, np.ndarray]]
    iterations: np.ndarray
    calls: np.ndarray
    cutbacks: np.ndarray
    methods: list[str]
    messages: list[str]
    damping: list[np.ndarray]
    e1: np.ndarray
    e2: np.ndarray
    residuals: np.ndarray
    timings: dict[str, Any] = field(default_factory=dict)
    resumed_from: int = 0
    #: ADR iterations Newton ran at stalls per step (``relax`` of :func:`solve_nonlinear`)
    relaxations: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: Newton iterations that finished stalled ADR increments per step (``polish`` of
    #: :func:`solve_nonlinear`; failed tries included)
    polishes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: load-step index (0-based) of each entry of ``states``: all steps, or with
    #: ``keep_states=False`` the last one (after a resume from a checkpoint written with
    #: ``keep_states=False``: its last committed step followed by the steps solved here)
    state_steps: list[int] = field(default_factory=list)

    def state_at(self, step: int) -> dict[str, np.ndarray] | None:
        """Committed state after load step ``step`` (0-based), or None if not kept."""
        k = step % self.n_steps if self.n_steps else step
        try:
            return self.states[self.state_steps.index(k)]
        except ValueError:
            return None

    @property
    def converged(self) -> bool:
        """Every step converged (a failing step raises, so always True on a result)."""
        return True

    @property
    def state(self) -> dict[str, np.ndarray]:
        """The committed state after the last step."""
        return self.states[-1]

    @property
    def n_steps(self) -> int:
        return int(self.times.size)

    def _table(self) -> list[tuple[str, Any]]:
        k, n, d = (int(s) for s in self.u.shape)
        return [
            ("model", repr(self.problem.model)),
            ("points", n),
            ("dim", d),
            ("DOFs", n * d),
            ("steps", k),
            ("times", time_span(self.times)),
            ("methods", ", ".join(sorted(set(self.methods))) or None),
            ("iterations", int(self.iterations.sum())),
            ("cutbacks", int(self.cutbacks.sum())),
            ("max residual", float(np.max(self.residuals)) if k else None),
            ("resumed from step", self.resumed_from or None),
            ("time (s)", float(self.timings.get("total", np.nan))),
        ]

    def __repr__(self) -> str:
        """Sizes, steps, drivers, iterations and residual (no arrays, no memory address)."""
        names = {"max residual": "max_residual", "time (s)": "seconds"}
        names["resumed from step"] = "resumed_from"
        items = {names.get(key, key): v for key, v in self._table() if key != "model"}
        return compact_repr("NonlinearResult", items)

    def _repr_html_(self) -> str:
        """The summary as an HTML table (Jupyter)."""
        return html_table("NonlinearResult", self._table())

    def summary(self) -> dict[str, Any]:
        """Plain-data summary (for the CLI and logs)."""
        return {
            "steps": self.n_steps,
            "points": int(self.u.shape[1]),
            "dim": int(self.u.shape[2]),
            "methods": sorted(set(self.methods)),
            "iterations": int(self.iterations.sum()),
            "constitutive_calls": int(self.calls.sum()),
            "cutbacks": int(self.cutbacks.sum()),
            "relaxation_iterations": int(self.relaxations.sum()),
            "polish_iterations": int(self.polishes.sum()),
            "fallbacks": int(sum(1 for m in self.methods if "failed" in m)),
            "newton_skipped": int(sum(1 for m in self.methods if m == _SKIPPED)),
            "max_relative_residual": float(np.max(self.residuals)) if self.n_steps else 0.0,
            "timings": {
                "setup": round(float(self.timings.get("setup", 0.0)), 4),
                "total": round(float(self.timings.get("total", 0.0)), 4),
            },
        }


def _times(steps: int, t_end: float | None, times: Sequence[float] | None) -> np.ndarray:
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
    """The (L, center) shared by every TimePath of the system, if there is one."""
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
        # the state at the start of the last converged increment, whose end is the
        # committed solution: the continuation tangent's state (None before the first)
        self.prev_state: dict[str, np.ndarray] | None = None
        self._fails = 0  # failed tries since the last converged increment

    def converged(self, start_state: dict[str, np.ndarray]) -> None:
        """An increment from ``start_state`` converged: the continuation tangent's state."""
        self.prev_state = start_state
        self._fails = 0

    def failed(self) -> None:
        """A try failed: after ``_RESTART_ELASTIC`` in a row the retries start from the
        committed-state (elastic) tangent until an increment converges again."""
        self._fails += 1
        if self._fails >= _RESTART_ELASTIC:
            self.prev_state = None

    def resolved(self, driver: str) -> str:
        """The predictor a driver uses: 'auto' is the tangent one for Newton (half the
        iterations of the affine map on plastic polycrystals), the affine map of spec 001
        §4.3 for ADR when the paths share a velocity gradient."""
        if self.kind != "auto":
            return self.kind
        if driver == "adr" and self.path is not None:
            return "affine"
        return "tangent"

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
        elif kind == "committed-tangent":
            u0 = self._tangent(u_c, state, factor, values)
        elif kind == "extrapolate" and u_p is not None and t_p is not None and t_c > t_p:
            u0 = u_c + (t_new - t_c) / (t_c - t_p) * (u_c - u_p)
        else:
            u0 = u_c.copy()
        u0[sysm.dofs] = values
        return u0

    def _tangent(
        self, u_c: np.ndarray, state: dict[str, np.ndarray], factor: float, values: np.ndarray
    ) -> np.ndarray:
        """``u_c + Δu`` with ``K_T(u_c) Δu = r(u_c)`` and the prescribed increment imposed.

        ``K_T`` and ``f_int`` are ``respond(u_c, state)``: from the committed state (the
        response at ``u_c`` of a zero increment: for crystal plasticity the elastic
        tangent), or from the state at the start of the last converged increment (the
        consistent tangent at that increment's end, which carries its active sets on
        into the next step; the force is the committed one up to the step tolerance).
        """
        sysm = self.system
        resp = sysm.respond(u_c, state, tangent=True)
        self.calls += int(resp.calls)
        if resp.tangent is None:  # a model without a tangent: keep the last solution
            return u_c.copy()
        r = sysm.residual(None, factor=factor, f_int=resp.force)
        A, b = eliminate_dirichlet(
            sp.bsr_array(resp.tangent), r, sysm.dofs, values - u_c[sysm.dofs], inplace=True
        )
        b[sysm.dofs] = 0.0
        solver = _linear_solver(sysm, self.linear_solver)
        try:
            lin = solve_linear(
                A,
                b,
                solver,
                rtol=1e-10,
                near_null=sysm.near_null() if solver.startswith("amg") else None,
                blocksize=sysm.dim,
                symmetric=sysm.symmetric,
            )
        except ConvergenceError as exc:
            log.info("tangent predictor failed (%s); starting from the last solution", exc)
            return u_c.copy()
        return u_c + lin.x


def _why_unreadable(exc: BaseException) -> str:
    """Why ``np.load`` could not read a file (numpy takes a file that is no ZIP archive for
    a pickle and suggests ``allow_pickle=``: here it is just not an NPZ file)."""
    if isinstance(exc, ValueError) and "pickled" in str(exc):
        return "not an NPZ file"
    return f"{type(exc).__name__}: {exc}"


def _write_atomic_npz(path: Path, arrays: dict[str, np.ndarray], what: str = "checkpoint") -> None:
    """Write ``arrays`` to ``path`` through ``<path>.tmp`` and a rename: ``path`` holds the
    old or the new file, never a part of one, and no ``.tmp`` file is left behind.

    Raises
    ------
    CheckpointWriteError
        The write failed (e.g. a full disk); the message names ``path`` (``what``: the
        kind of file) and the previous file is kept.
    """
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)  # type: ignore[arg-type]
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:  # pragma: no cover - the folder itself is gone
            pass
        if isinstance(exc, OSError):
            reason = exc.strerror or str(exc) or type(exc).__name__
            raise CheckpointWriteError(
                f"could not write the {what} {str(path)!r}: {reason}; the previous {what} "
                "(if any) is kept"
            ) from exc
        raise


def _write_snapshots(path: Path, snaps: dict[str, dict[str, np.ndarray]]) -> None:
    """The ADR snapshots of the running load step, by increment key, in one NPZ file."""
    arrays: dict[str, np.ndarray] = {"keys": np.array(list(snaps), dtype=str)}
    for i, entry in enumerate(snaps.values()):
        for name, value in entry.items():
            arrays[f"s{i}__{name}"] = np.asarray(value)
    _write_atomic_npz(path, arrays, "ADR snapshot file")


def _read_snapshots(
    path: Path, say: Callable[[str], None] = lambda msg: None
) -> dict[str, dict[str, np.ndarray]]:
    """The snapshots of :func:`_write_snapshots` (none from an unreadable file, which is
    named in a warning and through ``say``: the increments then start afresh, as without
    snapshots, and end where the snapshots would have led)."""
    try:
        with np.load(path, allow_pickle=False) as f:
            keys = [str(k) for k in f["keys"]]
            out: dict[str, dict[str, np.ndarray]] = {key: {} for key in keys}
            for name in f.files:
                if name != "keys":
                    idx, _, field_name = name.partition("__")
                    out[keys[int(idx[1:])]][field_name] = f[name]
    except _UNREADABLE as exc:
        why = _why_unreadable(exc)
        log.warning("ADR snapshot file %s is unreadable (%s); the step starts afresh", path, why)
        say(f"ADR snapshot file {path} is unreadable ({why}); the step starts afresh")
        return {}
    return out


def _fingerprint(
    system: ConstrainedSystem, hom_w: np.ndarray, solver_options: dict[str, Any]
) -> dict[str, str]:
    """The digests of a checkpoint's fingerprint but the per-step loads (``_PARTS``)."""
    cloud = system.cloud
    bonds = getattr(system.disc, "bonds", None) or system.disc.real_bonds
    return {
        "points": digest(cloud.points, cloud.volumes),
        "bonds": digest(
            *(bonds.i, bonds.j, bonds.omega, bonds.volume_j, bonds.horizon),
            *(bonds.shape, bonds.influence),
        ),
        "model": digest(system.model),
        "homogenize": digest(hom_w),
        "solver": digest(solver_options),
    }


def _load_digest(system: ConstrainedSystem, t: float, t_end: float) -> str:
    """The digest of a load step's prescribed DOFs, their values and the external force at
    time ``t`` (plain values and loads scaled by ``t / t_end``, load paths evaluated)."""
    factor = t / t_end
    return digest(system.dofs, system.values_at(t, factor), factor * system.f_ext)


def _read_checkpoint(path: Path) -> dict[str, np.ndarray]:
    """Every array of a checkpoint file.

    Raises
    ------
    CheckpointError
        The file is unreadable (truncated, not an NPZ file, an array missing).
    """
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {name: f[name] for name in f.files}
        int(data["version"]), int(data["done"])  # noqa: B018 - present and readable
    except _UNREADABLE as exc:
        raise CheckpointError(
            f"checkpoint {str(path)!r} is unreadable ({_why_unreadable(exc)}); remove it, "
            "or start afresh without resume (pdlin run without --resume), which overwrites it"
        ) from exc
    return data


def _check_checkpoint(
    path: Path,
    data: dict[str, np.ndarray],
    system: ConstrainedSystem,
    tt: np.ndarray,
    te: float,
    fingerprint: dict[str, str],
    branch: bool,
) -> None:
    """Refuse a checkpoint of another problem (``_PARTS``, the step times; the solver
    options only when not ``branch``), naming the parts that differ.

    Raises
    ------
    CheckpointError
        Written by a pdlin without a fingerprint, or for another problem.
    """
    where = f"checkpoint {str(path)!r}"
    fix = "remove it, or start afresh without resume (pdlin run without --resume)"
    version = int(data["version"])
    if version != _CHECKPOINT_VERSION or any(f"fp__{p}" not in data for p in _PARTS):
        raise CheckpointError(
            f"{where} has no problem fingerprint (version {version}, written by an earlier "
            f"pdlin; this one writes version {_CHECKPOINT_VERSION}), so it cannot be checked "
            f"against this problem; {fix}"
        )
    done = int(data["done"])
    ck_times = np.asarray(data["times"], dtype=float)
    differ = [
        _PARTS[part]
        for part, value in fingerprint.items()
        if str(data[f"fp__{part}"]) != value and not (branch and part == "solver")
    ]
    if done > tt.size or not np.allclose(ck_times[:done], tt[:done], rtol=1e-12, atol=0.0):
        differ.append(f"step times (the checkpoint's first {done}: {ck_times[:done].tolist()})")
    else:
        stored = [str(v) for v in data["fp__loads"][:done]]
        if stored != [_load_digest(system, float(t), te) for t in ck_times[:done]]:
            differ.append(_PARTS["loads"])
    if differ:
        hint = (
            "; resume='branch' continues a checkpoint with other solver options"
            if differ == [_PARTS["solver"]]
            else ""
        )
        raise CheckpointError(
            f"{where} was written for a different problem: {', '.join(differ)} differ; {fix}{hint}"
        )


#: ``result.methods`` entry of a load step that Newton failed and ADR finished
_FELL_BACK = "adr (newton failed)"
#: ``result.methods`` entry of a load step that ``auto`` gave to ADR without trying Newton
#: (``newton_backoff``)
_SKIPPED = "adr (newton skipped)"


def _check_committed(u: np.ndarray, state: Any, k: int, t: float) -> None:
    """Raise :class:`~pdlin.errors.ConvergenceError` when a converged load step would
    commit a non-finite displacement or state variable (trial iterates may overflow;
    their floating-point warnings are not issued, so this is where nothing may pass)."""
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


def solve_nonlinear(
    problem: StaticProblem,
    steps: int = 10,
    *,
    method: str = "auto",
    t_end: float | None = None,
    times: Sequence[float] | None = None,
    predictor: str = "auto",
    rtol: float = 1e-8,
    maxiter: int = 25,
    line_search: bool = True,
    max_cutbacks: int = 8,
    fallback_cutbacks: int = 2,
    newton_backoff: bool = True,
    linear_solver: str = "auto",
    relax: int = 0,
    e_l: float = 1e-6,
    density: Any = "gershgorin",
    density_safety: float = 1.1,
    dt: float | None = None,
    damping: float | None = None,
    c0: float = 1.0,
    adr_maxiter: int | None = None,
    floor: float = 1e-12,
    polish: bool | None = None,
    adr_stall: int | None = None,
    homogenize: Any = None,
    keep_states: bool = True,
    checkpoint: str | os.PathLike[str] | None = None,
    resume: bool | str = False,
    progress: Callable[[str], None] | None = None,
    progress_every: float = 60.0,
    snapshot_every: float = 300.0,
) -> NonlinearResult:
    """Solve a static problem with a nonlinear or history-dependent model in load steps.

    Step ``k`` runs to time ``t_k`` (``times``, or ``t_end k / steps``):
    :class:`~pdlin.TimePath` conditions (e.g. :meth:`pdlin.Dirichlet.velocity_gradient`)
    are evaluated at ``t_k``, other prescribed values and loads are scaled
    by ``t_k / t_end``.  The model's state (e.g. plastic deformation and slip
    resistances of :class:`pdlin.CrystalPlasticity`) is committed only when a
    step converges.

    Parameters
    ----------
    problem : StaticProblem
        Any pdlin model; nonlinear ones implement :meth:`pdlin.Model.respond`
        (e.g. ``Correspondence(material=CrystalPlasticity(...))``).  Linear
        models are solved exactly the same way (Newton converges in one
        iteration; ADR converges to the linear solution).
    steps : int
        Number of equal load steps up to ``t_end`` (ignored with ``times``).
    method : {'auto', 'newton', 'adr'}
        'newton': Newton-Raphson with the consistent tangent, backtracking
        line search and step cut-back.  'adr': adaptive dynamic relaxation
        (Kilic-Madenci; spec 001 §4).  'auto': Newton, falling back to ADR
        from Newton's last converged increment when an increment fails even
        after ``max_cutbacks`` halvings (``result.methods`` says so; after
        such a step, see ``fallback_cutbacks``).
    t_end : float, optional
        Time of the full load (default 1): the end of ``steps`` equal steps,
        and the time at which plain prescribed values and loads reach their
        given size (they scale with ``t / t_end``; with ``times`` beyond
        ``t_end`` they keep growing proportionally).
    times : sequence of float, optional
        Explicit step times (increasing, > 0).
    predictor : {'auto', 'affine', 'tangent', 'committed-tangent', 'extrapolate', 'previous'}
        Start of each step: the incremental affine map of a velocity-gradient
        path (spec 001 §4.3); the tangent predictor ``u + Δu`` with
        ``K_T(u) Δu = r(u)`` and the prescribed increment imposed (one linear
        solve; exact for linear models), ``K_T`` the consistent tangent at the
        end of the last converged increment (its active sets carried on; from
        the committed state at the first step); 'committed-tangent' the same
        with ``K_T`` from the committed state (a zero increment: for crystal
        plasticity the elastic tangent); a linear extrapolation of the last
        two steps; or the last solution. 'auto': tangent for Newton steps;
        for ADR steps affine when the prescribed paths share one velocity
        gradient, else tangent.
    rtol, maxiter, line_search, max_cutbacks, linear_solver
        Newton: convergence ``‖r_free‖ <= rtol`` x force scale (the larger of
        ``‖λ f_ext‖`` and the reaction norm), iteration budget per (sub)step,
        backtracking on/off, how often one increment may be halved (Newton and
        ADR; the smallest increment is the step / 2**max_cutbacks; a converged
        increment is doubled after easy convergence and the last one starts the
        next step; ADR grows its increments back to a size that failed only
        after a hold: the next load step stays below it, the one after starts with
        it; while the retry fails the hold doubles, 1, 2, 4, ... load steps, and
        after it converges the next larger size is held likewise), inner linear
        solver
        ('auto': direct up to 2·10⁵ DOFs in 2D / 3·10⁴ in 3D, then AMG-Krylov).
    fallback_cutbacks : int
        ``method='auto'``: Newton's halvings in a load step that follows an
        ADR fallback, one fewer for every further consecutive fallback step
        down to the whole step alone (``max_cutbacks`` again once Newton
        carries a step); the step starts with a whole-step increment.  Where
        Newton failed the last step it likely fails this one too, and each
        failed increment costs up to ``maxiter`` tangents and linear solves,
        while ADR's cost hardly depends on how much of the step is left (10⁵
        crystal-plasticity points: ≈ 20 min of creeping Newton increments per
        step before the fallback with ``max_cutbacks`` halvings,
        docs/nonlinear.md).
    newton_backoff : bool
        ``method='auto'``: once Newton has failed ``fallback_cutbacks + 1`` load steps in a
        row (its tries then down to the whole step alone), try it only when the number of
        steps in a row without Newton is a power of two (4, 8, 16, ...) and give the other
        steps to ADR directly (``result.methods``: ``'adr (newton skipped)'``); a step
        Newton carries ends the streak.  At 10⁵ crystal-plasticity points a failing
        whole-step Newton try costs ≈ 1.5 min of an ≈ 9 min step (docs/nonlinear.md).
        False: try Newton at every step.
    relax : int
        Newton's relaxation at stalls (0, the default: off; e.g. 50): when five
        Newton iterations reduce ``‖r‖`` less than twofold, or a line search
        fails, up to ``relax`` ADR iterations from the current iterate (at rest,
        Gershgorin density of the current tangent and at least that of the
        elastic one), and Newton resumes from the last of them.
        At active-set switches (a crystal whose slip systems load or unload)
        ``r(u)`` has kinks, and Newton can stall jumping across them; the
        relaxation settles such local errors (``result.relaxations`` counts its
        iterations).  It lets ``method='newton'`` through stalls it would fail;
        with ``'auto'`` it was not faster than the ADR fallback in the measured
        runs (docs/nonlinear.md), hence off by default.
    e_l, density, density_safety, dt, damping, c0, adr_maxiter, floor
        ADR: target of the relative criteria e₁, e₂ (spec 001 Eqs. 19-20);
        fictitious density ``'gershgorin'`` (Kilic-Madenci, ``Λ_ii = s ¼ Δt²
        Σ_j |K_ij|`` of the tangent at each step's predictor, at least that of
        the initial (elastic) tangent, with Δt = ``dt`` or 1 and the safety
        ``s = density_safety``: at ``s = 1`` the highest mode sits at the
        stability limit and decays very slowly, 1.1 keeps it damped;
        hardening materials far from equilibrium may need more) or a
        positive number / ``(n*dim,)`` array with an explicit ``dt`` (spec
        001 Eq. 12: ``Λ = 1``, ``Δt = h sqrt(1/E_max)``); constant
        ``damping`` instead of the adaptive Rayleigh quotient (finite, >= 0); initial
        damping ``c0`` (finite, >= 0); iteration budget per step, an integer >= 1
        (default ``200 ⌈N^(1/dim)⌉ + 2000``); absolute floor on ``‖r‖`` relative to the
        force scale.
    polish : bool, optional
        Finish ADR increments that stall with Newton from ADR's iterate
        (:func:`~pdlin.solvers.adr_step`'s ``polish``, with this call's Newton options):
        when the best ``‖r‖`` of the last ``adr_stall`` iterations is not below half the
        best before them, and when the budget runs out.  A converged try ends the
        increment at Newton's residual criterion ``rtol`` (``result.polishes`` counts
        its iterations, ``e1``/``e2`` are NaN); a failed one costs its Newton iterations
        and ADR goes on unchanged.  Default (None): on with ``method='auto'``, off with
        ``'adr'`` (ADR alone, spec 001's method).  ADR's damped dynamics can stall just
        above its criteria near an equilibrium Newton reaches in 2 iterations
        (docs/nonlinear.md: step 30 of the 10⁵-point run).
    adr_stall : int, optional
        The stall window of ``polish`` in ADR iterations (default: an eighth of the ADR
        budget, at least 500).
    homogenize : index array or mask, optional
        Points of the volume average (default all), e.g. the real points of a
        ghost-layer problem.
    keep_states : bool
        Keep the committed state of every step (else only the last); the checkpoint then
        keeps them too, so that a resumed run returns every step's state.
    checkpoint : path, optional
        NPZ file written atomically after every converged step (a failed write, e.g. on a
        full disk, raises :class:`~pdlin.errors.CheckpointWriteError` naming the file and
        keeps the previous checkpoint).  It carries a fingerprint of the problem: SHA-256
        digests of the points, the bonds (horizon, influence), the model and material
        parameters (orientations included), the homogenized points, each committed step's
        prescribed values and loads, and the solver options that change the iterates.
        Its folder must exist.
    resume : {False, True, 'branch'}
        True: continue an existing ``checkpoint`` from its last committed step; it must
        have been written for this problem with these solver options, and its step times
        must be the first ones of this run (a finished run can be extended with more
        steps).  'branch': the same, but the solver options may differ (another driver or
        tolerance from a committed state, e.g. a copy of the checkpoint).  Without a
        checkpoint file the run says so (``progress``) and starts from step 1.
    progress : callable, optional
        Called with one line per step, one per failed increment (why, and the time it
        is cut back to) and, during an increment, one line every ``progress_every``
        seconds (ADR: iteration, e₁, e₂, damping, residual; Newton: iteration, residual,
        step length); a Newton iteration's linear solve also reports its iterations and
        residual every ``pdlin._progress.PROGRESS_EVERY`` seconds.
    progress_every : float
        Seconds between the in-step progress lines (default 60; a 10⁵-particle plastic
        step runs ≈ 30,000 ADR iterations in ≈ 6 min, a failing Newton try there ≈ 1.5
        min).
    snapshot_every : float
        With ``checkpoint``: seconds between snapshots of a running ADR increment (its
        iterates, damping and histories; default 300, checked every 64 iterations; 0:
        every 64 iterations), one per increment the step tried, written atomically next
        to the checkpoint (``run.npz`` -> ``run.adr.npz``, ≈ 5 MB per increment at 10⁵
        points) and removed when the load step commits.  A resumed run that reaches the
        same increment again (same target time, start displacement, committed state and
        density) continues its ADR iteration from the snapshot, bit for bit as if
        uninterrupted (a whole step that failed fails again within a snapshot interval,
        the half it was cut back to goes on), instead of from its start: a killed
        10⁵-particle run loses at most ``snapshot_every`` seconds of a step that takes
        10-40 min.  The step's wall time adds the killed run's up to its last snapshot.

    Returns
    -------
    NonlinearResult

    Raises
    ------
    InputError
        An option is out of range (``method``, ``steps``, ``times``, ``rtol``, ``e_l``,
        ``density``, ``dt``, ``damping``, ``c0``, ``adr_maxiter``, ``checkpoint``, ...).
    CheckpointError
        ``resume``: the checkpoint is unreadable (truncated, not an NPZ file), was written
        by a pdlin without a fingerprint, or for another problem (the message names the
        parts that differ).
    CheckpointWriteError
        Writing the checkpoint or an ADR snapshot failed (an ``OSError``: a full disk, ...).
    ConvergenceError
        A step fails with the chosen method (with 'auto': Newton and ADR).

    Examples
    --------
    A bond-based bar pulled in 4 steps: from the last solution Newton
    converges in one iteration per step (the default tangent predictor would
    be exact here, a linear model), and ADR reaches the same solution.

    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((20,), spacing=0.05)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.1,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3)])
    >>> res = pdlin.solve_nonlinear(prob, steps=4, method="newton", predictor="previous")
    >>> res.iterations.tolist(), res.u.shape
    ([1, 1, 1, 1], (4, 20, 1))
    >>> adr = pdlin.solve_nonlinear(prob, steps=1, method="adr", e_l=1e-10)
    >>> bool(np.abs(adr.u[-1] - res.u[-1]).max() < 1e-9)
    True
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    for name, val, lo in (("rtol", rtol, 0.0), ("e_l", e_l, 0.0), ("floor", floor, 0.0)):
        if not (isinstance(val, int | float) and math.isfinite(val) and val > lo):
            raise InputError(f"{name} must be a positive number, got {val!r}")
    for name, ival in (
        ("maxiter", maxiter),
        ("max_cutbacks", max_cutbacks),
        ("fallback_cutbacks", fallback_cutbacks),
        ("relax", relax),
    ):
        if isinstance(ival, bool) or not isinstance(ival, int) or ival < 0:
            raise InputError(f"{name} must be an integer >= 0, got {ival!r}")
    for name, secs in (("progress_every", progress_every), ("snapshot_every", snapshot_every)):
        if (
            isinstance(secs, bool)
            or not (isinstance(secs, int | float) and math.isfinite(secs))
            or secs < 0
        ):
            raise InputError(f"{name} must be a finite number of seconds >= 0, got {secs!r}")
    for name, opt in (("damping", damping), ("c0", c0)):
        if opt is None and name == "damping":
            continue
        if not (isinstance(opt, int | float) and not isinstance(opt, bool)) or not (
            math.isfinite(opt) and opt >= 0
        ):
            raise InputError(f"{name} must be a finite number >= 0, got {opt!r}")
    if polish is not None and not isinstance(polish, bool):
        raise InputError(f"polish must be True, False or None, got {polish!r}")
    if adr_stall is not None and (
        isinstance(adr_stall, bool) or not isinstance(adr_stall, int) or adr_stall < 1
    ):
        raise InputError(f"adr_stall must be an integer >= 1 (ADR iterations), got {adr_stall!r}")
    if not isinstance(newton_backoff, bool):
        raise InputTypeError(f"newton_backoff must be True or False, got {newton_backoff!r}")
    if adr_maxiter is not None:
        adr_maxiter = integer(adr_maxiter, "adr_maxiter", minimum=1)
    if not any(resume is r or (isinstance(r, str) and resume == r) for r in _RESUME):
        raise InputError(f"resume must be True, False or 'branch', got {resume!r}")
    if resume and checkpoint is None:
        raise InputError("resume=True needs checkpoint= (the file to resume from), got None")
    if checkpoint is not None:
        if not isinstance(checkpoint, str | os.PathLike):
            raise InputTypeError(f"checkpoint must be a path, got {type(checkpoint).__name__}")
        parent = Path(checkpoint).parent
        if not parent.is_dir():
            raise InputError(
                f"checkpoint must be a path in an existing folder, got {os.fspath(checkpoint)!r} "
                f"(folder {str(parent)!r} does not exist)"
            )
    say = progress or (lambda msg: None)
    t_start = time.perf_counter()
    tt = _times(steps, t_end, times)
    te = 1.0 if t_end is None else float(t_end)
    system = constrained_system(problem)
    n, d = system.n, system.dim
    pred = _Predictor(system, predictor, linear_solver)
    state0 = system.initial_state()

    hom_w = np.asarray(system.cloud.volumes, dtype=float).copy()
    if homogenize is not None:
        idx = system.cloud.select(homogenize)
        mask = np.zeros(n, dtype=bool)
        mask[idx] = True
        hom_w[~mask] = 0.0
    if hom_w.sum() <= 0:
        raise InputError("homogenize selects no points with positive volume")

    lam: np.ndarray | None = None
    adr_dt = 1.0
    if method in ("adr", "auto"):
        if isinstance(density, str):
            if density != "gershgorin":
                raise InputError(
                    f"density must be 'gershgorin', a positive number or an array, got {density!r}"
                )
            adr_dt = 1.0 if dt is None else float(dt)
        else:
            dens = as_float_array(density, "density")
            if dens.ndim > 1 or dens.size not in (1, system.ndof):
                raise ShapeError(
                    f"density must be a scalar or have shape ({system.ndof},), got {dens.shape}"
                )
            if np.any(dens <= 0):
                raise InputError(f"density must be > 0, got min {float(dens.min())}")
            if dt is None:
                raise InputError("an explicit ADR density needs dt (e.g. h sqrt(Λ / E_max))")
            adr_dt = float(dt)
            arr = np.broadcast_to(dens.reshape(-1), (system.ndof,)).copy()
            lam = arr
    budget = int(adr_maxiter) if adr_maxiter is not None else 200 * math.ceil(n ** (1.0 / d)) + 2000
    polish_on = (method == "auto") if polish is None else polish
    stall_window = int(adr_stall) if adr_stall is not None else max(500, budget // 8)
    # the options that change a run's iterates (checked on resume): Newton's where Newton
    # runs (also as ADR's polish), ADR's where ADR runs; not progress, output, keep_states
    # or the number of threads (docs/nonlinear.md, "Checkpoints")
    solver_options: dict[str, Any] = {"method": method, "predictor": predictor}
    if method != "adr" or polish_on:
        solver_options.update(
            rtol=rtol,
            maxiter=maxiter,
            line_search=line_search,
            max_cutbacks=max_cutbacks,
            linear_solver=linear_solver,
            relax=relax,
        )
    if method == "auto":
        solver_options.update(fallback_cutbacks=fallback_cutbacks, newton_backoff=newton_backoff)
    if method != "newton":
        solver_options.update(
            max_cutbacks=max_cutbacks,
            e_l=e_l,
            density="gershgorin" if lam is None else lam,
            density_safety=density_safety if lam is None else None,
            dt=adr_dt,
            damping=damping,
            c0=c0,
            adr_maxiter=budget,
            floor=floor,
            polish=polish_on,
            adr_stall=stall_window if polish_on else None,
        )

    # per-step records
    K = tt.size
    u_hist = np.zeros((K, n, d))
    reac_hist = np.zeros((K, n, d))
    stress_hist: np.ndarray | None = None
    hom_hist: np.ndarray | None = None
    iters = np.zeros(K, dtype=np.int64)
    calls = np.zeros(K, dtype=np.int64)
    cuts = np.zeros(K, dtype=np.int64)
    relax_hist = np.zeros(K, dtype=np.int64)
    polish_hist = np.zeros(K, dtype=np.int64)
    e1s = np.full(K, np.nan)
    e2s = np.full(K, np.nan)
    resid = np.zeros(K)
    step_time = np.zeros(K)
    methods: list[str] = [""] * K
    load_digests: list[str] = [""] * K  # the checkpoint's fingerprint of each step's loads
    messages: list[str] = [""] * K
    damping_hist: list[np.ndarray] = [np.zeros(0)] * K
    states: list[dict[str, np.ndarray]] = []
    state_steps: list[int] = []

    u_c = np.zeros(system.ndof)
    state_c = dict(state0)
    t_c, u_p, t_p = 0.0, None, None
    start = 0
    # the automatic incrementation's memory (see substeps below), kept in the checkpoint
    inc_frac0 = {"newton": 1.0, "adr": 1.0}
    backoff0 = {"frac": 1.0, "until": -1, "hold": 0}
    ckpt = None if checkpoint is None else Path(checkpoint)
    fingerprint: dict[str, str] = {}
    if ckpt is not None:
        fingerprint = _fingerprint(system, hom_w, solver_options)
    if ckpt is not None and resume and not ckpt.exists():
        say(f"no checkpoint {ckpt} to resume: starting from step 1")
        log.info("no checkpoint %s to resume: starting from step 1", ckpt)
    if ckpt is not None and resume and ckpt.exists():
        data = _read_checkpoint(ckpt)
        _check_checkpoint(ckpt, data, system, tt, te, fingerprint, branch=resume == "branch")
        start = int(data["done"])
        load_digests[:start] = [str(v) for v in data["fp__loads"][:start]]
        u_hist[:start] = data["u"][:start]
        reac_hist[:start] = data["reactions"][:start]
        for arr, key in ((iters, "iterations"), (calls, "calls"), (cuts, "cutbacks")):
            arr[:start] = data[key][:start]
        if "relaxations" in data:  # absent from checkpoints of earlier versions
            relax_hist[:start] = data["relaxations"][:start]
        if "polishes" in data:  # idem
            polish_hist[:start] = data["polishes"][:start]
        # step wall times and Newton's failure messages of the steps the file holds (runs
        # that wrote none: times unknown, NaN)
        step_time[:start] = data["step_time"][:start] if "step_time" in data else np.nan
        if "messages" in data:
            messages[:start] = [str(m) for m in data["messages"][:start]]
        e1s[:start], e2s[:start] = data["e1"][:start], data["e2"][:start]
        resid[:start] = data["residuals"][:start]
        if "stress" in data:
            stress_hist = np.full((K, n, d, d), np.nan)
            stress_hist[:start] = data["stress"][:start]
            hom_hist = np.full((K, d, d), np.nan)
            hom_hist[:start] = data["homogenized_stress"][:start]
        meth = [str(m) for m in data["methods"]]
        methods[:start] = meth[:start]
        state_c = {k[len("state__") :]: data[k] for k in data if k.startswith("state__")}
        u_c = u_hist[start - 1].reshape(-1).copy() if start else u_c
        t_c = float(tt[start - 1]) if start else 0.0
        if start >= 2:
            u_p, t_p = u_hist[start - 2].reshape(-1).copy(), float(tt[start - 2])
        prev = {k[len("prev_state__") :]: data[k] for k in data if k.startswith("prev_state__")}
        pred.prev_state = prev or None  # absent from checkpoints of earlier versions
        if "increments" in data:  # idem: a resumed run continues the same increments
            inc_n, inc_a, b_frac, b_until, b_hold = (float(v) for v in data["increments"])
            inc_frac0 = {"newton": inc_n, "adr": inc_a}
            backoff0 = {"frac": b_frac, "until": int(b_until), "hold": int(b_hold)}
        history = {k[len("states__") :]: data[k] for k in data if k.startswith("states__")}
        if keep_states and history and all(v.shape[:1] == (start,) for v in history.values()):
            # the committed states of every step, as an uninterrupted run keeps them
            states = [{key: v[i] for key, v in history.items()} for i in range(start - 1)]
            states.append(dict(state_c))
            state_steps = list(range(start))
        else:
            states = [dict(state_c)] if start else []
            state_steps = [start - 1] if start else []
        say(f"resuming from {ckpt} after step {start} of {K}")
    snap_path = None if ckpt is None else ckpt.with_name(f"{ckpt.stem}.adr{ckpt.suffix}")
    # the running load step's ADR snapshots (snapshot_every), one per increment tried
    # (keyed by adr_key below), all in one file: a resumed run continues every increment
    # it tries again from its snapshot, a failed whole step (which then fails again
    # within a snapshot interval, bit for bit) as well as the half it was cut back to
    snaps: dict[str, dict[str, np.ndarray]] = {}
    saved: dict[str, dict[str, np.ndarray]] = {}  # the killed run's, each used once
    if snap_path is not None and resume and snap_path.exists():
        saved = _read_snapshots(snap_path, say)
    # the interrupted run's time in the running step up to its last snapshot (added to
    # the step's wall time) and the step's start (read by the snapshots)
    step_clock = {"t0": 0.0, "before": 0.0}
    timings: dict[str, Any] = {"setup": time.perf_counter() - t_start}

    def values(t: float) -> np.ndarray:
        return system.values_at(t, t / te)

    lam0: dict[str, np.ndarray] = {}
    # the sub-step state read by the predictor closures below
    t_cur: float = t_c
    u_prev: np.ndarray | None = u_p
    t_prev: float | None = t_p

    direct_cache: dict[str, Any] = {}  # the tangent's factorization, reused across steps

    def relax_density() -> np.ndarray | None:
        """Newton's relaxation density at stalls: at least the elastic tangent's bound."""
        if relax == 0:
            return None
        if "relax" not in lam0:
            lam0["relax"] = adr_density(system, state0, None, dt=1.0, safety=1.1)
        return lam0["relax"]

    def newton_to(t_new: float, u_from: np.ndarray, st: dict[str, np.ndarray]) -> StepOutcome:
        u0 = pred(u_from, st, t_cur, u_prev, t_prev, t_new, t_new / te, values(t_new))
        return newton_from(t_new, u0, st)

    def newton_from(t_new: float, u0: np.ndarray, st: dict[str, np.ndarray]) -> StepOutcome:
        """Newton from ``u0`` (a predictor, or an ADR iterate for ``polish``), whose
        prescribed entries are this increment's."""
        return newton_step(
            system,
            u0,
            st,
            factor=t_new / te,
            rtol=rtol,
            maxiter=maxiter,
            line_search=line_search,
            linear_solver=linear_solver,
            direct_cache=direct_cache,
            relax=relax,
            relax_density=relax_density(),
            progress=None if progress is None else (lambda m: say(f"  t = {t_new:g}: {m}")),
            progress_every=progress_every,
        )

    def adr_key(t_new: float, u0: np.ndarray, st: dict[str, np.ndarray], dens: Any) -> str:
        """A fingerprint of an ADR increment: its target time, start displacement,
        committed state and density, and the options that change its iterates (Δt, a
        constant damping, the budget): a snapshot continues only the same increment."""
        opts = (t_new, adr_dt, -1.0 if damping is None else float(damping), float(budget))
        h = hashlib.sha256(np.array(opts, dtype=float).tobytes())
        h.update(np.ascontiguousarray(u0, dtype=float).tobytes())
        h.update(np.ascontiguousarray(dens, dtype=float).tobytes())
        for key in sorted(st):
            h.update(key.encode())
            h.update(np.ascontiguousarray(st[key]).tobytes())
        return h.hexdigest()

    def adr_to(t_new: float, u_from: np.ndarray, st: dict[str, np.ndarray]) -> StepOutcome:
        u0 = pred(u_from, st, t_cur, u_prev, t_prev, t_new, t_new / te, values(t_new), "adr")
        if lam is not None:
            dens = lam
        else:
            # Gershgorin density of the tangent at the step's start (hardening raises it),
            # never below that of the initial, elastic tangent (softening or plastic
            # tangents would under-estimate the stiffness of elastic unloading)
            if "elastic" not in lam0:
                lam0["elastic"] = adr_density(
                    system, state0, None, dt=adr_dt, safety=density_safety
                )
            dens = np.maximum(
                lam0["elastic"], adr_density(system, st, u0, dt=adr_dt, safety=density_safety)
            )
        snapshot = restart = None
        if snap_path is not None:
            key = adr_key(t_new, u0, st, dens)
            restart = saved.pop(key, None)
            if restart is not None:
                snaps[key] = restart  # kept in the file until this run snapshots it anew
                step_clock["before"] = max(
                    step_clock["before"], float(restart.get("step_elapsed", 0.0))
                )
                say(
                    f"  t = {t_new:g}: ADR continues from its snapshot after iteration "
                    f"{int(restart['iteration']):,} ({snap_path})"
                )

            def snapshot(loop: dict[str, Any]) -> None:
                entry = {k: np.array(v) for k, v in loop.items()}  # copies: buffers rotate
                entry["step_elapsed"] = np.array(
                    step_clock["before"] + time.perf_counter() - step_clock["t0"]
                )
                snaps[key] = entry
                assert snap_path is not None
                _write_snapshots(snap_path, snaps)

        return adr_step(
            system,
            u0,
            st,
            factor=t_new / te,
            density=dens,
            dt=adr_dt,
            e_l=e_l,
            maxiter=budget,
            c0=c0,
            damping=damping,
            floor=floor,
            progress=None if progress is None else (lambda m: say(f"  t = {t_new:g}: {m}")),
            progress_every=progress_every,
            snapshot=snapshot,
            snapshot_every=float(snapshot_every),
            restart=restart,
            polish=(lambda u: newton_from(t_new, u, st)) if polish_on else None,
            stall=stall_window,
        )

    # automatic incrementation: the last converged increment of each driver, as a
    # fraction of its load step, starts the next step (grown after easy convergence)
    inc_frac = inc_frac0
    # ADR's backoff (any ADR increment is grown, so without it a size that fails would
    # be tried again at every step, each time for a whole iteration budget: ≈ 11 min per
    # load step at 10⁵ crystal-plasticity points): the held size `frac` (a fraction of
    # its load step; the last that failed) caps the increments at half of it until load
    # step `until`, which starts with that size again; `hold` load steps in between,
    # doubled when the retry fails; when it converges, the next larger size is held
    # (the same number of steps), up to the whole step, then the backoff ends
    backoff = backoff0

    def substeps(
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
        (u, state), from which a fallback driver continues."""
        nonlocal t_cur, u_prev, t_prev
        span = t_target - t_cur
        smallest = span / 2.0**cutbacks
        frac = min(1.0, inc_frac[driver])
        held = driver == "adr" and k < backoff["until"]
        if driver == "adr" and backoff["hold"] > 0:
            # below the failed size while it is held, that size again when the hold ends
            frac = min(frac, 0.5 * backoff["frac"]) if held else max(frac, backoff["frac"])
        inc = max(min(1.0, frac) * span, smallest)
        cur_u, cur_state = u_start, st_start
        cnt = _Counts()
        out: StepOutcome | None = None
        easy = max(2, maxiter // 4)
        while t_target - t_cur > 1e-12 * span:
            last = t_target - t_cur <= inc * (1.0 + 1e-9)
            target = t_target if last else t_cur + inc
            try:
                out = step_fn(target, cur_u, cur_state)
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
                if 0.5 * min(inc, t_target - t_cur) < smallest * (1.0 - 1e-9):
                    inc_frac[driver] = inc / span
                    return None, str(exc), cnt, (cur_u, cur_state)
                inc = 0.5 * min(inc, t_target - t_cur)
                log.info("t = %.6g: %s; cutting back to t = %.6g", target, exc, t_cur + inc)
                say(f"  t = {target:g}: {exc}; cutting back to t = {t_cur + inc:g}")
                continue
            cnt.add(out)
            if damp is not None and out.damping is not None:
                damp.append(out.damping)
            u_prev, t_prev = cur_u, t_cur
            pred.converged(cur_state)
            cur_u, cur_state, t_cur = out.u, out.response.state, target
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
        inc_frac[driver] = inc / span
        return out, "", cnt, (cur_u, cur_state)

    for k in range(start, K):
        with warnings.catch_warnings():
            # trial iterates may leave a material's state questionable (e.g. a crystal's
            # active set unsettled); only the committed state matters (checked below)
            warnings.simplefilter("ignore", TrialStateWarning)
            t0 = time.perf_counter()
            step_clock["t0"], step_clock["before"] = t0, 0.0
            t_target = float(tt[k])
            step_u, step_state = u_c, state_c
            cnt = _Counts()
            pred.calls = 0
            damp: list[np.ndarray] = []
            out: StepOutcome | None = None
            used = method
            why = ""
            # the sub-step loop shares these with the predictor closures
            t_cur, u_prev, t_prev = t_c, u_p, t_p
            if method in ("newton", "auto"):
                cut_n = max_cutbacks
                streak = 0  # load steps just before this one without Newton (failed or skipped)
                while (
                    method == "auto"
                    and streak < k
                    and methods[k - 1 - streak] in (_FELL_BACK, _SKIPPED)
                ):
                    streak += 1
                if streak:
                    # one halving fewer per further failed step, down to the whole step alone
                    cut_n = min(max_cutbacks, max(0, fallback_cutbacks - (streak - 1)))
                    inc_frac["newton"] = 1.0
                skip = (
                    newton_backoff
                    and streak > fallback_cutbacks + 1
                    and streak & (streak - 1) != 0  # not a power of two
                )
                if skip:
                    why = (
                        f"Newton skipped: no Newton in the last {streak} load steps "
                        "(newton_backoff: tried again when that count is a power of two)"
                    )
                else:
                    out, why, cnt, (step_u, step_state) = substeps(
                        newton_to, "newton", t_target, step_u, step_state, None, cut_n
                    )
                if skip:
                    used = _SKIPPED
                elif out is None:
                    if method == "newton":
                        raise ConvergenceError(
                            f"Newton failed at load step {k + 1} (t = {t_target:.6g}) after "
                            f"{cnt.cutbacks} cut-back(s): {why}"
                        )
                    # ADR continues from Newton's last converged increment
                    used = _FELL_BACK
                else:
                    used = "newton"
            if method == "adr" or out is None:
                out, adr_why, adr_cnt, _ = substeps(
                    adr_to, "adr", t_target, step_u, step_state, damp, max_cutbacks
                )
                cnt.merge(adr_cnt)
                if out is None:
                    if used == _SKIPPED:
                        prefix = f"{why}; "
                    else:
                        prefix = f"Newton failed ({why}); " if why else ""
                    raise ConvergenceError(
                        f"{prefix}ADR failed at load step {k + 1} (t = {t_target:.6g}) after "
                        f"{adr_cnt.cutbacks} cut-back(s): {adr_why}"
                    )
                e1s[k] = np.nan if out.e1 is None else out.e1
                e2s[k] = np.nan if out.e2 is None else out.e2
                if method == "adr":
                    used = "adr"
            assert out is not None
            resp = out.response
            u_new = out.u
            factor = t_target / te
            u_hist[k] = u_new.reshape(n, d)
            reac_hist[k] = system.reactions(u_new, factor=factor, f_int=resp.force)
            sig = resp.stress
            if sig is None:
                try:
                    sig = system.disc.stress(u_new.reshape(n, d))
                except Exception:  # noqa: BLE001 - models without a stress: record none
                    sig = None
            if sig is not None:
                if stress_hist is None:
                    stress_hist = np.full((K, n, d, d), np.nan)
                    hom_hist = np.full((K, d, d), np.nan)
                assert hom_hist is not None
                stress_hist[k] = sig
                hom_hist[k] = np.einsum("i,iab->ab", hom_w, sig) / hom_w.sum()
            iters[k], calls[k], cuts[k] = cnt.iterations, cnt.calls + pred.calls, cnt.cutbacks
            relax_hist[k], polish_hist[k] = cnt.relaxation, cnt.polish
            resid[k] = out.residual
            methods[k], messages[k] = used, why
            damping_hist[k] = np.concatenate(damp) if damp else np.zeros(0)
        _check_committed(u_new, resp.state, k, t_target)
        if ckpt is not None:
            load_digests[k] = _load_digest(system, t_target, te)
        # commit
        u_p, t_p = u_c, t_c
        u_c, state_c, t_c = u_new, dict(resp.state), t_target
        for category, message in system.model.committed_issues(state_c):
            warnings.warn(
                f"load step {k + 1} (t = {t_target:.6g}): {message}", category, stacklevel=2
            )
        if keep_states:
            states.append(state_c)
            state_steps.append(k)
        else:
            states = [state_c]
            state_steps = [k]
        # with the interrupted run's time in this step up to its last snapshot, if resumed
        step_time[k] = time.perf_counter() - t0 + step_clock["before"]
        if ckpt is not None:
            arrays: dict[str, np.ndarray] = {
                "version": np.array(_CHECKPOINT_VERSION),
                "shape": np.array([n, d]),
                "times": tt,
                "done": np.array(k + 1),
                "u": u_hist[: k + 1],
                "reactions": reac_hist[: k + 1],
                "iterations": iters[: k + 1],
                "calls": calls[: k + 1],
                "cutbacks": cuts[: k + 1],
                "relaxations": relax_hist[: k + 1],
                "polishes": polish_hist[: k + 1],
                "e1": e1s[: k + 1],
                "e2": e2s[: k + 1],
                "residuals": resid[: k + 1],
                "methods": np.array(methods[: k + 1]),
                "messages": np.array(messages[: k + 1]),
                "step_time": step_time[: k + 1],
                **{f"fp__{part}": np.array(value) for part, value in fingerprint.items()},
                "fp__loads": np.array(load_digests[: k + 1]),
                "increments": np.array(
                    [
                        inc_frac["newton"],
                        inc_frac["adr"],
                        backoff["frac"],
                        backoff["until"],
                        backoff["hold"],
                    ],
                    dtype=float,
                ),
            }
            if stress_hist is not None and hom_hist is not None:
                arrays["stress"] = stress_hist[: k + 1]
                arrays["homogenized_stress"] = hom_hist[: k + 1]
            for key, value in state_c.items():
                arrays[f"state__{key}"] = np.asarray(value)
            if keep_states and state_steps == list(range(k + 1)):
                # every committed state: a resumed run returns and writes them all
                for key in state_c:
                    arrays[f"states__{key}"] = np.stack([np.asarray(st[key]) for st in states])
            for key, value in (pred.prev_state or {}).items():
                arrays[f"prev_state__{key}"] = np.asarray(value)
            _write_atomic_npz(ckpt, arrays)
            snaps.clear()  # the step's increments are committed
            saved.clear()  # (a killed run's snapshots belong to this step or none)
            if snap_path is not None and snap_path.exists():
                snap_path.unlink()
        say(
            f"step {k + 1}/{K} t = {t_target:.6g}: {used}, {cnt.iterations} iteration(s), "
            f"{cnt.cutbacks} cut-back(s), "
            + (f"{cnt.relaxation} relaxation iteration(s), " if cnt.relaxation else "")
            + (f"{cnt.polish} Newton polish iteration(s), " if cnt.polish else "")
            + f"residual {out.residual:.2e}, {step_time[k]:.2f} s"
        )

    timings["steps"] = step_time
    timings["total"] = time.perf_counter() - t_start
    return NonlinearResult(
        problem=problem,
        system=system,
        times=tt,
        factors=tt / te,
        u=u_hist,
        stress=stress_hist,
        homogenized_stress=hom_hist,
        reactions=reac_hist,
        states=states,
        state_steps=state_steps,
        iterations=iters,
        calls=calls,
        cutbacks=cuts,
        relaxations=relax_hist,
        polishes=polish_hist,
        methods=methods,
        messages=messages,
        damping=damping_hist,
        e1=e1s,
        e2=e2s,
        residuals=resid,
        timings=timings,
        resumed_from=start,
    )
