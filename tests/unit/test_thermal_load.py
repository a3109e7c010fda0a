"""The thermal load's plumbing: scene key, load vector, results, drivers that refuse it."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.constraints import thermal_load
from pdlin.errors import InputError, SceneError
from pdlin.models.thermal import ThermalExpansion, thermal_force
from pdlin.scene import scene_from_dict


def _scene(thermal: dict) -> dict:
    return {
        "geometry": {"type": "grid", "shape": [10, 6], "spacing": 0.1},
        "material": {"E": 1.0, "nu": 0.25},
        "model": {"type": "lps"},
        "horizon": {"ratio": 3.015},
        "dirichlet": [{"points": [0], "value": 0.0}, {"points": [54], "components": "y",
                                                       "value": 0.0}],
        "thermal": thermal,
    }  # fmt: skip


def test_scene_thermal_key_uniform_and_expression() -> None:
    scene = scene_from_dict(_scene({"alpha": 2e-5, "temperature_change": 50.0}))
    th = scene.problem.thermal
    assert isinstance(th, ThermalExpansion)
    res = pdlin.solve(scene.problem, solver="direct")
    x = scene.cloud.points
    # free expansion α ΔT (x - x_0) about the pinned point 0 (closed form)
    assert np.abs(res.u - 1e-3 * (x - x[0])).max() < 1e-12
    scene = scene_from_dict(_scene({"alpha": 2e-5, "temperature_change": "50 + 100 * x"}))
    assert np.allclose(scene.problem.thermal.temperature(scene.cloud), 50 + 100 * x[:, 0])


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ({"alpha": 1e-5}, r"temperature_change"),
        ({"temperature_change": 1.0}, r"alpha"),
        ({"alpha": 1e-5, "temperature_change": 1.0, "T0": 3}, r"thermal.*T0"),
        ({"alpha": "x", "temperature_change": 1.0}, r"thermal.alpha"),
        ({"alpha": 1e-5, "temperature_change": "import os"}, r"thermal.temperature_change"),
    ],
)
def test_scene_thermal_key_errors(table: dict, match: str) -> None:
    with pytest.raises(SceneError, match=match):
        scene_from_dict(_scene(table))


def test_thermal_load_is_self_equilibrated_and_linear() -> None:
    cloud = pdlin.grid((8, 5, 4), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.015)
    dT = np.random.default_rng(0).uniform(-50, 50, cloud.n)
    for model in (pdlin.BondBased(E=1.0), pdlin.LPS(E=1.0, nu=0.3),
                  pdlin.Correspondence(E=1.0, nu=0.3)):  # fmt: skip
        f1 = thermal_force(model, cloud, bonds, ThermalExpansion(dT, 1e-5))
        f2 = thermal_force(model, cloud, bonds, ThermalExpansion(2 * dT, 1e-5))
        assert np.abs(f1.sum(axis=0)).max() < 1e-12 * np.abs(f1).max()  # no net force
        assert np.allclose(f2, 2 * f1, rtol=1e-12, atol=0)
        # no net moment either (pairwise central forces / a symmetric stress)
        m = np.cross(cloud.points, f1).sum(axis=0)
        assert np.abs(m).max() < 1e-10 * np.abs(f1).max()
    with pytest.raises(InputError, match="thermal needs the bonds"):
        thermal_load(pdlin.BondBased(E=1.0), cloud, None, ThermalExpansion(1.0, 1.0))


def test_per_point_alpha_and_no_change_is_no_load() -> None:
    cloud = pdlin.grid((6, 6), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    model = pdlin.LPS(E=1.0, nu=0.25)
    assert not thermal_force(model, cloud, bonds, ThermalExpansion(0.0, 1e-5)).any()
    a = np.where(cloud.points[:, 0] < 0.25, 1e-5, 2e-5)  # two blocks
    f = thermal_force(model, cloud, bonds, ThermalExpansion(10.0, a))
    g = thermal_force(model, cloud, bonds, ThermalExpansion(10.0 * a / 1e-5, 1e-5))
    assert np.array_equal(f, g)  # only α ΔT counts


def test_result_repr_and_fields_without_thermal_unchanged() -> None:
    cloud = pdlin.grid((6, 4), spacing=0.1)
    prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, ratio=3.015,
                               dirichlet=[pdlin.Dirichlet("x-", 0.0),
                                          pdlin.Dirichlet("x+", [1e-3, 0.0])])  # fmt: skip
    res = pdlin.solve(prob, solver="direct")
    assert prob.thermal is None and "thermal" not in repr(prob)
    F = res.deformation_gradient()
    assert np.array_equal(res.strain(), 0.5 * (F + np.swapaxes(F, 1, 2)) - np.eye(2))


def test_drivers_without_thermal_support_refuse_it() -> None:
    cloud = pdlin.grid((8, 4), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0), cloud, ratio=3.015, dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        thermal=ThermalExpansion(10.0, 1e-5),
    )  # fmt: skip
    with pytest.raises(InputError, match="solve_nonlinear does not take thermal"):
        pdlin.solve_nonlinear(prob, steps=1)
    with pytest.raises(InputError, match="solve_damage does not take thermal"):
        pdlin.solve_damage(prob, 0.01)
    from pdlin.submodeling import subregion

    with pytest.raises(InputError, match="subregion does not take thermal"):
        subregion(prob, [[0.2, 0.0], [0.5, 0.4]], None)
