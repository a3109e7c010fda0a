"""Scenes: TOML scene files, Peridigm / PeriLab decks, checks, calibration and tradeoff files.

This package turns input files into pdlin problems and knows how to run and check them;
it sits above the drivers (:func:`pdlin.solve`, :func:`pdlin.solve_nonlinear`,
:func:`pdlin.solve_damage`, :func:`pdlin.tradeoff`) and below the command line.  Loading
never solves: work a scene needs before its run (the coarse solve of a ``[subregion]``)
is done by :meth:`Scene.prepare`, when the scene's problem is first used.  File formats
without physics (result writers and readers) live in :mod:`pdlin.io`.

Modules
-------
``pdlin.scene.scene``
    TOML scenes (:func:`load_scene`, :func:`scene_from_dict`) and the built-in examples.
``pdlin.scene.decks``
    Peridigm and PeriLab input decks (:func:`~pdlin.read_deck`).
``pdlin.scene.checks``
    ``[[check]]`` tables: what a run verifies and against which reference.
``pdlin.scene.targets``
    Calibration files (``pdlin calibrate``).
``pdlin.scene.tradeoff``
    ``[tradeoff]`` tables of scenes (``pdlin tradeoff``, ``pdlin run --select``).
"""

from .checks import Check, CheckResult, evaluate_checks, parse_checks
from .decks import read_deck
from .materials import Block, blocks_per_point
from .scene import Scene, builtin_scene, list_builtin_scenes, load_scene, scene_from_dict
from .targets import CalibrationJob, calibration_from_dict, load_calibration, target_from_table
from .tradeoff import (
    SceneSweep,
    load_tradeoff,
    run_scene_tradeoff,
    select_scene,
    tradeoff_from_dict,
)

__all__ = [
    "Scene",
    "Block",
    "blocks_per_point",
    "load_scene",
    "scene_from_dict",
    "builtin_scene",
    "list_builtin_scenes",
    "read_deck",
    "Check",
    "CheckResult",
    "parse_checks",
    "evaluate_checks",
    "CalibrationJob",
    "calibration_from_dict",
    "load_calibration",
    "target_from_table",
    "SceneSweep",
    "load_tradeoff",
    "tradeoff_from_dict",
    "run_scene_tradeoff",
    "select_scene",
]
