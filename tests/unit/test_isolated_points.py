"""Points without bonds (``find_bonds(allow_isolated=True)``): held at rest, or refused."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError, NoNeighborsError
from pdlin.static import solve_steps


def _clouds(dim: int = 2):
    """A grid and the same grid plus two far points (indices n, n + 1)."""
    shape = (10, 4) if dim == 2 else (6, 4, 4)
    grid = pdlin.grid(shape, spacing=0.1)
    far = np.full((2, dim), 3.0)
    far[1, 0] = 4.0
    pts = np.vstack([grid.points, far])
    vol = np.full(pts.shape[0], 0.1**dim)
    return grid, pdlin.PointCloud(pts, vol, thickness=grid.thickness)


def _conditions(points: np.ndarray, n_grid: int):
    left = np.flatnonzero(points[:n_grid, 0] < 0.1)
    right = np.flatnonzero(points[:n_grid, 0] > points[:n_grid, 0].max() - 0.1)
    d = points.shape[1]
    force = np.zeros(d)
    force[0] = 1e-3
    return [pdlin.Dirichlet(left, 0.0)], [pdlin.TotalForce(right, force)]


MODELS = [
    pdlin.BondBased(E=1.0),
    pdlin.LPS(E=1.0, nu=0.25),
    pdlin.Correspondence(E=1.0, nu=0.25),
]


@pytest.mark.parametrize("model", MODELS, ids=lambda m: type(m).__name__)
def test_unloaded_isolated_points_rest_and_the_rest_is_unchanged(model, caplog):
    grid, cloud = _clouds()
    bc, loads = _conditions(grid.points, grid.n)
    ref = pdlin.solve(pdlin.StaticProblem(model, grid, ratio=3.015, dirichlet=bc, loads=loads))
    prob = pdlin.StaticProblem(
        model, cloud, horizon=0.3015, bond_options={"allow_isolated": True}, dirichlet=bc,
        loads=loads,
    )  # fmt: skip
    with caplog.at_level("WARNING", logger="pdlin.system"):
        res = pdlin.solve(prob, solver="direct")
    assert res.info["isolated_points"] == [grid.n, grid.n + 1]
    assert "2 point(s) without bonds held at rest" in caplog.text
    assert not res.u[grid.n :].any()
    assert np.allclose(res.u[: grid.n], ref.u, rtol=1e-10, atol=1e-16)
    assert not res.stress()[grid.n :].any()
    F = res.deformation_gradient()
    assert np.array_equal(F[grid.n :], np.broadcast_to(np.eye(2), (2, 2, 2)))
    assert res.fields()["family_size"][grid.n :].tolist() == [0.0, 0.0]
    assert np.isfinite(res.reactions).all() and not res.reactions[grid.n :].any()


def test_prescribed_isolated_point_moves_and_loaded_one_raises():
    grid, cloud = _clouds()
    bc, loads = _conditions(grid.points, grid.n)
    model = pdlin.LPS(E=1.0, nu=0.25)
    opts = {"allow_isolated": True}
    moved = [*bc, pdlin.Dirichlet([grid.n], [0.5, 0.0], components="x")]
    res = pdlin.solve(
        pdlin.StaticProblem(model, cloud, horizon=0.3015, bond_options=opts, dirichlet=moved,
                            loads=loads),
        solver="direct",
    )  # fmt: skip
    assert res.u[grid.n].tolist() == [0.5, 0.0]  # x prescribed, y held at rest
    bad = [*loads, pdlin.TotalForce([grid.n + 1], [0.0, 1.0])]
    with pytest.raises(
        NoNeighborsError,
        match=rf"loads act on 1 point\(s\) without bonds.*{grid.n + 1} at \[4.0, 3.0\]",
    ):
        pdlin.solve(pdlin.StaticProblem(model, cloud, horizon=0.3015, bond_options=opts,
                                        dirichlet=bc, loads=bad))  # fmt: skip
    # without allow_isolated the bond search refuses them, as before
    with pytest.raises(NoNeighborsError, match="allow_isolated=True"):
        pdlin.solve(pdlin.StaticProblem(model, cloud, horizon=0.3015, dirichlet=bc, loads=loads))
    with pytest.raises(InputError, match="without bonds"):
        pdlin.solve_nonlinear(
            pdlin.StaticProblem(model, cloud, horizon=0.3015, bond_options=opts, dirichlet=bc,
                                loads=loads), steps=1,
        )  # fmt: skip


def test_isolated_points_matrix_free_and_steps():
    grid, cloud = _clouds(3)
    bc, loads = _conditions(grid.points, grid.n)
    model = pdlin.LPS(E=1.0, nu=0.25)
    opts = {"allow_isolated": True}
    prob = pdlin.StaticProblem(model, cloud, horizon=0.2015, bond_options=opts, dirichlet=bc,
                               loads=loads)  # fmt: skip
    direct = pdlin.solve(prob, solver="direct")
    mf = pdlin.solve(prob, solver="amg-cg", operator="matrix-free", rtol=1e-10)
    assert mf.info["operator"] == "matrix-free" and mf.info["isolated_points"] == [96, 97]
    assert np.allclose(mf.u, direct.u, rtol=0, atol=1e-8 * np.abs(direct.u).max())
    steps = [
        pdlin.StaticProblem(model, cloud, horizon=0.2015, bond_options=opts, dirichlet=bc,
                            loads=[pdlin.TotalForce(loads[0].where, f * loads[0].force)])
        for f in (0.5, 1.0)
    ]  # fmt: skip
    res = solve_steps(steps, solver="direct")
    assert res[1].info["setup_reused"]
    assert np.array_equal(res[1].u, direct.u)


def test_isolated_points_with_a_thermal_load():
    """A heated body beside isolated points: the body expands freely, they stay put."""
    from pdlin.models.thermal import ThermalExpansion

    grid, cloud = _clouds()
    x = cloud.points
    eps = 1e-5 * 100.0
    pins = [pdlin.Dirichlet([0], eps * x[0]), pdlin.Dirichlet([36], eps * x[36])]
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.25), cloud, horizon=0.3015, bond_options={"allow_isolated": True},
        dirichlet=pins, thermal=ThermalExpansion(100.0, np.full(cloud.n, 1e-5)),
    )  # fmt: skip
    res = pdlin.solve(prob, solver="direct")
    assert np.abs(res.u[: grid.n] - eps * x[: grid.n]).max() < 1e-12  # α ΔT x (closed form)
    assert not res.u[grid.n :].any()
    assert np.abs(res.stress()).max() < 1e-12
