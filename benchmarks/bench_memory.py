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
* ``lps3d-direct24`` (only with ``--cases``): LPS, 24³ grid, δ = 3.015 h, direct with the
  backend ``auto`` picks (CHOLMOD or PARDISO after ``scripts/install_direct.sh``; with SuperLU
  alone the run is refused before its bond search);
* ``cor2d``: correspondence with stress points, 401² grid, δ = 2 h, AMG-CG;
* ``cp_shear``: the built-in crystal-plasticity example (625 points, 30 Newton steps).

Usage: ``python benchmarks/bench_memory.py [--cases bb2d,cor2d]``.

``--stages`` prints instead the peak RSS per stage of ``pdlin.solve(problem)`` (defaults:
assembled K, AMG-CG) on a 3D bond-based cube (δ = 3.015 h, x- clamped, x+ pulled with a
``TotalForce``) at 40³ and 60³ (80³ and 100³ with ``--big``, ~13 and ~20 GB), each size in a
fresh interpreter.  A stage's peak is the kernel's ``VmHWM`` since the previous stage
boundary (reset by writing ``5`` to ``/proc/self/clear_refs``); the boundaries are the
progress messages of :func:`pdlin.solve` and the entry of ``ConstrainedSystem.eliminate``.
Stages: ``grid`` (``pdlin.grid``), ``plan`` (the ``StaticProblem`` and the printed estimate),
``bonds`` (bond search, Dirichlet and load resolution), ``assembly`` (K and its prescribed
rows), ``elimination``, ``checks`` (``solve_linear``'s input checks: K finite and in range),
``AMG setup``, ``solve`` (CG, expansion, reactions), ``fields`` (``result.fields()``).
Each cell is GB (bytes per directed bond). Two more rows (``STAGE_MODELS``; ``--no-models``
leaves them out) audit the other 3D models with their defaults: LPS at 30³ (matrix-free
operator, AMG-CG on its surrogate) and correspondence with stress points at 20³ (δ =
3.015 h; for them "assembly" is the operator's set-up). ``--sizes 80,100`` runs chosen
bond-based sizes.
``--save-u DIR`` / ``--check-u DIR`` store / compare (bit for bit) the displacement of each
size, to show that a memory change keeps the results identical.
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
    # the 24³ direct case: needs CHOLMOD / PARDISO (scripts/install_direct.sh);
    # SuperLU is refused before the bond search (its estimate does not fit in 24 GB)
    "lps3d-direct24": dict(shape="[24, 24, 24]", nu="0.25", model="lps", extra="",
                           ratio="3.015", solver="direct"),
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
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = use.ru_utime + use.ru_stime
    # this interpreter runs one case (--one): the children's maximum is that run's peak
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024  # KiB on Linux
    err = proc.stderr
    est, n, nb = _parse(err)
    return {
        "case": name, "rc": proc.returncode, "estimate": est, "peak": float(peak), "points": n,
        "bonds": nb, "wall": wall, "cpu": cpu, "stderr": err if proc.returncode else "",
    }  # fmt: skip


#: cube edges (points per side) of the ``--stages`` table; ``--big`` adds the large ones
STAGE_SIZES = (40, 60)
STAGE_SIZES_BIG = (80, 100)


def _status_kib(key: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return 0


class _StagePeaks:
    """Peak RSS per stage: ``VmHWM`` read and reset at each stage boundary."""

    def __init__(self) -> None:
        self.stage = "start"
        self.peaks: dict[str, int] = {}
        self.seconds: dict[str, float] = {}
        self.t = time.perf_counter()
        self._reset()

    @staticmethod
    def _reset() -> None:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")

    def mark(self, stage: str) -> None:
        peak = _status_kib("VmHWM") * 1024
        self.peaks[self.stage] = max(self.peaks.get(self.stage, 0), peak)
        now = time.perf_counter()
        self.seconds[self.stage] = self.seconds.get(self.stage, 0.0) + now - self.t
        self.t = now
        self.stage = stage
        self._reset()

    def progress(self, msg: str) -> None:
        for prefix, stage in (("bonds", "bonds"), ("assembly", "assembly"),
                              ("solve (", "checks"), ("  AMG set-up", "AMG setup"),
                              ("  AMG hierarchy", "solve")):  # fmt: skip
            if msg.startswith(prefix):
                self.mark(stage)
        if msg.startswith("memory estimate"):
            self.estimate_line = msg


#: the ``--stages`` rows of the other 3D models (model, cube edge, horizon ratio): LPS with
#: its default operator (matrix-free with AMG-CG) and correspondence with stress points
STAGE_MODELS = (("lps", 30, 3.015), ("cor", 20, 3.015))


def _model(kind: str) -> object:
    import pdlin

    if kind == "lps":
        return pdlin.LPS(E=1.0e9, nu=0.25)
    if kind == "cor":
        return pdlin.Correspondence(E=1.0e9, nu=0.25, control="stress_points")
    return pdlin.BondBased(E=1.0e9, nu=0.25)


def _stages_one(
    m: int, save: str | None, check: str | None, kind: str = "bb", ratio: float = 3.015
) -> None:
    """One size of the ``--stages`` table, in this interpreter (prints one row)."""
    import numpy as np

    import pdlin
    from pdlin.system import ConstrainedSystem

    cpu0 = time.process_time()  # all threads of this interpreter
    rec = _StagePeaks()
    rec.estimate_line = ""
    original = ConstrainedSystem.eliminate

    def eliminate(self: ConstrainedSystem, *a: object, **k: object) -> object:
        rec.mark("elimination")
        return original(self, *a, **k)

    ConstrainedSystem.eliminate = eliminate  # type: ignore[method-assign]
    rec.mark("grid")
    h = 1.0 / m
    cloud = pdlin.grid((m, m, m), spacing=h)
    prob = pdlin.StaticProblem(
        _model(kind), cloud, ratio=ratio,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)], loads=[pdlin.TotalForce("x+", [1.0e3, 0.0, 0.0])],
    )  # fmt: skip
    rec.mark("plan")
    res = pdlin.solve(prob, progress=rec.progress)
    rec.mark("fields")
    res.fields()
    rec.mark("end")
    ConstrainedSystem.eliminate = original  # type: ignore[method-assign]
    nb = res.bonds.n_bonds
    est = _parse(rec.estimate_line + " ")[0] if rec.estimate_line else None
    u = np.ascontiguousarray(res.u)
    same = "-"
    tag = f"{m}" if kind == "bb" else f"{kind}_{m}"
    if save:
        np.save(Path(save) / f"u_{tag}.npy", u)
    if check and (Path(check) / f"u_{tag}.npy").exists():
        ref = np.load(Path(check) / f"u_{tag}.npy")
        if ref.shape != u.shape or ref.tobytes() != u.tobytes():
            raise SystemExit(f"{m}^3: u differs from {check}/u_{m}.npy (max |du| "
                             f"{float(np.max(np.abs(ref - u))):.3e})")  # fmt: skip
        same = "bitwise equal"
    order = ("grid", "plan", "bonds", "assembly", "elimination", "checks", "AMG setup",
             "solve", "fields")  # fmt: skip
    cells = " | ".join(
        f"{rec.peaks.get(s, 0) / 1e9:.2f} ({rec.peaks.get(s, 0) / nb:.0f})" for s in order
    )
    peak = max(rec.peaks.values())
    label = {"bb": "", "lps": "LPS ", "cor": "corr. SP "}[kind]
    print(f"| {label}{m}³ = {m**3:,} | {nb:,} | {cells} | {peak / 1e9:.2f} ({peak / nb:.0f}) | "
          f"{(est or 0) / 1e9:.2f} | {(est or 0) / peak:.2f} | {res.n_iter} | "
          f"{sum(rec.seconds.values()):.1f} | {time.process_time() - cpu0:.1f} | "
          f"{same} |")  # fmt: skip


def stages(
    sizes: tuple[int, ...], save: str | None, check: str | None, models: bool = True
) -> None:
    """Print the per-stage peak RSS table (each size in a fresh interpreter)."""
    print("peak RSS per stage, GB (bytes per directed bond); estimate = pdlin's printed "
          "'memory estimate' (GB)")  # fmt: skip
    print(
        "| points | directed bonds | grid | plan | bonds | assembly | elimination | checks | "
        "AMG setup | solve | fields | peak | estimate | estimate / peak | CG its | wall (s) | "
        "CPU (s) | u |"
    )
    print("|---" * 18 + "|")
    rows = [("bb", m, 3.015) for m in sizes] + list(STAGE_MODELS if models else ())
    for kind, m, ratio in rows:
        argv = [sys.executable, __file__, "--stage-one", str(m), save or "", check or "", kind,
                str(ratio)]  # fmt: skip
        r = subprocess.run(argv, capture_output=True, text=True)
        print(r.stdout.strip() or f"| {kind} {m}³ | failed: {r.stderr.strip()[-300:]} |",
              flush=True)  # fmt: skip


def main() -> None:
    from _context import header  # benchmarks/_context.py: load, cores, BLAS, direct backends

    header()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--cases",
        default=",".join(c for c in CASES if c != "lps3d-direct24"),
        help="comma-separated case names (lps3d-direct24 only when asked)",
    )
    ap.add_argument("--stages", action="store_true",
                    help="per-stage peak RSS of a 3D bond-based cube (40³, 60³)")  # fmt: skip
    ap.add_argument("--big", action="store_true", help="with --stages: also 80³ and 100³")
    ap.add_argument(
        "--sizes",
        default=None,
        help="with --stages: comma-separated cube edges (bond-based rows only)",
    )
    ap.add_argument(
        "--no-models",
        action="store_true",
        help="with --stages: without the LPS and correspondence rows",
    )
    ap.add_argument("--save-u", default=None, help="with --stages: store u of each size here")
    ap.add_argument("--check-u", default=None,
                    help="with --stages: compare u bit for bit with the stored one")  # fmt: skip
    args = ap.parse_args()
    if args.stages:
        print(f"load average {os.getloadavg()}, {os.cpu_count()} cores, "
              f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")  # fmt: skip
        sizes = STAGE_SIZES + (STAGE_SIZES_BIG if args.big else ())
        if args.sizes:
            sizes = tuple(int(v) for v in args.sizes.split(","))
        stages(sizes, args.save_u, args.check_u, not args.no_models)
        return
    print(f"load average {os.getloadavg()}, {os.cpu_count()} cores, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")  # fmt: skip
    print("| case | points | bonds | estimate (GB) | peak RSS (GB) | estimate / peak | "
          "peak bytes per bond | wall (s) | CPU (s) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
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
        f"{est / peak:.2f} | {bpb:,.0f} | {float(r['wall']):.1f} | "  # type: ignore[arg-type]
        f"{float(r['cpu']):.1f} |"  # type: ignore[arg-type]
    )


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--one":
        _one(sys.argv[2], sys.argv[3])
    elif len(sys.argv) in (5, 7) and sys.argv[1] == "--stage-one":
        extra = (sys.argv[5], float(sys.argv[6])) if len(sys.argv) == 7 else ()
        _stages_one(int(sys.argv[2]), sys.argv[3] or None, sys.argv[4] or None, *extra)
    else:
        main()
