"""meshio point clouds of ``vertex`` cells (Peridigm-style clouds) as pdlin clouds (issue 34):
the volume from a point field or the ``volume`` option."""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest

import pdlin
from pdlin.cli.main import main
from pdlin.errors import InputError
from pdlin.geometry.mesh import read_mesh


def _cloud_mesh(pts, **kw):
    n = len(pts)
    return meshio.Mesh(pts, [("vertex", np.arange(n).reshape(-1, 1))], **kw)


def test_pdlin_vtu_output_reads_back_as_the_cloud(tmp_path):
    """pdlin's own .vtu (vertex cells + a ``Volume`` point field, as Peridigm names it)."""
    cloud = pdlin.grid((4, 3, 2), spacing=0.5)
    p = pdlin.io.write_points(tmp_path / "c.vtu", cloud, {"u": np.zeros((cloud.n, 3))})
    back = read_mesh(p)
    assert back.dim == 3
    np.testing.assert_array_equal(back.points, cloud.points)
    np.testing.assert_array_equal(back.volumes, cloud.volumes)
    # a 2D cloud is padded with z = 0 in the file: read back as 2D
    cloud2 = pdlin.grid((4, 3), spacing=0.5)
    p = pdlin.io.write_points(tmp_path / "c2.vtu", cloud2, {})
    back = read_mesh(p)
    assert back.dim == 2
    np.testing.assert_array_equal(back.points, cloud2.points)
    np.testing.assert_array_equal(back.volumes, cloud2.volumes)
    assert read_mesh(p, dim=3).dim == 3  # dim= keeps the constant z


def test_volume_option_field_name_and_sets():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    mesh = _cloud_mesh(
        pts,
        point_data={"vol": np.array([1.0, 2, 3, 4])},
        cell_sets={"first_two": [np.array([0, 1])]},
    )
    mesh.point_sets = {"top": np.array([3])}
    c = read_mesh(mesh, volume="vol")
    np.testing.assert_array_equal(c.volumes, [1.0, 2, 3, 4])  # the "vol" field above
    assert c.sets["first_two"].tolist() == [0, 1] and c.sets["top"].tolist() == [3]
    c = read_mesh(mesh, volume=0.25)
    np.testing.assert_array_equal(c.volumes, 0.25)  # the constant given
    with pytest.raises(
        InputError, match=r"dim=2: .* beyond xy must be constant, got a spread of 1"
    ):
        read_mesh(mesh, volume=0.25, dim=2)  # z spans 0..1 above
    # a cloud without any cells: every mesh point
    c = read_mesh(meshio.Mesh(pts, []), volume=0.5)
    assert c.n == 4 and c.dim == 3


@pytest.mark.parametrize(
    ("kwargs", "point_data", "pattern"),
    [
        ({}, {}, r"point cloud .* needs a volume per point: a 'Volume' / 'volume' point field"),
        ({"volume": "V"}, {}, r"volume: point field 'V' not found; point fields: none"),
        ({}, {"Volume": [1.0, -1, 1, 1]}, r"'Volume' must be > 0 and finite, got -1.0 at point 1"),
        ({}, {"Volume": [1.0, np.nan, 1, 1]}, r"'Volume' must be > 0 and finite, got nan"),
        (
            {},
            {"Volume": np.ones((4, 2))},
            r"'Volume' must hold one value per point \(4\)",
        ),
        ({"volume": -2.0}, {}, r"volume must be > 0 and finite, got -2.0"),
        ({"volume": True}, {}, r"volume must be a number or a point field name, got True"),
    ],
)
def test_bad_point_cloud_volumes_are_refused(kwargs, point_data, pattern):
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    mesh = _cloud_mesh(pts, point_data={k: np.asarray(v) for k, v in point_data.items()})
    with pytest.raises(InputError, match=pattern):
        read_mesh(mesh, **kwargs)


def test_volume_option_on_a_mesh_of_cells_is_refused():
    mesh = meshio.Mesh(np.array([[0.0, 0], [1, 0], [0, 1]]), [("triangle", [[0, 1, 2]])])
    with pytest.raises(InputError, match=r"volume is for point clouds .* got a mesh of triangle"):
        read_mesh(mesh, volume=1.0)


def test_info_and_scene_read_point_cloud_files(tmp_path, capsys):
    pts = pdlin.grid((5, 4), spacing=0.1).points
    _cloud_mesh(np.column_stack([pts, np.zeros(len(pts))])).write(tmp_path / "c.vtu")
    assert main(["info", str(tmp_path / "c.vtu"), "--volume", "0.01", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["points"] == 20 and info["dim"] == 2
    assert info["total_volume"] == pytest.approx(0.2)  # 20 points x 0.01
    assert main(["info", str(tmp_path / "c.vtu")]) == 2
    assert "needs a volume per point" in capsys.readouterr().err
    scene = tmp_path / "s.toml"
    scene.write_text(
        '[geometry]\ntype = "mesh"\npath = "c.vtu"\nvolume = 0.01\n'
        '[material]\nE = 1.0\nnu = 0.25\nplane = "stress"\n[horizon]\nratio = 3.015\n'
    )
    cloud = pdlin.scene.load_scene(scene).cloud
    np.testing.assert_array_equal(cloud.volumes, 0.01)  # geometry.volume above
