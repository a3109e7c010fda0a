"""Calibration targets and files (``pdlin calibrate TARGET.toml``).

A target stiffness is given in a TOML table as one of

* ``class = "<symmetry class>"`` with ``constants = { C11 = ..., ... }``
  (the keyword arguments of the :mod:`pdlin.constitutive` constructor),
* ``material = "<name>"`` (the named materials of :func:`pdlin.constitutive.material`),
* ``voigt = [[...], ...]`` (6x6 or 3x3 plain Voigt matrix),

optionally rotated by ``rotation = [[...], ...]`` (an orthogonal matrix,
``C' = Q * C``) and reduced to 2D by ``plane = "stress" | "strain"``.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PdlinError, SceneError
from ._keys import check_keys, number, read_toml

if sys.version_info >= (3, 11):
    pass
else:  # pragma: no cover
    pass

__all__ = ["target_from_table", "CalibrationJob", "load_calibration", "calibration_from_dict"]

_TARGET = {"class", "constants", "material", "voigt", "rotation", "plane", "units"}
_FAMILY = {
    "dim",
    "horizon",
    "lattice",
    "spacing",
    "shape",
    "axes",
    "influence",
    "rotation",
    "thickness",
}
_OPTIONS = {
    "method",
    "lower_bound",
    "weighting",
    "qp_solver",
    "boundary",
    "pair_rule",
    "raise_on_infeasible",
}
_OUTPUT = {"path", "plot"}
_TOP = {"name", "target", "family", "calibration", "output"}


def _keys(table: Any, allowed: set[str], where: str) -> dict[str, Any]:
    return check_keys(table, allowed, where)


def _matrix(value: Any, where: str) -> np.ndarray:
    """Read a numeric array from TOML, or raise SceneError naming ``where``."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SceneError(
            f"{where} must be a numeric matrix (array of arrays of numbers), got {value!r}: {exc}"
        ) from exc


def target_from_table(table: Mapping[str, Any], where: str = "target") -> np.ndarray:
    """Build the Voigt stiffness of a target table (see the module docstring).

    Parameters
    ----------
    table : Mapping
        Exactly one of ``class`` (with ``constants``), ``material`` or ``voigt``;
        optional ``rotation`` and ``plane``.
    where : str, optional
        The table's key path for messages.

    Returns
    -------
    numpy.ndarray
        Voigt stiffness, ``(6, 6)`` (``(3, 3)`` with ``plane``).

    Raises
    ------
    SceneError
        A missing, unknown or invalid key, named by its path.

    Examples
    --------
    >>> C = target_from_table({"class": "cubic", "constants": {"C11": 252, "C12": 145, "C44": 142}})
    >>> C[0, :3].tolist(), float(C[3, 3])
    ([252.0, 145.0, 145.0], 142.0)
    >>> target_from_table({"class": "cubic", "constants": {"C11": 1.0}})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.SceneError: target.constants does not fit cubic(...): cubic() missing 2 ...
    """
    from .. import constitutive as cst

    tbl = _keys(table, _TARGET, where)
    given = [k for k in ("class", "material", "voigt") if k in tbl]
    if len(given) != 1:
        raise SceneError(f"{where} needs exactly one of 'class', 'material', 'voigt', got {given}")
    try:
        if "class" in tbl:
            name = tbl["class"]
            if name not in cst.SYMMETRY_CLASSES:
                raise SceneError(
                    f"{where}.class must be one of {sorted(cst.SYMMETRY_CLASSES)}, got {name!r}"
                )
            consts = tbl.get("constants")
            if not isinstance(consts, Mapping):
                raise SceneError(f"{where}.constants must be a table of the {name} constants")
            try:
                C = cst.SYMMETRY_CLASSES[name](**{k: consts[k] for k in consts})
            except TypeError as exc:
                raise SceneError(f"{where}.constants does not fit {name}(...): {exc}") from exc
        elif "material" in tbl:
            C = cst.material(str(tbl["material"]))
        else:
            C = cst.check_stiffness(_matrix(tbl["voigt"], f"{where}.voigt"), f"{where}.voigt")
        if "rotation" in tbl:
            C = cst.rotate(C, _matrix(tbl["rotation"], f"{where}.rotation"))
        if "plane" in tbl:
            plane = tbl["plane"]
            if plane not in ("stress", "strain"):
                raise SceneError(f"{where}.plane must be 'stress' or 'strain', got {plane!r}")
            C = cst.plane_stress(C) if plane == "stress" else cst.plane_strain(C)
    except SceneError:
        raise
    except PdlinError as exc:
        raise SceneError(f"{where}: {exc}") from exc
    return np.array(C, dtype=float)


@dataclass
class CalibrationJob:
    """A parsed calibration file: target, family, options and outputs."""

    name: str
    target: np.ndarray
    family: Any
    options: dict[str, Any] = field(default_factory=dict)
    output: Path | None = None
    plot: Path | None = None

    def run(self) -> Any:
        """Calibrate and return the :class:`~pdlin.calibration.CalibrationResult`.

        Returns
        -------
        CalibrationResult
            Micromoduli, status and the fitted tensor's error.
        """
        from ..calibration import calibrate_micromoduli

        return calibrate_micromoduli(self.target, self.family, **self.options)


def calibration_from_dict(
    data: Mapping[str, Any], base_dir: str | Path | None = None
) -> CalibrationJob:
    """Build a :class:`CalibrationJob` from parsed TOML.

    Parameters
    ----------
    data : Mapping
        Parsed calibration file: ``target``, ``family``, optional ``calibration``
        options and ``output``.
    base_dir : str or Path, optional
        Folder that relative output paths are resolved against (default: the working
        directory).

    Returns
    -------
    CalibrationJob
        Ready to :meth:`~CalibrationJob.run`.

    Raises
    ------
    SceneError
        A missing, unknown or invalid key, named by its path.

    Examples
    --------
    >>> job = calibration_from_dict({
    ...     "target": {"material": "isotropic"},
    ...     "family": {"dim": 3, "horizon": 3.0, "influence": "delta_over_r"},
    ... })
    >>> res = job.run()
    >>> res.status, res.relative_error < 1e-12
    ('step1', True)
    """
    from ..calibration import lattice_family

    base = Path(base_dir) if base_dir is not None else Path.cwd()
    top = _keys(data, _TOP, "")
    if "target" not in top:
        raise SceneError("missing key 'target'")
    if "family" not in top:
        raise SceneError("missing key 'family'")
    fam_cfg = _keys(top["family"], _FAMILY, "family")
    for k in ("dim", "horizon"):
        if k not in fam_cfg:
            raise SceneError(f"missing key family.{k}")
    target = target_from_table(top["target"])
    dim = number(fam_cfg["dim"], "family.dim", integer=True, type_name=False)
    horizon = number(fam_cfg["horizon"], "family.horizon", type_name=False)
    spacing = number(fam_cfg.get("spacing", 1.0), "family.spacing", type_name=False)
    thickness = number(fam_cfg.get("thickness", 1.0), "family.thickness", type_name=False)
    try:
        family = lattice_family(
            dim,
            horizon,
            lattice=fam_cfg.get("lattice"),
            spacing=spacing,
            shape=fam_cfg.get("shape", "sphere"),
            axes=fam_cfg.get("axes"),
            influence=fam_cfg.get("influence", "constant"),
            rotation=fam_cfg.get("rotation"),
            thickness=thickness,
        )
    except PdlinError as exc:
        raise SceneError(f"family: {exc}") from exc
    options = _keys(top.get("calibration", {}), _OPTIONS, "calibration")
    options.pop("boundary", None)
    options.pop("pair_rule", None)
    if "lower_bound" in options:
        options["lower_bound"] = number(
            options["lower_bound"], "calibration.lower_bound", type_name=False
        )
    if "raise_on_infeasible" in options and not isinstance(options["raise_on_infeasible"], bool):
        raise SceneError(
            "calibration.raise_on_infeasible must be true or false, got "
            f"{options['raise_on_infeasible']!r}"
        )
    for key in ("method", "weighting", "qp_solver"):
        if key in options and not isinstance(options[key], str):
            raise SceneError(f"calibration.{key} must be a string, got {options[key]!r}")
    name = top.get("name", "calibration")
    if not isinstance(name, str):
        raise SceneError(f"name must be a string, got {name!r}")
    out = _keys(top.get("output", {}), _OUTPUT, "output")

    def _path(p: Any) -> Path | None:
        if p is None:
            return None
        q = Path(str(p))
        return q if q.is_absolute() else base / q

    return CalibrationJob(
        name=name,
        target=target,
        family=family,
        options=options,
        output=_path(out.get("path")),
        plot=_path(out.get("plot")),
    )


def load_calibration(path: str | Path) -> CalibrationJob:
    """Read and validate a calibration TOML file.

    Parameters
    ----------
    path : str or Path
        The calibration ``.toml`` file.

    Returns
    -------
    CalibrationJob
        As :func:`calibration_from_dict` builds it.

    Raises
    ------
    SceneError
        A missing file, invalid TOML or an invalid key.
    """
    data, base = read_toml(path, "calibration")
    return calibration_from_dict(data, base)
