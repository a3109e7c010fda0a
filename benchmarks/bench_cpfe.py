"""CPPD against CPFE, 21-grain polycrystal (Luo, Ramazani & Sundararaghavan 2017, Figs. 5, 8, 14).

The polycrystal of ``bench_nonlinear.problem`` (n x n particles of a 1 x 1 mm square, δ = h,
21 seeded Voronoi grains, planar-2 crystal plasticity, the boundary ring on the
velocity-gradient path, 30 steps of η = 0.002) solved twice:

* CPPD: ``pdlin.solve_nonlinear(problem, method='auto')`` (the correspondence model of the
  paper, no control);
* CPFE: ``pdlin.verification.crystal_plasticity_fem(problem)`` on the same grid (Q4 F-bar
  elements centred on the particles, the boundary nodes on the same path).

Prints, per grid and load, the homogenized stress (σ_xy in shear, σ_yy in compression) of
both at strains 0.002 / 0.006 / 0.02 / 0.04 / 0.06, the relative gap of the magnitudes
(|CPPD| − |CPFE|) / |CPFE| (negative: CPPD below CPFE, the paper's Fig. 14 finding) and wall
times; the F-bar / full-integration comparison of CPFE (volumetric locking); the
σ_xy and reorientation map statistics.  Each run is cached as NPZ in ``--cache`` (the
figure script ``docs/gen_cpfe_figures.py`` reads them).  Nothing is asserted.

Usage::

    python benchmarks/bench_cpfe.py                       # n = 15, 25 (225, 625 particles)
    python benchmarks/bench_cpfe.py --n 15 25 50          # and the paper's 2,500
    python benchmarks/bench_cpfe.py --n 25 --full          # with the full-integration CPFE
    python benchmarks/bench_cpfe.py --n 15 25 50 --full --sqrt2 --cached   # print what is cached
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import pdlin
from pdlin.verification import crystal_plasticity_fem, element_average

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_nonlinear as bn  # noqa: E402
from _context import header  # noqa: E402

STEPS = np.arange(1.0, 31.0)
SHOW = (1, 3, 10, 20, 30)  # load steps printed (strain 0.002 t)
COMPONENT = {"shear": (0, 1), "compression": (1, 1)}


def problem(n: int, load: str, ratio: float = 1.0) -> pdlin.StaticProblem:
    """The polycrystal of ``bench_nonlinear.problem`` with the horizon ``ratio`` h."""
    prob, h = bn.problem(n, load)
    if ratio == 1.0:
        return prob
    bonds = pdlin.find_bonds(prob.cloud, ratio=ratio, influence="constant")
    return pdlin.StaticProblem(prob.model, prob.cloud, bonds, dirichlet=prob.dirichlet)


def total_variation(field: np.ndarray, n: int) -> float:
    """Mean ``|f_i − f_j|`` over the horizontal and vertical neighbours of an n x n C-order grid."""
    f = np.asarray(field).reshape(n, n)
    return float(np.concatenate([np.abs(np.diff(f, axis=0)).ravel(),
                                 np.abs(np.diff(f, axis=1)).ravel()]).mean())  # fmt: skip


def solve(n: int, load: str, kind: str, cache: Path) -> dict[str, Any]:
    """One run (``cppd``, ``cppd-sqrt2``, ``cpfe``, ``cpfe-full``), cached as NPZ."""
    path = cache / f"{kind}_{load}_{n}.npz"
    if path.exists():
        return dict(np.load(path, allow_pickle=False))
    t0 = time.perf_counter()
    if kind.startswith("cppd"):
        prob = problem(n, load, np.sqrt(2.0) if kind == "cppd-sqrt2" else 1.0)
        res = pdlin.solve_nonlinear(prob, times=STEPS, method="auto")
        rot = res.state["reorientation"]
        extra = {"methods": np.array(res.methods)}
    else:
        prob = problem(n, load)
        integ = "full" if kind == "cpfe-full" else "fbar"
        res = crystal_plasticity_fem(prob, times=STEPS, integration=integ, method="auto")
        rot = element_average(res.state["reorientation"], 2**prob.cloud.dim)
        extra = {"methods": np.array(res.methods)}
    out = {
        "hom": np.asarray(res.homogenized_stress),
        "stress": np.asarray(res.stress[-1]),
        "rot": np.asarray(rot),
        "points": np.asarray(prob.cloud.points),
        "iterations": np.asarray(res.iterations),
        "cutbacks": np.asarray(res.cutbacks),
        "time": np.array(time.perf_counter() - t0),
        **extra,
    }
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(path, **out)
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[15, 25])
    ap.add_argument("--loads", nargs="+", default=["shear", "compression"])
    ap.add_argument("--full", action="store_true", help="also the full-integration CPFE")
    ap.add_argument("--sqrt2", action="store_true", help="also CPPD with delta = sqrt(2) h")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/pdlin-cpfe"))
    ap.add_argument("--cached", action="store_true", help="only print the cached runs")
    args = ap.parse_args(argv)
    header(benchmark="bench_cpfe: CPPD vs CPFE, 21-grain planar-2 polycrystal, 30 steps")
    kinds = ["cppd", "cpfe"] + (["cpfe-full"] if args.full else [])
    kinds += ["cppd-sqrt2"] if args.sqrt2 else []
    runs: dict[tuple[str, str, int], dict[str, Any]] = {}
    for n in args.n:
        for load in args.loads:
            for kind in kinds:
                if args.cached and not (args.cache / f"{kind}_{load}_{n}.npz").exists():
                    continue
                runs[kind, load, n] = r = solve(n, load, kind, args.cache)
                print(
                    f"  ran {kind:10s} {load:11s} N = {n * n:5d}: {float(r['time']):7.1f} s, "
                    f"{int(r['iterations'].sum())} iterations, {int(r['cutbacks'].sum())} "
                    f"cut-backs, drivers {sorted(set(r['methods'].tolist()))}",
                    flush=True,
                )
    print("\nHomogenized stress (MPa; shear: σ_xy, compression: σ_yy), gap (|v| − |CPFE|) / |CPFE|")
    print("    N  load         kind        " + "".join(f"  t={t:<2d}    " for t in SHOW))
    for load in args.loads:
        i, j = COMPONENT[load]
        for n in args.n:
            if ("cpfe", load, n) not in runs:
                continue
            fe = runs["cpfe", load, n]["hom"][:, i, j]
            for kind in kinds:
                if (kind, load, n) not in runs:
                    continue
                v = runs[kind, load, n]["hom"][:, i, j]
                cells = "".join(f"{v[t - 1]:9.3f}   " for t in SHOW)
                print(f"{n * n:5d}  {load:11s}  {kind:10s} {cells}")
                if kind != "cpfe":
                    gap = (np.abs(v) - np.abs(fe)) / np.abs(fe)
                    cells = "".join(f"{100 * gap[t - 1]:+8.2f} % " for t in SHOW)
                    print(f"{'':5s}  {'':11s}  {'gap':10s} {cells}")
    print("\nMaps at step 30: σ_xy under shear, reorientation Δθ (deg) under compression;")
    print("corr: Pearson correlation with the CPFE map of the same grid, point by point")
    print("TV: mean |Δθ_i − Δθ_j| over grid neighbours (deg; larger: sharper bands)")
    print("    N  kind         σ_xy min / mean / max   corr    |Δθ| mean / 99 % / max  corr    TV")
    for n in args.n:
        fe_s = runs.get(("cpfe", "shear", n))
        fe_c = runs.get(("cpfe", "compression", n))
        for kind in kinds:
            sh = runs.get((kind, "shear", n))
            co = runs.get((kind, "compression", n))
            s = c_s = r = c_r = ""
            if sh is not None:
                v = sh["stress"][:, 0, 1]
                s = f"{v.min():7.2f} / {v.mean():6.2f} / {v.max():6.2f}"
                if fe_s is not None:
                    c_s = f"{np.corrcoef(v, fe_s['stress'][:, 0, 1])[0, 1]:.3f}"
            if co is not None:
                a = np.abs(co["rot"])
                r = f"{a.mean():5.2f} / {np.percentile(a, 99):5.2f} / {a.max():5.2f}"
                if fe_c is not None:
                    c_r = f"{np.corrcoef(co['rot'], fe_c['rot'])[0, 1]:.3f}  "
                c_r += f"{total_variation(co['rot'], n):5.2f}"
            print(f"{n * n:5d}  {kind:10s}  {s:24s} {c_s:6s}  {r:22s} {c_r}")


if __name__ == "__main__":
    main()
