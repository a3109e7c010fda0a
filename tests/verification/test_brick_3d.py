"""Luo & Sundararaghavan (2018), Sec. 5.3: the R3D brick, correspondence PD (no control, stress
points) vs Hex8.

Setup (reconstruction R3D, docs/theory/conventions.md#brick): node grid 33 x 33 x 17 with h = 2.5 mm
on the 80 x 80 x 40 mm brick, E = 1000 MPa, ν = 0.3, nearest-neighbour bonds (ω = 1, V = h³), the
four side faces fully prescribed ``u = (ε0 (x - 40), ε0 (y - 40), 0)`` with ε0 = 0.01, top and
bottom free.  Reference: Hex8 FEM with its nodes at the particles
(:func:`pdlin.verification.fem.solve_hex8`, AMG-CG to 1e-12).  Stress points use seed 0.

The full size takes ~30 s on 2 cores (mostly the no-control AMG-CG solve), so it is marked
``slow``; the default run uses the same brick at h = 5 mm (17 x 17 x 9) with tolerances
calibrated on that grid.

AMG: ``amg_options={"strength": ("symmetric", {"theta": 0.0})}`` (pyamg's default strength
measure).  pdlin's default block-relative strength, tuned for wide horizons, needs 352 (no
control) / 107 (SP) iterations here and a 7-11 s setup, versus 330 / 91 and < 1 s.

AMG-CG is reproducible: pdlin seeds pyamg's setup (which draws spectral-radius start vectors
from numpy's global random state) and restores the caller's state.  Before that, and before
``pdlin.solve(operator="auto")`` assembled nearest-neighbour two-hop operators, some global
states gave a breakdown through the matrix-free path's bond-based surrogate, which has shear
mechanisms with axis-only bonds (fixed: the surrogate adds half its graph Laplacian ⊗ I).
``test_amg_cg_does_not_depend_on_the_global_random_state`` checks that.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import numpy as np
import pytest

import pdlin
from pdlin.verification.fem import solve_hex8

E, NU = 1000.0, 0.3  # MPa; Luo & Sundararaghavan (2018), Sec. 5.3
EPS0 = 0.01  # ε0 = Δ/d = 0.4 mm / 40 mm (Sec. 5.3's increment Δ; conventions.md#brick)
AMG = {"strength": ("symmetric", {"theta": 0.0})}
SEED = 1  # numpy global random state for pyamg's setup (see the module docstring)


def _node_grid_hexes(shape: tuple[int, int, int]) -> np.ndarray:
    """Hexahedra (meshio order) on the C-ordered node grid of :func:`pdlin.grid`."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    i, j, k = (a.ravel() for a in np.indices(tuple(s - 1 for s in shape)))
    return np.stack(
        [
            idx[i, j, k],
            idx[i + 1, j, k],
            idx[i + 1, j + 1, k],
            idx[i, j + 1, k],
            idx[i, j, k + 1],
            idx[i + 1, j, k + 1],
            idx[i + 1, j + 1, k + 1],
            idx[i, j + 1, k + 1],
        ],
        axis=1,
    )


@contextlib.contextmanager
def _global_random_state(seed: int) -> Iterator[None]:
    """Fix numpy's global random state (used by pyamg's setup), then restore it."""
    saved = np.random.get_state()  # noqa: NPY002 - pyamg draws from the legacy global state
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(saved)  # noqa: NPY002


def _dirichlet_problem(n_xy: int, n_z: int) -> tuple:
    h = 80.0 / (n_xy - 1)
    assert np.isclose(h * (n_z - 1), 40.0)
    # pdlin.grid is cell-centred: shift by h/2 so the nodes sit at 0, h, ..., 80
    cloud = pdlin.grid((n_xy, n_xy, n_z), spacing=h, origin=(-h / 2,) * 3)
    p = cloud.points
    side = np.flatnonzero(
        np.isclose(p[:, 0], 0) | np.isclose(p[:, 0], 80) | np.isclose(p[:, 1], 0)
        | np.isclose(p[:, 1], 80)
    )  # fmt: skip
    ub = np.column_stack([EPS0 * (p[:, 0] - 40), EPS0 * (p[:, 1] - 40), np.zeros(cloud.n)])
    return cloud, side, ub


def _r3d(n_xy: int, n_z: int, solver: str) -> dict:
    """Solve the R3D brick on an n_xy x n_xy x n_z node grid: FE and both PD controls."""
    cloud, side, ub = _dirichlet_problem(n_xy, n_z)
    p = cloud.points
    # nearest neighbours (Luo & Sundararaghavan (2018), Sec. 2)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    fixed = (3 * side[:, None] + np.arange(3)).ravel()
    u_fe = solve_hex8(p, _node_grid_hexes((n_xy, n_xy, n_z)), E, NU, fixed, ub[side].ravel(),
                      solver="amg")  # fmt: skip
    out = {"cloud": cloud, "bonds": bonds, "fe": u_fe}
    for control in ("none", "stress_points"):
        model = pdlin.Correspondence(E=E, nu=NU, control=control, seed=0)
        res = pdlin.solve(
            pdlin.StaticProblem(model, cloud, bonds, dirichlet=[pdlin.Dirichlet(side, ub[side])]),
            solver=solver,
            rtol=1e-10,
            amg_options=AMG,
        )
        out[control] = res
    # the line x = 40, z = 0 of Fig. 13, ordered by y
    line = np.flatnonzero(np.isclose(p[:, 0], 40) & np.isclose(p[:, 2], 0))
    out["line"] = line[np.argsort(p[line, 1])]
    return out


def _rel_l2(u: np.ndarray, ref: np.ndarray) -> float:
    return float(np.linalg.norm(u - ref) / np.linalg.norm(ref))


@pytest.fixture(scope="module")
def r3d_small():
    with _global_random_state(0):  # the Hex8 reference uses AMG-CG
        return _r3d(17, 9, "direct")


@pytest.fixture(scope="module")
def r3d():
    with _global_random_state(SEED):
        return _r3d(33, 17, "amg-cg")


def test_r3d_coarse_brick(r3d_small):
    """h = 5 mm (17 x 17 x 9, direct solves): V22 ordering, bounds calibrated on this grid."""
    s = r3d_small
    fe, none, sp = s["fe"], s["none"].u, s["stress_points"].u
    mid = s["line"][np.isclose(s["cloud"].points[s["line"], 1], 40)][0]
    # FE w(40, 40, 0) = 0.1850 mm at h = 2.5 (reference value of an independent implementation);
    # measured 0.18601 at h = 5 (2026-11-21): the coarse Hex8 is within 1%
    assert fe[mid, 2] == pytest.approx(0.1850, rel=1e-2)
    err_none, err_sp = _rel_l2(none, fe), _rel_l2(sp, fe)
    # measured 2026-11-21: rel-L2 SP 2.678e-2, no control 6.109e-2 (calibrated bounds; at h = 2.5
    # the reference values are 1.14e-2 / 3.23e-2)
    assert err_sp <= 3.0e-2
    assert err_none >= 5.0e-2
    assert err_sp <= 0.5 * err_none
    # measured 2026-11-21: w(y = 40) SP 0.18761, no control 0.20159 (rel. to FE +0.9% / +8.4%)
    assert abs(sp[mid, 2] / fe[mid, 2] - 1) <= 0.02
    assert none[mid, 2] / fe[mid, 2] - 1 >= 0.05


@pytest.mark.slow
def test_v22_r3d_brick(r3d):
    """Luo & Sundararaghavan (2018), Sec. 5.3, reconstruction R3D at full size (33 x 33 x 17 =
    18,513 particles)."""
    cloud, bonds, fe = r3d["cloud"], r3d["bonds"], r3d["fe"]
    none, sp = r3d["none"], r3d["stress_points"]
    # V3 bookkeeping: R3D has 32,928 stress points (2 per interior particle, 1 per boundary
    # particle)
    info = pdlin.Correspondence(E=E, nu=NU, control="stress_points", seed=0).stress_points(
        cloud, bonds
    )
    assert info["owner"].size == 32928
    # V22: global rel-L2(u) SP ≤ 1.5e-2, no control ≥ 2.5e-2 (acceptance bounds; reference values
    # 1.14e-2 / 3.23e-2; measured 2026-11-21: 1.139e-2 / 3.228e-2)
    err_sp, err_none = _rel_l2(sp.u, fe), _rel_l2(none.u, fe)
    assert err_sp <= 1.5e-2
    assert err_none >= 2.5e-2
    # V22: AMG-CG converges within 150 iterations: SP (measured 2026-11-21: 91 to 1e-10)
    assert sp.n_iter <= 150
    line = r3d["line"]
    y = cloud.points[line, 1]
    mid = line[np.isclose(y, 40)][0]
    # FE w(y = 40) = 0.1850 mm on x = 40, z = 0 (reference value; measured 0.184994)
    assert fe[mid, 2] == pytest.approx(0.1850, rel=1e-2)
    # PD w(y = 40): SP 0.1860, no control 0.1928 (reference values; measured 2026-11-21: 0.186035 /
    # 0.192758); SP depends on the random cases, allow 1%
    assert sp.u[mid, 2] == pytest.approx(0.1860, rel=1e-2)
    assert none.u[mid, 2] == pytest.approx(0.1928, rel=1e-2)
    # line max a_w for 10 < y < 70: no control 4.2e-2 vs SP 2.0e-2 (reference values; measured
    # 2026-11-21: 4.197e-2 / 2.040e-2)
    inner = line[(y > 10) & (y < 70)]

    def max_aw(u: np.ndarray) -> float:
        return float(np.abs(u[inner, 2] / fe[inner, 2] - 1).max())

    assert max_aw(none.u) == pytest.approx(4.2e-2, rel=0.1)
    assert max_aw(sp.u) == pytest.approx(2.0e-2, rel=0.1)
    # the no-control sawtooth at the first line particle y = 2.5: FE 0.0681, SP 0.0562, no control
    # 0.0411 (reference values; measured 2026-11-21: 0.06806 / 0.05622 / 0.04107)
    first = line[np.isclose(y, 2.5)][0]
    assert fe[first, 2] == pytest.approx(0.0681, rel=1e-2)
    assert none.u[first, 2] == pytest.approx(0.0411, rel=2e-2)
    assert sp.u[first, 2] == pytest.approx(0.0562, rel=2e-2)  # depends on the random cases


@pytest.mark.slow
def test_v22_no_control_amg_iterations(r3d):
    # V22 (acceptance criterion): AMG-CG converges in ≤ 150 iterations for both controls (measured
    # 2026-11-21 to 1e-10: no control 124, stress points 34; reference implementation 48 / 75)
    assert r3d["none"].n_iter <= 150
    assert r3d["stress_points"].n_iter <= 150


def test_amg_cg_does_not_depend_on_the_global_random_state():
    cloud, side, ub = _dirichlet_problem(17, 9)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    model = pdlin.Correspondence(E=E, nu=NU, control="stress_points", seed=0)
    problem = pdlin.StaticProblem(model, cloud, bonds, dirichlet=[pdlin.Dirichlet(side, ub[side])])
    iters = []
    for seed in range(4):
        with _global_random_state(seed):
            iters.append(pdlin.solve(problem, solver="amg-cg", rtol=1e-10).n_iter)
    # every random state gives the same convergent solve (V22: ≤ 150 iterations; measured
    # 2026-11-21: 26 with the assembled operator)
    assert len(set(iters)) == 1 and iters[0] <= 150
    for seed in range(2):  # the matrix-free path (bond-based + Laplacian surrogate) too
        with _global_random_state(seed):
            res = pdlin.solve(problem, solver="amg-cg", rtol=1e-10, operator="matrix-free")
        assert res.n_iter <= 150  # measured 52
