"""PETSc backend: 1 vs 2 MPI ranks (strong scaling), iterations and peak memory per rank.

Usage::

    python benchmarks/bench_petsc.py        # 3D LPS 40^3 and 2D BB 400^2, 1 and 2 ranks
    python benchmarks/bench_petsc.py --cases lps3d:24 bb2d:200 --ranks 1 2

Each configuration runs as ``mpiexec -n P python benchmarks/bench_petsc.py --worker CASE``;
every rank reports its wall times, its owned rows, its local cloud (owned + halo points) and
its peak resident memory (``resource.getrusage``), and the table shows the slowest rank's
times and the largest rank's memory.  Cases: ``lps3d:N`` (LPS, N^3 grid, delta = 2.015 h,
CG + GAMG), ``bb2d:N`` (bond-based, N^2 grid, delta = 3.015 h, CG + GAMG), ``cor2d:N``
(correspondence with spring control, N^2, delta = 3.015 h).

The header gives the load average and usable cores; the last column marks a speed-up of P
ranks unreliable when the load average at the start exceeded the cores the P ranks left free.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _context import header as context_header  # noqa: E402
from _context import speedup_flag  # noqa: E402


def _problem(case: str):
    import pdlin

    kind, n_s = case.split(":")
    n = int(n_s)
    if kind == "lps3d":
        cloud = pdlin.grid((n, n, n), spacing=1.0 / n)
        model, ratio, force = pdlin.LPS(E=1.0, nu=0.25), 2.015, [1e-3, 0.0, 0.0]
    elif kind == "bb2d":
        cloud = pdlin.grid((n, n), spacing=1.0 / n)
        model, ratio, force = pdlin.BondBased(E=1.0), 3.015, [1e-3, 0.0]
    elif kind == "cor2d":
        cloud = pdlin.grid((n, n), spacing=1.0 / n)
        model = pdlin.Correspondence(E=1.0, nu=0.25, control="springs")
        ratio, force = 3.015, [1e-3, 0.0]
    else:
        raise SystemExit(f"unknown case {case!r}: lps3d:N, bb2d:N or cor2d:N")
    return pdlin.StaticProblem(
        model,
        cloud,
        bond_options={"ratio": ratio},
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", force)],
    )


def worker(case: str, out: Path, solver: str) -> None:
    import pdlin
    from pdlin.backends.petsc import comm_rank_size

    rank, size = comm_rank_size()
    t0 = time.perf_counter()
    c0 = time.process_time()
    prob = _problem(case)
    res = pdlin.solve(prob, solver, rtol=1e-8, backend="petsc")
    rec = {
        "case": case,
        "ranks": size,
        "rank": rank,
        "points": prob.cloud.n,
        "dofs": prob.cloud.ndof,
        "bonds": res.info["n_bonds"],
        "local_rows": res.info["local_rows"],
        "local_points_with_halo": res.info["local_points_with_halo"],
        "local_nnz": res.info["local_nnz"],
        "iterations": res.n_iter,
        "relative_residual": res.relative_residual,
        "timings": res.timings,
        "wall": time.perf_counter() - t0,
        "cpu": time.process_time() - c0,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "ksp": f"{res.info['ksp_type']}+{res.info['pc_type']}",
    }
    (out / f"{case.replace(':', '_')}_{size}_{rank}.json").write_text(json.dumps(rec))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["lps3d:40", "bb2d:400"])
    ap.add_argument("--ranks", nargs="+", type=int, default=[1, 2])
    ap.add_argument("--solver", default="amg-cg")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.worker, Path(args.out), args.solver)
        return
    ctx = context_header()
    mpiexec = shutil.which("mpiexec")
    if mpiexec is None:
        raise SystemExit("mpiexec not found: install PETSc with scripts/install_petsc.sh")
    env = {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        "OMPI_ALLOW_RUN_AS_ROOT": "1",
        "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
        "OMPI_MCA_rmaps_base_oversubscribe": "1",
    }
    out = Path(os.environ.get("TMPDIR", "/tmp")) / f"bench_petsc_{os.getpid()}"
    out.mkdir(parents=True, exist_ok=True)
    header = (
        "| case | points | bonds | ranks | KSP | its | bonds s | assembly s | setup s | "
        "solve s | total s | speed-up | CPU s max / sum | local points (owned + halo) | "
        "peak RSS / rank MB | speed-up reliable? |"
    )
    print(header)
    print("|" + "---|" * (header.count("|") - 1))
    for case in args.cases:
        base = None
        for p in args.ranks:
            cmd = [mpiexec, "-n", str(p), sys.executable, __file__, "--worker", case,
                   "--out", str(out), "--solver", args.solver]  # fmt: skip
            subprocess.run(cmd, check=True, env=env)
            recs = [
                json.loads((out / f"{case.replace(':', '_')}_{p}_{r}.json").read_text())
                for r in range(p)
            ]
            t = {k: max(r["timings"][k] for r in recs) for k in recs[0]["timings"]}
            base = t["total"] if base is None else base
            r0 = recs[0]
            dim = 3 if "3d" in case else 2
            own = [r["local_rows"] // dim for r in recs]
            halo = " / ".join(
                f"{o:,} + {r['local_points_with_halo'] - o:,}"
                for o, r in zip(own, recs, strict=True)
            )
            rss = " / ".join(f"{r['peak_rss_mb']:.0f}" for r in recs)
            print(
                f"| {case} | {r0['points']:,} | {r0['bonds']:,} | {p} | {r0['ksp']} | "
                f"{r0['iterations']} | {t['bonds']:.2f} | {t['assembly']:.2f} | {t['setup']:.2f} | "
                f"{t['solve']:.2f} | {t['total']:.2f} | {base / t['total']:.2f} | "
                f"{max(r['cpu'] for r in recs):.1f} / {sum(r['cpu'] for r in recs):.1f} | "
                f"{halo} | {rss} | {speedup_flag(p, ctx.load1, ctx.cores) or 'yes'} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
