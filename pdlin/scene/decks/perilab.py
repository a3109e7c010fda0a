"""PeriLab.jl input decks (YAML, static subset) read into a pdlin scene.

A material per block (one model type), linear elastic (``PD Solid Elastic`` as pdlin's LPS,
``Bond-based Elastic``, ``Correspondence Elastic``), displacement conditions evaluated
at ``Final Time``.  Sources of the format (read, not copied): PeriLab.jl
``examples/Dogbone/Dogbone.yaml``, ``Dogbone_plastic_corr_static.yaml``, ``Dogbone.txt``
(``header: x y block_id volume``) and ``ns_Dogbone_2.txt``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import PdlinError, SceneError
from ...geometry.cloud import PointCloud
from ...operators.bc import Dirichlet
from ..materials import Block, blocks_per_point
from ..scene import Scene
from ._common import (
    _COORD,
    _ELASTIC_CONSTANTS,
    _cloud,
    _constants,
    _flag,
    _node_ids,
    _note,
    _number,
    _read_text,
    _read_text_table,
    _resolve_file,
    _scene,
    _table,
    _unknown,
    log,
)
from .expressions import deck_expression

# --------------------------------------------------------------------------------------
# PeriLab
# --------------------------------------------------------------------------------------
_PL_TOP = {
    "Discretization": "",
    "Models": "",
    "Blocks": "",
    "Boundary Conditions": "",
    "Solver": "",
    "Outputs": "pdlin writes all of its fields",
    "Compute Class Parameters": "output computations",
}
_PL_DISC = {"Type": "", "Input Mesh File": "", "Node Sets": ""}
_PL_MODELS = {
    "Material Models": "",
    "Damage Models": "definitions only (a block using one is an error)",
    "Pre Calculation": "PeriLab bookkeeping",
    "Pre Calculation Global": "PeriLab bookkeeping",
}
_PL_MATERIAL = {
    "Material Model": "",
    "Symmetry": "",
    "Bulk Modulus": "",
    "Shear Modulus": "",
    "Young's Modulus": "",
    "Poisson's Ratio": "",
}
_PL_KINDS = {
    "PD Solid Elastic": "lps",
    "Correspondence Elastic": "correspondence",
    "Bond-based Elastic": "bond_based",
}
_PL_BLOCK = {"Block ID": "", "Horizon": "", "Material Model": "", "Density": "dynamics only"}
_PL_BC = {"Variable": "", "Coordinate": "", "Node Set": "", "Value": "", "Type": ""}
_PL_SOLVER = {
    "Initial Time": "",
    "Final Time": "",
    "Static": "",
    "Material Models": "PeriLab switch (must be true)",
    "Damage Models": "PeriLab switch (must be false)",
    "Number of Steps": "a linear model's final state is one solve at Final Time",
    "Numerical Damping": "dynamics only",
}
_PL_STATIC = {
    "NLsolver": "nonlinear-solver switch (one linear solve here)",
    "Show solver iteration": "cosmetic",
    "Residual tolerance": "pdlin checks its own residual",
    "Solution tolerance": "pdlin checks its own residual",
    "Linear Start Value": "initial guess (one direct linear solve here)",
    "Residual scaling": "solver scaling",
    "m": "Anderson memory of PeriLab's solver",
    "Maximum number of iterations": "one linear solve here",
}


def _perilab(deck: Mapping[str, Any], base: Path, name: str) -> Scene:
    """Read the scene of a PeriLab deck (the body of its top-level ``PeriLab`` list)."""
    root = _table(deck, "PeriLab")
    _unknown(root, _PL_TOP, "PeriLab", "PeriLab deck")
    for k in ("Discretization", "Models", "Blocks", "Boundary Conditions", "Solver"):
        if k not in root:
            raise SceneError(f"missing deck key PeriLab.{k}")
    for k in ("Outputs", "Compute Class Parameters"):
        if k in root:
            _note(f"PeriLab.{k}", _PL_TOP[k])
    cloud, block_id, sets, mesh = _perilab_mesh(root["Discretization"], base)
    dim = cloud.dim
    mats = _perilab_materials(root["Models"], dim)
    horizon, kind, consts, blocks = _perilab_blocks(root["Blocks"], block_id, mats, mesh)
    try:
        model = _perilab_model(kind, consts, dim)
    except SceneError:
        raise
    except PdlinError as exc:
        raise SceneError(f"Models.Material Models: {exc}") from None
    t = _perilab_solver(root["Solver"])
    dirichlet = _perilab_bcs(root["Boundary Conditions"], sets, cloud, t)
    scene = _scene(name, model, cloud, horizon, dirichlet, [], base, None)
    scene.time = t  # the state at Final Time
    scene.blocks = blocks
    return scene


def _perilab_mesh(
    value: Any, base: Path
) -> tuple[PointCloud, np.ndarray, dict[str, np.ndarray], Path]:
    """``Discretization``: the cloud, each point's block id, the node sets, the mesh file."""
    disc = _table(value, "Discretization")
    _unknown(disc, _PL_DISC, "Discretization", "PeriLab discretization")
    if disc.get("Type") != "Text File":
        raise SceneError(
            f"Discretization.Type must be 'Text File' for PeriLab decks, got {disc.get('Type')!r}"
        )
    path = _resolve_file(disc.get("Input Mesh File"), base, "Discretization.Input Mesh File")
    header = next(
        (
            ln.strip()[len("header:") :].split()
            for ln in _read_text(path, "Discretization.Input Mesh File").splitlines()
            if ln.strip().startswith("header:")
        ),
        None,
    )
    if header is None:
        raise SceneError(
            f"Discretization.Input Mesh File: {path.name} has no 'header: x y ...' line"
        )
    want2 = ["x", "y", "block_id", "volume"]
    want3 = ["x", "y", "z", "block_id", "volume"]
    if header not in (want2, want3):
        raise SceneError(
            f"Discretization.Input Mesh File: header must be {' '.join(want2)!r} or "
            f"{' '.join(want3)!r} (extra columns are not supported), got {' '.join(header)!r}"
        )
    data = _read_text_table(path, "Discretization.Input Mesh File", (len(header),))
    dim = len(header) - 2
    cloud = _cloud(data[:, :dim], data[:, dim + 1], "Discretization.Input Mesh File")
    sets: dict[str, np.ndarray] = {}
    for sname, v in _table(disc.get("Node Sets", {}), "Discretization.Node Sets").items():
        sets[sname] = _node_ids(v, base, f"Discretization.Node Sets.{sname}", cloud.n)
    return cloud, data[:, dim], sets, path


def _perilab_materials(value: Any, dim: int) -> dict[str, dict[str, Any]]:
    """``Models``: each material's kind, elastic constants and plane."""
    models = _table(value, "Models")
    _unknown(models, _PL_MODELS, "Models", "PeriLab models")
    for k in models:
        if _PL_MODELS[k]:
            _note(f"Models.{k}", _PL_MODELS[k])
    mats: dict[str, dict[str, Any]] = {}
    for mname, m in _table(models.get("Material Models", {}), "Models.Material Models").items():
        key = f"Models.Material Models.{mname}"
        m = _table(m, key)
        _unknown(m, _PL_MATERIAL, key, "PeriLab material")
        kind = m.get("Material Model")
        if kind not in _PL_KINDS:
            raise SceneError(
                f"{key}.Material Model: {kind!r} is not supported; supported: {sorted(_PL_KINDS)} "
                "(combined models 'A+B' and plastic / damage models are nonlinear)"
            )
        sym = str(m.get("Symmetry", "isotropic")).strip().lower()
        planes = {
            "isotropic": None,
            "isotropic plane strain": "strain",
            "isotropic plane stress": "stress",
        }
        if sym not in planes:
            raise SceneError(
                f"{key}.Symmetry must be one of {sorted(planes)}, got {m.get('Symmetry')!r}"
            )
        plane = planes[sym]
        if (dim == 2) != (plane is not None):
            raise SceneError(
                f"{key}.Symmetry: {sym!r} does not fit the {dim}D mesh (2D meshes need "
                "'isotropic plane strain' or 'isotropic plane stress', 3D ones 'isotropic')"
            )
        consts = _constants(m, key, exactly=None)
        if _PL_KINDS[kind] != "bond_based" and len(consts) != 2:
            raise SceneError(f"{key} needs exactly two of {list(_ELASTIC_CONSTANTS)}")
        mats[mname] = {"kind": _PL_KINDS[kind], "consts": consts, "plane": plane or "stress"}
    return mats


def _perilab_blocks(
    value: Any, block_id: np.ndarray, mats: Mapping[str, dict[str, Any]], mesh: Path
) -> tuple[np.ndarray, str, dict[str, Any], list[Block]]:
    """``Blocks``: per-point horizons, the model type and constants, the scene's blocks.

    Each block may use its own material (one model type for all: pdlin assembles one
    stiffness matrix), mapped onto the points by :func:`pdlin.scene.blocks_per_point`,
    as a TOML scene's ``[[block]]`` tables.
    """
    blocks: list[Block] = []
    for bname, b in _table(value, "Blocks").items():
        key = f"Blocks.{bname}"
        b = _table(b, key)
        if "Damage Model" in b:
            raise SceneError(f"{key}.Damage Model: damage is not supported by pdlin's deck reader")
        _unknown(b, _PL_BLOCK, key, "PeriLab block")
        bid = b.get("Block ID")
        if bid is None:
            m_ = re.fullmatch(r"block_(\d+)", bname)
            if not m_:
                raise SceneError(f"{key}: give 'Block ID' or name the block 'block_<id>'")
            bid = int(m_.group(1))
        idx = np.flatnonzero(block_id == bid)
        if idx.size == 0:
            raise SceneError(f"{key}: block id {bid} has no points in {mesh.name}")
        pl_mat = b.get("Material Model")
        if pl_mat not in mats:
            raise SceneError(f"{key}.Material Model: {pl_mat!r} is not defined ({sorted(mats)})")
        h = _number(b.get("Horizon"), f"{key}.Horizon", positive=True)
        mat = mats[str(pl_mat)]
        consts = {**mat["consts"], "plane": mat["plane"]}
        blocks.append(Block(bname, idx, consts, mat["kind"], key, horizon=h))
    covered = np.zeros(block_id.shape[0], dtype=bool)
    for blk in blocks:
        covered[blk.points] = True
    if not covered.all():
        ids = sorted({int(v) for v in block_id[~covered]})
        raise SceneError(f"Blocks: block id(s) {ids} of the mesh are not assigned to a block")
    kind, consts, horizon = blocks_per_point(blocks, block_id.shape[0])
    assert horizon is not None  # every PeriLab block has one
    return horizon, kind, consts, blocks


def _perilab_solver(value: Any) -> float:
    """``Solver``: checks of the static subset; the ``Final Time`` the state is solved at."""
    s = _table(value, "Solver")
    _unknown(s, _PL_SOLVER, "Solver", "PeriLab solver (static subset)")
    if "Static" not in s:
        raise SceneError(
            "Solver needs 'Static' (pdlin solves statics; 'Verlet' dynamics is not supported)"
        )
    st = _table(s["Static"], "Solver.Static")
    _unknown(st, _PL_STATIC, "Solver.Static", "PeriLab static solver")
    if "Damage Models" in s and _flag(s["Damage Models"], "Solver.Damage Models"):
        raise SceneError("Solver.Damage Models: true is not supported (damage)")
    if "Material Models" in s and not _flag(s["Material Models"], "Solver.Material Models"):
        raise SceneError("Solver.Material Models: false (no material forces) is not supported")
    for k in s:
        if _PL_SOLVER[k] and k not in ("Material Models", "Damage Models"):
            _note(f"Solver.{k}", _PL_SOLVER[k])
    for k in st:
        _note(f"Solver.Static.{k}", _PL_STATIC[k])
    if "Final Time" not in s:
        raise SceneError("missing deck key Solver.Final Time")
    return _number(s["Final Time"], "Solver.Final Time")


def _perilab_bcs(
    value: Any, sets: Mapping[str, np.ndarray], cloud: PointCloud, t: float
) -> list[Dirichlet]:
    """``Boundary Conditions``: prescribed displacements at time ``t``."""
    dim = cloud.dim
    dirichlet: list[Dirichlet] = []
    for bcname, bc in _table(value, "Boundary Conditions").items():
        key = f"Boundary Conditions.{bcname}"
        bc = _table(bc, key)
        _unknown(bc, _PL_BC, key, "PeriLab boundary condition")
        if bc.get("Variable") != "Displacements":
            raise SceneError(
                f"{key}.Variable: only 'Displacements' is supported, got {bc.get('Variable')!r}"
            )
        if bc.get("Type", "Dirichlet") != "Dirichlet":
            raise SceneError(f"{key}.Type: only 'Dirichlet' is supported, got {bc.get('Type')!r}")
        set_name: Any = bc.get("Node Set")
        if set_name not in sets:
            raise SceneError(
                f"{key}.Node Set: {set_name!r} is not under Discretization.Node Sets "
                f"({sorted(sets)})"
            )
        idx = sets[set_name]
        coord = str(bc.get("Coordinate", "x")).strip().upper()
        if coord not in _COORD or _COORD[coord] >= dim:
            raise SceneError(
                f"{key}.Coordinate must be one of {'xyz'[:dim]!r}, got {bc.get('Coordinate')!r}"
            )
        val = deck_expression(
            bc.get("Value", 0.0), cloud.points[idx], t, f"{key}.Value", caret_power=True
        )
        dirichlet.append(Dirichlet(idx, val[:, None], components=[_COORD[coord]]))
    return dirichlet


def _perilab_model(kind: str, consts: Mapping[str, Any], dim: int) -> Any:
    from ...models import LPS, BondBased, Correspondence

    c = {k: v for k, v in consts.items() if k != "plane"}
    plane = consts.get("plane", "stress")
    if kind == "bond_based":
        if len(c) == 1:
            return BondBased(**c, plane=plane)
        if "K" in c:
            return BondBased(K=c["K"], plane=plane)
        from ...constitutive import isotropic_constants  # per-point constants of blocks

        E, nu = isotropic_constants(**c)
        return BondBased(K=E / (3.0 * (1.0 - 2.0 * nu)), plane=plane)
    if kind == "lps":
        if dim == 2:
            log.warning(
                "PeriLab 'PD Solid Elastic' in 2D is read as pdlin's plane-%s LPS; PeriLab's 2D "
                "coefficients (Bobaru et al. 2016 section 6.3) are not verified to coincide",
                plane,
            )
        return LPS(**c, plane=plane, peridigm=True)
    return Correspondence(**c, plane=plane)
