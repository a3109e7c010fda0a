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
    cloud = pdlin.grid((60, 50), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0, influence="inverse")
    control = "none" if kind == "corr-none" else "stress_points"
    if control == "stress_points":
        bonds = pdlin.find_bonds(cloud, ratio=2.0)
    return pdlin.Correspondence(E=1.0, nu=0.25, control=control, plane="strain"), cloud, bonds


@pytest.mark.parametrize("kind", ["bb3", "corr-none", "corr-sp"])
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
