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
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .constraints import (
    check_constraints,
    eliminate_dirichlet,
    load_vector,
    matrix_rows,
    resolve_dirichlet,
)
from .errors import InputError, InputTypeError, ModelError
from .fields import deformation_gradient
from .geometry.bonds import Bonds
from .geometry.cloud import PointCloud
from .models.base import Model
from .operators.assembly import assemble_stiffness
from .operators.bc import Dirichlet, TimePath
from .operators.rigid import rigid_body_modes
from .operators.symmetry import symmetry_reduction

__all__ = ["Discretization", "PlainDiscretization", "ConstrainedSystem", "constrained_system"]


@runtime_checkable
class Discretization(Protocol):
    """A model's operators on the points a driver solves for.

    Vectors are ``(n, dim)`` or flat ``(n*dim,)`` on :attr:`cloud`.
    """

    model: Any

    @property
    def cloud(self) -> PointCloud: ...

    @property
    def real_bonds(self) -> Bonds: ...

    @property
    def family_size(self) -> np.ndarray: ...

    def stiffness(self) -> sp.sparray: ...

    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray: ...

    def load_vector(
        self, loads: Sequence[Any], *, prescribed: np.ndarray | None = None
    ) -> np.ndarray: ...

    def dirichlet(self) -> list[Dirichlet]: ...

    def check_constraints(self, dofs: np.ndarray) -> None: ...

    def deformation_gradient(self, u: Any) -> np.ndarray: ...

    def stress(self, u: Any) -> np.ndarray: ...

    def initial_state(self) -> dict[str, np.ndarray]: ...

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any: ...


@dataclass(frozen=True, eq=False)
class PlainDiscretization:
    """The model on the cloud itself (no reduction).

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
        return self.points

    @property
    def real_bonds(self) -> Bonds:
        return self.bonds

    @property
    def family_size(self) -> np.ndarray:
        return self.bonds.family_size

    def stiffness(self) -> sp.sparray:
        """Assembled stiffness of the model (BSR with blocksize dim)."""
        return assemble_stiffness(self.model, self.points, self.bonds)

    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray:
        return np.asarray(self.model.internal_force(self.points, self.bonds, u, linear=linear))

    def load_vector(
        self, loads: Sequence[Any], *, prescribed: np.ndarray | None = None
    ) -> np.ndarray:
        """External force ``(ndof,)``; loads acting on ``prescribed`` DOFs only raise."""
        return load_vector(self.points, loads, prescribed=prescribed)

    def dirichlet(self) -> list[Dirichlet]:
        """No extra conditions (a reduction adds its plane conditions here)."""
        return []

    def check_constraints(self, dofs: np.ndarray) -> None:
        check_constraints(self.points, self.bonds, dofs)

    def deformation_gradient(self, u: Any) -> np.ndarray:
        return deformation_gradient(self.points, self.bonds, u)

    def stress(self, u: Any) -> np.ndarray:
        if not hasattr(self.model, "stress"):
            raise InputError(f"model {type(self.model).__name__} does not define a stress")
        return np.asarray(self.model.stress(self.points, self.bonds, u))

    def initial_state(self) -> dict[str, np.ndarray]:
        return dict(self.model.initial_state(self.points, self.bonds))

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any:
        return self.model.respond(self.points, self.bonds, u, state, tangent=tangent)

    # -- matrix-free path (only the plain discretization has it) ----------
    def operator(self) -> spla.LinearOperator:
        return self.model.operator(self.points, self.bonds)

    def surrogate_stiffness(self) -> sp.sparray:
        return self.model.surrogate_stiffness(self.points, self.bonds)

    def estimate_nnz_blocks(self) -> int:
        return int(self.model.estimate_nnz_blocks(self.points, self.bonds))

    def with_model(self, model: Any) -> PlainDiscretization:
        """The same points and bonds under another model (e.g. a preconditioner's)."""
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

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((10,), spacing=0.1)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.2,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0)], loads=[pdlin.TotalForce("x+", [1e-3])])
    >>> sys = pdlin.constrained_system(prob)
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
    #: Dirichlet conditions whose value is a :class:`~pdlin.TimePath` (re-evaluated per time)
    paths: tuple[Dirichlet, ...] = ()
    _free: np.ndarray | None = field(default=None, repr=False)

    # -- sizes and masks ----------------------------------------------------
    @property
    def cloud(self) -> PointCloud:
        """The solved points (the real half / quarter with symmetry planes)."""
        return self.disc.cloud

    @property
    def model(self) -> Any:
        return self.disc.model

    @property
    def dim(self) -> int:
        return self.cloud.dim

    @property
    def n(self) -> int:
        return self.cloud.n

    @property
    def ndof(self) -> int:
        return self.cloud.n * self.cloud.dim

    @property
    def symmetric(self) -> bool:
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
        """Rigid-body modes with the prescribed rows zeroed (AMG near-null space)."""
        B = rigid_body_modes(self.cloud)
        B[self.dofs] = 0.0
        return B

    def prescribed(self, factor: float = 1.0) -> np.ndarray:
        """Full displacement vector ``(ndof,)`` holding ``factor`` x the prescribed values."""
        u = np.zeros(self.ndof)
        u[self.dofs] = factor * self.values
        return u

    def values_at(self, t: float, factor: float) -> np.ndarray:
        """Prescribed values at time ``t`` of a load path ``(m,)``.

        Plain values are scaled by the load ``factor``; :class:`~pdlin.TimePath`
        values (e.g. :meth:`~pdlin.Dirichlet.velocity_gradient`) are evaluated
        at ``t`` instead.
        """
        vals = factor * self.values
        if self.paths:
            pd, pv = resolve_dirichlet(self.cloud, self.paths, t=t)
            vals[np.searchsorted(self.dofs, pd)] = pv
        return vals

    # -- operators ----------------------------------------------------------
    def estimate_nnz_blocks(self) -> int:
        if hasattr(self.disc, "estimate_nnz_blocks"):
            return int(self.disc.estimate_nnz_blocks())
        return int(self.model.estimate_nnz_blocks(self.cloud, self.disc.real_bonds))

    def assemble(self) -> sp.sparray:
        """The (unconstrained) stiffness on the solved DOFs."""
        return self.disc.stiffness()

    def eliminate(
        self, K: sp.sparray, *, inplace: bool = False, factor: float = 1.0
    ) -> tuple[sp.sparray, np.ndarray]:
        """Eliminated system ``(A, b)`` for the unknown ``x`` with ``x[dofs] = 0``.

        ``A`` keeps K's size and block structure (prescribed rows and
        columns become ``s I``); ``b`` holds ``f_ext - K_fc u_c`` on the free
        rows and 0 on the prescribed ones, so the relative residual of a
        solve is that of the free equations.  :meth:`expand` writes the
        prescribed values back.
        """
        A, b = eliminate_dirichlet(
            K, factor * self.f_ext, self.dofs, factor * self.values, inplace=inplace
        )
        b = np.array(b, dtype=float)
        b[self.dofs] = 0.0
        return A, b

    def eliminate_matrix(self, K: sp.sparray) -> sp.sparray:
        """``K`` with the prescribed rows and columns replaced by ``s I`` (no load)."""
        A, _ = eliminate_dirichlet(
            K, np.zeros(self.ndof), self.dofs, np.zeros(self.dofs.size), inplace=True
        )
        return A

    def matrix_free(
        self, factor: float = 1.0
    ) -> tuple[spla.LinearOperator, np.ndarray, sp.sparray]:
        """Eliminated matrix-free system and the eliminated surrogate preconditioner matrix.

        Prescribed rows and columns become ``s * I`` in both, with ``s`` the
        mean free diagonal of the surrogate, as in :meth:`eliminate`; ``b``
        is 0 on the prescribed rows.
        """
        if not self.matrix_free_capable:
            raise InputError(
                "operator='matrix-free' does not support symmetry planes yet; "
                "use operator='assembled'"
            )
        ndof = self.ndof
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
        """Eliminated assembled stiffness of another model on the same points and bonds."""
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
        """Displacement ``(n, dim)`` from a solution ``x`` of the eliminated system."""
        u = np.array(x, dtype=float).reshape(-1)
        if u.shape != (self.ndof,):
            raise InputError(f"x must have {self.ndof} entries, got {u.shape}")
        u[self.dofs] = factor * self.values
        return u.reshape(self.n, self.dim)

    def initial_state(self) -> dict[str, np.ndarray]:
        """The model's committed state before the first load step."""
        return dict(self.disc.initial_state())

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any:
        """The model's ``Response`` at ``u`` (flat or ``(n, dim)``).

        A pure function of ``(u, state)``: ``state`` is the committed state
        of the last converged load step and is never modified.
        """
        uu = np.asarray(u, dtype=float).reshape(self.n, self.dim)
        return self.disc.respond(uu, state, tangent=tangent)

    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray:
        """``f_int(u)`` flat ``(ndof,)``."""
        return np.asarray(self.disc.internal_force(u, linear=linear), dtype=float).reshape(-1)

    def residual(
        self, u: Any, *, factor: float = 1.0, linear: bool = True, f_int: Any = None
    ) -> np.ndarray:
        """Out-of-balance force ``f_int(u) + factor f_ext`` on the free DOFs (0 elsewhere)."""
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
        """Nodal reactions ``(n, dim)``: ``-(f_int + f_ext)`` on the prescribed DOFs.

        ``rows`` are K's prescribed rows (``pdlin.operators.bc.matrix_rows``,
        kept before an in-place elimination), which give ``f_int = -K u``
        there without a full internal-force pass.
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
        """K's prescribed rows (for :meth:`reactions`), taken before elimination."""
        return matrix_rows(K, self.dofs)


def constrained_system(problem: Any) -> ConstrainedSystem:
    """Transform a :class:`~pdlin.StaticProblem` once into its constrained system.

    Finds the bonds (on the mirrored cloud with symmetry planes), resolves
    the Dirichlet conditions (plus the planes' own), builds the load
    vector and checks that no rigid motion stays free.

    Raises
    ------
    FloatingBodyError
        When the conditions leave rigid-body motions free.
    InputError
        When a load acts on prescribed DOFs only (a :class:`~pdlin.TotalForce` acting
        there in part warns, :class:`~pdlin.errors.AccuracyWarning`).
    """
    from .problem import StaticProblem

    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    model, cloud = problem.model, problem.cloud
    disc: Any
    if problem.symmetry:
        disc = symmetry_reduction(
            model, cloud, problem.symmetry, problem.horizon, problem.bond_options
        )
    else:
        disc = PlainDiscretization(model, cloud, problem.get_bonds())
    if not isinstance(disc, Discretization):  # pragma: no cover - interface guard
        raise ModelError(f"{type(disc).__name__} does not implement Discretization")
    dofs, vals = resolve_dirichlet(cloud, (*problem.dirichlet, *disc.dirichlet()))
    # a load on prescribed DOFs only would vanish into the support: refused here, where
    # every driver (solve, solve_nonlinear, solve_damage, the CLI) passes
    f_ext = disc.load_vector(problem.loads, prescribed=dofs)
    disc.check_constraints(dofs)
    paths = tuple(bc for bc in problem.dirichlet if isinstance(bc.value, TimePath))
    return ConstrainedSystem(disc, dofs, vals, np.asarray(f_ext, dtype=float), problem, paths)
