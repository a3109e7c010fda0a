"""Scenes of explicit dynamics: ``[solver] kind = "explicit"`` and ``pdlin run``."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from pdlin.cli.main import main
from pdlin.dynamics import solve_explicit
from pdlin.errors import SceneError
from pdlin.scene.checks import evaluate_checks
from pdlin.scene.scene import builtin_scene, scene_from_dict


def _data(**edits):
    data = copy.deepcopy(builtin_scene("impact_bar")[0])
    data["check"] = []
    for table, values in edits.items():
        data.setdefault(table, {}).update(values)
    return data


def _checks(data):
    sc = scene_from_dict(data)
    res = solve_explicit(sc.problem, **sc.explicit)
    return evaluate_checks(sc.checks, sc, res)


def test_explicit_scene_options():
    sc = scene_from_dict(_data(solver={"safety": 0.5, "time_step": "lanczos"}))
    assert sc.explicit == {
        "t_end": 1e-4,
        "density": 8000.0,
        "dt": 8e-7,
        "safety": 0.5,
        "time_step": "lanczos",
        "output_every": 5,
    }
    assert sc.nonlinear is None and sc.damage is None


def test_impact_bar_checks_fail_with_a_wrong_density():
    data = copy.deepcopy(builtin_scene("impact_bar")[0])
    assert all(r.passed for r in _checks(data))
    data["material"]["density"] = 1.04 * 8000.0  # 2 % slower wave: u off by 1.6 %
    first = _checks(data)[0]
    assert not first.passed and first.error > 0.01


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        ({"solver": {"kind": "implicit"}}, "solver.kind must be 'static' or 'explicit'"),
        ({"solver": {"name": "direct"}}, "solver.name is not used by"),
        ({"solver": {"density": 1.0}}, "the mass density is material.density"),
        ({"solver": {"safety": 2.0}}, "solver.safety must be a number in"),
        ({"solver": {"time_step": "cfl"}}, "solver.time_step must be one of"),
        ({"solver": {"kinematics": "big"}}, "solver.kinematics must be"),
        ({"solver": {"output_every": 0}}, "solver.output_every"),
        ({"damage": {"steps": 3}}, "damage.steps is not used"),
        ({"output": {"fields": ["strain"]}}, "output.fields is not used"),
    ],
)
def test_explicit_scene_keys_are_checked(edit, message):
    with pytest.raises(SceneError, match=message):
        scene_from_dict(_data(**edit))


def test_density_and_t_end_are_required_and_static_scenes_refuse_explicit_keys():
    data = _data()
    del data["material"]["density"]
    with pytest.raises(SceneError, match="material.density is required"):
        scene_from_dict(data)
    data = _data()
    del data["solver"]["t_end"]
    with pytest.raises(SceneError, match="t_end"):
        scene_from_dict(data)
    data = _data()
    data["solver"] = {"safety": 0.5}
    with pytest.raises(SceneError, match="solver.safety needs \\[solver\\] kind = 'explicit'"):
        scene_from_dict(data)
    data = _data()
    data["dirichlet"][0]["value"] = 0.0
    with pytest.raises(SceneError, match="takes 'velocity' or 'value'"):
        scene_from_dict(data)


def test_damage_table_gives_the_critical_stretch():
    sc = scene_from_dict(_data(damage={"critical_stretch": 1e-3}))
    assert sc.explicit["critical_stretch"] == 1e-3


def test_pdlin_run_writes_the_series_and_resumes(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    text = builtin_scene("impact_bar")[1].replace(
        "output_every = 5", 'output_every = 5\ncheckpoint = "ck.npz"\ncheckpoint_every = 50'
    )
    (tmp_path / "bar.toml").write_text(text)
    assert main(["run", "bar.toml", "-q", "--json", "--strict", "-o", "a.npz"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["steps"] == 125 and all(c["passed"] for c in first["checks"])
    assert (tmp_path / "ck.npz").exists()
    a = np.load(tmp_path / "a.npz")
    assert a["displacement"].shape == (26, 400, 1) and a["times"][-1] == pytest.approx(1e-4)
    # a longer run resumed from the checkpoint of step 125
    longer = text.replace("t_end = 1.0e-4", "t_end = 1.2e-4")
    (tmp_path / "bar.toml").write_text(longer)
    assert main(["run", "bar.toml", "-q", "--json", "--resume", "-o", "b.npz"]) == 0
    second = json.loads(capsys.readouterr().out)
    assert second["resumed_from"] == 125 and second["steps"] == 150
    b = np.load(tmp_path / "b.npz")
    assert np.array_equal(b["displacement"][:26], a["displacement"])


@pytest.mark.slow  # ~20 s each: 3,200 XOSB points, 260 steps
def test_kalthoff_winkler_checks_fail_with_the_printed_fracture_energy():
    data = copy.deepcopy(builtin_scene("kalthoff_winkler")[0])
    assert all(r.passed for r in _checks(data))
    # the paper's printed G0 = 222,170 J/m^2: no crack grows (its erratum)
    data["damage"]["G0"] = 222170.0
    res = _checks(data)
    assert not res[1].passed and not res[2].passed


def test_a_static_scene_checks_material_density():
    data = copy.deepcopy(builtin_scene("damage_plate")[0])
    data["material"]["density"] = -1.0
    with pytest.raises(SceneError, match="material.density must be > 0"):
        scene_from_dict(data)


def test_blocks_give_one_density_per_point():
    data = _data()
    del data["material"]
    data["materials"] = {
        "steel": {"E": 200e9, "density": 8000.0},
        "light": {"E": 200e9, "density": 2000.0},
    }
    data["block"] = [
        {"box": [[0.0], [0.5]], "material": "steel"},
        {"box": [[0.5], [1.0]], "material": "light"},
    ]
    sc = scene_from_dict(data)
    rho = sc.explicit["density"]
    x = sc.problem.cloud.points[:, 0]
    assert rho.shape == (400,) and set(rho[x < 0.5]) == {8000.0} and set(rho[x > 0.5]) == {2000.0}
    res = solve_explicit(sc.problem, **{**sc.explicit, "t_end": 2e-5})
    assert np.isfinite(res.u).all()
    del data["materials"]["light"]["density"]
    with pytest.raises(SceneError, match="materials.light.density is required"):
        scene_from_dict(data)
