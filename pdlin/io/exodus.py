"""Exodus II files of point results, written and read with netCDF4 directly.

The layout follows Peridigm's Exodus output (``Peridigm_OutputManager_ExodusII``):
three coordinates ``coordx``/``coordy``/``coordz`` (zero ``coordz`` / ``coordy``
for 2D / 1D clouds), one ``SPHERE`` element per point grouped into one element
block per phase (block id = ``material + 1``, connectivity = the points of that
phase), every step's time in ``time_whole`` and every field as nodal variables,
vectors as ``<Name>X``, ``<Name>Y``, ``<Name>Z`` and 3 x 3 tensors as
``<Name>XX`` ... ``<Name>ZZ`` (ParaView's Exodus reader and meshio group these
suffixes back into vectors and tensors).  Named point sets become node sets
(``ns_names``, ``node_ns<k>``); an empty set is written as a null node set
(``ns_status = 0``, no ``node_ns`` variable), as the Exodus library does.

Why not meshio's Exodus writer: it writes a single dummy time step and stores
multi-component point data with extra dimensions ParaView does not read.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .output import need_module

__all__ = ["EXODUS_SUFFIXES", "write_exodus_file", "read_exodus_file", "split_components"]

EXODUS_SUFFIXES = (".e", ".exo")

_VEC = ("X", "Y", "Z")
_TEN = tuple(a + b for a in _VEC for b in _VEC)  # XX, XY, XZ, YX, ... row-major
#: symmetric tensors: the order VTK's Exodus reader groups into a 6-component tensor
_SYM = ("XX", "YY", "ZZ", "XY", "XZ", "YZ")
_SYM_IDX = (0, 4, 8, 1, 2, 5)  # their positions in the row-major 3 x 3


def need_netcdf4() -> Any:
    """Import netCDF4 or raise MissingDependencyError naming the extra to install.

    Returns
    -------
    module
        The imported ``netCDF4`` module.

    Raises
    ------
    MissingDependencyError
        When netCDF4 is not installed (install ``pdlin[exodus]``).
    """
    return need_module("netCDF4", "exodus", "Exodus II (.e / .exo) files")


def is_symmetric(arr: np.ndarray) -> bool:
    """Test whether the rows are exactly symmetric 3 x 3 tensors.

    Parameters
    ----------
    arr : (n, 9) array_like
        Row-major 3 x 3 tensors, one per row.

    Returns
    -------
    bool
        True when every tensor equals its transpose bit for bit.
    """
    t = np.asarray(arr).reshape(-1, 3, 3)
    return bool(np.array_equal(t, t.transpose(0, 2, 1)))


def split_components(
    name: str, arr: np.ndarray, *, symmetric: bool = False
) -> list[tuple[str, np.ndarray]]:
    """Split one field into the scalar nodal variables of an Exodus file.

    (n, 3) -> ``nameX, nameY, nameZ``; (n, 9) -> ``nameXX ... nameZZ``
    (row-major), or with ``symmetric=True`` the six ``nameXX, nameYY,
    nameZZ, nameXY, nameXZ, nameYZ`` (ParaView shows a symmetric tensor);
    (n,) and (n, 1) -> ``name``; other widths ``name_0`` ...

    Parameters
    ----------
    name : str
        File name of the field (e.g. ``'Displacement'``).
    arr : (n,) or (n, k) array
        The field's values at the ``n`` nodes.
    symmetric : bool
        Write a 9-component tensor as its six symmetric components.

    Returns
    -------
    list of (str, (n,) ndarray)
        Variable name and column, in file order.

    Examples
    --------
    >>> import numpy as np
    >>> [c for c, _ in split_components("Displacement", np.zeros((4, 3)))]
    ['DisplacementX', 'DisplacementY', 'DisplacementZ']
    >>> [c for c, _ in split_components("F", np.zeros((4, 9)))][:4]
    ['FXX', 'FXY', 'FXZ', 'FYX']
    >>> [c for c, _ in split_components("Strain", np.zeros((4, 9)), symmetric=True)]
    ['StrainXX', 'StrainYY', 'StrainZZ', 'StrainXY', 'StrainXZ', 'StrainYZ']
    """
    a = np.asarray(arr, dtype=float)
    if a.ndim == 1:
        return [(name, a)]
    a = a.reshape(a.shape[0], -1)
    w = a.shape[1]
    if w == 1:
        return [(name, a[:, 0])]
    if w == 9 and symmetric:
        return [(name + c, a[:, k]) for c, k in zip(_SYM, _SYM_IDX, strict=True)]
    suffixes = _VEC if w == 3 else _TEN if w == 9 else tuple(f"_{k}" for k in range(w))
    return [(name + s, a[:, k]) for k, s in enumerate(suffixes)]


def _group_components(names: Sequence[str]) -> list[tuple[str, list[int]]]:
    """Inverse of :func:`split_components` on a list of variable names (in order)."""
    index = {nm: k for k, nm in enumerate(names)}
    used: set[int] = set()
    out: list[tuple[str, list[int]]] = []
    for k, nm in enumerate(names):
        if k in used:
            continue
        groups = []
        if nm.endswith("XX"):
            groups.append((nm[:-2], _TEN))
            groups.append((nm[:-2], _SYM))
        if nm.endswith("X"):
            groups.append((nm[:-1], _VEC))
        if nm.endswith("_0"):
            base = nm[:-2]
            w = 0
            while f"{base}_{w}" in index:
                w += 1
            groups.append((base, tuple(f"_{j}" for j in range(w))))
        for base, suffixes in groups:
            cols = [index.get(base + s) for s in suffixes]
            if all(c is not None for c in cols) and not used.intersection(cols):
                ids = [int(c) for c in cols if c is not None]
                out.append((base, ids))
                used.update(ids)
                break
        else:
            out.append((nm, [k]))
            used.add(k)
    return out


def _chars(netCDF4: Any, names: Sequence[str], width: int) -> np.ndarray:
    return netCDF4.stringtochar(np.array([s.encode() for s in names], dtype=f"S{width}"))


def write_exodus_file(
    out: Path,
    points: np.ndarray,
    material: np.ndarray,
    sets: Mapping[str, np.ndarray],
    times: np.ndarray,
    steps: Sequence[Mapping[str, np.ndarray]],
    *,
    dim: int,
    title: str = "pdlin",
) -> None:
    """Write one Exodus II file (NetCDF 64-bit offset) holding every step.

    The file is built in memory (netCDF4's ``memory=``) and written with
    Python's file I/O: a write that fails (full disk, file-size limit) raises
    ``OSError`` instead of crashing the process in the netCDF library.

    Parameters
    ----------
    out : Path
        File to create (the caller stages it for the atomic replace).
    points : (n, dim) ndarray
        Point coordinates (padded with zeros to ``coordx/y/z``).
    material : (n,) ndarray of int
        Phase of each point; element block ``material + 1``.
    sets : mapping of name to index arrays
        Written as node sets, in this order, with ids 1, 2, ...
    times : (k,) ndarray
        Time of each step (``time_whole``).
    steps : k mappings of file field name -> (n,) / (n, c) arrays
        The same names and shapes in every step.
    dim : int
        Dimension of the cloud, stored as the global attribute ``pdlin_dim``.
    title : str
        The file's ``title`` attribute.
    """
    netCDF4 = need_netcdf4()
    pts = np.zeros((points.shape[0], 3))
    pts[:, : points.shape[1]] = points
    n = pts.shape[0]
    mat = np.asarray(material, dtype=np.int64)
    block_ids = np.unique(mat) + 1
    order = np.argsort(mat, kind="stable")
    sym = {
        name: arr.ndim == 2 and arr.shape[1] == 9 and all(is_symmetric(st[name]) for st in steps)
        for name, arr in steps[0].items()
    }
    var_names = [
        c
        for name, arr in steps[0].items()
        for c, _ in split_components(name, arr, symmetric=sym[name])
    ]
    set_names = list(sets)
    longest = max([len(s) for s in var_names + set_names + ["block_1"]] + [32])
    len_name = longest + 1
    nc = netCDF4.Dataset(str(out), "w", format="NETCDF3_64BIT_OFFSET", memory=1 << 16)
    try:
        nc.setncatts(
            {
                "api_version": np.float32(8.03),
                "version": np.float32(8.03),
                "floating_point_word_size": np.int32(8),
                "file_size": np.int32(1),
                "maximum_name_length": np.int32(longest),
                "int64_status": np.int32(0),
                "title": title,
                "pdlin_dim": np.int32(dim),
            }
        )
        for d, size in (
            ("len_string", 33),
            ("len_line", 81),
            ("four", 4),
            ("len_name", len_name),
            ("time_step", None),
            ("num_dim", 3),
            ("num_nodes", n),
            ("num_elem", n),
            ("num_el_blk", block_ids.size),
        ):
            nc.createDimension(d, size)
        tw = nc.createVariable("time_whole", "f8", ("time_step",))
        tw[:] = np.asarray(times, dtype=float)
        cn = nc.createVariable("coor_names", "S1", ("num_dim", "len_name"))
        cn[:] = _chars(netCDF4, ["X", "Y", "Z"], len_name)
        for k, c in enumerate("xyz"):
            nc.createVariable(f"coord{c}", "f8", ("num_nodes",))[:] = pts[:, k]
        nc.createVariable("node_num_map", "i4", ("num_nodes",))[:] = np.arange(1, n + 1)
        # element k of the block-ordered numbering is the sphere on point order[k]
        nc.createVariable("elem_num_map", "i4", ("num_elem",))[:] = order + 1
        nc.createVariable("eb_status", "i4", ("num_el_blk",))[:] = np.ones(block_ids.size)
        prop = nc.createVariable("eb_prop1", "i4", ("num_el_blk",))
        prop.setncattr("name", "ID")
        prop[:] = block_ids
        eb = nc.createVariable("eb_names", "S1", ("num_el_blk", "len_name"))
        eb[:] = _chars(netCDF4, [f"block_{b}" for b in block_ids], len_name)
        sorted_mat = mat[order]
        starts = np.searchsorted(sorted_mat, block_ids - 1, side="left")
        ends = np.searchsorted(sorted_mat, block_ids - 1, side="right")
        for b, (s, e) in enumerate(zip(starts, ends, strict=True), start=1):
            nc.createDimension(f"num_el_in_blk{b}", int(e - s))
            nc.createDimension(f"num_nod_per_el{b}", 1)
            conn = nc.createVariable(
                f"connect{b}", "i4", (f"num_el_in_blk{b}", f"num_nod_per_el{b}")
            )
            conn.setncattr("elem_type", "SPHERE")
            conn[:] = (order[s:e] + 1).reshape(-1, 1)
        if set_names:
            nc.createDimension("num_node_sets", len(set_names))
            sizes = [int(np.asarray(sets[s]).size) for s in set_names]
            st = nc.createVariable("ns_status", "i4", ("num_node_sets",))
            st[:] = np.array([1 if m else 0 for m in sizes])
            nsp = nc.createVariable("ns_prop1", "i4", ("num_node_sets",))
            nsp.setncattr("name", "ID")
            nsp[:] = np.arange(1, len(set_names) + 1)
            nsn = nc.createVariable("ns_names", "S1", ("num_node_sets", "len_name"))
            nsn[:] = _chars(netCDF4, set_names, len_name)
            for k, (name, m) in enumerate(zip(set_names, sizes, strict=True), start=1):
                if m == 0:
                    continue
                nc.createDimension(f"num_nod_ns{k}", m)
                nc.createVariable(f"node_ns{k}", "i4", (f"num_nod_ns{k}",))[:] = (
                    np.asarray(sets[name], dtype=np.int64) + 1
                )
        if var_names:
            nc.createDimension("num_nod_var", len(var_names))
            nv = nc.createVariable("name_nod_var", "S1", ("num_nod_var", "len_name"))
            nv[:] = _chars(netCDF4, var_names, len_name)
            j = 0
            for name in steps[0]:
                per_step = [split_components(name, st[name], symmetric=sym[name]) for st in steps]
                for col in range(len(per_step[0])):
                    j += 1
                    v = nc.createVariable(f"vals_nod_var{j}", "f8", ("time_step", "num_nodes"))
                    v[:] = np.stack([comps[col][1] for comps in per_step])
    finally:
        image = nc.close()
    with open(out, "wb") as fh:
        fh.write(image)


def entity_names(ds: Any, var: str, count: int) -> list[str]:
    """Read the names of an Exodus entity type (``eb_names`` / ``ns_names``).

    Parameters
    ----------
    ds : netCDF4.Dataset
        The open Exodus file.
    var : str
        Name variable, ``'eb_names'`` or ``'ns_names'``.
    count : int
        Number of entities of that type.

    Returns
    -------
    list of str
        ``count`` names, ``''`` where blank or when the file has no (valid) names.
    """
    if var not in ds.variables:
        return [""] * count
    raw = np.asarray(ds.variables[var][:])
    if raw.ndim != 2 or raw.shape[0] != count:
        return [""] * count
    out = []
    for row in raw:
        chars = [
            c.decode("latin-1") if isinstance(c, bytes) else str(c) for c in np.ma.filled(row, b"")
        ]
        out.append("".join(chars).split("\x00")[0].strip())
    return out


def entity_ids(ds: Any, var: str, count: int, what: str) -> np.ndarray:
    """Read the ids of an Exodus entity type (``eb_prop1`` / ``ns_prop1``).

    Parameters
    ----------
    ds : netCDF4.Dataset
        The open Exodus file.
    var : str
        Id variable, ``'eb_prop1'`` or ``'ns_prop1'``.
    count : int
        Number of entities of that type.
    what : str
        Entity kind for the error message (``'node set'``, ``'block'``).

    Returns
    -------
    (count,) ndarray of int64
        The ids; ``1..count`` when the file has none.

    Raises
    ------
    InputError
        When the file holds another number of ids than ``count``.
    """
    if var not in ds.variables:
        return np.arange(1, count + 1)
    ids = np.asarray(np.ma.filled(ds.variables[var][:], -1), dtype=np.int64).ravel()
    if ids.size != count:
        raise InputError(f"Exodus {var} must hold {count} {what} ids, got {ids.size}")
    return ids


def node_sets(ds: Any, path: Any) -> tuple[list[str], list[np.ndarray | None]]:
    """Read the node set names and 0-based node lists of an Exodus file.

    ``node_ns<k>`` is the k-th set of ``ns_prop1`` / ``ns_names`` (file order); a set
    without a name is ``nodelist_<id>``, as in Peridigm
    (``Peridigm_ExodusDiscretization.cpp``), so blank names never collapse into one; a
    null set (no ``node_ns<k>``) is None.

    Parameters
    ----------
    ds : netCDF4.Dataset
        The open Exodus file.
    path : str or path-like
        The file's path, for error messages.

    Returns
    -------
    names : list of str
        Set names in file order.
    lists : list of (m,) ndarray of int64 or None
        0-based node indices per set; ``None`` for a null set.

    Raises
    ------
    InputError
        When two sets have the same name.
    """
    n_ns = len(ds.dimensions["num_node_sets"]) if "num_node_sets" in ds.dimensions else 0
    ids = entity_ids(ds, "ns_prop1", n_ns, "node set")
    names = [
        nm or f"nodelist_{int(i)}"
        for nm, i in zip(entity_names(ds, "ns_names", n_ns), ids, strict=True)
    ]
    seen: set[str] = set()
    for nm in names:
        if nm in seen:
            raise InputError(f"{path}: Exodus file has two node sets named {nm!r}")
        seen.add(nm)
    lists: list[np.ndarray | None] = []
    for k in range(1, n_ns + 1):
        var = ds.variables.get(f"node_ns{k}")
        lists.append(None if var is None else np.asarray(var[:], dtype=np.int64) - 1)
    return names, lists


def _names(var: Any) -> list[str]:
    var.set_auto_mask(False)
    return [b"".join(row).decode().rstrip("\x00").strip() for row in var[:]]


def read_exodus_file(path: str | Path) -> dict[str, Any]:
    """Read an Exodus II file of point results (nodal variables, node sets, blocks).

    Parameters
    ----------
    path : str or Path
        The ``.e`` / ``.exo`` file (pdlin's or Peridigm's particle output).

    Returns
    -------
    dict
        ``points`` (n, dim), ``dim``, ``times`` (k,), ``steps`` (k dicts of
        file field name -> (n,) / (n, c) arrays, components regrouped),
        ``sets`` (name -> 0-based node indices) and ``block`` (n,) block id of
        each node.
    """
    netCDF4 = need_netcdf4()
    with netCDF4.Dataset(path) as nc:
        nc.set_auto_mask(False)
        n = len(nc.dimensions["num_nodes"])
        nd = len(nc.dimensions["num_dim"])
        coords = [np.asarray(nc.variables[f"coord{c}"][:], dtype=float) for c in "xyz"[:nd]]
        pts = np.column_stack(coords)
        if "pdlin_dim" in nc.ncattrs():
            dim = int(nc.getncattr("pdlin_dim"))
        else:
            dim = nd
        pts = pts[:, :dim]
        times = np.asarray(nc.variables["time_whole"][:], dtype=float)
        names = _names(nc.variables["name_nod_var"]) if "name_nod_var" in nc.variables else []
        raw = [np.asarray(nc.variables[f"vals_nod_var{j + 1}"][:]) for j in range(len(names))]
        steps: list[dict[str, np.ndarray]] = [{} for _ in range(times.size)]
        for base, cols in _group_components(names):
            for k in range(times.size):
                if len(cols) == 1:
                    steps[k][base] = raw[cols[0]][k].astype(float)
                elif len(cols) == 6 and names[cols[1]] == base + "YY":  # symmetric tensor
                    full = np.zeros((n, 9))
                    for c, pos in zip(cols, _SYM_IDX, strict=True):
                        full[:, pos] = raw[c][k]
                    full[:, [3, 6, 7]] = full[:, [1, 2, 5]]
                    steps[k][base] = full
                else:
                    steps[k][base] = np.column_stack([raw[c][k] for c in cols]).astype(float)
        ns_names, ns_lists = node_sets(nc, path)
        sets = {
            name: np.zeros(0, dtype=np.int64) if idx is None else idx
            for name, idx in zip(ns_names, ns_lists, strict=True)
        }
        block = np.zeros(n, dtype=np.int64)
        ids = np.asarray(nc.variables["eb_prop1"][:], dtype=np.int64)
        conns: dict[int, np.ndarray] = {}
        for b, bid in enumerate(ids, start=1):
            conn = nc.variables.get(f"connect{b}")
            if conn is not None:
                cb = np.asarray(conn[:], dtype=np.int64)
                block[cb.ravel() - 1] = bid
                conns[b] = cb
        _element_fields(nc, conns, n, times.size, steps)
    return {"points": pts, "dim": dim, "times": times, "steps": steps, "sets": sets, "block": block}


def _element_fields(
    nc: Any, conns: dict[int, np.ndarray], n: int, k: int, steps: list[dict[str, np.ndarray]]
) -> None:
    """Add element variables of one-node (sphere) elements to ``steps`` as point fields.

    Peridigm writes ``Volume``, ``Damage``, ``Element_Id``, ... that way; a field is kept
    only where every point has a value and no nodal field has its name.
    """
    if "name_elem_var" not in nc.variables or not conns:
        return
    if any(c.shape[1] != 1 for c in conns.values()):
        return  # not a particle file: element values do not belong to single points
    names = _names(nc.variables["name_elem_var"])
    raw: list[np.ndarray | None] = []
    for j in range(1, len(names) + 1):
        vals = np.full((k, n), np.nan)
        for b, c in conns.items():
            var = nc.variables.get(f"vals_elem_var{j}eb{b}")
            if var is not None:
                vals[:, c[:, 0] - 1] = np.asarray(var[:], dtype=float)
        raw.append(vals if np.all(np.isfinite(vals)) else None)
    for base, cols in _group_components(names):
        if any(raw[c] is None for c in cols) or base in steps[0]:
            continue
        for step in range(k):
            parts = [raw[c][step] for c in cols]  # type: ignore[index]
            steps[step][base] = parts[0] if len(parts) == 1 else np.column_stack(parts)
