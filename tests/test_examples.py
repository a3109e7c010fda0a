"""The runnable examples run and give the documented results."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_bar_tension_example():
    out = _load("bar_tension").main()
    errs = [r["max_rel_error"] for r in out["graded_1d"]]
    ns = [r["N"] for r in out["graded_1d"]]
    rate = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert rate > 1.9  # O(h^2) at fixed delta/h (docs/bond_based.md)
    assert out["bar_3d"]["max_strain_error"] < 1e-9  # exact affine interior


def test_anisotropic_block_tutorial(tmp_path):
    from pdlin import constitutive as cst

    out = _load("anisotropic_block").main(plot=str(tmp_path / "c.png"))
    C = out["target"]
    res = out["calibration"]
    # Prakash, anisotropic micromoduli, Table 1: transversely isotropic error 1.5335 % at delta = 6;
    # at delta = 3 the family has full rank 15, so the error is again the Cauchy distance (derived,
    # conventions.md#calibration-in-the-frobenius-norm)
    assert res.rank == 15
    assert abs(res.relative_error - cst.cauchy_distance(C)) < 1e-10
    S = np.linalg.inv(cst.cauchy_projection(C))
    for row, k in zip(out["blocks"], (0, 2), strict=True):
        assert row["max_strain_error"] < 1e-8  # exact affine interior
        np.testing.assert_allclose(row["apparent_modulus"], 1 / S[k, k], rtol=1e-8)
    assert (tmp_path / "c.png").stat().st_size > 0


def test_correspondence_controls_tutorial(tmp_path):
    out = _load("correspondence_controls").main(plot=str(tmp_path))
    bar = {(r["label"], r["delta"], r["coefficient"]): r for r in out["bar"]}
    sp, none = bar[("stress_points", "1h", None)], bar[("none", "1h", None)]
    # reference values of an independent implementation (graded bar), n = 500: rel-L2 u 1.975e-2
    # (SP) and 1.548e-2 (no control); no control oscillates (osc ~1.0e-2), SP does not (~1e-16) --
    # SP is not the more accurate one in L2 (reference computation), its benefit is the absence of
    # oscillation
    assert sp["rel_l2_u"] == pytest.approx(1.975e-2, rel=0.01)
    assert none["rel_l2_u"] == pytest.approx(1.548e-2, rel=0.01)
    assert none["osc"] == pytest.approx(1.0e-2, rel=0.05) and sp["osc"] < 1e-12
    assert none["rel_l2_u"] < sp["rel_l2_u"]
    # reference values, osc: springs 4.3e-3 / 2.5e-6 at C̃ = 1e-3 / 0.1, ADS 2.2e-10 at 0.1
    assert bar[("springs", "1h", 1e-3)]["osc"] == pytest.approx(4.3e-3, rel=0.05)
    assert bar[("springs", "1h", 0.1)]["osc"] == pytest.approx(2.5e-6, rel=0.05)
    assert bar[("ads", "1h", 0.1)]["osc"] == pytest.approx(2.2e-10, rel=0.05)
    for control in ("springs", "ads"):  # reference computation: no C̃ gives osc < 1e-6 and L2 < 2 %
        rows = [r for r in out["bar"] if r["control"] == control]
        assert rows and not any(r["osc"] < 1e-6 and r["rel_l2_u"] < 0.02 for r in rows)
    plate = {r["label"]: r for r in out["plate"]["rows"]}
    # reference values (R2D, conventions.md#plate-with-a-square-hole), h = 2: rel-L2 u 2.48e-2 /
    # 1.30e-2 and checker 2.48e-2 / 2.72e-3 (no control / stress points, seed 0)
    assert plate["none"]["rel_l2_u"] == pytest.approx(2.48e-2, rel=0.01)
    assert plate["none"]["checker"] == pytest.approx(2.48e-2, rel=0.01)
    assert plate["stress_points"]["rel_l2_u"] == pytest.approx(1.30e-2, rel=0.01)
    assert plate["stress_points"]["checker"] == pytest.approx(2.72e-3, rel=0.01)
    for name in ("bar_controls.png", "plate_controls.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_crystal_plasticity_polycrystal_tutorial(tmp_path):
    import meshio

    steps = 6
    out = _load("crystal_plasticity_polycrystal").main(
        ["--n", "10", "--steps", str(steps), "--compare", "1,3,6", "--out", str(tmp_path)]
    )
    runs = out["runs"]
    for load in ("shear", "compression"):
        res = runs[load]["result"]
        assert res.n_steps == steps and len(res.states) == steps  # merged segments
        # time series (.pvd + one .vtu per step, with the committed state) and the CSV
        pvd = (tmp_path / f"{load}.pvd").read_text()
        assert pvd.count("<DataSet") == steps
        (piece,) = tmp_path.glob(f"{load}.pvd.*/{load}_{steps:04d}.vtu")  # versioned folder
        last = meshio.read(piece)
        assert {"Displacement", "Cauchy_Stress", "State_reorientation"} <= set(last.point_data)
        csv = np.genfromtxt(tmp_path / f"{load}_homogenized.csv", delimiter=",", names=True)
        np.testing.assert_allclose(csv["sigma_12"], res.homogenized_stress[:, 0, 1], rtol=1e-9)
        # plasticity starts at step 3 (reference runs: ~30 % of the particles plastic there)
        plastic = [float(np.mean(st["plastic"])) for st in res.states]
        assert plastic[0] == 0.0 and plastic[2] > 0.05
        # conventions.md#crystal-plasticity-conventions: from a shared committed state the two
        # drivers agree in the homogenized stress (measured ≤ 1e-7 here; ≤ 3e-4 at n = 25), never
        # compare pointwise
        cmp = runs[load]["compare"]
        assert sorted(cmp) == [1, 3, 6] and all(c["ok"] for c in cmp.values())
        assert runs[load]["max_difference"] <= 2e-3
        assert all(c["method"] == "adr" for c in cmp.values())
    sxy = runs["shear"]["result"].homogenized_stress[:, 0, 1]
    syy = runs["compression"]["result"].homogenized_stress[:, 1, 1]
    sxx = runs["compression"]["result"].homogenized_stress[:, 0, 0]
    # reference runs of an independent implementation (seeded 21-grain maps at n = 25, "indicative ±
    # 10 %"): mean σ_xy ≈ 3.7 / 10 and mean σ_yy ≈ -4.3 / -11.0 MPa at steps 1 / 3.  This is a 10 x
    # 10 grid (a third of the particles sit in the prescribed ring) and another map, so the
    # tolerance is ± 25 % (measured: σ_xy 3.92 / 10.79, σ_yy -3.94 / -10.62).
    np.testing.assert_allclose(sxy[[0, 2]], [3.7, 10.0], rtol=0.25)
    np.testing.assert_allclose(syy[[0, 2]], [-4.3, -11.0], rtol=0.25)
    assert np.all(sxy > 0) and np.all(np.diff(sxy) > 0)  # hardening, no softening
    assert np.all(syy < 0) and np.all(sxx > 0)  # compression along y, lateral tension
    # the plastic plateau sits far below the elastic line (h0 = 10 MPa: near-perfect plasticity)
    assert sxy[-1] < 0.6 * steps * sxy[0]
    for name in ("cp_shear_sxy", "cp_compression_reorientation", "cp_grains"):
        assert (tmp_path / f"{name}.png").stat().st_size > 0
    assert (tmp_path / "cp_stress_strain.png").exists() and (tmp_path / "cp_adr.png").exists()
