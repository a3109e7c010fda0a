"""``StaticProblem(..., ratio=m)``: the horizon as a multiple of the spacing, as
``find_bonds(cloud, ratio=m)`` takes it (issue 34)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError


def _model():
    return pdlin.LPS(E=1.0, nu=0.25)


def test_ratio_builds_the_bonds_find_bonds_builds():
    cloud = pdlin.grid((9, 7), spacing=0.1)
    prob = pdlin.StaticProblem(_model(), cloud, ratio=3.015, dirichlet=[pdlin.Dirichlet("x-", 0)])
    ref = pdlin.find_bonds(cloud, ratio=3.015)
    got = prob.get_bonds()
    np.testing.assert_array_equal(got.i, ref.i)
    np.testing.assert_array_equal(got.j, ref.j)
    np.testing.assert_array_equal(got.horizon, ref.horizon)
    assert prob.bond_options["ratio"] == 3.015  # kept where find_bonds' other options are
    # with other find_bonds options, and through dataclasses.replace (fracture's sweeps)
    prob = pdlin.StaticProblem(
        _model(), cloud, ratio=2.015, bond_options={"shape": "cube"},
        dirichlet=[pdlin.Dirichlet("x-", 0)], loads=[pdlin.TotalForce("x+", [1e-3, 0])],
    )  # fmt: skip
    ref = pdlin.find_bonds(cloud, ratio=2.015, shape="cube")
    np.testing.assert_array_equal(prob.get_bonds().j, ref.j)
    again = dataclasses.replace(prob, bonds=ref)
    assert again.bond_options == prob.bond_options
    u = pdlin.solve(prob, solver="direct").u
    np.testing.assert_array_equal(pdlin.solve(again, solver="direct").u, u)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        ({"horizon": 0.3}, r"ratio and horizon: give one of them, got ratio=3.015 and horizon=0.3"),
        ({"bond_options": {"ratio": 2.0}}, r"ratio and bond_options\['ratio'\]: give one"),
        ({"bonds": "find"}, r"ratio and bonds: give one of them .*precomputed Bonds"),
    ],
)
def test_conflicting_arguments_are_refused_by_name(kwargs, pattern):
    cloud = pdlin.grid((6, 5), spacing=0.1)
    if kwargs.get("bonds") == "find":
        kwargs = {"bonds": pdlin.find_bonds(cloud, ratio=2.0)}
    with pytest.raises(InputError, match=pattern):
        pdlin.StaticProblem(_model(), cloud, ratio=3.015, **kwargs)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), "abc", [3.0]])
def test_bad_ratio_is_refused(bad):
    with pytest.raises(InputError, match=r"ratio must be"):
        pdlin.StaticProblem(_model(), pdlin.grid((6, 5)), ratio=bad)
