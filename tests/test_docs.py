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
