"""Isotropic constants as users have them: (E, ν), (K, G), Lamé — issue 15 item 5."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.constitutive import isotropic_constants
from pdlin.errors import InputError, ModelError

# steel-like constants: E = 200, ν = 0.3 -> K = E / (3 (1 - 2ν)) = 166.67,
# G = E / (2 (1 + ν)) = 76.92, λ = E ν / ((1 + ν)(1 - 2ν)) = 115.38 (closed forms)
E0, NU0 = 200.0, 0.3
K0 = E0 / (3 * (1 - 2 * NU0))
G0 = E0 / (2 * (1 + NU0))
L0 = E0 * NU0 / ((1 + NU0) * (1 - 2 * NU0))

PAIRS = [
    {"E": E0, "nu": NU0},
    {"K": K0, "G": G0},
    {"lam": L0, "mu": G0},
    {"E": E0, "K": K0},
    {"E": E0, "G": G0},
    {"E": E0, "lam": L0},
    {"nu": NU0, "K": K0},
    {"nu": NU0, "G": G0},
    {"nu": NU0, "lam": L0},
    {"K": K0, "lam": L0},
    {"G": G0, "lam": L0},
]


@pytest.mark.parametrize("pair", PAIRS, ids=lambda p: "-".join(p))
def test_every_pair_gives_e_and_nu(pair):
    E, nu = isotropic_constants(**pair)
    np.testing.assert_allclose([E, nu], [E0, NU0], rtol=1e-12)


def test_per_point_constants_and_consistent_extras():
    K = np.array([1.0, 2.0, 4.0])
    E, nu = isotropic_constants(K=K, G=0.6 * K)
    # ν = (3K - 2G) / (2 (3K + G)) = (3 - 1.2) / (2 * 3.6) = 0.25 for G = 0.6 K
    np.testing.assert_allclose(nu, 0.25, rtol=1e-14)
    np.testing.assert_allclose(E, 9 * K * 0.6 * K / (3 * K + 0.6 * K), rtol=1e-14)
    assert isotropic_constants(E=E0, nu=NU0, K=K0, G=G0, mu=G0) == pytest.approx((E0, NU0))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"K": 1.0}, "needs two of E, nu, K"),
        ({}, "got 0: none"),
        ({"E": 1.0, "nu": 0.25, "K": 1.0}, "inconsistent isotropic constants: K = 1"),
        ({"G": 1.0, "mu": 2.0}, "mu and G are the same shear modulus"),
        ({"K": -1.0, "G": 1.0}, "not positive definite"),
        ({"E": 1.0, "nu": 0.5}, "do not determine finite"),
        ({"E": np.nan, "nu": 0.25}, "E must be finite"),
    ],
)
def test_bad_constant_sets_raise(kwargs, match):
    with pytest.raises(InputError, match=match):
        isotropic_constants(**kwargs)


def _bar3d():
    cloud = pdlin.grid((6, 5, 5), spacing=0.1)
    return cloud, pdlin.find_bonds(cloud, ratio=2.015)


# the small block leaves some XOSB corner λ systems ill-conditioned (warned); irrelevant here
@pytest.mark.filterwarnings("ignore:XOSB")
@pytest.mark.parametrize("cls", [pdlin.LPS, pdlin.XOSB])
def test_state_based_models_take_k_g_and_lame(cls):
    cloud, bonds = _bar3d()
    ref = pdlin.assemble_stiffness(cls(E0, NU0), cloud, bonds).toarray()
    for kw in ({"K": K0, "G": G0}, {"lam": L0, "mu": G0}):
        K = pdlin.assemble_stiffness(cls(**kw), cloud, bonds).toarray()
        np.testing.assert_allclose(K, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    with pytest.raises(InputError, match=f"{cls.__name__} needs E and nu"):
        cls(E=E0)
    with pytest.raises(InputError, match="inconsistent"):
        cls(E=E0, nu=NU0, K=2 * K0)
    with pytest.raises(InputError, match="one Poisson ratio for all points"):
        cls(K=np.array([1.0, 1.0]), G=np.array([0.5, 0.6]))


def test_correspondence_takes_k_g():
    cloud, bonds = _bar3d()
    ref = pdlin.assemble_stiffness(pdlin.Correspondence(E=E0, nu=NU0), cloud, bonds)
    K = pdlin.assemble_stiffness(pdlin.Correspondence(K=K0, G=G0), cloud, bonds)
    np.testing.assert_allclose(K.toarray(), ref.toarray(), rtol=1e-12, atol=1e-9)
    with pytest.raises(InputError, match="C and K"):
        pdlin.Correspondence(np.eye(6), K=K0, G=G0)


def test_bond_based_single_modulus_uses_implied_nu():
    cloud, bonds = _bar3d()
    # 3D bond-based implies ν = 1/4: E = 3 K (1 - 2ν) = 1.5 K and E = 2 G (1 + ν) = 2.5 G
    ref = pdlin.assemble_stiffness(pdlin.BondBased(E=3.0), cloud, bonds).toarray()
    for model in (pdlin.BondBased(K=2.0), pdlin.BondBased(G=1.2), pdlin.BondBased(K=2.0, G=1.2)):
        K = pdlin.assemble_stiffness(model, cloud, bonds).toarray()
        np.testing.assert_allclose(K, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    # two constants fix ν, which must be the implied one
    with pytest.raises(ModelError, match="implies nu = 0.25 in 3D, got nu = 0.3"):
        pdlin.assemble_stiffness(pdlin.BondBased(K=K0, G=G0), cloud, bonds)
    with pytest.raises(InputError, match="either elastic constants or an explicit micromodulus"):
        pdlin.BondBased(K=1.0, micromodulus=2.0)
    line = pdlin.grid((5,), spacing=0.1)
    with pytest.raises(ModelError, match="1D bond-based model needs E"):
        pdlin.assemble_stiffness(pdlin.BondBased(K=1.0), line, pdlin.find_bonds(line, ratio=2.0))
