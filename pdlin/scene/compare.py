"""``[compare]`` tables of scene files: a second discretization run beside the scene's own.

``[compare.cpfe]`` (or ``[compare] cpfe = true``) makes ``pdlin run`` solve a
crystal-plasticity scene a second time by crystal-plasticity finite elements
(``pdlin.verification.crystal_plasticity_fem``: Q4 / Hex8 F-bar elements centred on the
particles, Luo, Ramazani & Sundararaghavan 2017, Sec. 4), on the same load steps, and
report the gap of the homogenized stress curves per step.  Loading the scene checks the
table and whether the comparator can run on the scene (a complete pixel grid, Dirichlet
paths on named point sets, no loads); it never solves.

Keys of ``[compare.cpfe]``:

``integration``
    ``"fbar"`` (default) or ``"full"`` (plain 2 x 2 (x 2) Gauss rule).
``method``
    Load-step driver of the element system: ``"auto"`` (default: Newton with an ADR
    fallback per step, as ``[tradeoff] reference = "cpfe"``), ``"newton"`` or ``"adr"``.
``output``
    The CPFE time series (default ``<scene output stem>_cpfe<suffix>``), the fields on the
    particles (element centres).
``homogenized``
    Its homogenized CSV (default ``<series stem>_homogenized.csv``).
``tolerance``
    Optional: the largest relative gap ``(|CPPD| - |CPFE|) / |CPFE|`` of the compared
    stress component over the steps that passes (a PASS/FAIL line; ``pdlin run --strict``
    returns 5 on FAIL).
``component``
    The compared homogenized stress component (``"xy"``, ``"yy"``, ...; default: the
    component of largest magnitude of the CPFE curve's last step).

The load steps (``solver.steps``, ``t_end``) and the Newton options (``rtol``,
``maxiter``, ``predictor``, ``max_cutbacks``, ``fallback_cutbacks``, ``linear_solver``,
``e_l``) of ``[solver]`` apply to both runs.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SceneError
from ._keys import number, scene_keys

__all__ = [
    "COMPARATORS",
    "CPFE_KEYS",
    "compare_options",
    "cpfe_keywords",
    "cpfe_problem",
    "homogenized_gap",
    "stress_component",
]

#: the discretizations a ``[compare]`` table can run
COMPARATORS = {"cpfe"}
#: keys of ``[compare.cpfe]``
CPFE_KEYS = {"integration", "method", "output", "homogenized", "tolerance", "component"}
#: ``[solver]`` options of the scene passed on to the comparator
_SHARED = (
    "steps",
    "t_end",
    "rtol",
    "maxiter",
    "predictor",
    "max_cutbacks",
    "fallback_cutbacks",
    "linear_solver",
    "e_l",
)


def stress_component(name: Any, dim: int, key: str) -> tuple[int, int]:
    """Parse a stress component name (``"xy"``) into its indices.

    Parameters
    ----------
    name : str
        Two axis letters of ``xyz`` (``dim`` of them allowed).
    dim : int
        Spatial dimension.
    key : str
        The key path for messages.

    Returns
    -------
    tuple of int
        ``(i, j)`` with ``i <= j``.

    Raises
    ------
    SceneError
        Not two letters of the first ``dim`` axes.

    Examples
    --------
    >>> stress_component("yx", 2, "compare.cpfe.component")
    (0, 1)
    >>> stress_component("zz", 2, "compare.cpfe.component")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.SceneError: compare.cpfe.component must be two of the axes 'xy' ...
    """
    axes = "xyz"[:dim]
    if not (isinstance(name, str) and len(name) == 2 and all(c in axes for c in name)):
        raise SceneError(f"{key} must be two of the axes {axes!r} (e.g. 'xy'), got {name!r}")
    i, j = sorted(axes.index(c) for c in name)
    return i, j


def _real_grid_problem(problem: Any, n_real: int, real_cloud: Any) -> Any:
    """Return the scene's problem on its real pixels: ghosts and their conditions dropped.

    The ghost layer gives the peridynamic boundary points complete families; the elements
    on the pixels need none, and their nodes on the outer ring carry the ``boundary`` path.
    """
    import copy

    from ..models.correspondence import Correspondence
    from ..problem import StaticProblem

    pts = np.asarray(problem.cloud.points)[:n_real]
    if real_cloud is None or real_cloud.n != n_real or not np.allclose(pts, real_cloud.points):
        raise SceneError(  # pragma: no cover - ghost_layer keeps the real points first
            "compare.cpfe: the real points of the ghost-layer scene are not its grid"
        )
    material = copy.copy(problem.model.material)
    ori = np.asarray(material.orientation)
    if ori.ndim and ori.shape[0] == problem.cloud.n:  # per point: the real points' rows
        material.orientation = ori[:n_real]
    bcs = [bc for bc in problem.dirichlet if bc.where != "ghost"]
    h = problem.horizon
    if np.ndim(h):  # per point (the elements do not use it; the problem keeps it)
        h = np.asarray(h)[:n_real]
    return StaticProblem(
        Correspondence(material=material),
        real_cloud,
        horizon=h,
        dirichlet=bcs,
        bond_options=dict(problem.bond_options or {}),
    )


def _cpfe_applies(
    problem: Any, nonlinear: Mapping[str, Any] | None, n_real: int, real_cloud: Any = None
) -> Any:
    """Return the problem the comparator solves, or raise a SceneError naming why it cannot.

    A ghost-layer scene gives the problem on its real pixels (``real_cloud``).
    """
    from ..constitutive import CrystalPlasticity

    if nonlinear is None:
        raise SceneError(
            "compare.cpfe compares crystal-plasticity load steps: the scene is linear (give "
            "material.type = 'crystal-plasticity' with model.type = 'correspondence')"
        )
    material = getattr(problem.model, "material", None)
    if not isinstance(material, CrystalPlasticity):
        got = type(material).__name__ if material is not None else type(problem.model).__name__
        raise SceneError(
            "compare.cpfe needs material.type = 'crystal-plasticity' (a CrystalPlasticity "
            f"material of a correspondence model), got {got}"
        )
    if problem.cloud.n != n_real:
        if real_cloud is None:
            raise SceneError(
                "compare.cpfe builds its elements on the pixels of the grid: remove "
                f"geometry.ghost_layers (the scene has {problem.cloud.n - n_real} ghost "
                "point(s), a peridynamic boundary device the elements do not need)"
            )
        problem = _real_grid_problem(problem, n_real, real_cloud)
    cloud = problem.cloud
    lat = getattr(cloud, "lattice", None)
    if lat is None or lat.index is not None or cloud.dim not in (2, 3):
        raise SceneError(
            "compare.cpfe needs a complete 2D or 3D pixel grid (geometry.type = 'grid' "
            "without holes, or an image without voids), got "
            + ("points without a lattice" if lat is None else f"a {cloud.dim}D grid")
            + (" with missing cells" if lat is not None and lat.index is not None else "")
        )
    for k, bc in enumerate(problem.dirichlet):
        if not isinstance(bc.where, str):
            raise SceneError(
                f"compare.cpfe resolves dirichlet[{k}] on the element nodes by its set name: "
                "give it set = 'boundary', 'x-', ... instead of box or points"
            )
    if problem.loads:
        raise SceneError(
            f"compare.cpfe runs Dirichlet paths only, got {len(problem.loads)} load(s) "
            "([[load]] or a [shadow] stress layer)"
        )
    if problem.symmetry:
        raise SceneError("compare.cpfe does not support [[symmetry]] planes")
    return problem


def compare_options(
    table: Any,
    problem: Any,
    nonlinear: Mapping[str, Any] | None,
    n_real: int,
    base: Path,
    real_cloud: Any = None,
) -> dict[str, Any] | None:
    """Check a scene's ``[compare]`` table; return its options (None: no table).

    Parameters
    ----------
    table : Mapping or None
        The ``[compare]`` table as read.
    problem : StaticProblem
        The scene's problem.
    nonlinear : Mapping or None
        The scene's ``solve_nonlinear`` options (None: a linear scene).
    n_real : int
        Number of real (not ghost) points.
    base : Path
        The scene's folder (relative output paths).
    real_cloud : PointCloud, optional
        The grid of the real points of a ghost-layer scene (the comparator's pixels; its
        ``ghost`` conditions are dropped).  Without it, ghost points are refused.

    Returns
    -------
    dict or None
        ``{"cpfe": {...}}`` with ``integration``, ``method``, ``output``,
        ``homogenized``, ``tolerance``, ``component`` (None when not given) and
        ``problem``, the problem the comparator solves (:func:`cpfe_problem`).

    Raises
    ------
    SceneError
        An unknown key or a bad value (named by its key path), or a scene the comparator
        cannot run on (linear, not crystal plasticity, ghosts, holes, boxes, loads).

    Examples
    --------
    >>> from pathlib import Path
    >>> from pdlin.scene import scene_from_dict
    >>> sc = scene_from_dict({"geometry": {"type": "grid", "shape": [4, 4]},
    ...     "material": {"E": 1.0, "nu": 0.25}, "horizon": {"ratio": 1.5},
    ...     "model": {"type": "correspondence"}, "dirichlet": [{"set": "x-"}]})
    >>> compare_options({"cpfe": {"integraton": "full"}}, sc.problem, {}, 16, Path("."))
    ... # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.SceneError: unknown scene key 'compare.cpfe.integraton'; did you mean ...
    """
    if table is None:
        return None
    from ..solvers.options import METHODS
    from ..verification.cpfe import INTEGRATIONS

    top = scene_keys(table, COMPARATORS, "compare")
    out: dict[str, Any] = {}
    if "cpfe" not in top:
        return None
    raw = top["cpfe"]
    if raw is False:
        return None
    if raw is True:
        raw = {}
    if not isinstance(raw, Mapping):
        raise SceneError(f"compare.cpfe must be true or a table, got {type(raw).__name__} {raw!r}")
    cfg = scene_keys(raw, CPFE_KEYS, "compare.cpfe")
    integration = cfg.get("integration", "fbar")
    if integration not in INTEGRATIONS:
        raise SceneError(
            f"compare.cpfe.integration must be one of {list(INTEGRATIONS)}, got {integration!r}"
        )
    method = cfg.get("method", "auto")
    if method not in METHODS:
        raise SceneError(f"compare.cpfe.method must be one of {list(METHODS)}, got {method!r}")
    paths: dict[str, Path | None] = {}
    for key in ("output", "homogenized"):
        v = cfg.get(key)
        if v is not None and not isinstance(v, str):
            raise SceneError(f"compare.cpfe.{key} must be a path string, got {v!r}")
        paths[key] = None if v is None else (Path(v) if Path(v).is_absolute() else base / v)
    tol = cfg.get("tolerance")
    if tol is not None:
        tol = number(tol, "compare.cpfe.tolerance", positive=True)
    comp = cfg.get("component")
    if comp is not None:
        stress_component(comp, problem.cloud.dim, "compare.cpfe.component")
    fe_problem = _cpfe_applies(problem, nonlinear, n_real, real_cloud)
    out["cpfe"] = {
        "problem": fe_problem,
        "integration": integration,
        "method": method,
        "output": paths["output"],
        "homogenized": paths["homogenized"],
        "tolerance": tol,
        "component": comp,
    }
    return out


def cpfe_keywords(scene: Any) -> dict[str, Any]:
    """Return the keyword arguments of ``crystal_plasticity_fem`` for a scene's comparison.

    The scene's load steps and Newton options, the ``[compare.cpfe]`` integration rule
    and method: ``crystal_plasticity_fem(cpfe_problem(scene), **cpfe_keywords(scene))``
    is the run ``pdlin run`` makes.

    Parameters
    ----------
    scene : Scene
        A scene with a ``[compare.cpfe]`` table.

    Returns
    -------
    dict
        ``integration``, ``method`` and the shared ``[solver]`` options given.

    Raises
    ------
    SceneError
        The scene has no ``[compare.cpfe]`` table.

    Examples
    --------
    >>> from pdlin.scene.scene import builtin_scene, scene_from_dict
    >>> data, _ = builtin_scene("cp_shear")
    >>> data["compare"] = {"cpfe": {"integration": "full"}}
    >>> sorted(cpfe_keywords(scene_from_dict(data)).items())
    [('integration', 'full'), ('method', 'auto'), ('steps', 30), ('t_end', 30.0)]
    """
    cmp = getattr(scene, "compare", None)
    if not cmp or "cpfe" not in cmp:
        raise SceneError("the scene has no [compare.cpfe] table")
    nl = scene.nonlinear or {}
    kw = {k: nl[k] for k in _SHARED if k in nl}
    kw["integration"] = cmp["cpfe"]["integration"]
    kw["method"] = cmp["cpfe"]["method"]
    return kw


def cpfe_problem(scene: Any) -> Any:
    """Return the problem the CPFE comparator of a scene solves.

    The scene's problem, or for a ghost-layer scene the same body on its real pixels (the
    ghosts and their ``ghost`` conditions dropped; the orientations of the real points).

    Parameters
    ----------
    scene : Scene
        A scene with a ``[compare.cpfe]`` table.

    Returns
    -------
    StaticProblem
        ``crystal_plasticity_fem(cpfe_problem(scene), **cpfe_keywords(scene))`` is the run
        ``pdlin run`` makes.

    Raises
    ------
    SceneError
        The scene has no ``[compare.cpfe]`` table.

    Examples
    --------
    >>> from pdlin.scene.scene import builtin_scene, scene_from_dict
    >>> data, _ = builtin_scene("cp_single_crystal")
    >>> data["compare"] = {"cpfe": True}
    >>> sc = scene_from_dict(data)
    >>> sc.problem.cloud.n, cpfe_problem(sc).cloud.n      # 10 x 10 pixels + 44 ghosts
    (144, 100)
    """
    cmp = getattr(scene, "compare", None)
    if not cmp or "cpfe" not in cmp:
        raise SceneError("the scene has no [compare.cpfe] table")
    return cmp["cpfe"]["problem"] or scene.problem


def homogenized_gap(cppd: Any, cpfe: Any, component: tuple[int, int]) -> dict[str, np.ndarray]:
    """Gap of two homogenized stress histories in one component.

    Parameters
    ----------
    cppd, cpfe : (k, d, d) array_like
        The homogenized stress per step of the scene's run and of the comparator.
    component : tuple of int
        ``(i, j)``.

    Returns
    -------
    dict
        ``cppd``, ``cpfe`` (the component per step), ``difference`` (CPPD - CPFE) and
        ``relative`` ``(|CPPD| - |CPFE|) / |CPFE|`` (negative: CPPD below CPFE; NaN where
        CPFE is 0).

    Examples
    --------
    >>> g = homogenized_gap([[[0, 9.0], [9.0, 0]]], [[[0, 10.0], [10.0, 0]]], (0, 1))
    >>> float(g["difference"][0]), float(g["relative"][0])
    (-1.0, -0.1)
    """
    i, j = component
    a = np.asarray(cppd, dtype=float)[:, i, j]
    b = np.asarray(cpfe, dtype=float)[:, i, j]
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(b != 0.0, (np.abs(a) - np.abs(b)) / np.abs(np.where(b != 0, b, 1.0)), np.nan)
    return {"cppd": a, "cpfe": b, "difference": a - b, "relative": rel}
