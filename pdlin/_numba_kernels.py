"""numba kernels of :mod:`pdlin._kernels` (imported only when numba is installed).

Work is split into fixed chunks of rows (``prange``); each output row is computed by one
chunk, from the same operands in the same order whatever the thread count, so results are
bitwise identical for 1, 2, ... threads.  The arithmetic is that of scipy's sparsetools
``bsr_matmat`` (each block ``C_ij += A_ik B_kj`` accumulated over the stored ``k`` of row
``i`` in storage order, every entry as ``c + a_0 b_0 + a_1 b_1 ...`` from left to right),
without fused multiply-adds (numba does not enable floating-point contraction by default),
so the values equal scipy's for the same operands; the block columns of each row come out
sorted.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(parallel=True, cache=True)
def bsr_row_counts(a_ptr, a_ind, b_ptr, b_ind, n_bcol, edges):
    """Blocks per output row of ``A @ B`` and block products per row (the work)."""
    n_row = a_ptr.size - 1
    nnz = np.zeros(n_row, np.int64)
    work = np.zeros(n_row, np.int64)
    for c in numba.prange(edges.size - 1):
        mark = np.full(n_bcol, -1, np.int64)
        for i in range(edges[c], edges[c + 1]):
            cnt = 0
            w = 0
            for jj in range(a_ptr[i], a_ptr[i + 1]):
                k = a_ind[jj]
                w += b_ptr[k + 1] - b_ptr[k]
                for kk in range(b_ptr[k], b_ptr[k + 1]):
                    j = b_ind[kk]
                    if mark[j] != i:
                        mark[j] = i
                        cnt += 1
            nnz[i] = cnt
            work[i] = w
    return nnz, work


@numba.njit(inline="always", cache=True)
def _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, R, N, S):
    """Blocks of output row ``i``: ``C_ij += A_ik B_kj`` over the stored ``k`` in order."""
    for jj in range(a_ptr[i], a_ptr[i + 1]):
        k = a_ind[jj]
        for kk in range(b_ptr[k], b_ptr[k + 1]):
            q = pos[b_ind[kk]]
            for r in range(R):
                for s in range(S):
                    acc = c_dat[q, r, s]
                    for t in range(N):
                        acc += a_dat[jj, r, t] * b_dat[kk, t, s]
                    c_dat[q, r, s] = acc


@numba.njit(parallel=True, cache=True)
def bsr_fill(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat, n_bcol, edges):
    """Sorted block columns and blocks of ``C = A @ B`` (``c_ptr`` from the counts)."""
    R = a_dat.shape[1]
    N = a_dat.shape[2]
    S = b_dat.shape[2]
    for c in numba.prange(edges.size - 1):
        pos = np.full(n_bcol, -1, np.int64)
        for i in range(edges[c], edges[c + 1]):
            p0 = c_ptr[i]
            p = p0
            for jj in range(a_ptr[i], a_ptr[i + 1]):
                k = a_ind[jj]
                for kk in range(b_ptr[k], b_ptr[k + 1]):
                    j = b_ind[kk]
                    if pos[j] < p0:  # rows of a chunk run in order: older marks are < p0
                        pos[j] = p
                        c_ind[p] = j
                        p += 1
            c_ind[p0:p].sort()
            for q in range(p0, p):
                pos[c_ind[q]] = q
                for r in range(R):
                    for s in range(S):
                        c_dat[q, r, s] = 0.0
            # constant block sizes for the common cases (LLVM unrolls the block product)
            if R == 1 and N == 1 and S == 1:
                _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, 1, 1, 1)
            elif R == 2 and N == 1 and S == 2:
                _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, 2, 1, 2)
            elif R == 3 and N == 1 and S == 3:
                _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, 3, 1, 3)
            elif R == 2 and N == 3 and S == 2:
                _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, 2, 3, 2)
            elif R == 3 and N == 6 and S == 3:
                _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, 3, 6, 3)
            elif R == 2 and N == 4 and S == 2:
                _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, 2, 4, 2)
            elif R == 3 and N == 9 and S == 3:
                _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, 3, 9, 3)
            else:
                _row_product(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_dat, pos, i, R, N, S)


@numba.njit(parallel=True, cache=True)
def csr_t_block_counts(indptr, indices, d, n_pts, edges):
    """Blocks per (row chunk, point) of ``Xᵀ`` in ``d x 1`` blocks: ``(n_chunks, n_pts)``.

    A block is one (row of ``X``, point ``p``) pair with a stored entry in the columns
    ``p d .. p d + d - 1``.
    """
    n_chunks = edges.size - 1
    cnt = np.zeros((n_chunks, n_pts), np.int64)
    for c in numba.prange(n_chunks):
        mark = np.full(n_pts, -1, np.int64)
        for r in range(edges[c], edges[c + 1]):
            for jj in range(indptr[r], indptr[r + 1]):
                p = indices[jj] // d
                if mark[p] != r:
                    mark[p] = r
                    cnt[c, p] += 1
    return cnt


@numba.njit(cache=True)
def csr_t_block_offsets(cnt):
    """Row pointer of ``Xᵀ`` (per point) and each chunk's first slot per point."""
    n_chunks, n_pts = cnt.shape
    ptr = np.zeros(n_pts + 1, np.int64)
    off = np.empty((n_chunks, n_pts), np.int64)
    acc = 0
    for p in range(n_pts):
        for c in range(n_chunks):
            off[c, p] = acc
            acc += cnt[c, p]
        ptr[p + 1] = acc
    return ptr, off


@numba.njit(parallel=True, cache=True)
def csr_t_block_fill(indptr, indices, data, d, off, edges, row0, out_ind, out_dat):
    """Blocks of ``Xᵀ`` (``d x 1``): each chunk fills its own slots, rows in order.

    Within a point the chunks' slots follow each other and a chunk's rows run in order,
    so the block columns (rows of ``X``, ``row0`` + local row: the piece's first row in
    a vertical stack) come out sorted; each block is ``0 + x₁ + x₂ ...`` over the stored
    entries in storage order, as scipy's ``tobsr`` sums them.
    """
    n_chunks = edges.size - 1
    n_pts = off.shape[1]
    for c in numba.prange(n_chunks):
        mark = np.full(n_pts, -1, np.int64)
        slot = np.empty(n_pts, np.int64)
        pos = off[c].copy()
        for r in range(edges[c], edges[c + 1]):
            for jj in range(indptr[r], indptr[r + 1]):
                col = indices[jj]
                p = col // d
                if mark[p] != r:
                    mark[p] = r
                    q = pos[p]
                    pos[p] = q + 1
                    slot[p] = q
                    out_ind[q] = row0 + r
                    for k in range(d):
                        out_dat[q, k, 0] = 0.0
                    if d == 1:  # scipy copies 1 x 1 blocks (keeps -0.0)
                        out_dat[q, 0, 0] = data[jj]
                        continue
                out_dat[slot[p], col - p * d, 0] += data[jj]


@numba.njit(parallel=True, cache=True)
def csr_row_block_counts(indptr, indices, d, n_pts, edges):
    """Blocks per row of ``Y`` in ``1 x d`` blocks (distinct points per row)."""
    n_row = indptr.size - 1
    nnz = np.zeros(n_row, np.int64)
    for c in numba.prange(edges.size - 1):
        mark = np.full(n_pts, -1, np.int64)
        for r in range(edges[c], edges[c + 1]):
            cnt = 0
            for jj in range(indptr[r], indptr[r + 1]):
                p = indices[jj] // d
                if mark[p] != r:
                    mark[p] = r
                    cnt += 1
            nnz[r] = cnt
    return nnz


@numba.njit(parallel=True, cache=True)
def csr_row_block_fill(indptr, indices, data, d, n_pts, out_ptr, edges, out_ind, out_dat):
    """Blocks of ``Y`` (``1 x d``) in order of first appearance, as scipy's ``tobsr``."""
    for c in numba.prange(edges.size - 1):
        mark = np.full(n_pts, -1, np.int64)
        slot = np.empty(n_pts, np.int64)
        for r in range(edges[c], edges[c + 1]):
            q = out_ptr[r]
            for jj in range(indptr[r], indptr[r + 1]):
                col = indices[jj]
                p = col // d
                if mark[p] != r:
                    mark[p] = r
                    slot[p] = q
                    out_ind[q] = p
                    for k in range(d):
                        out_dat[q, 0, k] = 0.0
                    q += 1
                    if d == 1:  # scipy copies 1 x 1 blocks (keeps -0.0)
                        out_dat[q - 1, 0, 0] = data[jj]
                        continue
                out_dat[slot[p], 0, col - p * d] += data[jj]


@numba.njit(parallel=True, cache=True)
def bsr_t_fill(indptr, indices, data, off, edges, out_ind, out_dat):
    """Blocks of ``Aᵀ`` (BSR, each block transposed): each chunk fills its own slots.

    ``off`` from :func:`csr_t_block_offsets` of the block pattern; block columns (rows of
    ``A``) come out sorted, as scipy's ``bsr_transpose`` leaves them.
    """
    R = data.shape[1]
    C = data.shape[2]
    for c in numba.prange(edges.size - 1):
        pos = off[c].copy()
        for r in range(edges[c], edges[c + 1]):
            for jj in range(indptr[r], indptr[r + 1]):
                k = indices[jj]
                q = pos[k]
                pos[k] = q + 1
                out_ind[q] = r
                for a in range(R):
                    for b in range(C):
                        out_dat[q, b, a] = data[jj, a, b]


@numba.njit(nogil=True, cache=True)
def pair_blocks_fill(
    r0, r1, bptr, bj, vec, length, unit_given, kb, kb0, indices, data
):  # pragma: no cover
    """Blocks of the rows ``r0:r1`` of a pairwise operator, written once into the BSR slots.

    Bond ``b = (r, j)`` of row ``r`` (bonds CSR-sorted, increasing ``j``) gets the block
    ``-k_b n nᵀ`` (``k_b = kb[b - kb0]``; ``n = vec[b]`` when ``unit_given``, else
    ``vec[b] * (1 / length[b])``) at slot ``b + r`` (``+ 1`` past the diagonal when
    ``j > r``); the diagonal block is the negated sum of the row's blocks in bond order
    (``+0`` for a row without bonds). Serial (``nogil``): the caller runs disjoint row
    chunks on its threads. The arithmetic is the numpy path's (``(n_a * -k_b) * n_c``, the
    lower triangle copied from the upper, sums in bond order).
    """
    d = vec.shape[1]
    acc = np.empty((d, d))
    n = np.empty(d)
    for r in range(r0, r1):
        b0 = bptr[r]
        b1 = bptr[r + 1]
        acc[:, :] = 0.0
        nless = 0
        for b in range(b0, b1):
            j = bj[b]
            pos = b + r
            if j > r:
                pos += 1
            else:
                nless += 1
            indices[pos] = j
            if unit_given:
                for a in range(d):
                    n[a] = vec[b, a]
            else:
                inv = 1.0 / length[b]
                for a in range(d):
                    n[a] = vec[b, a] * inv
            mk = -kb[b - kb0]
            for a in range(d):
                ka = n[a] * mk
                for c in range(a, d):
                    v = ka * n[c]
                    data[pos, a, c] = v
                    acc[a, c] += v
                    if c > a:
                        data[pos, c, a] = v
        diag = b0 + r + nless
        indices[diag] = r
        for a in range(d):
            for c in range(a, d):
                v = -acc[a, c] if b1 > b0 else 0.0
                data[diag, a, c] = v
                if c > a:
                    data[diag, c, a] = v
