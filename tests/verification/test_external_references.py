"""Reference cases published with other peridynamics codes, rebuilt from their definitions.

The 12-point LPS compression (a 3 x 2 x 2 cube in the style of Peridigm's smallest
quasi-static regression decks) is checked against an independent, loop-based
implementation of Peridigm's linear peridynamic solid written here from its force state

    t = (3 K θ / m) ω |ξ| + (15 μ / m) ω e^d,
    θ = (3 / m) Σ ω |ξ| e V,  e^d = e - θ |ξ| / 3,  m = Σ ω |ξ|² V,

so that pdlin's vectorized energy Hessian (``LPS(peridigm=True)``) is compared with the
force-state definition itself, not with pdlin's own code.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import pdlin


def _peridigm_lps_force(points, vol, horizon, K, G, u):
    """Peridigm's linearized LPS force (ω = 1, discrete m), one loop per point."""
    n = len(points)
    fam = [
        [j for j in range(n) if j != i and np.linalg.norm(points[j] - points[i]) <= horizon]
        for i in range(n)
    ]
    m = np.array(
        [sum(np.sum((points[j] - points[i]) ** 2) * vol[j] for j in fam[i]) for i in range(n)]
    )
    theta = np.zeros(n)
    for i in range(n):
        for j in fam[i]:
            xi = points[j] - points[i]
            r = np.linalg.norm(xi)
            e = (u[j] - u[i]) @ xi / r  # linearized extension
            theta[i] += 3.0 / m[i] * r * e * vol[j]
    f = np.zeros_like(u)
    for i in range(n):
        for j in fam[i]:
            xi = points[j] - points[i]
            r = np.linalg.norm(xi)
            e = (u[j] - u[i]) @ xi / r
            ed = e - theta[i] * r / 3.0
            t = 3.0 * K * theta[i] / m[i] * r + 15.0 * G / m[i] * ed
            # t acts on i towards j and its reaction on j (pair force of the state at i)
            f[i] += t * xi / r * vol[j]
            f[j] -= t * xi / r * vol[i]
    return f


def test_twelve_point_lps_compression_matches_peridigm_force_state():
    # 3 x 2 x 2 points, unit spacing and volume, horizon 1.75: bonds to the axis neighbours,
    # the face diagonals (1.414) and the body diagonals (1.732), not to distance 2
    cloud = pdlin.grid((3, 2, 2), spacing=1.0)
    pts, vol = cloud.points, np.asarray(cloud.volumes)
    K, G, horizon = 1.3e3, 0.6e3, 1.75
    x = pts[:, 0]
    left, right = np.flatnonzero(x < 1.0), np.flatnonzero(x > 2.0)
    # pin left[0] in y and z, and the left point beside it in y (same z) in z: no rotation
    a = left[0]
    b = left[(pts[left, 2] == pts[a, 2]) & (pts[left, 1] != pts[a, 1])][0]
    # compression along x: u_x prescribed on both end faces, one end pinned laterally
    presc = {**{3 * i: 0.0 for i in left}, **{3 * i: -0.01 for i in right}}
    presc.update({3 * a + 1: 0.0, 3 * a + 2: 0.0, 3 * b + 2: 0.0})
    dofs = np.array(sorted(presc))
    vals = np.array([presc[k] for k in dofs])

    # independent reference: the force is linear in u, so its matrix follows column by column
    ndof = 3 * cloud.n
    Kref = np.zeros((ndof, ndof))
    for k in range(ndof):
        e = np.zeros(ndof)
        e[k] = 1.0
        Kref[:, k] = -_peridigm_lps_force(pts, vol, horizon, K, G, e.reshape(-1, 3)).ravel()
    free = np.setdiff1d(np.arange(ndof), dofs)
    uref = np.zeros(ndof)
    uref[dofs] = vals
    uref[free] = np.linalg.solve(Kref[np.ix_(free, free)], -Kref[np.ix_(free, dofs)] @ vals)
    reac_ref = Kref @ uref

    bonds = pdlin.find_bonds(cloud, horizon, influence="constant")
    prob = pdlin.StaticProblem(
        pdlin.LPS(K=K, G=G, peridigm=True),
        cloud,
        bonds,
        dirichlet=[pdlin.Dirichlet(left, 0.0, "x"), pdlin.Dirichlet(right, -0.01, "x"),
                   pdlin.Dirichlet([a], 0.0, "yz"), pdlin.Dirichlet([b], 0.0, "z")],
    )  # fmt: skip
    res = pdlin.solve(prob, solver="direct")
    np.testing.assert_allclose(res.u.ravel(), uref, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(res.reactions.ravel()[dofs], reac_ref[dofs], rtol=1e-9, atol=1e-10)
    # the end-face reactions balance (no loads); the support pushes the right face in -x
    assert res.reactions[right, 0].sum() < 0
    np.testing.assert_allclose(res.reactions.sum(axis=0), 0.0, atol=1e-9)


@pytest.mark.parametrize("u_pattern", ["random", "checkerboard"])
def test_peridigm_force_state_equals_pdlin_internal_force(u_pattern):
    # the same independent force against pdlin's matrix-free force on arbitrary fields
    cloud = pdlin.grid((3, 2, 2), spacing=1.0)
    bonds = pdlin.find_bonds(cloud, 1.75, influence="constant")
    if u_pattern == "random":
        u = np.random.default_rng(3).normal(size=(cloud.n, 3))
    else:
        idx = np.array(list(itertools.product(range(3), range(2), range(2))))
        u = ((-1.0) ** idx.sum(axis=1))[:, None] * np.array([1.0, 0.5, -0.25])
    ref = _peridigm_lps_force(cloud.points, np.asarray(cloud.volumes), 1.75, 2.0, 1.0, u)
    got = pdlin.LPS(K=2.0, G=1.0, peridigm=True).internal_force(cloud, bonds, u)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
