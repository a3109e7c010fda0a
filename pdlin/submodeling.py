"""Sub-regions: model only the part of a body that a question needs (global-local).

A coarse solve of the whole body drives a fine model of a box: the fine points inside the
box are free, the fine points of a layer one horizon thick around it are prescribed by the
coarse displacement interpolated at them (the cut-boundary displacement method of finite-
element submodeling, with a layer as deep as the nonlocal interaction), and everything else
is left out.  The sub-problem has the fine problem's model, horizon, conditions and loads
restricted to the kept points, so its cost is that of the box, not of the body.

The answer is as good as the driving field in the layer: exact when the coarse solution is
(affine fields, consistent models), otherwise within the coarse error at the layer, which
decays into the box away from it (Saint-Venant).  See ``docs/tradeoff.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._validation import as_float_array
from .constraints import load_vector, resolve_dirichlet
from .errors import InputError, ShapeError
from .operators.bc import BodyForce, Dirichlet
from .problem import StaticProblem

__all__ = ["SubregionProblem", "subregion", "problem_horizon"]


@dataclass
class SubregionProblem:
    """A fine sub-problem cut out of a larger one.

    Attributes
    ----------
    problem : StaticProblem
        The sub-problem (kept points only).
    index : (k,) ndarray of int
        Indices of the kept points in the full problem's cloud.
    interior : (k,) ndarray of bool
        Kept points inside the box (the answer); the others form the driven layer.
    layer : float
        Thickness of the driven layer.
    """

    problem: StaticProblem
    index: np.ndarray
    interior: np.ndarray
    layer: float


def problem_horizon(problem: StaticProblem) -> float:
    """Return the largest horizon of a problem (its bonds, ``horizon`` or ``ratio`` x spacing).

    Parameters
    ----------
    problem : StaticProblem
        The problem; its bonds, ``horizon``, the cloud's horizon or
        ``bond_options['ratio']`` times the (lattice or median) spacing is used,
        in that order.

    Returns
    -------
    float
        The largest horizon, in length units.

    Raises
    ------
    InputError
        If the problem has none of them.

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((10, 10), spacing=0.1)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, bond_options={"ratio": 3.0})
    >>> round(problem_horizon(prob), 12)
    0.3
    """
    if problem.bonds is not None and problem.bonds.n_bonds:
        return float(np.max(problem.bonds.horizon))
    if problem.horizon is not None:
        return float(np.max(np.asarray(problem.horizon, dtype=float)))
    cloud = problem.cloud
    if cloud.horizon is not None:
        return float(np.max(cloud.horizon))
    ratio = (problem.bond_options or {}).get("ratio")
    if ratio is None:
        raise InputError("problem has no bonds, horizon or bond_options['ratio']")
    h = (
        float(np.max(cloud.lattice.spacing))
        if cloud.lattice is not None
        else float(np.median(cloud.spacing))
    )
    return float(ratio) * h


def _per_entity_data(model: Any, n_points: int, n_bonds: int | None) -> str | None:
    """Name of a model attribute that holds one value per point or bond, if any."""
    for name, v in vars(model).items():
        if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] > 1:
            if v.shape[0] == n_points or (n_bonds is not None and v.shape[0] == n_bonds):
                return name
    material = getattr(model, "material", None)
    if material is not None and material is not model and hasattr(material, "__dict__"):
        found = _per_entity_data(material, n_points, n_bonds)
        if found is not None:
            return f"material.{found}"
    return None


def subregion(
    problem: StaticProblem,
    box: Any,
    driver: Any,
    *,
    layer: float | None = None,
) -> SubregionProblem:
    """Cut a fine sub-problem out of ``problem``, driven by a global solution.

    Parameters
    ----------
    problem : StaticProblem
        The fine problem of the whole body (its cloud is needed, its bonds are not: give
        ``horizon`` or ``bond_options`` so that only the kept points' bonds are found).
    box : (2, dim) array_like
        Lower and upper corners of the region of interest.
    driver : callable, (points, u) pair or StaticResult
        The global displacement: ``driver(X) -> (k, dim)``, or a coarse solution's
        points and displacements (interpolated linearly, see
        :func:`pdlin.sweeps.interpolate_field`), or a :class:`~pdlin.StaticResult`.
    layer : float, optional
        Thickness of the driven layer around the box (default: the largest horizon times
        the model's ``coupling_range`` — one horizon for bond-based models, two for
        state-based and correspondence ones — so that the force on every free point is
        computed from the same points as in the whole body).

    Returns
    -------
    SubregionProblem
        The sub-problem, the kept points' indices, the interior mask and the layer.

    Notes
    -----
    The sub-problem's loads are the problem's on the box's free DOFs: entries on the
    layer (driven) and on the problem's own supports inside the box are left out; the
    latter go into those supports' reactions in the whole body, so the sub-problem's
    reaction there is the whole body's plus that load.

    Raises
    ------
    InputError
        Symmetry planes, a model with per-point or per-bond data, a box that selects no
        free point, or a box without a layer.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((40, 10), spacing=0.025)
    >>> F = np.array([[1.001, 0.0], [0.0, 0.9997]])
    >>> prob = pdlin.StaticProblem(
    ...     pdlin.Correspondence(E=1.0, nu=0.3, plane="stress"), cloud,
    ...     bond_options={"ratio": 2.015}, dirichlet=[pdlin.Dirichlet.affine("boundary", F)])
    >>> sub = subregion(prob, [[0.3, 0.05], [0.6, 0.2]], lambda X: X @ (F - np.eye(2)).T)
    >>> sub.problem.cloud.n, int(sub.interior.sum())
    (200, 72)
    >>> res = pdlin.solve(sub.problem)
    >>> X = sub.problem.cloud.points
    >>> bool(np.allclose(res.u, X @ (F - np.eye(2)).T, atol=1e-12))
    True
    """
    if not isinstance(problem, StaticProblem):
        raise InputError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    if problem.thermal is not None:  # the eigenstrain load is linear (pdlin.models.thermal)
        raise InputError(
            "subregion does not take thermal loads (problem.thermal); solve them with pdlin.solve"
        )
    if problem.symmetry:
        raise InputError("subregion: a problem with symmetry planes is not supported")
    cloud = problem.cloud
    d = cloud.dim
    b = as_float_array(box, "box")
    if b.shape != (2, d):
        raise ShapeError(f"box must have shape (2, {d}) (lower and upper corner), got {b.shape}")
    if np.any(b[1] <= b[0]):
        raise InputError(f"box upper corner must exceed the lower one, got {b.tolist()}")
    n_bonds = None if problem.bonds is None else problem.bonds.n_bonds
    per = _per_entity_data(problem.model, cloud.n, n_bonds)
    if per is not None:
        raise InputError(
            f"subregion: the model holds one value per point or bond ({per!r}); only models "
            "whose parameters do not depend on the point or bond index can be cut"
        )
    if layer is None:
        # every free point's force must see the same neighbours (and, for state-based and
        # correspondence models, the neighbours' own families) as in the whole body
        layer = problem_horizon(problem) * int(getattr(problem.model, "coupling_range", 1))
    layer = float(layer)
    if not (np.isfinite(layer) and layer > 0):
        raise InputError(f"layer must be a positive number, got {layer!r}")
    P = cloud.points
    tol = 1e-12 * max(float(np.max(np.abs(P))) if P.size else 1.0, 1.0)
    inside = np.all((P >= b[0] - tol) & (P <= b[1] + tol), axis=1)
    near = np.all((P >= b[0] - layer - tol) & (P <= b[1] + layer + tol), axis=1)
    if not inside.any():
        raise InputError(f"box {b.tolist()} contains no point of the cloud")
    keep = np.flatnonzero(near)
    interior = inside[keep]
    driven = np.flatnonzero(~interior)
    if driven.size == 0:
        raise InputError(
            "the box and its layer contain the whole cloud: nothing is cut (use the problem)"
        )
    # the problem's own conditions and loads, resolved on the full cloud (cheap: no bonds)
    dofs, vals = resolve_dirichlet(cloud, problem.dirichlet)
    presc = np.zeros((cloud.n, d), dtype=bool)
    pval = np.zeros((cloud.n, d))
    presc.reshape(-1)[dofs] = True
    pval.reshape(-1)[dofs] = vals
    f_ext = load_vector(cloud, problem.loads).reshape(cloud.n, d)
    # the driving displacement at the layer's points
    Xl = P[keep[driven]]
    if callable(driver):
        ul = np.asarray(driver(Xl), dtype=float)
    else:
        pts, u = _driver_arrays(driver)
        if pts.shape[1] != d:
            raise ShapeError(f"driver points must have {d} columns, got {pts.shape[1]}")
        from .sweeps.core import interpolate_field

        ul = interpolate_field(pts, u.reshape(pts.shape[0], d), Xl)
    if ul.shape != (driven.size, d) or not np.all(np.isfinite(ul)):
        raise ShapeError(
            f"driver must give finite ({driven.size}, {d}) displacements at the layer, "
            f"got shape {ul.shape}"
        )
    sub_cloud = cloud.subset(keep)
    k_presc = presc[keep].copy()
    k_val = pval[keep].copy()
    # the layer: the problem's own conditions win, the driver prescribes the rest
    free_in_layer = ~k_presc[driven]
    k_val[driven] = np.where(free_in_layer, ul, k_val[driven])
    k_presc[driven] = True
    dirichlet = []
    for c in range(d):
        pts_c = np.flatnonzero(k_presc[:, c])
        if pts_c.size:
            dirichlet.append(Dirichlet(pts_c, k_val[pts_c, c], components=[c]))
    loads: list[Any] = []
    # the load on free DOFs of the box: an entry on a prescribed DOF (the problem's own
    # support inside the box) goes straight into that support's reaction and loads nothing
    fi = np.where(k_presc, 0.0, f_ext[keep])
    loaded = np.flatnonzero(np.any(fi != 0.0, axis=1) & interior)
    if loaded.size:
        measure = 1.0 if d == 3 else cloud.thickness
        dens = fi[loaded] / (sub_cloud.volumes[loaded] * measure)[:, None]
        loads.append(BodyForce(loaded, dens))
    horizon = problem.horizon
    if horizon is not None and np.ndim(horizon) > 0:
        horizon = np.asarray(horizon)[keep]
    if (
        horizon is None
        and problem.bonds is not None
        and sub_cloud.horizon is None
        and "ratio" not in (problem.bond_options or {})
    ):
        horizon = problem_horizon(problem)  # precomputed bonds: find the kept ones again
    sub = StaticProblem(
        problem.model,
        sub_cloud,
        None,
        horizon=horizon,
        dirichlet=dirichlet,
        loads=loads,
        bond_options=dict(problem.bond_options or {}),
    )
    return SubregionProblem(sub, keep, interior, layer)


def _driver_arrays(driver: Any) -> tuple[np.ndarray, np.ndarray]:
    from .system import StaticResult

    if isinstance(driver, StaticResult):
        return np.asarray(driver.problem.cloud.points), np.asarray(driver.u, dtype=float)
    if isinstance(driver, tuple) and len(driver) == 2:
        return as_float_array(driver[0], "driver points"), as_float_array(driver[1], "driver u")
    raise InputError(
        "driver must be a callable u(X), a (points, u) pair or a StaticResult, "
        f"got {type(driver).__name__}"
    )
