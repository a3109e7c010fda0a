"""Distributed assembly and solve on PETSc (petsc4py), one MPI rank per point block.

``pdlin.solve(problem, backend="petsc")`` runs here.  Under
``mpiexec -n P`` every rank

1. partitions the points (recursive coordinate bisection, :func:`rcb_partition`;
   the same on every rank, no communication) and owns one contiguous range of
   them in the new numbering;
2. takes the prescribed DOFs, values and load vector of the constrained system
   (:func:`pdlin.system.point_system`: the functions of :mod:`pdlin.constraints`
   on the same points as the scipy path, without a global bond search);
3. grows its owned points by ``model.coupling_range`` horizons (a KD-tree over
   the coordinates: the point cloud itself is O(n) on every rank), finds the
   bonds of that *local cloud* only and assembles the model's stiffness there
   with the model's own routine, keeping the block rows of its owned points
   (their families and their neighbours' families are complete there, so those
   rows equal the rows of the global K); with symmetry planes the local cloud is
   mirrored and the rows are those of the reduced ``K_sym``
   (:func:`local_rows_mirrored`);
4. eliminates the prescribed DOFs from its own rows by the rule of
   :func:`pdlin.constraints.eliminate_dirichlet` (prescribed rows and columns
   become ``s I`` with ``s`` the mean free diagonal of the global K, the load
   ``b = f - K_fc u_c``), and hands its rows to PETSc in one CSR call
   (``MatMPIAIJSetPreallocationCSR`` / ``MatMPIBAIJSetPreallocationCSR``);
5. solves with KSP (CG + GAMG with the rigid-body near-null space, GMRES for
   nonsymmetric models, or LU through MUMPS) and checks the true residual.

No rank holds the whole K or the whole bond list.  The displacement, the
reactions and the point fields are gathered to every rank into a
:class:`PetscStaticResult` (a :class:`~pdlin.StaticResult`).

PETSc options: ``petsc_options={"ksp_monitor": None, "pc_gamg_threshold": 0.02}``
or the command line of the script (``python script.py -ksp_view``), or the
``PETSC_OPTIONS`` environment variable, all applied after pdlin's defaults.
"""

from __future__ import annotations

import dataclasses
import logging
import sys
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .._validation import integer, tolerance
from ..constraints import matrix_rows
from ..errors import ConvergenceError, InputError, InputTypeError, NoNeighborsError
from ..fields import deformation_gradient, small_strain
from ..geometry.bonds import Bonds, find_bonds, resolve_horizon
from ..geometry.cloud import PointCloud
from ..operators.symmetry import SymmetryPlane, SymmetryReduction, symmetry_reduction
from ..problem import StaticProblem, memory_hints, plan_memory
from ..resources import check_memory
from ..solvers.linear import SOLVERS, LinearSolveInfo, check_force_balance
from ..system import (
    ConstrainedSystem,
    StaticResult,
    mirror_reach,
    point_system,
)

__all__ = [
    "PetscStaticResult",
    "solve_petsc",
    "rcb_partition",
    "local_rows",
    "local_rows_mirrored",
    "petsc_available",
    "comm_rank_size",
    "PARTITIONS",
]

log = logging.getLogger(__name__)

#: point partitioners: recursive coordinate bisection, or contiguous ranges in the cloud's order
PARTITIONS = ("rcb", "natural")
#: PETSc matrix formats (block size = dim in both)
MAT_TYPES = ("aij", "baij")

_INSTALL_HINT = (
    'backend="petsc" needs petsc4py: install PETSc and petsc4py with scripts/install_petsc.sh '
    '(or pip install "pdlin[petsc]" against an installed PETSc; see docs/petsc.md)'
)


def _petsc() -> Any:
    """petsc4py.PETSc, initialized with the command line (so -ksp_* options apply)."""
    try:
        import petsc4py
    except ImportError as exc:
        raise ImportError(_INSTALL_HINT) from exc
    if "petsc4py.PETSc" not in sys.modules:
        petsc4py.init(sys.argv)
    from petsc4py import PETSc

    return PETSc


def _check_rank_memory(problem: Any, solver: str, size: int, say: Callable[[str], None]) -> None:
    """Refuse a run whose share per rank does not fit this rank's memory.

    The share is the scipy estimate of :func:`pdlin.problem.plan_memory` over ``size``
    ranks, checked before the bond search and assembly.
    """
    plan = plan_memory(problem, "direct" if solver == "direct" else "amg-cg")
    share = dataclasses.replace(plan, stages={k: -(-v // size) for k, v in plan.stages.items()})
    say(f"{share.summary()}, per rank of {size}")
    check_memory(
        f"this run on {size} rank(s) (its share per rank)",
        share.need,
        lambda: memory_hints(share),
    )


def petsc_available() -> bool:
    """Tell whether petsc4py imports (PETSc installed).

    Returns
    -------
    bool
        True when ``backend='petsc'`` can run.

    Examples
    --------
    >>> from pdlin.backends.petsc import petsc_available
    >>> isinstance(petsc_available(), bool)
    True
    """
    try:
        _petsc()
    except ImportError:
        return False
    return True


def comm_rank_size() -> tuple[int, int]:
    """Return ``(rank, size)`` of PETSc's ``COMM_WORLD``.

    Returns
    -------
    rank : int
        This process's rank (0 without petsc4py).
    size : int
        Number of ranks (1 without petsc4py).
    """
    if not petsc_available():
        return 0, 1
    PETSc = _petsc()
    return int(PETSc.COMM_WORLD.getRank()), int(PETSc.COMM_WORLD.getSize())


def rcb_partition(points: Any, nparts: int) -> np.ndarray:
    """Recursive coordinate bisection of points into ``nparts`` parts.

    Each part is split along its longest axis at the point count that keeps
    the parts' sizes proportional to the number of ranks they hold; the result
    depends on the coordinates only, so every rank computes the same labels.

    Parameters
    ----------
    points : (n, dim) array_like of float
    nparts : int
        Number of parts (ranks), ``1 <= nparts <= n``.

    Returns
    -------
    (n,) ndarray of int
        Part of each point; part sizes differ by at most one per bisection level.

    Examples
    --------
    >>> import numpy as np
    >>> from pdlin.backends.petsc import rcb_partition
    >>> pts = np.stack(np.meshgrid(np.arange(4.0), [0.0, 1.0], indexing="ij"), -1).reshape(-1, 2)
    >>> rcb_partition(pts, 2).tolist()   # split across x, the longest axis
    [0, 0, 0, 0, 1, 1, 1, 1]
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = pts[:, None]
    n = pts.shape[0]
    k = integer(nparts, "nparts", minimum=1)
    if k > n:
        raise InputError(f"nparts must be <= the number of points ({n}), got {k}")
    labels = np.zeros(n, dtype=np.int64)
    work = [(np.arange(n), 0, k)]
    while work:  # one entry per part (at most nparts), vectorized over points inside
        idx, first, parts = work.pop()
        if parts == 1:
            labels[idx] = first
            continue
        sub = pts[idx]
        axis = int(np.argmax(np.ptp(sub, axis=0)))
        left = parts // 2
        nl = (idx.size * left) // parts
        order = np.argsort(sub[:, axis], kind="stable")
        work.append((idx[order[:nl]], first, left))
        work.append((idx[order[nl:]], first + left, parts - left))
    return labels


@dataclasses.dataclass
class _Layout:
    """Point ownership: the new numbering and this rank's range."""

    perm: np.ndarray  # new -> old point index
    new_of_old: np.ndarray
    offsets: np.ndarray  # (size + 1,) point ranges per rank in the new numbering
    rank: int
    size: int

    @property
    def lo(self) -> int:
        return int(self.offsets[self.rank])

    @property
    def hi(self) -> int:
        return int(self.offsets[self.rank + 1])

    @property
    def owned(self) -> np.ndarray:
        """Old indices of the owned points, in the new order."""
        return self.perm[self.lo : self.hi]


def _layout(cloud: PointCloud, rank: int, size: int, partition: str) -> _Layout:
    n = cloud.n
    if size > n:
        raise InputError(
            f"the number of MPI ranks must be <= the number of points ({n}), got {size}"
        )
    if partition == "rcb":
        labels = rcb_partition(cloud.points, size)
    else:  # natural: contiguous ranges of the cloud's own order
        labels = (np.arange(n, dtype=np.int64) * size) // n
    perm = np.argsort(labels, kind="stable")
    counts = np.bincount(labels, minlength=size)
    offsets = np.zeros(size + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    new_of_old = np.empty(n, dtype=np.int64)
    new_of_old[perm] = np.arange(n)
    return _Layout(perm, new_of_old, offsets, rank, size)


def _reach(cloud: PointCloud, hor: np.ndarray, options: Mapping[str, Any]) -> float:
    """Radius containing every bond of every point (superset for non-spherical shapes)."""
    shape = options.get("shape", "sphere")
    rtol = float(options.get("rtol", 1e-9))
    r = float(np.max(hor))
    if shape in ("ellipsoid", "box") and options.get("axes") is not None:
        r = max(r, float(np.max(np.asarray(options["axes"], dtype=float))))
    if shape in ("cube", "box"):
        r *= float(np.sqrt(cloud.dim))
    return r * (1.0 + rtol) * (1.0 + 1e-9)


def _halo(cloud: PointCloud, owned: np.ndarray, hops: int, radius: float) -> np.ndarray:
    """Old indices of the points ``hops`` radius-steps or fewer from ``owned`` (owned excluded)."""
    tree = cKDTree(cloud.points)
    member = np.zeros(cloud.n, dtype=bool)
    member[owned] = True
    frontier = owned
    for _ in range(hops):  # coupling range: 1 or 2 steps
        if frontier.size == 0:
            break
        pairs = cKDTree(cloud.points[frontier]).sparse_distance_matrix(
            tree, radius, output_type="ndarray"
        )
        near = np.unique(pairs["j"])
        new = near[~member[near]]
        member[new] = True
        frontier = new
    member[owned] = False
    return np.flatnonzero(member)


def _local_cloud(cloud: PointCloud, index: np.ndarray) -> PointCloud:
    """``cloud.subset(index)``: the owned points first, then the halo.

    The lattice is dropped: in this order its stencil search would not give
    CSR-sorted bonds, so the KD-tree search runs (bond vectors then differ from
    the stencil's exact ones by rounding only, ~1e-16 relative).
    """
    return cloud.subset(index)


def _check_model_arrays(model: Any, n: int) -> None:
    """Refuse per-point model parameters on several ranks (they cannot be split generically)."""
    for name, val in vars(model).items():
        if isinstance(val, np.ndarray) and val.ndim >= 1 and val.shape[0] == n and n > 3:
            raise InputError(
                f"backend='petsc' on several ranks needs point-independent model parameters; "
                f"model.{name} has one value per point (shape {val.shape}): use materials "
                "(cloud.material) or run on one rank"
            )


def local_rows(
    model: Any,
    cloud: PointCloud,
    owned: np.ndarray,
    *,
    horizon: Any = None,
    bond_options: Mapping[str, Any] | None = None,
    timings: dict[str, float] | None = None,
) -> tuple[sp.bsr_array, np.ndarray, PointCloud, Bonds]:
    """Rows of the stiffness K for some points, without assembling the rest.

    The points ``owned`` are grown by ``model.coupling_range`` bond hops (a
    KD-tree radius search), the bonds of that local cloud are found with
    :func:`pdlin.find_bonds` and the model assembles its stiffness there; the
    owned points' families and their neighbours' families are complete in the
    local cloud, so their block rows equal those of the global K.

    Parameters
    ----------
    model : pdlin model
    cloud : PointCloud
    owned : (m,) array_like of int
        Points whose rows are wanted.
    horizon : float or (n,) array_like, optional
        As for :func:`pdlin.find_bonds` (default ``cloud.horizon``).
    bond_options : mapping, optional
        Other :func:`pdlin.find_bonds` keyword arguments (``ratio`` included).
    timings : dict, optional
        Receives the seconds spent in 'bonds' (halo and bond search) and 'assembly'.

    Returns
    -------
    rows : bsr_array of shape (m*dim, n*dim)
        The owned block rows, columns in the cloud's numbering.
    index : (m + h,) ndarray of int
        The local cloud: ``owned`` then the ``h`` halo points.
    local : PointCloud
        The local cloud.
    bonds : Bonds
        Its bonds (complete families for the first ``m`` points).

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.backends.petsc import local_rows
    >>> cloud = pdlin.grid((12, 12), spacing=0.1)
    >>> model = pdlin.LPS(E=1.0, nu=0.25)
    >>> rows, index, _, _ = local_rows(model, cloud, np.arange(30), bond_options={"ratio": 3.015})
    >>> K = pdlin.operators.assemble_stiffness(model, cloud, pdlin.find_bonds(cloud, ratio=3.015))
    >>> bool(abs(rows - K.tocsr()[:60]).max() < 1e-12 * abs(K).max()), index.size < cloud.n
    (True, True)
    """
    t0 = time.perf_counter()
    own, hor, opts, allow_isolated, index, local = _local_part(
        model, cloud, owned, horizon, bond_options
    )
    bonds = find_bonds(local, hor[index], allow_isolated=True, **opts)
    m = own.size
    _check_isolated(bonds.family_size[:m], own, cloud, allow_isolated)
    t1 = time.perf_counter()
    rows = _owned_block_rows(model.stiffness(local, bonds), index, m, cloud)
    if timings is not None:
        timings["bonds"] = timings.get("bonds", 0.0) + t1 - t0
        timings["assembly"] = timings.get("assembly", 0.0) + time.perf_counter() - t1
    return rows, index, local, bonds


def _local_part(
    model: Any,
    cloud: PointCloud,
    owned: Any,
    horizon: Any,
    bond_options: Mapping[str, Any] | None,
) -> tuple[np.ndarray, np.ndarray, dict[str, Any], bool, np.ndarray, PointCloud]:
    """Owned points grown by ``model.coupling_range`` bond reaches: the local cloud.

    Returns the owned indices, the cloud's horizons, the remaining find_bonds options,
    ``allow_isolated``, the local cloud's indices (owned first) and the local cloud.
    """
    own = np.asarray(owned, dtype=np.int64)
    opts = dict(bond_options or {})
    hor = resolve_horizon(cloud, horizon, opts.pop("ratio", None))
    opts.pop("method", None)
    allow_isolated = bool(opts.pop("allow_isolated", False))
    hops = int(getattr(model, "coupling_range", 1))
    halo = _halo(cloud, own, hops, _reach(cloud, hor, opts))
    index = np.concatenate([own, halo])
    return own, hor, opts, allow_isolated, index, _local_cloud(cloud, index)


def _check_isolated(
    family_size: np.ndarray, own: np.ndarray, cloud: PointCloud, allow_isolated: bool
) -> None:
    """Refuse owned points without bonds (as :func:`pdlin.find_bonds` does)."""
    if allow_isolated:
        return
    empty = np.flatnonzero(family_size == 0)
    if empty.size:
        p = int(own[empty[0]])
        raise NoNeighborsError(
            f"every point needs at least one bond, got {empty.size} isolated point(s), "
            f"first index {p} at {cloud.points[p].tolist()}; increase the horizon or pass "
            "allow_isolated=True"
        )


def _owned_block_rows(K: Any, index: np.ndarray, m: int, cloud: PointCloud) -> sp.bsr_array:
    """Keep the first ``m`` block rows of a local-cloud K, columns in the cloud's numbering."""
    d = cloud.dim
    K = (
        K
        if isinstance(K, sp.bsr_array) and K.blocksize == (d, d)
        else sp.bsr_array(K, blocksize=(d, d))
    )
    nnzb = int(K.indptr[m])
    # copies: the halo rows of the local K are freed with it
    return sp.bsr_array(
        (K.data[:nnzb].copy(), index[K.indices[:nnzb]], K.indptr[: m + 1].copy()),
        shape=(m * d, cloud.n * d),
        blocksize=(d, d),
    )


@dataclasses.dataclass
class _LocalPart:
    """Owned rows of this rank and what its point fields are computed on.

    The fields are evaluated on ``field_cloud`` / ``field_bonds`` with the displacement
    ``expand(u[index])`` (the local cloud itself, or its mirrored cloud with symmetry
    planes); their first ``m`` points are the owned ones.
    """

    rows: sp.bsr_array
    index: np.ndarray
    bonds: Bonds
    n_bonds: int
    family_size: np.ndarray
    model: Any
    field_cloud: PointCloud
    field_bonds: Bonds
    expand: Callable[[np.ndarray], np.ndarray]


def _identity(u: np.ndarray) -> np.ndarray:
    return u


def _plain_part(problem: Any, owned: np.ndarray) -> tuple[_LocalPart, float]:
    """Owned rows of K without symmetry planes, and the seconds of the bond search."""
    model, cloud = problem.model, problem.cloud
    m = owned.size
    if problem.bonds is not None:  # one rank, precomputed bonds: the global problem itself
        bonds = problem.bonds
        index, local = np.arange(cloud.n), cloud
        rows = sp.bsr_array(model.stiffness(cloud, bonds), blocksize=(cloud.dim,) * 2)
        t_bonds = 0.0
    else:
        part: dict[str, float] = {}
        rows, index, local, bonds = local_rows(
            model, cloud, owned, horizon=problem.horizon, bond_options=problem.bond_options,
            timings=part,
        )  # fmt: skip
        t_bonds = part["bonds"]
    fam = bonds.family_size[:m]
    lp = _LocalPart(rows, index, bonds, int(bonds.indptr[m]), fam, model, local, bonds, _identity)
    return lp, t_bonds


def local_rows_mirrored(
    model: Any,
    cloud: PointCloud,
    owned: Any,
    planes: Sequence[SymmetryPlane],
    *,
    horizon: Any = None,
    bond_options: Mapping[str, Any] | None = None,
    timings: dict[str, float] | None = None,
) -> tuple[sp.bsr_array, np.ndarray, SymmetryReduction | None, Bonds]:
    """Rows of the symmetry-reduced stiffness ``K_sym`` for some points.

    As :func:`local_rows`, on the local cloud's symmetry reduction: the local cloud (the
    owned points grown by ``model.coupling_range`` bond reaches) is mirrored across the
    planes that lie within the ghost layer's depth of it
    (:func:`pdlin.system.mirror_reach`).  Every augmented point that couples to an owned
    point is the image of a point of the local cloud (a reflection never brings two
    points of one side closer), so the owned rows equal those of the global ``K_sym``.

    Parameters
    ----------
    model : pdlin model
        The problem's model.
    cloud : PointCloud
        The modelled part (all points on one side of each plane).
    owned : (m,) array_like of int
        Points whose rows are wanted.
    planes : sequence of SymmetryPlane
        The planes, their ``side`` resolved (``MirrorCloud.planes``).
    horizon : float or (n,) array_like, optional
        As for :func:`pdlin.find_bonds` (default ``cloud.horizon``).
    bond_options : mapping, optional
        Other :func:`pdlin.find_bonds` keyword arguments (``ratio`` included).
    timings : dict, optional
        Receives the seconds spent in 'bonds' (halo and bond search) and 'assembly'.

    Returns
    -------
    rows : bsr_array of shape (m*dim, n*dim)
        The owned block rows of ``K_sym``, columns in the cloud's numbering.
    index : (m + h,) ndarray of int
        The local cloud: ``owned`` then the ``h`` halo points.
    reduction : SymmetryReduction or None
        The local cloud's reduction (None when no plane comes near the local cloud).
    bonds : Bonds
        The local cloud's bonds between real points.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.backends.petsc import local_rows_mirrored
    >>> cloud = pdlin.grid((12, 12), spacing=0.1)
    >>> prob = pdlin.StaticProblem(pdlin.LPS(E=1.0, nu=0.25), cloud,
    ...     bond_options={"ratio": 3.015}, symmetry=[pdlin.SymmetryPlane("x")],
    ...     dirichlet=[pdlin.Dirichlet("y-", 0.0)])
    >>> from pdlin.system import point_system
    >>> planes = point_system(prob).disc.mirror.planes
    >>> rows, index, _, _ = local_rows_mirrored(prob.model, cloud, np.arange(30), planes,
    ...     bond_options={"ratio": 3.015})
    >>> K = pdlin.system.constrained_system(prob).assemble()
    >>> bool(abs(rows - K.tocsr()[:60]).max() < 1e-12 * abs(K).max()), index.size < cloud.n
    (True, True)
    """
    t0 = time.perf_counter()
    own, hor, opts, allow_isolated, index, local = _local_part(
        model, cloud, owned, horizon, bond_options
    )
    m = own.size
    reach = mirror_reach(model, cloud, hor, opts) * (1.0 + 1e-9)
    near = tuple(
        p for p in planes if float(np.min(np.abs(p.signed_distance(local.points)))) <= reach
    )
    red: SymmetryReduction | None = None
    if near:
        red = symmetry_reduction(model, local, near, hor[index], {**opts, "allow_isolated": True})
        bonds, family = red.real_bonds, red.family_size
    else:
        bonds = find_bonds(local, hor[index], allow_isolated=True, **opts)
        family = bonds.family_size
    _check_isolated(family[:m], own, cloud, allow_isolated)
    t1 = time.perf_counter()
    K = red.stiffness() if red is not None else model.stiffness(local, bonds)
    rows = _owned_block_rows(K, index, m, cloud)
    if timings is not None:
        timings["bonds"] = timings.get("bonds", 0.0) + t1 - t0
        timings["assembly"] = timings.get("assembly", 0.0) + time.perf_counter() - t1
    return rows, index, red, bonds


def _mirrored_part(
    problem: Any, system: ConstrainedSystem, owned: np.ndarray
) -> tuple[_LocalPart, float]:
    """Owned rows of ``K_sym`` with symmetry planes, and the seconds of the bond search."""
    model, cloud = problem.model, problem.cloud
    m = owned.size
    part: dict[str, float] = {}
    rows, index, red, bonds = local_rows_mirrored(
        model, cloud, owned, system.disc.mirror.planes, horizon=problem.horizon,
        bond_options=problem.bond_options, timings=part,
    )  # fmt: skip
    n_bonds = int(bonds.indptr[m])
    if red is None:
        lp = _LocalPart(
            rows, index, bonds, n_bonds, bonds.family_size[:m], model, cloud.subset(index),
            bonds, _identity,
        )  # fmt: skip
    else:
        lp = _LocalPart(
            rows, index, bonds, n_bonds, red.family_size[:m], red.model, red.mirror.cloud,
            red.bonds, red.expand,
        )  # fmt: skip
    return lp, part["bonds"]


@dataclasses.dataclass
class PetscStaticResult(StaticResult):
    """A :class:`~pdlin.StaticResult` of the PETSc backend.

    ``bonds`` holds this rank's local-cloud bonds (the owned points first); the
    point fields were computed per rank on the owned points and gathered, so
    :meth:`fields`, :meth:`deformation_gradient` and :meth:`stress` are plain
    lookups (no collective call: rank 0 alone may write them).
    """

    point_fields: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)

    def deformation_gradient(self) -> np.ndarray:
        """Return the gathered nonlocal deformation gradient.

        Returns
        -------
        (n, dim, dim) ndarray
            ``F`` per point.

        Raises
        ------
        InputError
            When a rank could not compute it (singular shape tensor).
        """
        if "deformation_gradient" not in self.point_fields:
            raise InputError("the deformation gradient was not computed (singular shape tensor)")
        d = self.u.shape[1]
        return self.point_fields["deformation_gradient"].reshape(-1, d, d)

    def stress(self) -> np.ndarray:
        """Return the gathered model stress.

        Returns
        -------
        (n, dim, dim) ndarray
            Stress per point.

        Raises
        ------
        InputError
            When the model gave no stress.
        """
        if "stress" not in self.point_fields:
            raise InputError(f"model {type(self.problem.model).__name__} gave no stress")
        d = self.u.shape[1]
        return self.point_fields["stress"].reshape(-1, d, d)

    def fields(self) -> dict[str, np.ndarray]:
        """Collect the gathered point fields (as :meth:`pdlin.StaticResult.fields`).

        Returns
        -------
        dict of str to ndarray
            One row per point.
        """
        out: dict[str, np.ndarray] = {
            "displacement": self.u,
            "reaction": self.reactions,
            "family_size": self.point_fields["family_size"],
            "volume": np.asarray(self.problem.cloud.volumes),
            "material": np.asarray(self.problem.cloud.material, dtype=float),
        }
        if "deformation_gradient" in self.point_fields:
            F = self.point_fields["deformation_gradient"]
            out["deformation_gradient"] = F
            out["strain"] = small_strain(self.deformation_gradient()).reshape(F.shape[0], -1)
        if "stress" in self.point_fields:
            out["stress"] = self.point_fields["stress"]
        return out

    def summary(self) -> dict[str, Any]:
        """Summarize the run as plain data, with the global bond count and the ranks.

        Returns
        -------
        dict
            :meth:`pdlin.StaticResult.summary` plus ``ranks``.
        """
        s = super().summary()
        s["bonds"] = int(self.info.get("n_bonds", s["bonds"]))
        s["ranks"] = int(self.info.get("ranks", 1))
        return s


#: pdlin solver name -> (KSP type, PC type) for symmetric / nonsymmetric operators
_KSP = {
    "amg-cg": ("cg", "gamg"),
    "amg-gmres": ("gmres", "gamg"),
    "cg": ("cg", "none"),
    "jacobi-cg": ("cg", "jacobi"),
    "gmres": ("gmres", "none"),
    "ilu-gmres": ("gmres", "bjacobi"),
    "direct": ("preonly", "lu"),
}


def _factor_package(PETSc: Any, size: int) -> str:
    for pkg in ("mumps", "superlu_dist"):
        if PETSc.Sys.hasExternalPackage(pkg):
            return pkg
    if size == 1:
        return "petsc"
    raise InputError(
        "solver='direct' on several ranks needs a PETSc built with MUMPS or SuperLU_DIST, "
        "got neither; use solver='amg-cg'"
    )


class _Gather:
    """Gathers this rank's rows of a distributed vector to every rank, old numbering."""

    def __init__(self, PETSc: Any, layout: _Layout, width: int) -> None:
        self.PETSc = PETSc
        self.layout = layout
        self.width = width
        n_own = layout.hi - layout.lo
        n = layout.perm.size
        self.vec = PETSc.Vec().createMPI((n_own * width, n * width), comm=PETSc.COMM_WORLD)
        self.scatter, self.full = PETSc.Scatter.toAll(self.vec)

    def __call__(self, local: np.ndarray) -> np.ndarray:
        self.vec.setArray(np.ascontiguousarray(local, dtype=float).reshape(-1))
        return self.gather_vec(self.vec)

    def gather_vec(self, vec: Any) -> np.ndarray:
        PETSc = self.PETSc
        self.scatter.scatter(vec, self.full, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)
        new = self.full.getArray().reshape(-1, self.width)
        out = np.empty_like(new)
        out[self.layout.perm] = new
        return out

    def destroy(self) -> None:
        for obj in (self.scatter, self.full, self.vec):
            obj.destroy()


def _global_sum(PETSc: Any, value: float) -> float:
    """Sum of one float over all ranks (a PETSc Vec with one entry per rank)."""
    v = PETSc.Vec().createMPI((1, PETSc.DECIDE), comm=PETSc.COMM_WORLD)
    v.setArray(np.array([value], dtype=float))
    s = float(v.sum())
    v.destroy()
    return s


def solve_petsc(
    problem: Any,
    solver: str = "auto",
    *,
    rtol: float = 1e-8,
    maxiter: int | None = None,
    petsc_options: Mapping[str, Any] | None = None,
    partition: str = "rcb",
    mat_type: str = "aij",
    progress: Callable[[str], None] | None = None,
) -> Any:
    """Solve a static problem on PETSc, distributed over the MPI ranks of ``COMM_WORLD``.

    Called by ``pdlin.solve(problem, backend="petsc", ...)``; run the script
    under ``mpiexec -n P`` for P ranks.  Every rank must call it.

    Parameters
    ----------
    problem : StaticProblem
        A linear problem, with or without symmetry planes; on several ranks with
        ``horizon`` / ``bond_options`` (no precomputed bonds) and point-independent
        model parameters.
    solver : str
        pdlin's names: 'auto' (CG + GAMG, GMRES + GAMG for nonsymmetric
        models), 'amg-cg', 'amg-gmres', 'cg', 'jacobi-cg', 'gmres',
        'ilu-gmres' (block Jacobi + ILU(0)), 'direct' (LU through MUMPS, else
        SuperLU_DIST, else PETSc's serial LU on one rank).
    rtol : float
        Relative tolerance of the unpreconditioned residual, in ``(0, 1)``.
    maxiter : int, optional
        Iteration limit (default 10,000).
    petsc_options : mapping, optional
        PETSc options without the leading dash (``{"ksp_monitor": None}``),
        applied after pdlin's defaults and removed afterwards; command-line
        and ``PETSC_OPTIONS`` options apply too.
    partition : {'rcb', 'natural'}
        Recursive coordinate bisection, or contiguous ranges of the cloud's order.
    mat_type : {'aij', 'baij'}
        MATMPIAIJ or MATMPIBAIJ, block size dim in both (GAMG needs 'aij').
    progress : callable, optional
        Called with a message at each stage.

    Returns
    -------
    PetscStaticResult
        A :class:`~pdlin.StaticResult` holding the gathered ``u`` and
        reactions on every rank; ``info`` names the KSP / PC, the ranks, the
        local rows per rank and the bond count.

    Raises
    ------
    ImportError
        When petsc4py is not installed.
    InputError
        For invalid arguments, a nonlinear model, ``mat_type='baij'`` with GAMG, or
        precomputed bonds / per-point model parameters on several ranks.
    FloatingBodyError
        When the conditions leave a rigid motion free.
    ConvergenceError
        When KSP diverges or the true residual misses ``10 rtol`` (1e-8 for 'direct').
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    rtol, maxiter = _check_arguments(problem, solver, rtol, maxiter, partition, mat_type,
                                     petsc_options)  # fmt: skip
    PETSc = _petsc()
    comm = PETSc.COMM_WORLD
    rank, size = int(comm.getRank()), int(comm.getSize())
    if size > 1 and problem.bonds is not None:
        raise InputError(
            "backend='petsc' on several ranks finds the bonds per rank: give the problem a "
            "horizon / bond_options instead of precomputed bonds"
        )
    say = progress or (lambda msg: None)
    _check_rank_memory(problem, solver, size, say)
    model, cloud = problem.model, problem.cloud
    d, n = cloud.dim, cloud.n
    if size > 1:
        _check_model_arrays(model, n)
    timings: dict[str, float] = {}
    t_start = time.perf_counter()

    # -- ownership and the constrained system's point data (O(n) on every rank) ---------
    say(f"bonds ({size} rank(s), {partition} partition)")
    t0 = time.perf_counter()
    layout = _layout(cloud, rank, size, partition)
    system = point_system(problem)
    owned = layout.owned
    m = owned.size
    timings["bonds"] = time.perf_counter() - t0

    say("bonds and assembly of the owned rows")
    t0 = time.perf_counter()
    if problem.symmetry:
        lp, t_bonds = _mirrored_part(problem, system, owned)
    else:
        lp, t_bonds = _plain_part(problem, owned)
    timings["bonds"] += t_bonds
    t0 += t_bonds
    elim = _eliminate_owned(PETSc, lp.rows, owned, system)
    A = _petsc_matrix(PETSc, elim.data, elim.cols, elim.indptr, layout, mat_type)
    n_bonds_local = lp.n_bonds
    nnz_local = int(elim.indptr[-1]) * d * d
    del elim.data, lp.rows  # PETSc holds its copy
    timings["assembly"] = time.perf_counter() - t0

    ks = _ksp_solve(PETSc, A, elim.b_loc, cloud.points[owned], solver, model, rtol, maxiter,
                    mat_type, petsc_options, size, say)  # fmt: skip
    timings["setup"] = ks.setup_time
    timings["solve"] = ks.solve_time

    # -- gather to every rank (old numbering) ---------------------------------------------
    gather = _Gather(PETSc, layout, d)
    xg = gather.gather_vec(ks.x).reshape(-1)
    bg = gather.gather_vec(ks.b).reshape(-1)
    u = system.expand(xg)
    flat = u.reshape(-1)
    reac_loc = np.zeros(m * d)
    pres = elim.pres_rows
    reac_loc[pres] = elim.K_pres @ flat - system.f_ext[elim.row_dofs[pres]]
    reac = gather(reac_loc).reshape(n, d)
    point_fields = _point_fields(lp, u[lp.index], m, gather)
    n_bonds = int(round(_global_sum(PETSc, float(n_bonds_local))))
    rows_per_rank = gather_counts(PETSc, m * d, size)
    gather.destroy()
    ks.destroy()
    A.destroy()

    lin = LinearSolveInfo(
        xg, ks.name, ks.its, ks.residuals, ks.rr, ks.setup_time, ks.solve_time, ks.info
    )
    if ks.reason <= 0 or not np.isfinite(ks.rr) or ks.rr > ks.tol:
        raise ConvergenceError(
            f"{ks.name} ({ks.info['ksp_type']} + {ks.info['pc_type']}): no convergence to "
            f"rtol={rtol:.1e} after {ks.its} iterations (true relative residual {ks.rr:.3e}, "
            f"KSP reason {ks.reason})"
        )
    with warnings.catch_warnings():
        if rank != 0:
            warnings.simplefilter("ignore")
        check_force_balance(lin, bg, reac, system.f_ext)
    timings["total"] = time.perf_counter() - t_start
    info = {
        "solver": ks.name,
        "backend": "petsc",
        **ks.info,
        "ranks": size,
        "partition": partition,
        "mat_type": mat_type,
        "local_rows": m * d,
        "rows_per_rank": rows_per_rank,
        "local_points_with_halo": int(lp.index.size),
        "local_nnz": nnz_local,
        "n_bonds": n_bonds,
        "model": model.describe(),
        "operator": "assembled",
        "operator_reason": "the PETSc backend assembles K",
    }
    return PetscStaticResult(
        problem=problem,
        bonds=lp.bonds,
        u=u,
        converged=True,
        n_iter=ks.its,
        residuals=ks.residuals,
        relative_residual=ks.rr,
        timings=timings,
        reactions=reac,
        prescribed_dofs=system.dofs,
        info=info,
        point_fields=point_fields,
    )


def _check_arguments(
    problem: StaticProblem,
    solver: str,
    rtol: float,
    maxiter: int | None,
    partition: str,
    mat_type: str,
    petsc_options: Any,
) -> tuple[float, int]:
    """Validate :func:`solve_petsc`'s arguments; return ``rtol`` and ``maxiter``."""
    if solver not in SOLVERS:
        raise InputError(f"solver must be one of {SOLVERS}, got {solver!r}")
    rtol = tolerance(rtol, "rtol")
    maxiter = 10_000 if maxiter is None else integer(maxiter, "maxiter", minimum=1)
    if partition not in PARTITIONS:
        raise InputError(f"partition must be one of {PARTITIONS}, got {partition!r}")
    if mat_type not in MAT_TYPES:
        raise InputError(f"mat_type must be one of {MAT_TYPES}, got {mat_type!r}")
    if petsc_options is not None and not isinstance(petsc_options, Mapping):
        raise InputTypeError(
            f"petsc_options must be a mapping of PETSc option names to values, got "
            f"{type(petsc_options).__name__}"
        )
    if getattr(problem.model, "nonlinear", False):
        raise InputError(
            f"backend='petsc' solves linear problems; model {type(problem.model).__name__} is "
            "nonlinear (use pdlin.solve_nonlinear)"
        )
    return rtol, maxiter


@dataclasses.dataclass
class _Eliminated:
    """Eliminated block rows of this rank (new column numbering not yet applied)."""

    data: np.ndarray  # (nnzb, d, d) eliminated blocks
    cols: np.ndarray  # (nnzb,) block columns, the cloud's numbering
    indptr: np.ndarray  # (m + 1,)
    b_loc: np.ndarray  # (m*d,) right-hand side of the owned rows
    row_dofs: np.ndarray  # (m*d,) global DOFs of the owned rows
    pres_rows: np.ndarray  # owned rows that are prescribed
    K_pres: sp.csr_array  # K's prescribed owned rows, kept for the reactions


def _eliminate_owned(
    PETSc: Any, rows: sp.bsr_array, owned: np.ndarray, system: ConstrainedSystem
) -> _Eliminated:
    """Eliminate the system's prescribed DOFs from this rank's block rows of K.

    The rule of :func:`pdlin.constraints.eliminate_dirichlet`: prescribed rows and columns
    become ``s I`` with ``s`` the mean |diagonal| of the free DOFs over all ranks, the load
    ``b = f - K_fc u_c`` (0 on the prescribed rows, as
    :meth:`~pdlin.system.ConstrainedSystem.eliminate` sets it).
    """
    d = system.dim
    rows = sp.bsr_array(rows)
    rows.sort_indices()
    m = owned.size
    free = system.free
    uc = system.prescribed()
    row_dofs = (owned[:, None] * d + np.arange(d)).reshape(-1)
    b_loc = system.f_ext[row_dofs] - rows @ uc
    pres_rows = np.flatnonzero(~free[row_dofs])
    K_pres = matrix_rows(rows, pres_rows)  # prescribed rows, kept for the reactions
    brow = np.repeat(np.arange(m), np.diff(rows.indptr))
    cols = rows.indices.astype(np.int64)
    isdiag = owned[brow] == cols
    pos = np.flatnonzero(isdiag)
    diag = np.einsum("bkk->bk", rows.data[pos]).reshape(-1)
    diag_dofs = (owned[brow[pos]][:, None] * d + np.arange(d)).reshape(-1)
    n_free = int(free.sum())
    s_sum = float(np.abs(diag[free[diag_dofs]]).sum())
    s = _global_sum(PETSc, s_sum) / n_free if n_free else 1.0
    fr = free.reshape(-1, d)[owned[brow]]
    fc = free.reshape(-1, d)[cols]
    data = rows.data  # eliminated in place: rows is this rank's own copy
    data *= fr[:, :, None]
    data *= fc[:, None, :]
    for k in range(d):  # identity s on the prescribed diagonal entries
        fixed = ~free[owned[brow[pos]] * d + k]
        data[pos[fixed], k, k] = s
    b_loc[pres_rows] = 0.0
    return _Eliminated(data, cols, rows.indptr, b_loc, row_dofs, pres_rows, K_pres)


def _petsc_matrix(
    PETSc: Any,
    data: np.ndarray,
    cols: np.ndarray,
    indptr: np.ndarray,
    layout: _Layout,
    mat_type: str,
) -> Any:
    """Create the distributed matrix: owned block rows in the new numbering, one CSR call."""
    m = layout.hi - layout.lo
    d = data.shape[1]
    N = layout.perm.size * d
    comm = PETSc.COMM_WORLD
    new_cols = layout.new_of_old[cols]
    A_loc = sp.bsr_array((data, new_cols, indptr), shape=(m * d, N), blocksize=(d, d))
    A_loc.sort_indices()
    if mat_type == "baij":
        A = PETSc.Mat().createBAIJ(
            size=((m * d, N), (m * d, N)),
            bsize=d,
            csr=(
                A_loc.indptr.astype(PETSc.IntType),
                A_loc.indices.astype(PETSc.IntType),
                A_loc.data.reshape(-1),
            ),
            comm=comm,
        )
    else:
        C = A_loc.tocsr()
        C.sort_indices()
        A = PETSc.Mat().createAIJ(
            size=((m * d, N), (m * d, N)),
            bsize=d,
            csr=(C.indptr.astype(PETSc.IntType), C.indices.astype(PETSc.IntType), C.data),
            comm=comm,
        )
        del C
    A.assemble()
    return A


@dataclasses.dataclass
class _KspSolve:
    """A KSP solve of :func:`solve_petsc`: the PETSc objects and what it reports."""

    name: str
    x: Any
    b: Any
    its: int
    reason: int
    rr: float
    residuals: list[float]
    info: dict[str, Any]
    tol: float
    setup_time: float
    solve_time: float
    objects: list[Any]

    def destroy(self) -> None:
        """Free the PETSc objects (KSP, vectors, near-null space)."""
        for obj in self.objects:
            obj.destroy()


def _ksp_solve(
    PETSc: Any,
    A: Any,
    b_loc: np.ndarray,
    points: np.ndarray,
    solver: str,
    model: Any,
    rtol: float,
    maxiter: int,
    mat_type: str,
    petsc_options: Mapping[str, Any] | None,
    size: int,
    say: Callable[[str], None],
) -> _KspSolve:
    """Set up KSP on ``A`` (pdlin's defaults, then the options) and solve for ``b_loc``."""
    comm = PETSc.COMM_WORLD
    symmetric = bool(getattr(model, "symmetric", True))
    name = solver
    if name == "auto":
        name = "amg-cg" if symmetric else "amg-gmres"
    ksp_type, pc_type = _KSP[name]
    if mat_type == "baij" and pc_type == "gamg":
        raise InputError(
            f"mat_type='baij' does not work with solver {name!r}: PETSc's GAMG needs an AIJ "
            "matrix (MatCreateGraph); use mat_type='aij' (block size dim) or a solver without "
            "GAMG ('direct', 'jacobi-cg', 'ilu-gmres')"
        )
    if not symmetric and ksp_type == "cg":
        ksp_type = "gmres"
    say(f"solve (PETSc {ksp_type} + {pc_type}, {size} rank(s))")
    t0 = time.perf_counter()
    ksp = PETSc.KSP().create(comm=comm)
    ksp.setOperators(A)
    ksp.setType(ksp_type)
    pc = ksp.getPC()
    pc.setType(pc_type)
    factor = None
    ns = None
    if pc_type == "lu":
        factor = _factor_package(PETSc, size)
        pc.setFactorSolverType(factor)
    else:
        ksp.setTolerances(rtol=rtol, atol=0.0, max_it=maxiter)
        if ksp_type == "gmres":
            ksp.setGMRESRestart(min(100, maxiter))
        if pc_type == "gamg":
            d = points.shape[1]
            m = points.shape[0]
            coords = PETSc.Vec().createMPI((m * d, A.getSize()[0]), bsize=d, comm=comm)
            coords.setArray(np.ascontiguousarray(points).reshape(-1))
            ns = PETSc.NullSpace().createRigidBody(coords)
            A.setNearNullSpace(ns)
            coords.destroy()
    ksp.setConvergenceHistory()
    bvec, x = _ksp_setup(PETSc, ksp, A, b_loc, ksp_type, pc_type, petsc_options)
    t1 = time.perf_counter()
    nb = bvec.norm()
    if nb > 0:
        try:
            ksp.solve(bvec, x)
        except PETSc.Error as exc:
            raise ConvergenceError(
                f"petsc-{name} ({ksp.getType()} + {ksp.getPC().getType()}) failed: {exc}"
            ) from exc
    t2 = time.perf_counter()
    reason = int(ksp.getConvergedReason()) if nb > 0 else 1
    its = int(ksp.getIterationNumber()) if nb > 0 else 0
    r = bvec.duplicate()
    A.mult(x, r)
    r.aypx(-1.0, bvec)  # r = b - A x
    rr = float(r.norm() / nb) if nb > 0 else 0.0
    hist = np.asarray(ksp.getConvergenceHistory(), dtype=float) if nb > 0 else np.zeros(0)
    residuals = (hist / nb).tolist() if nb > 0 and hist.size else [rr]
    info_ksp = {
        "ksp_type": ksp.getType(),
        "pc_type": ksp.getPC().getType(),
        "converged_reason": reason,
    }
    if factor is not None:
        info_ksp["factor_package"] = ksp.getPC().getFactorSolverType()
    tol = 1e-8 if pc_type == "lu" else 10.0 * rtol
    objects = [ksp, bvec, x, r] + ([ns] if ns is not None else [])
    return _KspSolve(f"petsc-{name}", x, bvec, its, reason, rr, residuals, info_ksp, tol,
                     t1 - t0, t2 - t1, objects)  # fmt: skip


def _ksp_setup(
    PETSc: Any,
    ksp: Any,
    A: Any,
    b_loc: np.ndarray,
    ksp_type: str,
    pc_type: str,
    petsc_options: Mapping[str, Any] | None,
) -> tuple[Any, Any]:
    """Apply the options, make the vectors and set KSP up; return ``(b, x)``."""
    opts = PETSc.Options()
    given = {}
    for key, val in dict(petsc_options or {}).items():
        if not isinstance(key, str) or not key.lstrip("-"):
            raise InputError(f"petsc_options keys must be PETSc option names, got {key!r}")
        given[key.lstrip("-")] = "" if val is None else str(val)
    for key, val in given.items():
        opts.setValue(key, val)
    try:
        ksp.setFromOptions()
        # stop on the true (unpreconditioned) residual, as the scipy solvers do, unless the
        # options chose another Krylov method or norm
        if pc_type != "lu" and ksp.getType() == ksp_type and not opts.hasName("ksp_norm_type"):
            if ksp_type == "gmres" and not opts.hasName("ksp_pc_side"):
                ksp.setPCSide(PETSc.PC.Side.RIGHT)
            ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        bvec = A.createVecLeft()
        bvec.setArray(b_loc)
        x = A.createVecRight()
        x.set(0.0)
        ksp.setUp()
    except PETSc.Error as exc:
        raise InputError(
            f"PETSc could not set up {ksp.getType()} + {ksp.getPC().getType()} with "
            f"petsc_options={given} and the command-line / PETSC_OPTIONS options: {exc}"
        ) from exc
    finally:
        for key in given:
            opts.delValue(key)
    return bvec, x


def gather_counts(PETSc: Any, value: int, size: int) -> list[int]:
    """Gather one integer per rank to every rank (collective).

    Parameters
    ----------
    PETSc : module
        ``petsc4py.PETSc``.
    value : int
        This rank's integer.
    size : int
        Number of ranks.

    Returns
    -------
    list of int
        The ``size`` integers in rank order.
    """
    v = PETSc.Vec().createMPI((1, size), comm=PETSc.COMM_WORLD)
    v.setArray(np.array([float(value)]))
    sc, full = PETSc.Scatter.toAll(v)
    sc.scatter(v, full, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)
    out = [int(round(c)) for c in full.getArray()]
    for obj in (sc, full, v):
        obj.destroy()
    return out


def _point_fields(
    lp: _LocalPart, u_local: np.ndarray, m: int, gather: _Gather
) -> dict[str, np.ndarray]:
    """Family size, F and stress of the owned points, gathered (collective).

    Computed on the local part's field cloud (the local cloud, or its mirrored cloud with
    symmetry planes, whose first ``m`` points are the owned ones).
    """
    PETSc = gather.PETSc
    d = lp.field_cloud.dim
    out: dict[str, np.ndarray] = {}
    fam = np.asarray(lp.family_size, dtype=float)
    out["family_size"] = _gather_width(PETSc, gather.layout, fam[:, None]).reshape(-1)
    u_field = lp.expand(u_local)

    def collective(name: str, what: str, compute: Any) -> None:
        # every rank computes its owned rows; written only when no rank failed
        try:
            vals = np.asarray(compute())[:m].reshape(m, d * d)
            ok = 1.0
        except (InputError, np.linalg.LinAlgError) as exc:
            log.warning("%s not written: %s", what, exc)
            vals, ok = np.zeros((m, d * d)), 0.0
        if _global_sum(PETSc, 1.0 - ok) == 0.0:
            out[name] = _gather_width(PETSc, gather.layout, vals)

    collective(
        "deformation_gradient",
        "strain",
        lambda: deformation_gradient(lp.field_cloud, lp.field_bonds, u_field, n_owners=m),
    )
    if hasattr(lp.model, "stress"):
        collective(
            "stress", "stress", lambda: lp.model.stress(lp.field_cloud, lp.field_bonds, u_field)
        )
    return out


def _gather_width(PETSc: Any, layout: _Layout, local: np.ndarray) -> np.ndarray:
    g = _Gather(PETSc, layout, local.shape[1])
    try:
        return g(local)
    finally:
        g.destroy()
