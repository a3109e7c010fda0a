"""The 3D soft precipitate of Javaheri, Luo, Lakshmanan & Sundararaghavan (2022), Sec. III.C, 48³.

The paper's size: a 3 mm cube of 48³ particles (h = 62.5 µm) of transversely isotropic Mg
(Sec. III.C: C11 = 59.3, C12 = 25.7, C13 = 21.4, C33 = 61.5, C44 = 16.4 GPa) with a central sphere
of diameter 0.875 mm and stiffness ratio r_c = 0.1, pulled by the inward shadow layer (Sec. II.D)
carrying ``F = I + 0.02 diag(1, -0.5, -0.5)``.  Reconstructed (docs/theory/conventions.md#soft-
precipitate): c ∥ z, corner origin, the precipitate ``|X - X_c| ≤ d/2``.  The paper's Figs. 16-18
carry no numbers; the reference values are those of an independent implementation of the same
reconstruction (static CG to 1e-10), on the centreline y = z = index 24: ``raw = max|Δ²u_x|``,
``filt`` the same after a 2-point average (which annihilates the θ = π sawtooth every centrally
symmetric weight set keeps), ``dev = max|u_x − affine|``, all in µm.
"""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.constitutive import transversely_isotropic
from pdlin.models import shadow_problem

# reference values (independent implementation, 48³, µm): raw / filt / dev per weight set.
# HO 3h (5.04 / 1.17 / 7.67) is not here: 824 CPU s and 8.5 GB peak RSS in pdlin, beyond the slow
# tier; benchmarks/bench_precipitate.py --rows ho3 compares it (docs/weights.md's table)
REFERENCE_48 = {
    (1, "higher_order"): (4.82, 1.62, 7.73),
    (2, "higher_order"): (4.71, 1.30, 7.84),
}


def _centreline(m: int, control: str, n: int = 48) -> tuple[float, float, float]:
    C = transversely_isotropic(C11=59.3, C33=61.5, C12=25.7, C13=21.4, C44=16.4)
    h = 3.0 / n
    cloud = pdlin.grid((n, n, n), spacing=h)
    inside = np.linalg.norm(cloud.points - 1.5, axis=1) <= 0.875 / 2
    cloud = cloud.replace(material=inside.astype(int))
    bonds = pdlin.find_bonds(cloud, ratio=float(m))
    model = pdlin.Correspondence({0: C, 1: 0.1 * C}, control=control)
    F = np.eye(3) + 0.02 * np.diag([1.0, -0.5, -0.5])
    prob = shadow_problem(model, cloud, bonds, F)
    res = pdlin.solve(prob, rtol=1e-10)
    ij = np.rint(cloud.points / h - 0.5).astype(int)
    row = np.flatnonzero((ij[:, 1] == n // 2) & (ij[:, 2] == n // 2))
    row = np.setdiff1d(row, prob.model.shadow)
    row = row[np.argsort(cloud.points[row, 0])]
    ux = 1e3 * res.u[row, 0]  # mm -> µm
    affine = 1e3 * 0.02 * cloud.points[row, 0]
    raw = float(np.abs(np.diff(ux, 2)).max())
    filt = float(np.abs(np.diff(0.5 * (ux[1:] + ux[:-1]), 2)).max())
    return raw, filt, float(np.abs(ux - affine).max())


@pytest.mark.slow
def test_precipitate_48_cubed_error_table():
    got = {key: _centreline(*key) for key in REFERENCE_48}
    for key, want in REFERENCE_48.items():
        np.testing.assert_allclose(got[key], want, rtol=0.02)  # 3 digits printed: ± 2 %
    # the higher-order weights do not roughen the field: filt(HO 2h) <= 1.25 filt(δ = h)
    # (the bound of pdlin's 2D and 24³ precipitate tests; reference ratio 1.30 / 1.62 = 0.80)
    assert got[2, "higher_order"][1] <= 1.25 * got[1, "higher_order"][1]
