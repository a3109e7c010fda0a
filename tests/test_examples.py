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
    # spec 004 Table 1: transversely isotropic error 1.5335 % at delta = 6; at delta = 3 the
    # family has full rank 15, so the error is again the Cauchy distance (spec 2.3)
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
    # spec 003 §7.1 [REF], n = 500: rel-L2 u 1.975e-2 (SP) and 1.548e-2 (no control); no
    # control oscillates (osc ~1.0e-2), SP does not (~1e-16) -- SP is not the more accurate
    # one in L2 (spec 003 §10), its benefit is the absence of oscillation
    assert sp["rel_l2_u"] == pytest.approx(1.975e-2, rel=0.01)
    assert none["rel_l2_u"] == pytest.approx(1.548e-2, rel=0.01)
    assert none["osc"] == pytest.approx(1.0e-2, rel=0.05) and sp["osc"] < 1e-12
    assert none["rel_l2_u"] < sp["rel_l2_u"]
    # spec 003 §7.1 [REF] osc: springs 4.3e-3 / 2.5e-6 at C̃ = 1e-3 / 0.1, ADS 2.2e-10 at 0.1
    assert bar[("springs", "1h", 1e-3)]["osc"] == pytest.approx(4.3e-3, rel=0.05)
    assert bar[("springs", "1h", 0.1)]["osc"] == pytest.approx(2.5e-6, rel=0.05)
    assert bar[("ads", "1h", 0.1)]["osc"] == pytest.approx(2.2e-10, rel=0.05)
    for control in ("springs", "ads"):  # spec 003 §9 V18: no C̃ gives osc < 1e-6 and L2 < 2 %
        rows = [r for r in out["bar"] if r["control"] == control]
        assert rows and not any(r["osc"] < 1e-6 and r["rel_l2_u"] < 0.02 for r in rows)
    plate = {r["label"]: r for r in out["plate"]["rows"]}
    # spec 003 §7.2 [REF], h = 2: rel-L2 u 2.48e-2 / 1.30e-2 and checker 2.48e-2 / 2.72e-3
    # (no control / stress points, seed 0)
    assert plate["none"]["rel_l2_u"] == pytest.approx(2.48e-2, rel=0.01)
    assert plate["none"]["checker"] == pytest.approx(2.48e-2, rel=0.01)
    assert plate["stress_points"]["rel_l2_u"] == pytest.approx(1.30e-2, rel=0.01)
    assert plate["stress_points"]["checker"] == pytest.approx(2.72e-3, rel=0.01)
    for name in ("bar_controls.png", "plate_controls.png"):
        assert (tmp_path / name).stat().st_size > 0
