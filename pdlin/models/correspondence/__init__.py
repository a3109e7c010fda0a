"""Correspondence (non-ordinary state-based) peridynamics on sparse operators.

The model is linear small strain (Javaheri et al. (2022), Sec. III.C; Luo &
Sundararaghavan (2018), Sec. 5): a nonlocal displacement gradient per *gradient
point* (a particle, or a stress point of a particle), ``∇u_g = Σ_b (u_b - u_a) ⊗ c_gb``
with ``c_gb = ω_ab V_b K_g⁻¹ ξ_ab`` (Javaheri et al. (2022), Eqs. 6-7, in sparse form),
Cauchy stress ``σ_g = C_a : ε_g`` used in place of ``P``, and the energy
``Π = ½ Σ_g w_g V_a ε_g : C_a : ε_g``.  The stiffness is therefore

``K = Gᵀ blockdiag(w_g V_a C_a) G``

with ``G`` the sparse gradient operator (``n_gp·d²`` x ``n·d``); it is symmetric PSD for
any sign of the weights.  Zero-energy-mode controls: ``'none'``, ``'higher_order'``
(Javaheri et al. (2022)), ``'penalty'`` (a bond-based penalty on the non-affine part of
each bond), ``'stress_points'`` (Luo & Sundararaghavan (2018), Sec. 3) and the baseline
control forces ``'springs'`` and ``'ads'`` (averaged displacement state, Luo &
Sundararaghavan (2018), Eqs. 7-8).  See ``docs/correspondence.md``.

The package's modules:

- :mod:`~pdlin.models.correspondence.gradient`: the gradient operator G (bond
  coefficients, blocks, CSR), the block products and their threaded / numba paths;
- :mod:`~pdlin.models.correspondence.controls`: what the zero-energy controls add
  (stress-point split, penalty, springs and ADS stiffness);
- :mod:`~pdlin.models.correspondence.model`: :class:`Correspondence` itself (assembly
  plan, operators, the nonlinear-material interface);
- :mod:`~pdlin.models.correspondence.shadow`: the shadow-layer problem builder.
"""

from .controls import CONTROLS, DEFAULT_CONTROL_COEFFICIENT, SP_BALANCE_TOL, SP_MIN_RATIO
from .gradient import gradient_operator, intact_shape_tensor, voigt_projector
from .model import DEFAULT_MAX_BYTES, Correspondence
from .peridigm import PeridigmCorrespondence
from .shadow import shadow_problem, shadow_real_counts

__all__ = [
    "Correspondence",
    "PeridigmCorrespondence",
    "CONTROLS",
    "gradient_operator",
    "voigt_projector",
    "intact_shape_tensor",
    "shadow_real_counts",
    "shadow_problem",
    "DEFAULT_CONTROL_COEFFICIENT",
    "DEFAULT_MAX_BYTES",
    "SP_BALANCE_TOL",
    "SP_MIN_RATIO",
]
