"""Time and memory of a 3D FCC polycrystal in shear (crystal-plasticity correspondence, 10⁴ points).

An n³ grid (spacing 1/n of a unit cube, mm) with ``pdlin.voronoi_polycrystal`` grains (seeded,
uniformly random orientations), ``CrystalPlasticity("fcc")`` (12 {111}<110> systems; pdlin's
default OFHC-copper-like constants, docs/crystal_plasticity.md), ``Correspondence`` at δ = h,
one ghost layer (``pdlin.geometry.ghost_layer``) and the boundary ring and the ghosts prescribed
by the pure-shear path ``u = (exp(L t) − I) X``, ``L = η (e_x⊗e_y + e_y⊗e_x)``.
This is pdlin's own case: the papers pdlin follows run 3D polycrystals with hcp WE43 data
(Javaheri et al. 2022, Sec. III.D) that are not published; 3D FCC shear is not in them.

One row per method: points, grains, DOFs, load steps, iterations (total, largest per step),
cut-backs and ADR fallbacks, wall and CPU seconds of ``solve_nonlinear`` (bonds, setup and all
steps), peak RSS of the run (each run in a forked child, so the rows do not share a peak) and the
final homogenized σ_xy.  Nothing is asserted.

``--split`` runs ``solve_nonlinear`` under ``cProfile`` with a CPU-time clock
(``time.process_time``: every thread of the process, so the constitutive update's and the
assembly's worker threads count) and prints a second table: CPU seconds per Newton iteration
in the constitutive update (``CrystalPlasticity.update`` and ``.piola``, line-search trials
included), the tangent assembly (``Correspondence.tangent_matrix``), the linear solve
(``pdlin.solvers.solve_linear``: factorization and back-substitution) and the rest
(gradient products, force assembly, residual checks, bookkeeping).  The profiler's own
overhead lands in "other" (a few per cent here: the work is in vectorized calls).

Usage::

    python benchmarks/bench_cp3d.py                           # 22³ = 10,648 points, newton
    python benchmarks/bench_cp3d.py --n 22 --steps 10 --methods newton auto adr
    python benchmarks/bench_cp3d.py --steps 10 --split         # + CPU split per iteration
"""

from __future__ import annotations

import argparse
import cProfile
import re
import resource
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import pdlin

#: (file suffix, function name) of the profiled calls of each part of an iteration
PARTS = {
    "update": (("crystal_plasticity.py", "update"), ("crystal_plasticity.py", "piola")),
    "tangent": (("correspondence/model.py", "tangent_matrix"),),
    "solve": (("solvers/linear.py", "solve_linear"),),
}

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _context import fork_call, header  # noqa: E402


def problem(n: int, grains: int, eta: float) -> pdlin.StaticProblem:
    """The n³ FCC polycrystal with one ghost layer, prescribed by the pure-shear path."""
    base = pdlin.grid((n, n, n), spacing=1.0 / n)
    _, rot = pdlin.voronoi_polycrystal(base, grains, seed=1)
    g = pdlin.geometry.ghost_layer(base, layers=1)
    material = pdlin.CrystalPlasticity("fcc", orientation=rot[g.source])
    model = pdlin.Correspondence(material=material)
    bonds = pdlin.find_bonds(g.cloud, ratio=1.0)
    L = np.zeros((3, 3))
    L[0, 1] = L[1, 0] = eta
    fixed = np.union1d(g.cloud.point_set("boundary"), g.ghost)
    bc = pdlin.Dirichlet.velocity_gradient(fixed, L)
    return pdlin.StaticProblem(model, g.cloud, bonds, dirichlet=[bc])


def split(prof: cProfile.Profile) -> dict[str, float]:
    """CPU seconds of each part of :data:`PARTS`, each call counted once.

    ``totaltime`` of an entry excludes recursive re-entries of the same function; a part's
    function called inside another of the same part (``piola`` falls back on ``update``) is
    subtracted from the caller, so that a line-search trial is not counted twice.
    """

    def match(code: Any, keys: tuple[tuple[str, str], ...]) -> bool:
        if isinstance(code, str):
            return False
        fname = code.co_filename.replace("\\", "/")
        return any(fname.endswith(f) and code.co_name == fn for f, fn in keys)

    stats = prof.getstats()
    out = {}
    for part, keys in PARTS.items():
        tot = 0.0
        for entry in stats:
            if not match(entry.code, keys):
                continue
            tot += entry.totaltime
            for sub in entry.calls or ():
                if match(sub.code, keys) and sub.code is not entry.code:
                    tot -= sub.totaltime
        out[part] = tot
    return out


class Progress:
    """``solve_nonlinear``'s progress on stderr; after each step (``--split``) the split so far.

    A run stopped before its last step (a time limit) still leaves its per-step CPU seconds and
    the split of the steps it finished.
    """

    def __init__(self, prof: cProfile.Profile | None, c0: float) -> None:
        self.prof, self.c0, self.iterations = prof, c0, 0

    def __call__(self, msg: str) -> None:
        cpu = time.process_time() - self.c0
        print(f"# progress ({cpu:.0f} CPU s): {msg}", file=sys.stderr, flush=True)
        hit = re.match(r"step \d+/\d+ .*?(\d+) iteration", msg)
        if hit is None:
            return
        self.iterations += int(hit.group(1))
        if self.prof is not None and self.iterations:
            p = split(self.prof)
            other = cpu - p["update"] - p["tangent"] - p["solve"]
            cells = ", ".join(
                f"{k} {v / self.iterations:.2f}" for k, v in (*p.items(), ("other", other))
            )
            print(
                f"# split so far: {self.iterations} iterations, {cpu:.0f} CPU s; per iteration "
                f"(CPU s, finished calls): {cells}",
                file=sys.stderr,
                flush=True,
            )


def run(
    n: int,
    grains: int,
    eta: float,
    steps: int,
    method: str,
    profile: bool = False,
    progress: bool = False,
) -> dict[str, Any]:
    """One solve_nonlinear run; wall / CPU seconds, iterations, peak RSS (this process)."""
    t0, c0 = time.perf_counter(), time.process_time()
    prob = problem(n, grains, eta)
    prof = cProfile.Profile(time.process_time) if profile else None
    c1 = time.process_time()
    try:
        if prof is not None:
            prof.enable()
        res = pdlin.solve_nonlinear(
            prob,
            times=np.arange(1.0, steps + 1.0),
            t_end=float(steps),
            method=method,
            keep_states=False,
            progress=Progress(prof, c1) if progress else None,
        )
        c_solve = time.process_time() - c1
    except pdlin.errors.ConvergenceError as exc:
        return {"failed": str(exc)[:160]}
    finally:
        if prof is not None:
            prof.disable()
    parts = split(prof) if prof is not None else {}
    hom = res.homogenized_stress
    assert hom is not None
    return {
        "points": prob.cloud.n,
        "real": n**3,
        "dofs": prob.cloud.n * 3,
        "iterations": int(res.iterations.sum()),
        "max_it": int(res.iterations.max()),
        "cutbacks": int(res.cutbacks.sum()),
        "fallbacks": sum("failed" in m or "skipped" in m for m in res.methods),
        "wall": time.perf_counter() - t0,
        "cpu": time.process_time() - c0,
        "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "sxy": float(hom[-1][0, 1]),
        "c_solve": c_solve,
        "parts": parts,
        "per_step": [int(k) for k in res.iterations],
    }


def forked(*args: Any) -> dict[str, Any]:
    """:func:`run` in a forked child (its own peak RSS); a failure as ``{"failed": ...}``."""
    out = fork_call(run, *args)
    return {"failed": out} if isinstance(out, str) else dict(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=22, help="points per side (default 22: 10,648)")
    ap.add_argument("--grains", type=int, default=20)
    ap.add_argument("--eta", type=float, default=1e-4, help="shear strain rate per step")
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--methods", nargs="+", default=["newton"])
    ap.add_argument("--threads", type=int, default=2, help="pdlin threads (default 2)")
    ap.add_argument("--split", action="store_true", help="CPU split per iteration (cProfile)")
    ap.add_argument("--progress", action="store_true", help="solve_nonlinear progress on stderr")
    args = ap.parse_args()
    pdlin.set_num_threads(args.threads)
    header()
    print(
        f"# FCC polycrystal, {args.n}³ real points + 1 ghost layer, {args.grains} grains, pure "
        f"shear η = {args.eta:g} per step, {args.steps} steps, {args.threads} pdlin thread(s)"
    )
    print(
        "| real points | points (with ghosts) | DOFs | grains | steps | method | iterations "
        "(max/step) | cut-backs | fallbacks | wall s | CPU s | peak RSS MB | σ_xy last (MPa) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    done = []
    for method in args.methods:
        r = forked(args.n, args.grains, args.eta, args.steps, method, args.split, args.progress)
        if "failed" in r:
            print(f"| {args.n**3:,} | | | {args.grains} | {args.steps} | {method} | failed: "
                  f"{r['failed']} | | | | | | |", flush=True)  # fmt: skip
            continue
        print(
            f"| {r['real']:,} | {r['points']:,} | {r['dofs']:,} | {args.grains} | {args.steps} | "
            f"{method} | {r['iterations']} ({r['max_it']}) | {r['cutbacks']} | {r['fallbacks']} | "
            f"{r['wall']:.1f} | {r['cpu']:.1f} | {r['rss']:.0f} | {r['sxy']:.2f} |",
            flush=True,
        )
        print(f"# {method}: iterations per step {r['per_step']}", flush=True)
        done.append((method, r))
    if args.split and done:
        print_split(done)


def print_split(done: list[tuple[str, dict[str, Any]]]) -> None:
    """The CPU split per Newton iteration (``--split``)."""
    print("\n# CPU seconds per iteration of solve_nonlinear (cProfile, process CPU clock)")
    print(
        "| method | iterations | solve_nonlinear CPU s | constitutive update | tangent assembly "
        "| linear solve | other |"
    )
    print("|---|---|---|---|---|---|---|")
    for method, r in done:
        it, tot, p = r["iterations"], r["c_solve"], r["parts"]
        other = tot - p["update"] - p["tangent"] - p["solve"]
        cells = [
            f"{v / it:.2f} ({100 * v / tot:.0f} %)"
            for v in (p["update"], p["tangent"], p["solve"], other)
        ]
        print(f"| {method} | {it} | {tot:.1f} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
