"""Hostile input: result writers and system export; a failed write leaves no file."""

from __future__ import annotations

import numpy as np
import pytest
from hostile_util import NAN, expect, problem

import pdlin
from pdlin.errors import FloatingBodyError, InputError, InputTypeError, NonFiniteError, ShapeError
from pdlin.io import export_system, write_points, write_series

C = pdlin.grid((4, 4), 0.1)
U = np.zeros((16, 2))

CASES = [
    (
        "points-ext",
        lambda d: write_points(d / "a.xyz", C, {"u": U}),
        InputError,
        r"output path must end with one of .* got '.*a.xyz'",
    ),
    (
        "points-nan",
        lambda d: write_points(d / "a.vtu", C, {"u": np.full((16, 2), NAN)}),
        InputError,
        r"field 'u' holds NaN or inf; refusing to write it",
    ),
    (
        "points-rows",
        lambda d: write_points(d / "a.vtu", C, {"u": np.zeros((5, 2))}),
        ShapeError,
        r"field 'u' must have 16 rows, got shape \(5, 2\)",
    ),
    (
        "points-str",
        lambda d: write_points(d / "a.vtu", C, {"u": "abc"}),
        InputError,
        r"field 'u' must be a numeric array, got str",
    ),
    (
        "points-scalar",
        lambda d: write_points(d / "a.vtu", C, {"u": 1.0}),
        ShapeError,
        r"field 'u' must have 16 rows, got shape \(\)",
    ),
    (
        "points-not-mapping",
        lambda d: write_points(d / "a.vtu", C, [1, 2]),
        InputTypeError,
        r"fields must be a mapping .* got list",
    ),
    (
        "points-name",
        lambda d: write_points(d / "a.vtu", C, {1: np.zeros(16)}),
        InputTypeError,
        r"field names must be non-empty strings, got 1",
    ),
    (
        "points-cloud",
        lambda d: write_points(d / "a.vtu", None, {}),
        InputTypeError,
        r"cloud must be a PointCloud, got NoneType",
    ),
    (
        "points-npz-nan",
        lambda d: write_points(d / "a.npz", C, {"u": np.full(16, np.inf)}),
        InputError,
        r"field 'u' holds NaN or inf",
    ),
    (
        "series-length",
        lambda d: write_series(d / "s.pvd", C, [0.0, 1.0], [{"u": U}]),
        ShapeError,
        r"times and steps must have the same non-zero length, got 2 and 1",
    ),
    (
        "series-times-nan",
        lambda d: write_series(d / "s.pvd", C, [NAN], [{"u": U}]),
        NonFiniteError,
        r"times must be finite, got nan",
    ),
    (
        "series-decreasing",
        lambda d: write_series(d / "s.pvd", C, [1.0, 0.5], [{"u": U}] * 2),
        InputError,
        r"times must be increasing, got times\[0\] = 1.0 and times\[1\] = 0.5",
    ),
    (
        "series-ext",
        lambda d: write_series(d / "s.txt", C, [1.0], [{"u": U}]),
        InputError,
        r"series path must end with one of .* got '.*s.txt'",
    ),
    (
        "series-nan-step",
        lambda d: write_series(
            d / "s.pvd", C, [1.0, 2.0], [{"u": U}, {"u": np.full((16, 2), NAN)}]
        ),
        InputError,
        r"field 'u' holds NaN or inf",
    ),
    ("series-empty", lambda d: write_series(d / "s.pvd", C, [], []), ShapeError, r"got 0 and 0"),
    (
        "series-npz-rows",
        lambda d: write_series(d / "s.npz", C, [1.0], [{"u": np.zeros((3, 2))}]),
        ShapeError,
        r"field 'u' must have 16 rows, got shape \(3, 2\)",
    ),
    (
        "export-ext",
        lambda d: export_system(d / "K.txt", problem()),
        InputError,
        r"export path must end with .mtx or .npz, got '.*K.txt'",
    ),
    (
        "export-problem",
        lambda d: export_system(d / "K.mtx", "p"),
        InputTypeError,
        r"problem must be a StaticProblem, got str",
    ),
    (
        "export-floating",
        lambda d: export_system(d / "K.mtx", problem(dirichlet=[])),
        FloatingBodyError,
        r"the body is floating",
    ),
    (
        "export-nan-load",
        lambda d: export_system(
            d / "K.npz", problem(loads=[pdlin.BodyForce("all", lambda x: np.full(x.shape, NAN))])
        ),
        NonFiniteError,
        r"loads\[0\].density \(callable result\) must be finite",
    ),
    (
        "export-eliminated",
        lambda d: export_system(d / "K.npz", problem(), eliminated="yes"),
        InputTypeError,
        r"eliminated must be True or False, got 'yes'",
    ),
]


@pytest.mark.parametrize(
    ("call", "exc", "pattern"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_writers_reject_and_leave_nothing(tmp_path, call, exc, pattern):
    expect(lambda: call(tmp_path), exc, pattern)
    assert list(tmp_path.iterdir()) == [], "a failed write left files behind"


def _garbage(d, name, text="not a result file"):
    p = d / name
    p.write_text(text)
    return p


READ_CASES = [
    ("read-suffix", lambda d: _garbage(d, "r.txt"), r"result file must end with one of"),
    ("read-missing", lambda d: d / "absent.vtu", r"result file '.*absent.vtu' does not exist"),
    ("read-exodus-garbage", lambda d: _garbage(d, "r.e"), r"cannot read '.*r.e' as a pdlin result"),
    ("read-vtu-garbage", lambda d: _garbage(d, "r.vtu"), r"cannot read '.*r.vtu'"),
    ("read-npz-garbage", lambda d: _garbage(d, "r.npz"), r"cannot read '.*r.npz'"),
    ("read-pvd-garbage", lambda d: _garbage(d, "r.pvd"), r"is not a ParaView .pvd collection"),
    (
        "read-pvd-empty",
        lambda d: _garbage(d, "r.pvd", "<VTKFile><Collection/></VTKFile>"),
        r"lists no DataSet files",
    ),
    (
        "read-pvd-missing-step",
        lambda d: _garbage(
            d, "r.pvd", '<VTKFile><Collection><DataSet file="gone.vtu"/></Collection></VTKFile>'
        ),
        r"cannot read '.*r.pvd'",
    ),
]


@pytest.mark.parametrize(
    ("make", "pattern"), [c[1:] for c in READ_CASES], ids=[c[0] for c in READ_CASES]
)
def test_reader_rejects_with_the_file_named(tmp_path, make, pattern):
    from pdlin.io import read_result

    if "exodus" in pattern or "r.e'" in pattern:
        pytest.importorskip("netCDF4")
    expect(lambda: read_result(make(tmp_path)), InputError, pattern)


# -- a real full disk (item 6) ------------------------------------------------------------

_TMPFS_STATIC = (
    'name = "plate"\n[geometry]\ntype = "grid"\nshape = [12, 12]\nspacing = 0.1\n'
    '[material]\nE = 1.0\n[horizon]\nratio = 3.015\n[[dirichlet]]\nset = "x-"\nvalue = 0.0\n'
    '[[dirichlet]]\nset = "x+"\nvalue = 1e-3\ncomponents = "x"\n'
)
#: the 8 x 8 polycrystal of test_hostile_checkpoint.py, two Newton steps (a .pvd series)
_TMPFS_SERIES = (
    'name = "cp"\n[geometry]\ntype = "grid"\nshape = [8, 8]\nspacing = 0.125\n'
    '[material]\ntype = "crystal-plasticity"\n[material.polycrystal]\ngrains = 3\nseed = 1\n'
    '[model]\ntype = "correspondence"\n[horizon]\nratio = 1.0\ninfluence = "constant"\n'
    '[[dirichlet]]\nset = "boundary"\nvelocity_gradient = [[0.0, 0.004], [0.004, 0.0]]\n'
    '[solver]\nnonlinear = "newton"\nsteps = 2\nt_end = 2.0\n'
)


@pytest.fixture
def tiny_disk(tmp_path):
    """A 1 MiB tmpfs mounted in ``tmp_path`` (needs root and a mount namespace that allows
    it; skipped otherwise), unmounted after."""
    import shutil
    import subprocess

    disk = tmp_path / "disk"
    disk.mkdir()
    mount, umount = shutil.which("mount"), shutil.which("umount")
    if mount is None or umount is None:
        pytest.skip("no mount command")
    done = subprocess.run(
        [mount, "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield disk
    finally:
        subprocess.run([umount, str(disk)], check=False)


@pytest.mark.parametrize(
    "scene, name",
    # the cases (the .e / .xdmf writers crashed, a .pvd series) in the default run;
    # the others (each ~2 s: two subprocesses) in the slow tier
    [(_TMPFS_STATIC, "r.e"), (_TMPFS_STATIC, "r.xdmf"), (_TMPFS_SERIES, "s.pvd")]
    + [
        pytest.param(scene, name, marks=pytest.mark.slow)
        for scene, name in [(_TMPFS_STATIC, "r.vtu"), (_TMPFS_SERIES, "s.xdmf")]
        + [(_TMPFS_SERIES, "s.exo")]
    ],
)
def test_pdlin_run_on_a_full_disk_is_one_error_line(tmp_path, tiny_disk, scene, name):
    """``pdlin run`` writing to a real full file system (a tmpfs filled but for 1 kB): one
    ``pdlin: error:`` line naming the output and the reason, exit 2, the old output byte for
    byte and nothing partial left (main: h5py / netCDF4 errors, then signal 11)."""
    import os
    import subprocess
    import sys

    if name.endswith((".e", ".exo")):
        pytest.importorskip("netCDF4")
    if name.endswith(".xdmf"):
        pytest.importorskip("h5py")
    path = tmp_path / "scene.toml"
    path.write_text(scene)
    out = tiny_disk / name
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    cmd = [sys.executable, "-m", "pdlin", "run", str(path), "-q", "-o", str(out)]
    first = subprocess.run(cmd, capture_output=True, env=env, cwd=tmp_path)
    assert first.returncode == 0, first.stderr.decode()

    def files():
        return {str(p): p.read_bytes() for p in tiny_disk.rglob("*") if p.is_file()}

    before = files()
    st = os.statvfs(tiny_disk)
    (tiny_disk / "filler").write_bytes(b"\0" * (st.f_bavail * st.f_frsize - 1024))
    before[str(tiny_disk / "filler")] = (tiny_disk / "filler").read_bytes()
    again = subprocess.run(cmd, capture_output=True, env=env, cwd=tmp_path)
    err = again.stderr.decode()
    assert again.returncode == 2, err
    assert err.count("\n") == 1 and err.startswith("pdlin: error: cannot write "), err
    assert str(tiny_disk) in err and "No space left on device" in err, err
    assert files() == before
    assert not [p for p in tiny_disk.rglob("*") if p.name.endswith((".partial", ".tmp"))]


def test_checkpoint_on_a_full_disk_is_one_error_line(tmp_path, tiny_disk):
    """A nonlinear run whose checkpoint lives on a full file system: one ``pdlin: error:``
    line naming the checkpoint, exit 2, the previous checkpoint byte for byte, no
    ``.tmp`` left (item 8 on a real full disk)."""
    import os
    import subprocess
    import sys

    ck = tiny_disk / "cp.ckpt.npz"
    path = tmp_path / "scene.toml"
    path.write_text(_TMPFS_SERIES + f"checkpoint = {str(ck)!r}\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    cmd = [sys.executable, "-m", "pdlin", "run", str(path), "-q", "-o", str(tmp_path / "s.pvd")]
    first = subprocess.run(cmd, capture_output=True, env=env, cwd=tmp_path)
    assert first.returncode == 0, first.stderr.decode()
    old = ck.read_bytes()
    st = os.statvfs(tiny_disk)
    (tiny_disk / "filler").write_bytes(b"\0" * (st.f_bavail * st.f_frsize - 1024))
    again = subprocess.run(cmd, capture_output=True, env=env, cwd=tmp_path)
    err = again.stderr.decode()
    assert again.returncode == 2, err
    assert err.count("\n") == 1 and err.startswith("pdlin: error: "), err
    assert str(ck) in err and "No space left on device" in err, err
    assert ck.read_bytes() == old
    assert sorted(p.name for p in tiny_disk.iterdir()) == ["cp.ckpt.npz", "filler"]
