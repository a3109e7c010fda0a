"""Surface corrections of the bond-based and LPS models (after Le & Bobaru 2018).

Points within a horizon of a free surface have truncated families, so a model
calibrated on the full horizon is too soft there (the PD *surface* or *skin*
effect).  The corrections compute, once per ``(cloud, bonds)``, per-point
factors ``g_{k,i}`` (one per direction ``k``) by comparing the point's
discrete response to the continuum bulk value, and combine them into one
factor per bond that multiplies the bond's stiffness:

``'volume'``
    ``m_i = V_0(δ_i) / Σ_j V_j`` (full-ball volume over the neighbourhood
    volume), bond factor ``2 / (1/m_i + 1/m_j)`` (``= 2V_0 / (V_i + V_j)``
    for a constant horizon), the same in every direction.
``'energy'``
    ``g_{k,i} = W_bulk / W_i`` under the uniaxial unit strain
    ``u = x_k e_k`` (Madenci & Oterkus; Peridynamics.jl's
    ``EnergySurfaceCorrection``).
``'force-normalization'``
    ``g_{k,i} = F_bulk / F_i`` with ``F_i = Σ_j |t_ij n_k| V_j`` the total
    k-projected force density of the bonds under the same unit strain
    (the force density method of Macek & Silling as compared by Le & Bobaru).

Directional factors are averaged over the two ends of a bond and combined
through the ellipsoid of the bond's direction cosines,
``g_b = (Σ_k n_k² / ḡ_k²)^(-1/2)``, ``ḡ_k = (g_{k,i} + g_{k,j}) / 2``,
which is symmetric over the bond pair (so K stays symmetric).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._lazy import quad
from ..errors import InputError, ModelError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from ..geometry.influence import influence_function

__all__ = [
    "SURFACE_CORRECTIONS",
    "SurfaceFactors",
    "check_surface_correction",
    "ball_volume",
    "radial_moment",
    "volume_point_factors",
    "harmonic_bond_factors",
    "ellipsoid_bond_factors",
]

#: accepted values of ``surface_correction`` (besides None)
SURFACE_CORRECTIONS = ("volume", "energy", "force-normalization")


@dataclass(frozen=True, eq=False)
class SurfaceFactors:
    """Surface-correction factors of one model on one ``(cloud, bonds)`` pair.

    Attributes
    ----------
    method : str
        One of :data:`SURFACE_CORRECTIONS`.
    point : (n, dim) ndarray
        Directional point factors ``g_{k,i}`` (the volume method repeats
        ``m_i`` in every column).
    dilatation : (n,) ndarray
        Factor of the dilatational term of LPS (``m_i`` for 'volume', the mean
        of ``g_{k,i}`` over ``k`` otherwise); ones for bond-based models.
    bond : (nb,) ndarray
        Factor per directed bond, symmetric over bond pairs.
    """

    method: str
    point: np.ndarray
    dilatation: np.ndarray
    bond: np.ndarray


def check_surface_correction(value: Any, owner: str = "model") -> str | None:
    """Validate a ``surface_correction`` argument.

    Parameters
    ----------
    value : str or None
        None or one of ``'volume'``, ``'energy'``, ``'force-normalization'``.
    owner : str
        Name of the model, used in the error message.

    Returns
    -------
    str or None
        ``value`` unchanged.

    Raises
    ------
    InputError
        If ``value`` is not None and not a known correction.

    Examples
    --------
    >>> check_surface_correction(None), check_surface_correction("energy")
    (None, 'energy')
    >>> check_surface_correction("energie")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.InputError: surface_correction of model must be None or one of ...
    """
    if value is None or (isinstance(value, str) and value in SURFACE_CORRECTIONS):
        return value
    allowed = ", ".join(repr(v) for v in SURFACE_CORRECTIONS)
    raise InputError(
        f"surface_correction of {owner} must be None or one of {allowed}, got {value!r}"
    )


def ball_volume(horizon: Any, dim: int) -> np.ndarray:
    """Return the measure of the full ball of radius ``horizon``: ``2δ``, ``πδ²``, ``4πδ³/3``.

    Parameters
    ----------
    horizon : float or array_like of float
        Radius δ.
    dim : {1, 2, 3}
        Spatial dimension.

    Returns
    -------
    ndarray of float
        Length, area or volume, shape of ``horizon``.

    Raises
    ------
    InputError
        If ``dim`` is not 1, 2 or 3.

    Examples
    --------
    >>> float(ball_volume(1.0, 2)), float(ball_volume(3.0, 1))
    (3.141592653589793, 6.0)
    """
    h = np.asarray(horizon, dtype=float)
    if dim == 1:
        return 2.0 * h
    if dim == 2:
        return np.pi * h**2
    if dim == 3:
        return 4.0 * np.pi * h**3 / 3.0
    raise InputError(f"dim must be 1, 2 or 3, got {dim}")


def radial_moment(influence: Any, horizon: Any, p: float) -> np.ndarray:
    """Compute ``∫₀^δ ω(r, δ) r^p dr`` for each horizon (quadrature per distinct δ).

    Parameters
    ----------
    influence : str or callable
        Influence function; ``'constant'`` is integrated in closed form.
    horizon : float or array_like of float
        Horizon δ per entry.
    p : float
        Power of ``r``.

    Returns
    -------
    ndarray of float
        The integral, shape of ``horizon``.

    Examples
    --------
    >>> float(radial_moment("constant", 2.0, 3))
    4.0
    """
    hor = np.asarray(horizon, dtype=float)
    if isinstance(influence, str) and influence == "constant":
        return np.asarray(hor ** (p + 1) / (p + 1))
    fn = influence_function(influence)
    uniq, inv = np.unique(np.atleast_1d(hor), return_inverse=True)

    def one(h: float) -> float:
        def integrand(r: float) -> float:
            return float(fn(np.array([r]), np.array([h]))[0]) * r**p

        return float(quad(integrand, 0.0, h, limit=200)[0])

    vals = np.array([one(float(h)) for h in uniq])
    return vals[inv].reshape(hor.shape)


def _check_sphere(bonds: Bonds, method: str) -> None:
    if bonds.shape != "sphere":
        raise ModelError(
            f"surface_correction={method!r} needs spherical neighbourhoods "
            f"(find_bonds(shape='sphere')), got shape {bonds.shape!r}"
        )


def volume_point_factors(cloud: PointCloud, bonds: Bonds) -> np.ndarray:
    """Compute ``m_i = V_0(δ_i) / Σ_j V_j``, the full-ball over the neighbourhood volume.

    Parameters
    ----------
    cloud : PointCloud
        The points (dimension).
    bonds : Bonds
        Bonds of the cloud (CSR by owner point).

    Returns
    -------
    ndarray of float, shape (n,)
        Factor per point (1 for points without bonds).

    Raises
    ------
    ModelError
        If the bonds do not use spherical neighbourhoods.

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((12,), spacing=1.0)
    >>> m = volume_point_factors(cloud, pdlin.find_bonds(cloud, 2.0))
    >>> m[:3].tolist()   # end point sees 2 of 4 neighbours, the next 3 of 4
    [2.0, 1.3333333333333333, 1.0]
    """
    _check_sphere(bonds, "volume")
    vi = np.bincount(bonds.i, weights=bonds.volume_j, minlength=cloud.n)
    v0 = ball_volume(bonds.horizon, cloud.dim)
    return np.asarray(np.divide(v0, vi, out=np.ones(cloud.n), where=vi > 0))


def harmonic_bond_factors(m: np.ndarray, bonds: Bonds) -> np.ndarray:
    """Combine point factors ``m`` into the bond factor ``2 / (1/m_i + 1/m_j)``.

    Parameters
    ----------
    m : (n,) ndarray of float
        Factor per point, > 0.
    bonds : Bonds
        Bonds of the cloud (CSR by owner point).

    Returns
    -------
    ndarray of float, shape (n_bonds,)
        Harmonic mean of the two ends' factors, symmetric over bond pairs.
    """
    return 2.0 / (1.0 / m[bonds.i] + 1.0 / m[bonds.j])


def ellipsoid_bond_factors(g: np.ndarray, bonds: Bonds) -> np.ndarray:
    """Combine directional point factors ``g`` into one factor per bond.

    ``g_b = (Σ_k n_k² / ḡ_k²)^(-1/2)`` with ``ḡ_k = (g_{k,i} + g_{k,j})/2``
    and ``n`` the bond direction; equal factors give ``g_b = g``.

    Parameters
    ----------
    g : (n, dim) ndarray of float
        Factor per point and direction, > 0.
    bonds : Bonds
        Bonds of the cloud (CSR by owner point).

    Returns
    -------
    ndarray of float, shape (n_bonds,)
        Factor per directed bond, symmetric over bond pairs.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((5, 5), spacing=1.0)
    >>> bonds = pdlin.find_bonds(cloud, 1.5)
    >>> g = np.column_stack([np.full(25, 2.0), np.full(25, 2.0)])
    >>> bool(np.allclose(ellipsoid_bond_factors(g, bonds), 2.0))
    True
    """
    gb = 0.5 * (g[bonds.i] + g[bonds.j])
    n2 = (bonds.xi / bonds.length[:, None]) ** 2
    return np.asarray(1.0 / np.sqrt(np.einsum("bk,bk->b", n2, 1.0 / gb**2)))


def ratio_factors(target: np.ndarray, discrete: np.ndarray) -> np.ndarray:
    """Return ``target / discrete`` per point and direction; 1 where ``discrete`` is 0.

    A point has no discrete response in direction ``k`` only when all its bonds
    are normal to ``e_k``; every bond touching it then has ``n_k = 0`` and the
    value does not enter :func:`ellipsoid_bond_factors`.

    Parameters
    ----------
    target : ndarray of float
        Bulk (full-horizon) value, broadcast to ``discrete.shape``.
    discrete : (n, dim) ndarray of float
        Value of each point's actual family per direction, >= 0.

    Returns
    -------
    ndarray of float, shape of ``discrete``
        The correction factors.
    """
    t = np.broadcast_to(target, discrete.shape)
    ok = discrete > 1e-300
    return np.asarray(np.divide(t, discrete, out=np.ones(discrete.shape), where=ok))


#: ∫ |n_1|^p over the unit sphere (p = 3, 4) by dimension
_ANGULAR = {
    (1, 3): 2.0,
    (1, 4): 2.0,
    (2, 3): 8.0 / 3.0,
    (2, 4): 0.75 * np.pi,
    (3, 3): np.pi,
    (3, 4): 0.8 * np.pi,
}


def angular_moment(dim: int, p: int) -> float:
    """Return ``∫ |n_1|^p dΩ`` over the unit sphere of ``dim`` dimensions (p = 3 or 4).

    Parameters
    ----------
    dim : {1, 2, 3}
        Spatial dimension (in 1D the "sphere" is the two points ±1).
    p : {3, 4}
        Power of the direction component.

    Returns
    -------
    float
        The angular integral (closed-form table).

    Raises
    ------
    KeyError
        For another ``(dim, p)``.

    Examples
    --------
    >>> round(angular_moment(3, 4), 6)   # 4π/5
    2.513274
    """
    return float(_ANGULAR[(dim, p)])
