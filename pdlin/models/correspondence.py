"""Correspondence (non-ordinary state-based) peridynamics on sparse operators.

The model is linear small strain (spec 000 §8, spec 003 §2): a nonlocal
displacement gradient per *gradient point* (a particle, or a stress point
of a particle), ``∇u_g = Σ_b (u_b - u_a) ⊗ c_gb`` with
``c_gb = ω_ab V_b K_g⁻¹ ξ_ab`` (spec 000 §3), Cauchy stress
``σ_g = C_a : ε_g`` used in place of ``P``, and the energy
``Π = ½ Σ_g w_g V_a ε_g : C_a : ε_g``.  The stiffness is therefore

``K = Gᵀ blockdiag(w_g V_a C_a) G``

with ``G`` the sparse gradient operator (``n_gp·d²`` x ``n·d``); it is
symmetric PSD for any sign of the weights.  Zero-energy-mode controls:
``'none'``, ``'higher_order'`` (spec 000), ``'penalty'`` (a bond-based
penalty on the non-affine part of each bond), ``'stress_points'``
(spec 003 §4) and the baseline control forces ``'springs'`` and
``'ads'`` (averaged displacement state, spec 003 §3).  See
``docs/correspondence.md``.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._kernels import _kernels, bsr_matmul, bsr_transpose, use_numba
from .._threads import even_chunks, ptr_chunks, thread_map
from .._validation import as_displacement, as_float_array, check_finite, integer
from ..constitutive import check_stiffness, isotropic, isotropic_2d, plane_strain, plane_stress
from ..constitutive.tensors import _mandel_weights, _pairs
from ..errors import InputError, InputTypeError, ModelError, ShapeError
from ..fields import _per_point_outer
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from ._state import uniform_nu_constants
from .base import Model, Response
from .bond_based import BondBased, _c1111

__all__ = [
    "Correspondence",
    "CONTROLS",
    "gradient_operator",
    "voigt_projector",
    "intact_shape_tensor",
    "shadow_real_counts",
    "shadow_problem",
    "solve_matrix_free",
]

log = logging.getLogger(__name__)

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


def _coefficients_2d_fused(
    mod: Any,
    ptrs: tuple[np.ndarray, np.ndarray],
    owner_b: np.ndarray,
    n_gp: int,
    w: np.ndarray,
    xi: np.ndarray,
) -> np.ndarray:
    """:func:`_coefficients` in 2D as one numba pass per point chunk (shape tensors, their
    inverses and the coefficients; the numpy path's arithmetic and error)."""
    bptr, gptr = ptrs
    K = np.empty((n_gp, 2, 2))
    bad = np.empty(n_gp, dtype=bool)
    out = np.empty_like(xi, dtype=np.float64)
    args = (
        bptr,
        gptr,
        np.ascontiguousarray(owner_b, dtype=np.int64),
        np.ascontiguousarray(w, dtype=np.float64),
        np.ascontiguousarray(xi, dtype=np.float64),
        K,
        bad,
        out,
    )
    kern = mod.coefficients_2d_fill
    thread_map(lambda r: kern(r[0], r[1], *args), ptr_chunks(bptr, _POINT_CHUNK))
    if bad.any():
        _raise_singular(np.flatnonzero(bad), 2)
    return out


def _raise_singular(bad: np.ndarray, d: int) -> None:
    raise ModelError(
        f"shape tensor must be invertible at every gradient point, got {bad.size} singular "
        f"one(s) (first: gradient point {int(bad[0])}); its bonds do not span {d}D "
        "(isolated points, one-point-wide strips, or weights with Ω = 0)"
    )


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
        lambda r: kern(r[0], r[1], xi_c, basis, vnorm, out), even_chunks(xi.shape[0], _ROW_CHUNK)
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


def _check_stiffness_per_point(arr: np.ndarray) -> None:
    """Validate per-point Voigt stiffnesses ``(n, nv, nv)``: every distinct one, batched.

    The first failing point is re-checked by :func:`check_stiffness` for its message.
    """
    n, nv, _ = arr.shape
    flat = arr.reshape(n, -1)
    uniq, first = np.unique(flat, axis=0, return_index=True)
    U = uniq.reshape(-1, nv, nv)
    scale = np.maximum(np.abs(U).max(axis=(1, 2)), np.finfo(float).tiny)
    bad = ~np.isfinite(U).all(axis=(1, 2))
    bad |= np.abs(U - U.transpose(0, 2, 1)).max(axis=(1, 2)) > 1e-12 * scale
    w = _mandel_weights(2 if nv == 3 else 3) if nv > 1 else np.ones(1)
    ok = ~bad
    eig = np.linalg.eigvalsh(U[ok] * np.outer(w, w))
    tol = 1e-13 * np.maximum(np.abs(eig).max(axis=1), np.finfo(float).tiny)
    bad[np.flatnonzero(ok)[eig[:, 0] <= tol]] = True
    if bad.any():
        k = int(first[np.flatnonzero(bad)].min())
        if nv == 1:
            raise InputError(f"C[{k}] must be a positive scalar in 1D, got {arr[k, 0, 0]!r}")
        check_stiffness(arr[k], f"C[{k}]")  # raises with the specific reason
        raise InputError(f"C[{k}] must be a symmetric positive definite Voigt stiffness")


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
        thread_map(lambda r: kern(r[0], r[1], *args), ptr_chunks(bptr, _POINT_CHUNK))
        return ok2
    full_k = _per_point_outer(bonds.i, n, omega_v, bonds.xi, bonds.xi)
    full_g = _per_point_outer(bonds.i, n, geo, bonds.xi, bonds.xi)
    scale = np.sqrt(np.einsum("nij,nij->n", full_g, full_g))
    ok = np.ones(n, dtype=bool)
    for side in sides:
        half = _per_point_outer(bonds.i, n, np.where(side, omega_v, 0.0), bonds.xi, bonds.xi)
        other = full_k - half
        half_g = _per_point_outer(bonds.i, n, np.where(side, geo, 0.0), bonds.xi, bonds.xi)
        diff = 2.0 * half_g - full_g
        balanced = np.sqrt(np.einsum("nij,nij->n", diff, diff)) <= SP_BALANCE_TOL * scale
        ok &= _ratio_ok(half) & _ratio_ok(other) & balanced
    return ok


#: default byte budget of an assembled K (beyond it :meth:`Correspondence.plan`
#: chooses the matrix-free operator)
DEFAULT_MAX_BYTES = 4 * 1024**3


# ---------------------------------------------------------------------------
# operators


def voigt_projector(dim: int) -> np.ndarray:
    """Map ``vec(∇u)`` (row-major ``(i, j)`` → ``d*i + j``) to Voigt strain.

    Engineering shear: 2D ``[ε11, ε22, γ12]``, 3D
    ``[ε11, ε22, ε33, γ23, γ13, γ12]`` (the order of
    :mod:`pdlin.constitutive`).  ``Pᵀ C P`` is the full tensor ``C_ijkl``
    acting on ``vec(∇u)``.

    Examples
    --------
    >>> voigt_projector(2).tolist()
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 1.0, 1.0, 0.0]]
    """
    pairs = {1: ((0, 0),), 2: ((0, 0), (1, 1), (0, 1)),
             3: ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))}  # fmt: skip
    if dim not in pairs:
        raise InputError(f"dim must be 1, 2 or 3, got {dim}")
    P = np.zeros((len(pairs[dim]), dim * dim))
    for a, (i, j) in enumerate(pairs[dim]):
        P[a, dim * i + j] = 1.0
        P[a, dim * j + i] = 1.0
    return P


def _coefficients(
    owner_b: np.ndarray,
    n_gp: int,
    omega: np.ndarray,
    volume_j: np.ndarray,
    xi: np.ndarray,
    kinv_override: Mapping[int, np.ndarray] | None = None,
    override_rows: np.ndarray | None = None,
    override_kinv: np.ndarray | None = None,
    ptrs: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Bond coefficients ``c_b = ω V_j K_g⁻¹ ξ`` (nb, d); K_g from the gradient point's bonds.

    ``ptrs = (bptr, gptr)``: point ``p`` owns the bonds ``bptr[p]:bptr[p+1]`` and the
    gradient points ``gptr[p]:gptr[p+1]`` of those bonds (no control, stress points): the
    shape tensors are then summed over point chunks on the threads without a pass to find
    them, and in 2D with numba tensors, inverses and coefficients are one pass.
    """
    d = xi.shape[1]
    w = omega * volume_j
    mod = _kernels() if ptrs is not None and use_numba(xi.size) else None
    if mod is not None and ptrs is not None and d == 2 and override_rows is None:
        return _coefficients_2d_fused(mod, ptrs, owner_b, n_gp, w, xi)
    K = _per_point_outer(owner_b, n_gp, w, xi, xi, runs=ptrs)  # pdlin.fields' shape tensor
    if override_rows is not None and override_rows.size:
        assert override_kinv is not None
        K[override_rows] = np.linalg.inv(override_kinv)
    tr = np.abs(np.einsum("nii->n", K))
    if d == 2:  # closed form (batched 2 x 2 LAPACK calls cost ~10x more)
        det = K[:, 0, 0] * K[:, 1, 1] - K[:, 0, 1] * K[:, 1, 0]
    else:
        det = np.linalg.det(K)
    bad = np.flatnonzero(~(np.abs(det) > 1e-12 * np.maximum(tr / d, 1e-300) ** d))
    if bad.size:
        _raise_singular(bad, d)
    if d == 2:  # adjugate / det (as accurate as LU for 2 x 2)
        Kinv = np.empty_like(K)
        Kinv[:, 0, 0] = K[:, 1, 1]
        Kinv[:, 1, 1] = K[:, 0, 0]
        Kinv[:, 0, 1] = -K[:, 0, 1]
        Kinv[:, 1, 0] = -K[:, 1, 0]
        Kinv /= det[:, None, None]
    else:
        Kinv = np.linalg.inv(K)
    if override_rows is not None and override_rows.size:
        Kinv[override_rows] = override_kinv
    Kinv = np.ascontiguousarray(Kinv, dtype=np.float64)
    out = np.empty_like(xi)
    mod = _kernels() if use_numba(xi.size) else None
    if mod is not None:  # one nogil pass per bond chunk, the numpy path's arithmetic
        kern = mod.bond_coefficients_fill
        own_c = np.ascontiguousarray(owner_b, dtype=np.int64)
        xi_c = np.ascontiguousarray(xi, dtype=np.float64)
        w_c = np.ascontiguousarray(w, dtype=np.float64)

        def fused(rng: tuple[int, int]) -> None:
            kern(rng[0], rng[1], own_c, w_c, xi_c, Kinv, out)

        thread_map(fused, even_chunks(xi.shape[0], _ROW_CHUNK))
        return out
    cols = [np.ascontiguousarray(Kinv[:, :, q]) for q in range(d)]

    def chunk(rng: tuple[int, int]) -> None:  # fixed bond chunks on the threads (elementwise)
        b0, b1 = rng
        own = owner_b[b0:b1]
        c = np.zeros((b1 - b0, d))
        for q in range(d):  # Σ_q K⁻¹[:, q] ξ_q, gathered per component (no batched einsum)
            c += cols[q][own] * xi[b0:b1, q : q + 1]
        np.multiply(w[b0:b1, None], c, out=out[b0:b1])

    thread_map(chunk, even_chunks(xi.shape[0], _ROW_CHUNK))
    return out


@dataclasses.dataclass(frozen=True)
class _GradientBlocks:
    """G by (gradient point, point) blocks: block ``(g, col)`` is ``I_d ⊗ val`` (d² x d).

    Blocks of a gradient point are contiguous (``indptr``) and sorted by point; the
    owner's block (``diag``) holds ``-Σ c`` (zero on intact horizons).
    """

    indptr: np.ndarray  # (n_gp + 1,)
    col: np.ndarray  # (nblk,) point of each block
    val: np.ndarray  # (nblk, d) coefficient vector
    diag: np.ndarray  # (nblk,) bool: owner's block, no bond in it
    bond_block: np.ndarray  # (nb,) block holding each bond's (g, j)
    owner_block: np.ndarray  # (n_gp,) block of each gradient point's owner

    @property
    def row(self) -> np.ndarray:
        """Gradient point of each block, ``(nblk,)``."""
        return np.repeat(np.arange(self.indptr.size - 1), np.diff(self.indptr))


def _gradient_blocks(
    gp_owner: np.ndarray,
    gp_of_bond: np.ndarray,
    j: np.ndarray,
    c: np.ndarray,
    n_points: int,
    ptrs: tuple[np.ndarray, np.ndarray] | None = None,
) -> _GradientBlocks:
    """Block structure of G from bond coefficients; round-off diagonals snapped to 0.

    One sort of the ``(g, point)`` keys (bonds and owners together); repeated pairs
    (periodic images of one point in a small lattice) are summed.
    """
    d = c.shape[1]
    n_gp = gp_owner.size
    fast = _fused_blocks(gp_owner, gp_of_bond, j, c, n_points, ptrs)
    if fast is None:
        fast = _owner_sorted_blocks(gp_owner, gp_of_bond, j, c, n_points)
    if fast is not None:
        return fast
    # diagonal -Σ_b c_gb per gradient point; exact zero on intact (symmetric) horizons
    diag = np.empty((n_gp, d))
    scale = np.empty((n_gp, d))
    for q in range(d):
        diag[:, q] = -np.bincount(gp_of_bond, weights=c[:, q], minlength=n_gp)
        scale[:, q] = np.bincount(gp_of_bond, weights=np.abs(c[:, q]), minlength=n_gp)
    diag[np.abs(diag) <= 64 * np.finfo(float).eps * scale] = 0.0
    keys = np.concatenate(
        [
            gp_of_bond.astype(np.int64) * n_points + j,
            np.arange(n_gp, dtype=np.int64) * n_points + gp_owner,
        ]
    )
    vals = np.concatenate([c, diag])
    is_diag = np.concatenate([np.zeros(j.size, dtype=bool), np.ones(n_gp, dtype=bool)])
    order = np.argsort(keys, kind="stable")
    keys = keys[order]
    vals = vals[order]
    is_diag = is_diag[order]
    first = np.ones(keys.size, dtype=bool)
    first[1:] = keys[1:] != keys[:-1]
    block_of = np.empty(keys.size, dtype=np.int64)  # block of each input entry
    block_of[order] = np.cumsum(first) - 1
    if not first.all():  # repeated (g, point) pairs: sum them
        starts = np.flatnonzero(first)
        vals = np.add.reduceat(vals, starts, axis=0)
        is_diag = np.logical_and.reduceat(is_diag, starts)
        keys = keys[starts]
    g = keys // n_points
    indptr = np.zeros(n_gp + 1, dtype=np.int64)
    np.cumsum(np.bincount(g, minlength=n_gp), out=indptr[1:])
    nb = j.size
    return _GradientBlocks(indptr, keys - g * n_points, vals, is_diag, block_of[:nb], block_of[nb:])


def _fused_blocks(
    gp_owner: np.ndarray,
    gp_of_bond: np.ndarray,
    j: np.ndarray,
    c: np.ndarray,
    n_points: int,
    ptrs: tuple[np.ndarray, np.ndarray] | None = None,
) -> _GradientBlocks | None:
    """The blocks of :func:`_gradient_blocks` in one numba pass per point chunk, when each
    point owns consecutive gradient points and the bonds of those gradient points in the
    :class:`Bonds` order (no control, stress points): None otherwise (or without numba).

    A gradient point's blocks are its bonds in order (increasing, distinct neighbours,
    none the owner) with the owner's block among them: their slots are known from the
    counts, so point chunks write them on the threads (``np.bincount``, which the sorting
    path sums with, holds the GIL); the sums run over the same bonds in the same order:
    the same arrays bitwise.
    """
    n_gp, nb, d = gp_owner.size, j.size, c.shape[1]
    mod = _kernels() if use_numba(nb * d) else None
    if mod is None or n_gp == 0:
        return None
    if ptrs is not None:  # the structure is known (see _coefficients)
        bptr, gptr = ptrs
    else:
        if not bool(np.all(gp_owner[1:] >= gp_owner[:-1])):
            return None
        own_b = gp_owner[gp_of_bond]  # point of each bond
        if not bool(np.all(own_b[1:] >= own_b[:-1])):
            return None
        pts = np.arange(n_points + 1)
        gptr = np.searchsorted(gp_owner, pts).astype(np.int64)
        bptr = np.searchsorted(own_b, pts).astype(np.int64)
    per_gp = np.bincount(gp_of_bond, minlength=n_gp)
    indptr = np.zeros(n_gp + 1, dtype=np.int64)
    np.cumsum(per_gp + 1, out=indptr[1:])
    nblk = int(indptr[-1])
    col = np.empty(nblk, dtype=np.int64)
    val = np.empty((nblk, d))
    is_diag = np.empty(nblk, dtype=bool)
    bond_block = np.empty(nb, dtype=np.int64)
    owner_block = np.empty(n_gp, dtype=np.int64)
    kern = mod.gradient_blocks_fill
    gob = np.ascontiguousarray(gp_of_bond, dtype=np.int64)
    jc = np.ascontiguousarray(j, dtype=np.int64)
    cc = np.ascontiguousarray(c, dtype=np.float64)
    tiny = 64 * np.finfo(float).eps
    layout_ok = np.empty(n_points, dtype=bool)

    def chunk(rng: tuple[int, int]) -> None:
        kern(
            rng[0], rng[1], bptr, gptr, gob, jc, cc, indptr, col, val, is_diag, bond_block,
            owner_block, tiny, layout_ok,
        )  # fmt: skip

    thread_map(chunk, ptr_chunks(bptr, _POINT_CHUNK))
    if not layout_ok.all():  # repeated neighbours (periodic images) or a bond to itself
        return None
    return _GradientBlocks(indptr, col, val, is_diag, bond_block, owner_block)


def _owner_sorted_blocks(
    gp_owner: np.ndarray, gp_of_bond: np.ndarray, j: np.ndarray, c: np.ndarray, n_points: int
) -> _GradientBlocks | None:
    """The blocks of :func:`_gradient_blocks` without its sort, when one gradient point per
    point owns that point's bonds in the :class:`Bonds` order (no control): None otherwise.

    Block slots are known (bond ``b`` of point ``g``: ``b + g + [j_b > g]``; the owner's
    block after its smaller neighbours), so fixed point chunks write them on the threads;
    each per-point sum runs over the same bonds in the same order as the sorting path's
    ``np.bincount``: the same arrays bitwise.
    """
    n_gp, nb, d = gp_owner.size, j.size, c.shape[1]
    if n_gp != n_points or nb == 0 or not np.array_equal(gp_owner, np.arange(n_gp)):
        return None
    g = gp_of_bond
    if not bool(np.all(g[1:] >= g[:-1])) or bool(np.any(j == g)):
        return None
    if not bool(np.all((j[1:] > j[:-1]) | (g[1:] != g[:-1]))):
        return None
    bptr = np.zeros(n_gp + 1, dtype=np.int64)
    np.cumsum(np.bincount(g, minlength=n_gp), out=bptr[1:])
    nblk = nb + n_gp
    col = np.empty(nblk, dtype=np.int64)
    val = np.empty((nblk, d))
    is_diag = np.zeros(nblk, dtype=bool)
    bond_block = np.empty(nb, dtype=np.int64)
    owner_block = np.empty(n_gp, dtype=np.int64)
    tiny = 64 * np.finfo(float).eps

    def chunk(rng: tuple[int, int]) -> None:
        p0, p1 = rng
        b0, b1 = int(bptr[p0]), int(bptr[p1])
        own, nbr = g[b0:b1], j[b0:b1]
        pos = np.arange(b0, b1) + own + (nbr > own)
        bond_block[b0:b1] = pos
        col[pos] = nbr
        val[pos] = c[b0:b1]
        loc = own - p0
        pts = np.arange(p0, p1)
        dpos = bptr[p0:p1] + pts + np.bincount(loc[nbr < own], minlength=p1 - p0)
        owner_block[p0:p1] = dpos
        col[dpos] = pts
        is_diag[dpos] = True
        for q in range(d):
            dq = -np.bincount(loc, weights=c[b0:b1, q], minlength=p1 - p0)
            sq = np.bincount(loc, weights=np.abs(c[b0:b1, q]), minlength=p1 - p0)
            dq[np.abs(dq) <= tiny * sq] = 0.0
            val[dpos, q] = dq

    step = 1 << 16
    starts = g[np.arange(step, nb, step)]
    edges = np.unique(np.concatenate([[0], starts, [n_gp]]))
    thread_map(chunk, list(zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True)))
    indptr = bptr + np.arange(n_gp + 1)
    return _GradientBlocks(indptr, col, val, is_diag, bond_block, owner_block)


def _blocks_to_csr(blk: _GradientBlocks, n_points: int) -> sp.csr_array:
    """G in CSR, rows ``(g, i, q)``: the nonzero coefficients only.

    Exact zeros are dropped: the owner's entries of a symmetric family, and the components
    of bond coefficients ``c_gp`` that vanish — at δ = h on a grid half of them (an axial
    bond's coefficient has no transverse component), so keeping them doubled the work of
    every ``G u`` and ``Gᵀ s`` (the sums are the same without them)."""
    d = blk.val.shape[1]
    n_gp = blk.indptr.size - 1
    counts = np.diff(blk.indptr)
    g = blk.row
    pos = np.arange(g.size) - blk.indptr[g]
    iq = np.arange(d * d).reshape(1, d, d)  # i*d + q
    # full layout: row (g, i, q) holds all blocks of g in order
    off = (
        (d * d * blk.indptr[g])[:, None, None] + iq * counts[g][:, None, None] + pos[:, None, None]
    )
    n_full = int(d * d * blk.indptr[-1])
    data = np.empty(n_full)
    data[off] = np.broadcast_to(blk.val[:, None, :], off.shape)
    idx_dtype = np.int32 if max(n_full, n_points * d) < np.iinfo(np.int32).max else np.int64
    indices = np.empty(n_full, dtype=idx_dtype)
    comp = np.arange(d)
    indices[off] = np.broadcast_to((blk.col[:, None] * d + comp)[:, :, None], off.shape)
    drop_bq = blk.val == 0.0  # (nblk, q): zero coefficients (every i)
    lengths = np.repeat(counts, d * d)
    if drop_bq.any():
        keep = np.ones(n_full, dtype=bool)
        keep[off[np.broadcast_to(drop_bq[:, None, :], off.shape)]] = False
        data, indices = data[keep], indices[keep]
        b, q = np.nonzero(drop_bq)
        rows = ((g[b][:, None] * d + comp) * d + q[:, None]).ravel()  # every i
        lengths = lengths - np.bincount(rows, minlength=n_gp * d * d)
    indptr = np.zeros(n_gp * d * d + 1, dtype=idx_dtype)
    np.cumsum(lengths, out=indptr[1:])
    return sp.csr_array((data, indices, indptr), shape=(n_gp * d * d, n_points * d))


def _gradient_csr(
    gp_owner: np.ndarray,
    gp_of_bond: np.ndarray,
    j: np.ndarray,
    c: np.ndarray,
    n_points: int,
) -> sp.csr_array:
    """Assemble G (n_gp·d² x n·d) from bond coefficients; round-off diagonals snapped to 0."""
    return _blocks_to_csr(_gradient_blocks(gp_owner, gp_of_bond, j, c, n_points), n_points)


def gradient_operator(
    cloud: PointCloud, bonds: Bonds, omega: np.ndarray | None = None
) -> sp.csr_array:
    """Sparse nonlocal gradient ``G``: ``(G @ u.ravel()).reshape(n, d, d) = ∇u``.

    ``G_j[a, b] = c_ab,j`` and ``G_j[a, a] = -Σ_b c_ab,j`` with
    ``c_ab = ω_ab V_b K_a⁻¹ ξ_ab`` (spec 000 §3); rows are ordered
    ``(a, i, j)`` for ``∂u_i/∂X_j`` and columns are interleaved DOFs.
    ``G u`` equals ``pdlin.deformation_gradient(cloud, bonds, u) - I``, so it
    is exact for affine fields wherever ``K_a`` is invertible.  Diagonals
    that vanish up to round-off (intact horizons) are stored as exact zeros.

    Parameters
    ----------
    cloud : PointCloud
    bonds : Bonds
    omega : (nb,) array_like, optional
        Weights replacing ``bonds.omega`` (may be negative, e.g. the
        higher-order sets of spec 000).

    Returns
    -------
    scipy.sparse.csr_array of shape (n*d*d, n*d)

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((5, 4), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=2.0)
    >>> G = gradient_operator(cloud, bonds)
    >>> H = np.array([[1e-3, 2e-3], [-4e-3, 5e-4]])
    >>> grad = (G @ (cloud.points @ H.T).ravel()).reshape(cloud.n, 2, 2)
    >>> bool(np.allclose(grad, H, atol=1e-14))
    True
    """
    om = bonds.omega if omega is None else as_float_array(omega, "omega")
    if om.shape != (bonds.n_bonds,):
        raise ShapeError(f"omega must have shape ({bonds.n_bonds},), got {om.shape}")
    c = _coefficients(bonds.i, cloud.n, om, bonds.volume_j, bonds.xi)
    return _gradient_csr(np.arange(cloud.n), bonds.i, bonds.j, c, cloud.n)


def intact_shape_tensor(cloud: PointCloud, bonds: Bonds, omega_fn: Any) -> np.ndarray:
    """Shape tensor of a complete lattice horizon, ``(d, d)``.

    Built from the integer stencil ``|p h| <= δ`` of a :func:`pdlin.grid`
    cloud with uniform spacing, volume and horizon; ``omega_fn(length,
    horizon)`` gives the weights.  Shadow particles use it (spec 000 §7).
    """
    lat = cloud.lattice
    if lat is None:
        raise ModelError("a shadow layer needs a pdlin.grid cloud (lattice metadata), got none")
    hs = np.asarray(lat.spacing, dtype=float)
    hor = np.asarray(bonds.horizon, dtype=float)
    if not (np.allclose(hs, hs[0], rtol=1e-12) and np.allclose(hor, hor[0], rtol=1e-12)):
        raise ModelError("a shadow layer needs equal spacing on every axis and a constant horizon")
    vol = np.asarray(cloud.volumes)
    if not np.allclose(vol, vol[0], rtol=1e-12):
        raise ModelError("a shadow layer needs uniform point volumes")
    d = cloud.dim
    delta = float(hor[0])
    m = int(np.floor(delta * (1 + 1e-9) / hs[0]))
    rng = np.arange(-m, m + 1)
    offs = np.stack([g.ravel() for g in np.meshgrid(*([rng] * d), indexing="ij")], axis=1)
    offs = offs[np.any(offs != 0, axis=1)]
    vec = offs * hs[0]
    length = np.sqrt(np.sum(vec**2, axis=1))
    keep = length <= delta * (1 + 1e-9)
    vec, length = vec[keep], length[keep]
    om = np.asarray(omega_fn(length, np.full(length.size, delta)), dtype=float)
    return np.einsum("b,bi,bj->ij", om * vol[0], vec, vec)


def shadow_real_counts(cloud: PointCloud, shadow: np.ndarray) -> np.ndarray:
    """Number of real (non-shadow) lattice positions along each axis, ``(d,)``."""
    lat = cloud.lattice
    if lat is None:
        raise ModelError("shadow_real_counts needs a pdlin.grid cloud, got no lattice metadata")
    real = np.ones(cloud.n, dtype=bool)
    real[shadow] = False
    if not real.any():
        return np.zeros(cloud.dim, dtype=int)
    idx = np.arange(cloud.n) if lat.index is None else np.asarray(lat.index)
    multi = np.unravel_index(idx[real], lat.shape)
    return np.array([np.unique(mk).size for mk in multi])


# ---------------------------------------------------------------------------
# the model


def _mean_per_point(owner: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """Plain mean of gradient-point tensors ``(n_gp, d, d)`` over each point's gradient points."""
    d = values.shape[1]
    cnt = np.bincount(owner, minlength=n).astype(float)
    flat = values.reshape(len(owner), d * d)
    out = np.stack([np.bincount(owner, weights=flat[:, k], minlength=n) for k in range(d * d)], 1)
    return (out / cnt[:, None]).reshape(n, d, d)


#: rows per chunk of the threaded dense products (fixed: results do not depend on the
#: thread count)
_ROW_CHUNK = 1 << 15
#: stored blocks per chunk of block rows in the zero-block dropping
_DROP_CHUNK = 1 << 16
#: bonds per chunk of points in the numba passes over points (coefficients, G's blocks,
#: stress-point sides)
_POINT_CHUNK = 1 << 16


def _rows_matmul(
    A: np.ndarray,
    M: np.ndarray,
    row_scale: np.ndarray | Callable[[int, int], np.ndarray] | None = None,
) -> np.ndarray:
    """``A @ M`` (times ``row_scale`` per row: an array, or a function giving the scales of
    the rows ``a:b``), computed in fixed row chunks on threads."""
    out = np.empty((A.shape[0], M.shape[1]))

    def chunk(rng: tuple[int, int]) -> None:
        a, b = rng
        np.matmul(A[a:b], M, out=out[a:b])
        if callable(row_scale):
            out[a:b] *= row_scale(a, b)[:, None]
        elif row_scale is not None:
            out[a:b] *= row_scale[a:b, None]

    thread_map(chunk, even_chunks(A.shape[0], _ROW_CHUNK))
    return out


def _drop_zero_blocks(
    K: sp.bsr_array, sizes: tuple[np.ndarray, np.ndarray] | None = None
) -> sp.bsr_array:
    """``K`` without its stored blocks that cancel in exact arithmetic.

    At δ = h the nearest-neighbour blocks of ``Wᵀ W`` cancel exactly (the decoupled
    sub-lattices), and higher-order weights cancel more: keeping them would inflate nnz and
    every product with K. In floating point some of these sums leave round-off (3D δ = h:
    entries ~1e-17 of the diagonal, 4.6 % more blocks on a 24³ grid), so an off-diagonal
    block ``(i, j)`` is dropped when ``max|K_ij| <= 16 ε sqrt(max|K_ii| max|K_jj|)``: below
    the round-off of the product itself, symmetric in ``(i, j)`` (``K`` stays bitwise
    symmetric) and independent of the units. Diagonal blocks are always kept. ``sizes``:
    the block sizes of :func:`pdlin._kernels.bsr_matmul` (``block_sizes=True``), if known.
    """
    nrow = K.shape[0] // K.blocksize[0]
    ptr = np.asarray(K.indptr, dtype=np.int64)
    mod = _kernels() if use_numba(K.data.size) else None
    if mod is not None:
        return _drop_zero_blocks_fused(K, mod, sizes)
    flat = K.data.reshape(K.data.shape[0], -1)
    size = np.empty(flat.shape[0])
    dsize = np.zeros(nrow)
    # fixed chunks of block rows on the threads (elementwise work: results do not depend
    # on the thread count); the kept blocks are copied chunk by chunk into their slots
    chunks = ptr_chunks(ptr, _DROP_CHUNK)

    def block_sizes(rng: tuple[int, int]) -> None:
        r0, r1 = rng
        b0, b1 = int(ptr[r0]), int(ptr[r1])
        sz = size[b0:b1]
        # max |entry| per block, column by column (3x faster than axis=)
        np.abs(flat[b0:b1, 0], out=sz)
        for c in range(1, flat.shape[1]):
            np.maximum(sz, np.abs(flat[b0:b1, c]), out=sz)
        brow = np.repeat(np.arange(r0, r1), np.diff(ptr[r0 : r1 + 1]))
        on = K.indices[b0:b1] == brow
        dsize[brow[on]] = sz[on]

    thread_map(block_sizes, chunks)
    keep = np.empty(flat.shape[0], dtype=bool)
    counts = np.empty(nrow, dtype=np.int64)
    eps2 = (16.0 * np.finfo(float).eps) ** 2

    def marks(rng: tuple[int, int]) -> None:
        r0, r1 = rng
        b0, b1 = int(ptr[r0]), int(ptr[r1])
        brow = np.repeat(np.arange(r0, r1), np.diff(ptr[r0 : r1 + 1]))
        col = K.indices[b0:b1]
        tol = dsize[brow]
        tol *= dsize[col]
        tol *= eps2
        sz = size[b0:b1]
        sz *= sz
        kp = keep[b0:b1]
        np.greater(sz, tol, out=kp)
        kp |= col == brow
        cs = np.zeros(b1 - b0 + 1, dtype=np.int64)
        np.cumsum(kp, out=cs[1:])
        counts[r0:r1] = cs[ptr[r0 + 1 : r1 + 1] - b0] - cs[ptr[r0:r1] - b0]

    thread_map(marks, chunks)
    if keep.all():
        return K
    indptr = np.zeros(nrow + 1, dtype=K.indptr.dtype)
    np.cumsum(counts, out=indptr[1:])
    total = int(indptr[-1])
    data = np.empty((total,) + K.data.shape[1:])
    indices = np.empty(total, dtype=K.indices.dtype)

    def copy(rng: tuple[int, int]) -> None:
        r0, r1 = rng
        b0, b1 = int(ptr[r0]), int(ptr[r1])
        o0, o1 = int(indptr[r0]), int(indptr[r1])
        kp = keep[b0:b1]
        np.compress(kp, K.data[b0:b1], axis=0, out=data[o0:o1])
        np.compress(kp, K.indices[b0:b1], out=indices[o0:o1])

    thread_map(copy, chunks)
    return sp.bsr_array((data, indices, indptr), shape=K.shape, blocksize=K.blocksize)


def _drop_zero_blocks_fused(
    K: sp.bsr_array, mod: Any, sizes: tuple[np.ndarray, np.ndarray] | None
) -> sp.bsr_array:
    """:func:`_drop_zero_blocks` in nogil numba passes over row chunks on the threads
    (block sizes unless given, kept blocks, copy): the same decisions and arrays."""
    nrow = K.shape[0] // K.blocksize[0]
    ptr = np.asarray(K.indptr, dtype=np.int64)
    ind = np.ascontiguousarray(K.indices)
    data = np.ascontiguousarray(K.data)
    chunks = ptr_chunks(ptr, _DROP_CHUNK)
    if sizes is None:
        size = np.empty(data.shape[0])
        dsize = np.empty(nrow)
        thread_map(lambda r: mod.block_sizes_fill(r[0], r[1], ptr, ind, data, size, dsize), chunks)
    else:
        size, dsize = sizes
    keep = np.empty(data.shape[0], dtype=bool)
    counts = np.empty(nrow, dtype=np.int64)
    eps2 = (16.0 * np.finfo(float).eps) ** 2
    thread_map(
        lambda r: mod.block_keep_fill(r[0], r[1], ptr, ind, size, dsize, eps2, keep, counts),
        chunks,
    )
    if int(counts.sum()) == data.shape[0]:
        return K
    indptr = np.zeros(nrow + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    total = int(indptr[-1])
    out_dat = np.empty((total,) + data.shape[1:])
    out_ind = np.empty(total, dtype=ind.dtype)
    thread_map(
        lambda r: mod.block_compress_fill(
            r[0], r[1], ptr, ind, data, keep, indptr, out_ind, out_dat
        ),
        chunks,
    )
    return sp.bsr_array(
        (out_dat, out_ind, indptr.astype(K.indptr.dtype)), shape=K.shape, blocksize=K.blocksize
    )


def _with_diagonal_blocks(K: sp.sparray, d: int) -> sp.bsr_array:
    """``K`` as BSR with every diagonal block stored (explicit zeros where empty).

    Energy-free shadow points may have empty rows; Dirichlet elimination writes its identity
    into stored diagonal entries.
    """
    Kb = sp.bsr_array(K, blocksize=(d, d))
    nrow = Kb.shape[0] // d
    mod = _kernels() if use_numba(Kb.indices.size) else None
    if mod is not None:  # row chunks on the threads
        has = np.empty(nrow, dtype=bool)
        ptr = np.asarray(Kb.indptr, dtype=np.int64)
        ind = np.ascontiguousarray(Kb.indices)
        thread_map(
            lambda r: mod.rows_with_diagonal(r[0], r[1], ptr, ind, has),
            ptr_chunks(ptr, _DROP_CHUNK),
        )
    else:
        rows = np.repeat(np.arange(nrow), np.diff(Kb.indptr))
        has = np.zeros(nrow, dtype=bool)
        has[rows[Kb.indices == rows]] = True
    if has.all():
        return Kb
    Kc = sp.coo_array(Kb)
    nd = Kb.shape[0]
    ar = np.arange(nd)
    Kc = sp.coo_array(
        (np.concatenate([Kc.data, np.zeros(nd)]),
         (np.concatenate([Kc.row, ar]), np.concatenate([Kc.col, ar]))),
        shape=Kb.shape,
    )  # fmt: skip
    return sp.bsr_array(Kc.tocsr(), blocksize=(d, d))


@dataclasses.dataclass(frozen=True)
class _Plan:
    gp_owner: np.ndarray  # (n_gp,) particle of each gradient point
    gp_of_bond: np.ndarray  # (nb,) gradient point owning each bond
    weight: np.ndarray  # (n_gp,) w_g
    energy: np.ndarray  # (n_gp,) bool: carries energy (False for shadow points)
    omega: np.ndarray  # (nb,) weights used
    blocks: _GradientBlocks  # G by (gradient point, point) blocks
    n_points: int
    #: () -> Cv (n_gp, nv, nv): Voigt stiffness of the owner (read-only; a broadcast view
    #: for one material), and (Cv) -> D (n_gp, d*d, d*d): w V C_ijkl (0 for energy-free
    #: points); both evaluated on first use (a nonlinear material's small-strain tangent
    #: is only needed by the linearized operators; the assembly needs Cv only)
    stiffness_fn: Any = dataclasses.field(compare=False, repr=False)
    d_fn: Any = dataclasses.field(compare=False, repr=False)
    _lazy: dict[str, Any] = dataclasses.field(default_factory=dict, compare=False, repr=False)

    @property
    def D(self) -> np.ndarray:
        if "D" not in self._lazy:
            self._lazy["D"] = self.d_fn(self.Cv)
        return self._lazy["D"]

    @property
    def Cv(self) -> np.ndarray:
        if "Cv" not in self._lazy:
            self._lazy["Cv"] = self.stiffness_fn()
        return self._lazy["Cv"]

    @property
    def G(self) -> sp.csr_array:
        """G in CSR ``(n_gp*d*d, n*d)``, built from the blocks on first use."""
        if "G" not in self._lazy:
            self._lazy["G"] = _blocks_to_csr(self.blocks, self.n_points)
        return self._lazy["G"]


def _symmetric_tangent(material: Any) -> bool:
    """Whether ``dP/dF`` of ``material`` has major symmetry (K_T symmetric).

    ``None`` (linear elastic C) and hyperelastic materials (with an ``energy`` method, e.g.
    :class:`pdlin.SaintVenantKirchhoff`) do; an explicit ``symmetric_tangent`` attribute
    overrides; anything else (crystal plasticity) is treated as nonsymmetric.
    """
    if material is None:
        return True
    flag = getattr(material, "symmetric_tangent", None)
    if flag is not None:
        return bool(flag)
    return callable(getattr(material, "energy", None))


def _orientation_count(orientation: Any, dim: int) -> int | None:
    """Points described by a material orientation (None: one for all points)."""
    if orientation is None:
        return None
    from ..constitutive.crystal_plasticity import _n_orientations

    return _n_orientations(orientation, dim)


def _tangent_blocks_product(
    blk: _GradientBlocks, A: np.ndarray, d: int
) -> tuple[np.ndarray, np.ndarray]:
    """Blocks of ``G`` (d² x d) and of ``A G`` (d² x d) for blockdiag ``A`` (n_gp, d², d²).

    The G block of (g, point) is ``I_d ⊗ c``: entry ``[(i, q), k] = δ_ik c_q`` (rows
    ``(i, q)`` in the row-major order of ``vec F``).
    """
    nblk = blk.col.size
    Gd = np.zeros((nblk, d, d, d))  # [b, i, q, k]
    for i in range(d):
        Gd[:, i, :, i] = blk.val
    # (A G)[b, p, k] = Σ_q A[g, p, (k, q)] c_bq
    Ar = A.reshape(-1, d * d, d, d)[blk.row]  # (nblk, d², k, q)
    AG = np.einsum("bpkq,bq->bpk", Ar, blk.val)
    return Gd.reshape(nblk, d * d, d), AG


class Correspondence(Model):
    """Linear correspondence (NOSB) peridynamics with zero-energy-mode controls.

    Parameters
    ----------
    C : array_like, optional
        Voigt stiffness (plain Voigt, :mod:`pdlin.constitutive` order):
        ``(6, 6)`` (reduced in 2D by ``plane``), ``(3, 3)`` 2D in-plane,
        ``(1, 1)`` or scalar in 1D; or one per point ``(n, nv, nv)``; or a
        mapping / sequence of them per material id (``cloud.material``).
    E, nu : float or (n,) array_like, optional
        Isotropic alternative to ``C`` (``E`` may vary per point; 1D uses
        ``E`` only).
    K, G, lam, mu : float or (n,) array_like, optional
        Any two isotropic constants instead of ``E, nu``: bulk modulus,
        shear modulus (``mu`` is the same), Lamé's first constant (see
        :func:`pdlin.constitutive.isotropic_constants`; Peridigm decks give
        ``K`` and ``G``).
    plane : {'stress', 'strain'}
        2D reduction of 3D data.
    control : {'none', 'higher_order', 'penalty', 'stress_points', 'springs', 'ads'}
        * ``'none'``: the bonds' ω (e.g. ``influence='inverse'`` for the
          LAMMPS-PD ``ω = 1/|ξ|``, or ``'constant'``).
        * ``'higher_order'``: the model re-weights the bonds of a
          :func:`pdlin.grid` cloud with
          ``pdlin.higher_order_weights(dim, δ/h)`` (spec 000 §6; negative
          weights allowed).  Build the bonds with ``find_bonds(cloud,
          ratio=m)`` (any influence: it is replaced).
        * ``'penalty'``: adds ``½ Σ_b ½ penalty k_b |z_b|²`` with
          ``z_b = u_j - u_i - ∇u_i ξ_b`` (non-affine part of bond b) and
          ``k_b = c ω V_i V_j / |ξ|`` the bond stiffness of
          :class:`pdlin.BondBased` with the modulus ``E_eq`` whose
          bond-based ``C_1111`` equals the mean axial modulus of ``C_i``:
          ``penalty = 1`` resists non-affine motion like a bond-based
          material of the same stiffness (full vector, not projected).
        * ``'stress_points'``: spec 003: two stress points per full-horizon
          particle, one per boundary particle.  Stress point 1 of case ``s``
          owns the bonds with ``s·ξ > 0`` (ties broken by orthogonal
          vectors), stress point 2 the rest: for nearest-neighbour axis bonds
          this is the paper's ``{s_k e_k} / {-s_k e_k}`` split, for larger
          horizons pdlin's half-space extension.  A particle gets two stress
          points (weight ``w_s = sp_weight``) when, for every case, both halves
          have well-conditioned shape tensors (``λ_min/λ_max ≥ SP_MIN_RATIO``)
          and are *balanced* (``‖K_1 - K_2‖ ≤ SP_BALANCE_TOL ‖K‖``: complete,
          point-symmetric families), otherwise one.  The one-SP weight is
          ``w_s`` on the paper's nearest-neighbour families (spec 003 §4.3: the
          body is the node hull, a bar of ``n_y`` rows has the section
          ``(n_y - 1) h``) and ``2 w_s`` beyond them (an ordinary gradient
          point with its whole volume, section ``n_y h``).  Truncated families
          split into unbalanced halves do not act on a uniform stress like
          one gradient point, which made the free-surface bar at δ = 3h fail
          its patch test by 1.1 % before this rule.
        * ``'springs'``: spec 003 Eq. 7, the force state
          ``T_a⟨ξ_ij⟩ = C1 ω (u_j - u_i)`` (full vector) added to every
          bond: ``K_a`` is the graph Laplacian ⊗ I_d with bond weight
          ``2 C1 ω V_i V_j``.
        * ``'ads'``: spec 003 Eq. 8, the averaged displacement state
          ``T_a,i = C2 Σ_k ω V_k (u_k - u_i)`` (one vector per particle):
          ``K_a = C2 diag(V) Lap_V Lap_ωV``.  Symmetric for constant ω
          (the spec's ω = 1) and any V; nonsymmetric for varying ω
          (``model.symmetric`` is False until a plan shows constant ω).

        Springs and ADS use one gradient point per particle (as
        ``'none'``); see :meth:`control_constants` for ``C1``, ``C2``.
    coefficient : float, optional
        Dimensionless ``C̃ >= 0`` of ``'springs'`` (default 0.01) / ``'ads'``
        (default 0.03), normalized by the family (:meth:`control_constants`):
        ``C1 = d C̃ E_ref / S_ref`` and ``C2 = 4 d² C̃ E_ref / (S_ref Ω_ref)``
        with ``S = Σ_j ω V_j |ξ|²``, ``Ω = Σ_j ω V_j`` of a complete family and
        ``E_ref = max_i tr(C_i[:d, :d])/d``.  At ``C̃ = 1`` the springs are a
        full-vector material of modulus ``E_ref`` (energy ``½ E_ref |∇u|²``)
        at any ``δ/h`` and dimension; on nearest-neighbour families this is
        spec 003 §3's ``C̃ (E A / h) Lap0`` (springs) and ``C̃ (E A / h) Lap0²``
        (ADS) in 1D.  Neither control passes an affine patch test next to
        free surfaces (both act on affine fields there): measured on a 2D
        free-surface bar, springs stiffen uniaxial tension by ≈ 1.1 C̃ and
        reduce the lateral strain by ≈ (1 - ν²) C̃ at every δ/h; ADS errs only
        in a surface layer (C̃ = 0.1: lateral strain -0.4 % at δ = h, -2.2 %
        at 3h on an 11-particle-wide bar; ``docs/correspondence.md``).  The
        paper's C1/C2 (Table 1) are not transferable.
    penalty : float
        Dimensionless penalty coefficient (``control='penalty'``).
    influence : callable, optional
        ``ω(length, horizon)`` overriding the bonds' weights (e.g. a
        hand-made weight set); with ``'higher_order'`` it replaces the
        generated set.
    shadow : (m,) array_like of int, optional
        Shadow particles (spec 000 §7, e.g. from :func:`pdlin.shadow_layer`):
        they carry no energy, and their gradient rows use the intact-lattice
        shape tensor (with stress points: the intact one-bond-per-axis
        tensor of a stress point, ``ω V h² I``); their prescribed stress
        enters through :meth:`shadow_loads`.  Springs and ADS keep the
        spring bonds of shadow particles and set the ADS vector of a
        shadow particle to that of the affine continuation, 0.
    seed : int
        Seed of the stress-point case generator.
    case : int, optional
        One fixed stress-point case for every particle (default: random).
    sp_weight : float
        Stress-point weight ``w_s`` (½: passes the patch test and gives
        exact 1D reactions, spec 003 §4.3; 1 is the paper's literal scheme).
    max_bytes : int
        Budget of an assembled K; beyond it :meth:`plan` picks the
        matrix-free operator.
    material : object, optional
        A nonlinear material instead of ``C`` / ``E``: anything with
        ``initial_state(n)`` and ``update(F, state, *, tangent) -> (P, state_new,
        dPdF)``, e.g. :class:`pdlin.CrystalPlasticity` (orientation per particle:
        ``orientation=theta`` with ``theta (n,)``) or
        :class:`pdlin.SaintVenantKirchhoff`.  The model is then finite strain
        (``nonlinear = True``): :meth:`initial_state` and :meth:`respond` give
        ``F = I + G u``, ``f = -Gᵀ vec(w V P)`` and ``K_T = Gᵀ blockdiag(w V
        dP/dF) G`` (spec 001 §2); ``symmetric`` is False unless the material is
        hyperelastic.  Penalty, springs and ADS act as linear add-ons; the
        linearized ``K`` uses ``dP/dF`` at ``F = I``.  Not with ``shadow``.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((8, 8), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=2.0)
    >>> model = pdlin.Correspondence(E=1.0, nu=0.25, plane="strain")
    >>> K = pdlin.assemble_stiffness(model, cloud, bonds)
    >>> u = np.random.default_rng(0).normal(size=(cloud.n, 2))
    >>> bool(np.allclose(K @ u.ravel(), -model.internal_force(cloud, bonds, u).ravel()))
    True
    """

    coupling_range = 2
    symmetric = True

    def __init__(
        self,
        C: Any = None,
        *,
        E: Any = None,
        nu: float | None = None,
        K: Any = None,
        G: Any = None,
        lam: Any = None,
        mu: Any = None,
        plane: str = "stress",
        control: str = "none",
        penalty: float = 1.0,
        influence: Any = None,
        shadow: Any = None,
        seed: int = 0,
        case: int | None = None,
        sp_weight: float = 0.5,
        max_bytes: int = DEFAULT_MAX_BYTES,
        coefficient: float | None = None,
        material: Any = None,
    ) -> None:
        if material is not None:
            given = {"C": C, "E": E, "nu": nu, "K": K, "G": G, "lam": lam, "mu": mu}
            both = [k for k, v in given.items() if v is not None]
            if both:
                raise InputError(
                    "Correspondence needs exactly one of material= (a nonlinear material) or "
                    f"elastic constants, got material and {', '.join(both)}"
                )
            for meth in ("initial_state", "update"):
                if not callable(getattr(material, meth, None)):
                    raise InputTypeError(
                        "material must provide initial_state(n) and update(F, state, "
                        "tangent=...) (e.g. pdlin.CrystalPlasticity, pdlin.SaintVenantKirchhoff),"
                        f" got {type(material).__name__} without {meth}()"
                    )
            if shadow is not None:
                raise ModelError(
                    "shadow= is not supported with material= (its shadow loads are linear); "
                    "use pdlin.ghost_layer to give the prescribed particles full families, got "
                    "both"
                )
        iso = [k for k, v in {"K": K, "G": G, "lam": lam, "mu": mu}.items() if v is not None]
        if iso and material is None:
            if C is not None:
                raise InputError(
                    "Correspondence needs exactly one of C (Voigt stiffness) or isotropic "
                    f"constants, got C and {', '.join(iso)}"
                )
            E, nu = uniform_nu_constants("Correspondence", E, nu, K=K, G=G, lam=lam, mu=mu)
        if material is None and (C is None) == (E is None):
            raise InputError(
                "Correspondence needs exactly one of C (Voigt stiffness) or E (with nu, or two "
                f"of K, G, lam, mu), got {'both' if C is not None else 'neither'}"
            )
        if control not in CONTROLS:
            raise InputError(f"control must be one of {CONTROLS}, got {control!r}")
        if plane not in ("stress", "strain"):
            raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
        pen = float(penalty)
        if not np.isfinite(pen) or pen < 0:
            raise InputError(f"penalty must be a finite number >= 0, got {penalty!r}")
        if influence is not None and not callable(influence):
            raise InputError(f"influence must be a callable ω(length, horizon), got {influence!r}")
        if not isinstance(sp_weight, int | float | np.number) or not float(sp_weight) > 0:
            raise InputError(f"sp_weight must be > 0, got {sp_weight}")
        if case is not None and control != "stress_points":
            raise InputError(f"case is only used with control='stress_points', got {control!r}")
        if coefficient is not None and control not in ("springs", "ads"):
            raise InputError(
                f"coefficient is only used with control='springs' or 'ads', got {control!r}"
            )
        default = DEFAULT_CONTROL_COEFFICIENT.get(control, 0.0)
        coef = default if coefficient is None else float(coefficient)
        if not (np.isfinite(coef) and coef >= 0):
            raise InputError(f"coefficient must be a finite number >= 0, got {coefficient!r}")
        if C is not None and not isinstance(C, Mapping):
            c_arr = np.asarray(C) if not isinstance(C, list | tuple) else None
            if c_arr is not None and c_arr.dtype.kind in "fiub":
                check_finite(np.asarray(c_arr, dtype=float), "C")
            elif c_arr is not None and c_arr.dtype.kind != "O":
                raise InputTypeError(f"C must be a numeric array, got dtype {c_arr.dtype}")
        self.C = C
        self.E = None if E is None else as_float_array(E, "E")
        if self.E is not None and np.any(self.E <= 0):
            raise InputError(f"E must be > 0, got min {float(np.min(self.E))}")
        self.nu = None if nu is None else float(nu)
        self.plane = plane
        self.control = control
        self.penalty = pen
        self.influence = influence
        self.shadow = None if shadow is None else np.unique(np.asarray(shadow, dtype=np.intp))
        self.seed = integer(seed, "seed")
        self.case = None if case is None else int(case)
        self.sp_weight = float(sp_weight)
        self.coefficient = coef
        self.max_bytes = integer(max_bytes, "max_bytes", minimum=1)
        #: the nonlinear material (None: linear elastic C)
        self.material = material
        #: whether f(u) is nonlinear / history dependent (a ``material`` was given)
        self.nonlinear = material is not None
        #: whether K (K_T) is symmetric: False for 'ads' until a plan shows a constant ω, and
        #: for materials without a major-symmetric dP/dF (crystal plasticity)
        self.symmetric = control != "ads" and _symmetric_tangent(material)
        self._voigt_cache: tuple[PointCloud, np.ndarray] | None = None
        self._cache: tuple[PointCloud, Bonds, _Plan] | None = None
        #: how the last :meth:`plan` decided to apply K ('assembled' / 'matrix-free') and why
        self.assembly: dict[str, Any] = {}

    # -- material --------------------------------------------------------
    def voigt_stiffness(self, cloud: PointCloud) -> np.ndarray:
        """Per-point Voigt stiffness ``(n, nv, nv)`` in the cloud's dimension.

        With ``material=`` it is the material's tangent ``dP/dF`` at ``F = I`` from its
        initial state (the small-strain stiffness, rotated by the particle's orientation):
        the linearized ``K`` and the penalty / springs / ADS constants use it.
        """
        if self.material is not None:
            return self._material_voigt(cloud)
        d, n = cloud.dim, cloud.n
        nv = {1: 1, 2: 3, 3: 6}[d]
        if self.E is not None:
            E = self.E
            if E.ndim and E.shape != (n,):
                raise ShapeError(f"E must be a scalar or have shape ({n},), got {E.shape}")
            if d == 1:
                base = np.ones((1, 1))
            else:
                if self.nu is None:
                    raise InputError(f"nu must be given with E in {d}D, got None")
                base = (
                    isotropic(E=1.0, nu=self.nu)
                    if d == 3
                    else isotropic_2d(1.0, self.nu, plane=self.plane)
                )
            if E.ndim == 0:  # one material: a read-only view, as for one C below
                return np.broadcast_to(E * base, (n, nv, nv))
            return E[:, None, None] * base[None]
        C = self.C
        per_material = isinstance(C, Mapping) or (
            isinstance(C, list | tuple) and len(C) > 0 and np.ndim(C[0]) == 2
        )
        if per_material:
            mats = np.asarray(cloud.material, dtype=np.intp)
            keys = np.unique(mats)
            table = {}
            for k in keys:
                try:
                    table[int(k)] = self._one_voigt(C[int(k)], d, f"C[{int(k)}]")
                except (KeyError, IndexError):
                    raise InputError(
                        f"C must give a stiffness for every material id of the cloud, "
                        f"got none for id {int(k)}"
                    ) from None
            out = np.empty((n, nv, nv))
            for k, v in table.items():
                out[mats == k] = v
            return out
        arr = np.asarray(C, dtype=float)
        if arr.ndim == 3:
            if arr.shape[0] != n:
                raise ShapeError(f"per-point C must have shape ({n}, {nv}, {nv}), got {arr.shape}")
            if arr.shape[1:] == (nv, nv):
                _check_stiffness_per_point(arr)
                return arr
            return np.stack([self._one_voigt(a, d, f"C[{k}]") for k, a in enumerate(arr)])
        return np.broadcast_to(self._one_voigt(arr, d, "C"), (n, nv, nv))

    def _one_voigt(self, C: Any, d: int, name: str) -> np.ndarray:
        arr = np.asarray(C, dtype=float)
        if d == 1:
            if arr.size != 1 or not arr.ravel()[0] > 0:
                raise InputError(f"{name} must be a positive scalar or (1, 1) in 1D, got {arr!r}")
            return arr.reshape(1, 1)
        if d == 2 and arr.shape == (6, 6):
            return plane_stress(arr) if self.plane == "stress" else plane_strain(arr)
        want = (3, 3) if d == 2 else (6, 6)
        if arr.shape != want:
            raise ShapeError(
                f"{name} must be a Voigt matrix of shape {want} in {d}D, got {arr.shape}"
            )
        return check_stiffness(arr, name)

    # -- weights ----------------------------------------------------------
    def bond_weights(self, cloud: PointCloud, bonds: Bonds) -> np.ndarray:
        """The ω used per bond, ``(nb,)`` (higher-order sets may be negative)."""
        fn = self._omega_fn(cloud, bonds)
        if fn is None:
            return np.asarray(bonds.omega, dtype=float)
        om = np.asarray(fn(bonds.length, bonds.horizon_ij), dtype=float)
        return np.broadcast_to(om, bonds.length.shape).astype(float)

    def _omega_fn(self, cloud: PointCloud, bonds: Bonds) -> Any:
        if self.influence is not None:
            return self.influence
        if self.control != "higher_order":
            return None
        lat = cloud.lattice
        if lat is None or not np.allclose(lat.spacing, lat.spacing[0], rtol=1e-12):
            raise ModelError(
                "control='higher_order' needs a pdlin.grid cloud with equal spacing on every "
                "axis, got " + ("no lattice" if lat is None else f"spacing {lat.spacing}")
            )
        h = float(lat.spacing[0])
        hor = np.asarray(bonds.horizon)
        if not np.allclose(hor, hor[0], rtol=1e-12):
            raise ModelError("control='higher_order' needs a constant horizon, got a per-point one")
        ratio = float(hor[0]) / h
        try:
            from .weights import as_influence, higher_order_weights
        except ImportError:
            if abs(ratio - 1.0) < 1e-6:  # δ = h: the only shell, weight 1 (spec 000 §6 Table)
                return lambda length, horizon: np.ones_like(length)
            raise ModelError(
                f"control='higher_order' at δ/h = {ratio:g} needs pdlin.models.weights "
                "(not available); pass influence= with a weight set"
            ) from None
        return as_influence(higher_order_weights(cloud.dim, ratio), h)

    # -- gradient points --------------------------------------------------
    def _gradient_points(
        self, cloud: PointCloud, bonds: Bonds
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = cloud.n
        if self.control != "stress_points":
            return np.arange(n), bonds.i, np.ones(n)
        d = cloud.dim
        cases = _SP_CASES[d]
        # SP1 of case s owns the bonds with s·ξ > 0 (ties broken by the next vectors of an
        # orthogonal basis); for nearest-neighbour axis bonds this is spec 003's
        # {s_k e_k} / {-s_k e_k} split, for larger horizons its half-space extension
        first = _sides(bonds, cases)  # (n_cases, nb)
        omega = self.bond_weights(cloud, bonds)
        full = _halves_well_conditioned(bonds, omega * bonds.volume_j, first, n, omega)
        if bonds.n_bonds and not full.any():
            warnings.warn(
                "stress points: no particle has two balanced, well-conditioned half families "
                "(irregular cloud or a body thinner than two horizons); every particle gets one "
                "gradient point and the control is inactive (ordinary correspondence): use "
                "control='penalty' on irregular clouds",
                UserWarning,
                stacklevel=4,
            )
        cases = _SP_CASES[d]
        if self.case is None:
            # one draw per full-horizon particle, in point order (the convention of the
            # spec 003 reference implementation, so seeded results are comparable)
            chosen = np.zeros(n, dtype=np.intp)
            chosen[full] = np.random.default_rng(self.seed).integers(
                0, cases.shape[0], int(full.sum())
            )
        else:
            if not 0 <= self.case < cases.shape[0]:
                raise InputError(
                    f"case must be in [0, {cases.shape[0] - 1}] in {d}D, got {self.case}"
                )
            chosen = np.full(n, self.case)
        n_sp = np.where(full, 2, 1)
        base = np.zeros(n, dtype=np.intp)
        np.cumsum(n_sp[:-1], out=base[1:])
        mod = _kernels() if use_numba(bonds.n_bonds) else None
        if mod is not None:  # point chunks on the threads
            gp_of_bond = np.empty(bonds.n_bonds, dtype=np.intp)
            bptr = np.asarray(bonds.indptr, dtype=np.int64)
            thread_map(
                lambda r: mod.sp_gp_of_bond(
                    r[0], r[1], bptr, base, full, chosen, first, gp_of_bond
                ),
                ptr_chunks(bptr, _POINT_CHUNK),
            )
        else:
            second = full[bonds.i] & ~first[chosen[bonds.i], np.arange(bonds.n_bonds)]
            gp_of_bond = base[bonds.i] + second
        gp_owner = np.repeat(np.arange(n), n_sp)
        # one-SP weight: spec 003 §4.3 (w_s for every SP) on the paper's nearest-neighbour
        # families; beyond them a one-SP particle is an ordinary gradient point carrying its
        # whole volume (2 w_s, as its two half-SPs would for a uniform stress)
        single = 1.0 if int(bonds.family_size.max(initial=0)) <= 2 * d else 2.0
        weight = np.where(np.repeat(full, n_sp), 1.0, single) * self.sp_weight
        return gp_owner, gp_of_bond, weight

    # -- assembly plan ----------------------------------------------------
    def _plan(self, cloud: PointCloud, bonds: Bonds) -> _Plan:
        # the cache holds the objects themselves (not ids, which can be reused)
        if self._cache is not None and self._cache[0] is cloud and self._cache[1] is bonds:
            return self._cache[2]
        if bonds.n_points != cloud.n or bonds.dim != cloud.dim:
            raise ShapeError(
                f"bonds were built for {bonds.n_points} points in {bonds.dim}D, "
                f"got a cloud of {cloud.n} points in {cloud.dim}D"
            )
        d, n = cloud.dim, cloud.n
        omega = self.bond_weights(cloud, bonds)
        gp_owner, gp_of_bond, w = self._gradient_points(cloud, bonds)
        n_gp = gp_owner.size
        energy = np.ones(n_gp, dtype=bool)
        rows = None
        kinv = None
        if self.shadow is not None:
            if self.shadow.size and (self.shadow.min() < 0 or self.shadow.max() >= n):
                raise InputError(
                    f"shadow must hold point indices in [0, {n - 1}], got "
                    f"[{int(self.shadow.min())}, {int(self.shadow.max())}]"
                )
            is_shadow = np.zeros(n, dtype=bool)
            is_shadow[self.shadow] = True
            rows = np.flatnonzero(is_shadow[gp_owner])
            energy[rows] = False
            fn = self._omega_fn(cloud, bonds)
            if fn is None:
                from ..geometry.influence import influence_function

                fn = influence_function(bonds.influence)
            K_int = intact_shape_tensor(cloud, bonds, fn)
            kinv = np.linalg.inv(K_int)
            if self.control == "stress_points":
                # a half family holds half the intact tensor (§4.2, one bond per axis at
                # δ = h); a one-SP particle of weight 2 w_s beyond δ = h holds all of it
                kinv = kinv[None] * (2.0 * self.sp_weight / w[rows])[:, None, None]
        # each point owns its bonds and the gradient points of those (_gradient_points)
        gptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(gp_owner, minlength=n), out=gptr[1:])
        ptrs = (np.asarray(bonds.indptr, dtype=np.int64), gptr)
        c = _coefficients(
            gp_of_bond, n_gp, omega, bonds.volume_j, bonds.xi,
            override_rows=rows, override_kinv=kinv, ptrs=ptrs,
        )  # fmt: skip
        blocks = _gradient_blocks(gp_owner, gp_of_bond, bonds.j, c, n, ptrs)
        vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
        scale = w * vol[gp_owner] * energy

        def stiffness_fn() -> np.ndarray:
            V = self.voigt_stiffness(cloud)
            if V.ndim == 3 and V.shape[0] and V.strides[0] == 0:  # one C: a view, no copy
                return np.broadcast_to(V[0], (n_gp,) + V.shape[1:])
            return V[gp_owner]

        def d_fn(Cv: np.ndarray) -> np.ndarray:
            P = voigt_projector(d)
            D = np.empty((Cv.shape[0], d * d, d * d))

            def chunk(rng: tuple[int, int]) -> None:  # Pᵀ C P per gradient point, on threads
                g0, g1 = rng
                D[g0:g1] = (P.T @ Cv[g0:g1] @ P) * scale[g0:g1, None, None]

            thread_map(chunk, even_chunks(Cv.shape[0], _ROW_CHUNK))
            return D

        plan = _Plan(gp_owner, gp_of_bond, w, energy, omega, blocks, n, stiffness_fn, d_fn)
        if self.material is None:  # validate C now (errors at plan time)
            plan.Cv  # noqa: B018
        if self.control == "ads":  # S N is symmetric for constant ω, any V (see the docs)
            const = bool(np.allclose(omega, omega[0], rtol=1e-12))
            self.symmetric = const and _symmetric_tangent(self.material)
        self._cache = (cloud, bonds, plan)
        return plan

    def gradient(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Displacement gradient per gradient point ``(n_gp, d, d)``."""
        p = self._plan(cloud, bonds)
        uu = _as_u(u, cloud)
        return (p.G @ uu.ravel()).reshape(-1, cloud.dim, cloud.dim)

    def gradient_matrix(self, cloud: PointCloud, bonds: Bonds) -> sp.csr_array:
        """The gradient operator G of the model (gradient points x DOFs)."""
        return self._plan(cloud, bonds).G

    def stress_points(self, cloud: PointCloud, bonds: Bonds) -> dict[str, np.ndarray]:
        """Bookkeeping of the gradient points: ``owner``, ``bond_owner``, ``weight``."""
        p = self._plan(cloud, bonds)
        return {"owner": p.gp_owner, "bond_owner": p.gp_of_bond, "weight": p.weight}

    # -- operators -----------------------------------------------------------
    def _dblock(self, p: _Plan) -> sp.bsr_array:
        n_gp, q, _ = p.D.shape
        ar = np.arange(n_gp + 1, dtype=np.int32)
        return sp.bsr_array((p.D, ar[:-1], ar), shape=(n_gp * q, n_gp * q), blocksize=(q, q))

    def _penalty_k(self, cloud: PointCloud, bonds: Bonds, p: _Plan) -> np.ndarray:
        """Penalty stiffness per bond ``½ penalty k_b`` (0 on energy-free owners), ``(nb,)``."""
        d = cloud.dim
        Cv = self.voigt_stiffness(cloud)
        axial = np.einsum("nkk->n", Cv[:, :d, :d]) / d
        e_eq = axial / _c1111(np.ones(1), d, self.plane)[0]
        bb = BondBased(E=e_eq, plane=self.plane)
        k = 0.5 * self.penalty * bb.bond_stiffness(cloud, dataclasses.replace(bonds, omega=p.omega))
        return k * p.energy[bonds.i]

    def _penalty_force(
        self, cloud: PointCloud, bonds: Bonds, p: _Plan, k: np.ndarray, x: np.ndarray
    ) -> np.ndarray:
        """``Zᵀ(k z)`` with ``z_b = u_j - u_i - ∇u_g ξ_b``, matrix-free, ``(n*d,)``."""
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
        for a in range(d):
            for q in range(d):
                t[:, a, q] = np.bincount(
                    p.gp_of_bond, weights=kz[:, a] * bonds.xi[:, q], minlength=ngp
                )
        return out.ravel() - np.asarray(p.G.T @ t.ravel())

    def _penalty_matrix(self, cloud: PointCloud, bonds: Bonds, p: _Plan) -> sp.bsr_array:
        """``Zᵀ diag(k) Z`` with ``Z = Z_s ⊗ I_d`` (BSR, d x d blocks).

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
        """
        d, n = cloud.dim, cloud.n
        k = self._penalty_k(cloud, bonds, p)
        blk = p.blocks
        g = p.gp_of_bond
        nb = g.size
        n_gp = blk.indptr.size - 1
        nblk = blk.col.size
        kx = k[:, None] * bonds.xi
        # M_g = Σ_b k_b ξ_b ξ_bᵀ; U block (g, p) = ½ M_g c_gp - Σ_{b: j_b = p} k_b ξ_b
        # (+ Σ_b k_b ξ_b on the owner's block)
        M = np.empty((n_gp, d, d))
        for q in range(d):
            for r in range(q, d):
                M[:, q, r] = M[:, r, q] = np.bincount(
                    g, weights=kx[:, q] * bonds.xi[:, r], minlength=n_gp
                )
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

    # -- springs / ADS (spec 003 §3) ----------------------------------------
    def control_constants(self, cloud: PointCloud, bonds: Bonds) -> dict[str, float]:
        """Constants of the ``'springs'`` / ``'ads'`` control forces (spec 003 §3).

        Returns ``{'coefficient': C̃, 'E_ref', 'V_ref', 'h_ref', 'S_ref', 'Omega_ref',
        'C1', 'C2'}``.  ``E_ref = max_i tr(C_i[:d, :d])/d`` (the largest mean axial
        modulus; ``E`` in 1D); the family moments ``S_i = Σ_j ω V_j |ξ_ij|²`` and
        ``Ω_i = Σ_j ω V_j`` (``V`` times the thickness in 2D / cross-section in 1D) give
        ``S_ref = max_i S_i`` and ``Omega_ref = max_i Ω_i`` (a complete family on a lattice), and

        ``C1 = d C̃ E_ref / S_ref``,    ``C2 = 4 d² C̃ E_ref / (S_ref Ω_ref)``.

        Meaning, for any ``δ/h`` and dimension: under a homogeneous gradient ``H`` the springs
        of a complete family store ``½ C̃ E_ref |H|²`` per unit volume (a full-vector
        "Laplacian" material of modulus ``C̃ E_ref``: uniaxial stretch gains the stress
        ``C̃ E_ref ε``), and ADS stores ``½ C̃ E_ref ℓ² |∇²u|²`` with ``ℓ² = S_ref/Ω_ref``
        the family's mean square bond length (zero on affine fields, except where families
        are truncated).  On the nearest-neighbour families of spec 003 (``S = 2d V h²``,
        ``Ω = 2d V``) this is ``C1 = C̃ E/(2 V h²)``, ``C2 = C̃ E/(V² h²)``: on a uniform
        chain (``V = A h``, ω = 1) springs add ``C̃ (E A / h) Lap0`` and ADS
        ``C̃ (E A / h) Lap0²`` (spec 003 §3, ``Lap0`` the chain graph Laplacian).  ``V_ref``
        (mean volume) and ``h_ref`` (mean shortest bond) are reported for information.

        Examples
        --------
        >>> import pdlin
        >>> cloud = pdlin.grid((11,), spacing=0.1)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
        >>> m = pdlin.Correspondence(E=2.0, control="springs", coefficient=0.5)
        >>> c = m.control_constants(cloud, bonds)
        >>> round(2 * c["C1"] * c["V_ref"] ** 2, 12)   # C̃ E A / h = 0.5 * 2 / 0.1
        10.0
        >>> b3 = pdlin.find_bonds(cloud, ratio=3.0)   # same springs' modulus, 6 bonds
        >>> c3 = m.control_constants(cloud, b3)
        >>> round(c3["S_ref"] / (2 * 0.1 * (0.1**2 + 0.2**2 + 0.3**2)), 12)
        1.0
        """
        d = cloud.dim
        Cv = self.voigt_stiffness(cloud)
        e_ref = float(np.max(np.einsum("nkk->n", Cv[:, :d, :d]) / d))
        vol = np.asarray(cloud.volumes, dtype=float) * (1.0 if d == 3 else cloud.thickness)
        v_ref = float(np.mean(vol))
        shortest = np.full(cloud.n, np.inf)
        np.minimum.at(shortest, bonds.i, bonds.length)
        has = np.isfinite(shortest)
        if not has.any():
            raise ModelError("springs/ADS controls need bonds, got a cloud without any")
        h_ref = float(np.mean(shortest[has]))
        wv = self.bond_weights(cloud, bonds) * vol[bonds.j]
        s_ref = float(np.max(np.bincount(bonds.i, weights=wv * bonds.length**2, minlength=cloud.n)))
        o_ref = float(np.max(np.bincount(bonds.i, weights=wv, minlength=cloud.n)))
        if not (s_ref > 0 and o_ref > 0):
            raise ModelError(
                "springs/ADS controls need positive family moments Σ ω V_j |ξ|², Σ ω V_j, "
                f"got {s_ref:.3g}, {o_ref:.3g}"
            )
        c = self.coefficient
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

    def _laplacian(
        self, cloud: PointCloud, bonds: Bonds, w: np.ndarray, rows: np.ndarray | None = None
    ) -> sp.csr_array:
        """``(Lap_w u)_i = Σ_b w_b (u_i - u_j)`` over the bonds of i, ⊗ I_d; ``rows``: keep only."""
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

    def _control_factors(
        self, cloud: PointCloud, bonds: Bonds, p: _Plan
    ) -> tuple[sp.csr_array, sp.csr_array] | None:
        """The springs / ADS stiffness as a product ``S @ N`` of one-hop matrices (or None).

        Springs: ``S = Σ_b C1 ω V_i V_j (e_i - e_j)(e_i - e_j)ᵀ ⊗ I``, ``N = I``
        (every bond, shadow ones too).  ADS: ``S = C2 diag(V) Lap_V``,
        ``N = Lap_ωV`` with the rows of shadow particles zeroed (their
        averaged displacement state is that of the affine continuation, 0).
        """
        if self.control not in ("springs", "ads") or self.coefficient == 0:
            return None
        d = cloud.dim
        c = self.control_constants(cloud, bonds)
        vol = np.asarray(cloud.volumes, dtype=float) * (1.0 if d == 3 else cloud.thickness)
        vi, vj = vol[bonds.i], vol[bonds.j]
        nd = cloud.n * d
        if self.control == "springs":
            k = c["C1"] * p.omega * vi * vj
            i, j = bonds.i, bonds.j
            Ls = sp.coo_array(
                (np.concatenate([k, k, -k, -k]),
                 (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))),
                shape=(cloud.n, cloud.n),
            ).tocsr()  # fmt: skip
            S = sp.csr_array(sp.kron(Ls, sp.eye_array(d), format="csr"))
            return S, sp.csr_array(sp.eye_array(nd, format="csr"))
        S = self._laplacian(cloud, bonds, c["C2"] * vi * vj)  # diag(V) Lap_V, symmetric
        rows = None
        if self.shadow is not None:
            rows = np.ones(cloud.n, dtype=bool)
            rows[self.shadow] = False
        N = self._laplacian(cloud, bonds, p.omega * vj, rows)
        return S, N

    def _control_matrix(self, cloud: PointCloud, bonds: Bonds, p: _Plan) -> sp.csr_array | None:
        """Assembled springs / ADS stiffness ``S N`` (None for the other controls)."""
        f = self._control_factors(cloud, bonds, p)
        if f is None:
            return None
        S, N = f
        return S if self.control == "springs" else sp.csr_array(S @ N)

    def _control_products(
        self, cloud: PointCloud, bonds: Bonds, p: _Plan
    ) -> tuple[Any, Any] | None:
        """Matrix-free ``x -> S N x`` and its transpose (None for the other controls)."""
        f = self._control_factors(cloud, bonds, p)
        if f is None:
            return None
        S, N = f
        if self.control == "springs":
            return (lambda x: S @ x), (lambda x: S @ x)
        Nt = sp.csr_array(N.T)
        return (lambda x: S @ (N @ x)), (lambda x: Nt @ (S @ x))

    def stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.bsr_array:
        """Assembled ``K = Gᵀ blockdiag(w V C) G`` (+ penalty / springs / ADS), BSR (dim blocks)."""
        p = self._plan(cloud, bonds)
        d = cloud.dim
        self.plan(cloud, bonds)
        if self.assembly.get("path") == "matrix-free":
            log.warning("assembling K beyond the byte budget: %s", self.assembly["reason"])
        K = self._core_stiffness(cloud, p)
        if self.control == "penalty" and self.penalty > 0:
            K = sp.bsr_array(K + self._penalty_matrix(cloud, bonds, p))  # both bitwise symmetric
        Ka = self._control_matrix(cloud, bonds, p)
        if Ka is not None:  # springs / ADS (ADS may be nonsymmetric: added unsymmetrized)
            K = sp.bsr_array(sp.csr_array(K) + sp.csr_array(Ka), blocksize=(d, d))
        return _with_diagonal_blocks(K, d)

    def _core_stiffness(self, cloud: PointCloud, p: _Plan) -> sp.bsr_array:
        """``Bᵀ blockdiag(w V C) B`` as ``Wᵀ W`` in BSR arithmetic, ``W = √(w V) Lᵀ B``.

        ``B = P_sym G`` has one ``(n_v x d)`` block per (gradient point, point) pair, built
        straight from the blocks of G, and ``C = L Lᵀ`` (Cholesky per gradient point).  The
        product ``Wᵀ W`` is symmetric to the last bit (both triangles sum the same products
        in the same order), so no ``(K + Kᵀ)/2`` pass is needed.  A Voigt stiffness that is
        not positive definite falls back to ``Bᵀ (D B)`` symmetrized.
        """
        d = cloud.dim
        blk = p.blocks
        P = voigt_projector(d)
        nv = P.shape[0]
        # B block (a, i) = Σ_q P[a, i*d + q] c_q  (G block is I_d ⊗ c)
        Pr = P.reshape(nv * d, d)
        nblk = blk.col.size

        def bdata() -> np.ndarray:
            return _rows_matmul(blk.val, Pr.T).reshape(nblk, nv, d)

        n_gp = p.Cv.shape[0]
        vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
        scale = p.weight * vol[p.gp_owner] * p.energy
        shape = (n_gp * nv, p.n_points * d)
        Wdata = self._root_blocks(p, blk, bdata, scale) if (scale >= 0).all() else None
        if Wdata is not None:
            W = sp.bsr_array((Wdata, blk.col, blk.indptr), shape=shape, blocksize=(nv, d))
            K, sizes = bsr_matmul(bsr_transpose(W), W, block_sizes=True)
            return _drop_zero_blocks(K, sizes)
        Bdata = bdata()
        B = sp.bsr_array((Bdata, blk.col, blk.indptr), shape=shape, blocksize=(nv, d))
        ar = np.arange(n_gp + 1, dtype=np.int32)
        Db = sp.bsr_array(
            (p.Cv * scale[:, None, None], ar[:-1], ar),
            shape=(n_gp * nv, n_gp * nv),
            blocksize=(nv, nv),
        )
        K = bsr_matmul(bsr_transpose(B), bsr_matmul(Db, B))
        return sp.bsr_array(0.5 * (K + K.T), blocksize=(d, d))

    @staticmethod
    def _root_blocks(
        p: _Plan, blk: _GradientBlocks, bdata: Any, scale: np.ndarray
    ) -> np.ndarray | None:
        """Blocks of ``W = √scale Lᵀ B`` (``C = L Lᵀ``), or None if a ``C`` is not SPD.

        ``bdata()`` returns the ``(nblk, n_v, d)`` blocks of ``B`` (only needed when the
        material varies between gradient points).
        """
        nblk = blk.col.size
        d = blk.val.shape[1]
        nv = p.Cv.shape[1]
        sq = np.sqrt(scale)
        ptr = blk.indptr
        try:
            one = p.Cv.strides[0] == 0 or bool((p.Cv == p.Cv[0]).all())
            if one:  # one material: one (n_v·d x d) map for all blocks
                L0 = np.linalg.cholesky(p.Cv[0])
                M = (L0.T @ voigt_projector(d)).reshape(nv * d, d)

                def root_rows(a: int, b: int) -> np.ndarray:  # √scale of blocks a:b
                    g0 = int(np.searchsorted(ptr, a, side="right")) - 1
                    g1 = int(np.searchsorted(ptr, b, side="left"))
                    cnt = np.minimum(ptr[g0 + 1 : g1 + 1], b) - np.maximum(ptr[g0:g1], a)
                    return np.repeat(sq[g0:g1], cnt)

                # one (nblk, n_v·d) product, scaled in place, in fixed row chunks on threads
                W = _rows_matmul(blk.val, M.T, root_rows)
                return W.reshape(nblk, nv, d)
            Lr = np.linalg.cholesky(p.Cv)[blk.row]
        except np.linalg.LinAlgError:
            return None
        Bdata = bdata()
        W = np.zeros((nblk, nv, d))
        for b in range(nv):  # Lᵀ B per block
            W += Lr[:, b, :, None] * Bdata[:, b, None, :]
        return W * sq[blk.row][:, None, None]

    def apply(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Matrix-free ``K u`` through G (and the bonds for the penalty), ``(n*d,)``."""
        return np.asarray(self.linear_operator(cloud, bonds) @ np.asarray(u, float).reshape(-1))

    def linear_operator(self, cloud: PointCloud, bonds: Bonds) -> spla.LinearOperator:
        """Matrix-free ``K`` as a :class:`scipy.sparse.linalg.LinearOperator`.

        ``K x = Gᵀ(D(G x))`` plus, for the penalty, ``Zᵀ(k Z x)`` evaluated
        bond by bond (vectorized); memory is that of G and the bond arrays.
        """
        p = self._plan(cloud, bonds)
        nd = cloud.n * cloud.dim
        k = (
            self._penalty_k(cloud, bonds, p)
            if self.control == "penalty" and self.penalty > 0
            else None
        )
        G, Gt = p.G, sp.csr_array(p.G.T)
        D = p.D
        d2 = cloud.dim**2
        extra = self._control_products(cloud, bonds, p)  # springs / ADS: (S N x, Nᵀ S x)

        def mv(x: np.ndarray) -> np.ndarray:
            x = np.asarray(x, dtype=float).reshape(-1)
            s = np.einsum("gij,gj->gi", D, (G @ x).reshape(-1, d2)).ravel()
            out = np.asarray(Gt @ s)
            if k is not None:
                out = out + self._penalty_force(cloud, bonds, p, k, x)
            if extra is not None:
                out = out + extra[0](x)
            return out

        def rmv(x: np.ndarray) -> np.ndarray:
            if extra is None:
                return mv(x)
            x = np.asarray(x, dtype=float).reshape(-1)
            return mv(x) - extra[0](x) + extra[1](x)

        return spla.LinearOperator((nd, nd), matvec=mv, rmatvec=rmv, dtype=float)

    def operator(self, cloud: PointCloud, bonds: Bonds) -> spla.LinearOperator:
        """Matrix-free ``K`` (the :class:`~pdlin.models.base.Model` interface name)."""
        return self.linear_operator(cloud, bonds)

    def surrogate_stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.bsr_array:
        """One-hop preconditioner base: bond-based K plus half its graph Laplacian ⊗ I.

        The bond-based stiffness of the same bonds (ω ≥ 0, equivalent modulus) resists only
        bond stretch: with nearest-neighbour axis bonds it has shear mechanisms, and its
        AMG then breaks CG down on the correspondence operator.  Adding ``½ L ⊗ I_d``, ``L``
        the graph Laplacian with the bond stiffnesses as weights (springs acting on the full
        vector, like the correspondence operator), removes them and, measured, cuts the
        AMG-CG iterations of the matrix-free solve (3D brick with stress points: breakdown
        → 52; 14³ higher-order δ = 2h: 156 → 75; 2D penalty: 32 → 26).
        """
        d = cloud.dim
        Cv = self.voigt_stiffness(cloud)
        axial = np.einsum("nkk->n", Cv[:, :d, :d]) / d
        e_eq = axial / _c1111(np.ones(1), d, self.plane)[0]
        b = dataclasses.replace(bonds, omega=np.abs(self.bond_weights(cloud, bonds)))
        K = sp.bsr_array(BondBased(E=e_eq, plane=self.plane).stiffness(cloud, b))
        n = cloud.n
        rows = np.repeat(np.arange(n), np.diff(K.indptr))
        off = rows != K.indices
        k_b = -np.einsum("bii->b", K.data[off])  # bond stiffness: -trace of its block
        W = sp.csr_array((k_b, (rows[off], K.indices[off])), shape=(n, n))
        L = sp.diags_array(np.asarray(W.sum(axis=1)).ravel()) - W
        return sp.bsr_array(K + 0.5 * sp.kron(L, sp.eye_array(d), format="bsr"), blocksize=(d, d))

    def plan(self, cloud: PointCloud, bonds: Bonds) -> dict[str, Any]:
        """Decide between assembled K and the matrix-free operator (also in ``self.assembly``).

        The estimate counts the two-hop block pattern (:meth:`estimate_nnz_blocks`)
        and the intermediate products; beyond ``max_bytes`` the matrix-free
        path (``K x = Gᵀ(D(G x))``, preconditioned with AMG on
        :meth:`surrogate_stiffness`) is chosen.
        """
        d = cloud.dim
        nblk = self.estimate_nnz_blocks(cloud, bonds)
        est = int(nblk * (8 * d * d + 4) * 6)  # peak ~6x the K estimate (measured, 3D HO 3h)
        if est <= self.max_bytes:
            info = {"path": "assembled", "reason": f"~{est / 1e9:.3g} GB <= budget "
                    f"{self.max_bytes / 1e9:.3g} GB", "nnz_blocks": nblk, "bytes": est}  # fmt: skip
        else:
            info = {"path": "matrix-free", "reason": f"~{est / 1e9:.3g} GB > budget "
                    f"{self.max_bytes / 1e9:.3g} GB", "nnz_blocks": nblk, "bytes": est}  # fmt: skip
        log.info("correspondence K: %s (%s)", info["path"], info["reason"])
        self.assembly = info
        return info

    def estimate_nnz_blocks(self, cloud: PointCloud, bonds: Bonds) -> int:
        """Upper bound of the dim x dim blocks of K: the two-hop pattern.

        On a lattice: interior points x the size of the stencil difference
        set ``{q - p}``; otherwise the number of points within twice the
        largest horizon of each point (cKDTree counts).
        """
        lat = cloud.lattice
        n = cloud.n
        hor = np.asarray(bonds.horizon)
        if lat is not None and np.allclose(hor, hor[0]):
            h = np.asarray(lat.spacing, dtype=float)
            m = np.floor(hor[0] * (1 + 1e-9) / h).astype(int)
            axes = [np.arange(-k, k + 1) for k in m]
            offs = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)
            offs = offs[np.sqrt(np.sum((offs * h) ** 2, axis=1)) <= hor[0] * (1 + 1e-9)]
            diff = np.unique((offs[:, None, :] - offs[None, :, :]).reshape(-1, cloud.dim), axis=0)
            return int(min(n, diff.shape[0]) * n)
        from scipy.spatial import cKDTree

        counts = cKDTree(cloud.points).query_ball_point(
            cloud.points, 2.0 * float(hor.max()) * (1 + 1e-9), return_length=True
        )
        return int(np.sum(counts))

    def internal_force(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, linear: bool = True
    ) -> np.ndarray:
        """Nodal internal force ``f = -Gᵀ vec(w V σ)`` (small strain: ``f = -K u``).

        The elastic model is linear small strain (spec 000 §8), so ``linear=False``
        returns the same force.  With ``material=``, ``linear=False`` is the finite-strain
        force of :meth:`respond` from the initial state; ``linear=True`` is ``-K u`` with the
        material's small-strain stiffness.
        """
        uu = _as_u(u, cloud)
        if not linear and self.material is not None:
            return self.respond(cloud, bonds, uu, self.initial_state(cloud, bonds)).force
        return -self.apply(cloud, bonds, uu).reshape(cloud.n, cloud.dim)

    # -- nonlinear materials ---------------------------------------------------
    def _check_material_dim(self, cloud: PointCloud) -> None:
        md = getattr(self.material, "dim", cloud.dim)
        if md != cloud.dim:
            raise ModelError(
                f"material is {md}D but the cloud is {cloud.dim}D ({type(self.material).__name__})"
            )

    def _material_initial_state(self, cloud: PointCloud, owner: np.ndarray) -> dict[str, Any]:
        """The material's initial state for points ``owner`` (particle of each row)."""
        mat = self.material
        self._check_material_dim(cloud)
        o = getattr(mat, "orientation", None)
        count = _orientation_count(o, cloud.dim)
        if count is None:
            return dict(mat.initial_state(owner.size))
        if count != cloud.n:
            raise ShapeError(
                "material.orientation must describe all particles at once or one particle "
                f"each ({cloud.n}), got {count} orientations"
            )
        return dict(mat.initial_state(owner.size, orientation=np.asarray(o)[owner]))

    def _material_voigt(self, cloud: PointCloud) -> np.ndarray:
        """Voigt form of the material's ``dP/dF`` at ``F = I`` per particle (cached)."""
        if self._voigt_cache is not None and self._voigt_cache[0] is cloud:
            return self._voigt_cache[1]
        d, n = cloud.dim, cloud.n
        state = self._material_initial_state(cloud, np.arange(n))
        eye = np.broadcast_to(np.eye(d), (n, d, d)).copy()
        _, _, A = self.material.update(eye, state, tangent=True)
        if A is None:
            raise ModelError(
                f"material.update(F, state, tangent=True) must return dP/dF, got None "
                f"({type(self.material).__name__})"
            )
        A = np.asarray(A, dtype=float).reshape(n, d, d, d, d)
        if d == 1:
            Cv = A.reshape(n, 1, 1)
        else:
            ij = np.array(_pairs(d))
            Cv = A[:, ij[:, 0, None], ij[:, 1, None], ij[None, :, 0], ij[None, :, 1]]
        try:
            _check_stiffness_per_point(Cv)
        except InputError as exc:
            raise ModelError(
                f"material's small-strain tangent dP/dF(F = I) must be a symmetric positive "
                f"definite stiffness ({type(self.material).__name__}): {exc}"
            ) from None
        self._voigt_cache = (cloud, Cv)
        return Cv

    def initial_state(self, cloud: PointCloud, bonds: Bonds) -> dict[str, np.ndarray]:
        """The material's committed state before the first load step, per gradient point.

        One entry per gradient point (``stress_points(...)['owner']`` maps them to their
        particle: one per particle without stress points).  A per-particle orientation of
        the material (``CrystalPlasticity(orientation=theta)``, ``theta (n,)``) is given to
        every gradient point of that particle.  Empty without ``material=``.

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((4, 4), spacing=0.25)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
        >>> theta = np.linspace(-0.5, 0.5, cloud.n)
        >>> model = pdlin.Correspondence(material=pdlin.CrystalPlasticity(orientation=theta),
        ...                              control="stress_points")
        >>> state = model.initial_state(cloud, bonds)
        >>> owner = model.stress_points(cloud, bonds)["owner"]
        >>> state["Fp"].shape[0] == owner.size, bool(np.allclose(state["theta0"], theta[owner]))
        (True, True)
        """
        if self.material is None:
            return {}
        p = self._plan(cloud, bonds)
        return self._material_initial_state(cloud, p.gp_owner)

    def deformation_gradient(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """``F = I + G u`` per gradient point ``(n_gp, d, d)`` (spec 001 Eq. 16).

        Exact for affine fields at every gradient point whose shape tensor is invertible,
        truncated families included (spec 001 §2.4, T1).
        """
        return np.eye(cloud.dim) + self.gradient(cloud, bonds, u)

    def nodal_force(self, cloud: PointCloud, bonds: Bonds, P: Any) -> np.ndarray:
        """Nodal force of a first Piola–Kirchhoff stress per gradient point, ``(n, d)``.

        ``f = -Gᵀ vec(w V P)`` (spec 001 §2.1: ``L = -V⁻¹ Bᵀ(V ⊙ P)``, ``f = V L``), i.e.
        the pairwise sum ``f_a = V_a Σ_b ω V_b (P_a K_a⁻¹ + P_b K_b⁻¹) ξ_ab`` of spec 001
        Eqs. 15–18 for one gradient point per particle.

        Parameters
        ----------
        P : (n_gp, d, d) or (d, d) array_like of float
            Stress per gradient point (``(d, d)``: the same at every one).

        Examples
        --------
        A uniform stress on a truncated-family grid at δ = h gives ``V P n / (2h)`` on the
        first free ring (spec 001 §2.4), here ``0.25² · 1 / 0.5`` in x at the second column:

        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((4, 4), spacing=0.25)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
        >>> f = pdlin.Correspondence(E=1.0, nu=0.3).nodal_force(cloud, bonds, np.eye(2))
        >>> float(f.reshape(4, 4, 2)[1, 2, 0])
        -0.125
        """
        p = self._plan(cloud, bonds)
        d = cloud.dim
        n_gp = p.gp_owner.size
        arr = as_float_array(P, "P")
        if arr.shape == (d, d):
            arr = np.broadcast_to(arr, (n_gp, d, d))
        if arr.shape != (n_gp, d, d):
            raise ShapeError(
                f"P must have shape ({n_gp}, {d}, {d}) (one per gradient point) or ({d}, {d}), "
                f"got {arr.shape}"
            )
        return self._force_of(cloud, p, arr.reshape(n_gp, d * d)).reshape(cloud.n, d)

    def _force_of(self, cloud: PointCloud, p: _Plan, P: np.ndarray) -> np.ndarray:
        """``-Gᵀ vec(w V P)`` for a checked ``(n_gp, d*d)`` stress, flat ``(n*d,)``.

        The weights ``-w V`` (0 at energy-free points) are kept in the plan, the sign
        folded into them (the same bits as negating the product)."""
        if "neg_wv" not in p._lazy:
            d = cloud.dim
            vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
            p._lazy["neg_wv"] = -(p.weight * vol[p.gp_owner] * p.energy)[:, None]
        w = p._lazy["neg_wv"]
        flat = np.empty_like(P)
        if P.size >= _THREADED_MULTIPLY:  # numpy's loop releases the GIL: row chunks
            from .._threads import even_chunks, thread_map

            thread_map(
                lambda c: np.multiply(P[c[0] : c[1]], w[c[0] : c[1]], out=flat[c[0] : c[1]]),
                even_chunks(P.shape[0], _THREADED_MULTIPLY // (2 * P.shape[1])),
            )
        else:
            np.multiply(P, w, out=flat)
        return np.asarray(_threaded(p, "GT", p.G.T) @ flat.ravel())

    def _addon_matrix(self, cloud: PointCloud, bonds: Bonds, p: _Plan) -> sp.csr_array | None:
        """Assembled penalty / springs / ADS stiffness ``K_c`` (None without such a control),
        built once per plan: the nonlinear force ``-K_c u`` and the tangent's ``+K_c``."""
        if "addon" not in p._lazy:
            if self.control == "penalty" and self.penalty > 0:
                Kc = sp.csr_array(self._penalty_matrix(cloud, bonds, p))
            else:
                Kc = self._control_matrix(cloud, bonds, p)
            if Kc is not None:
                # without the zeros of its d x d blocks (multiples of I_d for the penalty:
                # half of the CSR's entries in 2D), which every K_c u would multiply
                Kc = sp.csr_array(Kc, copy=True)  # a copy: S of springs is kept elsewhere
                Kc.eliminate_zeros()
            p._lazy["addon"] = Kc
        return p._lazy["addon"]

    def tangent_matrix(self, cloud: PointCloud, bonds: Bonds, dPdF: Any) -> sp.bsr_array:
        """``K_T = Gᵀ blockdiag(w V dP/dF) G`` (+ the linear control stiffness), BSR.

        Parameters
        ----------
        dPdF : (n_gp, d, d, d, d) array_like of float
            ``dPdF[g, i, j, k, l] = ∂P_ij/∂F_kl`` per gradient point; reshaped to
            ``(d², d²)`` blocks in the row-major ``(i, j)`` order of ``vec F`` (the order of
            G's rows).

        Returns
        -------
        scipy.sparse.bsr_array of shape (n*d, n*d), blocksize (d, d)
            Nonsymmetric unless ``dP/dF`` has major symmetry (then symmetrized to the
            last bit); blocks that cancel in exact arithmetic (the δ = h sub-lattice
            coupling) are dropped.
        """
        p = self._plan(cloud, bonds)
        d = cloud.dim
        n_gp = p.gp_owner.size
        A = as_float_array(dPdF, "dPdF")
        if A.shape not in ((n_gp, d, d, d, d), (n_gp, d * d, d * d)):
            raise ShapeError(f"dPdF must have shape ({n_gp}, {d}, {d}, {d}, {d}), got {A.shape}")
        vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
        scale = p.weight * vol[p.gp_owner] * p.energy
        A = A.reshape(n_gp, d * d, d * d) * scale[:, None, None]
        blk = p.blocks
        Gd, AG = _tangent_blocks_product(blk, A, d)
        shape = (n_gp * d * d, p.n_points * d)
        Gb = sp.bsr_array((Gd, blk.col, blk.indptr), shape=shape, blocksize=(d * d, d))
        AGb = sp.bsr_array((AG, blk.col, blk.indptr), shape=shape, blocksize=(d * d, d))
        K = _drop_zero_blocks(bsr_matmul(bsr_transpose(Gb), AGb))
        Kc = self._addon_matrix(cloud, bonds, p)
        if Kc is not None:
            K = sp.bsr_array(sp.csr_array(K) + Kc, blocksize=(d, d))
        if self.symmetric:  # major-symmetric dP/dF: make K_T symmetric to the last bit
            K = sp.bsr_array(0.5 * (K + K.T), blocksize=(d, d))
        return _with_diagonal_blocks(K, d)

    def respond(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray,
        state: dict[str, np.ndarray],
        *,
        tangent: bool = False,
    ) -> Response:
        """Finite-strain force, trial state, tangent and Cauchy stress at ``u``.

        ``F_g = I + (G u)_g`` per gradient point; ``P, trial, dP/dF =
        material.update(F, state, tangent=tangent)`` (without the tangent, from a
        material that has ``piola(F, state)``: ``P`` from it and the trial state on the
        first read of ``Response.state``); ``f = -Gᵀ vec(w V P)`` and
        ``K_T = Gᵀ blockdiag(w V dP/dF) G`` (:meth:`nodal_force`, :meth:`tangent_matrix`).
        Penalty, springs and ADS controls are linear add-ons: ``f -= K_c u``,
        ``K_T += K_c``.  ``state`` (from :meth:`initial_state` or a committed trial state)
        is not modified.  Without ``material=`` this is the linear model
        (:meth:`pdlin.Model.respond`).

        Returns
        -------
        Response
            ``force (n, d)``, ``state`` (trial, per gradient point), ``tangent`` (BSR or
            None), ``stress`` (Cauchy per particle: mean over its gradient points, ``(n, d,
            d)``), ``calls`` (constitutive evaluations: the number of gradient points).

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((6, 6), spacing=1 / 6)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
        >>> model = pdlin.Correspondence(material=pdlin.CrystalPlasticity())
        >>> state = model.initial_state(cloud, bonds)
        >>> Fbar = np.array([[1.0, 0.002], [0.002, 1.0]])
        >>> r = model.respond(cloud, bonds, cloud.points @ (Fbar - np.eye(2)).T, state,
        ...                   tangent=True)
        >>> r.force.shape, r.tangent.shape, r.calls, model.symmetric
        ((36, 2), (72, 72), 36, False)
        >>> round(float(r.stress[14, 0, 1]), 3)   # interior particle, elastic (spec §8.1: 8.000)
        8.0
        """
        if self.material is None:
            return super().respond(cloud, bonds, u, state, tangent=tangent)
        p = self._plan(cloud, bonds)
        d, n = cloud.dim, cloud.n
        n_gp = p.gp_owner.size
        uu = _as_u(u, cloud)
        if not isinstance(state, Mapping):
            raise InputTypeError(
                f"state must be a dict from initial_state(cloud, bonds), got {type(state).__name__}"
            )
        for key, val in state.items():
            if isinstance(val, np.ndarray) and val.ndim and val.shape[0] != n_gp:
                raise ShapeError(
                    f"state[{key!r}] must have one row per gradient point ({n_gp}), got "
                    f"shape {val.shape} (use model.initial_state(cloud, bonds))"
                )
        x = uu.ravel()
        Gx = np.asarray(_threaded(p, "G", p.G) @ x)
        if "eye" not in p._lazy:  # vec I per gradient point: I + G u as one contiguous add
            p._lazy["eye"] = np.tile(np.eye(d).ravel(), n_gp)
        F = np.add(Gx, p._lazy["eye"], out=Gx).reshape(n_gp, d, d)
        material = self.material
        trial: Any
        if not tangent and hasattr(material, "piola"):
            # the force alone (an ADR iteration, a line-search trial): the material's
            # stress without its trial state, which is computed on the first read of
            # Response.state (once per converged step) from the same F and state
            P, A = material.piola(F, state), None

            def trial() -> dict[str, np.ndarray]:
                return dict(material.update(F, state)[1])

        else:
            P, trial, A = material.update(F, state, tangent=tangent)
            trial = dict(trial)
        P = np.asarray(P, dtype=float)
        if P.shape == (n_gp, d, d):  # the usual case, checked here without a copy
            check_finite(P, "P")
            force = self._force_of(cloud, p, P.reshape(n_gp, d * d))
        else:  # validated (one P for all, or a shape error)
            force = self.nodal_force(cloud, bonds, P).ravel()
        # the control's assembled stiffness (the tangent's too): at 10⁵ points its product
        # costs 1.8 ms against 23 ms matrix-free (_penalty_force; 2D, δ = h penalty)
        Kc = self._addon_matrix(cloud, bonds, p)
        if Kc is not None:
            force -= _threaded(p, "addon", Kc) @ x
        K = None
        if tangent:
            if A is None:
                raise ModelError(
                    f"material.update(..., tangent=True) must return dP/dF, got None "
                    f"({type(self.material).__name__})"
                )
            K = self.tangent_matrix(cloud, bonds, A)
        cauchy: Any = getattr(self.material, "cauchy", None)
        if cauchy is None:
            from ..constitutive.crystal_plasticity import cauchy_stress

            cauchy = cauchy_stress
        owner = p.gp_owner

        def sigma() -> np.ndarray:  # on first read (once per converged step)
            return _mean_per_point(owner, np.asarray(cauchy(P, F)), n)

        return Response(force.reshape(n, d), trial, K, sigma, int(n_gp))

    def stress(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Cauchy stress per particle ``(n, d, d)``: the mean over its stress points."""
        p = self._plan(cloud, bonds)
        d = cloud.dim
        grad = self.gradient(cloud, bonds, u).reshape(-1, d * d)
        P = voigt_projector(d)
        sv = np.einsum("gab,gb->ga", p.Cv, grad @ P.T)
        return _mean_per_point(p.gp_owner, (sv @ P).reshape(-1, d, d), cloud.n)

    def strain(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Small strain per particle ``(n, d, d)``: the mean over its stress points."""
        p = self._plan(cloud, bonds)
        grad = self.gradient(cloud, bonds, u)
        return _mean_per_point(p.gp_owner, 0.5 * (grad + np.swapaxes(grad, 1, 2)), cloud.n)

    def shadow_loads(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        *,
        F: Any = None,
        stress: Any = None,
    ) -> np.ndarray:
        """Nodal force of the prescribed shadow stress on the real points, ``(n, d)``.

        ``-(Σ_j G_jᵀ (w V σ_S,:j))`` over the gradient points of the shadow
        particles (stress points: ``w = w_s``), whose rows of G are built from
        the intact shape tensor (spec 000 §7); add it to the external load
        (e.g. as a :class:`pdlin.BodyForce` on the real points, see
        :func:`shadow_problem`).  Give the shadow stress directly
        (``stress``, ``(m, d, d)`` or ``(d, d)``) or through ``F``
        (``σ = C : ε(F)`` with each shadow particle's own C).
        """
        if self.shadow is None:
            raise ModelError("shadow_loads needs a model built with shadow=indices, got None")
        p = self._plan(cloud, bonds)
        d = cloud.dim
        m = self.shadow.size
        if (F is None) == (stress is None):
            raise InputError("shadow_loads needs exactly one of F or stress")
        P = voigt_projector(d)
        if F is not None:
            Fm = as_float_array(F, "F")
            if Fm.shape != (d, d):
                raise ShapeError(f"F must have shape ({d}, {d}), got {Fm.shape}")
            H = (Fm - np.eye(d)).ravel()
            sv = np.einsum("gab,b->ga", self.voigt_stiffness(cloud)[self.shadow], P @ H)
            sig = sv @ P  # vec layout with both shear entries
        else:
            s = as_float_array(stress, "stress")
            if s.shape == (d, d):
                s = np.broadcast_to(s, (m, d, d))
            if s.shape != (m, d, d):
                raise ShapeError(
                    f"stress must have shape ({m}, {d}, {d}) or ({d}, {d}), got {s.shape}"
                )
            sig = s.reshape(m, d * d)
        vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
        full = np.zeros((p.gp_owner.size, d * d))
        rows = np.flatnonzero(~p.energy)  # gradient points of shadow particles
        owner = p.gp_owner[rows]
        wv = p.weight[rows] * vol[owner]
        full[rows] = sig[np.searchsorted(self.shadow, owner)] * wv[:, None]
        return -np.asarray(p.G.T @ full.ravel()).reshape(cloud.n, d)

    def describe(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "model": "Correspondence",
            "control": self.control,
            "plane": self.plane,
            "shadow": None if self.shadow is None else int(self.shadow.size),
        }
        if self.material is not None:
            out["material"] = type(self.material).__name__
        if self.control == "penalty":
            out["penalty"] = self.penalty
        if self.control == "stress_points":
            out.update(seed=self.seed, case=self.case, sp_weight=self.sp_weight)
        if self.control in ("springs", "ads"):
            out["coefficient"] = self.coefficient
        if self.assembly:
            out["assembly"] = self.assembly.get("path")
        return out

    def _repr_items(self) -> dict[str, Any]:
        items: dict[str, Any] = {}
        if self.E is not None:
            items["E"] = self.E
            items["nu"] = self.nu
        elif self.C is not None:
            items["C"] = np.asarray(self.C)
        return {**items, **super()._repr_items()}


def shadow_problem(
    model: Correspondence,
    cloud: PointCloud,
    bonds: Bonds,
    F: Any,
    *,
    depth: float | None = None,
    allow_odd: bool = False,
) -> Any:
    """Static problem with a shadow layer of depth δ prescribed to the affine field of ``F``.

    Returns a :class:`pdlin.StaticProblem` whose model is ``model`` with
    ``shadow`` set, whose Dirichlet condition is :func:`pdlin.shadow_layer`
    and whose load is the shadow-stress force :meth:`Correspondence.shadow_loads`
    (spec 000 §7).  Odd real counts along an axis make K_RR singular
    (spec 000 §4 parity rule) and raise unless ``allow_odd``; stress points,
    springs and ADS couple the sublattices and are exempt.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.models.correspondence import shadow_problem
    >>> cloud = pdlin.grid((12, 12), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=2.0)
    >>> C = pdlin.constitutive.isotropic_2d(1.0, 0.3, plane="strain")
    >>> F = np.eye(2) + [[0.02, 0.005], [0.003, -0.01]]
    >>> prob = shadow_problem(pdlin.Correspondence(C), cloud, bonds, F)
    >>> res = pdlin.solve(prob, solver="direct")
    >>> bool(np.abs(res.u - cloud.points @ (F - np.eye(2)).T).max() < 1e-12)
    True
    """
    from ..operators.bc import BodyForce, shadow_layer
    from ..problem import StaticProblem

    dep = float(np.max(bonds.horizon)) if depth is None else float(depth)
    bc, shadow = shadow_layer(cloud, F, dep)
    counts = shadow_real_counts(cloud, shadow)
    # stress points and springs / ADS couple the sublattices: no parity rule
    decoupled = model.control not in ("stress_points", "springs", "ads")
    if decoupled and not allow_odd and np.any(counts % 2 == 1):
        raise ModelError(
            f"real particle counts per axis must be even with a shadow layer (K_RR is singular "
            f"otherwise, spec 000 §4), got {counts.tolist()}; pass allow_odd=True to proceed"
        )
    params = dict(model.__dict__)
    m2 = Correspondence.__new__(Correspondence)
    m2.__dict__.update(params)
    m2.shadow = np.asarray(shadow, dtype=np.intp)
    m2._cache = None
    m2.assembly = {}
    f = m2.shadow_loads(cloud, bonds, F=F)
    real = np.setdiff1d(np.arange(cloud.n), shadow)
    vol = np.asarray(cloud.volumes) * (1.0 if cloud.dim == 3 else cloud.thickness)
    load = BodyForce(real, f[real] / vol[real, None])
    return StaticProblem(m2, cloud, bonds, dirichlet=[bc], loads=[load])


def solve_matrix_free(
    problem: Any,
    *,
    rtol: float = 1e-8,
    maxiter: int | None = None,
    preconditioner: str = "jacobi",
) -> Any:
    """Solve a static correspondence problem without assembling K.

    CG on the matrix-free operator ``K x = Gᵀ(D(G x))`` (+ penalty)
    restricted to the free DOFs, preconditioned by the diagonal of
    :meth:`Correspondence.surrogate_stiffness` (the bond-based K of the
    same bonds, ``'jacobi'``, default), smoothed-aggregation AMG on that
    surrogate (``'amg'``) or nothing (``'none'``).  The true residual is
    checked; a miss raises :class:`~pdlin.errors.ConvergenceError`.  This is
    ``pdlin.solve(problem, solver=..., operator="matrix-free")`` with the
    preconditioner named the Correspondence way.

    Measured (20³ cube, shadow layer, HO weights, rtol 1e-10; iterations
    none / jacobi / amg): δ = h 111 / 111 / 275, 2h 103 / 103 / 219,
    3h 569 / 569 / 720.  The bond-based surrogate does not see the
    odd-even decoupling of the correspondence operator, so its AMG
    hierarchy is a poor preconditioner; it is kept as an option.

    Returns
    -------
    pdlin.StaticResult
        ``info['solver']`` names the path and preconditioner.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.models.correspondence import solve_matrix_free
    >>> cloud = pdlin.grid((12, 6), spacing=0.1)
    >>> prob = pdlin.StaticProblem(pdlin.Correspondence(E=1.0, nu=0.3, control="penalty"),
    ...     cloud, horizon=0.2, dirichlet=[pdlin.Dirichlet("x-", 0.0)],
    ...     loads=[pdlin.TotalForce("x+", [1e-3, 0.0])])
    >>> res = solve_matrix_free(prob, rtol=1e-10)
    >>> ref = pdlin.solve(prob, solver="direct")
    >>> bool(np.allclose(res.u, ref.u, rtol=1e-7, atol=1e-9 * np.abs(ref.u).max()))
    True
    """
    from ..static import solve

    solvers = {"amg": "amg-cg", "jacobi": "jacobi-cg", "none": "cg"}
    if preconditioner not in solvers:
        raise InputError(
            f"preconditioner must be 'amg', 'jacobi' or 'none', got {preconditioner!r}"
        )
    if not isinstance(problem.model, Correspondence):
        raise InputError(
            f"problem.model must be a Correspondence, got {type(problem.model).__name__}"
        )
    return solve(
        problem,
        solver=solvers[preconditioner],
        rtol=rtol,
        maxiter=maxiter,
        operator="matrix-free",
    )


#: entries of a stress array from which ``w V P`` is multiplied in row chunks on threads
_THREADED_MULTIPLY = 1 << 18


def _threaded(p: _Plan, key: str, A: Any) -> Any:
    """``A`` for repeated mat-vecs: as :class:`pdlin._threads.RowBlocks` (built once,
    kept in the plan) when it holds at least two blocks' worth of entries, so that the
    nonlinear iterations' ``G u``, ``Gᵀ (w V P)`` and ``K_c u`` run on pdlin's threads
    (the same values bitwise); smaller ones stay plain scipy products."""
    from .._threads import ROW_BLOCK_NNZ, RowBlocks

    if A.nnz < 2 * ROW_BLOCK_NNZ:
        return A
    cache = p._lazy.setdefault("row_blocks", {})
    if key not in cache:
        cache[key] = RowBlocks(A, ROW_BLOCK_NNZ)
    return cache[key]


def _as_u(u: Any, cloud: PointCloud) -> np.ndarray:
    return as_displacement(u, cloud.n, cloud.dim)
