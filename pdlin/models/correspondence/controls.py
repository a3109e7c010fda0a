"""TODO controls."""

from __future__ import annotations

import numpy as np

from ..._arrays import (
    per_point_outer,
)
from ..._kernels import _kernels, use_numba
from ..._threads import even_chunks, ptr_chunks, thread_map
from ...geometry.bonds import Bonds
from . import gradient as _gradient

#: zero-energy-mode controls accepted by :class:`Correspondence`
CONTROLS = ("none", "higher_order", "penalty", "stress_points", "springs", "ads")


#: default dimensionless coefficient C̃ of the 'springs' and 'ads' controls (family-normalized,
#: :meth:`Correspondence.control_constants`).  Measured on a free-surface 2D bar (61 x 11,
#: δ = h...3h, docs/correspondence.md): springs bias the stiffness by ≈ 1.1 C̃ at any δ/h
#: (0.01: 1.2 %), ADS only near free surfaces (0.03: elongation ≤ 0.11 %, lateral strain
#: ≤ 0.6 %) while keeping the checkerboard energy ratio ≥ 2 (stress points: 3.5-43)
DEFAULT_CONTROL_COEFFICIENT: dict[str, float] = {"springs": 0.01, "ads": 0.03}


#: stress-point cases (spec 003 §4.1): sign vector s of SP1's bonds, per dimension
_SP_CASES: dict[int, np.ndarray] = {
    1: np.array([[1]]),
    2: np.array([[1, 1], [1, -1]]),
    3: np.array([[1, 1, 1], [1, 1, -1], [1, -1, 1], [-1, 1, 1]]),
}


#: smallest eigenvalue ratio λ_min/λ_max of a half-family shape tensor for which a
#: particle gets two stress points (nearest-neighbour interior particles: 1)
SP_MIN_RATIO = 1e-2


#: largest relative imbalance ``‖K_1 - K_2‖_F / ‖K‖_F`` of the two half-family shape tensors
#: for which a particle gets two stress points (complete lattice families: 0 to round-off)
SP_BALANCE_TOL = 1e-6


def _half_space_basis(s: np.ndarray, d: int) -> list[np.ndarray]:
    """The orthogonal basis of case ``s`` whose projections decide a bond's side."""
    basis = [np.asarray(s, dtype=float)]
    if d >= 2:
        t = np.zeros(d)
        t[0], t[1] = -s[1], s[0]
        basis.append(t)
    if d == 3:
        basis.append(np.cross(basis[0], basis[1]))
    return basis


def _sides(bonds: Bonds, cases: np.ndarray) -> np.ndarray:
    """``(n_cases, nb)`` bool: :func:`_half_space` of every case (numba: bond chunks on
    the threads)."""
    xi = bonds.xi
    mod = _kernels() if use_numba(xi.size * cases.shape[0]) else None
    if mod is None:
        return np.stack([_half_space(xi, s) for s in cases])
    d = xi.shape[1]
    basis = np.array([_half_space_basis(s, d) for s in cases])  # (n_cases, d, d)
    vnorm = np.linalg.norm(basis, axis=2)
    out = np.empty((cases.shape[0], xi.shape[0]), dtype=bool)
    xi_c = np.ascontiguousarray(xi, dtype=np.float64)
    kern = mod.half_space_fill
    thread_map(
        lambda r: kern(r[0], r[1], xi_c, basis, vnorm, out),
        even_chunks(xi.shape[0], _gradient._ROW_CHUNK),
    )
    return out


def _half_space(xi: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Bonds owned by stress point 1 of case ``s``: ``s·ξ > 0``, ties by orthogonal vectors.

    ``ξ`` and ``-ξ`` always land on different sides, so the two halves of a point-symmetric
    family are mirror images (each holds half of its shape tensor).
    """
    basis = _half_space_basis(s, xi.shape[1])
    tol = 1e-9 * np.linalg.norm(xi, axis=1)
    key = np.zeros(xi.shape[0])
    undecided = np.ones(xi.shape[0], dtype=bool)
    for v in basis:
        proj = xi @ v
        take = undecided & (np.abs(proj) > tol * np.linalg.norm(v))
        key[take] = proj[take]
        undecided &= ~take
    return key > 0


def _ratio_ok(K: np.ndarray) -> np.ndarray:
    """Per tensor of ``K (n, d, d)``: λ_min/λ_max ≥ SP_MIN_RATIO.

    2 x 2 in closed form, ``(a + c)/2 ± hypot((a - c)/2, b)`` (accurate to ~ε/SP_MIN_RATIO
    at the threshold; 10x faster than batched LAPACK), otherwise ``eigvalsh``.
    """
    if K.shape[1] == 2:
        mid = 0.5 * (K[:, 0, 0] + K[:, 1, 1])
        rad = np.hypot(0.5 * (K[:, 0, 0] - K[:, 1, 1]), K[:, 0, 1])
        lo, hi = mid - rad, mid + rad
    else:
        lam = np.linalg.eigvalsh(K)
        lo, hi = lam[:, 0], lam[:, -1]
    return lo >= SP_MIN_RATIO * np.maximum(hi, 1e-300)


def _halves_well_conditioned(
    bonds: Bonds, omega_v: np.ndarray, sides: np.ndarray, n: int, omega: np.ndarray | None = None
) -> np.ndarray:
    """Per point: in every case (row of ``sides``) both halves' shape tensors are well
    conditioned and *balanced*, ``‖K_1 - K_2‖_F ≤ SP_BALANCE_TOL ‖K‖_F``.

    Balance is a property of the family's geometry: it is tested on the tensors of the
    weights ``omega`` (without volumes) when given, so a lattice with non-uniform volumes
    keeps its two stress points (spec 003's scheme) while truncated families next to free
    surfaces and irregular clouds get one gradient point.

    The second half's tensor is the full one minus the first's (one pass per case).  Balanced
    halves (``K_1 = K_2 = K/2``: a point-symmetric, complete family) are what makes two
    stress points of weight ``w`` act on a uniform stress exactly like one gradient point of
    weight ``2w`` (``w (K/2)⁻¹ = 2w K⁻¹`` on every bond), hence consistent next to free
    surfaces; unbalanced halves of truncated families are not (measured: 1.1 % patch-test
    error on a free-surface 2D bar at δ = 3h).
    """
    geo = omega_v if omega is None else omega
    mod = _kernels() if use_numba(bonds.xi.size * sides.shape[0]) else None
    if mod is not None and bonds.dim == 2 and bonds.n_points == n:
        # one nogil pass per point chunk on the threads (the same tensors; the decisions
        # compare with tolerances far above round-off)
        ok2 = np.empty(n, dtype=bool)
        bptr = np.asarray(bonds.indptr, dtype=np.int64)
        args = (
            bptr,
            np.ascontiguousarray(bonds.xi, dtype=np.float64),
            np.ascontiguousarray(omega_v, dtype=np.float64),
            np.ascontiguousarray(geo, dtype=np.float64),
            np.ascontiguousarray(sides),
            SP_MIN_RATIO,
            SP_BALANCE_TOL,
            ok2,
        )
        kern = mod.sp_halves_2d
        thread_map(lambda r: kern(r[0], r[1], *args), ptr_chunks(bptr, _gradient._POINT_CHUNK))
        return ok2
    full_k = per_point_outer(bonds.i, n, omega_v, bonds.xi, bonds.xi)
    full_g = per_point_outer(bonds.i, n, geo, bonds.xi, bonds.xi)
    scale = np.sqrt(np.einsum("nij,nij->n", full_g, full_g))
    ok = np.ones(n, dtype=bool)
    for side in sides:
        half = per_point_outer(bonds.i, n, np.where(side, omega_v, 0.0), bonds.xi, bonds.xi)
        other = full_k - half
        half_g = per_point_outer(bonds.i, n, np.where(side, geo, 0.0), bonds.xi, bonds.xi)
        diff = 2.0 * half_g - full_g
        balanced = np.sqrt(np.einsum("nij,nij->n", diff, diff)) <= SP_BALANCE_TOL * scale
        ok &= _ratio_ok(half) & _ratio_ok(other) & balanced
    return ok
