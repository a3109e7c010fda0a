"""Point clouds from finite-element meshes (any format meshio reads).

One material point is placed at the centroid of every cell of the mesh's
highest topological dimension (or of ``dim``), with the cell's exact length,
area or volume.  Cell sets and gmsh physical groups become named point sets;
groups defined on lower-dimensional cells (boundary lines of a 2D mesh,
boundary faces of a 3D mesh, tagged nodes) are mapped onto the adjacent
cells, see :func:`read_mesh`.  A mesh of ``vertex`` cells only is a point cloud:
its vertices become the points, with volumes from a ``Volume`` point field or the
``volume`` option.
"""

from __future__ import annotations

import logging
import os
import pathlib
from collections.abc import Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import InputError, InputTypeError, ShapeError
from .cloud import PointCloud

__all__ = ["read_mesh", "cell_measures", "SUPPORTED_CELL_TYPES"]

log = logging.getLogger(__name__)

# linear cell type and number of corner nodes of every supported cell type
# (quadratic cells keep their corner nodes, which meshio stores first)
_LINEAR: dict[str, tuple[str, int]] = {
    "line": ("line", 2),
    "line3": ("line", 2),
    "triangle": ("triangle", 3),
    "triangle6": ("triangle", 3),
    "triangle7": ("triangle", 3),
    "quad": ("quad", 4),
    "quad8": ("quad", 4),
    "quad9": ("quad", 4),
    "polygon": ("polygon", -1),
    "tetra": ("tetra", 4),
    "tetra10": ("tetra", 4),
    "hexahedron": ("hexahedron", 8),
    "hexahedron20": ("hexahedron", 8),
    "hexahedron27": ("hexahedron", 8),
    "wedge": ("wedge", 6),
    "wedge15": ("wedge", 6),
    "wedge18": ("wedge", 6),
    "pyramid": ("pyramid", 5),
    "pyramid13": ("pyramid", 5),
    "pyramid14": ("pyramid", 5),
}

#: Cell types that can become material points (meshio names).
SUPPORTED_CELL_TYPES: tuple[str, ...] = tuple(_LINEAR)

_TOPO_DIM = {
    "vertex": 0,
    "line": 1,
    "triangle": 2,
    "quad": 2,
    "polygon": 2,
    "tetra": 3,
    "hexahedron": 3,
    "wedge": 3,
    "pyramid": 3,
}

# Outward faces (right-hand rule) of the meshio node orderings: VTK's, except
# for the linear wedge, where meshio adopts gmsh's prism (the normal of the
# triangle (0, 1, 2) points towards the triangle (3, 4, 5)).
_FACES: dict[str, tuple[list[list[int]], list[list[int]]]] = {
    # (triangular faces, quadrilateral faces)
    "hexahedron": (
        [],
        [[0, 4, 7, 3], [1, 2, 6, 5], [0, 1, 5, 4], [3, 7, 6, 2], [0, 3, 2, 1], [4, 5, 6, 7]],
    ),
    "wedge": ([[0, 2, 1], [3, 4, 5]], [[0, 1, 4, 3], [1, 2, 5, 4], [2, 0, 3, 5]]),
    "pyramid": ([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]], [[0, 3, 2, 1]]),
}

_MEASURE_NAME = {1: "length", 2: "area", 3: "volume"}
_DEGENERATE_RTOL = 1e-12
_GAUSS2 = np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)])


def _topological_dimension(cell_type: str) -> int | None:
    """Topological dimension of a meshio cell type (None when unknown)."""
    linear = _LINEAR.get(cell_type, (cell_type, 0))[0]
    if linear in _TOPO_DIM:
        return _TOPO_DIM[linear]
    try:
        from meshio._mesh import topological_dimension
    except ImportError:  # pragma: no cover - other meshio versions
        return None
    value = topological_dimension.get(cell_type)
    return None if value is None else int(value)


def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _polygon(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed area (shoelace) and area centroid of planar polygons ``(m, k, 2)``."""
    nxt = np.roll(x, -1, axis=1)
    cr = _cross2(x, nxt)  # (m, k)
    area = 0.5 * cr.sum(axis=1)
    safe = np.where(area == 0.0, 1.0, area)
    cen = np.einsum("mk,mkd->md", cr, x + nxt) / (6.0 * safe)[:, None]
    return area, cen


def _faces_measure(x: np.ndarray, cell_type: str) -> tuple[np.ndarray, np.ndarray]:
    """Signed volume and exact centroid of hexahedra, wedges and pyramids.

    The cell is the region bounded by its flat triangular faces and the
    bilinear (doubly ruled) interpolants of its quadrilateral faces, i.e. the
    image of the isoparametric map.  The volume is the sum of the tetrahedra
    (cell node mean, face node mean, edge): 24 tetrahedra for a hexahedron,
    14 for a wedge, 8 for a pyramid; it is exact for that region (also with
    warped faces).  The first moment uses the divergence theorem,
    ``int x_k dV = 1/2 oint x_k^2 n_k dA``, integrated exactly (2x2 Gauss
    points on the bilinear faces, edge midpoints on triangles).
    """
    tris, quads = _FACES[cell_type]
    c = x.mean(axis=1)
    vol = np.zeros(x.shape[0])
    mom = np.zeros((x.shape[0], 3))
    for f in tris:
        a, b, d = (x[:, k] for k in f)
        vol += np.einsum("md,md->m", np.cross(a - c, b - c), d - c) / 6.0
        nA = 0.5 * np.cross(b - a, d - a)
        sq = ((a + b) / 2) ** 2 + ((b + d) / 2) ** 2 + ((d + a) / 2) ** 2
        mom += 0.5 * nA * sq / 3.0
    for f in quads:
        p = x[:, f]  # (m, 4, 3)
        m = p.mean(axis=1)
        for k in range(4):
            a, b = p[:, k], p[:, (k + 1) % 4]
            vol += np.einsum("md,md->m", np.cross(a - c, b - c), m - c) / 6.0
        for s in _GAUSS2:
            for t in _GAUSS2:
                xs = (1 - t) * (p[:, 1] - p[:, 0]) + t * (p[:, 2] - p[:, 3])
                xt = (1 - s) * (p[:, 3] - p[:, 0]) + s * (p[:, 2] - p[:, 1])
                xq = (
                    (1 - s) * (1 - t) * p[:, 0]
                    + s * (1 - t) * p[:, 1]
                    + s * t * p[:, 2]
                    + (1 - s) * t * p[:, 3]
                )
                mom += 0.5 * 0.25 * xq**2 * np.cross(xs, xt)
    safe = np.where(vol == 0.0, 1.0, vol)
    return vol, mom / safe[:, None]


def cell_measures(points: Any, cells: Any, cell_type: str) -> tuple[np.ndarray, np.ndarray]:
    """Compute the signed measure and centroid of every cell of one type.

    Parameters
    ----------
    points : (N, dim) array_like of float
        Node coordinates; ``dim`` must equal the cell's topological dimension
        (1 for lines, 2 for triangles/quads/polygons, 3 for solids).
    cells : (m, k) array_like of int
        Node indices per cell in meshio (VTK) order.  Quadratic types use
        their corner nodes only (straight-sided cells).
    cell_type : str
        meshio cell type, one of :data:`SUPPORTED_CELL_TYPES`.

    Returns
    -------
    measure : (m,) ndarray
        Signed length/area/volume: negative for cells whose node order is
        inverted (clockwise polygons, left-handed solids).  Lines are
        unoriented (always positive unless degenerate).
    centroid : (m, dim) ndarray
        True length/area/volume centroid (not the node average).

    Raises
    ------
    InputError
        If ``cell_type`` is not supported or a node index is out of range.
    ShapeError
        If ``points`` or ``cells`` has the wrong shape for the cell type.

    Notes
    -----
    Polygons (triangles, quads, polygons) use the shoelace formula and its
    centroid.  Tetrahedra use the determinant.  Hexahedra, wedges and
    pyramids are the regions bounded by their bilinear faces (the image of
    the isoparametric map): the volume is the sum of the tetrahedra spanned
    by the cell node mean, each face's node mean and each face edge (the
    24-tetrahedron decomposition of a hexahedron), which is exact for warped
    (non-planar) faces; the centroid integrates the first moment exactly over
    the bilinear faces by the divergence theorem.

    Examples
    --------
    >>> import numpy as np
    >>> square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    >>> area, centroid = cell_measures(square, [[0, 1, 2, 3]], "quad")
    >>> area.tolist(), centroid.tolist()
    ([2.0], [[1.0, 0.5]])
    >>> cell_measures(square, [[0, 3, 2, 1]], "quad")[0].tolist()  # clockwise: negative
    [-2.0]
    """
    if cell_type not in _LINEAR:
        raise InputError(
            f"cell_type must be one of {', '.join(SUPPORTED_CELL_TYPES)}, got {cell_type!r}"
        )
    linear, nc = _LINEAR[cell_type]
    tdim = _TOPO_DIM[linear]
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != tdim:
        raise ShapeError(
            f"points must have shape (N, {tdim}) for {cell_type!r} cells, got {pts.shape}"
        )
    con = np.asarray(cells)
    if con.ndim != 2 or not np.issubdtype(con.dtype, np.integer):
        raise ShapeError(
            f"cells must be a 2-D integer array (m, k), got shape {con.shape} dtype {con.dtype}"
        )
    if nc > 0:
        if con.shape[1] < nc:
            raise ShapeError(f"{cell_type!r} cells need at least {nc} nodes, got shape {con.shape}")
        con = con[:, :nc]
    elif con.shape[1] < 3:
        raise ShapeError(f"polygon cells need at least 3 nodes, got shape {con.shape}")
    if con.size and (con.min() < 0 or con.max() >= pts.shape[0]):
        raise InputError(
            f"cells must hold node indices in [0, {pts.shape[0] - 1}], "
            f"got range [{con.min()}, {con.max()}]"
        )
    x = pts[con]  # (m, k, dim)
    if linear == "line":
        d = x[:, 1] - x[:, 0]
        return np.sqrt(np.einsum("md,md->m", d, d)), 0.5 * (x[:, 0] + x[:, 1])
    if linear in ("triangle", "quad", "polygon"):
        return _polygon(x)
    if linear == "tetra":
        e = x[:, 1:] - x[:, :1]
        vol = np.einsum("md,md->m", np.cross(e[:, 0], e[:, 1]), e[:, 2]) / 6.0
        return vol, x.mean(axis=1)
    return _faces_measure(x, linear)


def _quad_is_simple(x: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """Flag the quads that one diagonal splits into two same-signed triangles."""

    def tri(a: int, b: int, c: int) -> np.ndarray:
        return _cross2(x[:, b] - x[:, a], x[:, c] - x[:, a]) * sign

    return ((tri(0, 1, 2) > 0) & (tri(0, 2, 3) > 0)) | ((tri(1, 2, 3) > 0) & (tri(1, 3, 0) > 0))


def _check_cells(
    x: np.ndarray, measure: np.ndarray, linear: str, dim: int, label: str, offset: int
) -> None:
    """Raise on degenerate cells (zero measure, bow-tie quads) naming the cell."""
    size = np.sqrt(np.sum(np.ptp(x, axis=1) ** 2, axis=1))
    bad = np.abs(measure) <= _DEGENERATE_RTOL * size**dim
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"mesh cell {offset + k} ({label}, row {k}) is degenerate: "
            f"{_MEASURE_NAME[dim]} must be nonzero, got {measure[k]:.6g} "
            f"(nodes at {x[k].tolist()})"
        )
    if linear == "quad":
        ok = _quad_is_simple(x[:, :4], np.sign(measure))
        if not ok.all():
            k = int(np.flatnonzero(~ok)[0])
            raise InputError(
                f"mesh cell {offset + k} ({label}, row {k}) is a self-intersecting "
                f"(bow-tie) or degenerate quad: expected a simple polygon, "
                f"got nodes {x[k].tolist()}"
            )


def _field_names(field_data: Mapping[str, Any]) -> dict[tuple[int, int], str]:
    """(tag, dim) -> name from gmsh-style field_data (``name: [tag, dim]``)."""
    names: dict[tuple[int, int], str] = {}
    for name, value in field_data.items():
        arr = np.asarray(value).ravel()
        if arr.size == 2 and np.issubdtype(arr.dtype, np.number):
            names.setdefault((int(arr[0]), int(arr[1])), str(name))
    return names


_TAG_DATA = ("gmsh:physical", "gmsh:geometrical", "cell_tags")
_JOIN_CHARS = ("-", "_", "#", "+", "/")


def _decode_set_data(key: str, data: Any, n_blocks: int) -> dict[str, list[np.ndarray]]:
    """Cell sets from meshio's ``cell_sets_to_data`` encoding (used by VTU/VTK).

    meshio stores the sets ``a, b, c`` as one integer cell-data array named
    ``'a-b-c'`` (another join character when a name holds ``'-'``) whose
    value is the set index of each cell, or -1 for cells in no set.
    """
    if key in _TAG_DATA or len(data) != n_blocks:
        return {}
    arrays = [np.asarray(d) for d in data]
    if not all(a.ndim == 1 and a.dtype.kind in "iu" for a in arrays):
        return {}
    values = np.concatenate(arrays) if arrays else np.zeros(0, np.int64)
    if values.size == 0:
        return {}
    char = next((c for c in _JOIN_CHARS if c in key), None)
    names = key.split(char) if char else [key]
    if any(not n for n in names) or len(set(names)) != len(names):
        return {}
    lo, hi = int(values.min()), int(values.max())
    if lo < -1 or hi > len(names) - 1 or (len(names) == 1 and lo != -1):
        return {}
    return {n: [np.flatnonzero(a == v) for a in arrays] for v, n in enumerate(names)}


def _incidence(rows: list[np.ndarray], n_nodes: int) -> sp.csr_array:
    """0/1 sparse matrix: one row per cell, ones at its (distinct) nodes."""
    counts = np.concatenate([np.full(r.shape[0], r.shape[1]) for r in rows])
    cols = np.concatenate([r.ravel() for r in rows]).astype(np.int64)
    row = np.repeat(np.arange(counts.size), counts)
    m = sp.coo_array((np.ones(cols.size), (row, cols)), shape=(counts.size, n_nodes)).tocsr()
    m.sum_duplicates()
    m.data[:] = 1.0
    return m


def _as_mesh(source: Any, file_format: str | None) -> Any:
    try:
        import meshio
    except ImportError as exc:  # pragma: no cover - meshio is a core dependency
        raise ImportError("read_mesh needs meshio: pip install meshio") from exc
    if isinstance(source, meshio.Mesh):
        return source
    if not isinstance(source, str | os.PathLike):
        raise InputTypeError(
            f"source must be a file path or a meshio.Mesh, got {type(source).__name__}"
        )
    path = os.fspath(source)
    if not os.path.isfile(path):
        raise InputError(f"mesh file {path!r} does not exist (or is not a file)")
    # meshio.read prints the error of every candidate format and calls sys.exit(1)
    # when none fits, so try the candidates here and raise one clear error instead.
    helpers = getattr(meshio, "_helpers", None)
    readers = getattr(helpers, "reader_map", None)
    guess = getattr(helpers, "_filetypes_from_path", None)
    if readers is None or guess is None:  # pragma: no cover - other meshio versions
        try:
            return meshio.read(path, file_format=file_format)
        except (Exception, SystemExit) as exc:
            raise InputError(f"could not read mesh file {path!r}: {exc}") from None
    if file_format is not None:
        formats = [file_format]
    else:
        try:
            formats = list(guess(pathlib.Path(path)))
        except Exception as exc:
            raise InputError(
                f"mesh file {path!r} has an extension meshio does not know ({exc}); "
                "pass file_format"
            ) from None
    failures = []
    for fmt in formats:
        if fmt not in readers:
            raise InputError(f"file_format must be a meshio format name, got {fmt!r}")
        try:
            return readers[fmt](path)
        except Exception as exc:  # meshio raises ReadError, KeyError, ValueError, ...
            detail = f": {exc}" if str(exc) else " (file content does not match)"
            failures.append(f"as {fmt}: {type(exc).__name__}{detail}")
    raise InputError(f"could not read mesh file {path!r}: {'; '.join(failures)}")


def read_mesh(
    source: Any,
    *,
    dim: int | None = None,
    horizon_ratio: float | None = None,
    boundary: str = "facet",
    material: str | None = None,
    thickness: float = 1.0,
    sets_from_data: bool = True,
    file_format: str | None = None,
    volume: float | str | None = None,
) -> PointCloud:
    """Read a mesh as a point cloud with one point per cell (centroid, exact measure).

    A mesh of ``vertex`` cells only (or of points without cells) is a point cloud
    already, as Peridigm's and pdlin's own ``.vtu`` files are: its points are the
    vertices (in cell order; every mesh point when there are no cells) and their
    volumes come from ``volume`` or from a ``Volume`` / ``volume`` point field.

    Parameters
    ----------
    source : str or os.PathLike or meshio.Mesh
        A file meshio can read (``.msh``, ``.vtu``, ``.vtk``, ``.xdmf``,
        ``.inp``, ``.med``, ...) or a mesh object.
    dim : {1, 2, 3}, optional
        Topological dimension of the cells that become points (default: the
        highest one present).  The cloud has this spatial dimension too, so
        coordinates beyond the first ``dim`` must be constant over the cells'
        nodes (z = 0 in a 2D mesh); higher-dimensional cells are ignored.
    horizon_ratio : float, optional
        Store the per-point horizon ``delta_i = m * V_i ** (1 / dim)`` (the
        XOSB convention, ``m = 3.01`` in the paper's examples).
    boundary : {'facet', 'node'}
        How a group of lower-dimensional cells (boundary lines of a 2D mesh,
        faces or edges of a 3D mesh, tagged vertices) becomes a point set of
        the adjacent cells: ``'facet'`` keeps the cells that contain *all*
        nodes of at least one tagged cell (the cell layer along a tagged
        boundary edge/face); ``'node'`` keeps the cells that share *at least
        one* node with a tagged cell (also the cells touching a tagged edge
        at a corner).
    material : str, optional
        Name of an integer cell-data array (e.g. ``'gmsh:physical'``) to use
        as the material id of each point.
    thickness : float
        Out-of-plane thickness stored on 2D clouds.
    sets_from_data : bool
        Also decode integer cell data written by meshio for formats without
        cell sets (VTU, VTK): an array named ``'a-b-c'`` holding the set
        index of each cell (-1 for none) becomes the sets ``a``, ``b``,
        ``c``.  Such sets are disjoint (meshio keeps one set per cell).
    file_format : str, optional
        meshio format name when the file extension is ambiguous.
    volume : float or str, optional
        Point clouds only: the volume of every point, or the name of the point
        field (or ``vertex`` cell field) holding each point's volume.  Default: the
        field ``Volume`` or ``volume``; without one the cloud is refused.  A point
        cloud's ``dim`` defaults to its number of coordinates less the trailing
        constant ones (a 2D cloud stored with z = 0 is 2D); ``dim`` keeps them.

    Returns
    -------
    PointCloud
        Points in mesh order (cell blocks of dimension ``dim`` in order,
        cells in block order) with named ``sets`` from:

        * meshio ``cell_sets`` (same name), also as decoded from cell data
          (``sets_from_data``);
        * gmsh physical groups (``cell_data['gmsh:physical']``), named by
          ``field_data`` (``name: [tag, dim]``) or ``'physical<tag>'``
          (``'physical<tag>_dim<d>'`` for unnamed lower-dimensional groups).

        Sets of the same name are merged.

    Raises
    ------
    InputError
        Missing or unreadable file, no cells of dimension ``dim``,
        unsupported cell type (named), degenerate cell (zero measure or
        bow-tie quad; the message names the cell index), non-planar 2D mesh.

    Notes
    -----
    Measures and centroids are exact for straight-sided cells, see
    ``cell_measures``; quadratic cells use their corner nodes.  Cells
    with inverted node order (clockwise polygons, left-handed solids) use
    the absolute measure and are reported by one logging warning.

    Examples
    --------
    >>> import numpy as np, meshio
    >>> pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [2.0, 0.0]])
    >>> mesh = meshio.Mesh(pts, [("quad", [[0, 1, 2, 3]]), ("triangle", [[1, 4, 2]]),
    ...                          ("line", [[1, 4]])],
    ...                    cell_sets={"bottom": [[], [], [0]]})
    >>> cloud = read_mesh(mesh, horizon_ratio=3.0)
    >>> cloud.points.round(4).tolist()
    [[0.5, 0.5], [1.3333, 0.3333]]
    >>> cloud.volumes.tolist(), cloud.sets["bottom"].tolist()
    ([1.0, 0.5], [1])
    """
    mesh = _as_mesh(source, file_format)
    if boundary not in ("facet", "node"):
        raise InputError(f"boundary must be 'facet' or 'node', got {boundary!r}")
    ratio = None
    if horizon_ratio is not None:
        ratio = float(horizon_ratio)
        if not np.isfinite(ratio) or ratio <= 0:
            raise InputError(f"horizon_ratio must be > 0, got {horizon_ratio!r}")
    blocks = list(mesh.cells)
    tdims = [_topological_dimension(b.type) for b in blocks]
    present = sorted({d for d in tdims if d is not None and d > 0})
    if all(d == 0 for d in tdims):  # vertices only (or no cells): a point cloud
        return _point_cloud(
            mesh, blocks, tdims, dim, volume, ratio, material, thickness, sets_from_data
        )
    if volume is not None:
        kinds = sorted({b.type for b, d in zip(blocks, tdims, strict=True) if d != 0})
        raise InputError(
            "volume is for point clouds (meshes of vertex cells only), got a mesh of "
            f"{', '.join(map(str, kinds))} cells (their measures are the volumes)"
        )
    if dim is None:
        unknown = [b.type for b, d in zip(blocks, tdims, strict=True) if d is None]
        if unknown:
            raise InputError(
                f"unsupported cell type {unknown[0]!r} in the mesh; supported: "
                f"{', '.join(SUPPORTED_CELL_TYPES)}"
            )
        if not present:
            raise InputError("mesh must hold cells of dimension >= 1, got only vertices")
        dim = present[-1]
    elif dim not in (1, 2, 3):
        raise InputError(f"dim must be 1, 2 or 3, got {dim!r}")
    top = [k for k, d in enumerate(tdims) if d == dim]
    if not top:
        raise InputError(
            f"mesh has no cells of dimension dim={dim}; cell dimensions present: {present}"
        )
    for k in top:
        if blocks[k].type not in _LINEAR:
            raise InputError(
                f"unsupported cell type {blocks[k].type!r} (cell block {k}) for dim={dim}; "
                f"supported: {', '.join(SUPPORTED_CELL_TYPES)}"
            )
    skipped = [blocks[k].type for k, d in enumerate(tdims) if d is not None and d > dim]
    if skipped:
        log.info("read_mesh: ignoring cells of dimension > %d: %s", dim, sorted(set(skipped)))

    allpts = np.asarray(mesh.points, dtype=np.float64)
    if allpts.ndim != 2 or allpts.shape[1] < dim:
        raise ShapeError(
            f"mesh points must have at least {dim} coordinates for dim={dim} cells, "
            f"got shape {allpts.shape}"
        )
    used = np.zeros(allpts.shape[0], dtype=bool)
    for k in top:
        con = np.asarray(blocks[k].data).ravel()
        if con.size and (con.min() < 0 or con.max() >= allpts.shape[0]):
            raise InputError(
                f"cell block {k} ({blocks[k].type}) must hold node indices in "
                f"[0, {allpts.shape[0] - 1}], got range [{con.min()}, {con.max()}]"
            )
        used[con] = True
    if allpts.shape[1] > dim:
        extra = allpts[used][:, dim:]
        spread = np.ptp(extra, axis=0)
        scale = max(float(np.max(np.ptp(allpts[used][:, :dim], axis=0))), 1e-300)
        if np.any(spread > 1e-10 * scale):
            ax = "xyz"[dim + int(np.argmax(spread))]
            raise InputError(
                f"a dim={dim} mesh must lie in the {'xyz'[:dim]} space with constant {ax}; "
                f"got {ax} spread {float(spread.max()):.6g} over the cells' nodes "
                "(curved surfaces/line networks are not supported)"
            )
    pts = allpts[:, :dim]

    offsets = np.zeros(len(blocks) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(b.data) for b in blocks])
    measures, centroids, point_offset = [], [], {}
    n_points = 0
    inverted: list[tuple[int, str, int]] = []
    for k in top:
        b = blocks[k]
        con = np.asarray(b.data)
        meas, cen = cell_measures(pts, con, b.type)
        linear, nc = _LINEAR[b.type]
        x = pts[con if nc < 0 else con[:, :nc]]
        _check_cells(x, meas, linear, dim, f"{b.type} block {k}", int(offsets[k]))
        neg = np.flatnonzero(meas < 0)
        if neg.size:
            inverted.append((neg.size, b.type, int(offsets[k] + neg[0])))
        point_offset[k] = n_points
        n_points += meas.size
        measures.append(np.abs(meas))
        centroids.append(cen)
    if inverted:
        total = sum(c for c, _, _ in inverted)
        first = ", ".join(f"{c} {t} (first: cell {i})" for c, t, i in inverted)
        log.warning(
            "read_mesh: %d inverted (negatively oriented) cells use their absolute %s: %s",
            total,
            _MEASURE_NAME[dim],
            first,
        )
    volumes = np.concatenate(measures)
    points = np.concatenate(centroids)

    sets = _collect_sets(
        mesh, blocks, tdims, dim, top, point_offset, n_points, boundary, sets_from_data
    )

    mat = None
    if material is not None:
        if material not in mesh.cell_data:
            known = ", ".join(sorted(mesh.cell_data)) or "none"
            raise InputError(f"material cell data {material!r} not found; cell data: {known}")
        mat = np.concatenate([np.asarray(mesh.cell_data[material][k]).ravel() for k in top])

    horizon = None if ratio is None else ratio * volumes ** (1.0 / dim)
    return PointCloud(
        points, volumes, horizon=horizon, material=mat, sets=sets, thickness=thickness
    )


def _point_cloud(
    mesh: Any,
    blocks: list[Any],
    tdims: list[int | None],
    dim: int | None,
    volume: float | str | None,
    ratio: float | None,
    material: str | None,
    thickness: float,
    sets_from_data: bool,
) -> PointCloud:
    """Convert a mesh of ``vertex`` cells only (or without cells) to the cloud of its points."""
    allpts = np.asarray(mesh.points, dtype=np.float64)
    if allpts.ndim != 2 or allpts.shape[0] == 0 or not 1 <= allpts.shape[1] <= 3:
        raise InputError(f"mesh points must be an (n, 1..3) array, got shape {allpts.shape}")
    top = list(range(len(blocks)))
    if blocks:
        nodes = np.concatenate([np.asarray(b.data, dtype=np.int64).reshape(-1) for b in blocks])
        if nodes.size and (nodes.min() < 0 or nodes.max() >= allpts.shape[0]):
            raise InputError(
                f"vertex cells must hold node indices in [0, {allpts.shape[0] - 1}], got range "
                f"[{nodes.min()}, {nodes.max()}]"
            )
    else:
        nodes = np.arange(allpts.shape[0])
    if nodes.size == 0:
        raise InputError("mesh must hold points, got vertex cells without any")
    pts = allpts[nodes]
    if dim is None:
        const = np.ptp(pts, axis=0) == 0
        dim = allpts.shape[1]
        while dim > 1 and const[dim - 1]:
            dim -= 1
    elif dim not in (1, 2, 3) or dim > allpts.shape[1]:
        raise InputError(
            f"dim must be 1, 2 or 3 and at most the {allpts.shape[1]} coordinates of the "
            f"points, got {dim!r}"
        )
    elif pts.shape[1] > dim and np.any(np.ptp(pts[:, dim:], axis=0) > 0):
        spread = float(np.max(np.ptp(pts[:, dim:], axis=0)))
        raise InputError(
            f"dim={dim}: the point cloud's coordinates beyond {'xyz'[:dim]} must be constant, "
            f"got a spread of {spread:.6g}"
        )

    def field(name: str) -> np.ndarray | None:
        if name in mesh.point_data:
            return np.asarray(mesh.point_data[name])[nodes]
        if blocks and name in mesh.cell_data:
            return np.concatenate([np.asarray(a).reshape(len(b.data), -1) for a, b in
                                   zip(mesh.cell_data[name], blocks, strict=True)])  # fmt: skip
        return None

    if volume is None or isinstance(volume, str):
        names = [volume] if isinstance(volume, str) else ["Volume", "volume"]
        found = [(nm, f) for nm in names if (f := field(nm)) is not None]
        if not found:
            known = ", ".join(sorted(mesh.point_data)) or "none"
            if isinstance(volume, str):
                raise InputError(f"volume: point field {volume!r} not found; point fields: {known}")
            raise InputError(
                f"a point cloud (a mesh of {nodes.size} vertices, no cells of dimension >= 1) "
                "needs a volume per point: a 'Volume' / 'volume' point field, or the volume "
                f"option (read_mesh(volume=...), geometry.volume, --volume); point fields: {known}"
            )
        name, vol = found[0]
        vol = np.asarray(vol, dtype=np.float64)
        if vol.ndim == 2 and vol.shape[1] == 1:
            vol = vol[:, 0]
        if vol.shape != (nodes.size,):
            raise InputError(
                f"point field {name!r} must hold one value per point ({nodes.size}), got "
                f"shape {vol.shape}"
            )
        bad = np.flatnonzero(~(np.isfinite(vol) & (vol > 0)))
        if bad.size:
            raise InputError(
                f"point field {name!r} must be > 0 and finite, got {vol[bad[0]]} at point "
                f"{int(bad[0])}"
            )
    else:
        if isinstance(volume, bool) or not isinstance(volume, int | float | np.number):
            raise InputError(f"volume must be a number or a point field name, got {volume!r}")
        v = float(volume)
        if not (np.isfinite(v) and v > 0):
            raise InputError(f"volume must be > 0 and finite, got {v}")
        vol = np.full(nodes.size, v)

    offsets = np.cumsum([0] + [len(b.data) for b in blocks])
    point_offset = {k: int(offsets[k]) for k in top}
    sets = _collect_sets(
        mesh, blocks, tdims, 0, top, point_offset, nodes.size, "node", sets_from_data
    )
    node_point = np.full(allpts.shape[0], -1, dtype=np.int64)
    node_point[nodes] = np.arange(nodes.size)
    for name, idx in (getattr(mesh, "point_sets", None) or {}).items():
        pidx = node_point[np.asarray(idx, dtype=np.int64).ravel()]
        prev = sets.get(str(name), np.zeros(0, dtype=np.int64))
        sets[str(name)] = np.union1d(prev, pidx[pidx >= 0])

    mat = None
    if material is not None:
        m = field(material)
        if m is None:
            known = ", ".join(sorted({*mesh.point_data, *mesh.cell_data})) or "none"
            raise InputError(f"material field {material!r} not found; fields: {known}")
        mat = np.asarray(m).reshape(nodes.size)
    horizon = None if ratio is None else ratio * vol ** (1.0 / dim)
    return PointCloud(
        pts[:, :dim], vol, horizon=horizon, material=mat, sets=sets, thickness=thickness
    )


def _collect_sets(
    mesh: Any,
    blocks: list[Any],
    tdims: list[int | None],
    dim: int,
    top: list[int],
    point_offset: dict[int, int],
    n_points: int,
    boundary: str,
    sets_from_data: bool,
) -> dict[str, np.ndarray]:
    """Named point sets from cell_sets, encoded set data and gmsh physical groups."""
    direct: dict[str, list[np.ndarray]] = {}
    lower: dict[str, list[np.ndarray]] = {}

    def add(name: str, k: int, idx: np.ndarray) -> None:
        d = tdims[k]
        if idx.size == 0 or d is None or d > dim:
            return
        if d == dim:
            direct.setdefault(name, []).append(point_offset[k] + idx)
        else:
            lower.setdefault(name, []).append(np.asarray(blocks[k].data)[idx])

    for name, members in mesh.cell_sets.items():
        if len(members) != len(blocks):
            log.warning(
                "read_mesh: cell set %r has %d entries for %d cell blocks; ignored",
                name,
                len(members),
                len(blocks),
            )
            continue
        for k, idx in enumerate(members):
            if idx is not None:
                add(str(name), k, np.asarray(idx, dtype=np.int64).ravel())

    if sets_from_data:
        for key, data in mesh.cell_data.items():
            decoded = _decode_set_data(str(key), data, len(blocks))
            for name, members in decoded.items():
                for k, idx in enumerate(members):
                    add(name, k, idx)

    phys = mesh.cell_data.get("gmsh:physical")
    if phys is not None:
        names = _field_names(mesh.field_data)
        for k, tags in enumerate(phys):
            d = tdims[k]
            if d is None or d > dim:
                continue
            tags = np.asarray(tags).ravel()
            for t in np.unique(tags):
                default = f"physical{t}" if d == dim else f"physical{t}_dim{d}"
                name = names.get((int(t), d), default)
                add(name, k, np.flatnonzero(tags == t))

    sets: dict[str, np.ndarray] = {}
    if lower:
        cells_nodes = _incidence([np.asarray(blocks[k].data) for k in top], len(mesh.points))
        node_cells = cells_nodes.T.tocsr()  # (n_nodes, n_points)
    for name in sorted(set(direct) | set(lower)):
        parts = list(direct.get(name, []))
        if name in lower:
            tagged = _incidence(lower[name], len(mesh.points))
            need = np.diff(tagged.indptr)
            shared = (tagged @ node_cells).tocsr()
            rows = np.repeat(np.arange(shared.shape[0]), np.diff(shared.indptr))
            hit = shared.data >= (need[rows] if boundary == "facet" else 1)
            parts.append(shared.indices[hit].astype(np.int64))
        member = np.zeros(n_points, dtype=bool)
        for part in parts:
            member[part] = True
        idx = np.flatnonzero(member)
        if idx.size == 0:
            log.warning("read_mesh: set %r has no adjacent cells of dimension %d", name, dim)
        sets[name] = idx
    return sets
