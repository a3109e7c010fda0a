"""Rigid-body modes of a point cloud."""

from __future__ import annotations

import numpy as np

from ..geometry.cloud import PointCloud

__all__ = ["rigid_body_modes", "rigid_mode_names"]


def rigid_mode_names(dim: int) -> list[str]:
    """Name the rigid-body modes returned by :func:`rigid_body_modes`, in column order.

    Parameters
    ----------
    dim : {1, 2, 3}
        Spatial dimension.

    Returns
    -------
    list of str
        ``dim`` translations, then the rotations (about z in 2D; about x, y, z in 3D).

    Raises
    ------
    KeyError
        When ``dim`` is not 1, 2 or 3.
    """
    return {
        1: ["translation x"],
        2: ["translation x", "translation y", "rotation about z"],
        3: [
            "translation x",
            "translation y",
            "translation z",
            "rotation about x",
            "rotation about y",
            "rotation about z",
        ],
    }[dim]


def rigid_body_modes(cloud: PointCloud | np.ndarray, *, orthonormal: bool = False) -> np.ndarray:
    """Build the infinitesimal rigid-body modes as columns, ``(n*dim, n_modes)``.

    1 mode in 1D, 3 in 2D, 6 in 3D; rotations are taken about the centroid
    so the columns are well conditioned (this is the near-null space
    ``B`` handed to smoothed-aggregation AMG).

    Parameters
    ----------
    cloud : PointCloud or (n, dim) array
        The points (their positions only).
    orthonormal : bool
        Orthonormalize the columns (QR).

    Returns
    -------
    (n*dim, n_modes) ndarray
        Point-major DOF order (``dim * i + k``); columns in the order of
        ``rigid_mode_names``, rotations about the centroid (not normalized unless
        ``orthonormal``).

    Examples
    --------
    >>> import pdlin
    >>> B = pdlin.operators.rigid_body_modes(pdlin.grid((3, 3)))
    >>> B.shape
    (18, 3)
    """
    pts = cloud.points if isinstance(cloud, PointCloud) else np.asarray(cloud, dtype=float)
    n, d = pts.shape
    x = pts - pts.mean(axis=0)
    nm = {1: 1, 2: 3, 3: 6}[d]
    B = np.zeros((n, d, nm))
    for k in range(d):
        B[:, k, k] = 1.0
    if d == 2:
        B[:, 0, 2] = -x[:, 1]
        B[:, 1, 2] = x[:, 0]
    elif d == 3:
        # rotation about x: (0, -z, y); about y: (z, 0, -x); about z: (-y, x, 0)
        B[:, 1, 3] = -x[:, 2]
        B[:, 2, 3] = x[:, 1]
        B[:, 0, 4] = x[:, 2]
        B[:, 2, 4] = -x[:, 0]
        B[:, 0, 5] = -x[:, 1]
        B[:, 1, 5] = x[:, 0]
    modes = B.reshape(n * d, nm)
    if orthonormal:
        modes, _ = np.linalg.qr(modes)
    return modes
