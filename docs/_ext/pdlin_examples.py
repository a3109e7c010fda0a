"""Sphinx extension: one tutorial page per ``examples/*.py``, run at build time.

On ``builder-inited`` every script in ``examples/`` is run (through ``run_example.py``:
headless, figures saved) and ``docs/examples/<name>.md`` is written with the script's
docstring, the command, its printed output, its figures and its full source.  The
generated folder is not tracked by git.

``conf.py`` sets ``pdlin_examples`` to ``{name: options}``; every option is optional:

* ``args``: command-line arguments (``{out}`` is replaced by the figure folder);
* ``run``: ``False`` to skip running (a long script); then ``figures`` lists stored
  images (paths relative to ``docs/``) and ``why`` says why it is not run;
* ``timeout``: seconds (default 300).

A script missing from the dict is run without arguments.  A script that fails stops the
build.  Results are cached in ``docs/examples/`` by the hash of script and options, so a
rebuild only reruns changed scripts.
"""

from __future__ import annotations

import ast
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from sphinx.application import Sphinx
from sphinx.errors import ExtensionError
from sphinx.util import logging

logger = logging.getLogger(__name__)
HERE = Path(__file__).resolve().parent


def _docstring(path: Path) -> tuple[str, str]:
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or path.stem
    title, _, body = doc.partition("\n")
    return title.strip(), body.strip()


def _run(script: Path, outdir: Path, args: list[str], timeout: float, root: Path) -> str:
    env = dict(
        os.environ,
        MPLBACKEND="Agg",
        PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]).rstrip(
            os.pathsep
        ),
    )
    cmd = [sys.executable, str(HERE / "run_example.py"), str(script), str(outdir), *args]
    proc = subprocess.run(cmd, cwd=outdir, env=env, capture_output=True, text=True,
                          timeout=timeout)  # fmt: skip
    if proc.returncode != 0:
        raise ExtensionError(
            f"examples/{script.name} failed (exit {proc.returncode}):\n{proc.stderr[-3000:]}"
        )
    return proc.stdout


def _page(name: str, script: Path, opts: dict[str, Any], result: dict[str, Any]) -> str:
    title, body = _docstring(script)
    args = " ".join(a.replace("{out}", "OUT") for a in opts.get("args", []))
    cmd = f"python examples/{script.name}" + (f" {args}" if args else "")
    lines = [f"# `{script.name}`: {title}", ""]
    if body:
        lines += ["```{eval-rst}", body, "```", ""]
    if result.get("ran"):
        lines += [
            f"Run at docs build time as `{cmd}` ({result['seconds']:.1f} s on the build machine).",
            "",
        ]
        if result["stdout"].strip():
            lines += ["## Output", "", "```text", result["stdout"].rstrip(), "```", ""]
    else:
        lines += [f"Not run at docs build time: {opts.get('why', 'excluded in docs/conf.py')}.", ""]
    if result["figures"]:
        lines += ["## Figures", ""]
        for fig in result["figures"]:
            lines += [f"```{{image}} {fig}", f":alt: figure of examples/{script.name}", "```", ""]
    lines += [
        "## Source",
        "",
        f"```{{literalinclude}} ../../examples/{script.name}",
        ":language: python",
        "```",
        "",
    ]
    return "\n".join(lines)


def generate(app: Sphinx) -> None:
    srcdir = Path(app.srcdir)
    root = srcdir.parent
    outdir = srcdir / "examples"
    outdir.mkdir(exist_ok=True)
    config: dict[str, dict[str, Any]] = app.config.pdlin_examples
    scripts = sorted((root / "examples").glob("*.py"))
    unknown = set(config) - {s.stem for s in scripts}
    if unknown:
        raise ExtensionError(f"pdlin_examples names no script in examples/: {sorted(unknown)}")
    names = []
    for script in scripts:
        name = script.stem
        names.append(name)
        opts = config.get(name, {})
        key = hashlib.sha256(
            script.read_bytes() + json.dumps(opts, sort_keys=True).encode()
        ).hexdigest()
        cache = outdir / f".{name}.json"
        result = json.loads(cache.read_text()) if cache.exists() else {}
        if result.get("key") != key:
            if opts.get("run", True):
                figdir = outdir / f"{name}_files"  # the script's cwd and figure folder
                shutil.rmtree(figdir, ignore_errors=True)
                figdir.mkdir()
                args = [a.replace("{out}", str(figdir)) for a in opts.get("args", [])]
                logger.info(f"running examples/{script.name} {' '.join(args)}")
                t0 = time.perf_counter()
                stdout = _run(script, figdir, args, opts.get("timeout", 300), root)
                seconds = time.perf_counter() - t0
                figures = sorted(f"{figdir.name}/{p.name}" for p in figdir.rglob("*.png"))
                result = {"ran": True, "stdout": stdout, "seconds": seconds, "figures": figures}
            else:
                figs = [f"../{f}" for f in opts.get("figures", [])]
                missing = [f for f in opts.get("figures", []) if not (srcdir / f).exists()]
                if missing:
                    raise ExtensionError(
                        f"examples/{script.name}: stored figures missing: {missing}"
                    )
                result = {"ran": False, "stdout": "", "seconds": 0.0, "figures": figs}
            result["key"] = key
            cache.write_text(json.dumps(result))
        page = outdir / f"{name}.md"
        text = _page(name, script, opts, result)
        if not page.exists() or page.read_text() != text:
            page.write_text(text)
    for stale in outdir.glob("*.md"):  # pages, caches and figures of removed scripts
        if stale.stem not in names and stale.stem != "index":
            stale.unlink()
            (outdir / f".{stale.stem}.json").unlink(missing_ok=True)
            shutil.rmtree(outdir / f"{stale.stem}_files", ignore_errors=True)
    index = [
        "# Example scripts",
        "",
        "Each page is generated from a script in `examples/` when the docs are built: its",
        "docstring, the command, what it printed and the figures it drew (run at build time",
        "unless the page says otherwise), and the full source.",
        "",
        "```{toctree}",
        ":maxdepth: 1",
        "",
        *names,
        "```",
        "",
    ]
    text = "\n".join(index)
    if not (outdir / "index.md").exists() or (outdir / "index.md").read_text() != text:
        (outdir / "index.md").write_text(text)


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_config_value("pdlin_examples", {}, "env")
    app.connect("builder-inited", generate)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
