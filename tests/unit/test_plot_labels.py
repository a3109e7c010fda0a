"""Plots carry units on their axes and colour bars, and a 3D slice is named in the title."""

from __future__ import annotations

import re

import numpy as np
import pytest

import pdlin
from pdlin.cli.main import main
from pdlin.errors import InputError
from pdlin.io import write_homogenized_csv, write_nonlinear, write_result

pytest.importorskip("matplotlib")
import matplotlib.pyplot as plt  # noqa: E402

from pdlin import plotting  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    cloud = pdlin.grid((10, 5), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        cloud,
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", [1e-3, 2e-4])],
    )
    res = pdlin.solve(prob, solver="direct")
    return write_result(tmp_path_factory.mktemp("plate") / "plate.npz", res)


def _labels(plot):
    ax, cbar = plot.figure.axes[0], plot.figure.axes[1]
    return ax.get_xlabel(), ax.get_ylabel(), cbar.get_ylabel()


@pytest.mark.parametrize("system", sorted(plotting.UNIT_SYSTEMS))
def test_axes_and_colour_bar_carry_the_units(plate, system):
    units = plotting.UNIT_SYSTEMS[system]
    L, S = units["length"], units["stress"]
    cases = {
        ("displacement", "x"): f"displacement x [{L}]",
        ("reaction", "magnitude"): f"|reaction| [{units['force']}]",
        ("stress", "xy"): f"stress xy [{S}]",
        ("strain", "yy"): "strain yy [-]",
        ("volume", None): f"volume [{L}²]",  # 2D: a cell's area
        ("family_size", None): "family_size",  # a count: no unit
    }
    for (field, comp), colour_label in cases.items():
        plot = plotting.plot_result(plate, field=field, component=comp, units=system)
        assert _labels(plot) == (f"x [{L}]", f"y [{L}]", colour_label)
        assert _labels(plot)[2].startswith(plot.label)


def test_default_labels_name_the_quantity(plate):
    # pdlin computes in the consistent units of its input: the label says which quantity
    plot = plotting.plot_result(plate, field="stress", component="xx")
    assert _labels(plot) == ("x [length]", "y [length]", "stress xx [stress]")
    assert plot.unit == "stress"
    custom = {"length": "in", "force": "lbf", "stress": "psi"}
    plot = plotting.plot_result(plate, component="y", units=custom)
    assert _labels(plot) == ("x [in]", "y [in]", "displacement y [in]") and plot.unit == "in"


def test_bad_units_name_the_option_and_the_choices(plate, capsys):
    with pytest.raises(InputError, match=r"units \(--units\) must be one of \['SI'"):
        plotting.plot_result(plate, units="furlongs")
    with pytest.raises(InputError, match=r"'length', 'force' and 'stress'.*got \{'length'"):
        plotting.plot_result(plate, units={"length": "m"})
    assert main(["plot", str(plate), "--units", "cgs"]) == 2
    assert "units (--units) must be one of" in capsys.readouterr().err


def test_one_dimensional_axes_carry_units(tmp_path):
    cloud = pdlin.grid((6,), spacing=0.5)
    p = pdlin.io.write_points(tmp_path / "bar.npz", cloud, {"displacement": cloud.points**2})
    ax = plotting.plot_result(p, component="x", units="SI").figure.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [m]", "displacement x [m]")


def test_slice_is_named_in_the_title(tmp_path):
    cloud = pdlin.grid((4, 4, 4), spacing=0.25)  # cell centres 0.125, 0.375, ...
    f = {"damage": np.arange(64.0), "displacement": np.tile([1.0, 2.0, 2.0], (64, 1))}
    p = pdlin.io.write_points(tmp_path / "cube.vtu", cloud, f)
    plot = plotting.plot_result(p, field="damage", slice="z=0.4", units="mm-N-MPa")
    title = plot.figure.axes[0].get_title()
    # h/2 = 0.125 from the volumes (0.25³), the 16 points of the layer at z = 0.375
    m = re.search(r"slice z = 0\.4 \(±([\d.]+) mm, (\d+) points\)", title)
    assert m is not None, title
    assert float(m.group(1)) == 0.125 and int(m.group(2)) == plot.values.size == 16
    assert _labels(plot)[:2] == ("x [mm]", "y [mm]")
    side = plotting.plot_result(p, slice=("x", 0.125)).figure.axes[0]
    assert "slice x = 0.125" in side.get_title()
    assert (side.get_xlabel(), side.get_ylabel()) == ("y [length]", "z [length]")


def test_homogenized_curve_axes_carry_units(tmp_path):
    prob = pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        pdlin.grid((8, 4), spacing=0.1),
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [1e-3, 0.0])],
    )
    res = pdlin.solve_nonlinear(prob, steps=2, method="newton")
    write_nonlinear(tmp_path / "run.pvd", res)
    write_homogenized_csv(tmp_path / "run_homogenized.csv", res)
    curve = plotting.plot_homogenized(tmp_path / "run_homogenized.csv", units="mm-N-MPa")
    ax = curve.figure.axes[0]
    assert ax.get_xlabel() == "mean strain F_11 - δ [-]"
    assert ax.get_ylabel() == "mean stress sigma_11 [MPa]" and curve.unit == "MPa"
    default = plotting.plot_homogenized(tmp_path / "run_homogenized.csv").figure.axes[0]
    assert default.get_ylabel() == "mean stress sigma_11 [stress]"
