"""Anisotropy ratio E1/E2 = 1e4: calibration, calibrated bond-based statics, correspondence."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import pdlin
from pdlin import constitutive as cm
from pdlin.calibration import lattice_family

# 2D plain Voigt (11, 22, 12), C11/C22 = 1e4.  Cauchy (C12 = C66) and inside the cone of
# nonnegative micromoduli (C12**2 < C11 C22), so reachable (docs/calibration.md).
C_CAUCHY = np.array([[1e4, 0.5, 0.0], [0.5, 1.0, 0.0], [0.0, 0.0, 0.5]])
# not Cauchy (C12 = 0.3 != C66 = 0.2): bond-based models reach only its Cauchy projection
C_GENERAL = np.array([[1e4, 0.3, 0.0], [0.3, 1.0, 0.0], [0.0, 0.0, 0.2]])
H = 1.0
DELTA = 3.015 * H


def test_calibration_2d_cauchy_target_exact():
    res = pdlin.calibrate_micromoduli(C_CAUCHY, lattice_family(2, 3.0))
    assert res.feasible and res.rank == 5 and res.c_min >= 0.0
    # measured 7.3e-16: a Cauchy target is reproduced to round-off times cond ~ 1e4
    assert res.relative_error < 1e-11


@pytest.mark.parametrize("method", ["two-step", "robust"])
def test_calibration_2d_non_cauchy_error_is_cauchy_distance(method):
    res = pdlin.calibrate_micromoduli(C_GENERAL, lattice_family(2, 3.0), method=method)
    assert res.feasible and res.c_min >= 0.0
    dist = cm.cauchy_distance(C_GENERAL)  # 1.1547e-5: the smallest bond-based error
    # measured: error == Cauchy distance (1.1547005e-5) to 1e-15 for both methods
    assert res.relative_error == pytest.approx(dist, rel=1e-6)
    assert res.relative_error < 2e-5


def test_calibration_3d_transversely_isotropic():
    # axis e3 stiff: C33/C11 = 1e4
    T = cm.transversely_isotropic(C11=1.0, C33=1e4, C12=0.3, C13=0.5, C44=0.5)
    res = pdlin.calibrate_micromoduli(T, lattice_family(3, 3.0))
    assert res.status == "qp" and res.feasible and res.c_min >= 0.0
    # measured 5.7735e-6 = cauchy_distance(T): the Cauchy projection, to 1e-6 relative
    assert res.relative_error == pytest.approx(cm.cauchy_distance(T), rel=1e-6)


def _calibrated_patch():
    cloud = pdlin.grid((24, 24), H)
    bonds = pdlin.find_bonds(cloud, DELTA)
    # 'bulk': c = c(xi) of the complete family everywhere (homogeneous material)
    res = pdlin.calibrate_micromoduli(C_CAUCHY, bonds, thickness=cloud.thickness, boundary="bulk")
    fam = res.families[int(np.argmax([f.n_bonds for f in res.families]))]
    # measured 7.5e-16 on the complete family
    assert fam.relative_error < 1e-11
    return cloud, pdlin.BondBased(micromodulus=res.micromoduli), fam.tensor


@pytest.mark.parametrize("axis", [0, 1], ids=["stiff-x", "soft-y"])
def test_calibrated_bond_based_uniaxial_patch(axis):
    """Shadow layer on the two faces normal to ``axis``; the other faces are free.

    The layer carries the closed-form uniaxial-stress field of the calibrated tensor:
    eps_aa = e, eps_oo = -C_ao / C_oo e.  The interior strain must reproduce it.
    """
    cloud, model, Ceff = _calibrated_patch()
    e, o = 1e-3, 1 - axis
    F = np.eye(2)
    F[axis, axis] += e
    F[o, o] -= Ceff[axis, o] / Ceff[o, o] * e  # closed form, uniaxial stress
    faces = ["x-", "x+"] if axis == 0 else ["y-", "y+"]
    bc, _ = pdlin.shadow_layer(cloud, F, depth=DELTA, faces=faces)
    prob = pdlin.StaticProblem(model, cloud, horizon=DELTA, dirichlet=[bc])
    with warnings.catch_warnings():
        # no AccuracyWarning is expected at 1e4; one would fail the test loudly
        warnings.simplefilter("error", pdlin.errors.AccuracyWarning)
        out = {s: pdlin.solve(prob, solver=s, rtol=1e-10) for s in ("direct", "amg-cg")}
    X = cloud.points
    core = np.all(np.abs(X - X.mean(0)) < 2 * H, axis=1)
    A = np.c_[X[core], np.ones(core.sum())]
    grad = np.linalg.lstsq(A, out["direct"].u[core], rcond=None)[0][:2].T
    rel = np.abs(np.diag(grad) - np.diag(F - np.eye(2))) / np.abs(np.diag(F - np.eye(2)))
    # loaded axis: measured 2.2e-8 (stiff) and 1.0e-8 (soft)
    assert rel[axis] < 1e-6
    # lateral axis: PD free-surface effect of the 3-cell layers on the free faces;
    # measured 3.4e-3 (stiff pull, lateral = -5e-4) and 1.9e-4 (soft pull, lateral -5e-8)
    assert rel[o] < 1e-2
    # AMG-CG vs direct: rtol 1e-10 of ||b|| times cond ~ 1e4 bounds it by ~1e-6;
    # measured 1.5e-8 (stiff) and 1.8e-12 (soft).  An AMG failure would raise
    # ConvergenceError or an AccuracyWarning (turned into an error above).
    ref = np.abs(out["direct"].u).max()
    assert np.abs(out["amg-cg"].u - out["direct"].u).max() / ref < 1e-6


@pytest.mark.parametrize("control", ["none", "penalty", "higher_order"])
@pytest.mark.parametrize("solver", ["direct", "amg-cg"])
def test_correspondence_anisotropic_patch_exact(control, solver):
    """Linear correspondence is consistent: any affine field is exact for any C."""
    cloud = pdlin.grid((20, 18), H)
    F = np.eye(2) + np.array([[1e-3, 2e-4], [-3e-4, 5e-4]])
    bc, _ = pdlin.shadow_layer(cloud, F, depth=2 * DELTA)  # two-hop model: 2 delta deep
    model = pdlin.Correspondence(C=C_GENERAL, control=control)
    prob = pdlin.StaticProblem(model, cloud, horizon=DELTA, dirichlet=[bc])
    res = pdlin.solve(prob, solver=solver, rtol=1e-12)
    exact = cloud.points @ (F - np.eye(2)).T
    err = np.abs(res.u - exact).max() / np.abs(exact).max()
    # measured: direct 1e-15 .. 5e-15, AMG-CG 2e-13 .. 1.2e-10 (control 'none')
    assert err < 1e-8
