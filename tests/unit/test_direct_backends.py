"""Direct factorization backends behind ``solver='direct'`` (issue 13, "Direct solves").

Every installed backend must reproduce SuperLU's displacement; the ones that are not
installed are skipped with the install line in the reason.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import pdlin
from pdlin.cli.main import main
from pdlin.errors import ConvergenceError, InputError, MissingDependencyError
from pdlin.solvers import direct as direct_mod
from pdlin.solvers import solve_linear
from pdlin.solvers.direct import DirectSolver, available_direct_backends

AVAILABLE = available_direct_backends()
OPTIONAL = ("cholmod", "pardiso", "mumps")


def _need(name: str) -> None:
    if not AVAILABLE[name]:
        pytest.skip(f"direct backend {name!r} not installed ({direct_mod._INSTALL[name]})")


def _problem(kind: str, dim: int) -> pdlin.StaticProblem:
    shape = (14, 9) if dim == 2 else (7, 5, 5)
    cloud = pdlin.grid(shape, spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    kw = {"plane": "strain"} if dim == 2 else {}
    model = {
        "bb": lambda: pdlin.BondBased(E=1.0, nu=0.25, **kw),
        "lps": lambda: pdlin.LPS(E=1.0, nu=0.25, **kw),
        "corr": lambda: pdlin.Correspondence(E=1.0, nu=0.25, control="stress_points", **kw),
        "xosb-paper": lambda: pdlin.XOSB(E=1.0, nu=0.25, linearization="paper", **kw),
    }[kind]()
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 1e-3, components="x")]
    return pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc)


CASES = [(k, d) for k in ("bb", "lps", "corr") for d in (2, 3)]


@pytest.mark.parametrize("backend", OPTIONAL)
@pytest.mark.parametrize(("kind", "dim"), CASES)
def test_backend_matches_superlu(backend: str, kind: str, dim: int) -> None:
    _need(backend)
    prob = _problem(kind, dim)
    ref = pdlin.solve(prob, "direct", direct_backend="superlu")
    res = pdlin.solve(prob, "direct", direct_backend=backend)
    assert ref.info["direct_backend"] == "superlu"
    assert res.info["direct_backend"] == backend
    # same linear system, two factorizations: agreement to round-off (issue 13: 1e-10 rel)
    err = np.abs(res.u - ref.u).max() / np.abs(ref.u).max()
    assert err < 1e-10
    assert res.relative_residual < 1e-10


@pytest.mark.filterwarnings("ignore:XOSB")  # the coarse grid's corner λ systems
@pytest.mark.parametrize("backend", ("pardiso", "mumps"))
def test_nonsymmetric_backend_matches_superlu(backend: str) -> None:
    """The XOSB paper linearization K_p is nonsymmetric: LU backends only."""
    _need(backend)
    prob = _problem("xosb-paper", 2)
    ref = pdlin.solve(prob, "direct", direct_backend="superlu")
    res = pdlin.solve(prob, "direct", direct_backend=backend)
    assert res.info["direct_backend"] == backend
    assert np.abs(res.u - ref.u).max() / np.abs(ref.u).max() < 1e-10
    # refactorization of a nonsymmetric matrix of the same pattern (Newton tangents)
    sysm = pdlin.constrained_system(prob)
    A, b = sysm.eliminate(sysm.assemble())
    s = DirectSolver(A, symmetric=False, backend=backend)
    x1 = s.solve(b)
    s.refactor(2.0 * A)
    np.testing.assert_allclose(s.solve(b), 0.5 * x1, rtol=1e-9, atol=1e-12 * np.abs(x1).max())


def test_cholmod_refuses_nonsymmetric() -> None:
    A = sp.csr_array(np.array([[4.0, 1.0], [0.0, 3.0]]))
    with pytest.raises(InputError, match="cholmod.*symmetric"):
        DirectSolver(A, symmetric=False, backend="cholmod")


def test_auto_choice_is_reported(monkeypatch: pytest.MonkeyPatch) -> None:
    prob = _problem("lps", 2)
    res = pdlin.solve(prob, "direct")
    # small K (< AUTO_MIN unknowns): SuperLU
    assert res.info["direct_backend"] == "superlu"
    assert res.summary()["direct_backend"] == "superlu"
    # from AUTO_MIN on: the first installed of CHOLMOD, PARDISO, MUMPS for symmetric K
    # (on one thread; on several PARDISO comes first, test_auto_chain_order)
    monkeypatch.setattr(direct_mod, "AUTO_MIN", 10)
    monkeypatch.setattr(direct_mod, "get_num_threads", lambda: 1)
    res = pdlin.solve(prob, "direct")
    expected = next((b for b in ("cholmod", "pardiso", "mumps") if AVAILABLE[b]), "superlu")
    assert res.info["direct_backend"] == expected
    assert res.summary()["direct_backend"] == expected


def test_auto_chain_order(monkeypatch: pytest.MonkeyPatch) -> None:
    every = {"superlu": True, "cholmod": True, "pardiso": True, "mumps": True}
    monkeypatch.setattr(direct_mod, "available_direct_backends", lambda: dict(every))
    big = direct_mod.AUTO_MIN
    monkeypatch.setattr(direct_mod, "get_num_threads", lambda: 1)
    assert direct_mod._auto_chain(True, big) == ["cholmod", "pardiso", "mumps", "superlu"]
    monkeypatch.setattr(direct_mod, "get_num_threads", lambda: 2)
    assert direct_mod._auto_chain(True, big) == ["pardiso", "cholmod", "mumps", "superlu"]
    assert direct_mod._auto_chain(False, big) == ["pardiso", "mumps", "superlu"]
    assert direct_mod._auto_chain(False, 10) == ["superlu"]
    assert direct_mod._auto_chain(True, big - 1) == ["superlu"]


def test_auto_chain_prefers_cholmod_in_3d(monkeypatch: pytest.MonkeyPatch) -> None:
    # issue 33: on several threads CHOLMOD leads for 3D (3 x 3 blocks) symmetric K,
    # PARDISO for 2D or unknown dimension; nonsymmetric K never gets CHOLMOD
    every = {"superlu": True, "cholmod": True, "pardiso": True, "mumps": True}
    monkeypatch.setattr(direct_mod, "available_direct_backends", lambda: dict(every))
    monkeypatch.setattr(direct_mod, "get_num_threads", lambda: 2)
    big = direct_mod.AUTO_MIN
    assert direct_mod.auto_chain(True, big, 3) == ["cholmod", "pardiso", "mumps", "superlu"]
    assert direct_mod.auto_chain(True, big, 2) == ["pardiso", "cholmod", "mumps", "superlu"]
    assert direct_mod.auto_chain(True, big, None) == ["pardiso", "cholmod", "mumps", "superlu"]
    assert direct_mod.auto_chain(False, big, 3) == ["pardiso", "mumps", "superlu"]
    assert direct_mod.auto_chain(True, big - 1, 3) == ["superlu"]
    monkeypatch.setattr(direct_mod, "get_num_threads", lambda: 1)
    assert direct_mod.auto_chain(True, big, 2) == ["cholmod", "pardiso", "mumps", "superlu"]
    # without CHOLMOD installed the 3D order keeps the rest
    monkeypatch.setattr(direct_mod, "get_num_threads", lambda: 2)
    monkeypatch.setattr(
        direct_mod, "available_direct_backends", lambda: {**every, "cholmod": False}
    )
    assert direct_mod.auto_chain(True, big, 3) == ["pardiso", "mumps", "superlu"]


def test_direct_solver_passes_the_block_size_as_dimension(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    seen: list[int | None] = []

    def chain(symmetric: bool, n: int, dim: int | None = None) -> list[str]:
        seen.append(dim)
        return ["superlu"]

    monkeypatch.setattr(direct_mod, "auto_chain", chain)
    A = sp.random(12, 12, density=0.3, random_state=0)
    A = (A @ A.T + 12 * sp.eye(12)).tocsr()
    for blocks in (3, 2):
        DirectSolver(sp.bsr_array(A, blocksize=(blocks, blocks)), symmetric=True)
    DirectSolver(A, symmetric=True)
    assert seen == [3, 2, None]


def test_cholmod_blas_threads_follow_pdlin(monkeypatch: pytest.MonkeyPatch) -> None:
    # issue 33: CHOLMOD's OpenBLAS is capped at pdlin's thread count during the
    # factorization (never raised) and restored after it
    _need("cholmod")
    libs = direct_mod._openblas_libs()
    if not libs:
        pytest.skip("CHOLMOD's BLAS here is not a plain OpenBLAS")
    before = [lib.openblas_get_num_threads() for lib in libs]
    seen: list[list[int]] = []
    with direct_mod._openblas_threads(1):
        seen.append([lib.openblas_get_num_threads() for lib in libs])
    assert seen == [[1] * len(libs)]
    assert [lib.openblas_get_num_threads() for lib in libs] == before
    with direct_mod._openblas_threads(10_000):  # never raised above the current count
        assert [lib.openblas_get_num_threads() for lib in libs] == before
    monkeypatch.setattr(direct_mod, "get_num_threads", lambda: 1)
    A = sp.random(60, 60, density=0.1, random_state=1)
    A = (A @ A.T + 60 * sp.eye(60)).tocsc()
    s = DirectSolver(A, symmetric=True, backend="cholmod")
    assert np.allclose(A @ s.solve(np.ones(60)), 1.0)
    assert [lib.openblas_get_num_threads() for lib in libs] == before


def test_auto_falls_back_on_indefinite_matrix() -> None:
    """A symmetric indefinite matrix: CHOLMOD fails, auto goes on and says why."""
    _need("cholmod")
    A = sp.csc_matrix(np.array([[1.0, 2.0], [2.0, 1.0]]))  # eigenvalues 3 and -1
    mp = pytest.MonkeyPatch()
    mp.setattr(direct_mod, "AUTO_MIN", 1)
    try:
        s = DirectSolver(A)
    finally:
        mp.undo()
    # the next of the chain (PARDISO's SPD mode fails too; MUMPS' LDLᵀ or SuperLU succeed)
    assert s.backend in ("mumps", "superlu")
    assert "cholmod: not positive definite" in s.info["fallback"]
    # x = A⁻¹ (3, 3) = (1, 1) by hand
    np.testing.assert_allclose(s.solve(np.array([3.0, 3.0])), [1.0, 1.0], rtol=1e-14)
    with pytest.raises(ConvergenceError, match="not positive definite"):
        DirectSolver(A, backend="cholmod")


def test_missing_backend_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(name: str) -> None:
        raise ModuleNotFoundError(f"No module named {direct_mod._MODULES[name]!r}")

    monkeypatch.setattr(direct_mod.importlib, "import_module", broken)
    A = sp.csr_array(np.eye(3))
    for name in OPTIONAL:
        with pytest.raises(MissingDependencyError, match=rf"direct_backend='{name}'.*install"):
            DirectSolver(A, symmetric=True, backend=name)
    with pytest.raises(MissingDependencyError, match=r"pdlin\[direct\]"):
        DirectSolver(A, symmetric=True, backend="pardiso")
    # auto never needs an optional backend
    assert DirectSolver(A, symmetric=True).backend == "superlu"
    assert isinstance(MissingDependencyError("x"), ImportError)


def test_unknown_backend_rejected() -> None:
    with pytest.raises(InputError, match="direct_backend must be one of"):
        DirectSolver(sp.csr_array(np.eye(2)), backend="umfpack")
    prob = _problem("bb", 2)
    with pytest.raises(InputError, match="direct_backend"):
        pdlin.solve(prob, "direct", direct_backend="spooles")


@pytest.mark.parametrize("backend", ("superlu", *OPTIONAL))
def test_refactor_reuses_and_solves(backend: str) -> None:
    if backend != "superlu":
        _need(backend)
    prob = _problem("lps", 2)
    sysm = pdlin.constrained_system(prob)
    A, b = sysm.eliminate(sysm.assemble())
    s = DirectSolver(A, symmetric=True, backend=backend)
    x1 = s.solve(b)
    # same pattern, values scaled by 2: the solution halves
    s.refactor(2.0 * A)
    x2 = s.solve(b)
    np.testing.assert_allclose(x2, 0.5 * x1, rtol=1e-10, atol=1e-12 * np.abs(x1).max())
    # several right-hand sides at once
    X = s.solve(np.column_stack([b, 3.0 * b]))
    np.testing.assert_allclose(X[:, 1], 3.0 * X[:, 0], rtol=1e-12, atol=1e-12 * np.abs(X).max())
    with pytest.raises(InputError, match="shape"):
        s.refactor(sp.eye(3, format="csr"))


def test_solve_linear_cache_refactors() -> None:
    prob = _problem("corr", 2)
    sysm = pdlin.constrained_system(prob)
    A, b = sysm.eliminate(sysm.assemble())
    cache: dict = {}
    a = solve_linear(A, b, "direct", direct_cache=cache)
    assert a.info["direct_reused"] is False and isinstance(cache["solver"], DirectSolver)
    first = cache["solver"]
    c = solve_linear(4.0 * A, b, "direct", direct_cache=cache)
    assert c.info["direct_reused"] is True and cache["solver"] is first
    np.testing.assert_allclose(c.x, 0.25 * a.x, rtol=1e-10, atol=1e-12 * np.abs(a.x).max())


def test_newton_reuses_the_factorization() -> None:
    """solve_nonlinear keeps one factorization object across its Newton iterations."""
    cloud = pdlin.grid((8, 6), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.0)
    model = pdlin.BondBased(E=1.0, nu=0.25, plane="strain", kinematics="finite")
    bc = [pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 0.02, components="x")]
    prob = pdlin.StaticProblem(model, cloud, bonds=bonds, dirichlet=bc)
    made: list[int] = []
    real = direct_mod.DirectSolver.__init__

    def counting(self: DirectSolver, *args: object, **kwargs: object) -> None:
        made.append(1)
        real(self, *args, **kwargs)  # type: ignore[arg-type]

    mp = pytest.MonkeyPatch()
    mp.setattr(direct_mod.DirectSolver, "__init__", counting)
    try:
        res = pdlin.solve_nonlinear(prob, steps=3, method="newton")
    finally:
        mp.undo()
    lin = pdlin.solve(
        pdlin.StaticProblem(
            pdlin.BondBased(E=1.0, nu=0.25, plane="strain"), cloud, bonds=bonds, dirichlet=bc
        ),
        "direct",
    )
    assert res.iterations.sum() >= 3  # at least one Newton solve per step
    # one factorization object made for the whole run (plus the tangent predictor's own
    # solves, which do not share the cache): fewer objects than Newton solves
    assert len(made) < int(res.iterations.sum()) + 3
    # small stretch (2 %): the finite-strain answer is close to the linear one
    assert np.abs(res.u[-1] - lin.u).max() < 0.05 * np.abs(lin.u).max()


def test_cli_reports_backend(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = tmp_path / "s.toml"
    scene.write_text(
        'name = "p"\n[geometry]\ntype = "grid"\nshape = [12, 6]\nspacing = 0.1\n'
        '[material]\nE = 1.0\nnu = 0.25\nplane = "strain"\n[horizon]\nratio = 2.0\n'
        '[[dirichlet]]\nset = "x-"\nvalue = 0.0\n[[dirichlet]]\nset = "x+"\nvalue = 1e-3\n'
        'components = "x"\n[solver]\nname = "direct"\ndirect_backend = "superlu"\n'
    )
    assert main(["run", str(scene), "-q", "--output", str(tmp_path / "o.vtu")]) == 0
    assert "solver       direct (superlu)" in capsys.readouterr().out
    assert main(["run", str(scene), "--json", "-q", "--output", str(tmp_path / "o.vtu")]) == 0
    assert json.loads(capsys.readouterr().out)["direct_backend"] == "superlu"
    bad = scene.read_text().replace('"superlu"', '"umfpack"')
    scene.write_text(bad)
    from pdlin.errors import SceneError
    from pdlin.scene.scene import load_scene

    with pytest.raises(SceneError, match="solver.direct_backend"):
        load_scene(scene)


@pytest.mark.parametrize("fmt", ("bsr", "csr", "csc", "coo"))
def test_conversions_keep_the_matrix(fmt: str) -> None:
    # the cheap CSR-as-CSC reading of a symmetric matrix and the vectorized upper
    # triangle must equal scipy's own conversions exactly (empty rows included)
    rng = np.random.default_rng(3)
    B = sp.random(40, 40, density=0.1, random_state=rng, format="csr")
    A = B + B.T + sp.diags(np.arange(40.0) % 3)  # symmetric, rows 0, 3, ... may be empty
    A = sp.csr_array(A)
    A = A.tobsr(blocksize=(2, 2)) if fmt == "bsr" else A.asformat(fmt)
    csc = direct_mod._as_csc(A, symmetric=True)
    assert csc.format == "csc"
    assert (csc != sp.csc_matrix(A)).nnz == 0
    U = direct_mod._triu(csc)
    ref = sp.triu(sp.csc_matrix(A), format="csr")
    ref.sort_indices()
    assert U.has_sorted_indices
    assert np.array_equal(U.indptr, ref.indptr) and np.array_equal(U.indices, ref.indices)
    assert np.array_equal(U.data, ref.data)
    # a nonsymmetric matrix is converted, not reinterpreted
    N = sp.csr_array(sp.random(30, 30, density=0.2, random_state=rng))
    assert (direct_mod._as_csc(N, symmetric=False) != sp.csc_matrix(N)).nnz == 0


def test_pardiso_solvers_skip_pypardisos_library_search(monkeypatch: pytest.MonkeyPatch) -> None:
    # pypardiso searches the environment for libmkl_rt (a recursive glob, 0.35-0.7 s) on
    # every solver unless PYPARDISO_MKL_RT names it; pdlin sets it once from the wheel's
    # lib folder, so a new PARDISO factorization must not search again
    _need("pardiso")
    direct_mod._import("pardiso")
    import pypardiso.pardiso_wrapper as pw

    def no_search(*args: object, **kwargs: object) -> list[str]:
        raise AssertionError("pypardiso searched for libmkl_rt again")

    monkeypatch.setattr(pw.glob, "glob", no_search)
    monkeypatch.setattr(pw, "find_library", no_search)
    A = sp.csr_array(sp.diags([4.0] * 30) + sp.diags([1.0] * 29, 1) + sp.diags([1.0] * 29, -1))
    s = DirectSolver(A, symmetric=True, backend="pardiso")
    np.testing.assert_allclose(A @ s.solve(np.ones(30)), np.ones(30), rtol=1e-12)
