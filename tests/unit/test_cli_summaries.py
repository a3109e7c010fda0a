"""`pdlin run` summaries say what their numbers are: stress components with labels and
units, and where a calibration's largest tensor error comes from."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np

import pdlin
from pdlin.cli.main import _stress_components, main
from pdlin.scene.scene import load_scene

EXAMPLES = Path(pdlin.__file__).parent / "examples"


def test_anisotropic_block_explains_its_largest_tensor_error(tmp_path, capsys):
    cal = load_scene(EXAMPLES / "anisotropic_block.toml").calibration
    err, fam = np.asarray(cal.relative_error), np.asarray(cal.family_of_point)
    assert main(["run", "--example", "anisotropic_block", "-o", str(tmp_path / "a.vtu")]) == 0
    lines = capsys.readouterr().out.splitlines()
    (k,) = [i for i, line in enumerate(lines) if line.startswith("calibration")]
    line = lines[k]
    # the complete families' error and count, then the largest error and where it is
    assert f"{err[fam >= 0].max():.3e} at the {int(np.sum(fam >= 0)):,} points" in line
    assert f"up to {err.max():.3e} at the {int(np.sum(fam < 0)):,} points" in line
    assert "surface effect" in line
    # beside the PASS lines of the checks
    assert all(s.startswith("check:") and "PASS" in s for s in lines[k + 1 :])
    # the complete families reproduce the target (calibrate_micromoduli, boundary 'bulk':
    # "interior points reproduce the target exactly"), to round-off
    assert err[fam >= 0].max() < 1e-12 < err.max()


def test_anisotropic_block_json_summary_splits_the_error(tmp_path, capsys):
    out = str(tmp_path / "a.vtu")
    assert main(["run", "--example", "anisotropic_block", "-o", out, "--json", "-q"]) == 0
    cal = json.loads(capsys.readouterr().out)["calibration"]
    assert cal["calibrated_points"] + cal["cut_family_points"] == 800  # the 40 x 20 grid
    assert cal["calibrated_error"] < 1e-12 < cal["relative_error"]


def test_nonlinear_summary_labels_stress_components_with_units(tmp_path, capsys):
    out = tmp_path / "cp.pvd"
    assert main(["run", "--example", "cp_single_crystal", "-o", str(out)]) == 0
    (line,) = [s for s in capsys.readouterr().out.splitlines() if s.startswith("mean stress")]
    with open(tmp_path / "cp_homogenized.csv", newline="") as fh:
        last = list(csv.DictReader(fh))[-1]
    # the scene's crystal uses CrystalPlasticity's default constants, in MPa (Luo, Ramazani &
    # Sundararaghavan (2017), Sec. 4)
    for label, col in (("sxx", "sigma_11"), ("syy", "sigma_22"), ("sxy", "sigma_12")):
        m = re.search(rf"\b{label} (\S+) MPa", line)
        assert m is not None, (label, line)
        assert np.isclose(float(m.group(1)), float(last[col]), rtol=1e-3)  # 4 digits shown


def test_stress_components_units_only_where_known():
    sig = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 5.0, 6.0]])
    text = _stress_components(sig)
    assert text.startswith("sxx 1, syy 4, szz 6, sxy 2, sxz 3, syz 5")
    assert "MPa" not in text and "units of the elastic constants" in text
    default = pdlin.Correspondence(material=pdlin.CrystalPlasticity("fcc"))
    assert _stress_components(sig, default).startswith("sxx 1 MPa, syy 4 MPa")
    # other constants: the stress is in their units, which pdlin does not know
    other = pdlin.CrystalPlasticity("fcc", elastic={"C11": 170.0, "C12": 124.0, "C44": 75.0})
    text = _stress_components(sig, pdlin.Correspondence(material=other))
    assert "MPa" not in text and "units of the elastic constants" in text
