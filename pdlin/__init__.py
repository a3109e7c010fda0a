"""pdlin: implicit/static peridynamics on scipy sparse operators.

The pipeline: points -> bonds -> model -> sparse operators -> boundary
conditions -> constrained system -> solver -> fields -> files
(docs/architecture.md draws it and says which folder owns each stage).

The names below are the front door, in pipeline order: what a first script
needs.  Everything else lives in its subpackage (``pdlin.geometry``,
``pdlin.models``, ``pdlin.operators``, ``pdlin.analysis``, ``pdlin.io``,
``pdlin.plotting``, ...).  ``__all__`` is the list of the names imported
below (each name is written once, in its import); the names that left the
front door are listed once in ``_MOVED`` and keep working as ``pdlin.<name>``
for one release, with a :class:`DeprecationWarning` naming their new home.
"""

import typing as _typing
from types import ModuleType as _ModuleType

# subpackages used as ``pdlin.<name>.X`` (modules: not in ``__all__``)
from . import calibration as calibration
from . import constitutive as constitutive
from . import errors as errors
from . import fields as fields
from . import fracture as fracture
from . import io as io
from . import operators as operators
from . import sweeps as sweeps
from ._lazy import moved_attribute as _moved_attribute

# the front door, in pipeline order (the order of __all__); isort keeps it as written
# isort: off
# threads
from ._threads import get_num_threads as get_num_threads
from ._threads import set_num_threads as set_num_threads

# points and bonds (and the readers that make them)
from .geometry import Bonds as Bonds
from .geometry import PointCloud as PointCloud
from .geometry import find_bonds as find_bonds
from .geometry import grid as grid
from .geometry import plate_with_hole_mesh as plate_with_hole_mesh
from .geometry import read_mesh as read_mesh
from .geometry import voronoi_polycrystal as voronoi_polycrystal
from .scene.decks import read_deck as read_deck

# models and materials
from .models import LPS as LPS
from .models import XOSB as XOSB
from .models import BondBased as BondBased
from .models import Correspondence as Correspondence
from .constitutive import CrystalPlasticity as CrystalPlasticity
from .constitutive import SaintVenantKirchhoff as SaintVenantKirchhoff
from .calibration import calibrate_micromoduli as calibrate_micromoduli

# conditions
from .operators import BodyForce as BodyForce
from .operators import Dirichlet as Dirichlet
from .operators import SymmetryPlane as SymmetryPlane
from .operators import TotalForce as TotalForce
from .operators import shadow_layer as shadow_layer

# the problem and its drivers
from .problem import StaticProblem as StaticProblem
from .system import StaticResult as StaticResult
from .static import solve as solve
from .nonlinear import NonlinearResult as NonlinearResult
from .nonlinear import solve_nonlinear as solve_nonlinear
from .fracture import solve_damage as solve_damage
from .submodeling import subregion as subregion
from .sweeps import tradeoff as tradeoff
# isort: on

__version__ = "0.1.0"

#: the front door: every public non-module name bound above, in pipeline order
__all__ = [
    name
    for name, value in globals().items()
    if not name.startswith("_") and not isinstance(value, _ModuleType)
]

#: names that left the front door -> the module they are imported from now; ``pdlin.<name>``
#: keeps working for one release with a DeprecationWarning
_MOVED = {
    **dict.fromkeys(("ConvergenceError", "FloatingBodyError"), "pdlin.errors"),
    **dict.fromkeys(("from_image", "ghost_layer", "GhostLayer"), "pdlin.geometry"),
    **dict.fromkeys(("Model", "shadow_problem"), "pdlin.models"),
    **dict.fromkeys(
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
        "pdlin.models.weights",
    ),
    **dict.fromkeys(
        (
            "bond_stretch",
            "break_bonds",
            "critical_stretch",
            "damage_index",
            "drop_isolated",
            "isolated_points",
        ),
        "pdlin.models.damage",
    ),
    **dict.fromkeys(("MaterialPointResult", "material_point"), "pdlin.constitutive"),
    **dict.fromkeys(("assemble_stiffness", "rigid_body_modes", "TimePath"), "pdlin.operators"),
    **dict.fromkeys(("SparsityReport", "sparsity_report"), "pdlin.analysis"),
    "plot_spy": "pdlin.plotting",
    **dict.fromkeys(("ConstrainedSystem", "constrained_system"), "pdlin.system"),
    **dict.fromkeys(("deformation_gradient", "shape_tensor", "small_strain"), "pdlin.fields"),
    "CalibrationResult": "pdlin.calibration",
    "DamageResult": "pdlin.fracture",
    "SubregionProblem": "pdlin.submodeling",
    **dict.fromkeys(("TradeoffCase", "TradeoffResult"), "pdlin.sweeps"),
}


def __getattr__(name: str) -> _typing.Any:
    return _moved_attribute(__name__, _MOVED, name)
