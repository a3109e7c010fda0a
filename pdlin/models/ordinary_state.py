"""Shared machinery of the ordinary state-based models (LPS / OSBPD and XOSB).

Notation follows Liu, Chen & Skelton, XOSB (Eqs. 9-70).  Per ordered bond ``b = (i -> j)``:

- ``e_b = n_b · (u_j - u_i)`` (linearized) or ``|Y| - r`` (nonlinear);
- ``θ_i = Σ_b a_b e_b`` with ``a_b = ω^h_b r_b V_j``;
- ``e^d_b = e_b - θ_i r_b / n_d``;
- paper force state ``t_b = κ ω̃^h r θ_i + 2μ ω̃^d e^d_b``;
- energy force state ``t^E_b = κ θ_i ω^h r + 2μ ω̃^d e^d_b - (2μ ω^h r / n_d) Z_i``,
  ``Z_i = Σ_k ω̃^d r e^d V_k``;
- nodal force ``f_i = Σ_b V_i V_j (t_b + t_rev(b)) M_b``, i.e. ``f = -B(M)ᵀ (w ⊙ t)``.

The linearized stiffness (``f = -K u``) is assembled with one sparse product
``K = Xᵀ Y`` of stacked point-level operators (derived):

- energy: ``K_E = Θᵀ diag(κV + s) Θ - ΓᵀΘ - ΘᵀΓ + Bᵀ diag(w c) B`` with
  ``Γ = Pᵀ diag(w c r / n_d) B`` and ``s_i = Σ_b w c r² / n_d²``
  (the expansion of ``Θᵀ diag(κV) Θ + Hᵀ diag(w c) H``);
- paper: ``K_p = Γ_βᵀ Θ + Bᵀ diag(w c) B`` with ``Γ_β = Pᵀ diag(w β) B``.
"""

from __future__ import annotations

import logging
import threading
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._kernels import bsr_matmul, csr_to_bsr_rows, csr_to_bsr_t, use_numba
from .._lazy import quad
from .._threads import even_chunks, ptr_chunks, thread_map
from .._validation import as_displacement, as_float_array
from ..constitutive.symmetry import isotropic_constants
from ..errors import AccuracyWarning, InputError, ModelError, ShapeError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from .base import Model
from .surface import (
    SurfaceFactors,
    check_surface_correction,
    ellipsoid_bond_factors,
    harmonic_bond_factors,
    radial_moment,
    ratio_factors,
    volume_point_factors,
)

__all__ = [
    "bulk_shear_moduli",
    "analytic_weighted_volume",
    "StateWeights",
    "OrdinaryStateBased",
    "basis_h",
    "basis_d",
    "TARGET_H",
    "TARGET_D",
]

log = logging.getLogger(__name__)

#: bonds per preprocessing / assembly chunk
_CHUNK = 1 << 14

_PLANES = ("stress", "strain")
_LINEARIZATIONS = ("energy", "paper")

#: right-hand sides r of the constraint systems (Liu, Chen & Skelton, XOSB, Eqs. 29-64)
TARGET_H = {2: np.array([1.0, 1.0, 0.0]), 3: np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])}
TARGET_D = {
    2: np.array([1.5, 1.5, 0.5, 0.0, 0.0]),
    3: np.array([1.5, 1.5, 1.5, 0.5, 0.5, 0.5] + [0.0] * 9),
}


def uniform_nu_constants(
    owner: str, E: Any, nu: Any, *, K: Any, G: Any, lam: Any, mu: Any
) -> tuple[Any, float]:
    """Return ``(E, ν)`` from any two isotropic constants, with one ν for every point.

    pdlin's isotropic models take per-point ``E`` and one ``ν``; per-point
    constants that imply a varying ν raise (use a per-point Voigt ``C``).

    Parameters
    ----------
    owner : str
        Name of the model, for the error message.
    E, nu : float or (n,) array_like or None
        Young's modulus and Poisson ratio.
    K, G, lam, mu : float or (n,) array_like or None
        Bulk modulus, shear modulus, Lamé's first constant, shear modulus.

    Returns
    -------
    E : float or ndarray
        Young's modulus (per point when the constants are).
    nu : float
        The one Poisson ratio.

    Raises
    ------
    InputError
        Not two constants, or constants implying a varying ν.
    """
    E_, nu_ = isotropic_constants(E, nu, K=K, G=G, lam=lam, mu=mu)
    nu_arr = np.asarray(nu_, dtype=float)
    if nu_arr.ndim and float(np.ptp(nu_arr)) > 1e-12 * max(1.0, float(np.abs(nu_arr).max())):
        raise InputError(
            f"{owner} takes one Poisson ratio for all points, but the given constants imply "
            f"nu from {float(nu_arr.min()):.6g} to {float(nu_arr.max()):.6g}; give constants "
            "with a uniform ratio (or a per-point Voigt C to Correspondence)"
        )
    return E_, float(nu_arr.ravel()[0])


def elastic_constants(
    owner: str, E: Any, nu: Any, *, K: Any, G: Any, lam: Any, mu: Any, plane: str
) -> tuple[np.ndarray, float, str]:
    """Return the checked elastic constants ``(E, ν, plane)`` of a state-based model.

    The one front of the isotropic constants of :class:`OrdinaryStateBased`,
    :class:`pdlin.LPS` and :class:`pdlin.XOSB`: ``E`` and ``nu``, or any two of
    ``K, G, lam, mu`` (converted by :func:`uniform_nu_constants`).

    Parameters
    ----------
    owner : str
        Name of the model, for the error messages.
    E : float or (n,) array_like or None
        Young's modulus (per point for graded materials).
    nu : float or None
        Poisson ratio in (-1, 0.5).
    K, G, lam, mu : float or (n,) array_like or None
        Bulk modulus, shear modulus, Lamé's first constant, shear modulus (``mu`` is
        ``G``): any two instead of ``E, nu``.
    plane : {'stress', 'strain'}
        2D assumption.

    Returns
    -------
    E : ndarray
        Young's modulus, a 0-d or ``(n,)`` float array, positive.
    nu : float
        The Poisson ratio, one for every point.
    plane : str
        ``plane``, checked.

    Raises
    ------
    InputError
        Neither ``E, nu`` nor two other constants, constants implying a varying ν,
        ``E <= 0`` or not a scalar / ``(n,)`` array, ``nu`` outside (-1, 0.5), or an
        unknown ``plane``.

    Examples
    --------
    >>> E, nu, plane = elastic_constants("LPS", None, None, K=5.0, G=3.0, lam=None,
    ...                                  mu=None, plane="strain")
    >>> round(float(E), 12), round(nu, 12), plane   # E = 9KG/(3K+G), ν = (3K-2G)/(2(3K+G))
    (7.5, 0.25, 'strain')
    """
    if all(v is None for v in (K, G, lam, mu)):
        if E is None or nu is None:
            raise InputError(
                f"{owner} needs E and nu (or two of K, G, lam, mu), got E = {E!r}, nu = {nu!r}"
            )
    else:
        E, nu = uniform_nu_constants(owner, E, nu, K=K, G=G, lam=lam, mu=mu)
    E_arr = as_float_array(E, "E")
    if E_arr.ndim > 1 or np.any(E_arr <= 0):
        raise InputError(f"E must be a positive scalar or (n,) array, got {E!r}")
    try:
        nu_f = float(nu)
    except (TypeError, ValueError) as exc:
        raise InputError(f"nu must be a number in (-1, 0.5), got {nu!r}") from exc
    if not -1.0 < nu_f < 0.5:
        raise InputError(f"nu must be in (-1, 0.5), got {nu_f}")
    if plane not in _PLANES:
        raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
    return E_arr, nu_f, plane


def bulk_shear_moduli(E: Any, nu: float, dim: int, plane: str = "stress") -> tuple[Any, Any]:
    """Return the bulk modulus κ and shear modulus μ (Liu, Chen & Skelton, XOSB, Eq. 66).

    ``κ = E/(3(1-2ν))`` (3D), ``E/(2(1+ν)(1-2ν))`` (plane strain),
    ``E/(2(1-ν))`` (plane stress); ``μ = E/(2(1+ν))``.

    Parameters
    ----------
    E : float or (n,) array_like
        Young's modulus.
    nu : float
        Poisson ratio.
    dim : {2, 3}
        Spatial dimension.
    plane : {'stress', 'strain'}
        2D assumption.

    Returns
    -------
    kappa, mu : float or ndarray
        Same shape as ``E``.

    Examples
    --------
    >>> k, m = bulk_shear_moduli(70e9, 0.33, 2, "stress")
    >>> round(k / 1e9, 3), round(m / 1e9, 3)
    (52.239, 26.316)
    """
    mu = E / (2.0 * (1.0 + nu))
    if dim == 3:
        kappa = E / (3.0 * (1.0 - 2.0 * nu))
    elif dim == 2:
        if plane == "stress":
            kappa = E / (2.0 * (1.0 - nu))
        elif plane == "strain":
            kappa = E / (2.0 * (1.0 + nu) * (1.0 - 2.0 * nu))
        else:
            raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
    else:
        raise ModelError(f"ordinary state-based models need dim 2 or 3, got dim {dim}")
    return kappa, mu


def analytic_weighted_volume(horizon: Any, dim: int) -> np.ndarray:
    """Return the weighted volume ``m = ∫ ω r² dV`` of a full ball with ω = 1.

    Liu, Chen & Skelton, XOSB, Eq. 25.

    ``πδ⁴/2`` in 2D, ``4πδ⁵/5`` in 3D.

    Parameters
    ----------
    horizon : float or (n,) array_like
        Horizon δ.
    dim : {2, 3}
        Spatial dimension.

    Returns
    -------
    ndarray of float
        Same shape as ``horizon``.

    Examples
    --------
    >>> float(analytic_weighted_volume(1.0, 2)), float(analytic_weighted_volume(1.0, 3))
    (1.5707963267948966, 2.5132741228718345)
    """
    h = np.asarray(horizon, dtype=float)
    if dim == 2:
        return np.pi * h**4 / 2.0
    if dim == 3:
        return 4.0 * np.pi * h**5 / 5.0
    raise ModelError(f"ordinary state-based models need dim 2 or 3, got dim {dim}")


def _basis_h_t(x: np.ndarray) -> np.ndarray:
    """Hydrostatic basis from component-major ``x`` ``(d, m)``: ``(k, m)``."""
    if x.shape[0] == 2:
        x0, x1 = x
        return np.stack([x0 * x0, x1 * x1, x0 * x1])
    x0, x1, x2 = x
    return np.stack([x0 * x0, x1 * x1, x2 * x2, x0 * x1, x1 * x2, x2 * x0])


def _basis_d_t(x: np.ndarray) -> np.ndarray:
    """Deviatoric basis from component-major ``x`` ``(d, m)``: ``(k, m)``."""
    inv_r2 = 1.0 / np.einsum("im,im->m", x, x)
    if x.shape[0] == 2:
        x0, x1 = x
        a, b = x0 * x0, x1 * x1
        cols = [a * a, b * b, a * b, a * x0 * x1, b * x1 * x0]
    else:
        x0, x1, x2 = x
        a, b, c = x0 * x0, x1 * x1, x2 * x2
        cols = [
            a * a,
            b * b,
            c * c,
            a * b,
            b * c,
            c * a,
            a * x0 * x1,
            a * x0 * x2,
            b * x1 * x0,
            b * x1 * x2,
            c * x2 * x0,
            c * x2 * x1,
            a * x1 * x2,
            b * x0 * x2,
            c * x0 * x1,
        ]
    out = np.stack(cols)
    out *= inv_r2
    return out


def basis_h(x: np.ndarray) -> np.ndarray:
    """Return the hydrostatic basis ξ̂^h per bond.

    Liu, Chen & Skelton, XOSB, Eqs. 30-44.

    Parameters
    ----------
    x : (m, d) ndarray of float
        Bond vectors ξ.

    Returns
    -------
    (m, 3) or (m, 6) ndarray of float
        2D or 3D.

    Examples
    --------
    >>> basis_h(np.array([[1.0, 2.0]]))
    array([[1., 4., 2.]])
    """
    return _basis_h_t(np.asarray(x, dtype=float).T).T


def basis_d(x: np.ndarray) -> np.ndarray:
    """Return the deviatoric basis ξ̂^d per bond.

    Liu, Chen & Skelton, XOSB, Eqs. 45-64.

    Parameters
    ----------
    x : (m, d) ndarray of float
        Bond vectors ξ.

    Returns
    -------
    (m, 5) or (m, 15) ndarray of float
        2D or 3D.

    Examples
    --------
    >>> basis_d(np.array([[1.0, 1.0]]))
    array([[0.5, 0.5, 0.5, 0.5, 0.5]])
    """
    return _basis_d_t(np.asarray(x, dtype=float).T).T


def _buffer(store: dict[int, np.ndarray], shape: tuple[int, int]) -> np.ndarray:
    """Return a reusable (rows, cols) work array (grown when a larger chunk needs it)."""
    buf = store.get(shape[0])
    if buf is None or buf.shape[1] < shape[1]:
        buf = np.empty((shape[0], max(shape[1], _CHUNK)))
        store[shape[0]] = buf
    return buf[:, : shape[1]]


def _segment_sum(x: np.ndarray, ptr: np.ndarray) -> np.ndarray:
    """Return the sums of ``x[:, ptr[r]:ptr[r+1]]`` over contiguous segments: ``(k, rows)``."""
    rows = ptr.size - 1
    out = np.zeros((x.shape[0], rows))
    nonempty = ptr[1:] > ptr[:-1]
    if nonempty.any():
        out[:, nonempty] = np.add.reduceat(x, ptr[:-1][nonempty], axis=1)
    return out


@dataclass(frozen=True, eq=False)
class StateWeights:
    """Per-bond influence weights of an ordinary state-based model.

    Attributes
    ----------
    omega_h, omega_d : (nb,) ndarray
        Corrected (XOSB) or spherical (LPS) hydrostatic / deviatoric weights.
    omega_h_s, omega_d_s : (nb,) ndarray
        Spherical weights ``n_d ω/m_i`` and ``n_d(n_d+2) ω/(2 m_i)``.
    omega_h_force, omega_d_force : (nb,) ndarray
        Weights ω̃ used in the force state (spherical at fallback points).
    fallback : (n,) ndarray of bool
        Points whose family has some ω^h < 0 (Liu, Chen & Skelton, XOSB, Sec. 3.3).
    singular : (n,) ndarray of bool
        Points whose λ system was singular or ill-conditioned (min-norm λ used).
    cond_h, cond_d : (n,) ndarray
        Condition numbers of the scaled Gram matrices: 1-norm (2-norm where a system
        went through the eigendecomposition path), NaN for LPS.
    weighted_volume : (n,) ndarray
        ``m_i`` used by the spherical weights.
    """

    omega_h: np.ndarray
    omega_d: np.ndarray
    omega_h_s: np.ndarray
    omega_d_s: np.ndarray
    omega_h_force: np.ndarray
    omega_d_force: np.ndarray
    fallback: np.ndarray
    singular: np.ndarray
    cond_h: np.ndarray
    cond_d: np.ndarray
    weighted_volume: np.ndarray

    @property
    def fallback_points(self) -> np.ndarray:
        """Indices of the fallback points."""
        return np.flatnonzero(self.fallback)


def _row_chunks(indptr: np.ndarray, chunk: int = _CHUNK) -> list[tuple[int, int]]:
    """Ranges of owner rows holding about ``chunk`` bonds each (rows never split)."""
    return ptr_chunks(indptr, chunk)


def _solve_eigh(
    gram: np.ndarray, rhs: np.ndarray, max_cond: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eigendecomposition path: 2-norm condition, minimum-norm λ where it is too large."""
    lam, vec = np.linalg.eigh(gram)
    top = np.maximum(lam[:, -1], np.finfo(float).tiny)
    low = lam[:, 0]
    cond = np.where(low > 0, top / np.where(low > 0, low, 1.0), np.inf)
    bad = ~(cond <= max_cond)
    cut = np.where(bad, 1e-10, 0.0)[:, None] * top[:, None]
    keep = lam > cut
    inv = np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)
    proj = np.einsum("nkl,nk->nl", vec, rhs)
    sol = np.einsum("nkl,nl->nk", vec, proj * inv)
    return sol, cond, bad


def _solve_batched(
    gram: np.ndarray, rhs: np.ndarray, max_cond: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve the stack ``A_i λ_i = R_i``; minimum-norm λ where ``A_i`` is ill-conditioned.

    Batched Cholesky (positive definiteness) and inverse give λ and the 1-norm condition
    number ``‖A‖₁‖A⁻¹‖₁``; systems above ``max_cond`` (and every system of a batch whose
    Cholesky fails) go through a symmetric eigendecomposition, whose pseudo-inverse gives
    the minimum-norm λ.  Returns ``(λ, cond, bad)``.
    """
    if gram.shape[0] == 0:
        return np.zeros_like(rhs), np.zeros(0), np.zeros(0, dtype=bool)
    try:
        np.linalg.cholesky(gram)  # raises if any system is not positive definite
        inv = np.linalg.inv(gram)
    except np.linalg.LinAlgError:
        return _solve_eigh(gram, rhs, max_cond)
    norm_a = np.abs(gram).sum(axis=1).max(axis=1)
    norm_inv = np.abs(inv).sum(axis=1).max(axis=1)
    cond = norm_a * norm_inv
    bad = ~(cond <= max_cond)
    sol = np.einsum("nkl,nl->nk", inv, rhs)
    if bad.any():
        sol[bad], cond[bad], _ = _solve_eigh(gram[bad], rhs[bad], 0.0)
    return sol, cond, bad


def compute_weights(
    cloud: PointCloud,
    bonds: Bonds,
    *,
    corrections: bool,
    weighted_volume: str,
    unit_influence: bool = False,
    fallback: bool = True,
    max_cond: float = 1e10,
) -> StateWeights:
    """Return the spherical and (optionally) corrected influence weights.

    Liu, Chen & Skelton, XOSB, Eqs. 9-64 and Sec. 3.3.

    Vectorized and chunked over owner rows: Gram entries are accumulated by
    segment sums over the owner-sorted bonds per chunk, the small systems are solved
    in batches, and no ``nb x k x k`` array is formed.

    Parameters
    ----------
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).
    corrections : bool
        Solve for the corrected weights ω^h, ω^d (XOSB); else spherical only.
    weighted_volume : {'analytic', 'discrete'}
        ``m_i`` of the spherical weights.
    unit_influence : bool
        Ignore the bonds' ω (use 1, Peridigm's convention).
    fallback : bool
        Apply the fallback rule at points with some ω^h < 0.
    max_cond : float
        Scaled condition number above which a point's system is solved by minimum norm
        and flagged singular.

    Returns
    -------
    StateWeights
    """
    d = cloud.dim
    n = cloud.n
    nb = bonds.n_bonds
    omega = np.ones(nb) if unit_influence else np.asarray(bonds.omega, dtype=float)
    r = bonds.length
    vj = bonds.volume_j
    if weighted_volume == "analytic":
        infl = getattr(bonds, "influence", "constant")
        if not unit_influence and not (isinstance(infl, str) and infl == "constant"):
            raise ModelError(
                "weighted_volume='analytic' needs the constant influence function (ω = 1), "
                f"got influence={infl!r}; use weighted_volume='discrete'"
            )
        m = analytic_weighted_volume(bonds.horizon, d)
    elif weighted_volume == "discrete":
        m = np.bincount(bonds.i, weights=omega * r * r * vj, minlength=n)
        if np.any(m <= 0):
            k = int(np.flatnonzero(m <= 0)[0])
            raise ModelError(f"weighted volume must be > 0 at every point, got 0 at point {k}")
    else:
        raise InputError(
            f"weighted_volume must be 'analytic' or 'discrete', got {weighted_volume!r}"
        )
    mb = m[bonds.i]
    wh_s = d * omega / mb
    wd_s = d * (d + 2) * omega / (2.0 * mb)
    cond_h = np.full(n, np.nan)
    cond_d = np.full(n, np.nan)
    singular = np.zeros(n, dtype=bool)
    if not corrections:
        fb = np.zeros(n, dtype=bool)
        return StateWeights(wh_s, wd_s, wh_s, wd_s, wh_s, wd_s, fb, singular, cond_h, cond_d, m)
    wh = np.empty(nb)
    wd = np.empty(nb)
    indptr = np.asarray(bonds.indptr, dtype=np.int64)
    scale = np.asarray(bonds.horizon, dtype=float)
    th, td = TARGET_H[d], TARGET_D[d]
    local = threading.local()  # one set of work buffers per thread

    def chunk(rng: tuple[int, int]) -> None:
        r0, r1 = rng
        buffers: dict[int, np.ndarray] = local.__dict__.setdefault("buffers", {})
        b0, b1 = int(indptr[r0]), int(indptr[r1])
        own = bonds.values("i", b0, b1)
        loc = own - r0
        ptr = indptr[r0 : r1 + 1] - b0
        s = scale[own]
        xt = bonds.values("xi", b0, b1).T / s  # component-major (d, m), scaled by the owner's δ
        v = vj[b0:b1]
        s2 = s * s
        for phi, target, ws, out, cnd in (
            (_basis_h_t(xt), th, wh_s[b0:b1], wh, cond_h),
            (_basis_d_t(xt), td, wd_s[b0:b1], wd, cond_d),
        ):
            k = phi.shape[0]
            iu, ju = np.triu_indices(k)
            pv = phi * v
            # products of the distinct pairs (p, q >= p), row by row into a reused buffer
            # (fresh large temporaries cost more in first-touch page faults than in flops)
            prod = _buffer(buffers, (iu.size, phi.shape[1]))
            off = 0
            for a in range(k):
                np.multiply(phi[a], pv[a:], out=prod[off : off + k - a])
                off += k - a
            gram_u = _segment_sum(prod, ptr).T  # (rows, k(k+1)/2)
            gram = np.empty((r1 - r0, k, k))
            gram[:, iu, ju] = gram_u
            gram[:, ju, iu] = gram_u
            rhs = target[None, :] - _segment_sum(pv * (s2 * ws), ptr).T
            lam, cond, bad = _solve_batched(gram, rhs, max_cond)
            cnd[r0:r1] = cond
            singular[r0:r1] |= bad
            corr = np.einsum("km,km->m", phi, lam.T[:, loc])
            out[b0:b1] = ws + corr / s2

    # fixed chunks of owner rows on the threads: each writes its own rows and bonds
    thread_map(chunk, _row_chunks(indptr))
    if singular.any():
        idx = np.flatnonzero(singular)
        warnings.warn(
            f"XOSB: {idx.size} point(s) have a singular or ill-conditioned λ system "
            f"(cond > {max_cond:g}), first index {int(idx[0])}; minimum-norm λ used. "
            "Perturb the horizon slightly or change the influence function.",
            stacklevel=3,
        )
    neg = np.bincount(bonds.i, weights=(wh < 0).astype(float), minlength=n) > 0
    fb = neg if fallback else np.zeros(n, dtype=bool)
    if fb.any():
        log.info("XOSB fallback (some ω^h < 0) at %d point(s)", int(fb.sum()))
        fbb = fb[bonds.i]
        whf = np.where(fbb, wh_s, wh)
        wdf = np.where(fbb, wd_s, wd)
    else:
        whf, wdf = wh, wd
    return StateWeights(wh, wd, wh_s, wd_s, whf, wdf, fb, singular, cond_h, cond_d, m)


def _point_operator(
    bonds: Bonds, coef: np.ndarray, unit: np.ndarray, n: int, d: int
) -> sp.csr_array:
    """``Pᵀ diag(coef) B`` as an ``n x n·d`` CSR array (row i = Σ_{b∈i} coef_b B_b).

    Row ``i`` holds the ``d``-blocks ``coef_b n_b`` at the neighbors ``j_b`` and
    ``-Σ_b coef_b n_b`` at ``i``, sorted by column, explicit zeros kept.  With the
    neighbors of each family increasing (the :class:`Bonds` order) the blocks are written
    in place in point chunks on the threads (:func:`pdlin._threads.thread_map`), each
    per-point sum over the same bonds in the same order as one global ``np.bincount``;
    otherwise a COO -> CSR conversion sorts them.  Both give the same array bitwise.
    """
    cn = coef[:, None] * unit  # (nb, d)
    ii, jj = bonds.i, bonds.j
    ptr = np.asarray(bonds.indptr, dtype=np.int64)
    nb = ii.size
    if not _families_sorted(bonds):
        diag = np.empty((n, d))
        for k in range(d):
            diag[:, k] = -np.bincount(ii, weights=cn[:, k], minlength=n)
        rows = np.concatenate([np.repeat(ii, d), np.repeat(np.arange(n), d)])
        cols = np.concatenate(
            [
                (d * jj[:, None] + np.arange(d)).ravel(),
                (d * np.arange(n)[:, None] + np.arange(d)).ravel(),
            ]
        )
        data = np.concatenate([cn.ravel(), diag.ravel()])
        out = sp.coo_array((data, (rows, cols)), shape=(n, n * d)).tocsr()
        out.sum_duplicates()
        return out
    nblk = nb + n
    idt = np.int32 if nblk * d < np.iinfo(np.int32).max else np.int64
    blk = np.empty((nblk, d))
    col = np.empty((nblk, d), dtype=idt)
    ar = np.arange(d, dtype=idt)

    def chunk(rng: tuple[int, int]) -> None:
        p0, p1 = rng
        b0, b1 = int(ptr[p0]), int(ptr[p1])
        own = ii[b0:b1]
        nbr = jj[b0:b1]
        # block slot of bond b: b + i_b (one diagonal block per earlier row) + [j_b > i_b]
        pos = np.arange(b0, b1) + own + (nbr > own)
        blk[pos] = cn[b0:b1]
        col[pos] = nbr[:, None].astype(idt) * d + ar
        loc = own - p0
        pts = np.arange(p0, p1)
        lt = np.bincount(loc[nbr < own], minlength=p1 - p0)  # neighbors before the owner
        dpos = ptr[p0:p1] + pts + lt
        for k in range(d):
            blk[dpos, k] = -np.bincount(loc, weights=cn[b0:b1, k], minlength=p1 - p0)
        col[dpos] = pts[:, None].astype(idt) * d + ar

    thread_map(chunk, _row_chunks(ptr, 1 << 18))
    indptr = (d * (ptr + np.arange(n + 1))).astype(idt)
    out = sp.csr_array((blk.ravel(), col.ravel(), indptr), shape=(n, n * d))
    out.has_sorted_indices = True
    return out


def _families_sorted(bonds: Bonds) -> bool:
    """Whether every family lists distinct neighbors other than its owner, increasing."""
    ii, jj = bonds.i, bonds.j
    if ii.size == 0:
        return True
    if np.any(ii == jj):
        return False
    step = np.diff(jj) > 0
    same_row = ii[1:] == ii[:-1]
    if not (bool(np.all(step | ~same_row)) and bool(np.all(np.diff(ii) >= 0))):
        return False
    # owners agree with the row pointer (the chunks are cut by it)
    counts = np.bincount(ii, minlength=bonds.indptr.size - 1)
    return counts.size == bonds.indptr.size - 1 and bool(np.all(counts == np.diff(bonds.indptr)))


def _force_angular(rho: float, d: int) -> float:
    """``∫ |ρ + (d+2)(n_1² - 1/d)| |n_1| dΩ`` over the unit sphere (ρ = κ/μ)."""
    if d == 2:

        def f2(a: float) -> float:
            c = np.cos(a)
            return abs(rho + 4.0 * (c * c - 0.5)) * abs(c)

        return float(4.0 * quad(f2, 0.0, 0.5 * np.pi, limit=200)[0])

    def f3(c: float) -> float:  # c = cos φ, dΩ = 2π dc
        return abs(rho + 5.0 * (c * c - 1.0 / 3.0)) * c

    return float(4.0 * np.pi * quad(f3, 0.0, 1.0, limit=200)[0])


def _segment_max(x: np.ndarray, indptr: np.ndarray) -> np.ndarray:
    """Per-owner maximum of non-negative bond values (0 for empty families)."""
    ptr = np.asarray(indptr, dtype=np.int64)
    out = np.zeros(ptr.size - 1)
    nonempty = ptr[1:] > ptr[:-1]
    if nonempty.any():
        out[nonempty] = np.maximum.reduceat(x, ptr[:-1][nonempty])
    return out


def _take_rows(rows_op: sp.csr_array, rows: np.ndarray, n: int) -> sp.csr_array:
    """Scatter the rows of ``rows_op`` back to positions ``rows`` of an n-row array."""
    sel = sp.csr_array((np.ones(rows.size), (rows, np.arange(rows.size))), shape=(n, rows.size))
    return sel @ rows_op


def _bond_operator(bonds: Bonds, unit: np.ndarray, n: int, d: int) -> sp.csr_array:
    """``B`` (nb x n·d): row b = -n_bᵀ at the owner, +n_bᵀ at the neighbor.

    Written in fixed bond chunks on the threads (:func:`pdlin._threads.thread_map`).
    """
    nb = bonds.n_bonds
    idt = np.int32 if max(n * d, 2 * d * nb) < np.iinfo(np.int32).max else np.int64
    cols = np.empty((nb, 2 * d), dtype=idt)
    data = np.empty((nb, 2 * d))
    ar = np.arange(d, dtype=idt)

    def chunk(rng: tuple[int, int]) -> None:
        b0, b1 = rng
        cols[b0:b1, :d] = bonds.values("i", b0, b1)[:, None].astype(idt) * d + ar
        cols[b0:b1, d:] = bonds.j[b0:b1, None].astype(idt) * d + ar
        np.negative(unit[b0:b1], out=data[b0:b1, :d])
        data[b0:b1, d:] = unit[b0:b1]

    thread_map(chunk, even_chunks(nb, 1 << 18))
    indptr = np.arange(0, 2 * d * nb + 1, 2 * d, dtype=idt)
    return sp.csr_array((data.ravel(), cols.ravel(), indptr), shape=(nb, n * d))


def _scale_rows(data: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Return ``data`` of ``B`` (``2·d`` entries per row) times ``w`` per row, on threads."""
    k = data.size // max(w.size, 1)
    src = data.reshape(w.size, k)
    out = np.empty_like(src)

    def chunk(rng: tuple[int, int]) -> None:
        b0, b1 = rng
        np.multiply(src[b0:b1], w[b0:b1, None], out=out[b0:b1])

    thread_map(chunk, even_chunks(w.size, 1 << 18))
    return out.ravel()


#: κ/μ from which LPS-type models check their dilatation (ν ≈ 0.49 in plane strain and 3D;
#: plane stress never reaches it: κ/μ = (1 + ν)/(1 - ν) <= 3)
KAPPA_MU_WARN = 40.0
#: largest |θ - 1| under a unit uniaxial strain that counts as exact
DILATATION_TOL = 1e-6


class OrdinaryStateBased(Model):
    """Common base of :class:`pdlin.LPS` and :class:`pdlin.XOSB` (not public)."""

    coupling_range = 2
    _corrections = False

    def __init__(
        self,
        E: Any = None,
        nu: Any = None,
        *,
        K: Any = None,
        G: Any = None,
        lam: Any = None,
        mu: Any = None,
        plane: str = "stress",
        linearization: str = "energy",
        weighted_volume: str = "analytic",
        fallback: bool = True,
        unit_influence: bool = False,
        max_cond: float = 1e10,
        surface_correction: str | None = None,
    ) -> None:
        self.surface_correction = check_surface_correction(surface_correction, type(self).__name__)
        self._surface_cache: tuple[PointCloud, Bonds, SurfaceFactors] | None = None
        self.E, self.nu, self.plane = elastic_constants(
            type(self).__name__, E, nu, K=K, G=G, lam=lam, mu=mu, plane=plane
        )
        if linearization not in _LINEARIZATIONS:
            raise InputError(f"linearization must be 'energy' or 'paper', got {linearization!r}")
        if weighted_volume not in ("analytic", "discrete"):
            raise InputError(
                f"weighted_volume must be 'analytic' or 'discrete', got {weighted_volume!r}"
            )
        self.linearization = linearization
        self.weighted_volume = weighted_volume
        self.fallback = bool(fallback)
        self.unit_influence = bool(unit_influence)
        self.max_cond = float(max_cond)
        self.symmetric = linearization == "energy"
        self._cache: tuple[PointCloud, Bonds, StateWeights] | None = None

    # -- material ------------------------------------------------------------
    def moduli(self, dim: int) -> tuple[Any, Any]:
        """Return the bulk and shear moduli ``(κ, μ)`` for ``dim``.

        Parameters
        ----------
        dim : {2, 3}
            Spatial dimension.

        Returns
        -------
        kappa, mu : float or ndarray
            Scalars or per point.
        """
        return bulk_shear_moduli(self.E, self.nu, dim, self.plane)

    def weights(self, cloud: PointCloud, bonds: Bonds) -> StateWeights:
        """Return the influence weights of this model on ``bonds`` (cached for the last pair).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        StateWeights

        Raises
        ------
        ModelError, ShapeError
            A 1D cloud, or bonds of another cloud.
        """
        if cloud.dim not in (2, 3):
            raise ModelError(f"{type(self).__name__} needs a 2D or 3D cloud, got dim {cloud.dim}")
        if bonds.n_points != cloud.n or bonds.dim != cloud.dim:
            raise ShapeError(
                f"bonds were built for {bonds.n_points} points in {bonds.dim}D, "
                f"got a cloud of {cloud.n} points in {cloud.dim}D"
            )
        if self._cache is not None and self._cache[0] is cloud and self._cache[1] is bonds:
            return self._cache[2]
        w = compute_weights(
            cloud,
            bonds,
            corrections=self._corrections,
            weighted_volume=self.weighted_volume,
            unit_influence=self.unit_influence,
            fallback=self.fallback,
            max_cond=self.max_cond,
        )
        # strong references: an id() key could be reused by a new object after GC
        self._cache = (cloud, bonds, w)
        self._warn_near_incompressible(cloud, bonds, w)
        return w

    def _warn_near_incompressible(self, cloud: PointCloud, bonds: Bonds, w: StateWeights) -> None:
        """Warn when κ/μ >= :data:`KAPPA_MU_WARN` and the dilatation is not exact.

        The measured cause: κ multiplies the dilatation error of the uniaxial
        strains ``u = x_k e_k`` (θ should be 1) at truncated families, and
        the field follows it (``docs/solvers.md``, "Numerical extremes").
        XOSB's corrected weights make θ exact, so it does not warn.
        """
        d = cloud.dim
        kappa, mu = self.moduli(d)
        ratio = float(np.max(np.asarray(kappa, dtype=float) / np.asarray(mu, dtype=float)))
        if ratio < KAPPA_MU_WARN:
            return
        n = cloud.n
        err = np.zeros(n)
        own, xi, vj = bonds.i, bonds.xi, bonds.volume_j
        for k in range(d):
            theta = np.bincount(own, weights=w.omega_h * xi[:, k] ** 2 * vj, minlength=n)
            err = np.maximum(err, np.abs(theta - 1.0))
        bad = err > DILATATION_TOL
        if not bad.any():
            return
        where = "3D" if d == 3 else f"plane {self.plane}"
        warnings.warn(
            f"{type(self).__name__} with nu = {self.nu:g} ({where}: kappa/mu = {ratio:.3g}): "
            f"the dilatation of a uniaxial strain is off by up to {err.max():.1%} at "
            f"{int(bad.sum())} point(s) (first index {int(np.flatnonzero(bad)[0])}; truncated "
            "or uncorrected families) and kappa amplifies that error: a plane-strain bar with "
            "free surfaces measured -12 % at nu = 0.49 and -37 % at nu = 0.4999 (+4 % at "
            "nu = 0.3). Use XOSB (exact dilatation) near incompressibility; see docs/solvers.md, "
            "'Numerical extremes'.",
            AccuracyWarning,
            stacklevel=3,
        )

    def _coefficients(self, cloud: PointCloud, bonds: Bonds) -> dict[str, Any]:
        """Per-bond / per-point coefficients, surface-corrected when asked."""
        co = self._raw_coefficients(cloud, bonds)
        sf = self.surface_factors(cloud, bonds)
        if sf is not None:
            alpha = sf.dilatation
            co["c"] = co["c"] * sf.bond
            co["kh"] = co["kh"] * alpha[bonds.i]
            co["kth"] = co["kth"] * alpha[bonds.i]
            co["kV"] = co["kV"] * alpha
        return co

    def surface_factors(self, cloud: PointCloud, bonds: Bonds) -> SurfaceFactors | None:
        """Return the surface-correction factors on ``bonds`` (None without correction).

        ``dilatation`` (per point) multiplies κ, ``bond`` (per directed bond,
        symmetric over the pair) multiplies the deviatoric modulus ``2μω^d``
        (``docs/state_based.md``).  Cached for the last ``(cloud, bonds)`` pair.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        SurfaceFactors or None
        """
        method = self.surface_correction
        if method is None:
            return None
        cache = self._surface_cache
        if cache is not None and cache[0] is cloud and cache[1] is bonds:
            return cache[2]
        d = cloud.dim
        if method == "volume":
            m = volume_point_factors(cloud, bonds)
            g = np.repeat(m[:, None], d, axis=1)
            out = SurfaceFactors(method, g, m, harmonic_bond_factors(m, bonds))
        else:
            g = self._directional_factors(cloud, bonds, method)
            out = SurfaceFactors(method, g, g.mean(axis=1), ellipsoid_bond_factors(g, bonds))
        self._surface_cache = (cloud, bonds, out)
        return out

    def _directional_factors(self, cloud: PointCloud, bonds: Bonds, method: str) -> np.ndarray:
        """``g_{k,i}`` of the 'energy' / 'force-normalization' methods, ``(n, d)``.

        Under the unit uniaxial strain ``u = x_k e_k`` (``e = r n_k²``), with the
        uncorrected coefficients: energy ``W_i = κθ²/2 + μ Σ ω̃^d (e^d)² V_j`` against
        ``κ/2 + μ(n_d-1)/n_d``; force ``F_i = Σ_j |t n_k| V_j`` (paper force state) against
        its continuum value ``(n_d/m) ∫ω r^{n_d} dr ∫|κ + (n_d+2)μ(n_1² - 1/n_d)||n_1| dΩ``.
        """
        # compact bonds compute these on each access: read them once
        bi = bonds.i
        n, d = cloud.n, cloud.dim
        co = self._raw_coefficients(cloud, bonds)
        kappa, mu = self.moduli(d)
        kap = np.broadcast_to(kappa, (n,)).astype(float)
        mup = np.broadcast_to(mu, (n,)).astype(float)
        r = bonds.length
        vj = bonds.volume_j
        nabs = np.abs(bonds.xi / r[:, None])
        disc = np.empty((n, d))
        for k in range(d):
            e = r * nabs[:, k] ** 2
            theta = np.bincount(bi, weights=co["a"] * e, minlength=n)
            ed = e - theta[bi] * r / d
            if method == "energy":
                dev = np.bincount(bi, weights=co["c"] * ed * ed * vj, minlength=n)
                disc[:, k] = 0.5 * kap * theta**2 + 0.5 * dev
            else:
                t = co["kh"] * theta[bi] + co["c"] * ed
                disc[:, k] = np.bincount(bi, weights=np.abs(t) * nabs[:, k] * vj, minlength=n)
        if method == "energy":
            target = 0.5 * kap + mup * (d - 1) / d
        else:
            infl = "constant" if self.unit_influence else getattr(bonds, "influence", "constant")
            hor = np.asarray(bonds.horizon, dtype=float)
            full = 2.0 * np.pi if d == 2 else 4.0 * np.pi
            m_bulk = full * radial_moment(infl, hor, d + 1)
            k1, m1 = bulk_shear_moduli(1.0, self.nu, d, self.plane)
            ang = _force_angular(float(k1) / float(m1), d)
            target = d / m_bulk * radial_moment(infl, hor, d) * mup * ang
        return ratio_factors(target[:, None], disc)

    def _raw_coefficients(self, cloud: PointCloud, bonds: Bonds) -> dict[str, Any]:
        d = cloud.dim
        w = self.weights(cloud, bonds)
        kappa, mu = self.moduli(d)
        vol = np.asarray(cloud.volumes, dtype=float)
        meas = 1.0 if d == 3 else float(cloud.thickness)
        kap = np.broadcast_to(kappa, (cloud.n,)).astype(float)
        mub = np.broadcast_to(mu, (cloud.n,))[bonds.i]
        r = bonds.length
        return {
            "w": vol[bonds.i] * bonds.volume_j * meas,
            "a": w.omega_h * r * bonds.volume_j,
            "c": 2.0 * mub * w.omega_d_force,
            "kh": kap[bonds.i] * w.omega_h_force * r,  # κ ω̃^h r
            "kth": kap[bonds.i] * w.omega_h * r,  # κ ω^h r (energy)
            "kV": kap * vol * meas,
            "d": d,
        }

    # -- kinematics ----------------------------------------------------------
    def _extension(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray, linear: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        uu = as_displacement(u, cloud.n, cloud.dim)
        eta = uu[bonds.j] - uu[bonds.i]
        if linear:
            unit = bonds.xi / bonds.length[:, None]
            return np.einsum("ij,ij->i", unit, eta), unit
        y = bonds.xi + eta
        ly = np.sqrt(np.einsum("ij,ij->i", y, y))
        if np.any(ly <= 0):
            raise InputError("u collapses a bond to zero length; the force state is undefined")
        return ly - bonds.length, y / ly[:, None]

    def dilatation(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, linear: bool = True
    ) -> np.ndarray:
        """Return the dilatation ``θ_i = Σ_j ω^h r e V_j`` (corrected ω^h).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.
        linear : bool
            Linearized extension (True) or ``|ξ+η| - |ξ|``.

        Returns
        -------
        (n,) ndarray of float
        """
        e, _ = self._extension(cloud, bonds, u, linear)
        w = self.weights(cloud, bonds)
        return np.bincount(
            bonds.i, weights=w.omega_h * bonds.length * bonds.volume_j * e, minlength=cloud.n
        )

    def strain_energy_density(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray,
        *,
        linear: bool = True,
        force_weights: bool = False,
    ) -> np.ndarray:
        """Return the strain energy density ``W_i = κθ²/2 + μ Σ_j ω^d (e^d)² V_j``.

        Liu, Chen & Skelton, XOSB, Eq. 22.

        ``force_weights=True`` uses ω̃^d (spherical at fallback points), the
        energy whose Hessian is ``K_E``.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.
        linear : bool
            Linearized extension (True) or ``|ξ+η| - |ξ|``.
        force_weights : bool
            Use the force-state weights ω̃^d.

        Returns
        -------
        (n,) ndarray of float
        """
        d = cloud.dim
        e, _ = self._extension(cloud, bonds, u, linear)
        w = self.weights(cloud, bonds)
        kappa, mu = self.moduli(d)
        theta = np.bincount(
            bonds.i, weights=w.omega_h * bonds.length * bonds.volume_j * e, minlength=cloud.n
        )
        ed = e - theta[bonds.i] * bonds.length / d
        wd = w.omega_d_force if force_weights else w.omega_d
        sf = self.surface_factors(cloud, bonds)
        if sf is not None:
            wd = wd * sf.bond
            kappa = kappa * sf.dilatation
        dev = np.bincount(bonds.i, weights=wd * ed * ed * bonds.volume_j, minlength=cloud.n)
        return 0.5 * kappa * theta**2 + mu * dev

    def force_state(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray,
        *,
        linear: bool = True,
        variant: str | None = None,
    ) -> np.ndarray:
        """Return the scalar force state ``t_b`` per ordered bond (``paper`` or ``energy``).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.
        linear : bool
            Linearized extension (True) or ``|ξ+η| - |ξ|``.
        variant : {'paper', 'energy'}, optional
            Default: the model's ``linearization``.

        Returns
        -------
        (nb,) ndarray of float
        """
        t, _, _ = self._force_state(cloud, bonds, u, linear, variant or self.linearization)
        return t

    def _force_state(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray | None,
        linear: bool,
        variant: str,
        extension: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
        # compact bonds compute these on each access: read them once
        bi = bonds.i
        blen = bonds.length
        bvj = bonds.volume_j
        co = self._coefficients(cloud, bonds)
        d = co["d"]
        if extension is None:
            assert u is not None  # a displacement, or a given extension state
            e, unit = self._extension(cloud, bonds, u, linear)
        else:  # a given extension state (thermal eigenstrain), reference directions
            e, unit = extension, bonds.xi / blen[:, None]
        theta = np.bincount(bi, weights=co["a"] * e, minlength=cloud.n)
        thb = theta[bi]
        ed = e - thb * blen / d
        cd = co["c"] * ed
        if variant == "paper":
            t = co["kh"] * thb + cd
        else:
            z = np.bincount(bi, weights=cd * blen * bvj, minlength=cloud.n)
            t = (co["kth"] * thb + cd) - (co["a"] / bvj / d) * z[bi]
        return t, unit, co

    def internal_force(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, linear: bool = True
    ) -> np.ndarray:
        """Return the nodal internal force ``f_i = Σ_j V_iV_j (t_ij + t_ji) M_ij``.

        ``linear=True`` uses ``e = n·η`` along the reference direction, so
        ``f == -K u``; ``linear=False`` uses ``e = |ξ+η| - |ξ|`` and the
        deformed direction ``M``.  The force state is the paper's (Eq. 70)
        or the energy-consistent one, per ``linearization``.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.
        linear : bool
            Reference direction and linearized extension (True) or the deformed ones.

        Returns
        -------
        (n, d) ndarray of float
        """
        t, unit, co = self._force_state(cloud, bonds, u, linear, self.linearization)
        d = cloud.dim
        tw = co["w"] * t
        tw = tw + tw[bonds.reverse]
        f = np.empty((cloud.n, d))
        for k in range(d):
            f[:, k] = np.bincount(bonds.i, weights=tw * unit[:, k], minlength=cloud.n)
        return f

    def extension_response(
        self, cloud: PointCloud, bonds: Bonds, extension: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the linear force and stress of a given bond-extension state.

        :meth:`internal_force` (``linear=True``) and :meth:`stress` with the extension
        ``e_b`` given per ordered bond instead of ``n·(u_j - u_i)`` (the thermal
        eigenstrain of :mod:`pdlin.models.thermal`).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        extension : (nb,) ndarray of float
            Extension per ordered bond (length units).

        Returns
        -------
        force : (n, d) ndarray of float
            Nodal force (the model's ``linearization``).
        stress : (n, d, d) ndarray of float
            ``Σ_j t_ij n_ij ⊗ ξ_ij V_j`` with the paper's force state.
        """
        e = np.asarray(extension, dtype=float)
        t, unit, co = self._force_state(cloud, bonds, None, True, self.linearization, e)
        d = cloud.dim
        tw = co["w"] * t
        tw = tw + tw[bonds.reverse]
        force = np.stack(
            [np.bincount(bonds.i, weights=tw * unit[:, k], minlength=cloud.n) for k in range(d)],
            axis=1,
        )
        tp, _, _ = self._force_state(cloud, bonds, None, True, "paper", e)
        g = tp * bonds.volume_j
        xi = bonds.xi
        stress = np.empty((cloud.n, d, d))
        for a in range(d):
            for b in range(d):
                stress[:, a, b] = np.bincount(
                    bonds.i, weights=g * unit[:, a] * xi[:, b], minlength=cloud.n
                )
        return force, stress

    def stress(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Return the per-point stress ``σ_i = Σ_j t_ij n_ij ⊗ ξ_ij V_j`` (paper t).

        Equals ``κ tr ε I + 2μ ε^d`` for affine ``u`` at non-fallback XOSB
        points (Liu, Chen & Skelton, XOSB, Eq. 29, stress consistency).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.

        Returns
        -------
        (n, d, d) ndarray of float
        """
        t, unit, _ = self._force_state(cloud, bonds, u, True, "paper")
        d = cloud.dim
        out = np.empty((cloud.n, d, d))
        g = t * bonds.volume_j
        for a in range(d):
            for b in range(d):
                out[:, a, b] = np.bincount(
                    bonds.i, weights=g * unit[:, a] * bonds.xi[:, b], minlength=cloud.n
                )
        return out

    # -- operators -----------------------------------------------------------
    def stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.bsr_array:
        """Return the assembled linearized stiffness, ``f = -K u``.

        One sparse product ``Xᵀ Y`` of stacked point-level operators (see the
        module docstring); ``K_E`` for ``linearization='energy'``, ``K_p`` for
        ``'paper'``.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        scipy.sparse.bsr_array
            ``(n*d, n*d)``, blocks ``(d, d)``.
        """
        d, n = cloud.dim, cloud.n
        co = self._coefficients(cloud, bonds)
        unit = bonds.xi / bonds.length[:, None]
        r = bonds.length
        wc = co["w"] * co["c"]
        B = _bond_operator(bonds, unit, n, d)
        theta_op = _point_operator(bonds, co["a"], unit, n, d)
        Bw = sp.csr_array((_scale_rows(B.data, wc), B.indices, B.indptr), shape=B.shape)
        if self.linearization == "energy":
            gcoef = wc * r / d
            s = np.bincount(bonds.i, weights=wc * r * r / d**2, minlength=n)
            # owners whose row Γ_i is ρ_i Θ_i (spherical weights: LPS, fallback-free
            # families with ω^d ∝ ω^h) fold -ΓᵀΘ - ΘᵀΓ into the diagonal weight:
            # one product Θᵀ diag(g) Θ instead of three row blocks
            a = co["a"]
            rho = np.bincount(bonds.i, weights=gcoef * a, minlength=n)
            den = np.bincount(bonds.i, weights=a * a, minlength=n)
            rho = np.divide(rho, den, out=np.zeros(n), where=den > 0)
            dev = np.abs(gcoef - rho[bonds.i] * a)
            gmax = _segment_max(np.abs(gcoef), bonds.indptr)
            devmax = _segment_max(dev, bonds.indptr)
            prop = devmax <= 1e-14 * gmax
            g = co["kV"] + s - 2.0 * np.where(prop, rho, 0.0)
            gdiag = sp.dia_array((g, 0), shape=(n, n))
            if prop.all():
                Xs = [theta_op, B]
                Ys = [gdiag @ theta_op, Bw]
            else:
                rows = np.flatnonzero(~prop)
                gam = _point_operator(bonds, gcoef, unit, n, d)[rows]
                Xs = [theta_op, gam, B]
                Ys = [gdiag @ theta_op - _take_rows(gam, rows, n), -theta_op[rows], Bw]
                del gam
        else:
            wb = co["w"] * r * (co["kh"] / r - co["c"] / d)  # w β
            Xs = [_point_operator(bonds, wb, unit, n, d), B]
            Ys = [theta_op, Bw]
        del B, Bw, theta_op
        if use_numba(sum(x.nnz for x in Xs) * d):
            # row-parallel product with sorted block columns (pdlin._kernels): (d x 1)
            # blocks of Xᵀ times (1 x d) blocks of Y give the d x d blocks of K directly
            # (no transpose); each entry sums the products of the scipy path below in
            # another order (BSR conversion order), equal to ~1e-15 relative.  X and Y
            # go to blocks from their stacked pieces in row chunks on the threads
            # (scipy's vstack, CSR -> CSC and tobsr: serial), the same blocks bitwise
            Xt = csr_to_bsr_t(Xs, d)
            del Xs
            Yb = csr_to_bsr_rows(Ys, d)
            del Ys
            Kb = bsr_matmul(Xt, Yb)
            if not Kb.has_sorted_indices:  # scipy fallback of a product below _MIN_WORK
                Kb.sort_indices()
            return Kb
        X = sp.vstack(Xs, format="csr")
        del Xs
        Y = sp.vstack(Ys, format="csr")
        del Ys
        # block product: (d x 1) blocks of Yᵀ times (1 x d) blocks of X give the d x d
        # blocks of Kᵀ directly (faster than a scalar CSR product + tobsr); the final
        # O(nnz) block transpose returns K with sorted block indices (cheaper than a sort)
        Yt = sp.bsr_array(Y.T.tocsr().tobsr(blocksize=(d, 1)))
        del Y
        Xb = sp.bsr_array(X.tobsr(blocksize=(1, d)))
        del X
        Kt = sp.bsr_array(Yt @ Xb)
        del Yt, Xb
        Kb = sp.bsr_array(Kt.transpose())
        del Kt
        if not Kb.has_sorted_indices:
            Kb.sort_indices()
        return Kb

    def operator(self, cloud: PointCloud, bonds: Bonds) -> spla.LinearOperator:
        """Return the matrix-free ``K`` as a :class:`~scipy.sparse.linalg.LinearOperator`.

        Products use the factors ``B`` (nb x n·dim, 2·dim entries per row)
        and per-bond coefficients only: ``K u = Bᵀ (w ⊙ t(Bu))``; memory is
        O(nb) instead of the O(two-hop) of the assembled matrix.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        scipy.sparse.linalg.LinearOperator
            ``(n*d, n*d)``.
        """
        d, n = cloud.dim, cloud.n
        co = self._coefficients(cloud, bonds)
        unit = bonds.xi / bonds.length[:, None]
        B = _bond_operator(bonds, unit, n, d)
        Bt = B.T.tocsr()
        own = bonds.i
        r = bonds.length
        a, c, w = co["a"], co["c"], co["w"]
        paper = self.linearization == "paper"
        kh = co["kh"] if paper else co["kth"]
        zc = a / bonds.volume_j / d
        rv = r * bonds.volume_j

        def matvec(x: np.ndarray) -> np.ndarray:
            e = B @ np.ravel(x)
            theta = np.bincount(own, weights=a * e, minlength=n)[own]
            cd = c * (e - theta * r / d)
            t = kh * theta + cd
            if not paper:
                t -= zc * np.bincount(own, weights=cd * rv, minlength=n)[own]
            return Bt @ (w * t)

        return spla.LinearOperator((n * d, n * d), matvec=matvec, dtype=float)

    def estimate_nnz_blocks(self, cloud: PointCloud, bonds: Bonds) -> int:
        """Return the blocks of K without assembling it: nnz of the pattern of (A + I)².

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        int
        """
        n = cloud.n
        adj = sp.csr_array(
            (np.ones(bonds.n_bonds, dtype=np.float32), bonds.j, bonds.indptr), shape=(n, n)
        ) + sp.eye_array(n, dtype=np.float32, format="csr")
        total = 0
        for r0, r1 in _row_chunks(np.asarray(adj.indptr, dtype=np.int64), 1 << 22):
            total += int((adj[r0:r1] @ adj).nnz)
        return total

    def surrogate_stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.sparray:
        """Return the one-hop matrix that preconditions the matrix-free path.

        It is the stiffness of :class:`pdlin.BondBased` with this model's ``E`` and
        ``plane`` on the same bonds, spectrally close to the state-based ``K``.

        Parameters
        ----------
        cloud : PointCloud
            The points.
        bonds : Bonds
            Their bonds.

        Returns
        -------
        scipy.sparse.bsr_array
            The bond-based ``K``, ``(n*dim, n*dim)``.
        """
        from .bond_based import BondBased

        return BondBased(E=self.E, plane=self.plane).stiffness(cloud, bonds)

    def describe(self) -> dict[str, Any]:
        """Return a plain-data description of the model (for results and logs).

        Returns
        -------
        dict
            Model name, constants and options.
        """
        return {
            "model": type(self).__name__,
            "E": float(self.E) if self.E.ndim == 0 else "per-point",
            "nu": self.nu,
            "plane": self.plane,
            "linearization": self.linearization,
            "weighted_volume": self.weighted_volume,
            "corrections": self._corrections,
            "fallback": self.fallback,
        }
