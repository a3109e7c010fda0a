"""Per-point calibration of every family of a cloud (grouping identical families)."""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..geometry.bonds import Bonds
from .calibrate import (
    _VOIGT,
    CalibrationResult,
    _multiplicity,
    _solve_family,
    _voigt_matrix,
    _voigt_vector,
    design_matrix,
)
from .lattices import Family

__all__ = ["calibrate_bonds", "group_families"]

log = logging.getLogger(__name__)

_STATUS_RANK = {"step1": 0, "qp": 1, "nnls-qp": 2, "negative": 3, "failed": 4, "infeasible": 5}


def _quantize(values: np.ndarray, rel: float) -> np.ndarray:
    scale = float(np.abs(values).max()) if values.size else 1.0
    return np.round(values / (max(scale, 1e-300) * rel)).astype(np.int64)


def _hash_rows(q: np.ndarray, seed: int) -> np.ndarray:
    """64-bit hash of each row of an int64 matrix (wrapping arithmetic)."""
    rng = np.random.default_rng(seed)
    h = np.zeros(q.shape[0], dtype=np.uint64)
    mult = rng.integers(1, 2**63, size=q.shape[1], dtype=np.uint64) | np.uint64(1)
    with np.errstate(over="ignore"):
        for k in range(q.shape[1]):  # loop over a few columns
            h = (h ^ q[:, k].astype(np.uint64)) * mult[k]
            h ^= h >> np.uint64(29)
    return h


def group_families(
    bonds: Bonds, rel: float = 1e-9, *, return_types: bool = False
) -> tuple[np.ndarray, ...]:
    """Group the points of a cloud by identical families.

    Two families are identical when they hold the same multiset of bonds
    ``(xi, omega, volume_j)`` (within a relative tolerance ``rel``).

    Parameters
    ----------
    bonds : Bonds
        Bonds of the whole cloud (CSR by owner point).
    rel : float
        Relative tolerance, of the largest magnitude of each quantity, under
        which two bond vectors, influence values or volumes count as equal.
    return_types : bool
        Also return the bond type of every bond and one bond per type.

    Returns
    -------
    family_of_point : (n,) ndarray of int
        Group index per point (-1 for points without bonds).
    representative : (g,) ndarray of int
        One point per group.
    order : (nb,) ndarray of int
        Bond permutation sorting each family by bond type, so position ``k``
        of two identical families holds the same bond type.
    bond_type, type_first : (nb,), (ntype,) ndarray of int
        Only with ``return_types``: type id of each bond (same ``xi``,
        ``omega``, ``volume_j``) and one bond per type.

    Raises
    ------
    InputError
        If the grouping fails its exact verification (a 128-bit hash collision).

    Examples
    --------
    >>> import pdlin
    >>> bonds = pdlin.find_bonds(pdlin.grid((5, 5)), 1.5)
    >>> fam, rep, order = group_families(bonds)
    >>> len(rep)   # 3 x 3 distinct positions per axis pair: corner, edge, interior
    9
    """
    nb = bonds.n_bonds
    n = bonds.n_points
    q = np.concatenate(
        [
            _quantize(bonds.xi, rel),
            _quantize(bonds.omega, rel)[:, None],
            _quantize(bonds.volume_j, rel)[:, None],
        ],
        axis=1,
    )
    h = _hash_rows(q, 20261121)
    _, first, btype = np.unique(h, return_index=True, return_inverse=True)
    btype = btype.ravel()
    if not np.array_equal(q, q[first[btype]]):  # hash collision: exact (slower) grouping
        _, first, btype = np.unique(q, axis=0, return_index=True, return_inverse=True)
        btype = btype.ravel()
    del q, h
    ntype = int(btype.max()) + 1 if nb else 0
    rng = np.random.default_rng(7)
    r1 = rng.integers(0, 2**63, size=ntype, dtype=np.uint64)
    r2 = rng.integers(0, 2**63, size=ntype, dtype=np.uint64)
    size = np.diff(bonds.indptr)
    nonempty = size > 0
    starts = bonds.indptr[:-1][nonempty]
    h1 = np.zeros(n, dtype=np.uint64)
    h2 = np.zeros(n, dtype=np.uint64)
    if nb:
        with np.errstate(over="ignore"):
            h1[nonempty] = np.add.reduceat(r1[btype], starts)
            h2[nonempty] = np.add.reduceat(r2[btype], starts)
    key = np.stack([h1, h2, size.astype(np.uint64)], axis=1)
    idx = np.flatnonzero(nonempty)
    _, rep_local, grp = np.unique(key[idx], axis=0, return_index=True, return_inverse=True)
    family_of_point = np.full(n, -1, dtype=np.int64)
    family_of_point[idx] = grp.ravel()
    representative = idx[rep_local]
    # sort each family by bond type and verify the grouping exactly
    bi = bonds.i  # read once (a compact Bonds computes it on every read)
    order = np.argsort(bi.astype(np.int64) * max(ntype, 1) + btype, kind="stable")
    stype = btype[order]
    pos = np.arange(nb) - bonds.indptr[bi]  # bonds.i is sorted (CSR)
    rep_of_bond = representative[family_of_point[bi]]
    if not np.array_equal(stype, stype[bonds.indptr[rep_of_bond] + pos]):
        raise InputError(  # pragma: no cover - 128-bit hash collision
            "family grouping failed verification (hash collision); please report"
        )
    if return_types:
        return family_of_point, representative, order, btype, first
    return family_of_point, representative, order


def _family_bonds(bonds: Bonds, order: np.ndarray, p: int) -> np.ndarray:
    """Bond indices of point ``p``'s family, sorted by bond type."""
    return order[bonds.indptr[p] : bonds.indptr[p + 1]]


def _calibrate_groups(
    target: np.ndarray,
    bonds: Bonds,
    todo: list[int],
    reps: np.ndarray,
    order: np.ndarray,
    thickness: float,
    opts: dict[str, Any],
) -> dict[int, CalibrationResult]:
    """Calibrate the representative family of each group in ``todo``."""
    results: dict[int, CalibrationResult] = {}
    for g in todo:  # loop over distinct families (few), vectorized within
        p = int(reps[g])
        sel = _family_bonds(bonds, order, p)
        fam = Family(
            bonds.xi[sel],
            bonds.omega[sel],
            bonds.volume_j[sel],
            thickness,
            f"family of point {p} ({sel.size} bonds)",
        )
        results[g] = _solve_family(target, fam, **opts)
    return results


def _scatter_bulk(
    bonds: Bonds, res: CalibrationResult, sel: np.ndarray, btype: np.ndarray, ntype: int
) -> np.ndarray:
    """Give every bond the complete family's value of its bond type, symmetrized."""
    lut = np.full(ntype, np.nan)
    lut[btype[sel]] = res.micromoduli
    c = lut[btype]
    missing = ~np.isfinite(c) & np.isfinite(lut).any()
    if np.any(missing):
        k = int(np.flatnonzero(missing)[0])
        raise InputError(
            f"boundary='bulk' needs every bond to occur in the complete family, got "
            f"{int(missing.sum())} bond(s) without a match (first: bond {k}, "
            f"xi = {bonds.xi[k].tolist()}); use boundary='calibrate'"
        )
    return 0.5 * (c + c[bonds.reverse])


def _scatter_interior_mean(
    bonds: Bonds,
    cf: np.ndarray,
    inner_point: np.ndarray,
    order: np.ndarray,
    pos: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Complete-family values inside, their mean on bonds touching other families.

    Returns the final micromoduli and the owners' values (``c_owner``).
    """
    c_owner = np.empty(bonds.n_bonds)
    inner_bond = inner_point[bonds.i]
    c_owner[order[inner_bond[order]]] = cf[pos[inner_bond[order]]]
    c = np.full(bonds.n_bonds, float(np.mean(cf)))
    both = inner_bond & inner_point[bonds.j]
    c[both] = c_owner[both]
    return c, c_owner


def _scatter_calibrated(
    bonds: Bonds,
    results: dict[int, CalibrationResult],
    fam_of_pt: np.ndarray,
    order: np.ndarray,
    pos: np.ndarray,
    pair_rule: str,
) -> tuple[np.ndarray, np.ndarray]:
    """Each bond takes its owner family's value, then the pair rule.

    Returns the final micromoduli and the owners' values (``c_owner``).
    """
    ng = len(results)
    offs = np.zeros(ng + 1, dtype=np.int64)
    np.cumsum([results[g].n_bonds for g in range(ng)], out=offs[1:])
    allc = np.concatenate([results[g].micromoduli for g in range(ng)])
    c_owner = np.empty(bonds.n_bonds)
    # bond order[b] sits at position pos[b] of its (sorted) family
    c_owner[order] = allc[offs[fam_of_pt[bonds.i]] + pos]
    c = 0.5 * (c_owner + c_owner[bonds.reverse]) if pair_rule == "mean" else c_owner
    return c, c_owner


def _achieved_tensors(
    target: np.ndarray,
    bonds: Bonds,
    c: np.ndarray,
    c_owner: np.ndarray,
    *,
    btype: np.ndarray,
    tfirst: np.ndarray,
    thickness: float,
    owner_differs: bool,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Per-point achieved tensors, their relative errors and the pair rule's change.

    Returns the ``(n, nv(nv+1)/2)`` upper-triangle Voigt vectors (NaN at points with a
    NaN bond), the relative Frobenius error per point and the largest relative change
    of a point's tensor between ``c_owner`` and ``c`` (NaN when none is finite).
    """
    # (n x ntype) sparse sums of c times the design column of each bond type
    # (no (21 x nb) intermediate)
    Xt = design_matrix(
        bonds.xi[tfirst],
        bonds.omega[tfirst],
        bonds.volume_j[tfirst],
        thickness,
        weighting="voigt",
    ).T
    n = bonds.n_points
    finite = np.isfinite(c)
    c0 = np.where(finite, c, 0.0)
    co = np.where(np.isfinite(c_owner), c_owner, 0.0) if owner_differs else c0
    shape = (n, tfirst.size)
    bi = bonds.i  # read once (a compact Bonds computes it on every read)
    vec = sp.csr_array((c0, (bi, btype)), shape=shape) @ Xt
    owner_vec = sp.csr_array((co, (bi, btype)), shape=shape) @ Xt
    bad_pt = np.bincount(bi, weights=(~finite).astype(float), minlength=n) > 0
    vec[bad_pt] = np.nan
    m = _multiplicity(bonds.dim)
    b = _voigt_vector(target)
    nb_ = float(np.sqrt(np.sum(m * b**2)))
    err = np.sqrt(np.sum(m * (vec - b) ** 2, axis=1)) / nb_
    change = np.sqrt(np.sum(m * (vec - owner_vec) ** 2, axis=1)) / nb_
    fin = np.isfinite(change)
    pair_change = float(change[fin].max()) if fin.any() else float("nan")
    return vec, err, pair_change


def _cloud_messages(
    fam_results: tuple[CalibrationResult, ...],
    worst: CalibrationResult,
    *,
    n_groups: int,
    family_sizes: np.ndarray,
    boundary: str,
    pair_rule: str,
    pair_change: float,
) -> list[str]:
    """Summary notes of a cloud calibration (families, failures, boundary rule)."""
    n_bad = sum(r.status in ("infeasible", "failed") for r in fam_results)
    msgs = [
        f"{n_groups} distinct families ({len(fam_results)} calibrated, sizes "
        f"{int(family_sizes.min())}..{int(family_sizes.max())}, ranks "
        f"{min(r.rank for r in fam_results)}..{max(r.rank for r in fam_results)})"
    ]
    if n_bad:
        msgs.append(
            f"{n_bad} families have no admissible solution (status {worst.status}); their bonds "
            "carry NaN; method='robust' always gives an admissible fit"
        )
    if boundary == "calibrate":
        msgs.append(
            f"pair rule {pair_rule!r}: max relative change of a point's tensor {pair_change:.3g}"
        )
    elif boundary == "bulk":
        msgs.append(
            "boundary 'bulk': every bond carries the complete family's value of its bond "
            "vector (a homogeneous material); truncated families fit the target only in part"
        )
    else:
        msgs.append(
            f"boundary 'interior-mean': bonds touching non-complete families get the mean "
            f"{float(np.mean(fam_results[0].micromoduli)):.6g}"
        )
    return msgs


def calibrate_bonds(
    target: np.ndarray,
    bonds: Bonds,
    *,
    thickness: float,
    pair_rule: str,
    boundary: str,
    **opts: Any,
) -> CalibrationResult:
    """Calibrate every distinct family of ``bonds`` (see :func:`~pdlin.calibrate_micromoduli`).

    Identical families (see :func:`group_families`) are calibrated once; the
    values are scattered to every bond by ``boundary`` and ``pair_rule``.

    Parameters
    ----------
    target : (nv, nv) ndarray
        Validated plain-Voigt target in the dimension of ``bonds``.
    bonds : Bonds
        Bonds of the whole cloud.
    thickness : float
        Out-of-plane thickness (2D).
    pair_rule : {'mean', 'owner'}
        Value of bond ``i -> j``: mean of the values calibrated at ``i`` and
        ``j``, or the owner's.
    boundary : {'calibrate', 'interior-mean', 'bulk'}
        Which families are calibrated and how truncated ones are served.
    **opts
        ``weighting``, ``lower_bound``, ``method``, ``qp_solver``, ``rcond``,
        ``zero_tol`` and ``raise_on_infeasible``, as for
        :func:`~pdlin.calibrate_micromoduli`.

    Returns
    -------
    CalibrationResult
        One micromodulus per directed bond, one achieved tensor and relative
        error per point, the per-family results in ``families``.

    Raises
    ------
    InputError
        If ``bonds`` is empty, a family has no solution and
        ``raise_on_infeasible`` is set, or with ``boundary='bulk'`` a bond
        does not occur in the complete family.
    """
    t0 = time.perf_counter()
    fam_of_pt, reps, order, btype, tfirst = group_families(bonds, return_types=True)
    ng = reps.size
    size = np.diff(bonds.indptr)
    if ng == 0:
        raise InputError("bonds must hold at least one bond, got an empty family for every point")
    if boundary in ("interior-mean", "bulk"):
        full_size = size[reps]
        counts = np.bincount(fam_of_pt[fam_of_pt >= 0], minlength=ng)
        # the complete family: largest bond count (ties: the most frequent)
        todo = [int(np.lexsort((counts, full_size))[-1])]
    else:
        todo = list(range(ng))
    results = _calibrate_groups(target, bonds, todo, reps, order, thickness, opts)
    pos = np.arange(bonds.n_bonds) - bonds.indptr[bonds.i]
    fam_results: tuple[CalibrationResult, ...]
    if boundary in ("bulk", "interior-mean"):
        g_full = todo[0]
        fam_results = (results[g_full],)
        fam_index = np.where(fam_of_pt == g_full, 0, -1)
        if boundary == "bulk":
            sel = _family_bonds(bonds, order, int(reps[g_full]))
            c = _scatter_bulk(bonds, results[g_full], sel, btype, tfirst.size)
            c_owner = c
        else:
            c, c_owner = _scatter_interior_mean(
                bonds, results[g_full].micromoduli, fam_of_pt == g_full, order, pos
            )
    else:
        c, c_owner = _scatter_calibrated(bonds, results, fam_of_pt, order, pos, pair_rule)
        fam_results = tuple(results[g] for g in range(ng))
        fam_index = fam_of_pt
    vec, err, pair_change = _achieved_tensors(
        target,
        bonds,
        c,
        c_owner,
        btype=btype,
        tfirst=tfirst,
        thickness=thickness,
        owner_differs=boundary == "calibrate",
    )
    worst = max(fam_results, key=lambda r: _STATUS_RANK.get(r.status, 9))
    msgs = _cloud_messages(
        fam_results,
        worst,
        n_groups=ng,
        family_sizes=size[reps],
        boundary=boundary,
        pair_rule=pair_rule,
        pair_change=pair_change,
    )
    c_fin = c[np.isfinite(c)]
    lb = float(opts["lower_bound"])
    cmax = float(np.abs(c_fin).max()) if c_fin.size else 1.0
    zthr = float(opts["zero_tol"]) * cmax
    return CalibrationResult(
        micromoduli=c,
        tensor=_voigt_matrix(vec, len(_VOIGT[bonds.dim])),
        target=target,
        relative_error=err,
        status=worst.status,
        message="; ".join(msgs),
        path=worst.path,
        solver_status=worst.solver_status,
        residual=max(r.residual for r in fam_results),
        kkt={
            k: max((abs(r.kkt[k]) for r in fam_results), default=0.0)
            for k in ("equality", "bound", "stationarity", "dual")
        },
        rank=min(r.rank for r in fam_results),
        n_bonds=bonds.n_bonds,
        n_columns=sum(r.n_columns for r in fam_results),
        n_directions=max(r.n_directions for r in fam_results),
        n_zero=int(np.sum(np.abs(c_fin - lb) <= zthr)),
        zero_threshold=zthr,
        lower_bound=lb,
        c_min=float(c_fin.min()) if c_fin.size else float("nan"),
        c_max=float(c_fin.max()) if c_fin.size else float("nan"),
        c_mean=float(c_fin.mean()) if c_fin.size else float("nan"),
        c_norm=float(np.linalg.norm(c_fin)),
        weighting=str(opts["weighting"]),
        method=str(opts["method"]),
        time=time.perf_counter() - t0,
        families=fam_results,
        family_of_point=fam_index,
        pair_change=pair_change if boundary == "calibrate" else 0.0,
    )
