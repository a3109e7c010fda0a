"""Shared fixtures: small clouds in 1D/2D/3D; a file-size limit."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import pytest


@pytest.fixture
def file_size_limit():
    """``with file_size_limit(nbytes):`` lowers this process's RLIMIT_FSIZE (``ulimit -f``)
    to ``nbytes`` with SIGXFSZ ignored (as Python does at start-up), restored after."""
    import resource
    import signal

    @contextmanager
    def limit(nbytes: int):
        soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
        old = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, hard))
        try:
            yield
        finally:
            resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
            signal.signal(signal.SIGXFSZ, old)

    return limit


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261121)


@pytest.fixture
def spec004_tension():
    """Prakash, anisotropic micromoduli, Sec. 4.4: uniaxial tension of the 24³ cube (Δ = 1, centres
    at 0..23).

    Returns ``build(model, cloud, bonds) -> StaticProblem``: u_z = 0 on z = 0, u_x = 0 on
    x = 0, u_y = 0 on y = 0 (DOF elimination) and +z force 1 MN per top-layer particle.
    """
    import pdlin

    def build(model, cloud, bonds):
        top = cloud.point_set("z+")
        return pdlin.StaticProblem(
            model,
            cloud,
            bonds,
            dirichlet=[
                pdlin.Dirichlet("z-", 0.0, "z"),
                pdlin.Dirichlet("x-", 0.0, "x"),
                pdlin.Dirichlet("y-", 0.0, "y"),
            ],
            loads=[pdlin.TotalForce(top, [0.0, 0.0, 1e6 * top.size])],  # 1 MN per top particle
        )

    return build
