"""The CPFE comparator ``pdlin.verification.crystal_plasticity_fem`` (Q4 / Hex8, F-bar).

References: the homogeneous material-point driver (``material_point``, whose tables
reproduce Luo, Ramazani & Sundararaghavan 2017 to every printed digit), central finite
differences of the element force, and pdlin's linear Q4 / Hex8 solvers
(``pdlin.verification.fem``) in the small-strain limit.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import pdlin
from pdlin.constitutive import material_point
from pdlin.errors import InputError, InputTypeError
from pdlin.verification import crystal_plasticity_fem, element_average, pixel_mesh
from pdlin.verification.cpfe import _FEDiscretization, _gauss_state
from pdlin.verification.fem import solve_hex8, solve_q4

SHEAR = np.array([[0.0, 1.0], [1.0, 0.0]])
COMPRESSION = np.diag([1.0, -1.0])


def _cp_problem(mat, shape, L, spacing=1.0, where="boundary"):
    cloud = pdlin.grid(shape, spacing=spacing)
    bc = pdlin.Dirichlet.velocity_gradient(where, L)
    return pdlin.StaticProblem(
        pdlin.Correspondence(material=mat), cloud, horizon=1.5 * spacing, dirichlet=[bc]
    )


@pytest.mark.parametrize("integration", ["fbar", "full"])
@pytest.mark.parametrize(
    ("loading", "L"), [("shear", SHEAR), ("compression", COMPRESSION)], ids=["shear", "compr"]
)
@pytest.mark.parametrize("deg", [0.0, -60.0, 15.0])
def test_single_crystal_equals_material_point(integration, loading, L, deg):
    """Homogeneous path: every element equals the material point to 1e-10 (all 12 steps)."""
    mat = pdlin.CrystalPlasticity("planar-2", orientation=np.radians(deg))
    prob = _cp_problem(mat, (4, 3), 0.002 * L, spacing=0.25)
    steps = 12  # elastic (1-2), yield at 3 (or 6), plastic after: the tables' regimes
    res = crystal_plasticity_fem(prob, times=np.arange(1.0, steps + 1), integration=integration)
    ref = material_point(mat, loading, steps=steps)  # F = exp(0.002 L t), the tables' driver
    sig = ref.stress[:, 0]  # (steps, 2, 2)
    assert np.abs(res.stress - sig[:, None]).max() < 1e-10
    assert np.abs(res.homogenized_stress - sig).max() < 1e-10
    gam = element_average(res.state["gamma"], 4)
    assert np.abs(gam - ref.gamma[-1, 0]).max() < 1e-10
    assert ref.yield_step[0] in (3, 6)  # plastic steps were really exercised
    assert res.stress.shape == (steps, 12, 2, 2) and res.u.shape == (steps, 20, 2)


def test_single_crystal_3d_fcc_equals_material_point():
    """Hex8: an fcc single crystal in x-y shear equals the material point to 1e-10."""
    R = Rotation.from_euler("ZXZ", [0.3, 0.7, 1.1]).as_matrix()
    mat = pdlin.CrystalPlasticity("fcc", orientation=R)
    eta = 5e-5  # fcc needs small increments (docs/crystal_plasticity.md, Limitations)
    L = np.zeros((3, 3))
    L[0, 1] = L[1, 0] = 1.0
    prob = _cp_problem(mat, (2, 2, 2), eta * L, spacing=0.5)
    steps = 5
    res = crystal_plasticity_fem(prob, times=np.arange(1.0, steps + 1), rtol=1e-12)
    ref = material_point(mat, "shear", steps=steps, eta=eta)
    assert ref.plastic[-1, 0]  # the last steps slip
    assert np.abs(res.stress - ref.stress[:, 0][:, None]).max() < 1e-10  # measured 7e-15
    assert np.abs(res.homogenized_stress - ref.stress[:, 0]).max() < 1e-10


def _fd_tangent(disc, u, state, eps):
    K = np.zeros((u.size, u.size))
    for j in range(u.size):  # a 3 x 3 or 2 x 2 x 2 mesh: a few dozen DOFs
        e = np.zeros(u.size)
        e[j] = eps
        fp = disc.respond(u + e, state).force.ravel()
        fm = disc.respond(u - e, state).force.ravel()
        K[:, j] = -(fp - fm) / (2.0 * eps)
    return K


@pytest.mark.parametrize("integration", ["fbar", "full"])
def test_tangent_is_consistent_2d(integration):
    """K_T of a plastic polycrystal patch equals central differences of the force (≤ 1e-8)."""
    rng = np.random.default_rng(0)
    cloud = pdlin.grid((3, 3), spacing=0.5)
    mat = pdlin.CrystalPlasticity("planar-2", orientation=rng.uniform(-1.5, 1.5, cloud.n))
    mesh = pixel_mesh(cloud)
    st = _gauss_state(mat, cloud.n, 4)
    disc = _FEDiscretization(None, mat, mesh, integration, st)
    X = mesh.nodes.points
    u = (X @ (0.01 * rng.normal(size=(2, 2))).T + 0.002 * rng.normal(size=X.shape)).ravel()
    r = disc.respond(u, st, tangent=True)
    assert r.state["plastic"].mean() > 0.5  # mostly slipping Gauss points
    K = r.tangent.toarray()
    err = np.abs(K - _fd_tangent(disc, u, st, 1e-7)).max() / np.abs(K).max()
    assert err < 1e-8  # measured 5e-10 (FD truncation)


def test_tangent_is_consistent_3d_fbar():
    """Hex8 F-bar tangent of a finite-strain SVK element pair equals central differences."""
    rng = np.random.default_rng(1)
    C = pdlin.constitutive.isotropic(E=1000.0, nu=0.3)
    mat = pdlin.SaintVenantKirchhoff(C)
    cloud = pdlin.grid((2, 1, 1), spacing=0.5)
    mesh = pixel_mesh(cloud)
    disc = _FEDiscretization(None, mat, mesh, "fbar", {})
    X = mesh.nodes.points
    u = (X @ (0.05 * rng.normal(size=(3, 3))).T + 0.01 * rng.normal(size=X.shape)).ravel()
    K = disc.respond(u, {}, tangent=True).tangent.toarray()
    assert np.abs(K - K.T).max() > 1e-3 * np.abs(K).max()  # F-bar: not symmetric
    err = np.abs(K - _fd_tangent(disc, u, {}, 1e-6)).max() / np.abs(K).max()
    assert err < 1e-8  # measured 5e-11


def _plane_strain_C(E, nu):
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])


def _q4_gap(a):
    E, nu = 1000.0, 0.3
    mat = pdlin.SaintVenantKirchhoff(_plane_strain_C(E, nu))
    cloud = pdlin.grid((6, 4), spacing=0.25)
    bcs = [
        pdlin.Dirichlet("x-", 0.0),
        pdlin.Dirichlet("x+", lambda x: a * np.c_[1.0 + x[:, 1] ** 2, 0.5 * x[:, 1]]),
    ]
    prob = pdlin.StaticProblem(pdlin.Correspondence(material=mat), cloud, horizon=0.3,
                               dirichlet=bcs)  # fmt: skip
    res = crystal_plasticity_fem(prob, steps=1, integration="full", rtol=1e-8)
    sysm = res.system
    u_ref = solve_q4(sysm.cloud.points, pixel_mesh(cloud).conn, E, nu, sysm.dofs,
                     sysm.values, plane="strain")  # fmt: skip
    free = sysm.free.reshape(-1, 2)
    assert np.abs(u_ref[free]).max() > 0.1 * a  # a non-trivial interior field
    return np.abs(res.u[-1] - u_ref).max() / np.abs(u_ref).max()


def test_linear_limit_equals_q4_reference():
    """Full integration, small strain: the nodal field tends to ``solve_q4`` (plane strain).

    The finite-strain SVK differs from linear elasticity by O(strain): the gap must be
    below the strain and fall tenfold with it.
    """
    g4, g5 = _q4_gap(1e-4), _q4_gap(1e-5)
    assert g5 < 1e-4
    assert 5.0 < g4 / g5 < 20.0


def test_linear_limit_equals_hex8_reference():
    """Hex8, full integration, tiny strain: the nodal field equals ``solve_hex8``."""
    E, nu, a = 1000.0, 0.25, 1e-5
    mat = pdlin.SaintVenantKirchhoff(pdlin.constitutive.isotropic(E=E, nu=nu))
    cloud = pdlin.grid((3, 2, 2), spacing=0.5)
    bcs = [
        pdlin.Dirichlet("x-", 0.0),
        pdlin.Dirichlet("x+", lambda x: a * np.c_[1.0 + x[:, 1], x[:, 2], 0.3 + 0 * x[:, 0]]),
    ]
    prob = pdlin.StaticProblem(pdlin.Correspondence(material=mat), cloud, horizon=0.6,
                               dirichlet=bcs)  # fmt: skip
    res = crystal_plasticity_fem(prob, steps=1, integration="full", rtol=1e-8)
    sysm = res.system
    u_ref = solve_hex8(sysm.cloud.points, pixel_mesh(cloud).conn, E, nu, sysm.dofs, sysm.values)
    assert np.abs(res.u[-1] - u_ref).max() / np.abs(u_ref).max() < 1e-4  # O(strain)


def test_result_fields_and_reactions():
    """Element stress, homogenized stress as its volume average, nodal reactions."""
    mat = pdlin.CrystalPlasticity("planar-2", orientation=np.radians([0, 30, -45, 60, 15, 75]))
    prob = _cp_problem(mat, (3, 2), 0.002 * SHEAR, spacing=0.5)
    res = crystal_plasticity_fem(prob, times=[1.0, 2.0, 3.0, 4.0])
    assert isinstance(res, pdlin.NonlinearResult)
    assert res.stress.shape == (4, 6, 2, 2) and res.u.shape == (4, 12, 2)
    assert np.allclose(res.homogenized_stress, res.stress.mean(axis=1), atol=1e-12)
    assert res.states[-1]["Fp"].shape == (24, 2, 2)  # one row per Gauss point
    assert np.all(res.residuals <= 1e-8)
    # a polycrystal: the elements differ (not a homogeneous field)
    assert np.ptp(res.stress[-1, :, 0, 1]) > 0.1


def test_input_errors():
    mat = pdlin.CrystalPlasticity("planar-2", orientation=0.0)
    prob = _cp_problem(mat, (3, 3), 0.002 * SHEAR)
    with pytest.raises(InputError, match="integration"):
        crystal_plasticity_fem(prob, integration="reduced")
    with pytest.raises(InputTypeError, match="StaticProblem"):
        crystal_plasticity_fem("problem")
    with pytest.raises(InputTypeError, match="material"):
        crystal_plasticity_fem(
            pdlin.StaticProblem(
                pdlin.BondBased(E=1.0), prob.cloud, horizon=1.5, dirichlet=prob.dirichlet
            )  # fmt: skip
        )
    idx = pdlin.StaticProblem(
        prob.model, prob.cloud, horizon=1.5,
        dirichlet=[pdlin.Dirichlet.velocity_gradient(np.arange(3), 0.002 * SHEAR)],
    )  # fmt: skip
    with pytest.raises(InputError, match="region name"):
        crystal_plasticity_fem(idx)
    cloud = pdlin.PointCloud(prob.cloud.points, volumes=1.0)
    bare = pdlin.StaticProblem(prob.model, cloud, horizon=1.5, dirichlet=prob.dirichlet)
    with pytest.raises(InputError, match="pixel grid"):
        crystal_plasticity_fem(bare)
    with pytest.raises(InputError, match="method"):
        crystal_plasticity_fem(prob, method="explicit")


@pytest.mark.slow
def test_mesh_convergence_of_homogenized_curve():
    """The homogenized shear curve converges as h halves (8, 16, 32 elements per side).

    A smooth orientation field θ = 0.6 sin(2πx) cos(πy) (grain maps converge erratically:
    their pixelated boundaries change with the grid).  Measured (docs/crystal_plasticity.md,
    CPFE section), gaps of σ̄_xy between successive grids 8-16 / 16-32 / 32-64: elastic step
    0.0315 / 0.0077 / 0.0020 MPa (second order), step 3 0.109 / 0.011 / 0.0097, step 10
    0.43 / 0.34 / 0.23 (slow: the slip bands narrow with the mesh).
    """
    curves = {}
    for n in (8, 16, 32):
        cloud = pdlin.grid((n, n), spacing=1.0 / n)
        x, y = cloud.points.T
        mat = pdlin.CrystalPlasticity(
            "planar-2", orientation=0.6 * np.sin(2 * np.pi * x) * np.cos(np.pi * y)
        )
        bc = pdlin.Dirichlet.velocity_gradient("boundary", 0.002 * SHEAR)
        prob = pdlin.StaticProblem(pdlin.Correspondence(material=mat), cloud, horizon=1.5 / n,
                                   dirichlet=[bc])  # fmt: skip
        res = crystal_plasticity_fem(prob, times=np.arange(1.0, 11.0), method="auto")
        curves[n] = res.homogenized_stress[:, 0, 1]
    g1 = np.abs(curves[16] - curves[8])
    g2 = np.abs(curves[32] - curves[16])
    assert g2[0] < 0.35 * g1[0]  # elastic: measured 0.245, second order 0.25
    assert np.all(g2[:3] < 0.5 * g1[:3])  # up to the knee (yield at step 2-3)
    assert g2.max() < g1.max()  # the whole curve: 0.34 < 0.43
    assert g2.max() / np.abs(curves[32]).max() < 0.03  # measured 2.5 %


def test_scene_tradeoff_reference_cpfe():
    """``reference = "cpfe"`` in a nonlinear scene's [tradeoff]: the error of each point is
    that of its homogenized history against the CPFE solve of the same grid."""
    from pdlin.errors import SceneError
    from pdlin.scene.scene import builtin_scene, scene_from_dict
    from pdlin.scene.tradeoff import tradeoff_from_dict
    from pdlin.sweeps.core import error_metric

    data, _ = builtin_scene("cp_shear")
    data["solver"].update(steps=4, t_end=4.0)
    data["tradeoff"]["reference"] = "cpfe"
    data["tradeoff"]["sweep"] = {"h": [0.125]}
    data["tradeoff"].pop("finest")
    sweep = tradeoff_from_dict(data)
    res = sweep.run(memory="none")
    (row,) = res.table
    assert row["status"] == "ok" and row["reference"] == "fem"
    # the same error computed directly: CPPD and CPFE on the 8 x 8 scene problem
    sc = scene_from_dict(sweep.scene_data(h=0.125))
    pd = pdlin.solve_nonlinear(sc.problem, **sc.nonlinear).homogenized_stress
    fe = crystal_plasticity_fem(sc.problem, steps=4, t_end=4.0, method="auto")
    expected = error_metric("rel-max")(pd.reshape(4, -1), fe.homogenized_stress.reshape(4, -1))
    assert row["error"] == pytest.approx(expected, rel=1e-6)
    assert 0.0 < row["error"] < 0.3  # CPPD near CPFE (measured 0.09 at 8 x 8, 4 steps)
    lin, _ = builtin_scene("bar")
    lin["tradeoff"] = {"reference": "cpfe", "sweep": {"m": [3.015]}}
    with pytest.raises(InputError, match="nonlinear scenes only") as info:
        tradeoff_from_dict(lin).run(memory="none")
    assert isinstance(info.value.__cause__, SceneError)


@pytest.mark.slow
def test_full_integration_locks_fbar_does_not():
    """Volumetric locking of the isochoric slip: the fully integrated Q4 stiffens with the
    plastic strain against F-bar (why F-bar is the default).

    Measured on this 12 x 12, 8-grain map: full / F-bar − 1 = 0.4 % at the elastic step,
    2.9 % at step 10 and 4.4 % at step 20 (the 21-grain benchmark: 5.1-5.2 % at step 30).
    """
    n = 12
    cloud = pdlin.grid((n, n), spacing=1.0 / n)
    _, theta = pdlin.voronoi_polycrystal(cloud, 8, seed=2)
    mat = pdlin.CrystalPlasticity("planar-2", orientation=theta)
    bc = pdlin.Dirichlet.velocity_gradient("boundary", 0.002 * SHEAR)
    prob = pdlin.StaticProblem(pdlin.Correspondence(material=mat), cloud, horizon=1.5 / n,
                               dirichlet=[bc])  # fmt: skip
    sig = {
        k: crystal_plasticity_fem(
            prob, times=np.arange(1.0, 11.0), integration=k, method="auto"
        ).homogenized_stress[:, 0, 1]  # fmt: skip
        for k in ("fbar", "full")
    }
    excess = sig["full"] / sig["fbar"] - 1.0
    assert 0.0 < excess[0] < 0.01  # elastic: the two rules nearly agree
    assert np.all(np.diff(excess) > 0.0)  # the excess grows with the plastic strain
    assert excess[-1] > 0.02
