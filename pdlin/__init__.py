"""pdlin: implicit/static peridynamics on scipy sparse operators.

The pipeline: points -> bonds -> model -> sparse operators -> boundary
conditions -> solver -> fields -> files.
"""

from typing import TYPE_CHECKING, Any

from . import (
    constitutive,
    errors,
    sweeps,  # noqa: E402  (after problem: the harness calls pdlin.solve)
)
from ._lazy import lazy_attribute
from ._threads import get_num_threads, set_num_threads
from .calibration import CalibrationResult, calibrate_micromoduli
from .constitutive.crystal_plasticity import (
    CrystalPlasticity,
    MaterialPointResult,
    SaintVenantKirchhoff,
    material_point,
)
from .errors import ConvergenceError, FloatingBodyError
from .fields import deformation_gradient, shape_tensor, small_strain
from .fracture import DamageResult, solve_damage
from .geometry import Bonds, GhostLayer, PointCloud, find_bonds, from_image, ghost_layer, grid
from .geometry.generators import plate_with_hole_mesh
from .geometry.mesh import read_mesh
from .geometry.polycrystal import voronoi_polycrystal
from .scene.decks import read_deck
from .models import LPS, XOSB, BondBased, Correspondence, Model, shadow_problem
from .models.damage import (
    bond_stretch,
    break_bonds,
    critical_stretch,
    damage_index,
    drop_isolated,
    isolated_points,
)
from .nonlinear import NonlinearResult, solve_nonlinear
from .operators import (
    BodyForce,
    Dirichlet,
    SparsityReport,
    SymmetryPlane,
    TimePath,
    TotalForce,
    assemble_stiffness,
    plot_spy,
    rigid_body_modes,
    shadow_layer,
    sparsity_report,
)
from .problem import StaticProblem
from .static import solve
from .submodeling import SubregionProblem, subregion
from .sweeps import TradeoffCase, TradeoffResult, tradeoff
from .system import ConstrainedSystem, StaticResult, constrained_system

if TYPE_CHECKING:
    from .models.weights import (
        HigherOrderWeights,
        WeightStatus,
        as_influence,
        gradient_exactness_order,
        gradient_symbol,
        higher_order_weights,
        moment_weights,
        weights_table,
    )

#: public names imported on first access (``pdlin.X``, ``from pdlin import X``): the
#: exact weights import sympy (~0.2 s), which most runs never need
_LAZY = dict.fromkeys(
    (
        "HigherOrderWeights",
        "WeightStatus",
        "as_influence",
        "gradient_exactness_order",
        "gradient_symbol",
        "higher_order_weights",
        "moment_weights",
        "weights_table",
    ),
    ".models.weights",
)


def __getattr__(name: str) -> Any:
    return lazy_attribute(__name__, _LAZY, globals(), name)


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__version__ = "0.1.0"

__all__ = [
    "set_num_threads",
    "get_num_threads",
    "errors",
    "constitutive",
    "ConvergenceError",
    "FloatingBodyError",
    "PointCloud",
    "Bonds",
    "grid",
    "from_image",
    "ghost_layer",
    "GhostLayer",
    "read_mesh",
    "read_deck",
    "plate_with_hole_mesh",
    "find_bonds",
    "BondBased",
    "LPS",
    "XOSB",
    "Correspondence",
    "shadow_problem",
    "Model",
    "assemble_stiffness",
    "rigid_body_modes",
    "Dirichlet",
    "TimePath",
    "BodyForce",
    "TotalForce",
    "shadow_layer",
    "SymmetryPlane",
    "sparsity_report",
    "SparsityReport",
    "plot_spy",
    "StaticProblem",
    "StaticResult",
    "solve",
    "solve_nonlinear",
    "subregion",
    "SubregionProblem",
    "NonlinearResult",
    "ConstrainedSystem",
    "constrained_system",
    "deformation_gradient",
    "shape_tensor",
    "small_strain",
    "calibrate_micromoduli",
    "CalibrationResult",
    "higher_order_weights",
    "weights_table",
    "HigherOrderWeights",
    "WeightStatus",
    "as_influence",
    "moment_weights",
    "gradient_symbol",
    "gradient_exactness_order",
    "critical_stretch",
    "bond_stretch",
    "break_bonds",
    "damage_index",
    "isolated_points",
    "drop_isolated",
    "solve_damage",
    "DamageResult",
    "CrystalPlasticity",
    "SaintVenantKirchhoff",
    "MaterialPointResult",
    "material_point",
    "voronoi_polycrystal",
    "sweeps",
    "tradeoff",
    "TradeoffCase",
    "TradeoffResult",
]
