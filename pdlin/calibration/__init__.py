"""Micromodulus calibration for anisotropic bond-based PD (Prakash, anisotropic micromoduli).

:func:`~pdlin.calibrate_micromoduli` fits one micromodulus per bond so that a bond
family (or every family of a cloud) reproduces a target stiffness tensor in
the Frobenius norm; :func:`lattice_family` builds single lattice families.
"""

from typing import Any

from .._lazy import moved_attribute
from .calibrate import (
    METHODS,
    QP_SOLVERS,
    CalibrationResult,
    calibrate_micromoduli,
    design_matrix,
    max_lower_bound,
)
from .lattices import LATTICES, Family, equiangle_rotation, lattice_family, reflection

__all__ = [
    "calibrate_micromoduli",
    "CalibrationResult",
    "Family",
    "lattice_family",
    "design_matrix",
    "max_lower_bound",
    "equiangle_rotation",
    "reflection",
    "LATTICES",
    "METHODS",
    "QP_SOLVERS",
]


def __getattr__(name: str) -> Any:  # plot_micromoduli moved to pdlin.plotting (deprecated here)
    return moved_attribute(__name__, {"plot_micromoduli": "pdlin.plotting"}, name)
