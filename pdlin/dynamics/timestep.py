"""Stable time steps of central differences (velocity Verlet) on a peridynamic model.

Central differences on ``M ü = f(u)`` are stable while ``Δt ω_max <= 2``, ``ω_max²``
the largest eigenvalue of ``M⁻¹K`` (``K`` the linearized stiffness, ``M`` the lumped
nodal masses ``ρ_i V_i``).  Three estimates of ``Δt_c = 2/ω_max``:

* ``'gershgorin'`` (default, any model): ``ω_max² <= max_i Σ_j |K_ij| / M_i`` (Gershgorin's
  circle theorem on ``M⁻¹K``; the row sums ADR uses for its fictitious density,
  Kilic & Madenci 2010), so ``Δt = 2 / sqrt(max_i Σ_j |K_ij| / M_i)`` is stable for every
  model, symmetric or not, and for stress points and other controls too, whose ``K``
  it reads;
* ``'silling-askari'`` (:class:`pdlin.BondBased` only): Silling & Askari (2005)'s
  von Neumann bound of the bond-based explicit scheme, ``Δt < sqrt(2ρ / Σ_p V_p C_p)``
  per point, ``C_p`` the bond's micromodulus over its length (pdlin's
  ``k_b / (V_i V_p)``);
* ``'lanczos'`` (symmetric models): ``λ_max(M^-½ K M^-½)`` by Lanczos iterations
  (scipy's ``eigsh``) -- the exact linear limit, not a bound.

:func:`nearest_neighbour_time_step` gives the closed forms of Luo & Sundararaghavan (2018),
Eqs. (13)-(15), for nearest-neighbour correspondence lattices (halved with stress points).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import InputError, ModelError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from ..models.bond_based import BondBased

__all__ = [
    "TimeStepEstimate",
    "estimate_time_step",
    "nodal_masses",
    "nearest_neighbour_time_step",
    "TIME_STEP_METHODS",
]

TIME_STEP_METHODS = ("gershgorin", "silling-askari", "lanczos")


@dataclass(frozen=True)
class TimeStepEstimate:
    """A stable-time-step estimate.

    Attributes
    ----------
    dt : float
        The critical time step ``2 / ω_max`` of ``method`` (a run at ``dt`` sits on the
        limit; :func:`pdlin.dynamics.solve_explicit` runs at ``safety * dt``).
    method : str
        ``'gershgorin'``, ``'silling-askari'`` or ``'lanczos'``.
    point : int
        The point whose row gives the bound (-1 for ``'lanczos'``).
    omega_max : float
        The estimate of the largest angular frequency, ``2 / dt``.
    """

    dt: float
    method: str
    point: int = -1
    omega_max: float = field(init=False)

    def __post_init__(self) -> None:
        """Derive ``omega_max``."""
        object.__setattr__(self, "omega_max", 2.0 / self.dt)


def _measure(cloud: PointCloud) -> float:
    return 1.0 if cloud.dim == 3 else float(cloud.thickness)


def nodal_masses(cloud: PointCloud, density: Any) -> np.ndarray:
    """Return the lumped nodal masses ``ρ_i V_i`` (times thickness / cross-section).

    Parameters
    ----------
    cloud : PointCloud
        The points.
    density : float or (n,) array_like
        Mass density per point (> 0, finite).

    Returns
    -------
    (n,) ndarray
        Nodal masses, in the units of pdlin's nodal forces (``f = V L``).

    Raises
    ------
    InputError
        ``density`` is not positive and finite, or has the wrong shape.

    Examples
    --------
    >>> import pdlin
    >>> nodal_masses(pdlin.grid((2, 2), spacing=0.5, thickness=0.1), 8000.0).tolist()
    [200.0, 200.0, 200.0, 200.0]
    """
    try:
        rho = np.asarray(density, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"density must be a number or one per point, got {density!r}") from exc
    if rho.ndim not in (0, 1) or (rho.ndim == 1 and rho.shape != (cloud.n,)):
        raise InputError(
            f"density must be a number or have shape ({cloud.n},) (one per point), "
            f"got shape {rho.shape}"
        )
    if not np.all(np.isfinite(rho)) or np.any(rho <= 0):
        raise InputError(f"density must be finite and > 0, got min {float(np.min(rho))}")
    vol = np.asarray(cloud.volumes, dtype=float) * _measure(cloud)
    return np.broadcast_to(rho, (cloud.n,)) * vol


def estimate_time_step(
    model: Any,
    cloud: PointCloud,
    bonds: Bonds,
    density: Any,
    *,
    method: str = "gershgorin",
) -> TimeStepEstimate:
    """Estimate the critical time step of central differences (see the module docstring).

    Parameters
    ----------
    model : Model
        The model (its linearized stiffness at the reference state).
    cloud : PointCloud
        The points.
    bonds : Bonds
        Their bonds.
    density : float or (n,) array_like
        Mass density per point.
    method : {'gershgorin', 'silling-askari', 'lanczos'}
        The estimate.

    Returns
    -------
    TimeStepEstimate
        The critical step ``2 / ω_max`` of the method.

    Raises
    ------
    InputError
        An unknown method.
    ModelError
        ``'silling-askari'`` for a model other than :class:`pdlin.BondBased`, ``'lanczos'``
        for a model with a nonsymmetric stiffness, or a stiffness with no positive row.

    Examples
    --------
    A 1D bar with nearest-neighbour bonds (δ = h): the micromodulus ``c = 2E/(A δ²)``
    makes the bond stiffness ``k = 2EA/h``, ``K`` the three-point stencil ``k [-1, 2, -1]``,
    whose largest eigenvalue over the mass ``ρAh`` tends to ``8E/(ρh²)``: ``Δt_c → h
    sqrt(ρ/E) / sqrt(2)``, which both the bound and Lanczos give:

    >>> import pdlin
    >>> cloud = pdlin.grid((200,), spacing=0.01)
    >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
    >>> est = estimate_time_step(pdlin.BondBased(E=1.0), cloud, bonds, 1.0)
    >>> round(est.dt, 7), est.method
    (0.0070711, 'gershgorin')
    >>> round(estimate_time_step(pdlin.BondBased(E=1.0), cloud, bonds, 1.0,
    ...                          method="lanczos").dt, 5)
    0.00707
    """
    if method not in TIME_STEP_METHODS:
        raise InputError(f"method must be one of {list(TIME_STEP_METHODS)}, got {method!r}")
    mass = nodal_masses(cloud, density)
    d = cloud.dim
    if method == "silling-askari":
        if not isinstance(model, BondBased):
            raise ModelError(
                f"method='silling-askari' is the bond-based bound, got {type(model).__name__}; "
                "use 'gershgorin'"
            )
        k = np.asarray(model.bond_stiffness(cloud, bonds), dtype=float)
        ksum = np.bincount(np.asarray(bonds.i), weights=k, minlength=cloud.n)
        ratio = ksum / mass
        p = int(np.argmax(ratio))
        if ratio[p] <= 0:
            raise ModelError("the stiffness has no positive row: no time-step bound")
        return TimeStepEstimate(math.sqrt(2.0 / ratio[p]), method, p)
    mdof = np.repeat(mass, d)
    if method == "gershgorin":
        K = sp.csr_array(model.stiffness(cloud, bonds))
        rows = np.asarray(abs(K).sum(axis=1)).ravel() / mdof
        p = int(np.argmax(rows))
        if rows[p] <= 0:
            raise ModelError("the stiffness has no positive row: no time-step bound")
        return TimeStepEstimate(2.0 / math.sqrt(rows[p]), method, p // d)
    if not getattr(model, "symmetric", True):
        raise ModelError(
            f"method='lanczos' needs a symmetric stiffness, {type(model).__name__} "
            f"(linearization={getattr(model, 'linearization', None)!r}) has none; use 'gershgorin'"
        )
    op = model.operator(cloud, bonds)
    s = 1.0 / np.sqrt(mdof)
    scaled = spla.LinearOperator(op.shape, matvec=lambda x: s * op.matvec(s * x), dtype=float)
    lam = spla.eigsh(scaled, k=1, which="LA", tol=1e-10, return_eigenvectors=False)
    lmax = float(lam[0])
    if lmax <= 0:
        raise ModelError("the stiffness has no positive eigenvalue: no time-step bound")
    return TimeStepEstimate(2.0 / math.sqrt(lmax), method)


def nearest_neighbour_time_step(
    spacing: float, density: float, E_max: float, dim: int, *, stress_points: bool = False
) -> float:
    """Return the closed-form time step of a nearest-neighbour correspondence lattice.

    Luo & Sundararaghavan (2018), Eqs. (14) and (15): ``Δt <= (2/n) Δx sqrt(ρ/E_max)``
    without a control, ``(1/n) Δx sqrt(ρ/E_max)`` with stress points (half: each
    stress point sees one side of a bond pair), ``n`` the dimension.  In 1D (Eq. 13)
    the no-control form is ``2 Δx / c``; on a bar with Dirichlet ends it is not safe
    (the exact limit is ``sqrt(3) Δx / c`` there): use :func:`estimate_time_step` on the
    problem instead, which reads the actual stiffness.

    Parameters
    ----------
    spacing : float
        Lattice spacing ``Δx`` (> 0).
    density : float
        Mass density (> 0).
    E_max : float
        Largest entry of the elastic tensor (> 0).
    dim : {1, 2, 3}
        Dimension ``n``.
    stress_points : bool
        Stress-point control (halves the step).

    Returns
    -------
    float
        The time step.

    Raises
    ------
    InputError
        A non-positive argument or an unknown dimension.

    Examples
    --------
    >>> nearest_neighbour_time_step(1.0, 1.0, 1.0, 2), nearest_neighbour_time_step(
    ...     1.0, 1.0, 1.0, 2, stress_points=True)
    (1.0, 0.5)
    """
    for name, v in (("spacing", spacing), ("density", density), ("E_max", E_max)):
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    if dim not in (1, 2, 3):
        raise InputError(f"dim must be 1, 2 or 3, got {dim!r}")
    base = (2.0 / dim) * spacing * math.sqrt(density / E_max)
    return base / 2.0 if stress_points else base
