"""Installation hazards: what pdlin leaves on disk, what ``import pdlin`` costs.

- numba's on-disk cache must not land inside the installed package: files left in
  ``site-packages/pdlin/__pycache__`` survive ``pip uninstall`` and turn the folder into an
  empty namespace package that shadows the next (editable) install.
- ``import pdlin`` must not import the heavy optional parts (sympy, cvxpy, numba, ...).
"""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _env(**extra: str) -> dict[str, str]:
    """This environment without PYTHONPATH (the worktree must not shadow the install)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PIP_REQUIRE_VIRTUALENV")}
    env.update(extra)
    return env


def _run(args: list[str], cwd: Path, env: dict[str, str]) -> str:
    out = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, f"{args}:\n{out.stdout}\n{out.stderr}"
    return out.stdout


@pytest.mark.slow
def test_numba_cache_survives_uninstall_and_editable_reinstall(tmp_path: Path) -> None:
    """install -> run a numba kernel -> uninstall -> ``pip install -e .`` -> import works.

    The throwaway venv sees this interpreter's site-packages through a ``.pth`` line
    (numpy, scipy, numba, pip, setuptools), so the installs need neither the network nor
    dependencies (``--no-deps --no-build-isolation``).
    """
    pytest.importorskip("numba")
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = Path(
        subprocess.run(
            [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    )
    # after the venv's own site-packages: this interpreter's packages except pdlin (no
    # installed or editable pdlin of this environment may answer ``import pdlin``)
    outer = tmp_path / "outer"
    outer.mkdir()
    for entry in Path(sysconfig.get_paths()["purelib"]).iterdir():
        if not entry.name.lower().startswith(("pdlin", "__editable__")) and entry.suffix != ".pth":
            (outer / entry.name).symlink_to(entry)
    (site / "_outer.pth").write_text(f"{outer}\n")
    src = tmp_path / "src"  # a copy of the source tree (pip writes build/ and egg-info)
    _copy_source(ROOT, src)
    cache = tmp_path / "cache"
    env = _env(XDG_CACHE_HOME=str(cache))
    pip = [str(py), "-m", "pip", "install", "-q", "--no-deps"]
    _run([*pip, str(src)], tmp_path, env)
    installed = site / "pdlin"
    assert (installed / "__init__.py").is_file()
    # one numba kernel, compiled with its disk cache (PDLIN_NUMBA unset: numba on)
    code = (
        "import numpy as np; from pdlin._kernels import _kernels; "
        "k = _kernels(); assert k is not None; "
        "print(k.csr_t_block_offsets(np.ones((2, 3), np.int64))[0].tolist())"
    )
    env_run = {k: v for k, v in env.items() if k not in ("PDLIN_NUMBA", "NUMBA_CACHE_DIR")}
    # pointer of 2 chunks x 3 points with one block each: 0, 2, 4, 6 (cumulative counts)
    assert _run([str(py), "-c", code], tmp_path, env_run).split() == ["[0,", "2,", "4,", "6]"]
    left = sorted(p.name for p in installed.rglob("*.nb[ic]"))
    assert left == [], f"numba cache files inside the installed package: {left}"
    cached = list(cache.rglob("*.nbi"))
    assert cached, f"no numba index under {cache}"
    _run([str(py), "-m", "pip", "uninstall", "-y", "-q", "pdlin"], tmp_path, env)
    assert not installed.exists(), f"left after uninstall: {sorted(installed.rglob('*'))}"
    _run([*pip, "-e", str(src)], tmp_path, env)
    code = "import pdlin; print(pdlin.grid.__name__, pdlin.__file__)"
    out = _run([str(py), "-c", code], tmp_path, env).split()
    assert out == ["grid", str(src / "pdlin" / "__init__.py")]


def _copy_source(root: Path, dest: Path) -> None:
    """``pyproject.toml``, ``README.md`` and ``pdlin/`` without caches or build output."""
    import shutil

    dest.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(root / name, dest / name)
    shutil.copytree(
        root / "pdlin",
        dest / "pdlin",
        ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc"),
    )


def test_import_pdlin_leaves_heavy_optional_parts_unimported() -> None:
    """``import pdlin`` imports none of sympy, cvxpy, osqp, numba, matplotlib, meshio, pyamg."""
    heavy = ("sympy", "cvxpy", "osqp", "numba", "matplotlib", "meshio", "pyamg")
    code = f"import sys, pdlin; print(' '.join(m for m in {heavy!r} if m in sys.modules))"
    out = subprocess.run(
        [sys.executable, "-c", code],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.split() == []


def test_lazy_public_names_still_import() -> None:
    """Every name of ``pdlin.__all__`` resolves (lazily imported ones on first access)."""
    import pdlin

    missing = [name for name in pdlin.__all__ if getattr(pdlin, name, None) is None]
    assert missing == []
    from pdlin import higher_order_weights, weights_table  # noqa: F401


def _readme_test_command() -> str:
    """The README's Quick start command that runs the test suite."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    cmds = [ln for ln in lines if ln.startswith("pip install") and "pytest" in ln]
    assert len(cmds) == 1, cmds
    return cmds[0]


def test_readme_test_command_runs_the_suite_in_parallel() -> None:
    """The README's test command spreads the suite over the CPUs (pytest-xdist, ``-n auto``),
    the ``test`` extra installs pytest-xdist, and CI runs the README's command verbatim."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib

    cmd = _readme_test_command()
    assert cmd.split()[-2:] == ["-n", "auto"], cmd
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"][
        "optional-dependencies"
    ]
    assert any(req.startswith("pytest-xdist") for req in extras["test"]), extras["test"]
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert cmd in ci, f"{cmd!r} is not a line of .ci/run"


def test_gallery_size_problems_do_not_compile_numba() -> None:
    """Problems of the gallery's size (10³ points, 625 crystal-plasticity points) stay on
    numpy / scipy: numba is not even imported, so a first run compiles nothing (compiling
    the kernels took 60-100 s on a loaded machine for ``lps_cube`` and ``cp_compression``,
    whose warm runs take seconds: benchmarks/bench_first_run.py)."""
    pytest.importorskip("numba")
    code = """
import sys
import numpy as np
import pdlin
from pdlin._kernels import numba_enabled
assert numba_enabled.__module__ == "pdlin._kernels"
# the lps_cube scene: 10 x 10 x 10 points, horizon 2.015 h (pdlin/examples/lps_cube.toml)
cloud = pdlin.grid((10, 10, 10), spacing=0.1)
bonds = pdlin.find_bonds(cloud, ratio=2.015)
K = pdlin.LPS(E=200e9, nu=0.25).stiffness(cloud, bonds)
# the cp scenes' crystal-plasticity update: 625 points of planar double slip
mat = pdlin.CrystalPlasticity()
F = np.tile(np.eye(2) + 0.01 * np.array([[0.0, 1.0], [1.0, 0.0]]), (625, 1, 1))
mat.update(F, mat.initial_state(625), tangent=False)
print("numba" in sys.modules)
"""
    env = {k: v for k, v in os.environ.items() if k != "PDLIN_NUMBA"}
    env["PYTHONPATH"] = str(ROOT)
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False"]


def _requirement(req: str) -> tuple[str, str | None]:
    """``(name, lower bound)`` of a requirement string such as ``"scipy>=1.15; ..."``."""
    import re

    spec = req.split(";")[0].strip()
    m = re.fullmatch(r"([A-Za-z0-9_.\-]+)(?:\[[^\]]*\])?\s*(?:>=\s*([0-9][^,\s]*))?.*", spec)
    assert m, req
    return m.group(1).lower(), m.group(2)


def test_declared_floors_are_the_tested_floors() -> None:
    """Every runtime dependency (and the optional packages the tests use) has a lower bound in
    pyproject.toml, and .ci/floors.txt, the versions CI installs and tests in a venv of
    their own (.ci/run), pins exactly that bound: a floor that is declared but never
    tested (``scipy>=1.10`` while pdlin needed 1.15) cannot come back unnoticed."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extras = project["optional-dependencies"]
    tools = ("pytest", "pytest-xdist", "hypothesis")  # the test runner's own packages
    reqs = [r for r in project["dependencies"] if "python_version" not in r]
    reqs += extras["fast"] + [r for r in extras["test"] if _requirement(r)[0] not in tools]
    declared = dict(_requirement(r) for r in reqs)
    assert all(declared.values()), declared
    for name, group in extras.items():  # one floor per package in every extra
        for r in group:
            pkg, low = _requirement(r)
            assert pkg not in declared or low == declared[pkg], (name, r, declared[pkg])
    pins = {}
    for line in (ROOT / ".ci" / "floors.txt").read_text(encoding="utf-8").splitlines():
        line = line.split("#")[0].strip()
        if line:
            name, _, version = line.partition("==")
            pins[name.strip().lower()] = version.strip()
    from packaging.version import Version  # (a dependency of pytest)

    assert {k: Version(v) for k, v in pins.items()} == {k: Version(v) for k, v in declared.items()}
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert ".ci/floors.txt" in ci


def test_unwritable_cache_directory_compiles_without_disk_cache(tmp_path: Path) -> None:
    """Where the per-user cache directory cannot be made (``XDG_CACHE_HOME`` is a file),
    the kernels still run, compiled in memory only: nothing is written into pdlin's folder
    (numba's default would fall back to it)."""
    pytest.importorskip("numba")
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("")
    code = (
        "import numpy as np; from pdlin import _numba_kernels as k; "
        "print(k.cache_dir(), type(k.csr_t_block_offsets._cache).__name__, "
        "k.csr_t_block_offsets(np.ones((1, 2), np.int64))[0].tolist())"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(PYTHONPATH=str(ROOT), XDG_CACHE_HOME=str(blocker))
    before = sorted((ROOT / "pdlin").rglob("*.nb[ic]"))
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    # cache_dir() None; numba's no-op cache; pointer of 1 chunk x 2 points: 0, 1, 2
    assert out.stdout.split() == ["None", "NullCache", "[0,", "1,", "2]"]
    assert sorted((ROOT / "pdlin").rglob("*.nb[ic]")) == before
