"""Reading back the result files pdlin writes (VTU, PVD, XDMF, NPZ, Exodus II).

:func:`read_result` returns the points and, per step, the fields under their
API keys (``displacement``, ``reaction``, ``stress``, ...) with the 3D padding
of the ParaView formats removed, whichever spelling the file uses (the
ParaView names of ``pdlin.io.names`` or the lowercase names of files
written by earlier pdlin versions).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._repr import Raw, compact_repr, html_table, time_span
from ..errors import InputError
from .exodus import EXODUS_SUFFIXES, read_exodus_file
from .names import from_file_value

__all__ = ["ResultFile", "read_result", "READ_SUFFIXES"]

READ_SUFFIXES = (".vtu", ".vtk", ".pvd", ".xdmf", ".npz", *EXODUS_SUFFIXES)


@dataclass(frozen=True)
class ResultFile:
    """Points and per-step point fields read from a result file.

    Attributes
    ----------
    path : Path
        The file read.
    points : (n, dim) ndarray
        Point coordinates (without the zero padding of the 3D file formats).
    times : (k,) ndarray
        Step times (``[0.0]`` for a single result).
    steps : list of k dicts
        API key -> (n,) / (n, c) array of each step.
    sets : dict
        Named point sets (Exodus node sets; empty for the other formats).
    extra : dict
        Arrays of an NPZ file that are not point fields (``residual_history``).
    """

    path: Path
    points: np.ndarray
    times: np.ndarray
    steps: list[dict[str, np.ndarray]]
    sets: dict[str, np.ndarray] = field(default_factory=dict)
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def dim(self) -> int:
        """Spatial dimension of the points (1, 2 or 3)."""
        return int(self.points.shape[1])

    @property
    def n_steps(self) -> int:
        """Number of stored steps."""
        return len(self.steps)

    def _table(self) -> list[tuple[str, Any]]:
        k = self.n_steps
        last = self.steps[-1] if k else {}
        shapes = {key: "" if np.ndim(v) < 2 else f"[{np.shape(v)[1]}]" for key, v in last.items()}
        return [
            ("file", self.path.name),
            ("points", int(self.points.shape[0])),
            ("dim", self.dim),
            ("steps", k),
            ("times", time_span(self.times)),
            ("fields", ", ".join(f"{key}{s}" for key, s in shapes.items()) or None),
            ("sets", ", ".join(sorted(self.sets)) or None),
        ]

    def __repr__(self) -> str:
        """File, sizes, steps and field names (no arrays, no memory address)."""
        items = dict(self._table())
        items["fields"] = Raw("[" + ", ".join(self.steps[-1] if self.steps else ()) + "]")
        items["sets"] = len(self.sets) or None
        return compact_repr("ResultFile", items)

    def _repr_html_(self) -> str:
        """Render the summary as an HTML table (Jupyter)."""
        return html_table("ResultFile", self._table())

    def step_index(self, step: int) -> int:
        """Validate a step number and return it as a 0-based index.

        Parameters
        ----------
        step : int
            Step number; negative counts from the end (``-1`` is the last).

        Returns
        -------
        int
            The index in ``0 .. n_steps - 1``.

        Raises
        ------
        InputError
            When ``step`` is not an integer in ``[-n_steps, n_steps - 1]``.
        """
        k = self.n_steps
        if isinstance(step, bool) or not isinstance(step, int | np.integer) or not -k <= step < k:
            raise InputError(
                f"step (--step) must be an integer in [{-k}, {k - 1}] ({k} step(s) in "
                f"{self.path.name}), got {step!r}"
            )
        return int(step) % k

    def fields(self, step: int = -1) -> dict[str, np.ndarray]:
        """Return the fields of one step.

        Parameters
        ----------
        step : int
            Step number (default: the last); negative counts from the end.

        Returns
        -------
        dict
            API key -> ``(n,)`` / ``(n, c)`` array (the stored dict, not a copy).

        Raises
        ------
        InputError
            When ``step`` is out of range.
        """
        return self.steps[self.step_index(step)]


def _dim_of(points3: np.ndarray) -> int:
    """Dimension of a cloud whose coordinates were padded with zeros to 3."""
    if points3.shape[1] < 3:
        return int(points3.shape[1])
    if np.any(points3[:, 2] != 0):
        return 3
    return 2 if np.any(points3[:, 1] != 0) else 1


def _unpad(point_data: dict[str, Any], dim: int) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for name, arr in point_data.items():
        key, val = from_file_value(name, np.asarray(arr), dim)
        out[key] = val
    return out


def _read_meshio(path: Path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    import meshio

    # the format's own reader: meshio.read calls sys.exit on a file it cannot read
    reader = {".vtu": meshio.vtu.read, ".vtk": meshio.vtk.read, ".xdmf": meshio.xdmf.read}
    mesh = reader[path.suffix.lower()](str(path))
    pts = np.asarray(mesh.points, dtype=float)
    dim = _dim_of(pts)
    return pts[:, :dim], _unpad(dict(mesh.point_data), dim)


def read_result(path: str | Path) -> ResultFile:
    """Read a result file written by pdlin (static or time series).

    Parameters
    ----------
    path : str or Path
        ``.vtu``/``.vtk``, ``.pvd`` (with its VTU files), ``.xdmf`` (with its
        ``.h5``; needs h5py), ``.npz`` or ``.e``/``.exo`` (needs netCDF4).

    Returns
    -------
    ResultFile
        Points, times, the fields of every step under their API keys, point sets.

    Raises
    ------
    InputError
        When the suffix is not readable, the file does not exist or cannot be read as a
        pdlin result.

    Examples
    --------
    >>> import numpy as np, pdlin, tempfile, os
    >>> from pdlin.io import write_series
    >>> cloud = pdlin.grid((3, 2))
    >>> p = write_series(os.path.join(tempfile.mkdtemp(), "run.pvd"), cloud, [0.5, 1.0],
    ...                  [{"displacement": k * np.ones((6, 2))} for k in (1, 2)])
    >>> r = read_result(p)
    >>> r.n_steps, r.times.tolist(), r.fields(-1)["displacement"].shape
    (2, [0.5, 1.0], (6, 2))
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in READ_SUFFIXES:
        raise InputError(f"result file must end with one of {READ_SUFFIXES}, got {str(p)!r}")
    if not p.is_file():
        raise InputError(f"result file {str(p)!r} does not exist")
    import meshio

    try:
        return _read(p, suffix)
    except (OSError, KeyError, ValueError, IndexError, ET.ParseError, meshio.ReadError) as exc:
        raise InputError(
            f"cannot read {str(p)!r} as a pdlin result ({suffix}): {type(exc).__name__}: {exc}"
        ) from exc


def _read(p: Path, suffix: str) -> ResultFile:
    if suffix in EXODUS_SUFFIXES:
        d = read_exodus_file(p)
        steps = [_unpad(s, d["dim"]) for s in d["steps"]]
        return ResultFile(p, d["points"], d["times"], steps, d["sets"])
    if suffix == ".npz":
        with np.load(p) as data:
            arrays = {k: np.asarray(data[k]) for k in data.files}
        pts = arrays.pop("points")
        vols = arrays.pop("volumes", None)
        n = pts.shape[0]
        series = "times" in arrays
        if series:
            times = arrays.pop("times").astype(float)
            lead: tuple[int, ...] = (times.size, n)
        else:
            times = np.zeros(1)
            lead = (n,)
        extra = {k: v for k, v in arrays.items() if v.shape[: len(lead)] != lead}
        per_point = {k: v for k, v in arrays.items() if k not in extra}
        if series:
            steps = [{k: v[j] for k, v in per_point.items()} for j in range(times.size)]
        else:
            steps = [per_point]
        if vols is not None:
            for s in steps:
                s.setdefault("volume", vols)
        return ResultFile(p, pts, times, steps, extra=extra)
    if suffix == ".pvd":
        try:
            root = ET.parse(p).getroot()
        except ET.ParseError as exc:
            raise InputError(f"{str(p)!r} is not a ParaView .pvd collection: {exc}") from exc
        entries = [
            (float(e.get("timestep", "0")), p.parent / str(e.get("file")))
            for e in root.iter("DataSet")
        ]
        if not entries:
            raise InputError(f"{str(p)!r} lists no DataSet files")
        steps = []
        pts = np.zeros((0, 1))
        for _, f in entries:
            pts, pd = _read_meshio(f)
            steps.append(pd)
        return ResultFile(p, pts, np.array([t for t, _ in entries]), steps)
    if suffix == ".xdmf" and "Temporal" in p.read_text(errors="replace"):
        import meshio

        with meshio.xdmf.TimeSeriesReader(str(p)) as reader:
            pts3, _ = reader.read_points_cells()
            raw = [reader.read_data(k) for k in range(reader.num_steps)]
        pts3 = np.asarray(pts3, dtype=float)
        dim = _dim_of(pts3)
        times = np.array([float(t) for t, _, _ in raw])
        steps = [_unpad(dict(pd), dim) for _, pd, _ in raw]
        return ResultFile(p, pts3[:, :dim], times, steps)
    pts, pd = _read_meshio(p)
    return ResultFile(p, pts, np.zeros(1), [pd])
