"""Tables of docs/tradeoff.md: pdlin.tradeoff on the bundled problems.

    python benchmarks/tradeoff_tables.py              # about 1-2 minutes on 2 cores
    python benchmarks/tradeoff_tables.py --out DIR    # also CSV tables and PNG figures

Each sweep prints a Markdown table (Pareto rows marked *), its convergence rates and the
fastest configuration meeting an error target.  Every point runs in a forked child, so
``peak MB`` is that child's peak resident-set growth during the solve.  ``solver used`` names
the solver that ran, a direct one with its backend (``direct (superlu)``); each sweep's time
is given in wall and CPU seconds (the forked children's included) after the context header.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

import pdlin
from pdlin.sweeps import TradeoffResult, affine_patch, graded_bar, plate_with_hole, tension_bar

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, timed  # noqa: E402

SWEEPS: list[tuple[str, Any, dict[str, list[Any]], float, str]] = [
    (
        "tension_bar_3d",
        tension_bar,
        {
            "model": ["bb", "lps", "xosb", "correspondence:penalty"],
            "dim": [3],
            "h": [0.125, 0.0625],
            "m": [2.0, 3.015],
            "symmetry": [True],
        },
        0.05,
        "3D bar 2 x 1 x 1 in tension (quarter model), ends in shadow layers, lateral faces free; "
        "closed form",
    ),
    (
        "plate_with_hole",
        plate_with_hole,
        {
            "model": ["bb", "lps", "xosb", "correspondence:penalty"],
            "h": [1 / 20, 1 / 40],
            "m": [2.0, 3.015],
        },
        0.03,
        "square plate with a hole (Liu, Chen & Skelton, XOSB, Sec. 5.1), edges held at the Q4 "
        "solution; Q4 reference",
    ),
    (
        "graded_bar_1d",
        graded_bar,
        {
            "control": ["higher_order", "none", "penalty"],
            "m": [1, 2, 4],
            "N": [100, 200, 400],
        },
        0.05,
        "1D graded bar (Javaheri et al. 2022, Sec. III.A), correspondence; closed form "
        "(sqrt singularity)",
    ),
    (
        "affine_patch_solvers",
        affine_patch,
        {
            "model": ["bb"],
            "dim": [2],
            "h": [0.01],
            "m": [3.015],
            "solver": ["direct", "amg-cg", "jacobi-cg"],
            "rtol": [1e-4, 1e-6, 1e-8],
        },
        1e-6,
        "2D affine patch 100 x 100, bond-based; closed form (the error is the solver's)",
    ),
]


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        if not np.isfinite(v):
            return "-"
        return f"{v:.3g}"
    return str(v)


def markdown(res: TradeoffResult) -> str:
    front = {id(r) for r in res.pareto()}
    cols = [p for p in res.params if len({str(r[p]) for r in res.table}) > 1]
    head = [*cols, "error", "bonds s", "assembly s", "setup s", "solve s", "total s",
            "peak MB", "nnz", "it", "solver used", "status"]  # fmt: skip
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in res.table:
        mark = "**" if id(r) in front else ""
        cells = [_fmt(r[c]) for c in cols]
        cells += [f"{mark}{_fmt(r['error'])}{mark}"]
        cells += [_fmt(r[c]) for c in ("t_bonds", "t_assembly", "t_setup", "t_solve")]
        cells += [f"{mark}{_fmt(r['t_total'])}{mark}"]
        cells += [_fmt(r["peak_mb"]), _fmt(r["nnz"]), _fmt(r["iterations"])]
        cells += [str(r.get("solver_used") or "-"), str(r["status"])]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def rates_text(res: TradeoffResult) -> str:
    out = []
    for x in ("h", "delta"):
        try:
            groups = res.rates(x)
        except pdlin.errors.InputError:
            continue
        for g in groups:
            fixed = ", ".join(
                f"{k}={g[k]}"
                for k in g
                if k not in ("rate", "n", "x", "error") and len({str(r[k]) for r in res.table}) > 1
            )
            out.append(f"- rate in {x}: {g['rate']:.2f} ({g['n']} points; {fixed})")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, help="folder for CSV tables and PNG figures")
    ap.add_argument("--only", help="run one sweep by name")
    args = ap.parse_args(argv)
    header()
    with timed() as t_all:
        for name, factory, grid, target, title in SWEEPS:
            if args.only and name != args.only:
                continue
            sweep(name, factory, grid, target, title, args.out)
    print(f"\ntotal {t_all.wall:.1f} s (CPU {t_all.cpu:.1f} s)")


def sweep(name: str, factory: Any, grid: dict, target: float, title: str, out_dir: Any) -> None:
    """Run one sweep and print its table, rates, choice and time."""
    with timed() as t0:
        out = None
        if out_dir is not None:
            out_dir.mkdir(parents=True, exist_ok=True)
            out = out_dir / f"{name}.csv"
        res = pdlin.tradeoff(factory, grid, output=out, resume=False, timeout=300.0)
    print(f"\n### {name}: {title}\n")
    print(f"reference: {res.reference}\n")
    print(markdown(res))
    print()
    print(rates_text(res))
    best = res.best(target)
    if best is None:
        print(f"- no configuration meets error <= {target:g}")
    else:
        print(
            f"- fastest with error <= {target:g}: {best['key']} (error "
            f"{best['error']:.3g}, {best['t_total']:.3g} s)"
        )
    print(f"- sweep time {t0.wall:.1f} s (CPU {t0.cpu:.1f} s, forked points included)")
    if out_dir is not None:
        res.plot(out_dir / f"{name}.png")


if __name__ == "__main__":
    main()
