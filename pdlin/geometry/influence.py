"""Influence functions omega(|xi|, delta) as plain vectorized functions."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import InputError, InputTypeError, NonFiniteError

__all__ = ["INFLUENCE_FUNCTIONS", "influence_function", "evaluate_influence"]

InfluenceFunction = Callable[[np.ndarray, np.ndarray], np.ndarray]


def constant(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """omega = 1."""
    return np.ones_like(length)


def inverse(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """omega = 1 / |xi| (units 1/length)."""
    return 1.0 / length


def delta_over_r(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """omega = delta / |xi| (dimensionless; seed 004's default)."""
    return horizon / length


def gaussian(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """omega = exp(-|xi|^2 / delta^2)."""
    return np.exp(-((length / horizon) ** 2))


def hat(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """omega = 1 - |xi| / delta (zero on the horizon boundary)."""
    return 1.0 - length / horizon


#: Influence functions ``omega(|xi|, delta)`` by name (``influence=`` of :func:`pdlin.find_bonds`).
INFLUENCE_FUNCTIONS: dict[str, InfluenceFunction] = {
    "constant": constant,
    "inverse": inverse,
    "delta_over_r": delta_over_r,
    "gaussian": gaussian,
    "hat": hat,
}


def influence_function(spec: str | InfluenceFunction) -> InfluenceFunction:
    """Resolve a name of :data:`INFLUENCE_FUNCTIONS` or a callable.

    Examples
    --------
    >>> import numpy as np
    >>> influence_function("delta_over_r")(np.array([1.0, 2.0]), np.array([2.0, 2.0]))
    array([2., 1.])
    """
    if callable(spec):
        return spec
    if isinstance(spec, str):
        try:
            return INFLUENCE_FUNCTIONS[spec]
        except KeyError:
            raise InputError(
                f"influence must be one of {sorted(INFLUENCE_FUNCTIONS)} or a callable, "
                f"got {spec!r}"
            ) from None
    raise InputTypeError(f"influence must be a string or a callable, got {type(spec).__name__}")


def evaluate_influence(
    spec: str | InfluenceFunction,
    length: np.ndarray,
    horizon: np.ndarray,
    *,
    allow_negative: bool = False,
) -> np.ndarray:
    """Evaluate an influence function on bonds and check the result.

    Non-finite values always raise.  Negative values raise unless
    ``allow_negative`` (higher-order correspondence weights are negative by
    design; for bond-based and state-based models they would be unstable).
    """
    fn = influence_function(spec)
    omega = np.asarray(fn(length, horizon), dtype=np.float64)
    if omega.shape != length.shape:
        omega = np.broadcast_to(omega, length.shape).copy()
    if omega.size and not np.all(np.isfinite(omega)):
        raise NonFiniteError(f"influence function returned non-finite values ({spec!r})")
    if omega.size and omega.min() < 0 and not allow_negative:
        raise InputError(
            f"influence function must be >= 0 inside the horizon, got min {omega.min():.3g} "
            "(pass allow_negative_influence=True for signed weights such as higher-order "
            "correspondence weights)"
        )
    return omega
