"""Sparsity of the bond-based stiffness matrix versus the horizon ratio m = delta / h.

Prints three tables for 2D and 3D cell-centred grids, all from
:func:`pdlin.analysis.sparsity_report` built from the model and its bonds (the
pattern is the bonds plus the diagonal; ``K`` is never assembled):

1. pattern and memory: nnz, nnz per DOF row (mean / max), CSR and BSR memory
   (MB, bytes per directed bond), half-bandwidth in natural (C) order and
   after reverse Cuthill-McKee, coupling distance in horizons;
2. structural fill-in ``nnz(L) + nnz(U)`` of SuperLU for the natural, COLAMD,
   MMD(A+Aᵀ) and RCM+natural orderings on smaller grids (where affordable);
3. cross-checks of the counts against lattice-point counts (sphere bond counts
   32 ... 1418 for m = 2 ... 7, two-hop stencils); the script exits with status 1 if one
   of them is off.

Usage::

    python benchmarks/sparsity_vs_horizon.py            # full run, about 2 minutes
    python benchmarks/sparsity_vs_horizon.py --quick    # seconds
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

import pdlin
from pdlin.analysis import SparsityReport, coupling_pattern, sparsity_report

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import Timing, header, timed  # noqa: E402

MB = 1024.0**2


def _report(dim: int, n: int, m: float, **kw: object) -> tuple[SparsityReport, Timing]:
    with timed() as t:
        cloud = pdlin.grid((n,) * dim)
        bonds = pdlin.find_bonds(cloud, float(m))
        r = sparsity_report(model=pdlin.BondBased(E=1.0), cloud=cloud, bonds=bonds, **kw)
    return r, t


def pattern_table(dims: list[int], grids: dict[int, int], ms: list[int]) -> None:
    print("\n## 1. Pattern and memory (bond-based, pattern = bonds + diagonal)\n")
    head = (
        f"{'dim':>3} {'m':>2} {'grid':>8} {'DOFs':>8} {'family':>6} {'nnz':>12} "
        f"{'nnz/row':>8} {'max':>5} {'CSR MB':>8} {'BSR MB':>8} {'CSR B/bond':>10} "
        f"{'BSR B/bond':>10} {'bw nat':>7} {'bw RCM':>7} {'reach/delta':>11} {'s':>6} "
        f"{'CPU s':>6}"
    )
    print(head)
    print("-" * len(head))
    for dim in dims:
        n = grids[dim]
        for m in ms:
            r, sec = _report(dim, n, m, fill_limit=0)
            print(
                f"{dim:>3} {m:>2} {f'{n}^{dim}':>8} {r.n:>8,} {r.blocks_per_row_max - 1:>6} "
                f"{r.nnz:>12,} {r.nnz_per_row_mean:>8.1f} {r.nnz_per_row_max:>5} "
                f"{r.memory_csr_bytes / MB:>8.1f} {r.memory_bsr_bytes / MB:>8.1f} "
                f"{r.bytes_per_bond_csr:>10.1f} {r.bytes_per_bond_bsr:>10.1f} "
                f"{r.bandwidth:>7,} {r.bandwidth_rcm:>7,} {r.coupling_range_horizons:>11.3f} "
                f"{sec.wall:>6.2f} {sec.cpu:>6.2f}",
                flush=True,
            )


def fill_table(
    dims: list[int], grids: dict[int, int], ms: list[int], max_m: dict[int, int]
) -> None:
    print("\n## 2. Structural fill-in nnz(L)+nnz(U) of SuperLU (free-floating pattern)\n")
    head = (
        f"{'dim':>3} {'m':>2} {'grid':>6} {'DOFs':>6} {'nnz':>10} {'natural':>11} {'COLAMD':>11} "
        f"{'MMD(A+At)':>11} {'RCM+nat':>11} {'best/nnz':>8} {'n^2/nnz':>9} {'s':>6} {'CPU s':>6}"
    )
    print(head)
    print("-" * len(head))
    for dim in dims:
        n = grids[dim]
        for m in ms:
            label = f"{n}^{dim}"
            if m > max_m[dim]:
                why = f"skipped: m > {max_m[dim]} in {dim}D (factor nearly dense, slow)"
                print(f"{dim:>3} {m:>2} {label:>6} {why:>54}")
                continue
            r, sec = _report(dim, n, m, fill_limit=10**7)
            fills = [r.fill_natural, r.fill_colamd, r.fill_mmd_at_plus_a, r.fill_rcm]
            best = min(f for f in fills if f is not None)
            print(
                f"{dim:>3} {m:>2} {label:>6} {r.n:>6,} {r.nnz:>10,} "
                + " ".join(f"{f:>11,}" for f in fills)
                + f" {best / r.nnz:>8.2f} {r.n * r.n / r.nnz:>9.1f}"
                + f" {sec.wall:>6.2f} {sec.cpu:>6.2f}",
                flush=True,
            )


def cross_checks() -> bool:
    """Compare counts with the provenance numbers; return True if all agree."""
    print("\n## 3. Cross-checks against lattice-point counts\n")
    rows: list[tuple[str, int, int]] = []
    # interior family size at delta = 3.015 h: lattice points 0 < |xi| <= 3.015 h
    for dim, expected in ((2, 28), (3, 122)):
        r, _ = _report(dim, 9, 3.015, fill_limit=0)
        rows.append((f"{dim}D family size, m = 3.015", r.blocks_per_row_max - 1, expected))
    # sphere bond counts, inclusive |xi| <= m, simple cubic lattice (Prakash, anisotropic
    # micromoduli, uses m = 6: 924 bonds); reference values counted by enumeration
    for m, expected in zip(range(2, 8), (32, 122, 256, 514, 924, 1418), strict=True):
        r, _ = _report(3, 2 * m + 1, float(m), fill_limit=0)
        rows.append((f"3D sphere bonds, m = {m}", r.blocks_per_row_max - 1, expected))
    # state-based (two-hop) pattern at delta = 3.01 h, interior point: points within two
    # bonds (the Minkowski sum of the family with itself), counted by enumeration
    for dim, n, coupled, nnz_row in ((2, 15, 105, 210), (3, 13, 829, 2487)):
        cloud = pdlin.grid((n,) * dim)
        P = coupling_pattern(pdlin.find_bonds(cloud, 3.01), 2)
        c = int(np.diff(P.indptr).max())
        rows.append((f"{dim}D two-hop points per row, m = 3.01", c, coupled))
        rows.append((f"{dim}D two-hop nnz per row, m = 3.01", dim * c, nnz_row))
    ok = True
    print(f"{'quantity':<40} {'computed':>9} {'expected':>9}  status")
    print("-" * 68)
    for name, got, exp in rows:
        good = got == exp
        ok &= good
        print(f"{name:<40} {got:>9,} {exp:>9,}  {'ok' if good else 'MISMATCH'}")
    return ok


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small grids, m <= 4 (seconds)")
    p.add_argument("--dims", default="2,3", help="comma-separated dimensions (default 2,3)")
    args = p.parse_args(argv)
    dims = [int(d) for d in args.dims.split(",")]
    if args.quick:
        ms = [1, 2, 3, 4]
        grids = {2: 60, 3: 14}
        fill_grids = {2: 30, 3: 8}
        fill_max_m = {2: 4, 3: 3}
    else:
        ms = [1, 2, 3, 4, 5, 6]
        grids = {2: 200, 3: 30}
        fill_grids = {2: 60, 3: 12}
        fill_max_m = {2: 6, 3: 4}
    print("# sparsity of the bond-based stiffness K vs horizon ratio m = delta / h")
    header(run="quick" if args.quick else "full")
    print(
        "sphere neighbourhood |xi| <= m h (inclusive), cell-centred grid, interleaved DOFs; "
        "family = max bonds per point (interior); 'max' = max nnz per DOF row; "
        "bw = half-bandwidth in DOFs; B/bond = bytes per directed bond"
    )
    with timed() as total:
        pattern_table(dims, grids, ms)
        fill_table(dims, fill_grids, ms, fill_max_m)
        ok = cross_checks()
    print(f"\ntotal {total.wall:.1f} s (CPU {total.cpu:.1f} s)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
