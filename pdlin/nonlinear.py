"""Load-stepped nonlinear static solves: ``pdlin.solve_nonlinear``.

A problem is transformed once into its :class:`~pdlin.system.ConstrainedSystem`;
each load step then runs the load stepping of :mod:`pdlin.solvers.stepping`
(Newton of :mod:`pdlin.solvers.newton` with line search and cut-back, adaptive
dynamic relaxation of :mod:`pdlin.solvers.adr`, or Newton with an ADR fallback)
and commits the model's trial state when it converges; checkpoints are written by
:mod:`pdlin.solvers.checkpoint`.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._repr import compact_repr, html_table, time_span
from .errors import InputError, InputTypeError
from .problem import StaticProblem
from .solvers.checkpoint import problem_fingerprint
from .solvers.options import (
    METHODS,
    PREDICTORS,
    ADROptions,
    NewtonOptions,
    StepControl,
    check_keywords,
    resolve_density,
)
from .solvers.stepping import (
    SKIPPED,
    LoadStepper,
    history_arrays,
    homogenize_weights,
    make_predictor,
    step_times,
)
from .system import ConstrainedSystem, constrained_system

__all__ = ["NonlinearResult", "solve_nonlinear", "METHODS", "PREDICTORS"]


@dataclass
class NonlinearResult:
    """Per-step results of :func:`solve_nonlinear`.

    Attributes
    ----------
    times, factors : (k,) ndarray
        Time and proportional load factor ``t / t_end`` of each load step.
    u : (k, n, dim) ndarray
        Converged displacement per step.
    stress : (k, n, dim, dim) ndarray or None
        Cauchy stress per point (the model's response, or its linear stress).
    homogenized_stress : (k, dim, dim) ndarray or None
        Volume average of ``stress`` over the homogenized points.
    reactions : (k, n, dim) ndarray
        Nodal reactions on the prescribed DOFs.
    states : list of dict
        Committed states (every step, also after a resume; only the last with
        ``keep_states=False``, or after a resume from a checkpoint written with it):
        ``state_steps`` gives their step indices and :meth:`state_at` looks one up.
    iterations, calls, cutbacks : (k,) ndarray of int
        Newton iterations or ADR iterations, constitutive evaluations and
        failed increments (cut-backs) per step (summed over sub-steps).
    methods : list of str
        Driver that converged each step: ``'newton'``, ``'adr'``,
        ``'adr (newton failed)'`` (``method='auto'`` fell back) or ``'adr (newton
        skipped)'`` (``auto`` did not try Newton, ``newton_backoff``).
    messages : list of str
        Why Newton failed on a step that fell back, or why it was skipped (empty
        otherwise).
    damping : list of ndarray
        ADR damping coefficient per iteration of each step (empty for Newton).
    e1, e2 : (k,) ndarray
        ADR's final relative criteria (NaN for Newton steps).
    residuals : (k,) ndarray
        Final relative residual ``‖r_free‖ / force scale`` per step.
    timings : dict
        ``'setup'``, ``'total'`` seconds (of this call) and ``'steps'`` (k,) wall seconds
        per step; a resumed run's steps from the checkpoint carry the times measured by
        the run that solved them (NaN from a checkpoint that recorded none).
    """

    problem: StaticProblem
    system: ConstrainedSystem
    times: np.ndarray
    factors: np.ndarray
    u: np.ndarray
    stress: np.ndarray | None
    homogenized_stress: np.ndarray | None
    reactions: np.ndarray
    states: list[dict[str, np.ndarray]]
    iterations: np.ndarray
    calls: np.ndarray
    cutbacks: np.ndarray
    methods: list[str]
    messages: list[str]
    damping: list[np.ndarray]
    e1: np.ndarray
    e2: np.ndarray
    residuals: np.ndarray
    timings: dict[str, Any] = field(default_factory=dict)
    resumed_from: int = 0
    #: ADR iterations Newton ran at stalls per step (``relax`` of :func:`solve_nonlinear`)
    relaxations: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: Newton iterations that finished stalled ADR increments per step (``polish`` of
    #: :func:`solve_nonlinear`; failed tries included)
    polishes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: load-step index (0-based) of each entry of ``states``: all steps, or with
    #: ``keep_states=False`` the last one (after a resume from a checkpoint written with
    #: ``keep_states=False``: its last committed step followed by the steps solved here)
    state_steps: list[int] = field(default_factory=list)

    def state_at(self, step: int) -> dict[str, np.ndarray] | None:
        """Return the committed state after load step ``step``, or None if not kept.

        Parameters
        ----------
        step : int
            Load-step index (0-based; negative counts from the end).

        Returns
        -------
        dict of str to ndarray or None
            The model's state variables after that step (None: not kept, see
            ``keep_states``).
        """
        k = step % self.n_steps if self.n_steps else step
        try:
            return self.states[self.state_steps.index(k)]
        except ValueError:
            return None

    @property
    def converged(self) -> bool:
        """Every step converged (a failing step raises, so always True on a result)."""
        return True

    @property
    def state(self) -> dict[str, np.ndarray]:
        """The committed state after the last step."""
        return self.states[-1]

    @property
    def n_steps(self) -> int:
        """Number of load steps."""
        return int(self.times.size)

    def _table(self) -> list[tuple[str, Any]]:
        k, n, d = (int(s) for s in self.u.shape)
        return [
            ("model", repr(self.problem.model)),
            ("points", n),
            ("dim", d),
            ("DOFs", n * d),
            ("steps", k),
            ("times", time_span(self.times)),
            ("methods", ", ".join(sorted(set(self.methods))) or None),
            ("iterations", int(self.iterations.sum())),
            ("cutbacks", int(self.cutbacks.sum())),
            ("max residual", float(np.max(self.residuals)) if k else None),
            ("resumed from step", self.resumed_from or None),
            ("time (s)", float(self.timings.get("total", np.nan))),
        ]

    @classmethod
    def from_run(
        cls,
        problem: StaticProblem,
        run: Any,
        times: np.ndarray,
        t_end: float,
        timings: dict[str, Any],
        t_start: float,
        cols: dict[str, Any],
        **extra: Any,
    ) -> NonlinearResult:
        """Build the result of a finished load-step run.

        Parameters
        ----------
        problem : StaticProblem
            The solved problem.
        run : LoadStepper
            The run (its system, committed states and their steps).
        times : (k,) ndarray
            The load-step times.
        t_end : float
            The time at which the load factor is 1.
        timings : dict
            Seconds so far (``'setup'``); ``'steps'`` and ``'total'`` are added.
        t_start : float
            ``time.perf_counter()`` at the start of the run.
        cols : dict
            The per-step columns (``pdlin.solvers.stepping.history_arrays``).
        **extra
            Further fields (``resumed_from``).

        Returns
        -------
        NonlinearResult
            The result.
        """
        timings["steps"] = cols.pop("step_time")
        timings["total"] = time.perf_counter() - t_start
        return cls(
            problem=problem,
            system=run.system,
            times=times,
            factors=times / t_end,
            states=run.states,
            state_steps=run.state_steps,
            relaxations=cols.pop("relaxations"),
            polishes=cols.pop("polishes"),
            timings=timings,
            **extra,
            **cols,
        )

    def __repr__(self) -> str:
        """Sizes, steps, drivers, iterations and residual (no arrays, no memory address)."""
        names = {"max residual": "max_residual", "time (s)": "seconds"}
        names["resumed from step"] = "resumed_from"
        items = {names.get(key, key): v for key, v in self._table() if key != "model"}
        return compact_repr("NonlinearResult", items)

    def _repr_html_(self) -> str:
        """Return the summary as an HTML table (Jupyter)."""
        return html_table("NonlinearResult", self._table())

    def summary(self) -> dict[str, Any]:
        """Return a plain-data summary (for the CLI and logs).

        Returns
        -------
        dict
            Steps, points, dim, drivers used, iteration, constitutive-call, cut-back,
            relaxation and polish totals, fallbacks, skipped Newton steps, the largest
            relative residual and the setup and total seconds.
        """
        return {
            "steps": self.n_steps,
            "points": int(self.u.shape[1]),
            "dim": int(self.u.shape[2]),
            "methods": sorted(set(self.methods)),
            "iterations": int(self.iterations.sum()),
            "constitutive_calls": int(self.calls.sum()),
            "cutbacks": int(self.cutbacks.sum()),
            "relaxation_iterations": int(self.relaxations.sum()),
            "polish_iterations": int(self.polishes.sum()),
            "fallbacks": int(sum(1 for m in self.methods if "failed" in m)),
            "newton_skipped": int(sum(1 for m in self.methods if m == SKIPPED)),
            "max_relative_residual": float(np.max(self.residuals)) if self.n_steps else 0.0,
            "timings": {
                "setup": round(float(self.timings.get("setup", 0.0)), 4),
                "total": round(float(self.timings.get("total", 0.0)), 4),
            },
        }


def solve_nonlinear(
    problem: StaticProblem,
    steps: int = 10,
    *,
    method: str = "auto",
    t_end: float | None = None,
    times: Sequence[float] | None = None,
    predictor: str = "auto",
    rtol: float = 1e-8,
    maxiter: int = 25,
    line_search: bool = True,
    max_cutbacks: int = 8,
    fallback_cutbacks: int = 2,
    newton_backoff: bool = True,
    linear_solver: str = "auto",
    relax: int = 0,
    forcing: str = "fixed",
    globalization: str = "line-search",
    e_l: float = 1e-6,
    density: Any = "gershgorin",
    density_safety: float = 1.1,
    dt: float | None = None,
    damping: float | None = None,
    c0: float = 1.0,
    adr_maxiter: int | None = None,
    floor: float = 1e-12,
    polish: bool | None = None,
    adr_stall: int | None = None,
    homogenize: Any = None,
    keep_states: bool = True,
    checkpoint: str | os.PathLike[str] | None = None,
    resume: bool | str = False,
    progress: Callable[[str], None] | None = None,
    progress_every: float = 60.0,
    snapshot_every: float = 300.0,
) -> NonlinearResult:
    """Solve a static problem with a nonlinear or history-dependent model in load steps.

    Step ``k`` runs to time ``t_k`` (``times``, or ``t_end k / steps``):
    :class:`~pdlin.operators.TimePath` conditions (e.g. :meth:`pdlin.Dirichlet.velocity_gradient`)
    are evaluated at ``t_k``, other prescribed values and loads are scaled
    by ``t_k / t_end``.  The model's state (e.g. plastic deformation and slip
    resistances of :class:`pdlin.CrystalPlasticity`) is committed only when a
    step converges.

    Parameters
    ----------
    problem : StaticProblem
        Any pdlin model; nonlinear ones implement :meth:`pdlin.models.Model.respond`
        (e.g. ``Correspondence(material=CrystalPlasticity(...))``).  Linear
        models are solved exactly the same way (Newton converges in one
        iteration; ADR converges to the linear solution).
    steps : int
        Number of equal load steps up to ``t_end`` (ignored with ``times``).
    method : {'auto', 'newton', 'adr'}
        'newton': Newton-Raphson with the consistent tangent, backtracking line search
        and step cut-back.  'adr': adaptive dynamic relaxation (Kilic & Madenci 2010;
        Luo, Ramazani & Sundararaghavan 2017, Section 2.2).  'auto': Newton, falling
        back to ADR from Newton's last converged increment when an increment fails even
        after ``max_cutbacks`` halvings (``result.methods`` says so; after such a step,
        see ``fallback_cutbacks``).
    t_end : float, optional
        Time of the full load (default 1): the end of ``steps`` equal steps,
        and the time at which plain prescribed values and loads reach their
        given size (they scale with ``t / t_end``; with ``times`` beyond
        ``t_end`` they keep growing proportionally).
    times : sequence of float, optional
        Explicit step times (increasing, > 0).
    predictor : {'auto', 'affine', 'tangent', 'committed-tangent', 'extrapolate', 'previous'}
        Start of each step: the incremental affine map of a velocity-gradient path
        (``exp(L Δt)(X + u) - X``, pdlin's default for ADR); the tangent predictor
        ``u + Δu`` with ``K_T(u) Δu = r(u)`` and the prescribed increment imposed (one linear
        solve; exact for linear models), ``K_T`` the consistent tangent at the end of
        the last converged increment (its active sets carried on; from the committed
        state at the first step); 'committed-tangent' the same with ``K_T`` from the
        committed state (a zero increment: for crystal plasticity the elastic tangent);
        a linear extrapolation of the last two steps; or the last solution. 'auto':
        tangent for Newton steps; for ADR steps affine when the prescribed paths share
        one velocity gradient, else tangent.
    rtol, maxiter, line_search, max_cutbacks, linear_solver
        Newton: convergence ``‖r_free‖ <= rtol`` x force scale (the larger of
        ``‖λ f_ext‖`` and the reaction norm), iteration budget per (sub)step,
        backtracking on/off, how often one increment may be halved (Newton and
        ADR; the smallest increment is the step / 2**max_cutbacks; a converged
        increment is doubled after easy convergence and the last one starts the
        next step; ADR grows its increments back to a size that failed only
        after a hold: the next load step stays below it, the one after starts with
        it; while the retry fails the hold doubles, 1, 2, 4, ... load steps, and
        after it converges the next larger size is held likewise), inner linear
        solver
        ('auto': direct up to 2·10⁵ DOFs in 2D / 3·10⁴ in 3D, then AMG-Krylov;
        'krylov': GMRES preconditioned by one AMG hierarchy of the symmetrized elastic
        tangent, built once per run and reused by every iteration and step).
    fallback_cutbacks : int
        ``method='auto'``: Newton's halvings in a load step that follows an
        ADR fallback, one fewer for every further consecutive fallback step
        down to the whole step alone (``max_cutbacks`` again once Newton
        carries a step); the step starts with a whole-step increment.  Where
        Newton failed the last step it likely fails this one too, and each
        failed increment costs up to ``maxiter`` tangents and linear solves,
        while ADR's cost hardly depends on how much of the step is left (10⁵
        crystal-plasticity points: ≈ 20 min of creeping Newton increments per
        step before the fallback with ``max_cutbacks`` halvings,
        docs/nonlinear.md).
    newton_backoff : bool
        ``method='auto'``: once Newton has failed ``fallback_cutbacks + 1`` load steps in a
        row (its tries then down to the whole step alone), try it only when the number of
        steps in a row without Newton is a power of two (4, 8, 16, ...) and give the other
        steps to ADR directly (``result.methods``: ``'adr (newton skipped)'``); a step
        Newton carries ends the streak.  At 10⁵ crystal-plasticity points a failing
        whole-step Newton try costs ≈ 1.5 min of an ≈ 9 min step (docs/nonlinear.md).
        False: try Newton at every step.
    relax : int
        Newton's relaxation at stalls (0, the default: off; e.g. 50): when five
        Newton iterations reduce ``‖r‖`` less than twofold, or a line search
        fails, up to ``relax`` ADR iterations from the current iterate (at rest,
        Gershgorin density of the current tangent and at least that of the
        elastic one), and Newton resumes from the last of them.
        At active-set switches (a crystal whose slip systems load or unload)
        ``r(u)`` has kinks, and Newton can stall jumping across them; the
        relaxation settles such local errors (``result.relaxations`` counts its
        iterations).  It lets ``method='newton'`` through stalls it would fail;
        with ``'auto'`` it was not faster than the ADR fallback in the measured
        runs (docs/nonlinear.md), hence off by default.
    forcing : {'fixed', 'eisenstat-walker'}
        Newton with ``linear_solver='krylov'``: the tolerance of each GMRES solve, 1e-10
        or Eisenstat & Walker's (1996) choice 2 (loose far from the solution, tight
        near it: inexact Newton).
    globalization : {'line-search', 'ptc'}
        Newton's globalization: backtracking line search with the watchdog
        (``line_search``), or pseudo-transient continuation, ``(K_T + Λ/τ) du = r`` with
        ``Λ`` ADR's Gershgorin density of the elastic tangent and ``τ`` growing as
        ``‖r‖`` falls (Kelley & Keyes 1998); ``maxiter`` counts its linear solves.
    e_l, density, density_safety, dt, damping, c0, adr_maxiter, floor
        ADR: target of the relative criteria e₁, e₂ (Luo, Ramazani &
        Sundararaghavan 2017, Eqs. 19-20);
        fictitious density ``'gershgorin'`` (Kilic-Madenci, ``Λ_ii = s ¼ Δt²
        Σ_j |K_ij|`` of the tangent at each step's predictor, at least that of
        the initial (elastic) tangent, with Δt = ``dt`` or 1 and the safety
        ``s = density_safety``: at ``s = 1`` the highest mode sits at the
        stability limit and decays very slowly, 1.1 keeps it damped;
        hardening materials far from equilibrium may need more) or a
        positive number / ``(n*dim,)`` array with an explicit ``dt`` (the
        paper's Eq. 12 with ``Λ = 1``: ``Δt = h sqrt(1/E_max)``,
        :func:`~pdlin.solvers.adr_time_step`); constant
        ``damping`` instead of the adaptive Rayleigh quotient (finite, >= 0); initial
        damping ``c0`` (finite, >= 0); iteration budget per step, an integer >= 1
        (default ``200 ⌈N^(1/dim)⌉ + 2000``); absolute floor on ``‖r‖`` relative to the
        force scale.
    polish : bool, optional
        Finish ADR increments that stall with Newton from ADR's iterate
        (:func:`~pdlin.solvers.adr_step`'s ``polish``, with this call's Newton options):
        when the best ``‖r‖`` of the last ``adr_stall`` iterations is not below half the
        best before them, and when the budget runs out.  A converged try ends the
        increment at Newton's residual criterion ``rtol`` (``result.polishes`` counts
        its iterations, ``e1``/``e2`` are NaN); a failed one costs its Newton iterations
        and ADR goes on unchanged.  Default (None): on with ``method='auto'``, off with
        ``'adr'`` (ADR alone, the method of Luo, Ramazani & Sundararaghavan 2017).
        ADR's damped dynamics can stall just
        above its criteria near an equilibrium Newton reaches in 2 iterations
        (docs/nonlinear.md: step 30 of the 10⁵-point run).
    adr_stall : int, optional
        The stall window of ``polish`` in ADR iterations (default: an eighth of the ADR
        budget, at least 500).
    homogenize : index array or mask, optional
        Points of the volume average (default all), e.g. the real points of a
        ghost-layer problem.
    keep_states : bool
        Keep the committed state of every step (else only the last); the checkpoint then
        keeps them too, so that a resumed run returns every step's state.
    checkpoint : path, optional
        NPZ file written atomically after every converged step (a failed write, e.g. on a
        full disk, raises :class:`~pdlin.errors.CheckpointWriteError` naming the file and
        keeps the previous checkpoint).  It carries a fingerprint of the problem: SHA-256
        digests of the points, the bonds (horizon, influence), the model and material
        parameters (orientations included), the homogenized points, each committed step's
        prescribed values and loads, and the solver options that change the iterates.
        Its folder must exist.
    resume : {False, True, 'branch'}
        True: continue an existing ``checkpoint`` from its last committed step; it must
        have been written for this problem with these solver options, and its step times
        must be the first ones of this run (a finished run can be extended with more
        steps).  'branch': the same, but the solver options may differ (another driver or
        tolerance from a committed state, e.g. a copy of the checkpoint).  Without a
        checkpoint file the run says so (``progress``) and starts from step 1.
    progress : callable, optional
        Called with one line per step, one per failed increment (why, and the time it
        is cut back to) and, during an increment, one line every ``progress_every``
        seconds (ADR: iteration, e₁, e₂, damping, residual; Newton: iteration, residual,
        step length); a Newton iteration's linear solve also reports its iterations and
        residual every ``pdlin._progress.PROGRESS_EVERY`` seconds.
    progress_every : float
        Seconds between the in-step progress lines (default 60; a 10⁵-particle plastic
        step runs ≈ 30,000 ADR iterations in ≈ 6 min, a failing Newton try there ≈ 1.5
        min).
    snapshot_every : float
        With ``checkpoint``: seconds between snapshots of a running ADR increment (its
        iterates, damping and histories; default 300, checked every 64 iterations; 0:
        every 64 iterations), one per increment the step tried, written atomically next
        to the checkpoint (``run.npz`` -> ``run.adr.npz``, ≈ 5 MB per increment at 10⁵
        points) and removed when the load step commits.  A resumed run that reaches the
        same increment again (same target time, start displacement, committed state and
        density) continues its ADR iteration from the snapshot, bit for bit as if
        uninterrupted (a whole step that failed fails again within a snapshot interval,
        the half it was cut back to goes on), instead of from its start: a killed
        10⁵-particle run loses at most ``snapshot_every`` seconds of a step that takes
        10-40 min.  The step's wall time adds the killed run's up to its last snapshot.

    Returns
    -------
    NonlinearResult

    Raises
    ------
    InputError
        An option is out of range (``method``, ``steps``, ``times``, ``rtol``, ``e_l``,
        ``density``, ``dt``, ``damping``, ``c0``, ``adr_maxiter``, ``checkpoint``, ...).
    CheckpointError
        ``resume``: the checkpoint is unreadable (truncated, not an NPZ file), was written
        by a pdlin without a fingerprint, or for another problem (the message names the
        parts that differ).
    CheckpointWriteError
        Writing the checkpoint or an ADR snapshot failed (an ``OSError``: a full disk, ...).
    ConvergenceError
        A step fails with the chosen method (with 'auto': Newton and ADR).

    Examples
    --------
    A bond-based bar pulled in 4 steps: from the last solution Newton
    converges in one iteration per step (the default tangent predictor would
    be exact here, a linear model), and ADR reaches the same solution.

    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((20,), spacing=0.05)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.1,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3)])
    >>> res = pdlin.solve_nonlinear(prob, steps=4, method="newton", predictor="previous")
    >>> res.iterations.tolist(), res.u.shape
    ([1, 1, 1, 1], (4, 20, 1))
    >>> adr = pdlin.solve_nonlinear(prob, steps=1, method="adr", e_l=1e-10)
    >>> bool(np.abs(adr.u[-1] - res.u[-1]).max() < 1e-9)
    True
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    if problem.thermal is not None:  # the eigenstrain load is linear (pdlin.models.thermal)
        raise InputError(
            "solve_nonlinear does not take thermal loads (problem.thermal); "
            "solve them with pdlin.solve"
        )
    kw = dict(locals())
    adr_maxiter = check_keywords(kw)
    t_start = time.perf_counter()
    tt = step_times(steps, t_end, times)
    te = 1.0 if t_end is None else float(t_end)
    system = constrained_system(problem)
    pred = make_predictor(system, predictor, linear_solver)
    state0 = system.initial_state()
    hom_w = homogenize_weights(system, homogenize)
    lam, adr_dt = resolve_density(system.ndof, method, density, dt)
    budget = (
        int(adr_maxiter)
        if adr_maxiter is not None
        else 200 * math.ceil(system.n ** (1.0 / system.dim)) + 2000
    )
    polish_on = (method == "auto") if polish is None else polish
    newton = NewtonOptions(
        rtol=rtol,
        maxiter=maxiter,
        line_search=line_search,
        linear_solver=linear_solver,
        relax=relax,
        forcing=forcing,
        globalization=globalization,
    )
    adr = ADROptions(
        e_l=e_l,
        density=lam,
        density_safety=density_safety,
        dt=adr_dt,
        damping=damping,
        c0=c0,
        maxiter=budget,
        floor=floor,
        stall=int(adr_stall) if adr_stall is not None else max(500, budget // 8),
    )
    control = StepControl(
        method=method,
        predictor=predictor,
        max_cutbacks=max_cutbacks,
        fallback_cutbacks=fallback_cutbacks,
        newton_backoff=newton_backoff,
        polish=polish_on,
    )
    ckpt = None if checkpoint is None else Path(checkpoint)
    fp = (
        {} if ckpt is None else problem_fingerprint(system, hom_w, control.fingerprint(newton, adr))
    )
    run = LoadStepper(
        system, tt, te, control, newton, adr, pred, state0, hom_w, keep_states, ckpt, fp,
        progress, progress_every, snapshot_every,
    )  # fmt: skip
    if resume:
        run.resume(branch=resume == "branch")
    timings: dict[str, Any] = {"setup": time.perf_counter() - t_start}
    for k in range(run.start, tt.size):
        run.step(k)
    cols = history_arrays(run.records)
    return NonlinearResult.from_run(
        problem, run, tt, te, timings, t_start, cols, resumed_from=run.start
    )
