"""Input/output: result files, time series, system export and scene files."""

from .read import ResultFile, read_result
from .results import (
    export_system,
    write_homogenized_csv,
    write_nonlinear,
    write_points,
    write_result,
    write_series,
)

__all__ = [
    "write_points",
    "write_result",
    "write_series",
    "write_nonlinear",
    "write_homogenized_csv",
    "export_system",
    "read_result",
    "ResultFile",
]
