"""``[[check]]`` tables of scene files: what a run verifies and against which reference.

A scene may declare any number of checks; ``pdlin run`` evaluates them after the solve
and prints one line per check::

    check: strain_xx = 5.0011e-06 vs 5e-06 (sigma / E, uniaxial stress): rel. error 2.2e-04 \
- PASS within 0.01

Every check names its reference (``source``) and a tolerance.  Kinds:

``value``
    A scalar of the result (``quantity``, reduced over a region) against ``expected``;
    relative error ``|c - e| / |e|`` held to ``tolerance``, or the absolute error held to
    ``atol`` instead (needed for an expected 0).
``closed-form``
    The affine displacement ``u = (F - I)(X - center) + translation`` (the
    ``[tradeoff.exact]`` form) on a region, error by ``metric`` (``rel-max``).
``closed-form-uniaxial``
    Uniaxial stress along ``axis``: ``F = I + ε e⊗e - ν ε (I - e⊗e)`` with
    ``ε = strain`` or ``stress / E``; compared like ``closed-form``.
``reference``
    The bundled problem's own reference (closed form or finite elements) of a scene
    built from ``[problem] factory = ...`` (:mod:`pdlin.sweeps.problems`).
``scene``
    Another scene's solution (a built-in name or a path): the displacement at this
    scene's points, matched by coordinates (e.g. a symmetry-reduced model against
    the full one).
``material-point``
    The homogenized stress of every load step against the homogeneous crystal-plasticity
    driver :func:`pdlin.constitutive.material_point` at the same steps (the constitutive
    model of Luo, Ramazani & Sundararaghavan 2017, Sec. 3).

Quantities of ``value`` checks: a field component ``displacement_x``, ``strain_xy``,
``stress_yy``, ``deformation_gradient_xx`` (reduced by ``reduce``: mean, max, min, sum,
max-abs over ``set`` / ``box`` / ``points``), ``reaction_x`` (summed), nonlinear runs'
``homogenized_stress_xy`` (at ``step``, 1-based, default the last) and damage runs'
``broken_bonds``, ``damage`` (field) and ``first_break_load``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PdlinError, SceneError
from ._keys import check_keys, number

__all__ = [
    "Check",
    "CheckResult",
    "parse_checks",
    "evaluate_checks",
    "format_check",
    "uniaxial_F",
    "KINDS",
    "METRICS",
]

_COMMON = {"kind", "quantity", "source", "tolerance", "set", "box", "points"}
#: keys allowed per check kind (besides kind, quantity, source, tolerance and the region)
KINDS: dict[str, set[str]] = {
    "value": {"expected", "atol", "reduce", "step"},
    "closed-form": {"F", "center", "translation", "metric"},
    "closed-form-uniaxial": {"axis", "strain", "stress", "E", "nu", "center", "metric"},
    "reference": {"metric"},
    "scene": {"scene", "metric"},
    "material-point": {"loading", "eta"},
}
_REDUCE = ("mean", "max", "min", "sum", "max-abs")
#: error measures of field checks: the trade-off harness's three and ``rel-range`` (pdlin's
#: ring metric of the XOSB plate with a hole, Liu, Chen & Skelton, XOSB, Sec. 5.1):
#: max over components of max |u_c - r_c| / range(r_c)
METRICS = ("rel-max", "rel-l2", "max-abs", "rel-range")
_FIELDS = (
    "displacement",
    "strain",
    "stress",
    "deformation_gradient",
    "reaction",
    "homogenized_stress",
)
_AXES = "xyz"


@dataclass(frozen=True)
class Check:
    """One parsed ``[[check]]`` table (``where`` is ``check[k]`` for messages)."""

    kind: str
    quantity: str
    source: str
    tolerance: float
    options: dict[str, Any]
    where: str


@dataclass(frozen=True)
class CheckResult:
    """The outcome of one check."""

    check: Check
    computed: float
    reference: float
    error: float
    passed: bool
    measure: str

    def line(self) -> str:
        """Format the one-line report ``pdlin run`` prints.

        Returns
        -------
        str
            ``format_check`` of this result.
        """
        return format_check(self)


def format_check(r: CheckResult) -> str:
    """Format a check's result as ``pdlin run`` prints it.

    ``check: <quantity> = computed vs reference (source): <measure> X - PASS within tol``.

    Parameters
    ----------
    r : CheckResult
        The evaluated check.

    Returns
    -------
    str
        One line, ending in ``PASS`` or ``FAIL`` and the tolerance.

    Examples
    --------
    >>> c = Check("value", "strain_xx", "sigma / E", 0.01, {}, "check[0]")
    >>> format_check(CheckResult(c, 5.01e-6, 5e-6, 2e-3, True, "rel. error"))
    'check: strain_xx = 5.01e-06 vs 5e-06 (sigma / E): rel. error 2.00e-03 - PASS within 0.01'
    """
    verdict = "PASS" if r.passed else "FAIL"
    return (
        f"check: {r.check.quantity} = {r.computed:.6g} vs {r.reference:.6g} "
        f"({r.check.source}): {r.measure} {r.error:.2e} - {verdict} within "
        f"{r.check.tolerance:g}"
    )


def _matrix(value: Any, key: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{key} must be a square matrix of numbers, got {value!r}") from exc
    if a.ndim != 2 or a.shape[0] != a.shape[1] or not np.all(np.isfinite(a)):
        raise SceneError(f"{key} must be a square matrix of finite numbers, got {value!r}")
    return a


def parse_checks(table: Any) -> list[Check]:
    """Validate a scene's ``check`` entry (one table or an array of tables).

    Parameters
    ----------
    table : Mapping or list of Mapping
        The scene's ``check`` value: one table or an array of tables (``[[check]]``).

    Returns
    -------
    list of Check
        One validated check per table, in order.

    Raises
    ------
    SceneError
        Naming the key (``check[1].tolerance``) of an unknown kind or key, a missing one
        or a value of the wrong type.

    Examples
    --------
    >>> [c.kind for c in parse_checks({"kind": "value", "quantity": "strain_xx",
    ...     "expected": 5e-6, "tolerance": 0.01, "source": "sigma / E"})]
    ['value']
    >>> parse_checks([{"kind": "exact", "source": "x", "tolerance": 0.1}])
    Traceback (most recent call last):
    ...
    pdlin.errors.SceneError: check[0].kind must be one of ['closed-form', \
'closed-form-uniaxial', 'material-point', 'reference', 'scene', 'value'], got 'exact'
    """
    items = [table] if isinstance(table, Mapping) else table
    if not isinstance(items, list):
        raise SceneError(
            f"check must be a table or an array of tables ([[check]]), got {type(table).__name__}"
        )
    out = []
    for k, raw in enumerate(items):
        where = f"check[{k}]"
        if not isinstance(raw, Mapping):
            raise SceneError(f"{where} must be a table, got {type(raw).__name__}")
        kind = raw.get("kind")
        if kind not in KINDS:
            raise SceneError(f"{where}.kind must be one of {sorted(KINDS)}, got {kind!r}")
        t = check_keys(raw, _COMMON | KINDS[kind], where, what="scene key")
        source = t.get("source")
        if not isinstance(source, str) or not source.strip():
            raise SceneError(
                f"{where}.source must say where the reference comes from (a non-empty "
                f"string), got {source!r}"
            )
        if kind == "value" and "atol" in t:
            if "tolerance" in t:
                raise SceneError(
                    f"{where} takes a relative 'tolerance' or an absolute 'atol', not both"
                )
            tol = number(t["atol"], f"{where}.atol", positive=True, phrase=True)
        elif "tolerance" not in t:
            raise SceneError(f"missing scene key {where}.tolerance")
        else:
            tol = number(t["tolerance"], f"{where}.tolerance", positive=True, phrase=True)
        quantity = t.get("quantity", "displacement" if kind != "value" else None)
        if quantity is None:
            raise SceneError(f"missing scene key {where}.quantity")
        if not isinstance(quantity, str):
            raise SceneError(f"{where}.quantity must be a string, got {quantity!r}")
        opts = {key: t[key] for key in t if key not in ("kind", "quantity", "source", "tolerance")}
        _validate(kind, quantity, opts, where)
        out.append(Check(kind, quantity, source, tol, opts, where))
    return out


def _validate(kind: str, quantity: str, opts: dict[str, Any], where: str) -> None:
    if kind == "value":
        if "expected" not in opts:
            raise SceneError(f"missing scene key {where}.expected")
        number(opts["expected"], f"{where}.expected", phrase=True)
        if "atol" in opts:
            number(opts["atol"], f"{where}.atol", positive=True, phrase=True)
        if opts.get("reduce", "mean") not in _REDUCE:
            raise SceneError(
                f"{where}.reduce must be one of {list(_REDUCE)}, got {opts['reduce']!r}"
            )
        if "step" in opts:
            st = opts["step"]
            if isinstance(st, bool) or not isinstance(st, int) or st == 0:
                raise SceneError(
                    f"{where}.step must be a nonzero integer (1-based; -1 = last), got {st!r}"
                )
        _parse_quantity(quantity, where)
    elif kind != "material-point" and quantity != "displacement":
        raise SceneError(
            f"{where}.quantity must be 'displacement' for kind = {kind!r}, got {quantity!r}"
        )
    if kind == "material-point" and quantity != "homogenized_stress":
        raise SceneError(
            f"{where}.quantity must be 'homogenized_stress' for kind = 'material-point', "
            f"got {quantity!r}"
        )
    if kind == "closed-form":
        if "F" not in opts:
            raise SceneError(f"missing scene key {where}.F")
        _matrix(opts["F"], f"{where}.F")
    if kind == "closed-form-uniaxial":
        if ("strain" in opts) == ("stress" in opts):
            raise SceneError(f"{where} needs exactly one of 'strain' or 'stress'")
        if "stress" in opts and "E" not in opts:
            raise SceneError(f"missing scene key {where}.E (needed with {where}.stress)")
        if "nu" not in opts:
            raise SceneError(f"missing scene key {where}.nu")
        for key in ("strain", "stress", "nu"):
            if key in opts:
                number(opts[key], f"{where}.{key}", phrase=True)
        if "E" in opts:
            number(opts["E"], f"{where}.E", positive=True, phrase=True)
        if opts.get("axis", "x") not in tuple(_AXES):
            raise SceneError(f"{where}.axis must be 'x', 'y' or 'z', got {opts['axis']!r}")
    if kind == "scene" and not isinstance(opts.get("scene"), str):
        raise SceneError(
            f"{where}.scene must name a built-in scene or a scene file, got {opts.get('scene')!r}"
        )
    if "metric" in opts and opts["metric"] not in METRICS:
        raise SceneError(f"{where}.metric must be one of {list(METRICS)}, got {opts['metric']!r}")
    if "eta" in opts:
        number(opts["eta"], f"{where}.eta", positive=True, phrase=True)


def _parse_quantity(q: str, where: str) -> tuple[str, tuple[int, ...]]:
    """``'strain_xy'`` -> ('strain', (0, 1)); scalars -> (name, ())."""
    if q in ("broken_bonds", "first_break_load", "damage"):
        return q, ()
    name, _, comp = q.rpartition("_")
    if name not in _FIELDS or not comp or any(c not in _AXES for c in comp):
        raise SceneError(
            f"{where}.quantity must be a field component such as 'displacement_x', "
            "'strain_xy', 'stress_yy', 'deformation_gradient_xx', 'reaction_x', "
            "'homogenized_stress_xy', or 'broken_bonds', 'damage', 'first_break_load'; "
            f"got {q!r}"
        )
    idx = tuple(_AXES.index(c) for c in comp)
    want = 1 if name in ("displacement", "reaction") else 2
    if len(idx) != want:
        raise SceneError(f"{where}.quantity {q!r} needs {want} component letter(s)")
    return name, idx


# --- evaluation --------------------------------------------------------------------------


def _region(check: Check, cloud: Any) -> np.ndarray:
    o = check.options
    given = [k for k in ("set", "box", "points") if k in o]
    if len(given) > 1:
        raise SceneError(f"{check.where} takes one of set / box / points, got {given}")
    if not given:
        return np.arange(cloud.n)
    key = given[0]
    if key == "box":
        box = np.asarray(o["box"], dtype=float)
        if box.shape != (2, cloud.dim):
            raise SceneError(
                f"{check.where}.box must be [[lower...], [upper...]] with {cloud.dim} "
                f"coordinates each, got {o['box']!r}"
            )
        try:  # NaN corners and inverted boxes raise (-inf / inf are open sides)
            idx = cloud.select(box=(box[0], box[1]))
        except PdlinError as exc:
            raise SceneError(f"{check.where}.box: {exc}") from exc
    else:
        try:
            idx = np.asarray(cloud.select(o[key]), dtype=np.int64)
        except Exception as exc:  # noqa: BLE001 - any selection error names the key
            raise SceneError(f"{check.where}.{key}: {exc}") from exc
    if idx.size == 0:
        raise SceneError(f"{check.where}.{key} selects no points")
    return idx


def _rel_range(u: np.ndarray, r: np.ndarray) -> float:
    span = np.ptp(r, axis=0)
    span = np.where(span > 0, span, 1.0)
    return float((np.abs(u - r).max(axis=0) / span).max())


def _metric(name: str) -> Any:
    if name == "rel-range":
        return _rel_range
    from ..sweeps.core import error_metric

    return error_metric(name)


class _Outcome:
    """Uniform access to static, nonlinear and damage results."""

    def __init__(self, scene: Any, result: Any) -> None:
        self.scene = scene
        self.result = result
        self.kind = (
            "explicit"  # pdlin.dynamics.ExplicitResult: its frames are the steps
            if hasattr(result, "step_times")
            else "damage"
            if hasattr(result, "first_break")
            else "nonlinear"
            if hasattr(result, "homogenized_stress")
            else "static"
        )

    @property
    def cloud(self) -> Any:
        if self.kind == "damage":
            return self.result.final.problem.cloud
        return self.result.problem.cloud

    def u(self, step: int = -1) -> np.ndarray:
        if self.kind == "static":
            return np.asarray(self.result.u)
        return np.asarray(self.result.u[step])

    def field(self, name: str, step: int, where: str) -> np.ndarray:
        r = self.result
        if name == "displacement":
            return self.u(step)
        if self.kind == "damage":
            if name == "damage":
                return np.asarray(r.damage[step])
            st = r.final
            if step not in (-1, r.n_steps - 1):
                raise SceneError(f"{where}: damage runs give {name} at the last step only")
            scale = float(r.factors[-1])
            if name == "reaction":
                return scale * np.asarray(st.reactions)
            return _static_field(st, name, scale)
        if self.kind == "explicit":
            if name == "damage" and r.damage is not None:
                return np.asarray(r.damage[step])
            if name != "damage":
                raise SceneError(f"{where}: explicit runs give displacement and damage")
        if self.kind == "nonlinear":
            if name == "reaction":
                return np.asarray(r.reactions[step])
            if name == "stress" and r.stress is not None:
                return np.asarray(r.stress[step])
            raise SceneError(f"{where}: nonlinear runs give displacement, reaction and stress")
        if name == "damage":
            raise SceneError(f"{where}: 'damage' needs a damage run ([damage] table)")
        if name == "reaction":
            return np.asarray(r.reactions)
        return _static_field(r, name, 1.0)


def _static_field(r: Any, name: str, scale: float) -> np.ndarray:
    if name == "strain":
        return scale * np.asarray(r.strain())
    if name == "stress":
        return scale * np.asarray(r.stress())
    F = np.asarray(r.deformation_gradient())
    eye = np.eye(F.shape[-1])
    return eye + scale * (F - eye)


_REDUCERS: dict[str, Callable[[np.ndarray], Any]] = {
    "mean": np.mean,
    "max": np.max,
    "min": np.min,
    "sum": np.sum,
    "max-abs": lambda a: np.max(np.abs(a)),
}


def _step_index(check: Check, n_steps: int) -> int:
    st = int(check.options.get("step", -1))
    if abs(st) > n_steps or st == 0:
        raise SceneError(f"{check.where}.step must be in 1..{n_steps} (or -1 = last), got {st}")
    return st - 1 if st > 0 else st


def _value(check: Check, out: _Outcome) -> CheckResult:
    o = check.options
    name, idx = _parse_quantity(check.quantity, check.where)
    if out.kind == "static" and "step" in o:
        raise SceneError(f"{check.where}.step needs a load-stepped (nonlinear or damage) run")
    scalar = name in ("broken_bonds", "first_break_load") or name == "homogenized_stress"
    extra = [k for k in ("reduce", "set", "box", "points") if k in o]
    if scalar and extra:
        raise SceneError(
            f"{check.where}.{extra[0]} does not apply to {check.quantity!r} (one number per run "
            "or step, not a field)"
        )
    if name == "first_break_load" and "step" in o:
        raise SceneError(f"{check.where}.step does not apply to 'first_break_load'")
    n_steps = 1 if out.kind == "static" else int(out.result.n_steps)
    step = _step_index(check, n_steps) if out.kind != "static" else -1
    r = out.result
    if name == "broken_bonds" or name == "first_break_load":
        if out.kind == "explicit" and name == "broken_bonds":
            c = float(r.broken[r.frame_steps[step]])
        elif out.kind != "damage":
            raise SceneError(f"{check.where}: {name!r} needs a damage run ([damage] table)")
        else:
            c = float(r.broken[step]) if name == "broken_bonds" else float(r.first_break)
    elif check.quantity.startswith("homogenized_stress_"):
        if out.kind != "nonlinear" or r.homogenized_stress is None:
            raise SceneError(f"{check.where}: {check.quantity!r} needs a nonlinear run")
        c = float(r.homogenized_stress[step][idx])
    else:
        values = out.field(name, step, check.where)
        sel = _region(check, out.cloud)
        v = values[sel]
        v = v[(slice(None),) + idx] if idx else v
        red = o.get("reduce", "sum" if name == "reaction" else "mean")
        c = float(_REDUCERS[red](v))
    e = float(o["expected"])
    if "atol" in o or e == 0.0:
        if "atol" not in o:
            raise SceneError(f"{check.where}: expected = 0 needs an absolute tolerance 'atol'")
        err = abs(c - e)
        return CheckResult(check, c, e, err, bool(err <= check.tolerance), "abs. error")
    err = abs(c - e) / abs(e)
    return CheckResult(check, c, e, err, bool(err <= check.tolerance), "rel. error")


def _field_result(check: Check, u: np.ndarray, ref: np.ndarray) -> CheckResult:
    metric = check.options.get("metric", "rel-max")
    err = float(_metric(metric)(u, ref))
    if not np.isfinite(err):
        raise SceneError(f"{check.where}: the error is not finite (NaN in the solution?)")
    computed = float(np.linalg.norm(u, axis=1).max())
    reference = float(np.linalg.norm(ref, axis=1).max())
    return CheckResult(
        check, computed, reference, err, bool(err <= check.tolerance), f"{metric} error"
    )


def _affine(F: np.ndarray, center: Any, translation: Any, X: np.ndarray, where: str) -> np.ndarray:
    d = X.shape[1]
    if F.shape != (d, d):
        raise SceneError(f"{where}.F must be {d} x {d} for this {d}D scene, got {F.shape}")
    c = np.zeros(d) if center is None else np.asarray(center, dtype=float)
    t = np.zeros(d) if translation is None else np.asarray(translation, dtype=float)
    if c.shape != (d,) or t.shape != (d,):
        raise SceneError(f"{where}.center / translation must have {d} coordinates")
    return np.asarray((X - c) @ (F - np.eye(d)).T + t)


def uniaxial_F(axis: str, strain: float, nu: float, dim: int) -> np.ndarray:
    """Deformation gradient of uniaxial stress: ``ε`` along ``axis``, ``-ν ε`` across.

    Parameters
    ----------
    axis : {'x', 'y', 'z'}
        The loaded axis.
    strain : float
        Axial strain ``ε``.
    nu : float
        Poisson's ratio ``ν``.
    dim : int
        Dimension (1, 2 or 3).

    Returns
    -------
    numpy.ndarray
        ``F = I + ε e⊗e - ν ε (I - e⊗e)``, shape ``(dim, dim)``.

    Examples
    --------
    >>> uniaxial_F("x", 1e-3, 0.25, 2).tolist()
    [[1.001, 0.0], [0.0, 0.99975]]
    """
    a = _AXES.index(axis)
    F = np.eye(dim) * (1.0 - nu * strain)
    F[a, a] = 1.0 + strain
    return F


def _closed_form(check: Check, out: _Outcome) -> CheckResult:
    o = check.options
    X = out.cloud.points
    sel = _region(check, out.cloud)
    if check.kind == "closed-form":
        F = _matrix(o["F"], f"{check.where}.F")
    else:
        eps = float(o["strain"]) if "strain" in o else float(o["stress"]) / float(o["E"])
        if o.get("axis", "x") not in _AXES[: X.shape[1]]:
            raise SceneError(
                f"{check.where}.axis {o['axis']!r} is not an axis of a {X.shape[1]}D scene"
            )
        F = uniaxial_F(o.get("axis", "x"), eps, float(o["nu"]), X.shape[1])
    ref = _affine(F, o.get("center"), o.get("translation"), X[sel], check.where)
    return _field_result(check, out.u()[sel], ref)


def _case_reference(check: Check, out: _Outcome) -> CheckResult:
    case = getattr(out.scene, "case", None)
    if case is None:
        raise SceneError(
            f"{check.where}.kind = 'reference' needs a scene built from a bundled problem "
            "([problem] factory = ...)"
        )
    X = out.cloud.points
    if case.exact is not None:
        ref = np.asarray(case.exact(X))
    elif case.reference is not None:
        ref = np.asarray(case.reference() if callable(case.reference) else case.reference)
    else:
        raise SceneError(f"{check.where}: the bundled problem has no reference")
    sel = case.measure if case.measure is not None else np.arange(X.shape[0])
    if any(k in check.options for k in ("set", "box", "points")):
        sel = np.intersect1d(sel, _region(check, out.cloud))
    return _field_result(check, out.u()[sel], ref[sel])


def _other_scene(check: Check, out: _Outcome) -> CheckResult:
    from ..static import solve
    from .scene import builtin_scene, list_builtin_scenes, load_scene, scene_from_dict

    name = check.options["scene"]
    base = getattr(out.scene, "base_dir", None) or Path.cwd()
    path = Path(name) if Path(name).is_absolute() else Path(base) / name
    if name.endswith(".toml") and path.exists():
        other = load_scene(path)
    elif name in list_builtin_scenes(hidden=True):
        other = scene_from_dict(builtin_scene(name)[0], Path.cwd())
    else:
        raise SceneError(
            f"{check.where}.scene: no scene file {str(path)!r} and no built-in scene {name!r}"
        )
    if other.nonlinear is not None:
        raise SceneError(f"{check.where}.scene must be a linear static scene")
    res = solve(other.problem, solver=other.solver, rtol=other.rtol, maxiter=other.maxiter)
    X = out.cloud.points
    from scipy.spatial import cKDTree

    dist, near = cKDTree(other.cloud.points).query(X)
    h = float(np.median(np.asarray(out.cloud.spacing))) if hasattr(out.cloud, "spacing") else 1.0
    if np.any(dist > 1e-8 * max(h, 1e-300)):
        raise SceneError(
            f"{check.where}.scene: {int(np.count_nonzero(dist > 1e-8 * h))} point(s) of this "
            f"scene are not points of {name!r} (largest distance {float(dist.max()):.3g})"
        )
    sel = _region(check, out.cloud)
    return _field_result(check, out.u()[sel], np.asarray(res.u)[near[sel]])


def _material_point(check: Check, out: _Outcome) -> CheckResult:
    from ..constitutive.crystal_plasticity import CrystalPlasticity, material_point

    r = out.result
    if out.kind != "nonlinear" or r.homogenized_stress is None:
        raise SceneError(f"{check.where}: kind = 'material-point' needs a nonlinear run")
    model = out.scene.problem.model
    mat = getattr(model, "material", None)
    if not isinstance(mat, CrystalPlasticity):
        raise SceneError(f"{check.where}: kind = 'material-point' needs a crystal-plasticity scene")
    orient = np.asarray(mat.orientation)
    if orient.ndim > 0 and orient.size > 1 and not np.allclose(orient, orient.ravel()[0]):
        raise SceneError(
            f"{check.where}: kind = 'material-point' needs a single crystal (one orientation)"
        )
    times = np.asarray(r.times, dtype=float)
    steps = times.size
    eta = float(check.options.get("eta", 0.002))
    loading = check.options.get("loading", "shear")
    if not np.allclose(times, np.arange(1, steps + 1)):
        raise SceneError(
            f"{check.where}: the material-point driver runs at t = 1..steps; set "
            f"solver.t_end = solver.steps (got times {times[:3].tolist()}...)"
        )
    o1 = np.atleast_1d(orient.ravel()[0]) if orient.ndim == 1 and orient.size > 1 else None
    mp = material_point(mat, loading, steps=steps, eta=eta, orientation=o1)
    ref = mp.stress[:, 0]
    pd = np.asarray(r.homogenized_stress)
    err = float(np.abs(pd - ref).max() / max(float(np.abs(ref).max()), 1e-300))
    return CheckResult(
        check,
        float(np.abs(pd[-1]).max()),
        float(np.abs(ref[-1]).max()),
        err,
        bool(err <= check.tolerance),
        "rel-max error over all steps",
    )


_EVAL = {
    "value": _value,
    "closed-form": _closed_form,
    "closed-form-uniaxial": _closed_form,
    "reference": _case_reference,
    "scene": _other_scene,
    "material-point": _material_point,
}


def check_before_run(checks: list[Check], scene: Any) -> None:
    """Refuse, before the solve, the checks that cannot apply to ``scene``'s run.

    A region that selects no point, a quantity or a ``step`` the kind of run (static,
    damage, nonlinear) does not give: :func:`evaluate_checks` would find them only after
    the work.

    Parameters
    ----------
    checks : list of Check
        The scene's parsed checks.
    scene : Scene
        The scene about to run (prepared: its problem is the one solved).

    Raises
    ------
    SceneError
        Naming the check, as :func:`evaluate_checks` would.
    """
    kind = (
        "damage"
        if scene.damage is not None
        else "nonlinear"
        if scene.nonlinear is not None
        else "static"
    )
    cloud = scene.problem.cloud
    for check in checks:
        o = check.options
        if any(k in o for k in ("set", "box", "points")):
            _region(check, cloud)
        if check.kind != "value":
            continue
        where = check.where
        name, _ = _parse_quantity(check.quantity, where)
        if kind == "static" and "step" in o:
            raise SceneError(f"{where}.step needs a load-stepped (nonlinear or damage) run")
        if name in ("broken_bonds", "first_break_load", "damage") and kind != "damage":
            raise SceneError(f"{where}: {name!r} needs a damage run ([damage] table)")
        if name == "homogenized_stress" and kind != "nonlinear":
            raise SceneError(f"{where}: {check.quantity!r} needs a nonlinear run")
        if kind == "nonlinear" and name not in (
            "displacement", "reaction", "stress", "homogenized_stress",
        ):  # fmt: skip
            raise SceneError(f"{where}: nonlinear runs give displacement, reaction and stress")


def evaluate_checks(checks: list[Check], scene: Any, result: Any) -> list[CheckResult]:
    """Evaluate parsed checks on a run's result (static, nonlinear or damage).

    Parameters
    ----------
    checks : list of Check
        Parsed checks (:func:`parse_checks`).
    scene : Scene
        The scene that was run.
    result : StaticResult, NonlinearResult or DamageResult
        Its result.

    Returns
    -------
    list of CheckResult
        One per check, in order.

    Raises
    ------
    SceneError
        A check that cannot be evaluated on this result (naming it); a ``scene`` check
        whose other scene cannot be loaded or does not share this scene's points.

    Examples
    --------
    >>> import pdlin
    >>> from pdlin.scene import scene_from_dict
    >>> sc = scene_from_dict({
    ...     "geometry": {"type": "grid", "shape": [20], "spacing": 0.05},
    ...     "material": {"E": 2.0}, "horizon": {"ratio": 3.015},
    ...     "shadow": {"F": [[1.001]]},
    ...     "check": [{"kind": "closed-form", "F": [[1.001]], "tolerance": 1e-8,
    ...                "source": "affine patch test"}]})
    >>> res = pdlin.solve(sc.problem, solver="direct")
    >>> [r.passed for r in evaluate_checks(sc.checks, sc, res)]
    [True]
    """
    out = _Outcome(scene, result)
    return [_EVAL[c.kind](c, out) for c in checks]
