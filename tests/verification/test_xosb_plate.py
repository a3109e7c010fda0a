"""Liu, Chen & Skelton, XOSB, Sec. 5.1: plate with a central hole, XOSBPD vs OSBPD vs a Q4 FE
reference.

Setup (docs/theory/conventions.md#plate-with-a-hole, reconstructed): square L = 1 m, hole r = 0.1 m,
plane stress, E = 70 GPa, ν = 0.33, u_x = 0 / u0 = 5e-4 m on the left / right edges; the PD mesh is
the 7,680-quad O-grid (4 x 32 x 60), δ_i = 3.01 √A_i.  PD boundary condition "B": the FE
displacement (both components) prescribed on the 64 particles of the outermost radial layer of the
left and right blocks.  Metric: max over the ring (first radial layer, 128 particles) of |u_PD -
u_FE| / range_ring(u_FE), per component.

FE reference: our own Q4 plane-stress solve (2 x 2 Gauss, vectorized assembly, spsolve) on the
O-grid 4 x 64 x 120, i.e. 2x coarser than the 4 x 128 x 240 reference mesh; the 2x coarser mesh
differs from that one by 1.05e-4 max|u| (independent reference computation).  It is checked against
the recorded FE hole-edge values of the 4 x 128 x 240 mesh before use.  FE values at the PD
centroids are interpolated linearly (Delaunay) from the FE nodes.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import LinearNDInterpolator

import pdlin
from pdlin.verification.fem import plate_extension_q4

E, NU, U0 = 70e9, 0.33, 5e-4  # Liu, Chen & Skelton, XOSB, Sec. 5.1


def _q4_plane_stress(points: np.ndarray, quads: np.ndarray, solver: str = "lu") -> np.ndarray:
    """Nodal displacements of the plate-with-a-hole FE problem (pdlin.verification.fem, vectorized
    Q4).

    ``solver='lu'``: SuperLU on the free DOFs; ``'amg'``: pdlin's AMG-CG to 1e-12 (for the
    fine 4 x 128 x 240 mesh).
    """
    return plate_extension_q4(points, quads, E, NU, U0, solver=solver)


@pytest.fixture(scope="module")
def fe():
    mesh = pdlin.plate_with_hole_mesh(64, 120)
    quads = next(c.data for c in mesh.cells if c.type == "quad")
    pts = np.asarray(mesh.points[:, :2], dtype=float)
    u = _q4_plane_stress(pts, quads)
    return pts, u


@pytest.fixture(scope="module")
def plate():
    cloud = pdlin.read_mesh(pdlin.plate_with_hole_mesh())  # 4 x 32 x 60 = 7,680 particles
    bonds = pdlin.find_bonds(cloud, ratio=3.01)
    return cloud, bonds


def _ring_and_strips(cloud: pdlin.PointCloud, n_ang: int = 32) -> tuple[np.ndarray, np.ndarray]:
    x, y = cloud.points.T
    rad = np.hypot(x, y)
    ring = np.argsort(rad)[: 4 * n_ang]  # first radial layer: 4 x 32 particles
    side = np.flatnonzero(np.abs(x) > np.abs(y))
    right = side[np.argsort(-x[side])[:n_ang]]  # outermost radial layer of the right block
    left = side[np.argsort(x[side])[:n_ang]]
    return ring, np.concatenate([left, right])


@pytest.mark.slow
def test_fe_reference_matches_spec_hole_edge_values(fe):
    pts, u = fe
    on_hole = np.isclose(np.hypot(*pts.T), 0.1)
    beta = np.degrees(np.arctan2(pts[:, 1], pts[:, 0])) % 360
    # FE on the hole edge r = 0.1 (β: u_x, u_y in m): Q4 reference on the 4 x 128 x 240 mesh (values
    # recorded from an independent implementation)
    table = {
        0: (3.9003e-4, 0.0),
        45: (3.4932e-4, -3.3438e-5),
        90: (2.5000e-4, -4.7804e-5),
        135: (1.5068e-4, -3.3438e-5),
        180: (1.0997e-4, 0.0),
    }
    scale = np.abs(u).max()
    for b, ref in table.items():
        k = np.flatnonzero(on_hole & np.isclose(beta, b, atol=1e-6))
        assert k.size == 1
        # 2x coarser FE mesh: differs by ~1.05e-4 max|u| (independent reference computation); allow
        # 5e-4
        assert np.abs(u[k[0]] - ref).max() <= 5e-4 * scale


@pytest.mark.slow
def test_c2_plate_with_hole_bc_b(fe, plate):
    pts, u_fe = fe
    cloud, bonds = plate
    interp = LinearNDInterpolator(pts, u_fe)
    u_ref = interp(cloud.points)
    assert np.all(np.isfinite(u_ref))
    ring, strips = _ring_and_strips(cloud)
    bc = [pdlin.Dirichlet(strips, u_ref[strips])]
    rng_ring = np.ptp(u_ref[ring], axis=0)
    # FE ring ranges: u_x 2.8042e-4 m, u_y 9.6945e-5 m (4 x 128 x 240 FE reference); ours within 1%
    np.testing.assert_allclose(rng_ring, [2.8042e-4, 9.6945e-5], rtol=1e-2)

    def ring_error(model, solver, preconditioner=None):
        res = pdlin.solve(
            pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc),
            solver=solver,
            rtol=1e-10,
            preconditioner=preconditioner,
        )
        err = np.abs(res.u[ring] - u_ref[ring]).max(axis=0) / rng_ring
        # B8: AMG-CG on K_E and GMRES + AMG(K_E) on K_p converge in ≤ 40 iterations (reference runs:
        # 17 and 19 iterations)
        assert res.n_iter <= 40
        return err, res.u

    err_xo, u_xo = ring_error(
        pdlin.XOSB(E, NU, linearization="paper"), "amg-gmres", preconditioner=pdlin.XOSB(E, NU)
    )
    err_xe, u_xe = ring_error(pdlin.XOSB(E, NU), "amg-cg")
    err_os, u_os = ring_error(pdlin.LPS(E, NU, linearization="paper"), "amg-gmres")
    # XOSBPD ring max error ≤ 2% (u_x), ≤ 4% (u_y) (reference values of an independent
    # implementation of the paper's formulas, not in the paper: 0.95% / 2.2%)
    assert err_xo[0] <= 0.02 and err_xo[1] <= 0.04
    assert err_xe[0] <= 0.02 and err_xe[1] <= 0.04  # energy variant: reference 1.00% / 2.26%
    # OSBPD ring u_y error ≥ 4x XOSBPD's (reference values 14.5% vs 2.2%)
    assert err_os[1] >= 4 * err_xo[1]
    # at β ≈ 90°: -5.0e-5 < u_y^XO < -4.6e-5 and u_y^OS < -5.5e-5 (bounds around the reference
    # values)
    beta = np.degrees(np.arctan2(cloud.points[ring, 1], cloud.points[ring, 0]))
    top = ring[np.argmin(np.abs(beta - 88.6))]
    assert -5.0e-5 < u_xo[top, 1] < -4.6e-5
    assert u_os[top, 1] < -5.5e-5
    # ring values at β = 88.6°: XO u_y -4.9414e-5, OS u_y -6.2508e-5, XO u_x 2.5339e-4 m (reference
    # values of an independent implementation of the paper's formulas, not in the paper; FE
    # reference differences allow 1%)
    assert abs(beta[np.argmin(np.abs(beta - 88.6))] - 88.6) < 0.05
    np.testing.assert_allclose(u_xo[top], [2.5339e-4, -4.9414e-5], rtol=1e-2)
    np.testing.assert_allclose(u_os[top, 1], -6.2508e-5, rtol=1e-2)
    # energy and paper variants agree within 0.5% max|u| (reference value 2.3e-3)
    assert np.abs(u_xe - u_xo).max() <= 5e-3 * np.abs(u_xo).max()


@pytest.mark.slow
def test_c2_refinement_with_the_spec_fe_mesh():
    """4x particles: XOSBPD converges, OSBPD does not (Liu, Chen & Skelton, XOSB, Sec. 5.1).

    FE reference on the 4 x 128 x 240 reference mesh (AMG-CG to 1e-12).
    """
    mesh = pdlin.plate_with_hole_mesh(128, 240)
    quads = next(c.data for c in mesh.cells if c.type == "quad")
    pts = np.asarray(mesh.points[:, :2], dtype=float)
    interp = LinearNDInterpolator(pts, _q4_plane_stress(pts, quads, solver="amg"))
    errors = {}
    for n_ang, n_rad in ((32, 60), (64, 120)):
        cloud = pdlin.read_mesh(pdlin.plate_with_hole_mesh(n_ang, n_rad))
        bonds = pdlin.find_bonds(cloud, ratio=3.01)
        u_ref = interp(cloud.points)
        ring, strips = _ring_and_strips(cloud, n_ang)
        bc = [pdlin.Dirichlet(strips, u_ref[strips])]
        for name, model in (
            ("xo", pdlin.XOSB(E, NU, linearization="paper")),
            ("os", pdlin.LPS(E, NU, linearization="paper")),
        ):
            res = pdlin.solve(
                pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc),
                solver="amg-gmres",
                rtol=1e-10,
            )
            err = np.abs(res.u[ring] - u_ref[ring]).max(axis=0) / np.ptp(u_ref[ring], axis=0)
            errors[name, cloud.n] = err
    # ring max errors (reference values of an independent implementation of the paper's formulas,
    # not in the paper): 7,680 XO 0.95% / 2.2%, OS 1.4% / 14.5%; 30,720 XO 0.65% / 0.98%, OS 1.2% /
    # 19.2%; tolerance 0.1 percentage point
    ref = {
        ("xo", 7680): (0.0095, 0.022),
        ("os", 7680): (0.014, 0.145),
        ("xo", 30720): (0.0065, 0.0098),
        ("os", 30720): (0.012, 0.192),
    }
    for key, val in ref.items():
        np.testing.assert_allclose(errors[key], val, rtol=0, atol=1e-3)
    # XOSBPD ring u_y error drops by >= 1.5x at 4x particles; OSBPD stays >= 10%
    assert errors["xo", 7680][1] >= 1.5 * errors["xo", 30720][1]
    assert errors["os", 30720][1] >= 0.10
