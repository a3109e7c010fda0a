"""The ``pdlin`` command: ``run``, ``info``, ``sparsity``, ``tradeoff``, ``examples``, ``plot``.

Only this layer prints; the library logs.  ``main(argv)`` returns an exit
code and can be called from tests.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import os
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PdlinError

__all__ = ["main"]


class _Progress:
    """Stage messages with elapsed time on stderr."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.t0 = time.perf_counter()
        self.last: str | None = None

    def __call__(self, msg: str) -> None:
        if self.quiet:
            return
        t = time.perf_counter() - self.t0
        print(f"[{t:8.2f} s] {msg} ...", file=sys.stderr, flush=True)


def _plan(problem: Any, prog: Any, solver: str, steps: int, nonlinear: bool = False) -> None:
    """Print the memory estimate of a load-stepping run and refuse it when it does not fit."""
    from ..problem import memory_hints, plan_memory
    from ..resources import LATE_IMPORTS, NONLINEAR_LATE_IMPORTS, check_memory, current_rss

    plan = plan_memory(problem, solver, history_steps=steps)
    if nonlinear:  # the material kernels' compile replaces the linear models' one
        from ..constitutive.crystal_plasticity import compiles_kernels

        compiles = compiles_kernels(problem.cloud.n)  # imports no numba
        plan.base = current_rss() + LATE_IMPORTS + (NONLINEAR_LATE_IMPORTS if compiles else 0)
    prog(plan.summary())
    check_memory("this run", plan.need, lambda: memory_hints(plan))


def _bytes_so_far(out: Path) -> int:
    """Count the bytes written so far for ``out``.

    The file, or the writers' staging directory (``.NAME.*.partial`` beside it,
    :mod:`pdlin.io.results`).
    """
    staged = [f for d in out.parent.glob(f".{out.name}.*.partial") for f in d.iterdir()]
    total = 0
    for f in staged or [out]:  # the old file, if any, stays until the new one replaces it
        try:
            total += f.stat().st_size if f.is_file() else 0
        except OSError:
            pass
    return total


@contextlib.contextmanager
def _write_progress(out: Path, prog: Any) -> Iterator[None]:
    """Report the bytes written every few seconds while the body writes ``out``."""
    from .._progress import Throttle
    from ..resources import format_bytes

    done = threading.Event()
    tick = Throttle(prog)

    def watch() -> None:
        while not done.wait(0.5):
            tick(lambda: f"  writing: {format_bytes(_bytes_so_far(out))} so far")

    th = threading.Thread(target=watch, daemon=True)
    th.start()
    try:
        yield
    finally:
        done.set()
        th.join()


def _with_write(summary: dict[str, Any], t_write: float) -> dict[str, Any]:
    """``summary`` with ``timings['write']`` and a total that covers the write as well."""
    tim = {k: v for k, v in summary["timings"].items() if k != "total"}
    tim["write"] = round(t_write, 4)
    tim["total"] = round(summary["timings"].get("total", 0.0) + t_write, 4)
    summary["timings"] = tim
    return summary


def _timings_line(summary: dict[str, Any]) -> str:
    """Format the ``time (s)`` line of a run's printed summary: every stage, then the total."""
    return "time (s)     " + ", ".join(f"{k} {v:.3f}" for k, v in summary["timings"].items())


def _size(path: Path) -> str:
    """Bytes written to ``path`` (a file), human readable."""
    from ..resources import format_bytes

    try:
        return format_bytes(path.stat().st_size)
    except OSError:
        return "?"


def _load(args: argparse.Namespace) -> Any:
    from ..scene.scene import builtin_scene, load_scene, scene_from_dict

    if getattr(args, "example", None):
        data, _ = builtin_scene(args.example)
        return scene_from_dict(data, Path.cwd())
    if not args.scene:
        raise PdlinError("give a scene file or --example NAME")
    if Path(args.scene).suffix.lower() in (".yaml", ".yml", ".xml"):
        from ..scene.decks import read_deck  # Peridigm / PeriLab input decks

        return read_deck(args.scene, kinematics=getattr(args, "kinematics", None) or "auto")
    if getattr(args, "kinematics", None):
        raise PdlinError("--kinematics applies to Peridigm decks (.yaml, .xml)")
    return load_scene(args.scene)


def _check_out(path: str | Path, suffixes: Sequence[str], what: str) -> Path:
    """Suffix, optional library and writable folder of an output, before the work."""
    from ..io.output import check_output

    return check_output(path, suffixes, what)


def _check_figure(path: str | Path, what: str) -> Path:
    from ..plotting import check_figure

    return check_figure(path, what)


def _homogenized_path(args: argparse.Namespace, scene: Any, out: Path) -> Path:
    """Choose the homogenized CSV of a nonlinear run.

    ``<out stem>_homogenized.csv`` beside the ``-o`` result (where ``pdlin plot`` looks
    for it), else ``output.homogenized`` or that default beside ``output.path``.
    """
    if args.output or scene.homogenized is None:
        return out.with_name(f"{out.stem}_homogenized.csv")
    return Path(scene.homogenized)


def _check_run_outputs(args: argparse.Namespace, scene: Any) -> None:
    """Every file ``pdlin run`` writes for ``scene``, checked before the solve."""
    from ..io.results import SERIES_SUFFIXES, SUPPORTED_SUFFIXES

    what = "-o/--output" if args.output else "output.path"
    if scene.nonlinear is not None:
        out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.pvd"))
        _check_out(out, SERIES_SUFFIXES, f"{what} (a nonlinear run's time series)")
        csv_path = _homogenized_path(args, scene, out)
        _check_out(csv_path, (".csv",), "output.homogenized")
        if getattr(scene, "compare", None):
            from .compare import cpfe_paths

            fe_out, fe_csv = cpfe_paths(scene, out)
            _check_out(fe_out, SERIES_SUFFIXES, "compare.cpfe.output (the CPFE time series)")
            _check_out(fe_csv, (".csv",), "compare.cpfe.homogenized")
    else:
        out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.vtu"))
        _check_out(out, SUPPORTED_SUFFIXES, what)


def _cmd_run(args: argparse.Namespace) -> int:
    from ..io.results import SERIES_SUFFIXES, SUPPORTED_SUFFIXES, write_result
    from ..static import solve

    prog = _Progress(args.quiet)
    prog("reading scene")
    chosen: dict[str, Any] | None = None
    if args.select:
        if not args.scene:
            raise PdlinError("--select needs a scene file with a [tradeoff] table")
        from ..scene.tradeoff import select_scene

        if args.output:  # before the sweep; the kind of run is known after it
            _check_out(args.output, tuple({*SUPPORTED_SUFFIXES, *SERIES_SUFFIXES}), "-o/--output")

        prog("measuring the scene's [tradeoff] sweep (finished points are reused)")
        scene, chosen, _ = select_scene(args.scene, target_error=args.target_error)
        prog(f"fastest configuration meeting the target: {chosen}")
    else:
        scene = _load(args)
    if getattr(scene, "explicit", None) is not None:  # [solver] kind = "explicit"
        from .explicit import run_explicit

        return run_explicit(args, scene, prog)
    if args.resume and scene.nonlinear is None:
        raise PdlinError("--resume needs a nonlinear scene with solver.checkpoint")
    _check_run_outputs(args, scene)
    scene.prepare()  # work loading deferred to the run (a [subregion] coarse solve)
    if scene.checks:
        from ..scene.checks import check_before_run

        check_before_run(scene.checks, scene)
    if scene.nonlinear is not None and scene.steps:  # a deck with Peridigm's finite kinematics
        from .finite_steps import run_finite_steps

        return run_finite_steps(args, scene, prog)
    if scene.nonlinear is not None:
        return _run_nonlinear(args, scene, prog)
    if scene.damage is not None:
        return _run_damage(args, scene, prog)
    if scene.steps:  # a deck with several load steps: one solve each, one time series
        from .steps import run_load_steps

        return run_load_steps(args, scene, prog)
    solver = args.solver or scene.solver
    extra: dict[str, Any] = (
        {"operator": chosen["operator"]} if chosen and "operator" in chosen else {}
    )
    writer = True
    backend = args.backend or scene.backend
    if backend != "scipy":  # under mpiexec every rank solves, rank 0 writes
        from ..backends.petsc import comm_rank_size

        extra.update(backend=backend, petsc_options=scene.petsc_options)
        writer = comm_rank_size()[0] == 0
        if not writer:
            prog = _Progress(True)
    result = solve(
        scene.problem,
        solver=solver,
        rtol=scene.rtol,
        maxiter=scene.maxiter,
        progress=prog,
        direct_backend=scene.direct_backend,
        **extra,
    )
    out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.vtu"))
    if not writer:
        return 0
    prog(f"writing {out}")
    t_write = time.perf_counter()
    fields = result.fields()
    if scene.fields:
        missing = [f for f in scene.fields if f not in fields]
        if missing:
            raise PdlinError(
                f"output.fields: unknown field(s) {missing}; available {sorted(fields)}"
            )
        fields = {k: fields[k] for k in scene.fields}
    from ..io.results import write_points

    with _write_progress(out, prog):
        if scene.fields:
            write_points(out, scene.cloud, fields, time=scene.time)
        else:
            write_result(out, result, time=scene.time)
    t_write = time.perf_counter() - t_write
    prog(f"wrote {_size(out)} in {t_write:.1f} s")
    summary = _with_write(result.summary(), t_write)
    summary["scene"] = scene.name
    if chosen is not None:
        summary["selected"] = {
            k: (v if isinstance(v, int | float | str) else str(v)) for k, v in chosen.items()
        }
    if scene.calibration is not None:
        summary["calibration"] = _calibration_summary(scene.calibration)
    if scene.subregion is not None:
        summary["subregion"] = {k: v for k, v in scene.subregion.items() if k != "interior"}
    summary["output"] = str(out)
    checks = _checks(scene, result, summary, prog)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        u = summary["max_abs_u"]
        print(f"scene        {scene.name}")
        if chosen is not None:
            print("selected     " + ", ".join(f"{k} = {v}" for k, v in summary["selected"].items()))
        print(f"points       {summary['points']:,} ({summary['dim']}D), bonds {summary['bonds']:,}")
        if scene.subregion is not None:
            sr = summary["subregion"]
            print(
                f"subregion    {sr['free_points']:,} free + {sr['points'] - sr['free_points']:,} "
                f"driven of {sr['whole_body_points']:,} points; driver: {sr['coarse_points']:,}"
                f"-point solve at h = {sr['coarse_spacing']:.4g} ({sr['t_coarse']:.3f} s)"
            )
        print(
            f"solver       {summary['solver']}"
            + (f" ({summary['direct_backend']})" if "direct_backend" in summary else "")
            + f": {summary['iterations']} iteration(s), "
            f"relative residual {summary['relative_residual']:.2e}"
        )
        print("max |u|      " + ", ".join(f"{v:.6e}" for v in u))
        print(_timings_line(summary))
        print(f"results      {out}")
        if scene.calibration is not None:
            cal = summary["calibration"]
            print(f"calibration  {_calibration_line(cal)}")
        _print_checks(checks)
    return _check_status(args, checks)


def _checks(scene: Any, result: Any, summary: dict[str, Any], prog: Any) -> list[Any]:
    """Evaluate the scene's [[check]] tables; add them to the summary."""
    if not scene.checks:
        return []
    from ..scene.checks import evaluate_checks

    prog(f"checking {len(scene.checks)} reference(s)")
    res = evaluate_checks(scene.checks, scene, result)
    summary["checks"] = [
        {
            "kind": r.check.kind,
            "quantity": r.check.quantity,
            "computed": r.computed,
            "reference": r.reference,
            "error": r.error,
            "measure": r.measure,
            "tolerance": r.check.tolerance,
            "source": r.check.source,
            "passed": r.passed,
        }
        for r in res
    ]
    return res


def _print_checks(checks: list[Any]) -> None:
    for r in checks:
        print(r.line())


def _check_status(args: argparse.Namespace, checks: list[Any]) -> int:
    """Exit code: 5 when a check failed and --strict was given, else 0."""
    failed = [r for r in checks if not r.passed]
    if failed and not getattr(args, "json", False):
        print(f"{len(failed)} of {len(checks)} check(s) FAILED", file=sys.stderr)
    return 5 if failed and getattr(args, "strict", False) else 0


def _run_damage(args: argparse.Namespace, scene: Any, prog: Any) -> int:
    """``pdlin run`` on a scene with a [damage] table: load steps with bond breaking."""
    from ..fracture import solve_damage
    from ..io.results import write_points

    opts = dict(scene.damage)
    if args.solver:
        opts["solver"] = args.solver
    _plan(scene.problem, prog, opts.get("solver", "auto"), int(opts.get("steps", 10)))
    result = solve_damage(scene.problem, progress=prog, **opts)
    out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.vtu"))
    prog(f"writing {out}")
    t_write = time.perf_counter()
    with _write_progress(out, prog):
        write_points(
            out,
            scene.cloud,
            {"displacement": result.u[-1], "damage": result.damage[-1]},
        )
    t_write = time.perf_counter() - t_write
    prog(f"wrote {_size(out)} in {t_write:.1f} s")
    summary = _with_write(result.summary(), t_write)
    summary["scene"] = scene.name
    summary["output"] = str(out)
    checks = _checks(scene, result, summary, prog)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"scene        {scene.name}")
        print(
            f"load steps   {summary['steps']}, {summary['linear_solves']} linear solve(s), "
            f"critical stretch {summary['critical_stretch']:.6g}"
        )
        print(
            "broken bonds " + ", ".join(str(int(b)) for b in result.broken) + " (cumulative, "
            f"per step); max damage {summary['max_damage']:.4f}"
        )
        fb = summary["first_break_load"]
        print(f"first break  at load factor {fb:.6g}" if np.isfinite(fb) else "first break  none")
        if result.stopped:
            print(f"stopped      {result.stopped}")
        print(_timings_line(summary))
        print(f"results      {out}")
        _print_checks(checks)
    return _check_status(args, checks)


def _stress_components(sig: np.ndarray, model: Any = None) -> str:
    """Format a symmetric ``(d, d)`` stress as ``sxx 2.8 MPa, syy ..., sxy ...``.

    The unit is MPa for a :class:`~pdlin.CrystalPlasticity` material with its default
    (MPa) elastic constants; otherwise the stress is in the units of the given constants.

    Examples
    --------
    >>> import numpy as np
    >>> _stress_components(np.array([[2.8, 13.25], [13.25, -0.5]]))
    'sxx 2.8, syy -0.5, sxy 13.25 (units of the elastic constants)'
    """
    from ..constitutive import CrystalPlasticity

    s = np.asarray(sig, dtype=float)
    d = s.shape[0]
    pairs = [(i, i) for i in range(d)] + [(i, j) for i in range(d) for j in range(i + 1, d)]
    mat = getattr(model, "material", None)
    default = isinstance(mat, CrystalPlasticity) and np.array_equal(
        mat.C, CrystalPlasticity(mat.slip, c_over_a=mat.c_over_a, shear=mat.shear).C
    )
    unit = " MPa" if default else ""
    text = ", ".join(f"s{'xyz'[i]}{'xyz'[j]} {s[i, j]:.4g}{unit}" for i, j in pairs)
    return text if default else f"{text} (units of the elastic constants)"


def _run_nonlinear(args: argparse.Namespace, scene: Any, prog: Any) -> int:
    """``pdlin run`` on a nonlinear scene: load steps, one time series and a CSV."""
    from ..io.results import write_homogenized_csv, write_nonlinear
    from ..nonlinear import solve_nonlinear

    opts = dict(scene.nonlinear)
    if args.solver:
        opts["linear_solver"] = args.solver
    if args.resume:
        if "checkpoint" not in opts:
            raise PdlinError("--resume needs solver.checkpoint in the scene")
        opts["resume"] = True
    _plan(scene.problem, prog, "auto", int(opts.get("steps", 1)), nonlinear=True)
    result = solve_nonlinear(scene.problem, progress=prog, **opts)
    out = Path(args.output) if args.output else (scene.output or Path(f"{scene.name}.pvd"))
    prog(f"writing {out}")
    t_write = time.perf_counter()
    with _write_progress(out, prog):
        series = write_nonlinear(out, result)
    csv_path = _homogenized_path(args, scene, out)
    write_homogenized_csv(csv_path, result)
    t_write = time.perf_counter() - t_write
    prog(f"wrote {series} and {csv_path} in {t_write:.1f} s")
    summary = _with_write(result.summary(), t_write)
    summary["scene"] = scene.name
    summary["output"] = str(series)
    summary["homogenized"] = str(csv_path)
    if result.homogenized_stress is not None:
        summary["final_homogenized_stress"] = result.homogenized_stress[-1].tolist()
    checks = _checks(scene, result, summary, prog)
    cmp = None
    if getattr(scene, "compare", None):
        from .compare import cpfe_summary, run_cpfe

        fe, fe_series, fe_csv, fe_write = run_cpfe(scene, series, prog)
        cmp = summary["cpfe"] = cpfe_summary(scene, result, fe, fe_series, fe_csv)
        cmp["timings"]["write"] = round(fe_write, 4)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"scene        {scene.name}")
        print(
            f"load steps   {summary['steps']} ({', '.join(summary['methods'])}): "
            f"{summary['iterations']} iteration(s), {summary['cutbacks']} cut-back(s), "
            f"{summary['fallbacks']} ADR fallback(s)"
        )
        if result.homogenized_stress is not None:
            print(
                "mean stress  "
                + _stress_components(result.homogenized_stress[-1], scene.problem.model)
            )
        print(_timings_line(summary))
        print(f"results      {series} (time series), {csv_path} (homogenized)")
        if cmp is not None:
            from .compare import print_cpfe

            print_cpfe(cmp)
        _print_checks(checks)
    status = _check_status(args, checks)
    if cmp is not None and cmp.get("passed") is False:
        if not args.json:
            print("the CPPD vs CPFE comparison FAILED its tolerance", file=sys.stderr)
        return 5 if args.strict else status
    return status


def _cmd_export(args: argparse.Namespace) -> int:
    from ..io.results import export_system

    _check_out(args.output, (".mtx", ".npz"), "-o/--output")
    scene = _load(args)
    out = export_system(args.output, scene.problem, eliminated=not args.unconstrained)
    kind = "K, f (unconstrained)" if args.unconstrained else "A, b (Dirichlet eliminated)"
    print(f"wrote {out} ({kind}, {scene.cloud.n * scene.cloud.dim:,} DOFs)")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from ..geometry.bonds import find_bonds

    path = Path(args.mesh)
    if path.suffix in (".toml", ".yaml", ".yml", ".xml"):
        from ..scene.decks import read_deck
        from ..scene.scene import load_scene

        scene = load_scene(path) if path.suffix == ".toml" else read_deck(path)
        cloud = scene.cloud
        bonds = scene.bonds()
    else:
        from ..geometry.mesh import read_mesh

        cloud = read_mesh(path, volume=args.volume)
        if args.horizon is not None:
            bonds = find_bonds(cloud, args.horizon)
        else:
            bonds = find_bonds(cloud, ratio=args.ratio)
    fs = bonds.family_size
    h = bonds.horizon
    vol = cloud.volumes
    info = {
        "points": cloud.n,
        "dim": cloud.dim,
        "total_volume": float(vol.sum()),
        "volume_min_mean_max": [float(vol.min()), float(vol.mean()), float(vol.max())],
        "bonds": bonds.n_bonds,
        "bonds_per_point_min_mean_max": [int(fs.min()), float(fs.mean()), int(fs.max())],
        "horizon_min_mean_max": [float(h.min()), float(h.mean()), float(h.max())],
        "bounds": [cloud.bounds[0].tolist(), cloud.bounds[1].tolist()],
        "sets": {k: int(v.size) for k, v in sorted(cloud.sets.items())},
    }
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        for k, v in info.items():
            print(f"{k:30s} {v}")
    return 0


def _cmd_sparsity(args: argparse.Namespace) -> int:
    from ..analysis.sparsity import sparsity_report
    from ..constraints import resolve_dirichlet

    scene = _load(args)
    bonds = scene.bonds()
    # the constrained system: the scene's Dirichlet DOFs are eliminated (K_ff beside K)
    fixed = resolve_dirichlet(scene.cloud, scene.problem.dirichlet)[0]
    rep = sparsity_report(
        model=scene.model,
        cloud=scene.cloud,
        bonds=bonds,
        fixed_dofs=fixed,
        numeric=args.numeric,
        fill_limit=args.fill_limit,
    )
    if args.json:
        print(json.dumps(rep.to_dict(), indent=2))
    else:
        print(rep)
    return 0


def _calibration_summary(res: Any) -> dict[str, Any]:
    err = np.asarray(res.relative_error, dtype=float)
    fam = getattr(res, "family_of_point", None)
    cut = {}
    if err.ndim and fam is not None and 0 < int(np.sum(fam < 0)) < fam.size:
        # boundary 'bulk' / 'interior-mean': only complete families are calibrated; the
        # others (families cut by a free face) keep bulk values and fit the target in part
        cut = {
            "calibrated_points": int(np.sum(fam >= 0)),
            "calibrated_error": float(err[fam >= 0].max()),
            "cut_family_points": int(np.sum(fam < 0)),
        }
    return {
        "status": res.status,
        "relative_error": float(err.max()) if err.ndim else float(err),
        **cut,
        "rank": int(res.rank) if np.ndim(res.rank) == 0 else None,
        "bonds": int(res.n_bonds),
        "c_min_max_mean": [float(res.c_min), float(res.c_max), float(res.c_mean)],
        "zero_micromoduli": int(res.n_zero),
        "zero_threshold": float(res.zero_threshold),
        "message": res.message,
        "time_s": round(float(res.time), 4),
    }


def _calibration_line(cal: dict[str, Any]) -> str:
    """Format the summary's calibration line: where the largest tensor error is and why.

    Examples
    --------
    >>> _calibration_line({"status": "step1", "relative_error": 0.563, "calibrated_points":
    ...     476, "calibrated_error": 7.9e-16, "cut_family_points": 324})  # doctest: +ELLIPSIS
    'step1, relative tensor error 7.900e-16 at the 476 points ... up to 5.630e-01 at the 324 ...'
    """
    if "calibrated_points" not in cal:
        return f"{cal['status']}, max relative tensor error {cal['relative_error']:.3e}"
    return (
        f"{cal['status']}, relative tensor error {cal['calibrated_error']:.3e} at the "
        f"{cal['calibrated_points']:,} points with complete families; up to "
        f"{cal['relative_error']:.3e} at the {cal['cut_family_points']:,} points whose "
        "families the boundary cuts (they keep the bulk micromoduli: the PD surface effect, "
        "not a calibration error)"
    )


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from ..scene.targets import load_calibration

    job = load_calibration(args.target)
    out = Path(args.output) if args.output else job.output
    if out is not None:
        _check_out(out, (".csv", ".npz"), "-o/--output" if args.output else "output.path")
    if job.plot is not None and not args.no_plot:
        _check_figure(job.plot, "output.plot")
    res = job.run()
    summary = _calibration_summary(res)
    summary["name"] = job.name
    if out is not None:
        from ..io.output import staging

        fam = job.family
        with staging(out) as st:  # atomic; a failed write names the file
            if out.suffix.lower() == ".csv":
                cols = [
                    np.asarray(fam.xi),
                    np.asarray(fam.omega)[:, None],
                    np.asarray(fam.volume)[:, None],
                    np.asarray(res.micromoduli)[:, None],
                ]
                head = ",".join([f"xi{k}" for k in range(fam.dim)] + ["omega", "volume", "c"])
                np.savetxt(st.main, np.hstack(cols), delimiter=",", header=head, comments="")
            else:
                with open(st.main, "wb") as fh:
                    np.savez(
                        fh,
                        xi=np.asarray(fam.xi),
                        omega=np.asarray(fam.omega),
                        volume=np.asarray(fam.volume),
                        micromoduli=np.asarray(res.micromoduli),
                        tensor=np.asarray(res.tensor),
                        target=np.asarray(res.target),
                    )
        summary["output"] = str(out)
    if job.plot is not None and not args.no_plot:
        from ..plotting import plot_micromoduli, save_figure, use_agg

        use_agg()

        ax = plot_micromoduli(res, job.family)
        save_figure(ax.figure, job.plot, dpi=120)
        summary["plot"] = str(job.plot)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        for k, v in summary.items():
            print(f"{k:18s} {v}")
    return 0 if res.status not in ("infeasible", "failed") else 4


def _cmd_examples(args: argparse.Namespace) -> int:
    from ..scene.scene import builtin_scene, list_builtin_scenes

    if args.show:
        print(builtin_scene(args.show)[1])
        return 0
    from ..scene.checks import parse_checks

    rows = []
    for name in list_builtin_scenes():
        data, _ = builtin_scene(name)
        about = data.get("about", {})
        checks = parse_checks(data["check"]) if "check" in data else []
        parts = [f"{c.quantity} vs {c.source}" for c in checks]
        cpfe = data.get("compare", {}).get("cpfe")
        if isinstance(cpfe, dict) and "tolerance" in cpfe:  # [compare.cpfe] with a tolerance
            parts.append(f"homogenized stress vs CPFE ({cpfe.get('integration', 'fbar')} elements)")
        verifies = "; ".join(parts) or "-"
        rows.append(
            {
                "name": name,
                "description": about.get("description", ""),
                "verifies": verifies,
                "runtime": about.get("runtime", ""),
            }
        )
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    for r in rows:
        print(f"{r['name']:22s} {r['description']}")
        print(f"{'':22s}   verifies: {r['verifies']}")
        print(f"{'':22s}   runtime:  {r['runtime']}")
    print("\nrun one with: pdlin run --example NAME   (show its scene: pdlin examples --show NAME)")
    return 0


def _cmd_tradeoff(args: argparse.Namespace) -> int:
    from ..scene.tradeoff import load_tradeoff

    if getattr(args, "example", None):
        from ..scene.scene import builtin_scene
        from ..scene.tradeoff import tradeoff_from_dict

        data, _ = builtin_scene(args.example)
        if "tradeoff" not in data:
            raise PdlinError(f"built-in scene {args.example!r} has no [tradeoff] table")
        sweep = tradeoff_from_dict(data, Path.cwd())
    elif not args.scene:
        raise PdlinError("give a scene file or --example NAME")
    else:
        sweep = load_tradeoff(args.scene)
    opts: dict[str, Any] = {"resume": args.resume}
    if args.output:
        opts["output"] = Path(args.output)
    table = opts.get("output", sweep.options.get("output"))
    if table is not None:
        what = "-o/--output" if args.output else "tradeoff.output"
        _check_out(table, (".csv", ".json", ".jsonl", ".ndjson"), what)
    fig_path = Path(args.plot) if args.plot else sweep.plot
    if fig_path is not None:
        _check_figure(fig_path, "--plot" if args.plot else "tradeoff.plot")
    if args.target_error is not None:
        opts["target_error"] = args.target_error
    if not args.quiet:
        t0 = time.perf_counter()

        def bar(done: int, total: int, row: dict[str, Any]) -> None:
            fill = int(30 * done / max(total, 1))
            err = row.get("error")
            e = f"{err:.3g}" if isinstance(err, float) and np.isfinite(err) else "-"
            print(
                f"[{'#' * fill}{'.' * (30 - fill)}] {done}/{total} {row['key']}: "
                f"{row.get('status')}, error {e}, {time.perf_counter() - t0:.1f} s",
                file=sys.stderr,
                flush=True,
            )

        opts["progress"] = bar
    result = sweep.run(**opts)
    target = opts.get("target_error", sweep.options.get("target_error"))
    if args.json:
        print(result.to_json())
    else:
        print(result.summary(target_error=target))
    out = opts.get("output", sweep.options.get("output"))
    if out is not None:
        print(f"table        {out}")
    plot = Path(args.plot) if args.plot else sweep.plot
    if plot is not None:
        result.plot(plot)
        print(f"plot         {plot}")
    return 0


def _check_plot_outputs(args: argparse.Namespace) -> None:
    """Check the library ``pdlin plot`` needs, its figure's suffix and folder, first."""
    from ..io.output import check_folder, need_module

    if args.render:
        need_module("pyvista", "render", "pdlin plot --render")
        kinds = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
        if args.output:
            _check_out(args.output, kinds, "-o/--output")
    else:
        need_module("matplotlib", "plotting", "pdlin plot")
        if args.output:
            _check_figure(args.output, "-o/--output")
    # the figures written beside the input (or in the working folder)
    base = Path(args.path).parent if args.path else Path.cwd()
    check_folder(base / "figure.png", "the figure beside the input")


def _cmd_plot(args: argparse.Namespace) -> int:
    from .. import plotting

    _check_plot_outputs(args)
    written: list[Path] = []
    if args.spy or args.sparsity_vs_horizon:
        args.scene = args.path
        scene = _load(args)
        stem = Path(args.path).stem if args.path else scene.name
        base = Path(args.path).parent if args.path else Path.cwd()
        if args.spy:
            plot = plotting.plot_scene_spy(scene, order=args.order)
            out = Path(args.output) if args.output else base / f"{stem}_spy.png"
            written.append(plotting.save_figure(plot.figure, out, dpi=args.dpi))
        if args.sparsity_vs_horizon:
            try:
                ratios = [float(v) for v in args.ratios.split(",")]
            except ValueError as exc:
                raise PdlinError(
                    f"--ratios must be comma-separated numbers, got {args.ratios!r}"
                ) from exc
            plot = plotting.plot_sparsity_vs_horizon(scene, ratios)
            out = (
                Path(args.output)
                if args.output and not args.spy
                else base / f"{stem}_sparsity_vs_horizon.png"
            )
            written.append(plotting.save_figure(plot.figure, out, dpi=args.dpi))
    else:
        if not args.path:
            raise PdlinError("give a result file, or --spy / --sparsity-vs-horizon with a scene")
        from ..io.read import read_result

        src = Path(args.path)
        result = read_result(src)
        if args.render:
            tag = args.field + (f"_{args.component}" if args.component else "")
            out = Path(args.output) if args.output else src.with_name(f"{src.stem}_{tag}_3d.png")
            plotting.render_result(
                result,
                out,
                field=args.field,
                component=args.component,
                step=args.step,
                scale=args.scale,
            )
            print(f"wrote {out}")
            return 0
        if args.convergence:
            plot = plotting.plot_convergence(result)
            out = Path(args.output) if args.output else src.with_name(f"{src.stem}_convergence.png")
        else:
            plot = plotting.plot_result(
                result,
                field=args.field,
                component=args.component,
                step=args.step,
                scale=args.scale,
                slice=args.slice,
                units=args.units,
            )
            tag = args.field + (f"_{args.component}" if args.component else "")
            out = Path(args.output) if args.output else src.with_name(f"{src.stem}_{tag}.png")
        written.append(plotting.save_figure(plot.figure, out, dpi=args.dpi))
        csv_path = (
            Path(args.homogenized)
            if args.homogenized
            else src.with_name(f"{src.stem}_homogenized.csv")
        )
        if args.homogenized or (result.n_steps > 1 and csv_path.is_file() and not args.convergence):
            curve = plotting.plot_homogenized(csv_path, units=args.units)
            written.append(
                plotting.save_figure(
                    curve.figure, out.with_name(f"{out.stem}_homogenized.png"), dpi=args.dpi
                )
            )
    plotting.close_figures()
    for w in written:
        print(f"wrote {w}")
    return 0


def _add_run(sub: Any) -> None:
    """Add the ``pdlin run`` subcommand."""
    r = sub.add_parser("run", help="solve a scene and write the results")
    r.add_argument(
        "scene", nargs="?", help="scene file (.toml) or Peridigm / PeriLab deck (.yaml, .xml)"
    )
    r.add_argument("--example", help="run a built-in example scene (see 'pdlin examples')")
    r.add_argument(
        "-o",
        "--output",
        help="results file (.vtu, .xdmf, .npz, .e/.exo Exodus II; nonlinear scenes: "
        ".pvd, .xdmf, .npz, .e/.exo series)",
    )
    r.add_argument("--solver", help="override the scene's solver")
    r.add_argument(
        "--backend",
        choices=("scipy", "petsc"),
        help="override the scene's solver.backend (petsc: run under mpiexec -n P)",
    )
    r.add_argument("--json", action="store_true", help="print the summary as JSON")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    r.add_argument(
        "--resume",
        action="store_true",
        help="continue a nonlinear run from its checkpoint (solver.checkpoint); refused, "
        "naming what differs, if the scene changed since it was written",
    )
    r.add_argument(
        "--select",
        action="store_true",
        help="run the fastest configuration of the scene's [tradeoff] sweep that meets "
        "tradeoff.target_error (the sweep's finished points are reused)",
    )
    r.add_argument("--target-error", type=float, help="override tradeoff.target_error")
    r.add_argument(
        "--kinematics",
        choices=("auto", "finite", "linear"),
        help="Peridigm decks' Elastic / Elastic Plastic materials: finite (their own "
        "kinematics, Newton per load step), linear (linearized at u = 0) or auto (default: "
        "finite with plasticity or several load steps)",
    )
    r.add_argument(
        "--strict",
        action="store_true",
        help="exit with code 5 when one of the scene's [[check]] references fails",
    )
    r.set_defaults(func=_cmd_run)


def _add_plot(sub: Any) -> None:
    """Add the ``pdlin plot`` subcommand."""
    pl = sub.add_parser(
        "plot",
        help="PNG of a result field (VTU/PVD/XDMF/NPZ/Exodus), or a scene's stiffness pattern",
    )
    pl.add_argument("path", nargs="?", help="result file, or scene (.toml) with --spy")
    pl.add_argument("-o", "--output", help="PNG file (default: beside the input)")
    pl.add_argument("--field", default="displacement", help="field (default displacement)")
    pl.add_argument("--component", help="magnitude, x, y, z of vectors; xx, xy, ... of tensors")
    pl.add_argument("--step", type=int, default=-1, help="step of a series (0-based; -1 last)")
    pl.add_argument("--scale", type=float, default=0.0, help="draw at x + scale * u")
    pl.add_argument("--slice", help="plane of a 3D result, e.g. z=0.5 (points within h/2)")
    pl.add_argument(
        "--units",
        help="unit system of the result for the labels: SI, mm-N-MPa, m-N-Pa, mm-kN-GPa "
        "(default: the labels name the quantity, [length], [stress])",
    )
    pl.add_argument(
        "--homogenized",
        metavar="CSV",
        help="also plot this homogenized stress-strain CSV (default: <stem>_homogenized.csv "
        "beside a series, if it exists)",
    )
    pl.add_argument("--convergence", action="store_true", help="linear solver residuals (.npz)")
    pl.add_argument(
        "--render", action="store_true", help="3D rendering with pyvista (pdlin[render])"
    )
    pl.add_argument("--spy", action="store_true", help="spy plot of the scene's stiffness")
    pl.add_argument(
        "--sparsity-vs-horizon",
        action="store_true",
        help="nonzeros per row of the scene's stiffness vs delta/h",
    )
    pl.add_argument("--ratios", default="2,3,4,5", help="delta/h values (default 2,3,4,5)")
    pl.add_argument("--order", default="rcm", help="spy ordering: natural or rcm (default)")
    pl.add_argument("--example", help="a built-in scene (with --spy / --sparsity-vs-horizon)")
    pl.add_argument("--dpi", type=int, default=120)
    pl.set_defaults(func=_cmd_plot, scene=None)


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of the ``pdlin`` command.

    Returns
    -------
    argparse.ArgumentParser
        With one subparser per subcommand.
    """
    p = argparse.ArgumentParser(prog="pdlin", description="Static peridynamics on sparse operators")
    p.add_argument("-v", "--verbose", action="store_true", help="log library messages")
    sub = p.add_subparsers(dest="command", required=True)

    _add_run(sub)

    i = sub.add_parser("info", help="points, volumes, bonds and horizons of a mesh or scene")
    i.add_argument(
        "mesh", help="mesh file readable by meshio, a scene .toml or a deck .yaml / .xml"
    )
    i.add_argument("--ratio", type=float, default=3.015, help="horizon / spacing (default 3.015)")
    i.add_argument("--horizon", type=float, help="absolute horizon (overrides --ratio)")
    i.add_argument(
        "--volume",
        type=float,
        help="volume of every point of a point cloud (a mesh of vertex cells) without a "
        "Volume point field",
    )
    i.add_argument("--json", action="store_true")
    i.set_defaults(func=_cmd_info)

    s = sub.add_parser("sparsity", help="stiffness-matrix sparsity report of a scene")
    s.add_argument("scene", nargs="?", help="scene file (.toml)")
    s.add_argument("--example", help="use a built-in example scene")
    s.add_argument("--json", action="store_true")
    s.add_argument(
        "--numeric",
        action="store_true",
        help="assemble K for symmetry, diagonal dominance and conditioning",
    )
    s.add_argument(
        "--fill-limit",
        type=int,
        default=5000,
        help="measure factorization fill-in up to this many DOFs (default 5000)",
    )
    s.set_defaults(func=_cmd_sparsity)

    c = sub.add_parser("calibrate", help="calibrate anisotropic bond micromoduli to a target")
    c.add_argument("target", help="calibration file (.toml): [target], [family], [calibration]")
    c.add_argument("-o", "--output", help="micromoduli file (.npz or .csv)")
    c.add_argument("--json", action="store_true")
    c.add_argument("--no-plot", action="store_true", help="skip the plot named in the file")
    c.set_defaults(func=_cmd_calibrate)

    x = sub.add_parser("export", help="write a scene's assembled system (Matrix Market or npz)")
    x.add_argument("scene", nargs="?", help="scene file (.toml)")
    x.add_argument("--example", help="use a built-in example scene")
    x.add_argument("-o", "--output", required=True, help="K.mtx (+ K_rhs.mtx) or system.npz")
    x.add_argument(
        "--unconstrained",
        action="store_true",
        help="write K and f before the Dirichlet elimination (default: the eliminated A, b)",
    )
    x.set_defaults(func=_cmd_export)

    t = sub.add_parser("tradeoff", help="sweep a scene's [tradeoff] table: error vs time")
    t.add_argument("scene", nargs="?", help="scene file (.toml) with a [tradeoff] table")
    t.add_argument("--example", help="a built-in scene with a [tradeoff] table (e.g. bar)")
    t.add_argument("-o", "--output", help="table written point by point (.csv or .jsonl)")
    t.add_argument("--plot", help="figure: error vs time and error vs delta/h (.png, .pdf)")
    t.add_argument("--resume", action="store_true", help="keep the finished points of -o")
    t.add_argument("--target-error", type=float, help="report the fastest config meeting it")
    t.add_argument("--json", action="store_true", help="print the table as JSON")
    t.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    t.set_defaults(func=_cmd_tradeoff)

    _add_plot(sub)

    e = sub.add_parser("examples", help="list the built-in example scenes")
    e.add_argument("--show", metavar="NAME", help="print the scene file of an example")
    e.add_argument("--json", action="store_true", help="print the list as JSON")
    e.set_defaults(func=_cmd_examples)
    # global options also after the subcommand (pdlin run -v); SUPPRESS keeps a subcommand
    # without them from overwriting what was given before it
    for sp in sub.choices.values():
        sp.add_argument(
            "-v",
            "--verbose",
            action="store_true",
            default=argparse.SUPPRESS,
            help="log library messages",
        )
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``pdlin`` command.

    0 ok, 2 bad input (or an output that cannot be written: the message names the
    file), 3 solver failure, 4 infeasible calibration target, 5 a scene check failed
    under ``pdlin run --strict`` (without it failed checks only print FAIL), 141 stdout
    closed by its reader (``| head``).

    Exit codes: 0 ok, 2 bad input (or an output that cannot be written: the message
    names the file), 3 solver failure, 4 infeasible calibration target, 5 a scene check
    failed under ``pdlin run --strict`` (without it failed checks only print FAIL), 141
    stdout closed by its reader (``| head``).

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    from ..errors import ConvergenceError

    try:
        code = int(args.func(args))
        sys.stdout.flush()  # a closed pipe shows here, not at exit
        return code
    except BrokenPipeError:
        # the reader of stdout went away (pdlin examples --show X | head): stop quietly,
        # as a shell tool killed by SIGPIPE does
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # no second error when Python flushes at exit
        return 141
    except ConvergenceError as exc:
        print(f"pdlin: solver failed: {exc}", file=sys.stderr)
        return 3
    except MemoryError as exc:  # pdlin's refusal, or an allocation that still failed
        from ..resources import out_of_memory_message

        print(f"pdlin: error: {out_of_memory_message(exc)}", file=sys.stderr)
        return 2
    except (PdlinError, OSError) as exc:
        print(f"pdlin: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
