"""Influence functions omega(|xi|, delta) as plain vectorized functions."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import InputError, InputTypeError, NonFiniteError

__all__ = ["INFLUENCE_FUNCTIONS", "influence_function", "evaluate_influence"]

InfluenceFunction = Callable[[np.ndarray, np.ndarray], np.ndarray]


def constant(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """Return ``omega = 1`` for every bond.

    Parameters
    ----------
    length : ndarray of float
        Bond lengths ``|xi|``.
    horizon : ndarray of float
        Horizon ``delta`` of each bond's owner, same shape as ``length``.

    Returns
    -------
    ndarray of float
        ``omega`` per bond, same shape as ``length``.
    """
    return np.ones_like(length)


def inverse(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """Return ``omega = 1 / |xi|`` (units 1/length).

    Parameters
    ----------
    length : ndarray of float
        Bond lengths ``|xi|``.
    horizon : ndarray of float
        Horizon ``delta`` of each bond's owner, same shape as ``length``.

    Returns
    -------
    ndarray of float
        ``omega`` per bond, same shape as ``length``.
    """
    return 1.0 / length


def delta_over_r(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """Return ``omega = delta / |xi|`` (dimensionless).

    The default of Prakash, anisotropic micromoduli (§4).

    Parameters
    ----------
    length : ndarray of float
        Bond lengths ``|xi|``.
    horizon : ndarray of float
        Horizon ``delta`` of each bond's owner, same shape as ``length``.

    Returns
    -------
    ndarray of float
        ``omega`` per bond, same shape as ``length``.
    """
    return horizon / length


def gaussian(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """Return ``omega = exp(-|xi|^2 / delta^2)``.

    Parameters
    ----------
    length : ndarray of float
        Bond lengths ``|xi|``.
    horizon : ndarray of float
        Horizon ``delta`` of each bond's owner, same shape as ``length``.

    Returns
    -------
    ndarray of float
        ``omega`` per bond, same shape as ``length``.
    """
    return np.exp(-((length / horizon) ** 2))


def hat(length: np.ndarray, horizon: np.ndarray) -> np.ndarray:
    """Return ``omega = 1 - |xi| / delta`` (zero on the horizon boundary).

    Parameters
    ----------
    length : ndarray of float
        Bond lengths ``|xi|``.
    horizon : ndarray of float
        Horizon ``delta`` of each bond's owner, same shape as ``length``.

    Returns
    -------
    ndarray of float
        ``omega`` per bond, same shape as ``length``.
    """
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

    Parameters
    ----------
    spec : str or callable
        A name (``'constant'``, ``'inverse'``, ``'delta_over_r'``, ``'gaussian'``,
        ``'hat'``) or a function ``f(length, horizon) -> omega``.

    Returns
    -------
    callable
        ``f(length, horizon) -> omega`` (a callable ``spec`` is returned unchanged).

    Raises
    ------
    InputError
        If ``spec`` is an unknown name.
    InputTypeError
        If ``spec`` is neither a str nor callable.

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

    Parameters
    ----------
    spec : str or callable
        Influence function name or ``f(length, horizon) -> omega``.
    length : ndarray of float
        Bond lengths ``|xi|``.
    horizon : ndarray of float
        Horizon of each bond's owner, same shape as ``length``.
    allow_negative : bool
        Accept negative values (signed higher-order weights).

    Returns
    -------
    ndarray of float
        ``omega`` per bond, shape of ``length`` (broadcast if the function returns a
        scalar).

    Raises
    ------
    NonFiniteError
        If a value is NaN or infinite.
    InputError
        If a value is negative and ``allow_negative`` is False, or ``spec`` is unknown.
    InputTypeError
        If ``spec`` is neither a str nor callable.
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
