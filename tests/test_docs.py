"""Documentation stays in step with the code."""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import re
from pathlib import Path

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
