"""Safe output: a killed writer never leaves a truncated result; system export."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import scipy.io

import pdlin
from pdlin.cli.main import main
from pdlin.io import export_system, write_points

WRITER = textwrap.dedent(
    """
    import sys, numpy as np, pdlin
    from pdlin.io import write_points
    cloud = pdlin.grid((200, 200))
    k = 0
    while True:  # rewrite the same target until killed
        k += 1
        write_points(sys.argv[1], cloud, {"u": np.full((cloud.n, 2), float(k)),
                                          "noise": np.random.default_rng(k).random((cloud.n, 6))})
        print(k, flush=True)
    """
)


@pytest.mark.parametrize("suffix", [".npz", ".vtu", ".e"])
def test_killed_writer_leaves_a_complete_file(tmp_path, suffix):
    if suffix == ".e":
        pytest.importorskip("netCDF4")
    target = tmp_path / f"result{suffix}"
    script = tmp_path / "writer.py"
    script.write_text(WRITER)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen(
        [sys.executable, str(script), str(target)], stdout=subprocess.PIPE, env=env, text=True
    )
    try:
        assert proc.stdout is not None
        proc.stdout.readline()  # one complete write
        time.sleep(0.05 + 0.2 * np.random.default_rng().random())  # then kill mid-write
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    # the target is a complete file from one of the writes: every value of u the same
    cloud = pdlin.grid((200, 200))
    if suffix == ".npz":
        u = np.load(target)["u"]
    elif suffix == ".e":
        from pdlin.io import read_result

        u = read_result(target).fields()["u"][:, :2]
    else:
        import meshio

        u = meshio.read(target).point_data["u"][:, :2]
    assert u.shape == (cloud.n, 2) and np.unique(u).size == 1
    # a killed writer may leave its hidden staging directory; the next write clears it
    write_points(target, cloud, {"u": np.zeros((cloud.n, 2))})
    assert sorted(os.listdir(tmp_path)) == sorted(["writer.py", target.name])


def _problem():
    cloud = pdlin.grid((8, 4), spacing=0.1)
    return pdlin.StaticProblem(
        pdlin.LPS(E=1.0, nu=0.3),
        cloud,
        horizon=0.2015,
        dirichlet=[pdlin.Dirichlet("x-", 0.0)],
        loads=[pdlin.TotalForce("x+", [1e-3, 0.0])],
    )


def test_exported_system_solves_to_pdlins_answer(tmp_path):
    prob = _problem()
    ref = pdlin.solve(prob, solver="direct").u.ravel()
    p = export_system(tmp_path / "sys.npz", prob)
    d = np.load(p)
    import scipy.sparse as sp

    A = sp.csr_array((d["data"], d["indices"], d["indptr"]), shape=tuple(d["shape"]))
    x = np.linalg.solve(A.toarray(), d["rhs"])
    x[d["dofs"]] = d["values"]
    np.testing.assert_allclose(x, ref, rtol=1e-10, atol=1e-15)
    # unconstrained K, f in Matrix Market through the CLI
    scene_k = tmp_path / "K.mtx"
    raw = export_system(scene_k, prob, eliminated=False)
    K = scipy.io.mmread(raw)
    f = scipy.io.mmread(tmp_path / "K_rhs.mtx").ravel()
    np.testing.assert_allclose(K @ ref - f, pdlin.solve(prob).reactions.ravel(), atol=1e-9)


def test_export_command_and_bad_suffix(tmp_path, capsys):
    assert main(["export", "--example", "bar", "-o", str(tmp_path / "bar.npz")]) == 0
    assert "Dirichlet eliminated" in capsys.readouterr().out
    with pytest.raises(pdlin.errors.InputError, match="must end with .mtx or .npz"):
        export_system(tmp_path / "K.txt", _problem())


def _limited_writers():
    from pdlin.io import write_series
    from pdlin.plotting import save_figure

    cloud = pdlin.grid((30, 30))
    rng = np.random.default_rng(0)  # incompressible values: every file > the limit
    f = {"displacement": rng.random((cloud.n, 2)), "stress": rng.random((cloud.n, 2, 2))}

    def figure(p):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig = plt.figure()
        plt.plot(rng.random(2000))
        save_figure(fig, p, dpi=200)
        plt.close(fig)

    return {
        **{f"res{s}": (lambda p: write_points(p, cloud, f)) for s in (".vtu", ".vtk", ".npz")},
        **{f"res{s}": (lambda p: write_points(p, cloud, f)) for s in (".xdmf", ".e")},
        **{
            f"series{s}": (lambda p: write_series(p, cloud, [1.0, 2.0], [f, f]))
            for s in (".pvd", ".xdmf", ".npz", ".exo")
        },
        "K.mtx": lambda p: export_system(p, _problem()),
        "figure.png": figure,
    }


@pytest.mark.parametrize(
    "name",
    ["res.vtu", "res.vtk", "res.npz", "res.xdmf", "res.e"]
    + ["series.pvd", "series.xdmf", "series.npz", "series.exo", "K.mtx", "figure.png"],
)
def test_file_size_limit_fails_cleanly_with_the_path_named(tmp_path, name, file_size_limit):
    """Under RLIMIT_FSIZE every writer raises a WriteError naming the file and the reason,
    keeps the old files byte for byte and leaves no staging folder (h5py and netCDF4
    crashed the process with signal 11 here before; scipy's mmwrite truncated silently)."""
    if name.endswith((".e", ".exo")):
        pytest.importorskip("netCDF4")
    if name.endswith(".xdmf"):
        pytest.importorskip("h5py")
    if name.endswith(".png"):
        pytest.importorskip("matplotlib")
    write = _limited_writers()[name]
    target = tmp_path / name
    write(target)

    def files():
        return {str(p): p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}

    before = files()
    with file_size_limit(4000):  # bytes; every file of the writers is larger
        with pytest.raises(pdlin.errors.WriteError) as info:
            write(target)
    # the reason: EFBIG, or numpy's short write (.vtk) that carries no errno
    assert str(info.value).startswith(f"cannot write {str(target)!r}: "), info.value
    assert "file-size limit" in str(info.value), info.value
    assert files() == before
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".partial")]


def test_full_disk_error_names_the_file(tmp_path, monkeypatch):
    """ENOSPC inside a writer: a WriteError naming the target, the old file intact."""
    import errno

    cloud = pdlin.grid((4, 3))
    p = write_points(tmp_path / "r.npz", cloud, {"u": np.ones((cloud.n, 2))})
    before = p.read_bytes()

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(np, "savez_compressed", full)
    with pytest.raises(pdlin.errors.WriteError, match=r"cannot write '.*r\.npz': No space left"):
        write_points(p, cloud, {"u": np.zeros((cloud.n, 2))})
    assert p.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["r.npz"]


def _series(p, value):
    cloud = pdlin.grid((4, 3))
    return pdlin.io.write_series(
        p, cloud, [1.0, 2.0, 3.0], [{"displacement": np.full((cloud.n, 2), value)}] * 3
    )


@pytest.mark.parametrize("suffix", [".pvd", ".xdmf"])
def test_series_killed_during_its_renames_is_one_run(tmp_path, monkeypatch, suffix):
    """A series is replaced as one unit: killed after any number of its final renames,
    the main file reads back every step of the old run or every step of the new one."""
    if suffix == ".xdmf":
        pytest.importorskip("h5py")
    from pdlin.io import read_result

    target = tmp_path / f"run{suffix}"
    real = os.replace
    for allowed in range(8):  # 8 > the renames of a 3-step series (4 on main, 2 now)
        _series(target, 1.0)
        calls = []

        def replace(src, dst, calls=calls, allowed=allowed):
            if len(calls) == allowed:
                raise KeyboardInterrupt("killed")  # no clean-up, like SIGKILL
            calls.append(dst)
            real(src, dst)

        monkeypatch.setattr(os, "replace", replace)
        try:
            _series(target, 2.0)
        except KeyboardInterrupt:
            pass
        monkeypatch.setattr(os, "replace", real)
        values = {float(v) for s in read_result(target).steps for v in s["displacement"].ravel()}
        assert values in ({1.0}, {2.0}), f"killed after {allowed} rename(s): mixed {values}"
    # a last complete write leaves the main file and one set of companions
    _series(target, 3.0)
    assert len(os.listdir(tmp_path)) == 2, os.listdir(tmp_path)


def test_series_replaces_the_pieces_of_the_old_layout_only(tmp_path):
    """A .pvd of the earlier layout (run_0001.vtu ... beside it): its pieces are removed
    once the new series is in place; files it does not list are kept."""
    from pdlin.io import read_result

    old = _series(tmp_path / "run.pvd", 1.0)
    (piece_dir,) = tmp_path.glob("run.pvd.*")
    for f in piece_dir.iterdir():  # move the pieces to the earlier, flat layout
        f.rename(tmp_path / f.name)
    piece_dir.rmdir()
    old.write_text(old.read_text().replace(f"{piece_dir.name}/", ""))
    assert read_result(old).n_steps == 3
    (tmp_path / "run_0009.vtu").write_text("not listed by run.pvd")
    (tmp_path / "other_0001.vtu").write_text("another result")
    _series(tmp_path / "run.pvd", 2.0)
    left = sorted(f.name for f in tmp_path.iterdir() if not f.name.startswith("run.pvd."))
    assert left == ["other_0001.vtu", "run.pvd", "run_0009.vtu"]
    assert {float(v) for s in read_result(old).steps for v in s["displacement"].ravel()} == {2.0}


@pytest.mark.parametrize("suffix", [".pvd", ".xdmf"])
def test_the_same_series_gets_the_same_file_names(tmp_path, suffix):
    """Companions are named by a hash of the data: a run writing the same result (a resumed
    one) writes the same files; other data, other names."""
    if suffix == ".xdmf":
        pytest.importorskip("h5py")
    a, b = tmp_path / "a", tmp_path / "b"
    _series(a / f"run{suffix}", 1.0)
    _series(b / f"run{suffix}", 1.0)
    _series(b / f"run{suffix}", 1.0)  # rewritten with the same data: unchanged
    assert sorted(os.listdir(a)) == sorted(os.listdir(b)) and len(os.listdir(a)) == 2
    assert (a / f"run{suffix}").read_bytes() == (b / f"run{suffix}").read_bytes()
    _series(b / f"run{suffix}", 2.0)
    assert sorted(os.listdir(a)) != sorted(os.listdir(b)) and len(os.listdir(b)) == 2
