"""Scenes of explicit dynamics: ``[solver] kind = "explicit"``.

The keys (``docs/dynamics.md``, "Scenes"):

* ``[solver]``: ``kind = "explicit"``, ``t_end`` (required), ``dt``, ``safety``,
  ``time_step`` (``'gershgorin'``, ``'silling-askari'``, ``'lanczos'``), ``kinematics``
  (``'small'`` or ``'finite'``), ``output_every``, ``checkpoint``, ``checkpoint_every``,
  ``progress_every``;
* ``[material] density`` (required), or ``density`` in each ``[[block]]``'s material: the
  mass density;
* ``[damage]``: ``critical_stretch`` or ``G0`` (bonds break during the time steps);
* ``[[dirichlet]] velocity = [...]``: a prescribed velocity (the path ``u = v t``).

:func:`explicit_scene` turns them into the keyword arguments of
:func:`pdlin.dynamics.solve_explicit` (``Scene.explicit``); ``pdlin run`` solves them.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..dynamics.timestep import TIME_STEP_METHODS
from ..errors import SceneError
from ..problem import StaticProblem
from ._keys import number, require

__all__ = ["explicit_scene", "explicit_options", "EXPLICIT_KEYS"]

#: [solver] keys of an explicit scene
EXPLICIT_KEYS = {
    "kind",
    "t_end",
    "dt",
    "safety",
    "time_step",
    "kinematics",
    "output_every",
    "checkpoint",
    "checkpoint_every",
    "progress_every",
}
_DAMAGE_KEYS = {"critical_stretch", "G0"}


def _block_densities(top: Mapping[str, Any], blocks: list[Any], n: int) -> np.ndarray:
    """One density per point from the materials of the ``[[block]]`` tables."""
    rho = np.empty(n)
    named = top.get("materials", {})
    for k, blk in enumerate(blocks):
        mat = top["block"][k]["material"]
        key = f"block[{k}].material"
        if isinstance(mat, str):
            key, mat = f"materials.{mat}", named[mat]
        if "density" not in mat:
            raise SceneError(
                f"{key}.density is required by [solver] kind = 'explicit' (the mass density "
                "of the block's material)"
            )
        rho[np.asarray(blk.points, dtype=np.int64)] = number(
            mat["density"], f"{key}.density", positive=True
        )
    return rho


def explicit_options(
    top: Mapping[str, Any],
    scfg: Mapping[str, Any],
    problem: StaticProblem,
    base: Path,
    blocks: list[Any] | None = None,
) -> dict[str, Any]:
    """Return the :func:`pdlin.dynamics.solve_explicit` keywords of an explicit scene.

    Parameters
    ----------
    top : Mapping
        The scene's top-level tables.
    scfg : Mapping
        Its ``[solver]`` table (``kind = "explicit"``).
    problem : StaticProblem
        Its problem.
    base : Path
        Folder of the scene (relative checkpoint paths).
    blocks : list of Block, optional
        The scene's ``[[block]]`` materials: each gives the density of its points.

    Returns
    -------
    dict
        ``t_end``, ``density`` (a number, or one per point with blocks) and the options
        given.

    Raises
    ------
    SceneError
        A key of another kind of run, a missing ``t_end`` or ``material.density``, or a bad
        value, named by its key path.

    Examples
    --------
    >>> import pdlin
    >>> from pathlib import Path
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), pdlin.grid((4,)), ratio=1.5)
    >>> explicit_options({"material": {"E": 1.0, "density": 2.0}},
    ...                  {"kind": "explicit", "t_end": 1.0}, prob, Path("."))
    {'t_end': 1.0, 'density': 2.0}
    >>> explicit_options({"material": {"E": 1.0}}, {"kind": "explicit", "t_end": 1.0},
    ...                  prob, Path("."))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.SceneError: material.density is required by [solver] kind = 'explicit' ...
    """
    other = sorted(set(scfg) - EXPLICIT_KEYS)
    if other:
        hint = (
            " (the mass density is material.density)"
            if other[0] == "density"
            else f"; allowed: {sorted(EXPLICIT_KEYS)}"
        )
        raise SceneError(f"solver.{other[0]} is not used by [solver] kind = 'explicit'{hint}")
    if problem.symmetry:
        raise SceneError("[solver] kind = 'explicit' cannot be combined with [[symmetry]] planes")
    material = top.get("material", {})
    if blocks is not None:
        density: Any = _block_densities(top, blocks, problem.cloud.n)
    elif "density" not in material:
        raise SceneError(
            "material.density is required by [solver] kind = 'explicit' (the mass density, "
            "e.g. 8000.0 kg/m^3 for steel)"
        )
    else:
        density = number(material["density"], "material.density", positive=True)
    opts: dict[str, Any] = {
        "t_end": number(require(scfg, "t_end", "solver"), "solver.t_end", positive=True),
        "density": density,
    }
    if "dt" in scfg:
        opts["dt"] = number(scfg["dt"], "solver.dt", positive=True)
    if "safety" in scfg:
        s = number(scfg["safety"], "solver.safety", positive=True)
        if s > 1:
            raise SceneError(f"solver.safety must be a number in (0, 1], got {s}")
        opts["safety"] = s
    if "time_step" in scfg:
        if scfg["time_step"] not in TIME_STEP_METHODS:
            raise SceneError(
                f"solver.time_step must be one of {list(TIME_STEP_METHODS)}, "
                f"got {scfg['time_step']!r}"
            )
        opts["time_step"] = scfg["time_step"]
    if "kinematics" in scfg:
        if scfg["kinematics"] not in ("small", "finite"):
            raise SceneError(
                f"solver.kinematics must be 'small' or 'finite', got {scfg['kinematics']!r}"
            )
        opts["linear"] = scfg["kinematics"] == "small"
    for key in ("output_every", "checkpoint_every"):
        if key in scfg:
            opts[key] = number(scfg[key], f"solver.{key}", positive=True, integer=True)
    if "progress_every" in scfg:
        every = number(scfg["progress_every"], "solver.progress_every")
        if not every >= 0:
            raise SceneError(f"solver.progress_every must be seconds >= 0, got {every}")
        opts["progress_every"] = every
    if "checkpoint" in scfg:
        ck = scfg["checkpoint"]
        if not isinstance(ck, str):
            raise SceneError(f"solver.checkpoint must be a path string, got {ck!r}")
        opts["checkpoint"] = Path(ck) if Path(ck).is_absolute() else base / ck
    if "damage" in top:
        d = top["damage"]
        extra = sorted(set(d) - _DAMAGE_KEYS)
        if extra:
            raise SceneError(
                f"damage.{extra[0]} is not used by [solver] kind = 'explicit' (bonds break "
                "during the time steps); allowed: ['G0', 'critical_stretch']"
            )
        if len(d) != 1:
            raise SceneError("damage needs exactly one of 'critical_stretch' or 'G0'")
        key = next(iter(d))
        opts[key] = number(d[key], f"damage.{key}", positive=True)
    return opts


def explicit_scene(
    top: Mapping[str, Any],
    base: Path,
    problem: StaticProblem,
    scfg: Mapping[str, Any],
    ocfg: Mapping[str, Any],
    blocks: list[Any] | None = None,
) -> Any:
    """Build the :class:`~pdlin.scene.Scene` of an explicit-dynamics scene.

    Parameters
    ----------
    top : Mapping
        The scene's top-level tables.
    base : Path
        Its folder.
    problem : StaticProblem
        Its problem.
    scfg, ocfg : Mapping
        Its ``[solver]`` and ``[output]`` tables.
    blocks : list of Block, optional
        Its ``[[block]]`` materials (their densities).

    Returns
    -------
    Scene
        With ``explicit`` holding the :func:`pdlin.dynamics.solve_explicit` keywords.

    Raises
    ------
    SceneError
        As :func:`explicit_options`, or an ``[output]`` key other than ``path``.
    """
    from .scene import Scene, _checks

    opts = explicit_options(top, scfg, problem, base, blocks)
    extra = sorted(set(ocfg) - {"path"})
    if extra:
        raise SceneError(
            f"output.{extra[0]} is not used by [solver] kind = 'explicit' (it writes "
            "displacement, velocity and damage every output_every steps)"
        )
    out = ocfg.get("path")
    if out is not None and not isinstance(out, str):
        raise SceneError(f"output.path must be a path string, got {out!r}")
    about = top.get("about", {})
    return Scene(
        name=str(top.get("name", "scene")),
        problem=problem,
        output=None if out is None else (Path(out) if Path(out).is_absolute() else base / out),
        base_dir=base,
        about=dict(about) if isinstance(about, Mapping) else {},
        explicit=opts,
        checks=_checks(top),
    )
