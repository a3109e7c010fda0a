"""Symmetric (upper-triangle) storage of the bond-based K: bytes saved, SpMV cost (issue 33).

Assembles the 3D bond-based K of an m³ cube (δ = 3.015 h), keeps its upper block triangle
and applies ``K x = U x + Uᵀ x - D x`` with scipy, against the full BSR product.  Prints the
bytes per directed bond of both storages and the milliseconds per product.

    python benchmarks/bench_symmetric_storage.py [m]
"""

from __future__ import annotations

import sys
import time

import numpy as np
import scipy.sparse as sp

import pdlin
from pdlin.operators import assemble_stiffness


def _nbytes(a: sp.sparray) -> int:
    parts = [a.data, a.indices, a.indptr]  # type: ignore[attr-defined]
    return sum(int(p.nbytes) for p in parts)


def _per_call(f, n: int = 20) -> float:  # type: ignore[no-untyped-def]
    f()
    t0 = time.perf_counter()
    for _ in range(n):
        f()
    return (time.perf_counter() - t0) / n


def main() -> None:
    from _context import header  # benchmarks/_context.py: load, cores, BLAS, threads

    header()
    m = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    cloud = pdlin.grid((m, m, m), spacing=1.0 / m)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    K = sp.bsr_array(assemble_stiffness(pdlin.BondBased(E=1e9), cloud, bonds))
    coo = K.tocoo()
    br, bc = coo.row // 3, coo.col // 3
    upper = br <= bc
    U = sp.coo_array((coo.data[upper], (coo.row[upper], coo.col[upper])), shape=K.shape).tobsr(
        blocksize=(3, 3)
    )
    on = br == bc
    D = sp.coo_array((coo.data[on], (coo.row[on], coo.col[on])), shape=K.shape).tocsr()
    x = np.random.default_rng(0).standard_normal(K.shape[0])

    def sym() -> np.ndarray:
        return U @ x + U.T @ x - D @ x

    diff = float(np.abs(K @ x - sym()).max() / np.abs(K @ x).max())
    nb = bonds.n_bonds
    print("| m | directed bonds | full K B/bond | upper + diagonal B/bond | full SpMV ms | "
          "symmetric SpMV ms | max rel. diff |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    print(f"| {m} | {nb:,} | {_nbytes(K) / nb:.1f} | {(_nbytes(U) + _nbytes(D)) / nb:.1f} | "
          f"{_per_call(lambda: K @ x) * 1e3:.1f} | {_per_call(sym) * 1e3:.1f} | "
          f"{diff:.1e} |")  # fmt: skip


if __name__ == "__main__":
    main()
