"""Deprecated alias of :mod:`pdlin.scene.decks` (moved; works for one release)."""

import importlib
import warnings
from typing import Any

warnings.warn(
    "pdlin.io.decks is deprecated: import from pdlin.scene.decks instead",
    DeprecationWarning,
    stacklevel=2,
)


def __getattr__(name: str) -> Any:
    # every name, public or not, from the new module (PEP 562)
    return getattr(importlib.import_module("pdlin.scene.decks"), name)
