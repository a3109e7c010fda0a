"""Peridigm / PeriLab input decks (pdlin.read_deck): formats, mapping, key-path errors.

The decks are written here from the documented formats (Peridigm ``examples/`` and
``src/`` readers, PeriLab.jl ``examples/Dogbone``; see the module docstring of
``pdlin/io/decks.py``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pdlin
from pdlin.errors import SceneError
from pdlin.scene.decks import deck_expression, peridigm_hourglass_penalty

yaml = pytest.importorskip("yaml")

H = 0.1  # point spacing of the test bars


def bar_points(nx: int = 8, ny: int = 2, nz: int = 2, h: float = H) -> np.ndarray:
    """Cell-centred points of an nx x ny x nz bar (x fastest last, as np.meshgrid ij)."""
    ax = [(np.arange(k) + 0.5) * h for k in (nx, ny, nz)]
    return np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3)


def write_text_mesh(path: Path, pts: np.ndarray, vol: float, block=None) -> None:
    block = np.ones(len(pts), int) if block is None else block
    lines = ["# x y z block_id volume", "// a C++-style comment", "* a starred comment", ""]
    for p, b in zip(pts, block, strict=True):
        lines.append(f"{float(p[0])!r} {float(p[1])!r} {float(p[2])!r} {b} {float(vol)!r}")
    path.write_text("\n".join(lines) + "\n")


def peridigm_deck(material: dict, *, extra_bc: dict | None = None, solver: dict | None = None):
    """A Peridigm deck (as a dict) pulling an 8 x 2 x 2 bar along x."""
    bcs = {
        "Node Set One": "left.txt",
        "Node Set Two": "right.txt",
        "Fix X": {
            "Type": "Prescribed Displacement",
            "Node Set": "Node Set One",
            "Coordinate": "x",
            "Value": "0.0",
        },
        "Pull X": {
            "Type": "Prescribed Displacement",
            "Node Set": "Node Set Two",
            "Coordinate": "x",
            "Value": "0.001*t",
        },
        "Fix YZ": {
            "Type": "Prescribed Displacement",
            "Node Set": "Full Domain",
            "Coordinate": "y",
            "Value": 0.0,
        },
        "Fix Z": {
            "Type": "Prescribed Displacement",
            "Node Set": "Full Domain",
            "Coordinate": "z",
            "Value": 0.0,
        },
    }
    bcs.update(extra_bc or {})
    return {
        "Peridigm": {
            "Verbose": False,
            "Discretization": {"Type": "Text File", "Input Mesh File": "bar.txt"},
            "Materials": {"My Material": material},
            "Blocks": {
                "My Block": {"Block Names": "block_1", "Material": "My Material", "Horizon": 0.2015}
            },
            "Boundary Conditions": bcs,
            "Solver": solver
            or {
                "Verbose": False,
                "Initial Time": 0.0,
                "Final Time": 2.0,
                "QuasiStatic": {"Number of Load Steps": 4, "Absolute Tolerance": 1.0},
            },
            "Output": {"Output Filename": "out", "Output Variables": {"Displacement": True}},
        }
    }


LPS_MAT = {
    "Material Model": "Elastic",
    "Density": 7.8,
    "Bulk Modulus": 130.0,
    "Shear Modulus": 70.0,
}


@pytest.fixture
def bar_dir(tmp_path: Path) -> Path:
    pts = bar_points()
    write_text_mesh(tmp_path / "bar.txt", pts, H**3)
    left = np.flatnonzero(pts[:, 0] < 2 * H) + 1  # 1-based ids (Peridigm node sets)
    right = np.flatnonzero(pts[:, 0] > 6 * H) + 1
    (tmp_path / "left.txt").write_text("# left end\n" + "\n".join(map(str, left)) + "\n")
    (tmp_path / "right.txt").write_text(" ".join(map(str, right)) + "\n")
    return tmp_path


def write_yaml(path: Path, deck: dict) -> Path:
    path.write_text(yaml.safe_dump(deck, sort_keys=False))
    return path


def to_xml(name: str, table: dict, indent: str = "") -> str:
    """Teuchos ParameterList XML of a nested dict (the Peridigm XML deck format)."""
    out = [f'{indent}<ParameterList name="{name}">']
    for k, v in table.items():
        if isinstance(v, dict):
            out.append(to_xml(k, v, indent + "  "))
        else:
            typ = {bool: "bool", int: "int", float: "double", str: "string"}[type(v)]
            val = str(v).lower() if isinstance(v, bool) else str(v)
            out.append(f'{indent}  <Parameter name="{k}" type="{typ}" value="{val}"/>')
    out.append(f"{indent}</ParameterList>")
    return "\n".join(out)


# ---------------------------------------------------------------- expressions
def test_expression_arithmetic_functions_and_time():
    pts = np.array([[1.0, 2.0, 3.0], [0.5, 0.0, -1.0]])
    got = deck_expression("value = 0.5*x + y*z - 2*t + sqrt(4) + pow(x, 2) - abs(z)", pts, 3.0)
    # hand evaluation: point 0: 0.5 + 6 - 6 + 2 + 1 - 3 = 0.5; point 1: 0.25 + 0 - 6 + 2 + 0.25 - 1
    np.testing.assert_allclose(got, [0.5, -4.5], rtol=0, atol=1e-15)
    # PeriLab (Julia) power: 2^3 = 8
    assert deck_expression("x^3", pts[:1], 0.0, caret_power=True).tolist() == [1.0]
    assert deck_expression(0.25, pts, 0.0).tolist() == [0.25, 0.25]


@pytest.mark.parametrize(
    "expr, pattern",
    [
        ("__import__('os').system('true')", "unsupported construct"),
        ("x.real", "unsupported construct Attribute"),
        ("lambda: 1", "unsupported construct Lambda"),
        ("open('f')", "unknown function 'open'"),
        ("q + 1", "unknown name 'q'"),
        ("x if y else z", "unsupported construct IfExp"),
        ("'abc'", "unsupported construct Constant"),
        ("x +", "cannot parse expression"),
        ("x // 2", "unsupported construct BinOp"),
        ("1/(x-1)", "is not finite at point 0"),
    ],
)
def test_expression_rejects_anything_else(expr, pattern):
    with pytest.raises(SceneError, match=r"^Boundary.Value: .*" + pattern):
        deck_expression(expr, np.array([[1.0, 0.0, 0.0]]), 0.0, "Boundary.Value")


# ---------------------------------------------------------------- Peridigm, text files
def test_yaml_deck_builds_the_lps_problem(bar_dir):
    scene = pdlin.read_deck(write_yaml(bar_dir / "deck.yaml", peridigm_deck(LPS_MAT)))
    model = scene.model
    assert isinstance(model, pdlin.LPS) and model.peridigm
    # K = 130, G = 70 -> E = 9KG/(3K+G) = 81900/460, nu = (3K-2G)/(2(3K+G)) = 250/920
    np.testing.assert_allclose([model.E, model.nu], [81900 / 460, 250 / 920], rtol=1e-14)
    assert scene.cloud.n == 32 and scene.cloud.dim == 3
    np.testing.assert_allclose(scene.cloud.volumes, H**3, rtol=1e-15)
    assert scene.output == bar_dir / "out.vtu"
    dofs, vals = pdlin.constraints.resolve_dirichlet(scene.cloud, scene.problem.dirichlet)
    x = scene.cloud.points
    right = np.flatnonzero(x[:, 0] > 6 * H)
    # the pull is evaluated at Final Time = 2: 0.001 * 2
    pulled = vals[np.isin(dofs, 3 * right)]
    np.testing.assert_allclose(pulled, 0.002, rtol=1e-15)
    assert pulled.size == right.size


def test_xml_and_yaml_decks_give_the_same_solution(bar_dir):
    deck = peridigm_deck(LPS_MAT)
    ry = pdlin.solve(pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck)).problem)
    (bar_dir / "d.xml").write_text(
        '<?xml version="1.0"?>\n<!-- a Peridigm deck -->\n'
        + to_xml("Peridigm", deck["Peridigm"]).replace(
            '<ParameterList name="Peridigm">', "<ParameterList>", 1
        )
    )
    rx = pdlin.solve(pdlin.read_deck(bar_dir / "d.xml").problem)
    np.testing.assert_allclose(rx.u, ry.u, rtol=0, atol=1e-15)
    np.testing.assert_allclose(rx.reactions, ry.reactions, rtol=0, atol=1e-12)


def test_inline_node_sets_and_all_sets(bar_dir):
    deck = peridigm_deck(LPS_MAT)
    bcs = deck["Peridigm"]["Boundary Conditions"]
    bcs["Node Set One"] = "1 2 3 4"
    bcs["Node Set Two"] = 32  # a single node id
    bcs["Fix X"]["Node Set"] = "All Sets"
    bcs.pop("Pull X")
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    fix_x = scene.problem.dirichlet[0]
    np.testing.assert_array_equal(fix_x.where, [0, 1, 2, 3, 31])


@pytest.mark.parametrize(
    "edit, pattern",
    [
        (
            lambda b: b.update({"Node Set One": "missing.txt"}),
            r"Node Set One: file not found: .*missing.txt",
        ),
        (
            lambda b: b.update({"Node Set One": "0 1 2"}),
            r"Node Set One: node ids are 1-based .* \[0, 2\]",
        ),
        (
            lambda b: b.update({"Node Set One": "1 33"}),
            r"node ids are 1-based and must lie in \[1, 32\]",
        ),
        (
            lambda b: b["Fix X"].update({"Node Set": "Node Set Three"}),
            r"Fix X.Node Set: node set 'Node Set Three' not found",
        ),
        (
            lambda b: b["Fix X"].update({"Coordinate": "w"}),
            r"Fix X.Coordinate must be x, y or z, got 'w'",
        ),
        (
            lambda b: b["Fix X"].update({"Type": "Initial Velocity"}),
            r"Fix X.Type: 'Initial Velocity' is not supported; supported: "
            r"'Prescribed Displacement', 'Body Force'",
        ),
        (
            lambda b: b["Fix X"].update({"Scale": 2.0}),
            r"Fix X.Scale: not supported .* supported keys: "
            r"\['Coordinate', 'Node Set', 'Type', 'Value'\]",
        ),
        (lambda b: b["Pull X"].update({"Value": "0.001*t*q"}), r"Pull X.Value: unknown name 'q'"),
        (lambda b: b.pop("Node Set One"), r"Fix X.Node Set: node set 'Node Set One' not found"),
    ],
)
def test_boundary_condition_errors_name_the_key(bar_dir, edit, pattern):
    deck = peridigm_deck(LPS_MAT)
    edit(deck["Peridigm"]["Boundary Conditions"])
    with pytest.raises(SceneError, match=pattern):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))


@pytest.mark.parametrize(
    "where, key, value, pattern",
    [
        ("Peridigm", "Contact", {}, r"Peridigm.Contact: not supported"),
        (
            "Peridigm",
            "Damage Models",
            {},
            r"Peridigm.Damage Models: damage is supported with Solver.Verlet only",
        ),
        (
            "Discretization",
            "Type",
            "Sphere Mesh",
            r"Discretization.Type must be 'Text File', 'Exodus' or 'PdQuickGrid'.*'Sphere Mesh'",
        ),
        (
            "Discretization",
            "Bond Filters",
            {"F": {"Type": "Exodus Mesh", "File Name": "cracks.g"}},
            r"Discretization.Bond Filters.F.Type must be 'Rectangular_Plane' or 'Disk'",
        ),
        (
            "Discretization",
            "Bond Filters",
            {"F": {"Type": "Disk", "Center_X": 0.0}},
            r"missing deck key Discretization.Bond Filters.F.Center_Y",
        ),
        (
            "Discretization",
            "Bond Filters",
            {"F": {"Type": "Disk", "Centre_X": 0.0}},
            r"Discretization.Bond Filters.F.Centre_X: not supported",
        ),
        (
            "Discretization",
            "Omit Bonds Between Blocks",
            "Some",
            r"Discretization.Omit Bonds Between Blocks must be 'None' .* or 'All' .*got 'Some'",
        ),
        (
            "Discretization",
            "Construct Neighborhood Lists",
            False,
            r"Discretization.Construct Neighborhood Lists: false \(no bonds\) is not supported",
        ),
        (
            "Material",
            "Material Model",
            "Elastic Plastic",
            # Peridigm_ElasticPlasticMaterial.cpp reads Yield Stress (required)
            r"missing deck key Materials\.My Material\.Yield Stress "
            r"\(required by 'Elastic Plastic'\)",
        ),
        (
            "Material",
            "Material Model",
            "Linear LPS Partial Volume",
            r"partial-volume materials are not supported",
        ),
        (
            "Material",
            "Plane Strain",
            True,
            r"Plane Strain: true is not supported: pdlin reads Peridigm decks as 3D",
        ),
        ("Material", "Influence Function", "Gaussian", r"Influence Function: only 'One'"),
        (  # supported (thermal strains) but must be a number
            "Material",
            "Thermal Expansion Coefficient",
            "hot",
            r"Materials\.My Material\.Thermal Expansion Coefficient",
        ),
        (
            "Material",
            "Young's Modulus",
            200.0,
            r"needs exactly two of .* got \['Bulk Modulus', 'Shear Modulus', \"Young's Modulus\"\]",
        ),
        ("Material", "Damage Model", "My Damage", r"Damage Model: not supported"),
        ("Block", "Horizon", "0.2*x", r"Horizon: expressions for the horizon are not supported"),
        ("Block", "Horizon", -0.1, r"Horizon must be > 0, got -0.1"),
        ("Block", "Block Names", "block_2", r"Block Names: 'block_2' is not in the discretization"),
        ("Block", "Material", "Other", r"Material: 'Other' is not defined under Materials"),
        ("Block", "Damage Model", "D", r"Blocks.My Block.Damage Model: not supported"),
        # a Verlet list beside QuasiStatic: the Verlet solver reads no QuasiStatic list
        ("Solver", "Verlet", {"Safety Factor": 0.8}, r"Solver.QuasiStatic: not supported"),
        ("Solver", "Final Time", -1.0, r"Solver.Final Time must exceed Initial Time"),
        ("QuasiStatic", "Number of Load Steps", 0, r"Number of Load Steps must be an integer >= 1"),
        ("QuasiStatic", "Bogus Key", 1, r"Solver.QuasiStatic.Bogus Key: not supported"),
        ("Output", "Output Type", "x", r"Output.Output Type: not supported"),
    ],
)
def test_unsupported_keys_raise_with_their_path(bar_dir, where, key, value, pattern):
    deck = peridigm_deck(dict(LPS_MAT))
    root = deck["Peridigm"]
    table = {
        "Peridigm": root,
        "Discretization": root["Discretization"],
        "Material": root["Materials"]["My Material"],
        "Block": root["Blocks"]["My Block"],
        "Solver": root["Solver"],
        "QuasiStatic": root["Solver"]["QuasiStatic"],
        "Output": root["Output"],
    }[where]
    table[key] = value
    with pytest.raises(SceneError, match=pattern):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))


def test_missing_sections_and_files(bar_dir):
    deck = peridigm_deck(LPS_MAT)
    del deck["Peridigm"]["Solver"]
    with pytest.raises(SceneError, match=r"missing deck key Peridigm.Solver"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    deck = peridigm_deck(LPS_MAT)
    deck["Peridigm"]["Discretization"]["Input Mesh File"] = "nope.txt"
    with pytest.raises(SceneError, match=r"Discretization.Input Mesh File: file not found"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    with pytest.raises(SceneError, match=r"deck file not found"):
        pdlin.read_deck(bar_dir / "absent.yaml")
    (bar_dir / "d.toml").write_text("")
    with pytest.raises(SceneError, match=r"must end with .yaml, .yml or .xml"):
        pdlin.read_deck(bar_dir / "d.toml")
    (bar_dir / "x.yaml").write_text("Other: {}\n")
    with pytest.raises(SceneError, match=r"top-level list must be 'Peridigm' or 'PeriLab'"):
        pdlin.read_deck(bar_dir / "x.yaml")


def test_text_file_format_errors(bar_dir):
    (bar_dir / "bar.txt").write_text("0 0 0 1\n")
    with pytest.raises(SceneError, match=r"bar.txt line 1 has 4 columns, expected 5"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", peridigm_deck(LPS_MAT)))
    (bar_dir / "bar.txt").write_text("0 0 0 1 abc\n")
    with pytest.raises(SceneError, match=r"bar.txt line 1 is not numbers"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", peridigm_deck(LPS_MAT)))
    (bar_dir / "bar.txt").write_text("# only comments\n")
    with pytest.raises(SceneError, match=r"holds no points"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", peridigm_deck(LPS_MAT)))


def test_xml_type_errors(bar_dir):
    (bar_dir / "d.xml").write_text(
        '<ParameterList><ParameterList name="Solver">'
        '<Parameter name="Final Time" type="double" value="abc"/></ParameterList></ParameterList>'
    )
    with pytest.raises(
        SceneError, match=r"Peridigm.Solver.Final Time: 'abc' is not a valid double"
    ):
        pdlin.read_deck(bar_dir / "d.xml")
    (bar_dir / "d.xml").write_text(
        '<ParameterList><Parameter name="V" type="Array" value="1"/></ParameterList>'
    )
    with pytest.raises(SceneError, match=r"Peridigm.V: Parameter type must be one of"):
        pdlin.read_deck(bar_dir / "d.xml")
    (bar_dir / "d.xml").write_text("<ParameterList><Parameter")
    with pytest.raises(SceneError, match=r"invalid XML"):
        pdlin.read_deck(bar_dir / "d.xml")


def test_material_mapping():
    # Peridigm's Elastic Correspondence hourglass constant 18 C K/(pi d^4) vs pdlin's
    # bond-based 18 K_eq/(pi d^4), K_eq = (K + 4G/3)/1.8: penalty = 1.8 C K/(K + 4G/3)
    assert peridigm_hourglass_penalty(0.02, 1.0, 0.75) == pytest.approx(1.8 * 0.02 / 2.0, rel=1e-15)


def test_bond_based_and_correspondence_decks(bar_dir):
    bb = {"Material Model": "Elastic Bond Based", "Density": 1.0, "Bulk Modulus": 3.0}
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", peridigm_deck(bb)))
    bonds = scene.bonds()
    c = scene.model.bond_micromodulus(scene.cloud, bonds)
    # Peridigm elastic_bond_based.cxx: c = 18 K / (pi delta^4), delta = 0.2015
    np.testing.assert_allclose(c, 18 * 3.0 / (np.pi * 0.2015**4), rtol=1e-12)
    co = {
        "Material Model": "Elastic Correspondence",
        "Density": 1.0,
        "Young's Modulus": 2.0,
        "Poisson's Ratio": 0.25,
        "Hourglass Coefficient": 0.02,
    }
    model = pdlin.read_deck(
        write_yaml(bar_dir / "d.yaml", peridigm_deck(co)), kinematics="linear"
    ).model
    assert isinstance(model, pdlin.Correspondence) and model.control == "penalty"
    # E = 2, nu = 1/4: K = E/(3(1-2nu)) = 4/3, G = E/(2(1+nu)) = 0.8
    assert model.penalty == pytest.approx(1.8 * 0.02 * (4 / 3) / (4 / 3 + 4 * 0.8 / 3), rel=1e-13)
    co["Hourglass Coefficient"] = 0.0
    model = pdlin.read_deck(
        write_yaml(bar_dir / "d.yaml", peridigm_deck(co)), kinematics="linear"
    ).model
    assert model.control == "none"
    del co["Hourglass Coefficient"]
    with pytest.raises(SceneError, match=r"Hourglass Coefficient is required"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", peridigm_deck(co)))


def test_body_force_is_a_force_density(bar_dir):
    bf = {
        "Gravity": {
            "Type": "Body Force",
            "Node Set": "Full Domain",
            "Coordinate": "z",
            "Value": "-9.8*t",
        }
    }
    deck = peridigm_deck(LPS_MAT, extra_bc=bf)
    deck["Peridigm"]["Boundary Conditions"].pop("Fix Z")
    deck["Peridigm"]["Boundary Conditions"]["Fix X"]["Node Set"] = "Full Domain"
    deck["Peridigm"]["Boundary Conditions"].pop("Pull X")
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    f = pdlin.constraints.load_vector(scene.cloud, scene.problem.loads).reshape(-1, 3)
    # b V at t = Final Time = 2: -19.6 * 0.001 per point, z only
    np.testing.assert_allclose(f[:, 2], -19.6 * H**3, rtol=1e-14)
    assert np.all(f[:, :2] == 0)


def test_multiple_blocks_per_point_horizons_and_constants(bar_dir):
    pts = bar_points()
    block = np.where(pts[:, 0] < 0.4, 1, 2)
    write_text_mesh(bar_dir / "bar.txt", pts, H**3, block)
    deck = peridigm_deck(LPS_MAT)
    root = deck["Peridigm"]
    root["Materials"]["Soft"] = {**LPS_MAT, "Bulk Modulus": 13.0, "Shear Modulus": 7.0}
    root["Blocks"] = {
        "A": {"Block Names": "block_1", "Material": "My Material", "Horizon": 0.2015},
        "B": {"Block Names": "block_2", "Material": "Soft", "Horizon": 0.25},
    }
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    np.testing.assert_allclose(scene.problem.horizon, np.where(block == 1, 0.2015, 0.25))
    E = np.asarray(scene.model.E)
    np.testing.assert_allclose(E, np.where(block == 1, 81900 / 460, 8190 / 460), rtol=1e-13)
    root["Blocks"] = {"A": {"Block Names": "block_1", "Material": "My Material", "Horizon": 0.2}}
    with pytest.raises(SceneError, match=r"block\(s\) \['block_2'\] are not assigned"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))


# ---------------------------------------------------------------- Exodus
def write_exodus(path: Path, coords, blocks, node_sets=()) -> None:
    """A minimal Exodus II file written with netCDF4 (the variables Peridigm reads).

    ``blocks``: (id, name, elem_type, 1-based connectivity[, attributes]) in file order;
    ``node_sets``: (id, name, 1-based node numbers) in file order.  Blank names are
    written as empty strings, as Cubit does.
    """
    netCDF4 = pytest.importorskip("netCDF4")
    coords = np.asarray(coords, float)
    with netCDF4.Dataset(path, "w") as ds:
        ds.createDimension("len_name", 33)
        ds.createDimension("num_dim", 3)
        ds.createDimension("num_nodes", len(coords))
        ds.createDimension("num_el_blk", len(blocks))
        for c, k in zip("xyz", range(3), strict=True):
            ds.createVariable(f"coord{c}", "f8", ("num_nodes",))[:] = coords[:, k]

        def names(var: str, dim: str, values) -> None:
            v = ds.createVariable(var, "S1", (dim, "len_name"))
            v[:] = netCDF4.stringtochar(np.array([n.ljust(33, "\0") for n in values], "S33"))

        ds.createVariable("eb_prop1", "i4", ("num_el_blk",))[:] = [b[0] for b in blocks]
        names("eb_names", "num_el_blk", [b[1] for b in blocks])
        for k, blk in enumerate(blocks, 1):
            conn = np.asarray(blk[3])
            ds.createDimension(f"num_el_in_blk{k}", conn.shape[0])
            ds.createDimension(f"num_nod_per_el{k}", conn.shape[1])
            v = ds.createVariable(f"connect{k}", "i4", (f"num_el_in_blk{k}", f"num_nod_per_el{k}"))
            v.elem_type = blk[2]
            v[:] = conn
            if len(blk) > 4:
                att = np.asarray(blk[4], float)
                ds.createDimension(f"num_att_in_blk{k}", att.shape[1])
                ds.createVariable(f"attrib{k}", "f8", (f"num_el_in_blk{k}", f"num_att_in_blk{k}"))[
                    :
                ] = att
        if node_sets:
            ds.createDimension("num_node_sets", len(node_sets))
            ds.createVariable("ns_prop1", "i4", ("num_node_sets",))[:] = [ns[0] for ns in node_sets]
            names("ns_names", "num_node_sets", [ns[1] for ns in node_sets])
            for k, ns in enumerate(node_sets, 1):
                ds.createDimension(f"num_nod_ns{k}", len(ns[2]))
                ds.createVariable(f"node_ns{k}", "i4", (f"num_nod_ns{k}",))[:] = ns[2]


def hex_bar(nx: int = 3):
    """Nodes and 1-based hex connectivity of nx hexes of size 0.5 x 1 x 2 along x."""
    xs = 0.5 * np.arange(nx + 1)
    nodes = np.array([[x, y, z] for z in (0.0, 2.0) for y in (0.0, 1.0) for x in xs])
    n4 = len(xs)

    def nid(i, j, k):
        return i + n4 * (j + 2 * k) + 1

    hexes = [
        [nid(i, 0, 0), nid(i + 1, 0, 0), nid(i + 1, 1, 0), nid(i, 1, 0),
         nid(i, 0, 1), nid(i + 1, 0, 1), nid(i + 1, 1, 1), nid(i, 1, 1)]
        for i in range(nx)
    ]  # fmt: skip
    end = {i: [nid(i, j, k) for j in (0, 1) for k in (0, 1)] for i in (0, nx)}
    return nodes, np.array(hexes), end


def exodus_deck(bcs: dict, block_names: str = "block_1", horizon: float = 1.1) -> dict:
    deck = peridigm_deck(LPS_MAT)
    root = deck["Peridigm"]
    root["Discretization"] = {"Type": "Exodus", "Input Mesh File": "bar.g"}
    root["Blocks"]["My Block"].update({"Block Names": block_names, "Horizon": horizon})
    root["Boundary Conditions"] = {
        name: {"Type": "Prescribed Displacement", "Coordinate": "x", "Value": "0", "Node Set": ns}
        for name, ns in bcs.items()
    }
    return deck


def test_exodus_discretization_elements_become_points(tmp_path):
    nodes, hexes, end = hex_bar()
    write_exodus(tmp_path / "bar.g", nodes, [(1, "", "HEX8", hexes)], [(1, "", end[0])])
    scene = pdlin.read_deck(write_yaml(tmp_path / "d.yaml", exodus_deck({"Fix": "nodelist_1"})))
    # centroids (0.25 + 0.5 i, 0.5, 1), volumes 0.5 * 1 * 2 = 1 (Peridigm: one point per hex)
    np.testing.assert_allclose(
        scene.cloud.points, [[0.25, 0.5, 1.0], [0.75, 0.5, 1.0], [1.25, 0.5, 1.0]]
    )
    np.testing.assert_allclose(scene.cloud.volumes, 1.0, rtol=1e-14)
    # nodelist_1 (the x = 0 nodes) -> the element holding them
    np.testing.assert_array_equal(scene.problem.dirichlet[0].where, [0])


def test_exodus_sets_and_blocks_are_named_by_id(tmp_path):
    # Peridigm_ExodusDiscretization.cpp: a blank node-set name is nodelist_<ns_prop1 id>, a
    # blank block name block_<eb_prop1 id>; ids need not follow the file order. Three blank
    # sets used to collapse into one set '' (meshio keys point_sets by ns_names).
    nodes, hexes, end = hex_bar()
    write_exodus(
        tmp_path / "bar.g",
        nodes,
        [(20, "", "HEX8", hexes[:2]), (10, "", "HEX8", hexes[2:])],
        [(7, "", end[3]), (3, "", end[0]), (5, "named_set", end[0])],
    )
    deck = exodus_deck(
        {"Right": "nodelist_7", "Left": "nodelist_3", "Also Left": "named_set"},
        block_names="block_10 block_20",
    )
    scene = pdlin.read_deck(write_yaml(tmp_path / "d.yaml", deck))
    where = [d.where.tolist() for d in scene.problem.dirichlet]
    # node set 7 holds the x = 1.5 nodes: element 3 (index 2); sets 3 and 5 the x = 0 ones
    assert where == [[2], [0], [0]]
    # the ids are the block names: block 20 -> the first two elements
    deck["Peridigm"]["Blocks"]["My Block"]["Block Names"] = "block_20"
    with pytest.raises(SceneError, match=r"block\(s\) \['block_10'\] are not assigned"):
        pdlin.read_deck(write_yaml(tmp_path / "d.yaml", deck))
    # duplicate names stop the run, as in Peridigm ("Duplicate node set found")
    write_exodus(tmp_path / "bar.g", nodes, [(1, "", "HEX8", hexes)], [(3, "", end[0])] * 2)
    with pytest.raises(SceneError, match=r"two node sets named 'NODELIST_3'"):
        pdlin.read_deck(write_yaml(tmp_path / "d.yaml", exodus_deck({"F": "nodelist_3"})))


def test_exodus_sphere_and_tet_elements(tmp_path):
    # sphere elements: the point is the element's node, the volume its 2nd attribute
    # (Peridigm_ExodusDiscretization.cpp); tets: vertex mean and a . (b x c) / 6
    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 0, 0], [4, 0, 0]], float)
    write_exodus(
        tmp_path / "bar.g",
        nodes,
        [
            (1, "", "TETRA", [[1, 2, 3, 4]]),
            (2, "", "SPHERE", [[5], [6]], [[0.5, 0.25], [0.5, 0.125]]),
        ],
        [(1, "", [6])],
    )
    deck = exodus_deck({"Fix": "nodelist_1"}, block_names="block_1 block_2", horizon=3.5)
    scene = pdlin.read_deck(write_yaml(tmp_path / "d.yaml", deck))
    np.testing.assert_allclose(scene.cloud.points, [[0.25] * 3, [3, 0, 0], [4, 0, 0]])
    np.testing.assert_allclose(scene.cloud.volumes, [1 / 6, 0.25, 0.125], rtol=1e-14)
    np.testing.assert_array_equal(scene.problem.dirichlet[0].where, [2])
    # an inverted tet (negative a . (b x c)) stops the run, as Peridigm's tetVolume does
    write_exodus(tmp_path / "bar.g", nodes, [(1, "", "TETRA", [[1, 3, 2, 4]])], [(1, "", [1])])
    with pytest.raises(SceneError, match=r"block 1 element 1 is inverted"):
        pdlin.read_deck(write_yaml(tmp_path / "d.yaml", exodus_deck({"F": "nodelist_1"})))


def test_exodus_file_errors_name_the_key(tmp_path):
    netCDF4 = pytest.importorskip("netCDF4")
    nodes, hexes, end = hex_bar()
    deck = write_yaml(tmp_path / "d.yaml", exodus_deck({"F": "nodelist_1"}))
    key = r"^Discretization.Input Mesh File: "
    cases = [
        ([(1, "", "QUAD4", hexes[:, :4])], [(1, "", end[0])], key + r".*'QUAD4' elements"),
        ([(1, "", "HEX8", hexes)], [(1, "", [1, 99])], key + r"Exodus node set 1 must hold"),
        ([(1, "", "HEX8", hexes + 100)], [], key + r"Exodus block 1 connectivity must hold"),
        (
            [(1, "", "SPHERE", [[1]])],
            [],
            key + r"Exodus block 1 has sphere elements without the volume",
        ),
    ]
    for blocks, sets, pattern in cases:
        write_exodus(tmp_path / "bar.g", nodes, blocks, sets)
        with pytest.raises(SceneError, match=pattern):
            pdlin.read_deck(deck)
    (tmp_path / "bar.g").write_text("not netCDF")
    with pytest.raises(SceneError, match=key + r"cannot read .* as Exodus"):
        pdlin.read_deck(deck)
    with netCDF4.Dataset(tmp_path / "bar.g", "w") as ds:  # a 2D mesh
        ds.createDimension("num_nodes", 3)
        for c in "xy":
            ds.createVariable(f"coord{c}", "f8", ("num_nodes",))[:] = 0.0
    with pytest.raises(SceneError, match=key + r"bar.g is a 2D mesh"):
        pdlin.read_deck(deck)


def test_numeric_strings_are_numbers(bar_dir):
    # YAML 1.1 loads 160.0e10 (no exponent sign) as a string; Teuchos reads a double
    text = yaml.safe_dump(peridigm_deck(LPS_MAT), sort_keys=False)
    text = text.replace("Bulk Modulus: 130.0", "Bulk Modulus: 13.0e1")
    text = text.replace("Horizon: 0.2015", "Horizon: '2.015e-1'")
    assert "13.0e1" in text and "'2.015e-1'" in text
    assert yaml.safe_load(text)["Peridigm"]["Materials"]["My Material"]["Bulk Modulus"] == "13.0e1"
    (bar_dir / "d.yaml").write_text(text)
    ref = pdlin.read_deck(write_yaml(bar_dir / "ref.yaml", peridigm_deck(LPS_MAT)))
    scene = pdlin.read_deck(bar_dir / "d.yaml")
    assert scene.model.moduli(3) == ref.model.moduli(3)
    assert scene.problem.horizon == ref.problem.horizon == 0.2015
    for bad in ("'1e9 Pa'", "'nan'", "'0x10'", "'1_000'"):
        (bar_dir / "d.yaml").write_text(text.replace("13.0e1", bad))
        with pytest.raises(SceneError, match=r"Materials.My Material.Bulk Modulus must be a"):
            pdlin.read_deck(bar_dir / "d.yaml")


NOX = {
    "Nonlinear Solver": "Line Search Based",
    "Number of Load Steps": 1,
    "Max Solver Iterations": 100,
    "Relative Tolerance": 1.0e-9,
    "Max Age Of Prec": 50,
    "Direction": {"Method": "Newton", "Newton": {"Linear Solver": {"Preconditioner": "None"}}},
    "Line Search": {"Method": "Polynomial"},
    "Printing": {"Output Information": 0},
}


@pytest.mark.parametrize(
    "solver",
    [
        # keys Peridigm.cpp reads (executeNOXQuasiStatic, executeQuasiStatic)
        {"Final Time": 2.0, "Peridigm Preconditioner": "None", "NOXQuasiStatic": NOX},
        {
            "Final Time": 2.0,
            "Jacobian Diagnostics": False,
            "Disable Heuristics": True,
            "QuasiStatic": {
                "Number of Load Steps": 2,
                "Damped Newton Diagonal Scale Factor": 1.0001,
                "Damped Newton Diagonal Shift Factor": 1e-5,
                "Belos Linear Solver": "BlockCG",
                "Belos Maximum Iterations": 100,
                "Belos Relative Tolerance": 1e-8,
                "Belos Print Status": False,
                "Adaptive Load-Stepping": {
                    "Maximum load step reductions in one step": 4,
                    "Maximum total load step reductions": 10,
                },
            },
        },
        # without Number of Load Steps Peridigm takes the Time Steps list (the last is final)
        {"QuasiStatic": {"Time Steps": "0.0 0.5 1.0 2.0"}},
    ],
    ids=["nox", "quasistatic", "time-steps"],
)
def test_peridigm_solver_keys_are_accepted(bar_dir, solver, caplog):
    ref = pdlin.solve(
        pdlin.read_deck(write_yaml(bar_dir / "r.yaml", peridigm_deck(LPS_MAT))).problem
    )
    deck = peridigm_deck(LPS_MAT, solver=solver)
    with caplog.at_level("INFO", logger="pdlin.io.decks"):
        res = pdlin.solve(pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck)).problem)
    # the same final time (2.0) gives the same solution
    np.testing.assert_allclose(res.u, ref.u, rtol=0, atol=1e-12 * np.abs(ref.u).max())
    sub = next(k for k in solver if k.endswith("QuasiStatic"))
    for k in solver[sub]:
        assert f"Solver.{sub}.{k} accepted" in caplog.text


def test_switch_to_verlet_and_bad_time_steps_are_refused(bar_dir):
    for qs, pattern in [
        (
            {"Number of Load Steps": 2, "Adaptive Load-Stepping": {"Switch to Verlet": {}}},
            r"Solver.QuasiStatic.Adaptive Load-Stepping.Switch to Verlet: explicit dynamics",
        ),
        ({"Time Steps": "0 a 1"}, r"Solver.QuasiStatic.Time Steps must be a list of times"),
        (
            {"Time Steps": "1.0 0.5"},
            r"Solver.QuasiStatic.Time Steps must be two or more finite, increasing times",
        ),
        ({"Time Steps": "0 0.5 0.5 1"}, r"Time Steps must be two or more .* got '0 0.5 0.5 1'"),
    ]:
        deck = peridigm_deck(LPS_MAT, solver={"Final Time": 2.0, "QuasiStatic": qs})
        if "Time Steps" in qs:
            del deck["Peridigm"]["Solver"]["Final Time"]
        with pytest.raises(SceneError, match=pattern):
            pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))


def test_peridigm_discretization_and_material_defaults_are_accepted(bar_dir, caplog):
    # keys Peridigm's discretizations and elastic.cxx read, at their defaults
    deck = peridigm_deck({**LPS_MAT, "Compute Partial Stress": True})
    deck["Peridigm"]["Discretization"].update(
        {
            "Verbose": False,
            "Construct Neighborhood Lists": True,
            "Omit Bonds Between Blocks": "None",
        }
    )
    with caplog.at_level("INFO", logger="pdlin.io.decks"):
        assert pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck)).cloud.n == 32
    for k in ("Discretization.Verbose", "Compute Partial Stress"):
        assert k in caplog.text


def test_omit_bonds_between_blocks_all_drops_the_bonds_joining_blocks(bar_dir):
    # Peridigm's ExodusDiscretization::filterBonds: 'All' keeps bonds within a block only
    pts = bar_points()
    block = np.where(pts[:, 0] < 4 * H, 1, 2)
    write_text_mesh(bar_dir / "bar.txt", pts, H**3, block)
    deck = peridigm_deck(LPS_MAT)
    deck["Peridigm"]["Blocks"]["My Block"]["Block Names"] = "block_1 block_2"
    scenes = {}
    for omit in ("None", "All"):
        deck["Peridigm"]["Discretization"]["Omit Bonds Between Blocks"] = omit
        scenes[omit] = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    p = scenes["All"].problem
    kept = pdlin.find_bonds(p.cloud, p.horizon, **p.bond_options)
    everything = pdlin.find_bonds(p.cloud, p.horizon)
    # (Peridigm keeps points without neighbours: every deck allows isolated points)
    assert scenes["None"].problem.bond_options == {"allow_isolated": True}
    assert not np.any(block[kept.i] != block[kept.j])
    same = block[everything.i] == block[everything.j]
    assert kept.n_bonds == int(same.sum()) < everything.n_bonds


def test_rectangular_plane_filter_is_peridigms_arithmetic():
    from pdlin.scene.decks import peridigm_bond_filters

    # PrecrackedPlateTwoCracks' right filter: Bottom_Unit_Vector (1, 4, 0) is neither unit
    # nor in the plane y = 4; Peridigm uses it as given: u_a = u_b x n = (0, 0, 1) and
    # (x - r0).u_b = dx on the plane, so the cut is 0 <= x <= 10, -10 <= z <= 10 at y = 4
    f = {"Type": "Rectangular_Plane", "Normal_X": 0, "Normal_Y": 1, "Normal_Z": 0}
    f |= {"Lower_Left_Corner_X": 0, "Lower_Left_Corner_Y": 4, "Lower_Left_Corner_Z": -10}
    f |= {"Bottom_Unit_Vector_X": 1, "Bottom_Unit_Vector_Y": 4, "Bottom_Unit_Vector_Z": 0}
    f |= {"Bottom_Length": 10, "Side_Length": 20}
    (cut,) = peridigm_bond_filters({"R": f}, "BF")
    p = np.array(
        [
            [5.0, 3.5, 0.0],  # crosses at (5, 4, 0): inside
            [-0.5, 3.5, 0.0],  # crosses at x = -0.5: outside
            [10.5, 3.5, 0.0],  # crosses at x = 10.5: outside
            [5.0, 3.5, 10.5],  # crosses at z = 10.5: outside
            [5.0, 4.0, 0.0],  # starts on the plane (t = 0): cut, as Peridigm's t >= 0
            [5.0, 3.5, 0.0],  # parallel to the plane: never cut
            [5.0, 3.0, 0.0],  # ends short of the plane (t > 1): not cut
        ]
    )
    q = p + np.array([[0, 1, 0]] * 5 + [[1, 0, 0], [0, 0.5, 0]], float)
    assert cut(p, q).tolist() == [True, False, False, False, True, False, False]
    # the corners themselves are in (Peridigm's 1e-15 tolerance on both sides)
    corner = np.array([[0.0, 3.5, -10.0], [10.0, 3.5, 10.0]])
    assert cut(corner, corner + [0, 1, 0]).all()


def test_default_block_takes_the_blocks_no_other_entry_names(bar_dir):
    # Peridigm's initializeBlocks: Block Names "default" applies to every discretization
    # block not named elsewhere (the MultipleHorizons / DefaultBlocks decks)
    pts = bar_points()
    block = np.where(pts[:, 0] < 4 * H, 1, 2)
    write_text_mesh(bar_dir / "bar.txt", pts, H**3, block)
    deck = peridigm_deck(LPS_MAT)
    root = deck["Peridigm"]
    root["Materials"]["Soft"] = {**LPS_MAT, "Bulk Modulus": 13.0, "Shear Modulus": 7.0}
    root["Blocks"] = {
        "Default Block": {"Block Names": "default", "Material": "Soft", "Horizon": 0.25},
        "Two": {"Block Names": "block_2", "Material": "My Material", "Horizon": 0.2015},
    }
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    k_mod, _ = scene.model.moduli(3)
    np.testing.assert_array_equal(k_mod, np.where(block == 1, 13.0, 130.0))
    np.testing.assert_array_equal(scene.problem.horizon, np.where(block == 1, 0.25, 0.2015))
    del root["Blocks"]["Default Block"]
    with pytest.raises(SceneError, match=r"Blocks: discretization block\(s\) \['block_1'\]"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))


def test_caret_is_the_power_in_peridigm_values(bar_dir):
    # Peridigm's function parser reads ^ as the power: CentrifugalLoad's "1E-5 * 94.25^2 * x"
    bc = {
        "Spin": {
            "Type": "Body Force",
            "Node Set": "Full Domain",
            "Coordinate": "x",
            "Value": "1E-5 * 94.25^2 * x",
        }
    }
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", peridigm_deck(LPS_MAT, extra_bc=bc)))
    body = scene.problem.loads[0]
    np.testing.assert_allclose(
        np.asarray(body.density)[:, 0], 1e-5 * 94.25**2 * scene.cloud.points[:, 0], rtol=1e-14
    )


@pytest.mark.parametrize(
    ("spelling", "value"),
    [("1", True), ("0", False), ("YES", True), ("no", False), ("True", True), ("FALSE", False)],
)
def test_xml_bool_spellings_of_teuchos(bar_dir, spelling, value):
    # Teuchos XMLObject::getRequiredBool: TRUE / YES / 1, FALSE / NO / 0, any case
    deck = peridigm_deck({**LPS_MAT, "Plane Strain": False})
    xml = to_xml("Peridigm", deck["Peridigm"]).replace(
        'name="Plane Strain" type="bool" value="false"',
        f'name="Plane Strain" type="bool" value="{spelling}"',
    )
    assert f'value="{spelling}"' in xml
    (bar_dir / "d.xml").write_text(xml)
    if value:
        with pytest.raises(SceneError, match=r"Materials.My Material.Plane Strain: true is not"):
            pdlin.read_deck(bar_dir / "d.xml")
    else:
        assert pdlin.read_deck(bar_dir / "d.xml").cloud.n == 32


# ---------------------------------------------------------------- PeriLab
def perilab_deck(material: dict, solver: dict | None = None) -> dict:
    return {
        "PeriLab": {
            "Discretization": {
                "Input Mesh File": "plate.txt",
                "Node Sets": {"Node Set 1": "ns_1.txt", "Node Set 2": "ns_2.txt"},
                "Type": "Text File",
            },
            "Models": {
                "Pre Calculation": {"Deformation Gradient": False},
                "Material Models": {"Mat": material},
            },
            "Boundary Conditions": {
                "BC_1": {
                    "Coordinate": "x",
                    "Node Set": "Node Set 1",
                    "Variable": "Displacements",
                    "Value": 0,
                },
                "BC_2": {
                    "Coordinate": "x",
                    "Node Set": "Node Set 2",
                    "Variable": "Displacements",
                    "Value": "0.5*t^2",
                    "Type": "Dirichlet",
                },
                "BC_3": {
                    "Coordinate": "y",
                    "Node Set": "Node Set 1",
                    "Variable": "Displacements",
                    "Value": 0,
                },
            },
            "Blocks": {
                "block_1": {
                    "Block ID": 1,
                    "Density": 1e-8,
                    "Horizon": 0.301,
                    "Material Model": "Mat",
                }
            },
            "Solver": solver
            or {"Final Time": 0.1, "Initial Time": 0.0, "Static": {"NLsolver": False}},
            "Outputs": {
                "Output": {"Output Filename": "o", "Output Variables": {"Displacements": True}}
            },
        }
    }


@pytest.fixture
def plate_dir(tmp_path: Path) -> Path:
    ax = (np.arange(10) + 0.5) * H
    pts = np.stack(np.meshgrid(ax, ax[:5], indexing="ij"), -1).reshape(-1, 2)
    lines = ["# PeriLab mesh", "header: x y block_id volume"]
    lines += [f"{float(p[0])!r} {float(p[1])!r} 1 {H * H!r}" for p in pts]
    (tmp_path / "plate.txt").write_text("\n".join(lines) + "\n")
    (tmp_path / "ns_1.txt").write_text("\n".join(map(str, np.flatnonzero(pts[:, 0] < 0.3) + 1)))
    (tmp_path / "ns_2.txt").write_text("\n".join(map(str, np.flatnonzero(pts[:, 0] > 0.7) + 1)))
    return tmp_path


def test_perilab_2d_plane_strain_deck(plate_dir):
    mat = {
        "Material Model": "PD Solid Elastic",
        "Symmetry": "isotropic plane strain",
        "Bulk Modulus": 2.5e3,
        "Shear Modulus": 1.15e3,
    }
    scene = pdlin.read_deck(write_yaml(plate_dir / "p.yaml", perilab_deck(mat)))
    assert scene.cloud.dim == 2 and scene.cloud.n == 50
    assert isinstance(scene.model, pdlin.LPS) and scene.model.plane == "strain"
    dofs, vals = pdlin.constraints.resolve_dirichlet(scene.cloud, scene.problem.dirichlet)
    right = np.flatnonzero(scene.cloud.points[:, 0] > 0.7)
    # 0.5 t^2 at Final Time 0.1 (Julia ^ is the power)
    np.testing.assert_allclose(vals[np.isin(dofs, 2 * right)], 0.005, rtol=1e-14)
    r = pdlin.solve(scene.problem)
    assert r.converged and r.reaction(right)[0] > 0
    mat["Material Model"] = "Correspondence Elastic"
    assert isinstance(
        pdlin.read_deck(write_yaml(plate_dir / "p.yaml", perilab_deck(mat))).model,
        pdlin.Correspondence,
    )


@pytest.mark.parametrize(
    "edit, pattern",
    [
        (
            lambda d: d["Models"]["Material Models"]["Mat"].update(
                {"Material Model": "Correspondence Elastic+Correspondence Plastic"}
            ),
            r"Material Model: 'Correspondence Elastic\+Correspondence Plastic' is not supported",
        ),
        (
            lambda d: d["Models"]["Material Models"]["Mat"].update({"Symmetry": "isotropic"}),
            r"Symmetry: 'isotropic' does not fit the 2D mesh",
        ),
        (
            lambda d: d["Models"]["Material Models"]["Mat"].update(
                {"Zero Energy Control": "Global"}
            ),
            r"Zero Energy Control: not supported",
        ),
        (
            lambda d: d["Blocks"]["block_1"].update({"Damage Model": "Damage"}),
            r"Blocks.block_1.Damage Model: damage is not supported",
        ),
        (
            lambda d: d.update({"Solver": {"Final Time": 1e-5, "Verlet": {"Safety Factor": 1.0}}}),
            r"Solver.Verlet: not supported",
        ),
        (
            lambda d: d["Boundary Conditions"]["BC_1"].update({"Variable": "Temperature"}),
            r"BC_1.Variable: only 'Displacements'",
        ),
        (
            lambda d: d["Boundary Conditions"]["BC_1"].update({"Node Set": "Node Set 9"}),
            r"BC_1.Node Set: 'Node Set 9' is not under Discretization.Node Sets",
        ),
        (
            lambda d: d["Boundary Conditions"]["BC_1"].update({"Coordinate": "z"}),
            r"BC_1.Coordinate must be one of 'xy'",
        ),
        (
            lambda d: d.update({"Surface Correction": {"Type": "Volume Correction"}}),
            r"PeriLab.Surface Correction: not supported",
        ),
        (
            lambda d: d["Discretization"]["Node Sets"].update({"Node Set 1": "gone.txt"}),
            r"Node Sets.Node Set 1: file not found",
        ),
    ],
)
def test_perilab_errors_name_the_key(plate_dir, edit, pattern):
    mat = {
        "Material Model": "PD Solid Elastic",
        "Symmetry": "isotropic plane stress",
        "Young's Modulus": 7e5,
        "Poisson's Ratio": 0.33,
    }
    deck = perilab_deck(mat)
    edit(deck["PeriLab"])
    with pytest.raises(SceneError, match=pattern):
        pdlin.read_deck(write_yaml(plate_dir / "p.yaml", deck))


def test_perilab_mesh_header_required(plate_dir):
    (plate_dir / "plate.txt").write_text("0 0 1 0.01\n")
    mat = {
        "Material Model": "PD Solid Elastic",
        "Symmetry": "isotropic plane stress",
        "Young's Modulus": 1.0,
        "Poisson's Ratio": 0.3,
    }
    with pytest.raises(SceneError, match=r"has no 'header: x y ...' line"):
        pdlin.read_deck(write_yaml(plate_dir / "p.yaml", perilab_deck(mat)))


# ---------------------------------------------------------------- CLI
def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    return subprocess.run(
        [sys.executable, "-m", "pdlin", *args], cwd=cwd, env=env, capture_output=True, text=True
    )


def test_cli_runs_yaml_and_xml_decks(bar_dir):
    write_yaml(bar_dir / "deck.yaml", peridigm_deck(LPS_MAT))
    res = _cli("run", "deck.yaml", "-q", "--json", cwd=bar_dir)
    assert res.returncode == 0, res.stderr
    # four load steps: one .vtu per step (the initial state included, in the series' own
    # folder out.pvd.<tag>/) and a .pvd collection
    assert (bar_dir / "out.pvd").exists() and len(list(bar_dir.glob("out.pvd.*/out_0005.vtu"))) == 1
    assert json.loads(res.stdout)["steps"] == 5
    deck = peridigm_deck({**LPS_MAT, "Material Model": "Elastic Plastic"})
    (bar_dir / "bad.xml").write_text(to_xml("Peridigm", deck["Peridigm"]))
    res = _cli("info", "deck.yaml", "--json", cwd=bar_dir)
    assert res.returncode == 0 and '"points": 32' in res.stdout, res.stderr
    res = _cli("run", "bad.xml", "-q", cwd=bar_dir)
    assert res.returncode == 2
    assert "Materials.My Material.Yield Stress (required by 'Elastic Plastic')" in res.stderr


def test_cosmetic_keys_are_logged_not_ignored(bar_dir, caplog):
    deck = peridigm_deck(LPS_MAT)
    deck["Peridigm"]["Output"]["Output Frequency"] = 5
    with caplog.at_level("INFO", logger="pdlin.io.decks"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    text = caplog.text
    for key in (
        "Peridigm.Verbose",
        "Materials.My Material.Density",
        "Solver.QuasiStatic.Number of Load Steps",
        "Output.Output Frequency",
        "Output.Output Variables",
    ):
        assert f"deck key {key} accepted without effect" in text


def test_perilab_solver_switches(plate_dir):
    mat = {
        "Material Model": "Bond-based Elastic",
        "Symmetry": "isotropic plane stress",
        "Young's Modulus": 1.0,
    }
    solver = {"Final Time": 1.0, "Material Models": False, "Static": {}}
    with pytest.raises(SceneError, match=r"Solver.Material Models: false .* is not supported"):
        pdlin.read_deck(write_yaml(plate_dir / "p.yaml", perilab_deck(mat, solver)))
    solver = {"Final Time": 1.0, "Damage Models": True, "Static": {}}
    with pytest.raises(SceneError, match=r"Solver.Damage Models: true is not supported"):
        pdlin.read_deck(write_yaml(plate_dir / "p.yaml", perilab_deck(mat, solver)))
    model = pdlin.read_deck(write_yaml(plate_dir / "p.yaml", perilab_deck(mat))).model
    assert isinstance(model, pdlin.BondBased) and model.plane == "stress"


def test_missing_pyyaml_names_the_extra(bar_dir, monkeypatch):
    write_yaml(bar_dir / "d.yaml", peridigm_deck(LPS_MAT))
    monkeypatch.setitem(sys.modules, "yaml", None)  # import yaml -> ImportError
    with pytest.raises(pdlin.errors.PdlinError, match=r'pip install "pdlin\[decks\]"'):
        pdlin.read_deck(bar_dir / "d.yaml")


def test_legacy_discretization_horizon_and_aliases(bar_dir):
    # early Peridigm decks (examples/tensile_test at 0b2088a) put the horizon under
    # Discretization and named the linear LPS "Linear Elastic"
    deck = peridigm_deck({**LPS_MAT, "Material Model": "Linear Elastic"})
    root = deck["Peridigm"]
    root["Discretization"]["Horizon"] = 0.25
    del root["Blocks"]["My Block"]["Horizon"]
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    assert scene.problem.horizon == 0.25 and isinstance(scene.model, pdlin.LPS)
    del root["Discretization"]["Horizon"]
    with pytest.raises(SceneError, match=r"missing deck key Blocks.My Block.Horizon"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))


@pytest.mark.parametrize("name", ["../../../x", "sub/../../x", "/tmp/pdlin_elsewhere/x"])
def test_deck_output_filename_cannot_leave_the_decks_folder(bar_dir, name):
    """A deck (often someone else's file) writes only inside its own folder."""
    deck = peridigm_deck(dict(LPS_MAT))
    deck["Peridigm"]["Output"]["Output Filename"] = name
    with pytest.raises(SceneError, match=r"Output.Output Filename .* leaves the deck's folder"):
        pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))


def test_deck_output_filename_in_a_subfolder(bar_dir):
    deck = peridigm_deck(dict(LPS_MAT))
    deck["Peridigm"]["Output"]["Output Filename"] = "results/./bar"
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    assert scene.output == bar_dir / "results" / "bar.vtu"


def test_peridigm_deck_without_boundary_conditions(bar_dir):
    # no Boundary Conditions: no constraint and no load; Peridigm's answer is u = 0
    deck = peridigm_deck(LPS_MAT)
    del deck["Peridigm"]["Boundary Conditions"]
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    res = pdlin.solve(scene.problem)
    assert np.array_equal(np.asarray(res.u), np.zeros((32, 3)))
    # a body force alone on an unconstrained body has no static solution: a clean error
    deck["Peridigm"]["Boundary Conditions"] = {
        "Gravity": {"Type": "Body Force", "Node Set": "Full Domain", "Coordinate": "z",
                    "Value": "-1.0"},
    }  # fmt: skip
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck))
    with pytest.raises(pdlin.errors.FloatingBodyError, match="the body is floating"):
        pdlin.solve(scene.problem)


def test_load_steps_are_peridigms_times(bar_dir):
    # Peridigm.cpp executeQuasiStatic: t0 and t0 + (i + 1) (t1 - t0) / N; each step's
    # problem holds that step's prescribed values (Fix X: "0.01 * t" on the right end)
    deck = peridigm_deck(LPS_MAT, solver={"Initial Time": 0.5, "Final Time": 2.0,
                                          "QuasiStatic": {"Number of Load Steps": 3}})  # fmt: skip
    # linearized: one problem per step (finite kinematics: one problem, TimePath values)
    scene = pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck), kinematics="linear")
    times = [t for t, _ in scene.steps]
    assert times == [0.5, 1.0, 1.5, 2.0]  # (2.0 - 0.5) / 3 = 0.5 exactly in binary
    assert scene.steps[-1][1] is scene.problem
    pulled = [np.asarray(p.dirichlet[1].value).ravel() for _, p in scene.steps]  # Pull X
    assert np.allclose([v.max() for v in pulled], [0.001 * t for t in times], rtol=1e-15)
    # one step: no series
    deck["Peridigm"]["Solver"]["QuasiStatic"] = {"Number of Load Steps": 1}
    assert pdlin.read_deck(write_yaml(bar_dir / "d.yaml", deck), kinematics="linear").steps is None
