"""``[compare.cpfe]``: the CPFE comparator run from a scene by ``pdlin run``."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest

import pdlin
from pdlin.cli.main import main
from pdlin.errors import SceneError
from pdlin.scene.compare import cpfe_keywords
from pdlin.scene.scene import load_scene, scene_from_dict
from pdlin.verification.cpfe import crystal_plasticity_fem

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

# a 5 x 5 single crystal at 0.26 rad in pure shear: small enough for seconds
SCENE = """
name = "sc"
[geometry]
type = "grid"
shape = [5, 5]
spacing = 0.2
[material]
type = "crystal-plasticity"
slip = "planar-2"
orientation = 0.26
[model]
type = "correspondence"
[horizon]
ratio = 1.0
[[dirichlet]]
set = "boundary"
velocity_gradient = [[0.0, 0.002], [0.002, 0.0]]
center = [0.0, 0.0]
[solver]
nonlinear = "auto"
steps = 5
t_end = 5.0
[output]
path = "sc.pvd"
[compare.cpfe]
"""

POLY = SCENE.replace("orientation = 0.26\n", "[material.polycrystal]\ngrains = 3\nseed = 1\n")


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return p


def _run_json(tmp_path: Path, text: str, capsys: pytest.CaptureFixture[str]) -> dict:
    assert main(["run", str(_write(tmp_path, text)), "--json", "-q"]) == 0
    return json.loads(capsys.readouterr().out)


def test_scene_cpfe_equals_the_python_call(tmp_path, capsys):
    summary = _run_json(tmp_path, SCENE, capsys)
    # the same problem built in Python, solved by the documented call
    mat = pdlin.CrystalPlasticity("planar-2", orientation=0.26)
    L = 0.002 * np.array([[0.0, 1.0], [1.0, 0.0]])
    prob = pdlin.StaticProblem(
        pdlin.Correspondence(material=mat),
        pdlin.grid((5, 5), spacing=0.2),
        horizon=0.2,
        dirichlet=[pdlin.Dirichlet.velocity_gradient("boundary", L, center=[0.0, 0.0])],
    )
    ref = crystal_plasticity_fem(prob, steps=5, t_end=5.0, method="auto")
    got = np.array(summary["cpfe"]["homogenized_stress"])
    assert got.shape == (5, 2, 2)
    np.testing.assert_allclose(got, ref.homogenized_stress, rtol=1e-12, atol=1e-12)
    # the CSV: the scene's own columns, the CPFE history to its 10 printed digits
    with open(tmp_path / "sc_cpfe_homogenized.csv") as fh:
        rows = list(csv.DictReader(fh))
    with open(tmp_path / "sc_homogenized.csv") as fh:
        assert list(csv.DictReader(fh).fieldnames) == list(rows[0])
    sxy = [float(r["sigma_12"]) for r in rows]
    np.testing.assert_allclose(sxy, ref.homogenized_stress[:, 0, 1], rtol=1e-9)
    # the series: per-particle element stress, one file per step
    series = meshio.read(next(tmp_path.glob("sc_cpfe.pvd.*/*_0005.vtu")))
    assert series.points.shape[0] == 25
    # the gap reported per step is CPPD - CPFE of the printed component
    g = summary["cpfe"]["gap"]
    assert summary["cpfe"]["component"] == "xy"  # pure shear: sigma_xy dominates
    cppd = np.array(summary["final_homogenized_stress"])
    assert g["cppd"][-1] == pytest.approx(cppd[0, 1], rel=1e-15)
    assert g["difference"][-1] == pytest.approx(cppd[0, 1] - ref.homogenized_stress[-1, 0, 1])


def test_scene_cpfe_polycrystal_and_full_integration(tmp_path, capsys):
    text = POLY.replace("[compare.cpfe]\n", '[compare.cpfe]\nintegration = "full"\n')
    summary = _run_json(tmp_path, text, capsys)
    sc = load_scene(tmp_path / "scene.toml")
    assert cpfe_keywords(sc) == {"steps": 5, "t_end": 5.0, "integration": "full", "method": "auto"}
    ref = crystal_plasticity_fem(sc.problem, steps=5, t_end=5.0, integration="full", method="auto")
    got = np.array(summary["cpfe"]["homogenized_stress"])
    np.testing.assert_allclose(got, ref.homogenized_stress, rtol=1e-12, atol=1e-12)
    fbar = crystal_plasticity_fem(sc.problem, steps=5, t_end=5.0, method="auto")
    # the key takes effect: full integration locks (stiffer, docs/crystal_plasticity.md)
    assert np.abs(got[-1, 0, 1]) > np.abs(fbar.homogenized_stress[-1, 0, 1])


def test_printed_gap_table_and_strict_failure(tmp_path, capsys):
    text = SCENE.replace("[compare.cpfe]\n", "[compare.cpfe]\ntolerance = 1e-9\n")
    scene = _write(tmp_path, text)
    assert main(["run", str(scene), "-q"]) == 0  # FAIL prints, returns 0 without --strict
    out = capsys.readouterr()
    assert "gap          homogenized sigma_xy per step" in out.out
    assert len([ln for ln in out.out.splitlines() if ln.strip().startswith(("1 ", "5 "))]) == 2
    assert "- FAIL within 1e-09" in out.out and "FAILED its tolerance" in out.err
    assert main(["run", str(scene), "-q", "--strict"]) == 5
    capsys.readouterr()
    text = SCENE.replace("[compare.cpfe]\n", "[compare.cpfe]\ntolerance = 0.5\n")
    assert main(["run", str(_write(tmp_path, text)), "-q", "--strict"]) == 0
    assert "- PASS within 0.5" in capsys.readouterr().out


def _data(text: str = SCENE) -> dict:
    return tomllib.loads(text)


def _with(edit, text: str = SCENE) -> dict:
    d = _data(text)
    edit(d)
    return d


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d["compare"]["cpfe"].update(integraton="full"),
         r"unknown scene key 'compare.cpfe.integraton'; did you mean 'integration'\?"),
        (lambda d: d["compare"].update(cpef=True),
         r"unknown scene key 'compare.cpef'; did you mean 'cpfe'\?"),
        (lambda d: d["compare"].update(cpfe="yes"),
         r"compare.cpfe must be true or a table, got str 'yes'"),
        (lambda d: d["compare"]["cpfe"].update(integration=2),
         r"compare.cpfe.integration must be one of \['fbar', 'full'\], got 2"),
        (lambda d: d["compare"]["cpfe"].update(method="picard"),
         r"compare.cpfe.method must be one of .*got 'picard'"),
        (lambda d: d["compare"]["cpfe"].update(tolerance=-0.1),
         r"compare.cpfe.tolerance must be > 0, got -0.1"),
        (lambda d: d["compare"]["cpfe"].update(tolerance="5%"),
         r"compare.cpfe.tolerance must be a number, got str '5%'"),
        (lambda d: d["compare"]["cpfe"].update(output=3),
         r"compare.cpfe.output must be a path string, got 3"),
        (lambda d: d["compare"]["cpfe"].update(component="zz"),
         r"compare.cpfe.component must be two of the axes 'xy'"),
        (lambda d: d["geometry"].update(holes=[{"center": [0.5, 0.5], "radius": 0.1}]),
         r"compare.cpfe needs a complete 2D or 3D pixel grid .*got points without a lattice"),
        (lambda d: d["dirichlet"][0].update(set="x-") or d["dirichlet"].append(
            {"box": [[0.85, -1.0], [2.0, 2.0]], "velocity_gradient": [[0.0, 0.002], [0.002, 0.0]]}),
         r"compare.cpfe resolves dirichlet\[1\] on the element nodes by its set name"),
        (lambda d: d["solver"].update(kind="explicit"),
         r"compare.cpfe compares quasi-static crystal-plasticity load steps"),
    ],
)  # fmt: skip
def test_compare_errors_name_the_key(edit, match):
    with pytest.raises(SceneError, match=match):
        scene_from_dict(_with(edit))


def test_compare_refuses_linear_and_non_cp_scenes():
    lin = _data()
    lin["material"] = {"E": 1.0, "nu": 0.25}
    del lin["solver"]
    with pytest.raises(SceneError, match=r"compare.cpfe compares crystal-plasticity load "
                       r"steps: the scene is linear"):  # fmt: skip
        scene_from_dict(lin)
    lin["solver"] = {"nonlinear": "newton", "steps": 2}  # elastic correspondence, load-stepped
    with pytest.raises(SceneError, match=r"compare.cpfe needs material.type = "
                       r"'crystal-plasticity' .*got "):  # fmt: skip
        scene_from_dict(lin)


def test_compare_outputs_checked_before_the_solve(tmp_path, capsys):
    text = SCENE.replace("[compare.cpfe]\n", '[compare.cpfe]\noutput = "fe.vtk"\n')
    assert main(["run", str(_write(tmp_path, text)), "-q"]) == 2
    err = capsys.readouterr().err
    assert "compare.cpfe.output" in err and "fe.vtk" in err
    assert not (tmp_path / "sc_homogenized.csv").exists()  # refused before the CPPD run


def test_gap_summary_is_json_without_nan(capsys):
    from types import SimpleNamespace

    from pdlin.cli.compare import cpfe_summary, print_cpfe

    # CPFE sigma_xy = 0 at step 1 (no relative gap there), 10 at step 2, CPPD 9: -10 %
    hf = np.array([[[0.0, 0.0], [0.0, 0.0]], [[0.0, 10.0], [10.0, 0.0]]])
    hp = np.array([[[0.0, 0.5], [0.5, 0.0]], [[0.0, 9.0], [9.0, 0.0]]])
    fe = SimpleNamespace(
        homogenized_stress=hf, iterations=np.array([1, 2]), cutbacks=np.array([0, 0]),
        timings={"setup": 0.1, "total": 0.5}, times=np.array([1.0, 2.0]),
    )  # fmt: skip
    cppd = SimpleNamespace(homogenized_stress=hp)
    cfg = {"integration": "fbar", "method": "auto", "component": None, "tolerance": 0.05}
    scene = SimpleNamespace(compare={"cpfe": cfg})
    s = cpfe_summary(scene, cppd, fe, Path("a.pvd"), Path("a.csv"))
    text = json.dumps(s, allow_nan=False)  # strict JSON
    assert s["component"] == "xy" and s["gap"]["relative"] == [None, -0.1]
    assert s["max_relative_gap"] == pytest.approx(0.1) and s["passed"] is False
    assert json.loads(text)["gap"]["difference"] == [0.5, -1.0]
    print_cpfe(s)
    out = capsys.readouterr().out
    assert "CPPD below CPFE at 1 of 1 step(s)" in out and "- FAIL within 0.05" in out


def test_ghost_layer_scene_compares_on_its_real_pixels(tmp_path, capsys):
    # the gallery's single crystal (10 x 10 pixels + one ghost ring), 5 steps: the ghosts and
    # their 'ghost' condition are dropped for the elements; a homogeneous path, so both
    # discretizations give the material point (docs/crystal_plasticity.md)
    from pdlin.constitutive import material_point
    from pdlin.scene.compare import cpfe_problem
    from pdlin.scene.scene import builtin_scene

    text = builtin_scene("cp_single_crystal")[1]
    text = text[: text.index("[[check]]")]  # its checks are of 30 steps
    text = text.replace("steps = 30", "steps = 5").replace("t_end = 30.0", "t_end = 5.0")
    text += "\n[compare.cpfe]\ntolerance = 1e-10\n"
    scene = _write(tmp_path, text)
    assert main(["run", str(scene), "--json", "-q", "-o", str(tmp_path / "r.pvd")]) == 0
    summary = json.loads(capsys.readouterr().out)
    sc = load_scene(scene)
    prob = cpfe_problem(sc)
    assert sc.problem.cloud.n == 144 and prob.cloud.n == 100  # 44 ghosts dropped
    assert [bc.where for bc in prob.dirichlet] == ["boundary"]
    ref = crystal_plasticity_fem(prob, **cpfe_keywords(sc))
    got = np.array(summary["cpfe"]["homogenized_stress"])
    np.testing.assert_allclose(got, ref.homogenized_stress, rtol=1e-12, atol=1e-12)
    mp = material_point(sc.problem.model.material, "shear", steps=5)
    np.testing.assert_allclose(got, mp.stress[:, 0], rtol=0, atol=1e-10 * np.abs(got).max())
    assert summary["cpfe"]["passed"] and summary["cpfe"]["max_relative_gap"] < 1e-10


def test_ghost_layers_refused_without_the_real_grid():
    from pdlin.scene.compare import compare_options

    d = _data()
    d["geometry"]["ghost_layers"] = 1
    del d["compare"]
    sc = scene_from_dict(d)
    with pytest.raises(SceneError, match=r"remove geometry.ghost_layers \(the scene has 24 ghost"):
        compare_options({"cpfe": True}, sc.problem, sc.nonlinear, 25, Path("."))


def test_tradeoff_cpfe_reference_uses_the_compare_table_and_real_pixels():
    from pdlin.scene.scene import builtin_scene
    from pdlin.scene.tradeoff import tradeoff_from_dict

    # the ghost-layer single crystal: before, the comparator refused its cloud (ghosts); now
    # it runs on the 10 x 10 real pixels and both give the material point (error ~1e-13)
    data, _ = builtin_scene("cp_single_crystal")
    data.pop("check")
    data["solver"].update(steps=3, t_end=3.0)
    data["tradeoff"] = {"reference": "cpfe", "sweep": {"method": ["newton"]}}
    (row,) = tradeoff_from_dict(data).run(memory="none").table
    assert row["status"] == "ok" and row["error"] < 1e-10
    # a [compare.cpfe] table sets the comparator's integration rule: full integration is
    # stiffer than F-bar on a polycrystal, so the error against it differs
    poly = _data(POLY)
    poly["solver"].update(steps=3, t_end=3.0)
    errs = []
    for rule in ("fbar", "full"):
        poly["compare"] = {"cpfe": {"integration": rule}}
        poly["tradeoff"] = {"reference": "cpfe", "sweep": {"method": ["newton"]}}
        (row,) = tradeoff_from_dict(poly).run(memory="none").table
        errs.append(row["error"])
    assert errs[0] != pytest.approx(errs[1], rel=1e-3)
