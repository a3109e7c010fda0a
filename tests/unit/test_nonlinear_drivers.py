"""Load-stepped drivers (Newton, ADR, auto) on the constrained system."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import scipy.sparse as sp

import pdlin
from pdlin.errors import ConvergenceError, InputError
from pdlin.models.base import Model, Response
from pdlin.solvers import StepFailed


class CubicChain(Model):
    """1D chain of hardening springs, bond force k (e + β e³), e = u_j - u_i.

    Its state keeps the largest |e| seen per point (a history variable), to
    check that drivers commit states only at converged steps.
    """

    nonlinear = True

    def __init__(self, k: Any = 1.0, beta: float = 1e4) -> None:
        self.k, self.beta = np.asarray(k, dtype=float), beta

    def _kb(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        k = np.broadcast_to(self.k, (int(max(i.max(), j.max())) + 1,))
        return 0.5 * (k[i] + k[j])

    def _pairs(self, bonds: Any) -> tuple[np.ndarray, np.ndarray]:
        keep = bonds.i < bonds.j
        return bonds.i[keep], bonds.j[keep]

    def stiffness(self, cloud: Any, bonds: Any) -> sp.sparray:
        i, j = self._pairs(bonds)
        n = cloud.n
        w = self._kb(i, j)
        A = sp.coo_array((np.r_[w, w, -w, -w], (np.r_[i, j, i, j], np.r_[i, j, j, i])), (n, n))
        return sp.bsr_array(A.tocsr(), blocksize=(1, 1))

    def internal_force(self, cloud: Any, bonds: Any, u: Any, *, linear: bool = True) -> Any:
        return -(self.stiffness(cloud, bonds) @ np.ravel(u)).reshape(-1, 1)

    def initial_state(self, cloud: Any, bonds: Any) -> dict[str, np.ndarray]:
        return {"emax": np.zeros(cloud.n)}

    def respond(self, cloud: Any, bonds: Any, u: Any, state: Any, *, tangent: bool = False):
        i, j = self._pairs(bonds)
        x = np.ravel(u)
        e = x[j] - x[i]
        t = self._kb(i, j) * (e + self.beta * e**3)
        f = np.zeros(cloud.n)
        np.add.at(f, i, t)
        np.add.at(f, j, -t)
        emax = np.maximum(state["emax"], 0.0)
        np.maximum.at(emax, i, np.abs(e))
        K = None
        if tangent:
            kt = self._kb(i, j) * (1.0 + 3.0 * self.beta * e**2)
            n = cloud.n
            A = sp.coo_array(
                (np.r_[kt, kt, -kt, -kt], (np.r_[i, j, i, j], np.r_[i, j, j, i])), (n, n)
            )
            K = sp.bsr_array(A.tocsr(), blocksize=(1, 1))
        return Response(f.reshape(-1, 1), {"emax": emax}, K, None, cloud.n)


def _chain(n: int = 21, u_end: float = 0.05, beta: float = 1e4, graded: bool = False):
    cloud = pdlin.grid((n,), spacing=1.0 / (n - 1), origin=[-0.5 / (n - 1)])
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    k = 1.0 + 9.0 * cloud.points[:, 0] if graded else 1.0
    return pdlin.StaticProblem(
        CubicChain(k=k, beta=beta),
        cloud,
        bonds,
        dirichlet=[pdlin.Dirichlet([0], 0.0), pdlin.Dirichlet([n - 1], u_end)],
    )


def test_newton_solves_the_hardening_chain_and_commits_history():
    prob = _chain()
    res = pdlin.solve_nonlinear(prob, steps=3, method="newton")
    # uniform chain: the exact solution is linear in x whatever the spring law
    x = prob.cloud.points[:, 0]
    u_exact = 0.05 * (x - x[0]) / (x[-1] - x[0])
    np.testing.assert_allclose(res.u[-1, :, 0], u_exact, rtol=1e-9, atol=1e-12)
    assert res.methods == ["newton"] * 3 and res.cutbacks.tolist() == [0, 0, 0]
    # the committed history variable grows with the load: e = u_end / 20 per bond
    np.testing.assert_allclose(res.states[-1]["emax"][:-1], 0.05 / 20, rtol=1e-9)
    np.testing.assert_allclose(res.states[0]["emax"][:-1], 0.05 / 60, rtol=1e-9)
    # the support pulls the right end with the spring force k (e + β e³)
    e = 0.05 / 20
    np.testing.assert_allclose(res.reactions[-1, -1, 0], e + 1e4 * e**3, rtol=1e-9)
    np.testing.assert_allclose(res.reactions[-1].sum(), 0.0, atol=1e-12)


class SpyChain(CubicChain):
    """The cubic chain, recording ``(u, state['emax'])`` of every tangent evaluation."""

    def __init__(self, *args: Any, **kw: Any) -> None:
        super().__init__(*args, **kw)
        self.tangent_calls: list[tuple[np.ndarray, np.ndarray]] = []

    def respond(self, cloud: Any, bonds: Any, u: Any, state: Any, *, tangent: bool = False):
        if tangent:
            self.tangent_calls.append((np.ravel(u).copy(), state["emax"].copy()))
        return super().respond(cloud, bonds, u, state, tangent=tangent)


@pytest.mark.parametrize("predictor", ["tangent", "committed-tangent"])
def test_tangent_predictor_states(predictor):
    # the default tangent predictor takes K_T at the committed solution u_k from the state
    # at the start of the increment that reached u_k (the last Newton tangent: its history
    # carried on), the committed-tangent predictor from the committed state; after
    # _RESTART_ELASTIC failed tries in a row the retries start from the committed state.
    # Graded chain, maxiter=1: the first increments of steps 2 and 3 fail 3 and 2 times
    # (counts measured 2026-11-25)
    from pdlin.solvers.stepping import _RESTART_ELASTIC

    base = _chain(u_end=0.2, graded=True)
    spy = SpyChain(k=base.model.k)
    prob = pdlin.StaticProblem(spy, base.cloud, base.bonds, dirichlet=base.dirichlet)
    ends: list[int] = []  # tangent calls made when each step ended
    res = pdlin.solve_nonlinear(
        prob,
        steps=3,
        method="newton",
        maxiter=1,
        predictor=predictor,
        progress=lambda msg: msg.startswith("step ") and ends.append(len(spy.tangent_calls)),
    )
    tries = []
    for k in (1, 2):  # steps 2 and 3: the tangent calls at u_k are tries of the first increment
        calls = spy.tangent_calls[ends[k - 1] : ends[k]]
        at = [st for u, st in calls if np.array_equal(u, res.u[k - 1].ravel())]
        committed = res.states[k - 1]["emax"]
        tries.append(len(at))
        if predictor == "committed-tangent":
            assert all(np.array_equal(st, committed) for st in at)
            continue
        # continuation (less history than committed), then the committed state
        for st in at[:_RESTART_ELASTIC]:
            assert np.all(st <= committed) and not np.array_equal(st, committed)
        for st in at[_RESTART_ELASTIC:]:
            assert np.array_equal(st, committed)
    assert max(tries) > _RESTART_ELASTIC  # a restart from the committed state happened


def test_newton_converges_quadratically():
    prob = _chain(u_end=0.2, graded=True)
    res = pdlin.solve_nonlinear(prob, steps=1, method="newton", predictor="tangent")
    # hardening springs with a strong cubic term: several iterations, the last ones quadratic
    assert res.iterations[0] >= 3
    assert res.residuals[0] <= 1e-8


def test_cutback_then_success_and_auto_fallback_to_adr(tmp_path):
    prob = _chain(u_end=0.2, graded=True, beta=1e3)
    # three iterations are too few for the full step: halvings make each piece easy enough
    res = pdlin.solve_nonlinear(prob, steps=1, method="newton", maxiter=3, predictor="tangent")
    assert res.cutbacks[0] >= 1 and res.methods == ["newton"]
    with pytest.raises(ConvergenceError, match="Newton failed at load step 1"):
        pdlin.solve_nonlinear(
            prob, steps=1, method="newton", maxiter=1, max_cutbacks=0, predictor="tangent"
        )
    ck = tmp_path / "auto.npz"
    kw: dict[str, Any] = {
        "steps": 1, "method": "auto", "maxiter": 1, "max_cutbacks": 0, "predictor": "tangent",
        "e_l": 1e-9, "checkpoint": ck,
    }  # fmt: skip
    auto = pdlin.solve_nonlinear(prob, **kw)
    assert auto.methods == ["adr (newton failed)"]
    assert "no convergence in 1 iterations" in auto.messages[0]
    # the checkpoint keeps why Newton failed and the step's time: a resumed run reports them
    again = pdlin.solve_nonlinear(prob, resume=True, **kw)
    assert again.resumed_from == 1 and again.messages == auto.messages
    assert again.timings["steps"].tolist() == auto.timings["steps"].tolist()
    # the step's iterations: Newton's failed one plus one damping value per ADR iteration
    assert auto.damping[0].size == auto.iterations[0] - 1 > 0
    np.testing.assert_allclose(auto.u[-1], res.u[-1], rtol=0, atol=1e-6 * 0.2)


def test_linear_models_newton_one_iteration_and_matches_solve():
    cloud = pdlin.grid((12, 6), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        cloud,
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [1e-3, 5e-4])],
    )
    lin = pdlin.solve(prob, solver="direct")
    res = pdlin.solve_nonlinear(prob, steps=2, method="newton", predictor="previous")
    assert res.iterations.tolist() == [1, 1]
    np.testing.assert_allclose(res.u[-1], lin.u, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(res.reactions[-1], lin.reactions, rtol=1e-7, atol=1e-12)
    # half the load at step 1 (proportional loading)
    np.testing.assert_allclose(res.u[0], 0.5 * lin.u, rtol=1e-9, atol=1e-15)
    assert res.homogenized_stress is not None and res.homogenized_stress.shape == (2, 2, 2)


@pytest.mark.parametrize("e_l", [1e-4, 1e-6, 1e-8])
def test_adr_error_against_linear_solve_decreases_with_e_l(e_l):
    # elastic steps, ADR vs a linear solve: max|Δu|/max|u| <= 10 e_l
    cloud = pdlin.grid((14, 8), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.Correspondence(E=1.0, nu=0.3, control="penalty"),
        cloud,
        horizon=0.2015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [1e-3, 0.0])],
    )
    lin = pdlin.solve(prob, solver="direct")
    # from the last solution (the tangent predictor would start at the linear solution)
    res = pdlin.solve_nonlinear(prob, steps=1, method="adr", e_l=e_l, predictor="previous")
    assert res.iterations[0] > 20
    err = np.abs(res.u[-1] - lin.u).max() / np.abs(lin.u).max()
    assert err <= 10 * e_l
    assert res.e1[0] < e_l and res.e2[0] < e_l


def test_adr_explicit_density_stability_limit():
    # stability limit of the central-difference update on a linear chain: Λ = 1, Δt at 0.98 x
    # 2/sqrt(λ_max) converges, at 1.02 x the update is unstable (linear forces are unbounded: the
    # step fails)
    prob = _chain(n=31, beta=0.0)
    system = pdlin.constrained_system(prob)
    K = system.eliminate_matrix(system.assemble()).toarray()
    free = system.free
    lmax = np.linalg.eigvalsh(K[np.ix_(free, free)]).max()
    dt_c = 2.0 / np.sqrt(lmax)
    kw = {"method": "adr", "density": 1.0, "predictor": "previous"}
    ok = pdlin.solve_nonlinear(prob, steps=1, dt=0.98 * dt_c, **kw)
    assert ok.iterations[0] > 0
    with pytest.raises(ConvergenceError, match="ADR"):
        pdlin.solve_nonlinear(prob, steps=1, dt=1.02 * dt_c, adr_maxiter=3000, **kw)


def test_checkpoint_resume_keeps_committed_steps(tmp_path):
    prob = _chain(u_end=0.1)
    full = pdlin.solve_nonlinear(prob, steps=4, method="newton")
    ck = tmp_path / "run.npz"

    class Killed(Exception):
        pass

    def kill_after_two(msg: str) -> None:
        if msg.startswith("step 2/4"):
            raise Killed

    with pytest.raises(Killed):
        pdlin.solve_nonlinear(
            prob, steps=4, method="newton", checkpoint=ck, progress=kill_after_two
        )
    assert ck.exists() and not (tmp_path / "run.npz.tmp").exists()
    assert int(np.load(ck)["done"]) == 2
    first = np.load(ck)["step_time"]
    res = pdlin.solve_nonlinear(prob, steps=4, method="newton", checkpoint=ck, resume=True)
    assert res.resumed_from == 2
    # every step's wall time: steps 1-2 as measured by the killed run, 3-4 by this one
    steps = res.timings["steps"]
    assert first.shape == (2,) and np.all(first > 0) and steps[:2].tolist() == first.tolist()
    assert np.all(steps[2:] > 0) and np.all(np.isfinite(steps))
    # a checkpoint of an earlier version (no step times, no messages) still resumes; the
    # unknown times are NaN, not zero
    old = tmp_path / "old.npz"
    with np.load(ck) as data:
        np.savez(old, **{k: data[k] for k in data.files if k not in ("step_time", "messages")})
    legacy = pdlin.solve_nonlinear(prob, steps=4, method="newton", checkpoint=old, resume=True)
    assert np.isnan(legacy.timings["steps"][:4]).all() and legacy.messages == [""] * 4
    np.testing.assert_allclose(legacy.u, full.u, rtol=1e-12, atol=1e-15)
    # every committed state is kept: the checkpoint's two (issue 31: before, only its
    # last) and the two solved steps'
    assert res.state_steps == [0, 1, 2, 3]
    assert np.array_equal(res.state_at(0)["emax"], full.states[0]["emax"])
    np.testing.assert_allclose(res.state_at(1)["emax"], full.states[1]["emax"], rtol=1e-12)
    np.testing.assert_allclose(res.u, full.u, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(res.states[-1]["emax"], full.states[-1]["emax"], rtol=1e-12)
    with pytest.raises(InputError, match="different problem: step times"):
        pdlin.solve_nonlinear(prob, steps=5, method="newton", checkpoint=ck, resume=True)
    # a finished run extended by more steps of the same path continues after step 4
    more = pdlin.solve_nonlinear(
        prob, times=[0.25, 0.5, 0.75, 1.0, 1.25], method="newton", checkpoint=ck, resume=True
    )
    assert more.resumed_from == 4 and more.iterations[:4].tolist() == full.iterations.tolist()
    # plain prescribed values scale with t / t_end: 1.25 x the end displacement at t = 1.25
    np.testing.assert_allclose(more.u[-1, -1, 0], 1.25 * 0.1, rtol=1e-12)


def test_velocity_gradient_path_and_affine_predictor():
    # a linear patch under u = (exp(L t) - I) X on its boundary: the affine predictor is the
    # exact solution of the linearized problem only to O(|L t|²), Newton fixes the rest
    cloud = pdlin.grid((8, 8), spacing=0.125)
    L = 0.002 * np.array([[0.0, 1.0], [1.0, 0.0]])
    ring = np.flatnonzero((cloud.points.min(axis=1) < 0.125) | (cloud.points.max(axis=1) > 0.875))
    prob = pdlin.StaticProblem(
        pdlin.Correspondence(E=1.0, nu=0.3),
        cloud,
        horizon=0.126,
        dirichlet=[pdlin.Dirichlet.velocity_gradient(ring, L)],
    )
    res = pdlin.solve_nonlinear(prob, steps=3, t_end=30.0, method="newton")
    system = res.system
    for k, t in enumerate(res.times):
        H = __import__("scipy").linalg.expm(L * t) - np.eye(2)
        np.testing.assert_allclose(res.u[k][ring], cloud.points[ring] @ H.T, rtol=1e-12, atol=1e-15)
        assert np.abs(system.residual(res.u[k])).max() < 1e-10
    np.testing.assert_allclose(res.times, [10.0, 20.0, 30.0])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"method": "newtonn"}, "method must be one of"),
        ({"steps": 0}, "steps must be an integer >= 1"),
        ({"times": [1.0, 0.5]}, "times must be a non-empty increasing"),
        ({"predictor": "affine"}, "predictor='affine' needs"),
        ({"method": "adr", "density": 1.0}, "explicit ADR density needs dt"),
        ({"rtol": -1.0}, "rtol must be a positive number"),
        ({"maxiter": 1.5}, "maxiter must be an integer"),
    ],
)
def test_bad_arguments_name_themselves(kwargs, match):
    with pytest.raises(InputError, match=match):
        pdlin.solve_nonlinear(_chain(), **kwargs)


class _NoisyChain(CubicChain):
    """CubicChain whose trial states warn and whose committed states report an issue once
    the strain passes a threshold: the drivers' model-side hook."""

    def respond(self, cloud: Any, bonds: Any, u: Any, state: Any, *, tangent: bool = False):
        import warnings

        warnings.warn("trial state questionable", pdlin.errors.TrialStateWarning, stacklevel=1)
        return super().respond(cloud, bonds, u, state, tangent=tangent)

    def committed_issues(self, state):
        big = state["emax"] > 0.05 / 45  # passed in steps 2 and 3 (bond strain 0.05 k / 60)
        if big.any():
            return [(UserWarning, f"{int(big.sum())} point(s) past the threshold")]
        return []


@pytest.mark.parametrize("method", ["newton", "adr"])
def test_committed_issues_are_warned_per_step_and_trial_warnings_ignored(method):
    import warnings

    p = _chain()
    prob = pdlin.StaticProblem(_NoisyChain(beta=1e4), p.cloud, p.bonds, dirichlet=list(p.dirichlet))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdlin.solve_nonlinear(prob, steps=3, method=method)
    msgs = [str(w.message) for w in caught]
    assert not any("trial state" in m for m in msgs)
    # steps 2 and 3 commit e = 0.05 * 2/60, 0.05 * 3/60 > 0.05/45 at the 20 points that start
    # a bond (the last point starts none); step 1 (0.05/60) does not
    assert [m for m in msgs if "threshold" in m] == [
        "load step 2 (t = 0.666667): 20 point(s) past the threshold",
        "load step 3 (t = 1): 20 point(s) past the threshold",
    ]


class _FragileChain(CubicChain):
    """CubicChain whose material update fails (NonFiniteError) when a bond's strain grows
    by more than 0.001 in one call beyond the committed history (a return mapping that
    diverges on too large an increment)."""

    def respond(self, cloud: Any, bonds: Any, u: Any, state: Any, *, tangent: bool = False):
        i, j = self._pairs(bonds)
        e = np.ravel(u)[j] - np.ravel(u)[i]
        if np.any(np.abs(e) - state["emax"][i] > 1e-3):
            raise pdlin.errors.NonFiniteError("P must be finite, got nan (increment too large)")
        return super().respond(cloud, bonds, u, state, tangent=tangent)


@pytest.mark.parametrize("method", ["newton", "adr"])
def test_failed_material_update_cuts_the_step_back(method):
    # one load step to a bond strain of 0.0025 cannot be taken at once (the material fails
    # above an increment of 0.001): the driver halves it twice (0.0025 -> 0.00125 -> 0.000625)
    # instead of letting the material's error escape, and converges to the exact solution
    p = _chain()
    prob = pdlin.StaticProblem(_FragileChain(), p.cloud, p.bonds, dirichlet=list(p.dirichlet))
    res = pdlin.solve_nonlinear(prob, steps=1, method=method, max_cutbacks=4)
    assert res.cutbacks[0] >= 2
    x = prob.cloud.points[:, 0]
    u_exact = 0.05 * (x - x[0]) / (x[-1] - x[0])
    np.testing.assert_allclose(res.u[-1, :, 0], u_exact, rtol=1e-6, atol=1e-9)
    # with no cut-back allowed the step fails loudly as a ConvergenceError naming the cause
    with pytest.raises(ConvergenceError, match="non-finite constitutive response"):
        pdlin.solve_nonlinear(prob, steps=1, method=method, max_cutbacks=0)


class _OverflowChain(CubicChain):
    """CubicChain whose force overflows (numpy warns, inf results) when a bond's strain
    grows by more than 0.001 in one call: a diverging trial iterate's arithmetic."""

    def respond(self, cloud: Any, bonds: Any, u: Any, state: Any, *, tangent: bool = False):
        r = super().respond(cloud, bonds, u, state, tangent=tangent)
        i, j = self._pairs(bonds)
        e = np.ravel(u)[j] - np.ravel(u)[i]
        jump = np.abs(e) - state["emax"][i]
        blow = np.zeros(cloud.n)
        blow[i] = np.exp(np.where(jump > 1e-3, 1e4, 0.0)) - 1.0  # overflow -> inf, warns
        r.force[:, 0] = r.force[:, 0] + blow * 0.0 + blow  # inf * 0 -> nan, warns
        return r


@pytest.mark.parametrize("method", ["newton", "adr"])
def test_overflowing_trial_iterates_neither_warn_nor_pass(method):
    # the too-large trial increments overflow inside the model: the drivers cut them back
    # (as for a NonFiniteError), numpy's floating-point warnings of those trial iterates
    # are not issued (an error filter would raise them), and the converged result is exact
    import warnings

    p = _chain()
    prob = pdlin.StaticProblem(_OverflowChain(), p.cloud, p.bonds, dirichlet=list(p.dirichlet))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = pdlin.solve_nonlinear(prob, steps=1, method=method, max_cutbacks=4)
    assert res.cutbacks[0] >= 2
    x = prob.cloud.points[:, 0]
    u_exact = 0.05 * (x - x[0]) / (x[-1] - x[0])
    np.testing.assert_allclose(res.u[-1, :, 0], u_exact, rtol=1e-6, atol=1e-9)


class _NaNTangentChain(CubicChain):
    """CubicChain whose tangent (not force) is NaN when a bond's strain grows by more than
    0.001 in one call."""

    def respond(self, cloud: Any, bonds: Any, u: Any, state: Any, *, tangent: bool = False):
        r = super().respond(cloud, bonds, u, state, tangent=tangent)
        i, j = self._pairs(bonds)
        e = np.ravel(u)[j] - np.ravel(u)[i]
        if tangent and np.any(np.abs(e) - state["emax"][i] > 1e-3):
            r.tangent.data[:] = np.nan
        return r


@pytest.mark.parametrize("method", ["newton", "adr"])
def test_non_finite_tangent_cuts_the_step_back(method):
    # Newton's linear solve and ADR's Gershgorin density meet a NaN tangent on the
    # too-large increments: a failed increment (cut back), not an input error escaping;
    # graded stiffness, so that no predictor is already the (nonlinear) solution
    p = _chain(graded=True)
    k = p.model.k
    prob = pdlin.StaticProblem(_NaNTangentChain(k=k), p.cloud, p.bonds, dirichlet=list(p.dirichlet))
    res = pdlin.solve_nonlinear(prob, steps=1, method=method, max_cutbacks=4)
    assert res.cutbacks[0] >= 1
    ref = pdlin.solve_nonlinear(p, steps=4, method="newton")  # the same chain, sane tangent
    np.testing.assert_allclose(res.u[-1], ref.u[-1], rtol=1e-5, atol=1e-9)
    with pytest.raises(ConvergenceError, match="non-finite|linear solve failed"):
        pdlin.solve_nonlinear(prob, steps=1, method=method, max_cutbacks=0)


class _NaNStateChain(CubicChain):
    """CubicChain whose state turns NaN at point 3 once its bond strain passes 0.001
    while the force stays finite: a converged step must not commit it."""

    def respond(self, cloud: Any, bonds: Any, u: Any, state: Any, *, tangent: bool = False):
        r = super().respond(cloud, bonds, u, state, tangent=tangent)
        if r.state["emax"][3] > 1e-3:
            r.state["emax"][3] = np.nan
        return r


@pytest.mark.parametrize("method", ["newton", "adr"])
def test_non_finite_committed_state_raises(method):
    # step 1 of 2 reaches the bond strain e = 0.025 / 20 = 0.00125 > 0.001 (_chain: 21
    # points, u_end 0.05): the NaN state at point 3 is named instead of being committed
    p = _chain()
    prob = pdlin.StaticProblem(_NaNStateChain(), p.cloud, p.bonds, dirichlet=list(p.dirichlet))
    with pytest.raises(ConvergenceError, match=r"load step 1 .*'emax' is not finite .*point 3\)"):
        pdlin.solve_nonlinear(prob, steps=2, method=method)


def test_cutback_depth_not_count_bounds_the_increments():
    # max_cutbacks bounds how often one increment is halved (smallest increment: the step
    # / 2**max_cutbacks), not the failures of a step: with 2, increments of 0.0025 / 4 =
    # 0.000625 <= 0.001 (the _FragileChain limit) pass, and every later try of a doubled
    # increment (0.00125) fails once more, so the step has more failures than 2
    p = _chain()
    prob = pdlin.StaticProblem(_FragileChain(), p.cloud, p.bonds, dirichlet=list(p.dirichlet))
    res = pdlin.solve_nonlinear(prob, steps=1, method="newton", max_cutbacks=2)
    assert res.cutbacks[0] > 2
    x = prob.cloud.points[:, 0]
    np.testing.assert_allclose(res.u[-1, :, 0], 0.05 * (x - x[0]) / (x[-1] - x[0]), atol=1e-9)
    # one level less and the smallest increment (0.00125) is still too large
    with pytest.raises(ConvergenceError, match="after 2 cut-back"):
        pdlin.solve_nonlinear(prob, steps=1, method="newton", max_cutbacks=1)


def test_increment_carries_into_the_next_step(monkeypatch):
    # a Newton that refuses load increments above 0.3 (of the load factor) and reports
    # every converged increment as hard (10 iterations, so it is not grown): step 1
    # (increment 0.5) is cut back once to 0.25 and finishes in two increments; step 2
    # starts from the carried 0.25 and is never cut back (halving from the full step
    # each time would fail once per step)
    import pdlin.solvers.stepping as nl

    real_newton = nl.newton_step
    last = [0.0]

    def newton_limited(system, u0, committed, *, factor, **kw):
        if factor - last[0] > 0.3 + 1e-12:
            raise nl.StepFailed("Newton: increment too large (test)")
        out = real_newton(system, u0, committed, factor=factor, **kw)
        last[0] = factor
        out.iterations = 10
        return out

    monkeypatch.setattr(nl, "newton_step", newton_limited)
    res = pdlin.solve_nonlinear(_chain(u_end=0.05, beta=10.0), steps=2, method="newton")
    assert res.cutbacks.tolist() == [1, 0]
    assert res.iterations.tolist() == [20, 20]  # two increments of 10 per step


@pytest.mark.parametrize(
    ("first_ok", "fallback_cutbacks", "expected"),
    [
        # Newton fails every increment: 6 tries (whole step, 1/2 ... 1/32) in step 1; after
        # that fallback, step 2 tries the whole step and one half (fallback_cutbacks=1)
        (False, 1, [6, 2]),
        (False, 5, [6, 6]),  # the limit at max_cutbacks: as many tries as step 1
        (True, 1, [0, 6]),  # step 1 by Newton: step 2 keeps max_cutbacks halvings
    ],
)
def test_auto_after_a_fallback_newton_tries_fewer_halvings(
    monkeypatch, first_ok, fallback_cutbacks, expected
):
    """After a load step that Newton failed (ADR fallback), 'auto' gives the next step's
    Newton ``fallback_cutbacks`` halvings from a whole-step increment, not ``max_cutbacks``
    from the tiny increment it failed at (a 10⁵-point polycrystal spent ≈ 20 min per step on
    creeping Newton increments before the fallback)."""
    import pdlin.solvers.stepping as nl

    real_newton = nl.newton_step
    tries: list[tuple[float, float]] = []

    def newton(system, u0, committed, *, factor, **kw):
        tries.append((factor, float(np.max(committed["emax"]))))
        if first_ok and factor <= 0.5 + 1e-12:
            return real_newton(system, u0, committed, factor=factor, **kw)
        raise nl.StepFailed("Newton: refused (test)")

    monkeypatch.setattr(nl, "newton_step", newton)
    prob = _chain(u_end=0.05, beta=10.0)
    res = pdlin.solve_nonlinear(
        prob, steps=2, method="auto", max_cutbacks=5, fallback_cutbacks=fallback_cutbacks,
        e_l=1e-10,
    )  # fmt: skip
    assert res.cutbacks.tolist() == expected
    second = [f for f, _ in tries[len(tries) - expected[1] :]]
    assert second[0] == pytest.approx(1.0)  # step 2 starts with its whole increment
    assert second[1] == pytest.approx(0.75)  # then halves it
    assert res.methods[1] == "adr (newton failed)"
    x = prob.cloud.points[:, 0]  # uniform chain: u linear in x
    np.testing.assert_allclose(res.u[-1, :, 0], 0.05 * (x - x[0]) / (x[-1] - x[0]), atol=1e-8)


def test_auto_newton_tries_shrink_over_consecutive_fallbacks(monkeypatch):
    """Every further load step that Newton fails in a row takes one halving off the next
    step's Newton (fallback_cutbacks = 2: 2, 1, then the whole step alone); a step that
    Newton carries restores max_cutbacks."""
    import pdlin.solvers.stepping as nl

    real_newton = nl.newton_step
    ok_at = {4 / 6}  # load factors at which Newton is allowed to converge (step 4 of 6)

    def newton(system, u0, committed, *, factor, **kw):
        if any(abs(factor - f) < 1e-12 for f in ok_at):
            return real_newton(system, u0, committed, factor=factor, **kw)
        raise nl.StepFailed("Newton: refused (test)")

    monkeypatch.setattr(nl, "newton_step", newton)
    prob = _chain(u_end=0.05, beta=10.0)
    res = pdlin.solve_nonlinear(
        prob, steps=6, method="auto", max_cutbacks=4, fallback_cutbacks=2, e_l=1e-10
    )
    # tries per step: 5 (whole + 4 halvings), 3, 2, then step 4 by Newton at once (the
    # whole step, streak 3: no halving), step 5 again 5 tries, step 6 after one fallback 3
    assert res.cutbacks.tolist() == [5, 3, 2, 0, 5, 3]
    assert res.methods == [nl._FELL_BACK] * 3 + ["newton"] + [nl._FELL_BACK] * 2


def test_auto_continues_with_adr_from_newtons_last_increment(monkeypatch):
    # Newton converges up to half of the load and fails beyond; ADR must take over from
    # Newton's converged half step (its start state already has the history of t = 0.5)
    import pdlin.solvers.stepping as nl

    real_newton, real_adr = nl.newton_step, nl.adr_step
    seen: list[float] = []

    def newton_half(system, u0, committed, *, factor, **kw):
        if factor > 0.5 + 1e-12:
            raise nl.StepFailed("Newton: refused beyond half the load (test)")
        return real_newton(system, u0, committed, factor=factor, **kw)

    def adr_logged(system, u0, committed, **kw):
        seen.append(float(np.max(committed["emax"])))
        return real_adr(system, u0, committed, **kw)

    monkeypatch.setattr(nl, "newton_step", newton_half)
    monkeypatch.setattr(nl, "adr_step", adr_logged)
    prob = _chain(u_end=0.05, beta=10.0)
    res = pdlin.solve_nonlinear(prob, steps=1, method="auto", max_cutbacks=2, e_l=1e-10)
    assert res.methods == ["adr (newton failed)"]
    # committed history at ADR's start: the strain of half the load, 0.05 / 20 / 2
    np.testing.assert_allclose(seen[0], 0.05 / 40, rtol=1e-9)
    x = prob.cloud.points[:, 0]
    np.testing.assert_allclose(res.u[-1, :, 0], 0.05 * (x - x[0]) / (x[-1] - x[0]), atol=1e-8)


def test_adr_divergence_names_where_the_iterates_ran_away():
    # a graded linear chain whose density is the Gershgorin bound at safety 1 except at one
    # point near its stiff end, 40 % below: the central differences blow up there; the
    # error names the first non-finite force and the point that had moved farthest (that
    # one), with the remedies
    from pdlin.solvers import StepFailed, adr_density, adr_step

    prob = _chain(n=21, beta=0.0, graded=True)
    system = pdlin.constrained_system(prob)
    st = system.initial_state()
    lam = adr_density(system, st, None, dt=1.0, safety=1.0)
    lam[-3] *= 0.6  # the point next to the stiff end's support
    with pytest.raises(StepFailed) as err:
        adr_step(system, system.prescribed(1.0), st, factor=1.0, density=lam, dt=1.0)
    msg = str(err.value)
    assert "non-finite force at iteration" in msg and "density_safety" in msg
    assert "control" in msg
    p = int(msg.split("farthest from the increment's start at point ")[1].split()[0])
    assert p == 18  # the point whose density was lowered (points 0-20, x = 0.9)


def _refuse_newton(monkeypatch) -> list[float]:
    """Make every Newton increment fail; returns the list of load factors it was tried at."""
    import pdlin.solvers.stepping as nl

    tried: list[float] = []

    def newton(system, u0, committed, *, factor, **kw):
        tried.append(factor)
        raise nl.StepFailed("Newton: refused (test)")

    monkeypatch.setattr(nl, "newton_step", newton)
    return tried


@pytest.mark.parametrize("backoff", [True, False])
def test_auto_newton_backoff_after_a_long_fallback_streak(monkeypatch, backoff):
    """Newton fails every step: after fallback_cutbacks + 1 = 3 failed steps in a row,
    ``auto`` tries it only when the streak is a power of two (4, 8) and hands the other
    steps to ADR directly; with newton_backoff=False it tries every step."""
    import pdlin.solvers.stepping as nl

    tried = _refuse_newton(monkeypatch)
    prob = _chain(u_end=0.05, beta=10.0)
    kw = {"method": "auto", "max_cutbacks": 0, "e_l": 1e-10, "newton_backoff": backoff}
    res = pdlin.solve_nonlinear(prob, steps=12, **kw)
    steps = sorted({round(f * 12) for f in tried})  # load steps (1-based) Newton was tried in
    if backoff:
        # streaks 0, 1, 2, 3 (down to the whole step alone), then 4 and 8: steps 1-5 and 9
        assert steps == [1, 2, 3, 4, 5, 9]
        skipped = [6, 7, 8, 10, 11, 12]
        assert [k + 1 for k, m in enumerate(res.methods) if m == nl._SKIPPED] == skipped
        assert "Newton skipped" in res.messages[5] and res.summary()["newton_skipped"] == 6
        assert res.summary()["fallbacks"] == 6
    else:
        assert steps == list(range(1, 13)) and nl._SKIPPED not in res.methods
    # the same solution either way (ADR carries every step from the same states)
    x = prob.cloud.points[:, 0]
    np.testing.assert_allclose(
        res.u[-1, :, 0], 0.05 * (x - x[0]) / (x[-1] - x[0]), rtol=1e-7, atol=1e-10
    )


def test_auto_newton_backoff_streak_survives_a_resume(monkeypatch, tmp_path):
    # a resumed run continues the streak from the checkpoint's methods
    import pdlin.solvers.stepping as nl

    tried = _refuse_newton(monkeypatch)
    prob = _chain(u_end=0.05, beta=10.0)
    ck = tmp_path / "run.npz"
    kw = {"method": "auto", "max_cutbacks": 0, "e_l": 1e-10, "t_end": 12.0, "checkpoint": ck}
    pdlin.solve_nonlinear(prob, times=np.arange(1.0, 7.0), **kw)  # steps 1-6, 6 skipped
    tried.clear()
    res = pdlin.solve_nonlinear(prob, times=np.arange(1.0, 13.0), resume=True, **kw)
    assert sorted({round(f * 12) for f in tried}) == [9]  # streak 8 at step 9 only
    assert res.methods[5] == nl._SKIPPED and res.methods[6] == nl._SKIPPED


def _limit_adr(
    monkeypatch, limits: dict[int, float], steps: int
) -> tuple[list[tuple[int, float]], list[float]]:
    """Make ADR refuse increments larger than ``limits[step]`` (a fraction of the load
    step; 1-based steps, default: no limit) at once; returns (step, increment) per try
    and the last converged load factor (a list, to reset it for a new run)."""
    import pdlin.solvers.stepping as nl

    real_adr = nl.adr_step
    last = [0.0]
    tries: list[tuple[int, float]] = []

    def adr(system, u0, committed, *, factor, **kw):
        step = int(np.ceil(factor * steps - 1e-9))
        inc = (factor - last[0]) * steps
        tries.append((step, round(inc, 9)))
        if inc > limits.get(step, 1.0) + 1e-9:
            raise nl.StepFailed("ADR: increment too large (test)")
        out = real_adr(system, u0, committed, factor=factor, **kw)
        last[0] = factor
        return out

    monkeypatch.setattr(nl, "adr_step", adr)
    return tries, last


@pytest.mark.parametrize(
    ("limits", "expected", "whole_failed"),
    [
        # whole steps fail from step 3 on, halves converge: the whole step is retried at
        # steps 5 (after a hold of 1 step), 8 (2) and 13 (4), not at every step
        ({s: 0.6 for s in range(3, 14)}, [0, 0, 1, 0, 1, 0, 0, 1, 0, 0, 0, 0, 1], [3, 5, 8, 13]),
        # halves fail at steps 3-4 too: quarters there; the half is retried at step 5 and
        # converges, then the whole step (held as long, 1 step) at step 7, where it fails
        # again (hold 2: retried at step 10, where it converges)
        (
            {3: 0.3, 4: 0.3, **{s: 0.6 for s in range(5, 10)}},
            [0, 0, 2, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0],
            [3, 7],
        ),
    ],
)
def test_adr_increment_backoff_after_a_failed_size(
    monkeypatch, tmp_path, limits, expected, whole_failed
):
    """ADR grows every converged increment (its iterations hardly depend on the size), so
    without a backoff a size that failed is tried again at every load step, each time for
    a whole iteration budget (≈ 11 min at 10⁵ crystal-plasticity points)."""
    tries, last = _limit_adr(monkeypatch, limits, 13)
    prob = _chain(u_end=0.05, beta=10.0)
    kw = {"method": "adr", "max_cutbacks": 3, "e_l": 1e-10}
    res = pdlin.solve_nonlinear(prob, steps=13, **kw)
    assert res.cutbacks.tolist() == expected
    whole = [s for s, inc in tries if inc == 1.0]  # steps tried as one increment
    assert [s for s in whole if limits.get(s, 1.0) < 1.0] == whole_failed
    x = prob.cloud.points[:, 0]
    np.testing.assert_allclose(res.u[-1, :, 0], 0.05 * (x - x[0]) / (x[-1] - x[0]), atol=1e-8)
    # a run killed after step 6 and resumed makes the same tries (the checkpoint keeps
    # the increments and the backoff)
    ck = tmp_path / "run.npz"
    first = list(tries)
    tries.clear()
    last[0] = 0.0
    pdlin.solve_nonlinear(prob, times=np.arange(1.0, 7.0), t_end=13.0, checkpoint=ck, **kw)
    pdlin.solve_nonlinear(
        prob, times=np.arange(1.0, 14.0), t_end=13.0, checkpoint=ck, resume=True, **kw
    )
    assert tries == first


def test_newton_backoff_must_be_a_bool():
    with pytest.raises(pdlin.errors.InputTypeError, match="newton_backoff must be True or False"):
        pdlin.solve_nonlinear(_chain(), steps=1, newton_backoff=1)


def test_adr_dot_is_the_blas_product_and_keeps_non_finite_values() -> None:
    """The ADR loop's BLAS-free dot product (``_dot``, einsum) equals ``a @ b`` to
    round-off on long vectors, and an inf / nan in either vector reaches the result (the
    loop detects a runaway from ``sqrt(_dot(r, r))``)."""
    from pdlin.solvers.adr import _dot

    rng = np.random.default_rng(7)
    a, b = rng.standard_normal(200_001), rng.standard_normal(200_001)
    assert _dot(a, b) == pytest.approx(float(a @ b), rel=1e-12, abs=1e-9)
    assert _dot(a, a) == pytest.approx(float(np.linalg.norm(a)) ** 2, rel=1e-12)
    a[12345] = np.inf
    assert _dot(a, a) == np.inf
    a[12345] = np.nan
    assert np.isnan(_dot(a, b))


def test_adr_reports_progress_within_a_step():
    """``progress_every`` seconds between ADR's in-step lines (iteration, e1, e2, damping,
    residual; checked every 64 iterations): with 0 a line every 64 iterations, with a
    long interval only the step lines; a bad value names the argument."""
    prob = _chain(u_end=0.05, beta=10.0)
    lines: list[str] = []
    res = pdlin.solve_nonlinear(
        prob,
        steps=1,
        method="adr",
        e_l=1e-10,
        predictor="previous",
        progress=lines.append,
        progress_every=0,
    )
    inner = [m for m in lines if "ADR iteration" in m]
    assert res.iterations[0] >= 128 and len(inner) == res.iterations[0] // 64
    assert inner[0].startswith("  t = 1: ADR iteration 64: e1 = ")
    assert all(k in inner[0] for k in ("e2 = ", "(target 1e-10)", "c = ", "|r|/scale = "))
    assert lines[-1].startswith("step 1/1")
    quiet: list[str] = []
    pdlin.solve_nonlinear(
        prob, steps=1, method="adr", e_l=1e-10, predictor="previous", progress=quiet.append
    )
    assert not any("ADR iteration" in m for m in quiet) and len(quiet) == 1
    for bad in (-1.0, float("nan"), True, "60"):
        with pytest.raises(InputError, match="progress_every must be a finite number of seco"):
            pdlin.solve_nonlinear(prob, steps=1, progress_every=bad)


def test_newton_and_cutbacks_report_progress_within_a_step():
    """Newton's in-step lines (iteration, relative residual against rtol, last step length;
    with ``progress_every=0`` one per iteration after the first) and one line per failed
    increment (why, and the time it is cut back to): a 10⁵-point Newton try takes minutes
    and printed nothing before the step ended."""
    lines: list[str] = []
    res = pdlin.solve_nonlinear(
        _chain(),
        steps=1,
        method="newton",
        predictor="previous",  # not the tangent predictor, exact for a uniform chain
        progress=lines.append,
        progress_every=0,
    )
    inner = [m for m in lines if "Newton iteration" in m]
    assert res.iterations[0] >= 3 and len(inner) == res.iterations[0]
    assert inner[0].startswith("  t = 1: Newton iteration 1: |r|/scale = ")
    assert "(target 1e-08), step length " in inner[0]
    # _FragileChain fails increments above a bond strain of 0.001: t = 1 and t = 0.5 fail
    p = _chain()
    prob = pdlin.StaticProblem(_FragileChain(), p.cloud, p.bonds, dirichlet=list(p.dirichlet))
    lines.clear()
    res = pdlin.solve_nonlinear(prob, steps=1, method="newton", progress=lines.append)
    cut = [m for m in lines if "cutting back" in m]
    assert len(cut) == res.cutbacks[0] >= 2
    assert cut[0].startswith("  t = 1: Newton: start of the step: non-finite constitutive")
    assert cut[0].endswith("; cutting back to t = 0.5")
    assert not any("Newton iteration" in m for m in lines)  # 60 s between in-step lines


@pytest.mark.parametrize("damping", [None, 0.05])
def test_adr_compiled_update_is_the_numpy_update_bitwise(monkeypatch, damping):
    """With numba, ADR's update and δu / local stiffness run as compiled passes over DOF
    chunks on pdlin's threads; they repeat the numpy steps' arithmetic in its order, so
    150 iterations of a 92² crystal-plasticity polycrystal (16,928 DOFs, with the
    compiled kernels' threshold lowered to 2¹⁴) give the same iterates, damping and residual history
    bitwise, for 1 and 2 threads and with constant damping (δu only)."""
    pytest.importorskip("numba")
    from pdlin._kernels import numba_enabled
    from pdlin.solvers import adr as nl

    if not numba_enabled():
        pytest.skip("numba disabled (PDLIN_NUMBA=0)")
    from pdlin import _kernels

    monkeypatch.setattr(_kernels, "_MIN_WORK", 1 << 14)  # 16,928 DOFs: the compiled path
    n = 92
    cloud = pdlin.grid((n, n), spacing=1.0 / n)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    _, theta = pdlin.voronoi_polycrystal(cloud, 5, seed=1)
    model = pdlin.Correspondence(
        material=pdlin.CrystalPlasticity(orientation=theta), control="penalty", penalty=0.1
    )
    L = 0.002 * np.array([[0.0, 1.0], [1.0, 0.0]])
    prob = pdlin.StaticProblem(
        model, cloud, bonds, dirichlet=[pdlin.Dirichlet.velocity_gradient("boundary", L)]
    )
    system = pdlin.constrained_system(prob)
    st = system.initial_state()
    pts = cloud.points
    u0 = np.column_stack([0.01 * pts[:, 1], np.zeros(len(pts))]).ravel()
    assert nl._adr_kernels(u0.size) is not None  # the compiled path is taken
    lam = nl.adr_density(system, st, u0)

    def run() -> Any:
        with pytest.raises(nl.StepFailed) as err:  # the budget: 150 iterations
            nl.adr_step(
                system, u0, st, factor=1.0, density=lam, dt=1.0, maxiter=150, damping=damping
            )
        return err.value.outcome

    outs = []
    for threads in (1, 2):
        pdlin.set_num_threads(threads)
        try:
            outs.append(run())
        finally:
            pdlin.set_num_threads(None)
    monkeypatch.setattr(nl, "_adr_kernels", lambda ndof: None)
    outs.append(run())  # the numpy steps
    ref = outs[-1]
    assert ref.iterations == 150 and np.abs(ref.u - u0).max() > 0  # it moved
    for out in outs[:-1]:
        assert np.array_equal(out.u, ref.u)
        assert np.array_equal(out.damping, ref.damping)
        assert out.history == ref.history


def _compiled_cp_update(monkeypatch: Any) -> None:
    """The compiled crystal-plasticity update for the small polycrystal's 400 points (by
    default numba takes batches of 8,192 points on): the iteration counts the snapshot
    tests rely on are those of the compiled update, which equals the numpy update only to
    round-off (numpy's path: 118 ADR iterations in step 3 instead of more than 128, and no
    cut-back at a budget of 130)."""
    pytest.importorskip("numba")
    from pdlin._kernels import numba_enabled
    from pdlin.constitutive import crystal_plasticity as cpm

    if not numba_enabled():
        pytest.skip("numba disabled (PDLIN_NUMBA=0)")
    monkeypatch.setattr(cpm, "_NUMBA_MIN_POINTS", 256)


def _small_polycrystal(n: int = 20) -> Any:
    cloud = pdlin.grid((n, n), spacing=1.0 / n)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    _, theta = pdlin.voronoi_polycrystal(cloud, 3, seed=1)
    model = pdlin.Correspondence(
        material=pdlin.CrystalPlasticity(orientation=theta), control="penalty", penalty=0.1
    )
    L = 0.002 * np.array([[0.0, 1.0], [1.0, 0.0]])
    return pdlin.StaticProblem(
        model, cloud, bonds, dirichlet=[pdlin.Dirichlet.velocity_gradient("boundary", L)]
    )


class _Killed(Exception):
    """Raised from a progress callback: a run killed at a given progress line."""


def _run_killed_at(prob: Any, checkpoint: Any, line: str, **kw: Any) -> None:
    """Run ``solve_nonlinear`` with a checkpoint until the progress line starting with
    ``line`` (in-step lines every 64 iterations), where it is killed."""

    def kill(msg: str) -> None:
        if msg.startswith(line):
            raise _Killed

    with pytest.raises(_Killed):
        pdlin.solve_nonlinear(prob, checkpoint=checkpoint, progress=kill, progress_every=0, **kw)


def test_adr_snapshot_resumes_an_interrupted_increment_bitwise(tmp_path, monkeypatch):
    """A run killed inside an ADR increment resumes from the increment's snapshot (written
    next to the checkpoint every ``snapshot_every`` seconds; 0: every 64 iterations) and
    ends exactly where an uninterrupted run ends: displacements, iterations, damping and
    criteria bitwise, two more constitutive sweeps counted (the responses at the start and
    at the snapshot).  A snapshot of another increment (here: another density) is not
    used, and the snapshot is removed when its load step commits."""
    _compiled_cp_update(monkeypatch)
    prob = _small_polycrystal()
    times = np.arange(1.0, 5.0)  # shear strain 0.002 per step: plastic from step 3
    kw: dict[str, Any] = {"times": times, "t_end": 30.0, "method": "adr", "snapshot_every": 0}
    ref = pdlin.solve_nonlinear(prob, checkpoint=tmp_path / "ref.npz", **kw)
    assert ref.iterations[2] > 128  # step 3 runs past the first snapshots

    ck = tmp_path / "run.npz"
    snap = tmp_path / "run.adr.npz"
    _run_killed_at(prob, ck, "  t = 3: ADR iteration 128:", **kw)
    assert int(np.load(ck)["done"]) == 2 and snap.exists()
    with np.load(snap) as f:  # step 3's whole increment, snapshot before the progress line
        assert f["keys"].size == 1 and int(f["s0__iteration"]) == 128
    said: list[str] = []
    res = pdlin.solve_nonlinear(prob, checkpoint=ck, resume=True, progress=said.append, **kw)
    assert any("ADR continues from its snapshot after iteration 128" in m for m in said)
    assert not snap.exists()  # removed when step 3 committed
    assert res.iterations.tolist() == ref.iterations.tolist()
    assert np.array_equal(res.u, ref.u)
    for k in (2, 3):  # the steps this run solved (the checkpoint keeps no damping history)
        assert np.array_equal(res.damping[k], ref.damping[k])
    assert res.e1.tolist() == ref.e1.tolist() and res.e2.tolist() == ref.e2.tolist()
    n_gp = prob.cloud.n  # one gradient point per particle (no stress points)
    assert res.calls[2] == ref.calls[2] + 2 * n_gp and res.calls[3] == ref.calls[3]

    # another increment's snapshot (another density: another key) is not continued (a
    # checkpoint continued with other solver options: resume="branch")
    ck2 = tmp_path / "other.npz"
    _run_killed_at(prob, ck2, "  t = 3: ADR iteration 128:", **kw)
    said.clear()
    other = pdlin.solve_nonlinear(
        prob, checkpoint=ck2, resume="branch", progress=said.append, density_safety=1.2, **kw
    )
    assert not any("continues from its snapshot" in m for m in said)
    assert other.iterations[2] != ref.iterations[2] or not np.array_equal(other.u, ref.u)
    with pytest.raises(InputError, match="snapshot_every must be a finite number"):
        pdlin.solve_nonlinear(prob, steps=1, snapshot_every=-1.0)


def test_adr_snapshots_resume_a_cut_back_step_bitwise(tmp_path, monkeypatch):
    """Killed in the half increment of a step whose whole increment failed (budget 130
    iterations: step 3 needs 136 as a whole), the resumed run finds both increments'
    snapshots: the whole step continues from its iteration 128 and fails again at 130,
    the half continues from its iteration 64; the run ends where the uninterrupted one
    does, bit for bit, the step's wall time including the killed run's."""
    _compiled_cp_update(monkeypatch)
    prob = _small_polycrystal()
    kw: dict[str, Any] = {
        "times": np.arange(1.0, 4.0),
        "t_end": 30.0,
        "method": "adr",
        "adr_maxiter": 130,
        "snapshot_every": 0,
    }
    ref = pdlin.solve_nonlinear(prob, **kw)
    assert ref.cutbacks.tolist() == [0, 0, 1]  # step 3: the whole fails, two halves

    ck = tmp_path / "run.npz"
    _run_killed_at(prob, ck, "  t = 2.5: ADR iteration 64:", **kw)
    with np.load(tmp_path / "run.adr.npz") as f:
        assert f["keys"].size == 2  # the failed whole step's and the half's
        assert sorted(int(f[f"s{i}__iteration"]) for i in range(2)) == [64, 128]
        killed_time = max(float(f[f"s{i}__step_elapsed"]) for i in range(2))
    said: list[str] = []
    res = pdlin.solve_nonlinear(prob, checkpoint=ck, resume=True, progress=said.append, **kw)
    resumed = [m for m in said if "continues from its snapshot" in m]
    assert len(resumed) == 2 and "t = 3:" in resumed[0] and "t = 2.5:" in resumed[1]
    assert np.array_equal(res.u, ref.u) and res.iterations.tolist() == ref.iterations.tolist()
    assert res.cutbacks.tolist() == ref.cutbacks.tolist()
    assert np.array_equal(res.damping[2], ref.damping[2])
    assert res.timings["steps"][2] > killed_time > 0
    assert not (tmp_path / "run.adr.npz").exists()


# ---------------------------------------------------------------------------------------
# Newton polish of stalled ADR increments (``polish`` / ``adr_stall``)


def _chain_system() -> tuple[Any, dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """The graded hardening chain's constrained system, initial state, start (the end
    values, linear in between) and Gershgorin density."""
    from pdlin.solvers.adr import adr_density

    system = pdlin.constrained_system(_chain(u_end=0.2, graded=True, beta=10.0))
    st = system.initial_state()
    u0 = 0.2 * np.linspace(0.0, 1.0, system.ndof)  # the end values, linear in between
    return system, st, u0, adr_density(system, st, u0, dt=1.0, safety=1.1)


def test_stalled_compares_the_last_window_with_the_best_before():
    from pdlin.solvers.adr import _stalled

    falling = [2.0**-k for k in range(40)]  # halves every iteration: never stalled
    assert not _stalled(falling, 40, 10)
    flat = [1.0] * 40
    assert _stalled(flat, 40, 10)
    # a twofold drop within the last window is progress; a drop to 0.6 of the best is not
    assert not _stalled([1.0] * 30 + [0.49] * 10, 40, 10)
    assert _stalled([1.0] * 30 + [0.6] * 10, 40, 10)
    # an earlier minimum counts: a plateau above the best reached before is a stall
    assert _stalled([1.0] * 10 + [1e-3] + [1e-2] * 29, 40, 10)


def test_adr_polish_finishes_an_undamped_stall_with_newton():
    """Undamped ADR (``damping=0``) never settles: its ‖r‖ oscillates without a trend, so
    the first stall check (iteration 2·stall) calls ``polish``, whose Newton solution ends
    the increment at Newton's residual criterion; e1/e2 are not ADR's then (None)."""
    from pdlin.solvers import adr_step, newton_step

    system, st, u0, lam = _chain_system()
    tries: list[int] = []

    def polish(u):
        tries.append(1)
        return newton_step(system, u, st, factor=1.0, maxiter=25)

    kw: dict[str, Any] = {"factor": 1.0, "density": lam, "dt": 1.0, "damping": 0.0}
    out = adr_step(system, u0, st, maxiter=1000, polish=polish, stall=50, **kw)
    assert tries == [1] and out.iterations == 100  # the first check: 2 x the window
    assert 1 <= out.polish <= 25 and out.e1 is None and out.e2 is None
    assert out.residual <= 1e-8  # newton_step's default rtol
    ref = newton_step(system, u0, st, factor=1.0, maxiter=25)
    np.testing.assert_allclose(out.u, ref.u, rtol=0, atol=1e-9 * 0.2)
    # without polish the same undamped iteration runs out of its budget
    with pytest.raises(StepFailed, match="no convergence in 1000 iterations"):
        adr_step(system, u0, st, maxiter=1000, **kw)


def test_failed_polish_leaves_the_adr_iterates_bitwise():
    """A polish that fails costs its Newton iterations (``polish``) and calls; the ADR
    iteration goes on exactly as without it, and the last try's reason is in the
    budget failure's message."""
    from pdlin.solvers import StepOutcome, adr_step

    system, st, u0, lam = _chain_system()
    tries: list[np.ndarray] = []

    def refuse(u):
        tries.append(u)
        raise StepFailed("Newton: refused (test)", StepOutcome(u, None, 3, 7, 1.0))

    kw: dict[str, Any] = {"factor": 1.0, "density": lam, "dt": 1.0, "damping": 0.0}
    with pytest.raises(StepFailed) as plain:
        adr_step(system, u0, st, maxiter=400, **kw)
    with pytest.raises(StepFailed, match="Newton from its last iterate failed") as tried:
        adr_step(system, u0, st, maxiter=400, polish=refuse, stall=50, **kw)
    a, b = plain.value.outcome, tried.value.outcome
    assert a is not None and b is not None
    assert np.array_equal(a.u, b.u) and np.array_equal(a.damping, b.damping)
    # tries at the stall checks 100, 150, ..., 400 (the last also the budget's end)
    assert len(tries) == 7 and b.polish == 3 * 7 and b.calls == a.calls + 7 * 7
    with pytest.raises(InputError, match="stall must be an integer >= 0"):
        adr_step(system, u0, st, maxiter=10, stall=-1, **kw)


def test_auto_polishes_adr_at_the_end_of_its_budget(tmp_path):
    """``method='auto'``: Newton fails from the predictor (two iterations are too few),
    ADR falls back with a budget too small for e_l = 1e-12, and Newton from ADR's last
    iterate converges in those two iterations: the step converges, ``polishes`` counts
    them, e1/e2 are NaN (Newton's criterion decided); ADR alone fails the same step, and
    ``polish=True`` lets it through too.  The checkpoint keeps the counts."""
    prob = _chain(u_end=0.2, graded=True, beta=1e3)
    kw: dict[str, Any] = {
        "steps": 1, "maxiter": 2, "max_cutbacks": 0, "predictor": "tangent",
        "adr_maxiter": 100, "e_l": 1e-12,
    }  # fmt: skip
    ck = tmp_path / "auto.npz"
    said: list[str] = []
    res = pdlin.solve_nonlinear(prob, method="auto", checkpoint=ck, progress=said.append, **kw)
    assert res.methods == ["adr (newton failed)"] and res.polishes.tolist() == [2]
    assert any("ADR iteration 100: budget spent" in m for m in said)
    assert any("Newton from this iterate converged in 2 iteration(s)" in m for m in said)
    assert "2 Newton polish iteration(s)" in said[-1]  # the step line
    assert np.isnan(res.e1[0]) and np.isnan(res.e2[0]) and res.residuals[0] <= 1e-8
    assert res.summary()["polish_iterations"] == 2
    ref = pdlin.solve_nonlinear(prob, steps=1, method="newton", predictor="tangent")
    np.testing.assert_allclose(res.u[-1], ref.u[-1], rtol=0, atol=1e-9 * 0.2)
    again = pdlin.solve_nonlinear(prob, method="auto", checkpoint=ck, resume=True, **kw)
    assert again.resumed_from == 1 and again.polishes.tolist() == [2]
    with pytest.raises(ConvergenceError, match="ADR failed at load step 1"):
        pdlin.solve_nonlinear(prob, method="adr", **kw)
    adr = pdlin.solve_nonlinear(prob, method="adr", polish=True, **kw)
    assert adr.methods == ["adr"] and adr.polishes.tolist() == [2]
    with pytest.raises(ConvergenceError, match="ADR failed at load step 1"):
        pdlin.solve_nonlinear(prob, method="auto", polish=False, **kw)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"polish": "yes"}, "polish must be True, False or None, got 'yes'"),
        ({"adr_stall": 0}, "adr_stall must be an integer >= 1"),
        ({"adr_stall": 2.5}, "adr_stall must be an integer >= 1"),
    ],
)
def test_polish_arguments_name_themselves(kwargs, match):
    with pytest.raises(InputError, match=match):
        pdlin.solve_nonlinear(_chain(), **kwargs)


def test_adr_restart_with_polish_tries_is_bitwise_and_keeps_their_count():
    """A snapshot taken after failed polish tries restarts to the same end: the iterates
    bit for bit and the tries' Newton iterations (kept in the snapshot) counted once."""
    from pdlin.solvers import StepOutcome, adr_step

    system, st, u0, lam = _chain_system()

    def refuse(u):
        raise StepFailed("Newton: refused (test)", StepOutcome(u, None, 3, 7, 1.0))

    snaps: list[dict[str, Any]] = []

    def keep(loop: dict[str, Any]) -> None:
        snaps.append({k: np.array(v) for k, v in loop.items()})

    kw: dict[str, Any] = {
        "factor": 1.0, "density": lam, "dt": 1.0, "damping": 0.0, "maxiter": 400,
        "polish": refuse, "stall": 50,
    }  # fmt: skip
    with pytest.raises(StepFailed) as whole:
        adr_step(system, u0, st, snapshot=keep, snapshot_every=0.0, **kw)
    snap = next(s for s in snaps if int(s["iteration"]) == 128)  # after the try at 100
    assert int(snap["polish"]) == 3
    with pytest.raises(StepFailed) as resumed:
        adr_step(system, u0, st, restart=snap, **kw)
    a, b = whole.value.outcome, resumed.value.outcome
    assert a is not None and b is not None
    assert np.array_equal(a.u, b.u) and a.polish == b.polish == 3 * 7
