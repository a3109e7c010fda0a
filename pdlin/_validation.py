"""Small argument-checking helpers shared by the package (internal)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError, InputTypeError, NonFiniteError, ShapeError


def as_float_array(value: Any, name: str, *, ndim: int | None = None) -> np.ndarray:
    """Return ``value`` as a float64 array, checking dimensionality and finiteness.

    Complex input raises :class:`InputTypeError` (its imaginary part would be dropped).
    """
    try:
        is_complex = np.iscomplexobj(value)
    except (TypeError, ValueError):  # ragged sequences: reported by the conversion below
        is_complex = False
    if is_complex:
        raise InputTypeError(f"{name} must be real, got complex dtype {np.asarray(value).dtype}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric, got {type(value).__name__}: {exc}") from exc
    if ndim is not None and arr.ndim != ndim:
        raise ShapeError(f"{name} must be a {ndim}-D array, got shape {arr.shape}")
    check_finite(arr, name)
    return arr


def check_finite(arr: np.ndarray, name: str) -> None:
    """Raise :class:`NonFiniteError` naming the first bad entry of ``arr``."""
    if arr.size and not np.all(np.isfinite(arr)):
        if arr.ndim == 0:
            raise NonFiniteError(f"{name} must be finite, got {arr[()]}")
        bad = np.argwhere(~np.isfinite(arr))[0]
        idx = tuple(int(k) for k in bad)
        raise NonFiniteError(
            f"{name} must be finite, got {arr[idx]} at index {idx if len(idx) > 1 else idx[0]}"
        )


def positive_scalar(value: Any, name: str) -> float:
    """Return ``value`` as a positive finite float or raise :class:`InputError`."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a positive number, got {value!r}") from exc
    if not np.isfinite(v) or v <= 0.0:
        raise InputError(f"{name} must be > 0, got {v}")
    return v


def integer(value: Any, name: str, *, minimum: int | None = None) -> int:
    """Return ``value`` as an int (bools, strings and non-integral floats raise).

    Integral floats such as ``3.0`` are accepted; ``minimum`` is an inclusive lower bound.
    """
    ok = isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)
    if not ok and isinstance(value, float | np.floating) and float(value).is_integer():
        ok = True
    if not ok:
        bound = "" if minimum is None else f" >= {minimum}"
        shown = value.item() if isinstance(value, np.generic) else value
        raise InputError(f"{name} must be an integer{bound}, got {shown!r}")
    v = int(value)
    if minimum is not None and v < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {v}")
    return v


def tolerance(value: Any, name: str) -> float:
    """Return ``value`` as a relative tolerance: a finite real number in ``(0, 1)``."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.number):
        raise InputError(f"{name} must be a number in (0, 1), got {value!r}")
    v = float(value)
    if not (np.isfinite(v) and 0.0 < v < 1.0):
        raise InputError(f"{name} must be a number in (0, 1), got {v}")
    return v


def as_bool(value: Any, name: str) -> bool:
    """Return ``value`` if it is a bool (numpy bools too), else raise :class:`InputTypeError`."""
    if not isinstance(value, bool | np.bool_):
        raise InputTypeError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def as_displacement(u: Any, n: int, d: int) -> np.ndarray:
    """``u`` as a finite ``(n, d)`` float array (any shape with ``n * d`` entries)."""
    arr = np.asarray(u, dtype=float)
    if arr.size != n * d:
        raise ShapeError(f"u must have {n * d} entries (shape ({n}, {d})), got shape {arr.shape}")
    arr = arr.reshape(n, d)
    check_finite(arr, "u")
    return arr
