"""1 vs 2 threads on pdlin's threaded kernels (issue 13, "Use both cores on one machine").

For each kernel the script alternates ``pdlin.set_num_threads(1)`` and ``(2)`` runs back to
back ``--repeat`` times and reports the best time of each and their ratio; it also checks
that the results are bitwise identical.  Kernels: the bond search of an irregular cloud
(cKDTree on the scipy path, a threaded cell list with numba), assembly of the bond-based
(3D), LPS and
XOSB (3D) and correspondence (2D, 401², δ = 2h, no control and stress points) stiffness,
and the matrix-free products ``K x`` of LPS and correspondence (scipy's mat-vecs, serial:
a numba mat-vec did not win).  The bond-based assembly
runs on pdlin's thread pool (one fused numba pass per row chunk that writes each block
once, or numpy chunks without numba); the sparse products of the other
models use the optional numba kernels (``pip install "pdlin[fast]"``, pdlin/_kernels.py)
when numba is installed, else scipy (which holds the GIL: no speed-up).  The column
"scipy path" is the same call with the numba kernels switched off (1 thread), i.e. pdlin
without the ``fast`` extra; "vs scipy" is that time over the 2-thread time.  The serial
parts of each call (zero-block dropping, transposes, coefficients) are included, so the
ratios are those of the whole call.  numba's compile (or cache load) happens in a warm-up
before the timings and is printed.

Times are wall seconds with the CPU seconds of the same run beside them (CPU / wall near 2
means both threads worked).  The last column marks a speed-up unreliable when the load
average at the start exceeded the cores the 2-thread run left free (``_context.speedup_flag``).

Usage: ``python benchmarks/bench_threads.py`` (~4 min), ``--quick`` (small sizes).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

import pdlin  # noqa: E402
from pdlin import _kernels  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, speedup_flag, timed  # noqa: E402


def _same(a: Any, b: Any) -> bool:
    if sp.issparse(a):
        a, b = sp.csr_array(a), sp.csr_array(b)
        return bool(
            np.array_equal(a.indptr, b.indptr)
            and np.array_equal(a.indices, b.indices)
            and np.array_equal(a.data, b.data)
        )
    return bool(np.array_equal(a, b))


def _rel_diff(a: Any, b: Any) -> float:
    if sp.issparse(a):
        a, b = sp.csr_array(a), sp.csr_array(b)
        return float(abs(a - b).max() / abs(a).max())
    return float(np.abs(a - b).max() / np.abs(a).max())


def _set_numba(on: bool) -> None:
    _kernels._loaded = None if on else False


def measure(fn: Callable[[], Any], repeat: int) -> tuple[float, float, bool, Any, dict[int, float]]:
    """Best wall time of 1 and 2 threads, bitwise equality, the result, CPU s of the bests."""
    best = {1: float("inf"), 2: float("inf")}
    cpu = {1: 0.0, 2: 0.0}
    out: dict[int, Any] = {}
    for _ in range(repeat):
        for nt in (1, 2):
            pdlin.set_num_threads(nt)
            with timed() as t:
                out[nt] = fn()
            if t.wall < best[nt]:
                best[nt], cpu[nt] = t.wall, t.cpu
    pdlin.set_num_threads(None)
    return best[1], best[2], _same(out[1], out[2]), out[1], cpu


def measure_scipy(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Best time of ``fn`` on the scipy path (numba kernels off), 1 thread."""
    _set_numba(False)
    pdlin.set_num_threads(1)
    best, out = float("inf"), None
    try:
        for _ in range(repeat):
            t = time.perf_counter()
            out = fn()
            best = min(best, time.perf_counter() - t)
    finally:
        _set_numba(True)
        pdlin.set_num_threads(None)
    return best, out


def warm_up() -> str:
    """Compile (or load from numba's cache) every kernel signature the rows use."""
    if not _kernels.numba_enabled():
        return "numba not installed: every product is scipy's"
    t = time.perf_counter()
    for dim in (2, 3):
        cloud = pdlin.grid((12,) * dim, spacing=0.1)
        bonds = pdlin.find_bonds(cloud, ratio=3.015)
        pdlin.LPS(E=1.0, nu=0.3).stiffness(cloud, bonds)
        c = pdlin.Correspondence(E=1.0, nu=0.25, plane="strain")
        c.stiffness(cloud, pdlin.find_bonds(cloud, ratio=2.0))
    import numba

    return (
        f"numba {numba.__version__} ({numba.threading_layer()} threading layer): warm-up "
        f"(compile on a first run, else cache load; the same products on small grids) "
        f"{time.perf_counter() - t:.1f} s, not in the timings"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    q = args.quick
    print(f"# bench_threads.py {'--quick ' if q else ''}(best of {args.repeat} alternating runs)")
    ctx = header()
    print(f"\n{warm_up()}\n")
    print(
        "| kernel | size | scipy path, 1 thread (s) | 1 thread (s, CPU s) | 2 threads (s, CPU s) "
        "| speed-up 2 vs 1 | vs scipy path | bitwise equal 1/2 threads | rel. diff. to scipy "
        "path | speed-up reliable? |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    rows: list[tuple[str, str, Callable[[], Any], bool]] = []

    n3 = 20 if q else 40
    c3 = pdlin.grid((n3,) * 3, spacing=1.0 / n3)
    b3 = pdlin.find_bonds(c3, ratio=3.015)
    bb = pdlin.BondBased(E=1.0, nu=0.25)
    size3 = f"{c3.n:,} pts, {b3.n_bonds:,} bonds"
    rows.append(("bond-based K (3D, δ = 3.015h)", size3, lambda: bb.stiffness(c3, b3), True))
    # bond search of an irregular cloud (the lattice stencil is for grids): the same points
    # as a plain PointCloud go to the cKDTree path (scipy) or the threaded cell list (numba)
    c3p = pdlin.PointCloud(c3.points, volumes=c3.volumes)
    h3 = 3.015 / n3 * (1 + 1e-9)
    rows.append(
        (
            "bond search (3D, irregular-cloud path)",
            size3,
            lambda: pdlin.find_bonds(c3p, horizon=h3).xi,
            True,
        )
    )
    nl = 16 if q else 30
    cl = pdlin.grid((nl,) * 3, spacing=1.0 / nl)
    bl = pdlin.find_bonds(cl, ratio=3.015)
    sizel = f"{cl.n:,} pts, {bl.n_bonds:,} bonds"
    lps = pdlin.LPS(E=1.0, nu=0.25)
    xosb = pdlin.XOSB(E=1.0, nu=0.25)
    rows.append(("LPS K (3D, δ = 3.015h)", sizel, lambda: lps.stiffness(cl, bl), True))
    rows.append(("XOSB K (3D, δ = 3.015h)", sizel, lambda: xosb.stiffness(cl, bl), True))
    xl = np.random.default_rng(0).normal(size=cl.n * 3)
    op_l = lps.operator(cl, bl)
    rows.append(("LPS K x, matrix-free (3D; scipy mat-vecs)", sizel, lambda: op_l @ xl, False))
    n2 = 201 if q else 401
    c2 = pdlin.grid((n2, n2), spacing=1.0 / n2)
    bn = pdlin.find_bonds(c2, ratio=2.0, influence="inverse")
    bs = pdlin.find_bonds(c2, ratio=2.0)
    size2 = f"{n2}² = {c2.n:,} pts"

    def corr(control: str, bonds: Any) -> Callable[[], Any]:
        # a fresh model each call: no cached plan (G, weights) between runs
        return lambda: pdlin.Correspondence(
            E=1.0, nu=0.25, control=control, plane="strain"
        ).stiffness(c2, bonds)

    rows.append(("correspondence K, no control (δ = 2h)", size2, corr("none", bn), True))
    sp_name = "correspondence K, stress points (δ = 2h)"
    rows.append((sp_name, size2, corr("stress_points", bs), True))
    cm = pdlin.Correspondence(E=1.0, nu=0.25, control="none", plane="strain")
    op_c = cm.operator(c2, bn)
    x2 = np.random.default_rng(0).normal(size=c2.n * 2)
    mf_name = "correspondence K x, matrix-free (δ = 2h; scipy mat-vecs)"
    rows.append((mf_name, size2, lambda: op_c @ x2, False))
    for name, size, fn, uses_numba in rows:
        t1, t2, same, out, cpu = measure(fn, args.repeat)
        times = f"{t1:.3f} ({cpu[1]:.3f}) | {t2:.3f} ({cpu[2]:.3f}) | {t1 / t2:.2f}"
        if uses_numba and _kernels.numba_enabled():
            ts, ref = measure_scipy(fn, args.repeat)
            scipy_cols = f"{ts:.3f} | {times} | {ts / t2:.2f}"
            diff = f"{_rel_diff(ref, out):.1e}"
        else:
            scipy_cols = f"— | {times} | {t1 / t2:.2f}"
            diff = "—"
        flag = speedup_flag(2, ctx.load1, ctx.cores) or "yes"
        print(f"| {name} | {size} | {scipy_cols} | {same} | {diff} | {flag} |", flush=True)
    print(f"\nload average after the run: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
