"""Deprecated: sparsity reports moved to :mod:`pdlin.analysis.sparsity`, spy plots to plotting.

This module re-exports them from :mod:`pdlin.analysis.sparsity` and :mod:`pdlin.plotting`
for one release.
"""

import warnings

from ..analysis.sparsity import (
    FILL_ORDERINGS,
    SparsityReport,
    coupling_pattern,
    rcm_permutation,
    sparsity_report,
)
from ..plotting import plot_spy

warnings.warn(
    "pdlin.operators.sparsity is deprecated: import sparsity_report, SparsityReport, "
    "coupling_pattern, rcm_permutation and FILL_ORDERINGS from pdlin.analysis, plot_spy "
    "from pdlin.plotting",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = [
    "SparsityReport",
    "sparsity_report",
    "coupling_pattern",
    "rcm_permutation",
    "plot_spy",
    "FILL_ORDERINGS",
]
