"""Progress of long stages: iterations and residuals, the write and a total including it
(issue 31, item 12)."""

from __future__ import annotations

import json
import time

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
