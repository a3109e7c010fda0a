"""The compiled (numba) bond-based force pass of explicit dynamics against the numpy path.

The compiled pass repeats the numpy arithmetic per bond in its order and sums each point's
family in bond order, so forces and bond masks must be equal bit for bit, for any thread
count and chunking; energies are chunk sums (round-off).  Skipped without numba (or with
``PDLIN_NUMBA=0``).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

import pdlin
from pdlin._kernels import numba_enabled
from pdlin.dynamics import force_kernel, forces, solve_explicit
from pdlin.errors import InputError

if not numba_enabled():  # numba missing or PDLIN_NUMBA=0
    pytest.skip("the compiled passes need numba", allow_module_level=True)

SHAPES = {1: (40,), 2: (14, 9), 3: (7, 6, 5)}


@pytest.fixture(autouse=True)
def _small_chunks(monkeypatch):
    # many chunks on small clouds, so the chunking and the threads are exercised
    monkeypatch.setattr(forces, "_CHUNK_BONDS", 64)
    yield
    pdlin.set_num_threads(None)


def _setup(dim, ratio=3.015):
    cloud = pdlin.grid(SHAPES[dim], spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=ratio)
    plane = {"plane": "strain"} if dim == 2 else {}
    return pdlin.BondBased(E=3.0, **plane), cloud, bonds


def _pair(dim, linear, ratio=3.015):
    model, cloud, bonds = _setup(dim, ratio)
    a = force_kernel(model, cloud, bonds, linear=linear, compiled=False)
    b = force_kernel(model, cloud, bonds, linear=linear, compiled=True)
    assert a.kern is None and b.kern is not None
    return a, b, cloud, bonds


def _u(cloud, scale=0.02, seed=1):
    return scale * np.random.default_rng(seed).normal(size=(cloud.n, cloud.dim))


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("linear", [True, False])
def test_force_bitwise_equal_to_numpy(dim, linear):
    a, b, cloud, bonds = _pair(dim, linear)
    u = _u(cloud)
    assert np.array_equal(a.force(u, None), b.force(u, None))
    # a symmetric mask with some bonds broken (both directions)
    rev = np.asarray(bonds.reverse)
    cut = np.random.default_rng(2).random(bonds.n_bonds) < 0.2
    alive = np.where(cut | cut[rev], 0.0, 1.0)
    fa, ea, _ = a.evaluate(u, alive.copy(), None)
    fb, eb, _ = b.evaluate(u, alive.copy(), None)
    assert np.array_equal(fa, fb)
    # energies: chunk sums against numpy's dot, round-off only
    assert eb == pytest.approx(ea, rel=1e-13)


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("linear", [True, False])
def test_breaking_bitwise_equal_to_numpy(dim, linear):
    a, b, cloud, bonds = _pair(dim, linear)
    u = _u(cloud)
    s0 = np.full(bonds.n_bonds, 0.05)  # about a third of the bonds of u exceed it
    al_a, al_b = np.ones(bonds.n_bonds), np.ones(bonds.n_bonds)
    fa, ea, ra = a.evaluate(u, al_a, s0)
    fb, eb, rb = b.evaluate(u, al_b, s0)
    n_broken = int(np.sum(al_a == 0))
    assert 0 < n_broken < bonds.n_bonds
    assert np.array_equal(al_a, al_b)
    assert np.array_equal(al_b, al_b[np.asarray(bonds.reverse)])
    assert np.array_equal(fa, fb)
    assert eb == pytest.approx(ea, rel=1e-13)
    assert rb == pytest.approx(ra, rel=1e-13)
    # breaking is irreversible: a second pass at u breaks nothing more
    fb2, eb2, rb2 = b.evaluate(u, al_b, s0)
    assert rb2 == 0.0 and np.array_equal(fb2, fb) and np.array_equal(al_a, al_b)


@pytest.mark.parametrize("linear", [True, False])
def test_threads_do_not_change_the_bits(linear):
    _, b, cloud, bonds = _pair(3, linear)
    u = _u(cloud)
    s0 = np.full(bonds.n_bonds, 0.05)
    out = []
    for n in (1, 2):
        pdlin.set_num_threads(n)
        alive = np.ones(bonds.n_bonds)
        out.append((*b.evaluate(u, alive, s0), alive))
    for x, y in zip(out[0], out[1], strict=True):
        assert np.array_equal(x, y)


def test_asymmetric_thresholds_fall_back_to_numpy():
    a, b, cloud, bonds = _pair(2, False)
    u = _u(cloud)
    rev = np.asarray(bonds.reverse)
    s0 = np.full(bonds.n_bonds, 0.05)
    s0[np.arange(bonds.n_bonds) < rev] = 10.0  # one direction unbreakable
    al_a, al_b = np.ones(bonds.n_bonds), np.ones(bonds.n_bonds)
    fa, _, _ = a.evaluate(u, al_a, s0)
    fb, _, _ = b.evaluate(u, al_b, s0)
    # numpy's rule: a bond breaks in both directions when either exceeds its threshold
    assert np.sum(al_a == 0) > 0
    assert np.array_equal(al_a, al_b) and np.array_equal(fa, fb)


def test_collapsed_bond_raises():
    _, b, cloud, bonds = _pair(1, False, ratio=1.0)
    u = np.zeros((cloud.n, 1))
    u[1, 0] = -0.1  # point 1 onto point 0 (spacing 0.1)
    with pytest.raises(InputError, match="zero length"):
        b.evaluate(u, None, None)


def test_solve_explicit_same_bits(monkeypatch):
    from pdlin.dynamics import explicit

    model, cloud, bonds = _setup(2)
    from pdlin.operators import TimePath

    pull = pdlin.Dirichlet("x+", TimePath(lambda x, t: 0.2 * t), components="x")
    prob = pdlin.StaticProblem(model, cloud, bonds, dirichlet=[pdlin.Dirichlet("x-", 0.0), pull])
    runs = []
    for compiled in (False, True):
        monkeypatch.setattr(
            explicit, "force_kernel", functools.partial(force_kernel, compiled=compiled)
        )
        runs.append(solve_explicit(prob, 1.0, density=1.0, critical_stretch=0.02))
    a, b = runs
    assert a.steps == b.steps > 10
    assert 0 < int(a.broken[-1])  # the pull (0.2 at t = 1 against a 0.1 spacing) breaks bonds
    assert np.array_equal(a.u, b.u) and np.array_equal(a.v, b.v)
    assert np.array_equal(a.alive, b.alive)
    np.testing.assert_allclose(b.strain, a.strain, rtol=1e-12, atol=1e-12 * a.strain.max())


# -- state-based (LPS, XOSB) --------------------------------------------------------------

STATE_MODELS = {
    "lps": lambda pl: pdlin.LPS(E=3.0, nu=0.25, **pl),
    "xosb": lambda pl: pdlin.XOSB(E=3.0, nu=0.25, **pl),
    "xosb-paper": lambda pl: pdlin.XOSB(E=3.0, nu=0.25, linearization="paper", **pl),
}


def _state_pair(name, dim, linear):
    cloud = pdlin.grid(SHAPES[dim], spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    model = STATE_MODELS[name]({"plane": "strain"} if dim == 2 else {})
    a = force_kernel(model, cloud, bonds, linear=linear, compiled=False)
    b = force_kernel(model, cloud, bonds, linear=linear, compiled=True)
    assert a.kern is None and b.kern is not None
    return a, b, cloud, bonds


@pytest.mark.parametrize("name", sorted(STATE_MODELS))
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("linear", [True, False])
def test_state_force_and_breaking_bitwise_equal_to_numpy(name, dim, linear):
    a, b, cloud, bonds = _state_pair(name, dim, linear)
    u = _u(cloud)
    assert np.array_equal(a.force(u, None), b.force(u, None))
    rev = np.asarray(bonds.reverse)
    cut = np.random.default_rng(2).random(bonds.n_bonds) < 0.2
    alive = np.where(cut | cut[rev], 0.0, 1.0)
    fa, ea, _ = a.evaluate(u, alive.copy(), None)
    fb, eb, _ = b.evaluate(u, alive.copy(), None)
    assert np.array_equal(fa, fb)
    assert eb == pytest.approx(ea, rel=1e-13)  # chunk sums against numpy's dot
    s0 = np.full(bonds.n_bonds, 0.05)
    al_a, al_b = np.ones(bonds.n_bonds), np.ones(bonds.n_bonds)
    fa, ea, ra = a.evaluate(u, al_a, s0)
    fb, eb, rb = b.evaluate(u, al_b, s0)
    assert 0 < np.sum(al_a == 0) < bonds.n_bonds
    assert np.array_equal(al_a, al_b) and np.array_equal(fa, fb)
    assert eb == pytest.approx(ea, rel=1e-13)
    assert rb == pytest.approx(ra, rel=1e-12)


def test_state_threads_do_not_change_the_bits():
    _, b, cloud, bonds = _state_pair("xosb", 3, False)
    u = _u(cloud)
    s0 = np.full(bonds.n_bonds, 0.05)
    out = []
    for n in (1, 2):
        pdlin.set_num_threads(n)
        alive = np.ones(bonds.n_bonds)
        out.append((*b.evaluate(u, alive, s0), alive))
    for x, y in zip(out[0], out[1], strict=True):
        assert np.array_equal(x, y)


def test_state_fractional_mask_falls_back_to_numpy():
    a, b, cloud, bonds = _state_pair("lps", 2, True)
    u = _u(cloud)
    alive = np.full(bonds.n_bonds, 0.5)  # not 0/1: the compiled passes decline it
    assert b._compiled(u, alive, None) is None
    assert np.array_equal(a.force(u, alive), b.force(u, alive))


def test_solve_explicit_lps_same_bits(monkeypatch):
    from pdlin.dynamics import explicit
    from pdlin.operators import TimePath

    cloud = pdlin.grid(SHAPES[2], spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    model = pdlin.LPS(E=3.0, nu=0.25, plane="strain")
    pull = pdlin.Dirichlet("x+", TimePath(lambda x, t: 0.2 * t), components="x")
    prob = pdlin.StaticProblem(model, cloud, bonds, dirichlet=[pdlin.Dirichlet("x-", 0.0), pull])
    runs = []
    for compiled in (False, True):
        monkeypatch.setattr(
            explicit, "force_kernel", functools.partial(force_kernel, compiled=compiled)
        )
        runs.append(solve_explicit(prob, 1.0, density=1.0, critical_stretch=0.02))
    a, b = runs
    assert a.steps == b.steps > 10 and int(a.broken[-1]) > 0
    assert np.array_equal(a.u, b.u) and np.array_equal(a.v, b.v)
    assert np.array_equal(a.alive, b.alive)
    np.testing.assert_allclose(b.strain, a.strain, rtol=1e-12, atol=1e-12 * a.strain.max())
