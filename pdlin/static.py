"""The static driver: ``solve(problem)`` on scipy, or on PETSc with ``backend='petsc'``.

The layers below it: the problem's data (``pdlin.problem``), its constrained system
(:mod:`pdlin.system`, built by :func:`~pdlin.system.constrained_system`), the linear
solvers (``pdlin.solvers.linear``) and the PETSc backend
(``pdlin.backends.petsc``).  ``solve`` plans the memory, builds the system, picks the
assembled or matrix-free operator, solves and returns a :class:`~pdlin.system.StaticResult`.
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._validation import integer, tolerance
from .backends import BACKENDS
from .backends.petsc import solve_petsc
from .errors import InputError, InputTypeError, SlowRunWarning
from .models.base import Model
from .operators.assembly import estimate_bond_operator_bytes
from .problem import StaticProblem, choose_operator, memory_hints, plan_memory
from .resources import ASSEMBLY_TRANSIENT, check_memory
from .solvers.linear import (
    SOLVERS,
    LinearSolveInfo,
    SolverSetup,
    check_force_balance,
    solve_linear,
)
from .system import ConstrainedSystem, StaticResult, constrain, constrained_system, discretize

__all__ = ["solve", "solve_steps"]

log = logging.getLogger(__name__)


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
        when their assembled K would exceed 40 % of the machine's memory
        (one-hop models such as bond-based stay assembled: their
        matrix-free path would keep a preconditioning matrix of K's size).
        ``result.info['operator']`` and ``['operator_reason']`` say which
        path ran and why.
    preconditioner : Model, optional
        Build the preconditioner ('amg-cg', 'amg-gmres', 'ilu-gmres',
        'jacobi-cg') from the assembled stiffness of this model on the same
        cloud, bonds and Dirichlet conditions instead of from the operator
        being solved (or its surrogate).  Typical use: the nonsymmetric
        force-state linearization ``K_p`` of :class:`~pdlin.XOSB` /
        :class:`~pdlin.LPS` (``linearization='paper'``) solved by GMRES with
        the AMG of the symmetric energy-consistent ``K_E`` (pdlin's check on the plate
        with a hole of Liu, Chen & Skelton, XOSB, Sect. 5.1: GMRES on ``K_p`` with
        it converges in under 40 iterations, as CG + AMG does on ``K_E``).
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
        return solve_petsc(
            problem, solver, rtol=rtol, maxiter=maxiter, petsc_options=petsc_options,
            progress=progress,
        )  # fmt: skip
    rtol, maxiter = _check_scipy_options(rtol, maxiter, amg_options)
    say = progress or (lambda msg: None)
    timings: dict[str, float] = {}
    t_start = time.perf_counter()
    plan = _plan(problem, solver, operator, keep_stiffness, direct_backend, say)
    say("bonds")
    t0 = time.perf_counter()
    system = constrained_system(problem)
    timings["bonds"] = time.perf_counter() - t0
    ops = _operators(system, solver, operator, keep_stiffness, plan, say, timings)
    if preconditioner is not None:
        ops.precond = system.preconditioner_matrix(preconditioner)
    say(f"solve ({ops.solver})")
    lin = solve_linear(
        ops.A, ops.b, ops.solver, rtol=rtol, maxiter=maxiter, near_null=system.near_null(),
        blocksize=system.dim, symmetric=system.symmetric, amg_options=dict(amg_options or {}),
        preconditioner_matrix=ops.precond, direct_backend=direct_backend, progress=progress,
    )  # fmt: skip
    info = {"preconditioner": preconditioner.describe()} if preconditioner is not None else {}
    return _result(problem, system, ops, lin, ops.b, timings, t_start, keep_stiffness, info)


def solve_steps(
    problems: Sequence[StaticProblem],
    solver: str = "auto",
    *,
    rtol: float = 1e-8,
    maxiter: int | None = None,
    amg_options: Mapping[str, Any] | None = None,
    keep_stiffness: bool = False,
    progress: Callable[[str], None] | None = None,
    direct_backend: str = "auto",
) -> list[StaticResult]:
    """Solve the load steps of one body: bonds, K and its factorization or AMG once.

    The steps share the model, the points, the bonds and the prescribed DOFs and differ
    only in the prescribed values and the loads (a Peridigm deck's load steps,
    ``scene.steps``).  The bond search, the assembly, the elimination and the
    factorization (``'direct'``) or the preconditioner (AMG hierarchy, ILU, Jacobi) are
    done once, for the first step; every step then builds its right-hand side
    (:meth:`~pdlin.system.ConstrainedSystem.rhs`), solves, checks its own residual and
    gets its reactions.  Each result is bitwise the one of ``solve(problem, ...)``.
    On the matrix-free path (``operator='auto'`` of :func:`pdlin.solve` picks it for LPS and
    correspondence models in 3D) the operator and the preconditioner built from its
    surrogate are the shared part.  Steps that differ in model, points, bonds, symmetry
    planes or prescribed DOFs are solved independently by :func:`pdlin.solve`, the reason
    logged (``logging.INFO``, logger ``pdlin.static``).

    Parameters
    ----------
    problems : sequence of StaticProblem
        The steps, in order (at least one).
    solver, rtol, maxiter, amg_options, keep_stiffness, progress, direct_backend
        As in :func:`pdlin.solve` (for every step).

    Returns
    -------
    list of StaticResult
        One per step.  ``info['shared_system']`` is True on the steps that reused the
        first step's bonds and matrix (their ``timings`` hold ``rhs``, ``setup`` and
        ``solve``), ``info['setup_reused']`` on those that also reused its factorization
        or preconditioner (a step with a zero right-hand side solves nothing).

    Raises
    ------
    InputError
        When ``problems`` is empty or an option is out of range.
    InputTypeError
        When a step is not a :class:`~pdlin.StaticProblem`.
    FloatingBodyError, ConvergenceError
        As :func:`pdlin.solve`.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((20, 4), spacing=0.05)
    >>> model = pdlin.BondBased(E=1.0)
    >>> steps = [pdlin.StaticProblem(model, cloud, horizon=0.1,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [t * 1e-3, 0.0])])
    ...     for t in (0.5, 1.0)]
    >>> res = pdlin.static.solve_steps(steps, solver="direct")
    >>> [(r.info["shared_system"], r.info["setup_reused"]) for r in res]
    [(False, False), (True, True)]
    >>> all(np.array_equal(r.u, pdlin.solve(p, solver="direct").u) for r, p in zip(res, steps))
    True
    """
    problems = list(problems)
    if not problems:
        raise InputError("problems must hold at least one StaticProblem, got none")
    for k, p in enumerate(problems):
        if not isinstance(p, StaticProblem):
            raise InputTypeError(f"problems[{k}] must be a StaticProblem, got {type(p).__name__}")
    if solver not in SOLVERS:
        raise InputError(f"solver must be one of {SOLVERS}, got {solver!r}")
    rtol, maxiter = _check_scipy_options(rtol, maxiter, amg_options)
    opts: dict[str, Any] = dict(
        rtol=rtol, maxiter=maxiter, amg_options=amg_options, keep_stiffness=keep_stiffness,
        progress=progress, direct_backend=direct_backend,
    )  # fmt: skip
    say = progress or (lambda msg: None)
    why = _steps_differ(problems)
    if why is not None:
        return _independent(problems, solver, why, opts)
    t_start = time.perf_counter()
    timings: dict[str, float] = {}
    plan = _plan(problems[0], solver, "auto", keep_stiffness, direct_backend, say)
    say("bonds")
    t0 = time.perf_counter()
    disc = discretize(problems[0])
    first = constrain(problems[0], disc)
    systems = [first, *(constrain(p, disc, checked=first.dofs) for p in problems[1:])]
    timings["bonds"] = time.perf_counter() - t0
    for k, sk in enumerate(systems[1:], 2):
        if not np.array_equal(sk.dofs, first.dofs):
            return _independent(problems, solver, f"step {k} prescribes other DOFs", opts)
    ops = _operators(first, solver, "auto", keep_stiffness, plan, say, timings, True)
    setup = SolverSetup()
    near_null = first.near_null()
    results = []
    for k, (problem, system) in enumerate(zip(problems, systems, strict=True)):
        if k > 0:
            t_start, timings = time.perf_counter(), {}
            t0 = time.perf_counter()
            ops.b = system.rhs(ops.cols)
            timings["rhs"] = time.perf_counter() - t0
        say(f"load step {k + 1}/{len(problems)}: solve ({ops.solver})")
        uses = setup.uses
        lin = solve_linear(
            ops.A, ops.b, ops.solver, rtol=rtol, maxiter=maxiter, near_null=near_null,
            blocksize=system.dim, symmetric=system.symmetric,
            amg_options=dict(amg_options or {}), preconditioner_matrix=ops.precond,
            direct_backend=direct_backend, progress=progress, setup=setup,
        )  # fmt: skip
        extra = {"shared_system": k > 0, "setup_reused": setup.uses > uses}
        results.append(
            _result(problem, system, ops, lin, ops.b, timings, t_start, keep_stiffness, extra)
        )
    return results


def _same(a: Any, b: Any) -> bool:
    """Whether two pieces of problem data are the same (arrays by value, else ``==``)."""
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, tuple | list) and isinstance(b, tuple | list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    try:
        return bool(a == b)
    except (TypeError, ValueError):  # e.g. dataclasses holding arrays
        return False


def _steps_differ(problems: list[StaticProblem]) -> str | None:
    """Why the load steps cannot share one system (None when they can)."""
    p0 = problems[0]
    for k, p in enumerate(problems[1:], 2):
        if not _same(p.model, p0.model):
            return f"step {k} has another model"
        if not _same(p.cloud, p0.cloud):
            return f"step {k} has other points"
        if not (
            _same(p.bonds, p0.bonds) and _same(p.horizon, p0.horizon)
            and _same(dict(p.bond_options), dict(p0.bond_options))
        ):  # fmt: skip
            return f"step {k} has other bonds"
        if not _same(tuple(p.symmetry), tuple(p0.symmetry)):
            return f"step {k} has other symmetry planes"
    return None


def _independent(
    problems: list[StaticProblem], solver: str, why: str, opts: dict[str, Any]
) -> list[StaticResult]:
    """Solve every step on its own (:func:`pdlin.solve`), saying why the steps share nothing."""
    log.info("solve_steps: %d independent solves: %s", len(problems), why)
    if opts["progress"] is not None:
        opts["progress"](f"load steps solved independently: {why}")
    results = [solve(p, solver, **opts) for p in problems]
    for r in results:
        r.info.update(shared_system=False, setup_reused=False)
    return results


def _check_scipy_options(
    rtol: float, maxiter: int | None, amg_options: Mapping[str, Any] | None
) -> tuple[float, int | None]:
    """Check ``rtol``, ``maxiter`` and ``amg_options`` of a scipy solve; return them normalized."""
    rtol = tolerance(rtol, "rtol")
    if maxiter is not None:
        maxiter = integer(maxiter, "maxiter", minimum=1)
    if amg_options is not None and not isinstance(amg_options, Mapping):
        raise InputTypeError(
            f"amg_options must be a mapping of pyamg keyword arguments, got "
            f"{type(amg_options).__name__}"
        )
    return rtol, maxiter


def _plan(
    problem: StaticProblem,
    solver: str,
    operator: str,
    keep_stiffness: bool,
    direct_backend: str,
    say: Callable[[str], None],
) -> Any:
    """Plan the run's memory, refuse it when it does not fit, warn when it will be slow."""
    plan = plan_memory(
        problem, solver, operator=operator, keep_stiffness=keep_stiffness,
        direct_backend=direct_backend,
    )  # fmt: skip
    say(plan.summary())
    check_memory("this run", plan.need, lambda: memory_hints(plan))
    slow = plan.slow_warning()
    if slow is not None:
        say(f"warning: {slow}")
        warnings.warn(slow, SlowRunWarning, stacklevel=3)
    return plan


@dataclass
class _Operators:
    """The eliminated system of a solve: operator, right-hand side, what the reactions need."""

    path: str
    reason: str
    solver: str
    A: Any
    b: np.ndarray
    K: Any = None
    K_rows: Any = None
    precond: Any = None
    cols: Any = None


def _operators(
    system: ConstrainedSystem,
    solver: str,
    operator: str,
    keep_stiffness: bool,
    plan: Any,
    say: Callable[[str], None],
    timings: dict[str, float],
    keep_columns: bool = False,
) -> _Operators:
    """Pick the assembled or matrix-free operator, build it and eliminate the conditions."""
    model, cloud, d = system.model, system.cloud, system.dim
    nblocks = system.estimate_nnz_blocks()
    est = estimate_bond_operator_bytes(cloud.n, nblocks, d)
    path, reason = choose_operator(
        operator, model, cloud, solver, est, not system.matrix_free_capable, keep_stiffness,
        nblocks=nblocks,
    )  # fmt: skip
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
        # and its prescribed columns, for the right-hand sides of further load steps
        cols = system.prescribed_columns(K) if keep_columns else None
        A, b = system.eliminate(K, inplace=not keep_stiffness)
        return _Operators(path, reason, solver, A, b, K=K, K_rows=K_rows, cols=cols)
    say(f"matrix-free operator ({reason})")
    t0 = time.perf_counter()
    op = system.disc.operator() if keep_columns else None
    A, b, precond = system.matrix_free(op=op)
    timings["assembly"] = time.perf_counter() - t0
    if solver == "auto":
        solver = "amg-cg" if system.symmetric else "amg-gmres"
    # the operator itself gives the right-hand sides of further load steps
    return _Operators(path, reason, solver, A, b, precond=precond, cols=op)


def _result(
    problem: StaticProblem,
    system: ConstrainedSystem,
    ops: _Operators,
    lin: LinearSolveInfo,
    b: np.ndarray,
    timings: dict[str, float],
    t_start: float,
    keep_stiffness: bool,
    extra: dict[str, Any],
) -> StaticResult:
    """Expand the solution, compute the reactions, check the force balance, build the result."""
    timings["setup"] = lin.setup_time
    timings["solve"] = lin.solve_time
    u = system.expand(lin.x)
    # reactions -(f_int + f_ext) on prescribed DOFs, f_int = -K u from the assembled rows
    # when there are, else the model's matrix-free internal force
    reac = system.reactions(u, rows=ops.K_rows)
    check_force_balance(lin, b, reac, system.f_ext)
    timings["total"] = time.perf_counter() - t_start
    info = {
        "solver": lin.solver,
        **lin.info,
        "model": problem.model.describe(),
        "operator": ops.path,
        "operator_reason": ops.reason,
        **extra,
    }
    isolated = getattr(system.disc, "isolated", None)
    if isolated is not None:  # points without bonds, held at rest (pdlin.constraints)
        info["isolated_points"] = isolated.tolist()
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
        stiffness=ops.K if keep_stiffness and ops.K is not None else None,
        system=system,
    )
