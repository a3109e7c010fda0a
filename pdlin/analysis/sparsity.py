"""Sparsity studies of stiffness matrices: pattern, bandwidth, fill-in, memory, conditioning.

:func:`sparsity_report` describes a stiffness matrix ``K`` either from the
assembled matrix or, without assembling it, from a model, a cloud and its
bonds (the block pattern of a model with ``coupling_range = r`` is the
``r``-th boolean power of the bond graph plus the diagonal).  Quantities that
need the numerical entries (symmetry, diagonal dominance, conditioning) are
computed when ``K`` is given or when ``numeric=True`` asks for assembly.
:func:`spy_pattern` gives the pattern in an ordering, which
:func:`pdlin.plotting.plot_spy` draws (needs the ``plotting`` extra).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import reverse_cuthill_mckee

from ..errors import InputError, InputTypeError, NonFiniteError, ShapeError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud

__all__ = [
    "SparsityReport",
    "sparsity_report",
    "coupling_pattern",
    "rcm_permutation",
    "spy_pattern",
    "FILL_ORDERINGS",
]

log = logging.getLogger(__name__)

#: orderings compared by the fill-in measurement (SuperLU ``permc_spec`` or RCM + natural)
FILL_ORDERINGS = ("natural", "colamd", "mmd_at_plus_a", "rcm")

_PERMC = {"natural": "NATURAL", "colamd": "COLAMD", "mmd_at_plus_a": "MMD_AT_PLUS_A"}

#: entries of the coupling-distance computation handled per chunk (bounds temporary memory)
_CHUNK = 2_000_000


@dataclass(frozen=True)
class SparsityReport:
    """Sparsity, memory and conditioning figures of a stiffness matrix.

    All counts refer to the *stored* pattern: an assembled BSR ``K`` keeps
    every entry of its ``dim x dim`` blocks, including exact zeros (bonds
    along a lattice axis give blocks with zero off-diagonal entries), and
    the pattern built from the bonds is the same full-block pattern.
    ``nnz_numeric`` counts the numerically non-zero entries when ``K`` is
    known.

    Attributes
    ----------
    source : str
        ``'matrix'`` or ``'model:<ModelName>'`` (pattern from the bonds).
    n : int
        Rows (DOFs) of ``K``.
    n_points : int
        Block rows (points), ``n // block_size``.
    block_size : int
        DOFs per point (``dim``).
    coupling_range : int or None
        Hops of the bond graph the model couples (1 bond-based, 2
        state-based); None for a bare matrix.
    nnz, n_blocks : int
        Stored entries and stored ``block_size x block_size`` blocks.
    nnz_numeric : int or None
        Entries that are numerically non-zero (needs ``K``).
    nnz_per_row_min, nnz_per_row_mean, nnz_per_row_max : int, float, int
        Stored entries per DOF row.
    blocks_per_row_min, blocks_per_row_mean, blocks_per_row_max : int, float, int
        Points coupled to each point (its block row), itself included.
    n_bonds : int or None
        Directed bonds (when bonds are known).
    coupling_distance : float or None
        Largest distance between two coupled points (needs the points).
    coupling_range_horizons : float or None
        ``coupling_distance / max(horizon)``: about 1 for bond-based, 2 for
        state-based models (needs points and horizon).
    bandwidth, profile : int
        Half-bandwidth ``max |r - c|`` and envelope (profile)
        ``sum_r (r - f_r)``, ``f_r`` the first column of row ``r`` in the
        symmetrized pattern, in DOFs and the given ordering.
    bandwidth_rcm, profile_rcm : int
        The same after reverse Cuthill-McKee of the point graph, applied
        blockwise to the DOFs.
    fill_natural, fill_colamd, fill_mmd_at_plus_a, fill_rcm : int or None
        ``nnz(L) + nnz(U)`` of SuperLU (both diagonals counted) with the
        natural, COLAMD and minimum-degree (``A + Aᵀ``) column orderings
        and with the natural ordering after RCM; None when skipped.
    fill_skipped : str or None
        Why the fill-in was not measured.
    memory_csr_bytes, memory_bsr_bytes : int
        Bytes of ``K`` as CSR and as BSR (values, indices, row pointer).
    bytes_per_nnz_csr, bytes_per_nnz_bsr : float or None
        Memory per stored entry (None for an empty matrix).
    bytes_per_bond_csr, bytes_per_bond_bsr : float or None
        Memory per directed bond.
    symmetry : float or None
        ``||K - Kᵀ||_F / ||K||_F``.
    diag_dominant_fraction : float or None
        Fraction of rows with ``|a_rr| >= sum_{c != r} |a_rc|``.
    diag_dominance_min_ratio : float or None
        ``min_r |a_rr| / sum_{c != r} |a_rc|`` over rows with off-diagonal
        entries.
    n_fixed : int
        DOFs eliminated (Dirichlet) before fill-in and conditioning.
    condition_2 : float or None
        2-norm condition number from the dense spectrum (small cases):
        ``s_max / s_min`` over the singular values above the zero tolerance,
        i.e. on the non-zero-energy (non-rigid) subspace for a free-floating
        ``K``; of ``K_ff`` when DOFs are fixed.
    condition_1_est : float or None
        ``onenormest(K_ff) * onenormest(K_ff⁻¹)`` (1-norm estimate through a
        sparse LU), only with fixed DOFs.
    zero_modes : int or None
        Singular values ``<= zero_tol * s_max`` (zero-energy modes, rigid
        ones included) from the dense spectrum (of ``K_ff`` when DOFs are fixed).
    nnz_free : int or None
        Stored entries of ``K_ff``, the constrained system's matrix (rows and
        columns of the free DOFs); None without ``fixed_dofs``.
    nnz_per_row_free_min, nnz_per_row_free_mean, nnz_per_row_free_max : int, float, int or None
        Stored entries per row of ``K_ff``.
    notes : tuple of str
        What was skipped and why.
    timings : dict of str to float
        Seconds per stage (not compared by ``==``).
    """

    source: str
    n: int
    n_points: int
    block_size: int
    coupling_range: int | None
    nnz: int
    n_blocks: int
    nnz_numeric: int | None
    nnz_per_row_min: int
    nnz_per_row_mean: float
    nnz_per_row_max: int
    blocks_per_row_min: int
    blocks_per_row_mean: float
    blocks_per_row_max: int
    n_bonds: int | None
    coupling_distance: float | None
    coupling_range_horizons: float | None
    bandwidth: int
    profile: int
    bandwidth_rcm: int
    profile_rcm: int
    fill_natural: int | None
    fill_colamd: int | None
    fill_mmd_at_plus_a: int | None
    fill_rcm: int | None
    fill_skipped: str | None
    memory_csr_bytes: int
    memory_bsr_bytes: int
    bytes_per_nnz_csr: float | None
    bytes_per_nnz_bsr: float | None
    bytes_per_bond_csr: float | None
    bytes_per_bond_bsr: float | None
    symmetry: float | None
    diag_dominant_fraction: float | None
    diag_dominance_min_ratio: float | None
    n_fixed: int
    condition_2: float | None
    condition_1_est: float | None
    zero_modes: int | None
    nnz_free: int | None = None
    nnz_per_row_free_min: int | None = None
    nnz_per_row_free_mean: float | None = None
    nnz_per_row_free_max: int | None = None
    notes: tuple[str, ...] = ()
    timings: Mapping[str, float] = field(default_factory=dict, compare=False)

    #: fields that depend only on the pattern (equal for a matrix and its model)
    PATTERN_FIELDS = (
        "n",
        "n_points",
        "block_size",
        "nnz",
        "n_blocks",
        "nnz_per_row_min",
        "nnz_per_row_mean",
        "nnz_per_row_max",
        "blocks_per_row_min",
        "blocks_per_row_mean",
        "blocks_per_row_max",
        "coupling_distance",
        "coupling_range_horizons",
        "bandwidth",
        "profile",
        "bandwidth_rcm",
        "profile_rcm",
        "fill_natural",
        "fill_colamd",
        "fill_mmd_at_plus_a",
        "fill_rcm",
        "memory_csr_bytes",
        "memory_bsr_bytes",
        "nnz_free",
        "nnz_per_row_free_min",
        "nnz_per_row_free_mean",
        "nnz_per_row_free_max",
    )

    def pattern_dict(self) -> dict[str, Any]:
        """Return the pattern-only quantities (see ``PATTERN_FIELDS``) as a dict.

        Returns
        -------
        dict of str to int, float or None
            Field name -> value for each name of ``PATTERN_FIELDS`` (equal for a matrix
            and the model it was assembled from).
        """
        return {k: getattr(self, k) for k in self.PATTERN_FIELDS}

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-serializable dict of every field (``notes`` as a list).

        Returns
        -------
        dict of str to object
            Field name -> value; ``notes`` a list of str, ``timings`` a dict.

        Examples
        --------
        >>> import json, pdlin
        >>> cloud = pdlin.grid((8,))
        >>> bonds = pdlin.find_bonds(cloud, 2.0)
        >>> r = sparsity_report(model=pdlin.BondBased(E=1.0), cloud=cloud, bonds=bonds)
        >>> d = json.loads(json.dumps(r.to_dict()))
        >>> d["nnz"], SparsityReport.from_dict(d) == r
        (34, True)
        """
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["notes"] = list(self.notes)
        out["timings"] = dict(self.timings)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SparsityReport:
        """Rebuild a report from :meth:`to_dict` output (e.g. read back from JSON).

        Parameters
        ----------
        data : mapping of str to object
            Field name -> value, as written by :meth:`to_dict`; missing optional fields
            take their defaults.

        Returns
        -------
        SparsityReport
            The report (equal to the one that was written, ``timings`` aside).

        Raises
        ------
        InputError
            ``data`` holds a key that is not a field.
        """
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise InputError(
                f"data must hold SparsityReport fields only, got unknown keys {unknown}"
            )
        kw = dict(data)
        kw["notes"] = tuple(kw.get("notes", ()))
        kw["timings"] = dict(kw.get("timings", {}))
        return cls(**kw)

    def __str__(self) -> str:
        """Format the report as a two-column table of quantities and values."""

        def num(v: Any) -> str:
            if v is None:
                return "-"
            if isinstance(v, bool):
                return str(v)
            if isinstance(v, int):
                return f"{v:,}"
            if isinstance(v, float):
                return f"{v:.4g}"
            return str(v)

        def fill(v: int | None) -> str:
            if v is None:
                return "-"
            return f"{v:,} ({v / self.nnz:.2f} x nnz)" if self.nnz else f"{v:,}"

        rows: list[tuple[str, str]] = [
            ("source", self.source),
            (
                "rows (DOFs) / points / block size",
                f"{self.n:,} / {self.n_points:,} / {self.block_size}",
            ),
            ("coupling range (hops)", num(self.coupling_range)),
            ("nnz stored / numeric", f"{self.nnz:,} / {num(self.nnz_numeric)}"),
            ("blocks", num(self.n_blocks)),
            (
                "nnz per row min / mean / max",
                f"{self.nnz_per_row_min} / {self.nnz_per_row_mean:.2f} / {self.nnz_per_row_max}",
            ),
            (
                "points coupled per row min / mean / max",
                f"{self.blocks_per_row_min} / {self.blocks_per_row_mean:.2f} / "
                f"{self.blocks_per_row_max}",
            ),
            ("directed bonds", num(self.n_bonds)),
            (
                "coupling distance / in horizons",
                f"{num(self.coupling_distance)} / {num(self.coupling_range_horizons)}",
            ),
            ("bandwidth natural / RCM", f"{self.bandwidth:,} / {self.bandwidth_rcm:,}"),
            ("profile natural / RCM", f"{self.profile:,} / {self.profile_rcm:,}"),
            ("fill nnz(L+U) natural", fill(self.fill_natural)),
            ("fill nnz(L+U) COLAMD", fill(self.fill_colamd)),
            ("fill nnz(L+U) MMD(A+A^T)", fill(self.fill_mmd_at_plus_a)),
            ("fill nnz(L+U) RCM + natural", fill(self.fill_rcm)),
            (
                "memory CSR bytes (per nnz, per bond)",
                f"{self.memory_csr_bytes:,} "
                f"({num(self.bytes_per_nnz_csr)}, {num(self.bytes_per_bond_csr)})",
            ),
            (
                "memory BSR bytes (per nnz, per bond)",
                f"{self.memory_bsr_bytes:,} "
                f"({num(self.bytes_per_nnz_bsr)}, {num(self.bytes_per_bond_bsr)})",
            ),
            ("symmetry ||K-K^T||_F/||K||_F", num(self.symmetry)),
            (
                "diag. dominant rows (fraction, min ratio)",
                f"{num(self.diag_dominant_fraction)}, {num(self.diag_dominance_min_ratio)}",
            ),
            ("fixed DOFs", num(self.n_fixed)),
        ]
        ff = " (K_ff)" if self.n_fixed else ""
        if self.nnz_free is not None:
            rows.append(
                (
                    "free DOFs (K_ff) nnz / per row min / mean / max",
                    f"{self.n - self.n_fixed:,}: {self.nnz_free:,} / "
                    f"{num(self.nnz_per_row_free_min)} / {num(self.nnz_per_row_free_mean)} / "
                    f"{num(self.nnz_per_row_free_max)}",
                )
            )
        rows += [
            (f"condition (2-norm, dense){ff}", num(self.condition_2)),
            (f"condition (1-norm estimate){ff}", num(self.condition_1_est)),
            (f"zero-energy modes{ff}", num(self.zero_modes)),
        ]
        if self.fill_skipped:
            rows.append(("fill skipped", self.fill_skipped))
        rows += [("note", s) for s in self.notes]
        width = max(len(k) for k, _ in rows)
        lines = [f"{'quantity':<{width}}  value", f"{'-' * width}  {'-' * 24}"]
        lines += [f"{k:<{width}}  {v}" for k, v in rows]
        return "\n".join(lines)


# -- patterns -------------------------------------------------------------------


def coupling_pattern(bonds: Bonds, coupling_range: int = 1) -> sp.csr_array:
    """Boolean point pattern of ``K`` from the bonds, without assembling ``K``.

    ``P = (A + I) ** coupling_range`` with ``A`` the bond adjacency, computed
    with boolean sparse products (one hop per product).  ``coupling_range =
    1`` is the bond-based pattern (bonds plus diagonal), ``2`` the
    state-based / correspondence pattern (points sharing a neighbor).

    Parameters
    ----------
    bonds : Bonds
    coupling_range : int
        Number of bond hops coupled by the model (>= 1).

    Returns
    -------
    (n_points, n_points) scipy.sparse.csr_array of bool
        Sorted indices, diagonal included.

    Examples
    --------
    >>> import pdlin
    >>> bonds = pdlin.find_bonds(pdlin.grid((15, 15)), 3.01)
    >>> P = coupling_pattern(bonds, 2)
    >>> int(P[[112]].nnz)   # centre point: the 105 points within two bond hops of it
    105
    """
    if not isinstance(bonds, Bonds):
        raise InputTypeError(f"bonds must be pdlin Bonds, got {type(bonds).__name__}")
    r = _hops(coupling_range, "coupling_range")
    n = bonds.n_points
    A = bonds.adjacency()
    A = sp.csr_array(A + sp.eye_array(n, dtype=bool, format="csr"), dtype=bool)
    P = A
    for _ in range(r - 1):  # loop over hops, each a vectorized sparse product
        P = sp.csr_array(P @ A, dtype=bool)
    P.sum_duplicates()
    P.sort_indices()
    return P


def _hops(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InputError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def rcm_permutation(pattern: Any, block_size: int = 1) -> np.ndarray:
    """Reverse Cuthill-McKee permutation of a point pattern, expanded to DOFs.

    Parameters
    ----------
    pattern : (n_points, n_points) sparse array
        Point (block) pattern; it is symmetrized before ordering.
    block_size : int
        DOFs per point; the returned permutation keeps each point's DOFs
        together (``dof = block_size * i + k``).

    Returns
    -------
    (n_points * block_size,) ndarray of int
        ``perm[new] = old``: ``K[perm][:, perm]`` is the reordered matrix.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> P = sp.csr_array(np.array([[1, 0, 1], [0, 1, 0], [1, 0, 1]]))
    >>> rcm_permutation(P, 2).reshape(-1, 2)[:, 0] % 2
    array([0, 0, 0])
    """
    bs = _hops(block_size, "block_size")
    P = sp.csr_array(pattern, dtype=bool)
    if P.shape[0] != P.shape[1]:
        raise ShapeError(f"pattern must be square, got shape {P.shape}")
    S = sp.csr_array(P + P.T, dtype=bool)
    perm = np.asarray(reverse_cuthill_mckee(S, symmetric_mode=True), dtype=np.int64)
    if bs == 1:
        return perm
    return (bs * perm[:, None] + np.arange(bs)[None, :]).ravel()


def _envelope(
    rows: np.ndarray, cols: np.ndarray, n: int, q: np.ndarray | None, d: int
) -> tuple[int, int]:
    """Half-bandwidth and profile (DOFs) of a pattern given as entries of full d x d blocks.

    ``q[old] = new`` relabels the block indices.  Profile of the symmetrized
    pattern: ``sum_r (r - f_r)``, ``f_r = min(r, first column of row r)``.
    """
    a = rows if q is None else q[rows]
    b = cols if q is None else q[cols]
    hi = np.maximum(a, b)
    lo = np.minimum(a, b)
    first = np.arange(n, dtype=np.int64)
    if hi.size:
        np.minimum.at(first, hi, lo)
    width = int(np.max(hi - lo)) if hi.size else 0
    env = int(np.sum(np.arange(n, dtype=np.int64) - first))
    return d * width + d - 1, d * d * env + n * d * (d - 1) // 2


def _index_bytes(maxval: int) -> int:
    """Index itemsize scipy uses for arrays holding values up to ``maxval``."""
    return 4 if maxval <= np.iinfo(np.int32).max else 8


def _coo_chunks_max_dist(points: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> float:
    best = 0.0
    for s in range(0, rows.size, _CHUNK):  # bounded-memory chunks, vectorized inside
        r = rows[s : s + _CHUNK]
        c = cols[s : s + _CHUNK]
        dx = points[c] - points[r]
        if dx.size:
            best = max(best, float(np.sqrt(np.max(np.einsum("ij,ij->i", dx, dx)))))
    return best


def _fill(pattern: sp.csr_array, free: np.ndarray | None, perm_rcm: np.ndarray) -> dict[str, int]:
    """SuperLU ``nnz(L) + nnz(U)`` of a DOF pattern for each ordering.

    The values are an M-matrix surrogate with the pattern of ``K``
    (off-diagonal -1, diagonal row degree + 1): strictly diagonally dominant,
    so diagonal pivoting never fails, and every elimination update is
    strictly negative, so no entry cancels -- the counts are the structural
    fill of the pattern, independent of the values of ``K``.
    """
    n = pattern.shape[0]
    S = sp.csr_array(pattern, dtype=np.float64, copy=True)
    S.sum_duplicates()
    count = np.diff(S.indptr)
    rows = np.repeat(np.arange(n, dtype=np.int64), count)
    on_diag = rows == S.indices  # every row stores its diagonal (added by the caller)
    S.data[:] = -1.0
    S.data[on_diag] = count[rows[on_diag]].astype(np.float64)  # (count - 1) + 1
    out: dict[str, int] = {}
    keep = np.arange(n) if free is None else np.flatnonzero(free)
    for name in ("natural", "colamd", "mmd_at_plus_a", "rcm"):
        if name == "rcm":
            order = perm_rcm if free is None else perm_rcm[free[perm_rcm]]
            M = S[order][:, order]
            spec = "NATURAL"
        else:
            M = S if free is None else S[keep][:, keep]
            spec = _PERMC[name]
        lu = spla.splu(
            sp.csc_array(M), permc_spec=spec, diag_pivot_thresh=0.0, options={"SymmetricMode": True}
        )
        out[name] = int(lu.L.nnz + lu.U.nnz)
    return out


# -- argument handling -------------------------------------------------------


def _free_mask(fixed_dofs: Any, n: int) -> np.ndarray | None:
    if fixed_dofs is None:
        return None
    arr = np.asarray(fixed_dofs)
    free = np.ones(n, dtype=bool)
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise ShapeError(f"fixed_dofs boolean mask must have shape ({n},), got {arr.shape}")
        free[arr] = False
        return free
    if arr.size == 0:
        return free
    if not np.issubdtype(arr.dtype, np.integer):
        raise InputError(
            f"fixed_dofs must hold integer DOF indices or a mask, got dtype {arr.dtype}"
        )
    arr = arr.ravel()
    if arr.min() < 0 or arr.max() >= n:
        raise InputError(
            f"fixed_dofs must hold DOF indices in [0, {n - 1}], "
            f"got range [{arr.min()}, {arr.max()}]"
        )
    free[arr] = False
    return free


def _as_sparse(K: Any) -> sp.sparray:
    if sp.issparse(K):
        data = np.asarray(K.data)
        if data.dtype.kind in "fc" and not np.all(np.isfinite(data)):
            raise NonFiniteError("K must be finite, got NaN or inf entries")
        return K
    if isinstance(K, np.ndarray):
        if K.ndim != 2:
            raise ShapeError(f"K must be a 2-D matrix, got an array of shape {K.shape}")
        if K.dtype.kind in "fc" and not np.all(np.isfinite(K)):
            raise NonFiniteError("K must be finite, got NaN or inf entries")
        return sp.csr_array(K)
    raise InputTypeError(f"K must be a scipy sparse array or a 2-D ndarray, got {type(K).__name__}")


def _max_horizon(horizon: Any, n_points: int) -> float | None:
    if horizon is None:
        return None
    h = np.asarray(horizon, dtype=float)
    if h.ndim > 1 or (h.ndim == 1 and h.shape != (n_points,)):
        raise ShapeError(f"horizon must be a scalar or have shape ({n_points},), got {h.shape}")
    if h.size == 0 or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise InputError(f"horizon must be finite and > 0, got {h if h.ndim == 0 else h.min()}")
    return float(np.max(h))


# -- the report ------------------------------------------------------------------


def sparsity_report(
    K: Any = None,
    *,
    model: Any = None,
    cloud: PointCloud | None = None,
    bonds: Bonds | None = None,
    points: Any = None,
    horizon: Any = None,
    block_size: int | None = None,
    fixed_dofs: Any = None,
    numeric: bool = False,
    fill_limit: int = 10_000,
    eig_limit: int = 2_000,
    cond_limit: int = 20_000,
    zero_tol: float = 1e-10,
) -> SparsityReport:
    """Sparsity, memory, fill-in and conditioning report of a stiffness matrix.

    Two calling forms:

    * ``sparsity_report(K, points=cloud.points, horizon=delta)``: from an
      assembled matrix.  ``points``/``horizon`` (or ``cloud``/``bonds``) add
      the coupling distance; ``bonds`` adds the per-bond memory.
    * ``sparsity_report(model=model, cloud=cloud, bonds=bonds)``: from the
      model and its bonds, **without assembling** ``K`` for the pattern
      figures: the point pattern is ``(A + I) ** model.coupling_range`` of
      the bond graph ``A`` (bonds plus diagonal for bond-based models, the
      bond graph squared for state-based ones), each entry a full
      ``dim x dim`` block.  ``numeric=True`` assembles ``K`` for the
      quantities that need its entries.

    Parameters
    ----------
    K : (n, n) sparse array or ndarray, optional
        Assembled stiffness.  Mutually exclusive with ``model``.
    model : pdlin model, optional
        Any object with ``coupling_range`` (int) and ``stiffness(cloud,
        bonds)``; needs ``cloud`` and ``bonds``.
    cloud : PointCloud, optional
        Points (and default horizon) of ``K``; required with ``model``.
    bonds : Bonds, optional
        Bonds of the cloud; required with ``model``.  With ``K`` they supply
        the number of bonds and the horizon.
    points : (n_points, dim) array_like, optional
        Point coordinates when no cloud is given (``K`` form only).
    horizon : float or (n_points,) array_like, optional
        Horizon(s); defaults to ``bonds.horizon``, then ``cloud.horizon``.
    block_size : int, optional
        DOFs per point; defaults to ``K.blocksize`` for BSR, the points'
        dimension, else 1.
    fixed_dofs : array_like of int or (n,) bool mask, optional
        Dirichlet DOFs eliminated before fill-in and conditioning (the
        figures then describe ``K_ff``); ``nnz_free`` and
        ``nnz_per_row_free_*`` give ``K_ff``'s pattern beside ``K``'s.
    numeric : bool
        With ``model``: assemble ``K`` and report the numerical quantities
        (symmetry, diagonal dominance, conditioning, ``nnz_numeric``).
        Always on in the ``K`` form.
    fill_limit : int
        Largest number of (free) DOFs for which SuperLU factorizations are
        run to measure fill-in; above it ``fill_*`` are None and
        ``fill_skipped`` says why.  0 skips them.
    eig_limit : int
        Largest number of (free) DOFs for the dense spectrum
        (``condition_2``, ``zero_modes``).
    cond_limit : int
        Largest number of free DOFs for the 1-norm condition estimate (one
        sparse LU plus a few solves; needs ``fixed_dofs``).
    zero_tol : float
        Relative tolerance below which a singular value counts as a
        zero-energy mode.

    Returns
    -------
    SparsityReport
        The pattern, memory, fill-in and (with ``K`` or ``numeric=True``) numerical
        figures; ``notes`` says what was skipped and why.

    Raises
    ------
    InputError, InputTypeError, ShapeError
        Neither or both of ``K`` and ``model``; arguments of the wrong type, shape or
        range (each message names the argument).
    NonFiniteError
        ``K`` holds NaN or inf entries.

    Notes
    -----
    *Fill-in* is the structural fill of the stored pattern: SuperLU
    (diagonal pivoting, symmetric mode) factors an M-matrix with the pattern
    of ``K`` or ``K_ff``, so the counts depend on the pattern only and agree
    between the two calling forms.  Explicit zeros inside blocks count as
    entries, as they do when the BSR ``K`` is handed to a solver.

    *Conditioning.*  A free-floating ``K`` is singular: its dense spectrum
    (``n <= eig_limit``) gives the number of zero-energy modes (rigid modes
    and any spurious ones) and ``condition_2`` on the remaining non-zero
    spectrum.  With ``fixed_dofs``, ``K_ff`` is used: ``condition_2`` from
    its dense spectrum and ``condition_1_est`` from
    :func:`scipy.sparse.linalg.onenormest` of ``K_ff`` and of its inverse
    (through ``splu``).

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((10, 10))
    >>> bonds = pdlin.find_bonds(cloud, 3.015)
    >>> model = pdlin.BondBased(E=1.0)
    >>> r = sparsity_report(model=model, cloud=cloud, bonds=bonds)
    >>> r.blocks_per_row_max, r.nnz_per_row_max      # 28 bonds + itself, 2 DOFs
    (29, 58)
    >>> r.coupling_range_horizons <= 1.0
    True
    >>> from pdlin.operators import assemble_stiffness
    >>> K = assemble_stiffness(model, cloud, bonds)
    >>> rk = sparsity_report(K, points=cloud.points, horizon=3.015)
    >>> rk.pattern_dict() == r.pattern_dict(), rk.symmetry
    (True, 0.0)
    """
    timings: dict[str, float] = {}
    notes: list[str] = []
    t0 = time.perf_counter()
    zt, pts = _check_arguments(
        K, model, cloud, bonds, points, (fill_limit, eig_limit, cond_limit), zero_tol
    )
    if model is not None:
        pat = _model_pattern(model, cloud, bonds, block_size, numeric, timings)
    else:
        pat = _matrix_pattern(K, pts, block_size)
    timings["pattern"] = time.perf_counter() - t0

    free = _free_mask(fixed_dofs, pat.n)
    n_free = pat.n if free is None else int(free.sum())
    free_rows = _free_rows(pat, free)

    t = time.perf_counter()
    dist, ratio = _coupling_distance(pat, pts, horizon, bonds, cloud, notes)
    timings["coupling"] = time.perf_counter() - t
    pat.brow = pat.bcol = None  # the block entries are not needed any more (memory)

    fills, fill_skipped = _fill_in(pat, free, n_free, fill_limit, timings)
    numbers = _numerical(pat, free, n_free, (eig_limit, cond_limit), zt, notes, timings)

    timings["total"] = time.perf_counter() - t0
    log.debug("sparsity report (%s, n=%d): %s", pat.source, pat.n, timings)
    return _report(
        pat, bonds, n_free, free_rows, dist, ratio, fills, fill_skipped, numbers, notes, timings
    )


@dataclass
class _Pattern:
    """The stored pattern of ``K`` (from the bonds or from the matrix) and its figures."""

    source: str
    hops: int | None
    n: int
    n_pts: int
    d: int
    P: sp.csr_array  # point (block) pattern
    brow: np.ndarray | None  # block entries (row, column), freed after the coupling distance
    bcol: np.ndarray | None
    n_blocks: int
    bpr: np.ndarray  # blocks per block row
    nnz: int
    nnz_row: np.ndarray
    envelope: tuple[int, int, int, int]  # bandwidth, profile; after RCM: bandwidth, profile
    perm: np.ndarray  # RCM permutation of the DOFs
    itemsize: int
    dof_pattern: sp.csr_array | None  # DOF pattern (K form; built for the fill-in otherwise)
    Kmat: Any  # the matrix (K form, or assembled with numeric=True); None otherwise
    Kc: sp.csr_array | None  # K as CSR with summed duplicates (K form)


def _check_arguments(
    K: Any,
    model: Any,
    cloud: PointCloud | None,
    bonds: Bonds | None,
    points: Any,
    limits: tuple[int, int, int],
    zero_tol: float,
) -> tuple[float, np.ndarray | None]:
    """Check the arguments of :func:`sparsity_report`; the zero tolerance and the points."""
    if model is not None and K is not None:
        raise InputError("pass either K or model (with cloud and bonds), not both")
    if model is None and K is None:
        raise InputError("sparsity_report needs K or model=, cloud=, bonds=; got neither")
    if cloud is not None and not isinstance(cloud, PointCloud):
        raise InputTypeError(f"cloud must be a PointCloud, got {type(cloud).__name__}")
    if bonds is not None and not isinstance(bonds, Bonds):
        raise InputTypeError(f"bonds must be pdlin Bonds, got {type(bonds).__name__}")
    if cloud is not None and points is not None:
        raise InputError("pass points or cloud, not both")
    for name, lim in zip(("fill_limit", "eig_limit", "cond_limit"), limits, strict=True):
        if isinstance(lim, bool) or not isinstance(lim, int | np.integer) or lim < 0:
            raise InputError(f"{name} must be an integer >= 0, got {lim!r}")
    zt = float(zero_tol)
    if not (0.0 < zt < 1.0):
        raise InputError(f"zero_tol must be in (0, 1), got {zero_tol!r}")

    pts: np.ndarray | None = None
    if cloud is not None:
        pts = cloud.points
    elif points is not None:
        pts = np.asarray(points, dtype=float)
        if pts.ndim == 1:
            pts = pts[:, None]
        if pts.ndim != 2 or pts.shape[1] not in (1, 2, 3):
            raise ShapeError(
                f"points must have shape (n_points, dim) with dim in 1..3, got {pts.shape}"
            )
        if not np.all(np.isfinite(pts)):
            raise InputError("points must be finite, got NaN or inf")
    if bonds is not None and pts is not None and bonds.n_points != pts.shape[0]:
        raise ShapeError(f"bonds were built for {bonds.n_points} points, got {pts.shape[0]} points")
    return zt, pts


def _model_pattern(
    model: Any,
    cloud: PointCloud | None,
    bonds: Bonds | None,
    block_size: int | None,
    numeric: bool,
    timings: dict[str, float],
) -> _Pattern:
    """Build the pattern of a model's ``K`` from its bonds (``K`` assembled if ``numeric``)."""
    if cloud is None or bonds is None:
        raise InputError(
            "model needs cloud= and bonds= as well, got "
            f"cloud={'given' if cloud is not None else None}, "
            f"bonds={'given' if bonds is not None else None}"
        )
    if not hasattr(model, "stiffness"):
        raise InputTypeError(
            f"model must be a pdlin model with a stiffness() method, got {type(model).__name__}"
        )
    if bonds.n_points != cloud.n or bonds.dim != cloud.dim:
        raise ShapeError(
            f"bonds were built for {bonds.n_points} points in {bonds.dim}D, "
            f"got a cloud of {cloud.n} points in {cloud.dim}D"
        )
    hops = _hops(getattr(model, "coupling_range", 1), "model.coupling_range")
    d = cloud.dim
    if block_size is not None and block_size != d:
        raise InputError(
            f"block_size must equal the cloud dimension {d} with a model, got {block_size}"
        )
    n_pts = cloud.n
    P = coupling_pattern(bonds, hops)
    Kmat = None
    if numeric:
        t = time.perf_counter()
        Kmat = model.stiffness(cloud, bonds)
        timings["assemble"] = time.perf_counter() - t
        if Kmat.shape != (n_pts * d,) * 2:
            raise ShapeError(
                f"model.stiffness returned shape {Kmat.shape}, expected {(n_pts * d,) * 2}"
            )
    brow = np.repeat(np.arange(n_pts, dtype=np.int64), np.diff(P.indptr))
    bcol = np.asarray(P.indices, dtype=np.int64)
    n_blocks = int(P.nnz)
    bpr = np.diff(P.indptr)
    nnz_row = np.repeat(bpr * d, d) if n_pts else np.zeros(0, dtype=np.int64)
    band, prof = _envelope(brow, bcol, n_pts, None, d)
    perm_pts = rcm_permutation(P, 1)
    q = np.empty(n_pts, dtype=np.int64)
    q[perm_pts] = np.arange(n_pts)
    band_r, prof_r = _envelope(brow, bcol, n_pts, q, d)
    return _Pattern(
        source=f"model:{type(model).__name__}",
        hops=hops,
        n=n_pts * d,
        n_pts=n_pts,
        d=d,
        P=P,
        brow=brow,
        bcol=bcol,
        n_blocks=n_blocks,
        bpr=bpr,
        nnz=n_blocks * d * d,
        nnz_row=nnz_row,
        envelope=(band, prof, band_r, prof_r),
        perm=rcm_permutation(P, d) if d > 1 else perm_pts,
        itemsize=8,
        dof_pattern=None,  # built lazily for the fill-in
        Kmat=Kmat,
        Kc=None,
    )


def _matrix_pattern(K: Any, pts: np.ndarray | None, block_size: int | None) -> _Pattern:
    """Read the stored pattern of an assembled ``K`` (explicit zeros of BSR blocks included)."""
    Kmat = _as_sparse(K)
    if Kmat.ndim != 2 or Kmat.shape[0] != Kmat.shape[1]:
        raise ShapeError(f"K must be square, got shape {Kmat.shape}")
    n = int(Kmat.shape[0])
    if n == 0:
        raise ShapeError("K must have at least one row, got shape (0, 0)")
    if block_size is None:
        if Kmat.format == "bsr" and Kmat.blocksize[0] == Kmat.blocksize[1]:
            d = int(Kmat.blocksize[0])
        elif pts is not None:
            d = int(pts.shape[1])
        else:
            d = 1
    else:
        d = _hops(block_size, "block_size")
    if n % d:
        raise ShapeError(f"K has {n} rows, not a multiple of block_size {d}")
    n_pts = n // d
    if pts is not None and pts.shape[0] != n_pts:
        raise ShapeError(
            f"points must have {n_pts} rows to match K ({n} DOFs / block size {d}), "
            f"got {pts.shape[0]}"
        )
    Kc = sp.csr_array(Kmat)  # keeps explicit zeros of BSR blocks
    Kc.sum_duplicates()
    Kc.sort_indices()
    nnz = int(Kc.nnz)
    nnz_row = np.diff(Kc.indptr)
    rows = np.repeat(np.arange(n, dtype=np.int64), nnz_row)
    cols = np.asarray(Kc.indices, dtype=np.int64)
    if d == 1:
        P = sp.csr_array((np.ones(nnz, dtype=bool), Kc.indices, Kc.indptr), shape=(n, n))
    else:
        P = sp.csr_array(
            sp.coo_array((np.ones(nnz, dtype=bool), (rows // d, cols // d)), shape=(n_pts, n_pts))
        )
        P.sum_duplicates()
    bpr = np.diff(P.indptr)
    band, prof = _envelope(rows, cols, n, None, 1)
    perm = rcm_permutation(P, d)
    q = np.empty(n, dtype=np.int64)
    q[perm] = np.arange(n)
    band_r, prof_r = _envelope(rows, cols, n, q, 1)
    return _Pattern(
        source="matrix",
        hops=None,
        n=n,
        n_pts=n_pts,
        d=d,
        P=P,
        brow=np.repeat(np.arange(n_pts, dtype=np.int64), bpr),
        bcol=np.asarray(P.indices, dtype=np.int64),
        n_blocks=int(P.nnz),
        bpr=bpr,
        nnz=nnz,
        nnz_row=nnz_row,
        envelope=(band, prof, band_r, prof_r),
        perm=perm,
        itemsize=int(Kc.dtype.itemsize),
        dof_pattern=sp.csr_array((np.ones(nnz, dtype=bool), Kc.indices, Kc.indptr), shape=(n, n)),
        Kmat=Kmat,
        Kc=Kc,
    )


def _free_rows(pat: _Pattern, free: np.ndarray | None) -> np.ndarray | None:
    """Count the stored entries per row of ``K_ff`` (None without fixed DOFs)."""
    if free is None:
        return None
    if pat.dof_pattern is None:  # full blocks: a free DOF's row holds its block row's free DOFs
        per_point = free.reshape(pat.n_pts, pat.d).sum(axis=1)
        counts = sp.csr_array(pat.P, dtype=np.int64) @ per_point
        return np.repeat(counts, pat.d)[free]
    fidx = np.flatnonzero(free)
    return np.diff(sp.csr_array(pat.dof_pattern[fidx][:, fidx]).indptr)


def _coupling_distance(
    pat: _Pattern,
    pts: np.ndarray | None,
    horizon: Any,
    bonds: Bonds | None,
    cloud: PointCloud | None,
    notes: list[str],
) -> tuple[float | None, float | None]:
    """Largest distance between coupled points, and in horizons (None where unknown)."""
    assert pat.brow is not None and pat.bcol is not None
    dist = None if pts is None else _coo_chunks_max_dist(pts, pat.brow, pat.bcol)
    hmax = _max_horizon(horizon, pat.n_pts)
    if hmax is None and bonds is not None:
        hmax = float(np.max(bonds.horizon))
    if hmax is None and cloud is not None and cloud.horizon is not None:
        hmax = float(np.max(cloud.horizon))
    ratio = None if dist is None or hmax is None else dist / hmax
    if pts is None:
        notes.append("coupling distance needs points (pass points= or cloud=)")
    elif hmax is None:
        notes.append("coupling range in horizons needs horizon= (or bonds/cloud with a horizon)")
    return dist, ratio


def _fill_in(
    pat: _Pattern,
    free: np.ndarray | None,
    n_free: int,
    fill_limit: int,
    timings: dict[str, float],
) -> tuple[dict[str, int | None], str | None]:
    """Fill-in per ordering (see :func:`_fill`) and why it was skipped; frees the DOF pattern."""
    fills: dict[str, int | None] = dict.fromkeys(FILL_ORDERINGS)
    fill_skipped = None
    if n_free > fill_limit:
        fill_skipped = f"{n_free} free DOFs > fill_limit {fill_limit}"
    elif n_free == 0:
        fill_skipped = "no free DOFs"
    else:
        t = time.perf_counter()
        dof_pattern = pat.dof_pattern
        if dof_pattern is None:
            blk = sp.csr_array(np.ones((pat.d, pat.d), dtype=bool))
            dof_pattern = sp.csr_array(sp.kron(pat.P, blk, format="csr"), dtype=bool)
        diag = sp.eye_array(pat.n, dtype=bool, format="csr")
        fills.update(_fill(sp.csr_array(dof_pattern + diag, dtype=bool), free, pat.perm))
        del dof_pattern
        timings["fill"] = time.perf_counter() - t
    pat.dof_pattern = None
    return fills, fill_skipped


@dataclass
class _Numbers:
    """The quantities of :class:`SparsityReport` that need the entries of ``K``."""

    nnz_numeric: int | None = None
    symmetry: float | None = None
    dd_frac: float | None = None
    dd_min: float | None = None
    cond2: float | None = None
    cond1: float | None = None
    zero_modes: int | None = None


def _numerical(
    pat: _Pattern,
    free: np.ndarray | None,
    n_free: int,
    limits: tuple[int, int],
    zt: float,
    notes: list[str],
    timings: dict[str, float],
) -> _Numbers:
    """Symmetry, diagonal dominance and conditioning of ``K`` (of ``K_ff`` with fixed DOFs)."""
    out = _Numbers()
    if pat.Kmat is None:
        notes.append("numerical quantities need K: pass K or numeric=True")
        return out
    eig_limit, cond_limit = limits
    t = time.perf_counter()
    Kc = pat.Kc
    if Kc is None:  # K assembled from the model (numeric=True); the K form built Kc already
        Kc = sp.csr_array(pat.Kmat)
        Kc.sum_duplicates()
        if Kc.nnz != pat.nnz:
            notes.append(
                f"assembled K stores {Kc.nnz} entries, the pattern from the bonds "
                f"(coupling_range {pat.hops}) predicts {pat.nnz}"
            )
    out.nnz_numeric = int(np.count_nonzero(Kc.data))
    nrm = float(spla.norm(Kc, "fro"))
    asym = float(spla.norm(Kc - Kc.T, "fro"))
    symmetry = asym / nrm if nrm > 0 else 0.0
    out.symmetry = symmetry
    diagv = np.abs(Kc.diagonal())
    absrow = np.asarray(abs(Kc).sum(axis=1)).ravel()
    off = np.maximum(absrow - diagv, 0.0)
    dominant = diagv >= off - 1e-12 * (diagv + off)
    out.dd_frac = float(np.mean(dominant))
    has_off = off > 0
    out.dd_min = float(np.min(diagv[has_off] / off[has_off])) if has_off.any() else None
    timings["numeric"] = time.perf_counter() - t
    Kf = Kc if free is None else Kc[np.flatnonzero(free)][:, np.flatnonzero(free)]
    sym = symmetry <= 1e-12
    if n_free == 0:
        notes.append("conditioning skipped: no free DOFs")
    elif n_free <= eig_limit:
        t = time.perf_counter()
        dense = Kf.toarray()
        s = np.abs(sla.eigvalsh(dense)) if sym else sla.svdvals(dense)
        smax = float(np.max(s))
        if smax > 0:
            nonzero = s > zt * smax
            out.zero_modes = int(np.count_nonzero(~nonzero))
            out.cond2 = smax / float(np.min(s[nonzero]))
        else:
            out.zero_modes = int(s.size)
        timings["dense_spectrum"] = time.perf_counter() - t
    else:
        notes.append(f"dense spectrum skipped: {n_free} free DOFs > eig_limit {eig_limit}")
    if free is None:
        notes.append("condition_1_est needs fixed_dofs (a free-floating K is singular)")
    elif n_free and n_free <= cond_limit:
        t = time.perf_counter()
        out.cond1 = _condition_1(Kf, sym, notes)
        timings["condition_1"] = time.perf_counter() - t
    elif n_free:
        notes.append(f"condition_1_est skipped: {n_free} free DOFs > cond_limit {cond_limit}")
    return out


def _report(
    pat: _Pattern,
    bonds: Bonds | None,
    n_free: int,
    free_rows: np.ndarray | None,
    dist: float | None,
    ratio: float | None,
    fills: dict[str, int | None],
    fill_skipped: str | None,
    numbers: _Numbers,
    notes: list[str],
    timings: dict[str, float],
) -> SparsityReport:
    """Assemble the :class:`SparsityReport` (memory figures computed here)."""
    n, n_pts, d, nnz, n_blocks = pat.n, pat.n_pts, pat.d, pat.nnz, pat.n_blocks
    idx_csr = _index_bytes(max(nnz, n))
    mem_csr = nnz * (pat.itemsize + idx_csr) + (n + 1) * idx_csr
    idx_bsr = _index_bytes(max(n_blocks, n_pts))
    mem_bsr = n_blocks * (d * d * pat.itemsize + idx_bsr) + (n_pts + 1) * idx_bsr
    n_bonds = None if bonds is None else int(bonds.n_bonds)
    bpr, nnz_row = pat.bpr, pat.nnz_row
    band, prof, band_r, prof_r = pat.envelope
    has_free = bool(n_free) and free_rows is not None
    return SparsityReport(
        source=pat.source,
        n=int(n),
        n_points=int(n_pts),
        block_size=int(d),
        coupling_range=pat.hops,
        nnz=int(nnz),
        n_blocks=n_blocks,
        nnz_numeric=numbers.nnz_numeric,
        nnz_per_row_min=int(np.min(nnz_row)),
        nnz_per_row_mean=float(nnz) / n,
        nnz_per_row_max=int(np.max(nnz_row)),
        blocks_per_row_min=int(np.min(bpr)),
        blocks_per_row_mean=float(np.mean(bpr)) if bpr.size else 0.0,
        blocks_per_row_max=int(np.max(bpr)),
        n_bonds=n_bonds,
        coupling_distance=dist,
        coupling_range_horizons=ratio,
        bandwidth=int(band),
        profile=int(prof),
        bandwidth_rcm=int(band_r),
        profile_rcm=int(prof_r),
        fill_natural=fills["natural"],
        fill_colamd=fills["colamd"],
        fill_mmd_at_plus_a=fills["mmd_at_plus_a"],
        fill_rcm=fills["rcm"],
        fill_skipped=fill_skipped,
        memory_csr_bytes=int(mem_csr),
        memory_bsr_bytes=int(mem_bsr),
        bytes_per_nnz_csr=mem_csr / nnz if nnz else None,
        bytes_per_nnz_bsr=mem_bsr / nnz if nnz else None,
        bytes_per_bond_csr=None if not n_bonds else mem_csr / n_bonds,
        bytes_per_bond_bsr=None if not n_bonds else mem_bsr / n_bonds,
        symmetry=numbers.symmetry,
        diag_dominant_fraction=numbers.dd_frac,
        diag_dominance_min_ratio=numbers.dd_min,
        n_fixed=int(n - n_free),
        condition_2=numbers.cond2,
        condition_1_est=numbers.cond1,
        zero_modes=numbers.zero_modes,
        nnz_free=None if free_rows is None else int(free_rows.sum()),
        nnz_per_row_free_min=int(free_rows.min()) if has_free and free_rows is not None else None,
        nnz_per_row_free_mean=(
            float(free_rows.sum()) / n_free if has_free and free_rows is not None else None
        ),
        nnz_per_row_free_max=int(free_rows.max()) if has_free and free_rows is not None else None,
        notes=tuple(notes),
        timings=timings,
    )


def _condition_1(Kf: sp.csr_array, symmetric: bool, notes: list[str]) -> float | None:
    """``onenormest(K) * onenormest(K⁻¹)`` through a sparse LU of ``K``."""
    csc = sp.csc_array(Kf)
    try:
        if symmetric:
            lu = spla.splu(
                csc,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        else:
            lu = spla.splu(csc, permc_spec="COLAMD")
    except RuntimeError as exc:
        notes.append(f"condition_1_est skipped: K_ff is singular ({exc})")
        return None
    m = Kf.shape[0]
    inv = spla.LinearOperator(
        (m, m),
        matvec=lambda x: lu.solve(np.asarray(x, dtype=float).ravel()),
        rmatvec=lambda x: lu.solve(np.asarray(x, dtype=float).ravel(), trans="T"),
        matmat=lambda X: lu.solve(np.asarray(X, dtype=float)),
        rmatmat=lambda X: lu.solve(np.asarray(X, dtype=float), trans="T"),
        dtype=float,
    )
    na = float(spla.onenormest(csc))
    ninv = float(spla.onenormest(inv))
    if not np.isfinite(ninv):
        notes.append("condition_1_est: K_ff⁻¹ has non-finite entries (singular K_ff)")
        return None
    return na * ninv


# -- the pattern a spy plot draws ---------------------------------------------------


def spy_pattern(
    K: Any,
    *,
    order: str | Sequence[int] | np.ndarray = "natural",
    block_size: int | None = None,
    blocks: bool = False,
) -> tuple[sp.csr_array, str]:
    """Boolean pattern of ``K`` in a given ordering: what :func:`pdlin.plotting.plot_spy` draws.

    Parameters
    ----------
    K : (n, n) sparse array or ndarray
        The matrix; its stored entries (explicit zeros included) make the pattern.
    order : {'natural', 'rcm'} or (m,) array_like of int
        Row/column ordering: as stored, reverse Cuthill-McKee of the point
        graph, or an explicit permutation (``perm[new] = old``, in DOFs, or
        in points when ``blocks=True``).
    block_size : int, optional
        DOFs per point (default: ``K.blocksize`` for BSR, else 1).
    blocks : bool
        The point (block) pattern instead of the DOF pattern.

    Returns
    -------
    pattern : (m, m) scipy.sparse.csr_array of bool
        ``m = n`` (DOFs) or ``n // block_size`` (points, ``blocks=True``), reordered.
    label : str
        ``'natural'``, ``'rcm'`` or ``'permuted'``.

    Raises
    ------
    ShapeError
        ``K`` is not square, or its size is not a multiple of ``block_size``.
    InputError
        ``order`` is neither ``'natural'``, ``'rcm'`` nor a permutation of the right size.

    Examples
    --------
    >>> import numpy as np
    >>> P, label = spy_pattern(np.array([[1.0, 0.0], [2.0, 3.0]]), order=[1, 0])
    >>> P.toarray().astype(int).tolist(), label
    ([[1, 1], [0, 1]], 'permuted')
    """
    Kmat = _as_sparse(K)
    if Kmat.shape[0] != Kmat.shape[1]:
        raise ShapeError(f"K must be square, got shape {Kmat.shape}")
    n = int(Kmat.shape[0])
    if block_size is None:
        d = int(Kmat.blocksize[0]) if Kmat.format == "bsr" else 1
    else:
        d = _hops(block_size, "block_size")
    if n % d:
        raise ShapeError(f"K has {n} rows, not a multiple of block_size {d}")
    Kc = sp.csr_array(Kmat)
    pat = sp.csr_array((np.ones(Kc.nnz, dtype=bool), Kc.indices, Kc.indptr), shape=(n, n))
    bpat = pat
    if d > 1:
        coo = pat.tocoo()
        bpat = sp.csr_array(
            sp.coo_array(
                (np.ones(coo.nnz, dtype=bool), (coo.row // d, coo.col // d)), shape=(n // d, n // d)
            )
        )
    target = bpat if blocks else pat
    size = target.shape[0]
    label = "natural"
    if isinstance(order, str):
        if order == "rcm":
            perm = rcm_permutation(bpat, 1 if blocks else d)
            target = target[perm][:, perm]
            label = "rcm"
        elif order != "natural":
            raise InputError(f"order must be 'natural', 'rcm' or a permutation, got {order!r}")
    else:
        perm = np.asarray(order)
        if perm.shape != (size,) or not np.array_equal(np.sort(perm), np.arange(size)):
            raise InputError(
                f"order must be a permutation of range({size}), got an array of shape {perm.shape}"
            )
        target = target[perm][:, perm]
        label = "permuted"
    return target, label
