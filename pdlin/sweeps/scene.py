"""Deprecated alias of :mod:`pdlin.scene.tradeoff` (moved there; this path works for one release)."""

import importlib
import warnings
from typing import Any

warnings.warn(
    "pdlin.sweeps.scene is deprecated: import from pdlin.scene.tradeoff instead",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ["SceneSweep", "load_tradeoff", "tradeoff_from_dict", "run_scene_tradeoff", "select_scene"]


def __getattr__(name: str) -> Any:
    return getattr(importlib.import_module("pdlin.scene.tradeoff"), name)
