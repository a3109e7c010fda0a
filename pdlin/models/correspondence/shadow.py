"""Shadow-layer problems of correspondence peridynamics (Javaheri et al. (2022), Sec. II.D)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...errors import ModelError
from ...geometry.bonds import Bonds
from ...geometry.cloud import PointCloud
from .model import Correspondence

__all__ = [
    "shadow_problem",
    "shadow_real_counts",
]


def shadow_real_counts(cloud: PointCloud, shadow: np.ndarray) -> np.ndarray:
    """Return the number of real (non-shadow) lattice positions along each axis.

    Parameters
    ----------
    cloud : PointCloud
        A :func:`pdlin.grid` cloud.
    shadow : (m,) array_like of int
        The shadow particles.

    Returns
    -------
    (d,) ndarray of int
        Zeros when every particle is a shadow one.

    Raises
    ------
    ModelError
        The cloud has no lattice.
    """
    lat = cloud.lattice
    if lat is None:
        raise ModelError("shadow_real_counts needs a pdlin.grid cloud, got no lattice metadata")
    real = np.ones(cloud.n, dtype=bool)
    real[shadow] = False
    if not real.any():
        return np.zeros(cloud.dim, dtype=int)
    idx = np.arange(cloud.n) if lat.index is None else np.asarray(lat.index)
    multi = np.unravel_index(idx[real], lat.shape)
    return np.array([np.unique(mk).size for mk in multi])


def shadow_problem(
    model: Correspondence,
    cloud: PointCloud,
    bonds: Bonds,
    F: Any,
    *,
    depth: float | None = None,
    allow_odd: bool = False,
) -> Any:
    """Return a static problem with a shadow layer prescribed to the affine field of ``F``.

    Returns a :class:`pdlin.StaticProblem` whose model is ``model`` with
    ``shadow`` set, whose Dirichlet condition is :func:`pdlin.shadow_layer`
    and whose load is the shadow-stress force :meth:`pdlin.Correspondence.shadow_loads`
    (Javaheri et al. (2022), Sec. II.D).  Odd real counts along an axis make K_RR singular
    (derived parity rule, see docs/correspondence.md) and raise unless ``allow_odd``; stress points,
    springs and ADS couple the sublattices and are exempt.

    Parameters
    ----------
    model : Correspondence
        The model (copied, with ``shadow`` set).
    cloud : PointCloud
        A :func:`pdlin.grid` cloud.
    bonds : Bonds
        Its bonds.
    F : (d, d) array_like
        The affine deformation gradient.
    depth : float, optional
        Depth of the shadow layer (default: the largest horizon, δ).
    allow_odd : bool
        Proceed with odd real counts (singular ``K_RR`` without a coupling control).

    Returns
    -------
    pdlin.StaticProblem
        Model, cloud, bonds, the shadow Dirichlet condition and the shadow-stress load.

    Raises
    ------
    ModelError
        Odd real counts along an axis without ``allow_odd`` (controls 'none',
        'higher_order', 'penalty').

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.models.correspondence import shadow_problem
    >>> cloud = pdlin.grid((12, 12), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=2.0)
    >>> C = pdlin.constitutive.isotropic_2d(1.0, 0.3, plane="strain")
    >>> F = np.eye(2) + [[0.02, 0.005], [0.003, -0.01]]
    >>> prob = shadow_problem(pdlin.Correspondence(C), cloud, bonds, F)
    >>> res = pdlin.solve(prob, solver="direct")
    >>> bool(np.abs(res.u - cloud.points @ (F - np.eye(2)).T).max() < 1e-12)
    True
    """
    from ...operators.bc import BodyForce, shadow_layer
    from ...problem import StaticProblem

    dep = float(np.max(bonds.horizon)) if depth is None else float(depth)
    bc, shadow = shadow_layer(cloud, F, dep)
    counts = shadow_real_counts(cloud, shadow)
    # stress points and springs / ADS couple the sublattices: no parity rule
    decoupled = model.control not in ("stress_points", "springs", "ads")
    if decoupled and not allow_odd and np.any(counts % 2 == 1):
        raise ModelError(
            f"real particle counts per axis must be even with a shadow layer (K_RR is singular "
            f"otherwise), got {counts.tolist()}; pass allow_odd=True to proceed"
        )
    params = dict(model.__dict__)
    m2 = Correspondence.__new__(Correspondence)
    m2.__dict__.update(params)
    m2.shadow = np.asarray(shadow, dtype=np.intp)
    m2._cache = None
    m2.assembly = {}
    f = m2.shadow_loads(cloud, bonds, F=F)
    real = np.setdiff1d(np.arange(cloud.n), shadow)
    vol = np.asarray(cloud.volumes) * (1.0 if cloud.dim == 3 else cloud.thickness)
    load = BodyForce(real, f[real] / vol[real, None])
    return StaticProblem(m2, cloud, bonds, dirichlet=[bc], loads=[load])
