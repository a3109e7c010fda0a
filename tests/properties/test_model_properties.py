"""Invariants every pdlin model must satisfy (one table of all models).

Later models (LPS, XOSB, correspondence) add rows to ``CASES``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
import scipy.sparse as sp

import pdlin
from pdlin.fields import deformation_gradient


def _jittered(dim: int, n: int, seed: int = 1) -> pdlin.PointCloud:
    rng = np.random.default_rng(seed)
    c = pdlin.grid((n,) * dim, spacing=1.0 / n)
    pts = c.points + rng.uniform(-0.2, 0.2, c.points.shape) / n
    return pdlin.PointCloud(
        pts, c.volumes * rng.uniform(0.8, 1.2, c.n), horizon=rng.uniform(2.0, 3.2, c.n) / n
    )


def _case_1d() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((30,), spacing=0.1)
    return pdlin.BondBased(E=2.0), c, pdlin.find_bonds(c, ratio=3.015)


def _case_2d_stress() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((14, 11), spacing=0.1)
    return pdlin.BondBased(E=70e9, plane="stress"), c, pdlin.find_bonds(c, ratio=3.015)


def _case_2d_strain_inverse() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((12, 12), spacing=0.5)
    b = pdlin.find_bonds(c, ratio=2.5, influence="inverse")
    return pdlin.BondBased(E=3.0, plane="strain"), c, b


def _case_3d() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((10, 10, 9), spacing=0.25)
    return pdlin.BondBased(E=1.0), c, pdlin.find_bonds(c, ratio=3.015)


def _case_2d_variable_horizon() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = _jittered(2, 14)
    E = np.random.default_rng(3).uniform(1.0, 5.0, c.n)
    return pdlin.BondBased(E=E), c, pdlin.find_bonds(c)


def _case_3d_per_bond_micromodulus() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = _jittered(3, 7)
    b = pdlin.find_bonds(c, influence="delta_over_r")
    rng = np.random.default_rng(5)
    cb = rng.uniform(0.5, 2.0, b.n_bonds)
    cb = 0.5 * (cb + cb[b.reverse])  # micromoduli must be symmetric over bond pairs
    return pdlin.BondBased(micromodulus=cb), c, b


def _case_corr_2d_none() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    from pdlin import constitutive as cst

    c = pdlin.grid((16, 14), spacing=0.1)
    C = cst.plane_strain(cst.material("transversely_isotropic"))
    return pdlin.Correspondence(C, control="none"), c, pdlin.find_bonds(c, ratio=2.015)


def _case_corr_3d_higher_order() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((12, 12, 11), spacing=0.2)
    model = pdlin.Correspondence(E=1.0, nu=0.3, control="higher_order")
    return model, c, pdlin.find_bonds(c, ratio=2.0)


def _case_corr_2d_penalty_jittered() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = _jittered(2, 10)
    return pdlin.Correspondence(E=2.0, nu=0.25, control="penalty"), c, pdlin.find_bonds(c)


def _case_2d_volume_correction() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((20, 20), spacing=0.1)
    m = pdlin.BondBased(E=70e9, surface_correction="volume")
    return m, c, pdlin.find_bonds(c, ratio=3.015)


def _case_3d_energy_correction() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((12, 11, 11), spacing=0.25)
    return pdlin.BondBased(E=1.0, surface_correction="energy"), c, pdlin.find_bonds(c, ratio=2.01)


def _case_2d_force_correction_jittered() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = _jittered(2, 14)
    E = np.random.default_rng(6).uniform(1.0, 5.0, c.n)
    m = pdlin.BondBased(E=E, plane="strain", surface_correction="force-normalization")
    return m, c, pdlin.find_bonds(c, influence="delta_over_r")


CASES: dict[str, Callable[[], tuple[Any, pdlin.PointCloud, pdlin.Bonds]]] = {
    "bb-1d": _case_1d,
    "bb-2d-stress": _case_2d_stress,
    "bb-2d-strain-inverse": _case_2d_strain_inverse,
    "bb-3d": _case_3d,
    "bb-2d-variable-horizon-graded": _case_2d_variable_horizon,
    "bb-3d-per-bond-micromodulus": _case_3d_per_bond_micromodulus,
    "bb-2d-volume-correction": _case_2d_volume_correction,
    "bb-3d-energy-correction": _case_3d_energy_correction,
    "bb-2d-force-correction-jittered-graded": _case_2d_force_correction_jittered,
    "corr-2d-none-anisotropic": _case_corr_2d_none,
    "corr-3d-higher-order": _case_corr_3d_higher_order,
    "corr-2d-penalty-jittered": _case_corr_2d_penalty_jittered,
}


@pytest.fixture(params=sorted(CASES), scope="module")
def case(request):
    model, cloud, bonds = CASES[request.param]()
    K = pdlin.assemble_stiffness(model, cloud, bonds)
    return model, cloud, bonds, K


def test_shape_and_blocks(case):
    model, cloud, bonds, K = case
    assert K.shape == (cloud.ndof, cloud.ndof)
    assert isinstance(K, sp.sparray | sp.spmatrix)
    assert np.all(np.isfinite(K.data))


def test_symmetric(case):
    model, cloud, bonds, K = case
    if not getattr(model, "symmetric", True):
        pytest.skip("model declares a nonsymmetric K")
    Kc = sp.csr_array(K)
    asym = sp.linalg.norm(Kc - Kc.T) / sp.linalg.norm(Kc)
    assert asym <= 1e-14


def test_rigid_body_modes_in_null_space(case):
    model, cloud, bonds, K = case
    B = pdlin.rigid_body_modes(cloud)
    kn = abs(K).sum(axis=1).max()  # infinity norm of K
    for k in range(B.shape[1]):
        r = K @ B[:, k]
        assert np.abs(r).max() <= 1e-12 * kn * np.abs(B[:, k]).max()


def test_positive_energy_on_non_rigid_fields(case, rng):
    model, cloud, bonds, K = case
    if not getattr(model, "symmetric", True):
        pytest.skip("a nonsymmetric K (e.g. XOSB 'paper', Eq. 70) is not an energy Hessian")
    B = pdlin.rigid_body_modes(cloud, orthonormal=True)
    for _ in range(5):
        u = rng.normal(size=cloud.ndof)
        u -= B @ (B.T @ u)
        e = u @ (K @ u)
        assert e > 0
        np.testing.assert_allclose(
            model.energy(cloud, bonds, u.reshape(cloud.n, -1)), 0.5 * e, rtol=1e-12
        )


def test_internal_force_matches_stiffness(case, rng):
    model, cloud, bonds, K = case
    u = rng.normal(size=(cloud.n, cloud.dim))
    f = model.internal_force(cloud, bonds, u)
    np.testing.assert_allclose(K @ u.ravel(), -f.ravel(), rtol=1e-12, atol=1e-12 * np.abs(f).max())


def test_nonlinear_force_linearizes_to_K(case, rng):
    model, cloud, bonds, K = case
    scale = 1e-7 * float(np.median(cloud.spacing))
    u = scale * rng.normal(size=(cloud.n, cloud.dim))
    f_nl = model.internal_force(cloud, bonds, u, linear=False)
    ku = K @ u.ravel()
    err = np.linalg.norm(f_nl.ravel() + ku) / np.linalg.norm(ku)
    assert err < 1e-5  # second-order remainder, O(|u| / h) ~ 1e-7


def test_affine_fields_give_zero_force_on_complete_families(case, rng):
    model, cloud, bonds, K = case
    d = cloud.dim
    H = rng.normal(size=(d, d)) * 1e-3
    u = cloud.points @ H.T
    f = model.internal_force(cloud, bonds, u)
    # complete family (and complete neighbour families for two-hop models): the point is
    # at least coupling_range horizons inside the box; surface-corrected bonds depend on
    # the families of both ends, one horizon more
    lo, hi = cloud.bounds
    hops = getattr(model, "coupling_range", 1)
    if getattr(model, "surface_correction", None) is not None:
        hops += 1
    reach = hops * bonds.horizon.max() * (1 + 1e-9) + 0.5 * cloud.spacing.max()
    inner = np.all((cloud.points - lo > reach) & (hi - cloud.points > reach), axis=1)
    if bonds.horizon.min() != bonds.horizon.max() or not inner.any():
        pytest.skip("no lattice-complete families in this case")
    scale = np.abs(f).max()
    assert np.abs(f[inner]).max() <= 1e-12 * scale


def test_deformation_gradient_exact_for_affine_fields(case, rng):
    model, cloud, bonds, K = case
    d = cloud.dim
    H = rng.normal(size=(d, d)) * 1e-2
    u = cloud.points @ H.T + rng.normal(size=d)
    F = deformation_gradient(cloud, bonds, u)
    np.testing.assert_allclose(F, np.broadcast_to(np.eye(d) + H, F.shape), atol=1e-12)
