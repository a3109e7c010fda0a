"""Rate-independent crystal plasticity (Anand–Kothari 1996) and a Saint Venant–Kirchhoff material.

Luo, Ramazani & Sundararaghavan (2017), Section 3 and Appendix (planar polycrystals),
and Javaheri, Luo, Lakshmanan & Sundararaghavan (2022), Section III (3D polycrystals).
See ``docs/crystal_plasticity.md`` for the equations as implemented and the
conventions.

Material interface (used by the nonlinear drivers)
--------------------------------------------------
``initial_state(n) -> dict[str, ndarray]``
    Committed state of ``n`` points (``Fp = I``, ``s = s0``, zero slips, orientation).
``update(F, state_n, *, tangent=False) -> (P, state_new, dPdF)``
    Pure function of ``(F, state_n)``: first Piola–Kirchhoff stress ``P (n, d, d)``,
    the trial state at ``F`` (a new dict; ``state_n`` is not touched) and, with
    ``tangent=True``, the consistent algorithmic tangent ``dP/dF (n, d, d, d, d)``
    (``D[p, i, j, k, l] = ∂P_ij/∂F_kl``).  A driver commits ``state_new`` at the end
    of a converged load step.

Conventions
-----------
* Units: the defaults are in mm–MPa (stresses in MPa).
* Orientation ``R`` maps crystal to sample vectors (Luo, Ramazani & Sundararaghavan
  2017, Section 4): 2D ``R = [[cos θ, -sin θ], [sin θ, cos θ]]``; 3D rotation matrices,
  or Bunge Euler angles ``(φ1, Φ, φ2)`` with ``R = Rz(φ1) Rx(Φ) Rz(φ2)`` (the Bunge
  matrix ``g = Rᵀ`` maps sample to crystal coordinates).  All constitutive work is done
  in the crystal frame: ``F_c = Rᵀ F R`` and ``P = R P_c Rᵀ``.
* Lattice reorientation is reported in degrees, counter-clockwise positive (2D).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import n_orientations
from .._repr import Raw, compact_repr, format_value
from .._validation import check_finite, integer, positive_scalar
from ..errors import (
    ActiveSetWarning,
    ConvergenceError,
    InputError,
    InputTypeError,
    NonFiniteError,
    ShapeError,
)
from .tensors import (
    _tensor_to_voigt_unchecked,
    _voigt_to_tensor_unchecked,
    check_stiffness,
)

__all__ = [
    "SLIP_FAMILIES",
    "ORIENTATIONS_2D",
    "CrystalPlasticity",
    "SaintVenantKirchhoff",
    "MaterialPointResult",
    "material_point",
    "slip_systems",
    "euler_to_rotation",
    "cauchy_stress",
]

FloatArray = NDArray[np.float64]

#: The 12-value orientation set of Luo, Ramazani & Sundararaghavan (2017), Section 4:
#: θ_k = −π/2 + kπ/12, k = 0..11 (radians).
ORIENTATIONS_2D: FloatArray = np.asarray(
    -0.5 * np.pi + np.arange(12) * np.pi / 12.0, dtype=np.float64
)
ORIENTATIONS_2D.setflags(write=False)

#: Slip-system families of each lattice, in system order.
SLIP_FAMILIES: dict[str, tuple[tuple[str, int], ...]] = {
    "planar-2": (("planar", 2),),
    "fcc": (("octahedral", 12),),
    "hcp": (("basal", 3), ("prismatic", 3), ("pyramidal_a", 6), ("pyramidal_ca", 6)),
}

# --- default material data ------------------------------------------------------------
# planar-2: Luo, Ramazani & Sundararaghavan (2017), Section 4 (D11 = 2, D12 = 1,
# D33 = 2 GPa; pdlin reads them as Voigt with engineering shear and D22 = D11, since the
# paper states neither) and Eqs. 22-24 (h0 = 10, s0 = 10, ss = 200 MPa, a = 2, q = 1.4).
_DEFAULT_ELASTIC: dict[str, dict[str, float]] = {
    "planar-2": {"D11": 2000.0, "D22": 2000.0, "D12": 1000.0, "D33": 2000.0},
    # fcc (pdlin's default, not in the papers): OFHC copper, Kalidindi, Bronkhorst & Anand
    # (1992), MPa.
    "fcc": {"C11": 170e3, "C12": 124e3, "C44": 75e3},
    # hcp: Mg, Javaheri, Luo, Lakshmanan & Sundararaghavan (2022), Section III.C
    # (C11 = 59.3, C12 = 25.7, C13 = 21.4, C33 = 61.5, C44 = 16.4 GPa).
    "hcp": {"C11": 59.3e3, "C12": 25.7e3, "C13": 21.4e3, "C33": 61.5e3, "C44": 16.4e3},
}
_DEFAULT_HARDENING: dict[str, dict[str, Any]] = {
    "planar-2": {"h0": 10.0, "s0": 10.0, "ss": 200.0, "a": 2.0, "q": 1.4},
    # fcc (pdlin's default): Kalidindi, Bronkhorst & Anand (1992), OFHC copper.
    "fcc": {"h0": 180.0, "s0": 16.0, "ss": 148.0, "a": 2.25, "q": 1.4},
    # hcp (pdlin's default): the WE43 values of Javaheri et al. (2022) are only in its
    # ref. [18] (not available), so these are *placeholders*: the hardening law of
    # Luo, Ramazani & Sundararaghavan (2017), Eqs. 22-24, with Mg-like CRSS ratios
    # basal : prismatic : pyramidal<a> : pyramidal<c+a> = 1 : 4 : 4 : 8.
    "hcp": {
        "h0": 10.0,
        "s0": {"basal": 10.0, "prismatic": 40.0, "pyramidal_a": 40.0, "pyramidal_ca": 80.0},
        "ss": {"basal": 200.0, "prismatic": 200.0, "pyramidal_a": 200.0, "pyramidal_ca": 300.0},
        "a": 2.0,
        "q": 1.4,
    },
}
#: Default c/a of the hcp lattice (pdlin's default): pure Mg (WE43 is within 0.1 %).
DEFAULT_C_OVER_A = 1.624

_ELASTIC_KEYS = {
    "planar-2": ("D11", "D22", "D12", "D33"),
    "fcc": ("C11", "C12", "C44"),
    "hcp": ("C11", "C12", "C13", "C33", "C44"),
}
_POSITIVE_KEYS = {"D11", "D22", "D33", "C11", "C33", "C44"}


# ---------------------------------------------------------------------------------------
# slip systems and orientations


def _mb_direction(u: float, v: float, t: float, w: float, c: float) -> FloatArray:
    """Cartesian vector of the Miller–Bravais direction [uvtw] (a1 = e1, c ∥ e3)."""
    return np.array([1.5 * u, np.sqrt(3.0) / 2.0 * (v - t), c * w])


def _mb_normal(h: float, k: float, i: float, l: float, c: float) -> FloatArray:  # noqa: E741
    """Cartesian normal of the Miller–Bravais plane (hkil) (reciprocal basis)."""
    return np.array([h, (h + 2.0 * k) / np.sqrt(3.0), l / c])


_HCP_SYSTEMS = (
    # basal {0001}<11-20>
    ((0, 0, 0, 1), (2, -1, -1, 0)),
    ((0, 0, 0, 1), (-1, 2, -1, 0)),
    ((0, 0, 0, 1), (-1, -1, 2, 0)),
    # prismatic {10-10}<11-20>
    ((1, 0, -1, 0), (-1, 2, -1, 0)),
    ((0, 1, -1, 0), (2, -1, -1, 0)),
    ((-1, 1, 0, 0), (-1, -1, 2, 0)),
    # pyramidal <a> {10-11}<11-20>
    ((1, 0, -1, 1), (-1, 2, -1, 0)),
    ((0, 1, -1, 1), (-2, 1, 1, 0)),
    ((-1, 1, 0, 1), (-1, -1, 2, 0)),
    ((-1, 0, 1, 1), (1, -2, 1, 0)),
    ((0, -1, 1, 1), (2, -1, -1, 0)),
    ((1, -1, 0, 1), (1, 1, -2, 0)),
    # pyramidal <c+a> {11-22}<11-23>
    ((1, 1, -2, 2), (-1, -1, 2, 3)),
    ((-1, 2, -1, 2), (1, -2, 1, 3)),
    ((-2, 1, 1, 2), (2, -1, -1, 3)),
    ((-1, -1, 2, 2), (1, 1, -2, 3)),
    ((1, -2, 1, 2), (-1, 2, -1, 3)),
    ((2, -1, -1, 2), (-2, 1, 1, 3)),
)

_FCC_SYSTEMS = (
    ((1, 1, 1), (0, 1, -1)),
    ((1, 1, 1), (1, 0, -1)),
    ((1, 1, 1), (1, -1, 0)),
    ((-1, 1, 1), (0, 1, -1)),
    ((-1, 1, 1), (1, 0, 1)),
    ((-1, 1, 1), (1, 1, 0)),
    ((1, -1, 1), (0, 1, 1)),
    ((1, -1, 1), (1, 0, -1)),
    ((1, -1, 1), (1, 1, 0)),
    ((1, 1, -1), (0, 1, 1)),
    ((1, 1, -1), (1, 0, 1)),
    ((1, 1, -1), (1, -1, 0)),
)


def slip_systems(slip: str, c_over_a: float = DEFAULT_C_OVER_A) -> tuple[FloatArray, FloatArray]:
    """Return the unit slip directions ``m`` and plane normals ``n`` in the crystal frame.

    Parameters
    ----------
    slip : {"planar-2", "fcc", "hcp"}
        ``planar-2``: the two systems at ±π/6 of Luo, Ramazani & Sundararaghavan
        (2017), Section 4, system 1 at φ = +30°, system 2 at −30° (pdlin's labelling),
        ``m = (cos φ, sin φ)``, ``n = (−sin φ, cos φ)``.  ``fcc``: the 12
        {111}<110> systems (cube axes = crystal axes).  ``hcp``: 3 basal, 3 prismatic,
        6 pyramidal <a> {10-11}<11-20> and 6 pyramidal <c+a> {11-22}<11-23> systems,
        ``a1 ∥ e1``, ``c ∥ e3``.
    c_over_a : float
        Axial ratio of the hcp lattice (ignored otherwise).

    Returns
    -------
    m, n : (nslip, d) ndarray

    Examples
    --------
    >>> m, n = slip_systems("planar-2")
    >>> np.round(np.einsum("ai,aj->aij", m, n)[0], 4).tolist()   # S0^1 = m ⊗ n of system 1
    [[-0.433, 0.75], [-0.25, 0.433]]
    >>> [slip_systems(s)[0].shape for s in ("fcc", "hcp")]
    [(12, 3), (18, 3)]
    """
    if slip == "planar-2":
        phi = np.radians([30.0, -30.0])
        m = np.stack([np.cos(phi), np.sin(phi)], axis=1)
        n = np.stack([-np.sin(phi), np.cos(phi)], axis=1)
        return m, n
    if slip == "fcc":
        n = np.array([s[0] for s in _FCC_SYSTEMS], dtype=np.float64)
        m = np.array([s[1] for s in _FCC_SYSTEMS], dtype=np.float64)
    elif slip == "hcp":
        c = float(c_over_a)
        if not np.isfinite(c) or c <= 0.0:
            raise InputError(f"c_over_a must be > 0, got {c_over_a!r}")
        n = np.array([_mb_normal(*s[0], c) for s in _HCP_SYSTEMS])
        m = np.array([_mb_direction(*s[1], c) for s in _HCP_SYSTEMS])
    else:
        raise InputError(f"slip must be one of {sorted(SLIP_FAMILIES)}, got {slip!r}")
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return m, n


def euler_to_rotation(angles: ArrayLike) -> FloatArray:
    """Crystal → sample rotations ``R = Rz(φ1) Rx(Φ) Rz(φ2)`` from Bunge Euler angles.

    Parameters
    ----------
    angles : (3,) or (n, 3) array_like of float
        ``(φ1, Φ, φ2)`` in radians.  The Bunge orientation matrix is ``g = Rᵀ``.

    Returns
    -------
    (3, 3) or (n, 3, 3) ndarray

    Examples
    --------
    >>> R = euler_to_rotation([np.pi / 2, 0.0, 0.0])
    >>> np.round(R @ [1.0, 0.0, 0.0], 12).tolist()   # crystal e1 lies along sample e2
    [0.0, 1.0, 0.0]
    """
    from scipy.spatial.transform import Rotation

    a = np.asarray(angles, dtype=np.float64)
    if a.shape[-1:] != (3,) or a.ndim > 2:
        raise ShapeError(f"angles must have shape (3,) or (n, 3), got {a.shape}")
    check_finite(a, "angles")
    return np.asarray(Rotation.from_euler("ZXZ", a).as_matrix(), dtype=np.float64)


#: points per chunk of the threaded :meth:`CrystalPlasticity.update` (fixed: the results do
#: not depend on the thread count; smaller chunks cost more Python overhead per point)
_UPDATE_CHUNK = 8192
#: smallest batch of points that :meth:`CrystalPlasticity.update` sends to the numba
#: kernel of planar double slip: one full chunk; below it numba's import (~1 s) and, on a
#: first run, the kernels' compilation (~100 s on a loaded machine for the gallery's
#: 625-point cp_compression) cost more than the kernel saves (~0.4 µs a point per update)
_NUMBA_MIN_POINTS = _UPDATE_CHUNK
#: Newton iterations of the rate-dependent slip update per point (far from the root each
#: iteration lowers ln|τ/s| by about 1/n: a trial 50 % over the resistance at n = 100 takes ≈ 40)
_RATE_MAXITER = 200
#: points from which the local Newton of the power law runs compiled (numba installed)
_RATE_NUMBA_MIN_POINTS = 256


def compiles_kernels(n_points: int) -> bool:
    """Return whether an update of ``n_points`` points may use (and compile) numba kernels.

    True from one full update chunk of points on, when numba is installed and not
    switched off (``PDLIN_NUMBA=0``); the command line uses it to plan memory.

    Parameters
    ----------
    n_points : int
        Number of material points updated together.

    Returns
    -------
    bool
        Whether the compiled path applies.

    Examples
    --------
    >>> compiles_kernels(100)
    False
    """
    from .._kernels import numba_enabled

    return n_points >= _NUMBA_MIN_POINTS and numba_enabled()


def _rows_of(state: Mapping[str, Any], idx: NDArray[np.intp], n: int) -> dict[str, Any]:
    """Return the rows ``idx`` of every per-point array of ``state`` (others as they are)."""
    return {
        k: (v[idx] if isinstance(v, np.ndarray) and v.ndim and len(v) == n else v)
        for k, v in state.items()
    }


def _degenerate(exc: ZeroDivisionError) -> NonFiniteError:
    """Return the error of a compiled update that divided by zero (numpy gives inf / nan)."""
    return NonFiniteError(
        "CrystalPlasticity: the compiled update divided by zero at a degenerate deformation "
        f"gradient (e.g. det F = 0): P would not be finite ({exc})"
    )


def _time_increment(state: Mapping[str, Any]) -> float | None:
    """Return the time increment ``state["dt"]`` of a rate-dependent update (None: absent)."""
    if "dt" not in state:
        return None
    dt = state["dt"]
    try:
        v = float(np.asarray(dt, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise InputError(f"state_n['dt'] must be a number >= 0, got {dt!r}") from exc
    if not np.isfinite(v) or v < 0.0:
        raise InputError(f"state_n['dt'] must be a finite number >= 0, got {v!r}")
    return v


def _rotation_2d(theta: FloatArray) -> FloatArray:
    """Rotation matrices ``[[cos θ, -sin θ], [sin θ, cos θ]]``, shape ``θ.shape + (2, 2)``.

    Examples
    --------
    >>> _rotation_2d(np.array([0.0, np.pi / 2])).round(12).tolist()
    [[[1.0, 0.0], [0.0, 1.0]], [[0.0, -1.0], [1.0, 0.0]]]
    """
    c, s = np.cos(theta), np.sin(theta)
    out = np.empty(np.shape(theta) + (2, 2), dtype=np.result_type(c, s))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    return out


def _orientation_arrays(
    orientation: Any, n: int, dim: int, name: str = "orientation"
) -> tuple[FloatArray, FloatArray | None]:
    """(R (n, d, d), θ (n,) in 2D or None) of an orientation argument."""
    try:
        o = np.asarray(orientation, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric, got {type(orientation).__name__}") from exc
    check_finite(o, name)
    if dim == 2:
        if o.ndim == 0 or o.shape == (n,):
            theta = np.broadcast_to(o, (n,)).astype(np.float64)
            return _rotation_2d(theta), theta
        raise ShapeError(
            f"{name} must be a scalar angle or have shape ({n},) (one angle per point), "
            f"got shape {o.shape}"
        )
    if o.shape == (3, 3) or (o.ndim == 3 and o.shape[1:] == (3, 3) and o.shape[0] in (1, n)):
        R = np.broadcast_to(o, (n, 3, 3)).copy()
        err = float(np.max(np.abs(R.transpose(0, 2, 1) @ R - np.eye(3)), initial=0.0))
        det = np.linalg.det(R) if n else np.ones(0)
        if err > 1e-8 or np.any(det < 0.0):
            raise InputError(
                f"{name} must hold proper rotation matrices (RᵀR = I, det R = +1), got "
                f"max |RᵀR - I| = {err:.3g}, min det = {float(np.min(det, initial=1.0)):.3g}"
            )
        return R, None
    if o.shape == (3,) or (o.ndim == 2 and o.shape == (n, 3)):
        return np.broadcast_to(euler_to_rotation(o), (n, 3, 3)).copy(), None
    if o.ndim == 0 and float(o) == 0.0:
        return np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), None
    raise ShapeError(
        f"{name} must be rotation matrices (3, 3) / ({n}, 3, 3) or Bunge Euler angles "
        f"(3,) / ({n}, 3), got shape {o.shape}"
    )


# ---------------------------------------------------------------------------------------
# small batched helpers


def _T(a: NDArray[Any]) -> NDArray[Any]:
    return np.swapaxes(a, -1, -2)


def _mm(a: NDArray[Any], b: NDArray[Any]) -> NDArray[Any]:
    """Multiply stacks of matrices, ``a @ b`` with numpy broadcasting of the leading axes.

    A closed form for stacks of 2 × 2 matrices (5x faster than matmul).

    Examples
    --------
    >>> a = np.arange(8.0).reshape(2, 2, 2); b = a[::-1]
    >>> bool(np.array_equal(_mm(a, b), a @ b))
    True
    >>> c = np.arange(24.0).reshape(2, 3, 2, 2)
    >>> bool(np.array_equal(_mm(a[:, None], c), a[:, None] @ c))
    True
    """
    if a.ndim >= 2 and b.ndim >= 2 and a.shape[-2:] == (2, 2) and b.shape[-2:] == (2, 2):
        out = np.empty(np.broadcast_shapes(a.shape, b.shape), np.result_type(a, b))
        a00, a01, a10, a11 = a[..., 0, 0], a[..., 0, 1], a[..., 1, 0], a[..., 1, 1]
        b00, b01, b10, b11 = b[..., 0, 0], b[..., 0, 1], b[..., 1, 0], b[..., 1, 1]
        out[..., 0, 0] = a00 * b00 + a01 * b10
        out[..., 0, 1] = a00 * b01 + a01 * b11
        out[..., 1, 0] = a10 * b00 + a11 * b10
        out[..., 1, 1] = a10 * b01 + a11 * b11
        return out
    return np.asarray(a @ b)


def _inv(a: NDArray[Any]) -> NDArray[Any]:
    """Batched inverse; closed form for 2 × 2 (much faster than LAPACK for tiny blocks)."""
    if a.shape[-1] == 2:
        det = a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
        out = np.empty_like(a)
        out[..., 0, 0] = a[..., 1, 1] / det
        out[..., 1, 1] = a[..., 0, 0] / det
        out[..., 0, 1] = -a[..., 0, 1] / det
        out[..., 1, 0] = -a[..., 1, 0] / det
        return out
    return np.linalg.inv(a)


def _det(a: NDArray[Any]) -> NDArray[Any]:
    if a.shape[-1] == 2:
        return a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
    return np.linalg.det(a)


def _solve(A: NDArray[Any], b: NDArray[Any]) -> NDArray[Any]:
    """Batched solve of (m, k, k) x = (m, k); pseudo-inverse where a matrix is singular.

    2 × 2 systems (planar double slip) by Cramer's rule, ~10x faster than LAPACK's
    batched solve for such tiny blocks.

    Examples
    --------
    >>> A = np.array([[[2.0, 1.0], [1.0, 3.0]], [[1.0, 0.0], [0.0, 0.0]]])
    >>> _solve(A, np.array([[3.0, 4.0], [2.0, 5.0]])).tolist()  # 2nd: singular, pinv
    [[1.0, 1.0], [2.0, 0.0]]
    """
    if A.shape[-2:] == (2, 2) and A.ndim == 3:
        a00, a01, a10, a11 = A[:, 0, 0], A[:, 0, 1], A[:, 1, 0], A[:, 1, 1]
        det = _det(A)
        scale = np.maximum(np.abs(a00 * a11), np.abs(a01 * a10))
        ok = np.abs(det) > 1e-14 * scale
        if np.all(ok):
            x = np.empty(b.shape, dtype=np.result_type(A, b))
            x[:, 0] = (a11 * b[:, 0] - a01 * b[:, 1]) / det
            x[:, 1] = (a00 * b[:, 1] - a10 * b[:, 0]) / det
            return x
    try:
        x = np.linalg.solve(A, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        x = (np.linalg.pinv(A) @ b[..., None])[..., 0]
    return x


def _set_code(act: NDArray[np.bool_], sgn: FloatArray, bits: NDArray[np.int64]) -> NDArray[Any]:
    """One integer per point encoding its active set and the slip signs on it."""
    return np.asarray(act @ bits + (act & (sgn < 0.0)) @ (bits << bits.size))


def cauchy_stress(P: ArrayLike, F: ArrayLike) -> FloatArray:
    """Return the Cauchy stress ``σ = P Fᵀ / det F`` of first Piola–Kirchhoff stresses.

    Parameters
    ----------
    P, F : (..., d, d) array_like of float
        First Piola–Kirchhoff stresses and deformation gradients (same shape).

    Returns
    -------
    (..., d, d) ndarray
        Cauchy stresses.

    Raises
    ------
    ShapeError
        ``P`` and ``F`` differ in shape or are not stacks of square matrices.

    Examples
    --------
    >>> F = np.diag([2.0, 1.0]); P = np.diag([4.0, 0.0])
    >>> cauchy_stress(P, F).tolist()
    [[4.0, 0.0], [0.0, 0.0]]
    """
    p = np.asarray(P, dtype=np.float64)
    f = np.asarray(F, dtype=np.float64)
    if p.shape != f.shape or p.ndim < 2 or p.shape[-1] != p.shape[-2]:
        raise ShapeError(
            f"P and F must have the same shape (..., d, d), got P {p.shape} and F {f.shape}"
        )
    return np.asarray(_mm(p, _T(f)) / _det(f)[..., None, None], dtype=np.float64)


def _von_mises(sigma: FloatArray) -> FloatArray:
    if sigma.shape[-1] == 2:
        # 2D: σ33 = 0 in the von Mises stress (pdlin's convention; the paper only names
        # the von Mises stress, footnote in its Section 4.3)
        sxx, syy, sxy = sigma[..., 0, 0], sigma[..., 1, 1], sigma[..., 0, 1]
        return np.asarray(np.sqrt(sxx**2 - sxx * syy + syy**2 + 3.0 * sxy**2))
    dev = sigma - np.trace(sigma, axis1=-2, axis2=-1)[..., None, None] / 3.0 * np.eye(3)
    return np.asarray(np.sqrt(1.5 * np.einsum("...ij,...ij->...", dev, dev)))


def _check_F(F: Any, dim: int) -> FloatArray:
    f = np.asarray(F, dtype=np.float64)
    if f.ndim != 3 or f.shape[1:] != (dim, dim):
        raise ShapeError(f"F must have shape (n, {dim}, {dim}), got {f.shape}")
    check_finite(f, "F")
    return f


# ---------------------------------------------------------------------------------------
# Saint Venant–Kirchhoff


class SaintVenantKirchhoff:
    """Hyperelastic Saint Venant–Kirchhoff material ``S = C : E``, ``P = F S``.

    Same interface as :class:`CrystalPlasticity` (the state is empty), useful to test the
    nonlinear drivers (the energy ``Ψ = ½ E : C : E`` is provided, so that a tangent can be
    checked against the energy's derivatives).

    Parameters
    ----------
    C : (3, 3), (6, 6), (2, 2, 2, 2) or (3, 3, 3, 3) array_like of float
        Symmetric positive-definite stiffness (plain Voigt, see :mod:`pdlin.constitutive`).

    Examples
    --------
    >>> mat = SaintVenantKirchhoff(np.array([[2000.0, 1000, 0], [1000, 2000, 0], [0, 0, 500]]))
    >>> F = np.array([[[1.001, 0.0], [0.0, 1.0]]])
    >>> P, state, D = mat.update(F, mat.initial_state(1), tangent=True)
    >>> round(float(P[0, 0, 0]), 6), D.shape
    (2.003001, (1, 2, 2, 2, 2))
    """

    def __init__(self, C: ArrayLike) -> None:
        arr = check_stiffness(C, "C")
        self.C: FloatArray = (
            _voigt_to_tensor_unchecked(arr) if arr.ndim == 2 else np.array(arr, dtype=np.float64)
        )
        self.dim = int(self.C.shape[0])

    def __repr__(self) -> str:
        """Class, dimension and stiffness size (no arrays, no memory address)."""
        return compact_repr("SaintVenantKirchhoff", {"dim": self.dim, "C": self.C})

    def initial_state(self, n: int) -> dict[str, FloatArray]:
        """Return the empty state (the material has no internal variables).

        Parameters
        ----------
        n : int
            Number of points (unused).

        Returns
        -------
        dict
            An empty dict.
        """
        return {}

    def energy(self, F: ArrayLike) -> FloatArray:
        """Return the strain energy density ``Ψ = ½ E : C : E`` per point.

        Parameters
        ----------
        F : (n, d, d) array_like
            Deformation gradients.

        Returns
        -------
        (n,) ndarray
            ``Ψ`` per point (stress x strain units, e.g. MPa).
        """
        f = _check_F(F, self.dim)
        E = 0.5 * (_T(f) @ f - np.eye(self.dim))
        S = np.einsum("ijkl,nkl->nij", self.C, E)
        return np.asarray(0.5 * np.einsum("nij,nij->n", S, E))

    def update(
        self,
        F: ArrayLike,
        state_n: Mapping[str, FloatArray] | None = None,
        *,
        tangent: bool = False,
    ) -> tuple[FloatArray, dict[str, FloatArray], FloatArray | None]:
        """Return the first Piola–Kirchhoff stress and, on request, its tangent.

        Parameters
        ----------
        F : (n, d, d) array_like
            Deformation gradients.
        state_n : mapping, optional
            Ignored (the material has no state).
        tangent : bool
            Also return ``dP/dF``.

        Returns
        -------
        P : (n, d, d) ndarray
            ``P = F S``, ``S = C : E``.
        state : dict
            An empty dict.
        dPdF : (n, d, d, d, d) ndarray or None
            ``dP_ij/dF_kl = δ_ik S_lj + F_ia C_ajbl F_kb`` (None unless ``tangent``).
        """
        f = _check_F(F, self.dim)
        d = self.dim
        E = 0.5 * (_T(f) @ f - np.eye(d))
        S = np.einsum("ijkl,nkl->nij", self.C, E)
        P = f @ S
        D = None
        if tangent:
            D = np.einsum("ik,nlj->nijkl", np.eye(d), S) + np.einsum(
                "nia,ajbl,nkb->nijkl", f, self.C, f, optimize=True
            )
        return P, {}, D

    @staticmethod
    def cauchy(P: ArrayLike, F: ArrayLike) -> FloatArray:
        """Return the Cauchy stress ``P Fᵀ / det F``.

        Parameters
        ----------
        P, F : (..., d, d) array_like of float
            First Piola–Kirchhoff stresses and deformation gradients.

        Returns
        -------
        (..., d, d) ndarray
            Cauchy stresses.
        """
        return cauchy_stress(P, F)


# ---------------------------------------------------------------------------------------
# crystal plasticity


def _per_system(value: Any, key: str, families: tuple[tuple[str, int], ...]) -> FloatArray:
    """Expand a scalar / per-family mapping / per-family sequence to one value per system."""
    names = [f for f, _ in families]
    counts = [k for _, k in families]
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - set(names))
        missing = [f for f in names if f not in value]
        if unknown or missing:
            raise InputError(
                f"hardening[{key!r}] must map every slip family {names} to a number, got "
                f"keys {sorted(value)}"
            )
        vals = [value[f] for f in names]
    elif np.ndim(value) == 0:
        vals = [value] * len(names)
    else:
        vals = list(np.asarray(value, dtype=np.float64).ravel())
        if len(vals) != len(names):
            raise ShapeError(
                f"hardening[{key!r}] must be a scalar or have one value per family "
                f"({len(names)}: {names}), got {len(vals)}"
            )
    try:
        arr = np.repeat(np.asarray(vals, dtype=np.float64), counts)
    except (TypeError, ValueError) as exc:
        raise InputError(f"hardening[{key!r}] must be numeric, got {value!r}") from exc
    check_finite(arr, f"hardening[{key!r}]")
    return arr


class CrystalPlasticity:
    """Rate-independent single-crystal plasticity with Anand–Kothari return mapping.

    Luo, Ramazani & Sundararaghavan (2017), Section 3: multiplicative ``F = Fᵉ Fᵖ``,
    St Venant–Kirchhoff elasticity of ``T̄ = 𝓛ᵉ[½(FᵉᵀFᵉ − I)]`` in the intermediate
    (lattice) frame, resolved shear ``τ^α = T̄ : S₀^α``, hardening
    ``h^{αβ} = h₀^β (q + (1 − q) δ^{αβ}) (1 − s^β/s_s^β)^a``, active-set return mapping
    of the paper's Appendix (Eqs. 26-34; in pdlin's reading the consistency condition of
    the garbled Eq. 32 is ``|τ^α| = s_n^α + Σ_β h^{αβ} Δγ^β``, a system is active when
    ``|τ_tr^α| > s^α`` and ``h`` is evaluated at the committed ``s_n``).

    Parameters
    ----------
    slip : {"planar-2", "fcc", "hcp"}
        Lattice and slip systems (:func:`~pdlin.constitutive.slip_systems`); ``planar-2``
        is 2D (plane strain, out-of-plane stress not modelled), the others 3D.
    elastic : mapping or array_like, optional
        Crystal-frame stiffness.  A mapping of constants: ``planar-2`` ``D11, D22, D12,
        D33`` (2D Voigt); ``fcc`` ``C11, C12, C44``; ``hcp`` ``C11, C12, C13,
        C33, C44`` (c ∥ e3).  Or a plain-Voigt matrix (3 × 3 / 6 × 6) or a full tensor.
        Defaults: Luo, Ramazani & Sundararaghavan (2017), Section 4 (planar-2), OFHC
        copper (fcc, pdlin's default after Kalidindi, Bronkhorst & Anand 1992), Mg of
        Javaheri, Luo, Lakshmanan & Sundararaghavan (2022), Section III.C (hcp), all in
        MPa.
    hardening : mapping, optional
        Keys ``h0, s0, ss, a, q`` (missing keys keep their defaults); each a scalar, a
        mapping family → value or a sequence with one value per family
        (:data:`~pdlin.constitutive.SLIP_FAMILIES`); ``q`` is the latent factor of the
        hardening system β.
        Defaults: Luo, Ramazani & Sundararaghavan 2017, Eqs. 22-24 (planar-2); copper (fcc) and
        placeholders (hcp), pdlin's defaults (see
        ``docs/crystal_plasticity.md``).
    orientation : float, array_like
        Default orientation of :meth:`initial_state`: 2D angle θ (radians, scalar or
        ``(n,)``); 3D rotation matrices ``(3, 3)``/``(n, 3, 3)`` or Bunge Euler angles
        ``(3,)``/``(n, 3)`` (crystal → sample).
    shear : {"engineering", "tensor"}
        How the shear entries of a Voigt/constant ``elastic`` act (the paper does not say):
        ``engineering`` (default) ``T̄12 = D33 · 2Ē12``; ``tensor`` ``T̄12 = D33 Ē12``.
    renormalize : bool
        Rescale ``Fᵖ`` to ``det Fᵖ = 1`` after each update (default off, as in the paper's
        update, whose ``det Fᵖ`` drifts by about 6e-6 per 0.002 step in double slip).
    c_over_a : float
        hcp axial ratio (default 1.624, Mg; pdlin's default).
    tangent : {"analytic", "complex-step"}
        How ``update(..., tangent=True)`` computes dP/dF (both are the consistent
        tangent; they agree to ≈1e-15 relative).
    tangent_step : float
        Step of the complex-step tangent.
    active_set : {"auto", "reactivate", "prune"}
        Active-set search.  ``prune`` is the paper's Appendix as written: start from the
        potentially active set, drop every system with ``Δγ ≤ 0`` and re-solve until no
        point changes (a dropped system is never re-activated).  ``reactivate``
        then checks ``τ^α`` of the final state on the inactive systems and adds back those
        with ``|τ^α| > s^α (1 + yield_tol)`` (``s^α`` the updated resistance, slip sign
        of the final ``τ^α``), re-solving and pruning again, until no point changes
        (Anand & Kothari 1996; Miehe & Schröder 2001).  Both give identical results
        wherever pruning leaves no inactive system over the yield surface (all
        ``planar-2`` material-point reference paths of docs/crystal_plasticity.md).
        ``auto`` (default): ``prune`` for ``planar-2`` (Luo, Ramazani & Sundararaghavan
        2017; its two systems span the 2D deviatoric space, and the re-activation passes
        make the force non-smooth enough on far-from-equilibrium ADR iterates that a
        plastic polycrystal step stalled at e₁ ≈ 1.5e-5 with them and converged
        without), ``reactivate`` for ``fcc`` and ``hcp`` (pruning alone left inactive
        systems up to 100 % over their resistance).
    yield_tol : float
        Relative tolerance of the re-activation check (default 1e-4).
    max_passes : int
        Cap on the re-activation passes per update (default 20).  A point that still
        violates the yield condition after the cap, or that revisits an earlier active
        set (a cycle of the search), is *unsettled*: it keeps the visited solution with the
        smallest violation, ``state["unsettled"]`` flags it and
        :class:`~pdlin.errors.ActiveSetWarning` is issued naming how many points did not
        settle (turn it into an error with
        ``warnings.simplefilter("error", ActiveSetWarning)``).
    rate_exponent : float, optional
        Exponent ``n`` of a rate-dependent (power-law) slip rule,
        ``γ̇^α = γ̇₀ |τ^α / s^α|ⁿ sign τ^α`` on every system (Peirce, Asaro & Needleman
        1983; Kalidindi, Bronkhorst & Anand 1992), integrated by backward Euler:
        ``Δγ^α = γ̇₀ Δt |τ^α / s^α|ⁿ sign τ^α`` with ``τ^α`` and ``s^α`` at the end of the
        increment (the same Eq. 31 linearization of ``τ`` in the slips and hardening at
        the committed ``s_n`` as the rate-independent update).  There is no active set:
        the stress is a smooth function of ``F``, which lets Newton carry plastic steps
        that the rate-independent active-set switches stall (docs/crystal_plasticity.md,
        "Rate-dependent regularization").  Large ``n`` (50-200) approaches the
        rate-independent model (the flow stress at slip rate ``γ̇`` is
        ``s (γ̇/γ̇₀)^{1/n}``).  The time increment is ``state_n["dt"]`` (the load-step
        drivers set it; :func:`material_point` uses 1 per step).  Default None: the
        paper's rate-independent model.
    reference_rate : float
        Reference slip rate ``γ̇₀`` of ``rate_exponent``, in 1 / (the load steps' time
        unit) (default 1).

    Notes
    -----
    The consistent tangent is the exact linearization of the return mapping (the paper's
    Appendix) with the active set and slip signs of the real solve (after pruning and
    re-activation) frozen (valid wherever the active set does not switch).
    ``analytic`` (default): forward-mode chain rule, ``dΔγ = A⁻¹(db − dA Δγ)`` with one
    factorization of ``A`` and ``d²`` right-hand sides per point.  ``complex-step``: the
    same derivative as ``Im P(F + i h E_kl) / h`` of the pure update (``d²`` complex
    updates per point, ≈2–4× slower), kept as an independent check.

    Examples
    --------
    The elastic first step of pure shear at θ = 0 (η = 0.002, the paper's Section 4.1).

    >>> from scipy.linalg import expm
    >>> mat = CrystalPlasticity()
    >>> F = expm(0.002 * np.array([[0.0, 1.0], [1.0, 0.0]]))[None]
    >>> P, state, _ = mat.update(F, mat.initial_state(1))
    >>> round(float(mat.cauchy(P, F)[0, 0, 1]), 6)          # 8.000133 (pdlin's reference value)
    8.000133
    >>> mat.nslip, sorted(state)[:4]
    (2, ['Fp', 'R', 'R0', 'dep'])
    """

    def __init__(
        self,
        slip: str = "planar-2",
        elastic: Mapping[str, float] | ArrayLike | None = None,
        hardening: Mapping[str, Any] | None = None,
        orientation: ArrayLike = 0.0,
        *,
        shear: str = "engineering",
        renormalize: bool = False,
        c_over_a: float = DEFAULT_C_OVER_A,
        tangent: str = "analytic",
        tangent_step: float = 1e-30,
        active_set: str = "auto",
        yield_tol: float = 1e-4,
        max_passes: int = 20,
        rate_exponent: float | None = None,
        reference_rate: float = 1.0,
    ) -> None:
        if tangent not in ("analytic", "complex-step"):
            raise InputError(f"tangent must be 'analytic' or 'complex-step', got {tangent!r}")
        self.tangent_method = tangent
        if rate_exponent is not None:
            if isinstance(rate_exponent, bool) or not isinstance(
                rate_exponent, int | float | np.number
            ):
                raise InputError(
                    f"rate_exponent must be a number >= 1 or None, got {rate_exponent!r}"
                )
            if not np.isfinite(rate_exponent) or rate_exponent < 1.0:
                raise InputError(
                    f"rate_exponent must be a finite number >= 1 or None, got {rate_exponent!r}"
                )
            if tangent != "analytic":
                raise InputError(
                    "tangent='complex-step' is not available with rate_exponent (the "
                    f"rate-dependent update has the analytic tangent only), got {tangent!r}"
                )
        #: Exponent n of the power-law slip rate (None: rate independent, the paper's).
        self.rate_exponent: float | None = None if rate_exponent is None else float(rate_exponent)
        #: Reference slip rate γ̇₀ (1 / time unit of the load steps).
        self.reference_rate = positive_scalar(reference_rate, "reference_rate")
        #: Whether :meth:`update` reads the time increment ``state_n["dt"]``.
        self.rate_dependent = self.rate_exponent is not None
        if active_set not in ("auto", "reactivate", "prune"):
            raise InputError(
                f"active_set must be 'auto', 'reactivate' or 'prune', got {active_set!r}"
            )
        if active_set == "auto":
            active_set = "prune" if slip == "planar-2" else "reactivate"
        self.active_set = active_set
        self.yield_tol = float(yield_tol)
        if not np.isfinite(self.yield_tol) or self.yield_tol < 0.0:
            raise InputError(f"yield_tol must be a finite number >= 0, got {yield_tol!r}")
        if isinstance(max_passes, bool) or int(max_passes) != max_passes or max_passes < 0:
            raise InputError(f"max_passes must be an integer >= 0, got {max_passes!r}")
        self.max_passes = int(max_passes)
        if not isinstance(slip, str) or slip not in SLIP_FAMILIES:
            raise InputError(f"slip must be one of {sorted(SLIP_FAMILIES)}, got {slip!r}")
        if shear not in ("engineering", "tensor"):
            raise InputError(f"shear must be 'engineering' or 'tensor', got {shear!r}")
        self.slip = slip
        self.shear = shear
        self.renormalize = bool(renormalize)
        self.c_over_a = float(c_over_a)
        self.tangent_step = positive_scalar(tangent_step, "tangent_step")
        self.dim = 2 if slip == "planar-2" else 3
        self.families = SLIP_FAMILIES[slip]
        self.m, self.n = slip_systems(slip, self.c_over_a)
        self.nslip = int(self.m.shape[0])
        self.family = np.repeat(np.arange(len(self.families)), [k for _, k in self.families])
        #: Schmid tensors S₀^α = m^α ⊗ n^α, (nslip, d, d), crystal frame.
        self.S0: FloatArray = np.einsum("ai,aj->aij", self.m, self.n)
        self.C: FloatArray = self._stiffness(elastic)
        self._set_hardening(hardening)
        d2 = self.dim * self.dim
        self._Cflat = self.C.reshape(d2, d2)
        self._S0flat = self.S0.reshape(self.nslip, d2)
        # 𝓛ᵉ[S₀^α] (symmetric because of the minor symmetry of C), flattened
        self._CS0flat = self._S0flat @ self._Cflat.T
        # A_el^{αβ} = (Ce S₀^β) : 𝓛[S₀^α] = Σ_ik Ce_ik M^{αβ}_ik with
        # M^{αβ}_ik = Σ_j S₀^β_kj 𝓛[S₀^α]_ij: one GEMM per batch instead of an einsum
        CS0 = self._CS0flat.reshape(self.nslip, self.dim, self.dim)
        self._AelM = np.einsum("bkj,aij->abik", self.S0, CS0).reshape(
            self.nslip * self.nslip, self.dim * self.dim
        )
        self.orientation = orientation
        _orientation_arrays(orientation, n_orientations(orientation, self.dim) or 1, self.dim)

    def __repr__(self) -> str:
        """Lattice, slip systems and options (no arrays, no memory address).

        Examples
        --------
        >>> CrystalPlasticity("fcc")
        CrystalPlasticity(slip='fcc', dim=3, nslip=12, orientation=0, active_set='reactivate')
        """
        orientation = np.asarray(self.orientation)
        return compact_repr(
            "CrystalPlasticity",
            {
                "slip": self.slip,
                "dim": self.dim,
                "nslip": self.nslip,
                "orientation": orientation if orientation.ndim else orientation.item(),
                "active_set": None if self.rate_dependent else self.active_set,
                "rate_exponent": self.rate_exponent,
                "reference_rate": self.reference_rate if self.rate_dependent else None,
                "shear": None if self.shear == "engineering" else self.shear,
                "renormalize": self.renormalize or None,
            },
        )

    # -- construction helpers ----------------------------------------------------------
    def _stiffness(self, elastic: Any) -> FloatArray:
        d = self.dim
        if elastic is None:
            elastic = _DEFAULT_ELASTIC[self.slip]
        if isinstance(elastic, Mapping):
            keys = _ELASTIC_KEYS[self.slip]
            unknown = sorted(set(elastic) - set(keys))
            missing = [
                k for k in keys if k not in elastic and not (k == "D22" and "D11" in elastic)
            ]
            if unknown or missing:
                raise InputError(
                    f"elastic must give the constants {list(keys)} for slip={self.slip!r} "
                    f"(D22 defaults to D11), got keys {sorted(elastic)}"
                )
            c: dict[str, float] = {}
            for k, v in elastic.items():
                try:
                    c[k] = float(v)
                except (TypeError, ValueError) as exc:
                    raise InputError(f"elastic[{k!r}] must be a number, got {v!r}") from exc
                if not np.isfinite(c[k]):
                    raise InputError(f"elastic[{k!r}] must be finite, got {c[k]}")
                if k in _POSITIVE_KEYS and c[k] <= 0.0:
                    raise InputError(f"elastic[{k!r}] must be > 0, got {c[k]}")
            if self.slip == "planar-2":
                c.setdefault("D22", c["D11"])
                V = np.array(
                    [[c["D11"], c["D12"], 0.0], [c["D12"], c["D22"], 0.0], [0.0, 0.0, c["D33"]]]
                )
            elif self.slip == "fcc":
                a, b, s = c["C11"], c["C12"], c["C44"]
                V = np.array(
                    [[a, b, b, 0, 0, 0], [b, a, b, 0, 0, 0], [b, b, a, 0, 0, 0],
                     [0, 0, 0, s, 0, 0], [0, 0, 0, 0, s, 0], [0, 0, 0, 0, 0, s]],
                    dtype=np.float64,
                )  # fmt: skip
            else:
                a, b, e, z, s = c["C11"], c["C12"], c["C13"], c["C33"], c["C44"]
                h = 0.5 * (a - b)
                V = np.array(
                    [[a, b, e, 0, 0, 0], [b, a, e, 0, 0, 0], [e, e, z, 0, 0, 0],
                     [0, 0, 0, s, 0, 0], [0, 0, 0, 0, s, 0], [0, 0, 0, 0, 0, h]],
                    dtype=np.float64,
                )  # fmt: skip
        else:
            try:
                V = np.asarray(elastic, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise InputError(
                    f"elastic must be a mapping of constants or a stiffness array, got "
                    f"{type(elastic).__name__}"
                ) from exc
            ok = ((3, 3), (2, 2, 2, 2)) if d == 2 else ((6, 6), (3, 3, 3, 3))
            if V.shape not in ok:
                raise ShapeError(
                    f"elastic must have shape {ok[0]} (Voigt) or {ok[1]} (full tensor) for "
                    f"slip={self.slip!r}, got {V.shape}"
                )
            if V.ndim == 4:
                V = _tensor_to_voigt_unchecked(check_stiffness(V, "elastic"))
        if self.shear == "tensor":
            V = V.copy()
            V[:, d:] *= 0.5  # the shear columns multiply tensor (not engineering) strains
        V = check_stiffness(V, "elastic")
        return _voigt_to_tensor_unchecked(V)

    def _set_hardening(self, hardening: Mapping[str, Any] | None) -> None:
        params = dict(_DEFAULT_HARDENING[self.slip])
        if hardening is not None:
            if not isinstance(hardening, Mapping):
                raise InputError(
                    f"hardening must be a mapping with keys h0, s0, ss, a, q, got "
                    f"{type(hardening).__name__}"
                )
            unknown = sorted(set(hardening) - set(params))
            if unknown:
                raise InputError(
                    f"hardening keys must be among ['a', 'h0', 'q', 's0', 'ss'], got {unknown}"
                )
            params.update(hardening)
        fam = self.families
        self.h0 = _per_system(params["h0"], "h0", fam)
        self.s0 = _per_system(params["s0"], "s0", fam)
        self.ss = _per_system(params["ss"], "ss", fam)
        self.a = _per_system(params["a"], "a", fam)
        self.q = _per_system(params["q"], "q", fam)
        for key, arr, lo in (("h0", self.h0, "≥ 0"), ("s0", self.s0, "> 0"), ("a", self.a, "≥ 0")):
            bad = arr < 0.0 if lo == "≥ 0" else arr <= 0.0
            if np.any(bad):
                raise InputError(f"hardening[{key!r}] must be {lo}, got {arr[bad][0]}")
        if np.any(self.ss <= self.s0):
            i = int(np.argmax(self.ss <= self.s0))
            raise InputError(
                f"hardening['ss'] must be > s0 on every system, got ss = {self.ss[i]} <= "
                f"s0 = {self.s0[i]} (system {i})"
            )
        N = self.nslip
        #: latent matrix Q^{αβ} = q^β + (1 − q^β) δ^{αβ}
        self.Q = np.where(np.eye(N, dtype=bool), 1.0, np.broadcast_to(self.q, (N, N)))

    # -- state ------------------------------------------------------------------------
    def initial_state(self, n: int, orientation: ArrayLike | None = None) -> dict[str, FloatArray]:
        """Return the committed state of ``n`` points at the start of the loading.

        Keys: ``Fp`` (n, d, d) = I (crystal frame), ``s`` (n, nslip) = s0, ``gamma``
        accumulated slips, ``dgamma`` last increments, ``tau`` resolved shears,
        ``R0``/``R`` initial / current lattice rotation (crystal → sample), ``theta0``,
        ``theta`` (2D, radians), ``reorientation`` (degrees), ``dep``/``ep`` equivalent
        plastic strain increment / accumulated, ``plastic`` (bool as float); after an
        update also ``sign`` (slip signs: sign of τ_tr, or of the final τ for a system
        entered by re-activation), ``pruned`` (potentially active systems left inactive),
        ``reactivated`` (re-activation passes, one entering system each), ``unsettled``
        (1 where the active-set search did not settle, see ``max_passes``) and, in 2D,
        the lattice spin sum ``theta_rate`` (Σ θ̇ Δt, radians).  With ``rate_exponent``
        every loaded system slips a little: ``plastic`` marks the points where some
        ``Δγ^α > 1e-3 γ̇₀ Δt``.

        Parameters
        ----------
        n : int
            Number of points.
        orientation : optional
            Overrides the material's orientation (same forms).

        Returns
        -------
        dict of str to ndarray
            The state arrays named above, one row per point.
        """
        n = int(n)
        if n < 0:
            raise InputError(f"n must be >= 0, got {n}")
        o = self.orientation if orientation is None else orientation
        R, theta = _orientation_arrays(o, n, self.dim)
        d, N = self.dim, self.nslip
        state: dict[str, FloatArray] = {
            "Fp": np.broadcast_to(np.eye(d), (n, d, d)).copy(),
            "s": np.broadcast_to(self.s0, (n, N)).copy(),
            "gamma": np.zeros((n, N)),
            "dgamma": np.zeros((n, N)),
            "tau": np.zeros((n, N)),
            "R0": R,
            "R": R.copy(),
            "reorientation": np.zeros(n),
            "dep": np.zeros(n),
            "ep": np.zeros(n),
            "plastic": np.zeros(n),
        }
        if theta is not None:
            state["theta0"] = theta.copy()
            state["theta"] = theta.copy()
            state["theta_rate"] = np.zeros(n)
        return state

    def _check_state(self, state: Mapping[str, FloatArray], n: int) -> None:
        d, N = self.dim, self.nslip
        for key, shape in (("Fp", (n, d, d)), ("s", (n, N)), ("gamma", (n, N)), ("R0", (n, d, d))):
            if key not in state:
                raise InputError(
                    f"state_n must contain {key!r} (use initial_state), got keys {sorted(state)}"
                )
            if np.shape(state[key]) != shape:
                raise ShapeError(
                    f"state_n[{key!r}] must have shape {shape} to match F, got "
                    f"{np.shape(state[key])}"
                )
        for key in ("ep", "theta0", "theta", "theta_rate"):  # optional, one value per point
            if key in state and np.shape(state[key]) != (n,):
                raise ShapeError(
                    f"state_n[{key!r}] must have shape ({n},) to match F, got "
                    f"{np.shape(state[key])}"
                )

    # -- return mapping kernel (crystal frame) -----------------------------------------
    def _hardening_matrix(self, s_n: FloatArray) -> FloatArray:
        r = 1.0 - s_n / self.ss
        fac = self.h0 * np.sign(r) * np.abs(r) ** self.a  # (1 − s/ss)^a, sign kept past ss
        return np.asarray(self.Q[None, :, :] * fac[:, None, :])

    def _return_map(
        self,
        Fc: NDArray[Any],
        Fp_n: FloatArray,
        s_n: FloatArray,
        H: FloatArray,
        active: NDArray[np.bool_] | None = None,
        sign: FloatArray | None = None,
        dt: float | None = None,
        g0: FloatArray | None = None,
    ) -> dict[str, Any]:
        """Run the return mapping on a batch (real or complex ``Fc``).

        The update of Luo, Ramazani & Sundararaghavan (2017), Appendix (Eqs. 26-34).

        ``active`` (with ``sign``) freezes the active set and the slip signs (tangent);
        otherwise the active set is searched: the Appendix's pruning, then (``active_set=
        "reactivate"``) re-activation passes until every inactive system satisfies
        ``|τ^α| ≤ s^α (1 + yield_tol)`` at the final state.
        """
        d = self.dim
        m = Fc.shape[0]
        eye = np.eye(d)
        Fe_tr = _mm(Fc, _inv(Fp_n))
        Ce = _mm(_T(Fe_tr), Fe_tr)
        Etr = 0.5 * (Ce - eye)
        tau_tr = Etr.reshape(m, d * d) @ self._CS0flat.T  # τ^α = 𝓛[E] : S₀^α = E : 𝓛[S₀^α]
        if sign is None:
            sgn = np.where(tau_tr.real < 0.0, -1.0, 1.0)
        else:
            sgn = np.array(sign, dtype=np.float64)
        if self.rate_dependent and active is None:
            return self._rate_map(Fc, Fp_n, s_n, H, Ce, tau_tr, dt, g0)
        b = sgn * tau_tr - s_n
        if active is None:
            act = b.real > 0.0
        else:
            act = active.copy()
        trial = act.copy()
        dgam = np.zeros(b.shape, dtype=b.dtype)
        unsettled = np.zeros(m, dtype=bool)
        passes = np.zeros(m, dtype=np.int64)
        idx = np.flatnonzero(act.any(axis=1))
        if idx.size:
            # A^{αβ} = h^{αβ} + ½ sgn_α sgn_β 𝓛[B^β] : S₀^α
            #        = h^{αβ} + sgn_α sgn_β (Ce S₀^β) : 𝓛[S₀^α]
            Ael = self._elastic_slip_matrix(Ce[idx])  # (m, α, β)
            sg = sgn[idx]
            A = H[idx] + sg[:, :, None] * sg[:, None, :] * Ael
            a_ = act[idx]
            if active is not None:
                dg = self._solve_set(A, b[idx], a_, prune=False)
            else:
                dg = self._solve_set(A, b[idx], a_, prune=True)
                if self.active_set == "reactivate":
                    dg, bad, npass = self._reactivate(
                        s_n[idx], H[idx], tau_tr[idx], Ael, trial[idx], sg, a_, dg
                    )
                    sgn[idx] = sg
                    unsettled[idx] = bad
                    passes[idx] = npass
            dgam[idx] = dg
            act[idx] = a_
        return self._mapped(
            Fc, Fp_n, Ce, dgam, sgn, act, (trial & ~act).sum(axis=1), passes, unsettled
        )

    def _mapped(
        self,
        Fc: NDArray[Any],
        Fp_n: FloatArray,
        Ce: NDArray[Any],
        dgam: NDArray[Any],
        sgn: NDArray[Any],
        act: NDArray[np.bool_],
        pruned: NDArray[Any],
        passes: NDArray[Any],
        unsettled: NDArray[np.bool_],
    ) -> dict[str, Any]:
        """Return the final state of slip increments ``dgam`` (signs ``sgn``) as a dict.

        Step 6 of the Appendix: ``Fᵖ = (I + Σ Δγ sgn S₀) Fᵖ_n``, ``Fᵉ = F Fᵖ⁻¹``,
        ``T̄ = 𝓛[½(FᵉᵀFᵉ − I)]``, ``P = Fᵉ T̄ Fᵖ⁻ᵀ``.
        """
        Fp, Fp_inv, Fe, Tbar = self._final_state(Fc, Fp_n, dgam, sgn)
        P = _mm(_mm(Fe, Tbar), _T(Fp_inv))
        return {
            "P": P,
            "Fp": Fp,
            "Fp_inv": Fp_inv,
            "Ce": Ce,
            "Fe": Fe,
            "Tbar": Tbar,
            "dgamma": dgam,
            "sgn": sgn,
            "active": act,
            "pruned": pruned,
            "reactivated": passes,
            "unsettled": unsettled,
        }

    def _rate_map(
        self,
        Fc: FloatArray,
        Fp_n: FloatArray,
        s_n: FloatArray,
        H: FloatArray,
        Ce: FloatArray,
        tau_tr: FloatArray,
        dt: float | None,
        g0: FloatArray | None = None,
    ) -> dict[str, Any]:
        """Backward-Euler update of the power-law slip rule (``rate_exponent``).

        Solves ``g^α = γ̇₀ Δt φ^α(g)``, ``φ^α = |τ^α/s^α|ⁿ sign τ^α``, for the signed slip
        increments ``g`` of every system, with ``τ = τ_tr − A_el g`` (Eq. 31's
        linearization, ``A_el^{αβ} = (Cᵉ_tr S₀^β) : 𝓛ᵉ[S₀^α]``) and
        ``s = s_n + h |g|`` (:meth:`_rate_solve`), then the final state as the
        rate-independent update does.
        """
        m = Fc.shape[0]
        Ael = self._elastic_slip_matrix(Ce)
        if dt is None:
            if np.any(tau_tr != 0.0):
                raise InputError(
                    "state_n['dt'] (the time increment) is required by a rate-dependent "
                    "CrystalPlasticity (rate_exponent set) away from F = Fp; the load-step "
                    "drivers set it; got a state without 'dt'"
                )
            dt = 0.0
        g, jac, dphi = self._rate_solve(tau_tr, s_n, H, Ael, self.reference_rate * dt, g0=g0)
        sgn = np.where(g < 0.0, -1.0, 1.0)
        zero = np.zeros(m, dtype=np.int64)
        out = self._mapped(
            Fc, Fp_n, Ce, np.abs(g), sgn, np.ones(g.shape, dtype=bool), zero, zero,
            np.zeros(m, dtype=bool),
        )  # fmt: skip
        out.update(rate_jacobian=jac, rate_dphi=dphi)
        return out

    def _rate_solve(
        self,
        tau_tr: FloatArray,
        s_n: FloatArray,
        H: FloatArray,
        Ael: FloatArray,
        k: float,
        g0: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Solve ``r(g) = g − k φ(τ_tr − A_el g, s_n + H|g|) = 0`` per point by Newton.

        From ``g0`` (the committed increment: in steady flow the next one is close), and
        at the points where that fails from ``g = 0`` (the residual of one system is
        increasing and concave in ``g`` from there, so Newton approaches the root
        monotonically from below). A point is converged when its correction is below
        ``1e-12 max|g| + 1e-300``; a point that does not converge in ``_RATE_MAXITER``
        iterations from ``g = 0`` raises :class:`~pdlin.errors.ConvergenceError` (the
        drivers cut the increment back).

        Returns
        -------
        g : (m, N) ndarray
            Signed slip increments.
        jac : (m, N, N) ndarray
            ``∂r/∂g`` at the solution (the tangent's).
        dphi : (m, N) ndarray
            ``k ∂φ^α/∂τ^α`` at the solution.
        """
        m, N = tau_tr.shape
        g = np.zeros((m, N))
        jac = np.broadcast_to(np.eye(N), (m, N, N)).copy()
        dphi = np.zeros((m, N))
        if k == 0.0 or m == 0:
            return g, jac, dphi
        if m >= _RATE_NUMBA_MIN_POINTS:
            from .._kernels import compiled_kernels

            mod = compiled_kernels()
            if mod is not None:
                warm = g0 is not None and bool(np.any(g0 != 0.0))
                fail = np.zeros(m, dtype=np.bool_)
                mod.cp_rate_fill(
                    0, m,
                    np.ascontiguousarray(tau_tr), np.ascontiguousarray(s_n),
                    np.ascontiguousarray(H), np.ascontiguousarray(Ael),
                    float(k), float(self.rate_exponent),  # type: ignore[arg-type]
                    np.ascontiguousarray(g0 if warm else g), warm, _RATE_MAXITER,
                    g, jac, dphi, fail,
                )  # fmt: skip
                if fail.any():
                    self._rate_failed(int(fail.sum()), m)
                return g, jac, dphi
        every = np.arange(m)
        bad = every
        if g0 is not None and np.any(g0 != 0.0):
            g[:] = g0
            bad = self._rate_newton(g, jac, dphi, tau_tr, s_n, H, Ael, k, every)
            g[bad] = 0.0
        if bad.size:
            left = self._rate_newton(g, jac, dphi, tau_tr, s_n, H, Ael, k, bad)
            if left.size:
                self._rate_failed(left.size, m)
        return g, jac, dphi

    def _rate_failed(self, bad: int, m: int) -> None:
        raise ConvergenceError(
            "CrystalPlasticity: the rate-dependent slip update did not converge in "
            f"{_RATE_MAXITER} Newton iterations at {bad} of {m} point(s) (or left a slip "
            "increment |Δγ| > 1): the strain increment is too large for rate_exponent = "
            f"{self.rate_exponent:g}; cut the load step"
        )

    def _rate_newton(
        self,
        g: FloatArray,
        jac: FloatArray,
        dphi: FloatArray,
        tau_tr: FloatArray,
        s_n: FloatArray,
        H: FloatArray,
        Ael: FloatArray,
        k: float,
        pos: NDArray[np.intp],
    ) -> NDArray[np.intp]:
        """Newton iterations of :meth:`_rate_solve` on the points ``pos`` (``g`` in place).

        Returns the points that did not converge (or left ``|g| ≤ 1``, or overflowed).
        The working arrays are re-gathered only when the unconverged set has halved.
        """
        nexp = float(self.rate_exponent)  # type: ignore[arg-type]
        N = g.shape[1]
        eyeN = np.eye(N)
        failed: list[NDArray[np.intp]] = []
        sub = pos
        gp, Ap, Hp, tt, sn = g[sub], Ael[sub], H[sub], tau_tr[sub], s_n[sub]
        live = np.ones(sub.size, dtype=bool)
        for _ in range(_RATE_MAXITER):
            idx = np.flatnonzero(live)
            if idx.size == 0:
                break
            if 2 * idx.size < live.size:  # compress the working arrays
                g[sub] = gp
                sub = sub[idx]
                gp, Ap, Hp, tt, sn = gp[idx], Ap[idx], Hp[idx], tt[idx], sn[idx]
                live = np.ones(sub.size, dtype=bool)
                idx = np.arange(sub.size)
            G, A_, H_ = gp[idx], Ap[idx], Hp[idx]
            tau = tt[idx] - (A_ @ G[:, :, None])[:, :, 0]
            s = sn[idx] + (H_ @ np.abs(G)[:, :, None])[:, :, 0]
            x = np.abs(tau) / s
            with np.errstate(over="ignore", invalid="ignore"):  # checked right below
                xn1 = x ** (nexp - 1.0)
                phi = np.where(tau < 0.0, -1.0, 1.0) * xn1 * x
            r = G - k * phi
            dp = k * nexp * xn1 / s  # k ∂φ/∂τ
            sg = np.where(G != 0.0, np.sign(G), np.where(tau < 0.0, -1.0, 1.0))
            with np.errstate(over="ignore", invalid="ignore"):
                J = (
                    eyeN
                    + dp[:, :, None] * A_
                    + (k * nexp * phi / s)[:, :, None] * H_ * sg[:, None, :]
                )
                step = _solve(J, -r)
                G = G + step
            jac[sub[idx]], dphi[sub[idx]] = J, dp
            gp[idx] = G
            wild = ~(np.max(np.abs(G), axis=1) <= 1.0)  # also NaN / inf
            if wild.any():
                failed.append(sub[idx[wild]])
            done = np.max(np.abs(step), axis=1) <= 1e-12 * np.max(np.abs(G), axis=1) + 1e-300
            live[idx[done | wild]] = False
        g[sub] = gp
        failed.append(sub[live])
        return np.concatenate(failed)

    def _plastic_floor(self, state_n: Mapping[str, Any]) -> float:
        """Slip increment above which a point counts as plastic (``state["plastic"]``).

        0 for the rate-independent update; ``1e-3 γ̇₀ Δt`` for the power law, whose every
        loaded system slips a little (at ``n = 50`` a system at ``|τ| = 0.87 s`` slips at
        ``1e-3 γ̇₀``).
        """
        if not self.rate_dependent:
            return 0.0
        return 1e-3 * self.reference_rate * (_time_increment(state_n) or 0.0)

    def _elastic_slip_matrix(self, Ce: NDArray[Any]) -> NDArray[Any]:
        """``A_el^{αβ} = (Cᵉ S₀^β) : 𝓛ᵉ[S₀^α]`` per point, ``(m, N, N)`` (real or complex)."""
        m, N, d = Ce.shape[0], self.nslip, self.dim
        return (Ce.reshape(m, d * d) @ self._AelM.T).reshape(m, N, N)

    def _final_state(
        self, Fc: NDArray[Any], Fp_n: FloatArray, dgam: NDArray[Any], sgn: FloatArray
    ) -> tuple[NDArray[Any], NDArray[Any], NDArray[Any], NDArray[Any]]:
        """Return ``(Fᵖ, Fᵖ⁻¹, Fᵉ, T̄)`` of slip increments ``dgam`` with signs ``sgn``."""
        d, m = self.dim, Fc.shape[0]
        G = np.eye(d) + ((dgam * sgn) @ self._S0flat).reshape(m, d, d)
        Fp = _mm(G, Fp_n)
        if self.renormalize:
            Fp = Fp / (_det(Fp) ** (1.0 / d))[:, None, None]
        Fp_inv = _inv(Fp)
        Fe = _mm(Fc, Fp_inv)
        E = 0.5 * (_mm(_T(Fe), Fe) - np.eye(d))
        Tbar = (E.reshape(m, d * d) @ self._Cflat.T).reshape(m, d, d)
        return Fp, Fp_inv, Fe, Tbar

    @staticmethod
    def _solve_set(
        A: NDArray[Any], b: NDArray[Any], act: NDArray[np.bool_], *, prune: bool
    ) -> NDArray[Any]:
        """Solve ``Σ_{β∈act} A^{αβ} Δγ^β = b^α`` per point (``prune``: drop ``Δγ ≤ 0``).

        With ``prune``, the Appendix's pruning: drop the systems with ``Δγ ≤ 0`` and
        re-solve.

        Every point solves its N × N system with the inactive rows/columns replaced by the
        identity.  With ``prune``, every system with ``Δγ ≤ 0`` is dropped (``act`` is
        updated in place) and only the points whose set changed are re-solved, until no
        point changes; an emptied set is elastic (Δγ = 0).

        Returns
        -------
        (m, N) ndarray
            Slip increments, zero on the inactive systems.
        """
        N = A.shape[-1]
        eyeN = np.eye(N)
        dgam = np.zeros(b.shape, dtype=b.dtype)
        pos = np.flatnonzero(act.any(axis=1))
        while pos.size:
            aa = act[pos]
            mask = aa[:, :, None] & aa[:, None, :]
            Am = np.where(mask, A[pos], 0.0) + (~aa)[:, :, None] * eyeN
            x = _solve(Am, np.where(aa, b[pos], 0.0))
            if not prune:
                dgam[pos] = np.where(aa, x, 0.0)
                break
            good = x.real > 0.0
            done = np.all(good | ~aa, axis=1)
            fin = pos[done]
            dgam[fin] = np.where(aa[done], x[done], 0.0)
            act[pos] = aa & good
            left = pos[~done]
            pos = left[act[left].any(axis=1)]
        return dgam

    def _reactivate(
        self,
        s_n: FloatArray,
        H: FloatArray,
        tau_tr: FloatArray,
        Ael: FloatArray,
        trial: NDArray[np.bool_],
        sg: FloatArray,
        act: NDArray[np.bool_],
        dgam: FloatArray,
    ) -> tuple[FloatArray, NDArray[np.bool_], NDArray[np.int64]]:
        """Re-activation passes of the active-set search (``active_set="reactivate"``).

        After the Appendix's pruning, the resolved shear of the final state,
        ``τ^α = τ_tr^α − Σ_β sgn_β (Cᵉ_tr S₀^β) : 𝓛ᵉ[S₀^α] Δγ^β`` (the Eq. 31 state on which
        the consistency conditions are solved), is checked on the inactive systems
        against the updated resistance ``s^α = s_n^α + Σ_β h^{αβ} Δγ^β``.  At every point
        with ``|τ^α| > s^α (1 + yield_tol)`` the most violated system α enters the active
        set (slip sign ``sign τ^α``) by a principal pivot: ``Δγ^α = t`` grows from 0 with the
        active systems kept consistent, ``Δγ_S(t) = Δγ_S − t A_SS⁻¹ A_Sα``, until α is
        consistent or an active ``Δγ^β`` reaches 0 first (β is pruned and the growth goes
        on).  The set is then re-solved and pruned as in the Appendix, and the check is repeated,
        only for the points that changed (Anand & Kothari 1996; Miehe & Schröder 2001).
        Plain "add every violated system and re-solve" cycles when the enlarged set is
        (nearly) linearly dependent, as 5 and more fcc systems are.

        A point that still violates after ``max_passes`` passes, revisits an earlier
        (set, signs) pair or finds no consistent pivot (ray termination) is *unsettled*:
        it keeps the visited solution with the smallest yield violation.  ``sg`` and
        ``act`` are updated in place.

        Returns
        -------
        dgam : (m, N) ndarray
            Final slip increments.
        unsettled : (m,) bool ndarray
        passes : (m,) int ndarray
            Re-activation passes per point.
        """
        m, N = act.shape
        tol = self.yield_tol
        bits = 2 ** np.arange(N, dtype=np.int64)
        unsettled = np.zeros(m, dtype=bool)
        passes = np.zeros(m, dtype=np.int64)
        best = np.full(m, np.inf)
        best_dg, best_act, best_sg = dgam.copy(), act.copy(), sg.copy()
        pos = np.arange(m)
        # (active set, signs) each point started a solve from; revisiting one is a cycle
        seen = [_set_code(trial, sg, bits)]
        seen_pos = [pos]
        for k in range(self.max_passes + 1):
            tau = tau_tr[pos] - (Ael[pos] @ (sg[pos] * dgam[pos])[:, :, None])[:, :, 0]
            s = s_n[pos] + (H[pos] @ dgam[pos][:, :, None])[:, :, 0]
            over = np.where(act[pos], -np.inf, (np.abs(tau) - s * (1.0 + tol)) / s)
            worst = over.max(axis=1)
            better = worst < best[pos]
            bp = pos[better]
            best[bp] = worst[better]
            best_dg[bp], best_act[bp], best_sg[bp] = dgam[bp], act[bp], sg[bp]
            hit = worst > 0.0
            pos, tau, over = pos[hit], tau[hit], over[hit]
            if not pos.size:
                break
            if k == self.max_passes:
                unsettled[pos] = True
                break
            # the most violated system enters with the sign of its τ
            r = np.arange(pos.size)
            al = np.argmax(over, axis=1)
            sg[pos, al] = np.where(tau[r, al] < 0.0, -1.0, 1.0)
            sp = sg[pos]
            A = H[pos] + sp[:, :, None] * sp[:, None, :] * Ael[pos]
            b = sp * tau_tr[pos] - s_n[pos]
            S = act[pos]
            ray = self._pivot(A, b, S, al)
            unsettled[pos[ray]] = True
            S[r, al] = ~ray
            code = _set_code(S, sp, bits)
            cyc = ray.copy()
            for c_old, p_old in zip(seen, seen_pos, strict=True):
                j = np.minimum(np.searchsorted(p_old, pos), p_old.size - 1)
                cyc |= (p_old[j] == pos) & (c_old[j] == code)
            unsettled[pos[cyc]] = True
            keep = ~cyc
            pos, S, A, b = pos[keep], S[keep], A[keep], b[keep]
            if not pos.size:
                break
            seen.append(code[keep])
            seen_pos.append(pos)
            passes[pos] += 1
            act[pos] = S
            dgam[pos] = self._solve_set(A, b, S, prune=True)
            act[pos] = S
        bad = np.flatnonzero(unsettled)
        dgam[bad], act[bad], sg[bad] = best_dg[bad], best_act[bad], best_sg[bad]
        return dgam, unsettled, passes

    @staticmethod
    def _pivot(
        A: FloatArray, b: FloatArray, S: NDArray[np.bool_], al: NDArray[np.intp]
    ) -> NDArray[np.bool_]:
        """Principal pivot bringing system ``al`` into the active sets ``S`` (in place).

        ``Δγ^α = t`` grows from 0 while the systems of ``S`` stay consistent,
        ``Δγ_S(t) = x₀ − t d`` with ``A_SS x₀ = b_S``, ``A_SS d = A_Sα``; α becomes
        consistent at ``t* = (b_α − A_αS x₀) / (A_αα − A_αS d)`` (if the Schur complement
        is positive); an active β with ``d_β > 0`` blocks at ``t_β = x₀_β / d_β``.  A
        blocking β before ``t*`` is removed from ``S`` and the growth goes on.  ``S`` is
        left without α (the caller adds it).

        Returns
        -------
        (m,) bool ndarray
            Points with no consistent pivot (ray termination).
        """
        m, N = S.shape
        r = np.arange(m)
        eyeN = np.eye(N)
        ray = np.zeros(m, dtype=bool)
        live = np.arange(m)
        for _ in range(N):
            if not live.size:
                break
            Sl, a = S[live], al[live]
            rl = r[: live.size]
            Al = A[live]
            mask = Sl[:, :, None] & Sl[:, None, :]
            Am = np.where(mask, Al, 0.0) + (~Sl)[:, :, None] * eyeN
            rhs = np.stack([np.where(Sl, b[live], 0.0), np.where(Sl, Al[rl, :, a], 0.0)], -1)
            try:
                sol = np.linalg.solve(Am, rhs)
            except np.linalg.LinAlgError:
                sol = np.linalg.pinv(Am) @ rhs
            x0, d = sol[..., 0], sol[..., 1]
            row = np.where(Sl, Al[rl, a, :], 0.0)
            sigma = Al[rl, a, a] - np.sum(row * d, axis=1)
            y0 = b[live, a] - np.sum(row * x0, axis=1)
            t_star = np.where(sigma > 0.0, y0 / np.where(sigma > 0.0, sigma, 1.0), np.inf)
            blocking = Sl & (d > 0.0)
            t_b = np.where(blocking, x0 / np.where(blocking, d, 1.0), np.inf)
            beta = np.argmin(t_b, axis=1)
            t_block = t_b[rl, beta]
            done = t_star <= t_block
            dead = ~done & ~np.isfinite(t_block)
            ray[live[dead]] = True
            drop = ~done & ~dead
            S[live[drop], beta[drop]] = False
            live = live[drop]
        ray[live] = True
        return ray

    # -- public update -----------------------------------------------------------------
    def committed_issues(self, state: dict[str, np.ndarray]) -> list[tuple[type[Warning], str]]:
        """Report the points of a committed state whose active-set search did not settle.

        Called by the nonlinear drivers after each converged load step (see
        :meth:`pdlin.models.Model.committed_issues`).

        Parameters
        ----------
        state : dict of str to ndarray
            A committed state (its ``unsettled`` flags; absent: none).

        Returns
        -------
        list of (type, str)
            One ``(ActiveSetWarning, message)`` when some point did not settle, else
            empty.

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cp = pdlin.CrystalPlasticity()
        >>> cp.committed_issues({"unsettled": np.array([False, True, False])})[0][1][:58]
        'the crystal-plasticity active-set search did not settle at'
        """
        from ..errors import ActiveSetWarning

        unsettled = np.asarray(state.get("unsettled", np.zeros(0)), dtype=bool)
        if not unsettled.any():
            return []
        return [
            (
                ActiveSetWarning,
                "the crystal-plasticity active-set search did not settle at "
                f"{int(unsettled.sum())} of {unsettled.size} gradient point(s) of the committed "
                "state (state['unsettled']); use smaller steps",
            )
        ]

    def update(
        self,
        F: ArrayLike,
        state_n: Mapping[str, FloatArray],
        *,
        tangent: bool = False,
    ) -> tuple[FloatArray, dict[str, FloatArray], FloatArray | None]:
        """Return mapping at ``F`` from the committed ``state_n`` (a pure function).

        Parameters
        ----------
        F : (n, d, d) array_like of float
            Deformation gradient (sample frame) at the current iterate.
        state_n : dict
            Committed state (:meth:`initial_state` or a previous ``state_new``); not
            modified.  With ``rate_exponent`` also ``state_n["dt"]``, the time increment
            of the update (a number >= 0; the load-step drivers add it).
        tangent : bool
            Also return the consistent tangent ``dP/dF``.

        Returns
        -------
        P : (n, d, d) ndarray
            First Piola–Kirchhoff stress (sample frame).
        state_new : dict
            Trial state at ``F`` (commit it to advance the load step).
        dPdF : (n, d, d, d, d) ndarray or None
            ``dPdF[p, i, j, k, l] = ∂P_ij/∂F_kl`` (complex-step, active set frozen).
        """
        f = _check_F(F, self.dim)
        n = f.shape[0]
        self._check_state(state_n, n)
        if n >= _NUMBA_MIN_POINTS and self._numba_ok(tangent):
            P, state, D = self._update_numba(f, state_n, tangent)
        elif n >= 2 * _UPDATE_CHUNK:
            # fixed chunks of points on pdlin's threads (numpy releases the GIL in the
            # batched arithmetic; every point's update is independent): the same arrays
            # for any thread count
            from .._threads import even_chunks, thread_map

            def rows(v: Any, a: int, b: int) -> Any:
                return v[a:b] if isinstance(v, np.ndarray) and v.ndim and len(v) == n else v

            parts = thread_map(
                lambda c: self._update_points(
                    f[c[0] : c[1]], {k: rows(v, c[0], c[1]) for k, v in state_n.items()}, tangent
                ),
                even_chunks(n, _UPDATE_CHUNK),
            )
            P = np.concatenate([q[0] for q in parts])
            state = {k: np.concatenate([q[1][k] for q in parts]) for k in parts[0][1]}
            D = np.concatenate([q[2] for q in parts]) if tangent else None
        else:
            P, state, D = self._update_points(f, state_n, tangent)
        n_bad = int(np.count_nonzero(state["unsettled"]))
        if n_bad:
            first = int(np.argmax(state["unsettled"]))
            warnings.warn(
                f"CrystalPlasticity: the active-set search did not settle at {n_bad} of {n} "
                f"point(s) (first index {first}): an inactive slip system still has "
                f"|tau| > s (1 + {self.yield_tol:g}) after {self.max_passes} re-activation "
                "passes or the search cycled; the solution with the smallest violation is "
                "kept (state['unsettled']). Reduce the strain increment or raise max_passes.",
                ActiveSetWarning,
                stacklevel=2,
            )
        return P, state, D

    def _numba_ok(self, tangent: bool) -> bool:
        """Whether :meth:`update` runs the compiled planar kernels."""
        if self.slip != "planar-2" or self.active_set != "prune" or self.rate_dependent:
            return False
        if tangent and self.tangent_method != "analytic":
            return False
        from .._kernels import numba_enabled

        return numba_enabled()

    def _numba_inputs(
        self, f: FloatArray, state_n: Mapping[str, Any]
    ) -> tuple[tuple[Any, ...], tuple[Any, ...]]:
        """Return the input and constant arguments of ``cp_planar_fill`` (contiguous)."""
        n = f.shape[0]

        def arr(key: str, default: Any = None) -> FloatArray:
            # the defaults (a fresh state without the key) only when the key is missing:
            # computing them eagerly costs ≈ 0.4 ms per call at 10⁵ points (5 % of the update)
            v = state_n[key] if key in state_n else default()
            return np.ascontiguousarray(v, dtype=np.float64)

        R0 = np.ascontiguousarray(state_n["R0"], dtype=np.float64)
        theta0 = arr("theta0", lambda: np.arctan2(R0[:, 1, 0], R0[:, 0, 0]))
        ins = (
            np.ascontiguousarray(f),
            R0,
            arr("Fp"),
            arr("s"),
            arr("gamma"),
            arr("ep", lambda: np.zeros(n)),
            theta0,
            arr("theta", lambda: theta0),
            arr("theta_rate", lambda: np.zeros(n)),
        )
        consts = (
            np.ascontiguousarray(self._CS0flat),
            np.ascontiguousarray(self._AelM),
            np.ascontiguousarray(self._S0flat),
            np.ascontiguousarray(self._Cflat),
            np.ascontiguousarray(self.Q, dtype=np.float64),
            np.ascontiguousarray(self.h0, dtype=np.float64),
            np.ascontiguousarray(self.ss, dtype=np.float64),
            np.ascontiguousarray(self.a, dtype=np.float64),
            bool(self.renormalize),
        )
        return ins, consts

    def _update_numba(
        self, f: FloatArray, state_n: Mapping[str, Any], tangent: bool
    ) -> tuple[FloatArray, dict[str, FloatArray], FloatArray | None]:
        """Run :meth:`update` of planar double slip in the numba kernels.

        The Appendix's pruning in ``cp_planar_fill`` and (``tangent``)
        ``cp_planar_tangent_fill``, the analytic tangent (chunks of points on pdlin's
        threads); points whose active-set matrix is singular are redone by the numpy
        path.  Equal to :meth:`_update_points` to round-off (its 4-term products and
        2 x 2 solves run through BLAS / LAPACK).
        """
        from .._kernels import compiled_kernels
        from .._threads import even_chunks, thread_map

        mod = compiled_kernels()
        assert mod is not None
        n = f.shape[0]
        ins, consts = self._numba_inputs(f, state_n)
        R0, theta0 = ins[1], ins[6]
        N = self.nslip
        P = np.empty((n, 2, 2))
        st: dict[str, FloatArray] = {
            "Fp": np.empty((n, 2, 2)),
            "s": np.empty((n, N)),
            "gamma": np.empty((n, N)),
            "dgamma": np.empty((n, N)),
            "tau": np.empty((n, N)),
            "dep": np.empty(n),
            "ep": np.empty(n),
            "plastic": np.empty(n),
            "sign": np.empty((n, N)),
            "pruned": np.empty(n),
            "theta": np.empty(n),
            "R": np.empty((n, 2, 2)),
            "reorientation": np.empty(n),
            "theta_rate": np.empty(n),
        }
        bad = np.zeros(n, dtype=np.bool_)
        outs = (
            P, st["Fp"], st["s"], st["gamma"], st["dgamma"], st["tau"], st["dep"], st["ep"],
            st["plastic"], st["sign"], st["pruned"], st["theta"], st["R"],
            st["reorientation"], st["theta_rate"], bad,
        )  # fmt: skip
        kern = mod.cp_planar_fill
        tkern = mod.cp_planar_tangent_fill
        D = np.empty((n, 2, 2, 2, 2)) if tangent else None
        t_ins = (ins[0], R0, ins[2], ins[3])

        def run(c: tuple[int, int]) -> None:
            kern(c[0], c[1], *ins, *consts, *outs, True)
            if D is not None:
                t_outs = (st["Fp"], st["dgamma"], st["sign"])
                tkern(c[0], c[1], *t_ins, *t_outs, *consts, D)

        try:
            thread_map(run, even_chunks(n, _UPDATE_CHUNK))
        except ZeroDivisionError as exc:  # numba raises where numpy gives inf / nan
            raise _degenerate(exc) from exc
        state: dict[str, FloatArray] = {
            "Fp": st["Fp"],
            "s": st["s"],
            "gamma": st["gamma"],
            "dgamma": st["dgamma"],
            "tau": st["tau"],
            "R0": R0,
            "dep": st["dep"],
            "ep": st["ep"],
            "plastic": st["plastic"],
            "sign": st["sign"],
            "pruned": st["pruned"],
            "reactivated": np.zeros(n),
            "unsettled": np.zeros(n),
            "theta0": theta0,
            "theta": st["theta"],
            "R": st["R"],
            "reorientation": st["reorientation"],
            "theta_rate": st["theta_rate"],
        }
        idx = np.flatnonzero(bad)
        if idx.size:  # singular active-set matrices: numpy's pseudo-inverse path
            Pb, sb, Db = self._update_points(f[idx], _rows_of(state_n, idx, n), tangent)
            P[idx] = Pb
            for k, v in sb.items():
                state[k][idx] = v
            if D is not None:
                D[idx] = Db
        return P, state, D

    def piola(self, F: ArrayLike, state_n: Mapping[str, FloatArray]) -> FloatArray:
        """Return the first Piola–Kirchhoff stress at ``F`` from ``state_n``, no trial state.

        ``update(F, state_n)[0]``: what an iteration that only needs the force (ADR, a
        line-search trial) asks for.  For planar double slip with the Appendix's pruning the
        compiled kernel then skips the trial state (Fᵖ, resistances, slips, plastic work,
        lattice rotation): ≈ 40 % less work per point, the same ``P`` bitwise.  Other
        slip families and active-set searches run the full :meth:`update`.

        Parameters
        ----------
        F : (n, d, d) array_like
            Deformation gradients (sample frame).
        state_n : mapping of str to ndarray
            The committed state of the ``n`` points.

        Returns
        -------
        (n, d, d) ndarray
            ``P`` in the sample frame.

        Examples
        --------
        >>> import numpy as np, pdlin
        >>> cp = pdlin.CrystalPlasticity()
        >>> state = cp.initial_state(300)
        >>> F = np.broadcast_to([[1.0, 0.004], [0.0, 1.0]], (300, 2, 2))
        >>> bool(np.array_equal(cp.piola(F, state), cp.update(F, state)[0]))
        True
        """
        f = _check_F(F, self.dim)
        n = f.shape[0]
        self._check_state(state_n, n)
        if not (n >= _NUMBA_MIN_POINTS and self._numba_ok(False)):
            return self.update(f, state_n)[0]
        from .._kernels import compiled_kernels
        from .._threads import even_chunks, thread_map

        mod = compiled_kernels()
        assert mod is not None
        ins, consts = self._numba_inputs(f, state_n)
        N = self.nslip
        P = np.empty((n, 2, 2))
        bad = np.zeros(n, dtype=np.bool_)
        one, pair, mat = np.empty(1), np.empty((1, N)), np.empty((1, 2, 2))  # not written
        outs = (
            P, mat, pair, pair, pair, pair, one, one, one, pair, one, one, mat, one, one, bad,
        )  # fmt: skip
        kern = mod.cp_planar_fill
        try:
            thread_map(
                lambda c: kern(c[0], c[1], *ins, *consts, *outs, False),
                even_chunks(n, _UPDATE_CHUNK),
            )
        except ZeroDivisionError as exc:  # numba raises where numpy gives inf / nan
            raise _degenerate(exc) from exc
        idx = np.flatnonzero(bad)
        if idx.size:  # singular active-set matrices: numpy's pseudo-inverse path
            P[idx] = self._update_points(f[idx], _rows_of(state_n, idx, n), False)[0]
        return P

    def _update_points(
        self, f: FloatArray, state_n: Mapping[str, Any], tangent: bool
    ) -> tuple[FloatArray, dict[str, FloatArray], FloatArray | None]:
        """:meth:`update` of a batch of points (validated), without the warning."""
        n, d = f.shape[0], self.dim
        R0 = np.asarray(state_n["R0"], dtype=np.float64)
        Fp_n = np.asarray(state_n["Fp"], dtype=np.float64)
        s_n = np.asarray(state_n["s"], dtype=np.float64)
        H = self._hardening_matrix(s_n)
        Fc = _mm(_mm(_T(R0), f), R0)
        g0 = None
        if self.rate_dependent and "sign" in state_n and "dgamma" in state_n:
            # the committed increment starts the local Newton of the power law
            g0 = np.asarray(state_n["sign"]) * np.asarray(state_n["dgamma"])
        out = self._return_map(Fc, Fp_n, s_n, H, dt=_time_increment(state_n), g0=g0)
        P = _mm(_mm(R0, out["P"]), _T(R0))
        dgam = out["dgamma"].real
        sgn = out["sgn"]
        Tbar = out["Tbar"]
        Fe = out["Fe"]
        s_new = s_n + np.einsum("mab,mb->ma", H, dgam)
        tau = Tbar.reshape(n, d * d) @ self._S0flat.T
        sigma = cauchy_stress(P, f)
        seff = _von_mises(sigma)
        work = np.sum(np.abs(tau) * dgam, axis=1)
        dep = np.divide(work, seff, out=np.zeros(n), where=seff > 0.0)
        state: dict[str, FloatArray] = {
            "Fp": out["Fp"],
            "s": s_new,
            "gamma": np.asarray(state_n["gamma"]) + dgam,
            "dgamma": dgam,
            "tau": tau,
            "R0": R0,
            "dep": dep,
            "ep": np.asarray(state_n.get("ep", np.zeros(n))) + dep,
            "plastic": np.any(dgam > self._plastic_floor(state_n), axis=1).astype(np.float64),
            "sign": sgn.real.astype(np.float64),
            "pruned": out["pruned"].astype(np.float64),
            "reactivated": out["reactivated"].astype(np.float64),
            "unsettled": out["unsettled"].astype(np.float64),
        }
        if d == 2:
            # closed form of the paper's reorientation (derived, frame independent):
            # θ = θ0 + atan2(Fe21 − Fe12, Fe11 + Fe22)
            phi = np.arctan2(Fe[:, 1, 0] - Fe[:, 0, 1], Fe[:, 0, 0] + Fe[:, 1, 1])
            theta0 = np.asarray(state_n.get("theta0", np.arctan2(R0[:, 1, 0], R0[:, 0, 0])))
            theta_prev = np.asarray(state_n.get("theta", theta0))
            state["theta0"] = theta0
            state["theta"] = theta0 + phi
            state["R"] = _rotation_2d(theta0 + phi)
            state["reorientation"] = np.degrees(phi)
            # rate form (Luo, Ramazani & Sundararaghavan 2017, Section 4):
            # Ω Δt = ΔRᵉ Rᵉᵀ, Δθ = (Ω21 − Ω12)/2
            Rp = _rotation_2d(theta_prev - theta0)
            Rn = _rotation_2d(phi)
            W = _mm(Rn - Rp, _T(Rn))
            state["theta_rate"] = np.asarray(state_n.get("theta_rate", np.zeros(n))) + 0.5 * (
                W[:, 1, 0] - W[:, 0, 1]
            )
        else:
            U, _, Vt = np.linalg.svd(Fe)
            Re = U @ Vt
            state["R"] = R0 @ Re
            cosang = np.clip(0.5 * (np.trace(Re, axis1=1, axis2=2) - 1.0), -1.0, 1.0)
            state["reorientation"] = np.degrees(np.arccos(cosang))
        D = None
        if tangent and self.tangent_method == "analytic":
            D = self._tangent_analytic(Fc, R0, Fp_n, H, out)
        elif tangent:
            D = self._tangent(f, R0, Fp_n, s_n, H, out["active"], out["sgn"].real)
        return P, state, D

    def _tangent_analytic(
        self,
        Fc: FloatArray,
        R0: FloatArray,
        Fp_n: FloatArray,
        H: FloatArray,
        out: dict[str, Any],
    ) -> FloatArray:
        """Linearize the return mapping in forward mode, active set frozen, all d² directions.

        ``dΔγ = A⁻¹ (db − dA Δγ)`` on the active set (one factorization, d² right-hand
        sides), then the chain rule through Fᵖ, Fᵉ, T̄ and P.
        """
        n, d, N = Fc.shape[0], self.dim, self.nslip
        d2 = d * d
        eye = np.eye(d)
        # crystal-frame directions of the sample perturbations e_k ⊗ e_l: (n, kl, i, j)
        dF = np.einsum("nki,nlj->nklij", R0, R0).reshape(n, d2, d, d)
        Fp_n_inv = _inv(Fp_n)
        Fe_tr = _mm(Fc, Fp_n_inv)
        dFe_tr = _mm(dF, Fp_n_inv[:, None])
        dCe = _mm(_T(dFe_tr), Fe_tr[:, None])
        dCe = dCe + _T(dCe)
        sgn = out["sgn"].real
        act = out["active"]
        dgam = out["dgamma"].real
        ddg = np.zeros((n, d2, N))
        idx = np.flatnonzero(act.any(axis=1))
        rate = "rate_jacobian" in out
        if idx.size:
            aa = act[idx]
            sg = sgn[idx]
            if rate:
                # rate-dependent: ∂r/∂g dg = k ∂φ/∂τ (dτ_tr − dA_el g), g = sgn Δγ, so
                # dΔγ = S J⁻¹ K S (db − dA Δγ) with S = diag(sgn), K = diag(k ∂φ/∂τ)
                Am = out["rate_jacobian"][idx]
            else:
                ss = sg[:, :, None] * sg[:, None, :]
                A = H[idx] + ss * self._elastic_slip_matrix(out["Ce"][idx])
                mask = aa[:, :, None] & aa[:, None, :]
                Am = np.where(mask, A, 0.0) + (~aa)[:, :, None] * np.eye(N)
            dC = dCe[idx]  # (m, kl, d, d)
            # db^α = sgn_α dτ_tr^α = sgn_α ½ dCe : 𝓛[S₀^α]
            db = 0.5 * sg[:, None, :] * (dC.reshape(idx.size, d2, d2) @ self._CS0flat.T)
            # (dA Δγ)^α = Σ_β sgn_α sgn_β (dCe S₀^β) : 𝓛[S₀^α] Δγ^β
            w = (sg * dgam[idx])[:, None, :]  # (m, 1, β)
            dCeS = np.einsum("mkil,blj->mkbij", dC, self.S0).reshape(idx.size, d2, N, d2)
            dAx = sg[:, None, :] * np.einsum(
                "mkb,mkbq,aq->mka",
                np.broadcast_to(w, (idx.size, d2, N)),
                dCeS,
                self._CS0flat,
                optimize=True,
            )
            rhs = np.where(aa[:, None, :], db - dAx, 0.0)  # (m, kl, α)
            if rate:
                rhs = rhs * (out["rate_dphi"][idx] * sg)[:, None, :]
            try:
                sol = np.linalg.solve(Am, _T(rhs))
            except np.linalg.LinAlgError:
                sol = np.linalg.pinv(Am) @ _T(rhs)
            if rate:
                sol = sol * sg[:, :, None]
            ddg[idx] = np.where(aa[:, None, :], _T(sol), 0.0)
        dG = ((ddg * sgn[:, None, :]) @ self._S0flat).reshape(n, d2, d, d)
        Fp_inv = out["Fp_inv"]
        dFp = _mm(dG, Fp_n[:, None])
        if self.renormalize:
            G = eye + ((dgam * sgn) @ self._S0flat).reshape(n, d, d)
            Fq = _mm(G, Fp_n)
            J = _det(Fq)
            tr = np.einsum("nij,nkji->nk", _inv(Fq), dFp)
            dFp = (dFp - tr[:, :, None, None] / d * Fq[:, None]) / (J ** (1.0 / d))[
                :, None, None, None
            ]
        dFp_inv = -_mm(_mm(Fp_inv[:, None], dFp), Fp_inv[:, None])
        Fe, Tbar = out["Fe"], out["Tbar"]
        dFe = _mm(dF, Fp_inv[:, None]) + _mm(Fc[:, None], dFp_inv)
        dE = _mm(_T(dFe), Fe[:, None])
        dE = 0.5 * (dE + _T(dE))
        dT = (dE.reshape(n, d2, d2) @ self._Cflat.T).reshape(n, d2, d, d)
        FpiT = _T(Fp_inv)[:, None]
        dP = _mm(dFe, _mm(Tbar, _T(Fp_inv))[:, None]) + _mm(_mm(Fe[:, None], dT), FpiT)
        dP = dP + _mm(_mm(Fe, Tbar)[:, None], _T(dFp_inv))
        dP = _mm(_mm(R0[:, None], dP), _T(R0)[:, None])  # back to the sample frame
        return np.ascontiguousarray(dP.reshape(n, d, d, d, d).transpose(0, 3, 4, 1, 2))

    def _tangent(
        self,
        f: FloatArray,
        R0: FloatArray,
        Fp_n: FloatArray,
        s_n: FloatArray,
        H: FloatArray,
        active: NDArray[np.bool_],
        sign: FloatArray,
    ) -> FloatArray:
        """Complex-step tangent ``Im P(F + i h E_kl) / h``, active set and signs frozen."""
        n, d, N = f.shape[0], self.dim, self.nslip
        h = self.tangent_step
        D = np.empty((n, d, d, d, d))
        # perturbations E_kl in the crystal frame: Rᵀ (i h e_k ⊗ e_l) R
        Ekl = np.einsum("nki,nlj->nklij", R0, R0)  # (n, k, l, i, j) = R_ki R_lj
        Fc = _mm(_mm(_T(R0), f), R0)
        per_point = d * d * (N * d * d + 2 * N * N + 8 * d * d)
        chunk = max(1, int(4e6 // per_point))
        for lo in range(0, n, chunk):
            sl = slice(lo, min(n, lo + chunk))
            k = sl.stop - sl.start
            Fz = Fc[sl, None, None] + 1j * h * Ekl[sl]  # (k, d, d, d, d)
            Fz = Fz.reshape(k * d * d, d, d)

            def rep(a: NDArray[Any]) -> NDArray[Any]:
                return np.repeat(a[sl], d * d, axis=0)  # noqa: B023

            out = self._return_map(Fz, rep(Fp_n), rep(s_n), rep(H), rep(active), rep(sign))
            Pz = rep(R0) @ out["P"] @ _T(rep(R0))
            D[sl] = (Pz.imag / h).reshape(k, d, d, d, d).transpose(0, 3, 4, 1, 2)
        return D

    # -- post-processing ---------------------------------------------------------------
    @staticmethod
    def cauchy(P: ArrayLike, F: ArrayLike) -> FloatArray:
        """Return the Cauchy stress ``σ = P Fᵀ / det F``.

        Parameters
        ----------
        P, F : (..., d, d) array_like of float
            First Piola–Kirchhoff stresses and deformation gradients.

        Returns
        -------
        (..., d, d) ndarray
            Cauchy stresses.
        """
        return cauchy_stress(P, F)

    def schmid_factors(
        self,
        direction: ArrayLike | None = None,
        orientation: ArrayLike | None = None,
        *,
        state: Mapping[str, FloatArray] | None = None,
    ) -> FloatArray:
        """Schmid factors ``𝕊^α = |(m^α·l_c)(n^α·l_c)|``, ``l_c = Rᵀ l_s``.

        Parameters
        ----------
        direction : (d,) or (n, d) array_like, optional
            Loading direction ``l_s`` in the sample frame (normalized; default ``e1``).
        orientation : optional
            Orientations (forms of :class:`CrystalPlasticity`); default the material's.
        state : dict, optional
            Use the current lattice rotation ``state["R"]`` instead.

        Returns
        -------
        (n, nslip) ndarray

        Examples
        --------
        >>> mat = CrystalPlasticity()
        >>> np.round(mat.schmid_factors([1.0, 0.0], np.radians([-75.0, 0.0])), 3).tolist()
        [[0.5, 0.25], [0.433, 0.433]]
        """
        if state is not None:
            R = np.asarray(state["R"], dtype=np.float64)
        else:
            o = self.orientation if orientation is None else orientation
            R, _ = _orientation_arrays(o, n_orientations(o, self.dim) or 1, self.dim)
        l_s = np.asarray(np.eye(self.dim)[0] if direction is None else direction, dtype=float)
        if l_s.shape not in ((self.dim,), (R.shape[0], self.dim)):
            raise ShapeError(
                f"direction must have shape ({self.dim},) or ({R.shape[0]}, {self.dim}), got "
                f"{l_s.shape}"
            )
        check_finite(l_s, "direction")
        l_s = l_s / np.linalg.norm(l_s, axis=-1, keepdims=True)
        l_c = (
            np.einsum("nji,...j->ni", R, l_s) if l_s.ndim == 1 else np.einsum("nji,nj->ni", R, l_s)
        )
        return np.asarray(np.abs((l_c @ self.m.T) * (l_c @ self.n.T)))

    @staticmethod
    def reorientation(state: Mapping[str, FloatArray]) -> FloatArray:
        """Return the lattice reorientation since the start, in degrees.

        Parameters
        ----------
        state : mapping of str to ndarray
            A state of :meth:`update` (its ``reorientation`` entry).

        Returns
        -------
        (n,) ndarray
            2D: the signed angle, counter-clockwise positive; 3D: the rotation angle.
        """
        return np.asarray(state["reorientation"])

    @staticmethod
    def plastic_strain_increment(state: Mapping[str, FloatArray]) -> FloatArray:
        """Return the equivalent plastic strain increment ``dεᵖ = Σ|τ^α|Δγ^α / σ_eff``.

        Anand & Kalidindi (1994), as in Luo, Ramazani & Sundararaghavan (2017), Section 4.3.

        Parameters
        ----------
        state : mapping of str to ndarray
            A state of :meth:`update` (its ``dep`` entry).

        Returns
        -------
        (n,) ndarray
            ``dεᵖ`` per point of the update that produced ``state``.
        """
        return np.asarray(state["dep"])


# ---------------------------------------------------------------------------------------
# homogeneous material-point driver


@dataclass(frozen=True)
class MaterialPointResult:
    """Per-step history of a homogeneous material-point run (``steps`` rows, ``n`` points).

    Attributes
    ----------
    t : (steps,) load-step times 1..steps
    F : (steps, d, d) applied deformation gradients ``exp(η L t)``
    stress : (steps, n, d, d) Cauchy stress
    gamma : (steps, n, nslip) accumulated slips
    s : (steps, n, nslip) slip resistances
    rotation : (steps, n) lattice reorientation in degrees (2D: CCW positive)
    rotation_rate : (steps, n) Σ θ̇ Δt in degrees (2D rate form); NaN in 3D
    plastic : (steps, n) bool, step with Δγ > 0
    yield_step : (n,) first plastic step (0 if none)
    states : list of committed states, one per step
    """

    t: FloatArray
    F: FloatArray
    stress: FloatArray
    gamma: FloatArray
    s: FloatArray
    rotation: FloatArray
    rotation_rate: FloatArray
    plastic: NDArray[np.bool_]
    yield_step: NDArray[np.int64]
    states: list[dict[str, FloatArray]]

    def __repr__(self) -> str:
        """Summarize steps, points, slip systems and the first yield (no arrays)."""
        steps, n, nslip = (int(v) for v in self.gamma.shape)
        plastic = self.yield_step[self.yield_step > 0]
        return compact_repr(
            "MaterialPointResult",
            {
                "steps": steps,
                "points": n,
                "dim": int(self.F.shape[-1]),
                "nslip": nslip,
                "t": Raw(f"{format_value(self.t[0])} .. {format_value(self.t[-1])}")
                if steps
                else None,
                "first_yield_step": int(plastic.min()) if plastic.size else None,
            },
        )


_LOADINGS = {
    2: {
        "shear": np.array([[0.0, 1.0], [1.0, 0.0]]),  # the paper's Section 4.1
        "compression": np.array([[1.0, 0.0], [0.0, -1.0]]),  # Y-compression, Section 4.2
        "tension": np.array([[-1.0, 0.0], [0.0, 1.0]]),
    },
    3: {
        "shear": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
        "compression": np.diag([0.5, 0.5, -1.0]),
        "tension": np.diag([-0.5, -0.5, 1.0]),
    },
}


def material_point(
    material: CrystalPlasticity | SaintVenantKirchhoff,
    loading: str | ArrayLike = "shear",
    steps: int = 30,
    eta: float = 0.002,
    orientation: ArrayLike | None = None,
) -> MaterialPointResult:
    """Run the homogeneous driver ``F(t) = exp(η L t)``, ``t = 1..steps``.

    pdlin's material-point check (the reference tables of docs/crystal_plasticity.md).

    Every orientation is one point of a single batched update per step; the state is
    committed after each step.

    Parameters
    ----------
    material : CrystalPlasticity or SaintVenantKirchhoff
        The material (its dimension sets ``d``).
    loading : {"shear", "compression", "tension"} or (d, d) array_like
        Velocity gradient ``L``: 2D shear ``[[0, 1], [1, 0]]``, compression (along y)
        ``diag(1, -1)``, tension ``diag(-1, 1)``; 3D shear in the x–y plane, compression
        ``diag(½, ½, -1)`` and tension ``diag(-½, -½, 1)`` (along z).
    steps : int
        Number of load steps.
    eta : float
        Rate η per load step.
    orientation : optional
        Orientations, one per point (default the material's).

    Returns
    -------
    MaterialPointResult
        Per-step stresses, slips, resistances, reorientation and committed states.

    Examples
    --------
    >>> r = material_point(CrystalPlasticity(), "shear", orientation=np.radians([0.0, 60.0]))
    >>> r.yield_step.tolist(), np.round(r.stress[-1, :, 0, 1], 3).tolist()   # reference values
    ([3, 3], [24.005, 10.862])
    """
    from scipy.linalg import expm

    if not isinstance(material, CrystalPlasticity | SaintVenantKirchhoff):
        raise InputTypeError(
            "material must be a CrystalPlasticity or SaintVenantKirchhoff, got "
            f"{type(material).__name__}"
        )
    d = material.dim
    if isinstance(loading, str):
        if loading not in _LOADINGS[d]:
            raise InputError(f"loading must be one of {sorted(_LOADINGS[d])}, got {loading!r}")
        L = _LOADINGS[d][loading]
    else:
        L = np.asarray(loading, dtype=np.float64)
        if L.shape != (d, d):
            raise ShapeError(f"loading must have shape ({d}, {d}), got {L.shape}")
        check_finite(L, "loading")
    steps = integer(steps, "steps", minimum=1)
    eta_v = float(eta) if isinstance(eta, int | float | np.number) else np.nan
    if not np.isfinite(eta_v):
        raise InputError(f"eta must be a finite number, got {eta!r}")
    eta = float(eta)
    if isinstance(material, CrystalPlasticity):
        o = material.orientation if orientation is None else orientation
        n = n_orientations(o, d) or 1
        state = material.initial_state(n, o)
        N = material.nslip
    else:
        n = 1 if orientation is None else int(np.asarray(orientation).shape[0])
        state = material.initial_state(n)
        N = 0
    t = np.arange(1, steps + 1, dtype=np.float64)
    Fs = np.array([expm(eta * ti * L) for ti in t])
    stress = np.empty((steps, n, d, d))
    gamma = np.zeros((steps, n, N))
    s = np.zeros((steps, n, N))
    rot = np.zeros((steps, n))
    rate = np.full((steps, n), np.nan)
    plastic = np.zeros((steps, n), dtype=bool)
    states = []
    for k in range(steps):
        F = np.broadcast_to(Fs[k], (n, d, d))
        if getattr(material, "rate_dependent", False):
            state = {**state, "dt": np.asarray(1.0)}  # t = 1..steps: unit time increments
        P, state, _ = material.update(F, state)
        stress[k] = cauchy_stress(P, F)
        if N:
            gamma[k] = state["gamma"]
            s[k] = state["s"]
            rot[k] = state["reorientation"]
            plastic[k] = state["plastic"] > 0.0
            if "theta_rate" in state:
                rate[k] = np.degrees(state["theta_rate"])
        states.append(state)
    first = np.argmax(plastic, axis=0) + 1
    yield_step = np.where(plastic.any(axis=0), first, 0).astype(np.int64)
    return MaterialPointResult(t, Fs, stress, gamma, s, rot, rate, plastic, yield_step, states)
