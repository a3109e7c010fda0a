"""Bonds (families) between points: neighbor search and per-bond arrays."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from .._validation import as_float_array
from ..errors import DuplicatePointError, InputError, NoNeighborsError, ShapeError
from .cloud import PointCloud
from .influence import InfluenceFunction, evaluate_influence

__all__ = ["Bonds", "find_bonds", "resolve_horizon", "SHAPES"]

log = logging.getLogger(__name__)

#: Neighbourhood shapes accepted by ``find_bonds(shape=...)``.
SHAPES = ("sphere", "cube", "ellipsoid", "box")


#: per-bond arrays a compact :class:`Bonds` computes on access
_LAZY = ("i", "xi", "length", "omega", "volume_j")


@dataclass(frozen=True)
class _CompactStore:
    """What a compact :class:`Bonds` keeps instead of its per-bond arrays.

    ``stencil`` (per bond, small unsigned ints) indexes the rows of the ``tables``
    (``xi``, ``length``, and ``omega`` unless ``omega_const``); without a stencil the
    tables are the per-bond arrays themselves. ``volume_j`` is ``volumes[j]``.
    """

    stencil: np.ndarray | None
    tables: dict[str, np.ndarray]
    omega_const: float | None
    volumes: np.ndarray

    def kept(self, m: np.ndarray) -> _CompactStore:
        """Return the store of the bonds where ``m`` is True."""
        if self.stencil is not None:
            return _CompactStore(self.stencil[m], self.tables, self.omega_const, self.volumes)
        tabs = {k: v[m] for k, v in self.tables.items()}
        return _CompactStore(None, tabs, self.omega_const, self.volumes)


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Return True when two float arrays hold the same bits (signed zeros, NaNs)."""
    a, b = np.ascontiguousarray(a, np.float64), np.ascontiguousarray(b, np.float64)
    return a.shape == b.shape and bool(np.array_equal(a.view(np.int64), b.view(np.int64)))


def _compact_store(
    stencil: np.ndarray | None,
    xi: np.ndarray,
    length: np.ndarray,
    omega: np.ndarray,
    omega_table: Callable[[], np.ndarray] | None,
    volumes: np.ndarray,
) -> _CompactStore:
    """Choose the smallest exact storage of the per-bond arrays.

    ``xi`` and ``length`` are the stencil tables when ``stencil`` is given, else per bond.
    ``omega`` (per bond) becomes one constant when all its bits are equal, a stencil table
    (``omega_table()``) when that table gathered gives the same bits, else is kept.
    """
    tables = {"xi": xi, "length": length}
    const = None
    bits = omega.view(np.int64) if omega.dtype == np.float64 else None
    if bits is not None and omega.size and bool(np.all(bits == bits[0])):
        const = float(omega[0])
    elif stencil is not None and omega_table is not None:
        tab = omega_table()
        tables["omega"] = tab if _same_bits(tab[stencil], omega) else omega
        if tables["omega"] is omega:  # no table: keep one value per bond
            tables = {"xi": xi[stencil], "length": length[stencil], "omega": omega}
            stencil = None
    else:
        tables["omega"] = omega
        if stencil is not None:
            tables = {"xi": xi[stencil], "length": length[stencil], "omega": omega}
            stencil = None
    return _CompactStore(stencil, tables, const, volumes)


@dataclass(frozen=True, eq=False)
class Bonds:
    """Directed bonds of a point cloud in CSR order (both directions stored).

    Bond ``b`` goes from point ``i[b]`` to point ``j[b]``; bonds of point
    ``p`` are ``indptr[p]:indptr[p+1]`` with ``j`` increasing.

    Attributes
    ----------
    n_points : int
        Number of points of the cloud.
    i, j : (nb,) ndarray of int
        Owner and neighbor of each bond.
    xi : (nb, dim) ndarray
        Reference bond vector ``x_j - x_i``.
    length : (nb,) ndarray
        ``|xi|``.
    omega : (nb,) ndarray
        Influence function value (symmetric: ``omega[b] == omega[reverse[b]]``).
    volume_j : (nb,) ndarray
        Volume of the neighbor (one-point quadrature, no partial volumes).
    indptr : (n_points + 1,) ndarray
        CSR row pointer over owners.
    horizon : (n_points,) ndarray
        Horizon of each point; a bond exists when
        ``|xi| <= max(horizon[i], horizon[j])`` (the symmetric family rule).
    shape : str
        Neighborhood shape used.
    influence : str or callable
        Influence function used for ``omega``.

    Notes
    -----
    :func:`find_bonds` returns a *compact* Bonds: it keeps ``j`` and ``indptr`` and, instead
    of ``i``, ``xi``, ``length``, ``omega`` and ``volume_j``, what they are computed from
    (``indptr``; the stencil index of each bond and the stencil's vectors and lengths on a
    lattice; one constant or a per-stencil table of ``omega``; the point volumes). Those
    attributes are then computed on each access (the same values, bit for bit, as the
    arrays the search made), so a large solve does not hold them resident (9 bytes per
    bond on a lattice instead of 64); :meth:`values` gives a range of bonds without the
    whole array. A Bonds built from arrays (the constructor, ``dataclasses.replace``)
    stores them as given.
    """

    n_points: int
    i: np.ndarray
    j: np.ndarray
    xi: np.ndarray
    length: np.ndarray
    omega: np.ndarray
    volume_j: np.ndarray
    indptr: np.ndarray
    horizon: np.ndarray
    shape: str = "sphere"
    influence: Any = "constant"

    def __getattr__(self, name: str) -> np.ndarray:
        """Compute a per-bond array a compact Bonds does not store (see Notes)."""
        # reached only for attributes missing from the instance
        if name in _LAZY and "_compact" in self.__dict__:
            return self.values(name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def values(self, name: str, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Return one per-bond array for the bonds ``start:stop``.

        On a compact Bonds (see Notes) only that range is computed; the values are those
        of the full attribute's slice, bit for bit.

        Parameters
        ----------
        name : {'i', 'j', 'xi', 'length', 'omega', 'volume_j'}
            The attribute.
        start, stop : int
            Bond range (``stop`` None: to the last bond).

        Returns
        -------
        ndarray
            ``getattr(self, name)[start:stop]``: shape ``(stop - start,)``, or
            ``(stop - start, dim)`` for ``xi``.

        Raises
        ------
        InputError
            If ``name`` is not one of the per-bond arrays.
        """
        if name not in _LAZY and name != "j":
            raise InputError(f"name must be one of {('j',) + _LAZY}, got {name!r}")
        nb = self.n_bonds
        b1 = nb if stop is None else min(int(stop), nb)
        b0 = min(int(start), b1)
        c = self.__dict__.get("_compact")
        if c is None or name == "j" or name in self.__dict__:
            return np.asarray(getattr(self, name))[b0:b1]
        if name == "i":
            if b0 == 0 and b1 == nb:
                return np.repeat(np.arange(self.n_points, dtype=np.int64), self.family_size)
            ptr = np.asarray(self.indptr, dtype=np.int64)
            r0 = int(np.searchsorted(ptr, b0, side="right")) - 1
            r1 = int(np.searchsorted(ptr, b1, side="left"))
            counts: np.ndarray = np.diff(np.clip(ptr[r0 : r1 + 1], b0, b1)).astype(np.int64)
            return np.repeat(np.arange(r0, r1, dtype=np.int64), counts)
        if name == "volume_j":
            return c.volumes[self.j[b0:b1]]
        if name == "omega" and c.omega_const is not None:
            return np.full(b1 - b0, c.omega_const)
        table = c.tables[name]
        return table[b0:b1] if c.stencil is None else table[c.stencil[b0:b1]]

    @property
    def n_bonds(self) -> int:
        """Number of directed bonds."""
        return int(self.j.size)

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        c = self.__dict__.get("_compact")
        if c is not None and "xi" not in self.__dict__:
            return int(c.tables["xi"].shape[1])
        return int(self.xi.shape[1])

    @classmethod
    def _from_parts(
        cls,
        n_points: int,
        j: np.ndarray,
        indptr: np.ndarray,
        horizon: np.ndarray,
        shape: str,
        influence: Any,
        store: _CompactStore,
    ) -> Bonds:
        """Build a compact Bonds (no ``i``, ``xi``, ``length``, ``omega``, ``volume_j``)."""
        self = object.__new__(cls)
        for k, v in (("n_points", n_points), ("j", j), ("indptr", indptr),
                     ("horizon", horizon), ("shape", shape), ("influence", influence),
                     ("_compact", store)):  # fmt: skip
            object.__setattr__(self, k, v)
        return self

    @property
    def family_size(self) -> np.ndarray:
        """Number of bonds per point, ``(n_points,)``."""
        return np.diff(self.indptr)

    @property
    def horizon_ij(self) -> np.ndarray:
        """Bond horizon ``max(horizon[i], horizon[j])`` per bond."""
        return np.maximum(self.horizon[self.i], self.horizon[self.j])

    @cached_property
    def reverse(self) -> np.ndarray:
        """Index of the opposite bond ``j -> i`` for each bond ``i -> j``."""
        nb = self.n_bonds
        a = sp.csr_array(
            (np.arange(nb, dtype=np.int64), self.j, self.indptr),
            shape=(self.n_points, self.n_points),
        )
        t = a.T.tocsr()
        t.sort_indices()
        return np.asarray(t.data)

    def adjacency(self) -> sp.csr_array:
        """Return the boolean point adjacency matrix.

        Returns
        -------
        scipy.sparse.csr_array of bool, shape (n_points, n_points)
            True at ``(i, j)`` for every bond ``i -> j``.
        """
        data = np.ones(self.n_bonds, dtype=bool)
        return sp.csr_array((data, self.j, self.indptr), shape=(self.n_points,) * 2)

    def per_point_sum(self, values: np.ndarray) -> np.ndarray:
        """Sum bond values over each family: ``out[p] = sum_{b in p} values[b]``.

        Parameters
        ----------
        values : (n_bonds, ...) array_like
            One value (or array) per bond; trailing dimensions are kept.

        Returns
        -------
        ndarray of float, shape (n_points, ...)
            Per-point sums (0 for points without bonds).

        Raises
        ------
        ShapeError
            If ``values`` does not have ``n_bonds`` rows.
        """
        vals = np.asarray(values)
        if vals.shape[0] != self.n_bonds:
            raise ShapeError(f"values must have {self.n_bonds} rows, got {vals.shape}")
        if vals.ndim == 1:
            return np.bincount(self.i, weights=vals, minlength=self.n_points)
        flat = vals.reshape(self.n_bonds, -1)
        out = np.empty((self.n_points, flat.shape[1]))
        for k in range(flat.shape[1]):
            out[:, k] = np.bincount(self.i, weights=flat[:, k], minlength=self.n_points)
        return out.reshape((self.n_points,) + vals.shape[1:])

    def keep(self, mask: np.ndarray) -> Bonds:
        """Return the bonds where ``mask`` is True (keep masks symmetric).

        Parameters
        ----------
        mask : (n_bonds,) array_like of bool
            Bonds to keep; drop ``i -> j`` and ``j -> i`` together.

        Returns
        -------
        Bonds
            The kept bonds, in CSR order, with the same points and horizon.

        Raises
        ------
        ShapeError
            If ``mask`` does not have shape ``(n_bonds,)``.
        """
        m = np.asarray(mask, dtype=bool)
        if m.shape != (self.n_bonds,):
            raise ShapeError(f"mask must have shape ({self.n_bonds},), got {m.shape}")
        counts = np.bincount(self.i[m], minlength=self.n_points)
        indptr = np.zeros(self.n_points + 1, dtype=np.int64)
        np.cumsum(counts, out=indptr[1:])
        c = self.__dict__.get("_compact")
        if c is not None:
            return Bonds._from_parts(
                self.n_points, self.j[m], indptr, self.horizon, self.shape, self.influence,
                c.kept(m),
            )  # fmt: skip
        return Bonds(
            self.n_points,
            self.i[m],
            self.j[m],
            self.xi[m],
            self.length[m],
            self.omega[m],
            self.volume_j[m],
            indptr,
            self.horizon,
            self.shape,
            self.influence,
        )

    def nbytes(self) -> int:
        """Return the memory held by the bond arrays.

        Returns
        -------
        int
            Bytes of the per-bond arrays held: ``i``, ``j``, ``xi``, ``length``, ``omega``,
            ``volume_j`` and ``indptr`` as stored (a compact Bonds: ``j``, ``indptr``, the
            stencil index and the small tables; the point volumes it shares with the cloud
            are not counted).
        """
        c = self.__dict__.get("_compact")
        held = [self.__dict__[k] for k in ("j", "indptr") + _LAZY if k in self.__dict__]
        if c is not None:
            held += [c.stencil] if c.stencil is not None else []
            held += list(c.tables.values())
        return int(sum(np.asarray(a).nbytes for a in held))

    def __repr__(self) -> str:
        """Return point and bond counts, family-size range and shape (no arrays)."""
        fs = self.family_size
        return (
            f"Bonds(n_points={self.n_points}, n_bonds={self.n_bonds}, family size "
            f"{fs.min() if fs.size else 0}..{fs.max() if fs.size else 0}, shape={self.shape!r})"
        )


def resolve_horizon(
    cloud: PointCloud, horizon: float | Sequence[float] | np.ndarray | None, ratio: float | None
) -> np.ndarray:
    """Return the per-point horizon from an absolute value, a ratio to the spacing, or the cloud.

    Parameters
    ----------
    cloud : PointCloud
        The points (their lattice spacing, spacing or stored horizon is used).
    horizon : float or (n,) array_like of float or None
        Absolute horizon, scalar or per point.
    ratio : float or None
        Horizon over spacing: times the largest lattice spacing of a grid cloud,
        otherwise times each point's ``spacing``.

    Returns
    -------
    ndarray of float, shape (n,)
        Horizon per point, all > 0.

    Raises
    ------
    InputError
        If both or (with no ``cloud.horizon``) neither are given, or a value is not > 0.
    ShapeError
        If a per-point ``horizon`` has the wrong length.
    """
    if horizon is not None and ratio is not None:
        raise InputError("pass either horizon or ratio, not both")
    if ratio is not None:
        r = float(ratio)
        if not np.isfinite(r) or r <= 0:
            raise InputError(f"ratio must be > 0, got {ratio}")
        if cloud.lattice is not None:
            return np.full(cloud.n, r * float(np.max(cloud.lattice.spacing)))
        return r * cloud.spacing
    if horizon is None:
        if cloud.horizon is None:
            raise InputError(
                "horizon must be given (argument horizon or ratio, or PointCloud.horizon), got None"
            )
        return np.asarray(cloud.horizon)
    h = as_float_array(horizon, "horizon")
    if h.ndim == 0:
        if h <= 0:
            raise InputError(f"horizon must be > 0, got {float(h)}")
        return np.full(cloud.n, float(h))
    if h.shape != (cloud.n,):
        raise ShapeError(f"horizon must be a scalar or have shape ({cloud.n},), got {h.shape}")
    if np.any(h <= 0):
        k = int(np.flatnonzero(h <= 0)[0])
        raise InputError(f"horizon must be > 0, got {h[k]} at point {k}")
    return h


def shape_mask(
    xi: np.ndarray,
    length: np.ndarray,
    hor: np.ndarray,
    shape: str,
    axes: np.ndarray | None,
    rtol: float,
) -> np.ndarray:
    """Flag the bond vectors inside a neighbourhood shape (inclusive membership).

    Parameters
    ----------
    xi : (m, dim) ndarray of float
        Bond vectors.
    length : (m,) ndarray of float
        Their lengths ``|xi|``.
    hor : (m,) ndarray of float
        Horizon of each bond (sphere radius, cube half-width).
    shape : {'sphere', 'cube', 'ellipsoid', 'box'}
        Neighbourhood shape (see :data:`SHAPES`).
    axes : (dim,) ndarray of float or None
        Semi-axes ('ellipsoid') or half-widths ('box'); unused otherwise.
    rtol : float
        Relative tolerance of the membership test.

    Returns
    -------
    ndarray of bool, shape (m,)
        True for bonds inside the shape.
    """
    if shape == "sphere":
        return length <= hor * (1.0 + rtol)
    if shape == "cube":
        return np.max(np.abs(xi), axis=1) <= hor * (1.0 + rtol)
    assert axes is not None
    if shape == "box":
        return np.all(np.abs(xi) <= axes * (1.0 + rtol), axis=1)
    # ellipsoid
    return np.sum((xi / axes) ** 2, axis=1) <= (1.0 + rtol) ** 2


def _segments_cross_2d(p: np.ndarray, q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Vectorized test whether segments p-q (many) properly cross segment a-b."""

    def orient(u: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (
            w[..., 0] - u[..., 0]
        )

    o1 = orient(p, q, a)
    o2 = orient(p, q, b)
    o3 = orient(a, b, p)
    o4 = orient(a, b, q)
    return (o1 * o2 < 0) & (o3 * o4 <= 0) | (o1 * o2 <= 0) & (o3 * o4 < 0)


#: tolerance of the barycentric edge tests of :func:`_segments_cross_triangle`: a bond through
#: the shared edge of two crack triangles lands, by round-off, just outside both unless the
#: edges are widened a little (dimensionless: a fraction of the triangle)
_EDGE_TOL = 1e-12


def _segments_cross_triangle(p: np.ndarray, q: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Test segments p-q against a triangle (vectorized Moller-Trumbore).

    Edges count as hits up to :data:`_EDGE_TOL` (so a crack made of several triangles
    has no seams).
    """
    v0, v1, v2 = tri
    e1 = v1 - v0
    e2 = v2 - v0
    d = q - p
    h = np.cross(d, e2)
    a = h @ e1
    ok = np.abs(a) > 1e-300
    f = np.where(ok, 1.0 / np.where(ok, a, 1.0), 0.0)
    s = p - v0
    u = f * np.einsum("ij,ij->i", s, h)
    qv = np.cross(s, e1)
    v = f * np.einsum("ij,ij->i", d, qv)
    t = f * (qv @ e2)
    tol = _EDGE_TOL
    return ok & (u >= -tol) & (v >= -tol) & (u + v <= 1 + tol) & (t > 0) & (t < 1)


class MirroredCracks(NamedTuple):
    """Crack pieces plus their mirror images, as symmetry reductions pass them.

    ``pieces`` holds ``copies`` blocks of the ``m`` original pieces (the originals first);
    piece ``k`` and its images ``k + m``, ``k + 2m``, ... count as one crack when
    :func:`find_bonds` checks that every crack cuts a bond.

    Parameters
    ----------
    pieces : (copies * m, ...) ndarray
        The crack pieces (segments in 2D, triangles in 3D), originals first.
    copies : int
        Number of blocks (1 + number of mirror images).
    """

    pieces: np.ndarray
    copies: int


def _crack_mask(points: np.ndarray, i: np.ndarray, j: np.ndarray, cracks: Any) -> np.ndarray:
    """Flag the bonds that cross any crack (2D segments or 3D triangles).

    A crack (with its mirror images, :class:`MirroredCracks`) that cuts no bond raises:
    it would leave the body intact, which can only be a misplaced crack.
    """
    dim = points.shape[1]
    copies = 1
    if isinstance(cracks, MirroredCracks):
        cracks, copies = cracks.pieces, int(cracks.copies)
    cr = as_float_array(cracks, "cracks")
    if dim == 2:
        if cr.ndim != 3 or cr.shape[1:] != (2, 2):
            raise ShapeError(f"cracks in 2D must have shape (m, 2, 2) (segments), got {cr.shape}")
    elif dim == 3:
        if cr.ndim != 3 or cr.shape[1:] != (3, 3):
            raise ShapeError(f"cracks in 3D must have shape (m, 3, 3) (triangles), got {cr.shape}")
    else:
        raise InputError("cracks are supported in 2D and 3D only, got a 1D cloud")
    cut = np.zeros(i.size, dtype=bool)
    cuts_any = np.zeros(cr.shape[0], dtype=bool)
    p = points[i]
    q = points[j]
    for k, c in enumerate(cr):  # loop over a handful of crack pieces, vectorized over bonds
        mine = (
            _segments_cross_2d(p, q, c[0], c[1]) if dim == 2 else _segments_cross_triangle(p, q, c)
        )
        cuts_any[k] = bool(mine.any())
        cut |= mine
    m = cr.shape[0] // max(copies, 1)
    idle = np.flatnonzero(~cuts_any.reshape(copies, m).any(axis=0)) if m else np.zeros(0, int)
    if idle.size:
        k = int(idle[0])
        what = "segment" if dim == 2 else "triangle"
        corners = " - ".join("(" + ", ".join(f"{v:g}" for v in x) + ")" for x in cr[k])
        lo, hi = points.min(axis=0), points.max(axis=0)
        raise InputError(
            f"cracks[{k}] ({what} {corners}) cuts no bond ({idle.size} of {m} crack piece(s) "
            f"cut none; points span {lo.tolist()} to {hi.tolist()}): a crack must cross the "
            "bonds it separates; move it into the body or drop it"
        )
    return cut


def _lattice_pairs(
    cloud: PointCloud, hor: float, shape: str, axes: np.ndarray | None, rtol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Directed bonds of a regular lattice from an integer stencil (already CSR sorted).

    Returns ``(i, j, stencil, vectors, lengths)``: bond ``b`` has ``ξ = vectors[stencil[b]]``
    and ``|ξ| = lengths[stencil[b]]`` (``stencil`` of the smallest unsigned int type).
    """
    lat = cloud.lattice
    assert lat is not None
    dim = cloud.dim
    h = np.asarray(lat.spacing, dtype=float)
    if shape in ("sphere", "cube"):
        reach = hor * (1.0 + rtol)
    else:
        assert axes is not None
        reach = float(np.max(axes)) * (1.0 + rtol)
    m = np.floor(reach / h).astype(int)
    rng = [np.arange(-mk, mk + 1) for mk in m]
    offs = np.stack([g.ravel() for g in np.meshgrid(*rng, indexing="ij")], axis=1)
    offs = offs[np.any(offs != 0, axis=1)]
    vec = offs * h
    length = np.sqrt(np.sum(vec**2, axis=1))
    keep = shape_mask(vec, length, np.full(length.size, hor), shape, axes, rtol)
    offs, vec, length = offs[keep], vec[keep], length[keep]
    shp = np.array(lat.shape)
    strides = np.array([int(np.prod(shp[k + 1 :])) for k in range(dim)], dtype=np.int64)
    flat_off = offs @ strides
    order = np.argsort(flat_off, kind="stable")
    offs, vec, length, flat_off = offs[order], vec[order], length[order], flat_off[order]
    n = cloud.n
    noff = offs.shape[0]
    flat_i = np.arange(n, dtype=np.int64) if lat.index is None else np.asarray(lat.index, np.int64)
    multi = np.unravel_index(flat_i, lat.shape)
    # validity of each (point, offset) pair from small per-axis tables
    # (coordinate value x offset) gathered by the point's grid coordinate:
    # bool gathers instead of int64 arithmetic on (n, noff) arrays
    valid = np.ones((n, noff), dtype=bool)
    for k in range(dim):
        c = np.arange(shp[k])[:, None] + offs[None, :, k]
        valid &= ((c >= 0) & (c < shp[k]))[multi[k]]
    del multi
    q = np.flatnonzero(valid)  # row-major: bonds come out CSR-sorted by (i, j)
    del valid
    rows = q // noff
    cols = q - rows * noff
    del q
    if lat.index is None:
        j = rows + flat_off[cols]
    else:
        lookup = np.full(int(np.prod(shp)), -1, dtype=np.int64)
        lookup[flat_i] = np.arange(n)
        j = lookup[flat_i[rows] + flat_off[cols]]
        ok = j >= 0
        rows, cols, j = rows[ok], cols[ok], j[ok]
    sdt = np.uint8 if noff <= 1 << 8 else np.uint16 if noff <= 1 << 16 else np.int64
    return rows, j, cols.astype(sdt), vec, length


#: points per chunk of the threaded cell-list search
_CELL_CHUNK = 1 << 13


def _cell_candidates(
    pts: np.ndarray, reach: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Find directed candidate bonds with a threaded cell list (numba).

    Returns ``(i, j, ξ = x_j - x_i)`` with ``|ξ| <= reach (1 + 1e-9)``, CSR sorted, from a
    cell list searched in point chunks on the threads; None without numba, for small
    clouds, on one thread in 1D / 2D (where scipy's tree is as fast) or when the cell grid
    would not fit in int64 keys.
    """
    from .._kernels import compiled_kernels, use_numba
    from .._threads import even_chunks, get_num_threads, thread_map

    n, d = pts.shape
    if d < 3 and get_num_threads() == 1:
        # one thread in 1D / 2D: scipy's tree is as fast (401², δ = 2h: 0.17 s against
        # 0.22 s; 3D 64,000 points, δ = 3.015h: 0.84 s against 0.43 s)
        return None
    mod = compiled_kernels() if use_numba(n * 64) else None
    if mod is None or not (reach > 0 and np.isfinite(reach)):
        return None
    r = reach * (1.0 + 1e-9)
    lo = pts.min(axis=0)
    span = (pts.max(axis=0) - lo) / r
    if float(np.prod(np.floor(span) + 1.0)) > 2.0**62:
        return None
    cell = np.floor((pts - lo) / r).astype(np.int64)
    dims = cell.max(axis=0) + 1
    strides = np.ones(d, dtype=np.int64)
    for k in range(d - 2, -1, -1):
        strides[k] = strides[k + 1] * dims[k + 1]
    key = cell @ strides
    order = np.argsort(key, kind="stable")
    ukeys, first = np.unique(key[order], return_index=True)
    cell_ptr = np.append(first, n).astype(np.int64)
    offsets = np.stack(
        [g.ravel() for g in np.meshgrid(*([np.arange(-1, 2)] * d), indexing="ij")], axis=1
    ).astype(np.int64)
    args = (pts, cell, dims, strides, offsets, ukeys, cell_ptr, order, r * r)
    counts = np.empty(n, dtype=np.int64)
    chunks = even_chunks(n, _CELL_CHUNK)
    empty, empty_xi = np.empty(0, dtype=np.int64), np.empty((0, d))
    thread_map(lambda c: mod.cell_pairs(c[0], c[1], *args, counts, empty, empty_xi), chunks)
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=ptr[1:])
    j = np.empty(int(ptr[-1]), dtype=np.int64)
    xi = np.empty((j.size, d))
    thread_map(lambda c: mod.cell_pairs(c[0], c[1], *args, ptr, j, xi), chunks)
    return np.repeat(np.arange(n, dtype=np.int64), counts), j, xi


def _lengths_of_distinct(
    pts: np.ndarray, a: np.ndarray, b: np.ndarray, xi: np.ndarray
) -> np.ndarray:
    """Return the bond lengths ``|ξ|``.

    Raises for a pair of coincident points (``|ξ| <= 1e-12`` of the cloud's extent),
    naming the first pair.
    """
    length = np.sqrt(np.einsum("ij,ij->i", xi, xi))
    scale = float(np.max(np.ptp(pts, axis=0))) if pts.shape[0] > 1 else 1.0
    dup = length <= 1e-12 * max(scale, 1e-300)
    if dup.any():
        k = int(np.flatnonzero(dup)[0])
        p0, p1 = int(min(a[k], b[k])), int(max(a[k], b[k]))
        raise DuplicatePointError(
            f"points must be distinct, got points {p0} and {p1} both at {pts[p0].tolist()}",
            p0,
            p1,
        )
    return length


def _tree_pairs(
    cloud: PointCloud, hor: np.ndarray, shape: str, axes: np.ndarray | None, rtol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Find the directed bonds, sorted into CSR order.

    A cKDTree radius search, or with numba a threaded cell-list search.
    """
    pts = cloud.points
    n = cloud.n
    if shape in ("sphere", "cube"):
        reach = float(hor.max()) * (1 + rtol)
    else:
        assert axes is not None
        reach = float(np.max(axes)) * (1 + rtol)
    if shape in ("cube", "box"):
        reach *= math.sqrt(cloud.dim)  # the corner of the cube / box
    cand = _cell_candidates(np.ascontiguousarray(pts, dtype=np.float64), reach)
    if cand is not None:
        i, j, xi = cand
        length = _lengths_of_distinct(pts, i, j, xi)
        hij = np.full(1, hor[0]) if bool(np.all(hor == hor[0])) else np.maximum(hor[i], hor[j])
        keep = shape_mask(xi, length, hij, shape, axes, rtol)
        if keep.all():  # spheres: the candidates' margin rarely holds a bond
            return i, j, xi, length
        return i[keep], j[keep], xi[keep], length[keep]
    from scipy.spatial import cKDTree  # imported here: scipy.spatial is ~0.1 s of import

    tree = cKDTree(pts)
    if shape == "cube":
        pairs = tree.query_pairs(float(hor.max()) * (1 + rtol), p=np.inf, output_type="ndarray")
    elif shape == "box":
        assert axes is not None
        pairs = tree.query_pairs(float(axes.max()) * (1 + rtol), p=np.inf, output_type="ndarray")
    elif shape == "ellipsoid":
        assert axes is not None
        pairs = tree.query_pairs(float(axes.max()) * (1 + rtol), output_type="ndarray")
    else:
        pairs = tree.query_pairs(float(hor.max()) * (1 + rtol), output_type="ndarray")
    a = pairs[:, 0].astype(np.int64)
    b = pairs[:, 1].astype(np.int64)
    xi = pts[b] - pts[a]
    length = _lengths_of_distinct(pts, a, b, xi)
    hij = np.maximum(hor[a], hor[b])
    keep = shape_mask(xi, length, hij, shape, axes, rtol)
    a, b, xi, length = a[keep], b[keep], xi[keep], length[keep]
    nb = 2 * a.size
    ii = np.concatenate([a, b])
    jj = np.concatenate([b, a])
    # O(nb) counting sort through scipy's COO -> CSR conversion, then per-row sort by j
    perm = sp.coo_array((np.arange(nb, dtype=np.int64), (ii, jj)), shape=(n, n)).tocsr()
    perm.sort_indices()
    order = np.asarray(perm.data)
    xi_all = np.concatenate([xi, -xi])[order]
    return ii[order], jj[order], xi_all, np.concatenate([length, length])[order]


def _check_bond_memory(cloud: PointCloud, hor: np.ndarray, shape: str) -> None:
    """Refuse a bond search whose bonds do not fit in memory.

    The estimate is the neighbour count of a lattice ball of the horizon ratio (exact
    pair count on grid clouds).
    """
    from ..resources import (
        BOND_SEARCH_TRANSIENT,
        bonds_bytes,
        check_memory,
        estimate_pair_count,
        format_bytes,
    )

    nb = float(estimate_pair_count(cloud, hor))
    if shape in ("cube", "box"):
        nb *= 2.0**cloud.dim / (math.pi ** (cloud.dim / 2) / math.gamma(cloud.dim / 2 + 1))
    need = bonds_bytes(nb, cloud.n, cloud.dim) * (1 + BOND_SEARCH_TRANSIENT)
    ratio = float(np.median(hor / cloud.spacing))

    def hints() -> list[str]:
        return [
            f"a smaller horizon ratio (now {ratio:.3g} spacings, ~{nb / cloud.n:,.0f} "
            "neighbours per point; bytes grow as ratio^dim)",
            "a coarser discretization",
        ]

    check_memory(
        f"bond search (~{nb:,.0f} bonds, {format_bytes(bonds_bytes(nb, cloud.n, cloud.dim))})",
        need,
        hints,
    )


def _bond_store(
    cloud: PointCloud,
    j: np.ndarray,
    indptr: np.ndarray,
    hor: np.ndarray,
    stencil: np.ndarray | None,
    xi: np.ndarray,
    length: np.ndarray,
    influence: Any,
    allow_negative: bool,
) -> _CompactStore:
    """Evaluate the influence function and choose the compact storage of the bonds."""
    per_bond = length if stencil is None else length[stencil]
    if bool(np.all(hor == hor[0])):
        hij = np.full(j.size, hor[0])
    else:
        i = np.repeat(np.arange(cloud.n, dtype=np.int64), np.diff(indptr))
        hij = np.maximum(hor[i], hor[j])
        del i
    omega = evaluate_influence(influence, per_bond, hij, allow_negative=allow_negative)
    del hij, per_bond

    def table() -> np.ndarray:
        return evaluate_influence(
            influence, length, np.full(length.size, hor[0]), allow_negative=allow_negative
        )

    return _compact_store(stencil, xi, length, omega, table, np.asarray(cloud.volumes))


def find_bonds(
    cloud: PointCloud,
    horizon: float | Sequence[float] | np.ndarray | None = None,
    *,
    ratio: float | None = None,
    shape: str = "sphere",
    axes: Sequence[float] | None = None,
    influence: str | InfluenceFunction = "constant",
    cracks: Any = None,
    exclude: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    allow_isolated: bool = False,
    allow_negative_influence: bool = False,
    rtol: float = 1e-9,
    method: str = "auto",
) -> Bonds:
    """Find the bonds (families) of every point.

    Parameters
    ----------
    cloud : PointCloud
        The points (their lattice metadata enables the integer-stencil search).
    horizon : float or (n,) array_like, optional
        Constant or per-point horizon delta_i.  ``j`` is in the family of
        ``i`` when ``|x_j - x_i| <= max(delta_i, delta_j)`` (the symmetric
        family rule of XOSB), so families are symmetric.  Defaults to
        ``cloud.horizon``.
    ratio : float, optional
        Horizon as a multiple ``m`` of the spacing (``delta_i = m * h_i``,
        with ``h_i = V_i ** (1/dim)``, or the lattice spacing for grids).
    shape : {'sphere', 'cube', 'ellipsoid', 'box'}
        Neighborhood shape: Euclidean ball, cube of half-width delta,
        ellipsoid with semi-axes ``axes`` or box with half-widths ``axes``.
    axes : (dim,) array_like of float, optional
        Semi-axes / half-widths for 'ellipsoid' / 'box' (absolute lengths).
    influence : str or callable
        Influence function name (see
        :data:`pdlin.geometry.INFLUENCE_FUNCTIONS`) or
        ``f(length, horizon_ij) -> omega``.
    cracks : array_like, optional
        Bonds crossing these are removed: 2D segments ``(m, 2, 2)`` or 3D
        triangles ``(m, 3, 3)``.
    exclude : callable, optional
        ``exclude(x_i, x_j) -> bool mask`` of bonds to drop (both directions
        are tested, a bond is dropped if either direction is flagged).
    allow_isolated : bool
        Allow points without any bond (default: raise NoNeighborsError).
    allow_negative_influence : bool
        Accept negative influence values (higher-order correspondence
        weights, :func:`pdlin.models.higher_order_weights`); bond-based models
        refuse bonds with negative stiffness.
    rtol : float
        Relative tolerance of the inclusive membership test, in ``[0, 1)``.
    method : {'auto', 'lattice', 'tree'}
        'lattice' uses the integer stencil of a :func:`pdlin.grid` cloud
        (exact bond vectors, no search); 'auto' picks it when possible.

    Returns
    -------
    Bonds
        Directed bonds in CSR order (both directions stored).

    Raises
    ------
    InputError
        If an option is invalid (``shape``, ``rtol``, ``method``, ``axes``), a non-sphere
        shape has a per-point horizon, or ``cloud`` is not a PointCloud.
    ShapeError
        If ``exclude`` returns a mask of the wrong shape.
    NoNeighborsError
        If a point has no bond and ``allow_isolated`` is False.

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((7, 7, 7))
    >>> bonds = pdlin.find_bonds(cloud, 3.015)
    >>> int(bonds.family_size.max())   # 122 neighbors inside a sphere of radius 3.015 h
    122
    """
    if not isinstance(cloud, PointCloud):
        raise InputError(f"cloud must be a PointCloud, got {type(cloud).__name__}")
    hor = resolve_horizon(cloud, horizon, ratio)
    if shape not in SHAPES:
        raise InputError(f"shape must be one of {SHAPES}, got {shape!r}")
    if not isinstance(rtol, int | float | np.number) or not (0.0 <= float(rtol) < 1.0):
        raise InputError(f"rtol must be a number in [0, 1), got {rtol!r}")
    ax: np.ndarray | None = None
    if shape in ("ellipsoid", "box"):
        if axes is None:
            raise InputError(f"axes must be given for shape={shape!r}, got None")
        ax = as_float_array(axes, "axes")
        if ax.shape != (cloud.dim,) or np.any(ax <= 0):
            raise InputError(f"axes must be {cloud.dim} positive lengths, got {ax.tolist()}")
        if not np.all(hor == hor[0]):
            raise InputError(f"shape={shape!r} requires a constant horizon, got a per-point one")
    elif axes is not None:
        raise InputError(f"axes is only used with shape 'ellipsoid' or 'box', got shape={shape!r}")
    uniform = bool(np.all(hor == hor[0]))
    if method not in ("auto", "lattice", "tree"):
        raise InputError(f"method must be 'auto', 'lattice' or 'tree', got {method!r}")
    use_lattice = cloud.lattice is not None and uniform and method != "tree"
    if method == "lattice" and not use_lattice:
        raise InputError("method='lattice' needs a grid cloud and a constant horizon")
    _check_bond_memory(cloud, hor, shape)
    stencil: np.ndarray | None = None
    if use_lattice:
        i, j, stencil, xi, length = _lattice_pairs(cloud, float(hor[0]), shape, ax, rtol)
    else:
        i, j, xi, length = _tree_pairs(cloud, hor, shape, ax, rtol)
    drop = None
    if cracks is not None:
        drop = _crack_mask(cloud.points, i, j, cracks)
    if exclude is not None:
        m = np.asarray(exclude(cloud.points[i], cloud.points[j]), dtype=bool)
        if m.shape != i.shape:
            raise ShapeError(f"exclude must return a mask of shape {i.shape}, got {m.shape}")
        drop = m if drop is None else drop | m
    counts = np.bincount(i, minlength=cloud.n)
    indptr = np.zeros(cloud.n + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    del i
    bonds = Bonds._from_parts(
        cloud.n, j, indptr, hor, shape, influence,
        _bond_store(cloud, j, indptr, hor, stencil, xi, length, influence,
                    allow_negative_influence),
    )  # fmt: skip
    if drop is not None and drop.any():
        drop = drop | drop[bonds.reverse]
        bonds = bonds.keep(~drop)
    if not allow_isolated:
        empty = np.flatnonzero(bonds.family_size == 0)
        if empty.size:
            raise NoNeighborsError(
                f"every point needs at least one bond, got {empty.size} isolated point(s), "
                f"first index {int(empty[0])} at {cloud.points[empty[0]].tolist()} "
                f"(horizon {float(hor[empty[0]]):.4g}); increase the horizon or pass "
                "allow_isolated=True"
            )
    log.debug("found %d bonds for %d points", bonds.n_bonds, cloud.n)
    return bonds
