"""Correspondence (non-ordinary state-based) peridynamics.

TODO
"""

from .controls import CONTROLS, DEFAULT_CONTROL_COEFFICIENT, SP_BALANCE_TOL, SP_MIN_RATIO
from .gradient import gradient_operator, intact_shape_tensor, voigt_projector
from .model import DEFAULT_MAX_BYTES, Correspondence
from .shadow import shadow_problem, shadow_real_counts

__all__ = [
    "Correspondence",
    "CONTROLS",
    "gradient_operator",
    "voigt_projector",
    "intact_shape_tensor",
    "shadow_real_counts",
    "shadow_problem",
    "DEFAULT_CONTROL_COEFFICIENT",
    "DEFAULT_MAX_BYTES",
    "SP_BALANCE_TOL",
    "SP_MIN_RATIO",
]
