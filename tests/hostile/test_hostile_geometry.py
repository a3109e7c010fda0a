"""Hostile input: point clouds, generators, bond search, meshes, images, polycrystals."""

from __future__ import annotations

import numpy as np
import pytest
from hostile_util import INF, NAN, expect

import pdlin
from pdlin.errors import (
    DuplicatePointError,
    InputError,
    InputTypeError,
    NoNeighborsError,
    NonFiniteError,
    ShapeError,
)

C2 = pdlin.grid((5, 5), 0.1)
P2 = [[0.0, 0.0], [1.0, 0.0]]

CASES = [
    # grid
    (
        "grid-nan-spacing",
        lambda: pdlin.grid((4, 4), NAN),
        NonFiniteError,
        r"spacing must be finite, got nan",
    ),
    (
        "grid-neg-spacing",
        lambda: pdlin.grid((4, 4), -1.0),
        InputError,
        r"spacing must be > 0, got \[-1.0",
    ),
    (
        "grid-zero-shape",
        lambda: pdlin.grid((0, 4)),
        InputError,
        r"shape entries must be >= 1, got \(0, 4\)",
    ),
    (
        "grid-float-shape",
        lambda: pdlin.grid((2.5, 4)),
        InputError,
        r"shape\[0\] must be an integer, got 2.5",
    ),
    (
        "grid-str-shape",
        lambda: pdlin.grid("ab"),
        InputError,
        r"shape must be an integer or a sequence of integers, got 'ab'",
    ),
    (
        "grid-4d",
        lambda: pdlin.grid((2, 2, 2, 2)),
        ShapeError,
        r"shape must have 1, 2 or 3 entries, got \(2, 2, 2, 2\)",
    ),
    (
        "grid-empty-shape",
        lambda: pdlin.grid(()),
        ShapeError,
        r"shape must have 1, 2 or 3 entries, got \(\)",
    ),
    (
        "grid-origin-nan",
        lambda: pdlin.grid((3, 3), 1.0, (NAN, 0)),
        NonFiniteError,
        r"origin must be finite, got nan",
    ),
    (
        "grid-origin-len",
        lambda: pdlin.grid((3, 3), 1.0, (0, 0, 0)),
        ShapeError,
        r"origin must have shape \(2,\), got \(3,\)",
    ),
    (
        "grid-spacing-len",
        lambda: pdlin.grid((3, 3), (1.0, 1.0, 1.0)),
        ShapeError,
        r"spacing must be a scalar or have shape \(2,\), got \(3,\)",
    ),
    (
        "grid-horizon-neg",
        lambda: pdlin.grid((3, 3), horizon=-1),
        InputError,
        r"horizon must be > 0, got -1.0",
    ),
    (
        "grid-thickness-0",
        lambda: pdlin.grid((3, 3), thickness=0),
        InputError,
        r"thickness must be > 0, got 0",
    ),
    (
        "grid-thickness-str",
        lambda: pdlin.grid((3, 3), thickness="a"),
        InputError,
        r"thickness must be a positive number, got 'a'",
    ),
    # PointCloud
    (
        "cloud-empty",
        lambda: pdlin.PointCloud(np.zeros((0, 2)), 1.0),
        InputError,
        r"points must hold at least one point, got 0",
    ),
    (
        "cloud-inf",
        lambda: pdlin.PointCloud([[0, 0], [INF, 0]], 1.0),
        NonFiniteError,
        r"points must be finite, got inf at index \(1, 0\)",
    ),
    (
        "cloud-4d",
        lambda: pdlin.PointCloud(np.zeros((3, 4)), 1.0),
        ShapeError,
        r"points must have shape \(n, dim\).*got \(3, 4\)",
    ),
    (
        "cloud-str",
        lambda: pdlin.PointCloud("abc", 1.0),
        InputError,
        r"points must be numeric, got str",
    ),
    (
        "cloud-ragged",
        lambda: pdlin.PointCloud([[0, 0], [1]], 1.0),
        InputError,
        r"points must be numeric, got list",
    ),
    (
        "cloud-complex",
        lambda: pdlin.PointCloud(np.array([[1j, 0]]), 1.0),
        InputTypeError,
        r"points must be real, got complex",
    ),
    (
        "cloud-vol-0",
        lambda: pdlin.PointCloud(P2, 0.0),
        InputError,
        r"volumes must be > 0, got 0.0 at point 0",
    ),
    (
        "cloud-vol-neg",
        lambda: pdlin.PointCloud(P2, [1.0, -1.0]),
        InputError,
        r"volumes must be > 0, got -1.0 at point 1",
    ),
    (
        "cloud-vol-nan",
        lambda: pdlin.PointCloud(P2, [1.0, NAN]),
        NonFiniteError,
        r"volumes must be finite, got nan at index 1",
    ),
    (
        "cloud-vol-shape",
        lambda: pdlin.PointCloud(P2, [1.0, 1.0, 1.0]),
        ShapeError,
        r"volumes must have shape \(2,\).*got \(3,\)",
    ),
    (
        "cloud-horizon-0",
        lambda: pdlin.PointCloud(P2, 1.0, horizon=0.0),
        InputError,
        r"horizon must be > 0, got 0.0",
    ),
    (
        "cloud-material-float",
        lambda: pdlin.PointCloud(P2, 1.0, material=[0.5, 1]),
        InputError,
        r"material must hold integer ids, got dtype float64",
    ),
    (
        "cloud-material-str",
        lambda: pdlin.PointCloud(P2, 1.0, material=["a", "b"]),
        InputError,
        r"material must hold integer ids, got dtype <U1",
    ),
    (
        "cloud-set-oob",
        lambda: pdlin.PointCloud(P2, 1.0, sets={"a": [5]}),
        InputError,
        r"sets\['a'\] must hold indices in \[0, 1\], got range \[5, 5\]",
    ),
    (
        "cloud-set-float",
        lambda: pdlin.PointCloud(P2, 1.0, sets={"a": [0.5]}),
        InputError,
        r"sets\['a'\] must hold integer point indices, got dtype float64",
    ),
    (
        "cloud-set-name",
        lambda: pdlin.PointCloud(P2, 1.0, sets={1: [0]}),
        InputError,
        r"set names must be strings, got 1",
    ),
    (
        "cloud-thickness-neg",
        lambda: pdlin.PointCloud(P2, 1.0, thickness=-1),
        InputError,
        r"thickness must be > 0, got -1",
    ),
    ("cloud-unknown-set", lambda: C2.point_set("nope"), InputError, r"unknown point set 'nope'"),
    (
        "cloud-subset-oob",
        lambda: C2.subset([100]),
        InputError,
        r"index must hold indices in \[0, 24\], got range \[100, 100\]",
    ),
    (
        "cloud-box-shape",
        lambda: C2.select(box=([0], [1, 1])),
        ShapeError,
        r"box corners must have shape \(2,\), got \(1,\) and \(2,\)",
    ),
    # find_bonds
    (
        "bonds-duplicates",
        lambda: pdlin.find_bonds(pdlin.PointCloud([[0.0, 0], [0, 0], [1, 0]], 1.0), 1.5),
        DuplicatePointError,
        r"points must be distinct, got points 0 and 1",
    ),
    (
        "bonds-single-point",
        lambda: pdlin.find_bonds(pdlin.PointCloud([[0.0, 0]], 1.0), 1.5),
        NoNeighborsError,
        r"got 1 isolated point\(s\), first index 0",
    ),
    (
        "bonds-horizon-0",
        lambda: pdlin.find_bonds(C2, 0.0),
        InputError,
        r"horizon must be > 0, got 0.0",
    ),
    (
        "bonds-horizon-neg",
        lambda: pdlin.find_bonds(C2, -0.3),
        InputError,
        r"horizon must be > 0, got -0.3",
    ),
    (
        "bonds-horizon-nan",
        lambda: pdlin.find_bonds(C2, NAN),
        NonFiniteError,
        r"horizon must be finite, got nan",
    ),
    (
        "bonds-horizon-inf",
        lambda: pdlin.find_bonds(C2, INF),
        NonFiniteError,
        r"horizon must be finite, got inf",
    ),
    (
        "bonds-horizon-str",
        lambda: pdlin.find_bonds(C2, "big"),
        InputError,
        r"horizon must be numeric, got str",
    ),
    (
        "bonds-horizon-shape",
        lambda: pdlin.find_bonds(C2, np.ones(3)),
        ShapeError,
        r"horizon must be a scalar or have shape \(25,\), got \(3,\)",
    ),
    (
        "bonds-horizon-and-ratio",
        lambda: pdlin.find_bonds(C2, 0.3, ratio=3),
        InputError,
        r"pass either horizon or ratio, not both",
    ),
    (
        "bonds-no-horizon",
        lambda: pdlin.find_bonds(C2),
        InputError,
        r"horizon must be given .* got None",
    ),
    (
        "bonds-ratio-neg",
        lambda: pdlin.find_bonds(C2, ratio=-3),
        InputError,
        r"ratio must be > 0, got -3",
    ),
    (
        "bonds-isolated",
        lambda: pdlin.find_bonds(C2, 0.01),
        NoNeighborsError,
        r"got 25 isolated point\(s\).*horizon 0.01",
    ),
    (
        "bonds-shape",
        lambda: pdlin.find_bonds(C2, 0.3, shape="cubic"),
        InputError,
        r"shape must be one of .*got 'cubic'",
    ),
    (
        "bonds-influence",
        lambda: pdlin.find_bonds(C2, 0.3, influence="gauss2"),
        InputError,
        r"influence must be one of .*got 'gauss2'",
    ),
    (
        "bonds-method",
        lambda: pdlin.find_bonds(C2, 0.3, method="fast"),
        InputError,
        r"method must be 'auto', 'lattice' or 'tree', got 'fast'",
    ),
    (
        "bonds-rtol-neg",
        lambda: pdlin.find_bonds(C2, 0.3, rtol=-1),
        InputError,
        r"rtol must be a number in \[0, 1\), got -1",
    ),
    (
        "bonds-axes-neg",
        lambda: pdlin.find_bonds(C2, 0.3, shape="ellipsoid", axes=[1, -1]),
        InputError,
        r"axes must be 2 positive lengths, got \[1.0, -1.0\]",
    ),
    (
        "bonds-not-cloud",
        lambda: pdlin.find_bonds(np.zeros((3, 2)), 0.3),
        InputError,
        r"cloud must be a PointCloud, got ndarray",
    ),
    # read_mesh
    (
        "mesh-missing",
        lambda: pdlin.read_mesh("/nonexistent/x.msh"),
        InputError,
        r"mesh file '/nonexistent/x.msh' does not exist",
    ),
    (
        "mesh-directory",
        lambda: pdlin.read_mesh("/"),
        InputError,
        r"mesh file '/' does not exist \(or is not a file\)",
    ),
    (
        "mesh-int",
        lambda: pdlin.read_mesh(5),
        InputTypeError,
        r"source must be a file path or a meshio.Mesh, got int",
    ),
    # from_image
    (
        "image-empty",
        lambda: pdlin.from_image(np.zeros((0, 3))),
        ShapeError,
        r"image must be a non-empty .* got shape \(0, 3\)",
    ),
    (
        "image-all-void",
        lambda: pdlin.from_image(np.zeros((3, 3), int), void=0),
        InputError,
        r"image holds only the void phase 0",
    ),
    (
        "image-nan",
        lambda: pdlin.from_image(np.array([[1.0, NAN]])),
        NonFiniteError,
        r"image must be finite, got nan at index \(0, 1\)",
    ),
    (
        "image-4d",
        lambda: pdlin.from_image(np.ones((2, 2, 2, 2), int)),
        ShapeError,
        r"got shape \(2, 2, 2, 2\)",
    ),
    (
        "image-str",
        lambda: pdlin.from_image(np.array([["a", "b"]])),
        InputError,
        r"image must hold integer phase ids, got dtype <U1",
    ),
    (
        "image-fraction",
        lambda: pdlin.from_image(np.full((3, 3), 0.5)),
        InputError,
        r"image must hold integer phase ids, got dtype float64",
    ),
    # ghost_layer, voronoi_polycrystal
    (
        "ghost-0",
        lambda: pdlin.ghost_layer(C2, 0),
        InputError,
        r"layers must be an integer >= 1, got 0",
    ),
    (
        "ghost-float",
        lambda: pdlin.ghost_layer(C2, 1.5),
        InputError,
        r"layers must be an integer >= 1, got 1.5",
    ),
    (
        "ghost-no-lattice",
        lambda: pdlin.ghost_layer(pdlin.PointCloud(P2, 1.0), 1),
        InputError,
        r"ghost_layer needs a lattice cloud",
    ),
    (
        "voronoi-0",
        lambda: pdlin.voronoi_polycrystal(C2, 0),
        InputError,
        r"n_grains must be an integer in \[1, 25\].*got 0",
    ),
    (
        "voronoi-too-many",
        lambda: pdlin.voronoi_polycrystal(C2, 1000),
        InputError,
        r"n_grains .* got 1000",
    ),
    (
        "voronoi-orient-nan",
        lambda: pdlin.voronoi_polycrystal(C2, 2, orientations=[1, NAN]),
        NonFiniteError,
        r"orientations must be finite, got nan at index 1",
    ),
    (
        "voronoi-seed",
        lambda: pdlin.voronoi_polycrystal(C2, 2, seed="x"),
        InputError,
        r"seed must be an int, None or a numpy Generator, got 'x'",
    ),
]


@pytest.mark.parametrize(
    ("call", "exc", "pattern"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_geometry_rejects(call, exc, pattern):
    expect(call, exc, pattern)


# --- geometric selectors: non-finite numbers and empty selections (issue 31, item 3) -------

C3 = pdlin.grid((4, 4, 4), 0.1)

SELECTOR_CASES = [
    (
        "select-box-nan",
        lambda: C2.select(box=([NAN, 0.0], [1.0, 1.0])),
        NonFiniteError,
        r"box lower corner must hold numbers \(-inf / inf for open sides\), got nan at index 0",
    ),
    (
        "select-box-upper-nan",
        lambda: C2.select(box=([0.0, 0.0], [1.0, NAN])),
        NonFiniteError,
        r"box upper corner must hold numbers .* got nan at index 1",
    ),
    (
        "select-box-inverted",
        lambda: C2.select(box=([0.3, 0.0], [0.1, 1.0])),
        InputError,
        r"box lower corner must not exceed the upper one, got lower \[0.3, 0.0\] and upper "
        r"\[0.1, 1.0\] \(axis 0\)",
    ),
    (
        "crack-nan",
        lambda: pdlin.find_bonds(C2, 0.15, cracks=[[[NAN, 0.0], [0.2, 0.5]]]),
        NonFiniteError,
        r"cracks must be finite, got nan at index \(0, 0, 0\)",
    ),
    (
        "crack-inf",
        lambda: pdlin.find_bonds(C2, 0.15, cracks=[[[0.2, 0.0], [0.2, INF]]]),
        NonFiniteError,
        r"cracks must be finite, got inf at index \(0, 1, 1\)",
    ),
    (
        # C2 spans [0.05, 0.45]^2: a crack at x = 5 cuts nothing
        "crack-outside",
        lambda: pdlin.find_bonds(C2, 0.15, cracks=[[[5.0, 5.0], [6.0, 6.0]]]),
        InputError,
        r"cracks\[0\] \(segment \(5, 5\) - \(6, 6\)\) cuts no bond \(1 of 1 crack piece\(s\) "
        r"cut none; points span",
    ),
    (
        # the first crack (x = 0.2, between the columns at 0.15 and 0.25) cuts; the second not
        "crack-second-idle",
        lambda: pdlin.find_bonds(
            C2, 0.15, cracks=[[[0.2, 0.0], [0.2, 0.5]], [[0.2, 2.0], [0.3, 3.0]]]
        ),
        InputError,
        r"cracks\[1\] \(segment \(0.2, 2\) - \(0.3, 3\)\) cuts no bond",
    ),
    (
        "crack-triangle-outside",
        lambda: pdlin.find_bonds(C3, 0.15, cracks=[[[2, 2, 2], [3, 2, 2], [2, 3, 2]]]),
        InputError,
        r"cracks\[0\] \(triangle \(2, 2, 2\) - \(3, 2, 2\) - \(2, 3, 2\)\) cuts no bond",
    ),
    (
        "crack-outside-with-symmetry",
        lambda: pdlin.solve(
            pdlin.StaticProblem(
                pdlin.BondBased(E=1.0),
                pdlin.grid((6, 6), 0.1),
                horizon=0.301,
                dirichlet=[pdlin.Dirichlet("x+", 0.0)],
                loads=[pdlin.TotalForce("y+", [0.0, 1e-3])],
                symmetry=[pdlin.SymmetryPlane("x", 0.0)],
                bond_options={"cracks": [[[5.0, 5.0], [6.0, 6.0]]]},
            )
        ),
        InputError,
        r"cracks\[0\] \(segment \(5, 5\) - \(6, 6\)\) cuts no bond",
    ),
    (
        "symmetry-position-nan",
        lambda: pdlin.SymmetryPlane("x", NAN),
        NonFiniteError,
        r"position must be finite, got nan",
    ),
    (
        "subregion-box-nan",
        lambda: pdlin.subregion(
            pdlin.StaticProblem(
                pdlin.BondBased(E=1.0), C2, horizon=0.15, dirichlet=[pdlin.Dirichlet("x-")]
            ),
            [[0.1, NAN], [0.3, 0.3]],
            lambda X: 0.0 * X,
        ),
        NonFiniteError,
        r"box must be finite, got nan at index \(0, 1\)",
    ),
]


@pytest.mark.parametrize(
    ("call", "exc", "pattern"),
    [c[1:] for c in SELECTOR_CASES],
    ids=[c[0] for c in SELECTOR_CASES],
)
def test_selectors_reject(call, exc, pattern):
    expect(call, exc, pattern)


def test_select_box_open_sides_still_work():
    # -inf / inf are open sides: the right column of the 5 x 5 grid (x = 0.45)
    idx = C2.select(box=([0.4, -INF], [INF, INF]))
    assert idx.tolist() == [20, 21, 22, 23, 24]  # C order: point (4, j) is 5 * 4 + j


def test_crack_with_symmetry_counts_its_images():
    # plane x = 0, ghosts reach x = -0.301: the crack at x = 0.45 cuts real bonds, its
    # image at x = -0.45 lies beyond the ghosts and cuts nothing; the crack is accepted
    from pdlin.operators.symmetry import symmetry_reduction

    cloud, plane = pdlin.grid((6, 6), 0.1), [pdlin.SymmetryPlane("x", 0.0)]
    model = pdlin.BondBased(E=1.0)
    cut = symmetry_reduction(model, cloud, plane, 0.301, {"cracks": [[[0.45, 0.0], [0.45, 0.3]]]})
    whole = symmetry_reduction(model, cloud, plane, 0.301)
    assert cut.bonds.n_bonds < whole.bonds.n_bonds
