"""Speed of explicit dynamics: force passes and whole steps, in bond updates per second.

Two tables.

**Bond-based 3D, numpy against the compiled (numba) pass** (``--sizes``, default about
10^5, 10^6 and 10^7 directed bonds; ``δ = 3.015 h``, about 122 bonds per interior point).
One ``force_kernel(...).evaluate`` with the critical-stretch test (exact kinematics, no bond
breaks: the cost of the test is in), on numpy and on the compiled pass at 1 and 2 of
pdlin's threads (:func:`pdlin.set_num_threads`): wall and CPU milliseconds, million bond
updates per second (directed bonds / wall time, and / CPU time: the rate of one busy core),
and the memory-bandwidth bound of the pass: the bytes it must stream per bond (``j`` 8,
``ξ`` 24, ``|ξ|`` 8, ``k`` 8, ``alive`` 8, ``s0`` 8 = 64; ``u_j`` is gathered from a few
cached rows) over the bandwidth measured here by a numpy copy of a 256 MB array (read +
write).  ``step`` is one whole velocity-Verlet step of :func:`pdlin.dynamics.solve_explicit`
(the force pass plus the O(points) vector updates and energy bookkeeping).

**All models** (``--models``): bond-based, LPS, XOSB in 2D and 3D on numpy (force, with
the damage test, whole step), and the compiled pass with the damage test on pdlin's
threads (wall / CPU ms, and bond updates per CPU second).

Run ``python benchmarks/bench_explicit.py`` (a few minutes; about 2.5 GB at 10^7 bonds
for the numpy pass) or ``--quick``.  The header gives the load average: on a shared
machine wall times are upper bounds, CPU times are what the work cost.
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import pdlin  # noqa: E402
from pdlin.dynamics import force_kernel, solve_explicit  # noqa: E402

#: bytes streamed per directed bond by the compiled bond-based pass with damage (exact
#: kinematics): j, ξ (3), |ξ|, k, alive, s0 as float64 / int64 (see the module docstring)
BYTES_COMPILED = 8 * 8
#: float64 arrays read per directed bond by one numpy state-based pass (xi 2-3, length, i,
#: j, reverse, a, c, kth, w, vj, alive, s0) and written (e, m, theta gathers, t, tw):
#: counted from forces.py; bond-based reads fewer
BYTES_PER_BOND = {"bond": 8 * 14, "lps": 8 * 26, "xosb": 8 * 26}


def _model(name: str, dim: int) -> pdlin.models.Model:
    plane = {"plane": "strain"} if dim == 2 else {}
    if name == "bond":
        return pdlin.BondBased(E=200e9, **plane)
    if name == "lps":
        return pdlin.LPS(E=200e9, nu=0.25, **plane)
    return pdlin.XOSB(E=200e9, nu=0.25, **plane)


def _time(fn, repeat: int) -> float:
    fn()
    t0 = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - t0) / repeat


def _timed(fn, repeat: int) -> tuple[float, float]:
    """Wall and CPU seconds per call (after one warm-up call)."""
    from _context import timed

    fn()
    with timed() as t:
        for _ in range(repeat):
            fn()
    return t.wall / repeat, t.cpu / repeat


def _step_time(prob: pdlin.StaticProblem, u: np.ndarray, steps: int, compiled: bool) -> float:
    """Wall seconds per Verlet step of ``solve_explicit`` with the damage test."""
    from pdlin.dynamics import explicit

    orig = explicit.force_kernel
    explicit.force_kernel = functools.partial(force_kernel, compiled=compiled)
    try:
        res = solve_explicit(
            prob, steps * 1e-9, 1e-9, density=8000.0, critical_stretch=1.0, check_dt=False,
            output_every=10**6, u0=u,
        )  # fmt: skip
    finally:
        explicit.force_kernel = orig
    return res.timings["steps"] / res.steps


def bandwidth() -> float:
    """STREAM-like copy bandwidth in bytes/s: ``np.copyto`` of 256 MB (read + write), best of 5."""
    a = np.ones(1 << 25)
    b = np.empty_like(a)
    best = np.inf
    for _ in range(5):
        t0 = time.perf_counter()
        np.copyto(b, a)
        best = min(best, time.perf_counter() - t0)
    return 2 * a.nbytes / best


def compiled_rows(n: int, steps: int, bw: float) -> list[str]:
    """Rows of the numpy / numba table for a ``n^3`` bond-based grid."""
    from pdlin._kernels import numba_enabled

    cloud = pdlin.grid((n, n, n), spacing=1e-3)
    model = pdlin.BondBased(E=200e9)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    nb = bonds.n_bonds
    u = 1e-7 * np.random.default_rng(0).normal(size=(cloud.n, 3))
    alive, s0 = np.ones(nb), np.full(nb, 1.0)
    rep = max(2, int(2e7 // nb))
    prob = pdlin.StaticProblem(model, cloud, bonds)
    bound = bw / BYTES_COMPILED / 1e6
    rows = []
    configs = [("numpy", False, 1)]
    if numba_enabled():
        configs += [("numba", True, 1), ("numba", True, 2)]
    for label, compiled, threads in configs:
        pdlin.set_num_threads(threads)
        kern = force_kernel(model, cloud, bonds, linear=False, compiled=compiled)
        wall, cpu = _timed(functools.partial(kern.evaluate, u, alive, s0), rep if compiled else 2)
        del kern
        t_s = _step_time(prob, u, steps if compiled else max(2, steps // 10), compiled)
        rows.append(
            f"| {nb:,} | {cloud.n:,} | {label} | {threads} | {wall * 1e3:.1f} | "
            f"{cpu * 1e3:.1f} | {nb / wall / 1e6:.1f} | {nb / cpu / 1e6:.1f} | "
            f"{t_s * 1e3:.1f} | {nb / t_s / 1e6:.1f} | {bound:.0f} |"
        )
    pdlin.set_num_threads(None)
    return rows


def main() -> None:
    """Print the tables."""
    from _context import header

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--sizes", type=int, nargs="*", default=[10, 22, 46])
    ap.add_argument("--models", action="store_true", help="also the numpy table of all models")
    args = ap.parse_args()
    header()
    sizes = [10, 22] if args.quick else args.sizes
    bw = bandwidth()
    print(f"\ncopy bandwidth (np.copyto of 256 MB, read + write): {bw / 1e9:.2f} GB/s; "
          f"bound of the compiled pass: {BYTES_COMPILED} B/bond -> "
          f"{bw / BYTES_COMPILED / 1e6:.0f} M bond/s\n")  # fmt: skip
    print(
        "| bonds | points | pass | threads | force wall ms | force CPU ms | M bond/s (wall) "
        "| M bond/s (CPU) | step wall ms | M bond/s (step) | bandwidth bound M bond/s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for n in sizes:
        for row in compiled_rows(n, args.steps, bw):
            print(row, flush=True)
    if not args.models:
        return
    cases = [("bond", 2, 200), ("lps", 2, 200), ("xosb", 2, 200), ("bond", 3, 30), ("lps", 3, 30)]
    print(
        "\n| model | dim | points | bonds | force ms | M bond/s | +damage ms | step ms | "
        "M bond/s (step) | GB/s implied | numba +damage wall / CPU ms | numba M bond/s (CPU) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, dim, n in cases:
        print(measure(name, dim, n, args.steps), flush=True)


def measure(name: str, dim: int, n: int, steps: int) -> str:
    """Measure one configuration (numpy, and numba where installed) and return its row."""
    cloud = pdlin.grid((n,) * dim, spacing=1e-3)
    prob = pdlin.StaticProblem(_model(name, dim), cloud, ratio=3.015)
    bonds = prob.get_bonds()
    prob = pdlin.StaticProblem(prob.model, cloud, bonds)
    nb = bonds.n_bonds
    kern = force_kernel(prob.model, cloud, bonds, linear=False, compiled=False)
    u = 1e-7 * np.random.default_rng(0).normal(size=(cloud.n, dim))
    alive = np.ones(nb)
    s0 = np.full(nb, 1.0)
    rep = max(3, int(2e6 // nb))
    t_f = _time(lambda: kern.evaluate(u, alive, None), rep)
    t_d = _time(lambda: kern.evaluate(u, alive, s0), rep)
    t_s = _step_time(prob, u, steps, False)
    gbs = BYTES_PER_BOND[name] * nb / t_f / 1e9
    from pdlin._kernels import numba_enabled

    fast = "–"
    if numba_enabled():
        kc = force_kernel(prob.model, cloud, bonds, linear=False, compiled=True)
        wall, cpu = _timed(functools.partial(kc.evaluate, u, alive, s0), rep)
        fast = f"{wall * 1e3:.2f} / {cpu * 1e3:.2f} | {nb / cpu / 1e6:.1f}"
    else:
        fast += " | –"
    return (
        f"| {name} | {dim} | {cloud.n:,} | {nb:,} | {t_f * 1e3:.2f} | {nb / t_f / 1e6:.1f} | "
        f"{t_d * 1e3:.2f} | {t_s * 1e3:.2f} | {nb / t_s / 1e6:.1f} | {gbs:.2f} | {fast} |"
    )


if __name__ == "__main__":
    main()
