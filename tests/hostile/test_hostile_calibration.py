"""Hostile input: ``pdlin.calibrate_micromoduli`` and ``pdlin calibrate TARGET.toml``.

Every case raises a specific :mod:`pdlin.errors` exception whose message names the
argument, what was expected and what was received.  An infeasible target is not an
error by default: the result has ``status == 'infeasible'``, NaN micromoduli (so
``BondBased`` refuses them), NaN ``relative_error`` and a message carrying the measured
least-squares error; ``raise_on_infeasible=True`` raises ``InputError`` instead and the
CLI exits with code 4 (docs/calibration.md, "two-step" step 3).
"""

from __future__ import annotations

import copy
import json
import re

import numpy as np
import pytest
from hostile_util import INF, NAN, expect

import pdlin
from pdlin import constitutive as cm
from pdlin.calibration import Family, design_matrix, lattice_family, max_lower_bound
from pdlin.cli.main import main
from pdlin.errors import InputError, InputTypeError, NonFiniteError, SceneError, ShapeError
from pdlin.scene.targets import calibration_from_dict

cal = pdlin.calibrate_micromoduli
C_ISO = cm.isotropic(E=1.0, nu=0.25)  # Cauchy-isotropic (nu = 1/4): reachable exactly
FAM2 = lattice_family(3, 2.0)  # 13 directions modulo sign, rank 12 (docs/calibration.md)
XI3 = np.eye(3)  # three axis bonds


def _with(C, idx, value):
    out = np.array(C, dtype=float)
    out[idx] = value
    return out


CASES = [
    # --- the target C -----------------------------------------------------------------
    (
        "C-nan",
        lambda: cal(_with(C_ISO, (0, 0), NAN), FAM2),
        NonFiniteError,
        r"C must be finite, got nan at index \(0, 0\)",
    ),
    (
        "C-inf",
        lambda: cal(_with(C_ISO, (1, 1), INF), FAM2),
        NonFiniteError,
        r"C must be finite, got inf at index \(1, 1\)",
    ),
    (
        "C-shape-5x5",
        lambda: cal(np.eye(5), FAM2),
        ShapeError,
        r"C must have shape \(6, 6\) or \(3, 3\) \(Voigt\) .* got \(5, 5\)",
    ),
    (
        "C-shape-vector",
        lambda: cal(np.ones(6), FAM2),
        ShapeError,
        r"C must have shape \(6, 6\) .* got \(6,\)",
    ),
    ("C-none", lambda: cal(None, FAM2), ShapeError, r"C must have shape \(6, 6\) .* got \(\)"),
    ("C-str", lambda: cal("steel", FAM2), InputError, r"C must be a numeric array, got str"),
    (
        # library fix: the imaginary part used to be dropped with a ComplexWarning only
        "C-complex",
        lambda: cal(C_ISO + 1e-3j, FAM2),
        InputTypeError,
        r"C must be real, got complex dtype complex128",
    ),
    (
        "C-nonsymmetric",
        lambda: cal(_with(C_ISO, (0, 1), C_ISO[0, 1] + 0.1), FAM2),
        InputError,
        r"C must be symmetric \(major symmetry C_ab = C_ba\), got max \|C - C.T\| = 0.1",
    ),
    (
        "C-not-spd",
        lambda: cal(_with(C_ISO, (3, 3), -1.0), FAM2),
        InputError,
        r"C must be positive definite, got smallest eigenvalue -2 \(Mandel form\)",
    ),
    (
        "C-zero",
        lambda: cal(np.zeros((6, 6)), FAM2),
        InputError,
        r"C must be positive definite, got smallest eigenvalue 0",
    ),
    (
        "C-2d-for-3d-family",
        lambda: cal(cm.plane_stress(C_ISO), FAM2),
        ShapeError,
        r"C is a 2D stiffness \(3, 3\) but the bond family is 3D; pass a \(6, 6\) target",
    ),
    # --- options ----------------------------------------------------------------------
    (
        "method",
        lambda: cal(C_ISO, FAM2, method="lsq"),
        InputError,
        r"method must be one of \('two-step', 'robust', 'min-norm'\), got 'lsq'",
    ),
    (
        "weighting",
        lambda: cal(C_ISO, FAM2, weighting="l2"),
        InputError,
        r"weighting must be one of \('frobenius', 'voigt'\), got 'l2'",
    ),
    (
        "qp_solver",
        lambda: cal(C_ISO, FAM2, qp_solver="gurobi"),
        InputError,
        r"qp_solver must be one of \('clarabel', 'osqp', 'cvxpy'\), got 'gurobi'",
    ),
    (
        "plane",
        lambda: cal(C_ISO, lattice_family(2, 3.0), plane="flat"),
        InputError,
        r"plane must be 'stress' or 'strain', got 'flat'",
    ),
    (
        "pair_rule",
        lambda: cal(C_ISO, FAM2, pair_rule="max"),
        InputError,
        r"pair_rule must be one of \('mean', 'owner'\), got 'max'",
    ),
    (
        "boundary",
        lambda: cal(C_ISO, FAM2, boundary="none"),
        InputError,
        r"boundary must be one of \('calibrate', 'interior-mean', 'bulk'\), got 'none'",
    ),
    (
        "lower_bound-nan",
        lambda: cal(C_ISO, FAM2, lower_bound=NAN),
        InputError,
        r"lower_bound must be finite, got nan",
    ),
    (
        "lower_bound-inf",
        lambda: cal(C_ISO, FAM2, lower_bound=INF),
        InputError,
        r"lower_bound must be finite, got inf",
    ),
    (
        # library fix: was a bare ValueError from float()
        "lower_bound-str",
        lambda: cal(C_ISO, FAM2, lower_bound="zero"),
        InputError,
        r"lower_bound must be a finite real number, got 'zero'",
    ),
    (
        # library fix: was a bare TypeError from float()
        "lower_bound-none",
        lambda: cal(C_ISO, FAM2, lower_bound=None),
        InputError,
        r"lower_bound must be a finite real number, got None",
    ),
    (
        "lower_bound-list",
        lambda: cal(C_ISO, FAM2, lower_bound=[0.0, 1.0]),
        InputError,
        r"lower_bound must be a finite real number, got \[0.0, 1.0\]",
    ),
    (
        # library fix: NaN rcond made every singular value fail the cutoff and was
        # reported as "design matrix is zero (all omega == 0?)"
        "rcond-nan",
        lambda: cal(C_ISO, FAM2, rcond=NAN),
        InputError,
        r"rcond must be finite, got nan",
    ),
    (
        # library fix: a negative cutoff kept round-off singular values and returned
        # status 'infeasible' for a reachable target
        "rcond-negative",
        lambda: cal(C_ISO, FAM2, rcond=-1.0),
        InputError,
        r"rcond must be in \[0, 1\), got -1.0",
    ),
    (
        "zero_tol-nan",
        lambda: cal(C_ISO, FAM2, zero_tol=NAN),
        InputError,
        r"zero_tol must be finite, got nan",
    ),
    (
        "zero_tol-negative",
        lambda: cal(C_ISO, FAM2, zero_tol=-1e-9),
        InputError,
        r"zero_tol must be >= 0, got -1e-09",
    ),
    (
        "raise_on_infeasible",
        lambda: cal(cm.material("monoclinic"), FAM2, raise_on_infeasible=True),
        InputError,
        r"calibration infeasible: rank 12 < 15: .* no micromoduli >= 0 reproduce the "
        r"least-squares tensor \(error [0-9.]+ %\)",
    ),
    # --- bond families ----------------------------------------------------------------
    (
        "bonds-empty-array",
        lambda: cal(C_ISO, np.zeros((0, 3))),
        InputError,
        r"xi must hold at least one bond, got an empty family \(0 bonds\)",
    ),
    (
        "bonds-empty-list",
        lambda: cal(C_ISO, []),
        ShapeError,
        r"xi must have shape \(M, dim\) with dim 2 or 3, got \(0,\)",
    ),
    (
        "bonds-nan-xi",
        lambda: cal(C_ISO, [[NAN, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        NonFiniteError,
        r"xi must be finite, got nan at index \(0, 0\)",
    ),
    (
        "bonds-zero-xi",
        lambda: cal(C_ISO, [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        InputError,
        r"xi must hold non-zero bond vectors, got a zero vector at bond 0",
    ),
    (
        "bonds-4-columns",
        lambda: cal(C_ISO, np.ones((3, 4))),
        ShapeError,
        r"xi must have shape \(M, dim\) with dim 2 or 3, got \(3, 4\)",
    ),
    (
        "bonds-str",
        lambda: cal(C_ISO, "cube"),
        InputTypeError,
        r"bonds must be a pdlin.Bonds, a calibration Family or an \(M, dim\) array of bond "
        r"vectors, got str",
    ),
    (
        "volume-zero",
        lambda: cal(C_ISO, XI3, volume=[1.0, 0.0, 1.0]),
        InputError,
        r"volume must be > 0, got min 0.0",
    ),
    (
        "volume-nan",
        lambda: cal(C_ISO, XI3, volume=[1.0, NAN, 1.0]),
        NonFiniteError,
        r"volume must be finite, got nan at index 1",
    ),
    (
        "volume-length",
        lambda: cal(C_ISO, XI3, volume=[1.0, 1.0]),
        ShapeError,
        r"volume must be a scalar or have shape \(3,\), got \(2,\)",
    ),
    (
        "omega-negative",
        lambda: cal(C_ISO, XI3, omega=-1.0),
        InputError,
        r"omega must be >= 0, got min -1.0",
    ),
    (
        "omega-all-zero",
        lambda: cal(C_ISO, XI3, omega=0.0),
        InputError,
        r"bonds must carry stiffness, got a family whose design matrix is zero",
    ),
    (
        "thickness-nan",
        lambda: cal(C_ISO, XI3, thickness=NAN),
        InputError,
        r"thickness must be > 0, got nan",
    ),
    (
        "family-zero-volume",
        lambda: Family(XI3, 1.0, 0.0),
        InputError,
        r"volume must be > 0, got min 0.0",
    ),
    (
        # library fix: a zero bond gave a NaN design matrix silently
        "design_matrix-zero-xi",
        lambda: design_matrix([[0.0, 0.0, 0.0]], 1.0, 1.0),
        InputError,
        r"xi must hold non-zero bond vectors, got a zero vector at bond 0",
    ),
    (
        "max_lower_bound-array",
        lambda: max_lower_bound(C_ISO, XI3),
        InputTypeError,
        r"family must be a calibration Family, got ndarray",
    ),
]


@pytest.mark.parametrize(
    ("call", "exc", "pattern"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_calibration_rejects(call, exc, pattern):
    expect(call, exc, pattern)


def test_infeasible_target_is_reported_not_returned_wrong():
    """Monoclinic CoTeO4 on the delta = 2 cubic sphere: no c >= 0 (docs/calibration.md)."""
    res = cal(cm.material("monoclinic"), FAM2)
    assert res.status == "infeasible"
    assert not res.feasible
    assert np.isnan(res.micromoduli).all()  # BondBased refuses NaN micromoduli
    assert np.isnan(res.tensor).all() and np.isnan(res.relative_error)
    # the measured least-squares error is in the message
    assert "infeasible: no micromoduli >= 0 reproduce the least-squares tensor (error" in (
        res.message
    )
    with pytest.raises(NonFiniteError, match="micromodulus must be finite"):
        pdlin.BondBased(micromodulus=res.micromoduli)


def test_lower_bound_above_max_is_infeasible():
    """A uniform bound above max_lower_bound (0.23870, reference value for isotropic delta = 6,
    omega = 1) has no solution."""
    fam = lattice_family(3, 6.0)
    C = cm.material("isotropic")
    lmax = max_lower_bound(C, fam)
    res = cal(C, fam, lower_bound=2.0 * lmax)
    assert res.status == "infeasible" and np.isnan(res.micromoduli).all()


def test_rank_deficient_family_reports_error():
    """Three axis bonds: rank 3 of 15; status 'step1' but the error is measured, not hidden."""
    res = cal(C_ISO, XI3)
    assert res.rank == 3
    assert res.message.startswith("rank 3 < 15: the quartics")
    # only C11, C22, C33 are reachable: error = |offdiag part|_F / |C|_F (measured 0.632)
    assert res.relative_error > 0.5


# ---------------------------------------------------------------------------
# calibration files
# ---------------------------------------------------------------------------
BASE = {"target": {"material": "isotropic"}, "family": {"dim": 3, "horizon": 2.0}}


def _mod(path, value=None, *, delete=False):
    d = copy.deepcopy(BASE)
    t = d
    for p in path[:-1]:
        t = t.setdefault(p, {})
    if delete:
        del t[path[-1]]
    else:
        t[path[-1]] = value
    return d


FAM = BASE["family"]
TOML_CASES = [
    (
        "top-typo",
        _mod(["familly"], {}),
        SceneError,
        r"unknown key 'familly'; did you mean 'family'",
    ),
    ("no-target", _mod(["target"], delete=True), SceneError, r"missing key 'target'"),
    ("no-family", _mod(["family"], delete=True), SceneError, r"missing key 'family'"),
    ("target-str", _mod(["target"], "iso"), SceneError, r"target must be a table, got str"),
    (
        "target-two-kinds",
        _mod(["target", "class"], "cubic"),
        SceneError,
        r"target needs exactly one of 'class', 'material', 'voigt', got \['class', 'material'\]",
    ),
    (
        "target-key-typo",
        _mod(["target", "matrial"], "x"),
        SceneError,
        r"unknown key 'target.matrial'; did you mean 'material'",
    ),
    (
        "class-unknown",
        {"target": {"class": "hexagon", "constants": {}}, "family": FAM},
        SceneError,
        r"target.class must be one of \[.*\], got 'hexagon'",
    ),
    (
        "constants-missing",
        {"target": {"class": "cubic"}, "family": FAM},
        SceneError,
        r"target.constants must be a table of the cubic constants",
    ),
    (
        "constants-extra",
        {"target": {"class": "cubic", "constants": {"C11": 3, "C12": 1, "C44": 1, "C13": 2}}},
        SceneError,
        r"target.constants does not fit cubic\(...\): .*unexpected keyword argument 'C13'",
    ),
    (
        "constants-str",
        {"target": {"class": "cubic", "constants": {"C11": "a", "C12": 1, "C44": 1}}},
        SceneError,
        r"target: C11 must be a real number, got 'a'",
    ),
    (
        "constants-not-spd",
        {"target": {"class": "cubic", "constants": {"C11": 1, "C12": 3, "C44": 1}}},
        SceneError,
        r"target: C \(cubic\) must be positive definite, got smallest eigenvalue -2",
    ),
    (
        "material-unknown",
        _mod(["target", "material"], "unobtainium"),
        SceneError,
        r"target: name must be one of \[.*\], got 'unobtainium'",
    ),
    (
        # library fix: was a bare ValueError from numpy
        "voigt-ragged",
        {"target": {"voigt": [[1, 2], [3]]}, "family": FAM},
        SceneError,
        r"target.voigt must be a numeric matrix \(array of arrays of numbers\), "
        r"got \[\[1, 2\], \[3\]\]",
    ),
    (
        "voigt-str",
        {"target": {"voigt": "abc"}, "family": FAM},
        SceneError,
        r"target.voigt must be a numeric matrix .* got 'abc'",
    ),
    (
        "voigt-5x5",
        {"target": {"voigt": np.eye(5).tolist()}, "family": FAM},
        SceneError,
        r"target.voigt must have shape \(6, 6\) or \(3, 3\) .* got \(5, 5\)",
    ),
    (
        "voigt-nan",
        {"target": {"voigt": [[1, 0, 0], [0, NAN, 0], [0, 0, 1]]}, "family": FAM},
        SceneError,
        r"target.voigt must be finite, got nan at index \(1, 1\)",
    ),
    (
        "voigt-nonsymmetric",
        {"target": {"voigt": (np.eye(6) + 0.1 * np.triu(np.ones((6, 6)), 1)).tolist()}},
        SceneError,
        r"target.voigt must be symmetric \(major symmetry C_ab = C_ba\), got max",
    ),
    (
        "rotation-not-orthogonal",
        _mod(["target", "rotation"], [[1, 2, 0], [0, 1, 0], [0, 0, 1]]),
        SceneError,
        r"target: Q must be orthogonal \(max \|QᵀQ - I\| <= 1e-10\), got 4",
    ),
    (
        "rotation-str",
        _mod(["target", "rotation"], "x"),
        SceneError,
        r"target.rotation must be a numeric matrix .* got 'x'",
    ),
    (
        "plane",
        _mod(["target", "plane"], "flat"),
        SceneError,
        r"target.plane must be 'stress' or 'strain', got 'flat'",
    ),
    (
        "family-key-typo",
        _mod(["family", "horizn"], 1),
        SceneError,
        r"unknown key 'family.horizn'; did you mean 'horizon'",
    ),
    ("family-no-dim", _mod(["family", "dim"], delete=True), SceneError, r"missing key family.dim"),
    (
        # library fix: int("three") raised a bare ValueError
        "family-dim-str",
        _mod(["family", "dim"], "three"),
        SceneError,
        r"family.dim must be an integer, got 'three'",
    ),
    (
        # library fix: int(2.5) silently became a 2D family
        "family-dim-float",
        _mod(["family", "dim"], 2.5),
        SceneError,
        r"family.dim must be an integer, got 2.5",
    ),
    (
        "family-dim-bool",
        _mod(["family", "dim"], True),
        SceneError,
        r"family.dim must be an integer, got True",
    ),
    ("family-dim-4", _mod(["family", "dim"], 4), SceneError, r"family: dim must be 2 or 3, got 4"),
    (
        "family-horizon-list",
        _mod(["family", "horizon"], [1, 2]),
        SceneError,
        r"family.horizon must be a number, got \[1, 2\]",
    ),
    (
        "family-horizon-negative",
        _mod(["family", "horizon"], -1.0),
        SceneError,
        r"family: horizon must be > 0, got -1.0",
    ),
    (
        "family-horizon-empty",
        _mod(["family", "horizon"], 0.5),
        SceneError,
        r"family: horizon 0.5 selects no neighbour on a cubic lattice .* the family is empty",
    ),
    (
        "family-spacing-zero",
        _mod(["family", "spacing"], 0.0),
        SceneError,
        r"family: spacing must be > 0, got 0.0",
    ),
    (
        "family-thickness-str",
        _mod(["family", "thickness"], "x"),
        SceneError,
        r"family.thickness must be a number, got 'x'",
    ),
    (
        "family-influence",
        _mod(["family", "influence"], "gauss"),
        SceneError,
        r"family: influence must be one of \[.*\] or a callable, got 'gauss'",
    ),
    (
        "calibration-key-typo",
        _mod(["calibration", "methd"], "x"),
        SceneError,
        r"unknown key 'calibration.methd'; did you mean 'method'",
    ),
    (
        "calibration-lower_bound-str",
        _mod(["calibration", "lower_bound"], "x"),
        SceneError,
        r"calibration.lower_bound must be a number, got 'x'",
    ),
    (
        "calibration-weighting-int",
        _mod(["calibration", "weighting"], 3),
        SceneError,
        r"calibration.weighting must be a string, got 3",
    ),
    (
        # library fix: the string "yes" was truthy and silently accepted
        "calibration-raise-str",
        _mod(["calibration", "raise_on_infeasible"], "yes"),
        SceneError,
        r"calibration.raise_on_infeasible must be true or false, got 'yes'",
    ),
    (
        # the option names are checked when the job runs (calibrate_micromoduli)
        "calibration-method",
        _mod(["calibration", "method"], "x"),
        InputError,
        r"method must be one of \('two-step', 'robust', 'min-norm'\), got 'x'",
    ),
    (
        "output-typo",
        _mod(["output", "file"], "x"),
        SceneError,
        r"unknown key 'output.file'; allowed keys: \['path', 'plot'\]",
    ),
    ("name-list", _mod(["name"], [1]), SceneError, r"name must be a string, got \[1\]"),
]
for _c in TOML_CASES:
    if _c[0] != "no-family":  # the other cases need a valid family table
        _c[1].setdefault("family", dict(FAM))


@pytest.mark.parametrize(
    ("data", "exc", "pattern"), [c[1:] for c in TOML_CASES], ids=[c[0] for c in TOML_CASES]
)
def test_calibration_file_rejects(data, exc, pattern):
    expect(lambda: calibration_from_dict(data).run(), exc, pattern)


def _toml(tmp_path, text):
    p = tmp_path / "target.toml"
    p.write_text(text)
    return str(p)


@pytest.mark.parametrize(
    ("text", "code", "pattern"),
    [
        ("[target\n", 2, r"invalid TOML"),
        (
            '[target]\nmaterial = "isotropic"\n[family]\ndim = "3"\nhorizon = 2.0\n',
            2,
            r"family.dim must be an integer, got '3'",
        ),
        (
            '[target]\nmaterial = "isotropic"\n[family]\ndim = 3\nhorizon = 2.0\n'
            '[calibration]\nqp_solver = "mosek"\n',
            2,
            r"qp_solver must be one of",
        ),
        # infeasible target: exit code 4, status and message printed (not an error)
        ('[target]\nmaterial = "monoclinic"\n[family]\ndim = 3\nhorizon = 2.0\n', 4, None),
    ],
    ids=["bad-toml", "dim-str", "qp-solver", "infeasible"],
)
def test_cli_calibrate(tmp_path, capsys, text, code, pattern):
    rc = main(["calibrate", _toml(tmp_path, text), "--json"])
    out = capsys.readouterr()
    assert rc == code
    if pattern is None:
        summary = json.loads(out.out)
        assert summary["status"] == "infeasible"
        assert "least-squares tensor (error" in summary["message"]
    else:
        assert len(out.err.strip().splitlines()) == 1
        assert out.err.startswith("pdlin: error: ")
        assert re.search(pattern, out.err)


def test_cli_missing_file(tmp_path, capsys):
    assert main(["calibrate", str(tmp_path / "nope.toml")]) == 2
    assert "calibration file not found" in capsys.readouterr().err
