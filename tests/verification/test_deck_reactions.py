"""Issue 14 "done when": Peridigm QuasiStatic decks run in pdlin and match pdlin scenes.

A Peridigm LPS (``Elastic``) deck in YAML and an ``Elastic Correspondence`` deck in
XML, both on a text discretization, give the same reaction as the equivalent
hand-written TOML scene (``pdlin.scene.scene_from_dict``, a grid with the same
points) to 1e-10; the LPS deck's operator equals an independent loop implementation of
Peridigm's linear peridynamic solid force state; and the bar's reaction is compared
with E A strain.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree
from test_external_references import _peridigm_lps_force

import pdlin
from pdlin.constraints import resolve_dirichlet
from pdlin.scene.scene import scene_from_dict

yaml = pytest.importorskip("yaml")

H = 0.1
SHAPE = (12, 3, 3)
DELTA = 0.2015  # 2.015 h
K_BULK, G_SHEAR = 130.0, 70.0
STRAIN = 1e-3


def _points(shape: tuple[int, int, int] = SHAPE) -> np.ndarray:
    ax = [(np.arange(k) + 0.5) * H for k in shape]
    return np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3)


def _deck(
    tmp: Path, material: dict, *, affine: bool = False, shape: tuple[int, int, int] = SHAPE
) -> dict:
    """Write the bar's text discretization and node sets; return the deck dict.

    Ends: two layers each (x < 2h, x > 10h).  ``affine``: both ends follow u_x = ε x
    (the exact uniaxial-stress field of a homogeneous bar); else left fixed, right
    pulled by ε L with the lateral motion of every point fixed (uniaxial strain).
    """
    pts = _points(shape)
    nx, ny, nz = shape
    rows = [f"{float(p[0])!r} {float(p[1])!r} {float(p[2])!r} 1 {H**3!r}" for p in pts]
    (tmp / "bar.txt").write_text("# x y z block_id volume\n" + "\n".join(rows) + "\n")
    left = np.flatnonzero(pts[:, 0] < 2 * H) + 1
    right = np.flatnonzero(pts[:, 0] > (nx - 2) * H) + 1
    (tmp / "left.txt").write_text("\n".join(map(str, left)))
    (tmp / "right.txt").write_text("\n".join(map(str, right)))
    pd = "Prescribed Displacement"
    if affine:
        bcs = {
            "Node Set One": "left.txt",
            "Node Set Two": "right.txt",
            "Left": {
                "Type": pd,
                "Node Set": "Node Set One",
                "Coordinate": "x",
                "Value": f"{STRAIN}*x*t",
            },
            "Right": {
                "Type": pd,
                "Node Set": "Node Set Two",
                "Coordinate": "x",
                "Value": f"{STRAIN}*x*t",
            },
            # one point pinned laterally at each end corner, rigid modes only
            "Node Set Pin": "1",
            "Pin Y": {"Type": pd, "Node Set": "Node Set Pin", "Coordinate": "y", "Value": "0.0"},
            "Pin Z": {"Type": pd, "Node Set": "Node Set Pin", "Coordinate": "z", "Value": "0.0"},
            "Node Set Twist": str(nz + 1),  # point (0, 1, 0): no twist about x
            "Twist Z": {
                "Type": pd,
                "Node Set": "Node Set Twist",
                "Coordinate": "z",
                "Value": "0.0",
            },
            "Node Set Tip": str(len(pts) - ny * nz + 1),  # point (nx - 1, 0, 0)
            "Tip Y": {"Type": pd, "Node Set": "Node Set Tip", "Coordinate": "y", "Value": "0.0"},
            "Tip Z": {"Type": pd, "Node Set": "Node Set Tip", "Coordinate": "z", "Value": "0.0"},
        }
    else:
        bcs = {
            "Node Set One": "left.txt",
            "Node Set Two": "right.txt",
            "Fix X": {"Type": pd, "Node Set": "Node Set One", "Coordinate": "x", "Value": "0.0"},
            "Pull X": {
                "Type": pd,
                "Node Set": "Node Set Two",
                "Coordinate": "x",
                "Value": "0.0012*t",
            },
            "Fix Y": {"Type": pd, "Node Set": "Full Domain", "Coordinate": "y", "Value": "0.0"},
            "Fix Z": {"Type": pd, "Node Set": "Full Domain", "Coordinate": "z", "Value": "0.0"},
        }
    return {
        "Peridigm": {
            "Discretization": {"Type": "Text File", "Input Mesh File": "bar.txt"},
            "Materials": {"M": material},
            "Blocks": {"B": {"Block Names": "block_1", "Material": "M", "Horizon": DELTA}},
            "Boundary Conditions": bcs,
            "Solver": {
                "Verbose": False,
                "Initial Time": 0.0,
                "Final Time": 1.0,
                "QuasiStatic": {
                    "Number of Load Steps": 10,
                    "Absolute Tolerance": 1.0e-6,
                    "Maximum Solver Iterations": 10,
                },
            },
        }
    }


def _toml_scene(model: dict) -> pdlin.scene.Scene:
    """The equivalent hand-written scene: grid, K/G, boxes for the node sets."""
    eps = 1e-9
    return scene_from_dict(
        {
            "geometry": {"type": "grid", "shape": list(SHAPE), "spacing": H},
            "material": {"K": K_BULK, "G": G_SHEAR},
            "model": model,
            "horizon": {"value": DELTA},
            "dirichlet": [
                {"box": [[-1, -1, -1], [2 * H - eps, 1, 1]], "components": "x", "value": 0.0},
                {"box": [[10 * H + eps, -1, -1], [2, 1, 1]], "components": "x", "value": 0.0012},
                {"set": "all", "components": [1, 2], "value": 0.0},
            ],
            "solver": {"name": "direct"},
        }
    )


def _reaction_left(problem: pdlin.StaticProblem) -> float:
    res = pdlin.solve(problem, solver="direct")
    left = np.flatnonzero(problem.cloud.points[:, 0] < 2 * H)
    return float(res.reaction(left)[0])


LPS_MATERIAL = {
    "Material Model": "Elastic",
    "Density": 8.0,
    "Bulk Modulus": K_BULK,
    "Shear Modulus": G_SHEAR,
}


def test_peridigm_lps_yaml_deck_matches_the_toml_scene(tmp_path):
    path = tmp_path / "lps.yaml"
    path.write_text(yaml.safe_dump(_deck(tmp_path, LPS_MATERIAL)))
    r_deck = _reaction_left(pdlin.read_deck(path).problem)
    r_toml = _reaction_left(_toml_scene({"type": "lps", "peridigm": True}).problem)
    assert r_deck < 0
    assert r_deck == pytest.approx(r_toml, rel=1e-10)


def test_peridigm_correspondence_xml_deck_matches_the_toml_scene(tmp_path):
    mat = {
        "Material Model": "Elastic Correspondence",
        "Density": 8.0,
        "Bulk Modulus": K_BULK,
        "Shear Modulus": G_SHEAR,
        "Hourglass Coefficient": 0.02,
    }
    deck = _deck(tmp_path, mat)["Peridigm"]
    (tmp_path / "corr.xml").write_text(_xml(deck))
    # the linear mapping (kinematics 'auto' runs PeridigmCorrespondence on this 2-step deck)
    scene = pdlin.read_deck(tmp_path / "corr.xml", kinematics="linear")
    r_deck = _reaction_left(scene.problem)
    # the mapping of docs/decks.md: penalty = 1.8 C_hg K / (K + 4G/3)
    penalty = 1.8 * 0.02 * K_BULK / (K_BULK + 4 * G_SHEAR / 3)
    r_toml = _reaction_left(
        _toml_scene({"type": "correspondence", "control": "penalty", "penalty": penalty}).problem
    )
    assert r_deck < 0
    assert r_deck == pytest.approx(r_toml, rel=1e-10)


def _xml(table: dict, name: str | None = None, ind: str = "") -> str:
    head = "<ParameterList>" if name is None else f'<ParameterList name="{name}">'
    out = [ind + head]
    for k, v in table.items():
        if isinstance(v, dict):
            out.append(_xml(v, k, ind + "  "))
        else:
            typ = {bool: "bool", int: "int", float: "double", str: "string"}[type(v)]
            val = str(v).lower() if isinstance(v, bool) else str(v)
            out.append(f'{ind}  <Parameter name="{k}" type="{typ}" value="{val}"/>')
    return "\n".join([*out, ind + "</ParameterList>"])


def test_lps_deck_operator_is_peridigms_force_state(tmp_path):
    path = tmp_path / "lps.yaml"
    path.write_text(yaml.safe_dump(_deck(tmp_path, LPS_MATERIAL)))
    scene = pdlin.read_deck(path)
    bonds = scene.bonds()
    u = np.random.default_rng(3).normal(size=(scene.cloud.n, 3)) * 1e-3
    got = scene.model.internal_force(scene.cloud, bonds, u)
    # independent loop implementation of Peridigm's elastic.cxx (linearized), horizon DELTA
    ref = _peridigm_lps_force(
        scene.cloud.points, np.asarray(scene.cloud.volumes), DELTA, K_BULK, G_SHEAR, u
    )
    # Peridigm's Force = Force_Density * Volume (pdlin's internal_force is the nodal force)
    ref = ref * np.asarray(scene.cloud.volumes)[:, None]
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


@pytest.mark.parametrize("kind", ["lps", "correspondence"])
def test_bar_reaction_against_e_a_strain(tmp_path, kind):
    """Uniaxial stress on a 12 x 6 x 6 bar: both end layers follow u_x = ε x, sides free."""
    shape = (12, 6, 6)
    mat = dict(LPS_MATERIAL)
    if kind == "correspondence":
        mat.update({"Material Model": "Elastic Correspondence", "Hourglass Coefficient": 0.02})
    path = tmp_path / "bar.yaml"
    path.write_text(yaml.safe_dump(_deck(tmp_path, mat, affine=True, shape=shape)))
    scene = pdlin.read_deck(path)
    res = pdlin.solve(scene.problem, solver="direct")
    right = np.flatnonzero(scene.cloud.points[:, 0] > (shape[0] - 2) * H)
    reaction = float(res.reaction(right)[0])
    E = 9 * K_BULK * G_SHEAR / (3 * K_BULK + G_SHEAR)  # 178.04
    area = (shape[1] * H) * (shape[2] * H)
    rel = reaction / (E * area * STRAIN) - 1.0
    # Neither model has a surface correction here: free lateral surfaces make the bar
    # stiffer.  Measured (this deck): LPS with Peridigm's discrete m +47.1 % (3 x 3
    # section: +87 %; docs/state_based.md reports +64 % on a 20 x 4 x 4 bar with the
    # analytic m), correspondence with the mapped hourglass penalty +6.2 %.
    band = {"lps": (0.40, 0.55), "correspondence": (0.03, 0.10)}[kind]
    assert band[0] < rel < band[1], rel


def test_affine_field_is_reproduced_inside(tmp_path):
    """Patch test through a deck: u = A x prescribed on a 2δ-thick shell of a cube.

    The free points and their neighbours have complete families, so the LPS solution
    is the affine field itself (closed form).
    """
    n = 10
    pts = _points((n, n, n))
    rows = [f"{float(p[0])!r} {float(p[1])!r} {float(p[2])!r} 1 {H**3!r}" for p in pts]
    (tmp_path / "cube.txt").write_text("\n".join(rows) + "\n")
    lo, hi = 4 * H, (n - 4) * H  # shell: every point within 4h >= 2 delta of the faces
    shell = np.flatnonzero(np.any((pts < lo) | (pts > hi), axis=1)) + 1
    A = np.array([[1.0, 0.3, -0.2], [0.1, -0.5, 0.4], [0.25, 0.0, 0.7]]) * 1e-3
    bcs: dict = {"Node Set Shell": " ".join(map(str, shell))}
    for k, c in enumerate("xyz"):
        expr = " + ".join(f"{float(A[k, m])!r}*{v}" for m, v in enumerate("xyz"))
        bcs[f"Shell {c}"] = {
            "Type": "Prescribed Displacement",
            "Node Set": "Node Set Shell",
            "Coordinate": c,
            "Value": f"({expr})*t",
        }
    deck = {
        "Peridigm": {
            "Discretization": {"Type": "Text File", "Input Mesh File": "cube.txt"},
            "Materials": {"M": LPS_MATERIAL},
            "Blocks": {"B": {"Block Names": "block_1", "Material": "M", "Horizon": DELTA}},
            "Boundary Conditions": bcs,
            "Solver": {"Final Time": 1.0, "NOXQuasiStatic": {"Number of Load Steps": 1}},
        }
    }
    (tmp_path / "cube.yaml").write_text(yaml.safe_dump(deck))
    scene = pdlin.read_deck(tmp_path / "cube.yaml")
    res = pdlin.solve(scene.problem, solver="direct")
    free = np.setdiff1d(np.arange(len(pts)), shell - 1)
    assert free.size == 8  # the 2 x 2 x 2 core
    exact = pts @ A.T
    np.testing.assert_allclose(res.u[free], exact[free], rtol=0, atol=1e-12 * np.abs(exact).max())


def _peridigm_correspondence_stiffness(points, vol, delta, K, G, c_hg):
    """Dense K (f = -K u) of Peridigm's Elastic Correspondence, linearized, with hourglass.

    Written from ``correspondence.cxx``: shape tensor ``K_i = Σ ξ⊗ξ V_j`` (ω = 1),
    ``∇u_i = (Σ (u_j - u_i)⊗ξ V_j) K_i⁻¹``, force state ``T = σ_i K_i⁻¹ ξ`` with
    ``f_i += T V_j``, ``f_j -= T V_i``; hourglass ``c (e·z) e`` on the same pair with
    ``z = u_j - u_i - ∇u_i ξ`` and ``c = 18 C_hg K / (π δ⁴)`` (``computeHourglassForce``
    at u = 0: deformed bond = ξ).  Returns force densities (Peridigm's Force_Density).
    """
    n = len(points)
    pairs = np.array(sorted(cKDTree(points).query_pairs(delta * (1 + 1e-9))))
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    xi = points[j] - points[i]
    e = xi / np.linalg.norm(xi, axis=1)[:, None]
    shape = np.zeros((n, 3, 3))
    np.add.at(shape, i, np.einsum("bp,bq->bpq", xi, xi) * vol[j, None, None])
    kinv = np.linalg.inv(shape)
    lam = K - 2.0 * G / 3.0

    def force_density(u):
        du = u[j] - u[i]
        a = np.zeros((n, 3, 3))
        np.add.at(a, i, np.einsum("bp,bq->bpq", du, xi) * vol[j, None, None])
        grad = a @ kinv
        eps = 0.5 * (grad + grad.transpose(0, 2, 1))
        sig = lam * np.trace(eps, axis1=1, axis2=2)[:, None, None] * np.eye(3) + 2 * G * eps
        t = np.einsum("bpq,bq->bp", (sig @ kinv)[i], xi)
        z = du - np.einsum("bpq,bq->bp", grad[i], xi)
        t = t + c_hg * np.einsum("bp,bp->b", e, z)[:, None] * e
        f = np.zeros((n, 3))
        np.add.at(f, i, t * vol[j, None])
        np.add.at(f, j, -t * vol[i, None])
        return f

    eye = np.eye(3 * n)
    return np.column_stack([-force_density(eye[k].reshape(n, 3)).ravel() for k in range(3 * n)])


@pytest.mark.parametrize("affine", [False, True], ids=["uniaxial-strain", "uniaxial-stress"])
@pytest.mark.parametrize("hourglass", [0.0, 0.02])
def test_correspondence_deck_against_peridigms_hourglass_force(tmp_path, affine, hourglass):
    """The mapped penalty control vs Peridigm's own (linearized) correspondence + hourglass."""
    mat = {
        "Material Model": "Elastic Correspondence",
        "Density": 1.0,
        "Bulk Modulus": K_BULK,
        "Shear Modulus": G_SHEAR,
        "Hourglass Coefficient": hourglass,
    }
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(_deck(tmp_path, mat, affine=affine)))
    scene = pdlin.read_deck(tmp_path / "c.yaml")
    res = pdlin.solve(scene.problem, solver="direct")
    pts, vol = scene.cloud.points, np.asarray(scene.cloud.volumes)
    c_hg = 18.0 * hourglass * K_BULK / (np.pi * DELTA**4)
    kd = _peridigm_correspondence_stiffness(pts, vol, DELTA, K_BULK, G_SHEAR, c_hg)
    kd = kd * np.repeat(vol, 3)[:, None]  # Force = Force_Density * Volume
    dofs, vals = resolve_dirichlet(scene.cloud, scene.problem.dirichlet)
    free = np.setdiff1d(np.arange(kd.shape[0]), dofs)
    u = np.zeros(kd.shape[0])
    u[dofs] = vals
    u[free] = np.linalg.solve(kd[np.ix_(free, free)], -kd[np.ix_(free, dofs)] @ vals)
    right = np.flatnonzero(pts[:, 0] > 10 * H)
    r_peridigm = (kd @ u).reshape(-1, 3)[right, 0].sum()
    r_pdlin = float(res.reaction(right)[0])
    if hourglass == 0.0:
        # no control: pdlin's correspondence operator is Peridigm's
        np.testing.assert_allclose(res.u.ravel(), u, rtol=0, atol=1e-10 * np.abs(u).max())
        assert r_pdlin == pytest.approx(r_peridigm, rel=1e-10)
    else:
        # the mapped penalty is not Peridigm's hourglass force (docs/decks.md); measured
        # here: reaction +0.18 % (uniaxial strain) / -0.04 % (uniaxial stress)
        assert r_pdlin == pytest.approx(r_peridigm, rel=5e-3)
