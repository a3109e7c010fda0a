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
