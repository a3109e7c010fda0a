"""Hostile input: Peridigm / PeriLab decks (files, expressions, XML entities, types)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hostile_util import expect

import pdlin
from pdlin.errors import SceneError

yaml = pytest.importorskip("yaml")

POINTS = "\n".join(f"{0.1 * i + 0.05} 0.05 0.05 1 0.001" for i in range(6))


def _deck(**edits: object) -> dict:
    deck = {
        "Discretization": {"Type": "Text File", "Input Mesh File": "p.txt"},
        "Materials": {"M": {"Material Model": "Elastic Bond Based", "Bulk Modulus": 1.0}},
        "Blocks": {"B": {"Block Names": "block_1", "Material": "M", "Horizon": 0.21}},
        "Boundary Conditions": {
            "Node Set A": "1 2",
            "Fix": {"Type": "Prescribed Displacement", "Node Set": "Node Set A", "Value": "0"},
        },
        "Solver": {"Final Time": 1.0, "QuasiStatic": {}},
    }
    for path, value in edits.items():
        *parents, last = path.split("__")
        t: dict = deck
        for k in parents:
            t = t[k]
        t[last] = value
    return {"Peridigm": deck}


def _run(tmp: Path, deck: object, points: str = POINTS, name: str = "d.yaml") -> None:
    (tmp / "p.txt").write_text(points)
    (tmp / name).write_text(yaml.safe_dump(deck) if not isinstance(deck, str) else deck)
    pdlin.read_deck(tmp / name)


def _fix(value: object) -> dict:
    """The deck with the prescribed value of its one boundary condition replaced."""
    bc = {"Type": "Prescribed Displacement", "Node Set": "Node Set A", "Value": value}
    return _deck(**{"Boundary Conditions__Fix": bc})


def _nodes(value: object) -> dict:
    return _deck(**{"Boundary Conditions__Node Set A": value})


BB = {"Material Model": "Elastic Bond Based"}
CASES = [
    ("nan-coordinate", _deck(), "nan 0 0 1 0.001\n", r"Mesh File: points must be finite"),
    ("negative-volume", _deck(), "0 0 0 1 -0.001\n", r"Mesh File: volumes must be > 0"),
    ("inf-volume", _deck(), "0 0 0 1 inf\n", r"Mesh File: volumes must be finite"),
    ("float-block-id", _deck(), "0 0 0 1.5 0.001\n", r"non-integer block ids"),
    ("binary-mesh", _deck(), "\x00\x01\x02 3 4 5 6\n", r"line 1 is not numbers"),
    ("empty-deck", "", POINTS, r"one top-level list, 'Peridigm' or 'PeriLab', got NoneType"),
    ("list-deck", "- 1\n- 2\n", POINTS, r"got list"),
    ("bad-yaml", "Peridigm: [unclosed\n", POINTS, r"invalid YAML"),
    ("section-not-table", _deck(Solver=3), POINTS, r"Solver must be a list of parameters, got int"),
    ("horizon-bool", _deck(Blocks__B__Horizon=True), POINTS, r"Horizon must be a number, got True"),
    (
        "horizon-nan",
        _deck(Blocks__B__Horizon=float("nan")),
        POINTS,
        r"Horizon must be > 0, got nan",
    ),
    (
        "modulus-string",
        # a string that is not a number ("1e9" itself is one, as Teuchos reads it)
        _deck(Materials__M={**BB, "Bulk Modulus": "1e9 Pa"}),
        POINTS,
        r"Materials.M.Bulk Modulus must be a number, got '1e9 Pa'",
    ),
    ("node-ids-float", _nodes("1.5 2"), POINTS, r"Node Set A: file not found"),
    ("node-ids-negative", _nodes("-1 2"), POINTS, r"node ids are 1-based"),
    ("node-set-dict", _nodes({"a": 1}), POINTS, r"Node Set A must be a node-set file name or a"),
    ("value-list", _fix([1, 2]), POINTS, r"Fix.Value must be a number or an expression string"),
    ("value-huge-power", _fix("10**10**10"), POINTS, r"Fix.Value: (cannot evaluate|expression)"),
    ("value-deep", _fix("(" * 5000 + "x" + ")" * 5000), POINTS, r"Fix.Value: cannot parse"),
    ("value-dunder", _fix("x.__class__"), POINTS, r"Fix.Value: unsupported construct Attribute"),
    (
        "value-nan",
        _fix("sqrt(-1.0)"),
        POINTS,
        r"Fix.Value: expression 'sqrt\(-1.0\)' is not finite",
    ),
    ("bc-not-table", _deck(**{"Boundary Conditions__Fix": "x"}), POINTS, r"Fix must be a list of"),
    ("mesh-key-typo", _deck(Discretization__Mesh_File="x"), POINTS, r"Mesh_File: not supported"),
    (
        "mesh-file-directory",
        _deck(**{"Discretization__Input Mesh File": ".."}),
        POINTS,
        r"Input Mesh File: is not a file",
    ),
]


QG = {"X Origin": 0.0, "Y Origin": 0.0, "Z Origin": 0.0, "X Length": 0.6, "Y Length": 0.1}
QG |= {"Z Length": 0.1, "Number Points X": 6, "Number Points Y": 1, "Number Points Z": 1}


def _qg(edits: dict | None = None, **disc: object) -> dict:
    """A PdQuickGrid deck (6 x 1 x 1 cells) with generator keys / discretization keys changed."""
    gen = {k: v for k, v in {**QG, **(edits or {})}.items() if v is not None}
    d = {"Type": "PdQuickGrid", "NeighborhoodType": "Spherical"}
    d |= {"TensorProduct3DMeshGenerator": gen, **disc}
    return _deck(Discretization={k: v for k, v in d.items() if v is not None})


CASES += [
    ("qg-no-norm", _qg(NeighborhoodType=None), POINTS, r"NeighborhoodType must be 'Spherical'"),
    ("qg-cylinder", _qg(TensorProduct3DMeshGenerator=None, TensorProductCylinderMeshGenerator={}),
     # the cylinder generator is read now (issue 34): an empty one names its first missing key
     POINTS, r"missing deck key .*TensorProductCylinderMeshGenerator\.Inner Radius"),
    ("qg-zero-points", _qg({"Number Points X": 0}), POINTS, r"Number Points X must be an integer"),
    ("qg-float-points", _qg({"Number Points Y": 2.5}), POINTS, r"Number Points Y must be an int"),
    ("qg-negative-length", _qg({"Z Length": -1.0}), POINTS, r"Z Length must be > 0, got -1.0"),
    ("qg-missing-origin", _qg({"X Origin": None}), POINTS, r"missing deck key .*\.X Origin"),
    ("qg-typo", _qg({"X Lenght": 1.0}), POINTS, r"Generator\.X Lenght: not supported"),
    ("qg-bond-filters", _qg(**{"Bond Filters": {}}), POINTS, r"Bond Filters: Peridigm does not"),
]  # fmt: skip


@pytest.mark.parametrize("name, deck, points, pattern", CASES, ids=[c[0] for c in CASES])
def test_hostile_decks(tmp_path, name, deck, points, pattern):
    expect(lambda: _run(tmp_path, deck, points), SceneError, pattern)


def test_xml_external_entity_is_not_resolved(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("do not read")
    (tmp_path / "d.xml").write_text(
        f'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY e SYSTEM "file://{secret}">]>'
        '<ParameterList><Parameter name="Verbose" type="string" value="&e;"/></ParameterList>'
    )
    expect(lambda: pdlin.read_deck(tmp_path / "d.xml"), SceneError, r"invalid XML")


def test_xml_bool_and_root(tmp_path):
    (tmp_path / "d.xml").write_text(
        # Teuchos reads true / yes / 1 and false / no / 0 (any case); nothing else
        '<ParameterList><Parameter name="Verbose" type="bool" value="maybe"/></ParameterList>'
    )
    expect(
        lambda: pdlin.read_deck(tmp_path / "d.xml"),
        SceneError,
        r"Peridigm.Verbose: 'maybe' is not a valid bool",
    )
    (tmp_path / "d.xml").write_text("<Deck/>")
    expect(lambda: pdlin.read_deck(tmp_path / "d.xml"), SceneError, r"root element must be")
