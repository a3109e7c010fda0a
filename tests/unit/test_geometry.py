"""Point clouds, generators and bond search."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.errors import (
    DuplicatePointError,
    InputError,
    NoNeighborsError,
    NonFiniteError,
    ShapeError,
)


def test_grid_points_volumes_and_faces():
    c = pdlin.grid((4, 3, 2), spacing=(0.1, 0.2, 0.3), origin=(1.0, 2.0, 3.0))
    assert c.n == 24 and c.dim == 3
    # cell centres: origin + (k + 1/2) h
    np.testing.assert_allclose(c.points[0], [1.05, 2.1, 3.15])
    np.testing.assert_allclose(c.volumes, 0.1 * 0.2 * 0.3)
    assert c.point_set("x-").size == 6 and c.point_set("z+").size == 12
    np.testing.assert_allclose(c.points[c.point_set("x+"), 0], 1.35)


@pytest.mark.parametrize(
    "dim, ratio, expected",
    [
        # interior family sizes of cubic lattices, |xi| <= m h inclusive:
        (1, 3.015, 6),  # 2 * 3 neighbours on a line
        (2, 3.015, 28),  # lattice count: 2D family size 28 at 3.01
        (3, 3.015, 122),  # lattice count: 122 neighbours
        (3, 2.0, 32),  # lattice count: sphere m = 2 -> 32 bonds
        (3, 6.0, 924),  # lattice count: sphere m = 6 -> 924 bonds
    ],
)
def test_interior_family_sizes(dim, ratio, expected):
    n = int(2 * np.ceil(ratio) + 1)
    c = pdlin.grid((n,) * dim)
    b = pdlin.find_bonds(c, ratio=ratio)
    centre = int(np.ravel_multi_index((n // 2,) * dim, (n,) * dim))
    assert b.family_size[centre] == expected


@pytest.mark.parametrize(
    "shape, axes, expected",
    [
        ("cube", None, 2196),  # lattice count: cube |xi_k| <= 6 -> 2196 bonds
        ("ellipsoid", (4.0, 5.0, 6.0), 490),  # lattice count: ellipsoid a = (4, 5, 6) -> 490
        ("box", (4.0, 5.0, 6.0), 1286),  # lattice count: cuboid |xi| <= (4, 5, 6) -> 1286
    ],
)
def test_neighbourhood_shapes(shape, axes, expected):
    c = pdlin.grid((13, 13, 13))
    b = pdlin.find_bonds(c, 6.0, shape=shape, axes=axes)
    centre = int(np.ravel_multi_index((6, 6, 6), (13, 13, 13)))
    assert b.family_size[centre] == expected
    bt = pdlin.find_bonds(c, 6.0, shape=shape, axes=axes, method="tree")
    assert bt.family_size[centre] == expected


def test_lattice_and_tree_paths_agree(rng):
    c = pdlin.grid((9, 7, 6), spacing=0.3)
    a = pdlin.find_bonds(c, ratio=2.5, influence="inverse")
    b = pdlin.find_bonds(c, ratio=2.5, influence="inverse", method="tree")
    np.testing.assert_array_equal(a.indptr, b.indptr)
    np.testing.assert_array_equal(a.j, b.j)
    np.testing.assert_allclose(a.xi, b.xi, atol=1e-14)
    np.testing.assert_allclose(a.omega, b.omega, rtol=1e-14)


def test_bonds_are_symmetric_and_sorted(rng):
    pts = rng.random((300, 2))
    c = pdlin.PointCloud(pts, volumes=1.0 / 300, horizon=rng.uniform(0.08, 0.15, 300))
    b = pdlin.find_bonds(c)
    rev = b.reverse
    np.testing.assert_array_equal(b.i[rev], b.j)
    np.testing.assert_array_equal(b.j[rev], b.i)
    np.testing.assert_allclose(b.xi[rev], -b.xi)
    # symmetric family rule: |xi| <= max(delta_i, delta_j)
    assert np.all(b.length <= np.maximum(c.horizon[b.i], c.horizon[b.j]) * (1 + 1e-9))
    # and nothing missing: brute force count
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    hij = np.maximum(c.horizon[:, None], c.horizon[None])
    expected = (d <= hij) & ~np.eye(300, dtype=bool)
    assert b.n_bonds == int(expected.sum())
    for row in (0, 17, 299):
        seg = b.j[b.indptr[row] : b.indptr[row + 1]]
        assert np.all(np.diff(seg) > 0)
        np.testing.assert_array_equal(seg, np.flatnonzero(expected[row]))


def test_influence_functions():
    c = pdlin.grid((9, 9))
    for name, fn in [
        ("constant", lambda r, d: np.ones_like(r)),
        ("inverse", lambda r, d: 1 / r),
        ("delta_over_r", lambda r, d: d / r),
        ("gaussian", lambda r, d: np.exp(-((r / d) ** 2))),
    ]:
        b = pdlin.find_bonds(c, 3.0, influence=name)
        np.testing.assert_allclose(b.omega, fn(b.length, 3.0))
    b = pdlin.find_bonds(c, 3.0, influence=lambda r, d: 1.0 - (r / d) ** 1.5)
    np.testing.assert_allclose(b.omega, 1.0 - (b.length / 3.0) ** 1.5)
    with pytest.raises(InputError, match="influence function must be >= 0"):
        pdlin.find_bonds(c, 3.0, influence=lambda r, d: r - 2.0)
    with pytest.raises(InputError, match="influence must be one of"):
        pdlin.find_bonds(c, 3.0, influence="triangle")


def test_crack_removes_crossing_bonds():
    c = pdlin.grid((10, 10), spacing=0.1)
    crack = [[[0.5, -1.0], [0.5, 0.55]]]  # vertical cut x = 0.5 from the bottom to y = 0.55
    b = pdlin.find_bonds(c, ratio=2.0, cracks=crack)
    xi, xj = c.points[b.i], c.points[b.j]
    crosses = (xi[:, 0] - 0.5) * (xj[:, 0] - 0.5) < 0
    ycross = xi[:, 1] + (0.5 - xi[:, 0]) / np.where(crosses, xj[:, 0] - xi[:, 0], 1) * (
        xj[:, 1] - xi[:, 1]
    )
    assert not np.any(crosses & (ycross < 0.55))
    assert np.any(crosses & (ycross > 0.55))  # bonds above the tip survive
    np.testing.assert_array_equal(b.i[b.reverse], b.j)


def test_crack_triangles_3d():
    c = pdlin.grid((6, 6, 6), spacing=1.0)
    tri = [[[3.0, -1, -1], [3.0, 30, -1], [3.0, -1, 30]]]  # covers the plane x = 3 of the box
    b = pdlin.find_bonds(c, 1.5, cracks=tri)
    assert not np.any((c.points[b.i, 0] - 3) * (c.points[b.j, 0] - 3) < 0)


def test_crack_made_of_two_triangles_cuts_a_bond_through_their_shared_edge():
    # the rectangle x in [-6, 0], z in [-4, 1] of the plane y = 0 as two triangles; the bond
    # (two points of PrecrackJIntegral.g) meets the plane at (-1.5, 0, -0.25), on the diagonal
    # (found on Peridigm's PrecrackJIntegral deck: by round-off it crossed neither triangle)
    pts = np.array(
        [[-1.5, 0.5000000000000004, 7.285838599102592e-17], [-1.5, -1.5000000000000002, -1.0]]
    )
    cloud = pdlin.PointCloud(pts, np.ones(2))
    rect = [[[-6, 0, -4], [0, 0, -4], [0, 0, 1]], [[-6, 0, -4], [0, 0, 1], [-6, 0, 1]]]
    b = pdlin.find_bonds(cloud, 3.015, cracks=rect, allow_isolated=True)
    assert b.n_bonds == 0


def test_exclude_callable():
    c = pdlin.grid((8, 8))
    b = pdlin.find_bonds(c, 2.0, exclude=lambda a, z: (a[:, 0] < 2) & (z[:, 0] > 2))
    assert not np.any((c.points[b.i, 0] < 2) & (c.points[b.j, 0] > 2))
    assert not np.any((c.points[b.j, 0] < 2) & (c.points[b.i, 0] > 2))


def test_image_cloud():
    img = np.zeros((4, 5, 3), dtype=int)
    img[1:3, 1:4, :] = 1
    img[0, 0, 0] = -1
    c = pdlin.from_image(img, spacing=0.5, void=-1)
    assert c.n == 59  # 60 voxels minus one void voxel
    assert c.point_set("phase1").size == 18  # 2 * 3 * 3 voxels of phase 1
    b = pdlin.find_bonds(c, 1.0)
    bt = pdlin.find_bonds(c, 1.0, method="tree")
    np.testing.assert_array_equal(b.j, bt.j)


# -- bad input -------------------------------------------------------------
def test_nan_and_inf_coordinates():
    with pytest.raises(NonFiniteError, match="points must be finite"):
        pdlin.PointCloud([[0.0, 0.0], [np.inf, 1.0]], 1.0)


def test_duplicate_points_report_both_indices():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 0.0]])
    c = pdlin.PointCloud(pts, 1.0)
    with pytest.raises(DuplicatePointError, match="points 1 and 3") as exc:
        pdlin.find_bonds(c, 1.5)
    assert (exc.value.first, exc.value.second) == (1, 3)


def test_non_positive_volume():
    with pytest.raises(InputError, match=r"volumes must be > 0, got -1.0 at point 1"):
        pdlin.PointCloud([[0.0], [1.0]], [1.0, -1.0])


def test_isolated_point():
    c = pdlin.PointCloud([[0.0], [1.0], [5.0]], 1.0)
    with pytest.raises(NoNeighborsError, match="first index 2"):
        pdlin.find_bonds(c, 1.5)
    b = pdlin.find_bonds(c, 1.5, allow_isolated=True)
    assert b.family_size.tolist() == [1, 1, 0]


@pytest.mark.parametrize("h", [0.0, -0.1])
def test_bad_horizon(h):
    with pytest.raises(InputError, match="horizon must be > 0"):
        pdlin.find_bonds(pdlin.grid((4,)), h)


def test_mismatched_shapes():
    with pytest.raises(ShapeError, match=r"volumes must have shape \(3,\)"):
        pdlin.PointCloud(np.zeros((3, 2)) + np.arange(3)[:, None], [1.0, 1.0])
    with pytest.raises(ShapeError, match="points must have shape"):
        pdlin.PointCloud(np.zeros((3, 4)), 1.0)
    with pytest.raises(ShapeError, match=r"horizon must be a scalar or have shape \(4,\)"):
        pdlin.find_bonds(pdlin.grid((4,)), [1.0, 2.0])
    with pytest.raises(InputError, match="unknown point set 'top'"):
        pdlin.grid((3, 3)).point_set("top")
