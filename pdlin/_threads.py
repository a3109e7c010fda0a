"""Thread count of pdlin's parallel kernels.

Three kinds of work run on :func:`get_num_threads` threads:

- numpy kernels on pdlin's thread pool (:func:`thread_map`): the bond-based assembly
  (block formation, scatter, per-row sums by ``np.add.reduceat``, the bond coefficients),
  the LPS / XOSB factors (the point operators ``Pᵀ diag(c) B`` written sorted in place,
  the bond operator ``B`` and its weighted copy) and, in the correspondence assembly, the
  bond coefficients, the shape tensors, ``Pᵀ C P`` per gradient point, the blocks of G
  (no control), the dense block products and the zero-block dropping; the XOSB weights.
  The hot loops run over fixed chunks of owner rows, bonds or block rows (bonds of a row
  are contiguous); each chunk writes its own slots of the output while numpy releases the
  GIL inside its array operations.
- with the optional extra ``pdlin[fast]`` (numba), the sparse products of the LPS / XOSB /
  correspondence assembly, the block conversions of the LPS / XOSB factors and the BSR
  transpose of the correspondence ``Wᵀ W`` (:mod:`pdlin._kernels`, numba ``prange`` over
  row chunks).  Without numba they are scipy's sparsetools and stay serial, as do the
  linear solvers' matrix-free mat-vecs.
- :class:`RowBlocks`: the CSR mat-vecs of the nonlinear correspondence iterations
  (``G u``, ``Gᵀ (w V P)``, a penalty's ``K_c u``) in fixed row blocks; scipy's CSR
  mat-vec releases the GIL, so the blocks run in parallel (1.4-1.5 x on two threads at
  10⁵ points).

Every chunk does the same arithmetic in the same order whatever the thread count, so
results are bitwise identical for 1, 2, ... threads.

The count is ``pdlin.set_num_threads(n)``, else the environment variable
``PDLIN_NUM_THREADS``, else the CPUs this process may run on (its affinity mask); numba's
kernels use the same count (capped at numba's ``NUMBA_NUM_THREADS``).  BLAS / MKL threads
of the direct backends follow their own variables (``OPENBLAS_NUM_THREADS``,
``MKL_NUM_THREADS``, ``OMP_NUM_THREADS``); the OpenBLAS of CHOLMOD and MUMPS is also capped
at this count during their factorizations.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import numpy as np

from .errors import InputError, InputTypeError

__all__ = ["set_num_threads", "get_num_threads", "thread_map", "RowBlocks"]

T = TypeVar("T")

_lock = threading.Lock()
_n_threads: int | None = None
_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_local = threading.local()


def _after_fork_in_child() -> None:
    """Start the pool afresh in a forked child (it inherits the object, not the threads)."""
    global _lock, _pool, _pool_size
    _lock = threading.Lock()
    _pool = None
    _pool_size = 0
    _local.__dict__.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)


def _cpu_count() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def _from_env() -> int | None:
    raw = os.environ.get("PDLIN_NUM_THREADS")
    if raw is None or raw.strip() == "":
        return None
    try:
        n = int(raw)
    except ValueError:
        raise InputError(f"PDLIN_NUM_THREADS must be an integer >= 1, got {raw!r}") from None
    if n < 1:
        raise InputError(f"PDLIN_NUM_THREADS must be an integer >= 1, got {raw!r}")
    return n


def set_num_threads(n: int | None) -> None:
    """Set the number of threads of pdlin's chunked kernels.

    Parameters
    ----------
    n : int or None
        Threads (>= 1); ``1`` runs every chunk on the calling thread (the
        single-threaded behaviour).  ``None`` restores the default:
        ``PDLIN_NUM_THREADS`` when set, else the CPUs of the affinity mask.

    Raises
    ------
    InputError
        When ``n`` is not an integer >= 1.

    Examples
    --------
    >>> import pdlin
    >>> pdlin.set_num_threads(1)
    >>> pdlin.get_num_threads()
    1
    >>> pdlin.set_num_threads(None)
    """
    global _n_threads
    if n is not None:
        if isinstance(n, bool) or not isinstance(n, int):
            raise InputTypeError(f"set_num_threads: n must be an integer >= 1, got {n!r}")
        if n < 1:
            raise InputError(f"set_num_threads: n must be an integer >= 1, got {n}")
    with _lock:
        _n_threads = n


def get_num_threads() -> int:
    """Threads pdlin's chunked kernels use now (see :func:`set_num_threads`).

    Examples
    --------
    >>> import pdlin
    >>> pdlin.get_num_threads() >= 1
    True
    """
    if _n_threads is not None:
        return _n_threads
    env = _from_env()
    return env if env is not None else _cpu_count()


def _executor(n: int) -> ThreadPoolExecutor:
    global _pool, _pool_size
    with _lock:
        if _pool is None or _pool_size != n:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(max_workers=n, thread_name_prefix="pdlin")
            _pool_size = n
        return _pool


def thread_map(fn: Callable[[T], Any], items: Iterable[T]) -> list[Any]:
    """``[fn(x) for x in items]``, spread over :func:`get_num_threads` threads.

    Results come back in the order of ``items``.  Calls made from inside a
    worker run serially (no nested pools).  ``fn`` must only write to memory
    no other item writes.

    Examples
    --------
    >>> thread_map(lambda x: x * x, range(5))
    [0, 1, 4, 9, 16]
    """
    seq: Sequence[T] = items if isinstance(items, Sequence) else list(items)
    n = get_num_threads()
    if n <= 1 or len(seq) <= 1 or getattr(_local, "inside", False):
        return [fn(x) for x in seq]

    def run(x: T) -> Any:
        _local.inside = True
        try:
            return fn(x)
        finally:
            _local.inside = False

    return list(_executor(n).map(run, seq))


def even_chunks(n: int, size: int) -> list[tuple[int, int]]:
    """Ranges ``[a, b)`` of ``size`` items covering ``range(n)`` (the last one shorter).

    Examples
    --------
    >>> even_chunks(5, 2)
    [(0, 2), (2, 4), (4, 5)]
    """
    return [(a, min(a + size, n)) for a in range(0, n, size)]


def ptr_chunks(ptr: Any, size: int) -> list[tuple[int, int]]:
    """Split the rows of a CSR-style row pointer into ranges of about ``size`` entries.

    Rows are never split; empty input gives one range.

    Examples
    --------
    >>> ptr_chunks(np.array([0, 3, 3, 7, 8]), 4)
    [(0, 2), (2, 4)]
    """
    p = np.asarray(ptr, dtype=np.int64)
    n = p.size - 1
    starts = np.searchsorted(p, np.arange(0, max(int(p[-1]), 1), size), side="right") - 1
    edges = np.unique(np.concatenate([[0], np.clip(starts, 0, n), [n]]))
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


#: stored entries per row block of :class:`RowBlocks` (fixed: the products do not depend
#: on the thread count; the correspondence iterations use blocks from two blocks' worth)
ROW_BLOCK_NNZ = 200_000


class RowBlocks:
    """A CSR matrix cut into row blocks whose mat-vecs run on pdlin's threads.

    scipy's CSR mat-vec releases the GIL, so the blocks' products ``A[a:b] @ x`` run
    in parallel; every row is computed as in ``A @ x`` (the same entries in the same
    order), so the result equals ``A @ x`` bitwise for any thread count.  The blocks are
    views of the CSR arrays (no copy of a CSR input; a CSC input, e.g. the transpose of
    a CSR matrix, is converted once).  Measured on the 316² polycrystal's
    gradient operator (1.6·10⁶ entries) and penalty stiffness (3.6·10⁶), both since
    halved by dropping stored zeros, on two threads in blocks of 4·10⁵ entries: 0.80 →
    0.59 and 1.58 → 1.04 ms (docs/large_problems.md).

    Parameters
    ----------
    A : sparse array or matrix
        Converted to CSR (a CSC ``Aᵀ`` of a CSR matrix becomes the CSR of the
        transpose: its rows sum in the order of ``A.T @ x``, bitwise equal to it).
    nnz : int
        Stored entries per block (rows are never split).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> A = sp.random_array((500, 300), density=0.05, rng=1, format="csr")
    >>> x = np.arange(300.0)
    >>> R = RowBlocks(A, nnz=1000)
    >>> len(R.blocks) > 1, bool(np.array_equal(R @ x, A @ x))
    (True, True)
    """

    def __init__(self, A: Any, nnz: int = ROW_BLOCK_NNZ) -> None:
        import scipy.sparse as sp

        csr = sp.csr_array(A)
        self.shape: tuple[int, int] = (int(csr.shape[0]), int(csr.shape[1]))
        self.ranges = ptr_chunks(csr.indptr, max(int(nnz), 1))
        self.blocks = []
        for a, b in self.ranges:
            # rows a..b as views of data / indices (the constructor would copy them)
            s0, s1 = int(csr.indptr[a]), int(csr.indptr[b])
            blk = sp.csr_array((b - a, self.shape[1]), dtype=csr.dtype)
            blk.data, blk.indices = csr.data[s0:s1], csr.indices[s0:s1]
            blk.indptr = csr.indptr[a : b + 1] - csr.indptr.dtype.type(s0)
            self.blocks.append(blk)

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        y = np.empty(self.shape[0], dtype=np.result_type(x, *(b.dtype for b in self.blocks)))

        def run(k: int) -> None:
            a, b = self.ranges[k]
            y[a:b] = self.blocks[k] @ x

        thread_map(run, range(len(self.blocks)))
        return y
