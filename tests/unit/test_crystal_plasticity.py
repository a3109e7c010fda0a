"""Unit tests of the crystal-plasticity constitutive layer (Luo, Ramazani & Sundararaghavan (2017),
Sec. 3 and Appendix; T8, T9, tangent)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

import pdlin
from pdlin.constitutive import (
    CrystalPlasticity,
    SaintVenantKirchhoff,
    euler_to_rotation,
    rotate,
    rotation_matrix,
    slip_systems,
)
from pdlin.errors import InputError, ShapeError

SHEAR = np.array([[0.0, 1.0], [1.0, 0.0]])


def _fd_tangent(mat, F, state, eps=None):
    """Central finite differences of P(F) from the committed ``state``.

    The default step perturbs the stress by ≈ 2e-3 MPa (1e-6 of the planar D = 2000 MPa),
    far below the yield margins of the states tested, and keeps round-off ≈ 1e-9 relative.
    """
    n, d = F.shape[:2]
    if eps is None:
        eps = 1e-6 * 2000.0 / np.abs(getattr(mat, "C", np.full(1, 2000.0))).max()
    D = np.empty((n, d, d, d, d))
    for k in range(d):
        for l in range(d):  # noqa: E741
            E = np.zeros((d, d))
            E[k, l] = eps
            Pp = mat.update(F + E, state)[0]
            Pm = mat.update(F - E, state)[0]
            D[..., k, l] = (Pp - Pm) / (2 * eps)
    return D


def _assert_tangent(mat, F, state):
    P, new, D = mat.update(F, state, tangent=True)
    Dfd = _fd_tangent(mat, F, state)
    scale = np.abs(Dfd).reshape(F.shape[0], -1).max(axis=1)
    err = np.abs(D - Dfd).reshape(F.shape[0], -1).max(axis=1) / scale
    assert np.all(err <= 1e-6), err
    # the FD step did not switch the active set (away from switching points)
    return new


def _uniaxial_L(C_voigt, R):
    """Velocity gradient of uniaxial stress along sample z (small strain), |L_zz| = 1."""
    Cs = rotate(C_voigt, R)
    eps = np.linalg.solve(Cs, np.array([0, 0, 1.0, 0, 0, 0]))  # engineering shears
    L = np.array(
        [
            [eps[0], eps[5] / 2, eps[4] / 2],
            [eps[5] / 2, eps[1], eps[3] / 2],
            [eps[4] / 2, eps[3] / 2, eps[2]],
        ]
    )
    return L / L[2, 2]


# ---------------------------------------------------------------------------------------
# slip systems


@pytest.mark.parametrize(("slip", "count"), [("planar-2", 2), ("fcc", 12), ("hcp", 18)])
def test_slip_systems_orthonormal_and_traceless(slip, count):
    m, n = slip_systems(slip)
    assert m.shape[0] == count
    np.testing.assert_allclose(np.einsum("ai,ai->a", m, n), 0.0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(m, axis=1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-15)
    S0 = CrystalPlasticity(slip).S0
    np.testing.assert_allclose(np.trace(S0, axis1=1, axis2=2), 0.0, atol=1e-15)
    # no duplicated system (up to the sign of m and n)
    P = np.abs(S0.reshape(count, -1) @ S0.reshape(count, -1).T)
    assert np.all(P[~np.eye(count, dtype=bool)] < 1 - 1e-9)


def test_planar_schmid_tensors_of_spec():
    S0 = CrystalPlasticity().S0
    # conventions.md#crystal-plasticity-conventions (systems at ±30°): S0¹ = [−0.4330 0.75; −0.25
    # 0.4330], S0² = [0.4330 0.75; −0.25 −0.4330]
    np.testing.assert_allclose(S0[0], [[-0.4330, 0.75], [-0.25, 0.4330]], atol=5e-5)
    np.testing.assert_allclose(S0[1], [[0.4330, 0.75], [-0.25, -0.4330]], atol=5e-5)


def test_hcp_families_geometry():
    c = 1.624
    m, n = slip_systems("hcp", c)
    # basal and prismatic normals ⟂ / ∥ c, <a> directions in the basal plane
    np.testing.assert_allclose(np.abs(n[:3, 2]), 1.0)
    np.testing.assert_allclose(n[3:6, 2], 0.0, atol=1e-15)
    np.testing.assert_allclose(m[:12, 2], 0.0, atol=1e-15)
    # <c+a> = <11-23>: angle to c from tan = a / c (|a1 + a2| = a, closed form)
    np.testing.assert_allclose(np.abs(m[12:, 2]), c / np.hypot(1.0, c), rtol=1e-14)
    # {10-11} normal tilt: tan(angle to c) = (2/√3) c / 1 ... n ∝ (1, 1/√3, 1/c)
    np.testing.assert_allclose(np.abs(n[6:12, 2]), (1 / c) / np.sqrt(4 / 3 + 1 / c**2))


# ---------------------------------------------------------------------------------------
# return mapping invariants (T8), purity, objectivity (T9)


def _t8_path(mat, rng, n=64, steps=15):
    """Yield ``(state_n, F, state_new)`` along the random-increment paths of check T8.

    Increments of 0.002 for the planar material (D = 2000 MPa); the 3D defaults are
    30-85x stiffer and the Eq. 31 vs Fᵉ consistency gap grows as C Δγ², so their
    increments are 1e-4: a persistent direction per point plus noise makes them yield and
    keeps changing the active sets.
    """
    d = mat.dim
    inc = 0.002 if d == 2 else 1e-4
    drift = rng.normal(size=(n, d, d))
    drift /= np.abs(drift).max(axis=(1, 2), keepdims=True)
    o = (
        rng.uniform(-np.pi / 2, np.pi / 2, n)
        if d == 2
        else euler_to_rotation(rng.uniform(0, 3, (n, 3)))
    )
    state = mat.initial_state(n, o)
    F = np.broadcast_to(np.eye(d), (n, d, d)).copy()
    for _ in range(steps):
        G = rng.normal(size=(n, d, d))
        G = G / np.abs(G).max(axis=(1, 2), keepdims=True)
        F = F + inc * (G if d == 2 else drift + 0.5 * G)
        new = mat.update(F, state)[1]
        yield state, F, new
        state = new


@pytest.mark.parametrize("slip", ["planar-2", "fcc", "hcp"])
def test_t8_return_mapping_invariants(slip, rng):
    mat = CrystalPlasticity(slip)
    n = 64
    s_scale = mat.s0.max()
    n_plastic = n_pruned = n_react = 0
    for state, _, new in _t8_path(mat, rng, n, steps=15 if slip == "planar-2" else 30):
        dg, tau, s = new["dgamma"], np.abs(new["tau"]), new["s"]
        assert np.all(dg >= 0.0)
        act = dg > 0
        n_plastic += int(act.any(axis=1).sum())
        n_pruned += int(new["pruned"].sum())
        n_react += int(new["reactivated"].sum())
        assert not np.any(new["unsettled"])
        # check T8: active |abs(τ) − s| ≤ 2e-3 s; inactive abs(τ) ≤ s (1 + 1e-3), every system of
        # every lattice (re-activation passes, active_set="reactivate")
        assert np.all(np.abs(tau - s)[act] <= 2e-3 * s[act])
        assert np.all(tau[~act] <= s[~act] * (1 + 1e-3) + 1e-12 * s_scale)
        detFp_n = np.linalg.det(state["Fp"])
        assert np.all(np.abs(np.linalg.det(new["Fp"]) / detFp_n - 1) <= 1e-4)
        np.testing.assert_allclose(new["gamma"], state["gamma"] + dg, rtol=0, atol=1e-15)
    assert n_plastic > n  # many plastic updates were checked
    assert n_pruned > 0  # includes steps where §3.6 step 5 pruned the active set
    if slip != "planar-2":
        assert n_react > 0  # and steps where a pruned / inactive system was re-activated


@pytest.mark.parametrize("slip", ["fcc", "hcp"])
def test_pruning_alone_leaves_overstressed_systems(slip, rng):
    # §3.6 as written (active_set="prune") on the same kind of paths: a dropped system can
    # end far above its resistance (15-110 % measured); re-activation removes it (above)
    mat = CrystalPlasticity(slip, active_set="prune")
    worst = 0.0
    for _, _, new in _t8_path(mat, rng, n=200, steps=30):
        act = new["dgamma"] > 0
        worst = max(worst, float(np.max((np.abs(new["tau"]) / new["s"] - 1)[~act])))
        assert not np.any(new["reactivated"])
    assert worst > 0.05


def test_reactivation_leaves_planar_results_identical(rng):
    # planar-2: pruning never leaves an inactive system above s (1 + yield_tol), so both
    # strategies agree bit for bit (also on steps with pruning)
    a, b = CrystalPlasticity(), CrystalPlasticity(active_set="prune")
    pruned = 0
    for state, F, _ in _t8_path(a, rng, n=200, steps=20):
        P1, s1, D1 = a.update(F, state, tangent=True)
        P2, s2, D2 = b.update(F, state, tangent=True)
        np.testing.assert_array_equal(P1, P2)
        np.testing.assert_array_equal(D1, D2)
        np.testing.assert_array_equal(s1["dgamma"], s2["dgamma"])
        assert not np.any(s1["reactivated"])
        pruned += int(s1["pruned"].sum())
    assert pruned > 0


def test_tangent_on_reactivated_steps(rng):
    # consistent tangent with the final (re-activated) active set and slip signs
    mat = CrystalPlasticity("fcc")
    cs = CrystalPlasticity("fcc", tangent="complex-step")
    checked = 0
    for state, F, new in _t8_path(mat, rng, n=64, steps=15):
        hit = np.flatnonzero(new["reactivated"] > 0)[:4]
        if hit.size:
            st = {key: v[hit] for key, v in state.items()}
            sub = _assert_tangent(mat, F[hit], st)
            np.testing.assert_array_equal(sub["dgamma"] > 0, new["dgamma"][hit] > 0)
            np.testing.assert_allclose(sub["dgamma"], new["dgamma"][hit], rtol=1e-12)
            Db = cs.update(F[hit], st, tangent=True)[2]
            Da = mat.update(F[hit], st, tangent=True)[2]
            np.testing.assert_allclose(Da, Db, rtol=0, atol=1e-12 * np.abs(Db).max())
            checked += hit.size
    assert checked >= 4


def test_unsettled_points_warn():
    # with no re-activation pass allowed, the overstressed points are reported
    mat = CrystalPlasticity("fcc", max_passes=0)
    rng = np.random.default_rng(20261121)
    with pytest.warns(pdlin.errors.ActiveSetWarning, match=r"did not settle at \d+ of 64"):
        for _, _, new in _t8_path(mat, rng):
            if np.any(new["unsettled"]):
                break
    assert np.any(new["unsettled"])
    # the kept solution is the pruned one of §3.6
    assert not np.any(new["reactivated"])
    with pytest.raises(InputError, match="active_set must be"):
        CrystalPlasticity("fcc", active_set="lcp")
    with pytest.raises(InputError, match="max_passes must be"):
        CrystalPlasticity("fcc", max_passes=-1)
    with pytest.raises(InputError, match="yield_tol must be"):
        CrystalPlasticity("fcc", yield_tol=np.nan)


def test_update_is_pure_and_does_not_mutate(rng):
    mat = CrystalPlasticity()
    r = pdlin.material_point(mat, "shear", steps=4, orientation=np.radians([0.0, 30.0, 45.0]))
    state = r.states[-1]
    copy = {k: v.copy() for k, v in state.items()}
    F = np.broadcast_to(expm(0.002 * 5 * SHEAR), (3, 2, 2)).copy()
    P1, s1, _ = mat.update(F, state, tangent=True)
    P2, s2, _ = mat.update(F, state)
    for k in copy:
        np.testing.assert_array_equal(state[k], copy[k])
    np.testing.assert_array_equal(P1, P2)
    np.testing.assert_array_equal(s1["Fp"], s2["Fp"])
    assert s1["Fp"] is not state["Fp"]


@pytest.mark.parametrize("slip", ["planar-2", "fcc", "hcp"])
def test_t9_objectivity(slip, rng):
    mat = CrystalPlasticity(slip)
    d, n = mat.dim, 10
    o = rng.uniform(-1.5, 1.5, n) if d == 2 else euler_to_rotation(rng.uniform(0, 3, (n, 3)))
    L = SHEAR if d == 2 else np.diag([-0.5, -0.5, 1.0])
    r = pdlin.material_point(mat, L, steps=6, eta=0.002 if d == 2 else 0.0005, orientation=o)
    state = r.states[-2]
    assert np.any(state["plastic"])  # a plastic committed state (Fp ≠ I)
    F = np.broadcast_to(r.F[-1], (n, d, d)) + 1e-3 * rng.normal(size=(n, d, d))
    if d == 2:
        Q = np.broadcast_to(rotation_matrix([0, 0, 1], 0.7)[:2, :2], (n, 2, 2))
    else:
        Q = euler_to_rotation(rng.uniform(0, 3, (n, 3)))
    P, s1, _ = mat.update(F, state)
    PQ, s2, _ = mat.update(Q @ F, state)
    np.testing.assert_allclose(PQ, Q @ P, rtol=0, atol=1e-10 * np.abs(P).max())
    np.testing.assert_allclose(s1["dgamma"], s2["dgamma"], rtol=0, atol=1e-14)


def test_double_slip_determinant_and_renormalization():
    # derived: det of the update = 1 + 0.75 Δγ¹Δγ² (sign product) for double slip (planar)
    mat = CrystalPlasticity()
    r = pdlin.material_point(mat, "shear", steps=8, orientation=np.radians([-45.0, 0.0]))
    st0, st1 = r.states[-2], r.states[-1]
    dg, sg = st1["dgamma"], st1["sign"]
    assert np.all(dg > 0)  # both points in double slip
    ratio = np.linalg.det(st1["Fp"]) / np.linalg.det(st0["Fp"])
    expected = 1 + 0.75 * dg[:, 0] * dg[:, 1] * sg[:, 0] * sg[:, 1]
    np.testing.assert_allclose(ratio, expected, rtol=1e-13)
    assert np.all(np.abs(ratio - 1) > 1e-7)  # the drift is real without renormalization
    ren = CrystalPlasticity(renormalize=True)
    r2 = pdlin.material_point(ren, "shear", steps=8, orientation=np.radians([-45.0, 0.0]))
    np.testing.assert_allclose(np.linalg.det(r2.states[-1]["Fp"]), 1.0, atol=1e-14)


def test_active_set_pruning_happens():
    # §3.6 step 5: a potentially active system with Δγ ≤ 0 is removed and the set re-solved
    mat = CrystalPlasticity()
    theta = np.random.default_rng(0).uniform(-np.pi / 2, np.pi / 2, 200)
    r = pdlin.material_point(mat, "shear", steps=30, orientation=theta)
    pruned = np.array([st["pruned"] for st in r.states])
    assert pruned.sum() > 0
    # the 12 orientations of the §8.1 tables never prune (their tables do not exercise it)
    r = pdlin.material_point(mat, "shear", steps=30, orientation=pdlin.constitutive.ORIENTATIONS_2D)
    assert sum(st["pruned"].sum() for st in r.states) == 0


def test_tangent_on_pruned_steps():
    # consistent tangent where the active set was pruned (away from the switching points)
    mat = CrystalPlasticity()
    theta = np.random.default_rng(0).uniform(-np.pi / 2, np.pi / 2, 200)
    r = pdlin.material_point(mat, "shear", steps=30, orientation=theta)
    checked = 0
    for k in range(1, 30):
        hit = np.flatnonzero(r.states[k]["pruned"] > 0)
        if hit.size:
            st = {key: v[hit] for key, v in r.states[k - 1].items()}
            F = np.broadcast_to(r.F[k], (hit.size, 2, 2)).copy()
            new = _assert_tangent(mat, F, st)
            np.testing.assert_array_equal(new["pruned"], r.states[k]["pruned"][hit])
            checked += hit.size
    assert checked > 10


# ---------------------------------------------------------------------------------------
# consistent tangent vs central finite differences


def _states_with_active(mat, o, L, eta, steps, counts):
    """(F, committed state) per wanted active count, taken from a material-point run."""
    r = pdlin.material_point(mat, L, steps=steps, eta=eta, orientation=o)
    out = {}
    for k in range(1, steps):
        nact = (r.states[k]["dgamma"] > 0).sum(axis=1)
        for c in counts:
            hit = np.flatnonzero(nact == c)
            if c not in out and hit.size:
                p = hit[0]
                sub = {key: v[p : p + 1] for key, v in r.states[k - 1].items()}
                out[c] = (r.F[k][None].copy(), sub)
    return out


def test_tangent_planar_elastic_single_double():
    mat = CrystalPlasticity()
    found = _states_with_active(mat, np.radians([0.0, 60.0, 45.0]), SHEAR, 0.002, 8, (0, 1, 2))
    assert sorted(found) == [0, 1, 2]
    for c, (F, st) in found.items():
        new = _assert_tangent(mat, F, st)
        assert (new["dgamma"] > 0).sum() == c
    # many points at once, including steps with pruning
    r = pdlin.material_point(
        mat, "compression", steps=5, orientation=pdlin.constitutive.ORIENTATIONS_2D
    )
    F = np.broadcast_to(expm(0.002 * 6 * np.diag([1.0, -1.0])), (12, 2, 2)).copy()
    _assert_tangent(mat, F, r.states[-1])


def test_tangent_elastic_matches_svk_when_fp_is_identity():
    mat = CrystalPlasticity()
    svk = SaintVenantKirchhoff(np.array([[2000.0, 1000, 0], [1000, 2000, 0], [0, 0, 2000]]))
    F = np.array([expm(0.001 * SHEAR)])
    _, _, D1 = mat.update(F, mat.initial_state(1, 0.0), tangent=True)
    _, _, D2 = svk.update(F, svk.initial_state(1), tangent=True)
    np.testing.assert_allclose(D1, D2, rtol=0, atol=1e-9 * np.abs(D2).max())


@pytest.mark.parametrize("slip", ["fcc", "hcp"])
def test_tangent_3d_elastic_single_double(slip, rng):
    mat = CrystalPlasticity(slip)
    o = euler_to_rotation(rng.uniform(0, np.pi, (20, 3)))
    found = _states_with_active(mat, o, "tension", 2e-5, 40, (0, 1, 2))
    assert sorted(found) == [0, 1, 2], sorted(found)
    for c, (F, st) in found.items():
        new = _assert_tangent(mat, F, st)
        assert (new["dgamma"] > 0).sum() == c


def test_tangent_fcc_multislip_batch(rng):
    mat = CrystalPlasticity("fcc")
    o = euler_to_rotation(rng.uniform(0, np.pi, (6, 3)))
    r = pdlin.material_point(mat, "tension", steps=14, eta=5e-5, orientation=o)
    assert np.all(r.states[-1]["plastic"])
    F = np.broadcast_to(expm(15 * 5e-5 * np.diag([-0.5, -0.5, 1.0])), (6, 3, 3)).copy()
    _assert_tangent(mat, F, r.states[-1])


# ---------------------------------------------------------------------------------------
# FCC / HCP single crystals: Schmid-law yield in closed form


def test_fcc_001_tension_yields_at_sqrt6_s0():
    C11, C12 = 170e3, 124e3  # default fcc elasticity (copper, MPa)
    s0 = 16.0  # default fcc s0 (MPa)
    mat = CrystalPlasticity("fcc")
    S = mat.schmid_factors([0, 0, 1], np.eye(3))[0]
    # 8 systems with Schmid factor 1/√6 along [001], 4 with 0
    np.testing.assert_allclose(np.sort(S), [0] * 4 + [1 / np.sqrt(6)] * 8, atol=1e-15)
    r = C12 / (C11 + C12)  # lateral contraction of uniaxial stress along [001]
    eta = 5e-5
    res = pdlin.material_point(
        mat, np.diag([-r, -r, 1.0]), steps=20, eta=eta, orientation=np.eye(3)
    )
    E100 = (C11 - C12) * (C11 + 2 * C12) / (C11 + C12)  # Young's modulus along [001]
    # yield at τ = s0 → σ_zz = √6 s0 (closed form) → first step with E100 η t > √6 s0
    assert res.yield_step[0] == int(np.ceil(np.sqrt(6) * s0 / (E100 * eta)))
    k = res.yield_step[0] - 1
    assert res.stress[k - 1, 0, 2, 2] < np.sqrt(6) * s0 < E100 * eta * (k + 1)
    for st, sig in zip(res.states[k:], res.stress[k:, 0], strict=True):
        dg = st["dgamma"][0]
        on = S > 0.1
        assert np.all(dg[on] > 0) and np.all(dg[~on] == 0)
        np.testing.assert_allclose(dg[on], dg[on][0], rtol=1e-8)  # symmetric 8-fold slip
        # Schmid law on the 8 systems: (σ_zz − σ_xx)/√6 = s (T̄ vs σ: O(strain) ≈ 1e-3)
        assert (sig[2, 2] - sig[0, 0]) / np.sqrt(6) == pytest.approx(st["s"][0, 0], rel=3e-3)


def test_hcp_basal_single_crystal_yields_at_twice_s0():
    mat = CrystalPlasticity("hcp")
    s0_basal = 10.0  # default basal s0 (MPa)
    R = rotation_matrix([0, 1, 0], -np.pi / 4)  # c axis at 45° to the load (sample z)
    S = mat.schmid_factors([0, 0, 1], R)[0]
    assert S[0] == pytest.approx(0.5, abs=1e-15)  # basal (0001)[2-1-10]: cos 45° sin 45°
    ratio = S / mat.s0
    assert np.argmax(ratio) == 0 and np.sort(ratio)[-2] < 0.6 * ratio[0]
    C = mat.C
    from pdlin.constitutive import tensor_to_voigt

    L = _uniaxial_L(tensor_to_voigt(C), R)
    eta = 2e-5
    res = pdlin.material_point(mat, L, steps=40, eta=eta, orientation=R)
    k = res.yield_step[0] - 1
    assert k > 0
    # the elastic step before yield is below 2 s0, the yield step above it (Schmid 0.5)
    assert res.stress[k - 1, 0, 2, 2] < 2 * s0_basal
    for st, sig in zip(res.states[k:], res.stress[k:, 0], strict=True):
        dg = st["dgamma"][0]
        assert dg[0] > 0 and np.all(dg[1:] == 0)  # basal single slip
        # Schmid law in the sample frame: τ = (R m)·σ·(R n) = s (T̄ vs σ: O(strain))
        tau = (R @ mat.m[0]) @ sig @ (R @ mat.n[0])
        assert abs(tau) == pytest.approx(st["s"][0, 0], rel=3e-3)
    # yield between the last elastic stress and its linear extrapolation to the yield step
    s_el = res.stress[k - 1, 0, 2, 2]
    assert 0.5 * s_el < s0_basal <= 0.5 * s_el * (k + 1) / k * (1 + 1e-3)


# ---------------------------------------------------------------------------------------
# post-processing, interface details


def test_equivalent_plastic_strain_increment():
    mat = CrystalPlasticity()
    r = pdlin.material_point(mat, "shear", steps=5, orientation=np.radians([0.0, 30.0]))
    st = r.states[-1]
    s = r.stress[-1]
    seff = np.sqrt(
        s[:, 0, 0] ** 2 - s[:, 0, 0] * s[:, 1, 1] + s[:, 1, 1] ** 2 + 3 * s[:, 0, 1] ** 2
    )  # conventions.md#crystal-plasticity-conventions: σ_eff (2D)
    expected = np.sum(np.abs(st["tau"]) * st["dgamma"], axis=1) / seff
    np.testing.assert_allclose(mat.plastic_strain_increment(st), expected, rtol=1e-14)
    assert np.all(expected > 0)


def test_orientation_forms_3d_agree(rng):
    angles = rng.uniform(0, np.pi, (4, 3))
    R = euler_to_rotation(angles)
    a = CrystalPlasticity("fcc", orientation=angles).initial_state(4)["R0"]
    b = CrystalPlasticity("fcc", orientation=R).initial_state(4)["R0"]
    np.testing.assert_allclose(a, b, atol=1e-15)
    # Bunge: g = Rᵀ maps sample to crystal; φ1 = 90° turns crystal e1 onto sample e2
    np.testing.assert_allclose(
        euler_to_rotation([np.pi / 2, 0, 0]) @ [1, 0, 0], [0, 1, 0], atol=1e-15
    )


def test_rotated_crystal_frame_convention():
    # θ = 90° maps crystal x to sample y: uniaxial F along sample y equals F along crystal x
    mat = CrystalPlasticity()
    Fy = np.array([[[1.0, 0.0], [0.0, 1.001]]])
    Fx = np.array([[[1.001, 0.0], [0.0, 1.0]]])
    P90 = mat.update(Fy, mat.initial_state(1, np.pi / 2))[0]
    P0 = mat.update(Fx, mat.initial_state(1, 0.0))[0]
    np.testing.assert_allclose(P90[0, 1, 1], P0[0, 0, 0], rtol=1e-14)


def test_svk_energy_gradient(rng):
    # T4 ingredient: P = ∂Ψ/∂F (central FD), and the analytic tangent = FD of P
    C = pdlin.constitutive.isotropic(E=1000.0, nu=0.3)
    svk = SaintVenantKirchhoff(C)
    F = np.eye(3) + 0.05 * rng.normal(size=(5, 3, 3))
    P, _, D = svk.update(F, {}, tangent=True)
    eps = 1e-6
    for k in range(3):
        for l in range(3):  # noqa: E741
            E = np.zeros((3, 3))
            E[k, l] = eps
            dpsi = (svk.energy(F + E) - svk.energy(F - E)) / (2 * eps)
            np.testing.assert_allclose(dpsi, P[:, k, l], rtol=1e-7, atol=1e-7 * np.abs(P).max())
    np.testing.assert_allclose(D, _fd_tangent(svk, F, {}), rtol=0, atol=1e-6 * np.abs(D).max())


# ---------------------------------------------------------------------------------------
# Voronoi polycrystal


def test_voronoi_polycrystal_2d():
    cloud = pdlin.grid((25, 25), spacing=1 / 25)
    grain, theta = pdlin.voronoi_polycrystal(cloud, 21, seed=3)
    assert grain.shape == (625,) and theta.shape == (625,)
    assert set(np.unique(grain)) == set(range(21))
    # every orientation of the 12-value set used at least once (conventions.md#polycrystal)
    np.testing.assert_allclose(np.unique(theta), pdlin.constitutive.ORIENTATIONS_2D, atol=0)
    # one orientation per grain
    for g in range(21):
        assert np.unique(theta[grain == g]).size == 1
    g2, t2 = pdlin.voronoi_polycrystal(cloud, 21, seed=3)
    np.testing.assert_array_equal(grain, g2)
    np.testing.assert_array_equal(theta, t2)
    # the per-point orientations feed the material directly
    mat = CrystalPlasticity(orientation=theta)
    assert mat.initial_state(625)["R0"].shape == (625, 2, 2)


def test_voronoi_polycrystal_3d_rotations():
    cloud = pdlin.grid((6, 6, 6))
    grain, R = pdlin.voronoi_polycrystal(cloud, 7, seed=0)
    assert R.shape == (216, 3, 3)
    np.testing.assert_allclose(
        R.transpose(0, 2, 1) @ R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0, rtol=1e-12)
    assert np.unique(grain).size == 7
    with pytest.raises(InputError, match="n_grains"):
        pdlin.voronoi_polycrystal(cloud, 0)


# ---------------------------------------------------------------------------------------
# input validation


def test_bad_slip_name():
    with pytest.raises(InputError, match=r"slip must be one of .* got 'bcc'"):
        CrystalPlasticity("bcc")


def test_bad_elastic_constants():
    with pytest.raises(InputError, match=r"elastic\['D11'\] must be > 0, got -1"):
        CrystalPlasticity(elastic={"D11": -1.0, "D12": 1000.0, "D33": 2000.0})
    with pytest.raises(InputError, match="elastic must be positive definite"):
        CrystalPlasticity(elastic={"D11": 1000.0, "D12": 3000.0, "D33": 2000.0})
    with pytest.raises(InputError, match=r"elastic must give the constants"):
        CrystalPlasticity("fcc", elastic={"C11": 1.0, "C12": 0.5})
    with pytest.raises(ShapeError, match=r"elastic must have shape \(3, 3\).* got \(6, 6\)"):
        CrystalPlasticity(elastic=np.eye(6))


def test_bad_hardening():
    with pytest.raises(InputError, match=r"hardening\['ss'\] must be > s0"):
        CrystalPlasticity(hardening={"ss": 5.0})
    with pytest.raises(InputError, match="hardening keys"):
        CrystalPlasticity(hardening={"tau0": 5.0})
    with pytest.raises(InputError, match=r"hardening\['s0'\] must map every slip family"):
        CrystalPlasticity("hcp", hardening={"s0": {"basal": 1.0}})
    mat = CrystalPlasticity("hcp", hardening={"s0": [1.0, 2.0, 3.0, 4.0], "ss": 100.0})
    np.testing.assert_array_equal(mat.s0, np.repeat([1.0, 2.0, 3.0, 4.0], [3, 3, 6, 6]))


def test_bad_shapes():
    mat = CrystalPlasticity()
    st = mat.initial_state(3)
    with pytest.raises(ShapeError, match=r"F must have shape \(n, 2, 2\), got \(3, 3, 3\)"):
        mat.update(np.zeros((3, 3, 3)), st)
    with pytest.raises(ShapeError, match=r"state_n\['Fp'\] must have shape \(4, 2, 2\)"):
        mat.update(np.broadcast_to(np.eye(2), (4, 2, 2)), st)
    # the optional per-point keys too (the compiled update reads them point by point): a
    # short one is an error, not a broadcast
    big = mat.initial_state(300)
    F = np.broadcast_to(np.eye(2), (300, 2, 2))
    for key in ("ep", "theta0", "theta", "theta_rate"):
        bad = {**big, key: np.zeros(1)}
        with pytest.raises(ShapeError, match=rf"state_n\['{key}'\] must have shape \(300,\)"):
            mat.update(F, bad)
    with pytest.raises(ShapeError, match=r"orientation must be .* shape \(3,\)"):
        mat.initial_state(3, np.zeros(5))
    with pytest.raises(ShapeError, match="orientation must be rotation matrices"):
        CrystalPlasticity("fcc").initial_state(2, np.zeros((2, 2)))
    with pytest.raises(InputError, match="proper rotation"):
        CrystalPlasticity("fcc", orientation=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InputError, match="loading must be one of"):
        pdlin.material_point(mat, "torsion")
    with pytest.raises(InputError, match="shear must be"):
        CrystalPlasticity(shear="voigt")


@pytest.mark.parametrize("slip", ["planar-2", "fcc", "hcp"])
@pytest.mark.parametrize("renormalize", [False, True])
def test_analytic_tangent_equals_complex_step(slip, renormalize, rng):
    kw = {"renormalize": renormalize}
    a = CrystalPlasticity(slip, **kw)
    b = CrystalPlasticity(slip, tangent="complex-step", **kw)
    d, n = a.dim, 40
    o = rng.uniform(-1.5, 1.5, n) if d == 2 else euler_to_rotation(rng.uniform(0, 3, (n, 3)))
    eta = 0.002 if d == 2 else 5e-5
    r = pdlin.material_point(a, "shear" if d == 2 else "tension", steps=12, eta=eta, orientation=o)
    assert np.mean(r.states[-1]["plastic"]) > 0.3
    F = np.broadcast_to(r.F[-1], (n, d, d)) + 1e-4 * rng.normal(size=(n, d, d))
    Da = a.update(F, r.states[-1], tangent=True)[2]
    Db = b.update(F, r.states[-1], tangent=True)[2]
    np.testing.assert_allclose(Da, Db, rtol=0, atol=1e-12 * np.abs(Db).max())
    if renormalize:
        _assert_tangent(a, F[:8], {k: v[:8] for k, v in r.states[-1].items()})


def _numba_kernels(monkeypatch):
    """pdlin's numba kernels, sent batches from 256 points on (by default one chunk,
    8,192 points: the tests' few hundred points would stay on numpy)."""
    pytest.importorskip("numba")
    from pdlin._kernels import _kernels
    from pdlin.constitutive import crystal_plasticity as cpm

    mod = _kernels()
    if mod is None:
        pytest.skip("numba disabled (PDLIN_NUMBA=0)")
    monkeypatch.setattr(cpm, "_NUMBA_MIN_POINTS", 256)
    return mod


@pytest.mark.parametrize("renormalize", [False, True])
def test_planar_update_numba_kernel_matches_numpy(monkeypatch, renormalize):
    """Planar double slip with §3.6 pruning (its default active set) runs ``update`` in the
    numba kernels from ``_NUMBA_MIN_POINTS`` points on: P, every state array and the
    analytic consistent tangent equal the numpy path's to round-off (its 4-term products
    and 2 x 2 solves go through BLAS / LAPACK), active sets, slip signs and prune counts
    exactly, for a fresh state (no θ keys) and committed plastic ones; bitwise the same for
    1-3 threads."""
    from pdlin.constitutive import crystal_plasticity as cpm

    mod = _numba_kernels(monkeypatch)
    calls = []
    real, real_t = mod.cp_planar_fill, mod.cp_planar_tangent_fill

    def counted(*args):
        calls.append(args[1] - args[0])
        return real(*args)

    def counted_t(*args):
        calls.append(-(args[1] - args[0]))
        return real_t(*args)

    monkeypatch.setattr(mod, "cp_planar_fill", counted)
    monkeypatch.setattr(mod, "cp_planar_tangent_fill", counted_t)
    monkeypatch.setattr(cpm, "_UPDATE_CHUNK", 97)
    mat = CrystalPlasticity(renormalize=renormalize)
    rng = np.random.default_rng(11)
    cases = [(k, st, F) for k, (st, F, _) in enumerate(_t8_path(mat, rng, n=600, steps=15))]
    plastic = pruned = 0.0
    for k, state, F in cases[::7]:
        ref_P, ref, ref_D = mat._update_points(F, state, True)
        plastic += ref["plastic"].sum()
        pruned += ref["pruned"].sum()
        for tangent in (False, True):
            first = None
            for nt in (1, 2, 3):
                pdlin.set_num_threads(nt)
                try:
                    calls.clear()
                    P, st, D = mat.update(F, state, tangent=tangent)
                finally:
                    pdlin.set_num_threads(None)
                assert sum(c for c in calls if c > 0) == 600 and max(calls) == 97
                assert sum(c for c in calls if c < 0) == (-600 if tangent else 0)
                assert (D is None) != tangent
                assert st.keys() == ref.keys()
                if first is None:
                    first = (P, st, D)
                    np.testing.assert_allclose(P, ref_P, rtol=0, atol=1e-13 * np.abs(ref_P).max())
                    if tangent:
                        atol = 1e-13 * np.abs(ref_D).max()
                        np.testing.assert_allclose(D, ref_D, rtol=0, atol=atol)
                    for key in st:
                        scale = max(np.abs(ref[key]).max(), 1.0)
                        np.testing.assert_allclose(
                            st[key], ref[key], rtol=0, atol=1e-13 * scale, err_msg=f"{k}: {key}"
                        )
                    for key in ("sign", "pruned", "plastic", "reactivated", "unsettled"):
                        np.testing.assert_array_equal(st[key], ref[key], err_msg=key)
                    np.testing.assert_array_equal(st["dgamma"] > 0, ref["dgamma"] > 0)
                else:
                    np.testing.assert_array_equal(P, first[0])
                    if tangent:
                        np.testing.assert_array_equal(D, first[2])
                    for key in st:
                        np.testing.assert_array_equal(st[key], first[1][key], err_msg=key)
    # the compared states slip and prune (seed 11: 154 plastic points, 7 pruned systems;
    # otherwise the test would not discriminate)
    assert plastic > 100 and pruned > 5, (plastic, pruned)


def test_planar_numba_tangent_matches_finite_differences(monkeypatch):
    """The compiled tangent is the derivative of the compiled update (central differences
    of P through the kernel, 1e-6 relative; points away from active-set switches)."""
    _numba_kernels(monkeypatch)
    mat = CrystalPlasticity()
    rng = np.random.default_rng(5)
    *_, (state, F, _) = _t8_path(mat, rng, n=300, steps=10)
    assert mat.update(F, state)[1]["plastic"].sum() > 20  # seed 5: plastic points compared
    _assert_tangent(mat, F, state)


def test_planar_update_numba_kernel_singular_points_and_scope(monkeypatch):
    """Points the kernel marks singular are redone by the numpy path (their kernel
    outputs discarded, the tangent's too); the complex-step tangent, re-activation or 3D
    slip keep the numpy path."""
    mod = _numba_kernels(monkeypatch)
    real = mod.cp_planar_fill

    def every_fifth_bad(p0, p1, *args):
        real(p0, p1, *args)
        P, bad = args[-17], args[-2]  # the last argument is `full`
        bad[p0:p1:5] = True
        P[p0:p1:5] = np.nan  # must not survive

    mat = CrystalPlasticity()
    rng = np.random.default_rng(3)
    *_, (state, F, _) = _t8_path(mat, rng, n=400, steps=6)
    ref_P, ref, ref_D = mat._update_points(F, state, True)
    monkeypatch.setattr(mod, "cp_planar_fill", every_fifth_bad)
    for tangent in (False, True):
        P, st, D = mat.update(F, state, tangent=tangent)
        np.testing.assert_allclose(P, ref_P, rtol=0, atol=1e-13 * np.abs(ref_P).max())
        np.testing.assert_array_equal(P[::5], ref_P[::5])  # the numpy path's own values
        if tangent:
            np.testing.assert_array_equal(D[::5], ref_D[::5])
            np.testing.assert_allclose(D, ref_D, rtol=0, atol=1e-13 * np.abs(ref_D).max())
        for key in ref:
            scale = max(np.abs(ref[key]).max(), 1.0)
            np.testing.assert_allclose(st[key], ref[key], rtol=0, atol=1e-13 * scale, err_msg=key)
    P = mat.piola(F, state)  # the stress-only kernel: the same fallback
    np.testing.assert_array_equal(P[::5], ref_P[::5])
    np.testing.assert_allclose(P, ref_P, rtol=0, atol=1e-13 * np.abs(ref_P).max())

    def forbidden(*args):
        raise AssertionError("the numba kernel must not run here")

    monkeypatch.setattr(mod, "cp_planar_fill", forbidden)
    monkeypatch.setattr(mod, "cp_planar_tangent_fill", forbidden)
    CrystalPlasticity(tangent="complex-step").update(F, state, tangent=True)
    CrystalPlasticity(active_set="reactivate").update(F, state)
    m3 = CrystalPlasticity("fcc")
    m3.update(np.broadcast_to(np.eye(3), (300, 3, 3)).copy(), m3.initial_state(300))


@pytest.mark.parametrize("slip", ["planar-2", "fcc", "hcp"])
def test_update_in_point_chunks_on_threads(monkeypatch, slip):
    """Above two chunks the update runs in fixed point chunks on the threads: P, every state
    array and the consistent tangent are bitwise the same for 1-3 threads, equal the
    one-batch update to round-off (BLAS / LAPACK batched products and solves differ in the
    last bit with the batch size), and the unsettled warning counts and indexes the points
    of the whole batch."""
    import warnings

    from pdlin.constitutive import crystal_plasticity as cpm

    mat = CrystalPlasticity(slip, max_passes=0) if slip == "fcc" else CrystalPlasticity(slip)
    rng = np.random.default_rng(7)
    *_, (state, F, _) = _t8_path(mat, rng, n=90, steps=6)

    def run() -> tuple:
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            out = mat.update(F, state, tangent=True)
        return out, [str(w.message) for w in rec]

    monkeypatch.setattr(cpm, "_UPDATE_CHUNK", 1 << 20)  # one batch
    ref, ref_msg = run()
    assert bool(ref_msg) == (slip == "fcc")  # fcc without re-activation passes: unsettled
    monkeypatch.setattr(cpm, "_UPDATE_CHUNK", 13)  # 7 chunks
    first = None
    try:
        for nt in (1, 2, 3):
            pdlin.set_num_threads(nt)
            (P, st, D), msg = run()
            assert msg == ref_msg
            assert st.keys() == ref[1].keys()
            if first is None:
                first = (P, st, D)
                tol = 1e-13
                np.testing.assert_allclose(P, ref[0], rtol=tol, atol=tol * np.abs(ref[0]).max())
                np.testing.assert_allclose(D, ref[2], rtol=tol, atol=tol * np.abs(ref[2]).max())
                for k in st:
                    scale = max(np.abs(ref[1][k]).max(), 1.0)
                    # 3D reorientation = arccos(½(tr Rᵉ - 1)): an ulp of the cosine near 1 is
                    # ~1e-8 of a small angle
                    atol = 1e-6 if k == "reorientation" else tol * scale
                    np.testing.assert_allclose(st[k], ref[1][k], rtol=0, atol=atol, err_msg=k)
            else:
                np.testing.assert_array_equal(P, first[0])
                np.testing.assert_array_equal(D, first[2])
                for k in st:
                    np.testing.assert_array_equal(st[k], first[1][k], err_msg=k)
    finally:
        pdlin.set_num_threads(None)


def test_piola_is_the_updates_stress_bitwise_and_keeps_the_numpy_scope(monkeypatch):
    """``piola`` (the kernel without the trial state) gives ``update``'s P bitwise on a
    plastic path, for points elastic, on one system and pruned; outside the kernel's scope
    (re-activation, fcc, fewer than _NUMBA_MIN_POINTS points) it is ``update(...)[0]``."""
    _numba_kernels(monkeypatch)
    mat = CrystalPlasticity()
    rng = np.random.default_rng(5)
    *_, (state, F, _) = _t8_path(mat, rng, n=300, steps=10)
    P_full, trial, _ = mat.update(F, state)
    assert 20 < trial["plastic"].sum() < 300  # seed 5: elastic and plastic points
    np.testing.assert_array_equal(mat.piola(F, state), P_full)
    for other in (CrystalPlasticity(active_set="reactivate"), CrystalPlasticity("fcc")):
        n = 300
        Fo = np.broadcast_to(np.eye(other.dim), (n, other.dim, other.dim)).copy()
        Fo[:, 0, 1] = np.linspace(0.0, 0.01, n)
        so = other.initial_state(n)
        np.testing.assert_array_equal(other.piola(Fo, so), other.update(Fo, so)[0])
    few = F[:10]
    sub = {k: (v[:10] if isinstance(v, np.ndarray) and v.ndim else v) for k, v in state.items()}
    np.testing.assert_array_equal(mat.piola(few, sub), mat.update(few, sub)[0])
    with pytest.raises(ShapeError, match="state_n"):
        mat.piola(F, sub)
