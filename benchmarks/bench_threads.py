"""1 vs 2 threads on pdlin's chunked kernels (issue 13, "Use both cores on one machine").

For each kernel the script alternates ``pdlin.set_num_threads(1)`` and ``(2)`` runs
back to back ``--repeat`` times and reports the best time of each and their ratio; it
also checks that the results are bitwise identical.  Kernels: assembly of the
bond-based (3D) and correspondence (2D, 401², δ = 2h, no control and stress points)
stiffness, and LPS (3D) as a reference that is not threaded (its cost is scipy's sparse
product, which holds the GIL).  The serial parts of each assembly (sparse products,
zero-block dropping, transposes) are included, so the ratio is that of the whole call.

Usage: ``python benchmarks/bench_threads.py`` (~3 min), ``--quick`` (small sizes).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import time
from collections.abc import Callable
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

import pdlin  # noqa: E402


def _same(a: Any, b: Any) -> bool:
    if sp.issparse(a):
        a, b = sp.csr_array(a), sp.csr_array(b)
        return bool(
            np.array_equal(a.indptr, b.indptr)
            and np.array_equal(a.indices, b.indices)
            and np.array_equal(a.data, b.data)
        )
    return bool(np.array_equal(a, b))


def measure(fn: Callable[[], Any], repeat: int) -> tuple[float, float, bool]:
    best = {1: float("inf"), 2: float("inf")}
    out: dict[int, Any] = {}
    for _ in range(repeat):
        for nt in (1, 2):
            pdlin.set_num_threads(nt)
            t = time.perf_counter()
            out[nt] = fn()
            best[nt] = min(best[nt], time.perf_counter() - t)
    pdlin.set_num_threads(None)
    return best[1], best[2], _same(out[1], out[2])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    q = args.quick
    print(
        f"# bench_threads.py {'--quick ' if q else ''}"
        f"({datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, python "
        f"{platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} cores, "
        f"best of {args.repeat} alternating runs)\n"
    )
    print("| kernel | size | 1 thread (s) | 2 threads (s) | speed-up | bitwise equal |")
    print("|---|---|---|---|---|---|")
    rows: list[tuple[str, str, Callable[[], Any]]] = []

    n3 = 20 if q else 40
    c3 = pdlin.grid((n3,) * 3, spacing=1.0 / n3)
    b3 = pdlin.find_bonds(c3, ratio=3.015)
    bb = pdlin.BondBased(E=1.0, nu=0.25)
    size3 = f"{c3.n:,} pts, {b3.n_bonds:,} bonds"
    rows.append(("bond-based K (3D, δ = 3.015h)", size3, lambda: bb.stiffness(c3, b3)))
    nl = 16 if q else 30
    cl = pdlin.grid((nl,) * 3, spacing=1.0 / nl)
    bl = pdlin.find_bonds(cl, ratio=3.015)
    lps = pdlin.LPS(E=1.0, nu=0.25)
    sizel = f"{cl.n:,} pts, {bl.n_bonds:,} bonds"
    rows.append(("LPS K (3D, δ = 3.015h; not threaded)", sizel, lambda: lps.stiffness(cl, bl)))
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

    rows.append(("correspondence K, no control (δ = 2h)", size2, corr("none", bn)))
    rows.append(("correspondence K, stress points (δ = 2h)", size2, corr("stress_points", bs)))
    for name, size, fn in rows:
        t1, t2, same = measure(fn, args.repeat)
        print(f"| {name} | {size} | {t1:.2f} | {t2:.2f} | {t1 / t2:.2f} | {same} |", flush=True)


if __name__ == "__main__":
    main()
