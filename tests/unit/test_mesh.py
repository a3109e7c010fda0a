"""Tests of pdlin.read_mesh, cell_measures and plate_with_hole_mesh."""

from __future__ import annotations

import importlib.util
import logging
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError, InputTypeError
from pdlin.geometry.generators import plate_with_hole_mesh
from pdlin.geometry.mesh import cell_measures, read_mesh

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

UNIT_CUBE = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)


def _trilinear_gauss(x: np.ndarray) -> tuple[float, np.ndarray]:
    """Volume and centroid of a trilinear hexahedron by 2x2x2 Gauss quadrature.

    Independent of pdlin: det J of the trilinear map has degree <= 2 and
    x det J degree <= 3 per reference variable, so 2 Gauss points per axis
    integrate both exactly.
    """
    g = np.array([0.5 - 0.5 / np.sqrt(3), 0.5 + 0.5 / np.sqrt(3)])
    ref = UNIT_CUBE
    vol, mom = 0.0, np.zeros(3)
    for u in g:
        for v in g:
            for w in g:
                p = np.array([u, v, w])
                # shape functions prod_k (ref_k p_k + (1 - ref_k)(1 - p_k))
                f = ref * p + (1 - ref) * (1 - p)
                n = f.prod(axis=1)
                dn = np.empty((8, 3))
                for k in range(3):
                    others = np.delete(f, k, axis=1).prod(axis=1)
                    dn[:, k] = (2 * ref[:, k] - 1) * others
                det = np.linalg.det(x.T @ dn) / 8.0
                vol += det
                mom += det * (n @ x)
    return vol, mom / vol


# --------------------------------------------------------------------------- measures


def test_unit_square_two_triangles() -> None:
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    area, cen = cell_measures(pts, [[0, 1, 2], [0, 2, 3]], "triangle")
    # hand computation: each half of the unit square has area 1/2,
    # centroid = vertex mean (2/3, 1/3) and (1/3, 2/3)
    np.testing.assert_allclose(area, [0.5, 0.5], rtol=1e-15)
    np.testing.assert_allclose(cen, [[2 / 3, 1 / 3], [1 / 3, 2 / 3]], rtol=1e-15)


def test_unit_square_four_quads_through_read_mesh() -> None:
    x, y = np.meshgrid([0.0, 0.5, 1.0], [0.0, 0.5, 1.0], indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(9)], axis=1)  # z = 0 -> 2D cloud
    node = np.arange(9).reshape(3, 3)
    quads = [
        [node[i, j], node[i + 1, j], node[i + 1, j + 1], node[i, j + 1]]
        for i in range(2)
        for j in range(2)
    ]
    cloud = read_mesh(meshio.Mesh(pts, [("quad", quads)]))
    assert cloud.dim == 2
    # hand computation: 2x2 cells of side 1/2
    np.testing.assert_allclose(cloud.volumes, 0.25, rtol=1e-15)
    np.testing.assert_allclose(
        cloud.points, [[0.25, 0.25], [0.25, 0.75], [0.75, 0.25], [0.75, 0.75]], rtol=1e-15
    )


def test_quad_area_centroid_is_not_node_average() -> None:
    pts = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 3.0]])
    area, cen = cell_measures(pts, [[0, 1, 2, 3]], "quad")
    # hand computation: rectangle [0,2]x[0,1] (area 2, centroid (1, 1/2)) plus
    # triangle (0,1),(2,1),(0,3) (area 2, centroid (2/3, 5/3)):
    # area 4, centroid (10/12, 13/12); the node mean would be (1, 1.25)
    np.testing.assert_allclose(area, [4.0], rtol=1e-15)
    np.testing.assert_allclose(cen, [[10 / 12, 13 / 12]], rtol=1e-14)


def test_tetra() -> None:
    pts = np.array([[1.0, 1.0, 1.0], [3.0, 1.0, 1.0], [1.0, 4.0, 1.0], [1.0, 1.0, 5.0]])
    vol, cen = cell_measures(pts, [[0, 1, 2, 3]], "tetra")
    # hand computation: legs 2, 3, 4 -> volume 2*3*4/6 = 4; centroid = vertex mean
    np.testing.assert_allclose(vol, [4.0], rtol=1e-15)
    np.testing.assert_allclose(cen, [[1.5, 1.75, 2.0]], rtol=1e-15)


def test_skewed_parallelepiped_hexahedron() -> None:
    A = np.array([[2.0, 0.5, 0.3], [0.0, 1.5, 0.4], [0.1, 0.0, 0.8]])
    b = np.array([1.0, -2.0, 0.5])
    x = UNIT_CUBE @ A.T + b
    vol, cen = cell_measures(x, [list(range(8))], "hexahedron")
    # affine image of the unit cube: volume det(A), centroid A (1/2, 1/2, 1/2) + b
    np.testing.assert_allclose(vol, [np.linalg.det(A)], rtol=1e-14)
    np.testing.assert_allclose(cen, [A @ [0.5, 0.5, 0.5] + b], rtol=1e-14)


def test_hexahedron_with_warped_face_closed_form() -> None:
    h = 0.6
    x = UNIT_CUBE.copy()
    x[6, 2] += h  # node (1, 1, 1) raised: the top face is a hyperbolic paraboloid
    vol, cen = cell_measures(x, [list(range(8))], "hexahedron")
    # derived: the trilinear map is x = u, y = v, z = w (1 + h u v), det J = 1 + h u v,
    # V = 1 + h/4, int x dV = 1/2 + h/6, int z dV = (1 + h/2 + h^2/9) / 2
    V = 1 + h / 4
    np.testing.assert_allclose(vol, [V], rtol=1e-14)
    expected = np.array([(0.5 + h / 6) / V, (0.5 + h / 6) / V, 0.5 * (1 + h / 2 + h**2 / 9) / V])
    np.testing.assert_allclose(cen[0], expected, rtol=1e-14)
    # the node average (0.5, 0.5, 0.5 + h/8) is not the centroid
    assert abs(cen[0, 2] - (0.5 + h / 8)) > 1e-3


def test_random_warped_hexahedra_match_trilinear_quadrature() -> None:
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = UNIT_CUBE + 0.15 * rng.standard_normal((8, 3))
        vol, cen = cell_measures(x, [list(range(8))], "hexahedron")
        v_ref, c_ref = _trilinear_gauss(x)  # independent exact quadrature (above)
        np.testing.assert_allclose(vol, [v_ref], rtol=1e-13)
        np.testing.assert_allclose(cen[0], c_ref, rtol=1e-13)


def test_wedge_right_prism_and_affine_image() -> None:
    # meshio/gmsh wedge order: triangle (0, 1, 2) counterclockwise seen from (3, 4, 5)
    ref = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]], dtype=float)
    vol, cen = cell_measures(ref, [list(range(6))], "wedge")
    # hand computation: triangle area 1/2 times height 1; centroid (1/3, 1/3, 1/2)
    np.testing.assert_allclose(vol, [0.5], rtol=1e-15)
    np.testing.assert_allclose(cen, [[1 / 3, 1 / 3, 0.5]], rtol=1e-15)
    A = np.array([[1.0, 0.2, 0.3], [0.1, 2.0, 0.0], [0.0, 0.4, 1.5]])
    vol, cen = cell_measures(ref @ A.T, [list(range(6))], "wedge")
    # affine image: volume det(A)/2, centroid A (1/3, 1/3, 1/2)
    np.testing.assert_allclose(vol, [0.5 * np.linalg.det(A)], rtol=1e-14)
    np.testing.assert_allclose(cen, [A @ [1 / 3, 1 / 3, 0.5]], rtol=1e-14)


def test_wedge_with_warped_quad_face() -> None:
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]], dtype=float)
    x[4, 2] += 0.5  # node (1, 0, 1) raised: faces (0,1,4,3) and (1,2,5,4) warp
    vol, cen = cell_measures(x, [list(range(6))], "wedge")
    # derived: isoparametric map (r, s, w) -> (r, s, w (1 + 0.5 r)) over the unit
    # triangle x [0, 1]: det J = 1 + r/2, V = 1/2 + 1/12 = 7/12,
    # int x dV = 1/6 + 1/24, int y dV = 1/6 + 1/48, int z dV = (1/2 + 1/6 + 1/48) / 2
    # (triangle moments: int 1 = 1/2, int r = 1/6, int r^2 = 1/12, int r s = 1/24)
    V = 7 / 12
    np.testing.assert_allclose(vol, [V], rtol=1e-14)
    expected = np.array([5 / 24, 9 / 48, (1 / 2 + 1 / 6 + 1 / 48) / 2]) / V
    np.testing.assert_allclose(cen[0], expected, rtol=1e-14)


def test_pyramid() -> None:
    x = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 3]], dtype=float)
    vol, cen = cell_measures(x, [list(range(5))], "pyramid")
    # hand computation: base 4 x height 3 / 3 = 4; centroid at a quarter of the height
    np.testing.assert_allclose(vol, [4.0], rtol=1e-15)
    np.testing.assert_allclose(cen, [[1.0, 1.0, 0.75]], rtol=1e-15)


def test_quadratic_cells_use_corner_nodes() -> None:
    pts = np.array(
        [[0, 0], [2, 0], [0, 2], [1, 0.3], [1, 1.2], [0.1, 1]], dtype=float
    )  # curved midside nodes are ignored
    area, cen = cell_measures(pts, [[0, 1, 2, 3, 4, 5]], "triangle6")
    # straight-sided triangle (0,0),(2,0),(0,2): area 2, centroid (2/3, 2/3)
    np.testing.assert_allclose(area, [2.0], rtol=1e-15)
    np.testing.assert_allclose(cen, [[2 / 3, 2 / 3]], rtol=1e-15)
    tet = np.vstack([np.eye(3), [[0, 0, 0]], np.full((6, 3), 0.3)])
    vol, _ = cell_measures(tet, [[3, 0, 1, 2, 4, 5, 6, 7, 8, 9]], "tetra10")
    # corner tetra (0,0,0), e1, e2, e3: 1/6
    np.testing.assert_allclose(vol, [1 / 6], rtol=1e-15)


def test_mixed_2d_mesh_and_boundary_rules() -> None:
    # unit square: quad [0,1/2]x[0,1] + two triangles on [1/2,1]x[0,1]; bottom line tagged
    pts = np.array([[0, 0], [0.5, 0], [1, 0], [0, 1], [0.5, 1], [1, 1]], dtype=float)
    mesh = meshio.Mesh(
        pts,
        [
            ("quad", [[0, 1, 4, 3]]),
            ("triangle", [[1, 2, 5], [1, 5, 4]]),
            ("line", [[0, 1], [1, 2]]),
        ],
        cell_sets={"bottom-right": [[], [], [1]], "quad": [[0], [], []]},
    )
    cloud = read_mesh(mesh)
    # hand computation: areas 1/2, 1/4, 1/4 (sum = 1, the square)
    np.testing.assert_allclose(cloud.volumes, [0.5, 0.25, 0.25], rtol=1e-15)
    np.testing.assert_allclose(
        cloud.points, [[0.25, 0.5], [5 / 6, 1 / 3], [2 / 3, 2 / 3]], rtol=1e-15
    )
    # facet rule: only the triangle holding both nodes of line (1, 2)
    assert cloud.sets["bottom-right"].tolist() == [1]
    assert cloud.sets["quad"].tolist() == [0]
    # node rule: every cell touching node 1 or 2 (all three)
    assert read_mesh(mesh, boundary="node").sets["bottom-right"].tolist() == [0, 1, 2]


def _mixed_3d_mesh() -> meshio.Mesh:
    """Hex [0,1]^3, wedge over triangle (1,0),(2,0),(1,1) x [0,1], tetra on top of the hex."""
    pts = np.array(
        [
            [0, 0, 0],
            [1, 0, 0],
            [1, 1, 0],
            [0, 1, 0],
            [0, 0, 1],
            [1, 0, 1],
            [1, 1, 1],
            [0, 1, 1],
            [2, 0, 0],
            [2, 0, 1],
            [0, 0, 2],
        ],
        dtype=float,
    )
    return meshio.Mesh(
        pts,
        [
            ("hexahedron", [[0, 1, 2, 3, 4, 5, 6, 7]]),
            ("wedge", [[1, 8, 2, 5, 9, 6]]),
            ("tetra", [[4, 5, 7, 10]]),
            ("quad", [[0, 3, 7, 4], [1, 2, 6, 5]]),  # faces x = 0 and x = 1
            ("triangle", [[8, 2, 6]]),  # unnamed group 4: nodes of the wedge (not a face)
        ],
        cell_data={
            "gmsh:physical": [[1], [1], [1], [2, 3], [4]],
            "gmsh:geometrical": [[1], [1], [1], [2, 3], [4]],
        },
        field_data={
            "solid": np.array([1, 3]),
            "x0": np.array([2, 2]),
            "x1": np.array([3, 2]),
        },
    )


def test_mixed_3d_mesh_and_boundary_faces(tmp_path: Path) -> None:
    mesh = _mixed_3d_mesh()
    cloud = read_mesh(mesh)
    assert cloud.dim == 3
    # hand computation: cube 1, right prism (1/2 x 1) = 1/2, tetra with legs 1, 1, 1 = 1/6
    np.testing.assert_allclose(cloud.volumes, [1.0, 0.5, 1 / 6], rtol=1e-15)
    np.testing.assert_allclose(
        cloud.points, [[0.5, 0.5, 0.5], [4 / 3, 1 / 3, 0.5], [0.25, 0.25, 1.25]], rtol=1e-15
    )
    assert cloud.sets["solid"].tolist() == [0, 1, 2]
    # facet rule: the x = 0 face belongs to the hex only, the x = 1 face to hex and wedge
    assert cloud.sets["x0"].tolist() == [0]
    assert cloud.sets["x1"].tolist() == [0, 1]
    assert cloud.sets["physical4_dim2"].tolist() == [1]  # all three nodes are wedge nodes
    # node rule: the tetra touches the x = 0 face at nodes 4 and 7
    assert read_mesh(mesh, boundary="node").sets["x0"].tolist() == [0, 2]
    # the same through a gmsh 2.2 file
    path = tmp_path / "mixed.msh"
    meshio.write(path, mesh, file_format="gmsh22", binary=False)
    back = read_mesh(path)
    np.testing.assert_allclose(back.volumes, cloud.volumes, rtol=1e-15)
    assert {k: v.tolist() for k, v in back.sets.items()} == {
        k: v.tolist() for k, v in cloud.sets.items()
    }


def test_dim_option_selects_lower_dimensional_cells() -> None:
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0], [0.0, 1.0]])
    mesh = meshio.Mesh(pts, [("triangle", [[0, 1, 3]]), ("line", [[0, 1], [1, 2]])])
    assert read_mesh(mesh).dim == 2
    line_cloud = read_mesh(mesh, dim=1, horizon_ratio=2.0)
    # hand computation: segments [0,1] and [1,3] on the x axis
    np.testing.assert_allclose(line_cloud.points[:, 0], [0.5, 2.0])
    np.testing.assert_allclose(line_cloud.volumes, [1.0, 2.0])
    np.testing.assert_allclose(line_cloud.horizon, [2.0, 4.0])  # 2 * length
    with pytest.raises(InputError, match="dim=3"):
        read_mesh(mesh, dim=3)


def test_horizon_ratio_and_material_and_unnamed_physical_groups() -> None:
    pts = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0], [3.0, 0.0]])
    mesh = meshio.Mesh(
        pts,
        [("quad", [[0, 1, 2, 3]]), ("triangle", [[1, 4, 2]]), ("line", [[0, 3]])],
        cell_data={"gmsh:physical": [[7], [8], [3]]},
        field_data={"steel": np.array([7, 2])},
    )
    cloud = read_mesh(mesh, horizon_ratio=3.01, material="gmsh:physical")
    # delta_i = 3.01 sqrt(A_i): areas 4 and 1 (hand computation)
    np.testing.assert_allclose(cloud.horizon, [3.01 * 2.0, 3.01 * 1.0], rtol=1e-15)
    assert cloud.material.tolist() == [7, 8]
    assert cloud.sets["steel"].tolist() == [0]  # named by field_data [tag 7, dim 2]
    assert cloud.sets["physical8"].tolist() == [1]  # unnamed surface group
    assert cloud.sets["physical3_dim1"].tolist() == [0]  # unnamed line group -> adjacent quad
    with pytest.raises(InputError, match="horizon_ratio"):
        read_mesh(mesh, horizon_ratio=-1.0)
    with pytest.raises(InputError, match="'nope' not found"):
        read_mesh(mesh, material="nope")


# --------------------------------------------------------------------------- validation


def test_missing_file_names_path(tmp_path: Path) -> None:
    path = tmp_path / "missing.msh"
    with pytest.raises(InputError, match="missing.msh"):
        read_mesh(path)


def test_unreadable_file_raises_instead_of_exiting(tmp_path: Path) -> None:
    path = tmp_path / "garbage.msh"
    path.write_text("not a mesh\n")
    with pytest.raises(InputError, match="garbage.msh"):
        read_mesh(path)
    with pytest.raises(InputTypeError, match="meshio.Mesh"):
        read_mesh(42)


def test_degenerate_cell_names_index() -> None:
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [2.0, 0.0], [3.0, 0.0]])
    # cell 2 (triangle block 1, row 1) is collinear -> zero area
    mesh = meshio.Mesh(pts, [("triangle", [[0, 1, 2]]), ("triangle", [[1, 3, 2], [1, 3, 4]])])
    with pytest.raises(InputError, match=r"mesh cell 2 \(triangle block 1, row 1\)"):
        read_mesh(mesh)


def test_node_index_out_of_range() -> None:
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    mesh = meshio.Mesh(pts, [("triangle", [[0, 1, 3]])])  # node 3 does not exist
    with pytest.raises(InputError, match=r"cell block 0 \(triangle\).*got range \[0, 3\]"):
        read_mesh(mesh)


def test_bow_tie_quad_rejected() -> None:
    pts = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 1.0], [1.0, 3.0], [0.0, -2.0]])
    # cell 2 = (0,0),(3,0),(0,1),(1,3): edges 1-2 and 3-0 cross at (0.3, 0.9);
    # its shoelace area is 1 (not zero), so only the bow-tie test catches it
    mesh = meshio.Mesh(pts, [("triangle", [[0, 4, 1]]), ("quad", [[0, 1, 3, 2], [0, 1, 2, 3]])])
    with pytest.raises(InputError, match="cell 2 .*bow-tie"):
        read_mesh(mesh)


def test_unsupported_cell_type_named() -> None:
    pts = np.random.default_rng(0).random((10, 2))
    mesh = meshio.Mesh(pts, [("triangle10", [list(range(10))])])
    with pytest.raises(InputError, match="unsupported cell type 'triangle10'"):
        read_mesh(mesh)
    with pytest.raises(InputError, match="cell_type must be one of"):
        cell_measures(pts, [[0, 1, 2]], "hexahedron64")


def test_inverted_cells_warn_and_use_absolute_measure(caplog: pytest.LogCaptureFixture) -> None:
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    mesh = meshio.Mesh(pts, [("quad", [[0, 3, 2, 1]])])  # clockwise
    with caplog.at_level(logging.WARNING, logger="pdlin.geometry.mesh"):
        cloud = read_mesh(mesh)
    assert cloud.volumes.tolist() == [1.0]
    assert "1 inverted" in caplog.text and "cell 0" in caplog.text


def test_non_planar_2d_mesh_rejected() -> None:
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]])
    with pytest.raises(InputError, match="constant z"):
        read_mesh(meshio.Mesh(pts, [("triangle", [[0, 1, 2]])]))


# --------------------------------------------------------------------------- O-grid plate


def test_ogrid_total_area_is_square_minus_inscribed_polygon(
    caplog: pytest.LogCaptureFixture,
) -> None:
    n_ang = 8
    with caplog.at_level(logging.WARNING, logger="pdlin.geometry.mesh"):
        cloud = read_mesh(plate_with_hole_mesh(n_ang, 10))
    assert "inverted" not in caplog.text  # the generator orients quads counterclockwise
    n = 4 * n_ang
    # the hole is the regular n-gon inscribed in r = 0.1: area (n/2) r^2 sin(2 pi / n)
    exact = 1.0 - 0.5 * n * 0.1**2 * np.sin(2 * np.pi / n)
    np.testing.assert_allclose(cloud.volumes.sum(), exact, rtol=1e-13)
    assert cloud.volumes.sum() > 1.0 - np.pi * 0.01  # polygon hole is smaller than the disk


def test_ogrid_sets_sit_on_their_edges() -> None:
    cloud = read_mesh(plate_with_hole_mesh(8, 10))
    # 4 blocks x 8 angular cells, one ring of 32 cells around the hole
    assert {k: v.size for k, v in cloud.sets.items()} == {
        "hole": 32,
        "right": 8,
        "top": 8,
        "left": 8,
        "bottom": 8,
        "plate": 320,
    }
    x, y = cloud.points.T
    assert np.all(x[cloud.sets["right"]] > 0.45) and np.all(x[cloud.sets["left"]] < -0.45)
    assert np.all(y[cloud.sets["top"]] > 0.45) and np.all(y[cloud.sets["bottom"]] < -0.45)
    # the hole ring is the 32 cells closest to the centre
    np.testing.assert_array_equal(np.sort(np.argsort(np.hypot(x, y))[:32]), cloud.sets["hole"])
    # node rule adds the two corner cells of the neighbouring blocks to each edge
    node = read_mesh(plate_with_hole_mesh(8, 10), boundary="node")
    assert node.sets["left"].size == 10 and node.sets["hole"].size == 32


def test_ogrid_spec_geometry() -> None:
    mesh = plate_with_hole_mesh()  # 4 x 32 x 60
    cloud = read_mesh(mesh, horizon_ratio=3.01)
    assert cloud.n == 7680  # Liu, Chen & Skelton, XOSB, Sec. 5.1: 7,680 particles
    sa = np.sqrt(cloud.volumes)
    # conventions.md#plate-with-a-hole O-grid: sqrt(A) in [0.0039, 0.0245] m, delta in [0.0119,
    # 0.0738] m
    assert (round(sa.min(), 4), round(sa.max(), 4)) == (0.0039, 0.0245)
    assert (round(cloud.horizon.min(), 4), round(cloud.horizon.max(), 4)) == (0.0119, 0.0738)
    bonds = pdlin.find_bonds(cloud, horizon=cloud.horizon)
    fs = bonds.family_size
    # reference values: family sizes 12-34, mean 30.1 (symmetric family rule)
    assert (fs.min(), fs.max(), round(fs.mean(), 1)) == (12, 34, 30.1)


@pytest.mark.parametrize(
    ("suffix", "options"),
    [
        (".vtu", {}),
        (".msh", {"file_format": "gmsh22", "binary": False}),
        (".msh", {"file_format": "gmsh22", "binary": True}),
    ],
)
def test_file_round_trip_preserves_sets(tmp_path: Path, suffix: str, options: dict) -> None:
    ref = read_mesh(plate_with_hole_mesh(8, 6))
    path = tmp_path / f"plate{suffix}"
    meshio.write(path, plate_with_hole_mesh(8, 6), **options)
    cloud = read_mesh(path)
    np.testing.assert_allclose(cloud.points, ref.points, rtol=0, atol=1e-15)
    np.testing.assert_allclose(cloud.volumes, ref.volumes, rtol=1e-14)
    for name in ("hole", "right", "top", "left", "bottom"):
        np.testing.assert_array_equal(cloud.sets[name], ref.sets[name])


def test_generator_argument_errors() -> None:
    with pytest.raises(InputError, match="radius must be < length / 2"):
        plate_with_hole_mesh(radius=0.6)
    with pytest.raises(InputError, match="n_ang must be a positive integer"):
        plate_with_hole_mesh(0)
    with pytest.raises(InputError, match="backend must be"):
        plate_with_hole_mesh(backend="triangle")


def test_gmsh_backend_is_optional(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "gmsh", None)  # import gmsh raises ImportError
    with pytest.raises(ImportError, match=r"pdlin\[meshing\]"):
        plate_with_hole_mesh(backend="gmsh")


def test_gmsh_backend_triangles() -> None:
    pytest.importorskip("gmsh")
    cloud = read_mesh(plate_with_hole_mesh(backend="gmsh", mesh_size=0.05))
    # the area of the plate minus the (polygonal) hole stays within 1% of 1 - pi r^2
    assert abs(cloud.volumes.sum() - (1 - np.pi * 0.01)) < 0.01
    for name in ("hole", "right", "top", "left", "bottom"):
        assert cloud.sets[name].size > 0


# --------------------------------------------------------------------------- example


def _load_example():
    path = EXAMPLES / "plate_with_hole.py"
    spec = importlib.util.spec_from_file_location("plate_with_hole", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_example_plate_with_hole_runs(capsys: pytest.CaptureFixture) -> None:
    summary = _load_example().main(["--n-ang", "8", "--n-rad", "15"])
    out = capsys.readouterr().out
    assert "hole edge" in out
    assert summary["points"] == 480  # 4 x 8 x 15
    # u_x = u0 = 5e-4 m is prescribed on the right edge layer (the maximum)
    np.testing.assert_allclose(summary["max_abs_u"][0], 5e-4, rtol=1e-12)
    b0, b90 = summary["hole_beta_0"], summary["hole_beta_90"]
    # Q4 FE reference (conventions.md#plate-with-a-hole): u_x = 3.9e-4 (beta 0) > 2.5e-4 (beta
    # 90) > 0, u_y(90) < 0
    assert 0 < b90["u_x"] < b0["u_x"] < 5e-4
    assert b90["u_y"] < 0


@pytest.mark.slow
def test_example_plate_with_hole_full_size_matches_fem_u_x() -> None:
    summary = _load_example().main([])
    # reference ring values (beta = 1.4 deg): FEM u_x = 3.9021e-4 m; bond-based (nu = 1/3 instead of
    # 0.33, pinned u_y) stays within 2 %
    assert summary["hole_beta_0"]["beta_deg"] == pytest.approx(1.4, abs=0.01)
    assert summary["hole_beta_0"]["u_x"] == pytest.approx(3.9021e-4, rel=0.02)
