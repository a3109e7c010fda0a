"""Peridigm's PdQuickGrid ``TensorProductCylinderMeshGenerator``.

No deck of Peridigm's test folders uses the cylinder generator (commit 82c6ad8: only a
QuickGrid unit test), so the points and volumes are checked against QuickGrid's formulas
re-derived here cell by cell (``src/io/mesh_input/quick_grid/QuickGrid.cxx``,
``Peridigm_PdQuickGridDiscretization.cpp``), and the cell window against the neighbour
lists of Peridigm's own unit test ``quick_grid/unit_test/ut_SmallMeshCylinder.cxx``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import pdlin
from pdlin.errors import SceneError
from pdlin.models.thermal import ThermalExpansion
from pdlin.scene.decks.peridigm import _cylinder_window, quickgrid_cylinder

DECK = """<ParameterList>
  <ParameterList name="Discretization">
    <Parameter name="Type" type="string" value="PdQuickGrid"/>
    <Parameter name="NeighborhoodType" type="string" value="Spherical"/>
    <ParameterList name="TensorProductCylinderMeshGenerator">
      <Parameter name="Type" type="string" value="PdQuickGrid"/>
      <Parameter name="Inner Radius" type="double" value="{ri}"/>
      <Parameter name="Outer Radius" type="double" value="{ro}"/>
      <Parameter name="Cylinder Length" type="double" value="{L}"/>
      <Parameter name="Number Points Radius" type="int" value="{nr}"/>
      <Parameter name="Ring Center x" type="double" value="0.0"/>
      <Parameter name="Ring Center y" type="double" value="0.0"/>
      <Parameter name="Z Origin" type="double" value="{z0}"/>
    </ParameterList>
  </ParameterList>
  <ParameterList name="Materials">
    <ParameterList name="M">
      <Parameter name="Material Model" type="string" value="Elastic"/>
      <Parameter name="Density" type="double" value="7800.0"/>
      <Parameter name="Bulk Modulus" type="double" value="130.0e9"/>
      <Parameter name="Shear Modulus" type="double" value="78.0e9"/>
    </ParameterList>
  </ParameterList>
  <ParameterList name="Blocks">
    <ParameterList name="B">
      <Parameter name="Block Names" type="string" value="block_1"/>
      <Parameter name="Material" type="string" value="M"/>
      <Parameter name="Horizon" type="double" value="{h}"/>
    </ParameterList>
  </ParameterList>
  <ParameterList name="Solver">
    <Parameter name="Final Time" type="double" value="1.0"/>
    <ParameterList name="QuasiStatic">
      <Parameter name="Number of Load Steps" type="int" value="1"/>
    </ParameterList>
  </ParameterList>
</ParameterList>
"""


def _centres(n: int, x0: float, length: float) -> list[float]:
    """QuickGrid's ``getDiscretization(Spec1D)``: ``p = x0 + h/2``, then ``p += h``."""
    h = length / n
    out, p = [], x0 + h / 2.0
    for _ in range(n):
        out.append(p)
        p += h
    return out


def _peridigm_cells(ri: float, ro: float, nr: int, length: float, z0: float):
    """Points and volumes cell by cell, as ``TensorProductCylinderMeshGenerator`` loops."""
    dr = (ro - ri) / nr
    n_rays = int(2 * math.pi / (dr / ((ri + ro) / 2))) + 1  # SpecRing2D
    n_axis = int(length / (abs(ro - ri) / nr)) + 1  # PdQuickGridDiscretization
    r = _centres(nr, ri, abs(ro - ri))
    theta = _centres(n_rays, 0.0, 2 * math.pi)
    z = _centres(n_axis, z0, length)
    cell_rads, dz = 2 * math.pi / n_rays, length / n_axis
    pts, vol = [], []
    for k in range(n_axis):
        for j in range(n_rays):
            c, s = math.cos(theta[j]), math.sin(theta[j])
            for i in range(nr):
                pts.append((r[i] * c, r[i] * s, z[k]))  # global id i + j nr + k nr n_rays
                vol.append(r[i] * dr * cell_rads * dz)
    return np.array(pts), np.array(vol), n_rays, n_axis


@pytest.mark.parametrize(
    ("ri", "ro", "nr", "L", "z0"),
    [(16.0, 17.0, 4, 1.0, 0.0), (1.0, 2.0, 3, 2.5, -1.25), (0.0, 1.0, 4, 0.5, 2.0)],
)
def test_points_and_volumes_are_quickgrids(ri, ro, nr, L, z0, tmp_path):
    pts, vol, n_rays, n_axis = _peridigm_cells(ri, ro, nr, L, z0)
    cyl = quickgrid_cylinder(ri, ro, nr, L, z0)
    assert (cyl["n_rays"], cyl["n_axis"]) == (n_rays, n_axis)
    # the same arithmetic, bit for bit (measured: numpy's cos / sin equal libm's here)
    assert np.array_equal(cyl["points"], pts)
    assert np.array_equal(cyl["volumes"], vol)
    # the cells tile the tube: volume π (ro² - ri²) L (closed form)
    assert np.isclose(vol.sum(), math.pi * (ro**2 - ri**2) * L, rtol=1e-12)
    (tmp_path / "c.xml").write_text(DECK.format(ri=ri, ro=ro, L=L, nr=nr, z0=z0, h=0.6 * (ro - ri)))
    scene = pdlin.read_deck(tmp_path / "c.xml")
    assert np.array_equal(scene.cloud.points, cyl["points"])
    assert np.array_equal(scene.cloud.volumes, cyl["volumes"])


# ut_SmallMeshCylinder.cxx, cylindericalCellPerProcIterator1ProcTest: neighbour lists of the
# 32 cells (NoOpNorm: the cell window only), copied from Peridigm's unit test
_UT_NEIGHBOURS = [
    [12, 13, 14, 15, 1, 2, 3, 4, 5, 28, 29, 30, 31, 16, 17, 18, 19, 20, 21],
    [12, 13, 14, 15, 0, 2, 3, 4, 5, 28, 29, 30, 31, 16, 17, 18, 19, 20, 21],
    [14, 15, 0, 1, 3, 4, 5, 6, 7, 30, 31, 16, 17, 18, 19, 20, 21, 22, 23],
    [14, 15, 0, 1, 2, 4, 5, 6, 7, 30, 31, 16, 17, 18, 19, 20, 21, 22, 23],
    [0, 1, 2, 3, 5, 6, 7, 8, 9, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25],
    [0, 1, 2, 3, 4, 6, 7, 8, 9, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25],
    [2, 3, 4, 5, 7, 8, 9, 10, 11, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27],
    [2, 3, 4, 5, 6, 8, 9, 10, 11, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27],
    [4, 5, 6, 7, 9, 10, 11, 12, 13, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29],
    [4, 5, 6, 7, 8, 10, 11, 12, 13, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29],
    [6, 7, 8, 9, 11, 12, 13, 14, 15, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31],
    [6, 7, 8, 9, 10, 12, 13, 14, 15, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31],
    [8, 9, 10, 11, 13, 14, 15, 0, 1, 24, 25, 26, 27, 28, 29, 30, 31, 16, 17],
    [8, 9, 10, 11, 12, 14, 15, 0, 1, 24, 25, 26, 27, 28, 29, 30, 31, 16, 17],
    [10, 11, 12, 13, 15, 0, 1, 2, 3, 26, 27, 28, 29, 30, 31, 16, 17, 18, 19],
    [10, 11, 12, 13, 14, 0, 1, 2, 3, 26, 27, 28, 29, 30, 31, 16, 17, 18, 19],
    [12, 13, 14, 15, 0, 1, 2, 3, 4, 5, 28, 29, 30, 31, 17, 18, 19, 20, 21],
    [12, 13, 14, 15, 0, 1, 2, 3, 4, 5, 28, 29, 30, 31, 16, 18, 19, 20, 21],
    [14, 15, 0, 1, 2, 3, 4, 5, 6, 7, 30, 31, 16, 17, 19, 20, 21, 22, 23],
    [14, 15, 0, 1, 2, 3, 4, 5, 6, 7, 30, 31, 16, 17, 18, 20, 21, 22, 23],
    [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 16, 17, 18, 19, 21, 22, 23, 24, 25],
    [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 16, 17, 18, 19, 20, 22, 23, 24, 25],
    [2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 18, 19, 20, 21, 23, 24, 25, 26, 27],
    [2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 18, 19, 20, 21, 22, 24, 25, 26, 27],
    [4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 20, 21, 22, 23, 25, 26, 27, 28, 29],
    [4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 20, 21, 22, 23, 24, 26, 27, 28, 29],
    [6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 22, 23, 24, 25, 27, 28, 29, 30, 31],
    [6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 22, 23, 24, 25, 26, 28, 29, 30, 31],
    [8, 9, 10, 11, 12, 13, 14, 15, 0, 1, 24, 25, 26, 27, 29, 30, 31, 16, 17],
    [8, 9, 10, 11, 12, 13, 14, 15, 0, 1, 24, 25, 26, 27, 28, 30, 31, 16, 17],
    [10, 11, 12, 13, 14, 15, 0, 1, 2, 3, 26, 27, 28, 29, 31, 16, 17, 18, 19],
    [10, 11, 12, 13, 14, 15, 0, 1, 2, 3, 26, 27, 28, 29, 30, 16, 17, 18, 19],
]


def test_cell_window_is_peridigms_unit_test():
    ring = 2.0  # the unit test's ring thickness, inner radius, 2 rings, 2 axial cells
    ri = ring * (7 / (2.0 * math.pi) - 1) * 0.5
    cyl = quickgrid_cylinder(ri, ri + ring, 2, 2.0, 0.0, n_axis=2)
    assert cyl["points"].shape[0] == 32 and cyl["n_rays"] == 8  # the unit test's 16 ring cells
    cloud = pdlin.PointCloud(cyl["points"], cyl["volumes"])
    window = _cylinder_window(cyl, 1.51 * 1.0, "test", sphere=False)  # SCALE * cellSize
    bonds = pdlin.find_bonds(cloud, 100.0, exclude=window)
    got = [sorted(bonds.j[bonds.i == p].tolist()) for p in range(32)]
    assert got == [sorted(v) for v in _UT_NEIGHBOURS]


def test_spherical_bonds_and_thermal_expansion_on_the_cylinder(tmp_path):
    ri, ro, nr, L = 1.0, 2.0, 3, 1.0
    h = 1.01 * (ro - ri) / nr * 3  # three ring thicknesses
    (tmp_path / "c.xml").write_text(DECK.format(ri=ri, ro=ro, L=L, nr=nr, z0=0.0, h=h))
    scene = pdlin.read_deck(tmp_path / "c.xml")
    bonds = scene.problem.get_bonds()
    sphere = pdlin.find_bonds(scene.cloud, h)
    # the window keeps only pairs of the ball, and at the inner rings it cuts some of them
    # (its ring reach is set at the mean radius); the pairs kept are symmetric
    kept = set(zip(bonds.i.tolist(), bonds.j.tolist(), strict=True))
    ball = set(zip(sphere.i.tolist(), sphere.j.tolist(), strict=True))
    assert kept < ball and kept == {(j, i) for i, j in kept}
    x = scene.cloud.points
    r = np.hypot(x[:, 0], x[:, 1])
    cut = np.bincount(sphere.i, minlength=scene.cloud.n) - bonds.family_size
    assert cut[r < 1.2].sum() > 0 and cut[r > 1.8].sum() == 0
    # a free heated tube expands by α ΔT x on Peridigm's bonds (closed form)
    eps = 1e-5 * 100.0
    pins = []
    for p in (0, int(np.argmax(x[:, 0])), int(np.argmax(x[:, 1]))):
        pins.append(pdlin.Dirichlet([p], eps * x[p]))
    prob = pdlin.StaticProblem(
        scene.model, scene.cloud, bonds=bonds, dirichlet=pins,
        thermal=ThermalExpansion(100.0, 1e-5),
    )  # fmt: skip
    res = pdlin.solve(prob, solver="direct")
    assert np.abs(res.u - eps * x).max() < 1e-9 * eps * ro


def test_cylinder_keys_are_checked(tmp_path):
    text = DECK.format(ri=1.0, ro=2.0, L=1.0, nr=3, z0=0.0, h=0.5)
    (tmp_path / "a.xml").write_text(text.replace('name="Z Origin"', 'name="Z Start"'))
    with pytest.raises(SceneError, match=r"TensorProductCylinderMeshGenerator.*Z Start"):
        pdlin.read_deck(tmp_path / "a.xml")
    (tmp_path / "b.xml").write_text(text.replace('value="2.0"/>', 'value="0.5"/>', 1))
    with pytest.raises(SceneError, match=r"Inner Radius < Outer Radius"):
        pdlin.read_deck(tmp_path / "b.xml")
    big = DECK.format(ri=1.0, ro=2.0, L=1.0, nr=3, z0=0.0, h=5.0)
    (tmp_path / "c.xml").write_text(big)
    with pytest.raises(SceneError, match="rays"):
        pdlin.read_deck(tmp_path / "c.xml").problem.get_bonds()
