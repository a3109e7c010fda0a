"""Error versus surface correction: tension bar, plate in tension, shear block (δ = 3.015 h).

Prints one Markdown table of signed relative errors (positive: too soft) of

* the elongation of a 20 x 4 x 4 bar in tension (3D, ``F L / (E A)``),
* the axial and lateral strains of a 40 x 20 plate in uniaxial tension (2D plane stress,
  ``σ/E`` and ``-ν σ/E``),
* the shear strain of a 30 x 30 block in pure shear (2D plane stress, ``τ/G``),

for ``pdlin.BondBased`` (ν = 1/4 in 3D, 1/3 in plane stress) and ``pdlin.LPS`` (ν = 0.3,
analytic and discrete weighted volume) with each ``surface_correction``.  The problems are
:mod:`pdlin.verification.surface`.  Run ``python benchmarks/surface_correction.py`` (about
ten seconds).  The errors do not depend on the machine; the context header and the last
line (wall and CPU seconds of the whole table) say how long it took where.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import pdlin
from pdlin.verification.surface import (
    plate_tension_errors,
    shear_block_error,
    tension_bar_error,
)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, timed  # noqa: E402

CORRECTIONS = (None, "volume", "energy", "force-normalization")

MODELS: dict[str, Callable[[Any], Any]] = {
    "BB": lambda sc: pdlin.BondBased(E=1.0, surface_correction=sc),
    "LPS": lambda sc: pdlin.LPS(E=1.0, nu=0.3, surface_correction=sc),
    "LPS discrete m": lambda sc: pdlin.LPS(
        E=1.0, nu=0.3, weighted_volume="discrete", surface_correction=sc
    ),
}


def main() -> None:
    header()
    with timed() as total:
        table()
    print(f"\n{total}")


def table() -> None:
    print("| model | surface_correction | bar elongation | plate ε_xx | plate ε_yy | shear γ |")
    print("|---|---|---|---|---|---|")
    for name, make in MODELS.items():
        for sc in CORRECTIONS:
            bar = tension_bar_error(make(sc))
            exx, eyy = plate_tension_errors(make(sc))
            gam = shear_block_error(make(sc))
            cells = " | ".join(f"{100 * v:+.1f} %" for v in (bar, exx, eyy, gam))
            print(f"| {name} | {sc or 'None'} | {cells} |")


if __name__ == "__main__":
    main()
