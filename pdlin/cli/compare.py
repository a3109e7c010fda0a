"""``pdlin run`` on a scene with ``[compare.cpfe]``: the CPFE comparator beside the CPPD run.

The scene's problem is solved a second time by ``crystal_plasticity_fem`` (Q4 / Hex8 F-bar
elements centred on the particles) on the same load steps; its series and homogenized CSV
are written like the scene's own (fields on the particles = element centres), and the gap
of the homogenized curves is printed per step (``pdlin.scene.compare``).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["cpfe_paths", "run_cpfe", "cpfe_summary", "print_cpfe"]


def cpfe_paths(scene: Any, series: Path) -> tuple[Path, Path]:
    """Return the CPFE series and CSV: ``[compare.cpfe]`` paths, else beside the scene's.

    Parameters
    ----------
    scene : Scene
        A scene with ``compare["cpfe"]``.
    series : Path
        The scene's own series (``-o`` or ``output.path``).

    Returns
    -------
    tuple of Path
        ``(series, csv)``: default ``<stem>_cpfe<suffix>`` and ``<its stem>_homogenized.csv``.
    """
    cfg = scene.compare["cpfe"]
    out = cfg["output"] or series.with_name(f"{series.stem}_cpfe{series.suffix}")
    csv_path = cfg["homogenized"] or out.with_name(f"{out.stem}_homogenized.csv")
    return Path(out), Path(csv_path)


def _element_fields(result: Any, n_gauss: int) -> list[dict[str, np.ndarray]]:
    """Per-step fields on the elements (= particles): centre displacement, stress, states."""
    from ..verification.cpfe import element_average

    mesh = result.system.disc.mesh
    ne, d = mesh.n_elements, mesh.dim
    steps = []
    for k in range(result.n_steps):
        u = np.asarray(result.u[k]).reshape(-1, d)
        f: dict[str, np.ndarray] = {
            # the bilinear / trilinear field at the element centre: the mean of its corners
            "displacement": u[mesh.conn].mean(axis=1),
            "stress": np.asarray(result.stress[k]).reshape(ne, -1),
        }
        state = result.state_at(k)
        for key, val in (state or {}).items():
            arr = np.asarray(val)
            if arr.shape[:1] == (ne * n_gauss,) and arr.ndim <= 2 and arr.dtype.kind in "fiub":
                f[f"state_{key}"] = element_average(arr.astype(float), n_gauss)
        steps.append(f)
    return steps


def _write_csv(path: Path, result: Any) -> Path:
    """Write the homogenized CSV of a CPFE result, with the columns of the scene's own CSV.

    The mean F is the volume average of the element F (Gauss-weighted in each element).
    """
    from ..io.results import write_homogenized_csv

    return write_homogenized_csv(path, result, weights=result.system.disc.mesh.volumes)


def run_cpfe(scene: Any, series: Path, prog: Any) -> tuple[Any, Path, Path, float]:
    """Solve the scene by CPFE and write its series and CSV.

    Parameters
    ----------
    scene : Scene
        A scene with ``compare["cpfe"]``.
    series : Path
        The scene's own series (the default CPFE paths sit beside it).
    prog : callable
        Progress printer.

    Returns
    -------
    result : NonlinearResult
        The CPFE result.
    written : Path
        Its series.
    csv_path : Path
        Its homogenized CSV.
    t_write : float
        Seconds spent writing.
    """
    from ..io.results import write_series
    from ..scene.compare import cpfe_keywords, cpfe_problem
    from ..verification.cpfe import crystal_plasticity_fem
    from .main import _size, _write_progress

    kw = cpfe_keywords(scene)
    prog(f"CPFE comparator: {kw['integration']} Q4/Hex8 elements on the pixels, {kw['method']}")
    problem = cpfe_problem(scene)  # a ghost-layer scene: its real pixels
    result = crystal_plasticity_fem(problem, progress=prog, **kw)
    out, csv_path = cpfe_paths(scene, series)
    prog(f"writing {out}")
    t_write = time.perf_counter()
    n_gauss = result.system.disc.mesh.n_gauss
    with _write_progress(out, prog):
        times = [float(t) for t in result.times]
        written = write_series(out, problem.cloud, times, _element_fields(result, n_gauss))
    _write_csv(csv_path, result)
    t_write = time.perf_counter() - t_write
    prog(f"wrote {_size(Path(written))} and {csv_path} in {t_write:.1f} s")
    return result, Path(written), csv_path, t_write


def cpfe_summary(scene: Any, cppd: Any, cpfe: Any, written: Path, csv_path: Path) -> dict[str, Any]:
    """Build the ``cpfe`` entry of the run's summary: histories, gap per step, check.

    Parameters
    ----------
    scene : Scene
        The scene (``compare["cpfe"]``: component, tolerance).
    cppd, cpfe : NonlinearResult
        The scene's run and the comparator's.
    written, csv_path : Path
        The CPFE series and CSV.

    Returns
    -------
    dict
        JSON-ready: ``homogenized_stress`` (every step), ``component``, ``gap`` per step
        (CPPD, CPFE, CPPD - CPFE, relative gap of the magnitudes), ``max_relative_gap``,
        and with a tolerance ``passed``.
    """
    from ..scene.compare import homogenized_gap, stress_component

    cfg = scene.compare["cpfe"]
    hf = np.asarray(cpfe.homogenized_stress, dtype=float)
    d = hf.shape[-1]
    if cfg["component"] is not None:
        i, j = stress_component(cfg["component"], d, "compare.cpfe.component")
    else:  # the component of largest magnitude at the last step (ties: the first)
        pairs = [(a, b) for a in range(d) for b in range(a, d)]
        i, j = max(pairs, key=lambda p: abs(hf[-1][p]))
    gap = homogenized_gap(cppd.homogenized_stress, hf, (i, j))
    rel = gap["relative"]
    worst = float(np.nanmax(np.abs(rel))) if np.isfinite(rel).any() else float("nan")
    s: dict[str, Any] = {
        "integration": cfg["integration"],
        "method": cfg["method"],
        "output": str(written),
        "homogenized": str(csv_path),
        "iterations": int(np.sum(cpfe.iterations)),
        "cutbacks": int(np.sum(cpfe.cutbacks)),
        "timings": {k: round(float(cpfe.timings.get(k, 0.0)), 4) for k in ("setup", "total")},
        "homogenized_stress": hf.tolist(),
        "component": "xyz"[i] + "xyz"[j],
        "gap": {
            "time": [float(t) for t in cpfe.times],
            # JSON has no NaN: a step where the CPFE component is 0 has no relative gap
            **{k: [float(x) if np.isfinite(x) else None for x in v] for k, v in gap.items()},
        },
        "max_relative_gap": worst if np.isfinite(worst) else None,
    }
    if cfg["tolerance"] is not None:
        s["tolerance"] = cfg["tolerance"]
        s["passed"] = bool(np.isfinite(worst) and worst <= cfg["tolerance"])
    return s


def print_cpfe(s: dict[str, Any]) -> None:
    """Print the comparison: the gap table per step and the PASS/FAIL line.

    Parameters
    ----------
    s : dict
        :func:`cpfe_summary`.
    """
    c = s["component"]
    g = s["gap"]
    print(
        f"CPFE         {s['integration']} elements, {s['method']}: {s['iterations']} "
        f"iteration(s), {s['cutbacks']} cut-back(s); {s['output']} (time series), "
        f"{s['homogenized']} (homogenized)"
    )
    print(f"gap          homogenized sigma_{c} per step; rel = (|CPPD| - |CPFE|) / |CPFE|")
    print(f"  {'step':>4} {'t':>10} {'CPPD':>12} {'CPFE':>12} {'CPPD-CPFE':>12} {'rel':>9}")
    for k, t in enumerate(g["time"]):
        rel = g["relative"][k]
        r = f"{100 * rel:+8.2f}%" if rel is not None else f"{'-':>9}"
        print(
            f"  {k + 1:>4} {t:>10.4g} {g['cppd'][k]:>12.5g} {g['cpfe'][k]:>12.5g} "
            f"{g['difference'][k]:>+12.4g} {r}"
        )
    rel = np.array([np.nan if v is None else v for v in g["relative"]], dtype=float)
    fin = np.isfinite(rel)
    below = int(np.sum(rel[fin] < 0))
    worst = s["max_relative_gap"]
    worst = float("nan") if worst is None else worst
    print(
        f"  CPPD below CPFE at {below} of {int(fin.sum())} step(s); largest |rel| "
        f"{100 * worst:.2f} %"
    )
    if "passed" in s:
        word = "PASS" if s["passed"] else "FAIL"
        print(
            f"check: CPPD vs CPFE sigma_{c}: largest relative gap "
            f"{worst:.3e} - {word} within {s['tolerance']:g}"
        )
