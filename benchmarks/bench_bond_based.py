"""Performance of the bond-based pipeline: bonds, assembly, memory and linear solvers.

A bar (3D, ``2m x m x m`` cells) or plate (2D, ``2m x m`` cells) on a
cell-centred grid with horizon 3.015 h (122 / 28 neighbours per interior
point), held on the x- face (``u_x = 0``, plus point pins removing the
remaining rigid motions) and pulled by a total force on the x+ face.
For each size the script prints one table row:

* ``Mb/s``: million directed bonds per second of ``find_bonds`` (lattice
  path) plus ``BondBased.stiffness`` on one core, best of ``--repeat``
  runs, from the process's CPU time (``wall``: from wall time; ``cold``:
  wall time of the first run, which also pays the kernel's first touch of
  fresh memory, ``user``/``sys`` its CPU split);
* ``B/bond``: bytes of the assembled BSR operator per directed bond, and
  the traced peak memory per bond of assembly and of the AMG solve;
* ``spmv``: median CPU time of ``K @ x`` (before and after the AMG runs),
  the unit of the solver columns;
* AMG-PCG (pdlin's defaults, relative residual 1e-8, best of two runs):
  setup and solve in mat-vec equivalents, iterations, levels and operator
  complexity; ``amg wall``: setup + solve from wall times;
* ``amg s`` / ``amg cpu``: setup + solve of the faster AMG run in wall and CPU seconds;
* Jacobi-CG iterations and mat-vec equivalents; the direct solve
  (``direct_backend='auto'``: SuperLU in symmetric mode unless CHOLMOD or PARDISO is
  installed and the system is large; ``backend`` names the one that ran) in mat-vec
  equivalents, wall and CPU seconds for small sizes, and the relative difference of
  the AMG solution to the direct one.

The header (``_context.header``) gives the load average, usable cores, BLAS threads and
the installed direct backends.

Run ``python benchmarks/bench_bond_based.py --quick`` for a small table
(about a minute) or without arguments for the full one (several minutes;
3D up to 2.5e5 points, 2D up to 1e6 points).  ``--large`` adds a 3D bar
of 5e5 points; ``--m2`` / ``--m3`` replace the sizes (e.g. ``--dims 3
--m3 63`` for the 5e5-point bar alone).  The last lines estimate the largest 3D problem fitting in
the machine's memory from the measured peak bytes per bond.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core: CPU time == work
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import gc  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header as context_header  # noqa: E402
from _context import timed  # noqa: E402

import pdlin  # noqa: E402
from pdlin.constraints import eliminate_dirichlet, load_vector, resolve_dirichlet  # noqa: E402
from pdlin.operators.assembly import estimate_bond_operator_bytes  # noqa: E402
from pdlin.operators.rigid import rigid_body_modes  # noqa: E402
from pdlin.solvers import solve_linear  # noqa: E402

RATIO = 3.015


@dataclass
class Row:
    """One line of the table."""

    dim: int
    n: int
    values: dict[str, Any] = field(default_factory=dict)


def stencil_size(dim: int, ratio: float = RATIO) -> int:
    """Neighbours of an interior grid point within ``ratio`` spacings."""
    m = int(np.floor(ratio))
    g = np.stack(np.meshgrid(*[np.arange(-m, m + 1)] * dim, indexing="ij"), -1).reshape(-1, dim)
    r2 = np.sum(g**2, axis=1)
    return int(np.count_nonzero((r2 > 0) & (r2 <= ratio**2 * (1 + 1e-9))))


def make_cloud(dim: int, m: int) -> pdlin.PointCloud:
    shape = (2 * m, m, m) if dim == 3 else (2 * m, m)
    return pdlin.grid(shape, spacing=1.0 / m)


def spmv_time(A: Any, reps: int = 9) -> tuple[float, float]:
    """Median CPU and wall times of ``A @ x``."""
    x = np.random.default_rng(0).standard_normal(A.shape[0])
    A @ x
    cpu, wall = [], []
    for _ in range(reps):
        c0 = time.process_time()
        t0 = time.perf_counter()
        A @ x
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(cpu)), float(np.median(wall))


def run_case(dim: int, m: int, args: argparse.Namespace) -> Row:
    cloud = make_cloud(dim, m)
    n = cloud.n
    row = Row(dim, n)
    v = row.values
    model = pdlin.BondBased(E=1e9)
    nb_est = n * stencil_size(dim)
    est = estimate_bond_operator_bytes(n, nb_est + n, dim)
    print(
        f"# {dim}D n={n:,}: up to {nb_est:,} bonds; K ~ {est / 1e9:.2f} GB, "
        f"bond arrays ~ {64 * nb_est / 1e9:.2f} GB",
        flush=True,
    )
    # -- bonds + assembly: best of `repeat` (first run = cold memory) ----------
    walls, cpus = [], []
    K = bonds = None
    for _ in range(args.repeat):
        del K, bonds
        gc.collect()
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        c0 = os.times()
        t0 = time.perf_counter()
        bonds = pdlin.find_bonds(cloud, ratio=RATIO, method="lattice")
        K = model.stiffness(cloud, bonds)
        walls.append(time.perf_counter() - t0)
        c1 = os.times()
        cpus.append(c1.user - c0.user + c1.system - c0.system)
        peak_asm = tracemalloc.get_traced_memory()[1] - base
        v["user"] = c1.user - c0.user
        v["sys"] = c1.system - c0.system
    assert K is not None and bonds is not None
    nb = bonds.n_bonds
    v["bonds"] = nb
    v["Mb/s"] = nb / min(cpus) / 1e6
    v["Mb/s wall"] = nb / min(walls) / 1e6
    v["Mb/s cold"] = nb / walls[0] / 1e6
    v["B/bond K"] = (K.data.nbytes + K.indices.nbytes + K.indptr.nbytes) / nb
    v["B/bond asm"] = peak_asm / nb
    # -- boundary conditions: roller on x-, rigid motions removed by point --
    # -- pins (as /work/scratch/bar3d.py), total force on x+ ------------------
    load = [1e6 / m ** (dim - 1)] + [0.0] * (dim - 1)
    face = cloud.select("x-")
    bcs = [pdlin.Dirichlet("x-", 0.0, "x"), pdlin.Dirichlet(face[:1], 0.0)]
    if dim == 3:
        bcs.append(pdlin.Dirichlet(face[[0, m]], 0.0, "z"))
    dofs, vals = resolve_dirichlet(cloud, bcs)
    f = load_vector(cloud, [pdlin.TotalForce("x+", load)])
    A, b = eliminate_dirichlet(K, f, dofs, vals, inplace=True)
    del bonds
    B = rigid_body_modes(cloud)
    B[dofs] = 0.0
    # -- AMG-PCG: best of two runs; the K @ x unit is measured before and after
    c_before, w_before = spmv_time(A)
    gc.collect()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    runs = [solve_linear(A, b, "amg-cg", rtol=1e-8, near_null=B, blocksize=dim) for _ in range(2)]
    v["B/bond solve"] = (tracemalloc.get_traced_memory()[1] - base + K.data.nbytes) / nb
    c_after, w_after = spmv_time(A)
    ts = 0.5 * (c_before + c_after)
    tw = 0.5 * (w_before + w_after)
    amg = runs[-1]
    v["spmv ms"] = 1e3 * ts
    v["amg setup"] = min(r.info["setup_cpu"] for r in runs) / ts
    v["amg it"] = amg.n_iter
    v["amg solve"] = min(r.info["solve_cpu"] for r in runs) / ts
    v["amg wall"] = min(r.setup_time + r.solve_time for r in runs) / tw
    v["amg s"] = min(r.setup_time + r.solve_time for r in runs)
    v["amg cpu"] = min(r.info["setup_cpu"] + r.info["solve_cpu"] for r in runs)
    v["levels"] = amg.info["levels"]
    v["op cx"] = amg.info["operator_complexity"]
    # -- Jacobi-CG -------------------------------------------------------------
    if n <= args.jacobi_max[dim]:
        jac = solve_linear(A, b, "jacobi-cg", rtol=1e-8, maxiter=20000)
        v["jac it"] = jac.n_iter
        v["jac spmv"] = (jac.info["setup_cpu"] + jac.info["solve_cpu"]) / ts
    # -- direct ----------------------------------------------------------------
    if n <= args.direct_max[dim]:
        with timed() as t:
            d = solve_linear(A, b, "direct")
        v["direct spmv"] = t.cpu / ts
        v["direct s"] = t.wall
        v["direct cpu"] = t.cpu
        v["backend"] = d.info.get("direct_backend", "?")
        v["err"] = float(np.linalg.norm(amg.x - d.x) / np.linalg.norm(d.x))
    return row


COLUMNS = [  # name, width, format
    ("dim", 3, "{}"),
    ("n", 9, "{:,}"),
    ("bonds", 11, "{:,}"),
    ("Mb/s", 5, "{:.2f}"),
    ("Mb/s wall", 9, "{:.2f}"),
    ("Mb/s cold", 9, "{:.2f}"),
    ("user", 5, "{:.2f}"),
    ("sys", 5, "{:.2f}"),
    ("B/bond K", 8, "{:.1f}"),
    ("B/bond asm", 10, "{:.1f}"),
    ("B/bond solve", 12, "{:.1f}"),
    ("spmv ms", 7, "{:.2f}"),
    ("amg setup", 9, "{:.1f}"),
    ("amg it", 6, "{}"),
    ("amg solve", 9, "{:.1f}"),
    ("amg wall", 8, "{:.1f}"),
    ("amg s", 6, "{:.3g}"),
    ("amg cpu", 7, "{:.3g}"),
    ("levels", 6, "{}"),
    ("op cx", 5, "{:.2f}"),
    ("jac it", 6, "{}"),
    ("jac spmv", 8, "{:.1f}"),
    ("direct spmv", 11, "{:.1f}"),
    ("direct s", 8, "{:.3g}"),
    ("direct cpu", 10, "{:.3g}"),
    ("backend", 8, "{}"),
    ("err", 8, "{:.1e}"),
]


def fmt_row(row: Row) -> str:
    cells = []
    for name, width, f in COLUMNS:
        val = row.dim if name == "dim" else row.n if name == "n" else row.values.get(name)
        text = "-" if val is None else f.format(val)
        cells.append(text.rjust(max(width, len(name))))
    return " ".join(cells)


def header() -> str:
    return " ".join(name.rjust(max(width, len(name))) for name, width, _ in COLUMNS)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small sizes only (about a minute)")
    p.add_argument("--large", action="store_true", help="add a 3D bar of 5e5 points")
    p.add_argument("--dims", type=int, nargs="+", default=[2, 3], choices=[2, 3])
    p.add_argument("--m2", type=int, nargs="+", help="2D sizes m (plate 2m x m)")
    p.add_argument("--m3", type=int, nargs="+", help="3D sizes m (bar 2m x m x m)")
    p.add_argument("--repeat", type=int, default=2, help="bonds+assembly repetitions")
    p.add_argument("--memory-gb", type=float, default=24.0, help="memory of the target machine")
    args = p.parse_args(argv)
    if args.quick:
        sizes = {2: [50, 141], 3: [8, 16]}
        args.jacobi_max = {2: 10**5, 3: 10**5}
        args.direct_max = {2: 10**5, 3: 10**4}
    else:
        sizes = {2: [50, 141, 400, 708], 3: [10, 20, 40, 50]}
        if args.large:
            sizes[3].append(63)
        args.jacobi_max = {2: 3.3e5, 3: 1.3e5}
        args.direct_max = {2: 4.0e4, 3: 2.0e3}
    if args.m2:
        sizes[2] = args.m2
    if args.m3:
        sizes[3] = args.m3
    print("# pdlin bond-based benchmark")
    context_header()
    print(
        "# horizon 3.015 h; solver columns in K @ x equivalents: CPU time of the step / CPU time"
        " of one K @ x ('amg wall': AMG setup + solve in wall time / wall spmv)"
    )
    tracemalloc.start()
    rows = []
    print(header(), flush=True)
    for dim in args.dims:
        for m in sizes[dim]:
            row = run_case(dim, m, args)
            rows.append(row)
            print(fmt_row(row), flush=True)
    tracemalloc.stop()
    three = [r for r in rows if r.dim == 3]
    if three:
        big = max(three, key=lambda r: r.n)
        per_bond = max(big.values["B/bond asm"], big.values["B/bond solve"])
        per_point = per_bond * stencil_size(3)
        n_max = 0.9 * args.memory_gb * 1e9 / per_point
        print(
            f"# estimate (not run): largest 3D bar in {args.memory_gb:g} GB at "
            f"{per_bond:.0f} peak bytes/bond (n={big.n:,}) x {stencil_size(3)} bonds/point, "
            f"90 % usable: ~{n_max / 1e6:.1f} million points "
            f"(~{n_max * stencil_size(3) / 1e6:,.0f} million bonds)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
