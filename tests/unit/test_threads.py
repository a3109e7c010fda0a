"""Threaded kernels (issue 13, "Use both cores"): control and bitwise determinism."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest
import scipy.sparse as sp

import pdlin
from pdlin import _threads
from pdlin._threads import thread_map
from pdlin.errors import InputError, InputTypeError


@pytest.fixture(autouse=True)
def _restore_threads():
    yield
    pdlin.set_num_threads(None)


def test_default_is_affinity_or_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PDLIN_NUM_THREADS", raising=False)
    pdlin.set_num_threads(None)
    assert pdlin.get_num_threads() == len(os.sched_getaffinity(0))
    monkeypatch.setenv("PDLIN_NUM_THREADS", "3")
    assert pdlin.get_num_threads() == 3
    pdlin.set_num_threads(1)  # explicit setting wins over the environment
    assert pdlin.get_num_threads() == 1
    pdlin.set_num_threads(None)
    monkeypatch.setenv("PDLIN_NUM_THREADS", "zero")
    with pytest.raises(InputError, match="PDLIN_NUM_THREADS.*'zero'"):
        pdlin.get_num_threads()
    monkeypatch.setenv("PDLIN_NUM_THREADS", "0")
    with pytest.raises(InputError, match="PDLIN_NUM_THREADS"):
        pdlin.get_num_threads()


@pytest.mark.parametrize("bad", [0, -2])
def test_set_num_threads_rejects_bad_values(bad: int) -> None:
    with pytest.raises(InputError, match="n must be an integer >= 1, got"):
        pdlin.set_num_threads(bad)


@pytest.mark.parametrize("bad", [1.5, "2", True])
def test_set_num_threads_rejects_bad_types(bad: object) -> None:
    with pytest.raises(InputTypeError, match="n must be an integer"):
        pdlin.set_num_threads(bad)  # type: ignore[arg-type]


def test_thread_map_order_threads_and_nesting() -> None:
    pdlin.set_num_threads(2)
    names: set[str] = set()
    lock = threading.Lock()

    def f(x: int) -> list[int]:
        with lock:
            names.add(threading.current_thread().name)
        return thread_map(lambda y: 10 * x + y, range(3))  # nested: serial

    out = thread_map(f, range(6))
    assert out == [[10 * x + y for y in range(3)] for x in range(6)]
    assert all(n.startswith("pdlin") for n in names)
    pdlin.set_num_threads(1)
    names.clear()
    thread_map(f, range(4))
    assert names == {threading.current_thread().name}  # 1 thread: the caller only


def _case(kind: str) -> tuple:
    if kind == "bb3":
        cloud = pdlin.grid((14, 14, 14), spacing=0.1)
        bonds = pdlin.find_bonds(cloud, ratio=3.015)
        return pdlin.BondBased(E=1.0, nu=0.25), cloud, bonds
    if kind in ("lps3", "xosb2"):  # numba's row-parallel product (pdlin[fast]) or scipy
        cloud = pdlin.grid((12, 11, 10) if kind == "lps3" else (60, 50), spacing=0.1)
        bonds = pdlin.find_bonds(cloud, ratio=3.015)
        cls = pdlin.LPS if kind == "lps3" else pdlin.XOSB
        return cls(E=1.0, nu=0.3, plane="strain"), cloud, bonds
    cloud = pdlin.grid((60, 50), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0, influence="inverse")
    control = "none" if kind == "corr-none" else "stress_points"
    if control == "stress_points":
        bonds = pdlin.find_bonds(cloud, ratio=2.0)
    return pdlin.Correspondence(E=1.0, nu=0.25, control=control, plane="strain"), cloud, bonds


@pytest.mark.parametrize("kind", ["bb3", "lps3", "xosb2", "corr-none", "corr-sp"])
def test_assembly_and_products_identical_across_thread_counts(kind: str) -> None:
    """1, 2 and 3 threads give bitwise the same K (and matrix-free K x)."""
    model, cloud, bonds = _case(kind)
    x = np.random.default_rng(2).normal(size=cloud.n * cloud.dim)
    Ks, ys = [], []
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        K = sp.csr_array(model.stiffness(cloud, bonds))
        Ks.append(K)
        ys.append(np.asarray(model.operator(cloud, bonds) @ x))
    for K, y in zip(Ks[1:], ys[1:], strict=True):
        assert np.array_equal(K.indptr, Ks[0].indptr)
        assert np.array_equal(K.indices, Ks[0].indices)
        assert np.array_equal(K.data, Ks[0].data)
        assert np.array_equal(y, ys[0])
    # the matrix-free product is the assembled one (independent check of both paths)
    ref = Ks[0] @ x
    assert np.abs(ys[0] - ref).max() <= 1e-10 * np.abs(ref).max()


def test_solve_identical_across_thread_counts() -> None:
    cloud = pdlin.grid((30, 20), spacing=0.1)
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    model = pdlin.Correspondence(E=1.0, nu=0.25, control="stress_points", plane="strain")
    prob = pdlin.StaticProblem(model, cloud, dirichlet=bc, horizon=0.2)
    us = []
    for nt in (1, 2):
        pdlin.set_num_threads(nt)
        us.append(pdlin.solve(prob, "amg-cg", operator="assembled").u)
    assert np.array_equal(us[0], us[1])
    assert _threads._n_threads == 2


def test_thread_map_works_in_a_forked_child() -> None:
    """A forked child (the tradeoff harness, benchmarks) gets a fresh pool, not a dead one."""
    import multiprocessing as mp

    pdlin.set_num_threads(2)
    assert thread_map(lambda x: x + 1, range(4)) == [1, 2, 3, 4]  # the parent's pool exists
    ctx = mp.get_context("fork")
    q = ctx.Queue()

    def child() -> None:
        q.put(thread_map(lambda x: 2 * x, range(8)))

    p = ctx.Process(target=child)
    p.start()
    out = q.get(timeout=30)  # a dead pool would block here
    p.join(timeout=10)
    assert out == [2 * x for x in range(8)]


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_pair_stiffness_chunks_with_empty_rows(monkeypatch: pytest.MonkeyPatch, dim: int) -> None:
    """Per-row sums over contiguous segments (np.add.reduceat) with isolated points, tiny chunks.

    Reference: the dense sum over bonds of ``k n nᵀ`` into the four blocks (independent loop).
    """
    from pdlin.operators import assembly

    rng = np.random.default_rng(dim)
    cloud = pdlin.PointCloud(rng.random((200, dim)), volumes=np.full(200, 1e-3))
    horizon = {1: 0.004, 2: 0.05, 3: 0.12}[dim]
    bonds = pdlin.find_bonds(cloud, horizon=horizon, allow_isolated=True)
    empty = np.flatnonzero(np.diff(bonds.indptr) == 0)
    assert empty.size > 5 and bonds.n_bonds > 100  # isolated points inside chunks and at ends
    k = rng.random(bonds.n_bonds)
    unit = bonds.xi / bonds.length[:, None]
    ref = np.zeros((200 * dim, 200 * dim))
    for b in range(bonds.n_bonds):
        i, j = bonds.i[b] * dim, bonds.j[b] * dim
        blk = k[b] * np.outer(unit[b], unit[b])
        ref[i : i + dim, j : j + dim] -= blk
        ref[i : i + dim, i : i + dim] += blk
    for chunk in (7, 37, 1 << 16):
        monkeypatch.setattr(assembly, "_CHUNK", chunk)
        for nt in (1, 2):
            pdlin.set_num_threads(nt)
            K = assembly.pair_stiffness_bsr(bonds, k)
            K.check_format(full_check=True)
            assert K.has_sorted_indices
            assert np.abs(K.toarray() - ref).max() <= 1e-14 * np.abs(ref).max()
            Kf = assembly.pair_stiffness_bsr(bonds, lambda b0, b1: k[b0:b1])  # chunked coef
            assert np.array_equal(Kf.data, K.data) and np.array_equal(Kf.indices, K.indices)
            # an isolated point stores one block, its (zero) diagonal
            assert (np.diff(K.indptr)[empty] == 1).all()
            assert (K.indices[K.indptr[empty]] == empty).all()
            assert not K.data[K.indptr[empty]].any()


def test_bond_stiffness_error_names_the_global_bond(monkeypatch: pytest.MonkeyPatch) -> None:
    """A negative bond stiffness found inside a chunk names its index among all bonds."""
    import re

    from pdlin.models.weights import as_influence, higher_order_weights
    from pdlin.operators import assembly

    cloud = pdlin.grid((8, 8))
    h = float(np.max(cloud.lattice.spacing))
    infl = as_influence(higher_order_weights(2, 2), h)  # some ω < 0 (paper Table 2)
    bonds = pdlin.find_bonds(cloud, ratio=2.0, influence=infl, allow_negative_influence=True)
    model = pdlin.BondBased(micromodulus=1.0)
    msgs = []
    for chunk, nt in ((1 << 16, 1), (40, 1), (40, 2)):
        monkeypatch.setattr(assembly, "_CHUNK", chunk)
        pdlin.set_num_threads(nt)
        with pytest.raises(pdlin.errors.ModelError, match="energy positivity") as err:
            model.stiffness(cloud, bonds)
        msgs.append(str(err.value))
    b = [int(re.search(r"at bond (\d+) ", m).group(1)) for m in msgs]  # type: ignore[union-attr]
    assert b[0] == int(np.argmin(bonds.omega / bonds.length))  # one chunk: the global argmin
    assert bonds.omega[b[1]] < 0 and b[1] >= int(np.flatnonzero(bonds.omega < 0)[0])
    assert msgs[1] == msgs[2]  # the same chunk reports it for any thread count


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_row_blocks_equal_the_scipy_products_bitwise(threads):
    """RowBlocks(A) @ x == A @ x bitwise for any thread count, also for the CSC transpose
    of a CSR matrix (its CSR rows sum in the order of csc_matvec); blocks never split a
    row and cover all of them."""
    from pdlin._threads import RowBlocks

    rng = np.random.default_rng(4)
    A = sp.random_array((700, 400), density=0.04, rng=rng, format="csr")
    x, y = rng.standard_normal(400), rng.standard_normal(700)
    try:
        pdlin.set_num_threads(threads)
        R, RT = RowBlocks(A, nnz=1500), RowBlocks(A.T, nnz=1500)
        assert len(R.blocks) >= 5 and R.ranges[0][0] == 0 and R.ranges[-1][1] == 700
        assert all(b == c for (_, b), (c, _) in zip(R.ranges[:-1], R.ranges[1:], strict=True))
        np.testing.assert_array_equal(R @ x, A @ x)
        np.testing.assert_array_equal(RT @ y, A.T @ y)
        assert all(np.shares_memory(b.data, A.data) for b in R.blocks)  # views, no copy
    finally:
        pdlin.set_num_threads(None)


def test_correspondence_respond_on_row_blocks_is_bitwise_the_plain_one(monkeypatch):
    """Above the size threshold the correspondence respond runs G u, Gᵀ(w V P) and the
    penalty's K_c u on RowBlocks: force and stress equal the plain scipy products."""
    cloud = pdlin.grid((20, 20), spacing=0.05)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    F = np.array([[1.004, 0.006], [0.002, 0.998]])
    u = cloud.points @ (F - np.eye(2)).T + 1e-4 * np.sin(7.0 * cloud.points[:, ::-1])
    out = {}
    for nnz in (10**9, 2_000):  # plain scipy, then blocks of 2,000 entries
        monkeypatch.setattr(_threads, "ROW_BLOCK_NNZ", nnz)
        model = pdlin.Correspondence(
            material=pdlin.CrystalPlasticity(), control="penalty", penalty=0.1
        )
        state = model.initial_state(cloud, bonds)
        r = model.respond(cloud, bonds, u, state)
        blocks = model._plan(cloud, bonds)._lazy.get("row_blocks", {})
        out[nnz] = (r.force, r.stress, sorted(blocks))
    assert out[10**9][2] == [] and out[2_000][2] == ["G", "GT", "addon"]
    np.testing.assert_array_equal(out[2_000][0], out[10**9][0])
    np.testing.assert_array_equal(out[2_000][1], out[10**9][1])
