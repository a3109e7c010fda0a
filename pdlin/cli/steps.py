"""``pdlin run`` on a deck with several load steps: one shared system, one series."""

from __future__ import annotations

import argparse
import json
import time
from functools import partial
from pathlib import Path
from typing import Any

from .._progress import Throttle
from ..io.results import write_series
from ..static import solve_steps


def run_load_steps(args: argparse.Namespace, scene: Any, prog: Any) -> int:
    """Solve every ``(time, problem)`` of ``scene.steps``; write them as one time series.

    Each step is a linear solve at that step's prescribed values (pdlin's deck models are
    linear; Peridigm's quasi-static solver would Newton-iterate each step from the last).
    The steps share the bonds, K and its factorization or AMG hierarchy
    (``pdlin.static.solve_steps``); each checks its own residual.  The series goes
    through :func:`pdlin.io.results.write_series` (``.vtu`` output becomes a ``.pvd``
    collection with one ``.vtu`` per step).  Progress is reported per step and for the
    write; the summary's ``timings`` add up the steps' stages and include the write.

    Parameters
    ----------
    args : argparse.Namespace
        The ``pdlin run`` arguments (output, solver, ``--json``).
    scene : Scene
        A scene with ``steps``.
    prog : callable
        Progress printer.

    Returns
    -------
    int
        The exit code (0).
    """
    from .main import _size, _timings_line, _with_write, _write_progress

    solver = args.solver or scene.solver
    times = [float(t) for t, _ in scene.steps]
    n = len(times)
    prog(f"{n} load steps, t = {times[0]:.6g} .. {times[-1]:.6g}: one system for all")
    t0 = time.perf_counter()
    results = solve_steps(
        [problem for _, problem in scene.steps],
        solver=solver,
        rtol=scene.rtol,
        maxiter=scene.maxiter,
        direct_backend=scene.direct_backend,
        progress=prog,
    )
    t_solve = time.perf_counter() - t0
    out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.pvd"))
    prog(f"writing {out} ({n} steps: fields, then the files)")
    t_write = time.perf_counter()
    tick = Throttle(prog)
    fields: list[dict[str, Any]] = []
    for k, res in enumerate(results):
        tick(partial("  fields of step {}/{} (t = {:.6g})".format, k + 1, n, times[k]))
        f = res.fields()
        if scene.fields:
            f = {name: f[name] for name in scene.fields if name in f}
        fields.append(f)
    with _write_progress(out, prog):
        series = write_series(out, scene.cloud, times, fields)
    t_write = time.perf_counter() - t_write
    prog(f"wrote {_size(Path(series))} in {t_write:.1f} s")
    summary = results[-1].summary()
    summary["timings"] = _step_timings(results, t_solve)
    summary = _with_write(summary, t_write)
    summary["scene"] = scene.name
    summary["steps"] = n
    summary["times"] = times
    summary["max_relative_residual"] = max(float(r.relative_residual) for r in results)
    summary["shared_system"] = any(r.info.get("shared_system", False) for r in results)
    summary["output"] = str(series)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"scene        {scene.name}")
        print(f"points       {summary['points']:,} ({summary['dim']}D), bonds {summary['bonds']:,}")
        how = "one shared system" if summary["shared_system"] else "independent solves"
        print(
            f"load steps   {n} linear solve(s) ({how}), t = {times[0]:.6g} .. {times[-1]:.6g}; "
            f"largest relative residual {summary['max_relative_residual']:.2e}"
        )
        print("max |u|      " + ", ".join(f"{v:.6e}" for v in summary["max_abs_u"]))
        print(_timings_line(summary))
        print(f"results      {series} (time series)")
    return 0


#: the order of the stages in the summary's ``timings``
_STAGES = ("bonds", "assembly", "rhs", "setup", "solve")


def _step_timings(results: list[Any], t_solve: float) -> dict[str, float]:
    """Sum the stages' seconds over the steps; ``total`` is the wall time of all solves."""
    keys = {k for r in results for k in r.timings if k != "total"}
    order = [k for k in _STAGES if k in keys] + sorted(keys - set(_STAGES))
    tim = {k: round(sum(float(r.timings.get(k, 0.0)) for r in results), 4) for k in order}
    tim["total"] = round(t_solve, 4)
    return tim
