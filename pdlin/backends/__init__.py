"""Optional solver backends beyond scipy (imported lazily).

* :mod:`pdlin.backends.petsc` -- distributed assembly and solve on PETSc
  through petsc4py (``pip install "pdlin[petsc]"`` after installing PETSc,
  see ``docs/petsc.md``); used by ``pdlin.solve(problem, backend="petsc")``.
"""

from __future__ import annotations

__all__ = ["BACKENDS"]

#: values of ``pdlin.solve(..., backend=...)`` and of the scene key ``[solver] backend``
BACKENDS = ("scipy", "petsc")
