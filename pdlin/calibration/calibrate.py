"""Calibration of anisotropic bond micromoduli (Prakash, anisotropic micromoduli).

The effective tensor of a bond family is linear in the micromoduli,
``C_PD = X c`` (the paper's Eqs. 29 and 32).  :func:`~pdlin.calibrate_micromoduli` finds
the minimum-norm nonnegative ``c`` whose tensor is closest to a target ``C`` in the
Frobenius norm of the full fourth-order tensor: the paper's two-step method (§3,
Eqs. 36-43) with its least squares weighted by the multiplicity of each Voigt entry
(derived: the printed unweighted Eq. 34 does not reproduce the paper's Table 1, the
weighted one does).  The 2D forms are pdlin's extension; the paper is 3D only.
"""

from __future__ import annotations

import itertools
import logging
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._repr import compact_repr
from .._validation import as_float_array
from ..errors import InputError, InputTypeError, ShapeError
from ..geometry.bonds import Bonds
from .lattices import Family

__all__ = [
    "CalibrationResult",
    "calibrate_micromoduli",
    "design_matrix",
    "max_lower_bound",
    "METHODS",
    "QP_SOLVERS",
]

log = logging.getLogger(__name__)

#: ``method`` values of :func:`pdlin.calibrate_micromoduli`.
METHODS = ("two-step", "robust", "min-norm")
#: ``qp_solver`` values of :func:`pdlin.calibrate_micromoduli` (clarabel and osqp fall
#: back on each other).
QP_SOLVERS = ("clarabel", "osqp", "cvxpy")
_WEIGHTINGS = ("frobenius", "voigt")
_PAIR_RULES = ("mean", "owner")
_BOUNDARY_RULES = ("calibrate", "interior-mean", "bulk")

# Voigt index -> tensor index pair (3D: the paper's Voigt map; 2D: 11, 22, 12)
_VOIGT = {3: ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)), 2: ((0, 0), (1, 1), (0, 1))}
_CAUCHY_DIM = {3: 15, 2: 5}


# ---------------------------------------------------------------------------
# Voigt helpers (small and private; pdlin.constitutive holds the public ones)
# ---------------------------------------------------------------------------
def _upper(nv: int) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.triu_indices(nv)
    return a, b


def _multiplicity(dim: int) -> np.ndarray:
    """Return the multiplicity of each upper-triangle Voigt entry in the full tensor."""
    from ..constitutive import frobenius_multiplicity

    return frobenius_multiplicity(dim).astype(float)


def _check_target(C: Any, dim: int, plane: str) -> np.ndarray:
    """Validate the target and return it as a (nv, nv) Voigt matrix for ``dim``.

    Shape, finiteness, symmetry and positive definiteness are checked by
    :func:`pdlin.constitutive.check_stiffness`.
    """
    from ..constitutive import check_stiffness, plane_strain, plane_stress, tensor_to_voigt

    arr = check_stiffness(C, "C")
    if arr.ndim == 4:
        arr = tensor_to_voigt(arr)
    arr = 0.5 * (arr + arr.T)
    d = 3 if arr.shape == (6, 6) else 2
    if d == dim:
        return arr
    if d == 3 and dim == 2:
        if plane not in ("stress", "strain"):
            raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
        return plane_stress(arr) if plane == "stress" else plane_strain(arr)
    raise ShapeError(
        f"C is a 2D stiffness {arr.shape} but the bond family is {dim}D; pass a (6, 6) target"
    )


def _voigt_vector(V: np.ndarray) -> np.ndarray:
    a, b = _upper(V.shape[0])
    return V[a, b]


def _voigt_matrix(v: np.ndarray, nv: int) -> np.ndarray:
    """Inverse of :func:`_voigt_vector` (works on trailing axis)."""
    a, b = _upper(nv)
    out = np.zeros(v.shape[:-1] + (nv, nv))
    out[..., a, b] = v
    out[..., b, a] = v
    return out


def _finite_scalar(value: Any, name: str) -> float:
    """``value`` as a finite real float, or InputError naming ``name``."""
    real = int | float | np.integer | np.floating
    if isinstance(value, bool | np.bool_) or not isinstance(value, real):
        raise InputError(f"{name} must be a finite real number, got {value!r}")
    v = float(value)
    if not np.isfinite(v):
        raise InputError(f"{name} must be finite, got {value!r}")
    return v


# ---------------------------------------------------------------------------
# design matrix
# ---------------------------------------------------------------------------
def design_matrix(
    xi: Any, omega: Any, volume: Any, thickness: float = 1.0, *, weighting: str = "frobenius"
) -> np.ndarray:
    """Return the design matrix ``X`` with ``C_PD = X c`` over upper-triangle Voigt entries.

    ``X[(a, b), N] = ½ ω_N ζ_a ζ_b V_N t / |ξ_N|³`` (Prakash, anisotropic
    micromoduli, Eq. 32; in 2D the same sum over in-plane components times
    the thickness ``t``), rows ordered ``C11, C12, ..., C16, C22, ..., C66``
    (21 rows in 3D, 6 in 2D).  ``weighting='frobenius'`` multiplies row
    ``(a, b)`` by ``sqrt(m_ab)``, the multiplicity of that component in the
    full tensor, so the Euclidean norm of the rows is the Frobenius norm of
    the tensor (see :func:`pdlin.constitutive.frobenius_multiplicity`).

    Parameters
    ----------
    xi : (M, dim) array_like of float
        Bond vectors of one family, ``dim`` 2 or 3, all nonzero.
    omega : float or (M,) array_like of float
        Influence value of each bond.
    volume : float or (M,) array_like of float
        Neighbour volume of each bond (area in 2D).
    thickness : float
        Out-of-plane thickness (2D); use 1.0 in 3D.
    weighting : {'frobenius', 'voigt'}
        Row weighting by ``sqrt(m_ab)`` or none (the printed Eq. 34).

    Returns
    -------
    ndarray of float, shape (21, M) or (6, M)
        C-contiguous design matrix.

    Raises
    ------
    InputError
        If ``weighting`` is unknown or a bond vector is zero.
    ShapeError
        If ``xi`` is not of shape (M, 2) or (M, 3).

    Examples
    --------
    >>> import numpy as np
    >>> X = design_matrix([[1.0, 0.0, 0.0]], 1.0, 1.0, weighting="voigt")
    >>> X[:, 0].tolist()[:3]   # only C11 = ½ c for a unit bond along x
    [0.5, 0.0, 0.0]
    """
    if weighting not in _WEIGHTINGS:
        raise InputError(f"weighting must be one of {_WEIGHTINGS}, got {weighting!r}")
    x = as_float_array(xi, "xi")
    if x.ndim != 2 or x.shape[1] not in (2, 3):
        raise ShapeError(f"xi must have shape (M, dim) with dim 2 or 3, got {x.shape}")
    m = x.shape[0]
    om = np.broadcast_to(as_float_array(omega, "omega"), (m,))
    vol = np.broadcast_to(as_float_array(volume, "volume"), (m,))
    dim = x.shape[1]
    length = np.sqrt(np.einsum("ij,ij->i", x, x))
    if np.any(length <= 0):
        k = int(np.flatnonzero(length <= 0)[0])
        raise InputError(f"xi must hold non-zero bond vectors, got a zero vector at bond {k}")
    zeta = np.stack([x[:, i] * x[:, j] for i, j in _VOIGT[dim]], axis=1)
    w = 0.5 * om * vol * float(thickness) / length**3
    a, b = _upper(len(_VOIGT[dim]))
    X = (zeta[:, a] * zeta[:, b] * w[:, None]).T
    if weighting == "frobenius":
        X = X * np.sqrt(_multiplicity(dim))[:, None]
    return np.ascontiguousarray(X)


# ---------------------------------------------------------------------------
# result
# ---------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Outcome of :func:`~pdlin.calibrate_micromoduli`.

    For a single family the arrays refer to its bonds; for a
    :class:`pdlin.Bonds` of a cloud ``micromoduli`` has one value per
    directed bond and ``tensor`` / ``relative_error`` one entry per point.

    Attributes
    ----------
    micromoduli : (M,) or (nb,) ndarray
        Calibrated micromoduli (units of C divided by length**4 in 3D,
        length**3 per thickness in 2D).  NaN where no valid solution
        exists (status 'infeasible').
    tensor : (nv, nv) or (n, nv, nv) ndarray
        Achieved Voigt tensor ``X c`` (plain Voigt, no factor 2).
    target : (nv, nv) ndarray
        Voigt target actually fitted (after plane stress/strain reduction).
    relative_error : float or (n,) ndarray
        ``|C - C_PD|_F / |C|_F`` over the full tensor (the paper's relative
        error; with ``weighting='voigt'`` still the full-tensor Frobenius norm).
    status : str
        'step1' (minimum-norm least squares already >= lower bound), 'qp'
        (bound active, step 2), 'nnls-qp' (robust variant: NNLS start, then
        step 2), 'negative' (method 'min-norm' with entries below the
        bound), 'infeasible' (no c >= bound reaches the least-squares fit),
        'failed' (QP solver did not converge).  For a cloud: the worst
        status of its families.
    message : str
        Plain-words summary (rank deficiency, unreachable quartics,
        infeasibility, effect of the pair rule).
    path : tuple of str
        Steps taken, e.g. ``('min-norm', 'qp:clarabel', 'active-set')``.
    solver_status : str
        Status string of the QP solver ('' when no QP was needed).
    residual : float
        Weighted least-squares residual ``|bw - Xw c|``.
    kkt : dict
        ``equality`` (relative), ``bound`` (max bound violation),
        ``stationarity`` and ``dual`` (most negative bound multiplier) of
        the QP optimality conditions; zeros for step 1.
    rank : int
        Numerical rank of the weighted design matrix (max 15 in 3D, 5 in
        2D: the dimension of fully symmetric tensors).
    n_bonds, n_columns, n_directions : int
        Bonds, distinct columns after merging identical ones (``±ξ``), and
        distinct bond directions modulo sign.
    n_zero : int
        Micromoduli within ``zero_threshold`` of the lower bound.
    zero_threshold : float
        Absolute distance from the bound below which a micromodulus counts as zero.
    lower_bound : float
        The bound ``l`` of ``c >= l`` used.
    c_min, c_max, c_mean, c_norm : float
        Min, max, mean and Euclidean norm of ``micromoduli``.
    weighting, method : str
        The ``weighting`` and ``method`` arguments used.
    time : float
        Wall time in seconds.
    families : tuple of CalibrationResult
        Cloud input only: one result per distinct family.
    family_of_point : (n,) ndarray of int or None
        Cloud input only: index into ``families`` per point (-1 for points
        without bonds).
    pair_change : float
        Cloud input only: max over points of the relative change of the
        achieved tensor caused by the pair rule (0 for a single family).
    """

    micromoduli: np.ndarray
    tensor: np.ndarray
    target: np.ndarray
    relative_error: Any
    status: str
    message: str
    path: tuple[str, ...]
    solver_status: str
    residual: float
    kkt: dict[str, float]
    rank: int
    n_bonds: int
    n_columns: int
    n_directions: int
    n_zero: int
    zero_threshold: float
    lower_bound: float
    c_min: float
    c_max: float
    c_mean: float
    c_norm: float
    weighting: str
    method: str
    time: float
    families: tuple[CalibrationResult, ...] = ()
    family_of_point: np.ndarray | None = None
    pair_change: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        """Status, error, bonds and micromodulus range (no arrays)."""
        err = np.asarray(self.relative_error, dtype=float)
        return compact_repr(
            "CalibrationResult",
            {
                "status": self.status,
                "relative_error": float(np.nanmax(err)) if err.size else None,
                "rank": self.rank if np.ndim(self.rank) == 0 else None,
                "n_bonds": self.n_bonds,
                "c_min": self.c_min,
                "c_max": self.c_max,
                "n_zero": self.n_zero,
                "families": len(self.families) or None,
                "method": self.method,
            },
        )

    @property
    def feasible(self) -> bool:
        """True when every micromodulus is valid (no NaN) and >= the bound."""
        return self.status not in ("infeasible", "failed", "negative")

    def summary(self) -> str:
        """Return the key figures on one line (for logs and the CLI).

        Returns
        -------
        str
            Status and path, rank, bond count, largest relative error (in %),
            micromodulus range, mean and norm, and the count at the bound.
        """
        err = self.relative_error
        e = f"{100 * float(np.max(err)):.6g} %" if np.size(err) else "n/a"
        return (
            f"status {self.status} ({' -> '.join(self.path)}), rank {self.rank}, "
            f"{self.n_bonds} bonds, error {e}, c in [{self.c_min:.6g}, {self.c_max:.6g}], "
            f"mean {self.c_mean:.6g}, |c| {self.c_norm:.6g}, {self.n_zero} at the bound"
        )


# ---------------------------------------------------------------------------
# quartic forms (rank messages)
# ---------------------------------------------------------------------------
def _quartic_exponents(dim: int) -> list[tuple[int, ...]]:
    return sorted((e for e in itertools.product(range(5), repeat=dim) if sum(e) == 4), reverse=True)


def _format_poly(coef: np.ndarray, exps: list[tuple[int, ...]]) -> str:
    names = "xyz"
    terms = []
    for cf, e in zip(coef, exps, strict=True):
        if abs(cf) < 1e-9:
            continue
        mono = "*".join(names[k] + (f"^{p}" if p > 1 else "") for k, p in enumerate(e) if p > 0)
        mag = abs(cf)
        s = mono if abs(mag - 1) < 1e-9 else f"{mag:.4g}*{mono}"
        terms.append(("-" if cf < 0 else "+", s))
    if not terms:
        return "0"
    out = ("-" if terms[0][0] == "-" else "") + terms[0][1]
    for sgn, s in terms[1:]:
        out += f" {sgn} {s}"
    return out


def _unreachable_quartics(directions: np.ndarray, dim: int) -> list[str]:
    """Quartic forms vanishing on every bond direction (null space of the evaluation)."""
    exps = _quartic_exponents(dim)
    E = np.array(exps)
    A = np.prod(directions[:, None, :] ** E[None, :, :], axis=2)  # (K, n_mono)
    _, s, vt = np.linalg.svd(A, full_matrices=True)
    r = int(np.sum(s > 1e-10 * (s[0] if s.size else 1.0)))
    N = vt[r:]
    if N.shape[0] == 0:
        return []
    # reduced row echelon form for readable coefficients
    R = N.copy()
    row = 0
    for col in range(R.shape[1]):
        if row >= R.shape[0]:
            break
        piv = row + int(np.argmax(np.abs(R[row:, col])))
        if abs(R[piv, col]) < 1e-9:
            continue
        R[[row, piv]] = R[[piv, row]]
        R[row] /= R[row, col]
        for k in range(R.shape[0]):
            if k != row:
                R[k] -= R[k, col] * R[row]
        row += 1
    return [_format_poly(r_, exps) for r_ in R]


# ---------------------------------------------------------------------------
# QP (step 2)
# ---------------------------------------------------------------------------
@dataclass
class _QPOut:
    x: np.ndarray | None
    status: str
    solver: str


def _qp_clarabel(Q: np.ndarray, d: np.ndarray, lb: np.ndarray) -> _QPOut:
    import clarabel
    import scipy.sparse as sp

    n = Q.shape[1]
    r = Q.shape[0]
    P = sp.identity(n, format="csc")
    A = sp.vstack([sp.csc_matrix(Q), -sp.identity(n, format="csc")], format="csc")
    b = np.concatenate([d, -lb])
    cones = [clarabel.ZeroConeT(r), clarabel.NonnegativeConeT(n)]
    st = clarabel.DefaultSettings()
    st.verbose = False
    st.tol_gap_abs = 1e-12
    st.tol_gap_rel = 1e-12
    st.tol_feas = 1e-12
    st.tol_ktratio = 1e-10
    st.max_iter = 200
    sol = clarabel.DefaultSolver(P, np.zeros(n), A, b, cones, st).solve()
    status = str(sol.status)
    x = np.asarray(sol.x) if "Solved" in status else None
    return _QPOut(x, status, "clarabel")


def _qp_osqp(Q: np.ndarray, d: np.ndarray, lb: np.ndarray) -> _QPOut:
    import osqp
    import scipy.sparse as sp

    n = Q.shape[1]
    P = sp.identity(n, format="csc")
    A = sp.vstack([sp.csc_matrix(Q), sp.identity(n, format="csc")], format="csc")
    lo = np.concatenate([d, lb])
    hi = np.concatenate([d, np.full(n, np.inf)])
    s = osqp.OSQP()
    s.setup(
        P,
        np.zeros(n),
        A,
        lo,
        hi,
        eps_abs=1e-10,
        eps_rel=1e-10,
        polishing=True,
        max_iter=200000,
        verbose=False,
    )
    res = s.solve(raise_error=False)
    status = str(res.info.status)
    x = np.asarray(res.x) if status.startswith("solved") else None
    return _QPOut(x, status, "osqp")


def _qp_cvxpy(Q: np.ndarray, d: np.ndarray, lb: np.ndarray) -> _QPOut:
    import cvxpy as cp

    x = cp.Variable(Q.shape[1])
    prob = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(x)), [Q @ x == d, x >= lb])
    status = ""
    for solver, opts in (
        (cp.CLARABEL, {}),
        (cp.OSQP, {"eps_abs": 1e-10, "eps_rel": 1e-10, "max_iter": 200000, "polish": True}),
    ):
        try:
            prob.solve(solver=solver, **opts)
        except cp.error.SolverError as exc:  # pragma: no cover - solver specific
            status = f"{solver}: {exc}"
            continue
        status = f"{solver}:{prob.status}"
        if prob.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            return _QPOut(np.asarray(x.value), status, "cvxpy")
        if prob.status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
            return _QPOut(None, "infeasible: " + status, "cvxpy")
    return _QPOut(None, status, "cvxpy")


def _active_set_polish(
    x: np.ndarray, Q: np.ndarray, d: np.ndarray, lb: np.ndarray, tol: float
) -> tuple[np.ndarray, bool]:
    """Refine an approximate QP solution by the exact active-set KKT solve.

    ``min ½|x|² s.t. Q x = d, x >= lb``: with the active set ``A`` fixed,
    ``x_F`` is the minimum-norm solution of ``Q_F x_F = d - Q_A lb_A``.
    Accepted when primal feasible and the bound multipliers are >= 0.
    """
    scale = max(float(np.abs(x).max()), float(np.abs(lb).max()), 1e-300)
    active = x <= lb + 1e-6 * scale
    for _ in range(20):
        free = ~active
        rhs = d - Q[:, active] @ lb[active]
        Qf = Q[:, free]
        # min-norm x_F lies in the row space of Q_F: x_F = Q_F^T lam with Q_F Q_F^T lam = rhs
        G = Qf @ Qf.T
        lam = np.linalg.lstsq(G, rhs, rcond=None)[0]
        xf = Qf.T @ lam
        xn = lb.copy()
        xn[free] = xf
        eq = float(np.linalg.norm(Q @ xn - d)) / max(float(np.linalg.norm(d)), 1e-300)
        mu = lb[active] - Q[:, active].T @ lam  # bound multipliers
        viol = xf < lb[free] - tol * scale
        neg = mu < -tol * scale
        if eq <= 1e-10 and not viol.any() and not neg.any():
            return xn, True
        if eq > 1e-10:
            return x, False
        fi = np.flatnonzero(free)
        ai = np.flatnonzero(active)
        active[fi[viol]] = True
        if neg.any():
            active[ai[np.argmin(mu)]] = False
    return x, False


# ---------------------------------------------------------------------------
# single family
# ---------------------------------------------------------------------------
def _merge_columns(Xw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distinct columns of ``Xw`` (identical ones, e.g. ``±ξ``), inverse map, counts."""
    scale = float(np.abs(Xw).max()) if Xw.size else 1.0
    key = np.round(Xw.T / max(scale, 1e-300) * 1e12).astype(np.int64)
    _, first, inv, counts = np.unique(
        key, axis=0, return_index=True, return_inverse=True, return_counts=True
    )
    return first, inv.ravel(), counts


def _directions_mod_sign(xi: np.ndarray, active: np.ndarray) -> np.ndarray:
    u = xi[active] / np.linalg.norm(xi[active], axis=1)[:, None]
    # canonical sign: first non-negligible component positive
    lead = np.argmax(np.abs(u) > 1e-12, axis=1)
    sgn = np.sign(u[np.arange(u.shape[0]), lead])
    u = u * sgn[:, None]
    _, idx = np.unique(np.round(u * 1e10).astype(np.int64), axis=0, return_index=True)
    return u[np.sort(idx)]


@dataclass(frozen=True)
class _ReducedSystem:
    """The weighted least-squares system of one family, merged and factorized.

    ``A t ≈ bw`` in the merged unknowns ``t = sqrt(k) c`` (``k`` identical
    columns merged into one); ``Vr`` holds the leading ``rank`` right
    singular vectors and ``t_ls`` the minimum-norm least-squares solution.
    """

    X: np.ndarray  # (nv(nv+1)/2, M) unweighted design matrix
    b: np.ndarray  # upper-triangle Voigt entries of the target
    m: np.ndarray  # Frobenius multiplicity of each entry
    Xw: np.ndarray  # weighted design matrix
    bw: np.ndarray  # weighted target
    first: np.ndarray  # first bond of each merged column
    inv: np.ndarray  # merged column of each bond
    sk: np.ndarray  # sqrt of each merged column's count
    A: np.ndarray  # merged, scaled design matrix (zero columns cleared)
    nonzero: np.ndarray  # merged columns that carry stiffness
    s: np.ndarray  # singular values of A
    Vr: np.ndarray  # (rank, n_columns) leading right singular vectors
    rank: int
    t_ls: np.ndarray  # minimum-norm least-squares t (0 on zero columns)


def _reduce_family(fam: Family, target: np.ndarray, weighting: str, rcond: float) -> _ReducedSystem:
    """Build, merge and factorize the weighted system of ``fam`` for ``target``."""
    m = _multiplicity(fam.dim)
    sqm = np.sqrt(m)
    X = design_matrix(fam.xi, fam.omega, fam.volume, fam.thickness, weighting="voigt")
    b = _voigt_vector(target)
    w = sqm if weighting == "frobenius" else np.ones_like(sqm)
    Xw = X * w[:, None]
    bw = b * w
    first, inv, counts = _merge_columns(Xw)
    sk = np.sqrt(counts.astype(float))
    A = Xw[:, first] * sk[None, :]  # reduced system in t = sqrt(k) c
    # zero columns (omega = 0) do not enter the fit: c = max(bound, 0) there
    nonzero = np.any(A != 0.0, axis=0)
    A = np.where(nonzero[None, :], A, 0.0)
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    smax = float(s[0]) if s.size else 0.0
    rank = int(np.sum(s > rcond * smax)) if smax > 0 else 0
    if rank == 0:
        raise InputError(
            "bonds must carry stiffness, got a family whose design matrix is zero (all omega == 0?)"
        )
    Ur, sr, Vr = U[:, :rank], s[:rank], Vt[:rank]
    t_ls = Vr.T @ ((Ur.T @ bw) / sr)
    t_ls[~nonzero] = 0.0
    return _ReducedSystem(X, b, m, Xw, bw, first, inv, sk, A, nonzero, s, Vr, rank, t_ls)


@dataclass
class _Step:
    """Outcome of the admissibility step (step 2) of one family."""

    t: np.ndarray
    status: str
    path: list[str]
    solver_status: str
    kkt: dict
    messages: list[str]


def _admissible_step(
    sys_: _ReducedSystem, *, method: str, lower_bound: float, qp_solver: str
) -> _Step:
    """Keep the least-squares solution or move it into ``t >= lower_bound * sqrt(k)``.

    'min-norm' only reports values below the bound (status 'negative');
    'two-step' and 'robust' (NNLS start) solve the QP that keeps the fitted
    tensor, statuses 'qp' / 'nnls-qp', or 'infeasible' / 'failed' with NaN.
    """
    A, bw, t_ls, sk = sys_.A, sys_.bw, sys_.t_ls, sys_.sk
    kkt = {"equality": 0.0, "bound": 0.0, "stationarity": 0.0, "dual": 0.0}
    step = _Step(t_ls, "step1", ["min-norm"], "", kkt, [])
    c_ls = (t_ls / sk)[sys_.inv]
    if not c_ls[sys_.nonzero[sys_.inv]].min() < lower_bound:
        return step
    if method == "min-norm":
        step.status = "negative"
        step.messages.append(
            f"minimum-norm least squares has {int(np.sum(c_ls < lower_bound))} micromoduli "
            f"below the bound {lower_bound:g} (min {c_ls.min():.6g}); use method='two-step' "
            "or 'robust' for admissible values"
        )
        return step
    lt = lower_bound * sk
    start = t_ls
    if method == "robust":
        from scipy.optimize import nnls

        tp, _ = nnls(A, bw - A @ lt, maxiter=50 * A.shape[1])
        start = lt + tp
        step.path.append("nnls")
    Q = sys_.Vr
    d = Q @ start
    scale = max(float(np.abs(start).max()), float(np.abs(lt).max()), 1e-300)
    out = _run_qp(Q, d / scale, lt / scale, qp_solver)
    step.path.append(f"qp:{out.solver}")
    step.solver_status = out.status
    if out.x is None:
        infeasible = "nfeasible" in out.status
        step.status = "infeasible" if infeasible else "failed"
        step.t = np.full_like(t_ls, np.nan)
        e_ls = float(np.linalg.norm(bw - A @ t_ls)) / float(np.linalg.norm(bw))
        if infeasible:
            step.messages.append(
                f"infeasible: no micromoduli >= {lower_bound:g} reproduce the "
                f"least-squares tensor (error {100 * e_ls:.6g} %); the cone "
                "{X c : c >= bound} misses it. method='robust' gives the nearest "
                "admissible fit (NNLS) instead"
            )
        else:
            step.messages.append(f"the QP solver failed ({out.status}); no solution returned")
        return step
    x, ok = _active_set_polish(out.x, Q, d / scale, lt / scale, 1e-9)
    if ok:
        step.path.append("active-set")
    step.status = "nnls-qp" if method == "robust" else "qp"
    step.t = np.maximum(x * scale, lt)
    step.kkt = _kkt(step.t, Q, d, lt, scale)
    return step


def _bond_micromoduli(sys_: _ReducedSystem, step: _Step, lower_bound: float) -> np.ndarray:
    """Expand the merged unknowns ``t`` of ``step`` to one micromodulus per bond."""
    c_red = step.t / sys_.sk
    if step.status in ("qp", "nnls-qp"):
        c_red = np.maximum(c_red, lower_bound)  # remove round-off below the bound
    c_red[~sys_.nonzero] = max(lower_bound, 0.0) if step.status != "negative" else 0.0
    return c_red[sys_.inv]


def _relative_frobenius(sys_: _ReducedSystem, c: np.ndarray) -> float:
    """``|C - X c|_F / |C|_F`` over the full tensor."""
    m, b = sys_.m, sys_.b
    return float(np.sqrt(np.sum(m * (b - sys_.X @ c) ** 2)) / np.sqrt(np.sum(m * b**2)))


def _summary_messages(
    sys_: _ReducedSystem,
    step: _Step,
    *,
    cauchy_dim: int,
    lower_bound: float,
    n_zero: int,
    weighting: str,
) -> list[str]:
    """Return the closing notes of a family: full rank first, then what step 1 or 2 did."""
    msgs = list(step.messages)
    rank, status = sys_.rank, step.status
    if rank == cauchy_dim:
        msgs.insert(0, f"rank {rank} (full)")
    if status == "step1":
        msgs.append(
            f"step 1: the minimum-norm least-squares micromoduli are all >= {lower_bound:g}"
        )
    elif status in ("qp", "nnls-qp"):
        msgs.append(
            f"step 2 (QP): {n_zero} micromoduli at the bound {lower_bound:g}, the fitted tensor "
            "kept"
        )
    if status in ("step1", "qp") and rank == cauchy_dim and weighting == "frobenius":
        msgs.append("the achieved tensor is the Cauchy projection of C")
    return msgs


def _solve_family(
    target: np.ndarray,
    fam: Family,
    *,
    weighting: str,
    lower_bound: float,
    method: str,
    qp_solver: str,
    rcond: float,
    zero_tol: float,
    raise_on_infeasible: bool,
) -> CalibrationResult:
    """Calibrate one family: least squares, then the admissibility step, then the report."""
    t0 = time.perf_counter()
    dim = fam.dim
    sys_ = _reduce_family(fam, target, weighting, rcond)
    cauchy_dim = _CAUCHY_DIM[dim]
    rank = sys_.rank
    dirs = _directions_mod_sign(fam.xi, np.abs(sys_.Xw).max(axis=0) > 0)
    step = _admissible_step(sys_, method=method, lower_bound=lower_bound, qp_solver=qp_solver)
    if rank < cauchy_dim:
        quart = _unreachable_quartics(dirs, dim)
        step.messages.insert(
            0,
            f"rank {rank} < {cauchy_dim}: the quartics {', '.join(quart)} vanish on all "
            f"{dirs.shape[0]} bond directions (modulo sign) of the family "
            f"({fam.description or f'{fam.n_bonds} bonds'}), so no micromoduli reach them",
        )
    c = _bond_micromoduli(sys_, step, lower_bound)
    if step.status in ("infeasible", "failed") and raise_on_infeasible:
        raise InputError("calibration " + step.status + ": " + "; ".join(step.messages))
    valid = np.all(np.isfinite(c))
    ach = sys_.X @ c if valid else np.full(sys_.b.shape, np.nan)
    residual = float(np.linalg.norm(sys_.bw - sys_.Xw @ c)) if valid else float("nan")
    e_full = _relative_frobenius(sys_, c) if valid else float("nan")
    if step.status == "nnls-qp" and valid:
        c_ls = (sys_.t_ls / sys_.sk)[sys_.inv]
        e_ls = _relative_frobenius(sys_, c_ls)
        if e_full > e_ls * (1 + 1e-8) + 1e-14:
            step.messages.append(
                f"the least-squares tensor is outside the cone of admissible micromoduli; "
                f"NNLS fit error {100 * e_full:.6g} % vs unconstrained {100 * e_ls:.6g} %"
            )
    zthr = zero_tol * (float(np.nanmax(np.abs(c))) if valid and c.size else 1.0)
    n_zero = int(np.sum(np.abs(c - lower_bound) <= zthr)) if valid else 0
    msgs = _summary_messages(
        sys_,
        step,
        cauchy_dim=cauchy_dim,
        lower_bound=lower_bound,
        n_zero=n_zero,
        weighting=weighting,
    )
    return CalibrationResult(
        micromoduli=c,
        tensor=_voigt_matrix(ach, len(_VOIGT[dim])),
        target=target,
        relative_error=e_full,
        status=step.status,
        message="; ".join(msgs),
        path=tuple(step.path),
        solver_status=step.solver_status,
        residual=residual,
        kkt=step.kkt,
        rank=rank,
        n_bonds=fam.n_bonds,
        n_columns=int(sys_.first.size),
        n_directions=int(dirs.shape[0]),
        n_zero=n_zero,
        zero_threshold=zthr,
        lower_bound=lower_bound,
        c_min=float(np.min(c)),
        c_max=float(np.max(c)),
        c_mean=float(np.mean(c)),
        c_norm=float(np.linalg.norm(c)),
        weighting=weighting,
        method=method,
        time=time.perf_counter() - t0,
        extra={"family": fam, "singular_values": sys_.s},
    )


def _kkt(t: np.ndarray, Q: np.ndarray, d: np.ndarray, lt: np.ndarray, scale: float) -> dict:
    eq = float(np.linalg.norm(Q @ t - d)) / max(float(np.linalg.norm(d)), 1e-300)
    bound = float(max(0.0, np.max(lt - t))) / scale
    free = t > lt + 1e-9 * scale
    lam = (
        np.linalg.lstsq(Q[:, free].T, t[free], rcond=None)[0]
        if free.any()
        else np.zeros(Q.shape[0])
    )
    stat = float(np.linalg.norm(t[free] - Q[:, free].T @ lam)) / max(
        float(np.linalg.norm(t)), 1e-300
    )
    mu = t[~free] - Q[:, ~free].T @ lam
    dual = float(min(0.0, mu.min())) / scale if mu.size else 0.0
    return {"equality": eq, "bound": bound, "stationarity": stat, "dual": dual}


def _run_qp(Q: np.ndarray, d: np.ndarray, lb: np.ndarray, qp_solver: str) -> _QPOut:
    """Solve ``min ½|x|² s.t. Q x = d, x >= lb`` with the chosen backend (and fallback)."""
    order = {"clarabel": ("clarabel", "osqp"), "osqp": ("osqp", "clarabel"), "cvxpy": ("cvxpy",)}
    runners = {"clarabel": _qp_clarabel, "osqp": _qp_osqp, "cvxpy": _qp_cvxpy}
    out = _QPOut(None, "", qp_solver)
    statuses = []
    for name in order[qp_solver]:
        out = runners[name](Q, d, lb)
        statuses.append(f"{name}: {out.status}")
        if out.x is not None or "nfeasible" in out.status:
            break
    return _QPOut(out.x, "; ".join(statuses), out.solver)


# ---------------------------------------------------------------------------
# public entry point
# ---------------------------------------------------------------------------
def calibrate_micromoduli(
    C: Any,
    bonds: Bonds | Family | Any,
    *,
    omega: Any = 1.0,
    volume: Any = 1.0,
    thickness: float = 1.0,
    weighting: str = "frobenius",
    lower_bound: float = 0.0,
    method: str = "two-step",
    plane: str = "stress",
    qp_solver: str = "clarabel",
    pair_rule: str = "mean",
    boundary: str = "calibrate",
    raise_on_infeasible: bool = False,
    rcond: float = 1e-12,
    zero_tol: float = 1e-9,
) -> CalibrationResult:
    """Calibrate bond micromoduli so a bond family reproduces a stiffness tensor.

    The two-step method of Prakash, anisotropic micromoduli (§3, Eqs. 36-43),
    in the Frobenius norm: among all minimizers of the misfit
    ``|C - X c|_F`` (full fourth-order tensor) the one with minimum
    ``|c|_2`` subject to ``c >= lower_bound``.  When the target's Cauchy
    projection (total symmetrization) is reachable, the achieved tensor is
    exactly that projection.

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like
        Target stiffness: plain Voigt (no factor 2 on shear entries, as
        in the paper) or the full tensor.  Must be symmetric, finite and positive
        definite.  A 3D target for a 2D family is reduced by ``plane``.
    bonds : Bonds, Family or (M, dim) array_like
        * :class:`pdlin.Bonds` of a whole cloud: every distinct family is
          calibrated once (interior families of a lattice are identical up
          to translation; truncated boundary families are calibrated on
          their own), values are scattered to every point with that family
          and then made symmetric over bond pairs by ``pair_rule``.
        * :class:`~pdlin.calibration.Family` (e.g. from
          :func:`~pdlin.calibration.lattice_family`): one family.
        * bond vectors ``xi`` of one family, with ``omega``, ``volume``.
    omega, volume : float or (M,) array_like
        Influence values and neighbour volumes when ``bonds`` is an array.
    thickness : float
        Out-of-plane thickness of 2D bodies (must match
        ``PointCloud.thickness`` for a cloud); ignored for a Family (it
        carries its own).
    weighting : {'frobenius', 'voigt'}
        'frobenius' (default) weights the 21 (2D: 6) Voigt rows by the
        square root of their multiplicity: the least squares is then in the
        Frobenius norm of the full tensor, which reproduces the paper.
        'voigt' is the printed unweighted system (Eq. 34); it does **not**
        reproduce the paper's numbers.
    lower_bound : float
        Bound ``l`` with ``c >= l`` (default 0: energy positivity).
    method : {'two-step', 'robust', 'min-norm'}
        'two-step': minimum-norm least squares (pseudo-inverse); if any
        value is below the bound, a QP keeps the fitted tensor and finds
        the minimum-norm admissible ``c``; reports 'infeasible' when none
        exists.  'robust': NNLS start (always feasible for ``l = 0``, may
        fit worse than the unconstrained projection), then the same QP.
        'min-norm': step 1 only, may return values below the bound (status
        'negative').
    plane : {'stress', 'strain'}
        Reduction of a 3D target for a 2D family
        (:func:`pdlin.constitutive.plane_stress`, :func:`pdlin.constitutive.plane_strain`).
    qp_solver : {'clarabel', 'osqp', 'cvxpy'}
        Step-2 backend: Clarabel interior point (default; falls back to
        OSQP), OSQP (eps 1e-10, polishing; falls back to Clarabel), or
        cvxpy (Clarabel, then OSQP).  Every backend's output is refined by
        an exact active-set KKT solve when its active set is consistent.
    pair_rule : {'mean', 'owner'}
        Cloud input: bond ``i -> j`` gets the average of the values
        calibrated at ``i`` and at ``j`` ('mean', symmetric as
        :class:`pdlin.BondBased` requires), or the owner's value ('owner',
        in general not symmetric).  The effect on the achieved tensors is
        reported as ``pair_change``.
    boundary : {'calibrate', 'interior-mean', 'bulk'}
        Cloud input: 'calibrate' calibrates every distinct (also truncated)
        family; 'interior-mean' calibrates only the complete family (the
        largest one) and gives every bond touching a point with another
        family the mean complete-family value (pdlin's reading of the
        "average" the paper's §4.4 example gives to boundary bonds); 'bulk'
        calibrates only the complete family and gives every bond the value
        of its bond vector there (a homogeneous material, ``c = c(ξ)``;
        interior points reproduce the target exactly, truncated families
        show the usual PD surface effect).
    raise_on_infeasible : bool
        Raise :class:`~pdlin.errors.InputError` instead of returning status
        'infeasible' (with NaN micromoduli).
    rcond : float
        Relative singular-value cutoff of the pseudo-inverse and the rank.
    zero_tol : float
        Values within ``zero_tol * max|c|`` of the bound count as zero.

    Returns
    -------
    CalibrationResult
        Micromoduli, achieved tensor(s), error, status and diagnostics.

    Raises
    ------
    InputError
        If an option is unknown or out of range, the target is not symmetric
        positive definite, the family carries no stiffness, or (with
        ``raise_on_infeasible``) no admissible solution exists.
    ShapeError
        If ``C`` or the bond vectors have the wrong shape.
    InputTypeError
        If ``bonds`` is of an unsupported type.

    Examples
    --------
    Prakash, anisotropic micromoduli, §4.1.8: isotropic Pyroceram 9608 on the
    924-bond sphere (δ = 6); the range of ``c`` is this implementation's
    output (the paper shows it as a figure only):

    >>> import numpy as np
    >>> from pdlin.calibration import lattice_family, calibrate_micromoduli
    >>> C = np.zeros((6, 6))
    >>> C[:3, :3] = 34.4
    >>> C[[0, 1, 2], [0, 1, 2]] = 103.2
    >>> C[[3, 4, 5], [3, 4, 5]] = 34.4
    >>> fam = lattice_family(3, 6.0, influence="delta_over_r")
    >>> res = calibrate_micromoduli(C, fam)
    >>> res.status, res.rank, res.relative_error < 1e-12
    ('step1', 15, True)
    >>> round(res.c_min, 4), round(res.c_max, 4)
    (0.1726, 0.2076)

    A δ = 2 sphere has only 13 directions modulo sign:

    >>> res2 = calibrate_micromoduli(C, lattice_family(3, 2.0))
    >>> res2.rank
    12
    >>> print(res2.message.split(":")[0])
    rank 12 < 15
    """
    if weighting not in _WEIGHTINGS:
        raise InputError(f"weighting must be one of {_WEIGHTINGS}, got {weighting!r}")
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    if qp_solver not in QP_SOLVERS:
        raise InputError(f"qp_solver must be one of {QP_SOLVERS}, got {qp_solver!r}")
    if pair_rule not in _PAIR_RULES:
        raise InputError(f"pair_rule must be one of {_PAIR_RULES}, got {pair_rule!r}")
    if boundary not in _BOUNDARY_RULES:
        raise InputError(f"boundary must be one of {_BOUNDARY_RULES}, got {boundary!r}")
    if plane not in ("stress", "strain"):
        raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
    lb = _finite_scalar(lower_bound, "lower_bound")
    rc = _finite_scalar(rcond, "rcond")
    if not 0.0 <= rc < 1.0:
        raise InputError(f"rcond must be in [0, 1), got {rc!r}")
    zt = _finite_scalar(zero_tol, "zero_tol")
    if zt < 0.0:
        raise InputError(f"zero_tol must be >= 0, got {zt!r}")
    if lb < 0 and method != "min-norm":
        log.warning("lower_bound %g < 0 allows negative micromoduli (unstable bonds)", lb)
    opts: dict[str, Any] = dict(
        weighting=weighting,
        lower_bound=lb,
        method=method,
        qp_solver=qp_solver,
        rcond=rc,
        zero_tol=zt,
        raise_on_infeasible=raise_on_infeasible,
    )
    if isinstance(bonds, Bonds):
        from .cloud import calibrate_bonds

        if bonds.dim not in (2, 3):
            raise InputError(f"bonds must be 2D or 3D, got a {bonds.dim}D cloud")
        target = _check_target(C, bonds.dim, plane)
        return calibrate_bonds(
            target, bonds, thickness=thickness, pair_rule=pair_rule, boundary=boundary, **opts
        )
    if isinstance(bonds, Family):
        fam = bonds
    elif isinstance(bonds, np.ndarray | list | tuple):
        fam = Family(bonds, omega, volume, thickness, "")
    else:
        raise InputTypeError(
            "bonds must be a pdlin.Bonds, a calibration Family or an (M, dim) array of bond "
            f"vectors, got {type(bonds).__name__}"
        )
    target = _check_target(C, fam.dim, plane)
    return _solve_family(target, fam, **opts)


def max_lower_bound(
    C: Any, family: Family, *, weighting: str = "frobenius", plane: str = "stress"
) -> float:
    """Return the largest uniform bound ``l`` for which the two-step QP is feasible.

    Linear program: maximize ``l`` s.t. ``Xw x = Xw c0`` and ``x >= l``
    (``c0`` the minimum-norm least-squares solution).  Prakash, anisotropic
    micromoduli (§4.1.8) chose ``l = 0.23`` "after some numerical
    experimentation"; this gives the limit directly.

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like
        Target stiffness, as for :func:`~pdlin.calibrate_micromoduli`.
    family : Family
        One bond family.
    weighting : {'frobenius', 'voigt'}
        Row weighting of the least squares.
    plane : {'stress', 'strain'}
        Reduction of a 3D target for a 2D family.

    Returns
    -------
    float
        The largest ``l`` (units of the micromoduli) with an admissible solution.

    Raises
    ------
    InputTypeError
        If ``family`` is not a :class:`~pdlin.calibration.Family`.
    InputError
        If the target is invalid or the linear program does not solve.

    Examples
    --------
    >>> import numpy as np
    >>> from pdlin.calibration import lattice_family
    >>> C = np.zeros((6, 6)); C[:3, :3] = 34.4
    >>> C[[0, 1, 2], [0, 1, 2]] = 103.2; C[[3, 4, 5], [3, 4, 5]] = 34.4
    >>> round(max_lower_bound(C, lattice_family(3, 6.0)), 4)   # omega = 1: above the paper's 0.23
    0.2387
    """
    from scipy.optimize import linprog

    if not isinstance(family, Family):
        raise InputTypeError(f"family must be a calibration Family, got {type(family).__name__}")
    target = _check_target(C, family.dim, plane)
    X = design_matrix(family.xi, family.omega, family.volume, family.thickness, weighting=weighting)
    bw = _voigt_vector(target)
    if weighting == "frobenius":
        bw = bw * np.sqrt(_multiplicity(family.dim))
    U, s, Vt = np.linalg.svd(X, full_matrices=False)
    r = int(np.sum(s > 1e-12 * s[0]))
    c0 = Vt[:r].T @ ((U[:, :r].T @ bw) / s[:r])
    Q = Vt[:r]
    n = X.shape[1]
    scale = float(np.abs(c0).max())
    # variables (x, l): minimize -l; Q x = Q c0; l - x <= 0
    cost = np.zeros(n + 1)
    cost[-1] = -1.0
    A_eq = np.hstack([Q, np.zeros((r, 1))])
    A_ub = np.hstack([-np.eye(n), np.ones((n, 1))])
    res = linprog(
        cost,
        A_ub=A_ub,
        b_ub=np.zeros(n),
        A_eq=A_eq,
        b_eq=Q @ c0 / scale,
        bounds=[(None, None)] * (n + 1),
        method="highs",
    )
    if res.status != 0:
        raise InputError(f"the bound LP did not solve: {res.message}")
    return float(res.x[-1] * scale)
