"""Optional solver backends beyond scipy (their libraries are imported on first use).

* :mod:`pdlin.backends.petsc` -- distributed assembly and solve on PETSc
  through petsc4py (``pip install "pdlin[petsc]"`` after installing PETSc,
  see ``docs/petsc.md``); used by ``pdlin.solve(problem, backend="petsc")``.
  petsc4py itself is imported by the first PETSc call, not by ``import pdlin``.
"""

from __future__ import annotations

__all__ = ["BACKENDS"]

#: values of ``pdlin.solve(..., backend=...)`` and of the scene key ``[solver] backend``
BACKENDS = ("scipy", "petsc")
