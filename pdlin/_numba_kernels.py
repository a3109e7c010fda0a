"""numba kernels of :mod:`pdlin._kernels` (imported only when numba is installed).

Work is split into fixed chunks of rows (``prange``); each output row is computed by one
chunk, from the same operands in the same order whatever the thread count, so results are
bitwise identical for 1, 2, ... threads.  The arithmetic is that of scipy's sparsetools
``bsr_matmat`` (each block ``C_ij += A_ik B_kj`` accumulated over the stored ``k`` of row
``i`` in storage order, every entry as ``c + a_0 b_0 + a_1 b_1 ...`` from left to right),
without fused multiply-adds (numba does not enable floating-point contraction by default),
so the values equal scipy's for the same operands; the block columns of each row come out
sorted.

The ``nogil`` kernels without ``prange`` (``*_fill``, ``cell_pairs``, ...) are serial: their
callers run disjoint chunks of rows, points or bonds on pdlin's thread pool
(:func:`pdlin._threads.thread_map`), each chunk writing only its own slots, and each repeats
the numpy path's arithmetic in its order (sums in bond order, no contraction), so their
arrays equal the numpy path's bitwise for any chunking and thread count.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from numba.core import caching as _caching

# --- where the compiled kernels are cached on disk --------------------------------------
# numba's default (``cache=True``) writes ``.nbi`` / ``.nbc`` files next to the source, into
# ``site-packages/pdlin/__pycache__``: ``pip uninstall`` does not remove them, and the
# folder left behind is then imported as an empty namespace package that shadows the next
# (editable) install.  pdlin's kernels are cached per user instead, in
# ``$XDG_CACHE_HOME/pdlin/numba`` (default ``~/.cache/pdlin/numba``), or in numba's
# ``NUMBA_CACHE_DIR`` where the user set one; without a writable directory, not on disk.
# Only pdlin's functions use this locator: numba's behaviour for other code is unchanged.

#: numba's locator of ``NUMBA_CACHE_DIR`` (``_UserProvidedCacheLocator`` in older numba)
_UserProvided: Any = getattr(_caching, "UserProvidedCacheLocator", None)
if _UserProvided is None:  # pragma: no cover - older numba
    _UserProvided = vars(_caching)["_UserProvidedCacheLocator"]


def cache_dir() -> str | None:
    """Return pdlin's per-user numba cache directory (created), or None where not writable.

    ``$XDG_CACHE_HOME/pdlin/numba``, by default ``~/.cache/pdlin/numba``.

    Examples
    --------
    >>> from pdlin._numba_kernels import cache_dir
    >>> path = cache_dir()
    >>> path is None or path.endswith("numba")
    True
    """
    base = os.environ.get("XDG_CACHE_HOME", "").strip() or os.path.join(
        os.path.expanduser("~"), ".cache"
    )
    path = os.path.join(base, "pdlin", "numba")
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return None
    return path


_CACHE_DIR = cache_dir()


class _PdlinCacheLocator(_UserProvided):
    """numba's ``NUMBA_CACHE_DIR`` locator pointed at :func:`cache_dir`."""

    def __init__(self, py_func: Any, py_file: str) -> None:
        super().__init__(py_func, py_file)
        assert _CACHE_DIR is not None
        self._cache_path = os.path.join(_CACHE_DIR, self.get_suitable_cache_subpath(py_file))

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        if _CACHE_DIR is None:
            return None
        # the source-file mixin's checks (file exists, directory writable), not config's
        return super(_UserProvided, cls).from_function(py_func, py_file)


class _PdlinCacheImpl(_caching.CompileResultCacheImpl):
    _locator_classes = [_UserProvided, _PdlinCacheLocator]


class _PdlinFunctionCache(_caching.FunctionCache):
    _impl_class = _PdlinCacheImpl


def _njit(**options: Any) -> Callable[[Any], Any]:
    """``numba.njit(**options)`` cached in :func:`cache_dir` (not in the package folder).

    Functions inlined into their callers (``inline="always"``) are not cached on their own.
    """

    def wrap(func: Any) -> Any:
        disp = numba.njit(**options)(func)
        if options.get("inline") != "always":
            try:
                # what numba's ``enable_caching`` does, with pdlin's locator
                disp._cache = _PdlinFunctionCache(disp.py_func)
            except RuntimeError:  # no locator: neither NUMBA_CACHE_DIR nor cache_dir()
                pass
        return disp

    return wrap


@_njit(parallel=True)
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


@_njit(inline="always")
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


@_njit(parallel=True)
def bsr_fill(a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat, n_bcol, edges):
    """Sorted block columns and blocks of ``C = A @ B`` (``c_ptr`` from the counts)."""
    size = np.empty(0)
    for c in numba.prange(edges.size - 1):
        _fill_chunk(
            a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat, n_bcol,
            edges[c], edges[c + 1], False, size, size,
        )  # fmt: skip


@_njit(parallel=True)
def bsr_fill_sizes(
    a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat, n_bcol, edges, size, dsize
):
    """Run :func:`bsr_fill` and also write the block sizes while each row is in cache.

    ``size[q] = max |C block q|`` and ``dsize[i]``, that of row ``i``'s diagonal block (0
    without one).
    """
    for c in numba.prange(edges.size - 1):
        _fill_chunk(
            a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat, n_bcol,
            edges[c], edges[c + 1], True, size, dsize,
        )  # fmt: skip


@_njit()
def _fill_chunk(
    a_ptr,
    a_ind,
    a_dat,
    b_ptr,
    b_ind,
    b_dat,
    c_ptr,
    c_ind,
    c_dat,
    n_bcol,
    i0,
    i1,
    sizes,
    size,
    dsize,
):
    """Rows ``i0:i1`` of :func:`bsr_fill` (with the block sizes when ``sizes``)."""
    R = a_dat.shape[1]
    N = a_dat.shape[2]
    S = b_dat.shape[2]
    pos = np.full(n_bcol, -1, np.int64)
    for i in range(i0, i1):
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
        if sizes:
            _row_block_sizes(i, p0, p, c_ind, c_dat, size, dsize)


@_njit(inline="always")
def _row_block_sizes(r, k0, k1, ind, data, size, dsize):  # pragma: no cover
    """Write ``size[k] = max |block k|`` for the blocks ``k0:k1`` of block row ``r``.

    ``dsize[r]`` gets that of its diagonal block (0 when it has none).
    """
    dsize[r] = 0.0
    for k in range(k0, k1):
        m = 0.0
        for a in range(data.shape[1]):
            for b in range(data.shape[2]):
                v = abs(data[k, a, b])
                if v > m:
                    m = v
        size[k] = m
        if ind[k] == r:
            dsize[r] = m


@_njit(parallel=True)
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


@_njit()
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


@_njit(parallel=True)
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


@_njit(parallel=True)
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


@_njit(parallel=True)
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


@_njit(parallel=True)
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


@_njit(nogil=True)
def pair_blocks_fill(
    r0, r1, bptr, bj, vec, length, unit_given, kb, kb0, indices, data
):  # pragma: no cover
    """Blocks of the rows ``r0:r1`` of a pairwise operator, written once into the BSR slots.

    Bond ``b = (r, j)`` of row ``r`` (bonds CSR-sorted, increasing ``j``) gets the block
    ``-k_b n nᵀ`` (``k_b = kb[b - kb0]``; ``n = vec[b - kb0]`` when ``unit_given``, else
    ``vec[b - kb0] * (1 / length[b - kb0])``: the chunk's own arrays) at slot ``b + r``
    (``+ 1`` past the diagonal when ``j > r``); the diagonal block is the negated sum of
    the row's blocks in bond order (``+0`` for a row without bonds). Serial (``nogil``):
    the caller runs disjoint row chunks on its threads. The arithmetic is the numpy path's
    (``(n_a * -k_b) * n_c``, the lower triangle copied from the upper, sums in bond order).
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
                    n[a] = vec[b - kb0, a]
            else:
                inv = 1.0 / length[b - kb0]
                for a in range(d):
                    n[a] = vec[b - kb0, a] * inv
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


@_njit(nogil=True)
def outer_sums_fill(p0, p1, b0, b1, owner, w, a, b, out):  # pragma: no cover
    """``out[p] = Σ w a ⊗ b`` over the bonds ``b0:b1`` of the owners ``p0:p1``.

    Serial (``nogil``): the caller runs disjoint (owner, bond) runs on its threads. Each
    sum is ``0 + (w a_r) b_c + ...`` in bond order, ``np.bincount``'s arithmetic.
    """
    d = a.shape[1]
    for p in range(p0, p1):
        for r in range(d):
            for c in range(d):
                out[p, r, c] = 0.0
    for e in range(b0, b1):
        p = owner[e]
        for r in range(d):
            wa = w[e] * a[e, r]
            for c in range(d):
                out[p, r, c] += wa * b[e, c]


@_njit(nogil=True)
def bond_coefficients_fill(b0, b1, owner, w, xi, kinv, out):  # pragma: no cover
    """``out[e] = w_e K⁻¹_g ξ_e`` (``g = owner[e]``) for the bonds ``b0:b1``.

    Each component is ``w (0 + K⁻¹_a0 ξ_0 + K⁻¹_a1 ξ_1 ...)``: the numpy path's order.
    """
    d = xi.shape[1]
    for e in range(b0, b1):
        g = owner[e]
        for r in range(d):
            s = 0.0
            for q in range(d):
                s += kinv[g, r, q] * xi[e, q]
            out[e, r] = w[e] * s


@_njit(nogil=True)
def gradient_blocks_fill(
    p0,
    p1,
    bptr,
    gptr,
    gp_of_bond,
    j,
    c,
    indptr,
    col,
    val,
    is_diag,
    bond_block,
    owner_block,
    tiny,
    layout_ok,
):  # pragma: no cover
    """Blocks of the gradient points of the points ``p0:p1`` (correspondence ``G``).

    Point ``p`` owns the gradient points ``gptr[p]:gptr[p+1]`` and the bonds
    ``bptr[p]:bptr[p+1]`` (increasing neighbours ``j != p``); gradient point ``g`` gets one
    block per bond (value ``c_e``, column ``j_e``) and the owner's block (column ``p``,
    value ``-Σ c`` in bond order, snapped to 0 where ``|Σ c| <= tiny Σ |c|``) in column
    order from ``indptr[g]``. The values are those of the sorting path. ``layout_ok[p]`` is
    False when a bond of ``p`` breaks that layout (neighbours not increasing, or ``p``
    itself): the caller then discards the blocks.
    """
    d = c.shape[1]
    dsum = np.empty(d)
    ssum = np.empty(d)
    for p in range(p0, p1):
        b0 = bptr[p]
        b1 = bptr[p + 1]
        ok = True
        for e in range(b0, b1):
            if j[e] == p or (e > b0 and j[e] <= j[e - 1]):
                ok = False
        layout_ok[p] = ok
        for g in range(gptr[p], gptr[p + 1]):
            base = indptr[g]
            k = 0
            nless = 0
            for q in range(d):
                dsum[q] = 0.0
                ssum[q] = 0.0
            for e in range(b0, b1):
                if gp_of_bond[e] != g:
                    continue
                jj = j[e]
                pos = base + k
                if jj > p:
                    pos += 1
                else:
                    nless += 1
                k += 1
                bond_block[e] = pos
                col[pos] = jj
                is_diag[pos] = False
                for q in range(d):
                    v = c[e, q]
                    val[pos, q] = v
                    dsum[q] += v
                    ssum[q] += abs(v)
            dpos = base + nless
            owner_block[g] = dpos
            col[dpos] = p
            is_diag[dpos] = True
            for q in range(d):
                v = -dsum[q]
                if abs(v) <= tiny * ssum[q]:
                    v = 0.0
                val[dpos, q] = v


@_njit(nogil=True)
def half_space_fill(b0, b1, xi, basis, vnorm, out):  # pragma: no cover
    """Stress-point sides of the bonds ``b0:b1`` for every case (``out[s, e]``).

    Case ``s`` puts bond ``e`` on side 1 when the first basis vector ``v`` of the case
    with ``|ξ·v| > 1e-9 |ξ| |v|`` has ``ξ·v > 0`` (``basis (n_cases, m, d)``, ``vnorm``
    their norms).
    """
    n_cases = basis.shape[0]
    m = basis.shape[1]
    d = xi.shape[1]
    for e in range(b0, b1):
        nrm = 0.0
        for q in range(d):
            nrm += xi[e, q] * xi[e, q]
        tol = 1e-9 * np.sqrt(nrm)
        for s in range(n_cases):
            key = 0.0
            for k in range(m):
                proj = 0.0
                for q in range(d):
                    proj += xi[e, q] * basis[s, k, q]
                if abs(proj) > tol * vnorm[s, k]:
                    key = proj
                    break
            out[s, e] = key > 0.0


@_njit(inline="always")
def _ratio_ok_2d(a, b, c, min_ratio):  # pragma: no cover
    mid = 0.5 * (a + c)
    rad = np.hypot(0.5 * (a - c), b)
    return mid - rad >= min_ratio * max(mid + rad, 1e-300)


@_njit(nogil=True)
def sp_halves_2d(p0, p1, bptr, xi, wv, geo, sides, min_ratio, bal_tol, ok):  # pragma: no cover
    """Flag the points ``p0:p1`` (2D) whose half families are usable in every case.

    In every case both half families' shape tensors must be well conditioned
    (``λ_min/λ_max >= min_ratio``) and balanced (``‖2 K_1 - K‖_F <= bal_tol ‖K‖_F`` on
    the ``geo`` weights): ``_halves_well_conditioned`` per point chunk.
    """
    n_cases = sides.shape[0]
    for p in range(p0, p1):
        b0 = bptr[p]
        b1 = bptr[p + 1]
        k00 = k01 = k11 = 0.0
        g00 = g01 = g11 = 0.0
        for e in range(b0, b1):
            x0 = xi[e, 0]
            x1 = xi[e, 1]
            k00 += wv[e] * x0 * x0
            k01 += wv[e] * x0 * x1
            k11 += wv[e] * x1 * x1
            g00 += geo[e] * x0 * x0
            g01 += geo[e] * x0 * x1
            g11 += geo[e] * x1 * x1
        scale = np.sqrt(g00 * g00 + 2.0 * g01 * g01 + g11 * g11)
        good = True
        for s in range(n_cases):
            h00 = h01 = h11 = 0.0
            q00 = q01 = q11 = 0.0
            for e in range(b0, b1):
                if sides[s, e]:
                    x0 = xi[e, 0]
                    x1 = xi[e, 1]
                    h00 += wv[e] * x0 * x0
                    h01 += wv[e] * x0 * x1
                    h11 += wv[e] * x1 * x1
                    q00 += geo[e] * x0 * x0
                    q01 += geo[e] * x0 * x1
                    q11 += geo[e] * x1 * x1
            d00 = 2.0 * q00 - g00
            d01 = 2.0 * q01 - g01
            d11 = 2.0 * q11 - g11
            balanced = np.sqrt(d00 * d00 + 2.0 * d01 * d01 + d11 * d11) <= bal_tol * scale
            if not (
                balanced
                and _ratio_ok_2d(h00, h01, h11, min_ratio)
                and _ratio_ok_2d(k00 - h00, k01 - h01, k11 - h11, min_ratio)
            ):
                good = False
                break
        ok[p] = good


@_njit(nogil=True)
def block_sizes_fill(r0, r1, ptr, ind, data, size, dsize):  # pragma: no cover
    """Write ``size[k] = max |block k|`` for the blocks of the block rows ``r0:r1``.

    ``dsize[r]`` gets that of row ``r``'s diagonal block (0 when it has none).
    """
    for r in range(r0, r1):
        _row_block_sizes(r, ptr[r], ptr[r + 1], ind, data, size, dsize)


@_njit(nogil=True)
def block_keep_fill(r0, r1, ptr, ind, size, dsize, eps2, keep, counts):  # pragma: no cover
    """Keep a block when ``size² > eps2 dsize[r] dsize[c]`` or it is diagonal; kept per row."""
    for r in range(r0, r1):
        cnt = 0
        for k in range(ptr[r], ptr[r + 1]):
            c = ind[k]
            kp = c == r or size[k] * size[k] > eps2 * (dsize[r] * dsize[c])
            keep[k] = kp
            if kp:
                cnt += 1
        counts[r] = cnt


@_njit(nogil=True)
def block_compress_fill(
    r0, r1, ptr, ind, data, keep, out_ptr, out_ind, out_dat
):  # pragma: no cover
    """Copy the kept blocks of the rows ``r0:r1`` to their slots from ``out_ptr``."""
    R = data.shape[1]
    C = data.shape[2]
    for r in range(r0, r1):
        q = out_ptr[r]
        for k in range(ptr[r], ptr[r + 1]):
            if keep[k]:
                out_ind[q] = ind[k]
                for a in range(R):
                    for b in range(C):
                        out_dat[q, a, b] = data[k, a, b]
                q += 1


@_njit(nogil=True)
def rows_with_diagonal(r0, r1, ptr, ind, has):  # pragma: no cover
    """``has[r]``: block row ``r`` of a BSR array stores its diagonal block."""
    for r in range(r0, r1):
        h = False
        for k in range(ptr[r], ptr[r + 1]):
            if ind[k] == r:
                h = True
                break
        has[r] = h


@_njit(nogil=True)
def sp_gp_of_bond(p0, p1, bptr, base, full, chosen, first, out):  # pragma: no cover
    """Write the gradient point of each bond of the points ``p0:p1``.

    That is ``base[p]``, plus 1 (stress point 2) when ``p`` has two and the bond is not on
    side 1 of ``p``'s case.
    """
    for p in range(p0, p1):
        for e in range(bptr[p], bptr[p + 1]):
            out[e] = base[p] + (1 if full[p] and not first[chosen[p], e] else 0)


@_njit(nogil=True)
def coefficients_2d_fill(p0, p1, bptr, gptr, owner, w, xi, K, bad, out):  # pragma: no cover
    """Compute the 2D bond coefficients ``w_e K_g⁻¹ ξ_e`` of the points ``p0:p1`` in one pass.

    Shape tensors ``K_g`` (sums in bond order), their inverses (adjugate / det) and the
    coefficients, with the arithmetic of the numpy path; ``bad[g]`` flags a singular
    ``K_g`` (``|det| <= 1e-12 (|tr| / 2)²``), whose coefficients are left unset.
    """
    for p in range(p0, p1):
        g0 = gptr[p]
        g1 = gptr[p + 1]
        for g in range(g0, g1):
            K[g, 0, 0] = 0.0
            K[g, 0, 1] = 0.0
            K[g, 1, 0] = 0.0
            K[g, 1, 1] = 0.0
        b0 = bptr[p]
        b1 = bptr[p + 1]
        for e in range(b0, b1):
            g = owner[e]
            for r in range(2):
                wa = w[e] * xi[e, r]
                for c in range(2):
                    K[g, r, c] += wa * xi[e, c]
        for g in range(g0, g1):
            k00 = K[g, 0, 0]
            k01 = K[g, 0, 1]
            k10 = K[g, 1, 0]
            k11 = K[g, 1, 1]
            det = k00 * k11 - k01 * k10
            tr = abs(k00 + k11)
            ref = max(tr / 2, 1e-300)
            bad[g] = not (abs(det) > 1e-12 * (ref * ref))
            if bad[g]:
                continue
            # the inverse, stored in place of K
            K[g, 0, 0] = k11 / det
            K[g, 1, 1] = k00 / det
            K[g, 0, 1] = -k01 / det
            K[g, 1, 0] = -k10 / det
        for e in range(b0, b1):
            g = owner[e]
            if bad[g]:
                continue
            for r in range(2):
                s = 0.0
                s += K[g, r, 0] * xi[e, 0]
                s += K[g, r, 1] * xi[e, 1]
                out[e, r] = w[e] * s


@_njit(inline="always")
def _cell_slot(ukeys, key):  # pragma: no cover
    """Index of ``key`` in the sorted ``ukeys`` or -1."""
    lo = 0
    hi = ukeys.size
    while lo < hi:
        mid = (lo + hi) // 2
        if ukeys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    if lo < ukeys.size and ukeys[lo] == key:
        return lo
    return -1


@_njit(nogil=True)
def cell_pairs(
    p0, p1, pts, cell, dims, strides, offsets, ukeys, cell_ptr, order, r2, ptr, out, out_xi
):  # pragma: no cover
    """Find the neighbours ``j != i`` with ``|x_j - x_i|² <= r2`` of the points ``p0:p1``.

    From a cell list (cells of edge ``>= sqrt(r2)``, the points of occupied cell
    ``ukeys[c]`` are ``order[cell_ptr[c]:cell_ptr[c+1]]``). With ``out`` empty only the
    counts are written (``ptr[i]``); else each row ``out[ptr[i]:ptr[i+1]]`` gets its
    neighbours, sorted, and ``out_xi`` their bond vectors ``x_j - x_i``.
    """
    d = pts.shape[1]
    count_only = out.size == 0
    nbr = np.empty(d, np.int64)
    for i in range(p0, p1):
        c = 0
        base = 0 if count_only else ptr[i]
        for o in range(offsets.shape[0]):
            key = 0
            inside = True
            for k in range(d):
                nbr[k] = cell[i, k] + offsets[o, k]
                if nbr[k] < 0 or nbr[k] >= dims[k]:
                    inside = False
                key += nbr[k] * strides[k]
            if not inside:
                continue
            slot = _cell_slot(ukeys, key)
            if slot < 0:
                continue
            for q in range(cell_ptr[slot], cell_ptr[slot + 1]):
                j = order[q]
                if j == i:
                    continue
                s = 0.0
                for k in range(d):
                    t = pts[j, k] - pts[i, k]
                    s += t * t
                if s <= r2:
                    if not count_only:
                        out[base + c] = j
                    c += 1
        if count_only:
            ptr[i] = c
        else:
            out[base : base + c].sort()
            for q in range(base, base + c):
                j = out[q]
                for k in range(d):
                    out_xi[q, k] = pts[j, k] - pts[i, k]


@_njit(inline="always")
def _mm2(a00, a01, a10, a11, b00, b01, b10, b11):  # pragma: no cover
    """2 x 2 product in the order of ``crystal_plasticity._mm``."""
    return (
        a00 * b00 + a01 * b10,
        a00 * b01 + a01 * b11,
        a10 * b00 + a11 * b10,
        a10 * b01 + a11 * b11,
    )


@_njit(inline="always")
def _inv2(a00, a01, a10, a11):  # pragma: no cover
    """2 x 2 inverse in the order of ``crystal_plasticity._inv``."""
    det = a00 * a11 - a01 * a10
    return a11 / det, -a01 / det, -a10 / det, a00 / det


@_njit(inline="always")
def _cp_crystal_frame(R0, f, i):  # pragma: no cover
    """``Fc = (R0ᵀ f) R0`` of point ``i``."""
    r00, r01, r10, r11 = R0[i, 0, 0], R0[i, 0, 1], R0[i, 1, 0], R0[i, 1, 1]
    a00, a01, a10, a11 = _mm2(r00, r10, r01, r11, f[i, 0, 0], f[i, 0, 1], f[i, 1, 0], f[i, 1, 1])
    return _mm2(a00, a01, a10, a11, r00, r01, r10, r11)


@_njit(inline="always")
def _cp_hardening_factor(s_n, i, be, h0, ss, expo):  # pragma: no cover
    """``h0 sgn(r)|r|^a``, ``r = 1 - s/ss``, of system ``be``.

    ``a = 2`` (the hardening of Luo, Ramazani & Sundararaghavan 2017, Eq. 24) as ``r r``,
    ``pow``'s value up to its last bit: ``pow`` had been a quarter of the stress-only
    kernel's time (6.6 → 4.9 ms per 10⁵ elastic points on one thread).
    """
    rr = 1.0 - s_n[i, be] / ss[be]
    sgr = 1.0 if rr > 0.0 else (-1.0 if rr < 0.0 else 0.0)
    ar = rr * rr if expo[be] == 2.0 else abs(rr) ** expo[be]
    return h0[be] * sgr * ar


@_njit(inline="always")
def _cp_hardening(s_n, i, Q, h0, ss, expo, fac, H):  # pragma: no cover
    """``H^{αβ} = Q^{αβ} h0 sgn(r)|r|^a``, ``r = 1 - s/ss`` of β, into ``H``."""
    N = H.shape[0]
    for be in range(N):
        fac[be] = _cp_hardening_factor(s_n, i, be, h0, ss, expo)
    for al in range(N):
        for be in range(N):
            H[al, be] = Q[al, be] * fac[be]


@_njit(inline="always")
def _cp_cauchy_green(e00, e01, e10, e11, Ce):  # pragma: no cover
    """``Ce = Feᵀ Fe`` (flat) into ``Ce``."""
    Ce[0] = e00 * e00 + e10 * e10
    Ce[1] = e00 * e01 + e10 * e11
    Ce[2] = e01 * e00 + e11 * e10
    Ce[3] = e01 * e01 + e11 * e11


@_njit(inline="always")
def _cp_slip_matrix(Ce, AelM, H, sg, A):  # pragma: no cover
    """``A^{αβ} = H^{αβ} + sgn_α sgn_β (Cᵉ S₀^β) : 𝓛[S₀^α]`` into ``A``."""
    N = A.shape[0]
    for al in range(N):
        for be in range(N):
            t = 0.0
            for k in range(4):
                t += Ce[k] * AelM[al * N + be, k]
            A[al, be] = H[al, be] + sg[al] * sg[be] * t


@_njit(inline="always")
def _cp_masked(A, act):  # pragma: no cover
    """Form the 2 x 2 active-set matrix: ``A`` on active rows / columns, identity elsewhere."""
    m00 = A[0, 0] if act[0] else 1.0
    m11 = A[1, 1] if act[1] else 1.0
    m01 = A[0, 1] if act[0] and act[1] else 0.0
    m10 = A[1, 0] if act[0] and act[1] else 0.0
    return m00, m01, m10, m11


@_njit(inline="always")
def _cp_second_pk(e00, e01, e10, e11, Cm, Et, tb):  # pragma: no cover
    """``T̄ = 𝓛[½(FeᵀFe − I)]`` (flat) into ``tb`` (``Et`` scratch)."""
    Et[0] = 0.5 * ((e00 * e00 + e10 * e10) - 1.0)
    Et[1] = 0.5 * (e00 * e01 + e10 * e11)
    Et[2] = 0.5 * (e01 * e00 + e11 * e10)
    Et[3] = 0.5 * ((e01 * e01 + e11 * e11) - 1.0)
    for k in range(4):
        t = 0.0
        for ll in range(4):
            t += Et[ll] * Cm[k, ll]
        tb[k] = t


@_njit(inline="always")
def _dot4(a0, a1, a2, a3, M, row):  # pragma: no cover
    """``Σ_k a_k M[row, k]`` summed left to right from 0 (the loops' order and bits)."""
    t = 0.0
    t += a0 * M[row, 0]
    t += a1 * M[row, 1]
    t += a2 * M[row, 2]
    t += a3 * M[row, 3]
    return t


@_njit(inline="always")
def _sum2(a, b):  # pragma: no cover
    """Sum ``a + b`` from 0 (a two-term loop's order and bits)."""
    t = 0.0
    t += a
    t += b
    return t


@_njit(inline="always")
def _dot2(w0, w1, M, col):  # pragma: no cover
    """``Σ_α w_α M[α, col]`` over two systems, summed from 0 (the loops' order)."""
    return _sum2(w0 * M[0, col], w1 * M[1, col])


@_njit(nogil=True)
def cp_planar_fill(  # pragma: no cover
    p0, p1, f, R0, Fp_n, s_n, gamma_n, ep_n, theta0, theta_n, rate_n,
    CS0, AelM, S0, Cm, Q, h0, ss, expo, renorm,
    P, Fp, s, gamma, dgamma, tau, dep, ep, plastic, sign, pruned, theta, R, reor, rate, bad,
    full,
):  # fmt: skip
    """Run the planar double-slip return mapping with active-set pruning on points ``p0 .. p1``.

    The return mapping of Luo, Ramazani & Sundararaghavan (2017), Appendix (Eqs. 26-34),
    with systems of ``Δγ <= 0`` dropped and the rest re-solved
    (``CrystalPlasticity('planar-2', active_set='prune')``), and its trial state, in the
    order of the numpy path's operations (``_update_points``).  Sums over the 4 tensor entries or
    the 2 systems run left to right (the numpy path's small matrix products go through
    BLAS, so the two agree to round-off, not bitwise).  ``bad[i]`` marks a point whose
    2 x 2 active-set matrix is singular (numpy's pseudo-inverse path): its outputs are
    left for the caller to recompute.  With ``full`` false only ``P`` and ``bad`` are
    written (the other outputs may be dummies; :meth:`CrystalPlasticity.piola`): the
    trial state's Fp, resistances, slips, resolved shears, plastic work and lattice
    rotation (seven trigonometric calls per point) are skipped, ≈ 40 % of the work.

    Every per-point quantity is a scalar local (the two systems unrolled), none a
    scratch array (those live on the heap, their entries go through memory), and the
    hardening matrix is formed only where a system is active or the trial state is
    written: the stress-only sweep ≈ 1.1-1.2 x faster than with scratch arrays, the same
    bits (10⁵ points of the 21-grain benchmark polycrystal, one thread).
    """
    for i in range(p0, p1):
        bad[i] = False
        r00, r01, r10, r11 = R0[i, 0, 0], R0[i, 0, 1], R0[i, 1, 0], R0[i, 1, 1]
        f00, f01, f10, f11 = f[i, 0, 0], f[i, 0, 1], f[i, 1, 0], f[i, 1, 1]
        c00, c01, c10, c11 = _cp_crystal_frame(R0, f, i)
        # trial state: Fe_tr = Fc Fp_n⁻¹, Ce = Fe_trᵀ Fe_tr, E = ½(Ce − I)
        q00, q01, q10, q11 = Fp_n[i, 0, 0], Fp_n[i, 0, 1], Fp_n[i, 1, 0], Fp_n[i, 1, 1]
        i00, i01, i10, i11 = _inv2(q00, q01, q10, q11)
        e00, e01, e10, e11 = _mm2(c00, c01, c10, c11, i00, i01, i10, i11)
        ce0 = e00 * e00 + e10 * e10
        ce1 = e00 * e01 + e10 * e11
        ce2 = e01 * e00 + e11 * e10
        ce3 = e01 * e01 + e11 * e11
        x0, x1, x2, x3 = 0.5 * (ce0 - 1.0), 0.5 * ce1, 0.5 * ce2, 0.5 * (ce3 - 1.0)
        t0 = _dot4(x0, x1, x2, x3, CS0, 0)
        t1 = _dot4(x0, x1, x2, x3, CS0, 1)
        sg0 = -1.0 if t0 < 0.0 else 1.0
        sg1 = -1.0 if t1 < 0.0 else 1.0
        b0 = sg0 * t0 - s_n[i, 0]
        b1 = sg1 * t1 - s_n[i, 1]
        a0 = b0 > 0.0
        a1 = b1 > 0.0
        tr0, tr1 = a0, a1
        dg0 = dg1 = 0.0
        h00 = h01 = h10 = h11 = 0.0
        if a0 or a1 or full:  # H^{αβ} = Q^{αβ} h0 sgn(r)|r|^a, r = 1 - s/ss of β
            fa0 = _cp_hardening_factor(s_n, i, 0, h0, ss, expo)
            fa1 = _cp_hardening_factor(s_n, i, 1, h0, ss, expo)
            h00, h01 = Q[0, 0] * fa0, Q[0, 1] * fa1
            h10, h11 = Q[1, 0] * fa0, Q[1, 1] * fa1
        if a0 or a1:
            # A^{αβ} = H^{αβ} + sgn_α sgn_β (Cᵉ S₀^β) : 𝓛[S₀^α]
            A00 = h00 + sg0 * sg0 * _dot4(ce0, ce1, ce2, ce3, AelM, 0)
            A01 = h01 + sg0 * sg1 * _dot4(ce0, ce1, ce2, ce3, AelM, 1)
            A10 = h10 + sg1 * sg0 * _dot4(ce0, ce1, ce2, ce3, AelM, 2)
            A11 = h11 + sg1 * sg1 * _dot4(ce0, ce1, ce2, ce3, AelM, 3)
            # solve on the active set, drop Δγ <= 0, repeat
            while True:
                m00 = A00 if a0 else 1.0
                m11 = A11 if a1 else 1.0
                m01 = A01 if a0 and a1 else 0.0
                m10 = A10 if a0 and a1 else 0.0
                y0 = b0 if a0 else 0.0
                y1 = b1 if a1 else 0.0
                dt = m00 * m11 - m01 * m10
                scl = max(abs(m00 * m11), abs(m01 * m10))
                if not abs(dt) > 1e-14 * scl:
                    bad[i] = True
                    break
                z0 = (m11 * y0 - m01 * y1) / dt
                z1 = (m00 * y1 - m10 * y0) / dt
                if (z0 > 0.0 or not a0) and (z1 > 0.0 or not a1):
                    dg0 = z0 if a0 else 0.0
                    dg1 = z1 if a1 else 0.0
                    break
                a0 = a0 and z0 > 0.0
                a1 = a1 and z1 > 0.0
                if not (a0 or a1):
                    break
            if bad[i]:
                continue
        # Fp = (I + Σ Δγ sgn S0) Fp_n, Fe = Fc Fp⁻¹, T̄ = 𝓛[½(FeᵀFe − I)]
        w0, w1 = dg0 * sg0, dg1 * sg1
        g0 = 1.0 + _dot2(w0, w1, S0, 0)
        g1 = _dot2(w0, w1, S0, 1)
        g2 = _dot2(w0, w1, S0, 2)
        g3 = 1.0 + _dot2(w0, w1, S0, 3)
        u00 = g0 * q00 + g1 * q10
        u01 = g0 * q01 + g1 * q11
        u10 = g2 * q00 + g3 * q10
        u11 = g2 * q01 + g3 * q11
        if renorm:
            dd = np.sqrt(u00 * u11 - u01 * u10)
            u00, u01, u10, u11 = u00 / dd, u01 / dd, u10 / dd, u11 / dd
        if full:
            Fp[i, 0, 0], Fp[i, 0, 1], Fp[i, 1, 0], Fp[i, 1, 1] = u00, u01, u10, u11
        i00, i01, i10, i11 = _inv2(u00, u01, u10, u11)
        e00, e01, e10, e11 = _mm2(c00, c01, c10, c11, i00, i01, i10, i11)
        x0 = 0.5 * ((e00 * e00 + e10 * e10) - 1.0)
        x1 = 0.5 * (e00 * e01 + e10 * e11)
        x2 = 0.5 * (e01 * e00 + e11 * e10)
        x3 = 0.5 * ((e01 * e01 + e11 * e11) - 1.0)
        tb0 = _dot4(x0, x1, x2, x3, Cm, 0)
        tb1 = _dot4(x0, x1, x2, x3, Cm, 1)
        tb2 = _dot4(x0, x1, x2, x3, Cm, 2)
        tb3 = _dot4(x0, x1, x2, x3, Cm, 3)
        # P = (Fe T̄) Fp⁻ᵀ in the crystal frame, then R0 P R0ᵀ
        v00 = e00 * tb0 + e01 * tb2
        v01 = e00 * tb1 + e01 * tb3
        v10 = e10 * tb0 + e11 * tb2
        v11 = e10 * tb1 + e11 * tb3
        w00 = v00 * i00 + v01 * i01
        w01 = v00 * i10 + v01 * i11
        w10 = v10 * i00 + v11 * i01
        w11 = v10 * i10 + v11 * i11
        z00 = r00 * w00 + r01 * w10
        z01 = r00 * w01 + r01 * w11
        z10 = r10 * w00 + r11 * w10
        z11 = r10 * w01 + r11 * w11
        p00 = z00 * r00 + z01 * r01
        p01 = z00 * r10 + z01 * r11
        p10 = z10 * r00 + z11 * r01
        p11 = z10 * r10 + z11 * r11
        P[i, 0, 0], P[i, 0, 1], P[i, 1, 0], P[i, 1, 1] = p00, p01, p10, p11
        if not full:
            continue
        # trial state variables
        s[i, 0] = s_n[i, 0] + _sum2(h00 * dg0, h01 * dg1)
        s[i, 1] = s_n[i, 1] + _sum2(h10 * dg0, h11 * dg1)
        ta0 = _dot4(tb0, tb1, tb2, tb3, S0, 0)
        ta1 = _dot4(tb0, tb1, tb2, tb3, S0, 1)
        tau[i, 0], tau[i, 1] = ta0, ta1
        gamma[i, 0], gamma[i, 1] = gamma_n[i, 0] + dg0, gamma_n[i, 1] + dg1
        dgamma[i, 0], dgamma[i, 1] = dg0, dg1
        sign[i, 0], sign[i, 1] = sg0, sg1
        work = _sum2(abs(ta0) * dg0, abs(ta1) * dg1)
        plastic[i] = 1.0 if (dg0 > 0.0 or dg1 > 0.0) else 0.0
        pruned[i] = (1.0 if tr0 and not a0 else 0.0) + (1.0 if tr1 and not a1 else 0.0)
        # Cauchy stress σ = P fᵀ / det f (σ33 = 0) for the von Mises measure
        df = f00 * f11 - f01 * f10
        sxx = (p00 * f00 + p01 * f01) / df
        sxy = (p00 * f10 + p01 * f11) / df
        syy = (p10 * f10 + p11 * f11) / df
        seff = np.sqrt(sxx**2 - sxx * syy + syy**2 + 3.0 * sxy**2)
        dp = work / seff if seff > 0.0 else 0.0
        dep[i] = dp
        ep[i] = ep_n[i] + dp
        # lattice rotation: θ = θ0 + atan2(Fe21 − Fe12, Fe11 + Fe22), the closed form of
        # the reorientation rate θ̇ = (Ω21 − Ω12)/2 of Luo et al. (2017), Sec. 4
        phi = np.arctan2(e10 - e01, e00 + e11)
        th0 = theta0[i]
        th = th0 + phi
        theta[i] = th
        cth, sth = np.cos(th), np.sin(th)
        R[i, 0, 0], R[i, 0, 1], R[i, 1, 0], R[i, 1, 1] = cth, -sth, sth, cth
        reor[i] = phi * (180.0 / np.pi)
        cp, sp_ = np.cos(theta_n[i] - th0), np.sin(theta_n[i] - th0)
        cn, sn = np.cos(phi), np.sin(phi)
        d00, d01, d10, d11 = cn - cp, -sn + sp_, sn - sp_, cn - cp
        wa = d10 * cn + d11 * -sn
        wb = d00 * sn + d01 * cn
        rate[i] = rate_n[i] + 0.5 * (wa - wb)


@_njit(nogil=True)
def cp_planar_tangent_fill(  # pragma: no cover
    p0, p1, f, R0, Fp_n, s_n, Fp, dgamma, sign,
    CS0, AelM, S0, Cm, Q, h0, ss, expo, renorm, D,
):  # fmt: skip
    """Compute the consistent tangent ``D[i, j, k, l] = ∂P_ij/∂F_kl`` for points ``p0 .. p1``.

    The tangent of :func:`cp_planar_fill`'s update (active set ``Δγ > 0`` and signs
    frozen): the forward linearization of ``CrystalPlasticity._tangent_analytic`` per
    point and direction ``e_k ⊗ e_l``, from the committed state and the update's ``Fp``,
    ``dgamma``, ``sign``.
    """
    N = 2
    fac = np.empty(N)
    H = np.empty((N, N))
    A = np.empty((N, N))
    act = np.empty(N, np.bool_)
    sg = np.empty(N)
    dg = np.empty(N)
    Ce = np.empty(4)
    tb = np.empty(4)
    Et = np.empty(4)
    gg = np.empty(4)
    z00 = z01 = z10 = z11 = w00 = w01 = w10 = w11 = Jr = 1.0
    for i in range(p0, p1):
        r00, r01, r10, r11 = R0[i, 0, 0], R0[i, 0, 1], R0[i, 1, 0], R0[i, 1, 1]
        c00, c01, c10, c11 = _cp_crystal_frame(R0, f, i)
        _cp_hardening(s_n, i, Q, h0, ss, expo, fac, H)
        q00, q01, q10, q11 = Fp_n[i, 0, 0], Fp_n[i, 0, 1], Fp_n[i, 1, 0], Fp_n[i, 1, 1]
        n00, n01, n10, n11 = _inv2(q00, q01, q10, q11)  # Fp_n⁻¹
        t00, t01, t10, t11 = _mm2(c00, c01, c10, c11, n00, n01, n10, n11)  # Fe_tr
        _cp_cauchy_green(t00, t01, t10, t11, Ce)
        anyact = False
        for al in range(N):
            dg[al] = dgamma[i, al]
            sg[al] = sign[i, al]
            act[al] = dg[al] > 0.0
            anyact = anyact or act[al]
        if anyact:
            _cp_slip_matrix(Ce, AelM, H, sg, A)
        m00, m01, m10, m11 = _cp_masked(A, act)
        mdet = m00 * m11 - m01 * m10
        # final state: Fp⁻¹, Fe = Fc Fp⁻¹, T̄ = 𝓛[½(FeᵀFe − I)]
        i00, i01, i10, i11 = _inv2(Fp[i, 0, 0], Fp[i, 0, 1], Fp[i, 1, 0], Fp[i, 1, 1])
        e00, e01, e10, e11 = _mm2(c00, c01, c10, c11, i00, i01, i10, i11)
        _cp_second_pk(e00, e01, e10, e11, Cm, Et, tb)
        # T̄ Fp⁻ᵀ and Fe T̄ (constant over the directions)
        x00, x01, x10, x11 = _mm2(tb[0], tb[1], tb[2], tb[3], i00, i10, i01, i11)
        y00, y01, y10, y11 = _mm2(e00, e01, e10, e11, tb[0], tb[1], tb[2], tb[3])
        if renorm:
            gg[:] = 0.0
            for al in range(N):
                w = dg[al] * sg[al]
                for k in range(4):
                    gg[k] += w * S0[al, k]
            z00, z01, z10, z11 = _mm2(
                1.0 + gg[0], gg[1], gg[2], 1.0 + gg[3], q00, q01, q10, q11
            )  # Fq = G Fp_n
            J = z00 * z11 - z01 * z10
            w00, w01, w10, w11 = z11 / J, -z01 / J, -z10 / J, z00 / J  # Fq⁻¹
            Jr = np.sqrt(J)
        for kk in range(2):
            for ll in range(2):
                # crystal-frame direction dF_ij = R0_ki R0_lj
                d00 = R0[i, kk, 0] * R0[i, ll, 0]
                d01 = R0[i, kk, 0] * R0[i, ll, 1]
                d10 = R0[i, kk, 1] * R0[i, ll, 0]
                d11 = R0[i, kk, 1] * R0[i, ll, 1]
                v00, v01, v10, v11 = _mm2(d00, d01, d10, d11, n00, n01, n10, n11)
                # dCe = dFe_trᵀ Fe_tr + its transpose
                g00, g01, g10, g11 = _mm2(v00, v10, v01, v11, t00, t01, t10, t11)
                g00, g01, g10, g11 = g00 + g00, g01 + g10, g10 + g01, g11 + g11
                ddg0 = 0.0
                ddg1 = 0.0
                if anyact:
                    rh0 = 0.0
                    rh1 = 0.0
                    for al in range(N):
                        if not act[al]:
                            continue
                        db = 0.5 * sg[al] * (
                            g00 * CS0[al, 0] + g01 * CS0[al, 1] + g10 * CS0[al, 2]
                            + g11 * CS0[al, 3]
                        )  # fmt: skip
                        dax = 0.0
                        for be in range(N):
                            w = sg[be] * dg[be]
                            s00, s01, s10, s11 = _mm2(
                                g00, g01, g10, g11, S0[be, 0], S0[be, 1], S0[be, 2], S0[be, 3]
                            )
                            dax += w * (
                                s00 * CS0[al, 0] + s01 * CS0[al, 1] + s10 * CS0[al, 2]
                                + s11 * CS0[al, 3]
                            )  # fmt: skip
                        if al == 0:
                            rh0 = db - sg[al] * dax
                        else:
                            rh1 = db - sg[al] * dax
                    x0 = (m11 * rh0 - m01 * rh1) / mdet
                    x1 = (m00 * rh1 - m10 * rh0) / mdet
                    ddg0 = x0 if act[0] else 0.0
                    ddg1 = x1 if act[1] else 0.0
                # dG = Σ dΔγ sgn S0, dFp = dG Fp_n
                o0 = ddg0 * sg[0]
                o1 = ddg1 * sg[1]
                h00 = o0 * S0[0, 0] + o1 * S0[1, 0]
                h01 = o0 * S0[0, 1] + o1 * S0[1, 1]
                h10 = o0 * S0[0, 2] + o1 * S0[1, 2]
                h11 = o0 * S0[0, 3] + o1 * S0[1, 3]
                p00, p01, p10, p11 = _mm2(h00, h01, h10, h11, q00, q01, q10, q11)
                if renorm:
                    tr = w00 * p00 + w01 * p10 + w10 * p01 + w11 * p11
                    p00 = (p00 - tr / 2.0 * z00) / Jr
                    p01 = (p01 - tr / 2.0 * z01) / Jr
                    p10 = (p10 - tr / 2.0 * z10) / Jr
                    p11 = (p11 - tr / 2.0 * z11) / Jr
                # dFp⁻¹ = −Fp⁻¹ dFp Fp⁻¹
                k00, k01, k10, k11 = _mm2(i00, i01, i10, i11, p00, p01, p10, p11)
                k00, k01, k10, k11 = _mm2(k00, k01, k10, k11, i00, i01, i10, i11)
                k00, k01, k10, k11 = -k00, -k01, -k10, -k11
                # dFe = dF Fp⁻¹ + Fc dFp⁻¹
                l00, l01, l10, l11 = _mm2(d00, d01, d10, d11, i00, i01, i10, i11)
                m_00, m_01, m_10, m_11 = _mm2(c00, c01, c10, c11, k00, k01, k10, k11)
                l00, l01, l10, l11 = l00 + m_00, l01 + m_01, l10 + m_10, l11 + m_11
                # dE = ½(dFeᵀ Fe + Feᵀ dFe), dT = 𝓛[dE]
                j00, j01, j10, j11 = _mm2(l00, l10, l01, l11, e00, e01, e10, e11)
                Et[0] = 0.5 * (j00 + j00)
                Et[1] = 0.5 * (j01 + j10)
                Et[2] = 0.5 * (j10 + j01)
                Et[3] = 0.5 * (j11 + j11)
                dt0 = Et[0] * Cm[0, 0] + Et[1] * Cm[0, 1] + Et[2] * Cm[0, 2] + Et[3] * Cm[0, 3]
                dt1 = Et[0] * Cm[1, 0] + Et[1] * Cm[1, 1] + Et[2] * Cm[1, 2] + Et[3] * Cm[1, 3]
                dt2 = Et[0] * Cm[2, 0] + Et[1] * Cm[2, 1] + Et[2] * Cm[2, 2] + Et[3] * Cm[2, 3]
                dt3 = Et[0] * Cm[3, 0] + Et[1] * Cm[3, 1] + Et[2] * Cm[3, 2] + Et[3] * Cm[3, 3]
                # dP = dFe (T̄ Fp⁻ᵀ) + (Fe dT) Fp⁻ᵀ + (Fe T̄) dFp⁻ᵀ
                a00, a01, a10, a11 = _mm2(l00, l01, l10, l11, x00, x01, x10, x11)
                b00, b01, b10, b11 = _mm2(e00, e01, e10, e11, dt0, dt1, dt2, dt3)
                b00, b01, b10, b11 = _mm2(b00, b01, b10, b11, i00, i10, i01, i11)
                a00, a01, a10, a11 = a00 + b00, a01 + b01, a10 + b10, a11 + b11
                b00, b01, b10, b11 = _mm2(y00, y01, y10, y11, k00, k10, k01, k11)
                a00, a01, a10, a11 = a00 + b00, a01 + b01, a10 + b10, a11 + b11
                # back to the sample frame: R0 dP R0ᵀ
                a00, a01, a10, a11 = _mm2(r00, r01, r10, r11, a00, a01, a10, a11)
                a00, a01, a10, a11 = _mm2(a00, a01, a10, a11, r00, r10, r01, r11)
                D[i, 0, 0, kk, ll] = a00
                D[i, 0, 1, kk, ll] = a01
                D[i, 1, 0, kk, ll] = a10
                D[i, 1, 1, kk, ll] = a11


@_njit(nogil=True)
def adr_update_fill(i0, i1, r, inv_lam, u, u_prev, fixed, h2, cdt, out):  # pragma: no cover
    """Do one central-difference ADR update of the DOFs ``i0:i1``.

    ``_adr_run``'s numpy steps in their order: ``((r Λ⁻¹) 2Δt² + 4u + (cΔt − 2) u⁻) /
    (2 + cΔt)`` (Luo, Ramazani & Sundararaghavan 2017, Eq. 8); prescribed DOFs keep ``u``.
    """
    a = cdt - 2.0
    b = 2.0 + cdt
    for i in range(i0, i1):
        if fixed[i]:
            out[i] = u[i]
        else:
            v = r[i] * inv_lam[i]
            v = v * h2
            v = v + u[i] * 4.0
            v = v + u_prev[i] * a
            out[i] = v / b


@_njit(nogil=True)
def adr_local_fill(i0, i1, r, r_new, lam, u_new, u, du, k, local):  # pragma: no cover
    """Compute ``δu = uⁿ⁺¹ − uⁿ`` and (``local``) the diagonal local stiffness of DOFs ``i0:i1``.

    ``k = (rⁿ − rⁿ⁺¹) / (Λ δu)`` (Luo, Ramazani & Sundararaghavan 2017, Eq. 14), ``Λ δu``
    taken as ``∞`` where ``δu = 0`` (``_adr_run``'s numpy steps in their order).
    """
    for i in range(i0, i1):
        d = u_new[i] - u[i]
        du[i] = d
        if local:
            m = lam[i] * d
            if d == 0.0:
                m = np.inf
            k[i] = (r[i] - r_new[i]) / m


@_njit(nogil=True)
def bond_force_fill(  # pragma: no cover
    p0, p1, u, j, indptr, xi, unit, length, k, alive, s0, linear, mask, breaking, f, out
):
    """Bond-based force of points ``p0:p1``, each summing its own family (owner computes).

    ``pdlin.dynamics.forces.BondKernel.evaluate``'s numpy arithmetic per directed bond, in
    its order: ``η = u_j − u_i``; linearized ``e = n·η`` (``n = ξ/|ξ|``) or exact
    ``e = |ξ + η| − |ξ|`` along ``m = (ξ + η)/|ξ + η|``; with ``breaking`` a surviving bond
    whose exact stretch exceeds ``s0`` gets ``alive = 0`` (``s0`` and ``alive`` symmetric
    under bond reversal, which the caller checks, so the owner decides both directions
    alike); ``f_i += (k alive e) m`` summed in bond order from zero (what ``np.bincount``
    does), so ``f`` equals the numpy path's bitwise.  ``out[0]`` gets ``Σ k alive e²`` and
    ``out[1]`` that of the bonds broken now (the caller's ``¼`` and chunk sums round
    differently from numpy's ``dot``).  Zero-length deformed bonds set ``out[2] = 1``.
    """
    d = u.shape[1]
    en = 0.0
    rel = 0.0
    s = 0.0
    ly = 0.0
    for p in range(p0, p1):
        for a in range(d):
            f[p, a] = 0.0
        for b in range(indptr[p], indptr[p + 1]):
            q = j[b]
            y0 = 0.0
            y1 = 0.0
            y2 = 0.0
            e0 = u[q, 0] - u[p, 0]
            y0 = xi[b, 0] + e0
            ly2 = y0 * y0
            e1 = 0.0
            e2 = 0.0
            if d > 1:
                e1 = u[q, 1] - u[p, 1]
                y1 = xi[b, 1] + e1
                ly2 = ly2 + y1 * y1
            if d > 2:
                e2 = u[q, 2] - u[p, 2]
                y2 = xi[b, 2] + e2
                ly2 = ly2 + y2 * y2
            if linear:
                e = unit[b, 0] * e0
                if d > 1:
                    e = e + unit[b, 1] * e1
                if d > 2:
                    e = e + unit[b, 2] * e2
                m0 = unit[b, 0]
                m1 = unit[b, 1] if d > 1 else 0.0
                m2 = unit[b, 2] if d > 2 else 0.0
                if breaking:
                    ly = np.sqrt(ly2)
                    s = ly / length[b] - 1.0
            else:
                ly = np.sqrt(ly2)
                if ly <= 0.0:
                    out[2] = 1.0
                    return
                e = ly - length[b]
                m0 = y0 / ly
                m1 = y1 / ly
                m2 = y2 / ly
                s = e / length[b]
            kb = k[b]
            if mask:
                al = alive[b]
                if breaking and al > 0.0 and s > s0[b]:
                    rel += (kb * al) * (e * e)
                    alive[b] = 0.0
                    al = 0.0
                kb = kb * al
            tb = kb * e
            en += tb * e
            f[p, 0] += tb * m0
            if d > 1:
                f[p, 1] += tb * m1
            if d > 2:
                f[p, 2] += tb * m2
    out[0] = en
    out[1] = rel


@_njit(nogil=True)
def state_dilatation_fill(  # pragma: no cover
    p0,
    p1,
    u,
    j,
    indptr,
    xi,
    unit,
    length,
    a,
    c,
    vj,
    w,
    kV,
    alive,
    s0,
    linear,
    breaking,
    energy_variant,
    e_out,
    ed_out,
    broke,
    theta,
    z,
    out,
):
    """First pass of the state-based (LPS, XOSB) force: points ``p0:p1``.

    ``pdlin.dynamics.forces.StateKernel``'s numpy arithmetic in its order: extension ``e``
    (stored), breaking (``alive`` set to 0 where the exact stretch exceeds ``s0``; symmetric
    masks, checked by the caller), ``θ_i = Σ (a alive) e`` and ``θ`` with the mask before
    the breaking, ``e^d = e − θ_i |ξ| / d`` (stored), ``z_i = Σ ((c alive) e^d) |ξ| V_j``
    (``linearization='energy'``), and per chunk ``out[0]`` = strain energy ``Σ κV θ²/2 +
    Σ w (c alive) (e^d)²/2`` (``w = V_i V_j``) after the breaking, ``out[1]`` the same before it.
    Collapsed bonds (exact kinematics) set ``out[2] = 1``.
    """
    d = u.shape[1]
    en = 0.0
    en0 = 0.0
    for p in range(p0, p1):
        th = 0.0
        th0 = 0.0
        for b in range(indptr[p], indptr[p + 1]):
            # the extension and the exact stretch as forces.py computes them, in its order
            # (written out: an inlined helper returning a tuple ran 2.5x slower)
            q = j[b]
            e0 = u[q, 0] - u[p, 0]
            y0 = xi[b, 0] + e0
            ly2 = y0 * y0
            e1 = 0.0
            e2 = 0.0
            if d > 1:
                e1 = u[q, 1] - u[p, 1]
                y1 = xi[b, 1] + e1
                ly2 = ly2 + y1 * y1
            if d > 2:
                e2 = u[q, 2] - u[p, 2]
                y2 = xi[b, 2] + e2
                ly2 = ly2 + y2 * y2
            if linear:
                e = unit[b, 0] * e0
                if d > 1:
                    e = e + unit[b, 1] * e1
                if d > 2:
                    e = e + unit[b, 2] * e2
                s = 0.0
                if breaking:
                    s = np.sqrt(ly2) / length[b] - 1.0
            else:
                ly = np.sqrt(ly2)
                if ly <= 0.0:
                    out[2] = 1.0
                    return
                e = ly - length[b]
                s = e / length[b]
            e_out[b] = e
            al = alive[b]
            th0 += (a[b] * al) * e
            broke[b] = 0
            if breaking and al > 0.0 and s > s0[b]:
                broke[b] = 1
                alive[b] = 0.0
                al = 0.0
            th += (a[b] * al) * e
        theta[p] = th
        zp = 0.0
        wp = 0.0
        wp0 = 0.0
        for b in range(indptr[p], indptr[p + 1]):
            ed = e_out[b] - th * length[b] / d
            ed_out[b] = ed
            ca = c[b] * alive[b]
            cd = ca * ed
            if energy_variant:
                zp += cd * length[b] * vj[b]
            wp += w[b] * ca * ed * ed
            if breaking:
                ed0 = e_out[b] - th0 * length[b] / d
                wp0 += w[b] * (c[b] * (alive[b] + broke[b])) * ed0 * ed0
        z[p] = zp
        en += kV[p] * th * th + wp
        en0 += kV[p] * th0 * th0 + wp0
    out[0] = 0.5 * en
    out[1] = 0.5 * en0


@_njit(nogil=True)
def state_force_fill(  # pragma: no cover
    p0, p1, indptr, a, c, kth, kh, vj, w, alive, dim, energy_variant, theta, z, ed, tw
):
    """Second pass: the weighted force scalar ``tw_b = w t_b`` of the bonds of ``p0:p1``.

    ``t = (kth θ_i + (c alive) e^d) − (a / V_j / d) z_i`` (``'energy'``) or ``kh θ_i + (c alive)
    e^d`` (``'paper'``), times ``alive``, as forces.py's ``_force_of`` in its order.
    """
    for p in range(p0, p1):
        for b in range(indptr[p], indptr[p + 1]):
            al = alive[b]
            cd = c[b] * al * ed[b]
            if energy_variant:
                t = (kth[b] * theta[p] + cd) - (a[b] / vj[b] / dim) * z[p]
            else:
                t = kh[b] * theta[p] + cd
            tw[b] = w[b] * (t * al)


@_njit(nogil=True)
def state_scatter_fill(  # pragma: no cover
    p0, p1, u, j, indptr, xi, unit, length, rev, linear, tw, f
):
    """Third pass: ``f_i = Σ_b (tw_b + tw_rev(b)) m_b`` in bond order from zero."""
    d = u.shape[1]
    for p in range(p0, p1):
        for a in range(d):
            f[p, a] = 0.0
        for b in range(indptr[p], indptr[p + 1]):
            q = j[b]
            y1 = 0.0
            y2 = 0.0
            y0 = xi[b, 0] + (u[q, 0] - u[p, 0])
            ly2 = y0 * y0
            if d > 1:
                y1 = xi[b, 1] + (u[q, 1] - u[p, 1])
                ly2 = ly2 + y1 * y1
            if d > 2:
                y2 = xi[b, 2] + (u[q, 2] - u[p, 2])
                ly2 = ly2 + y2 * y2
            if linear:
                m0 = unit[b, 0]
                m1 = unit[b, 1] if d > 1 else 0.0
                m2 = unit[b, 2] if d > 2 else 0.0
            else:
                ly = np.sqrt(ly2)
                m0 = y0 / ly
                m1 = y1 / ly
                m2 = y2 / ly
            t = tw[b] + tw[rev[b]]
            f[p, 0] += t * m0
            if d > 1:
                f[p, 1] += t * m1
            if d > 2:
                f[p, 2] += t * m2


# --- the power-law slip rule of CrystalPlasticity(rate_exponent=...) ---------------------


@_njit(inline="always")
def _rate_point(
    p, g, jac, dphi, tau_tr, s_n, H, Ael, k, nexp, maxiter, J, rhs, tau, s
):  # pragma: no cover
    """Newton of one point from its ``g[p]``: True when converged (``|g| ≤ 1``)."""
    N = g.shape[1]
    for _it in range(maxiter):
        for a in range(N):
            ta = tau_tr[p, a]
            sa = s_n[p, a]
            for b in range(N):
                ta -= Ael[p, a, b] * g[p, b]
                sa += H[p, a, b] * abs(g[p, b])
            tau[a] = ta
            s[a] = sa
        for a in range(N):
            x = abs(tau[a]) / s[a]
            xn1 = x ** (nexp - 1.0)
            sgn_t = -1.0 if tau[a] < 0.0 else 1.0
            phi = sgn_t * xn1 * x
            dp = k * nexp * xn1 / s[a]
            dphi[p, a] = dp
            rhs[a] = -(g[p, a] - k * phi)
            c = k * nexp * phi / s[a]
            for b in range(N):
                gb = g[p, b]
                sb = (1.0 if gb > 0.0 else -1.0) if gb != 0.0 else (-1.0 if tau[b] < 0.0 else 1.0)
                v = dp * Ael[p, a, b] + c * H[p, a, b] * sb
                if a == b:
                    v += 1.0
                J[a, b] = v
                jac[p, a, b] = v
        # Gaussian elimination with partial pivoting on J (N x N), rhs in place
        for c0 in range(N):
            piv = c0
            big = abs(J[c0, c0])
            for r in range(c0 + 1, N):
                if abs(J[r, c0]) > big:
                    big = abs(J[r, c0])
                    piv = r
            if big == 0.0 or not np.isfinite(big):
                return False
            if piv != c0:
                for b in range(N):
                    J[c0, b], J[piv, b] = J[piv, b], J[c0, b]
                rhs[c0], rhs[piv] = rhs[piv], rhs[c0]
            for r in range(c0 + 1, N):
                f = J[r, c0] / J[c0, c0]
                if f != 0.0:
                    for b in range(c0, N):
                        J[r, b] -= f * J[c0, b]
                    rhs[r] -= f * rhs[c0]
        for r in range(N - 1, -1, -1):
            v = rhs[r]
            for b in range(r + 1, N):
                v -= J[r, b] * rhs[b]
            rhs[r] = v / J[r, r]
        smax = 0.0
        gmax = 0.0
        for a in range(N):
            g[p, a] += rhs[a]
            smax = max(smax, abs(rhs[a]))
            gmax = max(gmax, abs(g[p, a]))
        if not gmax <= 1.0:  # also NaN
            return False
        if smax <= 1e-12 * gmax + 1e-300:
            return True
    return False


@_njit(nogil=True)
def cp_rate_fill(
    lo, hi, tau_tr, s_n, H, Ael, k, nexp, g0, warm, maxiter, g, jac, dphi, fail
):  # pragma: no cover
    """Backward-Euler power-law slip increments of points ``lo:hi``.

    The per-point Newton of ``CrystalPlasticity._rate_newton`` (the same residual,
    Jacobian and stopping test; the linear solves by Gaussian elimination, so the slips
    agree with the numpy path to the stopping tolerance, not bitwise): from ``g0`` when
    ``warm``, again from 0 where that fails; ``fail[p]`` where both fail.
    """
    N = g.shape[1]
    J = np.empty((N, N))
    rhs = np.empty(N)
    tau = np.empty(N)
    s = np.empty(N)
    for p in range(lo, hi):
        ok = False
        if warm:
            for a in range(N):
                g[p, a] = g0[p, a]
            ok = _rate_point(p, g, jac, dphi, tau_tr, s_n, H, Ael, k, nexp, maxiter, J, rhs, tau, s)
        if not ok:
            for a in range(N):
                g[p, a] = 0.0
            ok = _rate_point(p, g, jac, dphi, tau_tr, s_n, H, Ael, k, nexp, maxiter, J, rhs, tau, s)
        fail[p] = not ok
