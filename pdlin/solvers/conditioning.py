"""Condition estimates of factored systems, and the warning when digits are lost.

A direct solve whose residual is tiny can still return a wrong field when the matrix is
nearly singular: the forward error is bounded by ``κ(A) ε`` (Higham, *Accuracy and
Stability of Numerical Algorithms*, §7), not by the residual.  With a factorization at hand
the 1-norm condition number ``κ₁(A) = ‖A‖₁ ‖A⁻¹‖₁`` is estimated from a handful of solves
by Hager-Higham's block 1-norm estimator (:func:`scipy.sparse.linalg.onenormest`), the same
estimate LAPACK's ``xGECON`` gives; for symmetric matrices ``A⁻ᵀ = A⁻¹`` and the solves are
the factorization's own.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import AccuracyWarning

__all__ = ["condition_estimate", "warn_if_ill_conditioned", "CONDITION_WARN"]

#: κ₁ above which a solve warns: at 1e12 only about 4 of float64's 16 significant digits
#: are guaranteed in the solution (forward error ≲ κ ε with ε = 2.2e-16)
CONDITION_WARN = 1e12


def condition_estimate(
    A: Any,
    solve: Callable[[np.ndarray], np.ndarray],
    *,
    solve_transposed: Callable[[np.ndarray], np.ndarray] | None = None,
    symmetric: bool = True,
) -> float:
    """Estimate of the 1-norm condition number ``‖A‖₁ ‖A⁻¹‖₁`` from a factorization.

    Parameters
    ----------
    A : sparse array
        The (square) matrix.
    solve : callable
        ``solve(b) -> A⁻¹ b`` (the factorization's solve).
    solve_transposed : callable, optional
        ``A⁻ᵀ b``; needed when ``A`` is not symmetric (without it, NaN is returned).
    symmetric : bool
        ``A`` is symmetric, so ``A⁻ᵀ = A⁻¹``.

    Returns
    -------
    float
        The estimate (a lower bound of κ₁, usually within a factor 3; ``inf`` for a
        singular factorization, NaN when it cannot be computed).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp, scipy.sparse.linalg as spla
    >>> A = sp.csc_array(np.diag([1.0, 1e-3, 2.0]))
    >>> lu = spla.splu(A)
    >>> round(condition_estimate(A, lu.solve))   # 2 / 1e-3
    2000
    """
    n = A.shape[0]
    if n == 0:
        return 1.0
    tr = solve if symmetric else solve_transposed
    if tr is None:
        return float("nan")
    norm_a = (
        float(spla.norm(sp.csr_array(A), 1))
        if sp.issparse(A)
        else float(np.linalg.norm(np.asarray(A), 1))
    )
    op = spla.LinearOperator(
        (n, n),
        matvec=lambda x: solve(np.asarray(x, dtype=float).reshape(-1)),
        rmatvec=lambda x: tr(np.asarray(x, dtype=float).reshape(-1)),
        dtype=float,
    )
    try:
        with np.errstate(all="ignore"):
            norm_inv = float(spla.onenormest(op, t=2))
    except (ArithmeticError, ValueError, RuntimeError):
        return float("nan")
    if not math.isfinite(norm_inv):
        return float("inf")
    return norm_a * norm_inv


def warn_if_ill_conditioned(kappa: float, what: str, *, limit: float = CONDITION_WARN) -> None:
    """Issue an :class:`~pdlin.errors.AccuracyWarning` when ``kappa`` exceeds ``limit``.

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     warn_if_ill_conditioned(3e13, "direct solve")
    >>> str(w[0].message)[:59]
    'direct solve: condition number estimate 3.0e+13, so about 2'
    """
    if not (math.isfinite(kappa) and kappa > limit) and not math.isinf(kappa):
        return
    digits = max(0, int(math.floor(16 - math.log10(kappa)))) if math.isfinite(kappa) else 0
    warnings.warn(
        f"{what}: condition number estimate {kappa:.1e}, so about {digits} significant "
        "digit(s) of the solution can be trusted (forward error ≲ κ ε); a near-singular "
        "system: check the Dirichlet conditions (one clamped point, a weakly held rotation), "
        "stiffness contrasts, near-incompressibility or the units",
        AccuracyWarning,
        stacklevel=3,
    )
