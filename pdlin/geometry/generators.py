"""Mesh generators for standard benchmark geometries (no gmsh needed).

The generators return :class:`meshio.Mesh` objects; turn them into point
clouds with :func:`pdlin.read_mesh`.
"""

from __future__ import annotations

import os
import tempfile
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["plate_with_hole_mesh", "PLATE_WITH_HOLE_GROUPS"]

#: gmsh physical groups of :func:`plate_with_hole_mesh`: name -> (tag, dim).
PLATE_WITH_HOLE_GROUPS: dict[str, tuple[int, int]] = {
    "hole": (1, 1),
    "right": (2, 1),
    "top": (3, 1),
    "left": (4, 1),
    "bottom": (5, 1),
    "plate": (6, 2),
}
_EDGE_OF_BLOCK = ("right", "top", "left", "bottom")


def _positive_int(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InputError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _positive_float(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a positive number, got {value!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise InputError(f"{name} must be > 0, got {value!r}")
    return v


def _check_mesh_memory(n_nodes: float, bytes_per_node: float, what: str) -> None:
    """Refuse a generated mesh whose arrays do not fit (before building them)."""
    from ..resources import check_memory

    check_memory(
        f"plate_with_hole_mesh ({n_nodes:,.0f} nodes)",
        n_nodes * bytes_per_node,
        [f"a smaller {what} resolution: the point count grows with its square"],
    )


def plate_with_hole_mesh(
    n_ang: int = 32,
    n_rad: int = 60,
    *,
    length: float = 1.0,
    radius: float = 0.1,
    grading: float = 4.0,
    backend: str = "ogrid",
    mesh_size: float | None = None,
    layers: int | None = None,
    depth: float | None = None,
) -> Any:
    """Mesh a square plate with a central circular hole as a :class:`meshio.Mesh`.

    The default ``'ogrid'`` backend builds the structured O-grid of the
    plate example of Liu, Chen & Skelton, XOSB (§5.1; the paper gives only the
    quad count, the layout is pdlin's reconstruction): four blocks (right, top,
    left, bottom), each spanning 90 degrees of polar angle in ``n_ang``
    equal steps and ``n_rad`` graded radial layers.  Node ``(phi, l)`` of the
    right block is ``p_in + g(l / n_rad) (p_out - p_in)`` with
    ``p_in = r (cos phi, sin phi)``, ``p_out = (L/2, L/2 tan phi)`` and
    ``g(t) = (q**t - 1) / (q - 1)`` (``q = grading``; ``q = 1`` is uniform);
    the other blocks are rotated by 90, 180 and 270 degrees.

    Parameters
    ----------
    n_ang : int
        Angular cells per block (32 in the paper: 4 x 32 x 60 = 7,680 quads).
    n_rad : int
        Radial cell layers (60 in the paper).
    length : float
        Side of the square, centred at the origin.
    radius : float
        Hole radius (< length / 2).
    grading : float
        Ratio ``q`` of the radial grading ``g(t) = (q^t - 1)/(q - 1)``:
        cells grow away from the hole.
    backend : {'ogrid', 'gmsh'}
        ``'gmsh'`` meshes the plate with unstructured triangles (needs the
        optional gmsh package, ``pip install pdlin[meshing]``).
    mesh_size : float, optional
        Element size of the gmsh backend at the outer edges (default
        ``length / 50``); it is four times smaller at the hole.
    layers : int, optional
        Extrude the O-grid into ``layers`` uniform layers of hexahedra
        through ``z in [0, depth]`` (the 3D block with a hole of the XOSB
        paper, §5.2, is 0.3 thick: ``depth=0.3``; e.g. ``layers=8``).  Default: the 2D mesh.
        Only with ``backend='ogrid'``; needs ``depth``.
    depth : float, optional
        Thickness of the extruded block (required with ``layers``).

    Returns
    -------
    meshio.Mesh
        2D points (z dropped), one ``quad`` block (ring-major: cell
        ``l * 4 n_ang + a`` is layer ``l``, angular position ``a``; the first
        ``4 n_ang`` cells form the hole ring) and one ``line`` block of the
        boundary edges.  Named groups ``hole``, ``right``, ``top``, ``left``,
        ``bottom`` are stored twice: as ``cell_sets`` on the adjacent quad
        layer, and as gmsh physical groups of the boundary lines
        (``cell_data['gmsh:physical']`` with names in ``field_data``, see
        ``PLATE_WITH_HOLE_GROUPS``), which survive ``.msh`` and ``.vtu``
        files; :func:`pdlin.read_mesh` maps both to the same point sets.

        With ``layers``: 3D points (node ``(k, p)`` of layer ``k`` is
        ``k * n_2d + p``, ``p`` the 2D node), one ``hexahedron`` block
        (meshio node order, layer-major: cell ``k * 4 n_ang n_rad + c`` is 2D
        cell ``c`` in layer ``k``) and one ``quad`` block of the boundary
        faces.  The groups ``hole``, ``right``, ``top``, ``left``, ``bottom``
        (the lateral faces) and ``back`` / ``front`` (``z = 0`` / ``z =
        depth``) are ``cell_sets`` on the adjacent hexahedra and gmsh
        physical groups of dimension 2 on the faces (tags 1-5, 7, 8; tag 6,
        dimension 3, is the ``block``).

    Raises
    ------
    InputError
        If ``radius >= length / 2``, ``backend`` is unknown, or ``layers`` and ``depth``
        are not given together (``layers`` only with ``backend='ogrid'``).
    ImportError
        If meshio is not installed.

    Examples
    --------
    >>> mesh = plate_with_hole_mesh(4, 3)
    >>> mesh.cells[0].type, len(mesh.cells[0]), len(mesh.cells_dict["line"])
    ('quad', 48, 32)
    >>> [len(mesh.cell_sets[k][0]) for k in ("hole", "right", "top", "left", "bottom")]
    [16, 4, 4, 4, 4]

    Extruded into 2 layers of hexahedra, 0.3 deep:

    >>> block = plate_with_hole_mesh(4, 3, layers=2, depth=0.3)
    >>> block.points.shape, block.cells[0].type, len(block.cells[0])
    ((192, 3), 'hexahedron', 96)
    >>> [len(block.cell_sets[k][0]) for k in ("hole", "right", "back", "front")]
    [32, 8, 48, 48]
    """
    try:
        import meshio
    except ImportError as exc:  # pragma: no cover - meshio is a core dependency
        raise ImportError("plate_with_hole_mesh needs meshio: pip install meshio") from exc
    na = _positive_int(n_ang, "n_ang")
    nr = _positive_int(n_rad, "n_rad")
    L = _positive_float(length, "length")
    r = _positive_float(radius, "radius")
    q = _positive_float(grading, "grading")
    if r >= L / 2:
        raise InputError(f"radius must be < length / 2 = {L / 2}, got {r}")
    if layers is None:
        if depth is not None:
            raise InputError(f"depth needs layers (the number of extruded layers), got {depth!r}")
    else:
        nl = _positive_int(layers, "layers")
        if depth is None:
            raise InputError("layers needs depth (the thickness of the extruded block), got None")
        dz = _positive_float(depth, "depth")
        if backend != "ogrid":
            raise InputError(f"layers needs backend='ogrid', got {backend!r}")
    if backend == "gmsh":
        size = L / 50 if mesh_size is None else _positive_float(mesh_size, "mesh_size")
        # ~2 triangles per size² of the plate; gmsh holds ~1 kB per element while meshing
        _check_mesh_memory(2.0 * (L / size) ** 2, 1000.0, "mesh_size")
        return _plate_with_hole_gmsh(L, r, size)
    if backend != "ogrid":
        raise InputError(f"backend must be 'ogrid' or 'gmsh', got {backend!r}")
    n_layers = 1 if layers is None else nl + 1
    # nodes: coordinates and the (nr+1, 4 na, 2) intermediates; cells: corners + tags
    _check_mesh_memory(float(nr + 1) * 4 * na * n_layers, 160.0 + 8 * 8 * 2, "n_ang x n_rad")

    n_ring = 4 * na
    a = np.arange(n_ring)
    block = a // na
    phi_local = np.deg2rad(-45.0 + (a % na) * (90.0 / na))
    rot = block * (np.pi / 2)
    p_in = r * np.stack([np.cos(phi_local), np.sin(phi_local)], axis=1)
    p_out = np.stack([np.full(n_ring, L / 2), (L / 2) * np.tan(phi_local)], axis=1)
    t = np.arange(nr + 1) / nr
    g = t if q == 1.0 else (q**t - 1.0) / (q - 1.0)
    local = p_in[None] + g[:, None, None] * (p_out - p_in)[None]  # (nr+1, n_ring, 2)
    c, s = np.cos(rot), np.sin(rot)
    x = c * local[..., 0] - s * local[..., 1]
    y = s * local[..., 0] + c * local[..., 1]
    points = np.stack([x.ravel(), y.ravel()], axis=1)  # node (l, a) -> l * n_ring + a
    points[np.abs(points) < 1e-15 * L] = 0.0

    layer, angle = np.meshgrid(np.arange(nr), a, indexing="ij")
    ll, aa = layer.ravel(), angle.ravel()
    a1 = (aa + 1) % n_ring
    # counterclockwise: outwards along the ray, then on to the next angle
    quads = np.stack(
        [ll * n_ring + aa, (ll + 1) * n_ring + aa, (ll + 1) * n_ring + a1, ll * n_ring + a1],
        axis=1,
    )
    hole_lines = np.stack([a, (a + 1) % n_ring], axis=1)
    outer_lines = nr * n_ring + hole_lines
    lines = np.concatenate([hole_lines, outer_lines])

    last = (nr - 1) * n_ring
    quad_sets = {"hole": a}
    line_sets = {"hole": a}
    for b, name in enumerate(_EDGE_OF_BLOCK):
        quad_sets[name] = last + b * na + np.arange(na)
        line_sets[name] = n_ring + b * na + np.arange(na)
    empty = np.zeros(0, dtype=np.int64)
    cell_sets = {
        name: [quad_sets[name], empty] for name in ("hole", "right", "top", "left", "bottom")
    }
    line_tags = np.zeros(lines.shape[0], dtype=np.int64)
    for name, idx in line_sets.items():
        line_tags[idx] = PLATE_WITH_HOLE_GROUPS[name][0]
    if layers is not None:
        return _extrude(points, quads, lines, line_tags, quad_sets, nl, dz)
    quad_tags = np.full(quads.shape[0], PLATE_WITH_HOLE_GROUPS["plate"][0], dtype=np.int64)
    return meshio.Mesh(
        points,
        [("quad", quads), ("line", lines)],
        cell_data={
            "gmsh:physical": [quad_tags, line_tags],
            "gmsh:geometrical": [quad_tags, line_tags],
        },
        field_data={k: np.array(v) for k, v in PLATE_WITH_HOLE_GROUPS.items()},
        cell_sets=cell_sets,
    )


#: gmsh physical groups of the extruded block: name -> (tag, dim).
_BLOCK_WITH_HOLE_GROUPS: dict[str, tuple[int, int]] = {
    **{name: (tag, 2) for name, (tag, _) in PLATE_WITH_HOLE_GROUPS.items() if name != "plate"},
    "block": (6, 3),
    "back": (7, 2),
    "front": (8, 2),
}


def _extrude(
    points: np.ndarray,
    quads: np.ndarray,
    lines: np.ndarray,
    line_tags: np.ndarray,
    quad_sets: dict[str, np.ndarray],
    layers: int,
    depth: float,
) -> Any:
    """Extrude the 2D O-grid into ``layers`` uniform layers of hexahedra (z in [0, depth])."""
    import meshio

    n2, nq = points.shape[0], quads.shape[0]
    z = np.linspace(0.0, depth, layers + 1)
    pts3 = np.column_stack(
        [np.tile(points, (layers + 1, 1)), np.repeat(z, n2)]
    )  # node (k, p) -> k * n2 + p
    off = (np.arange(layers) * n2)[:, None, None]  # (layers, 1, 1)
    # meshio order: the counter-clockwise bottom quad, then the same quad one layer up
    hexes = np.concatenate([quads[None] + off, quads[None] + off + n2], axis=2).reshape(-1, 8)
    # lateral faces: each boundary line swept through the layers (outward normals not needed)
    side = np.concatenate([lines[None] + off, lines[None, :, ::-1] + off + n2], axis=2).reshape(
        -1, 4
    )
    side_tags = np.tile(line_tags, layers)
    faces = np.concatenate([side, quads[:, ::-1], quads + layers * n2])
    face_tags = np.concatenate(
        [
            side_tags,
            np.full(nq, _BLOCK_WITH_HOLE_GROUPS["back"][0], dtype=np.int64),
            np.full(nq, _BLOCK_WITH_HOLE_GROUPS["front"][0], dtype=np.int64),
        ]
    )
    layer_off = (np.arange(layers) * nq)[:, None]
    hex_sets = {name: (idx[None] + layer_off).ravel() for name, idx in quad_sets.items()}
    hex_sets["back"] = np.arange(nq)
    hex_sets["front"] = (layers - 1) * nq + np.arange(nq)
    empty = np.zeros(0, dtype=np.int64)
    names = ("hole", "right", "top", "left", "bottom", "back", "front")
    hex_tags = np.full(hexes.shape[0], _BLOCK_WITH_HOLE_GROUPS["block"][0], dtype=np.int64)
    return meshio.Mesh(
        pts3,
        [("hexahedron", hexes), ("quad", faces)],
        cell_data={
            "gmsh:physical": [hex_tags, face_tags],
            "gmsh:geometrical": [hex_tags, face_tags],
        },
        field_data={k: np.array(v) for k, v in _BLOCK_WITH_HOLE_GROUPS.items()},
        cell_sets={name: [hex_sets[name], empty] for name in names},
    )


def _plate_with_hole_gmsh(L: float, r: float, size: float) -> Any:  # pragma: no cover
    """Unstructured triangle mesh of the plate with gmsh (optional extra)."""
    try:
        import gmsh
    except ImportError as exc:
        raise ImportError(
            "plate_with_hole_mesh(backend='gmsh') needs gmsh: pip install pdlin[meshing]"
        ) from exc
    import meshio

    init_here = not gmsh.isInitialized()
    if init_here:
        gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("pdlin_plate_with_hole")
        occ = gmsh.model.occ
        square = occ.addRectangle(-L / 2, -L / 2, 0.0, L, L)
        disk = occ.addDisk(0.0, 0.0, 0.0, r, r)
        out, _ = occ.cut([(2, square)], [(2, disk)])
        occ.synchronize()
        surf = [tag for d, tag in out if d == 2]
        groups: dict[str, list[int]] = {k: [] for k in ("hole", "right", "top", "left", "bottom")}
        tol = 1e-6 * L
        for _, tag in gmsh.model.getBoundary(out, oriented=False):
            x0, y0, _, x1, y1, _ = gmsh.model.getBoundingBox(1, abs(tag))
            if x1 - x0 < tol:
                groups["left" if x0 < 0 else "right"].append(abs(tag))
            elif y1 - y0 < tol:
                groups["bottom" if y0 < 0 else "top"].append(abs(tag))
            else:
                groups["hole"].append(abs(tag))
        for name, tags in groups.items():
            ptag, pdim = PLATE_WITH_HOLE_GROUPS[name]
            gmsh.model.addPhysicalGroup(pdim, tags, ptag, name=name)
        ptag, pdim = PLATE_WITH_HOLE_GROUPS["plate"]
        gmsh.model.addPhysicalGroup(pdim, surf, ptag, name="plate")
        # size at the hole = size / 4, growing linearly outwards (like the O-grid's q = 4)
        gmsh.model.mesh.setSize(gmsh.model.getEntities(0), size)
        hole_points = gmsh.model.getBoundary(
            [(1, t) for t in groups["hole"]], combined=False, recursive=True
        )
        gmsh.model.mesh.setSize([p for p in hole_points if p[0] == 0], size / 4)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.model.mesh.generate(2)
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "plate.msh")
            gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
            gmsh.write(path)
            mesh = meshio.read(path, file_format="gmsh")
    finally:
        gmsh.model.remove()
        if init_here:
            gmsh.finalize()
    mesh.points = np.ascontiguousarray(mesh.points[:, :2])
    return mesh
