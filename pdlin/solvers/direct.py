"""Sparse direct factorizations behind ``solver="direct"``: SuperLU, CHOLMOD, PARDISO.

SuperLU (scipy) is always present.  The optional backends are imported lazily:

* ``'cholmod'``: supernodal Cholesky of SuiteSparse through ``scikit-sparse``
  (no wheels: ``apt-get install libsuitesparse-dev`` then ``pip install
  scikit-sparse``, ``==0.4.16`` for SuiteSparse 5 as in Debian 12; an
  optimized BLAS such as ``libopenblas0-pthread`` makes it fast).
  Symmetric positive definite matrices only.
* ``'pardiso'``: Intel MKL PARDISO through ``pypardiso`` (``pip install
  "pdlin[direct]"``, MKL wheels): ``mtype 2`` (SPD, upper triangle) for
  symmetric matrices, ``mtype 11`` (real nonsymmetric) otherwise.
* ``'mumps'``: the multifrontal MUMPS (sequential) through ``python-mumps``
  >= 0.0.4, which builds from source against Debian's ``libmumps-seq-dev``
  (``apt-get install libmumps-seq-dev && pip install python-mumps``; the
  0.0.2 wheels on PyPI are built for numpy 1 and do not load): LDLᵀ on the
  upper triangle for symmetric matrices, LU otherwise, SCOTCH ordering when
  available.

``backend='auto'`` picks PARDISO, then CHOLMOD (CHOLMOD first when pdlin runs on
one thread or the matrix is 3D: a BSR matrix of 3 x 3 blocks), then MUMPS, then
SuperLU for symmetric matrices and PARDISO, then SuperLU for nonsymmetric ones (SuperLU alone below
:data:`~pdlin.solvers.AUTO_MIN` unknowns); a Cholesky that
finds the matrix not positive definite falls back down the list and the
reason is kept in :attr:`DirectSolver.info` (``'fallback'``).
"""

from __future__ import annotations

import ctypes
import glob
import importlib
import logging
import os
import site
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._threads import get_num_threads
from ..errors import (
    ConvergenceError,
    InputError,
    InsufficientMemoryError,
    MissingDependencyError,
)
from ..resources import (
    SUPERLU_WORKSPACE,
    available_memory,
    check_memory,
    direct_factor_bytes,
    direct_factor_nnz,
    format_bytes,
)

__all__ = ["DIRECT_BACKENDS", "AUTO_MIN", "available_direct_backends", "DirectSolver"]

log = logging.getLogger(__name__)

#: names accepted by ``direct_backend=``
DIRECT_BACKENDS = ("auto", "superlu", "cholmod", "pardiso", "mumps")

#: module imported for each optional backend, and how to install it
_MODULES = {"cholmod": "sksparse.cholmod", "pardiso": "pypardiso", "mumps": "mumps"}
_INSTALL = {
    "cholmod": "apt-get install libsuitesparse-dev && pip install scikit-sparse (SuiteSparse 5, "
    "e.g. Debian 12: scikit-sparse==0.4.16)",
    "pardiso": 'pip install "pdlin[direct]" (pypardiso with the MKL wheels)',
    "mumps": "apt-get install libmumps-seq-dev && pip install 'python-mumps>=0.0.4'",
}


class _NotPositiveDefinite(Exception):
    """A Cholesky factorization met a non-positive pivot."""


def _mkl_rt_path() -> str | None:
    """Find the MKL runtime library of the pip ``mkl`` wheel (``<prefix>/lib/libmkl_rt.so.N``).

    pypardiso looks for it on every solver it creates (``find_library``, then a recursive
    glob of the environment: 0.35-0.7 s each, measured; its import creates one solver)
    unless ``PYPARDISO_MKL_RT`` names it, so pdlin finds it once, non-recursively.
    """
    for base in (sys.prefix, site.USER_BASE or ""):
        hits = [
            path
            for pattern in ("lib/libmkl_rt.so*", "lib/libmkl_rt*.dylib", "Library/bin/mkl_rt*.dll")
            for path in glob.glob(os.path.join(base, pattern))
        ]
        if hits:
            return min(hits, key=len)
    return None


def _import(name: str) -> Any:
    """Import the module of backend ``name`` or raise MissingDependencyError."""
    if name == "pardiso" and not os.environ.get("PYPARDISO_MKL_RT"):
        path = _mkl_rt_path()
        if path is not None:  # pypardiso's own variable: skips its search in every solver
            os.environ["PYPARDISO_MKL_RT"] = path
    try:
        return importlib.import_module(_MODULES[name])
    except Exception as exc:  # ImportError, or a binary built against another numpy
        raise MissingDependencyError(
            f"direct_backend={name!r} is not installed or does not load ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0][:120] if str(exc) else ''}); install it with "
            f"{_INSTALL[name]}, or use direct_backend='auto' or 'superlu'"
        ) from exc


def available_direct_backends() -> dict[str, bool]:
    """Which direct backends load in this environment.

    Returns
    -------
    dict
        ``{'superlu': True, 'cholmod': bool, 'pardiso': bool, 'mumps': bool}``.

    Examples
    --------
    >>> available_direct_backends()["superlu"]
    True
    """
    out = {"superlu": True}
    for name in ("cholmod", "pardiso", "mumps"):
        try:
            _import(name)
            out[name] = True
        except MissingDependencyError:
            out[name] = False
    return out


#: ``'auto'`` uses the optional backends from this many unknowns on.  Below, SuperLU is
#: fast (< 1 s), PARDISO's analysis and thread start-up alone take 0.3-0.7 s (measured at
#: n = 100), and small solves keep SuperLU's measured round-off (``tests/extremes``: a 1D
#: bar at contrast 1e4 loses 10x more digits under CHOLMOD's nested-dissection order)
AUTO_MIN = 20_000


def auto_chain(symmetric: bool, n: int, dim: int | None = None) -> list[str]:
    """Return the direct backends ``backend="auto"`` tries, fastest first.

    Parameters
    ----------
    symmetric : bool
        Whether the matrix is symmetric (CHOLMOD applies only then).
    n : int
        Number of unknowns; below ``AUTO_MIN`` SuperLU alone is used (the others' set-up
        costs more than it saves).
    dim : int, optional
        Spatial dimension of the problem (2 or 3; :class:`DirectSolver` takes it from the
        block size of a BSR matrix), ``None`` when unknown (then treated as 2D).

    Returns
    -------
    list of str
        Names of the installed backends in the order they are tried.

    Examples
    --------
    >>> auto_chain(True, 10)
    ['superlu']
    """
    avail = available_direct_backends()
    if n < AUTO_MIN:
        return ["superlu"]
    if not symmetric:
        return [b for b in ("pardiso", "mumps", "superlu") if avail[b]]
    # symmetric (benchmarks/README.md, "CHOLMOD or PARDISO: by dimension and threads (issue
    # 33)"; 2 cores, AMD EPYC, OpenBLAS 0.3.21 / MKL 2026.2):
    # - one thread: CHOLMOD (2D 401² no control 14.2 vs 17.2 s; 3D 1.6-1.9 x fewer CPU s);
    # - several threads, 3D: CHOLMOD (30³ bond-based δ = 2.015h 17-21 vs 31-34 CPU s, 20³
    #   LPS 8-11 vs 14-16 CPU s; PARDISO's 2 threads gain little in 3D and lose most
    #   under load);
    # - several threads, 2D: PARDISO (quiet 2 cores, 401²: 8.6 vs 9.9 s no control, 4.4
    #   vs 6.9 s stress points; under load the two are within the noise)
    cholmod_first = get_num_threads() == 1 or dim == 3
    order = ["cholmod", "pardiso"] if cholmod_first else ["pardiso", "cholmod"]
    return [b for b in [*order, "mumps", "superlu"] if avail[b]]


#: former private name, kept for code that patched or called it
_auto_chain = auto_chain


# -- backends ------------------------------------------------------------------------------


class _SuperLU:
    name = "superlu"

    def __init__(self, A: sp.csc_matrix, symmetric: bool) -> None:
        self.symmetric = symmetric
        self._factor(A)

    def _factor(self, csc: sp.csc_matrix) -> None:
        if self.symmetric or _pattern_symmetric(csc):
            # symmetric mode: a symmetric ordering of A + Aᵀ.  Symmetric A: diagonal
            # pivots.  Nonsymmetric values on a symmetric pattern (e.g. the consistent
            # tangent Gᵀ (dP/dF) G of crystal plasticity): a preference for diagonal pivots
            # (threshold partial pivoting kept) fills in less than COLAMD (measured 31 vs
            # 72 ms at 2,500 particles, 308 vs 491 ms at 10⁴); the caller's residual check
            # and refinement guard the pivoting
            thresh = 0.0 if self.symmetric else 0.1
            self.ordering = (
                "MMD_AT_PLUS_A (symmetric mode)"
                if self.symmetric
                else "MMD_AT_PLUS_A (threshold 0.1)"
            )
            self._lu = spla.splu(
                csc,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=thresh,
                options={"SymmetricMode": True},
            )
        else:
            self.ordering = "COLAMD"
            self._lu = spla.splu(csc, permc_spec="COLAMD")

    def refactor(self, csc: sp.csc_matrix) -> None:
        self._factor(csc)

    def fill(self) -> int:
        return int(self._lu.L.nnz + self._lu.U.nnz)

    def flops(self) -> float | None:
        return None

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(b)


def _openblas_libs() -> list[Any]:
    """List the plain OpenBLAS libraries loaded in this process (CHOLMOD's BLAS) as ctypes handles.

    Linux only (``/proc/self/maps``); numpy's own ``scipy_openblas`` exports prefixed
    names and is not among them.
    """
    try:
        with open("/proc/self/maps") as fh:
            paths = {line.split()[-1] for line in fh if "openblas" in line.rsplit("/", 1)[-1]}
    except OSError:
        return []
    libs = []
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
            lib.openblas_get_num_threads.restype = ctypes.c_int
            lib.openblas_set_num_threads.argtypes = [ctypes.c_int]
        except (OSError, AttributeError):
            continue
        libs.append(lib)
    return libs


@contextmanager
def _openblas_threads(n: int) -> Iterator[None]:
    """Cap the OpenBLAS of CHOLMOD / MUMPS at ``n`` threads for the block, then restore it.

    OpenBLAS starts as many threads as there are cores whatever pdlin's setting; with the
    other core busy, 2 threads made CHOLMOD 2x slower than 1 (issue 33: 401² no control,
    38.2 / 49.3 s against 19.7 / 28.1 s; benchmarks/README.md). Only ever lowers the count
    (``OPENBLAS_NUM_THREADS`` stays an upper bound).
    """
    saved = []
    for lib in _openblas_libs():
        old = int(lib.openblas_get_num_threads())
        if n < old:
            lib.openblas_set_num_threads(n)
            saved.append((lib, old))
    try:
        yield
    finally:
        for lib, old in saved:
            lib.openblas_set_num_threads(old)


class _Cholmod:
    name = "cholmod"

    def __init__(self, A: sp.csc_matrix, symmetric: bool) -> None:
        mod = _import("cholmod")
        self._mod = mod
        # METIS nested dissection when CHOLMOD was built with it, else CHOLMOD's own choice
        # (AMD, then METIS/NESDIS when AMD fills in much)
        self._analyze(A)
        self.refactor(A)

    def _analyze(self, A: sp.csc_matrix) -> None:
        mod = self._mod
        self._pattern = (A.indptr.copy(), A.indices.copy())
        self.ordering = "metis"
        try:
            self._f = mod.analyze(A, mode="supernodal", ordering_method="metis")
        except Exception:  # CHOLMOD built without METIS
            self.ordering = "default (AMD / METIS, best of)"
            self._f = mod.analyze(A, mode="supernodal")

    def refactor(self, csc: sp.csc_matrix) -> None:
        csc.sort_indices()
        if not (
            np.array_equal(csc.indptr, self._pattern[0])
            and np.array_equal(csc.indices, self._pattern[1])
        ):
            self._analyze(csc)  # the symbolic factorization holds for one pattern only
        try:
            with _openblas_threads(get_num_threads()):
                self._f.cholesky_inplace(csc)
        except self._mod.CholmodNotPositiveDefiniteError as exc:
            raise _NotPositiveDefinite(str(exc)) from exc

    def fill(self) -> int:
        return int(self._f.L().nnz)

    def flops(self) -> float | None:
        # sum over the columns of L of c_j², c_j = nnz of column j (George & Liu)
        L = self._f.L()
        c = np.diff(L.indptr).astype(float)
        return float(np.sum(c * c))

    def solve(self, b: np.ndarray) -> np.ndarray:
        return np.asarray(self._f(b))


class _Pardiso:
    name = "pardiso"

    def __init__(self, A: sp.csc_matrix, symmetric: bool) -> None:
        mod = _import("pardiso")
        self.symmetric = symmetric
        self._s = mod.PyPardisoSolver(mtype=2 if symmetric else 11)
        self._s.set_statistical_info_off()
        self._s.iparm[0] = 1  # iparm(1): user settings below, PARDISO defaults otherwise
        # iparm(2): METIS nested dissection, the parallel (OpenMP) version: same ordering
        # and fill, analysis 1.65 -> 1.27 s on 2 threads (401² stress points, δ = 2h)
        self._s.iparm[1] = 3
        self._s.iparm[9] = 8 if symmetric else 13  # iparm(10): pivot perturbation 1e-8 / 1e-13
        self._s.iparm[10] = 0 if symmetric else 1  # iparm(11): scaling (nonsymmetric)
        self._s.iparm[12] = 0 if symmetric else 1  # iparm(13): weighted matching
        self._s.iparm[17] = -1  # iparm(18): report nnz(L + U)
        self._s.iparm[18] = -1  # iparm(19): report the factorization MFLOP
        self.ordering = "METIS (PARDISO)"
        self._M = self._matrix(A)
        self._call(11)
        self.refactor(A)

    def _matrix(self, A: sp.csc_matrix) -> sp.csr_matrix:
        M = _triu(A) if self.symmetric else sp.csr_matrix(A)
        M.sort_indices()
        M.data = np.ascontiguousarray(M.data, dtype=np.float64)
        return M

    def _call(self, phase: int, b: np.ndarray | None = None) -> np.ndarray:
        s = self._s
        s.set_phase(phase)
        s._check_A(self._M)  # sets iparm(13 / 12) for CSR and checks empty rows
        rhs = np.zeros((self._M.shape[0], 1)) if b is None else np.asfortranarray(b)
        try:
            return s._call_pardiso(self._M, rhs)
        except Exception as exc:  # PyPardisoError: -4 zero pivot, -2 memory, ...
            code = getattr(exc, "value", None)
            if self.symmetric and code == -4:
                raise _NotPositiveDefinite(str(exc)) from exc
            raise ConvergenceError(f"direct solve (PARDISO, phase {phase}): {exc}") from exc

    def refactor(self, csc: sp.csc_matrix) -> None:
        M = self._matrix(csc)
        if not (
            np.array_equal(M.indptr, self._M.indptr) and np.array_equal(M.indices, self._M.indices)
        ):
            self._M = M
            self._call(11)
        self._M = M
        self._call(22)
        if self.symmetric and int(self._s.iparm[22]) > 0:  # iparm(23): negative eigenvalues
            raise _NotPositiveDefinite(f"{int(self._s.iparm[22])} negative pivots")

    def fill(self) -> int:
        return int(self._s.iparm[17])

    def flops(self) -> float | None:
        return float(self._s.iparm[18]) * 1e6

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = self._call(33, b)
        return x.reshape(b.shape)

    def __del__(self) -> None:  # release PARDISO's internal memory
        try:
            self._s.set_phase(-1)
            self._s._call_pardiso(sp.csr_matrix((0, 0)), np.zeros(0))
        except Exception:  # pragma: no cover - interpreter shutdown
            pass


class _Mumps:
    name = "mumps"

    def __init__(self, A: sp.csc_matrix, symmetric: bool) -> None:
        mod = _import("mumps")
        self.symmetric = symmetric
        self._ctx = mod.Context()
        self._err = mod.MUMPSError
        orders = mod.possible_orderings()
        self._ordering = "scotch" if "scotch" in orders else "auto"
        self._pattern: tuple[np.ndarray, np.ndarray] | None = None
        self.refactor(A)

    def refactor(self, csc: sp.csc_matrix) -> None:
        # MUMPS reads the upper triangle of a symmetric matrix in any order (coordinates)
        M = (_triu(csc) if self.symmetric else sp.csc_matrix(csc)).tocoo()
        same = self._pattern is not None and (
            np.array_equal(M.row, self._pattern[0]) and np.array_equal(M.col, self._pattern[1])
        )
        try:
            if not same:
                self._ctx.set_matrix(M, symmetric=self.symmetric)
                self._ctx.analyze(ordering=self._ordering)
                self._pattern = (M.row.copy(), M.col.copy())
                self.ordering = str(self._ctx.analysis_stats.ordering)
            with _openblas_threads(get_num_threads()):  # Debian's MUMPS: the same OpenBLAS
                self._ctx.factor(M, reuse_analysis=True)
        except self._err as exc:
            raise ConvergenceError(f"direct solve (MUMPS): {exc}") from exc

    def fill(self) -> int:
        return int(self._ctx.factor_stats.nonzeros)

    def flops(self) -> float | None:
        return float(self._ctx.factor_stats.flops)

    def solve(self, b: np.ndarray) -> np.ndarray:
        return np.asarray(self._ctx.solve(b)).reshape(b.shape)


_CLASSES: dict[str, Any] = {
    "superlu": _SuperLU,
    "cholmod": _Cholmod,
    "pardiso": _Pardiso,
    "mumps": _Mumps,
}


def _pattern_symmetric(A: sp.csc_matrix) -> bool:
    """Whether the sparsity pattern of ``A`` equals that of ``Aᵀ`` (values ignored)."""
    P = sp.csr_array((np.ones(A.nnz), A.indices, A.indptr), shape=A.shape)  # pattern of Aᵀ
    Q = sp.csr_array((np.ones(A.nnz), A.indices, A.indptr), shape=A.shape).T.tocsr()
    if P.nnz != Q.nnz:
        return False
    P.sort_indices()
    Q.sort_indices()
    return bool(np.array_equal(P.indptr, Q.indptr) and np.array_equal(P.indices, Q.indices))


def _factor_hints(backend: str) -> list[str]:
    hints = ["solver='amg-cg' (no factor: AMG needs about K's size again)"]
    if backend == "superlu":
        hints.append(
            "direct_backend='cholmod' or 'pardiso' (nested-dissection orderings fill in "
            "2-5 x less than SuperLU's L + U; docs/large_problems.md)"
        )
    hints.append("a coarser discretization or a smaller horizon ratio")
    return hints


def check_factor_memory(A: Any, backend: str) -> int:
    """Estimate the bytes of the factor of ``A`` and refuse it if memory is short.

    The fill comes from :func:`pdlin.resources.direct_factor_nnz` (nested dissection on a
    lattice of ``A``'s size and blocks per row; a BSR ``A`` gives its block size as the
    dimension).

    Parameters
    ----------
    A : scipy sparse matrix or array
        The matrix to factorize, ``(N, N)``.
    backend : {'superlu', 'cholmod', 'pardiso'}
        The factorization; SuperLU's estimate includes its workspace expansions
        (``SUPERLU_WORKSPACE`` times the factor).

    Returns
    -------
    int
        Estimated peak bytes of the factorization.

    Raises
    ------
    InsufficientMemoryError
        When the estimate exceeds the available memory (the message suggests an iterative
        solver, another backend or a coarser discretization).
    """
    b = int(A.blocksize[0]) if getattr(A, "format", None) == "bsr" else 1
    n_pts = max(A.shape[0] // b, 1)
    dim = b if b in (2, 3) else 2
    nnz_l = direct_factor_nnz(n_pts, int(A.nnz) // (b * b), dim, b)
    need = direct_factor_bytes(nnz_l, backend, n_pts, dim)
    if backend == "superlu":  # its memory expansions during the factorization
        need = int(need * SUPERLU_WORKSPACE)
    check_memory(
        f"direct factorization ({backend}, ~{nnz_l:,} nonzeros in L)",
        need,
        lambda: _factor_hints(backend),
    )
    return need


def _as_csc(A: Any, symmetric: bool) -> sp.csc_matrix:
    """Convert ``A`` to CSC; a symmetric ``A`` reuses its CSR arrays.

    The CSR of ``A`` is the CSC of ``Aᵀ = A``: BSR -> CSR is a block expansion, 20x
    cheaper than BSR -> CSC (measured 0.025 vs 0.49 s at 16.6 million nonzeros).
    """
    if not symmetric or sp.issparse(A) and A.format == "csc":
        return sp.csc_matrix(A)
    R = sp.csr_matrix(A)
    R.sort_indices()
    return sp.csc_matrix((R.data, R.indices, R.indptr), shape=R.shape)


def _dim(A: Any) -> int | None:
    """Spatial dimension of ``A``'s problem: its BSR block size when 2 or 3, else None."""
    if getattr(A, "format", None) == "bsr" and int(A.blocksize[0]) in (2, 3):
        return int(A.blocksize[0])
    return None


def _triu(A: sp.csc_matrix) -> sp.csr_matrix:
    """Upper triangle (diagonal included) of a symmetric ``A`` in CSR with sorted rows.

    The CSC arrays of a symmetric matrix are its CSR arrays, so the upper triangle is a
    mask over each row's columns (vectorized; 10x faster than ``scipy.sparse.triu``).
    """
    A.sort_indices()
    n = A.shape[0]
    counts = np.diff(A.indptr)
    rows = np.repeat(np.arange(n, dtype=A.indices.dtype), counts)
    keep = A.indices >= rows
    indptr = np.zeros(n + 1, dtype=A.indptr.dtype)
    np.cumsum(np.bincount(rows[keep], minlength=n), out=indptr[1:])
    return sp.csr_matrix((A.data[keep], A.indices[keep], indptr), shape=A.shape)


def _is_symmetric(A: Any, tol: float = 1e-12) -> bool:
    Ac = sp.csr_array(A)
    d = Ac - Ac.T
    nrm = spla.norm(Ac, "fro") if Ac.nnz else 1.0
    return bool(spla.norm(d, "fro") <= tol * max(nrm, 1e-300)) if d.nnz else True


class DirectSolver:
    """Sparse direct factorization reusable for many right-hand sides.

    Parameters
    ----------
    A : sparse array
        Square matrix.
    symmetric : bool, optional
        Whether ``A`` is symmetric (checked numerically when omitted).
    backend : {'auto', 'superlu', 'cholmod', 'pardiso', 'mumps'}
        ``'auto'``: PARDISO, then CHOLMOD (supernodal Cholesky; first when
        :func:`pdlin.get_num_threads` is 1 or ``A`` is a BSR matrix of 3 x 3 blocks,
        i.e. 3D), MUMPS, then SuperLU for symmetric
        ``A``; PARDISO, MUMPS, then SuperLU for nonsymmetric ``A``, skipping
        those not installed; SuperLU alone below
        :data:`~pdlin.solvers.AUTO_MIN` unknowns.  SuperLU runs in symmetric mode
        (minimum degree on ``A + Aᵀ``, diagonal pivots) for symmetric ``A``.

    Attributes
    ----------
    backend : str
        The backend that factorized ``A``.
    info : dict
        ``backend``, ``ordering``, ``setup_time`` and, when a Cholesky fell
        back, ``fallback`` (why).

    Raises
    ------
    InputError
        For an unknown ``backend``.
    MissingDependencyError
        When an explicitly requested backend is not installed.
    ConvergenceError
        When the matrix is singular, or not positive definite for an
        explicitly requested ``'cholmod'``.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> A = sp.csr_array(np.array([[4.0, 1.0], [1.0, 3.0]]))
    >>> lu = DirectSolver(A, backend="superlu")
    >>> lu.solve(np.array([1.0, 2.0])).round(6)
    array([0.090909, 0.636364])
    >>> lu.backend
    'superlu'
    """

    def __init__(self, A: Any, *, symmetric: bool | None = None, backend: str = "auto") -> None:
        if backend not in DIRECT_BACKENDS:
            raise InputError(f"direct_backend must be one of {DIRECT_BACKENDS}, got {backend!r}")
        t0 = time.perf_counter()
        if symmetric is None:
            symmetric = _is_symmetric(A)
        self.symmetric = bool(symmetric)
        csc = _as_csc(A, self.symmetric)
        if backend == "cholmod" and not self.symmetric:
            raise InputError(
                "direct_backend='cholmod' needs a symmetric matrix (Cholesky); this one is "
                "nonsymmetric: use 'pardiso', 'superlu' or 'auto'"
            )
        chain = [backend] if backend != "auto" else auto_chain(self.symmetric, A.shape[0], _dim(A))
        factor_bytes = check_factor_memory(A, chain[0])
        self.info: dict[str, Any] = {}
        notes: list[str] = []
        impl: Any = None
        for name in chain:
            try:
                impl = _CLASSES[name](csc, self.symmetric)
                break
            except MemoryError as exc:  # the estimate fitted, the backend still ran out
                if isinstance(exc, InsufficientMemoryError):
                    raise
                raise InsufficientMemoryError(
                    f"direct factorization ({name}) ran out of memory ({exc or 'MemoryError'}; "
                    f"estimated factor ~{format_bytes(factor_bytes)}, "
                    f"{available_memory().describe()} available); what would fit: "
                    + "; ".join(_factor_hints(name)),
                    need=factor_bytes,
                    hints=_factor_hints(name),
                ) from exc
            except _NotPositiveDefinite as exc:
                if backend != "auto":
                    raise ConvergenceError(
                        f"direct solve ({name}): the matrix is not positive definite ({exc}); "
                        "use direct_backend='superlu' or 'auto'"
                    ) from exc
                notes.append(f"{name}: not positive definite ({exc})")
                log.info("direct backend %s: not positive definite, trying the next", name)
        if impl is None:  # every Cholesky of the chain failed: SuperLU always runs
            impl = _SuperLU(csc, self.symmetric)
        self._impl = impl
        self.backend: str = impl.name
        self.shape = A.shape
        self.setup_time = time.perf_counter() - t0
        self.info = {"backend": self.backend, "ordering": impl.ordering}
        if notes:
            self.info["fallback"] = "; ".join(notes)

    @property
    def fill(self) -> int:
        """Nonzeros of the factors (``L + U`` for LU, ``L`` for Cholesky)."""
        return self._impl.fill()

    def flops(self) -> float | None:
        """Return the factorization's flop count when the backend reports it.

        Returns
        -------
        float or None
            Floating-point operations of the numeric factorization (CHOLMOD, PARDISO);
            ``None`` for SuperLU, which does not report it.
        """
        return self._impl.flops()

    def refactor(self, A: Any) -> None:
        """Factorize a new matrix with the same backend, reusing the symbolic analysis.

        CHOLMOD and PARDISO keep their ordering and symbolic factorization when
        the pattern of ``A`` is unchanged (e.g. successive Newton tangents);
        SuperLU factorizes from scratch.

        Parameters
        ----------
        A : scipy sparse matrix or array
            The new matrix, same shape (and, for reuse, same pattern) as the first.

        Raises
        ------
        InputError
            When ``A`` has another shape.
        ConvergenceError
            When a Cholesky backend finds ``A`` not positive definite.

        Examples
        --------
        >>> import numpy as np, scipy.sparse as sp
        >>> s = DirectSolver(sp.csr_array(np.diag([2.0, 4.0])), backend="superlu")
        >>> s.refactor(sp.csr_array(np.diag([1.0, 8.0])))
        >>> s.solve(np.array([1.0, 8.0]))
        array([1., 1.])
        """
        if A.shape != self.shape:
            raise InputError(f"refactor: A must have shape {self.shape}, got {A.shape}")
        t0 = time.perf_counter()
        try:
            self._impl.refactor(_as_csc(A, self.symmetric))
        except _NotPositiveDefinite as exc:
            raise ConvergenceError(
                f"direct solve ({self.backend}): the matrix is not positive definite ({exc})"
            ) from exc
        self.setup_time = time.perf_counter() - t0

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve for one or several right-hand sides.

        Parameters
        ----------
        b : (N,) or (N, k) ndarray
            Right-hand side(s), one per column.

        Returns
        -------
        ndarray
            The solution, same shape as ``b``.

        Raises
        ------
        ConvergenceError
            When the solution is not finite (a singular matrix).
        """
        x = self._impl.solve(np.asarray(b, dtype=float))
        if not np.all(np.isfinite(x)):
            raise ConvergenceError("direct solve produced non-finite values (singular matrix?)")
        return x
