"""Analysis tools: zero-energy modes of stiffness operators."""

from .zero_energy import (
    CheckerboardReport,
    ZeroEnergyReport,
    checkerboard_energy_ratio,
    compare_controls,
    count_zero_modes,
    periodic_lattice_bonds,
)

__all__ = [
    "ZeroEnergyReport",
    "CheckerboardReport",
    "count_zero_modes",
    "checkerboard_energy_ratio",
    "compare_controls",
    "periodic_lattice_bonds",
]
