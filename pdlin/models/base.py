"""The interface every pdlin model implements."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._repr import compact_repr
from ..errors import ModelError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud

__all__ = ["Model", "Response"]


@dataclass
class Response:
    """What a model returns to a nonlinear driver at one displacement.

    Attributes
    ----------
    force : (n, dim) ndarray
        Nodal internal force ``f_int(u)`` from the committed state.
    state : dict of str -> ndarray
        Trial state at ``u`` (per point or per gradient point).  Drivers
        commit it when the load step converges; the model never mutates the
        committed state it was given.  Like ``stress``, a model may give a
        function of no arguments instead, called on the first read: an ADR
        iteration or a line-search trial only needs the force.  It reads the
        committed state as it is then, so a caller must not change that state
        before reading ``state`` (the drivers never change a committed state).
    tangent : sparse array, optional
        Consistent tangent stiffness ``K_T = -∂f_int/∂u`` (BSR, blocksize
        dim), when asked for.
    stress : (n, dim, dim) ndarray, optional
        Cauchy stress per point at ``u`` (for output and homogenization).  A
        model may give a function of no arguments instead: it is called on the
        first read of ``stress`` (drivers read it once per converged step, not
        at every ADR iteration or line-search trial).
    calls : int
        Constitutive evaluations spent (points x updates), for the driver's
        counters.

    Examples
    --------
    >>> import numpy as np
    >>> r = Response(np.zeros((2, 1)), stress=lambda: np.ones((2, 1, 1)),
    ...              state=lambda: {"ep": np.zeros(2)})
    >>> r.stress.shape, sorted(r.state)
    ((2, 1, 1), ['ep'])
    """

    force: np.ndarray
    state: Any = field(default_factory=dict)
    tangent: sp.sparray | None = None
    stress: Any = None
    calls: int = 0

    def __getattribute__(self, name: str) -> Any:
        """Return an attribute, evaluating a lazy ``stress`` or ``state`` once on first read."""
        value = object.__getattribute__(self, name)
        if name not in ("stress", "state") or not callable(value):
            return value
        # the lazy stress or state, evaluated once
        value = np.asarray(value()) if name == "stress" else dict(value())
        object.__setattr__(self, name, value)
        return value


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
    #: whether the internal force is nonlinear in u or depends on a history state
    #: (such models are solved by :func:`pdlin.solve_nonlinear`)
    nonlinear: bool = False

    @abstractmethod
    def stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.sparray:
        """Return the sparse linearized stiffness ``K`` (n*dim x n*dim).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``dim``).
        bonds : Bonds
            Their bonds.

        Returns
        -------
        scipy.sparse.sparray
            ``K`` with ``internal_force(u) == -K @ u`` for the linear form.
        """

    @abstractmethod
    def internal_force(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, linear: bool = True
    ) -> np.ndarray:
        """Return the nodal internal force ``(n, dim)`` for displacement ``u``.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``dim``).
        bonds : Bonds
            Their bonds.
        u : (n, dim) array_like
            Nodal displacement.
        linear : bool
            Linearized force ``-K u`` (True) or the model's nonlinear force.

        Returns
        -------
        (n, dim) ndarray
            Nodal forces (force density times volume).
        """

    def operator(self, cloud: PointCloud, bonds: Bonds) -> spla.LinearOperator:
        """Return ``K`` as a :class:`~scipy.sparse.linalg.LinearOperator`.

        The default wraps the assembled stiffness; models whose K couples
        two horizons override it with a matrix-free product.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``dim``).
        bonds : Bonds
            Their bonds.

        Returns
        -------
        scipy.sparse.linalg.LinearOperator
            ``(n*dim, n*dim)``.
        """
        return spla.aslinearoperator(self.stiffness(cloud, bonds))

    def surrogate_stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.sparray:
        """Return an assembled one-hop matrix spectrally close to ``K``.

        The matrix-free path preconditions with it.  The default is the model's own
        stiffness when ``K`` couples one horizon (``coupling_range == 1``: it is its
        own best surrogate); models coupling two horizons override it (state-based:
        the bond-based ``K`` of the same bonds).

        Parameters
        ----------
        cloud : PointCloud
            The points.
        bonds : Bonds
            Their bonds.

        Returns
        -------
        scipy.sparse.sparray
            ``(n*dim, n*dim)``.

        Raises
        ------
        ModelError
            The model couples two horizons and defines no surrogate.
        """
        if self.coupling_range == 1:
            return self.stiffness(cloud, bonds)
        raise ModelError(
            f"{type(self).__name__} has no surrogate stiffness for the matrix-free path "
            "(define surrogate_stiffness or use operator='assembled')"
        )

    def energy(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> float:
        """Return the linearized strain energy ``½ uᵀ K u`` (matrix-free where possible).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``dim``).
        bonds : Bonds
            Their bonds.
        u : (n, dim) array_like
            Nodal displacement.

        Returns
        -------
        float
            The energy, from the linear internal force.
        """
        f = self.internal_force(cloud, bonds, u, linear=True)
        return float(-0.5 * np.sum(f * np.asarray(u).reshape(f.shape)))

    # -- nonlinear interface (drivers: Newton, ADR) ---------------------------
    def initial_state(self, cloud: PointCloud, bonds: Bonds) -> dict[str, np.ndarray]:
        """Return the committed state before the first load step (empty for elastic models).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``dim``).
        bonds : Bonds
            Their bonds.

        Returns
        -------
        dict of str -> ndarray
            The state variables (none here).
        """
        return {}

    def respond(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray,
        state: dict[str, np.ndarray],
        *,
        tangent: bool = False,
    ) -> Response:
        """Return the internal force, trial state and (optionally) tangent at ``u``.

        ``state`` is the committed state of the last converged load step;
        the call is a pure function of ``(u, state)``.  The default is the
        linear model: ``f = -K u`` (matrix-free product where the model has
        one), the state unchanged and ``K_T = K``.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``dim``).
        bonds : Bonds
            Their bonds.
        u : (n, dim) array_like
            Nodal displacement.
        state : dict of str -> ndarray
            Committed state of the last converged load step.
        tangent : bool
            Whether to compute the tangent ``K_T``.

        Returns
        -------
        Response
            Force, trial state, tangent (None unless asked) and counters.
        """
        f = np.asarray(self.internal_force(cloud, bonds, u, linear=True))
        K = self.stiffness(cloud, bonds) if tangent else None
        return Response(f, dict(state), K, None, 0)

    def committed_issues(self, state: dict[str, np.ndarray]) -> list[tuple[type[Warning], str]]:
        """Warnings about a committed state (``(category, message)`` pairs, default none).

        The nonlinear drivers call it after every converged load step and issue what it
        returns; trial states are not checked (their :class:`~pdlin.errors.TrialStateWarning`
        are ignored).  Models with a history-dependent material delegate to it.

        Parameters
        ----------
        state : dict of str -> ndarray
            A committed state.

        Returns
        -------
        list of (type, str)
            Warning category and message pairs (empty by default).
        """
        material = getattr(self, "material", None)
        check = getattr(material, "committed_issues", None)
        return list(check(state)) if callable(check) else []

    def estimate_nnz_blocks(self, cloud: PointCloud, bonds: Bonds) -> int:
        """Return the number of dim x dim blocks of K, without assembling it.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``dim``).
        bonds : Bonds
            Their bonds.

        Returns
        -------
        int
            Bonds plus diagonal blocks (one-hop models).
        """
        return int(bonds.n_bonds + cloud.n)

    def describe(self) -> dict[str, Any]:
        """Return a plain-data description of the model (for results and logs).

        Returns
        -------
        dict
            At least ``{'model': class name}``.
        """
        return {"model": type(self).__name__}

    def _repr_items(self) -> dict[str, Any]:
        """Parameters shown by ``repr`` (default: :meth:`describe` without the name)."""
        return {k: v for k, v in self.describe().items() if k != "model"}

    def __repr__(self) -> str:
        """Class and parameters, without arrays or memory addresses.

        Examples
        --------
        >>> import pdlin
        >>> pdlin.LPS(E=1e9, nu=0.25)  # doctest: +ELLIPSIS
        LPS(E=1e+09, nu=0.25, plane='stress', ...)
        """
        return compact_repr(type(self).__name__, self._repr_items())
