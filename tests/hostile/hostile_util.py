"""Shared helpers of the hostile-input suite."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import pdlin
from pdlin.errors import PdlinError


def expect(call: Callable[[], Any], exc: type[Exception], pattern: str) -> None:
    """``call()`` raises exactly a pdlin ``exc`` whose message matches ``pattern``."""
    with pytest.raises(exc, match=pattern) as info:
        call()
    assert isinstance(info.value, PdlinError), f"{type(info.value).__name__} is not a pdlin error"


def problem(**kw: Any) -> pdlin.StaticProblem:
    """A small valid 2D bond-based problem; keyword arguments replace its parts."""
    args: dict[str, Any] = dict(
        model=pdlin.BondBased(E=1.0),
        cloud=pdlin.grid((6, 6), 0.1),
        horizon=0.301,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", [1e-3, 0.0])],
    )
    args.update(kw)
    return pdlin.StaticProblem(**args)


NAN, INF = np.nan, np.inf
__all__ = ["expect", "problem", "NAN", "INF", "re"]
