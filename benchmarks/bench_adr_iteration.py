"""Cost of one ADR iteration on the crystal-plasticity polycrystal, and what BLAS threads do to it.

ADR iterations of ``pdlin.solvers.adr.adr_step`` on the 21-grain polycrystal of
``bench_nonlinear.problem`` (planar-2 crystal plasticity, δ = h, n x n grid, pure shear,
optionally a control) from the affine state at shear γ = ``--gamma`` over the initial
state: milliseconds per iteration and of them in the material's stress, for pdlin's
thread count 1 and 2, two ways of taking the loop's dot products and norms:

- ``pdlin``: what the ADR loop does (``_dot``: numpy's ``einsum``, no BLAS);
- ``blas``: the same products through BLAS (``a @ b``), as the loop did before;

two ways of getting the stress in ``Correspondence.respond``:

- ``piola``: what respond does without the tangent (``CrystalPlasticity.piola``: the
  compiled kernel without the trial state, which is computed when the state is read);
- ``update``: the full ``CrystalPlasticity.update`` at every iteration, as before
  (``piola`` removed from the material's class in the child);

three ADR loops: ``compiled`` (``_adr_run`` with numba: the update and δu / local
stiffness as one compiled pass each over DOF chunks on pdlin's threads, bitwise the numpy
steps), ``buffers`` (the same loop with its numpy steps: in-place vector work in
preallocated buffers, no masked gathers) and ``masked`` (the loop before, kept here as
:func:`_masked_loop`: fresh arrays and boolean-mask gathers every iteration);

two forms of the operators ``G`` and ``K_c``: ``nonzeros`` (what the plan builds: no
stored zeros) and ``zeros`` (as before, :func:`_with_stored_zeros`: at δ = h half of G's
entries are vanishing components of bond coefficients and half of the penalty's CSR
entries the zeros of its d x d blocks);

and the mat-vecs ``G u``, ``Gᵀ (w V P)``, ``K_c u`` as ``blocks`` (row blocks on pdlin's
threads, ``pdlin._threads.RowBlocks``, from 2 x ``ROW_BLOCK_NNZ`` entries) or ``plain``
(scipy's serial product: the threshold raised in the child).

BLAS keeps its default thread count here (all cores), unlike the other benchmarks: with
OpenBLAS a ``ddot`` of a long vector runs on BLAS's threads, which then spin for a while
and take the cores of the constitutive update that follows.  Every case is a forked child
(fresh BLAS and pdlin thread pools).  Nothing is asserted; wall-clock times on a shared
machine, with the CPU milliseconds per iteration beside them; rows of 2 pdlin threads are
marked unreliable when the load average at the start (header) exceeded the free cores.

Examples
--------
``python benchmarks/bench_adr_iteration.py --n 316 --iterations 200 --repeats 3``
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _context import header, speedup_flag  # noqa: E402
from bench_nonlinear import forked, problem  # noqa: E402


def _masked_loop(nl: Any) -> Any:
    """``_adr_run`` as it was before the buffers (2026-11-26, 8b7a6e2), for the baseline rows:
    the vector work of an iteration (everything but respond and the residual) only."""
    import math

    def run(system: Any, u: Any, resp: Any, r: Any, committed: Any, **kw: Any) -> Any:
        lam, free, npts, dt, c = kw["density"], system.free, system.n, kw["dt"], kw["c0"]
        u_prev, calls, cs, eps0, h2 = u.copy(), 0, [], None, 2.0 * kw["dt"] ** 2
        for it in range(1, kw["maxiter"] + 1):
            a = np.where(free, r / lam, 0.0)
            u_new = (h2 * a + 4.0 * u + (c * dt - 2.0) * u_prev) / (2.0 + c * dt)
            u_new[~free] = u[~free]
            resp_new = nl._respond(system, u_new, committed, f"ADR iteration {it}")
            r_new = nl._residual(system, resp_new, kw["factor"])
            n1 = math.sqrt(nl._dot(r_new, r_new))
            du = u_new - u
            mask = free & (du != 0.0)
            k = np.zeros_like(u)
            k[mask] = -(r_new[mask] - r[mask]) / (lam[mask] * du[mask])
            uf = u_new[free]
            q = nl._dot(uf, k[free] * uf) / nl._dot(uf, uf)
            c = 2.0 * math.sqrt(q) if q > 0 else 0.0
            cs.append(c)
            eps = (n1 / npts, math.sqrt(nl._dot(du, du)) / npts)
            eps0 = eps if eps0 is None else eps0
            u_prev, u, r = u, u_new, r_new
            calls += 1
        out = nl.StepOutcome(u, resp_new, it, calls, n1, [], np.array(cs), 1.0, 1.0)
        return nl._AdrRun(out, False)

    return run


def _with_stored_zeros() -> None:
    """G and K_c as in c606a50 (for the baseline rows): G keeps the vanishing
    components of bond coefficients (half its entries at δ = h), the penalty's CSR the
    zeros of its d x d blocks."""
    import scipy.sparse as sp

    from pdlin.models import correspondence as corr
    from pdlin.models.correspondence import gradient

    live = gradient._blocks_to_csr

    def blocks_to_csr(blk: Any, n_points: int) -> Any:
        # the live conversion keeps nonzeros only: mark the bond coefficients' vanishing
        # components (not the owner's, which c606a50 dropped too) by NaN, convert, and
        # put the zeros back into those slots
        keep = (blk.val == 0.0) & ~blk.diag[:, None]
        G = live(dataclasses.replace(blk, val=np.where(keep, np.nan, blk.val)), n_points)
        G.data[np.isnan(G.data)] = 0.0
        return G

    def addon_matrix(self: Any, cloud: Any, bonds: Any, p: Any) -> Any:
        if "addon" not in p._lazy:
            if self.control == "penalty" and self.penalty > 0:
                p._lazy["addon"] = sp.csr_array(self._penalty_matrix(cloud, bonds, p))
            else:
                p._lazy["addon"] = self._control_matrix(cloud, bonds, p)
        return p._lazy["addon"]

    gradient._blocks_to_csr = blocks_to_csr  # type: ignore[assignment]
    corr.Correspondence._addon_matrix = addon_matrix  # type: ignore[method-assign]


def _case(
    n: int,
    threads: int,
    loop: str,
    dots: str,
    stress: str,
    matvecs: str,
    operators: str,
    iterations: int,
    gamma: float,
    control: str,
    repeats: int = 1,
) -> Any:
    import pdlin
    from pdlin.solvers import adr as nl
    from pdlin.system import constrained_system

    pdlin.set_num_threads(threads)
    if matvecs == "plain":
        from pdlin import _threads

        _threads.ROW_BLOCK_NNZ = 10**15
    if dots == "blas":
        nl._dot = lambda a, b: float(a @ b)  # type: ignore[assignment]
    if loop == "masked":
        nl._adr_run = _masked_loop(nl)  # type: ignore[assignment]
    if loop != "compiled":  # the numpy steps of the update (also without numba)
        nl._adr_kernels = lambda ndof: None  # type: ignore[assignment]
    if operators == "zeros":
        _with_stored_zeros()
    prob, _ = problem(n, "shear", control)
    system = constrained_system(prob)
    state = system.initial_state()
    pts = system.cloud.points
    u = np.column_stack([gamma * pts[:, 1], np.zeros(len(pts))]).ravel()
    cls = type(prob.model.material)
    if stress == "update":
        del cls.piola  # a forked child: respond falls back to the full update
    spent = [0.0]

    def timed(fn: Any) -> Any:
        def call(self: Any, *a: Any, **kw: Any) -> Any:
            t0 = time.perf_counter()
            out = fn(self, *a, **kw)
            spent[0] += time.perf_counter() - t0
            return out

        return call

    for name in ("update", "piola"):
        if hasattr(cls, name):
            setattr(cls, name, timed(getattr(cls, name)))
    density = nl.adr_density(system, state, u)
    best: tuple[float, float, int, float] | None = None
    for _ in range(repeats):  # the fastest of `repeats` runs (a shared machine's noise)
        spent[0] = 0.0
        t0 = time.perf_counter()
        c0 = time.process_time()
        try:
            its = nl.adr_step(
                system, u, state, factor=1.0, density=density, dt=1.0, maxiter=iterations
            ).iterations
        except nl.StepFailed as exc:  # the budget (or the baseline loop, which never stops)
            its = exc.outcome.iterations if exc.outcome is not None else iterations
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0
        run = (wall / its * 1e3, spent[0] / its * 1e3, its, cpu / its * 1e3)
        best = run if best is None or run[0] < best[0] else best
    assert best is not None
    return best


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, nargs="+", default=[100, 316], help="grid sides")
    p.add_argument("--iterations", type=int, default=200)
    p.add_argument("--repeats", type=int, default=1, help="runs per case, the fastest reported")
    p.add_argument("--gamma", type=float, default=0.01, help="affine shear of the start")
    p.add_argument("--control", default="penalty:0.1", help="'none', 'penalty:C', ...")
    args = p.parse_args(argv)
    ctx = header()
    print(
        f"ADR iterations from an affine shear γ = {args.gamma} (control {args.control}), "
        f"{args.iterations} per run, the fastest of {args.repeats} run(s) per case; BLAS at "
        "its default thread count"
    )
    print()
    print(
        "| particles | pdlin threads | loop | dot products | stress | mat-vecs | operators "
        "| ms per iteration | CPU ms per iteration | of it material | vs first row | 2 threads "
        "reliable? |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    cases = (
        ("masked", "blas", "update", "plain", "zeros"),
        ("masked", "pdlin", "update", "plain", "zeros"),
        ("masked", "pdlin", "piola", "plain", "zeros"),
        ("buffers", "pdlin", "piola", "plain", "zeros"),
        ("buffers", "pdlin", "piola", "blocks", "zeros"),
        ("buffers", "pdlin", "piola", "blocks", "nonzeros"),
        ("compiled", "pdlin", "piola", "blocks", "nonzeros"),
    )
    for n in args.n:
        for threads in (1, 2):
            base = None
            for loop, dots, stress, matvecs, operators in cases:
                out = forked(
                    _case,
                    n,
                    threads,
                    loop,
                    dots,
                    stress,
                    matvecs,
                    operators,
                    args.iterations,
                    args.gamma,
                    args.control,
                    args.repeats,
                )
                row = (
                    f"| {n * n:,} | {threads} | {loop} | {dots} | {stress} | {matvecs} "
                    f"| {operators} |"
                )
                if isinstance(out, str):  # the child's error
                    print(f"{row} {out} | | | | |", flush=True)
                    continue
                it_ms, mat_ms, _, cpu_ms = out
                base = it_ms if base is None else base
                flag = (
                    (speedup_flag(threads, ctx.load1, ctx.cores) or "yes") if threads > 1 else "—"
                )
                print(
                    f"{row} {it_ms:.2f} | {cpu_ms:.2f} | {mat_ms:.2f} | {base / it_ms:.2f} x | "
                    f"{flag} |",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
