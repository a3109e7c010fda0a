"""The rate-dependent (power-law) slip rule of ``CrystalPlasticity(rate_exponent=...)``.

Backward Euler of ``γ̇ = γ̇₀ |τ/s|ⁿ sign τ`` (Peirce, Asaro & Needleman 1983; Kalidindi,
Bronkhorst & Anand 1992) on the Eq. 31 linearization of Luo, Ramazani & Sundararaghavan
(2017), Appendix: its limit n → ∞ is the paper's rate-independent update, its tangent is
consistent, and the load-step drivers give it the time increment.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

import pdlin
from pdlin.constitutive import CrystalPlasticity, material_point
from pdlin.errors import InputError

SHEAR = np.array([[0.0, 1.0], [1.0, 0.0]])
THETA = np.radians([0.0, 30.0, 60.0, -45.0])


def _path(mat, L, steps, eta, orientation, dt=1.0):
    """Run ``F = exp(η L t)`` with the time increment ``dt`` per step; Cauchy σ per step."""
    n, d = len(orientation), mat.dim
    st = mat.initial_state(n, orientation)
    out = []
    for k in range(1, steps + 1):
        F = np.broadcast_to(expm(eta * k * L), (n, d, d))
        P, st, _ = mat.update(F, {**st, "dt": np.asarray(dt)})
        out.append(mat.cauchy(P, F))
    return np.array(out), st


def test_rate_independent_limit_and_overstress_bound():
    ri = material_point(CrystalPlasticity(), "shear", orientation=THETA)
    errs = []
    for n in (25, 50, 100, 200):
        mat = CrystalPlasticity(rate_exponent=n, reference_rate=0.002)
        r = material_point(mat, "shear", orientation=THETA)
        err = np.abs(r.stress[:, :, 0, 1] - ri.stress[:, :, 0, 1]).max()
        errs.append(err)
        # slip rates stay within 20x the reference rate 0.002 (per unit step), so the flow
        # stress s (rate / γ̇₀)^(1/n) is within a factor 20^(1/n) of s: the stress differs
        # from the rate-independent one by less than that relative overstress (of |σ| ≤ 25 MPa)
        assert err <= (20.0 ** (1.0 / n) - 1.0) * 25.0
    # and converges monotonically to it, at least halving per doubling of n (≈ 1/n)
    assert all(b <= 0.6 * a for a, b in zip(errs, errs[1:], strict=False)), errs
    # the elastic steps are the rate-independent ones to round-off plus the tiny creep
    # |τ/s|^n of the loaded systems (at step 1, |τ/s| ≤ 0.8: ≤ 0.8^200 ≈ 4e-20 of slip)
    mat = CrystalPlasticity(rate_exponent=200, reference_rate=0.002)
    r = material_point(mat, "shear", orientation=THETA)
    np.testing.assert_allclose(r.stress[0], ri.stress[0], rtol=0, atol=1e-12)


def test_rate_dependence_is_physical():
    """Faster loading (smaller dt for the same strain) raises the flow stress by (rate)^(1/n)."""
    mat = CrystalPlasticity(rate_exponent=20, reference_rate=0.002)
    th = np.array([0.0])
    slow, _ = _path(mat, SHEAR, 40, 0.002, th, dt=1.0)
    fast, _ = _path(mat, SHEAR, 40, 0.002, th, dt=0.01)
    ratio = fast[-1, 0, 0, 1] / slow[-1, 0, 0, 1]
    # saturated flow at θ = 0: both systems slip at the rate ratio 100; the resistances
    # differ by the (rate-dependent) hardening history, so the ratio is near 100^(1/20)
    assert 1.15 < ratio < 100.0 ** (1.0 / 20.0) * 1.05


@pytest.mark.parametrize("slip", ["planar-2", "fcc", "hcp"])
def test_rate_tangent_is_consistent(slip):
    rng = np.random.default_rng(3)
    mat = CrystalPlasticity(slip, rate_exponent=30, reference_rate=0.002)
    d, n = mat.dim, 5
    ori = rng.uniform(-1, 1, n) if d == 2 else rng.uniform(0, 2, (n, 3))
    L = rng.normal(size=(d, d)) * (1.0 if d == 2 else 0.3)
    eta = 0.002 if d == 2 else 0.0005
    st = mat.initial_state(n, ori)
    for k in range(1, 6):
        F = np.broadcast_to(expm(eta * k * L), (n, d, d)).copy()
        st_in = {**st, "dt": np.asarray(1.0)}
        P, new, D = mat.update(F, st_in, tangent=True)
        st = new
    assert np.any(new["plastic"])  # the last step is plastic
    h = 1e-6 * 2000.0 / np.abs(mat.C).max()
    Dfd = np.empty_like(D)
    for a in range(d):
        for b in range(d):
            E = np.zeros((d, d))
            E[a, b] = h
            Dfd[..., a, b] = (mat.update(F + E, st_in)[0] - mat.update(F - E, st_in)[0]) / (2 * h)
    scale = np.abs(Dfd).reshape(n, -1).max(axis=1)
    err = np.abs(D - Dfd).reshape(n, -1).max(axis=1) / scale
    assert np.all(err <= 1e-6), err  # central differences: O(h²) + round-off / h ≈ 1e-8


def test_rate_arguments_and_missing_time_increment():
    with pytest.raises(InputError, match="rate_exponent must be a finite number >= 1"):
        CrystalPlasticity(rate_exponent=0.5)
    with pytest.raises(InputError, match="rate_exponent must be a number"):
        CrystalPlasticity(rate_exponent=True)
    with pytest.raises(InputError, match="reference_rate must be > 0"):
        CrystalPlasticity(rate_exponent=50, reference_rate=0.0)
    with pytest.raises(InputError, match="complex-step"):
        CrystalPlasticity(rate_exponent=50, tangent="complex-step")
    mat = CrystalPlasticity(rate_exponent=50)
    st = mat.initial_state(2)
    # F = I: no resolved shear, no time increment needed (the models' elastic set-up)
    P, _, _ = mat.update(np.broadcast_to(np.eye(2), (2, 2, 2)), st, tangent=True)
    assert np.all(P == 0.0)
    F = np.broadcast_to(expm(0.002 * SHEAR), (2, 2, 2))
    with pytest.raises(InputError, match=r"state_n\['dt'\] \(the time increment\) is required"):
        mat.update(F, st)
    with pytest.raises(InputError, match=r"state_n\['dt'\] must be a finite number >= 0"):
        mat.update(F, {**st, "dt": np.asarray(-1.0)})
    assert "rate_exponent=50" in repr(mat)


def test_too_large_increment_fails_the_update_not_silently():
    mat = CrystalPlasticity(rate_exponent=200, reference_rate=0.002)
    st = mat.initial_state(1)
    F = expm(0.5 * SHEAR)[None]  # τ_tr ≈ 100 s0: ≈ 200 ln 100 ≈ 900 iterations from g = 0
    with pytest.raises(pdlin.errors.ConvergenceError, match="did not converge|overflowed"):
        mat.update(F, {**st, "dt": np.asarray(1.0)})


def test_newton_carries_the_rate_dependent_polycrystal():
    """A plastic polycrystal (no control) where rate-independent Newton needs cut-backs."""
    n = 20
    h = 1.0 / n
    cloud = pdlin.grid((n, n), spacing=h)
    bonds = pdlin.find_bonds(cloud, ratio=1.0, influence="constant")
    _, theta = pdlin.voronoi_polycrystal(cloud, 5, seed=1)
    L = 0.002 * SHEAR
    bc = pdlin.Dirichlet.velocity_gradient("boundary", L)

    def run(dt_steps, **kw):
        mat = CrystalPlasticity(orientation=theta, rate_exponent=50, reference_rate=0.002, **kw)
        prob = pdlin.StaticProblem(pdlin.Correspondence(material=mat), cloud, bonds, dirichlet=[bc])
        return pdlin.solve_nonlinear(prob, times=dt_steps, t_end=12.0, method="newton")

    res = run(np.arange(1.0, 13.0))
    assert np.all(res.cutbacks == 0)
    assert res.iterations.max() <= 8
    assert np.mean(res.state["plastic"]) > 0.5  # the run is plastic
    # the same path in half the time increments: backward Euler is first order in dt, and
    # the homogenized stress agrees to the time-discretization error (well under 1 %)
    fine = run(np.arange(0.5, 12.01, 0.5))
    s12, f12 = res.homogenized_stress[-1, 0, 1], fine.homogenized_stress[-1, 0, 1]
    assert abs(s12 - f12) <= 1e-2 * abs(f12)


def test_compiled_local_newton_matches_numpy(monkeypatch):
    """The numba per-point Newton solves the same equations as the numpy path."""
    pytest.importorskip("numba")
    from pdlin.constitutive import crystal_plasticity as cpmod

    rng = np.random.default_rng(7)
    for slip in ("planar-2", "fcc"):
        mat = CrystalPlasticity(slip, rate_exponent=40, reference_rate=0.002)
        d, n = mat.dim, 400  # above _RATE_NUMBA_MIN_POINTS: the compiled kernel
        ori = rng.uniform(-1, 1, n) if d == 2 else rng.uniform(0, 2, (n, 3))
        L = rng.normal(size=(d, d)) * (1.0 if d == 2 else 0.3)
        st = mat.initial_state(n, ori)
        out = {}
        for k in range(1, 5):
            F = np.broadcast_to(expm((0.002 if d == 2 else 0.0005) * k * L), (n, d, d))
            st_in = {**st, "dt": np.asarray(1.0)}
            out["numba"] = mat.update(F, st_in, tangent=True)
            with monkeypatch.context() as mp:
                mp.setattr(cpmod, "_RATE_NUMBA_MIN_POINTS", 10**9)
                out["numpy"] = mat.update(F, st_in, tangent=True)
            st = out["numba"][1]
        (Pa, sa, Da), (Pb, sb, Db) = out["numba"], out["numpy"]
        assert np.any(sa["plastic"])
        # both stop at corrections below 1e-12 |Δγ|: the same solution to ≈ 1e-12
        np.testing.assert_allclose(
            sa["dgamma"], sb["dgamma"], rtol=0, atol=1e-11 * sa["dgamma"].max()
        )
        np.testing.assert_allclose(Pa, Pb, rtol=0, atol=1e-9 * np.abs(Pb).max())
        np.testing.assert_allclose(Da, Db, rtol=0, atol=1e-8 * np.abs(Db).max())


SCENE = """
name = "cp_rate"
[geometry]
type = "grid"
shape = [8, 8]
spacing = 0.125
[material]
type = "crystal-plasticity"
orientation = 0.2617993877991494
rate_exponent = 100
reference_rate = 0.002
[model]
type = "correspondence"
[horizon]
ratio = 1.0
influence = "constant"
[[dirichlet]]
set = "boundary"
velocity_gradient = [[0.0, 0.002], [0.002, 0.0]]
[solver]
nonlinear = "newton"
steps = 6
t_end = 6.0
"""


def test_scene_keys_and_bitwise_resume(tmp_path):
    from pdlin.scene import load_scene

    path = tmp_path / "cp_rate.toml"
    path.write_text(SCENE)
    sc = load_scene(path)
    mat = sc.problem.model.material
    assert (mat.rate_exponent, mat.reference_rate) == (100.0, 0.002)
    full = pdlin.solve_nonlinear(sc.problem, steps=6, t_end=6.0, method="newton")
    assert np.any(full.state["plastic"])  # θ = 15° yields at step 3 (material-point tables)
    # killed after 4 steps, resumed to 6: the increments' dt (and the predictor's state of the
    # last increment) come back from the checkpoint, so the run continues bitwise
    ck = tmp_path / "run.npz"
    pdlin.solve_nonlinear(
        sc.problem, times=[1.0, 2.0, 3.0, 4.0], t_end=6.0, method="newton", checkpoint=ck
    )
    res = pdlin.solve_nonlinear(
        sc.problem, steps=6, t_end=6.0, method="newton", checkpoint=ck, resume=True
    )
    assert res.resumed_from == 4
    np.testing.assert_array_equal(res.u, full.u)
    bad = path.read_text().replace("rate_exponent = 100", "rate_exponent = 0.5")
    path.write_text(bad)
    with pytest.raises(InputError, match="rate_exponent must be a finite number >= 1"):
        load_scene(path)


def test_the_documented_large_scene_runs_reduced(tmp_path):
    """The 10⁵ scene of docs/crystal_plasticity.md, on a 20 x 20 grid for 4 steps."""
    import re
    from pathlib import Path

    from pdlin.scene.scene import scene_from_dict, tomllib

    page = Path(__file__).resolve().parents[2] / "docs" / "crystal_plasticity.md"
    block = re.search(r'```toml\n(name = "cp_shear_large".*?)```', page.read_text(), re.S)
    assert block is not None
    data = tomllib.loads(block.group(1))
    assert data["geometry"]["shape"] == [316, 316]  # the documented size: 99,856 particles
    data["geometry"].update(shape=[20, 20], spacing=1.0 / 20)
    data["solver"].update(steps=4, t_end=4.0)
    data["solver"].pop("checkpoint")
    sc = scene_from_dict(data, base_dir=tmp_path)
    assert sc.problem.model.material.rate_exponent == 100.0
    res = pdlin.solve_nonlinear(sc.problem, steps=4, t_end=4.0, method="newton")
    assert np.all(res.cutbacks == 0) and np.any(res.state["plastic"])


def test_a_failed_update_at_the_predictor_cuts_back():
    """The second-order predictor's evaluation at u₁ may fail the local Newton (found at 10⁵).

    One load step of 10x the paper's increment: the trial stress is ≈ 4 s, beyond what the
    power law's local Newton (n = 200) solves from Δγ = 0 in its 200 iterations; the
    increment is cut back instead of the run failing.
    """
    cloud = pdlin.grid((6, 6), spacing=1 / 6)
    bonds = pdlin.find_bonds(cloud, ratio=1.0, influence="constant")
    mat = CrystalPlasticity(rate_exponent=200, reference_rate=0.02)
    bc = pdlin.Dirichlet.velocity_gradient("boundary", 0.02 * SHEAR)
    prob = pdlin.StaticProblem(pdlin.Correspondence(material=mat), cloud, bonds, dirichlet=[bc])
    res = pdlin.solve_nonlinear(prob, times=[1.0, 2.0], t_end=2.0, method="newton")
    assert res.cutbacks.sum() >= 1 and np.any(res.state["plastic"])


def test_compiled_update_at_a_degenerate_f_is_a_non_finite_error():
    """numba raises ZeroDivisionError where numpy gives inf / nan (found by the 10⁵ ADR run)."""
    pytest.importorskip("numba")
    cp = CrystalPlasticity()  # planar double slip, pruning: the compiled kernel from 8,192 points
    n = 8192
    with pytest.raises(pdlin.errors.NonFiniteError, match="degenerate deformation gradient"):
        cp.update(np.zeros((n, 2, 2)), cp.initial_state(n))
