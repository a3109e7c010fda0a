"""Zero-energy modes of the uncontrolled correspondence model as the grid is refined.

The elastic tangent of the 21-grain crystal-plasticity polycrystal of
``bench_nonlinear.problem`` (Luo, Ramazani & Sundararaghavan 2017, Sec. 4: δ = h, n x n
grid, boundary ring prescribed) restricted to the free DOFs, for each control: its smallest
eigenvalue λ_min (shift-invert Lanczos) and largest λ_max, both against the Rayleigh quotient
R_s of the smoothest admissible field ``sin(πx) sin(πy) e_x`` (the lowest mode of a
well-posed discretization), and the Rayleigh quotient of the same envelope times the
checkerboard ``(-1)^(i+j)`` (and the other {0, π}² patterns) against R_s
(``pdlin.analysis.zero_energy.checkerboard_energy_ratio``, smallest ratio). In a well-posed
discretization the checkerboard is the stiffest pattern (its ratio grows like λ_max / R_s,
∝ n²); a zero-energy mode keeps it as soft as the smoothest field (ratio O(1) for every n),
so the high-frequency content of the solution is set by forces of the order of the smooth
mode's, whatever the solver (Newton's tangent or ADR's dynamics). Nothing is asserted.

Usage::

    python benchmarks/bench_zero_energy_scaling.py --sizes 25 50 100 200 316
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_nonlinear as bn  # noqa: E402
from _context import header  # noqa: E402

from pdlin.analysis.zero_energy import checkerboard_energy_ratio  # noqa: E402


def spectrum(n: int, control: str) -> tuple[float, float, float, float, float]:
    """Return ``(λ_min, R_s, λ_max, checkerboard ratio, seconds)`` of the elastic tangent."""
    t0 = time.perf_counter()
    prob, h = bn.problem(n, "shear", control)
    cloud, bonds, model = prob.cloud, prob.bonds, prob.model
    state = model.initial_state(cloud, bonds)
    K = model.respond(cloud, bonds, np.zeros((cloud.n, 2)), state, tangent=True).tangent
    K = sp.csr_array(K)
    K = 0.5 * (K + K.T)  # the elastic tangent is symmetric up to round-off
    fixed = np.zeros(cloud.n, dtype=bool)
    fixed[cloud.point_set("boundary")] = True
    free = np.flatnonzero(np.repeat(~fixed, 2))
    Kf = sp.csc_array(K[free][:, free])
    x = (cloud.points - cloud.points.min(axis=0)) / np.ptp(cloud.points, axis=0)
    s = np.zeros((cloud.n, 2))
    s[:, 0] = np.sin(np.pi * x[:, 0]) * np.sin(np.pi * x[:, 1])
    v = s.ravel()[free]
    Rs = float(v @ (Kf @ v) / (v @ v))
    lam_min = float(spla.eigsh(Kf, k=1, sigma=0.0, which="LM", return_eigenvectors=False)[0])
    lam_max = float(spla.eigsh(Kf, k=1, which="LA", return_eigenvectors=False, tol=1e-3)[0])
    cb = checkerboard_energy_ratio(K, cloud).min_ratio
    return lam_min, Rs, lam_max, cb, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[25, 50, 100, 200])
    ap.add_argument("--controls", nargs="+", default=["none", "penalty:0.1"])
    args = ap.parse_args()
    header()
    print(
        "| n² | control | λ_min | R_s (smooth mode) | λ_min / R_s | checkerboard / R_s | "
        "λ_max / R_s | s |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        for control in args.controls:
            lam, Rs, lmax, cb, sec = spectrum(n, control)
            print(
                f"| {n * n:,} | {control} | {lam:.3e} | {Rs:.3e} | {lam / Rs:.2f} | {cb:.2f} | "
                f"{lmax / Rs:.2e} | {sec:.0f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
