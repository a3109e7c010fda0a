"""Hostile input: solve_nonlinear options (load steps, Newton, ADR, checkpoints)."""

from __future__ import annotations

import numpy as np
import pytest
from hostile_util import NAN, expect, problem

import pdlin
from pdlin.errors import InputError, InputTypeError, ShapeError


def _nl(**kw):
    return pdlin.solve_nonlinear(problem(), **kw)


CASES = [
    ("method", lambda: _nl(method="bfgs"), InputError, r"method must be one of .* got 'bfgs'"),
    ("steps-0", lambda: _nl(steps=0), InputError, r"steps must be an integer >= 1, got 0"),
    ("steps-float", lambda: _nl(steps=2.5), InputError, r"steps must be an integer >= 1, got 2.5"),
    ("steps-str", lambda: _nl(steps="10"), InputError, r"steps must be an integer >= 1, got '10'"),
    (
        "times-decreasing",
        lambda: _nl(times=[0.5, 0.2]),
        InputError,
        r"times must be a non-empty increasing .* got \[0.5, 0.2\]",
    ),
    ("times-nan", lambda: _nl(times=[0.5, NAN]), InputError, r"times must be .* got \[0.5, nan\]"),
    ("times-empty", lambda: _nl(times=[]), InputError, r"times must be a non-empty .* got \[\]"),
    ("t-end-neg", lambda: _nl(t_end=-1), InputError, r"t_end must be a positive number, got -1"),
    ("rtol-nan", lambda: _nl(rtol=NAN), InputError, r"rtol must be a positive number, got nan"),
    (
        "maxiter-neg",
        lambda: _nl(maxiter=-1),
        InputError,
        r"maxiter must be an integer >= 0, got -1",
    ),
    (
        "max-cutbacks",
        lambda: _nl(max_cutbacks=-1),
        InputError,
        r"max_cutbacks must be an integer >= 0, got -1",
    ),
    (
        "fallback-cutbacks",
        lambda: _nl(fallback_cutbacks=True),
        InputError,
        r"fallback_cutbacks must be an integer >= 0, got True",
    ),
    (
        "relax-float",
        lambda: _nl(relax=2.5),
        InputError,
        r"relax must be an integer >= 0, got 2.5",
    ),
    (
        "e-l-neg",
        lambda: _nl(method="adr", e_l=-1),
        InputError,
        r"e_l must be a positive number, got -1",
    ),
    (
        "density-str",
        lambda: _nl(method="adr", density="gersh"),
        InputError,
        r"density must be 'gershgorin', a positive number or an array, got 'gersh'",
    ),
    (
        "density-neg",
        lambda: _nl(method="adr", density=-1.0, dt=1.0),
        InputError,
        r"density must be > 0, got min -1.0",
    ),
    (
        "density-nan",
        lambda: _nl(method="adr", density=NAN, dt=1.0),
        InputError,
        r"density must be finite, got nan",
    ),
    (
        "density-shape",
        lambda: _nl(method="adr", density=np.ones(5), dt=1.0),
        ShapeError,
        r"density must be a scalar or have shape \(72,\), got \(5,\)",
    ),
    (
        "density-without-dt",
        lambda: _nl(method="adr", density=1.0),
        InputError,
        r"an explicit ADR density needs dt",
    ),
    ("dt-neg", lambda: _nl(method="adr", dt=-1.0), InputError, r"dt must be > 0 .* got dt = -1.0"),
    (
        "density-safety",
        lambda: _nl(method="adr", density_safety=0),
        InputError,
        r"safety >= 1, got dt = 1.0, safety = 0",
    ),
    (
        "damping-neg",
        lambda: _nl(method="adr", damping=-1.0),
        InputError,
        r"damping must be a finite number >= 0, got -1.0",
    ),
    (
        "damping-nan",
        lambda: _nl(method="adr", damping=NAN),
        InputError,
        r"damping must be a finite number >= 0, got nan",
    ),
    (
        "c0-neg",
        lambda: _nl(method="adr", c0=-1),
        InputError,
        r"c0 must be a finite number >= 0, got -1",
    ),
    (
        "adr-maxiter-0",
        lambda: _nl(method="adr", adr_maxiter=0),
        InputError,
        r"adr_maxiter must be an integer >= 1, got 0",
    ),
    ("floor-neg", lambda: _nl(floor=-1), InputError, r"floor must be a positive number, got -1"),
    (
        "predictor",
        lambda: _nl(predictor="linear2"),
        InputError,
        r"predictor must be one of .* got 'linear2'",
    ),
    (
        "linear-solver",
        lambda: _nl(linear_solver="lu"),
        InputError,
        r"solver must be one of .* got 'lu'",
    ),
    (
        "checkpoint-folder",
        lambda: _nl(checkpoint="/nonexistent/dir/ck.npz"),
        InputError,
        r"checkpoint must be a path in an existing folder, got '/nonexistent/dir/ck.npz'",
    ),
    (
        "checkpoint-type",
        lambda: _nl(checkpoint=3),
        InputTypeError,
        r"checkpoint must be a path, got int",
    ),
    (
        "resume-without-checkpoint",
        lambda: _nl(resume=True),
        InputError,
        r"resume=True needs checkpoint= .* got None",
    ),
    ("homogenize-set", lambda: _nl(homogenize="yes"), InputError, r"unknown point set 'yes'"),
    (
        "problem",
        lambda: pdlin.solve_nonlinear("p"),
        InputTypeError,
        r"problem must be a StaticProblem, got str",
    ),
]


@pytest.mark.parametrize(
    ("call", "exc", "pattern"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_nonlinear_rejects(call, exc, pattern):
    expect(call, exc, pattern)


@pytest.mark.parametrize("method", ["newton", "adr"])
def test_nonlinear_result_is_finite(method):
    """No NaN escapes: every committed step of a valid run is finite."""
    res = pdlin.solve_nonlinear(problem(), steps=2, method=method, e_l=1e-8)
    assert np.all(np.isfinite(res.u)) and np.all(np.isfinite(res.reactions))
