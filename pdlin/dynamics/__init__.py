"""Explicit dynamics: velocity Verlet on a model's internal force, with bond damage.

``solve_explicit`` (:mod:`pdlin.dynamics.explicit`) integrates a
:class:`~pdlin.StaticProblem` in time; ``estimate_time_step``
(:mod:`pdlin.dynamics.timestep`) gives its stable time step; ``force_kernel``
(:mod:`pdlin.dynamics.forces`) the internal force with a mask of broken bonds.
See ``docs/dynamics.md``.
"""

from .explicit import ExplicitResult, solve_explicit, step_count
from .forces import force_kernel
from .timestep import (
    TimeStepEstimate,
    estimate_time_step,
    nearest_neighbour_time_step,
    nodal_masses,
)

__all__ = [
    "solve_explicit",
    "ExplicitResult",
    "step_count",
    "estimate_time_step",
    "TimeStepEstimate",
    "nearest_neighbour_time_step",
    "nodal_masses",
    "force_kernel",
]
