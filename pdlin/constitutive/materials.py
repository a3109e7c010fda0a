"""Reference elasticity tensors of Prakash, anisotropic micromoduli (§4.1, Eqs. 50-94).

One material per symmetry class, 6×6 plain-Voigt matrices in GPa in the material frame
of the paper, with the universal anisotropy index ``A^U`` of the paper's Table 1.  The
matrices are stored **as printed**, with the OCR's obvious misreadings corrected (the
isotropic off-diagonal entries read "0.4" for 34.4): in particular Ta₂C is not exactly
trigonal (``C66 = 153`` against ``(C11 - C12)/2 = 152.5``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import InputError

__all__ = ["MATERIALS", "MATERIAL_NAMES", "material"]


def _frozen(rows: list[list[float]]) -> NDArray[np.float64]:
    arr = np.array(rows, dtype=np.float64)
    arr.setflags(write=False)
    return arr


def _iso_like(c11: float, c12: float, c44: float) -> list[list[float]]:
    z = 0.0
    return [
        [c11, c12, c12, z, z, z],
        [c12, c11, c12, z, z, z],
        [c12, c12, c11, z, z, z],
        [z, z, z, c44, z, z],
        [z, z, z, z, c44, z],
        [z, z, z, z, z, c44],
    ]


#: Class name → (C in GPa, 6×6 plain Voigt, read-only; A^U as printed in the paper's Table 1).
MATERIALS: dict[str, tuple[NDArray[np.float64], float]] = {
    # KIO3, paper Eq. (50); A^U = 0.1965
    "triclinic": (
        _frozen(
            [
                [43, 11, 13, 1, -2, 2],
                [11, 35, 12, 3, -1, 3],
                [13, 12, 43, 2, -2, 1],
                [1, 3, 2, 13, 0, 0],
                [-2, -1, -2, 0, 13, 1],
                [2, 3, 1, 0, 1, 12],
            ]
        ),
        0.1965,
    ),
    # CoTeO4, paper Eq. (56) (mirror z = 0); A^U = 28.3169
    "monoclinic": (
        _frozen(
            [
                [135, 19, 54, 0, 0, 42],
                [19, 13, 15, 0, 0, 6],
                [54, 15, 269, 0, 0, 18],
                [0, 0, 0, 14, 25, 0],
                [0, 0, 0, 25, 66, 0],
                [42, 6, 18, 0, 0, 18],
            ]
        ),
        28.3169,
    ),
    # Te2W, paper Eq. (62); A^U = 54.0623
    "orthotropic": (
        _frozen(
            [
                [143, 1, 37, 0, 0, 0],
                [1, 3, 3, 0, 0, 0],
                [37, 3, 102, 0, 0, 0],
                [0, 0, 0, 2, 0, 0],
                [0, 0, 0, 0, 46, 0],
                [0, 0, 0, 0, 0, 1],
            ]
        ),
        54.0623,
    ),
    # Ta2C, paper Eq. (69), as printed (C66 = 153, not 152.5);
    # A^U = 0.5875
    "trigonal": (
        _frozen(
            [
                [464, 159, 141, -45, 0, 0],
                [159, 464, 141, 45, 0, 0],
                [141, 141, 493, 0, 0, 0],
                [-45, 45, 0, 125, 0, 0],
                [0, 0, 0, 0, 125, -45],
                [0, 0, 0, 0, -45, 153],
            ]
        ),
        0.5875,
    ),
    # Si, paper Eq. (75); A^U = 0.1231
    "tetragonal": (
        _frozen(
            [
                [212, 70, 58, 0, 0, 0],
                [70, 212, 58, 0, 0, 0],
                [58, 58, 179, 0, 0, 0],
                [0, 0, 0, 58, 0, 0],
                [0, 0, 0, 0, 58, 0],
                [0, 0, 0, 0, 0, 85],
            ]
        ),
        0.1231,
    ),
    # MoN, paper Eq. (81) (axis e3); A^U = 0.2551
    "transversely_isotropic": (
        _frozen(
            [
                [499, 177, 235, 0, 0, 0],
                [177, 499, 235, 0, 0, 0],
                [235, 235, 714, 0, 0, 0],
                [0, 0, 0, 241, 0, 0],
                [0, 0, 0, 0, 241, 0],
                [0, 0, 0, 0, 0, 161],
            ]
        ),
        0.2551,
    ),
    # spinel MgAl2O4 (the paper prints "MgAl2O2"), Eq. (87); A^U = 1.2372
    "cubic": (_frozen(_iso_like(252.0, 145.0, 142.0)), 1.2372),
    # Pyroceram 9608, Eq. (94) (the OCR's "0.4" read as 34.4); E = 86, nu = 0.25; A^U = 0
    "isotropic": (_frozen(_iso_like(103.2, 34.4, 34.4)), 0.0),
}

#: Class name → material name used in the paper.
MATERIAL_NAMES: dict[str, str] = {
    "triclinic": "KIO3",
    "monoclinic": "CoTeO4",
    "orthotropic": "Te2W",
    "trigonal": "Ta2C",
    "tetragonal": "Si",
    "transversely_isotropic": "MoN",
    "cubic": "MgAl2O4",
    "isotropic": "Pyroceram 9608",
}

_ALIASES = {v.lower(): k for k, v in MATERIAL_NAMES.items()}
_ALIASES.update({"spinel": "cubic", "pyroceram": "isotropic"})


def material(name: str) -> NDArray[np.float64]:
    """Return a writable copy of one of the paper's reference stiffnesses.

    The eight materials of Prakash, anisotropic micromoduli (§4.1), one per
    symmetry class, see :data:`MATERIALS`.

    Parameters
    ----------
    name : str
        A symmetry class (key of :data:`MATERIALS`, e.g. ``"trigonal"``) or the material
        name (``"Ta2C"``, ``"KIO3"``, ``"spinel"``, ``"Pyroceram"``, ...; case-insensitive).

    Returns
    -------
    ndarray of float, shape (6, 6)
        Plain-Voigt stiffness (no factor 2 on shear entries) in GPa, a fresh copy.

    Raises
    ------
    InputError
        If ``name`` is not a str or names no known class or material.

    Examples
    --------
    >>> float(material("Si")[5, 5])
    85.0
    >>> material("isotropic")[0, :3].tolist()
    [103.2, 34.4, 34.4]
    """
    if not isinstance(name, str):
        raise InputError(f"name must be a str, got {type(name).__name__}")
    key = name if name in MATERIALS else _ALIASES.get(name.lower())
    if key is None:
        known = sorted(MATERIALS) + sorted(MATERIAL_NAMES.values())
        raise InputError(f"name must be one of {known}, got {name!r}")
    return np.array(MATERIALS[key][0])
