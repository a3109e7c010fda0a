"""Analysis tools: sparsity studies and zero-energy modes of stiffness operators."""

from .sparsity import (
    FILL_ORDERINGS,
    SparsityReport,
    coupling_pattern,
    rcm_permutation,
    sparsity_report,
    spy_pattern,
)
from .zero_energy import (
    CheckerboardReport,
    ZeroEnergyReport,
    checkerboard_energy_ratio,
    compare_controls,
    count_zero_modes,
    periodic_lattice_bonds,
)

__all__ = [
    "SparsityReport",
    "sparsity_report",
    "coupling_pattern",
    "rcm_permutation",
    "spy_pattern",
    "FILL_ORDERINGS",
    "ZeroEnergyReport",
    "CheckerboardReport",
    "count_zero_modes",
    "checkerboard_energy_ratio",
    "compare_controls",
    "periodic_lattice_bonds",
]
