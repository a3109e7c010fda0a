"""The constrained system shared by the drivers (linear, Newton, ADR)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla

import pdlin
from pdlin.operators.symmetry import SymmetryPlane, SymmetryReduction
from pdlin.system import ConstrainedSystem, PlainDiscretization


def _plate(symmetry=()):
    cloud = pdlin.grid((12, 6), spacing=0.1)
    return pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        cloud,
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0, "x"), pdlin.Dirichlet("x+", 1e-3, "x")]
        + ([] if symmetry else [pdlin.Dirichlet([0], 0.0, "y")]),
        loads=[pdlin.BodyForce(np.arange(cloud.n), [0.0, -0.01])],
        symmetry=symmetry,
    )


@pytest.mark.parametrize("symmetry", [(), (SymmetryPlane("y", 0.0, side="+"),)])
def test_system_residual_vanishes_at_the_solution(symmetry):
    prob = _plate(symmetry)
    system = pdlin.constrained_system(prob)
    assert isinstance(system.disc, SymmetryReduction if symmetry else PlainDiscretization)
    K = system.assemble()
    rows = system.prescribed_rows(K)
    A, b = system.eliminate(K)
    u = system.expand(spla.spsolve(A.tocsc(), b))
    r = system.residual(u)
    assert np.abs(r).max() <= 1e-12 * np.abs(system.f_ext).max()
    # reactions from K's rows equal those of the internal force, and balance the loads
    np.testing.assert_allclose(system.reactions(u, rows=rows), system.reactions(u), atol=1e-14)
    total = system.reactions(u).sum(axis=0) + system.f_ext.reshape(-1, 2).sum(axis=0)
    if not symmetry:  # with a mirror plane the other half carries the y load through ghost bonds
        np.testing.assert_allclose(total, 0.0, atol=1e-13)
    # the driver-level solve returns the same field through the same system
    res = pdlin.solve(prob, solver="direct")
    np.testing.assert_allclose(res.u, u, rtol=1e-10, atol=1e-15)
    assert isinstance(res.system, ConstrainedSystem)
    assert (res.symmetry is not None) == bool(symmetry)


def test_load_factor_scales_prescribed_values_and_loads():
    system = pdlin.constrained_system(_plate())
    K = system.assemble()
    A1, b1 = system.eliminate(K)
    A2, b2 = system.eliminate(K, factor=0.25)
    np.testing.assert_allclose(b2, 0.25 * b1, rtol=1e-14, atol=1e-18)
    u1 = system.expand(spla.spsolve(A1.tocsc(), b1))
    u2 = system.expand(spla.spsolve(A2.tocsc(), b2), factor=0.25)
    # linear problem: the solution scales with the load factor
    np.testing.assert_allclose(u2, 0.25 * u1, rtol=1e-10, atol=1e-16)
    assert np.abs(system.residual(u2, factor=0.25)).max() < 1e-14


def test_matrix_free_system_matches_assembled():
    system = pdlin.constrained_system(_plate())
    A, b = system.eliminate(system.assemble())
    Am, bm, P = system.matrix_free()
    np.testing.assert_allclose(bm, b, rtol=1e-12, atol=1e-16)
    x = np.random.default_rng(1).normal(size=system.ndof)
    x[system.dofs] = 0.0
    np.testing.assert_allclose(Am @ x, A @ x, rtol=1e-10, atol=1e-12)
    assert P.shape == A.shape


def test_symmetry_system_has_no_matrix_free_operator():
    system = pdlin.constrained_system(_plate((SymmetryPlane("y", 0.0, side="+"),)))
    assert not system.matrix_free_capable
    with pytest.raises(pdlin.errors.InputError, match="does not support symmetry planes"):
        system.matrix_free()
    with pytest.raises(pdlin.errors.InputError, match="without symmetry planes"):
        system.preconditioner_matrix(pdlin.BondBased(E=1.0))
