"""Peridigm's ordinary state-based materials with their own finite kinematics.

Peridigm's ``Elastic`` material (``src/materials/elastic.cxx`` with
``material_utilities.cxx``) and its ``Elastic Plastic`` material
(``elastic_plastic.cxx``; Mitchell 2011, "A nonlocal, ordinary, state-based plasticity
model for peridynamics", SAND2011-3166) as nonlinear pdlin models for
:func:`pdlin.solve_nonlinear`.  Per directed bond ``b = (i, j)`` (3D, influence ω = 1):

* reference length ``ζ = |ξ|``, deformed bond ``Y = ξ + u_j - u_i``, exact extension
  ``e = |Y| - ζ`` and direction ``n = Y / |Y|``;
* weighted volume ``m_i = Σ_j ζ² V_j``, dilatation ``θ_i = (3 / m_i) Σ_j ζ e V_j``;
* deviatoric extension ``e^d = e - θ_i ζ / 3`` and trial deviatoric force
  ``t^d_tr = α_i (e^d - e^dp_N)``, ``α_i = 15 μ_i / m_i``, with the committed deviatoric
  plastic extension ``e^dp_N`` (0 for ``Elastic``);
* yield function ``f = ‖t^d_tr‖² / 2 - ψ_0`` with ``‖t‖² = Σ_j t² V_j`` and
  ``ψ_0 = 25 σ_y² / (8 π δ⁵)`` (Mitchell 2011; ``elastic_plastic.cxx``); when ``f > 0``
  the return mapping ``t^d = √(2ψ_0) t^d_tr / ‖t^d_tr‖``, ``Δλ = (‖t^d_tr‖ / √(2ψ_0) - 1) / α``
  and ``e^dp = e^dp_N + Δλ t^d``;
* scalar force ``t = 3 K_i θ_i ζ / m_i + t^d`` along ``n``: the nodal force
  ``t V_i V_j n`` acts on ``i`` and its reaction on ``j``.

The tangent is the consistent linearization of that force (including the return mapping,
with the point's elastic / plastic decision frozen), so Newton converges quadratically.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from .._validation import as_displacement, as_float_array
from ..errors import InputError, ModelError, NonFiniteError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from .base import Response
from .lps import LPS

__all__ = ["PeridigmElastic", "PeridigmElasticPlastic", "peridigm_yield_value"]


def peridigm_yield_value(yield_stress: Any, horizon: Any) -> np.ndarray:
    """Return Peridigm's 3D yield value ``ψ_0 = 25 σ_y² / (8 π δ⁵)``.

    The value of the deviatoric force-state norm's ``‖t^d‖² / 2`` at yield in uniaxial
    stress (Mitchell 2011, SAND2011-3166; ``elastic_plastic.cxx``).  An infinite yield
    stress (Peridigm's ``Disable Plasticity``) gives an infinite value: never yields.

    Parameters
    ----------
    yield_stress : float or array_like
        Yield stress ``σ_y`` (> 0, ``inf`` allowed).
    horizon : float or array_like
        Horizon ``δ`` (> 0).

    Returns
    -------
    ndarray
        ``ψ_0`` (broadcast of the two).

    Raises
    ------
    InputError
        A yield stress or horizon that is not positive.

    Examples
    --------
    >>> float(peridigm_yield_value(1.0, 1.0)) == 25 / (8 * 3.141592653589793)
    True
    """
    sy = np.asarray(yield_stress, dtype=float)
    h = np.asarray(horizon, dtype=float)
    if np.any(np.isnan(sy)) or np.any(sy <= 0):
        raise InputError(f"yield_stress must be > 0 (inf: never yields), got {yield_stress!r}")
    if np.any(~np.isfinite(h)) or np.any(h <= 0):
        raise InputError(f"horizon must be finite and > 0, got {horizon!r}")
    with np.errstate(over="ignore"):
        return 25.0 * sy * sy / (8.0 * np.pi * h**5)


class PeridigmElasticPlastic(LPS):
    """Peridigm's ``Elastic Plastic`` material: finite-kinematics LPS with perfect plasticity.

    Ordinary state-based elastic-perfectly-plastic model of Mitchell (2011,
    SAND2011-3166) as Peridigm implements it (``elastic_plastic.cxx``): the deviatoric
    force state is bounded by the yield surface ``‖t^d‖² / 2 = ψ_0`` (see
    ``peridigm_yield_value``), the bonds' deviatoric plastic extensions are the
    committed state (``state["edp"]``, one per directed bond; ``state["lambda"]`` the
    accumulated plastic multiplier per point).  Without yielding the force is Peridigm's
    ``Elastic`` one with finite kinematics (:class:`PeridigmElastic`).  Its linearization at
    ``u = 0`` is ``LPS(K=, G=, peridigm=True)`` (which ``stiffness`` gives); nonlinear
    solves go through :meth:`respond`.  3D only (Peridigm's decks are 3D).

    Parameters
    ----------
    K, G : float or (n,) array_like
        Bulk and shear modulus (per point for several blocks).
    yield_stress : float or (n,) array_like, optional
        Yield stress ``σ_y`` per point; ``None`` or ``inf``: never yields.
    horizon : float or (n,) array_like, optional
        Horizon ``δ`` of the yield value; default each point's horizon of the bonds.

    Examples
    --------
    A bar pulled along x yields; unloaded to zero force it keeps a plastic extension:

    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((8, 3, 3), spacing=1.0)
    >>> m = PeridigmElasticPlastic(K=1.0e3, G=5.0e2, yield_stress=2.0)
    >>> p = pdlin.StaticProblem(m, cloud, horizon=1.51, dirichlet=[
    ...     pdlin.Dirichlet("x-", 0.0, components="x"), pdlin.Dirichlet("x+", 0.03, components="x"),
    ...     pdlin.Dirichlet("all", 0.0, components="yz")])
    >>> r = pdlin.solve_nonlinear(p, steps=3, method="newton")
    >>> bool(r.state_at(2)["lambda"].max() > 0)
    True
    """

    nonlinear = True

    def __init__(self, *, K: Any, G: Any, yield_stress: Any = None, horizon: Any = None) -> None:
        super().__init__(K=K, G=G, peridigm=True)
        sy = np.inf if yield_stress is None else yield_stress
        try:
            sy_arr = np.asarray(sy, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"yield_stress must be a number or an array, got {sy!r}") from exc
        if np.any(np.isnan(sy_arr)) or np.any(sy_arr <= 0):
            raise InputError(f"yield_stress must be > 0 (None or inf: never yields), got {sy!r}")
        self.yield_stress = sy_arr if sy_arr.ndim else float(sy_arr)
        if horizon is not None:
            h = as_float_array(horizon, "horizon")
            if np.any(~np.isfinite(h)) or np.any(h <= 0):
                raise InputError(f"horizon must be finite and > 0, got {horizon!r}")
            horizon = h if h.ndim else float(h)
        self.yield_horizon = horizon

    # -- state ---------------------------------------------------------------
    def initial_state(self, cloud: PointCloud, bonds: Bonds) -> dict[str, np.ndarray]:
        """Return the virgin state: no plastic extension, no plastic multiplier.

        Parameters
        ----------
        cloud : PointCloud
            The points.
        bonds : Bonds
            Their (directed) bonds.

        Returns
        -------
        dict
            ``edp`` (one per directed bond) and ``lambda`` (one per point), zeros.
        """
        return {"edp": np.zeros(bonds.n_bonds), "lambda": np.zeros(cloud.n)}

    def _point_constants(self, cloud: PointCloud, bonds: Bonds) -> dict[str, np.ndarray]:
        """Bond arrays (each read once) and ``K``, ``μ``, ``m``, ``α``, ``ψ_0`` per point."""
        if cloud.dim != 3:
            raise ModelError(
                f"{type(self).__name__} is Peridigm's 3D material; got a {cloud.dim}D cloud"
            )
        n = cloud.n
        k_mod, mu = (np.broadcast_to(np.asarray(a, float), (n,)) for a in self.moduli(3))
        # compact bonds compute i, xi, length, volume_j on every access: read them once
        i, j, xi = bonds.i, bonds.j, bonds.xi
        zeta = np.sqrt(np.einsum("ij,ij->i", xi, xi))
        vj = np.asarray(bonds.volume_j, float)
        m = np.bincount(i, zeta * zeta * vj, n)
        if np.any(m <= 0):
            bad = int(np.flatnonzero(m <= 0)[0])
            raise ModelError(f"point {bad} has no bonds (weighted volume 0)")
        horizon = bonds.horizon if self.yield_horizon is None else self.yield_horizon
        psi0 = np.broadcast_to(peridigm_yield_value(self.yield_stress, horizon), (n,))
        return {
            "K": k_mod, "mu": mu, "m": m, "alpha": 15.0 * mu / m, "psi0": psi0,
            "i": i, "j": j, "xi": xi, "zeta": zeta, "vj": vj,
        }  # fmt: skip

    def force_and_state(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: Any,
        state: dict[str, np.ndarray],
        *,
        theta: Any = None,
    ) -> dict[str, np.ndarray]:
        """Peridigm's force and return mapping at ``u`` from the committed ``state``.

        Parameters
        ----------
        cloud : PointCloud
            The points (3D).
        bonds : Bonds
            Their directed bonds.
        u : (n, 3) or (n * 3,) array_like
            Displacement.
        state : dict
            Committed ``edp`` (per bond) and ``lambda`` (per point).
        theta : (n,) array_like, optional
            Dilatation to use instead of the computed one (Peridigm's material unit test
            sets it to zero); ``None``: ``θ_i = (3 / m_i) Σ_j ζ e V_j``.

        Returns
        -------
        dict
            ``force`` (n, 3) nodal, ``t`` (scalar force state per bond), ``edp``,
            ``lambda``, ``theta``, ``plastic`` (per point) and the intermediate arrays the
            tangent uses.

        Raises
        ------
        NonFiniteError
            A bond of zero deformed length (its direction is undefined).
        """
        c = self._point_constants(cloud, bonds)
        n = cloud.n
        i, j = c["i"], c["j"]
        uu = as_displacement(u, n, 3)
        y = c["xi"] + uu[j] - uu[i]
        ly = np.sqrt(np.einsum("ij,ij->i", y, y))
        if not np.all(ly > 0):
            bad = int(np.flatnonzero(~(ly > 0))[0])
            raise NonFiniteError(
                f"bond {bad} ({int(i[bad])}, {int(j[bad])}) has deformed length {ly[bad]}: "
                "its direction is undefined"
            )
        zeta, vj = c["zeta"], c["vj"]
        e = ly - zeta
        m = c["m"]
        th = np.bincount(i, 3.0 * zeta * e * vj, n) / m if theta is None else np.asarray(theta)
        th = np.broadcast_to(np.asarray(th, float), (n,))
        alpha = c["alpha"]
        edp_n = np.asarray(state.get("edp", 0.0), float)
        trial = alpha[i] * (e - th[i] * zeta / 3.0 - edp_n)
        norm = np.sqrt(np.bincount(i, trial * trial * vj, n))
        psi0 = c["psi0"]
        plastic = norm * norm / 2.0 - psi0 > 0
        s = np.sqrt(2.0 * psi0)
        scale = np.ones(n)
        np.divide(s, norm, out=scale, where=plastic)
        td = trial * scale[i]
        dlam = np.zeros(n)
        np.divide(norm / np.where(plastic, s, 1.0) - 1.0, alpha, out=dlam, where=plastic)
        edp = np.where(plastic[i], edp_n + td * dlam[i], edp_n)
        t = 3.0 * c["K"][i] * th[i] * zeta / m[i] + td
        unit = y / ly[:, None]
        pair = (t * np.asarray(cloud.volumes, float)[i] * vj)[:, None] * unit
        f = np.stack(
            [np.bincount(i, pair[:, k], n) - np.bincount(j, pair[:, k], n) for k in range(3)],
            axis=-1,
        )
        lam = np.asarray(state.get("lambda", np.zeros(n)), float) + dlam
        return {
            "force": f, "t": t, "edp": edp, "lambda": lam, "theta": th, "plastic": plastic,
            "unit": unit, "ly": ly, "trial": trial, "norm": norm, "s": s, **c,
        }  # fmt: skip

    def tangent(self, cloud: PointCloud, bonds: Bonds, out: dict[str, np.ndarray]) -> sp.sparray:
        """Consistent tangent ``K_T = -∂f/∂u`` at a :meth:`force_and_state` result.

        ``K_T = Gᵀ W (∂t/∂e) G + Σ_b (V_i V_j t_b / |Y_b|) (I - n nᵀ)`` on the bond's two
        points, with ``G`` the rows ``∂e_b/∂u`` (``-n`` at ``i``, ``n`` at ``j``),
        ``W = diag(V_i V_j)`` and ``∂t/∂e`` the per-point family matrices of the
        elastic law or of the return mapping (the point's elastic / plastic decision
        frozen).

        Parameters
        ----------
        cloud : PointCloud
            The points.
        bonds : Bonds
            Their bonds.
        out : dict
            What :meth:`force_and_state` returned.

        Returns
        -------
        scipy.sparse.bsr_array
            ``(3n, 3n)``, blocksize 3.
        """
        n, nb = cloud.n, bonds.n_bonds
        i, j = out["i"], out["j"]
        unit, ly, zeta, vj = out["unit"], out["ly"], out["zeta"], out["vj"]
        w = np.asarray(cloud.volumes, float)[i] * vj
        rows = np.repeat(np.arange(nb), 6)
        cols = np.concatenate([3 * i[:, None] + np.arange(3), 3 * j[:, None] + np.arange(3)], 1)
        grad = sp.csr_array(
            (np.concatenate([-unit, unit], 1).ravel(), (rows, cols.ravel())), shape=(nb, 3 * n)
        )
        owner = sp.csr_array((np.ones(nb), (i, np.arange(nb))), shape=(n, nb))
        m, alpha, k_mod = out["m"], out["alpha"], out["K"]
        plastic, norm, s, trial = out["plastic"], out["norm"], out["s"], out["trial"]
        # ∂t_b/∂e_d = d_i δ_bd + Σ_k c_k,i a_k[b] b_k[d] over the family of i
        ratio = np.where(plastic, s / np.where(plastic, norm, 1.0), 1.0)
        d = alpha * ratio
        inv3 = np.where(plastic, ratio / np.where(plastic, norm, 1.0) ** 2, 0.0)
        tvz = np.bincount(i, trial * vj * zeta, n)
        terms = [
            (9.0 * k_mod / m**2 - alpha * ratio / m, zeta, zeta * vj),
            (-alpha * inv3, trial, trial * vj),
            (alpha * inv3 * tvz / m, trial, zeta * vj),
        ]
        kt = grad.T @ (sp.diags_array(w * d[i]) @ grad)
        for coef, a, b in terms:
            if not np.any(coef):
                continue
            left = owner @ sp.diags_array(w * a) @ grad
            right = owner @ sp.diags_array(b) @ grad
            kt = kt + left.T @ sp.diags_array(coef) @ right
        # geometric stiffness of the turning bond direction
        g = w * out["t"] / ly
        proj = g[:, None, None] * (np.eye(3) - unit[:, :, None] * unit[:, None, :])
        bi = np.concatenate([i, j, i, j])
        bj = np.concatenate([i, j, j, i])
        blocks = np.concatenate([proj, proj, -proj, -proj])
        r = (3 * bi[:, None, None] + np.arange(3)[None, :, None]) + 0 * np.arange(3)
        cidx = (3 * bj[:, None, None] + np.arange(3)[None, None, :]) + 0 * r
        geo = sp.csr_array((blocks.ravel(), (r.ravel(), cidx.ravel())), shape=(3 * n, 3 * n))
        return sp.bsr_array(sp.csr_array(kt + geo), blocksize=(3, 3))

    def respond(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray,
        state: dict[str, np.ndarray],
        *,
        tangent: bool = False,
    ) -> Response:
        """Return the force, trial state and (optionally) consistent tangent at ``u``.

        Parameters
        ----------
        cloud : PointCloud
            The points (3D).
        bonds : Bonds
            Their directed bonds.
        u : (n, 3) or (n * 3,) array_like
            Displacement.
        state : dict
            Committed ``edp`` and ``lambda`` (not modified).
        tangent : bool
            Also return ``K_T``.

        Returns
        -------
        Response
            Nodal force, trial state ``{"edp", "lambda"}``, tangent (BSR) or None.

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cloud = pdlin.grid((3, 3, 3), spacing=1.0)
        >>> bonds = pdlin.find_bonds(cloud, 1.5)
        >>> model = PeridigmElastic(K=1.0, G=0.5)
        >>> Q = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        >>> u = cloud.points @ Q.T - cloud.points              # a rigid rotation
        >>> r = model.respond(cloud, bonds, u, model.initial_state(cloud, bonds))
        >>> float(np.abs(r.force).max()) < 1e-14
        True
        """
        out = self.force_and_state(cloud, bonds, u, state)
        kt = self.tangent(cloud, bonds, out) if tangent else None
        return Response(out["force"], {"edp": out["edp"], "lambda": out["lambda"]}, kt, None, 0)

    def describe(self) -> dict[str, Any]:
        """Return the model's parameters as plain data.

        Returns
        -------
        dict
            As ``LPS.describe``, with ``kinematics`` and ``yield_stress`` (a number, or
            ``'per-point'``).
        """
        out = super().describe()
        out["kinematics"] = "finite"
        ys = self.yield_stress
        out["yield_stress"] = "per-point" if isinstance(ys, np.ndarray) else ys
        return out


class PeridigmElastic(PeridigmElasticPlastic):
    """Peridigm's ``Elastic`` material with its finite kinematics (``elastic.cxx``).

    ``t = 3 K θ ζ / m + α (e - θ ζ / 3)`` along the deformed bond, with the exact
    extension ``e = |ξ + η| - |ξ|`` and the dilatation ``θ = (3/m) Σ ζ e V``; ω = 1,
    ``m = Σ ζ² V``, ``α = 15 μ / m``.  ``LPS(K=, G=, peridigm=True)`` is its
    linearization at ``u = 0``; this model is what :func:`pdlin.solve_nonlinear` iterates
    (Newton with the consistent tangent).

    Parameters
    ----------
    K, G : float or (n,) array_like
        Bulk and shear modulus (per point for several blocks).

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((6, 3, 3), spacing=1.0)
    >>> p = pdlin.StaticProblem(PeridigmElastic(K=1.0, G=0.5), cloud, horizon=1.51,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [0.5, 0.0, 0.0])])
    >>> r = pdlin.solve_nonlinear(p, steps=2, method="newton")
    >>> bool(r.iterations[-1] <= 6)
    True
    """

    def __init__(self, *, K: Any, G: Any) -> None:
        super().__init__(K=K, G=G, yield_stress=None)
