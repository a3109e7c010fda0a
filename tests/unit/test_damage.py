"""Stretch-based damage (Liu, Chen & Skelton, XOSB, Eq. 88; G0 erratum in
docs/theory/conventions.md#errata-liu-chen-and-skelton)."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError, ModelError, ShapeError
from pdlin.models.damage import (
    bond_stretch,
    break_bonds,
    critical_stretch,
    damage_index,
    drop_isolated,
    isolated_points,
)


# ---------------------------------------------------------------- critical stretch
@pytest.mark.parametrize(("G0", "expected"), [(22_170.0, 6.3714e-3), (222_170.0, 2.0170e-2)])
def test_critical_stretch_spec_values(G0, expected):
    # derived from Liu, Chen & Skelton, XOSB, Sec. 5.3: E = 190 GPa, delta = 3.01 * 1.25 mm, plane
    # strain (Eq. 88)
    s0 = critical_stretch(G0, 190e9, 3.7625e-3)
    assert s0 == pytest.approx(expected, rel=1e-4)
    assert critical_stretch(G0, 190e9, 3.7625e-3, plane="strain", dim=2) == s0


def test_critical_stretch_other_forms():
    G0, E, d = 1000.0, 70e9, 1e-3
    assert critical_stretch(G0, E, d, plane="stress") == pytest.approx(
        np.sqrt(4 * np.pi * G0 / (9 * E * d))
    )
    kappa = 2 * E / 3  # nu = 1/4
    assert critical_stretch(G0, E, d, dim=3) == pytest.approx(np.sqrt(5 * G0 / (9 * kappa * d)))
    s = critical_stretch(G0, E, np.array([1e-3, 4e-3]))
    assert s.shape == (2,)
    assert s[0] / s[1] == pytest.approx(2.0)


@pytest.mark.parametrize(
    "kwargs",
    [{"plane": "stress", "dim": 3}, {"plane": "axisym"}, {"dim": 1}, {"dim": 3, "plane": "strain"}],
)
def test_critical_stretch_unsupported(kwargs):
    with pytest.raises(ModelError):
        critical_stretch(1.0, 1.0, 1.0, **kwargs)


@pytest.mark.parametrize("args", [(0.0, 1.0, 1.0), (1.0, -1.0, 1.0), (1.0, 1.0, 0.0)])
def test_critical_stretch_nonpositive(args):
    with pytest.raises(InputError):
        critical_stretch(*args)


# ---------------------------------------------------------------- stretch
@pytest.fixture
def plate():
    cloud = pdlin.grid((12, 10), spacing=0.1)
    return cloud, pdlin.find_bonds(cloud, ratio=3.01)


def test_stretch_affine_small_strain(plate):
    cloud, bonds = plate
    eps = 1e-7 * np.array([[1.0, 0.4], [0.4, -0.3]])
    s = bond_stretch(cloud, bonds, cloud.points @ eps.T)
    n = bonds.xi / bonds.length[:, None]
    nen = np.einsum("bi,ij,bj->b", n, eps, n)
    assert np.max(np.abs(s - nen)) < 1e-13  # O(|eps|^2)
    assert np.array_equal(s, s[bonds.reverse])


def test_stretch_affine_finite(plate):
    cloud, bonds = plate
    H = np.array([[0.3, -0.2], [0.5, 0.1]])
    u = cloud.points @ H.T
    s = bond_stretch(cloud, bonds, u.ravel())  # flat layout accepted
    y = bonds.xi @ (np.eye(2) + H).T
    exact = np.linalg.norm(y, axis=1) / np.linalg.norm(bonds.xi, axis=1) - 1.0
    np.testing.assert_allclose(s, exact, rtol=0, atol=1e-13)


def test_stretch_3d_rigid_rotation():
    cloud = pdlin.grid((4, 4, 4), spacing=1.0)
    bonds = pdlin.find_bonds(cloud, 1.8)
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    u = cloud.points @ R.T - cloud.points
    assert np.max(np.abs(bond_stretch(cloud, bonds, u))) < 1e-14


# ---------------------------------------------------------------- breaking
def _pairs(b):
    return {(int(i), int(j)) for i, j in zip(b.i, b.j, strict=True)}


def _check_csr(b):
    assert b.indptr[0] == 0 and b.indptr[-1] == b.n_bonds
    assert np.array_equal(np.diff(b.indptr), np.bincount(b.i, minlength=b.n_points))
    assert np.all(np.diff(b.i) >= 0)
    for p in range(b.n_points):
        assert np.all(np.diff(b.j[b.indptr[p] : b.indptr[p + 1]]) > 0)
    rev = b.reverse
    assert np.array_equal(b.i[rev], b.j) and np.array_equal(b.j[rev], b.i)
    np.testing.assert_array_equal(b.xi[rev], -b.xi)


def test_break_bonds_both_directions(plate):
    cloud, bonds = plate
    rng = np.random.default_rng(0)
    u = 0.01 * rng.standard_normal((cloud.n, 2))
    s = bond_stretch(cloud, bonds, u)
    s0 = float(np.quantile(s, 0.8))
    new, nb = break_bonds(cloud, bonds, u, s0)
    assert nb == bonds.n_bonds - new.n_bonds > 0
    assert nb % 2 == 0
    _check_csr(new)
    gone = _pairs(bonds) - _pairs(new)
    assert all((j, i) in gone for i, j in gone)
    # exactly the bonds above s0 are gone (stretch is symmetric)
    assert gone == {(int(i), int(j)) for i, j in zip(bonds.i[s > s0], bonds.j[s > s0], strict=True)}
    phi = damage_index(bonds, new)
    assert phi.shape == (cloud.n,)
    assert np.all((phi >= 0) & (phi <= 1)) and phi.max() > 0
    # irreversible: breaking again with the same field breaks nothing more
    again, n2 = break_bonds(cloud, new, u, s0)
    assert n2 == 0 and again is new


def test_nothing_breaks(plate):
    cloud, bonds = plate
    u = 1e-6 * cloud.points
    new, nb = break_bonds(cloud, bonds, u, 1e-3)
    assert nb == 0 and new is bonds
    assert np.array_equal(damage_index(bonds, new), np.zeros(cloud.n))
    assert isolated_points(new).size == 0


def test_step_breaks_exactly_crossing_bonds():
    h = 0.1
    cloud = pdlin.grid((14, 11), spacing=h)
    bonds = pdlin.find_bonds(cloud, ratio=3.01)
    xc = float(cloud.points[:, 0].min()) + 6.5 * h  # between two columns
    u = np.zeros((cloud.n, 2))
    u[cloud.points[:, 0] > xc, 0] = 0.05 * h  # opening jump across x = xc
    new, nb = break_bonds(cloud, bonds, u, 1e-8)
    crack = [[[xc, -10.0], [xc, 10.0]]]
    ref = pdlin.find_bonds(cloud, ratio=3.01, cracks=crack)
    assert nb > 0
    assert np.array_equal(new.i, ref.i) and np.array_equal(new.j, ref.j)
    assert np.array_equal(new.indptr, ref.indptr)
    np.testing.assert_array_equal(new.xi, ref.xi)
    phi = damage_index(bonds, new)
    far = np.abs(cloud.points[:, 0] - xc) > 3.01 * h
    assert np.all(phi[far] == 0) and np.all(phi[~far] > 0)


def test_per_bond_s0(plate):
    cloud, bonds = plate
    u = 0.01 * cloud.points
    s0 = np.where(bonds.i < 5, 1e-3, 1.0)  # only the families of points 0..4 may break
    new, nb = break_bonds(cloud, bonds, u, s0)
    _check_csr(new)
    gone = _pairs(bonds) - _pairs(new)
    assert nb == len(gone) > 0
    assert all(i < 5 or j < 5 for i, j in gone)


def test_isolated_points_and_drop():
    cloud = pdlin.grid((5, 3), spacing=1.0)
    bonds = pdlin.find_bonds(cloud, 1.5)
    k = 7  # interior point, pulled away
    u = np.zeros((cloud.n, 2))
    u[k] = [0.0, 5.0]
    new, nb = break_bonds(cloud, bonds, u, 0.5)
    assert nb == 2 * bonds.family_size[k]
    assert np.array_equal(isolated_points(new), [k])
    assert damage_index(bonds, new)[k] == 1.0
    c2, b2, keep = drop_isolated(cloud, new)
    assert c2.n == cloud.n - 1 and k not in keep
    np.testing.assert_array_equal(c2.points, cloud.points[keep])
    _check_csr(b2)
    assert b2.n_bonds == new.n_bonds
    # same bonds, re-indexed
    np.testing.assert_array_equal(keep[b2.i], new.i)
    np.testing.assert_array_equal(keep[b2.j], new.j)
    assert isolated_points(b2).size == 0
    # the reduced stiffness has no empty rows
    K = pdlin.BondBased(1.0, plane="stress").stiffness(c2, b2).toarray()
    assert np.all(np.abs(K).sum(axis=1) > 0)


# ---------------------------------------------------------------- errors
def test_bad_inputs(plate):
    cloud, bonds = plate
    u = np.zeros((cloud.n, 2))
    for s0 in (0.0, -1.0, np.zeros(bonds.n_bonds)):
        with pytest.raises(InputError):
            break_bonds(cloud, bonds, u, s0)
    with pytest.raises(ShapeError):
        break_bonds(cloud, bonds, u, np.ones(3))
    with pytest.raises(ShapeError):
        bond_stretch(cloud, bonds, np.zeros((cloud.n, 3)))
    with pytest.raises(ShapeError):
        bond_stretch(cloud, bonds, np.zeros(cloud.n + 1))
    other = pdlin.grid((3, 3))
    with pytest.raises(ShapeError):
        bond_stretch(other, bonds, np.zeros((other.n, 2)))
    with pytest.raises(InputError):
        bond_stretch(cloud, bonds, np.full((cloud.n, 2), np.nan))
    small = pdlin.find_bonds(pdlin.grid((3, 3)), 1.5)
    with pytest.raises(ShapeError):
        damage_index(bonds, small)
    # bonds_now must be a subset of bonds_intact
    with pytest.raises(InputError):
        damage_index(pdlin.find_bonds(cloud, ratio=1.01), bonds)
