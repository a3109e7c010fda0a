"""``pdlin run`` on a Peridigm deck solved with its own finite kinematics (load steps)."""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import AccuracyWarning, ConvergenceError


def run_finite_steps(args: argparse.Namespace, scene: Any, prog: Any) -> int:
    """Solve a deck's load steps with :func:`pdlin.solve_nonlinear`; write them as the linear path.

    The deck reader sets ``scene.nonlinear`` (Newton, the deck's step times) and
    ``scene.steps`` (every time, the initial one included) for Peridigm's ``Elastic`` /
    ``Elastic Plastic`` materials with finite kinematics.  Every step is written as
    ``pdlin run`` writes a linear deck's steps: with two or more load steps one time
    series from the initial time (u = 0, Peridigm's initial state) on, with one load step
    one file with the state at ``Final Time``.  Fields: ``displacement``, ``reaction`` and,
    with plasticity, the plastic multiplier ``state_lambda`` (Peridigm's ``Lambda``).

    If Newton fails on an elastic deck that ``--kinematics auto`` (the default) sent down
    this path, the deck is solved linearized instead and a warning says so; with plasticity
    or an explicit ``--kinematics finite`` the failure is the error.

    Parameters
    ----------
    args : argparse.Namespace
        The ``pdlin run`` arguments (output, solver, ``--json``, ``--kinematics``).
    scene : Scene
        A deck scene with ``nonlinear`` and ``steps``.
    prog : callable
        Progress printer.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..io.results import write_points, write_series
    from ..nonlinear import solve_nonlinear
    from .main import _size, _with_write, _write_progress

    opts = dict(scene.nonlinear)
    if args.solver:
        opts["linear_solver"] = args.solver
    times = [float(t) for t, _ in scene.steps]
    prog(
        f"{len(times) - 1} load step(s), t = {times[0]:.6g} .. {times[-1]:.6g}: "
        "Peridigm's finite kinematics (Newton)"
    )
    try:
        result = solve_nonlinear(scene.problem, progress=prog, **opts)
    except ConvergenceError as exc:
        plastic = bool(np.isfinite(getattr(scene.problem.model, "yield_stress", np.inf)).any())
        if plastic or getattr(args, "kinematics", None) == "finite":
            raise
        from ..scene.decks import read_deck
        from .steps import run_load_steps

        msg = f"finite kinematics did not converge ({exc}); solving the linearization instead"
        warnings.warn(msg, AccuracyWarning, stacklevel=2)
        linear = read_deck(args.scene, kinematics="linear")
        if linear.steps:
            return run_load_steps(args, linear, prog)
        raise
    out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.pvd"))
    n, dim = scene.cloud.n, scene.cloud.dim
    fields = []
    for k in range(result.n_steps):
        f = {"displacement": result.u[k], "reaction": result.reactions[k]}
        state = result.state_at(k)
        if state is not None and "lambda" in state:
            f["state_lambda"] = np.asarray(state["lambda"], float)
        if result.stress is not None:  # Elastic Correspondence: Cauchy stress
            f["stress"] = result.stress[k].reshape(n, -1)
        fields.append(f)
    prog(f"writing {out}")
    t_write = time.perf_counter()
    with _write_progress(out, prog):
        if len(times) > 2:
            first = {k: np.zeros_like(v) for k, v in fields[0].items()}  # u = 0 at t0
            written = write_series(out, scene.cloud, times, [first, *fields])
        else:
            written = write_points(out, scene.cloud, fields[-1], time=scene.time)
    t_write = time.perf_counter() - t_write
    prog(f"wrote {_size(Path(written))} in {t_write:.1f} s")
    summary = _with_write(result.summary(), t_write)
    summary.update(
        scene=scene.name,
        kinematics="finite",
        points=n,
        dim=dim,
        times=times,
        steps=len(times) if len(times) > 2 else 1,  # states written, as the linear path
        max_abs_u=np.abs(result.u[-1]).max(axis=0).tolist(),
        output=str(written),
    )
    if args.json:
        print(json.dumps(summary, indent=2, default=str))
    else:
        print(f"scene        {scene.name}")
        print(f"points       {n:,} ({dim}D), Peridigm's finite kinematics")
        print(
            f"load steps   {summary['steps']} (Newton): {summary['iterations']} iteration(s), "
            f"{summary['cutbacks']} cut-back(s), t = {times[0]:.6g} .. {times[-1]:.6g}"
        )
        print("max |u|      " + ", ".join(f"{v:.6e}" for v in summary["max_abs_u"]))
        print(f"results      {written}")
    return 0
