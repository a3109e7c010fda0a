"""Geometry: point clouds, generators, meshes and bonds."""

from .bonds import SHAPES, Bonds, find_bonds, resolve_horizon
from .cloud import Lattice, PointCloud, from_image, grid
from .influence import INFLUENCE_FUNCTIONS, influence_function

__all__ = [
    "PointCloud",
    "Lattice",
    "grid",
    "from_image",
    "Bonds",
    "find_bonds",
    "resolve_horizon",
    "SHAPES",
    "INFLUENCE_FUNCTIONS",
    "influence_function",
]
