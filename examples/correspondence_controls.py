"""Zero-energy-mode controls of the correspondence model compared (Luo & Sundararaghavan 2018).

Tutorial for docs/tutorial_controls.md.  Two problems, both on nearest-neighbour node
lattices where the plain correspondence (NOSB) model has zero-energy modes:

1. **1D graded bar** (Luo & Sundararaghavan 2018, Sec. 5.1, Eqs. 18-21):
   x_i = (i - 1)/(n - 1), n = 500, u(0) = 0, u(1) = u_end = 0.005, E = E0 = 1 on x <= 1/2
   and E0 [1 + (β/2α)(x - 1/2)^(-1/2)]^(-1) beyond (α = 0.001, β = 0.004 sqrt 2); exact
   u = αx + β sqrt(x - 1/2) H(x - 1/2) and σ = 1e-3 everywhere.  Every control of
   :class:`pdlin.Correspondence` is solved and compared by

   * ``rel_l2_u`` = ||u - u_ex|| / ||u_ex|| over all particles,
   * ``rel_l2_eps`` = ||ε - ε_ex|| / ||ε_ex|| on x <= 0.48 (the exact strain is singular
     at x = 1/2+, so a global strain norm only measures the two particles next to it),
   * ``osc`` = ``max |Δ²(u - u_ex)| / u_end`` over the stencils inside 0.02 < x < 0.48 (Δ² the
     second difference along the bar): the odd-even (zero-energy) oscillation
     amplitude.
     The exact solution is linear there, so a smooth numerical error gives osc ≈ 0.

2. **Plate with a square hole** (Luo & Sundararaghavan 2018, Sec. 5.2, which gives neither
   dimensions nor load; reconstructed as in docs/theory/conventions.md): [0, 50]² mm minus
   [0, 10)², node grid h = 2 mm (651 particles), E = 1000 MPa, ν = 0.3, plane stress;
   u_x = 0 on x = 0, u_y = 0 on y = 0, u_x = 0.5 mm on x = 50, u_y = 0.5 mm on y = 50,
   tangential components free.  Reference: Q4 FEM with its nodes at the particles
   (:func:`pdlin.verification.solve_q4`).  Metrics (norms over the plate; the paper's Eq. 22
   is a pointwise relative error):

   * rel-L2 of u and of σ = [σ_xx, σ_yy, σ_xy] over all particles; the PD particle
     stress is :meth:`pdlin.Correspondence.stress` (the mean over the particle's stress
     points); the FEM nodal stress is the plain average, over the elements sharing the
     node, of the element stress at the centroid (equal to the mean of the 2 x 2 Gauss
     point stresses on these rectangular elements);
   * checker deviation = ``max_i |c_i^PD - c_i^FEM| / 0.5 mm`` with
     ``c_i = |u_i - mean of its 4 neighbours|``, over particles with 4 neighbours and
     x > 20 or y > 20.

Run ``python examples/correspondence_controls.py [--plot DIR] [--n 500] [--h 2]``; it prints
both tables (about 3 s), and ``--plot DIR`` saves ``bar_controls.png`` and
``plate_controls.png`` there (needs matplotlib).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

import pdlin
from pdlin.constraints import resolve_dirichlet
from pdlin.models.correspondence import CONTROLS
from pdlin.verification.fem import solve_q4

# --- 1D graded bar: Luo & Sundararaghavan (2018), Sec. 5.1 ---------------------------------
ALPHA = 1e-3
BETA = 4e-3 * np.sqrt(2.0)
U_END = 0.005

# --- plate with a square hole: Sec. 5.2, reconstructed (docs/theory/conventions.md) --------
E_PLATE, NU_PLATE = 1000.0, 0.3  # MPa, as in the paper
SIDE, HOLE, U_LOAD = 50.0, 10.0, 0.5  # mm


def modulus(x: np.ndarray) -> np.ndarray:
    """Graded modulus E(x) of Luo & Sundararaghavan (2018), Eq. 18 (E0 = 1)."""
    r = np.clip(x - 0.5, 1e-300, None)
    return np.where(x <= 0.5, 1.0, 1.0 / (1.0 + BETA / (2 * ALPHA) / np.sqrt(r)))


def u_exact(x: np.ndarray) -> np.ndarray:
    """Exact displacement, Eq. (19)."""
    return ALPHA * x + BETA * np.sqrt(np.clip(x - 0.5, 0.0, None))


def eps_exact(x: np.ndarray) -> np.ndarray:
    """Exact strain, Eq. (20)."""
    r = np.clip(x - 0.5, 1e-300, None)
    return np.where(x <= 0.5, ALPHA, ALPHA + BETA / (2.0 * np.sqrt(r)))


def bar_cases() -> list[dict[str, Any]]:
    """The bar runs: label, control, δ/h, influence and extra model keywords.

    ``'springs'`` and ``'ads'`` (Luo & Sundararaghavan 2018, Sec. 2.2) are included when this
    pdlin has them.
    """
    cases: list[dict[str, Any]] = [
        {"label": "none", "control": "none", "m": 1},
        {"label": "none", "control": "none", "m": 2},
        {"label": "none 1/|xi|", "control": "none", "m": 2, "influence": "inverse"},
        {"label": "none", "control": "none", "m": 3},
        {"label": "none 1/|xi|", "control": "none", "m": 3, "influence": "inverse"},
        {"label": "higher_order", "control": "higher_order", "m": 2},
        {"label": "higher_order", "control": "higher_order", "m": 3},
    ]
    for c in (0.1, 1.0):
        cases.append({"label": "penalty", "control": "penalty", "m": 1, "kw": {"penalty": c}})
    cases.append({"label": "stress_points", "control": "stress_points", "m": 1})
    for control in ("springs", "ads"):
        if control in CONTROLS:
            for c in (1e-3, 1e-1, 1e1):
                cases.append(
                    {"label": control, "control": control, "m": 1, "kw": {"coefficient": c}}
                )
    return cases


def solve_bar(
    n: int,
    control: str,
    m: int = 1,
    influence: str = "constant",
    kw: dict[str, Any] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node-layout bar of Luo & Sundararaghavan (2018), Sec. 5.1: return x, u and the strain ε.

    δ = m h; for m > 1 the exact u is prescribed on the m particles at each end (a
    boundary layer one horizon thick), otherwise the far particles of a δ > h no-control
    chain are only weakly tied to the ends.
    """
    h = 1.0 / (n - 1)
    cloud = pdlin.grid((n,), spacing=h, origin=[-0.5 * h])  # x_i = (i - 1) h, V = h
    bonds = pdlin.find_bonds(cloud, ratio=float(m), influence=influence)
    x = cloud.points[:, 0]
    model = pdlin.Correspondence(E=modulus(x), control=control, **(kw or {}))
    ends = np.r_[0:m, n - m : n]  # u_1 = 0, u_n = u_end; for δ = mh the m end particles
    problem = pdlin.StaticProblem(
        model, cloud, bonds, dirichlet=[pdlin.Dirichlet(ends, u_exact(x[ends])[:, None])]
    )
    u = pdlin.solve(problem, solver="direct").u
    eps = model.strain(cloud, bonds, u)[:, 0, 0]
    return x, u[:, 0], eps


def bar_metrics(x: np.ndarray, u: np.ndarray, eps: np.ndarray) -> dict[str, float]:
    """rel-L2 of u (all particles) and ε (x <= 0.48), and the oscillation amplitude osc."""
    ue = u_exact(x)
    left = x <= 0.48
    ee = eps_exact(x[left])
    window = (x > 0.02) & (x < 0.48)  # the stencils with all three points inside
    return {
        "rel_l2_u": float(np.linalg.norm(u - ue) / np.linalg.norm(ue)),
        "rel_l2_eps": float(np.linalg.norm(eps[left] - ee) / np.linalg.norm(ee)),
        "osc": float(np.abs(np.diff((u - ue)[window], 2)).max() / U_END),
    }


def run_bar(n: int = 500) -> list[dict[str, Any]]:
    """Solve every bar case; one row of metrics (and the fields) per case."""
    rows = []
    for case in bar_cases():
        x, u, eps = solve_bar(
            n, case["control"], case["m"], case.get("influence", "constant"), case.get("kw")
        )
        coef = next(iter((case.get("kw") or {}).values()), None)
        rows.append(
            {
                "label": case["label"],
                "control": case["control"],
                "delta": f"{case['m']}h",
                "coefficient": coef,
                **bar_metrics(x, u, eps),
                "x": x,
                "u": u,
                "eps": eps,
            }
        )
    return rows


# --- the R2D plate ------------------------------------------------------------------------


def square_hole_plate(h: float = 2.0) -> tuple[pdlin.PointCloud, np.ndarray]:
    """R2D node grid (spacing ``h``) without the hole, and the Q4 cells on the same nodes.

    Returns the cloud (particles at ``(i h, j h)``, V = h² for every particle) and the
    ``(ne, 4)`` counter-clockwise quads: the grid cells not inside the hole [0, 10)².
    """
    n = int(round(SIDE / h)) + 1
    full = pdlin.grid((n, n), spacing=h, origin=[-0.5 * h, -0.5 * h])
    tol = 1e-9 * h
    inside = np.all(full.points < HOLE - tol, axis=1)
    keep = np.flatnonzero(~inside)
    new = np.full(full.n, -1, dtype=np.intp)
    new[keep] = np.arange(keep.size)
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij"))
    cell = ~((i * h < HOLE - tol) & (j * h < HOLE - tol))  # lower-left corner outside the hole
    i, j = i[cell], j[cell]
    quads = np.stack([new[i * n + j], new[(i + 1) * n + j], new[(i + 1) * n + j + 1],
                      new[i * n + j + 1]], axis=1)  # fmt: skip
    return full.subset(keep), quads


def plate_dirichlet(cloud: pdlin.PointCloud) -> list[pdlin.Dirichlet]:
    """R2D boundary conditions: normal components on the four outer edges."""
    x, y = cloud.points.T
    tol = 1e-9 * SIDE
    return [
        pdlin.Dirichlet(np.flatnonzero(x < tol), 0.0, components="x"),
        pdlin.Dirichlet(np.flatnonzero(y < tol), 0.0, components="y"),
        pdlin.Dirichlet(np.flatnonzero(x > SIDE - tol), U_LOAD, components="x"),
        pdlin.Dirichlet(np.flatnonzero(y > SIDE - tol), U_LOAD, components="y"),
    ]


def _voigt(s: np.ndarray) -> np.ndarray:
    return np.stack([s[:, 0, 0], s[:, 1, 1], s[:, 0, 1]], axis=1)


def plate_fem(cloud: pdlin.PointCloud, quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Q4 reference: nodal u ``(n, 2)`` and nodal stress ``(n, 3)`` [σ_xx, σ_yy, σ_xy].

    Nodal stress = plain average over the elements sharing the node of the centroid
    stress (the mean of the 2 x 2 Gauss-point stresses on these rectangles).
    """
    dofs, vals = resolve_dirichlet(cloud, plate_dirichlet(cloud))
    u = solve_q4(cloud.points, quads, E_PLATE, NU_PLATE, dofs, vals, plane="stress")
    xe, ue = cloud.points[quads], u[quads]  # (ne, 4, 2)
    dn = 0.25 * np.array([[-1.0, 1.0, 1.0, -1.0], [-1.0, -1.0, 1.0, 1.0]])  # at the centroid
    jac = np.einsum("ak,ekb->eab", dn, xe)
    dx = np.linalg.solve(jac, np.broadcast_to(dn, (quads.shape[0], 2, 4)))  # (ne, 2, 4)
    grad = np.einsum("eak,ekc->eca", dx, ue)  # du_c/dx_a
    strain = np.stack([grad[:, 0, 0], grad[:, 1, 1], grad[:, 0, 1] + grad[:, 1, 0]], axis=1)
    nu = NU_PLATE
    D = E_PLATE / (1 - nu**2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    sig_e = strain @ D.T
    nodes = quads.ravel()
    count = np.bincount(nodes, minlength=cloud.n)
    sig = np.stack(
        [np.bincount(nodes, np.repeat(sig_e[:, c], 4), minlength=cloud.n) for c in range(3)],
        axis=1,
    )
    return u, sig / count[:, None]


def plate_pd(
    cloud: pdlin.PointCloud, control: str, **kw: Any
) -> tuple[np.ndarray, np.ndarray, pdlin.Correspondence, pdlin.Bonds]:
    """Correspondence solve on the plate: u ``(n, 2)``, particle stress ``(n, 3)``."""
    bonds = pdlin.find_bonds(cloud, ratio=1.0)  # nearest neighbours, as in the paper's Sec. 2
    model = pdlin.Correspondence(E=E_PLATE, nu=NU_PLATE, plane="stress", control=control, **kw)
    problem = pdlin.StaticProblem(model, cloud, bonds, dirichlet=plate_dirichlet(cloud))
    u = pdlin.solve(problem, solver="direct").u
    return u, _voigt(model.stress(cloud, bonds, u)), model, bonds


def checker_amplitude(cloud: pdlin.PointCloud, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """c_i = |u_i - mean of the 4 lattice neighbours| and the mask of particles that have 4."""
    h = float(np.min(np.diff(np.unique(cloud.points[:, 0]))))
    ij = np.rint(cloud.points / h).astype(np.intp) + 1
    lut = np.full(tuple(ij.max(axis=0) + 2), -1, dtype=np.intp)
    lut[ij[:, 0], ij[:, 1]] = np.arange(cloud.n)
    steps = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]])
    nb = lut[ij[:, None, 0] + steps[:, 0], ij[:, None, 1] + steps[:, 1]]  # (n, 4)
    full = np.all(nb >= 0, axis=1)
    c = np.linalg.norm(u - u[np.where(nb >= 0, nb, 0)].mean(axis=1), axis=1)
    return np.where(full, c, 0.0), full


def plate_metrics(
    cloud: pdlin.PointCloud,
    u: np.ndarray,
    sig: np.ndarray,
    u_fe: np.ndarray,
    sig_fe: np.ndarray,
) -> dict[str, float]:
    """Compute the plate metrics (rel-L2 of u and σ, checker deviation) of a PD solution vs FEM."""
    x, y = cloud.points.T
    c_pd, full = checker_amplitude(cloud, u)
    c_fe, _ = checker_amplitude(cloud, u_fe)
    far = full & ((x > 20.0) | (y > 20.0))
    row = np.flatnonzero((np.abs(y) < 1e-9) & (x > 20.0))  # axis-1, away from the hole
    at38 = np.flatnonzero((np.abs(y) < 1e-9) & (np.abs(x - 38.0) < 1e-9))
    return {
        "rel_l2_u": float(np.linalg.norm(u - u_fe) / np.linalg.norm(u_fe)),
        "rel_l2_sigma": float(np.linalg.norm(sig - sig_fe) / np.linalg.norm(sig_fe)),
        "checker": float(np.abs(c_pd[far] - c_fe[far]).max() / U_LOAD),
        "max_a_sigma": float(np.abs((sig[row, 0] - sig_fe[row, 0]) / sig_fe[row, 0]).max()),
        "sxx_38": float(sig[at38, 0][0]) if at38.size else float("nan"),
    }


def run_plate(h: float = 2.0) -> dict[str, Any]:
    """FEM, no control and stress points (seed 0 and the uniform case 0) on the R2D plate."""
    cloud, quads = square_hole_plate(h)
    u_fe, sig_fe = plate_fem(cloud, quads)
    runs: dict[str, dict[str, Any]] = {
        "none": {"control": "none"},
        "stress_points": {"control": "stress_points", "seed": 0},
        "stress_points case=0": {"control": "stress_points", "case": 0},
    }
    out: dict[str, Any] = {"cloud": cloud, "quads": quads, "u_fe": u_fe, "sig_fe": sig_fe}
    rows = []
    for label, kw in runs.items():
        u, sig, _, _ = plate_pd(cloud, **kw)
        rows.append({"label": label, **plate_metrics(cloud, u, sig, u_fe, sig_fe)})
        out[label] = (u, sig)
    fe = plate_metrics(cloud, u_fe, sig_fe, u_fe, sig_fe)
    rows.append({"label": "FEM (Q4)", **fe})
    out["rows"] = rows
    return out


# --- output -------------------------------------------------------------------------------


def format_bar(rows: list[dict[str, Any]], n: int) -> str:
    lines = [
        f"1D graded bar, n = {n} (Luo & Sundararaghavan 2018, Sec. 5.1)",
        f"{'control':<14} {'delta':>5} {'coef':>7} {'rel-L2 u':>9} {'rel-L2 eps':>10} {'osc':>9}",
    ]
    for r in rows:
        coef = "" if r["coefficient"] is None else f"{r['coefficient']:g}"
        lines.append(
            f"{r['label']:<14} {r['delta']:>5} {coef:>7} {r['rel_l2_u']:9.2e} "
            f"{r['rel_l2_eps']:10.2e} {r['osc']:9.2e}"
        )
    return "\n".join(lines)


def format_plate(rows: list[dict[str, Any]], h: float, n: int) -> str:
    lines = [
        f"plate with a square hole, h = {h:g} mm, {n} particles (reconstructed Sec. 5.2)",
        f"{'model':<21} {'rel-L2 u':>9} {'rel-L2 sig':>10} {'checker':>9} "
        f"{'max a_sig':>9} {'sxx(38,0)':>9}",
    ]
    for r in rows:
        lines.append(
            f"{r['label']:<21} {r['rel_l2_u']:9.2e} {r['rel_l2_sigma']:10.2e} "
            f"{r['checker']:9.2e} {r['max_a_sigma']:9.3f} {r['sxx_38']:9.2f}"
        )
    return "\n".join(lines)


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError("--plot needs matplotlib: pip install pdlin[plotting]") from exc
    return plt


def plot_bar(rows: list[dict[str, Any]], path: str) -> None:
    """Displacement error, strain ratio and |Δ²(u - u_ex)| along the bar for a few controls."""
    plt = _pyplot()
    pick = {("none", "1h"), ("higher_order", "2h"), ("penalty", "1h"), ("stress_points", "1h"),
            ("springs", "1h"), ("ads", "1h")}  # fmt: skip
    shown: set[str] = set()
    sel = []
    for r in rows:  # first row of each picked control (springs/ads: their middle coefficient)
        key = (r["label"], r["delta"])
        if key in pick and r["label"] not in shown:
            if r["label"] in ("springs", "ads") and r["coefficient"] != 1e-1:
                continue
            shown.add(r["label"])
            sel.append(r)
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for k, r in enumerate(sel):
        x, u, eps = r["x"], r["u"], r["eps"]
        label = r["label"] + ("" if r["coefficient"] is None else f" {r['coefficient']:g}")
        if r["delta"] != "1h":
            label += f" δ={r['delta']}"
        st = {"color": f"C{k}", "lw": 0.9}
        axes[0].plot(x, (u - u_exact(x)) / U_END, label=label, **st)
        axes[1].plot(x, eps / eps_exact(x), **st)
        d2 = np.abs(np.diff(u - u_exact(x), 2)) / U_END
        axes[2].semilogy(x[1:-1], np.maximum(d2, 1e-17), **st)
    axes[0].set_ylabel("(u - u_ex) / u_end")
    axes[1].set_ylabel("ε / ε_ex")
    axes[1].set_ylim(0.6, 1.6)
    axes[2].set_ylabel("|Δ²(u - u_ex)| / u_end")
    for ax in axes:
        ax.set_xlabel("x")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("1D graded bar, n = 500: displacement, strain and oscillation amplitude")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_plate(plate: dict[str, Any], path: str) -> None:
    """u_x - u_x^FEM over the plate (no control, stress points) and σ_xx along y = 0."""
    plt = _pyplot()
    cloud = plate["cloud"]
    x, y = cloud.points.T
    u_fe, sig_fe = plate["u_fe"], plate["sig_fe"]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    lim = max(np.abs(plate[k][0][:, 0] - u_fe[:, 0]).max() for k in ("none", "stress_points"))
    for ax, key in zip(axes[:2], ("none", "stress_points"), strict=True):
        err = plate[key][0][:, 0] - u_fe[:, 0]
        im = ax.scatter(x, y, c=err, s=14, marker="s", cmap="RdBu_r", vmin=-lim, vmax=lim)
        ax.set_aspect("equal")
        ax.set_title(f"u_x - u_x(FEM) [mm], {key}", fontsize=9)
    fig.colorbar(im, ax=axes[:2], shrink=0.8)
    row = np.flatnonzero(np.abs(y) < 1e-9)
    row = row[np.argsort(x[row])]
    axes[2].plot(x[row], sig_fe[row, 0], "k-", label="FEM (Q4)")
    axes[2].plot(x[row], plate["none"][1][row, 0], "C3s--", ms=3, lw=0.8, label="none")
    axes[2].plot(x[row], plate["stress_points"][1][row, 0], "C0o-", ms=3, lw=0.8,
                 label="stress_points")  # fmt: skip
    axes[2].set_xlabel("x [mm] (y = 0)")
    axes[2].set_ylabel("σ_xx [MPa]")
    axes[2].grid(alpha=0.3)
    axes[2].legend(fontsize=8)
    fig.savefig(path, dpi=80, bbox_inches="tight")
    plt.close(fig)


def main(n: int = 500, h: float = 2.0, plot: str | None = None) -> dict[str, Any]:
    """Run both comparisons, print the tables, optionally save the figures in ``plot``."""
    bar = run_bar(n)
    plate = run_plate(h)
    print(format_bar(bar, n))
    print()
    print(format_plate(plate["rows"], h, plate["cloud"].n))
    if plot is not None:
        os.makedirs(plot, exist_ok=True)
        plot_bar(bar, os.path.join(plot, "bar_controls.png"))
        plot_plate(plate, os.path.join(plot, "plate_controls.png"))
    return {"bar": bar, "plate": plate}


def _cli(argv: Sequence[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--plot", metavar="DIR", help="save bar_controls.png, plate_controls.png")
    parser.add_argument("--n", type=int, default=500, help="bar particles (default 500)")
    parser.add_argument("--h", type=float, default=2.0, help="plate spacing in mm (default 2)")
    args = parser.parse_args(argv)
    return main(args.n, args.h, plot=args.plot)


if __name__ == "__main__":
    _cli()
