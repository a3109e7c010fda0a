"""Peridigm's explicit (``Solver.Verlet``) decks as explicit-dynamics scenes.

Peridigm's ``executeExplicit`` (``src/core/Peridigm.cpp``) is velocity Verlet: per step
``v ← v + ½Δt a``, prescribed DOFs get the velocity ``(g(t) - g(t - Δt)) / Δt``,
``u ← u + Δt v``, damage, then the force and ``v ← v + ½Δt a``, with
``⌊(Final Time - Initial Time) / Δt⌋`` steps; :func:`pdlin.dynamics.solve_explicit` takes the
same steps.  The reader maps (``docs/decks.md``, "Explicit (Verlet) decks"):

* ``Solver.Verlet.Fixed dt`` (times ``Safety Factor``) -> ``dt``; without ``Fixed dt``
  pdlin's stable estimate times ``Safety Factor`` (Peridigm's own estimate differs);
* ``Materials.<m>.Density`` -> the density of the blocks of that material;
* ``Initial Velocity`` / ``Initial Displacement`` -> ``v0`` / ``u0``;
* ``Prescribed Displacement`` -> a :class:`~pdlin.TimePath` ``g(t0 + t) - g(t0)``
  (Peridigm's ``DirichletIncrementBC``: the displacement changes by the increments of
  its value; a value nonzero at the initial time is not applied at once);
* ``Body Force`` (constant in time) -> a body force;
* ``Damage Models.<d>.Damage Model: "Critical Stretch"`` on every block -> the critical
  stretch of the bonds (Peridigm's ``critical_stretch_damage_model.cxx``: the exact
  stretch, irreversible);
* ``Elastic`` -> :class:`pdlin.LPS` (``peridigm=True``, ``linearization="paper"``) with
  the exact extension: Peridigm's ``elastic.cxx`` force with bond damage;
  ``Elastic Bond Based`` -> :class:`pdlin.BondBased` with the exact stretch
  (``elastic_bond_based.cxx``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import SceneError
from ...geometry.cloud import PointCloud
from ...operators.bc import BodyForce, Dirichlet, TimePath
from ..materials import Block, blocks_per_point
from ..scene import Scene
from ._common import _COORD, _number, _table, _tidy, _unknown
from .expressions import deck_expression

__all__ = ["verlet_scene", "PD_VERLET"]

#: keys of ``Solver.Verlet`` (Peridigm.cpp, executeExplicit)
PD_VERLET = {"Fixed dt": "", "Safety Factor": "", "Verbose": "cosmetic"}
_SOLVER = {"Verbose": "", "Initial Time": "", "Final Time": "", "Verlet": ""}
_BC_TYPES = ("PRESCRIBED_DISPLACEMENT", "BODY_FORCE", "INITIAL_VELOCITY", "INITIAL_DISPLACEMENT")


def _steps(solver: Mapping[str, Any]) -> tuple[float, float, int]:
    """Return ``t0``, ``dt`` (None: estimate) and the number of steps of ``Solver.Verlet``."""
    _unknown(solver, _SOLVER, "Solver", "Peridigm Verlet solver")
    ver = _table(solver["Verlet"], "Solver.Verlet")
    _unknown(ver, PD_VERLET, "Solver.Verlet", "Peridigm Verlet solver")
    t0 = _number(solver.get("Initial Time", 0.0), "Solver.Initial Time")
    t1 = _number(solver.get("Final Time", 1.0), "Solver.Final Time")  # Peridigm's default 1
    if not t1 > t0:
        raise SceneError(f"Solver.Final Time must exceed Initial Time ({t0}), got {t1}")
    if "Fixed dt" not in ver:
        raise SceneError(
            "Solver.Verlet.Fixed dt is required: Peridigm's own stable-step estimate "
            "(ComputeCriticalTimeStep) is not reproduced by pdlin; give the time step"
        )
    dt = _number(ver["Fixed dt"], "Solver.Verlet.Fixed dt", positive=True)
    if "Safety Factor" in ver:
        dt *= _number(ver["Safety Factor"], "Solver.Verlet.Safety Factor", positive=True)
    nsteps = int(math.floor((t1 - t0) / dt))  # Peridigm.cpp: floor((timeFinal-timeInitial)/dt)
    if nsteps < 1:
        raise SceneError(
            f"Solver: Final Time - Initial Time = {t1 - t0} is shorter than one step dt = {dt}"
        )
    return t0, dt, nsteps


def _material_of(root: Mapping[str, Any], blk: Block) -> tuple[str, Mapping[str, Any]]:
    """Return the material name and the ``Blocks`` entry of a scene block."""
    entry = root["Blocks"][blk.key.split(".", 1)[1]]
    return str(entry["Material"]), entry


def _densities_and_damage(
    root: Mapping[str, Any], blocks: list[Block], n: int
) -> tuple[np.ndarray, float | None]:
    """Density per point and the critical stretch (None: no damage model)."""
    rho = np.full(n, np.nan)
    stretches: set[float | None] = set()
    models = root.get("Damage Models", {})
    for blk in blocks:
        mname, entry = _material_of(root, blk)
        mat = root["Materials"][mname]
        if "Density" not in mat:
            raise SceneError(f"missing deck key Materials.{mname}.Density (Solver.Verlet)")
        rho[np.asarray(blk.points, dtype=np.int64)] = _number(
            mat["Density"], f"Materials.{mname}.Density", positive=True
        )
        dname = entry.get("Damage Model")
        if dname is None:
            stretches.add(None)
            continue
        if dname not in models:
            raise SceneError(
                f"{blk.key}.Damage Model: {dname!r} is not defined under Damage Models "
                f"({sorted(models)})"
            )
        dm = _table(models[dname], f"Damage Models.{dname}")
        dkey = f"Damage Models.{dname}"
        _unknown(dm, {"Damage Model": "", "Critical Stretch": ""}, dkey, "Peridigm damage model")
        if dm.get("Damage Model") != "Critical Stretch":
            raise SceneError(
                f"{dkey}.Damage Model: {dm.get('Damage Model')!r} is not supported; "
                "supported: 'Critical Stretch'"
            )
        if "Critical Stretch" not in dm:
            raise SceneError(f"missing deck key {dkey}.Critical Stretch")
        stretches.add(_number(dm["Critical Stretch"], f"{dkey}.Critical Stretch", positive=True))
    if np.isnan(rho).any():
        raise SceneError("Blocks: some points have no material density (Solver.Verlet)")
    if len(stretches) > 1:
        raise SceneError(
            "Blocks: every block must use the same Critical Stretch damage model, or none "
            f"(got {sorted(str(s) for s in stretches)})"
        )
    return rho, next(iter(stretches))


def _conditions(
    bcs: Any, sets: Mapping[str, np.ndarray], cloud: PointCloud, t0: float, t1: float
) -> tuple[list[Dirichlet], list[BodyForce], np.ndarray, np.ndarray]:
    """Prescribed paths, body forces, initial displacement and velocity of a Verlet deck."""
    from .peridigm import _PD_BC, _bc_points

    n, d = cloud.n, cloud.dim
    u0, v0 = np.zeros((n, d)), np.zeros((n, d))
    dirichlet: list[Dirichlet] = []
    loads: list[BodyForce] = []
    for k, v in _table(bcs, "Boundary Conditions").items():
        key = f"Boundary Conditions.{k}"
        if "NODE_SET" in _tidy(k):
            continue
        bc = _table(v, key)
        _unknown(bc, _PD_BC, key, "Peridigm boundary condition")
        typ = _tidy(str(bc.get("Type", "")))
        if typ not in _BC_TYPES:
            raise SceneError(
                f"{key}.Type: {bc.get('Type')!r} is not supported with Solver.Verlet; "
                "supported: 'Prescribed Displacement', 'Initial Velocity', "
                "'Initial Displacement', 'Body Force'"
            )
        for req in ("Node Set", "Value"):
            if req not in bc:
                raise SceneError(f"missing deck key {key}.{req}")
        idx = _bc_points(bc["Node Set"], sets, n, f"{key}.Node Set")
        coord = str(bc.get("Coordinate", "x"))
        if _tidy(coord) not in _COORD:
            raise SceneError(f"{key}.Coordinate must be x, y or z, got {coord!r}")
        c = _COORD[_tidy(coord)]
        pts, text, vkey = cloud.points[idx], bc["Value"], f"{key}.Value"

        def value(t: float, pts: Any = pts, text: Any = text, vkey: str = vkey) -> np.ndarray:
            return np.asarray(deck_expression(text, pts, t, vkey, caret_power=True), dtype=float)

        if typ == "INITIAL_VELOCITY":
            v0[idx, c] = value(t0)
        elif typ == "INITIAL_DISPLACEMENT":
            u0[idx, c] = value(t0)
        elif typ == "BODY_FORCE":
            b = value(t0)
            if not np.allclose(value(t1), b, rtol=1e-12, atol=0.0):
                raise SceneError(
                    f"{vkey}: a Body Force that changes in time is not supported with "
                    "Solver.Verlet (pdlin's loads are constant in time)"
                )
            dens = np.zeros((idx.size, d))
            dens[:, c] = b
            loads.append(BodyForce(idx, dens))
        else:
            g0 = value(t0)

            def path(
                _x: Any, t: float, value: Any = value, g0: Any = g0, idx: Any = idx, c: int = c
            ) -> np.ndarray:
                # DirichletIncrementBC: u changes by the increments of the value from t0,
                # from the initial displacement; held after the run's end (pdlin validates
                # paths at t = 1, which may lie far past a deck's Final Time, where
                # exp(0.0953 t / 1e-8) overflows)
                inc = value(t0 + min(float(t), t1 - t0)) - g0
                return (u0[idx, c] + inc)[:, None]

            dirichlet.append(Dirichlet(idx, TimePath(path, f"{key}.Value"), components=[c]))
    return dirichlet, loads, u0, v0


def verlet_scene(
    root: Mapping[str, Any],
    name: str,
    model: Any,
    kind: str,
    cloud: PointCloud,
    horizon: np.ndarray,
    blocks: list[Block],
    sets: Mapping[str, np.ndarray],
    opts: dict[str, Any],
    base: Path,
    output: Path | None,
) -> Scene:
    """Build the explicit-dynamics scene of a Peridigm ``Solver.Verlet`` deck.

    Parameters
    ----------
    root : Mapping
        The deck's ``Peridigm`` list.
    name : str
        The scene's name.
    model : Model
        The deck's model (``kind`` ``'lps'`` or ``'bond_based'``).
    kind : str
        The material family of the blocks.
    cloud : PointCloud
        The points.
    horizon : ndarray
        Horizon per point.
    blocks : list of Block
        The deck's blocks.
    sets : Mapping
        Node sets by tidy name.
    opts : dict
        Bond options (filters).
    base : Path
        The deck's folder.
    output : Path or None
        The result path.

    Returns
    -------
    Scene
        ``scene.explicit`` holds the :func:`pdlin.dynamics.solve_explicit` keywords.

    Raises
    ------
    SceneError
        Keys or physics outside the mapping, named by their key path.

    Examples
    --------
    ``pdlin.read_deck`` calls it for a deck with ``Solver.Verlet``:

    >>> import pathlib, tempfile, pdlin
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "bar.yaml").write_text('''
    ... Peridigm:
    ...   Discretization:
    ...     Type: PdQuickGrid
    ...     NeighborhoodType: Spherical
    ...     TensorProduct3DMeshGenerator: {X Origin: 0.0, Y Origin: 0.0, Z Origin: 0.0,
    ...       X Length: 4.0, Y Length: 1.0, Z Length: 1.0,
    ...       Number Points X: 4, Number Points Y: 1, Number Points Z: 1}
    ...   Materials:
    ...     Steel: {Material Model: Elastic, Density: 7800.0, Bulk Modulus: 130.0e9,
    ...             Shear Modulus: 78.0e9}
    ...   Blocks:
    ...     All: {Block Names: block_1, Material: Steel, Horizon: 1.5}
    ...   Boundary Conditions:
    ...     Node Set End: "4"
    ...     Kick: {Type: Initial Velocity, Node Set: Node Set End, Coordinate: x, Value: "1.0"}
    ...   Solver: {Initial Time: 0.0, Final Time: 5.0e-5, Verlet: {Fixed dt: 1.0e-5}}
    ... ''')
    >>> scene = pdlin.read_deck(d / "bar.yaml")
    >>> scene.explicit["dt"], scene.explicit["t_end"], scene.explicit["v0"][3].tolist()
    (1e-05, 5e-05, [1.0, 0.0, 0.0])
    >>> from pdlin.dynamics import solve_explicit
    >>> res = solve_explicit(scene.problem, **scene.explicit)
    >>> res.steps, bool(res.u[-1, 0, 0] > 0)
    (5, True)
    """
    from ...models import LPS
    from ._common import _problem

    if kind not in ("lps", "bond_based"):
        raise SceneError(
            f"Materials: {kind!r} materials are not supported with Solver.Verlet (history "
            "state of Peridigm's correspondence / plastic materials); supported: 'Elastic', "
            "'Elastic Bond Based'"
        )
    t0, dt, nsteps = _steps(_table(root["Solver"], "Solver"))
    if kind == "lps":  # Peridigm's elastic.cxx: the deviatoric force without XOSB's correction
        _, consts, _ = blocks_per_point([b for b in blocks if b.points.size], cloud.n)
        K, G = (np.broadcast_to(np.asarray(consts[k], dtype=float), (cloud.n,)) for k in "KG")
        model = LPS(
            K=float(K[0]) if np.all(K == K[0]) else K,
            G=float(G[0]) if np.all(G == G[0]) else G,
            peridigm=True,
            linearization="paper",
        )
    rho, s0 = _densities_and_damage(root, blocks, cloud.n)
    t1 = t0 + nsteps * dt
    dirichlet, loads, u0, v0 = _conditions(root.get("Boundary Conditions", {}), sets, cloud, t0, t1)
    cube = opts.pop("cube", None)
    problem = _problem(model, cloud, horizon, dirichlet, loads, opts)
    if cube is not None:  # QuickGrid's box of cells: bonds beyond the horizon's sphere
        import dataclasses

        from ...geometry.bonds import find_bonds

        radius, window = cube
        bonds = find_bonds(cloud, horizon=radius, exclude=window, allow_isolated=True)
        problem = dataclasses.replace(problem, bonds=bonds)
    explicit: dict[str, Any] = {
        "t_end": nsteps * dt,
        "dt": dt,
        "check_dt": False,
        "density": float(rho[0]) if np.all(rho == rho[0]) else rho,
        "linear": False,
        "u0": u0,
        "v0": v0,
    }
    out = root.get("Output", {})
    if isinstance(out, Mapping) and "Output Frequency" in out:
        every = _number(out["Output Frequency"], "Output.Output Frequency")
        if every >= 1:
            explicit["output_every"] = int(every)
    if s0 is not None:
        explicit["critical_stretch"] = s0
    scene = Scene(name=name, problem=problem, output=output, base_dir=base, explicit=explicit)
    scene.time = t1
    scene.blocks = blocks
    return scene
