"""Print the material-point tables of the planar crystal (pure shear and Y-compression).

Run ``python examples/crystal_plasticity_tables.py``.  Each table is one batched
``pdlin.constitutive.material_point`` run over the 12 orientations θ_k = −90° + 15° k, 30 steps of
η = 0.002, with the default planar-2 material of Luo, Ramazani & Sundararaghavan (2017),
Sec. 3 (conventions: docs/theory/conventions.md).  The paper prints no such tables; these
are pdlin's reference values for its material and loading.
"""

from __future__ import annotations

import numpy as np

import pdlin
from pdlin.constitutive import ORIENTATIONS_2D, material_point


def table(loading: str) -> list[tuple[float, ...]]:
    """Rows (θ°, yield step, σ_xx, σ_yy, σ_xy, γ¹, γ², Δθ°) at t = 30."""
    r = material_point(pdlin.CrystalPlasticity(), loading, orientation=ORIENTATIONS_2D)
    s = r.stress[-1]
    return [
        (
            float(np.degrees(th)),
            int(r.yield_step[i]),
            float(s[i, 0, 0]),
            float(s[i, 1, 1]),
            float(s[i, 0, 1]),
            float(r.gamma[-1, i, 0]),
            float(r.gamma[-1, i, 1]),
            float(r.rotation[-1, i]),
        )
        for i, th in enumerate(ORIENTATIONS_2D)
    ]


def main() -> dict[str, list[tuple[float, ...]]]:
    out = {}
    for loading in ("shear", "compression"):
        rows = table(loading)
        out[loading] = rows
        print(f"\n{loading}\n")
        print("| θ° | yield | σ_xx | σ_yy | σ_xy | γ¹ | γ² | Δθ° |")
        print("|---|---|---|---|---|---|---|---|")
        for th, y, sxx, syy, sxy, g1, g2, dth in rows:
            print(
                f"| {th:.0f} | {y} | {sxx:.3f} | {syy:.3f} | {sxy:.3f} | {g1:.4f} | {g2:.4f} "
                f"| {dth:.2f} |"
            )
    return out


if __name__ == "__main__":
    main()
