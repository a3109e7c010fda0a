"""Time-series output (XDMF, VTU + PVD, NPZ, CSV) and atomic writes."""

from __future__ import annotations

import os

import meshio
import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError
from pdlin.io.results import write_homogenized_csv, write_nonlinear, write_points, write_series


def _fields(cloud, k):
    return {"u": (k + 1) * np.ones((cloud.n, 2)), "s": np.arange(cloud.n, dtype=float) * k}


@pytest.mark.parametrize("suffix", [".xdmf", ".pvd", ".npz"])
def test_series_round_trip(tmp_path, suffix):
    cloud = pdlin.grid((4, 3))
    times = [0.5, 1.0, 1.5]
    p = write_series(tmp_path / f"run{suffix}", cloud, times, [_fields(cloud, k) for k in range(3)])
    if suffix == ".xdmf":
        with meshio.xdmf.TimeSeriesReader(str(p)) as reader:
            reader.read_points_cells()
            got = [reader.read_data(k) for k in range(reader.num_steps)]
        assert [g[0] for g in got] == times
        np.testing.assert_allclose(got[2][1]["u"][:, :2], 3.0)
        np.testing.assert_allclose(got[1][1]["s"], np.arange(cloud.n))
    elif suffix == ".pvd":
        text = p.read_text()
        assert text.count("<DataSet") == 3 and 'timestep="1.5"' in text
        (piece,) = tmp_path.glob("run.pvd.*/run_0002.vtu")  # the pieces' versioned folder
        np.testing.assert_allclose(meshio.read(piece).point_data["u"][:, 0], 2)
    else:
        data = np.load(p)
        assert data["u"].shape == (3, cloud.n, 2) and data["times"].tolist() == times
    # nothing but the finished files: no staging directory left behind
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".partial")]


def test_failed_write_leaves_existing_file_untouched(tmp_path):
    cloud = pdlin.grid((4, 3))
    p = write_points(tmp_path / "res.vtu", cloud, {"u": np.ones((cloud.n, 2))})
    before = p.read_bytes()
    with pytest.raises(InputError, match="holds NaN"):
        write_points(p, cloud, {"u": np.full((cloud.n, 2), np.nan)})
    assert p.read_bytes() == before
    steps = [_fields(cloud, 0), {"u": np.full((cloud.n, 2), np.inf), "s": np.zeros(cloud.n)}]
    with pytest.raises(InputError, match="holds NaN or inf"):
        write_series(tmp_path / "run.pvd", cloud, [1.0, 2.0], steps)
    assert sorted(os.listdir(tmp_path)) == ["res.vtu"]


def test_nonlinear_result_series_and_csv(tmp_path):
    cloud = pdlin.grid((10, 5), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        cloud,
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [1e-3, 0.0])],
    )
    res = pdlin.solve_nonlinear(prob, steps=3, method="newton")
    p = write_nonlinear(tmp_path / "run.xdmf", res)
    with meshio.xdmf.TimeSeriesReader(str(p)) as reader:
        reader.read_points_cells()
        t, pd, _ = reader.read_data(2)
    assert t == pytest.approx(1.0)
    np.testing.assert_allclose(pd["Displacement"][:, :2], res.u[2], rtol=1e-12)
    # 2D stress tensors are written as XDMF 3 x 3 tensors
    assert pd["Cauchy_Stress"].shape == (cloud.n, 9)
    np.testing.assert_allclose(pd["Cauchy_Stress"][:, [0, 1, 3, 4]], res.stress[2].reshape(-1, 4))
    c = write_homogenized_csv(tmp_path / "curve.csv", res)
    rows = c.read_text().splitlines()
    assert rows[0].startswith("step,time,factor,sigma_11") and len(rows) == 4
    # proportional loading of a linear model: the mean stress grows linearly
    s11 = [float(r.split(",")[3]) for r in rows[1:]]
    np.testing.assert_allclose(s11, np.array([1, 2, 3]) * s11[0], rtol=1e-9)


POINT_SUFFIXES = [".vtu", ".vtk", ".xdmf", ".npz", ".e", ".exo"]
SERIES_ONLY = [".pvd", ".xdmf", ".npz", ".e"]


@pytest.mark.parametrize("tensor", ["nested", "flat"])
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize(
    ("kind", "suffix"),
    [("points", s) for s in POINT_SUFFIXES] + [("series", s) for s in SERIES_ONLY],
)
def test_every_writer_round_trips_every_field_shape(tmp_path, kind, suffix, dim, tensor):
    """Scalars, vectors and dim x dim tensors ((n, d, d) or (n, d*d)) of 2D and 3D clouds
    read back through read_result with the values written (tensors as (n, d*d) rows)."""
    from pdlin.io import read_result

    if suffix in (".e", ".exo"):
        pytest.importorskip("netCDF4")
    if suffix == ".xdmf":
        pytest.importorskip("h5py")
    cloud = pdlin.grid((5, 5) if dim == 2 else (3, 3, 3))
    rng = np.random.default_rng(dim)
    shape = (cloud.n, dim, dim) if tensor == "nested" else (cloud.n, dim * dim)

    def fields(k):
        return {
            "damage": rng.random(cloud.n) + k,
            "displacement": rng.random((cloud.n, dim)) + k,
            "stress": rng.random(shape) + k,
            "deformation_gradient": rng.random(shape) + k,
        }

    steps = [fields(k) for k in range(2 if kind == "series" else 1)]
    target = tmp_path / f"res{suffix}"
    if kind == "series":
        p = write_series(target, cloud, [0.5, 1.0], steps)
    else:
        p = write_points(target, cloud, steps[0])
    got = read_result(p)
    assert got.n_steps == len(steps)
    np.testing.assert_array_equal(got.points, cloud.points)
    for want, have in zip(steps, got.steps, strict=True):
        for name, arr in want.items():
            # tensors come back as the (n, d*d) rows of result.fields(), values unchanged
            np.testing.assert_allclose(have[name], arr.reshape(cloud.n, -1).squeeze(), rtol=0)
