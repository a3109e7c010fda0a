"""The ``[material]`` and ``[model]`` tables of scene files: the pdlin model they build.

Isotropic elastic constants (any two of E, nu, K, G, lam, mu, per phase), anisotropic
stiffness (correspondence), crystal plasticity (single crystal or a seeded polycrystal) and
bond micromoduli calibrated to a target tensor (``[material.calibration]``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import PdlinError, SceneError
from ..geometry.bonds import Bonds, find_bonds
from ..geometry.cloud import PointCloud
from ..models.base import Model
from ..models.bond_based import BondBased
from ._keys import number, require, scene_keys

__all__ = ["MODELS", "Block", "blocks_per_point", "per_phase"]

#: keys of a crystal-plasticity material table
_CP_KEYS = (
    "slip",
    "orientation",
    "elastic",
    "hardening",
    "shear",
    "polycrystal",
    "rate_exponent",
    "reference_rate",
)
_MATERIAL = {
    "type",
    *_CP_KEYS,
    "E",
    "nu",
    "K",
    "G",
    "lam",
    "mu",
    "plane",
    "micromodulus",
    "calibration",
    "stiffness",
    "density",  # mass density (explicit dynamics, pdlin.scene.explicit)
}
_POLYCRYSTAL = {"grains", "seed"}
#: isotropic constants a material table may give (any two; per phase tables allowed)
_ISO_KEYS = ("E", "nu", "K", "G", "lam", "mu")
_CALIBRATION = {
    "target",
    "method",
    "lower_bound",
    "weighting",
    "qp_solver",
    "boundary",
    "pair_rule",
}
_MODEL = {
    "type",
    "nu_mismatch",
    "average",
    "linearization",
    "weighted_volume",
    "peridigm",
    "fallback",
    "control",
    "penalty",
    "coefficient",
    "seed",
    "surface_correction",
}
_MODEL_KEYS = {
    "bond_based": {"type", "nu_mismatch", "average", "surface_correction"},
    "lps": {"type", "linearization", "weighted_volume", "peridigm", "surface_correction"},
    "xosb": {"type", "linearization", "weighted_volume", "fallback"},
    "correspondence": {"type", "control", "penalty", "coefficient", "seed"},
}


def _build_model(cfg: Mapping[str, Any], material: Mapping[str, Any], cloud: PointCloud) -> Model:
    mtype = material.get("type", "elastic")
    if mtype not in ("elastic", "crystal-plasticity"):
        raise SceneError(f"material.type must be 'elastic' or 'crystal-plasticity', got {mtype!r}")
    if mtype == "elastic":
        extra = [k for k in _CP_KEYS if k in material]
        if extra:
            raise SceneError(
                f"material.{extra[0]} is a crystal-plasticity key; set material.type = "
                "'crystal-plasticity' or remove it"
            )
    kind = cfg.get("type", "bond_based")
    if mtype == "crystal-plasticity" and kind != "correspondence":
        raise SceneError(
            "material.type = 'crystal-plasticity' needs model.type = 'correspondence', "
            f"got {kind!r}"
        )
    try:
        builder = MODELS[kind]
    except KeyError:
        raise SceneError(f"model.type must be one of {sorted(MODELS)}, got {kind!r}") from None
    if kind in _MODEL_KEYS:
        scene_keys(cfg, _MODEL_KEYS[kind], "model")
    return builder(cfg, material, cloud)


def _no_keys(material: Mapping[str, Any], keys: tuple[str, ...], kind: str) -> None:
    for k in keys:
        if k in material:
            raise SceneError(f"material.{k} is not used by model.type = {kind!r}")


def _state_based(kind: str) -> Callable[[Mapping[str, Any], Mapping[str, Any], PointCloud], Model]:
    def build(cfg: Mapping[str, Any], material: Mapping[str, Any], cloud: PointCloud) -> Model:
        from ..models import LPS, XOSB

        _no_keys(material, ("micromodulus", "stiffness"), kind)
        iso = _isotropic(material, cloud, kind)
        opts = {k: cfg[k] for k in cfg if k != "type"}
        cls = LPS if kind == "lps" else XOSB
        return cls(**iso, plane=material.get("plane", "stress"), **opts)

    return build


def _correspondence(
    cfg: Mapping[str, Any], material: Mapping[str, Any], cloud: PointCloud
) -> Model:
    from ..models import Correspondence
    from .targets import target_from_table

    _no_keys(material, ("micromodulus",), "correspondence")
    opts = {k: cfg[k] for k in cfg if k != "type"}
    if material.get("type") == "crystal-plasticity":
        return Correspondence(material=_crystal_plasticity(material, cloud), **opts)
    plane = material.get("plane", "stress")
    if "stiffness" in material:
        given = [k for k in _ISO_KEYS if k in material]
        if given:
            raise SceneError(
                f"material.stiffness and material.{given[0]} exclude each other "
                "(give a Voigt stiffness or isotropic constants)"
            )
        table = material["stiffness"]
        scale = table.get("scale") if isinstance(table, Mapping) else None
        if scale is not None:
            table = {k: v for k, v in table.items() if k != "scale"}
        C = target_from_table(table, "material.stiffness")
        if scale is None:
            return Correspondence(C, plane=plane, **opts)
        factor = per_phase(scale, cloud, "material.stiffness.scale")
        if not isinstance(scale, Mapping):
            raise SceneError(
                "material.stiffness.scale must be a table of per-phase factors "
                f'{{"0" = 1.0, "1" = 0.1}}, got {scale!r}'
            )
        phases = np.unique(np.asarray(cloud.material))
        by_phase = {int(p): float(factor[np.flatnonzero(cloud.material == p)[0]]) for p in phases}
        bad = {p: f for p, f in by_phase.items() if not (np.isfinite(f) and f > 0)}
        if bad:
            raise SceneError(f"material.stiffness.scale must be > 0 per phase, got {bad}")
        return Correspondence({p: f * C for p, f in by_phase.items()}, plane=plane, **opts)
    iso = _isotropic(material, cloud, "correspondence", minimum=1 if cloud.dim == 1 else 2)
    return Correspondence(**iso, plane=plane, **opts)


def _crystal_plasticity(material: Mapping[str, Any], cloud: PointCloud) -> Any:
    """``[material] type = "crystal-plasticity"``: slip systems, constants, orientations."""
    from ..constitutive.crystal_plasticity import CrystalPlasticity
    from ..geometry.polycrystal import voronoi_polycrystal

    bad = [k for k in _ISO_KEYS + ("plane", "stiffness", "micromodulus") if k in material]
    if bad:
        raise SceneError(
            f"material.{bad[0]} is not used by material.type = 'crystal-plasticity' (give "
            "material.elastic = {{...}} for the crystal's elastic constants)"
        )
    orientation: Any = material.get("orientation", 0.0)
    if "polycrystal" in material:
        if "orientation" in material:
            raise SceneError("material.orientation and material.polycrystal exclude each other")
        pc = scene_keys(material["polycrystal"], _POLYCRYSTAL, "material.polycrystal")
        grains = require(pc, "grains", "material.polycrystal")
        if isinstance(grains, bool) or not isinstance(grains, int) or grains < 1:
            raise SceneError(f"material.polycrystal.grains must be an integer >= 1, got {grains!r}")
        seed = int(pc.get("seed", 0))
        if "ghost" in cloud.sets:
            # grains on the real points; a ghost copies the orientation of its nearest one
            from scipy.spatial import cKDTree

            real = np.setdiff1d(np.arange(cloud.n), cloud.point_set("ghost"))
            _, ori_real = voronoi_polycrystal(cloud.points[real], grains, seed=seed)
            _, near = cKDTree(cloud.points[real]).query(cloud.points)
            orientation = ori_real[near]
        else:
            _, orientation = voronoi_polycrystal(cloud, grains, seed=seed)
    kw: dict[str, Any] = {}
    for key in ("elastic", "hardening", "shear", "rate_exponent", "reference_rate"):
        if key in material:
            kw[key] = material[key]
    return CrystalPlasticity(material.get("slip", "planar-2"), orientation=orientation, **kw)


def _isotropic(
    material: Mapping[str, Any], cloud: PointCloud, kind: str, *, minimum: int = 2
) -> dict[str, Any]:
    """Read the isotropic constants of a material table (E, nu, K, G, lam, mu; per phase).

    Fewer than ``minimum`` of them raise (the model checks the set further).
    """
    iso = {k: per_phase(material[k], cloud, f"material.{k}") for k in _ISO_KEYS if k in material}
    if len(iso) < minimum:
        raise SceneError(
            f"model.type = {kind!r} needs two isotropic constants in [material] "
            f"(E and nu, or K and G, or lam and mu, ...), got {sorted(iso) or 'none'}"
        )
    return iso


def per_phase(value: Any, cloud: PointCloud, key: str) -> Any:
    """Map a material constant given per phase onto the points.

    Tables are mapped onto points through ``cloud.material``; every phase
    present in the cloud must be listed.

    A constant is a number, or a table ``{"<phase id>" = value}`` mapped onto points
    through ``cloud.material``; every phase present in the cloud must be listed.

    Parameters
    ----------
    value : float or Mapping
        The constant as written in the scene.
    cloud : PointCloud
        The scene's points (``cloud.material`` holds each point's phase id).
    key : str
        The constant's key path for messages (``material.E``).

    Returns
    -------
    float or numpy.ndarray
        The number as given, or one value per point, shape ``(n,)``.

    Raises
    ------
    SceneError
        A value that is neither a number nor a table of phase ids to numbers, or a
        phase of the cloud missing from the table.
    """
    if isinstance(value, np.ndarray):  # per point already ([[block]] tables)
        return value
    if not isinstance(value, Mapping):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise SceneError(
                f"{key} must be a number or a table of per-phase numbers, got {value!r}"
            )
        return value
    try:
        table = {int(k): float(v) for k, v in value.items()}
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{key} table must map integer phase ids to numbers: {exc}") from exc
    mat = np.asarray(cloud.material)
    phases = np.unique(mat)
    missing = [int(p) for p in phases if int(p) not in table]
    if missing:
        raise SceneError(f"{key} has no value for phase(s) {missing} present in the geometry")
    lut = np.zeros(int(phases.max()) + 1)
    for k, v in table.items():
        if 0 <= k < lut.size:
            lut[k] = v
    return lut[mat]


def _bond_based(cfg: Mapping[str, Any], material: Mapping[str, Any], cloud: PointCloud) -> Model:
    iso = _isotropic(material, cloud, "bond_based", minimum=0)  # E, K, G or lam alone suffice
    return BondBased(
        **iso,
        plane=material.get("plane", "stress"),
        micromodulus=material.get("micromodulus"),
        average=cfg.get("average", "arithmetic"),
        nu_mismatch=cfg.get("nu_mismatch", "raise"),
        surface_correction=cfg.get("surface_correction"),
    )


#: model builders by scene name: ``builder(model_table, material_table, cloud) -> Model``
MODELS: dict[str, Callable[[Mapping[str, Any], Mapping[str, Any], PointCloud], Model]] = {
    "bond_based": _bond_based,
    "lps": _state_based("lps"),
    "xosb": _state_based("xosb"),
    "correspondence": _correspondence,
}


def _calibrated_model(
    material: Mapping[str, Any],
    model_cfg: Mapping[str, Any],
    cloud: PointCloud,
    horizon: Any,
    bond_options: Mapping[str, Any],
    has_symmetry: bool,
) -> tuple[Model, Bonds, Any]:
    """Bond-based model with micromoduli calibrated to ``material.calibration.target``."""
    from ..calibration import calibrate_micromoduli
    from .targets import target_from_table

    if model_cfg.get("type", "bond_based") != "bond_based":
        raise SceneError("material.calibration needs model.type = 'bond_based'")
    if has_symmetry:
        raise SceneError(
            "material.calibration cannot be combined with [[symmetry]] planes (per-bond "
            "micromoduli are calibrated on the part's own bonds)"
        )
    for key in ("E", "micromodulus"):
        if key in material:
            raise SceneError(f"material.{key} and material.calibration exclude each other")
    cal = scene_keys(material["calibration"], _CALIBRATION, "material.calibration")
    target = target_from_table(
        require(cal, "target", "material.calibration"), "material.calibration.target"
    )
    bonds = find_bonds(cloud, horizon, **dict(bond_options))
    opts = {k: cal[k] for k in cal if k != "target"}
    opts.setdefault("method", "robust")
    res = calibrate_micromoduli(
        target, bonds, thickness=cloud.thickness, plane=material.get("plane", "stress"), **opts
    )
    if res.status in ("infeasible", "failed") or not np.all(np.isfinite(res.micromoduli)):
        raise SceneError(f"material.calibration failed ({res.status}): {res.message}")
    model = BondBased(micromodulus=res.micromoduli, plane=material.get("plane", "stress"))
    return model, bonds, res


# --------------------------------------------------------------------------------------
# blocks: per-block materials ([[block]] tables of scenes, Blocks of Peridigm / PeriLab decks)
# --------------------------------------------------------------------------------------
#: keys of a block's material ([materials.<name>] or an inline table)
_BLOCK_MATERIAL = {*_ISO_KEYS, "plane", "model", "density"}  # density: explicit dynamics
_BLOCK = {"set", "box", "points", "material", "horizon"}


@dataclass(frozen=True, eq=False)
class Block:
    """One block of a scene: points with their own material (Peridigm's ``Blocks``).

    TOML scenes build them from ``[[block]]`` tables, the Peridigm and PeriLab deck
    readers from their ``Blocks`` lists; :func:`blocks_per_point` maps them onto the
    points.  ``Scene.blocks`` lists them (``None`` for a scene with one ``[material]``).

    Attributes
    ----------
    name : str
        The block's point set (``"block_2"``, a mesh's physical group), or its key path
        when the points were selected by a box or indices.
    points : numpy.ndarray
        Indices of its points.
    material : Mapping
        Its isotropic constants (two of ``E nu K G lam mu``, or one for a bond-based
        model) and, optionally, ``plane``.
    model : str
        Its model type (``bond_based``, ``lps``, ``xosb``, ``correspondence``).
    key : str
        Where it is defined, for messages (``block[1]``, ``Blocks.My Block``).
    horizon : float or None
        Its horizon, when the block sets one; None: the scene's ``[horizon]``.

    Examples
    --------
    >>> import numpy as np
    >>> Block("block_2", np.arange(3), {"K": 1.0, "G": 0.6}, "lps", "Blocks.B", horizon=0.3)
    Block('block_2', 3 points, lps, K=1.0, G=0.6, horizon=0.3)
    """

    name: str
    points: np.ndarray
    material: Mapping[str, Any]
    model: str
    key: str
    horizon: float | None = None

    def __repr__(self) -> str:
        """Return ``Block('block_2', 108 points, lps, K=..., G=..., horizon=...)``."""
        consts = ", ".join(f"{k}={v!r}" for k, v in self.material.items())
        return f"Block({self.name!r}, {self.points.size} points, {self.model}, {consts}" + (
            f", horizon={self.horizon!r})" if self.horizon is not None else ")"
        )


def blocks_per_point(
    blocks: Sequence[Block], n: int
) -> tuple[str, dict[str, Any], np.ndarray | None]:
    """Map per-block materials onto the points: one model type, per-point constants.

    Every point must lie in exactly one block, and all blocks must use one model type
    (pdlin assembles one stiffness matrix from one model; constants vary per point).
    Blocks giving different constants (``E, nu`` here, ``K, G`` there) are converted
    to the bulk and shear moduli ``K`` and ``G`` (3D constants, which the models take per
    point, as Peridigm's materials).

    Parameters
    ----------
    blocks : sequence of Block
        The blocks, in the order they were given.
    n : int
        Number of points of the scene.

    Returns
    -------
    kind : str
        The common model type.
    constants : dict
        Each constant (and ``plane`` when given): a number when all blocks agree, else
        one value per point, shape ``(n,)``.
    horizon : numpy.ndarray or None
        Per-point horizons when the blocks set them, else None.

    Raises
    ------
    SceneError
        No block, blocks that overlap, points in no block, different model types or
        planes, or constants that cannot be converted; the message names the block's
        key path.

    Examples
    --------
    >>> import numpy as np
    >>> bl = [Block("a", np.arange(2), {"E": 1.0, "nu": 0.25}, "lps", "block[0]"),
    ...       Block("b", np.arange(2, 4), {"K": 1.0, "G": 0.6}, "lps", "block[1]")]
    >>> kind, c, h = blocks_per_point(bl, 4)
    >>> kind, np.round(c["K"], 4).tolist(), np.round(c["G"], 4).tolist()
    ('lps', [0.6667, 0.6667, 1.0, 1.0], [0.4, 0.4, 0.6, 0.6])
    >>> blocks_per_point(bl[:1], 4)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.SceneError: 2 of 4 points are in no block (first: point 2); give every ...
    """
    if not blocks:
        raise SceneError("no block given: a scene with blocks needs at least one")
    owner = np.full(n, -1, dtype=np.int64)
    for b, blk in enumerate(blocks):  # a few blocks; vectorized over their points
        pts = np.asarray(blk.points, dtype=np.int64)
        if pts.size == 0:
            raise SceneError(f"{_label(blk)} holds no points")
        taken = owner[pts] >= 0
        if taken.any():
            other = blocks[int(owner[pts[taken][0]])]
            raise SceneError(
                f"{_label(blk)} overlaps {_label(other)} at "
                f"{int(taken.sum())} point(s) (first: point {int(pts[taken][0])}); a point "
                "has one material: make the blocks disjoint"
            )
        owner[pts] = b
    free = np.flatnonzero(owner < 0)
    if free.size:
        raise SceneError(
            f"{free.size} of {n} points are in no block (first: point {int(free[0])}); give "
            "every point a material: add a block for them"
        )
    kinds = {blk.model for blk in blocks}
    if len(kinds) > 1:
        first = blocks[0]
        other = next(blk for blk in blocks if blk.model != first.model)
        raise SceneError(
            f"{other.key} uses model {other.model!r} but {first.key} uses {first.model!r}: "
            "pdlin assembles one stiffness matrix from one model type; blocks may differ in "
            "their constants (E, nu, K, G, ...), not in the model"
        )
    planes = {str(blk.material.get("plane", "stress")) for blk in blocks}
    if len(planes) > 1:
        raise SceneError(
            f"blocks give different 'plane' values {sorted(planes)}: one model has one plane"
        )
    consts = [{k: v for k, v in blk.material.items() if k != "plane"} for blk in blocks]
    if len({tuple(sorted(c)) for c in consts}) > 1:
        consts = [_to_k_g(c, blk) for c, blk in zip(consts, blocks, strict=True)]
    out: dict[str, Any] = {}
    for k in consts[0]:
        vals = np.array([float(c[k]) for c in consts])
        out[k] = float(vals[0]) if np.all(vals == vals[0]) else vals[owner]
    if any("plane" in blk.material for blk in blocks):
        out["plane"] = planes.pop()
    hs = [blk.horizon for blk in blocks]
    horizon = None
    if any(h is not None for h in hs):
        missing = next(blk for blk in blocks if blk.horizon is None) if None in hs else None
        if missing is not None:
            raise SceneError(f"{missing.key} sets no horizon while other blocks do")
        horizon = np.asarray(hs, dtype=float)[owner]
    return kinds.pop(), out, horizon


def _label(blk: Block) -> str:
    """``block[1] ('steel')``: a block's key path and, when it differs, its name."""
    return blk.key if blk.name == blk.key else f"{blk.key} ({blk.name!r})"


def _to_k_g(c: Mapping[str, Any], blk: Block) -> dict[str, float]:
    """Two isotropic constants as ``K`` and ``G`` (blocks giving different constants)."""
    from ..constitutive import isotropic_constants

    if len(c) != 2:
        raise SceneError(
            f"{blk.key}: blocks give different constants, so each needs two of {list(_ISO_KEYS)} "
            f"(converted to K and G), got {sorted(c) or 'none'}"
        )
    try:
        E, nu = isotropic_constants(**{k: float(v) for k, v in c.items()})
    except PdlinError as exc:
        raise SceneError(f"{blk.key}: {exc}") from None
    E, nu = float(E), float(nu)
    return {"K": E / (3.0 * (1.0 - 2.0 * nu)), "G": E / (2.0 * (1.0 + nu))}


def _scene_blocks(
    top: Mapping[str, Any],
    cloud: PointCloud,
    where: Callable[[Mapping[str, Any], PointCloud, str], Any],
) -> list[Block]:
    """Read a scene's ``[[block]]`` tables (and the ``[materials.<name>]`` they name).

    ``where`` selects a table's points (``set`` / ``box`` / ``points``, as conditions do).
    """
    tables = top.get("block")
    if not isinstance(tables, list) or not tables:
        raise SceneError(f"block must be a non-empty array of tables ([[block]]), got {tables!r}")
    if "material" in top:
        raise SceneError(
            "material and block exclude each other: with [[block]] tables each block names its "
            "material (block[k].material = '<name>' of a [materials.<name>] table, or an "
            "inline table)"
        )
    named = top.get("materials", {})
    if not isinstance(named, Mapping):
        raise SceneError(f"materials must be a table of [materials.<name>] tables, got {named!r}")
    used: set[str] = set()
    blocks = []
    default_model = str(top.get("model", {}).get("type", "bond_based"))
    for k, table in enumerate(tables):
        key = f"block[{k}]"
        t = scene_keys(table, _BLOCK, key)
        mat = require(t, "material", key)
        mkey = f"{key}.material"
        if isinstance(mat, str):
            if mat not in named:
                raise SceneError(
                    f"{mkey}: {mat!r} is not a [materials.<name>] table (defined: "
                    f"{sorted(named) or 'none'})"
                )
            used.add(mat)
            mkey = f"materials.{mat}"
            mat = named[mat]
        mat = scene_keys(mat, _BLOCK_MATERIAL, mkey)
        consts = {}
        for c in _ISO_KEYS:
            if c in mat:
                consts[c] = number(mat[c], f"{mkey}.{c}")
        if "plane" in mat:
            consts["plane"] = mat["plane"]
        model = mat.get("model", default_model)
        if model not in MODELS:
            raise SceneError(f"{mkey}.model must be one of {sorted(MODELS)}, got {model!r}")
        if "type" in top.get("model", {}) and model != default_model:
            raise SceneError(
                f"{mkey}.model = {model!r} differs from model.type = {default_model!r}: pdlin "
                "assembles one stiffness matrix from one model type"
            )
        sel = where(t, cloud, key)
        name = sel if isinstance(sel, str) else key
        pts = cloud.point_set(sel) if isinstance(sel, str) else np.asarray(sel)
        h = None if "horizon" not in t else number(t["horizon"], f"{key}.horizon", positive=True)
        blocks.append(
            Block(name, np.asarray(pts, dtype=np.int64), consts, str(model), key, horizon=h)
        )
    unused = sorted(set(named) - used)
    if unused:
        raise SceneError(f"materials.{unused[0]} is not used by any [[block]]")
    return blocks


def _block_material(blocks: Sequence[Block], cloud: PointCloud) -> tuple[dict[str, Any], str]:
    """Return the ``[material]`` table (per-point constants) and model type of the blocks."""
    # horizons: the scene's [horizon] supplies defaults (pdlin.scene.scene._block_horizons)
    kind, consts, _ = blocks_per_point([replace(b, horizon=None) for b in blocks], cloud.n)
    return consts, kind
