"""The 3D soft precipitate of Javaheri, Luo, Lakshmanan & Sundararaghavan (2022), Sec. III.C (48³).

The paper's Example C at its size: a 3 mm cube of 48³ particles (h = 62.5 µm) of transversely
isotropic Mg (C11 = 59.3, C12 = 25.7, C13 = 21.4, C33 = 61.5, C44 = 16.4 GPa) with a central sphere
of diameter 0.875 mm and 0.1 times the matrix stiffness, pulled by the inward shadow layer
(``pdlin.models.shadow_problem``, the paper's Sec. II.D) carrying ``F = I + 0.02 diag(1, -0.5,
-0.5)``; c ∥ z and the corner origin are pdlin's reading (docs/theory/conventions.md).  The paper's
Figs. 16-18 carry no numbers; each row prints the centreline measures of docs/weights.md (y = z =
index 24, µm): ``raw = max|Δ²u_x|``, ``filt`` the same after a 2-point average, ``dev = max|u_x -
affine|``, beside those of an independent implementation of the same reconstruction (static CG to
1e-10; the table of docs/weights.md), the CG iterations of ``pdlin.solve(prob, rtol=1e-10)``
(AMG-CG), the CPU and wall seconds and the peak RSS of the row (each row in a forked child).

Rows: ``h`` (δ = h), ``ho2`` / ``ho3`` (the paper's higher-order weights at δ = 2h / 3h,
``control='higher_order'``), ``none2`` / ``none3`` (no control, ``ω = 1/|ξ|``).  Nothing is
asserted (the δ = h and HO 2h rows are tests/verification/test_seed_cases_precipitate.py).

Usage::

    python benchmarks/bench_precipitate.py                 # rows ho3 (the default)
    python benchmarks/bench_precipitate.py --rows h ho2 ho3 none2 none3
    python benchmarks/bench_precipitate.py --n 24 --rows h ho2 ho3   # coarse, no reference
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import pdlin
from pdlin.constitutive import transversely_isotropic
from pdlin.models import shadow_problem

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _context import fork_call, header  # noqa: E402

#: row -> (δ/h, control, influence)
ROWS = {
    "h": (1, "higher_order", "constant"),
    "ho2": (2, "higher_order", "constant"),
    "ho3": (3, "higher_order", "constant"),
    "none2": (2, "none", "inverse"),
    "none3": (3, "none", "inverse"),
}
LABEL = {
    "h": "δ = h",
    "ho2": "HO 2h",
    "ho3": "HO 3h",
    "none2": "no control 2h (ω = 1/|ξ|)",
    "none3": "no control 3h (ω = 1/|ξ|)",
}
#: raw / filt / dev (µm) of the independent implementation at 48³ (docs/weights.md's table)
REFERENCE_48 = {
    "h": (4.82, 1.62, 7.73),
    "ho2": (4.71, 1.30, 7.84),
    "ho3": (5.04, 1.17, 7.67),
    "none2": (20.5, 8.48, 11.6),
    "none3": (79.7, 24.6, 27.1),
}


def centreline(row: str, n: int) -> dict[str, Any]:
    """Solve one row at n³ and measure its centreline; CPU / wall s, CG iterations, peak RSS."""
    t0, c0 = time.perf_counter(), time.process_time()
    m, control, influence = ROWS[row]
    C = transversely_isotropic(C11=59.3, C33=61.5, C12=25.7, C13=21.4, C44=16.4)
    h = 3.0 / n
    cloud = pdlin.grid((n, n, n), spacing=h)
    inside = np.linalg.norm(cloud.points - 1.5, axis=1) <= 0.875 / 2
    cloud = cloud.replace(material=inside.astype(int))
    bonds = pdlin.find_bonds(cloud, ratio=float(m), influence=influence)
    model = pdlin.Correspondence({0: C, 1: 0.1 * C}, control=control)
    F = np.eye(3) + 0.02 * np.diag([1.0, -0.5, -0.5])
    prob = shadow_problem(model, cloud, bonds, F)
    res = pdlin.solve(prob, rtol=1e-10)
    ij = np.rint(cloud.points / h - 0.5).astype(int)
    line = np.flatnonzero((ij[:, 1] == n // 2) & (ij[:, 2] == n // 2))
    line = np.setdiff1d(line, prob.model.shadow)
    line = line[np.argsort(cloud.points[line, 0])]
    ux = 1e3 * res.u[line, 0]  # mm -> µm
    affine = 1e3 * 0.02 * cloud.points[line, 0]
    return {
        "raw": float(np.abs(np.diff(ux, 2)).max()),
        "filt": float(np.abs(np.diff(0.5 * (ux[1:] + ux[:-1]), 2)).max()),
        "dev": float(np.abs(ux - affine).max()),
        "iters": int(res.n_iter),
        "operator": str(res.info.get("operator", "?")),
        "solver": str(res.info.get("solver", "?")),
        "cpu": time.process_time() - c0,
        "wall": time.perf_counter() - t0,
        "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0**2,
    }


def forked(*args: Any) -> dict[str, Any]:
    """:func:`centreline` in a forked child (its own peak RSS); a failure as ``{"failed": ...}``."""
    out = fork_call(centreline, *args)
    return {"failed": out} if isinstance(out, str) else dict(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=48, help="particles per side (the paper: 48)")
    ap.add_argument("--rows", nargs="+", default=["ho3"], choices=list(ROWS))
    ap.add_argument("--threads", type=int, default=2, help="pdlin threads (default 2)")
    args = ap.parse_args()
    pdlin.set_num_threads(args.threads)
    header()
    print(
        f"# soft precipitate, {args.n}³ particles, pdlin.solve(rtol=1e-10), "
        f"{args.threads} pdlin thread(s); reference: independent implementation at 48³"
    )
    print(
        "| weights | raw / filt / dev, reference | raw / filt / dev, pdlin | CG iterations "
        "| operator | CPU s | wall s | peak RSS GB |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for row in args.rows:
        r = forked(row, args.n)
        ref = REFERENCE_48[row] if args.n == 48 else None
        ref_s = " / ".join(f"{v:.3g}" for v in ref) if ref else "—"
        if "failed" in r:
            print(f"| {LABEL[row]} | {ref_s} | failed: {r['failed']} | | | | | |", flush=True)
            continue
        print(
            f"| {LABEL[row]} | {ref_s} | {r['raw']:.3f} / {r['filt']:.3f} / {r['dev']:.3f} | "
            f"{r['iters']} | {r['operator']} | {r['cpu']:.0f} | {r['wall']:.0f} | "
            f"{r['rss']:.2f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
