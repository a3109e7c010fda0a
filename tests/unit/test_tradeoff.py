"""The speed-vs-accuracy harness: rates, Pareto front, resume, target error, CLI."""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import numpy as np
import pytest

import pdlin
from pdlin.errors import InputError
from pdlin.sweeps import TradeoffCase, TradeoffResult, graded_bar, tension_bar, tradeoff

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_rate_in_h_recovered_on_graded_bar():
    # graded bar (Javaheri et al. (2022), Sec. III.A): higher-order correspondence errors fall like
    # N^(-1/2) (ratio 1.41 per doubling, reference computation) because of the sqrt singularity at x
    # = 1/2
    res = tradeoff(graded_bar, {"control": ["higher_order"], "m": [1, 2], "N": [100, 200, 500]},
                   memory="none")  # fmt: skip
    rates = res.rates("h")
    assert len(rates) == 2
    for g in rates:
        assert g["rate"] == pytest.approx(0.5, abs=0.05)
        assert g["n"] == 3
    # the N = 500, 2h entry of the reference table (test_correspondence_bar.py): max |u - u_ex| =
    # 1.51e-4 (± 1 %)
    row = next(r for r in res.table if r["m"] == 2 and r["N"] == 500)
    u_max = 1e-3 + 4e-3 * np.sqrt(2.0) * np.sqrt(0.5 - 0.5 / 500)  # max |u_ex| on the real points
    assert row["error"] * u_max == pytest.approx(1.51e-4, rel=0.01)


def _rows(pairs):
    return [
        {"key": str(k), "p": k, "t_total": t, "error": e, "status": s}
        for k, (t, e, s) in enumerate(pairs)
    ]


def test_pareto_front_on_hand_made_table():
    table = _rows(
        [
            (1.0, 1e-1, "ok"),  # 0 front (fastest)
            (2.0, 1e-1, "ok"),  # 1 dominated by 0 (slower, same error)
            (2.0, 1e-2, "ok"),  # 2 front
            (3.0, 5e-2, "ok"),  # 3 dominated by 2
            (4.0, 1e-3, "ok"),  # 4 front
            (0.5, 1e-9, "failed"),  # 5 not a finished point
            (5.0, 1e-3, "ok"),  # 6 dominated by 4 (tie in error, slower)
            (6.0, 1e-4, "ok"),  # 7 front
        ]
    )
    for r in table:
        if r["status"] == "failed":
            r["error"] = float("nan")
    res = TradeoffResult(table, ["p"])
    assert [r["p"] for r in res.pareto()] == [0, 2, 4, 7]
    # permuting the rows does not change the front
    rng = np.random.default_rng(0)
    res2 = TradeoffResult([table[i] for i in rng.permutation(len(table))], ["p"])
    assert sorted(r["p"] for r in res2.pareto()) == [0, 2, 4, 7]


def test_best_picks_fastest_configuration_meeting_target():
    table = _rows([(3.0, 1e-3, "ok"), (1.0, 1e-1, "ok"), (2.0, 5e-3, "ok"), (0.1, 1e-9, "failed")])
    table[3]["error"] = float("nan")
    res = TradeoffResult(table, ["p"])
    assert res.best(1e-2)["p"] == 2
    assert res.best(2e-3)["p"] == 0
    assert res.best(1.0)["p"] == 1
    assert res.best(1e-6) is None
    with pytest.raises(InputError, match="target_error must be > 0"):
        res.best(0.0)


def test_target_error_on_real_sweep():
    res = tradeoff(
        tension_bar,
        {"model": ["bb", "lps"], "dim": [2], "h": [0.1], "m": [2.0, 3.015]},
        memory="none",
        target_error=0.05,
    )
    ok = [r for r in res.table if r["error"] <= 0.05]
    best = res.best(0.05)
    assert best is not None and best["error"] <= 0.05
    assert best["t_total"] == min(r["t_total"] for r in ok)
    assert "fastest with error <= 0.05" in res.summary(target_error=0.05)


class _Kill(RuntimeError):
    pass


def test_resume_skips_finished_points(tmp_path):
    calls: list[tuple[int, int]] = []

    def factory(N: int, m: int) -> TradeoffCase:
        calls.append((N, m))
        return graded_bar(N=N, m=m)

    grid = {"N": [50, 100, 200], "m": [1, 2]}
    out = tmp_path / "sweep.csv"

    def kill_after_three(done, total, row):
        if done == 3:
            raise _Kill("simulated kill")

    with pytest.raises(_Kill):
        tradeoff(factory, grid, output=out, memory="none", progress=kill_after_three)
    assert len(calls) == 3
    # a torn last line (killed during a write) is dropped on resume
    with open(out, "a") as f:
        f.write("N=200;m=2,200,2,ok,0.1")
    finished = list(calls)
    seen = []
    res = tradeoff(factory, grid, output=out, memory="none",
                   progress=lambda d, t, r: seen.append((d, t)))  # fmt: skip
    assert calls[:3] == finished and len(calls) == 6  # only the 3 missing points ran
    assert sorted(calls[3:]) == sorted(set((n, m) for n in grid["N"] for m in grid["m"]) -
                                        set(finished))  # fmt: skip
    assert seen == [(4, 6), (5, 6), (6, 6)]
    assert [r["status"] for r in res.table] == ["ok"] * 6
    rows = list(csv.DictReader(open(out)))
    assert len(rows) == 6 and len({r["key"] for r in rows}) == 6
    # the table keeps the grid's order and typed values
    assert [(r["N"], r["m"]) for r in res.table] == [(n, m) for n in (50, 100, 200) for m in (1, 2)]
    # nothing left: a third call runs no point
    tradeoff(factory, grid, output=out, memory="none")
    assert len(calls) == 6
    # resume=False starts over
    tradeoff(factory, {"N": [50], "m": [1]}, output=out, memory="none", resume=False)
    assert len(list(csv.DictReader(open(out)))) == 1


def test_finest_reference_and_jsonl(tmp_path):
    out = tmp_path / "s.jsonl"
    res = tradeoff(tension_bar, {"model": ["bb"], "dim": [2], "h": [0.1, 0.05, 0.025]},
                   reference="finest", output=out, memory="none")  # fmt: skip
    ref = [r for r in res.table if r["status"] == "reference"]
    assert len(ref) == 1 and ref[0]["h"] == 0.025 and ref[0]["error"] == 0.0
    assert all(r["reference"].startswith("finest: ") for r in res.table)
    assert len(res.pareto()) >= 1 and all(r["status"] == "ok" for r in res.pareto())
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert len(lines) == 3 and lines[0]["h"] == 0.025  # the reference runs first
    assert (tmp_path / "s.jsonl.finest.npz").exists()
    # a resumed sweep reads the stored reference instead of solving it again
    res2 = tradeoff(tension_bar, {"model": ["bb"], "dim": [2], "h": [0.1, 0.05, 0.025, 0.0125]},
                    reference="finest", output=out, memory="none",
                    finest={"h": 0.025})  # fmt: skip
    new = next(r for r in res2.table if r["h"] == 0.0125)
    assert new["status"] == "ok" and np.isfinite(new["error"])


def test_failures_and_timeouts_are_rows():
    def factory(mode: str) -> TradeoffCase:
        if mode == "bad":
            raise InputError("bad point")
        if mode == "slow":
            time.sleep(30)
        return graded_bar(N=50)

    res = tradeoff(factory, {"mode": ["ok", "bad", "slow"]}, memory="rss", timeout=3.0)
    status = {r["mode"]: r["status"] for r in res.table}
    assert status == {"ok": "ok", "bad": "failed", "slow": "timeout"}
    ok = res.table[0]
    assert ok["peak_mb"] >= 0 and ok["nnz"] > 0 and ok["iterations"] == 1
    assert "bad point" in res.table[1]["message"]


def test_symmetry_reduction_gives_same_error_cheaper():
    grid = {"model": ["bb"], "dim": [2], "h": [0.05], "symmetry": [False, True]}
    res = tradeoff(tension_bar, grid, memory="none", reference="closed-form")
    full, half = res.table
    assert half["points"] * 2 == full["points"]
    assert half["error"] == pytest.approx(full["error"], rel=1e-6)


def test_bad_arguments():
    with pytest.raises(InputError, match="reference must be"):
        tradeoff(graded_bar, {"N": [50]}, reference="nope")
    with pytest.raises(InputError, match="clashes"):
        tradeoff(graded_bar, {"error": [1]})
    with pytest.raises(InputError, match="timeout needs"):
        tradeoff(graded_bar, {"N": [50]}, memory="none", timeout=1.0)


def test_plot_and_exports(tmp_path):
    pytest.importorskip("matplotlib")
    res = tradeoff(graded_bar, {"control": ["higher_order", "none"], "m": [1, 2], "N": [50, 100]},
                   memory="none")  # fmt: skip
    fig = res.plot(tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 0 and len(fig.axes) == 2
    res.to_csv(tmp_path / "t.csv")
    assert len(list(csv.DictReader(open(tmp_path / "t.csv")))) == 8
    data = json.loads(res.to_json(tmp_path / "t.json"))
    assert len(data["table"]) == 8 and data["pareto"]


def test_cli_tradeoff_on_scene(tmp_path, capsys):
    from pdlin.cli.main import main

    scene = (EXAMPLES / "tradeoff_plate.toml").read_text()
    scene = scene.replace('model = ["bond_based", "lps", "xosb"]', 'model = ["bond_based", "lps"]')
    path = tmp_path / "plate.toml"
    path.write_text(scene)
    out, png = tmp_path / "t.csv", tmp_path / "t.png"
    assert main(["tradeoff", str(path), "-o", str(out), "--plot", str(png)]) == 0
    text = capsys.readouterr()
    assert "fastest with error <= 0.05" in text.out
    assert "8/8" in text.err  # progress bar
    rows = list(csv.DictReader(open(out)))
    assert len(rows) == 8 and all(r["status"] == "ok" for r in rows)
    assert png.exists()
    # bond-based at delta = 3.015 h: a few per mille on the free-surface plate
    bb = [float(r["error"]) for r in rows if r["model"] == "bond_based" and r["m"] == "3.015"]
    assert max(bb) < 0.01
    # --resume keeps all points: nothing runs again
    assert main(["tradeoff", str(path), "-o", str(out), "--resume", "-q"]) == 0
    assert len(list(csv.DictReader(open(out)))) == 8
    # the same scene still runs as a plain scene
    assert main(["run", str(path), "-o", str(tmp_path / "p.npz"), "-q"]) == 0


def test_scene_sweep_errors(tmp_path):
    from pdlin.errors import SceneError
    from pdlin.scene.tradeoff import tradeoff_from_dict

    base = {
        "geometry": {"type": "grid", "shape": [20], "spacing": 0.05},
        "material": {"E": 1.0},
        "horizon": {"ratio": 3.015},
        "dirichlet": [{"points": [0], "value": 0.0}],
    }
    with pytest.raises(SceneError, match="unknown tradeoff.sweep key 'ratioo'"):
        tradeoff_from_dict({**base, "tradeoff": {"sweep": {"ratioo": [1.0]}}})
    with pytest.raises(SceneError, match="points"):
        tradeoff_from_dict({**base, "tradeoff": {"sweep": {"h": [0.01]}}})
    with pytest.raises(SceneError, match="unknown scene key 'tradeoff.refrence'"):
        tradeoff_from_dict({**base, "tradeoff": {"sweep": {"m": [2.0]}, "refrence": "x"}})


def test_top_level_names():
    assert pdlin.tradeoff is tradeoff
    assert pdlin.TradeoffResult is TradeoffResult


def test_run_select_solves_the_fastest_configuration_meeting_the_target(tmp_path, capsys):
    # "model only what a scene requires": pdlin run --select measures the [tradeoff] sweep
    # (or reuses its finished points) and solves the fastest configuration within the target
    from pdlin.cli.main import main
    from pdlin.errors import SceneError
    from pdlin.scene.tradeoff import select_scene

    scene = (EXAMPLES / "tradeoff_plate.toml").read_text()
    scene = scene.replace('model = ["bond_based", "lps", "xosb"]', 'model = ["bond_based", "lps"]')
    path = tmp_path / "plate.toml"
    path.write_text(scene)
    table = tmp_path / "plate_tradeoff.csv"
    sc, chosen, res = select_scene(path, target_error=0.05, output=table)
    best = res.best(0.05)
    assert best is not None
    assert {p: str(v) for p, v in chosen.items()} == {p: str(best[p]) for p in res.params}
    # no faster row of the table meets the target
    ok = [r for r in res.ok() if float(r["error"]) <= 0.05]
    assert all(float(r[res.time]) >= float(best[res.time]) for r in ok)
    assert main(["run", str(path), "--select", "--target-error", "0.05", "--json", "-q",
                 "-o", str(tmp_path / "best.npz")]) == 0  # fmt: skip
    summary = json.loads(capsys.readouterr().out)
    assert summary["selected"]["model"] == str(chosen["model"])
    with pytest.raises(SceneError, match="no configuration of the sweep meets"):
        select_scene(path, target_error=1e-12, output=table)


def test_anisotropic_block_sweep():
    # the bundled orthotropic block (C11/C22 = 100): correspondence reproduces the uniaxial
    # closed form exactly (consistent), bond-based with bulk-calibrated micromoduli carries
    # its free-surface error (measured 0.8 % at δ = 2h, 4 % at 3h, h = 0.05)
    from pdlin.sweeps import anisotropic_block

    res = pdlin.tradeoff(
        anisotropic_block,
        {"model": ["bb", "correspondence:none"], "m": [2.015], "anisotropy": [100.0], "h": [0.05]},
        memory="none",
    )
    err = {r["model"]: float(r["error"]) for r in res.table}
    assert err["correspondence:none"] < 1e-10
    assert 1e-3 < err["bb"] < 0.02


def test_tradeoff_on_the_builtin_bar_scene(tmp_path, capsys):
    # pdlin tradeoff --example bar: the built-in scene's [tradeoff] table (δ/h and iterative
    # solver against the uniaxial-stress closed form); bond-based surface error measured
    # 4.8 % at δ = 2.015 h and 22 % at 3.015 h in the middle third (free lateral faces)
    from pdlin.cli.main import main

    out = tmp_path / "bar.csv"
    assert main(["tradeoff", "--example", "bar", "-o", str(out), "-q"]) == 0
    assert "fastest with error <= 0.1: m=2.015;solver=amg-cg" in capsys.readouterr().out
    rows = list(csv.DictReader(open(out)))
    err = {(r["m"], r["solver"]): float(r["error"]) for r in rows}
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    assert 0.02 < err[("2.015", "amg-cg")] < 0.1 < err[("3.015", "amg-cg")] < 0.4
    # both solvers reach the same field: the error is the model's, not the solver's
    assert abs(err[("2.015", "amg-cg")] - err[("2.015", "jacobi-cg")]) < 1e-4


def test_builtin_scene_without_a_tradeoff_table(monkeypatch, capsys):
    import pdlin.scene.scene as scene_mod
    from pdlin.cli.main import main

    data, path = scene_mod.builtin_scene("cp_shear")
    data.pop("tradeoff")
    monkeypatch.setattr(scene_mod, "builtin_scene", lambda name: (data, path))
    assert main(["tradeoff", "--example", "cp_shear", "-q"]) == 2
    assert "built-in scene 'cp_shear' has no [tradeoff] table" in capsys.readouterr().err


def _short_cp(name, steps=4):
    from pdlin.scene.scene import builtin_scene

    data, _ = builtin_scene(name)
    data["solver"].update(steps=steps, t_end=float(steps))
    return data


@pytest.mark.parametrize("name", ["cp_shear", "cp_compression"])
def test_nonlinear_scene_tradeoff_homogenized_stress_against_the_finest_run(name):
    # the built-in crystal-plasticity scenes carry a [tradeoff] table (h x method, reference
    # the finest Newton run); here 4 load steps and coarser grids: each point is solved by
    # solve_nonlinear and its error is that of the homogenized stress history
    from pdlin.scene.tradeoff import tradeoff_from_dict

    data = _short_cp(name)
    assert data["tradeoff"]["reference"] == "finest"
    data["tradeoff"]["sweep"] = {"h": [0.125, 0.0625], "method": ["newton", "adr"]}
    data["tradeoff"]["finest"] = {"h": 0.0625, "method": "newton"}
    res = tradeoff_from_dict(data).run(memory="none")
    rows = {(round(r["h"], 4), r["method"]): r for r in res.table}
    ref = rows[(0.0625, "newton")]
    assert ref["status"] == "reference" and ref["error"] == 0.0
    assert ref["solver_used"] == "newton" and ref["operator_used"] == "homogenized-stress"
    same_h = rows[(0.0625, "adr")]
    assert same_h["solver_used"] == "adr" and same_h["iterations"] > 10 * ref["iterations"]
    # ADR (e_l = 1e-6) against Newton on the same grid: a few 1e-3 at most (test_t18's tolerance
    # 1e-3 per plastic step, plus the non-unique plastic fields; measured 1.3e-3)
    assert 0.0 < same_h["error"] < 1e-2
    # the coarse grid discretizes the Voronoi grains differently: a larger, method-
    # independent error (measured 0.10 shear / 0.07 compression at 4 steps)
    coarse = [rows[(0.125, m)]["error"] for m in ("newton", "adr")]
    assert all(e > 5 * same_h["error"] for e in coarse)
    assert abs(coarse[0] - coarse[1]) < 0.1 * coarse[0]


def test_nonlinear_tradeoff_rejects_linear_only_options_and_keys():
    from pdlin.errors import SceneError
    from pdlin.scene.tradeoff import tradeoff_from_dict
    from pdlin.sweeps import tension_bar

    data = _short_cp("cp_shear", steps=1)
    data["tradeoff"]["exact"] = {"F": [[1.0, 0.0], [0.0, 1.0]]}
    data["tradeoff"]["sweep"] = {"h": [0.125]}
    data["tradeoff"].pop("finest")
    # the sweep's only point fails: the sweep raises with the point's message (issue 31)
    with pytest.raises(InputError, match="tradeoff.exact and tradeoff.measure apply to linear "
                       "scenes") as info:  # fmt: skip
        tradeoff_from_dict(data).run(memory="none")
    assert isinstance(info.value.__cause__, SceneError)
    # a nonlinear-only sweep key on a linear case is named in the point's message
    with pytest.raises(InputError, match="sweep key 'method' needs a nonlinear case"):
        pdlin.tradeoff(tension_bar, {"method": ["newton"]}, memory="none")


def test_scene_fem_reference_q4_at_the_particles():
    # reference = "fem": the Q4 counterpart of each sweep point's grid (nodes at the
    # particles, the scene's own conditions and nodal forces); correspondence (penalty)
    # converges to it: errors measured 0.225 / 0.141 / 0.085 at h = 0.1 / 0.05 / 0.025
    # (rate 0.70: the O(h) hull difference and the nodal end loads), 2026-11-25
    from pdlin.scene.tradeoff import tradeoff_from_dict

    data = {
        "geometry": {"type": "grid", "shape": [40, 20], "spacing": 0.05},
        "material": {"E": 1.0, "nu": 0.3, "plane": "stress"},
        "model": {"type": "correspondence", "control": "penalty"},
        "horizon": {"ratio": 2.015},
        "dirichlet": [{"set": "x-", "value": 0.0}],
        "load": [{"type": "total", "set": "x+", "force": [0.01, 0.0]}],
        "tradeoff": {"reference": "fem", "sweep": {"h": [0.1, 0.05, 0.025]}},
    }
    res = tradeoff_from_dict(data).run(memory="none")
    err = [float(r["error"]) for r in res.table]
    assert all(r["reference"] == "fem" for r in res.table)
    assert 0.15 < err[0] < 0.3 and err[0] > err[1] > err[2] and err[2] < 0.1
    assert 0.6 < res.rates("h")[0]["rate"] < 0.8


@pytest.mark.parametrize(
    "table, match",
    [
        ({"reference": "q4", "sweep": {"h": [0.1]}}, "tradeoff.reference must be"),
        ({"reference": "closed-form", "sweep": {"h": [0.1]}}, r"needs a \[tradeoff.exact\]"),
    ],
)
def test_scene_reference_errors(table, match):
    from pdlin.errors import SceneError
    from pdlin.scene.tradeoff import tradeoff_from_dict

    data = {
        "geometry": {"type": "grid", "shape": [10, 5], "spacing": 0.1},
        "material": {"E": 1.0, "nu": 0.3, "plane": "stress"},
        "model": {"type": "correspondence"},
        "horizon": {"ratio": 2.015},
        "dirichlet": [{"set": "x-", "value": 0.0}],
        "tradeoff": table,
    }
    with pytest.raises(SceneError, match=match):
        tradeoff_from_dict(data)


# --- sweeps that measure nothing raise (issue 31, item 4) ---------------------------------


def _always_raises(**params):
    return 1 / 0


def test_tradeoff_refuses_a_non_callable_factory():
    with pytest.raises(pdlin.errors.InputTypeError, match=r"factory must be callable.* got int 42"):
        tradeoff(42, {"a": [1]}, memory="none")


def test_tradeoff_refuses_an_empty_grid():
    with pytest.raises(InputError, match=r"grid must name at least one parameter .* got \{\}"):
        tradeoff(graded_bar, {}, memory="none")


@pytest.mark.parametrize("memory", ["none", "rss"])
def test_tradeoff_raises_when_every_point_fails(memory, tmp_path):
    if memory == "rss" and not hasattr(__import__("os"), "fork"):
        pytest.skip("rss mode needs fork")
    out = tmp_path / "t.csv"
    with pytest.raises(
        InputError,
        match=r"every point of the sweep failed \(2 of 2, none measured\); first failure, "
        r"point a=1: ZeroDivisionError: division by zero",
    ) as info:
        tradeoff(_always_raises, {"a": [1, 2]}, memory=memory, output=out)
    assert info.value.__cause__ is not None  # the first failure, chained
    # the failures are still recorded point by point
    with out.open() as f:
        assert [r["status"] for r in csv.DictReader(f)] == ["failed", "failed"]


def test_tradeoff_keeps_failed_points_while_others_succeed():
    def factory(N, fail):
        if fail:
            raise RuntimeError("this point breaks")
        return graded_bar(N=N)

    res = tradeoff(factory, {"N": [100], "fail": [False, True]}, memory="none")
    assert [r["status"] for r in res.table] == ["ok", "failed"]
    assert res.table[1]["message"] == "this point breaks"


def test_cli_tradeoff_every_point_failing_is_one_error_line(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(
        """
[geometry]
shape = [20]
spacing = 0.05
[material]
E = 1.0
[horizon]
ratio = 3.015
[[dirichlet]]
set = "x-"
[[load]]
set = "x+"
force = [1e-3]
[tradeoff.sweep]
solver = ["nope", "lu"]
"""
    )
    from pdlin.cli.main import main

    code = main(["tradeoff", str(scene), "-q"])
    err = capsys.readouterr().err
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.startswith("pdlin:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("pdlin: error: every point of the sweep failed (2 of 2")
    assert "solver must be one of" in lines[0]


def test_solver_used_names_the_direct_backend_that_ran():
    """A direct row says which factorization ran: 'auto' picks CHOLMOD / PARDISO when they are
    installed and the system is large, so "direct" alone hid a change of backend (issue 33)."""
    from pdlin.solvers import DIRECT_BACKENDS
    from pdlin.sweeps import affine_patch

    grid = {"model": ["bb"], "dim": [2], "h": [0.1], "m": [2.0], "solver": ["direct", "amg-cg"]}
    res = tradeoff(affine_patch, grid, memory="none")
    used = {r["solver"]: r["solver_used"] for r in res.table}
    backend = used["direct"].removeprefix("direct (").removesuffix(")")
    assert used["direct"] == f"direct ({backend})" and backend in DIRECT_BACKENDS[1:], used
    assert used["amg-cg"] == "amg-cg"  # iterative rows unchanged
    assert f"direct solves ran: direct ({backend})" in res.summary()  # pdlin tradeoff's table
