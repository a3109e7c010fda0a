"""Progress of long stages: iterations and residuals, the write and a total including it
(issue 31, item 12)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

import pdlin
import pdlin._progress as progress_mod
from pdlin.cli.main import main

_SCENE = (
    'name = "small"\n[geometry]\ntype = "grid"\nshape = [30, 10]\nspacing = 0.1\n'
    '[material]\nE = 1.0\n[model]\ntype = "bond_based"\n[horizon]\n'
    'ratio = 3.015\n[[dirichlet]]\nset = "x-"\nvalue = 0.0\n[[dirichlet]]\nset = "x+"\n'
    'value = 1e-3\ncomponents = "x"\n'
)


def _scene(tmp_path) -> str:
    path = tmp_path / "small.toml"
    path.write_text(_SCENE)
    return str(path)


def _problem() -> pdlin.StaticProblem:
    cloud = pdlin.grid((60, 30), spacing=0.1)
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    return pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.3015, dirichlet=bc)


@pytest.mark.parametrize("solver", ["amg-cg", "cg", "gmres"])
def test_iterative_solves_report_iterations_and_residuals(monkeypatch, solver: str) -> None:
    monkeypatch.setattr(progress_mod, "PROGRESS_EVERY", 0.0)  # every iteration
    lines: list[str] = []
    res = pdlin.solve(_problem(), solver, progress=lines.append)
    its = [ln for ln in lines if f"{solver}: iteration" in ln]
    # one line per appended residual (the initial one is iteration 0, never appended)
    assert len(its) == len(res.residuals) - 1 >= 1
    last = its[-1].split("residual ")[1]
    assert float(last) == pytest.approx(res.residuals[-1], rel=0.01)
    if solver == "amg-cg":
        assert any(ln.strip().startswith("AMG hierarchy:") for ln in lines)


def test_progress_is_throttled(monkeypatch) -> None:
    monkeypatch.setattr(progress_mod, "PROGRESS_EVERY", 3600.0)
    lines: list[str] = []
    pdlin.solve(_problem(), "cg", progress=lines.append)
    assert not any("iteration" in ln for ln in lines)


def test_cli_reports_the_write_and_counts_it_in_the_total(tmp_path, capsys) -> None:
    out = tmp_path / "bar.vtu"
    assert main(["run", _scene(tmp_path), "-o", str(out), "--json"]) == 0
    cap = capsys.readouterr()
    t = json.loads(cap.out)["timings"]
    assert t["write"] > 0.0
    assert t["total"] >= t["write"] + t["bonds"]
    from pdlin.resources import format_bytes

    assert f"wrote {format_bytes(out.stat().st_size)} in " in cap.err


def test_cli_reports_bytes_while_writing(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setattr(progress_mod, "PROGRESS_EVERY", 0.0)
    import pdlin.cli.main as cli

    real = cli._bytes_so_far
    seen: list[int] = []

    def slow_write(*args, **kwargs):  # a writer that takes a second, 1 kB staged
        staging = tmp_path / ".bar.vtu.x.partial"
        staging.mkdir()
        (staging / "bar.vtu").write_bytes(b"0" * 1000)
        time.sleep(1.0)
        seen.append(real(tmp_path / "bar.vtu"))
        (staging / "bar.vtu").replace(tmp_path / "bar.vtu")
        staging.rmdir()

    monkeypatch.setattr("pdlin.io.results.write_result", slow_write)
    assert main(["run", _scene(tmp_path), "-o", str(tmp_path / "bar.vtu")]) == 0
    err = capsys.readouterr().err
    assert seen == [1000]
    assert "  writing: 1.00 kB so far" in err


_DAMAGE = _SCENE + "[damage]\ncritical_stretch = 0.1\nsteps = 2\n"
#: the 8 x 8 polycrystal of tests/hostile/test_hostile_checkpoint.py, two Newton steps
_NONLINEAR = (
    'name = "cp"\n[geometry]\ntype = "grid"\nshape = [8, 8]\nspacing = 0.125\n'
    '[material]\ntype = "crystal-plasticity"\n[material.polycrystal]\ngrains = 3\nseed = 1\n'
    '[model]\ntype = "correspondence"\n[horizon]\nratio = 1.0\ninfluence = "constant"\n'
    '[[dirichlet]]\nset = "boundary"\nvelocity_gradient = [[0.0, 0.004], [0.004, 0.0]]\n'
    '[solver]\nnonlinear = "newton"\nsteps = 2\nt_end = 2.0\n'
)


@pytest.mark.parametrize(
    "text, out", [(_DAMAGE, "bar.vtu"), (_NONLINEAR, "cp.pvd")], ids=["damage", "nonlinear"]
)
def test_cli_damage_and_nonlinear_totals_include_the_write(tmp_path, capsys, text, out) -> None:
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    path = tmp_path / out
    assert main(["run", str(scene), "-o", str(path), "--json"]) == 0
    cap = capsys.readouterr()
    t = json.loads(cap.out)["timings"]
    assert t["write"] > 0.0
    assert t["total"] >= t["write"]
    assert "wrote " in cap.err and " in " in cap.err.split("wrote ")[1]
    assert main(["run", str(scene), "-o", str(path)]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("time (s)"))
    assert "write " in line and "total " in line


def test_newton_linear_solves_report_iterations_and_residuals(monkeypatch) -> None:
    """Each Newton iteration's linear solve reports its iterations like a static solve."""
    monkeypatch.setattr(progress_mod, "PROGRESS_EVERY", 0.0)  # every iteration
    cloud = pdlin.grid((8, 8), spacing=0.125)
    _, theta = pdlin.voronoi_polycrystal(cloud, 3, seed=1)
    model = pdlin.Correspondence(material=pdlin.CrystalPlasticity(orientation=theta))
    bc = pdlin.Dirichlet.velocity_gradient("boundary", 0.002 * np.array([[0, 1.0], [1.0, 0]]))
    prob = pdlin.StaticProblem(model, cloud, pdlin.find_bonds(cloud, ratio=1.0), dirichlet=[bc])
    lines: list[str] = []
    res = pdlin.solve_nonlinear(
        prob, times=[1.0], method="newton", linear_solver="gmres", progress=lines.append
    )
    its = [ln for ln in lines if "gmres: iteration" in ln]
    assert its, lines
    assert all(ln.startswith("  t = 1: ") for ln in its)  # the step's prefix
    assert int(res.iterations[0]) >= 1  # a linear solve ran


def test_damage_linear_solves_report_iterations(monkeypatch) -> None:
    """solve_damage's solves report their iterations, not pdlin.solve's stage lines."""
    monkeypatch.setattr(progress_mod, "PROGRESS_EVERY", 0.0)  # every iteration
    lines: list[str] = []
    pdlin.solve_damage(_problem(), s0=0.1, steps=2, solver="cg", progress=lines.append)
    its = [ln for ln in lines if "cg: iteration" in ln]
    assert its and all(ln.startswith("  unit-load solve: cg: iteration") for ln in its), lines
    assert not any(ln in ("bonds", "solve (cg)") for ln in lines)
