"""Bar in tension: 1D graded bar vs the closed form, and a 3D bar with a shadow layer.

Run: ``python examples/bar_tension.py``.  Prints the errors; no plotting
needed (pass ``--plot`` with matplotlib installed to see u(x)).
"""

from __future__ import annotations

import argparse

import numpy as np

import pdlin


def graded_bar_1d(N: int = 200, m: int = 3) -> dict[str, float]:
    """E(x) = 1 + x on (0, 1), sigma = 1e-3; exact u = sigma ln(1 + x)."""
    h = 1.0 / N
    cloud = pdlin.grid((N + 2 * m,), spacing=h, origin=(-m * h,))
    x = cloud.points[:, 0]
    exact = 1e-3 * np.log1p(x)
    shadow = np.r_[np.arange(m), np.arange(cloud.n - m, cloud.n)]
    problem = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0 + x),
        cloud,
        horizon=(m + 0.015) * h,
        dirichlet=[pdlin.Dirichlet(shadow, exact[shadow, None])],
    )
    res = pdlin.solve(problem, solver="direct")
    err = np.abs(res.u[:, 0] - exact).max() / np.abs(exact).max()
    return {"N": N, "max_rel_error": float(err)}


def bar_3d(shape: tuple[int, int, int] = (24, 12, 12), eps: float = 1e-4) -> dict[str, float]:
    """Uniaxial field imposed on an inward shadow layer of depth delta on every face."""
    h = 0.01
    cloud = pdlin.grid(shape, spacing=h)
    delta = 3.015 * h
    F = np.diag([1 + eps, 1 - 0.25 * eps, 1 - 0.25 * eps])  # bond-based 3D: nu = 1/4
    bc, shadow = pdlin.shadow_layer(cloud, F, depth=delta)
    problem = pdlin.StaticProblem(pdlin.BondBased(E=200e9), cloud, horizon=delta, dirichlet=[bc])
    res = pdlin.solve(problem, solver="amg-cg", rtol=1e-12)
    real = np.setdiff1d(np.arange(cloud.n), shadow)
    strain = res.strain()[real]
    return {
        "points": cloud.n,
        "real_points": int(real.size),
        "max_strain_error": float(np.abs(strain[:, 0, 0] / eps - 1).max()),
        "iterations": res.n_iter,
        "solve_s": res.timings["solve"],
    }


def main(plot: bool = False) -> dict[str, object]:
    out: dict[str, object] = {"graded_1d": [graded_bar_1d(N) for N in (50, 100, 200, 400)]}
    out["bar_3d"] = bar_3d()
    for row in out["graded_1d"]:  # type: ignore[union-attr]
        print(f"1D graded bar N={row['N']:4d}: max relative error {row['max_rel_error']:.3e}")
    print("3D shadow-layer bar:", out["bar_3d"])
    if plot:
        import matplotlib.pyplot as plt

        plt.plot(
            [r["N"] for r in out["graded_1d"]], [r["max_rel_error"] for r in out["graded_1d"]], "o-"
        )  # type: ignore[union-attr]
        plt.xscale("log")
        plt.yscale("log")
        plt.xlabel("N")
        plt.ylabel("max relative error")
        plt.show()
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--plot", action="store_true")
    main(ap.parse_args().plot)
