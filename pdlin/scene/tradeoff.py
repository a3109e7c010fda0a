"""``[tradeoff]`` tables of scene files: sweep a scene's own parameters.

The base problem is built by :func:`pdlin.scene.scene_from_dict`; every sweep point edits a
copy of the parsed scene (model, control, horizon ratio, spacing, influence function or
any dotted key) and builds it again.  See ``docs/tradeoff.md``.

.. code-block:: toml

    [tradeoff]
    reference = "closed-form"      # auto | closed-form | fem | finest | cpfe (nonlinear)
    metric = "rel-max"             # rel-max | rel-l2 | max-abs
    target_error = 0.05            # report the fastest configuration meeting it
    output = "bar_tradeoff.csv"    # each point appended as it finishes (.csv | .jsonl)
    plot = "bar_tradeoff.png"
    timeout = 120.0                # seconds per point
    measure = [[0.1, 0.0, 0.0], [0.5, 0.12, 0.12]]   # box where the error is measured

    [tradeoff.sweep]               # every combination is one point
    model = ["bond_based", "lps", "correspondence:penalty"]
    m = [2.0, 3.015]               # horizon.ratio
    h = [0.02, 0.01]               # geometry.spacing (the shape is rescaled to keep the box)
    influence = ["constant", "inverse"]
    solver = ["direct", "amg-cg"]  # also rtol, operator, maxiter
    # "model.surface_correction" = ["energy"]   # any dotted scene key

    [tradeoff.exact]               # closed form u = (F - I)(X - center) + translation
    F = [[1.000005, 0, 0], [0, 0.99999875, 0], [0, 0, 0.99999875]]
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PdlinError, SceneError
from ..sweeps.core import SOLVE_KEYS, TradeoffCase, TradeoffResult, tradeoff
from ._keys import check_keys, read_toml

__all__ = [
    "SceneSweep",
    "load_tradeoff",
    "tradeoff_from_dict",
    "run_scene_tradeoff",
    "select_scene",
]

_TRADEOFF = {
    "sweep",
    "reference",
    "metric",
    "target_error",
    "output",
    "plot",
    "timeout",
    "measure",
    "exact",
    "finest",
}
_EXACT = {"F", "center", "translation"}
_MODEL_ALIASES = {"bb": "bond_based", "cor": "correspondence"}


@dataclass
class SceneSweep:
    """A scene with its ``[tradeoff]`` table: the factory and the sweep options.

    Attributes
    ----------
    data : dict
        The parsed scene without its ``[tradeoff]`` table.
    grid : dict
        Swept parameters and their values.
    options : dict
        Keyword arguments of :func:`pdlin.tradeoff` (reference, metric, target_error,
        output, timeout, finest).
    plot : Path, optional
    """

    data: dict[str, Any]
    grid: dict[str, list[Any]]
    options: dict[str, Any] = field(default_factory=dict)
    plot: Path | None = None
    base_dir: Path = field(default_factory=Path.cwd)
    exact_F: np.ndarray | None = None
    exact_center: np.ndarray | None = None
    exact_translation: np.ndarray | None = None
    measure_box: np.ndarray | None = None

    def scene_data(self, **params: Any) -> dict[str, Any]:
        """Return the scene dictionary of one sweep point (solver keys excluded).

        Parameters
        ----------
        **params
            The point's value of each swept key (``h``, ``m``, ``model``, ...).

        Returns
        -------
        dict
            A deep copy of the base scene with the point's edits.
        """
        data = copy.deepcopy(self.data)
        for key, value in params.items():
            if key in SOLVE_KEYS:
                continue
            _apply(data, key, value)
        return data

    def factory(self, **params: Any) -> TradeoffCase:
        """Build one point's case (the factory passed to :func:`pdlin.tradeoff`).

        Parameters
        ----------
        **params
            The point's value of each swept key.

        Returns
        -------
        TradeoffCase
            The point's problem, reference and solve options.
        """
        from .scene import scene_from_dict

        data = self.scene_data(**params)
        sc = scene_from_dict(data, self.base_dir)
        kw: dict[str, Any] = {"solver": sc.solver, "rtol": sc.rtol}
        if sc.maxiter is not None:
            kw["maxiter"] = sc.maxiter
        exact: Callable[[np.ndarray], np.ndarray] | None = None
        if self.exact_F is not None:
            F = self.exact_F
            d = F.shape[0]
            c = np.zeros(d) if self.exact_center is None else self.exact_center
            t = np.zeros(d) if self.exact_translation is None else self.exact_translation

            def exact(X: np.ndarray) -> np.ndarray:
                return np.asarray((X - c) @ (F - np.eye(d)).T + t)

        cloud = sc.problem.cloud
        measure = None
        if self.measure_box is not None:
            lo, hi = self.measure_box
            try:  # NaN corners and inverted boxes raise (-inf / inf are open sides)
                measure = cloud.select(box=(lo, hi))
            except PdlinError as exc:
                raise SceneError(f"tradeoff.measure: {exc}") from exc
            if measure.size == 0:
                raise SceneError(f"tradeoff.measure selects no points: {self.measure_box.tolist()}")
        h = None
        if cloud.lattice is not None:
            h = float(np.max(cloud.lattice.spacing))
        if sc.nonlinear is not None:
            if exact is not None or measure is not None:
                raise SceneError(
                    "tradeoff.exact and tradeoff.measure apply to linear scenes; a nonlinear "
                    "scene's error is that of its homogenized stress history (reference = "
                    "'finest')"
                )
            nl = dict(sc.nonlinear)
            if "rtol" in kw and "rtol" not in nl:
                nl["rtol"] = kw["rtol"]
            if sc.maxiter is not None:
                nl.setdefault("maxiter", sc.maxiter)
            ref_nl = None
            if self.options.get("reference") == "cpfe":
                if sc.compare is None:  # the comparator's defaults and its checks
                    sc = scene_from_dict({**data, "compare": {"cpfe": {}}}, self.base_dir)
                ref_nl = _cpfe_reference(sc, nl)
            return TradeoffCase(sc.problem, {}, h=h, nonlinear=nl, reference=ref_nl)
        if self.options.get("reference") == "cpfe":
            raise SceneError("tradeoff.reference = 'cpfe' applies to nonlinear scenes only")
        reference = None
        if self.options.get("reference") == "fem":
            from ..verification.fem import grid_fe_reference

            problem = sc.problem

            def reference() -> np.ndarray:
                return grid_fe_reference(problem)

        return TradeoffCase(sc.problem, kw, exact=exact, reference=reference, measure=measure, h=h)

    def run(self, **kwargs: Any) -> TradeoffResult:
        """Run the sweep (keyword arguments override the scene's options).

        Parameters
        ----------
        **kwargs
            Keyword arguments of :func:`pdlin.tradeoff` (override the scene's).

        Returns
        -------
        TradeoffResult
            One row per sweep point: error, time, memory.
        """
        opts = {**self.options, **kwargs}
        if opts.get("reference") == "cpfe":  # the cases carry the CPFE history
            opts["reference"] = "fem"
        return tradeoff(self.factory, self.grid, **opts)


def _cpfe_reference(scene: Any, nl: Mapping[str, Any]) -> Callable[[], np.ndarray]:
    """Return the CPFE homogenized stress history of a scene as a callable (``cpfe``).

    Q4 / Hex8 elements centred on the particles (``pdlin.verification.cpfe``) on the
    scene's real pixels (``pdlin.scene.compare.cpfe_problem``), its ``[compare.cpfe]``
    integration rule and method (default F-bar, ``auto``), the load steps and Newton
    tolerance of the sweep point.
    """
    from .compare import cpfe_problem

    problem = cpfe_problem(scene)
    cfg = scene.compare["cpfe"]

    def reference() -> np.ndarray:
        from ..verification.cpfe import crystal_plasticity_fem

        keys = ("steps", "t_end", "times", "rtol", "maxiter")
        res = crystal_plasticity_fem(
            problem,
            integration=cfg["integration"],
            method=cfg["method"],
            **{k: nl[k] for k in keys if k in nl},
        )
        return np.asarray(res.homogenized_stress)

    return reference


def _set(data: dict[str, Any], path: str, value: Any) -> None:
    parts = path.split(".")
    node = data
    for p in parts[:-1]:
        node = node.setdefault(p, {})
        if not isinstance(node, dict):
            raise SceneError(f"tradeoff.sweep: {path!r} does not name a scene table key")
    node[parts[-1]] = value


def rescale_grid(data: dict[str, Any], h: float, where: str) -> None:
    """Set a grid scene's spacing to ``h``, keeping its box (the shape is rescaled).

    Shared by sweeps over ``h`` and the coarse run of ``[subregion]`` scenes; ``where``
    names the scene key that asked for it in the errors.

    Parameters
    ----------
    data : dict
        A scene dictionary with ``geometry.type = "grid"``; edited in place.
    h : float
        The new spacing.
    where : str
        The scene key that asked for it (``tradeoff.sweep.h``, ``subregion.coarse``).

    Raises
    ------
    SceneError
        A non-grid geometry, or conditions or loads selecting points by index (the new
        grid has other points); named by ``where``.
    """
    geo = data.get("geometry", {})
    if geo.get("type", "grid") != "grid":
        raise SceneError(f"{where}: needs geometry.type = 'grid'")
    old = np.broadcast_to(np.asarray(geo.get("spacing", 1.0), dtype=float), (len(geo["shape"]),))
    size = np.asarray(geo["shape"], dtype=float) * old
    geo["shape"] = [max(int(round(s / h)), 1) for s in size]
    geo["spacing"] = h
    for kind in ("dirichlet", "load"):
        for k, bc in enumerate(data.get(kind, [])):
            if "points" in bc:
                raise SceneError(
                    f"{where}: the spacing changes the grid, so {kind}[{k}].points (point "
                    "indices) would select other points; use set or box"
                )


def _apply(data: dict[str, Any], key: str, value: Any) -> None:
    if key == "model":
        base, _, control = str(value).partition(":")
        base = _MODEL_ALIASES.get(base, base)
        model = data.setdefault("model", {})
        keep = {"surface_correction"} if base in ("bond_based", "lps") else set()
        for k in list(model):
            if k not in keep:
                del model[k]
        model["type"] = base
        if control:
            model["control"] = control
    elif key == "control":
        data.setdefault("model", {})["control"] = value
    elif key in ("m", "ratio"):
        hz = data.setdefault("horizon", {})
        hz.pop("value", None)
        hz["ratio"] = float(value)
    elif key == "influence":
        data.setdefault("horizon", {})["influence"] = value
    elif key == "h":
        rescale_grid(data, float(value), "tradeoff.sweep.h")
    elif "." in key:
        _set(data, key, value)
    else:
        raise SceneError(
            f"unknown tradeoff.sweep key {key!r}: use model, control, m (or ratio), h, "
            f"influence, {', '.join(SOLVE_KEYS)} or a dotted scene key such as "
            "'model.surface_correction'"
        )


def tradeoff_from_dict(data: Mapping[str, Any], base_dir: str | Path | None = None) -> SceneSweep:
    """Build a :class:`SceneSweep` from a parsed scene with a ``[tradeoff]`` table.

    Parameters
    ----------
    data : Mapping
        The parsed scene.
    base_dir : str or Path, optional
        Folder of the scene's relative paths (default: the working directory).

    Returns
    -------
    SceneSweep
        The base scene, the swept keys and the sweep's options.

    Raises
    ------
    SceneError
        No ``[tradeoff]`` table, or an invalid key of it (named by its path).

    Examples
    --------
    >>> sw = tradeoff_from_dict({
    ...     "geometry": {"type": "grid", "shape": [20], "spacing": 0.05},
    ...     "material": {"E": 1.0},
    ...     "horizon": {"ratio": 3.015},
    ...     "dirichlet": [{"set": "x-", "value": 0.0}],
    ...     "load": [{"type": "total", "set": "x+", "force": [1e-3]}],
    ...     "tradeoff": {"sweep": {"m": [2.0, 3.015], "h": [0.05, 0.025]}},
    ... })
    >>> sw.grid, sw.scene_data(h=0.025)["geometry"]["shape"]
    ({'m': [2.0, 3.015], 'h': [0.05, 0.025]}, [40])
    """
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    scene = dict(data)
    if "tradeoff" not in scene:
        raise SceneError("missing scene key tradeoff (a [tradeoff] table with a [tradeoff.sweep])")
    t = check_keys(scene.pop("tradeoff"), _TRADEOFF, "tradeoff", what="scene key")
    sweep = check_keys(t.get("sweep", {}), set(t.get("sweep", {})), "tradeoff.sweep")
    if not sweep:
        raise SceneError("tradeoff.sweep must list at least one parameter")
    grid = {k: (list(v) if isinstance(v, list) else [v]) for k, v in sweep.items()}
    for k in grid:
        if k not in SOLVE_KEYS:
            _apply(copy.deepcopy(scene), k, grid[k][0])  # unknown keys fail early
    opts: dict[str, Any] = {}
    exact = t.get("exact")
    sw = SceneSweep(scene, grid, opts, base_dir=base)
    if exact is not None:
        ex = check_keys(exact, _EXACT, "tradeoff.exact", what="scene key")
        if "F" not in ex:
            raise SceneError("missing scene key tradeoff.exact.F")
        sw.exact_F = np.asarray(ex["F"], dtype=float)
        if sw.exact_F.ndim != 2 or sw.exact_F.shape[0] != sw.exact_F.shape[1]:
            raise SceneError(f"tradeoff.exact.F must be a square matrix, got {ex['F']!r}")
        if "center" in ex:
            sw.exact_center = np.asarray(ex["center"], dtype=float)
        if "translation" in ex:
            sw.exact_translation = np.asarray(ex["translation"], dtype=float)
    opts["reference"] = t.get("reference", "closed-form" if exact is not None else "finest")
    if opts["reference"] not in ("auto", "closed-form", "fem", "finest", "cpfe"):
        raise SceneError(
            "tradeoff.reference must be 'auto', 'closed-form', 'fem', 'finest' or 'cpfe', got "
            f"{opts['reference']!r}"
        )
    if opts["reference"] == "closed-form" and exact is None:
        raise SceneError("tradeoff.reference = 'closed-form' needs a [tradeoff.exact] table")
    if "metric" in t:
        opts["metric"] = t["metric"]
    if "target_error" in t:
        opts["target_error"] = float(t["target_error"])
    if "timeout" in t:
        opts["timeout"] = float(t["timeout"])
    if "finest" in t:
        opts["finest"] = dict(t["finest"])
    if "output" in t:
        out = Path(t["output"])
        opts["output"] = out if out.is_absolute() else base / out
    if "plot" in t:
        pl = Path(t["plot"])
        sw.plot = pl if pl.is_absolute() else base / pl
    if "measure" in t:
        try:
            box = np.asarray(t["measure"], dtype=float)
        except (TypeError, ValueError) as exc:
            raise SceneError(f"tradeoff.measure must be [[lower...], [upper...]]: {exc}") from exc
        if np.isnan(box).any():
            raise SceneError(
                "tradeoff.measure must hold numbers (-inf / inf for open sides), got "
                f"{t['measure']}"
            )
        if box.ndim != 2 or box.shape[0] != 2:
            raise SceneError(
                f"tradeoff.measure must be [[lower...], [upper...]], got {t['measure']}"
            )
        sw.measure_box = box
    return sw


def load_tradeoff(path: str | Path) -> SceneSweep:
    """Read a scene file with a ``[tradeoff]`` table.

    Parameters
    ----------
    path : str or Path
        The scene ``.toml`` file.

    Returns
    -------
    SceneSweep
        As :func:`tradeoff_from_dict` builds it.
    """
    data, base = read_toml(path, "scene")
    return tradeoff_from_dict(data, base)


def run_scene_tradeoff(path: str | Path, **kwargs: Any) -> TradeoffResult:
    """Run :func:`pdlin.tradeoff` on a scene file's ``[tradeoff]`` sweep.

    Parameters
    ----------
    path : str or Path
        The scene ``.toml`` file.
    **kwargs
        Keyword arguments of :meth:`SceneSweep.run`.

    Returns
    -------
    TradeoffResult
        One row per sweep point.
    """
    return load_tradeoff(path).run(**kwargs)


def select_scene(
    path: str | Path,
    *,
    target_error: float | None = None,
    output: str | Path | None = None,
    resume: bool = True,
    progress: Callable[..., Any] | None = None,
) -> tuple[Any, dict[str, Any], TradeoffResult]:
    """Pick the scene's fastest measured configuration meeting its error target.

    "Model only what a scene requires": runs (or resumes) the scene's ``[tradeoff]``
    sweep, takes the fastest row whose error is at most ``target_error`` (default
    ``tradeoff.target_error``) and returns that configuration as a
    :class:`~pdlin.scene.Scene` ready to solve, with the chosen parameters and the
    sweep's result.

    Parameters
    ----------
    path : str or Path
        The scene ``.toml`` file with a ``[tradeoff]`` table.
    target_error : float, optional
        Largest error accepted (default ``tradeoff.target_error``).
    output : str or Path, optional
        Where the sweep's table is written and resumed from.
    resume : bool, optional
        Reuse the finished points of an earlier run.
    progress : callable, optional
        Called with progress messages.

    Returns
    -------
    scene : Scene
        The chosen configuration, ready to solve.
    chosen : dict
        Its parameters.
    result : TradeoffResult
        The sweep.

    Raises
    ------
    SceneError
        Without a target, or when no configuration of the sweep meets it (the message
        gives the smallest error measured).
    """
    from .scene import scene_from_dict

    sweep = load_tradeoff(path)
    target = target_error if target_error is not None else sweep.options.get("target_error")
    if target is None:
        raise SceneError(
            "selecting a configuration needs tradeoff.target_error in the scene "
            "(or --target-error), got none"
        )
    opts: dict[str, Any] = {"resume": resume, "target_error": float(target)}
    if output is not None:
        opts["output"] = Path(output)
    elif sweep.options.get("output") is None:
        opts["output"] = Path(path).with_name(f"{Path(path).stem}_tradeoff.csv")
    if progress is not None:
        opts["progress"] = progress
    result = sweep.run(**opts)
    row = result.best(float(target))
    if row is None:
        errs = [float(r["error"]) for r in result.ok()]
        best = f"{min(errs):.3g}" if errs else "none (no point succeeded)"
        raise SceneError(
            f"no configuration of the sweep meets tradeoff.target_error = {target:g}; "
            f"smallest error measured: {best}"
        )
    # rows read back from a resumed table hold strings: map them onto the grid's values
    params: dict[str, Any] = {}
    for p in result.params:
        values = sweep.grid.get(p, [row[p]])
        params[p] = next((v for v in values if str(v) == str(row[p])), row[p])
    scene = scene_from_dict(sweep.scene_data(**params), sweep.base_dir)
    if "solver" in params:
        scene.solver = str(params["solver"])
    if "rtol" in params:
        scene.rtol = float(params["rtol"])
    if "maxiter" in params and params["maxiter"] is not None:
        scene.maxiter = int(params["maxiter"])
    return scene, params, result
