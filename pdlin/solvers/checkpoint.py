"""Checkpoints of :func:`pdlin.solve_nonlinear` and the ADR snapshots of a running step.

A checkpoint is one NPZ file per run, written after every converged load step.

A checkpoint carries the per-step records, the last committed state (with
``keep_states`` every committed state), the predictor's continuation state and the
automatic incrementation's memory, and a fingerprint of the problem (one SHA-256
digest per part, ``fp__<part>``) that a resume checks.  Files are written atomically
(through ``<path>.tmp`` and a rename).
"""

from __future__ import annotations

import hashlib
import logging
import os
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._fingerprint import digest
from ..errors import CheckpointError, CheckpointWriteError

if TYPE_CHECKING:
    from ..system import ConstrainedSystem

__all__ = ["problem_fingerprint"]

log = logging.getLogger(__name__)

#: 2: with the problem's fingerprint (``fp__*``) and, with ``keep_states``, every committed
#: state (``states__*``); 1: neither
_CHECKPOINT_VERSION = 2
#: the parts of a checkpoint's fingerprint (one SHA-256 digest each, ``fp__<part>``) and
#: how a refused resume names them; ``loads`` holds one digest per committed step
_PARTS = {
    "points": "points (coordinates, volumes)",
    "bonds": "bonds (horizon, influence)",
    "model": "model and material parameters",
    "homogenize": "homogenized points",
    "solver": "solver options",
    "loads": "boundary conditions and loads",
}
#: errors of reading a damaged NPZ file (truncated: BadZipFile or EOFError; garbage:
#: numpy's "pickled data" ValueError; a missing array: KeyError)
_UNREADABLE = (OSError, ValueError, KeyError, IndexError, EOFError, zipfile.BadZipFile)


def _why_unreadable(exc: BaseException) -> str:
    """Say why ``np.load`` could not read a file.

    numpy takes a file that is no ZIP archive for a pickle and suggests
    ``allow_pickle=``: here it is just not an NPZ file.
    """
    if isinstance(exc, ValueError) and "pickled" in str(exc):
        return "not an NPZ file"
    return f"{type(exc).__name__}: {exc}"


def _write_atomic_npz(path: Path, arrays: dict[str, np.ndarray], what: str = "checkpoint") -> None:
    """Write ``arrays`` to ``path`` through ``<path>.tmp`` and a rename.

    ``path`` holds the old or the new file, never a part of one, and no ``.tmp`` file is
    left behind.

    Raises
    ------
    CheckpointWriteError
        The write failed (e.g. a full disk); the message names ``path`` (``what``: the
        kind of file) and the previous file is kept.
    """
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)  # type: ignore[arg-type]
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:  # pragma: no cover - the folder itself is gone
            pass
        if isinstance(exc, OSError):
            reason = exc.strerror or str(exc) or type(exc).__name__
            raise CheckpointWriteError(
                f"could not write the {what} {str(path)!r}: {reason}; the previous {what} "
                "(if any) is kept"
            ) from exc
        raise


def _write_snapshots(path: Path, snaps: dict[str, dict[str, np.ndarray]]) -> None:
    """Write the ADR snapshots of the running load step, by increment key, to one file."""
    arrays: dict[str, np.ndarray] = {"keys": np.array(list(snaps), dtype=str)}
    for i, entry in enumerate(snaps.values()):
        for name, value in entry.items():
            arrays[f"s{i}__{name}"] = np.asarray(value)
    _write_atomic_npz(path, arrays, "ADR snapshot file")


def _read_snapshots(
    path: Path, say: Callable[[str], None] = lambda msg: None
) -> dict[str, dict[str, np.ndarray]]:
    """Read the snapshots of :func:`_write_snapshots`.

    None from an unreadable file, which is named in a warning and through ``say``: the
    increments then start afresh, as without snapshots, and end where the snapshots
    would have led.
    """
    try:
        with np.load(path, allow_pickle=False) as f:
            keys = [str(k) for k in f["keys"]]
            out: dict[str, dict[str, np.ndarray]] = {key: {} for key in keys}
            for name in f.files:
                if name != "keys":
                    idx, _, field_name = name.partition("__")
                    out[keys[int(idx[1:])]][field_name] = f[name]
    except _UNREADABLE as exc:
        why = _why_unreadable(exc)
        log.warning("ADR snapshot file %s is unreadable (%s); the step starts afresh", path, why)
        say(f"ADR snapshot file {path} is unreadable ({why}); the step starts afresh")
        return {}
    return out


def problem_fingerprint(
    system: ConstrainedSystem, hom_w: np.ndarray, solver_options: dict[str, Any]
) -> dict[str, str]:
    """Return the digests of a checkpoint's fingerprint but the per-step loads.

    Parameters
    ----------
    system : ConstrainedSystem
        The problem's constrained system (points, bonds, model).
    hom_w : (n,) ndarray
        The homogenization weights.
    solver_options : dict
        The options that change a run's iterates (:meth:`StepControl.fingerprint`).

    Returns
    -------
    dict of str to str
        One SHA-256 hex digest per part: ``points``, ``bonds``, ``model``,
        ``homogenize``, ``solver``.
    """
    cloud = system.cloud
    bonds = getattr(system.disc, "bonds", None) or system.disc.real_bonds
    return {
        "points": digest(cloud.points, cloud.volumes),
        "bonds": digest(
            *(bonds.i, bonds.j, bonds.omega, bonds.volume_j, bonds.horizon),
            *(bonds.shape, bonds.influence),
        ),
        "model": digest(system.model),
        "homogenize": digest(hom_w),
        "solver": digest(solver_options),
    }


def _load_digest(system: ConstrainedSystem, t: float, t_end: float) -> str:
    """Digest a load step's prescribed DOFs, their values and the external force at ``t``.

    Plain values and loads are scaled by ``t / t_end``, load paths evaluated.
    """
    factor = t / t_end
    return digest(system.dofs, system.values_at(t, factor), factor * system.f_ext)


def _read_checkpoint(path: Path) -> dict[str, np.ndarray]:
    """Every array of a checkpoint file.

    Raises
    ------
    CheckpointError
        The file is unreadable (truncated, not an NPZ file, an array missing).
    """
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {name: f[name] for name in f.files}
        int(data["version"]), int(data["done"])  # noqa: B018 - present and readable
    except _UNREADABLE as exc:
        raise CheckpointError(
            f"checkpoint {str(path)!r} is unreadable ({_why_unreadable(exc)}); remove it, "
            "or start afresh without resume (pdlin run without --resume), which overwrites it"
        ) from exc
    return data


def _check_checkpoint(
    path: Path,
    data: dict[str, np.ndarray],
    system: ConstrainedSystem,
    tt: np.ndarray,
    te: float,
    fingerprint: dict[str, str],
    branch: bool,
) -> None:
    """Refuse a checkpoint of another problem, naming the parts that differ.

    The parts are ``_PARTS`` and the step times; the solver options only when not
    ``branch``.

    Raises
    ------
    CheckpointError
        Written by a pdlin without a fingerprint, or for another problem.
    """
    where = f"checkpoint {str(path)!r}"
    fix = "remove it, or start afresh without resume (pdlin run without --resume)"
    version = int(data["version"])
    if version != _CHECKPOINT_VERSION or any(f"fp__{p}" not in data for p in _PARTS):
        raise CheckpointError(
            f"{where} has no problem fingerprint (version {version}, written by an earlier "
            f"pdlin; this one writes version {_CHECKPOINT_VERSION}), so it cannot be checked "
            f"against this problem; {fix}"
        )
    done = int(data["done"])
    ck_times = np.asarray(data["times"], dtype=float)
    differ = [
        _PARTS[part]
        for part, value in fingerprint.items()
        if str(data[f"fp__{part}"]) != value and not (branch and part == "solver")
    ]
    if done > tt.size or not np.allclose(ck_times[:done], tt[:done], rtol=1e-12, atol=0.0):
        differ.append(f"step times (the checkpoint's first {done}: {ck_times[:done].tolist()})")
    else:
        stored = [str(v) for v in data["fp__loads"][:done]]
        if stored != [_load_digest(system, float(t), te) for t in ck_times[:done]]:
            differ.append(_PARTS["loads"])
    if differ:
        hint = (
            "; resume='branch' continues a checkpoint with other solver options"
            if differ == [_PARTS["solver"]]
            else ""
        )
        raise CheckpointError(
            f"{where} was written for a different problem: {', '.join(differ)} differ; {fix}{hint}"
        )


def _adr_key(
    t_new: float, u0: np.ndarray, st: dict[str, np.ndarray], dens: Any, opts: tuple[float, ...]
) -> str:
    """Fingerprint an ADR increment: a snapshot continues only the same increment.

    Digests its target time, start displacement, committed state and density, and
    ``opts`` (the options that change its iterates: Δt, a constant damping, the budget).
    """
    h = hashlib.sha256(np.array((t_new, *opts), dtype=float).tobytes())
    h.update(np.ascontiguousarray(u0, dtype=float).tobytes())
    h.update(np.ascontiguousarray(dens, dtype=float).tobytes())
    for key in sorted(st):
        h.update(key.encode())
        h.update(np.ascontiguousarray(st[key]).tobytes())
    return h.hexdigest()


def _checkpoint_arrays(
    cols: dict[str, Any],
    *,
    times: np.ndarray,
    shape: tuple[int, int],
    fingerprint: dict[str, str],
    load_digests: list[str],
    increments: list[float],
    state: dict[str, Any],
    states: list[dict[str, Any]] | None,
    prev_state: dict[str, Any] | None,
) -> dict[str, np.ndarray]:
    """Return the arrays of a checkpoint after ``len(load_digests)`` committed steps.

    ``cols`` are the per-step columns (:func:`~pdlin.solvers.stepping.history_arrays`),
    ``increments`` the automatic incrementation's memory (Newton's and ADR's last
    increment fractions, ADR's held fraction, the step its hold ends, its length),
    ``states`` every committed state (None: only the last, ``state``) and ``prev_state``
    the continuation predictor's state.
    """
    arrays: dict[str, np.ndarray] = {
        "version": np.array(_CHECKPOINT_VERSION),
        "shape": np.array(list(shape)),
        "times": times,
        "done": np.array(len(load_digests)),
        **{key: cols[key] for key in ("u", "reactions", "iterations", "calls", "cutbacks")},
        **{key: cols[key] for key in ("relaxations", "polishes", "e1", "e2", "residuals")},
        "methods": np.array(cols["methods"]),
        "messages": np.array(cols["messages"]),
        "step_time": cols["step_time"],
        **{f"fp__{part}": np.array(value) for part, value in fingerprint.items()},
        "fp__loads": np.array(load_digests),
        "increments": np.array(increments, dtype=float),
    }
    if cols["stress"] is not None:
        arrays["stress"] = cols["stress"]
        arrays["homogenized_stress"] = cols["homogenized_stress"]
    for key, value in state.items():
        arrays[f"state__{key}"] = np.asarray(value)
    if states is not None:
        # every committed state: a resumed run returns and writes them all
        for key in state:
            arrays[f"states__{key}"] = np.stack([np.asarray(st[key]) for st in states])
    for key, value in (prev_state or {}).items():
        arrays[f"prev_state__{key}"] = np.asarray(value)
    return arrays


def _checkpoint_steps(data: dict[str, np.ndarray]) -> list[dict[str, Any]]:
    """Return the record of every step a checkpoint holds, as keyword arguments.

    Steps whose run recorded no wall time get NaN; ``relaxations``, ``polishes`` and
    ``messages`` are absent from checkpoints of earlier versions (0, 0, empty).
    """
    has = data.__contains__
    return [
        {
            "u": np.asarray(data["u"][i], dtype=float),
            "reactions": np.asarray(data["reactions"][i], dtype=float),
            "stress": data["stress"][i] if has("stress") else None,
            "homogenized_stress": data["homogenized_stress"][i] if has("stress") else None,
            "iterations": int(data["iterations"][i]),
            "calls": int(data["calls"][i]),
            "cutbacks": int(data["cutbacks"][i]),
            "relaxations": int(data["relaxations"][i]) if has("relaxations") else 0,
            "polishes": int(data["polishes"][i]) if has("polishes") else 0,
            "e1": float(data["e1"][i]),
            "e2": float(data["e2"][i]),
            "residual": float(data["residuals"][i]),
            "method": str(data["methods"][i]),
            "message": str(data["messages"][i]) if has("messages") else "",
            "step_time": float(data["step_time"][i]) if has("step_time") else np.nan,
            "load_digest": str(data["fp__loads"][i]),
        }
        for i in range(int(data["done"]))
    ]


def _checkpoint_states(
    data: dict[str, np.ndarray],
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Return a checkpoint's last committed state, predictor state and every state.

    The continuation predictor's state is empty from earlier versions; the stacked
    committed states of every step are empty when written without ``keep_states``.
    """

    def part(prefix: str) -> dict[str, np.ndarray]:
        return {k[len(prefix) :]: data[k] for k in data if k.startswith(prefix)}

    return part("state__"), part("prev_state__"), part("states__")
