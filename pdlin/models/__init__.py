"""Material models: each linearizes into sparse operators and provides f(u)."""

from .base import Model
from .bond_based import BondBased, implied_poisson_ratio, standard_micromodulus
from .correspondence import Correspondence, gradient_operator, shadow_problem
from .damage import (
    bond_stretch,
    break_bonds,
    critical_stretch,
    damage_index,
    drop_isolated,
    isolated_points,
)
from .lps import LPS
from .surface import SURFACE_CORRECTIONS, SurfaceFactors
from .weights import (
    HigherOrderWeights,
    MomentWeights,
    WeightStatus,
    as_influence,
    gradient_exactness_order,
    gradient_symbol,
    higher_order_weights,
    lattice_moment,
    lattice_shells,
    moment_weights,
    nocontrol_weights,
    symbol_extremes,
    weights_table,
)
from .xosb import XOSB

__all__ = [
    "Model",
    "BondBased",
    "implied_poisson_ratio",
    "standard_micromodulus",
    "LPS",
    "XOSB",
    "SURFACE_CORRECTIONS",
    "SurfaceFactors",
    "Correspondence",
    "gradient_operator",
    "shadow_problem",
    "HigherOrderWeights",
    "MomentWeights",
    "WeightStatus",
    "higher_order_weights",
    "weights_table",
    "lattice_shells",
    "nocontrol_weights",
    "as_influence",
    "lattice_moment",
    "gradient_exactness_order",
    "gradient_symbol",
    "symbol_extremes",
    "moment_weights",
    "critical_stretch",
    "bond_stretch",
    "break_bonds",
    "damage_index",
    "isolated_points",
    "drop_isolated",
]
