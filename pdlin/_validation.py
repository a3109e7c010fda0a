"""Small argument-checking helpers shared by the package (internal)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError, NonFiniteError, ShapeError


def as_float_array(value: Any, name: str, *, ndim: int | None = None) -> np.ndarray:
    """Return ``value`` as a float64 array, checking dimensionality and finiteness."""
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


def as_displacement(u: Any, n: int, d: int) -> np.ndarray:
    """``u`` as a finite ``(n, d)`` float array (any shape with ``n * d`` entries)."""
    arr = np.asarray(u, dtype=float)
    if arr.size != n * d:
        raise ShapeError(f"u must have {n * d} entries (shape ({n}, {d})), got shape {arr.shape}")
    arr = arr.reshape(n, d)
    check_finite(arr, "u")
    return arr
