"""Peridigm input decks (YAML or Teuchos XML, static subset) read into a pdlin scene.

Sources of the format (read, not copied):

* Peridigm ``examples/tensile_test/tensile_test.yaml`` / ``.xml`` and
  ``examples/wave_in_bar/wave_in_bar.yaml`` (deck layout, node-set files);
* Peridigm ``src/io/discretization/Peridigm_TextFileDiscretization.cpp`` (text
  discretization: five columns ``x y z block_id volume``, comment lines start with
  ``#``, ``/`` or ``*``, blocks named ``block_<id>``, 3D only);
* Peridigm ``src/core/Peridigm_BoundaryAndInitialConditionManager.cpp`` and
  ``Peridigm_Enums.cpp`` (names containing ``NODE_SET`` after upper-casing and
  ``' ' -> '_'`` are node-set definitions: a file of 1-based ids or an inline list;
  ``Full Domain`` / ``All Sets``; ``Coordinate`` defaults to x);
* Peridigm ``src/core/Peridigm_BoundaryCondition.cpp`` (``Value`` is a function of
  ``x, y, z, t``, optionally written ``value = ...``);
* Peridigm ``src/materials/Peridigm_Material.cpp`` (exactly two of Bulk Modulus,
  Shear Modulus, Young's Modulus, Poisson's Ratio), ``elastic.cxx`` (linear
  peridynamic solid, ω = 1, discrete weighted volume), ``elastic_bond_based.cxx``
  (``c = 18 K / (π δ⁴)``), ``correspondence.cxx`` (hourglass force
  ``18 C_hg K / (π δ⁴)``);
* Peridigm ``src/io/discretization/Peridigm_ExodusDiscretization.cpp`` and
  ``Peridigm_GeometryUtils.cpp`` (one point per element: tets and hexes at their
  centroid with their volume, hexes by a 24-tet decomposition, spheres at their node
  with their volume attribute; blank block / node-set names are ``block_<id>`` /
  ``nodelist_<id>`` by the Exodus ids);
* Peridigm ``src/io/discretization/Peridigm_PdQuickGridDiscretization.cpp`` and
  ``src/io/mesh_input/quick_grid/QuickGrid.cxx`` (``TensorProduct3DMeshGenerator``: cell
  centres, cell volumes, ``SphericalNormFunction``);
* Peridigm ``src/core/Peridigm.cpp`` (the keys its quasi-static solvers read; ``Time
  Steps``) and Teuchos ``XMLObject::getRequiredBool`` (``true/yes/1``, ``false/no/0``).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import InputError, PdlinError, SceneError
from ...geometry.cloud import PointCloud
from ...io.exodus import entity_ids
from ...io.exodus import entity_names as _exodus_names
from ...operators.bc import BodyForce, Dirichlet
from .._keys import NUMBER_TEXT
from ..materials import Block, blocks_per_point
from ..scene import Scene
from ._common import (
    _BOOL_SPELLINGS,
    _COORD,
    _ELASTIC_CONSTANTS,
    _bulk_shear,
    _cloud,
    _constants,
    _flag,
    _node_ids,
    _note,
    _number,
    _output_inside,
    _problem,
    _read_text_table,
    _resolve_file,
    _scene,
    _table,
    _tidy,
    _unknown,
)
from .expressions import deck_expression

__all__ = ["peridigm_hourglass_penalty", "peridigm_bond_filters", "peridigm_correspondence_model"]


def peridigm_hourglass_penalty(coefficient: float, K: Any, G: Any) -> Any:
    """Return the pdlin ``penalty`` matching Peridigm's ``Hourglass Coefficient``.

    Peridigm's correspondence hourglass force has the bond constant
    ``18 C_hg K / (π δ⁴)`` (``correspondence.cxx``); pdlin's penalty control uses the
    bond-based micromodulus ``18 K_eq / (π δ⁴)`` of the modulus ``E_eq`` whose
    bond-based axial stiffness equals ``C_1111 = K + 4G/3`` (``K_eq = C_1111 / 1.8``
    in 3D).  Equal constants give ``penalty = C_hg K / K_eq = 1.8 C_hg K / (K + 4G/3)``.
    The controls still differ (see ``docs/decks.md``): Peridigm penalizes the
    bond-direction projection of the non-affine displacement with a force that holds
    the deformation gradient fixed (nonsymmetric Jacobian); pdlin's penalty is the
    energy ``½ Σ ½ k_b |z_b|²`` of the full vector with ``k_b ∝ 1/|ξ|``.

    Parameters
    ----------
    coefficient : float
        Peridigm's ``Hourglass Coefficient`` ``C_hg``.
    K, G : float or numpy.ndarray
        Bulk and shear moduli (per point or scalar).

    Returns
    -------
    float or numpy.ndarray
        ``1.8 C_hg K / (K + 4G/3)``, shaped like ``K``.

    Examples
    --------
    >>> round(float(peridigm_hourglass_penalty(0.02, 1.5e12, 6.923e11)), 6)
    0.022286
    """
    return 1.8 * coefficient * np.asarray(K) / (np.asarray(K) + 4.0 * np.asarray(G) / 3.0)


# --------------------------------------------------------------------------------------
# Teuchos ParameterList XML
# --------------------------------------------------------------------------------------
_XML_TYPES: dict[str, Callable[[str], Any]] = {
    "string": str,
    "double": float,
    "float": float,
    "int": int,
    "bool": lambda s: _BOOL_SPELLINGS[s.strip().upper()],
}


def _xml_list(elem: Any, where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for child in elem:
        if not isinstance(child.tag, str):  # comments
            continue
        name = child.get("name")
        key = f"{where}.{name}" if where else str(name)
        if child.tag == "ParameterList":
            if name is None:
                raise SceneError(f"{where or 'deck'}: a nested <ParameterList> needs a name")
            out[name] = _xml_list(child, key)
        elif child.tag == "Parameter":
            typ = child.get("type", "string")
            value = child.get("value")
            if name is None or value is None:
                raise SceneError(f"{where or 'deck'}: <Parameter> needs name and value")
            if typ not in _XML_TYPES:
                raise SceneError(
                    f"{key}: Parameter type must be one of {sorted(_XML_TYPES)}, got {typ!r}"
                )
            try:
                out[name] = _XML_TYPES[typ](value)
            except (ValueError, KeyError):
                raise SceneError(f"{key}: {value!r} is not a valid {typ}") from None
        else:
            raise SceneError(
                f"{where or 'deck'}: unexpected XML element <{child.tag}> (Teuchos "
                "ParameterList decks hold <ParameterList> and <Parameter> only)"
            )
    return out


def _load_xml(path: Path) -> dict[str, Any]:
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise SceneError(f"{path}: invalid XML: {exc}") from None
    if root.tag != "ParameterList":
        raise SceneError(f"{path}: the root element must be <ParameterList>, got <{root.tag}>")
    name = root.get("name") or "Peridigm"
    return {name: _xml_list(root, name)}


# --------------------------------------------------------------------------------------
# Peridigm
# --------------------------------------------------------------------------------------
_PD_TOP = {
    "Verbose": "cosmetic",
    "Discretization": "",
    "Materials": "",
    "Blocks": "",
    "Boundary Conditions": "",
    "Solver": "",
    "Output": "",
    "Compute Class Parameters": "output computations (pdlin writes its own fields)",
    "Damage Models": "",
}
_PD_DISC = {
    "Type": "",
    "Input Mesh File": "",
    "Horizon": "legacy place of the horizon (used by blocks without one)",
    "Store Exodus Mesh": "output option",
    "Verbose": "cosmetic",
    "Construct Neighborhood Lists": "true: Peridigm's default (false -> error)",
    "Omit Bonds Between Blocks": "",
    "Bond Filters": "",
    "Construct Interfaces": "the interface-aperture output of Peridigm's Exodus "
    "discretization (no effect on the bonds or the solution)",
}
_PD_MAT_COMMON = {
    "Material Model": "",
    "Density": "dynamics only",
    "Bulk Modulus": "",
    "Shear Modulus": "",
    "Young's Modulus": "",
    "Poisson's Ratio": "",
    "Apply Automatic Differentiation Jacobian": "Jacobian algorithm (pdlin assembles K exactly)",
    "Plane Strain": "",
    "Plane Stress": "",
    "Influence Function": "",
}
_PD_MATERIALS: dict[str, dict[str, str]] = {
    "Elastic": {
        **_PD_MAT_COMMON,
        "Compute Partial Stress": "an output field of Peridigm's",
        "Apply Shear Correction Factor": "Peridigm's elastic.cxx computes it but does not use it "
        "in the force (the scaled alpha line is commented out)",
        "Hourglass Coefficient": "not read by Peridigm's Elastic material (Interfaces deck)",
        "Thermal Expansion Coefficient": "",
    },
    "Linear LPS": dict(_PD_MAT_COMMON),
    "Linear Elastic": dict(_PD_MAT_COMMON),
    "Elastic Correspondence": {
        **_PD_MAT_COMMON,
        "Hourglass Coefficient": "",
        "Thermal Expansion Coefficient": "",
    },
    "Elastic Bond Based": dict(_PD_MAT_COMMON),
    # PeridigmElasticPlastic (elastic_plastic.cxx); with Disable Plasticity: true
    # Peridigm_ElasticPlasticMaterial.cpp sets the yield stress to DBL_MAX (never yields)
    "Elastic Plastic": {
        **_PD_MAT_COMMON,
        "Disable Plasticity": "",
        "Yield Stress": "",
        "Apply Shear Correction Factor": "not read by Peridigm's Elastic Plastic material",
    },
}
_PD_BLOCK = {"Block Names": "", "Material": "", "Horizon": ""}
_PD_BC = {"Type": "", "Node Set": "", "Coordinate": "", "Value": ""}
# The keys Peridigm's src/core/Peridigm.cpp reads for its quasi-static solvers
# (execute, executeQuasiStatic, executeNOXQuasiStatic; the NOXQuasiStatic list is also
# handed to NOX::Solver::buildSolver, which reads Nonlinear Solver, Direction, Line
# Search, Printing, Solver Options, Status Tests and Trust Region).
_PD_SOLVER = {
    "Verbose": "cosmetic",
    "Initial Time": "",
    "Final Time": "",
    "QuasiStatic": "",
    "NOXQuasiStatic": "",
    "Peridigm Preconditioner": "preconditioner of NOX's linear solves (pdlin solves directly)",
    "Jacobian Diagnostics": "Jacobian check of Peridigm's NOX solver",
    "Disable Heuristics": "load-step heuristics of Peridigm's Newton solver",
    "Initialize Predictor From Previous Solver": "initial guess from an earlier solver",
}
_STEPS = "each load step is one linear solve at its time (pdlin run writes a time series)"
_PD_QS = {
    "Number of Load Steps": _STEPS,
    "Time Steps": _STEPS + " (the listed times)",
    "Absolute Tolerance": "Newton tolerance (pdlin checks its own residual)",
    "Relative Tolerance": "Newton tolerance (pdlin checks its own residual)",
    "Maximum Solver Iterations": "Newton iterations (one linear solve here)",
    "Damped Newton Diagonal Scale Factor": "Newton damping (one linear solve here)",
    "Damped Newton Diagonal Shift Factor": "Newton damping (one linear solve here)",
    "Belos Linear Solver": "Peridigm's iterative linear solver (pdlin solves directly)",
    "Belos Maximum Iterations": "Peridigm's iterative linear solver",
    "Belos Relative Tolerance": "Peridigm's iterative linear solver",
    "Belos Print Status": "cosmetic",
    "Adaptive Load-Stepping": "load-step reduction on Newton failures (one linear solve here)",
    "Verbose": "cosmetic",
    "Number of Steps": "as Number of Load Steps",
}
_PD_NOX = {
    "Number of Load Steps": _STEPS,
    "Time Steps": _STEPS + " (the listed times)",
    "Absolute Tolerance": "Newton tolerance (pdlin checks its own residual)",
    "Relative Tolerance": "Newton tolerance (pdlin checks its own residual)",
    "Max Solver Iterations": "Newton iterations (one linear solve here)",
    "Maximum Solver Iterations": "Newton iterations (one linear solve here)",
    "Verbose": "cosmetic",
    "Printing": "cosmetic",
    "Nonlinear Solver": "NOX algorithm choice (one linear solve here)",
    "Direction": "NOX algorithm choice",
    "Line Search": "NOX algorithm choice",
    "Solver Options": "NOX algorithm choice",
    "Status Tests": "NOX algorithm choice",
    "Trust Region": "NOX algorithm choice",
    "Jacobian Operator": "NOX algorithm choice",
    "Preconditioner": "NOX algorithm choice",
    "Max Age Of Prec": "NOX algorithm choice",
    "Maximum Age of Preconditioner": "NOX algorithm choice",
    "Preconditioner Reuse Policy": "NOX algorithm choice",
}
_PD_OUTPUT = {
    "Output File Type": "",
    "Output Format": "cosmetic",
    "Output Filename": "",
    "Output Frequency": "one state is written (the final one)",
    "Parallel Write": "cosmetic",
    "Output Variables": "pdlin writes all of its fields",
}


def _peridigm_cloud(disc: Mapping[str, Any], base: Path) -> tuple[PointCloud, dict[str, Any]]:
    """Points, volumes, block names (``block_<id>``) and mesh node sets."""
    kind = disc.get("Type")
    if kind == "Text File":
        path = _resolve_file(disc.get("Input Mesh File"), base, "Discretization.Input Mesh File")
        data = _read_text_table(path, "Discretization.Input Mesh File", (5,))
        block_id = data[:, 3]
        if np.any(block_id != np.round(block_id)):
            raise SceneError(f"Discretization: {path.name} has non-integer block ids (column 4)")
        cloud = _cloud(data[:, :3], data[:, 4], "Discretization.Input Mesh File")
        blocks = {
            f"block_{b}": np.flatnonzero(block_id == b) for b in np.unique(block_id.astype(int))
        }
        return cloud, {"blocks": blocks, "node_sets": {}}
    if kind == "Exodus":
        path = _resolve_file(disc.get("Input Mesh File"), base, "Discretization.Input Mesh File")
        return _exodus_cloud(path)
    if kind == "PdQuickGrid":
        return _quickgrid_cloud(disc)
    raise SceneError(
        "Discretization.Type must be 'Text File', 'Exodus' or 'PdQuickGrid' (pdlin's deck "
        f"reader), got {kind!r}"
    )


_PD_QUICKGRID = {
    "Type": "",
    "NeighborhoodType": "",
    "TensorProduct3DMeshGenerator": "",
    "TensorProductCylinderMeshGenerator": "",
    "Verbose": "cosmetic",
    "Store Exodus Mesh": "output option",
    "Construct Neighborhood Lists": "true: Peridigm's default (false -> error)",
    "Omit Bonds Between Blocks": "'None': Peridigm's default (one block here)",
}
_PD_TENSOR3D = ("X Origin", "Y Origin", "Z Origin", "X Length", "Y Length", "Z Length")
_PD_TENSOR3D_N = ("Number Points X", "Number Points Y", "Number Points Z")


def _quickgrid_axis(n: int, x0: float, length: float) -> np.ndarray:
    """QuickGrid's cell centres along one axis (``QuickGrid.cxx``, ``getDiscretization``).

    ``p = x0 + h / 2`` then ``p += h`` cell by cell (``h = length / n``): the running sum
    is kept (``np.cumsum`` adds in order) so the points are Peridigm's to the last bit.
    """
    h = length / n
    steps = np.full(n, h)
    steps[0] = x0 + h / 2.0
    return np.cumsum(steps)


def _quickgrid_cloud(disc: Mapping[str, Any]) -> tuple[PointCloud, dict[str, Any]]:
    """Peridigm's ``PdQuickGrid`` discretization (``Peridigm_PdQuickGridDiscretization.cpp``).

    ``TensorProduct3DMeshGenerator``: ``nx * ny * nz`` cell centres, point ``i + j nx +
    k nx ny`` at ``(x_i, y_j, z_k)``, every volume ``hx hy hz``, one block ``block_1``.
    ``NeighborhoodType: Spherical`` bonds the pairs with ``|x_j - x_i|² - δ² < 0``
    (``SphericalNormFunction``, strict; the cell box QuickGrid searches first holds the
    whole ball).  Without it QuickGrid bonds the whole cell box (``NoOpNormFunction``),
    which pdlin refuses.
    """
    key = "Discretization"
    if "Bond Filters" in disc:
        # Peridigm_PdQuickGridDiscretization.cpp stops on this too
        raise SceneError(
            f"{key}.Bond Filters: Peridigm does not support bond filters with PdQuickGrid"
        )
    gens = [k for k in ("TensorProduct3DMeshGenerator", "TensorProductCylinderMeshGenerator")
            if k in disc]  # fmt: skip
    if not gens:
        other = sorted(k for k in disc if k.startswith("TensorProduct"))
        raise SceneError(
            f"{key}: PdQuickGrid needs a TensorProduct3DMeshGenerator or "
            f"TensorProductCylinderMeshGenerator list, got {other or 'none'}"
        )
    _unknown(disc, _PD_QUICKGRID, key, "Peridigm PdQuickGrid discretization")
    for k, why in _PD_QUICKGRID.items():
        if why and k in disc:
            _note(f"{key}.{k}", why)
    norm = disc.get("NeighborhoodType")
    cube = norm is None and gens[0] == "TensorProduct3DMeshGenerator"
    if norm != "Spherical" and not cube:
        raise SceneError(
            f"{key}.NeighborhoodType must be 'Spherical' (without it QuickGrid bonds a cube of "
            f"cells, which pdlin does not read), got {norm!r}"
        )
    if gens[0] == "TensorProductCylinderMeshGenerator":  # Peridigm reads the 3D one first
        return _quickgrid_cylinder_cloud(disc)
    gkey = f"{key}.TensorProduct3DMeshGenerator"
    gen = _table(disc["TensorProduct3DMeshGenerator"], gkey)
    allowed = {k: "" for k in (*_PD_TENSOR3D, *_PD_TENSOR3D_N)}
    allowed["Type"] = "cosmetic (Peridigm does not read it)"
    _unknown(gen, allowed, gkey, "TensorProduct3DMeshGenerator")
    for k in (*_PD_TENSOR3D, *_PD_TENSOR3D_N):
        if k not in gen:
            raise SceneError(f"missing deck key {gkey}.{k}")
    origin = [_number(gen[f"{c} Origin"], f"{gkey}.{c} Origin") for c in "XYZ"]
    length = [_number(gen[f"{c} Length"], f"{gkey}.{c} Length", positive=True) for c in "XYZ"]
    counts = []
    for c in "XYZ":
        v = gen[f"Number Points {c}"]
        if isinstance(v, str) and re.fullmatch(r"\s*\d+\s*", v):
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise SceneError(f"{gkey}.Number Points {c} must be an integer >= 1, got {v!r}")
        counts.append(v)
    axes = [_quickgrid_axis(n, x0, L) for n, x0, L in zip(counts, origin, length, strict=True)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    points = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    # QuickGrid: xSpec.getCellSize() * ySpec.getCellSize() * zSpec.getCellSize()
    vol = (length[0] / counts[0]) * (length[1] / counts[1]) * (length[2] / counts[2])
    cloud = _cloud(points, np.full(points.shape[0], vol), gkey)
    if cube:  # QuickGrid's NoOpNorm: the whole cell box (read by Verlet decks only)
        return cloud, {
            "blocks": {"block_1": np.arange(cloud.n)},
            "node_sets": {},
            "cube": (np.array(origin), np.array(length) / np.array(counts), np.array(counts)),
        }
    return cloud, {
        "blocks": {"block_1": np.arange(cloud.n)},
        "node_sets": {},
        "strict_sphere": True,
    }


_PD_CYLINDER = {
    "Inner Radius": "",
    "Outer Radius": "",
    "Cylinder Length": "",
    "Number Points Radius": "",
    "Ring Center x": "",
    "Ring Center y": "",
    "Z Origin": "",
}


def _cell_reach(horizon: float, cell: float, n: int) -> int:
    """QuickGrid's one-sided cell horizon (``Spec1D::getCellNeighborhoodSize``)."""
    ratio = horizon / cell
    k = int(ratio)
    if abs(ratio - k) >= 0.5:
        k += 1
    return min(k, n)


def quickgrid_cylinder(
    inner_radius: float,
    outer_radius: float,
    n_rings: int,
    length: float,
    z0: float = 0.0,
    *,
    n_axis: int | None = None,
) -> dict[str, Any]:
    """Peridigm's ``TensorProductCylinderMeshGenerator`` cells (points, volumes, indices).

    ``QuickGrid.cxx`` with ``Peridigm_PdQuickGridDiscretization.cpp``: ``n_rings`` rings of
    thickness ``dr = (r_o - r_i) / n_rings``; ``n_rays = int(2π / (dr / R)) + 1`` rays,
    ``R = (r_i + r_o) / 2``, of ``dθ = 2π / n_rays``; ``n_axis = int(L / dr) + 1`` cells of
    ``dz = L / n_axis`` along the axis from ``z0``.  Cell ``(i, j, k)`` (ring, ray, axial)
    is point ``i + j n_rings + k n_rings n_rays`` at ``(r_i cos θ_j, r_i sin θ_j, z_k)`` with
    the centres accumulated as QuickGrid does (``p = x0 + h / 2``, then ``p += h``) and
    volume ``r_i dr dθ dz``.  Peridigm's generator places the ring about the z axis: it
    reads ``Ring Center x / y`` but does not apply them to the points.

    Parameters
    ----------
    inner_radius, outer_radius : float
        Radii of the ring (``Inner Radius``, ``Outer Radius``).
    n_rings : int
        Cells across the wall (``Number Points Radius``).
    length : float
        ``Cylinder Length``.
    z0 : float
        ``Z Origin``.
    n_axis : int, optional
        Cells along the axis (default Peridigm's ``int(length / dr) + 1``).

    Returns
    -------
    dict
        ``points`` (n, 3), ``volumes`` (n,), ``ijk`` (n, 3) cell indices and the cell
        sizes ``dr``, ``dtheta``, ``dz``, the counts ``n_rings``, ``n_rays``, ``n_axis`` and
        the mean radius ``R``.

    Examples
    --------
    >>> c = quickgrid_cylinder(1.0, 2.0, 2, 1.0)
    >>> c["n_rays"], c["n_axis"], c["points"].shape
    (19, 3, (114, 3))
    >>> round(float(c["volumes"].sum()), 12) == round(float(np.pi * (4 - 1) * 1.0), 12)
    True
    """
    dr = (outer_radius - inner_radius) / n_rings
    big_r = (inner_radius + outer_radius) / 2.0
    n_rays = int(2.0 * np.pi / (dr / big_r)) + 1
    thickness = abs(outer_radius - inner_radius)
    if n_axis is None:
        n_axis = int(length / (thickness / n_rings)) + 1
    r = _quickgrid_axis(n_rings, inner_radius, thickness)
    theta = _quickgrid_axis(n_rays, 0.0, 2.0 * np.pi)
    z = _quickgrid_axis(n_axis, z0, length)
    grids = np.meshgrid(np.arange(n_axis), np.arange(n_rays), np.arange(n_rings), indexing="ij")
    kk, jj, ii = (g.ravel() for g in grids)
    rr, th = r[ii], theta[jj]
    points = np.column_stack([rr * np.cos(th), rr * np.sin(th), z[kk]])
    d_r = thickness / n_rings
    dtheta = 2.0 * np.pi / n_rays
    dz = length / n_axis
    return {
        "points": points,
        "volumes": rr * d_r * dtheta * dz,  # QuickGrid: r*dr*cellRads*dz
        "ijk": np.column_stack([ii, jj, kk]),
        "dr": d_r,
        "dtheta": dtheta,
        "dz": dz,
        "n_rings": n_rings,
        "n_rays": n_rays,
        "n_axis": n_axis,
        "R": big_r,
    }


def _cylinder_window(
    cyl: Mapping[str, Any], horizon: float, key: str, *, sphere: bool = True
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``find_bonds`` exclude: QuickGrid's cell window of the cylinder and its sphere.

    ``TensorProductCylinderMeshGenerator::computePdGridData`` tries the cells within the
    one-sided cell horizons ``h_r = reach(δ / dr)``, ``h_z = reach(δ / dz)`` and, around
    the ring, ``h_θ = reach(δ / (R dθ))`` at the mean radius ``R`` (periodic), then keeps
    those with ``|ξ|² - δ² < 0``.  At radii below ``R`` the window in θ holds fewer cells
    than the sphere: Peridigm's bonds are the window's.  ``sphere=False``: the window alone
    (QuickGrid's ``NoOpNorm``, which Peridigm's own unit tests check).
    """
    from scipy.spatial import cKDTree

    h_r = _cell_reach(horizon, cyl["dr"], cyl["n_rings"])
    h_t = _cell_reach(horizon, cyl["dtheta"] * cyl["R"], cyl["n_rays"])
    h_z = _cell_reach(horizon, cyl["dz"], cyl["n_axis"])
    n_rays = cyl["n_rays"]
    if 2 * h_t + 1 > n_rays:
        raise SceneError(
            f"{key}: the horizon {horizon} spans {2 * h_t + 1} of the ring's {n_rays} rays; "
            "QuickGrid's ring window then visits cells twice (duplicate bonds): use a "
            "smaller horizon or a larger ring"
        )
    tree = cKDTree(cyl["points"])
    ijk = cyl["ijk"]
    in_sphere = _strict_sphere(horizon)

    def exclude(xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
        a = ijk[tree.query(xi)[1]]
        b = ijk[tree.query(xj)[1]]
        dj = np.abs(a[:, 1] - b[:, 1])
        dj = np.minimum(dj, n_rays - dj)
        outside = (np.abs(a[:, 0] - b[:, 0]) > h_r) | (dj > h_t) | (np.abs(a[:, 2] - b[:, 2]) > h_z)
        return (outside | in_sphere(xi, xj)) if sphere else outside

    return exclude


def _quickgrid_cylinder_cloud(disc: Mapping[str, Any]) -> tuple[PointCloud, dict[str, Any]]:
    """``PdQuickGrid`` with ``TensorProductCylinderMeshGenerator`` (:func:`quickgrid_cylinder`)."""
    gkey = "Discretization.TensorProductCylinderMeshGenerator"
    gen = _table(disc["TensorProductCylinderMeshGenerator"], gkey)
    allowed = dict(_PD_CYLINDER)
    allowed["Type"] = "cosmetic (Peridigm does not read it)"
    _unknown(gen, allowed, gkey, "TensorProductCylinderMeshGenerator")
    for k in _PD_CYLINDER:
        if k not in gen:
            raise SceneError(f"missing deck key {gkey}.{k}")
    r_i = _number(gen["Inner Radius"], f"{gkey}.Inner Radius")
    r_o = _number(gen["Outer Radius"], f"{gkey}.Outer Radius", positive=True)
    if not 0.0 <= r_i < r_o:
        raise SceneError(f"{gkey}: need 0 <= Inner Radius < Outer Radius, got {r_i} and {r_o}")
    length = _number(gen["Cylinder Length"], f"{gkey}.Cylinder Length", positive=True)
    z0 = _number(gen["Z Origin"], f"{gkey}.Z Origin")
    v = gen["Number Points Radius"]
    if isinstance(v, str) and re.fullmatch(r"\s*\d+\s*", v):
        v = int(v)
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise SceneError(f"{gkey}.Number Points Radius must be an integer >= 1, got {v!r}")
    centre = [_number(gen[f"Ring Center {c}"], f"{gkey}.Ring Center {c}") for c in "xy"]
    if any(centre):
        _note(
            f"{gkey}.Ring Center x/y",
            "read but not applied by Peridigm's generator (the ring is about the z axis)",
        )
    cyl = quickgrid_cylinder(r_i, r_o, v, length, z0)
    cloud = _cloud(cyl["points"], cyl["volumes"], gkey)
    return cloud, {
        "blocks": {"block_1": np.arange(cloud.n)},
        "node_sets": {},
        "cylinder": cyl,
    }


def _any_of(
    filters: list[Callable[[np.ndarray, np.ndarray], np.ndarray]],
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    if len(filters) == 1:
        return filters[0]

    def exclude(xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
        out = np.zeros(xi.shape[0], dtype=bool)
        for f in filters:  # a handful of filters, each vectorized over the bonds
            out |= f(xi, xj)
        return out

    return exclude


def _omit_between_blocks(
    points: np.ndarray, blocks: Mapping[str, np.ndarray]
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``Omit Bonds Between Blocks: All`` (``ExodusDiscretization::filterBonds``).

    ``find_bonds`` hands its ``exclude`` the bond end positions; they are mapped back to
    point numbers (the points are distinct) and bonds joining two blocks are dropped.
    """
    from scipy.spatial import cKDTree

    block_of = np.empty(points.shape[0], dtype=np.int64)
    for b, idx in enumerate(blocks.values()):
        block_of[idx] = b
    tree = cKDTree(points)

    def exclude(xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
        return block_of[tree.query(xi)[1]] != block_of[tree.query(xj)[1]]

    return exclude


_PD_PLANE = {
    "Type": "",
    **{
        f"{k}_{c}": "" for k in ("Normal", "Lower_Left_Corner", "Bottom_Unit_Vector") for c in "XYZ"
    },
    "Bottom_Length": "",
    "Side_Length": "",
}
_PD_DISK = {
    "Type": "",
    **{f"{k}_{c}": "" for k in ("Center", "Normal") for c in "XYZ"},
    "Radius": "",
}


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a[0] b[0] + a[1] b[1] + a[2] b[2]`` in Peridigm's order of summation."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _plane_crossing(
    p0: np.ndarray, p1: np.ndarray, point: np.ndarray, normal: np.ndarray, tol: float
) -> tuple[np.ndarray, np.ndarray]:
    """Bonds ``p0 -> p1`` meeting the plane at ``0 <= t <= 1`` and the meeting points.

    Peridigm's ``t = ((r0 - p0)·n) / ((p1 - p0)·n)``; ``|(p1 - p0)·n| < tol`` (parallel)
    meets nowhere.
    """
    num = _dot3(point - p0, normal)
    den = _dot3(p1 - p0, normal)
    parallel = np.abs(den) < tol
    t = num / np.where(parallel, 1.0, den)
    hit = ~parallel & (t >= 0.0) & (t <= 1.0)
    x = p0 + np.where(hit, t, 0.0)[:, None] * (p1 - p0)
    return hit, x


def peridigm_bond_filters(
    filters: Any, key: str
) -> list[Callable[[np.ndarray, np.ndarray], np.ndarray]]:
    """Peridigm's ``Bond Filters`` as ``find_bonds(exclude=...)`` callables.

    Each returns, for bonds from ``xi`` to ``xj``, whether Peridigm's filter cuts them,
    with Peridigm's arithmetic (``src/io/pdneigh/BondFilter.cxx``):

    * ``Rectangular_Plane`` (``FinitePlaneFilter``): the bond meets the plane through the
      lower-left corner ``r0`` with normal ``n`` at ``0 <= t <= 1`` (parallel when
      ``|(x_j - x_i)·n| < 1e-14``), and the meeting point ``x`` has
      ``-1e-15 < (x - r0)·u_a``, ``(x - r0)·u_a / Side_Length < 1 + 1e-15``,
      ``-1e-15 < (x - r0)·u_b`` and ``(x - r0)·u_b / Bottom_Length < 1 + 1e-15`` with
      ``u_b`` the ``Bottom_Unit_Vector`` as given (not normalized) and ``u_a = u_b × n``;
    * ``Disk`` (``DiskFilter``): the bond meets the plane through ``Center`` with normal
      ``Normal`` at ``0 <= t <= 1`` (parallel when ``|(x_j - x_i)·n| < 1e-15``) and
      ``|x - c|² < Radius²``.

    Peridigm filters each point's neighbour list from that point; ``find_bonds`` drops a
    bond when either direction is cut.

    Parameters
    ----------
    filters : Mapping
        The deck's ``Discretization.Bond Filters`` list (name -> filter list).
    key : str
        Its key path for messages.

    Returns
    -------
    list of callable
        One ``exclude(xi, xj) -> bool array`` per filter (points of shape ``(m, 3)``).

    Raises
    ------
    SceneError
        An unknown filter type or a missing or invalid key, named by its path.

    Examples
    --------
    >>> import numpy as np
    >>> (cut,) = peridigm_bond_filters({"F": {"Type": "Disk", "Center_X": 0, "Center_Y": 0,
    ...     "Center_Z": 0, "Normal_X": 0, "Normal_Y": 1, "Normal_Z": 0, "Radius": 1.0}}, "BF")
    >>> cut(np.array([[0.0, -0.5, 0.0], [2.0, -0.5, 0.0]]), np.array([[0.0, 0.5, 0.0]] * 2))
    array([ True, False])
    """
    out: list[Callable[[np.ndarray, np.ndarray], np.ndarray]] = []
    for fname, f in _table(filters, key).items():
        fkey = f"{key}.{fname}"
        f = _table(f, fkey)
        kind = f.get("Type")
        spec = {"Rectangular_Plane": _PD_PLANE, "Disk": _PD_DISK}.get(str(kind))
        if spec is None:
            raise SceneError(
                f"{fkey}.Type must be 'Rectangular_Plane' or 'Disk' (pdlin's deck reader; "
                f"'Exodus Mesh' filters are not supported), got {kind!r}"
            )
        _unknown(f, spec, fkey, f"Peridigm {kind} bond filter")
        for k in spec:
            if k not in f:
                raise SceneError(f"missing deck key {fkey}.{k}")

        def vec(name: str, f: Mapping[str, Any] = f, fkey: str = fkey) -> np.ndarray:
            return np.array([_number(f[f"{name}_{c}"], f"{fkey}.{name}_{c}") for c in "XYZ"])

        if kind == "Disk":
            out.append(
                _disk_filter(vec("Center"), vec("Normal"), _number(f["Radius"], f"{fkey}.Radius"))
            )
        else:
            out.append(
                _plane_filter(
                    vec("Normal"),
                    vec("Lower_Left_Corner"),
                    vec("Bottom_Unit_Vector"),
                    _number(f["Bottom_Length"], f"{fkey}.Bottom_Length"),
                    _number(f["Side_Length"], f"{fkey}.Side_Length"),
                )
            )
    return out


def _plane_filter(
    n: np.ndarray, r0: np.ndarray, ub: np.ndarray, b: float, a: float
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    # UTILITIES::Cross, term by term
    ua = np.array(
        [-ub[2] * n[1] + ub[1] * n[2], ub[2] * n[0] - ub[0] * n[2], -ub[1] * n[0] + ub[0] * n[1]]
    )

    def exclude(xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
        hit, x = _plane_crossing(xi, xj, r0, n, 1.0e-14)
        dr = x - r0
        aa, bb = _dot3(dr, ua), _dot3(dr, ub)
        zero, one = 1.0e-15, 1.0 + 1.0e-15
        with np.errstate(divide="ignore", invalid="ignore"):
            inside = (-zero < aa) & (aa / a < one) & (-zero < bb) & (bb / b < one)
        return hit & inside

    return exclude


def _disk_filter(
    c: np.ndarray, n: np.ndarray, radius: float
) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    def exclude(xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
        hit, x = _plane_crossing(xi, xj, c, n, 1.0e-15)
        d = x - c
        return hit & (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2] < radius * radius)

    return exclude


def _strict_sphere(horizon: float) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``find_bonds`` exclude: QuickGrid's strict ``dx² + dy² + dz² - δ² < 0`` test."""

    def exclude(xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
        d = xj - xi
        return d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2] - horizon * horizon >= 0.0

    return exclude


# Peridigm_GeometryUtils.cpp, hexCentroidAndVolume: 24 tets (edge a-b, the face's
# barycenter, the hex barycenter c = (f4 + f5) / 2), face by face in this order
_HEX_FACES = ((0, 1, 4, 5), (1, 2, 5, 6), (2, 3, 6, 7), (0, 3, 4, 7), (0, 1, 2, 3), (4, 5, 6, 7))
_HEX_TETS = (
    ((1, 0), (5, 1), (4, 5), (0, 4)),
    ((2, 1), (6, 2), (5, 6), (1, 5)),
    ((3, 2), (7, 3), (6, 7), (2, 6)),
    ((0, 3), (3, 7), (7, 4), (4, 0)),
    ((0, 1), (1, 2), (2, 3), (3, 0)),
    ((5, 4), (4, 7), (7, 6), (6, 5)),
)


def _peridigm_cells(x: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Peridigm's element volumes and centroids (``Peridigm_GeometryUtils.cpp``).

    ``x`` is ``(m, 4 or 8, 3)``.  Tets: the signed volume ``a · (b × c) / 6`` and the
    vertex mean; hexes: the sum of 24 such tets and their volume-weighted centroid.
    Returns volumes, centroids and the smallest signed (sub-)tet volume of each element
    (Peridigm stops on a negative one).
    """

    def tet(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray) -> np.ndarray:
        return np.einsum("ij,ij->i", p1 - p0, np.cross(p2 - p0, p3 - p0)) / 6.0

    if kind == "tetra":
        v = tet(x[:, 0], x[:, 1], x[:, 2], x[:, 3])
        return v, x.mean(axis=1), v
    faces = [x[:, list(f)].mean(axis=1) for f in _HEX_FACES]
    c = 0.5 * (faces[4] + faces[5])
    vol = np.zeros(len(x))
    cen = np.zeros((len(x), 3))
    vmin = np.full(len(x), np.inf)
    for f, tets in zip(faces, _HEX_TETS, strict=True):
        for a, b in tets:
            v = tet(x[:, a], x[:, b], f, c)
            vol += v
            cen += v[:, None] * 0.25 * (x[:, a] + x[:, b] + f + c)
            vmin = np.minimum(vmin, v)
    with np.errstate(divide="ignore", invalid="ignore"):
        return vol, cen / vol[:, None], vmin


def _exodus_ids(ds: Any, var: str, count: int, what: str) -> np.ndarray:
    """Entity ids (:func:`pdlin.io.exodus.entity_ids`), errors as deck errors."""
    try:
        return entity_ids(ds, var, count, what)
    except InputError as exc:
        raise SceneError(f"Discretization.Input Mesh File: {exc}") from None


def _exodus_cloud(path: Path) -> tuple[PointCloud, dict[str, Any]]:
    """Peridigm's Exodus conversion (``Peridigm_ExodusDiscretization.cpp``).

    One point per element: tet / hex elements at their centroid with their volume
    (10-node tets and 20-node hexes by their corner nodes), sphere elements at their
    node with the volume of their second attribute.  Element blocks and node sets are
    read from the netCDF variables by id (``eb_prop1`` / ``connect<k>``, ``ns_prop1``
    / ``node_ns<k>``): a block without a name in ``eb_names`` is ``block_<id>``, a node
    set without a name in ``ns_names`` is ``nodelist_<id>``, as in Peridigm.  A node
    set becomes the elements holding at least one of its nodes.  Side sets are not
    read (Peridigm does not read them either).
    """
    import scipy.sparse as sp

    try:
        import netCDF4
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise PdlinError(
            f"reading the Exodus mesh {path} needs netCDF4: pip install netCDF4"
        ) from exc
    key = "Discretization.Input Mesh File"
    try:
        ds = netCDF4.Dataset(path, "r")
    except OSError as exc:
        raise SceneError(f"{key}: cannot read {path} as Exodus (netCDF): {exc}") from None
    try:
        ds.set_auto_mask(False)
        return _exodus_cloud_from(ds, path, key, sp)
    except SceneError:
        raise
    except (KeyError, IndexError, ValueError) as exc:
        raise SceneError(f"{key}: {path.name} is not a readable Exodus mesh: {exc!r}") from None
    finally:
        ds.close()


def _exodus_cloud_from(ds: Any, path: Path, key: str, sp: Any) -> tuple[PointCloud, dict[str, Any]]:
    dims = ds.dimensions
    if "coordx" in ds.variables:
        xyz = [
            np.asarray(ds.variables[f"coord{c}"][:], dtype=float)
            for c in "xyz"
            if f"coord{c}" in ds.variables
        ]
        coords = np.column_stack(xyz)
    elif "coord" in ds.variables:
        coords = np.asarray(ds.variables["coord"][:], dtype=float).T
    else:
        raise SceneError(f"{key}: {path.name} holds no node coordinates (coordx / coord)")
    if coords.shape[1] != 3:
        raise SceneError(
            f"{key}: {path.name} is a {coords.shape[1]}D mesh; Peridigm's Exodus "
            "discretization (and pdlin's deck reader) needs a 3D mesh"
        )
    n_nodes = coords.shape[0]
    n_blk = len(dims["num_el_blk"]) if "num_el_blk" in dims else 0
    if n_blk == 0:
        raise SceneError(f"{key}: {path.name} has no element blocks")
    blk_ids = _exodus_ids(ds, "eb_prop1", n_blk, "element block")
    blk_names = _exodus_names(ds, "eb_names", n_blk)
    corners = {"TET": 4, "TETRA": 4, "TET4": 4, "TET10": 4, "HEX": 8, "HEX8": 8, "HEX20": 8}
    cents, vols, conn_rows, blocks = [], [], [], {}
    offset = 0
    for k in range(n_blk):
        bid = int(blk_ids[k])
        bname = blk_names[k] or f"block_{bid}"
        if bname in blocks:
            raise SceneError(f"{key}: {path.name} has two element blocks named {bname!r}")
        var = ds.variables.get(f"connect{k + 1}")
        if var is None:  # a null block (no elements)
            blocks[bname] = np.zeros(0, dtype=np.int64)
            continue
        conn = np.asarray(var[:], dtype=np.int64)
        etype = str(getattr(var, "elem_type", "")).strip().upper()
        if conn.size and (conn.min() < 1 or conn.max() > n_nodes):
            raise SceneError(
                f"{key}: Exodus block {bid} connectivity must hold node numbers in "
                f"[1, {n_nodes}], got [{int(conn.min())}, {int(conn.max())}]"
            )
        if etype == "SPHERE":
            attr = ds.variables.get(f"attrib{k + 1}")
            if attr is None or np.asarray(attr[:]).ndim != 2 or attr.shape[1] < 2:
                raise SceneError(
                    f"{key}: Exodus block {bid} has sphere elements without the volume "
                    "attribute (Peridigm reads the second attribute as the volume)"
                )
            nodes = conn[:, :1] - 1
            c, v = coords[nodes[:, 0]], np.asarray(attr[:], dtype=float)[:, 1]
        elif etype in corners:
            nodes = conn[:, : corners[etype]] - 1
            v, c, vmin = _peridigm_cells(coords[nodes], "tetra" if corners[etype] == 4 else "hex")
            if np.any(vmin < 0):
                e = int(np.flatnonzero(vmin < 0)[0])
                raise SceneError(
                    f"{key}: Exodus block {bid} element {e + 1} is inverted (a tet of Peridigm's "
                    f"decomposition has volume {vmin[e]:.3g}; check the node numbering)"
                )
        else:
            raise SceneError(
                f"{key}: Exodus block {bid} has {etype!r} elements; Peridigm's conversion "
                "supports TET / TETRA / TET4 / TET10, HEX / HEX8 / HEX20 and SPHERE elements"
            )
        if np.any(~np.isfinite(v) | (v <= 0)):
            e = int(np.flatnonzero(~np.isfinite(v) | (v <= 0))[0])
            raise SceneError(
                f"{key}: Exodus block {bid} element {e + 1} has volume {v[e]:.3g} "
                "(inverted or degenerate element)"
            )
        cents.append(c)
        vols.append(v)
        conn_rows.append(nodes)
        blocks[bname] = offset + np.arange(len(nodes))
        offset += len(nodes)
    if offset == 0:
        raise SceneError(f"{key}: {path.name} has no elements")
    cloud = _cloud(np.vstack(cents), np.concatenate(vols), key)
    offsets = np.cumsum([0] + [len(r) for r in conn_rows[:-1]])
    # element-node incidence -> node sets as element sets (any node in the set)
    rows = np.concatenate(
        [
            np.repeat(np.arange(len(r)) + off, r.shape[1])
            for r, off in zip(conn_rows, offsets, strict=True)
        ]
    )
    cols = np.concatenate([r.ravel() for r in conn_rows])
    inc = sp.csr_array((np.ones(rows.size), (rows, cols)), shape=(offset, n_nodes))
    n_ns = len(dims["num_node_sets"]) if "num_node_sets" in dims else 0
    ns_ids = _exodus_ids(ds, "ns_prop1", n_ns, "node set")
    ns_names = _exodus_names(ds, "ns_names", n_ns)
    node_sets: dict[str, np.ndarray] = {}
    for k in range(n_ns):
        sname = _tidy(ns_names[k] or f"nodelist_{int(ns_ids[k])}")
        if sname in node_sets:
            raise SceneError(f"{key}: {path.name} has two node sets named {sname!r}")
        var = ds.variables.get(f"node_ns{k + 1}")
        ids = np.zeros(0, dtype=np.int64) if var is None else np.asarray(var[:], np.int64)
        if ids.size and (ids.min() < 1 or ids.max() > n_nodes):
            raise SceneError(
                f"{key}: Exodus node set {int(ns_ids[k])} must hold node numbers in "
                f"[1, {n_nodes}], got [{int(ids.min())}, {int(ids.max())}]"
            )
        mask = np.zeros(n_nodes)
        mask[ids - 1] = 1.0
        node_sets[sname] = np.flatnonzero(inc @ mask > 0)
    return cloud, {"blocks": blocks, "node_sets": node_sets}


def _peridigm_material(name: str, mat: Mapping[str, Any], key: str) -> dict[str, Any]:
    """Read a Peridigm material list -> {'kind': pdlin model, 'K', 'G', 'hourglass'}."""
    model = mat.get("Material Model")
    if model not in _PD_MATERIALS:
        hint = (
            " (partial-volume materials are not supported)"
            if isinstance(model, str) and "Partial" in model
            else ""
        )
        raise SceneError(
            f"{key}.Material Model: {model!r} is not supported{hint}; supported: "
            f"{sorted(_PD_MATERIALS)}"
        )
    allowed = _PD_MATERIALS[model]
    _unknown(mat, allowed, key, f"Peridigm {model!r} material")
    yield_stress = _peridigm_yield(mat, key) if model == "Elastic Plastic" else None
    for k in ("Plane Strain", "Plane Stress"):
        if k in mat and _flag(mat[k], f"{key}.{k}"):
            raise SceneError(
                f"{key}.{k}: true is not supported: pdlin reads Peridigm decks as 3D point clouds "
                "(the text discretization is x y z block_id volume); for a 2D model write a pdlin "
                "scene with material.plane or a PeriLab deck with 'Symmetry'"
            )
    if "Influence Function" in mat and str(mat["Influence Function"]).strip() != "One":
        raise SceneError(
            f"{key}.Influence Function: only 'One' (ω = 1, Peridigm's default) is supported, got "
            f"{mat['Influence Function']!r}"
        )
    for k, why in allowed.items():
        if why and k in mat:
            _note(f"{key}.{k}", why)
    if model == "Elastic Bond Based":
        c = _constants(mat, key, exactly=None)
        if "K" in c and len(c) == 1:
            K = c["K"]
        else:
            if len(c) != 2:
                raise SceneError(
                    f"{key} needs Bulk Modulus or two of {list(_ELASTIC_CONSTANTS)}, got "
                    f"{[k for k in _ELASTIC_CONSTANTS if k in mat] or 'none'}"
                )
            K, _ = _bulk_shear(c, key)
        return {"kind": "bond_based", "K": K, "G": None, "hourglass": None}
    K, G = _bulk_shear(_constants(mat, key), key)
    # Peridigm's ElasticMaterial / ElasticCorrespondenceMaterial: e -= α ΔT |ξ| (thermal.py)
    alpha = None
    if "Thermal Expansion Coefficient" in mat:
        alpha = _number(
            mat["Thermal Expansion Coefficient"], f"{key}.Thermal Expansion Coefficient"
        )
    if model == "Elastic Correspondence":
        if "Hourglass Coefficient" not in mat:
            raise SceneError(
                f"{key}.Hourglass Coefficient is required for 'Elastic Correspondence'"
            )
        hg = _number(mat["Hourglass Coefficient"], f"{key}.Hourglass Coefficient")
        if hg < 0:
            raise SceneError(f"{key}.Hourglass Coefficient must be >= 0, got {hg}")
        return {"kind": "correspondence", "K": K, "G": G, "hourglass": hg, "alpha": alpha}
    return {"kind": "lps", "K": K, "G": G, "hourglass": None, "alpha": alpha, "yield": yield_stress}


def _peridigm_yield(mat: Mapping[str, Any], key: str) -> float | None:
    """``Yield Stress`` of an ``Elastic Plastic`` material (None: plasticity disabled)."""
    if "Yield Stress" not in mat:  # Peridigm_ElasticPlasticMaterial.cpp requires it
        raise SceneError(f"missing deck key {key}.Yield Stress (required by 'Elastic Plastic')")
    ys = _number(mat["Yield Stress"], f"{key}.Yield Stress", positive=True)
    if _flag(mat.get("Disable Plasticity", False), f"{key}.Disable Plasticity"):
        _note(f"{key}.Yield Stress", "unused: Disable Plasticity (never yields, the Elastic force)")
        return None
    return ys


#: ``kinematics`` of :func:`pdlin.read_deck` (``pdlin run --kinematics``)
KINEMATICS = ("auto", "finite", "linear")


def _peridigm(deck: Mapping[str, Any], base: Path, name: str, kinematics: str = "auto") -> Scene:
    root = _table(deck, "Peridigm")
    numbered = sorted(k for k in root if re.fullmatch(r"Output\d+", k))
    if numbered and "Output" not in root:
        # Peridigm's OutputManagerContainer writes every "Output<N>" list; pdlin the first
        root = {k: v for k, v in root.items() if k not in numbered[1:]}
        root["Output"] = root.pop(numbered[0])
        _note(f"Peridigm.{numbered[0]}", f"read as Output (not written: {numbered[1:]})")
    chained = sorted(k for k in root if re.fullmatch(r"Solver\d+", k))
    if chained and "Solver" not in root:
        return _chained_solvers(root, chained, base, name)
    _unknown(root, _PD_TOP, "Peridigm", "Peridigm deck")
    for k in ("Verbose", "Compute Class Parameters"):
        if k in root:
            _note(f"Peridigm.{k}", _PD_TOP[k])
    for k in ("Discretization", "Materials", "Blocks", "Solver"):
        if k not in root:
            raise SceneError(f"missing deck key Peridigm.{k}")
    disc = _table(root["Discretization"], "Discretization")
    omit = _peridigm_discretization_keys(disc)
    cloud, extra = _peridigm_cloud(disc, base)
    blocks_pts: dict[str, np.ndarray] = extra["blocks"]
    verlet = isinstance(root["Solver"], Mapping) and "Verlet" in root["Solver"]
    model, horizon, blocks, alpha, finite_model = _peridigm_blocks(
        _without_damage(root) if verlet else root, disc.get("Horizon"), blocks_pts, cloud.n
    )
    if "cube" in extra and not verlet:
        raise SceneError(
            "Discretization.NeighborhoodType must be 'Spherical' (without it QuickGrid bonds a "
            "cube of cells, which pdlin reads for Solver.Verlet decks only), got None"
        )
    if "Damage Models" in root and not verlet:
        raise SceneError(
            "Peridigm.Damage Models: damage is supported with Solver.Verlet only (explicit "
            "dynamics with critical stretch), not with quasi-static solvers"
        )

    # Peridigm runs a deck without Boundary Conditions (no constraint, no load: u = 0)
    n = cloud.n
    bcs = root.get("Boundary Conditions", {})
    sets = _peridigm_node_sets(bcs, base, n, extra["node_sets"])
    if verlet:
        if kinematics not in ("auto", "finite"):
            raise SceneError(
                f"kinematics {kinematics!r} is not available for Solver.Verlet decks: they run "
                "Peridigm's finite kinematics (exact extensions); use 'auto' or 'finite'"
            )
        return _verlet(root, name, model, cloud, horizon, blocks, sets, disc, extra, omit, base)
    times = _peridigm_solver(root["Solver"])
    at_rest = [Dirichlet(np.arange(n), np.zeros((n, cloud.dim)))]

    def conditions(t: float) -> tuple[list[Dirichlet], list[BodyForce]]:
        dirichlet, loads = _peridigm_bcs(bcs, sets, cloud, t)
        # nothing prescribed, nothing applied: Peridigm's quasi-static solve stops at its
        # zero residual, u = 0 (Peridigm's Interfaces deck); pdlin prescribes that u = 0
        # on every point rather than solving a singular system
        return (at_rest, loads) if not dirichlet and not loads else (dirichlet, loads)

    dirichlet, loads = conditions(times[-1])
    if dirichlet is at_rest:
        _note("Boundary Conditions", "none (no constraint, no load): u = 0 on every point")
    output = _peridigm_output(root, base, name)
    opts = _bond_options(cloud, horizon, disc, extra, omit)
    finite = _finite_kinematics(kinematics, finite_model, len(times) - 1)
    if finite and kinematics == "auto" and dirichlet is at_rest:
        finite = False  # nothing prescribed, nothing applied: u = 0 under either kinematics
    if finite and kinematics == "auto" and _loads_not_proportional(bcs, sets, cloud, times):
        # with plasticity _finite_scene refuses it; elastic decks stay linearized
        finite = _plastic(finite_model)
        if not finite:
            _note("Solver", "a Body Force not proportional to t over the load steps: linearized")
    if finite:
        scene = _finite_scene(
            name, finite_model, cloud, horizon, bcs, sets, times, opts, base, output
        )
        scene.blocks = blocks
        return scene
    scene = _scene(name, model, cloud, horizon, dirichlet, loads, base, output, opts)
    scene.time = times[-1]  # Peridigm writes the final state at Final Time
    scene.blocks = blocks
    # thermal strains: Thermal Expansion Coefficient and a Prescribed Temperature change
    dT = _peridigm_temperature(bcs, sets, cloud, times[-1], len(times) == 1)
    if (alpha is None) != (dT is None):
        _note(
            "Materials" if dT is None else "Boundary Conditions",
            "Thermal Expansion Coefficient without a Prescribed Temperature (ΔT = 0)"
            if dT is None
            else "Prescribed Temperature without a Thermal Expansion Coefficient (no strain)",
        )
    scene.problem = _with_thermal(scene.problem, alpha, dT)
    if len(times) > 2:
        # several load steps: each is a linear solve at that step's values (Peridigm's
        # own times, its initial state included); the last is the scene's problem
        steps = [
            (t, _with_thermal(
                _problem(model, cloud, horizon, *conditions(t), opts), alpha,
                _peridigm_temperature(bcs, sets, cloud, t, k == 0),
            ))
            for k, t in enumerate(times[:-1])
        ]  # fmt: skip
        scene.steps = [*steps, (times[-1], scene.problem)]
    return scene


def _bond_options(
    cloud: PointCloud, horizon: np.ndarray, disc: Mapping[str, Any], extra: Any, omit: str
) -> dict[str, Any]:
    """Return the ``find_bonds`` options of a deck (QuickGrid's sphere, filters, omitted pairs)."""
    blocks_pts: dict[str, np.ndarray] = extra["blocks"]
    filters: list[Callable[[np.ndarray, np.ndarray], np.ndarray]] = []
    if extra.get("strict_sphere"):
        filters.append(_strict_sphere(float(horizon[0])))
    if "cylinder" in extra:  # QuickGrid's cylinder: its cell window and sphere
        filters.append(_cylinder_window(extra["cylinder"], float(horizon[0]), "Blocks"))
    if "Bond Filters" in disc:
        filters += peridigm_bond_filters(disc["Bond Filters"], "Discretization.Bond Filters")
    if omit == "All" and len(blocks_pts) > 1:
        filters.append(_omit_between_blocks(cloud.points, blocks_pts))
    # Peridigm keeps points whose horizon reaches no other point (Number_Of_Neighbors 0,
    # its MultipleHorizons deck): pdlin.solve holds them at rest (pdlin.constraints)
    opts: dict[str, Any] = {"allow_isolated": True}
    if filters:
        opts["exclude"] = _any_of(filters)
    return opts


def _without_damage(root: Mapping[str, Any]) -> dict[str, Any]:
    """Return the deck without the blocks' ``Damage Model`` keys (the Verlet mapping reads them)."""
    blocks = {
        k: (
            {kk: vv for kk, vv in b.items() if kk != "Damage Model"}
            if isinstance(b, Mapping)
            else b
        )
        for k, b in _table(root["Blocks"], "Blocks").items()
    }
    return {**root, "Blocks": blocks}


def _verlet(
    root: Mapping[str, Any],
    name: str,
    model: Any,
    cloud: PointCloud,
    horizon: np.ndarray,
    blocks: list[Block],
    sets: dict[str, np.ndarray],
    disc: Mapping[str, Any],
    extra: Any,
    omit: str,
    base: Path,
) -> Scene:
    """Build the scene of a ``Solver.Verlet`` deck: explicit dynamics (``peridigm_verlet``)."""
    from .peridigm_verlet import verlet_scene

    kinds = {b.model for b in blocks if b.points.size}
    kind = next(iter(kinds)) if len(kinds) == 1 else "mixed"
    if kind == "lps" and any(
        "Thermal Expansion Coefficient" in m or _plastic_material(m)
        for m in _table(root["Materials"], "Materials").values()
    ):
        kind = "thermal or plastic"
    output = _peridigm_output(root, base, name)
    opts = _bond_options(cloud, horizon, disc, extra, omit)
    if "cube" in extra:
        opts["cube"] = _cube_window(extra["cube"], float(horizon[0]))
    return verlet_scene(root, name, model, kind, cloud, horizon, blocks, sets, opts, base, output)


def _cube_window(cube: Any, horizon: float) -> tuple[float, Any]:
    """QuickGrid's cube neighbourhood: search radius and ``find_bonds`` exclude.

    Without ``NeighborhoodType: Spherical`` QuickGrid (``TensorProduct3DMeshGenerator``,
    ``NoOpNormFunction``) bonds every cell within the one-sided cell horizons
    ``reach(δ / h_a)`` (``Spec1D::getCellNeighborhoodSize``) on each axis ``a``: a box of
    cells, whose corners may lie farther than δ.
    """
    origin, cell, counts = cube
    reach = np.array(
        [_cell_reach(horizon, float(c), int(n)) for c, n in zip(cell, counts, strict=True)]
    )

    def exclude(xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
        a = np.floor((xi - origin) / cell)
        b = np.floor((xj - origin) / cell)
        return np.any(np.abs(a - b) > reach, axis=1)

    radius = float(np.linalg.norm(reach * cell)) * (1 + 1e-9)
    return max(radius, 1e-300), exclude


def _chained_solvers(root: Mapping[str, Any], solvers: list[str], base: Path, name: str) -> Scene:
    """Build the Verlet scene of a deck that runs a quasi-static solver, then ``Verlet``.

    Peridigm's ``executeSolvers`` runs ``Solver1``, ``Solver2`` in turn on the same state;
    its quasi-static solver leaves the velocity ``Δu / Δt`` of its last load step
    (``executeQuasiStatic``), from which the Verlet solver continues.  pdlin solves the
    quasi-static part here (Newton, Peridigm's finite kinematics) and starts the explicit
    run from its final displacement and that velocity.
    """
    from ...nonlinear import solve_nonlinear

    kinds = [
        next((k for k in ("QuasiStatic", "NOXQuasiStatic", "Verlet") if k in root[s]), None)
        if isinstance(root[s], Mapping)
        else None
        for s in solvers
    ]
    if (
        len(solvers) != 2
        or kinds[0] not in ("QuasiStatic", "NOXQuasiStatic")
        or kinds[1] != "Verlet"
    ):
        raise SceneError(
            f"Peridigm.{solvers[0]}: several solvers are supported as a quasi-static solver "
            "followed by a Verlet solver ('Solver1', 'Solver2'), got "
            f"{dict(zip(solvers, kinds, strict=True))}"
        )
    rest = {k: v for k, v in root.items() if k not in solvers}
    qs = _peridigm({**rest, "Solver": root[solvers[0]]}, base, name, "finite")
    if qs.nonlinear is None or len(qs.nonlinear["times"]) < 2:
        raise SceneError(
            f"Peridigm.{solvers[0]}: the quasi-static solver before Verlet needs two or more "
            "load steps with Peridigm's finite kinematics (its final velocity)"
        )
    res = solve_nonlinear(qs.problem, **qs.nonlinear)
    t_end = float(qs.time)  # Final Time of the quasi-static solver (s = t / t_end)
    s = qs.nonlinear["times"]
    dt = (s[-1] - s[-2]) * t_end  # the last load step, in Peridigm's time
    scene = _peridigm({**rest, "Solver": root[solvers[1]]}, base, name)
    ex = scene.explicit
    assert ex is not None
    if np.any(ex["u0"]) or np.any(ex["v0"]):
        raise SceneError(
            "Boundary Conditions: initial conditions are not supported with chained solvers"
        )
    # in place: the prescribed paths of the Verlet scene start from this u0 (peridigm_verlet)
    ex["u0"][...] = res.u[-1]
    ex["v0"][...] = (res.u[-1] - res.u[-2]) / dt
    _note(f"Peridigm.{solvers[0]}", f"solved when the deck is read ({res.u.shape[0] - 1} steps)")
    return scene


def _plastic_material(mat: Any) -> bool:
    """Return whether a material is ``Elastic Plastic`` with plasticity (a history state)."""
    return (
        isinstance(mat, Mapping)
        and mat.get("Material Model") == "Elastic Plastic"
        and not _flag(mat.get("Disable Plasticity", False), "Disable Plasticity")
    )


def _peridigm_discretization_keys(disc: Mapping[str, Any]) -> str:
    """Check the keys of ``Discretization`` (not the cloud).

    Returns its ``Omit Bonds Between Blocks``: 'None' or 'All'.
    """
    if disc.get("Type") not in ("Text File", "Exodus", "PdQuickGrid"):  # name the cause first
        raise SceneError(
            "Discretization.Type must be 'Text File', 'Exodus' or 'PdQuickGrid' (pdlin's deck "
            f"reader), got {disc.get('Type')!r}"
        )
    if disc["Type"] != "PdQuickGrid":
        _unknown(disc, _PD_DISC, "Discretization", "Peridigm discretization")
    if "Construct Neighborhood Lists" in disc and not _flag(
        disc["Construct Neighborhood Lists"], "Discretization.Construct Neighborhood Lists"
    ):
        raise SceneError(
            "Discretization.Construct Neighborhood Lists: false (no bonds) is not supported"
        )
    omit = disc.get("Omit Bonds Between Blocks", "None")
    if omit not in ("None", "All"):
        raise SceneError(
            "Discretization.Omit Bonds Between Blocks must be 'None' (every block bonded to the "
            f"others, Peridigm's default) or 'All' (no bonds between blocks), got {omit!r}"
        )
    for k, why in _PD_DISC.items():
        if why and k in disc and disc["Type"] != "PdQuickGrid":
            _note(f"Discretization.{k}", why)
    return str(omit)


def _peridigm_blocks(
    root: Mapping[str, Any], default_h: Any, blocks_pts: Mapping[str, np.ndarray], n: int
) -> tuple[Any, np.ndarray, list[Block], np.ndarray | None, Any]:
    """Build the model, the per-point horizons, the scene's blocks and thermal coefficients.

    One material family with per-point constants (:func:`pdlin.scene.blocks_per_point`,
    as for a TOML scene's ``[[block]]`` tables); ``default_h`` is
    ``Discretization.Horizon``, if given.  The thermal expansion coefficients are None
    when no material has a ``Thermal Expansion Coefficient`` (0 on the points of those
    that have none).  Also returns the finite-kinematics model
    (:class:`~pdlin.models.PeridigmElasticPlastic`) of ``Elastic`` / ``Elastic Plastic``
    decks without thermal expansion, else None.
    """
    materials = _table(root["Materials"], "Materials")
    mats = {
        mname: _peridigm_material(mname, _table(m, f"Materials.{mname}"), f"Materials.{mname}")
        for mname, m in materials.items()
    }
    blocks: list[Block] = []
    alpha = np.zeros(n)
    yields = np.full(n, np.inf)  # Elastic and plasticity disabled: never yields
    hgs: set[float] = set()
    default: tuple[float, str, str] | None = None
    named: set[str] = set()

    def assign(bn: str, h: float, mname: str, key: str) -> None:
        mat = mats[mname]
        consts = {"K": mat["K"]} if mat["G"] is None else {"K": mat["K"], "G": mat["G"]}
        blocks.append(Block(bn, blocks_pts[bn], consts, mat["kind"], key, horizon=h))
        alpha[blocks_pts[bn]] = mat.get("alpha") or 0.0
        if mat.get("yield") is not None:
            yields[blocks_pts[bn]] = mat["yield"]
        if mat["hourglass"] is not None:
            hgs.add(mat["hourglass"])

    for bname, b in _table(root["Blocks"], "Blocks").items():
        key = f"Blocks.{bname}"
        b = _table(b, key)
        _unknown(b, _PD_BLOCK, key, "Peridigm block")
        names = b.get("Block Names")
        if not isinstance(names, str) or not names.split():
            raise SceneError(
                f"{key}.Block Names must name blocks (e.g. 'block_1 block_2'), got {names!r}"
            )
        mname = b.get("Material")
        if mname not in mats:
            raise SceneError(
                f"{key}.Material: {mname!r} is not defined under Materials ({sorted(mats)})"
            )
        h = b.get("Horizon", default_h)
        if h is None:
            raise SceneError(f"missing deck key {key}.Horizon")
        if isinstance(h, str) and not NUMBER_TEXT.fullmatch(h.strip()):
            raise SceneError(
                f"{key}.Horizon: expressions for the horizon are not supported; give a number"
            )
        h = _number(h, f"{key}.Horizon", positive=True)
        for bn in names.split():
            if bn in ("Default", "default", "DEFAULT"):
                # Peridigm's initializeBlocks: the blocks no other entry names
                default = (h, mname, key)
                continue
            if bn not in blocks_pts:
                raise SceneError(
                    f"{key}.Block Names: {bn!r} is not in the discretization (blocks "
                    f"{sorted(blocks_pts)}; 'default' names the blocks no other entry names)"
                )
            named.add(bn)
            assign(bn, h, mname, key)
    if default is not None:
        for bn in blocks_pts:
            if bn not in named:
                assign(bn, *default)
    missing = [
        bn for bn, idx in blocks_pts.items() if idx.size and bn not in named and default is None
    ]
    if missing:
        raise SceneError(f"Blocks: discretization block(s) {missing} are not assigned to any block")
    kind, consts, horizon = blocks_per_point([b for b in blocks if b.points.size], n)
    K = np.broadcast_to(np.asarray(consts["K"], dtype=float), (n,))
    G = np.broadcast_to(np.asarray(consts.get("G", np.nan), dtype=float), (n,))
    assert horizon is not None  # every Peridigm block has one
    thermal = any(m.get("alpha") is not None for m in mats.values())
    model = _build_model(kind, K, G, hgs, "Materials")
    # Peridigm's Elastic / Elastic Plastic with their own kinematics; PeridigmElasticPlastic
    # has no thermal strain, so a deck with thermal expansion stays linearized
    if thermal and np.isfinite(yields).any():  # Peridigm_ElasticPlasticMaterial.cpp refuses it
        raise SceneError(
            "Materials: 'Elastic Plastic' with plasticity does not take a Thermal Expansion "
            "Coefficient (Peridigm refuses it too)"
        )
    finite = None
    if kind == "lps" and not thermal:
        from ...models.peridigm_state import PeridigmElasticPlastic

        def one(a: np.ndarray) -> Any:
            return float(a[0]) if np.all(a == a[0]) else np.array(a)

        finite = PeridigmElasticPlastic(
            K=one(K), G=one(G), yield_stress=one(yields), horizon=one(horizon)
        )
    elif kind == "correspondence" and not thermal:
        try:  # one set of moduli and one hourglass coefficient (else linearized only)
            finite = peridigm_correspondence_model(K, G, hgs, "Materials")
        except SceneError:
            finite = None
    return model, horizon, blocks, alpha if thermal else None, finite


def _plastic(model: Any) -> bool:
    """Whether a finite-kinematics deck model can yield (a finite ``Yield Stress``)."""
    return model is not None and bool(np.isfinite(getattr(model, "yield_stress", np.inf)).any())


def _finite_kinematics(kinematics: str, finite_model: Any, n_steps: int) -> bool:
    """Whether the deck runs Peridigm's finite-kinematics material (``solve_nonlinear``).

    ``'auto'``: with plasticity (a finite ``Yield Stress``) or several load steps of an
    ``Elastic`` / ``Elastic Plastic`` deck; ``'finite'`` / ``'linear'`` as asked.
    """
    if kinematics not in KINEMATICS:
        raise SceneError(f"kinematics must be one of {list(KINEMATICS)}, got {kinematics!r}")
    plastic = _plastic(finite_model)
    if kinematics == "linear":
        if plastic:
            raise SceneError(
                "Materials: 'Elastic Plastic' with plasticity needs kinematics 'finite' or "
                "'auto' (pdlin runs Peridigm's plasticity with its finite kinematics); got "
                "'linear'"
            )
        return False
    if kinematics == "finite" and finite_model is None:
        raise SceneError(
            "kinematics 'finite' is available for Peridigm's 'Elastic', 'Elastic Plastic' and "
            "'Elastic Correspondence' materials (one set of correspondence moduli, no thermal "
            "expansion); this deck is solved linearized (use 'auto' or 'linear')"
        )
    return finite_model is not None and (kinematics == "finite" or plastic or n_steps > 1)


def _loads_not_proportional(
    bcs: Any, sets: Mapping[str, np.ndarray], cloud: PointCloud, times: list[float]
) -> bool:
    """Whether some body force is not ``t / Final Time`` times its final value at a step.

    ``solve_nonlinear`` scales loads proportionally and cannot follow such a load.
    """
    _, final = _peridigm_bcs(bcs, sets, cloud, times[-1])
    for t in times[1:-1] if final else []:
        for a, b in zip(_peridigm_bcs(bcs, sets, cloud, t)[1], final, strict=True):
            if not np.allclose(a.density, (t / times[-1]) * np.asarray(b.density), rtol=1e-12):
                return True
    return False


def _finite_scene(
    name: str,
    model: Any,
    cloud: PointCloud,
    horizon: np.ndarray,
    bcs: Any,
    sets: Mapping[str, np.ndarray],
    times: list[float],
    opts: dict[str, Any],
    base: Path,
    output: Path | None,
) -> Scene:
    """Build the scene Peridigm solves: Newton on the finite-kinematics force per step.

    The prescribed displacements are evaluated at each step's time (``TimePath`` of
    ``s = t / Final Time``, so that ``pdlin.solve(scene.problem)`` is at Final Time and
    ``scene.nonlinear["times"]`` are the steps' ``s``); body forces scale with ``s`` in
    :func:`pdlin.solve_nonlinear`, so a deck whose body force is not proportional to ``t``
    over its steps is refused.
    """
    from ...operators.bc import TimePath

    t_end = times[-1]
    dirichlet_end, loads = _peridigm_bcs(bcs, sets, cloud, t_end)
    if not dirichlet_end and not loads:
        dirichlet: list[Dirichlet] = [Dirichlet(np.arange(cloud.n), np.zeros((cloud.n, 3)))]
    else:
        dirichlet = []
        cache: dict[float, list[Dirichlet]] = {t_end: dirichlet_end}

        def at(t: float) -> list[Dirichlet]:
            if t not in cache:  # every condition of a step evaluated once
                cache[t] = _peridigm_bcs(bcs, sets, cloud, t)[0]
            return cache[t]

        for k, d in enumerate(dirichlet_end):

            def path(_x: np.ndarray, s: float, k: int = k) -> np.ndarray:
                # s = t / Final Time: a linear solve of the problem (s = 1) is at Final Time
                return np.asarray(at(t_end if s == 1.0 else float(s) * t_end)[k].value)

            dirichlet.append(
                Dirichlet(d.where, TimePath(path, f"deck value {k}"), components=d.components)
            )
    for t in times[1:-1]:
        _, lt = _peridigm_bcs(bcs, sets, cloud, t)
        for a, b in zip(lt, loads, strict=True):
            if not np.allclose(a.density, (t / t_end) * np.asarray(b.density), rtol=1e-12):
                raise SceneError(
                    "Boundary Conditions: a Body Force that is not proportional to t over the "
                    "load steps is not supported with finite kinematics (pdlin scales loads "
                    f"with t / Final Time); at t = {t} it is not"
                )
    scene = _scene(name, model, cloud, horizon, dirichlet, loads, base, output, opts)
    scene.time = t_end
    # the load path in s = t / Final Time (see path above); pdlin run writes Peridigm's times
    solve_times = [t / t_end for t in times[1:] if t > 0]
    # the first-order tangent predictor: the one verified on every finite deck against its
    # gold file; the second-order start stalls at Compression_QS_CyclicLoading's last step
    # (|u| ~ 2e-10, where the relative residual test sits at the force's round-off)
    scene.nonlinear = {
        "method": "newton", "times": solve_times, "t_end": 1.0, "predictor": "tangent",
    }  # fmt: skip
    scene.steps = [(t, scene.problem) for t in times]
    return scene


def _peridigm_output(root: Mapping[str, Any], base: Path, name: str) -> Path | None:
    """Return the result path of a deck's ``Output`` list (``None``: pdlin's default)."""
    if "Output" not in root:
        return None
    output = None
    out = _table(root["Output"], "Output")
    _unknown(out, _PD_OUTPUT, "Output", "Peridigm output")
    for k, why in _PD_OUTPUT.items():
        if why and k in out:
            _note(f"Output.{k}", why)
    suffix = ".vtu"
    if "Output File Type" in out:
        # Peridigm's OutputManagerContainer knows one type
        if out["Output File Type"] != "ExodusII":
            raise SceneError(
                "Output.Output File Type must be 'ExodusII', got "
                f"{out['Output File Type']!r} (Peridigm's only output type; pdlin then "
                "writes <Output Filename>.e)"
            )
        suffix = ".e"
        if "Output Filename" not in out:
            output = _output_inside(base, name, "the deck's name", suffix)
    if "Output Filename" in out:
        output = _output_inside(base, out["Output Filename"], "Output.Output Filename", suffix)
    return output


def _build_model(kind: str, K: np.ndarray, G: np.ndarray, hgs: set[float], key: str) -> Any:
    from ...models import LPS, BondBased, Correspondence

    def one(a: np.ndarray) -> Any:
        return float(a[0]) if np.all(a == a[0]) else a

    if kind == "bond_based":
        return BondBased(K=one(K))
    if kind == "lps":
        return LPS(K=one(K), G=one(G), peridigm=True)
    if len(hgs) != 1:
        raise SceneError(
            f"{key}: all correspondence blocks must share one Hourglass Coefficient, "
            f"got {sorted(hgs)}"
        )
    hg = next(iter(hgs))  # not popped: the finite-kinematics model reads the set too
    if hg == 0:
        return Correspondence(K=one(K), G=one(G), control="none")
    pen = peridigm_hourglass_penalty(hg, K, G)
    if not np.allclose(pen, pen[0], rtol=1e-12):
        raise SceneError(
            f"{key}: correspondence blocks with different K/G give different hourglass penalties; "
            "pdlin's penalty control takes one coefficient"
        )
    return Correspondence(K=one(K), G=one(G), control="penalty", penalty=float(pen[0]))


def peridigm_correspondence_model(K: Any, G: Any, hgs: set[float], key: str) -> Any:
    """Return Peridigm's ``Elastic Correspondence`` with its own finite kinematics.

    :class:`pdlin.models.correspondence.PeridigmCorrespondence`: Peridigm's hypoelastic
    stress update and its hourglass force (``correspondence.cxx``), for
    :func:`pdlin.solve_nonlinear` (one load step per Peridigm load step).  The arguments
    are those of the linear mapping (the per-point moduli and the blocks' hourglass
    coefficients).

    Parameters
    ----------
    K, G : float or (n,) array_like
        Bulk and shear modulus (one value: Peridigm's material constants).
    hgs : set of float
        The blocks' ``Hourglass Coefficient`` (one value).
    key : str
        Deck key path for messages.

    Returns
    -------
    PeridigmCorrespondence

    Raises
    ------
    SceneError
        Several moduli or hourglass coefficients.

    Examples
    --------
    >>> m = peridigm_correspondence_model(1.6e11, 7.7e10, {0.04}, "Materials")
    >>> m.hourglass, m.nonlinear
    (0.04, True)
    """
    from ...models.correspondence import PeridigmCorrespondence

    k_arr, g_arr = np.atleast_1d(np.asarray(K, float)), np.atleast_1d(np.asarray(G, float))
    if np.ptp(k_arr) or np.ptp(g_arr) or len(hgs) != 1:
        raise SceneError(
            f"{key}: Peridigm's finite-kinematics 'Elastic Correspondence' takes one material "
            f"(one K, G and Hourglass Coefficient), got {np.unique(k_arr).size} K, "
            f"{np.unique(g_arr).size} G and hourglass coefficients {sorted(hgs)}"
        )
    return PeridigmCorrespondence(
        K=float(k_arr[0]), G=float(g_arr[0]), hourglass=float(next(iter(hgs)))
    )


def _peridigm_node_sets(
    bcs: Any, base: Path, n: int, mesh_sets: Mapping[str, np.ndarray]
) -> dict[str, np.ndarray]:
    sets = dict(mesh_sets)
    for k, v in _table(bcs, "Boundary Conditions").items():
        if "NODE_SET" in _tidy(k):
            key = f"Boundary Conditions.{k}"
            if _tidy(k) in sets:
                raise SceneError(f"{key}: duplicate node set {_tidy(k)!r}")
            sets[_tidy(k)] = _node_ids(v, base, key, n)
    return sets


def _peridigm_solver(solver: Any) -> list[float]:
    """Check the solver keys; return Peridigm's step times (``Peridigm.cpp``).

    ``Final Time`` with ``Number of Load Steps N``: ``t0`` and ``t0 + (i + 1) (t1 - t0) / N``;
    else the ``Time Steps`` list; ``Final Time`` alone: ``[t0, t1]`` (one solve at ``t1``).
    """
    s = _table(solver, "Solver")
    _unknown(s, _PD_SOLVER, "Solver", "Peridigm solver (static subset)")
    kinds = [k for k in ("QuasiStatic", "NOXQuasiStatic") if k in s]
    if len(kinds) != 1:
        raise SceneError(
            f"Solver needs exactly one of 'QuasiStatic' or 'NOXQuasiStatic' (pdlin solves statics; "
            f"Verlet / Implicit dynamics are not supported), got {kinds or 'none'}"
        )
    skey = f"Solver.{kinds[0]}"
    sub = _table(s[kinds[0]], skey)
    allowed = _PD_QS if kinds[0] == "QuasiStatic" else _PD_NOX
    _unknown(sub, allowed, skey, f"Peridigm {kinds[0]} solver")
    for k in s:
        if _PD_SOLVER[k] and k != "Verbose":
            _note(f"Solver.{k}", _PD_SOLVER[k])
    for k in sub:
        _note(f"{skey}.{k}", allowed[k])
    adaptive = sub.get("Adaptive Load-Stepping")
    if isinstance(adaptive, Mapping) and "Switch to Verlet" in adaptive:
        raise SceneError(
            f"{skey}.Adaptive Load-Stepping.Switch to Verlet: explicit dynamics is not supported"
        )
    if "Number of Load Steps" in sub:
        steps = sub["Number of Load Steps"]
        if isinstance(steps, str) and re.fullmatch(r"\s*\d+\s*", steps):
            steps = int(steps)
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise SceneError(f"{skey}.Number of Load Steps must be an integer >= 1, got {steps!r}")
    t0 = _number(s.get("Initial Time", 0.0), "Solver.Initial Time")
    # Peridigm's order: Final Time with Number of Load Steps, else the Time Steps list
    if "Time Steps" in sub and not ("Final Time" in s and "Number of Load Steps" in sub):
        text = sub["Time Steps"]
        times = str(text).split()
        if not times or not all(NUMBER_TEXT.fullmatch(v) for v in times):
            raise SceneError(
                f"{skey}.Time Steps must be a list of times separated by spaces, got {text!r}"
            )
        tt = [float(v) for v in times]
        if not np.all(np.isfinite(tt)) or np.any(np.diff(tt) <= 0) or len(tt) < 2:
            raise SceneError(
                f"{skey}.Time Steps must be two or more finite, increasing times, got {text!r}"
            )
        return tt
    if "Final Time" not in s:
        raise SceneError("missing deck key Solver.Final Time")
    t1 = _number(s["Final Time"], "Solver.Final Time")
    if t1 <= t0:
        raise SceneError(f"Solver.Final Time must exceed Initial Time ({t0}), got {t1}")
    if "Number of Load Steps" not in sub:
        return [t0, t1]
    n = int(steps)
    return [t0, *(t0 + np.arange(1, n + 1) * (t1 - t0) / n).tolist()]


def _bc_points(set_name: Any, sets: Mapping[str, np.ndarray], n: int, key: str) -> np.ndarray:
    if not isinstance(set_name, str):
        raise SceneError(f"{key} must name a node set, got {set_name!r}")
    tid = _tidy(set_name)
    if tid == "FULL_DOMAIN":
        return np.arange(n)
    if tid == "ALL_SETS":
        if not sets:
            raise SceneError(f"{key}: 'All Sets' but the deck defines no node sets")
        return np.unique(np.concatenate(list(sets.values())))
    if tid not in sets:
        raise SceneError(f"{key}: node set {set_name!r} not found; defined: {sorted(sets)}")
    return sets[tid]


def _peridigm_bcs(
    bcs: Any, sets: Mapping[str, np.ndarray], cloud: PointCloud, t: float
) -> tuple[list[Dirichlet], list[BodyForce]]:
    dirichlet: list[Dirichlet] = []
    loads: list[BodyForce] = []
    for k, v in _table(bcs, "Boundary Conditions").items():
        key = f"Boundary Conditions.{k}"
        if "NODE_SET" in _tidy(k):
            continue
        if k == "Create Node Set For Rank Deficient Nodes":
            _note(key, "damage option")
            continue
        bc = _table(v, key)
        _unknown(bc, _PD_BC, key, "Peridigm boundary condition")
        typ = _tidy(str(bc.get("Type", "")))
        if typ == "PRESCRIBED_TEMPERATURE":
            continue  # the temperature change of thermal strains: _peridigm_temperature
        if typ not in ("PRESCRIBED_DISPLACEMENT", "BODY_FORCE"):
            raise SceneError(
                f"{key}.Type: {bc.get('Type')!r} is not supported; supported: "
                "'Prescribed Displacement', 'Body Force', 'Prescribed Temperature' (initial "
                "conditions, velocities, initial temperatures and fluxes are dynamics / "
                "multiphysics)"
            )
        if "Node Set" not in bc:
            raise SceneError(f"missing deck key {key}.Node Set")
        idx = _bc_points(bc["Node Set"], sets, cloud.n, f"{key}.Node Set")
        coord = str(bc.get("Coordinate", "x"))
        if _tidy(coord) not in _COORD:
            raise SceneError(f"{key}.Coordinate must be x, y or z, got {coord!r}")
        c = _COORD[_tidy(coord)]
        if "Value" not in bc:
            raise SceneError(f"missing deck key {key}.Value")
        # Peridigm's function parser (RTCompiler) reads ^ as the power
        val = deck_expression(bc["Value"], cloud.points[idx], t, f"{key}.Value", caret_power=True)
        if typ == "PRESCRIBED_DISPLACEMENT":
            dirichlet.append(Dirichlet(idx, val[:, None], components=[c]))
        else:
            dens = np.zeros((idx.size, cloud.dim))
            dens[:, c] = val
            loads.append(BodyForce(idx, dens))
    return dirichlet, loads


def _peridigm_temperature(
    bcs: Any, sets: Mapping[str, np.ndarray], cloud: PointCloud, t: float, initial: bool
) -> np.ndarray | None:
    """Return the ``Temperature_Change`` field at time ``t`` (None without a temperature BC).

    Peridigm's ``Prescribed Temperature`` sets the temperature and, through a
    ``DirichletIncrementBC`` relative to the initial value, the change
    ``ΔT = T(t) - T(t = 0)`` on its node set (``Peridigm_BoundaryAndInitialConditionManager``
    and ``Peridigm_BoundaryCondition.cpp``: ``timePrevious_ = 0.0``); the field is 0 on other
    points and at the initial time (the increment is not applied when the times are equal).
    """
    dT: np.ndarray | None = None
    for k, v in _table(bcs, "Boundary Conditions").items():
        if "NODE_SET" in _tidy(k) or not isinstance(v, Mapping):
            continue
        if _tidy(str(v.get("Type", ""))) != "PRESCRIBED_TEMPERATURE":
            continue
        key = f"Boundary Conditions.{k}"
        if "Node Set" not in v:
            raise SceneError(f"missing deck key {key}.Node Set")
        if "Value" not in v:
            raise SceneError(f"missing deck key {key}.Value")
        idx = _bc_points(v["Node Set"], sets, cloud.n, f"{key}.Node Set")
        if dT is None:
            dT = np.zeros(cloud.n)
        if initial:
            continue
        pts = cloud.points[idx]
        now = deck_expression(v["Value"], pts, t, f"{key}.Value", caret_power=True)
        start = deck_expression(v["Value"], pts, 0.0, f"{key}.Value", caret_power=True)
        dT[idx] = now - start
    return dT


def _with_thermal(problem: Any, alpha: np.ndarray | None, dT: np.ndarray | None) -> Any:
    """Return the problem with its thermal eigenstrain (unchanged without alpha or change)."""
    import dataclasses

    from ...models.thermal import ThermalExpansion

    if alpha is None or dT is None:
        return problem
    a: Any = float(alpha[0]) if np.all(alpha == alpha[0]) else alpha
    t: Any = float(dT[0]) if np.all(dT == dT[0]) else dT
    try:
        return dataclasses.replace(problem, thermal=ThermalExpansion(t, a))
    except PdlinError as exc:
        raise SceneError(f"invalid deck (thermal expansion): {exc}") from exc
