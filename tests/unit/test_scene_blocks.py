"""Per-block materials: ``[[block]]`` / ``[materials.<name>]`` scene tables, decks' Blocks."""

from __future__ import annotations

import re

import numpy as np
import pytest

import pdlin
from pdlin.errors import SceneError
from pdlin.scene import scene_from_dict
from pdlin.scene.materials import Block, blocks_per_point

N = 200  # points of the 1D bar of length 1
H = 1.0 / N
#: sqrt(12): neighbours j = 1..3 on each side, so the lattice sum 2 h^2 (1 + 2 + 3) = 12 h^2
#: equals the continuum integral delta^2 of the 1D bond-based calibration; interior strains
#: of a linear field are then exact (with 3.015 the bar is 1 / 0.7575 too stiff)
RATIO = 12**0.5
E1, E2, F = 2.0, 1.0, 1e-3


def bar_data(**over):
    data = {
        "geometry": {"type": "grid", "shape": [N], "spacing": H},
        "materials": {"stiff": {"E": E1}, "soft": {"E": E2}},
        "block": [
            {"box": [[0.0], [0.5]], "material": "stiff"},
            {"box": [[0.5], [1.0]], "material": "soft"},
        ],
        "model": {"type": "bond_based", "surface_correction": "energy"},
        "horizon": {"ratio": RATIO},
        "dirichlet": [{"set": "x-"}],
        "load": [{"type": "total", "set": "x+", "force": [F]}],
    }
    data.update(over)
    return data


def test_two_material_bar_equals_python_and_series_springs():
    sc = scene_from_dict(bar_data())
    x = sc.cloud.points[:, 0]
    assert [b.name for b in sc.blocks] == ["block[0]", "block[1]"]
    res = pdlin.solve(sc.problem, solver="direct")
    # the same bar built in Python: bitwise the same displacements
    model = pdlin.BondBased(E=np.where(x < 0.5, E1, E2), surface_correction="energy")
    prob = pdlin.StaticProblem(
        model,
        pdlin.grid(N, H),
        ratio=RATIO,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", [F])],
    )
    ref = pdlin.solve(prob, solver="direct")
    assert np.array_equal(res.u, ref.u)

    def strain(a, b):
        ia, ib = np.argmin(abs(x - a)), np.argmin(abs(x - b))
        return (res.u[ib, 0] - res.u[ia, 0]) / (x[ib] - x[ia])

    # series springs (closed form): the force F crosses both halves, strain F / (E A), A = 1;
    # measured 1e-11 in the interiors
    assert strain(0.1, 0.4) == pytest.approx(F / E1, rel=1e-8)
    assert strain(0.6, 0.9) == pytest.approx(F / E2, rel=1e-8)
    # elongation between the end points F (L1 / E1 + L2 / E2): the PD ends and interface
    # differ at first order in h (measured -7.1e-3, -3.5e-3, -1.8e-3 for N = 100, 200, 400)
    series = F * ((0.5 - x[0]) / E1 + (x[-1] - 0.5) / E2)
    assert res.u[-1, 0] - res.u[0, 0] == pytest.approx(series, rel=5e-3)


def test_blocks_from_toml_text_and_inline_materials(tmp_path):
    text = f"""
[geometry]
type = "grid"
shape = [{N}]
spacing = {H!r}
[model]
surface_correction = "energy"
[[block]]
box = [[0.0], [0.5]]
material = {{ E = {E1!r} }}
[[block]]
box = [[0.5], [1.0]]
material = "soft"
[materials.soft]
E = {E2!r}
[horizon]
ratio = {RATIO!r}
[[dirichlet]]
set = "x-"
[[load]]
set = "x+"
force = [{F!r}]
"""
    (tmp_path / "bar.toml").write_text(text)
    a = pdlin.scene.load_scene(tmp_path / "bar.toml")
    b = scene_from_dict(bar_data())
    assert np.array_equal(np.asarray(a.model.E), np.asarray(b.model.E))
    assert np.array_equal(
        pdlin.solve(a.problem, solver="direct").u, pdlin.solve(b.problem, solver="direct").u
    )


#: aluminium E = 70 GPa, nu = 0.3 given as bulk and shear moduli (LPS takes one nu for all points)
KA, GA = 70e9 / 1.2, 70e9 / 2.6


def test_blocks_on_mesh_physical_groups(tmp_path):
    meshio = pytest.importorskip("meshio")
    nx, ny, h = 20, 5, 0.05
    xs, ys = np.meshgrid(np.arange(nx + 1) * h, np.arange(ny + 1) * h, indexing="ij")
    pts = np.c_[xs.ravel(), ys.ravel(), np.zeros(xs.size)]
    nid = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    quads = np.stack([nid[i, j], nid[i + 1, j], nid[i + 1, j + 1], nid[i, j + 1]], axis=-1).reshape(
        -1, 4
    )
    tag = np.where(i.ravel() < nx // 2, 1, 2)
    mesh = meshio.Mesh(
        pts,
        [("quad", quads)],
        cell_data={"gmsh:physical": [tag], "gmsh:geometrical": [tag]},
        field_data={"steel": np.array([1, 2]), "aluminium": np.array([2, 2])},
    )
    meshio.write(tmp_path / "plate.msh", mesh, file_format="gmsh22", binary=False)
    data = {
        "geometry": {"type": "mesh", "path": "plate.msh"},
        "materials": {"steel": {"E": 210e9, "nu": 0.3}, "alu": {"K": KA, "G": GA}},
        "block": [{"set": "steel", "material": "steel"}, {"set": "aluminium", "material": "alu"}],
        "model": {"type": "lps"},
        "horizon": {"value": 3.015 * h},
        "dirichlet": [
            {"box": [[0, 0], [h, 1]], "components": "x"},
            {"points": [0], "components": "y"},
        ],
        "load": [{"type": "total", "box": [[1 - h, 0], [1, 1]], "force": [1e6, 0.0]}],
    }
    sc = scene_from_dict(data, tmp_path)
    assert [b.name for b in sc.blocks] == ["steel", "aluminium"]
    left = sc.cloud.points[:, 0] < 0.5
    # block 'alu' gives K, G, so both blocks are converted to K, G: steel
    # K = E / (3 (1 - 2 nu)) = E / 1.2, G = E / (2 (1 + nu)) = E / 2.6 (isotropic elasticity)
    E_alu = 70e9
    k_mod, g_mod = sc.model.moduli(3)
    np.testing.assert_allclose(k_mod, np.where(left, 210e9 / 1.2, KA), rtol=1e-14)
    np.testing.assert_allclose(g_mod, np.where(left, 210e9 / 2.6, GA), rtol=1e-14)
    res = pdlin.solve(sc.problem)
    x = sc.cloud.points[:, 0]
    mid = np.abs(sc.cloud.points[:, 1] - 0.125) < 0.03

    def slope(a, b):
        ia = np.flatnonzero(mid & (np.abs(x - a) < h / 2))
        ib = np.flatnonzero(mid & (np.abs(x - b) < h / 2))
        return (res.u[ib, 0].mean() - res.u[ia, 0].mean()) / (x[ib].mean() - x[ia].mean())

    # series: the same force through both halves, so the strains are in the ratio of the
    # moduli (E_steel / E_alu, closed form of uniaxial stress; lateral constraint at the
    # interface and the LPS surface effect of a 5-point-wide strip: measured -0.6 %)
    assert slope(0.625, 0.875) / slope(0.125, 0.375) == pytest.approx(210e9 / E_alu, rel=0.02)


@pytest.mark.parametrize(
    "edit, pattern",
    [
        (
            lambda d: d["block"][1].update(materail="soft"),
            "unknown scene key 'block[1].materail'; did you mean 'material'?",
        ),
        (
            lambda d: d["block"][0].update(box=None, set="nope") or d["block"][0].pop("box"),
            "block[0].set: ",
        ),
        (
            lambda d: d["block"][0].update(box=[[0.0], [0.6]]),
            "block[1] overlaps block[0] at 20 point(s) (first: point 100)",
        ),
        (
            lambda d: d["block"].pop() and d["materials"].pop("soft"),
            "100 of 200 points are in no block (first: point 100)",
        ),
        (
            lambda d: d["materials"]["soft"].update(model="lps"),
            "materials.soft.model = 'lps' differs from model.type = 'bond_based'",
        ),
        (lambda d: d.update(material={"E": 1.0}), "material and block exclude each other"),
        (
            lambda d: d["block"][1].update(material="rubber"),
            "block[1].material: 'rubber' is not a [materials.<name>] table",
        ),
        (
            lambda d: d["materials"].update(extra={"E": 3.0}),
            "materials.extra is not used by any [[block]]",
        ),
        (lambda d: d["materials"]["soft"].update(E=float("nan")), "materials.soft.E"),
        (lambda d: d["materials"]["soft"].update(Ee=1.0), "unknown scene key 'materials.soft.Ee'"),
        (lambda d: d.update(block=[]), "block must be a non-empty array of tables"),
        (lambda d: d.pop("block"), "materials: [materials.<name>] tables need [[block]]"),
    ],
)
def test_block_errors_name_the_key(edit, pattern):
    data = bar_data()
    edit(data)
    with pytest.raises(SceneError, match=re.escape(pattern)):
        scene_from_dict(data)


def test_blocks_with_different_model_types_are_refused():
    data = bar_data()
    data["model"] = {}
    data["materials"]["stiff"]["model"] = "lps"
    data["materials"]["stiff"]["nu"] = 0.25
    with pytest.raises(SceneError, match=r"block\[1\] uses model 'bond_based' but block\[0\]"):
        scene_from_dict(data)


def test_blocks_per_point_direct():
    pts = np.arange(4)
    a = Block("a", pts[:2], {"K": 2.0}, "bond_based", "k0", horizon=0.3)
    b = Block("b", pts[2:], {"K": 2.0}, "bond_based", "k1", horizon=0.4)
    kind, consts, horizon = blocks_per_point([a, b], 4)
    # equal constants stay one number; horizons per point
    assert (kind, consts) == ("bond_based", {"K": 2.0})
    assert horizon.tolist() == [0.3, 0.3, 0.4, 0.4]
    c = Block("c", pts[2:], {"E": 1.0}, "bond_based", "k2")
    with pytest.raises(SceneError, match="k0: blocks give different constants"):
        blocks_per_point([a, c], 4)
    with pytest.raises(SceneError, match="k1 sets no horizon while other blocks do"):
        blocks_per_point([a, Block("b", pts[2:], {"K": 2.0}, "bond_based", "k1")], 4)
    with pytest.raises(SceneError, match="k1 .'b'. holds no points"):
        blocks_per_point([a, Block("b", pts[:0], {"K": 2.0}, "bond_based", "k1")], 4)
    assert "Block('a', 2 points, bond_based, K=2.0, horizon=0.3)" == repr(a)


# ---------------------------------------------------------------- decks make the same blocks
DATA = __import__("pathlib").Path(__file__).parents[1] / "data" / "peridigm"


def test_peridigm_two_material_deck_gives_blocks():
    pytest.importorskip("netCDF4")
    sc = pdlin.read_deck(DATA / "Bar_TwoBlocks_TwoMaterial_QS" / "Bar.xml")
    # Bar.xml: MyGroup1 / MyGroup2, Elastic, K = 1.515e5, G = 7.813e4, Horizon 0.5025
    # (the reader passes K, G through E, nu: equal to round-off)
    assert [(b.name, b.key, b.model, b.horizon) for b in sc.blocks] == [
        ("block_1", "Blocks.MyGroup1", "lps", 0.5025),
        ("block_2", "Blocks.MyGroup2", "lps", 0.5025),
    ]
    for b in sc.blocks:
        assert dict(b.material) == pytest.approx({"K": 1.515e5, "G": 7.813e4}, rel=1e-15)
    assert sum(b.points.size for b in sc.blocks) == sc.cloud.n


def test_peridigm_deck_and_toml_blocks_agree(tmp_path):
    yaml = pytest.importorskip("yaml")
    h, shape = 0.1, (12, 3, 3)
    cloud = pdlin.grid(shape, h)
    pts = cloud.points
    block = np.where(pts[:, 0] < 0.6, 1, 2)
    rows = [
        f"{float(p[0])!r} {float(p[1])!r} {float(p[2])!r} {b} {float(v)!r}"
        for p, b, v in zip(pts, block, cloud.volumes, strict=True)
    ]
    (tmp_path / "bar.txt").write_text("\n".join(rows) + "\n")
    left = " ".join(map(str, np.flatnonzero(pts[:, 0] < 0.2) + 1))
    right = " ".join(map(str, np.flatnonzero(pts[:, 0] > 1.0) + 1))
    deck = {
        "Peridigm": {
            "Discretization": {"Type": "Text File", "Input Mesh File": "bar.txt"},
            "Materials": {
                "Hard": {"Material Model": "Elastic", "Bulk Modulus": 130.0, "Shear Modulus": 70.0},
                "Soft": {"Material Model": "Elastic", "Bulk Modulus": 13.0, "Shear Modulus": 7.0},
            },
            "Blocks": {
                "A": {"Block Names": "block_1", "Material": "Hard", "Horizon": 0.2015},
                "B": {"Block Names": "block_2", "Material": "Soft", "Horizon": 0.2015},
            },
            "Boundary Conditions": {
                "Node Set One": left,
                "Node Set Two": right,
                "Fix": {
                    "Type": "Prescribed Displacement",
                    "Node Set": "Node Set One",
                    "Coordinate": "x",
                    "Value": "0.0",
                },
                "Pull": {
                    "Type": "Prescribed Displacement",
                    "Node Set": "Node Set Two",
                    "Coordinate": "x",
                    "Value": "0.0012*t",
                },
                **{
                    f"Lateral {c}": {
                        "Type": "Prescribed Displacement",
                        "Node Set": "Full Domain",
                        "Coordinate": c,
                        "Value": "0.0",
                    }
                    for c in "yz"
                },
            },
            "Solver": {"Final Time": 1.0, "QuasiStatic": {}},
        }
    }
    (tmp_path / "bar.yaml").write_text(yaml.safe_dump(deck))
    from_deck = pdlin.read_deck(tmp_path / "bar.yaml")
    toml = scene_from_dict(
        {
            "geometry": {"type": "grid", "shape": list(shape), "spacing": h},
            "materials": {"hard": {"K": 130.0, "G": 70.0}, "soft": {"K": 13.0, "G": 7.0}},
            "block": [
                {"box": [[0, 0, 0], [0.6, 1, 1]], "material": "hard", "horizon": 0.2015},
                {"box": [[0.6, 0, 0], [1.2, 1, 1]], "material": "soft", "horizon": 0.2015},
            ],
            "model": {"type": "lps", "peridigm": True},
            "horizon": {},
            "dirichlet": [
                {"box": [[0, 0, 0], [0.2, 1, 1]], "components": "x"},
                {"box": [[1.0, 0, 0], [1.2, 1, 1]], "components": "x", "value": 0.0012},
                {"set": "all", "components": "yz"},
            ],
        }
    )
    # the same structure: two blocks, same points, model type and constants
    for a, b in zip(from_deck.blocks, toml.blocks, strict=True):
        assert np.array_equal(a.points, b.points)
        assert (a.model, dict(a.material), a.horizon) == (b.model, dict(b.material), b.horizon)
    assert [b.horizon for b in from_deck.blocks] == [0.2015, 0.2015]
    ua = pdlin.solve(from_deck.problem, solver="direct").u
    ub = pdlin.solve(toml.problem, solver="direct").u
    # same points and model; the deck's volumes are the grid's, so equal to round-off
    np.testing.assert_allclose(ua, ub, rtol=0, atol=1e-12 * np.abs(ub).max())


def test_perilab_blocks_with_two_materials(tmp_path):
    yaml = pytest.importorskip("yaml")
    h = 0.1
    cloud = pdlin.grid((10, 5), h)
    pts = cloud.points
    block = np.where(pts[:, 0] < 0.5, 1, 2)
    lines = ["header: x y block_id volume"]
    lines += [
        f"{float(p[0])!r} {float(p[1])!r} {b} {h * h!r}" for p, b in zip(pts, block, strict=True)
    ]
    (tmp_path / "plate.txt").write_text("\n".join(lines) + "\n")
    (tmp_path / "ns_1.txt").write_text("\n".join(map(str, np.flatnonzero(pts[:, 0] < 0.3) + 1)))
    mat = {"Material Model": "PD Solid Elastic", "Symmetry": "isotropic plane stress"}
    deck = {
        "PeriLab": {
            "Discretization": {
                "Type": "Text File",
                "Input Mesh File": "plate.txt",
                "Node Sets": {"Node Set 1": "ns_1.txt"},
            },
            "Models": {
                "Material Models": {
                    "Hard": {**mat, "Young's Modulus": 2.0, "Poisson's Ratio": 0.25},
                    "Soft": {**mat, "Bulk Modulus": 0.4, "Shear Modulus": 0.24},
                }
            },
            "Blocks": {
                "block_1": {"Horizon": 0.301, "Material Model": "Hard"},
                "block_2": {"Horizon": 0.35, "Material Model": "Soft"},
            },
            "Boundary Conditions": {
                "BC": {"Coordinate": "x", "Node Set": "Node Set 1", "Variable": "Displacements"}
            },
            "Solver": {"Final Time": 1.0, "Static": {}},
        }
    }
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(deck))
    sc = pdlin.read_deck(tmp_path / "p.yaml")
    assert [(b.name, b.key, b.model, b.horizon) for b in sc.blocks] == [
        ("block_1", "Blocks.block_1", "lps", 0.301),
        ("block_2", "Blocks.block_2", "lps", 0.35),
    ]
    np.testing.assert_array_equal(sc.problem.horizon, np.where(block == 1, 0.301, 0.35))
    # E = 2, nu = 0.25 -> K = E / (3 (1 - 2 nu)) = 4/3, G = E / (2 (1 + nu)) = 0.8; the soft
    # block is K = 0.4, G = 0.24 (same nu = 0.25): both as K, G per point
    k_mod, g_mod = sc.model.moduli(3)
    np.testing.assert_allclose(k_mod, np.where(block == 1, 4 / 3, 0.4), rtol=1e-14)
    np.testing.assert_allclose(g_mod, np.where(block == 1, 0.8, 0.24), rtol=1e-14)
    deck["PeriLab"]["Models"]["Material Models"]["Soft"]["Material Model"] = "Bond-based Elastic"
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(deck))
    with pytest.raises(SceneError, match=r"Blocks.block_2 uses model 'bond_based' but Blocks"):
        pdlin.read_deck(tmp_path / "p.yaml")


def test_block_horizons_per_point():
    data = bar_data()
    data["horizon"] = {}
    data["block"][0]["horizon"] = 3.015 * H
    data["block"][1]["horizon"] = 4.015 * H
    sc = scene_from_dict(data)
    x = sc.cloud.points[:, 0]
    # each block's own horizon on its points, as Peridigm's Blocks.<name>.Horizon
    np.testing.assert_array_equal(sc.problem.horizon, np.where(x < 0.5, 3.015 * H, 4.015 * H))
    assert [b.horizon for b in sc.blocks] == [3.015 * H, 4.015 * H]
    # horizon.value is the default of blocks without one
    del data["block"][1]["horizon"]
    data["horizon"] = {"value": 5.015 * H}
    sc = scene_from_dict(data)
    np.testing.assert_array_equal(sc.problem.horizon, np.where(x < 0.5, 3.015 * H, 5.015 * H))
    data["horizon"] = {}
    with pytest.raises(SceneError, match=r"block\[1\] sets no horizon while other blocks do"):
        scene_from_dict(data)
    data["horizon"] = {"ratio": 3.015}
    with pytest.raises(SceneError, match="block horizons and horizon.ratio exclude each other"):
        scene_from_dict(data)
    data["block"][0]["horizon"] = -1.0
    with pytest.raises(SceneError, match=r"block\[0\].horizon must be > 0"):
        scene_from_dict(data)
    # without block horizons [horizon] still needs value or ratio
    with pytest.raises(SceneError, match="horizon needs exactly one of 'value' or 'ratio'"):
        scene_from_dict(bar_data(horizon={}))
