"""Single bond families of regular lattices (the input of one calibration).

A *family* is the neighbourhood of one bulk particle: bond vectors ``xi``,
influence values ``omega`` and neighbour volumes ``volume`` (areas in 2D).
Prakash, anisotropic micromoduli (§3) calibrates micromoduli on such a family; see
:func:`pdlin.calibrate_micromoduli`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._validation import as_float_array, positive_scalar
from ..errors import InputError, ShapeError
from ..geometry.bonds import SHAPES, shape_mask
from ..geometry.influence import InfluenceFunction, evaluate_influence

__all__ = ["Family", "LATTICES", "lattice_family", "equiangle_rotation", "reflection"]

#: Lattice names per dimension.
LATTICES: dict[int, tuple[str, ...]] = {3: ("cubic",), 2: ("square", "triangular")}


@dataclass(frozen=True, eq=False)
class Family:
    """One bond family: the bonds of a single particle.

    Attributes
    ----------
    xi : (M, dim) ndarray
        Bond vectors.
    omega : (M,) ndarray
        Influence function value per bond.
    volume : (M,) ndarray
        Neighbour volume per bond (area in 2D).
    thickness : float
        Out-of-plane thickness (2D; 1 in 3D).
    description : str
        Human-readable origin, used in calibration messages.

    Raises
    ------
    ShapeError
        If ``xi`` is not ``(M, 2)`` or ``(M, 3)``, or ``omega`` / ``volume`` is
        neither a scalar nor ``(M,)``.
    InputError
        If the family is empty, a bond vector is zero, ``omega < 0``,
        ``volume <= 0`` or the thickness is not > 0.
    """

    xi: Any
    omega: Any
    volume: Any
    thickness: float = 1.0
    description: str = ""

    def __post_init__(self) -> None:
        """Validate the fields: nonzero bonds, omega >= 0, volume > 0, positive thickness."""
        xi = as_float_array(self.xi, "xi")
        if xi.ndim != 2 or xi.shape[1] not in (2, 3):
            raise ShapeError(f"xi must have shape (M, dim) with dim 2 or 3, got {xi.shape}")
        m = xi.shape[0]
        if m == 0:
            raise InputError("xi must hold at least one bond, got an empty family (0 bonds)")
        length = np.sqrt(np.einsum("ij,ij->i", xi, xi))
        if np.any(length <= 0):
            k = int(np.flatnonzero(length <= 0)[0])
            raise InputError(f"xi must hold non-zero bond vectors, got a zero vector at bond {k}")
        om = _per_bond(self.omega, "omega", m)
        vol = _per_bond(self.volume, "volume", m)
        if np.any(om < 0):
            raise InputError(f"omega must be >= 0, got min {float(om.min())}")
        if np.any(vol <= 0):
            raise InputError(f"volume must be > 0, got min {float(vol.min())}")
        object.__setattr__(self, "xi", xi)
        object.__setattr__(self, "omega", om)
        object.__setattr__(self, "volume", vol)
        object.__setattr__(self, "thickness", positive_scalar(self.thickness, "thickness"))

    @property
    def n_bonds(self) -> int:
        """Number of bonds ``M``."""
        return int(self.xi.shape[0])

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        return int(self.xi.shape[1])

    @property
    def length(self) -> np.ndarray:
        """Bond lengths ``|xi|``, ``(M,)``."""
        return np.sqrt(np.einsum("ij,ij->i", self.xi, self.xi))

    def rotated(self, Q: Any) -> Family:
        """Return the family with every bond rotated, ``xi_N -> Q xi_N``.

        Index ``N``, lengths, ``omega`` and volumes are kept, as in the
        lattice rotation of Prakash, anisotropic micromoduli (§4.3.2).

        Parameters
        ----------
        Q : (dim, dim) array_like of float
            Orthogonal matrix.

        Returns
        -------
        Family
            A new family; its description gains ", rotated".

        Raises
        ------
        ShapeError
            If ``Q`` is not ``(dim, dim)``.
        InputError
            If ``Q`` is not orthogonal.
        """
        q = _check_rotation(Q, self.dim)
        return Family(
            self.xi @ q.T, self.omega, self.volume, self.thickness, self.description + ", rotated"
        )

    def __repr__(self) -> str:
        """Return bond count, dimension and description (no arrays)."""
        return f"Family(n_bonds={self.n_bonds}, dim={self.dim}, {self.description!r})"


def _per_bond(value: Any, name: str, m: int) -> np.ndarray:
    arr = as_float_array(value, name)
    if arr.ndim == 0:
        return np.full(m, float(arr))
    if arr.shape != (m,):
        raise ShapeError(f"{name} must be a scalar or have shape ({m},), got {arr.shape}")
    return arr.copy()


def _check_rotation(Q: Any, dim: int) -> np.ndarray:
    q = as_float_array(Q, "rotation")
    if q.shape != (dim, dim):
        raise ShapeError(f"rotation must have shape ({dim}, {dim}), got {q.shape}")
    if not np.allclose(q @ q.T, np.eye(dim), atol=1e-10):
        raise InputError(
            f"rotation must be orthogonal (Q Q^T = I), got |Q Q^T - I| = "
            f"{float(np.abs(q @ q.T - np.eye(dim)).max()):.3g}"
        )
    return q


def _lattice_basis(dim: int, lattice: str, spacing: float) -> np.ndarray:
    if dim not in LATTICES:
        raise InputError(f"dim must be 2 or 3, got {dim}")
    if lattice not in LATTICES[dim]:
        raise InputError(f"lattice must be one of {LATTICES[dim]} for dim = {dim}, got {lattice!r}")
    if lattice == "triangular":
        return spacing * np.array([[1.0, 0.0], [0.5, np.sqrt(3.0) / 2.0]])
    return spacing * np.eye(dim)


def lattice_family(
    dim: int,
    horizon: float,
    *,
    lattice: str | None = None,
    spacing: float = 1.0,
    shape: str = "sphere",
    axes: Sequence[float] | None = None,
    influence: str | InfluenceFunction = "constant",
    rotation: Any = None,
    thickness: float = 1.0,
    rtol: float = 1e-9,
) -> Family:
    """Build the bond family of a bulk particle of a regular lattice.

    Parameters
    ----------
    dim : {2, 3}
        Spatial dimension.
    horizon : float
        Horizon delta (absolute length); also the ``delta`` passed to the
        influence function for every shape.
    lattice : {'cubic'} (3D) or {'square', 'triangular'} (2D), optional
        Defaults to 'cubic' / 'square'.
    spacing : float
        Lattice spacing Delta.  Neighbour volume ``Delta**3`` (cubic),
        ``Delta**2`` (square) or ``(sqrt(3)/2) Delta**2`` (triangular).
    shape : {'sphere', 'cube', 'ellipsoid', 'box'}
        Neighbourhood shape as in :func:`pdlin.find_bonds` (inclusive
        membership with relative tolerance ``rtol``).
    axes : (dim,) sequence of float, optional
        Semi-axes / half-widths for 'ellipsoid' / 'box'.
    influence : str or callable
        Influence function name or ``f(length, horizon) -> omega``; the
        paper's examples use ``'delta_over_r'``.
    rotation : (dim, dim) array_like, optional
        Rotate every bond after the neighbourhood is selected (index,
        length, omega and volume are kept, see :meth:`Family.rotated`).
    thickness : float
        Out-of-plane thickness (2D).
    rtol : float
        Relative tolerance of the membership test.

    Returns
    -------
    Family
        Bond vectors, influence values, neighbour volumes and thickness.

    Raises
    ------
    InputError
        If ``dim``, ``lattice``, ``shape`` or ``axes`` is invalid, or the
        horizon selects no neighbour.

    Examples
    --------
    >>> fam = lattice_family(3, 6.0, influence="delta_over_r")
    >>> fam.n_bonds   # the paper's default neighbourhood (sphere, delta = 6)
    924
    >>> lattice_family(3, 2.0).n_bonds, lattice_family(2, 1.0, lattice="triangular").n_bonds
    (32, 6)
    """
    if dim not in (2, 3):
        raise InputError(f"dim must be 2 or 3, got {dim!r}")
    hor = positive_scalar(horizon, "horizon")
    h = positive_scalar(spacing, "spacing")
    lat = lattice if lattice is not None else LATTICES[dim][0]
    basis = _lattice_basis(dim, lat, h)
    if shape not in SHAPES:
        raise InputError(f"shape must be one of {SHAPES}, got {shape!r}")
    ax: np.ndarray | None = None
    if shape in ("ellipsoid", "box"):
        if axes is None:
            raise InputError(f"axes must be given for shape={shape!r}, got None")
        ax = as_float_array(axes, "axes")
        if ax.shape != (dim,) or np.any(ax <= 0):
            raise InputError(f"axes must be {dim} positive lengths, got {ax.tolist()}")
        reach = float(np.max(ax))
    elif axes is not None:
        raise InputError(f"axes is only used with shape 'ellipsoid' or 'box', got shape={shape!r}")
    else:
        reach = hor
    if shape in ("cube", "box"):
        reach *= np.sqrt(dim)
    smin = float(np.linalg.svd(basis, compute_uv=False).min())
    mx = int(np.ceil(reach * (1.0 + rtol) / smin)) + 1
    rng = np.arange(-mx, mx + 1)
    offs = np.stack([g.ravel() for g in np.meshgrid(*([rng] * dim), indexing="ij")], axis=1)
    offs = offs[np.any(offs != 0, axis=1)]
    vec = offs @ basis
    length = np.sqrt(np.einsum("ij,ij->i", vec, vec))
    keep = shape_mask(vec, length, np.full(length.size, hor), shape, ax, rtol)
    vec, length = vec[keep], length[keep]
    if vec.shape[0] == 0:
        raise InputError(
            f"horizon {hor} selects no neighbour on a {lat} lattice with spacing {h} "
            f"(shape {shape!r}); the family is empty"
        )
    omega = evaluate_influence(influence, length, np.full(length.size, hor))
    vol = float(abs(np.linalg.det(basis)))
    name = influence if isinstance(influence, str) else getattr(influence, "__name__", "callable")
    desc = f"{lat} lattice, {shape}, delta = {hor:g}, spacing {h:g}, omega {name}"
    if rotation is not None:
        q = _check_rotation(rotation, dim)
        vec = vec @ q.T
        desc += ", rotated"
    return Family(vec, omega, np.full(vec.shape[0], vol), thickness, desc)


def equiangle_rotation(theta: float) -> np.ndarray:
    """Return the equal-angle rotation ``R = R_x R_y R_z`` of Prakash, anisotropic micromoduli.

    The rotation of the paper's lattice-rotation study (Eq. 103), the same
    angle about each axis.  ``R_y`` is the transpose of the usual
    convention (kept for reproduction of the paper).

    Parameters
    ----------
    theta : float
        Angle about each axis, in radians.

    Returns
    -------
    ndarray of float, shape (3, 3)
        Proper orthogonal matrix.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(equiangle_rotation(np.pi / 2), 12) + 0.0
    array([[ 0.,  0., -1.],
           [ 0.,  1.,  0.],
           [ 1.,  0.,  0.]])
    """
    c, s = np.cos(theta), np.sin(theta)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    ry = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return rx @ ry @ rz


def reflection(normal: Sequence[float]) -> np.ndarray:
    """Return the mirror ``R(n) = I - 2 n n^T`` for the normalised normal ``n``.

    Parameters
    ----------
    normal : (d,) sequence of float
        Plane normal, any nonzero length.

    Returns
    -------
    ndarray of float, shape (d, d)
        Symmetric orthogonal matrix.

    Raises
    ------
    InputError
        If ``normal`` is zero.

    Examples
    --------
    >>> reflection([0, 0, 1])
    array([[ 1.,  0.,  0.],
           [ 0.,  1.,  0.],
           [ 0.,  0., -1.]])
    """
    n = as_float_array(normal, "normal", ndim=1)
    nn = float(np.linalg.norm(n))
    if nn == 0:
        raise InputError("normal must be a non-zero vector, got the zero vector")
    n = n / nn
    return np.eye(n.size) - 2.0 * np.outer(n, n)
