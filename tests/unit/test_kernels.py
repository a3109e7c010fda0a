"""Optional numba kernels (pdlin._kernels, issue 13): products against scipy, threads, fallback."""

from __future__ import annotations

import multiprocessing as mp
import threading

import numpy as np
import pytest
import scipy.sparse as sp

import pdlin
from pdlin import _kernels
from pdlin._kernels import bsr_matmul

numba = pytest.importorskip("numba")


@pytest.fixture(autouse=True)
def _small_work_goes_to_numba(monkeypatch: pytest.MonkeyPatch):
    """Send every product to the kernels (the tests' matrices are small)."""
    monkeypatch.setattr(_kernels, "_MIN_WORK", 0)
    monkeypatch.setattr(_kernels, "_loaded", None)
    monkeypatch.delenv("PDLIN_NUMBA", raising=False)
    yield
    pdlin.set_num_threads(None)


def _random_bsr(rng, n_brow, n_bcol, blocksize, density, empty_rows=(), empty_cols=()):
    """BSR array with random blocks, some whole block rows / columns empty."""
    R, C = blocksize
    mask = rng.random((n_brow, n_bcol)) < density
    mask[list(empty_rows), :] = False
    mask[:, list(empty_cols)] = False
    rows, cols = np.nonzero(mask)
    data = rng.normal(size=(rows.size, R, C))
    indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=1))])
    return sp.bsr_array((data, cols, indptr), shape=(n_brow * R, n_bcol * C), blocksize=(R, C))


def _sorted(M: sp.bsr_array) -> sp.bsr_array:
    M = sp.bsr_array(M, copy=True)
    M.sort_indices()
    return M


# (R, N, S): blocks R x N times N x S; 1D / 2D / 3D stiffness blocks, the LPS (d x 1)(1 x d)
# factors and the correspondence (d x n_v)(n_v x d) factors (n_v = 3 in 2D, 6 in 3D)
SHAPES = [(1, 1, 1), (2, 1, 2), (3, 1, 3), (2, 2, 2), (3, 3, 3), (2, 3, 2), (3, 6, 3), (1, 2, 3)]


@pytest.mark.parametrize("shape", SHAPES)
def test_bsr_matmul_matches_scipy(shape: tuple[int, int, int]) -> None:
    R, N, S = shape
    rng = np.random.default_rng(sum(shape))
    A = _random_bsr(rng, 37, 29, (R, N), 0.15, empty_rows=[0, 5, 36], empty_cols=[3, 28])
    B = _random_bsr(rng, 29, 41, (N, S), 0.15, empty_rows=[7], empty_cols=[0, 40])
    C = bsr_matmul(A, B)
    ref = _sorted(sp.bsr_array(A @ B, blocksize=(R, S)))  # scipy's sparsetools product
    assert C.blocksize == (R, S) and C.shape == ref.shape
    assert C.has_sorted_indices
    assert np.array_equal(C.indptr, ref.indptr)  # the same block pattern, ...
    assert np.array_equal(C.indices, ref.indices)  # ... sorted
    assert np.allclose(C.data, ref.data, rtol=1e-14, atol=0.0)
    assert np.allclose(C.toarray(), A.toarray() @ B.toarray(), rtol=1e-13, atol=1e-13)
    # empty rows of A give empty rows of C
    assert np.diff(C.indptr)[[0, 5, 36]].tolist() == [0, 0, 0]


def test_bsr_matmul_empty_and_degenerate() -> None:
    rng = np.random.default_rng(4)
    A = sp.bsr_array((12, 9), blocksize=(3, 3))  # no stored block
    B = _random_bsr(rng, 3, 4, (3, 2), 0.5)
    C = bsr_matmul(A, B)
    assert C.shape == (12, 8) and C.blocksize == (3, 2) and C.nnz == 0
    Z = bsr_matmul(B.T.tobsr(blocksize=(2, 3)), sp.bsr_array((9, 6), blocksize=(3, 3)))
    assert Z.nnz == 0 and Z.shape == (8, 6)
    with pytest.raises(ValueError, match="do not chain"):
        bsr_matmul(A, sp.bsr_array((9, 4), blocksize=(1, 2)))


@pytest.mark.parametrize("shape", [(1, 1, 1), (3, 1, 3), (2, 3, 2)])
def test_bsr_matmul_identical_across_thread_counts(shape) -> None:
    R, N, S = shape
    rng = np.random.default_rng(7)
    A = _random_bsr(rng, 300, 200, (R, N), 0.05, empty_rows=[1, 2, 299])
    B = _random_bsr(rng, 200, 310, (N, S), 0.05)
    out = []
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        out.append(bsr_matmul(A, B))
    for C in out[1:]:
        assert np.array_equal(C.indptr, out[0].indptr)
        assert np.array_equal(C.indices, out[0].indices)
        assert np.array_equal(C.data, out[0].data)


@pytest.mark.parametrize("shape", [(2, 3, 2), (3, 6, 3), (1, 1, 1)])
def test_bsr_matmul_block_sizes(shape) -> None:
    """``block_sizes=True``: the same product bitwise, ``max |block|`` of every stored block
    and of each row's diagonal block (0 where a row stores none), on 1-3 threads."""
    R, N, S = shape
    rng = np.random.default_rng(11)
    A = _random_bsr(rng, 60, 50, (R, N), 0.08, empty_rows=[4, 59])
    B = _random_bsr(rng, 50, 60, (N, S), 0.08)
    plain = bsr_matmul(A, B)
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        C, (size, dsize) = bsr_matmul(A, B, block_sizes=True)
        assert np.array_equal(C.indptr, plain.indptr)
        assert np.array_equal(C.indices, plain.indices)
        assert np.array_equal(C.data, plain.data)
        assert np.array_equal(size, np.abs(C.data).max(axis=(1, 2)))
        rows = np.repeat(np.arange(60), np.diff(C.indptr))
        ref = np.zeros(60)
        on = C.indices == rows
        ref[rows[on]] = size[on]
        assert np.array_equal(dsize, ref)
        assert not on[np.isin(rows, [4, 59])].any() and dsize[[4, 59]].tolist() == [0.0, 0.0]


def test_disabled_by_environment_and_fallback(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PDLIN_NUMBA", "0")
    assert not _kernels.numba_enabled()
    A = _random_bsr(np.random.default_rng(1), 20, 20, (2, 1), 0.2)
    B = _random_bsr(np.random.default_rng(2), 20, 20, (1, 2), 0.2)
    C = bsr_matmul(A, B)  # scipy's product, unchanged (unsorted block columns allowed)
    ref = sp.bsr_array(A @ B, blocksize=(2, 2))
    assert np.array_equal(C.indices, ref.indices) and np.array_equal(C.data, ref.data)
    monkeypatch.setattr(_kernels, "_loaded", None)
    monkeypatch.delenv("PDLIN_NUMBA")
    assert _kernels.numba_enabled()


def test_concurrent_calls_from_python_threads() -> None:
    """numba's workqueue layer aborts on concurrent parallel calls: the module serializes them."""
    pdlin.set_num_threads(2)
    rng = np.random.default_rng(3)
    A = _random_bsr(rng, 400, 400, (3, 1), 0.03)
    B = _random_bsr(rng, 400, 400, (1, 3), 0.03)
    ref = bsr_matmul(A, B)
    results: list[sp.bsr_array] = []

    def work() -> None:
        for _ in range(5):
            results.append(bsr_matmul(A, B))

    ts = [threading.Thread(target=work) for _ in range(3)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert len(results) == 15
    assert all(np.array_equal(r.data, ref.data) for r in results)


def test_kernels_run_in_a_forked_child() -> None:
    """GNU OpenMP would abort a forked child; pdlin picks numba's fork-safe layer."""
    pdlin.set_num_threads(2)
    A = _random_bsr(np.random.default_rng(5), 60, 60, (2, 1), 0.1)
    B = sp.bsr_array(A.T, blocksize=(1, 2))
    ref = bsr_matmul(A, B).toarray()  # the parent has run a parallel kernel
    ctx = mp.get_context("fork")
    q = ctx.Queue()

    def child() -> None:
        q.put(bsr_matmul(A, B).toarray())

    p = ctx.Process(target=child)
    p.start()
    out = q.get(timeout=60)
    p.join(timeout=10)
    assert p.exitcode == 0
    assert np.array_equal(out, ref)


def _models(dim: int):
    cloud = pdlin.grid((9, 8, 7) if dim == 3 else (26, 21), spacing=0.1)
    yield pdlin.LPS(E=1.0, nu=0.3, plane="strain"), cloud, pdlin.find_bonds(cloud, ratio=3.015)
    yield pdlin.XOSB(E=1.0, nu=0.3, plane="strain"), cloud, pdlin.find_bonds(cloud, ratio=3.015)
    yield (
        pdlin.XOSB(E=1.0, nu=0.3, plane="strain", linearization="paper"),
        cloud,
        pdlin.find_bonds(cloud, ratio=3.015),
    )
    for control in ("none", "stress_points"):
        bonds = pdlin.find_bonds(cloud, ratio=2.0, influence="inverse")
        yield (
            pdlin.Correspondence(E=1.0, nu=0.3, control=control, plane="strain"),
            cloud,
            bonds,
        )


@pytest.mark.parametrize("dim", [2, 3])
def test_models_equal_with_and_without_numba(monkeypatch: pytest.MonkeyPatch, dim: int) -> None:
    """K of the numba path equals today's scipy path (1e-14 rel; correspondence: bitwise)."""
    x = None
    for model, cloud, bonds in _models(dim):
        if x is None:
            x = np.random.default_rng(0).normal(size=cloud.n * cloud.dim)
        monkeypatch.setattr(_kernels, "_loaded", False)  # numba "missing": scipy
        K0 = sp.csr_array(model.stiffness(cloud, bonds))
        monkeypatch.setattr(_kernels, "_loaded", None)
        assert _kernels.numba_enabled()
        K1 = sp.csr_array(model.stiffness(cloud, bonds))
        K0.sort_indices()
        K1.sort_indices()
        name = type(model).__name__
        assert np.array_equal(K0.indptr, K1.indptr), name
        assert np.array_equal(K0.indices, K1.indices), name
        scale = np.abs(K0.data).max()
        assert np.abs(K1.data - K0.data).max() <= 1e-14 * scale, name
        if name == "Correspondence":  # the same operands in the same order as scipy
            assert np.array_equal(K1.data, K0.data)
        y = K1 @ x  # and K is the matrix-free operator (independent path)
        y_mf = model.operator(cloud, bonds) @ x
        assert np.abs(y - y_mf).max() <= 1e-10 * np.abs(y_mf).max(), name
