"""The structure docs/architecture.md describes, checked on the source (fast, no solves).

Each test parses ``pdlin/`` with :mod:`ast` (or imports ``pdlin`` once) and fails with
the offending ``file:line`` of every violation:

* no module-level import cycle (imports under ``if TYPE_CHECKING:`` and inside functions
  do not count);
* no function longer than 150 lines, its docstring excluded (``LONG_FUNCTIONS`` lists the
  exceptions, each with its reason);
* a front door of at most 30 names, each resolving; every name that left it still
  resolves, with a DeprecationWarning naming its new home;
* ``import pdlin`` imports no sympy, matplotlib or numba;
* no citation of the project's private specs ("spec 00N") in pdlin/, docs/, README.md;
* numpydoc ``Parameters`` / ``Returns`` / ``Yields`` sections on every public function
  and method that takes arguments / returns a value / yields;
* no private name (``_name``) imported from another package.
"""

from __future__ import annotations

import ast
import importlib.util
import os
import subprocess
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path

import pytest

import pdlin

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "pdlin"
MAX_LINES = 150

#: functions allowed above MAX_LINES ("path relative to the repository::qualified name"),
#: each with its reason.  Only numba kernels (one compiled loop nest, which numba cannot
#: split without a call per point) and generated tables belong here.
LONG_FUNCTIONS: dict[str, str] = {}

#: the 72 names of ``pdlin.__all__`` before the front door was made small (issue 32); each
#: must keep resolving as ``pdlin.<name>`` for one release
OLD_FRONT_DOOR = (
    "set_num_threads get_num_threads errors constitutive ConvergenceError FloatingBodyError "
    "PointCloud Bonds grid from_image ghost_layer GhostLayer read_mesh read_deck "
    "plate_with_hole_mesh find_bonds BondBased LPS XOSB Correspondence shadow_problem Model "
    "assemble_stiffness rigid_body_modes Dirichlet TimePath BodyForce TotalForce shadow_layer "
    "SymmetryPlane sparsity_report SparsityReport plot_spy StaticProblem StaticResult solve "
    "solve_nonlinear subregion SubregionProblem NonlinearResult ConstrainedSystem "
    "constrained_system deformation_gradient shape_tensor small_strain calibrate_micromoduli "
    "CalibrationResult higher_order_weights weights_table HigherOrderWeights WeightStatus "
    "as_influence moment_weights gradient_symbol gradient_exactness_order critical_stretch "
    "bond_stretch break_bonds damage_index isolated_points drop_isolated solve_damage "
    "DamageResult CrystalPlasticity SaintVenantKirchhoff MaterialPointResult material_point "
    "voronoi_polycrystal sweeps tradeoff TradeoffCase TradeoffResult"
).split()


# -- the source tree -----------------------------------------------------------------------


def _modules() -> dict[str, Path]:
    """Dotted module name -> file, for every module of pdlin."""
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


MODULES = _modules()
TREES = {name: ast.parse(path.read_text(), str(path)) for name, path in MODULES.items()}


def _where(module: str, node: ast.AST) -> str:
    return f"{MODULES[module].relative_to(ROOT)}:{getattr(node, 'lineno', 0)}"


def _is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


def _target(module: str, node: ast.ImportFrom) -> str:
    """Absolute name of the module a ``from ... import`` reads from."""
    if not node.level:
        return node.module or ""
    base = module.split(".")
    if not _is_package(module):
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _module_level_imports(body: list[ast.stmt]) -> Iterator[ast.Import | ast.ImportFrom]:
    """Imports run when the module is imported (not under TYPE_CHECKING, not in functions)."""
    for node in body:
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
        elif isinstance(node, ast.If):
            if not _is_type_checking(node.test):
                yield from _module_level_imports(node.body)
            yield from _module_level_imports(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, *(h.body for h in node.handlers), node.orelse):
                yield from _module_level_imports(block)


def _import_graph() -> dict[str, dict[str, ast.AST]]:
    """Module -> {pdlin module it imports at module level: the import statement}."""
    graph: dict[str, dict[str, ast.AST]] = {}
    for module, tree in TREES.items():
        edges: dict[str, ast.AST] = {}
        for node in _module_level_imports(tree.body):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:  # ``from pkg import submodule`` needs pkg only as far as it is initialized
                base = _target(module, node)
                subs = [f"{base}.{a.name}" for a in node.names]
                names = subs if all(n in MODULES for n in subs) else [base, *subs]
            for name in names:
                if name in MODULES and name != module:
                    edges.setdefault(name, node)
        graph[module] = edges
    return graph


def _cycles(graph: dict[str, dict[str, ast.AST]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(graph[w])))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_no_module_level_import_cycle() -> None:
    graph = _import_graph()
    problems = []
    for comp in _cycles(graph):
        members = set(comp)
        edges = [
            f"  {_where(a, node)}: {a} imports {b}"
            for a in comp
            for b, node in sorted(graph[a].items())
            if b in members
        ]
        problems.append(f"cycle of {len(comp)} modules {comp}:\n" + "\n".join(edges))
    assert not problems, "module-level import cycles:\n" + "\n".join(problems)


#: the layers of docs/architecture.md, bottom (0) to top: a module imports at module level
#: only from its own layer or below.  Keys are module names or prefixes (the longest match
#: wins); a package's ``__init__`` re-exports its modules and sits with its highest one
LAYERS: dict[str, int] = {
    "pdlin.errors": 0,
    "pdlin.resources": 0,
    "pdlin._": 0,  # pdlin/_*.py: internal shared modules
    "pdlin.geometry": 1,
    "pdlin.constitutive": 1,
    "pdlin.io": 1,
    "pdlin.operators.assembly": 2,  # the BSR assembly the models build their K with
    "pdlin.operators.bc": 2,  # condition data
    "pdlin.operators.rigid": 2,
    "pdlin.fields": 2,
    "pdlin.models": 3,
    "pdlin.problem": 4,
    "pdlin.constraints": 4,
    "pdlin.operators.symmetry": 4,  # a discretization of the constrained system
    "pdlin.operators": 4,  # the package re-exports pdlin.constraints' functions
    "pdlin.system": 4,
    "pdlin.solvers": 5,
    "pdlin.backends": 5,
    "pdlin.dynamics": 5,  # explicit dynamics: beside the solvers, a driver of its own
    "pdlin.static": 6,
    "pdlin.nonlinear": 6,
    "pdlin.fracture": 6,
    "pdlin.submodeling": 6,
    "pdlin.analysis": 6,
    "pdlin.calibration": 6,
    "pdlin.verification": 6,
    "pdlin.sweeps": 7,
    "pdlin.scene": 8,
    "pdlin.cli": 9,
    "pdlin.plotting": 9,
    "pdlin.__main__": 9,
    "pdlin": 9,
}

#: deprecated modules left at old paths (they re-export from above for one release)
SHIMS = {
    "pdlin.operators.sparsity",
    "pdlin.calibration.plotting",
    "pdlin.io.scene",
    "pdlin.io.decks",
    "pdlin.io.checks",
    "pdlin.io.targets",
    "pdlin.sweeps.scene",
    "pdlin.solvers.nonlinear",
}


def _layer(module: str) -> int:
    keys = [
        k for k in LAYERS if module == k or module.startswith(k if k.endswith("_") else k + ".")
    ]
    if module.startswith("pdlin._") and module != "pdlin.__main__":
        keys.append("pdlin._")
    return LAYERS[max(keys, key=len)]


def test_modules_import_only_from_their_layer_or_below() -> None:
    graph = _import_graph()
    problems = [
        f"  {_where(a, node)}: {a} (layer {_layer(a)}) imports {b} (layer {_layer(b)})"
        for a, edges in sorted(graph.items())
        if a not in SHIMS
        for b, node in sorted(edges.items())
        if _layer(b) > _layer(a)
    ]
    assert not problems, (
        "upward imports (docs/architecture.md, 'Layers'); move the code or import inside the "
        "function that needs it:\n" + "\n".join(problems)
    )


def test_every_module_has_a_layer_and_shims_exist() -> None:
    assert SHIMS <= set(MODULES)
    assert _layer("pdlin._arrays") == 0 and _layer("pdlin.operators.assembly") == 2
    assert _layer("pdlin.models.correspondence.model") == 3 and _layer("pdlin.__main__") == 9
    for module in MODULES:
        _layer(module)  # raises on a module of no layer


def test_cycle_finder_finds_a_cycle() -> None:
    graph: dict[str, dict[str, ast.AST]] = {"a": {"b": ast.Pass()}, "b": {"a": ast.Pass()}}
    graph["c"] = {"a": ast.Pass()}
    assert _cycles(graph) == [["a", "b"]]


# -- function length -----------------------------------------------------------------------


def _functions(tree: ast.AST) -> Iterator[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]]:
    """(qualified name, node) of every function and method, nested ones included."""

    def walk(node: ast.AST, prefix: str) -> Iterator[tuple[str, ast.AST]]:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    yield name, child
                yield from walk(child, name + ".")
            else:
                yield from walk(child, prefix)

    for name, node in walk(tree, ""):
        assert isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        yield name, node


def _length(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines of a function from ``def`` to its end, its docstring excluded."""
    n = (node.end_lineno or node.lineno) - node.lineno + 1
    first = node.body[0]
    if (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    ):
        n -= (first.end_lineno or first.lineno) - first.lineno + 1
    return n


def test_no_function_longer_than_150_lines() -> None:
    long = {}
    for module, tree in TREES.items():
        for name, node in _functions(tree):
            n = _length(node)
            if n > MAX_LINES:
                long[f"{MODULES[module].relative_to(ROOT)}::{name}"] = (_where(module, node), n)
    stale = sorted(set(LONG_FUNCTIONS) - set(long))
    assert not stale, f"LONG_FUNCTIONS lists functions that are short now or gone: {stale}"
    over = [
        f"  {where}: {key.split('::')[1]} has {n} lines (docstring excluded)"
        for key, (where, n) in sorted(long.items())
        if key not in LONG_FUNCTIONS
    ]
    assert not over, f"functions longer than {MAX_LINES} lines:\n" + "\n".join(over)


# -- the front door ------------------------------------------------------------------------


def test_front_door_is_small_and_resolves() -> None:
    names = pdlin.__all__
    assert len(names) <= 30, f"pdlin.__all__ has {len(names)} names (at most 30): {names}"
    assert len(set(names)) == len(names), "pdlin.__all__ repeats a name"
    missing = [n for n in names if not hasattr(pdlin, n)]
    assert not missing, f"pdlin.__all__ names that do not resolve: {missing}"
    moved = pdlin._MOVED
    both = sorted(set(moved) & set(names))
    assert not both, f"names both in the front door and in pdlin._MOVED: {both}"


def test_names_that_left_the_front_door_still_resolve_with_a_warning() -> None:
    import importlib

    moved = pdlin._MOVED
    lost = [
        n
        for n in OLD_FRONT_DOOR
        if n not in pdlin.__all__ and n not in moved and not hasattr(pdlin, n)
    ]
    assert not lost, f"names of the old pdlin.__all__ that no longer resolve: {lost}"
    for name, home in moved.items():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            obj = getattr(pdlin, name)
        assert obj is getattr(importlib.import_module(home), name), (name, home)
        messages = [str(w.message) for w in caught if w.category is DeprecationWarning]
        assert len(messages) == 1 and f"from {home} import {name}" in messages[0], (
            name,
            messages,
        )
        assert f"{home}.{name}" in messages[0] and "pdlin/__init__" not in caught[0].filename
    with pytest.raises(AttributeError, match="no_such_name"):
        pdlin.no_such_name  # noqa: B018


@pytest.mark.parametrize(
    ("old", "name", "home"),
    [
        ("pdlin.operators", "sparsity_report", "pdlin.analysis"),
        ("pdlin.operators", "SparsityReport", "pdlin.analysis"),
        ("pdlin.operators", "coupling_pattern", "pdlin.analysis"),
        ("pdlin.operators", "plot_spy", "pdlin.plotting"),
        ("pdlin.calibration", "plot_micromoduli", "pdlin.plotting"),
        ("pdlin.io.output", "check_figure", "pdlin.plotting"),
    ],
)
def test_names_moved_out_of_subpackages_warn(old: str, name: str, home: str) -> None:
    import importlib

    with pytest.warns(DeprecationWarning, match=rf"from {home} import {name}"):
        obj = getattr(importlib.import_module(old), name)
    assert obj is getattr(importlib.import_module(home), name)


@pytest.mark.parametrize(
    ("shim", "names"),
    [
        (
            "pdlin.operators.sparsity",
            [
                "sparsity_report",
                "SparsityReport",
                "coupling_pattern",
                "rcm_permutation",
                "plot_spy",
            ],
        ),
        ("pdlin.calibration.plotting", ["plot_micromoduli"]),
        ("pdlin.io.scene", ["load_scene", "scene_from_dict", "builtin_scene"]),
        ("pdlin.io.decks", ["read_deck"]),
        ("pdlin.io.checks", ["evaluate_checks"]),
        ("pdlin.io.targets", ["load_calibration", "target_from_table"]),
        ("pdlin.sweeps.scene", ["select_scene"]),
        ("pdlin.solvers.nonlinear", ["adr_step", "adr_time_step", "newton_step", "StepOutcome"]),
    ],
)
def test_moved_modules_leave_a_warning_shim(shim: str, names: list[str]) -> None:
    """The shim warns on import (in a fresh interpreter) and re-exports the moved names."""
    code = (
        "import warnings\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        f"    import {shim} as m\n"
        "print(sum(x.category is DeprecationWarning for x in w))\n"
        f"print(all(hasattr(m, n) for n in {names!r}))\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *sys.path])}
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    assert run.stdout.split() == ["1", "True"], run.stdout + run.stderr


def test_import_pdlin_imports_no_sympy_matplotlib_numba() -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *sys.path])}
    run = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", "import pdlin"],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    imported = [line.rsplit("|", 1)[-1].strip() for line in run.stderr.splitlines()]
    heavy = [
        name
        for name in imported
        if name.split(".")[0] in ("sympy", "matplotlib", "numba", "mpl_toolkits")
    ]
    assert not heavy, "import pdlin imports heavy optional modules:\n" + "\n".join(heavy)


# -- citations -----------------------------------------------------------------------------


def _text_files() -> Iterator[Path]:
    yield ROOT / "README.md"
    for folder in (PKG, ROOT / "docs"):
        for path in sorted(folder.rglob("*")):
            if any(part in ("_build", "__pycache__") for part in path.parts):
                continue
            if path.is_file() and path.suffix in (".py", ".md", ".rst", ".toml", ".txt", ".yaml"):
                yield path


def test_no_private_spec_citations() -> None:
    needle = "spec 00"
    hits = [
        f"  {path.relative_to(ROOT)}:{k}: {line.strip()[:100]}"
        for path in _text_files()
        for k, line in enumerate(path.read_text(errors="replace").splitlines(), 1)
        if needle in line.lower()
    ]
    assert not hits, (
        f'{len(hits)} lines cite the private specs ("spec 00N"); cite the paper or a docs '
        "page instead:\n" + "\n".join(hits)
    )


# -- numpydoc ------------------------------------------------------------------------------


def _public_module(module: str) -> bool:
    return not any(part.startswith("_") for part in module.split("."))


def _decorators(node: ast.FunctionDef | ast.AsyncFunctionDef) -> set[str]:
    out = set()
    for d in node.decorator_list:
        if isinstance(d, ast.Call):
            d = d.func
        if isinstance(d, ast.Name):
            out.add(d.id)
        elif isinstance(d, ast.Attribute):
            out.add(d.attr)
    return out


def _own_nodes(node: ast.AST) -> Iterator[ast.AST]:
    """Nodes of a function's body, nested functions and classes excluded."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef | ast.Lambda):
            continue
        yield child
        yield from _own_nodes(child)


def _missing_sections(node: ast.FunctionDef | ast.AsyncFunctionDef, method: bool) -> list[str]:
    decorators = _decorators(node)
    if decorators & {"overload", "setter", "deleter"}:
        return []
    args = [a.arg for a in (*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs)]
    if method and args and args[0] in ("self", "cls") and "staticmethod" not in decorators:
        args = args[1:]
    if node.args.vararg:
        args.append(node.args.vararg.arg)
    if node.args.kwarg:
        args.append(node.args.kwarg.arg)
    body = list(_own_nodes(node))
    returns = any(
        isinstance(x, ast.Return)
        and x.value is not None
        and not (isinstance(x.value, ast.Constant) and x.value.value is None)
        for x in body
    )
    yields = any(isinstance(x, ast.Yield | ast.YieldFrom) for x in body)
    prop = bool(decorators & {"property", "cached_property"})
    doc = ast.get_docstring(node) or ""
    need = []
    if args and "Parameters\n---" not in doc:
        need.append("Parameters")
    if returns and not yields and not prop and "Returns\n---" not in doc:
        need.append("Returns")
    if yields and "Yields\n---" not in doc:
        need.append("Yields")
    return need


def test_public_functions_have_numpydoc_sections() -> None:
    problems = []
    for module, tree in TREES.items():
        if not _public_module(module):
            continue
        todo: list[tuple[ast.AST, str, bool]] = [(n, "", False) for n in tree.body]
        while todo:
            node, prefix, method = todo.pop()
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                todo.extend((n, f"{prefix}{node.name}.", True) for n in node.body)
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                if node.name.startswith("_"):
                    continue  # private, and dunders (documented on the class)
                need = _missing_sections(node, method)
                if need:
                    problems.append(
                        f"  {_where(module, node)}: {prefix}{node.name} lacks {', '.join(need)}"
                    )
    assert not problems, f"{len(problems)} public functions lack numpydoc sections:\n" + "\n".join(
        sorted(problems)
    )


def test_docstrings_follow_the_numpy_convention() -> None:
    """ruff's pydocstyle rules (numpy convention, pyproject.toml) on the library code."""
    if importlib.util.find_spec("ruff") is None:  # the dev extra and .ci/run install it
        pytest.skip("ruff is not installed (pip install ruff; .ci/run installs it)")
    run = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--select", "D", "--output-format", "concise"]
        + ["--no-cache", "pdlin"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert run.returncode == 0, "ruff pydocstyle (numpy convention):\n" + run.stdout[-20000:]


# -- private names across packages ---------------------------------------------------------


def _package(module: str) -> str:
    """The subpackage a module belongs to: ``pdlin.<first part>``, or ``pdlin`` for the
    modules directly in pdlin/."""
    parts = module.split(".")
    if len(parts) == 1 or (len(parts) == 2 and not _is_package(module)):
        return "pdlin"
    return ".".join(parts[:2])


def test_no_private_name_imported_across_packages() -> None:
    problems = []
    for module, tree in TREES.items():
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom):
                continue
            source = _target(module, node)
            if not source.startswith("pdlin"):
                continue
            for alias in node.names:
                name = alias.name
                if not name.startswith("_") or name.startswith("__"):
                    continue
                if f"{source}.{name}" in MODULES:
                    continue  # a private module (pdlin/_x.py): the internal shared modules
                if _package(source) != _package(module):
                    problems.append(
                        f"  {_where(module, node)}: {module} imports {name} from {source}"
                    )
    assert not problems, (
        "private names imported from another package (make them public in an internal "
        "module, e.g. pdlin/_arrays.py):\n" + "\n".join(problems)
    )
