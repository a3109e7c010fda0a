"""Direct factorization backends on the correspondence anchor case (issue 13, "Direct solves").

The anchor (issue 5): a 401 x 401 grid (160,801 points, 321,602 DOFs) of the linear
correspondence model, δ = 2h, x- face clamped, x+ face pulled (u_x = 1e-3).  A published
Julia implementation takes 3.1 s assembly + 19.6 s LU = 22.7 s on one core.  Rows:

* ``none``: no control, ω = 1/|ξ| (the anchor operator);
* ``stress_points``: stabilized with stress points, ω = 1, δ = 2h and δ = h.

Each (case, backend, threads) runs in a fresh subprocess (so BLAS / MKL thread counts
take effect) with a time limit: bonds, assembly (``system.assemble`` + elimination),
ordering + factorization (``DirectSolver``), solve, the true relative residual of the
eliminated system, nnz of the factor, the factorization flop count (PARDISO's
``iparm(19)``, MUMPS' statistics, CHOLMOD's Σ c_j² over the columns of L) and the flop
bound ``flops / dense rate``: the time the factorization would take at this machine's
measured dense ``dgemm`` rate (numpy matmul of 3000 x 3000, same thread count), a lower
bound for any method doing these flops.

Factorization and total are wall seconds with CPU seconds beside them (CPU / wall > 1: the
backend's threads worked); rows of 2 threads are marked unreliable when the load average at
the start exceeded the cores they left free.  The header: load, cores, BLAS, backends.

Usage: ``python benchmarks/bench_direct.py`` (all rows, ~10 min), ``--quick`` (201 x 201),
``--backends cholmod,pardiso``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, speedup_flag, timed  # noqa: E402

JULIA_TOTAL = 3.1 + 19.6  # s, published Julia implementation, 160,801 points, δ = 2h


def _dense_rate() -> float:
    import numpy as np

    a = np.random.default_rng(0).normal(size=(3000, 3000))
    a @ a
    best = float("inf")
    for _ in range(3):
        t = time.perf_counter()
        a @ a
        best = min(best, time.perf_counter() - t)
    return 2 * 3000**3 / best


def one(n: int, m: int, control: str, backend: str) -> dict[str, Any]:
    """One row, in this process (called in a subprocess by :func:`main`)."""
    import numpy as np

    import pdlin
    from pdlin.solvers.direct import DirectSolver
    from pdlin.system import constrained_system

    t0 = time.perf_counter()
    c0 = time.process_time()
    cloud = pdlin.grid((n, n), spacing=1.0 / n)
    t = time.perf_counter()
    if control == "none":
        bonds = pdlin.find_bonds(cloud, ratio=float(m), influence="inverse")
    else:
        bonds = pdlin.find_bonds(cloud, ratio=float(m))
    tb = time.perf_counter() - t
    model = pdlin.Correspondence(E=1.0, nu=0.25, control=control, plane="strain")
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    prob = pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc)
    t = time.perf_counter()
    system = constrained_system(prob)
    K = system.assemble()
    A, b = system.eliminate(K, inplace=True)
    ta = time.perf_counter() - t
    del K
    with timed() as tfac:
        s = DirectSolver(A, symmetric=True, backend=backend)
    tf = tfac.wall
    t = time.perf_counter()
    x = s.solve(b)
    ts = time.perf_counter() - t
    total = time.perf_counter() - t0
    total_cpu = time.process_time() - c0
    res = float(np.linalg.norm(b - A @ x) / np.linalg.norm(b))
    try:
        flops = s.flops()
    except Exception:  # noqa: BLE001 - reported as unknown
        flops = None
    return {
        "bonds": tb,
        "asm": ta,
        "fact": tf,
        "fact_cpu": tfac.cpu,
        "total_cpu": total_cpu,
        "solve": ts,
        "total": total,
        "res": res,
        "fill": s.fill,
        "flops": flops,
        "backend": s.backend,
        "ordering": s.info["ordering"],
        "ndof": A.shape[0],
        "nnzA": int(A.nnz),
        "rate": _dense_rate(),
    }


def _run(case: tuple, threads: int, limit: float) -> dict[str, Any]:
    env = dict(os.environ)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "PDLIN_NUM_THREADS"):
        env[var] = str(threads)
    here = os.path.dirname(os.path.abspath(__file__))
    env["PYTHONPATH"] = os.pathsep.join([os.path.dirname(here), env.get("PYTHONPATH", "")])
    cmd = [sys.executable, os.path.abspath(__file__), "--one", json.dumps(case)]
    try:
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=limit)
    except subprocess.TimeoutExpired:
        return {"timeout": limit}
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if out.returncode != 0 or not lines:
        err = (out.stderr.strip().splitlines() or ["?"])[-1]
        return {"error": err[:90]}
    return json.loads(lines[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="201 x 201 only")
    ap.add_argument("--backends", default="superlu,cholmod,pardiso,mumps")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--limit", type=float, default=150.0, help="seconds per row")
    ap.add_argument("--cases", default="none:2,stress_points:2,stress_points:1",
                    help="control:δ/h list")  # fmt: skip
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        n, m, control, backend = json.loads(args.one)
        print(json.dumps(one(n, m, control, backend)), flush=True)
        return
    from pdlin.solvers.direct import available_direct_backends

    avail = available_direct_backends()
    n = 201 if args.quick else 401
    print(f"# bench_direct.py {'--quick ' if args.quick else ''}")
    ctx = header()
    print(
        "\n| grid | control | δ/h | backend (ordering) | threads | bonds | assembly | "
        "ordering + factorization (CPU s) | solve | total (CPU s) | total / 22.7 s | "
        "rel. residual | nnz(A) | nnz(factor) | flops | flop bound (s) | threads reliable? |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    cases = [(n, int(c.split(":")[1]), c.split(":")[0]) for c in args.cases.split(",")]
    for nn, m, control in cases:
        for backend in args.backends.split(","):
            if not avail.get(backend, False):
                print(f"| {nn}² | {control} | {m} | {backend} | | not installed |", flush=True)
                continue
            for th in (int(x) for x in args.threads.split(",")):
                if backend in ("superlu", "mumps") and th > 1:
                    continue  # sequential codes (their BLAS threads aside)
                r = _run((nn, m, control, backend), th, args.limit)
                head = f"| {nn}² | {control} | {m} | {backend} | {th} |"
                if "timeout" in r or "error" in r:
                    msg = f"> {args.limit:.0f} s (stopped)" if "timeout" in r else r["error"]
                    print(head + f" {msg} |", flush=True)
                    continue
                fl = r["flops"]
                bound = "" if fl is None else f"{fl / r['rate']:.1f}"
                print(
                    f"| {nn}² | {control} | {m} | {r['backend']} ({r['ordering']}) | {th} | "
                    f"{r['bonds']:.2f} | {r['asm']:.2f} | {r['fact']:.2f} ({r['fact_cpu']:.2f}) | "
                    f"{r['solve']:.2f} | {r['total']:.2f} ({r['total_cpu']:.2f}) | "
                    f"{r['total'] / JULIA_TOTAL:.2f} | {r['res']:.1e} | "
                    f"{r['nnzA']:,} | {r['fill']:,} | "
                    f"{'' if fl is None else f'{fl:.2e}'} | {bound} "
                    f"({r['rate'] / 1e9:.0f} GFLOP/s) | "
                    f"{(speedup_flag(th, ctx.load1, ctx.cores) or 'yes') if th > 1 else '—'} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
