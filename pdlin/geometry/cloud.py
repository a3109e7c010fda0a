"""Point clouds: the discretization every pdlin model works on."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from .._validation import as_float_array, check_finite, integer, positive_scalar
from ..errors import InputError, NonFiniteError, ShapeError

__all__ = ["PointCloud", "Lattice", "grid", "from_image", "ghost_layer", "GhostLayer"]


@dataclass(frozen=True)
class Lattice:
    """Metadata of a regular cell-centred lattice (set by :func:`~pdlin.grid`).

    Parameters
    ----------
    shape : tuple of int
        Number of cells per axis.
    spacing : (dim,) ndarray
        Cell size per axis.
    origin : (dim,) ndarray
        Lower corner of the lattice box (not the first cell centre).
    index : (n,) ndarray of int or None
        Flat C-order lattice index of each point, or None when every cell
        holds a point in C order.
    """

    shape: tuple[int, ...]
    spacing: np.ndarray
    origin: np.ndarray
    index: np.ndarray | None = None


def _as_index_array(value: Any, name: str, n: int) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise ShapeError(f"{name} boolean mask must have shape ({n},), got {arr.shape}")
        return np.flatnonzero(arr)
    if arr.size == 0:
        return np.zeros(0, dtype=np.intp)
    if not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{name} must hold integer point indices, got dtype {arr.dtype}")
    arr = arr.ravel().astype(np.intp)
    if arr.min() < 0 or arr.max() >= n:
        raise InputError(
            f"{name} must hold indices in [0, {n - 1}], got range [{arr.min()}, {arr.max()}]"
        )
    return arr


_FACE_SETS = ("x-", "x+", "y-", "y+", "z-", "z+")


@dataclass(frozen=True, eq=False)
class PointCloud:
    """Material points with volumes, optional horizons, phases and named sets.

    Parameters
    ----------
    points : (n, dim) array_like of float
        Reference coordinates, ``dim`` in {1, 2, 3}.  A 1-D array is read as
        ``n`` points on a line.
    volumes : (n,) array_like of float or float
        Volume (length in 1D, area in 2D) of each point; a scalar is
        broadcast.  Must be > 0.
    horizon : (n,) array_like of float or float, optional
        Per-point horizon delta_i.  :func:`pdlin.find_bonds` uses it when no
        horizon is passed there.
    material : (n,) array_like of int, optional
        Material / phase id of each point (default all 0).
    sets : mapping of str to index array or boolean mask, optional
        Named point sets (boundary faces, load patches, physical groups).
    thickness : float, optional
        Out-of-plane thickness of 2D bodies (default 1); loads and
        reactions are reported per unit thickness times this value.
    lattice : Lattice, optional
        Regular-lattice metadata, enabling the stencil bond search.

    Raises
    ------
    ShapeError
        If ``points``, ``volumes``, ``horizon`` or ``material`` has the wrong shape.
    InputError
        If there is no point, a volume or horizon is not > 0, ``material`` is not
        integer, or a set name is not a string.

    Examples
    --------
    >>> import numpy as np
    >>> cloud = PointCloud(np.array([[0.0, 0.0], [1.0, 0.0]]), volumes=1.0)
    >>> cloud.n, cloud.dim
    (2, 2)
    >>> PointCloud([[0.0], [np.nan]], volumes=1.0)
    Traceback (most recent call last):
    ...
    pdlin.errors.NonFiniteError: points must be finite, got nan at index (1, 0)
    """

    points: np.ndarray
    volumes: np.ndarray
    horizon: np.ndarray | None = None
    material: np.ndarray | None = None
    sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    thickness: float = 1.0
    lattice: Lattice | None = None

    def __post_init__(self) -> None:
        """Validate the fields; make points and volumes read-only float arrays."""
        pts = as_float_array(self.points, "points")
        if pts.ndim == 1:
            pts = pts[:, None]
        if pts.ndim != 2 or pts.shape[1] not in (1, 2, 3):
            raise ShapeError(f"points must have shape (n, dim) with dim in 1..3, got {pts.shape}")
        n = pts.shape[0]
        if n == 0:
            raise InputError("points must hold at least one point, got 0")
        vol = as_float_array(self.volumes, "volumes")
        if vol.ndim == 0:
            vol = np.full(n, float(vol))
        if vol.shape != (n,):
            raise ShapeError(f"volumes must have shape ({n},) to match points, got {vol.shape}")
        if np.any(vol <= 0):
            k = int(np.flatnonzero(vol <= 0)[0])
            raise InputError(f"volumes must be > 0, got {vol[k]} at point {k}")
        hor = None
        if self.horizon is not None:
            hor = as_float_array(self.horizon, "horizon")
            if hor.ndim == 0:
                hor = np.full(n, float(hor))
            if hor.shape != (n,):
                raise ShapeError(f"horizon must have shape ({n},) or be a scalar, got {hor.shape}")
            if np.any(hor <= 0):
                k = int(np.flatnonzero(hor <= 0)[0])
                raise InputError(f"horizon must be > 0, got {hor[k]} at point {k}")
        mat = np.zeros(n, dtype=np.int64)
        if self.material is not None:
            m = np.asarray(self.material)
            if m.ndim == 0:
                m = np.full(n, m)
            if m.shape != (n,):
                raise ShapeError(f"material must have shape ({n},), got {m.shape}")
            if not np.issubdtype(m.dtype, np.integer):
                if not (np.issubdtype(m.dtype, np.floating) or m.dtype == bool):
                    raise InputError(f"material must hold integer ids, got dtype {m.dtype}")
                if np.issubdtype(m.dtype, np.floating):
                    check_finite(m, "material")
                if not np.all(np.asarray(m) == np.round(m)):
                    raise InputError(f"material must hold integer ids, got dtype {m.dtype}")
            mat = m.astype(np.int64)
        sets = {}
        for name, idx in dict(self.sets).items():
            if not isinstance(name, str):
                raise InputError(f"set names must be strings, got {name!r}")
            sets[name] = _as_index_array(idx, f"sets[{name!r}]", n)
        thick = positive_scalar(self.thickness, "thickness")
        pts.setflags(write=False)
        vol.setflags(write=False)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "volumes", vol)
        object.__setattr__(self, "horizon", hor)
        object.__setattr__(self, "material", mat)
        object.__setattr__(self, "sets", sets)
        object.__setattr__(self, "thickness", thick)

    @property
    def n(self) -> int:
        """Number of points."""
        return int(self.points.shape[0])

    @property
    def dim(self) -> int:
        """Spatial dimension (1, 2 or 3)."""
        return int(self.points.shape[1])

    @property
    def ndof(self) -> int:
        """Number of displacement degrees of freedom, ``n * dim``."""
        return self.n * self.dim

    @cached_property
    def spacing(self) -> np.ndarray:
        """Characteristic spacing per point, ``volume ** (1 / dim)``."""
        return np.asarray(self.volumes ** (1.0 / self.dim))

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners of the bounding box of the points."""
        return self.points.min(axis=0), self.points.max(axis=0)

    def point_set(self, name: str) -> np.ndarray:
        """Return the indices of the named set, or raise a clear error.

        Two names are always defined unless the cloud has sets of that name:
        ``'all'`` (every point) and ``'boundary'`` (the union of the face sets
        ``'x-'``, ``'x+'``, ... the cloud has, e.g. the outermost ring of a
        :func:`pdlin.grid`).

        Parameters
        ----------
        name : str
            A key of ``sets``, ``'all'`` or ``'boundary'``.

        Returns
        -------
        ndarray of int
            Point indices of the set.

        Raises
        ------
        InputError
            If no set of that name exists (the message lists the known ones).

        Examples
        --------
        >>> import pdlin
        >>> pdlin.grid((4, 4)).point_set("boundary").size   # 16 points minus the 2 x 2 core
        12
        """
        if name in self.sets:
            return self.sets[name]
        if name == "all":
            return np.arange(self.n)
        faces = [self.sets[f] for f in _FACE_SETS if f in self.sets]
        if name == "boundary" and faces:
            return np.unique(np.concatenate(faces))
        known = ", ".join([*sorted(self.sets), "all"] + (["boundary"] if faces else []))
        raise InputError(f"unknown point set {name!r}; known sets: {known}")

    def select(
        self,
        where: str | Sequence[int] | np.ndarray | None = None,
        *,
        box: tuple[Sequence[float], Sequence[float]] | None = None,
    ) -> np.ndarray:
        """Resolve a set name, index array, mask or bounding box to indices.

        Parameters
        ----------
        where : str or array_like, optional
            A set name, an index array or a boolean mask.
        box : (lower, upper), optional
            Select points with ``lower <= x <= upper`` componentwise (use
            ``-inf``/``inf`` for open sides).

        Returns
        -------
        (m,) ndarray of int
            Possibly empty: callers that need points say so (a condition or
            load selecting none raises there).

        Raises
        ------
        NonFiniteError
            A box corner holding NaN.
        InputError
            A box whose lower corner exceeds its upper one (it can hold no point).

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((4, 2))
        >>> cloud.select(box=([2.0, -np.inf], [np.inf, 1.0])).tolist()
        [4, 6]
        >>> cloud.select(box=([np.nan, 0.0], [1.0, 1.0]))  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        pdlin.errors.NonFiniteError: box lower corner must hold numbers ... got nan at index 0
        """
        if box is not None:
            try:
                lo = np.asarray(box[0], dtype=float)
                hi = np.asarray(box[1], dtype=float)
            except (TypeError, ValueError, IndexError) as exc:
                raise InputError(f"box must be (lower, upper) corners of numbers: {exc}") from exc
            if lo.shape != (self.dim,) or hi.shape != (self.dim,):
                raise ShapeError(
                    f"box corners must have shape ({self.dim},), got {lo.shape} and {hi.shape}"
                )
            for corner, name in ((lo, "lower"), (hi, "upper")):
                if np.isnan(corner).any():
                    k = int(np.flatnonzero(np.isnan(corner))[0])
                    raise NonFiniteError(
                        f"box {name} corner must hold numbers (-inf / inf for open sides), "
                        f"got nan at index {k}"
                    )
            if np.any(lo > hi):
                k = int(np.flatnonzero(lo > hi)[0])
                raise InputError(
                    f"box lower corner must not exceed the upper one, got lower {lo.tolist()} "
                    f"and upper {hi.tolist()} (axis {k})"
                )
            mask = np.all((self.points >= lo) & (self.points <= hi), axis=1)
            idx = np.flatnonzero(mask)
            if where is not None:
                idx = np.intersect1d(idx, self.select(where))
            return idx
        if where is None:
            return np.arange(self.n)
        if isinstance(where, str):
            return self.point_set(where)
        return _as_index_array(where, "point selection", self.n)

    def with_sets(self, **sets: Any) -> PointCloud:
        """Return a copy with extra named point sets.

        Parameters
        ----------
        **sets : array_like of int
            New sets by name (an existing name is replaced).

        Returns
        -------
        PointCloud
            A validated copy; the lattice metadata is kept.
        """
        merged = dict(self.sets)
        merged.update(sets)
        return self.replace(sets=merged)

    def replace(self, **changes: Any) -> PointCloud:
        """Return a copy with some fields replaced (validated again).

        Parameters
        ----------
        **changes
            New values for ``points``, ``volumes``, ``horizon``, ``material``, ``sets``,
            ``thickness`` or ``lattice``.  New ``points`` drop the lattice metadata unless
            ``lattice`` is given too.

        Returns
        -------
        PointCloud
            The new cloud.
        """
        data: dict[str, Any] = {
            "points": self.points,
            "volumes": self.volumes,
            "horizon": self.horizon,
            "material": self.material,
            "sets": self.sets,
            "thickness": self.thickness,
            "lattice": self.lattice,
        }
        if "points" in changes and "lattice" not in changes:
            data["lattice"] = None
        data.update(changes)
        return PointCloud(**data)

    def subset(self, index: Sequence[int] | np.ndarray) -> PointCloud:
        """Return the cloud restricted to ``index`` (sets are re-indexed).

        Parameters
        ----------
        index : array_like of int
            Points to keep, in the order of the new cloud.

        Returns
        -------
        PointCloud
            The subset, without lattice metadata; sets keep their surviving points.

        Raises
        ------
        InputError
            If an index is out of range or not an integer.
        """
        idx = _as_index_array(index, "index", self.n)
        new_of_old = np.full(self.n, -1, dtype=np.intp)
        new_of_old[idx] = np.arange(idx.size)
        sets = {}
        for name, s in self.sets.items():
            t = new_of_old[s]
            sets[name] = t[t >= 0]
        return PointCloud(
            self.points[idx],
            self.volumes[idx],
            horizon=None if self.horizon is None else self.horizon[idx],
            material=self.material[idx] if self.material is not None else None,
            sets=sets,
            thickness=self.thickness,
        )

    def __repr__(self) -> str:
        """Return size, dimension, total volume and set names (no arrays)."""
        return (
            f"PointCloud(n={self.n}, dim={self.dim}, volume={self.volumes.sum():.6g}, "
            f"sets={sorted(self.sets)})"
        )


_AXES = "xyz"


def _face_sets(points: np.ndarray, lo: np.ndarray, hi: np.ndarray, h: np.ndarray) -> dict:
    """Return the sets 'x-', 'x+', ... holding the outermost layer of a box of points."""
    sets: dict[str, np.ndarray] = {}
    for k in range(points.shape[1]):
        tol = 0.5 * h[k]
        sets[f"{_AXES[k]}-"] = np.flatnonzero(points[:, k] < lo[k] + tol)
        sets[f"{_AXES[k]}+"] = np.flatnonzero(points[:, k] > hi[k] - tol)
    return sets


def _check_grid_memory(shp: tuple[int, ...]) -> None:
    """Refuse a grid whose points do not fit, before allocating them."""
    from ..resources import available_memory, check_memory, grid_bytes

    n = math.prod(shp)  # exact Python int: no overflow for (10**6, 10**6)
    need = grid_bytes(float(n), len(shp))

    def hints() -> list[str]:
        fit = max(int(available_memory().bytes / max(need / n, 1.0) * 0.9), 1)
        per_axis = max(int(fit ** (1 / len(shp))), 1)
        return [
            f"at most ~{fit:,} points, e.g. shape {[per_axis] * len(shp)} (the bonds and K "
            "need 10-100 x more than the points: see pdlin.problem.plan_memory)"
        ]

    check_memory(f"grid of shape {list(shp)} ({n:,} points)", need, hints)


def grid(
    shape: int | Sequence[int],
    spacing: float | Sequence[float] = 1.0,
    origin: Sequence[float] | None = None,
    *,
    horizon: float | None = None,
    thickness: float = 1.0,
) -> PointCloud:
    """Build a cell-centred uniform grid of points in 1D, 2D or 3D.

    Parameters
    ----------
    shape : int or sequence of int
        Number of cells per axis; its length sets the dimension.
    spacing : float or sequence of float
        Cell size per axis (default 1).
    origin : sequence of float, optional
        Lower corner of the box; points sit at ``origin + (k + 1/2) h``.
        Defaults to the zero vector.
    horizon : float, optional
        Constant horizon stored on the cloud.
    thickness : float
        Out-of-plane thickness for 2D bodies.

    Returns
    -------
    PointCloud
        Points in C order (last axis fastest) with volumes ``prod(h)`` and
        the face sets ``'x-'``, ``'x+'``, ``'y-'``, ... (outermost layer).

    Raises
    ------
    InputError
        If ``shape`` is not integer, an entry is < 1, or a spacing is not > 0.
    ShapeError
        If ``shape`` has not 1-3 entries, or ``spacing`` / ``origin`` has the wrong length.

    Examples
    --------
    >>> cloud = grid((4, 2), spacing=0.5)
    >>> cloud.points[:3]
    array([[0.25, 0.25],
           [0.25, 0.75],
           [0.75, 0.25]])
    >>> float(cloud.volumes[0]), sorted(cloud.sets)
    (0.25, ['x+', 'x-', 'y+', 'y-'])
    """
    if isinstance(shape, str) or not isinstance(shape, int | np.integer | Sequence | np.ndarray):
        raise InputError(f"shape must be an integer or a sequence of integers, got {shape!r}")
    if isinstance(shape, int | np.integer):
        shp: tuple[int, ...] = (integer(shape, "shape"),)
    else:
        shp = tuple(integer(s, f"shape[{k}]") for k, s in enumerate(shape))
    dim = len(shp)
    if dim not in (1, 2, 3):
        raise ShapeError(f"shape must have 1, 2 or 3 entries, got {shp}")
    if any(s < 1 for s in shp):
        raise InputError(f"shape entries must be >= 1, got {shp}")
    h = as_float_array(spacing, "spacing")
    if h.ndim > 1 or h.size not in (1, dim):
        raise ShapeError(f"spacing must be a scalar or have shape ({dim},), got {h.shape}")
    h = np.broadcast_to(h.reshape(-1), (dim,)).astype(float)
    if np.any(h <= 0):
        raise InputError(f"spacing must be > 0, got {h.tolist()}")
    o = np.zeros(dim) if origin is None else as_float_array(origin, "origin")
    if o.shape != (dim,):
        raise ShapeError(f"origin must have shape ({dim},), got {o.shape}")
    _check_grid_memory(shp)
    axes = [o[k] + (np.arange(shp[k]) + 0.5) * h[k] for k in range(dim)]
    mesh = np.meshgrid(*axes, indexing="ij")
    points = np.stack([m.ravel() for m in mesh], axis=1)
    lo = o + 0.5 * h
    hi = o + (np.array(shp) - 0.5) * h
    return PointCloud(
        points,
        np.full(points.shape[0], float(np.prod(h))),
        horizon=None if horizon is None else np.full(points.shape[0], float(horizon)),
        sets=_face_sets(points, lo, hi, h),
        thickness=thickness,
        lattice=Lattice(shp, h, o),
    )


def from_image(
    image: Any,
    spacing: float | Sequence[float] = 1.0,
    origin: Sequence[float] | None = None,
    *,
    void: int | None = None,
    horizon: float | None = None,
    thickness: float = 1.0,
) -> PointCloud:
    """Build a point cloud from a pixel/voxel array of phase ids (a microstructure).

    Parameters
    ----------
    image : (nx,) or (nx, ny) or (nx, ny, nz) array_like of int
        Phase id per cell; axis k of the array is spatial axis k.
    spacing, origin, horizon, thickness
        As in :func:`~pdlin.grid`.
    void : int, optional
        Phase id marking empty cells (no point is created there).

    Returns
    -------
    PointCloud
        One point per non-void cell, ``material`` set to the phase id and one
        named set ``'phase<k>'`` per phase, plus the box face sets.

    Raises
    ------
    ShapeError
        If ``image`` is empty or not 1-, 2- or 3-dimensional.
    InputError
        If ``image`` holds non-integer ids or only the void phase.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.array([[0, 1], [2, 1]])
    >>> c = from_image(img, void=2)
    >>> c.n, c.material.tolist(), sorted(c.sets)[:2]
    (3, [0, 1, 1], ['phase0', 'phase1'])
    """
    img = np.asarray(image)
    if img.ndim not in (1, 2, 3) or img.size == 0:
        raise ShapeError(f"image must be a non-empty 1-D, 2-D or 3-D array, got shape {img.shape}")
    if not np.issubdtype(img.dtype, np.integer):
        if np.issubdtype(img.dtype, np.bool_):
            img = img.astype(np.int64)
        elif not np.issubdtype(img.dtype, np.floating):
            raise InputError(f"image must hold integer phase ids, got dtype {img.dtype}")
        else:
            imgf = np.asarray(img, dtype=float)
            check_finite(imgf, "image")
            if not np.all(imgf == np.round(imgf)):
                raise InputError(f"image must hold integer phase ids, got dtype {img.dtype}")
            img = imgf.astype(np.int64)
    full = grid(img.shape, spacing, origin, horizon=horizon, thickness=thickness)
    phases = img.ravel()
    keep = np.ones(phases.size, dtype=bool) if void is None else phases != void
    if not keep.any():
        raise InputError(f"image holds only the void phase {void}; no points would be created")
    idx = np.flatnonzero(keep)
    sub = full.subset(idx)
    sets = dict(sub.sets)
    for p in np.unique(phases[idx]):
        sets[f"phase{int(p)}"] = np.flatnonzero(phases[idx] == p)
    lat = full.lattice
    assert lat is not None
    return PointCloud(
        sub.points,
        sub.volumes,
        horizon=sub.horizon,
        material=phases[idx],
        sets=sets,
        thickness=thickness,
        lattice=Lattice(lat.shape, lat.spacing, lat.origin, index=idx),
    )


class GhostLayer(NamedTuple):
    """Result of :func:`ghost_layer`: ``cloud, ghost, source = ghost_layer(...)``."""

    #: the original points (same indices, first) followed by the ghost points
    cloud: PointCloud
    #: indices of the ghost points in ``cloud``, ``(m,)``
    ghost: np.ndarray
    #: for every point of ``cloud`` the original point it copies its data from (itself for
    #: original points, the nearest original point for ghosts), ``(n + m,)``
    source: np.ndarray


def ghost_layer(cloud: PointCloud, layers: int = 1) -> GhostLayer:
    """Add ``layers`` rings of ghost points around a lattice cloud.

    The ghosts fill the cells of the lattice box grown by ``layers`` cells on every side;
    prescribe their displacement by the same affine map as the boundary (e.g. with
    :meth:`pdlin.Dirichlet.velocity_gradient`) so that the original boundary particles
    have complete families.  With the correspondence model at δ = h or √2 h and the
    original outer ring prescribed, a uniform stress then gives zero force at every free
    particle and a single crystal under affine boundary conditions deforms exactly
    affinely; with the truncated families of Luo, Ramazani & Sundararaghavan (2017)
    it does not (derived: a uniform stress then leaves a force ``P n / (2h)`` at the free
    particles next to an edge).  The ghost layer is pdlin's option, not the paper's.

    The original points keep their indices; the ghosts are appended (C order of their
    cells).  Volumes are the lattice cell volume; ``horizon`` and ``material`` are copied
    from ``source``; the sets are kept, with two more: ``'ghost'`` (the ghosts) and
    ``'outer_ring'`` (the original points in the outermost cells of the original box).
    Extend per-particle data such as orientations with ``data[source]``.

    Parameters
    ----------
    cloud : PointCloud
        A cloud with lattice metadata (:func:`~pdlin.grid`, :func:`~pdlin.geometry.from_image`).
    layers : int
        Number of ghost rings (>= 1).

    Returns
    -------
    GhostLayer
        ``(cloud, ghost, source)``.

    Raises
    ------
    InputError
        If ``cloud`` has no lattice metadata or ``layers`` is not an integer >= 1.

    Examples
    --------
    >>> import numpy as np
    >>> g = ghost_layer(grid((4, 3), spacing=0.5))
    >>> g.cloud.n, g.ghost.size, g.cloud.lattice.shape
    (30, 18, (6, 5))
    >>> g.cloud.points[g.ghost[0]].tolist(), int(g.source[g.ghost[0]])
    ([-0.25, -0.25], 0)
    >>> g.cloud.point_set("outer_ring").size
    10
    """
    lat = cloud.lattice
    if lat is None:
        raise InputError(
            "ghost_layer needs a lattice cloud (pdlin.grid or pdlin.geometry.from_image), "
            "got a cloud without lattice metadata"
        )
    if isinstance(layers, bool) or not isinstance(layers, int | np.integer) or layers < 1:
        raise InputError(f"layers must be an integer >= 1, got {layers!r}")
    L = int(layers)
    dim, n = cloud.dim, cloud.n
    shp = np.array(lat.shape, dtype=np.int64)
    big = shp + 2 * L
    h = np.asarray(lat.spacing, dtype=float)
    origin = np.asarray(lat.origin, dtype=float) - L * h
    flat_old = np.arange(n, dtype=np.int64) if lat.index is None else np.asarray(lat.index)
    multi_old = np.stack(np.unravel_index(flat_old, tuple(shp)), axis=1)
    flat_new = np.ravel_multi_index(tuple((multi_old + L).T), tuple(big))
    cells = np.indices(tuple(big)).reshape(dim, -1).T  # C order
    outside = np.any((cells < L) | (cells >= shp + L), axis=1)
    gcells = cells[outside]
    gflat = np.flatnonzero(outside)
    gpts = origin + (gcells + 0.5) * h
    from scipy.spatial import cKDTree

    _, near = cKDTree(cloud.points).query(gpts)
    m = gpts.shape[0]
    source = np.concatenate([np.arange(n), np.asarray(near, dtype=np.intp)])
    ghost = np.arange(n, n + m)
    ring = np.flatnonzero(np.any((multi_old == 0) | (multi_old == shp - 1), axis=1))
    sets = dict(cloud.sets)
    sets["ghost"] = ghost
    sets["outer_ring"] = ring
    return GhostLayer(
        PointCloud(
            np.vstack([cloud.points, gpts]),
            np.concatenate([cloud.volumes, np.full(m, float(np.prod(h)))]),
            horizon=None if cloud.horizon is None else cloud.horizon[source],
            material=None if cloud.material is None else cloud.material[source],
            sets=sets,
            thickness=cloud.thickness,
            lattice=Lattice(
                tuple(int(b) for b in big), h, origin, np.concatenate([flat_new, gflat])
            ),
        ),
        ghost,
        source,
    )
