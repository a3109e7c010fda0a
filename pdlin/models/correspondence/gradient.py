"""The sparse gradient operator of correspondence peridynamics and its block products.

``∇u_g = Σ_b (u_b - u_a) ⊗ c_gb`` with ``c_gb = ω_ab V_b K_g⁻¹ ξ_ab`` (Javaheri et al.
(2022), Eqs. 6-7, in sparse form): bond coefficients (:func:`_coefficients`), the blocks of
G per (gradient point, point) pair, G in CSR, and the products and zero-block dropping of
``Gᵀ D G``.  Large inputs run in fixed chunks on pdlin's threads (and in numba passes when
numba is installed), with the same bits as the serial numpy path.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..._arrays import (
    per_point_outer,
    with_diagonal_blocks,
)
from ..._kernels import compiled_kernels, use_numba
from ..._threads import even_chunks, ptr_chunks, thread_map
from ..._validation import as_float_array
from ...errors import InputError, ModelError, ShapeError
from ...geometry.bonds import Bonds
from ...geometry.cloud import PointCloud

__all__ = [
    "gradient_operator",
    "voigt_projector",
    "intact_shape_tensor",
]


def _coefficients_2d_fused(
    mod: Any,
    ptrs: tuple[np.ndarray, np.ndarray],
    owner_b: np.ndarray,
    n_gp: int,
    w: np.ndarray,
    xi: np.ndarray,
) -> np.ndarray:
    """Return :func:`_coefficients` in 2D from one numba pass per point chunk.

    Shape tensors, their inverses and the coefficients, with the numpy path's arithmetic
    and error.
    """
    bptr, gptr = ptrs
    K = np.empty((n_gp, 2, 2))
    bad = np.empty(n_gp, dtype=bool)
    out = np.empty_like(xi, dtype=np.float64)
    args = (
        bptr,
        gptr,
        np.ascontiguousarray(owner_b, dtype=np.int64),
        np.ascontiguousarray(w, dtype=np.float64),
        np.ascontiguousarray(xi, dtype=np.float64),
        K,
        bad,
        out,
    )
    kern = mod.coefficients_2d_fill
    thread_map(lambda r: kern(r[0], r[1], *args), ptr_chunks(bptr, _POINT_CHUNK))
    if bad.any():
        _raise_singular(np.flatnonzero(bad), 2)
    return out


def _raise_singular(bad: np.ndarray, d: int) -> None:
    raise ModelError(
        f"shape tensor must be invertible at every gradient point, got {bad.size} singular "
        f"one(s) (first: gradient point {int(bad[0])}); its bonds do not span {d}D "
        "(isolated points, one-point-wide strips, or weights with Ω = 0)"
    )


def voigt_projector(dim: int) -> np.ndarray:
    """Map ``vec(∇u)`` (row-major ``(i, j)`` → ``d*i + j``) to Voigt strain.

    Engineering shear: 2D ``[ε11, ε22, γ12]``, 3D
    ``[ε11, ε22, ε33, γ23, γ13, γ12]`` (the order of
    :mod:`pdlin.constitutive`).  ``Pᵀ C P`` is the full tensor ``C_ijkl``
    acting on ``vec(∇u)``.

    Parameters
    ----------
    dim : {1, 2, 3}
        Spatial dimension.

    Returns
    -------
    (nv, dim*dim) ndarray of float
        ``P`` with ``ε_voigt = P vec(∇u)``; ``nv`` = 1, 3, 6.

    Examples
    --------
    >>> voigt_projector(2).tolist()
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 1.0, 1.0, 0.0]]
    """
    pairs = {1: ((0, 0),), 2: ((0, 0), (1, 1), (0, 1)),
             3: ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))}  # fmt: skip
    if dim not in pairs:
        raise InputError(f"dim must be 1, 2 or 3, got {dim}")
    P = np.zeros((len(pairs[dim]), dim * dim))
    for a, (i, j) in enumerate(pairs[dim]):
        P[a, dim * i + j] = 1.0
        P[a, dim * j + i] = 1.0
    return P


def _coefficients(
    owner_b: np.ndarray,
    n_gp: int,
    omega: np.ndarray,
    volume_j: np.ndarray,
    xi: np.ndarray,
    kinv_override: Mapping[int, np.ndarray] | None = None,
    override_rows: np.ndarray | None = None,
    override_kinv: np.ndarray | None = None,
    ptrs: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Bond coefficients ``c_b = ω V_j K_g⁻¹ ξ`` (nb, d); K_g from the gradient point's bonds.

    ``ptrs = (bptr, gptr)``: point ``p`` owns the bonds ``bptr[p]:bptr[p+1]`` and the
    gradient points ``gptr[p]:gptr[p+1]`` of those bonds (no control, stress points): the
    shape tensors are then summed over point chunks on the threads without a pass to find
    them, and in 2D with numba tensors, inverses and coefficients are one pass.
    """
    d = xi.shape[1]
    w = omega * volume_j
    mod = compiled_kernels() if ptrs is not None and use_numba(xi.size) else None
    if mod is not None and ptrs is not None and d == 2 and override_rows is None:
        return _coefficients_2d_fused(mod, ptrs, owner_b, n_gp, w, xi)
    K = per_point_outer(owner_b, n_gp, w, xi, xi, runs=ptrs)  # pdlin.fields' shape tensor
    if override_rows is not None and override_rows.size:
        assert override_kinv is not None
        K[override_rows] = np.linalg.inv(override_kinv)
    tr = np.abs(np.einsum("nii->n", K))
    if d == 2:  # closed form (batched 2 x 2 LAPACK calls cost ~10x more)
        det = K[:, 0, 0] * K[:, 1, 1] - K[:, 0, 1] * K[:, 1, 0]
    else:
        det = np.linalg.det(K)
    bad = np.flatnonzero(~(np.abs(det) > 1e-12 * np.maximum(tr / d, 1e-300) ** d))
    if bad.size:
        _raise_singular(bad, d)
    if d == 2:  # adjugate / det (as accurate as LU for 2 x 2)
        Kinv = np.empty_like(K)
        Kinv[:, 0, 0] = K[:, 1, 1]
        Kinv[:, 1, 1] = K[:, 0, 0]
        Kinv[:, 0, 1] = -K[:, 0, 1]
        Kinv[:, 1, 0] = -K[:, 1, 0]
        Kinv /= det[:, None, None]
    else:
        Kinv = np.linalg.inv(K)
    if override_rows is not None and override_rows.size:
        Kinv[override_rows] = override_kinv
    Kinv = np.ascontiguousarray(Kinv, dtype=np.float64)
    out = np.empty_like(xi)
    mod = compiled_kernels() if use_numba(xi.size) else None
    if mod is not None:  # one nogil pass per bond chunk, the numpy path's arithmetic
        kern = mod.bond_coefficients_fill
        own_c = np.ascontiguousarray(owner_b, dtype=np.int64)
        xi_c = np.ascontiguousarray(xi, dtype=np.float64)
        w_c = np.ascontiguousarray(w, dtype=np.float64)

        def fused(rng: tuple[int, int]) -> None:
            kern(rng[0], rng[1], own_c, w_c, xi_c, Kinv, out)

        thread_map(fused, even_chunks(xi.shape[0], _ROW_CHUNK))
        return out
    cols = [np.ascontiguousarray(Kinv[:, :, q]) for q in range(d)]

    def chunk(rng: tuple[int, int]) -> None:  # fixed bond chunks on the threads (elementwise)
        b0, b1 = rng
        own = owner_b[b0:b1]
        c = np.zeros((b1 - b0, d))
        for q in range(d):  # Σ_q K⁻¹[:, q] ξ_q, gathered per component (no batched einsum)
            c += cols[q][own] * xi[b0:b1, q : q + 1]
        np.multiply(w[b0:b1, None], c, out=out[b0:b1])

    thread_map(chunk, even_chunks(xi.shape[0], _ROW_CHUNK))
    return out


@dataclasses.dataclass(frozen=True)
class _GradientBlocks:
    """G by (gradient point, point) blocks: block ``(g, col)`` is ``I_d ⊗ val`` (d² x d).

    Blocks of a gradient point are contiguous (``indptr``) and sorted by point; the
    owner's block (``diag``) holds ``-Σ c`` (zero on intact horizons).
    """

    indptr: np.ndarray  # (n_gp + 1,)
    col: np.ndarray  # (nblk,) point of each block
    val: np.ndarray  # (nblk, d) coefficient vector
    diag: np.ndarray  # (nblk,) bool: owner's block, no bond in it
    bond_block: np.ndarray  # (nb,) block holding each bond's (g, j)
    owner_block: np.ndarray  # (n_gp,) block of each gradient point's owner

    @property
    def row(self) -> np.ndarray:
        """Gradient point of each block, ``(nblk,)``."""
        return np.repeat(np.arange(self.indptr.size - 1), np.diff(self.indptr))


def _gradient_blocks(
    gp_owner: np.ndarray,
    gp_of_bond: np.ndarray,
    j: np.ndarray,
    c: np.ndarray,
    n_points: int,
    ptrs: tuple[np.ndarray, np.ndarray] | None = None,
) -> _GradientBlocks:
    """Block structure of G from bond coefficients; round-off diagonals snapped to 0.

    One sort of the ``(g, point)`` keys (bonds and owners together); repeated pairs
    (periodic images of one point in a small lattice) are summed.
    """
    d = c.shape[1]
    n_gp = gp_owner.size
    fast = _fused_blocks(gp_owner, gp_of_bond, j, c, n_points, ptrs)
    if fast is None:
        fast = _owner_sorted_blocks(gp_owner, gp_of_bond, j, c, n_points)
    if fast is not None:
        return fast
    # diagonal -Σ_b c_gb per gradient point; exact zero on intact (symmetric) horizons
    diag = np.empty((n_gp, d))
    scale = np.empty((n_gp, d))
    for q in range(d):
        diag[:, q] = -np.bincount(gp_of_bond, weights=c[:, q], minlength=n_gp)
        scale[:, q] = np.bincount(gp_of_bond, weights=np.abs(c[:, q]), minlength=n_gp)
    diag[np.abs(diag) <= 64 * np.finfo(float).eps * scale] = 0.0
    keys = np.concatenate(
        [
            gp_of_bond.astype(np.int64) * n_points + j,
            np.arange(n_gp, dtype=np.int64) * n_points + gp_owner,
        ]
    )
    vals = np.concatenate([c, diag])
    is_diag = np.concatenate([np.zeros(j.size, dtype=bool), np.ones(n_gp, dtype=bool)])
    order = np.argsort(keys, kind="stable")
    keys = keys[order]
    vals = vals[order]
    is_diag = is_diag[order]
    first = np.ones(keys.size, dtype=bool)
    first[1:] = keys[1:] != keys[:-1]
    block_of = np.empty(keys.size, dtype=np.int64)  # block of each input entry
    block_of[order] = np.cumsum(first) - 1
    if not first.all():  # repeated (g, point) pairs: sum them
        starts = np.flatnonzero(first)
        vals = np.add.reduceat(vals, starts, axis=0)
        is_diag = np.logical_and.reduceat(is_diag, starts)
        keys = keys[starts]
    g = keys // n_points
    indptr = np.zeros(n_gp + 1, dtype=np.int64)
    np.cumsum(np.bincount(g, minlength=n_gp), out=indptr[1:])
    nb = j.size
    return _GradientBlocks(indptr, keys - g * n_points, vals, is_diag, block_of[:nb], block_of[nb:])


def _fused_blocks(
    gp_owner: np.ndarray,
    gp_of_bond: np.ndarray,
    j: np.ndarray,
    c: np.ndarray,
    n_points: int,
    ptrs: tuple[np.ndarray, np.ndarray] | None = None,
) -> _GradientBlocks | None:
    """Return the blocks of :func:`_gradient_blocks` in one numba pass per point chunk.

    Only when each point owns consecutive gradient points and the bonds of those
    gradient points in the :class:`Bonds` order (no control, stress points): None
    otherwise (or without numba).

    A gradient point's blocks are its bonds in order (increasing, distinct neighbours,
    none the owner) with the owner's block among them: their slots are known from the
    counts, so point chunks write them on the threads (``np.bincount``, which the sorting
    path sums with, holds the GIL); the sums run over the same bonds in the same order:
    the same arrays bitwise.
    """
    n_gp, nb, d = gp_owner.size, j.size, c.shape[1]
    mod = compiled_kernels() if use_numba(nb * d) else None
    if mod is None or n_gp == 0:
        return None
    if ptrs is not None:  # the structure is known (see _coefficients)
        bptr, gptr = ptrs
    else:
        if not bool(np.all(gp_owner[1:] >= gp_owner[:-1])):
            return None
        own_b = gp_owner[gp_of_bond]  # point of each bond
        if not bool(np.all(own_b[1:] >= own_b[:-1])):
            return None
        pts = np.arange(n_points + 1)
        gptr = np.searchsorted(gp_owner, pts).astype(np.int64)
        bptr = np.searchsorted(own_b, pts).astype(np.int64)
    per_gp = np.bincount(gp_of_bond, minlength=n_gp)
    indptr = np.zeros(n_gp + 1, dtype=np.int64)
    np.cumsum(per_gp + 1, out=indptr[1:])
    nblk = int(indptr[-1])
    col = np.empty(nblk, dtype=np.int64)
    val = np.empty((nblk, d))
    is_diag = np.empty(nblk, dtype=bool)
    bond_block = np.empty(nb, dtype=np.int64)
    owner_block = np.empty(n_gp, dtype=np.int64)
    kern = mod.gradient_blocks_fill
    gob = np.ascontiguousarray(gp_of_bond, dtype=np.int64)
    jc = np.ascontiguousarray(j, dtype=np.int64)
    cc = np.ascontiguousarray(c, dtype=np.float64)
    tiny = 64 * np.finfo(float).eps
    layout_ok = np.empty(n_points, dtype=bool)

    def chunk(rng: tuple[int, int]) -> None:
        kern(
            rng[0], rng[1], bptr, gptr, gob, jc, cc, indptr, col, val, is_diag, bond_block,
            owner_block, tiny, layout_ok,
        )  # fmt: skip

    thread_map(chunk, ptr_chunks(bptr, _POINT_CHUNK))
    if not layout_ok.all():  # repeated neighbours (periodic images) or a bond to itself
        return None
    return _GradientBlocks(indptr, col, val, is_diag, bond_block, owner_block)


def _owner_sorted_blocks(
    gp_owner: np.ndarray, gp_of_bond: np.ndarray, j: np.ndarray, c: np.ndarray, n_points: int
) -> _GradientBlocks | None:
    """Return the blocks of :func:`_gradient_blocks` without its sort.

    Only when one gradient point per point owns that point's bonds in the :class:`Bonds`
    order (no control): None otherwise.

    Block slots are known (bond ``b`` of point ``g``: ``b + g + [j_b > g]``; the owner's
    block after its smaller neighbours), so fixed point chunks write them on the threads;
    each per-point sum runs over the same bonds in the same order as the sorting path's
    ``np.bincount``: the same arrays bitwise.
    """
    n_gp, nb, d = gp_owner.size, j.size, c.shape[1]
    if n_gp != n_points or nb == 0 or not np.array_equal(gp_owner, np.arange(n_gp)):
        return None
    g = gp_of_bond
    if not bool(np.all(g[1:] >= g[:-1])) or bool(np.any(j == g)):
        return None
    if not bool(np.all((j[1:] > j[:-1]) | (g[1:] != g[:-1]))):
        return None
    bptr = np.zeros(n_gp + 1, dtype=np.int64)
    np.cumsum(np.bincount(g, minlength=n_gp), out=bptr[1:])
    nblk = nb + n_gp
    col = np.empty(nblk, dtype=np.int64)
    val = np.empty((nblk, d))
    is_diag = np.zeros(nblk, dtype=bool)
    bond_block = np.empty(nb, dtype=np.int64)
    owner_block = np.empty(n_gp, dtype=np.int64)
    tiny = 64 * np.finfo(float).eps

    def chunk(rng: tuple[int, int]) -> None:
        p0, p1 = rng
        b0, b1 = int(bptr[p0]), int(bptr[p1])
        own, nbr = g[b0:b1], j[b0:b1]
        pos = np.arange(b0, b1) + own + (nbr > own)
        bond_block[b0:b1] = pos
        col[pos] = nbr
        val[pos] = c[b0:b1]
        loc = own - p0
        pts = np.arange(p0, p1)
        dpos = bptr[p0:p1] + pts + np.bincount(loc[nbr < own], minlength=p1 - p0)
        owner_block[p0:p1] = dpos
        col[dpos] = pts
        is_diag[dpos] = True
        for q in range(d):
            dq = -np.bincount(loc, weights=c[b0:b1, q], minlength=p1 - p0)
            sq = np.bincount(loc, weights=np.abs(c[b0:b1, q]), minlength=p1 - p0)
            dq[np.abs(dq) <= tiny * sq] = 0.0
            val[dpos, q] = dq

    step = 1 << 16
    starts = g[np.arange(step, nb, step)]
    edges = np.unique(np.concatenate([[0], starts, [n_gp]]))
    thread_map(chunk, list(zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True)))
    indptr = bptr + np.arange(n_gp + 1)
    return _GradientBlocks(indptr, col, val, is_diag, bond_block, owner_block)


def _blocks_to_csr(blk: _GradientBlocks, n_points: int) -> sp.csr_array:
    """Return G in CSR, rows ``(g, i, q)``: the nonzero coefficients only.

    Exact zeros are dropped: the owner's entries of a symmetric family, and the components
    of bond coefficients ``c_gp`` that vanish — at δ = h on a grid half of them (an axial
    bond's coefficient has no transverse component), so keeping them doubled the work of
    every ``G u`` and ``Gᵀ s`` (the sums are the same without them).
    """
    d = blk.val.shape[1]
    n_gp = blk.indptr.size - 1
    counts = np.diff(blk.indptr)
    g = blk.row
    pos = np.arange(g.size) - blk.indptr[g]
    iq = np.arange(d * d).reshape(1, d, d)  # i*d + q
    # full layout: row (g, i, q) holds all blocks of g in order
    off = (
        (d * d * blk.indptr[g])[:, None, None] + iq * counts[g][:, None, None] + pos[:, None, None]
    )
    n_full = int(d * d * blk.indptr[-1])
    data = np.empty(n_full)
    data[off] = np.broadcast_to(blk.val[:, None, :], off.shape)
    idx_dtype = np.int32 if max(n_full, n_points * d) < np.iinfo(np.int32).max else np.int64
    indices = np.empty(n_full, dtype=idx_dtype)
    comp = np.arange(d)
    indices[off] = np.broadcast_to((blk.col[:, None] * d + comp)[:, :, None], off.shape)
    drop_bq = blk.val == 0.0  # (nblk, q): zero coefficients (every i)
    lengths = np.repeat(counts, d * d)
    if drop_bq.any():
        keep = np.ones(n_full, dtype=bool)
        keep[off[np.broadcast_to(drop_bq[:, None, :], off.shape)]] = False
        data, indices = data[keep], indices[keep]
        b, q = np.nonzero(drop_bq)
        rows = ((g[b][:, None] * d + comp) * d + q[:, None]).ravel()  # every i
        lengths = lengths - np.bincount(rows, minlength=n_gp * d * d)
    indptr = np.zeros(n_gp * d * d + 1, dtype=idx_dtype)
    np.cumsum(lengths, out=indptr[1:])
    return sp.csr_array((data, indices, indptr), shape=(n_gp * d * d, n_points * d))


def _gradient_csr(
    gp_owner: np.ndarray,
    gp_of_bond: np.ndarray,
    j: np.ndarray,
    c: np.ndarray,
    n_points: int,
) -> sp.csr_array:
    """Assemble G (n_gp·d² x n·d) from bond coefficients; round-off diagonals snapped to 0."""
    return _blocks_to_csr(_gradient_blocks(gp_owner, gp_of_bond, j, c, n_points), n_points)


def gradient_operator(
    cloud: PointCloud, bonds: Bonds, omega: np.ndarray | None = None
) -> sp.csr_array:
    """Sparse nonlocal gradient ``G``: ``(G @ u.ravel()).reshape(n, d, d) = ∇u``.

    ``G_j[a, b] = c_ab,j`` and ``G_j[a, a] = -Σ_b c_ab,j`` with
    ``c_ab = ω_ab V_b K_a⁻¹ ξ_ab`` (Javaheri et al. (2022), Eqs. 6-7, in sparse form); rows
    are ordered ``(a, i, j)`` for ``∂u_i/∂X_j`` and columns are interleaved DOFs.
    ``G u`` equals ``pdlin.fields.deformation_gradient(cloud, bonds, u) - I``, so it
    is exact for affine fields wherever ``K_a`` is invertible.  Diagonals
    that vanish up to round-off (intact horizons) are stored as exact zeros.

    Parameters
    ----------
    cloud : PointCloud
    bonds : Bonds
    omega : (nb,) array_like, optional
        Weights replacing ``bonds.omega`` (may be negative, e.g. the
        higher-order sets of Javaheri et al. (2022)).

    Returns
    -------
    scipy.sparse.csr_array of shape (n*d*d, n*d)

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((5, 4), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=2.0)
    >>> G = gradient_operator(cloud, bonds)
    >>> H = np.array([[1e-3, 2e-3], [-4e-3, 5e-4]])
    >>> grad = (G @ (cloud.points @ H.T).ravel()).reshape(cloud.n, 2, 2)
    >>> bool(np.allclose(grad, H, atol=1e-14))
    True
    """
    om = bonds.omega if omega is None else as_float_array(omega, "omega")
    if om.shape != (bonds.n_bonds,):
        raise ShapeError(f"omega must have shape ({bonds.n_bonds},), got {om.shape}")
    c = _coefficients(bonds.i, cloud.n, om, bonds.volume_j, bonds.xi)
    return _gradient_csr(np.arange(cloud.n), bonds.i, bonds.j, c, cloud.n)


def intact_shape_tensor(cloud: PointCloud, bonds: Bonds, omega_fn: Any) -> np.ndarray:
    """Return the shape tensor of a complete lattice horizon, ``(d, d)``.

    Built from the integer stencil ``|p h| <= δ`` of a :func:`pdlin.grid`
    cloud with uniform spacing, volume and horizon; ``omega_fn(length,
    horizon)`` gives the weights.  Shadow particles use it (pdlin's choice for the shadow
    layer of Javaheri et al. (2022), Sec. II.D).

    Parameters
    ----------
    cloud : PointCloud
        The points (``n`` of them, dimension ``d``).
    bonds : Bonds
        Their bonds (``nb`` ordered bonds).
    omega_fn : callable
        ``ω(length, horizon)``, the influence function.

    Returns
    -------
    (d, d) ndarray of float
        ``Σ_p ω V p h ⊗ p h`` over the stencil.
    """
    lat = cloud.lattice
    if lat is None:
        raise ModelError("a shadow layer needs a pdlin.grid cloud (lattice metadata), got none")
    hs = np.asarray(lat.spacing, dtype=float)
    hor = np.asarray(bonds.horizon, dtype=float)
    if not (np.allclose(hs, hs[0], rtol=1e-12) and np.allclose(hor, hor[0], rtol=1e-12)):
        raise ModelError("a shadow layer needs equal spacing on every axis and a constant horizon")
    vol = np.asarray(cloud.volumes)
    if not np.allclose(vol, vol[0], rtol=1e-12):
        raise ModelError("a shadow layer needs uniform point volumes")
    d = cloud.dim
    delta = float(hor[0])
    m = int(np.floor(delta * (1 + 1e-9) / hs[0]))
    rng = np.arange(-m, m + 1)
    offs = np.stack([g.ravel() for g in np.meshgrid(*([rng] * d), indexing="ij")], axis=1)
    offs = offs[np.any(offs != 0, axis=1)]
    vec = offs * hs[0]
    length = np.sqrt(np.sum(vec**2, axis=1))
    keep = length <= delta * (1 + 1e-9)
    vec, length = vec[keep], length[keep]
    om = np.asarray(omega_fn(length, np.full(length.size, delta)), dtype=float)
    return np.einsum("b,bi,bj->ij", om * vol[0], vec, vec)


def _mean_per_point(owner: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """Plain mean of gradient-point tensors ``(n_gp, d, d)`` over each point's gradient points."""
    d = values.shape[1]
    cnt = np.bincount(owner, minlength=n).astype(float)
    flat = values.reshape(len(owner), d * d)
    out = np.stack([np.bincount(owner, weights=flat[:, k], minlength=n) for k in range(d * d)], 1)
    return (out / cnt[:, None]).reshape(n, d, d)


#: rows per chunk of the threaded dense products (fixed: results do not depend on the
#: thread count)
_ROW_CHUNK = 1 << 15


#: stored blocks per chunk of block rows in the zero-block dropping
_DROP_CHUNK = 1 << 16


#: bonds per chunk of points in the numba passes over points (coefficients, G's blocks,
#: stress-point sides)
_POINT_CHUNK = 1 << 16


def _rows_matmul(
    A: np.ndarray,
    M: np.ndarray,
    row_scale: np.ndarray | Callable[[int, int], np.ndarray] | None = None,
) -> np.ndarray:
    """Return ``A @ M``, times ``row_scale`` per row, in fixed row chunks on threads.

    ``row_scale`` is an array, or a function giving the scales of the rows ``a:b``.
    """
    out = np.empty((A.shape[0], M.shape[1]))

    def chunk(rng: tuple[int, int]) -> None:
        a, b = rng
        np.matmul(A[a:b], M, out=out[a:b])
        if callable(row_scale):
            out[a:b] *= row_scale(a, b)[:, None]
        elif row_scale is not None:
            out[a:b] *= row_scale[a:b, None]

    thread_map(chunk, even_chunks(A.shape[0], _ROW_CHUNK))
    return out


def _drop_zero_blocks(
    K: sp.bsr_array, sizes: tuple[np.ndarray, np.ndarray] | None = None
) -> sp.bsr_array:
    """``K`` without its stored blocks that cancel in exact arithmetic.

    At δ = h the nearest-neighbour blocks of ``Wᵀ W`` cancel exactly (the decoupled
    sub-lattices), and higher-order weights cancel more: keeping them would inflate nnz and
    every product with K. In floating point some of these sums leave round-off (3D δ = h:
    entries ~1e-17 of the diagonal, 4.6 % more blocks on a 24³ grid), so an off-diagonal
    block ``(i, j)`` is dropped when ``max|K_ij| <= 16 ε sqrt(max|K_ii| max|K_jj|)``: below
    the round-off of the product itself, symmetric in ``(i, j)`` (``K`` stays bitwise
    symmetric) and independent of the units. Diagonal blocks are always kept. ``sizes``:
    the block sizes of :func:`pdlin._kernels.bsr_matmul` (``block_sizes=True``), if known.
    """
    nrow = K.shape[0] // K.blocksize[0]
    ptr = np.asarray(K.indptr, dtype=np.int64)
    mod = compiled_kernels() if use_numba(K.data.size) else None
    if mod is not None:
        return _drop_zero_blocks_fused(K, mod, sizes)
    flat = K.data.reshape(K.data.shape[0], -1)
    size = np.empty(flat.shape[0])
    dsize = np.zeros(nrow)
    # fixed chunks of block rows on the threads (elementwise work: results do not depend
    # on the thread count); the kept blocks are copied chunk by chunk into their slots
    chunks = ptr_chunks(ptr, _DROP_CHUNK)

    def block_sizes(rng: tuple[int, int]) -> None:
        r0, r1 = rng
        b0, b1 = int(ptr[r0]), int(ptr[r1])
        sz = size[b0:b1]
        # max |entry| per block, column by column (3x faster than axis=)
        np.abs(flat[b0:b1, 0], out=sz)
        for c in range(1, flat.shape[1]):
            np.maximum(sz, np.abs(flat[b0:b1, c]), out=sz)
        brow = np.repeat(np.arange(r0, r1), np.diff(ptr[r0 : r1 + 1]))
        on = K.indices[b0:b1] == brow
        dsize[brow[on]] = sz[on]

    thread_map(block_sizes, chunks)
    keep = np.empty(flat.shape[0], dtype=bool)
    counts = np.empty(nrow, dtype=np.int64)
    eps2 = (16.0 * np.finfo(float).eps) ** 2

    def marks(rng: tuple[int, int]) -> None:
        r0, r1 = rng
        b0, b1 = int(ptr[r0]), int(ptr[r1])
        brow = np.repeat(np.arange(r0, r1), np.diff(ptr[r0 : r1 + 1]))
        col = K.indices[b0:b1]
        tol = dsize[brow]
        tol *= dsize[col]
        tol *= eps2
        sz = size[b0:b1]
        sz *= sz
        kp = keep[b0:b1]
        np.greater(sz, tol, out=kp)
        kp |= col == brow
        cs = np.zeros(b1 - b0 + 1, dtype=np.int64)
        np.cumsum(kp, out=cs[1:])
        counts[r0:r1] = cs[ptr[r0 + 1 : r1 + 1] - b0] - cs[ptr[r0:r1] - b0]

    thread_map(marks, chunks)
    if keep.all():
        return K
    indptr = np.zeros(nrow + 1, dtype=K.indptr.dtype)
    np.cumsum(counts, out=indptr[1:])
    total = int(indptr[-1])
    data = np.empty((total,) + K.data.shape[1:])
    indices = np.empty(total, dtype=K.indices.dtype)

    def copy(rng: tuple[int, int]) -> None:
        r0, r1 = rng
        b0, b1 = int(ptr[r0]), int(ptr[r1])
        o0, o1 = int(indptr[r0]), int(indptr[r1])
        kp = keep[b0:b1]
        np.compress(kp, K.data[b0:b1], axis=0, out=data[o0:o1])
        np.compress(kp, K.indices[b0:b1], out=indices[o0:o1])

    thread_map(copy, chunks)
    return sp.bsr_array((data, indices, indptr), shape=K.shape, blocksize=K.blocksize)


def _drop_zero_blocks_fused(
    K: sp.bsr_array, mod: Any, sizes: tuple[np.ndarray, np.ndarray] | None
) -> sp.bsr_array:
    """Return :func:`_drop_zero_blocks` from nogil numba passes over row chunks.

    Block sizes unless given, kept blocks, copy, on the threads: the same decisions and
    arrays.
    """
    nrow = K.shape[0] // K.blocksize[0]
    ptr = np.asarray(K.indptr, dtype=np.int64)
    ind = np.ascontiguousarray(K.indices)
    data = np.ascontiguousarray(K.data)
    chunks = ptr_chunks(ptr, _DROP_CHUNK)
    if sizes is None:
        size = np.empty(data.shape[0])
        dsize = np.empty(nrow)
        thread_map(lambda r: mod.block_sizes_fill(r[0], r[1], ptr, ind, data, size, dsize), chunks)
    else:
        size, dsize = sizes
    keep = np.empty(data.shape[0], dtype=bool)
    counts = np.empty(nrow, dtype=np.int64)
    eps2 = (16.0 * np.finfo(float).eps) ** 2
    thread_map(
        lambda r: mod.block_keep_fill(r[0], r[1], ptr, ind, size, dsize, eps2, keep, counts),
        chunks,
    )
    if int(counts.sum()) == data.shape[0]:
        return K
    indptr = np.zeros(nrow + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    total = int(indptr[-1])
    out_dat = np.empty((total,) + data.shape[1:])
    out_ind = np.empty(total, dtype=ind.dtype)
    thread_map(
        lambda r: mod.block_compress_fill(
            r[0], r[1], ptr, ind, data, keep, indptr, out_ind, out_dat
        ),
        chunks,
    )
    return sp.bsr_array(
        (out_dat, out_ind, indptr.astype(K.indptr.dtype)), shape=K.shape, blocksize=K.blocksize
    )


def _with_diagonal_blocks(K: sp.sparray, d: int) -> sp.bsr_array:
    """``K`` as BSR with every diagonal block stored (explicit zeros where empty).

    Energy-free shadow points may have empty rows; Dirichlet elimination writes its identity
    into stored diagonal entries.  Large matrices find the stored diagonals in row chunks
    with numba.
    """
    Kb = sp.bsr_array(K, blocksize=(d, d))
    mod = compiled_kernels() if use_numba(Kb.indices.size) else None
    if mod is None:
        return with_diagonal_blocks(Kb)
    has = np.empty(Kb.shape[0] // d, dtype=bool)
    ptr = np.asarray(Kb.indptr, dtype=np.int64)
    ind = np.ascontiguousarray(Kb.indices)
    thread_map(
        lambda r: mod.rows_with_diagonal(r[0], r[1], ptr, ind, has),
        ptr_chunks(ptr, _DROP_CHUNK),
    )
    return with_diagonal_blocks(Kb, has_diagonal=has)


def _tangent_blocks_product(
    blk: _GradientBlocks, A: np.ndarray, d: int
) -> tuple[np.ndarray, np.ndarray]:
    """Blocks of ``G`` (d² x d) and of ``A G`` (d² x d) for blockdiag ``A`` (n_gp, d², d²).

    The G block of (g, point) is ``I_d ⊗ c``: entry ``[(i, q), k] = δ_ik c_q`` (rows
    ``(i, q)`` in the row-major order of ``vec F``).
    """
    nblk = blk.col.size
    Gd = np.zeros((nblk, d, d, d))  # [b, i, q, k]
    for i in range(d):
        Gd[:, i, :, i] = blk.val
    # (A G)[b, p, k] = Σ_q A[g, p, (k, q)] c_bq
    Ar = A.reshape(-1, d * d, d, d)[blk.row]  # (nblk, d², k, q)
    AG = np.einsum("bpkq,bq->bpk", Ar, blk.val)
    return Gd.reshape(nblk, d * d, d), AG
