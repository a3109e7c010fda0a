"""Verification utilities: independent reference solutions to check pdlin against.

These are not peridynamic models.  They exist so that tests and examples can compare pdlin's
results with a classical reference (e.g. a Q4 finite-element solve, spec 002 §9.1) without
each carrying its own copy of the reference solver.
"""

from __future__ import annotations

from .fem import evaluate_q4, plate_extension_q4, q4_stiffness, solve_q4

__all__ = ["evaluate_q4", "plate_extension_q4", "q4_stiffness", "solve_q4"]
