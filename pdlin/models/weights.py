"""Higher-order influence weights for correspondence peridynamics (Javaheri et al., 2022).

Two different ways of choosing influence weights that make the nonlocal
deformation gradient ``F = (sum w V dy (x) xi) K^-1`` more accurate:

* **Lattice-exact symbolic path** (:func:`higher_order_weights`,
  :func:`weights_table`): one weight per shell of the uniform 1D line, 2D
  square or 3D cubic lattice, solved in exact rational arithmetic (sympy)
  by the procedure of Javaheri, Luo, Lakshmanan & Sundararaghavan (2022),
  Sec. II.C (moment equations of increasing order, Eqs. 19-26; augmentation
  with the next-order mixed-monomial equations; pdlin's rejection rules).
  The paper gives the procedure in words; pdlin's reading of it, listed in
  :func:`higher_order_weights`, reproduces its Tables 1-3 exactly.
* **Numeric path for irregular families** (:func:`~pdlin.models.moment_weights`): the
  minimum-norm (volume-weighted) correction of base weights that makes the
  discrete moments of one family vanish, in floating point and batched over
  families.  On lattice families it agrees with the symbolic path only where
  the symbolic set is unique without augmentation (1D, 2D δ = h and 2h): it
  is a *different choice*, not an approximation of the symbolic one.

The lattice Fourier symbol :func:`~pdlin.models.gradient_symbol` and
:func:`symbol_extremes` support zero-energy-mode analysis (the paper's Sec. II.B,
Eq. 11, in Fourier form), and
:func:`gradient_exactness_order` checks polynomial exactness exactly.

Exact weights are :class:`sympy.Rational`; every result also offers float
access (:attr:`HigherOrderWeights.float_weights`, :meth:`HigherOrderWeights.offsets`).
"""

from __future__ import annotations

import enum
import itertools
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from functools import cache
from types import MappingProxyType
from typing import Any, Union

import numpy as np
import sympy
from sympy.polys.domains import QQ
from sympy.polys.matrices import DomainMatrix

from .._validation import as_float_array
from ..errors import InputError, InputTypeError, ModelError, NoNeighborsError, ShapeError

__all__ = [
    "WeightStatus",
    "HigherOrderWeights",
    "LatticeInfluence",
    "MomentWeights",
    "higher_order_weights",
    "weights_table",
    "lattice_shells",
    "nocontrol_weights",
    "as_influence",
    "lattice_moment",
    "gradient_exactness_order",
    "gradient_symbol",
    "symbol_extremes",
    "moment_weights",
]

log = logging.getLogger(__name__)

#: relative tolerance of the horizon membership test |p|^2 <= (delta/h)^2 (1 + tol)
_MEMBERSHIP_RTOL = 1e-12
#: default largest tabulated horizon ratio per dimension (the paper's Tables 1-3)
_TABLE_MAX_RATIO = {1: 4.0, 2: 3.0, 3: 3.0}
#: safety cap of the order loop (it always stops: see _solve_shells)
_MAX_HALF_ORDER = 64


class WeightStatus(str, enum.Enum):
    """Outcome of the weight generator (steps 3-4 of :func:`higher_order_weights`).

    Members compare equal to their string values
    (``WeightStatus.VALID == "valid"``).
    """

    #: a unique set with a nonzero farthest weight and an invertible shape tensor
    VALID = "valid"
    #: the farthest shell has weight 0: the set equals that of a smaller horizon
    FARTHEST_WEIGHT_ZERO = "farthest weight zero"
    #: Omega = 0, so the intact shape tensor K = Omega h^2 dV I is singular
    SINGULAR_SHAPE_TENSOR = "singular shape tensor"
    #: the augmented system is inconsistent or still underdetermined
    NO_UNIQUE_SET = "no unique set"

    def __str__(self) -> str:
        """Return the plain string value."""
        return self.value


Rational = sympy.Rational
WeightsLike = Union["HigherOrderWeights", Mapping[int, Any]]


# --------------------------------------------------------------------------- lattice geometry


def _check_dim(dim: Any) -> int:
    if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)):
        raise InputTypeError(f"dim must be an int (1, 2 or 3), got {type(dim).__name__}")
    if int(dim) not in (1, 2, 3):
        raise InputError(f"dim must be 1, 2 or 3, got {dim}")
    return int(dim)


def _max_shell(horizon_ratio: Any, name: str = "horizon_ratio") -> tuple[float, int]:
    """``(ratio, s_max)``: the largest integer ``s`` with ``s <= ratio^2 (1 + 1e-12)``."""
    if isinstance(horizon_ratio, bool):
        raise InputTypeError(f"{name} must be a real number, got bool")
    try:
        r = float(horizon_ratio)
    except (TypeError, ValueError) as exc:
        raise InputTypeError(
            f"{name} must be a real number, got {type(horizon_ratio).__name__}"
        ) from exc
    if not math.isfinite(r) or r <= 0.0:
        raise InputError(f"{name} must be a finite number > 0, got {horizon_ratio!r}")
    s_max = math.floor(r * r * (1.0 + _MEMBERSHIP_RTOL))
    if s_max < 1:
        raise NoNeighborsError(
            f"{name} must be >= 1 (delta >= h) so that the lattice horizon holds a neighbour, "
            f"got {r}"
        )
    return r, s_max


@cache
def _lattice_points(dim: int, s_max: int) -> tuple[tuple[int, ...], tuple[np.ndarray, ...]]:
    """Shells ``s`` (ascending) and the integer offsets of each shell (object int arrays)."""
    m = math.isqrt(s_max)
    rng = np.arange(-m, m + 1, dtype=np.int64)
    grid = np.stack(np.meshgrid(*([rng] * dim), indexing="ij"), axis=-1).reshape(-1, dim)
    s = np.sum(grid * grid, axis=1)
    keep = (s >= 1) & (s <= s_max)
    grid, s = grid[keep], s[keep]
    shells = tuple(int(v) for v in np.unique(s))
    points = tuple(grid[s == v].astype(object) for v in shells)
    return shells, points


def lattice_shells(dim: int, horizon_ratio: float) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Return the shells of the horizon on the 1D line, 2D square or 3D cubic lattice.

    Parameters
    ----------
    dim : {1, 2, 3}
        1D line, 2D square or 3D cubic lattice.
    horizon_ratio : float
        delta / h (inclusive, relative tolerance 1e-12).

    Returns
    -------
    shells : tuple of int
        Distinct squared offset lengths ``s = |p|^2`` (units h^2), ascending.
    multiplicities : tuple of int
        Number of lattice points in each shell.

    Examples
    --------
    >>> lattice_shells(3, 3)      # s = 9 joins (2,2,1)- and (3,0,0)-type points
    ((1, 2, 3, 4, 5, 6, 8, 9), (6, 12, 8, 6, 24, 24, 12, 30))
    """
    d = _check_dim(dim)
    _, s_max = _max_shell(horizon_ratio)
    shells, points = _lattice_points(d, s_max)
    return shells, tuple(len(p) for p in points)


def _monomial_row(points: tuple[np.ndarray, ...], exponents: tuple[int, ...]) -> list[int]:
    """Per-shell sums of ``prod_i p_i^e_i`` (exact integers)."""
    row = []
    for pts in points:
        term = np.ones(len(pts), dtype=object)
        for i, e in enumerate(exponents):
            if e:
                term = term * pts[:, i] ** e
        row.append(int(np.sum(term)) if len(pts) else 0)
    return row


def _partitions(n: int, parts: int) -> list[tuple[int, ...]]:
    """Partitions of ``n`` into at most ``parts`` parts, descending, zero-padded."""
    out: list[tuple[int, ...]] = []

    def rec(rest: int, maxpart: int, acc: tuple[int, ...]) -> None:
        if rest == 0:
            out.append(acc + (0,) * (parts - len(acc)))
            return
        if len(acc) == parts:
            return
        for k in range(min(rest, maxpart), 0, -1):
            rec(rest - k, k, acc + (k,))

    rec(n, n, ())
    return out


def _symmetric_rows(dim: int, shells_pts: tuple[np.ndarray, ...], n: int) -> list[list[int]]:
    """Return the degree-2n rows of the cubic-symmetry-reduced moment equations (Eqs. 19-26)."""
    return [_monomial_row(shells_pts, tuple(2 * k for k in part)) for part in _partitions(n, dim)]


# --------------------------------------------------------------------------- exact linear algebra


def _rref(rows: list[list[Any]], rhs: list[Any]) -> tuple[bool, bool, list[Any] | None]:
    """Solve ``rows @ w = rhs`` exactly over QQ.

    Returns ``(consistent, unique, solution)``; ``solution`` is a list of
    sympy Rationals when the system is consistent and unique.
    """
    n = len(rows[0])
    aug = [
        [QQ(int(v)) if isinstance(v, int) else QQ(v) for v in r] + [QQ(b)]
        for r, b in zip(rows, rhs, strict=True)
    ]
    mat = DomainMatrix(aug, (len(aug), n + 1), QQ)
    red, pivots = mat.rref()
    if n in pivots:
        return False, False, None
    if len(pivots) < n:
        return True, False, None
    lst = red.to_list()
    sol: list[Any] = [None] * n
    for r, c in enumerate(pivots):
        sol[c] = sympy.Rational(QQ.to_sympy(lst[r][n]))
    return True, True, sol


@dataclass(frozen=True)
class _Solved:
    shells: tuple[int, ...]
    multiplicities: tuple[int, ...]
    weights: tuple[Any, ...] | None
    half_order: int
    omega_sum: Any
    status: WeightStatus
    augmented: bool


@cache
def _solve_shells(dim: int, s_max: int) -> _Solved:
    """Run the generator of :func:`higher_order_weights` on the shells ``s <= s_max`` (cached)."""
    shells, pts = _lattice_points(dim, s_max)
    n_unk = len(shells)
    rows: list[list[Any]] = [[1] + [0] * (n_unk - 1)]  # step 2: omega_1 = 1
    rhs: list[Any] = [1]
    n_star = 1
    n = 2
    while True:  # step 2: add the degree-2n rows while the system stays consistent
        new = _symmetric_rows(dim, pts, n)
        consistent, _, _ = _rref(rows + new, rhs + [0] * len(new))
        if not consistent:
            break
        rows, rhs, n_star = rows + new, rhs + [0] * len(new), n
        n += 1
        if n > _MAX_HALF_ORDER:  # pragma: no cover - impossible (finite support)
            raise RuntimeError(f"moment equations consistent up to order {2 * n}")
    _, unique, sol = _rref(rows, rhs)
    augmented = False
    if not unique:  # step 3: the next-order rows that do not contain omega_1
        aug = [r for r in _symmetric_rows(dim, pts, n_star + 1) if r[0] == 0]
        augmented = True
        consistent, unique, sol = _rref(rows + aug, rhs + [0] * len(aug))
    mult = tuple(len(p) for p in pts)
    if sol is None:
        return _Solved(shells, mult, None, n_star, None, WeightStatus.NO_UNIQUE_SET, augmented)
    x2 = _monomial_row(pts, (2,) + (0,) * (dim - 1))
    omega_sum = sympy.Rational(sum((w * c for w, c in zip(sol, x2, strict=True)), Rational(0)))
    if sol[-1] == 0:  # step 4
        status = WeightStatus.FARTHEST_WEIGHT_ZERO
    elif omega_sum == 0:
        status = WeightStatus.SINGULAR_SHAPE_TENSOR
    else:
        status = WeightStatus.VALID
    return _Solved(shells, mult, tuple(sol), n_star, omega_sum, status, augmented)


# --------------------------------------------------------------------------- result object


@dataclass(frozen=True, eq=False)
class HigherOrderWeights:
    """Exact higher-order influence weights of one lattice horizon (Javaheri et al., 2022).

    Attributes
    ----------
    dim : int
        1 (line), 2 (square) or 3 (cubic lattice).
    horizon_ratio : float
        delta / h as requested.
    shells : tuple of int
        Squared bond lengths ``s_k = |p|^2`` in units of h^2 inside the
        horizon, ascending (``s_1 = 1``).
    multiplicities : tuple of int
        Lattice points per shell.
    weights : mapping of int to sympy.Rational, or None
        Exact weight ``omega_k`` per shell, keyed by ``s_k`` (``omega_1 = 1``;
        zero weights are kept).  ``None`` when the status is
        ``'no unique set'``.
    order : int
        ``2 n*``: the leading error of F is O(h^order), all even moments of
        orders 4..order vanish, and F is exact for polynomial displacements
        of degree <= order.
    Omega : sympy.Rational or None
        ``Omega = sum_bonds omega (xi_1/h)^2``; the intact shape tensor is
        ``K = Omega h^2 dV I`` (the paper's Eqs. 17-18).  ``None`` without a
        unique set.
    status : WeightStatus
        'valid', 'farthest weight zero', 'singular shape tensor' or
        'no unique set'.
    augmented : bool
        Whether the next-order mixed-monomial equations (step 3) were used.
    """

    dim: int
    horizon_ratio: float
    shells: tuple[int, ...]
    multiplicities: tuple[int, ...]
    weights: Mapping[int, Any] | None
    order: int
    Omega: Any
    status: WeightStatus
    augmented: bool
    _solved: _Solved = field(repr=False)

    @property
    def is_valid(self) -> bool:
        """True when the status is :attr:`WeightStatus.VALID`."""
        return self.status is WeightStatus.VALID

    @property
    def float_weights(self) -> dict[int, float]:
        """Weights as floats keyed by ``s`` (:class:`~pdlin.errors.ModelError` without a set)."""
        return {s: float(w) for s, w in self._require_weights().items()}

    @property
    def Omega_float(self) -> float:  # noqa: N802 - the paper's symbol
        """``Omega`` as a float (raises :class:`~pdlin.errors.ModelError` without a set)."""
        self._require_weights()
        return float(self.Omega)

    def _require_weights(self) -> Mapping[int, Any]:
        if self.weights is None:
            raise ModelError(
                f"weights of the {self.dim}D lattice at delta/h = {self.horizon_ratio:g} are "
                f"not defined: status must be 'valid', got {self.status.value!r}"
            )
        return self.weights

    def offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the integer lattice offsets of the horizon and their float weights.

        Returns
        -------
        p : (n, dim) ndarray of int64
            Offsets ``p`` (bond ``xi = p h``), shell by shell.
        omega : (n,) ndarray of float64
            Weight of each offset.

        Examples
        --------
        >>> p, w = higher_order_weights(1, 2).offsets()
        >>> p.ravel().tolist(), w.tolist()
        ([-1, 1, -2, 2], [1.0, 1.0, -0.0625, -0.0625])
        """
        wts = self._require_weights()
        _, pts = _lattice_points(self.dim, self.shells[-1])
        p = np.concatenate([q.astype(np.int64) for q in pts], axis=0)
        w = np.concatenate(
            [np.full(len(q), float(wts[s])) for s, q in zip(self.shells, pts, strict=True)]
        )
        return p, w

    def describe(self) -> str:
        """Return a one-line summary, e.g. ``'2D delta/h=2: O(h^4), Omega=3/2, valid'``.

        Returns
        -------
        str
            Dimension, horizon ratio, order of the gradient error, ``Omega`` and status.
        """
        om = "-" if self.Omega is None else str(self.Omega)
        return (
            f"{self.dim}D delta/h={_format_ratio(self.shells[-1])}: O(h^{self.order}), "
            f"Omega={om}, {self.status.value}"
        )


def _format_ratio(s: int) -> str:
    r = math.isqrt(s)
    return str(r) if r * r == s else f"√{s}"


def higher_order_weights(dim: int, horizon_ratio: float) -> HigherOrderWeights:
    """Compute the exact higher-order influence weights of a lattice horizon.

    Javaheri, Luo, Lakshmanan & Sundararaghavan (2022), Sec. II.C, in
    pdlin's reading (the paper describes the steps in words).
    The unknowns are one weight per shell ``s_k = |p|^2 <= (delta/h)^2``.
    With ``omega_1 = 1``, the cubic-symmetry-reduced moment equations of
    degree 4, 6, ... (the paper's Eqs. 19-26) are added while the system
    stays consistent (order ``2 n*``).  If the weights are not unique, the degree-``2 n* + 2`` rows
    that do not contain ``omega_1`` (the mixed monomials) are added; if the
    result is inconsistent or underdetermined the status is
    ``'no unique set'``.  Sets with ``omega_S = 0`` or ``Omega = 0`` are
    flagged ``'farthest weight zero'`` / ``'singular shape tensor'``.
    Everything is exact rational arithmetic (sympy ``QQ``); results are
    cached per ``(dim, largest shell)``.

    Parameters
    ----------
    dim : {1, 2, 3}
        1D line, 2D square or 3D cubic lattice.
    horizon_ratio : float
        delta / h >= 1, e.g. ``2`` or ``math.sqrt(8)``.  Shells with
        ``s <= (delta/h)^2 (1 + 1e-12)`` are inside.

    Returns
    -------
    HigherOrderWeights
        Exact weights per shell, order, ``Omega`` and status.

    Raises
    ------
    InputError
        ``dim`` not in {1, 2, 3} or ``horizon_ratio`` not a finite number > 0.
    InputTypeError
        ``dim`` not an int or ``horizon_ratio`` not a real number.
    NoNeighborsError
        ``horizon_ratio < 1``: the horizon holds no lattice neighbour.

    Examples
    --------
    >>> r = higher_order_weights(3, 3)         # Table 3 of the paper, delta = 3h
    >>> [str(r.weights[s]) for s in r.shells]
    ['1', '-80/267', '16/89', '-25/178', '14/267', '-8/267', '-2/267', '1/267']
    >>> r.order, r.Omega, r.status.value
    (6, 60/89, 'valid')
    >>> higher_order_weights(2, 8 ** 0.5).status.value
    'singular shape tensor'
    """
    d = _check_dim(dim)
    ratio, s_max = _max_shell(horizon_ratio)
    sol = _solve_shells(d, s_max)
    weights = (
        None
        if sol.weights is None
        else MappingProxyType(dict(zip(sol.shells, sol.weights, strict=True)))
    )
    return HigherOrderWeights(
        dim=d,
        horizon_ratio=ratio,
        shells=sol.shells,
        multiplicities=sol.multiplicities,
        weights=weights,
        order=2 * sol.half_order,
        Omega=sol.omega_sum,
        status=sol.status,
        augmented=sol.augmented,
        _solved=sol,
    )


def weights_table(dim: int, max_ratio: float | None = None) -> list[HigherOrderWeights]:
    """Compute the weights of every distinct lattice horizon up to ``max_ratio``.

    One entry per shell radius ``delta/h = sqrt(s)``, ``1 <= s <= max_ratio^2``,
    whatever the status (filter with :attr:`HigherOrderWeights.is_valid`).
    The valid entries up to the default ratios are the paper's Tables 1-3.

    Parameters
    ----------
    dim : {1, 2, 3}
        1D line, 2D square or 3D cubic lattice.
    max_ratio : float, optional
        Largest delta / h; default 4 in 1D and 3 in 2D/3D (the paper's tables).

    Returns
    -------
    list of HigherOrderWeights
        One result per shell radius, ascending.

    Raises
    ------
    InputError
        If ``dim`` is not 1, 2 or 3 or ``max_ratio`` is not a finite number > 0.

    Examples
    --------
    >>> for r in weights_table(2):
    ...     print(r.describe())
    2D delta/h=1: O(h^2), Omega=2, valid
    2D delta/h=√2: O(h^2), Omega=2, farthest weight zero
    2D delta/h=2: O(h^4), Omega=3/2, valid
    2D delta/h=√5: O(h^4), Omega=3/2, farthest weight zero
    2D delta/h=√8: O(h^6), Omega=0, singular shape tensor
    2D delta/h=3: O(h^6), Omega=4/3, valid
    """
    d = _check_dim(dim)
    mr = _TABLE_MAX_RATIO[d] if max_ratio is None else max_ratio
    _, s_max = _max_shell(mr, "max_ratio")
    shells, _ = _lattice_points(d, s_max)
    return [higher_order_weights(d, math.sqrt(s)) for s in shells]


def nocontrol_weights(dim: int, horizon_ratio: float) -> dict[int, float]:
    """Return the 'no control' set ``omega = 1/|xi|`` (units h = 1) keyed by shell ``s``.

    The LAMMPS-PD default that Javaheri et al. (2022) compare against; use it
    with :func:`~pdlin.models.gradient_symbol`.

    Parameters
    ----------
    dim : {1, 2, 3}
        1D line, 2D square or 3D cubic lattice.
    horizon_ratio : float
        delta / h >= 1.

    Returns
    -------
    dict of int to float
        ``{s: 1/sqrt(s)}`` for every shell ``s = |p|^2`` inside the horizon.

    Examples
    --------
    >>> nocontrol_weights(1, 2)
    {1: 1.0, 4: 0.5}
    """
    shells, _ = lattice_shells(dim, horizon_ratio)
    return {s: 1.0 / math.sqrt(s) for s in shells}


# --------------------------------------------------------------------------- influence callable


@dataclass(frozen=True, eq=False)
class LatticeInfluence:
    """Influence function ``f(length, horizon)`` mapping ``|xi|`` to its shell weight.

    Made by :func:`as_influence`; usable as ``influence=`` of
    :func:`pdlin.find_bonds`.  ``length`` must be a lattice bond length
    ``sqrt(s) h`` of the weight set (relative tolerance ``rtol`` on ``s``);
    any other length raises :class:`InputError`.  ``horizon`` is ignored.
    """

    h: float
    shells: np.ndarray
    values: np.ndarray
    rtol: float
    label: str

    def __call__(self, length: Any, horizon: Any = None) -> np.ndarray:
        """Return the shell weight of each bond length.

        Parameters
        ----------
        length : array_like of float
            Bond lengths, each ``sqrt(s) h`` for a shell ``s`` of the set.
        horizon : array_like of float, optional
            Ignored (the signature of an influence function).

        Returns
        -------
        ndarray of float
            Weight per length, same shape as ``length``.

        Raises
        ------
        InputError
            If a length is not a lattice bond length of the set.
        """
        length = np.asarray(length, dtype=np.float64)
        s_est = (length / self.h) ** 2
        k = np.rint(s_est)
        idx = np.clip(np.searchsorted(self.shells, k), 0, self.shells.size - 1)
        bad = (self.shells[idx] != k) | (np.abs(s_est - k) > self.rtol * np.maximum(k, 1.0))
        if np.any(bad):
            first = float(length[bad].ravel()[0])
            raise InputError(
                f"length must be a lattice bond length sqrt(s)*h with h = {self.h:g} and s in "
                f"{self.shells.astype(int).tolist()} ({self.label}), got {first} "
                f"(= sqrt({first * first / (self.h * self.h):.12g}) h)"
            )
        return self.values[idx]

    def __repr__(self) -> str:
        """Return the label and spacing."""
        return f"LatticeInfluence({self.label}, h={self.h:g})"


def as_influence(
    result: HigherOrderWeights, h: float, *, rtol: float = 1e-9, require_valid: bool = True
) -> LatticeInfluence:
    """Return the influence function of a weight set for a lattice of spacing ``h``.

    Parameters
    ----------
    result : HigherOrderWeights
        The weight set.
    h : float
        Lattice spacing (> 0).
    rtol : float
        Relative tolerance on ``(|xi|/h)^2`` when matching a shell.
    require_valid : bool
        Refuse sets whose status is not 'valid' (default).  Sets with
        ``'no unique set'`` are always refused.

    Returns
    -------
    LatticeInfluence
        ``f(length, horizon) -> omega``, vectorized.

    Raises
    ------
    InputTypeError
        If ``result`` is not a :class:`HigherOrderWeights`.
    ModelError
        If the set is not 'valid' and ``require_valid`` is True (or has no unique set).
    InputError
        If ``h`` is not a finite number > 0.

    Notes
    -----
    Higher-order sets have negative weights (used unchanged in K, F and the
    force state, as in the paper).  :func:`pdlin.find_bonds` accepts them with
    ``allow_negative_influence=True``; bond-based models refuse such bonds.

    Examples
    --------
    >>> f = as_influence(higher_order_weights(1, 3), h=0.1)
    >>> f([0.1, 0.2, 0.3], 0.3)
    array([ 1.        , -0.1       ,  0.00740741])
    """
    if not isinstance(result, HigherOrderWeights):
        raise InputTypeError(f"result must be a HigherOrderWeights, got {type(result).__name__}")
    if require_valid and not result.is_valid:
        raise ModelError(
            f"result must have status 'valid' (or pass require_valid=False), got "
            f"{result.status.value!r} for {result.describe()}"
        )
    wts = result._require_weights()
    hh = float(h)
    if not math.isfinite(hh) or hh <= 0:
        raise InputError(f"h must be a finite number > 0, got {h!r}")
    return LatticeInfluence(
        h=hh,
        shells=np.array(result.shells, dtype=np.float64),
        values=np.array([float(wts[s]) for s in result.shells]),
        rtol=float(rtol),
        label=f"HO {result.dim}D delta/h={_format_ratio(result.shells[-1])}",
    )


# --------------------------------------------------------------------------- moments, exactness


def _weights_and_points(
    weights: WeightsLike, dim: int | None
) -> tuple[int, list[tuple[int, Any, np.ndarray]]]:
    """``(dim, [(s, omega_s, points_s), ...])`` from a result or a ``{s: omega}`` mapping."""
    if isinstance(weights, HigherOrderWeights):
        if dim is not None and int(dim) != weights.dim:
            raise InputError(f"dim must be {weights.dim} for this weight set, got {dim}")
        wts = weights._require_weights()
        d = weights.dim
    elif isinstance(weights, Mapping):
        if dim is None:
            raise InputError("dim must be given when weights is a mapping, got None")
        d = _check_dim(dim)
        wts = weights
        if not wts:
            raise InputError("weights must hold at least one shell, got an empty mapping")
    else:
        raise InputTypeError(
            f"weights must be a HigherOrderWeights or a mapping {{s: omega}}, got "
            f"{type(weights).__name__}"
        )
    keys = sorted(int(s) for s in wts)
    if keys[0] < 1:
        raise InputError(f"weights keys must be squared lengths s >= 1, got {keys[0]}")
    shells, pts = _lattice_points(d, keys[-1])
    by_s = dict(zip(shells, pts, strict=True))
    out = []
    for s in keys:
        if s not in by_s:
            raise InputError(
                f"weights keys must be squared lattice lengths of the {d}D lattice "
                f"(sums of {d} squares), got {s}"
            )
        out.append((s, wts[s], by_s[s]))
    return d, out


def lattice_moment(
    weights: WeightsLike, exponents: tuple[int, ...], *, dim: int | None = None
) -> Any:
    """Compute the exact moment ``sum_p omega(|p|) prod_i p_i^e_i`` in units of h^k.

    The moments ``M^(k)`` whose vanishing gives the higher-order conditions of
    Javaheri et al. (2022), Eqs. 19-26.

    Parameters
    ----------
    weights : HigherOrderWeights or mapping of int to number
        A weight set, or ``{s: omega}`` (then ``dim`` is required).
    exponents : tuple of int
        One exponent per axis, e.g. ``(6, 0)`` for the x^6 moment.

    Returns
    -------
    sympy.Rational or float
        The moment (a float when the weights are floats).

    Raises
    ------
    InputError
        If ``exponents`` are not ``dim`` integers >= 0.

    Examples
    --------
    >>> # the first nonzero moment of the Table 3 set (delta = 3h; derived, not in the paper)
    >>> lattice_moment(higher_order_weights(3, 3), (8, 0, 0))
    2160/89
    """
    d, shells = _weights_and_points(weights, dim)
    e = tuple(int(v) for v in exponents)
    if len(e) != d or min(e) < 0:
        raise InputError(f"exponents must be {d} integers >= 0, got {exponents!r}")
    total: Any = 0
    for _, w, pts in shells:
        total += w * _monomial_row((pts,), e)[0]
    return total


def gradient_exactness_order(
    weights: WeightsLike, *, dim: int | None = None, max_degree: int = 40
) -> int:
    """Return the largest degree for which the intact-lattice gradient is exact.

    The largest ``k`` such that the gradient is exact for all polynomial
    displacements of degree <= ``k``.  The nonlocal gradient
    ``F_pq = (h^2 Omega)^-1 sum omega dy_p dx_q`` (Javaheri et al., 2022,
    Eq. 18) is applied to every monomial ``x^alpha`` at the origin of the lattice
    (any point: translation keeps the degree) and compared with the exact
    gradient in rational arithmetic.  Monomials of degree >= 2 must give 0,
    i.e. ``sum omega p^alpha p_q = 0``; degree 1 must give the identity.

    Parameters
    ----------
    weights : HigherOrderWeights or mapping of int to number
        Exact values (int, Fraction, sympy Rational) are compared exactly;
        floats with a relative tolerance of 1e-12.
    dim : int, optional
        Required when ``weights`` is a mapping.
    max_degree : int
        Stop searching here (returns ``max_degree`` if every degree passes).

    Returns
    -------
    int
        The largest exact degree (at most ``max_degree``).

    Raises
    ------
    ModelError
        If ``Omega = 0`` (the intact shape tensor is singular).

    Examples
    --------
    >>> gradient_exactness_order(higher_order_weights(3, 3))   # exact up to degree 2 n* = 6
    6
    """
    d, shells = _weights_and_points(weights, dim)
    exact = all(
        isinstance(w, (int, np.integer, Fraction, sympy.Rational)) and not isinstance(w, bool)
        for _, w, _ in shells
    )
    omega = sum((w * _monomial_row((pts,), (2,) + (0,) * (d - 1))[0] for _, w, pts in shells), 0)
    if omega == 0:
        raise ModelError("Omega must be nonzero for the gradient to exist, got Omega = 0")

    def moment(alpha: tuple[int, ...]) -> Any:
        return sum((w * _monomial_row((pts,), alpha)[0] for _, w, pts in shells), 0)

    def close(a: Any, b: Any) -> bool:
        if exact:
            return bool(sympy.Rational(a) == sympy.Rational(b))
        return abs(float(a) - float(b)) <= 1e-12 * max(1.0, abs(float(omega)))

    for k in range(1, max_degree + 1):
        for alpha in itertools.product(range(k + 1), repeat=d):
            if sum(alpha) != k:
                continue
            for q in range(d):
                beta = tuple(a + (i == q) for i, a in enumerate(alpha))
                target = omega if k == 1 and alpha[q] == 1 else 0
                if not close(moment(beta), target):
                    return k - 1
    return max_degree


# --------------------------------------------------------------------------- Fourier symbol


def _offsets_float(
    weights: WeightsLike, dim: int | None
) -> tuple[int, np.ndarray, np.ndarray, float]:
    d, shells = _weights_and_points(weights, dim)
    p = np.concatenate([pts.astype(np.int64) for _, _, pts in shells], axis=0)
    w = np.concatenate([np.full(len(pts), float(om)) for _, om, pts in shells])
    terms = w * p[:, 0] ** 2
    omega = float(np.sum(terms))
    exact_zero = isinstance(weights, HigherOrderWeights) and weights.Omega == 0
    if exact_zero or abs(omega) <= 1e-14 * float(np.sum(np.abs(terms))):
        raise ModelError("Omega must be nonzero for the gradient symbol, got Omega = 0")
    return d, p.astype(np.float64), w, omega


def gradient_symbol(
    weights: WeightsLike, theta: Any, *, dim: int | None = None, chunk: int = 32768
) -> np.ndarray:
    """Evaluate the lattice Fourier symbol ``g(theta) = Omega^-1 sum_p omega(|p|) p sin(theta·p)``.

    For ``u_a = v exp(i theta . a)`` the intact-lattice gradient is
    ``i v (x) g(theta) / h`` (derived from the paper's Eq. 18); the zeros of
    ``g`` are the zero-energy modes of its Sec. II.B.

    Parameters
    ----------
    weights : HigherOrderWeights or mapping of int to number
        A weight set or ``{s: omega}`` (e.g. :func:`~pdlin.models.nocontrol_weights`).
    theta : (..., dim) array_like of float
        Wave vectors (radians per lattice step).  In 1D, ``theta`` may also be
        an array of scalars (any shape without a trailing axis of length 1,
        e.g. ``(n,)``); the result then has ``theta.shape + (1,)``.
    dim : int, optional
        Required when ``weights`` is a mapping and ``theta`` is ambiguous;
        defaults to ``theta.shape[-1]``.
    chunk : int
        Number of wave vectors evaluated at once (memory bound).

    Returns
    -------
    (..., dim) ndarray
        ``g h`` (dimensionless).

    Raises
    ------
    ShapeError
        If ``theta`` does not end in an axis of length ``dim``.
    ModelError
        If ``Omega = 0``.

    Examples
    --------
    >>> import numpy as np
    >>> # 1D delta = 2h: g = (4/3) sin(theta) - (1/6) sin(2 theta), the modified
    >>> # wavenumber of the 4th-order central difference
    >>> g = gradient_symbol(higher_order_weights(1, 2), [np.pi / 4])
    >>> round(float(g[0, 0]), 4)
    0.7761
    """
    th = as_float_array(theta, "theta")
    if dim is None and not isinstance(weights, HigherOrderWeights):
        dim = th.shape[-1] if th.ndim else 1
    d_expected = weights.dim if isinstance(weights, HigherOrderWeights) else int(dim)  # type: ignore[arg-type]
    if d_expected == 1 and not (th.ndim >= 2 and th.shape[-1] == 1):
        th = th[..., None]
    if th.shape[-1] != d_expected:
        raise ShapeError(f"theta must have shape (..., {d_expected}), got {th.shape}")
    d, p, w, omega = _offsets_float(weights, d_expected)
    flat = th.reshape(-1, d)
    out = np.empty_like(flat)
    for start in range(0, flat.shape[0], max(1, int(chunk))):
        sl = slice(start, start + max(1, int(chunk)))
        out[sl] = (np.sin(flat[sl] @ p.T) * w) @ p / omega
    return out.reshape(th.shape)


def symbol_extremes(
    weights: WeightsLike,
    *,
    dim: int | None = None,
    exclusion: float = math.pi / 4,
    n_grid: int | None = None,
) -> dict[str, Any]:
    """Find the extremes of ``|g(theta)| h`` over the Brillouin zone.

    ``min`` is taken over wave vectors at Euclidean distance >= ``exclusion``
    from every point of ``{0, pi}^dim`` (mod 2 pi): the checkerboard zeros
    shared by every centrally symmetric set are excluded.  ``max`` is the
    high-frequency gain.  A grid search over ``[0, pi]^dim`` (enough for
    cubic-symmetric sets) is refined with SLSQP.

    Parameters
    ----------
    weights : HigherOrderWeights or mapping of int to number
        A weight set or ``{s: omega}``.
    dim : int, optional
        Required when ``weights`` is a mapping.
    exclusion : float
        Excluded radius around ``{0, pi}^dim``.
    n_grid : int, optional
        Grid points per axis (default 4097 / 257 / 49 in 1D / 2D / 3D).

    Returns
    -------
    dict
        ``{'min': float, 'argmin': ndarray, 'max': float, 'argmax': ndarray}``.

    Raises
    ------
    InputError
        If ``weights`` is a mapping and ``dim`` is not given.
    ModelError
        If ``Omega = 0``.

    Examples
    --------
    >>> # 1D delta = 3h: min at theta = pi/4, max (the high-frequency gain) near theta = 0.6 pi
    >>> ext = symbol_extremes(higher_order_weights(1, 3))
    >>> round(ext["min"], 4), round(ext["max"], 3)
    (0.7842, 1.586)
    """
    from scipy.optimize import minimize

    if isinstance(weights, HigherOrderWeights):
        d = weights.dim
    else:
        if dim is None:
            raise InputError("dim must be given when weights is a mapping, got None")
        d = _check_dim(dim)
    _, p, w, omega = _offsets_float(weights, d)
    n = n_grid if n_grid is not None else {1: 4097, 2: 257, 3: 49}[d]
    axis = np.linspace(0.0, math.pi, int(n))
    grid = np.stack(np.meshgrid(*([axis] * d), indexing="ij"), axis=-1).reshape(-1, d)

    def norm(th: np.ndarray) -> np.ndarray:
        return np.linalg.norm((np.sin(th @ p.T) * w) @ p / omega, axis=-1)

    corners = np.array(list(itertools.product((0.0, math.pi), repeat=d)))

    def dist(th: np.ndarray) -> np.ndarray:
        return np.min(np.linalg.norm(th[..., None, :] - corners, axis=-1), axis=-1)

    vals = np.concatenate([norm(grid[i : i + 32768]) for i in range(0, len(grid), 32768)])
    # boundary samples of the excluded balls (the constrained minimum often lies there)
    k = 64 if d > 1 else 1
    if d == 1:
        dirs = np.array([[1.0]])
    else:
        rs = np.random.default_rng(0).normal(size=(k * 16, d))
        dirs = np.abs(rs) / np.linalg.norm(rs, axis=1, keepdims=True)
        dirs = np.vstack([np.eye(d), dirs])
    bnd = []
    for c in corners:
        sign = np.where(c > 0, -1.0, 1.0)
        bnd.append(c + exclusion * dirs * sign)
    bpts = np.clip(np.vstack(bnd), 0.0, math.pi)
    bpts = bpts[dist(bpts) >= exclusion * (1 - 1e-12)]
    allowed = dist(grid) >= exclusion
    cand_pts = np.vstack([grid[allowed], bpts])
    cand_vals = np.concatenate([vals[allowed], norm(bpts)])

    bounds = [(0.0, math.pi)] * d
    cons = [{"type": "ineq", "fun": lambda t: float(dist(np.asarray(t)) - exclusion)}]
    best_min = (float(np.min(cand_vals)), cand_pts[int(np.argmin(cand_vals))])
    for j in np.argsort(cand_vals)[:8]:
        res = minimize(
            lambda t: float(norm(np.asarray(t)[None])[0]),
            cand_pts[j],
            method="SLSQP",
            bounds=bounds,
            constraints=cons,
            options={"ftol": 1e-14, "maxiter": 200},
        )
        x = np.clip(res.x, 0.0, math.pi)
        if dist(x) >= exclusion * (1 - 1e-9):
            v = float(norm(x[None])[0])
            if v < best_min[0]:
                best_min = (v, x)
    best_max = (float(np.max(vals)), grid[int(np.argmax(vals))])
    for j in np.argsort(-vals)[:8]:
        res = minimize(
            lambda t: -(float(norm(np.asarray(t)[None])[0]) ** 2),
            grid[j],
            method="L-BFGS-B",
            bounds=bounds,
            options={"ftol": 1e-15, "gtol": 1e-12},
        )
        x = np.clip(res.x, 0.0, math.pi)
        v = float(norm(x[None])[0])
        if v > best_max[0]:
            best_max = (v, x)
    return {"min": best_min[0], "argmin": best_min[1], "max": best_max[0], "argmax": best_max[1]}


# --------------------------------------------------------------------------- numeric path


@dataclass(frozen=True, eq=False)
class MomentWeights:
    """Result of :func:`~pdlin.models.moment_weights` (numeric, per family).

    Attributes
    ----------
    omega : (n_bonds,) ndarray
        Corrected weights.
    residual : (n_families,) ndarray
        Relative moment residual ``|A omega| / (|A| |omega|)`` per family.
    rank : (n_families,) ndarray of int
        Numerical rank of the moment conditions of each family.
    n_conditions : int
        Number of moment conditions (multi-indices of degree 3..order+1).
    shape_tensor_ratio : (n_families,) ndarray
        ``lambda_min`` of the corrected ``K = sum omega V xi (x) xi`` divided by
        ``lambda_max`` of the base ``K`` (lengths scaled per family); <= 0 or
        tiny means the corrected family has no usable shape tensor (e.g. only
        ``omega = 0`` satisfies the conditions).
    """

    omega: np.ndarray
    residual: np.ndarray
    rank: np.ndarray
    n_conditions: int
    shape_tensor_ratio: np.ndarray


def _family_tensor(wv: np.ndarray, xs: np.ndarray, fam: np.ndarray, nf: int) -> np.ndarray:
    """``(nf, d, d)`` per-family sums of ``wv xi (x) xi``."""
    d = xs.shape[1]
    k = np.zeros((nf, d, d))
    for i in range(d):
        for j in range(d):
            k[:, i, j] = np.bincount(fam, weights=wv * xs[:, i] * xs[:, j], minlength=nf)
    return k


def _multi_indices(dim: int, degrees: range) -> list[tuple[int, ...]]:
    out: list[tuple[int, ...]] = []
    for k in degrees:
        out.extend(a for a in itertools.product(range(k + 1), repeat=dim) if sum(a) == k)
    return out


def moment_weights(
    xi: Any,
    volumes: Any,
    order: int,
    *,
    indptr: Any = None,
    base: Any = None,
    rcond: float = 1e-10,
    chunk: int = 2048,
) -> MomentWeights:
    """Compute minimum-norm moment-corrected weights for arbitrary (irregular) families.

    For each family, find the weights closest to ``base`` in the
    volume-weighted norm ``sum_b V_b (omega_b - base_b)^2`` such that every
    discrete moment ``sum_b omega_b V_b xi_b^alpha`` of degree
    ``3 <= |alpha| <= order + 1`` vanishes: the nonlocal gradient is then
    exact for polynomial displacements of degree <= ``order`` (odd degrees
    included, which lattices get for free).  Solved in floating point by a
    batched SVD of the padded family blocks (the minimum-norm solution of an
    underdetermined system; a least-squares projection when the conditions
    have full column rank, which may leave only ``omega = 0``: check
    ``shape_tensor_ratio``).

    This is a *different choice* from the lattice-exact symbolic path of
    :func:`higher_order_weights`: on lattice families the two agree (up to
    the normalization ``omega_1 = 1``) where the symbolic set is unique
    without augmentation (1D, 2D delta = h, 2h); they differ on the augmented
    sets (2D 3h, 3D 2h, 3D 3h), and per-bond weights need not
    be constant on a shell.

    Parameters
    ----------
    xi : (n_bonds, dim) array_like of float
        Bond vectors, grouped by family.
    volumes : (n_bonds,) array_like of float
        Neighbour volumes ``V_b`` (> 0).
    order : int
        Target polynomial-exactness degree (>= 1; 1 returns ``base``).
    indptr : (n_families + 1,) array_like of int, optional
        CSR pointer of the families (e.g. ``bonds.indptr``); default: one family.
    base : (n_bonds,) array_like of float, optional
        Base weights (e.g. ``bonds.omega``); default 1.
    rcond : float
        Singular values below ``rcond * s_max`` of a family's (length-scaled)
        condition matrix count as zero.
    chunk : int
        Families processed per batched SVD.

    Returns
    -------
    MomentWeights
        Corrected weights per bond, with per-family residual, rank and shape-tensor ratio.

    Raises
    ------
    ShapeError
        If ``xi``, ``volumes``, ``base`` or ``indptr`` has the wrong shape.
    InputError
        If a volume is not > 0 or ``order`` is not an integer >= 1.

    Examples
    --------
    >>> import numpy as np
    >>> xi = np.array([[-2.0], [-1.0], [1.0], [2.0]])
    >>> mw = moment_weights(xi, np.ones(4), order=4)
    >>> np.round(mw.omega / mw.omega[1], 12).tolist()    # Table 1, delta = 2h: 1, -1/16
    [-0.0625, 1.0, 1.0, -0.0625]
    """
    x = as_float_array(xi, "xi")
    if x.ndim != 2 or x.shape[1] not in (1, 2, 3):
        raise ShapeError(f"xi must have shape (n_bonds, dim) with dim 1..3, got {x.shape}")
    nb, d = x.shape
    vol = as_float_array(volumes, "volumes")
    if vol.shape != (nb,):
        raise ShapeError(f"volumes must have shape ({nb},), got {vol.shape}")
    if nb and vol.min() <= 0:
        raise InputError(f"volumes must be > 0, got min {vol.min()}")
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1:
        raise InputError(f"order must be an int >= 1, got {order!r}")
    om0 = np.ones(nb) if base is None else as_float_array(base, "base")
    if om0.shape != (nb,):
        raise ShapeError(f"base must have shape ({nb},), got {om0.shape}")
    ptr = (
        np.array([0, nb], dtype=np.int64) if indptr is None else np.asarray(indptr, dtype=np.int64)
    )
    if ptr.ndim != 1 or ptr.size < 1 or ptr[0] != 0 or ptr[-1] != nb or np.any(np.diff(ptr) < 0):
        raise ShapeError(
            f"indptr must be a nondecreasing (n_families + 1,) array from 0 to {nb}, "
            f"got {ptr[:5].tolist()}..."
        )
    alphas = _multi_indices(d, range(3, int(order) + 2))
    nf = ptr.size - 1
    sizes = np.diff(ptr)
    omega = om0.copy()
    residual = np.zeros(nf)
    rank = np.zeros(nf, dtype=np.int64)
    ratio = np.zeros(nf)
    fam = np.repeat(np.arange(nf), sizes)
    # per-family length scale keeps the monomials O(1)
    lscale = np.zeros(nf)
    if nb:
        np.maximum.at(lscale, fam, np.linalg.norm(x, axis=1))
    lscale[lscale == 0] = 1.0
    pos = np.arange(nb) - np.repeat(ptr[:-1], sizes)
    for f0 in range(0, nf, max(1, int(chunk))):
        f1 = min(nf, f0 + max(1, int(chunk)))
        b0, b1 = ptr[f0], ptr[f1]
        nmax = int(sizes[f0:f1].max()) if f1 > f0 else 0
        if nmax == 0:
            continue
        lf = fam[b0:b1] - f0
        xs = x[b0:b1] / lscale[fam[b0:b1], None]
        sq = np.sqrt(vol[b0:b1])
        # A[f, a, b] = sqrt(V_b) xi_b^alpha (eta_b = sqrt(V_b) (omega_b - base_b))
        a = np.zeros((f1 - f0, max(1, len(alphas)), nmax))
        for r, al in enumerate(alphas):
            a[lf, r, pos[b0:b1]] = sq * np.prod(xs ** np.array(al), axis=1)
        eta0 = np.zeros((f1 - f0, nmax))
        eta0[lf, pos[b0:b1]] = sq * om0[b0:b1]
        if alphas:
            _, s, vt = np.linalg.svd(a, full_matrices=False)
            keep = s > rcond * np.maximum(s[:, :1], np.finfo(float).tiny)
            rank[f0:f1] = keep.sum(axis=1)
            vk = vt * keep[:, :, None]
            eta = eta0 - np.einsum("fkb,fk->fb", vk, np.einsum("fkb,fb->fk", vk, eta0))
            res = np.linalg.norm(np.einsum("fab,fb->fa", a, eta), axis=1)
            scale = np.linalg.norm(a, axis=(1, 2)) * np.linalg.norm(eta, axis=1)
            residual[f0:f1] = np.where(scale > 0, res / np.where(scale > 0, scale, 1.0), 0.0)
        else:
            eta = eta0
        omega[b0:b1] = eta[lf, pos[b0:b1]] / sq
        # smallest eigenvalue of the corrected shape tensor relative to the base one
        ev, ev0 = (
            np.linalg.eigvalsh(_family_tensor(wt * vol[b0:b1], xs, lf, f1 - f0))
            for wt in (omega[b0:b1], om0[b0:b1])
        )
        top = np.max(np.abs(ev0), axis=1)
        ratio[f0:f1] = np.where(top > 0, ev[:, 0] / np.where(top > 0, top, 1.0), 0.0)
    return MomentWeights(omega, residual, rank, len(alphas), ratio)
