"""``pdlin.Correspondence(material=...)``: the nonlinear interface (respond / initial_state),
its consistent tangent, controls, stress points, errors, and :func:`pdlin.ghost_layer`."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.linalg import expm

import pdlin
from pdlin.constitutive import isotropic, isotropic_2d
from pdlin.errors import InputError, InputTypeError, ModelError, ShapeError

#: plane-strain isotropic stiffness used for SVK and the linear model (E = 2000 MPa, ν = 0.3:
#: the order of D11 in Luo, Ramazani & Sundararaghavan (2017), Sec. 4)
C_ISO = isotropic_2d(2000.0, 0.3, plane="strain")

#: (control, bond ratio) pairs exercised by the tangent tests: the setting of Luo, Ramazani &
#: Sundararaghavan (2017) ('none', δ = h and √2 h), stress points (Luo & Sundararaghavan (2018),
#: δ = h), higher-order weights (δ = 2h) and the linear add-ons
CASES = [
    ("none", 1.0),
    ("none", np.sqrt(2.0)),
    ("stress_points", 1.0),
    ("higher_order", 2.0),
    ("penalty", 2.0),
    ("springs", 1.0),
    ("ads", 1.0),
]


def _cloud(n=5):
    return pdlin.grid((n, n), spacing=1.0 / n)


def _cp(cloud, seed=0):
    theta = np.random.default_rng(seed).uniform(-np.pi / 2, np.pi / 2, cloud.n)
    return pdlin.CrystalPlasticity(orientation=theta)


def _plastic_u(cloud, seed=0):
    """Shear 0.01 (5 load steps of Luo, Ramazani & Sundararaghavan (2017), Eq. 25, in one go) plus a
    small random field."""
    n = round(np.sqrt(cloud.n))
    F = expm(0.01 * np.array([[0.0, 1.0], [1.0, 0.0]]))
    rng = np.random.default_rng(seed)
    return cloud.points @ (F - np.eye(2)).T + 1e-3 / n * rng.standard_normal((cloud.n, 2))


def _fd_tangent(model, cloud, bonds, u, state, eps):
    x = u.ravel()
    K = np.empty((x.size, x.size))
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = eps
        fp = model.respond(cloud, bonds, (x + e).reshape(u.shape), state).force.ravel()
        fm = model.respond(cloud, bonds, (x - e).reshape(u.shape), state).force.ravel()
        K[:, k] = -(fp - fm) / (2 * eps)
    return K


# ---------------------------------------------------------------------------------------
# construction and errors


def test_material_flags():
    cp = pdlin.Correspondence(material=pdlin.CrystalPlasticity())
    svk = pdlin.Correspondence(material=pdlin.SaintVenantKirchhoff(C_ISO))
    lin = pdlin.Correspondence(C_ISO)
    assert cp.nonlinear and svk.nonlinear and not lin.nonlinear
    assert not cp.symmetric  # dP/dF of crystal plasticity has no major symmetry
    assert svk.symmetric and lin.symmetric  # hyperelastic: major symmetry
    assert cp.describe()["material"] == "CrystalPlasticity"


def test_material_errors_name_argument_expectation_and_value():
    class NoUpdate:
        def initial_state(self, n):
            return {}

    with pytest.raises(InputTypeError, match=r"material must provide .* got NoUpdate without upd"):
        pdlin.Correspondence(material=NoUpdate())
    with pytest.raises(InputError, match="got material and C"):
        pdlin.Correspondence(C_ISO, material=pdlin.SaintVenantKirchhoff(C_ISO))
    with pytest.raises(InputError, match="got material and E, nu"):
        pdlin.Correspondence(E=1.0, nu=0.3, material=pdlin.SaintVenantKirchhoff(C_ISO))
    with pytest.raises(ModelError, match="shadow= is not supported with material="):
        pdlin.Correspondence(material=pdlin.SaintVenantKirchhoff(C_ISO), shadow=[0])
    cloud = _cloud()
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    m3 = pdlin.Correspondence(material=pdlin.SaintVenantKirchhoff(isotropic(E=1.0, nu=0.3)))
    with pytest.raises(ModelError, match="material is 3D but the cloud is 2D"):
        m3.initial_state(cloud, bonds)
    bad = pdlin.Correspondence(material=pdlin.CrystalPlasticity(orientation=np.zeros(7)))
    with pytest.raises(ShapeError, match=r"one particle each \(25\), got 7"):
        bad.initial_state(cloud, bonds)
    model = pdlin.Correspondence(material=_cp(cloud), control="stress_points")
    wrong = pdlin.CrystalPlasticity().initial_state(cloud.n)  # per particle, not per SP
    with pytest.raises(ShapeError, match=r"one row per gradient point"):
        model.respond(cloud, bonds, np.zeros((cloud.n, 2)), wrong)
    with pytest.raises(InputTypeError, match="state must be a dict"):
        model.respond(cloud, bonds, np.zeros((cloud.n, 2)), [1, 2])


# ---------------------------------------------------------------------------------------
# state


def test_initial_state_per_gradient_point_with_orientation_of_the_owner():
    cloud = _cloud(6)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    mat = _cp(cloud, seed=2)
    model = pdlin.Correspondence(material=mat, control="stress_points")
    state = model.initial_state(cloud, bonds)
    owner = model.stress_points(cloud, bonds)["owner"]
    assert owner.size > cloud.n  # interior particles have two stress points
    assert state["Fp"].shape == (owner.size, 2, 2)
    np.testing.assert_array_equal(state["theta0"], mat.orientation[owner])
    plain = pdlin.Correspondence(material=mat)
    assert plain.initial_state(cloud, bonds)["Fp"].shape[0] == cloud.n
    # a scalar orientation is one crystal
    one = pdlin.Correspondence(material=pdlin.CrystalPlasticity(orientation=0.3))
    np.testing.assert_array_equal(one.initial_state(cloud, bonds)["theta0"], 0.3)
    svk = pdlin.Correspondence(material=pdlin.SaintVenantKirchhoff(C_ISO))
    assert svk.initial_state(cloud, bonds) == {}
    assert pdlin.Correspondence(C_ISO).initial_state(cloud, bonds) == {}


@pytest.mark.parametrize("control", ["none", "stress_points", "penalty"])
def test_respond_never_mutates_the_given_state(control):
    cloud = _cloud(6)
    bonds = pdlin.find_bonds(cloud, ratio=1.0 if control != "penalty" else 2.0)
    model = pdlin.Correspondence(material=_cp(cloud), control=control)
    state = model.initial_state(cloud, bonds)
    # a committed plastic state, then a second plastic trial from it
    state = model.respond(cloud, bonds, _plastic_u(cloud), state).state
    before = copy.deepcopy(state)
    r = model.respond(cloud, bonds, 1.5 * _plastic_u(cloud, 1), state, tangent=True)
    assert r.state["plastic"].any()
    assert sorted(state) == sorted(before)
    for key in before:
        np.testing.assert_array_equal(state[key], before[key])
    assert r.state is not state
    assert not np.array_equal(r.state["Fp"], state["Fp"])


def test_response_stress_and_calls():
    """Cauchy stress per particle = mean over its gradient points; calls = gradient points."""
    cloud = _cloud(6)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    mat = _cp(cloud, seed=3)
    model = pdlin.Correspondence(material=mat, control="stress_points")
    state = model.initial_state(cloud, bonds)
    u = _plastic_u(cloud, 3)
    r = model.respond(cloud, bonds, u, state)
    owner = model.stress_points(cloud, bonds)["owner"]
    assert r.calls == owner.size
    F = model.deformation_gradient(cloud, bonds, u)
    P, _, _ = mat.update(F, state)
    sig = mat.cauchy(P, F)
    ref = np.stack([sig[owner == a].mean(axis=0) for a in range(cloud.n)])
    np.testing.assert_allclose(r.stress, ref, rtol=1e-14, atol=1e-12)


def test_response_stress_is_computed_on_first_read_only(monkeypatch):
    """ADR iterations and line-search trials never read the stress: respond defers the
    per-particle Cauchy mean to the first read of ``stress`` and keeps it."""
    from pdlin.models.correspondence import model as cm

    cloud = _cloud(6)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    model = pdlin.Correspondence(material=_cp(cloud, seed=3))
    state = model.initial_state(cloud, bonds)
    means = []
    real = cm._mean_per_point
    monkeypatch.setattr(cm, "_mean_per_point", lambda *a: means.append(1) or real(*a))
    r = model.respond(cloud, bonds, _plastic_u(cloud, 3), state)
    assert means == []
    first = r.stress
    assert r.stress is first and means == [1] and first.shape == (cloud.n, 2, 2)


def test_response_state_without_tangent_is_computed_on_first_read_only(monkeypatch):
    """Without the tangent respond takes the force from ``material.piola`` and runs the
    full update for the trial state only when ``state`` is read (once per converged step),
    then keeps it; force and state equal those of the eager path (with the tangent).
    ``piola`` computes P without the trial state in the compiled kernel only (numba,
    batches from 256 points on here; by default from 8,192)."""
    pytest.importorskip("numba")
    from pdlin._kernels import numba_enabled
    from pdlin.constitutive import crystal_plasticity as cpm

    if not numba_enabled():
        pytest.skip("numba disabled (PDLIN_NUMBA=0)")
    monkeypatch.setattr(cpm, "_NUMBA_MIN_POINTS", 256)
    cloud = _cloud(16)  # 256 gradient points: the compiled kernel
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    mat = _cp(cloud, seed=3)
    model = pdlin.Correspondence(material=mat)
    state = model.initial_state(cloud, bonds)
    updates = []
    real = type(mat).update
    monkeypatch.setattr(type(mat), "update", lambda *a, **k: updates.append(1) or real(*a, **k))
    u = _plastic_u(cloud, 3)
    r = model.respond(cloud, bonds, u, state)
    assert updates == []
    eager = model.respond(cloud, bonds, u, state, tangent=True)
    assert updates == [1]
    np.testing.assert_array_equal(r.force, eager.force)
    trial = r.state
    assert updates == [1, 1] and r.state is trial and trial["plastic"].any()
    assert sorted(trial) == sorted(eager.state)
    for key in trial:
        np.testing.assert_array_equal(trial[key], eager.state[key], err_msg=key)


# ---------------------------------------------------------------------------------------
# tangent


@pytest.mark.parametrize(("control", "ratio"), CASES)
def test_tangent_matches_finite_differences_crystal_plasticity(control, ratio):
    """K_T vs central FD of f(u) at a plastic state (same committed state), 1e-6 rel."""
    cloud = _cloud(5)
    bonds = pdlin.find_bonds(cloud, ratio=ratio)
    model = pdlin.Correspondence(material=_cp(cloud, 4), control=control)
    state = model.initial_state(cloud, bonds)
    u = _plastic_u(cloud, 4)
    r = model.respond(cloud, bonds, u, state, tangent=True)
    assert r.state["plastic"].mean() > 0.5
    K = r.tangent.toarray()
    assert r.tangent.blocksize == (2, 2)
    KF = _fd_tangent(model, cloud, bonds, u, state, eps=1e-7 / 5)
    np.testing.assert_allclose(K, KF, rtol=0, atol=1e-6 * np.abs(K).max())
    assert np.abs(K - K.T).max() > 1e-3 * np.abs(K).max()  # nonsymmetric (CP)


@pytest.mark.parametrize(("control", "ratio"), CASES)
def test_tangent_matches_finite_differences_svk(control, ratio):
    cloud = _cloud(5)
    bonds = pdlin.find_bonds(cloud, ratio=ratio)
    model = pdlin.Correspondence(material=pdlin.SaintVenantKirchhoff(C_ISO), control=control)
    state = model.initial_state(cloud, bonds)
    rng = np.random.default_rng(5)
    u = 0.03 / 5 * rng.standard_normal((cloud.n, 2))  # strains of a few percent
    K = model.respond(cloud, bonds, u, state, tangent=True).tangent.toarray()
    KF = _fd_tangent(model, cloud, bonds, u, state, eps=1e-7 / 5)
    np.testing.assert_allclose(K, KF, rtol=0, atol=1e-6 * np.abs(K).max())
    if model.symmetric:  # ADS with constant ω is symmetric too
        assert np.array_equal(K, K.T)


def test_tangent_3d_fcc_and_svk():
    cloud = pdlin.grid((3, 3, 3), spacing=1.0 / 3)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    rng = np.random.default_rng(7)
    euler = rng.uniform(0, np.pi, (cloud.n, 3))  # Bunge angles per particle
    for mat in (
        pdlin.CrystalPlasticity("fcc", orientation=euler),
        pdlin.SaintVenantKirchhoff(isotropic(E=1000.0, nu=0.3)),
    ):
        model = pdlin.Correspondence(material=mat, control="stress_points")
        state = model.initial_state(cloud, bonds)
        u = (
            cloud.points
            @ (expm(0.003 * np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1.0]])) - np.eye(3)).T
        )
        u += 1e-4 * rng.standard_normal(u.shape)
        K = model.respond(cloud, bonds, u, state, tangent=True).tangent.toarray()
        KF = _fd_tangent(model, cloud, bonds, u, state, eps=1e-8)
        np.testing.assert_allclose(K, KF, rtol=0, atol=1e-6 * np.abs(K).max())


def test_stiffness_is_the_initial_tangent():
    """The linearized K of a material model is K_T at u = 0 from the initial state."""
    cloud = _cloud(6)
    bonds = pdlin.find_bonds(cloud, ratio=np.sqrt(2.0))
    model = pdlin.Correspondence(material=_cp(cloud, 8))
    state = model.initial_state(cloud, bonds)
    K0 = pdlin.assemble_stiffness(model, cloud, bonds).toarray()
    KT = model.respond(cloud, bonds, np.zeros((cloud.n, 2)), state, tangent=True).tangent
    np.testing.assert_allclose(KT.toarray(), K0, rtol=0, atol=1e-12 * np.abs(K0).max())


# ---------------------------------------------------------------------------------------
# linear limit


@pytest.mark.parametrize(("control", "ratio"), CASES)
def test_linear_limit_matches_the_linear_model(control, ratio):
    """SVK with the isotropic C at strains ~1e-6: f equals the linear model's force to
    ~1e-6 relative, and the gap is O(|u|²): relative to f ~ |u| it shrinks 10x for u / 10."""
    cloud = _cloud(6)
    bonds = pdlin.find_bonds(cloud, ratio=ratio)
    nl = pdlin.Correspondence(material=pdlin.SaintVenantKirchhoff(C_ISO), control=control)
    lin = pdlin.Correspondence(C_ISO, control=control)
    state = nl.initial_state(cloud, bonds)
    rng = np.random.default_rng(9)
    u = 1e-6 / 6 * rng.standard_normal((cloud.n, 2))  # |∇u| ~ 1e-6
    gaps = []
    for s in (1.0, 0.1):
        f_nl = nl.respond(cloud, bonds, s * u, state).force
        f_lin = lin.internal_force(cloud, bonds, s * u)
        gaps.append(np.abs(f_nl - f_lin).max() / np.abs(f_lin).max())
    assert gaps[0] < 1e-5
    assert 9 < gaps[0] / gaps[1] < 11  # |f_nl - f_lin| ~ |u|², |f_lin| ~ |u|
    np.testing.assert_allclose(
        nl.internal_force(cloud, bonds, u, linear=False),
        nl.respond(cloud, bonds, u, state).force,
    )
    np.testing.assert_allclose(
        nl.internal_force(cloud, bonds, u), lin.internal_force(cloud, bonds, u), rtol=1e-12
    )


def test_linear_model_respond_unchanged():
    cloud = _cloud(5)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    lin = pdlin.Correspondence(C_ISO)
    u = np.random.default_rng(1).standard_normal((cloud.n, 2))
    r = lin.respond(cloud, bonds, u, {}, tangent=True)
    np.testing.assert_allclose(r.force, lin.internal_force(cloud, bonds, u))
    assert r.calls == 0 and r.stress is None


def test_constrained_system_drives_respond_on_a_ghost_layer_problem():
    """The driver path: StaticProblem -> ConstrainedSystem.disc.respond, affine BC in time."""
    g = pdlin.ghost_layer(_cloud(6))
    # shear η = 0.002 (Luo, Ramazani & Sundararaghavan (2017), Eq. 25)
    L = np.array([[0.0, 0.002], [0.002, 0.0]])
    where = np.union1d(g.ghost, g.cloud.point_set("outer_ring"))
    model = pdlin.Correspondence(material=pdlin.CrystalPlasticity())
    prob = pdlin.StaticProblem(
        model, g.cloud, horizon=1.0 / 6, dirichlet=[pdlin.Dirichlet.velocity_gradient(where, L)]
    )
    sys = pdlin.constrained_system(prob)
    state = sys.disc.initial_state()
    u = np.zeros(sys.ndof)
    u[sys.dofs] = sys.values_at(2.0, 1.0)
    r = sys.disc.respond(u.reshape(-1, 2), state, tangent=True)
    assert r.tangent.shape == (sys.ndof, sys.ndof)
    # the prescribed values are the affine field of F = exp(2 L)
    Fm = expm(2.0 * L)
    np.testing.assert_allclose(
        u.reshape(-1, 2)[where], g.cloud.points[where] @ (Fm - np.eye(2)).T, atol=1e-15
    )


# ---------------------------------------------------------------------------------------
# ghost layer


def test_ghost_layer_structure():
    base = pdlin.grid((5, 4), spacing=0.25, origin=(1.0, -1.0))
    base = base.replace(material=np.arange(base.n) % 3, horizon=0.25)
    g = pdlin.ghost_layer(base, layers=2)
    cloud, ghost, source = g
    assert cloud.n == 9 * 8 and ghost.size == 9 * 8 - 20
    np.testing.assert_array_equal(cloud.points[: base.n], base.points)  # originals first
    np.testing.assert_array_equal(ghost, np.arange(base.n, cloud.n))
    np.testing.assert_array_equal(source[: base.n], np.arange(base.n))
    np.testing.assert_array_equal(cloud.material, base.material[source])
    np.testing.assert_allclose(cloud.volumes, 0.0625)
    # every ghost copies the nearest original point
    d = np.linalg.norm(cloud.points[ghost][:, None] - base.points[None], axis=2)
    np.testing.assert_allclose(d[np.arange(ghost.size), source[ghost]], d.min(axis=1))
    # the ghosts fill the grown box: the lattice stencil finds the same bonds as a tree
    b1 = pdlin.find_bonds(cloud, ratio=1.5)
    b2 = pdlin.find_bonds(cloud, ratio=1.5, method="tree")
    assert b1.n_bonds == b2.n_bonds
    pairs1 = set(zip(b1.i.tolist(), b1.j.tolist(), strict=True))
    assert pairs1 == set(zip(b2.i.tolist(), b2.j.tolist(), strict=True))
    assert np.array_equal(np.sort(cloud.point_set("outer_ring")), np.sort(
        np.union1d(np.union1d(base.sets["x-"], base.sets["x+"]),
                   np.union1d(base.sets["y-"], base.sets["y+"]))))  # fmt: skip
    np.testing.assert_array_equal(cloud.point_set("ghost"), ghost)
    assert sorted(set(base.sets)) == sorted(set(cloud.sets) - {"ghost", "outer_ring"})


def test_ghost_layer_errors():
    base = pdlin.grid((4, 4))
    with pytest.raises(InputError, match="layers must be an integer >= 1, got 0"):
        pdlin.ghost_layer(base, layers=0)
    no_lattice = pdlin.PointCloud(base.points, volumes=1.0)
    with pytest.raises(InputError, match="ghost_layer needs a lattice cloud"):
        pdlin.ghost_layer(no_lattice)


@pytest.mark.parametrize("control", ["penalty", "springs", "ads"])
def test_respond_control_force_is_the_matrix_free_product(control):
    # respond applies the control's assembled stiffness (faster at scale); its force is
    # that of the material alone minus the matrix-free product K_c u, to round-off
    cloud = _cloud(6)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    with_c = pdlin.Correspondence(material=_cp(cloud, 4), control=control, penalty=0.3)
    plain = pdlin.Correspondence(material=_cp(cloud, 4))
    state = with_c.initial_state(cloud, bonds)
    u = _plastic_u(cloud, 4)
    f_c = with_c.respond(cloud, bonds, u, state).force.ravel()
    f_0 = plain.respond(cloud, bonds, u, plain.initial_state(cloud, bonds)).force.ravel()
    p = with_c._plan(cloud, bonds)
    x = np.ravel(u)
    if control == "penalty":  # the matrix-free products of the linear operator
        ref = with_c._penalty_force(cloud, bonds, p, with_c._penalty_k(cloud, bonds, p), x)
    else:
        ref = with_c._control_products(cloud, bonds, p)[0](x)
    assert np.abs(ref).max() > 1e-3 * np.abs(f_0).max()  # the control matters here
    np.testing.assert_allclose(f_c, f_0 - ref, rtol=0, atol=1e-12 * np.abs(f_0).max())


@pytest.mark.parametrize("control", ["none", "penalty", "springs", "ads"])
def test_operators_hold_no_explicit_zeros(control):
    """G and the control stiffness K_c keep no stored zeros: at δ = h on a grid half of
    G's bond coefficients vanish (an axial bond has no transverse component) and half of
    the penalty's CSR entries are the zeros of its d x d blocks (multiples of I_d); each
    G u, Gᵀ s, K_c u of an ADR iteration multiplied them (2.6 → 1.5 ms for K_c u at 10⁵
    points, one thread). The products are those of the blocks (G) and of the assembled
    BSR (K_c), and building K_c leaves the springs' own matrix intact."""
    cloud = _cloud(6)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    model = pdlin.Correspondence(material=_cp(cloud, 4), control=control, penalty=0.3)
    p = model._plan(cloud, bonds)
    G = p.G
    assert G.nnz and np.all(G.data != 0.0)
    # the dense G from the blocks: row (g, i, q), column (point, i), value c_gp[q]
    d, blk = cloud.dim, p.blocks
    ref = np.zeros(G.shape)
    for b in range(blk.col.size):  # a 36-point grid: a loop over its blocks is fine
        for i in range(d):
            for q in range(d):
                ref[(blk.row[b] * d + i) * d + q, blk.col[b] * d + i] += blk.val[b, q]
    assert np.array_equal(G.toarray(), ref)
    assert np.count_nonzero(ref) == G.nnz  # exactly the nonzeros: none dropped, none kept
    if control == "none":
        assert model._addon_matrix(cloud, bonds, p) is None
        return
    before = None
    if control == "springs":
        S = model._control_factors(cloud, bonds, p)[0]
        before = (S.data.copy(), S.indices.copy(), S.indptr.copy())
    Kc = model._addon_matrix(cloud, bonds, p)
    assert Kc.nnz and np.all(Kc.data != 0.0)
    if control == "penalty":
        full = sp.csr_array(model._penalty_matrix(cloud, bonds, p)).toarray()
    else:
        full = sp.csr_array(model._control_matrix(cloud, bonds, p)).toarray()
    assert np.array_equal(Kc.toarray(), full)
    if before is not None:
        assert all(
            np.array_equal(a, b) for a, b in zip(before, (S.data, S.indices, S.indptr), strict=True)
        )


def test_force_weights_multiplied_in_row_chunks_on_threads(monkeypatch):
    """``w V P`` of a large stress array is multiplied in row chunks on pdlin's threads
    (from ``_THREADED_MULTIPLY`` entries); the nodal force is the same bitwise."""
    from pdlin.models.correspondence import model as corr

    cloud = _cloud(8)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    model = pdlin.Correspondence(material=_cp(cloud, 4))
    P = np.random.default_rng(5).standard_normal((cloud.n, 2, 2))
    ref = model.nodal_force(cloud, bonds, P)
    monkeypatch.setattr(corr, "_THREADED_MULTIPLY", 16)  # 2-row chunks
    pdlin.set_num_threads(2)
    try:
        assert np.array_equal(model.nodal_force(cloud, bonds, P), ref)
    finally:
        pdlin.set_num_threads(None)
