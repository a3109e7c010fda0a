"""Unit tests of pdlin.calibration (design matrix, solver paths, clouds, bad input)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import pdlin
from pdlin import constitutive as cst
from pdlin.calibration import (
    Family,
    calibrate_micromoduli,
    design_matrix,
    lattice_family,
)
from pdlin.calibration.cloud import group_families
from pdlin.constitutive import tensor_to_voigt, voigt_to_tensor
from pdlin.errors import InputError, InputTypeError, NonFiniteError, ShapeError


def _iso(c11: float = 103.2, c12: float = 34.4, c44: float = 34.4) -> np.ndarray:
    C = np.zeros((6, 6))
    C[:3, :3] = c12
    C[[0, 1, 2], [0, 1, 2]] = c11
    C[[3, 4, 5], [3, 4, 5]] = c44
    return C


# triclinic KIO3, Prakash, anisotropic micromoduli, Eq. 50 (a non-Cauchy target that discriminates
# weightings)
TRICLINIC = np.array(cst.material("triclinic"))


def _eq29(xi, omega, volume, c, thickness=1.0):
    """Prakash, anisotropic micromoduli, Eq. 29 summed directly over bonds (independent of
    design_matrix)."""
    L = np.linalg.norm(xi, axis=1)
    w = 0.5 * omega * c * volume * thickness / L**3
    return np.einsum("n,ni,nj,nk,nl->ijkl", w, xi, xi, xi, xi)


# --- design matrix ---------------------------------------------------------------------
def test_design_matrix_matches_eq29_and_energy(rng):
    xi = rng.normal(size=(40, 3))
    om = rng.uniform(0.5, 2, 40)
    vol = rng.uniform(0.5, 2, 40)
    c = rng.uniform(0, 1, 40)
    X = design_matrix(xi, om, vol, weighting="voigt")
    assert X.shape == (21, 40)
    T = _eq29(xi, om, vol, c)
    V = tensor_to_voigt(T)
    a, b = np.triu_indices(6)
    np.testing.assert_allclose(X @ c, V[a, b], rtol=1e-12)  # V3: X c = Voigt(Eq. 29)
    # V1: Eq. 29 is fully symmetric
    for perm in itertools.permutations(range(4)):
        np.testing.assert_allclose(T.transpose(perm), T, atol=1e-12 * np.abs(T).max())
    # V2: 1/2 eps:C:eps = 1/2 sum 1/2 omega c (xi.eps.xi)^2 V / r^3
    eps = rng.normal(size=(3, 3))
    eps = eps + eps.T
    lhs = 0.5 * np.einsum("ij,ijkl,kl->", eps, T, eps)
    L = np.linalg.norm(xi, axis=1)
    rhs = 0.5 * np.sum(0.5 * om * c * np.einsum("ni,ij,nj->n", xi, eps, xi) ** 2 * vol / L**3)
    np.testing.assert_allclose(lhs, rhs, rtol=1e-12)


def test_frobenius_weighting_equals_81_row_least_squares(rng):
    # V3: the sqrt(m)-weighted 21-row system and the 81-row tensor system give the same c
    fam = lattice_family(3, 3.0)
    res = calibrate_micromoduli(TRICLINIC, fam, method="min-norm")
    L = fam.length
    w = 0.5 * fam.omega * fam.volume / L**3
    X81 = np.einsum("n,ni,nj,nk,nl->ijkln", w, fam.xi, fam.xi, fam.xi, fam.xi).reshape(81, -1)
    b81 = voigt_to_tensor(TRICLINIC).ravel()
    c81 = np.linalg.lstsq(X81, b81, rcond=1e-12)[0]  # minimum-norm least squares
    np.testing.assert_allclose(res.micromoduli, c81, rtol=1e-9, atol=1e-12)
    # and it differs from the unweighted Voigt system (a Cauchy target could not tell them apart)
    unw = calibrate_micromoduli(TRICLINIC, fam, method="min-norm", weighting="voigt")
    assert np.abs(unw.micromoduli - c81).max() > 1e-3 * np.abs(c81).max()


def test_merged_columns_equal_plain_pseudo_inverse():
    # identical (±xi) columns are merged; the min-norm solution must equal pinv on all columns
    fam = lattice_family(3, 2.0)
    res = calibrate_micromoduli(TRICLINIC, fam, method="min-norm")
    X = design_matrix(fam.xi, fam.omega, fam.volume)
    b = tensor_to_voigt(voigt_to_tensor(TRICLINIC))[np.triu_indices(6)]
    # conventions.md#frobenius-norm-of-a-stiffness-tensor
    m = np.array([1, 2, 2, 4, 4, 4, 1, 2, 4, 4, 4, 1, 4, 4, 4, 4, 8, 8, 4, 8, 4])
    c = np.linalg.pinv(X, rcond=1e-12) @ (b * np.sqrt(m))
    np.testing.assert_allclose(res.micromoduli, c, rtol=1e-10, atol=1e-12)
    assert res.n_columns == 16 and res.n_bonds == 32  # 16 +-xi pairs
    # c(xi) = c(-xi) exactly (derived, conventions.md#calibration-in-the-frobenius-norm)
    key = {tuple(v): k for k, v in enumerate(fam.xi.round(9))}
    rev = np.array([key[tuple(-v)] for v in fam.xi.round(9)])
    np.testing.assert_array_equal(res.micromoduli, res.micromoduli[rev])


def test_robust_nnls_start_gives_same_result_when_projection_is_admissible():
    fam = lattice_family(3, 6.0, influence="delta_over_r")
    C = _iso(252, 145, 142)  # cubic spinel, Eq. 87 (corrected C12): needs the QP (Table 1)
    a = calibrate_micromoduli(C, fam)
    b = calibrate_micromoduli(C, fam, method="robust")
    assert a.status == "qp" and b.status == "nnls-qp" and "nnls" in b.path
    np.testing.assert_allclose(b.micromoduli, a.micromoduli, atol=1e-9 * a.c_max)


def test_min_norm_status_and_lower_bound_zero_counting():
    fam = lattice_family(3, 6.0, influence="delta_over_r")
    C = _iso(252, 145, 142)
    r = calibrate_micromoduli(C, fam, method="min-norm")
    assert r.status == "negative" and not r.feasible and r.c_min < 0
    assert "below the bound" in r.message
    q = calibrate_micromoduli(C, fam)
    assert q.feasible and q.n_zero > 0 and q.zero_threshold > 0
    assert q.n_zero == int(np.sum(q.micromoduli <= q.zero_threshold))
    assert "status qp" in q.summary()


def test_array_input_equals_family_input():
    fam = lattice_family(3, 3.0)
    a = calibrate_micromoduli(TRICLINIC, fam)
    b = calibrate_micromoduli(TRICLINIC, fam.xi, omega=fam.omega, volume=1.0)
    np.testing.assert_array_equal(a.micromoduli, b.micromoduli)
    # tensor input equals Voigt input
    c = calibrate_micromoduli(voigt_to_tensor(TRICLINIC), fam)
    np.testing.assert_allclose(c.micromoduli, a.micromoduli, rtol=1e-14)


def test_units_scale_linearly():
    fam = lattice_family(3, 3.0, spacing=0.5)
    a = calibrate_micromoduli(_iso(), fam)
    b = calibrate_micromoduli(_iso() * 1e9, fam)
    np.testing.assert_allclose(b.micromoduli, 1e9 * a.micromoduli, rtol=1e-12)
    # spacing h: c scales as 1/h^4 at fixed delta/h (C = 1/2 sum c xi^4 V/|xi|^3)
    ref = calibrate_micromoduli(_iso(), lattice_family(3, 6.0))
    np.testing.assert_allclose(a.micromoduli, ref.micromoduli * 0.5**-4, rtol=1e-10)


# --- clouds ----------------------------------------------------------------------------
def test_cloud_calibration_flows_into_bond_based_effective_tensor():
    cloud = pdlin.grid((9, 9, 9))
    bonds = pdlin.find_bonds(cloud, 2.0)
    C = TRICLINIC * 1e9
    res = pdlin.calibrate_micromoduli(C, bonds, method="robust")  # truncated families need NNLS
    assert res.micromoduli.shape == (bonds.n_bonds,)
    assert res.tensor.shape == (cloud.n, 6, 6)
    # 5 positions per axis (0, 1, interior, 7, 8) -> 125 distinct families
    assert len(res.families) == 125
    np.testing.assert_array_equal(res.micromoduli, res.micromoduli[bonds.reverse])  # symmetric
    model = pdlin.BondBased(micromodulus=res.micromoduli)
    T = model.effective_tensor(cloud, bonds)
    V = np.stack([tensor_to_voigt(t) for t in T])
    np.testing.assert_allclose(V, res.tensor, rtol=0, atol=1e-10 * np.abs(C).max())
    centre = int(np.flatnonzero(np.all(cloud.points == 4.5, axis=1))[0])
    single = calibrate_micromoduli(C, lattice_family(3, 2.0))
    np.testing.assert_allclose(res.tensor[centre], single.tensor, rtol=1e-12, atol=1e-3)
    np.testing.assert_allclose(res.relative_error[centre], single.relative_error, rtol=1e-10)
    assert res.pair_change > 0 and "pair rule 'mean'" in res.message


def test_cloud_owner_rule_reproduces_each_family():
    cloud = pdlin.grid((6, 6))
    bonds = pdlin.find_bonds(cloud, 2.3)
    C = np.array([[3.0, 1.0, 0.2], [1.0, 2.5, 0.1], [0.2, 0.1, 1.0]])
    res = calibrate_micromoduli(C, bonds, pair_rule="owner", method="robust")
    assert res.pair_change == 0.0
    for g, fr in enumerate(res.families):
        pts = np.flatnonzero(res.family_of_point == g)
        np.testing.assert_allclose(res.tensor[pts], fr.tensor[None].repeat(pts.size, 0))


def test_cloud_2d_thickness_matches_bond_based():
    cloud = pdlin.grid((8, 8), thickness=0.1)
    bonds = pdlin.find_bonds(cloud, 3.0)
    C = np.array([[3.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 1.0]]) * 1e9
    res = calibrate_micromoduli(C, bonds, thickness=0.1, method="robust")
    model = pdlin.BondBased(micromodulus=res.micromoduli)
    T = model.effective_tensor(cloud, bonds)
    V = np.stack([tensor_to_voigt(t) for t in T])
    np.testing.assert_allclose(V, res.tensor, rtol=0, atol=1e-10 * np.abs(C).max())


def test_group_families_irregular_cloud_and_verification(rng):
    cloud = pdlin.grid((6, 6, 6))
    pts = cloud.points + rng.normal(scale=1e-3, size=cloud.points.shape)
    cloud2 = pdlin.PointCloud(pts, volumes=1.0)
    bonds = pdlin.find_bonds(cloud2, 1.5)
    fam, rep, order = group_families(bonds)
    assert rep.size == cloud2.n  # perturbed points: every family distinct
    lattice = pdlin.find_bonds(cloud, 1.5)
    fam, rep, order = group_families(lattice)
    assert rep.size == 3**3  # 3 positions per axis (0, 1..4 interior, 5) with delta = 1.5
    # the permutation sorts each family: same xi at the same position for a group
    for g in range(rep.size):
        pts_g = np.flatnonzero(fam == g)
        a, b = pts_g[0], pts_g[-1]
        xa = lattice.xi[order[lattice.indptr[a] : lattice.indptr[a + 1]]]
        xb = lattice.xi[order[lattice.indptr[b] : lattice.indptr[b + 1]]]
        np.testing.assert_array_equal(xa, xb)


def test_cloud_interior_mean_rule():
    cloud = pdlin.grid((8, 8, 8))
    bonds = pdlin.find_bonds(cloud, 2.0)
    res = calibrate_micromoduli(_iso(), bonds, boundary="interior-mean")
    fr = res.families[0]
    inner = res.family_of_point == 0
    assert inner.sum() == 4**3  # points >= 2 from every face of an 8^3 block
    both = inner[bonds.i] & inner[bonds.j]
    # conventions.md#uniaxial-tension-of-a-cube
    np.testing.assert_allclose(res.micromoduli[~both], fr.c_mean)
    assert set(np.round(res.micromoduli[both], 4)) <= set(np.round(fr.micromoduli, 4))


def test_cloud_infeasible_families_carry_nan():
    cloud = pdlin.grid((7, 7, 7))
    bonds = pdlin.find_bonds(cloud, 2.0)
    # Prakash, anisotropic micromoduli, Eq. 56: infeasible at delta = 2 (Sec. 4.2.1)
    mono = np.array(
        [
            [135, 19, 54, 0, 0, 42],
            [19, 13, 15, 0, 0, 6],
            [54, 15, 269, 0, 0, 18],
            [0, 0, 0, 14, 25, 0],
            [0, 0, 0, 25, 66, 0],
            [42, 6, 18, 0, 0, 18],
        ],
        dtype=float,
    )
    res = calibrate_micromoduli(mono, bonds)
    assert res.status == "infeasible" and np.isnan(res.micromoduli).any()
    assert "method='robust'" in res.message
    with pytest.raises(NonFiniteError):
        pdlin.BondBased(micromodulus=res.micromoduli)
    rob = calibrate_micromoduli(mono, bonds, method="robust")
    assert np.all(np.isfinite(rob.micromoduli)) and rob.c_min >= 0


# --- bad input -------------------------------------------------------------------------
@pytest.mark.parametrize(
    "C, err, match",
    [
        (np.ones((5, 5)), ShapeError, r"C must have shape \(6, 6\)"),
        (np.triu(_iso()) + 0.0, InputError, "C must be symmetric"),
        (_iso() * 0.0, InputError, "positive definite"),
        (_iso(1.0, 2.0, 1.0), InputError, "positive definite"),
        (np.where(np.eye(6) > 0, np.nan, _iso()), NonFiniteError, "C must be finite"),
        (np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1]]), ShapeError, "2D stiffness"),
    ],
)
def test_bad_target(C, err, match):
    with pytest.raises(err, match=match):
        calibrate_micromoduli(C, lattice_family(3, 2.0))


def test_bad_tensor_symmetry():
    T = voigt_to_tensor(_iso())
    T[0, 1, 0, 0] += 1.0
    with pytest.raises(InputError, match="C must have minor symmetry"):
        calibrate_micromoduli(T, lattice_family(3, 2.0))


def test_bad_options_and_families():
    fam = lattice_family(3, 2.0)
    C = _iso()
    for kw, match in [
        ({"method": "lsq"}, "method must be one of"),
        ({"weighting": "mandel"}, "weighting must be one of"),
        ({"qp_solver": "gurobi"}, "qp_solver must be one of"),
        ({"plane": "membrane"}, "plane must be"),
        ({"pair_rule": "max"}, "pair_rule must be one of"),
        ({"boundary": "none"}, "boundary must be one of"),
        ({"lower_bound": np.nan}, "lower_bound must be finite"),
    ]:
        with pytest.raises(InputError, match=match):
            calibrate_micromoduli(C, fam, **kw)
    with pytest.raises(InputTypeError, match="bonds must be a pdlin.Bonds"):
        calibrate_micromoduli(C, "sphere")
    with pytest.raises(InputError, match="empty family"):
        calibrate_micromoduli(C, np.zeros((0, 3)))
    with pytest.raises(ShapeError, match=r"xi must have shape \(M, dim\)"):
        calibrate_micromoduli(C, np.ones((4, 4)))
    with pytest.raises(InputError, match="zero vector at bond 1"):
        Family([[1.0, 0, 0], [0, 0, 0]], 1.0, 1.0)
    with pytest.raises(ShapeError, match=r"omega must be a scalar or have shape \(2,\)"):
        Family([[1.0, 0, 0], [0, 1, 0]], [1.0, 1.0, 1.0], 1.0)
    with pytest.raises(NonFiniteError):
        Family([[1.0, np.nan, 0]], 1.0, 1.0)
    with pytest.raises(InputError, match="design matrix is zero"):
        calibrate_micromoduli(C, Family([[1.0, 0, 0]], 0.0, 1.0))


def test_bad_lattice_family_arguments():
    with pytest.raises(InputError, match="dim must be 2 or 3"):
        lattice_family(1, 2.0)
    with pytest.raises(InputError, match="lattice must be one of"):
        lattice_family(3, 2.0, lattice="triangular")
    with pytest.raises(InputError, match="horizon must be > 0"):
        lattice_family(3, -1.0)
    with pytest.raises(InputError, match="axes must be given"):
        lattice_family(3, 2.0, shape="box")
    with pytest.raises(InputError, match="selects no neighbour"):
        lattice_family(3, 0.5)
    with pytest.raises(InputError, match="rotation must be orthogonal"):
        lattice_family(3, 2.0, rotation=2 * np.eye(3))


def test_rank_deficient_2d_message():
    r = calibrate_micromoduli(_iso(), lattice_family(2, 1.0), plane="strain")
    # derived (pdlin's 2D extension): square delta = 1 has rank 2; x^3 y, x^2 y^2, x y^3 vanish on
    # the axes
    assert r.rank == 2
    assert "x^3*y, x^2*y^2, x*y^3" in r.message


def test_plot_micromoduli(tmp_path):
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    from pdlin.plotting import plot_micromoduli

    r2 = calibrate_micromoduli(_iso(), lattice_family(2, 3.0, lattice="triangular"))
    ax = plot_micromoduli(r2, lattice_family(2, 3.0, lattice="triangular"))
    assert ax.name == "polar"
    r3 = calibrate_micromoduli(TRICLINIC, lattice_family(3, 3.0))
    ax3 = plot_micromoduli(r3, lattice_family(3, 3.0))
    assert ax3.name == "3d"
    ax3.figure.savefig(tmp_path / "c.png")
    with pytest.raises(InputError, match="family"):
        plot_micromoduli(r3, lattice_family(3, 2.0))


def test_docs_examples():
    """The examples of docs/calibration.md are doctests; keep them true."""
    import doctest
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "docs" / "calibration.md"
    flags = doctest.NORMALIZE_WHITESPACE
    res = doctest.testfile(str(path), module_relative=False, optionflags=flags)
    assert res.attempted > 5 and res.failed == 0


def test_bulk_boundary_rule_gives_c_of_xi_and_exact_interior():
    import pdlin

    C = cst.material("transversely_isotropic")
    cloud = pdlin.grid((9, 9, 9))
    bonds = pdlin.find_bonds(cloud, 3.0, influence="delta_over_r")
    res = pdlin.calibrate_micromoduli(C, bonds, boundary="bulk")
    fam = pdlin.calibration.lattice_family(3, 3.0, influence="delta_over_r")
    ref = pdlin.calibrate_micromoduli(C, fam)
    # every bond carries the single-family value of its bond vector
    lut = {tuple(np.round(x).astype(int)): c for x, c in zip(fam.xi, ref.micromoduli, strict=True)}
    expect = np.array([lut[tuple(np.round(x).astype(int))] for x in bonds.xi])
    np.testing.assert_allclose(res.micromoduli, expect, rtol=1e-12)
    np.testing.assert_allclose(res.micromoduli, res.micromoduli[bonds.reverse], rtol=0)
    centre = int(np.ravel_multi_index((4, 4, 4), (9, 9, 9)))
    # interior tensor = the Cauchy projection of the target (derived,
    # conventions.md#calibration-in-the-frobenius-norm)
    P = cst.cauchy_projection(C)
    np.testing.assert_allclose(res.tensor[centre], P, rtol=1e-9, atol=1e-12 * np.abs(P).max())
    assert res.relative_error[centre] == pytest.approx(cst.cauchy_distance(C), rel=1e-9)
