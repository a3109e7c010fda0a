"""Small array helpers shared across pdlin's packages (Voigt index pairs, block storage, sums).

The module sits at the bottom of pdlin: at import time it depends on numpy and scipy only.
:func:`per_point_outer` reaches pdlin's thread pool (:mod:`pdlin._threads`) and the optional
numba kernels (:mod:`pdlin._kernels`) inside the call, for large inputs.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

__all__ = [
    "VOIGT_PAIRS_2D",
    "VOIGT_PAIRS_3D",
    "voigt_pairs",
    "mandel_weights",
    "n_orientations",
    "with_diagonal_blocks",
    "per_point_outer",
    "OUTER_CHUNK",
]

#: Index pairs (i, j) of the 3D Voigt components 1..6 (zero-based).
VOIGT_PAIRS_3D: tuple[tuple[int, int], ...] = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
#: Index pairs (i, j) of the 2D Voigt components 1..3 (zero-based).
VOIGT_PAIRS_2D: tuple[tuple[int, int], ...] = ((0, 0), (1, 1), (0, 1))

#: bonds per run of the threaded per-point sums of :func:`per_point_outer`
OUTER_CHUNK = 1 << 16


def voigt_pairs(dim: int) -> tuple[tuple[int, int], ...]:
    """Return the tensor index pairs ``(i, j)`` of the Voigt components in ``dim`` dimensions.

    Parameters
    ----------
    dim : {2, 3}
        Spatial dimension (any value other than 3 gives the 2D pairs).

    Returns
    -------
    tuple of (int, int)
        Zero-based pairs in pdlin's Voigt order: ``11, 22, 33, 23, 13, 12`` in 3D,
        ``11, 22, 12`` in 2D.

    Examples
    --------
    >>> voigt_pairs(2)
    ((0, 0), (1, 1), (0, 1))
    >>> len(voigt_pairs(3))
    6
    """
    return VOIGT_PAIRS_3D if dim == 3 else VOIGT_PAIRS_2D


def mandel_weights(dim: int) -> np.ndarray:
    """Return the factors that turn Voigt components into Mandel components.

    Parameters
    ----------
    dim : {2, 3}
        Spatial dimension (any value other than 3 gives the 2D weights).

    Returns
    -------
    (3,) or (6,) ndarray of float
        1 for the normal components and ``√2`` for the shear components, in the
        order of :func:`voigt_pairs`.

    Examples
    --------
    >>> mandel_weights(2).round(4).tolist()
    [1.0, 1.0, 1.4142]
    >>> mandel_weights(3).shape
    (6,)
    """
    n_shear = 3 if dim == 3 else 1
    return np.concatenate([np.ones(dim), np.full(n_shear, np.sqrt(2.0))])


def n_orientations(orientation: Any, dim: int) -> int | None:
    """Return how many points a crystal-orientation argument describes.

    Parameters
    ----------
    orientation : float, array_like
        In 2D an angle or ``(n,)`` angles; in 3D one rotation ``(3, 3)``, one set of
        Euler angles ``(3,)``, or ``n`` of either ``(n, 3, 3)`` / ``(n, 3)``.
    dim : {2, 3}
        Spatial dimension.

    Returns
    -------
    int or None
        The number of points ``n``, or None when the argument is one orientation that
        broadcasts to every point.

    Examples
    --------
    >>> n_orientations(0.3, 2) is None, n_orientations([0.1, 0.2], 2)
    (True, 2)
    >>> n_orientations(np.eye(3), 3) is None, n_orientations(np.zeros((5, 3)), 3)
    (True, 5)
    """
    o = np.asarray(orientation)
    if dim == 2:
        return None if o.ndim == 0 else int(o.shape[0])
    if o.ndim == 0 or o.shape in ((3, 3), (3,)):
        return None
    return int(o.shape[0])


def with_diagonal_blocks(
    K: sp.sparray, blocksize: int | None = None, *, has_diagonal: np.ndarray | None = None
) -> sp.bsr_array:
    """Return ``K`` as BSR with every diagonal block stored (zero blocks where none is).

    Dirichlet elimination writes its scaled identity into the stored diagonal blocks, so
    they must exist even when they are zero (an energy-free shadow point, a point on all
    symmetry planes).

    Parameters
    ----------
    K : sparse array, shape (n*r, n*r)
        The matrix; converted to BSR with blocks ``(r, r)``.
    blocksize : int, optional
        ``r``; default: ``K``'s own block size (``K`` must then be BSR).
    has_diagonal : (n,) ndarray of bool, optional
        Which block rows already store their diagonal block, when the caller has
        computed it (e.g. in parallel); default: computed here.

    Returns
    -------
    scipy.sparse.bsr_array
        The BSR form of ``K`` when every diagonal block is stored, else a new BSR array
        with the same blocks (duplicates summed) plus zero diagonal blocks, in sorted
        block order.

    Examples
    --------
    >>> import scipy.sparse as sp
    >>> K = sp.bsr_array(np.array([[0.0, 0.0, 1.0, 2.0], [0.0, 0.0, 3.0, 4.0],
    ...                           [1.0, 3.0, 5.0, 0.0], [2.0, 4.0, 0.0, 5.0]]), blocksize=(2, 2))
    >>> K.eliminate_zeros(); K.nnz
    12
    >>> Kd = with_diagonal_blocks(K)
    >>> Kd.nnz, Kd.indices.tolist(), bool((Kd.toarray() == K.toarray()).all())
    (16, [0, 1, 0, 1], True)
    """
    r = K.blocksize[0] if blocksize is None else int(blocksize)
    Kb = sp.bsr_array(K, blocksize=(r, r))
    nbr = Kb.shape[0] // r
    brow = np.repeat(np.arange(nbr), np.diff(Kb.indptr))
    if has_diagonal is None:
        has = np.zeros(nbr, dtype=bool)
        has[brow[Kb.indices == brow]] = True
    else:
        has = has_diagonal
    missing = np.flatnonzero(~has)
    if missing.size == 0:
        return Kb
    if not Kb.has_canonical_format:  # sorted blocks, duplicates summed (on a copy)
        Kb = Kb.copy()
        Kb.sum_duplicates()
        brow = np.repeat(np.arange(nbr), np.diff(Kb.indptr))
    rows = np.concatenate([brow, missing])
    cols = np.concatenate([Kb.indices, missing])
    data = np.concatenate([Kb.data, np.zeros((missing.size, r, r))])
    order = np.lexsort((cols, rows))
    indptr = np.zeros(nbr + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=nbr), out=indptr[1:])
    return sp.bsr_array((data[order], cols[order], indptr), shape=Kb.shape, blocksize=(r, r))


def per_point_outer(
    owner: np.ndarray,
    n: int,
    w: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    runs: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Return the per-owner sums of weighted outer products of bond vectors.

    ``out[p] = Σ_{e: owner_e = p} w_e a_e ⊗ b_e``: each entry is one
    ``np.bincount`` over the bonds.  When the bonds split into consecutive runs
    whose owners do not interleave (sorted owners, as in :class:`pdlin.Bonds`, or
    the two half families of a point's stress points), runs of about
    :data:`OUTER_CHUNK` bonds are summed on pdlin's threads, each owner's sum over
    the same bonds in the same order as one global ``np.bincount``: the same bits
    (with numba, each run is one ``nogil`` pass of that arithmetic, since
    ``np.bincount`` holds the GIL and its chunks would run one at a time).

    Parameters
    ----------
    owner : (m,) ndarray of int
        Owner index in ``[0, n)`` of every bond.
    n : int
        Number of owners (rows of the result).
    w : (m,) ndarray of float
        Bond weights.
    a, b : (m, d) ndarray of float
        The vectors of the outer products (may be the same array).
    runs : tuple of two ndarray of int, optional
        ``(bptr, optr)``: the bonds ``bptr[k]:bptr[k+1]`` have the owners
        ``optr[k]:optr[k+1]`` (e.g. the gradient points of point ``k``), so the runs are
        known without a pass over the owners.

    Returns
    -------
    (n, d, d) ndarray of float
        The sums (zero for owners without bonds).

    Examples
    --------
    >>> xi = np.array([[1.0, 0.0], [0.0, 2.0], [1.0, 1.0]])
    >>> per_point_outer(np.array([0, 0, 1]), 2, np.ones(3), xi, xi).tolist()
    [[[1.0, 0.0], [0.0, 4.0]], [[1.0, 1.0], [1.0, 1.0]]]
    """
    d = a.shape[1]
    nb = owner.size
    chunk_size = OUTER_CHUNK

    def fill(out: np.ndarray, p0: int, p1: int, b0: int, b1: int) -> None:
        own = owner[b0:b1] - p0 if p0 else owner[b0:b1]
        for r in range(d):
            wa = w[b0:b1] * a[b0:b1, r]
            for c in range(d):
                out[p0:p1, r, c] = np.bincount(own, weights=wa * b[b0:b1, c], minlength=p1 - p0)

    if nb < 2 * chunk_size:
        out = np.empty((n, d, d))
        fill(out, 0, n, 0, nb)
        return out
    from ._kernels import compiled_kernels

    mod = compiled_kernels()
    if mod is not None:  # one nogil pass per run (np.bincount holds the GIL): same sums
        kern = mod.outer_sums_fill
        own_c = np.ascontiguousarray(owner, dtype=np.int64)
        w_c = np.ascontiguousarray(w, dtype=np.float64)
        a_c = np.ascontiguousarray(a, dtype=np.float64)
        b_c = a_c if b is a else np.ascontiguousarray(b, dtype=np.float64)

        def fill(out: np.ndarray, p0: int, p1: int, b0: int, b1: int) -> None:
            kern(p0, p1, b0, b1, own_c, w_c, a_c, b_c, out)

    targets = np.arange(chunk_size, nb, chunk_size)
    if runs is not None:
        from ._threads import ptr_chunks

        bptr, optr = runs
        ends = np.array([e for _, e in ptr_chunks(bptr, chunk_size)][:-1], dtype=np.int64)
        cuts, first = bptr[ends], optr[ends]
    elif bool(np.all(owner[1:] >= owner[:-1])):  # sorted: cut where an owner's run starts
        cuts = np.unique(np.searchsorted(owner, owner[targets], side="left"))
        cuts = cuts[cuts > 0]
        first = owner[cuts]
    else:
        # a cut before bond e is clean when every owner before it is below every one after
        pre_max = np.maximum.accumulate(owner)
        suf_min = np.minimum.accumulate(owner[::-1])[::-1]
        clean = np.flatnonzero(pre_max[:-1] < suf_min[1:]) + 1
        pick = np.searchsorted(clean, targets)
        cuts = np.unique(clean[pick[pick < clean.size]])
        first = suf_min[cuts]
    if cuts.size == 0:
        out = np.empty((n, d, d))
        fill(out, 0, n, 0, nb)
        return out
    from ._threads import thread_map

    b_edges = np.concatenate([[0], cuts, [nb]])
    p_edges = np.concatenate([[0], first, [n]])  # owners of run k: [p_k, p_{k+1})
    out = np.empty((n, d, d))
    spans = [
        (int(p_edges[k]), int(p_edges[k + 1]), int(b_edges[k]), int(b_edges[k + 1]))
        for k in range(b_edges.size - 1)
    ]

    def chunk(span: tuple[int, int, int, int]) -> None:
        fill(out, *span)

    thread_map(chunk, spans)
    return out
