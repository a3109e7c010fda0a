"""Liu, Chen & Skelton, XOSB, Sec. 5.2: 3D block with a hole (the Sec. 5.1 plate extruded 0.3 m),
XOSBPD vs OSBPD vs Hex8.

Setup (pdlin's reconstruction, docs/theory/conventions.md#block-with-a-hole; a small CI size):
the O-grid 4 x 8 x 15 extruded into 8 layers of hexahedra
(``pdlin.plate_with_hole_mesh(8, 15, layers=8, depth=0.3)``, 3,840 cells = 3,840 particles),
δ_i = 3.01 V_i^(1/3), E = 70 GPa, ν = 0.33, u0 = 5e-4 m, z faces free.  PD boundary condition
"B" as in the 2D test (conventions.md#plate-with-a-hole): the FE displacement (all three
components) prescribed on the outermost radial layer of the left and right blocks, through
the whole thickness (128 particles).  Ring metric as in 2D: max over the hole ring
(first radial layer) of the two mid-thickness layers (z = 0.131 and 0.169 m, 64 particles)
of |u_PD - u_FE| / range_ring(u_FE), per component.

FE reference: Hex8 (:func:`pdlin.verification.fem.solve_hex8`, AMG-CG to 1e-12) on the
O-grid refined 2x in-plane (4 x 16 x 30, 8 layers, 17,856 nodes): u_x = 0 / u0 on
x = -0.5 / 0.5, u_y = 0 on the lines (±0.5, 0, z) and u_z = 0 at (±0.5, 0, 0.15), which
the problem's symmetry satisfies anyway.  FE values at the PD centroids come from the FE
interpolant itself (:func:`pdlin.verification.fem.evaluate_q4` on the node layers; the
PD centroids lie on FE node layers), not from a 3D Delaunay interpolation (``scipy``'s
``LinearNDInterpolator`` took minutes on the 3D node cloud).  FE convergence, measured
2026-11-21 against the 3x in-plane mesh (39,744 nodes), in % of the ring ranges
(u_x / u_y / u_z): 1x 0.92 / 2.06 / 0.97, 2x 0.12 / 0.33 / 0.07, 2x in-plane and 2x
through the thickness 0.11 / 0.31 / 0.13: the FE error is far below the PD errors.

No reference values exist (the paper prints none): the bounds are calibrated on the values measured
2026-11-21.  The paper's claim "OSBPD has significant errors, especially u_y, u_z" holds at this
size for the paper linearization (OSBPD errors 2.2x / 1.9x / 2.4x XOSBPD's in u_x / u_y / u_z).  For
pdlin's default energy-consistent XOSB it holds for u_x and u_y (2.4x, 5.6x) but not for u_z, where
XOSB (6.8%) and OSBPD (7.1%) are about equal, so u_z is only bounded for that variant.  In absolute
terms XOSBPD's u_y ring error at this coarse size (24% paper, 8.3% energy) is much larger than in 2D
at 7,680 particles (2.2%).
"""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError
from pdlin.verification.fem import evaluate_q4, hex8_stiffness, solve_hex8

E, NU, U0 = 70e9, 0.33, 5e-4  # Liu, Chen & Skelton, XOSB, Secs. 5.1-5.2
DEPTH = 0.3  # extrusion, Liu, Chen & Skelton, XOSB, Sec. 5.2
N_ANG, N_RAD, LAYERS = 8, 15, 8  # CI substitute 4 x 8 x 15 x 8 layers (pdlin's choice)
FE_REFINE = 2  # in-plane refinement of the FE mesh


def _fe_reference(xq: np.ndarray) -> np.ndarray:
    """Hex8 solution of the block with a hole on the refined O-grid, evaluated at ``xq``."""
    na, nr = FE_REFINE * N_ANG, FE_REFINE * N_RAD
    mesh = pdlin.plate_with_hole_mesh(na, nr, layers=LAYERS, depth=DEPTH)
    pts = mesh.points
    x, y, z = pts.T
    tol = 1e-9
    left = np.flatnonzero(np.abs(x + 0.5) <= tol)
    right = np.flatnonzero(np.abs(x - 0.5) <= tol)
    mid_lines = np.flatnonzero((np.abs(np.abs(x) - 0.5) <= tol) & (np.abs(y) <= tol))
    mid_points = mid_lines[np.abs(z[mid_lines] - DEPTH / 2) <= tol]
    assert mid_points.size == 2
    fixed = np.concatenate([3 * left, 3 * right, 3 * mid_lines + 1, 3 * mid_points + 2])
    vals = np.concatenate(
        [np.zeros(left.size), np.full(right.size, U0), np.zeros(mid_lines.size + 2)]
    )
    u = solve_hex8(pts, mesh.cells_dict["hexahedron"], E, NU, fixed, vals, solver="amg")
    # the FE interpolant: bilinear in each node layer (2D O-grid), linear in z between layers
    plate = pdlin.plate_with_hole_mesh(na, nr)
    p2, q2 = plate.points, plate.cells_dict["quad"]
    n2 = p2.shape[0]
    zs = np.linspace(0.0, DEPTH, LAYERS + 1)
    kz = np.clip(np.searchsorted(zs, xq[:, 2]) - 1, 0, LAYERS - 1)
    out = np.empty((xq.shape[0], 3))
    for k in np.unique(kz):  # a handful of layers
        sel = np.flatnonzero(kz == k)
        t = ((xq[sel, 2] - zs[k]) / (zs[k + 1] - zs[k]))[:, None]
        lo = evaluate_q4(p2, q2, u[k * n2 : (k + 1) * n2], xq[sel, :2])
        hi = evaluate_q4(p2, q2, u[(k + 1) * n2 : (k + 2) * n2], xq[sel, :2])
        out[sel] = (1 - t) * lo + t * hi
    return out


def _ring_and_strips(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Ring particles of the two mid layers; outermost radial layer of the left/right blocks.

    Cells (= particles) are layer-major, and each layer is ring-major with the right, top,
    left, bottom blocks in turn (see :func:`pdlin.plate_with_hole_mesh`).
    """
    per_layer, n_ring = 4 * N_ANG * N_RAD, 4 * N_ANG
    layer, cell = np.divmod(np.arange(n), per_layer)
    ring = np.flatnonzero((cell < n_ring) & np.isin(layer, (LAYERS // 2 - 1, LAYERS // 2)))
    outer = cell - (N_RAD - 1) * n_ring
    strips = np.flatnonzero((outer >= 0) & np.isin(outer // N_ANG, (0, 2)))
    return ring, strips


@pytest.fixture(scope="module")
def block():
    cloud = pdlin.read_mesh(pdlin.plate_with_hole_mesh(N_ANG, N_RAD, layers=LAYERS, depth=DEPTH))
    # δ_i = 3.01 V_i^(1/3), Liu, Chen & Skelton, XOSB, Sec. 5
    bonds = pdlin.find_bonds(cloud, ratio=3.01)
    u_ref = _fe_reference(cloud.points)
    ring, strips = _ring_and_strips(cloud.n)
    return cloud, bonds, u_ref, ring, strips


def test_extruded_ogrid_is_a_valid_hex8_mesh():
    mesh = pdlin.plate_with_hole_mesh(N_ANG, N_RAD, layers=LAYERS, depth=DEPTH)
    hexes = mesh.cells_dict["hexahedron"]
    assert hexes.shape == (4 * N_ANG * N_RAD * LAYERS, 8)
    # right-handed meshio order: positive volume of every hexahedron's corner tetrahedron
    p = mesh.points[hexes]
    vol = np.einsum("ei,ei->e", np.cross(p[:, 1] - p[:, 0], p[:, 3] - p[:, 0]), p[:, 4] - p[:, 0])
    assert np.all(vol > 0)
    hex8_stiffness(mesh.points, hexes, E, NU)  # positive Jacobians at all Gauss points
    # the 'quad' block is exactly the boundary: the hexahedron faces owned by one cell
    local = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    faces = np.sort(hexes[:, local].reshape(-1, 4), axis=1)
    uniq, count = np.unique(faces, axis=0, return_counts=True)
    boundary = np.sort(mesh.cells_dict["quad"], axis=1)
    np.testing.assert_array_equal(np.unique(boundary, axis=0), uniq[count == 1])
    assert boundary.shape[0] == uniq[count == 1].shape[0]
    cloud = pdlin.read_mesh(mesh)
    # volume of the polygonal block: 0.3 (1 - area of the 32-gon inscribed in r = 0.1)
    polygon = 0.5 * 32 * 0.1**2 * np.sin(2 * np.pi / 32)
    assert cloud.volumes.sum() == pytest.approx(DEPTH * (1 - polygon), rel=1e-12)
    ring, strips = _ring_and_strips(cloud.n)
    radius = np.hypot(*cloud.points[:, :2].T)
    assert ring.size == 64 and strips.size == 128
    assert np.all(radius[ring] < radius.min() + 0.01)
    np.testing.assert_allclose(np.unique(cloud.points[ring, 2].round(12)), [0.13125, 0.16875])
    assert np.all(np.abs(cloud.points[strips, 0]) > 0.45)
    assert set(cloud.sets) >= {"hole", "right", "top", "left", "bottom", "back", "front"}


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"layers": 0, "depth": 0.3}, "layers must be a positive integer"),
        ({"layers": 2.5, "depth": 0.3}, "layers must be a positive integer"),
        ({"layers": 4}, "layers needs depth"),
        ({"depth": 0.3}, "depth needs layers"),
        ({"layers": 4, "depth": -1.0}, "depth must be > 0"),
        ({"layers": 4, "depth": 0.3, "backend": "gmsh"}, "layers needs backend='ogrid'"),
    ],
)
def test_extrusion_arguments_are_checked(kwargs, match):
    with pytest.raises(InputError, match=match):
        pdlin.plate_with_hole_mesh(4, 3, **kwargs)


@pytest.mark.slow
def test_block_with_hole_xosb_vs_osbpd_bc_b(block):
    cloud, bonds, u_ref, ring, strips = block
    assert np.all(np.isfinite(u_ref))
    rng_ring = np.ptp(u_ref[ring], axis=0)
    # FE ring ranges u_x / u_y / u_z, measured 2026-11-21: 2.7243e-4 / 9.1806e-5 / 9.3718e-6 m
    # (3x in-plane mesh: 2.7283e-4 / 9.2194e-5 / 9.3739e-6); regression bound 1%
    np.testing.assert_allclose(rng_ring, [2.7243e-4, 9.1806e-5, 9.3718e-6], rtol=1e-2)
    bc = [pdlin.Dirichlet(strips, u_ref[strips])]

    def ring_error(model, solver):
        res = pdlin.solve(
            pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc),
            solver=solver,
            rtol=1e-10,
        )
        # measured 2026-11-21: 20 (XO paper, GMRES), 24 (XO energy, CG), 24 (OS paper)
        assert res.n_iter <= 40  # the 2D bound of test_xosb_plate.py
        return np.abs(res.u[ring] - u_ref[ring]).max(axis=0) / rng_ring

    xo = ring_error(pdlin.XOSB(E, NU, linearization="paper"), "amg-gmres")
    xe = ring_error(pdlin.XOSB(E, NU), "amg-cg")
    os_ = ring_error(pdlin.LPS(E, NU, linearization="paper"), "amg-gmres")
    # ring max errors u_x / u_y / u_z, measured 2026-11-21 (calibrated bounds, ~+25%):
    # XOSBPD paper 3.01% / 24.41% / 2.97%; XOSBPD energy 2.79% / 8.34% / 6.84%;
    # OSBPD paper 6.71% / 46.29% / 7.14% (OSBPD energy, not asserted: 8.2% / 52.2% / 17.5%)
    assert np.all(xo <= [0.04, 0.31, 0.037])
    assert np.all(xe <= [0.034, 0.11, 0.085])
    # OSBPD "significant errors" (Liu, Chen & Skelton, XOSB, Sec. 5.2)
    assert np.all(os_ >= [0.05, 0.35, 0.055])
    # the paper's claim, paper linearization: OSBPD worse in every component, "especially u_y, u_z"
    # (Liu, Chen & Skelton, XOSB, Sec. 5.2); measured ratios 2.23 / 1.90 / 2.40
    assert np.all(os_ >= 1.5 * xo)
    # energy-consistent XOSB: much better than OSBPD in u_x and u_y (measured 2.4x / 5.6x);
    # in u_z the two are about equal (6.84% vs 7.14%), so no ratio is claimed there
    assert os_[0] >= 2.0 * xe[0] and os_[1] >= 4.0 * xe[1]
