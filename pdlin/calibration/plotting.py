"""Plots of calibrated micromoduli (matplotlib imported lazily: extra ``plotting``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError
from .calibrate import CalibrationResult
from .lattices import Family

__all__ = ["plot_micromoduli"]


def _pyplot() -> Any:
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "plot_micromoduli needs matplotlib: pip install 'pdlin[plotting]'"
        ) from exc
    return plt


def plot_micromoduli(
    result: CalibrationResult,
    family: Family | None = None,
    *,
    ax: Any = None,
    cmap: str = "viridis",
    size: float = 20.0,
) -> Any:
    """Plot micromoduli against bond direction.

    2D: polar scatter of ``c`` against the bond angle (colour = bond
    length).  3D: the unit bond directions on the sphere, coloured by
    ``c`` (collinear bonds of different length overlap).

    Parameters
    ----------
    result : CalibrationResult
        A single-family result (for a cloud pass ``result.families[k]``).
    family : Family, optional
        The family that was calibrated; defaults to the one stored in the
        result.
    ax : matplotlib Axes, optional
        A polar (2D) or 3D axes; created when omitted.
    cmap : str
    size : float
        Marker size.

    Returns
    -------
    matplotlib Axes

    Examples
    --------
    >>> import numpy as np, matplotlib
    >>> matplotlib.use("Agg")
    >>> from pdlin.calibration import lattice_family, calibrate_micromoduli, plot_micromoduli
    >>> fam = lattice_family(2, 3.0, lattice="triangular")
    >>> res = calibrate_micromoduli(np.diag([3.0, 2.0, 1.0]), fam, method="robust")
    >>> plot_micromoduli(res).name
    'polar'
    """
    fam = family if family is not None else result.extra.get("family")
    if fam is None:
        raise InputError(
            "family must be given for a result without a stored family (cloud results: "
            "pass result.families[k])"
        )
    c = np.asarray(result.micromoduli)
    if fam.n_bonds != c.size:
        raise InputError(
            f"family must hold one bond per micromodulus ({c.size}), got {fam.n_bonds} bonds"
        )
    plt = _pyplot()
    xi = fam.xi
    if fam.dim == 2:
        if ax is None:
            _, ax = plt.subplots(subplot_kw={"projection": "polar"})
        theta = np.arctan2(xi[:, 1], xi[:, 0])
        sc = ax.scatter(theta, c, c=fam.length, cmap=cmap, s=size)
        ax.figure.colorbar(sc, ax=ax, label="|xi|")
        ax.set_title("micromodulus vs bond angle")
        return ax
    if ax is None:
        fig = plt.figure()
        ax = fig.add_subplot(projection="3d")
    u = xi / fam.length[:, None]
    sc = ax.scatter(u[:, 0], u[:, 1], u[:, 2], c=c, cmap=cmap, s=size)
    ax.figure.colorbar(sc, ax=ax, label="micromodulus c")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.set_title("micromodulus on the direction sphere")
    return ax
