"""Speed of explicit dynamics: force evaluations and whole steps, in bond updates per second.

Rows: model x dimension x size.  Columns:

* ``force``: one ``force_kernel(...).evaluate`` (extension, force and strain energy in one
  pass over the directed bonds; exact kinematics), milliseconds and million bond updates
  per second (directed bonds / time);
* ``+damage``: the same with the critical-stretch test (no bond breaks: the cost of the
  test);
* ``step``: one whole velocity-Verlet step of :func:`pdlin.dynamics.solve_explicit` with
  damage (the force pass plus the vector updates and the energy bookkeeping), measured over
  ``--steps`` steps;
* ``bytes/bond``: the memory traffic of one force pass counted from the arrays it reads and
  writes per bond (a lower bound), and the bandwidth it implies.

The force runs on numpy (no compiled kernel yet).  Run ``python benchmarks/bench_explicit.py``
(about a minute) or ``--quick``.  The header gives the load average: on a shared machine
the times are upper bounds.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import pdlin  # noqa: E402
from pdlin.dynamics import force_kernel, solve_explicit  # noqa: E402

#: float64 arrays read per directed bond by one state-based pass (xi 2-3, length, i, j,
#: reverse, a, c, kth, w, vj, alive, s0) and written (e, m, theta gathers, t, tw): counted
#: from forces.py; bond-based reads fewer
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


def main() -> None:
    """Print the table."""
    from _context import header

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--steps", type=int, default=50)
    args = ap.parse_args()
    header()
    cases = [("bond", 2, 200), ("lps", 2, 200), ("xosb", 2, 200), ("bond", 3, 30), ("lps", 3, 30)]
    if args.quick:
        cases = [("bond", 2, 100), ("xosb", 2, 100), ("bond", 3, 20)]
    print(
        "| model | dim | points | bonds | force ms | M bond/s | +damage ms | step ms | "
        "M bond/s (step) | GB/s implied |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, dim, n in cases:
        print(measure(name, dim, n, args.steps), flush=True)


def measure(name: str, dim: int, n: int, steps: int) -> str:
    """Measure one configuration and return its Markdown row."""
    cloud = pdlin.grid((n,) * dim, spacing=1e-3)
    prob = pdlin.StaticProblem(_model(name, dim), cloud, ratio=3.015)
    bonds = prob.get_bonds()
    prob = pdlin.StaticProblem(prob.model, cloud, bonds)
    nb = bonds.n_bonds
    kern = force_kernel(prob.model, cloud, bonds, linear=False)
    u = 1e-7 * np.random.default_rng(0).normal(size=(cloud.n, dim))
    alive = np.ones(nb)
    s0 = np.full(nb, 1.0)
    rep = max(3, int(2e6 // nb))
    t_f = _time(lambda: kern.evaluate(u, alive, None), rep)
    t_d = _time(lambda: kern.evaluate(u, alive, s0), rep)
    dt = 1e-9
    res = solve_explicit(
        prob, steps * dt, dt, density=8000.0, critical_stretch=1.0, check_dt=False,
        output_every=10**6, u0=u,
    )  # fmt: skip
    t_s = res.timings["steps"] / res.steps
    gbs = BYTES_PER_BOND[name] * nb / t_f / 1e9
    return (
        f"| {name} | {dim} | {cloud.n:,} | {nb:,} | {t_f * 1e3:.2f} | {nb / t_f / 1e6:.1f} | "
        f"{t_d * 1e3:.2f} | {t_s * 1e3:.2f} | {nb / t_s / 1e6:.1f} | {gbs:.2f} |"
    )


if __name__ == "__main__":
    main()
