"""Writing point fields to files (meshio VTU/XDMF, Exodus II, or numpy .npz), atomically.

Every writer builds its files in a private temporary directory next to the
target and moves them into place only when they are complete, so a run that
fails, is killed or runs out of disk never leaves a truncated file, and an
existing file is replaced only by a complete new one; a result of several files
(``.pvd`` + VTU pieces, ``.xdmf`` + HDF5) is replaced as one unit, and a failed
write raises :class:`pdlin.errors.WriteError` naming the file (see
:mod:`pdlin.io.output`).

The ParaView formats (VTU, PVD, XDMF, Exodus) name the fields as Peridigm does
where it has the quantity (``Displacement``, ``Volume``, ``Cauchy_Stress``, ...;
see ``pdlin.io.names``), pad vectors to 3 and ``dim x dim`` tensors to
3 x 3 components; NPZ files keep the API keys and shapes.
"""

from __future__ import annotations

import csv
import logging
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .._validation import as_bool, as_float_array
from ..errors import InputError, InputTypeError, ShapeError
from ..geometry.cloud import PointCloud
from .exodus import EXODUS_SUFFIXES, write_exodus_file
from .names import file_name, to_file_value
from .output import check_output, data_tag, staging
from .xdmf import write_xdmf

log = logging.getLogger(__name__)

__all__ = [
    "export_system",
    "write_points",
    "write_result",
    "write_series",
    "write_nonlinear",
    "write_homogenized_csv",
    "SUPPORTED_SUFFIXES",
    "SERIES_SUFFIXES",
]

SUPPORTED_SUFFIXES = (".vtu", ".xdmf", ".vtk", ".npz", *EXODUS_SUFFIXES)
#: time-series outputs: one XDMF (+ HDF5), a ParaView .pvd collection of VTU files, one NPZ,
#: one Exodus II file
SERIES_SUFFIXES = (".xdmf", ".pvd", ".vtu", ".npz", *EXODUS_SUFFIXES)


def _xdmf_fields(pd: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """XDMF attribute shapes: 2D tensors (n, 4) -> (n, 9); other widths split into scalars."""
    out: dict[str, np.ndarray] = {}
    for name, arr in pd.items():
        if arr.ndim == 1 or (arr.ndim == 2 and arr.shape[1] in (1, 2, 3, 6, 9)):
            out[name] = arr
        elif arr.ndim == 2 and arr.shape[1] == 4:
            t = np.zeros((arr.shape[0], 3, 3))
            t[:, :2, :2] = arr.reshape(-1, 2, 2)
            out[name] = t.reshape(-1, 9)
        else:
            flat = arr.reshape(arr.shape[0], -1)
            for k in range(flat.shape[1]):
                out[f"{name}_{k}"] = flat[:, k]
    return out


@contextmanager
def _staging(target: Path) -> Iterator[Path]:
    """Yield the private folder of :func:`pdlin.io.output.staging` (files named as the target)."""
    with staging(target) as stage:
        yield stage.dir


def _check_cloud(cloud: Any) -> None:
    if not isinstance(cloud, PointCloud):
        raise InputTypeError(f"cloud must be a PointCloud, got {type(cloud).__name__}")


def _check_fields(n: int, fields: Mapping[str, Any]) -> dict[str, np.ndarray]:
    if not isinstance(fields, Mapping):
        raise InputTypeError(
            f"fields must be a mapping of name to (n,) / (n, k) arrays, got {type(fields).__name__}"
        )
    data: dict[str, np.ndarray] = {}
    for name, val in fields.items():
        if not isinstance(name, str) or not name:
            raise InputTypeError(f"field names must be non-empty strings, got {name!r}")
        try:
            arr = np.asarray(val, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"field {name!r} must be a numeric array, got {type(val).__name__}: {exc}"
            ) from exc
        if arr.ndim == 0 or arr.shape[0] != n:
            raise ShapeError(f"field {name!r} must have {n} rows, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"field {name!r} holds NaN or inf; refusing to write it")
        # (n, d, d) tensors (and any (n, a, b, ...) array) as row-major (n, a * b) rows,
        # the layout of result.fields(): every format then stores and reads back the same
        data[name] = arr.reshape(n, -1) if arr.ndim > 2 else arr
    return data


def _point_data(cloud: PointCloud, data: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Fields under their ParaView names, vectors padded to 3 and tensors to 3 x 3."""
    pd: dict[str, np.ndarray] = {}
    if "volume" not in data:
        pd[file_name("volume")] = np.asarray(cloud.volumes, dtype=float)
    for name, arr in data.items():
        pd[file_name(name)] = to_file_value(name, arr, cloud.dim)
    return pd


def _write_exodus(out: Path, cloud: PointCloud, times: np.ndarray, data: Sequence[Any]) -> None:
    keys = list(data[0])
    for k, d in enumerate(data[1:], start=1):
        if list(d) != keys or any(d[f].shape != data[0][f].shape for f in keys):
            raise InputError(
                "Exodus nodal variables need the same fields in every step: step 0 has "
                f"{sorted(keys)}, step {k} has "
                f"{sorted((f, d[f].shape) for f in d)}; write .pvd or .xdmf instead"
            )
    write_exodus_file(
        out,
        np.asarray(cloud.points),
        np.asarray(cloud.material),
        cloud.sets,
        times,
        [_point_data(cloud, d) for d in data],
        dim=cloud.dim,
    )


def _pad3(a: np.ndarray) -> np.ndarray:
    if a.ndim == 2 and a.shape[1] < 3:
        out = np.zeros((a.shape[0], 3))
        out[:, : a.shape[1]] = a
        return out
    return a


def write_points(
    path: str | Path, cloud: PointCloud, fields: Mapping[str, Any], *, time: float = 0.0
) -> Path:
    """Write a point cloud with point fields.

    ``.vtu``/``.xdmf``/``.vtk`` go through meshio with the points as
    ``vertex`` cells (coordinates and vector fields padded to 3 components
    for 1D/2D so ParaView can warp by displacement); ``.e``/``.exo`` write
    an Exodus II file (one time step at ``time``, point sets as node sets,
    see ``pdlin.io.exodus``; needs ``pdlin[exodus]``); ``.npz`` stores the
    raw arrays (``points``, ``volumes`` and every field).  The ParaView
    formats name pdlin's fields as ``pdlin.io.names.FILE_NAMES`` says
    (``displacement`` -> ``Displacement``, ...); other names are kept.

    Parameters
    ----------
    path : str or Path
        Output file; its suffix picks the format.
    cloud : PointCloud
        The ``n`` points (positions, volumes and point sets are written).
    fields : mapping of name to (n,) or (n, k) arrays
        An (n, a, b) array (a ``dim x dim`` tensor per point) is written as
        its row-major (n, a * b) rows, the layout :meth:`pdlin.StaticResult.fields`
        uses, and :func:`pdlin.io.read_result` returns it so in every format.
    time : float, default 0.0
        Time of the state, written as the Exodus ``time_whole`` of its one step (a
        Peridigm deck's ``Solver.Final Time``, as Peridigm writes its final state).

    Returns
    -------
    Path
        The written file.

    Examples
    --------
    >>> import numpy as np, pdlin, tempfile, os, meshio
    >>> cloud = pdlin.grid((3, 2))
    >>> path = os.path.join(tempfile.mkdtemp(), "out.vtu")
    >>> _ = write_points(path, cloud, {"u": np.ones((6, 2)), "displacement": np.ones((6, 2))})
    >>> m = meshio.read(path)
    >>> m.point_data["u"].shape, m.point_data["Displacement"].shape
    ((6, 3), (6, 3))
    """
    return _write_points(path, cloud, fields, time=time)


def _write_points(
    path: str | Path,
    cloud: PointCloud,
    fields: Mapping[str, Any],
    npz_extra: Mapping[str, np.ndarray] | None = None,
    time: float = 0.0,
) -> Path:
    t = float(as_float_array(time, "time", ndim=0))
    p = check_output(path, SUPPORTED_SUFFIXES)
    suffix = p.suffix.lower()
    _check_cloud(cloud)
    data = _check_fields(cloud.n, fields)
    # companions (the .h5 of an .xdmf) named by the data: the same result, the same names
    tag = None
    if suffix == ".xdmf":
        tag = data_tag(np.asarray(cloud.points), np.asarray(cloud.volumes), data)
    with staging(p, tag) as st:
        out = st.main
        if suffix == ".npz":
            arrays = {
                "points": np.asarray(cloud.points),
                "volumes": np.asarray(cloud.volumes),
                **data,
                **(npz_extra or {}),
            }
            np.savez_compressed(out, **arrays)  # type: ignore[arg-type]
        elif suffix in EXODUS_SUFFIXES:
            _write_exodus(out, cloud, np.array([t]), [data])
        else:
            import meshio

            pdat = _point_data(cloud, data)
            cells = [("vertex", np.arange(cloud.n).reshape(-1, 1))]
            pts = _pad3(np.asarray(cloud.points))
            if suffix == ".xdmf":
                write_xdmf(out, st.companion(".h5"), pts, cells, _xdmf_fields(pdat))
            else:
                meshio.Mesh(pts, cells, point_data=pdat).write(out)
    return p


def write_result(path: str | Path, result: Any, *, time: float = 0.0) -> Path:
    """Write every field of a :class:`pdlin.StaticResult` (see :func:`write_points`).

    ``.npz`` files also store the linear solver's relative residual history
    (``residual_history``, drawn by ``pdlin plot --convergence``); ``time`` is the
    Exodus ``time_whole`` of the state (:func:`write_points`).

    Parameters
    ----------
    path : str or Path
        Output file (``.vtu``, ``.xdmf``, ``.vtk``, ``.e``/``.exo`` or ``.npz``).
    result : StaticResult
        The solve's result; ``result.fields()`` gives the fields written.
    time : float
        Time of the state, the Exodus ``time_whole`` of its one step.

    Returns
    -------
    Path
        The written file.
    """
    hist = np.asarray(result.residuals, dtype=float).reshape(-1)
    extra = {"residual_history": hist} if np.all(np.isfinite(hist)) else None
    return _write_points(path, result.problem.cloud, result.fields(), npz_extra=extra, time=time)


def write_series(
    path: str | Path,
    cloud: PointCloud,
    times: Sequence[float],
    steps: Sequence[Mapping[str, Any]],
) -> Path:
    """Write point fields of several steps as one time series.

    ``.xdmf``: one XDMF file with its HDF5 companion ``<name>.<tag>.h5``
    (meshio's time-series layout); ``.pvd`` (or ``.vtu``): a ParaView
    ``<stem>.pvd`` collection of one VTU file per step, in the folder
    ``<stem>.pvd.<tag>/`` (``<stem>_0001.vtu``, ...); ``.npz``: every field
    with a leading step axis plus ``times``; ``.e``/``.exo``: one Exodus II
    file with every step (``time_whole``) and the point sets as node sets
    (every step must hold the same fields).  Written atomically and as one
    unit: ``<tag>`` is a hash of the data (other data, other names; the same
    result, the same names), the main file is replaced last
    (one rename), then the previous companions are removed
    (``pdlin.io.output``).

    Parameters
    ----------
    path : str or Path
        ``.xdmf``, ``.pvd``, ``.vtu`` (written as ``.pvd``), ``.npz``, ``.e`` or ``.exo``.
    cloud : PointCloud
        The ``n`` points (positions and point sets).
    times : (k,) sequence of float
        Time of each step, increasing.
    steps : sequence of k mappings ``name -> (n,) or (n, c)`` array
        The point fields of each step.

    Returns
    -------
    Path
        The main file (``.xdmf``, ``.pvd``, ``.npz`` or ``.e``/``.exo``).

    Raises
    ------
    ShapeError
        When ``times`` and ``steps`` differ in length (or are empty), or a field has not
        one row per point.
    InputError
        When ``times`` is not increasing, the suffix is not a series format, or a field
        is empty, unnamed or holds NaN or inf.
    WriteError
        When a file cannot be written.

    Examples
    --------
    >>> import numpy as np, pdlin, tempfile, os, meshio
    >>> cloud = pdlin.grid((3, 2))
    >>> d = tempfile.mkdtemp()
    >>> p = write_series(os.path.join(d, "run.pvd"), cloud, [0.5, 1.0],
    ...                  [{"u": 0.5 * np.ones((6, 2))}, {"u": np.ones((6, 2))}])
    >>> pieces = [f for f in os.listdir(d) if f != "run.pvd"]
    >>> len(pieces), pieces[0].startswith("run.pvd."), p.name
    (1, True, 'run.pvd')
    >>> sorted(os.listdir(os.path.join(d, pieces[0])))
    ['run_0001.vtu', 'run_0002.vtu']
    """
    p = check_output(path, SERIES_SUFFIXES, "series path")
    suffix = p.suffix.lower()
    _check_cloud(cloud)
    tt = as_float_array(times, "times").reshape(-1)
    if tt.size != len(steps) or tt.size == 0:
        raise ShapeError(
            f"times and steps must have the same non-zero length, got {tt.size} and {len(steps)}"
        )
    if np.any(np.diff(tt) <= 0):
        k = int(np.flatnonzero(np.diff(tt) <= 0)[0])
        raise InputError(
            f"times must be increasing, got times[{k}] = {tt[k]} and times[{k + 1}] = {tt[k + 1]}"
        )
    data = [_check_fields(cloud.n, f) for f in steps]
    pts = _pad3(np.asarray(cloud.points))
    cells = [("vertex", np.arange(cloud.n).reshape(-1, 1))]
    if suffix == ".vtu":
        p = p.with_suffix(".pvd")
    # companions (.pvd pieces, the .h5 of an .xdmf) named by the data: a run that writes
    # the same result (e.g. a resumed one) writes the same file names
    tag = (
        data_tag(suffix, pts, np.asarray(cloud.volumes), tt, data)
        if suffix in (".pvd", ".vtu", ".xdmf")
        else None
    )
    with staging(p, tag) as st:
        if suffix == ".npz":
            arrays: dict[str, np.ndarray] = {
                "points": np.asarray(cloud.points),
                "volumes": np.asarray(cloud.volumes),
                "times": tt,
            }
            for name in data[0]:
                arrays[name] = np.stack([d[name] for d in data])
            np.savez_compressed(st.main, **arrays)  # type: ignore[arg-type]
        elif suffix in EXODUS_SUFFIXES:
            _write_exodus(st.main, cloud, tt, data)
        elif suffix == ".xdmf":
            pdats = [_xdmf_fields(_point_data(cloud, d)) for d in data]
            write_xdmf(st.main, st.companion(".h5"), pts, cells, list(zip(tt, pdats, strict=True)))
        else:
            import meshio

            # the pieces in a folder of their own, new for every write: the .pvd (replaced
            # last) always lists one complete set, never a mix of two runs
            folder = st.companion()
            (st.dir / folder).mkdir()
            entries = []
            for k, (t, d) in enumerate(zip(tt, data, strict=True)):
                name = f"{folder}/{p.stem}_{k + 1:04d}.vtu"
                meshio.Mesh(pts, cells, point_data=_point_data(cloud, d)).write(st.dir / name)
                entries.append(f'    <DataSet timestep="{t:.17g}" part="0" file="{name}"/>')
            st.main.write_text(
                '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                "  <Collection>\n" + "\n".join(entries) + "\n  </Collection>\n</VTKFile>\n"
            )
    return p


def write_homogenized_csv(path: str | Path, result: Any, *, weights: Any = None) -> Path:
    """Write the homogenized (volume-averaged) response per load step as CSV.

    Columns: ``step, time, factor``, the volume-averaged Cauchy stress
    ``sigma_ij`` and deformation gradient ``F_ij`` (volume-weighted mean of the nonlocal
    F over all points), the driver, iterations and cut-backs.  Written atomically.

    Parameters
    ----------
    path : str or Path
        The ``.csv`` file.
    result : NonlinearResult
        A :func:`pdlin.solve_nonlinear` result (stress columns are NaN when it holds
        no homogenized stress).
    weights : array_like, optional
        Weights of the mean F, one per row of ``result.system.disc.deformation_gradient``
        (default the points' volumes; the CPFE comparator passes its element volumes).

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    InputError
        When ``path`` does not end with ``.csv``.
    WriteError
        When the file cannot be written.
    """
    p = Path(path)
    if p.suffix.lower() != ".csv":
        raise InputError(f"homogenized output must end with .csv, got {str(p)!r}")
    d = result.u.shape[2]
    system = result.system
    w = np.asarray(system.cloud.volumes if weights is None else weights, dtype=float)
    ij = [f"{i + 1}{j + 1}" for i in range(d) for j in range(d)]
    header = ["step", "time", "factor"]
    header += [f"sigma_{c}" for c in ij] + [f"F_{c}" for c in ij]
    header += ["method", "iterations", "cutbacks"]
    rows = []
    for k in range(result.n_steps):
        F = system.disc.deformation_gradient(result.u[k])
        Fm = np.einsum("e,eab->ab", w, F) / w.sum()
        sig = (
            result.homogenized_stress[k]
            if result.homogenized_stress is not None
            else np.full((d, d), np.nan)
        )
        rows.append(
            [k + 1, f"{result.times[k]:.10g}", f"{result.factors[k]:.10g}"]
            + [f"{v:.10g}" for v in sig.ravel()]
            + [f"{v:.12g}" for v in Fm.ravel()]
            + [result.methods[k], int(result.iterations[k]), int(result.cutbacks[k])]
        )
    with staging(p) as st:
        with open(st.main, "w", newline="") as fh:
            wr = csv.writer(fh)
            wr.writerow(header)
            wr.writerows(rows)
    return p


def write_nonlinear(path: str | Path, result: Any) -> Path:
    """Write every step of a :class:`pdlin.NonlinearResult` as one time series.

    Any suffix of :func:`write_series` (``.pvd``, ``.xdmf``, ``.npz``,
    ``.e``/``.exo``).  Fields per step: ``displacement``, ``reaction``, and where available
    ``stress`` (Cauchy, ``dim²`` components) and the scalar / vector state
    variables of the committed state (e.g. ``state_gamma``, ``state_s``,
    ``state_reorientation`` of crystal plasticity; per-point ones only) of the steps
    whose committed state the result kept (:meth:`pdlin.NonlinearResult.state_at`).
    Exodus files hold only the fields every step has (a warning names the others).

    Parameters
    ----------
    path : str or Path
        Output file; its suffix picks the format.
    result : NonlinearResult
        A :func:`pdlin.solve_nonlinear` result.

    Returns
    -------
    Path
        The written main file.
    """
    cloud = result.system.cloud
    n = cloud.n
    steps = []
    for k in range(result.n_steps):
        fields: dict[str, np.ndarray] = {
            "displacement": result.u[k],
            "reaction": result.reactions[k],
        }
        if result.stress is not None:
            fields["stress"] = result.stress[k].reshape(n, -1)
        state = result.state_at(k) if hasattr(result, "state_at") else None
        if state is not None:
            for key, val in state.items():
                arr = np.asarray(val)
                if arr.shape[:1] == (n,) and arr.ndim <= 2 and arr.dtype.kind in "fiub":
                    fields[f"state_{key}"] = arr.astype(float)
        steps.append(fields)
    if Path(path).suffix.lower() in EXODUS_SUFFIXES:
        # Exodus nodal variables hold a value at every step: state variables kept for
        # only some steps (keep_states=False, or a resumed run) cannot be written there
        common = set.intersection(*(set(f) for f in steps))
        partial = sorted(set().union(*(set(f) for f in steps)) - common)
        if partial:
            log.warning(
                "Exodus output %s: %s kept for only some steps (keep_states=False or a "
                "resumed run) are not written; use .pvd or .xdmf to keep them",
                path,
                partial,
            )
            steps = [{k: v for k, v in f.items() if k in common} for f in steps]
    return write_series(path, cloud, result.times, steps)


def export_system(path: str | Path, problem: Any, *, eliminated: bool = True) -> Path:
    """Write the assembled system of a static problem for solvers outside pdlin.

    ``.mtx`` (Matrix Market): the matrix in ``<path>`` and the right-hand side
    in ``<stem>_rhs.mtx`` (a dense column); ``.npz``: one file holding the
    matrix in scipy's CSR arrays (``data``, ``indices``, ``indptr``,
    ``shape``), ``rhs``, the prescribed ``dofs`` and ``values``, ``dim`` and
    ``points``.  With ``eliminated=True`` (default) the matrix is the
    Dirichlet-eliminated ``A`` of :meth:`pdlin.system.ConstrainedSystem.eliminate`
    (same size, prescribed rows and columns ``s I``, ``rhs = 0`` there: solve
    ``A x = rhs`` and set ``x[dofs] = values``); otherwise the unconstrained
    ``K`` and the external force ``f``.  Written atomically.

    Parameters
    ----------
    path : str or Path
        ``.mtx`` or ``.npz`` file.
    problem : StaticProblem
        The problem whose system is assembled.
    eliminated : bool
        Export the Dirichlet-eliminated ``A`` and its ``rhs`` (default) instead of
        ``K`` and ``f``.

    Returns
    -------
    Path
        The written (main) file.

    Raises
    ------
    InputError
        When the suffix is not ``.mtx`` or ``.npz``, or the system holds NaN or inf.
    WriteError
        When a file cannot be written.

    Examples
    --------
    >>> import numpy as np, pdlin, tempfile, os, scipy.io
    >>> cloud = pdlin.grid((6,), spacing=0.1)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, horizon=0.2,
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0)], loads=[pdlin.TotalForce("x+", [1e-3])])
    >>> p = export_system(os.path.join(tempfile.mkdtemp(), "K.mtx"), prob)
    >>> A = scipy.io.mmread(p); b = scipy.io.mmread(p.with_name("K_rhs.mtx")).ravel()
    >>> x = np.linalg.solve(A.toarray(), b)
    >>> bool(np.allclose(x, pdlin.solve(prob, solver="direct").u.ravel()))
    True
    """
    import scipy.io
    import scipy.sparse as sp

    from ..system import constrained_system

    eliminated = as_bool(eliminated, "eliminated")
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in (".mtx", ".npz"):
        raise InputError(f"export path must end with .mtx or .npz, got {str(p)!r}")
    system = constrained_system(problem)
    K = system.assemble()
    if eliminated:
        A, rhs = system.eliminate(K)
    else:
        A, rhs = K, system.f_ext
    A = sp.csr_array(A)
    rhs = np.asarray(rhs, dtype=float)
    if not (np.all(np.isfinite(A.data)) and np.all(np.isfinite(rhs))):
        raise InputError("the assembled system holds NaN or inf; refusing to export it")
    with staging(p) as st:
        if suffix == ".mtx":
            # through Python file objects: scipy's writer to a path truncates silently
            # when a write fails (full disk, file-size limit)
            with open(st.main, "wb") as fh:
                scipy.io.mmwrite(fh, A, symmetry="general")
            with open(st.dir / f"{p.stem}_rhs.mtx", "wb") as fh:
                scipy.io.mmwrite(fh, rhs.reshape(-1, 1))
        else:
            np.savez_compressed(
                st.main,
                data=A.data,
                indices=A.indices,
                indptr=A.indptr,
                shape=np.array(A.shape),
                rhs=rhs,
                dofs=system.dofs,
                values=system.values,
                dim=np.array(system.dim),
                points=np.asarray(system.cloud.points),
                eliminated=np.array(bool(eliminated)),
            )
    return p
