"""Extended ordinary state-based peridynamics (XOSBPD) for non-spherical horizons."""

from __future__ import annotations

from typing import Any

import numpy as np

from .._validation import as_bool, positive_scalar
from ..errors import InputError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from .ordinary_state import OrdinaryStateBased, StateWeights

__all__ = ["XOSB", "StateWeights"]


class XOSB(OrdinaryStateBased):
    """XOSBPD: ordinary state-based PD with corrected influence weights (Liu, Chen & Skelton, XOSB).

    Per point, ``ω^h = ω_s^h + λ^h·ξ̂^h`` and ``ω^d = ω_s^d + λ^d·ξ̂^d`` solve
    small Gram systems (3x3 / 6x6 and 5x5 / 15x15) so that ``θ_i = tr ε``
    and ``W_i = κ(tr ε)²/2 + μ ε^d:ε^d`` hold exactly for every homogeneous
    strain, at every point of any family (boundaries, graded meshes,
    variable horizons, crack faces).  Points whose family has some
    ``ω^h < 0`` fall back to the spherical weights in the force state
    (Liu, Chen & Skelton, XOSB, Sec. 3.3); θ keeps the corrected ``ω^h``.

    Parameters
    ----------
    E : float or (n,) array_like
        Young's modulus.
    nu : float
        Poisson ratio in (-1, 0.5).
    K, G, lam, mu : float or (n,) array_like, optional
        Any two isotropic constants instead of ``E, nu`` (bulk, shear, Lamé;
        see :func:`pdlin.constitutive.isotropic_constants`).
    plane : {'stress', 'strain'}
        2D assumption (ignored in 3D).
    linearization : {'energy', 'paper'}
        ``'energy'`` (default): ``K_E``, the Hessian of ``Σ V_i W_i``,
        symmetric (CG + AMG).  ``'paper'``: the force state of Eq. 70 and its
        nonsymmetric tangent ``K_p`` (GMRES or LU).
    weighted_volume : {'analytic', 'discrete'}
        ``m_i`` of the spherical weights (default analytic, as in the paper).
    fallback : bool
        Apply the fallback rule (default True; False only for studies).
    max_cond : float
        Scaled condition number above which a point's λ is the minimum-norm
        solution and the point is flagged ``singular`` (with a warning).
    surface_correction : None
        Not supported yet (raises :class:`~pdlin.errors.InputError` for any
        other value): the corrected weights already remove the surface
        effect for homogeneous strains.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((40, 20), spacing=0.025)
    >>> bonds = pdlin.find_bonds(cloud, ratio=3.01)
    >>> model = pdlin.XOSB(E=70e9, nu=0.33)
    >>> model.fallback_points(cloud, bonds).size     # the four corners (Sec. 3.3)
    4
    >>> eps = np.array([[1e-3, 4e-4], [4e-4, -2e-4]])
    >>> theta = model.dilatation(cloud, bonds, cloud.points @ eps.T)
    >>> bool(np.allclose(theta, np.trace(eps), rtol=0, atol=1e-15))
    True
    >>> pdlin.XOSB(E=1.0, nu=0.3, linearization="paper").symmetric
    False
    """

    _corrections = True

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
        linearization: str = "energy",
        weighted_volume: str = "analytic",
        fallback: bool = True,
        max_cond: float = 1e10,
        surface_correction: str | None = None,
    ) -> None:
        if surface_correction is not None:
            raise InputError(
                "XOSB does not support surface_correction yet (its corrected weights already "
                "make θ and W exact for homogeneous strains at every non-fallback point); "
                f"expected None, got {surface_correction!r}"
            )
        fallback = as_bool(fallback, "fallback")
        max_cond = positive_scalar(max_cond, "max_cond")
        super().__init__(
            E,
            nu,
            K=K,
            G=G,
            lam=lam,
            mu=mu,
            plane=plane,
            linearization=linearization,
            weighted_volume=weighted_volume,
            fallback=fallback,
            max_cond=max_cond,
        )

    def fallback_points(self, cloud: PointCloud, bonds: Bonds) -> np.ndarray:
        """Return the indices of the points that use spherical weights in the force state.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        (k,) ndarray of int
        """
        w: StateWeights = self.weights(cloud, bonds)
        return np.flatnonzero(w.fallback)

    def singular_points(self, cloud: PointCloud, bonds: Bonds) -> np.ndarray:
        """Return the indices of the points whose λ system was singular / ill-conditioned.

        Parameters
        ----------
        cloud : PointCloud
            The points (``n`` of them, dimension ``d``).
        bonds : Bonds
            Their bonds (``nb`` ordered bonds).

        Returns
        -------
        (k,) ndarray of int
        """
        return np.flatnonzero(self.weights(cloud, bonds).singular)
