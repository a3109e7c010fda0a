"""Key checking shared by scene and calibration files (internal)."""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from typing import Any

from ..errors import SceneError


def check_keys(table: Any, allowed: set[str], where: str, *, what: str = "key") -> dict[str, Any]:
    """Return ``table`` as a dict, or raise naming an unknown key and the closest valid one."""
    if not isinstance(table, Mapping):
        raise SceneError(f"{where} must be a table, got {type(table).__name__}")
    for key in table:
        if key not in allowed:
            hint = difflib.get_close_matches(str(key), sorted(allowed), n=1)
            extra = f"; did you mean {hint[0]!r}?" if hint else f"; allowed keys: {sorted(allowed)}"
            path = f"{where}.{key}" if where else str(key)
            raise SceneError(f"unknown {what} {path!r}{extra}")
    return dict(table)
