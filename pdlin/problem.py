"""Static problems (data) and the memory plan of their solve.

A :class:`StaticProblem` holds the model, the cloud, the bonds or how to find them, the
conditions and loads and the symmetry planes; nothing is computed from it here but the
memory estimate of a run (:func:`plan_memory`).  The constrained system built from it is
in :mod:`pdlin.system`, the drivers that solve it on top (:func:`pdlin.solve` in
:mod:`pdlin.static`, :func:`pdlin.solve_nonlinear`, the PETSc backend).
"""

from __future__ import annotations

import importlib
import inspect
import logging
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import InitVar, dataclass, field
from typing import Any

import numpy as np

from ._repr import Raw as _Raw
from ._repr import compact_repr
from ._validation import as_float_array
from .errors import InputError, InputTypeError, ShapeError
from .geometry.bonds import Bonds, find_bonds
from .geometry.cloud import PointCloud
from .models.base import Model
from .models.thermal import ThermalExpansion, check_thermal
from .operators.assembly import estimate_bond_operator_bytes
from .operators.bc import (
    BodyForce,
    Dirichlet,
    TotalForce,
)
from .operators.symmetry import SymmetryPlane
from .resources import (
    RunEstimate,
    estimate_pair_count,
    estimate_static_run,
    format_bytes,
    resident_bonds_bytes,
)

__all__ = ["StaticProblem", "plan_memory", "memory_hints", "choose_operator", "OPERATORS"]

#: names that moved out of this module: name -> new module
_MOVED = {
    "solve": "pdlin.static",
    "StaticResult": "pdlin.system",
    "FORCE_BALANCE_TOL": "pdlin.solvers.linear",
}


def __getattr__(name: str) -> Any:
    """Return ``solve``, ``StaticResult`` or ``FORCE_BALANCE_TOL`` from their new modules.

    Deprecated access (a :class:`DeprecationWarning`); other names raise AttributeError.
    """
    if name in _MOVED:
        warnings.warn(
            f"pdlin.problem.{name} moved to {_MOVED[name]}.{name}; the old path will be "
            "removed in the next release",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module(_MOVED[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
    thermal : ThermalExpansion, optional
        A temperature change and thermal expansion coefficient
        (``pdlin.models.thermal.ThermalExpansion``): the free thermal strain is an
        eigenstrain, its load ``f_th`` joins the loads (``K u = f_ext + f_th``) and the
        result's strain and stress are the mechanical ones (thermal part removed).
        Not with symmetry planes.

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
    thermal: ThermalExpansion | None = None

    def __post_init__(self, ratio: float | None = None) -> None:
        """Check the data and normalize conditions, loads and planes to tuples."""
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
        if check_thermal(self.thermal) is not None and sym:
            raise InputError(
                "thermal with symmetry planes is not supported: give the whole body, got "
                f"{len(sym)} symmetry plane(s)"
            )

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
            "thermal": None if self.thermal is None else _Raw(repr(self.thermal)),
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
        """Return the problem's bonds (built on demand when not given).

        Returns
        -------
        Bonds
            ``bonds``, else ``find_bonds(cloud, horizon, **bond_options)`` (a new search
            on each call).
        """
        if self.bonds is not None:
            return self.bonds
        return find_bonds(self.cloud, self.horizon, **dict(self.bond_options))


#: values of ``pdlin.solve(..., operator=...)``
OPERATORS = ("assembled", "matrix-free", "auto")


def plan_memory(
    problem: StaticProblem,
    solver: str = "auto",
    *,
    operator: str = "auto",
    keep_stiffness: bool = False,
    direct_backend: str = "auto",
    history_steps: int = 0,
) -> RunEstimate:
    """Estimate the peak memory of ``solve(problem, ...)`` before any bond is searched.

    ``history_steps`` adds the per-step fields a load-stepping driver keeps
    (:func:`pdlin.solve_damage`, :func:`pdlin.solve_nonlinear`: u, stress and two scalars
    per point and step) to every stage.

    Counts the bonds (exactly on :func:`pdlin.grid` clouds with a constant horizon, from
    the neighbours of a lattice ball otherwise), the blocks of K (pairs within
    ``coupling_range`` horizons), picks the operator path ``solve`` would take and adds up
    the stages with the coefficients of :mod:`pdlin.resources`.

    Parameters
    ----------
    problem : StaticProblem
        The problem.
    solver : str
        As for :func:`pdlin.solve` (decides the direct or iterative path).
    operator : {'auto', 'assembled', 'matrix-free'}
        As for :func:`pdlin.solve`.
    keep_stiffness : bool
        As for :func:`pdlin.solve` (forces the assembled path).
    direct_backend : str
        As for :func:`pdlin.solve` (the factorization's memory coefficients).
    history_steps : int
        Load steps whose fields a stepping driver keeps.

    Returns
    -------
    RunEstimate
        Bonds, blocks, operator path and the bytes of every stage (``need``, ``peak``).

    Raises
    ------
    InputError
        When ``operator`` is not one of :data:`OPERATORS`, or ``'matrix-free'`` is asked
        with symmetry planes or the direct solver.

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
    path, _ = choose_operator(
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
        from .solvers.direct import AUTO_MIN, auto_chain

        backend = "superlu" if ndof < AUTO_MIN else auto_chain(True, ndof, d)[0]
    if problem.bonds is not None:
        resident = problem.bonds.nbytes()
    else:  # find_bonds' lattice search keeps j and a stencil index (compact Bonds)
        lattice = cloud.lattice is not None and opts.get("method", "auto") != "tree"
        lattice = lattice and np.ndim(problem.horizon) == 0
        resident = resident_bonds_bytes(nb, n, d, lattice)
    plan = estimate_static_run(
        n, nb, nblocks, d, path=path, coupling_range=rng, backend=backend,
        resident_bonds=resident,
    )  # fmt: skip
    if history_steps:
        hist = int(history_steps) * n * (d + d * d + 2) * 8
        plan.stages = {k: v + hist for k, v in plan.stages.items()}
        plan.history_steps, plan.history_bytes = int(history_steps), hist
    return plan


def memory_hints(plan: RunEstimate) -> list[str]:
    """List what would fit in the available memory instead of ``plan``.

    Iterative or matrix-free solves, a coarser grid, PETSc on more ranks (each with its
    estimated peak), fewer load steps (a kept history).

    Parameters
    ----------
    plan : RunEstimate
        The estimate that does not fit (:func:`plan_memory`).

    Returns
    -------
    list of str
        One hint per alternative, for the message of
        :class:`~pdlin.errors.InsufficientMemoryError`.
    """
    # looked up at call time: tests replace pdlin.resources.available_memory
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
    # (an estimate is not byte-exact: a need a few bytes over k budgets asks for k ranks)
    ranks = max(int(np.ceil(need / avail * (1.0 - 1e-6))), 2)
    hints.append(
        f"backend='petsc' on >= {ranks} ranks with their own memory "
        f"(mpiexec -n {ranks} pdlin run ..., docs/petsc.md)"
    )
    return hints


def choose_operator(
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
    """Choose the assembled or matrix-free K, and say why.

    A two-hop K (``model.coupling_range >= 2``) is applied matrix-free when it would take
    more than 40 % of the machine's memory: its operator and one-hop surrogate are smaller.
    A one-hop K stays assembled at any size, since its matrix-free path preconditions with
    the same one-hop matrix (``Model.surrogate_stiffness``) and saves nothing.
    In 3D a two-hop K is also applied matrix-free when it averages more than 60 blocks per point
    (LPS/XOSB at δ = 3 h: 300-830, correspondence at δ = 2 h: ~185): assembling it is then
    the dominant cost (scipy's single-threaded sparse product) and the factored product is
    cheaper.  Sparse two-hop operators (nearest-neighbour correspondence: 25 blocks per
    point) are assembled, which also lets AMG see the operator itself instead of a
    surrogate.

    Parameters
    ----------
    operator : {'auto', 'assembled', 'matrix-free'}
        The request.
    model : Model
        Its ``coupling_range`` counts.
    cloud : PointCloud
        The solved points.
    solver : str
        The linear solver ('direct' needs the assembled K).
    est_bytes : int
        Estimated bytes of the assembled K.
    assembled_only : bool
        The discretization has no matrix-free operator (symmetry planes).
    keep_stiffness : bool
        The result keeps the assembled K.
    nblocks : int
        Estimated stored blocks of K.

    Returns
    -------
    path : {'assembled', 'matrix-free'}
        The operator path.
    reason : str
        Why, for ``result.info['operator_reason']``.

    Raises
    ------
    InputError
        For an unknown ``operator``, or ``'matrix-free'`` with symmetry planes or with
        ``solver='direct'``.
    """
    if operator not in OPERATORS:
        raise InputError(f"operator must be one of {OPERATORS}, got {operator!r}")
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
    one_hop = getattr(model, "coupling_range", 1) < 2
    if total and est_bytes > 0.4 * total:
        big = f"~{est_bytes / 1e9:.1f} GB, over 40 % of {total / 1e9:.0f} GB of memory"
        if one_hop:  # its matrix-free path is preconditioned by a matrix of K's own size
            return "assembled", (
                f"assembled K {big}, but a one-hop model's matrix-free path would keep an "
                "assembled preconditioning matrix of the same size"
            )
        return "matrix-free", f"assembled K would take {big}"
    per_point = nblocks / max(cloud.n, 1)
    if not one_hop and cloud.dim == 3 and per_point > 60:
        return "matrix-free", (
            f"K couples points two horizons apart in 3D ({per_point:.0f} blocks per point): "
            "the factored product is cheaper than assembling it"
        )
    return "assembled", f"assembled K fits (~{est_bytes / 1e9:.2f} GB)"
