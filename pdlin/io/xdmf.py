"""XDMF files (meshio's layout) whose HDF5 data is built in memory, then written.

HDF5 writes that fail (full disk, file-size limit) can crash the process in
h5py's clean-up (signal 11) instead of raising.  Here the HDF5 file is built in
a ``BytesIO`` and written with Python's file I/O, so such a failure is an
ordinary ``OSError`` (:func:`pdlin.io.output.staging` turns it into a
:class:`~pdlin.errors.WriteError`).  The price: the HDF5 file is held in memory
once while it is written.
"""

from __future__ import annotations

import io
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .output import need_module

__all__ = ["write_xdmf"]


def _writers() -> tuple[type, type]:
    """Build subclasses of meshio's XDMF writers whose HDF5 file is a ``BytesIO``."""
    import meshio
    from meshio._common import write_xml
    from meshio.xdmf.main import XdmfWriter

    h5py = need_module("h5py", "io", "XDMF output")

    class _Single(XdmfWriter):
        def __init__(self, filename: Path, h5_name: str, mesh: meshio.Mesh, buf: io.BytesIO):
            # meshio's XdmfWriter.__init__ with the HDF5 file in ``buf``
            self.filename = Path(filename)
            self.data_format = "HDF"
            self.data_counter = 0
            self.compression = "gzip"
            self.compression_opts = 4
            self.h5_filename = h5_name
            with h5py.File(buf, "w") as self.h5_file:
                root = ET.Element("Xdmf", Version="3.0")
                grid = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="Grid")
                self.write_points(grid, mesh.points)
                self.write_cells(mesh.cells, grid)
                self.write_point_data(mesh.point_data, grid)
                self.write_cell_data(mesh.cell_data, grid)
            ET.register_namespace("xi", "https://www.w3.org/2001/XInclude/")
            write_xml(filename, root)

    class _Series(meshio.xdmf.TimeSeriesWriter):
        def __init__(self, filename: Path, h5_name: str, buf: io.BytesIO):
            super().__init__(filename)
            self.h5_filename = h5_name
            self._buf = buf

        def __enter__(self) -> _Series:
            self.h5_file = h5py.File(self._buf, "w")
            return self

        def __exit__(self, *exc: object) -> None:
            self.h5_file.close()
            if exc[0] is None:
                write_xml(self.filename, self.xdmf_file)

    return _Single, _Series


def write_xdmf(
    out: Path,
    h5_name: str,
    points: np.ndarray,
    cells: list[tuple[str, np.ndarray]],
    steps: Sequence[tuple[float, Mapping[str, np.ndarray]]] | Mapping[str, np.ndarray],
) -> None:
    """Write ``out`` (XDMF) and ``out.parent / h5_name`` (its HDF5 data).

    Parameters
    ----------
    out : Path
        The ``.xdmf`` file to write.
    h5_name : str
        File name of the HDF5 data, written next to ``out`` and referenced by it.
    points : (n, 3) ndarray
        Point coordinates (padded to 3D).
    cells : list of (str, ndarray)
        meshio cell blocks, e.g. ``[("vertex", (n, 1) indices)]``.
    steps : mapping or sequence of (float, mapping)
        One mapping of point data, field name -> ``(n,)`` / ``(n, k)`` array (a single
        mesh, as ``meshio.write`` does), or ``(time, point data)`` pairs (a temporal
        collection, as ``meshio.xdmf.TimeSeriesWriter`` does).

    Raises
    ------
    MissingDependencyError
        When meshio or h5py is not installed.
    OSError
        When a file cannot be written (an ordinary error, not a crash in h5py).
    """
    import meshio

    single, series = _writers()
    buf = io.BytesIO()
    if isinstance(steps, Mapping):
        single(out, h5_name, meshio.Mesh(points, cells, point_data=dict(steps)), buf)
    else:
        with series(out, h5_name, buf) as writer:
            writer.write_points_cells(points, cells)
            for t, pdat in steps:
                writer.write_data(float(t), point_data=dict(pdat))
    with open(out.parent / h5_name, "wb") as fh:
        fh.write(buf.getbuffer())
