"""The package metadata: a LICENSE matching pyproject's license, authors and classifiers."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from packaging.specifiers import SpecifierSet

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
#: the copyright holder the docs site names (docs/conf.py ``copyright``)
HOLDER = re.search(
    r'^copyright = "([^"]+)"', (ROOT / "docs" / "conf.py").read_text(encoding="utf-8"), re.M
)


def test_license_file_is_the_declared_bsd_3_clause() -> None:
    assert PROJECT["license"] == {"text": "BSD-3-Clause"}
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("BSD 3-Clause License")
    # the three conditions of the BSD-3-Clause text (https://spdx.org/licenses/BSD-3-Clause)
    for clause in (
        "1. Redistributions of source code must retain the above copyright notice",
        "2. Redistributions in binary form must reproduce the above copyright notice",
        "3. Neither the name of the copyright holder nor the names of its",
    ):
        assert clause in text, clause
    assert HOLDER is not None
    assert re.search(rf"^Copyright \(c\) \d{{4}}, {re.escape(HOLDER.group(1))}$", text, re.M)


def test_authors_are_the_copyright_holder() -> None:
    assert HOLDER is not None
    assert [a["name"] for a in PROJECT["authors"]] == [HOLDER.group(1)]


def test_classifiers_match_license_and_supported_pythons() -> None:
    classifiers = PROJECT["classifiers"]
    assert len(set(classifiers)) == len(classifiers)
    for needed in (
        "License :: OSI Approved :: BSD License",
        "Intended Audience :: Science/Research",
        "Topic :: Scientific/Engineering :: Physics",
        "Programming Language :: Python :: 3 :: Only",
    ):
        assert needed in classifiers, needed
    assert any(c.startswith("Operating System ::") for c in classifiers)
    versions = [
        m.group(1) for c in classifiers if (m := re.fullmatch(r".* :: Python :: (3\.\d+)", c))
    ]
    supported = SpecifierSet(PROJECT["requires-python"])
    assert versions and all(v in supported for v in versions), versions
    # every minor version from the floor of requires-python up to the newest listed
    lo, hi = (int(v.split(".")[1]) for v in (min(versions, key=_minor), max(versions, key=_minor)))
    assert f"3.{lo - 1}" not in supported
    assert sorted(versions, key=_minor) == [f"3.{k}" for k in range(lo, hi + 1)]


def _minor(version: str) -> int:
    return int(version.split(".")[1])


def test_project_urls_are_real_when_given() -> None:
    # no URL is invented: a listed one must be an absolute https address, no placeholder
    for name, url in PROJECT.get("urls", {}).items():
        assert re.fullmatch(r"https://[\w.-]+\.\w+(/\S*)?", url), (name, url)
        assert "example" not in url and "TODO" not in url, (name, url)
