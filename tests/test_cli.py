"""The pdlin command and scene files."""

from __future__ import annotations

import json
from pathlib import Path

import meshio
import numpy as np
import pytest

import pdlin
from pdlin.cli.main import main
from pdlin.errors import PdlinError, SceneError
from pdlin.io.scene import list_builtin_scenes, load_scene

SCENE = """
name = "plate"
[geometry]
type = "grid"
shape = [30, 10]
spacing = 0.01
[material]
E = 70e9
plane = "stress"
[horizon]
ratio = 3.015
influence = "constant"
[[dirichlet]]
set = "x-"
value = 0.0
[[load]]
type = "total"
set = "x+"
force = [1000.0, 0.0]
[solver]
name = "direct"
[output]
path = "out/plate.vtu"
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return p


def test_run_writes_results_and_summary(tmp_path, capsys):
    scene = _write(tmp_path, SCENE)
    assert main(["run", str(scene), "--json", "-q"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["points"] == 300 and summary["solver"] == "direct"
    assert summary["relative_residual"] < 1e-8
    mesh = meshio.read(tmp_path / "out" / "plate.vtu")
    # ParaView / Peridigm field names, vectors padded to 3 components
    assert mesh.point_data["Displacement"].shape == (300, 3)
    # the file holds the solution of the same problem solved through the API
    res = pdlin.solve(load_scene(scene).problem, solver="direct")
    np.testing.assert_allclose(mesh.point_data["Displacement"][:, :2], res.u, rtol=1e-10)
    np.testing.assert_allclose(mesh.point_data["Reaction_Force"][:, 0].sum(), -1000.0, rtol=1e-8)


def test_run_builtin_example_listed():
    assert "bar" in list_builtin_scenes()


def test_run_npz_output(tmp_path):
    scene = _write(tmp_path, SCENE)
    out = tmp_path / "r.npz"
    assert main(["run", str(scene), "-o", str(out), "-q"]) == 0
    data = np.load(out)
    assert data["displacement"].shape == (300, 2) and "strain" in data


def test_unknown_key_names_the_key(tmp_path, capsys):
    scene = _write(tmp_path, SCENE.replace("ratio = 3.015", "ratoi = 3.015"))
    assert main(["run", str(scene), "-q"]) == 2
    err = capsys.readouterr().err
    assert "unknown scene key 'horizon.ratoi'" in err and "did you mean 'ratio'" in err


def test_bad_set_and_missing_key(tmp_path):
    with pytest.raises(SceneError, match=r"dirichlet\[0\].set: unknown point set 'left'"):
        load_scene(_write(tmp_path, SCENE.replace('set = "x-"', 'set = "left"')))
    with pytest.raises(SceneError, match="missing scene key scene.material"):
        load_scene(_write(tmp_path, SCENE.replace('[material]\nE = 70e9\nplane = "stress"\n', "")))


def test_floating_scene_exit_code(tmp_path, capsys):
    scene = _write(
        tmp_path,
        SCENE.replace('set = "x-"\nvalue = 0.0', 'set = "x-"\ncomponents = "x"\nvalue = 0.0'),
    )
    assert main(["run", str(scene), "-q"]) == 2
    assert "rigid-body motion" in capsys.readouterr().err


def test_info_on_scene_and_mesh(tmp_path, capsys):
    scene = _write(tmp_path, SCENE)
    assert main(["info", str(scene), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["points"] == 300
    assert info["bonds_per_point_min_mean_max"][2] == 28  # 2D interior family at 3.015 h
    # a tiny quad mesh through meshio
    pts = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], dtype=float)
    mesh = meshio.Mesh(pts, [("quad", np.array([[0, 1, 4, 3], [1, 2, 5, 4]]))])
    path = tmp_path / "m.vtu"
    mesh.write(path)
    assert main(["info", str(path), "--horizon", "1.5", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["points"] == 2 and info["total_volume"] == pytest.approx(2.0)


def test_examples_command(capsys):
    assert main(["examples"]) == 0
    assert "bar" in capsys.readouterr().out
    assert main(["examples", "--show", "bar"]) == 0
    assert "[geometry]" in capsys.readouterr().out


def test_image_scene_with_per_phase_modulus(tmp_path):
    img = np.zeros((12, 6), dtype=int)
    img[6:, :] = 1  # right half is phase 1
    np.save(tmp_path / "micro.npy", img)
    text = """
[geometry]
type = "image"
path = "micro.npy"
spacing = 0.1
[material]
E = { "0" = 1.0e9, "1" = 4.0e9 }
[horizon]
ratio = 2.015
[[dirichlet]]
set = "x-"
value = 0.0
[[load]]
type = "total"
set = "x+"
force = [100.0, 0.0]
"""
    sc = load_scene(_write(tmp_path, text))
    E = sc.model.E
    np.testing.assert_array_equal(E[sc.cloud.point_set("phase1")], 4.0e9)
    np.testing.assert_array_equal(E[sc.cloud.point_set("phase0")], 1.0e9)
    res = pdlin.solve(sc.problem, solver="direct")
    # the stiffer half stretches less: mean strain ratio close to the modulus ratio 4
    eps = res.strain()[:, 0, 0]
    x = sc.cloud.points[:, 0]
    soft = eps[(x > 0.25) & (x < 0.45)].mean()
    stiff = eps[(x > 0.75) & (x < 0.95)].mean()
    assert 3.0 < soft / stiff < 5.0
    bad = text.replace('E = { "0" = 1.0e9, "1" = 4.0e9 }', 'E = { "0" = 1.0e9 }')
    with pytest.raises(SceneError, match=r"material.E has no value for phase\(s\) \[1\]"):
        load_scene(_write(tmp_path, bad))


def test_scene_with_symmetry_planes_matches_full_model(tmp_path):
    full = """
[geometry]
type = "grid"
shape = [16, 9]
spacing = 0.1
origin = [-0.8, -0.45]
[material]
E = 1.0e9
[horizon]
ratio = 3.015
[[dirichlet]]
set = "x-"
components = "x"
value = -1e-4
[[dirichlet]]
set = "x+"
components = "x"
value = 1e-4
[[dirichlet]]
box = [[-1.0, -0.01], [1.0, 0.01]]
components = "y"
value = 0.0
[solver]
name = "direct"
"""
    # points on the plane y = 0 (odd count): the quarter keeps them, with u_y = 0 imposed
    # by the symmetry plane itself
    quarter = full.replace("shape = [16, 9]", "shape = [8, 5]").replace(
        "origin = [-0.8, -0.45]", "origin = [0.0, -0.05]"
    )
    quarter = quarter.split("[[dirichlet]]")[0] + (
        '[[dirichlet]]\nset = "x+"\ncomponents = "x"\nvalue = 1e-4\n'
        '[[symmetry]]\naxis = "x"\nposition = 0.0\n[[symmetry]]\naxis = "y"\nposition = 0.0\n'
        '[solver]\nname = "direct"\n'
    )
    p_full = tmp_path / "full.toml"
    p_full.write_text(full)
    p_q = tmp_path / "quarter.toml"
    p_q.write_text(quarter)
    sf, sq = load_scene(p_full), load_scene(p_q)
    rf = pdlin.solve(sf.problem, solver="direct")
    rq = pdlin.solve(sq.problem, solver="direct")
    # the quarter's points are the full model's points with x > 0 and y > 0
    pf = sf.cloud.points
    sel = np.flatnonzero((pf[:, 0] > 0) & (pf[:, 1] > -1e-9))
    order = np.lexsort((pf[sel, 1], pf[sel, 0]))
    pq = sq.cloud.points
    oq = np.lexsort((pq[:, 1], pq[:, 0]))
    np.testing.assert_allclose(pf[sel][order], pq[oq])
    # the full model's u_y = 0 on the line y = 0 is what the symmetry implies there
    np.testing.assert_allclose(rq.u[oq], rf.u[sel][order], rtol=1e-9, atol=1e-12)


def test_sparsity_command(tmp_path, capsys):
    scene = _write(tmp_path, SCENE)
    assert main(["sparsity", str(scene), "--json", "--numeric"]) == 0
    rep = json.loads(capsys.readouterr().out)
    sc = load_scene(scene)
    K = pdlin.assemble_stiffness(sc.model, sc.cloud, sc.bonds())
    assert rep["nnz"] == K.nnz  # the pattern predicted from the bonds equals the assembled one
    assert main(["sparsity", str(scene)]) == 0
    assert "nnz" in capsys.readouterr().out


CALIBRATION = """
name = "ti"
[target]
class = "transversely_isotropic"
constants = { C11 = 499.0, C33 = 542.0, C12 = 166.0, C13 = 239.0, C44 = 239.0 }
[family]
dim = 3
horizon = 6.0
influence = "delta_over_r"
[calibration]
method = "two-step"
[output]
path = "c.npz"
"""


def test_calibrate_command(tmp_path, capsys):
    from pdlin import constitutive as cst

    p = tmp_path / "target.toml"
    p.write_text(CALIBRATION)
    assert main(["calibrate", str(p), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["status"] == "step1" and summary["bonds"] == 924  # spec 004 V4
    C = cst.transversely_isotropic(499.0, 542.0, 166.0, 239.0, 239.0)
    assert summary["relative_error"] == pytest.approx(cst.cauchy_distance(C), rel=1e-9)
    data = np.load(tmp_path / "c.npz")
    assert data["micromoduli"].shape == (924,) and np.all(data["micromoduli"] >= 0)
    assert main(["calibrate", str(p), "-o", str(tmp_path / "c.csv")]) == 0
    assert (tmp_path / "c.csv").read_text().startswith("xi0,xi1,xi2,omega,volume,c")


def test_calibrate_infeasible_and_bad_target(tmp_path, capsys):
    p = tmp_path / "t.toml"
    # spec 004 4.2: monoclinic at delta = 2 has no nonnegative solution
    p.write_text(
        CALIBRATION.replace(
            'class = "transversely_isotropic"\nconstants = '
            "{ C11 = 499.0, C33 = 542.0, C12 = 166.0, C13 = 239.0, "
            "C44 = 239.0 }",
            'material = "monoclinic"',
        )
        .replace("horizon = 6.0", "horizon = 2.0")
        .replace('influence = "delta_over_r"', 'influence = "constant"')
    )
    assert main(["calibrate", str(p), "--json"]) == 4
    assert json.loads(capsys.readouterr().out)["status"] == "infeasible"
    p.write_text(CALIBRATION.replace("C44 = 239.0", "C44 = -239.0"))
    assert main(["calibrate", str(p)]) == 2
    assert "positive definite" in capsys.readouterr().err


def test_scene_with_calibrated_material(tmp_path):
    text = """
[geometry]
type = "grid"
shape = [12, 12, 12]
[material.calibration]
method = "two-step"
boundary = "bulk"
[material.calibration.target]
material = "cubic"
[horizon]
value = 3.0
influence = "delta_over_r"
[shadow]
F = [[1.0001, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[solver]
name = "amg-cg"
rtol = 1e-12
"""
    sc = load_scene(_write(tmp_path, text))
    assert sc.calibration.status in ("step1", "qp")  # both reach the least-squares fit
    res = pdlin.solve(sc.problem, solver="amg-cg", rtol=1e-12)
    # shadow layer of depth 3 h on all faces; the 6^3 real core is strained affinely
    p = sc.cloud.points
    core = np.all((p > 3) & (p < 9), axis=1)
    np.testing.assert_allclose(res.strain()[core][:, 0, 0], 1e-4, rtol=1e-8)
    with pytest.raises(SceneError, match="material.E and material.calibration exclude"):
        load_scene(
            _write(
                tmp_path,
                text.replace(
                    "[material.calibration]\n", "[material]\nE = 1.0\n[material.calibration]\n"
                ),
            )
        )


_BASE_2D = """
[geometry]
type = "grid"
shape = [24, 20]
spacing = 0.1
[horizon]
ratio = {ratio}
[shadow]
F = [[1.001, 0.0005], [0.0002, 0.9995]]
{depth}
[solver]
name = "direct"
"""


@pytest.mark.parametrize(
    "model, material, ratio",
    [
        ('type = "lps"', 'E = 1.0e9\nnu = 0.3\nplane = "strain"', 3.015),
        ('type = "xosb"\nlinearization = "energy"', "E = 1.0e9\nnu = 0.3", 3.015),
        (
            'type = "correspondence"\ncontrol = "higher_order"',
            'plane = "strain"\n[material.stiffness]\nclass = "cubic"\n'
            "constants = { C11 = 252.0, C12 = 145.0, C44 = 142.0 }",
            2.0,
        ),
        ('type = "correspondence"\ncontrol = "penalty"', "E = 1.0\nnu = 0.25", 2.0),
        ('type = "correspondence"\ncontrol = "stress_points"\nseed = 3', "E = 1.0\nnu = 0.25", 1.0),
        (
            'type = "correspondence"\ncontrol = "springs"\ncoefficient = 0.5',
            "E = 1.0\nnu = 0.25",
            1.0,
        ),
        ('type = "correspondence"\ncontrol = "ads"\ncoefficient = 0.1', "E = 1.0\nnu = 0.25", 2.0),
    ],
)
def test_scene_models_reproduce_affine_field_with_shadow_layer(tmp_path, model, material, ratio):
    # state-based models couple two horizons: their layer must be two horizons deep for the
    # real points to see only affine dilatations; correspondence uses the intact-lattice
    # shape tensor on a one-horizon layer (spec 000 section 7)
    depth = "depth = 0.62" if "correspondence" not in model else ""
    text = _BASE_2D.format(ratio=ratio, depth=depth)
    text += f"[model]\n{model}\n[material]\n{material}\n"
    sc = load_scene(_write(tmp_path, text))
    res = pdlin.solve(sc.problem, solver="direct")
    F = np.array([[1.001, 0.0005], [0.0002, 0.9995]])
    exact = sc.cloud.points @ (F - np.eye(2)).T
    p = sc.cloud.points
    # points two horizons inside the box see only affine data (two-hop models)
    core = np.all((p > 0.65) & (p < np.array([2.4, 2.0]) - 0.65), axis=1)
    if "correspondence" in model:
        core = np.all((p > 0.2) & (p < np.array([2.4, 2.0]) - 0.2), axis=1)
    assert core.any()
    np.testing.assert_allclose(res.u[core], exact[core], atol=1e-10 * np.abs(exact).max())


def test_scene_model_key_checks(tmp_path):
    text = _BASE_2D.format(ratio=3.015, depth="") + '[model]\ntype = "lps"\ncontrol = "none"\n'
    text += "[material]\nE = 1.0\nnu = 0.3\n"
    with pytest.raises(SceneError, match="unknown scene key 'model.control'"):
        load_scene(_write(tmp_path, text))


@pytest.mark.parametrize("kind", ["lps", "xosb", "correspondence"])
def test_scene_material_bulk_and_shear_moduli(tmp_path, kind):
    # issue 15 item 5: [material] K and G (as in Peridigm decks) give the same problem as
    # E and nu; K = E / (3 (1 - 2ν)), G = E / (2 (1 + ν)) for E = 70e9, ν = 0.3 (closed form)
    E, nu = 70e9, 0.3
    K, G = E / (3 * (1 - 2 * nu)), E / (2 * (1 + nu))
    base = SCENE.replace("[horizon]", f'[model]\ntype = "{kind}"\n[horizon]')
    by_e = base.replace("E = 70e9\n", f"E = 70e9\nnu = {nu}\n")
    by_k = base.replace("E = 70e9\n", f"K = {K!r}\nG = {G!r}\n")
    sc_e = load_scene(_write(tmp_path, by_e))
    sc_k = load_scene(_write(tmp_path, by_k))
    u_e = pdlin.solve(sc_e.problem, solver="direct").u
    u_k = pdlin.solve(sc_k.problem, solver="direct").u
    np.testing.assert_allclose(u_k, u_e, rtol=1e-9, atol=1e-9 * np.abs(u_e).max())
    with pytest.raises(SceneError, match="needs two isotropic constants"):
        load_scene(_write(tmp_path, base.replace("E = 70e9\n", f"K = {K!r}\n")))
    with pytest.raises(PdlinError, match="inconsistent isotropic constants"):
        load_scene(_write(tmp_path, by_k.replace("G = ", "E = 1e9\nG = ")))


CP_SCENE = """
name = "cp"
[geometry]
type = "grid"
shape = [8, 8]
spacing = 0.125
[material]
type = "crystal-plasticity"
orientation = 0.2617993877991494
[model]
type = "correspondence"
[horizon]
ratio = 1.0
influence = "constant"
[[dirichlet]]
set = "boundary"
velocity_gradient = [[0.0, 0.002], [0.002, 0.0]]
[solver]
nonlinear = "newton"
steps = 4
t_end = 4.0
checkpoint = "cp.ckpt.npz"
[output]
path = "out/cp.pvd"
"""


def test_run_nonlinear_scene_writes_series_csv_and_resumes(tmp_path, capsys):
    # a single crystal (θ = 15°) in shear: step 3 is the first plastic one (spec 001 §8.1)
    scene = _write(tmp_path, CP_SCENE)
    assert main(["run", str(scene), "--json", "-q"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["steps"] == 4 and summary["methods"] == ["newton"]
    pvd = tmp_path / "out" / "cp.pvd"
    assert pvd.exists() and pvd.read_text().count("<DataSet") == 4
    (piece,) = (tmp_path / "out").glob("cp.pvd.*/cp_0004.vtu")  # the pieces' versioned folder
    step4 = meshio.read(piece)
    assert {"Displacement", "Cauchy_Stress", "State_gamma"} <= set(step4.point_data)
    rows = (tmp_path / "out" / "cp_homogenized.csv").read_text().splitlines()
    assert len(rows) == 5 and rows[0].startswith("step,time,factor,sigma_11")
    # the same problem through the API
    res = pdlin.solve_nonlinear(load_scene(scene).problem, steps=4, t_end=4.0, method="newton")
    np.testing.assert_allclose(summary["final_homogenized_stress"], res.homogenized_stress[-1])
    # elastic step 1 of this crystal: mean σ_xy close to the material point (8.000 at θ = 0;
    # truncated families soften it, spec 001 §2.4)
    assert 5.0 < float(rows[1].split(",")[4]) < 8.5
    # a resumed run continues after the 4 committed steps of the checkpoint: nothing to do
    assert main(["run", str(scene), "--json", "-q", "--resume"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["iterations"] == summary["iterations"]


@pytest.mark.parametrize(
    "edit, match",
    [
        (('type = "correspondence"', 'type = "lps"'), "needs model.type = 'correspondence'"),
        (("[solver]\n", '[solver]\nname = "direct"\n'), None),
        (('set = "boundary"', 'set = "rim"'), "unknown point set 'rim'"),
        (('nonlinear = "newton"', 'nonlinear = "explicit"'), "solver.nonlinear must be one of"),
        (("velocity_gradient", "value = 0.0\nvelocity_gradient"), "takes 'velocity_gradient' or"),
        (("orientation = 0.2617993877991494", "E = 1.0"), "material.E is not used by"),
    ],
)
def test_nonlinear_scene_errors_name_the_key(tmp_path, edit, match):
    text = CP_SCENE.replace(edit[0], edit[1])
    if match is None:
        assert load_scene(_write(tmp_path, text)).nonlinear["method"] == "newton"
        return
    with pytest.raises(SceneError, match=match):
        load_scene(_write(tmp_path, text))


def test_linear_scene_rejects_load_step_keys_without_nonlinear(tmp_path):
    text = SCENE.replace('[solver]\nname = "direct"', '[solver]\nname = "direct"\nsteps = 3')
    with pytest.raises(SceneError, match="solver.steps needs a nonlinear solve"):
        load_scene(_write(tmp_path, text))
    sc = load_scene(_write(tmp_path, text.replace("steps = 3", 'steps = 3\nnonlinear = "adr"')))
    assert sc.nonlinear == {"method": "adr", "steps": 3}


def test_ghost_layer_scene_reproduces_the_material_point(tmp_path, capsys):
    # spec 001 T21 through a scene: ghost ring + outer ring prescribed by the same path, the
    # single crystal deforms affinely and its mean stress is the §8.1 material-point stress
    text = CP_SCENE.replace("spacing = 0.125\n", "spacing = 0.125\nghost_layers = 1\n").replace(
        '[[dirichlet]]\nset = "boundary"',
        '[[dirichlet]]\nset = "ghost"\nvelocity_gradient = [[0.0, 0.002], [0.002, 0.0]]\n'
        '[[dirichlet]]\nset = "boundary"',
    )
    scene = load_scene(_write(tmp_path, text))
    assert scene.cloud.n == 100 and scene.nonlinear["homogenize"].size == 64
    assert main(["run", str(tmp_path / "scene.toml"), "--json", "-q"]) == 0
    summary = json.loads(capsys.readouterr().out)
    mat = pdlin.CrystalPlasticity(orientation=0.2617993877991494)
    ref = pdlin.material_point(mat, "shear", steps=4, eta=0.002).stress[-1, 0]
    np.testing.assert_allclose(summary["final_homogenized_stress"], ref, rtol=0, atol=1e-7)


def test_nonlinear_scene_options_pass_snapshot_every(tmp_path):
    # solver.snapshot_every reaches solve_nonlinear (ADR snapshots next to the checkpoint)
    from pdlin.io.scene import _nonlinear_options

    problem = load_scene(_write(tmp_path, CP_SCENE)).problem
    cfg = {"nonlinear": "adr", "snapshot_every": 120, "checkpoint": "cp.ckpt.npz"}
    opts = _nonlinear_options(cfg, problem, tmp_path)
    assert opts is not None and opts["snapshot_every"] == 120 and opts["method"] == "adr"
    assert opts["checkpoint"] == tmp_path / "cp.ckpt.npz"


def test_nonlinear_scene_options_pass_polish(tmp_path):
    # solver.polish / solver.adr_stall reach solve_nonlinear (Newton finishing stalled ADR)
    from pdlin.io.scene import _nonlinear_options

    problem = load_scene(_write(tmp_path, CP_SCENE)).problem
    cfg = {"nonlinear": "adr", "polish": True, "adr_stall": 400}
    opts = _nonlinear_options(cfg, problem, tmp_path)
    assert opts is not None and opts["polish"] is True and opts["adr_stall"] == 400


# -- outputs are checked before the work (issue 31) ---------------------------------------
def _no_work(monkeypatch):
    """Make every expensive step of every command fail loudly if it is reached."""

    def work(*args, **kwargs):
        raise AssertionError("the work started before the output was checked")

    import pdlin.calibration
    import pdlin.fracture
    import pdlin.io.read
    import pdlin.io.results
    import pdlin.nonlinear
    import pdlin.plotting
    import pdlin.static
    import pdlin.sweeps.scene
    from pdlin.io.targets import CalibrationJob

    monkeypatch.setattr(pdlin.static, "solve", work)
    monkeypatch.setattr(pdlin.nonlinear, "solve_nonlinear", work)
    monkeypatch.setattr(pdlin.fracture, "solve_damage", work)
    monkeypatch.setattr(pdlin.io.results, "export_system", work)
    monkeypatch.setattr(pdlin.io.read, "read_result", work)
    # pdlin.plotting binds read_result at its import: patched there too (and restored), so
    # no module imported during the test keeps the stand-in (docs/output.md's doctest did)
    monkeypatch.setattr(pdlin.plotting, "read_result", work)
    monkeypatch.setattr(pdlin.sweeps.scene.SceneSweep, "run", work)
    monkeypatch.setattr(CalibrationJob, "run", work)


def _cases(d):
    """(argv, missing module or None, expected message) of each up-front check."""
    (d / "afile").write_text("a file, not a folder")
    (d / "folder.vtu").mkdir()
    cal = d / "target.toml"
    cal.write_text(CALIBRATION)
    return [
        (["run", "--example", "bar", "-o", str(d / "r.txt")], None, r"must end with one of"),
        (["run", "--example", "damage_plate", "-o", str(d / "r.pvd")], None, r"one of \('.vtu'"),
        (["run", "--example", "cp_shear", "-o", str(d / "r.vtk")], None, r"one of \('.xdmf'"),
        (["run", "--example", "bar", "-o", str(d / "r.xdmf")], "h5py", r"needs h5py"),
        (["run", "--example", "cp_shear", "-o", str(d / "r.xdmf")], "h5py", r"needs h5py"),
        (["run", "--example", "bar", "-o", str(d / "r.e")], "netCDF4", r"needs netCDF4"),
        (["run", "--example", "cp_shear", "-o", str(d / "r.exo")], "netCDF4", r"needs netCDF4"),
        (["run", "--example", "bar", "-o", str(d / "afile" / "r.vtu")], None, r"is a file, not"),
        (["run", "--example", "bar", "-o", str(d / "folder.vtu")], None, r"is a folder; expected"),
        (["export", "--example", "bar", "-o", str(d / "K.txt")], None, r"one of \('.mtx'"),
        (["tradeoff", "--example", "bar", "-o", str(d / "t.txt")], None, r"one of \('.csv'"),
        (["tradeoff", "--example", "bar", "--plot", str(d / "t.xyz")], None, r"one of \(.*'\.png'"),
        (["tradeoff", "--example", "bar", "--plot", str(d / "t.png")], "matplotlib", r"matplotl"),
        (["calibrate", str(cal), "-o", str(d / "c.txt")], None, r"one of \('.csv', '.npz'\)"),
        (["plot", str(d / "r.vtu"), "-o", str(d / "p.xyz")], None, r"one of \(.*'\.png'"),
        (["plot", str(d / "r.vtu")], "matplotlib", r"needs matplotlib"),
        (["plot", str(d / "afile" / "r.vtu"), "--convergence"], None, r"is a file, not"),
    ]


@pytest.mark.parametrize("case", range(17))  # the cases of _cases
def test_outputs_are_checked_before_the_work(tmp_path, monkeypatch, capsys, case):
    import sys

    argv, missing, pattern = _cases(tmp_path)[case]
    _no_work(monkeypatch)
    if missing:
        monkeypatch.setitem(sys.modules, missing, None)  # as if not installed
    assert main(argv) == 2
    err = capsys.readouterr().err
    # one error line, the last (after at most the progress line of reading the scene)
    errors = [ln for ln in err.splitlines() if ln.startswith("pdlin: error: ")]
    assert len(errors) == 1 and err.splitlines()[-1] == errors[0], err
    assert "Traceback" not in err
    import re

    assert re.search(pattern, errors[0]), err


def test_closed_pipe_exits_quietly(tmp_path):
    """pdlin examples --show X | head: the reader leaves; no 'Broken pipe' error."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    code = "import sys; from pdlin.cli.main import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen(
        [sys.executable, "-c", code, "examples", "--show", "cp_shear"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader is gone before pdlin writes
    err = proc.stderr.read().decode()
    assert proc.wait() == 141, err  # 128 + SIGPIPE, as a shell tool killed by SIGPIPE
    assert err == ""


def test_file_size_limit_in_the_command_is_one_error_line(tmp_path, capsys, file_size_limit):
    """pdlin run under ulimit -f: one 'pdlin: error:' line naming the file, exit 2, the
    old result intact (main: signal 11 in h5py)."""
    pytest.importorskip("h5py")
    scene = _write(tmp_path, SCENE)
    out = tmp_path / "r.xdmf"
    assert main(["run", str(scene), "-q", "-o", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    capsys.readouterr()
    with file_size_limit(2000):  # bytes, less than the result
        code = main(["run", str(scene), "-q", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith(f"pdlin: error: cannot write {str(out)!r}: File too large"), err
    assert err.count("\n") == 1, err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
