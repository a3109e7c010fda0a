"""Deprecated alias of :mod:`pdlin.scene.targets` (moved there; this path works for one release)."""

import importlib
import warnings
from typing import Any

warnings.warn(
    "pdlin.io.targets is deprecated: import from pdlin.scene.targets instead",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ['target_from_table', 'CalibrationJob', 'calibration_from_dict', 'load_calibration']


def __getattr__(name: str) -> Any:
    return getattr(importlib.import_module("pdlin.scene.targets"), name)
