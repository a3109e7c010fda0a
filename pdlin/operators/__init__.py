"""Operators: assembly, boundary conditions, loads, rigid-body modes, sparsity reports."""

from ..constraints import check_constraints, eliminate_dirichlet, load_vector, resolve_dirichlet
from .assembly import assemble_stiffness, bond_pattern_bsr, pair_stiffness_bsr
from .bc import BodyForce, Dirichlet, TimePath, TotalForce, shadow_layer
from .rigid import rigid_body_modes
from .sparsity import SparsityReport, coupling_pattern, plot_spy, sparsity_report
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
    "SparsityReport",
    "sparsity_report",
    "coupling_pattern",
    "plot_spy",
    "SymmetryPlane",
    "MirrorCloud",
    "SymmetryReduction",
    "mirror_cloud",
    "symmetry_reduction",
]
