"""Material models: each linearizes into sparse operators and provides f(u)."""

from .base import Model
from .bond_based import BondBased, implied_poisson_ratio, standard_micromodulus
from .lps import LPS
from .xosb import XOSB

__all__ = [
    "Model",
    "BondBased",
    "implied_poisson_ratio",
    "standard_micromodulus",
    "LPS",
    "XOSB",
]
