"""Thread count of pdlin's chunked kernels (assembly, matrix-free products).

pdlin's hot loops run over independent chunks of owner rows (bonds of a row are
contiguous); each chunk writes its own slots of the output, so chunks can run on
several threads while numpy releases the GIL inside its array operations.  Every
chunk does the same arithmetic in the same order whatever the thread count, so
results are bitwise identical for 1, 2, ... threads.

The count is ``pdlin.set_num_threads(n)``, else the environment variable
``PDLIN_NUM_THREADS``, else the CPUs this process may run on (its affinity mask).
BLAS / MKL threads of the direct backends follow their own variables
(``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS``, ``OMP_NUM_THREADS``).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

from .errors import InputError, InputTypeError

__all__ = ["set_num_threads", "get_num_threads", "thread_map", "sparse_product", "RowChunked"]

T = TypeVar("T")

_lock = threading.Lock()
_n_threads: int | None = None
_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_local = threading.local()


def _after_fork_in_child() -> None:
    """A forked child inherits the pool object but not its threads: start afresh."""
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


def _row_edges(indptr: Any, n_rows: int, parts: int) -> list[int]:
    """Block-row boundaries cutting ``indptr`` into ``parts`` pieces of equal stored size."""
    import numpy as np

    ptr = np.asarray(indptr)
    cuts = np.searchsorted(ptr, np.linspace(0, ptr[-1], parts + 1)[1:-1])
    return np.unique(np.concatenate([[0], cuts, [n_rows]])).astype(int).tolist()


def _row_slice(A: Any, a: int, b: int) -> Any:
    """Block rows ``a:b`` of a CSR / BSR array as a view-backed array of the same format."""
    import scipy.sparse as sp

    ptr = A.indptr[a : b + 1]
    s0, s1 = int(ptr[0]), int(ptr[-1])
    if A.format == "bsr":
        r, c = A.blocksize
        return sp.bsr_array(
            (A.data[s0:s1], A.indices[s0:s1], ptr - s0),
            shape=((b - a) * r, A.shape[1]),
            blocksize=(r, c),
        )
    return sp.csr_array((A.data[s0:s1], A.indices[s0:s1], ptr - s0), shape=(b - a, A.shape[1]))


def sparse_product(A: Any, B: Any) -> Any:
    """``A @ B`` for CSR / BSR ``A``, computed in chunks of ``A``'s rows on threads.

    scipy's sparsetools builds each row of the product independently (and releases
    the GIL), so the chunked product is bitwise the one-call product for any thread
    count.  The result has ``A``'s format (BSR blocks ``(A rows, B cols)``).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> A = sp.random_array((50, 40), density=0.2, rng=0, format="csr")
    >>> B = sp.random_array((40, 30), density=0.2, rng=1, format="csr")
    >>> bool(np.array_equal(sparse_product(A, B).toarray(), (A @ B).toarray()))
    True
    """
    import numpy as np
    import scipy.sparse as sp

    bsr = A.format == "bsr"
    r = A.blocksize[0] if bsr else 1
    nbr = A.shape[0] // r
    nt = get_num_threads()
    if nt <= 1 or nbr < 8 * nt or A.format not in ("csr", "bsr"):
        return A @ B
    edges = _row_edges(A.indptr, nbr, 4 * nt)

    def part(k: int) -> Any:
        return _row_slice(A, edges[k], edges[k + 1]) @ B

    parts = thread_map(part, range(len(edges) - 1))
    if bsr:
        blk = parts[0].blocksize if parts[0].format == "bsr" else (r, 1)
        parts = [sp.bsr_array(q, blocksize=blk) for q in parts]
    else:
        parts = [sp.csr_array(q) for q in parts]
    offs = np.cumsum([0] + [int(q.indptr[-1]) for q in parts]).tolist()
    data = np.empty((offs[-1], *parts[0].data.shape[1:]))
    indices = np.empty(offs[-1], dtype=np.int64)
    indptr = np.empty(nbr + 1, dtype=np.int64)
    indptr[0] = 0

    def gather(k: int) -> None:  # the copies (and first touches of the pages) on threads
        q, o = parts[k], offs[k]
        data[o : offs[k + 1]] = q.data
        indices[o : offs[k + 1]] = q.indices
        indptr[edges[k] + 1 : edges[k + 1] + 1] = q.indptr[1:] + o

    thread_map(gather, range(len(parts)))
    if offs[-1] < np.iinfo(np.int32).max and B.shape[1] < np.iinfo(np.int32).max:
        indptr = indptr.astype(np.int32)
        indices = indices.astype(np.int32)
    shape = (A.shape[0], B.shape[1])
    if bsr:
        return sp.bsr_array((data, indices, indptr), shape=shape, blocksize=parts[0].blocksize)
    return sp.csr_array((data, indices, indptr), shape=shape)


class RowChunked:
    """A CSR / BSR array whose products with vectors run in row chunks on threads.

    ``M @ x`` computes each chunk's rows with scipy's matvec (GIL released) into its
    slice of the output: bitwise the one-call product, for any thread count.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> A = sp.random_array((300, 200), density=0.05, rng=0, format="csr")
    >>> x = np.arange(200.0)
    >>> bool(np.array_equal(RowChunked(A) @ x, A @ x))
    True
    """

    def __init__(self, A: Any) -> None:
        import scipy.sparse as sp

        if A.format not in ("csr", "bsr"):
            A = sp.csr_array(A)
        self.A = A
        self.shape = A.shape
        self.dtype = A.dtype
        r = A.blocksize[0] if A.format == "bsr" else 1
        nbr = A.shape[0] // r
        parts = max(1, 4 * _cpu_count())
        edges = _row_edges(A.indptr, nbr, parts) if nbr >= 8 * parts else [0, nbr]
        self._rows = [(edges[k] * r, edges[k + 1] * r) for k in range(len(edges) - 1)]
        self._chunks = [_row_slice(A, edges[k], edges[k + 1]) for k in range(len(edges) - 1)]

    def __matmul__(self, x: Any) -> Any:
        import numpy as np

        x = np.asarray(x)
        if get_num_threads() <= 1 or len(self._chunks) == 1:
            return self.A @ x
        out = np.empty((self.shape[0], *x.shape[1:]), dtype=np.result_type(self.dtype, x))

        def chunk(k: int) -> None:
            a, b = self._rows[k]
            out[a:b] = self._chunks[k] @ x

        thread_map(chunk, range(len(self._chunks)))
        return out
