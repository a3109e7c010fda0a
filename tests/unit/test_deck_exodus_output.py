"""Peridigm decks' Exodus output: Final Time in ``time_whole``, ``Output File Type``,
blank node set names read by id (issue 34)."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from tests.unit.test_decks import (
    LPS_MAT,
    H,
    _cli,
    bar_points,
    peridigm_deck,
    write_text_mesh,
    write_yaml,
)

netCDF4 = pytest.importorskip("netCDF4")


@pytest.fixture
def bar_dir(tmp_path):
    """The 8 x 2 x 2 bar of tests/unit/test_decks.py (its ``bar_dir``), node sets inline."""
    write_text_mesh(tmp_path / "bar.txt", bar_points(), H**3)
    pts = bar_points()
    left = np.flatnonzero(pts[:, 0] < 2 * H) + 1  # 1-based ids (Peridigm node sets)
    right = np.flatnonzero(pts[:, 0] > 6 * H) + 1
    (tmp_path / "left.txt").write_text("\n".join(map(str, left)) + "\n")
    (tmp_path / "right.txt").write_text("\n".join(map(str, right)) + "\n")
    return tmp_path


def _chars(var):
    var.set_auto_mask(False)
    return [b"".join(r).decode().strip("\x00 ") for r in var[:]]


def test_static_deck_writes_final_time_to_exodus(bar_dir):
    """Peridigm writes the final state at Solver.Final Time (D6), not at t = 0."""
    # one load step: one static result (several steps write a series, one time per step)
    one = {"Initial Time": 0.0, "Final Time": 2.0, "QuasiStatic": {"Number of Load Steps": 1}}
    deck = peridigm_deck(dict(LPS_MAT), solver=one)
    scene = pdlin.read_deck(write_yaml(bar_dir / "deck.yaml", deck))
    assert scene.time == 2.0 and scene.steps is None  # the deck's Solver.Final Time
    res = _cli("run", "deck.yaml", "-q", "-o", "final.e", cwd=bar_dir)
    assert res.returncode == 0, res.stderr
    with netCDF4.Dataset(bar_dir / "final.e") as nc:
        np.testing.assert_array_equal(nc["time_whole"][:], [2.0])  # Final Time above
    # four load steps (peridigm_deck's solver): the series ends at Final Time 2.0 too
    write_yaml(bar_dir / "deck.yaml", peridigm_deck(dict(LPS_MAT)))
    res = _cli("run", "deck.yaml", "-q", "-o", "steps.e", cwd=bar_dir)
    assert res.returncode == 0, res.stderr
    with netCDF4.Dataset(bar_dir / "steps.e") as nc:
        # Peridigm's step times t0 + (i + 1)(t1 - t0) / N from 0 to 2.0 in 4 steps
        np.testing.assert_array_equal(nc["time_whole"][:], [0.0, 0.5, 1.0, 1.5, 2.0])
    # the Time Steps list: its last entry is the final time
    deck["Peridigm"]["Solver"] = {
        "Initial Time": 0.0,
        "QuasiStatic": {"Time Steps": "0.0 0.5 1.5"},
    }
    scene = pdlin.read_deck(write_yaml(bar_dir / "deck.yaml", deck))
    assert scene.time == 1.5  # the last entry of Time Steps above


def test_write_result_time_argument(tmp_path):
    cloud = pdlin.grid((4, 3), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3), cloud, horizon=0.3015, dirichlet=[pdlin.Dirichlet("x-", 0.0)]
    )
    res = pdlin.solve(prob, solver="direct")
    p = pdlin.io.write_result(tmp_path / "r.e", res, time=3.5)
    with netCDF4.Dataset(p) as nc:
        np.testing.assert_array_equal(nc["time_whole"][:], [3.5])  # the time given above
    assert pdlin.io.read_result(p).times.tolist() == [3.5]
    with pytest.raises(pdlin.errors.InputError, match=r"time must be finite, got nan"):
        pdlin.io.write_result(tmp_path / "r.e", res, time=float("nan"))


def test_output_file_type_exodusii_writes_exodus(bar_dir):
    """``Output File Type: ExodusII`` (the only type Peridigm writes) -> ``<Output Filename>.e``."""
    deck = peridigm_deck(dict(LPS_MAT))
    deck["Peridigm"]["Output"]["Output File Type"] = "ExodusII"
    scene = pdlin.read_deck(write_yaml(bar_dir / "deck.yaml", deck))
    assert scene.output == bar_dir / "out.e"  # Output Filename "out" of peridigm_deck
    res = _cli("run", "deck.yaml", "-q", cwd=bar_dir)
    assert res.returncode == 0, res.stderr
    assert (bar_dir / "out.e").is_file() and not (bar_dir / "out.vtu").exists()
    with netCDF4.Dataset(bar_dir / "out.e") as nc:
        names = _chars(nc["name_nod_var"])
        # peridigm_deck's four load steps from 0 to its Final Time 2.0
        np.testing.assert_array_equal(nc["time_whole"][:], [0.0, 0.5, 1.0, 1.5, 2.0])
    # Peridigm's field names (docs/output.md)
    assert {"DisplacementX", "Reaction_ForceX", "Volume"} <= set(names)
    # -o (the user's choice) still overrides the deck
    res = _cli("run", "deck.yaml", "-q", "-o", "mine.vtu", cwd=bar_dir)
    assert res.returncode == 0, res.stderr
    assert (bar_dir / "mine.pvd").is_file()  # the four load steps: a .vtu series
    # without Output Filename: the deck's name beside it
    del deck["Peridigm"]["Output"]["Output Filename"]
    scene = pdlin.read_deck(write_yaml(bar_dir / "deck.yaml", deck))
    assert scene.output == bar_dir / "deck.e"


@pytest.mark.parametrize("kind", ["VTK", "Exodus", 3])
def test_unknown_output_file_type_is_refused(bar_dir, kind):
    deck = peridigm_deck(dict(LPS_MAT))
    deck["Peridigm"]["Output"]["Output File Type"] = kind
    with pytest.raises(
        pdlin.errors.SceneError, match=r"Output.Output File Type must be 'ExodusII', got"
    ):
        pdlin.read_deck(write_yaml(bar_dir / "deck.yaml", deck))


def test_read_exodus_file_names_blank_node_sets_by_id(tmp_path):
    """Blank ``ns_names`` -> ``nodelist_<ns_prop1 id>`` (Peridigm_ExodusDiscretization.cpp);
    they used to collapse into one set ''."""
    from pdlin.io.exodus import read_exodus_file

    cloud = pdlin.grid((4, 3), spacing=0.1)
    p = pdlin.io.write_points(tmp_path / "r.e", cloud, {"u": np.zeros((cloud.n, 2))})
    with netCDF4.Dataset(p, "a") as nc:
        names = _chars(nc["ns_names"])
        n_sets = len(names)
        ids = 10 * np.arange(n_sets, 0, -1)  # ids in reverse of the file order
        nc["ns_prop1"][:] = ids
        blank = nc["ns_names"][:]
        blank[:] = b""
        blank[0, :5] = np.frombuffer(b"named", dtype="S1")  # the first set keeps a name
        nc["ns_names"][:] = blank
    sets = read_exodus_file(p)["sets"]
    expected = ["named"] + [f"nodelist_{i}" for i in ids[1:]]
    assert sorted(sets) == sorted(expected)
    for k, name in enumerate(expected):  # each set keeps its own nodes (file order k)
        np.testing.assert_array_equal(sets[name], cloud.sets[names[k]])
    assert set(pdlin.io.read_result(p).sets) == set(expected)
    # two sets of one name cannot both be kept
    with netCDF4.Dataset(p, "a") as nc:
        nc["ns_prop1"][:] = 7
        nc["ns_names"][:] = b""
    with pytest.raises(pdlin.errors.InputError, match=r"two node sets named 'nodelist_7'"):
        read_exodus_file(p)
