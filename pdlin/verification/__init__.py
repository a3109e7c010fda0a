"""Verification utilities: independent reference solutions to check pdlin against.

These are not peridynamic models.  They exist so that tests and examples can compare pdlin's
results with a classical reference (Q4 and Hex8 finite-element solves for the plate and block
with a hole of Liu, Chen & Skelton, XOSB, §5.1-5.2, and the plate and brick of Luo &
Sundararaghavan (2018), §5.2-5.3) without each carrying its own copy of the reference solver,
the crystal-plasticity finite elements (CPFE, Q4 / Hex8 F-bar) that Luo, Ramazani &
Sundararaghavan (2017), Section 4, compare their peridynamic polycrystals with, and the
closed-form surface-effect problems (tension bar, plate, shear block) of the surface corrections.
"""

from __future__ import annotations

from .cpfe import crystal_plasticity_fem, element_average, pixel_mesh
from .fem import (
    evaluate_q4,
    grid_fe_reference,
    hex8_stiffness,
    plate_extension_q4,
    q4_stiffness,
    solve_hex8,
    solve_q4,
)
from .surface import plate_tension_errors, shear_block_error, tension_bar_error

__all__ = [
    "crystal_plasticity_fem",
    "element_average",
    "pixel_mesh",
    "evaluate_q4",
    "grid_fe_reference",
    "hex8_stiffness",
    "plate_extension_q4",
    "q4_stiffness",
    "solve_hex8",
    "solve_q4",
    "tension_bar_error",
    "plate_tension_errors",
    "shear_block_error",
]
