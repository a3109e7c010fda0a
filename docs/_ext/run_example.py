"""Run one example script headless and save the matplotlib figures it left unsaved.

Used by the docs build (``docs/_ext/pdlin_examples.py``)::

    python docs/_ext/run_example.py SCRIPT OUTDIR [ARGS...]

The script runs as ``__main__`` with ``sys.argv = [SCRIPT, *ARGS]`` under the Agg
backend; ``plt.show()`` is a no-op, and every figure still open at the end that the
script did not save itself is saved as ``OUTDIR/<stem>_fig<k>.png``.  Its stdout and
stderr pass through.
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path


def main(argv: list[str]) -> None:
    script, outdir, *args = argv
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    plt.show = lambda *a, **k: None  # figures stay open; saved below
    saved: set[int] = set()  # figures the script saved itself are not saved twice
    savefig = Figure.savefig

    def _savefig(self: Figure, *a: object, **k: object) -> None:
        saved.add(id(self))
        savefig(self, *a, **k)

    Figure.savefig = _savefig  # type: ignore[method-assign]
    sys.argv = [script, *args]
    sys.path.insert(0, str(Path(script).resolve().parent))
    runpy.run_path(script, run_name="__main__")
    stem = Path(script).stem
    figures = [plt.figure(num) for num in plt.get_fignums()]
    for k, fig in enumerate([f for f in figures if id(f) not in saved], start=1):
        savefig(fig, Path(outdir) / f"{stem}_fig{k}.png", dpi=90)
    plt.close("all")


if __name__ == "__main__":
    main(sys.argv[1:])
