"""Performance of the ordinary state-based models (LPS, XOSB of Liu, Chen & Skelton).

Rows (each in a forked child process, so ``peak`` is that configuration's own peak RSS):

* ``weights``: XOSB preprocessing (per-point λ solves of the scaled 3x3/6x6 and 5x5/15x15
  Gram systems, fallback flags), million directed bonds per second;
* ``asm``: assembly of ``K`` (energy ``K_E`` / paper ``K_p``) by one sparse product of
  stacked point-level operators, time and ``nnz/row`` (uniform interior at δ = 3.01 Δ:
  210 in 2D, 2,487 in 3D: counted from the two-hop lattice stencil);
* solves of a plate / cube clamped on x- and pulled (u_x prescribed) on x+, relative
  residual 1e-8: SuperLU (``direct``), AMG-CG on ``K_E``, AMG-GMRES on ``K_p``
  (iterations in brackets);
* ``mf-cg``: matrix-free CG on the :meth:`operator` of ``K_E`` (products from ``B`` and
  per-bond coefficients, O(bonds) memory), preconditioned by smoothed-aggregation AMG of
  the one-hop bond-based stiffness (a surrogate: the linearized bond-based matrix the
  paper uses for ADR's mass, Liu, Chen & Skelton, XOSB, Sec. 4.3).

``--anchor N`` runs the Peridigm anchor problem of the issue: a cell-centred N³ cube,
δ = 3.015 h, ``LPS(peridigm=True)``, x- face clamped, x+ face pulled (u_x prescribed),
through both the assembled path (``pdlin.solve``, AMG-CG) and the matrix-free path; the
target is N = 30 assembled and solved in ≤ 15 s with ≤ 4.5 GB peak.

Run ``python benchmarks/bench_state_based.py --quick`` (about a minute) or without
arguments (several minutes); times are wall-clock seconds on a shared machine with the CPU
seconds beside them (``wall / cpu``), solver iterations in brackets, and the ``direct``
columns name the backend that ran (``direct_backend='auto'``: SuperLU unless CHOLMOD or
PARDISO is installed and the system is large).  The header gives the load average, usable
cores, BLAS threads and installed direct backends.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import multiprocessing as mp  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header  # noqa: E402

import pdlin  # noqa: E402
from pdlin.constraints import eliminate_dirichlet, resolve_dirichlet  # noqa: E402
from pdlin.solvers.linear import amg_hierarchy  # noqa: E402


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def _since(t: tuple[float, float]) -> tuple[float, float]:
    return time.perf_counter() - t[0], time.process_time() - t[1]


def _problem(shape: tuple[int, ...], model: Any) -> tuple[Any, Any, Any]:
    cloud = pdlin.grid(shape, spacing=1.0 / shape[0])
    bonds = pdlin.find_bonds(cloud, ratio=3.01)
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    return cloud, bonds, pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc)


def matrix_free_solve(model: Any, cloud: Any, bonds: Any, dirichlet: Any, rtol: float = 1e-8):
    """CG on the matrix-free K_E (free DOFs) with AMG of the one-hop bond-based surrogate."""
    d = cloud.dim
    ndof = cloud.ndof
    dofs, vals = resolve_dirichlet(cloud, dirichlet)
    free = np.ones(ndof, dtype=bool)
    free[dofs] = False
    op = model.operator(cloud, bonds)
    uc = np.zeros(ndof)
    uc[dofs] = vals
    b = -(op @ uc)
    b[~free] = 0.0

    def mv(x: np.ndarray) -> np.ndarray:
        y = op @ (x * free)
        y[~free] = x[~free]
        return y

    A = spla.LinearOperator((ndof, ndof), matvec=mv, dtype=float)
    sur = pdlin.BondBased(E=float(model.E)).stiffness(cloud, bonds)
    As, _ = eliminate_dirichlet(sur, np.zeros(ndof), dofs, np.zeros(dofs.size), inplace=True)
    near = pdlin.operators.rigid_body_modes(cloud)
    near[dofs] = 0.0
    t = _clock()
    ml = amg_hierarchy(As, near, blocksize=d)
    setup = _since(t)
    its = [0]

    def cb(_: np.ndarray) -> None:
        its[0] += 1

    t = _clock()
    x, info = spla.cg(A, b, rtol=rtol, M=ml.aspreconditioner(), maxiter=2000, callback=cb)
    solve = _since(t)
    res = np.linalg.norm(A @ x - b) / np.linalg.norm(b)
    return x + uc, {"setup": setup, "solve": solve, "iters": its[0], "res": res, "info": info}


def _row(shape: tuple[int, ...], solvers: tuple[str, ...], mf: bool) -> dict[str, Any]:
    out: dict[str, Any] = {"shape": shape}
    warm = pdlin.grid(shape[:1] * len(shape) if len(shape) == 2 else (5, 5, 5), spacing=1.0)
    pdlin.XOSB(1.0, 0.3).stiffness(warm, pdlin.find_bonds(warm, ratio=3.01))  # imports, caches
    cloud, bonds, _ = _problem(shape, pdlin.XOSB(1.0, 0.3))
    out["n"] = cloud.n
    out["nb"] = bonds.n_bonds
    for lin in ("energy", "paper"):
        model = pdlin.XOSB(1e9, 0.3, linearization=lin)
        t = _clock()
        w = model.weights(cloud, bonds)
        if lin == "energy":
            out["weights"] = _since(t)
            out["fallback"] = int(w.fallback.sum())
        t = _clock()
        nblk = model.estimate_nnz_blocks(cloud, bonds)
        out[f"est_{lin}"] = _since(t)
        t = _clock()
        K = model.stiffness(cloud, bonds)
        out[f"asm_{lin}"] = _since(t)
        d = cloud.dim
        assert nblk == K.nnz // d**2
        out["nnz_row"] = K.nnz / cloud.ndof
        centre = int(np.argmin(np.linalg.norm(cloud.points - cloud.points.mean(0), axis=1)))
        Kc = K.tocsr()
        out["nnz_row_centre"] = int(np.diff(Kc.indptr)[centre * d])
        del K, Kc
        prob = pdlin.StaticProblem(
            model,
            cloud,
            bonds=bonds,
            dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")],
        )
        for s in solvers:
            if (lin == "paper" and s == "amg-cg") or (lin == "energy" and s == "amg-gmres"):
                continue
            t = _clock()
            res = pdlin.solve(prob, solver=s, rtol=1e-8)
            out[f"{s}_{lin}"] = (*_since(t), res.n_iter, res.info.get("direct_backend"))
        if mf and lin == "energy":
            t = _clock()
            _, info = matrix_free_solve(model, cloud, bonds, prob.dirichlet)
            out["mf"] = (*_since(t), info["iters"])
    out["peak"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    return out


def _anchor(n: int, assembled: bool) -> dict[str, Any]:
    out: dict[str, Any] = {"N": n}
    t_all = _clock()
    cloud = pdlin.grid((n,) * 3, spacing=1.0 / n)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    out["bonds"] = _since(t_all)
    out["nb"] = bonds.n_bonds
    model = pdlin.LPS(1e9, 0.3, peridigm=True)
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    if assembled:
        out["est_blocks"] = model.estimate_nnz_blocks(cloud, bonds)
        res = pdlin.solve(
            pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc), solver="amg-cg", rtol=1e-8
        )
        out["timings"] = {k: round(v, 2) for k, v in res.timings.items()}
        out["iters"] = res.n_iter
        out["u_max"] = float(np.abs(res.u).max())
    else:
        u, info = matrix_free_solve(model, cloud, bonds, bc)
        out["mf"] = {
            k: (tuple(round(x, 2) for x in v) if isinstance(v, tuple) else v)
            for k, v in info.items()
        }
        out["u_max"] = float(np.abs(u).max())
    out["total"] = _since(t_all)
    out["peak_GB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    return out


def _large(shape: tuple[int, ...], paper: bool) -> dict[str, Any]:
    """Matrix-free XOSB solve at sizes where the assembled K is not worth building.

    ``pdlin.solve(operator="matrix-free")``: CG on the energy ``K_E`` (or GMRES on the paper
    ``K_p`` with the same bond-based AMG surrogate preconditioner), x- clamped, x+ pulled.
    """
    out: dict[str, Any] = {"shape": shape}
    t_all = _clock()
    cloud = pdlin.grid(shape, spacing=1.0 / shape[0])
    bonds = pdlin.find_bonds(cloud, ratio=3.01)
    out["bonds"] = _since(t_all)
    out["n"], out["nb"] = cloud.n, bonds.n_bonds
    model = pdlin.XOSB(1e9, 0.3, linearization="paper" if paper else "energy")
    t = _clock()
    model.weights(cloud, bonds)
    out["weights"] = _since(t)
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    prob = pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc)
    t = _clock()
    res = pdlin.solve(
        prob, solver="amg-gmres" if paper else "amg-cg", operator="matrix-free", rtol=1e-8
    )
    out["solve_total"] = _since(t)
    out["timings"] = {k: round(v, 2) for k, v in res.timings.items()}
    out["iters"] = res.n_iter
    out["res"] = res.relative_residual
    out["total"] = _since(t_all)
    out["peak"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    return out


def _block3d(n_ang: int, n_rad: int, layers: int, model_name: str) -> dict[str, Any]:
    """Solve the 3D block with a hole of Liu, Chen & Skelton, XOSB, Sec. 5.2, matrix-free.

    The paper's 173,944-cell mesh is not given: an extruded O-grid stands in.

    L = 1 m, r = 0.1 m, depth 0.3 m, E = 70 GPa, ν = 0.33, δ_i = 3.01 Δ_i; the outermost
    radial layer of the left block clamped, that of the right block pulled by u0 = 5e-4 m in
    x (y, z free there); CG on ``K_E`` with the bond-based AMG surrogate, rtol 1e-8.
    """
    out: dict[str, Any] = {}
    t_all = _clock()
    mesh = pdlin.plate_with_hole_mesh(n_ang, n_rad, layers=layers, depth=0.3)
    cloud = pdlin.read_mesh(mesh)
    bonds = pdlin.find_bonds(cloud, ratio=3.01)
    out["bonds"] = _since(t_all)
    out["n"], out["nb"] = cloud.n, bonds.n_bonds
    model = pdlin.XOSB(70e9, 0.33) if model_name == "xosb" else pdlin.LPS(70e9, 0.33)
    t = _clock()
    if model_name == "xosb":
        w = model.weights(cloud, bonds)
        out["fallback"] = int(np.sum(w.fallback))
    out["weights"] = _since(t)
    x, y = cloud.points[:, 0], cloud.points[:, 1]
    side = np.abs(x) > np.abs(y)
    per_layer = n_ang * layers
    left = np.flatnonzero(side)[np.argsort(x[side])[:per_layer]]
    right = np.flatnonzero(side)[np.argsort(-x[side])[:per_layer]]
    bc = [pdlin.Dirichlet(left, 0.0), pdlin.Dirichlet(right, 5e-4, components="x")]
    prob = pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc)
    t = _clock()
    res = pdlin.solve(prob, solver="amg-cg", operator="matrix-free", rtol=1e-8)
    out["solve_total"] = _since(t)
    out["timings"] = {k: round(v, 2) for k, v in res.timings.items()}
    out["iters"] = res.n_iter
    out["res"] = res.relative_residual
    out["u_max"] = float(np.abs(res.u).max())
    out["total"] = _since(t_all)
    out["peak"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    return out


def _in_child(fn: Any, *args: Any) -> Any:
    ctx = mp.get_context("fork")
    with ctx.Pool(1) as pool:
        return pool.apply(fn, args)


def _fmt(t: Any) -> str:
    """``wall / cpu`` seconds, then ``(iterations)`` and the direct backend when given."""
    if t is None:
        return "-"
    text = f"{t[0]:.2f} / {t[1]:.2f}"
    if len(t) > 2 and t[2]:
        text += f" ({t[2]})"
    if len(t) > 3 and t[3]:
        text += f" {t[3]}"
    return text


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--anchor", type=int, default=0, help="run the N^3 Peridigm anchor only")
    p.add_argument("--no-assembled", action="store_true", help="anchor: matrix-free only")
    p.add_argument(
        "--large",
        action="store_true",
        help="matrix-free XOSB plates up to 10^6 points (2D) and a 40^3 cube",
    )
    p.add_argument(
        "--block3d",
        type=int,
        default=0,
        metavar="LAYERS",
        help="the XOSB paper's 3D block with a hole: 4 x 32 x 60 O-grid x LAYERS "
        "(23: 176,640 cells)",
    )
    args = p.parse_args(argv)
    header()
    if args.anchor:
        if not args.no_assembled:
            print("assembled:", _in_child(_anchor, args.anchor, True))
        print("matrix-free:", _in_child(_anchor, args.anchor, False))
        return
    if args.block3d:
        for name in ("xosb", "lps"):
            print(name, _in_child(_block3d, 32, 60, args.block3d, name), flush=True)
        return
    if args.large:
        print(
            "| shape | points | bonds | paper K_p? | bonds s | λ weights s | operator + "
            "AMG(surrogate) setup s | solve s | iterations | rel. residual | total s (wall / "
            "cpu) | peak GB |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for shape, paper in [
            ((500, 500), False),
            ((500, 500), True),
            ((710, 710), False),
            ((1000, 1000), False),
            ((40, 40, 40), False),
        ]:
            r = _in_child(_large, shape, paper)
            tm = r["timings"]
            print(
                f"| {'x'.join(map(str, shape))} | {r['n']:,} | {r['nb']:,} | {paper} | "
                f"{r['bonds'][0]:.2f} | {r['weights'][0]:.2f} | "
                f"{tm.get('assembly', 0) + tm.get('setup', 0):.2f} | {tm.get('solve', 0):.2f} | "
                f"{r['iters']} | {r['res']:.1e} | {_fmt(r['total'])} | {r['peak']:.2f} |",
                flush=True,
            )
        return
    if args.quick:
        sizes = [
            ((60, 30), ("direct", "amg-cg", "amg-gmres")),
            ((10, 10, 10), ("direct", "amg-cg", "amg-gmres")),
        ]
    else:
        sizes = [
            ((100, 50), ("direct", "amg-cg", "amg-gmres")),
            ((200, 100), ("direct", "amg-cg", "amg-gmres")),
            ((400, 200), ("amg-cg", "amg-gmres")),
            ((12, 12, 12), ("direct", "amg-cg", "amg-gmres")),
            ((16, 16, 16), ("amg-cg", "amg-gmres")),
            ((20, 20, 20), ("amg-cg", "amg-gmres")),
        ]
    hdr = (
        "| shape | points | bonds | fallback | weights s (Mb/s) | asm K_E s (wall / cpu) | "
        "asm K_p s (wall / cpu) | "
        "nnz/row (centre) | direct K_E | direct K_p | AMG-CG K_E | AMG-GMRES K_p | "
        "mf-CG K_E | peak GB |"
    )
    print(hdr)
    print("|" + "---|" * (hdr.count("|") - 1))
    for shape, solvers in sizes:
        r = _in_child(_row, shape, solvers, True)
        wt = r["weights"][0]
        print(
            f"| {'x'.join(map(str, shape))} | {r['n']:,} | {r['nb']:,} | {r['fallback']} | "
            f"{wt:.2f} ({r['nb'] / wt / 1e6:.1f}) | {_fmt(r['asm_energy'])} | "
            f"{_fmt(r['asm_paper'])} | {r['nnz_row']:.0f} ({r['nnz_row_centre']}) | "
            f"{_fmt(r.get('direct_energy'))} | {_fmt(r.get('direct_paper'))} | "
            f"{_fmt(r.get('amg-cg_energy'))} | {_fmt(r.get('amg-gmres_paper'))} | "
            f"{_fmt(r.get('mf'))} | {r['peak']:.2f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
