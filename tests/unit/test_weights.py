"""Unit tests of pdlin.models.weights (higher-order influence weights, Javaheri et al. (2022)).

Provenance of literal values: "paper Table k" is Javaheri et al. (2022), Tables 1-3; rows beyond the
paper ("all horizons") are reference values of pdlin's generator procedure
(docs/theory/conventions.md#higher-order-weights), checked in exact rational arithmetic; "derived"
marks closed forms worked out for pdlin (symbols, kernels, 1D weights).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import itertools
import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import sympy

import pdlin
from pdlin.errors import InputError, InputTypeError, ModelError, NoNeighborsError, ShapeError
from pdlin.models.weights import (
    HigherOrderWeights,
    WeightStatus,
    _lattice_points,
    _solve_shells,
    as_influence,
    gradient_exactness_order,
    gradient_symbol,
    higher_order_weights,
    lattice_moment,
    lattice_shells,
    moment_weights,
    nocontrol_weights,
    symbol_extremes,
    weights_table,
)

ROOT = Path(__file__).resolve().parents[2]
R = Fraction  # shorthand for exact expected values

VALID = WeightStatus.VALID
ZERO = WeightStatus.FARTHEST_WEIGHT_ZERO
SING = WeightStatus.SINGULAR_SHAPE_TENSOR
NONE = WeightStatus.NO_UNIQUE_SET

# all-horizons table (paper Tables 1-3 plus reference rows), row by row: (dim, s_max, order, weights
# by shell or None, Omega or None, status, augmented).  "aug" = augmented True.
ALL_HORIZONS = [
    # d = 1: paper Table 1 (δ = h, 2h, 3h, 4h)
    (1, 1, 2, [1], 2, VALID, False),
    (1, 4, 4, [1, R(-1, 16)], R(3, 2), VALID, False),
    (1, 9, 6, [1, R(-1, 10), R(1, 135)], R(4, 3), VALID, False),
    (1, 16, 8, [1, R(-1, 8), R(1, 63), R(-1, 896)], R(5, 4), VALID, False),
    # d = 2: paper Table 2 plus the excluded and beyond-the-paper reference rows
    (2, 1, 2, [1], 2, VALID, False),
    (2, 2, 2, [1, 0], 2, ZERO, True),
    (2, 4, 4, [1, 0, R(-1, 16)], R(3, 2), VALID, False),
    (2, 5, 4, [1, 0, R(-1, 16), 0], R(3, 2), ZERO, True),
    (2, 8, 6, [1, R(-2, 3), R(-1, 4), R(1, 6), R(-1, 24)], 0, SING, False),
    (2, 9, 6, [1, 0, R(-1, 10), 0, 0, R(1, 135)], R(4, 3), VALID, True),
    (2, 10, 6, [1, 0, R(-1, 10), 0, 0, R(1, 135), 0], R(4, 3), ZERO, True),
    (
        2,
        13,
        8,
        [1, R(-12, 17), R(-28, 85), R(39, 170), R(-6, 85), R(3, 85), R(-2, 85), R(1, 170)],
        0,
        SING,
        False,
    ),
    # reference row: "1D 4h weights on the axis shells (s = 1, 4, 9, 16), 0 elsewhere"
    (2, 16, 8, [1, 0, R(-1, 8), 0, 0, R(1, 63), 0, 0, R(-1, 896)], R(5, 4), VALID, True),
    # d = 3: paper Table 3 plus the reference rows
    (3, 1, 2, [1], 2, VALID, False),
    (3, 2, 2, [1, 0], 2, ZERO, True),
    (3, 3, 4, [1, R(-1, 2), R(1, 4)], 0, SING, False),
    (3, 4, 4, [1, 0, 0, R(-1, 16)], R(3, 2), VALID, True),
    (3, 5, 4, [1, 0, 0, R(-1, 16), 0], R(3, 2), ZERO, True),
    (3, 6, 6, [1, R(-11, 20), R(3, 10), R(-1, 10), R(1, 20), R(-1, 40)], 0, SING, False),
    (3, 8, 6, None, None, NONE, True),
    (
        3,
        9,
        6,
        [1, R(-80, 267), R(16, 89), R(-25, 178), R(14, 267), R(-8, 267), R(-2, 267), R(1, 267)],
        R(60, 89),
        VALID,
        True,
    ),
]


def _id(row: tuple) -> str:
    return f"{row[0]}D-s{row[1]}"


# --------------------------------------------------------------------------- generator (V1)


@pytest.mark.parametrize("row", ALL_HORIZONS, ids=_id)
def test_every_tabulated_horizon_matches_spec_table(row):
    """V1: weights, order, Omega, status and augmentation of every all-horizons row, exactly."""
    dim, s_max, order, weights, omega, status, augmented = row
    r = higher_order_weights(dim, math.sqrt(s_max))
    assert r.shells[-1] == s_max
    assert r.order == order
    assert r.status is status
    assert r.augmented is augmented
    if weights is None:
        assert r.weights is None and r.Omega is None
    else:
        got = [r.weights[s] for s in r.shells]
        assert all(isinstance(w, sympy.Rational) for w in got)
        assert got == [
            sympy.Rational(w.numerator, w.denominator) if isinstance(w, R) else w for w in weights
        ]
        assert r.Omega == sympy.Rational(Fraction(omega).numerator, Fraction(omega).denominator)


@pytest.mark.parametrize(
    ("dim", "rows"),
    [
        # paper Table 1 (1D), rows delta = h, 2h, 3h, 4h; columns omega_1..omega_4
        (1, [[1], [1, R(-1, 16)], [1, R(-1, 10), R(1, 135)], [1, R(-1, 8), R(1, 63), R(-1, 896)]]),
        # paper Table 2 (2D), rows h, 2h, 3h; columns omega_1..omega_6 (s = 1, 2, 4, 5, 8, 9)
        (2, [[1], [1, 0, R(-1, 16)], [1, 0, R(-1, 10), 0, 0, R(1, 135)]]),
        # paper Table 3 (3D), rows h, 2h, 3h; columns omega_1..omega_8 (s = 1..9 without 7)
        (
            3,
            [
                [1],
                [1, 0, 0, R(-1, 16)],
                [
                    1,
                    R(-80, 267),
                    R(16, 89),
                    R(-25, 178),
                    R(14, 267),
                    R(-8, 267),
                    R(-2, 267),
                    R(1, 267),
                ],
            ],
        ),
    ],
)
def test_paper_tables_are_the_valid_rows_of_weights_table(dim, rows):
    """Tables 1-3: the valid entries of weights_table are exactly the paper's rows."""
    valid = [r for r in weights_table(dim) if r.is_valid]
    assert [r.horizon_ratio for r in valid] == pytest.approx(list(range(1, len(rows) + 1)))
    for r, expected in zip(valid, rows, strict=True):
        got = [Fraction(int(w.p), int(w.q)) for w in (r.weights[s] for s in r.shells)]
        assert got == [Fraction(v) for v in expected]


def test_weights_table_statuses_and_default_ranges():
    """All-horizons table: every horizon up to 4h (1D) and 3h (2D, 3D) with its status."""
    expected = {
        1: ["valid"] * 4,  # d = 1 rows
        2: [
            "valid",
            "farthest weight zero",
            "valid",
            "farthest weight zero",
            "singular shape tensor",
            "valid",
        ],  # d = 2 rows up to 3h
        3: [
            "valid",
            "farthest weight zero",
            "singular shape tensor",
            "valid",
            "farthest weight zero",
            "singular shape tensor",
            "no unique set",
            "valid",
        ],
    }
    for dim, statuses in expected.items():
        table = weights_table(dim)
        assert [r.status.value for r in table] == statuses
        assert [str(r.status) for r in table] == statuses
    # an explicit max_ratio extends the 2D table to the beyond-the-paper reference rows
    assert [r.shells[-1] for r in weights_table(2, 4)] == [1, 2, 4, 5, 8, 9, 10, 13, 16]


def test_status_vocabulary_is_the_spec_vocabulary():
    # the generator's steps 3-4 (conventions.md#higher-order-weights): exactly these four outcomes
    assert {s.value for s in WeightStatus} == {
        "valid",
        "farthest weight zero",
        "singular shape tensor",
        "no unique set",
    }
    assert WeightStatus.VALID == "valid"


def test_shells_and_multiplicities():
    # shells of Javaheri et al. (2022), Sec. II.C.1 (|p|² values and multiplicities)
    assert lattice_shells(2, 3) == ((1, 2, 4, 5, 8, 9), (4, 4, 4, 8, 4, 4))
    assert lattice_shells(3, 3) == ((1, 2, 3, 4, 5, 6, 8, 9), (6, 12, 8, 6, 24, 24, 12, 30))
    assert lattice_shells(1, 4) == ((1, 4, 9, 16), (2, 2, 2, 2))


def test_membership_tolerance_and_any_horizon():
    # pdlin's horizon test: |p|^2 <= (delta/h)^2 (1 + 1e-12); a horizon between shells takes the
    # inner ones
    assert higher_order_weights(2, 2.0 * (1 - 1e-14)).shells[-1] == 4
    assert higher_order_weights(2, 2.0 * (1 - 1e-9)).shells[-1] == 2
    assert higher_order_weights(2, 2.1).shells == higher_order_weights(2, 2).shells
    assert higher_order_weights(2, sympy.sqrt(8)).status is SING  # reference row √8
    assert higher_order_weights(3, Fraction(3)).Omega == sympy.Rational(60, 89)  # paper Table 3


def test_float_access_and_offsets():
    r = higher_order_weights(3, 3)
    fw = r.float_weights
    assert fw[9] == pytest.approx(1 / 267, rel=1e-15)  # paper Table 3, omega_8
    assert r.Omega_float == pytest.approx(60 / 89, rel=1e-15)  # Javaheri et al. (2022), Table 3
    p, w = r.offsets()
    assert p.shape == (122, 3) and w.shape == (122,)  # 122 neighbours for 3D 3h
    # Omega = sum_bonds omega (xi_1/h)^2 (Javaheri et al. (2022), Eq. 18)
    assert float(np.sum(w * p[:, 0] ** 2)) == pytest.approx(60 / 89, rel=1e-14)
    # intact shape tensor K / (h^2 dV) = Omega I (Javaheri et al. (2022), Eq. 17)
    np.testing.assert_allclose(np.einsum("b,bi,bj->ij", w, p, p), 60 / 89 * np.eye(3), atol=1e-14)


def test_result_is_frozen_and_read_only():
    r = higher_order_weights(2, 2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.order = 8  # type: ignore[misc]
    with pytest.raises(TypeError):
        r.weights[1] = 2  # type: ignore[index]


def test_no_unique_set_has_no_weights():
    r = higher_order_weights(3, math.sqrt(8))  # reference row 3D √8: "no unique set"
    with pytest.raises(ModelError, match="no unique set"):
        _ = r.float_weights
    with pytest.raises(ModelError):
        r.offsets()


def test_results_are_cached():
    higher_order_weights(3, 3)
    assert _solve_shells.cache_info().currsize >= 1
    a = higher_order_weights(3, 3)
    b = higher_order_weights(3, 3.0000000000001)
    assert a._solved is b._solved


@pytest.mark.parametrize("m", [2, 3, 4, 5])
def test_1d_closed_form_and_fd_coefficients(m):
    """V6: omega_k = (-1)^(k+1)(m-1)!(m+1)!/(k^2 (m-k)!(m+k)!), Omega = (m+1)/m (derived,
    conventions.md#higher-order-weights)."""
    r = higher_order_weights(1, m)
    f = math.factorial
    for k in range(1, m + 1):
        closed = sympy.Rational((-1) ** (k + 1) * f(m - 1) * f(m + 1), k * k * f(m - k) * f(m + k))
        assert r.weights[k * k] == closed
    assert r.Omega == sympy.Rational(m + 1, m)
    a = [k * r.weights[k * k] / r.Omega for k in range(1, m + 1)]
    # derived: central-FD coefficients for m = 2, 3, 4 (m = 5: closed-form weights 1, -1/7, ...)
    fd = {
        2: ["2/3", "-1/12"],
        3: ["3/4", "-3/20", "1/60"],
        4: ["4/5", "-1/5", "4/105", "-1/280"],
        5: None,
    }[m]
    if fd is not None:
        assert [str(v) for v in a] == fd
    else:
        assert [str(r.weights[k * k]) for k in range(1, 6)] == [
            "1",
            "-1/7",
            "1/42",
            "-1/336",
            "1/5250",
        ]


# --------------------------------------------------------------------------- moments (V2)


def _all_exponents(dim: int, k: int):
    return [a for a in itertools.product(range(k + 1), repeat=dim) if sum(a) == k]


@pytest.mark.parametrize("row", [r for r in ALL_HORIZONS if r[5] is not NONE], ids=_id)
def test_moments_vanish_up_to_order(row):
    """V2: every moment (all monomials, not only the reduced ones) of order 3..order vanishes."""
    dim, s_max = row[:2]
    r = higher_order_weights(dim, math.sqrt(s_max))
    for k in range(3, r.order + 1):
        for e in _all_exponents(dim, k):
            assert lattice_moment(r, e) == 0, (k, e)
    # and the order is not higher than claimed: some moment of order order + 2 is nonzero
    assert any(lattice_moment(r, e) != 0 for e in _all_exponents(dim, r.order + 2))


@pytest.mark.parametrize(
    ("dim", "ratio", "exponents", "value"),
    [
        # derived first nonzero moments (units h^k)
        (1, 2, (6,), -6),
        (2, 2, (6, 0), -6),
        (3, 2, (6, 0, 0), -6),
        (1, 3, (8,), 48),
        (2, 3, (8, 0), 48),
        (1, 4, (10,), -720),
        (3, 3, (8, 0, 0), R(2160, 89)),
        (3, 3, (6, 2, 0), 0),
        (3, 3, (4, 4, 0), 0),
        (3, 3, (4, 2, 2), 0),
        (3, 3, (4, 4, 2), R(384, 89)),
        (3, 3, (10, 0, 0), R(30240, 89)),
    ],
)
def test_first_nonzero_moments(dim, ratio, exponents, value):
    got = lattice_moment(higher_order_weights(dim, ratio), exponents)
    v = Fraction(value)
    assert got == sympy.Rational(v.numerator, v.denominator)


def test_coefficient_rows_of_spec_tables():
    """Moment coefficient rows (Javaheri et al. (2022), Eqs. 19-26; (3D table, rows x^4, x^2y^2z^2,
    x^8) from lattice_moment."""
    shells = (1, 2, 3, 4, 5, 6, 8, 9)
    rows = {
        (4, 0, 0): [2, 8, 8, 32, 136, 144, 128, 426],
        (2, 2, 2): [0, 0, 8, 0, 0, 96, 0, 384],
        (8, 0, 0): [2, 8, 8, 512, 2056, 2064, 2048, 17226],
        (4, 2, 2): [0, 0, 8, 0, 0, 192, 0, 1152],
    }
    for e, expected in rows.items():
        got = [lattice_moment({s: 1}, e, dim=3) for s in shells]
        assert got == expected, e


# --------------------------------------------------------------------------- exactness (V4, V5)


@pytest.mark.parametrize("row", [r for r in ALL_HORIZONS if r[5] in (VALID, ZERO)], ids=_id)
def test_gradient_exactness_order_equals_order(row):
    """Derived: an O(h^2n) set gives the exact F for polynomials of degree <= 2n."""
    dim, s_max, order = row[:3]
    assert gradient_exactness_order(higher_order_weights(dim, math.sqrt(s_max))) == order


def test_gradient_exactness_order_detects_perturbation_and_float_sets():
    r = higher_order_weights(2, 3)
    w = dict(r.weights)
    w[9] = w[9] + sympy.Rational(1, 10**12)  # break the O(h^6) conditions slightly
    assert gradient_exactness_order(w, dim=2) == 2  # exact comparison sees 1e-12
    # Fractions are exact too: the 1D δ = 2h set of paper Table 1
    assert gradient_exactness_order({1: Fraction(1), 4: Fraction(-1, 16)}, dim=1) == 4
    # the 'no control' set omega = 1/|xi| is only second order (reference values)
    assert gradient_exactness_order(nocontrol_weights(2, 3), dim=2) == 2
    with pytest.raises(ModelError, match="Omega"):
        gradient_exactness_order(higher_order_weights(2, math.sqrt(8)))  # reference row: Omega = 0


def _nonlocal_gradient(p, w, h, x0, u):
    xi = p * h
    dy = u(x0 + xi) - u(x0[None])
    omega = float(np.sum(w * p[:, 0] ** 2))
    return np.einsum("b,bi,bj->ij", w, dy, xi) / (h * h * omega)


@pytest.mark.parametrize(("dim", "ratio"), [(1, 2), (1, 4), (2, 3), (3, 2), (3, 3)])
def test_polynomial_exactness_in_floating_point(dim, ratio):
    """V4: h = 0.1, degree <= 2n*: error < 1e-12; degree 2n* + 1: error > 1e-7."""
    r = higher_order_weights(dim, ratio)
    p, w = r.offsets()
    p = p.astype(float)
    h = 0.1
    x0 = np.full(dim, 0.05)
    c = np.array([0.9, -0.6, 0.5])[:dim]

    def poly(k):
        # u_i = (c . x + 0.3)^k e_i: every monomial direction of degree k appears
        def u(x):
            return np.repeat(((x @ c) + 0.3)[:, None] ** k, dim, axis=1)

        def grad(x):
            return np.outer(np.full(dim, k * ((x @ c) + 0.3) ** (k - 1)), c)

        return u, grad

    for k in range(1, r.order + 2):
        u, grad = poly(k)
        err = np.max(np.abs(_nonlocal_gradient(p, w, h, x0, u) - grad(x0)))
        if k <= r.order:
            assert err < 1e-12, (k, err)
        else:
            assert err > 1e-7, (k, err)


def test_v5_gradient_errors_2d():
    """V5 (reference values of an independent implementation): 2D u = (sin x cos 0.7y, e^0.3x sin y)
    at (0.3, 0.2), h = 0.1, ±1 %."""
    x0 = np.array([0.3, 0.2])

    def u(x):
        return np.stack(
            [np.sin(x[:, 0]) * np.cos(0.7 * x[:, 1]), np.exp(0.3 * x[:, 0]) * np.sin(x[:, 1])], 1
        )

    exact = np.array(
        [
            [np.cos(0.3) * np.cos(0.14), -0.7 * np.sin(0.3) * np.sin(0.14)],
            [0.3 * np.exp(0.09) * np.sin(0.2), np.exp(0.09) * np.cos(0.2)],
        ]
    )
    expected = {  # reference values (V5): HO h / 2h / 3h and none 2h / 3h at h = 0.1
        ("ho", 1): 1.79e-3,
        ("ho", 2): 3.57e-6,
        ("ho", 3): 7.64e-9,
        ("none", 2): 4.45e-3,
        ("none", 3): 9.94e-3,
    }
    for (kind, ratio), value in expected.items():
        if kind == "ho":
            p, w = higher_order_weights(2, ratio).offsets()
        else:
            nc = nocontrol_weights(2, ratio)
            shells, pts = _lattice_points(2, max(nc))
            p = np.concatenate([q.astype(np.int64) for q in pts])
            w = np.concatenate([np.full(len(q), nc[s]) for s, q in zip(shells, pts, strict=True)])
        err = np.max(np.abs(_nonlocal_gradient(p.astype(float), w, 0.1, x0, u) - exact))
        assert err == pytest.approx(value, rel=0.01), (kind, ratio)


# --------------------------------------------------------------------------- symbol (§4, V7, V8)


@functools.cache
def _ho_extremes(dim: int, ratio: int) -> dict:
    return symbol_extremes(higher_order_weights(dim, ratio))


@pytest.mark.parametrize(
    ("dim", "ratio", "min_value", "max_value"),
    [
        # reference values (symbol extremes): min |g|h (1D value in every d) and max |g|h 1D/2D/3D
        (1, 1, 0.7071, 1.000),
        (2, 1, 0.7071, 1.414),
        (3, 1, 0.7071, 1.732),
        (1, 2, 0.7761, 1.372),
        (2, 2, 0.7761, 1.941),
        (3, 2, 0.7761, 2.377),
        (1, 3, 0.7842, 1.586),
        (2, 3, 0.7842, 2.243),
        (3, 3, 0.7842, 11.86),
        (1, 4, 0.7852, 1.731),
    ],
)
def test_symbol_extremes_of_ho_sets(dim, ratio, min_value, max_value):
    r = higher_order_weights(dim, ratio)
    ext = _ho_extremes(dim, ratio)
    assert round(ext["min"], 4) == min_value
    digits = 2 if max_value > 10 else 3  # as recorded in the reference table
    assert round(ext["max"], digits) == max_value
    # derived: the HO minimum is attained on an axis at theta = pi/4
    axis = np.zeros(dim)
    axis[0] = np.pi / 4
    assert np.linalg.norm(gradient_symbol(r, axis)) == pytest.approx(ext["min"], abs=1e-9)


def test_symbol_argmax_3d_3h():
    # reference value: max 11.86 at theta ≈ (1.217, 0.783, 0.783) pi; |g| is invariant under sign
    # flips and permutations of theta, so compare |theta mod 2pi folded to [0, pi]|
    ext = _ho_extremes(3, 3)
    folded = np.sort(np.pi - np.abs(np.pi - np.mod(ext["argmax"], 2 * np.pi)))
    ref = np.sort(
        np.pi - np.abs(np.pi - np.mod(np.array([1.217, 0.783, 0.783]) * np.pi, 2 * np.pi))
    )
    np.testing.assert_allclose(folded / np.pi, ref / np.pi, atol=0.01)


@pytest.mark.parametrize(
    ("dim", "ratio", "max_value"),
    # reference values, row "none 2h / 3h": max 0.587, 0.417 / 0.784, 0.499 / 0.838, 0.544
    [(1, 2, 0.587), (1, 3, 0.417), (2, 2, 0.784), (2, 3, 0.499), (3, 2, 0.838), (3, 3, 0.544)],
)
def test_symbol_extremes_of_nocontrol_sets(dim, ratio, max_value):
    ext = symbol_extremes(nocontrol_weights(dim, ratio), dim=dim)
    assert round(ext["max"], 3) == max_value
    # derived / reference: min 0 in 1D, <= 0.01 in 2D/3D
    assert ext["min"] <= (1e-9 if dim == 1 else 0.01)


def test_nocontrol_zeros_and_near_zeros():
    # derived: 1D zeros at 2π/3 (2h); π/2, 2π/3 (3h); π/2, 2π/5, 4π/5 (4h); V7: 1e-12
    zeros = {2: [2 / 3], 3: [1 / 2, 2 / 3], 4: [1 / 2, 2 / 5, 4 / 5]}
    for ratio, thetas in zeros.items():
        g = gradient_symbol(nocontrol_weights(1, ratio), np.array(thetas) * np.pi, dim=1)
        assert np.max(np.abs(g)) < 1e-12
    # 2D/3D near-zeros with |g|h <= 0.01 near (0.63, 0.63)π (2D 3h) and (0, 1.38, 0)π (3D 3h)
    g2 = gradient_symbol(nocontrol_weights(2, 3), np.array([0.63, 0.63]) * np.pi)
    g3 = gradient_symbol(nocontrol_weights(3, 3), np.array([0.0, 1.38, 0.0]) * np.pi)
    assert np.linalg.norm(g2) <= 0.01 and np.linalg.norm(g3) <= 0.01
    # and the HO sets have no such zeros there (derived: their symbols are the central-FD
    # wavenumbers)
    assert np.linalg.norm(gradient_symbol(higher_order_weights(2, 3), [0.63 * np.pi] * 2)) > 0.5


@pytest.mark.parametrize(("dim", "ratio"), [(1, 1), (1, 4), (2, 3), (3, 2), (3, 3)])
def test_symbol_vanishes_on_checkerboard_and_matches_theta_at_long_waves(dim, ratio):
    r = higher_order_weights(dim, ratio)
    corners = np.array(list(itertools.product((0.0, np.pi), repeat=dim)))
    # derived (conventions.md#higher-order-weights): g = 0 on {0, π}^d for every centrally symmetric
    # set
    assert np.max(np.abs(gradient_symbol(r, corners))) < 1e-13
    theta = np.full((1, dim), 1e-3)
    np.testing.assert_allclose(gradient_symbol(r, theta), theta, rtol=1e-6)


@pytest.mark.parametrize(
    ("weights", "dim", "expected"),
    [
        # derived periodic kernels (V8): 2^d for δ = h and HO; 1D n = 24: 4 (none 2h), 6 (3h)
        (("ho", 1), 1, 2),
        (("ho", 4), 1, 2),
        (("ho", 1), 2, 4),
        (("ho", 3), 2, 4),
        (("ho", 2), 3, 8),
        (("ho", 3), 3, 8),
        (("none", 2), 1, 4),
        (("none", 3), 1, 6),
    ],
)
def test_periodic_kernel_dimension(weights, dim, expected):
    kind, ratio = weights
    n = 24
    axis = 2 * np.pi * np.arange(n) / n
    theta = np.stack(np.meshgrid(*([axis] * dim), indexing="ij"), -1).reshape(-1, dim)
    w = higher_order_weights(dim, ratio) if kind == "ho" else nocontrol_weights(dim, ratio)
    g = gradient_symbol(w, theta, dim=dim)
    assert int(np.sum(np.linalg.norm(g, axis=-1) < 1e-10)) == expected


def test_gradient_symbol_shapes_and_errors():
    r1 = higher_order_weights(1, 2)
    assert gradient_symbol(r1, 0.5).shape == (1,)
    assert gradient_symbol(r1, np.zeros((4, 1))).shape == (4, 1)
    assert gradient_symbol(r1, np.zeros(5)).shape == (5, 1)
    r2 = higher_order_weights(2, 2)
    assert gradient_symbol(r2, np.zeros((3, 4, 2))).shape == (3, 4, 2)
    with pytest.raises(ShapeError, match=r"theta must have shape \(\.\.\., 2\)"):
        gradient_symbol(r2, np.zeros((3, 3)))
    with pytest.raises(InputError, match="sums of 2 squares"):
        gradient_symbol({1: 1.0, 3: 1.0}, np.zeros(2), dim=2)
    with pytest.raises(InputTypeError):
        gradient_symbol([1.0, 2.0], np.zeros(2))
    with pytest.raises(ModelError, match="Omega"):
        gradient_symbol(higher_order_weights(3, math.sqrt(6)), np.zeros(3))  # Omega = 0
    # chunking does not change the result
    th = np.random.default_rng(1).uniform(0, np.pi, size=(50, 2))
    np.testing.assert_array_equal(gradient_symbol(r2, th, chunk=7), gradient_symbol(r2, th))


# --------------------------------------------------------------------------- influence callable


def test_as_influence_maps_lengths_to_shell_weights():
    r = higher_order_weights(3, 3)
    f = as_influence(r, h=0.25)
    lengths = 0.25 * np.sqrt(np.array([1.0, 2, 3, 4, 5, 6, 8, 9]))
    np.testing.assert_allclose(
        f(lengths, 0.75), [float(r.weights[s]) for s in r.shells], rtol=1e-15
    )  # paper Table 3 via the exact weights
    assert f(np.array([[0.25, 0.75]]), None).shape == (1, 2)
    assert "3D" in repr(f)
    # tolerance: lengths within rtol of a shell are accepted
    assert f([0.25 * (1 + 1e-12)], 0.75)[0] == 1.0
    with pytest.raises(InputError, match=r"length must be a lattice bond length.*got 0\.3"):
        f([0.3], 0.75)
    with pytest.raises(InputError, match="sqrt"):
        f([0.25 * math.sqrt(7)], 0.75)  # s = 7 is not a sum of three squares
    with pytest.raises(InputError):
        f([0.25 * 4], 0.75)  # s = 16 is outside the set


def test_as_influence_refuses_invalid_sets_and_bad_h():
    with pytest.raises(ModelError, match="status 'valid'"):
        as_influence(higher_order_weights(2, math.sqrt(8)), 1.0)
    f = as_influence(higher_order_weights(2, math.sqrt(5)), 1.0, require_valid=False)
    assert f([math.sqrt(5)], 3.0)[0] == 0.0  # reference row: √5 set has ω_S = 0
    with pytest.raises(ModelError, match="no unique set"):
        as_influence(higher_order_weights(3, math.sqrt(8)), 1.0, require_valid=False)
    with pytest.raises(InputError, match="h must be"):
        as_influence(higher_order_weights(2, 2), 0.0)
    with pytest.raises(InputTypeError):
        as_influence({1: 1}, 1.0)  # type: ignore[arg-type]


def test_as_influence_with_find_bonds_delta_h():
    cloud = pdlin.grid((6, 6))
    h = float(np.max(cloud.lattice.spacing))
    bonds = pdlin.find_bonds(
        cloud, ratio=1.0, influence=as_influence(higher_order_weights(2, 1), h)
    )
    np.testing.assert_array_equal(bonds.omega, 1.0)  # paper Table 2, δ = h


def test_as_influence_with_find_bonds_negative_weights():
    cloud = pdlin.grid((8, 8))
    h = float(np.max(cloud.lattice.spacing))
    r = higher_order_weights(2, 2)
    with pytest.raises(InputError, match="allow_negative_influence=True"):
        pdlin.find_bonds(cloud, ratio=2.0, influence=as_influence(r, h))
    bonds = pdlin.find_bonds(
        cloud, ratio=2.0, influence=as_influence(r, h), allow_negative_influence=True
    )
    assert np.isclose(bonds.omega.min(), -1 / 16)  # paper Table 2, ω_3 at δ = 2h
    with pytest.raises(pdlin.errors.ModelError, match="energy positivity"):
        pdlin.assemble_stiffness(pdlin.BondBased(micromodulus=1.0), cloud, bonds)


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("dim", [0, 4, -1])
def test_bad_dim(dim):
    with pytest.raises(InputError, match=f"dim must be 1, 2 or 3, got {dim}"):
        higher_order_weights(dim, 2)


@pytest.mark.parametrize("dim", [2.0, "2", True, None])
def test_bad_dim_type(dim):
    with pytest.raises(InputTypeError, match="dim must be an int"):
        higher_order_weights(dim, 2)  # type: ignore[arg-type]


@pytest.mark.parametrize("ratio", [0, -1.0, float("nan"), float("inf")])
def test_bad_ratio(ratio):
    with pytest.raises(InputError, match="horizon_ratio must be a finite number > 0"):
        higher_order_weights(2, ratio)


@pytest.mark.parametrize("ratio", ["two", None, True])
def test_bad_ratio_type(ratio):
    with pytest.raises(InputTypeError, match="horizon_ratio must be a real number"):
        higher_order_weights(2, ratio)  # type: ignore[arg-type]


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_ratio_below_one_has_no_neighbours(dim):
    with pytest.raises(NoNeighborsError, match=r"horizon_ratio must be >= 1.*got 0\.9"):
        higher_order_weights(dim, 0.9)
    with pytest.raises(NoNeighborsError):
        weights_table(dim, 0.5)


def test_weights_table_bad_max_ratio():
    with pytest.raises(InputError, match="max_ratio must be a finite number > 0"):
        weights_table(2, -3)


def test_lattice_moment_bad_input():
    with pytest.raises(InputError, match="exponents must be 2 integers"):
        lattice_moment(higher_order_weights(2, 2), (4,))
    with pytest.raises(InputError, match="dim must be given"):
        lattice_moment({1: 1}, (4,))
    with pytest.raises(InputError, match="empty"):
        lattice_moment({}, (4,), dim=1)


# --------------------------------------------------------------------------- numeric path


def _lattice_family(dim, s_max):
    shells, pts = _lattice_points(dim, s_max)
    p = np.concatenate([q.astype(float) for q in pts])
    s = np.concatenate([np.full(len(q), v) for v, q in zip(shells, pts, strict=True)])
    return p, s


@pytest.mark.parametrize(("dim", "ratio"), [(1, 2), (1, 3), (1, 4), (2, 1), (2, 2)])
def test_moment_weights_agree_with_exact_path_on_unique_sets(dim, ratio):
    """Unique (non-augmented) lattice sets: numeric min-norm = exact, up to ω₁ = 1
    (conventions.md#higher-order-weights)."""
    r = higher_order_weights(dim, ratio)
    p, s = _lattice_family(dim, r.shells[-1])
    h = 0.01
    mw = moment_weights(p * h, np.full(len(p), h**dim), r.order)
    w = mw.omega / mw.omega[s == 1][0]
    exact = np.array([float(r.weights[int(v)]) for v in s])
    np.testing.assert_allclose(w, exact, rtol=1e-10, atol=1e-12)
    assert mw.residual[0] < 1e-12 and mw.shape_tensor_ratio[0] > 1e-3


@pytest.mark.parametrize(("dim", "ratio"), [(2, 3), (3, 2), (3, 3)])
def test_moment_weights_differ_on_augmented_sets(dim, ratio):
    """conventions.md#higher-order-weights: least-squares/minimum-norm solvers differ where step 3
    applies."""
    r = higher_order_weights(dim, ratio)
    assert r.augmented
    p, s = _lattice_family(dim, r.shells[-1])
    mw = moment_weights(p, np.ones(len(p)), r.order)
    w = mw.omega / mw.omega[s == 1][0]
    exact = np.array([float(r.weights[int(v)]) for v in s])
    assert np.max(np.abs(w - exact)) > 0.1
    # ... but the numeric set satisfies the same moment conditions (exact to degree `order`)
    assert mw.residual[0] < 1e-12
    sums = [
        np.sum(mw.omega * np.prod(p ** np.array(e), axis=1))
        for k in range(3, r.order + 2)
        for e in _all_exponents(dim, k)
    ]
    assert np.max(np.abs(sums)) < 1e-9 * np.sum(np.abs(mw.omega))


def test_moment_weights_batched_irregular_families(rng):
    """Batched result = per-family results; the corrected gradient is exact to degree 2."""
    fams = []
    for n in (20, 27, 33):
        x = rng.uniform(-2.2, 2.2, size=(n, 2))
        fams.append(x[np.linalg.norm(x, axis=1) > 0.3])
    xi = np.vstack(fams)
    vol = rng.uniform(0.5, 1.5, size=len(xi))
    indptr = np.concatenate([[0], np.cumsum([len(f) for f in fams])])
    base = rng.uniform(0.5, 1.0, size=len(xi))
    batched = moment_weights(xi, vol, 2, indptr=indptr, base=base, chunk=2)
    for k in range(3):
        sl = slice(indptr[k], indptr[k + 1])
        single = moment_weights(xi[sl], vol[sl], 2, base=base[sl])
        np.testing.assert_allclose(batched.omega[sl], single.omega, rtol=1e-10, atol=1e-12)
    assert batched.n_conditions == 4  # degree-2 exactness: the 4 moments of degree 3 in 2D
    assert np.all(batched.residual < 1e-12)
    # polynomial of degree 2 through F = (Σ ω V dy ⊗ ξ) K⁻¹ on the first (irregular) family
    sl = slice(indptr[0], indptr[1])
    x, w, v = xi[sl], batched.omega[sl], vol[sl]
    x0 = np.array([0.4, -0.2])

    def u(y):
        return np.stack([y[:, 0] ** 2 + 3 * y[:, 0] * y[:, 1], y[:, 1] ** 2 - y[:, 0]], 1)

    grad = np.array([[2 * x0[0] + 3 * x0[1], 3 * x0[0]], [-1.0, 2 * x0[1]]])
    dy = u(x0 + x) - u(x0[None])
    k = np.einsum("b,bi,bj->ij", w * v, x, x)
    f = np.einsum("b,bi,bj->ij", w * v, dy, x) @ np.linalg.inv(k)
    np.testing.assert_allclose(f, grad, atol=1e-10)
    # the uncorrected base weights are not exact (the test can fail)
    k0 = np.einsum("b,bi,bj->ij", base[sl] * v, x, x)
    f0 = np.einsum("b,bi,bj->ij", base[sl] * v, dy, x) @ np.linalg.inv(k0)
    assert np.max(np.abs(f0 - grad)) > 1e-3


def test_moment_weights_order_one_returns_base_and_flags_empty_null_space():
    xi = np.array([[-1.0], [1.0]])
    np.testing.assert_array_equal(moment_weights(xi, [1.0, 1.0], 1).omega, [1.0, 1.0])
    # δ = h in 1D cannot be made 4th order: only ω = 0 remains, flagged by the ratio
    mw = moment_weights(xi, [1.0, 1.0], 4)
    assert np.allclose(mw.omega, 0.0) and abs(mw.shape_tensor_ratio[0]) < 1e-12


def test_moment_weights_bad_input():
    xi = np.zeros((4, 2)) + 1.0
    with pytest.raises(ShapeError, match="xi must have shape"):
        moment_weights(np.zeros((4, 4)), np.ones(4), 2)
    with pytest.raises(ShapeError, match=r"volumes must have shape \(4,\)"):
        moment_weights(xi, np.ones(3), 2)
    with pytest.raises(InputError, match="volumes must be > 0"):
        moment_weights(xi, np.zeros(4), 2)
    with pytest.raises(InputError, match="order must be an int >= 1"):
        moment_weights(xi, np.ones(4), 0)
    with pytest.raises(ShapeError, match="indptr"):
        moment_weights(xi, np.ones(4), 2, indptr=[0, 3])
    with pytest.raises(ShapeError, match="base"):
        moment_weights(xi, np.ones(4), 2, base=np.ones(2))


# --------------------------------------------------------------------------- docs


def test_docs_weight_tables_are_up_to_date():
    """docs/weights.md holds exactly the output of docs/gen_weight_tables.py."""
    spec = importlib.util.spec_from_file_location(
        "gen_weight_tables", ROOT / "docs" / "gen_weight_tables.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    doc = (ROOT / "docs" / "weights.md").read_text(encoding="utf-8")
    start, end = doc.index(mod.BEGIN), doc.index(mod.END) + len(mod.END)
    assert doc[start:end] == mod.render()


def test_top_level_exports():
    assert pdlin.higher_order_weights is higher_order_weights
    assert pdlin.HigherOrderWeights is HigherOrderWeights
    assert pdlin.models.weights_table is weights_table


def test_docs_examples_run():
    """The examples of docs/weights.md are doctests; keep them true."""
    import doctest

    res = doctest.testfile(
        str(ROOT / "docs" / "weights.md"),
        module_relative=False,
        optionflags=doctest.NORMALIZE_WHITESPACE,
    )
    assert res.attempted >= 8
    assert res.failed == 0
