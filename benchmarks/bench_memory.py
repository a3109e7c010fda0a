"""Printed memory estimate against the measured peak RSS of ``pdlin run`` (issue 31, item 11).

Each case is a scene run by ``python -m pdlin run`` in a fresh subprocess; the peak resident
set size is the child's ``ru_maxrss`` (``os.wait4``), the estimate the ``memory estimate:
peak ~X`` line the run prints before its bond search (:func:`pdlin.problem.plan_memory`).
The aim: estimate within +-35 % of the peak on every case.

Cases (each under ~8 GB):

* ``bb2d``: bond-based, 2D grid 548 x 548 (300,304 points), δ = 3.015 h, AMG-CG;
* ``lps3d``: LPS, 24³ grid, δ = 3.015 h, AMG-CG (``operator='auto'`` goes matrix-free);
* ``lps3d-direct``: LPS, 12³ grid, δ = 2.015 h, direct (SuperLU: at 24³ its minimum-degree
  factor needs ~6-15 GB and tens of minutes, see benchmarks/README.md);
* ``cor2d``: correspondence with stress points, 401² grid, δ = 2 h, AMG-CG;
* ``cp_shear``: the built-in crystal-plasticity example (625 points, 30 Newton steps).

Usage: ``python benchmarks/bench_memory.py [--cases bb2d,cor2d]``.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_GRID = """name = "{name}"
[geometry]
type = "grid"
shape = {shape}
spacing = 0.001
[material]
E = 1.0e9
nu = {nu}
[model]
type = "{model}"
{extra}
[horizon]
ratio = {ratio}
[[dirichlet]]
set = "x-"
value = 0.0
[[dirichlet]]
set = "x+"
value = 1.0e-6
components = "x"
[solver]
name = "{solver}"
[output]
path = "{name}.vtu"
"""

CASES: dict[str, dict[str, str]] = {
    "bb2d": dict(shape="[548, 548]", nu="0.3333333333333333", model="bond_based", extra="",
                 ratio="3.015", solver="amg-cg"),
    "lps3d": dict(shape="[24, 24, 24]", nu="0.25", model="lps", extra="", ratio="3.015",
                  solver="amg-cg"),
    "lps3d-direct": dict(shape="[12, 12, 12]", nu="0.25", model="lps", extra="",
                         ratio="2.015", solver="direct"),
    "cor2d": dict(shape="[401, 401]", nu="0.25", model="correspondence",
                  extra='control = "stress_points"', ratio="2.0", solver="amg-cg"),
    "cp_shear": {},
}  # fmt: skip

_UNITS = {"B": 1.0, "kB": 1e3, "MB": 1e6, "GB": 1e9, "TB": 1e12, "PB": 1e15}


def _parse(text: str) -> tuple[float | None, int | None, int | None]:
    m = re.search(
        r"memory estimate: peak ~([\d.]+) (\w+) .*?for ([\d,]+) points, ~([\d,]+) bonds", text
    )
    if not m:
        return None, None, None
    est = float(m.group(1)) * _UNITS[m.group(2)]
    return est, int(m.group(3).replace(",", "")), int(m.group(4).replace(",", ""))


def run_case(name: str, workdir: Path) -> dict[str, object]:
    if CASES[name]:
        scene = workdir / f"{name}.toml"
        scene.write_text(_GRID.format(name=name, **CASES[name]))
        argv = [sys.executable, "-m", "pdlin", "run", str(scene)]
    else:
        argv = [sys.executable, "-m", "pdlin", "run", "--example", name]
    t0 = time.perf_counter()
    proc = subprocess.run(argv, cwd=workdir, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    # this interpreter runs one case (--one): the children's maximum is that run's peak
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024  # KiB on Linux
    err = proc.stderr
    est, n, nb = _parse(err)
    return {
        "case": name, "rc": proc.returncode, "estimate": est, "peak": float(peak), "points": n,
        "bonds": nb, "wall": wall, "stderr": err if proc.returncode else "",
    }  # fmt: skip


def main() -> None:
    from _context import header  # benchmarks/_context.py: load, cores, BLAS, direct backends

    header()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated case names")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()}, {os.cpu_count()} cores, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")  # fmt: skip
    print("| case | points | bonds | estimate (GB) | peak RSS (GB) | estimate / peak | "
          "peak bytes per bond | wall (s) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.cases.split(","):
            # one case at a time: RUSAGE_CHILDREN is a maximum over all children so far,
            # so each case runs under its own interpreter
            r = subprocess.run(
                [sys.executable, __file__, "--one", name, tmp], capture_output=True, text=True
            )
            print(r.stdout.strip() or f"| {name} | failed: {r.stderr.strip()[-300:]} |",
                  flush=True)  # fmt: skip


def _one(name: str, tmp: str) -> None:
    r = run_case(name, Path(tmp))
    if r["rc"] != 0 or r["estimate"] is None:
        print(f"| {name} | run failed (rc {r['rc']}): {str(r['stderr']).strip()[-300:]} |")
        return
    est, peak = float(r["estimate"]), float(r["peak"])  # type: ignore[arg-type]
    bpb = peak / max(int(r["bonds"] or 1), 1)  # type: ignore[call-overload]
    print(
        f"| {name} | {r['points']:,} | {r['bonds']:,} | {est / 1e9:.3f} | {peak / 1e9:.3f} | "
        f"{est / peak:.2f} | {bpb:,.0f} | {float(r['wall']):.1f} |"  # type: ignore[arg-type]
    )


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--one":
        _one(sys.argv[2], sys.argv[3])
    else:
        main()
