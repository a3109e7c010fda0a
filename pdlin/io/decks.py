"""Deprecated alias of :mod:`pdlin.scene.decks` (moved there; this path works for one release)."""

import importlib
import warnings
from typing import Any

warnings.warn(
    "pdlin.io.decks is deprecated: import from pdlin.scene.decks instead",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ['read_deck', 'deck_expression', 'peridigm_hourglass_penalty', 'peridigm_bond_filters']


def __getattr__(name: str) -> Any:
    return getattr(importlib.import_module("pdlin.scene.decks"), name)
