"""Memory available to a run, what its stages will need, and the refusal when they do not fit.

pdlin estimates, from sizes known before the work (points, the horizon ratio, the number of
nonzeros, a fill estimate for direct factorizations), the bytes each large allocation needs
and compares them with :func:`available_memory`.  A stage that would not fit raises
:class:`pdlin.errors.InsufficientMemoryError` naming the estimate, what is available and
what would fit, instead of a raw ``MemoryError`` minutes into the run (``docs/large_problems.md``,
"Memory: estimates and refusals").

The coefficients below were measured with ``benchmarks/bench_memory.py`` (peak RSS of
``pdlin run`` in a subprocess against the printed estimate, ``benchmarks/README.md``).
"""

from __future__ import annotations

import math
import os
import resource
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import InputError, InsufficientMemoryError

__all__ = [
    "MemoryBudget",
    "available_memory",
    "check_memory",
    "neighbours_per_point",
    "lattice_pair_count",
    "estimate_pair_count",
    "bonds_bytes",
    "resident_bonds_bytes",
    "grid_bytes",
    "direct_factor_nnz",
    "direct_factor_bytes",
    "RunEstimate",
    "estimate_static_run",
    "format_bytes",
    "current_rss",
    "out_of_memory_message",
]

#: environment variable capping the memory pdlin plans with (bytes, or with a suffix
#: ``K``/``M``/``G``/``T``, e.g. ``PDLIN_MAX_MEMORY=8G``)
ENV_LIMIT = "PDLIN_MAX_MEMORY"

#: bytes per directed bond of :class:`pdlin.Bonds`: i, j (int64), ξ (8 d), |ξ|, ω, V_j
_BOND_BYTES_FIXED = 40

#: bytes per directed bond a compact :class:`pdlin.Bonds` of a lattice search keeps through
#: the solve: ``j`` (int64) and the stencil index (uint8); ``i``, ``ξ``, ``|ξ|``, a constant
#: or per-stencil ``ω`` and ``V_j`` are computed on access (measured: 9.2 B at 12 x 11 x 10)
COMPACT_BOND_BYTES = 9

#: bond search: transient bytes on top of the bonds it returns, as a multiple of them
#: (measured: 2D lattice 300,304 points, 0.47 GB of bonds, peak 0.75 GB above the start)
BOND_SEARCH_TRANSIENT = 0.6

#: assembly transient on top of K, as a multiple of K (measured: one-hop bond-based 2D
#: 300k points 0.75; two-hop correspondence 401² with stress points 1.0 besides the
#: compiled kernels, TWO_HOP_KERNELS)
#: (issue 33, with compact bonds and the fused numba kernel: 3D bond-based 60³ and 80³
#: 0.06-0.1; 0.15 kept for the numpy path; the solve stage stays the larger one)
ASSEMBLY_TRANSIENT = {1: 0.15, 2: 1.0}

#: two-hop models (LPS, XOSB, correspondence) compile their numba kernels on first use:
#: measured RSS +130 MB over the assembly of a 12³ LPS K of 24 MB
TWO_HOP_KERNELS = 130 * 2**20

#: smoothed-aggregation AMG hierarchy plus Krylov work vectors, as a multiple of K
#: (measured: bond-based 2D 300k points 0.9 x K)
AMG_FACTOR = 0.9

#: the same in 3D (measured, issue 33: bond-based 60³ and 80³ cubes, δ = 3.015 h, the AMG
#: set-up and CG peak 0.5 x K above K and the compact bonds)
AMG_FACTOR_3D = 0.55

#: matrix-free operator (per-bond coefficients, the AMG surrogate), bytes per directed bond
#: (measured: 3D LPS 24³, δ = 3.015 h: 0.51 GB over 1.46 M bonds, 0.38 GB without the
#: compiled kernels = 260 B)
MATRIX_FREE_BYTES_PER_BOND = {2: 160, 3: 260}

#: result fields and the output writer's staging, bytes per directed bond and per point
#: (measured: bond-based 2D 300k points, 0.53 GB while writing the VTU)
OUTPUT_BYTES_PER_BOND = 48
OUTPUT_BYTES_PER_POINT = 400

#: seconds per nonzero of K of a whole static solve (bonds, assembly, AMG set-up and
#: solve), the order of magnitude measured on 2 cores: bond-based 2D 300k points 7.3 s for
#: 34.7 M nonzeros, correspondence 401² 16-22 s for 26.4 M, 3D LPS 24³ matrix-free 4.9 s
#: for 77 M; SuperLU ~3e-7 s per nonzero of L + U (12³ LPS: 9.6 s for 12.4 M, 200²: 26 s
#: for 88 M)
SECONDS_PER_NONZERO = {"assembled-1": 2.5e-7, "assembled-2": 8e-7, "matrix-free": 1e-7}
SECONDS_PER_FACTOR_NONZERO = 3e-7

#: runs estimated to take longer than this warn before they start (SlowRunWarning)
LONG_RUN_SECONDS = 600.0

#: modules imported and kernels compiled after the estimate (pyamg, numba's JIT)
LATE_IMPORTS = 40 * 2**20

#: the nonlinear drivers' first load step compiles the material kernels (numba / LLVM) where
#: the material sends its points to them (crystal plasticity from 8,192 points): measured on
#: cp_shear with the kernels on, RSS 0.127 -> 0.245 GB over the first step of 625 points
NONLINEAR_LATE_IMPORTS = 110 * 2**20

#: fill constants of the nested-dissection estimate of nnz(L) (see direct_factor_nnz),
#: measured on the 401² correspondence anchor (CHOLMOD / PARDISO, docs/large_problems.md)
#: and SuperLU runs; SuperLU stores L and U with its own (minimum-degree) ordering
FILL_CONSTANT = {2: 3.5, 3: 2.5}

#: SuperLU's L + U against the nested-dissection nnz(L) above: about 2 in 2D (measured
#: 1.7-2.1 on LPS grids of 100²-200², δ = 1-3 h) and growing with the side N in 3D under its
#: minimum-degree order (measured 1.8, 2.2, 2.7 at N = 8, 10, 12, δ = 2 h: ~0.225 N)
SUPERLU_FILL_2D = 2.0
SUPERLU_FILL_3D_PER_SIDE = 0.225

#: METIS-ordered factors (CHOLMOD, PARDISO; MUMPS not measured) in 3D: the peak of their
#: factorization over the nested-dissection estimate of the factor's bytes. Measured on LPS
#: 24³, δ = 3.015 h (41,472 unknowns): PARDISO reports nnz(L) = 3.17e8 against 2.09e8
#: estimated, and the runs peak at 7.58 GB (PARDISO) and 7.67 GB (CHOLMOD), 6.2 GB of it
#: the factorization's, against a 2.51 GB estimate of the factor (benchmarks/README.md,
#: bench_memory.py --cases lps3d-direct24). In 2D the estimate of nnz(L) is calibrated on
#: CHOLMOD's (FILL_CONSTANT) and the factorizations' workspace is not yet measured.
ND_FACTOR_PEAK_3D = 2.45

#: SuperLU's peak during the factorization against its final L + U (its memory expansions:
#: measured 0.31 GB of peak for a 0.15 GB factor, 12³ LPS)
SUPERLU_WORKSPACE = 2.0


def format_bytes(n: float) -> str:
    """Format a size in bytes for people, e.g. ``'1.35 GB'`` (decimal units).

    Parameters
    ----------
    n : float
        Bytes.

    Returns
    -------
    str
        Two decimals and a unit from kB to PB; plain bytes below 1 kB.

    Examples
    --------
    >>> format_bytes(1.35e9), format_bytes(2.5e15)
    ('1.35 GB', '2.50 PB')
    """
    for unit, scale in (("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if abs(n) >= scale:
            return f"{n / scale:.2f} {unit}"
    return f"{int(n)} B"


def _parse_size(text: str) -> int:
    t = text.strip().upper().removesuffix("B")
    mult = 1
    for suffix, m in (("K", 2**10), ("M", 2**20), ("G", 2**30), ("T", 2**40)):
        if t.endswith(suffix):
            t, mult = t[:-1], m
            break
    try:
        value = float(t)
    except ValueError:
        value = -1.0
    if not (math.isfinite(value) and value > 0):
        raise InputError(
            f"{ENV_LIMIT} must be a positive size in bytes (suffix K, M, G or T allowed), "
            f"got {text!r}"
        )
    return int(value * mult)


def _read_int(path: str) -> int | None:
    try:
        with open(path) as f:
            text = f.read().strip()
    except OSError:
        return None
    if not text or text == "max":
        return None
    try:
        v = int(text)
    except ValueError:
        return None
    return v if 0 < v < 2**62 else None


def _meminfo() -> dict[str, int]:
    out: dict[str, int] = {}
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                key, _, rest = line.partition(":")
                parts = rest.split()
                if parts:
                    out[key] = int(parts[0]) * 1024
    except (OSError, ValueError):
        pass
    return out


def current_rss() -> int:
    """Measure the resident memory of this process.

    Returns
    -------
    int
        Bytes (from ``/proc/self/statm``); 0 where that cannot be read.
    """
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        return 0


def _vm_size() -> int:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        return 0


#: mount point of the cgroup file systems (v2 unified, or v1 with a ``memory`` hierarchy)
CGROUP_ROOT = "/sys/fs/cgroup"


def _cgroup_dirs() -> list[tuple[str, str]]:
    """List this process's memory cgroup directories as ``(version, directory)`` pairs.

    Innermost first, then the mount point (a container's own root); v2 before v1.
    """
    v2: list[str] = []
    v1: list[str] = []
    try:
        with open("/proc/self/cgroup") as f:
            for line in f:
                _, ctrl, path = line.rstrip("\n").split(":", 2)
                if ctrl == "" and path:
                    v2.append(os.path.join(CGROUP_ROOT, path.lstrip("/")))
                elif "memory" in ctrl.split(","):
                    v1.append(os.path.join(CGROUP_ROOT, "memory", path.lstrip("/")))
    except (OSError, ValueError):
        pass
    dirs = [("v2", d) for d in [*v2, CGROUP_ROOT]]
    dirs += [("v1", d) for d in [*v1, os.path.join(CGROUP_ROOT, "memory")]]
    return dirs


def _stat_value(path: str, key: str) -> int:
    try:
        with open(path) as f:
            for line in f:
                k, _, v = line.partition(" ")
                if k == key:
                    return int(v)
    except (OSError, ValueError):
        pass
    return 0


def _cgroup_headroom() -> int | None:
    """Return the limit minus the usage of the innermost memory cgroup with a limit.

    Reclaimable page cache (``inactive_file``) is not counted as used; None without a
    limit.
    """
    names = {
        "v2": ("memory.max", "memory.current", "inactive_file"),
        "v1": ("memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file"),
    }
    for version, d in _cgroup_dirs():
        lim_f, use_f, cache_key = names[version]
        lim = _read_int(os.path.join(d, lim_f))
        if lim is None:
            continue
        used = _read_int(os.path.join(d, use_f)) or 0
        used -= _stat_value(os.path.join(d, "memory.stat"), cache_key)
        return max(lim - max(used, 0), 0)
    return None


@dataclass(frozen=True)
class MemoryBudget:
    """Memory a run may still allocate.

    Attributes
    ----------
    bytes : int
        The smallest of the limits below: what pdlin plans with.
    limits : dict of str to int
        Each limit found (headroom in bytes): ``'cgroup'`` (limit minus usage),
        ``'RLIMIT_AS'`` (address-space limit minus this process's size),
        ``'MemAvailable'`` (or physical memory) and ``PDLIN_MAX_MEMORY``.
    """

    bytes: int
    limits: dict[str, int] = field(default_factory=dict)

    @property
    def source(self) -> str:
        """Name of the limit that binds."""
        return min(self.limits, key=self.limits.__getitem__) if self.limits else "unknown"

    def describe(self) -> str:
        """Describe the budget and the limit that binds.

        Returns
        -------
        str
            E.g. ``'1.20 GB (cgroup)'``.
        """
        return f"{format_bytes(self.bytes)} ({self.source})"


def available_memory() -> MemoryBudget:
    """Memory this process may still allocate, from every limit pdlin can read.

    The minimum of: the cgroup v2 (``memory.max - memory.current``) or v1 limit, the
    ``RLIMIT_AS`` soft limit minus the address space already in use, the kernel's
    ``MemAvailable`` (else physical memory) and the ``PDLIN_MAX_MEMORY`` environment
    variable (a cap set by the user, e.g. ``8G``).

    Returns
    -------
    MemoryBudget
        The smallest headroom in bytes and every limit found.

    Examples
    --------
    >>> from pdlin.resources import available_memory
    >>> budget = available_memory()
    >>> budget.bytes > 0
    True
    """
    limits: dict[str, int] = {}
    cg = _cgroup_headroom()
    if cg is not None:
        limits["cgroup"] = cg
    try:
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ValueError, OSError):  # pragma: no cover - exotic platforms
        soft = resource.RLIM_INFINITY
    if soft != resource.RLIM_INFINITY and soft > 0:
        limits["RLIMIT_AS"] = max(int(soft) - _vm_size(), 0)
    info = _meminfo()
    if "MemAvailable" in info:
        limits["MemAvailable"] = info["MemAvailable"]
    else:
        try:
            limits["physical memory"] = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES")
        except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
            pass
    env = os.environ.get(ENV_LIMIT)
    if env:
        limits[ENV_LIMIT] = max(_parse_size(env) - current_rss(), 0)
    if not limits:  # pragma: no cover - nothing readable: do not refuse
        return MemoryBudget(2**62, {})
    return MemoryBudget(min(limits.values()), limits)


def check_memory(
    stage: str,
    need: float,
    hints: Sequence[str] | Callable[[], Sequence[str]] = (),
    *,
    budget: MemoryBudget | None = None,
) -> MemoryBudget:
    """Refuse a stage whose estimated allocation exceeds the available memory.

    Parameters
    ----------
    stage : str
        What is about to be allocated (``'bond search'``, ``'assembly'``, ...).
    need : float
        Estimated bytes the stage allocates on top of what the process holds.
    hints : sequence of str, or a callable returning one
        What would fit instead (a coarser grid, ``solver='amg-cg'``, ...); a callable is
        called only when the stage does not fit.
    budget : MemoryBudget, optional
        Defaults to :func:`available_memory`.

    Returns
    -------
    MemoryBudget
        The budget checked against (when the stage fits).

    Raises
    ------
    InsufficientMemoryError
        When ``need`` exceeds the budget; the message states the estimate, what is
        available (and which limit binds) and the hints.

    Examples
    --------
    >>> from pdlin.resources import MemoryBudget, check_memory
    >>> check_memory("grid", 1e6, budget=MemoryBudget(2**30, {"test": 2**30})).bytes
    1073741824
    >>> try:
    ...     check_memory("grid", 1e12, ["a coarser grid"],
    ...                  budget=MemoryBudget(2**30, {"test": 2**30}))
    ... except MemoryError as exc:
    ...     print(exc)
    grid needs ~1.00 TB but 1.07 GB (test) is available; what would fit: a coarser grid
    """
    b = available_memory() if budget is None else budget
    if need > b.bytes:
        msg = f"{stage} needs ~{format_bytes(need)} but {b.describe()} is available"
        if callable(hints):
            hints = list(hints())
        if hints:
            msg += "; what would fit: " + "; ".join(hints)
        raise InsufficientMemoryError(msg, need=int(need), available=b.bytes, hints=hints)
    return b


# --------------------------------------------------------------------------- sizes


def _ball_volume(dim: int, r: float) -> float:
    return math.pi ** (dim / 2) / math.gamma(dim / 2 + 1) * r**dim


def neighbours_per_point(dim: int, ratio: float) -> float:
    """Count the neighbours of an interior point of a unit lattice within ``ratio`` spacings.

    Exact lattice-point count (without the point itself) for ``(2 ratio + 1)^dim`` up to
    10⁷ stencil points, the ball volume beyond.

    Parameters
    ----------
    dim : {1, 2, 3}
        Lattice dimension.
    ratio : float
        Radius in lattice spacings (δ / h); points at exactly ``ratio`` count (relative
        tolerance 1e-9).

    Returns
    -------
    float
        The count (an integer value), or the ball volume for very wide stencils.

    Raises
    ------
    InputError
        When ``dim`` is not 1, 2 or 3 or ``ratio`` is not finite and positive.

    Examples
    --------
    >>> from pdlin.resources import neighbours_per_point
    >>> neighbours_per_point(3, 3.015), neighbours_per_point(2, 3.015)  # find_bonds' 122, 28
    (122.0, 28.0)
    """
    if dim not in (1, 2, 3):
        raise InputError(f"dim must be 1, 2 or 3, got {dim!r}")
    r = float(ratio)
    if not (math.isfinite(r) and r > 0):
        raise InputError(f"ratio must be a finite number > 0, got {ratio!r}")
    m = int(math.floor(r * (1 + 1e-9)))
    if (2 * m + 1) ** dim > 10**7:
        return _ball_volume(dim, r)
    k = np.arange(-m, m + 1, dtype=float) ** 2
    r2 = r * r * (1 + 2e-9)
    if dim == 1:
        return float(np.count_nonzero(k <= r2) - 1)
    sq = k[:, None] + k[None, :]
    if dim == 2:
        return float(np.count_nonzero(sq <= r2) - 1)
    total = 0
    for kz in k:  # (2m+1) slices of a (2m+1)² table: no (2m+1)³ array
        total += int(np.count_nonzero(sq + kz <= r2))
    return float(total - 1)


def lattice_pair_count(
    shape: Sequence[int], spacing: Sequence[float], radius: float, hops: int = 1
) -> int:
    """Directed pairs of a regular grid within ``hops`` bonds of length <= ``radius``.

    The sum over the stencil offsets ``o`` of ``prod_k max(shape_k - |o_k|, 0)``, the
    stencil being the ball of ``radius`` (``hops = 1``, exact) or its ``hops``-fold
    Minkowski sum (the pattern of a K coupling points two bonds apart; exact in the
    interior, a slight overcount at the boundary; the ball of ``2 radius`` for wide
    stencils).  The stencil is clipped to the grid; above 2·10⁷ stencil points the interior
    count ``n x min(neighbours(hops x radius), n - 1)`` (an upper bound).

    Parameters
    ----------
    shape : sequence of int
        Points per axis.
    spacing : sequence of float
        Spacing per axis.
    radius : float
        Bond length limit (the horizon), same units as ``spacing``.
    hops : int
        1 for the bonds, 2 for the pattern of a two-hop (state-based) K.

    Returns
    -------
    int
        Number of directed pairs ``(i, j)``, ``i != j``.

    Examples
    --------
    >>> import pdlin
    >>> from pdlin.resources import lattice_pair_count
    >>> n = lattice_pair_count((7, 7, 7), (1.0, 1.0, 1.0), 3.015)
    >>> n == pdlin.find_bonds(pdlin.grid((7, 7, 7)), ratio=3.015).n_bonds
    True
    """
    shp = np.asarray(shape, dtype=np.int64)
    h = np.asarray(spacing, dtype=float)
    dim = shp.size
    n = int(np.prod(shp.astype(float)))
    r = float(radius) * (1 + 1e-9)
    # offsets reaching past the grid pair no points: clip the stencil to the grid
    m1 = np.minimum(np.floor(r / h).astype(np.int64), shp - 1)
    mh = np.minimum(np.floor(hops * r / h).astype(np.int64), shp - 1)
    ball1 = float(np.prod(2.0 * m1 + 1))
    if hops > 2 or float(np.prod(2.0 * mh + 1)) > 2e7:
        per = neighbours_per_point(dim, hops * r / float(np.max(h)))
        return int(n * min(per, n - 1))
    rng = [np.arange(-mk, mk + 1) for mk in (m1 if hops == 2 and ball1 <= 2000 else mh)]
    offs = np.stack([g.ravel() for g in np.meshgrid(*rng, indexing="ij")], axis=1)
    if hops == 2 and ball1 <= 2000:  # the Minkowski sum of the one-bond ball with itself
        offs = offs[np.sum((offs * h) ** 2, axis=1) <= r * r]
        offs = np.unique((offs[:, None, :] + offs[None, :, :]).reshape(-1, dim), axis=0)
    else:  # one bond, or two bonds of a wide ball: the ball of hops x radius
        offs = offs[np.sum((offs * h) ** 2, axis=1) <= (hops * r) ** 2]
    offs = offs[np.any(offs != 0, axis=1)]
    counts = np.prod(np.clip(shp[None, :] - np.abs(offs), 0, None).astype(float), axis=1)
    return int(min(np.sum(counts), float(n) * (n - 1)))


def estimate_pair_count(cloud: Any, horizon: Any = None, ratio: float | None = None, *,
                        hops: int = 1) -> int:  # fmt: skip
    """Estimate the directed pairs at most ``hops`` bonds apart, before any search.

    Exact for :func:`pdlin.grid` clouds with a constant horizon; otherwise
    ``sum_i neighbours(δ_i / h_i)`` with the point's spacing ``h_i = V_i^(1/d)`` (interior
    count: an upper bound for clouds with boundaries).

    Parameters
    ----------
    cloud : PointCloud
        The points.
    horizon : float or (n,) array_like, optional
        Horizon(s); see :func:`pdlin.find_bonds`.
    ratio : float, optional
        Horizon as a multiple of the spacing (instead of ``horizon``).
    hops : int
        1 for the bonds, 2 for the pattern of a two-hop K.

    Returns
    -------
    int
        Estimated number of directed pairs.
    """
    from .geometry.bonds import resolve_horizon

    hor = resolve_horizon(cloud, horizon, ratio)
    lat = getattr(cloud, "lattice", None)
    if lat is not None and lat.index is None and bool(np.all(hor == hor[0])):
        return lattice_pair_count(lat.shape, lat.spacing, float(hor[0]), hops=hops)
    rel = hops * np.asarray(hor, dtype=float) / np.asarray(cloud.spacing, dtype=float)
    # a handful of distinct ratios in practice: count each once
    vals, counts = np.unique(np.round(rel, 6), return_counts=True)
    if vals.size > 64:
        vals = np.array([float(np.median(rel))])
        counts = np.array([rel.size])
    n = cloud.n  # no point has more than n - 1 neighbours
    per = [
        c * min(neighbours_per_point(cloud.dim, v), n - 1)
        for v, c in zip(vals, counts, strict=True)
    ]
    return int(sum(per))


def bonds_bytes(n_bonds: float, n_points: float, dim: int) -> int:
    """Estimate the bytes of :class:`pdlin.Bonds` (matches ``Bonds.nbytes``).

    Parameters
    ----------
    n_bonds : float
        Directed bonds.
    n_points : float
        Points.
    dim : int
        Dimension (``xi`` holds ``dim`` floats per bond).

    Returns
    -------
    int
        Bytes of the bond arrays and the row pointer.
    """
    return int(n_bonds * (_BOND_BYTES_FIXED + 8 * dim) + 16 * (n_points + 1))


def resident_bonds_bytes(n_bonds: float, n_points: float, dim: int, lattice: bool) -> int:
    """Estimate the bytes a :func:`pdlin.find_bonds` result keeps through a solve.

    Parameters
    ----------
    n_bonds : float
        Directed bonds.
    n_points : float
        Points.
    dim : int
        Dimension.
    lattice : bool
        True for the integer-stencil search of a grid cloud (``j`` and a stencil index,
        :data:`COMPACT_BOND_BYTES`); False for a tree search, which keeps ``j``, ``ξ``,
        ``|ξ|`` and ``ω``.

    Returns
    -------
    int
        Bytes of the stored per-bond arrays and the row pointer.

    Examples
    --------
    >>> from pdlin.resources import resident_bonds_bytes
    >>> resident_bonds_bytes(1_000_000, 10_000, 3, True)
    9080008
    """
    per = COMPACT_BOND_BYTES if lattice else 24 + 8 * dim
    return int(n_bonds * per + 8 * (n_points + 1))


def grid_bytes(n_points: float, dim: int) -> int:
    """Estimate the peak bytes of building a grid cloud.

    Coordinates, volumes, the meshgrid copies and the face sets (each about
    ``n^((d-1)/d)`` indices).

    Parameters
    ----------
    n_points : float
        Points of the grid.
    dim : int
        Dimension.

    Returns
    -------
    int
        Estimated peak bytes.
    """
    faces = 2 * dim * 8 * n_points ** ((dim - 1) / dim) if dim > 1 else 16
    return int(8 * n_points * (3 * dim + 2) + faces)


def direct_factor_nnz(n_points: int, nnz_blocks: int, dim: int, dofs_per_point: int) -> int:
    """Nested-dissection estimate of the nonzeros of a Cholesky factor L.

    With ``m = nnz_blocks / n`` blocks per point the coupling radius is
    ``R = (m / V_d)^(1/d)`` lattice spacings and a separator of a body of ``N = n^(1/d)``
    points per side holds ``s = R N^(d-1) dofs`` unknowns.  Summing the dense fronts over the
    dissection levels gives ``nnz(L) ≈ c s² log2(N / R)`` in 2D and ``≈ c s²`` in 3D (the
    geometric series of the 3D levels), capped at the dense ``ndof² / 2``; ``c`` is
    :data:`FILL_CONSTANT` (2D: 401² correspondence, CHOLMOD nnz(L) 1.9·10⁸ against
    5.7·10⁷ for ``s² log2(N / R)``).

    Parameters
    ----------
    n_points : int
        Points (block rows of K).
    nnz_blocks : int
        Stored d x d blocks of K, diagonal included.
    dim : int
        Dimension of the body (1D is banded: no fill beyond K).
    dofs_per_point : int
        Block size.

    Returns
    -------
    int
        Estimated nonzeros of L, at least K's lower triangle, at most dense.
    """
    n = max(int(n_points), 1)
    ndof = n * dofs_per_point
    dense = ndof * (ndof + 1) / 2
    if dim == 1 or n < 64:
        return int(min(dense, nnz_blocks * dofs_per_point**2))
    m = max(nnz_blocks / n, 1.0)
    R = max((m / _ball_volume(dim, 1.0)) ** (1 / dim), 1.0)
    N = n ** (1 / dim)
    s = R * N ** (dim - 1) * dofs_per_point
    if dim == 2:
        est = FILL_CONSTANT[2] * s * s * max(math.log2(max(N / R, 2.0)), 1.0)
    else:
        est = FILL_CONSTANT[3] * s * s
    # never below K's own lower triangle
    return int(min(dense, max(est, nnz_blocks * dofs_per_point**2 / 2)))


def direct_factor_bytes(nnz_l: float, backend: str, n_points: int = 0, dim: int = 2) -> int:
    """Estimate the bytes of a direct factor with ``nnz_l`` (nested-dissection) nonzeros in L.

    8 (value) + 4 (index) bytes per entry; SuperLU holds L and U under a minimum-degree
    order (:data:`SUPERLU_FILL_2D`, :data:`SUPERLU_FILL_3D_PER_SIDE` times more).

    Parameters
    ----------
    nnz_l : float
        Nonzeros of L, e.g. from :func:`direct_factor_nnz`.
    backend : str
        ``'superlu'`` (L and U) or a Cholesky backend (``'cholmod'``, ``'pardiso'``).
    n_points : int
        Points (SuperLU's 3D fill grows with the side ``n^(1/3)``).
    dim : int
        Dimension.

    Returns
    -------
    int
        Estimated bytes of the factor.
    """
    f = 1.0
    if backend == "superlu":
        if dim == 3:
            f = max(1.5, SUPERLU_FILL_3D_PER_SIDE * max(n_points, 1) ** (1 / 3))
        else:
            f = SUPERLU_FILL_2D
    return int(12 * nnz_l * f)


# --------------------------------------------------------------------------- a whole run


@dataclass
class RunEstimate:
    """Estimated peak of a static solve, stage by stage (bytes above the current RSS).

    Attributes
    ----------
    n_points, n_bonds, nnz_blocks : int
        Points, directed bonds and d x d blocks of K.
    path : str
        ``'assembled'``, ``'matrix-free'`` or ``'direct'``.
    stages : dict of str to int
        Peak of each stage: ``'bonds'``, ``'assembly'``, ``'solve'``, ``'output'``.
    base : int
        Resident memory when the estimate was made, plus late imports.
    seconds : float
        Order-of-magnitude run time (:data:`SECONDS_PER_NONZERO`).
    coupling_range : int
        1 for one-hop K, 2 for models coupling points two bonds apart.
    history_steps, history_bytes : int
        Load steps whose fields a load-stepping driver keeps, and their bytes (included
        in every stage; :func:`pdlin.problem.plan_memory`).
    """

    n_points: int
    n_bonds: int
    nnz_blocks: int
    dim: int
    path: str
    stages: dict[str, int]
    base: int
    seconds: float = 0.0
    coupling_range: int = 1
    history_steps: int = 0
    history_bytes: int = 0

    @property
    def peak(self) -> int:
        """Estimated peak resident memory of the run."""
        return self.base + max(self.stages.values())

    def slow_warning(self) -> str | None:
        """Return a warning text when the run is estimated to exceed :data:`LONG_RUN_SECONDS`.

        Returns
        -------
        str or None
            The estimated minutes, the sizes and what would be faster; ``None`` for a
            shorter run.
        """
        if self.seconds <= LONG_RUN_SECONDS:
            return None
        return (
            f"this run is estimated to take ~{self.seconds / 60:,.0f} min ({self.n_points:,} "
            f"points, ~{self.n_bonds:,} bonds, {self.nnz_blocks * self.dim**2:,} nonzeros in "
            f"K, {self.path}); a smaller horizon ratio or a coarser discretization is faster"
        )

    @property
    def need(self) -> int:
        """Estimated bytes on top of what the process holds now."""
        return self.peak - current_rss()

    def summary(self) -> str:
        """Summarize the estimate in one line for the stage printer.

        Returns
        -------
        str
            Peak, its stage and the sizes.
        """
        big = max(self.stages, key=self.stages.__getitem__)
        return (
            f"memory estimate: peak ~{format_bytes(self.peak)} ({big}) for "
            f"{self.n_points:,} points, ~{self.n_bonds:,} bonds, {self.path} K"
        )


def estimate_static_run(
    n_points: int,
    n_bonds: int,
    nnz_blocks: int,
    dim: int,
    *,
    path: str = "assembled",
    coupling_range: int = 1,
    backend: str = "superlu",
    base: int | None = None,
    resident_bonds: int | None = None,
) -> RunEstimate:
    """Peak-memory estimate of a linear static solve from counts known before the work.

    Parameters
    ----------
    n_points, n_bonds, nnz_blocks, dim : int
        Points, directed bonds, d x d blocks of K (diagonal included) and dimension.
    path : {'assembled', 'matrix-free', 'direct'}
        Assembled K with AMG, matrix-free operator, or assembled K factorized.
    coupling_range : int
        1 for bond-based K, 2 for models coupling points two horizons apart.
    backend : str
        Direct backend (``'superlu'`` holds L and U).
    base : int, optional
        Resident bytes to start from (default: the current RSS plus late imports).
    resident_bonds : int, optional
        Bytes the bonds keep after their search (:func:`resident_bonds_bytes`; default:
        all per-bond arrays, :func:`bonds_bytes`).

    Returns
    -------
    RunEstimate
        Peak bytes per stage above ``base`` and an order-of-magnitude run time.

    Examples
    --------
    >>> from pdlin.resources import estimate_static_run
    >>> est = estimate_static_run(10_000, 280_000, 290_000, 2, base=0)
    >>> max(est.stages, key=est.stages.get), est.peak > 0
    ('solve', True)
    """
    from .operators.assembly import estimate_bond_operator_bytes

    K = estimate_bond_operator_bytes(n_points, nnz_blocks, dim)
    # the search holds every per-bond array; afterwards only what the Bonds store
    stages = {"bonds": int(bonds_bytes(n_bonds, n_points, dim) * (1 + BOND_SEARCH_TRANSIENT))}
    B = bonds_bytes(n_bonds, n_points, dim) if resident_bonds is None else int(resident_bonds)
    ta = ASSEMBLY_TRANSIENT[2 if coupling_range >= 2 else 1]
    vectors = 12 * 8 * n_points * dim
    if path == "matrix-free":
        mf = MATRIX_FREE_BYTES_PER_BOND[3 if dim == 3 else 2] * n_bonds
        stages["assembly"] = B + mf
        stages["solve"] = int(B + mf * 1.2 + vectors)
    else:
        stages["assembly"] = int(B + K * (1 + ta))
        if path == "direct":
            nnz_l = direct_factor_nnz(n_points, nnz_blocks, dim, dim)
            # K (eliminated in place), its CSC / triangle copy and the factor
            fb = direct_factor_bytes(nnz_l, backend, n_points, dim)
            if backend == "superlu":
                fb = int(fb * SUPERLU_WORKSPACE)
            elif dim == 3:
                fb = int(fb * ND_FACTOR_PEAK_3D)
            stages["solve"] = int(B + 1.6 * K + fb + vectors)
        else:
            amg = AMG_FACTOR_3D if dim == 3 else AMG_FACTOR
            stages["solve"] = int(B + K * (1 + amg) + vectors)
    stages["output"] = int(
        B + OUTPUT_BYTES_PER_BOND * n_bonds * dim * dim / 4 + OUTPUT_BYTES_PER_POINT * n_points
    )
    nnz = nnz_blocks * dim * dim
    late = LATE_IMPORTS + (TWO_HOP_KERNELS if coupling_range >= 2 and _compiles(nnz) else 0)
    b = current_rss() + late if base is None else int(base)
    if path == "matrix-free":
        secs = SECONDS_PER_NONZERO["matrix-free"] * nnz
    else:
        secs = SECONDS_PER_NONZERO[f"assembled-{2 if coupling_range >= 2 else 1}"] * nnz
        if path == "direct":
            fill = direct_factor_bytes(direct_factor_nnz(n_points, nnz_blocks, dim, dim),
                                       backend, n_points, dim) / 12  # fmt: skip
            secs += SECONDS_PER_FACTOR_NONZERO * fill
    return RunEstimate(
        n_points, n_bonds, nnz_blocks, dim, path, stages, b, float(secs), int(coupling_range)
    )


def _compiles(work: int) -> bool:
    """Whether an operation of ``work`` stored entries runs (and compiles) numba kernels."""
    from ._kernels import use_numba

    return use_numba(work)


#: what fits when a MemoryError escapes without an estimate of its own
GENERIC_HINTS = (
    "solver='amg-cg' instead of 'direct'",
    "operator='matrix-free'",
    "a coarser discretization or a smaller horizon ratio",
    "backend='petsc' on more ranks (docs/petsc.md)",
)


def out_of_memory_message(exc: MemoryError) -> str:
    """Report a ``MemoryError`` in one line.

    Parameters
    ----------
    exc : MemoryError
        The error; pdlin's own :class:`~pdlin.errors.InsufficientMemoryError` is
        reported as it is.

    Returns
    -------
    str
        For a raw ``MemoryError``: its text, the memory available now and
        :data:`GENERIC_HINTS`.
    """
    if isinstance(exc, InsufficientMemoryError):
        return str(exc)
    detail = str(exc).strip()
    return (
        f"out of memory ({type(exc).__name__}{': ' + detail if detail else ''}); "
        f"{available_memory().describe()} available now; what would fit: "
        + "; ".join(GENERIC_HINTS)
    )
