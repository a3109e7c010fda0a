"""Crystal-plasticity peridynamics on a 21-grain polycrystal: Newton and ADR.

Tutorial for docs/tutorial_crystal_plasticity.md; the solver options are described in
docs/nonlinear.md.  Reproduces the setup of Luo, Ramazani & Sundararaghavan (2017), Sec. 4
(Ex. 1 and Ex. 2; docs/theory/conventions.md, "Polycrystal"):

* unit square (mm), n x n particles at the pixel centres, δ = h (4 neighbours, ω = 1),
  ``pdlin.Correspondence(material=pdlin.CrystalPlasticity("planar-2"))``;
* 21 Voronoi grains (``pdlin.voronoi_polycrystal``, seed 1; the paper's map is not
  given), orientations from the 12-value set, every one used at least once;
* the boundary ring follows ``u = (exp(L t) - I) x`` (``Dirichlet.velocity_gradient``),
  30 load steps t = 1..30, η = 0.002: **Ex. 1** pure shear ``L = η [[0, 1], [1, 0]]`` and
  **Ex. 2** Y-compression ``L = η diag(1, -1)``; strain ηt = 0.06 at the last step.

For each load the *reference* history is solved with ``--method`` (default ``'auto'``:
Newton, and ADR from the step's committed state on a step Newton fails), in
segments that leave a checkpoint at every compared step.  The other driver (ADR for a
Newton history) then solves the compared steps **from the same committed state**
(checkpoint copy + ``resume="branch"``), and the two homogenized (volume-averaged Cauchy)
stresses are compared: plastic equilibria are not unique (docs/theory/conventions.md), so only the
homogenized stress of one step from one shared state is a fair comparison, never pointwise
fields (expected ≲ 1e-3 relative).

Run::

    python examples/crystal_plasticity_polycrystal.py                 # n = 25, 625 particles
    python examples/crystal_plasticity_polycrystal.py --n 50 --out figs  # the paper's 2,500
    python examples/crystal_plasticity_polycrystal.py --no-plots --compare all

It prints one table per load (strain, homogenized σ, iterations and time of both drivers,
relative difference) and writes into ``--out`` (default ``cp_polycrystal_out``):
``<load>.pvd`` (+ one ``.vtu`` per step in ``<load>.pvd.<tag>/``: Displacement,
Reaction_Force, Cauchy_Stress and the committed state, e.g. ``State_reorientation``),
``<load>_homogenized.csv`` and, unless ``--no-plots``, the figures ``cp_shear_sxy.png``,
``cp_compression_reorientation.png``, ``cp_grains.png``,
``cp_stress_strain.png``, ``cp_adr.png`` (matplotlib, imported only then).
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import pdlin
from pdlin.errors import ConvergenceError
from pdlin.io.results import write_homogenized_csv, write_nonlinear

# velocity-gradient magnitude per unit time (Luo, Ramazani & Sundararaghavan 2017, Sec. 4)
ETA = 0.002
LOADS = {
    "shear": ETA * np.array([[0.0, 1.0], [1.0, 0.0]]),
    "compression": ETA * np.array([[1.0, 0.0], [0.0, -1.0]]),
}
#: the stress component plotted for each load (homogenized σ_xy, σ_yy)
COMPONENT = {"shear": (0, 1), "compression": (1, 1)}
DEFAULT_COMPARE = (1, 2, 3, 5, 7, 10, 15, 20, 25, 30)


def build(n: int, load: str, *, grains: int = 21, seed: int = 1) -> dict[str, Any]:
    """The n x n polycrystal problem of one load (``'shear'`` or ``'compression'``)."""
    h = 1.0 / n
    cloud = pdlin.grid((n, n), spacing=h)  # pixel centres ((i + 1/2) h, (j + 1/2) h)
    bonds = pdlin.find_bonds(cloud, ratio=1.0, influence="constant")  # δ = h, ω = 1
    grain, theta = pdlin.voronoi_polycrystal(cloud, grains, seed=seed)
    material = pdlin.CrystalPlasticity("planar-2", orientation=theta)
    model = pdlin.Correspondence(material=material)
    bc = pdlin.Dirichlet.velocity_gradient("boundary", LOADS[load])  # centre: the corner
    prob = pdlin.StaticProblem(model, cloud, bonds, dirichlet=[bc])
    return {"problem": prob, "cloud": cloud, "grain": grain, "theta": theta, "material": material}


def _one_step(
    prob: pdlin.StaticProblem, times: np.ndarray, method: str, checkpoint: Path | None
) -> dict[str, Any]:
    """Solve the last of ``times`` with ``method`` from the state committed in ``checkpoint``."""
    t0 = time.perf_counter()
    try:
        res = pdlin.solve_nonlinear(
            prob,
            times=times,
            method=method,
            checkpoint=checkpoint,
            resume="branch" if checkpoint is not None else False,  # another driver
            keep_states=False,
        )
    except ConvergenceError as exc:
        return {"ok": False, "message": str(exc), "time": time.perf_counter() - t0}
    return {
        "ok": True,
        "stress": res.homogenized_stress[-1],
        "iterations": int(res.iterations[-1]),
        "cutbacks": int(res.cutbacks[-1]),
        "time": float(res.timings["steps"][-1]),
        "damping": res.damping[-1],
        "e1": float(res.e1[-1]),
        "e2": float(res.e2[-1]),
        "method": res.methods[-1],
        "resumed_from": res.resumed_from,
    }


def run_load(
    prob: pdlin.StaticProblem,
    steps: int,
    method: str,
    compare: Sequence[int],
    workdir: Path,
    progress: Any = None,
) -> dict[str, Any]:
    """Reference history with ``method`` plus the other driver on the ``compare`` steps.

    The history is solved in segments ``times[:b]`` that extend one checkpoint
    (``resume=True``); before step ``k`` of ``compare`` the checkpoint holds the committed
    state of step ``k - 1``, and a copy of it is continued by the other driver for one
    step.  Returns the merged reference :class:`pdlin.NonlinearResult` (every committed
    state, per-step times) and the comparison per step.
    """
    times = np.arange(1.0, steps + 1.0)  # t = 1..steps, strain η t
    other = "newton" if method == "adr" else "adr"
    ckpt = workdir / f"history_{method}.npz"
    ckpt.unlink(missing_ok=True)
    compare = sorted({int(k) for k in compare if 1 <= k <= steps})
    bounds = sorted({k - 1 for k in compare if k > 1} | {steps})
    cmp: dict[int, dict[str, Any]] = {}
    if 1 in compare:  # step 1 starts from the initial state: no checkpoint needed
        cmp[1] = _one_step(prob, times[:1], other, None)
    segments = []
    for b in bounds:
        seg = pdlin.solve_nonlinear(
            prob, times=times[:b], method=method, checkpoint=ckpt, resume=True, progress=progress
        )
        segments.append(seg)
        if b + 1 in compare:
            branch = workdir / f"branch_{b + 1}.npz"
            shutil.copyfile(ckpt, branch)  # the shared committed state of step b
            cmp[b + 1] = _one_step(prob, times[: b + 1], other, branch)
            branch.unlink(missing_ok=True)
    # a resumed run holds the whole history of u, stress, iterations, committed states and
    # step times (from the checkpoint) but only the damping it computed itself: merge that
    last = segments[-1]
    damping = list(segments[0].damping)
    for seg in segments[1:]:
        damping += seg.damping[seg.resumed_from :]
    step_time = np.asarray(last.timings["steps"], dtype=float)
    timings = dict(last.timings, total=float(step_time.sum()))
    result = dataclasses.replace(last, damping=damping, timings=timings)
    ckpt.unlink(missing_ok=True)
    return {"result": result, "method": method, "other": other, "compare": cmp, "times": times}


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """‖a − b‖_F / ‖a‖_F of two homogenized stresses."""
    return float(np.linalg.norm(a - b) / np.linalg.norm(a))


def format_table(load: str, run: dict[str, Any], method: str) -> str:
    res = run["result"]
    other = run["other"]
    lines = [
        f"{load}: {res.u.shape[1]} particles, history by {method}, {other} from the shared "
        "committed state of the previous step",
        f"{'step':>4} {'strain':>6} {'s_xx':>8} {'s_yy':>8} {'s_xy':>8} {'method':>20} "
        f"{'it':>4} {'cut':>3} {'t [s]':>6} | {other + ' it':>9} {'t [s]':>6} {'rel diff':>9}",
    ]
    for k in range(res.n_steps):
        s = res.homogenized_stress[k]
        row = (
            f"{k + 1:4d} {ETA * res.times[k]:6.3f} {s[0, 0]:8.3f} {s[1, 1]:8.3f} {s[0, 1]:8.3f} "
            f"{res.methods[k]:>20} {res.iterations[k]:4d} {res.cutbacks[k]:3d} "
            f"{res.timings['steps'][k]:6.2f} |"
        )
        c = run["compare"].get(k + 1)
        if c is not None and c["ok"]:
            row += (
                f" {c['iterations']:9d} {c['time']:6.2f} {relative_difference(s, c['stress']):9.2e}"
            )
        elif c is not None:
            row += f" {'FAILED':>9}  ({c['message'][:60]})"
        lines.append(row)
    return "\n".join(lines)


def timing_summary(run: dict[str, Any]) -> dict[str, dict[str, float]]:
    """Mean time per step of both drivers on elastic (steps 1-2) and plastic steps."""
    res = run["result"]
    plastic = np.array([np.asarray(st["plastic"]).any() for st in res.states])
    t = np.asarray(res.timings["steps"])
    out = {
        run["method"]: {
            "elastic": float(t[~plastic].mean()) if (~plastic).any() else float("nan"),
            "plastic": float(t[plastic].mean()) if plastic.any() else float("nan"),
        }
    }
    te, tp = [], []
    for k, c in run["compare"].items():
        if c["ok"]:
            (tp if plastic[k - 1] else te).append(c["time"])
    out[run["other"]] = {
        "elastic": float(np.mean(te)) if te else float("nan"),
        "plastic": float(np.mean(tp)) if tp else float("nan"),
    }
    return out


# --- figures ------------------------------------------------------------------------------
def _image(cloud: pdlin.PointCloud, values: np.ndarray, n: int) -> np.ndarray:
    ij = np.floor(np.asarray(cloud.points) * n).astype(int)
    img = np.full((n, n), np.nan)
    img[ij[:, 1], ij[:, 0]] = values
    return img


def plot_all(out: Path, n: int, setup: dict[str, Any], runs: dict[str, Any]) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    cloud, grain, theta = setup["cloud"], setup["grain"], setup["theta"]
    ext = (0, 1, 0, 1)

    def save(fig: Any, name: str) -> None:
        fig.tight_layout()
        fig.savefig(out / name, dpi=110)
        plt.close(fig)
        files.append(out / name)

    if "shear" in runs:  # Fig. 5: σ_xy at the last step
        res = runs["shear"]["result"]
        fig, ax = plt.subplots(figsize=(4.6, 3.8))
        im = ax.imshow(
            _image(cloud, res.stress[-1][:, 0, 1], n), origin="lower", extent=ext, cmap="jet"
        )
        fig.colorbar(im, ax=ax, label="σ_xy (MPa)")
        ax.set_title(f"pure shear, strain {ETA * res.times[-1]:.2f}, N = {n * n}")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        save(fig, "cp_shear_sxy.png")
    if "compression" in runs:  # Fig. 8: reorientation at the last step
        res = runs["compression"]["result"]
        fig, ax = plt.subplots(figsize=(4.6, 3.8))
        rot = np.asarray(res.states[-1]["reorientation"])
        lim = float(np.abs(rot).max()) or 1.0
        im = ax.imshow(
            _image(cloud, rot, n), origin="lower", extent=ext, cmap="RdBu_r", vmin=-lim, vmax=lim
        )
        fig.colorbar(im, ax=ax, label="reorientation (°)")
        ax.set_title(f"Y-compression, strain {ETA * res.times[-1]:.2f}, N = {n * n}")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        save(fig, "cp_compression_reorientation.png")
    # grain map and max Schmid factor per grain (Figs. 9-10: l_s = e2, compression axis)
    schmid = setup["material"].schmid_factors([0.0, 1.0]).max(axis=1)
    fig, axs = plt.subplots(1, 2, figsize=(8.6, 3.8))
    im = axs[0].imshow(
        _image(cloud, np.degrees(theta), n),
        origin="lower",
        extent=ext,
        cmap="twilight",
        vmin=-90,
        vmax=90,
    )
    fig.colorbar(im, ax=axs[0], label="θ (°)")
    for g in np.unique(grain):
        c = np.asarray(cloud.points)[grain == g].mean(axis=0)
        axs[0].text(c[0], c[1], str(g + 1), ha="center", va="center", fontsize=7)
    axs[0].set_title("21 grains (seed 1): orientation")
    im = axs[1].imshow(
        _image(cloud, schmid, n), origin="lower", extent=ext, cmap="viridis", vmin=0, vmax=0.5
    )
    fig.colorbar(im, ax=axs[1], label="max Schmid factor")
    axs[1].set_title("max Schmid factor, l_s = e2")
    for ax in axs:
        ax.set_xticks([])
        ax.set_yticks([])
    save(fig, "cp_grains.png")
    # homogenized stress-strain (Fig. 14), both drivers on the same axes
    fig, axs = plt.subplots(1, len(runs), figsize=(4.3 * len(runs), 3.6), squeeze=False)
    for ax, (load, run) in zip(axs[0], runs.items(), strict=True):
        res = run["result"]
        i, j = COMPONENT[load]
        name = "σ_xy" if load == "shear" else "σ_yy"
        ax.plot(
            ETA * np.r_[0, res.times],
            np.r_[0, res.homogenized_stress[:, i, j]],
            "-",
            label=f"{run['method']} (history)",
        )
        ks = [k for k, c in sorted(run["compare"].items()) if c["ok"]]
        ax.plot(
            [ETA * res.times[k - 1] for k in ks],
            [run["compare"][k]["stress"][i, j] for k in ks],
            "o",
            mfc="none",
            label=f"{run['other']} (shared state)",
        )
        ax.set_xlabel("strain ηt")
        ax.set_ylabel(f"homogenized {name} (MPa)")
        ax.set_title(load)
        ax.legend()
    save(fig, "cp_stress_strain.png")
    # ADR damping of a few steps (Fig. 6) and final e1 / e2 per step
    adr_runs = {k: r for k, r in runs.items() if r["other"] == "adr"}
    if adr_runs:
        fig, axs = plt.subplots(1, 2, figsize=(9.0, 3.6))
        run = next(iter(adr_runs.values()))
        load = next(iter(adr_runs))
        ok = [k for k, c in sorted(run["compare"].items()) if c["ok"]]
        for k in [k for k in ok if k in (1, 10, 20, 30)] or ok[-3:]:
            c = run["compare"][k]["damping"]
            axs[0].semilogy(
                np.arange(1, c.size + 1),
                np.where(c > 0, c, np.nan),
                lw=0.8,
                label=f"step {k} ({100 * (c == 0).mean():.0f} % c = 0)",
            )
        axs[0].set_xlabel("ADR iteration")
        axs[0].set_ylabel("damping c")
        axs[0].set_title(f"{load}: adaptive damping (c = 0 not drawn)")
        axs[0].legend(fontsize=8)
        for load, run in adr_runs.items():
            ks = [k for k, c in sorted(run["compare"].items()) if c["ok"]]
            axs[1].semilogy(ks, [run["compare"][k]["e1"] for k in ks], "o-", label=f"{load} e1")
            axs[1].semilogy(ks, [run["compare"][k]["e2"] for k in ks], "x--", label=f"{load} e2")
        axs[1].axhline(1e-6, color="k", lw=0.6)
        axs[1].set_xlabel("load step")
        axs[1].set_ylabel("final e1, e2")
        axs[1].set_title("ADR criteria at convergence (e_l = 1e-6)")
        axs[1].legend(fontsize=8)
        save(fig, "cp_adr.png")
    return files


# --- driver -------------------------------------------------------------------------------
def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument("--n", type=int, default=25, help="particles per side (default 25; 50 = paper)")
    p.add_argument("--steps", type=int, default=30, help="load steps, strain 0.002 each")
    p.add_argument(
        "--method",
        choices=("newton", "adr", "auto"),
        default="auto",
        help="driver of the full histories (default auto: Newton, ADR on a step Newton fails); "
        "the other one (ADR, or Newton for 'adr') solves the compared steps from the shared "
        "committed state",
    )
    p.add_argument(
        "--compare",
        default=",".join(map(str, DEFAULT_COMPARE)),
        help="steps solved by both drivers: comma list, 'all' or 'none'",
    )
    p.add_argument("--loads", default="shear,compression", help="comma list of loads")
    p.add_argument("--out", default="cp_polycrystal_out", help="output directory")
    p.add_argument("--no-plots", action="store_true", help="skip the matplotlib figures")
    p.add_argument("--seed", type=int, default=1, help="Voronoi seed (default 1)")
    p.add_argument("--verbose", action="store_true", help="print one line per solved step")
    return p.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Run the example; returns the runs per load, the setup and the written files."""
    args = parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.compare == "all":
        compare: list[int] = list(range(1, args.steps + 1))
    elif args.compare == "none":
        compare = []
    else:
        compare = [int(k) for k in args.compare.split(",") if k.strip()]
    loads = [s.strip() for s in args.loads.split(",") if s.strip()]
    progress = print if args.verbose else None
    runs: dict[str, Any] = {}
    files: list[Path] = []
    setup: dict[str, Any] = {}
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=out) as work:
        for load in loads:
            setup = build(args.n, load, seed=args.seed)
            run = run_load(setup["problem"], args.steps, args.method, compare, Path(work), progress)
            runs[load] = run
            print(format_table(load, run, args.method))
            times = timing_summary(run)
            print(
                "  mean time per step (s): "
                + "; ".join(
                    f"{m} elastic {v['elastic']:.3f}, plastic {v['plastic']:.3f}"
                    for m, v in times.items()
                )
            )
            run["timing"] = times
            diffs = [
                relative_difference(run["result"].homogenized_stress[k - 1], c["stress"])
                for k, c in run["compare"].items()
                if c["ok"]
            ]
            run["max_difference"] = max(diffs) if diffs else float("nan")
            print(f"  max relative homogenized difference: {run['max_difference']:.2e}\n")
            files.append(write_nonlinear(out / f"{load}.pvd", run["result"]))
            files.append(write_homogenized_csv(out / f"{load}_homogenized.csv", run["result"]))
    if not args.no_plots:
        files += plot_all(out, args.n, setup, runs)
    elapsed = time.perf_counter() - t_all
    print(f"wrote {len(files)} files to {out}/ in {elapsed:.1f} s")
    return {"runs": runs, "setup": setup, "files": files, "args": args, "elapsed": elapsed}


if __name__ == "__main__":
    main()
