"""The options of :func:`pdlin.solve_nonlinear` as small frozen records.

:func:`pdlin.solve_nonlinear` keeps its keyword interface; it checks the keywords and
groups them into a :class:`StepControl` (load steps, cut-backs, fallback, polish), a
:class:`NewtonOptions` and an :class:`ADROptions`, which the load stepping of
:mod:`pdlin.solvers.stepping` reads.

Examples
--------
>>> from pdlin.solvers.options import NewtonOptions, StepControl
>>> NewtonOptions(rtol=1e-10).maxiter
25
>>> StepControl(method="newton").fallback_cutbacks
2
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._validation import as_float_array, integer
from ..errors import InputError, InputTypeError, ShapeError
from .linear import SOLVERS

__all__ = [
    "METHODS",
    "PREDICTORS",
    "GLOBALIZATIONS",
    "FORCINGS",
    "KRYLOV",
    "NewtonOptions",
    "ADROptions",
    "StepControl",
    "check_keywords",
    "resolve_density",
]

#: the load-step drivers of :func:`pdlin.solve_nonlinear`
METHODS = ("newton", "adr", "auto")
#: the starts of a load step
PREDICTORS = (
    "auto",
    "affine",
    "tangent",
    "second-order",
    "committed-tangent",
    "extrapolate",
    "previous",
)
#: Newton's globalizations: backtracking line search, or pseudo-transient continuation
GLOBALIZATIONS = ("line-search", "ptc")
#: Newton's forcing terms (the Krylov tolerance of ``linear_solver='krylov'``)
FORCINGS = ("fixed", "eisenstat-walker")
#: the linear solver of Newton that keeps one AMG hierarchy of the elastic tangent
KRYLOV = "krylov"
#: what ``resume`` accepts
_RESUME = (False, True, "branch")


@dataclass(frozen=True)
class NewtonOptions:
    """Newton's options (also those of ADR's polish).

    Attributes
    ----------
    rtol : float
        Convergence ``‖r_free‖ <= rtol`` x force scale.
    maxiter : int
        Iteration budget per (sub)step.
    line_search : bool
        Backtracking on or off.
    linear_solver : str
        Inner linear solver ('auto': direct up to 2·10⁵ DOFs in 2D / 3·10⁴ in 3D;
        'krylov': GMRES with one AMG hierarchy of the symmetrized elastic tangent, built
        once per run).
    relax : int
        ADR iterations at a stall (0: off).
    forcing : {'fixed', 'eisenstat-walker'}
        Krylov tolerance of ``'krylov'``: 1e-10, or Eisenstat & Walker's (1996) choice 2.
    globalization : {'line-search', 'ptc'}
        Backtracking line search, or pseudo-transient continuation with the ADR density
        as the shift (``pdlin.solvers.ptc.ptc_step``).
    """

    rtol: float = 1e-8
    maxiter: int = 25
    line_search: bool = True
    linear_solver: str = "auto"
    relax: int = 0
    forcing: str = "fixed"
    globalization: str = "line-search"


@dataclass(frozen=True)
class ADROptions:
    """Adaptive dynamic relaxation's options, resolved (no ``None`` defaults left).

    Attributes
    ----------
    e_l : float
        Target of the relative criteria e₁, e₂.
    density : (ndof,) ndarray or None
        An explicit fictitious density, or None for the Gershgorin density.
    density_safety : float
        Safety factor of the Gershgorin density.
    dt : float
        ADR time step.
    damping : float or None
        Constant damping, or None for the adaptive Rayleigh quotient.
    c0 : float
        Initial damping.
    maxiter : int
        Iteration budget per increment.
    floor : float
        Absolute floor on ``‖r‖`` relative to the force scale.
    stall : int
        Stall window of the polish (ADR iterations).
    """

    e_l: float = 1e-6
    density: np.ndarray | None = None
    density_safety: float = 1.1
    dt: float = 1.0
    damping: float | None = None
    c0: float = 1.0
    maxiter: int = 20_000
    floor: float = 1e-12
    stall: int = 2500


@dataclass(frozen=True)
class StepControl:
    """Load stepping: the driver, the predictor, cut-backs, fallback and polish.

    Attributes
    ----------
    method : {'auto', 'newton', 'adr'}
        Driver of each load step.
    predictor : str
        Start of each increment (one of ``PREDICTORS``).
    max_cutbacks : int
        Halvings of one increment (Newton and ADR).
    fallback_cutbacks : int
        Newton's halvings in a load step after an ADR fallback (``'auto'``).
    newton_backoff : bool
        Skip Newton after repeated fallbacks unless the streak is a power of two.
    polish : bool
        Finish stalled ADR increments with Newton.
    """

    method: str = "auto"
    predictor: str = "auto"
    max_cutbacks: int = 8
    fallback_cutbacks: int = 2
    newton_backoff: bool = True
    polish: bool = True

    def fingerprint(self, newton: NewtonOptions, adr: ADROptions) -> dict[str, Any]:
        """Return the options that change a run's iterates (checked on resume).

        Newton's where Newton runs (also as ADR's polish), ADR's where ADR runs; not
        progress, output, ``keep_states`` or the number of threads.

        Parameters
        ----------
        newton : NewtonOptions
            Newton's options.
        adr : ADROptions
            ADR's options.

        Returns
        -------
        dict
            Option name to value, in a fixed order (the checkpoint digests it).
        """
        method, polish = self.method, self.polish
        out: dict[str, Any] = {"method": method, "predictor": self.predictor}
        if method != "adr" or polish:
            out.update(
                rtol=newton.rtol,
                maxiter=newton.maxiter,
                line_search=newton.line_search,
                max_cutbacks=self.max_cutbacks,
                linear_solver=newton.linear_solver,
                relax=newton.relax,
            )
            # only when not the default: checkpoints written before these options existed
            # keep their fingerprint
            if newton.forcing != "fixed":
                out.update(forcing=newton.forcing)
            if newton.globalization != "line-search":
                out.update(globalization=newton.globalization)
        if method == "auto":
            out.update(fallback_cutbacks=self.fallback_cutbacks, newton_backoff=self.newton_backoff)
        if method != "newton":
            lam = adr.density
            out.update(
                max_cutbacks=self.max_cutbacks,
                e_l=adr.e_l,
                density="gershgorin" if lam is None else lam,
                density_safety=adr.density_safety if lam is None else None,
                dt=adr.dt,
                damping=adr.damping,
                c0=adr.c0,
                adr_maxiter=adr.maxiter,
                floor=adr.floor,
                polish=polish,
                adr_stall=adr.stall if polish else None,
            )
        return out


def check_keywords(kw: dict[str, Any]) -> int | None:
    """Check the scalar keywords of :func:`pdlin.solve_nonlinear` in its documented order.

    Parameters
    ----------
    kw : dict
        The keywords by name (``method``, ``rtol``, ``e_l``, ``floor``, ``maxiter``,
        ``max_cutbacks``, ``fallback_cutbacks``, ``relax``, ``progress_every``,
        ``snapshot_every``, ``damping``, ``c0``, ``polish``, ``adr_stall``,
        ``newton_backoff``, ``linear_solver``, ``forcing``, ``globalization``,
        ``adr_maxiter``, ``resume``, ``checkpoint``).

    Returns
    -------
    int or None
        ``adr_maxiter`` as an integer (None: the default budget).

    Raises
    ------
    InputError
        An option is out of range.
    InputTypeError
        ``newton_backoff`` is not a bool or ``checkpoint`` not a path.
    """
    method = kw["method"]
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    for name in ("rtol", "e_l", "floor"):
        val = kw[name]
        if not (isinstance(val, int | float) and math.isfinite(val) and val > 0.0):
            raise InputError(f"{name} must be a positive number, got {val!r}")
    for name in ("maxiter", "max_cutbacks", "fallback_cutbacks", "relax"):
        ival = kw[name]
        if isinstance(ival, bool) or not isinstance(ival, int) or ival < 0:
            raise InputError(f"{name} must be an integer >= 0, got {ival!r}")
    for name in ("progress_every", "snapshot_every"):
        secs = kw[name]
        if (
            isinstance(secs, bool)
            or not (isinstance(secs, int | float) and math.isfinite(secs))
            or secs < 0
        ):
            raise InputError(f"{name} must be a finite number of seconds >= 0, got {secs!r}")
    for name in ("damping", "c0"):
        opt = kw[name]
        if opt is None and name == "damping":
            continue
        if not (isinstance(opt, int | float) and not isinstance(opt, bool)) or not (
            math.isfinite(opt) and opt >= 0
        ):
            raise InputError(f"{name} must be a finite number >= 0, got {opt!r}")
    polish, adr_stall = kw["polish"], kw["adr_stall"]
    if polish is not None and not isinstance(polish, bool):
        raise InputError(f"polish must be True, False or None, got {polish!r}")
    if adr_stall is not None and (
        isinstance(adr_stall, bool) or not isinstance(adr_stall, int) or adr_stall < 1
    ):
        raise InputError(f"adr_stall must be an integer >= 1 (ADR iterations), got {adr_stall!r}")
    solvers = (*SOLVERS, KRYLOV)
    for name, allowed in (
        ("forcing", FORCINGS),
        ("globalization", GLOBALIZATIONS),
        ("linear_solver", solvers),
    ):
        if kw[name] not in allowed:
            raise InputError(f"{name} must be one of {allowed}, got {kw[name]!r}")
    if not isinstance(kw["newton_backoff"], bool):
        raise InputTypeError(f"newton_backoff must be True or False, got {kw['newton_backoff']!r}")
    adr_maxiter = kw["adr_maxiter"]
    if adr_maxiter is not None:
        adr_maxiter = integer(adr_maxiter, "adr_maxiter", minimum=1)
    resume, checkpoint = kw["resume"], kw["checkpoint"]
    if not any(resume is r or (isinstance(r, str) and resume == r) for r in _RESUME):
        raise InputError(f"resume must be True, False or 'branch', got {resume!r}")
    if resume and checkpoint is None:
        raise InputError("resume=True needs checkpoint= (the file to resume from), got None")
    if checkpoint is not None:
        if not isinstance(checkpoint, str | os.PathLike):
            raise InputTypeError(f"checkpoint must be a path, got {type(checkpoint).__name__}")
        parent = Path(checkpoint).parent
        if not parent.is_dir():
            raise InputError(
                f"checkpoint must be a path in an existing folder, got {os.fspath(checkpoint)!r} "
                f"(folder {str(parent)!r} does not exist)"
            )
    return adr_maxiter


def resolve_density(
    ndof: int, method: str, density: Any, dt: float | None
) -> tuple[np.ndarray | None, float]:
    """Resolve the ``density`` and ``dt`` keywords of :func:`pdlin.solve_nonlinear`.

    Parameters
    ----------
    ndof : int
        Number of DOFs of the system.
    method : str
        The load-step driver (the density is checked only where ADR may run).
    density : 'gershgorin', float or (ndof,) array_like
        The fictitious density keyword.
    dt : float or None
        The ADR time step keyword.

    Returns
    -------
    lam : (ndof,) ndarray or None
        The explicit density, or None for the Gershgorin density.
    dt : float
        The ADR time step (1 unless given).

    Raises
    ------
    InputError
        An unknown density name, a density <= 0, or an explicit density without ``dt``.
    ShapeError
        The density is neither a scalar nor of shape ``(ndof,)``.
    """
    if method not in ("adr", "auto"):
        return None, 1.0
    if isinstance(density, str):
        if density != "gershgorin":
            raise InputError(
                f"density must be 'gershgorin', a positive number or an array, got {density!r}"
            )
        return None, 1.0 if dt is None else float(dt)
    dens = as_float_array(density, "density")
    if dens.ndim > 1 or dens.size not in (1, ndof):
        raise ShapeError(f"density must be a scalar or have shape ({ndof},), got {dens.shape}")
    if np.any(dens <= 0):
        raise InputError(f"density must be > 0, got min {float(dens.min())}")
    if dt is None:
        raise InputError("an explicit ADR density needs dt (e.g. h sqrt(Λ / E_max))")
    return np.broadcast_to(dens.reshape(-1), (ndof,)).copy(), float(dt)
