"""Sparse assembly from bond-structured data (vectorized, no global sort)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from .._kernels import compiled_kernels, use_numba
from .._threads import ptr_chunks, thread_map
from ..errors import InputTypeError, ShapeError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud

__all__ = [
    "assemble_stiffness",
    "bond_pattern_bsr",
    "pair_stiffness_bsr",
    "estimate_bond_operator_bytes",
]

log = logging.getLogger(__name__)

#: bonds per assembly chunk (blocks of one chunk: ~_CHUNK * 72 bytes in 3D)
_CHUNK = 1 << 16


def _index_dtype(n: int) -> type[np.signedinteger]:
    return np.int32 if n < np.iinfo(np.int32).max else np.int64


def bond_pattern_bsr(bonds: Bonds) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Build the block sparsity pattern of a one-hop operator: the bonds plus the diagonal.

    Bonds are already CSR-sorted with increasing ``j`` in each row, so the
    pattern is built by inserting the diagonal block in place (O(nb), no
    sort).

    Parameters
    ----------
    bonds : Bonds
        CSR-sorted bonds of ``n`` points (``nb`` directed bonds).

    Returns
    -------
    indptr : (n + 1,) ndarray
        Block-row pointers.
    indices : (nb + n,) ndarray
        Block-column indices, sorted in each row.
    bond_pos : (nb,) ndarray
        Position of each bond's block in the BSR data array.
    diag_pos : (n,) ndarray
        Position of each diagonal block.
    """
    n = bonds.n_points
    nb = bonds.n_bonds
    idt = _index_dtype(nb + n)
    i = bonds.i
    j = bonds.j
    upper = j > i
    nless = np.bincount(i[~upper], minlength=n)
    bond_pos = np.arange(nb, dtype=np.int64)
    bond_pos += i
    bond_pos += upper
    ar = np.arange(n, dtype=np.int64)
    diag_pos = bonds.indptr[:-1] + ar + nless
    indptr: np.ndarray = (bonds.indptr + np.arange(n + 1, dtype=np.int64)).astype(idt)
    indices: np.ndarray = np.empty(nb + n, dtype=idt)
    indices[bond_pos] = j
    indices[diag_pos] = ar
    return indptr, indices, bond_pos, diag_pos


def pair_stiffness_bsr(
    bonds: Bonds,
    coef: np.ndarray | Callable[[int, int], np.ndarray],
    directions: np.ndarray | None = None,
) -> sp.bsr_array:
    """Assemble ``K`` of a pairwise (bond-based) operator as a BSR array.

    For each directed bond ``b = (i, j)`` with scalar ``k_b = coef[b]`` and
    unit direction ``n_b`` the off-diagonal block is ``K[i, j] = -k_b n nᵀ``
    and the diagonal is ``K[i, i] = sum_j k_b n nᵀ``.  ``coef`` must be
    symmetric over bond pairs for ``K`` to be symmetric.

    Parameters
    ----------
    bonds : Bonds
        The directed bonds (both directions of each pair).
    coef : (nb,) ndarray or callable
        ``k_b`` per bond, or ``coef(b0, b1)`` returning ``k_b`` of the bonds
        ``b0:b1`` (computed chunk by chunk on the worker threads; it must be
        elementwise, so that its values do not depend on the chunking).
    directions : (nb, dim) ndarray, optional
        Unit vectors (default ``xi / |xi|``).

    Returns
    -------
    scipy.sparse.bsr_array
        Shape ``(n*dim, n*dim)``, blocksize ``(dim, dim)``.

    Raises
    ------
    ShapeError
        When an array ``coef`` does not have shape ``(nb,)``.
    """
    d = bonds.dim
    n = bonds.n_points
    nb = bonds.n_bonds
    if not callable(coef) and coef.shape != (nb,):
        raise ShapeError(f"coef must have shape ({nb},), got {coef.shape}")
    bptr = np.asarray(bonds.indptr, dtype=np.int64)
    idt = _index_dtype(nb + n)
    indptr: np.ndarray = (bptr + np.arange(n + 1, dtype=np.int64)).astype(idt)
    indices: np.ndarray = np.empty(nb + n, dtype=idt)
    data = np.empty((nb + n, d, d))
    # rows are processed in chunks of about _CHUNK bonds: the block pattern
    # (bond_pattern_bsr's positions, chunk by chunk: no global position
    # arrays), the per-bond blocks k n nᵀ formed once in a cache-sized
    # buffer and copied to their BSR slots as whole dim x dim blocks, and
    # their per-row sums (the bonds of a row are contiguous) for the
    # diagonal block; everything per chunk releases the GIL (np.add.reduceat, not
    # np.bincount, whose min/max pass holds it)
    chunks = ptr_chunks(bptr, _CHUNK)  # empty rows stay covered
    # with numba: one fused pass per chunk writes each block once (the numpy path below
    # makes component-major temporaries and a strided copy: ~3x the memory traffic, and
    # one thread already saturates the write bandwidth, docs/large_problems.md)
    mod = compiled_kernels() if use_numba(nb * d * d) else None
    fused: Callable[[tuple[int, int]], None] | None = None
    if mod is not None:
        fill = mod.pair_blocks_fill
        unit_given = directions is not None
        bj = bonds.j

        def fused(rows: tuple[int, int]) -> None:
            r0, r1 = rows
            b0, b1 = int(bptr[r0]), int(bptr[r1])
            kb = coef(b0, b1) if callable(coef) else coef[b0:b1]
            kb = np.ascontiguousarray(kb, dtype=np.float64)
            # this chunk's vectors only (a compact Bonds computes them on access)
            if unit_given:
                vec, ln = np.asarray(directions)[b0:b1], np.ones(0)
            else:
                vec, ln = bonds.values("xi", b0, b1), bonds.values("length", b0, b1)
            vec = np.ascontiguousarray(vec, dtype=np.float64)
            fill(r0, r1, bptr, bj, vec, ln, unit_given, kb, b0, indices, data)

    def chunk(rows: tuple[int, int]) -> None:
        r0, r1 = rows
        b0, b1 = int(bptr[r0]), int(bptr[r1])
        jj = bonds.j[b0:b1]
        ii = bonds.values("i", b0, b1)
        upper = jj > ii
        bond_pos = np.arange(b0, b1, dtype=np.int64)
        bond_pos += ii
        bond_pos += upper
        # rows with bonds (np.add.reduceat needs non-empty segments; empty rows sum to 0)
        full = bptr[r0 + 1 : r1 + 1] > bptr[r0:r1]
        seg0 = bptr[r0:r1][full] - b0
        diag_pos = bptr[r0:r1] + np.arange(r0, r1, dtype=np.int64)
        if b1 > b0:  # the diagonal block follows the row's bonds with j < i
            diag_pos[full] += np.add.reduceat(~upper, seg0, dtype=np.int64)
        indices[bond_pos] = jj
        indices[diag_pos] = np.arange(r0, r1)
        if directions is None:
            xl = bonds.values("xi", b0, b1), bonds.values("length", b0, b1)
            unit_t = (xl[0] * (1.0 / xl[1])[:, None]).T
        else:
            unit_t = np.asarray(directions[b0:b1]).T
        # component-major (d, d, m) blocks: contiguous inner loops; same
        # operation order as the component formula (-k n_a) n_b
        kb = coef(b0, b1) if callable(coef) else coef[b0:b1]
        ku_t = unit_t * -kb
        blk_t = np.empty((d, d, b1 - b0))
        np.multiply(ku_t[:, None, :], np.ascontiguousarray(unit_t)[None, :, :], out=blk_t)
        for a in range(d):  # exact symmetry: K[i, j] block b,a reuses entry a,b
            for b in range(a + 1, d):
                blk_t[b, a] = blk_t[a, b]
        data[bond_pos] = blk_t.transpose(2, 0, 1)
        # diagonal: per-row sums of the bond blocks over the contiguous row segments
        # (np.add.reduceat; empty rows, whose segment reduceat cannot express, get 0)
        dsum = np.zeros((r1 - r0, d, d))
        if b1 > b0:
            seg = np.add.reduceat(blk_t.reshape(d * d, b1 - b0), seg0, axis=1)
            np.negative(seg, out=seg)
            dsum[full] = seg.T.reshape(-1, d, d)
        data[diag_pos] = dsum

    # chunks write disjoint slots of indices / data: threads (numpy releases the GIL),
    # the same arithmetic per chunk for any thread count
    thread_map(chunk if fused is None else fused, chunks)
    return sp.bsr_array((data, indices, indptr), shape=(n * d, n * d), blocksize=(d, d))


def estimate_bond_operator_bytes(n_points: int, n_blocks: int, dim: int) -> int:
    """Estimate the bytes of a BSR operator of ``n_blocks`` dim x dim blocks.

    Parameters
    ----------
    n_points : int
        Block rows (points).
    n_blocks : int
        Stored blocks (e.g. bonds plus diagonal).
    dim : int
        Block size.

    Returns
    -------
    int
        float64 data plus the index arrays (int32 below 2³¹ blocks, else int64).
    """
    idx = 4 if n_blocks < np.iinfo(np.int32).max else 8
    return int(n_blocks * (8 * dim * dim + idx) + (n_points + 1) * idx)


def assemble_stiffness(model: Any, cloud: PointCloud, bonds: Bonds) -> sp.sparray:
    """Assemble the linearized stiffness ``K`` of any pdlin model.

    Convention: ``f_int(u) = -K u`` with nodal forces (force density times
    volume), so ``K`` is symmetric for variational models.

    Parameters
    ----------
    model : Model
        A pdlin model (anything with a ``stiffness(cloud, bonds)`` method, e.g.
        :class:`pdlin.BondBased`).
    cloud : PointCloud
        The ``n`` points.
    bonds : Bonds
        Bonds built for ``cloud``.

    Returns
    -------
    scipy.sparse.sparray
        Shape ``(n*dim, n*dim)`` (BSR, blocksize dim for the bundled models).

    Raises
    ------
    InputTypeError
        When ``model`` has no ``stiffness`` method or ``bonds`` is not :class:`~pdlin.Bonds`.
    ShapeError
        When ``bonds`` were built for another number of points or dimension.

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((6, 6), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=3.015)
    >>> K = pdlin.operators.assemble_stiffness(pdlin.BondBased(E=1e9), cloud, bonds)
    >>> K.shape, K.blocksize
    ((72, 72), (2, 2))
    """
    if not hasattr(model, "stiffness"):
        raise InputTypeError(
            f"model must be a pdlin model with a stiffness() method, got {type(model).__name__}"
        )
    if not isinstance(bonds, Bonds):
        raise InputTypeError(f"bonds must be pdlin Bonds, got {type(bonds).__name__}")
    if bonds.n_points != cloud.n or bonds.dim != cloud.dim:
        raise ShapeError(
            f"bonds were built for {bonds.n_points} points in {bonds.dim}D, "
            f"got a cloud of {cloud.n} points in {cloud.dim}D"
        )
    return model.stiffness(cloud, bonds)
