"""Unit tests of the Hex8 FE reference (pdlin.verification.fem.hex8_stiffness / solve_hex8)."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError, ShapeError
from pdlin.verification.fem import hex8_stiffness, solve_hex8

UNIT_CUBE = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)


def _box_mesh(nx: int, ny: int, nz: int, size=(1.0, 1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Structured nx x ny x nz hexahedra on a box, meshio node order."""
    axes = [np.linspace(0.0, s, m + 1) for s, m in zip(size, (nx, ny, nz), strict=True)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    node = np.arange(pts.shape[0]).reshape(nz + 1, ny + 1, nx + 1)
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    k, j, i = k.ravel(), j.ravel(), i.ravel()
    hexes = np.stack(
        [
            node[k, j, i],
            node[k, j, i + 1],
            node[k, j + 1, i + 1],
            node[k, j + 1, i],
            node[k + 1, j, i],
            node[k + 1, j, i + 1],
            node[k + 1, j + 1, i + 1],
            node[k + 1, j + 1, i],
        ],
        axis=1,
    )
    return pts, hexes


def _distort(pts: np.ndarray, rng: np.random.Generator, amount: float) -> np.ndarray:
    """Move the interior nodes randomly (boundary nodes stay on the box faces)."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    interior = np.all((pts > lo + 1e-12) & (pts < hi - 1e-12), axis=1)
    out = pts.copy()
    out[interior] += rng.uniform(-amount, amount, size=(int(interior.sum()), 3))
    return out


def _boundary(pts: np.ndarray) -> np.ndarray:
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return np.flatnonzero(np.any(np.isclose(pts, lo) | np.isclose(pts, hi), axis=1))


def test_symmetric_and_psd_with_six_rigid_modes(rng):
    for pts, hexes in ((UNIT_CUBE, [list(range(8))]), _box_mesh(3, 2, 2)):
        pts = _distort(pts, rng, 0.1) if len(hexes) > 1 else pts
        k = hex8_stiffness(pts, hexes, E=2.0, nu=0.3).toarray()
        assert np.abs(k - k.T).max() <= 1e-14 * np.abs(k).max()
        lam = np.linalg.eigvalsh(k)
        # exactly 6 zero eigenvalues (3 translations + 3 rotations) of a free body
        zero = np.abs(lam) < 1e-10 * lam.max()
        assert zero.sum() == 6
        assert lam.min() >= -1e-12 * lam.max()
        modes = pdlin.rigid_body_modes(pts)
        assert modes.shape[1] == 6
        assert np.abs(k @ modes).max() <= 1e-13 * np.abs(k).max() * np.abs(modes).max()


def test_single_cube_matches_closed_form_trace():
    # trace of the 2x2x2-Gauss Hex8 stiffness of a unit cube: 8 nodes x Σ_k ∫ B_k^T C B_k;
    # each diagonal entry K_(a,x),(a,x) = (λ + 2μ) ∫ N_a,x² + μ ∫ (N_a,y² + N_a,z²),
    # with ∫ N_a,x² = 1/9 on the unit cube (exact: the integrand is biquadratic in y, z),
    # so trace = 24 (λ + 4μ) / 9
    E, nu = 1.0, 0.3
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    k = hex8_stiffness(UNIT_CUBE, [list(range(8))], E, nu)
    assert abs(k.diagonal().sum() - 24 * (lam + 4 * mu) / 9) < 1e-13


def test_affine_patch_test_is_exact(rng):
    pts, hexes = _box_mesh(4, 3, 3, size=(2.0, 1.5, 1.0))
    pts = _distort(pts, rng, 0.12)
    A = rng.normal(size=(3, 3)) * 1e-3
    t = rng.normal(size=3) * 1e-3
    ue = pts @ A.T + t
    bnd = _boundary(pts)
    fixed = (3 * bnd[:, None] + np.arange(3)).ravel()
    for solver in ("lu", "amg"):
        u = solve_hex8(pts, hexes, 70e9, 0.33, fixed, ue[bnd].ravel(), solver=solver)
        assert np.abs(u - ue).max() <= 1e-10 * np.abs(ue).max()  # exact up to round-off


def test_affine_patch_test_on_distorted_mesh_with_mirrored_elements(rng):
    # strongly distorted interior nodes plus a mirrored (reflected) copy of the mesh: the
    # affine field is reproduced to round-off (|det J| handles left-handed elements)
    pts, hexes = _box_mesh(3, 3, 3)
    pts = _distort(pts, rng, 0.3 / 3)
    A = rng.normal(size=(3, 3)) * 1e-2
    for p, h in ((pts, hexes), (pts * [-1.0, 1.0, 1.0], hexes)):
        ue = p @ A.T
        bnd = _boundary(p)
        fixed = (3 * bnd[:, None] + np.arange(3)).ravel()
        u = solve_hex8(p, h, 1.0, 0.25, fixed, ue[bnd].ravel())
        assert np.abs(u - ue).max() <= 1e-11 * np.abs(ue).max()
        k = hex8_stiffness(p, h, 1.0, 0.25)
        interior = np.setdiff1d(np.arange(p.shape[0]), bnd)
        f = (k @ ue.ravel()).reshape(-1, 3)
        # zero nodal forces at interior nodes under an affine field (patch test)
        assert np.abs(f[interior]).max() <= 1e-12 * np.abs(k).max() * np.abs(ue).max()


def test_uniaxial_bar_analytic_displacement():
    # bar L x 1 x 1 along x: u_x = 0 on x = 0, u_x = u0 on x = L, lateral faces free, minimal
    # rigid-body constraints: exact uniaxial stress u = (u0 x/L, -nu u0 y/L, -nu u0 z/L)
    L, u0, nu = 5.0, 1e-3, 0.3
    pts, hexes = _box_mesh(10, 2, 2, size=(L, 1.0, 1.0))
    x0 = np.flatnonzero(pts[:, 0] == 0)
    xl = np.flatnonzero(np.isclose(pts[:, 0], L))
    origin = np.flatnonzero(np.all(pts == 0, axis=1))[0]
    ey = np.flatnonzero(np.all(np.isclose(pts, [0, 1, 0]), axis=1))[0]
    fixed = np.concatenate([3 * x0, 3 * xl, [3 * origin + 1, 3 * origin + 2, 3 * ey + 2]])
    vals = np.concatenate([np.zeros(x0.size), np.full(xl.size, u0), np.zeros(3)])
    u = solve_hex8(pts, hexes, 210e3, nu, fixed, vals)
    exact = np.column_stack(
        [u0 * pts[:, 0] / L, -nu * u0 * pts[:, 1] / L, -nu * u0 * pts[:, 2] / L]
    )
    assert np.abs(u - exact).max() <= 1e-12 * u0
    # reaction force on x = L equals E A ε
    k = hex8_stiffness(pts, hexes, 210e3, nu)
    reaction = (k @ u.ravel()).reshape(-1, 3)[xl, 0].sum()
    assert abs(reaction / (210e3 * 1.0 * u0 / L) - 1.0) < 1e-12


def test_amg_matches_lu_on_a_non_affine_problem(rng):
    pts, hexes = _box_mesh(6, 4, 4)
    pts = _distort(pts, rng, 0.05)
    x0 = np.flatnonzero(pts[:, 0] == 0)
    x1 = np.flatnonzero(pts[:, 0] == 1)
    fixed = np.concatenate([(3 * x0[:, None] + np.arange(3)).ravel(), 3 * x1 + 2])
    vals = np.concatenate([np.zeros(3 * x0.size), np.full(x1.size, 1e-3)])  # bending
    u_lu = solve_hex8(pts, hexes, 1.0, 0.3, fixed, vals)
    u_amg = solve_hex8(pts, hexes, 1.0, 0.3, fixed, vals, solver="amg")
    assert np.abs(u_amg - u_lu).max() <= 1e-8 * np.abs(u_lu).max()


def test_input_errors():
    good = [list(range(8))]
    with pytest.raises(ShapeError, match="points must have shape"):
        hex8_stiffness(UNIT_CUBE[:, :2], good, 1.0, 0.3)
    with pytest.raises(ShapeError, match="hexes must have shape"):
        hex8_stiffness(UNIT_CUBE, [list(range(4))], 1.0, 0.3)
    with pytest.raises(InputError, match="hexes must index points"):
        hex8_stiffness(UNIT_CUBE, [list(range(1, 9))], 1.0, 0.3)
    with pytest.raises(InputError, match="nu must be"):
        hex8_stiffness(UNIT_CUBE, good, 1.0, 0.5)
    with pytest.raises(InputError, match="E must be"):
        hex8_stiffness(UNIT_CUBE, good, -1.0, 0.3)
    # swapping two nodes tangles the element: Jacobian changes sign between Gauss points
    with pytest.raises(InputError, match="degenerate or tangled"):
        hex8_stiffness(UNIT_CUBE, [[0, 1, 3, 2, 4, 5, 6, 7]], 1.0, 0.3)
    with pytest.raises(InputError, match="solver must be"):
        solve_hex8(UNIT_CUBE, good, 1.0, 0.3, np.arange(24), 0.0, solver="qr")
    with pytest.raises(InputError, match="fixed must be DOFs"):
        solve_hex8(UNIT_CUBE, good, 1.0, 0.3, [24], 0.0)
