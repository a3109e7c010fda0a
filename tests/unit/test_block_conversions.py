"""Threaded construction of the LPS / XOSB factors (issue 13): equal to the serial scipy one.

The expected values are scipy's own conversions (``vstack``, ``.T.tocsr()``, ``tobsr``,
COO -> CSR) and the assembly as it was before the threaded construction (re-built here
from the same coefficients), compared bitwise (sign of zero included where stated) for
1, 2 and 3 threads and with the numba kernels on and off (``PDLIN_NUMBA=0``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.sparse as sp

import pdlin
from pdlin import _kernels
from pdlin._kernels import csr_to_bsr_rows, csr_to_bsr_t
from pdlin.models import ordinary_state as _state


@pytest.fixture(autouse=True)
def _reset(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(_kernels, "_MIN_WORK", 0)  # the tests' arrays are small
    monkeypatch.setattr(_kernels, "_loaded", None)
    monkeypatch.delenv("PDLIN_NUMBA", raising=False)
    yield
    pdlin.set_num_threads(None)


def _numba(monkeypatch: pytest.MonkeyPatch, on: bool) -> None:
    if on:
        pytest.importorskip("numba")
        monkeypatch.setattr(_kernels, "_loaded", None)
        assert _kernels.numba_enabled()
    else:
        monkeypatch.setattr(_kernels, "_loaded", False)  # as PDLIN_NUMBA=0 or no numba


def _bits_equal(A: sp.sparray, B: sp.sparray) -> bool:
    """Same shape, index arrays and data bits (-0.0 != 0.0)."""
    return (
        A.shape == B.shape
        and np.array_equal(A.indptr, B.indptr)
        and np.array_equal(A.indices, B.indices)
        and A.data.shape == B.data.shape
        and np.array_equal(A.data.view(np.int64), B.data.view(np.int64))
    )


def _messy_csr(rng: np.random.Generator, m: int, n_cols: int) -> sp.csr_array:
    """Canonical-free CSR: rows in reversed column order, explicit +0.0 and -0.0 entries."""
    dense = rng.normal(size=(m, n_cols)) * (rng.random((m, n_cols)) < 0.1)
    X = sp.csr_array(dense)
    X.data[::7] = 0.0
    X.data[::13] = -0.0
    X.data[::11] *= -1.0
    ind, dat = X.indices.copy(), X.data.copy()
    for r in range(0, m, 3):
        a, b = X.indptr[r], X.indptr[r + 1]
        ind[a:b] = ind[a:b][::-1]
        dat[a:b] = dat[a:b][::-1]
    return sp.csr_array((dat, ind, X.indptr), shape=X.shape)


@pytest.mark.parametrize("numba_on", [True, False])
@pytest.mark.parametrize("d", [1, 2, 3])
def test_block_conversions_equal_scipy(monkeypatch: pytest.MonkeyPatch, d: int, numba_on) -> None:
    _numba(monkeypatch, numba_on)
    rng = np.random.default_rng(d)
    X = _messy_csr(rng, 300, 60 * d)
    pieces = [sp.csr_array(X[:100]), sp.csr_array(X[100:101]), sp.csr_array(X[101:])]
    # scipy's serial conversions (the expected arrays)
    ref_t = sp.bsr_array(X.T.tocsr().tobsr(blocksize=(d, 1)))
    ref_t.sort_indices()
    ref_rows = sp.bsr_array(X.tobsr(blocksize=(1, d)))
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        for arg in (X, pieces):
            Xt = csr_to_bsr_t(arg, d)
            assert Xt.blocksize == (d, 1) and Xt.has_sorted_indices
            assert _bits_equal(Xt, ref_t)
            Xb = csr_to_bsr_rows(arg, d)
            assert Xb.blocksize == (1, d)
            assert _bits_equal(Xb, ref_rows)


def test_block_conversions_whole_blocks_keep_scipy_order(monkeypatch: pytest.MonkeyPatch) -> None:
    """Rows storing whole d-blocks: scipy's first-appearance order is the sorted one."""
    _numba(monkeypatch, True)
    cloud = pdlin.grid((6, 5, 4), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    unit = bonds.xi / bonds.length[:, None]
    B = _state._bond_operator(bonds, unit, cloud.n, 3)
    ref = sp.bsr_array(B.T.tocsr().tobsr(blocksize=(3, 1)))  # scipy's order, not re-sorted
    assert _bits_equal(csr_to_bsr_t(B, 3), ref)


def test_block_conversions_reject_bad_shapes() -> None:
    X = sp.csr_array(np.ones((2, 5)))
    with pytest.raises(ValueError, match="multiple of 2|stack in 2 columns"):
        csr_to_bsr_t(X, 2)
    with pytest.raises(ValueError, match="stack in 2 columns"):
        csr_to_bsr_rows([sp.csr_array(np.ones((2, 4))), sp.csr_array(np.ones((2, 6)))], 2)
    with pytest.raises(ValueError, match="no array"):
        csr_to_bsr_rows([], 2)


def _point_operator_coo(bonds, coef, unit, n, d):
    """The point operator as built before: COO -> CSR with sorted, summed duplicates."""
    cn = coef[:, None] * unit
    diag = np.empty((n, d))
    for k in range(d):
        diag[:, k] = -np.bincount(bonds.i, weights=cn[:, k], minlength=n)
    rows = np.concatenate([np.repeat(bonds.i, d), np.repeat(np.arange(n), d)])
    cols = np.concatenate(
        [
            (d * bonds.j[:, None] + np.arange(d)).ravel(),
            (d * np.arange(n)[:, None] + np.arange(d)).ravel(),
        ]
    )
    data = np.concatenate([cn.ravel(), diag.ravel()])
    out = sp.coo_array((data, (rows, cols)), shape=(n, n * d)).tocsr()
    out.sum_duplicates()
    return out


def _bond_operator_ref(bonds, unit, n, d):
    """``B`` as built before (one concatenation)."""
    cols = np.concatenate(
        [d * bonds.i[:, None] + np.arange(d), d * bonds.j[:, None] + np.arange(d)], axis=1
    )
    data = np.concatenate([-unit, unit], axis=1)
    indptr = np.arange(0, 2 * d * bonds.n_bonds + 1, 2 * d)
    return sp.csr_array((data.ravel(), cols.ravel(), indptr), shape=(bonds.n_bonds, n * d))


@pytest.mark.parametrize("dim", [2, 3])
def test_point_and_bond_operators_equal_serial(dim: int) -> None:
    cloud = pdlin.grid((23, 19) if dim == 2 else (9, 8, 7), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    unit = bonds.xi / bonds.length[:, None]
    coef = np.random.default_rng(dim).normal(size=bonds.n_bonds)
    coef[::5] = 0.0  # zero blocks stay stored
    ref_p = _point_operator_coo(bonds, coef, unit, cloud.n, dim)
    ref_b = _bond_operator_ref(bonds, unit, cloud.n, dim)
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        assert _bits_equal(_state._point_operator(bonds, coef, unit, cloud.n, dim), ref_p)
        assert _bits_equal(_state._bond_operator(bonds, unit, cloud.n, dim), ref_b)
    # families out of order (not the Bonds layout): the COO path sorts them
    perm = np.arange(bonds.n_bonds)
    a, b = bonds.indptr[3], bonds.indptr[4]
    perm[a:b] = perm[a:b][::-1]
    shuffled = pdlin.Bonds(
        bonds.n_points,
        bonds.i[perm],
        bonds.j[perm],
        bonds.xi[perm],
        bonds.length[perm],
        bonds.omega[perm],
        bonds.volume_j[perm],
        bonds.indptr,
        bonds.horizon,
    )
    assert not _state._families_sorted(shuffled)
    got = _state._point_operator(shuffled, coef[perm], unit[perm], cloud.n, dim)
    assert _bits_equal(got, _point_operator_coo(shuffled, coef[perm], unit[perm], cloud.n, dim))


def _stiffness_before(model, cloud, bonds) -> sp.bsr_array:
    """K as assembled before the threaded construction (energy linearization, all points
    with ω^d ∝ ω^h, as LPS): vstack, scipy's CSR -> CSC and tobsr, then the product."""
    d, n = cloud.dim, cloud.n
    co = model._coefficients(cloud, bonds)
    unit = bonds.xi / bonds.length[:, None]
    r = bonds.length
    wc = co["w"] * co["c"]
    B = _bond_operator_ref(bonds, unit, n, d)
    theta = _point_operator_coo(bonds, co["a"], unit, n, d)
    Bw = sp.csr_array((B.data * np.repeat(wc, 2 * d), B.indices, B.indptr), shape=B.shape)
    gcoef = wc * r / d
    s = np.bincount(bonds.i, weights=wc * r * r / d**2, minlength=n)
    a = co["a"]
    rho = np.bincount(bonds.i, weights=gcoef * a, minlength=n)
    den = np.bincount(bonds.i, weights=a * a, minlength=n)
    rho = np.divide(rho, den, out=np.zeros(n), where=den > 0)
    g = co["kV"] + s - 2.0 * rho
    X = sp.vstack([theta, B], format="csr")
    Y = sp.vstack([sp.dia_array((g, 0), shape=(n, n)) @ theta, Bw], format="csr")
    if _kernels.numba_enabled():
        Xt = sp.bsr_array(X.T.tocsr().tobsr(blocksize=(d, 1)))
        return _kernels.bsr_matmul(Xt, sp.bsr_array(Y.tobsr(blocksize=(1, d))))
    Yt = sp.bsr_array(Y.T.tocsr().tobsr(blocksize=(d, 1)))
    K = sp.bsr_array(sp.bsr_array(Yt @ sp.bsr_array(X.tobsr(blocksize=(1, d)))).transpose())
    K.sort_indices()
    return K


@pytest.mark.parametrize("numba_on", [True, False])
@pytest.mark.parametrize("dim", [2, 3])
def test_lps_stiffness_equals_serial_construction(monkeypatch, dim: int, numba_on) -> None:
    """LPS K: bitwise the assembly before the threaded construction, for 1, 2, 3 threads."""
    _numba(monkeypatch, numba_on)
    cloud = pdlin.grid((19, 17) if dim == 2 else (8, 7, 6), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    model = pdlin.LPS(E=2.0, nu=0.3, plane="strain")
    ref = sp.bsr_array(_stiffness_before(model, cloud, bonds), blocksize=(dim, dim))
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        K = model.stiffness(cloud, bonds)
        assert K.blocksize == (dim, dim)
        assert _bits_equal(K, ref), nt


@pytest.mark.parametrize("linearization", ["energy", "paper"])
def test_xosb_stiffness_identical_across_threads(monkeypatch, linearization: str) -> None:
    """XOSB (fallback rows, both linearizations): the same K bitwise for 1, 2, 3 threads."""
    _numba(monkeypatch, True)
    cloud = pdlin.grid((8, 7, 6), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=3.015)
    model = pdlin.XOSB(E=1.0, nu=0.3, linearization=linearization)
    out = []
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        out.append(model.stiffness(cloud, bonds))
    assert all(_bits_equal(K, out[0]) for K in out[1:])
    x = np.random.default_rng(1).normal(size=cloud.n * 3)
    y_mf = model.operator(cloud, bonds) @ x  # the matrix-free product, an independent path
    assert np.abs(out[0] @ x - y_mf).max() <= 1e-10 * np.abs(y_mf).max()


def _drop_zero_blocks_before(K: sp.bsr_array) -> sp.bsr_array:
    """Correspondence zero-block dropping as it was before threading (one serial pass)."""
    nrow = K.shape[0] // K.blocksize[0]
    brow = np.repeat(np.arange(nrow), np.diff(K.indptr))
    flat = K.data.reshape(K.data.shape[0], -1)
    size = np.abs(flat).max(axis=1)
    on_diag = K.indices == brow
    dsize = np.zeros(nrow)
    dsize[brow[on_diag]] = size[on_diag]
    tol = dsize[brow] * dsize[K.indices] * (16.0 * np.finfo(float).eps) ** 2
    keep = (size * size > tol) | on_diag
    counts = np.bincount(brow[keep], minlength=nrow)
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(K.indptr.dtype)
    return sp.bsr_array(
        (K.data[keep], K.indices[keep], indptr), shape=K.shape, blocksize=K.blocksize
    )


@pytest.mark.parametrize("numba_on", [True, False])
@pytest.mark.parametrize("dim", [2, 3])
def test_drop_zero_blocks_threaded_equals_serial(
    monkeypatch: pytest.MonkeyPatch, dim, numba_on
) -> None:
    """δ = h: the nearest-neighbour blocks of Wᵀ W cancel and are dropped; the threaded
    pass (small chunks: many per thread, empty block rows included) keeps the same blocks,
    numpy chunks or numba passes, with the block sizes computed or given by the product."""
    from pdlin.models.correspondence import gradient as corr

    cloud = pdlin.grid((9, 8, 7) if dim == 3 else (31, 23), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=1.0)
    model = pdlin.Correspondence(E=1.0, nu=0.25, control="none", plane="strain")
    plan = model._plan(cloud, bonds)
    monkeypatch.setattr(corr, "_drop_zero_blocks", lambda K, sizes=None: K)
    K = sp.bsr_array(model._core_stiffness(cloud, plan))
    monkeypatch.undo()
    _numba(monkeypatch, numba_on)
    # one block row emptied (dense -> BSR stores no zero block)
    K = sp.bsr_array(
        K.toarray() * (np.arange(K.shape[0]) // dim != 5)[:, None], blocksize=K.blocksize
    )
    ref = _drop_zero_blocks_before(K)
    assert ref.nnz < K.nnz  # blocks were dropped
    monkeypatch.setattr(corr, "_DROP_CHUNK", 37)  # many chunks on this small K
    monkeypatch.setattr(_kernels, "_MIN_WORK", 0)
    size = np.abs(K.data).max(axis=(1, 2))
    rows = np.repeat(np.arange(K.shape[0] // dim), np.diff(K.indptr))
    dsize = np.zeros(K.shape[0] // dim)
    dsize[rows[K.indices == rows]] = size[K.indices == rows]
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        assert _bits_equal(corr._drop_zero_blocks(K), ref)
        assert _bits_equal(corr._drop_zero_blocks(K, (size, dsize)), ref)


@pytest.mark.parametrize("numba_on", [True, False])
@pytest.mark.parametrize("blocksize", [(1, 1), (3, 2), (6, 3)])
def test_bsr_transpose_equals_scipy(monkeypatch: pytest.MonkeyPatch, blocksize, numba_on) -> None:
    _numba(monkeypatch, numba_on)
    R, C = blocksize
    rng = np.random.default_rng(R * 10 + C)
    mask = rng.random((50, 40)) < 0.2
    mask[3] = False  # an empty block row and an empty block column
    mask[:, 7] = False
    rows, cols = np.nonzero(mask)
    data = rng.normal(size=(rows.size, R, C))
    data[::5] = -0.0
    indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=1))])
    A = sp.bsr_array((data, cols, indptr), shape=(50 * R, 40 * C), blocksize=(R, C))
    ref = sp.bsr_array(A.T)  # scipy's serial bsr_transpose
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        At = _kernels.bsr_transpose(A)
        assert At.blocksize == (C, R)
        assert _bits_equal(At, ref)


def _coefficients_before(owner_b, n_gp, omega, volume_j, xi):
    """Correspondence bond coefficients ``ω V_j K⁻¹ ξ`` as computed before (2D / 3D)."""
    from pdlin._arrays import per_point_outer as _per_point_outer

    w = omega * volume_j
    K = _per_point_outer(owner_b, n_gp, w, xi, xi)
    if xi.shape[1] == 2:
        det = K[:, 0, 0] * K[:, 1, 1] - K[:, 0, 1] * K[:, 1, 0]
        Kinv = np.empty_like(K)
        Kinv[:, 0, 0], Kinv[:, 1, 1] = K[:, 1, 1], K[:, 0, 0]
        Kinv[:, 0, 1], Kinv[:, 1, 0] = -K[:, 0, 1], -K[:, 1, 0]
        Kinv /= det[:, None, None]
    else:
        Kinv = np.linalg.inv(K)
    c = np.zeros_like(xi)
    for q in range(xi.shape[1]):
        c += Kinv[:, :, q][owner_b] * xi[:, q : q + 1]
    return w[:, None] * c


@pytest.mark.parametrize("dim", [2, 3])
def test_correspondence_coefficients_and_moduli_threaded(monkeypatch, dim: int) -> None:
    """Bond coefficients and Pᵀ C P per gradient point in small chunks on 1-3 threads:
    bitwise the serial computation."""
    from pdlin.models.correspondence import gradient as corr

    cloud = pdlin.grid((17, 15) if dim == 2 else (7, 6, 5), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0, influence="inverse")
    ref = _coefficients_before(bonds.i, cloud.n, bonds.omega, bonds.volume_j, bonds.xi)
    model = pdlin.Correspondence(E=1.0, nu=0.25, plane="strain")
    Cv = model.voigt_stiffness(cloud)
    P = corr.voigt_projector(dim)
    vol = np.asarray(cloud.volumes) * (1.0 if dim == 3 else cloud.thickness)
    D_ref = (P.T @ Cv @ P) * vol[:, None, None]  # weight 1, every point carries energy
    monkeypatch.setattr(corr, "_ROW_CHUNK", 50)  # many chunks per thread
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        got = corr._coefficients(bonds.i, cloud.n, bonds.omega, bonds.volume_j, bonds.xi)
        assert np.array_equal(got.view(np.int64), ref.view(np.int64))
        model = pdlin.Correspondence(E=1.0, nu=0.25, plane="strain", control="none")
        assert np.array_equal(model._plan(cloud, bonds).D, D_ref)


def test_per_point_outer_threaded_equals_one_bincount(monkeypatch: pytest.MonkeyPatch) -> None:
    """Shape-tensor sums in runs of non-interleaving owners (1-3 threads): bitwise one
    bincount per entry over all bonds (the computation before)."""
    from pdlin import _arrays

    cloud = pdlin.grid((23, 19), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    w = np.random.default_rng(0).random(bonds.n_bonds)
    xi = bonds.xi
    side = (xi[:, 0] > 0).astype(np.int64)
    cases = [
        (bonds.i, cloud.n + 3),  # sorted owners, three without bonds at the end
        (2 * bonds.i + side, 2 * cloud.n),  # stress-point halves: interleaved within a point
        (np.random.default_rng(1).permutation(bonds.i), cloud.n),  # shuffled: one pass
    ]

    def before(owner, n):
        out = np.empty((n, 2, 2))
        for r in range(2):
            for c in range(2):
                out[:, r, c] = np.bincount(owner, weights=w * xi[:, r] * xi[:, c], minlength=n)
        return out

    monkeypatch.setattr(_arrays, "OUTER_CHUNK", 40)  # many runs
    for owner, n in cases:
        ref = before(owner, n)
        for nt in (1, 2, 3):
            pdlin.set_num_threads(nt)
            got = _arrays.per_point_outer(owner, n, w, xi, xi)
            assert np.array_equal(got.view(np.int64), ref.view(np.int64))
    # the stress-point halves with their runs given (point p: bonds indptr[p]:indptr[p+1],
    # owners 2p and 2p + 1), numba passes and numpy chunks
    owner, n = cases[1]
    runs = (np.asarray(bonds.indptr, dtype=np.int64), 2 * np.arange(cloud.n + 1))
    ref = before(owner, n)
    for numba_on in (True, False):
        monkeypatch.setattr(_kernels, "_loaded", None if numba_on else False)
        for nt in (1, 2, 3):
            pdlin.set_num_threads(nt)
            got = _arrays.per_point_outer(owner, n, w, xi, xi, runs=runs)
            assert np.array_equal(got.view(np.int64), ref.view(np.int64))


@pytest.mark.parametrize("numba_on", [True, False])
@pytest.mark.parametrize("control", ["none", "stress_points"])
@pytest.mark.parametrize("dim", [2, 3])
def test_gradient_blocks_fast_paths_equal_sort(monkeypatch, dim: int, control, numba_on) -> None:
    """G's blocks written in place in point chunks (1-3 threads; numba: one or two gradient
    points per point, with or without the known point structure; numpy: one per point) equal
    the sorting path's arrays bitwise (diagonals snapped to 0 on intact horizons included)."""
    from pdlin.models.correspondence import gradient as corr

    _numba(monkeypatch, numba_on)
    cloud = pdlin.grid((21, 17) if dim == 2 else (8, 7, 6), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0, influence="inverse")
    model = pdlin.Correspondence(E=1.0, nu=0.25, plane="strain", control=control)
    gp_owner, gp_of_bond, _ = model._gradient_points(cloud, bonds)
    n_gp = gp_owner.size
    c = corr._coefficients(gp_of_bond, n_gp, bonds.omega, bonds.volume_j, bonds.xi)
    gptr = np.concatenate([[0], np.cumsum(np.bincount(gp_owner, minlength=cloud.n))])
    ptrs = (np.asarray(bonds.indptr, dtype=np.int64), gptr.astype(np.int64))
    args = (gp_owner, gp_of_bond, bonds.j, c, cloud.n)
    fused, owner_sorted = corr._fused_blocks, corr._owner_sorted_blocks
    monkeypatch.setattr(corr, "_fused_blocks", lambda *a: None)
    monkeypatch.setattr(corr, "_owner_sorted_blocks", lambda *a: None)
    ref = corr._gradient_blocks(*args)  # one sort of the (g, point) keys
    monkeypatch.setattr(corr, "_fused_blocks", fused)
    monkeypatch.setattr(corr, "_owner_sorted_blocks", owner_sorted)
    assert (ref.val[ref.diag] == 0.0).any()  # interior diagonals snapped
    assert (n_gp > cloud.n) == (control == "stress_points")
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        paths = [corr._gradient_blocks(*args), corr._gradient_blocks(*args, ptrs)]
        paths += [fused(*args), fused(*args, ptrs), owner_sorted(*args)]
        assert (paths[2] is not None) == numba_on
        assert (paths[4] is not None) == (control == "none")
        for got in paths:
            if got is None:
                continue
            for f in ("indptr", "col", "diag", "bond_block", "owner_block"):
                a, b = getattr(got, f), getattr(ref, f)
                assert a.dtype == b.dtype and np.array_equal(a, b), f
            assert np.array_equal(got.val.view(np.int64), ref.val.view(np.int64))
    # other layouts take the sorting path
    order = np.arange(n_gp)[::-1].copy()
    assert fused(order, *args[1:]) is None and owner_sorted(order, *args[1:]) is None
    flipped = args[1][::-1].copy()
    assert fused(args[0], flipped, *args[2:]) is None
    assert owner_sorted(args[0], flipped, *args[2:]) is None


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize("given_directions", [False, True])
def test_pair_stiffness_fused_kernel_equals_numpy_path(
    monkeypatch: pytest.MonkeyPatch, dim: int, given_directions: bool
) -> None:
    """The numba pass that writes each bond block once (pair_blocks_fill) against the numpy
    chunk path: same index arrays, off-diagonal blocks bitwise (same formula), diagonal sums
    to round-off (1e-15 of the largest entry: summation order), bitwise equal for 1-3
    threads; isolated points (empty rows) inside chunks and tiny chunks included."""
    from pdlin.operators import assembly

    pytest.importorskip("numba")
    rng = np.random.default_rng(10 + dim)
    cloud = pdlin.PointCloud(rng.random((300, dim)), volumes=np.full(300, 1e-3))
    horizon = {1: 0.004, 2: 0.05, 3: 0.12}[dim]
    bonds = pdlin.find_bonds(cloud, horizon=horizon, allow_isolated=True)
    assert (np.diff(bonds.indptr) == 0).sum() > 5 and bonds.n_bonds > 100
    k = rng.random(bonds.n_bonds)
    dirs = None
    if given_directions:  # unit vectors not equal to xi / |xi|: the given ones must be used
        raw = bonds.xi + 0.1 * rng.standard_normal(bonds.xi.shape)
        dirs = raw / np.linalg.norm(raw, axis=1)[:, None]
    monkeypatch.setattr(assembly, "_CHUNK", 37)
    _numba(monkeypatch, False)
    ref = assembly.pair_stiffness_bsr(bonds, k, dirs)
    _numba(monkeypatch, True)
    rows = np.repeat(np.arange(bonds.n_points), np.diff(ref.indptr))
    off = ref.indices != rows
    first = None
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        K = assembly.pair_stiffness_bsr(bonds, lambda b0, b1: k[b0:b1], dirs)
        K.check_format(full_check=True)
        assert np.array_equal(K.indptr, ref.indptr) and np.array_equal(K.indices, ref.indices)
        assert np.array_equal(K.data[off], ref.data[off])
        scale = np.abs(ref.data).max()
        assert np.abs(K.data[~off] - ref.data[~off]).max() <= 1e-15 * scale
        first = K if first is None else first
        assert _bits_equal(K, first)


@pytest.mark.parametrize("dim", [2, 3])
def test_stress_point_plan_numba_equals_numpy(monkeypatch: pytest.MonkeyPatch, dim: int) -> None:
    """Stress points: sides, balanced halves, gradient points of the bonds and the bond
    coefficients summed over point chunks (numba, 1-3 threads, many small chunks) equal the
    numpy path's arrays bitwise, on a lattice (two stress points inside, one at the
    surface) and on a perturbed cloud (unbalanced halves: mostly one)."""
    from pdlin.models.correspondence import gradient as corr

    pytest.importorskip("numba")
    shape = (19, 16) if dim == 2 else (7, 6, 6)
    lattice = pdlin.grid(shape, spacing=0.1)
    pts = lattice.points + np.random.default_rng(3).normal(scale=0.004, size=lattice.points.shape)
    perturbed = pdlin.PointCloud(pts, volumes=lattice.volumes)
    for cloud, horizon in ((lattice, 0.2001), (perturbed, 0.25)):
        bonds = pdlin.find_bonds(cloud, horizon=horizon)

        def plan(cloud: pdlin.PointCloud, bonds: pdlin.Bonds) -> tuple[np.ndarray, ...]:
            model = pdlin.Correspondence(E=1.0, nu=0.25, plane="strain", control="stress_points")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # perturbed: no two-SP point
                owner, gob, w = model._gradient_points(cloud, bonds)
            gptr = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=cloud.n))])
            ptrs = (np.asarray(bonds.indptr, dtype=np.int64), gptr.astype(np.int64))
            args = (gob, owner.size, bonds.omega, bonds.volume_j, bonds.xi)
            c = corr._coefficients(*args, ptrs=ptrs)
            return owner, gob, w, c, corr._coefficients(*args)

        monkeypatch.setattr(_kernels, "_loaded", False)
        ref = plan(cloud, bonds)
        monkeypatch.setattr(_kernels, "_loaded", None)
        monkeypatch.setattr(corr, "_POINT_CHUNK", 40)
        monkeypatch.setattr(corr, "_ROW_CHUNK", 50)
        assert ref[0].size > cloud.n or cloud is perturbed  # two stress points somewhere
        for nt in (1, 2, 3):
            pdlin.set_num_threads(nt)
            got = plan(cloud, bonds)
            for a, b in zip(got, ref, strict=True):
                assert a.dtype == b.dtype and np.array_equal(a, b)
            assert np.array_equal(got[3].view(np.int64), ref[3].view(np.int64))


def test_gradient_blocks_fused_declines_repeated_neighbours(monkeypatch) -> None:
    """A point bonded twice to one neighbour (periodic images) or to itself: the numba pass
    flags the layout and the sorting path, which sums the repeated pairs, builds G."""
    from pdlin.models.correspondence import gradient as corr

    pytest.importorskip("numba")
    cloud = pdlin.grid((6, 5), spacing=1.0)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    n = cloud.n
    c = corr._coefficients(bonds.i, n, bonds.omega, bonds.volume_j, bonds.xi)
    ptrs = (np.asarray(bonds.indptr, dtype=np.int64), np.arange(n + 1, dtype=np.int64))
    fused = corr._fused_blocks
    b0 = int(bonds.indptr[7])  # the bonds of point 7
    for change in ("repeat", "self"):
        j = bonds.j.copy()
        j[b0 + 1] = j[b0] if change == "repeat" else 7
        args = (np.arange(n), bonds.i, j, c, n)
        assert fused(*args) is None and fused(*args, ptrs) is None
        got = corr._gradient_blocks(*args, ptrs)
        monkeypatch.setattr(corr, "_fused_blocks", lambda *a: None)
        monkeypatch.setattr(corr, "_owner_sorted_blocks", lambda *a: None)
        ref = corr._gradient_blocks(*args)
        monkeypatch.setattr(corr, "_fused_blocks", fused)
        assert got.col.size == bonds.n_bonds + n - 1  # the repeated pair summed into one
        for f in ("indptr", "col", "val", "diag", "bond_block", "owner_block"):
            assert np.array_equal(getattr(got, f), getattr(ref, f)), f


def test_fused_2d_coefficients_report_singular_shape_tensors() -> None:
    """A one-point-wide strip has collinear bonds: the fused 2D pass raises the numpy
    path's error (count and first gradient point) instead of dividing by det = 0."""
    from pdlin.errors import ModelError
    from pdlin.models.correspondence import gradient as corr

    pytest.importorskip("numba")
    cloud = pdlin.grid((40, 1), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    n = cloud.n
    ptrs = (np.asarray(bonds.indptr, dtype=np.int64), np.arange(n + 1, dtype=np.int64))
    args = (bonds.i, n, bonds.omega, bonds.volume_j, bonds.xi)
    with pytest.raises(
        ModelError, match="got 40 singular one\\(s\\) \\(first: gradient point 0\\)"
    ):
        corr._coefficients(*args, ptrs=ptrs)
    with pytest.raises(
        ModelError, match="got 40 singular one\\(s\\) \\(first: gradient point 0\\)"
    ):
        corr._coefficients(*args)
