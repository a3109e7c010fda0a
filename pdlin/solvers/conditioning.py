"""Condition estimates of factored systems, and the warning when digits are lost.

A direct solve whose residual is tiny can still return a wrong field when the matrix is
nearly singular: the forward error is bounded by ``κ(A) ε`` (Higham, *Accuracy and
Stability of Numerical Algorithms*, §7), not by the residual.  With a factorization at hand
the 1-norm condition number ``κ₁(A) = ‖A‖₁ ‖A⁻¹‖₁`` is estimated from a handful of solves
by Hager-Higham's 1-norm estimator (:func:`scipy.sparse.linalg.onenormest`), the estimate
LAPACK's ``xGECON`` gives; for symmetric matrices ``A⁻ᵀ = A⁻¹`` and the solves are the
factorization's own.

The estimate is of the symmetrically equilibrated matrix ``S A S`` with ``S = diag(a_ii)^-½``
by default: Cholesky and symmetric pivoting are invariant under that scaling (van der Sluis;
Higham §7.3, §10.1), so stiffness contrasts, units and coordinate scales do not count, only
genuine near-singularity does (weakly held rigid motions, near-mechanisms, near-incompressible
state-based models).  Contrasts large enough to lose the force balance are caught by the
solve's own residual check against the reactions.
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

__all__ = [
    "condition_estimate",
    "warn_if_ill_conditioned",
    "CONDITION_WARN",
    "CONDITION_AUTO_MAX",
]

#: κ₁ (of the equilibrated matrix) above which a solve warns: the forward error bound
#: κ ε (ε = 2.2e-16) passes 1e-7, fewer than 7 significant digits guaranteed.  Measured
#: (tests/unit/test_conditioning.py): well-posed PD problems up to 1e5 unknowns have
#: 3e4-1e6; the direct solve's residual check (1e-8) fails from about 2e9 on
CONDITION_WARN = 5e8

#: largest symmetric system whose direct solves estimate their condition by default
#: (``solve_linear(condition="auto")``): the estimate costs a few extra solves with the
#: factorization, a small fraction of the factorization below this size
CONDITION_AUTO_MAX = 100_000


def condition_estimate(
    A: Any,
    solve: Callable[[np.ndarray], np.ndarray],
    *,
    solve_transposed: Callable[[np.ndarray], np.ndarray] | None = None,
    symmetric: bool = True,
    scaled: bool = True,
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
    scaled : bool
        Estimate κ₁ of ``S A S`` with ``S = diag(a_ii)^-½`` (when every ``a_ii > 0``),
        the condition that governs a symmetric factorization's accuracy.

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
    >>> round(condition_estimate(A, lu.solve, scaled=False))   # 2 / 1e-3
    2000
    >>> round(condition_estimate(A, lu.solve))   # a diagonal matrix equilibrates exactly
    1
    """
    n = A.shape[0]
    if n == 0:
        return 1.0
    tr = solve if symmetric else solve_transposed
    if tr is None:
        return float("nan")
    As = sp.csr_array(A) if sp.issparse(A) else sp.csr_array(np.asarray(A, dtype=float))
    scale = np.ones(n)
    if scaled:
        diag = np.asarray(As.diagonal(), dtype=float)
        if np.all(diag > 0) and np.all(np.isfinite(diag)):
            scale = 1.0 / np.sqrt(diag)
            As = sp.csr_array(sp.diags_array(scale) @ As @ sp.diags_array(scale))
    norm_a = float(spla.norm(As, 1))
    back = tr

    def inv(x: np.ndarray) -> np.ndarray:  # (S A S)⁻¹ x = S⁻¹ A⁻¹ S⁻¹ x
        return np.asarray(solve(np.asarray(x, dtype=float).reshape(-1) / scale)) / scale

    def inv_t(x: np.ndarray) -> np.ndarray:
        return np.asarray(back(np.asarray(x, dtype=float).reshape(-1) / scale)) / scale

    op = spla.LinearOperator((n, n), matvec=inv, rmatvec=inv_t, dtype=float)
    try:
        with np.errstate(all="ignore"):
            norm_inv = float(spla.onenormest(op, t=1))
    except (ArithmeticError, ValueError, RuntimeError):
        return float("nan")
    if not math.isfinite(norm_inv):
        return float("inf")
    return norm_a * norm_inv


def warn_if_ill_conditioned(kappa: float, what: str, *, limit: float = CONDITION_WARN) -> None:
    """Issue an :class:`~pdlin.errors.AccuracyWarning` when ``kappa`` exceeds ``limit``.

    Parameters
    ----------
    kappa : float
        Condition-number estimate (``inf`` always warns, ``nan`` never).
    what : str
        The solve it belongs to, first words of the message.
    limit : float
        Threshold (default ``CONDITION_WARN`` = 5e8, about 8 trusted digits left).

    Warns
    -----
    AccuracyWarning
        With the number of significant digits that can be trusted (``16 - log10 κ``).

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
