"""The ``[material]`` and ``[model]`` tables of scene files: the pdlin model they build.

Isotropic elastic constants (any two of E, nu, K, G, lam, mu, per phase), anisotropic
stiffness (correspondence), crystal plasticity (single crystal or a seeded polycrystal) and
bond micromoduli calibrated to a target tensor (``[material.calibration]``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ..errors import SceneError
from ..geometry.bonds import Bonds, find_bonds
from ..geometry.cloud import PointCloud
from ..models.base import Model
from ..models.bond_based import BondBased
from ._keys import require, scene_keys

__all__ = ["MODELS", "per_phase"]

_MATERIAL = {
    "type",
    "slip",
    "orientation",
    "elastic",
    "hardening",
    "shear",
    "polycrystal",
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
}
_CP_KEYS = ("slip", "orientation", "elastic", "hardening", "shear", "polycrystal")
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
        C = target_from_table(material["stiffness"], "material.stiffness")
        return Correspondence(C, plane=plane, **opts)
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
    for key in ("elastic", "hardening", "shear"):
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
