"""TOML reading and key checking shared by scene and calibration files (internal)."""

from __future__ import annotations

import difflib
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..errors import SceneError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def read_toml(path: str | Path, what: str) -> tuple[dict[str, Any], Path]:
    """Parsed TOML file and its folder; a missing file or bad TOML raises SceneError."""
    p = Path(path)
    if not p.exists():
        raise SceneError(f"{what} file not found: {p}")
    try:
        return tomllib.loads(p.read_text()), p.parent
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{p}: invalid TOML: {exc}") from exc


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
