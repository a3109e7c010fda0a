"""Load steps of a Peridigm deck: independent solves against one shared system (issue 34).

A Peridigm quasi-static compression deck (``PdQuickGrid`` box of nx x ny x nz cells, h = 1,
``Elastic`` LPS with horizon 3.015 h, the x- face held, the x+ face pushed by
``-1e-3 * t / T``, ``Number of Load Steps: N``, so N + 1 steps with the initial state) is
read once; its ``scene.steps`` are solved

* before: one ``pdlin.solve`` per step, as ``pdlin run`` did (bonds, K or the matrix-free
  operator, elimination, factorization / AMG set-up every step);
* after: ``pdlin.static.solve_steps`` (all of that once; per step rhs, solve, residual
  check, reactions).

Both in the same process, the same run, each solver in turn (``auto`` is what the deck runs:
matrix-free AMG-CG for 3D LPS); the displacements are checked bitwise equal.  Columns are
wall seconds with CPU seconds beside them.

Usage: ``python benchmarks/bench_load_steps.py`` (24 x 12 x 12 cells, 10 load steps, ``auto``:
~1.5 min, peak RSS ~2 GB), ``--cells 12 6 6 --solvers auto,direct`` (~20 s).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, timed  # noqa: E402

import pdlin  # noqa: E402
from pdlin.static import solve_steps  # noqa: E402


def _ids(mask: np.ndarray) -> str:
    """Peridigm's 1-based node ids of a mask, space separated."""
    return " ".join(str(i + 1) for i in np.flatnonzero(mask))


def write_deck(folder: Path, cells: tuple[int, int, int], steps: int) -> Path:
    """Write the compression deck (YAML) for a box of ``cells`` cells of size 1."""
    nx, ny, nz = cells
    i = np.arange(nx * ny * nz)
    ix = i % nx
    bc = {
        "Min X": _ids(ix == 0),
        "Max X": _ids(ix == nx - 1),
    }
    sets = "\n".join(f'    {k} Node Set: "{v}"' for k, v in bc.items())
    fixed = "\n".join(
        f"""    Held {c}:
      Type: "Prescribed Displacement"
      Node Set: "Min X Node Set"
      Coordinate: "{c}"
      Value: "0.0\""""
        for c in "xyz"
    )
    text = f"""Peridigm:
  Discretization:
    Type: "PdQuickGrid"
    NeighborhoodType: "Spherical"
    TensorProduct3DMeshGenerator:
      Type: "PdQuickGrid"
      X Origin: 0.0
      Y Origin: 0.0
      Z Origin: 0.0
      X Length: {float(nx)}
      Y Length: {float(ny)}
      Z Length: {float(nz)}
      Number Points X: {nx}
      Number Points Y: {ny}
      Number Points Z: {nz}
  Materials:
    Steel:
      Material Model: "Elastic"
      Bulk Modulus: 130.0e+9
      Shear Modulus: 78.0e+9
  Blocks:
    All:
      Block Names: "block_1"
      Material: "Steel"
      Horizon: 3.015
  Boundary Conditions:
{sets}
{fixed}
    Pushed:
      Type: "Prescribed Displacement"
      Node Set: "Max X Node Set"
      Coordinate: "x"
      Value: "-1.0e-3*t/1.0"
  Solver:
    Initial Time: 0.0
    Final Time: 1.0
    QuasiStatic:
      Number of Load Steps: {steps}
  Output:
    Output Filename: "compression"
"""
    deck = folder / "compression.yaml"
    deck.write_text(text)
    return deck


def main() -> None:
    """Print the table: steps, points, solver, before and after, speed-up."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, nargs=3, default=(24, 12, 12))
    ap.add_argument("--steps", type=int, default=10, help="Number of Load Steps")
    ap.add_argument("--solvers", default="auto", help="comma-separated solvers")
    args = ap.parse_args()
    header()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        scene = pdlin.read_deck(write_deck(Path(tmp), tuple(args.cells), args.steps))
    probs = [p for _, p in scene.steps]
    solvers = args.solvers.split(",")
    pdlin.solve(probs[-1], solver=solvers[0])  # compile the kernels outside the timings
    print(
        "| steps | points | solver | operator | before: independent solves | "
        "after: solve_steps | speed-up | bitwise equal |"
    )
    print("|---:|---:|---|---|---:|---:|---:|---|")
    for solver in solvers:
        with timed() as before:
            ind = [pdlin.solve(p, solver=solver) for p in probs]
        with timed() as after:
            shared = solve_steps(probs, solver=solver)
        same = all(np.array_equal(a.u, b.u) for a, b in zip(ind, shared, strict=True))
        print(
            f"| {len(probs)} | {scene.cloud.n:,} | {solver} ({shared[-1].info['solver']}) | "
            f"{shared[-1].info['operator']} | {before.wall:.2f} s ({before.cpu:.2f} s CPU) | "
            f"{after.wall:.2f} s ({after.cpu:.2f} s CPU) | {before.wall / after.wall:.1f}x | "
            f"{same} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
