"""Hostile checkpoints of solve_nonlinear and ``pdlin run --resume`` (issue 31, items 1, 5,
8, 9): another problem's checkpoint, a corrupt or old one, a full disk, a killed run."""

from __future__ import annotations

import errno
import shutil
from pathlib import Path
from typing import Any

import meshio
import numpy as np
import pytest
from hostile_util import expect

import pdlin
import pdlin.nonlinear as nl
from pdlin.cli.main import main
from pdlin.errors import CheckpointError, CheckpointWriteError, InputError, PdlinError

#: shear velocity gradient of the small polycrystal (Luo, Ramazani & Sundararaghavan (2017), Eq. 25,
#: per unit time)
SHEAR = 0.002 * np.array([[0.0, 1.0], [1.0, 0.0]])
#: Newton, three steps of the 8 x 8 polycrystal: ≈ 0.1 s (measured)
KW: dict[str, Any] = {"times": [1.0, 2.0, 3.0], "method": "newton"}


def _poly(
    seed: int = 1, L: np.ndarray = SHEAR, control: str = "none", ratio: float = 1.0, n: int = 8
) -> pdlin.StaticProblem:
    """An n x n, 3-grain crystal-plasticity polycrystal in shear, built anew on every call."""
    cloud = pdlin.grid((n, n), spacing=1.0 / n)
    bonds = pdlin.find_bonds(cloud, ratio=ratio)
    _, theta = pdlin.voronoi_polycrystal(cloud, 3, seed=seed)
    kw = {"control": control, "penalty": 0.1} if control != "none" else {}
    model = pdlin.Correspondence(material=pdlin.CrystalPlasticity(orientation=theta), **kw)
    bc = pdlin.Dirichlet.velocity_gradient("boundary", L)
    return pdlin.StaticProblem(model, cloud, bonds, dirichlet=[bc])


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A checkpoint of two committed steps of ``_poly()`` (of the three of ``KW``)."""
    ck = tmp_path_factory.mktemp("ck") / "run.npz"
    pdlin.solve_nonlinear(_poly(), times=KW["times"][:2], method="newton", checkpoint=ck)
    return ck


def _resume(prob: pdlin.StaticProblem, ck: Path, tmp_path: Path, **kw: Any) -> Any:
    """Resume a copy of ``ck`` (the fixture's file stays as written)."""
    copy = tmp_path / ck.name
    shutil.copyfile(ck, copy)
    return pdlin.solve_nonlinear(prob, checkpoint=copy, **{**KW, "resume": True, **kw})


@pytest.mark.parametrize(
    "change, kw, part",
    [
        # issue 31's three reproduced cases (main exited 0 with the old run's stress)
        ("grain seed", {"prob": lambda: _poly(seed=2)}, "model and material parameters"),
        ("doubled L", {"prob": lambda: _poly(L=2 * SHEAR)}, "boundary conditions and loads"),
        ("control", {"prob": lambda: _poly(control="penalty")}, "model and material parameters"),
        ("horizon", {"prob": lambda: _poly(ratio=1.5)}, "bonds"),
        ("points", {"prob": lambda: _poly(n=9)}, "points"),
        ("rtol", {"rtol": 1e-6}, "solver options"),
        ("step times", {"times": [1.0, 2.5, 3.0]}, "step times"),
    ],
)
def test_resume_refuses_another_problems_checkpoint(written, tmp_path, change, kw, part):
    make = kw.pop("prob", _poly)
    expect(
        lambda: _resume(make(), written, tmp_path, **kw),
        CheckpointError,
        rf"checkpoint '.*run\.npz' was written for a different problem: .*{part}.* differ; "
        r"remove it, or start afresh without resume",
    )


def test_resume_names_every_differing_part(written, tmp_path):
    with pytest.raises(CheckpointError) as info:
        _resume(_poly(seed=2, L=2 * SHEAR), written, tmp_path, maxiter=30)
    msg = str(info.value)
    for part in ("model and material parameters", "boundary conditions", "solver options"):
        assert part in msg
    assert "points" not in msg and "bonds" not in msg and "step times" not in msg


def test_resume_of_the_same_problem_built_anew_continues_it(written, tmp_path):
    """New objects, a model whose caches and ``assembly`` record the first run, progress,
    keep_states and snapshot_every changed: the same problem, resumed bitwise."""
    prob = _poly()
    full = pdlin.solve_nonlinear(prob, **KW)  # fills the model's plan and assembly record
    res = _resume(prob, written, tmp_path, keep_states=False, snapshot_every=5.0)
    assert res.resumed_from == 2
    assert np.array_equal(res.u, full.u)
    # another driver from the same committed state: resume="branch"
    expect(lambda: _resume(_poly(), written, tmp_path, method="adr"), CheckpointError, "solver")
    adr = _resume(_poly(), written, tmp_path, method="adr", resume="branch")
    assert adr.resumed_from == 2 and adr.methods[-1] == "adr"
    expect(
        lambda: _resume(_poly(seed=2), written, tmp_path, resume="branch"),
        CheckpointError,
        "model and material parameters differ",
    )
    expect(lambda: _resume(prob, written, tmp_path, resume="yes"), InputError, "resume must be")


def test_plain_load_scaling_with_t_end_is_part_of_the_loads(tmp_path):
    """A plain prescribed value scales with t / t_end: another t_end is another load path
    (a velocity-gradient path does not depend on it)."""
    cloud = pdlin.grid((10,), spacing=0.1)
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        horizon=0.2,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3)],
    )
    ck = tmp_path / "bar.npz"
    pdlin.solve_nonlinear(prob, times=[1.0, 2.0], t_end=2.0, method="newton", checkpoint=ck)
    expect(
        lambda: pdlin.solve_nonlinear(
            prob, times=[1.0, 2.0, 3.0], t_end=3.0, method="newton", checkpoint=ck, resume=True
        ),
        CheckpointError,
        "boundary conditions and loads differ",
    )
    more = pdlin.solve_nonlinear(
        prob, times=[1.0, 2.0, 3.0], t_end=2.0, method="newton", checkpoint=ck, resume=True
    )
    assert more.resumed_from == 2


def test_resume_without_a_checkpoint_says_so(tmp_path):
    said: list[str] = []
    ck = tmp_path / "none.npz"
    res = pdlin.solve_nonlinear(_poly(), checkpoint=ck, resume=True, progress=said.append, **KW)
    assert said[0] == f"no checkpoint {ck} to resume: starting from step 1"
    assert res.resumed_from == 0 and ck.exists()


def test_checkpoint_without_fingerprint_is_refused(written, tmp_path):
    """A checkpoint of pdlin before issue 31 (version 1, no ``fp__*``) cannot be checked."""
    old = tmp_path / "old.npz"
    with np.load(written) as f:
        arrays = {k: f[k] for k in f.files if not k.startswith("fp__")}
    arrays["version"] = np.array(1)
    np.savez(old, **arrays)
    expect(
        lambda: pdlin.solve_nonlinear(_poly(), checkpoint=old, resume=True, **KW),
        CheckpointError,
        r"checkpoint '.*old\.npz' has no problem fingerprint \(version 1, written by an earlier",
    )


def _truncated(src: Path, dst: Path) -> None:
    dst.write_bytes(src.read_bytes()[: src.stat().st_size // 2])


def _garbage(src: Path, dst: Path) -> None:
    dst.write_bytes(b"not a checkpoint\n" * 64)


@pytest.mark.parametrize(
    "damage, why",
    # truncated: zipfile's BadZipFile; garbage: numpy's "pickled data" ValueError, here
    # "not an NPZ file" (measured on main: raw tracebacks)
    [(_truncated, "BadZipFile"), (_garbage, "not an NPZ file")],
)
def test_corrupt_checkpoint_is_named_unreadable(written, tmp_path, damage, why, capsys):
    bad = tmp_path / "bad.npz"
    damage(written, bad)
    expect(
        lambda: pdlin.solve_nonlinear(_poly(), checkpoint=bad, resume=True, **KW),
        CheckpointError,
        rf"checkpoint '.*bad\.npz' is unreadable \({why}",
    )
    # the CLI: one error line, exit 2
    scene = _scene(tmp_path, 'checkpoint = "bad.npz"')
    assert main(["run", str(scene), "-q", "--resume"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pdlin: error: checkpoint ")
    assert "bad.npz' is unreadable" in err[0]


def test_corrupt_adr_snapshot_is_named_and_the_step_starts_afresh(tmp_path, caplog):
    """An unreadable ``run.adr.npz`` (a snapshot only saves time) is named in a warning
    and the progress, and the run ends where an uninterrupted one does."""
    prob = _poly()
    kw: dict[str, Any] = {"times": [1.0], "method": "adr"}
    ref = pdlin.solve_nonlinear(prob, **kw)
    ck = tmp_path / "run.npz"
    (tmp_path / "run.adr.npz").write_bytes(b"PK\x03\x04 truncated")
    said: list[str] = []
    res = pdlin.solve_nonlinear(prob, checkpoint=ck, resume=True, progress=said.append, **kw)
    named = f"ADR snapshot file {tmp_path / 'run.adr.npz'} is unreadable ("
    assert any(m.startswith(named) for m in said)
    assert "run.adr.npz is unreadable" in caplog.text
    assert np.array_equal(res.u, ref.u)


_SAVEZ = np.savez


class _Full:
    """``np.savez`` on a full disk: writes a little, then ENOSPC."""

    def __init__(self) -> None:
        self.calls = 0

    def __call__(self, fh: Any, **arrays: Any) -> None:
        self.calls += 1
        if self.calls >= 2:  # the first checkpoint is written, the second is not
            fh.write(b"PK partial")
            raise OSError(errno.ENOSPC, "No space left on device")
        _SAVEZ(fh, **arrays)


def test_full_disk_names_the_checkpoint_and_leaves_no_tmp(tmp_path, monkeypatch):
    ck = tmp_path / "run.npz"
    monkeypatch.setattr(nl.np, "savez", _Full())
    expect(
        lambda: pdlin.solve_nonlinear(_poly(), checkpoint=ck, **KW),
        CheckpointWriteError,
        rf"could not write the checkpoint '{ck}': No space left on device; the previous",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]  # no run.npz.tmp
    monkeypatch.undo()
    assert int(np.load(ck)["done"]) == 1  # the previous checkpoint, intact
    assert isinstance(CheckpointWriteError("x"), OSError)  # caught as one by callers

    def interrupted(fh: Any, **arrays: Any) -> None:
        fh.write(b"PK partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(nl.np, "savez", interrupted)
    with pytest.raises(KeyboardInterrupt):
        pdlin.solve_nonlinear(_poly(), checkpoint=ck, **KW)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]


def test_failed_snapshot_write_names_the_snapshot_file(tmp_path, monkeypatch):
    """The ADR snapshot file (``run.adr.npz``, every 64 iterations with snapshot_every=0:
    step 3 of the 12 x 12 polycrystal takes 74, measured) is written the same way: a
    failed write names it and leaves no ``.tmp``; the checkpoint of the committed steps
    stays readable."""

    def full(fh: Any, **arrays: Any) -> None:
        if str(fh.name).endswith(".adr.npz.tmp"):
            raise OSError(errno.ENOSPC, "No space left on device")
        _SAVEZ(fh, **arrays)

    monkeypatch.setattr(nl.np, "savez", full)
    ck = tmp_path / "run.npz"
    expect(
        lambda: pdlin.solve_nonlinear(
            _poly(n=12), times=[1.0, 2.0, 3.0], method="adr", checkpoint=ck, snapshot_every=0
        ),
        CheckpointWriteError,
        rf"could not write the ADR snapshot file '{tmp_path / 'run.adr.npz'}': No space left",
    )
    assert not [p.name for p in tmp_path.iterdir() if p.name != "run.npz"]  # no .tmp
    monkeypatch.undo()
    assert not ck.exists() or int(np.load(ck)["done"]) >= 0


# -- pdlin run --resume ----------------------------------------------------------------

CP_SCENE = """
name = "cp"
[geometry]
type = "grid"
shape = [8, 8]
spacing = 0.125
[material]
type = "crystal-plasticity"
[material.polycrystal]
grains = 3
seed = 1
[model]
type = "correspondence"
[horizon]
ratio = 1.0
influence = "constant"
[[dirichlet]]
set = "boundary"
velocity_gradient = [[0.0, 0.004], [0.004, 0.0]]
[solver]
nonlinear = "newton"
steps = 4
t_end = 4.0
CHECKPOINT
[output]
path = "OUTPUT"
"""


def _scene(folder: Path, checkpoint: str, output: str = "out/cp.pvd", **edits: str) -> Path:
    text = CP_SCENE.replace("CHECKPOINT", checkpoint).replace("OUTPUT", output)
    for old, new in edits.items():
        text = text.replace(old, new)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "scene.toml"
    path.write_text(text)
    return path


class _Killed(Exception):
    pass


def _killed_after(monkeypatch: pytest.MonkeyPatch, line: str) -> None:
    """Kill ``pdlin run`` at its progress line starting with ``line``."""
    from pdlin.cli import main as cli

    real = cli._Progress.__call__

    def call(self: Any, msg: str) -> None:
        if msg.startswith(line):
            raise _Killed
        real(self, msg)

    monkeypatch.setattr(cli._Progress, "__call__", call)


@pytest.mark.parametrize("suffix", [".pvd", ".npz", ".xdmf", ".exo"])
def test_resumed_run_writes_the_files_of_an_uninterrupted_one(tmp_path, monkeypatch, suffix):
    """Killed after step 2 of 4 and resumed, ``pdlin run`` writes the same series (every
    step's displacement, reaction, stress and ``state_*`` fields, bitwise: Newton from the
    same committed states) and the same homogenized CSV as a run never killed."""
    if suffix == ".xdmf":
        pytest.importorskip("h5py")
    if suffix == ".exo":
        pytest.importorskip("netCDF4")
    out = f"out/cp{suffix}"
    whole = _scene(tmp_path / "whole", 'checkpoint = "cp.ckpt.npz"', out)
    assert main(["run", str(whole), "-q"]) == 0
    killed = _scene(tmp_path / "killed", 'checkpoint = "cp.ckpt.npz"', out)
    with monkeypatch.context() as m:
        _killed_after(m, "step 2/4")
        with pytest.raises(_Killed):
            main(["run", str(killed), "-q"])
    assert int(np.load(tmp_path / "killed" / "cp.ckpt.npz")["done"]) == 2
    assert main(["run", str(killed), "-q", "--resume"]) == 0
    a, b = tmp_path / "whole" / "out", tmp_path / "killed" / "out"
    assert sorted(p.name for p in a.iterdir()) == sorted(p.name for p in b.iterdir())
    if suffix == ".npz":
        with np.load(a / "cp.npz") as fa, np.load(b / "cp.npz") as fb:
            assert sorted(fa.files) == sorted(fb.files)
            assert any(k.startswith("state_") for k in fa.files)
            for key in fa.files:
                assert np.array_equal(fa[key], fb[key]), key
    elif suffix in (".xdmf", ".exo"):  # bitwise the same files, state fields in every step
        if suffix == ".xdmf":
            text = (a / "cp.xdmf").read_text()
            assert text.count('Name="State_gamma') >= 4, text  # one per step (4 steps)
        else:  # the names of the nodal variables (name_nod_var) hold the state fields
            assert b"State_gamma" in (a / "cp.exo").read_bytes()
        for pa in a.rglob("*"):
            if pa.is_file():
                assert pa.read_bytes() == (b / pa.relative_to(a)).read_bytes(), pa.name
    else:
        assert (a / "cp.pvd").read_text() == (b / "cp.pvd").read_text()
        for k in range(1, 5):
            (pa,), (pb,) = a.glob(f"cp.pvd.*/cp_{k:04d}.vtu"), b.glob(f"cp.pvd.*/cp_{k:04d}.vtu")
            ma, mb = meshio.read(pa), meshio.read(pb)
            assert sorted(ma.point_data) == sorted(mb.point_data), k
            assert "State_gamma" in ma.point_data
            for key, val in ma.point_data.items():
                assert np.array_equal(val, mb.point_data[key]), (k, key)
    csv_a = (a / "cp_homogenized.csv").read_text()
    assert csv_a == (b / "cp_homogenized.csv").read_text()


def test_cli_resume_of_a_changed_scene_is_one_error_line(tmp_path, capsys):
    scene = _scene(tmp_path, 'checkpoint = "cp.ckpt.npz"')
    assert main(["run", str(scene), "-q"]) == 0
    ck = (tmp_path / "cp.ckpt.npz").read_bytes()
    changed = {
        "seed = 1": "seed = 2",
        "0.004": "0.008",
        'type = "correspondence"': 'type = "correspondence"\ncontrol = "penalty"',
    }
    for old, new in changed.items():
        _scene(tmp_path, 'checkpoint = "cp.ckpt.npz"', **{old: new})
        assert main(["run", str(scene), "-q", "--resume"]) == 2, old
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1, err
        assert err[0].startswith("pdlin: error: checkpoint ") and "different problem" in err[0]
        assert (tmp_path / "cp.ckpt.npz").read_bytes() == ck  # left as it was
    # no checkpoint yet: said before step 1
    (tmp_path / "cp.ckpt.npz").unlink()
    _scene(tmp_path, 'checkpoint = "cp.ckpt.npz"')
    assert main(["run", str(scene), "--resume"]) == 0
    assert "no checkpoint" in capsys.readouterr().err


def test_errors_are_pdlin_errors():
    assert issubclass(CheckpointError, InputError) and issubclass(CheckpointWriteError, PdlinError)
