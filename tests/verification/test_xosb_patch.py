"""Free-edged patch residuals and the static bar for XOSB (Liu, Chen & Skelton, XOSB): regressions.

Setup (material of Liu, Chen & Skelton, XOSB, Sec. 5.1): uniform 100 x 40 plane-stress plate,
spacing Δ = 0.01 m, δ = 3.01 Δ, E = 70 GPa, ν = 0.33, the affine uniaxial-stress field ``u = (ε x,
-ν ε y)`` with ε = 1e-3.  "OSBPD" is :class:`pdlin.LPS` with the same families and the analytic
weighted volume (the paper's OSBPD comparison, Sec. 5).

**Patch (negative claim).**  Neither model is in equilibrium under the affine field at free
edges (the PD skin effect: exact-equilibrium patch tests with free edges fail for
both and prove nothing about the corrections), so this is a regression test of the residual
sizes, not an acceptance test.  The reference values are ``max |f_i| / (E ε Δ)`` with the force
density ``f_i`` in N/m³ and Δ in m (not dimensionless); we compare the dimensionless
``max |f_i| Δ / (E ε)``, which equals that number times Δ² = 1e-4 for this Δ.  Zones:
"interior" = at least 3 spacings from every edge, "corner zone" = within 3 spacings of two
edges, "edges" = the rest (this reproduces the reference values to their recorded digits).

**Static bar.**  The exact affine field prescribed (both components) on the one particle
layer at each end, the rest free: max error per component divided by that component's
max |u|.
"""

from __future__ import annotations

import numpy as np
import pytest

import pdlin

E, NU, EPS, H = 70e9, 0.33, 1e-3, 0.01  # material of Liu, Chen & Skelton, XOSB, Sec. 5.1; plate


@pytest.fixture(scope="module")
def plate():
    cloud = pdlin.grid((100, 40), spacing=H)
    # δ = 3.01 Δ (Liu, Chen & Skelton, XOSB, Sec. 5, Eq. 71)
    bonds = pdlin.find_bonds(cloud, ratio=3.01)
    x, y = cloud.points.T
    u = np.column_stack([EPS * x, -NU * EPS * y])
    return cloud, bonds, u


def _zones(cloud: pdlin.PointCloud) -> dict[str, np.ndarray]:
    x, y = cloud.points.T
    dx = np.minimum(x - x.min(), x.max() - x) / H
    dy = np.minimum(y - y.min(), y.max() - y) / H
    interior = (dx >= 3) & (dy >= 3)
    corner = (dx < 3) & (dy < 3)
    return {"interior": interior, "edges": ~interior & ~corner, "corner": corner}


# reference value, not in the paper: computed by an independent implementation of the paper's
# formulas: interior / edges / corner zone, in units of E ε Δ (x Δ² = ours)
PATCH_REF = {
    "xosb": (0.19, 0.71, 0.77),
    "osbpd": (5e-4, 0.50, 0.51),
}


@pytest.mark.parametrize("name", ["xosb", "osbpd"])
def test_c1_patch_residuals_regression(plate, name):
    cloud, bonds, u = plate
    model = (
        pdlin.XOSB(E, NU, linearization="paper")
        if name == "xosb"
        else pdlin.LPS(E, NU, linearization="paper")
    )
    f = model.internal_force(cloud, bonds, u, linear=True)
    r = np.linalg.norm(f, axis=1) * H / (E * EPS)  # dimensionless
    got = [float(r[m].max()) for m in _zones(cloud).values()]
    ref = np.array(PATCH_REF[name]) * H**2
    # regression bound: every zone ≤ 1.0 in units of E ε Δ
    assert max(got) <= 1.0 * H**2
    # the reference values to their recorded 1-2 digits (edges and corner 2 %, interior 10 %)
    np.testing.assert_allclose(got[1:], ref[1:], rtol=0.02)
    np.testing.assert_allclose(got[0], ref[0], rtol=0.1)
    # the skin effect is an edge effect: edge residuals ≥ 3x the interior ones for both
    assert got[1] >= 3 * got[0]


@pytest.mark.parametrize(
    "name,solver,bound",
    [
        # XOSBPD ≤ 2.5 % (u_x) and ≤ 3 % (u_y) (bounds; reference values 1.4 %, 2.1 %)
        ("xosb-paper", "amg-gmres", (0.025, 0.03)),
        ("xosb-energy", "direct", (0.025, 0.03)),
    ],
)
def test_c1_static_bar_xosb(plate, name, solver, bound):
    cloud, bonds, u = plate
    lin = name.split("-")[1]
    err = _bar_error(cloud, bonds, u, pdlin.XOSB(E, NU, linearization=lin), solver)
    assert err[0] <= bound[0] and err[1] <= bound[1]
    if lin == "paper":
        # the independent reference implementation: 1.4 % / 2.1 % (reference values)
        np.testing.assert_allclose(err, [0.014, 0.021], rtol=0.05)


def test_c1_static_bar_osbpd(plate):
    cloud, bonds, u = plate
    err = _bar_error(cloud, bonds, u, pdlin.LPS(E, NU, linearization="paper"), "amg-gmres")
    # OSBPD u_y error 3.7 % (reference value of the independent implementation); larger than
    # XOSBPD's 2.1 %
    np.testing.assert_allclose(err[1], 0.037, rtol=0.05)


def _bar_error(cloud, bonds, u, model, solver) -> np.ndarray:
    x = cloud.points[:, 0]
    ends = np.flatnonzero((x < x.min() + 1e-9) | (x > x.max() - 1e-9))
    prob = pdlin.StaticProblem(
        model, cloud, bonds=bonds, dirichlet=[pdlin.Dirichlet(ends, u[ends])]
    )
    res = pdlin.solve(prob, solver=solver, rtol=1e-12)
    return np.abs(res.u - u).max(axis=0) / np.abs(u).max(axis=0)
