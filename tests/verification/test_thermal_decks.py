"""Peridigm's thermal-expansion decks run unchanged and match Peridigm's gold files.

``test/verification/ThermalExpansionCube`` (``Elastic``, i.e. LPS) and
``ThermalExpansionCubeElasticCorrespondence`` (Peridigm commit 82c6ad8, kept under
``tests/data/peridigm`` with Peridigm's BSD license): a 5 x 5 x 5 PdQuickGrid cube heated
by ``1000 t / 3600`` (``Prescribed Temperature`` on every point), α = 1e-5, three lines of
points held against rigid motion, ten load steps.  The free cube expands by
``α ΔT(t) (x - x_0)`` (``x_0`` the corner the held lines meet at).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import pdlin
from pdlin.cli.main import main
from pdlin.errors import SceneError
from pdlin.io import read_result

netCDF4 = pytest.importorskip("netCDF4")

DATA = Path(__file__).resolve().parents[1] / "data" / "peridigm"
ALPHA = 1.0e-5  # the decks' Thermal Expansion Coefficient


def _gold(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Times, coordinates, displacements (steps, n, 3) and Temperature_Change of a gold file."""
    with netCDF4.Dataset(path) as ds:
        names = list(netCDF4.chartostring(ds.variables["name_nod_var"][:]))
        x = np.column_stack([np.asarray(ds.variables[f"coord{c}"][:]) for c in "xyz"])

        def var(name: str) -> np.ndarray:
            return np.asarray(ds.variables[f"vals_nod_var{names.index(name) + 1}"][:])

        u = np.stack([var(f"Displacement{c}") for c in "XYZ"], axis=-1)
        return np.asarray(ds.variables["time_whole"][:]), x, u, var("Temperature_Change")


def _run(tmp_path: Path, folder: str, deck: str):
    work = tmp_path / folder
    shutil.copytree(DATA / folder, work, ignore=shutil.ignore_patterns("*_gold.e"))
    assert main(["run", str(work / deck), "-q"]) == 0
    return pdlin.read_deck(work / deck), read_result(work / f"{folder}.e")


def test_lps_thermal_cube_matches_gold_at_every_step(tmp_path):
    folder = "ThermalExpansionCube"
    scene, res = _run(tmp_path, folder, f"{folder}.xml")
    t, x, ug, dT_gold = _gold(DATA / folder / f"{folder}_gold.e")
    assert np.array_equal(res.points, x)  # PdQuickGrid points: Peridigm's, in its order
    assert np.allclose(res.times, t, rtol=1e-12)
    assert isinstance(scene.model, pdlin.LPS) and scene.problem.thermal is not None
    # the deck's ΔT = T(t) - T(0) = 1000 t / 3600, Peridigm's Temperature_Change
    for (ts, p), dg in zip(scene.steps, dT_gold, strict=True):
        if p.thermal is None:
            assert ts == 0.0
            continue
        assert np.allclose(p.thermal.temperature(scene.cloud), dg, rtol=1e-14, atol=0)
    for k in range(t.size):
        u = res.steps[k]["displacement"]
        # Peridigm's Elastic (finite kinematics) is exact on a uniform dilation too: the
        # gold is α ΔT (x - x0) to 1e-15 and pdlin's linear solve the same (measured
        # max |Δu| 8e-16 against the gold at the final step, max |u| = 0.04)
        assert np.abs(u - ug[k]).max() <= 1e-12 * 0.04
        # mechanical stress and strain: zero (3 K α ΔT = 3.9e9 Pa at the final step)
        assert np.abs(res.steps[k]["stress"]).max() <= 1e-12 * 3.9e9
        assert np.abs(res.steps[k]["strain"]).max() <= 1e-12


def test_correspondence_thermal_cube_against_gold(tmp_path):
    """pdlin: ``α ΔT (x - x0)`` exactly; Peridigm: its rate-form integration of the strain.

    Peridigm's ``Elastic Correspondence`` reduces the unrotated rate of deformation by the
    thermal strain increment of each step in the current configuration, so each step
    stretches the cube by ``1 / (1 - α δT)`` (δT = 100 per step): ``λ_n = (1 - α δT)^-n``.
    The gold file is that closed form to round-off (checked below), and its linear part
    ``α ΔT`` is pdlin's answer.
    """
    folder = "ThermalExpansionCubeElasticCorrespondence"
    scene, res = _run(tmp_path, folder, f"{folder}.xml")
    t, x, ug, _ = _gold(DATA / folder / f"{folder}_gold.e")
    assert np.array_equal(res.points, x)
    assert isinstance(scene.model, pdlin.Correspondence) and scene.model.control == "penalty"
    x0 = x[0]
    for k in range(t.size):
        u = res.steps[k]["displacement"]
        dT = 1000.0 * t[k] / 3600.0  # the deck's Prescribed Temperature change
        # pdlin: the linear free expansion (measured 1e-9 absolute: the iterative solve's
        # 1e-8 relative tolerance on the matrix-free 3D correspondence operator)
        assert np.abs(u - ALPHA * dT * (x - x0)).max() <= 1e-7 * 0.04
        lam = (1.0 - ALPHA * 100.0) ** (-k)  # Peridigm's rate-form stretch (derived above)
        assert np.abs(ug[k] - (lam - 1.0) * (x - x0)).max() <= 1e-14
    # final step: max |Δu| 2.2e-4 = 5.5e-3 of max |u| (Peridigm's incremental integration)
    diff = np.abs(res.steps[-1]["displacement"] - ug[-1]).max()
    assert 2.0e-4 < diff < 2.3e-4


def test_thermal_deck_keys(tmp_path):
    """Deck-level details: α per material, ΔT relative to t = 0, refusals by key path."""
    text = (DATA / "ThermalExpansionCube" / "ThermalExpansionCube.xml").read_text()
    # a temperature change without a thermal expansion coefficient does nothing
    no_alpha = text.replace(
        '<Parameter name="Thermal Expansion Coefficient" type="double" value="10.0e-6"/>', ""
    )
    (tmp_path / "a.xml").write_text(no_alpha)
    scene = pdlin.read_deck(tmp_path / "a.xml")
    assert scene.problem.thermal is None
    # the change is T(t) - T(0) even when the run starts later (Peridigm's increment BC)
    later = text.replace('name="Initial Time" type="double" value="0.0"',
                         'name="Initial Time" type="double" value="360.0"')  # fmt: skip
    (tmp_path / "b.xml").write_text(later)
    scene = pdlin.read_deck(tmp_path / "b.xml")
    assert scene.steps[0][1].thermal.temperature(scene.cloud)[0] == 0.0  # initial state
    assert np.isclose(scene.steps[1][1].thermal.temperature(scene.cloud)[0], 1000 * 684 / 3600)
    # Peridigm refuses thermal expansion in other materials; so does the reader
    bad = text.replace('value="Elastic"/>', 'value="Elastic Bond Based"/>')
    (tmp_path / "c.xml").write_text(bad)
    with pytest.raises(SceneError, match="Thermal Expansion Coefficient"):
        pdlin.read_deck(tmp_path / "c.xml")
    flux = text.replace('value="Prescribed Temperature"', 'value="Thermal Flux"')
    (tmp_path / "d.xml").write_text(flux)
    with pytest.raises(SceneError, match="Prescribed Temperature"):
        pdlin.read_deck(tmp_path / "d.xml")
