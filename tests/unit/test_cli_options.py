"""``pdlin run`` outputs and options (issue 34): the homogenized CSV beside ``-o``,
global options after the subcommand, ``pdlin sparsity`` of the constrained system."""

from __future__ import annotations

from pathlib import Path

import pytest

from pdlin.cli.main import main
from tests.test_cli import CP_SCENE


def _write(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("scene_csv", [False, True])
def test_homogenized_csv_goes_beside_the_o_result(tmp_path, monkeypatch, scene_csv):
    """docs/scene.md: ``-o RES.pvd`` writes ``RES_homogenized.csv`` beside it, also when the
    scene names its own CSV (as the bundled cp_* examples do); ``pdlin plot RES.pvd`` reads it."""
    text = CP_SCENE.replace("steps = 4\nt_end = 4.0", "steps = 2\nt_end = 2.0")
    if scene_csv:
        text = text.replace('path = "out/cp.pvd"', 'path = "out/cp.pvd"\nhomogenized = "cp.csv"')
    scene = _write(tmp_path, text)
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["run", str(scene), "-q", "-o", str(tmp_path / "res" / "run.pvd")]) == 0
    assert (tmp_path / "res" / "run_homogenized.csv").is_file()
    assert not list(work.iterdir()) and not (tmp_path / "cp.csv").exists()
    # without -o: the scene's own CSV (or the default beside output.path)
    assert main(["run", str(scene), "-q"]) == 0
    expected = tmp_path / ("cp.csv" if scene_csv else "out/cp_homogenized.csv")
    assert expected.is_file()


@pytest.mark.parametrize("command", ["run", "info", "sparsity", "export", "tradeoff", "plot"])
def test_global_options_after_the_subcommand(command):
    """``pdlin run -v`` as ``pdlin -v run``: -v/--verbose is accepted on either side."""
    from pdlin.cli.main import build_parser

    p = build_parser()
    extra = ["-o", "x.npz"] if command == "export" else []
    for argv, want in (
        ([command, "s.toml", *extra], False),
        (["-v", command, "s.toml", *extra], True),
        ([command, "s.toml", "-v", *extra], True),
        ([command, "--verbose", "s.toml", *extra], True),
    ):
        assert p.parse_args(argv).verbose is want, argv


def test_run_verbose_after_subcommand_logs(tmp_path, capsys):
    from tests.test_cli import SCENE

    scene = _write(tmp_path, SCENE)
    assert main(["run", str(scene), "-q", "-v"]) == 0
    assert (tmp_path / "out" / "plate.vtu").is_file()
    assert main(["examples", "--verbose"]) == 0


def test_sparsity_reports_the_constrained_system(tmp_path, capsys):
    """``pdlin sparsity SCENE`` eliminates the scene's Dirichlet DOFs: fixed DOFs, the
    sparsity of K_ff as well as K's, and the zero-energy modes of K_ff (none here)."""
    import json

    import numpy as np

    import pdlin
    from pdlin.scene.scene import load_scene
    from tests.test_cli import SCENE

    scene_path = _write(tmp_path, SCENE)
    assert main(["sparsity", str(scene_path), "--json", "--numeric"]) == 0
    rep = json.loads(capsys.readouterr().out)
    scene = load_scene(scene_path)
    cloud = scene.cloud
    fixed = 2 * cloud.sets["x-"].size  # x- fixed in both components (SCENE's [[dirichlet]])
    assert rep["n_fixed"] == fixed == 20  # 10 points of the 30 x 10 grid's x- edge, 2 DOFs
    # K_ff counted independently: assemble K, drop the fixed rows and columns
    K = sp_csr(pdlin.assemble_stiffness(scene.model, cloud, scene.bonds()))
    free = np.ones(K.shape[0], bool)
    free[(2 * cloud.sets["x-"][:, None] + np.arange(2)).ravel()] = False
    Kff = K[np.flatnonzero(free)][:, np.flatnonzero(free)]
    assert rep["nnz"] == K.nnz and rep["nnz_free"] == Kff.nnz
    rows = np.diff(Kff.indptr)
    assert rep["nnz_per_row_free_min"] == rows.min()
    assert rep["nnz_per_row_free_max"] == rows.max()
    assert rep["nnz_per_row_free_mean"] == pytest.approx(rows.mean())
    assert rep["zero_modes"] == 0  # the clamped edge removes the 3 rigid modes of K
    assert main(["sparsity", str(scene_path), "--numeric"]) == 0
    text = capsys.readouterr().out
    assert "free DOFs (K_ff) nnz / per row" in text and "zero-energy modes (K_ff)" in text


def sp_csr(K):
    import scipy.sparse as sp

    Kc = sp.csr_array(K)
    Kc.sum_duplicates()
    Kc.sort_indices()
    return Kc
