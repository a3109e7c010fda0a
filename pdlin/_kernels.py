"""Optional compiled kernels (numba) for the sparse products that scipy runs on one core.

scipy's sparse products (sparsetools) hold the GIL, so threads cannot share them.  With
numba installed (``pip install "pdlin[fast]"``) these products run row-parallel on
:func:`pdlin.get_num_threads` threads instead:

- :func:`bsr_matmul`: ``A @ B`` of two BSR arrays (block sizes ``R x N`` and ``N x S``,
  any of 1, 2, 3, ...), a two-pass row-parallel Gustavson product (blocks per row, then
  sorted block columns and values); used by the LPS / XOSB assembly (``Yᵀ X``) and the
  correspondence assembly (``Wᵀ W``, ``Bᵀ (D B)`` and the tangent ``Gᵀ (A G)``);
- :func:`csr_matvec`: ``A @ x`` of a CSR array (the matrix-free products of LPS / XOSB
  and correspondence).

Each output row is computed by one thread in a fixed order, so results are bitwise
identical for any thread count, and the arithmetic is scipy's (same operations in the
same order: equal values; the BSR product's block columns come out sorted where scipy
leaves them unsorted).  Without numba, or with ``PDLIN_NUMBA=0`` in the environment,
every function is the plain scipy product.  The first call compiles the kernels (a few
seconds, ``cache=True`` keeps them on disk for later processes).
"""

from __future__ import annotations

import logging
import os
import threading
from types import ModuleType
from typing import Any

import numpy as np
import scipy.sparse as sp

from ._threads import get_num_threads

__all__ = ["numba_enabled", "use_numba", "bsr_matmul", "csr_matvec"]

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

#: smallest product (block products) / mat-vec (stored entries) sent to numba: below it
#: scipy's call overhead is smaller than the threads' start-up
_MIN_WORK = 1 << 14


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


def bsr_matmul(A: Any, B: Any) -> sp.bsr_array:
    """``A @ B`` of two BSR arrays whose block sizes chain (``R x N`` times ``N x S``).

    Parameters
    ----------
    A, B : scipy.sparse BSR arrays (real)

    Returns
    -------
    scipy.sparse.bsr_array of blocksize ``(R, S)``; with numba, sorted block columns.

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
        return sp.bsr_array(A @ B, blocksize=(R, S))
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
    with _lock:
        _set_threads()
        mod.bsr_fill(
            a_ptr, a_ind, a_dat, b_ptr, b_ind, b_dat, c_ptr, c_ind, c_dat, n_bcol,
            _edges(cum, n_chunks),
        )  # fmt: skip
    out = sp.bsr_array(
        (c_dat, c_ind, c_ptr.astype(idt)), shape=(A.shape[0], B.shape[1]), blocksize=(R, S)
    )
    out.has_sorted_indices = True
    return out


def csr_matvec(A: Any, x: np.ndarray) -> np.ndarray:
    """``A @ x`` of a CSR array and a vector (row-parallel with numba, else scipy).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from pdlin._kernels import csr_matvec
    >>> A = sp.csr_array(np.array([[1.0, 0.0, 2.0], [0.0, 3.0, 0.0]]))
    >>> csr_matvec(A, np.array([1.0, 1.0, 1.0]))
    array([3., 3.])
    """
    xv = np.asarray(x)
    real = A.dtype == np.float64 and xv.dtype == np.float64
    mod = _kernels() if real and use_numba(A.nnz) else None
    if mod is None:
        return np.asarray(A @ xv)
    if xv.shape != (A.shape[1],):
        raise ValueError(f"csr_matvec: x must have shape ({A.shape[1]},), got {xv.shape}")
    ptr = np.asarray(A.indptr, dtype=np.int64)
    edges = _edges(ptr, 4 * get_num_threads())
    with _lock:
        _set_threads()
        return np.asarray(mod.csr_matvec(ptr, A.indices, A.data, np.ascontiguousarray(xv), edges))
