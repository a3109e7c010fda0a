"""Unit tests of pdlin.solvers.linear: direct, AMG-PCG, Jacobi-CG, AMG-GMRES."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import pdlin
from pdlin.constraints import eliminate_dirichlet, load_vector, resolve_dirichlet
from pdlin.errors import ConvergenceError, InputError
from pdlin.operators.rigid import rigid_body_modes
from pdlin.solvers import SOLVERS, DirectSolver, amg_hierarchy, solve_linear
from pdlin.solvers import direct as direct_mod
from pdlin.solvers import linear as linear_mod

Bar = tuple[sp.sparray, np.ndarray, np.ndarray, int, sp.sparray]


def _bar(shape: tuple[int, ...]) -> Bar:
    """Bond-based bar clamped at x-, pulled at x+ (horizon 3.015 h).

    Returns the eliminated system ``(A, b)``, the near-null space, dim and
    the unconstrained (floating, singular) stiffness.
    """
    d = len(shape)
    cloud = pdlin.grid(shape, spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    K = pdlin.BondBased(E=1e9).stiffness(cloud, bonds)
    dofs, vals = resolve_dirichlet(cloud, [pdlin.Dirichlet("x-", 0.0)])
    f = load_vector(cloud, [pdlin.TotalForce("x+", [1e3] + [0.0] * (d - 1))])
    A, b = eliminate_dirichlet(K, f, dofs, vals)
    B = rigid_body_modes(cloud)
    B[dofs] = 0.0
    return A, b, B, d, K


@pytest.fixture(scope="module", params=[(30, 15), (12, 6, 6)], ids=["2d", "3d"])
def bar(request: pytest.FixtureRequest) -> Bar:
    return _bar(request.param)


def test_solvers_agree_with_direct(bar: tuple) -> None:
    A, b, B, d, _ = bar
    ref = solve_linear(A, b, "direct").x
    for name in ("amg-cg", "jacobi-cg", "amg-gmres"):
        res = solve_linear(A, b, name, rtol=1e-12, near_null=B, blocksize=d)
        err = np.linalg.norm(res.x - ref) / np.linalg.norm(ref)
        # 1e-8: the agreement the solver contract promises (issue requirement);
        # measured ~1e-13 with rtol=1e-12
        assert err < 1e-8, (name, err)
        # the reported residual is the true one, recomputed here
        true = np.linalg.norm(b - A @ res.x) / np.linalg.norm(b)
        assert res.relative_residual == pytest.approx(true, rel=1e-6)
        assert res.relative_residual <= 1e-11  # 10 * rtol: the check of solve_linear


def test_amg_beats_jacobi_in_iterations(bar: tuple) -> None:
    A, b, B, d, _ = bar
    amg = solve_linear(A, b, "amg-cg", near_null=B, blocksize=d)
    jac = solve_linear(A, b, "jacobi-cg")
    assert amg.info["levels"] > 1
    # measured 14-15 (AMG) vs 31 (3D) / 70 (2D) (Jacobi) at rtol 1e-8
    assert amg.n_iter < jac.n_iter


def test_amg_gmres_nonsymmetric() -> None:
    A, b, B, d, _ = _bar((12, 6, 6))
    s = np.random.default_rng(3).uniform(1.0, 2.0, A.shape[0])
    An = sp.csr_array(sp.diags_array(s) @ A)  # row scaling: nonsymmetric, same pattern
    ref = spla.spsolve(sp.csc_matrix(An), b)
    res = solve_linear(An, b, "amg-gmres", rtol=1e-12, near_null=B, blocksize=d, symmetric=False)
    assert np.linalg.norm(res.x - ref) / np.linalg.norm(ref) < 1e-8  # issue requirement
    plain = solve_linear(An, b, "gmres", rtol=1e-8, symmetric=False, maxiter=2000)
    amg = solve_linear(An, b, "amg-gmres", rtol=1e-8, near_null=B, blocksize=d, symmetric=False)
    # measured 16 (AMG) vs several hundred (no preconditioner)
    assert amg.n_iter < plain.n_iter / 5


@pytest.mark.parametrize("name", ["amg-cg", "jacobi-cg", "cg", "amg-gmres"])
def test_convergence_error_when_maxiter_too_small(bar: tuple, name: str) -> None:
    A, b, B, d, _ = bar
    with pytest.raises(ConvergenceError, match="no convergence") as exc:
        solve_linear(A, b, name, maxiter=2, near_null=B, blocksize=d)
    res = exc.value.result
    assert res is not None and res.relative_residual > 1e-8


def test_direct_singular_system_fails_the_residual_check(bar: tuple) -> None:
    _, _, _, _, K = bar  # no Dirichlet condition: rigid-body modes make K singular
    rhs = np.random.default_rng(0).normal(size=K.shape[0])  # not orthogonal to them
    with pytest.raises(ConvergenceError, match="direct"):
        solve_linear(K, rhs, "direct")


def test_direct_solver_reuses_factorization(monkeypatch: pytest.MonkeyPatch) -> None:
    A, b, _, _, _ = _bar((12, 6))
    calls = []
    real = direct_mod.spla.splu

    def counting(*args: object, **kwargs: object) -> object:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(direct_mod.spla, "splu", counting)
    lu = DirectSolver(A, backend="superlu")
    rhs = np.column_stack([b, 2.0 * b, np.random.default_rng(1).normal(size=b.size)])
    X = lu.solve(rhs)
    x1 = lu.solve(b)
    assert len(calls) == 1
    assert X.shape == rhs.shape
    np.testing.assert_allclose(A @ X, rhs, rtol=0, atol=1e-9 * np.abs(rhs).max())
    np.testing.assert_allclose(X[:, 1], 2.0 * X[:, 0], rtol=1e-12)  # linearity
    np.testing.assert_allclose(x1, X[:, 0], rtol=1e-12)


@pytest.mark.parametrize("name", ["amg-cg", "cg", "jacobi-cg"])
def test_symmetric_only_solvers_refuse_nonsymmetric(name: str) -> None:
    A = sp.csr_array(np.array([[2.0, 1.0], [0.0, 2.0]]))
    with pytest.raises(InputError, match=name):
        solve_linear(A, np.ones(2), name, symmetric=False)


def test_bad_solver_name_lists_choices() -> None:
    A = sp.csr_array(np.eye(2))
    with pytest.raises(InputError) as exc:
        solve_linear(A, np.ones(2), "multigrid")
    msg = str(exc.value)
    assert "'multigrid'" in msg
    for name in SOLVERS:
        assert name in msg


def test_amg_builds_several_levels_in_3d() -> None:
    A, b, B, d, _ = _bar((20, 13, 13))  # 3380 points, 10,140 DOFs
    assert 9000 < A.shape[0] < 11000
    ml = amg_hierarchy(A, B, blocksize=d)
    assert len(ml.levels) > 1
    # each level coarsens: aggregates of about 3 x 3 x 3 points
    sizes = [lev.A.shape[0] for lev in ml.levels]
    assert all(c < f / 4 for f, c in zip(sizes[:-1], sizes[1:], strict=True))
    # a dense PD fine level dominates: measured 1.03-1.04
    assert ml.operator_complexity() < 1.3


def test_block_relative_strength_keeps_nearest_neighbours() -> None:
    cloud = pdlin.grid((9, 9, 9), spacing=1.0)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    K = pdlin.BondBased(E=1.0).stiffness(cloud, bonds)
    C = linear_mod.block_relative_strength(K, 3, 0.65)
    centre = 4 * 81 + 4 * 9 + 4
    # 18 = 6 face + 12 edge neighbours (|xi| <= sqrt(2) h: 1/sqrt(2) >= 0.65,
    # corners 1/sqrt(3) < 0.65)
    assert C.indptr[centre + 1] - C.indptr[centre] == 18


def test_amg_options_validated() -> None:
    A, _, B, d, _ = _bar((12, 6))
    with pytest.raises(InputError, match="cycle"):
        amg_hierarchy(A, B, blocksize=d, cycle="X")
    with pytest.raises(InputError, match="unknown"):
        amg_hierarchy(A, B, blocksize=d, not_an_option=1)
    ml = amg_hierarchy(A, B, blocksize=d, cycle="V")
    assert ml.cycle == "V"


def test_zero_rhs_returns_zero() -> None:
    A = sp.csr_array(np.eye(3))
    res = solve_linear(A, np.zeros(3), "amg-cg")
    assert res.n_iter == 0 and not res.x.any()


@pytest.mark.parametrize("chunk", [7, 1 << 16])
def test_chunked_pair_assembly_matches_dense_formula(
    monkeypatch: pytest.MonkeyPatch, chunk: int
) -> None:
    """The chunked BSR assembly that feeds the solvers, with isolated points
    at the start, middle and end of the point order (empty block rows)."""
    import pdlin.operators.assembly as asm

    monkeypatch.setattr(asm, "_CHUNK", chunk)
    cloud = pdlin.grid((14, 9), spacing=0.1)

    def cut(xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
        bad = (xi[:, 0] < 0.2) | (np.abs(xi[:, 0] - 0.75) < 0.05) | (xi[:, 0] > 1.3)
        return bad | (xj[:, 0] < 0.2) | (np.abs(xj[:, 0] - 0.75) < 0.05) | (xj[:, 0] > 1.3)

    bonds = pdlin.find_bonds(cloud, ratio=3.015, exclude=cut, allow_isolated=True)
    assert bonds.family_size[0] == 0 and bonds.family_size[-1] == 0
    k = np.random.default_rng(0).random(bonds.n_bonds)
    K = asm.pair_stiffness_bsr(bonds, k).toarray()
    # reference: K[i, j] = -k n nᵀ per bond, K[i, i] = -sum_j K[i, j] (class docstring)
    d = 2
    ref = np.zeros_like(K)
    n = bonds.xi / bonds.length[:, None]
    blocks = -k[:, None, None] * n[:, :, None] * n[:, None, :]
    for a in range(d):
        for c in range(d):
            np.add.at(ref, (d * bonds.i + a, d * bonds.j + c), blocks[:, a, c])
            np.add.at(ref, (d * bonds.i + a, d * bonds.i + c), -blocks[:, a, c])
    np.testing.assert_allclose(K, ref, rtol=1e-13, atol=1e-15)


def test_cg_returns_the_true_residual_it_was_asked_for():
    """Jacobi-CG on an ill-conditioned SPD matrix: the recursive residual drifts.

    D L D with L the 1D Laplacian (n = 2000) and D = diag(logspace(0, 4)): before the
    true-residual check, CG stopped at a true 7.4e-10 for rtol 1e-10 (measured).
    """
    n = 2000
    L = sp.diags_array([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], offsets=[-1, 0, 1])
    D = sp.diags_array(np.logspace(0, 4, n))
    A = sp.csr_array(D @ L @ D)
    b = np.random.default_rng(0).normal(size=n)
    res = solve_linear(A, b, "jacobi-cg", rtol=1e-10, maxiter=100_000)
    assert np.linalg.norm(b - A @ res.x) <= 1e-10 * np.linalg.norm(b)
    # an unattainable tolerance stops on stagnation (not after maxiter) and raises
    with pytest.raises(ConvergenceError, match="no convergence") as info:
        solve_linear(A, b, "jacobi-cg", rtol=1e-13, maxiter=100_000)
    assert info.value.result.n_iter < 20_000
