"""Every figure pdlin draws: results, stiffness patterns, convergence, micromoduli, trade-offs.

This is the only module of pdlin that uses matplotlib (and pyvista for
:func:`render_result`); both are imported lazily inside the functions (extra
``plotting``), so ``import pdlin.plotting`` costs no matplotlib.  The result
plots draw with the Agg backend and return a :class:`Plot`: the figure plus the
data it drew, so tests and scripts can check what is on the picture.  The data
of a figure comes from the analysis modules (e.g. :func:`pdlin.analysis.spy_pattern`,
:func:`pdlin.analysis.sparsity_report`); this module only draws.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import InputError, MissingDependencyError
from .io.names import TENSOR_FIELDS
from .io.read import ResultFile, read_result

if TYPE_CHECKING:
    from .calibration.calibrate import CalibrationResult
    from .calibration.lattices import Family
    from .sweeps.core import TradeoffResult

__all__ = [
    "Plot",
    "plot_result",
    "plot_homogenized",
    "plot_convergence",
    "plot_scene_spy",
    "plot_sparsity_vs_horizon",
    "field_components",
    "field_unit",
    "UNIT_SYSTEMS",
    "save_figure",
    "render_result",
    "plot_spy",
    "plot_micromoduli",
    "plot_tradeoff",
    "check_figure",
    "use_agg",
    "close_figures",
]

_AXES = "xyz"

#: named unit systems of ``units=`` / ``pdlin plot --units``: the length, force and stress
#: units of a consistent set (pdlin computes in whatever consistent units its input has)
UNIT_SYSTEMS: dict[str, dict[str, str]] = {
    "SI": {"length": "m", "force": "N", "stress": "Pa"},
    "mm-N-MPa": {"length": "mm", "force": "N", "stress": "MPa"},
    "m-N-Pa": {"length": "m", "force": "N", "stress": "Pa"},
    "mm-kN-GPa": {"length": "mm", "force": "kN", "stress": "GPa"},
}
#: the quantity of each API field: its unit comes from the unit system ("-": dimensionless)
_FIELD_QUANTITY = {
    "displacement": "length",
    "reaction": "force",
    "stress": "stress",
    "strain": "-",
    "deformation_gradient": "-",
    "damage": "-",
    "volume": "volume",
}


def _unit_system(units: str | dict[str, str] | None) -> dict[str, str]:
    """``units`` as {'length', 'force', 'stress'} names; None: the names of the quantities."""
    if units is None:
        return {"length": "length", "force": "force", "stress": "stress"}
    if isinstance(units, str):
        if units not in UNIT_SYSTEMS:
            raise InputError(
                f"units (--units) must be one of {sorted(UNIT_SYSTEMS)}, got {units!r}"
            )
        return dict(UNIT_SYSTEMS[units])
    if (
        not isinstance(units, dict)
        or set(units) != {"length", "force", "stress"}
        or not all(isinstance(v, str) and v for v in units.values())
    ):
        raise InputError(
            "units must be a unit system name or a dict of the 'length', 'force' and "
            f"'stress' unit names, got {units!r}"
        )
    return dict(units)


def field_unit(key: str, dim: int, units: str | dict[str, str] | None = None) -> str:
    """Name the unit of a field in a unit system (``""`` for counts and unknown fields).

    Without ``units`` the unit is named by its quantity (``length``, ``force``,
    ``stress``): pdlin's results are in the consistent units of the input.

    Parameters
    ----------
    key : str
        API field name (``displacement``, ``stress``, ``volume``, ...).
    dim : int
        Dimension of the result (1, 2 or 3): a cell volume is a length, area or volume.
    units : str or dict, optional
        A name of :data:`UNIT_SYSTEMS` or a dict of ``length``, ``force`` and ``stress``
        unit names; None names the quantity instead.

    Returns
    -------
    str
        The unit (``"m"``, ``"MPa"``, ``"m²"``), ``"-"`` for dimensionless fields,
        ``""`` for counts and fields without a known quantity.

    Raises
    ------
    InputError
        ``units`` is neither a known system name nor such a dict.

    Examples
    --------
    >>> field_unit("displacement", 2, "SI"), field_unit("stress", 3, "mm-N-MPa")
    ('m', 'MPa')
    >>> field_unit("volume", 2, "SI"), field_unit("strain", 2), field_unit("stress", 2)
    ('m²', '-', 'stress')
    >>> field_unit("family_size", 3, "SI")
    ''
    """
    system = _unit_system(units)
    quantity = _FIELD_QUANTITY.get(key, "")
    if quantity == "volume":  # a cell's area in 2D (per unit thickness), length in 1D
        return system["length"] + {1: "", 2: "²", 3: "³"}[dim]
    return system.get(quantity, quantity)


def _with_unit(label: str, unit: str) -> str:
    return f"{label} [{unit}]" if unit else label


@dataclass
class Plot:
    """A drawn figure and the data on it.

    Attributes
    ----------
    figure : matplotlib Figure
        The figure drawn (an (h, w, 3) image array for :func:`render_result`).
    values : ndarray
        The plotted values (colour of each marker, or the curve's y values).
    points : ndarray
        Where they are drawn (marker positions (m, 2), or the curve's x values).
    label : str
        What ``values`` are (the colour-bar or y-axis label without its unit).
    unit : str
        Unit of ``values`` on the figure (``""`` for counts, ``"-"`` dimensionless).
    """

    figure: Any
    values: np.ndarray
    points: np.ndarray
    label: str
    unit: str = ""


def _plt() -> Any:
    try:
        import matplotlib
    except ImportError as exc:
        raise MissingDependencyError(
            "plots need matplotlib: pip install 'pdlin[plotting]'"
        ) from exc
    if matplotlib.get_backend().lower() != "agg":
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def field_components(arr: np.ndarray, dim: int, key: str = "") -> list[str]:
    """List the component names of a field (what ``component=`` accepts).

    Parameters
    ----------
    arr : (n,) or (n, ...) array_like
        The field's values per point.
    dim : int
        Dimension of the result.
    key : str
        API field name; tensors (``stress``, ``strain``, ...) are told apart from
        vectors of the same width by it.

    Returns
    -------
    list of str
        ``[]`` for scalars, vectors ``magnitude, x, y(, z)``, ``dim x dim`` tensors
        ``xx, xy, ...``, other widths ``0, 1, ...``.

    Examples
    --------
    >>> import numpy as np
    >>> field_components(np.zeros((5, 2)), 2), field_components(np.zeros((5, 4)), 2)
    (['magnitude', 'x', 'y'], ['xx', 'xy', 'yx', 'yy'])
    """
    a = np.asarray(arr)
    w = 1 if a.ndim == 1 else a.reshape(a.shape[0], -1).shape[1]
    if a.ndim == 1 or (w == 1 and dim > 1):
        return []
    if w == 1:  # (n, 1) of a 1D result
        return ["xx"] if key in TENSOR_FIELDS else ["magnitude", "x"]
    if w == dim * dim and (key in TENSOR_FIELDS or (dim > 1 and w != dim)):
        return [_AXES[i] + _AXES[j] for i in range(dim) for j in range(dim)]
    if w == dim or (key in ("displacement", "reaction") and w == 3):
        return ["magnitude", *_AXES[:w]]
    return [str(k) for k in range(w)]


def _component(
    key: str, arr: np.ndarray, dim: int, component: str | None
) -> tuple[np.ndarray, str]:
    comps = field_components(arr, dim, key)
    a = np.asarray(arr, dtype=float)
    if not comps:
        if component not in (None, "", "value"):
            raise InputError(
                f"component (--component) {component!r}: field {key!r} is a scalar, "
                "give no component"
            )
        return a.reshape(-1), key
    if component is None:
        component = comps[0]
    if component not in comps:
        raise InputError(
            f"component (--component) must be one of {comps} for field {key!r}, got {component!r}"
        )
    flat = a.reshape(a.shape[0], -1)
    if component == "magnitude":
        return np.linalg.norm(flat, axis=1), f"|{key}|"
    return flat[:, comps.index(component) - (1 if "magnitude" in comps else 0)], (
        f"{key} {component}"
    )


def _parse_slice(slice_: str | tuple[str, float], dim: int) -> tuple[int, float]:
    if isinstance(slice_, str):
        axis, sep, val = slice_.partition("=")
        try:
            value = float(val)
        except ValueError:
            value = float("nan")
        if not sep or not np.isfinite(value):
            raise InputError(f"slice (--slice) must look like 'z=0.5', got {slice_!r}")
    else:
        axis, value = slice_[0], float(slice_[1])
    axis = axis.strip().lower()
    if axis not in _AXES[:dim]:
        raise InputError(f"slice (--slice) axis must be one of {list(_AXES[:dim])}, got {axis!r}")
    return _AXES.index(axis), value


def _spacing(r: ResultFile, fields: dict[str, np.ndarray]) -> float:
    vol = fields.get("volume")
    if vol is not None and np.all(np.asarray(vol) > 0):
        return float(np.median(vol) ** (1.0 / r.dim))
    from scipy.spatial import cKDTree

    d, _ = cKDTree(r.points).query(r.points, k=2)
    return float(np.median(d[:, 1]))


def _step_field(
    r: ResultFile, step: int, field: str, component: str | None, scale: float
) -> tuple[int, dict[str, np.ndarray], np.ndarray, str, np.ndarray]:
    """Pick a step's field for the plotters (the checks both share).

    Returns the step index, the step's fields, the plotted values, their label and the
    points moved by ``scale`` x displacement (``(n, dim)``).
    """
    k = r.step_index(step)
    fields = r.steps[k]
    if field not in fields:
        raise InputError(
            f"field (--field) {field!r} is not in {r.path.name}; available: {sorted(fields)}"
        )
    values, label = _component(field, fields[field], r.dim, component)
    pts = np.asarray(r.points, dtype=float)
    scale = float(scale)
    if not np.isfinite(scale):
        raise InputError(f"scale (--scale) must be finite, got {scale}")
    if scale != 0.0:
        if "displacement" not in fields:
            raise InputError(
                f"scale (--scale) {scale} needs a displacement field; {r.path.name} has "
                f"{sorted(fields)}"
            )
        pts = pts + scale * np.asarray(fields["displacement"])[:, : r.dim]
    return k, fields, values, label, pts


def plot_result(
    result: str | Path | ResultFile,
    *,
    field: str = "displacement",
    component: str | None = None,
    step: int = -1,
    scale: float = 0.0,
    slice: str | tuple[str, float] | None = None,  # noqa: A002 - the CLI's --slice
    ax: Any = None,
    units: str | dict[str, str] | None = None,
) -> Plot:
    """Colour map of one field of a result file (or of a :class:`~pdlin.io.ResultFile`).

    2D results: the points coloured by the value, equal aspect; 3D results:
    the points within ``h/2`` of a plane (``slice="z=0.5"``, ``h`` the
    point spacing from the volumes), drawn in the other two coordinates; 1D
    results: the value along x.

    Parameters
    ----------
    result : path or ResultFile
        A result file (any format :func:`pdlin.io.read_result` reads) or one read already.
    field : str
        API key (``displacement``, ``reaction``, ``strain``, ``stress``, ...).
    component : str, optional
        ``magnitude``/``x``/``y``/``z`` of vectors (default magnitude),
        ``xx``/``xy``/... of tensors (default ``xx``); none for scalars.
    step : int
        Step of a series (0-based; negative from the end; default last).
    scale : float
        Draw at ``points + scale * displacement`` (0: the reference shape).
    slice : str or (axis, value), optional
        Plane of a 3D result, e.g. ``"z=0.5"``; the title names it.
    ax : matplotlib Axes, optional
        Axes to draw into (default: a new figure sized to the body's aspect).
    units : str or dict, optional
        Unit system of the result for the axis and colour-bar labels: a name of
        :data:`UNIT_SYSTEMS` (``"SI"``, ``"mm-N-MPa"``, ...) or a dict of ``length``,
        ``force`` and ``stress`` unit names.  Default: the labels name the quantity
        (``[length]``, ``[stress]``; strains ``[-]``), as pdlin computes in the
        consistent units of its input.

    Returns
    -------
    Plot
        ``values`` are the plotted field values, ``points`` the drawn positions.

    Examples
    --------
    >>> import numpy as np, pdlin, tempfile, os
    >>> from pdlin.io import write_points
    >>> cloud = pdlin.grid((4, 3))
    >>> u = np.column_stack([cloud.points[:, 0], np.zeros(12)])
    >>> p = write_points(os.path.join(tempfile.mkdtemp(), "r.vtu"), cloud, {"displacement": u})
    >>> plot = plot_result(p, component="x")
    >>> bool(np.array_equal(plot.values, u[:, 0])), plot.label
    (True, 'displacement x')
    >>> plot_result(p, component="x", units="SI").figure.axes[1].get_ylabel()
    'displacement x [m]'
    """
    plt = _plt()
    system = _unit_system(units)
    r = result if isinstance(result, ResultFile) else read_result(result)
    k, fields, values, label, pts = _step_field(r, step, field, component, scale)
    unit = field_unit(field, r.dim, system)
    length = system["length"]
    where = ""
    scale = float(scale)
    if r.dim == 3:
        if slice is None:
            lo, hi = r.points.min(axis=0), r.points.max(axis=0)
            raise InputError(
                "slice (--slice) is needed for a 3D result, e.g. 'z=0.5'; bounds "
                + ", ".join(f"{a} [{lo[i]:g}, {hi[i]:g}]" for i, a in enumerate(_AXES))
            )
        axis, value = _parse_slice(slice, 3)
        half = 0.5 * _spacing(r, fields)
        keep = np.abs(r.points[:, axis] - value) <= half * (1 + 1e-9)
        if not keep.any():
            c = r.points[:, axis]
            raise InputError(
                f"slice (--slice) {_AXES[axis]}={value:g} holds no point (within h/2 = "
                f"{half:g}); {_AXES[axis]} ranges over [{c.min():g}, {c.max():g}]"
            )
        others = [i for i in range(3) if i != axis]
        xy, values = pts[keep][:, others], values[keep]
        names = [_AXES[i] for i in others]
        where = (
            f", slice {_AXES[axis]} = {value:g} (±{half:.3g} {length}, {int(keep.sum()):,} points)"
        )
    elif slice is not None:
        raise InputError(f"slice (--slice) applies to 3D results; this one is {r.dim}D")
    else:
        xy, names = pts, list(_AXES[: r.dim])
    if ax is None:
        ext = np.ptp(xy, axis=0) if r.dim > 1 else np.ones(2)
        aspect = float(ext[1] / ext[0]) if r.dim > 1 and ext[0] > 0 else 0.75
        height = float(np.clip(5.6 * aspect + 1.2, 2.6, 7.0))
        fig, ax = plt.subplots(figsize=(6.4, height), layout="constrained")
    else:
        fig = ax.figure
    title = f"{r.path.name}: {label}{where}"
    if r.n_steps > 1:
        title += f" (step {k}, t = {r.times[k]:g})"
    if r.dim == 1:
        order = np.argsort(xy[:, 0])
        ax.plot(xy[order, 0], values[order], ".-")
        ax.set_xlabel(f"x [{length}]")
        ax.set_ylabel(_with_unit(label, unit))
        ax.set_title(title)
        return Plot(fig, values, xy[:, 0], label, unit)
    span = np.ptp(xy, axis=0).max() or 1.0
    width_pt = 72 * 5.0 * float(np.ptp(xy[:, 0]) or span) / span
    size = float(np.clip((0.9 * width_pt * _spacing(r, fields) / span) ** 2, 0.5, 200.0))
    sc = ax.scatter(xy[:, 0], xy[:, 1], c=values, s=size, marker="s", cmap="viridis")
    ext = np.ptp(xy, axis=0)
    shrink = float(np.clip(1.2 * ext[1] / ext[0], 0.4, 1.0)) if ext[0] > 0 else 1.0
    fig.colorbar(sc, ax=ax, label=_with_unit(label, unit), shrink=shrink)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{names[0]} [{length}]")
    ax.set_ylabel(f"{names[1]} [{length}]")
    if scale != 0.0:
        title += f", deformed x{scale:g}"
    ax.set_title(title)
    return Plot(fig, values, xy, label, unit)


def plot_homogenized(
    path: str | Path,
    *,
    component: str | None = None,
    ax: Any = None,
    units: str | dict[str, str] | None = None,
) -> Plot:
    """Homogenized stress-strain curve from the CSV of a nonlinear run.

    ``sigma_<component>`` against the strain ``F_<component> - delta`` (the
    volume-averaged nonlocal deformation gradient minus the identity).  The
    default component (``None``) is the one of largest magnitude at the last
    step (``12`` in shear, ``22`` in compression along y).  ``units`` labels the
    stress axis as in :func:`plot_result` (default ``[stress]``); the strain is
    dimensionless.

    Parameters
    ----------
    path : str or Path
        The ``<stem>_homogenized.csv`` of a nonlinear run (columns ``sigma_ij``, ``F_ij``).
    component : str, optional
        ``"11"``, ``"12"``, ... (default: largest magnitude at the last step).
    ax : matplotlib Axes, optional
        Axes to draw into (default: a new figure).
    units : str or dict, optional
        Unit system of the stress label, as in :func:`plot_result`.

    Returns
    -------
    Plot
        ``values`` = the stress column, ``points`` = the strain.
    """
    plt = _plt()
    stress_unit = _unit_system(units)["stress"]
    p = Path(path)
    if not p.is_file():
        raise InputError(f"homogenized CSV {str(p)!r} does not exist")
    with open(p, newline="") as fh:
        rows = list(csv.DictReader(fh))
    comps = sorted(c[6:] for c in (rows[0] if rows else {}) if c.startswith("sigma_"))
    if component is None and comps:
        last = [abs(float(rows[-1][f"sigma_{c}"])) for c in comps]
        component = comps[int(np.nanargmax(last))] if np.any(np.isfinite(last)) else comps[0]
    if component is None or component not in comps:
        raise InputError(
            f"component (--component) of the homogenized curve must be one of {comps}, "
            f"got {component!r}"
        )
    sig = np.array([float(r[f"sigma_{component}"]) for r in rows])
    delta = 1.0 if component[0] == component[1] else 0.0
    eps = np.array([float(r[f"F_{component}"]) for r in rows]) - delta
    if not (np.all(np.isfinite(sig)) and np.all(np.isfinite(eps))):
        raise InputError(
            f"{p.name} holds no finite sigma_{component} / F_{component} column (the run "
            "computed no homogenized stress)"
        )
    eps, sig = np.concatenate([[0.0], eps]), np.concatenate([[0.0], sig])
    if ax is None:
        fig, ax = plt.subplots(figsize=(5.5, 4.2))
    else:
        fig = ax.figure
    ax.plot(eps, sig, "o-")
    ax.set_xlabel(f"mean strain F_{component} - δ [-]")
    ax.set_ylabel(f"mean stress sigma_{component} [{stress_unit}]")
    ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 3))
    ax.set_title(p.name)
    ax.grid(True, alpha=0.3)
    return Plot(fig, sig, eps, f"sigma_{component}", stress_unit)


def plot_convergence(result: str | Path | ResultFile, *, ax: Any = None) -> Plot:
    """Plot the relative residual vs iteration of the linear solve stored in a result.

    Only NPZ results of :func:`pdlin.io.write_result` store the history
    (``residual_history``); other files raise an error saying so.

    Parameters
    ----------
    result : path or ResultFile
        An ``.npz`` result written by :func:`pdlin.io.write_result`.
    ax : matplotlib Axes, optional
        Axes to draw into (default: a new figure).

    Returns
    -------
    Plot
        ``values`` = the relative residuals, ``points`` = the iteration numbers.

    Raises
    ------
    InputError
        The result stores no residual history.
    """
    plt = _plt()
    r = result if isinstance(result, ResultFile) else read_result(result)
    hist = r.extra.get("residual_history")
    if hist is None:
        raise InputError(
            f"{r.path.name} stores no residual history (written by write_result as .npz)"
        )
    res = np.asarray(hist, dtype=float)
    it = np.arange(res.size, dtype=float)
    if ax is None:
        fig, ax = plt.subplots(figsize=(5.5, 4.2))
    else:
        fig = ax.figure
    ax.semilogy(it, np.maximum(res, np.finfo(float).tiny), "o-", ms=3)
    ax.set_xlabel("iteration")
    ax.set_ylabel("relative residual")
    ax.set_title(f"{r.path.name}: linear solver convergence")
    ax.grid(True, which="both", alpha=0.3)
    return Plot(fig, res, it, "relative residual")


def plot_scene_spy(scene: Any, *, order: str = "rcm", ax: Any = None) -> Plot:
    """Spy plot of a scene's assembled stiffness (``pdlin plot --spy SCENE``).

    Parameters
    ----------
    scene : Scene or path
        A loaded scene or a scene file (its constrained system is assembled).
    order : {'rcm', 'natural'}
        Row/column ordering drawn (see :func:`plot_spy`).
    ax : matplotlib Axes, optional
        Axes to draw into (default: a new figure).

    Returns
    -------
    Plot
        ``values`` = the nonzeros per row of the matrix drawn, ``points`` =
        ``[n_rows, nnz]``.
    """
    _plt()
    import scipy.sparse as sp

    from .scene.scene import load_scene
    from .system import constrained_system

    sc = scene if hasattr(scene, "problem") else load_scene(scene)
    K = sp.csr_array(constrained_system(sc.problem).assemble())
    ax = plot_spy(K, ax=ax, order=order, block_size=sc.cloud.dim)
    nnz_row = np.diff(K.indptr).astype(float)
    return Plot(ax.figure, nnz_row, np.array([K.shape[0], K.nnz]), "nonzeros per row")


def plot_sparsity_vs_horizon(
    scene: Any, ratios: Any = (2.0, 3.0, 4.0, 5.0), *, ax: Any = None
) -> Plot:
    """Mean nonzeros per row of a scene's stiffness against the horizon ratio δ/h.

    Each ratio rebuilds the bonds of the scene's cloud (``find_bonds(cloud,
    ratio=m)``) and counts the pattern with :func:`pdlin.analysis.sparsity_report`
    (``K`` is not assembled).

    Parameters
    ----------
    scene : Scene or path
        A loaded scene or a scene file (its cloud and model are used).
    ratios : sequence of float
        Horizon ratios δ/h to count (> 0).
    ax : matplotlib Axes, optional
        Axes to draw into (default: a new figure).

    Returns
    -------
    Plot
        ``values`` = mean nonzeros per DOF row, ``points`` = the ratios.
    """
    plt = _plt()
    from .analysis.sparsity import sparsity_report
    from .geometry.bonds import find_bonds
    from .scene.scene import load_scene

    sc = scene if hasattr(scene, "model") else load_scene(scene)
    m = np.asarray(ratios, dtype=float).reshape(-1)
    if m.size == 0 or not np.all(np.isfinite(m)) or np.any(m <= 0):
        raise InputError(f"ratios (--ratios) must be positive numbers, got {m.tolist()}")
    nnz = []
    for ratio in m:
        bonds = find_bonds(sc.cloud, ratio=float(ratio))
        rep = sparsity_report(model=sc.model, cloud=sc.cloud, bonds=bonds, fill_limit=0)
        nnz.append(rep.nnz_per_row_mean)
    vals = np.array(nnz)
    if ax is None:
        fig, ax = plt.subplots(figsize=(5.5, 4.2))
    else:
        fig = ax.figure
    ax.plot(m, vals, "o-")
    ax.set_xlabel("horizon ratio δ/h")
    ax.set_ylabel("nonzeros per DOF row (mean)")
    ax.set_title(f"{sc.name}: {sc.cloud.n:,} points, {sc.cloud.dim}D")
    ax.grid(True, alpha=0.3)
    return Plot(fig, vals, m, "nonzeros per DOF row (mean)")


def render_result(
    result: str | Path | ResultFile,
    output: str | Path,
    *,
    field: str = "displacement",
    component: str | None = None,
    step: int = -1,
    scale: float = 0.0,
    window_size: tuple[int, int] = (1024, 768),
) -> Plot:
    """3D rendering of a result with pyvista (off-screen), written to a PNG atomically.

    The points are drawn as spheres coloured by the field component (no
    slice needed); needs ``pip install "pdlin[render]"`` (pyvista).

    Parameters
    ----------
    result : path or ResultFile
        The result to draw.
    output : str or Path
        The PNG (or other image format pyvista writes) to write.
    field, component, step, scale
        As in :func:`plot_result`.
    window_size : (int, int)
        Image width and height in pixels.

    Returns
    -------
    Plot
        ``figure`` is the rendered image ((h, w, 3) uint8 array), ``values``
        the plotted values and ``points`` the drawn (3D) positions.
    """
    try:
        import pyvista as pv
    except ImportError as exc:
        raise MissingDependencyError(
            "3D rendering needs pyvista: pip install 'pdlin[render]'"
        ) from exc
    from .io.output import staging

    r = result if isinstance(result, ResultFile) else read_result(result)
    k, _, values, label, deformed = _step_field(r, step, field, component, scale)
    pts = np.zeros((r.points.shape[0], 3))
    pts[:, : r.dim] = deformed
    cloud = pv.PolyData(pts)
    cloud[label] = values
    pl = pv.Plotter(off_screen=True, window_size=list(window_size))
    pl.add_points(cloud, scalars=label, render_points_as_spheres=True, point_size=8, cmap="viridis")
    title = f"{r.path.name}: {label}" + (f", deformed x{float(scale):g}" if scale else "")
    if r.n_steps > 1:
        title += f" (step {k}, t = {r.times[k]:g})"
    pl.add_text(title, font_size=10)
    pl.camera_position = "iso"
    p = Path(output)
    with staging(p) as st:
        image = pl.screenshot(str(st.main), return_img=True)
    pl.close()
    return Plot(np.asarray(image), values, pts, label)


def save_figure(fig: Any, path: str | Path, *, dpi: int = 120) -> Path:
    """Save a figure atomically (written beside the target, then renamed).

    Parameters
    ----------
    fig : matplotlib Figure
        The figure to save.
    path : str or Path
        Target file; the suffix picks the format.
    dpi : int
        Resolution of raster formats.

    Returns
    -------
    Path
        ``path``.
    """
    from .io.output import staging

    p = Path(path)
    with staging(p) as st:
        fig.savefig(st.main, dpi=dpi)
    return p


def check_figure(path: str | Path, what: str = "figure") -> Path:
    """Check a figure path before the work is done.

    matplotlib must be installed, the suffix a format it writes (``.png``, ``.pdf``,
    ``.svg``, ...) and the folder writable.

    Parameters
    ----------
    path : str or Path
        The figure file to be written.
    what : str
        What the path is, for the error messages (``"--plot"``, ``"output.plot"``).

    Returns
    -------
    Path
        ``path`` as a Path.

    Raises
    ------
    MissingDependencyError
        matplotlib is not installed.
    InputError
        The suffix is not a format matplotlib writes.
    """
    from .io.output import check_output, need_module

    need_module("matplotlib", "plotting", f"{what} ({str(path)!r})")
    from matplotlib.backend_bases import FigureCanvasBase

    kinds = tuple(f".{k}" for k in sorted(FigureCanvasBase.get_supported_filetypes()))
    return check_output(path, kinds, what)


def use_agg() -> None:
    """Switch matplotlib to the non-interactive Agg backend (figures written to files only).

    Raises
    ------
    MissingDependencyError
        matplotlib is not installed.
    """
    try:
        import matplotlib
    except ImportError as exc:
        raise MissingDependencyError(
            "plots need matplotlib: pip install 'pdlin[plotting]'"
        ) from exc
    matplotlib.use("Agg")


def close_figures() -> None:
    """Close every open matplotlib figure (frees their memory after they were saved)."""
    import matplotlib.pyplot as plt

    plt.close("all")


def _pyplot(message: str) -> Any:
    """Import ``matplotlib.pyplot`` (current backend) or raise an ImportError with ``message``."""
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingDependencyError(message) from exc
    return plt


def plot_spy(
    K: Any,
    ax: Any = None,
    *,
    order: str | Sequence[int] | np.ndarray = "natural",
    block_size: int | None = None,
    blocks: bool = False,
    markersize: float | None = None,
    title: str | None = None,
    **kwargs: Any,
) -> Any:
    """Spy plot of the pattern of ``K`` (needs matplotlib: ``pip install pdlin[plotting]``).

    The pattern comes from :func:`pdlin.analysis.spy_pattern`.

    Parameters
    ----------
    K : (n, n) sparse array or ndarray
        The matrix whose stored entries are drawn.
    ax : matplotlib Axes, optional
        Axes to draw into (default: a new figure).
    order : {'natural', 'rcm'} or (n,) array_like of int
        Row/column ordering: as stored, reverse Cuthill-McKee of the point
        graph, or an explicit permutation (``perm[new] = old``, in DOFs, or
        in points when ``blocks=True``).
    block_size : int, optional
        DOFs per point (default: ``K.blocksize`` for BSR, else 1).
    blocks : bool
        Plot the point (block) pattern instead of the DOF pattern.
    markersize : float, optional
        Marker size (default scales with the matrix size).
    title : str, optional
        Axes title (default: size and nnz).
    **kwargs
        Passed to :meth:`matplotlib.axes.Axes.spy`.

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn into, titled with the size, nnz and ordering.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import pdlin
    >>> from pdlin.operators import assemble_stiffness
    >>> cloud = pdlin.grid((6, 6))
    >>> K = assemble_stiffness(pdlin.BondBased(E=1.0), cloud, pdlin.find_bonds(cloud, 2.0))
    >>> ax = plot_spy(K, order="rcm")
    >>> ax.get_title()      # 36 points + 316 directed bonds = 352 blocks of 2 x 2
    '72 x 72, nnz 1,408 (rcm)'
    >>> import matplotlib.pyplot as plt; plt.close("all")
    """
    plt = _pyplot(
        "plot_spy needs matplotlib, install the plotting extra: pip install pdlin[plotting]"
    )
    from .analysis.sparsity import spy_pattern

    target, label = spy_pattern(K, order=order, block_size=block_size, blocks=blocks)
    size = target.shape[0]
    if ax is None:
        _, ax = plt.subplots(figsize=(5, 5))
    ms = markersize if markersize is not None else float(np.clip(300.0 / max(size, 1), 0.05, 4.0))
    ax.spy(target, markersize=ms, **kwargs)
    ax.set_title(title if title is not None else f"{size} x {size}, nnz {target.nnz:,} ({label})")
    return ax


def plot_micromoduli(
    result: CalibrationResult,
    family: Family | None = None,
    *,
    ax: Any = None,
    cmap: str = "viridis",
    size: float = 20.0,
) -> Any:
    """Plot micromoduli against bond direction.

    2D: polar scatter of ``c`` against the bond angle (colour = bond
    length).  3D: the unit bond directions on the sphere, coloured by
    ``c`` (collinear bonds of different length overlap).

    Parameters
    ----------
    result : CalibrationResult
        A single-family result (for a cloud pass ``result.families[k]``).
    family : Family, optional
        The family that was calibrated; defaults to the one stored in the
        result.
    ax : matplotlib Axes, optional
        A polar (2D) or 3D axes; created when omitted.
    cmap : str
        matplotlib colour map name.
    size : float
        Marker size.

    Returns
    -------
    matplotlib Axes
        The polar (2D) or 3D axes drawn into.

    Examples
    --------
    >>> import numpy as np, matplotlib
    >>> matplotlib.use("Agg")
    >>> from pdlin.calibration import lattice_family, calibrate_micromoduli
    >>> fam = lattice_family(2, 3.0, lattice="triangular")
    >>> res = calibrate_micromoduli(np.diag([3.0, 2.0, 1.0]), fam, method="robust")
    >>> plot_micromoduli(res).name
    'polar'
    """
    fam = family if family is not None else result.extra.get("family")
    if fam is None:
        raise InputError(
            "family must be given for a result without a stored family (cloud results: "
            "pass result.families[k])"
        )
    c = np.asarray(result.micromoduli)
    if fam.n_bonds != c.size:
        raise InputError(
            f"family must hold one bond per micromodulus ({c.size}), got {fam.n_bonds} bonds"
        )
    plt = _pyplot("plot_micromoduli needs matplotlib: pip install 'pdlin[plotting]'")
    xi = fam.xi
    if fam.dim == 2:
        if ax is None:
            _, ax = plt.subplots(subplot_kw={"projection": "polar"})
        theta = np.arctan2(xi[:, 1], xi[:, 0])
        sc = ax.scatter(theta, c, c=fam.length, cmap=cmap, s=size)
        ax.figure.colorbar(sc, ax=ax, label="|xi|")
        ax.set_title("micromodulus vs bond angle")
        return ax
    if ax is None:
        fig = plt.figure()
        ax = fig.add_subplot(projection="3d")
    u = xi / fam.length[:, None]
    sc = ax.scatter(u[:, 0], u[:, 1], u[:, 2], c=c, cmap=cmap, s=size)
    ax.figure.colorbar(sc, ax=ax, label="micromodulus c")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.set_title("micromodulus on the direction sphere")
    return ax


def plot_tradeoff(result: TradeoffResult, path: str | os.PathLike[str] | None = None) -> Any:
    """Error against time (Pareto front drawn) and error against δ/h per model.

    Parameters
    ----------
    result : TradeoffResult
        A sweep of :func:`pdlin.tradeoff`; its successful rows are drawn.
    path : str or path-like, optional
        Save the figure there (atomically, 120 dpi; the Agg backend is selected first).

    Returns
    -------
    matplotlib Figure
        Two panels: error vs time with the Pareto front, error vs δ/h.
    """
    try:
        import matplotlib

        if path is not None:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError(
            "TradeoffResult.plot needs matplotlib: pip install 'pdlin[plotting]'"
        ) from exc
    rows = result.ok()
    label_key = "model" if "model" in result.params else (result.params[0] if result.params else "")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    labels = sorted({str(r.get(label_key, "")) for r in rows})
    for lab in labels:
        sel = [r for r in rows if str(r.get(label_key, "")) == lab]
        ax1.loglog(
            [r[result.time] for r in sel], [r["error"] for r in sel], "o", label=lab, alpha=0.8
        )
        ratio = [float(r["delta"]) / float(r["h"]) for r in sel]
        o = np.argsort(ratio)
        ax2.semilogy(np.array(ratio)[o], np.array([r["error"] for r in sel])[o], "o-", label=lab)
    front = result.pareto()
    if front:
        ax1.step(
            [r[result.time] for r in front], [r["error"] for r in front], "k--", where="post",
            lw=1, label="Pareto front",
        )  # fmt: skip
    ax1.set_xlabel(f"time ({result.time}) [s]")
    ax1.set_ylabel("error")
    ax1.set_title("error vs time")
    ax1.legend(fontsize=7)
    ax2.set_xlabel("δ / h")
    ax2.set_ylabel("error")
    ax2.set_title(f"error vs δ/h per {label_key}")
    fig.suptitle(f"reference: {result.reference}", fontsize=9)
    fig.tight_layout()
    if path is not None:
        save_figure(fig, Path(path), dpi=120)
    return fig
