"""Throttled progress lines for long stages (iterations, bytes written)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

#: seconds between two progress lines of one stage
PROGRESS_EVERY = 5.0


class Throttle:
    """Call ``say(message())`` at most every ``every`` seconds.

    The first call after ``every`` seconds of the stage, then every ``every`` seconds.

    Examples
    --------
    >>> lines = []
    >>> tick = Throttle(lines.append, every=0.0)
    >>> tick(lambda: "iteration 1")
    >>> lines
    ['iteration 1']
    """

    def __init__(self, say: Callable[[str], None], every: float | None = None) -> None:
        self.say = say
        self.every = float(PROGRESS_EVERY if every is None else every)
        self.last = time.perf_counter()

    def __call__(self, message: Callable[[], str]) -> None:
        now = time.perf_counter()
        if now - self.last >= self.every:
            self.last = now
            self.say(message())


class ResidualHistory(list[float]):
    """List relative residuals and report them as the Krylov solvers append them.

    The iteration count and the latest residual go through a :class:`Throttle`.
    """

    def __init__(self, tick: Throttle, label: str) -> None:
        super().__init__()
        self.tick = tick
        self.label = label

    def append(self, value: Any) -> None:
        super().append(value)
        self.tick(lambda: f"  {self.label}: iteration {len(self) - 1}, residual {value:.2e}")


def linear_progress(progress: Callable[[str], None], prefix: str) -> Callable[[str], None]:
    """Filter the progress of a linear solve run many times over (Newton iterations, damage).

    Passes its iteration lines (throttled by :func:`pdlin.solvers.solve_linear`) and an
    AMG set-up that took longer than :data:`PROGRESS_EVERY` seconds, each prefixed with
    ``prefix``; not the set-up line of every quick solve, nor the stage lines of
    :func:`pdlin.solve` (those not indented).

    Examples
    --------
    >>> lines = []
    >>> say = linear_progress(lines.append, "Newton iteration 2")
    >>> say("bonds")
    >>> say("  AMG set-up on 1,000 unknowns, 9,000 nonzeros")
    >>> say("  amg-cg: iteration 7, residual 1.00e-03")
    >>> lines
    ['Newton iteration 2: amg-cg: iteration 7, residual 1.00e-03']
    """
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        if not msg.startswith("  "):
            return
        msg = msg.strip()
        if msg.startswith("AMG") and time.perf_counter() - t0 < PROGRESS_EVERY:
            return
        progress(f"{prefix}: {msg}")

    return say
