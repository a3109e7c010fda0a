"""Unit tests of pdlin.sparsity_report, coupling_pattern and plot_spy."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
import scipy.sparse as sp

import pdlin
from pdlin.analysis.sparsity import SparsityReport, coupling_pattern, rcm_permutation
from pdlin.errors import InputError, InputTypeError, ShapeError
from pdlin.models.base import Model


class _TwoHopPattern(Model):
    """A model that only declares the state-based coupling range.

    Its operators raise: sparsity_report must get the pattern from the bonds
    alone, without assembling K.
    """

    coupling_range = 2

    def stiffness(self, cloud, bonds):  # noqa: D102
        raise AssertionError("the pattern statistics must not assemble K")

    def internal_force(self, cloud, bonds, u, *, linear=True):  # noqa: D102
        raise AssertionError("not needed for the pattern")


class _NoAssembly(pdlin.BondBased):
    def stiffness(self, cloud, bonds):  # noqa: D102
        raise AssertionError("the pattern statistics must not assemble K")


def _centre(shape: tuple[int, ...]) -> int:
    return int(np.ravel_multi_index(tuple(s // 2 for s in shape), shape))


def _report(cloud, bonds, model=None, **kw):
    return pdlin.sparsity_report(
        model=model if model is not None else pdlin.BondBased(E=1.0), cloud=cloud, bonds=bonds, **kw
    )


# -- counts against the provenance numbers ---------------------------------------


@pytest.mark.parametrize(
    ("dim", "family"),
    [
        (2, 28),  # lattice count (family size at delta = 3.01 h, 2D)
        (3, 122),  # lattice count (sphere m = 3 of the calibration, too)
    ],
)
def test_interior_family_size_at_3015(dim: int, family: int) -> None:
    cloud = pdlin.grid((9,) * dim)
    bonds = pdlin.find_bonds(cloud, 3.015)
    r = _report(cloud, bonds, model=_NoAssembly(E=1.0), fill_limit=0)
    assert r.blocks_per_row_max == family + 1  # the family plus the point itself
    assert r.nnz_per_row_max == dim * (family + 1)
    assert r.n_bonds == bonds.n_bonds
    assert r.nnz == dim * dim * (bonds.n_bonds + cloud.n)


@pytest.mark.parametrize(
    ("m", "count"),
    # lattice counts: sphere bond counts on the simple cubic lattice, inclusive |xi| <= m
    [(2, 32), (3, 122), (4, 256), (5, 514), (6, 924), (7, 1418)],
)
def test_sphere_bond_counts_3d(m: int, count: int) -> None:
    shape = (2 * m + 1,) * 3
    cloud = pdlin.grid(shape)
    bonds = pdlin.find_bonds(cloud, float(m))
    r = _report(cloud, bonds, fill_limit=0)
    assert r.blocks_per_row_max - 1 == count
    # the centre row is the full one
    P = coupling_pattern(bonds, 1)
    assert int(np.diff(P.indptr)[_centre(shape)]) == count + 1


@pytest.mark.parametrize(
    ("dim", "coupled", "nnz_row"),
    [
        (2, 105, 210),  # derived: state-based pattern at delta = 3.01 h, 2D
        (3, 829, 2487),  # derived: same, 3D
    ],
)
def test_two_hop_pattern_counts(dim: int, coupled: int, nnz_row: int) -> None:
    shape = (15, 15) if dim == 2 else (13, 13, 13)  # centre is >= 2 * 3.01 h from the faces
    cloud = pdlin.grid(shape)
    bonds = pdlin.find_bonds(cloud, 3.01)
    r = _report(cloud, bonds, model=_TwoHopPattern(), fill_limit=0)
    assert r.coupling_range == 2
    assert r.blocks_per_row_max == coupled
    assert r.nnz_per_row_max == nnz_row
    P = coupling_pattern(bonds, 2)
    assert int(np.diff(P.indptr)[_centre(shape)]) == coupled
    # farthest coupled pair: (6, 0) h = 2 x (3, 0) h, i.e. 6 / 3.01 horizons
    assert r.coupling_distance == pytest.approx(6.0, rel=1e-12)
    assert r.coupling_range_horizons == pytest.approx(6.0 / 3.01, rel=1e-12)
    assert r.symmetry is None and "numeric=True" in " ".join(r.notes)


def test_two_hop_pattern_matches_dense_square() -> None:
    cloud = pdlin.grid((7, 6))
    bonds = pdlin.find_bonds(cloud, 2.3)
    A = bonds.adjacency().toarray().astype(np.int64) + np.eye(cloud.n, dtype=np.int64)
    dense2 = (A @ A) > 0  # independent reference: dense integer square of A + I
    P = coupling_pattern(bonds, 2)
    np.testing.assert_array_equal(P.toarray(), dense2)
    r = _report(cloud, bonds, model=_TwoHopPattern(), fill_limit=0)
    assert r.n_blocks == int(dense2.sum())
    assert r.blocks_per_row_min == int(dense2.sum(axis=1).min())
    # 2 x 2 blocks: nnz = 4 x blocks over 2 n DOF rows
    assert r.nnz_per_row_mean == pytest.approx(4 * dense2.sum() / (2 * cloud.n), rel=1e-14)


def test_coupling_range_horizons_bond_based() -> None:
    cloud = pdlin.grid((12, 12), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    r = _report(cloud, bonds, fill_limit=0)
    # longest lattice bond within 3.015 h is |(3, 0)| h = 3 h (|(2, 2)| = 2.83, |(3, 1)| = 3.16)
    assert r.coupling_distance == pytest.approx(0.3, rel=1e-12)
    assert r.coupling_range_horizons == pytest.approx(3.0 / 3.015, rel=1e-12)


# -- consistency with the assembled K -----------------------------------------------


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_nnz_and_memory_match_assembled_k(dim: int) -> None:
    cloud = pdlin.grid((20, 9, 5)[:dim])
    bonds = pdlin.find_bonds(cloud, 2.5)
    K = pdlin.assemble_stiffness(pdlin.BondBased(E=3.0), cloud, bonds)
    r = _report(cloud, bonds, fill_limit=0)
    assert r.nnz == K.nnz
    assert r.n_blocks == K.indices.size
    assert r.memory_bsr_bytes == K.data.nbytes + K.indices.nbytes + K.indptr.nbytes
    Kc = K.tocsr()
    assert r.memory_csr_bytes == Kc.data.nbytes + Kc.indices.nbytes + Kc.indptr.nbytes
    assert r.nnz_per_row_max == int(np.diff(Kc.indptr).max())
    assert r.nnz_per_row_min == int(np.diff(Kc.indptr).min())
    assert r.bytes_per_bond_bsr == pytest.approx(r.memory_bsr_bytes / bonds.n_bonds)
    assert r.bytes_per_nnz_csr == pytest.approx(r.memory_csr_bytes / K.nnz)


@pytest.mark.parametrize("dim", [2, 3])
def test_report_from_k_equals_report_from_model(dim: int) -> None:
    cloud = pdlin.grid((11, 7, 4)[:dim], spacing=0.5)
    bonds = pdlin.find_bonds(cloud, ratio=2.5)
    model = pdlin.BondBased(E=2.0)
    K = pdlin.assemble_stiffness(model, cloud, bonds)
    fixed = np.flatnonzero(np.isin(np.arange(cloud.ndof) // dim, cloud.point_set("x-")))
    rm = _report(cloud, bonds, model=_NoAssembly(E=2.0), fixed_dofs=fixed)
    rk = pdlin.sparsity_report(K, points=cloud.points, horizon=1.25, bonds=bonds, fixed_dofs=fixed)
    assert rm.fill_natural is not None  # the fill-in is part of the comparison
    assert rk.pattern_dict() == rm.pattern_dict()
    assert rk.n_bonds == rm.n_bonds and rk.n_fixed == rm.n_fixed == fixed.size
    # the CSR K (explicit zeros kept) gives the same DOF pattern as the BSR one
    rc = pdlin.sparsity_report(
        K.tocsr(), cloud=cloud, horizon=1.25, block_size=dim, fixed_dofs=fixed
    )
    assert rc.pattern_dict() == rm.pattern_dict()
    # numeric=True assembles K and agrees with the K form on every numerical field
    rn = _report(cloud, bonds, model=model, fixed_dofs=fixed, numeric=True)
    for name in ("nnz_numeric", "symmetry", "diag_dominant_fraction", "condition_2", "zero_modes"):
        assert getattr(rn, name) == getattr(rk, name), name


def test_rcm_reduces_bandwidth_of_shuffled_cloud() -> None:
    base = pdlin.grid((30, 12))
    perm = np.random.default_rng(3).permutation(base.n)
    cloud = pdlin.PointCloud(base.points[perm], base.volumes[perm])
    bonds = pdlin.find_bonds(cloud, 2.01)
    K = pdlin.assemble_stiffness(pdlin.BondBased(E=1.0), cloud, bonds)
    r = pdlin.sparsity_report(K, cloud=cloud, bonds=bonds)
    assert r.bandwidth_rcm <= r.bandwidth
    # a 30 x 12 strip has a band of about 2 x 12 points; a random order is near-global
    assert r.bandwidth_rcm < r.bandwidth / 5
    assert r.profile_rcm < r.profile / 5
    assert r.fill_rcm < r.fill_natural


def test_bandwidth_profile_closed_form_1d() -> None:
    # chain with nearest and next-nearest bonds: half-bandwidth 2, profile 1 + 2 (n - 2)
    n = 12
    cloud = pdlin.grid((n,))
    r = _report(cloud, pdlin.find_bonds(cloud, 2.0))
    assert r.bandwidth == 2
    assert r.profile == 1 + 2 * (n - 2)
    # 2D blocks: DOF half-bandwidth d * b + d - 1; on a 5 x 4 grid in C order (index 4 x + y)
    # the farthest coupled pair within 2 h is the offset (2, 0): b = 2 * 4 = 8 points
    cloud2 = pdlin.grid((5, 4))
    r2 = _report(cloud2, pdlin.find_bonds(cloud2, 2.0), fill_limit=0)
    assert r2.bandwidth == 2 * 8 + 1


def test_fill_closed_form_tridiagonal() -> None:
    # nearest-neighbour chain: tridiagonal K, no fill with the natural ordering:
    # nnz(L) = nnz(U) = 2 n - 1 (both diagonals stored)
    n = 40
    cloud = pdlin.grid((n,))
    bonds = pdlin.find_bonds(cloud, 1.0)
    r = _report(cloud, bonds)
    assert r.fill_natural == 2 * (2 * n - 1)
    assert r.fill_rcm == 2 * (2 * n - 1)
    # shuffled: the natural order fills, RCM recovers the path order (no fill)
    perm = np.random.default_rng(0).permutation(n)
    shuffled = pdlin.PointCloud(cloud.points[perm], cloud.volumes[perm])
    rs = _report(shuffled, pdlin.find_bonds(shuffled, 1.0))
    assert rs.fill_rcm == 2 * (2 * n - 1)
    assert rs.fill_natural > rs.fill_rcm
    # fixing the first point removes one row and column
    rf = _report(cloud, bonds, fixed_dofs=[0])
    assert rf.fill_natural == 2 * (2 * (n - 1) - 1)


def test_fill_limit_skips() -> None:
    cloud = pdlin.grid((10, 10))
    r = _report(cloud, pdlin.find_bonds(cloud, 2.0), fill_limit=199)
    assert r.fill_natural is None and r.fill_mmd_at_plus_a is None
    assert r.fill_skipped == "200 free DOFs > fill_limit 199"


# -- numerical quantities -----------------------------------------------------------


def test_symmetry_zero_for_bond_based() -> None:
    cloud = pdlin.grid((8, 6))
    bonds = pdlin.find_bonds(cloud, 3.015)
    K = pdlin.assemble_stiffness(pdlin.BondBased(E=7.0), cloud, bonds)
    assert pdlin.sparsity_report(K).symmetry == 0.0
    vols = np.random.default_rng(1).uniform(0.5, 1.5, cloud.n)
    cloud_v = pdlin.PointCloud(cloud.points, vols)
    bonds_v = pdlin.find_bonds(cloud_v, 3.015)
    Kv = pdlin.assemble_stiffness(pdlin.BondBased(E=7.0), cloud_v, bonds_v)
    assert pdlin.sparsity_report(Kv).symmetry < 1e-15


def test_symmetry_and_dominance_of_hand_matrices() -> None:
    # ||K - K^T||_F = sqrt(2), ||K||_F = sqrt(4 + 1 + 4) = 3
    r = pdlin.sparsity_report(np.array([[2.0, 1.0], [0.0, 2.0]]), fill_limit=0)
    assert r.symmetry == pytest.approx(np.sqrt(2.0) / 3.0, rel=1e-14)
    # rows: 2 >= 1 (ratio 2), 1.5 < 2 (ratio 0.75), 3 >= 1 (ratio 3)
    A = np.array([[2.0, -1.0, 0.0], [-1.0, 1.5, -1.0], [0.0, -1.0, 3.0]])
    rd = pdlin.sparsity_report(sp.csr_array(A))
    assert rd.diag_dominant_fraction == pytest.approx(2.0 / 3.0)
    assert rd.diag_dominance_min_ratio == pytest.approx(0.75)
    assert rd.symmetry == 0.0
    assert rd.zero_modes == 0
    assert rd.condition_2 == pytest.approx(np.linalg.cond(A), rel=1e-12)


def _chain(n: int):
    cloud = pdlin.grid((n,))
    bonds = pdlin.find_bonds(cloud, 1.0)  # nearest neighbours only
    K = pdlin.assemble_stiffness(pdlin.BondBased(micromodulus=1.0), cloud, bonds)
    return cloud, bonds, K


def test_condition_closed_form_fixed_free_chain() -> None:
    n = 10
    cloud, bonds, K = _chain(n)
    r = pdlin.sparsity_report(K, points=cloud.points, fixed_dofs=[0])
    N = n - 1  # free DOFs: K_ff = k T, T tridiag(-1, 2, -1) with T[-1, -1] = 1
    # ||T||_1 = 4 and (T^-1)_ij = min(i, j), so ||T^-1||_1 = N (N + 1) / 2: cond_1 = 2 N (N + 1)
    assert r.condition_1_est == pytest.approx(2 * N * (N + 1), rel=1e-12)
    # eigenvalues of the fixed-free chain: 4 k sin^2((2 j - 1) pi / (2 (2 N + 1))), j = 1..N
    lam = np.sin((2 * np.arange(1, N + 1) - 1) * np.pi / (2 * (2 * N + 1))) ** 2
    assert r.condition_2 == pytest.approx(lam.max() / lam.min(), rel=1e-10)
    Kff = K.toarray()[1:, 1:]
    assert r.condition_2 == pytest.approx(np.linalg.cond(Kff), rel=1e-10)
    assert r.condition_1_est == pytest.approx(np.linalg.cond(Kff, 1), rel=1e-10)
    assert r.zero_modes == 0
    # the Laplacian-like 1D K is weakly diagonally dominant in every row, with equality
    assert r.diag_dominant_fraction == 1.0
    assert r.diag_dominance_min_ratio == pytest.approx(1.0, rel=1e-14)


@pytest.mark.parametrize(("dim", "rigid"), [(1, 1), (2, 3), (3, 6)])
def test_zero_modes_of_free_floating_k(dim: int, rigid: int) -> None:
    cloud = pdlin.grid((6, 5, 4)[:dim])
    bonds = pdlin.find_bonds(cloud, 2.0)
    K = pdlin.assemble_stiffness(pdlin.BondBased(E=1.0), cloud, bonds)
    r = pdlin.sparsity_report(K, cloud=cloud)
    assert r.zero_modes == rigid  # rigid-body modes: 1, 3, 6 (pdlin.rigid_body_modes)
    assert r.condition_1_est is None
    w = np.linalg.eigvalsh(K.toarray())
    assert r.condition_2 == pytest.approx(w[-1] / w[rigid], rel=1e-8)


def test_condition_limits_are_reported() -> None:
    cloud, _, K = _chain(30)
    r = pdlin.sparsity_report(K, fixed_dofs=[0], eig_limit=10, cond_limit=10)
    assert r.condition_2 is None and r.condition_1_est is None
    assert "dense spectrum skipped: 29 free DOFs > eig_limit 10" in r.notes
    assert "condition_1_est skipped: 29 free DOFs > cond_limit 10" in r.notes


# -- bad input -----------------------------------------------------------------------


def test_bad_input_errors() -> None:
    cloud = pdlin.grid((4, 4))
    bonds = pdlin.find_bonds(cloud, 1.5)
    model = pdlin.BondBased(E=1.0)
    K = pdlin.assemble_stiffness(model, cloud, bonds)
    with pytest.raises(InputError, match="needs K or model"):
        pdlin.sparsity_report()
    with pytest.raises(InputError, match="either K or model"):
        pdlin.sparsity_report(K, model=model, cloud=cloud, bonds=bonds)
    with pytest.raises(InputError, match="model needs cloud= and bonds="):
        pdlin.sparsity_report(model=model, cloud=cloud)
    with pytest.raises(InputTypeError, match="K must be a scipy sparse array or a 2-D ndarray"):
        pdlin.sparsity_report("K")
    with pytest.raises(ShapeError, match=r"K must be square, got shape \(32, 30\)"):
        pdlin.sparsity_report(K.tocsr()[:, :30])
    with pytest.raises(ShapeError, match="points must have 16 rows to match K"):
        pdlin.sparsity_report(K, points=cloud.points[:5])
    with pytest.raises(ShapeError, match="not a multiple of block_size 3"):
        pdlin.sparsity_report(K.tocsr(), block_size=3)
    with pytest.raises(InputError, match=r"fixed_dofs must hold DOF indices in \[0, 31\], got"):
        pdlin.sparsity_report(K, fixed_dofs=[0, 32])
    with pytest.raises(InputError, match="fill_limit must be an integer >= 0, got -1"):
        pdlin.sparsity_report(K, fill_limit=-1)
    with pytest.raises(InputError, match="horizon must be finite and > 0"):
        pdlin.sparsity_report(K, points=cloud.points, horizon=-1.0)
    with pytest.raises(InputTypeError, match="cloud must be a PointCloud, got ndarray"):
        pdlin.sparsity_report(K, cloud=cloud.points)
    with pytest.raises(InputError, match="coupling_range must be an integer >= 1, got 0"):
        coupling_pattern(bonds, 0)

    class _Zero(_TwoHopPattern):
        coupling_range = 0

    with pytest.raises(InputError, match="model.coupling_range must be an integer >= 1, got 0"):
        pdlin.sparsity_report(model=_Zero(), cloud=cloud, bonds=bonds)
    with pytest.raises(InputError, match="unknown keys"):
        SparsityReport.from_dict({"bogus": 1})


# -- serialization and plotting -----------------------------------------------------


def test_to_dict_json_round_trip_and_table() -> None:
    cloud = pdlin.grid((6, 5))
    bonds = pdlin.find_bonds(cloud, 2.0)
    K = pdlin.assemble_stiffness(pdlin.BondBased(E=1.0), cloud, bonds)
    r = pdlin.sparsity_report(K, cloud=cloud, bonds=bonds, fixed_dofs=[0, 1, 3])
    text = json.dumps(r.to_dict(), allow_nan=False)
    back = SparsityReport.from_dict(json.loads(text))
    assert back == r
    assert back.notes == r.notes
    table = str(r)
    assert "nnz per row min / mean / max" in table
    assert f"{r.nnz:,}" in table
    assert "fill nnz(L+U) MMD(A+A^T)" in table


def test_rcm_permutation_keeps_blocks_together() -> None:
    cloud = pdlin.grid((5, 5))
    P = coupling_pattern(pdlin.find_bonds(cloud, 1.5))
    perm = rcm_permutation(P, 3).reshape(-1, 3)
    np.testing.assert_array_equal(perm % 3, np.tile([0, 1, 2], (cloud.n, 1)))
    assert np.array_equal(np.sort(perm[:, 0] // 3), np.arange(cloud.n))


def test_plot_spy() -> None:
    mpl = pytest.importorskip("matplotlib")
    mpl.use("Agg")
    import matplotlib.pyplot as plt

    cloud = pdlin.grid((5, 4))
    K = pdlin.assemble_stiffness(pdlin.BondBased(E=1.0), cloud, pdlin.find_bonds(cloud, 1.5))
    fig, ax = plt.subplots()
    out = pdlin.plot_spy(K, ax=ax, order="rcm", blocks=True)
    assert out is ax
    # 5 x 4 grid within 1.5 h: 16 x-pairs + 15 y-pairs + 24 diagonal pairs = 55 pairs,
    # 110 directed bonds + 20 diagonal blocks = 130 blocks
    assert ax.get_title() == "20 x 20, nnz 130 (rcm)"
    with pytest.raises(InputError, match="order must be 'natural', 'rcm' or a permutation"):
        pdlin.plot_spy(K, ax=ax, order="amd")
    plt.close(fig)


def test_plot_spy_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", None)
    with pytest.raises(ImportError, match=r"pip install pdlin\[plotting\]"):
        pdlin.plot_spy(sp.eye_array(3))


def test_numeric_model_form_flags_a_wrong_coupling_range() -> None:
    class _ClaimsTwoHops(pdlin.BondBased):
        coupling_range = 2  # wrong on purpose: its K is one-hop

    cloud = pdlin.grid((6, 6))
    bonds = pdlin.find_bonds(cloud, 1.5)
    r = _report(cloud, bonds, model=_ClaimsTwoHops(E=1.0), numeric=True, fill_limit=0)
    K = pdlin.assemble_stiffness(pdlin.BondBased(E=1.0), cloud, bonds)
    assert f"assembled K stores {K.nnz} entries" in " ".join(r.notes)
    ok = _report(cloud, bonds, numeric=True, fill_limit=0)
    assert not any("assembled K stores" in n for n in ok.notes)


def test_fixed_dofs_mask_equals_indices_and_empty_matrix() -> None:
    cloud, _, K = _chain(8)
    mask = np.zeros(8, dtype=bool)
    mask[[0, 7]] = True
    a = pdlin.sparsity_report(K, fixed_dofs=mask)
    b = pdlin.sparsity_report(K, fixed_dofs=np.array([0, 7]))
    assert a == b and a.n_fixed == 2
    # an all-zero matrix: no entries, nothing to factor sensibly, but a valid report
    r = pdlin.sparsity_report(sp.csr_array((4, 4)), fill_limit=0)
    assert r.nnz == 0 and r.bytes_per_nnz_csr is None and r.zero_modes == 4
    json.dumps(r.to_dict(), allow_nan=False)
    assert "nnz stored / numeric" in str(r)


def test_constrained_pattern_agrees_between_model_and_matrix_forms():
    """nnz_free (K_ff's stored pattern) from the bonds equals that of the assembled K."""
    cloud = pdlin.grid((7, 5))
    bonds = pdlin.find_bonds(cloud, 2.015)
    model = pdlin.LPS(E=1.0, nu=0.25)
    fixed = (2 * cloud.sets["x-"][:, None] + np.arange(2)).ravel()
    rm = pdlin.sparsity_report(model=model, cloud=cloud, bonds=bonds, fixed_dofs=fixed)
    K = pdlin.assemble_stiffness(model, cloud, bonds)
    rk = pdlin.sparsity_report(K, points=cloud.points, horizon=2.015, fixed_dofs=fixed)
    assert rm.pattern_dict() == rk.pattern_dict()
    free = np.setdiff1d(np.arange(K.shape[0]), fixed)
    Kff = sp.csr_array(K)[free][:, free]
    assert rm.nnz_free == Kff.nnz < rm.nnz  # K_ff keeps fewer entries than K
    free_report = pdlin.sparsity_report(model=model, cloud=cloud, bonds=bonds)
    assert free_report.nnz_free is None and free_report.n_fixed == 0
