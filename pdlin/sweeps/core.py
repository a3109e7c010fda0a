"""The speed-versus-accuracy harness: sweep configurations, time them, measure their error.

:func:`tradeoff` runs :func:`pdlin.solve` on every combination of a parameter grid
(model / control, horizon ratio ``m``, spacing ``h``, influence function, solver,
tolerance, operator, symmetry reduction, ...), records the wall time of each stage, the
peak memory, nnz, iterations and the error against a reference, and writes each point
to a CSV or JSON-lines file as soon as it finishes (a killed sweep keeps its finished
points and ``resume=True`` skips them).  :class:`TradeoffResult` holds the table and
answers the questions a user has: the Pareto front of error against time, convergence
rates in ``h`` and ``δ``, and the fastest configuration that meets an error target.
"""

from __future__ import annotations

import csv
import itertools
import json
import logging
import math
import os
import time
import tracemalloc
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, InputTypeError
from ..io.output import write_error
from ..problem import StaticProblem
from ..static import solve

__all__ = [
    "TradeoffCase",
    "TradeoffResult",
    "tradeoff",
    "SOLVE_KEYS",
    "NONLINEAR_KEYS",
    "METRIC_COLUMNS",
    "interpolate_field",
    "point_key",
]

log = logging.getLogger(__name__)

#: sweep keys passed to :func:`pdlin.solve` instead of the problem factory
#: (for a nonlinear case: ``solver`` is the inner linear solver, ``rtol`` and ``maxiter``
#: Newton's, and ``method``, ``e_l``, ``predictor`` go to :func:`pdlin.solve_nonlinear`)
SOLVE_KEYS = ("solver", "rtol", "operator", "maxiter", "method", "e_l", "predictor")
#: the sweep keys that only a nonlinear case accepts
NONLINEAR_KEYS = ("method", "e_l", "predictor")

#: measured columns of every row, after the swept parameters
METRIC_COLUMNS = (
    "status",
    "error",
    "t_bonds",
    "t_assembly",
    "t_setup",
    "t_solve",
    "t_total",
    "t_wall",
    "peak_mb",
    "points",
    "dofs",
    "bonds",
    "nnz",
    "iterations",
    "residual",
    "h",
    "delta",
    "solver_used",
    "operator_used",
    "reference",
    "message",
)
_NUMERIC = set(METRIC_COLUMNS[METRIC_COLUMNS.index("error") : METRIC_COLUMNS.index("delta") + 1])


@dataclass
class TradeoffCase:
    """One configuration of a sweep, as built by a problem factory.

    Attributes
    ----------
    problem : StaticProblem
        The configured problem of this point.
    solve_kwargs : dict
        Extra keyword arguments of :func:`pdlin.solve` (the swept ``solver``, ``rtol``,
        ``operator``, ``maxiter`` override them).
    exact : callable, optional
        Closed-form displacement ``exact(X) -> (k, dim)`` at points ``X (k, dim)``.
    reference : callable or (n, dim) array, optional
        Another reference displacement on the problem's points (e.g. a finite-element
        solution interpolated at them); a callable is called with no argument.
    measure : (k,) array of int, optional
        Points where the error is measured (default all; e.g. the real, non-shadow points).
    h, delta : float, optional
        Grid spacing and horizon, reported in the table and used by
        :meth:`TradeoffResult.rates` (default: read from the problem).
    nonlinear : dict, optional
        Solve with :func:`pdlin.solve_nonlinear` and these keyword arguments instead of
        :func:`pdlin.solve`.  The error is then that of the homogenized (volume-averaged)
        stress history, never of the point-wise field (plastic equilibria of a nearly
        perfectly plastic crystal are not unique, so two solvers may legitimately end in
        different point-wise fields; see ``docs/tradeoff.md``): ``exact`` and
        ``reference`` give the reference history ``(steps, dim, dim)`` (``exact(times)``,
        or an array), e.g. the material-point driver of a homogeneous single crystal.
    """

    problem: StaticProblem
    solve_kwargs: dict[str, Any] = field(default_factory=dict)
    exact: Callable[[np.ndarray], np.ndarray] | None = None
    reference: Any = None
    measure: np.ndarray | None = None
    h: float | None = None
    delta: float | None = None
    nonlinear: dict[str, Any] | None = None


def _as_case(obj: Any) -> TradeoffCase:
    if isinstance(obj, TradeoffCase):
        return obj
    if isinstance(obj, StaticProblem):
        return TradeoffCase(obj)
    if isinstance(obj, tuple) and len(obj) in (2, 3) and isinstance(obj[0], StaticProblem):
        exact = obj[2] if len(obj) == 3 else None
        return TradeoffCase(obj[0], dict(obj[1] or {}), exact=exact)
    raise InputTypeError(
        "the factory must return a TradeoffCase, a StaticProblem or a tuple "
        f"(problem, solve_kwargs[, exact]), got {type(obj).__name__}"
    )


def _fmt(v: Any) -> str:
    """Canonical text of a parameter value (CSV cells and point keys)."""
    if isinstance(v, bool) or v is None:
        return str(v)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return str(v)


def point_key(params: Mapping[str, Any]) -> str:
    """Build the key of a sweep point: ``name=value`` pairs in the grid's order.

    Parameters
    ----------
    params : mapping str -> value
        The point's swept parameters, in the grid's order.

    Returns
    -------
    str
        ``name=value`` joined by ``;``, values in their canonical text (the key of
        ``resume`` and of the table's ``key`` column).

    Examples
    --------
    >>> point_key({"model": "bb", "m": 3, "h": 0.05})
    'model=bb;m=3;h=0.05'
    """
    return ";".join(f"{k}={_fmt(v)}" for k, v in params.items())


def _expand(grid: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    if not isinstance(grid, Mapping):
        raise InputTypeError(f"grid must be a mapping name -> list, got {type(grid).__name__}")
    if not grid:
        raise InputError(
            "grid must name at least one parameter to sweep ({name: [values, ...]}), got {}"
        )
    lists = {}
    for k, v in grid.items():
        vals = [v] if isinstance(v, (str, bytes)) or not isinstance(v, Iterable) else list(v)
        if not vals:
            raise InputError(f"grid[{k!r}] must list at least one value, got []")
        lists[k] = vals
    keys = list(lists)
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*lists.values())]


# --- error metrics ------------------------------------------------------------------------


def error_metric(
    name: str | Callable[..., float],
) -> Callable[[np.ndarray, np.ndarray], float]:
    """Return the error function of a metric name (or the callable itself).

    Parameters
    ----------
    name : {'rel-max', 'rel-l2', 'max-abs'} or callable
        'rel-max': largest point error over the largest reference norm; 'rel-l2': l2 norm
        of the error over that of the reference; 'max-abs': largest absolute component
        error. A callable ``f(u, ref) -> float`` is returned unchanged.

    Returns
    -------
    callable
        ``f(u, ref) -> float`` on ``(n, d)`` fields.

    Raises
    ------
    InputError
        ``name`` is neither a known metric nor callable.

    Examples
    --------
    >>> import numpy as np
    >>> error_metric("rel-max")(np.array([[1.0, 0.0]]), np.array([[2.0, 0.0]]))
    0.5
    """
    if callable(name):
        return name

    def rel_max(u: np.ndarray, r: np.ndarray) -> float:
        den = float(np.linalg.norm(r, axis=1).max())
        return float(np.linalg.norm(u - r, axis=1).max()) / (den if den > 0 else 1.0)

    def rel_l2(u: np.ndarray, r: np.ndarray) -> float:
        den = float(np.linalg.norm(r))
        return float(np.linalg.norm(u - r)) / (den if den > 0 else 1.0)

    def max_abs(u: np.ndarray, r: np.ndarray) -> float:
        return float(np.abs(u - r).max())

    table = {"rel-max": rel_max, "rel-l2": rel_l2, "max-abs": max_abs}
    if name not in table:
        raise InputError(f"metric must be one of {sorted(table)} or a callable, got {name!r}")
    return table[name]


def interpolate_field(points: np.ndarray, values: np.ndarray, xq: np.ndarray) -> np.ndarray:
    """Interpolate a point field to other points (the 'finest' reference on coarser runs).

    Identical clouds are copied; 1D uses :func:`numpy.interp`; grids (tensor-product
    point sets) use :class:`scipy.interpolate.RegularGridInterpolator` (linear, linearly
    extrapolated outside); scattered clouds use ``griddata`` (linear, nearest outside).

    Parameters
    ----------
    points : (n, d) array
        Positions of the known field.
    values : (n, k) array
        The field at ``points``.
    xq : (q, d) array
        Positions to interpolate at.

    Returns
    -------
    (q, k) array
        The interpolated field.

    Examples
    --------
    >>> x = np.linspace(0, 1, 11)[:, None]
    >>> interpolate_field(x, 2 * x, np.array([[0.25], [0.5]])).ravel().tolist()
    [0.5, 1.0]
    """
    points = np.asarray(points, dtype=float)
    values = np.asarray(values, dtype=float)
    xq = np.asarray(xq, dtype=float)
    if points.shape == xq.shape and np.allclose(points, xq, rtol=0, atol=1e-12):
        return values.copy()
    d = points.shape[1]
    if d == 1:
        o = np.argsort(points[:, 0])
        return np.column_stack(
            [np.interp(xq[:, 0], points[o, 0], values[o, k]) for k in range(values.shape[1])]
        )
    axes = [np.unique(np.round(points[:, k], 12)) for k in range(d)]
    if int(np.prod([a.size for a in axes])) == points.shape[0]:
        from scipy.interpolate import RegularGridInterpolator

        idx = tuple(np.searchsorted(a, np.round(points[:, k], 12)) for k, a in enumerate(axes))
        cube = np.empty(tuple(a.size for a in axes) + (values.shape[1],))
        cube[idx] = values
        f = RegularGridInterpolator(axes, cube, bounds_error=False, fill_value=None)
        return np.asarray(f(xq))
    from scipy.interpolate import griddata

    out = np.asarray(griddata(points, values, xq, method="linear"))
    bad = ~np.isfinite(out).all(axis=1)
    if bad.any():
        out[bad] = griddata(points, values, xq[bad], method="nearest")
    return out


# --- running one point --------------------------------------------------------------------


def _rss_kb(field_name: str) -> float:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field_name + ":"):
                    return float(line.split()[1])
    except OSError:
        pass
    import resource

    return float(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def _reset_peak_rss() -> float:
    """Reset the peak-RSS mark where Linux allows it; the current RSS in kB."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass
    return _rss_kb("VmRSS")


def _run_measured(run: Callable[[], Any], memory: str, t0: float) -> tuple[Any, float, float]:
    """``run()`` with its wall time since ``t0`` and peak memory (MB) per ``memory`` mode."""
    if memory == "tracemalloc":
        tracemalloc.start()
    rss0 = _reset_peak_rss() if memory == "rss" else 0.0
    peak = float("nan")
    try:
        res = run()
    finally:
        if memory == "tracemalloc":
            peak = tracemalloc.get_traced_memory()[1] / 2**20
            tracemalloc.stop()
    wall = time.perf_counter() - t0
    if memory == "rss":
        peak = max(_rss_kb("VmHWM") - rss0, 0.0) / 1024.0
    return res, wall, peak


def _solver_used(info: Mapping[str, Any]) -> str:
    """Name the solver that ran, with the direct backend in brackets (``'direct (cholmod)'``).

    ``direct_backend='auto'`` picks CHOLMOD or PARDISO when installed, so ``'direct'`` alone
    would hide which factorization a row timed.
    """
    name = str(info.get("solver"))
    backend = info.get("direct_backend")
    return f"{name} ({backend})" if backend else name


def _measure_point(
    factory: Callable[..., Any],
    params: dict[str, Any],
    memory: str,
) -> dict[str, Any]:
    """Build and solve one point; returns the raw measurements and the solution."""
    fparams = {k: v for k, v in params.items() if k not in SOLVE_KEYS}
    skw = {k: v for k, v in params.items() if k in SOLVE_KEYS}
    t0 = time.perf_counter()
    case = _as_case(factory(**fparams))
    if case.nonlinear is not None:
        return _measure_nonlinear(case, skw, memory, t0)
    extra = [k for k in skw if k in NONLINEAR_KEYS]
    if extra:
        raise InputError(
            f"sweep key {extra[0]!r} needs a nonlinear case (a scene with solver.nonlinear or "
            "a nonlinear material); this case is solved by pdlin.solve"
        )
    kw = {**case.solve_kwargs, **skw}
    res, wall, peak = _run_measured(lambda: solve(case.problem, **kw), memory, t0)
    cloud = case.problem.cloud
    d = cloud.dim
    system = res.system
    nnz = float("nan")
    if system is not None:
        try:
            nnz = float(system.estimate_nnz_blocks() * d * d)
        except Exception:  # pragma: no cover - a model without an estimate
            nnz = float("nan")
    h = case.h
    if h is None:
        h = float(np.median(cloud.spacing)) if cloud.n else float("nan")
    delta = case.delta
    if delta is None:
        delta = float(np.median(res.bonds.horizon)) if res.bonds.n_bonds else float("nan")
    ref = case.reference() if callable(case.reference) else case.reference
    t = res.timings
    return {
        "row": {
            "t_bonds": t.get("bonds", float("nan")),
            "t_assembly": t.get("assembly", float("nan")),
            "t_setup": t.get("setup", float("nan")),
            "t_solve": t.get("solve", float("nan")),
            "t_total": t.get("total", float("nan")),
            "t_wall": wall,
            "peak_mb": peak,
            "points": cloud.n,
            "dofs": cloud.n * d,
            "bonds": res.bonds.n_bonds,
            "nnz": nnz,
            "iterations": res.n_iter,
            "residual": res.relative_residual,
            "h": h,
            "delta": delta,
            "solver_used": _solver_used(res.info),
            "operator_used": str(res.info.get("operator")),
        },
        "points": np.asarray(cloud.points),
        "u": np.asarray(res.u),
        "exact": None if case.exact is None else np.asarray(case.exact(np.asarray(cloud.points))),
        "other": None if ref is None else np.asarray(ref, dtype=float),
        "measure": None if case.measure is None else np.asarray(case.measure),
    }


def _measure_nonlinear(
    case: TradeoffCase, skw: dict[str, Any], memory: str, t0: float
) -> dict[str, Any]:
    """:func:`_measure_point` of a nonlinear case: the homogenized stress history."""
    from ..nonlinear import solve_nonlinear

    kw = dict(case.nonlinear or {})
    for k in ("checkpoint", "resume", "progress"):
        kw.pop(k, None)  # sweep points neither checkpoint nor print
    if "operator" in skw:
        raise InputError("sweep key 'operator' applies to linear solves only")
    mapped = {("linear_solver" if k == "solver" else k): v for k, v in skw.items()}
    kw.update(mapped)
    res, wall, peak = _run_measured(lambda: solve_nonlinear(case.problem, **kw), memory, t0)
    if res.homogenized_stress is None:
        raise InputError("a nonlinear tradeoff case needs a model with a stress response")
    cloud = case.problem.cloud
    d = cloud.dim
    hom = np.asarray(res.homogenized_stress, dtype=float).reshape(res.n_steps, d * d)
    h = case.h if case.h is not None else float(np.median(cloud.spacing))
    bonds = res.system.disc.real_bonds
    delta = case.delta
    if delta is None:
        delta = float(np.median(bonds.horizon)) if bonds.n_bonds else float("nan")
    t = res.timings
    exact = None
    if case.exact is not None:
        exact = np.asarray(case.exact(np.asarray(res.times)), dtype=float).reshape(hom.shape)
    ref = case.reference() if callable(case.reference) else case.reference
    return {
        "row": {
            "t_bonds": float("nan"),
            "t_assembly": float("nan"),
            "t_setup": float(t.get("setup", float("nan"))),
            "t_solve": float(t.get("total", float("nan"))) - float(t.get("setup", 0.0)),
            "t_total": float(t.get("total", float("nan"))),
            "t_wall": wall,
            "peak_mb": peak,
            "points": cloud.n,
            "dofs": cloud.n * d,
            "bonds": bonds.n_bonds,
            "nnz": float("nan"),
            "iterations": int(np.sum(res.iterations)),
            "residual": float(np.max(res.residuals)) if res.n_steps else float("nan"),
            "h": h,
            "delta": delta,
            "solver_used": "+".join(sorted(set(res.methods))),
            "operator_used": "homogenized-stress",
        },
        # the compared "field": one row per load step (σ̄ flattened), so every metric and
        # the finest-run reference apply unchanged; points = (t, 0, ...) for the lookup
        "points": np.column_stack([res.times, np.zeros((res.n_steps, max(d - 1, 0)))]),
        "u": hom,
        "exact": exact,
        "other": None if ref is None else np.asarray(ref, dtype=float).reshape(hom.shape),
        "measure": None,
        "history": True,
    }


def _warm_imports() -> None:
    """Import the lazily imported solver modules once in the parent process.

    Forked points then do not each pay (and time) their import.
    """
    import importlib

    for name in ("pyamg", "scipy.sparse.linalg", "scipy.interpolate", "pdlin.models"):
        try:
            importlib.import_module(name)
        except ImportError:  # pragma: no cover - optional
            pass


def _run_isolated(
    factory: Callable[..., Any], params: dict[str, Any], timeout: float | None
) -> dict[str, Any]:
    """Run :func:`_measure_point` in a forked child (peak RSS per point, time limit)."""
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)

    def child() -> None:
        try:
            out: Any = ("ok", _measure_point(factory, params, "rss"))
        except BaseException as exc:  # noqa: BLE001 - everything is reported to the parent
            out = ("error", f"{type(exc).__name__}: {exc}")
        try:
            send.send(out)
        finally:
            send.close()

    proc = ctx.Process(target=child, daemon=True)
    proc.start()
    send.close()
    try:
        if not recv.poll(timeout):
            raise TimeoutError(f"point exceeded the time limit of {timeout} s")
        kind, payload = recv.recv()
    except EOFError:
        kind, payload = "error", f"worker died (exit code {proc.exitcode})"
    finally:
        if proc.is_alive() and proc.pid is not None:
            proc.kill()
        proc.join()
        recv.close()
    if kind == "error":
        raise _PointFailed(payload)
    return dict(payload)


class _PointFailed(RuntimeError):
    pass


# --- the table ----------------------------------------------------------------------------


def _parse_cell(col: str, text: str) -> Any:
    if col in _NUMERIC:
        try:
            return float(text) if text != "" else float("nan")
        except ValueError:
            return float("nan")
    return text


def _parse_param(text: str) -> Any:
    if text in ("True", "False"):
        return text == "True"
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


class _Writer:
    """Append rows to a CSV or JSON-lines file, flushed and fsynced per row."""

    def __init__(self, path: Path, columns: list[str], resume: bool) -> None:
        self.path = path
        self.columns = columns
        self.json = path.suffix.lower() in (".jsonl", ".json", ".ndjson")
        self.rows: list[dict[str, Any]] = []
        if resume and path.exists():
            self.rows = self._read()
        # rewrite the good rows (drops a torn last line left by a killed writer)
        tmp = path.with_name(path.name + ".tmp")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(tmp, "w", newline="") as f:
                if not self.json:
                    csv.writer(f).writerow(columns)
                for row in self.rows:
                    self._write(f, row)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise write_error(path, exc) from exc

    def _read(self) -> list[dict[str, Any]]:
        rows: list[dict[str, Any]] = []
        text = self.path.read_text()
        if self.json:
            for line in text.splitlines():
                try:
                    row = json.loads(line)
                except json.JSONDecodeError:
                    continue  # torn line of a killed sweep
                if isinstance(row, dict) and "key" in row:
                    rows.append(row)
            return rows
        lines = text.splitlines(keepends=True)
        if not lines:
            return rows
        header = next(csv.reader(lines[:1]))
        if header != self.columns:
            raise InputError(
                f"cannot resume {self.path}: its columns {header} differ from this sweep's "
                f"{self.columns} (use resume=False or another output)"
            )
        complete = lines if lines[-1].endswith("\n") else lines[:-1]
        for rec in csv.reader(complete[1:]):
            if len(rec) != len(header):
                continue
            rows.append(dict(zip(header, rec, strict=True)))
        return [_typed(r, self.columns) for r in rows]

    def _write(self, f: Any, row: Mapping[str, Any]) -> None:
        if self.json:
            f.write(json.dumps({c: _jsonable(row.get(c)) for c in self.columns}) + "\n")
        else:
            csv.writer(f).writerow([_cell(row.get(c)) for c in self.columns])

    def append(self, row: Mapping[str, Any]) -> None:
        try:
            with open(self.path, "a", newline="") as f:
                self._write(f, row)
                f.flush()
                os.fsync(f.fileno())
        except OSError as exc:  # a torn last row is dropped when the sweep resumes
            raise write_error(self.path, exc) from exc


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)


def _jsonable(v: Any) -> Any:
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if math.isfinite(f) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def _typed(row: Mapping[str, Any], columns: Sequence[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    metrics = set(METRIC_COLUMNS)
    for c in columns:
        v = row.get(c)
        if c in metrics:
            if c in _NUMERIC:
                out[c] = float("nan") if v is None or v == "" else float(v)
            else:
                out[c] = "" if v is None else str(v)
        elif c == "key":
            out[c] = str(v)
        else:
            out[c] = _parse_param(v) if isinstance(v, str) else v
    return out


@dataclass
class TradeoffResult:
    """Hold the table of a sweep and answer what to read from it.

    Attributes
    ----------
    table : list of dict
        One row per point: the swept parameters, then :data:`~pdlin.sweeps.METRIC_COLUMNS`.
    params : list of str
        The swept parameter names (grid keys), in order.
    reference : str
        How the errors were measured ('closed-form', 'fem', 'finest: ...', 'callable').
    time : str
        The column used as the cost in :meth:`pareto` and :meth:`best` ('t_total').

    Examples
    --------
    >>> rows = [{"model": "a", "error": 1e-2, "t_total": 1.0, "status": "ok"},
    ...         {"model": "b", "error": 1e-3, "t_total": 2.0, "status": "ok"},
    ...         {"model": "c", "error": 2e-2, "t_total": 3.0, "status": "ok"}]
    >>> res = TradeoffResult(rows, ["model"])
    >>> [r["model"] for r in res.pareto()]
    ['a', 'b']
    >>> res.best(5e-3)["model"]
    'b'
    """

    table: list[dict[str, Any]]
    params: list[str]
    reference: str = ""
    time: str = "t_total"

    def ok(self) -> list[dict[str, Any]]:
        """Return the rows that finished with a finite error and time.

        Returns
        -------
        list of dict
            Rows with status 'ok' (the 'reference' row of a 'finest' sweep excluded).
        """
        return [
            r
            for r in self.table
            if r.get("status", "ok") == "ok"
            and np.isfinite(float(r.get("error", np.nan)))
            and np.isfinite(float(r.get(self.time, np.nan)))
        ]

    def pareto(self) -> list[dict[str, Any]]:
        """Non-dominated rows of (time, error), fastest first.

        A row is dominated when another is at least as fast and at least as accurate,
        and strictly better in one of the two.

        Returns
        -------
        list of dict
            The non-dominated rows of :meth:`ok`, by increasing ``time`` column.
        """
        rows = self.ok()
        if not rows:
            return []
        t = np.array([float(r[self.time]) for r in rows])
        e = np.array([float(r["error"]) for r in rows])
        order = np.lexsort((e, t))  # by time, then error
        best_before = np.minimum.accumulate(np.r_[np.inf, e[order]])[:-1]
        keep = order[e[order] < best_before]
        return [rows[i] for i in keep]

    def best(self, target_error: float) -> dict[str, Any] | None:
        """Return the fastest row whose error is at most ``target_error``.

        Parameters
        ----------
        target_error : float
            Largest acceptable error, in the units of the sweep's metric (> 0).

        Returns
        -------
        dict or None
            The row of :meth:`ok` with the smallest ``time`` column among those meeting
            the target; ``None`` if no row does.

        Raises
        ------
        InputError
            When ``target_error`` is not positive.
        """
        if not target_error > 0:
            raise InputError(f"target_error must be > 0, got {target_error}")
        ok = [r for r in self.ok() if float(r["error"]) <= target_error]
        return min(ok, key=lambda r: float(r[self.time])) if ok else None

    def rates(
        self, x: str = "h", *, vary: str | None = None, roundoff: float = 1e-10
    ) -> list[dict[str, Any]]:
        """Convergence rates: log-log least-squares slopes of the error against ``x``.

        Parameters
        ----------
        x : str
            Abscissa column: 'h', 'delta' or any numeric swept parameter.
        vary : str, optional
            The swept parameter that changes along one line (default ``x`` if it is
            swept; for 'h' else 'N'; for 'delta' else 'm', 'h', 'N').  Rows are
            grouped by every other swept parameter; groups with fewer than two
            distinct ``x`` are skipped.
        roundoff : float
            Groups whose errors are all below it (exact up to round-off) have no rate.

        Returns
        -------
        list of dict
            Per group: its fixed parameters, ``rate`` (slope of log error against
            log x), ``n`` points, ``x`` and ``error`` lists.

        Raises
        ------
        InputError
            When ``vary`` is not one of the swept parameters (or none can be inferred).
        """
        if vary is None:
            cands = [x] + (["N", "n"] if x == "h" else ["m", "h", "N", "n"] if x == "delta" else [])
            vary = next((c for c in cands if c in self.params), None)
        if vary not in self.params:
            raise InputError(
                f"vary must be one of the swept parameters {self.params}, got {vary!r}"
            )
        fixed = [p for p in self.params if p != vary]
        groups: dict[tuple[str, ...], list[dict[str, Any]]] = {}
        for r in self.ok():
            if float(r["error"]) <= 0:
                continue
            groups.setdefault(tuple(_fmt(r[p]) for p in fixed), []).append(r)
        out = []
        for gk, rows in groups.items():
            xs = np.array([float(r[x]) for r in rows])
            es = np.array([float(r["error"]) for r in rows])
            if np.unique(xs).size < 2 or not (xs > 0).all() or es.max() < roundoff:
                continue
            slope = float(np.polyfit(np.log(xs), np.log(es), 1)[0])
            o = np.argsort(xs)
            out.append(
                {
                    **dict(zip(fixed, (rows[0][p] for p in fixed), strict=True)),
                    "rate": slope,
                    "n": int(xs.size),
                    "x": xs[o].tolist(),
                    "error": es[o].tolist(),
                }
            )
            del gk
        return out

    def columns(self) -> list[str]:
        """Return the column names of the table.

        Returns
        -------
        list of str
            ``'key'``, the swept parameters, then :data:`METRIC_COLUMNS` not swept.
        """
        return ["key", *self.params, *[c for c in METRIC_COLUMNS if c not in self.params]]

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the table as CSV.

        Parameters
        ----------
        path : str or path-like
            File to write (overwritten); one header row of :meth:`columns`, one row per
            point.

        Returns
        -------
        pathlib.Path
            The path written.
        """
        p = Path(path)
        with open(p, "w", newline="") as f:
            w = csv.writer(f)
            cols = self.columns()
            w.writerow(cols)
            for r in self.table:
                w.writerow([_cell(r.get(c)) for c in cols])
        return p

    def to_json(self, path: str | os.PathLike[str] | None = None) -> str:
        """Serialize the table and the Pareto keys as JSON.

        Parameters
        ----------
        path : str or path-like, optional
            Also write the text to this file.

        Returns
        -------
        str
            JSON object with ``params``, ``reference``, ``time``, ``table`` (one object
            per row, NaN as null) and ``pareto`` (keys of the front).
        """
        data = {
            "params": self.params,
            "reference": self.reference,
            "time": self.time,
            "table": [{c: _jsonable(r.get(c)) for c in self.columns()} for r in self.table],
            "pareto": [r.get("key") for r in self.pareto()],
        }
        text = json.dumps(data, indent=1)
        if path is not None:
            Path(path).write_text(text)
        return text

    def summary(self, *, target_error: float | None = None, width: int = 10) -> str:
        """Format the rows (Pareto rows marked ``*``), the rates and the best choice.

        Parameters
        ----------
        target_error : float, optional
            Also name the fastest configuration meeting this error (:meth:`best`).
        width : int
            Width of each column, characters (longer cells are cut).

        Returns
        -------
        str
            Multi-line text: the reference, one line per row, the direct backends that
            ran, the rates in ``h`` and ``delta``, and the choice.
        """
        front = {id(r) for r in self.pareto()}
        cols = self.params + ["error", "t_total", "t_solve", "peak_mb", "nnz", "iterations"]
        head = "  " + " ".join(f"{c[:width]:>{width}}" for c in cols) + "  status"
        lines = [f"reference: {self.reference}", head]
        for r in self.table:
            cells = []
            for c in cols:
                v = r.get(c)
                if isinstance(v, float):
                    s = f"{v:.3g}" if np.isfinite(v) else "-"
                else:
                    s = str(v)
                cells.append(f"{s[:width]:>{width}}")
            mark = "*" if id(r) in front else " "
            lines.append(f"{mark} " + " ".join(cells) + f"  {r.get('status', '')}")
        used = sorted(
            {str(r["solver_used"]) for r in self.table if "(" in str(r.get("solver_used") or "")}
        )
        if used:  # the factorization a direct row timed: 'auto' depends on what is installed
            lines.append(f"direct solves ran: {', '.join(used)}")
        for x in ("h", "delta"):
            try:
                rates = self.rates(x)
            except InputError:
                continue
            for g in rates:
                fixed = ", ".join(f"{k}={g[k]}" for k in g if k not in ("rate", "n", "x", "error"))
                lines.append(f"rate in {x}: {g['rate']:.2f} ({g['n']} points; {fixed})")
        if target_error is not None:
            b = self.best(target_error)
            if b is None:
                lines.append(f"no configuration meets error <= {target_error:g}")
            else:
                lines.append(
                    f"fastest with error <= {target_error:g}: {b.get('key')} "
                    f"(error {float(b['error']):.3g}, {float(b[self.time]):.3g} s)"
                )
        return "\n".join(lines)

    def plot(self, path: str | os.PathLike[str] | None = None) -> Any:
        """Error against time (Pareto front drawn) and error against δ/h per model.

        Needs matplotlib (the ``plotting`` extra); drawn by :func:`pdlin.plotting.plot_tradeoff`.

        Parameters
        ----------
        path : str or path-like, optional
            Save the figure there (atomically, 120 dpi).

        Returns
        -------
        matplotlib Figure
            The figure (also saved to ``path`` when given).
        """
        from ..plotting import plot_tradeoff

        return plot_tradeoff(self, path)


# --- the sweep ----------------------------------------------------------------------------


def _finest_index(points: list[dict[str, Any]], finest: Mapping[str, Any] | None) -> int:
    if finest is not None:
        for k, p in enumerate(points):
            if all(_fmt(p.get(a)) == _fmt(v) for a, v in finest.items()):
                return k
        raise InputError(f"finest={dict(finest)} matches no point of the grid")

    def score(p: Mapping[str, Any]) -> tuple[float, float, float, float, int, int]:
        h = float(p["h"]) if "h" in p else 0.0
        m = -float(p["m"]) if "m" in p else 0.0
        rtol = float(p["rtol"]) if "rtol" in p else 0.0
        e_l = float(p["e_l"]) if "e_l" in p else 0.0
        direct = 0 if p.get("solver", "direct") == "direct" else 1
        newton = 0 if p.get("method", "newton") == "newton" else 1
        return (h, m, rtol, e_l, direct, newton)

    return min(range(len(points)), key=lambda k: score(points[k]))


def _check_some_succeeded(
    table: list[dict[str, Any]], first: tuple[str, BaseException] | None
) -> None:
    """Raise when no point of the sweep gave a measured result (all failed or timed out).

    Failed points are rows of the table only while others succeed; a sweep of failures
    raises :class:`~pdlin.errors.InputError` with the first failure's message, chained to
    its exception (points resumed from ``output`` give their recorded message).
    """
    if any(r.get("status") in ("ok", "reference") for r in table):
        return
    if first is not None:
        key, exc = first
        msg = str(exc) if isinstance(exc, _PointFailed) else f"{type(exc).__name__}: {exc}"
    else:
        row = table[0]
        key, msg = str(row["key"]), f"{row.get('status')}: {row.get('message')}"
    raise InputError(
        f"every point of the sweep failed ({len(table)} of {len(table)}, none measured); "
        f"first failure, point {key}: {msg}"
    ) from (first[1] if first is not None else None)


def _check_sweep_arguments(
    params: Sequence[str],
    reference: Any,
    memory: str,
    timeout: float | None,
) -> str:
    """Validate the arguments of :func:`tradeoff` and resolve ``memory='auto'``.

    Parameters
    ----------
    params : sequence of str
        Names of the swept parameters; none may clash with a measured column.
    reference : str or callable
        ``'auto'``, ``'closed-form'``, ``'fem'``, ``'finest'`` or a callable.
    memory : str
        ``'auto'``, ``'rss'``, ``'tracemalloc'`` or ``'none'``.
    timeout : float or None
        Seconds per point; allowed only with ``memory='rss'``.

    Returns
    -------
    str
        The memory mode: ``'auto'`` becomes ``'rss'`` where :func:`os.fork` exists,
        else ``'tracemalloc'``.

    Raises
    ------
    InputError
        When a parameter name clashes with a table column, or ``memory``, ``timeout``
        or ``reference`` is not one of the accepted values.
    """
    bad = [p for p in params if (p in METRIC_COLUMNS and p not in ("h", "delta")) or p == "key"]
    if bad:
        raise InputError(f"grid key {bad[0]!r} clashes with a table column; rename it")
    if memory == "auto":
        memory = "rss" if hasattr(os, "fork") else "tracemalloc"
    if memory not in ("rss", "tracemalloc", "none"):
        raise InputError(f"memory must be 'auto', 'rss', 'tracemalloc' or 'none', got {memory!r}")
    if timeout is not None and memory != "rss":
        raise InputError("timeout needs memory='rss' (points run in a child process)")
    if not (callable(reference) or reference in ("auto", "closed-form", "fem", "finest")):
        raise InputError(
            "reference must be 'auto', 'closed-form', 'fem', 'finest' or a callable, "
            f"got {reference!r}"
        )
    return memory


@dataclass
class _FinestReference:
    """The sweep's 'finest' point: its key, its side file and its solution once measured."""

    key: str
    side: Path | None
    sol: dict[str, Any] | None = None

    @property
    def label(self) -> str:
        """Text of the ``reference`` column of rows measured against this point."""
        return "finest: " + self.key

    def store(self, X: np.ndarray, u: np.ndarray) -> None:
        """Keep the finest solution (points ``X`` and displacements ``u``), also on disk."""
        self.sol = {"points": X, "u": u}
        if self.side is not None:
            np.savez(self.side, key=self.key, points=X, u=u)

    def get(self) -> dict[str, Any] | None:
        """Return the finest solution, from memory or from the side file of a resumed sweep."""
        if self.sol is None and self.side is not None and self.side.exists():
            with np.load(self.side) as z:
                if str(z["key"]) == self.key:
                    self.sol = {"points": z["points"], "u": z["u"]}
        return self.sol


def _run_point(
    run: Callable[[dict[str, Any]], dict[str, Any]], p: dict[str, Any], key: str
) -> tuple[dict[str, Any], dict[str, Any] | None, BaseException | None]:
    """Measure one point; a failure or time-out becomes the row's status, not an exception.

    Returns the row (parameters, blank metrics, then the measured ones), the raw
    measurement (``None`` when the point failed) and the failure (or ``None``).
    """
    row: dict[str, Any] = {"key": key, **p}
    row.update({c: (float("nan") if c in _NUMERIC else "") for c in METRIC_COLUMNS if c not in p})
    try:
        meas = run(p)
    except TimeoutError as exc:
        row.update(status="timeout", message=str(exc))
        return row, None, exc
    except Exception as exc:  # noqa: BLE001 - a failing point is a row, not a crash
        log.warning("point %s failed: %s", key, exc)
        row.update(status="failed", message=str(exc)[:300])
        return row, None, exc
    row.update({c: v for c, v in meas["row"].items() if c not in p})
    row["status"] = "ok"
    return row, meas, None


def _reference_mode(ref_mode: str, meas: Mapping[str, Any]) -> str:
    """Resolve ``'auto'``: closed form, else the case's reference field, else the finest."""
    if ref_mode != "auto":
        return ref_mode
    if meas["exact"] is not None:
        return "closed-form"
    return "fem" if meas["other"] is not None else "finest"


def _record_error(
    row: dict[str, Any],
    meas: Mapping[str, Any],
    p: Mapping[str, Any],
    ref_mode: str,
    reference: Any,
    err_fn: Callable[[np.ndarray, np.ndarray], float],
    fine: _FinestReference,
    *,
    is_finest: bool,
) -> BaseException | None:
    """Fill the ``error`` and ``reference`` columns of a measured row.

    The finest point of a 'finest' sweep is stored and becomes the ``'reference'`` row
    (error 0).  A point whose reference is missing gets status ``'no-reference'``; the
    exception is returned (``None`` when the error was measured).
    """
    X, u = meas["points"], meas["u"]
    sel = meas["measure"] if meas["measure"] is not None else np.arange(X.shape[0])
    mode = _reference_mode(ref_mode, meas)
    if len(sel) == 0 and not is_finest:
        mode = "none"
    if is_finest and mode == "finest":
        fine.store(X, u)
        # the reference itself: error 0 by definition, left out of fronts and rates
        row.update(status="reference", error=0.0, reference=fine.label)
        return None
    try:
        if mode == "none":
            raise InputError("no points to measure the error on (measure is empty)")
        if mode == "closed-form":
            if meas["exact"] is None:
                raise InputError("reference='closed-form' but the case has no exact")
            uref = meas["exact"][sel]
            row["reference"] = "closed-form"
        elif mode == "fem":
            if meas["other"] is None:
                raise InputError("reference='fem' but the case has no reference field")
            uref = meas["other"][sel]
            row["reference"] = "fem"
        elif mode == "finest":
            uref = _finest_field(fine, meas, X[sel], u, sel)
            row["reference"] = fine.label
        else:
            assert callable(reference)
            uref = np.asarray(reference(X[sel]), dtype=float).reshape(len(sel), -1)
            row["reference"] = "callable"
        row["error"] = float(err_fn(u[sel], uref))
    except Exception as exc:  # noqa: BLE001 - recorded on the row
        row.update(status="no-reference", message=str(exc)[:300])
        return exc
    return None


def _finest_field(
    fine: _FinestReference,
    meas: Mapping[str, Any],
    Xs: np.ndarray,
    u: np.ndarray,
    sel: np.ndarray,
) -> np.ndarray:
    """Return the finest solution at the measured points ``Xs`` (or its stress history)."""
    sol = fine.get()
    if sol is None:
        raise InputError(f"the finest point ({fine.label}) did not finish")
    if meas.get("history"):
        if sol["u"].shape != u.shape:
            raise InputError(
                "the finest run has another number of load steps or "
                "dimension; sweep points must share the load path"
            )
        return np.asarray(sol["u"][sel])
    return interpolate_field(sol["points"], sol["u"], Xs)


def tradeoff(
    factory: Callable[..., Any],
    grid: Mapping[str, Sequence[Any]],
    *,
    reference: str | Callable[[np.ndarray], np.ndarray] = "auto",
    metric: str | Callable[[np.ndarray, np.ndarray], float] = "rel-max",
    output: str | os.PathLike[str] | None = None,
    resume: bool = True,
    progress: Callable[[int, int, dict[str, Any]], None] | None = None,
    target_error: float | None = None,
    memory: str = "auto",
    timeout: float | None = None,
    finest: Mapping[str, Any] | None = None,
) -> TradeoffResult:
    """Sweep configurations of a problem; measure time per stage, memory and error.

    Parameters
    ----------
    factory : callable
        ``factory(**params) -> TradeoffCase`` (or ``(problem, solve_kwargs[, exact])``
        or a :class:`~pdlin.StaticProblem`), called with the grid's parameters other than
        :data:`~pdlin.sweeps.SOLVE_KEYS` ('solver', 'rtol', 'operator', 'maxiter'; and for a
        nonlinear case 'method', 'e_l', 'predictor'), which go to :func:`pdlin.solve` (or to
        :func:`pdlin.solve_nonlinear` for a case with ``nonlinear`` options, whose error is
        that of the homogenized stress history).  :mod:`pdlin.sweeps` has factories for the
        bundled problems (:func:`~pdlin.sweeps.graded_bar`, :func:`~pdlin.sweeps.tension_bar`,
        ...).
    grid : mapping str -> list
        Values of each swept parameter; every combination is one point.
    reference : {'auto', 'closed-form', 'fem', 'finest'} or callable
        What the error is measured against: the case's closed form (``case.exact``), its
        other reference (``case.reference``, e.g. a Q4/Hex8 solution), the finest point
        of the sweep (smallest ``h``, then largest ``m``, smallest ``rtol`` and ``e_l``,
        direct solver, Newton; or the point given by ``finest``; a Richardson-style
        estimate, reported as such, whose own error is 0), or ``reference(X) -> (k, dim)``.
        'auto' takes the first of closed form, case reference and finest that the cases
        provide.
    metric : {'rel-max', 'rel-l2', 'max-abs'} or callable
        Error of the measured points: max point-wise ``|u - u_ref|`` / ``max |u_ref|``, relative
        Euclidean norm, max absolute component error, or ``metric(u, u_ref) -> float``.
    output : path, optional
        ``.csv`` or ``.jsonl`` file; each point is appended (flushed, fsynced) as soon as
        it finishes.
    resume : bool
        Keep the rows already in ``output`` and skip their points (matched by their
        parameters); a torn last line of a killed sweep is dropped.
    progress : callable, optional
        ``progress(done, total, row)`` after each point (after it is written).
    target_error : float, optional
        Report the fastest configuration measured to meet it (:meth:`TradeoffResult.best`).
    memory : {'auto', 'rss', 'tracemalloc', 'none'}
        Peak memory per point: 'rss' runs each point in a forked child and reports its
        peak resident-set growth (also enables ``timeout``); 'tracemalloc' traces Python
        and numpy allocations in-process (not SuperLU's); 'auto' is 'rss' where fork
        exists.
    timeout : float, optional
        Seconds per point ('rss' mode); a point over the limit is recorded as 'timeout'.
    finest : mapping, optional
        Parameters of the point used as the 'finest' reference.

    Returns
    -------
    TradeoffResult
        A failed or timed-out point is a row (``status`` 'failed' / 'timeout' /
        'no-reference' with its ``message``) while other points succeed.

    Raises
    ------
    InputTypeError
        When ``factory`` is not callable or ``grid`` is not a mapping.
    InputError
        When ``grid`` is empty or lists no value for a key, or every point of the sweep
        failed (the first failure's message, chained to its exception).

    Examples
    --------
    >>> from pdlin.sweeps import graded_bar
    >>> res = tradeoff(graded_bar, {"control": ["higher_order"], "N": [100, 200]},
    ...                memory="none")
    >>> [r["status"] for r in res.table]
    ['ok', 'ok']
    >>> round(res.rates("h")[0]["rate"], 1)   # error ∝ h^(1/2): the √(x - ½) singularity
    0.5
    """
    if not callable(factory):
        raise InputTypeError(
            "factory must be callable, factory(**params) -> TradeoffCase / StaticProblem, "
            f"got {type(factory).__name__} {factory!r}"
        )
    points = _expand(grid)
    params = list(grid)
    memory = _check_sweep_arguments(params, reference, memory, timeout)
    if memory == "rss":
        _warm_imports()
    err_fn = error_metric(metric)
    columns = ["key", *params, *[c for c in METRIC_COLUMNS if c not in params]]
    writer = _Writer(Path(output), columns, resume) if output is not None else None
    done = {str(r["key"]): r for r in (writer.rows if writer else [])}

    def run(p: dict[str, Any]) -> dict[str, Any]:
        if memory == "rss":
            return _run_isolated(factory, p, timeout)
        return _measure_point(factory, p, memory)

    # the 'finest' reference runs first (kept in a side file next to the output)
    ref_mode = reference if isinstance(reference, str) else "callable"
    k_fine = _finest_index(points, finest)
    order = list(range(len(points)))
    if ref_mode in ("finest", "auto"):
        order.remove(k_fine)
        order.insert(0, k_fine)
    fine = _FinestReference(
        point_key(points[k_fine]), None if output is None else Path(str(output) + ".finest.npz")
    )

    rows: list[dict[str, Any]] = [r for r in done.values()]
    first_failure: tuple[str, BaseException] | None = None
    total = len(points)
    n_done = sum(1 for p in points if point_key(p) in done)
    for k in order:
        p = points[k]
        key = point_key(p)
        if key in done:
            continue
        row, meas, failure = _run_point(run, p, key)
        if meas is not None:
            failure = _record_error(
                row, meas, p, ref_mode, reference, err_fn, fine, is_finest=k == k_fine
            )
        if failure is not None:
            first_failure = first_failure or (key, failure)
        if writer is not None:
            writer.append(row)
        rows.append(row)
        n_done += 1
        if progress is not None:
            progress(n_done, total, row)
    by_key = {str(r["key"]): r for r in rows}
    table = [by_key[point_key(p)] for p in points if point_key(p) in by_key]
    _check_some_succeeded(table, first_failure)
    refs = sorted({str(r.get("reference")) for r in table if r.get("reference")})
    result = TradeoffResult(table, params, reference=", ".join(refs) or ref_mode)
    if target_error is not None:
        b = result.best(target_error)
        log.info("fastest configuration with error <= %g: %s", target_error, b and b["key"])
    return result
