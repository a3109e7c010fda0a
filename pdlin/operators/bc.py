"""Boundary conditions and loads as data: Dirichlet, TimePath, BodyForce, TotalForce.

Their meaning on a cloud (prescribed DOFs and values, nodal forces, the rigid-motion
check and the elimination from ``K u = f``) is computed by :mod:`pdlin.constraints`
for :class:`pdlin.system.ConstrainedSystem`.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg

from .._repr import Raw, compact_repr
from .._validation import as_float_array, integer
from ..errors import InputError, ShapeError
from ..geometry.cloud import PointCloud

__all__ = [
    "Dirichlet",
    "TimePath",
    "BodyForce",
    "TotalForce",
    "shadow_layer",
    "parse_components",
]

#: functions of the constrained system that lived here (now in :mod:`pdlin.constraints`)
_MOVED = (
    "resolve_dirichlet",
    "load_vector",
    "eliminate_dirichlet",
    "matrix_rows",
    "check_constraints",
)


def __getattr__(name: str) -> Any:
    """Return a function moved to :mod:`pdlin.constraints` (deprecated access, warns)."""
    if name in _MOVED:
        warnings.warn(
            f"pdlin.operators.bc.{name} moved to pdlin.constraints.{name}; the old path "
            "will be removed in the next release",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module("pdlin.constraints"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


Where = str | Sequence[int] | np.ndarray
ValueSpec = float | Sequence[float] | np.ndarray | Callable[[np.ndarray], Any]

_AX = {"x": 0, "y": 1, "z": 2}


def parse_components(components: Any, dim: int) -> np.ndarray:
    """Convert a components spec to axis indices: None (all), 'x', 'xz', 0, [0, 2].

    Parameters
    ----------
    components : None, str, int or sequence of int
        None for all axes, letters from 'xyz' or axis indices.
    dim : int
        Spatial dimension.

    Returns
    -------
    (k,) ndarray of int
        Distinct axes in ``[0, dim)``, in the given order.

    Raises
    ------
    InputError
        For letters outside 'xyz', repeated axes or axes ``>= dim``.

    Examples
    --------
    >>> parse_components("xz", 3).tolist()
    [0, 2]
    """
    if components is None:
        return np.arange(dim)
    if isinstance(components, str):
        try:
            comps = [_AX[ch] for ch in components.lower()]
        except KeyError:
            raise InputError(f"components must be letters from 'xyz', got {components!r}") from None
    else:
        comps = [integer(c, "components") for c in np.atleast_1d(components)]
    arr = np.asarray(comps, dtype=np.intp)
    if arr.size == 0 or arr.min() < 0 or arr.max() >= dim or np.unique(arr).size != arr.size:
        raise InputError(f"components must be distinct axes in [0, {dim - 1}], got {components!r}")
    return arr


def _check_where(where: Any, name: str) -> None:
    """Eager type check of a point selection (set name, index array, mask or None)."""
    if where is None or isinstance(where, str):
        return
    arr = np.asarray(where)
    if arr.dtype != bool and arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise InputError(
            f"{name} must be a set name, integer point indices or a boolean mask, "
            f"got dtype {arr.dtype}"
        )


def _check_value(value: Any, name: str) -> None:
    """Eager check of a non-callable BC / load value: numeric and finite."""
    if value is None or callable(value) or isinstance(value, TimePath):
        return
    as_float_array(value, name)


@dataclass(frozen=True)
class TimePath:
    """A prescribed displacement that depends on time, ``fn(points, t)``.

    ``fn`` receives the ``(m, dim)`` reference points and the time ``t`` and
    returns any value form of :class:`~pdlin.Dirichlet`.  Linear solves evaluate it
    at ``t = 1``; :func:`pdlin.solve_nonlinear` at every load step's time
    (other Dirichlet values are scaled by the load factor instead).

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.constraints import resolve_dirichlet
    >>> cloud = pdlin.grid((2, 2))
    >>> bc = pdlin.Dirichlet("x+", TimePath(lambda x, t: 0.1 * t), components="x")
    >>> resolve_dirichlet(cloud, [bc], t=3.0)[1].round(6).tolist()
    [0.3, 0.3]
    """

    fn: Callable[[np.ndarray, float], Any]
    description: str = ""
    #: velocity gradient and centre of an affine path (set by
    #: :meth:`pdlin.Dirichlet.velocity_gradient`; drivers use them for the affine predictor)
    L: Any = None
    center: Any = None

    def __repr__(self) -> str:
        """Return ``TimePath(...)``: the description, or the function's name, and ``L``."""
        shown = self.description or _shown(self.fn)
        return compact_repr("TimePath", {"path": shown, "L": self.L})


def _shown(value: Any) -> Any:
    """Return a condition's field as :func:`~pdlin._repr.compact_repr` shows it."""
    if isinstance(value, TimePath):
        return Raw(repr(value))
    if callable(value):
        return Raw(f"<function {getattr(value, '__qualname__', type(value).__name__)}>")
    return value


@dataclass(frozen=True)
class Dirichlet:
    """Prescribed displacement on a point set.

    Parameters
    ----------
    where : str or index array or mask
        Point set name (e.g. ``'x-'``) or indices.
    value : float, array_like or callable
        Displacement of the ``m`` selected points.  Either the full vector,
        a scalar, ``(dim,)`` or ``(m, dim)`` (only the constrained
        components are used), or one column per constrained component:
        ``(k,)`` or ``(m, k)`` for ``k`` components, and ``(m,)`` when one
        component is named (an array of shape ``(m,)`` with ``m == dim`` is
        ambiguous and raises; pass ``(m, 1)``).  A callable receives the
        ``(m, dim)`` reference points and returns any of these forms (its
        per-point forms win over the full-vector ones).
    components : str or sequence of int, optional
        Constrained components (default all), e.g. ``'x'`` or ``[0, 2]``.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.constraints import resolve_dirichlet
    >>> cloud = pdlin.grid((3, 2))
    >>> bc = Dirichlet.affine("x+", np.eye(2) + [[0.01, 0], [0, 0]], components="x")
    >>> dofs, vals = resolve_dirichlet(cloud, [bc])
    >>> dofs.tolist(), vals.round(4).tolist()
    ([8, 10], [0.025, 0.025])

    One value per point for a single component:

    >>> bc = Dirichlet("x+", lambda x: 0.01 * x[:, 1], components="y")
    >>> resolve_dirichlet(cloud, [bc])[1].round(4).tolist()
    [0.005, 0.015]
    """

    where: Any
    value: Any = 0.0
    components: Any = None

    def __repr__(self) -> str:
        """Return ``Dirichlet(where=..., value=..., components=...)`` without whole arrays."""
        return compact_repr(
            "Dirichlet",
            {
                "where": _shown(self.where),
                "value": _shown(self.value),
                "components": self.components,
            },
        )

    def __post_init__(self) -> None:
        """Check the point selection, the value and the components eagerly."""
        _check_where(self.where, "where")
        _check_value(self.value, "value")
        if self.components is not None:
            parse_components(self.components, 3)  # letters / distinct ints >= 0 (dim: later)

    @classmethod
    def affine(
        cls,
        where: Any,
        F: Any,
        *,
        translation: Any = None,
        center: Any = None,
        components: Any = None,
    ) -> Dirichlet:
        """Prescribe the affine field ``u = (F - I)(X - center) + translation``.

        Parameters
        ----------
        where : str or index array or mask
            Point set name (e.g. ``'x-'``) or indices.
        F : (dim, dim) array_like
            Deformation gradient.
        translation : (dim,) array_like, optional
            Rigid translation (default 0).
        center : (dim,) array_like, optional
            Fixed point of ``F`` (default the origin).
        components : str or sequence of int, optional
            Constrained components (default all).

        Returns
        -------
        Dirichlet
            With a callable value evaluated on the selected points.

        Raises
        ------
        ShapeError
            When ``F`` is not square or ``center`` / ``translation`` do not match it.
        """
        Fm = as_float_array(F, "F", ndim=2)
        if Fm.shape[0] != Fm.shape[1]:
            raise ShapeError(f"F must be square (dim, dim), got {Fm.shape}")
        d = Fm.shape[0]
        H = Fm - np.eye(d)
        c = np.zeros(d) if center is None else as_float_array(center, "center")
        t = np.zeros(d) if translation is None else as_float_array(translation, "translation")
        if c.shape != (d,) or t.shape != (d,):
            raise ShapeError(f"center and translation must have shape ({d},)")

        def field(x: np.ndarray) -> np.ndarray:
            if x.shape[1] != d:
                raise ShapeError(f"F is {d}x{d} but the cloud is {x.shape[1]}D")
            return (x - c) @ H.T + t

        return cls(where, field, components)

    @classmethod
    def velocity_gradient(
        cls,
        where: Any,
        L: Any,
        *,
        center: Any = None,
        components: Any = None,
    ) -> Dirichlet:
        """Prescribe the path ``u(X, t) = (exp(L t) - I)(X - center)`` of a velocity gradient.

        The homogeneous deformation ``F(t) = exp(L t)`` (``Ḟ F⁻¹ = L``) of the boundary
        condition of Luo, Ramazani & Sundararaghavan (2017), Sect. 4 (their Eq. 25 gives
        pure shear ``L = η [[0, 1], [1, 0]]`` and compression ``L = η [[1, 0], [0, -1]]``);
        with ``center`` at the domain corner (pdlin's choice of origin: another one adds
        a rigid translation).  Evaluated at each load step's time by
        :func:`pdlin.solve_nonlinear` (at ``t = 1`` by :func:`pdlin.solve`).

        Parameters
        ----------
        where : str or index array or mask
            Point set name (e.g. ``'x-'``) or indices.
        L : (dim, dim) array_like
            Constant velocity gradient.
        center : (dim,) array_like, optional
            Fixed point of the motion (default the origin).
        components : str or sequence of int, optional
            Constrained components (default all).

        Returns
        -------
        Dirichlet
            With a :class:`TimePath` value (its ``L`` and ``center`` set for the drivers'
            affine predictor).

        Raises
        ------
        ShapeError
            When ``L`` is not square or ``center`` does not match it.

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> from pdlin.constraints import resolve_dirichlet
        >>> cloud = pdlin.grid((2, 2))
        >>> bc = pdlin.Dirichlet.velocity_gradient("x+", [[0.0, 0.002], [0.002, 0.0]])
        >>> vals = resolve_dirichlet(cloud, [bc], t=30.0)[1].reshape(-1, 2)
        >>> bool(np.allclose(vals[0], [np.sinh(0.06) * 0.5 + (np.cosh(0.06) - 1) * 1.5,
        ...                            (np.cosh(0.06) - 1) * 0.5 + np.sinh(0.06) * 1.5]))
        True
        """
        Lm = as_float_array(L, "L", ndim=2)
        if Lm.shape[0] != Lm.shape[1]:
            raise ShapeError(f"L must be square (dim, dim), got {Lm.shape}")
        d = Lm.shape[0]
        c = np.zeros(d) if center is None else as_float_array(center, "center")
        if c.shape != (d,):
            raise ShapeError(f"center must have shape ({d},), got {c.shape}")

        def path(x: np.ndarray, t: float) -> np.ndarray:
            if x.shape[1] != d:
                raise ShapeError(f"L is {d}x{d} but the cloud is {x.shape[1]}D")
            H = scipy.linalg.expm(Lm * float(t)) - np.eye(d)
            return (x - c) @ H.T

        return cls(where, TimePath(path, f"exp(L t), L = {Lm.tolist()}", Lm, c), components)


@dataclass(frozen=True)
class BodyForce:
    """Body force density (force per unit volume) on a point set.

    The nodal load is ``b(x_i) * V_i`` (times the thickness in 2D / the
    cross-section in 1D).

    Parameters
    ----------
    where : str or index array or mask or None
        Point set name (e.g. ``'x-'``), indices, a mask, or None for all points.
    density : float, array_like or callable
        Force per unit volume: a scalar, ``(dim,)``, ``(m, dim)``, or a callable of the
        ``(m, dim)`` reference points returning one of these.
    """

    where: Any
    density: Any

    def __repr__(self) -> str:
        """Return ``BodyForce(where=..., density=...)`` without whole arrays."""
        return compact_repr(
            "BodyForce", {"where": _shown(self.where), "density": _shown(self.density)}
        )

    def __post_init__(self) -> None:
        """Check the point selection and the density eagerly."""
        _check_where(self.where, "where")
        _check_value(self.density, "density")


@dataclass(frozen=True)
class TotalForce:
    """A total force spread over a point set in proportion to point volume.

    Parameters
    ----------
    where : str or index array or mask or None
        Point set name (e.g. ``'x+'``), indices, a mask, or None for all points.
    force : (dim,) array_like
        The total force.
    weights : (m,) array_like, optional
        Non-negative shares of the selected points (default their volumes).
    """

    where: Any
    force: Any
    weights: Any = field(default=None)

    def __repr__(self) -> str:
        """Return ``TotalForce(where=..., force=..., weights=...)`` without whole arrays."""
        return compact_repr(
            "TotalForce",
            {"where": _shown(self.where), "force": self.force, "weights": self.weights},
        )

    def __post_init__(self) -> None:
        """Check the point selection, the force and the weights eagerly."""
        _check_where(self.where, "where")
        _check_value(self.force, "force")
        if self.weights is not None:
            as_float_array(self.weights, "weights")


def shadow_layer(
    cloud: PointCloud,
    F: Any,
    depth: float,
    *,
    faces: Sequence[str] | None = None,
    translation: Any = None,
) -> tuple[Dirichlet, np.ndarray]:
    """Inward fictitious boundary layer ("shadow particles") of given depth.

    Points within ``depth`` (normally the horizon) of the bounding-box
    faces carry the prescribed affine field ``u = (F - I) X + translation``;
    only the remaining (real) points are solved for, and their horizons
    are always complete on a box.

    Parameters
    ----------
    cloud : PointCloud
    F : (dim, dim) array_like
        Imposed deformation gradient.
    depth : float
        Layer thickness measured from the outermost points' cell faces.
    faces : sequence of str, optional
        Box faces carrying the layer, e.g. ``['x-', 'x+']`` (default all).

    Returns
    -------
    (Dirichlet, shadow_indices)

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((10, 10), spacing=0.1)
    >>> bc, shadow = shadow_layer(cloud, np.eye(2) * 1.001, depth=0.2)
    >>> shadow.size   # 10x10 minus the 6x6 real core
    64
    """
    d = cloud.dim
    dep = float(depth)
    if not np.isfinite(dep) or dep <= 0:
        raise InputError(f"depth must be > 0, got {depth}")
    lo, hi = cloud.bounds
    half = (
        0.5 * np.asarray(cloud.lattice.spacing)
        if cloud.lattice is not None
        else 0.5 * float(np.median(cloud.spacing)) * np.ones(d)
    )
    lo = lo - half
    hi = hi + half
    names = [f"{a}{s}" for a in "xyz"[:d] for s in "-+"] if faces is None else list(faces)
    mask = np.zeros(cloud.n, dtype=bool)
    for name in names:
        if len(name) != 2 or name[0] not in "xyz"[:d] or name[1] not in "+-":
            raise InputError(f"faces entries must look like 'x-' or 'z+', got {name!r}")
        k = _AX[name[0]]
        if name[1] == "-":
            mask |= cloud.points[:, k] < lo[k] + dep
        else:
            mask |= cloud.points[:, k] > hi[k] - dep
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        raise InputError(f"shadow layer of depth {dep} holds no points")
    return Dirichlet.affine(idx, F, translation=translation), idx
