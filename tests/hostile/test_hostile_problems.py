"""Hostile input: boundary conditions, loads, static problems, linear solves, sparsity."""

from __future__ import annotations

import numpy as np
import pytest
from hostile_util import INF, NAN, expect, problem

import pdlin
from pdlin.errors import (
    FloatingBodyError,
    InputError,
    InputTypeError,
    NonFiniteError,
    ShapeError,
)

D, TF, BF = pdlin.Dirichlet, pdlin.TotalForce, pdlin.BodyForce


def _solve(**kw):
    return pdlin.solve(problem(**kw))


def _run(**kw):
    return pdlin.solve(problem(), **kw)


CASES = [
    # Dirichlet
    (
        "bc-unknown-set",
        lambda: _solve(dirichlet=[D("left", 0.0)]),
        InputError,
        r"unknown point set 'left'",
    ),
    ("bc-value-nan", lambda: D("x-", NAN), NonFiniteError, r"value must be finite, got nan"),
    (
        "bc-value-inf",
        lambda: D("x-", [0, INF]),
        NonFiniteError,
        r"value must be finite, got inf at index 1",
    ),
    ("bc-value-str", lambda: D("x-", "zero"), InputError, r"value must be numeric, got str"),
    (
        "bc-components-range",
        lambda: _solve(dirichlet=[D("x-", 0.0, components=[2])]),
        InputError,
        r"components must be distinct axes in \[0, 1\], got \[2\]",
    ),
    (
        "bc-components-neg",
        lambda: D("x-", 0.0, components=[-1]),
        InputError,
        r"components must be distinct axes in \[0, 2\], got \[-1\]",
    ),
    (
        "bc-components-float",
        lambda: D("x-", 0.0, components=[0.5]),
        InputError,
        r"components must be an integer, got 0.5",
    ),
    (
        "bc-components-letter",
        lambda: D("x-", 0.0, components="w"),
        InputError,
        r"components must be letters from 'xyz', got 'w'",
    ),
    (
        "bc-value-shape",
        lambda: _solve(dirichlet=[D("x-", [0, 0, 0])]),
        ShapeError,
        r"dirichlet\[0\].value must be a scalar or have shape .* got \(3,\)",
    ),
    (
        "bc-where-float",
        lambda: D(np.array([0.5]), 0.0),
        InputError,
        r"where must be a set name, integer point indices or a boolean mask, got dtype float64",
    ),
    (
        "bc-where-oob",
        lambda: _solve(dirichlet=[D([1000], 0.0)]),
        InputError,
        r"point selection must hold indices in \[0, 35\], got range \[1000, 1000\]",
    ),
    (
        "bc-empty-set",
        lambda: _solve(dirichlet=[D([], 0.0)]),
        InputError,
        r"dirichlet\[0\] selects no points \(where=\[\]\)",
    ),
    (
        "bc-conflict",
        lambda: _solve(dirichlet=[D("x-", 0.0), D("x-", 1.0)]),
        InputError,
        r"dirichlet conditions conflict: dof 0 .* prescribed as 0.0 and 1.0",
    ),
    (
        "affine-F-nan",
        lambda: D.affine("x-", np.full((2, 2), NAN)),
        NonFiniteError,
        r"F must be finite, got nan at index \(0, 0\)",
    ),
    (
        "affine-F-dim",
        lambda: _solve(dirichlet=[D.affine("x-", np.eye(3))]),
        ShapeError,
        r"F is 3x3 but the cloud is 2D",
    ),
    ("affine-F-str", lambda: D.affine("x-", "I"), InputError, r"F must be numeric, got str"),
    (
        "affine-F-nonsquare",
        lambda: D.affine("x-", np.ones((2, 3))),
        ShapeError,
        r"F must be square \(dim, dim\), got \(2, 3\)",
    ),
    (
        "affine-translation-nan",
        lambda: D.affine("x-", np.eye(2), translation=[NAN, 0]),
        NonFiniteError,
        r"translation must be finite, got nan at index 0",
    ),
    (
        "affine-center-shape",
        lambda: D.affine("x-", np.eye(2), center=[0, 0, 0]),
        ShapeError,
        r"center and translation must have shape \(2,\)",
    ),
    (
        "vgrad-L-nan",
        lambda: D.velocity_gradient("x-", np.full((2, 2), NAN)),
        NonFiniteError,
        r"L must be finite, got nan at index \(0, 0\)",
    ),
    (
        "vgrad-L-1d",
        lambda: D.velocity_gradient("x-", np.ones(3)),
        ShapeError,
        r"L must be a 2-D array, got shape \(3,\)",
    ),
    (
        "vgrad-center",
        lambda: D.velocity_gradient("x-", np.eye(2), center=[0.0]),
        ShapeError,
        r"center must have shape \(2,\), got \(1,\)",
    ),
    (
        "floating-body",
        lambda: _solve(dirichlet=[]),
        FloatingBodyError,
        r"the body is floating: 1 of 1 bond-connected piece",
    ),
    (
        "floating-translation",
        lambda: _solve(dirichlet=[D("x-", 0.0, components=[0])]),
        FloatingBodyError,
        r"leave 1 rigid-body motion\(s\) free \(translation y\)",
    ),
    # loads
    (
        "load-force-nan",
        lambda: TF("x+", [NAN, 0]),
        NonFiniteError,
        r"force must be finite, got nan at index 0",
    ),
    ("load-force-str", lambda: TF("x+", "big"), InputError, r"force must be numeric, got str"),
    (
        "load-force-shape",
        lambda: _solve(loads=[TF("x+", [1, 0, 0])]),
        ShapeError,
        r"loads\[0\].force must have shape \(2,\), got \(3,\)",
    ),
    (
        "load-empty-set",
        lambda: _solve(loads=[TF([], [1, 0])]),
        InputError,
        r"loads\[0\] selects no points \(where=\[\]\)",
    ),
    (
        "load-weights-neg",
        lambda: _solve(loads=[TF("x+", [1, 0], weights=-np.ones(6))]),
        InputError,
        r"loads\[0\].weights must be 6 non-negative numbers .* got min -1.0",
    ),
    (
        "load-weights-zero",
        lambda: _solve(loads=[TF("x+", [1, 0], weights=np.zeros(6))]),
        InputError,
        r"loads\[0\].weights .* positive sum, got min 0.0, sum 0.0",
    ),
    (
        "load-weights-shape",
        lambda: _solve(loads=[TF("x+", [1, 0], weights=np.ones(2))]),
        InputError,
        r"loads\[0\].weights must be 6 .* got shape \(2,\)",
    ),
    (
        "load-weights-nan",
        lambda: TF("x+", [1, 0], weights=[NAN] * 6),
        NonFiniteError,
        r"weights must be finite, got nan at index 0",
    ),
    (
        "body-force-nan",
        lambda: BF("all", [NAN, 0]),
        NonFiniteError,
        r"density must be finite, got nan at index 0",
    ),
    (
        "body-force-shape",
        lambda: _solve(loads=[BF("all", [1, 0, 0])]),
        ShapeError,
        r"loads\[0\].density must be a scalar, shape \(2,\) or \(36, 2\), got \(3,\)",
    ),
    (
        "body-force-callable-nan",
        lambda: _solve(loads=[BF("all", lambda x: np.full(x.shape, NAN))]),
        NonFiniteError,
        r"loads\[0\].density \(callable result\) must be finite",
    ),
    (
        "body-force-unknown-set",
        lambda: _solve(loads=[BF("nope", [1, 0])]),
        InputError,
        r"unknown point set 'nope'",
    ),
    # StaticProblem
    (
        "problem-model",
        lambda: pdlin.StaticProblem("bb", pdlin.grid((3, 3)), horizon=0.3),
        InputTypeError,
        r"model must be a pdlin model, got str",
    ),
    (
        "problem-cloud",
        lambda: pdlin.StaticProblem(pdlin.BondBased(E=1.0), np.zeros((3, 2)), horizon=0.3),
        InputTypeError,
        r"cloud must be a PointCloud, got ndarray",
    ),
    (
        "problem-horizon-nan",
        lambda: problem(horizon=NAN),
        NonFiniteError,
        r"horizon must be finite, got nan",
    ),
    (
        "problem-horizon-neg",
        lambda: problem(horizon=-0.1),
        InputError,
        r"horizon must be > 0, got min -0.1",
    ),
    (
        "problem-dirichlet-type",
        lambda: problem(dirichlet=[("x-", 0)]),
        InputTypeError,
        r"dirichlet\[0\] must be a pdlin Dirichlet, got tuple",
    ),
    (
        "problem-loads-type",
        lambda: problem(loads=[1.0]),
        InputTypeError,
        r"loads\[0\] must be a BodyForce or TotalForce, got float",
    ),
    (
        "problem-bond-options",
        lambda: problem(bond_options={"shapes": "sphere"}),
        InputError,
        r"bond_options has unknown key 'shapes'",
    ),
    (
        "problem-foreign-bonds",
        lambda: problem(horizon=None, bonds=pdlin.find_bonds(pdlin.grid((3, 3), 0.1), 0.301)),
        ShapeError,
        r"bonds must belong to the cloud \(36 points\), got bonds over 9 points",
    ),
    # solve options
    ("solve-solver", lambda: _run(solver="lu"), InputError, r"solver must be one of .* got 'lu'"),
    (
        "solve-rtol-neg",
        lambda: _run(rtol=-1),
        InputError,
        r"rtol must be a number in \(0, 1\), got -1",
    ),
    (
        "solve-rtol-nan",
        lambda: _run(rtol=NAN),
        InputError,
        r"rtol must be a number in \(0, 1\), got nan",
    ),
    (
        "solve-rtol-zero",
        lambda: _run(solver="cg", rtol=0),
        InputError,
        r"rtol must be a number in \(0, 1\), got 0",
    ),
    (
        "solve-rtol-big",
        lambda: _run(rtol=2.0),
        InputError,
        r"rtol must be a number in \(0, 1\), got 2.0",
    ),
    (
        "solve-rtol-str",
        lambda: _run(rtol="small"),
        InputError,
        r"rtol must be a number in \(0, 1\), got 'small'",
    ),
    (
        "solve-maxiter-0",
        lambda: _run(solver="cg", maxiter=0),
        InputError,
        r"maxiter must be an integer >= 1, got 0",
    ),
    (
        "solve-maxiter-float",
        lambda: _run(solver="cg", maxiter=2.5),
        InputError,
        r"maxiter must be an integer >= 1, got 2.5",
    ),
    (
        "solve-maxiter-str",
        lambda: _run(solver="cg", maxiter="10"),
        InputError,
        r"maxiter must be an integer >= 1, got '10'",
    ),
    (
        "solve-operator",
        lambda: _run(operator="sparse"),
        InputError,
        r"operator must be one of .* got 'sparse'",
    ),
    (
        "solve-amg-options",
        lambda: _run(solver="amg-cg", amg_options=3),
        InputTypeError,
        r"amg_options must be a mapping .* got int",
    ),
    (
        "solve-problem",
        lambda: pdlin.solve("p"),
        InputTypeError,
        r"problem must be a StaticProblem, got str",
    ),
    (
        "solve-preconditioner",
        lambda: _run(preconditioner="amg"),
        InputTypeError,
        r"preconditioner must be a pdlin model .* got str",
    ),
    # sparsity_report
    (
        "sparsity-nothing",
        lambda: pdlin.sparsity_report(),
        InputError,
        r"sparsity_report needs K or model=, cloud=, bonds=; got neither",
    ),
    (
        "sparsity-nonsquare",
        lambda: pdlin.sparsity_report(np.ones((3, 4))),
        ShapeError,
        r"K must be square, got shape \(3, 4\)",
    ),
    (
        "sparsity-nan",
        lambda: pdlin.sparsity_report(np.full((4, 4), NAN), numeric=True),
        NonFiniteError,
        r"K must be finite, got NaN or inf",
    ),
    (
        "sparsity-str",
        lambda: pdlin.sparsity_report("K"),
        InputTypeError,
        r"K must be a scipy sparse array or a 2-D ndarray, got str",
    ),
    (
        "sparsity-block",
        lambda: pdlin.sparsity_report(np.eye(4), block_size=3),
        ShapeError,
        r"K has 4 rows, not a multiple of block_size 3",
    ),
    (
        "sparsity-fixed-oob",
        lambda: pdlin.sparsity_report(np.eye(4), fixed_dofs=[10]),
        InputError,
        r"fixed_dofs must hold DOF indices in \[0, 3\], got range \[10, 10\]",
    ),
    (
        "sparsity-fill-limit",
        lambda: pdlin.sparsity_report(np.eye(4), fill_limit=-1),
        InputError,
        r"fill_limit must be an integer >= 0, got -1",
    ),
    (
        "sparsity-points-nan",
        lambda: pdlin.sparsity_report(
            model=pdlin.BondBased(E=1.0), points=[[0, 0], [NAN, 1]], horizon=1.0
        ),
        InputError,
        r"points must be finite, got NaN or inf",
    ),
]


@pytest.mark.parametrize(
    ("call", "exc", "pattern"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_problems_reject(call, exc, pattern):
    expect(call, exc, pattern)


def test_solve_result_is_finite():
    """No NaN escapes: a valid solve returns finite displacements and reactions."""
    res = pdlin.solve(problem())
    assert np.all(np.isfinite(res.u)) and np.all(np.isfinite(res.reactions))


# --- loads that vanish into the supports (issue 31, item 2) -------------------------------

#: the clamped corner of the 6 x 6 hostile problem: the point on both 'x-' and 'y-'
_CORNER = [0]


def _strict_solve(prob, **kw):
    """Solve with every AccuracyWarning an error (none may be issued)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", pdlin.errors.AccuracyWarning)
        return pdlin.solve(prob, **kw)


SUPPORT_CASES = [
    (
        "total-on-clamped-set",
        lambda: _solve(loads=[TF("x-", [1e-3, 0.0])]),
        r"loads\[0\] \(TotalForce on set 'x-'\) acts only on prescribed DOFs: all 6 of its",
    ),
    (
        "total-on-clamped-corner",
        lambda: _solve(loads=[TF("x+", [1e-3, 0.0]), TF(_CORNER, [0.0, 1e-3])]),
        r"loads\[1\] \(TotalForce on 1 point\(s\)\) acts only on prescribed DOFs",
    ),
    (
        "body-on-clamped-set",
        lambda: _solve(loads=[BF("x-", [0.0, -9.8])]),
        r"loads\[0\] \(BodyForce on set 'x-'\) acts only on prescribed DOFs",
    ),
    (
        # only x is prescribed on x-: the x-force sits on prescribed components alone
        "total-on-roller-component",
        lambda: _solve(
            dirichlet=[D("x-", 0.0, components="x"), D(_CORNER, 0.0)],
            loads=[TF("x+", [1e-3, 0.0]), TF("x-", [1e-3, 0.0])],
        ),
        r"loads\[1\] \(TotalForce on set 'x-'\) acts only on prescribed DOFs",
    ),
    (
        # points at y = 0.05 lie on the plane y = 0.05: their y displacement is prescribed
        "total-on-symmetry-plane",
        lambda: _solve(symmetry=[pdlin.SymmetryPlane("y", 0.05)], loads=[TF("y-", [0.0, 1e-3])]),
        r"loads\[0\] \(TotalForce on set 'y-'\) acts only on prescribed DOFs",
    ),
    (
        "solve-nonlinear-velocity-gradient",
        lambda: pdlin.solve_nonlinear(
            problem(
                dirichlet=[
                    D("x-", 0.0),
                    D.velocity_gradient("x+", [[1e-3, 0.0], [0.0, 0.0]]),
                ],
                loads=[TF("x+", [0.0, 1e-3])],
            ),
            steps=1,
        ),
        r"loads\[0\] \(TotalForce on set 'x\+'\) acts only on prescribed DOFs",
    ),
    (
        "solve-damage",
        lambda: pdlin.solve_damage(problem(loads=[TF("x-", [1e-3, 0.0])]), 0.01, steps=1),
        r"loads\[0\] \(TotalForce on set 'x-'\) acts only on prescribed DOFs",
    ),
]


@pytest.mark.parametrize(
    ("call", "pattern"), [c[1:] for c in SUPPORT_CASES], ids=[c[0] for c in SUPPORT_CASES]
)
def test_load_on_prescribed_dofs_only_is_refused(call, pattern):
    expect(call, InputError, pattern)


def test_load_on_prescribed_dofs_refused_by_petsc_backend():
    pytest.importorskip("petsc4py")
    prob = problem(loads=[TF("x-", [1e-3, 0.0])])
    expect(
        lambda: pdlin.solve(prob, backend="petsc"),
        InputError,
        r"loads\[0\] \(TotalForce on set 'x-'\) acts only on prescribed DOFs",
    )


def test_total_force_partly_on_a_determinate_support_is_applied_silently():
    # shear of the 6 x 6 grid by four self-equilibrated edge loads, held by a pin at point 0
    # and a roller (y) at its neighbour on y-: the pin sits in the sets x- and y-, so part of
    # two loads acts on prescribed DOFs. The support is statically determinate, so it supplies
    # exactly that part: no warning, zero reactions, and the same displacement as the same
    # loads held by a pin and a roller away from every loaded edge (rigid motion removed).
    cloud = pdlin.grid((6, 6), spacing=0.1)
    p = cloud.points
    shear = [TF("y+", [1e-3, 0.0]), TF("y-", [-1e-3, 0.0]), TF("x+", [0.0, 1e-3]),
             TF("x-", [0.0, -1e-3])]  # fmt: skip
    order = np.lexsort((p[:, 0], p[:, 1]))
    pin, roll = int(order[0]), int(order[1])  # (0.05, 0.05) and (0.15, 0.05): on y-
    inner = np.flatnonzero(np.all((p > 0.1) & (p < 0.5), axis=1))
    a, b = int(inner[0]), int(inner[inner.size // 2])  # two interior points, off every edge

    def run(i: int, j: int, comp: str) -> pdlin.StaticResult:
        prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.3015,
                                   dirichlet=[D([i], 0.0), D([j], 0.0, components=comp)],
                                   loads=shear)  # fmt: skip
        return _strict_solve(prob)

    edge, off = run(pin, roll, "y"), run(a, b, "x" if p[a, 1] != p[b, 1] else "y")
    np.testing.assert_allclose(edge.reactions, 0.0, atol=1e-15)
    # the two displacements differ by a rigid motion: compare the strains
    np.testing.assert_allclose(edge.strain(), off.strain(), rtol=1e-8, atol=1e-12)


def test_load_off_the_prescribed_components_is_silent():
    # x prescribed on x- and y at point 32 (on x+), the y force on x- and the x force on x+
    # act on free components: nothing is lost
    res = _strict_solve(
        problem(
            dirichlet=[D("x-", 0.0, components="x"), D([32], 0.0, components="y")],
            loads=[TF("x-", [0.0, 1e-3]), TF("x+", [1e-3, 0.0])],
        )
    )
    assert np.abs(res.u).max() > 0


def test_body_force_over_a_clamped_body_is_accepted_silently():
    # gravity on the whole body: the clamped layer's weight is carried by the support, as
    # it physically is; the reactions balance the whole weight
    prob = problem(loads=[BF("all", [0.0, -9.8])])
    res = _strict_solve(prob)
    weight = 9.8 * prob.cloud.volumes.sum()  # density 9.8 over the 0.6 x 0.6 plate
    np.testing.assert_allclose(res.reactions.sum(axis=0), [0.0, weight], rtol=1e-12, atol=1e-14)


def test_zero_load_on_support_is_not_refused():
    # a zero force loads nothing anywhere: it is not a load lost into the support
    res = _strict_solve(problem(loads=[TF("x+", [1e-3, 0.0]), TF("x-", [0.0, 0.0])]))
    assert np.all(np.isfinite(res.u))
