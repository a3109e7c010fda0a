"""Operators: assembly, boundary conditions, loads, rigid-body modes, symmetry planes.

Sparsity reports moved to :mod:`pdlin.analysis` and spy plots to :mod:`pdlin.plotting`;
``pdlin.operators.sparsity_report`` and the other old names keep working for one release
with a :class:`DeprecationWarning`.
"""

from typing import Any

from .._lazy import moved_attribute
from ..constraints import check_constraints, eliminate_dirichlet, load_vector, resolve_dirichlet
from .assembly import assemble_stiffness, bond_pattern_bsr, pair_stiffness_bsr
from .bc import BodyForce, Dirichlet, TimePath, TotalForce, shadow_layer
from .rigid import rigid_body_modes
from .symmetry import (
    MirrorCloud,
    SymmetryPlane,
    SymmetryReduction,
    mirror_cloud,
    symmetry_reduction,
)

__all__ = [
    "assemble_stiffness",
    "bond_pattern_bsr",
    "pair_stiffness_bsr",
    "Dirichlet",
    "TimePath",
    "BodyForce",
    "TotalForce",
    "shadow_layer",
    "resolve_dirichlet",
    "load_vector",
    "eliminate_dirichlet",
    "check_constraints",
    "rigid_body_modes",
    "SymmetryPlane",
    "MirrorCloud",
    "SymmetryReduction",
    "mirror_cloud",
    "symmetry_reduction",
]

#: names that moved away (deprecated here for one release) -> their new home
_MOVED = {
    **dict.fromkeys(("SparsityReport", "sparsity_report", "coupling_pattern"), "pdlin.analysis"),
    "plot_spy": "pdlin.plotting",
}


def __getattr__(name: str) -> Any:
    return moved_attribute(__name__, _MOVED, name)
