"""Inexact Newton: an AMG-preconditioned Krylov solve of the Newton system, reused.

Newton's tangent ``K_T`` of a history-dependent model (crystal plasticity) is
nonsymmetric and changes at every iteration; factorizing it costs 20-25 s at 2·10⁵
unknowns (SuperLU).  :class:`KrylovDirection` solves ``K_T du = r`` (and the shifted
system ``(K_T + Λ/τ) du = r`` of pseudo-transient continuation) by right-preconditioned
restarted GMRES whose preconditioner is one smoothed-aggregation AMG hierarchy of the
**symmetrized elastic tangent** ``½(K_e + K_eᵀ)`` (the response to a zero increment from
the initial state), built once per run and reused by every iteration of every load step.
:class:`ForcingTerm` chooses the Krylov tolerance of each iteration (Eisenstat & Walker
1996, "Choosing the forcing terms in an inexact Newton method", SIAM J. Sci. Comput. 17,
choice 2 with its safeguard).
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import ConvergenceError
from .linear import LinearSolveInfo, SolverSetup, solve_linear

__all__ = ["FORCING", "ForcingTerm", "KrylovDirection"]

log = logging.getLogger(__name__)

#: the forcing terms of Newton's linear solves (``forcing=`` of ``solve_nonlinear``)
FORCING = ("fixed", "eisenstat-walker")

#: below this shift factor (``τ`` of pseudo-transient continuation) the shifted operator
#: ``K_T + Λ/τ`` is dominated by its diagonal blocks and block Jacobi preconditions it
#: (eigenvalues of ``Λ⁻¹(K + Λ/τ)`` in ``[1/τ, 4/1.1 + 1/τ]`` for the Gershgorin ``Λ``);
#: above it the elastic AMG hierarchy does
_JACOBI_BELOW = 10.0


class ForcingTerm:
    """Krylov tolerance ``η_k`` of inexact Newton: fixed, or Eisenstat-Walker.

    Eisenstat & Walker (1996), choice 2: ``η_k = γ (‖r_k‖ / ‖r_{k-1}‖)^α`` with
    ``γ = 0.9``, ``α = 2``, safeguarded by ``γ η_{k-1}^α`` when that exceeds 0.1, capped at
    ``eta_max`` and never below the tolerance that already meets Newton's own target
    (``½ rtol · scale / ‖r_k‖``: no over-solving), except where ``‖r_k‖² <= rtol``
    (relative): quadratic convergence ends there, and the solve is taken to that
    tolerance so that the iteration is the last (at 10⁵ particles an elastic step took
    two iterations without this, the first one's linear residual above ``rtol``).

    Parameters
    ----------
    kind : {'fixed', 'eisenstat-walker'}
        The rule.
    fixed : float
        The tolerance of ``'fixed'`` (and the floor of both).
    eta0, eta_max : float
        The first and the largest Eisenstat-Walker tolerance.  Defaults by measurement
        (25 x 25 crystal-plasticity polycrystal, 8 shear steps): Eisenstat & Walker's
        ``η_max = 0.9`` class of values (0.5, first 0.1) doubled the Newton iterations and
        cut plastic increments back six times (inexact directions miss the active-set
        kinks); ``1e-3`` / ``1e-2`` keep the iterations of the exact solve with 2.8x fewer
        GMRES iterations.

    Examples
    --------
    >>> f = ForcingTerm("eisenstat-walker")
    >>> f.eta(1.0, 1e-8)                 # first iteration: eta0
    0.001
    >>> round(f.eta(0.1, 1e-8), 6)       # residual reduced tenfold: 0.9 * 0.1**2
    0.009
    >>> round(f.eta(0.09, 1e-8), 6)      # a poor reduction: capped at eta_max
    0.01
    >>> ForcingTerm("fixed", fixed=1e-10).eta(1.0, 1e-8)
    1e-10
    """

    def __init__(
        self, kind: str, *, fixed: float = 1e-10, eta0: float = 1e-3, eta_max: float = 1e-2
    ) -> None:
        self.kind = kind
        self.fixed = float(fixed)
        self.eta0, self.eta_max = float(eta0), float(eta_max)
        self.gamma, self.alpha = 0.9, 2.0
        self._prev_norm: float | None = None
        self._prev_eta: float | None = None

    def reset(self) -> None:
        """Forget the previous iteration (a new (sub)step)."""
        self._prev_norm = self._prev_eta = None

    def eta(self, norm: float, target: float) -> float:
        """Return the relative tolerance of this iteration's linear solve.

        Parameters
        ----------
        norm : float
            ``‖r_k‖`` (any consistent scale, e.g. relative to the force scale).
        target : float
            Newton's target in the same scale (``rtol`` when ``norm`` is relative).

        Returns
        -------
        float
            The Krylov tolerance ``‖K du − r‖ <= η ‖r‖``.
        """
        if self.kind == "fixed":
            return self.fixed
        if self._prev_norm is None or self._prev_eta is None or self._prev_norm <= 0.0:
            eta = self.eta0
        else:
            eta = self.gamma * (norm / self._prev_norm) ** self.alpha
            safe = self.gamma * self._prev_eta**self.alpha
            if safe > 0.1:
                eta = max(eta, safe)
            eta = min(eta, self.eta_max)
        if norm > 0.0:
            enough = 0.5 * target / norm  # meets the iteration's own target
            if norm * norm <= target:
                # quadratic convergence would end below the target now: solve the last
                # iteration that far, not a second one for the linear residual's sake
                eta = min(eta, enough)
            else:
                eta = max(eta, enough)  # no over-solving
        eta = min(max(eta, self.fixed), self.eta_max)
        self._prev_norm, self._prev_eta = norm, eta
        return eta


class KrylovDirection:
    """GMRES for Newton systems, preconditioned by AMG of the symmetrized elastic tangent.

    The hierarchy is built on the first solve (from ``system.respond`` at zero
    displacement and ``state0``, eliminated like every Newton system, symmetrized) and
    reused by every later solve of the run: tangents change, the preconditioner does not.
    Shifted systems ``A + diag(s)`` with a large shift (pseudo-transient continuation at
    ``τ < 10``) are preconditioned by their own block Jacobi instead.

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system.
    state0 : dict of str to ndarray
        The state of the elastic tangent (the model's initial state).
    maxiter : int
        GMRES iterations per solve (restarted every 100).

    Attributes
    ----------
    solves, iterations : int
        Linear solves and GMRES iterations so far.
    setup_time, solve_time : float
        Wall seconds of the AMG set-up and of the solves.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> from pdlin.system import constrained_system
    >>> cloud = pdlin.grid((12, 12), spacing=1 / 12)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=3 / 12,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3)])
    >>> system = constrained_system(prob)
    >>> kd = KrylovDirection(system, system.initial_state())
    >>> u = np.zeros(system.ndof)
    >>> resp = system.respond(u, system.initial_state(), tangent=True)
    >>> A = system.eliminate_matrix(resp.tangent.tocsr())
    >>> b = np.ones(system.ndof); b[system.dofs] = 0.0
    >>> x, rel = kd.solve(A, b, 1e-8)
    >>> bool(rel <= 1e-7), kd.solves, kd.iterations > 0
    (True, 1, True)
    """

    def __init__(self, system: Any, state0: dict[str, np.ndarray], *, maxiter: int = 300) -> None:
        self.system = system
        self.state0 = state0
        self.maxiter = int(maxiter)
        self._setup: SolverSetup | None = None
        self._P: Any = None
        self.solves = 0
        self.iterations = 0
        self.setup_time = 0.0
        self.solve_time = 0.0

    def _preconditioner_matrix(self) -> Any:
        """Return the eliminated, symmetrized elastic tangent (built once)."""
        if self._P is None:
            t0 = time.perf_counter()
            sysm = self.system
            resp = sysm.respond(np.zeros(sysm.ndof), self.state0, tangent=True)
            K = sp.bsr_array(resp.tangent) if sp.issparse(resp.tangent) else resp.tangent
            Ke = sysm.eliminate_matrix(K)
            self._P = sp.csr_array(0.5 * (Ke + Ke.T))
            self.setup_time += time.perf_counter() - t0
        return self._P

    def _block_jacobi(self, A: Any) -> Any:
        """``v -> D⁻¹ v`` with ``D`` the dim x dim diagonal blocks of ``A``."""
        d = self.system.dim
        B = sp.bsr_array(sp.csr_array(A), blocksize=(d, d))
        n = A.shape[0] // d
        blocks = np.zeros((n, d, d))
        rows = np.repeat(np.arange(n), np.diff(B.indptr))
        diag = B.indices == rows
        blocks[rows[diag]] = B.data[diag]
        inv = np.linalg.inv(blocks)

        def apply(v: np.ndarray) -> np.ndarray:
            return np.einsum("nij,nj->ni", inv, v.reshape(n, d)).reshape(-1)

        return apply

    def solve(
        self, A: Any, b: np.ndarray, rtol: float, *, tau: float = math.inf
    ) -> tuple[Any, float]:
        """Solve ``A x = b`` to ``‖b − A x‖ <= rtol ‖b‖`` (GMRES, verified residual).

        Parameters
        ----------
        A : sparse array
            The eliminated Newton matrix (shifted by ``Λ/τ`` for continuation).
        b : (ndof,) ndarray
            The right-hand side (zero on prescribed DOFs).
        rtol : float
            Relative tolerance (the forcing term).
        tau : float
            The continuation's ``τ`` (inf: no shift), which selects the preconditioner.

        Returns
        -------
        x : (ndof,) ndarray
            The solution.
        rel : float
            Its true relative residual.

        Raises
        ------
        ConvergenceError
            GMRES reached neither ``rtol`` nor half of ``‖b‖`` in ``maxiter`` iterations.
        NonFiniteError
            A non-finite matrix or right-hand side.
        """
        t0 = time.perf_counter()
        sysm = self.system
        if tau < _JACOBI_BELOW:
            jac = self._block_jacobi(A)
            kw: dict[str, Any] = {"preconditioner_matrix": None, "setup": _FixedSetup(jac)}
        else:
            P = self._preconditioner_matrix()
            if self._setup is None:
                self._setup = SolverSetup()
            kw = {"preconditioner_matrix": P, "setup": self._setup}
        filled = kw["setup"].filled
        try:
            lin = solve_linear(
                A,
                b,
                "amg-gmres",
                rtol=rtol,
                maxiter=self.maxiter,
                near_null=sysm.near_null(),
                blocksize=sysm.dim,
                symmetric=False,
                **kw,
            )
            x, rel, its = lin.x, float(lin.relative_residual), int(lin.n_iter)
            if not filled and tau >= _JACOBI_BELOW:
                self.setup_time += float(lin.setup_time)
        except ConvergenceError as exc:
            part = exc.result
            if not isinstance(part, LinearSolveInfo) or not np.all(np.isfinite(part.x)):
                raise
            if part.relative_residual > 0.5:
                raise
            # inexact Newton: a partial Krylov solution that halves ‖r‖ is a descent
            # direction of the linear model; the line search / continuation judges it
            x, rel, its = part.x, float(part.relative_residual), int(part.n_iter)
        self.solves += 1
        self.iterations += its
        self.solve_time += time.perf_counter() - t0
        log.debug(
            "Krylov solve %d: %d GMRES iterations, relative residual %.2e (target %.1e, %s)",
            self.solves,
            its,
            rel,
            rtol,
            "block Jacobi" if tau < _JACOBI_BELOW else "elastic AMG",
        )
        return x, rel


class _FixedSetup(SolverSetup):
    """A filled :class:`SolverSetup` holding a ready preconditioner."""

    def __init__(self, M: Any) -> None:
        super().__init__(M=M, filled=True)
