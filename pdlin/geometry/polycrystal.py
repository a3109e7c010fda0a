"""Seeded Voronoi polycrystals: grain ids and crystal orientations per point.

As in Luo, Ramazani & Sundararaghavan (2017), §4: Voronoi grains (21 in the paper,
seeds not given) with orientations from a 12-value set.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validation import as_float_array
from ..errors import InputError, ShapeError

__all__ = ["voronoi_polycrystal"]


def voronoi_polycrystal(
    cloud: Any,
    n_grains: int,
    seed: int | np.random.Generator | None = 0,
    orientations: ArrayLike | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Build a Voronoi grain map of a point cloud and one crystal orientation per point.

    Grain seeds are ``n_grains`` distinct points of the cloud drawn at random (so every
    grain holds at least its seed); each point joins the grain of its nearest seed
    (``scipy.spatial.cKDTree``).

    Parameters
    ----------
    cloud : PointCloud or (n, d) array_like of float
        Points, ``d`` = 2 or 3.
    n_grains : int
        Number of grains, ``1 <= n_grains <= n``.
    seed : int or numpy Generator, optional
        Random seed (reproducible maps).
    orientations : array_like, optional
        2D: the set of angles (radians) grains draw from; default the 12-value set
        θ_k = −π/2 + kπ/12 of Luo, Ramazani & Sundararaghavan (2017), §4.  When
        ``n_grains`` is at least the set size, every orientation is used at least once
        (pdlin's choice; the paper shows its assignment only in figures), the rest drawn
        uniformly.  3D: default uniformly random rotations
        (``scipy.spatial.transform.Rotation.random``); or a set ``(k, 3, 3)`` of rotation
        matrices drawn from in the same way.

    Returns
    -------
    grain : (n,) ndarray of int
        Grain id of each point, ``0 .. n_grains - 1``.
    orientation : (n,) ndarray (2D angles) or (n, 3, 3) ndarray (3D, crystal → sample)
        Orientation of each point's grain, ready for ``CrystalPlasticity(orientation=...)``.

    Raises
    ------
    InputError
        If ``n_grains`` is not an integer in ``[1, n]`` or ``seed`` is of the wrong type.
    ShapeError
        If the points are not 2D or 3D, or ``orientations`` has the wrong shape or is empty.

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((15, 15), spacing=1 / 15)
    >>> grain, theta = pdlin.voronoi_polycrystal(cloud, 21, seed=1)
    >>> len(np.unique(grain)), len(np.unique(theta))      # 21 grains, all 12 angles used
    (21, 12)
    """
    from scipy.spatial import cKDTree

    pts = getattr(cloud, "points", cloud)
    x = as_float_array(pts, "cloud", ndim=2)
    n, d = x.shape
    if d not in (2, 3):
        raise ShapeError(f"cloud must hold 2D or 3D points (n, 2) / (n, 3), got shape {x.shape}")
    try:
        k = int(n_grains)
    except (TypeError, ValueError) as exc:
        raise InputError(f"n_grains must be an integer, got {n_grains!r}") from exc
    if k != n_grains or not 1 <= k <= n:
        raise InputError(
            f"n_grains must be an integer in [1, {n}] (the point count), got {n_grains}"
        )
    if isinstance(seed, np.random.Generator):
        rng = seed
    else:
        try:
            rng = np.random.default_rng(seed)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"seed must be an int, None or a numpy Generator, got {seed!r}"
            ) from exc
    seeds = rng.choice(n, size=k, replace=False)
    _, grain = cKDTree(x[seeds]).query(x)
    grain = np.asarray(grain, dtype=np.int64)

    def draw(m_set: int) -> NDArray[np.int64]:
        if k >= m_set:
            picks = np.concatenate([np.arange(m_set), rng.integers(0, m_set, k - m_set)])
            return np.asarray(rng.permutation(picks), dtype=np.int64)
        return np.asarray(rng.integers(0, m_set, k), dtype=np.int64)

    if d == 2:
        if orientations is None:
            from ..constitutive.crystal_plasticity import ORIENTATIONS_2D

            oset = np.asarray(ORIENTATIONS_2D)
        else:
            oset = as_float_array(orientations, "orientations", ndim=1)
            if oset.size == 0:
                raise ShapeError("orientations must hold at least one angle, got shape (0,)")
        return grain, np.asarray(oset[draw(oset.size)][grain], dtype=np.float64)
    if orientations is None:
        from scipy.spatial.transform import Rotation

        R = Rotation.random(k, random_state=rng).as_matrix()
        return grain, np.asarray(R[grain], dtype=np.float64)
    oset = as_float_array(orientations, "orientations", ndim=3)
    if oset.shape[1:] != (3, 3) or oset.shape[0] == 0:
        raise ShapeError(
            f"orientations must be rotation matrices of shape (k, 3, 3), got {oset.shape}"
        )
    return grain, np.asarray(oset[draw(oset.shape[0])][grain], dtype=np.float64)
