"""Performance of the micromodulus calibration (Prakash, anisotropic micromoduli).

Table 1, single families: 3D simple cubic spheres (delta = 3, 6, 9, omega =
delta/|xi|) and 2D square / triangular disks (delta = 3, 6, 12), calibrated
against a target that needs the QP (cubic spinel MgAl2O4, the paper's Eq. 87; in 2D its
plane-strain part) and against one where step 1 suffices (triclinic KIO3 /
plane stress).  Columns are the wall time per solver path, best of
``--repeat`` runs:

* ``min-norm``: step 1 only (SVD pseudo-inverse on merged columns);
* ``qp:<solver>``: two-step method with Clarabel (direct API), OSQP
  (direct API, eps 1e-10, polishing) or cvxpy (Clarabel, then OSQP), each
  refined by the exact active-set solve;
* ``robust``: NNLS start + QP (Clarabel).

Table 2, clouds: ``calibrate_micromoduli(C, bonds)`` on a cubic block (all
distinct families, including truncated boundary families, calibrated once
each, then scattered and averaged over bond pairs), split into bond search,
family grouping, the family solves and the rest (scatter + per-point
tensors).

Run ``python benchmarks/bench_calibration.py --quick`` (under a minute) or
without arguments (50^3 block with delta = 3 and 24^3 with delta = 6, about 75 s).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, timed  # noqa: E402

import pdlin  # noqa: E402
from pdlin.calibration import calibrate_micromoduli, lattice_family  # noqa: E402
from pdlin.calibration.cloud import group_families  # noqa: E402
from pdlin.constitutive import material  # noqa: E402


def _best(repeat: int, *args, **kwargs) -> tuple[float, float, object]:
    """Best wall time of ``calibrate_micromoduli(*args, **kwargs)`` over ``repeat`` runs,
    that run's CPU time and the result."""
    best, cpu = np.inf, np.inf
    out = None
    for _ in range(repeat):
        with timed() as t:
            out = calibrate_micromoduli(*args, **kwargs)
        if t.wall < best:
            best, cpu = t.wall, t.cpu
    return best, cpu, out


def family_table(repeat: int, quick: bool) -> None:
    cases = [(3, "cubic", d) for d in ((3.0, 6.0) if quick else (3.0, 6.0, 9.0))]
    cases += [(2, lat, d) for lat in ("square", "triangular") for d in (3.0, 6.0, 12.0)]
    paths = [
        ("min-norm", {"method": "min-norm"}),
        ("qp:clarabel", {"qp_solver": "clarabel"}),
        ("qp:osqp", {"qp_solver": "osqp"}),
        ("qp:cvxpy", {"qp_solver": "cvxpy"}),
        ("robust", {"method": "robust"}),
    ]
    # warm-up: imports of clarabel, osqp, cvxpy are not part of the timings
    fam = lattice_family(3, 3.0)
    for _, kw in paths:
        calibrate_micromoduli(material("cubic"), fam, **kw)
    print(f"\nTable 1: single families (wall ms / CPU ms, best of {repeat})")
    head = "| dim | lattice | delta | bonds | columns | target | status |"
    head += "".join(f" {p} |" for p, _ in paths) + " error % |"
    print(head)
    print("|" + "---|" * (8 + len(paths)))
    for dim, lat, delta in cases:
        fam = lattice_family(dim, delta, lattice=lat, influence="delta_over_r")
        for tname in ("cubic", "triclinic"):
            C = material(tname)
            plane = "strain" if tname == "cubic" else "stress"
            times = []
            res = None
            for _, kw in paths:
                t, c, r = _best(repeat, C, fam, plane=plane, **kw)
                times.append((t, c))
                if kw.get("qp_solver") == "clarabel":
                    res = r
            assert res is not None
            row = (
                f"| {dim} | {lat} | {delta:g} | {fam.n_bonds} | {res.n_columns} | {tname}"
                f"{'' if dim == 3 else ' (' + plane + ')'} | {res.status} |"
            )
            row += "".join(f" {1e3 * t:.1f} / {1e3 * c:.1f} |" for t, c in times)
            row += f" {100 * res.relative_error:.4f} |"
            print(row, flush=True)


def cloud_table(quick: bool) -> None:
    blocks = [(24, 2.0), (20, 3.0), (16, 6.0)] if quick else [(24, 2.0), (50, 3.0), (24, 6.0)]
    C = material("cubic") * 1e9
    print("\nTable 2: per-point calibration of every distinct family of a cubic block (wall s)")
    print(
        "| block | delta | points | directed bonds | distinct families | bonds s | group s "
        "| family solves s | total calibrate s (CPU s) | max error % | pair change |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for n, delta in blocks:
        t = time.perf_counter()
        cloud = pdlin.grid((n, n, n))
        bonds = pdlin.find_bonds(cloud, delta)
        tb = time.perf_counter() - t
        t = time.perf_counter()
        fam_of_pt, reps, _ = group_families(bonds)
        tg = time.perf_counter() - t
        with timed() as tcal:
            res = calibrate_micromoduli(C, bonds, method="robust")
        tc = tcal.wall
        tf = sum(f.time for f in res.families)
        print(
            f"| {n}^3 | {delta:g} | {cloud.n:,} | {bonds.n_bonds:,} | {reps.size} | {tb:.2f} "
            f"| {tg:.2f} | {tf:.2f} | {tc:.2f} ({tcal.cpu:.2f}) "
            f"| {100 * float(np.max(res.relative_error)):.3g} "
            f"| {res.pair_change:.3g} |",
            flush=True,
        )
        del bonds, res, cloud


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller cases")
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs (default 3)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    header()
    family_table(args.repeat, args.quick)
    cloud_table(args.quick)
    print(f"\ntotal {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
