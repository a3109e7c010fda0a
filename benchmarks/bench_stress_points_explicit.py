"""Explicit dynamics of nearest-neighbour correspondence: stress points against other controls.

Luo & Sundararaghavan (2018), Sec. 5.4 and Appendix A: on a nearest-neighbour lattice the
stress-point (SP) scheme needs half the time step of the uncontrolled gradient (Eqs. 14-15:
``(2/n) h sqrt(ρ/E_max)`` without a control, ``(1/n) h sqrt(ρ/E_max)`` with SP; Appendix A:
``Δt_c = 2Δx/c`` against ``Δx/c`` in 1D), and their serial explicit runs took about twice
as long with SP (Fig. 14; its numbers are lost in our copy of the paper).

For each dimension (1D bar of 500 particles, 2D 51 x 51 plane stress, 3D 17 x 17 x 9;
E = 1, ν = 0.3, ρ = 1, h = 1, δ = h) and each control (``none``, ``stress_points``,
``springs``, ``ads``, ``penalty``) this prints:

* the stable step of :func:`pdlin.dynamics.estimate_time_step` (``'gershgorin'``, the
  default, and ``'lanczos'``, the exact linear limit ``2/sqrt(λ_max(M⁻¹K))``) in units of
  ``h sqrt(ρ/E_max)`` (``E_max`` the largest entry of the elastic matrix ``D``), and the
  paper's closed form (:func:`pdlin.dynamics.nearest_neighbour_time_step`);
* the wall and CPU time per step of :func:`pdlin.dynamics.solve_explicit` (the model's own
  matrix-free ``internal_force``), measured over ``--steps`` steps from a random field (CPU:
  a run of ``steps + 1`` steps minus a run of 1, so the setup cancels);
* the time to a fixed end time ``T = 50 h / c`` (``c = sqrt(E_max/ρ)``) at the default step
  (0.9 x Gershgorin): steps x CPU time per step (the machine may be shared: CPU time is
  what the work cost, wall time includes waiting for a core), and the ratio to ``none``.

Run ``python benchmarks/bench_stress_points_explicit.py`` (about a minute).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import pdlin  # noqa: E402
from pdlin.dynamics import (  # noqa: E402
    estimate_time_step,
    nearest_neighbour_time_step,
    solve_explicit,
    step_count,
)

CONTROLS = ("none", "stress_points", "springs", "ads", "penalty")
SHAPES = {1: (500,), 2: (51, 51), 3: (17, 17, 9)}
NU = 0.3


def e_max(dim: int) -> float:
    """Largest entry of the elastic matrix ``D`` at E = 1, ν = 0.3 (1D: E; 2D plane stress)."""
    if dim == 1:
        return 1.0
    if dim == 2:
        return 1.0 / (1.0 - NU**2)
    return (1.0 - NU) / ((1.0 + NU) * (1.0 - 2.0 * NU))


def row(dim: int, control: str, steps: int, base: dict[int, float]) -> str:
    """Measure one dimension x control and return its Markdown row."""
    from _context import timed

    cloud = pdlin.grid(SHAPES[dim], spacing=1.0)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    model = pdlin.Correspondence(E=1.0, nu=NU, control=control)
    unit = np.sqrt(1.0 / e_max(dim))  # h sqrt(rho / E_max)
    gersh = estimate_time_step(model, cloud, bonds, 1.0).dt
    try:
        lanc = f"{estimate_time_step(model, cloud, bonds, 1.0, method='lanczos').dt / unit:.3f}"
    except pdlin.errors.ModelError:  # ADS: nonsymmetric K
        lanc = "–"
    closed = "–"  # the paper gives closed forms for no control and stress points only
    if control in ("none", "stress_points"):
        step = nearest_neighbour_time_step(
            1.0, 1.0, e_max(dim), dim, stress_points=control == "stress_points"
        )
        closed = f"{step / unit:.3f}"
    prob = pdlin.StaticProblem(model, cloud, bonds)
    u0 = 1e-3 * np.random.default_rng(0).normal(size=(cloud.n, dim))
    dt = 0.9 * gersh
    cpu = []
    for n in (1, steps + 1):
        with timed() as t:
            res = solve_explicit(prob, n * dt, dt, density=1.0, u0=u0, output_every=10**6)
        cpu.append(t.cpu)
    per_step = res.timings["steps"] / res.steps
    cpu_step = (cpu[1] - cpu[0]) / steps  # the setup cancels
    t_end = 50.0 * unit
    n_end = step_count(t_end, dt)
    total = n_end * cpu_step
    if control == "none":
        base[dim] = total
    ratio = total / base[dim] if dim in base else float("nan")
    return (
        f"| {dim}D | {cloud.n:,} | {control} | {gersh / unit:.3f} | {lanc} | {closed} | "
        f"{per_step * 1e3:.2f} | {cpu_step * 1e3:.2f} | {n_end:,} | {total:.3f} | {ratio:.2f} |"
    )


def main() -> None:
    """Print the table."""
    from _context import header

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--dims", type=int, nargs="*", default=[1, 2, 3])
    args = ap.parse_args()
    header()
    print(
        "\n| dim | particles | control | Δt Gershgorin | Δt Lanczos | Δt paper Eq. 14/15 | "
        "ms/step wall | ms/step CPU | steps to T = 50 h/c | CPU s to T | "
        "time / none |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    base: dict[int, float] = {}
    for dim in args.dims:
        for control in CONTROLS:
            print(row(dim, control, args.steps, base), flush=True)
    print("\nΔt in units of h sqrt(ρ/E_max); CPU s to T = steps at 0.9 x Gershgorin x CPU ms/step.")


if __name__ == "__main__":
    main()
