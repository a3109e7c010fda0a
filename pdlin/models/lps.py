"""Linear peridynamic solid (LPS / ordinary state-based OSBPD) with spherical weights."""

from __future__ import annotations

from typing import Any

from .._validation import as_bool
from .ordinary_state import OrdinaryStateBased, analytic_weighted_volume, bulk_shear_moduli

__all__ = ["LPS", "bulk_shear_moduli", "analytic_weighted_volume"]


class LPS(OrdinaryStateBased):
    """Ordinary state-based peridynamics with spherical influence weights (LPS, OSBPD).

    ``θ_i = (n_d/m_i) Σ_j ω r e V_j``, ``e^d = e - θ r / n_d`` and
    ``W_i = κθ²/2 + μ Σ_j ω^d (e^d)² V_j`` with ``ω^d = n_d(n_d+2) ω/(2 m_i)``
    (Liu, Chen & Skelton, XOSB, Eqs. 9-28, the OSBPD baseline of XOSB).  Linearized, ``f = -K u``.

    Parameters
    ----------
    E : float or (n,) array_like
        Young's modulus (per point for graded materials).
    nu : float
        Poisson ratio in (-1, 0.5); any value (unlike bond-based PD).
    K, G, lam, mu : float or (n,) array_like, optional
        Bulk modulus, shear modulus (``mu`` is the same), Lamé's first
        constant: give any two isotropic constants instead of ``E, nu``
        (Peridigm decks give ``K`` and ``G``); see
        :func:`pdlin.constitutive.isotropic_constants`.
    plane : {'stress', 'strain'}
        2D assumption: ``κ = E/(2(1-ν))`` or ``E/(2(1+ν)(1-2ν))``.
    weighted_volume : {'analytic', 'discrete'}
        ``m_i = πδ⁴/2`` (2D) / ``4πδ⁵/5`` (3D) of the owner's horizon, or the
        discrete ``m_i = Σ_j ω r² V_j``.
    peridigm : bool
        Peridigm's convention: discrete ``m_i`` with ω = 1 (the bonds'
        influence values are ignored), no surface correction.  Implies
        ``weighted_volume='discrete'``.
    linearization : {'energy', 'paper'}
        ``'energy'`` (default): ``K`` is the Hessian of ``Σ V_i W_i``
        (symmetric).  ``'paper'``: the force state of Liu, Chen & Skelton, XOSB, Eq. 70.  The
        two coincide with discrete ``m`` (then ``Σ ω^d r e^d V = 0``).

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((8, 8), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=3.015)
    >>> model = pdlin.LPS(E=1.0, nu=0.3, plane="strain")
    >>> K = pdlin.operators.assemble_stiffness(model, cloud, bonds)
    >>> K.shape, K.blocksize, model.coupling_range, model.symmetric
    ((128, 128), (2, 2), 2, True)
    >>> u = np.random.default_rng(0).normal(size=(cloud.n, 2))
    >>> bool(np.allclose(K @ u.ravel(), -model.internal_force(cloud, bonds, u).ravel()))
    True
    >>> sc = pdlin.LPS(E=1.0, nu=0.3, plane="strain", surface_correction="energy")
    >>> sf = sc.surface_factors(cloud, bonds)
    >>> bool(sf.dilatation[0] > sf.dilatation[27] > 0.9)   # corner point vs centre point
    True
    """

    _corrections = False

    def __init__(
        self,
        E: Any = None,
        nu: Any = None,
        *,
        K: Any = None,
        G: Any = None,
        lam: Any = None,
        mu: Any = None,
        plane: str = "stress",
        weighted_volume: str = "analytic",
        peridigm: bool = False,
        linearization: str = "energy",
        surface_correction: str | None = None,
    ) -> None:
        peridigm = as_bool(peridigm, "peridigm")
        super().__init__(
            E,
            nu,
            K=K,
            G=G,
            lam=lam,
            mu=mu,
            plane=plane,
            linearization=linearization,
            weighted_volume="discrete" if peridigm else weighted_volume,
            unit_influence=bool(peridigm),
            surface_correction=surface_correction,
        )
        self.peridigm = peridigm

    def describe(self) -> dict[str, Any]:
        """Return a plain-data description of the model (for results and logs).

        Returns
        -------
        dict
            As ``OrdinaryStateBased.describe``, with ``peridigm`` and
            ``surface_correction``.
        """
        out = super().describe()
        out["peridigm"] = self.peridigm
        out["surface_correction"] = self.surface_correction
        return out
