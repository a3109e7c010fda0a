"""Post-processing fields: nonlocal deformation gradient, strain, stress."""

from __future__ import annotations

import numpy as np

from ._arrays import per_point_outer
from ._threads import ptr_chunks
from .errors import InputError, ShapeError
from .geometry.bonds import Bonds
from .geometry.cloud import PointCloud

__all__ = [
    "shape_tensor",
    "deformation_gradient",
    "small_strain",
    "isotropic_stress",
    "von_mises",
]


def shape_tensor(bonds: Bonds) -> np.ndarray:
    """Compute the shape tensors ``K_i = Σ_j ω ξ⊗ξ V_j``.

    Parameters
    ----------
    bonds : Bonds
        Bonds with influence values ``omega`` and neighbour volumes ``volume_j``.

    Returns
    -------
    ndarray of float, shape (n, dim, dim)
        Symmetric shape tensor per point (zero for points without bonds).
    """
    return _family_sums(bonds, bonds.n_points, None)[0]


#: bonds per chunk of :func:`_family_sums` (whole families): its per-bond temporaries
#: (``i``, ``j``, ``ξ``, weights, ``η``; ~70 B a bond) stay at ~0.3 GB
_FIELD_CHUNK = 1 << 22


def _family_sums(
    bonds: Bonds, n: int, uu: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """``K = Σ ω V_j ξ⊗ξ`` and (with ``uu``) ``N = Σ ω V_j η⊗ξ`` of the points ``0:n``.

    Computed over chunks of whole families: each point's sums are over the same bonds in
    the same order as one pass over all bonds (the same bits), without per-bond arrays of
    all bonds.
    """
    d = bonds.dim
    K = np.zeros((n, d, d))
    N = None if uu is None else np.zeros((n, d, d))
    ptr = np.asarray(bonds.indptr)[: n + 1]
    for r0, r1 in ptr_chunks(ptr, _FIELD_CHUNK):
        b0, b1 = int(ptr[r0]), int(ptr[r1])
        own = bonds.values("i", b0, b1) - r0
        xi = bonds.values("xi", b0, b1)
        w = bonds.values("omega", b0, b1) * bonds.values("volume_j", b0, b1)
        K[r0:r1] = per_point_outer(own, r1 - r0, w, xi, xi)
        if uu is not None and N is not None:
            j = bonds.values("j", b0, b1)
            eta = uu[j] - uu[own + r0]
            N[r0:r1] = per_point_outer(own, r1 - r0, w, eta, xi)
    return K, N


def deformation_gradient(
    cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, n_owners: int | None = None
) -> np.ndarray:
    """Compute the nonlocal deformation gradient ``F_i = I + [Σ ω η⊗ξ V_j] K_i⁻¹``.

    Exact for affine displacement fields at every point whose shape tensor
    is invertible, boundary points included.

    ``n_owners`` restricts the evaluation to the first points (bonds are
    owner-sorted), e.g. the real points of a cloud extended by mirror
    images; the result then has ``n_owners`` rows.

    Parameters
    ----------
    cloud : PointCloud
        The points.
    bonds : Bonds
        Bonds of ``cloud``.
    u : (n, dim) or (n * dim,) array_like of float
        Displacement per point.
    n_owners : int, optional
        Evaluate only the first ``n_owners`` points.

    Returns
    -------
    ndarray of float, shape (n, dim, dim) or (n_owners, dim, dim)
        Deformation gradient per point.

    Raises
    ------
    ShapeError
        If ``u`` does not hold ``n * dim`` values.
    InputError
        If a shape tensor is singular (a family that does not span the space).

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((4, 4), spacing=0.25)
    >>> bonds = pdlin.find_bonds(cloud, ratio=1.5)
    >>> H = np.array([[1e-3, 2e-3], [0.0, -5e-4]])
    >>> F = deformation_gradient(cloud, bonds, cloud.points @ H.T)
    >>> bool(np.allclose(F, np.eye(2) + H, atol=1e-14))
    True
    """
    d = cloud.dim
    uu = np.asarray(u, dtype=float)
    if uu.size != cloud.n * d:
        raise ShapeError(f"u must have shape ({cloud.n}, {d}), got {uu.shape}")
    uu = uu.reshape(cloud.n, d)
    n = cloud.n if n_owners is None else int(n_owners)
    K, N = _family_sums(bonds, n, uu)
    assert N is not None
    det = np.linalg.det(K)
    scale = np.einsum("nii->n", K) ** d / d**d
    bad = np.flatnonzero(np.abs(det) <= 1e-12 * np.maximum(scale, 1e-300))
    if bad.size:
        raise InputError(
            f"shape tensor is singular at {bad.size} point(s) (first {int(bad[0])}, "
            f"{int(bonds.family_size[bad[0]])} bonds): its family does not span {d}D"
        )
    Kinv = np.linalg.inv(K)
    return np.eye(d)[None] + N @ Kinv


def small_strain(F: np.ndarray) -> np.ndarray:
    """Compute the small strain ``ε = sym(F) - I``.

    Parameters
    ----------
    F : (..., d, d) ndarray of float
        Deformation gradients.

    Returns
    -------
    ndarray of float, shape of ``F``
        Symmetric small-strain tensors.
    """
    d = F.shape[-1]
    return 0.5 * (F + np.swapaxes(F, -1, -2)) - np.eye(d)


def isotropic_stress(
    strain: np.ndarray, E: float | np.ndarray, nu: float, *, plane: str = "stress"
) -> np.ndarray:
    """Compute the linear isotropic Cauchy stress from small strain.

    2D uses plane stress or plane strain; 1D returns ``E ε``.

    Parameters
    ----------
    strain : (..., d, d) ndarray of float
        Small-strain tensors.
    E : float or (n,) array_like of float
        Young's modulus, scalar or per point (leading axis of ``strain``).
    nu : float
        Poisson ratio.
    plane : {'stress', 'strain'}
        2D assumption (ignored in 1D and 3D).

    Returns
    -------
    ndarray of float, shape of ``strain``
        Stress tensors (units of ``E``).

    Raises
    ------
    InputError
        If (2D or 3D) ``plane`` is not 'stress' or 'strain'.
    """
    d = strain.shape[-1]
    E = np.asarray(E, dtype=float)
    Eb = E[..., None, None] if E.ndim else E
    tr = np.einsum("...ii->...", strain)[..., None, None]
    eye = np.eye(d)
    if d == 1:
        return Eb * strain
    mu = Eb / (2.0 * (1.0 + nu))
    if d == 2 and plane == "stress":
        lam = Eb * nu / (1.0 - nu**2)
    elif d in (2, 3):
        if plane not in ("stress", "strain"):
            raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
        lam = Eb * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return lam * tr * eye + 2.0 * mu * strain


def von_mises(stress: np.ndarray) -> np.ndarray:
    """Compute the von Mises equivalent stress.

    Parameters
    ----------
    stress : (..., d, d) ndarray of float
        Stress tensors; 2D tensors are taken with zero out-of-plane stress.

    Returns
    -------
    ndarray of float, shape ``stress.shape[:-2]``
        ``sqrt(3 J2)`` per tensor.
    """
    d = stress.shape[-1]
    tr = np.einsum("...ii->...", stress)
    dev = stress - tr[..., None, None] / 3.0 * np.eye(d)
    j2 = 0.5 * np.einsum("...ij,...ij->...", dev, dev)
    if d == 2:
        j2 = j2 + 0.5 * (tr / 3.0) ** 2  # the out-of-plane deviatoric entry
    return np.sqrt(3.0 * j2)
