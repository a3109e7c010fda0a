"""Quasi-static stretch damage: load steps, bond breaking and re-solves.

The stretch criterion of Liu, Chen & Skelton, XOSB (§5.3, Eq. 88), used quasi-statically.

:func:`~pdlin.solve_damage` drives a linear :class:`~pdlin.StaticProblem` through proportional
load steps ``t_k = k / steps`` (every prescribed displacement and load scaled by ``t``).
For a fixed set of bonds the response is linear, ``u(t) = t u(1)``, so each bond set is
solved once; at every step the bonds stretched beyond the critical stretch ``s0``
(:func:`pdlin.models.break_bonds`) are removed and the step is solved again until no bond
breaks (sequentially linear analysis).  Breaking is irreversible.
"""

from __future__ import annotations

import dataclasses
import logging
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ._progress import linear_progress
from ._repr import compact_repr, html_table
from ._validation import integer
from .errors import InputError, InputTypeError, SlowRunWarning
from .geometry.bonds import Bonds
from .models.damage import bond_stretch, break_bonds, damage_index, isolated_points
from .problem import StaticProblem
from .static import solve
from .system import StaticResult

__all__ = ["DamageResult", "solve_damage"]

log = logging.getLogger(__name__)


@dataclass
class DamageResult:
    """Per-step history of :func:`~pdlin.solve_damage`.

    Attributes
    ----------
    factors : (k,) ndarray
        Load factor ``t`` of each completed step.
    u : (k, n, dim) ndarray
        Displacement at the end of each step (after its last re-solve).
    damage : (k, n) ndarray
        Damage index ``phi`` (:func:`pdlin.models.damage_index`) after each step.
    broken : (k,) ndarray of int
        Cumulative number of broken directed bonds after each step.
    max_stretch : (k,) ndarray
        Largest bond stretch of the intact bonds at each step before breaking.
    resolves : (k,) ndarray of int
        Linear solves per step (1 + the re-solves after breaking).
    first_break : float
        Load factor at which the first bond reaches ``s0``: ``t s0 / s_max`` on the
        last step before any bond broke (the response is linear until then); NaN when
        no bond broke.
    stopped : str
        Empty, or why the stepping stopped early (a point lost all its bonds).
    final : StaticResult
        The last unit-load solve (its ``bonds`` are the surviving bonds).
    """

    factors: np.ndarray
    u: np.ndarray
    damage: np.ndarray
    broken: np.ndarray
    max_stretch: np.ndarray
    resolves: np.ndarray
    first_break: float
    stopped: str
    final: StaticResult
    s0: float
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        """Number of load steps stored."""
        return int(self.factors.size)

    def __repr__(self) -> str:
        """Return steps, broken bonds and damage (no arrays, no memory address)."""
        items = {k: v for k, v in self.summary().items() if k != "timings"}
        return compact_repr("DamageResult", {**items, "stopped": items["stopped"] or None})

    def _repr_html_(self) -> str:
        """Return the summary as an HTML table (Jupyter)."""
        rows = [(k.replace("_", " "), v) for k, v in self.summary().items() if k != "timings"]
        return html_table("DamageResult", rows)

    def summary(self) -> dict[str, Any]:
        """Return a plain-data summary (for the CLI).

        Returns
        -------
        dict
            ``steps``, ``points``, ``dim``, ``critical_stretch``, ``broken_bonds`` (after
            the last step), ``max_damage``, ``first_break_load`` (load factor of the
            first break, or None), ``linear_solves``, ``stopped`` (reason or None) and
            ``timings`` (seconds per phase, rounded).
        """
        return {
            "steps": self.n_steps,
            "points": int(self.u.shape[1]),
            "dim": int(self.u.shape[2]),
            "critical_stretch": self.s0,
            "broken_bonds": int(self.broken[-1]) if self.n_steps else 0,
            "max_damage": float(self.damage[-1].max()) if self.n_steps else 0.0,
            "first_break_load": self.first_break,
            "linear_solves": int(self.resolves.sum()),
            "stopped": self.stopped,
            "timings": {k: round(v, 4) for k, v in self.timings.items()},
        }


def _check_damage_history(n: int, dim: int, steps: int) -> None:
    """Refuse a step count whose stored history does not fit in memory.

    The history is u and damage per step, kept twice while the result arrays are built.
    """
    from .resources import LONG_RUN_SECONDS, available_memory, check_memory

    per_step = 2 * 8 * n * (dim + 1) + 64

    def hints() -> list[str]:
        fit = max(int(available_memory().bytes / per_step * 0.5), 1)
        return [f"at most ~{fit:,} steps (each stores u and the damage of {n:,} points)"]

    check_memory(f"damage history of {steps:,} load steps", float(per_step) * steps, hints)
    # each step is at least one pass over the bonds and a few array operations
    secs = steps * (DAMAGE_STEP_SECONDS + DAMAGE_STEP_SECONDS_PER_POINT * n)
    if secs > LONG_RUN_SECONDS:
        warnings.warn(
            f"damage.steps = {steps:,}: the load steps alone are estimated to take "
            f"~{secs / 60:,.0f} min ({n:,} points); fewer steps are faster",
            SlowRunWarning,
            stacklevel=3,
        )


#: seconds of one damage load step without re-solves: fixed cost and per point (measured
#: order of magnitude: the 2,000-point damage_plate example, ~1 ms per step)
DAMAGE_STEP_SECONDS = 2e-4
DAMAGE_STEP_SECONDS_PER_POINT = 4e-7


def solve_damage(
    problem: StaticProblem,
    s0: Any,
    *,
    steps: int = 10,
    max_resolves: int = 50,
    solver: str = "auto",
    rtol: float = 1e-10,
    progress: Callable[[str], None] | None = None,
) -> DamageResult:
    """Apply proportional load steps with irreversible stretch-based bond breaking.

    Parameters
    ----------
    problem : StaticProblem
        The problem at full load (``t = 1``); no symmetry planes (mirrored bonds would
        break differently from their images).
    s0 : float or (n_bonds,) array_like
        Critical stretch (:func:`pdlin.models.critical_stretch`), per bond of the problem's
        intact bonds or one value.
    steps : int
        Equal load steps up to ``t = 1``.
    max_resolves : int
        Re-solves allowed per step before breaking is declared not to settle.
    solver, rtol
        As in :func:`pdlin.solve`.
    progress : callable, optional
        Called with a message per step, and with the iterations and residual of a
        linear solve that takes longer than ``pdlin._progress.PROGRESS_EVERY``
        seconds (``pdlin._progress.linear_progress``).

    Returns
    -------
    DamageResult
        Per-step displacements, damage, broken-bond counts and the last solve.

    Raises
    ------
    InputError
        For bad ``steps`` / ``s0``, symmetry planes, or breaking that does not settle
        within ``max_resolves`` solves of one step.

    Examples
    --------
    A 2D bond-based plate held on every face by the affine field of 1 % stretch along
    x: every bond along x stretches by ``t * 0.01``, so with ``s0 = 0.0045`` the first
    bond breaks at ``t = 0.45``.

    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((12, 12), spacing=0.1)
    >>> bc, _ = pdlin.shadow_layer(cloud, np.diag([1.01, 1.0]), 0.31)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud,
    ...     bond_options={"ratio": 3.015}, dirichlet=[bc])
    >>> res = pdlin.solve_damage(prob, 0.0045, steps=5)
    >>> round(res.first_break, 6), bool(res.broken[-1] > 0), res.broken[:2].tolist()
    (0.45, True, [0, 0])
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    if problem.thermal is not None:  # the eigenstrain load is linear (pdlin.models.thermal)
        raise InputError(
            "solve_damage does not take thermal loads (problem.thermal); "
            "solve them with pdlin.solve"
        )
    if problem.symmetry:
        raise InputError(
            "solve_damage does not support symmetry planes (bonds across a plane would "
            "break independently of their images); model the full body"
        )
    steps = integer(steps, "steps", minimum=1)
    max_resolves = integer(max_resolves, "max_resolves", minimum=1)
    say = progress or (lambda msg: None)
    _check_damage_history(problem.cloud.n, problem.cloud.dim, steps)
    t_start = time.perf_counter()
    intact: Bonds = problem.get_bonds()
    crit = np.asarray(s0, dtype=float)
    if crit.ndim not in (0, 1) or (crit.ndim == 1 and crit.shape != (intact.n_bonds,)):
        raise InputError(
            f"s0 must be a number or one value per bond ({intact.n_bonds}), got shape {crit.shape}"
        )
    if not np.all(np.isfinite(crit)) or np.any(crit <= 0):
        raise InputError(f"s0 must be finite and > 0, got min {float(crit.min())}")
    # per-bond thresholds follow the surviving bonds through (i, j) keys
    n = problem.cloud.n
    key0 = intact.i.astype(np.int64) * n + intact.j
    order0 = np.argsort(key0)

    def s0_of(b: Bonds) -> Any:
        if crit.ndim == 0:
            return float(crit)
        k = b.i.astype(np.int64) * n + b.j
        return crit[order0[np.searchsorted(key0, k, sorter=order0)]]

    bonds = intact
    unit = solve(
        dataclasses.replace(problem, bonds=bonds),
        solver=solver,
        rtol=rtol,
        progress=None if progress is None else linear_progress(say, "  unit-load solve"),
    )
    factors, us, dmg, broken, smax, nsol = [], [], [], [], [], []
    first_break = np.nan
    t_prev_crit = np.nan
    stopped = ""
    total_broken = 0
    for k in range(1, steps + 1):
        t = k / steps
        say(f"load step {k}/{steps} (t = {t:.4g})")
        solves = 0
        s_now = bond_stretch(problem.cloud, bonds, t * unit.u)
        s_before = float(s_now.max(initial=0.0))
        pos = s_now > 0
        # load factor at which the first bond of this bond set reaches s0 (linear response)
        t_crit = (
            t * float(np.min(np.broadcast_to(s0_of(bonds), s_now.shape)[pos] / s_now[pos]))
            if pos.any()
            else np.nan
        )
        while True:
            u = t * unit.u
            new, nb = break_bonds(problem.cloud, bonds, u, s0_of(bonds))
            if nb == 0:
                break
            if np.isnan(first_break):
                # the intact response is linear in t: the previous step (or this one)
                # scales to the first bond reaching s0
                first_break = t_prev_crit if k > 1 else t_crit
            total_broken += nb
            bonds = new
            if isolated_points(bonds).size:
                stopped = (
                    f"step {k}: {isolated_points(bonds).size} point(s) lost all their bonds "
                    "(the body separated); stepping stopped"
                )
                break
            solves += 1
            if solves > max_resolves:
                raise InputError(
                    f"bond breaking did not settle within max_resolves = {max_resolves} "
                    f"solves at load step {k} (t = {t:g})"
                )
            unit = solve(
                dataclasses.replace(problem, bonds=bonds),
                solver=solver,
                rtol=rtol,
                progress=None
                if progress is None
                else linear_progress(say, f"  step {k}, re-solve {solves}"),
            )
        t_prev_crit = t_crit
        factors.append(t)
        us.append(t * unit.u)
        dmg.append(damage_index(intact, bonds))
        broken.append(total_broken)
        smax.append(s_before)
        nsol.append(solves + (1 if k == 1 else 0))
        if stopped:
            log.warning(stopped)
            break
    return DamageResult(
        factors=np.asarray(factors),
        u=np.asarray(us),
        damage=np.asarray(dmg),
        broken=np.asarray(broken, dtype=np.int64),
        max_stretch=np.asarray(smax),
        resolves=np.asarray(nsol, dtype=np.int64),
        first_break=float(first_break),
        stopped=stopped,
        final=unit,
        s0=float(np.min(crit)),
        timings={"total": time.perf_counter() - t_start},
    )
