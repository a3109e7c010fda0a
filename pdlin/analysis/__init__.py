"""Analysis tools: zero-energy modes of stiffness operators."""

from .zero_energy import (
    CheckerboardReport,
    ZeroEnergyReport,
    checkerboard_energy_ratio,
    compare_controls,
    count_zero_modes,
)

__all__ = [
    "ZeroEnergyReport",
    "CheckerboardReport",
    "count_zero_modes",
    "checkerboard_energy_ratio",
    "compare_controls",
]
