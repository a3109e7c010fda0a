"""Deprecated alias of the nonlinear step modules (moved; works for one release).

``StepOutcome`` and ``StepFailed`` are in :mod:`pdlin.solvers.outcome`, ``newton_step`` in
:mod:`pdlin.solvers.newton`, ``adr_step``, ``adr_density`` and ``adr_time_step`` in
:mod:`pdlin.solvers.adr`; all are also importable from :mod:`pdlin.solvers`.
"""

import warnings

from .adr import adr_density, adr_step, adr_time_step
from .newton import newton_step
from .outcome import StepFailed, StepOutcome

warnings.warn(
    "pdlin.solvers.nonlinear is deprecated: import from pdlin.solvers (or pdlin.solvers.adr, "
    ".newton, .outcome) instead",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ["StepOutcome", "StepFailed", "newton_step", "adr_step", "adr_density", "adr_time_step"]
