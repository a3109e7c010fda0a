"""Unit tests of pdlin.constitutive: elasticity tensors (Prakash, anisotropic micromoduli: Eq. 29,
Eq. 49, Appendix A and the materials of Sec. 4.1; docs/theory/conventions.md#voigt-notation and
conventions.md#frobenius-norm-of-a-stiffness-tensor; the 2D forms are pdlin's extension)."""

from __future__ import annotations

import doctest
import inspect
import itertools
from pathlib import Path

import numpy as np
import pytest

from pdlin import constitutive as pc
from pdlin.errors import InputError, NonFiniteError, ShapeError

CLASSES = list(pc.SYMMETRY_CLASSES)


def random_spd(n: int, seed: int) -> np.ndarray:
    """Random symmetric positive definite Voigt matrix (well conditioned)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


def random_rotation(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def bond_tensor(xi: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Prakash, anisotropic micromoduli, Eq. 29 (ω = ΔV = 1): C_ijkl = ½ Σ c ξiξjξkξl/|ξ|³ — Cauchy
    by construction."""
    r = np.linalg.norm(xi, axis=1)
    return 0.5 * np.einsum("n,ni,nj,nk,nl->ijkl", c / r**3, xi, xi, xi, xi)


# Sample parameters per class (positive definite), in constructor order.
PARAMS = {
    "triclinic": (random_spd(6, 0),),
    "monoclinic": (135, 13, 269, 19, 54, 15, 14, 66, 18, 42, 6, 18, 25),  # CoTeO4, Eq. 56
    "orthotropic": (143, 3, 102, 1, 37, 3, 2, 46, 1),  # Te2W, Eq. 62
    "trigonal": (464, 493, 159, 141, -45, 125),  # Ta2C, Eq. 69
    "tetragonal": (212, 179, 70, 58, 58, 85),  # Si, Eq. 75
    "transversely_isotropic": (499, 714, 177, 235, 241),  # MoN, Eq. 81
    "cubic": (252, 145, 142),  # spinel, Eq. 87
    "isotropic": (86.0, 0.25),  # Pyroceram E, nu, Eq. 94
}


def construct(name: str) -> np.ndarray:
    return pc.SYMMETRY_CLASSES[name](*PARAMS[name])


# --------------------------------------------------------------------------- formats


@pytest.mark.parametrize("n", [6, 3])
def test_voigt_tensor_mandel_round_trips(n):
    C = random_spd(n, 1)
    T = pc.voigt_to_tensor(C)
    dim = 3 if n == 6 else 2
    assert T.shape == (dim,) * 4
    # all 8 index symmetries of a stiffness tensor hold exactly
    for perm in [(1, 0, 2, 3), (0, 1, 3, 2), (2, 3, 0, 1)]:
        np.testing.assert_array_equal(T, T.transpose(perm))
    np.testing.assert_array_equal(pc.tensor_to_voigt(T), C)
    np.testing.assert_allclose(pc.mandel_to_voigt(pc.voigt_to_mandel(C)), C, rtol=1e-15)


def test_voigt_is_plain_no_shear_factor():
    C = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    T = pc.voigt_to_tensor(C)
    # conventions.md#voigt-notation: 4 -> 23, 5 -> 31, 6 -> 12 and C̃44 = C2323 (no factor 2)
    assert T[1, 2, 1, 2] == T[2, 1, 1, 2] == 4.0
    assert T[2, 0, 0, 2] == 5.0
    assert T[0, 1, 1, 0] == 6.0
    assert T[0, 0, 0, 0] == 1.0 and T[2, 2, 2, 2] == 3.0
    # Mandel: shear diagonal x2 (√2 on row and column)
    np.testing.assert_allclose(np.diag(pc.voigt_to_mandel(C)), [1, 2, 3, 8, 10, 12])
    # 2D order 11, 22, 12 (pdlin's 2D extension)
    T2 = pc.voigt_to_tensor(np.diag([1.0, 2.0, 3.0]))
    assert T2[0, 1, 1, 0] == 3.0 and T2[1, 1, 1, 1] == 2.0


def test_frobenius_multiplicity_matches_spec():
    # conventions.md#frobenius-norm-of-a-stiffness-tensor: m = 1 (α=β≤3), 2 (α<β≤3), 4 (α≤3<β), 4
    # (α=β>3), 8 (3<α<β); written out
    expected = [1, 2, 2, 4, 4, 4, 1, 2, 4, 4, 4, 1, 4, 4, 4, 4, 8, 8, 4, 8, 4]
    assert pc.frobenius_multiplicity(3).tolist() == expected
    assert pc.frobenius_multiplicity(3).sum() == 81  # 3**4 components
    assert pc.frobenius_multiplicity(2).tolist() == [1, 2, 4, 1, 4, 4]  # pdlin's 2D extension
    assert pc.frobenius_multiplicity(2).sum() == 16  # 2**4 components
    with pytest.raises(InputError, match="dim must be 2 or 3, got 4"):
        pc.frobenius_multiplicity(4)


def test_voigt_upper_order():
    C = np.zeros((6, 6))
    C[np.triu_indices(6)] = np.arange(21.0)
    C = C + np.triu(C, 1).T
    # row-major upper triangle: C11, C12, ..., C16, C22, ...
    assert pc.voigt_upper(C).tolist() == list(range(21))
    assert pc.voigt_upper(pc.voigt_to_tensor(C)).tolist() == list(range(21))


@pytest.mark.parametrize("n", [6, 3])
def test_frobenius_norms_agree(n):
    C = random_spd(n, 2)
    full = float(np.linalg.norm(pc.voigt_to_tensor(C)))
    mandel = float(np.linalg.norm(pc.voigt_to_mandel(C)))
    dim = 3 if n == 6 else 2
    weighted = float(np.linalg.norm(np.sqrt(pc.frobenius_multiplicity(dim)) * pc.voigt_upper(C)))
    assert mandel == pytest.approx(full, rel=1e-14)
    assert weighted == pytest.approx(full, rel=1e-14)
    assert pc.frobenius_norm(C) == pytest.approx(full, rel=1e-14)
    # the plain Voigt 6x6 norm is not the tensor norm (shear entries undercounted)
    assert float(np.linalg.norm(C)) < 0.99 * full


# --------------------------------------------------------------------------- rotations


def test_rotate_round_trip_and_formats():
    C = random_spd(6, 3)
    Q = random_rotation(4)
    Cr = pc.rotate(C, Q)
    assert pc.frobenius_norm(Cr - C) > 0.1 * pc.frobenius_norm(C)  # it did change
    np.testing.assert_allclose(pc.rotate(Cr, Q.T), C, rtol=0, atol=1e-12 * np.abs(C).max())
    # tensor input -> tensor output, same values
    Tr = pc.rotate(pc.voigt_to_tensor(C), Q)
    assert Tr.shape == (3, 3, 3, 3)
    np.testing.assert_allclose(pc.tensor_to_voigt(Tr), Cr, atol=1e-12 * np.abs(C).max())
    # composition: rotate by Q1 then Q2 == rotate by Q2 Q1
    Q2 = random_rotation(5)
    np.testing.assert_allclose(
        pc.rotate(pc.rotate(C, Q), Q2), pc.rotate(C, Q2 @ Q), atol=1e-12 * np.abs(C).max()
    )


def test_rotate_preserves_energy_of_rotated_strain():
    # independent check of Eq. 44: ε':C':ε' = ε:C:ε with ε' = Q ε Qᵀ
    C = random_spd(6, 6)
    Q = random_rotation(7)
    eps = np.random.default_rng(8).normal(size=(3, 3))
    eps = eps + eps.T
    T, Tr = pc.voigt_to_tensor(C), pc.voigt_to_tensor(pc.rotate(C, Q))
    epsr = Q @ eps @ Q.T
    e0 = np.einsum("ij,ijkl,kl", eps, T, eps)
    e1 = np.einsum("ij,ijkl,kl", epsr, Tr, epsr)
    assert e1 == pytest.approx(e0, rel=1e-13)


def test_rotate_quarter_turn_permutes_axes():
    C = pc.orthotropic(1, 2, 3, 0.1, 0.2, 0.3, 4, 5, 6)
    Q = pc.rotation_matrix([0, 0, 1], np.pi / 2)  # x -> y, y -> -x
    Cr = pc.rotate(C, Q)
    # hand-derived: axes 1 and 2 swap, so C11<->C22, C13<->C23, C44<->C55
    expected = pc.orthotropic(2, 1, 3, 0.1, 0.3, 0.2, 5, 4, 6)
    np.testing.assert_allclose(Cr, expected, atol=1e-14)


def test_rotate_2d():
    C = random_spd(3, 9)
    t = 0.7
    Q = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    np.testing.assert_allclose(pc.rotate(pc.rotate(C, Q), Q.T), C, atol=1e-12 * C.max())
    # 2D isotropic is invariant (plane stress ν = 0.3)
    Ciso = pc.isotropic_2d(1.0, 0.3)
    np.testing.assert_allclose(pc.rotate(Ciso, Q), Ciso, atol=1e-15)


def test_isotropic_invariant_cubic_not():
    Ciso = pc.material("isotropic")
    Ccub = pc.material("cubic")
    for seed in range(5):
        Q = random_rotation(seed)
        assert pc.is_symmetric_under(Ciso, Q, rtol=1e-13)
        assert pc.symmetry_distance(Ccub, Q) > 1e-2  # generic rotation breaks cubic
    for Q in pc.symmetry_group("cubic"):
        assert pc.is_symmetric_under(Ccub, Q, rtol=1e-13)


# --------------------------------------------------------------------------- symmetry classes


def _voigt_basis() -> list[np.ndarray]:
    basis = []
    for a, b in zip(*np.triu_indices(6), strict=True):
        E = np.zeros((6, 6))
        E[a, b] = E[b, a] = 1.0
        basis.append(E)
    return basis


def _invariant_dims(group: list[np.ndarray]) -> tuple[int, int]:
    """Dimensions of the Q-invariant subspace of the 21-dim Voigt space, and of its
    intersection with the Cauchy subspace, computed without any constructor."""
    basis = _voigt_basis()
    rows = []
    for Q in group:
        A = np.column_stack([pc.voigt_upper(pc.rotate(E, Q) - E) for E in basis])
        rows.append(A)
    A = np.vstack(rows)
    P = np.column_stack([pc.voigt_upper(pc.cauchy_projection(E) - E) for E in basis])
    d_inv = 21 - np.linalg.matrix_rank(A, tol=1e-9)
    d_cauchy = 21 - np.linalg.matrix_rank(np.vstack([A, P]), tol=1e-9)
    return int(d_inv), int(d_cauchy)


@pytest.mark.parametrize("name", CLASSES)
def test_group_invariant_dimension_matches_spec_table(name):
    d_inv, d_cauchy = _invariant_dims(pc.symmetry_group(name))
    # derived from Prakash, anisotropic micromoduli, Eq. 49: "classical -> with Cauchy"
    expected = {
        "triclinic": (21, 15), "monoclinic": (13, 9), "orthotropic": (9, 6),
        "trigonal": (6, 4), "tetragonal": (6, 4), "transversely_isotropic": (5, 3),
        "cubic": (3, 2), "isotropic": (2, 1),
    }[name]  # fmt: skip
    assert (d_inv, d_cauchy) == expected
    assert (pc.N_CONSTANTS[name], pc.N_CONSTANTS_CAUCHY[name]) == expected


@pytest.mark.parametrize("name", CLASSES)
def test_constructor_symmetric_under_its_group(name):
    C = construct(name)
    assert C.shape == (6, 6)
    for Q in pc.symmetry_group(name):
        np.testing.assert_allclose(Q.T @ Q, np.eye(3), atol=1e-14)
        assert pc.is_symmetric_under(C, Q, rtol=1e-13), name
    # the Cauchy projection commutes with the group: C_sym stays in the class
    Csym = pc.cauchy_projection(C)
    for Q in pc.symmetry_group(name):
        assert pc.is_symmetric_under(Csym, Q, rtol=1e-13), name


@pytest.mark.parametrize("name", CLASSES[1:-1])
def test_constructor_spans_the_invariant_space(name):
    """Parameter count = N_CONSTANTS and the constructor's (linear) map has full rank."""
    fn = pc.SYMMETRY_CLASSES[name]
    n_par = len(inspect.signature(fn).parameters)
    assert n_par == pc.N_CONSTANTS[name]
    p0 = np.array(PARAMS[name], dtype=float)
    C0 = pc.voigt_upper(fn(*p0))
    J = np.column_stack(
        [pc.voigt_upper(fn(*(p0 + 1e-3 * np.eye(n_par)[k]))) - C0 for k in range(n_par)]
    )
    assert np.linalg.matrix_rank(J, tol=1e-9) == n_par


def test_triclinic_and_isotropic_counts():
    # triclinic: a full 6x6 (21 upper entries); isotropic: any two moduli give one tensor
    assert pc.voigt_upper(pc.triclinic(random_spd(6, 10))).size == pc.N_CONSTANTS["triclinic"]
    basis = [pc.isotropic(lam=1.0, mu=1.0), pc.isotropic(lam=2.0, mu=1.0)]
    A = np.column_stack([pc.voigt_upper(b) for b in basis])
    assert np.linalg.matrix_rank(A) == pc.N_CONSTANTS["isotropic"]


def test_classes_not_symmetric_under_next_larger_group():
    # each class breaks a symmetry of a more symmetric class (so the group tests can fail)
    r = np.sqrt(0.5)
    cases = {
        "triclinic": pc.reflection([0, 0, 1]),
        "monoclinic": pc.reflection([1, 0, 0]),
        "orthotropic": pc.reflection([r, r, 0]),
        "trigonal": pc.reflection([0, 1, 0]),
        "tetragonal": pc.rotation_matrix([0, 0, 1], 1.0),
        "transversely_isotropic": pc.reflection([r, 0, r]),
        "cubic": pc.rotation_matrix([0, 0, 1], 1.0),
    }
    for name, Q in cases.items():
        assert pc.symmetry_distance(construct(name), Q) > 1e-3, name


def test_materials_match_constructors_and_classes():
    M = pc.MATERIALS
    for name in ["monoclinic", "orthotropic", "tetragonal", "transversely_isotropic", "cubic"]:
        np.testing.assert_array_equal(M[name][0], construct(name))
    np.testing.assert_allclose(M["isotropic"][0], pc.isotropic(E=86.0, nu=0.25), rtol=1e-14)
    # Ta2C as printed: constructor differs only in C66 = (464 - 159)/2 = 152.5 vs 153 (Eq. 69 as
    # printed; conventions.md#errata-prakash)
    diff = M["trigonal"][0] - pc.trigonal(*PARAMS["trigonal"])
    expected = np.zeros((6, 6))
    expected[5, 5] = 0.5
    np.testing.assert_array_equal(diff, expected)
    # reference values (conventions.md#errata-prakash, Eq. 64): R(e1) exact, ±60° mirrors to 1.2e-3,
    # R(e2), R(e3) change it by 35 %
    C = M["trigonal"][0]
    h = np.sqrt(3) / 2
    assert pc.symmetry_distance(C, pc.reflection([1, 0, 0])) < 1e-15
    assert round(pc.symmetry_distance(C, pc.reflection([0.5, h, 0])), 4) == 0.0012
    assert round(pc.symmetry_distance(C, pc.reflection([0, 1, 0])), 2) == 0.35
    assert round(pc.symmetry_distance(C, pc.reflection([0, 0, 1])), 2) == 0.35


@pytest.mark.parametrize("name", CLASSES)
def test_symmetry_group_about_other_axis(name):
    n = np.array([1.0, -2.0, 2.0]) / 3.0
    # any rotation taking e3 to n (built here independently of the library's frame choice)
    axis = np.cross([0, 0, 1], n)
    R = pc.rotation_matrix(axis, np.arccos(n[2]))
    np.testing.assert_allclose(R @ [0, 0, 1], n, atol=1e-15)
    Cr = pc.rotate(construct(name), R)
    group = pc.symmetry_group(name, n_axis=n)
    assert all(pc.is_symmetric_under(Cr, Q, rtol=1e-12) for Q in group)
    if name == "monoclinic":  # the mirror normal is n
        np.testing.assert_allclose(group[2] @ n, -n, atol=1e-15)


def test_symmetry_group_bad_name():
    with pytest.raises(InputError, match="name must be one of .* got 'hexagonal'"):
        pc.symmetry_group("hexagonal")


# --------------------------------------------------------------------------- isotropic


def test_isotropic_from_any_two_moduli():
    # Pyroceram (Eq. 94): E = 86, nu = 0.25 -> lam = mu = 34.4, K = 57.3333 (hand-computed: lam = E
    # nu/((1+nu)(1-2nu)) = 21.5/0.625, mu = E/2.5, K = E/(3(1-2nu)) = 86/1.5)
    ref = pc.material("isotropic")
    mod = {"E": 86.0, "nu": 0.25, "lam": 34.4, "G": 34.4, "K": 86.0 / 1.5}
    for a, b in itertools.combinations(mod, 2):
        kwargs = {a: mod[a], b: mod[b]}
        np.testing.assert_allclose(pc.isotropic(**kwargs), ref, rtol=1e-12, err_msg=str(kwargs))
    np.testing.assert_allclose(pc.isotropic(lam=34.4, mu=34.4), ref, rtol=1e-14)
    # ν = 1/4 <=> Cauchy (Prakash, anisotropic micromoduli, Eq. 93: C11 = 3 C12 = 3 C44)
    assert pc.satisfies_cauchy(ref)
    assert not pc.satisfies_cauchy(pc.isotropic(E=86.0, nu=0.3))


def test_isotropic_argument_errors():
    with pytest.raises(InputError, match="exactly two .* got 1: E"):
        pc.isotropic(E=1.0)
    with pytest.raises(InputError, match="exactly two .* got 3: E, nu, K"):
        pc.isotropic(E=1.0, nu=0.2, K=3.0)
    with pytest.raises(InputError, match="mu or G"):
        pc.isotropic(mu=1.0, G=1.0)
    with pytest.raises(InputError, match="nu must be in"):
        pc.isotropic(E=1.0, nu=0.5)
    with pytest.raises(InputError, match="positive definite"):
        pc.isotropic(K=-1.0, G=1.0)
    with pytest.raises(NonFiniteError, match="E must be finite"):
        pc.isotropic(E=np.nan, nu=0.2)


# --------------------------------------------------------------------------- Cauchy


def test_cauchy_projection_pair_formula_and_unaffected_entries():
    C = random_spd(6, 11)
    P = pc.cauchy_projection(C)
    # Cauchy pairs (a, b) (derived from Eq. 49), 1-based Voigt: C_a = C_b = (C_a + 2 C_b)/3
    pairs = [((1, 2), (6, 6)), ((1, 3), (5, 5)), ((2, 3), (4, 4)),
             ((1, 4), (5, 6)), ((2, 5), (4, 6)), ((3, 6), (4, 5))]  # fmt: skip
    touched = set()
    for (a1, a2), (b1, b2) in pairs:
        a, b = (a1 - 1, a2 - 1), (b1 - 1, b2 - 1)
        target = (C[a] + 2 * C[b]) / 3
        assert P[a] == pytest.approx(target, rel=1e-14)
        assert P[b] == pytest.approx(target, rel=1e-14)
        # = multiplicity-weighted mean, m_a : m_b = 1 : 2 (Frobenius multiplicities)
        touched |= {a, b}
    for a, b in zip(*np.triu_indices(6), strict=True):
        if (a, b) not in touched:  # the 9 unaffected entries (derived)
            assert P[a, b] == C[a, b]
    assert len([1 for a, b in zip(*np.triu_indices(6), strict=True) if (a, b) not in touched]) == 9


def test_cauchy_projection_2d():
    C = np.array([[5.0, 1.0, 0.5], [1.0, 4.0, 0.25], [0.5, 0.25, 2.0]])
    P = pc.cauchy_projection(C)
    # pdlin's 2D extension: C12 = C33 -> (C12 + 2 C33)/3 = (1 + 4)/3; the rest unchanged
    expected = C.copy()
    expected[0, 1] = expected[1, 0] = expected[2, 2] = 5.0 / 3.0
    np.testing.assert_allclose(P, expected, rtol=1e-15)
    # plane stress ν = 1/3 and plane strain ν = 1/4 isotropic satisfy Cauchy (derived)
    assert pc.satisfies_cauchy(pc.isotropic_2d(1.0, 1 / 3, "stress"))
    assert pc.satisfies_cauchy(pc.isotropic_2d(1.0, 0.25, "strain"))
    assert not pc.satisfies_cauchy(pc.isotropic_2d(1.0, 0.25, "stress"))


@pytest.mark.parametrize("n", [6, 3])
def test_cauchy_projection_is_orthogonal_projection(n):
    C = random_spd(n, 12)
    P = pc.cauchy_projection(C)
    np.testing.assert_allclose(pc.cauchy_projection(P), P, rtol=1e-14)  # idempotent
    T, TP = pc.voigt_to_tensor(C), pc.voigt_to_tensor(P)
    # residual orthogonal to the image (full-tensor Frobenius inner product)
    assert abs(np.sum((T - TP) * TP)) < 1e-12 * np.sum(T * T)
    # totally symmetric: invariant under every permutation of the four indices
    for perm in itertools.permutations(range(4)):
        np.testing.assert_allclose(TP.transpose(perm), TP, rtol=1e-14)
    # equals the total symmetrization (C_ijkl + C_ikjl + C_iljk)/3
    # (conventions.md#calibration-in-the-frobenius-norm) and the mean over all 24 index permutations
    # (independent of the Voigt pair formula)
    tot = (T + np.einsum("ikjl->ijkl", T) + np.einsum("iljk->ijkl", T)) / 3
    np.testing.assert_allclose(TP, tot, rtol=1e-14)
    mean24 = sum(T.transpose(p) for p in itertools.permutations(range(4))) / 24
    np.testing.assert_allclose(TP, mean24, rtol=1e-14)
    # full-tensor input gives the full-tensor result
    np.testing.assert_allclose(pc.cauchy_projection(T), TP, rtol=1e-14)


def test_cauchy_projection_commutes_with_rotation():
    C = random_spd(6, 13)
    Q = random_rotation(14)
    a = pc.cauchy_projection(pc.rotate(C, Q))
    b = pc.rotate(pc.cauchy_projection(C), Q)
    np.testing.assert_allclose(a, b, atol=1e-12 * np.abs(C).max())


def test_cauchy_projection_leaves_bond_tensors_unchanged():
    rng = np.random.default_rng(15)
    T = bond_tensor(rng.normal(size=(40, 3)), rng.uniform(0.1, 1.0, 40))
    C = pc.tensor_to_voigt(T)
    assert pc.cauchy_distance(C) < 1e-15
    np.testing.assert_allclose(pc.cauchy_projection(C), C, rtol=1e-14)
    assert not pc.satisfies_cauchy(random_spd(6, 16))


# Prakash, anisotropic micromoduli, Table 1 errors (%) (derived: e = Cauchy distance at full rank)
TABLE1 = {
    "triclinic": "3.1873", "monoclinic": "4.988", "orthotropic": "5.0958", "trigonal": "2.632",
    "tetragonal": "3.8634", "transversely_isotropic": "1.5335", "cubic": "0.8028",
}  # fmt: skip


@pytest.mark.parametrize("name", CLASSES)
def test_cauchy_distance_equals_table1_error(name):
    C = pc.material(name)
    e = 100 * pc.cauchy_distance(C)
    if name == "isotropic":
        assert e < 1e-13  # Pyroceram satisfies Cauchy exactly (derived)
        return
    printed = TABLE1[name]
    digits = len(printed.split(".")[1])
    assert round(e, digits) == float(printed)


@pytest.mark.parametrize("name", ["triclinic", "cubic", "trigonal"])
def test_cauchy_distance_is_best_bond_based_fit(name):
    """§2.3 identity, independently: least squares of C over Eq.-29 tensors of many bond
    directions (unconstrained c, full-tensor Frobenius norm) leaves the Cauchy distance."""
    rng = np.random.default_rng(17)
    xi = rng.normal(size=(60, 3))
    cols = np.column_stack([bond_tensor(x[None, :], np.ones(1)).ravel() for x in xi])
    T = pc.voigt_to_tensor(pc.material(name))
    c, *_ = np.linalg.lstsq(cols, T.ravel(), rcond=None)
    e_fit = np.linalg.norm(cols @ c - T.ravel()) / np.linalg.norm(T)
    assert e_fit == pytest.approx(pc.cauchy_distance(T), rel=1e-9)


def test_cauchy_projection_of_materials_matches_spec_csym():
    # calibrated tensors C_PD = C_sym (reference values, 4 decimals)
    P = {k: pc.cauchy_projection(pc.material(k)) for k in pc.MATERIALS}
    checks = [
        ("triclinic", (0, 1), 11.6667), ("triclinic", (5, 5), 11.6667),
        ("triclinic", (1, 2), 12.6667), ("triclinic", (1, 4), -0.3333),
        ("triclinic", (2, 5), 0.3333), ("triclinic", (0, 3), 1.0),
        ("monoclinic", (0, 1), 18.3333), ("monoclinic", (0, 2), 62.0),
        ("monoclinic", (1, 2), 14.3333), ("monoclinic", (2, 5), 22.6667),
        ("orthotropic", (0, 2), 43.0), ("orthotropic", (3, 3), 2.3333),
        ("trigonal", (0, 1), 155.0), ("trigonal", (5, 5), 155.0),
        ("trigonal", (0, 2), 130.3333), ("trigonal", (4, 4), 130.3333),
        ("trigonal", (4, 5), -45.0), ("trigonal", (1, 3), 45.0),
        ("tetragonal", (0, 1), 80.0), ("tetragonal", (3, 3), 58.0),
        ("transversely_isotropic", (0, 1), 166.3333), ("transversely_isotropic", (1, 2), 239.0),
        ("cubic", (0, 1), 143.0), ("cubic", (3, 3), 143.0),  # erratum E2: 143.0, not 143.5
    ]  # fmt: skip
    for name, idx, value in checks:
        assert round(float(P[name][idx]), 4) == value, (name, idx)
    np.testing.assert_allclose(P["isotropic"], pc.material("isotropic"), rtol=1e-15)
    # trigonal/TI with Cauchy: C11 = 3 C12 = 3 C66 (derived) — for the class constructors
    for name in ["trigonal", "transversely_isotropic"]:
        Cs = pc.cauchy_projection(construct(name))
        assert Cs[0, 0] == pytest.approx(3 * Cs[0, 1], rel=1e-13)
        assert Cs[0, 0] == pytest.approx(3 * Cs[5, 5], rel=1e-13)


# --------------------------------------------------------------------------- A^U


@pytest.mark.parametrize("name", CLASSES)
def test_universal_anisotropy_index_printed(name):
    C, printed = pc.MATERIALS[name]
    au = pc.universal_anisotropy_index(C)
    if name == "isotropic":
        assert abs(au) < 1e-12  # isotropic: A^U = 0 exactly (Appendix A)
    else:
        assert round(au, 4) == printed  # A^U as printed in Sec. 4.1 (4 decimals)
    # rotation invariant, and >= 0
    assert pc.universal_anisotropy_index(pc.rotate(C, random_rotation(18))) == pytest.approx(
        au, rel=1e-10, abs=1e-12
    )


def test_universal_anisotropy_index_nonnegative_and_3d_only():
    for seed in range(5):
        assert pc.universal_anisotropy_index(random_spd(6, 20 + seed)) > 0
    with pytest.raises(ShapeError, match="3D stiffness"):
        pc.universal_anisotropy_index(np.eye(3))


# --------------------------------------------------------------------------- 2D


@pytest.mark.parametrize("nu", [0.25, 0.3])
def test_plane_reductions_of_isotropic(nu):
    C = pc.isotropic(E=86.0, nu=nu)
    np.testing.assert_allclose(pc.plane_strain(C), pc.isotropic_2d(86.0, nu, "strain"), rtol=1e-13)
    np.testing.assert_allclose(pc.plane_stress(C), pc.isotropic_2d(86.0, nu, "stress"), rtol=1e-13)
    # full tensor in -> 2D full tensor out
    T2 = pc.plane_stress(pc.voigt_to_tensor(C))
    assert T2.shape == (2, 2, 2, 2)
    np.testing.assert_allclose(pc.tensor_to_voigt(T2), pc.plane_stress(C), rtol=1e-14)


def test_plane_stress_equals_inverse_of_inplane_compliance():
    # independent route: σ33 = σ23 = σ31 = 0  <=>  Q = (S_pp)⁻¹ with S = C⁻¹
    C = pc.material("triclinic")
    p = [0, 1, 5]
    S = np.linalg.inv(C)
    np.testing.assert_allclose(pc.plane_stress(C), np.linalg.inv(S[np.ix_(p, p)]), rtol=1e-12)
    np.testing.assert_array_equal(pc.plane_strain(C), C[np.ix_(p, p)])


def test_isotropic_2d_values_and_errors():
    # plane stress E/(1-ν²)·[1, ν; (1-ν)/2] at E=1, ν=0.5: 4/3, 2/3, 1/3 (hand-computed)
    np.testing.assert_allclose(
        pc.isotropic_2d(1.0, 0.5, "stress"), [[4 / 3, 2 / 3, 0], [2 / 3, 4 / 3, 0], [0, 0, 1 / 3]]
    )
    # plane strain at E=1, ν=0.25: 1/(1.25·0.5) = 1.6 -> 1.2, 0.4, 0.4 (hand-computed)
    np.testing.assert_allclose(
        pc.isotropic_2d(1.0, 0.25, "strain"), [[1.2, 0.4, 0], [0.4, 1.2, 0], [0, 0, 0.4]]
    )
    with pytest.raises(InputError, match="plane must be 'stress' or 'strain', got 'x'"):
        pc.isotropic_2d(1.0, 0.25, "x")
    with pytest.raises(InputError, match="nu must be in \\(-1, 0.5\\) for plane strain"):
        pc.isotropic_2d(1.0, 0.5, "strain")
    with pytest.raises(InputError, match="E must be > 0"):
        pc.isotropic_2d(-1.0, 0.25)


# --------------------------------------------------------------------------- errors


def test_check_stiffness_errors():
    C = random_spd(6, 21)
    assert pc.check_stiffness(C) is not None
    bad = C.copy()
    bad[0, 1] += 1.0
    with pytest.raises(InputError, match="Cmat must be symmetric .*max \\|C - C.T\\| = 1"):
        pc.check_stiffness(bad, name="Cmat")
    with pytest.raises(InputError, match="K must be positive definite, got smallest eigenvalue -1"):
        pc.check_stiffness(np.diag([1.0, 1, -1, 1, 1, 1]), name="K")
    with pytest.raises(InputError, match="positive definite.*smallest eigenvalue 0 "):
        pc.check_stiffness(np.zeros((3, 3)))
    nan = C.copy()
    nan[2, 3] = nan[3, 2] = np.nan
    with pytest.raises(NonFiniteError, match="C must be finite, got nan at index \\(2, 3\\)"):
        pc.check_stiffness(nan)
    with pytest.raises(ShapeError, match="C must have shape .* got \\(5, 5\\)"):
        pc.check_stiffness(np.eye(5))
    with pytest.raises(InputError, match="C must be a numeric array"):
        pc.check_stiffness("abc")
    T = pc.voigt_to_tensor(C)
    T[0, 1, 2, 2] += 1.0
    with pytest.raises(InputError, match="minor symmetry"):
        pc.check_stiffness(T)


def test_tensor_to_voigt_reports_which_symmetry():
    T = pc.voigt_to_tensor(random_spd(6, 22))
    Tm = T.copy()
    Tm[0, 0, 1, 2] += 0.5  # breaks minor (T_0012 != T_0021) and major
    with pytest.raises(InputError, match="minor symmetry.*max violation 0.5"):
        pc.tensor_to_voigt(Tm)
    Tj = T.copy()
    Tj[0, 0, 1, 1] += 0.25  # keeps minor, breaks major
    with pytest.raises(InputError, match="major symmetry.*max violation 0.25"):
        pc.tensor_to_voigt(Tj)
    with pytest.raises(ShapeError, match="T must be a full tensor"):
        pc.tensor_to_voigt(np.eye(6))
    with pytest.raises(ShapeError, match="C must be a Voigt matrix"):
        pc.voigt_to_tensor(T)


def test_rotate_rejects_non_orthogonal_q():
    C = random_spd(6, 23)
    with pytest.raises(InputError, match="Q must be orthogonal .* got 0.21"):  # 1.1² - 1
        pc.rotate(C, np.diag([1.1, 1.0, 1.0]))
    with pytest.raises(ShapeError, match="Q must have shape \\(3, 3\\) to match C, got \\(2, 2\\)"):
        pc.rotate(C, np.eye(2))
    with pytest.raises(NonFiniteError, match="Q must be finite"):
        pc.rotate(C, np.full((3, 3), np.inf))


def test_constructor_errors():
    with pytest.raises(InputError, match="C \\(cubic\\) must be positive definite"):
        pc.cubic(1.0, 2.0, 1.0)  # C11 - C12 < 0
    with pytest.raises(NonFiniteError, match="C44 must be finite"):
        pc.cubic(252.0, 145.0, np.nan)
    with pytest.raises(InputError, match="C13 must be a real number"):
        pc.orthotropic(1, 1, 1, 0, "x", 0, 1, 1, 1)
    with pytest.raises(ShapeError, match="6x6"):
        pc.triclinic(np.eye(3))
    with pytest.raises(InputError, match="must be symmetric"):
        pc.triclinic(np.triu(random_spd(6, 24)))


def test_material_lookup():
    np.testing.assert_array_equal(pc.material("Ta2C"), pc.MATERIALS["trigonal"][0])
    np.testing.assert_array_equal(pc.material("spinel"), pc.material("cubic"))
    C = pc.material("cubic")
    C[0, 0] = 0.0  # a copy: the registry is unchanged
    assert pc.MATERIALS["cubic"][0][0, 0] == 252.0  # Eq. 87
    assert not pc.MATERIALS["cubic"][0].flags.writeable
    with pytest.raises(InputError, match="name must be one of .* got 'unobtainium'"):
        pc.material("unobtainium")


def test_docs_examples_run():
    """The examples of docs/constitutive.md are doctests; keep them true."""
    path = Path(__file__).resolve().parents[2] / "docs" / "constitutive.md"
    res = doctest.testfile(
        str(path), module_relative=False, optionflags=doctest.NORMALIZE_WHITESPACE
    )
    assert res.attempted >= 15
    assert res.failed == 0
