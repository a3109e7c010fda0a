"""The :class:`Correspondence` model: assembly plan, operators and material interface."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import pdlin.models.correspondence.controls as _controls
import pdlin.models.correspondence.gradient as _gradient

from ..._arrays import (
    mandel_weights,
    n_orientations,
    voigt_pairs,
)
from ..._kernels import bsr_matmul, bsr_transpose
from ..._threads import even_chunks, thread_map
from ..._validation import as_displacement, as_float_array, check_finite, integer
from ...constitutive import check_stiffness, isotropic, isotropic_2d, plane_strain, plane_stress
from ...errors import InputError, InputTypeError, ModelError, ShapeError
from ...geometry.bonds import Bonds
from ...geometry.cloud import PointCloud
from ..base import Model, Response
from ..bond_based import BondBased
from ..ordinary_state import uniform_nu_constants
from .controls import (
    CONTROLS,
    DEFAULT_CONTROL_COEFFICIENT,
)
from .gradient import (
    _coefficients,
    _gradient_blocks,
    _GradientBlocks,
    _mean_per_point,
    _rows_matmul,
    _tangent_blocks_product,
    _with_diagonal_blocks,
    intact_shape_tensor,
    voigt_projector,
)

__all__ = [
    "Correspondence",
    "DEFAULT_MAX_BYTES",
]


#: the package's logger (its name as before the split into modules)
log = logging.getLogger("pdlin.models.correspondence")


def _check_stiffness_per_point(arr: np.ndarray) -> None:
    """Validate per-point Voigt stiffnesses ``(n, nv, nv)``: every distinct one, batched.

    The first failing point is re-checked by :func:`check_stiffness` for its message.
    """
    n, nv, _ = arr.shape
    flat = arr.reshape(n, -1)
    uniq, first = np.unique(flat, axis=0, return_index=True)
    U = uniq.reshape(-1, nv, nv)
    scale = np.maximum(np.abs(U).max(axis=(1, 2)), np.finfo(float).tiny)
    bad = ~np.isfinite(U).all(axis=(1, 2))
    bad |= np.abs(U - U.transpose(0, 2, 1)).max(axis=(1, 2)) > 1e-12 * scale
    w = mandel_weights(2 if nv == 3 else 3) if nv > 1 else np.ones(1)
    ok = ~bad
    eig = np.linalg.eigvalsh(U[ok] * np.outer(w, w))
    tol = 1e-13 * np.maximum(np.abs(eig).max(axis=1), np.finfo(float).tiny)
    bad[np.flatnonzero(ok)[eig[:, 0] <= tol]] = True
    if bad.any():
        k = int(first[np.flatnonzero(bad)].min())
        if nv == 1:
            raise InputError(f"C[{k}] must be a positive scalar in 1D, got {arr[k, 0, 0]!r}")
        check_stiffness(arr[k], f"C[{k}]")  # raises with the specific reason
        raise InputError(f"C[{k}] must be a symmetric positive definite Voigt stiffness")


#: default byte budget of an assembled K (beyond it :meth:`Correspondence.plan`
#: chooses the matrix-free operator)
DEFAULT_MAX_BYTES = 4 * 1024**3


@dataclasses.dataclass(frozen=True)
class _Plan:
    gp_owner: np.ndarray  # (n_gp,) particle of each gradient point
    gp_of_bond: np.ndarray  # (nb,) gradient point owning each bond
    weight: np.ndarray  # (n_gp,) w_g
    energy: np.ndarray  # (n_gp,) bool: carries energy (False for shadow points)
    omega: np.ndarray  # (nb,) weights used
    blocks: _GradientBlocks  # G by (gradient point, point) blocks
    n_points: int
    #: () -> Cv (n_gp, nv, nv): Voigt stiffness of the owner (read-only; a broadcast view
    #: for one material), and (Cv) -> D (n_gp, d*d, d*d): w V C_ijkl (0 for energy-free
    #: points); both evaluated on first use (a nonlinear material's small-strain tangent
    #: is only needed by the linearized operators; the assembly needs Cv only)
    stiffness_fn: Any = dataclasses.field(compare=False, repr=False)
    d_fn: Any = dataclasses.field(compare=False, repr=False)
    _lazy: dict[str, Any] = dataclasses.field(default_factory=dict, compare=False, repr=False)

    @property
    def D(self) -> np.ndarray:
        if "D" not in self._lazy:
            self._lazy["D"] = self.d_fn(self.Cv)
        return self._lazy["D"]

    @property
    def Cv(self) -> np.ndarray:
        if "Cv" not in self._lazy:
            self._lazy["Cv"] = self.stiffness_fn()
        return self._lazy["Cv"]

    @property
    def G(self) -> sp.csr_array:
        """G in CSR ``(n_gp*d*d, n*d)``, built from the blocks on first use."""
        if "G" not in self._lazy:
            self._lazy["G"] = _gradient._blocks_to_csr(self.blocks, self.n_points)
        return self._lazy["G"]


def _symmetric_tangent(material: Any) -> bool:
    """Whether ``dP/dF`` of ``material`` has major symmetry (K_T symmetric).

    ``None`` (linear elastic C) and hyperelastic materials (with an ``energy`` method, e.g.
    :class:`pdlin.SaintVenantKirchhoff`) do; an explicit ``symmetric_tangent`` attribute
    overrides; anything else (crystal plasticity) is treated as nonsymmetric.
    """
    if material is None:
        return True
    flag = getattr(material, "symmetric_tangent", None)
    if flag is not None:
        return bool(flag)
    return callable(getattr(material, "energy", None))


def _orientation_count(orientation: Any, dim: int) -> int | None:
    """Points described by a material orientation (None: one for all points)."""
    if orientation is None:
        return None
    return n_orientations(orientation, dim)


class Correspondence(Model):
    """Linear correspondence (NOSB) peridynamics with zero-energy-mode controls.

    Parameters
    ----------
    C : array_like, optional
        Voigt stiffness (plain Voigt, :mod:`pdlin.constitutive` order):
        ``(6, 6)`` (reduced in 2D by ``plane``), ``(3, 3)`` 2D in-plane,
        ``(1, 1)`` or scalar in 1D; or one per point ``(n, nv, nv)``; or a
        mapping / sequence of them per material id (``cloud.material``).
    E, nu : float or (n,) array_like, optional
        Isotropic alternative to ``C`` (``E`` may vary per point; 1D uses
        ``E`` only).
    K, G, lam, mu : float or (n,) array_like, optional
        Any two isotropic constants instead of ``E, nu``: bulk modulus,
        shear modulus (``mu`` is the same), Lamé's first constant (see
        :func:`pdlin.constitutive.isotropic_constants`; Peridigm decks give
        ``K`` and ``G``).
    plane : {'stress', 'strain'}
        2D reduction of 3D data.
    control : {'none', 'higher_order', 'penalty', 'stress_points', 'springs', 'ads'}
        * ``'none'``: the bonds' ω (e.g. ``influence='inverse'`` for the
          LAMMPS-PD ``ω = 1/|ξ|``, or ``'constant'``).
        * ``'higher_order'``: the model re-weights the bonds of a
          :func:`pdlin.grid` cloud with
          ``pdlin.models.higher_order_weights(dim, δ/h)`` (Javaheri et al.
          (2022), Sec. II.C.1; negative weights allowed).  Build the bonds with ``find_bonds(cloud,
          ratio=m)`` (any influence: it is replaced).
        * ``'penalty'``: adds ``½ Σ_b ½ penalty k_b |z_b|²`` with
          ``z_b = u_j - u_i - ∇u_i ξ_b`` (non-affine part of bond b) and
          ``k_b = c ω V_i V_j / |ξ|`` the bond stiffness of
          :class:`pdlin.BondBased` with the modulus ``E_eq`` whose
          bond-based ``C_1111`` equals the mean axial modulus of ``C_i``:
          ``penalty = 1`` resists non-affine motion like a bond-based
          material of the same stiffness (full vector, not projected).
        * ``'stress_points'``: Luo & Sundararaghavan (2018), Sec. 3: two stress points per
          full-horizon particle, one per boundary particle.  Stress point 1 of case ``s``
          owns the bonds with ``s·ξ > 0`` (ties broken by orthogonal
          vectors), stress point 2 the rest: for nearest-neighbour axis bonds
          this is the paper's ``{s_k e_k} / {-s_k e_k}`` split, for larger
          horizons pdlin's half-space extension.  A particle gets two stress
          points (weight ``w_s = sp_weight``) when, for every case, both halves
          have well-conditioned shape tensors (``λ_min/λ_max ≥ SP_MIN_RATIO``)
          and are *balanced* (``‖K_1 - K_2‖ ≤ SP_BALANCE_TOL ‖K‖``: complete,
          point-symmetric families), otherwise one.  The one-SP weight is
          ``w_s`` on the paper's nearest-neighbour families (derived: the
          body is the node hull, a bar of ``n_y`` rows has the section
          ``(n_y - 1) h``) and ``2 w_s`` beyond them (an ordinary gradient
          point with its whole volume, section ``n_y h``).  Truncated families
          split into unbalanced halves do not act on a uniform stress like
          one gradient point, which made the free-surface bar at δ = 3h fail
          its patch test by 1.1 % before this rule.
        * ``'springs'``: Luo & Sundararaghavan (2018), Eq. 7, the force state
          ``T_a⟨ξ_ij⟩ = C1 ω (u_j - u_i)`` (full vector) added to every
          bond: ``K_a`` is the graph Laplacian ⊗ I_d with bond weight
          ``2 C1 ω V_i V_j``.
        * ``'ads'``: Luo & Sundararaghavan (2018), Eq. 8, the averaged displacement state
          ``T_a,i = C2 Σ_k ω V_k (u_k - u_i)`` (one vector per particle):
          ``K_a = C2 diag(V) Lap_V Lap_ωV``.  Symmetric for constant ω
          (the paper's ω = 1) and any V; nonsymmetric for varying ω
          (``model.symmetric`` is False until a plan shows constant ω).

        Springs and ADS use one gradient point per particle (as
        ``'none'``); see :meth:`control_constants` for ``C1``, ``C2``.
    coefficient : float, optional
        Dimensionless ``C̃ >= 0`` of ``'springs'`` (default 0.01) / ``'ads'``
        (default 0.03), normalized by the family (:meth:`control_constants`):
        ``C1 = d C̃ E_ref / S_ref`` and ``C2 = 4 d² C̃ E_ref / (S_ref Ω_ref)``
        with ``S = Σ_j ω V_j |ξ|²``, ``Ω = Σ_j ω V_j`` of a complete family and
        ``E_ref = max_i tr(C_i[:d, :d])/d``.  At ``C̃ = 1`` the springs are a
        full-vector material of modulus ``E_ref`` (energy ``½ E_ref |∇u|²``)
        at any ``δ/h`` and dimension; on nearest-neighbour families this is
        (derived) ``C̃ (E A / h) Lap0`` (springs) and ``C̃ (E A / h) Lap0²``
        (ADS) in 1D.  Neither control passes an affine patch test next to
        free surfaces (both act on affine fields there): measured on a 2D
        free-surface bar, springs stiffen uniaxial tension by ≈ 1.1 C̃ and
        reduce the lateral strain by ≈ (1 - ν²) C̃ at every δ/h; ADS errs only
        in a surface layer (C̃ = 0.1: lateral strain -0.4 % at δ = h, -2.2 %
        at 3h on an 11-particle-wide bar; ``docs/correspondence.md``).  The
        paper's C1/C2 (Table 1) are not transferable.
    penalty : float
        Dimensionless penalty coefficient (``control='penalty'``).
    influence : callable, optional
        ``ω(length, horizon)`` overriding the bonds' weights (e.g. a
        hand-made weight set); with ``'higher_order'`` it replaces the
        generated set.
    shadow : (m,) array_like of int, optional
        Shadow particles (Javaheri et al. (2022), Sec. II.D, e.g. from :func:`pdlin.shadow_layer`):
        they carry no energy, and their gradient rows use the intact-lattice
        shape tensor (with stress points: the intact one-bond-per-axis
        tensor of a stress point, ``ω V h² I``); their prescribed stress
        enters through :meth:`shadow_loads`.  Springs and ADS keep the
        spring bonds of shadow particles and set the ADS vector of a
        shadow particle to that of the affine continuation, 0.
    seed : int
        Seed of the stress-point case generator.
    case : int, optional
        One fixed stress-point case for every particle (default: random).
    sp_weight : float
        Stress-point weight ``w_s`` (½: passes the patch test and gives
        exact 1D reactions, pdlin's default; 1 is the literal scheme of Luo &
        Sundararaghavan (2018)).
    max_bytes : int
        Budget of an assembled K; beyond it :meth:`plan` picks the
        matrix-free operator.
    material : object, optional
        A nonlinear material instead of ``C`` / ``E``: anything with
        ``initial_state(n)`` and ``update(F, state, *, tangent) -> (P, state_new,
        dPdF)``, e.g. :class:`pdlin.CrystalPlasticity` (orientation per particle:
        ``orientation=theta`` with ``theta (n,)``) or
        :class:`pdlin.SaintVenantKirchhoff`.  The model is then finite strain
        (``nonlinear = True``): :meth:`initial_state` and :meth:`respond` give
        ``F = I + G u``, ``f = -Gᵀ vec(w V P)`` and ``K_T = Gᵀ blockdiag(w V
        dP/dF) G`` (Luo, Ramazani & Sundararaghavan (2017), Eqs. 15-18, in matrix form);
        ``symmetric`` is False unless the material is hyperelastic.  Penalty, springs and ADS
        act as linear add-ons; the linearized ``K`` uses ``dP/dF`` at ``F = I``.  Not with
        ``shadow``.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((8, 8), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=2.0)
    >>> model = pdlin.Correspondence(E=1.0, nu=0.25, plane="strain")
    >>> K = pdlin.operators.assemble_stiffness(model, cloud, bonds)
    >>> u = np.random.default_rng(0).normal(size=(cloud.n, 2))
    >>> bool(np.allclose(K @ u.ravel(), -model.internal_force(cloud, bonds, u).ravel()))
    True
    """

    coupling_range = 2
    symmetric = True

    def __init__(
        self,
        C: Any = None,
        *,
        E: Any = None,
        nu: float | None = None,
        K: Any = None,
        G: Any = None,
        lam: Any = None,
        mu: Any = None,
        plane: str = "stress",
        control: str = "none",
        penalty: float = 1.0,
        influence: Any = None,
        shadow: Any = None,
        seed: int = 0,
        case: int | None = None,
        sp_weight: float = 0.5,
        max_bytes: int = DEFAULT_MAX_BYTES,
        coefficient: float | None = None,
        material: Any = None,
    ) -> None:
        if material is not None:
            given = {"C": C, "E": E, "nu": nu, "K": K, "G": G, "lam": lam, "mu": mu}
            both = [k for k, v in given.items() if v is not None]
            if both:
                raise InputError(
                    "Correspondence needs exactly one of material= (a nonlinear material) or "
                    f"elastic constants, got material and {', '.join(both)}"
                )
            for meth in ("initial_state", "update"):
                if not callable(getattr(material, meth, None)):
                    raise InputTypeError(
                        "material must provide initial_state(n) and update(F, state, "
                        "tangent=...) (e.g. pdlin.CrystalPlasticity, pdlin.SaintVenantKirchhoff),"
                        f" got {type(material).__name__} without {meth}()"
                    )
            if shadow is not None:
                raise ModelError(
                    "shadow= is not supported with material= (its shadow loads are linear); "
                    "use pdlin.geometry.ghost_layer to give the prescribed particles full "
                    "families, got both"
                )
        iso = [k for k, v in {"K": K, "G": G, "lam": lam, "mu": mu}.items() if v is not None]
        if iso and material is None:
            if C is not None:
                raise InputError(
                    "Correspondence needs exactly one of C (Voigt stiffness) or isotropic "
                    f"constants, got C and {', '.join(iso)}"
                )
            E, nu = uniform_nu_constants("Correspondence", E, nu, K=K, G=G, lam=lam, mu=mu)
        if material is None and (C is None) == (E is None):
            raise InputError(
                "Correspondence needs exactly one of C (Voigt stiffness) or E (with nu, or two "
                f"of K, G, lam, mu), got {'both' if C is not None else 'neither'}"
            )
        if control not in CONTROLS:
            raise InputError(f"control must be one of {CONTROLS}, got {control!r}")
        if plane not in ("stress", "strain"):
            raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
        pen = float(penalty)
        if not np.isfinite(pen) or pen < 0:
            raise InputError(f"penalty must be a finite number >= 0, got {penalty!r}")
        if influence is not None and not callable(influence):
            raise InputError(f"influence must be a callable ω(length, horizon), got {influence!r}")
        if not isinstance(sp_weight, int | float | np.number) or not float(sp_weight) > 0:
            raise InputError(f"sp_weight must be > 0, got {sp_weight}")
        if case is not None and control != "stress_points":
            raise InputError(f"case is only used with control='stress_points', got {control!r}")
        if coefficient is not None and control not in ("springs", "ads"):
            raise InputError(
                f"coefficient is only used with control='springs' or 'ads', got {control!r}"
            )
        default = DEFAULT_CONTROL_COEFFICIENT.get(control, 0.0)
        coef = default if coefficient is None else float(coefficient)
        if not (np.isfinite(coef) and coef >= 0):
            raise InputError(f"coefficient must be a finite number >= 0, got {coefficient!r}")
        if C is not None and not isinstance(C, Mapping):
            c_arr = np.asarray(C) if not isinstance(C, list | tuple) else None
            if c_arr is not None and c_arr.dtype.kind in "fiub":
                check_finite(np.asarray(c_arr, dtype=float), "C")
            elif c_arr is not None and c_arr.dtype.kind != "O":
                raise InputTypeError(f"C must be a numeric array, got dtype {c_arr.dtype}")
        self.C = C
        self.E = None if E is None else as_float_array(E, "E")
        if self.E is not None and np.any(self.E <= 0):
            raise InputError(f"E must be > 0, got min {float(np.min(self.E))}")
        self.nu = None if nu is None else float(nu)
        self.plane = plane
        self.control = control
        self.penalty = pen
        self.influence = influence
        self.shadow = None if shadow is None else np.unique(np.asarray(shadow, dtype=np.intp))
        self.seed = integer(seed, "seed")
        self.case = None if case is None else int(case)
        self.sp_weight = float(sp_weight)
        self.coefficient = coef
        self.max_bytes = integer(max_bytes, "max_bytes", minimum=1)
        #: the nonlinear material (None: linear elastic C)
        self.material = material
        #: whether f(u) is nonlinear / history dependent (a ``material`` was given)
        self.nonlinear = material is not None
        #: whether K (K_T) is symmetric: False for 'ads' until a plan shows a constant ω, and
        #: for materials without a major-symmetric dP/dF (crystal plasticity)
        self.symmetric = control != "ads" and _symmetric_tangent(material)
        self._voigt_cache: tuple[PointCloud, np.ndarray] | None = None
        self._cache: tuple[PointCloud, Bonds, _Plan] | None = None
        #: how the last :meth:`plan` decided to apply K ('assembled' / 'matrix-free') and why
        self.assembly: dict[str, Any] = {}

    # -- material --------------------------------------------------------
    def voigt_stiffness(self, cloud: PointCloud) -> np.ndarray:
        """Return the per-point Voigt stiffness ``(n, nv, nv)`` in the cloud's dimension.

        With ``material=`` it is the material's tangent ``dP/dF`` at ``F = I`` from its
        initial state (the small-strain stiffness, rotated by the particle's orientation):
        the linearized ``K`` and the penalty / springs / ADS constants use it.

        Parameters
        ----------
        cloud : PointCloud
            The points.

        Returns
        -------
        (n, nv, nv) ndarray of float
            Read-only; a broadcast view when one C serves every point.

        Raises
        ------
        InputError, ShapeError, ModelError
            A stiffness of the wrong shape or not positive definite, or a material of
            another dimension.
        """
        if self.material is not None:
            return self._material_voigt(cloud)
        d, n = cloud.dim, cloud.n
        nv = {1: 1, 2: 3, 3: 6}[d]
        if self.E is not None:
            E = self.E
            if E.ndim and E.shape != (n,):
                raise ShapeError(f"E must be a scalar or have shape ({n},), got {E.shape}")
            if d == 1:
                base = np.ones((1, 1))
            else:
                if self.nu is None:
                    raise InputError(f"nu must be given with E in {d}D, got None")
                base = (
                    isotropic(E=1.0, nu=self.nu)
                    if d == 3
                    else isotropic_2d(1.0, self.nu, plane=self.plane)
                )
            if E.ndim == 0:  # one material: a read-only view, as for one C below
                return np.broadcast_to(E * base, (n, nv, nv))
            return E[:, None, None] * base[None]
        C = self.C
        per_material = isinstance(C, Mapping) or (
            isinstance(C, list | tuple) and len(C) > 0 and np.ndim(C[0]) == 2
        )
        if per_material:
            mats = np.asarray(cloud.material, dtype=np.intp)
            keys = np.unique(mats)
            table = {}
            for k in keys:
                try:
                    table[int(k)] = self._one_voigt(C[int(k)], d, f"C[{int(k)}]")
                except (KeyError, IndexError):
                    raise InputError(
                        f"C must give a stiffness for every material id of the cloud, "
                        f"got none for id {int(k)}"
                    ) from None
            out = np.empty((n, nv, nv))
            for k, v in table.items():
                out[mats == k] = v
            return out
        arr = np.asarray(C, dtype=float)
        if arr.ndim == 3:
            if arr.shape[0] != n:
                raise ShapeError(f"per-point C must have shape ({n}, {nv}, {nv}), got {arr.shape}")
            if arr.shape[1:] == (nv, nv):
                _check_stiffness_per_point(arr)
                return arr
            return np.stack([self._one_voigt(a, d, f"C[{k}]") for k, a in enumerate(arr)])
        return np.broadcast_to(self._one_voigt(arr, d, "C"), (n, nv, nv))

    def _one_voigt(self, C: Any, d: int, name: str) -> np.ndarray:
        arr = np.asarray(C, dtype=float)
        if d == 1:
            if arr.size != 1 or not arr.ravel()[0] > 0:
                raise InputError(f"{name} must be a positive scalar or (1, 1) in 1D, got {arr!r}")
            return arr.reshape(1, 1)
        if d == 2 and arr.shape == (6, 6):
            return plane_stress(arr) if self.plane == "stress" else plane_strain(arr)
        want = (3, 3) if d == 2 else (6, 6)
        if arr.shape != want:
            raise ShapeError(
                f"{name} must be a Voigt matrix of shape {want} in {d}D, got {arr.shape}"
            )
        return check_stiffness(arr, name)

    # -- weights ----------------------------------------------------------
    def bond_weights(self, cloud: PointCloud, bonds: Bonds) -> np.ndarray:
        """Return the ω used per bond (higher-order sets may be negative).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        (nb,) ndarray of float
            The model's ``influence``, the higher-order set, or the bonds' own ω.

        Raises
        ------
        ModelError
            ``control='higher_order'`` on a cloud that is not an equal-spacing grid, or with
            a per-point horizon.
        """
        fn = self._omega_fn(cloud, bonds)
        if fn is None:
            return np.asarray(bonds.omega, dtype=float)
        om = np.asarray(fn(bonds.length, bonds.horizon_ij), dtype=float)
        return np.broadcast_to(om, bonds.length.shape).astype(float)

    def _omega_fn(self, cloud: PointCloud, bonds: Bonds) -> Any:
        if self.influence is not None:
            return self.influence
        if self.control != "higher_order":
            return None
        lat = cloud.lattice
        if lat is None or not np.allclose(lat.spacing, lat.spacing[0], rtol=1e-12):
            raise ModelError(
                "control='higher_order' needs a pdlin.grid cloud with equal spacing on every "
                "axis, got " + ("no lattice" if lat is None else f"spacing {lat.spacing}")
            )
        h = float(lat.spacing[0])
        hor = np.asarray(bonds.horizon)
        if not np.allclose(hor, hor[0], rtol=1e-12):
            raise ModelError("control='higher_order' needs a constant horizon, got a per-point one")
        ratio = float(hor[0]) / h
        try:
            from ..weights import as_influence, higher_order_weights
        except ImportError:
            if (
                abs(ratio - 1.0) < 1e-6
            ):  # δ = h: the only shell, weight 1 (Javaheri et al. (2022), Table 1)
                return lambda length, horizon: np.ones_like(length)
            raise ModelError(
                f"control='higher_order' at δ/h = {ratio:g} needs pdlin.models.weights "
                "(not available); pass influence= with a weight set"
            ) from None
        return as_influence(higher_order_weights(cloud.dim, ratio), h)

    # -- gradient points --------------------------------------------------
    def _gradient_points(
        self, cloud: PointCloud, bonds: Bonds
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """See :func:`pdlin.models.correspondence.controls.gradient_points`."""
        return _controls.gradient_points(self, cloud, bonds)

    # -- assembly plan ----------------------------------------------------
    def _plan(self, cloud: PointCloud, bonds: Bonds) -> _Plan:
        # the cache holds the objects themselves (not ids, which can be reused)
        if self._cache is not None and self._cache[0] is cloud and self._cache[1] is bonds:
            return self._cache[2]
        if bonds.n_points != cloud.n or bonds.dim != cloud.dim:
            raise ShapeError(
                f"bonds were built for {bonds.n_points} points in {bonds.dim}D, "
                f"got a cloud of {cloud.n} points in {cloud.dim}D"
            )
        d, n = cloud.dim, cloud.n
        omega = self.bond_weights(cloud, bonds)
        gp_owner, gp_of_bond, w = self._gradient_points(cloud, bonds)
        n_gp = gp_owner.size
        energy = np.ones(n_gp, dtype=bool)
        rows = None
        kinv = None
        if self.shadow is not None:
            if self.shadow.size and (self.shadow.min() < 0 or self.shadow.max() >= n):
                raise InputError(
                    f"shadow must hold point indices in [0, {n - 1}], got "
                    f"[{int(self.shadow.min())}, {int(self.shadow.max())}]"
                )
            is_shadow = np.zeros(n, dtype=bool)
            is_shadow[self.shadow] = True
            rows = np.flatnonzero(is_shadow[gp_owner])
            energy[rows] = False
            fn = self._omega_fn(cloud, bonds)
            if fn is None:
                from ...geometry.influence import influence_function

                fn = influence_function(bonds.influence)
            K_int = intact_shape_tensor(cloud, bonds, fn)
            kinv = np.linalg.inv(K_int)
            if self.control == "stress_points":
                # a half family holds half the intact tensor (§4.2, one bond per axis at
                # δ = h); a one-SP particle of weight 2 w_s beyond δ = h holds all of it
                kinv = kinv[None] * (2.0 * self.sp_weight / w[rows])[:, None, None]
        # each point owns its bonds and the gradient points of those (_gradient_points)
        gptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(gp_owner, minlength=n), out=gptr[1:])
        ptrs = (np.asarray(bonds.indptr, dtype=np.int64), gptr)
        c = _coefficients(
            gp_of_bond, n_gp, omega, bonds.volume_j, bonds.xi,
            override_rows=rows, override_kinv=kinv, ptrs=ptrs,
        )  # fmt: skip
        blocks = _gradient_blocks(gp_owner, gp_of_bond, bonds.j, c, n, ptrs)
        vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
        scale = w * vol[gp_owner] * energy

        def stiffness_fn() -> np.ndarray:
            V = self.voigt_stiffness(cloud)
            if V.ndim == 3 and V.shape[0] and V.strides[0] == 0:  # one C: a view, no copy
                return np.broadcast_to(V[0], (n_gp,) + V.shape[1:])
            return V[gp_owner]

        def d_fn(Cv: np.ndarray) -> np.ndarray:
            P = voigt_projector(d)
            D = np.empty((Cv.shape[0], d * d, d * d))

            def chunk(rng: tuple[int, int]) -> None:  # Pᵀ C P per gradient point, on threads
                g0, g1 = rng
                D[g0:g1] = (P.T @ Cv[g0:g1] @ P) * scale[g0:g1, None, None]

            thread_map(chunk, even_chunks(Cv.shape[0], _gradient._ROW_CHUNK))
            return D

        plan = _Plan(gp_owner, gp_of_bond, w, energy, omega, blocks, n, stiffness_fn, d_fn)
        if self.material is None:  # validate C now (errors at plan time)
            plan.Cv  # noqa: B018
        if self.control == "ads":  # S N is symmetric for constant ω, any V (see the docs)
            const = bool(np.allclose(omega, omega[0], rtol=1e-12))
            self.symmetric = const and _symmetric_tangent(self.material)
        self._cache = (cloud, bonds, plan)
        return plan

    def gradient(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Return the displacement gradient per gradient point.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.

        Returns
        -------
        (n_gp, d, d) ndarray of float
            ``∇u`` at each gradient point (:meth:`stress_points` maps them to particles).
        """
        p = self._plan(cloud, bonds)
        uu = _as_u(u, cloud)
        return (p.G @ uu.ravel()).reshape(-1, cloud.dim, cloud.dim)

    def gradient_matrix(self, cloud: PointCloud, bonds: Bonds) -> sp.csr_array:
        """Return the gradient operator G of the model.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        scipy.sparse.csr_array
            ``(n_gp*d*d, n*d)``: rows ``(g, i, j)`` of ``∇u``, columns the DOFs.
        """
        return self._plan(cloud, bonds).G

    def stress_points(self, cloud: PointCloud, bonds: Bonds) -> dict[str, np.ndarray]:
        """Return the bookkeeping of the gradient points.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        dict of str -> ndarray
            ``owner`` (particle of each gradient point), ``bond_owner`` (gradient point of
            each bond), ``weight`` (``w_g``).
        """
        p = self._plan(cloud, bonds)
        return {"owner": p.gp_owner, "bond_owner": p.gp_of_bond, "weight": p.weight}

    # -- operators -----------------------------------------------------------
    def _dblock(self, p: _Plan) -> sp.bsr_array:
        n_gp, q, _ = p.D.shape
        ar = np.arange(n_gp + 1, dtype=np.int32)
        return sp.bsr_array((p.D, ar[:-1], ar), shape=(n_gp * q, n_gp * q), blocksize=(q, q))

    def _penalty_k(self, cloud: PointCloud, bonds: Bonds, p: _Plan) -> np.ndarray:
        """See :func:`pdlin.models.correspondence.controls.penalty_bond_stiffness`."""
        return _controls.penalty_bond_stiffness(self, cloud, bonds, p)

    def _penalty_force(
        self, cloud: PointCloud, bonds: Bonds, p: _Plan, k: np.ndarray, x: np.ndarray
    ) -> np.ndarray:
        """See :func:`pdlin.models.correspondence.controls.penalty_force`."""
        return _controls.penalty_force(cloud, bonds, p, k, x)

    def _penalty_matrix(self, cloud: PointCloud, bonds: Bonds, p: _Plan) -> sp.bsr_array:
        """See :func:`pdlin.models.correspondence.controls.penalty_matrix`."""
        return _controls.penalty_matrix(self, cloud, bonds, p)

    # -- springs / ADS (Luo & Sundararaghavan (2018), Eqs. 7-8) -----------------------
    def control_constants(self, cloud: PointCloud, bonds: Bonds) -> dict[str, float]:
        """Return the constants of the ``'springs'`` / ``'ads'`` control forces.

        Luo & Sundararaghavan (2018), Eqs. 7-8, with pdlin's family normalization.

        Returns ``{'coefficient': C̃, 'E_ref', 'V_ref', 'h_ref', 'S_ref', 'Omega_ref',
        'C1', 'C2'}``.  ``E_ref = max_i tr(C_i[:d, :d])/d`` (the largest mean axial
        modulus; ``E`` in 1D); the family moments ``S_i = Σ_j ω V_j |ξ_ij|²`` and
        ``Ω_i = Σ_j ω V_j`` (``V`` times the thickness in 2D / cross-section in 1D) give
        ``S_ref = max_i S_i`` and ``Omega_ref = max_i Ω_i`` (a complete family on a lattice), and

        ``C1 = d C̃ E_ref / S_ref``,    ``C2 = 4 d² C̃ E_ref / (S_ref Ω_ref)``.

        Meaning, for any ``δ/h`` and dimension: under a homogeneous gradient ``H`` the springs
        of a complete family store ``½ C̃ E_ref |H|²`` per unit volume (a full-vector
        "Laplacian" material of modulus ``C̃ E_ref``: uniaxial stretch gains the stress
        ``C̃ E_ref ε``), and ADS stores ``½ C̃ E_ref ℓ² |∇²u|²`` with ``ℓ² = S_ref/Ω_ref``
        the family's mean square bond length (zero on affine fields, except where families
        are truncated).  On the nearest-neighbour families of Luo & Sundararaghavan (2018)
        (``S = 2d V h²``, ``Ω = 2d V``) this is ``C1 = C̃ E/(2 V h²)``, ``C2 = C̃ E/(V² h²)``:
        on a uniform chain (``V = A h``, ω = 1) springs add ``C̃ (E A / h) Lap0`` and ADS
        ``C̃ (E A / h) Lap0²`` (derived, ``Lap0`` the chain graph Laplacian).  ``V_ref``
        (mean volume) and ``h_ref`` (mean shortest bond) are reported for information.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        dict of str -> float
            ``coefficient``, ``E_ref``, ``V_ref``, ``h_ref``, ``S_ref``, ``Omega_ref``,
            ``C1``, ``C2``.

        Raises
        ------
        ModelError
            No bonds, or non-positive family moments.

        Examples
        --------
        >>> import pdlin
        >>> cloud = pdlin.grid((11,), spacing=0.1)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
        >>> m = pdlin.Correspondence(E=2.0, control="springs", coefficient=0.5)
        >>> c = m.control_constants(cloud, bonds)
        >>> round(2 * c["C1"] * c["V_ref"] ** 2, 12)   # C̃ E A / h = 0.5 * 2 / 0.1
        10.0
        >>> b3 = pdlin.find_bonds(cloud, ratio=3.0)   # same springs' modulus, 6 bonds
        >>> c3 = m.control_constants(cloud, b3)
        >>> round(c3["S_ref"] / (2 * 0.1 * (0.1**2 + 0.2**2 + 0.3**2)), 12)
        1.0
        """
        return _controls.control_constants(self, cloud, bonds)

    def _control_factors(
        self, cloud: PointCloud, bonds: Bonds, p: _Plan
    ) -> tuple[sp.csr_array, sp.csr_array] | None:
        """See :func:`pdlin.models.correspondence.controls.control_factors`."""
        return _controls.control_factors(self, cloud, bonds, p)

    def _control_matrix(self, cloud: PointCloud, bonds: Bonds, p: _Plan) -> sp.csr_array | None:
        """Assembled springs / ADS stiffness ``S N`` (None for the other controls)."""
        f = self._control_factors(cloud, bonds, p)
        if f is None:
            return None
        S, N = f
        return S if self.control == "springs" else sp.csr_array(S @ N)

    def _control_products(
        self, cloud: PointCloud, bonds: Bonds, p: _Plan
    ) -> tuple[Any, Any] | None:
        """Matrix-free ``x -> S N x`` and its transpose (None for the other controls)."""
        f = self._control_factors(cloud, bonds, p)
        if f is None:
            return None
        S, N = f
        if self.control == "springs":
            return (lambda x: S @ x), (lambda x: S @ x)
        Nt = sp.csr_array(N.T)
        return (lambda x: S @ (N @ x)), (lambda x: Nt @ (S @ x))

    def stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.bsr_array:
        """Return the assembled ``K = Gᵀ blockdiag(w V C) G`` (+ penalty / springs / ADS).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        scipy.sparse.bsr_array
            ``(n*d, n*d)``, blocks ``(d, d)``, every diagonal block stored.
        """
        p = self._plan(cloud, bonds)
        d = cloud.dim
        self.plan(cloud, bonds)
        if self.assembly.get("path") == "matrix-free":
            log.warning("assembling K beyond the byte budget: %s", self.assembly["reason"])
        K = self._core_stiffness(cloud, p)
        if self.control == "penalty" and self.penalty > 0:
            K = sp.bsr_array(K + self._penalty_matrix(cloud, bonds, p))  # both bitwise symmetric
        Ka = self._control_matrix(cloud, bonds, p)
        if Ka is not None:  # springs / ADS (ADS may be nonsymmetric: added unsymmetrized)
            K = sp.bsr_array(sp.csr_array(K) + sp.csr_array(Ka), blocksize=(d, d))
        return _with_diagonal_blocks(K, d)

    def _core_stiffness(self, cloud: PointCloud, p: _Plan) -> sp.bsr_array:
        """``Bᵀ blockdiag(w V C) B`` as ``Wᵀ W`` in BSR arithmetic, ``W = √(w V) Lᵀ B``.

        ``B = P_sym G`` has one ``(n_v x d)`` block per (gradient point, point) pair, built
        straight from the blocks of G, and ``C = L Lᵀ`` (Cholesky per gradient point).  The
        product ``Wᵀ W`` is symmetric to the last bit (both triangles sum the same products
        in the same order), so no ``(K + Kᵀ)/2`` pass is needed.  A Voigt stiffness that is
        not positive definite falls back to ``Bᵀ (D B)`` symmetrized.
        """
        d = cloud.dim
        blk = p.blocks
        P = voigt_projector(d)
        nv = P.shape[0]
        # B block (a, i) = Σ_q P[a, i*d + q] c_q  (G block is I_d ⊗ c)
        Pr = P.reshape(nv * d, d)
        nblk = blk.col.size

        def bdata() -> np.ndarray:
            return _rows_matmul(blk.val, Pr.T).reshape(nblk, nv, d)

        n_gp = p.Cv.shape[0]
        vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
        scale = p.weight * vol[p.gp_owner] * p.energy
        shape = (n_gp * nv, p.n_points * d)
        Wdata = self._root_blocks(p, blk, bdata, scale) if (scale >= 0).all() else None
        if Wdata is not None:
            W = sp.bsr_array((Wdata, blk.col, blk.indptr), shape=shape, blocksize=(nv, d))
            K, sizes = bsr_matmul(bsr_transpose(W), W, block_sizes=True)
            return _gradient._drop_zero_blocks(K, sizes)
        Bdata = bdata()
        B = sp.bsr_array((Bdata, blk.col, blk.indptr), shape=shape, blocksize=(nv, d))
        ar = np.arange(n_gp + 1, dtype=np.int32)
        Db = sp.bsr_array(
            (p.Cv * scale[:, None, None], ar[:-1], ar),
            shape=(n_gp * nv, n_gp * nv),
            blocksize=(nv, nv),
        )
        K = bsr_matmul(bsr_transpose(B), bsr_matmul(Db, B))
        return sp.bsr_array(0.5 * (K + K.T), blocksize=(d, d))

    @staticmethod
    def _root_blocks(
        p: _Plan, blk: _GradientBlocks, bdata: Any, scale: np.ndarray
    ) -> np.ndarray | None:
        """Blocks of ``W = √scale Lᵀ B`` (``C = L Lᵀ``), or None if a ``C`` is not SPD.

        ``bdata()`` returns the ``(nblk, n_v, d)`` blocks of ``B`` (only needed when the
        material varies between gradient points).
        """
        nblk = blk.col.size
        d = blk.val.shape[1]
        nv = p.Cv.shape[1]
        sq = np.sqrt(scale)
        ptr = blk.indptr
        try:
            one = p.Cv.strides[0] == 0 or bool((p.Cv == p.Cv[0]).all())
            if one:  # one material: one (n_v·d x d) map for all blocks
                L0 = np.linalg.cholesky(p.Cv[0])
                M = (L0.T @ voigt_projector(d)).reshape(nv * d, d)

                def root_rows(a: int, b: int) -> np.ndarray:  # √scale of blocks a:b
                    g0 = int(np.searchsorted(ptr, a, side="right")) - 1
                    g1 = int(np.searchsorted(ptr, b, side="left"))
                    cnt = np.minimum(ptr[g0 + 1 : g1 + 1], b) - np.maximum(ptr[g0:g1], a)
                    return np.repeat(sq[g0:g1], cnt)

                # one (nblk, n_v·d) product, scaled in place, in fixed row chunks on threads
                W = _rows_matmul(blk.val, M.T, root_rows)
                return W.reshape(nblk, nv, d)
            Lr = np.linalg.cholesky(p.Cv)[blk.row]
        except np.linalg.LinAlgError:
            return None
        Bdata = bdata()
        W = np.zeros((nblk, nv, d))
        for b in range(nv):  # Lᵀ B per block
            W += Lr[:, b, :, None] * Bdata[:, b, None, :]
        return W * sq[blk.row][:, None, None]

    def apply(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Return the matrix-free product ``K u`` through G (and the bonds for the penalty).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.

        Returns
        -------
        (n*d,) ndarray of float
        """
        return np.asarray(self.linear_operator(cloud, bonds) @ np.asarray(u, float).reshape(-1))

    def linear_operator(self, cloud: PointCloud, bonds: Bonds) -> spla.LinearOperator:
        """Return the matrix-free ``K`` as a :class:`scipy.sparse.linalg.LinearOperator`.

        ``K x = Gᵀ(D(G x))`` plus, for the penalty, ``Zᵀ(k Z x)`` evaluated
        bond by bond (vectorized); memory is that of G and the bond arrays.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        scipy.sparse.linalg.LinearOperator
            ``(n*d, n*d)``, with ``rmatvec`` for the nonsymmetric controls.
        """
        p = self._plan(cloud, bonds)
        nd = cloud.n * cloud.dim
        k = (
            self._penalty_k(cloud, bonds, p)
            if self.control == "penalty" and self.penalty > 0
            else None
        )
        G, Gt = p.G, sp.csr_array(p.G.T)
        D = p.D
        d2 = cloud.dim**2
        extra = self._control_products(cloud, bonds, p)  # springs / ADS: (S N x, Nᵀ S x)

        def mv(x: np.ndarray) -> np.ndarray:
            x = np.asarray(x, dtype=float).reshape(-1)
            s = np.einsum("gij,gj->gi", D, (G @ x).reshape(-1, d2)).ravel()
            out = np.asarray(Gt @ s)
            if k is not None:
                out = out + self._penalty_force(cloud, bonds, p, k, x)
            if extra is not None:
                out = out + extra[0](x)
            return out

        def rmv(x: np.ndarray) -> np.ndarray:
            if extra is None:
                return mv(x)
            x = np.asarray(x, dtype=float).reshape(-1)
            return mv(x) - extra[0](x) + extra[1](x)

        return spla.LinearOperator((nd, nd), matvec=mv, rmatvec=rmv, dtype=float)

    def operator(self, cloud: PointCloud, bonds: Bonds) -> spla.LinearOperator:
        """Return the matrix-free ``K`` (the :class:`~pdlin.models.base.Model` interface name).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        scipy.sparse.linalg.LinearOperator
            :meth:`linear_operator`.
        """
        return self.linear_operator(cloud, bonds)

    def surrogate_stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.bsr_array:
        """Return the one-hop preconditioner base: bond-based K plus half its graph Laplacian ⊗ I.

        The bond-based stiffness of the same bonds (ω ≥ 0, equivalent modulus) resists only
        bond stretch: with nearest-neighbour axis bonds it has shear mechanisms, and its
        AMG then breaks CG down on the correspondence operator.  Adding ``½ L ⊗ I_d``, ``L``
        the graph Laplacian with the bond stiffnesses as weights (springs acting on the full
        vector, like the correspondence operator), removes them and, measured, cuts the
        AMG-CG iterations of the matrix-free solve (3D brick with stress points: breakdown
        → 52; 14³ higher-order δ = 2h: 156 → 75; 2D penalty: 32 → 26).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        scipy.sparse.bsr_array
            ``(n*d, n*d)``, blocks ``(d, d)``.
        """
        d = cloud.dim
        Cv = self.voigt_stiffness(cloud)
        axial = np.einsum("nkk->n", Cv[:, :d, :d]) / d
        e_eq = axial / _controls.unit_axial_modulus(d, self.plane)
        b = dataclasses.replace(bonds, omega=np.abs(self.bond_weights(cloud, bonds)))
        K = sp.bsr_array(BondBased(E=e_eq, plane=self.plane).stiffness(cloud, b))
        n = cloud.n
        rows = np.repeat(np.arange(n), np.diff(K.indptr))
        off = rows != K.indices
        k_b = -np.einsum("bii->b", K.data[off])  # bond stiffness: -trace of its block
        W = sp.csr_array((k_b, (rows[off], K.indices[off])), shape=(n, n))
        L = sp.diags_array(np.asarray(W.sum(axis=1)).ravel()) - W
        return sp.bsr_array(K + 0.5 * sp.kron(L, sp.eye_array(d), format="bsr"), blocksize=(d, d))

    def plan(self, cloud: PointCloud, bonds: Bonds) -> dict[str, Any]:
        """Return the decision between assembled K and the matrix-free operator.

        It is also kept in ``self.assembly``.

        Decide between assembled K and the matrix-free operator (also in ``self.assembly``).

        The estimate counts the two-hop block pattern (:meth:`estimate_nnz_blocks`)
        and the intermediate products; beyond ``max_bytes`` the matrix-free
        path (``K x = Gᵀ(D(G x))``, preconditioned with AMG on
        :meth:`surrogate_stiffness`) is chosen.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        dict
            ``path`` ('assembled' or 'matrix-free'), the byte estimate and the reason.
        """
        d = cloud.dim
        nblk = self.estimate_nnz_blocks(cloud, bonds)
        est = int(nblk * (8 * d * d + 4) * 6)  # peak ~6x the K estimate (measured, 3D HO 3h)
        if est <= self.max_bytes:
            info = {"path": "assembled", "reason": f"~{est / 1e9:.3g} GB <= budget "
                    f"{self.max_bytes / 1e9:.3g} GB", "nnz_blocks": nblk, "bytes": est}  # fmt: skip
        else:
            info = {"path": "matrix-free", "reason": f"~{est / 1e9:.3g} GB > budget "
                    f"{self.max_bytes / 1e9:.3g} GB", "nnz_blocks": nblk, "bytes": est}  # fmt: skip
        log.info("correspondence K: %s (%s)", info["path"], info["reason"])
        self.assembly = info
        return info

    def estimate_nnz_blocks(self, cloud: PointCloud, bonds: Bonds) -> int:
        """Return an upper bound of the dim x dim blocks of K: the two-hop pattern.

        On a lattice: interior points x the size of the stencil difference
        set ``{q - p}``; otherwise the number of points within twice the
        largest horizon of each point (cKDTree counts).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        int
        """
        lat = cloud.lattice
        n = cloud.n
        hor = np.asarray(bonds.horizon)
        if lat is not None and np.allclose(hor, hor[0]):
            h = np.asarray(lat.spacing, dtype=float)
            m = np.floor(hor[0] * (1 + 1e-9) / h).astype(int)
            axes = [np.arange(-k, k + 1) for k in m]
            offs = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)
            offs = offs[np.sqrt(np.sum((offs * h) ** 2, axis=1)) <= hor[0] * (1 + 1e-9)]
            diff = np.unique((offs[:, None, :] - offs[None, :, :]).reshape(-1, cloud.dim), axis=0)
            return int(min(n, diff.shape[0]) * n)
        from scipy.spatial import cKDTree

        counts = cKDTree(cloud.points).query_ball_point(
            cloud.points, 2.0 * float(hor.max()) * (1 + 1e-9), return_length=True
        )
        return int(np.sum(counts))

    def internal_force(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, linear: bool = True
    ) -> np.ndarray:
        """Return the nodal internal force ``f = -Gᵀ vec(w V σ)`` (small strain: ``f = -K u``).

        The elastic model is linear small strain (Javaheri et al. (2022), Sec. III.C), so
        ``linear=False`` returns the same force.  With ``material=``, ``linear=False`` is the
        finite-strain force of :meth:`respond` from the initial state; ``linear=True`` is
        ``-K u`` with the material's small-strain stiffness.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.
        linear : bool
            With ``material=``: ``-K u`` (True) or the finite-strain force (False).

        Returns
        -------
        (n, d) ndarray of float
        """
        uu = _as_u(u, cloud)
        if not linear and self.material is not None:
            return self.respond(cloud, bonds, uu, self.initial_state(cloud, bonds)).force
        return -self.apply(cloud, bonds, uu).reshape(cloud.n, cloud.dim)

    # -- nonlinear materials ---------------------------------------------------
    def _check_material_dim(self, cloud: PointCloud) -> None:
        md = getattr(self.material, "dim", cloud.dim)
        if md != cloud.dim:
            raise ModelError(
                f"material is {md}D but the cloud is {cloud.dim}D ({type(self.material).__name__})"
            )

    def _material_initial_state(self, cloud: PointCloud, owner: np.ndarray) -> dict[str, Any]:
        """Return the material's initial state for points ``owner`` (particle of each row)."""
        mat = self.material
        self._check_material_dim(cloud)
        o = getattr(mat, "orientation", None)
        count = _orientation_count(o, cloud.dim)
        if count is None:
            return dict(mat.initial_state(owner.size))
        if count != cloud.n:
            raise ShapeError(
                "material.orientation must describe all particles at once or one particle "
                f"each ({cloud.n}), got {count} orientations"
            )
        return dict(mat.initial_state(owner.size, orientation=np.asarray(o)[owner]))

    def _material_voigt(self, cloud: PointCloud) -> np.ndarray:
        """Voigt form of the material's ``dP/dF`` at ``F = I`` per particle (cached)."""
        if self._voigt_cache is not None and self._voigt_cache[0] is cloud:
            return self._voigt_cache[1]
        d, n = cloud.dim, cloud.n
        state = self._material_initial_state(cloud, np.arange(n))
        eye = np.broadcast_to(np.eye(d), (n, d, d)).copy()
        _, _, A = self.material.update(eye, state, tangent=True)
        if A is None:
            raise ModelError(
                f"material.update(F, state, tangent=True) must return dP/dF, got None "
                f"({type(self.material).__name__})"
            )
        A = np.asarray(A, dtype=float).reshape(n, d, d, d, d)
        if d == 1:
            Cv = A.reshape(n, 1, 1)
        else:
            ij = np.array(voigt_pairs(d))
            Cv = A[:, ij[:, 0, None], ij[:, 1, None], ij[None, :, 0], ij[None, :, 1]]
        try:
            _check_stiffness_per_point(Cv)
        except InputError as exc:
            raise ModelError(
                f"material's small-strain tangent dP/dF(F = I) must be a symmetric positive "
                f"definite stiffness ({type(self.material).__name__}): {exc}"
            ) from None
        self._voigt_cache = (cloud, Cv)
        return Cv

    def initial_state(self, cloud: PointCloud, bonds: Bonds) -> dict[str, np.ndarray]:
        """Return the material's committed state before the first load step, per gradient point.

        One entry per gradient point (``stress_points(...)['owner']`` maps them to their
        particle: one per particle without stress points).  A per-particle orientation of
        the material (``CrystalPlasticity(orientation=theta)``, ``theta (n,)``) is given to
        every gradient point of that particle.  Empty without ``material=``.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        dict of str -> ndarray
            The material's state arrays, one row per gradient point (empty without
            ``material=``).

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((4, 4), spacing=0.25)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
        >>> theta = np.linspace(-0.5, 0.5, cloud.n)
        >>> model = pdlin.Correspondence(material=pdlin.CrystalPlasticity(orientation=theta),
        ...                              control="stress_points")
        >>> state = model.initial_state(cloud, bonds)
        >>> owner = model.stress_points(cloud, bonds)["owner"]
        >>> state["Fp"].shape[0] == owner.size, bool(np.allclose(state["theta0"], theta[owner]))
        (True, True)
        """
        if self.material is None:
            return {}
        p = self._plan(cloud, bonds)
        return self._material_initial_state(cloud, p.gp_owner)

    def deformation_gradient(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Return ``F = I + G u`` per gradient point ``(n_gp, d, d)``.

        Luo, Ramazani & Sundararaghavan (2017), Eq. 16.

        Exact for affine fields at every gradient point whose shape tensor is invertible,
        truncated families included (derived).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.

        Returns
        -------
        (n_gp, d, d) ndarray of float
        """
        return np.eye(cloud.dim) + self.gradient(cloud, bonds, u)

    def nodal_force(self, cloud: PointCloud, bonds: Bonds, P: Any) -> np.ndarray:
        """Return the nodal force of a first Piola–Kirchhoff stress per gradient point.

        ``f = -Gᵀ vec(w V P)`` (derived matrix form: ``L = -V⁻¹ Bᵀ(V ⊙ P)``, ``f = V L``), i.e.
        the pairwise sum ``f_a = V_a Σ_b ω V_b (P_a K_a⁻¹ + P_b K_b⁻¹) ξ_ab`` of Luo, Ramazani
        & Sundararaghavan (2017), Eqs. 15–18, for one gradient point per particle.

        Parameters
        ----------
        P : (n_gp, d, d) or (d, d) array_like of float
            Stress per gradient point (``(d, d)``: the same at every one).

        Returns
        -------
        (n, d) ndarray of float
            ``f = -Gᵀ vec(w V P)``.

        Examples
        --------
        A uniform stress on a truncated-family grid at δ = h gives ``V P n / (2h)`` on the
        first free ring (derived), here ``0.25² · 1 / 0.5`` in x at the second column:

        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((4, 4), spacing=0.25)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
        >>> f = pdlin.Correspondence(E=1.0, nu=0.3).nodal_force(cloud, bonds, np.eye(2))
        >>> float(f.reshape(4, 4, 2)[1, 2, 0])
        -0.125
        """
        p = self._plan(cloud, bonds)
        d = cloud.dim
        n_gp = p.gp_owner.size
        arr = as_float_array(P, "P")
        if arr.shape == (d, d):
            arr = np.broadcast_to(arr, (n_gp, d, d))
        if arr.shape != (n_gp, d, d):
            raise ShapeError(
                f"P must have shape ({n_gp}, {d}, {d}) (one per gradient point) or ({d}, {d}), "
                f"got {arr.shape}"
            )
        return self._force_of(cloud, p, arr.reshape(n_gp, d * d)).reshape(cloud.n, d)

    def _force_of(self, cloud: PointCloud, p: _Plan, P: np.ndarray) -> np.ndarray:
        """Return ``-Gᵀ vec(w V P)`` for a checked ``(n_gp, d*d)`` stress, flat ``(n*d,)``.

        The weights ``-w V`` (0 at energy-free points) are kept in the plan, the sign
        folded into them (the same bits as negating the product).
        """
        if "neg_wv" not in p._lazy:
            d = cloud.dim
            vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
            p._lazy["neg_wv"] = -(p.weight * vol[p.gp_owner] * p.energy)[:, None]
        w = p._lazy["neg_wv"]
        flat = np.empty_like(P)
        if P.size >= _THREADED_MULTIPLY:  # numpy's loop releases the GIL: row chunks
            from ..._threads import even_chunks, thread_map

            thread_map(
                lambda c: np.multiply(P[c[0] : c[1]], w[c[0] : c[1]], out=flat[c[0] : c[1]]),
                even_chunks(P.shape[0], _THREADED_MULTIPLY // (2 * P.shape[1])),
            )
        else:
            np.multiply(P, w, out=flat)
        return np.asarray(_threaded(p, "GT", p.G.T) @ flat.ravel())

    def _addon_matrix(self, cloud: PointCloud, bonds: Bonds, p: _Plan) -> sp.csr_array | None:
        """Return the assembled penalty / springs / ADS stiffness ``K_c`` (or None).

        None without such a control; built once per plan: the nonlinear force ``-K_c u``
        and the tangent's ``+K_c``.
        """
        if "addon" not in p._lazy:
            if self.control == "penalty" and self.penalty > 0:
                Kc = sp.csr_array(self._penalty_matrix(cloud, bonds, p))
            else:
                Kc = self._control_matrix(cloud, bonds, p)
            if Kc is not None:
                # without the zeros of its d x d blocks (multiples of I_d for the penalty:
                # half of the CSR's entries in 2D), which every K_c u would multiply
                Kc = sp.csr_array(Kc, copy=True)  # a copy: S of springs is kept elsewhere
                Kc.eliminate_zeros()
            p._lazy["addon"] = Kc
        return p._lazy["addon"]

    def tangent_matrix(self, cloud: PointCloud, bonds: Bonds, dPdF: Any) -> sp.bsr_array:
        """``K_T = Gᵀ blockdiag(w V dP/dF) G`` (+ the linear control stiffness), BSR.

        Parameters
        ----------
        dPdF : (n_gp, d, d, d, d) array_like of float
            ``dPdF[g, i, j, k, l] = ∂P_ij/∂F_kl`` per gradient point; reshaped to
            ``(d², d²)`` blocks in the row-major ``(i, j)`` order of ``vec F`` (the order of
            G's rows).

        Returns
        -------
        scipy.sparse.bsr_array of shape (n*d, n*d), blocksize (d, d)
            Nonsymmetric unless ``dP/dF`` has major symmetry (then symmetrized to the
            last bit); blocks that cancel in exact arithmetic (the δ = h sub-lattice
            coupling) are dropped.
        """
        p = self._plan(cloud, bonds)
        d = cloud.dim
        n_gp = p.gp_owner.size
        A = as_float_array(dPdF, "dPdF")
        if A.shape not in ((n_gp, d, d, d, d), (n_gp, d * d, d * d)):
            raise ShapeError(f"dPdF must have shape ({n_gp}, {d}, {d}, {d}, {d}), got {A.shape}")
        vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
        scale = p.weight * vol[p.gp_owner] * p.energy
        A = A.reshape(n_gp, d * d, d * d) * scale[:, None, None]
        blk = p.blocks
        Gd, AG = _tangent_blocks_product(blk, A, d)
        shape = (n_gp * d * d, p.n_points * d)
        Gb = sp.bsr_array((Gd, blk.col, blk.indptr), shape=shape, blocksize=(d * d, d))
        AGb = sp.bsr_array((AG, blk.col, blk.indptr), shape=shape, blocksize=(d * d, d))
        K = _gradient._drop_zero_blocks(bsr_matmul(bsr_transpose(Gb), AGb))
        Kc = self._addon_matrix(cloud, bonds, p)
        if Kc is not None:
            K = sp.bsr_array(sp.csr_array(K) + Kc, blocksize=(d, d))
        if self.symmetric:  # major-symmetric dP/dF: make K_T symmetric to the last bit
            K = sp.bsr_array(0.5 * (K + K.T), blocksize=(d, d))
        return _with_diagonal_blocks(K, d)

    def respond(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray,
        state: dict[str, np.ndarray],
        *,
        tangent: bool = False,
    ) -> Response:
        """Return the finite-strain force, trial state, tangent and Cauchy stress at ``u``.

        ``F_g = I + (G u)_g`` per gradient point; ``P, trial, dP/dF =
        material.update(F, state, tangent=tangent)`` (without the tangent, from a
        material that has ``piola(F, state)``: ``P`` from it and the trial state on the
        first read of ``Response.state``); ``f = -Gᵀ vec(w V P)`` and
        ``K_T = Gᵀ blockdiag(w V dP/dF) G`` (:meth:`nodal_force`, :meth:`tangent_matrix`).
        Penalty, springs and ADS controls are linear add-ons: ``f -= K_c u``,
        ``K_T += K_c``.  ``state`` (from :meth:`initial_state` or a committed trial state)
        is not modified.  Without ``material=`` this is the linear model
        (:meth:`pdlin.models.Model.respond`).

        Returns
        -------
        Response
            ``force (n, d)``, ``state`` (trial, per gradient point), ``tangent`` (BSR or
            None), ``stress`` (Cauchy per particle: mean over its gradient points, ``(n, d,
            d)``), ``calls`` (constitutive evaluations: the number of gradient points).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.
        state : dict of str -> ndarray
            Committed state (per gradient point).
        tangent : bool
            Whether to compute ``K_T``.

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((6, 6), spacing=1 / 6)
        >>> bonds = pdlin.find_bonds(cloud, ratio=1.0)
        >>> model = pdlin.Correspondence(material=pdlin.CrystalPlasticity())
        >>> state = model.initial_state(cloud, bonds)
        >>> Fbar = np.array([[1.0, 0.002], [0.002, 1.0]])
        >>> r = model.respond(cloud, bonds, cloud.points @ (Fbar - np.eye(2)).T, state,
        ...                   tangent=True)
        >>> r.force.shape, r.tangent.shape, r.calls, model.symmetric
        ((36, 2), (72, 72), 36, False)
        >>> round(float(r.stress[14, 0, 1]), 3)   # interior particle, elastic
        8.0
        """
        if self.material is None:
            return super().respond(cloud, bonds, u, state, tangent=tangent)
        p = self._plan(cloud, bonds)
        d, n = cloud.dim, cloud.n
        n_gp = p.gp_owner.size
        uu = _as_u(u, cloud)
        if not isinstance(state, Mapping):
            raise InputTypeError(
                f"state must be a dict from initial_state(cloud, bonds), got {type(state).__name__}"
            )
        for key, val in state.items():
            if isinstance(val, np.ndarray) and val.ndim and val.shape[0] != n_gp:
                raise ShapeError(
                    f"state[{key!r}] must have one row per gradient point ({n_gp}), got "
                    f"shape {val.shape} (use model.initial_state(cloud, bonds))"
                )
        x = uu.ravel()
        Gx = np.asarray(_threaded(p, "G", p.G) @ x)
        if "eye" not in p._lazy:  # vec I per gradient point: I + G u as one contiguous add
            p._lazy["eye"] = np.tile(np.eye(d).ravel(), n_gp)
        F = np.add(Gx, p._lazy["eye"], out=Gx).reshape(n_gp, d, d)
        material = self.material
        trial: Any
        if not tangent and hasattr(material, "piola"):
            # the force alone (an ADR iteration, a line-search trial): the material's
            # stress without its trial state, which is computed on the first read of
            # Response.state (once per converged step) from the same F and state
            P, A = material.piola(F, state), None

            def trial() -> dict[str, np.ndarray]:
                return dict(material.update(F, state)[1])

        else:
            P, trial, A = material.update(F, state, tangent=tangent)
            trial = dict(trial)
        P = np.asarray(P, dtype=float)
        if P.shape == (n_gp, d, d):  # the usual case, checked here without a copy
            check_finite(P, "P")
            force = self._force_of(cloud, p, P.reshape(n_gp, d * d))
        else:  # validated (one P for all, or a shape error)
            force = self.nodal_force(cloud, bonds, P).ravel()
        # the control's assembled stiffness (the tangent's too): at 10⁵ points its product
        # costs 1.8 ms against 23 ms matrix-free (_penalty_force; 2D, δ = h penalty)
        Kc = self._addon_matrix(cloud, bonds, p)
        if Kc is not None:
            force -= _threaded(p, "addon", Kc) @ x
        K = None
        if tangent:
            if A is None:
                raise ModelError(
                    f"material.update(..., tangent=True) must return dP/dF, got None "
                    f"({type(self.material).__name__})"
                )
            K = self.tangent_matrix(cloud, bonds, A)
        cauchy: Any = getattr(self.material, "cauchy", None)
        if cauchy is None:
            from ...constitutive.crystal_plasticity import cauchy_stress

            cauchy = cauchy_stress
        owner = p.gp_owner

        def sigma() -> np.ndarray:  # on first read (once per converged step)
            return _mean_per_point(owner, np.asarray(cauchy(P, F)), n)

        return Response(force.reshape(n, d), trial, K, sigma, int(n_gp))

    def stress(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Return the Cauchy stress per particle: the mean over its stress points.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.

        Returns
        -------
        (n, d, d) ndarray of float
        """
        p = self._plan(cloud, bonds)
        d = cloud.dim
        grad = self.gradient(cloud, bonds, u).reshape(-1, d * d)
        P = voigt_projector(d)
        sv = np.einsum("gab,gb->ga", p.Cv, grad @ P.T)
        return _mean_per_point(p.gp_owner, (sv @ P).reshape(-1, d, d), cloud.n)

    def strain(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Return the small strain per particle: the mean over its stress points.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        u : (n, d) array_like
            Nodal displacement.

        Returns
        -------
        (n, d, d) ndarray of float
        """
        p = self._plan(cloud, bonds)
        grad = self.gradient(cloud, bonds, u)
        return _mean_per_point(p.gp_owner, 0.5 * (grad + np.swapaxes(grad, 1, 2)), cloud.n)

    def shadow_loads(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        *,
        F: Any = None,
        stress: Any = None,
    ) -> np.ndarray:
        """Return the nodal force of the prescribed shadow stress on the real points.

        ``-(Σ_j G_jᵀ (w V σ_S,:j))`` over the gradient points of the shadow
        particles (stress points: ``w = w_s``), whose rows of G are built from
        the intact shape tensor (pdlin's choice for the shadow layer of Javaheri et al.
        (2022), Sec. II.D); add it to the external load
        (e.g. as a :class:`pdlin.BodyForce` on the real points, see
        :func:`shadow_problem`).  Give the shadow stress directly
        (``stress``, ``(m, d, d)`` or ``(d, d)``) or through ``F``
        (``σ = C : ε(F)`` with each shadow particle's own C).

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).
        F : (d, d) array_like, optional
            Deformation gradient of the shadow particles (``σ = C : ε(F)``).
        stress : (m, d, d) or (d, d) array_like, optional
            The shadow stress itself, instead of ``F``.

        Returns
        -------
        (n, d) ndarray of float
            Zero on the shadow particles.

        Raises
        ------
        ModelError, InputError
            No ``shadow`` set, or not exactly one of ``F`` and ``stress``.
        """
        if self.shadow is None:
            raise ModelError("shadow_loads needs a model built with shadow=indices, got None")
        p = self._plan(cloud, bonds)
        d = cloud.dim
        m = self.shadow.size
        if (F is None) == (stress is None):
            raise InputError("shadow_loads needs exactly one of F or stress")
        P = voigt_projector(d)
        if F is not None:
            Fm = as_float_array(F, "F")
            if Fm.shape != (d, d):
                raise ShapeError(f"F must have shape ({d}, {d}), got {Fm.shape}")
            H = (Fm - np.eye(d)).ravel()
            sv = np.einsum("gab,b->ga", self.voigt_stiffness(cloud)[self.shadow], P @ H)
            sig = sv @ P  # vec layout with both shear entries
        else:
            s = as_float_array(stress, "stress")
            if s.shape == (d, d):
                s = np.broadcast_to(s, (m, d, d))
            if s.shape != (m, d, d):
                raise ShapeError(
                    f"stress must have shape ({m}, {d}, {d}) or ({d}, {d}), got {s.shape}"
                )
            sig = s.reshape(m, d * d)
        vol = np.asarray(cloud.volumes) * (1.0 if d == 3 else cloud.thickness)
        full = np.zeros((p.gp_owner.size, d * d))
        rows = np.flatnonzero(~p.energy)  # gradient points of shadow particles
        owner = p.gp_owner[rows]
        wv = p.weight[rows] * vol[owner]
        full[rows] = sig[np.searchsorted(self.shadow, owner)] * wv[:, None]
        return -np.asarray(p.G.T @ full.ravel()).reshape(cloud.n, d)

    def describe(self) -> dict[str, Any]:
        """Return a plain-data description of the model (for results and logs).

        Returns
        -------
        dict
            Model name, elastic constants or material, control and its parameters.
        """
        out: dict[str, Any] = {
            "model": "Correspondence",
            "control": self.control,
            "plane": self.plane,
            "shadow": None if self.shadow is None else int(self.shadow.size),
        }
        if self.material is not None:
            out["material"] = type(self.material).__name__
        if self.control == "penalty":
            out["penalty"] = self.penalty
        if self.control == "stress_points":
            out.update(seed=self.seed, case=self.case, sp_weight=self.sp_weight)
        if self.control in ("springs", "ads"):
            out["coefficient"] = self.coefficient
        if self.assembly:
            out["assembly"] = self.assembly.get("path")
        return out

    def _repr_items(self) -> dict[str, Any]:
        items: dict[str, Any] = {}
        if self.E is not None:
            items["E"] = self.E
            items["nu"] = self.nu
        elif self.C is not None:
            items["C"] = np.asarray(self.C)
        return {**items, **super()._repr_items()}


#: the public path of the class (repr, pickles, checkpoint fingerprints as before the split)
Correspondence.__module__ = "pdlin.models.correspondence"


#: entries of a stress array from which ``w V P`` is multiplied in row chunks on threads
_THREADED_MULTIPLY = 1 << 18


def _threaded(p: _Plan, key: str, A: Any) -> Any:
    """Return ``A`` for repeated mat-vecs, row-blocked on threads when it is large.

    As :class:`pdlin._threads.RowBlocks` (built once, kept in the plan) when it holds at
    least two blocks' worth of entries, so that the nonlinear iterations' ``G u``,
    ``Gᵀ (w V P)`` and ``K_c u`` run on pdlin's threads (the same values bitwise);
    smaller ones stay plain scipy products.
    """
    from ..._threads import ROW_BLOCK_NNZ, RowBlocks

    if A.nnz < 2 * ROW_BLOCK_NNZ:
        return A
    cache = p._lazy.setdefault("row_blocks", {})
    if key not in cache:
        cache[key] = RowBlocks(A, ROW_BLOCK_NNZ)
    return cache[key]


def _as_u(u: Any, cloud: PointCloud) -> np.ndarray:
    return as_displacement(u, cloud.n, cloud.dim)


#: doctest collects the examples of the class's methods here (its ``__module__`` above
#: names the package, where only the class docstring is found)
__test__ = {"Correspondence": Correspondence}
