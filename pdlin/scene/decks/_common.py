"""Helpers shared by the Peridigm and PeriLab deck readers (internal)."""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ...constraints import load_vector, resolve_dirichlet
from ...errors import PdlinError, SceneError
from ...geometry.cloud import PointCloud
from ...operators.bc import Dirichlet
from ...problem import StaticProblem
from .._keys import number
from ..scene import Scene

# the logger keeps the name of the module the deck readers came from
log = logging.getLogger("pdlin.io.decks")


# --------------------------------------------------------------------------------------
# file readers
# --------------------------------------------------------------------------------------
def _load_yaml(path: Path) -> Any:
    try:
        import yaml
    except ImportError as exc:
        raise PdlinError(
            f'reading the YAML deck {path} needs PyYAML: pip install "pdlin[decks]"'
        ) from exc
    try:
        return yaml.safe_load(_read_text(path, "deck"))
    except yaml.YAMLError as exc:
        raise SceneError(f"{path}: invalid YAML: {exc}") from None


# Teuchos' XMLObject::getRequiredBool: TRUE / YES / 1 and FALSE / NO / 0, any case
_BOOL_SPELLINGS = {"TRUE": True, "YES": True, "1": True, "FALSE": False, "NO": False, "0": False}


def _read_text_table(path: Path, key: str, ncols: tuple[int, ...]) -> np.ndarray:
    """Rows of numbers; lines starting with '#', '/', '*' (or empty) are comments."""
    rows = []
    for lineno, raw in enumerate(_read_text(path, key).splitlines(), 1):
        line = raw.strip()
        if not line or line[0] in "#/*" or line.startswith("header:"):
            continue
        try:
            vals = [float(v) for v in line.split()]
        except ValueError:
            raise SceneError(f"{key}: {path.name} line {lineno} is not numbers: {line!r}") from None
        if len(vals) not in ncols:
            raise SceneError(
                f"{key}: {path.name} line {lineno} has {len(vals)} columns, expected "
                f"{' or '.join(map(str, ncols))}: {line!r}"
            )
        rows.append(vals)
    if not rows:
        raise SceneError(f"{key}: {path} holds no points")
    widths = {len(r) for r in rows}
    if len(widths) > 1:
        raise SceneError(f"{key}: {path.name} mixes rows of {sorted(widths)} columns")
    return np.asarray(rows, dtype=float)


def _cloud(points: np.ndarray, volumes: np.ndarray, key: str) -> PointCloud:
    try:
        return PointCloud(points, volumes)
    except PdlinError as exc:
        raise SceneError(f"{key}: {exc}") from None


def _resolve_file(value: Any, base: Path, key: str) -> Path:
    if not isinstance(value, str) or not value.strip():
        raise SceneError(f"{key} must be a file name, got {value!r}")
    p = Path(value.strip())
    if not p.is_absolute():
        p = base / p
    if not p.is_file():
        what = "is not a file" if p.exists() else "file not found"
        raise SceneError(f"{key}: {what}: {p}")
    return p


def _read_text(path: Path, key: str) -> str:
    try:
        return path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{key}: cannot read {path} as text: {exc}") from None


def _node_ids(value: Any, base: Path, key: str, n: int) -> np.ndarray:
    """Read a node set: a file of 1-based ids, an inline list or string of them -> 0-based."""
    if isinstance(value, list):
        toks: list[Any] = value
    elif isinstance(value, int) and not isinstance(value, bool):
        toks = [value]
    elif isinstance(value, str):
        s = value.strip()
        # Peridigm's rule (nodeSetStringToFileName): whitespace or an integer -> a list
        if re.fullmatch(r"[+-]?\d+(\s+[+-]?\d+)*", s):
            toks = s.split()
        else:
            path = _resolve_file(s, base, key)
            toks = []
            for raw in _read_text(path, key).splitlines():
                line = raw.strip()
                if line and line[0] not in "#/*":
                    toks.extend(line.split())
    else:
        raise SceneError(f"{key} must be a node-set file name or a list of node ids, got {value!r}")
    try:
        ids = np.array([int(str(v)) for v in toks], dtype=np.int64)
    except ValueError:
        raise SceneError(f"{key}: node ids must be integers, got {toks[:5]!r}...") from None
    if ids.size == 0:
        raise SceneError(f"{key}: the node set is empty")
    if ids.min() < 1 or ids.max() > n:
        raise SceneError(
            f"{key}: node ids are 1-based and must lie in [1, {n}], got range "
            f"[{int(ids.min())}, {int(ids.max())}]"
        )
    return np.unique(ids - 1)


def _tidy(name: str) -> str:
    """Peridigm's tidy_string: upper case, trimmed, spaces -> underscores."""
    return "_".join(name.strip().upper().split(" "))


def _table(value: Any, key: str) -> dict[str, Any]:
    if not isinstance(value, Mapping):
        raise SceneError(f"{key} must be a list of parameters, got {type(value).__name__}")
    return dict(value)


def _unknown(table: Mapping[str, Any], allowed: Mapping[str, str], key: str, what: str) -> None:
    for k in table:
        if k not in allowed:
            raise SceneError(
                f"{key}.{k}: not supported by pdlin's {what} reader; supported keys: "
                f"{sorted(allowed)}"
            )


def _note(key: str, why: str) -> None:
    log.info("deck key %s accepted without effect: %s", key, why)


def _number(value: Any, key: str, *, positive: bool = False) -> float:
    """Parse a deck number: :func:`pdlin.scene._keys.number`, decimal text accepted."""
    return float(number(value, key, positive=positive, text=True, type_name=False))


def _flag(value: Any, key: str) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().upper() in _BOOL_SPELLINGS:
        return _BOOL_SPELLINGS[value.strip().upper()]
    raise SceneError(
        f"{key} must be true or false (or yes / no / 1 / 0, as Teuchos reads them), got {value!r}"
    )


# --------------------------------------------------------------------------------------
# materials
# --------------------------------------------------------------------------------------
_ELASTIC_CONSTANTS = {
    "Bulk Modulus": "K",
    "Shear Modulus": "G",
    "Young's Modulus": "E",
    "Poisson's Ratio": "nu",
}


def _constants(mat: Mapping[str, Any], key: str, *, exactly: int | None = 2) -> dict[str, float]:
    got = {
        short: _number(mat[long], f"{key}.{long}")
        for long, short in _ELASTIC_CONSTANTS.items()
        if long in mat
    }
    if exactly is not None and len(got) != exactly:
        raise SceneError(
            f"{key} needs exactly two of {list(_ELASTIC_CONSTANTS)}, got "
            f"{[k for k in _ELASTIC_CONSTANTS if k in mat] or 'none'}"
        )
    return got


def _bulk_shear(c: Mapping[str, float], key: str) -> tuple[float, float]:
    from ...constitutive import isotropic_constants

    try:
        E, nu = isotropic_constants(**dict(c))
    except PdlinError as exc:
        raise SceneError(f"{key}: {exc}") from None
    E, nu = float(E), float(nu)
    return E / (3.0 * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


_COORD = {"X": 0, "Y": 1, "Z": 2}


def _output_inside(base: Path, value: Any, key: str, suffix: str = ".vtu") -> Path:
    """``<base>/<value><suffix>``, refused when it resolves outside ``base`` (the deck's folder).

    A deck is often someone else's file: it writes only beside itself.  ``pdlin run -o``
    (the user's own choice) may point anywhere.
    """
    root = base.resolve()
    out = (root / f"{value}{suffix}").resolve()
    if not out.is_relative_to(root):
        raise SceneError(
            f"{key} {str(value)!r} leaves the deck's folder {str(root)!r} (resolves to "
            f"{str(out)!r}); give a name inside it"
        )
    return base / out.relative_to(root)


def _scene(
    name: str,
    model: Any,
    cloud: PointCloud,
    horizon: np.ndarray,
    dirichlet: list[Dirichlet],
    loads: list[Any],
    base: Path,
    output: Path | None,
    bond_options: Mapping[str, Any] | None = None,
) -> Scene:
    problem = _problem(model, cloud, horizon, dirichlet, loads, bond_options)
    return Scene(name=name, problem=problem, output=output, base_dir=base)


def _problem(
    model: Any,
    cloud: PointCloud,
    horizon: np.ndarray,
    dirichlet: list[Dirichlet],
    loads: list[Any],
    bond_options: Mapping[str, Any] | None = None,
) -> StaticProblem:
    h: Any = float(horizon[0]) if np.all(horizon == horizon[0]) else horizon
    try:
        resolve_dirichlet(cloud, dirichlet)
        load_vector(cloud, loads)
        return StaticProblem(
            model,
            cloud,
            None,
            horizon=h,
            dirichlet=dirichlet,
            loads=loads,
            bond_options=dict(bond_options or {}),
        )
    except SceneError:
        raise
    except PdlinError as exc:
        raise SceneError(f"invalid deck: {exc}") from exc
