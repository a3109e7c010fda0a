"""Surface corrections of BondBased and LPS (Le & Bobaru 2018) against closed forms.

Problems of :mod:`pdlin.verification.surface` at δ = 3.015 h (the repository's usual
"3h" ratio, off the lattice ties): a 20 x 4 x 4 bar in tension, a 40 x 20 plate in
uniaxial tension and a 30 x 30 block in pure shear.  Errors are signed, relative to the
closed form, positive when the model is too soft.  Bounds marked "measured" were measured
on this implementation (benchmarks/surface_correction.py prints the table) and carry one
percentage point of slack, so a change that worsens an error by more than that fails.
"""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError
from pdlin.verification.surface import (
    plate_tension_errors,
    shear_block_error,
    tension_bar_error,
)

CORRECTIONS = ("volume", "energy", "force-normalization")


def _model(kind: str, sc: str | None):
    if kind == "bb":
        return pdlin.BondBased(E=1.0, surface_correction=sc)
    return pdlin.LPS(E=1.0, nu=0.3, surface_correction=sc)


# measured uncorrected bar errors: BB +49.2 %, LPS (analytic m) +64.3 %; the 4 x 4 section
# is narrower than 2δ, so every point has a truncated family and the bar is far too soft
BAR_UNCORRECTED_MIN = {"bb": 0.45, "lps": 0.60}
# measured |error| + 1 point: BB volume 20.2 %, energy 7.9 %, force-normalization 6.3 %;
# LPS volume 12.2 %, energy 27.3 %, force-normalization 14.9 %
BAR_BOUND = {
    ("bb", "volume"): 0.213,
    ("bb", "energy"): 0.089,
    ("bb", "force-normalization"): 0.073,
    ("lps", "volume"): 0.132,
    ("lps", "energy"): 0.283,
    ("lps", "force-normalization"): 0.159,
}


@pytest.fixture(scope="module")
def bar_uncorrected():
    return {kind: tension_bar_error(_model(kind, None)) for kind in ("bb", "lps")}


@pytest.mark.parametrize("kind", ["bb", "lps"])
@pytest.mark.parametrize("sc", CORRECTIONS)
def test_tension_bar_elongation(kind, sc, bar_uncorrected):
    base = bar_uncorrected[kind]
    assert base > BAR_UNCORRECTED_MIN[kind], base
    err = tension_bar_error(_model(kind, sc))
    assert abs(err) <= BAR_BOUND[kind, sc], err
    # "well below": every correction at most halves the uncorrected error (measured
    # ratios 0.13 ... 0.42)
    assert abs(err) < 0.5 * abs(base), (err, base)


# measured (plate ε_xx, plate ε_yy, shear γ) errors of each model / correction
MEASURED = {
    ("bb", None): (-0.019, -0.077, 0.052),
    ("bb", "volume"): (-0.108, -0.129, 0.031),
    ("bb", "energy"): (-0.025, -0.062, 0.091),
    ("bb", "force-normalization"): (-0.066, -0.101, 0.046),
    ("lps", None): (-0.033, -0.031, 0.031),
    ("lps", "volume"): (-0.115, -0.084, 0.010),
    ("lps", "energy"): (-0.062, -0.002, 0.127),
    ("lps", "force-normalization"): (-0.069, -0.036, 0.065),
}


@pytest.mark.parametrize("kind", ["bb", "lps"])
@pytest.mark.parametrize("sc", (None, *CORRECTIONS))
def test_plate_uniaxial_tension_strains(kind, sc):
    exx, eyy = plate_tension_errors(_model(kind, sc))
    mxx, myy, _ = MEASURED[kind, sc]
    # closed form σ/E and -ν σ/E; bounds: measured |error| + 1 point
    assert abs(exx) <= abs(mxx) + 0.01, exx
    assert abs(eyy) <= abs(myy) + 0.01, eyy
    if sc is not None:  # the correction changes the answer (a no-op would pass the bounds)
        ref = plate_tension_errors(_model(kind, None))
        assert abs(exx - ref[0]) > 3e-3


@pytest.mark.parametrize("kind", ["bb", "lps"])
@pytest.mark.parametrize("sc", (None, *CORRECTIONS))
def test_shear_block(kind, sc):
    err = shear_block_error(_model(kind, sc))
    # closed form γ = τ/G; bound: measured |error| + 1 point
    assert abs(err) <= abs(MEASURED[kind, sc][2]) + 0.01, err


def test_volume_correction_improves_the_shear_block():
    # measured: BB 5.2 % -> 3.1 %, LPS 3.1 % -> 1.0 %
    for kind in ("bb", "lps"):
        base = shear_block_error(_model(kind, None))
        assert abs(shear_block_error(_model(kind, "volume"))) < 0.7 * abs(base)


def test_lps_energy_correction_fixes_the_lateral_strain():
    # measured: ε_yy error -3.1 % uncorrected, -0.2 % with the energy correction
    _, eyy = plate_tension_errors(_model("lps", "energy"))
    assert abs(eyy) < 0.005


@pytest.mark.parametrize("sc", CORRECTIONS)
def test_bond_factors_symmetric_and_interior(sc):
    cloud = pdlin.grid((14, 13), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    for model in (
        pdlin.BondBased(E=2.0, surface_correction=sc),
        pdlin.LPS(2.0, 0.3, surface_correction=sc),
    ):
        sf = model.surface_factors(cloud, bonds)
        assert sf.method == sc
        np.testing.assert_array_equal(sf.bond, sf.bond[bonds.reverse])
        assert np.all(sf.bond > 0) and np.all(np.isfinite(sf.bond))
        # the factor is cached per (cloud, bonds) and reused
        assert model.surface_factors(cloud, bonds) is sf
        # points on the edge x = 0 are corrected upwards (missing bonds)
        edge = np.isclose(cloud.points[:, 0], cloud.points[:, 0].min())
        inner = np.all(np.abs(cloud.points - cloud.points.mean(axis=0)) < 0.2, axis=1)
        assert sf.point[edge, 0].min() > sf.point[inner, 0].max()


def test_energy_correction_makes_uniaxial_modulus_exact():
    """BB energy method: g_k = C1111 / C_i,kkkk, so the corrected C_i,kkkk equals the
    continuum C1111 at every point whose neighbours share its factors (the interior)."""
    cloud = pdlin.grid((16, 16), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    model = pdlin.BondBased(E=3.0, surface_correction="energy")
    C = model.effective_tensor(cloud, bonds)
    reach = 2 * 0.3015 + 0.05
    lo, hi = cloud.bounds
    inner = np.all((cloud.points - lo > reach) & (hi - cloud.points > reach), axis=1)
    assert inner.any()
    c1111 = 3.0 / (1 - 1 / 9)  # closed form: plane stress, ν = 1/3, E/(1-ν²)
    np.testing.assert_allclose(C[inner, 0, 0, 0, 0], c1111, rtol=1e-12)
    np.testing.assert_allclose(C[inner, 1, 1, 1, 1], c1111, rtol=1e-12)
    # without the correction the lattice quadrature is 3.7 % stiff (docs/bond_based.md)
    C0 = pdlin.BondBased(E=3.0).effective_tensor(cloud, bonds)
    assert C0[inner, 0, 0, 0, 0].min() > 1.03 * c1111


def test_lps_energy_correction_energy_density_at_edges():
    """LPS energy method on a 1-direction problem: the corrected W of a point whose factors
    are isotropic is the bulk value; the uncorrected edge W is far below it."""
    cloud = pdlin.grid((20, 20), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    plain = pdlin.LPS(E=1.0, nu=0.3)
    u = cloud.points * np.array([1e-3, 0.0])
    w0 = plain.strain_energy_density(cloud, bonds, u, force_weights=True)
    corr = pdlin.LPS(E=1.0, nu=0.3, surface_correction="energy")
    w1 = corr.strain_energy_density(cloud, bonds, u, force_weights=True)
    kappa, mu = plain.moduli(2)
    bulk = 1e-6 * (kappa / 2 + mu / 2)  # closed form: κ ε²/2 + μ ε^d:ε^d, ε^d:ε^d = ε²/2
    edge = np.isclose(cloud.points[:, 1], cloud.points[:, 1].min())
    mid = edge & (np.abs(cloud.points[:, 0] - 1.0) < 0.3)
    assert np.all(np.abs(w0[mid] / bulk - 1) > 0.2)
    assert np.all(np.abs(w1[mid] / bulk - 1) < np.abs(w0[mid] / bulk - 1))


@pytest.mark.parametrize("cls", [pdlin.BondBased, pdlin.LPS])
def test_unknown_correction_names_argument_values_and_input(cls):
    with pytest.raises(InputError) as exc:
        cls(E=1.0, nu=None if cls is pdlin.BondBased else 0.3, surface_correction="energie")
    msg = str(exc.value)
    for part in (
        "surface_correction",
        "'volume'",
        "'energy'",
        "'force-normalization'",
        "'energie'",
    ):
        assert part in msg


def test_xosb_refuses_surface_correction():
    assert pdlin.XOSB(E=1.0, nu=0.3, surface_correction=None).surface_correction is None
    with pytest.raises(InputError, match="XOSB does not support surface_correction"):
        pdlin.XOSB(E=1.0, nu=0.3, surface_correction="energy")


def test_volume_correction_needs_spherical_families():
    cloud = pdlin.grid((8, 8), spacing=1.0)
    bonds = pdlin.find_bonds(cloud, 2.0, shape="cube")
    with pytest.raises(pdlin.errors.ModelError, match="spherical"):
        pdlin.BondBased(E=1.0, surface_correction="volume").stiffness(cloud, bonds)


def test_scene_key(tmp_path):
    from pdlin.scene.scene import scene_from_dict

    data = {
        "geometry": {"shape": [10, 5]},
        "material": {"E": 1.0, "nu": 0.3},
        "model": {"type": "lps", "surface_correction": "force-normalization"},
        "horizon": {"ratio": 3.015},
        "dirichlet": [{"set": "x-"}],
        "load": [{"type": "total", "set": "x+", "force": [1.0, 0.0]}],
    }
    assert scene_from_dict(data).model.surface_correction == "force-normalization"
    data["model"] = {"type": "bond_based", "surface_correction": "energy"}
    del data["material"]["nu"]
    assert scene_from_dict(data).model.surface_correction == "energy"
    data["model"]["surface_correction"] = "bogus"
    with pytest.raises(pdlin.errors.SceneError, match="surface_correction"):
        scene_from_dict(data)
