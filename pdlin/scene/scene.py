"""Scene files (TOML): geometry, material, model, horizon, BCs, loads, solver, output.

A scene is plain data; :func:`load_scene` validates every key and builds
the pdlin objects.  Errors name the offending key (``dirichlet[1].set``).
See ``docs/scene.md`` for the full reference.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .._validation import as_float_array
from ..constraints import load_vector, resolve_dirichlet
from ..errors import AccuracyWarning, InsufficientMemoryError, PdlinError, SceneError
from ..geometry.bonds import SHAPES, Bonds, find_bonds
from ..geometry.cloud import PointCloud, from_image, grid
from ..geometry.influence import INFLUENCE_FUNCTIONS
from ..models.base import Model
from ..models.bond_based import BondBased
from ..operators.bc import BodyForce, Dirichlet, TimePath, TotalForce, shadow_layer
from ..problem import StaticProblem
from ._keys import number, read_toml, require, scene_keys
from .materials import (
    _MATERIAL,
    _MODEL,
    MODELS,
    Block,
    _block_material,
    _build_model,
    _calibrated_model,
    _scene_blocks,
    blocks_per_point,
)
from .materials import per_phase as per_phase  # public here before the split

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "Scene",
    "load_scene",
    "scene_from_dict",
    "builtin_scene",
    "list_builtin_scenes",
    "MODELS",
]

_TOP = {
    "name",
    "geometry",
    "material",
    "model",
    "horizon",
    "dirichlet",
    "load",
    "shadow",
    "symmetry",
    "solver",
    "output",
    "tradeoff",  # read by pdlin.scene.tradeoff (pdlin tradeoff), ignored by run
    "subregion",
    "check",  # [[check]]: references the run verifies (pdlin.scene.checks)
    "damage",  # stretch damage: load steps with bond breaking (pdlin.solve_damage)
    "about",  # description / runtime shown by `pdlin examples`
    "problem",  # a bundled problem of pdlin.sweeps.problems instead of geometry, ...
    "block",  # [[block]]: per-block materials instead of [material]
    "materials",  # [materials.<name>]: named materials of the [[block]] tables
    "deck",  # a Peridigm / PeriLab input deck instead of geometry, material, ...
    "thermal",  # [thermal] alpha, temperature_change: the thermal eigenstrain load
    "compare",  # [compare.cpfe]: the CPFE comparator beside a CP scene (pdlin.scene.compare)
}
#: top-level keys of a scene that runs an input deck ([deck] path = ...)
_DECK_TOP = {"name", "deck", "solver", "output", "check", "about"}
#: top-level keys of a scene built from a bundled problem ([problem] factory = ...)
_PROBLEM_TOP = {"name", "problem", "solver", "output", "check", "about"}
_DAMAGE = {"critical_stretch", "G0", "steps", "max_resolves"}
_ABOUT = {"description", "runtime"}
_SUBREGION = {"box", "coarse", "layer"}
_GEOM = {
    "grid": {
        "type",
        "shape",
        "spacing",
        "origin",
        "thickness",
        "ghost_layers",
        "holes",
        "inclusions",
    },
    "mesh": {"type", "path", "thickness", "dim", "volume"},
    "image": {"type", "path", "data", "spacing", "origin", "void", "thickness", "ghost_layers"},
}
_HORIZON = {"value", "ratio", "shape", "axes", "influence", "cracks"}
_DIRICHLET = {
    "set",
    "box",
    "points",
    "components",
    "value",
    "F",
    "translation",
    "center",
    "velocity_gradient",
    "velocity",  # a prescribed velocity: the path u = v t (explicit dynamics)
}
_LOAD = {"type", "set", "box", "points", "force", "density"}
_SHADOW = {"F", "depth", "faces", "translation", "mode"}
_SYMMETRY = {"axis", "position", "side"}
#: [solver] keys of solve_nonlinear (with rtol / maxiter for Newton)
_NONLINEAR_KEYS = (
    "steps",
    "t_end",
    "e_l",
    "predictor",
    "checkpoint",
    "max_cutbacks",
    "fallback_cutbacks",
    "newton_backoff",
    "relax",
    "linear_solver",
    "forcing",
    "globalization",
    "polish",
    "adr_stall",
    "progress_every",
    "snapshot_every",
    "density",
    "dt",
    "damping",
)
_SOLVER = {
    "name",
    "rtol",
    "maxiter",
    "direct_backend",
    "nonlinear",
    "backend",
    "petsc_options",
    *_NONLINEAR_KEYS,
    # [solver] kind = "explicit" (pdlin.scene.explicit)
    *("kind", "safety", "time_step", "kinematics", "output_every", "checkpoint_every"),
}
_OUTPUT = {"path", "fields", "homogenized"}


@dataclass
class Scene:
    """A parsed scene: the problem plus how to solve it and where to write."""

    name: str
    problem: StaticProblem
    solver: str = "auto"
    rtol: float = 1e-8
    maxiter: int | None = None
    #: factorization of ``solver = "direct"`` (``pdlin.solve(direct_backend=...)``)
    direct_backend: str = "auto"
    output: Path | None = None
    fields: list[str] | None = None
    #: time of the static state (a deck's ``Solver.Final Time``), written as the Exodus
    #: ``time_whole`` of the result as Peridigm writes its final state; 0 for scenes
    time: float = 0.0
    base_dir: Path = field(default_factory=Path.cwd)
    #: result of ``[material.calibration]`` (anisotropic micromoduli), if any
    calibration: Any = None
    #: ``solve_nonlinear`` options (``method`` and the [solver] load-step keys) when the
    #: scene asks for a nonlinear solve or its material is nonlinear; else None
    nonlinear: dict[str, Any] | None = None
    #: CSV of the homogenized response per load step (nonlinear scenes)
    homogenized: Path | None = None
    #: ``[subregion]`` scenes: the driving coarse solve and the cut (see
    #: :func:`pdlin.subregion`): box, layer, coarse spacing, points, seconds
    subregion: dict[str, Any] | None = None
    #: ``[[check]]`` tables (:func:`pdlin.scene.parse_checks`)
    checks: list[Any] = field(default_factory=list)
    #: ``[damage]`` options of :func:`pdlin.solve_damage` (``s0``, ``steps``, ...), or None
    damage: dict[str, Any] | None = None
    #: the bundled problem's :class:`~pdlin.sweeps.TradeoffCase` ([problem] scenes)
    case: Any = None
    #: ``[about]`` table: description and typical runtime
    about: dict[str, str] = field(default_factory=dict)
    #: linear-solve backend ('scipy' or 'petsc', ``[solver] backend``)
    backend: str = "scipy"
    #: PETSc options of the 'petsc' backend (``[solver.petsc_options]``)
    petsc_options: dict[str, Any] | None = None
    #: load steps of a deck with several (Peridigm's ``Number of Load Steps`` / ``Time
    #: Steps``): ``(time, problem)`` per step, the last being ``problem``; ``pdlin run``
    #: solves each and writes a time series.  None: one solve.
    steps: list[tuple[float, StaticProblem]] | None = None
    #: per-block materials (``[[block]]`` tables, a deck's ``Blocks``), in the order
    #: given; None: one ``[material]`` for every point
    blocks: list[Block] | None = None
    #: work loading deferred to the run (a ``[subregion]`` scene's coarse solve and cut),
    #: done once by :meth:`prepare`; None when there is none left
    pending: Callable[[Scene], None] | None = field(default=None, repr=False, compare=False)
    #: ``[solver] kind = "explicit"``: the keywords of ``pdlin.dynamics.solve_explicit``
    #: (``pdlin.scene.explicit``); None for other scenes
    explicit: dict[str, Any] | None = None
    #: ``[compare]`` options (``{"cpfe": {...}}``, ``pdlin.scene.compare.compare_options``):
    #: a second discretization ``pdlin run`` solves beside the scene's own; None: none
    compare: dict[str, Any] | None = None

    def prepare(self) -> Scene:
        """Do the work loading deferred to the run, once, and return the scene.

        Loading never solves: a ``[subregion]`` scene's coarse solve of the whole body
        and the cut of its box happen here.  Reading :attr:`problem` or
        :attr:`subregion` calls this first, so a scene is always used prepared.

        Returns
        -------
        Scene
            ``self``, with :attr:`problem` and :attr:`subregion` final.

        Raises
        ------
        SceneError
            The cut of the ``[subregion]`` box failed (naming ``subregion``).
        """
        job, self.pending = self.pending, None
        if job is not None:
            job(self)
        return self

    @property
    def cloud(self) -> PointCloud:
        """The problem's points."""
        return self.problem.cloud

    @property
    def model(self) -> Model:
        """The problem's model."""
        return self.problem.model

    def bonds(self) -> Bonds:
        """Return the problem's bonds (found on first use).

        Returns
        -------
        Bonds
            :meth:`pdlin.StaticProblem.get_bonds` of :attr:`problem`.
        """
        return self.problem.get_bonds()


def _prepared(name: str) -> property:
    """Make a :class:`Scene` field read through :meth:`Scene.prepare` (kept as ``_<name>``)."""
    slot = f"_{name}"

    def get(self: Scene) -> Any:
        if self.__dict__.get("pending") is not None:
            self.prepare()
        return self.__dict__[slot]

    def put(self: Scene, value: Any) -> None:
        self.__dict__[slot] = value

    return property(get, put, doc=f"The scene's ``{name}``, after :meth:`Scene.prepare`.")


# the dataclass __init__ assigns these through the properties (the defaults stay in it)
setattr(Scene, "problem", _prepared("problem"))  # noqa: B010
setattr(Scene, "subregion", _prepared("subregion"))  # noqa: B010


def _resolve_path(p: Any, base: Path, key: str) -> Path:
    if not isinstance(p, str):
        raise SceneError(f"{key} must be a path string, got {p!r}")
    path = Path(p)
    if not path.is_absolute():
        path = base / path
    if not path.exists():
        raise SceneError(f"{key}: file not found: {path}")
    return path


def _span(cloud: PointCloud) -> str:
    """``'points span [0, 0] to [1, 0.5]'``: the cloud's bounding box for messages."""
    lo, hi = cloud.bounds
    return "points span [{}] to [{}]".format(
        ", ".join(f"{v:g}" for v in lo), ", ".join(f"{v:g}" for v in hi)
    )


def _holes(cloud: PointCloud, holes: Any) -> PointCloud:
    """Remove the grid points inside circular (2D) / spherical (3D) holes."""
    if not isinstance(holes, list):
        raise SceneError(
            f"geometry.holes must be an array of tables {{center = [...], radius = r}}, "
            f"got {holes!r}"
        )
    inside = np.zeros(cloud.n, dtype=bool)
    shape = {1: "interval", 2: "circle", 3: "sphere"}[cloud.dim]
    for k, hole in enumerate(holes):  # a handful of holes, vectorized over points
        key = f"geometry.holes[{k}]"
        hole = scene_keys(hole, {"center", "radius"}, key)
        r = number(require(hole, "radius", key), f"{key}.radius", positive=True)
        c = require(hole, "center", key)
        if not isinstance(c, list) or len(c) != cloud.dim:
            raise SceneError(f"{key}.center must list {cloud.dim} coordinates, got {c!r}")
        centre = [number(v, f"{key}.center[{j}]") for j, v in enumerate(c)]
        mine = np.linalg.norm(cloud.points - np.asarray(centre), axis=1) < r
        if not mine.any():
            raise SceneError(
                f"{key} ({shape} at ({', '.join(f'{v:g}' for v in centre)}), radius {r:g}) "
                f"removes no points of the grid ({_span(cloud)}); move it into the body or "
                "drop it"
            )
        inside |= mine
    if inside.all():
        raise SceneError("geometry.holes remove every point of the grid")
    return cloud.subset(np.flatnonzero(~inside))


def _inclusions(cloud: PointCloud, items: Any) -> PointCloud:
    """Give the grid points inside circular / spherical inclusions their phase id.

    ``inclusions = [{center = [...], radius = r, phase = 1}]``: the points with
    ``|X - center| <= r`` get ``phase`` (later entries win); the others keep phase 0.  Per
    phase constants (``material.E = {"0" = ..., "1" = ...}``, ``material.stiffness.scale``)
    then apply, as to the phases of an image.
    """
    if not isinstance(items, list):
        raise SceneError(
            "geometry.inclusions must be an array of tables {center = [...], radius = r, "
            f"phase = k}}, got {items!r}"
        )
    phase = np.array(cloud.material, dtype=np.int64, copy=True)
    for k, inc in enumerate(items):  # a handful of inclusions, vectorized over points
        key = f"geometry.inclusions[{k}]"
        inc = scene_keys(inc, {"center", "radius", "phase"}, key)
        r = number(require(inc, "radius", key), f"{key}.radius", positive=True)
        c = require(inc, "center", key)
        if not isinstance(c, list) or len(c) != cloud.dim:
            raise SceneError(f"{key}.center must list {cloud.dim} coordinates, got {c!r}")
        centre = [number(v, f"{key}.center[{j}]") for j, v in enumerate(c)]
        ph = require(inc, "phase", key)
        if isinstance(ph, bool) or not isinstance(ph, int) or ph < 1:
            raise SceneError(f"{key}.phase must be an integer >= 1 (0 is the matrix), got {ph!r}")
        mine = np.linalg.norm(cloud.points - np.asarray(centre), axis=1) <= r
        if not mine.any():
            raise SceneError(
                f"{key} (at ({', '.join(f'{v:g}' for v in centre)}), radius {r:g}) holds no "
                f"point of the grid ({_span(cloud)}); move it into the body or enlarge it"
            )
        phase[mine] = ph
    return cloud.replace(material=phase)


def _geometry(cfg: Mapping[str, Any], base: Path) -> PointCloud:
    if not isinstance(cfg, Mapping):
        raise SceneError(f"geometry must be a table, got {type(cfg).__name__}")
    kind = cfg.get("type", "grid")
    if kind not in _GEOM:
        raise SceneError(f"geometry.type must be one of {sorted(_GEOM)}, got {kind!r}")
    scene_keys(cfg, _GEOM[kind], "geometry")
    thickness = number(cfg.get("thickness", 1.0), "geometry.thickness", positive=True)
    if kind == "grid":
        shape = require(cfg, "shape", "geometry")
        if not isinstance(shape, int | list) or isinstance(shape, bool):
            raise SceneError(
                f"geometry.shape must be an integer or a list of integers, got {shape!r}"
            )
        spacing = cfg.get("spacing", 1.0)
        for k, v in enumerate(spacing if isinstance(spacing, list) else [spacing]):
            number(v, "geometry.spacing" + (f"[{k}]" if isinstance(spacing, list) else ""))
        cloud = grid(shape, spacing, cfg.get("origin"), thickness=thickness)
        if "inclusions" in cfg:
            cloud = _inclusions(cloud, cfg["inclusions"])
        return _holes(cloud, cfg["holes"]) if "holes" in cfg else cloud
    if kind == "mesh":
        path = _resolve_path(require(cfg, "path", "geometry"), base, "geometry.path")
        from ..geometry import mesh as mesh_mod  # lazy: meshio readers

        kwargs: dict[str, Any] = {}
        if "dim" in cfg:
            if isinstance(cfg["dim"], bool) or not isinstance(cfg["dim"], int):
                raise SceneError(f"geometry.dim must be 1, 2 or 3, got {cfg['dim']!r}")
            kwargs["dim"] = cfg["dim"]
        if "volume" in cfg:  # point clouds (vertex cells): a number or a point field name
            vol = cfg["volume"]
            kwargs["volume"] = (
                vol if isinstance(vol, str) else number(vol, "geometry.volume", positive=True)
            )
        cloud = mesh_mod.read_mesh(path, **kwargs)
        return cloud.replace(thickness=thickness) if thickness != 1.0 else cloud
    # image
    if "data" in cfg:
        img = np.asarray(cfg["data"])
    else:
        path = _resolve_path(require(cfg, "path", "geometry"), base, "geometry.path")
        img = np.load(path)
    return from_image(
        img, cfg.get("spacing", 1.0), cfg.get("origin"), void=cfg.get("void"), thickness=thickness
    )


def _where(cfg: Mapping[str, Any], cloud: PointCloud, key: str) -> Any:
    given = [k for k in ("set", "box", "points") if k in cfg]
    if len(given) != 1:
        raise SceneError(
            f"{key} needs exactly one of 'set', 'box', 'points', got {given or 'none'}"
        )
    k = given[0]
    if k == "set":
        name = cfg["set"]
        try:
            cloud.point_set(name)  # named sets, plus 'all' and 'boundary'
        except PdlinError as exc:
            raise SceneError(f"{key}.set: {exc}") from None
        return name
    if k == "box":
        box = cfg["box"]
        try:
            idx = cloud.select(box=(box[0], box[1]))
        except (PdlinError, TypeError, IndexError, KeyError) as exc:
            raise SceneError(f"{key}.box must be [[lower...], [upper...]]: {exc}") from exc
        if idx.size == 0:
            raise SceneError(f"{key}.box selects no points: {box!r}, {_span(cloud)}")
        return idx
    pts = cfg["points"]
    if (
        not isinstance(pts, list)
        or not pts
        or not all(isinstance(p, int) and not isinstance(p, bool) for p in pts)
    ):
        raise SceneError(f"{key}.points must be a non-empty list of point indices, got {pts!r}")
    if min(pts) < 0 or max(pts) >= cloud.n:
        raise SceneError(
            f"{key}.points must hold indices in [0, {cloud.n - 1}], got range "
            f"[{min(pts)}, {max(pts)}]"
        )
    return np.asarray(pts, dtype=np.intp)


def _dirichlet(bc: Mapping[str, Any], where: Any, key: str) -> Dirichlet:
    """One ``[[dirichlet]]`` table as a :class:`Dirichlet` (value, F, velocity[_gradient])."""
    if "velocity" in bc:
        clash = [k for k in ("value", "F", "translation", "velocity_gradient") if k in bc]
        if clash:
            raise SceneError(f"{key} takes 'velocity' or '{clash[0]}', not both")
        vel = as_float_array(bc["velocity"], f"{key}.velocity")
        return Dirichlet(
            where, TimePath(lambda x, t: vel * t, f"{vel.tolist()} t"), bc.get("components")
        )
    if "velocity_gradient" in bc:
        clash = [k for k in ("value", "F", "translation") if k in bc]
        if clash:
            raise SceneError(f"{key} takes 'velocity_gradient' or '{clash[0]}', not both")
        return Dirichlet.velocity_gradient(
            where,
            bc["velocity_gradient"],
            center=bc.get("center"),
            components=bc.get("components"),
        )
    if "F" in bc:
        if "value" in bc:
            raise SceneError(f"{key} takes 'value' or 'F', not both")
        return Dirichlet.affine(
            where,
            bc["F"],
            translation=bc.get("translation"),
            center=bc.get("center"),
            components=bc.get("components"),
        )
    return Dirichlet(where, bc.get("value", 0.0), bc.get("components"))


def scene_from_dict(data: Mapping[str, Any], base_dir: str | Path | None = None) -> Scene:
    """Build a :class:`Scene` from a parsed TOML mapping.

    Every key is checked and the conditions and loads are resolved on the cloud (no
    bonds, no assembly, no solve); see ``docs/scene.md`` for the keys.

    Parameters
    ----------
    data : Mapping
        The parsed scene (what ``tomllib.loads`` gives for a scene file).
    base_dir : str or Path, optional
        Folder that relative paths inside the scene are resolved against (default: the
        working directory).

    Returns
    -------
    Scene
        The scene; a ``[subregion]`` scene's coarse solve waits for
        :meth:`Scene.prepare`.

    Raises
    ------
    SceneError
        An unknown key (with the closest valid one), a missing or invalid value, named by
        its key path (``dirichlet[1].set``).
    InsufficientMemoryError
        A valid scene too large for the memory.

    Examples
    --------
    >>> sc = scene_from_dict({
    ...     "geometry": {"type": "grid", "shape": [20], "spacing": 0.05},
    ...     "material": {"E": 1.0},
    ...     "horizon": {"ratio": 3.015},
    ...     "dirichlet": [{"set": "x-", "value": 0.0}],
    ...     "load": [{"type": "total", "set": "x+", "force": [1e-3]}],
    ... })
    >>> sc.problem.cloud.n, sc.solver
    (20, 'auto')
    >>> scene_from_dict({"geometry": {"type": "grid", "shape": [4]}, "materal": {}})
    Traceback (most recent call last):
    ...
    pdlin.errors.SceneError: unknown scene key 'materal'; did you mean 'material'?
    """
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    top = scene_keys(data, _TOP, "")
    if "subregion" in top:
        return _subregion_scene(top, base)
    if "problem" in top:
        return _problem_scene(top, base)
    if "deck" in top:
        return _deck_scene(top, base)
    try:
        problem, n_real, calibration, blocks = _scene_problem(top, base)
        scfg = scene_keys(top.get("solver", {}), _SOLVER, "solver")
        ocfg = scene_keys(top.get("output", {}), _OUTPUT, "output")
    except (SceneError, InsufficientMemoryError):  # a valid scene too large for memory
        raise
    except PdlinError as exc:
        raise SceneError(f"invalid scene: {exc}") from exc
    if "density" in top.get("material", {}):  # the mass density (explicit dynamics)
        number(top["material"]["density"], "material.density", positive=True)
    kind = scfg.get("kind", "static")
    if kind == "explicit":
        if "compare" in top:
            raise SceneError(
                "compare.cpfe compares quasi-static crystal-plasticity load steps; remove it "
                "or solver.kind = 'explicit'"
            )
        from .explicit import explicit_scene

        scene = explicit_scene(top, base, problem, scfg, ocfg, blocks)
        scene.blocks = blocks
        return scene
    if kind != "static":
        raise SceneError(f"solver.kind must be 'static' or 'explicit', got {kind!r}")
    explicit_only = ("safety", "time_step", "kinematics", "output_every", "checkpoint_every")
    stray = [k for k in explicit_only if k in scfg]
    if stray:
        raise SceneError(f"solver.{stray[0]} needs [solver] kind = 'explicit'")
    scene = _scene(top, base, problem, n_real, calibration, scfg, ocfg)
    scene.blocks = blocks
    return scene


def _scene_problem(
    top: Mapping[str, Any], base: Path
) -> tuple[StaticProblem, int, Any, list[Block] | None]:
    """Build the scene's problem; also its real (not ghost) points, calibration, blocks."""
    gcfg = require(top, "geometry", "scene")
    cloud = _geometry(gcfg, base)
    n_real = cloud.n
    if isinstance(gcfg, Mapping) and "ghost_layers" in gcfg:
        layers = gcfg["ghost_layers"]
        if isinstance(layers, bool) or not isinstance(layers, int) or layers < 1:
            raise SceneError(f"geometry.ghost_layers must be an integer >= 1, got {layers!r}")
        from ..geometry.cloud import ghost_layer

        cloud = ghost_layer(cloud, layers).cloud
    model_cfg = scene_keys(top.get("model", {}), _MODEL, "model")
    blocks = None
    if "block" in top or "materials" in top:
        if "block" not in top:
            raise SceneError(
                "materials: [materials.<name>] tables need [[block]] tables using them"
            )
        blocks = _scene_blocks(top, cloud, _where)
        material, kind = _block_material(blocks, cloud)
        model_cfg["type"] = kind
    else:
        material = scene_keys(require(top, "material", "scene"), _MATERIAL, "material")
    block_h = blocks is not None and any(b.horizon is not None for b in blocks)
    horizon, bond_options = _horizon(top, block_horizons=block_h)
    if blocks is not None and block_h:
        horizon = _block_horizons(blocks, horizon, bond_options, cloud.n)
    bonds = None
    calibration = None
    if "calibration" in material:
        model, bonds, calibration = _calibrated_model(
            material, model_cfg, cloud, horizon, bond_options, "symmetry" in top
        )
    else:
        model = _build_model(model_cfg, material, cloud)
    for name in ("dirichlet", "load", "symmetry"):
        if name in top and not isinstance(top[name], list):
            raise SceneError(
                f"{name} must be an array of tables ([[{name}]]), got {type(top[name]).__name__}"
            )
    dirichlet: list[Dirichlet] = []
    for k, bc in enumerate(top.get("dirichlet", [])):
        key = f"dirichlet[{k}]"
        bc = scene_keys(bc, _DIRICHLET, key)
        where = _where(bc, cloud, key)
        try:
            dirichlet.append(_dirichlet(bc, where, key))
        except SceneError:
            raise
        except PdlinError as exc:
            raise SceneError(f"{key}: {exc}") from exc
    shadow_loads: list[Any] = []
    if "shadow" in top:
        model, bonds, shadow_loads = _shadow(
            top["shadow"], model, cloud, horizon, bond_options, bonds, dirichlet
        )
    loads = _loads(top, cloud, shadow_loads)
    extra: dict[str, Any] = {}
    if "symmetry" in top:
        extra["symmetry"] = _symmetry(top["symmetry"])
    if "thermal" in top:
        extra["thermal"] = _thermal(top["thermal"], cloud)
    problem = StaticProblem(
        model,
        cloud,
        bonds,
        horizon=horizon,
        dirichlet=dirichlet,
        loads=loads,
        bond_options=bond_options,
        **extra,
    )
    # resolve the conditions and loads on the cloud now (cheap, no bonds): shapes,
    # conflicts, empty selections and loads on prescribed points only are reported
    # before any assembly (the symmetry planes' conditions are checked at solve time)
    dofs, _ = resolve_dirichlet(cloud, dirichlet)
    load_names = ["shadow stress load"] * len(shadow_loads) + [
        f"load[{k}]" for k in range(len(loads) - len(shadow_loads))
    ]
    with warnings.catch_warnings():  # partial losses warn once, when the scene is solved
        warnings.simplefilter("ignore", AccuracyWarning)
        load_vector(cloud, loads, prescribed=dofs, names=load_names)
    return problem, n_real, calibration, blocks


def _block_horizons(
    blocks: list[Block], default: Any, bond_options: Mapping[str, Any], n: int
) -> np.ndarray:
    """Per-point horizons of ``[[block]]`` tables that set ``horizon`` (else ``horizon.value``)."""
    if "ratio" in bond_options:
        raise SceneError(
            "block horizons and horizon.ratio exclude each other: give horizon.value as the "
            "default of blocks without a horizon, or a horizon in every block"
        )
    if default is not None and not isinstance(default, int | float):
        raise SceneError("block horizons need horizon.value to be one number (the default)")
    missing = [b.key for b in blocks if b.horizon is None]
    if missing and default is None:
        raise SceneError(
            f"{missing[0]} sets no horizon while other blocks do: give it one, or "
            "horizon.value as the default"
        )
    filled = [b if b.horizon is not None else replace(b, horizon=default) for b in blocks]
    _, _, h = blocks_per_point(filled, n)
    assert h is not None  # every block has a horizon now
    return h


def _horizon(top: Mapping[str, Any], *, block_horizons: bool = False) -> tuple[Any, dict[str, Any]]:
    """Read ``[horizon]``: the horizon value (None: by ratio) and the bond options.

    With ``block_horizons`` (``[[block]]`` tables setting ``horizon``) neither ``value``
    nor ``ratio`` is required.
    """
    hcfg = scene_keys(require(top, "horizon", "scene"), _HORIZON, "horizon")
    if ("value" in hcfg) == ("ratio" in hcfg) and not (block_horizons and "value" not in hcfg):
        given = [k for k in ("value", "ratio") if k in hcfg]
        raise SceneError(f"horizon needs exactly one of 'value' or 'ratio', got {given or 'none'}")
    if "ratio" in hcfg:
        number(hcfg["ratio"], "horizon.ratio", positive=True)
    elif "value" in hcfg:
        hv = hcfg["value"]
        if isinstance(hv, list):
            for k, v in enumerate(hv):
                number(v, f"horizon.value[{k}]", positive=True)
        else:
            number(hv, "horizon.value", positive=True)
    for key, allowed in (("shape", SHAPES), ("influence", tuple(INFLUENCE_FUNCTIONS))):
        if key in hcfg and hcfg[key] not in allowed:
            raise SceneError(f"horizon.{key} must be one of {list(allowed)}, got {hcfg[key]!r}")
    bond_options: dict[str, Any] = {
        k: hcfg[k] for k in ("shape", "axes", "influence", "cracks") if k in hcfg
    }
    if "ratio" in hcfg:
        bond_options["ratio"] = float(hcfg["ratio"])
    if "cracks" in hcfg:  # finite numbers now; a crack cutting no bond raises in find_bonds
        try:
            as_float_array(hcfg["cracks"], "horizon.cracks")
        except PdlinError as exc:
            raise SceneError(str(exc)) from exc
    return hcfg.get("value"), bond_options


def _shadow(
    table: Any,
    model: Model,
    cloud: PointCloud,
    horizon: Any,
    bond_options: Mapping[str, Any],
    bonds: Bonds | None,
    dirichlet: list[Dirichlet],
) -> tuple[Model, Bonds | None, list[Any]]:
    """Add the ``[shadow]`` frame's conditions; return the model, bonds and stress loads."""
    from ..models.correspondence import Correspondence, shadow_problem

    sh = scene_keys(table, _SHADOW, "shadow")
    depth = sh.get("depth")
    if depth is None:
        hv = (
            horizon
            if horizon is not None
            else float(bond_options.get("ratio", 0))
            * float(
                np.max(cloud.lattice.spacing)
                if cloud.lattice is not None
                else np.median(cloud.spacing)
            )
        )
        depth = float(np.max(hv))
    partial = sh.get("faces") is not None or sh.get("translation") is not None
    mode = sh.get("mode")
    if mode is None:
        mode = "stress" if isinstance(model, Correspondence) and not partial else "displacement"
    if mode not in ("stress", "displacement"):
        raise SceneError(f"shadow.mode must be 'stress' or 'displacement', got {mode!r}")
    if mode == "stress" and not isinstance(model, Correspondence):
        raise SceneError(
            "shadow.mode = 'stress' is the correspondence shadow problem (Javaheri et "
            f"al. 2022, Sec. II.D); got model {type(model).__name__}: use 'displacement'"
        )
    if mode == "stress" and partial:
        raise SceneError(
            "shadow.mode = 'stress' needs the whole frame: shadow.faces/translation "
            "apply to mode = 'displacement' (the layer prescribed like any points)"
        )
    if sh.get("depth") is None and mode == "displacement":
        # two-hop models (state-based, correspondence) need two horizons of layer
        depth = float(depth) * int(getattr(model, "coupling_range", 1))
    if mode == "stress" and isinstance(model, Correspondence):
        # correspondence shadow particles use the intact-lattice shape tensor and act
        # through their prescribed stress (Javaheri et al. 2022, Sec. II.D; the paper does not
        # say which shape tensor: the intact lattice's is pdlin's reading, see
        # docs/theory/conventions.md#shadow-boundary-layer)
        bonds = bonds if bonds is not None else find_bonds(cloud, horizon, **bond_options)
        sp_prob = shadow_problem(
            model, cloud, bonds, require(sh, "F", "shadow"), depth=float(depth)
        )
        dirichlet.extend(sp_prob.dirichlet)
        return sp_prob.model, bonds, list(sp_prob.loads)
    bc_sh, _ = shadow_layer(
        cloud,
        require(sh, "F", "shadow"),
        float(depth),
        faces=sh.get("faces"),
        translation=sh.get("translation"),
    )
    dirichlet.append(bc_sh)
    return model, bonds, []


def _loads(
    top: Mapping[str, Any], cloud: PointCloud, shadow_loads: list[Any]
) -> list[BodyForce | TotalForce]:
    """Read the ``[[load]]`` tables, after the shadow frame's stress loads."""
    loads: list[BodyForce | TotalForce] = list(shadow_loads)
    for k, ld in enumerate(top.get("load", [])):
        key = f"load[{k}]"
        ld = scene_keys(ld, _LOAD, key)
        where = _where(ld, cloud, key)
        kind = ld.get("type", "total")
        if kind not in ("total", "body"):
            raise SceneError(f"{key}.type must be 'total' or 'body', got {kind!r}")
        vkey = "force" if kind == "total" else "density"
        value = require(ld, vkey, key)
        try:
            loads.append(TotalForce(where, value) if kind == "total" else BodyForce(where, value))
        except PdlinError as exc:
            raise SceneError(f"{key}.{vkey}: {exc}") from exc
    return loads


def _thermal(table: Any, cloud: PointCloud) -> Any:
    """Read ``[thermal]``: ``alpha`` and ``temperature_change`` (number or expression)."""
    from ..models.thermal import ThermalExpansion
    from .decks.expressions import deck_expression

    cfg = scene_keys(table, {"alpha", "temperature_change"}, "thermal")
    alpha = number(require(cfg, "alpha", "thermal"), "thermal.alpha")
    dT = require(cfg, "temperature_change", "thermal")
    if isinstance(dT, str):  # an expression in x, y, z (the decks' whitelisted evaluator)
        dT = deck_expression(dT, cloud.points, 0.0, "thermal.temperature_change")
    else:
        dT = number(dT, "thermal.temperature_change")
    return ThermalExpansion(dT, alpha)


def _symmetry(tables: list[Any]) -> tuple[Any, ...]:
    """Read the ``[[symmetry]]`` planes."""
    from ..operators import symmetry as sym_mod

    planes = []
    for k, s in enumerate(tables):
        s = scene_keys(s, _SYMMETRY, f"symmetry[{k}]")
        planes.append(
            sym_mod.SymmetryPlane(
                require(s, "axis", f"symmetry[{k}]"),
                number(s.get("position", 0.0), f"symmetry[{k}].position"),
                side=s.get("side"),
            )
        )
    return tuple(planes)


def _scene(
    top: Mapping[str, Any],
    base: Path,
    problem: StaticProblem,
    n_real: int,
    calibration: Any,
    scfg: Mapping[str, Any],
    ocfg: Mapping[str, Any],
) -> Scene:
    """Build the scene around its problem: output, solver, nonlinear and damage options."""
    out = ocfg.get("path")
    for key in ("path", "homogenized"):
        if key in ocfg and not isinstance(ocfg[key], str):
            raise SceneError(f"output.{key} must be a path string, got {ocfg[key]!r}")
    if "fields" in ocfg and (
        not isinstance(ocfg["fields"], list) or not all(isinstance(f, str) for f in ocfg["fields"])
    ):
        raise SceneError(f"output.fields must be a list of field names, got {ocfg['fields']!r}")
    if "name" in top and not isinstance(top["name"], str):
        raise SceneError(f"name must be a string, got {top['name']!r}")
    _solver_options(scfg)
    nonlinear = _nonlinear_options(scfg, problem, base)
    if nonlinear is not None and problem.cloud.n != n_real:
        nonlinear["homogenize"] = np.arange(n_real)  # ghosts are not part of the body
    hom = ocfg.get("homogenized")
    if hom is not None and nonlinear is None:
        raise SceneError("output.homogenized needs a nonlinear solve ([solver] nonlinear = ...)")
    damage = _damage_options(top, problem, scfg)
    if damage is not None and nonlinear is not None:
        raise SceneError("[damage] runs linear load steps; remove solver.nonlinear")
    if "fields" in ocfg:
        if damage is not None or nonlinear is not None:
            raise SceneError(
                "output.fields selects the fields of a static run; a "
                f"{'damage' if damage is not None else 'nonlinear'} run writes its own "
                "(displacement and damage; the series of every step): remove output.fields"
            )
        _check_output_fields(ocfg["fields"], problem.model)
    from .compare import compare_options

    real = None
    if "compare" in top and problem.cloud.n != n_real:  # ghost layers: the real pixels
        real = _geometry(top["geometry"], base)
    compare = compare_options(top.get("compare"), problem, nonlinear, n_real, base, real)
    return Scene(
        name=str(top.get("name", "scene")),
        problem=problem,
        checks=_checks(top),
        damage=damage,
        about=_about(top),
        solver=str(scfg.get("name", "auto")),
        rtol=float(scfg.get("rtol", 1e-8)),
        maxiter=None if scfg.get("maxiter") is None else int(scfg["maxiter"]),
        direct_backend=str(scfg.get("direct_backend", "auto")),
        output=None if out is None else (Path(out) if Path(out).is_absolute() else base / out),
        fields=ocfg.get("fields"),
        base_dir=base,
        calibration=calibration,
        nonlinear=nonlinear,
        homogenized=None if hom is None else (Path(hom) if Path(hom).is_absolute() else base / hom),
        backend=str(scfg.get("backend", "scipy")),
        petsc_options=None if "petsc_options" not in scfg else dict(scfg["petsc_options"]),
        compare=compare,
    )


def _subregion_scene(top: Mapping[str, Any], base: Path) -> Scene:
    """Build a ``[subregion]`` scene: a coarse solve of the whole body drives the box.

    ``coarse`` is the spacing factor of the driving run (default 2: twice the scene's
    spacing), ``layer`` the driven layer's thickness (default: horizon x the model's
    coupling range).  Loading builds and checks the fine and coarse scenes and the cut
    (with a zero driver); the coarse solve, with the scene's solver, and the real cut
    wait for :meth:`Scene.prepare`.
    """
    import copy

    from ..submodeling import subregion
    from .tradeoff import rescale_grid

    sub = scene_keys(top["subregion"], _SUBREGION, "subregion")
    data = {k: copy.deepcopy(v) for k, v in top.items() if k != "subregion"}
    if "symmetry" in data or "shadow" in data:
        raise SceneError("subregion cannot be combined with symmetry or shadow tables")
    geo = data.get("geometry", {})
    if not isinstance(geo, Mapping) or geo.get("type", "grid") != "grid":
        raise SceneError("subregion needs geometry.type = 'grid' (the coarse run rescales it)")
    factor = number(sub.get("coarse", 2.0), "subregion.coarse")
    if not (np.isfinite(factor) and factor >= 1.0):
        raise SceneError(f"subregion.coarse must be a number >= 1, got {factor}")
    box = require(sub, "box", "subregion")
    fine = scene_from_dict(data, base)
    if fine.nonlinear is not None:
        raise SceneError("subregion supports linear scenes (the driver is one linear solve)")
    spacing = float(np.max(np.asarray(geo.get("spacing", 1.0), dtype=float)))
    coarse_data = copy.deepcopy(data)
    rescale_grid(coarse_data, spacing * factor, "subregion.coarse")
    coarse = scene_from_dict(coarse_data, base)
    layer = sub.get("layer")
    if layer is not None:
        layer = number(layer, "subregion.layer", positive=True)
    try:  # the cut's own checks (box, layer, model) now: the same cut with u = 0 driving
        subregion(fine.problem, box, np.zeros_like, layer=layer)
    except PdlinError as exc:
        raise SceneError(f"subregion: {exc}") from exc
    cut = _SubregionCut(coarse, box, layer, spacing * factor)
    fine.pending = cut
    return fine


@dataclass(frozen=True)
class _SubregionCut:
    """The deferred part of a ``[subregion]`` scene: coarse solve, then the cut."""

    coarse: Scene
    box: Any
    layer: float | None
    coarse_spacing: float

    def __call__(self, scene: Scene) -> None:
        import time

        from ..static import solve
        from ..submodeling import subregion

        coarse = self.coarse
        t0 = time.perf_counter()
        kw: dict[str, Any] = {"solver": coarse.solver, "rtol": coarse.rtol}
        if coarse.maxiter is not None:
            kw["maxiter"] = coarse.maxiter
        res = solve(coarse.problem, **kw)
        t_coarse = time.perf_counter() - t0
        whole = scene.problem
        try:
            cut = subregion(whole, self.box, res, layer=self.layer)
        except PdlinError as exc:
            raise SceneError(f"subregion: {exc}") from exc
        scene.problem = cut.problem
        scene.subregion = {
            "box": np.asarray(self.box, dtype=float).tolist(),
            "layer": cut.layer,
            "coarse_spacing": self.coarse_spacing,
            "coarse_points": coarse.problem.cloud.n,
            "points": cut.problem.cloud.n,
            "free_points": int(cut.interior.sum()),
            "whole_body_points": whole.cloud.n,
            "t_coarse": t_coarse,
            "interior": cut.interior,
        }


def _checks(top: Mapping[str, Any]) -> list[Any]:
    from .checks import parse_checks

    return parse_checks(top["check"]) if "check" in top else []


def _about(top: Mapping[str, Any]) -> dict[str, str]:
    about = scene_keys(top.get("about", {}), _ABOUT, "about")
    for k, v in about.items():
        if not isinstance(v, str):
            raise SceneError(f"about.{k} must be a string, got {v!r}")
    return about


def _damage_options(
    top: Mapping[str, Any], problem: StaticProblem, scfg: Mapping[str, Any]
) -> dict[str, Any] | None:
    """``[damage]``: critical stretch (or G0) and load steps of :func:`pdlin.solve_damage`."""
    if "damage" not in top:
        return None
    d = scene_keys(top["damage"], _DAMAGE, "damage")
    if ("critical_stretch" in d) == ("G0" in d):
        raise SceneError("damage needs exactly one of 'critical_stretch' or 'G0'")
    if problem.symmetry:
        raise SceneError("[damage] cannot be combined with [[symmetry]] planes")
    opts: dict[str, Any] = {}
    if "critical_stretch" in d:
        opts["s0"] = number(d["critical_stretch"], "damage.critical_stretch", positive=True)
    else:
        from ..models.damage import critical_stretch

        g0 = number(d["G0"], "damage.G0", positive=True)
        model = problem.model
        E = getattr(model, "E", None)
        if not isinstance(model, BondBased) or E is None or np.ndim(E) != 0:
            raise SceneError(
                "damage.G0 needs a bond-based model with one scalar material.E (the "
                "critical-stretch forms of pdlin.models.damage.critical_stretch); give "
                "damage.critical_stretch otherwise"
            )
        cloud = problem.cloud
        delta = problem.get_bonds().horizon.max()
        plane = getattr(model, "plane", "stress") if cloud.dim == 2 else None
        opts["s0"] = critical_stretch(g0, float(E), float(delta), plane=plane, dim=cloud.dim)
    for key, lo in (("steps", 1), ("max_resolves", 1)):
        if key in d:
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise SceneError(f"damage.{key} must be an integer >= {lo}, got {v!r}")
            opts[key] = v
    opts["solver"] = str(scfg.get("name", "auto"))
    if "rtol" in scfg:
        opts["rtol"] = float(scfg["rtol"])
    return opts


def _deck_scene(top: Mapping[str, Any], base: Path) -> Scene:
    """Build a scene from a Peridigm / PeriLab input deck (``[deck] path = ...``).

    The deck defines the geometry, materials, blocks, conditions and load steps
    (:func:`pdlin.read_deck`); the scene adds its name, ``[[check]]`` tables, ``[about]``,
    the linear solver (``[solver] name / rtol / maxiter``) and the output: ``output.path``,
    else ``<name>.vtu`` (``.pvd`` for several load steps) in the working directory, not
    the deck's ``Output Filename`` beside the deck.
    """
    from .decks import read_deck

    extra = sorted(set(top) - _DECK_TOP)
    if extra:
        raise SceneError(
            f"scene key {extra[0]!r} cannot be combined with [deck] (the deck defines the "
            f"geometry, materials and conditions); allowed: {sorted(_DECK_TOP)}"
        )
    cfg = scene_keys(top["deck"], {"path"}, "deck")
    path = _resolve_path(require(cfg, "path", "deck"), base, "deck.path")
    scene = read_deck(path)
    scfg = scene_keys(top.get("solver", {}), {"name", "rtol", "maxiter"}, "solver")
    _solver_options(scfg)
    ocfg = scene_keys(top.get("output", {}), {"path"}, "output")
    out = ocfg.get("path")
    if out is not None and not isinstance(out, str):
        raise SceneError(f"output.path must be a path string, got {out!r}")
    if "name" in top and not isinstance(top["name"], str):
        raise SceneError(f"name must be a string, got {top['name']!r}")
    scene.name = str(top.get("name", path.stem))
    scene.output = None if out is None else (Path(out) if Path(out).is_absolute() else base / out)
    scene.base_dir = base
    scene.solver = str(scfg.get("name", scene.solver))
    scene.rtol = float(scfg.get("rtol", scene.rtol))
    scene.maxiter = None if scfg.get("maxiter") is None else int(scfg["maxiter"])
    scene.checks = _checks(top)
    scene.about = _about(top)
    return scene


def _problem_scene(top: Mapping[str, Any], base: Path) -> Scene:
    """Build a scene from a bundled problem of :mod:`pdlin.sweeps.problems`.

    ``[problem] factory = "graded_bar"`` plus the factory's keyword parameters; the
    problem carries its own reference (closed form or finite elements), which checks of
    ``kind = "reference"`` compare against.
    """
    import inspect

    from ..sweeps.problems import FACTORIES

    extra = sorted(set(top) - _PROBLEM_TOP)
    if extra:
        raise SceneError(
            f"scene key {extra[0]!r} cannot be combined with [problem] (a bundled problem "
            f"defines its own geometry, model and conditions); allowed: {sorted(_PROBLEM_TOP)}"
        )
    cfg = top["problem"]
    if not isinstance(cfg, Mapping):
        raise SceneError(f"problem must be a table, got {type(cfg).__name__}")
    name = cfg.get("factory")
    if name not in FACTORIES:
        raise SceneError(f"problem.factory must be one of {sorted(FACTORIES)}, got {name!r}")
    factory = FACTORIES[name]
    params = set(inspect.signature(factory).parameters)
    scene_keys(cfg, params | {"factory"}, "problem")
    kwargs = {k: (tuple(v) if isinstance(v, list) else v) for k, v in cfg.items() if k != "factory"}
    try:
        case = factory(**kwargs)
    except SceneError:
        raise
    except (PdlinError, TypeError) as exc:
        raise SceneError(f"problem ({name}): {exc}") from exc
    # the linear-solve keys, and the load-step keys of solve_nonlinear (an ADR run of the
    # bundled problem, e.g. Liu, Chen & Skelton's plate: solver.nonlinear = "adr")
    keys = {"name", "rtol", "maxiter", "nonlinear", *_NONLINEAR_KEYS}
    scfg = scene_keys(top.get("solver", {}), keys, "solver")
    _solver_options(scfg)
    nonlinear = _nonlinear_options(scfg, case.problem, base)
    ocfg = scene_keys(top.get("output", {}), {"path", "fields", "homogenized"}, "output")
    hom = ocfg.get("homogenized")
    if hom is not None and (nonlinear is None or not isinstance(hom, str)):
        raise SceneError(
            "output.homogenized must be a path string of a nonlinear solve "
            f"([solver] nonlinear = ...), got {hom!r}"
        )
    if "fields" in ocfg and nonlinear is not None:
        raise SceneError("output.fields selects the fields of a static run; remove it")
    out = ocfg.get("path")
    if out is not None and not isinstance(out, str):
        raise SceneError(f"output.path must be a path string, got {out!r}")
    if "fields" in ocfg:
        _check_output_fields(ocfg["fields"], case.problem.model)
    solver = scfg.get("name", case.solve_kwargs.get("solver", "auto"))
    return Scene(
        name=str(top.get("name", name)),
        problem=case.problem,
        solver=str(solver),
        rtol=float(scfg.get("rtol", case.solve_kwargs.get("rtol", 1e-8))),
        maxiter=None if scfg.get("maxiter") is None else int(scfg["maxiter"]),
        output=None if out is None else (Path(out) if Path(out).is_absolute() else base / out),
        fields=ocfg.get("fields"),
        base_dir=base,
        checks=_checks(top),
        case=case,
        about=_about(top),
        nonlinear=nonlinear,
        homogenized=None if hom is None else (Path(hom) if Path(hom).is_absolute() else base / hom),
    )


def _solver_options(scfg: Mapping[str, Any]) -> None:
    """Type and range checks of the [solver] table's linear-solve keys."""
    from ..solvers.linear import DIRECT_BACKENDS, SOLVERS

    if "name" in scfg and scfg["name"] not in SOLVERS:
        raise SceneError(f"solver.name must be one of {list(SOLVERS)}, got {scfg['name']!r}")
    if "direct_backend" in scfg and scfg["direct_backend"] not in DIRECT_BACKENDS:
        raise SceneError(
            f"solver.direct_backend must be one of {list(DIRECT_BACKENDS)}, got "
            f"{scfg['direct_backend']!r}"
        )
    if "rtol" in scfg:
        rtol = number(scfg["rtol"], "solver.rtol")
        if not (np.isfinite(rtol) and 0 < rtol < 1):
            raise SceneError(f"solver.rtol must be a number in (0, 1), got {rtol}")
    if "maxiter" in scfg:
        mi = scfg["maxiter"]
        if isinstance(mi, bool) or not isinstance(mi, int) or mi < 1:
            raise SceneError(f"solver.maxiter must be an integer >= 1, got {mi!r}")
    from ..backends import BACKENDS

    if "backend" in scfg and scfg["backend"] not in BACKENDS:
        raise SceneError(f"solver.backend must be one of {list(BACKENDS)}, got {scfg['backend']!r}")
    if "petsc_options" in scfg:
        po = scfg["petsc_options"]
        if not isinstance(po, Mapping) or not all(
            isinstance(v, str | int | float) and not isinstance(v, bool) for v in po.values()
        ):
            raise SceneError(
                "solver.petsc_options must be a table of PETSc option names to strings or "
                f"numbers, got {po!r}"
            )
        if scfg.get("backend", "scipy") != "petsc":
            raise SceneError("solver.petsc_options needs solver.backend = 'petsc'")
    if scfg.get("backend") == "petsc" and "nonlinear" in scfg:
        raise SceneError("solver.backend = 'petsc' solves linear scenes; remove solver.nonlinear")


def _nonlinear_options(
    scfg: Mapping[str, Any], problem: StaticProblem, base: Path
) -> dict[str, Any] | None:
    """``solve_nonlinear`` keyword arguments from the [solver] table (None: linear solve)."""
    from ..nonlinear import METHODS

    method = scfg.get("nonlinear")
    given = [k for k in _NONLINEAR_KEYS if k in scfg]
    if method is None:
        if getattr(problem.model, "nonlinear", False):
            method = "auto"
        elif given:
            raise SceneError(
                f"solver.{given[0]} needs a nonlinear solve: add solver.nonlinear = "
                "'auto' | 'newton' | 'adr'"
            )
        else:
            return None
    if method not in METHODS:
        raise SceneError(f"solver.nonlinear must be one of {list(METHODS)}, got {method!r}")
    opts: dict[str, Any] = {"method": method}
    for k in given:
        opts[k] = scfg[k]
    for k in ("steps", "max_cutbacks", "fallback_cutbacks", "relax", "adr_stall"):
        if k in opts:
            v = opts[k]
            lo = 1 if k in ("steps", "adr_stall") else 0
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise SceneError(f"solver.{k} must be an integer >= {lo}, got {v!r}")
    for k in ("newton_backoff", "polish"):
        if k in opts and not isinstance(opts[k], bool):
            raise SceneError(f"solver.{k} must be true or false, got {opts[k]!r}")
    for k in ("t_end", "e_l", "dt"):
        if k in opts:
            number(opts[k], f"solver.{k}", positive=True)
    for k in ("progress_every", "snapshot_every"):
        if k in opts:
            every = number(opts[k], f"solver.{k}")
            if not (np.isfinite(every) and every >= 0):
                raise SceneError(f"solver.{k} must be seconds >= 0, got {every}")
    if "damping" in opts:
        dmp = number(opts["damping"], "solver.damping")
        if not (np.isfinite(dmp) and dmp >= 0):
            raise SceneError(f"solver.damping must be >= 0, got {dmp}")
    if "density" in opts and opts["density"] != "gershgorin":
        if isinstance(opts["density"], str):
            raise SceneError(
                f"solver.density must be 'gershgorin' or a number > 0, got {opts['density']!r}"
            )
        number(opts["density"], "solver.density", positive=True)
    if "checkpoint" in opts:
        ck = opts["checkpoint"]
        if not isinstance(ck, str):
            raise SceneError(f"solver.checkpoint must be a path string, got {ck!r}")
        opts["checkpoint"] = Path(ck) if Path(ck).is_absolute() else base / ck
    if "rtol" in scfg:
        opts["rtol"] = float(scfg["rtol"])
    if "maxiter" in scfg:
        opts["maxiter"] = int(scfg["maxiter"])
    return opts


def load_scene(path: str | Path) -> Scene:
    """Read and validate a TOML scene file.

    Parameters
    ----------
    path : str or Path
        The ``.toml`` file; paths inside it are relative to its folder.

    Returns
    -------
    Scene
        As :func:`scene_from_dict` builds it (nothing is solved).

    Raises
    ------
    SceneError
        A missing file, invalid TOML or an invalid scene key (named by its path).
    """
    data, base = read_toml(path, "scene")
    return scene_from_dict(data, base)


def list_builtin_scenes(*, hidden: bool = False) -> list[str]:
    """List the example scenes shipped with pdlin.

    Names starting with ``_`` are reference scenes used by other scenes' checks; they
    are listed only with ``hidden=True``.

    Names starting with ``_`` are reference scenes used by other scenes' checks; they
    are listed only with ``hidden=True``.

    Parameters
    ----------
    hidden : bool, optional
        Include the reference scenes.

    Returns
    -------
    list of str
        Sorted scene names (``pdlin run --example NAME``).
    """
    files = resources.files("pdlin") / "examples"
    names = sorted(f.name[:-5] for f in files.iterdir() if f.name.endswith(".toml"))
    return names if hidden else [n for n in names if not n.startswith("_")]


def builtin_scene(name: str) -> tuple[dict[str, Any], str]:
    """Read a built-in example scene.

    Parameters
    ----------
    name : str
        One of :func:`list_builtin_scenes` (``hidden=True``).

    Returns
    -------
    data : dict
        The parsed TOML (for :func:`scene_from_dict`).
    text : str
        The file's text.

    Raises
    ------
    SceneError
        An unknown name (the message lists the available ones).
    """
    if name not in list_builtin_scenes(hidden=True):
        raise SceneError(f"unknown built-in scene {name!r}; available: {list_builtin_scenes()}")
    folder = resources.files("pdlin") / "examples"
    text = (folder / f"{name}.toml").read_text()
    data = tomllib.loads(text)
    deck = data.get("deck")
    if isinstance(deck, dict) and isinstance(deck.get("path"), str):
        # a built-in scene's deck ships beside it, in pdlin's examples folder
        p = Path(deck["path"])
        if not p.is_absolute():
            deck["path"] = str(Path(str(folder)) / p)
    return data, text


#: the fields of every static result (:meth:`pdlin.StaticResult.fields`); ``stress`` where
#: the model has one
STATIC_FIELDS = (
    "displacement", "reaction", "family_size", "volume", "material",
    "deformation_gradient", "strain",
)  # fmt: skip


def _check_output_fields(fields: Any, model: Any) -> None:
    """Refuse ``output.fields`` that no static result of ``model`` has, before the work."""
    if not isinstance(fields, list) or not all(isinstance(f, str) for f in fields):
        raise SceneError(f"output.fields must be a list of field names, got {fields!r}")
    known = [*STATIC_FIELDS, *(["stress"] if hasattr(model, "stress") else [])]
    unknown = [f for f in fields if f not in known]
    if unknown:
        raise SceneError(
            f"output.fields: unknown field(s) {unknown} for a {type(model).__name__} model; "
            f"available {sorted(known)}"
        )
