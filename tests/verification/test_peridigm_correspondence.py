"""Peridigm's ``Elastic Correspondence`` with its own finite kinematics and hourglass force.

:class:`pdlin.constitutive.hypoelastic.Hypoelastic` and
:class:`pdlin.models.correspondence.PeridigmCorrespondence` against

* Peridigm's own code, transcribed here point by point and bond by bond from
  ``correspondence.cxx`` (``computeShapeTensorInverseAndApproximateDeformationGradient``,
  ``computeUnrotatedRateOfDeformationAndRotationTensor``, ``computeHourglassForce``) and
  ``elastic_correspondence.cxx`` (``updateElasticCauchyStress``), independently of
  pdlin's vectorized forms;
* central differences of the force (consistent tangents);
* Peridigm's gold file of ``test/verification/ElasticCorrespondenceQSTension`` (commit
  ``82c6ad8``), at the tolerances of the deck's ``.comp`` file, the deck read by
  ``pdlin.read_deck`` and solved by ``pdlin.solve_nonlinear``.
"""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import pdlin
from pdlin.constitutive.hypoelastic import Hypoelastic
from pdlin.errors import InputError, ModelError, SceneError
from pdlin.models.correspondence import PeridigmCorrespondence
from pdlin.scene.decks.peridigm import peridigm_correspondence_model, peridigm_hourglass_penalty

DATA = Path(__file__).resolve().parents[1] / "data" / "peridigm"
DECK = DATA / "ElasticCorrespondenceQSTension"


# -- Peridigm's code, transcribed ---------------------------------------------------------
def _inv3(m: list[float]) -> tuple[list[float], float]:
    """Peridigm's ``Invert3by3Matrix`` (row-major 9-vector)."""
    det = (
        m[0] * m[4] * m[8] + m[1] * m[5] * m[6] + m[2] * m[3] * m[7]
        - m[2] * m[4] * m[6] - m[1] * m[3] * m[8] - m[0] * m[5] * m[7]
    )  # fmt: skip
    inv = [
        m[4] * m[8] - m[5] * m[7], m[2] * m[7] - m[1] * m[8], m[1] * m[5] - m[2] * m[4],
        m[5] * m[6] - m[3] * m[8], m[0] * m[8] - m[2] * m[6], m[2] * m[3] - m[0] * m[5],
        m[3] * m[7] - m[4] * m[6], m[1] * m[6] - m[0] * m[7], m[0] * m[4] - m[1] * m[3],
    ]  # fmt: skip
    return [v / det for v in inv], det


def _mm(a: list[float], b: list[float], ta: bool = False, tb: bool = False) -> list[float]:
    """Peridigm's ``MatrixMultiply`` (optional transposes), row-major 3 x 3."""

    def at(m: list[float], i: int, j: int, t: bool) -> float:
        return m[3 * j + i] if t else m[3 * i + j]

    return [
        sum(at(a, i, k, ta) * at(b, k, j, tb) for k in range(3)) for i in range(3) for j in range(3)
    ]


def _peridigm_point(F, Fn, Vn, Rn, Sn, K, G, dt=0.5):
    """One point of Peridigm's quasi-static step, literally as in correspondence.cxx.

    ``Ḟ = (F - F_n)/dt`` (velocity ``Δu/dt``, ``Peridigm.cpp``); returns the Cauchy stress,
    V, R and the unrotated stress at N+1 (9-vectors).
    """
    Fdot = [(F[k] - Fn[k]) / dt for k in range(9)]
    Finv, _ = _inv3(F)
    L = _mm(Fdot, Finv)
    D = [
        L[0],
        0.5 * (L[1] + L[3]),
        0.5 * (L[2] + L[6]),
        0.0,
        L[4],
        0.5 * (L[5] + L[7]),
        0.0,
        0.0,
        L[8],
    ]
    D[3], D[6], D[7] = D[1], D[2], D[5]
    W = [
        0.0,
        0.5 * (L[1] - L[3]),
        0.5 * (L[2] - L[6]),
        0.0,
        0.0,
        0.5 * (L[5] - L[7]),
        0.0,
        0.0,
        0.0,
    ]
    W[3], W[6], W[7] = -W[1], -W[2], -W[5]
    V = Vn
    zX = -V[2] * D[3] - V[5] * D[4] - V[8] * D[5] + V[1] * D[6] + V[4] * D[7] + V[7] * D[8]
    zY = V[2] * D[0] + V[5] * D[1] + V[8] * D[2] - V[0] * D[6] - V[3] * D[7] - V[6] * D[8]
    zZ = -V[1] * D[0] - V[4] * D[1] - V[7] * D[2] + V[0] * D[3] + V[3] * D[4] + V[6] * D[5]
    wX, wY, wZ = 0.5 * (W[7] - W[5]), 0.5 * (W[2] - W[6]), 0.5 * (W[3] - W[1])
    tr = V[0] + V[4] + V[8]
    tmp = [tr - V[0], -V[1], -V[2], -V[3], tr - V[4], -V[5], -V[6], -V[7], tr - V[8]]
    ti, _ = _inv3(tmp)
    oX = wX + ti[0] * zX + ti[1] * zY + ti[2] * zZ
    oY = wY + ti[3] * zX + ti[4] * zY + ti[5] * zZ
    oZ = wZ + ti[6] * zX + ti[7] * zY + ti[8] * zZ
    Om = [0.0, -oZ, oY, oZ, 0.0, -oX, -oY, oX, 0.0]
    sq = oX * oX + oY * oY + oZ * oZ
    if sq > 1e-30:
        om = math.sqrt(sq)
        s1, s2 = math.sin(dt * om) / om, -(1.0 - math.cos(dt * om)) / sq
        Om2 = _mm(Om, Om)
        Q = [float(k in (0, 4, 8)) + s1 * Om[k] + s2 * Om2[k] for k in range(9)]
    else:
        Q = [float(k in (0, 4, 8)) for k in range(9)]
    R = _mm(Q, Rn)
    A, B = _mm(L, V), _mm(V, Om)
    Vnew = [V[k] + dt * (A[k] - B[k]) for k in range(9)]
    d = _mm(R, _mm(D, R), ta=True)
    # updateElasticCauchyStress
    inc = [d[k] * dt for k in range(9)]
    dil = inc[0] + inc[4] + inc[8]
    dev = list(inc)
    for k in (0, 4, 8):
        dev[k] -= dil / 3.0
    S = [Sn[k] + dev[k] * 2.0 * G for k in range(9)]
    for k in (0, 4, 8):
        S[k] += K * dil
    sigma = _mm(R, _mm(S, R, tb=True))  # rotateCauchyStress: R (S Rᵀ)
    return sigma, Vnew, R, S


def _peridigm_hourglass(x, u, vol, delta, nbrs, K, C):
    """``computeHourglassForce`` with its own F (shape tensor loop), per point and neighbour."""
    n = len(x)
    y = x + u
    f = np.zeros((n, 3))
    for i in range(n):
        shape = np.zeros((3, 3))
        first = np.zeros((3, 3))
        for j in nbrs[i]:
            xi, eta = x[j] - x[i], y[j] - y[i]
            shape += vol[j] * np.outer(xi, xi)
            first += vol[j] * np.outer(eta, xi)
        Fi = first @ np.linalg.inv(shape)
        const = 18.0 * C * K / math.pi / delta[i] ** 4
        for j in nbrs[i]:
            xi, eta = x[j] - x[i], y[j] - y[i]
            hvec = y[i] + Fi @ xi - y[j]
            dot = -float(hvec @ eta)
            mag = const * (dot / np.linalg.norm(xi)) * (1.0 / np.linalg.norm(eta))
            f[i] += mag * eta * vol[j] * vol[i]  # force density times the volume
            f[j] -= mag * eta * vol[i] * vol[j]
    return f


# -- the material ---------------------------------------------------------------------------
def _random_steps(rng, n, scale):
    F1 = np.eye(3) + scale * rng.standard_normal((n, 3, 3))
    F2 = F1 + scale * rng.standard_normal((n, 3, 3))
    return F1, F2


def test_hypoelastic_equals_peridigms_point_update_over_two_steps():
    rng = np.random.default_rng(0)
    K, G = 1.6e11, 7.7e10
    mat = Hypoelastic(K=K, G=G)
    # finite rotations and stretches (5 %), two steps: the update's history matters
    F1, F2 = _random_steps(rng, 4, 0.05)
    s0 = mat.initial_state(4)
    P1, s1, _ = mat.update(F1, s0)
    P2, s2, _ = mat.update(F2, s1)
    for g in range(4):
        eye = list(np.eye(3).ravel())
        sig1, V1, R1, S1 = _peridigm_point(list(F1[g].ravel()), eye, eye, eye, [0.0] * 9, K, G)
        sig2, V2, R2, S2 = _peridigm_point(
            list(F2[g].ravel()), list(F1[g].ravel()), V1, R1, S1, K, G
        )
        for ours, theirs in ((s2["V"], V2), (s2["R"], R2), (s2["S"], S2)):
            # round-off of two different evaluation orders (measured 3e-16 relative)
            assert np.abs(ours[g].ravel() - theirs).max() <= 1e-12 * max(1.0, np.abs(theirs).max())
        # P = J σ F⁻ᵀ (Peridigm's computeForce)
        P = np.linalg.det(F2[g]) * np.reshape(sig2, (3, 3)) @ np.linalg.inv(F2[g]).T
        assert np.abs(P2[g] - P).max() <= 1e-12 * np.abs(P).max()


def test_hypoelastic_tangent_is_the_derivative_of_p():
    rng = np.random.default_rng(1)
    mat = Hypoelastic(K=2.0, G=1.0)
    F1, F2 = _random_steps(rng, 5, 0.05)
    _, s1, _ = mat.update(F1, mat.initial_state(5))
    _, _, A = mat.update(F2, s1, tangent=True)
    h = 1e-6
    fd = np.zeros_like(A)
    for k in range(3):
        for m in range(3):
            dF = np.zeros((3, 3))
            dF[k, m] = h
            fd[..., k, m] = (mat.piola(F2 + dF, s1) - mat.piola(F2 - dF, s1)) / (2 * h)
    # central difference: truncation h² ~ 1e-12, round-off ε/h ~ 1e-10 (measured 7e-11)
    assert np.abs(A - fd).max() <= 1e-8 * np.abs(A).max()


def test_hypoelastic_small_strain_tangent_is_isotropic_c():
    mat = Hypoelastic(K=3.0, G=2.0)
    _, _, A = mat.update(np.eye(3)[None], mat.initial_state(1), tangent=True)
    mu = 2.0
    lam = 3.0 - 2.0 * mu / 3.0
    eye = np.eye(3)
    C = lam * np.einsum("ij,kl->ijkl", eye, eye) + 2.0 * mu * (
        0.5 * (np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye))
    )
    # at F = I, σ = 0: dP/dF = C acting on sym(dF) (closed form)
    assert np.abs(A[0] - C).max() <= 1e-14 * 3.0


def test_hypoelastic_rejects_bad_input():
    with pytest.raises(InputError, match="K must be a positive"):
        Hypoelastic(K=-1.0, G=1.0)
    with pytest.raises(InputError, match="G must be a positive number"):
        Hypoelastic(K=1.0, G="1")
    mat = Hypoelastic(K=1.0, G=1.0)
    with pytest.raises(pdlin.errors.ShapeError, match=r"F must have shape \(n, 3, 3\)"):
        mat.update(np.eye(2)[None], mat.initial_state(1))
    with pytest.raises(InputError, match=r"missing \['V', 'R'\]"):
        mat.update(np.eye(3)[None], {"F": np.eye(3)[None], "S": np.zeros((1, 3, 3))})
    with pytest.raises(pdlin.errors.ShapeError, match=r"state\['F'\] must have the shape of F"):
        mat.update(np.eye(3)[None], mat.initial_state(2))


# -- the model ----------------------------------------------------------------------------
def _block():
    cloud = pdlin.grid((6, 5, 4), spacing=0.5)
    return cloud, pdlin.find_bonds(cloud, 0.751)


def test_hourglass_force_is_peridigms_on_a_non_affine_field():
    cloud, bonds = _block()
    K, G, C = 1.6e11, 7.7e10, 0.04
    model = PeridigmCorrespondence(K=K, G=G, hourglass=C)
    rng = np.random.default_rng(2)
    u = 1e-3 * rng.standard_normal((cloud.n, 3))  # non-affine, finite (|u| ~ 0.2 % of h)
    nbrs = np.split(np.asarray(bonds.j), np.asarray(bonds.indptr)[1:-1])
    ref = _peridigm_hourglass(
        cloud.points, u, np.asarray(cloud.volumes), np.asarray(bonds.horizon), nbrs, K, C
    )
    f = model.hourglass_force(cloud, bonds, u)
    # two summation orders (measured 2e-15 relative)
    assert np.abs(f - ref).max() <= 1e-12 * np.abs(ref).max()
    # pdlin's penalty with the same constant (peridigm_hourglass_penalty) is another force
    # on non-affine fields (docs/decks.md, "Hourglass control"): measured 144 % apart
    pen = float(peridigm_hourglass_penalty(C, K, G))
    u_small = 1e-9 * rng.standard_normal((cloud.n, 3))
    f_pen = pdlin.Correspondence(K=K, G=G, control="penalty", penalty=pen).internal_force(
        cloud, bonds, u_small
    ) - pdlin.Correspondence(K=K, G=G).internal_force(cloud, bonds, u_small)
    f_pd = model.hourglass_force(cloud, bonds, u_small)
    assert np.linalg.norm(f_pd - f_pen) >= 0.5 * np.linalg.norm(f_pd)
    # both vanish on affine fields (z = 0 for every bond)
    u_aff = cloud.points @ np.array([[1e-3, 2e-4, 0.0], [0.0, -3e-4, 1e-4], [5e-4, 0.0, 2e-3]]).T
    assert np.abs(model.hourglass_force(cloud, bonds, u_aff)).max() <= 1e-9 * np.abs(f).max()


def test_tangent_is_the_derivative_of_the_force():
    cloud, bonds = _block()
    model = PeridigmCorrespondence(K=2.0, G=1.0, hourglass=0.2)
    rng = np.random.default_rng(4)
    state = model.initial_state(cloud, bonds)
    u1 = 1e-2 * rng.standard_normal((cloud.n, 3))
    state = model.respond(cloud, bonds, u1, state).state  # a committed step first
    u = u1 + 1e-2 * rng.standard_normal((cloud.n, 3))
    Kt = model.respond(cloud, bonds, u, state, tangent=True).tangent
    v = rng.standard_normal((cloud.n, 3))
    h = 1e-6
    fd = -(
        model.respond(cloud, bonds, u + h * v, state).force
        - model.respond(cloud, bonds, u - h * v, state).force
    ).ravel() / (2 * h)
    # central difference (measured 3e-11 relative)
    assert np.abs(Kt @ v.ravel() - fd).max() <= 1e-7 * np.abs(fd).max()
    # the hourglass part alone
    Kh = model.hourglass_tangent(cloud, bonds, u)
    fdh = -(
        model.hourglass_force(cloud, bonds, u + h * v)
        - model.hourglass_force(cloud, bonds, u - h * v)
    ).ravel() / (2 * h)
    assert np.abs(Kh @ v.ravel() - fdh).max() <= 1e-7 * np.abs(fdh).max()
    assert model.symmetric is False and abs(Kh - Kh.T).max() > 1e-3 * abs(Kh).max()


def test_linear_operators_are_the_tangent_at_zero():
    cloud, bonds = _block()
    K, G = 1.6e11, 7.7e10
    model = PeridigmCorrespondence(K=K, G=G, hourglass=0.04)
    zero = np.zeros((cloud.n, 3))
    Kt = model.respond(cloud, bonds, zero, model.initial_state(cloud, bonds), tangent=True).tangent
    Ks = model.stiffness(cloud, bonds)
    assert abs(Ks - Kt).max() <= 1e-12 * abs(Ks).max()
    x = np.random.default_rng(5).standard_normal(cloud.n * 3)
    assert np.allclose(model.apply(cloud, bonds, x), Ks @ x, rtol=1e-12, atol=0)
    # without hourglass: the small-strain correspondence K of the isotropic C
    plain = PeridigmCorrespondence(K=K, G=G).stiffness(cloud, bonds)
    ref = pdlin.Correspondence(K=K, G=G).stiffness(cloud, bonds)
    assert abs(plain - ref).max() <= 1e-12 * abs(ref).max()
    # linearized hourglass: c V_i V_j (e·z) e on i, z = u_j - u_i - ∇u_i ξ (docs/decks.md)
    u = 1e-6 * np.random.default_rng(6).standard_normal((cloud.n, 3))
    f_lin = -(model.hourglass_tangent(cloud, bonds) @ u.ravel()).reshape(-1, 3)
    f_nl = model.hourglass_force(cloud, bonds, u)
    assert np.abs(f_lin - f_nl).max() <= 1e-4 * np.abs(f_nl).max()


def test_model_rejects_bad_input():
    with pytest.raises(InputError, match="hourglass must be a finite number >= 0"):
        PeridigmCorrespondence(K=1.0, G=1.0, hourglass=-0.1)
    with pytest.raises(InputError, match="takes K, G, hourglass and max_bytes, got 'control'"):
        PeridigmCorrespondence(K=1.0, G=1.0, control="penalty")
    cloud = pdlin.grid((4, 4), spacing=1.0)
    with pytest.raises(ModelError, match="3D"):
        PeridigmCorrespondence(K=1.0, G=1.0, hourglass=0.1).hourglass_geometry(
            cloud, pdlin.find_bonds(cloud, 1.5)
        )
    with pytest.raises(SceneError, match="one K, G and Hourglass Coefficient"):
        peridigm_correspondence_model(np.array([1.0, 2.0]), 1.0, {0.04}, "Materials")


# -- Peridigm's deck and gold file ----------------------------------------------------------
_TENSORS = ("Cauchy_Stress", "Unrotated_Cauchy_Stress", "Left_Stretch_Tensor",
            "Rotation_Tensor", "Deformation_Gradient")  # fmt: skip


def _gold_fields(path, points):
    """Gold fields per step, at ``points`` (matched by position).

    Element variables are stored per element block in element order; each sphere element
    ``k`` is the node ``connect[k]`` (they are not in node order).
    """
    netCDF4 = pytest.importorskip("netCDF4")
    from scipy.spatial import cKDTree

    with netCDF4.Dataset(path) as ds:
        nod = list(netCDF4.chartostring(ds.variables["name_nod_var"][:]))
        ele = list(netCDF4.chartostring(ds.variables["name_elem_var"][:]))
        x = np.column_stack([np.asarray(ds.variables[f"coord{c}"][:]) for c in "xyz"])
        blocks = range(1, len(ds.variables["eb_prop1"][:]) + 1)
        node_of = np.concatenate(
            [np.asarray(ds.variables[f"connect{b}"][:]).ravel() for b in blocks]
        )
        node_of = node_of - 1

        def nodal(name):
            cols = [nod.index(name + c) + 1 for c in "XYZ"]
            return np.stack([np.asarray(ds.variables[f"vals_nod_var{k}"][:]) for k in cols], -1)

        def element(name):
            k = ele.index(name) + 1
            v = np.concatenate(
                [np.asarray(ds.variables[f"vals_elem_var{k}eb{b}"][:]) for b in blocks], 1
            )
            out = np.empty_like(v)
            out[:, node_of] = v
            return out

        out = {k: nodal(k) for k in ("Displacement", "Force", "Hourglass_Force_Density")}
        for k in _TENSORS:
            comps = [element(k + a + b) for a in "XYZ" for b in "XYZ"]
            out[k] = np.stack(comps, -1).reshape(-1, x.shape[0], 3, 3)
        for k in ("Volume", "Number_Of_Neighbors"):
            out[k] = element(k)
        out["time"] = np.asarray(ds.variables["time_whole"][:])
        out["x"] = x
    if points is None:
        return out
    dist, idx = cKDTree(x).query(points)
    assert dist.max() <= 1e-12  # Peridigm's points are the element centroids pdlin computes
    return {k: (v if k == "time" else v[:, idx] if k != "x" else v[idx]) for k, v in out.items()}


def test_elastic_correspondence_deck_matches_gold_at_comp_tolerance():
    pytest.importorskip("netCDF4")
    # the linear mapping (kinematics 'auto' would give PeridigmCorrespondence itself)
    scene = pdlin.read_deck(DECK / "ElasticCorrespondenceQSTension.xml", kinematics="linear")
    lin = scene.problem.model  # the linear mapping: E, nu of the deck
    E, nu = float(lin.E), float(lin.nu)
    K, G = E / (3 * (1 - 2 * nu)), E / (2 * (1 + nu))  # as the deck reader's _bulk_shear
    root = ET.parse(DECK / "ElasticCorrespondenceQSTension.xml").getroot()
    hg = float(root.find(".//Parameter[@name='Hourglass Coefficient']").get("value"))
    model = peridigm_correspondence_model(K, G, {hg}, "Materials")
    bonds = scene.problem.get_bonds()
    problem = dataclasses.replace(scene.problem, model=model, bonds=bonds)
    times = [t for t, _ in scene.steps][1:]  # Peridigm's load steps (t = 0 is the initial state)
    # the deck's values at Final Time = 1 scale with t (its expressions are linear in t)
    res = pdlin.solve_nonlinear(problem, times=times, t_end=1.0, method="newton", rtol=1e-12)
    gold = _gold_fields(DECK / "ElasticCorrespondenceQSTension_gold.e", scene.cloud.points)
    # the deck reader's bonds are Peridigm's neighbour lists
    assert np.array_equal(bonds.family_size, gold["Number_Of_Neighbors"][0])
    assert np.allclose(gold["time"][1:], times, rtol=0, atol=1e-14)  # .comp: TIME STEPS 1e-14
    vol = np.asarray(scene.cloud.volumes)[:, None]
    state = model.initial_state(scene.cloud, bonds)
    for k in range(len(times)):
        g = {key: v[k + 1] for key, v in gold.items() if key not in ("time", "x")}
        # tolerances of ElasticCorrespondenceQSTension.comp (absolute)
        assert np.abs(res.u[k] - g["Displacement"]).max() <= 1e-9  # measured 6e-15
        s = res.states[k]
        assert np.abs(s["F"] - g["Deformation_Gradient"]).max() <= 1e-12  # measured 6e-15
        assert np.abs(s["V"] - g["Left_Stretch_Tensor"]).max() <= 1e-12  # measured 4e-15
        assert np.abs(s["R"] - g["Rotation_Tensor"]).max() <= 1e-12  # measured 5e-15
        assert np.abs(s["S"] - g["Unrotated_Cauchy_Stress"]).max() <= 1e-2  # measured 7e-4
        assert np.abs(res.stress[k] - g["Cauchy_Stress"]).max() <= 1e-2  # measured 7e-4
        # Force = force density x volume at the converged state (reactions on the
        # prescribed points); the hourglass force density separately
        f = model.respond(scene.cloud, bonds, res.u[k], state).force
        assert np.abs(f - g["Force"]).max() <= 1e-3  # measured 3e-5
        hgd = model.hourglass_force(scene.cloud, bonds, res.u[k]) / vol
        assert np.abs(hgd - g["Hourglass_Force_Density"]).max() <= 1e-3  # measured 3e-4
        state = s


def test_fully_prescribed_deck_matches_gold_over_five_steps():
    """``ElasticCorrespondenceFullyPrescribedTension``: a Verlet deck, every point prescribed.

    Its deck prescribes ``u = (0, 0.001 y t / 1e-8, 0)`` on ``nodelist_1`` (every node), so
    Peridigm's force, stretch, rotation and stresses at its five steps (``Fixed dt`` 2e-9,
    velocity ``Δu/Δt`` on prescribed DOFs) are the model evaluated along that path: one
    committed step of :meth:`respond` per Verlet step.
    """
    folder = DATA / "ElasticCorrespondenceFullyPrescribedTension"
    gold = _gold_fields(folder / "ElasticCorrespondenceFullyPrescribedTension_gold.e", None)
    root = ET.parse(folder / "ElasticCorrespondenceFullyPrescribedTension.xml").getroot()

    def param(name):
        (value,) = [e.get("value") for e in root.iter("Parameter") if e.get("name") == name]
        return float(value)

    E, nu, hg = param("Young's Modulus"), param("Poisson's Ratio"), param("Hourglass Coefficient")
    x = gold["x"]
    cloud = pdlin.PointCloud(x, gold["Volume"][0])
    bonds = pdlin.find_bonds(cloud, param("Horizon"))
    assert np.array_equal(bonds.family_size, gold["Number_Of_Neighbors"][0])
    model = PeridigmCorrespondence(K=E / (3 * (1 - 2 * nu)), G=E / (2 * (1 + nu)), hourglass=hg)
    state = model.initial_state(cloud, bonds)
    times = gold["time"]
    assert np.allclose(np.diff(times), param("Fixed dt"), rtol=1e-12, atol=0)
    for k in range(1, times.size):
        u = np.zeros_like(x)
        u[:, 1] = 0.001 * x[:, 1] * times[k] / 1.0e-8  # the deck's Prescribed Displacement Y
        assert np.abs(u - gold["Displacement"][k]).max() <= 1e-9
        r = model.respond(cloud, bonds, u, state)
        state = r.state
        # tolerances of ElasticCorrespondenceFullyPrescribedTension.comp (absolute)
        assert np.abs(r.force - gold["Force"][k]).max() <= 1e-3  # measured 1.8e-6 (of 1.6e7)
        assert np.abs(r.stress - gold["Cauchy_Stress"][k]).max() <= 1e-2  # measured 2.2e-5
        assert np.abs(state["S"] - gold["Unrotated_Cauchy_Stress"][k]).max() <= 1e-2
        for key, name in (("V", "Left_Stretch_Tensor"), ("R", "Rotation_Tensor"),
                          ("F", "Deformation_Gradient")):  # fmt: skip
            assert np.abs(state[key] - gold[name][k]).max() <= 1e-12  # measured <= 1.6e-15
        hgd = model.hourglass_force(cloud, bonds, u) / gold["Volume"][0][:, None]
        assert np.abs(hgd - gold["Hourglass_Force_Density"][k]).max() <= 1e-9


def test_newton_converges_at_finite_rotation_and_stretch():
    """Consistent tangent: Newton's iterations stay few at large rotation and stretch."""
    cloud = pdlin.grid((5, 8, 4), spacing=0.5)
    bonds = pdlin.find_bonds(cloud, 0.751)
    x = cloud.points
    top = np.flatnonzero(x[:, 1] > x[:, 1].max() - 1e-9)
    center = np.array([x[:, 0].mean(), 0.0, x[:, 2].mean()])

    def path(points, t):  # the top face rotated by 0.2 t rad about z and stretched 5 % t
        c, s = np.cos(0.2 * t), np.sin(0.2 * t)
        X = points - center
        return (X * [1.0, 1.0 + 0.05 * t, 1.0]) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T - X

    model = PeridigmCorrespondence(K=2.0, G=1.0, hourglass=0.05)
    problem = pdlin.StaticProblem(
        model,
        cloud,
        bonds,
        dirichlet=[
            pdlin.Dirichlet("y-", 0.0),
            pdlin.Dirichlet(top, pdlin.operators.TimePath(path)),
        ],
    )
    res = pdlin.solve_nonlinear(problem, steps=4, method="newton", rtol=1e-10)
    # measured [3, 2, 2, 2] iterations, no cut-back; max |u| 0.80 (20 % of the block)
    assert res.iterations.max() <= 4 and res.cutbacks.sum() == 0
    assert np.abs(res.u[-1]).max() > 0.5
