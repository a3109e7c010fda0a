"""Geometry: point clouds, generators, meshes and bonds."""

from .bonds import SHAPES, Bonds, find_bonds, resolve_horizon
from .cloud import GhostLayer, Lattice, PointCloud, from_image, ghost_layer, grid
from .generators import plate_with_hole_mesh
from .influence import INFLUENCE_FUNCTIONS, influence_function
from .mesh import read_mesh
from .polycrystal import voronoi_polycrystal

__all__ = [
    "PointCloud",
    "Lattice",
    "grid",
    "from_image",
    "ghost_layer",
    "GhostLayer",
    "read_mesh",
    "plate_with_hole_mesh",
    "voronoi_polycrystal",
    "Bonds",
    "find_bonds",
    "resolve_horizon",
    "SHAPES",
    "INFLUENCE_FUNCTIONS",
    "influence_function",
]
