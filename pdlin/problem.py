"""Static problems and the ``solve`` verb."""

from __future__ import annotations

import inspect
import logging
import math
import os
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import InitVar, dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from ._repr import Raw as _Raw
from ._repr import compact_repr, html_table
from ._validation import as_float_array, integer, tolerance
from .errors import AccuracyWarning, InputError, InputTypeError, ShapeError, SlowRunWarning
from .fields import small_strain
from .geometry.bonds import Bonds, find_bonds
from .geometry.cloud import PointCloud
from .models.base import Model
from .operators.assembly import estimate_bond_operator_bytes
from .operators.bc import (
    BodyForce,
    Dirichlet,
    TotalForce,
)
from .operators.symmetry import SymmetryPlane, SymmetryReduction
from .resources import (
    ASSEMBLY_TRANSIENT,
    RunEstimate,
    check_memory,
    estimate_pair_count,
    estimate_static_run,
    format_bytes,
)
from .solvers.linear import SOLVERS, LinearSolveInfo, _safe_norm, solve_linear
from .system import ConstrainedSystem, PlainDiscretization, constrained_system

__all__ = ["StaticProblem", "StaticResult", "solve"]

log = logging.getLogger(__name__)


#: keyword arguments of find_bonds that ``StaticProblem.bond_options`` may hold
_BOND_OPTIONS = set(inspect.signature(find_bonds).parameters) - {"cloud", "horizon"}


@dataclass(frozen=True, eq=False)
class StaticProblem:
    """A linear static peridynamic problem: data only.

    Parameters
    ----------
    model : Model
        Any pdlin model (:class:`pdlin.BondBased`, ...).
    cloud : PointCloud
    bonds : Bonds, optional
        Precomputed bonds; otherwise built by :func:`pdlin.find_bonds` with
        ``horizon`` and ``bond_options`` at solve time.
    horizon : float or (n,) array, optional
        Horizon used when ``bonds`` is None (default ``cloud.horizon``).
    dirichlet : sequence of Dirichlet
    loads : sequence of BodyForce / TotalForce
    bond_options : mapping
        Extra keyword arguments of :func:`pdlin.find_bonds`.
    symmetry : sequence of SymmetryPlane
        Mirror planes: ``cloud`` is the half / quarter / eighth of a
        symmetric body, and points near a plane bond to mirror images of
        their neighbors (see :class:`~pdlin.operators.SymmetryReduction`).  Needs
        ``horizon`` / ``bond_options`` rather than precomputed ``bonds``.
    ratio : float, optional
        Horizon as a multiple of the spacing, as :func:`pdlin.find_bonds` takes it
        (``delta_i = ratio * h_i``): the bonds are ``find_bonds(cloud, ratio=ratio,
        **bond_options)``.  Stored as ``bond_options["ratio"]``; refused together with
        ``horizon``, ``bonds`` or ``bond_options["ratio"]``.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((20,), spacing=0.05)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.1,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0)], loads=[pdlin.TotalForce("x+", [1e-3])])
    >>> res = pdlin.solve(prob, solver="direct")
    >>> res.u.shape, res.relative_residual < 1e-10
    ((20, 1), True)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, ratio=2.015)
    >>> prob.bond_options, int(prob.get_bonds().family_size.max())
    ({'ratio': 2.015}, 4)
    """

    model: Model
    cloud: PointCloud
    bonds: Bonds | None = None
    horizon: Any = None
    dirichlet: Sequence[Dirichlet] = ()
    loads: Sequence[BodyForce | TotalForce] = ()
    bond_options: Mapping[str, Any] = field(default_factory=dict)
    symmetry: Sequence[SymmetryPlane] = ()
    #: init-only: merged into ``bond_options`` (so ``dataclasses.replace`` keeps it)
    ratio: InitVar[float | None] = None

    def __post_init__(self, ratio: float | None = None) -> None:
        if not hasattr(self.model, "stiffness") or not hasattr(self.model, "internal_force"):
            raise InputTypeError(f"model must be a pdlin model, got {type(self.model).__name__}")
        if not isinstance(self.cloud, PointCloud):
            raise InputTypeError(f"cloud must be a PointCloud, got {type(self.cloud).__name__}")
        if self.bonds is not None and not isinstance(self.bonds, Bonds):
            raise InputTypeError(f"bonds must be pdlin Bonds, got {type(self.bonds).__name__}")
        if isinstance(self.dirichlet, Dirichlet):
            object.__setattr__(self, "dirichlet", (self.dirichlet,))
        if isinstance(self.loads, BodyForce | TotalForce):
            object.__setattr__(self, "loads", (self.loads,))
        object.__setattr__(self, "dirichlet", tuple(self.dirichlet))
        object.__setattr__(self, "loads", tuple(self.loads))
        for k, bc in enumerate(self.dirichlet):
            if not isinstance(bc, Dirichlet):
                raise InputTypeError(
                    f"dirichlet[{k}] must be a pdlin Dirichlet, got {type(bc).__name__}"
                )
        for k, ld in enumerate(self.loads):
            if not isinstance(ld, BodyForce | TotalForce):
                raise InputTypeError(
                    f"loads[{k}] must be a BodyForce or TotalForce, got {type(ld).__name__}"
                )
        if self.bonds is not None and self.bonds.n_points != self.cloud.n:
            raise ShapeError(
                f"bonds must belong to the cloud ({self.cloud.n} points), got bonds over "
                f"{self.bonds.n_points} points"
            )
        if not isinstance(self.bond_options, Mapping):
            raise InputTypeError(
                f"bond_options must be a mapping, got {type(self.bond_options).__name__}"
            )
        if ratio is not None:
            self._merge_ratio(ratio)
        unknown = sorted(set(self.bond_options) - _BOND_OPTIONS)
        if unknown:
            raise InputError(
                f"bond_options has unknown key {unknown[0]!r}; allowed: {sorted(_BOND_OPTIONS)}"
            )
        if self.horizon is not None:
            h = as_float_array(self.horizon, "horizon")
            if h.size and np.any(h <= 0):
                raise InputError(f"horizon must be > 0, got min {float(h.min())}")
        sym = (self.symmetry,) if isinstance(self.symmetry, SymmetryPlane) else tuple(self.symmetry)
        for k, p in enumerate(sym):
            if not isinstance(p, SymmetryPlane):
                raise InputTypeError(
                    f"symmetry[{k}] must be a SymmetryPlane, got {type(p).__name__}"
                )
        if sym and self.bonds is not None:
            raise InputError(
                "bonds must be None with symmetry planes (they are found on the mirrored cloud); "
                "pass horizon and bond_options instead, got precomputed Bonds"
            )
        object.__setattr__(self, "symmetry", sym)

    def _merge_ratio(self, ratio: Any) -> None:
        """``ratio=`` as ``bond_options["ratio"]``; conflicting arguments refused by name."""
        if isinstance(ratio, bool) or not isinstance(ratio, int | float | np.number):
            raise InputError(f"ratio must be a positive number, got {ratio!r}")
        r = float(ratio)
        if not np.isfinite(r) or r <= 0.0:
            raise InputError(f"ratio must be a positive finite number, got {r}")
        if self.horizon is not None:
            raise InputError(
                f"ratio and horizon: give one of them, got ratio={r} and horizon={self.horizon}"
            )
        if self.bonds is not None:
            raise InputError(
                f"ratio and bonds: give one of them (ratio builds the bonds), got ratio={r} "
                "and precomputed Bonds"
            )
        if "ratio" in self.bond_options:
            raise InputError(
                f"ratio and bond_options['ratio']: give one of them, got ratio={r} and "
                f"bond_options['ratio']={self.bond_options['ratio']}"
            )
        object.__setattr__(self, "bond_options", {**self.bond_options, "ratio": r})

    def _repr_items(self) -> dict[str, Any]:
        h = None if self.horizon is None else np.asarray(self.horizon, dtype=float)
        return {
            "model": _Raw(repr(self.model)),
            "points": self.cloud.n,
            "dim": self.cloud.dim,
            "DOFs": self.cloud.n * self.cloud.dim,
            "bonds": None if self.bonds is None else self.bonds.n_bonds,
            "horizon": h if h is None or h.ndim == 0 or h.size > 1 else h.reshape(()),
            **{k: v for k, v in self.bond_options.items()},
            "dirichlet": len(self.dirichlet),
            "loads": len(self.loads),
            "symmetry": len(self.symmetry) or None,
        }

    def __repr__(self) -> str:
        """Model, sizes and conditions counts (no arrays, no memory address).

        Examples
        --------
        >>> import pdlin
        >>> pdlin.StaticProblem(pdlin.BondBased(E=1.0), pdlin.grid((20,), spacing=0.05),
        ...     horizon=0.1, dirichlet=[pdlin.Dirichlet("x-", 0.0)])
        StaticProblem(model=BondBased(E=1, plane='stress'), points=20, dim=1, DOFs=20,
            horizon=0.1, dirichlet=1, loads=0)
        """
        return compact_repr("StaticProblem", self._repr_items())

    def get_bonds(self) -> Bonds:
        """The problem's bonds (built on demand when not given)."""
        if self.bonds is not None:
            return self.bonds
        return find_bonds(self.cloud, self.horizon, **dict(self.bond_options))


@dataclass
class StaticResult:
    """Solution of a :class:`StaticProblem`.

    Attributes
    ----------
    u : (n, dim) ndarray
        Displacements.
    converged : bool
    n_iter : int
    residuals : list of float
        Relative residual history of the linear solver.
    relative_residual : float
        True relative residual ``||b - A x|| / ||b||`` of the eliminated system.
    timings : dict
        Seconds spent in 'bonds', 'assembly', 'setup', 'solve' and 'total'.
    reactions : (n, dim) ndarray
        Nodal reaction forces (non-zero only on prescribed DOFs).
    info : dict
        Solver details (name, AMG levels and complexity, fill-in, ...).
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
        """Nonlocal deformation gradient per point ``(n, dim, dim)``."""
        return np.asarray(self._disc.deformation_gradient(self.u))

    def strain(self) -> np.ndarray:
        """Small strain per point ``(n, dim, dim)``."""
        return small_strain(self.deformation_gradient())

    def stress(self) -> np.ndarray:
        """Model stress per point ``(n, dim, dim)`` (virial for bond-based models)."""
        return np.asarray(self._disc.stress(self.u))

    def reaction(self, where: Any) -> np.ndarray:
        """Total reaction force on a point set ``(dim,)``."""
        idx = self.problem.cloud.select(where)
        return self.reactions[idx].sum(axis=0)

    def fields(self) -> dict[str, np.ndarray]:
        """All point fields as numpy arrays (for output)."""
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
            out["strain"] = small_strain(F).reshape(F.shape[0], -1)
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
        """The summary as an HTML table (Jupyter)."""
        return html_table("StaticResult", self._table())

    def summary(self) -> dict[str, Any]:
        """Short plain-data summary (used by the CLI)."""
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


def solve(
    problem: StaticProblem,
    solver: str = "auto",
    *,
    rtol: float = 1e-8,
    maxiter: int | None = None,
    amg_options: Mapping[str, Any] | None = None,
    keep_stiffness: bool = False,
    progress: Callable[[str], None] | None = None,
    operator: str = "auto",
    preconditioner: Model | None = None,
    backend: str = "scipy",
    petsc_options: Mapping[str, Any] | None = None,
    direct_backend: str = "auto",
) -> StaticResult:
    """Assemble, constrain and solve a static problem; verify the residual.

    Parameters
    ----------
    problem : StaticProblem
    solver : str
        'auto' (direct up to 5,000 DOFs, then AMG-CG), 'direct', 'amg-cg',
        'cg', 'jacobi-cg', 'amg-gmres', 'ilu-gmres', 'gmres'.
    rtol : float
        Relative residual tolerance of iterative solvers, in ``(0, 1)``.
    maxiter : int, optional
        Iteration limit of iterative solvers (an integer >= 1).
    amg_options : mapping, optional
        Overrides of :data:`pdlin.solvers.AMG_DEFAULTS`.
    keep_stiffness : bool
        Keep the (unconstrained) stiffness matrix on the result.
    progress : callable, optional
        Called with a message at the start of each stage.
    operator : {'assembled', 'matrix-free', 'auto'}
        'assembled' builds the sparse K; 'matrix-free' applies K through the
        model's factored operator (``model.operator``) and builds the
        preconditioner ('amg-cg', 'jacobi-cg', 'amg-gmres', ...) from the
        model's assembled one-hop ``surrogate_stiffness``; 'auto' picks
        matrix-free for models coupling two horizons in 3D (where the
        assembled K has ~2,500 nonzeros per row and assembly dominates) or
        when the assembled K would exceed 40 % of the machine's memory.
        ``result.info['operator']`` and ``['operator_reason']`` say which
        path ran and why.
    preconditioner : Model, optional
        Build the preconditioner ('amg-cg', 'amg-gmres', 'ilu-gmres',
        'jacobi-cg') from the assembled stiffness of this model on the same
        cloud, bonds and Dirichlet conditions instead of from the operator
        being solved (or its surrogate).  Typical use: the nonsymmetric
        force-state linearization ``K_p`` of :class:`~pdlin.XOSB` /
        :class:`~pdlin.LPS` (``linearization='paper'``) solved by GMRES with
        the AMG of the symmetric energy-consistent ``K_E`` (spec 002 §11 B8).
        ``result.info['preconditioner']`` names the model used.
    backend : {'scipy', 'petsc'}
        'petsc' assembles and solves on PETSc through petsc4py, distributed
        over the MPI ranks when run under ``mpiexec -n P``
        (``pdlin.backends.petsc.solve_petsc``, ``docs/petsc.md``);
        ``operator`` and ``preconditioner`` are scipy-only.
    petsc_options : mapping, optional
        PETSc options for ``backend='petsc'`` (``{"ksp_monitor": None}``).
    direct_backend : {'auto', 'superlu', 'cholmod', 'pardiso', 'mumps'}
        Factorization of ``solver='direct'`` (and of ``'auto'`` on small
        problems): ``'auto'`` takes CHOLMOD's supernodal Cholesky for
        symmetric K, PARDISO, then SuperLU, whichever is installed
        (``pip install "pdlin[direct]"``, ``docs/large_problems.md``).
        ``result.info['direct_backend']`` names the one that ran.

    Returns
    -------
    StaticResult

    Raises
    ------
    InputError
        When ``solver``, ``rtol``, ``maxiter`` or ``amg_options`` are out of range, or the
        problem's data (horizon, conditions, loads) are invalid.
    FloatingBodyError
        When the conditions leave rigid-body motions free.
    ConvergenceError
        When the linear solver misses its tolerance.
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    if solver not in SOLVERS:
        raise InputError(f"solver must be one of {SOLVERS}, got {solver!r}")
    from .backends import BACKENDS

    if backend not in BACKENDS:
        raise InputError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if petsc_options is not None and backend != "petsc":
        raise InputError(f"petsc_options needs backend='petsc', got backend={backend!r}")
    if backend == "petsc":
        if (
            operator not in ("auto", "assembled")
            or preconditioner is not None
            or keep_stiffness
            or amg_options is not None
        ):
            raise InputError(
                "backend='petsc' assembles its own distributed K: operator, preconditioner, "
                "amg_options and keep_stiffness are scipy-only (PETSc's GAMG takes "
                f"petsc_options), got operator={operator!r}, preconditioner={preconditioner!r}, "
                f"amg_options={amg_options!r}, keep_stiffness={keep_stiffness!r}"
            )
        from .backends.petsc import solve_petsc

        return solve_petsc(
            problem, solver, rtol=rtol, maxiter=maxiter, petsc_options=petsc_options,
            progress=progress,
        )  # fmt: skip
    rtol = tolerance(rtol, "rtol")
    if maxiter is not None:
        maxiter = integer(maxiter, "maxiter", minimum=1)
    if amg_options is not None and not isinstance(amg_options, Mapping):
        raise InputTypeError(
            f"amg_options must be a mapping of pyamg keyword arguments, got "
            f"{type(amg_options).__name__}"
        )
    say = progress or (lambda msg: None)
    timings: dict[str, float] = {}
    t_start = time.perf_counter()
    model = problem.model

    plan = plan_memory(
        problem, solver, operator=operator, keep_stiffness=keep_stiffness,
        direct_backend=direct_backend,
    )  # fmt: skip
    say(plan.summary())
    check_memory("this run", plan.need, lambda: memory_hints(plan))
    slow = plan.slow_warning()
    if slow is not None:
        say(f"warning: {slow}")
        warnings.warn(slow, SlowRunWarning, stacklevel=2)
    say("bonds")
    t0 = time.perf_counter()
    system = constrained_system(problem)
    timings["bonds"] = time.perf_counter() - t0
    cloud, d = system.cloud, system.dim

    nblocks = system.estimate_nnz_blocks()
    est = estimate_bond_operator_bytes(cloud.n, nblocks, d)
    path, reason = _choose_operator(
        operator, model, cloud, solver, est, not system.matrix_free_capable, keep_stiffness,
        nblocks=nblocks,
    )  # fmt: skip
    K: Any = None
    K_rows = None
    precond = None
    if path == "assembled":
        ta = ASSEMBLY_TRANSIENT[2 if getattr(model, "coupling_range", 1) >= 2 else 1]
        check_memory("assembly of K", est * (1 + ta), lambda: memory_hints(plan))
        say(f"assembly (~{est / 1e9:.2f} GB for {nblocks * d * d:,} nonzeros)")
        log.info("assembling K: %d blocks, ~%.3g GB", nblocks, est / 1e9)
        t0 = time.perf_counter()
        K = system.assemble()
        timings["assembly"] = time.perf_counter() - t0
        # the prescribed rows, kept for the reactions (elimination overwrites them)
        K_rows = system.prescribed_rows(K)
        A, b = system.eliminate(K, inplace=not keep_stiffness)
    else:
        say(f"matrix-free operator ({reason})")
        t0 = time.perf_counter()
        A, b, precond = system.matrix_free()
        timings["assembly"] = time.perf_counter() - t0
        if solver == "auto":
            solver = "amg-cg" if system.symmetric else "amg-gmres"
    if preconditioner is not None:
        precond = system.preconditioner_matrix(preconditioner)
    say(f"solve ({solver})")
    lin: LinearSolveInfo = solve_linear(
        A,
        b,
        solver,
        rtol=rtol,
        maxiter=maxiter,
        near_null=system.near_null(),
        blocksize=d,
        symmetric=system.symmetric,
        amg_options=dict(amg_options or {}),
        preconditioner_matrix=precond,
        direct_backend=direct_backend,
        progress=progress,
    )
    timings["setup"] = lin.setup_time
    timings["solve"] = lin.solve_time
    u = system.expand(lin.x)
    # reactions -(f_int + f_ext) on prescribed DOFs, f_int = -K u from the assembled rows
    # when there are, else the model's matrix-free internal force
    reac = system.reactions(u, rows=K_rows)
    _check_force_balance(lin, b, reac, system.f_ext)
    timings["total"] = time.perf_counter() - t_start
    info = {
        "solver": lin.solver,
        **lin.info,
        "model": model.describe(),
        "operator": path,
        "operator_reason": reason,
    }
    if preconditioner is not None:
        info["preconditioner"] = preconditioner.describe()
    return StaticResult(
        problem=problem,
        bonds=system.disc.real_bonds,
        u=u,
        converged=True,
        n_iter=lin.n_iter,
        residuals=lin.residuals,
        relative_residual=lin.relative_residual,
        timings=timings,
        reactions=reac,
        prescribed_dofs=system.dofs,
        info=info,
        stiffness=K if keep_stiffness and K is not None else None,
        system=system,
    )


#: out-of-balance force, relative to the transmitted forces (reactions and loads), above
#: which a converged solve warns (``docs/solvers.md``, "Numerical extremes")
FORCE_BALANCE_TOL = 1e-4


def _check_force_balance(
    lin: LinearSolveInfo, b: np.ndarray, reactions: np.ndarray, f_ext: np.ndarray
) -> None:
    """Warn when the residual is small against ``b`` but not against the transmitted forces.

    The solvers stop on ``||b - A x|| <= rtol ||b||``.  When displacements are prescribed on
    a phase much stiffer than the one that carries the load (stiffness contrast 1e8), ``b``
    holds the stiff phase's forces and is ``contrast`` times larger than the reactions: a
    residual of 1e-12 ``||b||`` left 1 % of the reaction out of balance (AMG-CG, 1D bar).
    """
    scale = _safe_norm(np.ravel(reactions)) + _safe_norm(f_ext)
    nb = _safe_norm(b)
    if scale == 0.0 or nb == 0.0:
        return
    imbalance = lin.relative_residual * nb / scale
    if imbalance > FORCE_BALANCE_TOL:
        warnings.warn(
            f"{lin.solver}: the true residual is {lin.relative_residual:.1e} of ||b|| but "
            f"{imbalance:.1e} of the reaction and load forces (||b|| is {nb / scale:.1e} x "
            "larger: displacements prescribed on a much stiffer phase or region, e.g. a "
            "stiffness contrast); the reactions and the soft part of the field are accurate "
            "only to about that ratio. Use solver='direct' or a smaller rtol.",
            AccuracyWarning,
            stacklevel=3,
        )


_OPERATORS = ("assembled", "matrix-free", "auto")


def plan_memory(
    problem: StaticProblem,
    solver: str = "auto",
    *,
    operator: str = "auto",
    keep_stiffness: bool = False,
    direct_backend: str = "auto",
    history_steps: int = 0,
) -> RunEstimate:
    """Peak-memory estimate of ``solve(problem, ...)`` before any bond is searched.

    ``history_steps`` adds the per-step fields a load-stepping driver keeps
    (:func:`pdlin.solve_damage`, :func:`pdlin.solve_nonlinear`: u, stress and two scalars
    per point and step) to every stage.

    Counts the bonds (exactly on :func:`pdlin.grid` clouds with a constant horizon, from
    the neighbours of a lattice ball otherwise), the blocks of K (pairs within
    ``coupling_range`` horizons), picks the operator path ``solve`` would take and adds up
    the stages with the coefficients of :mod:`pdlin.resources`.

    Examples
    --------
    >>> import pdlin
    >>> from pdlin.problem import plan_memory
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), pdlin.grid((50, 50)), horizon=3.015)
    >>> plan = plan_memory(prob, "amg-cg")
    >>> plan.n_bonds == pdlin.find_bonds(prob.cloud, 3.015).n_bonds, plan.path
    (True, 'assembled')
    """
    cloud = problem.cloud
    n, d = cloud.n, cloud.dim
    model = problem.model
    rng = int(getattr(model, "coupling_range", 1))
    opts = dict(problem.bond_options)
    if problem.bonds is not None:
        nb = problem.bonds.n_bonds
        hor_b = float(np.max(problem.bonds.horizon))
        pairs = nb if rng < 2 else estimate_pair_count(cloud, hor_b, hops=rng)
    else:
        shape_factor = 1.0
        if opts.get("shape") in ("cube", "box"):  # the cube around the ball
            shape_factor = 2.0**d / (np.pi ** (d / 2) / math.gamma(d / 2 + 1))
        hor, ratio = problem.horizon, opts.get("ratio")
        nb = int(shape_factor * estimate_pair_count(cloud, hor, ratio))
        pairs = nb if rng < 2 else int(estimate_pair_count(cloud, hor, ratio, hops=rng))
    nblocks = n + pairs
    est = estimate_bond_operator_bytes(n, nblocks, d)
    path, _ = _choose_operator(
        operator, model, cloud, solver, est, bool(problem.symmetry), keep_stiffness,
        nblocks=nblocks,
    )  # fmt: skip
    ndof = n * d
    direct = solver == "direct" or (solver == "auto" and ndof <= 5000)
    if path == "assembled" and direct:
        path = "direct"
    backend = "superlu"
    if direct and direct_backend not in ("auto", "superlu"):
        backend = direct_backend
    elif direct and direct_backend == "auto":
        from .solvers.direct import AUTO_MIN, _auto_chain

        backend = "superlu" if ndof < AUTO_MIN else _auto_chain(True, ndof)[0]
    plan = estimate_static_run(n, nb, nblocks, d, path=path, coupling_range=rng, backend=backend)
    if history_steps:
        hist = int(history_steps) * n * (d + d * d + 2) * 8
        plan.stages = {k: v + hist for k, v in plan.stages.items()}
        plan.history_steps, plan.history_bytes = int(history_steps), hist
    return plan


def memory_hints(plan: RunEstimate) -> list[str]:
    """What would fit instead of ``plan``: iterative or matrix-free solves, a coarser grid,
    PETSc on more ranks (each with its estimated peak), fewer load steps (a kept history)."""
    from .resources import available_memory

    avail = max(available_memory().bytes, 1)
    need = max(plan.need, 1)
    hints: list[str] = []
    hist = plan.history_bytes
    if hist:
        per_step = hist / plan.history_steps
        room = avail - (need - hist)  # what the run needs besides its history
        fit = int(room // per_step) if room > 0 else 0
        hints.append(
            f"fewer load steps: at most ~{fit:,} load steps fit (each keeps "
            f"{format_bytes(per_step)} of fields; {plan.history_steps:,} need "
            f"{format_bytes(hist)})"
            if fit >= 1
            else f"fewer load steps ({plan.history_steps:,} keep {format_bytes(hist)} of fields)"
        )
    alt = {
        "direct": ("solver='amg-cg' (assembled K, AMG)", "assembled"),
        "assembled": ("operator='matrix-free'", "matrix-free"),
    }
    if plan.path in alt:
        text, path = alt[plan.path]
        other = estimate_static_run(
            plan.n_points, plan.n_bonds, plan.nnz_blocks, plan.dim, path=path,
            coupling_range=plan.coupling_range,
            base=plan.base + hist,  # the kept history stays whatever the solver
        )  # fmt: skip
        hints.append(f"{text}: ~{format_bytes(other.peak)}")
        if plan.path == "direct" and other.need > avail:
            mf = estimate_static_run(
                plan.n_points, plan.n_bonds, plan.nnz_blocks, plan.dim, path="matrix-free",
                base=plan.base + hist,
            )  # fmt: skip
            hints.append(f"solver='amg-cg' with operator='matrix-free': ~{format_bytes(mf.peak)}")
    frac = min(avail / need, 1.0)
    coarse = max(int(plan.n_points * frac * 0.9), 1)
    scale = (plan.n_points / coarse) ** (1 / plan.dim)
    hints.append(
        f"a coarser discretization of at most ~{coarse:,} points (spacing x {scale:.3g}, the "
        "same horizon ratio)"
    )
    ranks = max(int(np.ceil(need / avail)), 2)
    hints.append(
        f"backend='petsc' on >= {ranks} ranks with their own memory "
        f"(mpiexec -n {ranks} pdlin run ..., docs/petsc.md)"
    )
    return hints


def _choose_operator(
    operator: str,
    model: Model,
    cloud: PointCloud,
    solver: str,
    est_bytes: int,
    assembled_only: bool,
    keep_stiffness: bool = False,
    *,
    nblocks: int = 0,
) -> tuple[str, str]:
    """Assembled or matrix-free K, and why.

    In 3D a two-hop K is applied matrix-free when it averages more than 60 blocks per point
    (LPS/XOSB at δ = 3 h: 300-830, correspondence at δ = 2 h: ~185): assembling it is then
    the dominant cost (scipy's single-threaded sparse product) and the factored product is
    cheaper.  Sparse two-hop operators (nearest-neighbour correspondence: 25 blocks per
    point) are assembled, which also lets AMG see the operator itself instead of a
    surrogate.
    """
    if operator not in _OPERATORS:
        raise InputError(f"operator must be one of {_OPERATORS}, got {operator!r}")
    if operator == "assembled":
        return "assembled", "requested"
    if operator == "auto" and keep_stiffness:
        return "assembled", "keep_stiffness=True needs the assembled K"
    if assembled_only:  # the symmetry reduction has no matrix-free operator yet
        if operator == "matrix-free":
            raise InputError("operator='matrix-free' does not support symmetry planes yet")
        return "assembled", "symmetry planes need the assembled reduction"
    if operator == "matrix-free":
        if solver == "direct":
            raise InputError("solver 'direct' needs the assembled K; use operator='assembled'")
        return "matrix-free", "requested"
    if solver == "direct":
        return "assembled", "the direct solver needs the assembled K"
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        total = 0
    if total and est_bytes > 0.4 * total:
        return "matrix-free", (
            f"assembled K would take ~{est_bytes / 1e9:.1f} GB, over 40 % of "
            f"{total / 1e9:.0f} GB of memory"
        )
    per_point = nblocks / max(cloud.n, 1)
    if getattr(model, "coupling_range", 1) >= 2 and cloud.dim == 3 and per_point > 60:
        return "matrix-free", (
            f"K couples points two horizons apart in 3D ({per_point:.0f} blocks per point): "
            "the factored product is cheaper than assembling it"
        )
    return "assembled", f"assembled K fits (~{est_bytes / 1e9:.2f} GB)"
