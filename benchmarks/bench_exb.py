"""The 2D polycrystal of Javaheri, Luo, Lakshmanan & Sundararaghavan (2022), Sec. III.B, at 50².

The gallery scene ``cp_higher_order`` (pdlin/examples/cp_higher_order.toml: its comments state
what is reconstructed: pdlin's seeded 21-grain map, planar double slip with the paper's
hardening) on the paper's 50 × 50 particles instead of the scene's 24 × 24: 1 × 1 mm, plane
strain, y-compression ``L = 0.002 diag(1, -1)`` per step, 30 steps, the paper's higher-order
weights (``control='higher_order'``, their Table 2) at δ = m h and their inward layer of depth
δ (Sec. II.D) plus m ghost rings following the same path.  The paper's Figs. 13-14 are maps
without numbers: each row prints what docs/crystal_plasticity.md ("Seed cases") tabulates at
24²: Newton iterations over the 30 steps, CPU and wall seconds of ``solve_nonlinear`` (bonds,
setup and steps) and the peak RSS of the row (each row in a forked child), the
homogenized σ_yy (all grid points, ghosts excluded: the scene's check quantity) and the mean
σ_yy over the points outside the layer at every δ ≤ 3h (grid indices 3 .. N - 4) at steps 10
and 30, and the displacement roughness ``|u_i - mean of its four neighbours| / h`` at step 30
(median and max over the real points whose four neighbours are real and outside the layer: a
smooth field gives O(h × strain gradient), a zero-energy mode the order of the strain).
Nothing is asserted.

Rows: ``h``, ``ho2``, ``ho3`` (δ = h, 2h, 3h with the higher-order weights), ``none2``,
``none3`` (no control, ``ω = 1/|ξ|``).

Usage::

    python benchmarks/bench_exb.py                        # 50², rows ho2 ho3
    python benchmarks/bench_exb.py --rows h ho2 ho3 none2 none3
    python benchmarks/bench_exb.py --n 24 --rows h ho2    # the gallery scene's grid
"""

from __future__ import annotations

import argparse
import copy
import resource
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import pdlin
from pdlin.scene.scene import builtin_scene, scene_from_dict

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _context import fork_call, header  # noqa: E402

#: row -> (δ/h, control)
ROWS = {"h": (1, "higher_order"), "ho2": (2, "higher_order"), "ho3": (3, "higher_order"),
        "none2": (2, "none"), "none3": (3, "none")}  # fmt: skip
LABEL = {"h": "δ = h", "ho2": "HO 2h", "ho3": "HO 3h", "none2": "no control (ω = 1/|ξ|) 2h",
         "none3": "no control 3h"}  # fmt: skip
L = 0.002 * np.diag([1.0, -1.0])  # Javaheri et al. (2022), Sec. III.B: y-compression per step


def scene(n: int, m: int, control: str) -> Any:
    """The gallery scene on an n × n grid at δ = m h with the layer of depth m h."""
    data = copy.deepcopy(builtin_scene("cp_higher_order")[0])
    h = 1.0 / n
    data["geometry"]["shape"] = [n, n]
    data["geometry"]["spacing"] = h
    data["geometry"]["ghost_layers"] = m
    data["horizon"]["ratio"] = float(m)
    data["model"]["control"] = control
    data["horizon"]["influence"] = "inverse" if control == "none" else "constant"
    w, inf = m * h, float("inf")
    boxes = [
        [[-inf, -inf], [w, inf]],
        [[1.0 - w, -inf], [inf, inf]],
        [[-inf, -inf], [inf, w]],
        [[-inf, 1.0 - w], [inf, inf]],
    ]
    data["dirichlet"] = [
        {"box": b, "velocity_gradient": L.tolist(), "center": [0.0, 0.0]} for b in boxes
    ]
    data.pop("check", None)
    return scene_from_dict(data)


def measures(res: Any, points: np.ndarray, n: int, m: int) -> dict[str, float]:
    """σ_yy (homogenized and inner mean) at steps 10 / 30 and the roughness at step 30."""
    h = 1.0 / n
    ij = np.rint(points / h - 0.5).astype(int)
    real = np.all((ij >= 0) & (ij < n), axis=1)
    grid = np.full((n, n, 2), np.nan)
    grid[ij[real, 0], ij[real, 1]] = res.u[-1][real]
    avg = 0.25 * (grid[2:, 1:-1] + grid[:-2, 1:-1] + grid[1:-1, 2:] + grid[1:-1, :-2])
    hf = np.linalg.norm(grid[1:-1, 1:-1] - avg, axis=2) / h
    lo, hi = m, n - 2 - m  # points m + 1 .. n - m - 2: all four neighbours real, outside the layer
    inner = np.all((ij >= 3) & (ij < n - 3), axis=1)
    syy = res.stress[:, inner, 1, 1].mean(axis=1)
    hom = res.homogenized_stress[:, 1, 1]
    return {
        "hom10": float(hom[9]),
        "hom30": float(hom[29]),
        "in10": float(syy[9]),
        "in30": float(syy[29]),
        "rough_med": float(np.median(hf[lo:hi, lo:hi])),
        "rough_max": float(np.max(hf[lo:hi, lo:hi])),
    }


def run(row: str, n: int) -> dict[str, Any]:
    """One 30-step run of a row; iterations, CPU / wall seconds, peak RSS, the measures."""
    m, control = ROWS[row]
    t0, c0 = time.perf_counter(), time.process_time()
    sc = scene(n, m, control)
    try:
        # the scene's options, as ``pdlin run``: 30 steps to t = 30, method 'auto', the
        # homogenized stress over the real points (ghosts excluded)
        res = pdlin.solve_nonlinear(sc.problem, **sc.nonlinear)
    except pdlin.errors.ConvergenceError as exc:
        return {"failed": str(exc)[:160]}
    out = {
        "points": sc.cloud.n,
        "dofs": 2 * sc.cloud.n,
        "iterations": int(res.iterations.sum()),
        "cutbacks": int(res.cutbacks.sum()),
        "fallbacks": sum("failed" in s or "skipped" in s for s in res.methods),
        "cpu": time.process_time() - c0,
        "wall": time.perf_counter() - t0,
        "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }
    out.update(measures(res, sc.cloud.points, n, m))
    return out


def forked(*args: Any) -> dict[str, Any]:
    """:func:`run` in a forked child (its own peak RSS); a failure as ``{"failed": ...}``."""
    out = fork_call(run, *args)
    return {"failed": out} if isinstance(out, str) else dict(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50, help="particles per side (the paper: 50)")
    ap.add_argument("--rows", nargs="+", default=["ho2", "ho3"], choices=list(ROWS))
    ap.add_argument("--threads", type=int, default=2, help="pdlin threads (default 2)")
    args = ap.parse_args()
    pdlin.set_num_threads(args.threads)
    header()
    print(
        f"# Javaheri et al. (2022) Sec. III.B polycrystal, {args.n} x {args.n}, 30 steps of "
        f"y-compression, solve_nonlinear(**scene.nonlinear), {args.threads} pdlin thread(s)"
    )
    print(
        "| weights | points (with ghosts) | Newton iterations | cut-backs / fallbacks | CPU s "
        "| wall s | peak RSS MB | homogenized σ_yy, step 10 / 30 (MPa) | mean σ_yy outside "
        "the layer, step 10 / 30 (MPa) | roughness, median (max) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in args.rows:
        r = forked(row, args.n)
        if "failed" in r:
            print(f"| {LABEL[row]} | failed: {r['failed']} | | | | | | | | |", flush=True)
            continue
        print(
            f"| {LABEL[row]} | {r['points']:,} | {r['iterations']} | {r['cutbacks']} / "
            f"{r['fallbacks']} | {r['cpu']:.0f} | {r['wall']:.0f} | {r['rss']:.0f} | "
            f"{r['hom10']:.3f} / {r['hom30']:.3f} | {r['in10']:.3f} / {r['in30']:.3f} | "
            f"{r['rough_med']:.2e} ({r['rough_max']:.2e}) |",
            flush=True,
        )


if __name__ == "__main__":
    main()
