"""Luo, Ramazani & Sundararaghavan (2017) through the drivers: Newton, ADR and auto on
crystal-plasticity PD.

Plastic equilibria are not unique here (derived,
docs/theory/conventions.md#crystal-plasticity-conventions: h0 = 10 MPa, q = 1.4), so solver
cross-checks in plastic steps compare the homogenized (volume-averaged) stress of one step solved
from a shared committed state, never pointwise fields; the uniqueness control (T19, h0 = 1000 MPa, q
= 1) is compared pointwise.
"""

from __future__ import annotations

import shutil
import warnings

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse.linalg as spla

import pdlin

# Luo, Ramazani & Sundararaghavan (2017), Eq. 25, η = 0.002
SHEAR = 0.002 * np.array([[0.0, 1.0], [1.0, 0.0]])
COMPRESSION = 0.002 * np.array([[1.0, 0.0], [0.0, -1.0]])


@pytest.fixture(autouse=True)
def _quiet_active_set():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", pdlin.errors.ActiveSetWarning)
        yield


def polycrystal(n, L=SHEAR, seed=1, **cp):
    """Luo, Ramazani & Sundararaghavan (2017), Secs. 4-4.1: n x n pixels of the unit square, δ = h,
    ω = 1, 21 Voronoi grains, the boundary ring prescribed by u = (exp(L t) - I) x."""
    h = 1.0 / n
    cloud = pdlin.grid((n, n), spacing=h)
    bonds = pdlin.find_bonds(cloud, ratio=1.0, influence="constant")
    _, theta = pdlin.voronoi_polycrystal(cloud, 21, seed=seed)
    model = pdlin.Correspondence(material=pdlin.CrystalPlasticity(orientation=theta, **cp))
    bc = pdlin.Dirichlet.velocity_gradient("boundary", L)
    return pdlin.StaticProblem(model, cloud, bonds, dirichlet=[bc]), h


def spec_adr(h):
    """Luo, Ramazani & Sundararaghavan (2017), Eq. 12 with Λ = 1 per unit volume: nodal density V =
    h², Δt = h sqrt(1/E_max)."""
    return {"density": h * h, "dt": pdlin.solvers.adr_time_step(h, 2000.0)}


@pytest.mark.parametrize("n, dt", [(15, 1.491e-3), (25, 8.944e-4), (50, 4.472e-4)])
def test_t14_time_step_of_eq_12(n, dt):
    # Luo, Ramazani & Sundararaghavan (2017), Eq. 12: Δt = Δx sqrt(Λ / E_max), E_max = 2000 MPa, Λ =
    # 1 (1e-3 rel)
    assert pdlin.solvers.adr_time_step(1.0 / n, 2000.0) == pytest.approx(dt, rel=1e-3)


def _shared_state(tmp_path, prob, k, **kw):
    """Newton to step k, checkpointed; returns a function copying the checkpoint."""
    ck = tmp_path / "committed.npz"
    pdlin.solve_nonlinear(prob, steps=k, t_end=float(k), method="newton", checkpoint=ck, **kw)

    def copy(name):
        dst = tmp_path / name
        shutil.copy(ck, dst)
        return dst

    return copy


@pytest.mark.parametrize("method", ["newton", "adr"])
def test_t21_ghost_layer_single_crystal_matches_the_material_point(method):
    # derived (docs/theory/conventions.md#crystal-plasticity-conventions): with the ghost layer a
    # single crystal deforms affinely at every step, and its stress is the material-point stress of
    # pdlin.material_point (here θ = 15°, shear, 30 steps); the tangent predictor (Newton) is exact
    # to second order in the increment, ~1e-9. Newton starts from the committed-state (elastic)
    # tangent: in double slip with h0 = 10 MPa and four-neighbour families this operator is nearly
    # singular, and the default continuation tangent (the last increment's plastic one) turns
    # round-off into a non-affine drift (3.6e-5 of max|u| after 30 steps, measured 2026-11-25, at
    # residuals <= 1e-12 and the stress still within 1e-8): that is the predictor's conditioning,
    # not what T21 checks (the ghost-layer operator's affine response)
    n = 8
    g = pdlin.ghost_layer(pdlin.grid((n, n), spacing=1.0 / n))
    cloud = g.cloud
    bonds = pdlin.find_bonds(cloud, ratio=1.0, influence="constant")
    mat = pdlin.CrystalPlasticity(orientation=np.radians(15.0))
    fixed = np.union1d(g.ghost, cloud.point_set("outer_ring"))
    prob = pdlin.StaticProblem(
        pdlin.Correspondence(material=mat),
        cloud,
        bonds,
        dirichlet=[pdlin.Dirichlet.velocity_gradient(fixed, SHEAR)],
    )
    kw = spec_adr(1.0 / n) if method == "adr" else {"rtol": 1e-12, "predictor": "committed-tangent"}
    res = pdlin.solve_nonlinear(
        prob, steps=30, t_end=30.0, method=method, homogenize=np.arange(n * n), **kw
    )
    ref = pdlin.material_point(mat, "shear", steps=30, eta=0.002)
    # every step: homogenized stress = material point (1e-8 rel), field affine (1e-10 rel)
    scale = np.abs(ref.stress[:, 0]).max()
    np.testing.assert_allclose(res.homogenized_stress, ref.stress[:, 0], atol=1e-8 * scale)
    # material-point reference value (pdlin.material_point)
    np.testing.assert_allclose(res.homogenized_stress[-1, 0, 1], 18.099, atol=5e-4)
    # L = 0 at the free particles (1e-10 of the force scale) and the affine field (1e-8 rel)
    assert res.residuals.max() <= 1e-10
    for k, t in enumerate(res.times):
        exact = cloud.points @ (scipy.linalg.expm(SHEAR * t) - np.eye(2)).T
        assert np.abs(res.u[k] - exact).max() <= 1e-8 * np.abs(exact).max()
    if method == "adr":
        # the affine predictor is the solution: the absolute floor ends every step at once
        # (docs/theory/conventions.md#adaptive-dynamic-relaxation: the relative criteria of Eqs.
        # 19-20 degenerate with an exact initial guess)
        assert res.iterations.max() == 0
    else:
        assert res.iterations.max() <= 2


def test_t17_elastic_step_adr_vs_newton_error_decreases_with_e_l():
    # step 1 (elastic, unique): max|Δu|/max|u| <= 10 e_l, decreasing in e_l
    prob, h = polycrystal(12)
    newton = pdlin.solve_nonlinear(prob, steps=1, t_end=1.0, method="newton", rtol=1e-12)
    errs = []
    for e_l in (1e-4, 1e-6, 1e-8):
        adr = pdlin.solve_nonlinear(
            prob, steps=1, t_end=1.0, method="adr", e_l=e_l, predictor="previous", **spec_adr(h)
        )
        errs.append(np.abs(adr.u[-1] - newton.u[-1]).max() / np.abs(newton.u[-1]).max())
        assert errs[-1] <= 10 * e_l
    assert errs[0] > errs[1] > errs[2]


def test_t18_plastic_step_homogenized_stress_adr_vs_newton(tmp_path):
    # from a shared committed state (Newton to step 5, plastic), one more step with Newton and with
    # ADR: ‖Δσ̄‖ <= 1e-3 ‖σ̄‖; each residual below its criterion. Newton with the elastic
    # (committed-state) tangent predictor, as in the paper's implicit scheme; the default
    # continuation predictor starts from another point and reaches another equilibrium: 1.6e-3 from
    # ADR's here. Both predictors stay within the band measured over 18 shared-state steps (12²,
    # 20², 30², steps 5-10, 2026-11-25): Newton vs ADR up to 1.6e-3 (continuation) and 1.9e-3
    # (elastic predictor) -- wider than the 3.8e-4 of an independent reference implementation, so
    # the default is held to 2e-3, the elastic one to 1e-3
    prob, h = polycrystal(12)
    copy = _shared_state(tmp_path, prob, 5)
    kw = {"times": np.arange(1.0, 7.0), "t_end": 6.0, "resume": "branch"}  # other drivers
    new = pdlin.solve_nonlinear(
        prob, method="newton", checkpoint=copy("n.npz"), predictor="committed-tangent", **kw
    )
    cont = pdlin.solve_nonlinear(prob, method="newton", checkpoint=copy("c.npz"), **kw)
    adr = pdlin.solve_nonlinear(
        prob, method="adr", e_l=1e-8, checkpoint=copy("a.npz"), **kw, **spec_adr(h)
    )
    assert new.resumed_from == adr.resumed_from == cont.resumed_from == 5
    plastic = np.asarray(new.states[-1]["plastic"], dtype=bool)
    assert plastic.mean() > 0.3  # a plastic step (reference runs: ~30 % plastic at step 3)
    s_n, s_a = new.homogenized_stress[-1], adr.homogenized_stress[-1]
    assert np.linalg.norm(s_a - s_n) <= 1e-3 * np.linalg.norm(s_n)
    s_c = cont.homogenized_stress[-1]
    assert np.linalg.norm(s_a - s_c) <= 2e-3 * np.linalg.norm(s_c)
    assert new.residuals[-1] <= 1e-8 and adr.e1[-1] < 1e-8 and adr.e2[-1] < 1e-8
    assert cont.residuals[-1] <= 1e-8


def test_killed_plastic_run_resumes_bitwise(tmp_path):
    # a run killed after a plastic step and resumed from its checkpoint repeats the uninterrupted
    # run exactly: the checkpoint carries the state at the start of the last increment, from which
    # the default (continuation) tangent predictor starts the next step; without it the resumed step
    # 6 starts from the elastic tangent and lands on a different equilibrium (derived,
    # docs/theory/conventions.md#crystal-plasticity-conventions)
    prob, _ = polycrystal(12)
    kw = {"steps": 8, "t_end": 8.0, "method": "newton"}
    full = pdlin.solve_nonlinear(prob, **kw)
    assert np.asarray(full.states[4]["plastic"], dtype=bool).any()  # step 5 is plastic
    ck = tmp_path / "run.npz"

    class Killed(Exception):
        pass

    def kill(msg: str) -> None:
        if msg.startswith("step 5/8"):
            raise Killed

    with pytest.raises(Killed):
        pdlin.solve_nonlinear(prob, checkpoint=ck, progress=kill, **kw)
    res = pdlin.solve_nonlinear(prob, checkpoint=ck, resume=True, **kw)
    assert res.resumed_from == 5
    assert res.iterations.tolist() == full.iterations.tolist()
    np.testing.assert_array_equal(res.u, full.u)
    np.testing.assert_array_equal(res.homogenized_stress, full.homogenized_stress)


def test_t19_uniqueness_control_pointwise_agreement(tmp_path):
    # uniqueness control (derived): with h0 = 1000 MPa and q = 1 the plastic step has one solution:
    # ADR and Newton agree pointwise, max|Δu|/max|u| <= 1e-6
    prob, h = polycrystal(10, hardening={"h0": 1000.0, "q": 1.0})
    copy = _shared_state(tmp_path, prob, 4)
    kw = {"times": np.arange(1.0, 6.0), "t_end": 5.0, "resume": "branch"}  # other drivers
    new = pdlin.solve_nonlinear(prob, method="newton", rtol=1e-12, checkpoint=copy("n.npz"), **kw)
    adr = pdlin.solve_nonlinear(
        prob, method="adr", e_l=1e-10, checkpoint=copy("a.npz"), **kw, **spec_adr(h)
    )
    assert np.asarray(new.states[-1]["plastic"], dtype=bool).any()
    du = np.abs(adr.u[-1] - new.u[-1]).max() / np.abs(new.u[-1]).max()
    assert du <= 1e-6


def _lambda_max(prob, h):
    """λ_max(Λ⁻¹ K) of the elastic tangent on the free DOFs, Λ = h² (Luo, Ramazani & Sundararaghavan
    (2017), Sec. 2.2)."""
    system = pdlin.constrained_system(prob)
    r = system.respond(np.zeros(system.ndof), system.initial_state(), tangent=True)
    K = r.tangent.tocsr()[system.free][:, system.free] / (h * h)
    return float(spla.eigs(K, k=1, which="LR", return_eigenvectors=False)[0].real)


def test_t15_adr_stability_limit():
    # stability limit of the central-difference update (15 x 15 shear): at 0.98 x 2/sqrt(λ_max) ADR
    # converges (4 steps, into the plastic range); at 1.02 x and 1.1 x it stalls: yielding bounds
    # the forces, so no overflow, but no convergence in 3000 iterations
    prob, h = polycrystal(15)
    lmax = _lambda_max(prob, h)
    # reference values of an independent implementation: λ_max = 1.4-1.6e6 at n = 15; Eq. 12 sits at
    # 0.88-0.93 of the limit
    assert 1.3e6 <= lmax <= 1.7e6
    dt_c = 2.0 / np.sqrt(lmax)
    assert 0.85 <= spec_adr(h)["dt"] / dt_c <= 0.95
    kw = {"t_end": 4.0, "method": "adr", "density": h * h, "adr_maxiter": 3000}
    ok = pdlin.solve_nonlinear(prob, steps=4, dt=0.98 * dt_c, **kw)
    assert ok.iterations.max() < 3000
    for factor in (1.02, 1.1):
        with pytest.raises(pdlin.ConvergenceError, match="no convergence in 3000 iterations"):
            pdlin.solve_nonlinear(prob, steps=4, dt=factor * dt_c, **kw)


@pytest.mark.slow
@pytest.mark.parametrize("L", [SHEAR, COMPRESSION], ids=["shear", "compression"])
def test_t16_thirty_steps_all_methods_converge_and_agree_homogenized(L):
    # 15 x 15: every method converges in 30/30 steps; along the independent (diverging,
    # docs/theory/conventions.md#crystal-plasticity-conventions) histories the homogenized stress of
    # Newton and ADR stays within 5e-3 (measured up to ~2e-3 in compression with the active-set
    # pruning; an independent reference implementation found ≤ 6e-4 on its own seeded maps) and auto
    # needs no fallback or falls back and says so
    prob, h = polycrystal(15, L=L)
    runs = {
        "newton": pdlin.solve_nonlinear(prob, steps=30, t_end=30.0, method="newton"),
        "adr": pdlin.solve_nonlinear(prob, steps=30, t_end=30.0, method="adr", **spec_adr(h)),
        "auto": pdlin.solve_nonlinear(prob, steps=30, t_end=30.0, method="auto"),
    }
    ref = runs["newton"].homogenized_stress
    for name, res in runs.items():
        assert res.n_steps == 30
        diff = np.linalg.norm(res.homogenized_stress - ref, axis=(1, 2))
        assert np.all(diff <= 5e-3 * np.linalg.norm(ref, axis=(1, 2))), name
    assert all(m in ("newton", "adr (newton failed)") for m in runs["auto"].methods)
    # trend of the reference runs: the homogenized stress grows and saturates (near-perfect
    # plasticity)
    comp = 0 if L is SHEAR else 1
    sig = ref[:, comp, 1 - comp] if L is SHEAR else ref[:, 1, 1]
    mag = np.abs(sig)
    assert mag[29] > mag[9] > mag[2] > mag[0]
    assert mag[29] - mag[19] < 0.2 * (mag[2] - mag[0])


@pytest.mark.slow
def test_t20_adaptive_damping_beats_constant_c500():
    # Luo, Ramazani & Sundararaghavan (2017), Sec. 4.1 (25 x 25 shear, steps 1-12): adaptive damping
    # needs fewer iterations than constant c = 500; its damping is largest early in a step
    prob, h = polycrystal(25)
    kw = {"steps": 12, "t_end": 12.0, "method": "adr", **spec_adr(h)}
    adaptive = pdlin.solve_nonlinear(prob, **kw)
    const = pdlin.solve_nonlinear(prob, damping=500.0, **kw)
    assert adaptive.iterations.sum() < const.iterations.sum()
    c = np.concatenate(adaptive.damping)
    m = max(1, c.size // 10)
    assert c[:m].max() >= 3 * c[-m:].max()


@pytest.mark.parametrize("slip", ["fcc", "hcp"])
def test_3d_polycrystal_runs_through_the_drivers(slip):
    # Javaheri et al. (2022), Sec. III.D in miniature: a 3D polycrystal (fcc / hcp with its 18
    # systems) under F = exp(L t), L ∝ diag(1, -1/2, -1/2), on a boundary layer; Newton and ADR
    # agree on the homogenized stress of an elastic step exactly and stay within 2e-3 in plastic
    # steps
    n = 5
    cloud = pdlin.grid((n, n, n), spacing=1.0 / n)
    bonds = pdlin.find_bonds(cloud, ratio=1.0, influence="constant")
    _, R = pdlin.voronoi_polycrystal(cloud, 6, seed=0)
    model = pdlin.Correspondence(material=pdlin.CrystalPlasticity(slip, orientation=R))
    L = 1e-4 * np.diag([1.0, -0.5, -0.5])
    prob = pdlin.StaticProblem(
        model, cloud, bonds, dirichlet=[pdlin.Dirichlet.velocity_gradient("boundary", L)]
    )
    new = pdlin.solve_nonlinear(prob, steps=6, t_end=6.0, method="newton")
    adr = pdlin.solve_nonlinear(prob, steps=6, t_end=6.0, method="adr", e_l=1e-8)
    plastic = [float(np.mean(st["plastic"])) for st in new.states]
    assert plastic[0] == 0.0 and plastic[-1] > 0.05  # elastic first step, then yielding
    ref = np.linalg.norm(new.homogenized_stress, axis=(1, 2))
    diff = np.linalg.norm(adr.homogenized_stress - new.homogenized_stress, axis=(1, 2))
    assert diff[0] <= 1e-6 * ref[0] and np.all(diff <= 2e-3 * ref)
    # uniaxial-type loading: the axial mean stress is tensile and grows
    s11 = new.homogenized_stress[:, 0, 0]
    assert np.all(np.diff(s11) > 0) and s11[0] > 0


@pytest.mark.parametrize("eta", [0.001, 0.002])
def test_newton_elastic_steps_take_one_iteration(eta):
    # issue 11 aim "Newton elastic steps in one iteration", on the Luo, Ramazani & Sundararaghavan
    # (2017) polycrystal (12 x 12, 21 grains): steps in which no point slips take one Newton
    # iteration after the default (second-order) predictor. With the first-order tangent
    # predictor step 1 at η = 0.002 took two: its finite-strain residual after one correction
    # (2.9e-8, measured) sits just above rtol = 1e-8 (issue 35, item 3).
    prob, _ = polycrystal(12, L=SHEAR * (eta / 0.002))
    res = pdlin.solve_nonlinear(prob, steps=4, t_end=4.0, method="newton", keep_states=True)
    elastic = [k for k in range(4) if not np.any(res.state_at(k)["dgamma"] != 0.0)]
    assert elastic[:2] == [0, 1]  # steps 1 and 2 are elastic at both rates (measured)
    for k in elastic:
        assert res.iterations[k] == 1, (k, res.iterations)
    if eta == 0.002:  # the old path, still selectable: two iterations in step 1
        old = pdlin.solve_nonlinear(
            prob, times=[1.0], t_end=4.0, method="newton", predictor="tangent"
        )
        assert old.iterations.tolist() == [2]


def test_newton_relaxation_carries_a_stalled_plastic_step():
    # 30 x 30 polycrystal, shear, steps 1-8 at η t = 0.002 t: plain Newton needs 17
    # iterations in step 8 (a 5-iteration plateau at active-set switches, measured with
    # relax=0), so with a budget of 12 and no cut-back it fails; the stall relaxation
    # (ADR sweeps from the stalled iterate) carries the step within the budget. The
    # committed-state (elastic) tangent predictor: the default continuation tangent
    # takes step 8 in 5 iterations (measured 2026-11-25) and would not stall
    prob, _ = polycrystal(30)
    kw = {
        "times": np.arange(1.0, 9.0),
        "t_end": 30.0,
        "method": "newton",
        "max_cutbacks": 0,
        "predictor": "committed-tangent",
    }
    with pytest.raises(pdlin.errors.ConvergenceError, match="load step 8"):
        pdlin.solve_nonlinear(prob, maxiter=12, relax=0, **kw)
    res = pdlin.solve_nonlinear(prob, maxiter=12, relax=50, **kw)
    assert res.relaxations[7] > 0 and res.iterations[7] <= 12
    assert res.relaxations[:3].sum() == 0  # elastic and nearly elastic steps never stall
    assert res.residuals.max() <= 1e-8
    # plain Newton with a larger budget: identical up to step 7 (no relaxation there); step 8
    # reaches another equilibrium (plastic equilibria are not unique,
    # conventions.md#crystal-plasticity-conventions), so its homogenized stress is compared with
    # test_t18's ‖Δσ̄‖ <= 1e-3 ‖σ̄‖
    ref = pdlin.solve_nonlinear(prob, maxiter=25, relax=0, **kw)
    np.testing.assert_array_equal(res.u[:7], ref.u[:7])
    s_r, s_n = res.homogenized_stress[7], ref.homogenized_stress[7]
    assert np.linalg.norm(s_r - s_n) <= 1e-3 * np.linalg.norm(s_n)
