"""Deprecated alias of :mod:`pdlin.scene.scene` (moved there; this path works for one release)."""

import importlib
import warnings
from typing import Any

warnings.warn(
    "pdlin.io.scene is deprecated: import from pdlin.scene.scene instead",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ['Scene', 'load_scene', 'scene_from_dict', 'builtin_scene', 'list_builtin_scenes', 'MODELS']


def __getattr__(name: str) -> Any:
    return getattr(importlib.import_module("pdlin.scene.scene"), name)
