"""PETSc backend: same displacements as the scipy path on 1 and 2 MPI ranks.

Skipped with a reason when petsc4py is not installed (``scripts/install_petsc.sh``);
the two-rank tests also need ``mpiexec`` on PATH.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pdlin
from pdlin.backends.petsc import local_rows, petsc_available, rcb_partition
from pdlin.errors import InputError, SceneError

HERE = Path(__file__).parent
ROOT = HERE.parent.parent
_spec = importlib.util.spec_from_file_location("petsc_cases", HERE / "petsc_cases.py")
assert _spec is not None and _spec.loader is not None
cases = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cases)

needs_petsc = pytest.mark.skipif(
    not petsc_available(),
    reason="petsc4py not installed: PETSc backend tests skipped (run scripts/install_petsc.sh)",
)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """Relative max-norm difference."""
    return float(np.abs(a - b).max() / np.abs(b).max())


# --- pure-numpy parts (no PETSc needed) ------------------------------------------------------
def test_rcb_partition_balanced_and_spatial():
    pts = pdlin.grid((12, 9, 5), spacing=1.0).points
    lab = rcb_partition(pts, 3)
    # 540 points in 3 parts: 180 each (1 + 2 split of 540: 180 | 360 -> 180 | 180)
    assert np.bincount(lab).tolist() == [180, 180, 180]
    # first cut across x (the longest axis, 12 cells): part 0 is the slab of x-layers 0..3;
    # the other 8 x 9 x 5 block is longest along y (9 cells) and is cut across y
    assert np.unique(pts[lab == 0, 0]).tolist() == [0.5, 1.5, 2.5, 3.5]
    assert pts[lab == 1, 1].max() <= pts[lab == 2, 1].min()
    assert np.unique(pts[lab == 1, 0]).size == np.unique(pts[lab == 2, 0]).size == 8
    assert np.array_equal(lab, rcb_partition(pts, 3))  # deterministic on every rank
    with pytest.raises(InputError, match="nparts must be <= the number of points"):
        rcb_partition(pts[:2], 3)


@pytest.mark.parametrize("name", list(cases.CASES))
def test_local_rows_equal_global_rows(name):
    """Rows built from the owned points' local cloud equal the global K's rows."""
    prob = cases.problem(name)
    cloud = prob.cloud
    K = pdlin.assemble_stiffness(prob.model, cloud, prob.get_bonds()).tocsr()
    d = cloud.dim
    lab = rcb_partition(cloud.points, 2)
    for part in (0, 1):
        owned = np.flatnonzero(lab == part)
        rows, index, _, bonds = local_rows(prob.model, cloud, owned, bond_options=prob.bond_options)
        dofs = (owned[:, None] * d + np.arange(d)).reshape(-1)
        diff = abs(rows.tocsr() - K[dofs]).max()
        assert diff <= 1e-12 * abs(K).max(), (name, part, diff)
        assert index.size < cloud.n  # the halo does not reach the far side
        assert bonds.n_bonds < prob.get_bonds().n_bonds


def test_backend_validation_without_petsc():
    prob = cases.problem("bb-2d")
    with pytest.raises(InputError, match="backend must be one of"):
        pdlin.solve(prob, backend="trilinos")
    with pytest.raises(InputError, match="petsc_options needs backend='petsc'"):
        pdlin.solve(prob, petsc_options={"ksp_monitor": None})
    with pytest.raises(InputError, match="scipy-only"):
        pdlin.solve(prob, backend="petsc", operator="matrix-free")


def test_scene_backend_keys(tmp_path):
    from pdlin.io.scene import builtin_scene, scene_from_dict

    data, _ = builtin_scene("bar")
    data = dict(data)
    data.pop("tradeoff", None)
    data["solver"] = {"name": "amg-cg", "backend": "petsc", "petsc_options": {"ksp_rtol": 1e-9}}
    sc = scene_from_dict(data, tmp_path)
    assert sc.backend == "petsc" and sc.petsc_options == {"ksp_rtol": 1e-9}
    data["solver"] = {"backend": "cuda"}
    with pytest.raises(SceneError, match="solver.backend must be one of"):
        scene_from_dict(data, tmp_path)
    data["solver"] = {"petsc_options": {"ksp_rtol": 1e-9}}
    with pytest.raises(SceneError, match="needs solver.backend = 'petsc'"):
        scene_from_dict(data, tmp_path)


#: the built-in bar scene at 20 x 4 x 4 points, with its PETSc backend keys
SMALL_BAR = """
name = "small-bar"
[geometry]
type = "grid"
shape = [20, 4, 4]
spacing = 0.01
[material]
E = 200e9
[model]
type = "bond_based"
[horizon]
ratio = 2.015
[[dirichlet]]
set = "x-"
value = 0.0
[[load]]
type = "total"
set = "x+"
force = [1600.0, 0.0, 0.0]
[solver]
name = "amg-cg"
rtol = 1e-10
backend = "petsc"
[solver.petsc_options]
ksp_rtol = 1e-10
"""


# --- one rank, in process --------------------------------------------------------------------
@needs_petsc
@pytest.mark.parametrize("name", list(cases.CASES))
def test_one_rank_matches_scipy(name):
    prob = cases.problem(name)
    ref = pdlin.solve(prob, "direct")
    for solver in ("amg-cg", "direct"):
        res = pdlin.solve(prob, solver, rtol=1e-12, backend="petsc")
        assert type(res).__name__ == "PetscStaticResult" and isinstance(res, pdlin.StaticResult)
        assert _rel(res.u, ref.u) < 1e-8, (name, solver, _rel(res.u, ref.u))
        assert _rel(res.reactions, ref.reactions) < 1e-8
        assert res.relative_residual < (10e-12 if solver == "amg-cg" else 1e-8)
        assert res.info["local_rows"] == prob.cloud.ndof  # one rank owns every row
        print(f"{name} {solver}: {res.n_iter} iterations ({res.info['ksp_type']} + "
              f"{res.info['pc_type']})")  # fmt: skip
        if solver == "amg-cg":
            assert res.info["pc_type"] == "gamg" and 1 <= res.n_iter < 200
    # the gathered point fields match the scipy result's
    f_ref, f = ref.fields(), res.fields()
    for key in ("deformation_gradient", "stress", "family_size"):
        assert np.allclose(f[key], f_ref[key], rtol=1e-8, atol=1e-8 * np.abs(f_ref[key]).max())


@needs_petsc
def test_petsc_options_and_errors():
    prob = cases.problem("bb-2d")
    # ksp_max_it = 2 cannot reach rtol 1e-12: the options pass through and the miss is reported
    with pytest.raises(pdlin.ConvergenceError, match="no convergence"):
        pdlin.solve(prob, "amg-cg", rtol=1e-12, backend="petsc", petsc_options={"ksp_max_it": 2})
    res = pdlin.solve(prob, "cg", backend="petsc", petsc_options={"ksp_type": "minres"})
    assert res.info["ksp_type"] == "minres"


@needs_petsc
def test_cli_run_with_petsc_backend(tmp_path):
    scene = tmp_path / "bar.toml"
    scene.write_text(SMALL_BAR)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = {}
    for backend in ("scipy", "petsc"):
        p = subprocess.run(
            [sys.executable, "-m", "pdlin", "run", str(scene), "--json", "-q",
             "--backend", backend, "-o", str(tmp_path / f"{backend}.npz")],
            capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300,
        )  # fmt: skip
        assert p.returncode == 0, p.stderr
        out[backend] = json.loads(p.stdout)
    assert out["petsc"]["solver"].startswith("petsc-")
    u0 = np.asarray(out["scipy"]["max_abs_u"])
    assert np.allclose(out["petsc"]["max_abs_u"], u0, rtol=1e-7)
    a = np.load(tmp_path / "scipy.npz")
    b = np.load(tmp_path / "petsc.npz")
    assert _rel(b["displacement"], a["displacement"]) < 1e-7


# --- two ranks: mpiexec -n 2 -------------------------------------------------------------------
def _mpiexec() -> list[str] | None:
    exe = shutil.which("mpiexec")
    if exe is None:
        return None
    ver = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout
    extra = ["--oversubscribe"] if "Open MPI" in ver or "OpenRTE" in ver else []
    return [exe, "-n", "2", *extra]


def _mpi_env() -> dict[str, str]:
    return {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        "OMPI_ALLOW_RUN_AS_ROOT": "1",
        "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
        "OMPI_MCA_rmaps_base_oversubscribe": "1",
    }


@needs_petsc
@pytest.mark.skipif(_mpiexec() is None, reason="mpiexec not on PATH: two-rank PETSc tests skipped")
def test_two_ranks_match_scipy(tmp_path):
    cmd = [*_mpiexec(), sys.executable, str(HERE / "petsc_cases.py"), str(tmp_path)]
    p = subprocess.run(cmd, capture_output=True, text=True, env=_mpi_env(), timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    u = np.load(tmp_path / "u.npz")
    infos = [json.loads((tmp_path / f"rank{r}.json").read_text()) for r in (0, 1)]
    for name in cases.CASES:
        prob = cases.problem(name)
        ref = pdlin.solve(prob, "direct")
        ndof = prob.cloud.ndof
        for solver in ("amg-cg", "direct"):
            key = f"{name}/{solver}"
            assert _rel(u[key.replace("/", "__")], ref.u) < 1e-8, key
            r0, r1 = infos[0][key], infos[1][key]
            assert r0["ranks"] == 2
            # rank-local ownership: each rank's rows are its owned points x dim, no rank has all
            assert [r0["local_rows"], r1["local_rows"]] == r0["rows_per_rank"]
            assert r0["local_rows"] + r1["local_rows"] == ndof
            assert max(r0["local_rows"], r1["local_rows"]) < ndof
            assert r0["local_rows"] % prob.cloud.dim == 0
            # and no rank built the whole cloud's bonds: its local cloud is a strict part
            assert max(r0["local_points_with_halo"], r1["local_points_with_halo"]) < prob.cloud.n
            assert r0["n_bonds"] == ref.bonds.n_bonds  # summed over ranks: the global bond count
            print(f"{key} on 2 ranks: {r0['n_iter']} iterations, rows {r0['rows_per_rank']}")


@needs_petsc
def test_baij_gmres_and_nonsymmetric_paths():
    from pdlin.backends.petsc import solve_petsc

    prob = cases.problem("lps-2d")
    ref = pdlin.solve(prob, "direct")
    for solver in ("direct", "ilu-gmres", "jacobi-cg"):  # MATMPIBAIJ, block size 2
        res = solve_petsc(prob, solver, rtol=1e-12, mat_type="baij")
        assert res.info["mat_type"] == "baij" and _rel(res.u, ref.u) < 1e-8, solver
    with pytest.raises(InputError, match="GAMG needs an AIJ"):
        solve_petsc(prob, "amg-cg", mat_type="baij")
    # the force-state linearization of LPS is nonsymmetric: 'auto' runs GMRES + GAMG
    paper = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.25, linearization="paper"), prob.cloud,
        bond_options=prob.bond_options, dirichlet=prob.dirichlet, loads=prob.loads,
    )  # fmt: skip
    ref_p = pdlin.solve(paper, "direct")
    res = pdlin.solve(paper, rtol=1e-12, backend="petsc")
    assert res.info["ksp_type"] == "gmres" and res.info["pc_type"] == "gamg"
    assert _rel(res.u, ref_p.u) < 1e-8


# --- symmetry planes: the system's prescribed DOFs and loads, rows eliminated per rank -----------
@needs_petsc
@pytest.mark.parametrize("name", list(cases.SYMMETRY_CASES))
def test_symmetry_planes_one_rank_match_scipy(name):
    prob = cases.symmetry_problem(name)
    ref = pdlin.solve(prob, "direct")
    for solver in ("amg-cg", "direct"):
        res = pdlin.solve(prob, solver, rtol=1e-12, backend="petsc")
        assert _rel(res.u, ref.u) < 1e-8, (name, solver, _rel(res.u, ref.u))
        scale = np.abs(ref.reactions).max()
        assert np.abs(res.reactions - ref.reactions).max() <= 1e-8 * max(scale, 1e-30)
        assert np.array_equal(res.prescribed_dofs, ref.prescribed_dofs)
        assert res.info["n_bonds"] == ref.bonds.n_bonds  # real-real bonds, as scipy counts
    f_ref, f = ref.fields(), res.fields()
    for key in ("deformation_gradient", "stress", "family_size"):
        assert np.allclose(f[key], f_ref[key], rtol=1e-8, atol=1e-8 * np.abs(f_ref[key]).max())


@needs_petsc
@pytest.mark.skipif(_mpiexec() is None, reason="mpiexec not on PATH: two-rank PETSc tests skipped")
def test_symmetry_planes_two_ranks_match_scipy(tmp_path):
    cmd = [*_mpiexec(), sys.executable, str(HERE / "petsc_cases.py"), str(tmp_path), "--symmetry"]
    p = subprocess.run(cmd, capture_output=True, text=True, env=_mpi_env(), timeout=600)
    assert p.returncode == 0, p.stdout + p.stderr
    u = np.load(tmp_path / "u.npz")
    infos = [json.loads((tmp_path / f"rank{r}.json").read_text()) for r in (0, 1)]
    for name in cases.SYMMETRY_CASES:
        prob = cases.symmetry_problem(name)
        ref = pdlin.solve(prob, "direct")
        for solver in ("amg-cg", "direct"):
            key = f"{name}/{solver}"
            assert _rel(u[key.replace("/", "__")], ref.u) < 1e-8, key
            r0, r1 = infos[0][key], infos[1][key]
            assert r0["ranks"] == 2 and r0["local_rows"] + r1["local_rows"] == prob.cloud.ndof
            assert max(r0["local_rows"], r1["local_rows"]) < prob.cloud.ndof
            assert r0["n_bonds"] == ref.bonds.n_bonds
            assert np.isclose(r0["max_abs_reaction"], np.abs(ref.reactions).max(), rtol=1e-7,
                              atol=1e-30)  # fmt: skip


@pytest.mark.parametrize("name", list(cases.SYMMETRY_CASES) + ["lps-2d"])
def test_point_system_matches_the_constrained_system(name):
    """PETSc's bond-free system has the scipy system's prescribed DOFs, values and loads."""
    from pdlin.system import constrained_system, point_system

    prob = cases.symmetry_problem(name) if name in cases.SYMMETRY_CASES else cases.problem(name)
    full, pts = constrained_system(prob), point_system(prob)
    assert np.array_equal(pts.dofs, full.dofs) and np.array_equal(pts.values, full.values)
    assert np.array_equal(pts.f_ext, full.f_ext) and np.array_equal(pts.free, full.free)


def test_point_system_names_the_motions_the_planes_leave():
    prob = cases.symmetry_problem("sym-lps-3d")  # planes y and z: the x translation is free
    free = pdlin.StaticProblem(prob.model, prob.cloud, bond_options=prob.bond_options,
                               symmetry=prob.symmetry, loads=prob.loads)  # fmt: skip
    from pdlin.system import point_system

    with pytest.raises(pdlin.FloatingBodyError, match="translation x"):
        point_system(free)
