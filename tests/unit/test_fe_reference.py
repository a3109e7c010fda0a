"""grid_fe_reference: the Q4 / Hex8 counterpart of a grid problem (scene reference 'fem')."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError
from pdlin.verification import grid_fe_reference


def test_3d_hex8_uniaxial_displacement_field_is_exact():
    # bilinear/trilinear elements reproduce affine fields: uniaxial stress u_y = -nu eps y
    cloud = pdlin.grid((8, 4, 4), spacing=0.25)
    p0 = cloud.points.min(axis=0)
    fixed_corner = int(np.argmin(np.linalg.norm(cloud.points - p0, axis=1)))
    x_length = float(np.ptp(cloud.points[:, 0]))
    rel = cloud.points - p0
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=3.0, nu=0.2), cloud, bond_options={"ratio": 2.015},
        dirichlet=[
            pdlin.Dirichlet("x-", 0.0, "x"), pdlin.Dirichlet("x+", 0.01 * x_length, "x"),
            pdlin.Dirichlet([fixed_corner], 0.0),
            pdlin.Dirichlet(np.abs(rel[:, 1]) < 1e-9, 0.0, "y"),
            pdlin.Dirichlet(np.abs(rel[:, 2]) < 1e-9, 0.0, "z"),
        ],
    )  # fmt: skip
    u = grid_fe_reference(prob)
    assert np.allclose(u[:, 0], 0.01 * rel[:, 0], atol=1e-14)
    assert np.allclose(u[:, 1], -0.2 * 0.01 * rel[:, 1], atol=1e-14)
    assert np.allclose(u[:, 2], -0.2 * 0.01 * rel[:, 2], atol=1e-14)


def test_nodal_forces_are_applied_and_balance_the_reactions():
    # a clamped 2D block under a body force: the FE reactions balance the total load, and
    # the solution is linear in the load (no hidden scaling by thickness)
    cloud = pdlin.grid((12, 6), spacing=0.1, thickness=0.5)
    model = pdlin.Correspondence(E=1.0, nu=0.3, plane="strain")

    def solve(b):
        prob = pdlin.StaticProblem(
            model, cloud, bond_options={"ratio": 2.015},
            dirichlet=[pdlin.Dirichlet("x-", 0.0)], loads=[pdlin.BodyForce("all", [b, 0.0])],
        )  # fmt: skip
        return grid_fe_reference(prob)

    u1, u2 = solve(1e-3), solve(2e-3)
    assert np.allclose(u2, 2 * u1, rtol=1e-12, atol=0)
    assert u1[:, 0].max() > 0
    from pdlin.verification import q4_stiffness
    from pdlin.verification.fem import _lattice_cells

    conn, pts = _lattice_cells(cloud)
    K = q4_stiffness(pts, conn, 1.0, 0.3, plane="strain", thickness=0.5)
    f_int = (K @ u1.reshape(-1)).reshape(-1, 2)
    # total internal force = total body force (V b t summed), all reacted at x-
    total = 1e-3 * cloud.volumes.sum() * 0.5
    assert f_int[:, 0].sum() == pytest.approx(0.0, abs=1e-12 * total)
    free = np.setdiff1d(np.arange(cloud.n), cloud.sets["x-"])
    assert f_int[free, 0].sum() == pytest.approx(total * free.size / cloud.n, rel=1e-10)


def test_bond_based_uses_its_implied_poisson_ratio_and_holes_drop_cells():
    # an image grid with a void: cells touching the void are left out; bond-based 2D plane
    # stress implies nu = 1/3 (Cauchy relation), so the lateral contraction is -eps/3
    img = np.ones((10, 6), dtype=int)
    img[4:6, 2:4] = 0
    cloud = pdlin.from_image(img, spacing=0.1, void=0)
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0, plane="stress"), cloud, bond_options={"ratio": 2.015},
        dirichlet=[pdlin.Dirichlet("x-", 0.0, "x"), pdlin.Dirichlet("x+", 0.009, "x"),
                   pdlin.Dirichlet([0], 0.0)],
    )  # fmt: skip
    from pdlin.verification.fem import _lattice_cells

    conn, _ = _lattice_cells(cloud)
    # 9 x 5 = 45 cells; the 9 with a corner in the 2 x 2 void (cells i = 3..5, j = 1..3) go
    assert conn.shape[0] == 9 * 5 - 9
    u = grid_fe_reference(prob)
    assert np.all(np.isfinite(u)) and u[:, 0].max() == pytest.approx(0.009)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: pdlin.StaticProblem(
            pdlin.BondBased(E=1.0), pdlin.PointCloud(np.random.default_rng(0).random((20, 2)),
                                                     np.full(20, 0.01)),
            bond_options={"ratio": 2.0}), "needs a grid"),
        (lambda: pdlin.StaticProblem(pdlin.BondBased(E=1.0), pdlin.grid((10,)),
                                     bond_options={"ratio": 2.0}), "2D or 3D"),
        (lambda: pdlin.StaticProblem(pdlin.Correspondence(C=np.diag([2.0, 1.0, 0.5]),
                                                          plane="stress"),
                                     pdlin.grid((5, 5)), bond_options={"ratio": 2.0}),
         "one scalar E and nu"),
    ],
)  # fmt: skip
def test_unsupported_problems_are_named(make, match):
    with pytest.raises(InputError, match=match):
        grid_fe_reference(make())
