"""``pdlin run`` on an explicit-dynamics scene (``[solver] kind = "explicit"``)."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from ..errors import PdlinError

__all__ = ["run_explicit"]


def run_explicit(args: argparse.Namespace, scene: Any, prog: Any) -> int:
    """Integrate the scene in time and write its frames as one time series.

    Parameters
    ----------
    args : argparse.Namespace
        ``output``, ``resume``, ``json`` of ``pdlin run``.
    scene : Scene
        A scene with ``explicit`` options.
    prog : callable
        Progress lines.

    Returns
    -------
    int
        The exit status (5 when a check failed under ``--strict``, else 0).

    Raises
    ------
    PdlinError
        ``--resume`` without ``solver.checkpoint``, or an output that is no time series.
    """
    from ..dynamics import solve_explicit
    from ..io.output import check_output
    from ..io.results import SERIES_SUFFIXES
    from .main import _check_status, _checks, _print_checks

    opts = dict(scene.explicit)
    if args.resume:
        if "checkpoint" not in opts:
            raise PdlinError("--resume needs solver.checkpoint in the explicit scene")
        opts["resume"] = True
    out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.pvd"))
    what = "-o/--output" if args.output else "output.path"
    check_output(out, SERIES_SUFFIXES, f"{what} (an explicit run's time series)")
    result = solve_explicit(scene.problem, progress=prog, **opts)
    prog(f"writing {out}")
    t_write = time.perf_counter()
    path = result.write(out)
    t_write = time.perf_counter() - t_write
    summary = result.summary()
    summary["timings"]["write"] = round(t_write, 4)
    summary["scene"] = scene.name
    summary["output"] = str(path)
    checks = _checks(scene, result, summary, prog)
    if args.json:
        print(json.dumps(summary, indent=2))
        return _check_status(args, checks)
    est = summary["dt_estimate"]
    print(f"scene        {scene.name}")
    print(
        f"time steps   {summary['steps']:,} of dt = {summary['dt']:.6g} to t = "
        f"{summary['t_end']:.6g}"
        + ("" if est is None else f" (stable estimate {est:.6g}, {summary['estimate_method']})")
    )
    if summary["max_damage"] is not None:
        print(
            f"damage       {summary['broken_bonds']:,} broken bonds, max damage "
            f"{summary['max_damage']:.4f}"
        )
    print(f"energy       largest change of the balance {summary['energy_drift']:.3e} (relative)")
    t = summary["timings"]
    print(
        f"timings      setup {t['setup']:.2f} s, steps {t['steps']:.2f} s, write {t['write']:.2f} s"
    )
    print(f"results      {path} ({result.times.size} frames)")
    _print_checks(checks)
    return _check_status(args, checks)
