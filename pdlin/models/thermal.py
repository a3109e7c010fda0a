"""Thermal expansion as an eigenstrain load of the linear static models.

A temperature change ``ΔT`` (one value, or one per point) with the linear thermal
expansion coefficient ``α`` strains the body freely by ``α ΔT`` in every direction.
In the linear problem this free strain is an eigenstrain: the models' force is
evaluated on the mechanical part of the deformation only,

* bond-based and ordinary state-based (LPS, XOSB) models: the bond extension
  ``e = n·(u_j - u_i)`` is reduced by ``α ΔT_ij |ξ|``, ``ΔT_ij = (ΔT_i + ΔT_j) / 2``
  (Peridigm's ``elastic.cxx`` / ``material_utilities.cxx``: ``e -= α ΔT |ξ|``, with the
  owner's ``ΔT_i``; both are the same for a uniform ``ΔT``);
* correspondence models: the small strain ``ε = sym ∇u`` is reduced by ``α ΔT_i I`` at
  each point (Peridigm's ``elastic_correspondence.cxx`` reduces the rate of deformation
  by ``α dΔT I``), so the stress is ``C : (ε - α ΔT I)``.

The force is linear in the extension (in the strain), so the force of the eigenstrain
moves to the right-hand side: ``K u = f_ext + f_th`` with ``f_th = -F(e_th)``, ``F`` the
model's linear force of the bond-extension state ``e_th = α ΔT_ij |ξ|`` (of the stress
``C : α ΔT I``).  For a uniform ``ΔT`` ``f_th = K (α ΔT x)``: a free body expands by
``α ΔT x`` exactly and carries no stress.  For a linear ``ΔT`` the displacement
``α (ΔT_0 x + (g·x) x - |x|² g / 2)`` (``ΔT = ΔT_0 + g·x``) extends every bond by exactly
``α ΔT_ij |ξ|`` (derived), so the bond-based and state-based models leave a free body
with a linear temperature field stress-free too.

In plane strain the out-of-plane expansion is held, so the in-plane eigenstrain is
``(1 + ν) α ΔT`` (isotropic models; the model's Poisson's ratio); plane stress, 1D bars
and 3D use ``α ΔT``.

:class:`ThermalExpansion` is the data (``pdlin.StaticProblem(..., thermal=...)``);
:func:`thermal_force` and :func:`thermal_stress` evaluate it for a model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._validation import as_float_array
from ..errors import InputTypeError, ModelError, ShapeError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from .bond_based import BondBased, implied_poisson_ratio
from .correspondence import Correspondence
from .correspondence.gradient import voigt_projector
from .ordinary_state import OrdinaryStateBased

__all__ = [
    "ThermalExpansion",
    "thermal_strain",
    "thermal_force",
    "thermal_stress",
    "mechanical_strain",
    "check_thermal",
]


@dataclass(frozen=True, eq=False)
class ThermalExpansion:
    """A temperature change and the thermal expansion coefficient (an eigenstrain load).

    Parameters
    ----------
    temperature_change : float, (n,) array_like or callable
        ``ΔT`` from the stress-free reference state: one value for every point, one per
        point, or a function of the ``(n, dim)`` reference coordinates returning ``(n,)``.
    alpha : float or (n,) array_like
        Linear thermal expansion coefficient (strain per unit of temperature), one value
        or one per point (e.g. per block).

    Examples
    --------
    A free 1D bar heated by 100 expands by ``α ΔT x`` (here pinned at its left end):

    >>> import numpy as np, pdlin
    >>> from pdlin.models.thermal import ThermalExpansion
    >>> cloud = pdlin.grid((10,), spacing=0.1)
    >>> th = ThermalExpansion(temperature_change=100.0, alpha=1e-5)
    >>> left = int(np.argmin(cloud.points[:, 0]))
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.2015,
    ...     dirichlet=[pdlin.Dirichlet([left], 1e-3 * cloud.points[left, 0])], thermal=th)
    >>> res = pdlin.solve(prob, solver="direct")
    >>> bool(np.allclose(res.u[:, 0], 1e-3 * cloud.points[:, 0], rtol=1e-12, atol=1e-18))
    True
    >>> float(np.abs(res.stress()).max()) < 1e-14
    True
    """

    temperature_change: Any
    alpha: Any

    def __post_init__(self) -> None:
        """Check scalar / array values (a callable is checked when evaluated)."""
        if not callable(self.temperature_change):
            t = as_float_array(self.temperature_change, "thermal.temperature_change")
            if t.ndim > 1:
                raise ShapeError(
                    "thermal.temperature_change must be a scalar or one value per point "
                    f"(n,), got shape {t.shape}"
                )
        a = as_float_array(self.alpha, "thermal.alpha")
        if a.ndim > 1:
            raise ShapeError(
                f"thermal.alpha must be a scalar or one value per point (n,), got shape {a.shape}"
            )

    def temperature(self, cloud: PointCloud) -> np.ndarray:
        """Return ``ΔT`` per point ``(n,)``.

        Parameters
        ----------
        cloud : PointCloud
            The points (their reference coordinates for a callable).

        Returns
        -------
        (n,) ndarray of float

        Raises
        ------
        ShapeError
            When an array or the callable's result is not a scalar or ``(n,)``.
        """
        value = self.temperature_change
        if callable(value):
            return _per_point(
                value(cloud.points), cloud.n, "thermal.temperature_change (callable result)"
            )
        return _per_point(value, cloud.n, "thermal.temperature_change")

    def subset(self, cloud: PointCloud, keep: np.ndarray) -> ThermalExpansion:
        """Return the temperature change and coefficient of the points ``keep`` of ``cloud``.

        Parameters
        ----------
        cloud : PointCloud
            All points.
        keep : (m,) ndarray of int
            The points kept.

        Returns
        -------
        ThermalExpansion
            Per-point arrays of the ``m`` points.

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> th = ThermalExpansion(lambda x: x[:, 0], 1e-5)
        >>> th.subset(pdlin.grid((4,), spacing=1.0), np.array([1, 3])).temperature_change.tolist()
        [1.5, 3.5]
        """
        keep = np.asarray(keep, dtype=np.intp)
        alpha = _per_point(self.alpha, cloud.n, "thermal.alpha")[keep]
        return ThermalExpansion(self.temperature(cloud)[keep], alpha)

    def _repr_items(self) -> dict[str, Any]:
        def short(v: Any) -> Any:
            if callable(v):
                return getattr(v, "__name__", "callable")
            a = np.asarray(v, dtype=float)
            return float(a) if a.ndim == 0 else f"per-point ({a.size})"

        return {"temperature_change": short(self.temperature_change), "alpha": short(self.alpha)}

    def __repr__(self) -> str:
        """Short description (no arrays).

        Examples
        --------
        >>> ThermalExpansion(100.0, 1e-5)
        ThermalExpansion(temperature_change=100.0, alpha=1e-05)
        """
        items = ", ".join(f"{k}={v!r}" for k, v in self._repr_items().items())
        return f"ThermalExpansion({items})"


def _per_point(value: Any, n: int, name: str) -> np.ndarray:
    arr = as_float_array(value, name)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape == (n,):
        return arr
    raise ShapeError(f"{name} must be a scalar or have shape ({n},), got {arr.shape}")


def _plane_factor(model: Any, cloud: PointCloud) -> np.ndarray | float:
    """In-plane eigenstrain per unit ``α ΔT``: ``1 + ν`` in plane strain, else 1."""
    if cloud.dim != 2 or getattr(model, "plane", "stress") != "strain":
        return 1.0
    nu = getattr(model, "nu", None)
    if nu is None and isinstance(model, BondBased):
        nu = implied_poisson_ratio(2, "strain")
    if nu is None:
        raise ModelError(
            f"thermal expansion in plane strain needs an isotropic {type(model).__name__} with "
            "a Poisson's ratio (the in-plane eigenstrain is (1 + nu) alpha dT), got a model "
            "without nu"
        )
    return 1.0 + np.asarray(nu, dtype=float)


def thermal_strain(model: Any, cloud: PointCloud, thermal: ThermalExpansion) -> np.ndarray:
    """Return the free (eigen)strain per point ``(n,)``: ``α ΔT`` (``(1+ν) α ΔT`` in plane strain).

    Parameters
    ----------
    model : Model
        The model (its ``plane`` and ``nu`` in 2D).
    cloud : PointCloud
        The points.
    thermal : ThermalExpansion
        Temperature change and coefficient.

    Returns
    -------
    (n,) ndarray of float
        The isotropic free strain of each point.

    Raises
    ------
    InputTypeError
        When ``thermal`` is not a :class:`ThermalExpansion`.
    ShapeError
        When ``ΔT`` or ``α`` is neither a scalar nor one value per point.
    ModelError
        In plane strain for a model without a Poisson's ratio.

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((3, 3))
    >>> thermal_strain(pdlin.LPS(E=1.0, nu=0.25, plane="strain"), cloud,
    ...     ThermalExpansion(10.0, 1e-5)).round(12).tolist()[:2]
    [0.000125, 0.000125]
    """
    if not isinstance(thermal, ThermalExpansion):
        raise InputTypeError(f"thermal must be a ThermalExpansion, got {type(thermal).__name__}")
    dT = thermal.temperature(cloud)
    alpha = _per_point(thermal.alpha, cloud.n, "thermal.alpha")
    return np.asarray(alpha * dT * _plane_factor(model, cloud), dtype=float)


def _bond_extension(cloud: PointCloud, bonds: Bonds, eps: np.ndarray) -> np.ndarray:
    """Return the free extension of each directed bond, ``(ε_i + ε_j) / 2 |ξ|``."""
    return 0.5 * (eps[bonds.i] + eps[bonds.j]) * bonds.length


def _check_model(model: Any) -> None:
    if getattr(model, "nonlinear", False):
        raise ModelError(
            f"thermal expansion is an eigenstrain of the linear models; {type(model).__name__} "
            "is nonlinear here (material= / finite kinematics): use its linear form"
        )
    if not isinstance(model, BondBased | OrdinaryStateBased | Correspondence):
        raise ModelError(
            "thermal expansion is available for BondBased, LPS, XOSB and Correspondence, got "
            f"{type(model).__name__}"
        )


def _bb_bond_force(model: BondBased, cloud: PointCloud, bonds: Bonds, e: np.ndarray) -> np.ndarray:
    """Linear bond-based force ``Σ_j k_b e_b n_b`` of an extension state ``e``."""
    k = model.bond_stiffness(cloud, bonds)
    unit = bonds.xi / bonds.length[:, None]
    tb = k * e
    return np.stack(
        [
            np.bincount(bonds.i, weights=tb * unit[:, a], minlength=cloud.n)
            for a in range(cloud.dim)
        ],
        axis=1,
    )


def _bb_bond_stress(model: BondBased, cloud: PointCloud, bonds: Bonds, e: np.ndarray) -> np.ndarray:
    """Return the virial stress of :meth:`pdlin.BondBased.stress` for an extension state ``e``."""
    d = cloud.dim
    c = model.corrected_micromodulus(cloud, bonds)
    meas = 1.0 if d == 3 else cloud.thickness
    unit = bonds.xi / bonds.length[:, None]
    w = 0.5 * c * bonds.omega * e * bonds.volume_j * meas
    sig = np.empty((cloud.n, d, d))
    for a in range(d):
        for b in range(a, d):
            v = np.bincount(bonds.i, weights=w * unit[:, a] * unit[:, b], minlength=cloud.n)
            sig[:, a, b] = v
            sig[:, b, a] = v
    return sig


def _correspondence_stress(model: Correspondence, cloud: PointCloud, eps: np.ndarray) -> np.ndarray:
    """``C_i : (ε_i I)`` per point ``(n, d, d)``."""
    d = cloud.dim
    P = voigt_projector(d)
    ev = (np.eye(d).ravel() @ P.T)[None, :] * eps[:, None]  # Voigt eigenstrain per point
    sv = np.einsum("gab,gb->ga", model.voigt_stiffness(cloud), ev)
    return np.asarray((sv @ P).reshape(cloud.n, d, d))


def thermal_force(
    model: Any, cloud: PointCloud, bonds: Bonds, thermal: ThermalExpansion
) -> np.ndarray:
    """Return the thermal load ``f_th`` ``(n, dim)`` of ``K u = f_ext + f_th``.

    ``f_th = -F(e_th)``: minus the model's linear force of the free bond extensions
    ``e_th = α ΔT_ij |ξ|`` (bond-based, LPS, XOSB) or of the stress ``C : α ΔT I``
    (correspondence); see the module docstring.  It is self-equilibrated (no net force).

    Parameters
    ----------
    model : BondBased, LPS, XOSB or Correspondence
        A linear model.
    cloud : PointCloud
        The points.
    bonds : Bonds
        Their bonds.
    thermal : ThermalExpansion
        Temperature change and coefficient.

    Returns
    -------
    (n, dim) ndarray of float
        Nodal thermal load.

    Raises
    ------
    ModelError
        For another model, a nonlinear one, or plane strain without a Poisson's ratio.

    Examples
    --------
    For a uniform ``ΔT`` the load is ``K`` times the free expansion ``α ΔT x``:

    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((6, 6), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=3.015)
    >>> model = pdlin.LPS(E=1.0, nu=0.25)
    >>> f = thermal_force(model, cloud, bonds, ThermalExpansion(50.0, 2e-5))
    >>> Ku = model.stiffness(cloud, bonds) @ (1e-3 * cloud.points).ravel()
    >>> bool(np.allclose(f.ravel(), Ku, rtol=0, atol=1e-14))
    True
    """
    _check_model(model)
    eps = thermal_strain(model, cloud, thermal)
    if isinstance(model, Correspondence):
        return -np.asarray(model.nodal_force(cloud, bonds, _gp_stress(model, cloud, bonds, eps)))
    e = _bond_extension(cloud, bonds, eps)
    if isinstance(model, BondBased):
        return -_bb_bond_force(model, cloud, bonds, e)
    force, _ = model.extension_response(cloud, bonds, e)
    return -force


def _gp_stress(
    model: Correspondence, cloud: PointCloud, bonds: Bonds, eps: np.ndarray
) -> np.ndarray:
    """Return the eigenstress ``C : ε I`` of each gradient point's owner."""
    owner = model.stress_points(cloud, bonds)["owner"]
    return _correspondence_stress(model, cloud, eps)[owner]


def thermal_stress(
    model: Any, cloud: PointCloud, bonds: Bonds, thermal: ThermalExpansion
) -> np.ndarray:
    """Return the stress of the free thermal strain ``(n, dim, dim)``, as the model computes it.

    The model's stress of the total displacement minus this is the (mechanical) stress of
    the thermo-elastic problem: zero for a free expansion.

    Parameters
    ----------
    model : BondBased, LPS, XOSB or Correspondence
        A linear model.
    cloud : PointCloud
        The points.
    bonds : Bonds
        Their bonds.
    thermal : ThermalExpansion
        Temperature change and coefficient.

    Returns
    -------
    (n, dim, dim) ndarray of float
        ``σ(e_th)`` (bond-based virial, state-based ``Σ t n ⊗ ξ V``) or ``C : α ΔT I``.

    Raises
    ------
    ModelError
        As :func:`thermal_force`.

    Examples
    --------
    In 3D a uniform ``α ΔT`` gives ``3 K α ΔT I`` at a point with a full family:

    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((7, 7, 7), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=3.015)
    >>> s = thermal_stress(pdlin.LPS(K=2.0, G=1.0), cloud, bonds, ThermalExpansion(10.0, 1e-3))
    >>> np.round(s[171], 12).tolist()[0]  # the centre: 3 K α ΔT = 0.06
    [0.06, 0.0, 0.0]
    """
    _check_model(model)
    eps = thermal_strain(model, cloud, thermal)
    if isinstance(model, Correspondence):
        return _correspondence_stress(model, cloud, eps)
    e = _bond_extension(cloud, bonds, eps)
    if isinstance(model, BondBased):
        return _bb_bond_stress(model, cloud, bonds, e)
    _, stress = model.extension_response(cloud, bonds, e)
    return np.asarray(stress)


def mechanical_strain(
    strain: np.ndarray, model: Any, cloud: PointCloud, thermal: ThermalExpansion
) -> np.ndarray:
    """Return ``ε - ε_th I`` per point: a total strain ``(n, d, d)`` less the free strain.

    Parameters
    ----------
    strain : (n, d, d) ndarray
        Total small strain.
    model : Model
        The model (plane strain factor).
    cloud : PointCloud
        The points.
    thermal : ThermalExpansion
        Temperature change and coefficient.

    Returns
    -------
    (n, d, d) ndarray of float

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((2,))
    >>> mechanical_strain(np.full((2, 1, 1), 3e-3), pdlin.BondBased(E=1.0), cloud,
    ...     ThermalExpansion(100.0, 1e-5)).ravel().round(12).tolist()
    [0.002, 0.002]
    """
    eps = thermal_strain(model, cloud, thermal)
    d = cloud.dim
    return np.asarray(strain - eps[:, None, None] * np.eye(d))


def check_thermal(value: Any) -> ThermalExpansion | None:
    """Return ``value`` checked as a :class:`ThermalExpansion` or None.

    Parameters
    ----------
    value : Any
        ``StaticProblem(thermal=...)``.

    Returns
    -------
    ThermalExpansion or None
        ``value`` itself.

    Raises
    ------
    InputTypeError
        For anything else.
    """
    if value is None or isinstance(value, ThermalExpansion):
        return value
    raise InputTypeError(f"thermal must be a ThermalExpansion or None, got {type(value).__name__}")
