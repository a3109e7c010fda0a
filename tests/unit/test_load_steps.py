"""Load steps of one body share their system (issue 34): ``pdlin.static.solve_steps``.

The steps of a deck differ only in prescribed values and loads; the bond search, the
assembly, the elimination and the factorization or AMG hierarchy are done once, and
every step's result is bitwise the one of an independent ``pdlin.solve``.
"""

from __future__ import annotations

import json
import logging
import shutil
from pathlib import Path

import numpy as np
import pytest

import pdlin
import pdlin.problem
import pdlin.solvers.linear as linear
from pdlin.cli.main import main
from pdlin.static import solve_steps
from pdlin.system import ConstrainedSystem, constrained_system

DATA = Path(__file__).resolve().parents[1] / "data" / "peridigm"
COMPRESSION = DATA / "Compression_QS_3x2x2" / "Compression_QS_3x2x2.xml"


def _steps(dim: int, model, times=(0.0, 0.25, 0.5, 1.0)):
    """A plate (2D) or a bar (3D) pulled on its x+ face, a transverse load growing with t."""
    h = 0.1
    shape = (12, 5) if dim == 2 else (8, 3, 3)
    cloud = pdlin.grid(shape, spacing=h)
    probs = []
    for t in times:
        pull = [1e-3 * t] + [0.0] * (dim - 1)
        load = [0.0] * dim
        load[1] = 2e-4 * t * t
        probs.append(
            pdlin.StaticProblem(
                model,
                cloud,
                horizon=3.015 * h,
                dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", pull, components=[0])],
                loads=[pdlin.TotalForce("x+", load)],
            )  # fmt: skip
        )
    return probs


def _same_result(a, b) -> bool:
    """Bitwise the same displacements, reactions, residual and fields."""
    fa, fb = a.fields(), b.fields()
    return (
        np.array_equal(a.u, b.u)
        and np.array_equal(a.reactions, b.reactions)
        and a.relative_residual == b.relative_residual
        and a.n_iter == b.n_iter
        and fa.keys() == fb.keys()
        and all(np.array_equal(fa[k], fb[k]) for k in fa)
    )


MODELS = {
    "bond-based": lambda: pdlin.BondBased(E=1.0),
    "lps": lambda: pdlin.LPS(E=1.0, nu=0.3),
}


@pytest.mark.parametrize("solver", ["direct", "amg-cg"])
@pytest.mark.parametrize(("dim", "model"), [(2, "bond-based"), (3, "bond-based"), (3, "lps")])
def test_steps_are_bitwise_the_independent_solves(dim, model, solver):
    probs = _steps(dim, MODELS[model]())
    shared = solve_steps(probs, solver=solver, rtol=1e-10)
    for r, p in zip(shared, probs, strict=True):
        assert _same_result(r, pdlin.solve(p, solver=solver, rtol=1e-10))
    assert [r.info["shared_system"] for r in shared] == [False, True, True, True]
    # step 1 (t = 0) solves nothing; step 2 factorizes / sets up, 3 and 4 reuse it
    assert [r.info["setup_reused"] for r in shared] == [False, False, True, True]
    assert len({r.info["operator"] for r in shared}) == 1


def test_matrix_free_steps_share_the_operator_and_are_bitwise_equal():
    # 3D LPS on two horizons: solve's operator='auto' runs matrix-free
    probs = _steps(3, pdlin.LPS(E=1.0, nu=0.3))
    shared = solve_steps(probs)
    assert shared[0].info["operator"] == "matrix-free"
    assert all(_same_result(r, pdlin.solve(p)) for r, p in zip(shared, probs, strict=True))


class _Counter:
    """Wrap a function and count its calls."""

    def __init__(self, fn):
        self.fn, self.calls = fn, 0

    def __call__(self, *args, **kwargs):
        self.calls += 1
        return self.fn(*args, **kwargs)


@pytest.fixture
def counts(monkeypatch):
    """Count bond searches, assemblies, factorizations and AMG set-ups."""
    factorizations = _Counter(None)

    class CountingDirectSolver(linear.DirectSolver):  # a class: solve_linear isinstance()s it
        def __init__(self, *args, **kwargs):
            factorizations.calls += 1
            super().__init__(*args, **kwargs)

    c = {
        "bonds": _Counter(pdlin.problem.find_bonds),
        "assemble": _Counter(ConstrainedSystem.assemble),
        "factorize": factorizations,
        "amg": _Counter(linear.amg_hierarchy),
    }
    monkeypatch.setattr(pdlin.problem, "find_bonds", c["bonds"])
    monkeypatch.setattr(ConstrainedSystem, "assemble", lambda self: c["assemble"](self))
    monkeypatch.setattr(linear, "DirectSolver", CountingDirectSolver)
    monkeypatch.setattr(linear, "amg_hierarchy", c["amg"])
    return c


@pytest.mark.parametrize("solver", ["direct", "amg-cg"])
def test_steps_find_bonds_assemble_and_factorize_once(counts, solver):
    probs = _steps(2, pdlin.BondBased(E=1.0), times=(0.2, 0.4, 0.6, 0.8, 1.0))
    solve_steps(probs, solver=solver)
    assert counts["bonds"].calls == 1
    assert counts["assemble"].calls == 1
    assert counts["factorize"].calls == (1 if solver == "direct" else 0)
    assert counts["amg"].calls == (1 if solver == "amg-cg" else 0)


def test_pdlin_run_on_a_multistep_deck_assembles_once(counts, tmp_path, capsys):
    work = tmp_path / "deck"
    shutil.copytree(COMPRESSION.parent, work)
    # the linearized steps (the default for this Elastic deck is Peridigm's finite kinematics)
    assert main(["run", str(work / COMPRESSION.name), "--json", "--kinematics", "linear"]) == 0
    # 21 load steps (the initial state included): one bond search, one K, one factorization
    assert counts["bonds"].calls == 1
    assert counts["assemble"].calls == 1
    assert counts["factorize"].calls == 1
    out = capsys.readouterr()
    summary = json.loads(out.out)
    assert summary["steps"] == 21 and summary["shared_system"]
    # progress per step and for the series write; the timings include the write
    for k in (1, 11, 21):
        assert f"load step {k}/21: solve" in out.err
    assert "writing " in out.err and "(21 steps" in out.err and "wrote " in out.err
    tim = summary["timings"]
    assert list(tim)[-2:] == ["write", "total"]
    assert {"bonds", "assembly", "rhs", "setup", "solve"} <= set(tim)
    assert tim["total"] >= tim["write"] > 0.0


def test_pdlin_run_prints_the_timings_line(tmp_path, capsys):
    work = tmp_path / "deck"
    shutil.copytree(COMPRESSION.parent, work)
    assert main(["run", str(work / COMPRESSION.name), "-q", "--kinematics", "linear"]) == 0
    out = capsys.readouterr().out
    assert "one shared system" in out
    line = next(ln for ln in out.splitlines() if ln.startswith("time (s)"))
    assert "write" in line and "total" in line


def test_deck_steps_are_bitwise_the_independent_solves():
    scene = pdlin.read_deck(COMPRESSION, kinematics="linear")
    probs = [p for _, p in scene.steps]
    for solver in ("direct", "amg-cg"):
        shared = solve_steps(probs, solver=solver)
        assert all(r.info["shared_system"] for r in shared[1:])
        for r, p in zip(shared, probs, strict=True):
            assert _same_result(r, pdlin.solve(p, solver=solver))


def test_other_prescribed_dofs_fall_back_to_independent_solves(caplog):
    probs = _steps(2, pdlin.BondBased(E=1.0), times=(0.5, 1.0))
    other = pdlin.StaticProblem(
        probs[0].model, probs[0].cloud, horizon=probs[0].horizon,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)], loads=[pdlin.TotalForce("x+", [1e-4, 0.0])],
    )  # fmt: skip
    probs.append(other)
    with caplog.at_level(logging.INFO, logger="pdlin.static"):
        res = solve_steps(probs, solver="direct")
    assert "step 3 prescribes other DOFs" in caplog.text
    assert not any(r.info["shared_system"] for r in res)
    for r, p in zip(res, probs, strict=True):
        assert _same_result(r, pdlin.solve(p, solver="direct"))


def test_another_model_falls_back_to_independent_solves(caplog):
    probs = _steps(2, pdlin.BondBased(E=1.0), times=(0.5, 1.0))
    probs[1] = pdlin.StaticProblem(
        pdlin.BondBased(E=2.0), probs[1].cloud, horizon=probs[1].horizon,
        dirichlet=probs[1].dirichlet, loads=probs[1].loads,
    )  # fmt: skip
    with caplog.at_level(logging.INFO, logger="pdlin.static"):
        res = solve_steps(probs, solver="direct")
    assert "step 2 has another model" in caplog.text
    for r, p in zip(res, probs, strict=True):
        assert _same_result(r, pdlin.solve(p, solver="direct"))


def test_solve_steps_refuses_bad_input():
    with pytest.raises(pdlin.errors.InputError, match="at least one"):
        solve_steps([])
    with pytest.raises(pdlin.errors.InputTypeError, match=r"problems\[0\]"):
        solve_steps(["not a problem"])
    with pytest.raises(pdlin.errors.InputError, match="solver must be one of"):
        solve_steps(_steps(2, pdlin.BondBased(E=1.0)), solver="lu")


def test_rhs_from_prescribed_columns_is_bitwise_eliminate():
    prob = _steps(3, pdlin.BondBased(E=1.0))[-1]
    system = constrained_system(prob)
    K = system.assemble()
    cols = system.prescribed_columns(K)
    assert cols.nnz < K.nnz
    _, b = system.eliminate(K)
    assert np.array_equal(system.rhs(cols), b)
    csr = K.tocsr()
    assert np.array_equal(system.rhs(system.prescribed_columns(csr)), system.eliminate(csr)[1])


@pytest.mark.parametrize("solver", ["direct", "amg-cg", "jacobi-cg", "ilu-gmres"])
def test_solver_setup_reuses_the_factorization_or_preconditioner(solver):
    prob = _steps(2, pdlin.BondBased(E=1.0))[-1]
    system = constrained_system(prob)
    A, b = system.eliminate(system.assemble())
    setup = linear.SolverSetup()
    kw = dict(near_null=system.near_null(), blocksize=2, rtol=1e-10)
    first = linear.solve_linear(A, b, solver, setup=setup, **kw)
    assert setup.filled and setup.uses == 0
    again = linear.solve_linear(A, 3.0 * b, solver, setup=setup, **kw)
    assert setup.uses == 1
    fresh = linear.solve_linear(A, 3.0 * b, solver, **kw)
    assert np.array_equal(again.x, fresh.x)
    assert first.setup_time >= 0.0 and again.relative_residual == fresh.relative_residual
