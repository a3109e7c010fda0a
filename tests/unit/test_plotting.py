"""pdlin plot: the plotted data equals the fields, PNGs are written, errors name the option."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

import pdlin
from pdlin.cli.main import main
from pdlin.errors import InputError
from pdlin.io import read_result, write_homogenized_csv, write_nonlinear, write_result

pytest.importorskip("matplotlib")
import matplotlib.image  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402

from pdlin import plotting  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _plate():
    cloud = pdlin.grid((10, 5), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        cloud,
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", [1e-3, 2e-4])],
    )
    return pdlin.solve(prob, solver="direct")


@pytest.mark.parametrize("suffix", [".vtu", ".npz", ".e", ".xdmf"])
def test_plotted_values_are_the_fields(tmp_path, suffix):
    if suffix == ".e":
        pytest.importorskip("netCDF4")
    if suffix == ".xdmf":
        pytest.importorskip("h5py")
    res = _plate()
    p = write_result(tmp_path / f"plate{suffix}", res)
    u, s = res.u, res.stress().reshape(-1, 4)
    mag = plotting.plot_result(p)
    np.testing.assert_array_equal(mag.values, np.linalg.norm(u, axis=1))
    np.testing.assert_array_equal(mag.points, res.problem.cloud.points)
    assert mag.label == "|displacement|"
    uy = plotting.plot_result(p, component="y")
    np.testing.assert_array_equal(uy.values, u[:, 1])
    sxy = plotting.plot_result(p, field="stress", component="xy")
    np.testing.assert_array_equal(sxy.values, s[:, 1])
    eyy = plotting.plot_result(p, field="strain", component="yy")
    np.testing.assert_array_equal(eyy.values, res.strain()[:, 1, 1])
    # deformed shape: drawn at x + scale u
    dfm = plotting.plot_result(p, component="x", scale=100.0)
    np.testing.assert_allclose(dfm.points, res.problem.cloud.points + 100.0 * u, rtol=1e-15)


def test_png_is_written_atomically_with_the_figure_size(tmp_path):
    res = _plate()
    p = write_result(tmp_path / "plate.vtu", res)
    plot = plotting.plot_result(p, field="reaction", component="x")
    out = plotting.save_figure(plot.figure, tmp_path / "figs" / "r.png", dpi=50)
    img = matplotlib.image.imread(out)
    w, h = plot.figure.get_size_inches() * 50
    assert img.shape[:2] == (round(h), round(w))
    assert sorted(f.name for f in (tmp_path / "figs").iterdir()) == ["r.png"]


def test_slice_of_a_3d_result(tmp_path):
    cloud = pdlin.grid((4, 4, 4), spacing=0.25)  # cell centres 0.125, 0.375, ...
    f = {"damage": np.arange(64.0), "displacement": np.tile([1.0, 2.0, 2.0], (64, 1))}
    p = pdlin.io.write_points(tmp_path / "cube.vtu", cloud, f)
    plot = plotting.plot_result(p, field="damage", slice="z=0.4")  # within h/2 = 0.125 of 0.375
    keep = np.isclose(cloud.points[:, 2], 0.375)
    assert keep.sum() == 16
    np.testing.assert_array_equal(plot.values, np.arange(64.0)[keep])
    np.testing.assert_array_equal(plot.points, cloud.points[keep][:, :2])
    mag = plotting.plot_result(p, slice=("x", 0.125))
    np.testing.assert_allclose(mag.values, 3.0)  # |(1, 2, 2)| = 3
    with pytest.raises(InputError, match=r"slice \(--slice\) is needed for a 3D result"):
        plotting.plot_result(p)
    with pytest.raises(InputError, match=r"z=2 holds no point.*ranges over \[0.125, 0.875\]"):
        plotting.plot_result(p, slice="z=2")
    with pytest.raises(InputError, match=r"must look like 'z=0.5', got 'z0.5'"):
        plotting.plot_result(p, slice="z0.5")
    with pytest.raises(InputError, match=r"field 'damage' is a scalar"):
        plotting.plot_result(p, field="damage", component="x", slice="z=0.4")


def test_one_dimensional_result(tmp_path):
    cloud = pdlin.grid((6,), spacing=0.5)
    u = cloud.points**2
    p = pdlin.io.write_points(tmp_path / "bar.npz", cloud, {"displacement": u})
    plot = plotting.plot_result(p, component="x")
    np.testing.assert_array_equal(plot.values, u[:, 0])
    np.testing.assert_array_equal(plot.points, cloud.points[:, 0])


def test_errors_name_the_option_and_the_choices(tmp_path):
    res = _plate()
    p = write_result(tmp_path / "plate.npz", res)
    with pytest.raises(InputError, match=r"field \(--field\) 'strian'.*available: \['defor"):
        plotting.plot_result(p, field="strian")
    with pytest.raises(
        InputError, match=r"component \(--component\) must be one of \['magnitude', 'x', 'y'\]"
    ):
        plotting.plot_result(p, component="z")
    with pytest.raises(InputError, match=r"must be one of \['xx', 'xy', 'yx', 'yy'\]"):
        plotting.plot_result(p, field="stress", component="zz")
    with pytest.raises(InputError, match=r"step \(--step\) must be an integer in \[-1, 0\]"):
        plotting.plot_result(p, step=1)
    with pytest.raises(
        InputError, match=r"slice \(--slice\) applies to 3D results; this one is 2D"
    ):
        plotting.plot_result(p, slice="z=0")
    with pytest.raises(InputError, match=r"result file must end with one of"):
        read_result(tmp_path / "plate.txt")


def test_series_step_and_homogenized_curve(tmp_path, capsys):
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        pdlin.grid((8, 4), spacing=0.1),
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [1e-3, 0.0])],
    )
    res = pdlin.solve_nonlinear(prob, steps=3, method="newton")
    p = write_nonlinear(tmp_path / "run.pvd", res)
    write_homogenized_csv(tmp_path / "run_homogenized.csv", res)
    plot = plotting.plot_result(p, component="x", step=1)
    np.testing.assert_array_equal(plot.values, res.u[1][:, 0])
    assert "(step 1, t = " in plot.figure.axes[0].get_title()
    curve = plotting.plot_homogenized(tmp_path / "run_homogenized.csv")
    # uniaxial pull along x: sigma_11 is the largest mean stress, the default component
    assert curve.label == "sigma_11"
    # the CSV holds sigma to 10 significant digits; the curve starts at the origin
    np.testing.assert_allclose(curve.values[1:], res.homogenized_stress[:, 0, 0], rtol=1e-9)
    assert curve.values[0] == 0.0 and curve.points[0] == 0.0
    with pytest.raises(InputError, match=r"must be one of \['11', '12', '21', '22'\], got '33'"):
        plotting.plot_homogenized(tmp_path / "run_homogenized.csv", component="33")
    bad = tmp_path / "nan.csv"
    bad.write_text("step,time,factor,sigma_11,F_11\n1,1,1,nan,1.0\n")
    with pytest.raises(InputError, match="holds no finite sigma_11 / F_11 column"):
        plotting.plot_homogenized(bad)
    # the command: the chosen step plus the homogenized curve beside it
    out = tmp_path / "figs" / "u.png"
    assert main(["plot", str(p), "--step", "2", "--component", "x", "-o", str(out)]) == 0
    assert out.is_file() and (tmp_path / "figs" / "u_homogenized.png").is_file()
    assert main(["plot", str(p), "--step", "3"]) == 2
    assert "step (--step) must be an integer in [-3, 2]" in capsys.readouterr().err


def test_convergence_history_from_npz(tmp_path):
    res = _plate()
    p = write_result(tmp_path / "plate.npz", res)
    plot = plotting.plot_convergence(p)
    np.testing.assert_array_equal(plot.values, res.residuals)
    with pytest.raises(InputError, match="stores no residual history"):
        plotting.plot_convergence(write_result(tmp_path / "plate.vtu", res))


def test_spy_and_sparsity_vs_horizon(tmp_path, capsys):
    from tests.test_cli import SCENE

    scene = tmp_path / "plate.toml"
    scene.write_text(SCENE)
    loaded = pdlin.scene.load_scene(scene)
    spy = plotting.plot_scene_spy(scene)
    K = pdlin.assemble_stiffness(loaded.model, loaded.cloud, loaded.bonds())
    assert spy.points.tolist() == [600, K.nnz]
    np.testing.assert_array_equal(spy.values, np.diff(K.tocsr().indptr))
    curve = plotting.plot_sparsity_vs_horizon(scene, [2.0, 3.0])
    # bond-based pattern: one 2 x 2 block per directed bond plus the diagonal block, so
    # the mean over the 2n DOF rows is 2 (1 + bonds / n)
    for m, val in zip([2.0, 3.0], curve.values, strict=True):
        nb = pdlin.find_bonds(loaded.cloud, ratio=m).n_bonds
        assert val == pytest.approx(2 * (1 + nb / 300))
    assert main(["plot", "--spy", str(scene), "-o", str(tmp_path / "spy.png")]) == 0
    assert (tmp_path / "spy.png").is_file()
    assert main(["plot", "--sparsity-vs-horizon", str(scene), "--ratios", "2,3"]) == 0
    assert (tmp_path / "plate_sparsity_vs_horizon.png").is_file()
    assert main(["plot", "--sparsity-vs-horizon", str(scene), "--ratios", "2,x"]) == 2
    assert "--ratios must be comma-separated numbers" in capsys.readouterr().err


def test_files_of_earlier_versions_read_back(tmp_path):
    """Lowercase names and an unpadded 2D stress (VTU written before the ParaView names)."""
    cloud = pdlin.grid((3, 2))
    u3 = np.column_stack([np.arange(6.0), np.ones(6), np.zeros(6)])
    s4 = np.arange(24.0).reshape(6, 4)
    meshio.Mesh(
        np.column_stack([cloud.points, np.zeros(6)]),
        [("vertex", np.arange(6).reshape(-1, 1))],
        point_data={"displacement": u3, "stress": s4, "material": np.zeros(6)},
    ).write(tmp_path / "old.vtu")
    r = read_result(tmp_path / "old.vtu")
    np.testing.assert_array_equal(r.fields()["displacement"], u3[:, :2])
    np.testing.assert_array_equal(r.fields()["stress"], s4)
    np.testing.assert_array_equal(r.fields()["material"], 0.0)  # 0-based already
    plot = plotting.plot_result(r, field="stress", component="yx")
    np.testing.assert_array_equal(plot.values, s4[:, 2])


def test_render_3d_with_pyvista(tmp_path, capsys):
    pytest.importorskip("pyvista")
    cloud = pdlin.grid((4, 3, 2), spacing=0.5)
    u = np.column_stack([cloud.points[:, 0], np.zeros((24, 2))])
    p = pdlin.io.write_points(tmp_path / "box.e", cloud, {"displacement": u})
    out = tmp_path / "box.png"
    plot = plotting.render_result(p, out, component="x", scale=0.5, window_size=(320, 240))
    np.testing.assert_array_equal(plot.values, u[:, 0])
    np.testing.assert_allclose(plot.points, cloud.points + 0.5 * u)
    assert matplotlib.image.imread(out).shape[:2] == (240, 320) == plot.figure.shape[:2]
    assert main(["plot", str(p), "--render", "-o", str(tmp_path / "cli.png")]) == 0
    assert (tmp_path / "cli.png").is_file()
    with pytest.raises(InputError, match=r"field \(--field\) 'nope'"):
        plotting.render_result(p, out, field="nope")
