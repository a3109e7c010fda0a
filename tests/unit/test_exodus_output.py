"""Exodus II output (.e / .exo): read back with netCDF4 directly, meshio, VTK and pdlin."""

from __future__ import annotations

import logging
import os
import sys

import meshio
import numpy as np
import pytest

import pdlin
from pdlin.cli.main import main
from pdlin.errors import InputError
from pdlin.io import read_result, write_nonlinear, write_points, write_result, write_series

netCDF4 = pytest.importorskip("netCDF4")


def _chars(var):
    var.set_auto_mask(False)
    return [b"".join(r).decode().strip("\x00 ") for r in var[:]]


def _problem(shape=(10, 5)):
    cloud = pdlin.grid(shape, spacing=0.1)
    return pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        cloud,
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", [1e-3, 2e-4])],
    )


def test_static_result_raw_netcdf_layout(tmp_path):
    res = pdlin.solve(_problem(), solver="direct")
    cloud = res.problem.cloud
    f = res.fields()
    p = write_result(tmp_path / "plate.e", res)
    with netCDF4.Dataset(p) as nc:
        # Peridigm-like layout: 3 coordinates, one SPHERE element per point, one block
        assert len(nc.dimensions["num_dim"]) == 3 and len(nc.dimensions["num_nodes"]) == 50
        assert len(nc.dimensions["num_elem"]) == 50
        np.testing.assert_array_equal(nc["coordx"][:], cloud.points[:, 0])
        np.testing.assert_array_equal(nc["coordy"][:], cloud.points[:, 1])
        np.testing.assert_array_equal(nc["coordz"][:], 0.0)
        assert _chars(nc["coor_names"]) == ["X", "Y", "Z"]
        np.testing.assert_array_equal(nc["time_whole"][:], [0.0])  # a static result: t = 0
        assert nc["connect1"].elem_type == "SPHERE"
        np.testing.assert_array_equal(nc["connect1"][:].ravel(), np.arange(1, 51))
        assert nc["eb_prop1"][:].tolist() == [1] and nc["eb_prop1"].getncattr("name") == "ID"
        names = _chars(nc["name_nod_var"])
        # the field table of docs/output.md: vectors X/Y/Z, symmetric tensors the 6
        # components VTK groups, the non-symmetric deformation gradient all 9
        sym = ["XX", "YY", "ZZ", "XY", "XZ", "YZ"]
        full = [a + b for a in "XYZ" for b in "XYZ"]
        assert names == (
            ["DisplacementX", "DisplacementY", "DisplacementZ"]
            + ["Reaction_ForceX", "Reaction_ForceY", "Reaction_ForceZ"]
            + ["Number_Of_Neighbors", "Volume", "Block_Id"]
            + ["Deformation_Gradient" + c for c in full]
            + ["Strain" + c for c in sym]
            + ["Cauchy_Stress" + c for c in sym]
        )

        def var(name):
            return nc[f"vals_nod_var{names.index(name) + 1}"][:]

        assert var("DisplacementX").shape == (1, 50)
        np.testing.assert_array_equal(var("DisplacementX")[0], f["displacement"][:, 0])
        np.testing.assert_array_equal(var("DisplacementY")[0], f["displacement"][:, 1])
        np.testing.assert_array_equal(var("DisplacementZ")[0], 0.0)
        np.testing.assert_array_equal(var("Reaction_ForceY")[0], f["reaction"][:, 1])
        np.testing.assert_array_equal(var("Volume")[0], cloud.volumes)
        np.testing.assert_array_equal(var("Block_Id")[0], 1.0)  # phase 0 -> Peridigm block 1
        np.testing.assert_array_equal(var("Number_Of_Neighbors")[0], f["family_size"])
        F = f["deformation_gradient"].reshape(-1, 2, 2)
        np.testing.assert_array_equal(var("Deformation_GradientYX")[0], F[:, 1, 0])
        np.testing.assert_array_equal(var("Deformation_GradientZZ")[0], 0.0)
        S = f["stress"].reshape(-1, 2, 2)
        np.testing.assert_array_equal(var("Cauchy_StressXY")[0], S[:, 0, 1])
        np.testing.assert_array_equal(var("StrainYY")[0], f["strain"][:, 3])
        # point sets as node sets, 1-based node ids
        assert _chars(nc["ns_names"]) == list(cloud.sets)
        for k, name in enumerate(cloud.sets, start=1):
            np.testing.assert_array_equal(nc[f"node_ns{k}"][:], cloud.sets[name] + 1)
        assert nc["ns_prop1"][:].tolist() == list(range(1, len(cloud.sets) + 1))
    # pdlin's reader gives every field back exactly, under the API keys and shapes
    r = read_result(p)
    assert r.dim == 2 and r.n_steps == 1
    np.testing.assert_array_equal(r.points, cloud.points)
    got = r.fields()
    assert set(got) == set(f)
    for key, val in f.items():
        np.testing.assert_array_equal(got[key], val, err_msg=key)
    assert {k: v.tolist() for k, v in r.sets.items()} == {
        k: v.tolist() for k, v in cloud.sets.items()
    }


def test_meshio_reads_the_exodus_file(tmp_path):
    res = pdlin.solve(_problem(), solver="direct")
    p = write_result(tmp_path / "plate.exo", res)
    mesh = meshio.read(p)
    np.testing.assert_array_equal(mesh.points[:, :2], res.problem.cloud.points)
    # meshio groups the X/Y/Z components into one vector
    np.testing.assert_array_equal(mesh.point_data["Displacement"][:, :2], res.u)
    np.testing.assert_array_equal(mesh.point_data["Volume"], res.problem.cloud.volumes)
    assert mesh.cells[0].type == "vertex" and len(mesh.cells[0].data) == 50
    assert set(mesh.point_sets) == set(res.problem.cloud.sets)
    np.testing.assert_array_equal(mesh.point_sets["x+"], res.problem.cloud.sets["x+"])


def test_phases_become_element_blocks_and_empty_sets_null_node_sets(tmp_path):
    pts = pdlin.grid((4, 3)).points
    material = np.array([1, 0, 2, 1, 0, 2, 1, 0, 2, 1, 0, 2])
    sets = {"left": np.array([0, 1, 2]), "none": np.array([], dtype=int)}
    cloud = pdlin.PointCloud(pts, np.ones(12), material=material, sets=sets)
    p = write_points(tmp_path / "phases.e", cloud, {"damage": np.linspace(0, 1, 12)})
    with netCDF4.Dataset(p) as nc:
        assert nc["eb_prop1"][:].tolist() == [1, 2, 3]  # phases 0, 1, 2
        assert _chars(nc["eb_names"]) == ["block_1", "block_2", "block_3"]
        for b, phase in enumerate([0, 1, 2], start=1):
            conn = nc[f"connect{b}"][:].ravel() - 1
            np.testing.assert_array_equal(conn, np.flatnonzero(material == phase))
        # element k of the block-ordered numbering maps back to its point
        np.testing.assert_array_equal(
            nc["elem_num_map"][:] - 1, np.argsort(material, kind="stable")
        )
        # an empty set: a null node set (status 0, no node list), as the Exodus library writes
        assert nc["ns_status"][:].tolist() == [1, 0] and "node_ns2" not in nc.variables
    r = read_result(p)
    np.testing.assert_array_equal(r.fields()["damage"], np.linspace(0, 1, 12))
    assert r.sets["none"].size == 0 and r.sets["left"].tolist() == [0, 1, 2]


def test_nonlinear_series_in_one_file(tmp_path):
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        pdlin.grid((8, 4), spacing=0.1),
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [1e-3, 0.0])],
    )
    res = pdlin.solve_nonlinear(prob, steps=3, method="newton")
    p = write_nonlinear(tmp_path / "run.e", res)
    assert sorted(os.listdir(tmp_path)) == ["run.e"]  # one file, no companions
    with netCDF4.Dataset(p) as nc:
        np.testing.assert_array_equal(nc["time_whole"][:], res.times)
        names = _chars(nc["name_nod_var"])
        ux = nc[f"vals_nod_var{names.index('DisplacementX') + 1}"][:]
        assert ux.shape == (3, 32)
        np.testing.assert_array_equal(ux, res.u[:, :, 0])
    r = read_result(p)
    np.testing.assert_array_equal(r.times, res.times)
    for k in range(3):
        np.testing.assert_array_equal(r.steps[k]["displacement"], res.u[k])
        np.testing.assert_array_equal(r.steps[k]["reaction"], res.reactions[k])
        np.testing.assert_array_equal(r.steps[k]["stress"], res.stress[k].reshape(32, 4))


def test_vtk_exodus_reader_groups_vectors_and_tensors(tmp_path):
    """ParaView's reader (VTK's vtkExodusIIReader): vectors, tensors, steps, node sets."""
    pytest.importorskip("vtkmodules.vtkIOExodus")
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOExodus import vtkExodusIIReader

    cloud = pdlin.grid((4, 3))
    F = np.tile([1.0, 0.1, 0.0, 1.0], (12, 1))
    steps = [
        {"displacement": k * np.arange(24.0).reshape(12, 2), "stress": np.ones((12, 4)), "F": F}
        for k in (1, 2)
    ]
    steps = [{**s, "deformation_gradient": s.pop("F")} for s in steps]
    p = write_series(tmp_path / "run.e", cloud, [0.5, 1.0], steps)
    rd = vtkExodusIIReader()
    rd.SetFileName(str(p))
    rd.UpdateInformation()
    nodal = vtkExodusIIReader.NODAL
    names = [rd.GetObjectArrayName(nodal, i) for i in range(rd.GetNumberOfObjectArrays(nodal))]
    assert {"Displacement", "Cauchy_Stress", "Volume"} <= set(names)
    # the non-symmetric deformation gradient shows as its three rows
    assert {"Deformation_GradientX", "Deformation_GradientY"} <= set(names)
    assert rd.GetTimeStepRange() == (0, 1)
    ns = vtkExodusIIReader.NODE_SET
    assert [rd.GetObjectName(ns, i) for i in range(rd.GetNumberOfObjects(ns))] == list(cloud.sets)
    rd.SetAllArrayStatus(nodal, 1)
    rd.SetTimeStep(1)
    rd.Update()
    block = rd.GetOutput().GetBlock(0).GetBlock(0)
    pd = block.GetPointData()
    disp = vtk_to_numpy(pd.GetArray("Displacement"))
    np.testing.assert_array_equal(disp[:, :2], steps[1]["displacement"])
    assert pd.GetArray("Cauchy_Stress").GetNumberOfComponents() == 6
    # the reader recognizes "Displacement" and shows the deformed points by default
    pts = vtk_to_numpy(block.GetPoints().GetData())[:, :2]
    np.testing.assert_allclose(pts, cloud.points + steps[1]["displacement"], rtol=1e-6)
    rd.ApplyDisplacementsOff()
    rd.Update()
    pts = vtk_to_numpy(rd.GetOutput().GetBlock(0).GetBlock(0).GetPoints().GetData())[:, :2]
    np.testing.assert_allclose(pts, cloud.points, rtol=1e-6)


def test_run_command_writes_exodus(tmp_path, capsys):
    from tests.test_cli import SCENE

    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    out = tmp_path / "plate.e"
    assert main(["run", str(scene), "-o", str(out), "-q", "--json"]) == 0
    assert '"output": "' + str(out) in capsys.readouterr().out
    res = pdlin.solve(pdlin.scene.load_scene(scene).problem, solver="direct")
    r = read_result(out)
    np.testing.assert_allclose(r.fields()["displacement"], res.u, rtol=1e-10)
    # the reaction on the loaded set balances the applied 1000 N (SCENE)
    np.testing.assert_allclose(r.fields()["reaction"][:, 0].sum(), -1000.0, rtol=1e-8)


def test_exodus_failures_leave_nothing_behind(tmp_path, monkeypatch, caplog):
    cloud = pdlin.grid((4, 3))
    p = write_points(tmp_path / "r.e", cloud, {"u": np.ones((12, 2))})
    before = p.read_bytes()
    with pytest.raises(InputError, match="holds NaN"):
        write_points(p, cloud, {"u": np.full((12, 2), np.nan)})
    # steps with different fields cannot be Exodus nodal variables
    with pytest.raises(InputError, match="same fields in every step.*step 1 has"):
        write_series(tmp_path / "r.e", cloud, [1.0, 2.0], [{"u": np.ones(12)}, {"v": np.ones(12)}])
    assert p.read_bytes() == before and sorted(os.listdir(tmp_path)) == ["r.e"]
    # without netCDF4 the error names the extra to install
    monkeypatch.setitem(sys.modules, "netCDF4", None)
    with pytest.raises(ImportError, match=r"pdlin\[exodus\]"):
        write_points(tmp_path / "s.e", cloud, {"u": np.ones(12)})
    assert sorted(os.listdir(tmp_path)) == ["r.e"]


def test_partial_states_are_dropped_with_a_warning(tmp_path, caplog):
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        pdlin.grid((6, 3), spacing=0.1),
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [1e-3, 0.0])],
    )
    res = pdlin.solve_nonlinear(prob, steps=2, method="newton")
    # fake a committed state kept for the last step only (keep_states=False)
    res.states = [{"gamma": np.ones(18)}]
    res.state_steps = [1]
    with caplog.at_level(logging.WARNING):
        p = write_nonlinear(tmp_path / "run.e", res)
    assert "['state_gamma'] kept for only some steps" in caplog.text
    assert "state_gamma" not in read_result(p).fields()
    q = write_nonlinear(tmp_path / "run.npz", res)
    assert q.exists()


def test_bad_suffix_names_exodus():
    with pytest.raises(InputError, match=r"'\.e', '\.exo'"):
        write_points("x.exodus", pdlin.grid((2, 2)), {})


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("suffix", [".e", ".vtu", ".pvd", ".xdmf", ".npz"])
def test_every_format_round_trips_every_field_exactly(tmp_path, dim, suffix):
    if suffix == ".xdmf":
        pytest.importorskip("h5py")
    shape = {1: (7,), 2: (4, 3), 3: (3, 2, 2)}[dim]
    cloud = pdlin.grid(shape, spacing=0.5)
    n = cloud.n
    rng = np.random.default_rng(dim)
    sym = rng.random((n, dim, dim))
    sym = sym + sym.transpose(0, 2, 1)
    steps = [
        {
            "displacement": rng.random((n, dim)),
            "reaction": rng.random((n, dim)),
            "stress": sym.reshape(n, -1) * (k + 1),
            "deformation_gradient": rng.random((n, dim * dim)),
            "damage": rng.random(n),
            "material": np.zeros(n),
        }
        for k in range(2)
    ]
    times = [0.25, 1.0]
    p = write_series(tmp_path / f"s{suffix}", cloud, times, steps)
    r = read_result(p)
    assert r.dim == dim and r.times.tolist() == times
    np.testing.assert_array_equal(r.points, cloud.points)
    for k in range(2):
        for key, val in steps[k].items():
            np.testing.assert_array_equal(r.steps[k][key], val, err_msg=f"{key} step {k}")


def _peridigm_like_file(path):
    """A small Exodus file laid out as Peridigm writes one (written here with netCDF4 alone):
    3 coordinates, two SPHERE blocks, vectors as nodal ``<Name>X/Y/Z``, scalars as element
    variables per block (``vals_elem_var<j>eb<b>``), one node set, two steps."""
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 1]])
    with netCDF4.Dataset(path, "w", format="NETCDF3_64BIT_OFFSET") as nc:
        nc.title = "Peridigm"
        for d, s in [("len_name", 33), ("time_step", None), ("num_dim", 3), ("num_nodes", 4)]:
            nc.createDimension(d, s)
        for d, s in [("num_elem", 4), ("num_el_blk", 2), ("num_node_sets", 1)]:
            nc.createDimension(d, s)
        nc.createVariable("time_whole", "f8", ("time_step",))[:] = [0.0, 0.5]
        for k, c in enumerate("xyz"):
            nc.createVariable(f"coord{c}", "f8", ("num_nodes",))[:] = pts[:, k]
        nc.createVariable("eb_prop1", "i4", ("num_el_blk",))[:] = [1, 2]
        for b, nodes in [(1, [1, 3]), (2, [2, 4])]:
            nc.createDimension(f"num_el_in_blk{b}", 2)
            nc.createDimension(f"num_nod_per_el{b}", 1)
            v = nc.createVariable(f"connect{b}", "i4", (f"num_el_in_blk{b}", f"num_nod_per_el{b}"))
            v.elem_type = "SPHERE"
            v[:] = np.array(nodes).reshape(-1, 1)
        names = netCDF4.stringtochar(
            np.array([b"DisplacementX", b"DisplacementY", b"DisplacementZ"], "S33")
        )
        nc.createDimension("num_nod_var", 3)
        nc.createVariable("name_nod_var", "S1", ("num_nod_var", "len_name"))[:] = names
        for j in range(3):
            v = nc.createVariable(f"vals_nod_var{j + 1}", "f8", ("time_step", "num_nodes"))
            v[:] = [np.zeros(4), 0.1 * (j + 1) * np.arange(4)]
        nc.createDimension("num_elem_var", 2)
        enames = netCDF4.stringtochar(np.array([b"Volume", b"Damage"], "S33"))
        nc.createVariable("name_elem_var", "S1", ("num_elem_var", "len_name"))[:] = enames
        for b, nodes in [(1, [0, 2]), (2, [1, 3])]:
            v = nc.createVariable(f"vals_elem_var1eb{b}", "f8", ("time_step", f"num_el_in_blk{b}"))
            v[:] = [[0.25, 0.25]] * 2
            v = nc.createVariable(f"vals_elem_var2eb{b}", "f8", ("time_step", f"num_el_in_blk{b}"))
            v[:] = [[0.0, 0.0], [0.1 * nodes[0], 0.1 * nodes[1]]]
        nc.createDimension("num_nod_ns1", 2)
        nc.createVariable("ns_names", "S1", ("num_node_sets", "len_name"))[:] = (
            netCDF4.stringtochar(np.array([b"min_x"], "S33"))
        )
        nc.createVariable("node_ns1", "i4", ("num_nod_ns1",))[:] = [1, 3]
    return pts


def test_reads_a_peridigm_style_exodus_file(tmp_path):
    p = tmp_path / "peridigm.e"
    pts = _peridigm_like_file(p)
    r = read_result(p)
    assert r.dim == 3 and r.times.tolist() == [0.0, 0.5]
    np.testing.assert_array_equal(r.points, pts)
    u = r.steps[1]["displacement"]
    np.testing.assert_allclose(u, 0.1 * np.outer(np.arange(4), [1, 2, 3]))
    # element variables of the sphere blocks land on their points
    np.testing.assert_array_equal(r.steps[1]["volume"], 0.25)
    np.testing.assert_allclose(r.steps[1]["damage"], 0.1 * np.arange(4))
    assert r.sets["min_x"].tolist() == [0, 2]
