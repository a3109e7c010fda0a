"""Documentation stays in step with the code."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _gen_api():
    spec = importlib.util.spec_from_file_location("gen_api", DOCS / "gen_api.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_api_reference_lists_every_public_name():
    gen = _gen_api()
    text = (DOCS / "api.md").read_text()
    missing = []
    for modname in gen.MODULES:
        mod = importlib.import_module(modname)
        section = f"## `{modname}`"
        for name in getattr(mod, "__all__", []):
            if inspect.ismodule(getattr(mod, name)):
                continue  # a subpackage, documented in its own section
            if f"`{name}" not in text:
                missing.append(f"{modname}.{name}")
        assert section in text or not getattr(mod, "__all__", [])
    assert not missing, f"regenerate docs/api.md (python docs/gen_api.py): {missing}"


def test_index_links_exist():
    text = (DOCS / "index.md").read_text()
    for link in re.findall(r"\]\(([^)]+\.md)\)", text):
        assert (DOCS / link).exists(), link


def test_reference_pages_document_every_public_name():
    gen = _gen_api()
    pages = gen.reference_pages()
    text = "\n".join(pages.values())
    documented = set(re.findall(r"^\.\. (?:auto\w+|py:data):: (\w+)$", text, flags=re.M))
    import pdlin

    top_ids = {id(getattr(pdlin, n)) for n in pdlin.__all__}
    missing = []
    for modname in gen.TITLES:
        mod = importlib.import_module(modname)
        for name in getattr(mod, "__all__", []):
            obj = getattr(mod, name)
            if inspect.ismodule(obj):
                continue
            # a re-export of a top-level name is documented once, as pdlin.NAME
            if name not in documented and not (modname != "pdlin" and id(obj) in top_ids):
                missing.append(f"{modname}.{name}")
        assert f"{modname}.rst" in pages
    assert not missing, missing
    # the index page links every subpackage page
    for modname in gen.TITLES:
        assert f"   {modname}\n" in pages["index.rst"]


def test_constant_doc_reads_the_doc_comment(tmp_path, monkeypatch):
    gen = _gen_api()
    (tmp_path / "docmod_tmp.py").write_text(
        "#: Names of things.\n#: * ``a``: first\n#:   continued\nTHINGS = ('a',)\n\nBARE = 1\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    # the bullet's continuation keeps its indentation (reST needs it)
    assert gen._constant_doc("docmod_tmp", "THINGS") == [
        "Names of things.",
        "* ``a``: first",
        "  continued",
    ]
    with pytest.raises(ValueError, match="docmod_tmp.BARE: add a '#: description'"):
        gen._constant_doc("docmod_tmp", "BARE")


def test_index_toctree_lists_existing_pages():
    text = (DOCS / "index.md").read_text()
    block = re.search(r"```\{toctree\}\n(.*?)```", text, flags=re.S)
    assert block is not None
    entries = [
        line.strip()
        for line in block.group(1).splitlines()
        if line.strip() and not line.startswith(":")
    ]
    assert "*" in entries  # new docs/*.md pages join the site without editing the list
    generated = {"examples/index", "reference/index"}  # written at build time
    for entry in entries:
        if entry != "*" and entry not in generated:
            assert (DOCS / f"{entry}.md").exists(), entry


def test_example_runner_saves_unsaved_figures(tmp_path):
    pytest.importorskip("matplotlib")
    script = tmp_path / "demo.py"
    script.write_text(
        "import sys\n"
        "import matplotlib.pyplot as plt\n"
        "print('args', sys.argv[1:])\n"
        "fig, ax = plt.subplots(); ax.plot([0, 1]); fig.savefig('own.png')\n"
        "plt.figure(); plt.plot([1, 0]); plt.show()\n"
    )
    out = subprocess.run(
        [sys.executable, str(DOCS / "_ext" / "run_example.py"), str(script), str(tmp_path), "-x"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == "args ['-x']"
    # the script's own figure is not saved twice; the shown one is saved once
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["demo_fig1.png", "own.png"]


def _python_block_after(text: str, heading: str) -> str:
    """The first ```python block under ``heading``."""
    start = text.index(heading)
    m = re.search(r"```python\n(.*?)```", text[start:], flags=re.S)
    assert m is not None, heading
    return m.group(1)


def test_front_page_has_the_readme_ten_line_example_and_it_runs():
    import contextlib
    import io

    readme = (DOCS.parent / "README.md").read_text(encoding="utf-8")
    front = (DOCS / "index.md").read_text(encoding="utf-8")
    code = _python_block_after(front, "## Python in ten lines")
    assert code == _python_block_after(readme, "## Python in ten lines")
    namespace: dict = {}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "docs/index.md", "exec"), namespace)  # noqa: S102
    assert out.getvalue().strip()
    result = namespace["result"]
    assert result.converged and result.relative_residual < 1e-8  # solve's default rtol
    # uniaxial tension: eps_xx = sigma / E = (F / (height * thickness)) / E, height 20 * 0.01
    # and thickness 1 (the example's own numbers); PD with surface effects within 5 %
    closed = 1e4 / (20 * 0.01 * 1.0) / 70e9
    assert abs(result.strain()[500][0, 0] / closed - 1) < 0.05


def _install_page() -> str:
    return (DOCS / "install.md").read_text(encoding="utf-8")


def test_install_page_lists_every_extra_with_its_requirements():
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    from packaging.requirements import Requirement

    extras = tomllib.loads((DOCS.parent / "pyproject.toml").read_text(encoding="utf-8"))["project"][
        "optional-dependencies"
    ]
    rows = dict(re.findall(r"^\| `([\w-]+)` \| ([^|]+) \|", _install_page(), flags=re.M))
    assert set(rows) == set(extras)
    test_names = {Requirement(r).name for r in extras["test"]}
    for extra, reqs in extras.items():
        for req in map(Requirement, reqs):
            if extra == "dev" and req.name in test_names:
                continue  # the dev row says "the test packages and ..."
            floor = next(s.version for s in req.specifier if s.operator == ">=")
            assert f"{req.name} ≥ {floor}" in rows[extra], (extra, req.name, rows[extra])


def test_install_page_floors_are_the_ci_floors():
    floors = dict(
        line.split("==")
        for line in (DOCS.parent / ".ci" / "floors.txt").read_text().splitlines()
        if line and not line.startswith("#")
    )
    table = _install_page().split("## Dependency floors")[1].split("\n## ")[0]
    rows = dict(re.findall(r"^\| ([\w-]+) \| ([\w.]+) \|", table, flags=re.M))
    rows.pop("package", None)
    assert rows == floors


def _heading_anchors(text: str) -> set[str]:
    """GitHub / MyST anchors of the ``#``, ``##`` and ``###`` headings of a markdown page."""
    titles = re.findall(r"^#{1,3} (.+)$", text, flags=re.M)
    return {re.sub(r"[^\w\- ]", "", t.strip().lower()).replace(" ", "-") for t in titles}


def test_links_to_the_theory_pages_name_existing_sections():
    root = DOCS.parent
    anchors = {
        name: _heading_anchors((DOCS / "theory" / name).read_text(encoding="utf-8"))
        for name in ("conventions.md", "references.md")
    }
    files = [root / "README.md", *DOCS.rglob("*.md"), *(root / "pdlin").rglob("*.py")]
    files += sorted((root / "examples").glob("*.py"))
    broken = []
    for path in files:
        text = path.read_text(encoding="utf-8")
        for page, anchor in re.findall(r"theory/(conventions|references)\.md#([\w-]+)", text):
            if anchor not in anchors[f"{page}.md"]:
                broken.append(f"{path.relative_to(root)}: {page}.md#{anchor}")
        if path.parent == DOCS / "theory":  # links within the theory pages
            for anchor in re.findall(r"\]\(#([\w-]+)\)", text):
                if anchor not in anchors.get(path.name, set()):
                    broken.append(f"{path.relative_to(root)}: #{anchor}")
    assert not broken, broken


def test_readme_is_for_users():
    readme = (DOCS.parent / "README.md").read_text(encoding="utf-8")
    assert "spec 00" not in readme.lower()
    assert "Coming next" not in readme
    # no diary: dated entries belong in benchmarks/README.md or CHANGELOG.md
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b", readme)
    headings = ("## Quick start", "## Python in ten lines", "## Command line", "## Documentation")
    for heading in headings:
        assert heading in readme, heading
