"""Figures of the CPPD / CPFE comparison in docs/crystal_plasticity.md (cf. Luo, Ramazani &
Sundararaghavan 2017, Figs. 5, 8, 14).

Reads the runs of ``benchmarks/bench_cpfe.py`` from its cache (running the missing ones,
minutes at 2,500 particles) and writes to ``docs/figures/``:

* ``cpfe_stress_strain.png`` -- homogenized σ_xy (shear) and σ_yy (compression) of CPPD
  and CPFE at 225 / 625 / 2,500 particles (Fig. 14);
* ``cpfe_shear_sxy.png`` -- σ_xy maps at strain 0.06, CPPD beside CPFE, per grid (Fig. 5);
* ``cpfe_reorientation.png`` -- reorientation under Y-compression at strain 0.06: CPFE,
  CPPD δ = l_e and δ = √2 l_e at the largest grid given (Fig. 8).

Usage::

    python docs/gen_cpfe_figures.py                   # n = 15 25 50, cache /tmp/pdlin-cpfe
    python docs/gen_cpfe_figures.py --n 15 25 --out /tmp/figs
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "benchmarks"))
import bench_cpfe as bc  # noqa: E402


def _map(ax, field, n, **kw):
    return ax.imshow(np.asarray(field).reshape(n, n).T, origin="lower", extent=(0, 1, 0, 1), **kw)


def main(argv: list[str] | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ap = argparse.ArgumentParser(description="CPPD / CPFE figures")
    ap.add_argument("--n", type=int, nargs="+", default=[15, 25, 50])
    ap.add_argument("--cache", type=Path, default=Path("/tmp/pdlin-cpfe"))
    ap.add_argument("--out", type=Path, default=HERE / "figures")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)

    def run(kind: str, load: str, n: int) -> dict:
        return bc.solve(n, load, kind, args.cache)

    strain = 0.002 * bc.STEPS
    # -- Fig. 14: homogenized curves ----------------------------------------------------
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    colors = dict(zip(args.n, ["tab:blue", "tab:orange", "tab:green", "tab:red"], strict=False))
    for ax, load in zip(axes, ("shear", "compression"), strict=True):
        i, j = bc.COMPONENT[load]
        sign = 1.0 if load == "shear" else -1.0
        for n in args.n:
            for kind, style in (("cpfe", "-"), ("cppd", "--")):
                v = sign * run(kind, load, n)["hom"][:, i, j]
                ax.plot(strain, v, style, color=colors[n], label=f"{kind.upper()} {n * n}")
        ax.set_xlabel("strain")
        ax.set_ylabel("σ_xy (MPa)" if load == "shear" else "−σ_yy (MPa)")
        ax.set_title(f"{load}: CPPD (dashed) vs CPFE (solid)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(args.out / "cpfe_stress_strain.png", dpi=110)
    plt.close(fig)

    # -- Fig. 5: σ_xy maps ---------------------------------------------------------------
    fig, axes = plt.subplots(2, len(args.n), figsize=(3.3 * len(args.n), 6.2), squeeze=False)
    maps = {(k, n): run(k, "shear", n)["stress"][:, 0, 1] for n in args.n for k in ("cppd", "cpfe")}
    lo = min(np.percentile(v, 1) for v in maps.values())
    hi = max(np.percentile(v, 99) for v in maps.values())
    for c, n in enumerate(args.n):
        for r, kind in enumerate(("cppd", "cpfe")):
            im = _map(axes[r, c], maps[kind, n], n, cmap="jet", vmin=lo, vmax=hi)
            axes[r, c].set_title(f"{kind.upper()}, {n * n} {'particles' if r == 0 else 'elements'}")
            axes[r, c].set_xticks([])
            axes[r, c].set_yticks([])
    fig.colorbar(im, ax=axes, shrink=0.8, label="σ_xy (MPa), strain 0.06")
    fig.savefig(args.out / "cpfe_shear_sxy.png", dpi=110, bbox_inches="tight")
    plt.close(fig)

    # -- Fig. 8: reorientation maps -----------------------------------------------------
    n = max(args.n)
    kinds = (("cpfe", "CPFE"), ("cppd", "CPPD, δ = l_e"), ("cppd-sqrt2", "CPPD, δ = √2 l_e"))
    rots = {k: run(k, "compression", n)["rot"] for k, _ in kinds}
    lim = max(np.percentile(np.abs(v), 99.5) for v in rots.values())
    fig, axes = plt.subplots(1, 3, figsize=(12, 4))
    for ax, (k, title) in zip(axes, kinds, strict=True):
        im = _map(ax, rots[k], n, cmap="RdBu_r", vmin=-lim, vmax=lim)
        ax.set_title(f"{title} ({n * n})")
        ax.set_xticks([])
        ax.set_yticks([])
    fig.colorbar(im, ax=axes, shrink=0.8, label="reorientation Δθ (deg), Y-compression, 0.06")
    fig.savefig(args.out / "cpfe_reorientation.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    print("wrote", *(args.out / f for f in ("cpfe_stress_strain.png", "cpfe_shear_sxy.png",
                                            "cpfe_reorientation.png")))  # fmt: skip


if __name__ == "__main__":
    main()
