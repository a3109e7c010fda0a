"""Deprecated alias of :mod:`pdlin.scene.checks` (moved there; this path works for one release)."""

import importlib
import warnings
from typing import Any

warnings.warn(
    "pdlin.io.checks is deprecated: import from pdlin.scene.checks instead",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ['Check', 'CheckResult', 'parse_checks', 'evaluate_checks', 'format_check', 'uniaxial_F', 'KINDS', 'METRICS']


def __getattr__(name: str) -> Any:
    return getattr(importlib.import_module("pdlin.scene.checks"), name)
