"""Nonlinear static solves of the crystal-plasticity polycrystal (cost, accuracy, damping).

``pdlin.solve_nonlinear`` on the 21-grain Voronoi polycrystal of Luo, Ramazani &
Sundararaghavan (2017), Sec. 4 (the paper's grains are not given: a seeded map
``voronoi_polycrystal(cloud, 21, seed=1)``, planar-2 crystal plasticity,
``Correspondence(material=...)``, δ = h, n x n pixel grid, boundary ring prescribed by
``Dirichlet.velocity_gradient``, η = 0.002, 30 load steps of Δt = 1). Tables (wall-clock
seconds on a shared machine, one BLAS thread; nothing is asserted):

1. **B1 cost** (the timing split of the paper's Fig. 7): per size, load (pure shear,
   Y-compression) and method: wall time of load steps 1-7 and 8-30, iterations (Newton
   iterations or ADR iterations), constitutive calls,
   cut-backs, ADR fallbacks (``auto``), peak RSS of the run's child process and the plastic
   fraction. Methods: ``newton``; ``adr-spec`` (the paper's Λ = 1, Eq. 12: ``density=h²``,
   ``dt=h sqrt(1/2000)``, pdlin forces are nodal V·L); ``adr`` (default Gershgorin
   density); ``auto`` (Newton, ADR fallback). A run that exceeds ``--budget`` seconds is
   stopped after its current step and the remaining steps are extrapolated from the mean
   time of its completed steps of the same range (marked ``*``).
2. **Aim** (issue): "2,500 particles, 30 steps under 60 s on one core with either method;
   Newton elastic steps in one iteration", from table 1, and a cProfile split of one Newton
   and one ADR run (respond = constitutive update + tangent assembly + nodal force, linear
   solve, Dirichlet elimination, predictor, ADR density).
3. **10⁵ particles** (316 x 316): ``--big-method`` (Newton by default; ``auto`` for the
   end-to-end run) for the first ``--big-steps`` load steps, optionally with a checkpoint
   that a later run resumes (``--big-checkpoint PATH``: a killed run loses no committed step).
4. **B2 accuracy-cost** (ADR tolerance against error): ADR with e_l in ``--e-l`` from the
   committed state of a tight Newton reference (rtol 1e-12, ``checkpoint=`` +
   ``resume=True``), homogenized-stress error
   against Newton's next step (never pointwise: plastic equilibria of this nearly perfectly
   plastic crystal are not unique), for an elastic and a plastic step.
5. **T20** (the paper's Fig. 6 comparison with c = 500): adaptive ADR damping vs constant
   c = 200, 500, 2000 on 25 x 25 shear steps 1-12:
   iterations per step, max damping in the first and last 10 % of each step's iterations.
6. **Predictors** (``--sections predictors``, only on request): ``method='auto'`` with each
   of ``--predictors``: time, Newton iterations, cut-backs, ADR fallbacks and the largest
   homogenized-stress difference to a fine path (``--fine`` equal increments per step).
7. **Damping in plastic steps** (``--sections damping``, only on request): from ADR's
   committed step ``--damping-from`` of the ``--damping-size`` polycrystal (control
   ``--damping-control``, default ``penalty:0.1`` as the 10⁵ run), ``--damping-steps``
   further ADR steps with the adaptive damping and with each constant c of
   ``--damping-values``: iterations and homogenized σ_xy per step, the median c and the
   share of c = 0; c also relative to ``2 sqrt(λ_min(Λ⁻¹K_e))``, the critical damping of the
   lowest elastic mode (shift-invert Lanczos on the elastic tangent).
8. **Newton polish** (``--sections polish``, only on request): each of ``--methods`` on
   ``--sizes`` x ``--loads`` with ``polish=False`` and ``polish=True`` (default stall
   window): time, iterations, Newton polish iterations, steps polished, cut-backs and the
   largest homogenized-stress difference between the two.

9. **Newton's linear solver and globalization** (``--sections krylov``, only on request):
   on ``--krylov-size`` (default 100: 10⁴ particles), shear, control ``--krylov-control``,
   ``--krylov-steps`` load steps, each of ``--krylov-methods``: direct LU with line search
   (the old path), ``linear_solver='krylov'`` (GMRES, one AMG hierarchy of the symmetrized
   elastic tangent per run) with a fixed tolerance and with Eisenstat-Walker forcing, and
   pseudo-transient continuation (``globalization='ptc'``, ADR density as the shift):
   steps passed, Newton iterations (linear solves), GMRES iterations, cut-backs, ADR
   fallbacks, wall / CPU seconds, peak RSS.

10. **The goal** (``--sections goal``, only on request): the ``--goal-size`` (316: 10⁵)
    polycrystal, 30 shear steps, for each of ``--goal-rates`` (power-law exponent of
    ``CrystalPlasticity(rate_exponent=...)`` with the applied rate as reference rate, or
    ``none``: rate independent) x ``--goal-controls`` x ``--goal-methods``, each run
    stopped after ``--goal-budget`` seconds (30 min): steps done, wall / CPU s, iterations,
    cut-backs, ADR fallbacks, peak RSS, last σ_xy and the zero-energy-mode measure.

Every run is a forked child process (its peak RSS is the run's); B1 gives its CPU seconds
beside the wall seconds, and the header the load average, usable cores and BLAS threads.
``--quick`` (the default when no size is given) runs 15 x 15 and 25 x 25 only, about 2
minutes.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import cProfile  # noqa: E402
import pstats  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import fork_call, header  # noqa: E402

import pdlin  # noqa: E402

ETA = 0.002
LOADS = {"shear": [[0.0, 1.0], [1.0, 0.0]], "compression": [[1.0, 0.0], [0.0, -1.0]]}
METHODS = ("newton", "adr-spec", "adr", "auto")
SPLIT = 7  # steps 1-7 / 8-30 (Luo, Ramazani & Sundararaghavan 2017, Fig. 7)


class _Stop(Exception):
    """Raised from the progress callback when a run exceeds its time budget."""


def correspondence(material: Any, control: str = "none") -> Any:
    """``Correspondence(material=material, control=...)`` from a control spec: a control
    name, or ``"penalty:C"`` for the penalty at coefficient C."""
    name, _, coef = control.partition(":")
    kw: dict[str, Any] = {"penalty": float(coef)} if coef else {}
    return pdlin.Correspondence(material=material, control=name, **kw)


def problem(
    n: int, load: str, control: str = "none", rate: float | None = None
) -> tuple[Any, float]:
    """Build the 21-grain polycrystal on n x n particles.

    ``control`` is a spec of :func:`correspondence` (default: none, as in Luo, Ramazani &
    Sundararaghavan 2017). ``rate``: the power-law exponent of the rate-dependent
    regularization (``CrystalPlasticity(rate_exponent=rate, reference_rate=ETA)``: the
    reference slip rate is the applied strain rate, η per unit time); None: the paper's
    rate-independent model.
    """
    h = 1.0 / n
    cloud = pdlin.grid((n, n), spacing=h)
    bonds = pdlin.find_bonds(cloud, ratio=1.0, influence="constant")
    _, theta = pdlin.voronoi_polycrystal(cloud, 21, seed=1)
    kw: dict[str, Any] = {} if rate is None else {"rate_exponent": rate, "reference_rate": ETA}
    model = correspondence(pdlin.CrystalPlasticity("planar-2", orientation=theta, **kw), control)
    L = ETA * np.array(LOADS[load])
    bc = pdlin.Dirichlet.velocity_gradient("boundary", L)
    return pdlin.StaticProblem(model, cloud, bonds, dirichlet=[bc]), h


def options(method: str, h: float) -> dict[str, Any]:
    if method == "adr-spec":
        return {"method": "adr", "density": h * h, "dt": h * np.sqrt(1.0 / 2000.0)}
    return {"method": method}


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run(
    n: int,
    load: str,
    method: str,
    steps: int,
    budget: float,
    *,
    extra: dict[str, Any] | None = None,
    profile: bool = False,
    control: str = "none",
    rate: float | None = None,
    verbose: bool = False,
    hard_budget: bool = False,
) -> dict[str, Any]:
    """One solve_nonlinear run (in the calling process); stops after ``budget`` s.

    At the end of the first step past the budget, or with ``hard_budget`` inside the running
    step (its in-step progress messages come every 10 s; the step is not committed).
    """
    prob, h = problem(n, load, control, rate)
    kw = options(method, h)
    kw.update(extra or {})
    tmp = Path(tempfile.mkdtemp(prefix="bench_nl_"))
    ckpt = tmp / "run.npz"
    stamps: list[float] = []
    t0 = time.perf_counter()
    c0 = time.process_time()

    def progress(msg: str) -> None:
        if verbose and msg.startswith("step "):
            print(f"    {msg} (RSS {_peak_mb():.0f} MB)", flush=True)
        if msg.startswith("step "):
            stamps.append(time.perf_counter())
            if stamps[-1] - t0 > budget and len(stamps) < steps:
                raise _Stop
        elif hard_budget and time.perf_counter() - t0 > budget:
            raise _Stop  # inside a step (in-step progress every 10 s): the step is lost

    prof = cProfile.Profile() if profile else None
    out: dict[str, Any] = {"n": n * n, "load": load, "method": method}
    res = None
    try:
        if prof is not None:
            prof.enable()
        res = pdlin.solve_nonlinear(
            prob,
            steps=steps,
            t_end=float(steps),
            checkpoint=ckpt,
            progress=progress,
            progress_every=10.0 if hard_budget else 60.0,
            keep_states=False,
            **kw,
        )
    except _Stop:
        pass
    except pdlin.errors.ConvergenceError as exc:
        out["failed"] = str(exc).split(":")[0]
    finally:
        if prof is not None:
            prof.disable()
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    if not ckpt.exists():
        raise pdlin.errors.ConvergenceError(out.get("failed", "no step converged"))
    data = np.load(ckpt, allow_pickle=False)
    done = int(data["done"])
    if res is not None:
        st = np.asarray(res.timings["steps"], dtype=float)
        plastic = np.asarray(res.state.get("plastic", np.zeros(1)), dtype=bool)
    else:  # stopped by the budget or failed: times from the progress callback
        st = np.diff(np.concatenate([[t0], stamps]))[:done]
        plastic = np.asarray(data["state__plastic"], dtype=bool)
    out.update(
        done=done,
        steps=steps,
        wall=wall,
        cpu=cpu,
        step_times=st,
        iterations=np.asarray(data["iterations"]),
        calls=np.asarray(data["calls"]),
        cutbacks=np.asarray(data["cutbacks"]),
        methods=[str(m) for m in data["methods"]],
        polishes=np.asarray(data["polishes"]) if "polishes" in data else np.zeros(done, int),
        hom=np.asarray(data["homogenized_stress"]),
        plastic=float(plastic.mean()),
        peak_mb=_peak_mb(),
        hf=(
            high_frequency(np.asarray(data["u"][done - 1]).reshape(-1, 2), prob.cloud.points, n, h)
            if done
            else np.zeros(1)
        ),
    )
    if prof is not None:
        out["profile"] = profile_split(prof, wall)
    shutil.rmtree(tmp, ignore_errors=True)
    return out


def high_frequency(u: np.ndarray, points: np.ndarray, n: int, h: float) -> np.ndarray:
    """``|u_i - mean of the four grid neighbours| / h`` at the interior points of the grid.

    The zero-energy-mode measure of benchmarks/README.md: a smooth field gives
    O(h · strain gradient); the correspondence model's uncontrolled modes give O(strain) and
    more.
    """
    ij = np.rint((points - points.min(axis=0)) / h).astype(int)
    grid = np.zeros((n, n, u.shape[1]))
    grid[ij[:, 0], ij[:, 1]] = u
    avg = 0.25 * (grid[2:, 1:-1] + grid[:-2, 1:-1] + grid[1:-1, 2:] + grid[1:-1, :-2])
    return np.asarray(np.linalg.norm(grid[1:-1, 1:-1] - avg, axis=2).ravel() / h)


#: ``fn(*args, **kw)`` in a forked child (its own peak RSS); errors come back as str
forked = fork_call


# ---------------------------------------------------------------------------------------
# profile split


PROFILE_KEYS = (
    ("constitutive update", "crystal_plasticity.py", "update"),
    ("tangent assembly", "correspondence.py", "tangent_matrix"),
    ("nodal force", "correspondence.py", "nodal_force"),
    ("respond (total)", "correspondence.py", "respond"),
    ("linear solve", "linear.py", "solve_linear"),
    ("Dirichlet elimination", "bc.py", "eliminate_dirichlet"),
    ("predictor", "nonlinear.py", "__call__"),
    ("ADR density", "nonlinear.py", "adr_density"),
)


def profile_split(prof: cProfile.Profile, wall: float) -> list[tuple[str, float, int]]:
    stats = pstats.Stats(prof)
    raw: dict[Any, Any] = stats.stats  # type: ignore[attr-defined]
    rows = []
    for label, fname, func in PROFILE_KEYS:
        ct, nc = 0.0, 0
        for (path, _line, name), (_cc, ncalls, _tt, cum, _callers) in raw.items():
            if name == func and path.endswith(fname):
                ct += cum
                nc += ncalls
        rows.append((label, ct, nc))
    rows.append(("profiled wall", wall, 1))
    return rows


# ---------------------------------------------------------------------------------------
# tables


def _fmt_t(x: float, est: bool) -> str:
    return f"{x:.2f}{'*' if est else ''}"


def split_times(r: dict[str, Any]) -> tuple[float, bool, float, bool, float]:
    """Steps 1-7 and 8-30 wall times (extrapolated from the mean of done steps if stopped)."""
    st, done, steps = r["step_times"], r["done"], r["steps"]
    parts = []
    for lo, hi in ((0, min(SPLIT, steps)), (min(SPLIT, steps), steps)):
        have = st[lo : min(hi, done)]
        missing = hi - max(lo, min(hi, done))
        if missing <= 0:
            parts.append((float(have.sum()), False))
        elif have.size:
            parts.append((float(have.sum() + missing * have.mean()), True))
        else:
            parts.append((float("nan"), True))
    return parts[0][0], parts[0][1], parts[1][0], parts[1][1], parts[0][0] + parts[1][0]


def _print_head(head: str) -> None:
    """A Markdown table's header row and its separator."""
    print(head)
    print("|" + "---|" * (head.count("|") - 1))


def table_b1(
    sizes: list[int], loads: list[str], methods: list[str], steps: int, budget: float
) -> list[dict[str, Any]]:
    print(f"\n## B1: cost per size, load and method ({steps} load steps; * = extrapolated)\n")
    head = (
        "| particles | load | method | steps done | t 1-7 s | t 8-30 s | total s | wall / CPU s "
        "run | it 1-7 | "
        "it 8-30 | it max | calls | cut-backs | fallbacks | peak RSS MB | plastic |"
    )
    _print_head(head)
    rows = []
    for n in sizes:
        for load in loads:
            for m in methods:
                r = forked(run, n, load, m, steps, budget)
                if isinstance(r, str):
                    print(f"| {n * n:,} | {load} | {m} | failed: {r} |")
                    continue
                a, ae, b, be, tot = split_times(r)
                done = f"{r['done']}/{steps}" + (f" ({r['failed']})" if "failed" in r else "")
                it = r["iterations"]
                fb = sum("failed" in s for s in r["methods"])
                print(
                    f"| {n * n:,} | {load} | {m} | {done} | {_fmt_t(a, ae)} | "
                    f"{_fmt_t(b, be)} | {_fmt_t(tot, ae or be)} | "
                    f"{r['wall']:.2f} / {r['cpu']:.2f} | {int(it[:SPLIT].sum())} | "
                    f"{int(it[SPLIT:].sum())} | {int(it.max())} | {int(r['calls'].sum()):,} | "
                    f"{int(r['cutbacks'].sum())} | {fb} | {r['peak_mb']:.0f} | "
                    f"{r['plastic']:.2f} |",
                    flush=True,
                )
                rows.append(r)
    return rows


def table_aim(rows: list[dict[str, Any]], n_aim: int) -> None:
    print(f"\n## Aim: {n_aim * n_aim:,} particles, 30 steps < 60 s on one core\n")
    print("| load | method | total s | aim met | Newton it steps 1, 2 |")
    print("|---|---|---|---|---|")
    for r in rows:
        if r["n"] != n_aim * n_aim:
            continue
        tot = split_times(r)[4]
        est = r["done"] < r["steps"]
        its = r["iterations"][:2].tolist() if r["method"] in ("newton", "auto") else "-"
        met = "yes" if tot < 60 else "no"
        print(f"| {r['load']} | {r['method']} | {_fmt_t(tot, est)} | {met} | {its} |")


def table_predictors(
    sizes: list[int], loads: list[str], predictors: list[str], steps: int, sub: int
) -> None:
    """Newton's predictors (``method='auto'``): cost, and the homogenized stress against a
    fine path (``sub`` equal Newton increments per load step, the committed-state tangent
    predictor); the fine path with the default predictor gives the floor of that error
    (plastic equilibria are not unique, and the path of a path-dependent material depends
    on its increments)."""
    print(
        f"\n## Predictors: method='auto', {steps} load steps; homogenized σ against a fine "
        f"path ({sub} increments per step)\n"
    )
    head = (
        "| particles | load | predictor | total s | Newton it | it max | cut-backs | "
        "fallbacks | max ‖Δσ̄‖ / max ‖σ̄‖ vs fine path |"
    )
    _print_head(head)
    fine_times = np.arange(1, steps * sub + 1) / sub
    for n in sizes:
        for load in loads:
            ref = forked(
                run,
                n,
                load,
                "auto",
                steps,
                1e9,
                extra={"predictor": "committed-tangent", "times": fine_times},
            )
            if isinstance(ref, str):
                print(f"| {n * n:,} | {load} | fine path failed: {ref} |")
                continue
            ref_hom = ref["hom"][sub - 1 :: sub]
            scale = float(np.abs(ref_hom).max())
            cases = [(f"fine: {sub} x, tangent", {"predictor": "tangent", "times": fine_times})]
            cases += [(p, {"predictor": p}) for p in predictors]
            for label, extra in cases:
                r = forked(run, n, load, "auto", steps, 1e9, extra=extra)
                if isinstance(r, str):
                    print(f"| {n * n:,} | {load} | {label} | failed: {r} |")
                    continue
                hom = r["hom"][sub - 1 :: sub] if "times" in extra else r["hom"]
                err = float(np.abs(hom - ref_hom).max()) / scale
                fb = sum("failed" in m for m in r["methods"])
                it = r["iterations"]
                print(
                    f"| {n * n:,} | {load} | {label} | {r['wall']:.1f} | {int(it.sum())} | "
                    f"{int(it.max())} | {int(r['cutbacks'].sum())} | {fb} | {err:.1e} |",
                    flush=True,
                )


def table_profile(n: int, load: str, methods: list[str], steps: int, budget: float) -> None:
    print(f"\n## Profile: {n * n:,} particles, {load}, cProfile cumulative seconds\n")
    for m in methods:
        r = forked(run, n, load, m, steps, budget, profile=True)
        if isinstance(r, str):
            print(f"{m}: failed: {r}")
            continue
        it = int(r["iterations"].sum())
        print(f"{m}: {r['done']} steps, {it} iterations, wall (profiled) {r['wall']:.1f} s")
        print("\n| part | s | share | calls |")
        print("|---|---|---|---|")
        for label, ct, nc in r["profile"]:
            print(f"| {label} | {ct:.2f} | {ct / r['wall']:.0%} | {nc} |")
        print()


def _big(
    n: int,
    steps: int,
    load: str,
    method: str = "newton",
    checkpoint: str | None = None,
    control: str = "none",
) -> dict[str, Any]:
    prob, _ = problem(n, load, control)
    t0 = time.perf_counter()
    resume = checkpoint is not None and Path(checkpoint).exists()
    res = pdlin.solve_nonlinear(
        prob,
        times=np.arange(1.0, steps + 1.0),
        t_end=30.0,
        method=method,
        checkpoint=checkpoint,
        resume=resume,
        keep_states=False,
        progress=lambda msg: print(f"    {msg} (RSS {_peak_mb():.0f} MB)", flush=True),
    )
    plastic = np.asarray(res.state.get("plastic", np.zeros(1)), dtype=bool)
    return {
        "setup": float(res.timings["setup"]),
        "step_times": np.asarray(res.timings["steps"]),
        "iterations": res.iterations,
        "calls": res.calls,
        "cutbacks": res.cutbacks,
        "plastic": float(plastic.mean()),
        "wall": time.perf_counter() - t0,
        "peak_mb": _peak_mb(),
        "hom": res.homogenized_stress,
        "methods": list(res.methods),
        "resumed_from": res.resumed_from,
    }


def table_big(n: int, steps: int, load: str, **opts: Any) -> None:
    """The table of :func:`_big` (its options ``method``, ``checkpoint``, ``control``)."""
    method, control = opts.get("method", "newton"), opts.get("control", "none")
    print(
        f"\n## 10⁵ feasibility: {n}² = {n * n:,} particles, {load}, {method}, control "
        f"{control}, steps 1-{steps}\n"
    )
    r = forked(_big, n, steps, load, **opts)
    if isinstance(r, str):
        print(f"failed: {r}")
        return
    print("| step | s | method | iterations | calls | cut-backs |")
    print("|---|---|---|---|---|---|")
    first = int(r["resumed_from"])  # steps before it came from the checkpoint (no times)
    for k in range(first, len(r["step_times"])):
        print(
            f"| {k + 1} | {r['step_times'][k]:.1f} | {r['methods'][k]} | "
            f"{int(r['iterations'][k])} | {int(r['calls'][k]):,} | {int(r['cutbacks'][k])} |"
        )
    print(
        f"\nsetup {r['setup']:.1f} s, wall {r['wall']:.1f} s, peak RSS {r['peak_mb']:.0f} MB, "
        f"plastic fraction after step {steps}: {r['plastic']:.2f}"
    )


# ---------------------------------------------------------------------------------------
# the issue's goal: the 10⁵ polycrystal end to end, one row per method x control x material


def _material_name(rate: float | None) -> str:
    return "rate-independent" if rate is None else f"power law n = {rate:g}"


def table_goal(
    n: int,
    methods: list[str],
    controls: list[str],
    rates: list[float | None],
    steps: int,
    budget: float,
) -> None:
    """The n² polycrystal in shear, ``steps`` load steps, per material, control and method.

    Each run is a forked child stopped once it has run ``budget`` s, inside a step if need
    be ("k/30 (budget)": k steps committed). Columns: steps done, wall and CPU
    seconds, Newton / ADR iterations, cut-backs, steps that fell back to ADR, peak RSS, the
    homogenized σ_xy of the last step done and the zero-energy-mode measure ``hf`` (median /
    99 % / max of |u_i − mean of its 4 neighbours| / h) of the last step done.
    """
    print(
        f"\n## Goal: {n}² = {n * n:,} particles, shear, {steps} steps, budget {budget:.0f} s "
        "per run\n"
    )
    head = (
        "| material | control | method | steps | wall s | CPU s | iterations | cut-backs | "
        "ADR fallbacks | peak RSS MB | σ_xy last (MPa) | hf median / 99 % / max |"
    )
    _print_head(head)
    for rate in rates:
        for control in controls:
            for m in methods:
                print(f"    {_material_name(rate)}, {control}, {m}:", flush=True)
                r = forked(
                    run,
                    n,
                    "shear",
                    m,
                    steps,
                    budget,
                    control=control,
                    rate=rate,
                    verbose=True,
                    hard_budget=True,
                )
                lead = f"| {_material_name(rate)} | {control} | {m} |"
                if isinstance(r, str):
                    print(f"{lead} failed: {r} |", flush=True)
                    continue
                done = int(r["done"])
                tag = "" if done == steps else " (budget)"
                if "failed" in r:
                    tag = f" (failed: {r['failed']})"
                hf = r["hf"]
                fb = sum(1 for x in r["methods"] if str(x).startswith("adr"))
                print(
                    f"{lead} {done}/{steps}{tag} | {r['wall']:.0f} | {r['cpu']:.0f} | "
                    f"{int(r['iterations'].sum()):,} | {int(r['cutbacks'].sum())} | "
                    f"{fb if m != 'adr' else '-'} | {r['peak_mb']:.0f} | "
                    f"{float(r['hom'][done - 1][0, 1]) if done else float('nan'):.3f} | "
                    f"{np.median(hf):.1e} / {np.quantile(hf, 0.99):.1e} / {hf.max():.2f} |",
                    flush=True,
                )


# ---------------------------------------------------------------------------------------
# Newton polish of stalled ADR increments: the same runs with polish off and on


def table_polish(sizes: list[int], loads: list[str], methods: list[str], steps: int) -> None:
    """``solve_nonlinear(polish=False)`` against ``polish=True`` (default window), the same
    problem, method and steps in one run: time, ADR iterations, polish iterations,
    cut-backs, and the largest difference of the homogenized σ_xy / σ_yy over the steps
    (relative to the polish-off run's largest |σ|)."""
    print(f"\n## Newton polish of stalled ADR increments ({steps} load steps)\n")
    head = (
        "| particles | load | method | polish | total s | iterations | polish its | "
        "steps polished | cut-backs | max rel. Δσ_hom |"
    )
    _print_head(head)
    for n in sizes:
        for load in loads:
            for m in methods:
                ref: dict[str, Any] | None = None
                for flag in (False, True):
                    r = forked(run, n, load, m, steps, float("inf"), extra={"polish": flag})
                    if isinstance(r, str):
                        print(f"| {n * n:,} | {load} | {m} | {flag} | failed: {r} |")
                        continue
                    if "failed" in r:
                        print(f"| {n * n:,} | {load} | {m} | {flag} | failed: {r['failed']} |")
                        continue
                    diff = "-"
                    if ref is None:
                        ref = r
                    else:
                        big = float(np.abs(ref["hom"]).max())
                        diff = f"{float(np.abs(r['hom'] - ref['hom']).max()) / big:.1e}"
                    pol = r["polishes"]
                    print(
                        f"| {n * n:,} | {load} | {m} | {flag} | {float(r['wall']):.1f} | "
                        f"{int(r['iterations'].sum()):,} | {int(pol.sum())} | "
                        f"{int(np.count_nonzero(pol))} | {int(r['cutbacks'].sum())} | {diff} |",
                        flush=True,
                    )


# ---------------------------------------------------------------------------------------
# Newton's linear solver (direct / AMG-GMRES with forcing) and globalization

#: the variants of the 'krylov' table: solve_nonlinear keywords
KRYLOV_METHODS: dict[str, dict[str, Any]] = {
    "newton-direct": {"method": "newton"},
    "newton-krylov": {"method": "newton", "linear_solver": "krylov"},
    "newton-krylov-ew": {
        "method": "newton",
        "linear_solver": "krylov",
        "forcing": "eisenstat-walker",
    },
    "ptc-krylov-ew": {
        "method": "newton",
        "linear_solver": "krylov",
        "forcing": "eisenstat-walker",
        "globalization": "ptc",
        "maxiter": 60,
    },
    "auto-direct": {"method": "auto"},
    "auto-krylov-ew": {"method": "auto", "linear_solver": "krylov", "forcing": "eisenstat-walker"},
}


def _krylov_run(n: int, steps: int, control: str, kw: dict[str, Any]) -> dict[str, Any]:
    """One run of the 'krylov' table; GMRES iterations counted from the solver's log."""
    import logging

    class _Count(logging.Handler):
        solves = iterations = 0

        def emit(self, record: logging.LogRecord) -> None:
            if str(record.msg).startswith("Krylov solve"):
                self.solves += 1
                self.iterations += int(record.args[1])  # type: ignore[index]

    counter = _Count()
    lg = logging.getLogger("pdlin.solvers.newton_krylov")
    lg.addHandler(counter)
    lg.setLevel(logging.DEBUG)
    prob, _ = problem(n, "shear", control)
    done: list[str] = []
    t0, c0 = time.perf_counter(), time.process_time()
    failed = ""
    res = None
    try:
        res = pdlin.solve_nonlinear(
            prob,
            times=np.arange(1.0, steps + 1.0),
            t_end=30.0,
            keep_states=False,
            progress=lambda m: done.append(m) if m.startswith("step ") else None,
            **kw,
        )
    except pdlin.errors.ConvergenceError as exc:
        failed = str(exc)[:90]
    out = {
        "done": len(done),
        "failed": failed,
        "wall": time.perf_counter() - t0,
        "cpu": time.process_time() - c0,
        "solves": counter.solves,
        "gmres": counter.iterations,
        "peak_mb": _peak_mb(),
    }
    if res is not None:
        out.update(
            newton=int(res.iterations.sum()),
            cutbacks=int(res.cutbacks.sum()),
            fallbacks=sum("adr" in m for m in res.methods),
            sxy=float(res.homogenized_stress[-1, 0, 1]),
        )
    return out


def table_krylov(n: int, steps: int, control: str, methods: list[str]) -> None:
    """Newton's linear solver and globalization on the n x n polycrystal in shear."""
    print(
        f"\n## Newton's linear solver and globalization: {n}² = {n * n:,} particles, shear, "
        f"control {control}, {steps} load steps\n"
    )
    head = (
        "| method | steps passed | Newton it (solves) | GMRES it | cut-backs | ADR fallbacks | "
        "wall / CPU s | peak RSS MB | σ_xy last (MPa) |"
    )
    _print_head(head)
    for m in methods:
        r = forked(_krylov_run, n, steps, control, KRYLOV_METHODS[m])
        if isinstance(r, str):
            print(f"| {m} | failed: {r} |")
            continue
        passed = f"{r['done']}/{steps}" + (f" ({r['failed']})" if r["failed"] else "")
        print(
            f"| {m} | {passed} | {r.get('newton', '-')} | {r['gmres']:,} | "
            f"{r.get('cutbacks', '-')} | {r.get('fallbacks', '-')} | {r['wall']:.1f} / "
            f"{r['cpu']:.1f} | {r['peak_mb']:.0f} | "
            + (f"{r['sxy']:.4f}" if "sxy" in r else "-")
            + " |",
            flush=True,
        )


# ---------------------------------------------------------------------------------------
# B2 accuracy-cost


def _b2(n: int, load: str, k: int, e_ls: list[float]) -> list[tuple[Any, ...]]:
    prob, h = problem(n, load)
    tmp = Path(tempfile.mkdtemp(prefix="bench_b2_"))
    base = tmp / "base.npz"
    tight = {"method": "newton", "rtol": 1e-12}
    if k > 1:
        pdlin.solve_nonlinear(
            prob, steps=k - 1, t_end=float(k - 1), checkpoint=base, keep_states=False, **tight
        )

    def from_base(name: str, **kw: Any) -> Any:
        path = tmp / name
        if base.exists():
            shutil.copy(base, path)
        return pdlin.solve_nonlinear(
            prob,
            steps=k,
            t_end=float(k),
            checkpoint=path,
            resume="branch",
            keep_states=False,
            **kw,
        )

    ref = from_base("ref.npz", **tight)
    s_ref = ref.homogenized_stress[-1]
    scale = float(np.linalg.norm(s_ref))
    rows = []
    for dens in ("adr-spec", "adr"):
        for e_l in e_ls:
            kw = options(dens, h)
            t0 = time.perf_counter()
            res = from_base(f"{dens}{e_l}.npz", e_l=e_l, **kw)
            dt = time.perf_counter() - t0
            err = float(np.linalg.norm(res.homogenized_stress[-1] - s_ref)) / scale
            du = float(np.abs(res.u[-1] - ref.u[-1]).max() / np.abs(ref.u[-1]).max())
            rows.append((dens, e_l, int(res.iterations[-1]), dt, err, du))
    plastic = float(np.asarray(ref.state.get("plastic", np.zeros(1)), dtype=bool).mean())
    shutil.rmtree(tmp, ignore_errors=True)
    return [(k, plastic, int(ref.iterations[-1]), *row) for row in rows]


def table_b2(n: int, load: str, ks: list[int], e_ls: list[float]) -> None:
    print(f"\n## B2: accuracy-cost, {n * n:,} particles, {load}, ADR from Newton's state\n")
    print(
        "| step | plastic | Newton it | density | e_l | ADR it | ADR s | "
        "‖Δσ̄‖/‖σ̄‖ | max|Δu|/max|u| |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for k in ks:
        rows = forked(_b2, n, load, k, e_ls)
        if isinstance(rows, str):
            print(f"| {k} | failed: {rows} |")
            continue
        for kk, pl, nit, dens, e_l, it, dt, err, du in rows:
            print(
                f"| {kk} | {pl:.2f} | {nit} | {dens} | {e_l:.0e} | {it} | {dt:.2f} | "
                f"{err:.1e} | {du:.1e} |",
                flush=True,
            )


# ---------------------------------------------------------------------------------------
# T20 damping


def _t20(n: int, steps: int, total: int, damping: float | None) -> dict[str, Any]:
    prob, h = problem(n, "shear")
    res = pdlin.solve_nonlinear(
        prob,
        times=np.arange(1.0, steps + 1.0),
        t_end=float(total),
        method="adr",
        density=h * h,
        dt=h * np.sqrt(1.0 / 2000.0),
        damping=damping,
        keep_states=False,
    )
    first, last, zero = [], [], []
    for c in res.damping:
        m = max(1, int(np.ceil(0.1 * c.size)))
        first.append(float(c[:m].max()))
        last.append(float(c[-m:].max()))
        zero.append(float(np.mean(c == 0.0)))
    return {
        "it": res.iterations.tolist(),
        "first": first,
        "last": last,
        "zero": zero,
        "time": float(res.timings["total"]),
    }


def table_t20(n: int, steps: int) -> None:
    print(f"\n## T20: ADR damping, {n}x{n} shear, steps 1-{steps} (the paper's density, Λ = 1)\n")
    runs = {}
    for c in (None, 200.0, 500.0, 2000.0):
        r = forked(_t20, n, steps, 30, c)
        runs["adaptive" if c is None else f"c = {c:g}"] = r
    names = list(runs)
    print(
        "| step | " + " | ".join(f"it {k}" for k in names) + " | adaptive max c first 10 % | "
        "last 10 % | ratio | c = 0 share |"
    )
    print("|---" * (len(names) + 5) + "|")
    ad = runs["adaptive"]
    for k in range(steps):
        its = " | ".join(str(runs[m]["it"][k]) if isinstance(runs[m], dict) else "-" for m in names)
        if isinstance(ad, dict):
            f, la, z = ad["first"][k], ad["last"][k], ad["zero"][k]
            print(f"| {k + 1} | {its} | {f:.3g} | {la:.3g} | {f / max(la, 1e-300):.1f} | {z:.0%} |")
    tot = " | ".join(
        f"{sum(runs[m]['it'])} ({runs[m]['time']:.1f} s)" if isinstance(runs[m], dict) else "-"
        for m in names
    )
    print(f"| total (time) | {tot} | | | | |")


# ---------------------------------------------------------------------------------------
# ADR damping in late plastic steps: adaptive against constant c from one committed state


def elastic_critical_damping(n: int, load: str, control: str) -> float:
    """``2 sqrt(λ_min)`` of ``Λ⁻¹ K_e`` on the free DOFs: the damping that makes the lowest
    elastic mode of ADR's dynamics critical (Gershgorin density ``Λ`` of the elastic
    tangent, Δt = 1, as ``solve_nonlinear``'s default ADR; shift-invert Lanczos)."""
    from pdlin.solvers.adr import adr_density
    from pdlin.system import constrained_system

    prob, _ = problem(n, load, control)
    system = constrained_system(prob)
    st = system.initial_state()
    u0 = np.zeros(system.ndof)
    lam = adr_density(system, st, u0)
    K = sp.csr_array(system.respond(u0, st, tangent=True).tangent)
    free = np.flatnonzero(system.free)
    scale = sp.diags_array(1.0 / np.sqrt(lam[free]))
    A = sp.csr_array(scale @ K[free][:, free] @ scale)
    A = 0.5 * (A + A.T)  # symmetric to round-off (elastic tangent)
    vals = spla.eigsh(A, k=1, sigma=0.0, which="LM", return_eigenvectors=False)
    return 2.0 * float(np.sqrt(max(float(vals[0]), 0.0)))


def _damping_branch(
    n: int, load: str, control: str, base: str, k: int, m: int, damping: float | None
) -> dict[str, Any]:
    prob, _ = problem(n, load, control)
    ck = Path(tempfile.mkdtemp(prefix="bench_damp_")) / "branch.npz"
    shutil.copy(base, ck)
    t0 = time.perf_counter()
    res = pdlin.solve_nonlinear(
        prob,
        times=np.arange(1.0, k + m + 1.0),
        t_end=30.0,
        method="adr",
        damping=damping,
        checkpoint=ck,
        resume="branch",
        keep_states=False,
    )
    return {
        "it": [int(x) for x in res.iterations[k:]],
        "sxy": [float(np.asarray(s)[0, 1]) for s in res.homogenized_stress[k:]],
        "zero": [float(np.mean(np.asarray(c) == 0.0)) for c in res.damping[k:]],
        "cmed": [float(np.median(np.asarray(c))) for c in res.damping[k:]],
        "time": time.perf_counter() - t0,
    }


def _damping_base(n: int, load: str, control: str, k: int, path: str) -> float:
    prob, _ = problem(n, load, control)
    t0 = time.perf_counter()
    pdlin.solve_nonlinear(
        prob,
        times=np.arange(1.0, k + 1.0),
        t_end=30.0,
        method="adr",
        checkpoint=path,
        keep_states=False,
    )
    return time.perf_counter() - t0


def table_damping(n: int, load: str, control: str, k: int, m: int, values: list[float]) -> None:
    """ADR steps ``k+1 .. k+m`` from ADR's committed step ``k``: the adaptive damping of
    Luo, Ramazani & Sundararaghavan (2017), Eq. 13, and constant ``c`` (Δt = 1, Gershgorin
    density), with ``c`` relative to the elastic lowest mode's critical damping."""
    print(
        f"\n## ADR damping in plastic steps: {n}x{n} {load}, control {control}, steps "
        f"{k + 1}-{k + m} from ADR's committed step {k}\n"
    )
    base = str(Path(tempfile.mkdtemp(prefix="bench_damp_")) / "base.npz")
    t_base = forked(_damping_base, n, load, control, k, base)
    if isinstance(t_base, str):
        print(f"failed to reach step {k}: {t_base}")
        return
    c_crit = forked(elastic_critical_damping, n, load, control)
    crit = c_crit if isinstance(c_crit, float) else float("nan")
    print(
        f"steps 1-{k}: {t_base:.1f} s; elastic critical damping 2 sqrt(λ_min(Λ⁻¹K_e)) = "
        f"{crit:.4g}\n"
    )
    cols = " | ".join(f"step {k + j + 1}: iterations / σ_xy (MPa)" for j in range(m))
    print(f"| damping | c / c_crit | {cols} | median c | c = 0 share | s |")
    print("|---" * (m + 5) + "|")
    for c in [None, *values]:
        r = forked(_damping_branch, n, load, control, base, k, m, c)
        name = "adaptive (Eq. 13)" if c is None else f"c = {c:g}"
        rel = "-" if c is None else f"{c / crit:.2f}"
        if isinstance(r, str):
            print(f"| {name} | {rel} | failed: {r[:120]} |" + " |" * (m + 2))
            continue
        steps = " | ".join(f"{i:,} / {s:.4f}" for i, s in zip(r["it"], r["sxy"], strict=True))
        print(
            f"| {name} | {rel} | {steps} | {np.median(r['cmed']):.3g} | "
            f"{np.mean(r['zero']):.0%} | {r['time']:.1f} |"
        )


# ---------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", help="grid sides n (n x n particles)")
    ap.add_argument("--loads", nargs="+", default=list(LOADS), choices=list(LOADS))
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument(
        "--e-l",
        type=float,
        nargs="+",
        dest="e_l",
        default=[1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8],
    )
    ap.add_argument(
        "--budget",
        type=float,
        default=150.0,
        help="seconds per B1 run before it stops and extrapolates (default 150)",
    )
    ap.add_argument("--aim-size", type=int, default=50, help="grid side of the aim (50: 2,500)")
    ap.add_argument(
        "--big", type=int, help="grid side of the 10⁵ run (0: skip; default 316, 0 with --quick)"
    )
    ap.add_argument("--big-steps", type=int, default=3)
    ap.add_argument("--big-method", default="newton", choices=["newton", "auto", "adr"])
    ap.add_argument(
        "--big-checkpoint", help="checkpoint file of the 10⁵ run (resumed when it exists)"
    )
    ap.add_argument(
        "--big-control",
        default="none",
        help="zero-energy-mode control of the 10⁵ run: none (the paper's), stress_points, "
        "penalty or penalty:C (coefficient C; the end-to-end run uses penalty:0.1)",
    )
    ap.add_argument("--goal-size", type=int, default=316, help="grid side of 'goal' (10⁵)")
    ap.add_argument(
        "--goal-methods", nargs="+", default=["auto", "newton", "adr"], help="methods of 'goal'"
    )
    ap.add_argument(
        "--goal-controls",
        nargs="+",
        default=["penalty:0.1", "none"],
        help="controls of 'goal' (as --big-control)",
    )
    ap.add_argument(
        "--goal-rates",
        nargs="+",
        default=["100", "none"],
        help="power-law exponents of 'goal' ('none': the rate-independent model)",
    )
    ap.add_argument(
        "--goal-budget", type=float, default=1800.0, help="seconds per 'goal' run (30 min)"
    )
    ap.add_argument("--b2-size", type=int, default=25)
    ap.add_argument(
        "--b2-steps",
        type=int,
        nargs="+",
        default=[1, 8],
        help="load steps of B2 (an elastic and a plastic one)",
    )
    ap.add_argument(
        "--sections",
        nargs="+",
        default=["b1", "aim", "profile", "big", "b2", "t20"],
        choices=[
            "b1",
            "aim",
            "profile",
            "big",
            "b2",
            "t20",
            "predictors",
            "damping",
            "polish",
            "krylov",
            "goal",
        ],
        help="tables to print ('predictors', 'damping', 'goal', ... only on request)",
    )
    ap.add_argument(
        "--predictors",
        nargs="+",
        default=["tangent", "committed-tangent", "extrapolate"],
        help="Newton predictors of the 'predictors' table",
    )
    ap.add_argument(
        "--fine", type=int, default=4, help="increments per step of the predictors' fine path"
    )
    ap.add_argument(
        "--profile-budget", type=float, default=90.0, help="seconds per profiled run (default 90)"
    )
    ap.add_argument(
        "--threads",
        type=int,
        help="pdlin threads (pdlin.set_num_threads; default: pdlin's, i.e. PDLIN_NUM_THREADS "
        "or every core). The issue's aim is on one core: --threads 1",
    )
    ap.add_argument("--damping-size", type=int, default=100, help="grid side of 'damping'")
    ap.add_argument(
        "--damping-from", type=int, default=20, help="committed ADR step the branches start from"
    )
    ap.add_argument("--damping-steps", type=int, default=2, help="steps per branch")
    ap.add_argument(
        "--damping-values",
        type=float,
        nargs="+",
        default=[0.005, 0.01, 0.015, 0.02, 0.03, 0.05, 0.1, 0.2],
        help="constant damping values c (Δt = 1, Gershgorin density)",
    )
    ap.add_argument(
        "--damping-control", default="penalty:0.1", help="control of 'damping' (as --big-control)"
    )
    ap.add_argument("--krylov-size", type=int, default=100, help="grid side of 'krylov'")
    ap.add_argument("--krylov-steps", type=int, default=30, help="load steps of 'krylov'")
    ap.add_argument("--krylov-control", default="none", help="control of 'krylov'")
    ap.add_argument(
        "--krylov-methods",
        nargs="+",
        default=list(KRYLOV_METHODS),
        choices=list(KRYLOV_METHODS),
        help="variants of 'krylov'",
    )
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument(
        "--quick",
        action="store_true",
        help="the default: 15x15 and 25x25, 8 s per run, no 10⁵ run (about 2 min)",
    )
    mode.add_argument("--full", action="store_true", help="225 to 10,000 particles and the 10⁵ run")
    args = ap.parse_args(argv)
    if args.threads is not None:
        pdlin.set_num_threads(args.threads)
    quick = not args.full and args.sizes is None
    if args.sizes is None:
        args.sizes = [15, 25, 50, 100] if args.full else [15, 25]
    if args.big is None:
        args.big = 0 if quick else 316
    if quick:
        args.aim_size = max(args.sizes)
        args.budget = min(args.budget, 8.0)
        args.profile_budget = min(args.profile_budget, 8.0)
    print("# bench_nonlinear")
    header()
    t_all = time.perf_counter()
    rows: list[dict[str, Any]] = []
    if "b1" in args.sections:
        rows = table_b1(args.sizes, args.loads, args.methods, args.steps, args.budget)
    if "aim" in args.sections and rows:
        table_aim(rows, args.aim_size)
    if "predictors" in args.sections:
        table_predictors(args.sizes, args.loads, args.predictors, args.steps, args.fine)
    if "profile" in args.sections:
        n_prof = args.aim_size
        table_profile(
            n_prof, args.loads[0], ["newton", "adr-spec"], args.steps, args.profile_budget
        )
    if "big" in args.sections and args.big > 0:
        table_big(
            args.big,
            args.big_steps,
            args.loads[0],
            method=args.big_method,
            checkpoint=args.big_checkpoint,
            control=args.big_control,
        )
    if "b2" in args.sections:
        table_b2(args.b2_size, args.loads[0], args.b2_steps, args.e_l)
    if "t20" in args.sections:
        table_t20(25, 6 if quick else 12)
    if "polish" in args.sections:
        table_polish(args.sizes, args.loads, args.methods, args.steps)
    if "goal" in args.sections:
        rates = [None if r == "none" else float(r) for r in args.goal_rates]
        table_goal(
            args.goal_size, args.goal_methods, args.goal_controls, rates, 30, args.goal_budget
        )
    if "krylov" in args.sections:
        table_krylov(args.krylov_size, args.krylov_steps, args.krylov_control, args.krylov_methods)
    if "damping" in args.sections:
        table_damping(
            args.damping_size,
            args.loads[0],
            args.damping_control,
            args.damping_from,
            args.damping_steps,
            args.damping_values,
        )
    print(f"\nrun time {time.perf_counter() - t_all:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
