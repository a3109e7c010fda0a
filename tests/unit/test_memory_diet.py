"""Issue 33: the static pipeline's steps without temporaries the size of K, results unchanged.

Each change is checked twice: its output equals, bit for bit, the formula it replaced (kept
here as the reference), and the bytes it allocates (``tracemalloc`` sees numpy's buffers)
stay a small fraction of K's values, where the replaced formula allocated arrays of K's size.
"""

from __future__ import annotations

import re
import tracemalloc

import numpy as np
import pytest
import scipy.sparse as sp

import pdlin
from pdlin.constraints import eliminate_dirichlet
from pdlin.errors import InputError, NonFiniteError
from pdlin.solvers import linear


def _reference_eliminate(K, f, dofs, values, inplace=False):  # type: ignore[no-untyped-def]
    """``eliminate_dirichlet`` as it was before issue 33 (full-size index and mask arrays)."""
    ndof = K.shape[0]
    uc = np.zeros(ndof)
    uc[dofs] = values
    b = f - K @ uc
    free = np.ones(ndof, dtype=bool)
    free[dofs] = False
    A = K if inplace else K.copy()
    diag = K.diagonal()
    s = float(np.mean(np.abs(diag[free]))) if free.any() else 1.0
    if isinstance(A, sp.bsr_array | sp.bsr_matrix):
        r, c = A.blocksize
        brow = np.repeat(np.arange(A.shape[0] // r), np.diff(A.indptr))
        fr = free.reshape(-1, r)[brow]
        fc = free.reshape(-1, c)[A.indices]
        A.data *= fr[:, :, None]
        A.data *= fc[:, None, :]
        isdiag = brow == A.indices
        pos = np.flatnonzero(isdiag)
        rows = brow[pos]
        for k in range(r):
            fixed = ~free[r * rows + k]
            A.data[pos[fixed], k, k] = s
    else:
        A = sp.csr_array(A)
        rows = np.repeat(np.arange(ndof), np.diff(A.indptr))
        keep = free[rows] & free[A.indices]
        A.data = A.data * keep
        A.eliminate_zeros()
        A = A + sp.diags_array(np.where(free, 0.0, s), format="csr")
        A = sp.csr_array(A)
    b[~free] = s * uc[~free]
    return A, b


def _system(dim: int, shape: tuple[int, ...], lateral: bool = True) -> pdlin.ConstrainedSystem:
    """A small bond-based body with mixed prescribed components (some blocks partly fixed)."""
    cloud = pdlin.grid(shape, spacing=0.1)
    diri = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    if dim >= 2 and lateral:
        diri.append(pdlin.Dirichlet("y+", 0.0, components="y"))  # agrees with x- at corners
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=2.0e9), cloud, ratio=2.015, dirichlet=diri,
        loads=[pdlin.TotalForce("y-", [0.0, 5.0, -1.0][:dim] if dim > 1 else [5.0])],
    )  # fmt: skip
    return pdlin.constrained_system(prob)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Bit-for-bit equality (signed zeros and NaN payloads included)."""
    a, b = np.ascontiguousarray(a), np.ascontiguousarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("dim, shape", [(2, (7, 6)), (3, (5, 4, 4))])
@pytest.mark.parametrize("fmt", ["bsr", "csr"])
@pytest.mark.parametrize("inplace", [False, True])
def test_eliminate_dirichlet_equals_the_old_formula(
    dim: int, shape: tuple[int, ...], fmt: str, inplace: bool
) -> None:
    sysm = _system(dim, shape)
    K = sysm.assemble()
    K = sp.bsr_array(K, blocksize=(dim, dim)) if fmt == "bsr" else sp.csr_array(K)
    # negative entries in prescribed rows / columns: the old formula left -0.0 there
    assert (K.data < 0).any()
    f = np.asarray(sysm.f_ext, dtype=float)
    mixed = np.unique(sysm.dofs // dim, return_counts=True)[1]
    assert (mixed < dim).any() and (mixed == dim).any()  # partly and wholly fixed points
    A0, b0 = _reference_eliminate(K.copy(), f, sysm.dofs, sysm.values, inplace=inplace)
    Kin = K.copy()
    A1, b1 = eliminate_dirichlet(Kin, f, sysm.dofs, sysm.values, inplace=inplace)
    assert type(A1) is type(A0)
    assert _same(A1.data, A0.data) and _same(A1.indices, A0.indices)
    assert _same(A1.indptr, A0.indptr) and _same(b1, b0)
    if not inplace:
        assert _same(Kin.data, K.data)  # K untouched
    elif fmt == "bsr":
        assert A1 is Kin


def test_eliminate_dirichlet_allocates_no_array_of_k_size() -> None:
    # a long bar: the prescribed faces x- and x+ hold 2 / 80 of the points
    sysm = _system(3, (80, 4, 4), lateral=False)
    K = sp.bsr_array(sysm.assemble(), blocksize=(3, 3))
    f = np.asarray(sysm.f_ext, dtype=float)
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        eliminate_dirichlet(K, f, sysm.dofs, sysm.values, inplace=True)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # the old formula held a block-row index per block (8 B) and row / column masks
    # (3 + 3 B) beside the 72 B of values per block: measured 0.29 of K.data here with the
    # vectors (b, diag; ~20 blocks per point on this thin bar); now one boolean per block
    # (1 / 72), copies of the blocks in prescribed rows and columns and the vectors:
    # measured 0.10
    assert peak < 0.18 * K.data.nbytes, (peak, K.data.nbytes)


def _matrix(scale: float, n: int = 300) -> sp.csr_array:
    rng = np.random.default_rng(3)
    M = sp.random_array((n, n), density=0.05, rng=rng, format="csr")
    M.data = (M.data - 0.7) * scale  # mostly negative: the largest |entry| is a minimum
    return M


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("where", [0, -1])
def test_check_matrix_scale_refuses_non_finite_in_any_chunk(
    monkeypatch: pytest.MonkeyPatch, bad: float, where: int
) -> None:
    monkeypatch.setattr(linear, "_CHECK_CHUNK", 7)  # several chunks and a short last one
    M = _matrix(1.0)
    M.data[where] = bad
    with pytest.raises(NonFiniteError, match="A must be finite"):
        linear._check_matrix_scale(M, "A")
    B = sp.bsr_array(_matrix(1.0).toarray(), blocksize=(3, 3))
    B.data[where, 2, 1] = bad
    with pytest.raises(NonFiniteError, match="A must be finite"):
        linear._check_matrix_scale(B, "A")
    linear._check_matrix_scale(_matrix(1.0), "A")  # all finite: no error


@pytest.mark.parametrize("scale", [1e-120, 1e120])
def test_check_matrix_scale_reports_the_same_scale(scale: float) -> None:
    M = _matrix(scale)
    old = float(np.max(np.abs(M.data)))  # the formula it replaced
    with pytest.raises(InputError, match=re.escape(f"got {old:.3e}")):
        linear._check_matrix_scale(M, "K")
    B = sp.bsr_array(_matrix(scale, 300).toarray(), blocksize=(3, 3))
    old = float(np.max(np.abs(B.data)))
    with pytest.raises(InputError, match=re.escape(f"got {old:.3e}")):
        linear._check_matrix_scale(B, "K")
    linear._check_matrix_scale(_matrix(1.0), "K")  # in range: no error


def test_check_matrix_scale_allocates_no_copy_of_k() -> None:
    M = sp.bsr_array(_matrix(1.0, 900).toarray(), blocksize=(3, 3))
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        linear._check_matrix_scale(M, "A")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # np.abs(data) was a float copy (1.0 x data); the finite test's booleans are 1/8
    assert peak < 0.3 * M.data.nbytes, (peak, M.data.nbytes)
