"""The zero-energy-mode controls of :class:`~pdlin.models.correspondence.Correspondence`.

What each control adds to the plain correspondence operator ``Gᵀ blockdiag(w V C) G``:

- ``'stress_points'`` (Luo & Sundararaghavan (2018), Sec. 3): the split of each family
  into two half families with their own gradient points (:func:`gradient_points`);
- ``'penalty'``: ``½ Σ_b ½ penalty k_b |z_b|²`` on the non-affine part of each bond
  (:func:`penalty_matrix`, :func:`penalty_force`);
- ``'springs'`` and ``'ads'`` (Luo & Sundararaghavan (2018), Eqs. 7-8): one-hop
  stiffness factors ``S N`` (:func:`control_factors`) with family-normalized constants
  (:func:`control_constants`).

``'none'`` and ``'higher_order'`` change only the bond weights (the model's
``bond_weights``).  Every function takes the model and reads its parameters; the model's
methods of the same names delegate here.
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

import pdlin.models.correspondence.gradient as _gradient

from ..._arrays import per_point_outer
from ..._kernels import compiled_kernels, use_numba
from ..._threads import even_chunks, ptr_chunks, thread_map
from ...errors import InputError, ModelError
from ...geometry.bonds import Bonds
from ...geometry.cloud import PointCloud
from ..bond_based import BondBased, implied_poisson_ratio

if TYPE_CHECKING:
    from .model import Correspondence, _Plan

__all__ = [
    "CONTROLS",
    "DEFAULT_CONTROL_COEFFICIENT",
    "SP_MIN_RATIO",
    "SP_BALANCE_TOL",
    "gradient_points",
    "unit_axial_modulus",
    "penalty_bond_stiffness",
    "penalty_force",
    "penalty_matrix",
    "control_constants",
    "laplacian",
    "control_factors",
]


#: zero-energy-mode controls accepted by :class:`Correspondence`
CONTROLS = ("none", "higher_order", "penalty", "stress_points", "springs", "ads")


#: default dimensionless coefficient C̃ of the 'springs' and 'ads' controls (family-normalized,
#: :meth:`Correspondence.control_constants`).  Measured on a free-surface 2D bar (61 x 11,
#: δ = h...3h, docs/correspondence.md): springs bias the stiffness by ≈ 1.1 C̃ at any δ/h
#: (0.01: 1.2 %), ADS only near free surfaces (0.03: elongation ≤ 0.11 %, lateral strain
#: ≤ 0.6 %) while keeping the checkerboard energy ratio ≥ 2 (stress points: 3.5-43)
DEFAULT_CONTROL_COEFFICIENT: dict[str, float] = {"springs": 0.01, "ads": 0.03}


#: stress-point cases (Luo & Sundararaghavan (2018), Sec. 3, Fig. 5): sign vector s of SP1's
#: bonds, per dimension
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
    """Return the orthogonal basis of case ``s`` whose projections decide a bond's side."""
    basis = [np.asarray(s, dtype=float)]
    if d >= 2:
        t = np.zeros(d)
        t[0], t[1] = -s[1], s[0]
        basis.append(t)
    if d == 3:
        basis.append(np.cross(basis[0], basis[1]))
    return basis


def _sides(bonds: Bonds, cases: np.ndarray) -> np.ndarray:
    """Return ``(n_cases, nb)`` bool: :func:`_half_space` of every case.

    With numba: bond chunks on the threads.
    """
    xi = bonds.xi
    mod = compiled_kernels() if use_numba(xi.size * cases.shape[0]) else None
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
    """Return, per point, whether both halves of every case are well conditioned and balanced.

    Balanced: ``‖K_1 - K_2‖_F ≤ SP_BALANCE_TOL ‖K‖_F``.

    Per point: in every case (row of ``sides``) both halves' shape tensors are well
    conditioned and *balanced*, ``‖K_1 - K_2‖_F ≤ SP_BALANCE_TOL ‖K‖_F``.

    Balance is a property of the family's geometry: it is tested on the tensors of the
    weights ``omega`` (without volumes) when given, so a lattice with non-uniform volumes
    keeps its two stress points (the scheme of Luo & Sundararaghavan (2018)) while
    truncated families next to free surfaces and irregular clouds get one gradient point.

    The second half's tensor is the full one minus the first's (one pass per case).  Balanced
    halves (``K_1 = K_2 = K/2``: a point-symmetric, complete family) are what makes two
    stress points of weight ``w`` act on a uniform stress exactly like one gradient point of
    weight ``2w`` (``w (K/2)⁻¹ = 2w K⁻¹`` on every bond), hence consistent next to free
    surfaces; unbalanced halves of truncated families are not (measured: 1.1 % patch-test
    error on a free-surface 2D bar at δ = 3h).
    """
    # compact bonds compute these on each access: read them once
    bxi = bonds.xi
    geo = omega_v if omega is None else omega
    mod = compiled_kernels() if use_numba(bxi.size * sides.shape[0]) else None
    if mod is not None and bonds.dim == 2 and bonds.n_points == n:
        # one nogil pass per point chunk on the threads (the same tensors; the decisions
        # compare with tolerances far above round-off)
        ok2 = np.empty(n, dtype=bool)
        bptr = np.asarray(bonds.indptr, dtype=np.int64)
        args = (
            bptr,
            np.ascontiguousarray(bxi, dtype=np.float64),
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
    bi = bonds.i
    full_k = per_point_outer(bi, n, omega_v, bxi, bxi)
    full_g = per_point_outer(bi, n, geo, bxi, bxi)
    scale = np.sqrt(np.einsum("nij,nij->n", full_g, full_g))
    ok = np.ones(n, dtype=bool)
    for side in sides:
        half = per_point_outer(bi, n, np.where(side, omega_v, 0.0), bxi, bxi)
        other = full_k - half
        half_g = per_point_outer(bi, n, np.where(side, geo, 0.0), bxi, bxi)
        diff = 2.0 * half_g - full_g
        balanced = np.sqrt(np.einsum("nij,nij->n", diff, diff)) <= SP_BALANCE_TOL * scale
        ok &= _ratio_ok(half) & _ratio_ok(other) & balanced
    return ok


def unit_axial_modulus(dim: int, plane: str) -> float:
    """Return the axial modulus ``C_1111`` of a bond-based material of unit ``E``.

    Bond-based peridynamics implies ν (1/4 in 3D and plane strain, 1/3 in plane stress,
    :func:`pdlin.implied_poisson_ratio`); the penalty and the surrogate stiffness divide a
    mean axial modulus by this to get the equivalent bond-based ``E``.

    Parameters
    ----------
    dim : {1, 2, 3}
        Spatial dimension.
    plane : {'stress', 'strain'}
        2D assumption.

    Returns
    -------
    float
        ``1`` in 1D, ``1/(1-ν²)`` in plane stress, ``(1-ν)/((1+ν)(1-2ν))`` otherwise.

    Examples
    --------
    >>> unit_axial_modulus(3, "stress")
    1.2
    """
    if dim == 1:
        return 1.0
    nu = implied_poisson_ratio(dim, plane)
    if dim == 2 and plane == "stress":
        return float(1.0 / (1.0 - nu**2))
    return float(1.0 * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu)))


def gradient_points(
    model: Correspondence, cloud: PointCloud, bonds: Bonds
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the gradient points of ``model``: owner, bond owner and weight.

    One gradient point per particle, or with ``control='stress_points'`` two per particle whose
    half families are well conditioned and balanced (Luo & Sundararaghavan (2018), Sec. 3;
    :class:`Correspondence` describes the split and the weights).

    Parameters
    ----------
    model : Correspondence
        The model (its control parameters).
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).

    Returns
    -------
    gp_owner : (n_gp,) ndarray of int
        Particle of each gradient point.
    gp_of_bond : (nb,) ndarray of int
        Gradient point owning each bond.
    weight : (n_gp,) ndarray of float
        Weight ``w_g`` of each gradient point.

    Raises
    ------
    InputError
        ``model.case`` out of range for the dimension.
    """
    n = cloud.n
    if model.control != "stress_points":
        return np.arange(n), bonds.i, np.ones(n)
    d = cloud.dim
    cases = _SP_CASES[d]
    # SP1 of case s owns the bonds with s·ξ > 0 (ties broken by the next vectors of an
    # orthogonal basis); for nearest-neighbour axis bonds this is Luo & Sundararaghavan (2018)'s
    # {s_k e_k} / {-s_k e_k} split, for larger horizons its half-space extension
    first = _sides(bonds, cases)  # (n_cases, nb)
    omega = model.bond_weights(cloud, bonds)
    full = _halves_well_conditioned(bonds, omega * bonds.volume_j, first, n, omega)
    if bonds.n_bonds and not full.any():
        warnings.warn(
            "stress points: no particle has two balanced, well-conditioned half families "
            "(irregular cloud or a body thinner than two horizons); every particle gets one "
            "gradient point and the control is inactive (ordinary correspondence): use "
            "control='penalty' on irregular clouds",
            UserWarning,
            stacklevel=5,
        )
    cases = _SP_CASES[d]
    if model.case is None:
        # one draw per full-horizon particle, in point order (the convention of the
        # paper's random choice per particle, Sec. 3, so seeded results are comparable)
        chosen = np.zeros(n, dtype=np.intp)
        chosen[full] = np.random.default_rng(model.seed).integers(
            0, cases.shape[0], int(full.sum())
        )
    else:
        if not 0 <= model.case < cases.shape[0]:
            raise InputError(f"case must be in [0, {cases.shape[0] - 1}] in {d}D, got {model.case}")
        chosen = np.full(n, model.case)
    n_sp = np.where(full, 2, 1)
    base = np.zeros(n, dtype=np.intp)
    np.cumsum(n_sp[:-1], out=base[1:])
    mod = compiled_kernels() if use_numba(bonds.n_bonds) else None
    if mod is not None:  # point chunks on the threads
        gp_of_bond = np.empty(bonds.n_bonds, dtype=np.intp)
        bptr = np.asarray(bonds.indptr, dtype=np.int64)
        thread_map(
            lambda r: mod.sp_gp_of_bond(r[0], r[1], bptr, base, full, chosen, first, gp_of_bond),
            ptr_chunks(bptr, _gradient._POINT_CHUNK),
        )
    else:
        second = full[bonds.i] & ~first[chosen[bonds.i], np.arange(bonds.n_bonds)]
        gp_of_bond = base[bonds.i] + second
    gp_owner = np.repeat(np.arange(n), n_sp)
    # one-SP weight: w_s for every SP (pdlin's default, see the docs) on the paper's
    # nearest-neighbour families; beyond them a one-SP particle is an ordinary gradient
    # point carrying its whole volume (2 w_s, as its two half-SPs would for a uniform stress)
    single = 1.0 if int(bonds.family_size.max(initial=0)) <= 2 * d else 2.0
    weight = np.where(np.repeat(full, n_sp), 1.0, single) * model.sp_weight
    return gp_owner, gp_of_bond, weight


def penalty_bond_stiffness(
    model: Correspondence, cloud: PointCloud, bonds: Bonds, p: _Plan
) -> np.ndarray:
    """Return the penalty stiffness per bond, ``½ penalty k_b`` (0 on energy-free owners).

    Parameters
    ----------
    model : Correspondence
        The model (its control parameters).
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).
    p : _Plan
        The model's assembly plan on ``(cloud, bonds)``.

    Returns
    -------
    (nb,) ndarray of float
        Zero on bonds of energy-free (shadow) owners.
    """
    d = cloud.dim
    Cv = model.voigt_stiffness(cloud)
    axial = np.einsum("nkk->n", Cv[:, :d, :d]) / d
    e_eq = axial / unit_axial_modulus(d, model.plane)
    bb = BondBased(E=e_eq, plane=model.plane)
    k = 0.5 * model.penalty * bb.bond_stiffness(cloud, dataclasses.replace(bonds, omega=p.omega))
    return k * p.energy[bonds.i]


def penalty_force(
    cloud: PointCloud, bonds: Bonds, p: _Plan, k: np.ndarray, x: np.ndarray
) -> np.ndarray:
    """Return the penalty force ``Zᵀ(k z)`` of a displacement, matrix-free.

    ``Zᵀ(k z)`` with ``z_b = u_j - u_i - ∇u_g ξ_b``, matrix-free, ``(n*d,)``.

    Parameters
    ----------
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).
    p : _Plan
        The model's assembly plan on ``(cloud, bonds)``.
    k : (nb,) ndarray of float
        Penalty stiffness per bond (:func:`penalty_bond_stiffness`).
    x : (n*d,) ndarray of float
        Displacement, flat.

    Returns
    -------
    (n*d,) ndarray of float
        ``Zᵀ(k z)`` with ``z_b = u_j - u_i - ∇u_g ξ_b``.
    """
    d, n = cloud.dim, cloud.n
    u = x.reshape(n, d)
    grad = (p.G @ x).reshape(-1, d, d)
    z = u[bonds.j] - u[bonds.i] - np.einsum("bij,bj->bi", grad[p.gp_of_bond], bonds.xi)
    kz = k[:, None] * z
    out = np.empty((n, d))
    for a in range(d):
        out[:, a] = np.bincount(bonds.j, weights=kz[:, a], minlength=n) - np.bincount(
            bonds.i, weights=kz[:, a], minlength=n
        )
    # -Gᵀ Xᵀ(k z): per gradient point (g, i, q): Σ_b k z_i ξ_q
    ngp = p.gp_owner.size
    t = np.empty((ngp, d, d))
    xi = bonds.xi  # once (a compact Bonds computes it on each access)
    for a in range(d):
        for q in range(d):
            t[:, a, q] = np.bincount(p.gp_of_bond, weights=kz[:, a] * xi[:, q], minlength=ngp)
    return out.ravel() - np.asarray(p.G.T @ t.ravel())


def penalty_matrix(
    model: Correspondence, cloud: PointCloud, bonds: Bonds, p: _Plan
) -> sp.bsr_array:
    """Return the assembled penalty stiffness ``Zᵀ diag(k) Z``.

    ``Zᵀ diag(k) Z`` with ``Z = Z_s ⊗ I_d`` (BSR, d x d blocks).

    ``z_b = u_j - u_i - ∇u_g ξ_b`` and the G block of (g, point p) is ``I_d ⊗ c_gp``, so
    every block of Z is a multiple of ``I_d`` and ``Z_s = E - X G_s``: ``E`` the bond
    incidence (``e_j - e_i``), ``X`` puts ``ξ_b`` in the row of the bond's gradient point,
    ``G_s`` the scalar gradient (rows ``(g, q)``, block values ``c_gp``).  Expanded,

    ``Z_sᵀ k Z_s = Eᵀ k E + T + Tᵀ``, ``T = G_sᵀ U``, ``U = ½ M G_s - Xᵀ k E``,

    with ``M = Xᵀ k X = blockdiag_g(Σ_b k_b ξ_b ξ_bᵀ)``; ``U`` has the block pattern of
    ``G_s``.  The product ``G_sᵀ U`` costs ``n_gp d m²`` multiply-adds for ``m`` family
    members, ``Rᵀ R`` with ``R = √k Z_s`` would cost ``n_b m² = n_gp m³`` (6x more at 2D
    δ = 2h, 40x at 3D δ = 3h).  ``T + Tᵀ`` and ``Eᵀ k E = (√k E)ᵀ(√k E)`` are bitwise
    symmetric, so is the sum.

    Parameters
    ----------
    model : Correspondence
        The model (its control parameters).
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).
    p : _Plan
        The model's assembly plan on ``(cloud, bonds)``.

    Returns
    -------
    scipy.sparse.bsr_array
        ``(n*d, n*d)``, blocks ``(d, d)``, bitwise symmetric.
    """
    d, n = cloud.dim, cloud.n
    k = model._penalty_k(cloud, bonds, p)
    blk = p.blocks
    g = p.gp_of_bond
    nb = g.size
    n_gp = blk.indptr.size - 1
    nblk = blk.col.size
    xi = bonds.xi  # once (a compact Bonds computes it on each access)
    kx = k[:, None] * xi
    # M_g = Σ_b k_b ξ_b ξ_bᵀ; U block (g, p) = ½ M_g c_gp - Σ_{b: j_b = p} k_b ξ_b
    # (+ Σ_b k_b ξ_b on the owner's block)
    M = np.empty((n_gp, d, d))
    for q in range(d):
        for r in range(q, d):
            M[:, q, r] = M[:, r, q] = np.bincount(g, weights=kx[:, q] * xi[:, r], minlength=n_gp)
    U = np.einsum("bqr,br->bq", M[blk.row], blk.val)
    U *= 0.5
    for q in range(d):
        U[:, q] -= np.bincount(blk.bond_block, weights=kx[:, q], minlength=nblk)
        U[blk.owner_block, q] += np.bincount(g, weights=kx[:, q], minlength=n_gp)
    shape = (n_gp * d, n)
    Gs = sp.bsr_array((blk.val[:, :, None], blk.col, blk.indptr), shape=shape, blocksize=(d, 1))
    Us = sp.bsr_array((U[:, :, None], blk.col, blk.indptr), shape=shape, blocksize=(d, 1))
    T = sp.csr_array(sp.csr_array(Gs).T @ sp.csr_array(Us))
    # √k E: +√k at j_b, -√k at the owner (k ≥ 0: bond_stiffness rejects signed weights)
    sk = np.sqrt(k)
    Ek = sp.csr_array(
        (
            np.stack([sk, -sk], 1).ravel(),
            np.stack([blk.col[blk.bond_block], p.gp_owner[g]], 1).ravel(),
            np.arange(0, 2 * nb + 1, 2),
        ),
        shape=(nb, n),
    )
    Ks = sp.csr_array(Ek.T @ Ek + (T + T.T))
    Ks.sum_duplicates()
    blocks = Ks.data[:, None, None] * np.eye(d)
    return sp.bsr_array((blocks, Ks.indices, Ks.indptr), shape=(n * d, n * d), blocksize=(d, d))


def control_constants(model: Correspondence, cloud: PointCloud, bonds: Bonds) -> dict[str, float]:
    """Return the constants of the springs / ADS control forces of ``model``.

    See :meth:`Correspondence.control_constants` for their meaning
    (Luo & Sundararaghavan (2018), Eqs. 7-8, normalized by the family).

    Parameters
    ----------
    model : Correspondence
        The model (its control parameters).
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).

    Returns
    -------
    dict of str -> float
        ``coefficient``, ``E_ref``, ``V_ref``, ``h_ref``, ``S_ref``, ``Omega_ref``, ``C1``, ``C2``.

    Raises
    ------
    ModelError
        No bonds, or non-positive family moments.
    """
    d = cloud.dim
    Cv = model.voigt_stiffness(cloud)
    e_ref = float(np.max(np.einsum("nkk->n", Cv[:, :d, :d]) / d))
    vol = np.asarray(cloud.volumes, dtype=float) * (1.0 if d == 3 else cloud.thickness)
    v_ref = float(np.mean(vol))
    shortest = np.full(cloud.n, np.inf)
    np.minimum.at(shortest, bonds.i, bonds.length)
    has = np.isfinite(shortest)
    if not has.any():
        raise ModelError("springs/ADS controls need bonds, got a cloud without any")
    h_ref = float(np.mean(shortest[has]))
    wv = model.bond_weights(cloud, bonds) * vol[bonds.j]
    s_ref = float(np.max(np.bincount(bonds.i, weights=wv * bonds.length**2, minlength=cloud.n)))
    o_ref = float(np.max(np.bincount(bonds.i, weights=wv, minlength=cloud.n)))
    if not (s_ref > 0 and o_ref > 0):
        raise ModelError(
            "springs/ADS controls need positive family moments Σ ω V_j |ξ|², Σ ω V_j, "
            f"got {s_ref:.3g}, {o_ref:.3g}"
        )
    c = model.coefficient
    return {
        "coefficient": c,
        "E_ref": e_ref,
        "V_ref": v_ref,
        "h_ref": h_ref,
        "S_ref": s_ref,
        "Omega_ref": o_ref,
        "C1": d * c * e_ref / s_ref,
        "C2": 4.0 * d * d * c * e_ref / (s_ref * o_ref),
    }


def laplacian(
    cloud: PointCloud, bonds: Bonds, w: np.ndarray, rows: np.ndarray | None = None
) -> sp.csr_array:
    """Return the weighted graph Laplacian of the bonds, ⊗ I_d.

    ``(Lap_w u)_i = Σ_b w_b (u_i - u_j)`` over the bonds of i.

    Parameters
    ----------
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).
    w : (nb,) ndarray of float
        Bond weights.
    rows : (n,) ndarray of bool, optional
        Keep only the bonds of these owners (default: all).

    Returns
    -------
    scipy.sparse.csr_array
        ``(n*d, n*d)``.
    """
    n, d = cloud.n, cloud.dim
    i, j = bonds.i, bonds.j
    if rows is not None:
        keep = rows[i]
        i, j, w = i[keep], j[keep], w[keep]
    L = sp.coo_array(
        (np.concatenate([w, -w]), (np.concatenate([i, i]), np.concatenate([i, j]))),
        shape=(n, n),
    ).tocsr()
    return sp.csr_array(sp.kron(L, sp.eye_array(d), format="csr"))


def control_factors(
    model: Correspondence, cloud: PointCloud, bonds: Bonds, p: _Plan
) -> tuple[sp.csr_array, sp.csr_array] | None:
    """Return the springs / ADS stiffness as a product ``S @ N`` of one-hop matrices.

    Springs: ``S = Σ_b C1 ω V_i V_j (e_i - e_j)(e_i - e_j)ᵀ ⊗ I``, ``N = I``
    (every bond, shadow ones too).  ADS: ``S = C2 diag(V) Lap_V``,
    ``N = Lap_ωV`` with the rows of shadow particles zeroed (their
    averaged displacement state is that of the affine continuation, 0).

    Parameters
    ----------
    model : Correspondence
        The model (its control parameters).
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).
    p : _Plan
        The model's assembly plan on ``(cloud, bonds)``.

    Returns
    -------
    tuple of two scipy.sparse.csr_array or None
        ``(S, N)``, each ``(n*d, n*d)``; None for the other controls or a zero coefficient.
    """
    if model.control not in ("springs", "ads") or model.coefficient == 0:
        return None
    d = cloud.dim
    c = model.control_constants(cloud, bonds)
    vol = np.asarray(cloud.volumes, dtype=float) * (1.0 if d == 3 else cloud.thickness)
    vi, vj = vol[bonds.i], vol[bonds.j]
    nd = cloud.n * d
    if model.control == "springs":
        k = c["C1"] * p.omega * vi * vj
        i, j = bonds.i, bonds.j
        Ls = sp.coo_array(
            (np.concatenate([k, k, -k, -k]),
             (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))),
            shape=(cloud.n, cloud.n),
        ).tocsr()  # fmt: skip
        S = sp.csr_array(sp.kron(Ls, sp.eye_array(d), format="csr"))
        return S, sp.csr_array(sp.eye_array(nd, format="csr"))
    S = laplacian(cloud, bonds, c["C2"] * vi * vj)  # diag(V) Lap_V, symmetric
    rows = None
    if model.shadow is not None:
        rows = np.ones(cloud.n, dtype=bool)
        rows[model.shadow] = False
    N = laplacian(cloud, bonds, p.omega * vj, rows)
    return S, N
