"""Sub-regions (global-local): a coarse solve drives a fine box (pdlin.subregion)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pdlin
from pdlin.constraints import load_vector
from pdlin.errors import InputError, SceneError, ShapeError
from pdlin.io.scene import scene_from_dict
from pdlin.submodeling import subregion
from pdlin.sweeps.core import interpolate_field

F2 = np.array([[1.001, 0.0002], [0.0003, 0.9997]])


def _affine_problem(model, shape=(30, 20), h=0.05, ratio=2.015):
    cloud = pdlin.grid(shape, spacing=h)
    bc = pdlin.Dirichlet.affine("boundary", F2)
    return pdlin.StaticProblem(model, cloud, bond_options={"ratio": ratio}, dirichlet=[bc])


@pytest.mark.parametrize(
    "model",
    [
        pdlin.Correspondence(E=1.0, nu=0.3, plane="stress"),
        pdlin.LPS(E=1.0, nu=0.3, plane="stress"),
        pdlin.BondBased(E=1.0, plane="stress"),
    ],
    ids=["correspondence", "lps", "bond_based"],
)
def test_affine_driver_gives_the_affine_field_exactly(model):
    # a consistent driver (the affine field itself) on a layer of coupling_range x δ: every
    # free point sees the same neighbours (and neighbours' families) as in the whole body,
    # where the affine field is the solution (interior patch test; 1e-12 = round-off)
    prob = _affine_problem(model)
    exact = lambda X: X @ (F2 - np.eye(2)).T  # noqa: E731
    sub = subregion(prob, [[0.5, 0.3], [1.0, 0.7]], exact)
    delta = 2.015 * 0.05
    assert sub.layer == pytest.approx(delta * model.coupling_range)
    res = pdlin.solve(sub.problem)
    X = sub.problem.cloud.points
    assert np.abs(res.u - exact(X)).max() <= 1e-12 * np.abs(exact(X)).max()
    assert sub.problem.cloud.n < prob.cloud.n


def test_too_thin_layer_breaks_the_patch_test_for_two_hop_models():
    # the reason for the default: with one horizon only, the correspondence forces on the
    # free points next to the layer use truncated neighbour families (measured 5.5e-2 max
    # relative error, 2026-11-25)
    prob = _affine_problem(pdlin.Correspondence(E=1.0, nu=0.3, plane="stress"))
    exact = lambda X: X @ (F2 - np.eye(2)).T  # noqa: E731
    sub = subregion(prob, [[0.5, 0.3], [1.0, 0.7]], exact, layer=2.015 * 0.05)
    res = pdlin.solve(sub.problem)
    X = sub.problem.cloud.points
    assert np.abs(res.u - exact(X)).max() > 1e-2 * np.abs(exact(X)).max()


def test_coarse_solution_driver_is_interpolated_and_matches_the_fine_solve():
    # bond-based plate clamped at x- and pulled at x+: the box is driven by a 2h solve; inside
    # it the answer follows the fine whole-body solve within the coarse run's own error
    def plate(h):
        cloud = pdlin.grid((int(round(2 / h)), int(round(1 / h))), spacing=h)
        return pdlin.StaticProblem(
            pdlin.BondBased(E=1.0, plane="stress"),
            cloud,
            bond_options={"ratio": 3.015},
            dirichlet=[pdlin.Dirichlet("x-", 0.0)],
            loads=[pdlin.TotalForce("x+", [1e-2, 0.0])],
        )

    fine, coarse = plate(0.025), plate(0.05)
    rc, rf = pdlin.solve(coarse), pdlin.solve(fine)
    sub = subregion(fine, [[0.8, 0.3], [1.2, 0.7]], rc)
    rs = pdlin.solve(sub.problem)
    X = sub.problem.cloud.points[sub.interior]
    u_full = interpolate_field(fine.cloud.points, rf.u, X)
    u_coarse = interpolate_field(coarse.cloud.points, rc.u, X)
    err_sub = np.abs(rs.u[sub.interior] - u_full).max() / np.abs(u_full).max()
    err_coarse = np.abs(u_coarse - u_full).max() / np.abs(u_full).max()
    # measured 2026-11-25: 2.83e-2 for both; the coarse run's error here is global (the
    # bond-based surface effect at a coarser δ), so the box inherits it — no worse, no better
    assert err_sub < 0.05
    assert err_sub <= 1.01 * err_coarse
    # the loads of the whole body act through the driver; the box itself carries none
    assert len(sub.problem.loads) == 0


def test_conditions_of_the_body_win_over_the_driver_in_the_layer():
    # a box at the clamped edge: the layer points on x- keep u = 0 whatever the driver says
    prob = _affine_problem(pdlin.BondBased(E=1.0, plane="stress"))
    prob = pdlin.StaticProblem(
        prob.model, prob.cloud, bond_options={"ratio": 2.015},
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.BodyForce("all", [1.0, 0.0])],
    )  # fmt: skip
    sub = subregion(prob, [[0.1, 0.3], [0.6, 0.7]], lambda X: np.ones_like(X))
    dofs, vals = pdlin.constraints.resolve_dirichlet(sub.problem.cloud, sub.problem.dirichlet)
    on_edge = np.flatnonzero(sub.problem.cloud.points[:, 0] < 0.05)
    assert on_edge.size
    u = np.full(sub.problem.cloud.n * 2, np.nan)
    u[dofs] = vals
    assert np.all(u.reshape(-1, 2)[on_edge] == 0.0)
    # the body force on the free points is kept as nodal forces (same total)
    f_sub = pdlin.constraints.load_vector(sub.problem.cloud, sub.problem.loads).reshape(-1, 2)
    V = sub.problem.cloud.volumes[sub.interior]
    assert f_sub[sub.interior, 0] == pytest.approx(V * prob.cloud.thickness)


@pytest.mark.parametrize(
    "kwargs, err, match",
    [
        ({"box": [[0.5, 0.3]]}, ShapeError, r"box must have shape \(2, 2\)"),
        ({"box": [[0.5, 0.3], [0.4, 0.7]]}, InputError, "upper corner must exceed"),
        ({"box": [[5.0, 5.0], [6.0, 6.0]]}, InputError, "contains no point"),
        ({"box": [[-1.0, -1.0], [5.0, 5.0]]}, InputError, "contain the whole cloud"),
        ({"layer": -1.0}, InputError, "layer must be a positive number"),
        ({"driver": "coarse"}, InputError, "driver must be a callable"),
        ({"driver": lambda X: X[:, :1]}, ShapeError, "driver must give finite"),
    ],
)
def test_bad_arguments_name_themselves(kwargs, err, match):
    prob = _affine_problem(pdlin.BondBased(E=1.0, plane="stress"))
    args = {"box": [[0.5, 0.3], [1.0, 0.7]], "driver": lambda X: 0 * X, **kwargs}
    with pytest.raises(err, match=match):
        subregion(prob, args.pop("box"), args.pop("driver"), **args)


def test_models_with_per_point_data_are_refused():
    cloud = pdlin.grid((10, 10), spacing=0.1)
    theta = np.zeros(cloud.n)
    model = pdlin.Correspondence(material=pdlin.CrystalPlasticity(orientation=theta))
    prob = pdlin.StaticProblem(model, cloud, bond_options={"ratio": 1.0})
    with pytest.raises(InputError, match="one value per point or bond"):
        subregion(prob, [[0.2, 0.2], [0.5, 0.5]], lambda X: 0 * X)


SCENE = {
    "name": "plate_sub",
    "geometry": {"type": "grid", "shape": [80, 40], "spacing": 0.025},
    "material": {"E": 1.0, "nu": 0.3, "plane": "stress"},
    "model": {"type": "correspondence", "control": "penalty"},
    "horizon": {"ratio": 2.015},
    "dirichlet": [{"set": "x-", "value": 0.0}],
    "load": [{"type": "total", "set": "x+", "force": [0.01, 0.0]}],
    "subregion": {"box": [[0.8, 0.3], [1.2, 0.7]]},
}


def test_scene_subregion_table_and_cli(tmp_path, capsys):
    import copy

    from pdlin.cli.main import main

    sc = scene_from_dict(copy.deepcopy(SCENE))
    info = sc.subregion
    # 16 x 16 free points, a 2δ layer (coupling range 2): 24 x 24 kept; 800-point driver
    assert (info["free_points"], info["points"], info["coarse_points"]) == (256, 576, 800)
    assert info["whole_body_points"] == 3200 and info["coarse_spacing"] == pytest.approx(0.05)
    res = pdlin.solve(sc.problem)
    full_data = {k: v for k, v in copy.deepcopy(SCENE).items() if k != "subregion"}
    full = scene_from_dict(full_data)
    rf = pdlin.solve(full.problem)
    X = sc.problem.cloud.points[info["interior"]]
    uf = interpolate_field(full.problem.cloud.points, rf.u, X)
    err = np.abs(res.u[info["interior"]] - uf).max() / np.abs(uf).max()
    assert err < 0.04  # measured 2.1e-2: the 2h driver's own error (2026-11-25)
    path = tmp_path / "sub.toml"
    path.write_text(_toml(SCENE))
    assert main(["run", str(path), "-o", str(tmp_path / "sub.vtu"), "-q"]) == 0
    out = capsys.readouterr().out
    assert "subregion    256 free + 320 driven of 3,200 points" in out
    assert (tmp_path / "sub.vtu").exists()


@pytest.mark.parametrize(
    "edit, match",
    [
        ({"subregion": {"box": [[0.8, 0.3], [1.2, 0.7]], "coarsen": 2}}, "subregion.coarsen"),
        ({"subregion": {"coarse": 0.5, "box": [[0.8, 0.3], [1.2, 0.7]]}}, "coarse must be"),
        ({"subregion": {"coarse": 2.0}}, "subregion.*box"),
        ({"subregion": {"box": [[0.8, 0.3], [0.7, 0.7]]}}, "subregion: box upper corner"),
        ({"symmetry": [{"axis": "y", "position": 0.0}]}, "cannot be combined with symmetry"),
        ({"dirichlet": [{"points": [0], "value": 0.0}]}, r"subregion.coarse: .*points"),
    ],
)
def test_scene_subregion_errors_name_the_key(edit, match):
    import copy

    data = copy.deepcopy(SCENE)
    data.update(edit)
    with pytest.raises(SceneError, match=match):
        scene_from_dict(data)


def _toml(data):
    lines = []

    def val(v):
        return json.dumps(v)

    for k, v in data.items():
        if not isinstance(v, dict | list):
            lines.append(f"{k} = {val(v)}")
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append(f"[{k}]")
            lines += [f"{a} = {val(b)}" for a, b in v.items()]
        elif isinstance(v, list):
            for item in v:
                lines.append(f"[[{k}]]")
                lines += [f"{a} = {val(b)}" for a, b in item.items()]
    return "\n".join(lines) + "\n"


def test_load_on_the_supported_part_of_a_box_is_dropped_not_refused():
    """A body force over the whole plate, clamped on x-: a box around the clamped corner
    whose interior holds only clamped points (the x- column) keeps none of the load on free DOFs;
    the sub-problem drops the entries on its prescribed DOFs (they go into the support's
    reaction) instead of refusing the cut as a load acting only on prescribed DOFs."""
    cloud = pdlin.grid((10, 10), spacing=0.1)
    bf = pdlin.BodyForce("all", [0.0, -1.0])
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[bf],
    )
    whole = pdlin.solve(prob)
    box = [[0.0, 0.0], [0.06, 0.35]]  # the x- column (x = 0.05)'s lowest points: all clamped
    sub = subregion(prob, box, whole)
    assert sub.interior.sum() > 0
    res = pdlin.solve(sub.problem)
    np.testing.assert_allclose(res.u, whole.u[sub.index], atol=1e-12)
    # the reaction bookkeeping: the box's supports carry the whole body's reaction plus the
    # load left out (R = -(f_int + f_ext) on prescribed DOFs, pdlin.system)
    f = load_vector(cloud, [bf]).reshape(cloud.n, 2)[sub.index]
    inner = sub.interior
    np.testing.assert_allclose(
        res.reactions[inner], whole.reactions[sub.index[inner]] + f[inner], atol=1e-12
    )
    # a box with free loaded points keeps their load: the fine solve reproduces the whole
    box2 = [[0.0, 0.0], [0.45, 0.45]]
    sub2 = subregion(prob, box2, whole)
    res2 = pdlin.solve(sub2.problem)
    inner = sub2.interior
    np.testing.assert_allclose(res2.u[inner], whole.u[sub2.index[inner]], rtol=1e-8, atol=1e-12)
