"""Input/output: result files, time series, system export, mesh and result readers.

File formats only: this package builds no problem and runs no solve.  Scene files and
input decks (which build problems and know how to run them) are :mod:`pdlin.scene`; the
old paths ``pdlin.io.scene``, ``pdlin.io.decks``, ``pdlin.io.checks`` and
``pdlin.io.targets`` still work for one release, with a DeprecationWarning.
"""

import importlib
from typing import Any

from .read import ResultFile, read_result
from .results import (
    export_system,
    write_homogenized_csv,
    write_nonlinear,
    write_points,
    write_result,
    write_series,
)

__all__ = [
    "write_points",
    "write_result",
    "write_series",
    "write_nonlinear",
    "write_homogenized_csv",
    "export_system",
    "read_result",
    "ResultFile",
]

#: modules moved to :mod:`pdlin.scene`; their old paths are deprecation shims
_MOVED = ("scene", "decks", "checks", "targets")


def __getattr__(name: str) -> Any:
    # ``pdlin.io.scene.load_scene(...)`` after ``import pdlin`` (the shims warn)
    if name in _MOVED:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
