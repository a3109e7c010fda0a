"""Input/output: result files and scene files."""

from .results import write_points, write_result

__all__ = ["write_points", "write_result"]
