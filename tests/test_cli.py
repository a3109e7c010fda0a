"""The pdlin command and scene files."""

from __future__ import annotations

import json
from pathlib import Path

import meshio
import numpy as np
import pytest

import pdlin
from pdlin.cli.main import main
from pdlin.errors import SceneError
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
    assert mesh.point_data["displacement"].shape == (300, 3)
    # the file holds the solution of the same problem solved through the API
    res = pdlin.solve(load_scene(scene).problem, solver="direct")
    np.testing.assert_allclose(mesh.point_data["displacement"][:, :2], res.u, rtol=1e-10)
    np.testing.assert_allclose(mesh.point_data["reaction"][:, 0].sum(), -1000.0, rtol=1e-8)


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
