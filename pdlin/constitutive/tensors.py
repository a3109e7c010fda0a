"""Fourth-order elasticity tensors: Voigt/Mandel/full formats, rotations, norms, checks.

Conventions (Prakash, anisotropic micromoduli, §2 and Eq. 29; the 2D forms are pdlin's)
----------------------------------------------------------------------------------------
* **Voigt order** 3D: 1→11, 2→22, 3→33, 4→23, 5→31, 6→12; 2D: 1→11, 2→22, 3→12.
* **Plain Voigt** (stiffness convention): ``C̃_αβ`` *is* the tensor component, with no
  factor 2 or √2 on shear entries (``C̃44 = C2323``).
* **Mandel**: shear rows and columns multiplied by √2, so the 6×6 (3×3) Frobenius norm and
  the eigenvalues are those of the full tensor seen as a map on symmetric 2-tensors.
* Every function accepts a Voigt matrix ``(6, 6)``/``(3, 3)`` or a full tensor
  ``(3, 3, 3, 3)``/``(2, 2, 2, 2)`` and, when it returns a stiffness, returns the same format.

The Frobenius norm is always the norm of the full 81- (16-) component tensor.  On the
upper-triangle Voigt entries it is ``sqrt(Σ m_αβ C̃_αβ²)`` with the multiplicities of
:func:`frobenius_multiplicity` (the weighting that reproduces the calibration paper).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validation import check_finite
from ..errors import InputError, InputTypeError, NonFiniteError, ShapeError

__all__ = [
    "VOIGT_PAIRS_3D",
    "VOIGT_PAIRS_2D",
    "voigt_to_tensor",
    "tensor_to_voigt",
    "voigt_to_mandel",
    "mandel_to_voigt",
    "rotate",
    "reflection",
    "rotation_matrix",
    "frobenius_multiplicity",
    "voigt_upper",
    "frobenius_norm",
    "cauchy_projection",
    "cauchy_distance",
    "satisfies_cauchy",
    "universal_anisotropy_index",
    "check_stiffness",
    "plane_strain",
    "plane_stress",
    "isotropic_2d",
]

FloatArray = NDArray[np.float64]

#: Index pairs (i, j) of the 3D Voigt components 1..6 (zero-based).
VOIGT_PAIRS_3D: tuple[tuple[int, int], ...] = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
#: Index pairs (i, j) of the 2D Voigt components 1..3 (zero-based).
VOIGT_PAIRS_2D: tuple[tuple[int, int], ...] = ((0, 0), (1, 1), (0, 1))

_SHAPES = ((6, 6), (3, 3), (3, 3, 3, 3), (2, 2, 2, 2))
_SYM_RTOL = 1e-12


def _pairs(dim: int) -> tuple[tuple[int, int], ...]:
    return VOIGT_PAIRS_3D if dim == 3 else VOIGT_PAIRS_2D


def _voigt_index(dim: int) -> NDArray[np.intp]:
    """(dim, dim) array mapping a tensor index pair (i, j) to its Voigt index."""
    out = np.empty((dim, dim), dtype=np.intp)
    for a, (i, j) in enumerate(_pairs(dim)):
        out[i, j] = out[j, i] = a
    return out


def _mandel_weights(dim: int) -> FloatArray:
    n_normal = dim
    n_shear = 3 if dim == 3 else 1
    return np.concatenate([np.ones(n_normal), np.full(n_shear, np.sqrt(2.0))])


def _as_array(C: Any, name: str) -> FloatArray:
    """Float64 array of an allowed stiffness shape, finite (no symmetry check)."""
    try:
        is_complex = np.iscomplexobj(C)
    except (TypeError, ValueError):  # ragged input: reported by the conversion below
        is_complex = False
    if is_complex:
        raise InputTypeError(f"{name} must be real, got complex dtype {np.asarray(C).dtype}")
    try:
        arr = np.asarray(C, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a numeric array, got {type(C).__name__}: {exc}") from exc
    if arr.shape not in _SHAPES:
        raise ShapeError(
            f"{name} must have shape (6, 6) or (3, 3) (Voigt) or (3, 3, 3, 3) or (2, 2, 2, 2) "
            f"(full tensor), got {arr.shape}"
        )
    check_finite(arr, name)
    return arr


def _dim_of(arr: FloatArray) -> int:
    return {(6, 6): 3, (3, 3): 2, (3, 3, 3, 3): 3, (2, 2, 2, 2): 2}[arr.shape]


def _scale(arr: FloatArray) -> float:
    s = float(np.max(np.abs(arr))) if arr.size else 0.0
    return s if s > 0.0 else 1.0


def _check_major_voigt(arr: FloatArray, name: str, rtol: float) -> None:
    viol = float(np.max(np.abs(arr - arr.T)))
    if viol > rtol * _scale(arr):
        raise InputError(
            f"{name} must be symmetric (major symmetry C_ab = C_ba), got max |C - C.T| = "
            f"{viol:.3g} (relative {viol / _scale(arr):.3g} of max |C|, tolerance {rtol:g})"
        )


def _check_tensor_symmetries(arr: FloatArray, name: str, rtol: float) -> None:
    scale = _scale(arr)
    minor = max(
        float(np.max(np.abs(arr - arr.transpose(1, 0, 2, 3)))),
        float(np.max(np.abs(arr - arr.transpose(0, 1, 3, 2)))),
    )
    if minor > rtol * scale:
        raise InputError(
            f"{name} must have minor symmetry (T_ijkl = T_jikl = T_ijlk), got max violation "
            f"{minor:.3g} (relative {minor / scale:.3g} of max |T|, tolerance {rtol:g})"
        )
    major = float(np.max(np.abs(arr - arr.transpose(2, 3, 0, 1))))
    if major > rtol * scale:
        raise InputError(
            f"{name} must have major symmetry (T_ijkl = T_klij), got max violation "
            f"{major:.3g} (relative {major / scale:.3g} of max |T|, tolerance {rtol:g})"
        )


def _stiffness(C: Any, name: str, rtol: float = _SYM_RTOL) -> tuple[FloatArray, int, bool]:
    """Validate a symmetric stiffness in either format; return (array, dim, is_voigt)."""
    arr = _as_array(C, name)
    is_voigt = arr.ndim == 2
    if is_voigt:
        _check_major_voigt(arr, name, rtol)
    else:
        _check_tensor_symmetries(arr, name, rtol)
    return arr, _dim_of(arr), is_voigt


def _to_voigt(C: Any, name: str) -> tuple[FloatArray, int, bool]:
    arr, dim, is_voigt = _stiffness(C, name)
    return (arr if is_voigt else _tensor_to_voigt_unchecked(arr)), dim, is_voigt


def _to_tensor(C: Any, name: str) -> tuple[FloatArray, int, bool]:
    arr, dim, is_voigt = _stiffness(C, name)
    return (_voigt_to_tensor_unchecked(arr) if is_voigt else arr), dim, is_voigt


def _voigt_to_tensor_unchecked(C: FloatArray) -> FloatArray:
    dim = 3 if C.shape[0] == 6 else 2
    v = _voigt_index(dim)
    return np.ascontiguousarray(C[v[:, :, None, None], v[None, None, :, :]])


def _tensor_to_voigt_unchecked(T: FloatArray) -> FloatArray:
    dim = T.shape[0]
    ij = np.array(_pairs(dim))
    return np.ascontiguousarray(T[ij[:, 0, None], ij[:, 1, None], ij[None, :, 0], ij[None, :, 1]])


def _same_format(V: FloatArray, is_voigt: bool) -> FloatArray:
    return V if is_voigt else _voigt_to_tensor_unchecked(V)


# ---------------------------------------------------------------------------
# format conversions


def voigt_to_tensor(C: ArrayLike) -> FloatArray:
    """Return the full fourth-order tensor of a plain-Voigt stiffness matrix.

    Parameters
    ----------
    C : (6, 6) or (3, 3) array_like of float
        Symmetric Voigt matrix, 3D order (11, 22, 33, 23, 31, 12) or 2D order
        (11, 22, 12); entries are tensor components (no factor 2 on shear).

    Returns
    -------
    T : (3, 3, 3, 3) or (2, 2, 2, 2) ndarray
        ``T[i, j, k, l] = C[V(i, j), V(k, l)]``.

    Raises
    ------
    ShapeError, NonFiniteError, InputError
        Wrong shape, NaN/inf, or ``C`` not symmetric.

    Examples
    --------
    >>> import numpy as np
    >>> C = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    >>> T = voigt_to_tensor(C)
    >>> float(T[1, 2, 1, 2]), float(T[2, 1, 2, 1]), float(T[0, 1, 1, 0])
    (4.0, 4.0, 6.0)
    """
    arr, _, is_voigt = _stiffness(C, "C")
    if not is_voigt:
        raise ShapeError(f"C must be a Voigt matrix of shape (6, 6) or (3, 3), got {arr.shape}")
    return _voigt_to_tensor_unchecked(arr)


def tensor_to_voigt(T: ArrayLike, *, rtol: float = _SYM_RTOL) -> FloatArray:
    """Return the plain-Voigt matrix of a full fourth-order stiffness tensor.

    Parameters
    ----------
    T : (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Tensor with minor (``T_ijkl = T_jikl = T_ijlk``) and major (``T_ijkl = T_klij``)
        symmetry.
    rtol : float
        Allowed symmetry violation relative to ``max |T|``.

    Returns
    -------
    C : (6, 6) or (3, 3) ndarray
        Plain-Voigt matrix (no factor 2 on shear entries).

    Raises
    ------
    InputError
        ``T`` lacks minor or major symmetry; the message says which and how large the
        violation is.

    Examples
    --------
    >>> import numpy as np
    >>> C = np.arange(36.0).reshape(6, 6); C = C + C.T
    >>> bool(np.array_equal(tensor_to_voigt(voigt_to_tensor(C)), C))
    True
    >>> T = np.zeros((2, 2, 2, 2)); T[0, 1, 0, 0] = 1.0
    >>> tensor_to_voigt(T)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.InputError: T must have minor symmetry (T_ijkl = T_jikl = T_ijlk), got max ...
    """
    arr = _as_array(T, "T")
    if arr.ndim != 4:
        raise ShapeError(
            f"T must be a full tensor of shape (3, 3, 3, 3) or (2, 2, 2, 2), got {arr.shape}"
        )
    _check_tensor_symmetries(arr, "T", rtol)
    return _tensor_to_voigt_unchecked(arr)


def voigt_to_mandel(C: ArrayLike) -> FloatArray:
    """Return the Mandel matrix (shear rows and columns × √2) of a plain-Voigt stiffness.

    Parameters
    ----------
    C : (6, 6) or (3, 3) array_like of float
        Symmetric plain-Voigt stiffness.

    Returns
    -------
    ndarray of float, same shape as ``C``
        Mandel form: entry ``(α, β)`` times ``w_α w_β`` with ``w = √2`` on shear rows.

    Raises
    ------
    ShapeError
        If ``C`` is a full tensor or has another shape.

    Examples
    --------
    >>> import numpy as np
    >>> M = voigt_to_mandel(np.diag([1.0, 1.0, 1.0, 2.0, 2.0, 2.0]))
    >>> np.diag(M).tolist()
    [1.0, 1.0, 1.0, 4.0, 4.0, 4.0]
    """
    arr, dim, is_voigt = _stiffness(C, "C")
    if not is_voigt:
        raise ShapeError(f"C must be a Voigt matrix of shape (6, 6) or (3, 3), got {arr.shape}")
    w = _mandel_weights(dim)
    return arr * np.outer(w, w)


def mandel_to_voigt(M: ArrayLike) -> FloatArray:
    """Return the plain-Voigt matrix of a Mandel stiffness (inverse of :func:`voigt_to_mandel`).

    Parameters
    ----------
    M : (6, 6) or (3, 3) array_like of float
        Symmetric Mandel stiffness.

    Returns
    -------
    ndarray of float, same shape as ``M``
        Plain-Voigt form (shear rows and columns divided by √2).

    Raises
    ------
    ShapeError
        If ``M`` is a full tensor or has another shape.

    Examples
    --------
    >>> import numpy as np
    >>> C = np.eye(3) + 0.5
    >>> bool(np.allclose(mandel_to_voigt(voigt_to_mandel(C)), C))
    True
    """
    arr, dim, is_voigt = _stiffness(M, "M")
    if not is_voigt:
        raise ShapeError(f"M must be a Mandel matrix of shape (6, 6) or (3, 3), got {arr.shape}")
    w = _mandel_weights(dim)
    return arr / np.outer(w, w)


# ---------------------------------------------------------------------------
# rotations


def reflection(n: ArrayLike) -> FloatArray:
    """Return the reflection ``R(n) = I - 2 n⊗n / |n|²`` across the plane with normal ``n``.

    Parameters
    ----------
    n : (2,) or (3,) array_like of float
        Plane normal, any nonzero length.

    Returns
    -------
    ndarray of float, shape (d, d)
        Symmetric orthogonal matrix with determinant -1.

    Raises
    ------
    ShapeError
        If ``n`` is not of shape (2,) or (3,).
    InputError
        If ``n`` is zero or not finite.

    Examples
    --------
    >>> reflection([0, 0, 2]).tolist()
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]
    """
    v = np.asarray(n, dtype=np.float64)
    if v.shape not in ((2,), (3,)):
        raise ShapeError(f"n must have shape (2,) or (3,), got {v.shape}")
    check_finite(v, "n")
    nn = float(v @ v)
    if nn == 0.0:
        raise InputError("n must be a nonzero vector, got the zero vector")
    return np.eye(v.size) - 2.0 * np.outer(v, v) / nn


def rotation_matrix(axis: ArrayLike, angle: float) -> FloatArray:
    """Return the right-handed rotation by ``angle`` about ``axis`` (Rodrigues' formula).

    Parameters
    ----------
    axis : (3,) array_like of float
        Rotation axis, any nonzero length.
    angle : float
        Rotation angle in radians.

    Returns
    -------
    ndarray of float, shape (3, 3)
        Proper orthogonal matrix.

    Raises
    ------
    ShapeError
        If ``axis`` is not of shape (3,).
    InputError
        If ``axis`` is zero or not finite.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(rotation_matrix([0, 0, 1], np.pi / 2), 12).tolist()
    [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    """
    a = np.asarray(axis, dtype=np.float64)
    if a.shape != (3,):
        raise ShapeError(f"axis must have shape (3,), got {a.shape}")
    check_finite(a, "axis")
    norm = float(np.linalg.norm(a))
    if norm == 0.0:
        raise InputError("axis must be a nonzero vector, got the zero vector")
    k = a / norm
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def _check_orthogonal(Q: Any, dim: int, atol: float) -> FloatArray:
    q = np.asarray(Q, dtype=np.float64)
    if q.shape != (dim, dim):
        raise ShapeError(f"Q must have shape ({dim}, {dim}) to match C, got {q.shape}")
    check_finite(q, "Q")
    err = float(np.max(np.abs(q.T @ q - np.eye(dim))))
    if err > atol:
        raise InputError(f"Q must be orthogonal (max |QᵀQ - I| <= {atol:g}), got {err:.3g}")
    return q


def rotate(C: ArrayLike, Q: ArrayLike, *, atol: float = 1e-10) -> FloatArray:
    """Transform a stiffness by an orthogonal map: ``C'_pqrs = Q_pi Q_qj Q_rk Q_sl C_ijkl``.

    Prakash, anisotropic micromoduli, Eq. 44.  A material described by ``C`` in its own
    frame, turned by ``Q``, has stiffness ``rotate(C, Q)`` in the global frame.

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Symmetric stiffness, Voigt or full tensor.
    Q : (dim, dim) array_like of float
        Orthogonal matrix (rotation or reflection).
    atol : float
        Tolerance on ``max |QᵀQ - I|``.

    Returns
    -------
    ndarray
        Same format (Voigt or full) as ``C``.

    Examples
    --------
    >>> import numpy as np
    >>> C = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    >>> Q = rotation_matrix([0, 0, 1], np.pi / 2)      # swaps the x and y axes
    >>> np.round(np.diag(rotate(C, Q)), 12).tolist()
    [2.0, 1.0, 3.0, 5.0, 4.0, 6.0]
    """
    T, dim, is_voigt = _to_tensor(C, "C")
    q = _check_orthogonal(Q, dim, atol)
    out = np.einsum("pi,qj,rk,sl,ijkl->pqrs", q, q, q, q, T, optimize=True)
    # restore exact symmetry lost to rounding (average over the 8 index symmetries)
    out = 0.5 * (out + out.transpose(2, 3, 0, 1))
    out = 0.5 * (out + out.transpose(1, 0, 2, 3))
    out = 0.5 * (out + out.transpose(0, 1, 3, 2))
    return _tensor_to_voigt_unchecked(out) if is_voigt else out


# ---------------------------------------------------------------------------
# Frobenius norm and its Voigt weighting


def frobenius_multiplicity(dim: int = 3) -> NDArray[np.int64]:
    """Return the multiplicities of the upper-triangle Voigt entries in the full tensor.

    Entry ``(α, β)``, ``α ≤ β``, row-major, stands for ``m`` components of the full
    tensor: 3D ``m = 1`` (α = β ≤ 3), 2 (α < β ≤ 3), 4 (α ≤ 3 < β), 4 (α = β > 3),
    8 (3 < α < β), ``Σ m = 81``; 2D ``m = (1, 2, 4, 1, 4, 4)``, ``Σ m = 16``.  Weighting
    the least squares of Prakash, anisotropic micromoduli (Eqs. 32-35) by ``√m`` makes it a
    fit in the full-tensor Frobenius norm, which reproduces the paper's Table 1 (derived:
    the printed unweighted system does not).

    Parameters
    ----------
    dim : {2, 3}
        Spatial dimension.

    Returns
    -------
    ndarray of int64, shape (21,) or (6,)
        Multiplicity of each upper-triangle entry, row-major.

    Raises
    ------
    InputError
        If ``dim`` is not 2 or 3.

    Examples
    --------
    >>> frobenius_multiplicity(2).tolist()
    [1, 2, 4, 1, 4, 4]
    >>> int(frobenius_multiplicity(3).sum())
    81
    """
    if dim not in (2, 3):
        raise InputError(f"dim must be 2 or 3, got {dim!r}")
    p = np.array([1 if i == j else 2 for i, j in _pairs(dim)], dtype=np.int64)
    iu = np.triu_indices(p.size)
    return np.asarray(p[iu[0]] * p[iu[1]] * np.where(iu[0] == iu[1], 1, 2), dtype=np.int64)


def voigt_upper(C: ArrayLike) -> FloatArray:
    """Return the upper-triangle Voigt entries, row-major: 21 (3D) or 6 (2D) values.

    Order ``C11, C12, ..., C16, C22, ..., C66`` (2D: ``C11, C12, C13, C22, C23, C33``), the
    order of :func:`frobenius_multiplicity`.

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Symmetric stiffness.

    Returns
    -------
    ndarray of float, shape (21,) or (6,)
        The upper-triangle plain-Voigt entries.

    Examples
    --------
    >>> import numpy as np
    >>> voigt_upper(np.array([[1.0, 2, 3], [2, 4, 5], [3, 5, 6]])).tolist()
    [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    """
    V, _, _ = _to_voigt(C, "C")
    return V[np.triu_indices(V.shape[0])]


def frobenius_norm(C: ArrayLike) -> float:
    """Return the Frobenius norm of the full tensor (81 or 16 components).

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Symmetric stiffness, plain Voigt or full tensor.

    Returns
    -------
    float
        ``sqrt(Σ C_ijkl²)`` over all components of the full tensor.

    Examples
    --------
    >>> import numpy as np
    >>> frobenius_norm(np.diag([0.0, 0, 0, 1, 0, 0]))   # C2323 appears 4 times
    2.0
    """
    V, _, _ = _to_voigt(C, "C")
    return _frobenius_voigt(V)


def _frobenius_voigt(V: FloatArray) -> float:
    u = V[np.triu_indices(V.shape[0])]
    m = frobenius_multiplicity(3 if V.shape[0] == 6 else 2)
    return float(np.sqrt(np.sum(m * u * u)))


# ---------------------------------------------------------------------------
# Cauchy relations


#: Cauchy pairs (a, b) of zero-based Voigt index pairs (3D: Prakash, anisotropic
#: micromoduli, Eq. 49; 2D: derived, C1122 = C1212).
#: Total symmetrization sets both to (C_a + 2 C_b)/3 (C_b has twice the multiplicity).
_CAUCHY_PAIRS: dict[int, tuple[tuple[tuple[int, int], tuple[int, int]], ...]] = {
    3: (
        ((0, 1), (5, 5)),  # C12 = C66   (1122)
        ((0, 2), (4, 4)),  # C13 = C55   (1133)
        ((1, 2), (3, 3)),  # C23 = C44   (2233)
        ((0, 3), (4, 5)),  # C14 = C56   (1123)
        ((1, 4), (3, 5)),  # C25 = C46   (1223)
        ((2, 5), (3, 4)),  # C36 = C45   (1233)
    ),
    2: (((0, 1), (2, 2)),),  # C12 = C33 (1122)
}


def cauchy_projection(C: ArrayLike) -> FloatArray:
    """Project orthogonally onto totally symmetric tensors (the Cauchy subspace).

    ``C_sym,ijkl = (C_ijkl + C_ikjl + C_iljk) / 3``: for a tensor with minor and major
    symmetry this is the average over all 24 index permutations, hence idempotent, the
    orthogonal (full-tensor Frobenius) projection onto the Cauchy subspace, and
    commuting with rotations.  Per Cauchy pair (a, b) (``C12``/``C66``,
    ``C13``/``C55``, ``C23``/``C44``, ``C14``/``C56``, ``C25``/``C46``, ``C36``/``C45``;
    2D ``C12``/``C33``) both entries become ``(C_a + 2 C_b)/3`` — the multiplicity-weighted
    mean ``(m_a C_a + m_b C_b)/(m_a + m_b)`` with ``m_b = 2 m_a``; the other entries are
    unchanged.

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Symmetric stiffness, plain Voigt or full tensor.

    Returns
    -------
    ndarray
        Same format as ``C``.

    Examples
    --------
    >>> import numpy as np
    >>> C = np.array([[3.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 4.0]])
    >>> cauchy_projection(C).tolist()            # (1 + 2*4)/3 = 3
    [[3.0, 3.0, 0.0], [3.0, 3.0, 0.0], [0.0, 0.0, 3.0]]
    """
    V, dim, is_voigt = _to_voigt(C, "C")
    P = V.copy()
    for a, b in _CAUCHY_PAIRS[dim]:
        P[a] = P[a[::-1]] = P[b] = P[b[::-1]] = (V[a] + 2.0 * V[b]) / 3.0
    return _same_format(P, is_voigt)


def cauchy_distance(C: ArrayLike) -> float:
    """Return the relative distance ``‖C - proj(C)‖_F / ‖C‖_F`` from the Cauchy subspace.

    Full-tensor Frobenius norm.  This is the smallest relative error any bond-based
    (Cauchy-satisfying) model can reach, and so the error of a feasible full-rank
    calibration (:func:`pdlin.calibrate_micromoduli`).

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Symmetric stiffness, plain Voigt or full tensor.

    Returns
    -------
    float
        Relative distance, 0 for a tensor that satisfies the Cauchy relations.

    Raises
    ------
    InputError
        If ``C`` is zero.

    Examples
    --------
    >>> import numpy as np
    >>> from pdlin.constitutive import cubic
    >>> # spinel: the paper's Table 1 error of the calibrated tensor, in %
    >>> round(100 * cauchy_distance(cubic(252.0, 145.0, 142.0)), 4)
    0.8028
    """
    V, _, _ = _to_voigt(C, "C")
    norm = _frobenius_voigt(V)
    if norm == 0.0:
        raise InputError("C must be nonzero to measure a relative Cauchy distance, got C = 0")
    return _frobenius_voigt(V - cauchy_projection(V)) / norm


def satisfies_cauchy(C: ArrayLike, rtol: float = 1e-10) -> bool:
    """Test whether ``C`` satisfies the Cauchy relations: ``cauchy_distance(C) <= rtol``.

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Symmetric nonzero stiffness.
    rtol : float
        Largest relative distance from the Cauchy subspace counted as satisfying.

    Returns
    -------
    bool
        True when ``C`` is totally symmetric to ``rtol``.

    Examples
    --------
    >>> from pdlin.constitutive import isotropic
    >>> satisfies_cauchy(isotropic(E=1.0, nu=0.25)), satisfies_cauchy(isotropic(E=1.0, nu=0.3))
    (True, False)
    """
    return cauchy_distance(C) <= rtol


# ---------------------------------------------------------------------------
# checks and scalar measures


def check_stiffness(C: ArrayLike, name: str = "C") -> FloatArray:
    """Validate an elastic stiffness and return it as a float64 array.

    Checks, in order: shape ((6, 6)/(3, 3) Voigt or (3, 3, 3, 3)/(2, 2, 2, 2) full), finite
    entries, symmetry (major; full tensors also minor) to 1e-12 relative to ``max |C|``,
    and positive definiteness of the Mandel form (smallest eigenvalue greater than
    ``1e-13`` times the largest in magnitude).

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Candidate stiffness.
    name : str
        Name used in error messages.

    Returns
    -------
    ndarray of float
        ``C`` as a float64 array of the same shape.

    Raises
    ------
    InputTypeError
        If ``C`` is not numeric.
    ShapeError
        If the shape is not one of the four accepted.
    NonFiniteError
        If an entry is NaN or infinite.
    InputError
        If ``C`` is not symmetric or not positive definite (message names ``name``).

    Examples
    --------
    >>> import numpy as np
    >>> check_stiffness(np.diag([1.0, -3.2, 1.0]), name="D")
    Traceback (most recent call last):
    ...
    pdlin.errors.InputError: D must be positive definite, got smallest eigenvalue -3.2 (Mandel form)
    """
    arr, dim, is_voigt = _stiffness(C, name)
    V = arr if is_voigt else _tensor_to_voigt_unchecked(arr)
    w = _mandel_weights(dim)
    eig = np.linalg.eigvalsh(V * np.outer(w, w))
    if eig[0] <= 1e-13 * max(float(np.max(np.abs(eig))), np.finfo(float).tiny):
        raise InputError(
            f"{name} must be positive definite, got smallest eigenvalue {eig[0]:.6g} (Mandel form)"
        )
    return arr


def universal_anisotropy_index(C: ArrayLike) -> float:
    """Return the universal anisotropy index ``A^U = 5 G_V/G_R + K_V/K_R - 6``.

    Voigt (``K_V``, ``G_V``) and Reuss (``K_R``, ``G_R``) bounds from ``C`` and the
    compliance ``s = C⁻¹`` (Voigt), as in Prakash, anisotropic micromoduli, App. A.
    ``A^U ≥ 0``, zero exactly for isotropic ``C``.

    Parameters
    ----------
    C : (6, 6) or (3, 3, 3, 3) array_like of float
        Positive definite 3D stiffness.

    Returns
    -------
    float
        The index ``A^U`` (dimensionless).

    Raises
    ------
    ShapeError
        If ``C`` is a 2D stiffness.
    InputError
        If ``C`` is not symmetric positive definite.

    Examples
    --------
    >>> from pdlin.constitutive import cubic
    >>> round(universal_anisotropy_index(cubic(252.0, 145.0, 142.0)), 4)   # paper: 1.2372
    1.2372
    """
    arr = check_stiffness(C, "C")
    if _dim_of(arr) != 3:
        raise ShapeError(f"C must be a 3D stiffness ((6, 6) or (3, 3, 3, 3)), got {arr.shape}")
    V = arr if arr.ndim == 2 else _tensor_to_voigt_unchecked(arr)
    s = np.linalg.inv(V)
    d = np.arange(3)
    off = (np.array([0, 1, 2]), np.array([1, 2, 0]))
    kv = (V[d, d].sum() + 2.0 * V[off].sum()) / 9.0
    kr = 1.0 / (s[d, d].sum() + 2.0 * s[off].sum())
    gv = (V[d, d].sum() - V[off].sum() + 3.0 * V[d + 3, d + 3].sum()) / 15.0
    gr = 15.0 / (4.0 * s[d, d].sum() - 4.0 * s[off].sum() + 3.0 * s[d + 3, d + 3].sum())
    return float(5.0 * gv / gr + kv / kr - 6.0)


# ---------------------------------------------------------------------------
# 2D reductions


_IN_PLANE = np.array([0, 1, 5])
_OUT_OF_PLANE = np.array([2, 3, 4])


def _as_3d(C: Any) -> tuple[FloatArray, bool]:
    V, dim, is_voigt = _to_voigt(C, "C")
    if dim != 3:
        raise ShapeError(f"C must be a 3D stiffness ((6, 6) or (3, 3, 3, 3)), got {np.shape(C)}")
    return V, is_voigt


def plane_strain(C: ArrayLike) -> FloatArray:
    """Return the in-plane (x–y) stiffness under plane strain: Voigt rows/columns (11, 22, 12).

    The in-plane part of the 3D tensor (pdlin's 2D reduction).

    Parameters
    ----------
    C : (6, 6) or (3, 3, 3, 3) array_like of float
        Symmetric 3D stiffness.

    Returns
    -------
    ndarray of float
        (3, 3) Voigt for a (6, 6) input, (2, 2, 2, 2) for a full tensor.

    Raises
    ------
    ShapeError
        If ``C`` is not a 3D stiffness.

    Examples
    --------
    >>> from pdlin.constitutive import isotropic
    >>> plane_strain(isotropic(lam=1.0, mu=1.0)).tolist()
    [[3.0, 1.0, 0.0], [1.0, 3.0, 0.0], [0.0, 0.0, 1.0]]
    """
    V, is_voigt = _as_3d(C)
    return _same_format(np.ascontiguousarray(V[np.ix_(_IN_PLANE, _IN_PLANE)]), is_voigt)


def plane_stress(C: ArrayLike) -> FloatArray:
    """Return the in-plane stiffness under plane stress, ``Q = C_pp - C_po C_oo⁻¹ C_op``.

    ``p = {1, 2, 6}`` and ``o = {3, 4, 5}`` in Voigt numbering: the out-of-plane
    stresses σ33, σ23, σ31 vanish.

    Parameters
    ----------
    C : (6, 6) or (3, 3, 3, 3) array_like of float
        Symmetric positive definite 3D stiffness.

    Returns
    -------
    ndarray of float
        (3, 3) Voigt, or (2, 2, 2, 2) for a full-tensor input.

    Raises
    ------
    ShapeError
        If ``C`` is not a 3D stiffness.
    InputError
        If ``C`` is not positive definite.

    Examples
    --------
    >>> import numpy as np
    >>> from pdlin.constitutive import isotropic
    >>> Q = plane_stress(isotropic(E=1.0, nu=0.25))
    >>> bool(np.allclose(Q, isotropic_2d(1.0, 0.25, plane="stress")))
    True
    """
    V, is_voigt = _as_3d(C)
    check_stiffness(V, "C")
    p, o = _IN_PLANE, _OUT_OF_PLANE
    Q = V[np.ix_(p, p)] - V[np.ix_(p, o)] @ np.linalg.solve(V[np.ix_(o, o)], V[np.ix_(o, p)])
    Q = 0.5 * (Q + Q.T)
    return _same_format(Q, is_voigt)


def isotropic_2d(E: float, nu: float, plane: str = "stress") -> FloatArray:
    """Return the 2D isotropic Voigt stiffness (11, 22, 12) for plane stress or strain.

    Plane stress ``E/(1-ν²) [[1, ν, 0], [ν, 1, 0], [0, 0, (1-ν)/2]]``; plane strain
    ``E/((1+ν)(1-2ν)) [[1-ν, ν, 0], [ν, 1-ν, 0], [0, 0, (1-2ν)/2]]``.

    Parameters
    ----------
    E : float
        Young's modulus, > 0.
    nu : float
        Poisson ratio, in (-1, 1) for plane stress, (-1, 1/2) for plane strain.
    plane : {'stress', 'strain'}
        The 2D reduction.

    Returns
    -------
    ndarray of float, shape (3, 3)
        Plain-Voigt stiffness in the units of ``E``.

    Raises
    ------
    InputError
        If ``E <= 0``, ``nu`` is out of range or ``plane`` is unknown.
    NonFiniteError
        If ``E`` or ``nu`` is not finite.

    Examples
    --------
    >>> isotropic_2d(1.0, 1 / 3, plane="stress").round(6).tolist()   # C11 = 3 C12 = 3 C33
    [[1.125, 0.375, 0.0], [0.375, 1.125, 0.0], [0.0, 0.0, 0.375]]
    """
    e = _finite_scalar(E, "E")
    v = _finite_scalar(nu, "nu")
    if e <= 0.0:
        raise InputError(f"E must be > 0, got {e}")
    if plane == "stress":
        if not -1.0 < v < 1.0:
            raise InputError(f"nu must be in (-1, 1) for plane stress, got {v}")
        f = e / (1.0 - v * v)
        return f * np.array([[1.0, v, 0.0], [v, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - v)]])
    if plane == "strain":
        if not -1.0 < v < 0.5:
            raise InputError(f"nu must be in (-1, 0.5) for plane strain, got {v}")
        f = e / ((1.0 + v) * (1.0 - 2.0 * v))
        return f * np.array(
            [[1.0 - v, v, 0.0], [v, 1.0 - v, 0.0], [0.0, 0.0, 0.5 * (1.0 - 2.0 * v)]]
        )
    raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")


def _finite_scalar(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a real number, got {value!r}") from exc
    if not np.isfinite(v):
        raise NonFiniteError(f"{name} must be finite, got {v}")
    return v
