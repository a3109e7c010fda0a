"""Hostile input: scene files (keys, TOML types, paths, sets, BCs) and the ``pdlin`` CLI."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
from hostile_util import NAN

from pdlin.cli.main import main
from pdlin.errors import SceneError
from pdlin.scene.scene import scene_from_dict

BASE = {
    "geometry": {"type": "grid", "shape": [8, 4], "spacing": 0.1},
    "material": {"E": 1.0},
    "horizon": {"ratio": 3.015},
    "dirichlet": [{"set": "x-", "value": 0.0}],
    "load": [{"type": "total", "set": "x+", "force": [1e-3, 0.0]}],
}
DEL = object()


def _scene(path: str, value: object) -> dict:
    data = copy.deepcopy(BASE)
    *parents, last = path.split(".")
    t: object = data
    for k in parents:
        t = t[int(k)] if isinstance(t, list) else t[k]  # type: ignore[index]
    key: object = int(last) if isinstance(t, list) else last
    if value is DEL:
        del t[key]  # type: ignore[index, attr-defined]
    else:
        t[key] = value  # type: ignore[index]
    return data


# (scene key, value or DEL, message regex naming the key and what was received)
SCENE_CASES = [
    ("geometry", DEL, r"missing scene key scene.geometry"),
    ("horizon", DEL, r"missing scene key scene.horizon"),
    ("geometry.shape", DEL, r"missing scene key geometry.shape"),
    ("geometry", [1, 2], r"geometry must be a table, got list"),
    ("geometry.shape", "8", r"geometry.shape must be an integer or a list of integers, got '8'"),
    ("geometry.shape", [8.5, 4], r"shape\[0\] must be an integer, got 8.5"),
    ("geometry.shape", [0, 4], r"shape entries must be >= 1, got \(0, 4\)"),
    ("geometry.spacing", "0.1", r"geometry.spacing must be a number, got str '0.1'"),
    (
        "geometry.spacing",
        [0.1, 0.1, 0.1],
        r"spacing must be a scalar or have shape \(2,\), got \(3,\)",
    ),
    ("geometry.spacing", NAN, r"spacing must be finite, got nan"),
    ("geometry.thickness", "thick", r"geometry.thickness must be a number, got str 'thick'"),
    ("geometry.thickness", -1.0, r"geometry.thickness must be > 0, got -1.0"),
    ("geometry.typ", "grid", r"unknown scene key 'geometry.typ'; did you mean 'type'\?"),
    (
        "geometry.type",
        "sphere",
        r"geometry.type must be one of \['grid', 'image', 'mesh'\], got 'sphere'",
    ),
    (
        "geometry",
        {"type": "mesh", "path": "nonexistent.msh"},
        r"geometry.path: file not found: .*nonexistent.msh",
    ),
    ("geometry", {"type": "mesh", "path": 3}, r"geometry.path must be a path string, got 3"),
    (
        "geometry",
        {"type": "image", "data": [[1, "a"]]},
        r"image must hold integer phase ids, got dtype <U",
    ),
    ("geometry", {"type": "image", "path": "nonexistent.npy"}, r"geometry.path: file not found"),
    ("material", 3, r"material must be a table, got int"),
    (
        "material.E",
        "steel",
        r"material.E must be a number or a table of per-phase numbers, got 'steel'",
    ),
    ("material.E", NAN, r"E must be finite, got nan"),
    ("material.E", -1.0, r"E must be > 0, got min -1.0"),
    ("material.E", {"1": 1.0}, r"material.E has no value for phase\(s\) \[0\]"),
    ("material.E", {"x": 1.0}, r"material.E table must map integer phase ids to numbers"),
    ("material.nu", "0.3", r"material.nu must be a number .* got '0.3'"),
    ("material.Ee", 1.0, r"unknown scene key 'material.Ee'; did you mean 'E'\?"),
    (
        "material.type",
        "plastic",
        r"material.type must be 'elastic' or 'crystal-plasticity', got 'plastic'",
    ),
    ("material.plane", "strain2", r"plane must be 'stress' or 'strain', got 'strain2'"),
    ("model", {"type": "peridigm"}, r"model.type must be one of .* got 'peridigm'"),
    ("model", {"type": "lps"}, r"model.type = 'lps' needs two isotropic constants .* got \['E'\]"),
    ("model", {"type": "lps", "nu_mismatch": "warn"}, r"unknown scene key 'model.nu_mismatch'"),
    (
        "model",
        {"type": "bond_based", "average": 3},
        r"average must be 'arithmetic' or 'harmonic', got 3",
    ),
    ("horizon", {}, r"horizon needs exactly one of 'value' or 'ratio', got none"),
    (
        "horizon",
        {"value": 0.3, "ratio": 3},
        r"horizon needs exactly one of 'value' or 'ratio', got \['value', 'ratio'\]",
    ),
    ("horizon.ratio", "three", r"horizon.ratio must be a number, got str 'three'"),
    ("horizon.ratio", -3.0, r"horizon.ratio must be > 0, got -3.0"),
    ("horizon", {"value": NAN}, r"horizon.value must be > 0, got nan"),
    ("horizon", {"value": -0.3}, r"horizon.value must be > 0, got -0.3"),
    ("horizon.shape", "cubic", r"horizon.shape must be one of .* got 'cubic'"),
    ("horizon.influence", "gauss", r"horizon.influence must be one of .* got 'gauss'"),
    ("horizon.ratoi", 3, r"unknown scene key 'horizon.ratoi'; did you mean 'ratio'\?"),
    (
        "dirichlet",
        {"set": "x-"},
        r"dirichlet must be an array of tables \(\[\[dirichlet\]\]\), got dict",
    ),
    ("dirichlet", [3], r"dirichlet\[0\] must be a table, got int"),
    ("dirichlet.0.set", "left", r"dirichlet\[0\].set: unknown point set 'left'"),
    (
        "dirichlet.0.set",
        DEL,
        r"dirichlet\[0\] needs exactly one of 'set', 'box', 'points', got none",
    ),
    ("dirichlet.0.value", "zero", r"dirichlet\[0\]: value must be numeric, got str"),
    ("dirichlet.0.value", NAN, r"dirichlet\[0\]: value must be finite, got nan"),
    (
        "dirichlet.0.value",
        [0, 0, 0],
        r"dirichlet\[0\].value must be a scalar or have shape .* got \(3,\)",
    ),
    (
        "dirichlet.0.components",
        "w",
        r"dirichlet\[0\]: components must be letters from 'xyz', got 'w'",
    ),
    (
        "dirichlet.0.components",
        5,
        r"dirichlet\[0\]: components must be distinct axes in \[0, 2\], got 5",
    ),
    ("dirichlet.0.valeu", 0, r"unknown scene key 'dirichlet\[0\].valeu'; did you mean 'value'\?"),
    (
        "dirichlet",
        [{"points": [1000]}],
        r"dirichlet\[0\].points must hold indices in \[0, 31\], got range \[1000, 1000\]",
    ),
    (
        "dirichlet",
        [{"points": ["a"]}],
        r"dirichlet\[0\].points must be a non-empty list of point indices, got \['a'\]",
    ),
    ("dirichlet", [{"points": []}], r"dirichlet\[0\].points must be a non-empty list .* got \[\]"),
    (
        "dirichlet",
        [{"set": "x-", "value": 0.0}, {"set": "x-", "value": 1.0}],
        r"dirichlet conditions conflict: dof 0",
    ),
    ("dirichlet", [{"box": [[-1, -1], [-0.5, -0.5]]}], r"dirichlet\[0\].box selects no points"),
    (
        "dirichlet",
        [{"box": [[0], [1]]}],
        r"dirichlet\[0\].box must be \[\[lower...\], \[upper...\]\]",
    ),
    ("dirichlet.0.F", [[1, 0], [0, 1]], r"dirichlet\[0\] takes 'value' or 'F', not both"),
    ("load.0.type", "pressure", r"load\[0\].type must be 'total' or 'body', got 'pressure'"),
    ("load.0.force", DEL, r"missing scene key load\[0\].force"),
    ("load.0.force", [NAN, 0], r"load\[0\].force: force must be finite, got nan at index 0"),
    ("load.0.force", "big", r"load\[0\].force: force must be numeric, got str"),
    ("load.0.force", [1, 2, 3], r"load\[0\].force must have shape \(2,\), got \(3,\)"),
    ("load.0.set", "right", r"load\[0\].set: unknown point set 'right'"),
    (
        "load",
        [{"type": "body", "set": "all", "density": [float("inf"), 0]}],
        r"load\[0\].density: density must be finite, got inf",
    ),
    (
        "load",
        [{"type": "total", "box": [[10, 10], [11, 11]], "force": [1, 0]}],
        r"load\[0\].box selects no points",
    ),
    ("solver", {"name": "lu"}, r"solver.name must be one of .* got 'lu'"),
    ("solver", {"rtol": -1.0}, r"solver.rtol must be a number in \(0, 1\), got -1.0"),
    ("solver", {"rtol": "tight"}, r"solver.rtol must be a number, got str 'tight'"),
    ("solver", {"maxiter": "ten"}, r"solver.maxiter must be an integer >= 1, got 'ten'"),
    ("solver", {"maxiter": 2.5}, r"solver.maxiter must be an integer >= 1, got 2.5"),
    ("solver", {"steps": 3}, r"solver.steps needs a nonlinear solve"),
    ("solver", {"nonlinear": "bfgs"}, r"solver.nonlinear must be one of .* got 'bfgs'"),
    ("solver", {"nonlinear": "adr", "damping": -1.0}, r"solver.damping must be >= 0, got -1.0"),
    (
        "solver",
        {"nonlinear": "newton", "steps": "3"},
        r"solver.steps must be an integer >= 1, got '3'",
    ),
    (
        "solver",
        {"nonlinear": "newton", "relax": -5},
        r"solver.relax must be an integer >= 0, got -5",
    ),
    (
        "solver",
        {"nonlinear": "auto", "fallback_cutbacks": 1.5},
        r"solver.fallback_cutbacks must be an integer >= 0, got 1.5",
    ),
    (
        "solver",
        {"nonlinear": "auto", "newton_backoff": "yes"},
        r"solver.newton_backoff must be true or false, got 'yes'",
    ),
    (
        "solver",
        {"nonlinear": "auto", "polish": 1},
        r"solver.polish must be true or false, got 1",
    ),
    (
        "solver",
        {"nonlinear": "auto", "adr_stall": 0},
        r"solver.adr_stall must be an integer >= 1, got 0",
    ),
    (
        "solver",
        {"nonlinear": "adr", "progress_every": -5},
        r"solver.progress_every must be seconds >= 0, got -5.0",
    ),
    (
        "solver",
        {"nonlinear": "adr", "progress_every": "often"},
        r"solver.progress_every must be a number, got str 'often'",
    ),
    (
        "solver",
        {"nonlinear": "adr", "snapshot_every": -1},
        r"solver.snapshot_every must be seconds >= 0, got -1.0",
    ),
    (
        "solver",
        {"nonlinear": "newton", "checkpoint": 3},
        r"solver.checkpoint must be a path string, got 3",
    ),
    (
        "solver",
        {"nonlinear": "adr", "density": "x"},
        r"solver.density must be 'gershgorin' or a number > 0, got 'x'",
    ),
    ("solver", {"nonlinear": "adr", "e_l": -1.0}, r"solver.e_l must be > 0, got -1.0"),
    ("output", {"path": 3}, r"output.path must be a path string, got 3"),
    ("output", {"fields": "u"}, r"output.fields must be a list of field names, got 'u'"),
    ("output", {"homogenized": "h.csv"}, r"output.homogenized needs a nonlinear solve"),
    ("output", {"pathh": "x"}, r"unknown scene key 'output.pathh'; did you mean 'path'\?"),
    ("symmetry", [{"axis": 5}], r"axis must be 0, 1, 2 or one of 'x', 'y', 'z', got 5"),
    (
        "symmetry",
        [{"axis": 0, "position": "x"}],
        r"symmetry\[0\].position must be a number, got str 'x'",
    ),
    ("shadow", {"F": [[1, 0], [0, 1]], "depth": -1.0}, r"depth must be > 0, got -1.0"),
    ("shadow", {"depth": 0.2}, r"missing scene key shadow.F"),
    # geometric selectors (issue 31): non-finite numbers named, empty selections refused;
    # the 8 x 4 grid of spacing 0.1 spans [0.05, 0.75] x [0.05, 0.35]
    (
        "geometry.holes",
        [{"center": [5.0, 0.5], "radius": 0.1}],
        r"geometry.holes\[0\] \(circle at \(5, 0.5\), radius 0.1\) removes no points of the "
        r"grid \(points span \[0.05, 0.05\] to \[0.75, 0.35\]\)",
    ),
    (
        "geometry.holes",
        [{"center": [0.4, 0.2], "radius": 0.1}, {"center": [0.4, 2.0], "radius": 0.1}],
        r"geometry.holes\[1\] \(circle at \(0.4, 2\), radius 0.1\) removes no points",
    ),
    (
        "geometry.holes",
        [{"center": [NAN, 0.2], "radius": 0.1}],
        r"geometry.holes\[0\].center\[0\] must be finite, got nan",
    ),
    (
        "geometry.holes",
        [{"center": [0.4, float("inf")], "radius": 0.1}],
        r"geometry.holes\[0\].center\[1\] must be finite, got inf",
    ),
    (
        "symmetry",
        [{"axis": "y", "position": NAN}],
        r"symmetry\[0\].position must be finite, got nan",
    ),
    (
        "load",
        [{"type": "total", "box": [[NAN, 0.0], [1.0, 1.0]], "force": [1.0, 0.0]}],
        r"load\[0\].box must be \[\[lower...\], \[upper...\]\]: box lower corner must hold "
        r"numbers \(-inf / inf for open sides\), got nan at index 0",
    ),
    (
        "dirichlet",
        [{"box": [[0.5, 0.0], [0.1, 1.0]]}],
        r"dirichlet\[0\].box .*: box lower corner must not exceed the upper one",
    ),
    (
        "dirichlet",
        [{"box": [[-1, -1], [-0.5, -0.5]]}],
        r"dirichlet\[0\].box selects no points: \[\[-1, -1\], \[-0.5, -0.5\]\], points span "
        r"\[0.05, 0.05\] to \[0.75, 0.35\]",
    ),
    (
        "horizon",
        {"ratio": 3.015, "cracks": [[[NAN, 0.0], [0.2, 0.5]]]},
        r"horizon.cracks must be finite, got nan at index \(0, 0, 0\)",
    ),
    ("name", 3, r"name must be a string, got 3"),
    ("nmae", "x", r"unknown scene key 'nmae'; did you mean 'name'\?"),
]


@pytest.mark.parametrize(
    ("key", "value", "pattern"),
    SCENE_CASES,
    ids=[f"{k}={'DEL' if v is DEL else v!r}" for k, v, _ in SCENE_CASES],
)
def test_scene_rejects(tmp_path, key, value, pattern):
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(_scene(key, value), tmp_path)


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


GOOD = """
[geometry]
shape = [8, 4]
spacing = 0.1
[material]
E = 1.0
[horizon]
ratio = 3.015
[[dirichlet]]
set = "x-"
[[load]]
set = "x+"
force = [1e-3, 0.0]
"""

# (argv tail, scene text or None, expected stderr regex); exit code 2 = bad input
CLI_CASES = [
    (
        "run-missing-file",
        ["run", "{dir}/nope.toml"],
        None,
        r"pdlin: error: scene file not found: .*nope.toml",
    ),
    (
        "run-bad-toml",
        ["run", "{scene}"],
        "[geometry\nshape = ",
        r"pdlin: error: .*s.toml: invalid TOML",
    ),
    (
        "run-misspelled",
        ["run", "{scene}"],
        GOOD.replace("ratio", "ratoi"),
        r"unknown scene key 'horizon.ratoi'; did you mean 'ratio'\?",
    ),
    (
        "run-floating",
        ["run", "{scene}", "-q"],
        GOOD.replace('[[dirichlet]]\nset = "x-"\n', ""),
        r"pdlin: error: the body is floating",
    ),
    (
        "run-bad-solver",
        ["run", "{scene}", "-q", "--solver", "lu"],
        GOOD,
        r"pdlin: error: solver must be one of .* got 'lu'",
    ),
    ("run-no-scene", ["run"], None, r"pdlin: error: give a scene file or --example NAME"),
    ("run-unknown-example", ["run", "--example", "nope"], None, r"unknown built-in scene 'nope'"),
    (
        "run-bad-field",
        ["run", "{scene}", "-q", "-o", "{dir}/r.vtu"],
        GOOD + '[output]\nfields = ["nope"]\n',
        r"output.fields: unknown field\(s\) \['nope'\]",
    ),
    (
        "info-missing-mesh",
        ["info", "{dir}/nope.msh"],
        None,
        r"pdlin: error: mesh file .*nope.msh' does not exist",
    ),
    (
        "info-bad-horizon",
        ["info", "{scene}"],
        GOOD.replace("3.015", "-1.0"),
        r"pdlin: error: horizon.ratio must be > 0, got -1.0",
    ),
    (
        "sparsity-bad-scene",
        ["sparsity", "{scene}"],
        GOOD.replace("E = 1.0", 'E = "steel"'),
        r"material.E must be a number .* got 'steel'",
    ),
    (
        "export-bad-ext",
        ["export", "{scene}", "-o", "{dir}/K.txt"],
        GOOD,
        r"-o/--output must end with one of \('.mtx', '.npz'\)",  # checked before assembly
    ),
    (
        "calibrate-missing",
        ["calibrate", "{dir}/nope.toml"],
        None,
        r"pdlin: error: .*file not found: .*nope.toml",
    ),
    ("examples-unknown", ["examples", "--show", "nope"], None, r"unknown built-in scene 'nope'"),
    (
        "run-hole-removes-nothing",
        ["run", "{scene}", "-q"],
        GOOD.replace(
            "spacing = 0.1\n", "spacing = 0.1\nholes = [{center = [5.0, 0.5], radius = 0.1}]\n"
        ),
        r"pdlin: error: geometry.holes\[0\] \(circle at \(5, 0.5\), radius 0.1\) removes no points",
    ),
    (
        # the grid spans y in [0, 0.4]: a plane at y = -5 is beyond the coupling reach
        "run-symmetry-plane-outside",
        ["run", "{scene}", "-q"],
        GOOD + '[[symmetry]]\naxis = "y"\nposition = -5.0\n',
        r"pdlin: error: symmetry plane y = -5 is farther than the reach .* couples nothing",
    ),
    (
        "run-crack-cuts-nothing",
        ["run", "{scene}", "-q"],
        GOOD.replace("ratio = 3.015\n", "ratio = 3.015\ncracks = [[[5.0, 5.0], [6.0, 6.0]]]\n"),
        r"pdlin: error: cracks\[0\] \(segment \(5, 5\) - \(6, 6\)\) cuts no bond",
    ),
    (
        # the load sits on the clamped face: it would vanish into the support (issue 31)
        "run-load-on-support",
        ["run", "{scene}", "-q"],
        GOOD.replace('set = "x+"', 'set = "x-"'),
        r"pdlin: error: invalid scene: load\[0\] \(TotalForce on set 'x-'\) acts only on "
        r"prescribed DOFs",
    ),
]


@pytest.mark.parametrize(
    ("argv", "text", "pattern"), [c[1:] for c in CLI_CASES], ids=[c[0] for c in CLI_CASES]
)
def test_cli_reports_one_line(tmp_path, capsys, argv, text, pattern):
    scene = _write(tmp_path, text) if text is not None else tmp_path / "s.toml"
    args = [a.format(dir=tmp_path, scene=scene) for a in argv]
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.startswith("pdlin:")]
    assert len(lines) == 1, err
    assert __import__("re").search(pattern, lines[0]), lines[0]
    # no partial output is left next to the scene
    assert not list(tmp_path.glob("*.vtu")) and not list(tmp_path.glob("*.mtx"))


def test_check_box_refuses_nan_and_inverted_corners():
    import pdlin
    from pdlin.scene.checks import Check, _region

    cloud = pdlin.grid((8, 4), 0.1)

    def check(box):
        return Check("value", "displacement", "test", 0.1, {"box": box}, "check[0]")

    with pytest.raises(SceneError, match=r"check\[0\].box: box lower corner must hold numbers"):
        _region(check([[NAN, 0.0], [1.0, 1.0]]), cloud)
    with pytest.raises(SceneError, match=r"check\[0\].box: box lower corner must not exceed"):
        _region(check([[0.5, 0.0], [0.1, 1.0]]), cloud)
    with pytest.raises(SceneError, match=r"check\[0\].box selects no points"):
        _region(check([[5.0, 5.0], [6.0, 6.0]]), cloud)


def test_tradeoff_measure_box_refuses_nan():
    from pdlin.scene.tradeoff import tradeoff_from_dict

    data = copy.deepcopy(BASE)
    data["tradeoff"] = {"sweep": {"m": [2.0]}, "measure": [[NAN, 0.0], [1.0, 1.0]]}
    with pytest.raises(SceneError, match=r"tradeoff.measure must hold numbers \(-inf / inf"):
        tradeoff_from_dict(data)
    data["tradeoff"]["measure"] = [[0.5, 0.0], [0.1, 1.0]]
    sweep = tradeoff_from_dict(data)
    with pytest.raises(SceneError, match=r"tradeoff.measure: box lower corner must not exceed"):
        sweep.factory(m=2.0)


#: BASE as a scene file
_BASE_TOML = """
[geometry]
type = "grid"
shape = [8, 4]
spacing = 0.1
[material]
E = 1.0
[horizon]
ratio = 3.015
[[dirichlet]]
set = "x-"
value = 0.0
[[load]]
type = "total"
set = "x+"
force = [1e-3, 0.0]
"""


@pytest.mark.parametrize(
    "edit, text, pattern",
    [
        # main: the solve ran, then 'output.fields: unknown field(s)' at the write
        (
            {"output": {"fields": ["displacement", "bogus"]}},
            '[output]\nfields = ["displacement", "bogus"]\n',
            r"output.fields: unknown .*'bogus'",
        ),
        # main: ignored silently (a damage run writes displacement and damage)
        (
            {"output": {"fields": ["stress"]}, "damage": {"critical_stretch": 0.1}},
            '[output]\nfields = ["stress"]\n[damage]\ncritical_stretch = 0.1\n',
            r"output.fields .*static",
        ),
    ],
)
def test_output_fields_are_checked_before_the_work(tmp_path, capsys, edit, text, pattern):
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict({**copy.deepcopy(BASE), **edit}, tmp_path)
    path = _write(tmp_path, _BASE_TOML + text)
    assert main(["run", str(path), "-o", str(tmp_path / "r.vtu")]) == 2
    err = capsys.readouterr().err
    assert "solve" not in err and "load step" not in err, err  # refused before the work
    assert not (tmp_path / "r.vtu").exists()


def test_known_output_fields_are_written(tmp_path):
    text = '[output]\nfields = ["displacement", "stress"]\n'
    path = _write(tmp_path, _BASE_TOML + text)
    assert main(["run", str(path), "-q", "-o", str(tmp_path / "r.npz")]) == 0
    import numpy as np

    with np.load(tmp_path / "r.npz") as f:
        assert {"displacement", "stress"} <= set(f.files), f.files


_CHECK = '[[check]]\nkind = "value"\nexpected = 1.0\ntolerance = 0.1\nsource = "test"\n'


@pytest.mark.parametrize(
    "text, pattern",
    [
        # main: both found by 'checking 1 reference(s)' after the solve and the write
        (
            _CHECK + 'quantity = "displacement_x"\nbox = [[5.0, 5.0], [6.0, 6.0]]\n',
            r"box selects no",
        ),
        (_CHECK + 'quantity = "damage"\n', r"'damage' needs a damage run"),
        (_CHECK + 'quantity = "homogenized_stress_xy"\n', r"needs a nonlinear run"),
        (_CHECK + 'quantity = "displacement_x"\nstep = 2\n', r"step needs a load-stepped"),
    ],
)
def test_checks_that_cannot_apply_are_refused_before_the_work(tmp_path, capsys, text, pattern):
    path = _write(tmp_path, _BASE_TOML + text)
    assert main(["run", str(path), "-o", str(tmp_path / "r.vtu")]) == 2
    err = capsys.readouterr().err
    import re

    assert re.search(pattern, err.splitlines()[-1]), err
    assert "solve" not in err and "writing" not in err, err  # refused before the work
    assert not (tmp_path / "r.vtu").exists()


@pytest.mark.parametrize("example", ["damage_plate", "bar"])
def test_resume_of_a_run_without_checkpoints_is_refused_before_the_work(tmp_path, capsys, example):
    """--resume on a damage or static scene (no checkpoints): one error line, no run (main:
    a damage run ignored --resume silently and ran from the start)."""
    out = tmp_path / "r.vtu"
    assert main(["run", "--example", example, "--resume", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1].startswith("pdlin: error: --resume needs a nonlinear scene"), err
    assert "load step" not in err and "memory estimate" not in err, err
    assert not out.exists()
