"""Threaded cell-list bond search (numba) against the cKDTree path (issue 13, bond search)."""

from __future__ import annotations

import numpy as np
import pytest

import pdlin
from pdlin import _kernels
from pdlin.errors import DuplicatePointError
from pdlin.geometry import bonds as bonds_mod

pytest.importorskip("numba")

FIELDS = ("i", "j", "xi", "length", "omega", "volume_j", "indptr")


@pytest.fixture(autouse=True)
def _small_chunks(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(_kernels, "_MIN_WORK", 0)  # small clouds go to the cell search too
    monkeypatch.setattr(bonds_mod, "_CELL_CHUNK", 37)  # many point chunks
    yield
    pdlin.set_num_threads(None)


def _both(monkeypatch: pytest.MonkeyPatch, cloud: pdlin.PointCloud, **kw):
    monkeypatch.setattr(_kernels, "_loaded", False)  # the cKDTree path
    ref = pdlin.find_bonds(cloud, **kw)
    monkeypatch.setattr(_kernels, "_loaded", None)
    out = []
    for nt in (1, 2, 3):
        pdlin.set_num_threads(nt)
        out.append(pdlin.find_bonds(cloud, **kw))
    return ref, out


def _cloud(dim: int, seed: int = 0) -> pdlin.PointCloud:
    g = pdlin.grid((9, 8, 7)[:dim] if dim > 1 else (60,), spacing=0.1)
    rng = np.random.default_rng(seed)
    return pdlin.PointCloud(
        g.points + rng.normal(scale=0.012, size=g.points.shape), volumes=g.volumes
    )


@pytest.mark.parametrize("dim", [1, 2, 3])
@pytest.mark.parametrize(
    "kw",
    [
        {"horizon": 0.3015},
        {"ratio": 2.5},
        {"horizon": 0.2, "shape": "cube"},
        {"horizon": 0.2, "shape": "box", "axes": [0.3, 0.15, 0.2]},
        {"horizon": 0.2, "shape": "ellipsoid", "axes": [0.3, 0.15, 0.2]},
    ],
)
def test_cell_search_equals_kdtree(monkeypatch: pytest.MonkeyPatch, dim: int, kw) -> None:
    """Every bond array bitwise the cKDTree path's (CSR order, bond vectors, lengths), on
    1-3 threads, for spheres, cubes, boxes and ellipsoids (perturbed lattice: lengths near
    the horizon)."""
    kw = dict(kw)
    if "axes" in kw:
        kw["axes"] = kw["axes"][:dim]
    if dim == 1 and kw.get("shape") in ("box", "ellipsoid", "cube"):
        pytest.skip("1D: only spheres")
    ref, out = _both(monkeypatch, _cloud(dim), **kw)
    assert ref.n_bonds > 0
    for b in out:
        for f in FIELDS:
            assert np.array_equal(getattr(b, f), getattr(ref, f)), f


def test_cell_search_varying_horizon_and_isolated(monkeypatch: pytest.MonkeyPatch) -> None:
    """Per-point horizons (bond if within the larger of the two) and a far point."""
    c = _cloud(2, seed=1)
    pts = np.vstack([c.points, [[50.0, 50.0]]])
    cloud = pdlin.PointCloud(pts, volumes=np.append(c.volumes, c.volumes[0]))
    hor = 0.12 + 0.1 * np.random.default_rng(2).random(cloud.n)
    ref, out = _both(monkeypatch, cloud, horizon=hor, allow_isolated=True)
    assert ref.family_size[-1] == 0
    for b in out:
        for f in FIELDS:
            assert np.array_equal(getattr(b, f), getattr(ref, f)), f


def test_cell_search_reports_duplicates(monkeypatch: pytest.MonkeyPatch) -> None:
    c = _cloud(2)
    pts = c.points.copy()
    pts[40] = pts[7]
    cloud = pdlin.PointCloud(pts, volumes=c.volumes)
    with pytest.raises(DuplicatePointError, match="points 7 and 40") as exc:
        pdlin.find_bonds(cloud, horizon=0.25)
    assert (exc.value.first, exc.value.second) == (7, 40)
