"""The eight elastic symmetry classes: constructors, symmetry groups, invariance tests.

Constructors return 6×6 plain-Voigt matrices in the material frame of Prakash,
anisotropic micromoduli (§4.1): monoclinic mirror plane z = 0; orthotropic, tetragonal
and cubic axes along e₁, e₂, e₃; trigonal, tetragonal and transversely isotropic axis
e₃; trigonal mirror normal e₁.  For the trigonal class pdlin uses the mirror normals e₁
and ½e₁ ± (√3/2)e₂ with the sign pattern ``C14 = -C24 = C56`` (derived: these leave the
paper's Ta₂C matrix, Eq. 69, invariant; the normals (√3/2)e₁ ± ½e₂ printed in its Eq. 64
do not).  Every constructor checks that the result is positive definite.

=======================  ====================================  =========  ===========
class                    group generators                      constants  with Cauchy
=======================  ====================================  =========  ===========
triclinic                I, -I                                 21         15
monoclinic               I, -I, R(e₃)                          13         9
orthotropic              I, -I, R(e₁), R(e₂), R(e₃)            9          6
trigonal                 I, -I, R(e₁), R(½e₁ ± (√3/2)e₂), 3-fold about e₃   6   4
tetragonal               orthotropic + R((e₁ ± e₂)/√2)         6          4
transversely isotropic   I, -I, R(e₃), R(a e₁ + b e₂) (any)    5          3
cubic                    R(e_i), R((e_i ± e_j)/√2)             3          2
isotropic                all Q                                 2          1
=======================  ====================================  =========  ===========
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InputError, ShapeError
from .tensors import (
    _finite_scalar,
    _to_tensor,
    check_stiffness,
    reflection,
    rotate,
    rotation_matrix,
)

__all__ = [
    "triclinic",
    "monoclinic",
    "orthotropic",
    "trigonal",
    "tetragonal",
    "transversely_isotropic",
    "cubic",
    "isotropic_constants",
    "isotropic",
    "SYMMETRY_CLASSES",
    "N_CONSTANTS",
    "N_CONSTANTS_CAUCHY",
    "symmetry_group",
    "symmetry_distance",
    "is_symmetric_under",
]

FloatArray = NDArray[np.float64]


def _build(name: str, **entries: Any) -> FloatArray:
    """Symmetric 6×6 Voigt matrix from entries named ``Cab`` (1-based, a ≤ b)."""
    C = np.zeros((6, 6))
    for key, value in entries.items():
        a, b = int(key[1]) - 1, int(key[2]) - 1
        v = _finite_scalar(value, key)
        C[a, b] = C[b, a] = v
    return check_stiffness(C, f"C ({name})")


def triclinic(C: ArrayLike) -> FloatArray:
    """Return a triclinic stiffness: any symmetric positive definite 6×6 Voigt matrix.

    The triclinic class has 21 independent constants (no symmetry beyond ``±I``).

    Parameters
    ----------
    C : (6, 6) array_like of float
        Symmetric positive definite plain-Voigt matrix.

    Returns
    -------
    ndarray of float, shape (6, 6)
        A float64 copy of ``C``.

    Raises
    ------
    ShapeError
        If ``C`` is not 6×6.
    InputError
        If ``C`` is not finite, symmetric and positive definite.

    Examples
    --------
    >>> import numpy as np
    >>> triclinic(np.eye(6)).shape
    (6, 6)
    >>> triclinic(np.eye(3))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.ShapeError: C must be a 6x6 Voigt matrix, got shape (3, 3)
    """
    if np.shape(C) != (6, 6):
        raise ShapeError(f"C must be a 6x6 Voigt matrix, got shape {np.shape(C)}")
    return np.array(check_stiffness(C, "C"), dtype=np.float64)


def monoclinic(
    C11: float, C22: float, C33: float, C12: float, C13: float, C23: float,
    C44: float, C55: float, C66: float, C16: float, C26: float, C36: float, C45: float,
) -> FloatArray:  # fmt: skip
    """Build a monoclinic stiffness with mirror plane z = 0 (13 constants).

    Entries with an odd number of indices 3 vanish (C14, C15, C24, C25, C34, C35, C46, C56).

    Parameters
    ----------
    C11, C22, C33, C12, C13, C23, C44, C55, C66, C16, C26, C36, C45 : float
        The 13 independent plain-Voigt entries (1-based indices).

    Returns
    -------
    ndarray of float, shape (6, 6)
        Plain-Voigt stiffness (no factor 2 on shear entries), in the units of the input.

    Raises
    ------
    InputError
        If a constant is not a finite real number or the matrix is not positive definite.

    Examples
    --------
    >>> C = monoclinic(135, 13, 269, 19, 54, 15, 14, 66, 18, 42, 6, 18, 25)  # CoTeO4, Eq. 56
    >>> float(C[0, 5]), float(C[3, 4]), float(C[0, 3])
    (42.0, 25.0, 0.0)
    """
    return _build(
        "monoclinic", C11=C11, C22=C22, C33=C33, C12=C12, C13=C13, C23=C23,
        C44=C44, C55=C55, C66=C66, C16=C16, C26=C26, C36=C36, C45=C45,
    )  # fmt: skip


def orthotropic(
    C11: float, C22: float, C33: float, C12: float, C13: float, C23: float,
    C44: float, C55: float, C66: float,
) -> FloatArray:  # fmt: skip
    """Build an orthotropic stiffness with mirror planes normal to e₁, e₂, e₃ (9 constants).

    Parameters
    ----------
    C11, C22, C33, C12, C13, C23, C44, C55, C66 : float
        The 9 independent plain-Voigt entries; all others are zero.

    Returns
    -------
    ndarray of float, shape (6, 6)
        Plain-Voigt stiffness (no factor 2 on shear entries), in the units of the input.

    Raises
    ------
    InputError
        If a constant is not a finite real number or the matrix is not positive definite.

    Examples
    --------
    >>> orthotropic(143, 3, 102, 1, 37, 3, 2, 46, 1)[:3, :3].tolist()   # Te2W, Eq. 62
    [[143.0, 1.0, 37.0], [1.0, 3.0, 3.0], [37.0, 3.0, 102.0]]
    """
    return _build(
        "orthotropic", C11=C11, C22=C22, C33=C33, C12=C12, C13=C13, C23=C23,
        C44=C44, C55=C55, C66=C66,
    )  # fmt: skip


def trigonal(C11: float, C33: float, C12: float, C13: float, C14: float, C44: float) -> FloatArray:
    """Build a trigonal stiffness with 3-fold axis e₃ and mirror normal e₁ (6 constants).

    ``C22 = C11``, ``C23 = C13``, ``C55 = C44``, ``C24 = -C14``, ``C56 = C14``,
    ``C66 = (C11 - C12)/2``: the class constraints of Prakash, anisotropic micromoduli,
    Eq. 65, read with ``C14 = -C24 = C56`` (the OCR prints "C14 = C56 = -C14").

    Parameters
    ----------
    C11, C33, C12, C13, C14, C44 : float
        The 6 independent plain-Voigt entries.

    Returns
    -------
    ndarray of float, shape (6, 6)
        Plain-Voigt stiffness (no factor 2 on shear entries), in the units of the input.

    Raises
    ------
    InputError
        If a constant is not a finite real number or the matrix is not positive definite.

    Examples
    --------
    >>> C = trigonal(464, 493, 159, 141, -45, 125)       # Ta2C, Eq. 69 (C66 152.5, not 153)
    >>> float(C[0, 3]), float(C[1, 3]), float(C[4, 5]), float(C[5, 5])
    (-45.0, 45.0, -45.0, 152.5)
    """
    return _build(
        "trigonal", C11=C11, C22=C11, C33=C33, C12=C12, C13=C13, C23=C13, C14=C14,
        C24=-_finite_scalar(C14, "C14"), C44=C44, C55=C44, C56=C14,
        C66=0.5 * (_finite_scalar(C11, "C11") - _finite_scalar(C12, "C12")),
    )  # fmt: skip


def tetragonal(
    C11: float, C33: float, C12: float, C13: float, C44: float, C66: float
) -> FloatArray:
    """Build a tetragonal stiffness with 4-fold axis e₃ (6 constants).

    Mirror normals e₁, e₂, e₃ and (e₁ ± e₂)/√2; ``C22 = C11``, ``C23 = C13``,
    ``C55 = C44``.

    Parameters
    ----------
    C11, C33, C12, C13, C44, C66 : float
        The 6 independent plain-Voigt entries.

    Returns
    -------
    ndarray of float, shape (6, 6)
        Plain-Voigt stiffness (no factor 2 on shear entries), in the units of the input.

    Raises
    ------
    InputError
        If a constant is not a finite real number or the matrix is not positive definite.

    Examples
    --------
    >>> C = tetragonal(212, 179, 70, 58, 58, 85)          # Si, Eq. 75
    >>> float(C[1, 1]), float(C[1, 2]), float(C[4, 4]), float(C[5, 5])
    (212.0, 58.0, 58.0, 85.0)
    """
    return _build(
        "tetragonal", C11=C11, C22=C11, C33=C33, C12=C12, C13=C13, C23=C13,
        C44=C44, C55=C44, C66=C66,
    )  # fmt: skip


def transversely_isotropic(
    C11: float, C33: float, C12: float, C13: float, C44: float
) -> FloatArray:
    """Build a transversely isotropic stiffness with axis e₃ (5 constants).

    ``C22 = C11``, ``C23 = C13``, ``C55 = C44`` and ``C66 = (C11 - C12)/2``.

    Parameters
    ----------
    C11, C33, C12, C13, C44 : float
        The 5 independent plain-Voigt entries.

    Returns
    -------
    ndarray of float, shape (6, 6)
        Plain-Voigt stiffness (no factor 2 on shear entries), in the units of the input.

    Raises
    ------
    InputError
        If a constant is not a finite real number or the matrix is not positive definite.

    Examples
    --------
    >>> float(transversely_isotropic(499, 714, 177, 235, 241)[5, 5])   # MoN, Eq. 81
    161.0
    """
    return _build(
        "transversely isotropic", C11=C11, C22=C11, C33=C33, C12=C12, C13=C13, C23=C13,
        C44=C44, C55=C44,
        C66=0.5 * (_finite_scalar(C11, "C11") - _finite_scalar(C12, "C12")),
    )  # fmt: skip


def cubic(C11: float, C12: float, C44: float) -> FloatArray:
    """Build a cubic stiffness with axes e₁, e₂, e₃ (3 constants).

    Parameters
    ----------
    C11, C12, C44 : float
        Axial, off-diagonal axial and shear plain-Voigt entries.

    Returns
    -------
    ndarray of float, shape (6, 6)
        Plain-Voigt stiffness (no factor 2 on shear entries), in the units of the input.

    Raises
    ------
    InputError
        If a constant is not a finite real number or the matrix is not positive definite.

    Examples
    --------
    >>> C = cubic(252, 145, 142)                                      # spinel, Eq. 87
    >>> float(C[2, 2]), float(C[0, 2]), float(C[3, 3])
    (252.0, 145.0, 142.0)
    """
    return _build(
        "cubic", C11=C11, C22=C11, C33=C11, C12=C12, C13=C12, C23=C12,
        C44=C44, C55=C44, C66=C44,
    )  # fmt: skip


def isotropic(
    E: float | None = None,
    nu: float | None = None,
    *,
    lam: float | None = None,
    mu: float | None = None,
    K: float | None = None,
    G: float | None = None,
) -> FloatArray:
    """Build an isotropic stiffness from exactly two of E, ν, λ, μ (= G), K.

    ``C11 = λ + 2μ``, ``C12 = λ``, ``C44 = μ``.

    Parameters
    ----------
    E : float, optional
        Young's modulus.
    nu : float, optional
        Poisson ratio, in (-1, 1/2).
    lam, mu : float, optional
        Lamé's first constant and the shear modulus.
    K : float, optional
        Bulk modulus.
    G : float, optional
        Shear modulus (the same constant as ``mu``; give one of them).

    Returns
    -------
    ndarray of float, shape (6, 6)
        Plain-Voigt stiffness in the units of the moduli.

    Raises
    ------
    InputError
        Not exactly two moduli given (``mu`` and ``G`` are the same modulus), or moduli
        that do not give a positive definite tensor (need K > 0, G > 0).

    Examples
    --------
    >>> import numpy as np
    >>> C = isotropic(E=86.0, nu=0.25)                   # Pyroceram 9608, Eq. 94
    >>> round(float(C[0, 0]), 6), round(float(C[0, 1]), 6), round(float(C[3, 3]), 6)
    (103.2, 34.4, 34.4)
    >>> bool(np.allclose(isotropic(K=57.3333333333333, G=34.4), C))
    True
    """
    if mu is not None and G is not None:
        raise InputError(f"give mu or G (the same shear modulus), not both: mu = {mu}, G = {G}")
    passed = {"E": E, "nu": nu, "lam": lam, "mu": mu, "K": K, "G": G}
    names = [k for k, v in passed.items() if v is not None]
    if len(names) != 2:
        raise InputError(
            "isotropic needs exactly two of E, nu, lam, mu (or G), K, "
            f"got {len(names)}: {', '.join(names) or 'none'}"
        )
    given = {("G" if k == "mu" else k): _finite_scalar(passed[k], k) for k in names}
    _check_nu(given.get("nu"))
    lam_a, mu_a = _lame_arrays({k: np.asarray(v) for k, v in given.items()})
    if not (np.isfinite(lam_a) and np.isfinite(mu_a)):
        raise InputError(f"{', '.join(f'{k} = {v:g}' for k, v in given.items())} do not "
                         "determine finite elastic moduli")  # fmt: skip
    lam_, mu_ = float(lam_a), float(mu_a)
    return _build(
        "isotropic", C11=lam_ + 2 * mu_, C22=lam_ + 2 * mu_, C33=lam_ + 2 * mu_,
        C12=lam_, C13=lam_, C23=lam_, C44=mu_, C55=mu_, C66=mu_,
    )  # fmt: skip


_ISO_ORDER = ("E", "nu", "K", "G", "lam")


def _lame_arrays(g: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Elementwise (λ, μ) from a pair of E, ν, K, G (= μ), λ (arrays, no validation)."""
    keys = frozenset(g)
    with np.errstate(divide="ignore", invalid="ignore"):
        if keys == {"E", "nu"}:
            E, nu = g["E"], g["nu"]
            return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))
        if keys == {"K", "G"}:
            return g["K"] - 2.0 * g["G"] / 3.0, g["G"]
        if keys == {"G", "lam"}:
            return g["lam"], g["G"]
        if keys == {"E", "G"}:
            E, G = g["E"], g["G"]
            return G * (E - 2.0 * G) / (3.0 * G - E), G
        if keys == {"E", "K"}:
            E, K = g["E"], g["K"]
            G = 3.0 * K * E / (9.0 * K - E)
            return K - 2.0 * G / 3.0, G
        if keys == {"nu", "K"}:
            K, nu = g["K"], g["nu"]
            G = 3.0 * K * (1.0 - 2.0 * nu) / (2.0 * (1.0 + nu))
            return K - 2.0 * G / 3.0, G
        if keys == {"nu", "G"}:
            G, nu = g["G"], g["nu"]
            return 2.0 * G * nu / (1.0 - 2.0 * nu), G
        if keys == {"nu", "lam"}:
            lam, nu = g["lam"], g["nu"]
            return lam, lam * (1.0 - 2.0 * nu) / (2.0 * nu)
        if keys == {"K", "lam"}:
            return g["lam"], 1.5 * (g["K"] - g["lam"])
        E, lam = g["E"], g["lam"]  # {"E", "lam"}
        return lam, (E - 3.0 * lam + np.sqrt(E * E + 9.0 * lam * lam + 2.0 * E * lam)) / 4.0


def isotropic_constants(
    E: Any = None,
    nu: Any = None,
    *,
    K: Any = None,
    G: Any = None,
    lam: Any = None,
    mu: Any = None,
    rtol: float = 1e-9,
) -> tuple[Any, Any]:
    """Convert any two isotropic constants to Young's modulus and Poisson ratio ``(E, ν)``.

    Accepts two (or more, if consistent) of ``E``, ``nu``, ``K`` (bulk
    modulus), ``G`` or ``mu`` (shear modulus, the same constant) and ``lam``
    (Lamé's first constant), as scalars or per-point ``(n,)`` arrays: the
    constants users have (Peridigm decks give ``K`` and ``G``).  All are 3D
    constants; the 2D models apply their plane-stress / plane-strain
    reduction to the returned ``(E, ν)``.

    Parameters
    ----------
    E, nu, K, G, lam, mu : float or (n,) array_like, optional
        Young's modulus, Poisson ratio, bulk modulus, shear modulus, Lamé's first
        constant and the shear modulus again (``mu`` and ``G`` must agree if both given).
    rtol : float
        Relative tolerance when more than two constants are given: every
        extra one must agree with the pair ``E, nu, K, G, lam`` (first two
        in that order) to ``rtol``.

    Returns
    -------
    E, nu : float or ndarray
        Young's modulus (units of the inputs) and Poisson ratio; ``(n,)`` arrays when an
        input is an array.

    Raises
    ------
    InputError
        Fewer than two constants, non-finite values, ``mu`` and ``G`` that
        differ, constants that do not give a positive definite material
        (need ``K > 0`` and ``G > 0``, i.e. ``-1 < ν < 1/2``), or extra
        constants inconsistent with the first pair.

    Examples
    --------
    >>> E, nu = isotropic_constants(K=175e9, G=80.77e9)         # steel, Peridigm style
    >>> round(E / 1e9, 3), round(nu, 4)
    (210.0, 0.3)
    >>> isotropic_constants(lam=1.0, mu=1.0)
    (2.5, 0.25)
    >>> isotropic_constants(E=1.0, nu=0.25, K=1.0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.InputError: inconsistent isotropic constants: K = 1 but ... give K = 0.666667
    """
    if mu is not None and G is not None:
        Ga, ma = _finite_array(G, "G"), _finite_array(mu, "mu")
        if not np.allclose(Ga, ma, rtol=rtol, atol=0.0):
            raise InputError(
                f"mu and G are the same shear modulus and must agree, got {mu} and {G}"
            )
    if G is None:
        G = mu
    passed = {"E": E, "nu": nu, "K": K, "G": G, "lam": lam}
    names = [k for k in _ISO_ORDER if passed[k] is not None]
    if len(names) < 2:
        raise InputError(
            "isotropic elasticity needs two of E, nu, K (bulk), G or mu (shear), lam (Lamé), "
            f"got {len(names)}: {', '.join(names) or 'none'}"
        )
    vals = {k: _finite_array(passed[k], k) for k in names}
    scalar = all(v.ndim == 0 for v in vals.values())
    pair = {k: vals[k] for k in names[:2]}
    lam_, mu_ = _lame_arrays(pair)
    K_ = lam_ + 2.0 * mu_ / 3.0
    shown = ", ".join(f"{k} = {_show(passed[k])}" for k in names[:2])
    if not (np.all(np.isfinite(lam_)) and np.all(np.isfinite(mu_))):
        raise InputError(f"{shown} do not determine finite elastic moduli")
    if np.any(mu_ <= 0) or np.any(K_ <= 0):
        raise InputError(
            f"{shown} give a material that is not positive definite (need K > 0 and G > 0, "
            f"got K = {_show(K_)}, G = {_show(mu_)})"
        )
    E_ = mu_ * (3.0 * lam_ + 2.0 * mu_) / (lam_ + mu_)
    nu_ = lam_ / (2.0 * (lam_ + mu_))
    derived = {"E": E_, "nu": nu_, "K": K_, "G": mu_, "lam": lam_}
    for k in names[2:]:
        ref = derived[k]
        scale = np.maximum(np.abs(ref), np.abs(mu_) if k != "nu" else 1.0)
        if np.any(np.abs(vals[k] - ref) > rtol * scale):
            raise InputError(
                f"inconsistent isotropic constants: {k} = {_show(passed[k])} but {shown} "
                f"give {k} = {_show(ref)}"
            )
    if scalar:
        return float(E_), float(nu_)
    return E_, nu_


def _check_nu(nu: Any) -> None:
    """Check that a given Poisson ratio lies in (-1, 1/2) (positive definite isotropic tensor)."""
    if nu is None:
        return
    arr = np.asarray(nu, dtype=float)
    if np.any(arr <= -1.0) or np.any(arr >= 0.5):
        got = float(arr) if arr.ndim == 0 else _show(arr)
        raise InputError(f"nu must be in (-1, 0.5), got {got}")


def _finite_array(value: Any, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number or (n,) array, got {value!r}") from None
    if arr.ndim > 1:
        raise ShapeError(f"{name} must be a scalar or (n,) array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite, got {value!r}")
    return arr


def _show(value: Any) -> str:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return f"{float(arr):.6g}"
    return f"[{float(arr.min()):.6g} ... {float(arr.max()):.6g}] ({arr.size} values)"


#: Class name → constructor, from most to least anisotropic.
SYMMETRY_CLASSES: dict[str, Callable[..., FloatArray]] = {
    "triclinic": triclinic,
    "monoclinic": monoclinic,
    "orthotropic": orthotropic,
    "trigonal": trigonal,
    "tetragonal": tetragonal,
    "transversely_isotropic": transversely_isotropic,
    "cubic": cubic,
    "isotropic": isotropic,
}

#: Independent elastic constants per class (Prakash, anisotropic micromoduli, Table 1).
N_CONSTANTS: dict[str, int] = {
    "triclinic": 21, "monoclinic": 13, "orthotropic": 9, "trigonal": 6, "tetragonal": 6,
    "transversely_isotropic": 5, "cubic": 3, "isotropic": 2,
}  # fmt: skip

#: Independent constants once the Cauchy relations are imposed (the paper's Table 1).
N_CONSTANTS_CAUCHY: dict[str, int] = {
    "triclinic": 15, "monoclinic": 9, "orthotropic": 6, "trigonal": 4, "tetragonal": 4,
    "transversely_isotropic": 3, "cubic": 2, "isotropic": 1,
}  # fmt: skip

# Generic angles (irrational multiples of π) for the continuous groups.
_GENERIC_ANGLE = 1.0
_GENERIC_AXES = ((0.3, 0.5, 0.8), (-0.7, 0.2, 0.4))


def _frame(n_axis: ArrayLike) -> FloatArray:
    """Smallest rotation R with R e₃ = n (n normalized); R(−e₃) is a π turn about e₁."""
    n = np.asarray(n_axis, dtype=np.float64)
    if n.shape != (3,):
        raise ShapeError(f"n_axis must have shape (3,), got {n.shape}")
    norm = float(np.linalg.norm(n))
    if not np.isfinite(norm) or norm == 0.0:
        raise InputError(f"n_axis must be a finite nonzero vector, got {n.tolist()}")
    n = n / norm
    e3 = np.array([0.0, 0.0, 1.0])
    c = float(n @ e3)
    axis = np.cross(e3, n)
    s = float(np.linalg.norm(axis))
    if s < 1e-14:
        return np.eye(3) if c > 0 else rotation_matrix([1.0, 0.0, 0.0], np.pi)
    return rotation_matrix(axis, float(np.arctan2(s, c)))


def symmetry_group(name: str, n_axis: ArrayLike = (0, 0, 1)) -> list[FloatArray]:
    """Return orthogonal 3×3 matrices generating the symmetry group of a class.

    The reflections ``R(n) = I - 2 n⊗n`` (and, for trigonal, the 2π/3 turns about e₃) of
    the table in this module's docstring, for the material frame of the constructors.
    Continuous groups (transversely isotropic, isotropic) are represented by generators at
    generic angles whose closure is dense in the group, so invariance under the returned list is
    invariance under the whole group.  With ``n_axis``, the material axis e₃ is turned
    onto ``n_axis`` by the smallest rotation ``R`` and every element is conjugated,
    ``R Q Rᵀ``: the group of ``rotate(C, R)``.

    Parameters
    ----------
    name : str
        A key of :data:`SYMMETRY_CLASSES`.
    n_axis : (3,) array_like of float
        Direction of the material axis (monoclinic mirror normal, trigonal/tetragonal/
        transversely isotropic axis).

    Returns
    -------
    list of (3, 3) ndarray
        Orthogonal matrices (reflections, inversions and rotations) generating the group.

    Raises
    ------
    InputError
        If ``name`` is not a symmetry class or ``n_axis`` is zero or not finite.
    ShapeError
        If ``n_axis`` does not have shape (3,).

    Examples
    --------
    >>> from pdlin.constitutive import cubic
    >>> C = cubic(252.0, 145.0, 142.0)
    >>> all(is_symmetric_under(C, Q) for Q in symmetry_group("cubic"))
    True
    >>> len(symmetry_group("orthotropic"))
    5
    """
    if name not in SYMMETRY_CLASSES:
        raise InputError(f"name must be one of {sorted(SYMMETRY_CLASSES)}, got {name!r}")
    I3 = np.eye(3)
    e1, e2, e3 = I3
    base = [I3, -I3]
    r = np.sqrt(0.5)
    if name == "triclinic":
        group = base
    elif name == "monoclinic":
        group = base + [reflection(e3)]
    elif name == "orthotropic":
        group = base + [reflection(e1), reflection(e2), reflection(e3)]
    elif name == "trigonal":
        h = np.sqrt(3.0) / 2.0
        group = base + [
            reflection(e1),
            reflection([0.5, h, 0.0]),
            reflection([0.5, -h, 0.0]),
            rotation_matrix(e3, 2.0 * np.pi / 3.0),
            rotation_matrix(e3, 4.0 * np.pi / 3.0),
        ]
    elif name == "tetragonal":
        group = base + [
            reflection(e1), reflection(e2), reflection(e3),
            reflection([r, r, 0.0]), reflection([r, -r, 0.0]),
        ]  # fmt: skip
    elif name == "transversely_isotropic":
        t = _GENERIC_ANGLE
        group = base + [
            reflection(e3), reflection(e1), reflection(e2),
            reflection([np.cos(t), np.sin(t), 0.0]),
            rotation_matrix(e3, t),
        ]  # fmt: skip
    elif name == "cubic":
        group = [I3, -I3] + [reflection(e) for e in (e1, e2, e3)]
        for a, b in ((e1, e2), (e2, e3), (e1, e3)):
            group += [reflection(r * (a + b)), reflection(r * (a - b))]
    else:  # isotropic
        group = base + [reflection(e1), reflection(np.array(_GENERIC_AXES[0]))]
        group += [rotation_matrix(ax, _GENERIC_ANGLE) for ax in _GENERIC_AXES]
    R = _frame(n_axis)
    return [R @ Q @ R.T for Q in group]


def symmetry_distance(C: ArrayLike, Q: ArrayLike) -> float:
    """Return the relative change ``‖Q∗C - C‖_F / ‖C‖_F`` of a stiffness under ``Q``.

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Stiffness as plain Voigt or full tensor.
    Q : (d, d) array_like of float
        Orthogonal matrix (rotation or reflection) in the dimension of ``C``.

    Returns
    -------
    float
        Relative change in the Frobenius norm of the full fourth-order tensor.

    Raises
    ------
    InputError
        If ``C`` is zero.

    Examples
    --------
    >>> import numpy as np
    >>> from pdlin.constitutive import material
    >>> # Ta2C is not invariant under the mirror y -> -y (the paper's Eq. 64 normals)
    >>> round(symmetry_distance(material("trigonal"), reflection([0, 1, 0])), 2)
    0.35
    """
    T, _, _ = _to_tensor(C, "C")
    norm = float(np.linalg.norm(T))
    if norm == 0.0:
        raise InputError("C must be nonzero to measure a relative symmetry distance, got C = 0")
    return float(np.linalg.norm(rotate(T, Q) - T)) / norm


def is_symmetric_under(C: ArrayLike, Q: ArrayLike, rtol: float = 1e-10) -> bool:
    """Test whether ``Q`` is a symmetry of ``C``: ``symmetry_distance(C, Q) <= rtol``.

    Parameters
    ----------
    C : (6, 6), (3, 3), (3, 3, 3, 3) or (2, 2, 2, 2) array_like of float
        Stiffness as plain Voigt or full tensor.
    Q : (d, d) array_like of float
        Orthogonal matrix in the dimension of ``C``.
    rtol : float
        Largest relative Frobenius change counted as invariant.

    Returns
    -------
    bool
        True when ``Q∗C`` equals ``C`` to ``rtol``.

    Examples
    --------
    >>> import numpy as np
    >>> from pdlin.constitutive import material
    >>> C = material("trigonal")                      # printed Ta2C: C66 = 153, not 152.5
    >>> is_symmetric_under(C, reflection([1, 0, 0]))
    True
    >>> is_symmetric_under(C, rotation_matrix([0, 0, 1], 2 * np.pi / 3))
    False
    >>> is_symmetric_under(C, rotation_matrix([0, 0, 1], 2 * np.pi / 3), rtol=2e-3)
    True
    """
    return symmetry_distance(C, Q) <= rtol
