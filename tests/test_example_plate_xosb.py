"""The state-based tutorial example (examples/plate_with_hole_xosb.py) runs and shows its claim."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "plate_with_hole_xosb.py"


def _load():
    spec = importlib.util.spec_from_file_location("plate_with_hole_xosb", EXAMPLE)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_plate_with_hole_xosb_tutorial(tmp_path):
    ex = _load()
    n_ang, n_rad = ex.COARSE  # 4 x 24 x 45 = 4,320 particles, FE 4 x 48 x 90, ~5 s
    out = ex.main(n_ang, n_rad, plot=str(tmp_path / "ring.png"))
    assert out["points"] == 4 * n_ang * n_rad
    err = out["ring_error"]
    # Provenance: Liu, Chen & Skelton, XOSB, Sec. 5.1 (conventions.md#plate-with-a-hole, BC "B") --
    # XOSBPD's ring u_y error is several times smaller than uncorrected OSBPD's (2.2 % vs 14.5 % at
    # 7,680 particles, reference values of an independent implementation). At this coarser mesh we
    # measured XOSB 3.31 % (paper) / 3.33 % (energy) vs OSBPD 9.59 %; at 4 x 16 x 30 the ordering no
    # longer holds (6.4 % vs 6.1 %), hence this size.
    assert err["XOSB (paper)"][1] < err["OSBPD"][1]
    assert err["XOSB (energy)"][1] < err["OSBPD"][1]
    assert err["XOSB (paper)"][1] <= 0.04 and err["XOSB (paper)"][0] <= 0.02  # C2 bounds
    # the FE ring ranges agree with the 4 x 128 x 240 FE reference's (u_x 2.8042e-4 m, u_y 9.6945e-5
    # m) within 1 %
    fe = out["u_ring"]["FE"]
    np.testing.assert_allclose(np.ptp(fe, axis=0), [2.8042e-4, 9.6945e-5], rtol=1e-2)
    # β ≈ 90°: XOSB u_y near the FE value, OSBPD's too large (acceptance check C2, qualitatively)
    top = out["hole_edge"][90.0]
    assert abs(top["XOSB (paper)"][1] - top["FE"][1]) < abs(top["OSBPD"][1] - top["FE"][1])
    assert (tmp_path / "ring.png").stat().st_size > 0
