"""Checkpoints of :func:`pdlin.dynamics.solve_explicit`: the whole state of a run, atomically.

One NPZ file: the step, ``u``, ``v``, the internal force, the bond mask, the energy
histories and the stored frames, and a fingerprint of the problem (one SHA-256 digest
per part) that a resume checks.  A resumed run continues with the very arrays the
interrupted one had, so its result is bitwise that of an uninterrupted run.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._fingerprint import digest
from ..errors import CheckpointError, CheckpointWriteError

if TYPE_CHECKING:
    from ..problem import StaticProblem

__all__ = ["ExplicitCheckpoint", "fingerprint", "CHECKPOINT_VERSION"]

#: format of the explicit checkpoint files
CHECKPOINT_VERSION = 1
#: how a refused resume names the parts of the fingerprint
PARTS = {
    "points": "points (coordinates, volumes)",
    "bonds": "bonds (pairs, influence, horizons, pre-cracks)",
    "model": "model and material parameters",
    "mass": "densities",
    "conditions": "boundary conditions and loads",
    "run": "time step, kinematics or critical stretch",
}
_UNREADABLE = (OSError, ValueError, KeyError, IndexError, EOFError, zipfile.BadZipFile)


def fingerprint(problem: StaticProblem, st: Any, dt: float, linear: bool) -> dict[str, str]:
    """Return the digests a checkpoint is checked against, one per part of ``PARTS``.

    Parameters
    ----------
    problem : StaticProblem
        The problem (with its bonds).
    st : object
        The run's fixed data: ``mass``, ``dofs``, ``f_ext``, ``s0`` and ``prescribed(cloud,
        t)``.
    dt : float
        The time step.
    linear : bool
        The kinematics.

    Returns
    -------
    dict of str to str
        SHA-256 hex digests.
    """
    cloud = problem.cloud
    b = problem.get_bonds()
    return {
        "points": digest(cloud.points, cloud.volumes, float(cloud.thickness)),
        "bonds": digest(b.i, b.j, b.omega, b.volume_j, b.horizon, b.shape, b.influence),
        "model": digest(problem.model),
        "mass": digest(st.mass),
        "conditions": digest(
            st.dofs, st.prescribed(cloud, 0.0), st.prescribed(cloud, dt), st.f_ext
        ),
        "run": digest(float(dt), bool(linear), st.s0),
    }


class ExplicitCheckpoint:
    """A checkpoint file of one run.

    Parameters
    ----------
    path : Path
        The NPZ file.
    fp : dict of str to str
        The run's fingerprint (:func:`fingerprint`).
    """

    def __init__(self, path: Path, fp: dict[str, str]) -> None:
        self.path = Path(path)
        self.fp = fp

    def write(self, run: Any) -> None:
        """Write the state of ``run`` (atomically: ``<path>.tmp``, fsync, rename).

        Parameters
        ----------
        run : object
            The running integration (``k``, ``u``, ``v``, ``f_int``, ``alive``,
            ``hist``, ``frames``).

        Raises
        ------
        CheckpointWriteError
            The write failed; the previous checkpoint is kept.
        """
        arrays: dict[str, Any] = {
            "version": np.array(CHECKPOINT_VERSION),
            "k": np.array(run.k),
            "u": run.u,
            "v": run.v,
            "f_int": run.f_int,
            "put_in": np.array(run.put_in),
        }
        if run.alive is not None:
            arrays["alive"] = run.alive
        for name, values in run.hist.items():
            arrays[f"hist__{name}"] = np.asarray(values, dtype=float)
        arrays["frame_t"] = np.array([f[0] for f in run.frames])
        arrays["frame_u"] = np.stack([f[1] for f in run.frames])
        arrays["frame_v"] = np.stack([f[2] for f in run.frames])
        if run.alive is not None:
            arrays["frame_damage"] = np.stack([f[3] for f in run.frames])
        for part, value in self.fp.items():
            arrays[f"fp__{part}"] = np.array(value)
        tmp = self.path.with_name(self.path.name + ".tmp")
        try:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, self.path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise CheckpointWriteError(
                f"could not write the checkpoint {str(self.path)!r}: "
                f"{exc.strerror or exc}; the previous checkpoint (if any) is kept"
            ) from exc

    def restore(self, run: Any, progress: Callable[[str], None] | None = None) -> bool:
        """Load the checkpoint into ``run`` (nothing when there is no file).

        Parameters
        ----------
        run : object
            A freshly set-up run of the same problem.
        progress : callable, optional
            Told when there is no checkpoint to resume.

        Returns
        -------
        bool
            Whether a checkpoint was loaded.

        Raises
        ------
        CheckpointError
            The file is unreadable, of another format, or of another problem.
        """
        if not self.path.exists():
            if progress is not None:
                progress(f"no checkpoint {self.path} to resume: starting from step 0")
            return False
        where = f"checkpoint {str(self.path)!r}"
        fix = "remove it, or start afresh without resume"
        try:
            with np.load(self.path, allow_pickle=False) as f:
                data = {name: f[name] for name in f.files}
            version = int(data["version"])
        except _UNREADABLE as exc:
            raise CheckpointError(f"{where} is unreadable ({type(exc).__name__}); {fix}") from exc
        if version != CHECKPOINT_VERSION or any(f"fp__{p}" not in data for p in PARTS):
            raise CheckpointError(
                f"{where} is not an explicit-dynamics checkpoint of version "
                f"{CHECKPOINT_VERSION}; {fix}"
            )
        differ = [PARTS[p] for p in PARTS if str(data[f"fp__{p}"]) != self.fp[p]]
        if differ:
            raise CheckpointError(
                f"{where} was written for a different problem: {', '.join(differ)} differ; {fix}"
            )
        run.k = int(data["k"])
        run.u[...] = data["u"]
        run.v[...] = data["v"]
        run.f_int = np.array(data["f_int"])
        run._put_in = float(data["put_in"])
        if run.alive is not None:
            run.alive[...] = data["alive"]
        run.hist = {name: data[f"hist__{name}"].tolist() for name in run.hist}
        dmg = data.get("frame_damage")
        run.frames = [
            (
                float(t),
                np.array(data["frame_u"][k]),
                np.array(data["frame_v"][k]),
                None if dmg is None else np.array(dmg[k]),
            )
            for k, t in enumerate(data["frame_t"])
        ]
        run.resumed_from = run.k
        return True
