"""Explicit dynamics: velocity Verlet (central differences) with stretch damage.

:func:`solve_explicit` integrates ``M ü = f_int(u) + f_ext`` on the free DOFs of a
:class:`~pdlin.StaticProblem` (``M`` the lumped masses ``ρ_i V_i``), with prescribed
displacements (plain values held, :class:`~pdlin.TimePath` values evaluated at every
step: a prescribed velocity is the path ``u = v t``), body and total forces (constant in
time), initial displacement and velocity fields, and irreversible bond breaking by the
critical-stretch criterion (Silling & Askari 2005; the XOSB paper of Liu, Chen &
Skelton, §5.3).  See ``docs/dynamics.md``.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._progress import Throttle
from .._repr import compact_repr
from .._validation import as_float_array, integer
from ..constraints import load_vector, resolve_dirichlet
from ..errors import (
    InputError,
    InputTypeError,
    InstabilityError,
    ModelError,
    ShapeError,
    TimeStepWarning,
)
from ..models.damage import critical_stretch as stretch_from_energy
from ..operators.bc import TimePath
from ..problem import StaticProblem
from .checkpoint import ExplicitCheckpoint, fingerprint
from .forces import force_kernel
from .timestep import TIME_STEP_METHODS, TimeStepEstimate, estimate_time_step, nodal_masses

__all__ = ["ExplicitResult", "solve_explicit", "step_count"]

#: a run whose mechanical energy exceeds this multiple of the energy put in is unstable
GROWTH_LIMIT = 1e3


@dataclass
class ExplicitResult:
    """What :func:`solve_explicit` returns.

    Attributes
    ----------
    problem : StaticProblem
        The problem.
    times : (k,) ndarray
        Times of the stored frames (step 0, every ``output_every`` steps, the last step).
    u, v : (k, n, dim) ndarray
        Displacement and velocity of each frame.
    damage : (k, n) ndarray or None
        Damage index ``φ_i = 1 - Σ_alive V_j / Σ V_j`` of each frame (None without damage).
    step_times : (s + 1,) ndarray
        Time of every step, ``k dt``.
    kinetic, strain, external_work, dissipated : (s + 1,) ndarray
        Per step: kinetic energy of the free DOFs, strain energy, work of the external
        forces and of the reactions at the prescribed DOFs (trapezoidal), energy released
        by broken bonds (cumulative).
    verlet : (s + 1,) ndarray
        ``(Δt²/8) Σ_free f²/m`` per step (``f`` the total force): velocity Verlet conserves
        ``energy - verlet`` exactly for linear elastic forces (:attr:`modified_energy`).
    broken : (s + 1,) ndarray of int
        Broken directed bonds (cumulative).
    dt : float
        The time step.
    estimate : TimeStepEstimate or None
        The stable-step estimate (None when ``check_dt=False`` with a given ``dt``).
    alive : (n_bonds,) ndarray of bool
        Surviving bonds at the end (over ``bonds``, the intact bonds).
    bonds : Bonds
        The intact (pre-cracked) bonds.
    critical_stretch : ndarray or None
        Critical stretch per bond (None without damage).
    resumed_from : int
        Step of the checkpoint the run resumed from (0: a fresh run).
    timings : dict of str to float
        Seconds: ``setup``, ``steps``, ``total``.
    """

    problem: StaticProblem
    times: np.ndarray
    u: np.ndarray
    v: np.ndarray
    damage: np.ndarray | None
    step_times: np.ndarray
    kinetic: np.ndarray
    strain: np.ndarray
    external_work: np.ndarray
    dissipated: np.ndarray
    verlet: np.ndarray
    broken: np.ndarray
    dt: float
    estimate: TimeStepEstimate | None
    alive: np.ndarray
    bonds: Any
    critical_stretch: np.ndarray | None = None
    resumed_from: int = 0
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def steps(self) -> int:
        """Number of time steps taken."""
        return int(self.step_times.size - 1)

    @property
    def n_steps(self) -> int:
        """Number of stored frames (what a scene's ``[[check]]`` ``step`` counts)."""
        return int(self.times.size)

    @property
    def frame_steps(self) -> np.ndarray:
        """Time-step index of every stored frame, ``(k,)``."""
        return np.rint(self.times / self.dt).astype(np.int64)

    @property
    def energy(self) -> np.ndarray:
        """Energy balance per step: ``kinetic + strain + dissipated - external_work``."""
        return self.kinetic + self.strain + self.dissipated - self.external_work

    @property
    def modified_energy(self) -> np.ndarray:
        """Return the energy velocity Verlet conserves exactly for linear forces, per step.

        ``energy - verlet``: from ``v_{n+1} - v_n = ½Δt M⁻¹(f_n + f_{n+1})`` and
        ``u_{n+1} - u_n = Δt v_n + ½Δt² M⁻¹f_n``, the kinetic energy changes by the
        trapezoidal work of the forces plus ``(Δt²/8) Δ(fᵀM⁻¹f)``; for linear symmetric
        forces the trapezoidal work is the exact change of the strain energy.

        Returns
        -------
        (s + 1,) ndarray
        """
        return self.energy - self.verlet

    def summary(self) -> dict[str, Any]:
        """Return a plain-data summary (for the command line).

        Returns
        -------
        dict
            ``steps``, ``t_end``, ``dt``, ``dt_estimate``, ``estimate_method``, ``points``,
            ``broken_bonds``, ``max_damage``, ``energy_drift`` (the largest change of
            :attr:`energy` over the run relative to the largest of the kinetic, strain
            and external energies), ``resumed_from`` and ``timings``.
        """
        scale = max(
            float(np.max(np.abs(self.kinetic))),
            float(np.max(np.abs(self.strain))),
            float(np.max(np.abs(self.external_work))),
        )
        e = self.energy
        drift = float(np.max(np.abs(e - e[0]))) / scale if scale > 0 else 0.0
        return {
            "steps": self.steps,
            "t_end": float(self.step_times[-1]),
            "dt": self.dt,
            "dt_estimate": None if self.estimate is None else self.estimate.dt,
            "estimate_method": None if self.estimate is None else self.estimate.method,
            "points": int(self.u.shape[1]),
            "broken_bonds": int(self.broken[-1]),
            "max_damage": None if self.damage is None else float(self.damage[-1].max()),
            "energy_drift": drift,
            "resumed_from": self.resumed_from,
            "timings": {k: round(v, 4) for k, v in self.timings.items()},
        }

    def fields(self, k: int = -1) -> dict[str, np.ndarray]:
        """Return the point fields of frame ``k`` under pdlin's field names.

        Parameters
        ----------
        k : int
            Frame index (default the last).

        Returns
        -------
        dict of str to ndarray
            ``displacement``, ``velocity`` and, with damage, ``damage``.
        """
        out = {"displacement": self.u[k], "velocity": self.v[k]}
        if self.damage is not None:
            out["damage"] = self.damage[k]
        return out

    def write(self, path: str | Path) -> Path:
        """Write every frame as one time series (:func:`pdlin.io.results.write_series`).

        Parameters
        ----------
        path : str or Path
            ``.pvd``, ``.xdmf``, ``.npz`` or ``.e`` / ``.exo``.

        Returns
        -------
        Path
            The main file written.
        """
        from ..io.results import write_series

        frames = [self.fields(k) for k in range(self.times.size)]
        return write_series(path, self.problem.cloud, self.times.tolist(), frames)

    def __repr__(self) -> str:
        """Return steps, time step, damage and drift (no arrays)."""
        s = self.summary()
        return compact_repr(
            "ExplicitResult",
            {k: s[k] for k in ("steps", "t_end", "dt", "dt_estimate", "broken_bonds")},
        )


def step_count(t_end: float, dt: float) -> int:
    """Return the number of steps of size ``dt`` that reach ``t_end``.

    ``t_end / dt`` rounded when it is an integer to 1e-9 relative, else rounded up (the
    last step then ends past ``t_end`` by less than ``dt``).

    Parameters
    ----------
    t_end : float
        End time (> 0).
    dt : float
        Time step (> 0).

    Returns
    -------
    int

    Examples
    --------
    >>> step_count(104e-6, 80e-9), step_count(1.0, 0.3)
    (1300, 4)
    """
    x = t_end / dt
    r = round(x)
    return int(r) if r > 0 and abs(x - r) <= 1e-9 * x else int(math.ceil(x))


def _field(value: Any, name: str, n: int, d: int) -> np.ndarray:
    """Return an initial field as ``(n, d)`` (from ``(n, d)`` or ``(n*d,)``), finite."""
    if value is None:
        return np.zeros((n, d))
    a = as_float_array(value, name)
    if a.size != n * d or a.ndim not in (1, 2) or (a.ndim == 2 and a.shape != (n, d)):
        raise ShapeError(f"{name} must have shape ({n}, {d}) or ({n * d},), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be finite, got NaN or infinity")
    return a.reshape(n, d).copy()


def _youngs_modulus(model: Any, dim: int) -> Any:
    fn = getattr(model, "young_modulus", None)
    E = fn(dim) if callable(fn) else getattr(model, "E", None)
    if E is None:
        raise ModelError(
            f"{type(model).__name__} has no Young's modulus to turn G0 into a critical "
            "stretch; give critical_stretch instead"
        )
    return E


def _thresholds(problem: StaticProblem, bonds: Any, s0: Any, G0: Any) -> np.ndarray | None:
    """Critical stretch per intact bond, from ``s0`` or from ``G0`` (None: no damage)."""
    if s0 is None and G0 is None:
        return None
    if s0 is not None and G0 is not None:
        raise InputError("give critical_stretch or G0, not both")
    cloud, model = problem.cloud, problem.model
    if s0 is not None:
        crit = as_float_array(s0, "critical_stretch")
        if crit.ndim not in (0, 1) or (crit.ndim == 1 and crit.shape != (bonds.n_bonds,)):
            raise ShapeError(
                f"critical_stretch must be a number or have shape ({bonds.n_bonds},) (one per "
                f"bond), got shape {crit.shape}"
            )
        if not np.all(np.isfinite(crit)) or np.any(crit <= 0):
            raise InputError(f"critical_stretch must be finite and > 0, got {crit.min()}")
        return np.broadcast_to(crit, (bonds.n_bonds,)).astype(float)
    if cloud.dim == 1:
        raise ModelError("G0 -> critical stretch needs a 2D or 3D cloud; give critical_stretch")
    plane = getattr(model, "plane", None) if cloud.dim == 2 else None
    E = np.broadcast_to(np.asarray(_youngs_modulus(model, cloud.dim), dtype=float), (cloud.n,))
    g = np.broadcast_to(as_float_array(G0, "G0"), (cloud.n,))
    hor = np.broadcast_to(np.asarray(bonds.horizon, dtype=float), (cloud.n,))
    per_point = np.asarray(stretch_from_energy(g, E, hor, plane=plane, dim=cloud.dim))
    return np.asarray(np.minimum(per_point[bonds.i], per_point[bonds.j]), dtype=float)


@dataclass
class _Setup:
    """Everything fixed over a run."""

    kernel: Any
    mass: np.ndarray  # (n,)
    mdof: np.ndarray  # (n, d) masses per DOF
    free: np.ndarray  # (n, d) bool
    dofs: np.ndarray
    plain: np.ndarray  # values of dofs (plain conditions; path entries overwritten)
    paths: tuple[Any, ...]
    f_ext: np.ndarray  # (n, d)
    s0: np.ndarray | None
    vj: np.ndarray
    total_v: np.ndarray

    def prescribed(self, cloud: Any, t: float) -> np.ndarray:
        """Prescribed values of ``dofs`` at time ``t``."""
        vals = self.plain.copy()
        if self.paths:
            pd, pv = resolve_dirichlet(cloud, self.paths, t=t)
            vals[np.searchsorted(self.dofs, pd)] = pv
        return vals

    def damage(self, bi: np.ndarray, alive: np.ndarray) -> np.ndarray:
        """Damage index per point from the bond mask."""
        left = np.bincount(bi, weights=self.vj * alive, minlength=self.total_v.size)
        phi = np.zeros(self.total_v.size)
        has = self.total_v > 0
        phi[has] = 1.0 - left[has] / self.total_v[has]
        return np.clip(phi, 0.0, 1.0)


def _setup(problem: StaticProblem, density: Any, linear: bool, s0: Any, G0: Any) -> _Setup:
    cloud = problem.cloud
    n, d = cloud.n, cloud.dim
    bonds = problem.get_bonds()
    kernel = force_kernel(problem.model, cloud, bonds, linear=linear)
    thresholds = _thresholds(problem, bonds, s0, G0)
    if thresholds is not None and not kernel.damage:
        raise ModelError(
            f"bond damage during time stepping supports BondBased, LPS and XOSB, got "
            f"{type(problem.model).__name__}"
        )
    mass = nodal_masses(cloud, density)
    dofs, plain = resolve_dirichlet(cloud, problem.dirichlet, t=0.0)
    free = np.ones(n * d, dtype=bool)
    free[dofs] = False
    f_ext = load_vector(cloud, problem.loads, prescribed=dofs).reshape(n, d)
    vj = np.asarray(bonds.volume_j, dtype=float)
    return _Setup(
        kernel=kernel,
        mass=mass,
        mdof=np.repeat(mass, d).reshape(n, d),
        free=free.reshape(n, d),
        dofs=dofs,
        plain=plain,
        paths=tuple(bc for bc in problem.dirichlet if isinstance(bc.value, TimePath)),
        f_ext=f_ext,
        s0=thresholds,
        vj=vj,
        total_v=np.bincount(np.asarray(bonds.i), weights=vj, minlength=n),
    )


def _time_step(
    problem: StaticProblem,
    density: Any,
    dt: Any,
    safety: float,
    method: str,
    check_dt: bool,
) -> tuple[float, TimeStepEstimate | None]:
    """Return the run's time step and the estimate; warn when a given step exceeds it."""
    if not (isinstance(safety, int | float) and 0 < safety <= 1):
        raise InputError(f"safety must be a number in (0, 1], got {safety!r}")
    if method not in TIME_STEP_METHODS:
        raise InputError(f"time_step must be one of {list(TIME_STEP_METHODS)}, got {method!r}")
    if dt is not None:
        if isinstance(dt, bool) or not isinstance(dt, int | float) or not (0 < dt < math.inf):
            raise InputError(f"dt must be a positive finite number, got {dt!r}")
        if not check_dt:
            return float(dt), None
    est = estimate_time_step(
        problem.model, problem.cloud, problem.get_bonds(), density, method=method
    )
    if dt is None:
        return safety * est.dt, est
    if dt > est.dt:
        warnings.warn(
            f"dt = {dt:.6g} exceeds the estimated stable time step {est.dt:.6g} "
            f"({method} bound, point {est.point}) by {dt / est.dt:.3g}x: the run may blow up",
            TimeStepWarning,
            stacklevel=3,
        )
    return float(dt), est


def solve_explicit(
    problem: StaticProblem,
    t_end: float,
    dt: float | None = None,
    *,
    density: Any,
    u0: Any = None,
    v0: Any = None,
    safety: float = 0.9,
    time_step: str = "gershgorin",
    check_dt: bool = True,
    linear: bool | None = None,
    critical_stretch: Any = None,
    G0: Any = None,
    output_every: int | None = None,
    checkpoint: str | Path | None = None,
    checkpoint_every: int = 1000,
    resume: bool = False,
    progress: Callable[[str], None] | None = None,
    progress_every: float | None = None,
) -> ExplicitResult:
    """Integrate a problem in time with velocity Verlet (explicit central differences).

    Per step ``Δt``: ``v ← v + ½Δt a``; ``u ← u + Δt v`` (prescribed DOFs follow their
    values); bonds stretched beyond the critical stretch break; ``a = M⁻¹(f_int(u) +
    f_ext)``; ``v ← v + ½Δt a``.  Prescribed DOFs get the velocity of their path
    (``(g(t + Δt) - g(t)) / Δt``); plain Dirichlet values are held from ``t = 0``, a
    :class:`~pdlin.TimePath` is evaluated at every step.  Loads are constant in time.

    Parameters
    ----------
    problem : StaticProblem
        Model, points, bonds (``bond_options={"cracks": ...}`` gives pre-existing cracks),
        Dirichlet conditions and loads; no symmetry planes.  Free bodies are allowed.
    t_end : float
        End time (> 0); the run takes :func:`step_count` steps.
    dt : float, optional
        Time step; default ``safety`` times the estimate of ``time_step``.  A ``dt``
        above the estimate warns (:class:`~pdlin.errors.TimeStepWarning`).
    density : float or (n,) array_like
        Mass density per point (per material: one value per point of each material).
    u0, v0 : (n, dim) array_like, optional
        Initial displacement and velocity (default zero).
    safety : float
        Factor in (0, 1] on the estimated stable step when ``dt`` is not given.
    time_step : {'gershgorin', 'silling-askari', 'lanczos'}
        The estimate (:func:`pdlin.dynamics.estimate_time_step`).
    check_dt : bool
        Estimate the stable step also when ``dt`` is given (and warn above it).
    linear : bool, optional
        Linearized kinematics (True) or the exact stretch along the deformed bond
        (False).  Default: False with damage or a ``kinematics='finite'`` model, else True.
    critical_stretch : float or (n_bonds,) array_like, optional
        Critical stretch of the bonds (per bond of ``problem.get_bonds()``): bonds break
        irreversibly, both directions, when their exact stretch exceeds it.
    G0 : float or (n,) array_like, optional
        Critical energy release rate instead: the critical stretch of each bond is the
        smaller of its two points' :func:`pdlin.models.critical_stretch` (plane strain /
        plane stress from the model's ``plane``, or 3D).
    output_every : int, optional
        Store a frame every this many steps (always step 0 and the last step); default
        about 100 frames.
    checkpoint : str or Path, optional
        NPZ file written every ``checkpoint_every`` steps and at the end (atomically).
    checkpoint_every : int
        Steps between checkpoints.
    resume : bool
        Continue from ``checkpoint`` (refused if it was written for another problem, time
        step or damage), also to a later ``t_end``; the state is bitwise that of an
        uninterrupted run (the frames stored before the checkpoint keep their interval).
    progress : callable, optional
        Called with a line at the start, every ``progress_every`` seconds and at the end.
    progress_every : float, optional
        Seconds between progress lines (default 5).

    Returns
    -------
    ExplicitResult
        Frames, energies per step, damage, the time step and its estimate.

    Raises
    ------
    InputTypeError
        ``problem`` is not a :class:`~pdlin.StaticProblem`.
    InputError
        Bad ``t_end``, ``dt``, ``density``, fields, options, or symmetry planes.
    ModelError
        Damage with a model other than BondBased, LPS or XOSB; a history-dependent model.
    InstabilityError
        The fields became non-finite or the mechanical energy exceeded
        ``GROWTH_LIMIT`` times the energy put in (an unstable time step).
    CheckpointError
        ``resume`` with a checkpoint of another problem, or an unreadable one.

    Examples
    --------
    A bar released from a uniform stretch oscillates; velocity Verlet keeps its energy:

    >>> import numpy as np, pdlin
    >>> from pdlin.dynamics import solve_explicit
    >>> cloud = pdlin.grid((50,), spacing=0.02)
    >>> prob = pdlin.StaticProblem(pdlin.BondBased(E=1.0), cloud, ratio=3.015)
    >>> res = solve_explicit(prob, 2.0, density=1.0, u0=1e-3 * cloud.points)
    >>> res.steps, round(res.dt / res.estimate.dt, 3)
    (71, 0.9)
    >>> bool(res.summary()["energy_drift"] < 1e-2), bool(np.isfinite(res.u).all())
    (True, True)
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    if problem.symmetry:
        raise InputError("solve_explicit does not support symmetry planes; model the whole body")
    if isinstance(t_end, bool) or not isinstance(t_end, int | float) or not 0 < t_end < math.inf:
        raise InputError(f"t_end must be a positive finite number, got {t_end!r}")
    t0 = time.perf_counter()
    if problem.bonds is None:  # find the bonds once: every stage below uses these
        problem = dataclasses.replace(problem, bonds=problem.get_bonds())
    cloud = problem.cloud
    n, d = cloud.n, cloud.dim
    u = _field(u0, "u0", n, d)
    v = _field(v0, "v0", n, d)
    damaged = critical_stretch is not None or G0 is not None
    if linear is None:
        linear = not (damaged or getattr(problem.model, "kinematics", "small") == "finite")
    step, est = _time_step(problem, density, dt, safety, time_step, check_dt)
    nsteps = step_count(float(t_end), step)
    every = (
        max(nsteps // 100, 1)
        if output_every is None
        else integer(output_every, "output_every", minimum=1)
    )
    ck_every = integer(checkpoint_every, "checkpoint_every", minimum=1)
    st = _setup(problem, density, bool(linear), critical_stretch, G0)
    fp = fingerprint(problem, st, step, bool(linear))
    ck = None if checkpoint is None else ExplicitCheckpoint(Path(checkpoint), fp)
    run = _Run(problem, st, step, est, u, v)
    if ck is not None and resume:
        ck.restore(run, progress)
    if run.k > nsteps:
        raise InputError(
            f"the checkpoint is at step {run.k} (t = {run.k * step:.6g}), past t_end = {t_end} "
            f"({nsteps} steps)"
        )
    t_setup = time.perf_counter() - t0
    run.loop(nsteps, every, ck, ck_every, progress, progress_every)
    return run.result(nsteps, {"setup": t_setup, "total": time.perf_counter() - t0})


class _Run:
    """The state of a run (what a checkpoint stores) and its steps."""

    def __init__(
        self,
        problem: StaticProblem,
        st: _Setup,
        dt: float,
        est: TimeStepEstimate | None,
        u: np.ndarray,
        v: np.ndarray,
    ) -> None:
        self.problem, self.st, self.dt, self.est = problem, st, dt, est
        cloud = problem.cloud
        self.bi = np.asarray(problem.get_bonds().i)
        self.k = 0
        g0 = st.prescribed(cloud, 0.0)
        uf = u.reshape(-1)
        uf[st.dofs] = g0
        vf = v.reshape(-1)
        vf[st.dofs] = (st.prescribed(cloud, dt) - g0) / dt
        self.u, self.v = u, v
        self.alive = None if st.s0 is None else np.ones(st.s0.size)
        self.f_int, energy, released = self._evaluate(u)
        self.hist: dict[str, list[float]] = {
            "kinetic": [self._kinetic()],
            "strain": [0.0 if energy is None else energy],
            "external_work": [0.0],
            "dissipated": [released],
            "verlet": [self._verlet()],
            "broken": [0.0 if self.alive is None else float(np.sum(self.alive == 0))],
        }
        self.frames: list[tuple[float, np.ndarray, np.ndarray, np.ndarray | None]] = []
        self._frame()
        self.resumed_from = 0
        self.t_steps = 0.0
        #: the largest energy put in so far (initial energy, external work, dissipation)
        self.put_in = 0.0

    # -- pieces of a step ------------------------------------------------------
    def _evaluate(self, u: np.ndarray) -> tuple[np.ndarray, float | None, float]:
        """Break the bonds beyond s0, then the force, the strain energy and the energy released."""
        f, energy, released = self.st.kernel.evaluate(u, self.alive, self.st.s0)
        if not np.all(np.isfinite(f)):
            bad = int(np.flatnonzero(~np.isfinite(f).all(axis=1))[0])
            self._unstable(f"the internal force is not finite at point {bad}")
        return f, energy, released

    def _kinetic(self) -> float:
        st = self.st
        return float(0.5 * np.sum(st.mdof[st.free] * self.v[st.free] ** 2))

    def _verlet(self) -> float:
        st = self.st
        f = (self.f_int + st.f_ext)[st.free]
        return float(self.dt * self.dt / 8.0 * np.sum(f * f / st.mdof[st.free]))

    def _frame(self) -> None:
        dmg = None if self.alive is None else self.st.damage(self.bi, self.alive)
        self.frames.append((self.k * self.dt, self.u.copy(), self.v.copy(), dmg))

    def _unstable(self, why: str) -> None:
        est = "" if self.est is None else f" (estimated stable step {self.est.dt:.6g})"
        raise InstabilityError(
            f"explicit integration unstable at step {self.k + 1} "
            f"(t = {(self.k + 1) * self.dt:.6g}, dt = {self.dt:.6g}{est}): {why}; "
            "reduce dt (safety) or check the model"
        )

    def step(self) -> None:
        """Advance one time step."""
        st, dt, cloud = self.st, self.dt, self.problem.cloud
        free = st.free
        acc = (self.f_int + st.f_ext) / st.mdof
        g_old = np.where(free, st.f_ext, -self.f_int)
        u_old = self.u.copy()
        self.v[free] += 0.5 * dt * acc[free]
        self.u[free] += dt * self.v[free]
        t_new = (self.k + 1) * dt
        uf = self.u.reshape(-1)
        uf[st.dofs] = st.prescribed(cloud, t_new)
        f_new, energy, released = self._evaluate(self.u)
        acc = (f_new + st.f_ext) / st.mdof
        self.v[free] += 0.5 * dt * acc[free]
        vf = self.v.reshape(-1)
        vf[st.dofs] = (st.prescribed(cloud, t_new + dt) - uf[st.dofs]) / dt
        du = self.u - u_old
        g_new = np.where(free, st.f_ext, -f_new)
        work = 0.5 * float(np.sum((g_old + g_new) * du))
        internal = -0.5 * float(np.sum((self.f_int + f_new) * du))
        self.f_int = f_new
        self.k += 1
        h = self.hist
        h["kinetic"].append(self._kinetic())
        h["strain"].append(h["strain"][-1] + internal if energy is None else energy)
        h["external_work"].append(h["external_work"][-1] + work)
        h["dissipated"].append(h["dissipated"][-1] + released)
        h["verlet"].append(self._verlet())
        h["broken"].append(0.0 if self.alive is None else float(np.sum(self.alive == 0)))
        self._check_growth()

    def _check_growth(self) -> None:
        h = self.hist
        mech = h["kinetic"][-1] + h["strain"][-1]
        put_in = (
            h["kinetic"][0]
            + abs(h["strain"][0])
            + max(abs(w) for w in h["external_work"][-2:])
            + h["dissipated"][-1]
        )
        self.put_in = max(self.put_in, put_in)
        if not math.isfinite(mech) or mech > GROWTH_LIMIT * self.put_in:
            self.k -= 1
            self._unstable(
                f"the mechanical energy {mech:.3e} exceeds {GROWTH_LIMIT:g}x the energy put in "
                f"({self.put_in:.3e})"
            )

    # -- the loop --------------------------------------------------------------
    def loop(
        self,
        nsteps: int,
        every: int,
        ck: ExplicitCheckpoint | None,
        ck_every: int,
        progress: Callable[[str], None] | None,
        progress_every: float | None,
    ) -> None:
        """Run the steps ``k + 1 .. nsteps``, storing frames and checkpoints."""
        say = progress or (lambda msg: None)
        tick = Throttle(say, progress_every)
        k_start = self.k
        say(
            f"explicit: {nsteps:,} steps of dt = {self.dt:.4g} to t = {nsteps * self.dt:.4g}"
            + (
                ""
                if self.est is None
                else f" (stable estimate {self.est.dt:.4g}, {self.est.method})"
            )
            + (f", resuming at step {k_start:,}" if k_start else "")
        )
        t0 = time.perf_counter()
        while self.k < nsteps:
            self.step()
            if self.k % every == 0:
                self._frame()
            if ck is not None and self.k % ck_every == 0:
                ck.write(self)
            tick(lambda: self._line(nsteps, t0, k_start))
        self.t_steps = time.perf_counter() - t0
        if ck is not None and self.k % ck_every != 0:
            ck.write(self)
        say(self._line(nsteps, t0, k_start))

    def _line(self, nsteps: int, t0: float, k_start: int) -> str:
        h = self.hist
        per = (time.perf_counter() - t0) / max(self.k - k_start, 1)
        return (
            f"  step {self.k:,}/{nsteps:,} t = {self.k * self.dt:.4g}: "
            f"kinetic {h['kinetic'][-1]:.4g}, "
            f"strain {h['strain'][-1]:.4g}, external work {h['external_work'][-1]:.4g}, "
            f"broken bonds {int(h['broken'][-1]):,}, {per * 1e3:.3g} ms/step"
        )

    def result(self, nsteps: int, timings: dict[str, float]) -> ExplicitResult:
        """Return the result: the stored frames plus the last step."""
        frames = list(self.frames)
        if frames[-1][0] != self.k * self.dt or len(frames) == 0:
            dmg = None if self.alive is None else self.st.damage(self.bi, self.alive)
            frames.append((self.k * self.dt, self.u.copy(), self.v.copy(), dmg))
        h = self.hist
        return ExplicitResult(
            problem=self.problem,
            times=np.array([f[0] for f in frames]),
            u=np.stack([f[1] for f in frames]),
            v=np.stack([f[2] for f in frames]),
            damage=None if self.alive is None else np.stack([np.asarray(f[3]) for f in frames]),
            step_times=np.arange(self.k + 1) * self.dt,
            kinetic=np.asarray(h["kinetic"]),
            strain=np.asarray(h["strain"]),
            external_work=np.asarray(h["external_work"]),
            dissipated=np.asarray(h["dissipated"]),
            verlet=np.asarray(h["verlet"]),
            broken=np.asarray(h["broken"], dtype=np.int64),
            dt=self.dt,
            estimate=self.est,
            alive=np.ones(self.bi.size, dtype=bool) if self.alive is None else self.alive > 0,
            bonds=self.problem.get_bonds(),
            critical_stretch=self.st.s0,
            resumed_from=self.resumed_from,
            timings={**timings, "steps": self.t_steps},
        )
