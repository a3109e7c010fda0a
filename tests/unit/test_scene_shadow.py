"""[shadow] tables: the correspondence stress formulation (whole frame) and displacement
layers on chosen faces (any model), as used by correspondence sweeps of scene files."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import pdlin
from pdlin.errors import SceneError
from pdlin.io.scene import scene_from_dict

# uniaxial stress along x for E = 1, nu = 0.3 (plane stress): eps_yy = -0.3 eps_xx
F_UNI = [[1.001, 0.0], [0.0, 1.0 - 0.3e-3]]

BASE = {
    "geometry": {"type": "grid", "shape": [40, 16], "spacing": 0.05},
    "material": {"E": 1.0, "nu": 0.3, "plane": "stress"},
    "model": {"type": "correspondence", "control": "penalty"},
    "horizon": {"ratio": 2.015},
    "shadow": {"F": F_UNI, "faces": ["x-", "x+"]},
}


@pytest.mark.parametrize("control", ["penalty", "none", "stress_points"])
def test_correspondence_shadow_faces_pull_a_bar_exactly(control):
    # faces given -> mode 'displacement', depth 2δ (coupling range 2): the ends carry the
    # affine field of uniaxial stress, lateral faces free; correspondence is consistent, so
    # the whole bar takes the affine field (closed form; round-off measured ~1e-14)
    data = copy.deepcopy(BASE)
    data["model"]["control"] = control
    sc = scene_from_dict(data)
    res = pdlin.solve(sc.problem)
    X = sc.problem.cloud.points
    exact = X @ (np.array(F_UNI) - np.eye(2)).T
    assert np.abs(res.u - exact).max() <= 1e-10 * np.abs(exact).max()
    dofs, _ = pdlin.constraints.resolve_dirichlet(sc.problem.cloud, sc.problem.dirichlet)
    held = np.unique(dofs // 2)
    # 2δ = 0.2015 deep at each end: 4 columns of 16 points per end (x < 0.2015 from a face)
    assert held.size == 2 * 4 * 16


def test_lps_displacement_layer_defaults_to_two_horizons():
    data = copy.deepcopy(BASE)
    data["model"] = {"type": "lps"}
    data["shadow"] = {"F": F_UNI}
    sc = scene_from_dict(data)
    dofs, _ = pdlin.constraints.resolve_dirichlet(sc.problem.cloud, sc.problem.dirichlet)
    # every face, 2δ = 0.2015 deep: the free core is (40 - 8) x (16 - 8) points
    assert 40 * 16 - np.unique(dofs // 2).size == 32 * 8
    res = pdlin.solve(sc.problem)
    X = sc.problem.cloud.points
    exact = X @ (np.array(F_UNI) - np.eye(2)).T
    assert np.abs(res.u - exact).max() <= 1e-10 * np.abs(exact).max()  # interior patch test


def test_correspondence_whole_frame_keeps_the_stress_formulation():
    data = copy.deepcopy(BASE)
    data["shadow"] = {"F": F_UNI}
    data["geometry"]["shape"] = [40, 16]
    sc = scene_from_dict(data)
    assert sc.problem.model.shadow is not None  # spec 000 §7 shadow problem
    assert len(sc.problem.loads) == 1  # the shadow-stress force


@pytest.mark.parametrize(
    "shadow, match",
    [
        ({"F": F_UNI, "faces": ["x-"], "mode": "stress"}, "needs the whole frame"),
        ({"F": F_UNI, "mode": "traction"}, "shadow.mode must be"),
    ],
)
def test_shadow_mode_errors(shadow, match):
    data = copy.deepcopy(BASE)
    data["shadow"] = shadow
    with pytest.raises(SceneError, match=match):
        scene_from_dict(data)


def test_stress_mode_needs_correspondence():
    data = copy.deepcopy(BASE)
    data["model"] = {"type": "lps"}
    data["shadow"] = {"F": F_UNI, "mode": "stress"}
    with pytest.raises(SceneError, match="use 'displacement'"):
        scene_from_dict(data)
