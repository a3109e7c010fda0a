"""Closed-form and reference-value verification of the bond-based model."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin


def _bar_1d(N: int, m: int, E0: float, sigma: float, graded: bool, solver: str = "direct"):
    """Bar on (0, 1) with outward shadow layers of m points carrying the exact u."""
    h = 1.0 / N
    cloud = pdlin.grid((N + 2 * m,), spacing=h, origin=(-m * h,))
    x = cloud.points[:, 0]
    if graded:
        E = E0 * (1.0 + x)
        exact = sigma / E0 * np.log1p(x)  # (E u')' = 0 with E u' = sigma
    else:
        E = np.full(cloud.n, E0)
        exact = sigma / E0 * x
    shadow = np.r_[np.arange(m), np.arange(cloud.n - m, cloud.n)]
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=E),
        cloud,
        horizon=(m + 0.015) * h,
        dirichlet=[pdlin.Dirichlet(shadow, exact[shadow, None])],
    )
    res = pdlin.solve(prob, solver=solver, rtol=1e-12)
    real = np.setdiff1d(np.arange(cloud.n), shadow)
    return res, exact, real


def test_bar_1d_constant_modulus_is_exact():
    res, exact, real = _bar_1d(200, 3, 2e11, 1e8, graded=False)
    # affine data, complete families: the discrete solution is the exact linear one
    np.testing.assert_allclose(res.u[real, 0], exact[real], rtol=0, atol=1e-12 * exact.max())


def test_bar_1d_graded_modulus_spacing_convergence():
    Ns = [50, 100, 200, 400]
    errs = []
    for N in Ns:
        res, exact, real = _bar_1d(N, 3, 1.0, 1e-3, graded=True)
        errs.append(np.abs(res.u[real, 0] - exact[real]).max() / np.abs(exact).max())
    rate = -np.polyfit(np.log(Ns), np.log(errs), 1)[0]
    # fixed m = delta/h: the nonlocal error is O(delta^2) = O(h^2)
    assert rate > 1.8, (errs, rate)
    assert errs[-1] < 1e-5


def test_bar_1d_graded_modulus_horizon_convergence():
    N = 800
    errs = []
    ms = [16, 8, 4]
    for m in ms:
        res, exact, real = _bar_1d(N, m, 1.0, 1e-3, graded=True)
        errs.append(np.abs(res.u[real, 0] - exact[real]).max() / np.abs(exact).max())
    rate = np.polyfit(np.log(ms), np.log(errs), 1)[0]
    assert rate > 1.8, (errs, rate)  # error ~ delta^2 at fixed h


def test_bar_3d_shadow_layer_uniaxial_exact_interior():
    E, sigma = 200e9, 1e8
    eps = sigma / E
    nu = 0.25  # bond-based 3D implies nu = 1/4
    h = 0.01
    cloud = pdlin.grid((24, 12, 12), spacing=h)
    delta = 3.015 * h
    F = np.diag([1 + eps, 1 - nu * eps, 1 - nu * eps])
    bc, shadow = pdlin.shadow_layer(cloud, F, depth=delta)
    prob = pdlin.StaticProblem(pdlin.BondBased(E=E), cloud, horizon=delta, dirichlet=[bc])
    res = pdlin.solve(prob, solver="amg-cg", rtol=1e-12)
    real = np.setdiff1d(np.arange(cloud.n), shadow)
    assert real.size == 18 * 6 * 6  # 3 shadow layers per face
    strain = res.strain()[real]
    np.testing.assert_allclose(strain[:, 0, 0], eps, rtol=1e-8)
    np.testing.assert_allclose(strain[:, 1, 1], -nu * eps, rtol=1e-8)
    # virial stress = C_i : eps with the point's discrete effective tensor (Prakash, anisotropic
    # micromoduli, Eq. 29), which differs from the continuum C by the lattice quadrature (0.4 % at
    # 3.015 h)
    C = pdlin.BondBased(E=E).effective_tensor(cloud, res.bonds)[real]
    expected = np.einsum("nijkl,kl->nij", C, F - np.eye(3))
    stress = res.stress()[real]
    np.testing.assert_allclose(stress, expected, rtol=1e-8, atol=1e-8 * sigma)
    assert abs(stress[:, 0, 0].mean() / sigma - 1) < 5e-3


@pytest.mark.slow
def test_spec004_static_uniaxial_tension_analytical_micromodulus(spec004_tension):
    """Prakash, anisotropic micromoduli, Sec. 4.4: 24^3 cube, delta = 2, c = 18K/(pi delta^4).

    The analytical micromodulus is the paper's Eq. 18.
    """
    cloud = pdlin.grid((24, 24, 24), spacing=1.0, origin=(-0.5, -0.5, -0.5))
    bonds = pdlin.find_bonds(cloud, 2.0)
    model = pdlin.BondBased(E=86e9)  # Pyroceram, nu = 1/4: c = 20.5310 GPa/m^4 (Eq. 18)
    np.testing.assert_allclose(model.bond_micromodulus(cloud, bonds)[0], 20.5310e9, rtol=1e-5)
    prob = spec004_tension(model, cloud, bonds)
    res = pdlin.solve(prob, solver="amg-cg", rtol=1e-11)
    p = cloud.points
    inner = np.all((p >= 2) & (p <= 21), axis=1)
    assert inner.sum() == 8000
    ezz = res.strain()[inner, 2, 2].mean()
    np.testing.assert_allclose(ezz, 1.09325e-5, rtol=2e-4)  # reference value (analytical c)
    k = int(np.flatnonzero(np.all(p == [12, 12, 23], axis=1))[0])
    np.testing.assert_allclose(res.u[k, 2], 2.5502e-4, rtol=2e-4)  # reference value
    np.testing.assert_allclose(res.u[:, 0].min(), -5.7862e-5, rtol=2e-4)  # reference value
    C = model.effective_tensor(cloud, bonds)
    np.testing.assert_allclose(C[inner, 0, 0, 0, 0].mean() / 1e9, 106.4329, rtol=1e-5)  # reference
    # reference C44
    np.testing.assert_allclose(C[inner, 1, 2, 1, 2].mean() / 1e9, 30.3224, rtol=1e-5)
