"""Out-of-memory runs are refused before they allocate, with the estimate, the available
memory and what would fit (issue 31, items 10, 11 and 14)."""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.spatial import cKDTree

import pdlin
import pdlin.resources as res
from pdlin.cli.main import main
from pdlin.errors import InsufficientMemoryError, PdlinError, SlowRunWarning
from pdlin.problem import memory_hints, plan_memory
from pdlin.resources import MemoryBudget


def _small_budget(monkeypatch: pytest.MonkeyPatch, nbytes: int) -> None:
    """Pretend only ``nbytes`` are available to every check."""
    monkeypatch.setattr(res, "available_memory", lambda: MemoryBudget(nbytes, {"test": nbytes}))


def _bar_problem(shape=(40, 20), model=None, **kw) -> pdlin.StaticProblem:
    cloud = pdlin.grid(shape, spacing=0.1)
    model = model or pdlin.BondBased(E=1.0)
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    return pdlin.StaticProblem(model, cloud, horizon=0.3015, dirichlet=bc, **kw)


# --------------------------------------------------------------------------- estimators


@pytest.mark.parametrize(("dim", "expected"), [(1, 6), (2, 28), (3, 122)])
def test_neighbours_per_point_is_the_lattice_count(dim: int, expected: int) -> None:
    # expected: interior family sizes of find_bonds at δ = 3.015 h (its docstring: 122 in
    # 3D; docs/large_problems.md: 28 in 2D; 1D: 3 on each side)
    assert res.neighbours_per_point(dim, 3.015) == expected
    cloud = pdlin.grid((9,) * dim)
    assert int(pdlin.find_bonds(cloud, ratio=3.015).family_size.max()) == expected


@pytest.mark.parametrize(
    ("shape", "ratio"),
    [((13, 7), 3.015), ((6, 7, 5), 2.015), ((30,), 4.5), ((11, 9), 1.0), ((10, 7), 100.0)],
)
def test_lattice_pair_count_matches_find_bonds(shape: tuple[int, ...], ratio: float) -> None:
    cloud = pdlin.grid(shape, spacing=0.5)
    expected = pdlin.find_bonds(cloud, ratio=ratio).n_bonds
    assert res.lattice_pair_count(shape, (0.5,) * len(shape), ratio * 0.5) == expected


def test_pair_counts_never_exceed_all_pairs() -> None:
    # a horizon wider than the body: every point bonds to every other, n (n - 1) pairs
    cloud = pdlin.grid((12, 12, 12))
    assert res.lattice_pair_count((12,) * 3, (1.0,) * 3, 100.0, hops=2) == 1728 * 1727
    pts = pdlin.PointCloud(cloud.points + 0.01 * np.sin(cloud.points), cloud.volumes)
    assert res.estimate_pair_count(pts, 100.0) == 1728 * 1727


def test_pair_count_of_a_scattered_cloud_is_an_upper_estimate() -> None:
    rng = np.random.default_rng(3)
    base = pdlin.grid((40, 40), spacing=0.1)
    pts = base.points + rng.uniform(-0.02, 0.02, base.points.shape)
    cloud = pdlin.PointCloud(pts, base.volumes)
    found = 2 * len(cKDTree(pts).query_pairs(0.3015))
    est = res.estimate_pair_count(cloud, 0.3015)
    # the interior count ignores the boundary (15 % of these points are within δ of it)
    assert found <= est <= 1.3 * found


@pytest.mark.parametrize("model", [pdlin.BondBased(E=1.0), pdlin.LPS(E=1.0, nu=0.25)])
def test_plan_counts_bonds_and_blocks_exactly_on_grids(model: pdlin.Model) -> None:
    prob = _bar_problem(model=model)
    plan = plan_memory(prob, "amg-cg")
    system = pdlin.system.constrained_system(prob)
    assert plan.n_bonds == system.disc.real_bonds.n_bonds
    assert plan.nnz_blocks == system.estimate_nnz_blocks()


def test_direct_fill_estimate_brackets_superlu() -> None:
    # SuperLU's measured L + U on a 2D LPS grid against the estimate (docs/large_problems.md:
    # the estimate is within a factor 2 either way on 100²-200² grids)
    cloud = pdlin.grid((60, 60))
    bonds = pdlin.find_bonds(cloud, ratio=2.015)
    K = pdlin.assemble_stiffness(pdlin.LPS(E=1.0, nu=0.25, plane="strain"), cloud, bonds)
    K = sp.bsr_array(K + sp.eye(K.shape[0]) * abs(K.diagonal()).max(), blocksize=(2, 2))
    lu = pdlin.solvers.direct.DirectSolver(K, symmetric=True, backend="superlu")
    est = res.direct_factor_bytes(res.direct_factor_nnz(cloud.n, K.nnz // 4, 2, 2), "superlu")
    assert 0.5 < est / (12 * lu.fill) < 2.0


def test_available_memory_honours_the_user_cap(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(res.ENV_LIMIT, "64T")
    free = res.available_memory().bytes
    monkeypatch.setenv(res.ENV_LIMIT, "1G")
    b = res.available_memory()
    assert b.bytes <= 2**30 and b.bytes <= free
    assert b.source == res.ENV_LIMIT
    monkeypatch.setenv(res.ENV_LIMIT, "lots")
    with pytest.raises(PdlinError, match="PDLIN_MAX_MEMORY must be a positive size"):
        res.available_memory()


def test_available_memory_reads_a_cgroup_limit(tmp_path, monkeypatch) -> None:
    # a cgroup v2 limit of 2 GB with 0.5 GB used, 0.1 GB of it reclaimable page cache
    (tmp_path / "memory.max").write_text("2000000000\n")
    (tmp_path / "memory.current").write_text("500000000\n")
    (tmp_path / "memory.stat").write_text("anon 400000000\ninactive_file 100000000\n")
    monkeypatch.setattr(res, "CGROUP_ROOT", str(tmp_path))
    monkeypatch.delenv(res.ENV_LIMIT, raising=False)
    b = res.available_memory()
    assert b.limits["cgroup"] == 2_000_000_000 - 400_000_000
    assert b.bytes <= b.limits["cgroup"]
    (tmp_path / "memory.max").write_text("max\n")  # no limit
    assert "cgroup" not in res.available_memory().limits


# --------------------------------------------------------------------------- refusals


def test_huge_grid_refuses_fast_with_the_estimate() -> None:
    t0 = time.perf_counter()
    with pytest.raises(InsufficientMemoryError) as info:
        pdlin.grid((10**6, 10**6))
    assert time.perf_counter() - t0 < 1.0
    msg = str(info.value)
    # 10¹² points x (3 d + 2) x 8 bytes = 64 TB (grid_bytes)
    assert "1,000,000,000,000 points" in msg and "64.00 TB" in msg
    assert "available" in msg and "what would fit: at most" in msg
    assert isinstance(info.value, MemoryError) and isinstance(info.value, PdlinError)
    assert info.value.need > info.value.available


def test_scene_with_a_huge_shape_refuses_through_the_cli(tmp_path, capsys) -> None:
    scene = tmp_path / "huge.toml"
    scene.write_text(
        'name = "huge"\n[geometry]\ntype = "grid"\nshape = [100000, 100000, 100000]\n'
        'spacing = 0.001\n[material]\nE = 1.0\nnu = 0.25\n[model]\ntype = "lps"\n'
        '[horizon]\nratio = 3.015\n[[dirichlet]]\nset = "x-"\nvalue = 0.0\n'
    )
    t0 = time.perf_counter()
    assert main(["run", str(scene), "-q"]) == 2
    assert time.perf_counter() - t0 < 5.0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pdlin: error: grid of shape")
    assert "PB" in err[0] and "available" in err[0] and "what would fit" in err[0]


def test_bond_search_refuses_with_hints(monkeypatch: pytest.MonkeyPatch) -> None:
    _small_budget(monkeypatch, 10**6)
    cloud = pdlin.grid((100, 100))
    with pytest.raises(InsufficientMemoryError, match="bond search .* smaller horizon ratio"):
        pdlin.find_bonds(cloud, ratio=3.015)


def test_horizon_ratio_100_refuses_before_the_search() -> None:
    cloud = pdlin.grid((300, 300))  # 90,000 points x ~31,400 neighbours: ~160 GB of bonds
    t0 = time.perf_counter()
    with pytest.raises(InsufficientMemoryError, match=r"bond search \(~2[0-9,]+ bonds"):
        pdlin.find_bonds(cloud, ratio=100.0)
    assert time.perf_counter() - t0 < 2.0


def test_solve_refuses_the_whole_run_with_hints(monkeypatch: pytest.MonkeyPatch) -> None:
    prob = _bar_problem()
    plan = plan_memory(prob, "amg-cg")
    _small_budget(monkeypatch, max(plan.need // 2, 1))
    with pytest.raises(InsufficientMemoryError) as info:
        pdlin.solve(prob, "amg-cg")
    msg = str(info.value)
    assert msg.startswith("this run needs")
    assert "operator='matrix-free'" in msg and "coarser discretization" in msg
    assert "backend='petsc' on >= 2 ranks" in msg


def test_assembly_refuses_when_only_the_bonds_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    prob = _bar_problem()
    monkeypatch.setattr(
        "pdlin.static.check_memory",
        lambda stage, need, hints=(): (
            res.check_memory(stage, need, hints, budget=MemoryBudget(1000, {"test": 1000}))
            if stage.startswith("assembly")
            else None
        ),
    )
    with pytest.raises(InsufficientMemoryError, match="assembly of K needs .*matrix-free"):
        pdlin.solve(prob, "amg-cg", operator="assembled")


def test_direct_factorization_refuses_with_hints(monkeypatch: pytest.MonkeyPatch) -> None:
    K = sp.csr_array(sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(2000, 2000)))
    _small_budget(monkeypatch, 1000)
    with pytest.raises(InsufficientMemoryError, match=r"direct factorization \(superlu") as info:
        pdlin.solvers.direct.DirectSolver(K, backend="superlu")
    assert "solver='amg-cg'" in str(info.value) and "cholmod" in str(info.value)


def test_a_backend_memory_error_becomes_the_refusal(monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(self, csc):
        raise MemoryError("Not enough memory to perform factorization.")

    monkeypatch.setattr(pdlin.solvers.direct._SuperLU, "_factor", boom)
    K = sp.csr_array(sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(50, 50)))
    with pytest.raises(InsufficientMemoryError, match="ran out of memory .*solver='amg-cg'"):
        pdlin.solvers.direct.DirectSolver(K, backend="superlu")


def test_cli_reports_an_escaped_memory_error_on_one_line(monkeypatch, capsys) -> None:
    def boom(*args, **kwargs):
        raise MemoryError()

    monkeypatch.setattr("pdlin.static.solve", boom)
    assert main(["run", "--example", "bar", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pdlin: error: out of memory (MemoryError)")
    assert "available now" in err[0] and "solver='amg-cg'" in err[0]


def test_damage_steps_of_a_billion_refuse(capsys) -> None:
    prob = _bar_problem()
    t0 = time.perf_counter()
    with pytest.raises(InsufficientMemoryError, match="damage history of 1,000,000,000 load"):
        pdlin.solve_damage(prob, 1e-3, steps=10**9)
    assert time.perf_counter() - t0 < 1.0


def test_many_damage_steps_warn_before_they_start(monkeypatch) -> None:
    # 1,000 steps of 800 points: ~0.5 s by the per-step estimate, over a lowered threshold
    monkeypatch.setattr(res, "LONG_RUN_SECONDS", 0.01)
    monkeypatch.setattr(
        "pdlin.fracture.solve", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("stop"))
    )
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        with pytest.raises(RuntimeError, match="stop"):  # the warning comes before any solve
            pdlin.solve_damage(_bar_problem(), 1e-3, steps=1000)
    slow = [x for x in w if issubclass(x.category, SlowRunWarning)]
    assert len(slow) == 1 and "damage.steps = 1,000" in str(slow[0].message)


def test_a_long_static_run_warns_once_naming_the_estimate(monkeypatch) -> None:
    monkeypatch.setattr(res, "LONG_RUN_SECONDS", 1e-6)
    msgs: list[str] = []
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        pdlin.solve(_bar_problem(), "amg-cg", progress=msgs.append)
    slow = [x for x in w if issubclass(x.category, SlowRunWarning)]
    assert len(slow) == 1 and "estimated to take" in str(slow[0].message)
    assert msgs[0].startswith("memory estimate: peak ~") and msgs[1].startswith("warning:")


def test_scene_with_horizon_ratio_100_stops_before_the_bond_search(tmp_path, capsys) -> None:
    scene = tmp_path / "wide.toml"
    scene.write_text(
        'name = "wide"\n[geometry]\ntype = "grid"\nshape = [300, 300]\nspacing = 0.01\n'
        '[material]\nE = 1.0\nnu = 0.25\n[model]\ntype = "lps"\n[horizon]\nratio = 100\n'
        '[[dirichlet]]\nset = "x-"\nvalue = 0.0\n'
    )
    t0 = time.perf_counter()
    assert main(["run", str(scene)]) == 2
    assert time.perf_counter() - t0 < 5.0
    err = capsys.readouterr().err.strip().splitlines()
    assert "memory estimate: peak ~" in err[1]
    bonds = int(err[1].split(" bonds")[0].split("~")[-1].replace(",", ""))
    # at most 90,000 points x π 100² interior neighbours = 2.83e9; the body (300 h wide)
    # truncates the families of most points, but not below half that
    assert 1.4e9 < bonds <= 90_000 * np.pi * 100**2
    assert err[-1].startswith("pdlin: error: this run needs ~") and "what would fit" in err[-1]
    assert not any("] bonds ..." in ln for ln in err)


def test_generated_mesh_refuses_fast() -> None:
    t0 = time.perf_counter()
    # 4 x 10⁶ angles x (10⁶ + 1) layers = 4·10¹² nodes, ~288 B each (_check_mesh_memory)
    with pytest.raises(InsufficientMemoryError, match=r"4,000,004,000,000 nodes.*PB"):
        pdlin.plate_with_hole_mesh(10**6, 10**6)
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize("ranks", [1, 4])
def test_petsc_backend_refuses_a_rank_share_too_big_before_assembly(monkeypatch, ranks) -> None:
    """backend='petsc' estimates each rank's share (the run's estimate over the ranks) and
    refuses it before the bond search and assembly, naming the ranks (main: no check on
    the PETSc path; PETSc is faked here, petsc4py need not be installed)."""
    import types

    import pdlin.backends.petsc as bp

    comm = types.SimpleNamespace(getRank=lambda: 0, getSize=lambda: ranks)
    monkeypatch.setattr(bp, "_petsc", lambda: types.SimpleNamespace(COMM_WORLD=comm))

    def no_work(*args, **kwargs):
        raise AssertionError("the bond search started before the memory check")

    monkeypatch.setattr(bp, "local_rows", no_work)
    monkeypatch.setattr(bp, "_layout", no_work)
    prob = _bar_problem((200, 200))
    share = plan_memory(prob, "amg-cg").stages["solve"] // ranks
    _small_budget(monkeypatch, share // 2)  # half of one rank's share
    with pytest.raises(InsufficientMemoryError, match=rf"{ranks} rank\(s\)"):
        pdlin.solve(prob, "amg-cg", backend="petsc")
    if ranks > 1:  # room for two shares but not the whole: this rank goes on to the work
        _small_budget(monkeypatch, res.LATE_IMPORTS + 2 * share)
        with pytest.raises(AssertionError, match="bond search started"):
            pdlin.solve(prob, "amg-cg", backend="petsc")


def test_hints_of_a_long_history_count_it_and_offer_fewer_steps(monkeypatch) -> None:
    """damage.steps = 10⁹: the per-step history is what does not fit; the alternatives'
    estimates include it (main offered "solver='amg-cg': ~117 MB" for a 13 TB run) and a
    number of steps that fits is offered."""
    _small_budget(monkeypatch, 2**30)  # 1 GiB
    prob = _bar_problem()
    plan = plan_memory(prob, "direct", history_steps=10**9)
    hist = 10**9 * prob.cloud.n * (2 + 4 + 2) * 8  # u, stress and two scalars per point and step
    assert plan.peak >= hist
    hints = memory_hints(plan)
    amg = next(h for h in hints if h.startswith("solver='amg-cg'"))
    units = {"kB": 1e3, "MB": 1e6, "GB": 1e9, "TB": 1e12, "PB": 1e15}  # format_bytes's
    value, unit = amg.split(": ~")[1].split()[:2]
    assert float(value) * units[unit] >= hist, amg  # not ~117 MB
    steps = next(h for h in hints if "load steps" in h)
    fit = int(steps.split("at most ~")[1].split()[0].replace(",", ""))
    per_step = prob.cloud.n * (2 + 4 + 2) * 8
    assert 1 <= fit and fit * per_step < 2**30, steps
