"""Speed-versus-accuracy sweeps: :func:`pdlin.tradeoff` and the bundled problems.

See ``docs/tradeoff.md`` ("Choosing a model, horizon and solver").
"""

from __future__ import annotations

from .core import (
    METRIC_COLUMNS,
    SOLVE_KEYS,
    TradeoffCase,
    TradeoffResult,
    interpolate_field,
    point_key,
    tradeoff,
)
from .problems import (
    FACTORIES,
    MODEL_NAMES,
    affine_patch,
    anisotropic_block,
    graded_bar,
    make_model,
    plate_with_hole,
    plate_with_hole_ogrid,
    square_hole_plate,
    tension_bar,
)

__all__ = [
    "tradeoff",
    "TradeoffCase",
    "TradeoffResult",
    "SOLVE_KEYS",
    "METRIC_COLUMNS",
    "interpolate_field",
    "point_key",
    "make_model",
    "MODEL_NAMES",
    "graded_bar",
    "tension_bar",
    "affine_patch",
    "plate_with_hole",
    "anisotropic_block",
    "square_hole_plate",
    "plate_with_hole_ogrid",
    "FACTORIES",
]
