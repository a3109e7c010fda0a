"""Geometrically nonlinear bond-based PD (PMB, kinematics='finite') through the drivers."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError


def _plate():
    cloud = pdlin.grid((12, 5), spacing=0.1)
    return cloud, pdlin.find_bonds(cloud, ratio=2.015)


def test_tangent_matches_finite_differences_of_the_pmb_force():
    cloud, bonds = _plate()
    m = pdlin.BondBased(E=2.0, kinematics="finite")
    rng = np.random.default_rng(3)
    u = 0.05 * rng.normal(size=(cloud.n, 2))  # large, non-affine displacement
    K = m.respond(cloud, bonds, u, {}, tangent=True).tangent.toarray()
    assert np.abs(K - K.T).max() <= 1e-12 * np.abs(K).max()
    h = 1e-6
    for col in rng.choice(cloud.n * 2, 8, replace=False):
        e = np.zeros(cloud.n * 2)
        e[col] = h
        fp = m.respond(cloud, bonds, u + e.reshape(-1, 2), {}).force.ravel()
        fm = m.respond(cloud, bonds, u - e.reshape(-1, 2), {}).force.ravel()
        fd = -(fp - fm) / (2 * h)
        np.testing.assert_allclose(K[:, col], fd, rtol=0, atol=1e-6 * np.abs(K).max())
    # small kinematics and the undeformed state: the linear stiffness
    K0 = m.respond(cloud, bonds, np.zeros((cloud.n, 2)), {}, tangent=True).tangent.toarray()
    Klin = pdlin.assemble_stiffness(pdlin.BondBased(E=2.0), cloud, bonds).toarray()
    np.testing.assert_allclose(K0, Klin, rtol=0, atol=1e-12 * np.abs(Klin).max())


def test_large_rotation_is_stress_free_and_both_drivers_find_it():
    # rotate the prescribed ends by 60 degrees (a rigid rotation of the whole plate): finite
    # kinematics gives the rotated configuration with no force; Newton and ADR both converge
    cloud, bonds = _plate()
    x = cloud.points[:, 0]
    ends = np.flatnonzero((x < 0.15) | (x > 1.05))
    c, s = np.cos(np.pi / 3), np.sin(np.pi / 3)
    Q = np.array([[c, -s], [s, c]])
    model = pdlin.BondBased(E=1.0, kinematics="finite")
    prob = pdlin.StaticProblem(model, cloud, bonds, dirichlet=[pdlin.Dirichlet.affine(ends, Q)])
    exact = cloud.points @ (Q - np.eye(2)).T
    new = pdlin.solve_nonlinear(prob, steps=6, method="newton")
    adr = pdlin.solve_nonlinear(prob, steps=6, method="adr", e_l=1e-10)
    # plain prescribed values scale with the load factor: only the last step is rigid
    np.testing.assert_allclose(new.u[-1], exact, atol=1e-9)
    np.testing.assert_allclose(adr.u[-1], exact, atol=1e-7)
    assert np.abs(new.reactions[-1]).max() < 1e-10
    # the linearized model cannot: it stretches the rotated bonds
    lin = pdlin.solve(pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, bonds,
                                          dirichlet=[pdlin.Dirichlet.affine(ends, Q)]))  # fmt: skip
    assert np.abs(lin.reactions).max() > 1e-2


def test_kinematics_argument_is_checked():
    with pytest.raises(InputError, match="kinematics must be 'small' or 'finite', got 'large'"):
        pdlin.BondBased(E=1.0, kinematics="large")
    assert (
        not pdlin.BondBased(E=1.0).nonlinear
        and pdlin.BondBased(E=1.0, kinematics="finite").nonlinear
    )
