"""Writing point fields to files (meshio VTU/XDMF, or numpy .npz)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, ShapeError
from ..geometry.cloud import PointCloud

__all__ = ["write_points", "write_result", "SUPPORTED_SUFFIXES"]

SUPPORTED_SUFFIXES = (".vtu", ".xdmf", ".vtk", ".npz")


def _pad3(a: np.ndarray) -> np.ndarray:
    if a.ndim == 2 and a.shape[1] < 3:
        out = np.zeros((a.shape[0], 3))
        out[:, : a.shape[1]] = a
        return out
    return a


def write_points(path: str | Path, cloud: PointCloud, fields: Mapping[str, Any]) -> Path:
    """Write a point cloud with point fields.

    ``.vtu``/``.xdmf``/``.vtk`` go through meshio with the points as
    ``vertex`` cells (coordinates and vector fields padded to 3 components
    for 1D/2D so ParaView can warp by displacement); ``.npz`` stores the raw
    arrays (``points``, ``volumes`` and every field).

    Parameters
    ----------
    path : str or Path
    cloud : PointCloud
    fields : mapping of name to (n,) or (n, k) arrays

    Returns
    -------
    Path of the written file.

    Examples
    --------
    >>> import numpy as np, pdlin, tempfile, os, meshio
    >>> cloud = pdlin.grid((3, 2))
    >>> path = os.path.join(tempfile.mkdtemp(), "out.vtu")
    >>> _ = write_points(path, cloud, {"u": np.ones((6, 2))})
    >>> meshio.read(path).point_data["u"].shape
    (6, 3)
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise InputError(f"output path must end with one of {SUPPORTED_SUFFIXES}, got {str(p)!r}")
    data: dict[str, np.ndarray] = {}
    for name, val in fields.items():
        arr = np.asarray(val, dtype=float)
        if arr.shape[0] != cloud.n:
            raise ShapeError(f"field {name!r} must have {cloud.n} rows, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"field {name!r} holds NaN or inf; refusing to write it")
        data[name] = arr
    p.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".npz":
        arrays = {"points": np.asarray(cloud.points), "volumes": np.asarray(cloud.volumes), **data}
        np.savez_compressed(p, **arrays)  # type: ignore[arg-type]
        return p
    import meshio

    pts = _pad3(np.asarray(cloud.points))
    pd: dict[str, np.ndarray] = {"volume": np.asarray(cloud.volumes)}
    for name, arr in data.items():
        if arr.ndim == 2 and arr.shape[1] == cloud.dim and cloud.dim < 3:
            arr = _pad3(arr)
        pd[name] = arr
    cells = [("vertex", np.arange(cloud.n).reshape(-1, 1))]
    mesh = meshio.Mesh(pts, cells, point_data=pd)
    mesh.write(p)
    return p


def write_result(path: str | Path, result: Any) -> Path:
    """Write every field of a :class:`pdlin.StaticResult` (see :func:`write_points`)."""
    return write_points(path, result.problem.cloud, result.fields())
