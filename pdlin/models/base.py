"""The interface every pdlin model implements."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ModelError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud

__all__ = ["Model"]


class Model(ABC):
    """Base class of pdlin material models.

    A model turns a cloud and its bonds into sparse operators (``stiffness``)
    and evaluates its internal force ``f(u)``; solvers never see the model,
    only its operators and vectors.

    Conventions: nodal forces (force density times volume), interleaved
    DOFs ``dof = dim * i + k``, ``internal_force(u) == -K @ u`` for the
    linear form.
    """

    #: how many horizons apart two points coupled by K can be (1 for
    #: bond-based, 2 for state-based and correspondence models)
    coupling_range: int = 1
    #: whether K is symmetric
    symmetric: bool = True

    @abstractmethod
    def stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.sparray:
        """Sparse linearized stiffness ``K`` (n*dim x n*dim)."""

    @abstractmethod
    def internal_force(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, linear: bool = True
    ) -> np.ndarray:
        """Nodal internal force ``(n, dim)`` for displacement ``u`` ``(n, dim)``."""

    def operator(self, cloud: PointCloud, bonds: Bonds) -> spla.LinearOperator:
        """``K`` as a :class:`~scipy.sparse.linalg.LinearOperator`.

        The default wraps the assembled stiffness; models whose K couples
        two horizons override it with a matrix-free product.
        """
        return spla.aslinearoperator(self.stiffness(cloud, bonds))

    def surrogate_stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.sparray:
        """Assembled one-hop matrix spectrally close to K, used to precondition
        the matrix-free path (default: the bond-based stiffness with the
        model's ``E`` on the same bonds)."""
        from .bond_based import BondBased

        E = getattr(self, "E", None)
        if E is None:
            raise ModelError(
                f"{type(self).__name__} has no surrogate stiffness for the matrix-free path "
                "(define surrogate_stiffness or use operator='assembled')"
            )
        return BondBased(E=E, plane=getattr(self, "plane", "stress")).stiffness(cloud, bonds)

    def energy(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> float:
        """Linearized strain energy ``½ uᵀ K u`` (matrix-free where possible)."""
        f = self.internal_force(cloud, bonds, u, linear=True)
        return float(-0.5 * np.sum(f * np.asarray(u).reshape(f.shape)))

    def estimate_nnz_blocks(self, cloud: PointCloud, bonds: Bonds) -> int:
        """Number of dim x dim blocks of K, without assembling it."""
        return int(bonds.n_bonds + cloud.n)

    def describe(self) -> dict[str, Any]:
        """Plain-data description of the model (for results and logs)."""
        return {"model": type(self).__name__}
