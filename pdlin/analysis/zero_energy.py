"""Zero-energy-mode analysis: near-zero eigenvalue counts and checkerboard energies.

Two complementary measures of the zero-energy modes of Javaheri, Luo, Lakshmanan &
Sundararaghavan (2022, Sec. II.B) and Luo & Sundararaghavan (2018):

* :func:`count_zero_modes` counts the eigenvalues of K below
  ``tol * λ_max`` and subtracts the rigid-body modes (dense ``eigvalsh``
  below ``dense_limit`` DOFs, shift-invert Lanczos above).  On free finite
  bodies with their own truncated shape tensors every control shows the
  rigid modes only (observed for every control in pdlin's reference
  computations); the counts discriminate
  on constrained systems (``dofs=`` the real DOFs of a shadow layer).
* :func:`checkerboard_energy_ratio` compares the Rayleigh quotient of the
  modes ``s(x) (-1)^{θ·idx}``, ``θ ∈ {0, 1}^d``, ``θ ≠ 0``, with that of the
  smooth mode ``s = Π sin(π x̂_k)`` (pdlin's measure): a ratio of 1 means the
  operator cannot tell the checkerboard from the smooth field.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import InputError, ModelError, ShapeError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud

__all__ = [
    "ZeroEnergyReport",
    "CheckerboardReport",
    "count_zero_modes",
    "checkerboard_energy_ratio",
    "compare_controls",
    "periodic_lattice_bonds",
]

log = logging.getLogger(__name__)

_N_RIGID = {1: 1, 2: 3, 3: 6}


@dataclass(frozen=True)
class ZeroEnergyReport:
    """Near-zero eigenvalues of a stiffness.

    Attributes
    ----------
    n_zero : int
        Eigenvalues ``<= tol * lambda_max``.
    n_rigid : int
        Rigid-body modes expected (0 for constrained systems).
    n_spurious : int
        ``n_zero - n_rigid`` (zero-energy modes beyond rigid motion).  Negative when
        the operator resists rigid motions it should not: the ``'springs'`` and
        ``'ads'`` correspondence controls act on the full displacement vector and
        resist rotations, so a free 2D body has ``n_spurious = -1`` (3D: -3).
    eigenvalues : ndarray
        The smallest eigenvalues computed (ascending).
    lambda_max : float
        Largest eigenvalue of K (the scale of ``tol``).
    method : str
        'dense' or 'shift-invert'.
    tol : float
        Zero threshold relative to ``lambda_max``.
    """

    n_zero: int
    n_rigid: int
    n_spurious: int
    eigenvalues: np.ndarray
    lambda_max: float
    method: str
    tol: float


@dataclass(frozen=True)
class CheckerboardReport:
    """Rayleigh-quotient ratios ``R(checkerboard) / R(smooth)``.

    ``ratios[(theta, k)]`` for ``theta`` a 0/1 tuple (π on the axes with 1)
    and displacement component ``k``; ``min_ratio`` is the smallest.
    """

    ratios: dict[tuple[tuple[int, ...], int], float] = field(default_factory=dict)
    min_ratio: float = float("nan")


def count_zero_modes(
    K: Any,
    *,
    dim: int | None = None,
    n_rigid: int | None = None,
    dofs: Any = None,
    tol: float = 1e-10,
    dense_limit: int = 3000,
    k: int | None = None,
) -> ZeroEnergyReport:
    """Count near-zero eigenvalues of a symmetric PSD stiffness.

    Parameters
    ----------
    K : sparse array or ndarray (N, N)
        Symmetric positive semi-definite stiffness.
    dim : int, optional
        Spatial dimension; sets ``n_rigid`` for a free body (1 / 3 / 6).
    n_rigid : int, optional
        Expected rigid modes (overrides ``dim``; 0 for constrained systems).
    dofs : (m,) array_like of int, optional
        Restrict K to these DOFs (e.g. the real DOFs of a shadow layer).
    tol : float
        Zero threshold relative to ``lambda_max`` (pdlin's default 1e-10).
    dense_limit : int
        Dense ``eigvalsh`` up to this many DOFs, shift-invert ``eigsh`` above.
    k : int, optional
        Eigenvalues computed by the sparse path (default ``n_rigid + 20``).

    Returns
    -------
    ZeroEnergyReport
        Zero count, expected rigid modes, spurious count, smallest eigenvalues,
        ``lambda_max`` and the eigen-solver used.

    Raises
    ------
    ShapeError
        If ``K`` (restricted to ``dofs``) is not square.
    InputError
        If neither ``dim`` nor ``n_rigid`` is given, ``dim`` is not 1-3 or
        ``tol <= 0``.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((9,), spacing=1.0)
    >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
    >>> K = pdlin.operators.assemble_stiffness(pdlin.Correspondence(E=1.0), cloud, bonds)
    >>> count_zero_modes(K, dim=1).n_spurious   # free bar: one rigid mode only
    0
    """
    A = K
    if dofs is not None:
        idx = np.asarray(dofs, dtype=np.intp)
        A = sp.csr_array(K)[idx][:, idx] if sp.issparse(K) else np.asarray(K)[np.ix_(idx, idx)]
    if A.shape[0] != A.shape[1]:
        raise ShapeError(f"K must be square, got shape {A.shape}")
    n = A.shape[0]
    if n_rigid is None:
        if dim is None:
            raise InputError("count_zero_modes needs dim or n_rigid, got neither")
        if dim not in _N_RIGID:
            raise InputError(f"dim must be 1, 2 or 3, got {dim}")
        n_rigid = 0 if dofs is not None else _N_RIGID[dim]
    if not tol > 0:
        raise InputError(f"tol must be > 0, got {tol}")
    if n <= dense_limit:
        dense = A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)
        ev = np.linalg.eigvalsh(0.5 * (dense + dense.T))
        lmax = float(ev[-1])
        method = "dense"
    else:
        Ac = sp.csc_array(A)
        lmax = float(spla.eigsh(Ac, k=1, which="LA", return_eigenvectors=False)[0])
        kk = min(n - 2, (n_rigid + 20) if k is None else int(k))
        sigma = -1e-6 * lmax
        ev = np.sort(spla.eigsh(Ac, k=kk, sigma=sigma, which="LM", return_eigenvectors=False))
        method = "shift-invert"
        if np.all(ev <= tol * lmax):
            log.warning("all %d computed eigenvalues are zero: the count is a lower bound", kk)
    n_zero = int(np.sum(ev <= tol * lmax))
    return ZeroEnergyReport(
        n_zero, int(n_rigid), n_zero - int(n_rigid), ev[: max(n_zero + 5, 10)], lmax, method, tol
    )


def periodic_lattice_bonds(cloud: PointCloud, ratio: float, influence: Any = "constant") -> Bonds:
    """Build the bonds of a fully periodic lattice (every family intact).

    For symbol and kernel studies.

    ``cloud`` must be a complete :func:`pdlin.grid` with equal spacing ``h``; point ``a``
    bonds to ``a + p (mod n)`` for every integer offset ``|p| h <= ratio h`` with the
    unwrapped bond vector ``ξ = p h``.  Each axis needs more than ``2 floor(ratio)`` points
    (no neighbour twice).  On such a lattice the kernel of K is spanned by the lattice
    waves ``exp(i θ·a)`` at the zeros of the gradient symbol
    (:func:`pdlin.models.gradient_symbol`).

    Parameters
    ----------
    cloud : PointCloud
        A complete :func:`pdlin.grid` cloud with equal spacing on every axis.
    ratio : float
        Horizon over spacing, ``delta / h`` > 0.
    influence : str or callable
        Influence function (name or ``f(length, horizon)``), as for
        :func:`pdlin.find_bonds`.

    Returns
    -------
    Bonds
        Periodic bonds in CSR order, with horizon ``ratio h`` at every point.

    Raises
    ------
    ModelError
        If ``cloud`` is not a complete grid with equal spacing.
    InputError
        If ``ratio <= 0`` or an axis has too few points.

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((24,), spacing=1.0)
    >>> b = periodic_lattice_bonds(cloud, 2.0, influence="inverse")
    >>> K = pdlin.operators.assemble_stiffness(pdlin.Correspondence(E=1.0), cloud, b)
    >>> # omega = 1/|xi| at 2h: g = 0 at theta = 0, pi, +-2 pi/3 -> 4 modes on 24 points
    >>> count_zero_modes(K, n_rigid=0).n_zero
    4
    """
    from ..geometry.influence import evaluate_influence

    lat = cloud.lattice
    if lat is None or lat.index is not None:
        raise ModelError("periodic_lattice_bonds needs a complete pdlin.grid cloud")
    h = np.asarray(lat.spacing, dtype=float)
    if not np.allclose(h, h[0], rtol=1e-12):
        raise ModelError(f"periodic_lattice_bonds needs equal spacing, got {h.tolist()}")
    r = float(ratio)
    if not r > 0:
        raise InputError(f"ratio must be > 0, got {ratio}")
    d = cloud.dim
    m = int(np.floor(r * (1 + 1e-9)))
    shape = np.asarray(lat.shape)
    if np.any(shape <= 2 * m):
        raise InputError(
            f"every axis needs more than {2 * m} points for ratio {r:g}, got shape {lat.shape}"
        )
    rng = np.arange(-m, m + 1)
    offs = np.stack([g.ravel() for g in np.meshgrid(*([rng] * d), indexing="ij")], axis=1)
    offs = offs[np.any(offs != 0, axis=1)]
    offs = offs[np.sqrt(np.sum(offs.astype(float) ** 2, axis=1)) <= r * (1 + 1e-9)]
    n = cloud.n
    multi = np.stack(np.unravel_index(np.arange(n), lat.shape), axis=1)  # (n, d)
    jm = (multi[:, None, :] + offs[None, :, :]) % shape  # (n, no, d)
    j = np.ravel_multi_index(tuple(jm.reshape(-1, d).T), lat.shape)
    i = np.repeat(np.arange(n), offs.shape[0])
    xi = np.tile(offs * h[0], (n, 1))
    order = np.lexsort((j, i))
    i, j, xi = i[order], j[order], xi[order]
    length = np.sqrt(np.sum(xi**2, axis=1))
    hor = np.full(n, r * h[0])
    omega = evaluate_influence(influence, length, np.full(length.size, r * h[0]))
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(i, minlength=n), out=indptr[1:])
    return Bonds(
        n, i, j, xi, length, omega, np.asarray(cloud.volumes)[j], indptr, hor, "sphere", influence
    )


def _lattice_index(cloud: PointCloud) -> np.ndarray:
    lat = cloud.lattice
    if lat is None:
        raise ModelError("checkerboard modes need a pdlin.grid cloud (lattice metadata), got none")
    idx = np.arange(cloud.n) if lat.index is None else np.asarray(lat.index)
    return np.stack(np.unravel_index(idx, lat.shape), axis=1)


def checkerboard_energy_ratio(K: Any, cloud: PointCloud) -> CheckerboardReport:
    """Compute the energy of the ``{0, π}^d`` modes relative to the smooth mode.

    ``s = Π_k sin(π x̂_k)`` with ``x̂`` the points mapped to ``[0, 1]`` by
    their bounding box (so ``s = 0`` on the outermost points); the mode
    ``v = s (-1)^{θ·idx} e_k``.

    Parameters
    ----------
    K : sparse array or ndarray (n d, n d)
        Stiffness of ``cloud`` (point-major DOF order).
    cloud : PointCloud
        A :func:`pdlin.grid` cloud (lattice indices are needed).

    Returns
    -------
    CheckerboardReport
        ``R(v)/R(s e_k)`` with ``R(w) = wᵀKw / wᵀw`` per ``(θ, k)`` and the minimum.

    Raises
    ------
    ShapeError
        If ``K`` does not match the cloud's DOFs.
    ModelError
        If ``cloud`` carries no lattice metadata.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((21,), spacing=0.05)
    >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
    >>> K = pdlin.operators.assemble_stiffness(pdlin.Correspondence(E=1.0), cloud, bonds)
    >>> # no control at delta = h: the checkerboard costs exactly the smooth mode's energy
    >>> round(checkerboard_energy_ratio(K, cloud).min_ratio, 12)
    1.0
    """
    d, n = cloud.dim, cloud.n
    if K.shape != (n * d, n * d):
        raise ShapeError(f"K must have shape ({n * d}, {n * d}), got {K.shape}")
    idx = _lattice_index(cloud)
    lo, hi = cloud.bounds
    xh = (cloud.points - lo) / np.where(hi > lo, hi - lo, 1.0)
    s = np.prod(np.sin(np.pi * xh), axis=1)
    out: dict[tuple[tuple[int, ...], int], float] = {}
    for comp in range(d):
        w = np.zeros((n, d))
        w[:, comp] = s
        ws = w.ravel()
        rs = float(ws @ (K @ ws)) / float(ws @ ws)
        for theta in itertools.product((0, 1), repeat=d):
            if not any(theta):
                continue
            sign = (-1.0) ** (idx @ np.asarray(theta))
            wv = (w * sign[:, None]).ravel()
            rv = float(wv @ (K @ wv)) / float(wv @ wv)
            out[(tuple(theta), comp)] = rv / rs
    return CheckerboardReport(out, min(out.values()))


def compare_controls(
    cloud: PointCloud,
    bonds: Bonds,
    models: Mapping[str, Any],
    *,
    shadow: Any = None,
    tol: float = 1e-10,
    dense_limit: int = 3000,
) -> list[dict[str, Any]]:
    """Compare the zero-energy behaviour of several models on one cloud.

    Parameters
    ----------
    cloud : PointCloud
        The point cloud (a grid for the checkerboard measure).
    bonds : Bonds
        Bonds of ``cloud``.
    models : mapping of str to model
        Name -> model whose stiffness is assembled with
        :func:`pdlin.operators.assemble_stiffness`.
    shadow : array_like of int, optional
        Shadow-layer point indices: the count then runs on the real DOFs only
        and every zero counts as spurious.
    tol : float
        Zero threshold relative to ``lambda_max``.
    dense_limit : int
        Dense eigen-solve up to this many DOFs.

    Returns
    -------
    list of dict
        One row per model: ``name``, ``n_zero``, ``n_spurious``,
        ``checkerboard_min`` (min ratio of :func:`checkerboard_energy_ratio`,
        NaN off-lattice) and ``lambda_max``.

    Examples
    --------
    >>> import pdlin
    >>> from pdlin.analysis import compare_controls
    >>> cloud = pdlin.grid((11, 11), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
    >>> rows = compare_controls(cloud, bonds, {
    ...     "none": pdlin.Correspondence(E=1.0, nu=0.3),
    ...     "stress_points": pdlin.Correspondence(E=1.0, nu=0.3, control="stress_points")})
    >>> [(r["name"], r["n_spurious"]) for r in rows]
    [('none', 0), ('stress_points', 0)]
    >>> rows[0]["checkerboard_min"] < 1.0 + 1e-9 < rows[1]["checkerboard_min"]
    True
    """
    from ..operators.assembly import assemble_stiffness

    d = cloud.dim
    dofs = None
    if shadow is not None:
        real = np.setdiff1d(np.arange(cloud.n), np.asarray(shadow, dtype=np.intp))
        dofs = (d * real[:, None] + np.arange(d)).ravel()
    rows = []
    for name, model in models.items():
        K = assemble_stiffness(model, cloud, bonds)
        rep = count_zero_modes(K, dim=d, dofs=dofs, tol=tol, dense_limit=dense_limit)
        try:
            cb = checkerboard_energy_ratio(K, cloud).min_ratio
        except ModelError:
            cb = float("nan")
        rows.append(
            {
                "name": name,
                "n_zero": rep.n_zero,
                "n_spurious": rep.n_spurious,
                "checkerboard_min": cb,
                "lambda_max": rep.lambda_max,
            }
        )
    return rows
