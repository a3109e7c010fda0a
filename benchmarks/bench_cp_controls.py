"""Zero-energy-mode controls on the crystal-plasticity polycrystal (issue 11, 10⁵ stall).

The polycrystal of Luo, Ramazani & Sundararaghavan (2017), Sec. 4 (``bench_nonlinear.problem``:
n x n grid, δ = h, 21 Voronoi grains,
planar-2 crystal plasticity, boundary ring under ``Dirichlet.velocity_gradient``, 30 load
steps) solved with ``Correspondence(material=..., control=C)`` for each control C.  Prints
one row per control: wall time, iterations, largest iterations of a step, cut-backs, ADR
fallbacks, the high-frequency content of the displacement at step 1 and at the last step
(``hf``: ``|u_i - mean of its four grid neighbours| / h`` over interior points, median /
99 % / max; a smooth field gives O(h x strain gradient), zero-energy modes give values of
the order of the strain and more) and the homogenized stress (σ_xy for shear, σ_yy for
compression) at step 1 and at the last step.  Nothing is asserted.

Usage::

    python benchmarks/bench_cp_controls.py --n 50 --load shear --controls none stress_points penalty
    python benchmarks/bench_cp_controls.py --n 100 --load shear --controls penalty
    python benchmarks/bench_cp_controls.py --controls penalty:0.1 penalty:0.3   # coefficients
    python benchmarks/bench_cp_controls.py --rate 100 --method newton   # power-law slip rule
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import pdlin

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_nonlinear as bn  # noqa: E402
from _context import header, timed  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50, help="grid points per side (default 50)")
    ap.add_argument("--load", choices=sorted(bn.LOADS), default="shear")
    ap.add_argument("--method", choices=["newton", "adr", "auto"], default="auto")
    ap.add_argument(
        "--controls",
        nargs="+",
        default=["none", "stress_points", "penalty"],
        help="controls of Correspondence; 'penalty:C' sets the penalty coefficient C",
    )
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--threads", type=int, default=1, help="pdlin threads (default 1)")
    ap.add_argument(
        "--rate",
        type=float,
        help="power-law exponent of CrystalPlasticity(rate_exponent=...) (default: none, the "
        "paper's rate-independent model)",
    )
    args = ap.parse_args()
    pdlin.set_num_threads(args.threads)
    base, h = bn.problem(args.n, args.load, rate=args.rate)
    material = base.model.material
    comp = (0, 1) if args.load == "shear" else (1, 1)
    header()
    print(
        f"# {args.n}² = {args.n**2} particles, {args.load}, {args.method}, {args.steps} steps, "
        f"{args.threads} pdlin thread(s), "
        + ("rate independent" if args.rate is None else f"power law n = {args.rate:g}")
    )
    print(
        "| control | wall s / CPU s | iterations | max it/step | cut-backs | fallbacks "
        "| hf step 1 median/99%/max | hf last step median/99%/max | σ step 1 / last (MPa) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for control in args.controls:
        model = bn.correspondence(material, control)  # "penalty:0.1": coefficient 0.1
        prob = pdlin.StaticProblem(model, base.cloud, base.bonds, dirichlet=list(base.dirichlet))
        try:
            with timed() as t:
                res = pdlin.solve_nonlinear(
                    prob,
                    times=np.arange(1.0, args.steps + 1.0),
                    t_end=30.0,
                    method=args.method,
                    keep_states=False,
                )
        except pdlin.errors.ConvergenceError as exc:
            print(f"| {control} | failed: {str(exc)[:120]} | | | | | | | |", flush=True)
            continue
        hf = [bn.high_frequency(res.u[k], prob.cloud.points, args.n, h) for k in (0, -1)]
        q = [
            "/".join(f"{v:.1e}" for v in (np.median(a), np.quantile(a, 0.99), a.max())) for a in hf
        ]
        hom = res.homogenized_stress
        assert hom is not None
        fallbacks = sum("failed" in m for m in res.methods)
        print(
            f"| {control} | {t.wall:.1f} / {t.cpu:.1f} | {int(res.iterations.sum())} | "
            f"{int(res.iterations.max())} | {int(res.cutbacks.sum())} | {fallbacks} | {q[0]} | "
            f"{q[1]} | {hom[0][comp]:.3f} / {hom[-1][comp]:.3f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
