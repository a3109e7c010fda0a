"""Time and memory of a 3D FCC polycrystal in shear (crystal-plasticity correspondence, 10⁴ points).

An n³ grid (spacing 1/n of a unit cube, mm) with ``pdlin.voronoi_polycrystal`` grains (seeded,
uniformly random orientations), ``CrystalPlasticity("fcc")`` (12 {111}<110> systems; pdlin's
default OFHC-copper-like constants, docs/crystal_plasticity.md), ``Correspondence`` at δ = h,
one ghost layer (``pdlin.geometry.ghost_layer``) and the boundary ring and the ghosts prescribed
by the pure-shear path ``u = (exp(L t) − I) X``, ``L = η (e_x⊗e_y + e_y⊗e_x)``.
This is pdlin's own case: the papers pdlin follows run 3D polycrystals with hcp WE43 data
(Javaheri et al. 2022, Sec. III.D) that are not published; 3D FCC shear is not in them.

One row per method: points, grains, DOFs, load steps, iterations (total, largest per step),
cut-backs and ADR fallbacks, wall and CPU seconds of ``solve_nonlinear`` (bonds, setup and all
steps), peak RSS of the run (each run in a forked child, so the rows do not share a peak) and the
final homogenized σ_xy.  Nothing is asserted.

Usage::

    python benchmarks/bench_cp3d.py                           # 22³ = 10,648 points, newton
    python benchmarks/bench_cp3d.py --n 22 --steps 10 --methods newton auto adr
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import resource
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import pdlin

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _context import header  # noqa: E402


def problem(n: int, grains: int, eta: float) -> pdlin.StaticProblem:
    """The n³ FCC polycrystal with one ghost layer, prescribed by the pure-shear path."""
    base = pdlin.grid((n, n, n), spacing=1.0 / n)
    _, rot = pdlin.voronoi_polycrystal(base, grains, seed=1)
    g = pdlin.geometry.ghost_layer(base, layers=1)
    material = pdlin.CrystalPlasticity("fcc", orientation=rot[g.source])
    model = pdlin.Correspondence(material=material)
    bonds = pdlin.find_bonds(g.cloud, ratio=1.0)
    L = np.zeros((3, 3))
    L[0, 1] = L[1, 0] = eta
    fixed = np.union1d(g.cloud.point_set("boundary"), g.ghost)
    bc = pdlin.Dirichlet.velocity_gradient(fixed, L)
    return pdlin.StaticProblem(model, g.cloud, bonds, dirichlet=[bc])


def run(n: int, grains: int, eta: float, steps: int, method: str) -> dict[str, Any]:
    """One solve_nonlinear run; wall / CPU seconds, iterations, peak RSS (this process)."""
    t0, c0 = time.perf_counter(), time.process_time()
    prob = problem(n, grains, eta)
    try:
        res = pdlin.solve_nonlinear(
            prob,
            times=np.arange(1.0, steps + 1.0),
            t_end=float(steps),
            method=method,
            keep_states=False,
        )
    except pdlin.errors.ConvergenceError as exc:
        return {"failed": str(exc)[:160]}
    hom = res.homogenized_stress
    assert hom is not None
    return {
        "points": prob.cloud.n,
        "real": n**3,
        "dofs": prob.cloud.n * 3,
        "iterations": int(res.iterations.sum()),
        "max_it": int(res.iterations.max()),
        "cutbacks": int(res.cutbacks.sum()),
        "fallbacks": sum("failed" in m or "skipped" in m for m in res.methods),
        "wall": time.perf_counter() - t0,
        "cpu": time.process_time() - c0,
        "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "sxy": float(hom[-1][0, 1]),
    }


def _child(conn: Any, *args: Any) -> None:
    conn.send(run(*args))
    conn.close()


def forked(*args: Any) -> dict[str, Any]:
    """:func:`run` in a forked child (its own peak RSS)."""
    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_child, args=(child, *args))
    p.start()
    out = parent.recv()
    p.join()
    return dict(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=22, help="points per side (default 22: 10,648)")
    ap.add_argument("--grains", type=int, default=20)
    ap.add_argument("--eta", type=float, default=1e-4, help="shear strain rate per step")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--methods", nargs="+", default=["newton"])
    ap.add_argument("--threads", type=int, default=2, help="pdlin threads (default 2)")
    args = ap.parse_args()
    pdlin.set_num_threads(args.threads)
    header()
    print(
        f"# FCC polycrystal, {args.n}³ real points + 1 ghost layer, {args.grains} grains, pure "
        f"shear η = {args.eta:g} per step, {args.steps} steps, {args.threads} pdlin thread(s)"
    )
    print(
        "| real points | points (with ghosts) | DOFs | grains | steps | method | iterations "
        "(max/step) | cut-backs | fallbacks | wall s | CPU s | peak RSS MB | σ_xy last (MPa) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for method in args.methods:
        r = forked(args.n, args.grains, args.eta, args.steps, method)
        if "failed" in r:
            print(f"| {args.n**3:,} | | | {args.grains} | {args.steps} | {method} | failed: "
                  f"{r['failed']} | | | | | | |", flush=True)  # fmt: skip
            continue
        print(
            f"| {r['real']:,} | {r['points']:,} | {r['dofs']:,} | {args.grains} | {args.steps} | "
            f"{method} | {r['iterations']} ({r['max_it']}) | {r['cutbacks']} | {r['fallbacks']} | "
            f"{r['wall']:.1f} | {r['cpu']:.1f} | {r['rss']:.0f} | {r['sxy']:.2f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
