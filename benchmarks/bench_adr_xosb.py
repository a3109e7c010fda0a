"""ADR against the direct solve on the XOSB plate with a hole (Liu, Chen & Skelton, XOSB, Sec. 5.1).

The plate of the paper's Example 1 (square, side 1 m, hole r = 0.1 m, plane stress, E = 70 GPa,
ν = 0.33) on pdlin's graded O-grid (``pdlin.sweeps.plate_with_hole_ogrid``: 4 n_ang n_rad
particles, horizon 3.01 sqrt(A_i), the FE displacement prescribed on the outer radial layer of the
left and right blocks, docs/theory/conventions.md#plate-with-a-hole).  The paper solves it by ADR
(its Eqs. 75-79) to ‖F‖/‖F_ext‖ < 1e-8; pdlin's ADR (``solve_nonlinear(method="adr")``, one
load step from u = 0 on the free DOFs, ``predictor="previous"``) stops when ``e₁ = ‖r‖/‖r⁰‖`` and
``e₂ = ‖δu‖/‖δu⁰‖`` are both below ``e_l``; ``r⁰`` is the residual of the prescribed field alone,
which plays the part of the paper's F_ext (no body force is applied).  The mass is pdlin's
Gershgorin bound ``¼ Δt² Σ_j |K_ij|`` (x 1.1) of the XOSB stiffness itself with Δt = 1; the
paper bounds it with an LBBPD matrix (its Eqs. 80-87).

Per size and e_l the table prints ADR's iterations, the wall / CPU seconds of the direct solve
(``pdlin.solve(solver="direct")``, assembly included) and of ADR, their ratio, the difference
``max|u_ADR - u_dir| / max|u_dir|`` and the a-priori bound of the stopping rule,
``e_l ‖r⁰‖₂ / σ_min(K_ff)`` relative to ``max|u_dir|`` (σ_min by svds on the LU inverse).
Nothing is asserted (tests/verification/test_seed_cases_xosb_adr.py asserts the agreement).

Usage::

    python benchmarks/bench_adr_xosb.py                    # 4,320 and 7,680 (the paper's count)
    python benchmarks/bench_adr_xosb.py --sizes 32x60 --e-l 1e-6 1e-8
"""

from __future__ import annotations

import argparse
import resource
import sys
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import pdlin
from pdlin.sweeps.problems import plate_with_hole_ogrid
from pdlin.system import constrained_system

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _context import header, timed  # noqa: E402


def sigma_min(Kff: Any) -> float:
    """Smallest singular value of the free-DOF stiffness (largest of its inverse, LU-based)."""
    lu = spla.splu(sp.csc_matrix(Kff))
    n = Kff.shape[0]
    inv = spla.LinearOperator(
        (n, n), matvec=lu.solve, rmatvec=lambda x: lu.solve(x, trans="T"), dtype=float
    )
    s = spla.svds(inv, k=1, return_singular_vectors=False, random_state=0)
    return float(1.0 / s[0])


def compare(prob: pdlin.StaticProblem, e_l: float) -> dict[str, Any]:
    """Direct and ADR solves of one problem, their times and the bound of the stopping rule."""
    with timed() as td:
        direct = pdlin.solve(prob, solver="direct")
    with timed() as ta:
        adr = pdlin.solve_nonlinear(prob, steps=1, method="adr", e_l=e_l, predictor="previous")
    system = constrained_system(prob)
    K = sp.csr_array(system.assemble())
    free = system.free
    Kff = K[free][:, free]
    r0 = (K @ system.prescribed())[free] - system.f_ext[free]
    scale = float(np.abs(direct.u).max())
    return {
        "iterations": int(adr.iterations[0]),
        "e1": float(adr.e1[0]),
        "direct": td,
        "adr": ta,
        "diff": float(np.abs(adr.u[-1] - direct.u).max()) / scale,
        "bound": e_l * float(np.linalg.norm(r0)) / sigma_min(Kff) / scale,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["24x45", "32x60"], help="O-grid n_ang x n_rad")
    ap.add_argument("--e-l", nargs="+", type=float, default=[1e-6, 1e-8])
    ap.add_argument("--linearization", choices=["paper", "energy"], default="paper")
    args = ap.parse_args()
    header()
    print(f"# XOSB plate with a hole, linearization {args.linearization!r}, 1 pdlin thread")
    print(
        "| particles | e_l | ADR iterations | final e₁ | direct wall / CPU s | ADR wall / CPU s "
        "| time ratio ADR/direct wall / CPU | max\\|Δu\\|/max\\|u\\| | bound e_l‖r⁰‖/σ_min "
        "| peak RSS MB |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for size in args.sizes:
        na, nr = (int(v) for v in size.split("x"))
        prob = plate_with_hole_ogrid(
            "xosb", n_ang=na, n_rad=nr, linearization=args.linearization
        ).problem
        pdlin.solve(prob, solver="direct")  # warm-up: numba kernels compile once
        for e_l in args.e_l:
            r = compare(prob, e_l)
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
            print(
                f"| {prob.cloud.n:,} | {e_l:.0e} | {r['iterations']} | {r['e1']:.1e} | "
                f"{r['direct'].wall:.2f} / {r['direct'].cpu:.2f} | "
                f"{r['adr'].wall:.2f} / {r['adr'].cpu:.2f} | "
                f"{r['adr'].wall / r['direct'].wall:.1f} / {r['adr'].cpu / r['direct'].cpu:.1f} | "
                f"{r['diff']:.1e} | "
                f"{r['bound']:.1e} | {rss:.0f} |",
                flush=True,
            )


if __name__ == "__main__":
    pdlin.set_num_threads(1)
    main()
