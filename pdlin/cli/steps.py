"""``pdlin run`` on a deck with several load steps: one linear solve per step, one series."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from ..io.results import write_series
from ..static import solve


def run_load_steps(args: argparse.Namespace, scene: Any, prog: Any) -> int:
    """Solve every ``(time, problem)`` of ``scene.steps``; write them as one time series.

    Each step is an independent linear solve at that step's prescribed values (pdlin's
    deck models are linear; Peridigm's quasi-static solver would Newton-iterate each step
    from the last).  The series goes through :func:`pdlin.io.results.write_series`
    (``.vtu`` output becomes a ``.pvd`` collection with one ``.vtu`` per step).
    """
    solver = args.solver or scene.solver
    times: list[float] = []
    fields: list[dict[str, Any]] = []
    results = []
    for k, (t, problem) in enumerate(scene.steps):
        prog(f"load step {k + 1}/{len(scene.steps)} (t = {t:.6g})")
        res = solve(
            problem,
            solver=solver,
            rtol=scene.rtol,
            maxiter=scene.maxiter,
            direct_backend=scene.direct_backend,
        )
        f = res.fields()
        if scene.fields:
            f = {name: f[name] for name in scene.fields if name in f}
        times.append(float(t))
        fields.append(f)
        results.append(res)
    out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.pvd"))
    prog(f"writing {out}")
    series = write_series(out, scene.cloud, times, fields)
    summary = results[-1].summary()
    summary["scene"] = scene.name
    summary["steps"] = len(times)
    summary["times"] = times
    summary["max_relative_residual"] = max(float(r.relative_residual) for r in results)
    summary["output"] = str(series)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"scene        {scene.name}")
        print(f"points       {summary['points']:,} ({summary['dim']}D), bonds {summary['bonds']:,}")
        print(
            f"load steps   {len(times)} linear solve(s), t = {times[0]:.6g} .. {times[-1]:.6g}; "
            f"largest relative residual {summary['max_relative_residual']:.2e}"
        )
        print("max |u|      " + ", ".join(f"{v:.6e}" for v in summary["max_abs_u"]))
        print(f"results      {series} (time series)")
    return 0
