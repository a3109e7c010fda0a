"""Jupyter-friendly reprs: every public model and material, problems and results.

A repr names the class and its key facts (sizes, parameters, solver, steps) and never
dumps an array or shows a memory address, however large the problem; results also
render as an HTML table (``_repr_html_``).
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pdlin
from pdlin import constitutive as cst
from pdlin.models import Model
from pdlin.models.ordinary_state import OrdinaryStateBased

#: the reprs' length budget (issue 34: "under e.g. 300 characters for a 10^4-point problem")
LIMIT = 300
#: the brief's sample size: a problem of 10^4 points
N = 10_000


def _looks_clean(text: str) -> None:
    assert "array(" not in text, text  # numpy's repr of an array
    assert not re.search(r"0x[0-9a-f]{6,}", text), text  # object.__repr__'s address
    assert "\n" not in text, text
    assert len(text) <= LIMIT, (len(text), text)


#: one constructor per public model / material class: (class, build(E, nu, n), facts)
#: ``facts`` are substrings the repr must hold (the parameters given to the constructor)
MODELS: dict[str, tuple[type, Callable[[float, float, int], Any], Callable[..., list[str]]]] = {
    "BondBased": (
        pdlin.BondBased,
        lambda E, nu, n: pdlin.BondBased(E=E, plane="strain"),
        lambda E, nu, n: ["BondBased(", f"E={E:.4g}", "plane='strain'"],
    ),
    "BondBased per-point E": (
        pdlin.BondBased,
        lambda E, nu, n: pdlin.BondBased(E=np.full(n, E)),
        lambda E, nu, n: ["BondBased(", f"E=<{n} array>"],
    ),
    "OrdinaryStateBased": (
        OrdinaryStateBased,
        lambda E, nu, n: OrdinaryStateBased(E=E, nu=nu),
        lambda E, nu, n: ["OrdinaryStateBased(", f"E={E:.4g}", f"nu={nu:.4g}"],
    ),
    "LPS": (
        pdlin.LPS,
        lambda E, nu, n: pdlin.LPS(E=E, nu=nu, peridigm=True),
        lambda E, nu, n: ["LPS(", f"E={E:.4g}", f"nu={nu:.4g}", "peridigm=True"],
    ),
    "LPS per-point E": (
        pdlin.LPS,
        lambda E, nu, n: pdlin.LPS(E=np.full(n, E), nu=nu),
        lambda E, nu, n: ["LPS(", "E='per-point'", f"nu={nu:.4g}"],
    ),
    "XOSB": (
        pdlin.XOSB,
        lambda E, nu, n: pdlin.XOSB(E=E, nu=nu),
        lambda E, nu, n: ["XOSB(", f"E={E:.4g}", f"nu={nu:.4g}"],
    ),
    "Correspondence": (
        pdlin.Correspondence,
        lambda E, nu, n: pdlin.Correspondence(E=E, nu=nu, control="penalty"),
        lambda E, nu, n: ["Correspondence(", f"E={E:.4g}", "control='penalty'"],
    ),
    "Correspondence C": (
        pdlin.Correspondence,
        lambda E, nu, n: pdlin.Correspondence(cst.isotropic(E, nu)),
        lambda E, nu, n: ["Correspondence(", "C=<6x6 array>"],
    ),
    "Correspondence material": (
        pdlin.Correspondence,
        lambda E, nu, n: pdlin.Correspondence(
            material=pdlin.CrystalPlasticity(orientation=np.zeros(n))
        ),
        lambda E, nu, n: ["Correspondence(", "material='CrystalPlasticity'"],
    ),
    "CrystalPlasticity": (
        pdlin.CrystalPlasticity,
        lambda E, nu, n: pdlin.CrystalPlasticity("fcc", orientation=np.tile(np.eye(3), (n, 1, 1))),
        # fcc: 12 slip systems (pdlin.constitutive.SLIP_FAMILIES)
        lambda E, nu, n: ["CrystalPlasticity(", "slip='fcc'", "nslip=12", f"<{n}x3x3 array>"],
    ),
    "PeridigmElastic": (
        pdlin.models.PeridigmElastic,
        lambda E, nu, n: pdlin.models.PeridigmElastic(K=E, G=E / 2),
        lambda E, nu, n: ["PeridigmElastic(", "peridigm=True", "kinematics='finite'"],
    ),
    "PeridigmElasticPlastic": (
        pdlin.models.PeridigmElasticPlastic,
        lambda E, nu, n: pdlin.models.PeridigmElasticPlastic(
            K=E, G=E / 2, yield_stress=np.full(n, 2.0)
        ),
        lambda E, nu, n: ["PeridigmElasticPlastic(", "yield_stress='per-point'"],
    ),
    "PeridigmCorrespondence": (
        pdlin.models.PeridigmCorrespondence,
        lambda E, nu, n: pdlin.models.PeridigmCorrespondence(K=E, G=E / 2, hourglass=0.02),
        lambda E, nu, n: ["PeridigmCorrespondence(", f"K={E:.4g}", "hourglass=0.02"],
    ),
    "Hypoelastic": (
        cst.Hypoelastic,
        lambda E, nu, n: cst.Hypoelastic(K=E, G=E / 2),
        lambda E, nu, n: ["Hypoelastic(", f"K={E:g}", f"G={E / 2:g}"],
    ),
    "SaintVenantKirchhoff": (
        pdlin.SaintVenantKirchhoff,
        lambda E, nu, n: pdlin.SaintVenantKirchhoff(cst.isotropic(E, nu)),
        lambda E, nu, n: ["SaintVenantKirchhoff(", "dim=3", "C=<3x3x3x3 array>"],
    ),
}


def _public_classes() -> set[type]:
    """Model subclasses and materials (classes with ``update``) that pdlin exports."""
    names = {*pdlin.__all__, *pdlin.models.__all__, *cst.__all__}
    found: set[type] = {OrdinaryStateBased}  # the state-based base class users may subclass
    for name in names:
        obj = getattr(pdlin, name, None) or getattr(pdlin.models, name, None)
        obj = obj or getattr(cst, name, None)
        if not inspect.isclass(obj) or inspect.isabstract(obj):
            continue
        if issubclass(obj, Model) or (hasattr(obj, "update") and hasattr(obj, "initial_state")):
            found.add(obj)
    return found


def test_table_covers_every_public_model_and_material():
    assert _public_classes() == {cls for cls, _, _ in MODELS.values()}


@pytest.mark.parametrize("name", sorted(MODELS))
@settings(max_examples=5, deadline=None)
@given(
    E=st.floats(1e-3, 1e12, allow_nan=False),
    nu=st.floats(0.0, 0.45),
    n=st.sampled_from([3, N]),
)
def test_model_repr_is_short_and_informative(name, E, nu, n):
    cls, build, facts = MODELS[name]
    model = build(E, nu, n)
    assert type(model) is cls
    text = repr(model)
    _looks_clean(text)
    for fact in facts(E, nu, n):
        assert fact in text, (fact, text)


def _problem(n_side: int = 100, **kw: Any) -> pdlin.StaticProblem:
    cloud = pdlin.grid((n_side, n_side), spacing=1.0 / n_side)
    return pdlin.StaticProblem(
        pdlin.LPS(E=70e9, nu=0.3),
        cloud,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", [1e3, 0.0])],
        **kw,
    )


def test_static_problem_repr_of_a_large_problem():
    prob = _problem(ratio=3.015)  # 100 x 100 = 10^4 points, bonds not built
    text = repr(prob)
    _looks_clean(text)
    for fact in ("StaticProblem(", "LPS(E=7e+10", f"points={N}", "dim=2", f"DOFs={2 * N}"):
        assert fact in text, (fact, text)
    assert "ratio=3.015" in text and "dirichlet=1" in text and "loads=1" in text


def test_static_problem_repr_with_per_point_horizon_and_bonds():
    cloud = pdlin.grid((100, 100), spacing=0.01)
    h = np.full(cloud.n, 0.03)
    bonds = pdlin.find_bonds(cloud, h)
    text = repr(pdlin.StaticProblem(pdlin.BondBased(E=np.ones(cloud.n)), cloud, bonds=bonds))
    _looks_clean(text)
    assert f"bonds={bonds.n_bonds}" in text and f"E=<{N} array>" in text
    text = repr(pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=h))
    _looks_clean(text)
    assert f"horizon=<{N} array>" in text


@pytest.fixture(scope="module")
def static_result() -> pdlin.StaticResult:
    return pdlin.solve(_problem(12, ratio=3.015), solver="direct")


def test_static_result_repr_and_html(static_result):
    res = static_result
    text = repr(res)
    _looks_clean(text)
    facts = [
        "StaticResult(",
        f"points={res.u.shape[0]}",
        "dim=2",
        f"bonds={res.bonds.n_bonds}",
        f"DOFs={res.u.size}",
        "solver='direct'",
        "converged=True",
        f"iterations={res.n_iter}",
        f"residual={res.relative_residual:.4g}",
    ]
    for fact in facts:
        assert fact in text, (fact, text)
    html = res._repr_html_()
    assert html.startswith("<table>") and html.endswith("</table>")
    assert "relative residual" in html and "LPS(E=7e+10" in html
    assert "&#x27;direct&#x27;" not in html and "direct" in html  # plain text cells


def test_nonlinear_result_repr_and_html():
    cloud = pdlin.grid((20,), spacing=0.05)
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        horizon=0.1,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3)],
    )
    res = pdlin.solve_nonlinear(prob, steps=3, method="newton")
    text = repr(res)
    _looks_clean(text)
    for fact in ("NonlinearResult(", "points=20", "steps=3", "methods='newton'", "times=0.3333"):
        assert fact in text, (fact, text)
    assert f"iterations={int(res.iterations.sum())}" in text
    html = res._repr_html_()
    assert html.startswith("<table>") and "<th" in html and "steps" in html


def test_result_file_repr_and_html(static_result, tmp_path):
    from pdlin.io import read_result, write_result

    path = write_result(tmp_path / "plate.vtu", static_result)
    rf = read_result(path)
    text = repr(rf)
    _looks_clean(text)
    for fact in ("ResultFile(", "file='plate.vtu'", f"points={rf.points.shape[0]}", "steps=1"):
        assert fact in text, (fact, text)
    assert "displacement" in text
    html = rf._repr_html_()
    assert html.startswith("<table>") and "displacement[2]" in html


def test_damage_result_repr_and_html():
    cloud = pdlin.grid((30,), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        horizon=0.3015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 0.05)],
    )
    res = pdlin.solve_damage(prob, 0.01, steps=4, solver="direct")
    text = repr(res)
    _looks_clean(text)
    assert "DamageResult(" in text and f"steps={res.n_steps}" in text
    assert res._repr_html_().startswith("<table>")


def test_material_point_result_repr():
    # 10^4 orientations in one run: (steps, n, ...) histories
    theta = np.linspace(0.0, np.pi, N)
    res = pdlin.material_point(pdlin.CrystalPlasticity(), "shear", steps=4, orientation=theta)
    text = repr(res)
    _looks_clean(text)
    for fact in ("MaterialPointResult(", "steps=4", f"points={N}", "dim=2", "nslip=2"):
        assert fact in text, (fact, text)


def test_calibration_result_repr():
    cloud = pdlin.grid((40, 20), spacing=0.05)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    target = np.array([[4.0, 0.3, 0.0], [0.3, 1.0, 0.0], [0.0, 0.0, 0.3]])  # anisotropic_block
    res = pdlin.calibrate_micromoduli(target, bonds, plane="stress", boundary="bulk")
    text = repr(res)
    _looks_clean(text)
    for fact in (f"status='{res.status}'", f"n_bonds={bonds.n_bonds}", "families=1"):
        assert fact in text, (fact, text)
    assert f"relative_error={np.max(res.relative_error):.4g}" in text


@settings(max_examples=20, deadline=None)
@given(m=st.integers(min_value=1, max_value=N), dim=st.integers(min_value=1, max_value=3))
def test_condition_reprs_show_sets_and_values_without_arrays(m: int, dim: int) -> None:
    """Conditions given on m points (indices, per-point values, callables) stay one short line."""
    from pdlin.operators import BodyForce, TimePath

    idx = np.arange(m)
    conditions = [
        (pdlin.Dirichlet(idx, np.zeros((m, dim)), components=[0]), ["Dirichlet(", f"<{m} array>"]),
        (pdlin.Dirichlet("x-", 0.0), ["Dirichlet(where='x-', value=0)"]),
        (pdlin.Dirichlet("x+", lambda x: x[:, 0]), ["value=<function"]),
        (pdlin.Dirichlet("x+", TimePath(lambda x, t: t, "ramp")), ["TimePath(path='ramp')"]),
        (pdlin.TotalForce(idx, np.ones(dim), weights=np.ones(m)), ["TotalForce(", f"<{m} array>"]),
        (BodyForce(None, np.ones(dim)), ["BodyForce(density="]),
    ]
    for cond, facts in conditions:
        text = repr(cond)
        _looks_clean(text)
        for fact in facts:
            assert fact in text, (fact, text)


def test_constrained_system_repr_sizes_not_arrays() -> None:
    cloud = pdlin.grid((100, 100), spacing=0.01)  # 10^4 points
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        horizon=0.0201,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", [1.0, 0.0])],
    )
    text = repr(pdlin.system.constrained_system(prob))
    _looks_clean(text)
    # the x- edge: 100 points x 2 components prescribed (grid((100, 100)) has 100 per edge)
    for fact in ("ConstrainedSystem(", f"points={N}", "DOFs=20000", "prescribed=200"):
        assert fact in text, (fact, text)
