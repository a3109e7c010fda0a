"""Problems shared by the PETSc backend tests and their ``mpiexec -n 2`` script.

Run as a script under MPI: ``mpiexec -n 2 python tests/backends/petsc_cases.py OUT_DIR``
solves every case with ``backend="petsc"`` (with ``--symmetry``: the symmetry-plane
cases); rank 0 writes ``OUT_DIR/u.npz`` (the gathered displacements), every rank writes
``OUT_DIR/rank<r>.json`` (its ownership and iteration counts).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

import pdlin

#: case name -> (dim, model factory, horizon ratio); grids are 24 x 24 (2D) and 10 x 10 x 10 (3D)
#: so that a two-hop halo of one half (LPS, correspondence) does not reach the far end
CASES = {
    "bb-2d": (2, lambda: pdlin.BondBased(E=1.0), 3.015),
    "bb-3d": (3, lambda: pdlin.BondBased(E=1.0), 2.015),
    "lps-2d": (2, lambda: pdlin.LPS(E=1.0, nu=0.25), 3.015),
    "lps-3d": (3, lambda: pdlin.LPS(E=1.0, nu=0.25), 2.015),
    "cor-2d": (2, lambda: pdlin.Correspondence(E=1.0, nu=0.25, control="springs"), 3.015),
    "cor-3d": (3, lambda: pdlin.Correspondence(E=1.0, nu=0.25, control="springs"), 2.015),
}


def problem(name: str) -> pdlin.StaticProblem:
    """Clamped left face, traction on the right face, pulled and sheared."""
    dim, make, ratio = CASES[name]
    n = 24 if dim == 2 else 10
    cloud = pdlin.grid((n,) * dim, spacing=1.0 / n)
    force = [1e-3, 5e-4] if dim == 2 else [1e-3, 5e-4, -2e-4]
    return pdlin.StaticProblem(
        make(),
        cloud,
        bond_options={"ratio": ratio},
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", force)],
    )


#: symmetry-plane cases: name -> (dim, model factory, horizon ratio); the modelled part
#: touches the planes x = 0 (and y = 0 / z = 0), the far faces carry the load
SYMMETRY_CASES = {
    "sym-lps-2d": (2, lambda: pdlin.LPS(E=1.0, nu=0.25), 3.015),
    "sym-bb-2d": (2, lambda: pdlin.BondBased(E=1.0), 3.015),
    "sym-lps-3d": (3, lambda: pdlin.LPS(E=1.0, nu=0.25), 2.015),
}


def symmetry_problem(name: str) -> pdlin.StaticProblem:
    """A quarter plate pulled on x+ and y+ (two planes), a half plate clamped on y-
    (one plane, body force), a quarter bar clamped axially on x- (planes y and z)."""
    dim, make, ratio = SYMMETRY_CASES[name]
    n = 24 if dim == 2 else 10
    cloud = pdlin.grid((n,) * dim, spacing=1.0 / n)
    opts = {"bond_options": {"ratio": ratio}}
    if name == "sym-lps-2d":
        return pdlin.StaticProblem(
            make(), cloud, **opts,
            symmetry=[pdlin.SymmetryPlane("x", 0.0), pdlin.SymmetryPlane("y", 0.0)],
            loads=[pdlin.TotalForce("x+", [1e-3, 0.0]), pdlin.TotalForce("y+", [0.0, -4e-4])],
        )  # fmt: skip
    if name == "sym-bb-2d":
        return pdlin.StaticProblem(
            make(), cloud, **opts, symmetry=[pdlin.SymmetryPlane("x", 0.0)],
            dirichlet=[pdlin.Dirichlet("y-", 0.0)],
            loads=[pdlin.TotalForce("y+", [2e-4, 1e-3]), pdlin.BodyForce(None, [1e-4, 0.0])],
        )  # fmt: skip
    return pdlin.StaticProblem(
        make(), cloud, **opts,
        symmetry=[pdlin.SymmetryPlane("y", 0.0), pdlin.SymmetryPlane("z", 0.0)],
        dirichlet=[pdlin.Dirichlet("x-", 0.0, components="x")],
        loads=[pdlin.TotalForce("x+", [1e-3, 0.0, 0.0])],
    )  # fmt: skip


def main(out: Path, solvers: list[str], symmetry: bool = False) -> None:
    from pdlin.backends.petsc import comm_rank_size

    rank, _ = comm_rank_size()
    us: dict[str, np.ndarray] = {}
    infos: dict[str, dict] = {}
    names, make = (SYMMETRY_CASES, symmetry_problem) if symmetry else (CASES, problem)
    for name in names:
        for solver in solvers:
            res = pdlin.solve(make(name), solver, rtol=1e-12, backend="petsc")
            key = f"{name}/{solver}"
            us[key] = res.u
            keep = ("ranks", "local_rows", "rows_per_rank", "local_points_with_halo", "ksp_type",
                    "pc_type", "factor_package", "n_bonds")  # fmt: skip
            infos[key] = {k: res.info[k] for k in keep if k in res.info}
            infos[key]["n_iter"] = res.n_iter
            infos[key]["relative_residual"] = res.relative_residual
            infos[key]["n_points"] = res.u.shape[0]
            infos[key]["max_abs_reaction"] = float(np.abs(res.reactions).max())
    (out / f"rank{rank}.json").write_text(json.dumps(infos))
    if rank == 0:
        np.savez(out / "u.npz", **{k.replace("/", "__"): v for k, v in us.items()})


if __name__ == "__main__":
    # python petsc_cases.py OUT_DIR [SOLVERS] [--symmetry]: the symmetry-plane cases instead
    args = [a for a in sys.argv[1:] if a != "--symmetry"]
    main(
        Path(args[0]),
        args[1].split(",") if len(args) > 1 else ["amg-cg", "direct"],
        symmetry="--symmetry" in sys.argv,
    )
