"""Closed-form benchmarks of the PD surface effect: tension bar, plate, shear block.

Each function solves one static problem with the given model on a cell-centred grid
(spacing 1, δ = ``ratio`` h) and returns signed relative errors against the
closed-form linear-elastic answer, measured on interior sections (away from the
loaded and supported faces), so that the error is the effect of the free surfaces
(and of the one-point quadrature of the discrete families).  Used by
``tests/verification/test_surface_correction.py`` and
``benchmarks/surface_correction.py``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..geometry.cloud import grid
from ..models.base import Model
from ..operators.bc import Dirichlet, TotalForce
from ..problem import StaticProblem
from ..static import solve

__all__ = ["tension_bar_error", "plate_tension_errors", "shear_block_error"]


def _young_poisson(model: Model, dim: int) -> tuple[float, float]:
    E = np.asarray(getattr(model, "E", None), dtype=float)
    if E.ndim != 0:
        raise ValueError("the surface benchmarks need a model with a scalar E")
    nu = getattr(model, "nu", None)
    if nu is None:
        nu = model.implied_poisson_ratio(dim)  # type: ignore[attr-defined]
    return float(E), float(nu)


def _section(p: np.ndarray, axis: int, value: float, mask: Any = True) -> np.ndarray:
    return np.asarray(np.isclose(p[:, axis], value) & mask)


def tension_bar_error(
    model: Model, shape: tuple[int, int, int] = (20, 4, 4), ratio: float = 3.015
) -> float:
    """Compute the relative error of a 3D bar's elongation in tension, ``ΔL / (F L/(E A)) - 1``.

    The x- face is held in x only (plus one pinned point and one point held in y,
    which remove the rigid motions without restraining the lateral contraction), a
    total force ``F`` pulls the x+ face; ``ΔL`` is the difference of the mean
    ``u_x`` of the cross-sections 5 layers in from either end.

    Parameters
    ----------
    model : Model
        Isotropic model with a scalar Young's modulus ``E`` (and ``nu`` or an implied
        Poisson ratio).
    shape : (int, int, int)
        Points along x, y, z (spacing 1).
    ratio : float
        Horizon in units of the spacing (1).

    Returns
    -------
    float
        Relative error (positive: too soft).

    Examples
    --------
    >>> import pdlin
    >>> err = tension_bar_error(pdlin.BondBased(E=1.0))
    >>> round(err, 3)   # 20 x 4 x 4 points, δ = 3.015 h: 49 % too soft
    0.492
    """
    cloud = grid(shape, spacing=1.0)
    p = cloud.points
    E, _ = _young_poisson(model, 3)
    face = np.flatnonzero(np.isclose(p[:, 0], p[:, 0].min()))
    face = face[np.lexsort((p[face, 2], p[face, 1]))]  # by y, then z
    pin, other = face[0], face[1]  # same y, next z: holding u_y stops the x rotation
    force = 1.0
    prob = StaticProblem(
        model,
        cloud,
        horizon=ratio,
        dirichlet=[
            Dirichlet("x-", 0.0, components="x"),
            Dirichlet(np.array([pin]), 0.0),
            Dirichlet(np.array([other]), 0.0, components="y"),
        ],
        loads=[TotalForce("x+", [force, 0.0, 0.0])],
    )
    u = solve(prob, solver="direct").u
    xs = np.unique(p[:, 0])
    xa, xb = xs[5], xs[-6]
    ua = u[_section(p, 0, xa), 0].mean()
    ub = u[_section(p, 0, xb), 0].mean()
    area = float(shape[1] * shape[2])
    return float((ub - ua) / (force * (xb - xa) / (E * area)) - 1.0)


def plate_tension_errors(
    model: Model, shape: tuple[int, int] = (40, 20), ratio: float = 3.015
) -> tuple[float, float]:
    """Compute the relative errors of a plate's axial and lateral strains in uniaxial tension.

    2D (the model's plane assumption), x- face held in x, one point of it in y, total
    force on x+.  Axial strain from the mean ``u_x`` of the sections 10 columns in from
    either end, lateral strain from the mean ``u_y`` of the rows a quarter of the width
    in, between those sections; closed form ``σ/E`` and ``-ν σ/E``.

    Parameters
    ----------
    model : Model
        Isotropic model with a scalar Young's modulus ``E`` (and ``nu`` or an implied
        Poisson ratio).
    shape : (int, int)
        Points along x and y (spacing 1).
    ratio : float
        Horizon in units of the spacing (1).

    Returns
    -------
    (float, float)
        Relative errors of the axial and the lateral strain.

    Examples
    --------
    >>> import pdlin
    >>> exx, eyy = plate_tension_errors(pdlin.BondBased(E=1.0))
    >>> round(exx, 3), round(eyy, 3)
    (-0.019, -0.077)
    """
    cloud = grid(shape, spacing=1.0)
    p = cloud.points
    E, nu = _young_poisson(model, 2)
    face = np.flatnonzero(np.isclose(p[:, 0], p[:, 0].min()))
    force = 1.0
    prob = StaticProblem(
        model,
        cloud,
        horizon=ratio,
        dirichlet=[Dirichlet("x-", 0.0, components="x"), Dirichlet(face[:1], 0.0, components="y")],
        loads=[TotalForce("x+", [force, 0.0])],
    )
    u = solve(prob, solver="direct").u
    sigma = force / (shape[1] * cloud.thickness)
    xs, ys = np.unique(p[:, 0]), np.unique(p[:, 1])
    xa, xb = xs[10], xs[-11]
    ya, yb = ys[shape[1] // 4], ys[-1 - shape[1] // 4]
    mid = (p[:, 0] >= xa) & (p[:, 0] <= xb)
    exx = (u[_section(p, 0, xb), 0].mean() - u[_section(p, 0, xa), 0].mean()) / (xb - xa)
    eyy = (u[_section(p, 1, yb, mid), 1].mean() - u[_section(p, 1, ya, mid), 1].mean()) / (yb - ya)
    return float(exx / (sigma / E) - 1.0), float(eyy / (-nu * sigma / E) - 1.0)


def shear_block_error(model: Model, n: int = 30, ratio: float = 3.015) -> float:
    """Compute the relative error of a square block's shear strain in pure shear, ``γ G/τ - 1``.

    2D block of ``n x n`` points, shear tractions τ on all four faces (total forces
    ``±τ n`` tangential to each face, a self-equilibrated load), one pinned point and
    its x neighbour held in y against the rigid motions (no reactions).  ``γ`` is
    ``∂u_x/∂y + ∂u_y/∂x`` from the mean displacements of the rows / columns 5 in from
    the faces; ``G = E/(2(1+ν))``.

    Parameters
    ----------
    model : Model
        Isotropic model with a scalar Young's modulus ``E`` (and ``nu`` or an implied
        Poisson ratio).
    n : int
        Points per side (spacing 1).
    ratio : float
        Horizon in units of the spacing (1).

    Returns
    -------
    float
        Relative error (positive: too soft).

    Examples
    --------
    >>> import pdlin
    >>> round(shear_block_error(pdlin.BondBased(E=1.0)), 3)
    0.052
    """
    cloud = grid((n, n), spacing=1.0)
    p = cloud.points
    E, nu = _young_poisson(model, 2)
    tau = 1.0
    f = tau * n * cloud.thickness
    order = np.lexsort((p[:, 0], p[:, 1]))
    pin, nxt = order[0], order[1]  # bottom row, two neighbours along x
    prob = StaticProblem(
        model,
        cloud,
        horizon=ratio,
        dirichlet=[
            Dirichlet(np.array([pin]), 0.0),
            Dirichlet(np.array([nxt]), 0.0, components="y"),
        ],
        loads=[
            TotalForce("y+", [f, 0.0]),
            TotalForce("y-", [-f, 0.0]),
            TotalForce("x+", [0.0, f]),
            TotalForce("x-", [0.0, -f]),
        ],
    )
    u = solve(prob, solver="direct").u
    xs = np.unique(p[:, 0])
    a, b = xs[5], xs[-6]
    inx = (p[:, 0] >= a) & (p[:, 0] <= b)
    iny = (p[:, 1] >= a) & (p[:, 1] <= b)
    dux = (u[_section(p, 1, b, inx), 0].mean() - u[_section(p, 1, a, inx), 0].mean()) / (b - a)
    duy = (u[_section(p, 0, b, iny), 1].mean() - u[_section(p, 0, a, iny), 1].mean()) / (b - a)
    G = E / (2.0 * (1.0 + nu))
    return float((dux + duy) / (tau / G) - 1.0)
