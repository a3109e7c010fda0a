"""Time ``Correspondence(material=CrystalPlasticity).respond`` (Luo et al. 2017 setting).

Run ``python benchmarks/bench_nonlinear_correspondence.py``.  Pixel grid n x n, δ = h,
ω = 1, random orientations from the 12 values -π/2 + kπ/12 (Luo, Ramazani &
Sundararaghavan 2017, Sec. 4), u = the shear of load step 3 (Eq. 25, mostly plastic)
plus a small random field, from the initial state.  Best of
``--repeat``; prints a Markdown table with the constitutive share and the K_T assembly
(wall seconds, CPU seconds of the same run in brackets) after the context header.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np
from scipy.linalg import expm

import pdlin

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, timed  # noqa: E402


def _best(repeat, fn, *args, **kwargs):
    """``'wall (cpu)'`` of the fastest of ``repeat`` calls, and the result."""
    best, cpu = np.inf, 0.0
    out = None
    for _ in range(repeat):
        with timed() as t:
            out = fn(*args, **kwargs)
        if t.wall < best:
            best, cpu = t.wall, t.cpu
    return f"{best:.3f} ({cpu:.3f})", out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[50, 316])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--control", default="none")
    args = ap.parse_args(argv)
    header()
    print(
        "| particles | gradient points | plastic | respond (s) | respond + K_T (s) "
        "| update + dP/dF (s) | K_T assembly (s) | K_T nnz / row |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        cloud = pdlin.grid((n, n), spacing=1.0 / n)
        bonds = pdlin.find_bonds(cloud, ratio=1.0)
        rng = np.random.default_rng(0)
        theta = rng.choice(-np.pi / 2 + np.arange(12) * np.pi / 12, cloud.n)
        mat = pdlin.CrystalPlasticity(orientation=theta)
        model = pdlin.Correspondence(material=mat, control=args.control)
        state = model.initial_state(cloud, bonds)
        F = expm(0.006 * np.array([[0.0, 1.0], [1.0, 0.0]]))
        u = cloud.points @ (F - np.eye(2)).T + 1e-4 / n * rng.standard_normal((cloud.n, 2))
        t_f, r = _best(args.repeat, model.respond, cloud, bonds, u, state)
        t_k, r = _best(args.repeat, model.respond, cloud, bonds, u, state, tangent=True)
        Fg = model.deformation_gradient(cloud, bonds, u)
        t_u, (_, _, A) = _best(args.repeat, mat.update, Fg, state, tangent=True)
        t_a, K = _best(args.repeat, model.tangent_matrix, cloud, bonds, A)
        print(
            f"| {cloud.n} | {r.calls} | {r.state['plastic'].mean():.0%} | {t_f} | "
            f"{t_k} | {t_u} | {t_a} | {K.nnz / K.shape[0]:.1f} |"
        )


if __name__ == "__main__":
    main()
