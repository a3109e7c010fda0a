"""Uniaxial tension of a 2D bar with free lateral surfaces, every correspondence control.

The closed form (plane stress, E = 1, ν = 0.3): u_x = ε x, u_y = -ν ε (y - y_0), σ_xx = E ε,
reaction / transmitted force σ A with A = n_y h (the particles' cross-section, V = h² each).
Two problems on a 61 x 11 node grid (h = 1), δ = m h with ω = 1:

* **patch** (displacement driven, no shadow layer): u_x = ε x prescribed on the particles
  within 2δ of each end (x only; y is free except at one anchor), lateral faces free.  A
  consistent model reproduces the affine field exactly (its forces on an affine field
  vanish beyond 2δ from the loaded ends); the reaction is the sum over the right layer.
* **bar** (force driven, closed-form elongation): u_x = 0 on the left column, a total
  force σ A on the right column; ε and the lateral strain are least-squares slopes of u_x(x)
  and u_y(y) over the middle half (Saint-Venant zones excluded).

Issue items 3 (springs / ADS normalization and defaults) and 4 (stress points beyond
nearest neighbours); measured tables in docs/correspondence.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import pdlin

E, NU, EPS, H = 1.0, 0.3, 1e-3, 1.0
NX, NY = 61, 11


def _bar(m: int, control: str, mode: str, ny: int = NY, **kw: Any) -> dict[str, float]:
    """Relative errors ``el`` (ε), ``lat`` (lateral strain), and for mode 'patch' ``R``
    (reaction vs σ n_y h) and ``patch`` (max|u - u_ex| / max|u_ex|)."""
    cloud = pdlin.grid((NX, ny), spacing=H)
    bonds = pdlin.find_bonds(cloud, ratio=float(m))
    x, y = cloud.points.T
    L = NX * H
    model = pdlin.Correspondence(E=E, nu=NU, plane="stress", control=control, **kw)
    if mode == "bar":
        anchor = int(np.argmin(x + np.abs(y - y.mean())))
        bcs = [pdlin.Dirichlet("x-", 0.0, components="x"),
               pdlin.Dirichlet([anchor], 0.0, components="y")]  # fmt: skip
        loads = [pdlin.TotalForce("x+", [EPS * E * ny * H, 0.0])]
    else:
        left, right = np.flatnonzero(x < 2 * m * H), np.flatnonzero(x > L - 2 * m * H)
        anchor = int(left[np.argmin(np.abs(y[left] - y.mean()) + x[left])])
        bcs = [pdlin.Dirichlet(left, lambda p: EPS * p, components="x"),
               pdlin.Dirichlet(right, lambda p: EPS * p, components="x"),
               pdlin.Dirichlet([anchor], 0.0, components="y")]  # fmt: skip
        loads = []
    prob = pdlin.StaticProblem(model, cloud, bonds, dirichlet=bcs, loads=loads)
    res = pdlin.solve(prob, solver="direct")
    gauge = (x > L / 4) & (x < 3 * L / 4)
    out = {
        "el": np.polyfit(x[gauge], res.u[gauge, 0], 1)[0] / EPS - 1.0,
        "lat": np.polyfit(y[gauge], res.u[gauge, 1], 1)[0] / (-NU * EPS) - 1.0,
    }
    if mode == "patch":
        out["R"] = res.reactions[x > L - 2 * m * H, 0].sum() / (E * EPS * ny * H) - 1.0
        ue = np.c_[EPS * x, -NU * EPS * (y - y[anchor])]
        out["patch"] = float(np.abs(res.u - ue).max() / np.abs(ue).max())
    return out


# -- consistent controls: exact on the free-surface patch (no shadow layer) ----------------


@pytest.mark.parametrize("m", [1, 2, 3])
@pytest.mark.parametrize("control,kw", [
    ("none", {}), ("higher_order", {}), ("penalty", {}),
    ("stress_points", {}), ("stress_points", {"case": 1}),
])  # fmt: skip
def test_free_surface_patch_is_exact(m, control, kw):
    got = _bar(m, control, "patch", **kw)
    assert got["patch"] < 1e-10  # affine field reproduced (closed form)
    assert abs(got["lat"]) < 1e-9  # lateral strain -ν ε exactly (closed form)
    # reaction: σ n_y h, except stress points on the paper's nearest-neighbour families, whose
    # boundary stress points carry w_s = ½ (conventions.md#errata-luo-and-sundararaghavan-2018): the
    # body is the node hull, A = (n_y - 1) h, R/(σ n_y h) - 1 = -1/n_y exactly (before the fix: also
    # at δ = 2h, and δ = 3h failed the patch by 1.1e-2 with R -0.84 %)
    want = -1.0 / NY if (control == "stress_points" and m == 1) else 0.0
    assert got["R"] == pytest.approx(want, abs=1e-9)


@pytest.mark.parametrize("m", [1, 2, 3])
@pytest.mark.parametrize("control", ["higher_order", "penalty", "stress_points"])
def test_closed_form_elongation(m, control):
    # issue item 4: stress points within ~1 % like penalty / higher order at δ = h, 2h, 3h
    # (measured: SP δ = h +10.00 % vs A = n_y h, i.e. exact for A = (n_y - 1) h; 2h +0.00 %,
    # 3h -0.13 %; before the fix SP 2h was +10.0 % and 3h +0.68 %; HO / penalty ≤ 0.11 %)
    got = _bar(m, control, "bar")
    el, lat = got["el"], got["lat"]
    # node-hull section (n_y - 1) h, stress-point weight ½
    if control == "stress_points" and m == 1:
        el, lat = ((1.0 + v) * (NY - 1) / NY - 1.0 for v in (el, lat))
    assert abs(el) < 5e-3
    assert abs(lat) < 5e-3  # lateral strain -ν ε (measured ≤ 0.03 %)


def test_stress_points_3d_free_surface_patch():
    # 3D, δ = 2h: the balanced-halves rule keeps the free-surface patch exact
    cloud = pdlin.grid((16, 6, 6), spacing=H)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    x = cloud.points[:, 0]
    ends = np.flatnonzero((x < 4 * H) | (x > 12 * H))
    corner = int(np.argmin(np.sum(cloud.points, axis=1)))
    other = [int(np.argmin(np.abs(cloud.points - [0.5, 5.5, 0.5]).sum(axis=1)))]
    bcs = [pdlin.Dirichlet(ends, lambda p: EPS * p, components="x"),
           pdlin.Dirichlet([corner], 0.0, components=[1, 2]),
           pdlin.Dirichlet(other, 0.0, components=[2])]  # fmt: skip
    model = pdlin.Correspondence(E=E, nu=NU, control="stress_points", seed=1)
    res = pdlin.solve(pdlin.StaticProblem(model, cloud, bonds, dirichlet=bcs), solver="direct")
    p0 = cloud.points[corner]
    ue = np.c_[EPS * x, -NU * EPS * (cloud.points[:, 1:] - p0[1:])]
    assert np.abs(res.u - ue).max() < 1e-10 * np.abs(ue).max()  # before the fix: 1e-3-level


# -- springs and ADS: not consistent; their error is measured, bounded and linear in C̃ -----


def _springs_closed_form(ct: float) -> tuple[float, float]:
    """Springs = a full-vector material of modulus C̃E added to the plane-stress C: relative
    errors (uniaxial stress) of the axial stiffness and of the lateral strain."""
    a = E / (1 - NU**2)
    lat = NU * a / (a + ct * E) / NU - 1.0
    stiff = (a + ct * E + NU * a * (-NU * a / (a + ct * E))) / E - 1.0
    return stiff, lat


@pytest.mark.parametrize("m", [1, 2, 3])
def test_springs_error_is_family_normalized(m):
    # issue item 3: C̃ keeps its meaning for every δ/h (before: C̃ = 0.1 gave R +11.8 / +78.6 /
    # +350.8 % and ε -10.6 / -44.0 / -77.8 % at δ = h / 2h / 3h on this bar)
    ct = pdlin.models.correspondence.DEFAULT_CONTROL_COEFFICIENT["springs"]
    assert ct == 0.01
    stiff, lat = _springs_closed_form(ct)  # 1.09 %, -0.90 %
    got = _bar(m, "springs", "patch")
    assert got["R"] == pytest.approx(stiff, rel=0.15)  # measured 1.19 / 1.15 / 1.09 %
    assert got["lat"] == pytest.approx(lat, rel=0.15)  # measured -0.98 / -0.94 / -0.90 %
    el = _bar(m, "springs", "bar")["el"]
    assert -0.015 < el < -0.008  # measured -1.17 / -1.14 / -1.12 %
    # linear in C̃: doubling it doubles the error (to the curvature of the closed form, 1 %)
    got2 = _bar(m, "springs", "patch", coefficient=2 * ct)
    assert got2["R"] / got["R"] == pytest.approx(2.0, rel=0.03)
    assert got2["lat"] / got["lat"] == pytest.approx(2.0, rel=0.03)


@pytest.mark.parametrize("m,lat_bound", [(1, 1.5e-3), (2, 4e-3), (3, 7e-3)])
def test_ads_cannot_pass_free_surface_patch(m, lat_bound):
    # issue item 3: ADS acts on affine fields where families are truncated, so it resists
    # the lateral contraction next to free surfaces; at the default C̃ = 0.03 the error is
    # bounded (measured lateral -0.11 / -0.31 / -0.57 %, R +0.05 / +0.07 / +0.11 %; before
    # the fix C̃ = 0.1 gave lateral -0.44 / -24.7 / -88.3 % at δ = h / 2h / 3h), nonzero,
    # and grows with C̃ (slightly faster than linearly: 2.0-2.4x per doubling, measured)
    ct = pdlin.models.correspondence.DEFAULT_CONTROL_COEFFICIENT["ads"]
    assert ct == 0.03
    got = _bar(m, "ads", "patch")
    assert 1e-4 < -got["lat"] < lat_bound
    assert 0 < got["R"] < 2e-3
    assert got["patch"] > 1e-5  # not exact: ADS fails the free-surface patch test
    got2 = _bar(m, "ads", "patch", coefficient=2 * ct)
    assert 1.8 < got2["lat"] / got["lat"] < 2.5
    assert 1.8 < got2["R"] / got["R"] < 2.5
    # the surface layer is ~δ deep: a bar twice as wide halves the lateral error, roughly
    wide = _bar(m, "ads", "patch", ny=21)
    assert abs(wide["lat"]) < 0.75 * abs(got["lat"])
