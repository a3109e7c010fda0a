"""Time one crystal-plasticity ``update`` (with and without the tangent) on many points.

Run ``python benchmarks/bench_crystal_plasticity.py``.  Each case first drives the points
through a few load steps so that most of them are plastic, then times the next update
(best of ``--repeat``).  Prints a Markdown table; "re-activated" is the share of the
points that needed at least one re-activation pass of the active-set search, "max
viol." the largest ``|τ|/s − 1`` over the inactive systems after the update.
``--active-set prune`` times the return mapping of Luo, Ramazani & Sundararaghavan (2017),
Appendix, with systems of Δγ <= 0 dropped and never re-activated.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
from scipy.linalg import expm

from pdlin.constitutive import ORIENTATIONS_2D, CrystalPlasticity, euler_to_rotation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, timed  # noqa: E402


def _case(
    slip: str, n: int, repeat: int, active_set: str = "reactivate"
) -> tuple[tuple[float, float], tuple[float, float], float, float, float, float]:
    rng = np.random.default_rng(0)
    if slip == "planar-2":
        o = rng.choice(ORIENTATIONS_2D, n)
        L, eta, steps = np.array([[0.0, 1.0], [1.0, 0.0]]), 0.002, 4
    else:
        o = euler_to_rotation(rng.uniform(0.0, np.pi, (n, 3)))
        L, eta, steps = np.diag([-0.5, -0.5, 1.0]), 1e-4, 8
    mat = CrystalPlasticity(slip, orientation=o, active_set=active_set)
    d = mat.dim
    state = mat.initial_state(n)
    for k in range(1, steps):
        _, state, _ = mat.update(np.broadcast_to(expm(eta * k * L), (n, d, d)), state)
    F = np.broadcast_to(expm(eta * steps * L), (n, d, d)).copy()
    t_plain, t_tan = (np.inf, 0.0), (np.inf, 0.0)  # (wall, CPU) of the fastest run
    for _ in range(repeat):
        with timed() as a:
            _, new, _ = mat.update(F, state)
        with timed() as b:
            mat.update(F, state, tangent=True)
        t_plain = min(t_plain, (a.wall, a.cpu))
        t_tan = min(t_tan, (b.wall, b.cpu))
    plastic = float(new["plastic"].mean())
    mean_active = float((new["dgamma"] > 0).sum(axis=1)[new["plastic"] > 0].mean())
    react = float((new["reactivated"] > 0).mean())
    ratio = np.abs(new["tau"]) / new["s"] - 1.0
    viol = float(np.max(np.where(new["dgamma"] > 0, -np.inf, ratio)))
    return t_plain, t_tan, plastic, mean_active, react, viol


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--active-set", choices=("reactivate", "prune"), default="reactivate")
    args = p.parse_args(argv)
    header()
    cases = [("planar-2", 10_000), ("planar-2", 100_000), ("fcc", 10_000), ("hcp", 10_000)]
    print(
        "| slip | points | plastic | mean active | re-activated | max viol. | update (s, CPU s) "
        "| update + tangent (s, CPU s) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for slip, n in cases:
        t_plain, t_tan, plastic, act, react, viol = _case(slip, n, args.repeat, args.active_set)
        print(
            f"| {slip} | {n} | {plastic:.0%} | {act:.2f} | {react:.0%} | {viol:+.1e} "
            f"| {t_plain[0]:.3f} ({t_plain[1]:.3f}) | {t_tan[0]:.3f} ({t_tan[1]:.3f}) |"
        )


if __name__ == "__main__":
    main()
