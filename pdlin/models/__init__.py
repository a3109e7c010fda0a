"""Material models: each linearizes into sparse operators and provides f(u)."""

from typing import TYPE_CHECKING, Any

from .._lazy import lazy_attribute
from .base import Model
from .bond_based import BondBased, implied_poisson_ratio, standard_micromodulus
from .correspondence import (
    Correspondence,
    PeridigmCorrespondence,
    gradient_operator,
    shadow_problem,
)
from .damage import (
    bond_stretch,
    break_bonds,
    critical_stretch,
    damage_index,
    drop_isolated,
    isolated_points,
)
from .lps import LPS
from .peridigm_state import PeridigmElastic, PeridigmElasticPlastic
from .surface import SURFACE_CORRECTIONS, SurfaceFactors
from .xosb import XOSB

if TYPE_CHECKING:
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

#: names of :mod:`pdlin.models.weights`, imported on first access (it imports sympy, ~0.2 s)
_LAZY = dict.fromkeys(
    (
        "HigherOrderWeights",
        "MomentWeights",
        "WeightStatus",
        "as_influence",
        "gradient_exactness_order",
        "gradient_symbol",
        "higher_order_weights",
        "lattice_moment",
        "lattice_shells",
        "moment_weights",
        "nocontrol_weights",
        "symbol_extremes",
        "weights_table",
    ),
    ".weights",
)


def __getattr__(name: str) -> Any:
    return lazy_attribute(__name__, _LAZY, globals(), name)


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__all__ = [
    "Model",
    "BondBased",
    "implied_poisson_ratio",
    "standard_micromodulus",
    "LPS",
    "PeridigmElastic",
    "PeridigmElasticPlastic",
    "XOSB",
    "SURFACE_CORRECTIONS",
    "SurfaceFactors",
    "Correspondence",
    "PeridigmCorrespondence",
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
