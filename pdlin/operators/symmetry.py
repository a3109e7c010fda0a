r"""Symmetry planes: model a half, quarter or eighth of a mirror-symmetric body.

Points within reach of a symmetry plane bond to *mirror images* (ghosts)
of their neighbors; a ghost carries the volume, horizon and material of
its source point and the reflected displacement ``u_g = R u_s`` of it, so
no fictitious material is added.  The reduced operator on the real DOFs is

.. math::

    K_{sym} = W \, E^T K_{aug} P ,

with ``P`` the expansion from real to augmented DOFs (identity on real
points, the diagonal reflection ``R`` times the source displacement on
ghosts), ``E`` the selection of real rows and ``W`` the share of each real
point's volume that belongs to the reduced model (1, or 1/2, 1/4, 1/8 for
points lying on one, two or three planes).  ``K_sym = Pᵀ K_full P / |G|``
is the Hessian of the reduced energy, hence symmetric whenever ``K`` is;
see ``docs/symmetry.md`` for the derivation.
"""

from __future__ import annotations

import copy
import logging
import operator
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .._arrays import with_diagonal_blocks
from .._validation import as_float_array
from ..constraints import check_constraints, load_vector
from ..errors import (
    FloatingBodyError,
    InputError,
    InputTypeError,
    ModelError,
    NoNeighborsError,
    ShapeError,
)
from ..fields import deformation_gradient
from ..geometry.bonds import Bonds, MirroredCracks, find_bonds, resolve_horizon
from ..geometry.cloud import PointCloud
from .assembly import assemble_stiffness
from .bc import BodyForce, Dirichlet, TotalForce
from .rigid import rigid_body_modes, rigid_mode_names

__all__ = [
    "SymmetryPlane",
    "MirrorCloud",
    "SymmetryReduction",
    "mirror_cloud",
    "symmetry_reduction",
    "ON_PLANE_RTOL",
]

log = logging.getLogger(__name__)

#: A point whose distance to a plane is at most ``ON_PLANE_RTOL`` times its
#: spacing ``V ** (1/dim)`` lies *on* the plane: it gets no ghost and its
#: normal displacement is prescribed to zero.
ON_PLANE_RTOL = 1e-10

_AXES = {"x": 0, "y": 1, "z": 2}
_SIDES = (None, "+", "-")


@dataclass(frozen=True)
class SymmetryPlane:
    """A mirror-symmetry plane ``x_axis = position``.

    Parameters
    ----------
    axis : {0, 1, 2, 'x', 'y', 'z'}
        Axis normal to the plane.
    position : float
        Coordinate of the plane along ``axis`` (default 0).
    side : {None, '+', '-'}
        Side of the plane holding the modelled points; None detects it
        from the cloud (every point must lie on one side).

    Examples
    --------
    >>> SymmetryPlane("y", 0.5)
    SymmetryPlane(axis=1, position=0.5, side=None)
    >>> SymmetryPlane("w")
    Traceback (most recent call last):
    ...
    pdlin.errors.InputError: axis must be 0, 1, 2 or one of 'x', 'y', 'z', got 'w'
    """

    axis: int | str
    position: float = 0.0
    side: str | None = None

    def __post_init__(self) -> None:
        """Normalize ``axis`` to 0, 1 or 2 and ``position`` to a float; check ``side``."""
        ax = self.axis
        if isinstance(ax, str):
            if ax.lower() not in _AXES:
                raise InputError(f"axis must be 0, 1, 2 or one of 'x', 'y', 'z', got {ax!r}")
            k = _AXES[ax.lower()]
        else:
            if isinstance(ax, bool | np.bool_):
                raise InputTypeError(f"axis must be an int or 'x'/'y'/'z', got {ax!r}")
            try:
                k = operator.index(ax)
            except TypeError:
                raise InputTypeError(
                    f"axis must be an int or 'x'/'y'/'z', got {type(ax).__name__}"
                ) from None
            if k not in (0, 1, 2):
                raise InputError(f"axis must be 0, 1, 2 or one of 'x', 'y', 'z', got {ax!r}")
        pos = as_float_array(self.position, "position")
        if pos.ndim != 0:
            raise ShapeError(f"position must be a scalar, got shape {pos.shape}")
        if self.side not in _SIDES:
            raise InputError(f"side must be None, '+' or '-', got {self.side!r}")
        object.__setattr__(self, "axis", int(k))
        object.__setattr__(self, "position", float(pos))

    @property
    def name(self) -> str:
        """Readable name, e.g. ``'x = 0'``."""
        return f"{'xyz'[int(self.axis)]} = {self.position:g}"

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Return ``x[axis] - position`` of each point.

        Parameters
        ----------
        points : (n, dim) array_like
            Positions.

        Returns
        -------
        (n,) ndarray
            Signed distance to the plane, positive on the ``+`` side.
        """
        return np.asarray(points)[:, int(self.axis)] - self.position

    def reflect(self, points: np.ndarray) -> np.ndarray:
        """Return the mirror images of points across the plane.

        Parameters
        ----------
        points : (n, dim) array_like
            Positions.

        Returns
        -------
        (n, dim) ndarray
            A new array, coordinate ``axis`` replaced by ``2 position - x[axis]``.

        Examples
        --------
        >>> import numpy as np
        >>> SymmetryPlane(0, 1.0).reflect(np.array([[1.5, 2.0]]))
        array([[0.5, 2. ]])
        """
        out = np.array(points, dtype=float, copy=True)
        k = int(self.axis)
        out[:, k] = 2.0 * self.position - out[:, k]
        return out


def _as_planes(planes: Any, dim: int) -> tuple[SymmetryPlane, ...]:
    if isinstance(planes, SymmetryPlane):
        planes = (planes,)
    try:
        pl = tuple(planes)
    except TypeError:
        raise InputTypeError(
            f"planes must be a sequence of SymmetryPlane, got {type(planes).__name__}"
        ) from None
    for k, p in enumerate(pl):
        if not isinstance(p, SymmetryPlane):
            raise InputTypeError(f"planes[{k}] must be a SymmetryPlane, got {type(p).__name__}")
        if int(p.axis) >= dim:
            raise InputError(
                f"planes[{k}].axis must be < {dim} for a {dim}D cloud, "
                f"got {p.axis} ('{'xyz'[int(p.axis)]}')"
            )
    axes = [int(p.axis) for p in pl]
    if len(set(axes)) != len(axes):
        raise InputError(
            "planes must have distinct axes (two parallel mirrors make an infinite periodic "
            f"body), got axes {axes}"
        )
    return pl


@dataclass(frozen=True, eq=False)
class MirrorCloud:
    """A point cloud augmented with ghost images across symmetry planes.

    Real points come first (indices ``0..n_real-1``, identical to the input
    cloud), ghosts follow.  Build it with :func:`mirror_cloud`.

    Attributes
    ----------
    real : PointCloud
        The modelled part.
    cloud : PointCloud
        Real points plus ghosts; ghosts copy volume, horizon and material
        of their source; set ``'ghost'`` holds their indices.
    source : (n_aug,) ndarray of int
        Real point each augmented point is an image of (identity on reals).
    signs : (n_aug, dim) ndarray
        Diagonal of the reflection ``R`` per point: ``u_aug = signs * u[source]``;
        0 for the normal component of points lying on a plane and of their
        images (a symmetric field has none there), so ``P`` maps onto
        symmetric fields.
    image : (n_aug,) ndarray of int
        Bit mask of the planes a point was reflected across (0 for reals).
    on_plane : (n_real, n_planes) ndarray of bool
        Real points lying on each plane (no ghost, normal displacement 0).
    planes : tuple of SymmetryPlane
        The planes, with ``side`` resolved.
    reach : float
        Ghosts are made of real points closer than this to a plane.
    """

    real: PointCloud
    cloud: PointCloud
    source: np.ndarray
    signs: np.ndarray
    image: np.ndarray
    on_plane: np.ndarray
    planes: tuple[SymmetryPlane, ...]
    reach: float

    @property
    def n_real(self) -> int:
        """Number of real (modelled) points."""
        return self.real.n

    @property
    def n_ghosts(self) -> int:
        """Number of ghost points."""
        return self.cloud.n - self.real.n

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        return self.real.dim

    @cached_property
    def weight(self) -> np.ndarray:
        """Share of each real point in the reduced model, ``2**-(planes it lies on)``."""
        return np.asarray(0.5 ** self.on_plane.sum(axis=1), dtype=float)

    @cached_property
    def group_order(self) -> int:
        """Number of copies of the reduced model in the full body, ``2**n_planes``."""
        return 2 ** len(self.planes)

    @cached_property
    def expansion(self) -> sp.csr_array:
        """Sparse ``P`` (n_aug*dim x n_real*dim) with ``u_aug = P u_real``."""
        d = self.dim
        n_aug = self.cloud.n
        cols = (d * self.source[:, None] + np.arange(d)).ravel()
        return sp.csr_array(
            (self.signs.ravel(), cols, np.arange(n_aug * d + 1)),
            shape=(n_aug * d, self.n_real * d),
        )

    def expand(self, u: Any) -> np.ndarray:
        """Expand a displacement of the real points to the augmented cloud.

        Parameters
        ----------
        u : (n_real, dim) or (n_real*dim,) array_like
            Displacement of the real points.

        Returns
        -------
        (n_aug, dim) ndarray
            Real points unchanged, each ghost the reflected displacement of its source.

        Raises
        ------
        ShapeError
            When ``u`` does not have ``n_real * dim`` entries.

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> from pdlin.operators.symmetry import SymmetryPlane, mirror_cloud
        >>> m = mirror_cloud(pdlin.grid((2, 1)), [SymmetryPlane("x")], reach=1.0)
        >>> m.expand([[1.0, 2.0], [3.0, 4.0]])
        array([[ 1.,  2.],
               [ 3.,  4.],
               [-1.,  2.]])
        """
        d = self.dim
        uu = as_float_array(u, "u")
        if uu.size != self.n_real * d:
            raise ShapeError(
                f"u must have shape ({self.n_real}, {d}) (the real points), got {uu.shape}"
            )
        return uu.reshape(self.n_real, d)[self.source] * self.signs

    def mirror_cracks(self, cracks: Any) -> np.ndarray:
        """Return crack segments/triangles plus their images across the planes.

        Parameters
        ----------
        cracks : (m, k, dim) array_like
            ``m`` segments (``k = 2``) or triangles (``k = 3``).

        Returns
        -------
        (m * 2**n_planes, k, dim) ndarray
            The cracks, then their images across every non-empty subset of the planes.

        Raises
        ------
        ShapeError
            When ``cracks`` is not ``(m, k, dim)``.
        """
        cr = as_float_array(cracks, "cracks")
        if cr.ndim != 3 or cr.shape[2] != self.dim:
            raise ShapeError(f"cracks must have shape (m, k, {self.dim}), got {cr.shape}")
        out = [cr]
        for mask in range(1, 2 ** len(self.planes)):
            im = cr.copy()
            for b, pl in enumerate(self.planes):
                if mask >> b & 1:
                    k = int(pl.axis)
                    im[..., k] = 2.0 * pl.position - im[..., k]
            out.append(im)
        return np.concatenate(out, axis=0)

    def __repr__(self) -> str:
        """Summarize the real and ghost counts and the planes."""
        names = ", ".join(p.name for p in self.planes)
        return (
            f"MirrorCloud(n_real={self.n_real}, n_ghosts={self.n_ghosts}, planes=[{names}], "
            f"on_plane={int(self.on_plane.any(axis=1).sum())})"
        )


def mirror_cloud(
    cloud: PointCloud, planes: Sequence[SymmetryPlane] | SymmetryPlane, reach: float
) -> MirrorCloud:
    """Add ghost images of every point within ``reach`` of the symmetry planes.

    For each non-empty subset ``S`` of the planes, every real point closer
    than ``reach`` to all planes of ``S`` (and on none of them) gets one
    ghost reflected across all planes of ``S``: the images across single
    planes plus the corner images of quarter and eighth models.

    Parameters
    ----------
    cloud : PointCloud
        The modelled part; all points on one side of each plane.
    planes : SymmetryPlane or sequence of them
        At most one plane per axis.
    reach : float
        Coupling reach of the model: its largest horizon times its
        ``coupling_range`` (1 for bond-based, 2 for state-based models).

    Returns
    -------
    MirrorCloud
        The augmented cloud (real points first, then the ghosts), each ghost's source
        point and reflection signs.

    Raises
    ------
    InputError
        Axis outside the cloud's dimension, two planes on one axis, points
        on both sides of a plane, or a plane farther than ``reach`` from
        every point (it would couple nothing).

    Examples
    --------
    >>> import pdlin
    >>> from pdlin.operators.symmetry import SymmetryPlane, mirror_cloud
    >>> cloud = pdlin.grid((4, 4), spacing=1.0)            # the quadrant [0, 4]^2
    >>> m = mirror_cloud(cloud, [SymmetryPlane("x"), SymmetryPlane("y")], reach=1.0)
    >>> m.n_ghosts     # 4 images across x = 0, 4 across y = 0, 1 corner image
    9
    >>> m.cloud.points[m.image == 3].tolist()
    [[-0.5, -0.5]]
    """
    if not isinstance(cloud, PointCloud):
        raise InputTypeError(f"cloud must be a PointCloud, got {type(cloud).__name__}")
    d = cloud.dim
    pl = _as_planes(planes, d)
    if not pl:
        raise InputError("planes must hold at least one SymmetryPlane, got none")
    rc = float(reach)
    if not np.isfinite(rc) or rc <= 0:
        raise InputError(f"reach must be > 0, got {reach}")
    n = cloud.n
    pts = cloud.points
    tol = ON_PLANE_RTOL * cloud.spacing
    m = len(pl)
    on = np.zeros((n, m), dtype=bool)
    near = np.zeros((n, m), dtype=bool)
    resolved = []
    for k, p in enumerate(pl):  # a handful of planes, vectorized over points
        s = p.signed_distance(pts)
        below = s < -tol
        above = s > tol
        side = p.side
        if side is None:
            if below.any() and above.any():
                first = int(np.flatnonzero(below if below.sum() < above.sum() else above)[0])
                raise InputError(
                    f"points must all lie on one side of symmetry plane {p.name}, got "
                    f"{int(below.sum())} point(s) below and {int(above.sum())} above "
                    f"(e.g. point {first} at {pts[first].tolist()}); model only one side"
                )
            side = "-" if below.any() else "+"
        wrong = below if side == "+" else above
        if wrong.any():
            first = int(np.flatnonzero(wrong)[0])
            raise InputError(
                f"points must lie on the '{side}' side of symmetry plane {p.name}, got "
                f"{int(wrong.sum())} point(s) on the other side (first: point {first} at "
                f"{pts[first].tolist()})"
            )
        dist = np.abs(s)
        on[:, k] = dist <= tol
        near[:, k] = (dist <= rc * (1.0 + 1e-9)) & ~on[:, k]
        if not (on[:, k].any() or near[:, k].any()):
            raise InputError(
                f"symmetry plane {p.name} is farther than the reach {rc:.4g} from every point "
                f"(closest distance {float(dist.min()):.4g}), so it couples nothing; place it "
                "on the body's cut face"
            )
        resolved.append(SymmetryPlane(p.axis, p.position, side))
    src = [np.arange(n, dtype=np.intp)]
    ghost_pts = [pts]
    sign_rows = [np.ones((n, d))]
    image = [np.zeros(n, dtype=np.int64)]
    for mask in range(1, 2**m):  # <= 7 plane combinations
        sel = np.ones(n, dtype=bool)
        sign = np.ones(d)
        for b in range(m):
            if mask >> b & 1:
                sel &= near[:, b]
                sign[int(resolved[b].axis)] = -1.0
        idx = np.flatnonzero(sel)
        if idx.size == 0:
            continue
        g = pts[idx].copy()
        for b in range(m):
            if mask >> b & 1:
                k = int(resolved[b].axis)
                g[:, k] = 2.0 * resolved[b].position - g[:, k]
        src.append(idx)
        ghost_pts.append(g)
        sign_rows.append(np.broadcast_to(sign, (idx.size, d)))
        image.append(np.full(idx.size, mask, dtype=np.int64))
    source = np.concatenate(src)
    n_aug = source.size
    sets = dict(cloud.sets)
    sets["ghost"] = np.arange(n, n_aug)
    aug = PointCloud(
        np.concatenate(ghost_pts),
        cloud.volumes[source],
        horizon=None if cloud.horizon is None else cloud.horizon[source],
        material=None if cloud.material is None else cloud.material[source],
        sets=sets,
        thickness=cloud.thickness,
    )
    signs = np.concatenate(sign_rows)
    for k, p in enumerate(resolved):  # symmetric fields have no normal motion on a plane
        signs[np.flatnonzero(on[source, k]), int(p.axis)] = 0.0
    signs.setflags(write=False)
    log.debug("mirror cloud: %d real points, %d ghosts", n, n_aug - n)
    return MirrorCloud(cloud, aug, source, signs, np.concatenate(image), on, tuple(resolved), rc)


def _expand_model(model: Any, mirror: MirrorCloud) -> Any:
    """Map a model's per-point parameters onto the augmented cloud."""
    take = getattr(model, "take_points", None)
    if callable(take):
        return take(mirror.source)
    mm = getattr(model, "micromodulus", None)
    if isinstance(mm, np.ndarray) and mm.ndim >= 1:
        raise ModelError(
            "micromodulus must be a scalar with symmetry planes (per-bond values cannot be "
            f"mapped onto the mirrored bonds), got shape {mm.shape}"
        )
    E = getattr(model, "E", None)
    if isinstance(E, np.ndarray) and E.ndim == 1:
        if E.shape != (mirror.n_real,):
            raise ShapeError(f"E must be a scalar or have shape ({mirror.n_real},), got {E.shape}")
        new = copy.copy(model)
        new.E = E[mirror.source]
        return new
    return model


def _name_modes(text: str, names: list[str]) -> str:
    """Replace check_constraints' 'mode k' (column k of extra_modes) by its name."""

    def name(match: re.Match[str]) -> str:
        return names[int(match.group(1))]

    return re.sub(r"\bmode (\d+)\b", name, text)


@dataclass(frozen=True, eq=False)
class SymmetryReduction:
    """A model reduced by symmetry planes: operators on the real DOFs only.

    Build it with :func:`symmetry_reduction`.  All vectors are on the real
    points, ``(n_real, dim)`` or flat ``(n_real*dim,)``.

    Attributes
    ----------
    mirror : MirrorCloud
        The real points and their ghosts.
    bonds : Bonds
        Bonds of the augmented cloud (real points and ghosts).
    model : Model
        The model with per-point parameters expanded to the ghosts.
    """

    mirror: MirrorCloud
    bonds: Bonds
    model: Any

    @property
    def cloud(self) -> PointCloud:
        """The real (modelled) cloud."""
        return self.mirror.real

    @property
    def planes(self) -> tuple[SymmetryPlane, ...]:
        """The symmetry planes (sides resolved)."""
        return self.mirror.planes

    def expand(self, u: Any) -> np.ndarray:
        """Expand a displacement of the real points to the augmented cloud.

        Parameters
        ----------
        u : (n_real, dim) or (n_real*dim,) array_like
            Displacement of the real points.

        Returns
        -------
        (n_aug, dim) ndarray
            See :meth:`MirrorCloud.expand`.
        """
        return self.mirror.expand(u)

    @cached_property
    def real_bonds(self) -> Bonds:
        """Bonds between real points only (a valid :class:`~pdlin.Bonds` of the real cloud)."""
        n = self.mirror.n_real
        b = self.bonds
        end = int(b.indptr[n])
        keep = b.j[:end] < n
        i = b.i[:end][keep]
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(i, minlength=n), out=indptr[1:])
        return Bonds(
            n,
            i,
            b.j[:end][keep],
            b.xi[:end][keep],
            b.length[:end][keep],
            b.omega[:end][keep],
            b.volume_j[:end][keep],
            indptr,
            b.horizon[:n],
            b.shape,
            b.influence,
        )

    @property
    def family_size(self) -> np.ndarray:
        """Bonds per real point, ghosts included ``(n_real,)``."""
        n = self.mirror.n_real
        return np.diff(self.bonds.indptr[: n + 1])

    def stiffness(self) -> sp.bsr_array:
        """Assemble the reduced stiffness ``K_sym = W Eᵀ K_aug P``.

        Symmetric for symmetric models (it equals ``Pᵀ K_full P / |G|``).

        Returns
        -------
        scipy.sparse.bsr_array
            Shape ``(n_real*dim, n_real*dim)``, blocksize ``(dim, dim)``, every diagonal
            block stored.
        """
        m = self.mirror
        d = m.dim
        nd = m.n_real * d
        K_aug = sp.csr_array(assemble_stiffness(self.model, m.cloud, self.bonds))
        K = K_aug[:nd] @ m.expansion
        w = np.repeat(m.weight, d)
        if np.any(w != 1.0):
            K = sp.diags_array(w, format="csr") @ K
        K = sp.csr_array(K)
        K.sum_duplicates()
        K.sort_indices()
        return with_diagonal_blocks(sp.bsr_array(K, blocksize=(d, d)))

    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray:
        """Compute the reduced internal force ``W Eᵀ f_aug(P u)``.

        Parameters
        ----------
        u : (n_real, dim) array_like
            Displacement of the real points.
        linear : bool
            Linearized (small-displacement) force, passed to the model.

        Returns
        -------
        (n_real, dim) ndarray
            Nodal forces of the real points, those on a plane weighted by their share.
        """
        m = self.mirror
        f = self.model.internal_force(m.cloud, self.bonds, self.expand(u), linear=linear)
        return np.asarray(f)[: m.n_real] * m.weight[:, None]

    def load_vector(
        self,
        loads: Sequence[BodyForce | TotalForce],
        *,
        prescribed: np.ndarray | None = None,
    ) -> np.ndarray:
        """Assemble the reduced external force; points on a plane carry their share only.

        Parameters
        ----------
        loads : sequence of BodyForce or TotalForce
            Loads on the real points.
        prescribed : (k,) ndarray of int, optional
            Prescribed DOFs (with the planes' own): see
            :func:`pdlin.operators.load_vector`.

        Returns
        -------
        (n_real*dim,) ndarray
            Nodal forces, volumes of on-plane points scaled by their weight.
        """
        m = self.mirror
        cloud = m.real
        if np.any(m.weight != 1.0):
            cloud = cloud.replace(volumes=cloud.volumes * m.weight)
        return load_vector(cloud, loads, prescribed=prescribed)

    def dirichlet(self) -> list[Dirichlet]:
        """Build the zero normal displacement of the points lying on each plane.

        Returns
        -------
        list of Dirichlet
            One condition per plane with points on it (component ``axis``, value 0).
        """
        out = []
        for k, p in enumerate(self.planes):
            idx = np.flatnonzero(self.mirror.on_plane[:, k])
            if idx.size:
                out.append(Dirichlet(idx, 0.0, components=[int(p.axis)]))
        return out

    def rigid_modes(self, index: np.ndarray | None = None) -> tuple[np.ndarray, list[str]]:
        """Rigid-body modes compatible with the reflections.

        Parameters
        ----------
        index : (m,) ndarray of int, optional
            Real points of one connected piece (default all).

        Returns
        -------
        modes : (m*dim, k) ndarray
            The surviving modes on those real points.
        names : list of str
            Their names, e.g. ``['translation z']``.
        """
        m = self.mirror
        d = m.dim
        if index is None:
            aug_idx = np.arange(m.cloud.n)
            n_loc = m.n_real
        else:
            real_idx = np.asarray(index, dtype=np.intp)
            in_piece = np.zeros(m.n_real, dtype=bool)
            in_piece[real_idx] = True
            aug_idx = np.flatnonzero(in_piece[m.source])
            n_loc = real_idx.size
        B = rigid_body_modes(m.cloud.points[aug_idx]).reshape(aug_idx.size, d, -1)
        pos = np.searchsorted(aug_idx, m.source[aug_idx])
        resid = B - m.signs[aug_idx][:, :, None] * B[pos]
        rn = np.sqrt(np.einsum("pdk,pdk->k", resid, resid))
        bn = np.sqrt(np.einsum("pdk,pdk->k", B, B))
        keep = rn <= 1e-8 * np.maximum(bn, 1e-300)
        names = [nm for nm, k in zip(rigid_mode_names(d), keep, strict=True) if k]
        return B[:n_loc][:, :, keep].reshape(n_loc * d, int(keep.sum())), names

    def check_constraints(self, dofs: np.ndarray) -> None:
        """Check that no rigid motion compatible with the planes stays free.

        Connectivity counts bonds through ghosts; each connected piece is
        checked against the rigid modes its reflections leave (via
        :func:`pdlin.operators.check_constraints` with ``extra_modes``).

        Parameters
        ----------
        dofs : (k,) ndarray of int
            Constrained DOFs of the real points (point-major, ``dim * i + c``).

        Raises
        ------
        FloatingBodyError
            When a piece keeps a rigid motion the constraints do not remove; the message
            names the motions.
        """
        m = self.mirror
        n, d = m.n_real, m.dim
        dofs = np.asarray(dofs, dtype=np.intp)
        n_aug = m.cloud.n
        S = sp.csr_array((np.ones(n_aug), m.source, np.arange(n_aug + 1)), shape=(n_aug, n))
        A = S.T @ sp.csr_array(self.bonds.adjacency(), dtype=float) @ S
        ncomp, labels = connected_components(A, directed=False)
        if ncomp > 200:
            log.warning("only the first 200 of %d pieces are checked for rigid motions", ncomp)
        planes = ", ".join(p.name for p in self.planes)
        for c in range(min(ncomp, 200)):  # connected pieces (usually one)
            real_idx = np.flatnonzero(labels == c) if ncomp > 1 else np.arange(n)
            modes, names = self.rigid_modes(real_idx if ncomp > 1 else None)
            if not names:
                continue
            pt = dofs // d
            mine = labels[pt] == c
            local = d * np.searchsorted(real_idx, pt[mine]) + dofs[mine] % d
            sub = m.real if ncomp == 1 else m.real.subset(real_idx)
            try:
                check_constraints(sub, None, local, extra_modes=modes)
            except FloatingBodyError as exc:
                # check_constraints calls the columns of extra_modes 'mode k'
                msg = _name_modes(str(exc), names)
                piece = "" if ncomp == 1 else f" of piece {c} (of {ncomp})"
                raise FloatingBodyError(
                    f"{msg}; the symmetry planes {planes} leave these rigid motions{piece} "
                    f"to constrain: {', '.join(names)}"
                ) from exc

    def deformation_gradient(self, u: Any) -> np.ndarray:
        """Compute the nonlocal deformation gradient at the real points using ghost bonds.

        Exact for affine fields compatible with the reflections, and equal
        to the full model's value on the shared points.

        Parameters
        ----------
        u : (n_real, dim) array_like
            Displacement of the real points.

        Returns
        -------
        (n_real, dim, dim) ndarray
            ``F`` per real point.
        """
        m = self.mirror
        return deformation_gradient(m.cloud, self.bonds, self.expand(u), n_owners=m.n_real)

    def stress(self, u: Any) -> np.ndarray:
        """Compute the model's stress at the real points using ghost bonds.

        Parameters
        ----------
        u : (n_real, dim) array_like
            Displacement of the real points.

        Returns
        -------
        (n_real, dim, dim) ndarray
            Stress per real point, in the model's units.

        Raises
        ------
        InputError
            When the model defines no stress.
        """
        if not hasattr(self.model, "stress"):
            raise InputError(f"model {type(self.model).__name__} does not define a stress")
        m = self.mirror
        return np.asarray(self.model.stress(m.cloud, self.bonds, self.expand(u)))[: m.n_real]

    def initial_state(self) -> dict[str, np.ndarray]:
        """Return the committed state of the nonlinear drivers (empty: elastic models only).

        Returns
        -------
        dict
            Always ``{}``.

        Raises
        ------
        ModelError
            When the model is nonlinear (symmetry planes support elastic models only).
        """
        if getattr(self.model, "nonlinear", False):
            raise ModelError(
                f"symmetry planes do not support nonlinear models yet, got "
                f"{type(self.model).__name__} with a nonlinear material; model the full body"
            )
        return {}

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any:
        """Compute the linear response ``f = -K_sym u`` on the real DOFs.

        Parameters
        ----------
        u : (n_real, dim) array_like
            Displacement of the real points.
        state : dict
            Committed state (empty for the elastic models supported), copied through.
        tangent : bool
            Also assemble the tangent ``K_sym``.

        Returns
        -------
        Response
            Force ``(n_real, dim)``, the state, ``K_sym`` or ``None``, as
            :meth:`pdlin.models.Model.respond`.

        Raises
        ------
        ModelError
            When the model is nonlinear.
        """
        from ..models.base import Response

        self.initial_state()  # raises for nonlinear models
        f = self.internal_force(u, linear=True)
        return Response(f, dict(state), self.stiffness() if tangent else None, None, 0)

    def __repr__(self) -> str:
        """Summarize the mirror cloud and the bond count."""
        return f"SymmetryReduction({self.mirror!r}, n_bonds={self.bonds.n_bonds})"


def symmetry_reduction(
    model: Any,
    cloud: PointCloud,
    planes: Sequence[SymmetryPlane] | SymmetryPlane,
    horizon: Any = None,
    bond_options: Mapping[str, Any] | None = None,
) -> SymmetryReduction:
    """Mirror a cloud across symmetry planes and find the bonds of the result.

    Parameters
    ----------
    model : Model
        Its ``coupling_range`` (1 for bond-based) times the largest horizon
        is the depth of the ghost layer.
    cloud : PointCloud
        The modelled half / quarter / eighth.
    planes : SymmetryPlane or sequence of them
        The symmetry planes, at most one per axis.
    horizon : float or (n,) array_like, optional
        As in :func:`pdlin.find_bonds` (default ``cloud.horizon``); a per-point
        horizon is copied to the ghosts.
    bond_options : mapping, optional
        Keyword arguments of :func:`pdlin.find_bonds` (``ratio``, ``shape``,
        ``axes``, ``influence``, ``cracks``, ``exclude``, ``allow_isolated``,
        ``rtol``).  Cracks are mirrored with the points; ``exclude`` receives
        augmented coordinates; ``method`` is ignored (the augmented cloud is
        searched with a k-d tree).

    Returns
    -------
    SymmetryReduction
        The mirror cloud, the bonds of the augmented cloud and the model mapped onto it.

    Raises
    ------
    InputTypeError
        When ``model`` is not a pdlin model or ``cloud`` not a :class:`~pdlin.PointCloud`.
    ModelError
        When ``model.coupling_range`` is not an integer >= 1.
    NoNeighborsError
        When a real point has no bond and ``allow_isolated`` is not set.

    Examples
    --------
    A quarter of a plate: the reduced stiffness is symmetric and no rigid
    motion survives the two planes in 2D.

    >>> import numpy as np, pdlin
    >>> from pdlin.operators.symmetry import SymmetryPlane, symmetry_reduction
    >>> cloud = pdlin.grid((6, 4), spacing=0.1)
    >>> red = symmetry_reduction(pdlin.BondBased(E=1.0), cloud,
    ...     [SymmetryPlane("x"), SymmetryPlane("y")], bond_options={"ratio": 3.015})
    >>> K = red.stiffness()
    >>> K.shape, bool(abs(K - K.T).max() <= 1e-14 * abs(K).max())
    ((48, 48), True)
    >>> red.rigid_modes()[1]
    []
    """
    if not hasattr(model, "stiffness") or not hasattr(model, "internal_force"):
        raise InputTypeError(f"model must be a pdlin model, got {type(model).__name__}")
    if not isinstance(cloud, PointCloud):
        raise InputTypeError(f"cloud must be a PointCloud, got {type(cloud).__name__}")
    opts = dict(bond_options or {})
    ratio = opts.pop("ratio", None)
    allow_isolated = bool(opts.pop("allow_isolated", False))
    opts.pop("method", None)
    hor = resolve_horizon(cloud, horizon, ratio)
    cr = getattr(model, "coupling_range", 1)
    if not isinstance(cr, int | np.integer) or cr < 1:
        raise ModelError(f"model.coupling_range must be an int >= 1, got {cr!r}")
    bond_reach = float(hor.max())
    if opts.get("axes") is not None:
        bond_reach = max(bond_reach, float(np.max(as_float_array(opts["axes"], "axes"))))
    mirror = mirror_cloud(cloud, planes, int(cr) * bond_reach)
    if opts.get("cracks") is not None:
        # the images count with their crack when find_bonds checks that each cuts a bond
        opts["cracks"] = MirroredCracks(
            mirror.mirror_cracks(opts["cracks"]), 2 ** len(mirror.planes)
        )
    bonds = find_bonds(mirror.cloud, hor[mirror.source], allow_isolated=True, method="tree", **opts)
    if not allow_isolated:
        fs = np.diff(bonds.indptr[: cloud.n + 1])
        empty = np.flatnonzero(fs == 0)
        if empty.size:
            raise NoNeighborsError(
                f"every point needs at least one bond, got {empty.size} isolated point(s), "
                f"first index {int(empty[0])} at {cloud.points[empty[0]].tolist()}; increase "
                "the horizon or pass allow_isolated=True"
            )
    return SymmetryReduction(mirror, bonds, _expand_model(model, mirror))
