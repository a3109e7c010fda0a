"""Linearized bond-based peridynamics (and the nonlinear PMB force)."""

from __future__ import annotations

import itertools
import logging
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from .._lazy import quad
from .._validation import as_displacement, as_float_array
from ..constitutive.symmetry import isotropic_constants
from ..errors import InputError, ModelError, ShapeError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from ..geometry.influence import influence_function
from ..operators.assembly import pair_stiffness_bsr
from .base import Model
from .ordinary_state import uniform_nu_constants
from .surface import (
    SurfaceFactors,
    angular_moment,
    check_surface_correction,
    ellipsoid_bond_factors,
    harmonic_bond_factors,
    radial_moment,
    ratio_factors,
    volume_point_factors,
)

__all__ = ["BondBased", "implied_poisson_ratio", "standard_micromodulus"]

log = logging.getLogger(__name__)

_PLANES = ("stress", "strain")


def implied_poisson_ratio(dim: int, plane: str = "stress") -> float:
    """Return the Poisson ratio fixed by bond-based PD (Cauchy relations).

    1/4 in 3D and 2D plane strain, 1/3 in 2D plane stress; 1D has no
    lateral response (returns 0).

    Parameters
    ----------
    dim : {1, 2, 3}
        Spatial dimension.
    plane : {'stress', 'strain'}
        2D assumption (ignored in 1D and 3D).

    Returns
    -------
    float
        The implied Poisson ratio.

    Raises
    ------
    InputError
        If ``dim`` is not 1-3 or (2D) ``plane`` is unknown.

    Examples
    --------
    >>> implied_poisson_ratio(3), implied_poisson_ratio(2, "stress")
    (0.25, 0.3333333333333333)
    """
    if dim == 3:
        return 0.25
    if dim == 2:
        if plane not in _PLANES:
            raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
        return 1.0 / 3.0 if plane == "stress" else 0.25
    if dim == 1:
        return 0.0
    raise InputError(f"dim must be 1, 2 or 3, got {dim}")


def _c1111(E: np.ndarray, dim: int, plane: str) -> np.ndarray:
    """Axial modulus C_1111 of the isotropic material with the implied nu."""
    nu = implied_poisson_ratio(dim, plane)
    if dim == 1:
        return E
    if dim == 2 and plane == "stress":
        return E / (1.0 - nu**2)
    return E * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu))


def _moment(influence: Any, horizon: float, dim: int) -> float:
    """∫_0^δ ω(r) r^p dr with p = 1, 2, 3 for dim = 1, 2, 3."""
    fn = influence_function(influence)
    p = dim

    def integrand(r: float) -> float:
        return float(fn(np.array([r]), np.array([horizon]))[0]) * r**p

    if influence == "constant":
        return horizon ** (p + 1) / (p + 1)
    val, _ = quad(integrand, 0.0, horizon, limit=200)
    return float(val)


def standard_micromodulus(
    E: float | np.ndarray,
    horizon: float | np.ndarray,
    dim: int,
    *,
    plane: str = "stress",
    thickness: float = 1.0,
    influence: Any = "constant",
) -> np.ndarray:
    """Return the micromodulus matching E in the continuum limit (full spherical horizon).

    Equates ``C_1111 = (c/2) ∫ ω ξ₁⁴/|ξ|³ dV`` with the isotropic
    ``C_1111`` of the implied Poisson ratio.  For ω = 1 this gives the
    standard constants: ``12E/(πδ⁴)`` (3D, = 18K/(πδ⁴)), ``9E/(πtδ³)``
    (plane stress), ``48E/(5πtδ³)`` (plane strain), ``2E/(Aδ²)`` (1D, A =
    cross-section passed as ``thickness``).

    Parameters
    ----------
    E : float or ndarray of float
        Young's modulus.
    horizon : float or ndarray of float
        Horizon δ (broadcast against ``E``).
    dim : {1, 2, 3}
        Spatial dimension.
    plane : {'stress', 'strain'}
        2D assumption.
    thickness : float
        Out-of-plane thickness (2D) or cross-section area (1D).
    influence : str or callable
        Influence function; non-constant ones are integrated numerically.

    Returns
    -------
    ndarray of float
        Micromodulus ``c``, shape of the broadcast inputs (units of ``E`` per
        length⁴ in 3D and, with the thickness, in 2D).

    Examples
    --------
    >>> import numpy as np
    >>> c = standard_micromodulus(1.0, 2.0, 3)
    >>> bool(np.isclose(c, 12 / (np.pi * 2.0**4)))
    True
    """
    Ea = np.asarray(E, dtype=float)
    hor = np.asarray(horizon, dtype=float)
    c11 = _c1111(Ea, dim, plane)
    uniq, inv = np.unique(np.atleast_1d(hor), return_inverse=True)
    mom = np.array([_moment(influence, float(h), dim) for h in uniq])[inv].reshape(hor.shape)
    if dim == 3:
        denom = 0.4 * np.pi * mom  # (1/2)(4π/5)
    elif dim == 2:
        denom = 0.375 * np.pi * thickness * mom  # (1/2)(3π/4) t
    else:
        denom = thickness * mom  # (1/2) * 2 A
    return np.asarray(c11 / denom)


class BondBased(Model):
    """Linearized bond-based peridynamics with a micromodulus per bond.

    Pair force density ``f = c ω s M`` (``s`` bond stretch, ``M`` the
    bond direction); nodal stiffness blocks
    ``K[i, j] = -c ω V_i V_j n nᵀ / |ξ|``.

    Parameters
    ----------
    E : float or (n,) array_like, optional
        Young's modulus (per point for graded materials).  Needed unless
        ``micromodulus``, or ``K``, ``G`` or ``lam``, is given.
    nu : float, optional
        Poisson ratio requested by the user.  Bond-based PD implies
        ν = 1/4 (3D, plane strain) or 1/3 (plane stress); another value
        raises :class:`~pdlin.errors.ModelError` (or warns, see
        ``nu_mismatch``).
    K, G, lam, mu : float or (n,) array_like, optional
        Bulk modulus, shear modulus (``mu`` is the same) or Lamé's first
        constant (3D constants, as in Peridigm decks).  One of them alone
        fixes ``E`` through the implied Poisson ratio
        (:meth:`young_modulus`); two constants (with ``E`` or ``nu`` too)
        fix ``E`` and ``nu``, and ``nu`` is then checked like ``nu``.
    plane : {'stress', 'strain'}
        2D assumption.
    micromodulus : float or (nb,) array_like, optional
        Explicit micromodulus (scalar or one per directed bond, symmetric
        over bond pairs), e.g. from :func:`pdlin.calibrate_micromoduli`.
    average : {'arithmetic', 'harmonic'}
        How a bond combines the per-point moduli of its two ends.
    nu_mismatch : {'raise', 'warn'}
        What a ``nu`` other than the implied one does (see :meth:`check`).
    kinematics : {'small', 'finite'}
        ``'finite'``: the model is the prototype microelastic (PMB) force with
        the exact stretch ``(|ξ+η| - |ξ|)/|ξ|`` along the deformed bond
        (geometrically nonlinear: exact under finite rigid rotations), solved by
        :func:`pdlin.solve_nonlinear` with its consistent tangent
        ``k [(|ξ|/|y|) n nᵀ + (1 - |ξ|/|y|) I]`` per bond (``y = ξ + η``,
        ``n = y/|y|``).  ``'small'`` (default): the linearized model.
    surface_correction : {None, 'volume', 'energy', 'force-normalization'}
        Surface correction of the micromodulus near free surfaces (Le &
        Bobaru 2018, see ``pdlin.models.surface`` and
        ``docs/bond_based.md``): a factor per bond, symmetric over the pair,
        computed once per ``(cloud, bonds)`` and used by ``stiffness``,
        ``internal_force``, ``stress`` and ``effective_tensor``.

    Raises
    ------
    InputError
        If an option is unknown, a modulus is not > 0, a micromodulus is negative,
        or the elastic constants and the micromodulus are both or neither given.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((10,), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=2.0)
    >>> model = pdlin.BondBased(E=200e9)
    >>> K = pdlin.operators.assemble_stiffness(model, cloud, bonds)
    >>> u = np.random.default_rng(0).normal(size=(10, 1))
    >>> bool(np.allclose(K @ u.ravel(), -model.internal_force(cloud, bonds, u).ravel()))
    True
    >>> pdlin.BondBased(E=1.0, nu=0.3).check(3)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.ModelError: bond-based PD implies nu = 0.25 in 3D, got nu = 0.3; ...

    With a surface correction the end points of the bar get stiffer bonds:

    >>> sc = pdlin.BondBased(E=200e9, surface_correction="volume")
    >>> g = sc.surface_factors(cloud, bonds).bond
    >>> round(float(g[0]), 3), round(float(g[bonds.indptr[5]]), 3)   # end bond, interior bond
    (1.6, 1.0)
    """

    coupling_range = 1
    symmetric = True

    def __init__(
        self,
        E: float | np.ndarray | None = None,
        *,
        nu: float | None = None,
        K: Any = None,
        G: Any = None,
        lam: Any = None,
        mu: Any = None,
        plane: str = "stress",
        micromodulus: float | np.ndarray | None = None,
        average: str = "arithmetic",
        nu_mismatch: str = "raise",
        surface_correction: str | None = None,
        kinematics: str = "small",
    ) -> None:
        if kinematics not in ("small", "finite"):
            raise InputError(f"kinematics must be 'small' or 'finite', got {kinematics!r}")
        self.kinematics = kinematics
        #: finite kinematics: the PMB force of the exact stretch along the deformed bond,
        #: solved by :func:`pdlin.solve_nonlinear`
        self.nonlinear = kinematics == "finite"
        self.surface_correction = check_surface_correction(surface_correction, "BondBased")
        self._surface_cache: tuple[PointCloud, Bonds, SurfaceFactors] | None = None
        given = {"E": E, "nu": nu, "K": K, "G": G if G is not None else mu, "lam": lam}
        names = [k for k, v in given.items() if v is not None]
        #: a single modulus other than E (K, G or lam), converted to E with the implied ν
        self.modulus: tuple[str, np.ndarray] | None = None
        if micromodulus is not None and set(names) - {"nu"}:
            raise InputError(
                "BondBased takes either elastic constants or an explicit micromodulus, got "
                f"micromodulus and {', '.join(k for k in names if k != 'nu')}"
            )
        if len(names) >= 2:
            E, nu = uniform_nu_constants("BondBased", E, nu, K=K, G=G, lam=lam, mu=mu)
        elif names and names[0] in ("K", "G", "lam"):
            self.modulus = (names[0], as_float_array(given[names[0]], names[0]))
            if np.any(self.modulus[1] <= 0):
                raise InputError(f"{names[0]} must be > 0, got {given[names[0]]!r}")
        if E is None and micromodulus is None and self.modulus is None:
            raise InputError(
                "BondBased needs E (or K, G, lam, or two isotropic constants) or micromodulus, "
                f"got {', '.join(names) or 'none'}"
            )
        self.E = None if E is None else as_float_array(E, "E")
        if self.E is not None and np.any(self.E <= 0):
            raise InputError(f"E must be > 0, got min {float(np.min(self.E))}")
        if plane not in _PLANES:
            raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
        if average not in ("arithmetic", "harmonic"):
            raise InputError(f"average must be 'arithmetic' or 'harmonic', got {average!r}")
        if nu_mismatch not in ("raise", "warn"):
            raise InputError(f"nu_mismatch must be 'raise' or 'warn', got {nu_mismatch!r}")
        self.nu = None if nu is None else float(nu)
        self.plane = plane
        self.average = average
        self.nu_mismatch = nu_mismatch
        self.micromodulus = (
            None if micromodulus is None else as_float_array(micromodulus, "micromodulus")
        )
        if self.micromodulus is not None and np.any(self.micromodulus < 0):
            raise InputError(
                "micromodulus must be >= 0 (energy positivity), "
                f"got min {float(self.micromodulus.min())}"
            )

    # -- parameters -------------------------------------------------------
    def implied_poisson_ratio(self, dim: int) -> float:
        """Return the Poisson ratio of this model in ``dim`` dimensions.

        Parameters
        ----------
        dim : {1, 2, 3}
            Spatial dimension.

        Returns
        -------
        float
            1/4 (3D, plane strain), 1/3 (plane stress) or 0 (1D).
        """
        return implied_poisson_ratio(dim, self.plane)

    def young_modulus(self, dim: int) -> np.ndarray:
        """Return Young's modulus (scalar or per point) in ``dim`` dimensions.

        With a single ``K``, ``G`` or ``lam`` it is converted with the
        implied Poisson ratio of ``dim`` / ``plane`` (the constants are 3D
        ones, as in Peridigm decks).

        Parameters
        ----------
        dim : {1, 2, 3}
            Spatial dimension.

        Returns
        -------
        ndarray of float
            ``E``, a 0-d array or one value per point.

        Raises
        ------
        ModelError
            If the model has only an explicit micromodulus, or is 1D with a single
            ``K``, ``G`` or ``lam``.

        Examples
        --------
        >>> import pdlin
        >>> float(pdlin.BondBased(K=2.0).young_modulus(3))   # E = 3 K (1 - 2/4)
        3.0
        >>> float(pdlin.BondBased(G=2.0).young_modulus(2))   # plane stress: E = 2 G (1 + 1/3)
        5.333333333333333
        """
        if self.E is not None:
            return self.E
        if self.modulus is None:
            raise ModelError("BondBased has an explicit micromodulus and no Young's modulus")
        name, value = self.modulus
        if dim == 1:
            raise ModelError(
                f"a 1D bond-based model needs E (no Poisson ratio relates {name} to E in 1D), "
                f"got {name}"
            )
        kw: dict[str, Any] = {name: value}
        E, _ = isotropic_constants(None, self.implied_poisson_ratio(dim), **kw)
        return np.asarray(E, dtype=float)

    def check(self, dim: int) -> None:
        """Validate the requested Poisson ratio against the implied one.

        Parameters
        ----------
        dim : {1, 2, 3}
            Spatial dimension.

        Raises
        ------
        ModelError
            If ``nu`` differs from the implied value and ``nu_mismatch='raise'``
            (with ``'warn'`` a UserWarning is issued instead).
        """
        if self.nu is None or dim == 1:
            return
        implied = self.implied_poisson_ratio(dim)
        if abs(self.nu - implied) > 1e-12:
            where = "3D" if dim == 3 else f"2D plane {self.plane}"
            msg = (
                f"bond-based PD implies nu = {implied:.4g} in {where}, got nu = {self.nu}; "
                "use nu=None or a state-based model (LPS) for other Poisson ratios"
            )
            if self.nu_mismatch == "raise":
                raise ModelError(msg)
            warnings.warn(msg, stacklevel=3)

    def bond_micromodulus(self, cloud: PointCloud, bonds: Bonds) -> np.ndarray:
        """Return the micromodulus per directed bond (without surface correction).

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.

        Returns
        -------
        ndarray of float, shape (n_bonds,)
            The explicit micromodulus, or the one matching ``E`` (bond ends averaged by
            ``average``) on each bond's horizon.

        Raises
        ------
        ShapeError
            If a per-bond micromodulus or per-point ``E`` has the wrong length.
        ModelError
            If the requested Poisson ratio is refused (see :meth:`check`).
        """
        c = self._micromodulus(cloud, bonds)
        return np.full(bonds.n_bonds, c) if isinstance(c, float) else c

    def _micromodulus(self, cloud: PointCloud, bonds: Bonds) -> float | np.ndarray:
        """:meth:`bond_micromodulus`, a float when it is the same for every bond."""
        self.check(cloud.dim)
        nb = bonds.n_bonds
        if self.micromodulus is not None:
            c = self.micromodulus
            if c.ndim == 0:
                return float(c)
            if c.shape != (nb,):
                raise ShapeError(
                    f"micromodulus must be a scalar or have shape ({nb},), got {c.shape}"
                )
            return c
        E = self.young_modulus(cloud.dim)
        if E.ndim == 0:
            Eb: np.ndarray | float = float(E)
        else:
            if E.shape != (cloud.n,):
                raise ShapeError(f"E must be a scalar or have shape ({cloud.n},), got {E.shape}")
            if self.average == "arithmetic":
                Eb = 0.5 * (E[bonds.i] + E[bonds.j])
            else:
                Eb = 2.0 / (1.0 / E[bonds.i] + 1.0 / E[bonds.j])
        hor = bonds.horizon
        influence = getattr(bonds, "influence", "constant")
        if np.all(hor == hor[0]):
            cb = (
                standard_micromodulus(
                    1.0,
                    float(hor[0]),
                    cloud.dim,
                    plane=self.plane,
                    thickness=cloud.thickness,
                    influence=influence,
                )
                * Eb
            )
            return float(cb) if np.ndim(cb) == 0 else np.broadcast_to(cb, (nb,)).astype(float)
        cb = standard_micromodulus(
            1.0,
            bonds.horizon_ij,
            cloud.dim,
            plane=self.plane,
            thickness=cloud.thickness,
            influence=influence,
        )
        return np.asarray(cb * Eb, dtype=float)

    def surface_factors(self, cloud: PointCloud, bonds: Bonds) -> SurfaceFactors | None:
        """Return the surface-correction factors on ``bonds`` (None without correction).

        Cached for the last ``(cloud, bonds)`` pair.  ``bond`` multiplies the
        micromodulus of :meth:`bond_micromodulus` (which stays uncorrected).

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.

        Returns
        -------
        SurfaceFactors or None
            Per-point, per-direction factors and the symmetric per-bond factor.
        """
        method = self.surface_correction
        if method is None:
            return None
        cache = self._surface_cache
        if cache is not None and cache[0] is cloud and cache[1] is bonds:
            return cache[2]
        n, d = cloud.n, cloud.dim
        if method == "volume":
            m = volume_point_factors(cloud, bonds)
            g = np.repeat(m[:, None], d, axis=1)
            gb = harmonic_bond_factors(m, bonds)
        else:
            c = self.bond_micromodulus(cloud, bonds) * bonds.omega
            # each per-bond array read once (a compact Bonds computes it on every read)
            bi, length, vol = bonds.i, bonds.length, bonds.volume_j
            unit = np.abs(bonds.xi / length[:, None])
            infl = getattr(bonds, "influence", "constant")
            hij = bonds.horizon_ij
            if method == "energy":
                # W_i = ¼ Σ c ω n_k⁴ r V_j under u = x_k e_k; bulk ¼ c A₄ ∫ω r^d dr
                w = c * length * vol
                bulk = c * angular_moment(d, 4) * radial_moment(infl, hij, d)
                power = 4
            else:
                # F_i = Σ |c ω s n_k| V_j with s = n_k²; bulk c A₃ ∫ω r^(d-1) dr
                w = c * vol
                bulk = c * angular_moment(d, 3) * radial_moment(infl, hij, d - 1)
                power = 3
            disc = np.empty((n, d))
            for k in range(d):
                disc[:, k] = np.bincount(bi, weights=w * unit[:, k] ** power, minlength=n)
            count = np.maximum(np.diff(bonds.indptr), 1)
            target = np.bincount(bi, weights=bulk, minlength=n) / count
            g = ratio_factors(target[:, None], disc)
            gb = ellipsoid_bond_factors(g, bonds)
        out = SurfaceFactors(method, g, np.ones(n), gb)
        self._surface_cache = (cloud, bonds, out)
        return out

    def corrected_micromodulus(self, cloud: PointCloud, bonds: Bonds) -> np.ndarray:
        """Return the micromodulus per directed bond times its surface-correction factor.

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.

        Returns
        -------
        ndarray of float, shape (n_bonds,)
            Corrected micromodulus (equal to :meth:`bond_micromodulus` without correction).
        """
        c = self.bond_micromodulus(cloud, bonds)
        sf = self.surface_factors(cloud, bonds)
        return c if sf is None else c * sf.bond

    def bond_stiffness(self, cloud: PointCloud, bonds: Bonds) -> np.ndarray:
        """Return the scalar bond stiffness ``k_b = c ω V_i V_j t / |ξ|``.

        Nodal units, with the surface-corrected micromodulus.

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.

        Returns
        -------
        ndarray of float, shape (n_bonds,)
            Stiffness per directed bond (force per length).

        Raises
        ------
        ModelError
            If a bond stiffness is negative (a signed influence weight).
        """
        return self._bond_stiffness_fn(cloud, bonds)(0, bonds.n_bonds)

    def _bond_stiffness_fn(
        self, cloud: PointCloud, bonds: Bonds
    ) -> Callable[[int, int], np.ndarray]:
        """``fn(b0, b1)``: :meth:`bond_stiffness` of the bonds ``b0:b1`` (elementwise).

        The assembly evaluates it chunk by chunk on its worker threads.
        """
        c = self._micromodulus(cloud, bonds)
        sf = self.surface_factors(cloud, bonds)
        vol = _effective_volumes(cloud)
        meas = _measure(cloud)

        def fn(b0: int, b1: int) -> np.ndarray:
            cb = c if isinstance(c, float) else c[b0:b1]
            if sf is not None:
                cb = cb * sf.bond[b0:b1]
            k = cb * bonds.values("omega", b0, b1)
            k = k * vol[bonds.values("i", b0, b1)]
            k *= bonds.values("volume_j", b0, b1) * meas
            k /= bonds.values("length", b0, b1)
            if k.size and k.min() < 0:
                b = int(np.argmin(k))
                raise ModelError(
                    f"bond stiffness c*omega must be >= 0 (energy positivity), got {k[b]:.3g} "
                    f"at bond {b0 + b} (omega {bonds.values('omega', b0 + b, b0 + b + 1)[0]:.3g}); "
                    "signed influence "
                    "weights belong to correspondence models"
                )
            return k

        return fn

    # -- operators ----------------------------------------------------------
    def stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.bsr_array:
        """Assemble the BSR stiffness (see class docstring).

        The bond stiffness is computed chunk by chunk inside the threaded assembly
        (:func:`pdlin.set_num_threads`): bitwise the same for any thread count.

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.

        Returns
        -------
        scipy.sparse.bsr_array, shape (n * dim, n * dim)
            Symmetric positive semi-definite stiffness with ``dim x dim`` blocks.
        """
        return pair_stiffness_bsr(bonds, self._bond_stiffness_fn(cloud, bonds))

    def surrogate_stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.bsr_array:
        """Return the one-hop matrix that preconditions the matrix-free path.

        It is the stiffness of a plain ``BondBased(E, plane)`` on the same bonds: this
        model's own options (per-bond micromoduli, surface corrections, averaging) are
        left out, which keeps the preconditioner cheap to assemble.  Without an ``E``
        (micromoduli given directly) it is the model's own stiffness.

        Parameters
        ----------
        cloud : PointCloud
            The points.
        bonds : Bonds
            Their bonds.

        Returns
        -------
        scipy.sparse.bsr_array, shape (n * dim, n * dim)
            The plain bond-based stiffness.
        """
        if self.E is None:
            return super().surrogate_stiffness(cloud, bonds)
        return BondBased(E=self.E, plane=self.plane).stiffness(cloud, bonds)

    def internal_force(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, linear: bool = True
    ) -> np.ndarray:
        """Compute the nodal internal force.

        ``linear=True`` uses the linearized stretch ``n·η/|ξ|`` along the
        reference direction (so ``f == -K u``); ``linear=False`` is the
        prototype microelastic brittle (PMB) form with the exact stretch
        ``(|ξ+η| - |ξ|)/|ξ|`` along the deformed direction.

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.
        u : (n, dim) or (n * dim,) array_like of float
            Displacement per point.
        linear : bool
            Linearized (True) or exact (False) stretch.

        Returns
        -------
        ndarray of float, shape (n, dim)
            Internal force per point (nodal units).

        Raises
        ------
        InputError
            With ``linear=False``, if ``u`` collapses a bond to zero length.
        """
        # compact bonds compute these on each access: read them once
        bi = bonds.i
        bxi = bonds.xi
        blen = bonds.length
        d = cloud.dim
        uu = as_displacement(u, cloud.n, d)
        k = self.bond_stiffness(cloud, bonds)
        eta = uu[bonds.j] - uu[bi]
        if linear:
            unit = bxi / blen[:, None]
            tb = k * np.einsum("ij,ij->i", unit, eta)
            vec = tb[:, None] * unit
        else:
            y = bxi + eta
            ly = np.sqrt(np.einsum("ij,ij->i", y, y))
            if np.any(ly <= 0):
                raise InputError("u collapses a bond to zero length; the PMB force is undefined")
            stretch_len = ly - blen  # = s |ξ|
            tb = k * stretch_len
            vec = tb[:, None] * (y / ly[:, None])
        f = np.empty((cloud.n, d))
        for a in range(d):
            f[:, a] = np.bincount(bi, weights=vec[:, a], minlength=cloud.n)
        return f

    def stress(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Compute the per-point virial stress ``σ_i = ½ Σ_j c ω s (ξ⊗ξ/|ξ|) V_j``.

        Equals ``C_i : ε`` for affine fields, with ``C_i`` the point's
        effective tensor (:meth:`effective_tensor`), also at truncated families.

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.
        u : (n, dim) or (n * dim,) array_like of float
            Displacement per point.

        Returns
        -------
        ndarray of float, shape (n, dim, dim)
            Symmetric stress per point (linearized stretch).
        """
        d = cloud.dim
        uu = as_displacement(u, cloud.n, d)
        c = self.corrected_micromodulus(cloud, bonds)
        # each per-bond array read once (a compact Bonds computes it on every read)
        bi, length = bonds.i, bonds.length
        eta = uu[bonds.j] - uu[bi]
        unit = bonds.xi / length[:, None]
        s_len = np.einsum("ij,ij->i", unit, eta)  # s |ξ|
        w = 0.5 * c * bonds.omega * s_len * bonds.volume_j * _measure(cloud) / length
        sig = np.empty((cloud.n, d, d))
        for a in range(d):
            for b in range(a, d):
                v = np.bincount(bi, weights=w * unit[:, a] * unit[:, b] * length, minlength=cloud.n)
                sig[:, a, b] = v
                sig[:, b, a] = v
        return sig

    def effective_tensor(self, cloud: PointCloud, bonds: Bonds) -> np.ndarray:
        """Compute the per-point stiffness tensor ``C_ijkl = ½ Σ ω c ξ_iξ_jξ_kξ_l/|ξ|³ V_j``.

        Prakash, anisotropic micromoduli, Eq. 29, over the point's actual
        (possibly truncated) family, with the surface-corrected micromodulus.

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.

        Returns
        -------
        ndarray of float, shape (n, d, d, d, d)
            Fully symmetric fourth-order tensor per point.
        """
        d = cloud.dim
        c = self.corrected_micromodulus(cloud, bonds)
        bi, length = bonds.i, bonds.length  # read once (computed on each read when compact)
        unit = bonds.xi / length[:, None]
        w = 0.5 * c * bonds.omega * bonds.volume_j * _measure(cloud) * length
        out = np.empty((cloud.n, d, d, d, d))
        for idx in itertools.product(range(d), repeat=4):
            srt = tuple(sorted(idx))
            if srt != idx:
                out[(slice(None),) + idx] = out[(slice(None),) + srt]
                continue
            prod = w * unit[:, idx[0]] * unit[:, idx[1]] * unit[:, idx[2]] * unit[:, idx[3]]
            out[(slice(None),) + idx] = np.bincount(bi, weights=prod, minlength=cloud.n)
        return out

    def respond(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray,
        state: dict[str, np.ndarray],
        *,
        tangent: bool = False,
    ) -> Any:
        """Return force, state and tangent for the nonlinear drivers (``Model.respond``).

        With ``kinematics='finite'`` the PMB force and its consistent tangent
        (symmetric, BSR); otherwise the linear model.

        Parameters
        ----------
        cloud : PointCloud
            The points (dimension, volumes, thickness).
        bonds : Bonds
            Bonds of ``cloud``.
        u : (n, dim) or (n * dim,) array_like of float
            Displacement per point.
        state : dict of str to ndarray
            Committed history (bond-based PD has none; passed through).
        tangent : bool
            Also return the tangent stiffness.

        Returns
        -------
        Response
            ``force`` (``(n, dim)``), ``state``, and the tangent ``K`` (None unless
            ``tangent``).

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((4, 4), spacing=0.1)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.5)
        >>> m = pdlin.BondBased(E=1.0, kinematics="finite")
        >>> Q = np.array([[0.0, -1.0], [1.0, 0.0]])           # a 90 degree rigid rotation
        >>> u = cloud.points @ Q.T - cloud.points
        >>> r = m.respond(cloud, bonds, u, {})
        >>> float(np.abs(r.force).max()) < 1e-15             # no force: finite kinematics
        True
        """
        from .base import Response

        if self.kinematics == "small":
            return super().respond(cloud, bonds, u, state, tangent=tangent)
        f = self.internal_force(cloud, bonds, u, linear=False)
        K = None
        if tangent:
            uu = as_displacement(u, cloud.n, cloud.dim)
            y = bonds.xi + uu[bonds.j] - uu[bonds.i]
            ly = np.sqrt(np.einsum("ij,ij->i", y, y))
            k = self.bond_stiffness(cloud, bonds)
            ratio = bonds.length / ly
            K = pair_stiffness_bsr(bonds, k * ratio, y / ly[:, None])
            b = k * (1.0 - ratio)
            if np.any(b != 0.0):
                n, d = cloud.n, cloud.dim
                lap = sp.csr_array((-b, (bonds.i, bonds.j)), shape=(n, n))
                lap = lap + sp.diags_array(np.bincount(bonds.i, weights=b, minlength=n))
                iso = sp.kron(lap, sp.eye_array(d), format="bsr")
                K = sp.bsr_array(K + iso, blocksize=(d, d))
        return Response(np.asarray(f), dict(state), K, None, 0)

    def describe(self) -> dict[str, Any]:
        """Return the model's parameters as plain data.

        Returns
        -------
        dict
            ``model``, ``E`` (None if per point or absent), the single modulus if
            given, ``plane``, ``micromodulus`` (a float, ``'per-bond'`` or None)
            and ``surface_correction``.
        """
        return {
            "model": "BondBased",
            "E": None if self.E is None or self.E.ndim else float(self.E),
            **({} if self.modulus is None else {self.modulus[0]: _scalar_or_tag(self.modulus[1])}),
            "plane": self.plane,
            "micromodulus": "per-bond"
            if self.micromodulus is not None and self.micromodulus.ndim
            else (None if self.micromodulus is None else float(self.micromodulus)),
            "surface_correction": self.surface_correction,
        }

    def _repr_items(self) -> dict[str, Any]:
        items = super()._repr_items()
        if self.E is not None and self.E.ndim:
            items["E"] = self.E
        return items


def _scalar_or_tag(value: np.ndarray) -> float | str:
    return "per-point" if value.ndim else float(value)


def _measure(cloud: PointCloud) -> float:
    """Out-of-plane measure: thickness (2D), cross-section area (1D), 1 (3D)."""
    return 1.0 if cloud.dim == 3 else cloud.thickness


def _effective_volumes(cloud: PointCloud) -> np.ndarray:
    return np.asarray(cloud.volumes) * _measure(cloud)
