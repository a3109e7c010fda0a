"""Compact Bonds (issue 33): what find_bonds keeps resident, and that it changes no value."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

import pdlin
from pdlin.geometry import Bonds

NAMES = ("i", "j", "xi", "length", "omega", "volume_j")


def _full(b: Bonds) -> Bonds:
    """The same bonds built from arrays (the constructor stores what it is given)."""
    return Bonds(b.n_points, b.i, b.j, b.xi, b.length, b.omega, b.volume_j, b.indptr,
                 b.horizon, b.shape, b.influence)  # fmt: skip


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def test_lattice_bonds_hold_under_10_bytes_per_bond() -> None:
    # 3D, δ = 3.015 h, constant influence (the default solve's bonds): j (int64), the
    # stencil index (uint8) and indptr; the full arrays were 64 B per bond
    b = pdlin.find_bonds(pdlin.grid((12, 11, 10)), ratio=3.015)
    assert b.nbytes() / b.n_bonds < 10.0
    held = sum(v.nbytes for v in vars(b).values() if isinstance(v, np.ndarray))
    assert held / b.n_bonds < 10.0
    assert not {"i", "xi", "length", "omega", "volume_j"} & set(vars(b))
    assert _full(b).nbytes() / b.n_bonds > 60.0


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(ratio=3.015),
        dict(ratio=3.015, influence="gaussian"),
        dict(ratio=2.0, shape="cube", influence="inverse"),
        dict(ratio=2.5, method="tree"),
        dict(ratio=2.5, influence=lambda length, h: 1.0 + 0.0 * np.arange(length.size)),
        dict(ratio=2.5, exclude=lambda a, c: (a[:, 0] < 0.35) & (c[:, 0] > 0.35)),
    ],
)
def test_values_match_the_full_arrays(kwargs: dict) -> None:
    cloud = pdlin.grid((9, 8, 7), spacing=0.1)
    b = pdlin.find_bonds(cloud, **kwargs)
    full = _full(b)
    nb = b.n_bonds
    for name in NAMES:
        ref = np.asarray(getattr(full, name))
        assert _same(getattr(b, name), ref), name
        for lo, hi in ((0, nb), (0, 1), (17, 400), (nb - 5, nb), (nb, nb)):
            assert _same(b.values(name, lo, hi), ref[lo:hi]), (name, lo, hi)
            assert _same(full.values(name, lo, hi), ref[lo:hi]), (name, lo, hi)
    assert b.dim == 3 and nb == full.n_bonds
    mask = b.j % 3 != b.i % 3  # symmetric: depends on the pair only
    kept, kept_full = b.keep(mask), full.keep(mask)
    for name in NAMES + ("indptr",):
        assert _same(getattr(kept, name), getattr(kept_full, name)), name
    assert kept.nbytes() < kept_full.nbytes()


def test_compact_bonds_replace_pickle_and_errors() -> None:
    b = pdlin.find_bonds(pdlin.grid((6, 6, 6)), ratio=2.0)
    r = dataclasses.replace(b, omega=np.full(b.n_bonds, 7.0))
    assert _same(r.xi, b.xi) and float(r.omega[3]) == 7.0 and "omega" in vars(r)
    c = pickle.loads(pickle.dumps(b))
    assert _same(c.xi, b.xi) and _same(c.i, b.i)
    with pytest.raises(AttributeError):
        b.no_such_attribute  # noqa: B018
    with pytest.raises(pdlin.errors.InputError):
        b.values("indptr")


@pytest.mark.parametrize("method", ["lattice", "tree"])
def test_stiffness_and_fields_match_full_bonds(method: str) -> None:
    # several assembly chunks (65,536 bonds each) and both assembly paths (numba / numpy)
    cloud = pdlin.grid((24, 22, 20), spacing=0.1)
    b = pdlin.find_bonds(cloud, ratio=2.5, method=method)
    assert b.n_bonds > 3 * (1 << 16)
    full = _full(b)
    model = pdlin.BondBased(E=1.0e9, nu=0.25)
    ka, kb = model.stiffness(cloud, b), model.stiffness(cloud, full)
    assert _same(ka.data, kb.data) and _same(ka.indices, kb.indices)
    from pdlin.fields import deformation_gradient

    u = np.sin(7.0 * cloud.points)
    assert _same(deformation_gradient(cloud, b, u), deformation_gradient(cloud, full, u))


def test_plan_counts_the_compact_bonds() -> None:
    # the estimate's stages after the search count what the bonds keep: 9 B per bond on a
    # grid, 24 + 8 d after a tree search (pdlin.resources.resident_bonds_bytes)
    from pdlin.problem import plan_memory
    from pdlin.resources import bonds_bytes, estimate_static_run, resident_bonds_bytes

    cloud = pdlin.grid((16, 16, 16), spacing=1.0 / 16)
    kw = dict(dirichlet=[pdlin.Dirichlet("x-", 0.0)], loads=[pdlin.TotalForce("x+", [1.0, 0, 0])])
    prob = pdlin.StaticProblem(pdlin.BondBased(E=1e9, nu=0.25), cloud, ratio=3.015, **kw)
    plan = plan_memory(prob, "amg-cg")
    nb, n = plan.n_bonds, cloud.n
    assert resident_bonds_bytes(nb, n, 3, True) == nb * 9 + 8 * (n + 1)
    full = estimate_static_run(n, nb, plan.nnz_blocks, 3, base=plan.base)
    lean = estimate_static_run(
        n,
        nb,
        plan.nnz_blocks,
        3,
        base=plan.base,
        resident_bonds=resident_bonds_bytes(nb, n, 3, True),
    )
    assert plan.stages == lean.stages
    gap = bonds_bytes(nb, n, 3) - resident_bonds_bytes(nb, n, 3, True)
    assert full.stages["solve"] - lean.stages["solve"] == gap
    assert full.stages["bonds"] == lean.stages["bonds"]  # the search holds every array
    tree = plan_memory(
        pdlin.StaticProblem(pdlin.BondBased(E=1e9, nu=0.25), cloud, ratio=3.015,
                            bond_options={"method": "tree"}, **kw),
        "amg-cg",
    )  # fmt: skip
    assert tree.stages["solve"] - plan.stages["solve"] == nb * (24 + 24 - 9)
