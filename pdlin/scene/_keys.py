"""TOML reading, key checking and number parsing shared by every scene-like file (internal).

One parser for numbers, :func:`number`, serves TOML scenes, ``[[check]]`` tables,
calibration files and Peridigm / PeriLab decks (whose numbers may be text).
"""

from __future__ import annotations

import difflib
import re
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SceneError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: a decimal floating-point literal (what Teuchos reads as a double; YAML 1.1 loads
#: exponents without a sign, "160.0e10", as strings)
NUMBER_TEXT = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")


def read_toml(path: str | Path, what: str) -> tuple[dict[str, Any], Path]:
    """Read a TOML file.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file is, for the message of a missing file (``"scene"``).

    Returns
    -------
    data : dict
        The parsed TOML.
    folder : Path
        The file's folder (paths inside the file are relative to it).

    Raises
    ------
    SceneError
        The file does not exist or is not valid TOML.
    """
    p = Path(path)
    if not p.exists():
        raise SceneError(f"{what} file not found: {p}")
    try:
        return tomllib.loads(p.read_text()), p.parent
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{p}: invalid TOML: {exc}") from exc


def check_keys(table: Any, allowed: set[str], where: str, *, what: str = "key") -> dict[str, Any]:
    """Return ``table`` as a dict after checking its keys.

    Parameters
    ----------
    table : Mapping
        The table read from the file.
    allowed : set of str
        Its valid keys.
    where : str
        The table's key path for messages (``"solver"``; ``""`` for the top level).
    what : str, optional
        What a key is called in the message (``"scene key"``).

    Returns
    -------
    dict
        A shallow copy of ``table``.

    Raises
    ------
    SceneError
        ``table`` is not a table, or has a key outside ``allowed`` (named with the
        closest valid one).
    """
    if not isinstance(table, Mapping):
        raise SceneError(f"{where} must be a table, got {type(table).__name__}")
    for key in table:
        if key not in allowed:
            hint = difflib.get_close_matches(str(key), sorted(allowed), n=1)
            extra = f"; did you mean {hint[0]!r}?" if hint else f"; allowed keys: {sorted(allowed)}"
            path = f"{where}.{key}" if where else str(key)
            raise SceneError(f"unknown {what} {path!r}{extra}")
    return dict(table)


def number(
    value: Any,
    key: str,
    *,
    positive: bool = False,
    integer: bool = False,
    text: bool = False,
    type_name: bool = True,
    phrase: bool = False,
) -> Any:
    """Parse one number of an input file, or raise naming its key.

    Parameters
    ----------
    value : Any
        The value read (TOML, YAML or XML).
    key : str
        Its key path for messages (``"horizon.ratio"``).
    positive : bool, optional
        Require ``> 0``.
    integer : bool, optional
        Require an integer (TOML ``3``, not ``3.0``); it is returned as an int.
    text : bool, optional
        Also accept a decimal literal written as a string (``"1.5e3"``: Peridigm XML,
        YAML 1.1 exponents without a sign); never an expression.
    type_name : bool, optional
        Name the type of a non-number in the message (``got str '0.1'``; TOML scenes and
        checks) or only its value (``got True``; decks and calibration files).
    phrase : bool, optional
        Word a bad value as ``must be a positive finite number`` (``[[check]]`` tables)
        instead of ``must be > 0`` / ``must be finite``.

    Returns
    -------
    float or int
        The finite value as a float (an int when ``integer``).

    Raises
    ------
    SceneError
        A bool, a non-number (text unless ``text``), a non-finite value (TOML has
        ``inf`` and ``nan``) or, when ``positive``, a value ``<= 0``.

    Examples
    --------
    >>> number(2, "horizon.ratio", positive=True), number(" 1e3", "x", text=True)
    (2.0, 1000.0)
    >>> number(True, "solver.rtol")
    Traceback (most recent call last):
    ...
    pdlin.errors.SceneError: solver.rtol must be a number, got bool True
    """
    if text and isinstance(value, str) and NUMBER_TEXT.fullmatch(value.strip()):
        value = float(value.strip())
    ok = isinstance(value, int) or (not integer and isinstance(value, float))
    if isinstance(value, bool) or not ok:
        kind = "an integer" if integer else "a number"
        got = f"{type(value).__name__} {value!r}" if type_name else repr(value)
        raise SceneError(f"{key} must be {kind}, got {got}")
    v = float(value)
    bad = not np.isfinite(v) or (positive and v <= 0)
    if bad and phrase:
        raise SceneError(f"{key} must be a {'positive ' if positive else ''}finite number, got {v}")
    if bad:
        raise SceneError(f"{key} must be {'> 0' if positive else 'finite'}, got {v}")
    return value if integer else v


def scene_keys(table: Any, allowed: set[str], where: str) -> dict[str, Any]:
    """Check a scene table's keys: :func:`check_keys` naming them ``scene key``.

    Parameters
    ----------
    table : Mapping
        The table.
    allowed : set of str
        Its valid keys.
    where : str
        Its key path (``""`` for the top level).

    Returns
    -------
    dict
        A shallow copy of ``table``.

    Raises
    ------
    SceneError
        As :func:`check_keys`.
    """
    return check_keys(table, allowed, where, what="scene key")


def require(table: Mapping[str, Any], key: str, where: str) -> Any:
    """Return ``table[key]``, or raise naming the missing scene key.

    Parameters
    ----------
    table : Mapping
        The table.
    key : str
        The required key.
    where : str
        The table's key path (``"subregion"``).

    Returns
    -------
    Any
        The value.

    Raises
    ------
    SceneError
        ``missing scene key <where>.<key>``.
    """
    if key not in table:
        raise SceneError(f"missing scene key {where}.{key}")
    return table[key]
