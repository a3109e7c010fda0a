"""One constrained system shared by every driver (linear solve, Newton, ADR).

A :class:`~pdlin.StaticProblem` is transformed once into a
:class:`ConstrainedSystem`: the DOFs a driver solves for, their prescribed
subset and values, the external force, and how to apply or assemble the
(tangent) operator and evaluate ``f_int(u)`` and reactions.  The symmetry
reduction is one such transformation (a :class:`Discretization` whose
operators act on the real DOFs only), not a branch inside each stage; the
drivers never ask how the system was reduced.

The pieces:

* :class:`Discretization` -- the model's operators on the solved points:
  :class:`PlainDiscretization` (the cloud itself) or
  :class:`~pdlin.operators.symmetry.SymmetryReduction` (mirror planes).
* :class:`ConstrainedSystem` -- a discretization plus Dirichlet conditions
  and loads: Dirichlet elimination that keeps the BSR block structure,
  matrix-free systems, residuals of the free equations, reactions.
* :func:`constrained_system` = :func:`discretize` then :func:`constrain`;
  :func:`point_system` builds the same prescribed DOFs, values and loads on a
  :class:`PointDiscretization` (no bonds) for drivers that assemble their own
  rows (the PETSc backend).
* :class:`StaticResult` -- a solution of the system, with its fields.

Layers: the problem's data (``pdlin.problem``) and the functions of the
system (:mod:`pdlin.constraints`) below, the drivers (:func:`pdlin.solve` in
``pdlin.static``, :func:`pdlin.solve_nonlinear`, the PETSc backend
``pdlin.backends.petsc``) on top.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, cast, runtime_checkable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ._repr import Raw, compact_repr, html_table
from .constraints import (
    IsolatedPoints,
    check_constraints,
    eliminate_dirichlet,
    hold_isolated,
    load_vector,
    matrix_rows,
    resolve_dirichlet,
    thermal_load,
)
from .errors import FloatingBodyError, InputError, InputTypeError, ModelError
from .fields import deformation_gradient, small_strain
from .geometry.bonds import Bonds, resolve_horizon
from .geometry.cloud import PointCloud
from .models.base import Model
from .models.thermal import mechanical_strain, thermal_stress
from .operators.assembly import assemble_stiffness
from .operators.bc import Dirichlet, TimePath
from .operators.rigid import rigid_body_modes
from .operators.symmetry import MirrorCloud, SymmetryReduction, mirror_cloud, symmetry_reduction
from .problem import StaticProblem

__all__ = [
    "Discretization",
    "PlainDiscretization",
    "PointDiscretization",
    "ConstrainedSystem",
    "StaticResult",
    "constrained_system",
    "discretize",
    "constrain",
    "point_system",
    "mirror_reach",
]

log = logging.getLogger(__name__)


@runtime_checkable
class Discretization(Protocol):
    """A model's operators on the points a driver solves for.

    Vectors are ``(n, dim)`` or flat ``(n*dim,)`` on :attr:`cloud`.  Implemented by
    :class:`PlainDiscretization` and :class:`~pdlin.operators.symmetry.SymmetryReduction`.
    """

    model: Any

    @property
    def cloud(self) -> PointCloud:
        """The solved points."""
        ...

    @property
    def real_bonds(self) -> Bonds:
        """Bonds between solved points (ghost bonds of a reduction excluded)."""
        ...

    @property
    def family_size(self) -> np.ndarray:
        """Bonds per solved point ``(n,)``."""
        ...

    def stiffness(self) -> sp.sparray:
        """Return the assembled stiffness on the solved DOFs."""
        ...

    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray:
        """Return ``f_int(u)`` on the solved points.

        Parameters
        ----------
        u : (n, dim) or (n*dim,) array_like
            Displacement of the solved points.
        linear : bool
            The linearized (small-displacement) force, else the model's nonlinear one.
        """
        ...

    def load_vector(
        self, loads: Sequence[Any], *, prescribed: np.ndarray | None = None
    ) -> np.ndarray:
        """Return the external nodal force ``(n*dim,)``.

        Parameters
        ----------
        loads : sequence of BodyForce / TotalForce
            The problem's loads.
        prescribed : (m,) ndarray of int, optional
            Prescribed DOFs; a load acting on them only raises.
        """
        ...

    def dirichlet(self) -> list[Dirichlet]:
        """Return the discretization's own conditions (e.g. the symmetry planes')."""
        ...

    def check_constraints(self, dofs: np.ndarray) -> None:
        """Raise :class:`~pdlin.errors.FloatingBodyError` when ``dofs`` leave a rigid motion free.

        Parameters
        ----------
        dofs : (m,) ndarray of int
            Prescribed DOFs.
        """
        ...

    def deformation_gradient(self, u: Any) -> np.ndarray:
        """Return the nonlocal deformation gradient ``(n, dim, dim)``.

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement of the solved points.
        """
        ...

    def stress(self, u: Any) -> np.ndarray:
        """Return the model's stress ``(n, dim, dim)``.

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement of the solved points.
        """
        ...

    def initial_state(self) -> dict[str, np.ndarray]:
        """Return the model's committed state before the first load step."""
        ...

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any:
        """Return the model's ``Response`` (force, trial state, tangent) at ``u``.

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement of the solved points.
        state : dict of str to ndarray
            Committed state of the last converged load step (not modified).
        tangent : bool
            Also return the tangent stiffness.
        """
        ...


@dataclass(frozen=True, eq=False)
class PlainDiscretization:
    """The model on the cloud itself (no reduction).

    Parameters
    ----------
    model : Model
        Any pdlin model.
    points : PointCloud
        The solved points.
    bonds : Bonds
        Their bonds.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.system import PlainDiscretization
    >>> cloud = pdlin.grid((5,), spacing=0.1)
    >>> disc = PlainDiscretization(pdlin.BondBased(E=1.0), cloud, pdlin.find_bonds(cloud, ratio=2))
    >>> disc.stiffness().shape, disc.family_size.tolist()
    ((5, 5), [2, 3, 4, 3, 2])
    """

    model: Any
    points: PointCloud
    bonds: Bonds

    @property
    def cloud(self) -> PointCloud:
        """The solved points (``points``)."""
        return self.points

    @property
    def real_bonds(self) -> Bonds:
        """The bonds (all between solved points)."""
        return self.bonds

    @property
    def family_size(self) -> np.ndarray:
        """Bonds per point ``(n,)``."""
        return self.bonds.family_size

    def stiffness(self) -> sp.sparray:
        """Assemble the model's stiffness.

        Returns
        -------
        sparse array of shape (n*dim, n*dim)
            BSR with blocksize dim.
        """
        return assemble_stiffness(self.model, self.points, self.bonds)

    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray:
        """Compute the model's internal force.

        Parameters
        ----------
        u : (n, dim) or (n*dim,) array_like
            Displacement.
        linear : bool
            The linearized force ``-K u``, else the model's nonlinear force.

        Returns
        -------
        (n, dim) ndarray
            Nodal internal forces.
        """
        return np.asarray(self.model.internal_force(self.points, self.bonds, u, linear=linear))

    def load_vector(
        self, loads: Sequence[Any], *, prescribed: np.ndarray | None = None
    ) -> np.ndarray:
        """Compute the external force; loads acting on ``prescribed`` DOFs only raise.

        Parameters
        ----------
        loads : sequence of BodyForce / TotalForce
            The problem's loads.
        prescribed : (m,) ndarray of int, optional
            Prescribed DOFs (see :func:`pdlin.constraints.load_vector`).

        Returns
        -------
        (n*dim,) ndarray
            Nodal external forces.
        """
        return load_vector(self.points, loads, prescribed=prescribed)

    def dirichlet(self) -> list[Dirichlet]:
        """Return no extra conditions (a reduction adds its plane conditions here).

        Returns
        -------
        list of Dirichlet
            Empty.
        """
        return []

    def check_constraints(self, dofs: np.ndarray) -> None:
        """Raise when ``dofs`` leave a rigid motion of a bond-connected piece free.

        Parameters
        ----------
        dofs : (m,) ndarray of int
            Prescribed DOFs.

        Raises
        ------
        FloatingBodyError
            When a piece has no prescribed DOF or a rigid motion stays free.
        """
        check_constraints(self.points, self.bonds, dofs)

    def deformation_gradient(self, u: Any) -> np.ndarray:
        """Compute the nonlocal deformation gradient.

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement.

        Returns
        -------
        (n, dim, dim) ndarray
            ``F`` per point.
        """
        return deformation_gradient(self.points, self.bonds, u)

    def stress(self, u: Any) -> np.ndarray:
        """Compute the model's stress.

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement.

        Returns
        -------
        (n, dim, dim) ndarray
            Stress per point (virial for bond-based models).

        Raises
        ------
        InputError
            When the model defines no stress.
        """
        if not hasattr(self.model, "stress"):
            raise InputError(f"model {type(self.model).__name__} does not define a stress")
        return np.asarray(self.model.stress(self.points, self.bonds, u))

    def initial_state(self) -> dict[str, np.ndarray]:
        """Return the model's committed state before the first load step.

        Returns
        -------
        dict of str to ndarray
            Per-point state arrays (empty for elastic models).
        """
        return dict(self.model.initial_state(self.points, self.bonds))

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any:
        """Return the model's response at ``u`` from the committed ``state``.

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement.
        state : dict of str to ndarray
            Committed state of the last converged load step (not modified).
        tangent : bool
            Also compute the tangent stiffness.

        Returns
        -------
        Response
            Internal force, trial state and (with ``tangent``) the tangent.
        """
        return self.model.respond(self.points, self.bonds, u, state, tangent=tangent)

    # -- matrix-free path (only the plain discretization has it) ----------
    def operator(self) -> spla.LinearOperator:
        """Return the model's matrix-free stiffness operator.

        Returns
        -------
        LinearOperator of shape (n*dim, n*dim)
            Applies K without assembling it (``model.operator``).
        """
        return self.model.operator(self.points, self.bonds)

    def surrogate_stiffness(self) -> sp.sparray:
        """Assemble the model's one-hop surrogate of K (the matrix-free preconditioner's).

        Returns
        -------
        sparse array of shape (n*dim, n*dim)
            ``model.surrogate_stiffness``.
        """
        return self.model.surrogate_stiffness(self.points, self.bonds)

    def estimate_nnz_blocks(self) -> int:
        """Estimate the stored blocks of the assembled K.

        Returns
        -------
        int
            ``dim x dim`` blocks of K (``model.estimate_nnz_blocks``).
        """
        return int(self.model.estimate_nnz_blocks(self.points, self.bonds))

    def with_model(self, model: Any) -> PlainDiscretization:
        """Return the same points and bonds under another model (e.g. a preconditioner's).

        Parameters
        ----------
        model : Model
            The other model.

        Returns
        -------
        PlainDiscretization
        """
        return PlainDiscretization(model, self.points, self.bonds)


@dataclass(eq=False)
class ConstrainedSystem:
    """Prescribed and free DOFs, loads and operators of one problem.

    Attributes
    ----------
    disc : Discretization
        The model's operators on the solved points.
    dofs : (m,) ndarray of int
        Prescribed DOFs, sorted.
    values : (m,) ndarray
        Their prescribed values (at load factor 1).
    f_ext : (ndof,) ndarray
        External nodal forces (at load factor 1).
    problem : StaticProblem or None
        The problem it was built from.
    paths : tuple of Dirichlet
        Conditions whose value is a :class:`~pdlin.operators.TimePath` (re-evaluated per time).

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((10,), spacing=0.1)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.2,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0)], loads=[pdlin.TotalForce("x+", [1e-3])])
    >>> sys = pdlin.system.constrained_system(prob)
    >>> A, b = sys.eliminate(sys.assemble())
    >>> u = sys.expand(np.linalg.solve(A.toarray(), b))
    >>> bool(np.abs(sys.residual(u)).max() < 1e-15), sys.reactions(u).sum().round(6)
    (True, np.float64(-0.001))
    """

    disc: Any
    dofs: np.ndarray
    values: np.ndarray
    f_ext: np.ndarray
    problem: Any = None
    #: Dirichlet conditions with a :class:`~pdlin.operators.TimePath` value (re-evaluated per time)
    paths: tuple[Dirichlet, ...] = ()
    _free: np.ndarray | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        """Return a one-line summary: model, sizes, prescribed and free DOFs (no arrays)."""
        return compact_repr(
            "ConstrainedSystem",
            {
                "model": Raw(repr(self.model)),
                "points": self.n,
                "dim": self.dim,
                "DOFs": self.ndof,
                "prescribed": int(self.dofs.size),
                "discretization": type(self.disc).__name__,
                "time_paths": len(self.paths) or None,
            },
        )

    # -- sizes and masks ----------------------------------------------------
    @property
    def cloud(self) -> PointCloud:
        """The solved points (the real half / quarter with symmetry planes)."""
        return self.disc.cloud

    @property
    def model(self) -> Any:
        """The model (of the discretization: per-point parameters mapped to ghosts)."""
        return self.disc.model

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        return self.cloud.dim

    @property
    def n(self) -> int:
        """Number of solved points."""
        return self.cloud.n

    @property
    def ndof(self) -> int:
        """Number of solved DOFs, ``n * dim``."""
        return self.cloud.n * self.cloud.dim

    @property
    def symmetric(self) -> bool:
        """Whether the model's stiffness is symmetric (CG applies)."""
        return bool(getattr(self.model, "symmetric", True))

    @property
    def free(self) -> np.ndarray:
        """Boolean mask of the free DOFs ``(ndof,)``."""
        if self._free is None:
            free = np.ones(self.ndof, dtype=bool)
            free[self.dofs] = False
            self._free = free
        return self._free

    @property
    def matrix_free_capable(self) -> bool:
        """Whether the discretization can apply K without assembling it."""
        return hasattr(self.disc, "operator")

    def near_null(self) -> np.ndarray:
        """Return the rigid-body modes with the prescribed rows zeroed (AMG near-null space).

        Returns
        -------
        (ndof, k) ndarray
            The ``k`` rigid-body modes of the solved points (3 in 2D, 6 in 3D).
        """
        B = rigid_body_modes(self.cloud)
        B[self.dofs] = 0.0
        return B

    def prescribed(self, factor: float = 1.0) -> np.ndarray:
        """Return the full displacement vector holding ``factor`` x the prescribed values.

        Parameters
        ----------
        factor : float
            Load factor.

        Returns
        -------
        (ndof,) ndarray
            Zero on the free DOFs.
        """
        u = np.zeros(self.ndof)
        u[self.dofs] = factor * self.values
        return u

    def values_at(self, t: float, factor: float) -> np.ndarray:
        """Return the prescribed values at time ``t`` of a load path.

        Plain values are scaled by the load ``factor``; :class:`~pdlin.operators.TimePath`
        values (e.g. :meth:`~pdlin.Dirichlet.velocity_gradient`) are evaluated
        at ``t`` instead.

        Parameters
        ----------
        t : float
            Time of the load step.
        factor : float
            Load factor of the plain values.

        Returns
        -------
        (m,) ndarray
            Values of ``dofs``.
        """
        vals = factor * self.values
        if self.paths:
            pd, pv = resolve_dirichlet(self.cloud, self.paths, t=t)
            vals[np.searchsorted(self.dofs, pd)] = pv
        return vals

    # -- operators ----------------------------------------------------------
    def estimate_nnz_blocks(self) -> int:
        """Estimate the stored ``dim x dim`` blocks of the assembled stiffness.

        Returns
        -------
        int
            Block count (the memory plan and the operator choice use it).
        """
        if hasattr(self.disc, "estimate_nnz_blocks"):
            return int(self.disc.estimate_nnz_blocks())
        return int(self.model.estimate_nnz_blocks(self.cloud, self.disc.real_bonds))

    def assemble(self) -> sp.sparray:
        """Assemble the (unconstrained) stiffness on the solved DOFs.

        Returns
        -------
        sparse array of shape (ndof, ndof)
            BSR with blocksize dim.
        """
        return self.disc.stiffness()

    def eliminate(
        self, K: sp.sparray, *, inplace: bool = False, factor: float = 1.0
    ) -> tuple[sp.sparray, np.ndarray]:
        """Return the eliminated system ``(A, b)`` for the unknown ``x`` with ``x[dofs] = 0``.

        ``A`` keeps K's size and block structure (prescribed rows and
        columns become ``s I``); ``b`` holds ``f_ext - K_fc u_c`` on the free
        rows and 0 on the prescribed ones, so the relative residual of a
        solve is that of the free equations.  :meth:`expand` writes the
        prescribed values back.

        Parameters
        ----------
        K : sparse array of shape (ndof, ndof)
            The stiffness (:meth:`assemble`).
        inplace : bool
            Overwrite K's data (saves a copy of the largest array).
        factor : float
            Load factor of the prescribed values and the external force.

        Returns
        -------
        A : sparse array of shape (ndof, ndof)
            The eliminated matrix.
        b : (ndof,) ndarray
            The eliminated right-hand side.
        """
        A, b = eliminate_dirichlet(
            K, factor * self.f_ext, self.dofs, factor * self.values, inplace=inplace
        )
        b = np.array(b, dtype=float)
        b[self.dofs] = 0.0
        return A, b

    def eliminate_matrix(self, K: sp.sparray) -> sp.sparray:
        """Replace the prescribed rows and columns of ``K`` by ``s I`` (no load), in place.

        Parameters
        ----------
        K : sparse array of shape (ndof, ndof)
            A matrix on the solved DOFs (a preconditioner's stiffness, a surrogate).

        Returns
        -------
        sparse array of shape (ndof, ndof)
            The eliminated matrix.
        """
        A, _ = eliminate_dirichlet(
            K, np.zeros(self.ndof), self.dofs, np.zeros(self.dofs.size), inplace=True
        )
        return A

    def matrix_free(
        self, factor: float = 1.0, *, op: spla.LinearOperator | None = None
    ) -> tuple[spla.LinearOperator, np.ndarray, sp.sparray]:
        """Return the eliminated matrix-free system and its eliminated surrogate.

        Prescribed rows and columns become ``s * I`` in both, with ``s`` the
        mean free diagonal of the surrogate, as in :meth:`eliminate`; ``b``
        is 0 on the prescribed rows.

        Parameters
        ----------
        factor : float
            Load factor of the prescribed values and the external force.
        op : LinearOperator, optional
            The discretization's operator (``disc.operator()``) when already built (kept
            by ``pdlin.static.solve_steps`` for the right-hand sides, :meth:`rhs`).

        Returns
        -------
        A : LinearOperator of shape (ndof, ndof)
            The eliminated operator.
        b : (ndof,) ndarray
            The eliminated right-hand side.
        P : sparse array of shape (ndof, ndof)
            The eliminated one-hop surrogate (to build the preconditioner from).

        Raises
        ------
        InputError
            When the discretization has no matrix-free operator (symmetry planes).
        """
        if not self.matrix_free_capable:
            raise InputError(
                "operator='matrix-free' does not support symmetry planes yet; "
                "use operator='assembled'"
            )
        ndof = self.ndof
        if op is None:
            op = self.disc.operator()
        sur = self.disc.surrogate_stiffness()
        free = self.free
        diag = sur.diagonal()
        s = float(np.mean(np.abs(diag[free]))) if free.any() else 1.0
        P = self.eliminate_matrix(sur)
        uc = self.prescribed(factor)
        b = factor * self.f_ext - op @ uc
        b[~free] = 0.0
        fmask = free.astype(float)

        def mv(x: np.ndarray) -> np.ndarray:
            x = np.asarray(x, dtype=float).reshape(-1)
            y = np.asarray(op @ (x * fmask), dtype=float)
            y[~free] = s * x[~free]
            return y

        A = spla.LinearOperator((ndof, ndof), matvec=mv, rmatvec=mv, dtype=float)
        return A, b, P

    def preconditioner_matrix(self, pmodel: Any) -> sp.sparray:
        """Return the eliminated assembled stiffness of another model on the same bonds.

        Parameters
        ----------
        pmodel : Model
            The preconditioner's model.

        Returns
        -------
        sparse array of shape (ndof, ndof)
            Its stiffness with the prescribed rows and columns replaced by ``s I``.

        Raises
        ------
        InputTypeError
            When ``pmodel`` is not a pdlin model.
        InputError
            With symmetry planes.
        """
        if not isinstance(pmodel, Model):
            raise InputTypeError(
                "preconditioner must be a pdlin model (BondBased, LPS, XOSB, Correspondence), "
                f"got {type(pmodel).__name__}"
            )
        if not hasattr(self.disc, "with_model"):
            raise InputError(
                "preconditioner= needs a problem without symmetry planes, got "
                f"{type(self.disc).__name__}"
            )
        return self.eliminate_matrix(self.disc.with_model(pmodel).stiffness())

    # -- vectors -------------------------------------------------------------
    def expand(self, x: np.ndarray, factor: float = 1.0) -> np.ndarray:
        """Return the displacement from a solution ``x`` of the eliminated system.

        Parameters
        ----------
        x : (ndof,) array_like
            Solution of the eliminated system.
        factor : float
            Load factor of the prescribed values written back.

        Returns
        -------
        (n, dim) ndarray
            ``x`` with the prescribed values on ``dofs``.

        Raises
        ------
        InputError
            When ``x`` does not have ``ndof`` entries.
        """
        u = np.array(x, dtype=float).reshape(-1)
        if u.shape != (self.ndof,):
            raise InputError(f"x must have {self.ndof} entries, got {u.shape}")
        u[self.dofs] = factor * self.values
        return u.reshape(self.n, self.dim)

    def initial_state(self) -> dict[str, np.ndarray]:
        """Return the model's committed state before the first load step.

        Returns
        -------
        dict of str to ndarray
            Per-point state arrays (empty for elastic models).
        """
        return dict(self.disc.initial_state())

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any:
        """Return the model's ``Response`` at ``u`` (flat or ``(n, dim)``).

        A pure function of ``(u, state)``: ``state`` is the committed state
        of the last converged load step and is never modified.

        Parameters
        ----------
        u : (ndof,) or (n, dim) array_like
            Displacement.
        state : dict of str to ndarray
            Committed state.
        tangent : bool
            Also compute the tangent stiffness.

        Returns
        -------
        Response
            Internal force, trial state and (with ``tangent``) the tangent.
        """
        uu = np.asarray(u, dtype=float).reshape(self.n, self.dim)
        return self.disc.respond(uu, state, tangent=tangent)

    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray:
        """Compute the internal force ``f_int(u)``.

        Parameters
        ----------
        u : (ndof,) or (n, dim) array_like
            Displacement.
        linear : bool
            The linearized force, else the model's nonlinear one.

        Returns
        -------
        (ndof,) ndarray
            Flat nodal internal forces.
        """
        return np.asarray(self.disc.internal_force(u, linear=linear), dtype=float).reshape(-1)

    def residual(
        self, u: Any, *, factor: float = 1.0, linear: bool = True, f_int: Any = None
    ) -> np.ndarray:
        """Compute the out-of-balance force ``f_int(u) + factor f_ext`` on the free DOFs.

        Parameters
        ----------
        u : (ndof,) or (n, dim) array_like
            Displacement.
        factor : float
            Load factor of the external force.
        linear : bool
            The linearized internal force, else the model's nonlinear one.
        f_int : array_like, optional
            The internal force at ``u`` when already computed.

        Returns
        -------
        (ndof,) ndarray
            Residual, 0 on the prescribed DOFs.
        """
        fi = self.internal_force(u, linear=linear) if f_int is None else np.ravel(f_int)
        r = fi + factor * self.f_ext
        r[self.dofs] = 0.0
        return r

    def reactions(
        self,
        u: Any,
        *,
        factor: float = 1.0,
        rows: sp.sparray | None = None,
        linear: bool = True,
        f_int: Any = None,
    ) -> np.ndarray:
        """Compute the nodal reactions ``-(f_int + f_ext)`` on the prescribed DOFs.

        Parameters
        ----------
        u : (ndof,) or (n, dim) array_like
            Displacement.
        factor : float
            Load factor of the external force.
        rows : sparse array, optional
            K's prescribed rows (:meth:`prescribed_rows`, kept before an in-place
            elimination), which give ``f_int = -K u`` there without a full
            internal-force pass.
        linear : bool
            The linearized internal force, else the model's nonlinear one.
        f_int : array_like, optional
            The internal force at ``u`` when already computed.

        Returns
        -------
        (n, dim) ndarray
            Reactions, 0 on the free DOFs.
        """
        flat = np.asarray(u, dtype=float).reshape(-1)
        reac = np.zeros(self.ndof)
        if rows is not None:
            reac[self.dofs] = rows @ flat - factor * self.f_ext[self.dofs]
        else:
            fi = self.internal_force(u, linear=linear) if f_int is None else np.ravel(f_int)
            reac[self.dofs] = -(fi[self.dofs] + factor * self.f_ext[self.dofs])
        return reac.reshape(self.n, self.dim)

    def prescribed_rows(self, K: sp.sparray) -> sp.csr_array:
        """Return K's prescribed rows (for :meth:`reactions`), taken before elimination.

        Parameters
        ----------
        K : sparse array of shape (ndof, ndof)
            The stiffness.

        Returns
        -------
        csr_array of shape (m, ndof)
            The rows of ``dofs`` (:func:`pdlin.constraints.matrix_rows`).
        """
        return matrix_rows(K, self.dofs)

    def prescribed_columns(self, K: sp.sparray) -> sp.sparray:
        """Return K with only its (block) columns holding prescribed DOFs, before elimination.

        The entries keep K's format, block size and order, so ``cols @ u_c`` for a ``u_c``
        zero on the free DOFs sums the same products in the same order as ``K @ u_c``
        (the dropped ones are ``x * 0``): :meth:`rhs` gives bitwise the right-hand side of
        :meth:`eliminate` for other prescribed values and loads on the same DOFs.

        Parameters
        ----------
        K : sparse array of shape (ndof, ndof)
            The stiffness (:meth:`assemble`); BSR or CSR keep only the needed columns,
            another format is copied whole.

        Returns
        -------
        sparse array of shape (ndof, ndof)
            The prescribed columns (a new array; K may be eliminated in place afterwards).
        """
        if isinstance(K, sp.bsr_array | sp.bsr_matrix):
            bfixed: np.ndarray = ~np.all(self.free.reshape(-1, K.blocksize[1]), axis=1)
        elif isinstance(K, sp.csr_array | sp.csr_matrix):
            bfixed = ~self.free
        else:
            return K.copy()
        keep = bfixed[K.indices]
        counts = np.zeros(keep.size + 1, dtype=K.indptr.dtype)
        np.cumsum(keep, out=counts[1:])
        parts = (K.data[keep], K.indices[keep], counts[K.indptr])
        if isinstance(K, sp.bsr_array | sp.bsr_matrix):
            return sp.bsr_array(parts, shape=K.shape, blocksize=K.blocksize)
        return sp.csr_array(parts, shape=K.shape)

    def rhs(self, cols: sp.sparray | spla.LinearOperator, factor: float = 1.0) -> np.ndarray:
        """Return the eliminated right-hand side from K's prescribed columns.

        Bitwise the ``b`` of :meth:`eliminate` (``f_ext - K_fc u_c`` on the free rows, 0 on
        the prescribed ones) without K itself: a load step of
        ``pdlin.static.solve_steps`` reuses the eliminated matrix of the first.

        Parameters
        ----------
        cols : sparse array or LinearOperator of shape (ndof, ndof)
            :meth:`prescribed_columns` of the stiffness, or the discretization's
            matrix-free operator (then bitwise the ``b`` of :meth:`matrix_free`).
        factor : float
            Load factor of the prescribed values and the external force.

        Returns
        -------
        (ndof,) ndarray
            The eliminated right-hand side.
        """
        uc = np.zeros(self.ndof)
        uc[self.dofs] = factor * self.values
        b = np.array(factor * self.f_ext - cols @ uc, dtype=float)
        b[self.dofs] = 0.0
        return b


def discretize(problem: StaticProblem) -> Discretization:
    """Build the discretization a problem is solved on: its cloud, or the mirrored cloud.

    Parameters
    ----------
    problem : StaticProblem
        Without symmetry planes its bonds are ``problem.get_bonds()``; with them they are
        found on the mirrored cloud (:func:`~pdlin.operators.symmetry_reduction`).

    Returns
    -------
    Discretization
        A :class:`PlainDiscretization` or a
        :class:`~pdlin.operators.symmetry.SymmetryReduction`.

    Raises
    ------
    ModelError
        When the discretization does not implement :class:`Discretization`.
    """
    model, cloud = problem.model, problem.cloud
    disc: Any
    if problem.symmetry:
        disc = symmetry_reduction(
            model, cloud, problem.symmetry, problem.horizon, problem.bond_options
        )
    else:
        bonds = problem.get_bonds()
        if bonds.family_size.all():
            disc = PlainDiscretization(model, cloud, bonds)
        else:  # points without bonds (find_bonds(allow_isolated=True)): held at rest
            disc = IsolatedPoints(model, cloud, bonds)
    if not isinstance(disc, Discretization):  # pragma: no cover - interface guard
        raise ModelError(f"{type(disc).__name__} does not implement Discretization")
    return disc


def constrain(
    problem: StaticProblem, disc: Any, *, checked: np.ndarray | None = None
) -> ConstrainedSystem:
    """Apply a problem's Dirichlet conditions and loads to a discretization.

    Resolves the Dirichlet conditions (plus the discretization's own, e.g. the symmetry
    planes'), builds the load vector and checks that no rigid motion stays free.

    Parameters
    ----------
    problem : StaticProblem
        Supplies ``dirichlet`` and ``loads``.
    disc : Discretization or PointDiscretization
        Supplies the extra conditions, the load vector and the rigid-motion check.
    checked : (m,) ndarray of int, optional
        Prescribed DOFs already checked on ``disc`` (another load step's): the
        rigid-motion check is skipped when the problem prescribes exactly these.

    Returns
    -------
    ConstrainedSystem

    Raises
    ------
    FloatingBodyError
        When the conditions leave rigid-body motions free.
    InputError
        When a load acts on prescribed DOFs only (a :class:`~pdlin.TotalForce` acting
        there in part warns, :class:`~pdlin.errors.AccuracyWarning`).
    """
    dofs, vals = resolve_dirichlet(disc.cloud, (*problem.dirichlet, *disc.dirichlet()))
    # a load on prescribed DOFs only would vanish into the support: refused here, where
    # every driver (solve, solve_nonlinear, solve_damage, the CLI, PETSc) passes
    f_ext = disc.load_vector(problem.loads, prescribed=dofs)
    if problem.thermal is not None:  # the eigenstrain load K u = f_ext + f_th
        if isinstance(disc, IsolatedPoints):
            f_ext = f_ext + disc.thermal_load(problem.thermal)
        else:
            f_ext = f_ext + thermal_load(disc.model, disc.cloud, disc.bonds, problem.thermal)
    if isinstance(disc, IsolatedPoints):  # u = 0 on points without bonds; loaded ones raise
        dofs, vals = hold_isolated(disc.cloud, disc.isolated, dofs, vals, f_ext)
        if checked is None:
            log.warning(
                "%d point(s) without bonds held at rest (u = 0), first index %d",
                disc.isolated.size, int(disc.isolated[0]),
            )  # fmt: skip
    if checked is None or not np.array_equal(dofs, checked):
        disc.check_constraints(dofs)
    paths = tuple(bc for bc in problem.dirichlet if isinstance(bc.value, TimePath))
    return ConstrainedSystem(disc, dofs, vals, np.asarray(f_ext, dtype=float), problem, paths)


def constrained_system(problem: StaticProblem) -> ConstrainedSystem:
    """Transform a :class:`~pdlin.StaticProblem` once into its constrained system.

    Finds the bonds (on the mirrored cloud with symmetry planes, :func:`discretize`),
    resolves the Dirichlet conditions (plus the planes' own), builds the load vector and
    checks that no rigid motion stays free (:func:`constrain`).

    Parameters
    ----------
    problem : StaticProblem
        The problem.

    Returns
    -------
    ConstrainedSystem

    Raises
    ------
    InputTypeError
        When ``problem`` is not a :class:`~pdlin.StaticProblem`.
    FloatingBodyError
        When the conditions leave rigid-body motions free.
    InputError
        When a load acts on prescribed DOFs only (a :class:`~pdlin.TotalForce` acting
        there in part warns, :class:`~pdlin.errors.AccuracyWarning`).
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    return constrain(problem, discretize(problem))


@dataclass(frozen=True, eq=False)
class PointDiscretization:
    """The point data of a discretization, without bonds: conditions, loads, rigid motions.

    A distributed driver (the PETSc backend) builds the constrained system's prescribed
    DOFs, values and load vector from it on every rank (:func:`point_system`) and finds
    the bonds of its own points only.  With symmetry planes it holds the mirrored cloud
    (point data), whose reduction supplies the planes' conditions and the loads' shares.

    Parameters
    ----------
    model : Model
        The problem's model.
    points : PointCloud
        The solved points (the modelled part with symmetry planes).
    bonds : Bonds, optional
        Precomputed bonds of the problem (their connectivity is checked); None treats the
        cloud as one connected piece.
    mirror : MirrorCloud, optional
        The mirrored cloud of a problem with symmetry planes.
    """

    model: Any
    points: PointCloud
    bonds: Bonds | None = None
    mirror: MirrorCloud | None = None

    @property
    def cloud(self) -> PointCloud:
        """The solved points."""
        return self.points

    def _reduction(self) -> SymmetryReduction:
        """Return the symmetry reduction without bonds (its conditions and loads need none)."""
        assert self.mirror is not None
        return SymmetryReduction(self.mirror, cast(Bonds, None), self.model)

    def dirichlet(self) -> list[Dirichlet]:
        """Return the symmetry planes' conditions (none without planes).

        Returns
        -------
        list of Dirichlet
            Zero normal displacement of the points lying on each plane.
        """
        return [] if self.mirror is None else self._reduction().dirichlet()

    def load_vector(
        self, loads: Sequence[Any], *, prescribed: np.ndarray | None = None
    ) -> np.ndarray:
        """Compute the external force ``(ndof,)`` as the full discretization does.

        Parameters
        ----------
        loads : sequence of BodyForce / TotalForce
            The problem's loads.
        prescribed : (m,) ndarray of int, optional
            Prescribed DOFs; a load acting on them only raises.

        Returns
        -------
        (ndof,) ndarray
            Nodal forces; with symmetry planes the points lying on a plane carry their share.
        """
        if self.mirror is None:
            return load_vector(self.points, loads, prescribed=prescribed)
        return self._reduction().load_vector(loads, prescribed=prescribed)

    def check_constraints(self, dofs: np.ndarray) -> None:
        """Raise when the prescribed DOFs leave a rigid motion free.

        Parameters
        ----------
        dofs : (m,) ndarray of int
            Prescribed DOFs.

        Raises
        ------
        FloatingBodyError
            When a rigid motion (one compatible with the symmetry planes) stays free.
        """
        if self.mirror is None:
            check_constraints(self.points, self.bonds, dofs)
            return
        modes, names = self._reduction().rigid_modes()
        if not names:
            return
        try:
            check_constraints(self.points, None, dofs, extra_modes=modes)
        except FloatingBodyError as exc:
            msg = re.sub(r"\bmode (\d+)\b", lambda mt: names[int(mt.group(1))], str(exc))
            planes = ", ".join(p.name for p in self.mirror.planes)
            raise FloatingBodyError(
                f"{msg}; the symmetry planes {planes} leave these rigid motions to "
                f"constrain: {', '.join(names)}"
            ) from exc


def mirror_reach(model: Any, cloud: PointCloud, horizon: Any, bond_options: Any) -> float:
    """Depth of the ghost layer of a symmetry reduction: coupling range times bond reach.

    Parameters
    ----------
    model : Model
        Its ``coupling_range`` (1 for bond-based, 2 for state-based models).
    cloud : PointCloud
        The modelled part.
    horizon : float or (n,) array_like, optional
        As in :func:`pdlin.find_bonds`.
    bond_options : mapping
        :func:`pdlin.find_bonds` keyword arguments (``ratio``, ``axes``).

    Returns
    -------
    float
        The ``reach`` :func:`~pdlin.operators.symmetry_reduction` mirrors with.
    """
    opts = dict(bond_options or {})
    hor = resolve_horizon(cloud, horizon, opts.get("ratio"))
    reach = float(hor.max())
    if opts.get("axes") is not None:
        reach = max(reach, float(np.max(np.asarray(opts["axes"], dtype=float))))
    return int(getattr(model, "coupling_range", 1)) * reach


def point_system(problem: StaticProblem) -> ConstrainedSystem:
    """Build a problem's constrained system without searching its bonds.

    The prescribed DOFs and values, the load vector and the free mask are those of
    :func:`constrained_system` (the same functions on the same points); the rigid-motion
    check treats the cloud as one connected piece unless the problem has precomputed
    bonds.  Its discretization is a :class:`PointDiscretization`: it has no operators, so
    a driver that uses it (the PETSc backend) assembles and eliminates its own rows.

    Parameters
    ----------
    problem : StaticProblem
        The problem.

    Returns
    -------
    ConstrainedSystem

    Raises
    ------
    InputTypeError
        When ``problem`` is not a :class:`~pdlin.StaticProblem`.
    FloatingBodyError
        When the conditions leave rigid-body motions free.
    InputError
        When a load acts on prescribed DOFs only.
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    mirror = None
    if problem.symmetry:
        reach = mirror_reach(problem.model, problem.cloud, problem.horizon, problem.bond_options)
        mirror = mirror_cloud(problem.cloud, problem.symmetry, reach)
    disc = PointDiscretization(problem.model, problem.cloud, problem.bonds, mirror)
    return constrain(problem, disc)


@dataclass
class StaticResult:
    """Solution of a :class:`~pdlin.StaticProblem` (the result of :func:`pdlin.solve`).

    Attributes
    ----------
    problem : StaticProblem
        The problem solved.
    bonds : Bonds
        Its bonds (between real points with symmetry planes).
    u : (n, dim) ndarray
        Displacements.
    converged : bool
        True (a missed tolerance raises :class:`~pdlin.errors.ConvergenceError` instead).
    n_iter : int
        Iterations of the linear solver (1 for 'direct').
    residuals : list of float
        Relative residual history of the linear solver.
    relative_residual : float
        True relative residual ``||b - A x|| / ||b||`` of the eliminated system.
    timings : dict
        Seconds spent in 'bonds', 'assembly', 'setup', 'solve' and 'total'.
    reactions : (n, dim) ndarray
        Nodal reaction forces (non-zero only on prescribed DOFs).
    prescribed_dofs : (m,) ndarray of int
        The prescribed DOFs (Dirichlet conditions and symmetry planes).
    info : dict
        Solver details (name, AMG levels and complexity, fill-in, ...).
    stiffness : sparse array or None
        The unconstrained K with ``keep_stiffness=True``.
    system : ConstrainedSystem or None
        The constrained system the driver solved (its discretization maps fields back).
    """

    problem: StaticProblem
    bonds: Bonds
    u: np.ndarray
    converged: bool
    n_iter: int
    residuals: list[float]
    relative_residual: float
    timings: dict[str, float]
    reactions: np.ndarray
    prescribed_dofs: np.ndarray
    info: dict[str, Any]
    stiffness: sp.sparray | None = None
    #: the constrained system the driver solved (its discretization maps fields back)
    system: ConstrainedSystem | None = None

    @property
    def symmetry(self) -> SymmetryReduction | None:
        """Mirrored cloud, bonds and operators when the problem has symmetry planes.

        ``bonds`` then holds the real-real bonds only.
        """
        disc = None if self.system is None else self.system.disc
        return disc if isinstance(disc, SymmetryReduction) else None

    @property
    def _disc(self) -> Any:
        if self.system is not None:
            return self.system.disc
        return PlainDiscretization(self.problem.model, self.problem.cloud, self.bonds)

    def deformation_gradient(self) -> np.ndarray:
        """Compute the nonlocal deformation gradient per point.

        Returns
        -------
        (n, dim, dim) ndarray
            ``F`` at each point (with ghost bonds on a symmetry plane's side).
        """
        return np.asarray(self._disc.deformation_gradient(self.u))

    def strain(self) -> np.ndarray:
        """Compute the small strain per point.

        Returns
        -------
        (n, dim, dim) ndarray
            The symmetric part of ``F - I`` (less ``α ΔT I`` with ``problem.thermal``).
        """
        return self._mechanical(small_strain(self.deformation_gradient()))

    def _mechanical(self, strain: np.ndarray) -> np.ndarray:
        """Return the strain less the free thermal strain of ``problem.thermal`` (if any)."""
        th = self.problem.thermal
        if th is None:
            return strain
        return mechanical_strain(strain, self.problem.model, self.problem.cloud, th)

    def stress(self) -> np.ndarray:
        """Compute the model's stress per point.

        Returns
        -------
        (n, dim, dim) ndarray
            Stress (virial for bond-based models); with ``problem.thermal`` the stress of
            the mechanical strain (the free thermal strain's stress removed).
        """
        s = np.asarray(self._disc.stress(self.u))
        th = self.problem.thermal
        if th is not None:
            disc = self._disc
            if isinstance(disc, IsolatedPoints):
                s = s - disc.thermal_stress(th)
            else:
                s = s - thermal_stress(disc.model, disc.cloud, disc.bonds, th)
        return s

    def reaction(self, where: Any) -> np.ndarray:
        """Sum the reaction forces over a point set.

        Parameters
        ----------
        where : str or index array or mask
            Point set name (e.g. ``'x-'``), indices or a boolean mask.

        Returns
        -------
        (dim,) ndarray
            Total reaction force on those points.
        """
        idx = self.problem.cloud.select(where)
        return self.reactions[idx].sum(axis=0)

    def fields(self) -> dict[str, np.ndarray]:
        """Collect all point fields as numpy arrays (for output).

        Returns
        -------
        dict of str to ndarray
            ``displacement``, ``reaction``, ``family_size``, ``volume``, ``material``,
            ``deformation_gradient`` and ``strain`` (flattened ``dim*dim``; omitted with a
            logged warning when the shape tensor is singular) and ``stress`` when the model
            defines one; one row per point.
        """
        out: dict[str, np.ndarray] = {
            "displacement": self.u,
            "reaction": self.reactions,
            "family_size": np.asarray(self._disc.family_size, dtype=float),
            "volume": np.asarray(self.problem.cloud.volumes),
            "material": np.asarray(self.problem.cloud.material, dtype=float),
        }
        try:
            F = self.deformation_gradient()
            out["deformation_gradient"] = F.reshape(F.shape[0], -1)
            out["strain"] = self._mechanical(small_strain(F)).reshape(F.shape[0], -1)
        except InputError as exc:
            log.warning("strain not written: %s", exc)
        if hasattr(self.problem.model, "stress"):
            s = self.stress()
            out["stress"] = s.reshape(s.shape[0], -1)
        return out

    def _table(self) -> list[tuple[str, Any]]:
        u = self.u
        return [
            ("model", repr(self.problem.model)),
            ("points", int(u.shape[0])),
            ("dim", int(u.shape[1])),
            ("bonds", int(self.bonds.n_bonds)),
            ("DOFs", int(u.size)),
            ("prescribed DOFs", int(np.asarray(self.prescribed_dofs).size)),
            ("solver", self.info.get("solver")),
            ("converged", bool(self.converged)),
            ("iterations", int(self.n_iter)),
            ("relative residual", float(self.relative_residual)),
            ("max |u|", float(np.abs(u).max()) if u.size else 0.0),
            ("time (s)", float(self.timings.get("total", np.nan))),
        ]

    def __repr__(self) -> str:
        """Sizes, solver, iterations and residual (no arrays, no memory address).

        Examples
        --------
        >>> import pdlin
        >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), pdlin.grid((20,), spacing=0.05),
        ...     horizon=0.1, dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        ...     loads=[pdlin.TotalForce("x+", [1e-3])])
        >>> pdlin.solve(prob, solver="direct")  # doctest: +ELLIPSIS
        StaticResult(points=20, dim=1, bonds=74, DOFs=20, solver='direct', converged=True,
            iterations=1, ...)
        """
        names = {"relative residual": "residual", "max |u|": "max_abs_u", "time (s)": "seconds"}
        items = {
            names.get(k, k): v for k, v in self._table() if k not in ("model", "prescribed DOFs")
        }
        return compact_repr("StaticResult", items)

    def _repr_html_(self) -> str:
        """Render the summary as an HTML table (Jupyter)."""
        return html_table("StaticResult", self._table())

    def summary(self) -> dict[str, Any]:
        """Summarize the run as plain data (used by the CLI).

        Returns
        -------
        dict
            Sizes, solver, iterations, residual, ``max_abs_u`` per component and timings.
        """
        u = self.u
        return {
            "points": int(u.shape[0]),
            "dim": int(u.shape[1]),
            "bonds": int(self.bonds.n_bonds),
            "solver": self.info.get("solver"),
            **(
                {"direct_backend": self.info["direct_backend"]}
                if "direct_backend" in self.info
                else {}
            ),
            "iterations": int(self.n_iter),
            "relative_residual": float(self.relative_residual),
            "max_abs_u": [float(v) for v in np.abs(u).max(axis=0)],
            "timings": {k: round(v, 4) for k, v in self.timings.items()},
        }
