"""Optional compiled kernels (numba) for the sparse products that scipy runs on one core.

scipy's sparse products (sparsetools) hold the GIL, so threads cannot share them.  With
numba installed (``pip install "pdlin[fast]"``) these run row-parallel on
:func:`pdlin.get_num_threads` threads instead:

- :func:`csr_to_bsr_t` and :func:`csr_to_bsr_rows`: a CSR array ``X`` as the BSR array
  of ``Xᵀ`` in ``d x 1`` blocks (scipy: ``X.T.tocsr().tobsr((d, 1))``, a serial CSR -> CSC
  conversion and a serial block conversion) and as BSR in ``1 x d`` blocks
  (``X.tobsr((1, d))``), the factors of the LPS / XOSB product: row-chunk parallel, with
  scipy's block order and sums (bitwise equal);
- :func:`bsr_transpose`: ``Aᵀ`` of a BSR array (scipy's ``bsr_transpose``: serial),
  row-chunk parallel, the same arrays bitwise (the correspondence ``Wᵀ W``);
- ``_numba_kernels.pair_blocks_fill``: the bond-based (pairwise) blocks ``-k n nᵀ`` of a
  row chunk written once into their BSR slots with the row's diagonal sum (called by
  :func:`pdlin.operators.assembly.pair_stiffness_bsr` on its thread pool; 1.8 x on two
  threads and 1.8 x faster than its numpy chunks on one, docs/large_problems.md);
- :func:`bsr_matmul`: ``A @ B`` of two BSR arrays (block sizes ``R x N`` and ``N x S``,
  any of 1, 2, 3, ...), a two-pass row-parallel Gustavson product (blocks per row, then
  sorted block columns and values; optionally the largest entry of every block, computed
  while the row is in cache); used by the LPS / XOSB assembly (``K = Xᵀ Y``) and
  the correspondence assembly (``Wᵀ W``, ``Bᵀ (D B)`` and the tangent ``Gᵀ (A G)``);
- the correspondence plan and its clean-up, each a ``nogil`` pass over point (or block
  row) chunks on pdlin's thread pool, the numpy path's arithmetic in the same order (the
  same arrays bitwise; ``np.bincount``, which that path sums with, holds the GIL):
  per-point outer-product sums (shape tensors, :func:`pdlin.fields.shape_tensor`), the
  bond coefficients ``ω V K⁻¹ ξ`` (in 2D shape tensor, inverse and coefficients in one
  pass), the blocks of ``G`` for one or two gradient points per point, the stress-point
  sides and balanced-halves test (2D), the gradient point of each bond, the zero-block
  dropping of ``Wᵀ W`` and the check for stored diagonal blocks.

The conversions and the transpose count blocks per (row chunk, column) in a first
pass, so each chunk then writes its own slots; on one thread (CPU time, measured while
other jobs ran) they took 0.45 s for the LPS factors at 27,000 points in 3D against 0.97 s
of scipy's ``vstack`` + CSR -> CSC + ``tobsr``, and 0.030 vs 0.047 s for the 401²
correspondence ``Wᵀ`` (an earlier serial numba transpose: 0.058 s, not used).

Measured and left to scipy / numpy (numba did not win, see docs/large_problems.md): the
matrix-free mat-vecs (a numba CSR mat-vec took 0.099 vs 0.064 s per LPS ``K x`` on one
thread, 27,000 points in 3D, and was no faster on two) and the zero-block dropping of
the correspondence assembly (a serial numba pass: 0.15 vs 0.08 s; it runs as numpy in
block-row chunks on the thread pool instead).

Each output row is computed by one thread in a fixed order, so results are bitwise
identical for any thread count, and the arithmetic is scipy's (same operations in the
same order for the same operands: equal values; the product's block columns come out
sorted where scipy leaves them unsorted).  Without numba, or with ``PDLIN_NUMBA=0`` in
the environment, every function is the plain scipy operation.  Operations below
``_MIN_WORK`` stored entries (2²⁰: about 10⁴ points in 3D) stay on scipy without importing
numba, so small problems neither import numba nor compile anything.  The first call
compiles the kernels (~7 s for all signatures); they are cached per user
(``$XDG_CACHE_HOME/pdlin/numba``, :func:`pdlin._numba_kernels.cache_dir`; never in the
package folder, which ``pip uninstall`` would leave behind) for later processes, where
loading takes ~0.5 s plus numba's import, ~1 s.

numba's threading layer is set to ``'forksafe'`` (tbb if installed, else numba's
workqueue) unless ``NUMBA_THREADING_LAYER`` is set: GNU OpenMP, its default without tbb,
aborts a forked child (multiprocessing) that runs a parallel kernel.  The workqueue layer
must not be entered by two threads at once, so the calls here hold a lock.
"""

from __future__ import annotations

import logging
import os
import threading
from types import ModuleType
from typing import Any, Literal, overload

import numpy as np
import scipy.sparse as sp

from ._threads import get_num_threads

__all__ = [
    "numba_enabled",
    "use_numba",
    "bsr_matmul",
    "csr_to_bsr_t",
    "csr_to_bsr_rows",
    "bsr_transpose",
]

log = logging.getLogger(__name__)

#: the kernel module once imported, ``False`` when numba is missing or disabled
_loaded: ModuleType | bool | None = None
#: one kernel call at a time: numba's workqueue layer aborts on concurrent calls
_lock = threading.Lock()


def _new_lock_in_child() -> None:
    global _lock
    _lock = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_new_lock_in_child)

#: smallest operation (stored entries, times S for a product) sent to numba (about 10⁴
#: points in 3D): below it numba's import (~1 s) and, on a machine's first run, the
#: compilation of the kernels (60-100 s on a loaded machine for the gallery's lps_cube and
#: cp_compression, benchmarks/bench_first_run.py) cost more than the threads save; the
#: gallery's scenes stay on scipy (the largest of lps_cube's products: 704,304)
_MIN_WORK = 1 << 20


def _kernels() -> ModuleType | None:
    global _loaded
    if _loaded is None:
        if os.environ.get("PDLIN_NUMBA", "").strip() == "0":
            _loaded = False
        else:
            try:
                import numba
            except ImportError:
                _loaded = False
            else:
                if "NUMBA_THREADING_LAYER" not in os.environ:
                    # GNU OpenMP (numba's default layer where tbb is missing) aborts a
                    # forked child that runs a parallel kernel (multiprocessing's fork):
                    # 'forksafe' takes tbb if installed, else numba's own workqueue
                    cfg: Any = numba.config
                    cfg.THREADING_LAYER = "forksafe"
                from . import _numba_kernels

                _loaded = _numba_kernels
    return _loaded if isinstance(_loaded, ModuleType) else None


def numba_enabled() -> bool:
    """Whether the numba kernels are in use (numba installed and not ``PDLIN_NUMBA=0``).

    Examples
    --------
    >>> from pdlin._kernels import numba_enabled
    >>> numba_enabled() in (True, False)
    True
    """
    return _kernels() is not None


def use_numba(work: int) -> bool:
    """Whether an operation of ``work`` stored entries goes to numba (large enough, enabled).

    Small operations stay on scipy without importing numba (its import alone takes ~1 s).

    Examples
    --------
    >>> from pdlin._kernels import use_numba
    >>> use_numba(10)
    False
    """
    return work >= _MIN_WORK and numba_enabled()


def _set_threads() -> None:
    import numba

    cfg: Any = numba.config
    numba.set_num_threads(max(1, min(get_num_threads(), int(cfg.NUMBA_NUM_THREADS))))


def _edges(weight: np.ndarray, n_chunks: int) -> np.ndarray:
    """Row chunk edges of about equal ``weight`` (cumulative, ``(n_rows + 1,)``)."""
    n_rows = weight.size - 1
    n_chunks = max(1, min(n_chunks, n_rows))
    targets = np.linspace(0, float(weight[-1]), n_chunks + 1)
    edges = np.searchsorted(weight, targets[1:-1], side="left")
    return np.unique(np.concatenate([[0], edges, [n_rows]])).astype(np.int64)


@overload
def bsr_matmul(A: Any, B: Any, *, block_sizes: Literal[False] = ...) -> sp.bsr_array: ...


@overload
def bsr_matmul(
    A: Any, B: Any, *, block_sizes: Literal[True]
) -> tuple[sp.bsr_array, tuple[np.ndarray, np.ndarray] | None]: ...


def bsr_matmul(A: Any, B: Any, *, block_sizes: bool = False) -> Any:
    """Multiply two BSR arrays whose block sizes chain (``R x N`` times ``N x S``).

    Parameters
    ----------
    A, B : scipy.sparse BSR arrays (real)
    block_sizes : bool
        Also return ``(size, dsize)``: ``max |block|`` of every stored block of the
        product and that of each block row's diagonal block (0 without one), computed
        while each row is in cache; None on the scipy path.

    Returns
    -------
    scipy.sparse.bsr_array of blocksize ``(R, S)``; with numba, sorted block columns.
    With ``block_sizes``, the tuple ``(product, sizes)``.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from pdlin._kernels import bsr_matmul
    >>> A = sp.bsr_array(np.arange(24.0).reshape(4, 6), blocksize=(2, 3))
    >>> C = bsr_matmul(A, sp.bsr_array(A.T, blocksize=(3, 2)))
    >>> C.blocksize, bool(np.array_equal(C.toarray(), A.toarray() @ A.toarray().T))
    ((2, 2), True)
    """
    R, N = A.blocksize
    N2, S = B.blocksize
    if A.shape[1] != B.shape[0] or N != N2:
        raise ValueError(f"bsr_matmul: blocks {A.blocksize} x {B.blocksize} do not chain")
    real = A.dtype == np.float64 and B.dtype == np.float64
    mod = _kernels() if real and use_numba(A.nnz * S) else None
    if mod is None:
        prod = sp.bsr_array(A @ B, blocksize=(R, S))
        return (prod, None) if block_sizes else prod
    a_ptr = np.asarray(A.indptr, dtype=np.int64)
    b_ptr = np.asarray(B.indptr, dtype=np.int64)
    a_ind = np.ascontiguousarray(A.indices)
    b_ind = np.ascontiguousarray(B.indices)
    if b_ind.dtype != a_ind.dtype:
        a_ind = a_ind.astype(np.int64)
        b_ind = b_ind.astype(np.int64)
    a_dat = np.ascontiguousarray(A.data)
    b_dat = np.ascontiguousarray(B.data)
    n_row = A.shape[0] // R
    n_bcol = B.shape[1] // S
    n_chunks = 4 * get_num_threads()
    with _lock:
        _set_threads()
        nnz, work = mod.bsr_row_counts(a_ptr, a_ind, b_ptr, b_ind, n_bcol, _edges(a_ptr, n_chunks))
    c_ptr = np.zeros(n_row + 1, dtype=np.int64)
    np.cumsum(nnz, out=c_ptr[1:])
    total = int(c_ptr[-1])
    idt = np.int32 if max(total, n_bcol) < np.iinfo(np.int32).max else np.int64
    c_ind = np.empty(total, dtype=idt)
    c_dat = np.empty((total, R, S))
    cum = np.zeros(n_row + 1, dtype=np.int64)
    np.cumsum(work, out=cum[1:])
    sizes: tuple[np.ndarray, np.ndarray] | None = None
    with _lock:
        _set_threads()
        if block_sizes:
            sizes = (np.empty(total), np.empty(n_row))
            mod.bsr_fill_sizes(
                a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat, n_bcol,
                _edges(cum, n_chunks), *sizes,
            )  # fmt: skip
        else:
            mod.bsr_fill(
                a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat, n_bcol,
                _edges(cum, n_chunks),
            )  # fmt: skip
    out = sp.bsr_array(
        (c_dat, c_ind, c_ptr.astype(idt)), shape=(A.shape[0], B.shape[1]), blocksize=(R, S)
    )
    out.has_sorted_indices = True
    if block_sizes:
        return out, sizes
    return out


def _index_dtype(*maxvals: int) -> type[np.signedinteger[Any]]:
    return np.int32 if max(maxvals, default=0) < np.iinfo(np.int32).max else np.int64


def _pieces(X: Any, d: int) -> list[sp.csr_array]:
    """Return the CSR pieces of a vertical stack (one array or a sequence), checked to chain."""
    parts = [sp.csr_array(x) for x in (X if isinstance(X, (list, tuple)) else [X])]
    if not parts:
        raise ValueError("csr block conversion: no array given")
    n_col = parts[0].shape[1]
    if n_col % d or any(x.shape[1] != n_col for x in parts):
        shapes = [x.shape for x in parts]
        raise ValueError(f"csr block conversion: shapes {shapes} do not stack in {d} columns")
    return parts


def _csr_arrays(X: sp.csr_array) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return (
        np.asarray(X.indptr, dtype=np.int64),
        np.ascontiguousarray(X.indices),
        np.ascontiguousarray(X.data),
    )


def _numba_for(parts: list[sp.csr_array]) -> ModuleType | None:
    real = all(x.dtype == np.float64 for x in parts)
    return _kernels() if real and use_numba(sum(x.nnz for x in parts)) else None


def csr_to_bsr_t(X: Any, d: int) -> sp.bsr_array:
    """``Xᵀ`` of a CSR array ``X`` (``m x n·d``) as a BSR array in ``d x 1`` blocks.

    ``X`` may be a sequence of CSR arrays, the pieces of a vertical stack (not built).
    Block row ``p`` holds the rows of ``X`` with an entry in the columns of point ``p``,
    sorted; a block is ``0 + x₁ + x₂ ...`` over the entries of one row of ``X`` in storage
    order.  Without numba this is scipy's
    ``sp.vstack(X, format="csr").T.tocsr().tobsr(blocksize=(d, 1))`` with sorted block
    indices; with numba the conversion runs over row chunks of ``X`` on
    :func:`pdlin.get_num_threads` threads and gives the same arrays bitwise (for
    canonical pieces: no duplicate entries).  scipy's conversion alone orders the blocks
    of a row by first appearance, which is the sorted order when every row of ``X``
    stores whole ``d``-blocks (the LPS / XOSB factors: explicit zeros included).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from pdlin._kernels import csr_to_bsr_t
    >>> X = sp.csr_array(np.arange(12.0).reshape(3, 4))
    >>> Xt = csr_to_bsr_t([X, 2 * X], 2)
    >>> stack = np.vstack([X.toarray(), 2 * X.toarray()])
    >>> Xt.blocksize, bool(np.array_equal(Xt.toarray(), stack.T))
    ((2, 1), True)
    """
    parts = _pieces(X, d)
    mod = _numba_for(parts)
    if mod is None:
        stack = parts[0] if len(parts) == 1 else sp.vstack(parts, format="csr")
        Xt = sp.bsr_array(stack.T.tocsr().tobsr(blocksize=(d, 1)))
        Xt.sort_indices()
        return Xt
    n_row = sum(x.shape[0] for x in parts)
    n_pts = parts[0].shape[1] // d
    arrays = [_csr_arrays(x) for x in parts]
    # one chunk per thread: counts and offsets take 16 bytes per (chunk, point)
    edges = [_edges(a[0], get_num_threads()) for a in arrays]
    with _lock:
        _set_threads()
        cnt = [
            mod.csr_t_block_counts(a[0], a[1], d, n_pts, e)
            for a, e in zip(arrays, edges, strict=True)
        ]
    out_ptr, off = mod.csr_t_block_offsets(cnt[0] if len(cnt) == 1 else np.concatenate(cnt))
    del cnt
    total = int(out_ptr[-1])
    idt = _index_dtype(total, n_row)
    out_ind = np.empty(total, dtype=idt)
    out_dat = np.empty((total, d, 1))
    c0 = r0 = 0
    with _lock:
        _set_threads()
        for x, (ptr, ind, dat), e in zip(parts, arrays, edges, strict=True):
            c1 = c0 + e.size - 1
            mod.csr_t_block_fill(ptr, ind, dat, d, off[c0:c1], e, r0, out_ind, out_dat)
            c0, r0 = c1, r0 + x.shape[0]
    out = sp.bsr_array(
        (out_dat, out_ind, out_ptr.astype(idt)), shape=(n_pts * d, n_row), blocksize=(d, 1)
    )
    out.has_sorted_indices = True
    return out


def csr_to_bsr_rows(X: Any, d: int) -> sp.bsr_array:
    """Convert a CSR array ``X`` (``m x n·d``) to a BSR array in ``1 x d`` blocks.

    ``X`` may be a sequence of CSR arrays, the pieces of a vertical stack (not built).
    Equal, bitwise and in block order, to scipy's
    ``sp.vstack(X, format="csr").tobsr(blocksize=(1, d))`` (blocks of a row in order of
    first appearance, each ``0 + x₁ + x₂ ...`` over its entries in storage order), which
    is what runs without numba; with numba the conversion runs over row chunks on
    :func:`pdlin.get_num_threads` threads (for canonical pieces: no duplicate entries).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from pdlin._kernels import csr_to_bsr_rows
    >>> X = sp.csr_array(np.arange(12.0).reshape(3, 4))
    >>> Xb = csr_to_bsr_rows([X, 2 * X], 2)
    >>> stack = np.vstack([X.toarray(), 2 * X.toarray()])
    >>> Xb.blocksize, bool(np.array_equal(Xb.toarray(), stack))
    ((1, 2), True)
    """
    parts = _pieces(X, d)
    mod = _numba_for(parts)
    if mod is None:
        stack = parts[0] if len(parts) == 1 else sp.vstack(parts, format="csr")
        return sp.bsr_array(stack.tobsr(blocksize=(1, d)))
    n_row = sum(x.shape[0] for x in parts)
    n_pts = parts[0].shape[1] // d
    arrays = [_csr_arrays(x) for x in parts]
    edges = [_edges(a[0], 4 * get_num_threads()) for a in arrays]
    with _lock:
        _set_threads()
        nnz = [
            mod.csr_row_block_counts(a[0], a[1], d, n_pts, e)
            for a, e in zip(arrays, edges, strict=True)
        ]
    out_ptr = np.zeros(n_row + 1, dtype=np.int64)
    np.cumsum(np.concatenate(nnz), out=out_ptr[1:])
    del nnz
    total = int(out_ptr[-1])
    idt = _index_dtype(total, n_pts)
    out_ind = np.empty(total, dtype=idt)
    out_dat = np.empty((total, 1, d))
    r0 = 0
    with _lock:
        _set_threads()
        for x, (ptr, ind, dat), e in zip(parts, arrays, edges, strict=True):
            mod.csr_row_block_fill(ptr, ind, dat, d, n_pts, out_ptr[r0:], e, out_ind, out_dat)
            r0 += x.shape[0]
    return sp.bsr_array(
        (out_dat, out_ind, out_ptr.astype(idt)), shape=(n_row, n_pts * d), blocksize=(1, d)
    )


def bsr_transpose(A: Any) -> sp.bsr_array:
    """``Aᵀ`` of a BSR array (blocks ``R x C`` become ``C x R``), sorted block columns.

    Equal, bitwise, to scipy's ``sp.bsr_array(A.T)`` for an ``A`` without repeated block
    columns in a row, which is what runs without numba; with numba the blocks are moved
    over row chunks of ``A`` on :func:`pdlin.get_num_threads` threads.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from pdlin._kernels import bsr_transpose
    >>> A = sp.bsr_array(np.arange(24.0).reshape(4, 6), blocksize=(2, 3))
    >>> At = bsr_transpose(A)
    >>> At.blocksize, bool(np.array_equal(At.toarray(), A.toarray().T))
    ((3, 2), True)
    """
    A = sp.bsr_array(A)
    R, C = A.blocksize
    mod = _kernels() if A.dtype == np.float64 and use_numba(A.nnz) else None
    if mod is None:
        return sp.bsr_array(A.T)
    ptr = np.asarray(A.indptr, dtype=np.int64)
    ind = np.ascontiguousarray(A.indices)
    dat = np.ascontiguousarray(A.data)
    n_bcol = A.shape[1] // C
    edges = _edges(ptr, get_num_threads())  # one chunk per thread (16 B per column each)
    with _lock:
        _set_threads()
        cnt = mod.csr_t_block_counts(ptr, ind, 1, n_bcol, edges)
    out_ptr, off = mod.csr_t_block_offsets(cnt)
    del cnt
    total = int(out_ptr[-1])
    idt = _index_dtype(total, A.shape[0] // R)
    out_ind = np.empty(total, dtype=idt)
    out_dat = np.empty((total, C, R))
    with _lock:
        _set_threads()
        mod.bsr_t_fill(ptr, ind, dat, off, edges, out_ind, out_dat)
    out = sp.bsr_array(
        (out_dat, out_ind, out_ptr.astype(idt)), shape=(A.shape[1], A.shape[0]), blocksize=(C, R)
    )
    out.has_sorted_indices = True
    return out
