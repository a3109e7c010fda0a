"""Deprecated: plots of calibrated micromoduli moved to :mod:`pdlin.plotting`.

This module re-exports :func:`~pdlin.plotting.plot_micromoduli` for one release.
"""

import warnings

from ..plotting import plot_micromoduli

warnings.warn(
    "pdlin.calibration.plotting is deprecated: import plot_micromoduli from pdlin.plotting",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ["plot_micromoduli"]
