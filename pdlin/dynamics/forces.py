"""Internal forces of explicit dynamics, with a mask of broken bonds.

:func:`force_kernel` returns an object with ``force(u, alive)`` and ``energy(u, alive)``
for a model on fixed (intact, pre-cracked) bonds.  Broken bonds are masked, never
removed: the influence weights, the weighted volumes and XOSB's corrected ``ω^h``,
``ω^d`` stay those of the intact bonds (as in Peridigm's damage models and the XOSB
paper of Liu, Chen & Skelton, §5.3, where ``λ`` is not recomputed after breaking).

* :class:`pdlin.BondBased`: the pair force ``k_b s_b |ξ|`` along the bond
  (``k_b = model.bond_stiffness``), linearized or the exact PMB stretch;
  energy ``¼ Σ_b k_b (s_b |ξ_b|)²`` over directed bonds.
* :class:`pdlin.LPS`, :class:`pdlin.XOSB`: the ordinary state-based force state of
  the model (``linearization='energy'`` or ``'paper'``) with the dilatation and the
  deviatoric sums over the surviving bonds; energy ``Σ_i V_i W_i``
  (``W_i = κθ²/2 + μ Σ_j ω̃^d (e^d)² V_j``, Liu, Chen & Skelton, Eq. 22).
* any other model: ``model.respond`` on the intact bonds (no damage).

With every bond alive each kernel equals the model's own ``internal_force`` to
round-off (``tests/unit/test_explicit.py``).

With numba installed the bond-based and state-based passes run compiled (``pdlin._numba_kernels``:
``bond_force_fill``, ``state_*_fill``) on pdlin's threads, each point on its own family,
from ``2^16`` bonds on or with ``compiled=True``: forces and bond masks bitwise equal to
this module's numpy arithmetic, energies to round-off (``tests/unit/test_explicit_kernels.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError, ModelError
from ..geometry.bonds import Bonds
from ..geometry.cloud import PointCloud
from ..models.bond_based import BondBased
from ..models.ordinary_state import OrdinaryStateBased

__all__ = ["force_kernel", "BondKernel", "StateKernel", "GenericKernel"]


def _measure(cloud: PointCloud) -> float:
    """Out-of-plane measure: thickness (2D), cross-section (1D), 1 (3D)."""
    return 1.0 if cloud.dim == 3 else float(cloud.thickness)


def _scatter(i: np.ndarray, vec: np.ndarray, n: int) -> np.ndarray:
    d = vec.shape[1]
    f = np.empty((n, d))
    for a in range(d):
        f[:, a] = np.bincount(i, weights=vec[:, a], minlength=n)
    return f


def _rowdot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return the row-wise dot ``Σ_k a_k b_k`` summed left to right.

    ``einsum`` pairs the terms in an order of its own (``(a_0 b_0 + a_2 b_2) + a_1 b_1`` for
    three columns in numpy 2.4); the compiled pass sums left to right, and so must this one
    to give the same bits.
    """
    out = a[:, 0] * b[:, 0]
    for k in range(1, a.shape[1]):
        out += a[:, k] * b[:, k]
    return out


class _Geometry:
    """Bond arrays read once (compact bonds compute them on every access)."""

    def __init__(self, cloud: PointCloud, bonds: Bonds) -> None:
        self.n = cloud.n
        self.d = cloud.dim
        self.i = np.asarray(bonds.i)
        self.j = np.asarray(bonds.j)
        self.xi = np.asarray(bonds.xi, dtype=float)
        self.length = np.asarray(bonds.length, dtype=float)
        self.unit = self.xi / self.length[:, None]
        self.reverse = np.asarray(bonds.reverse)

    def extension(self, u: np.ndarray, linear: bool) -> tuple[np.ndarray, np.ndarray]:
        """Bond extension ``e`` and direction: ``n·η`` and ``n``, or ``|y| - |ξ|`` and ``y/|y|``."""
        eta = np.take(u, self.j, axis=0)
        eta -= np.take(u, self.i, axis=0)
        if linear:
            return _rowdot(self.unit, eta), self.unit
        y = self.xi + eta
        ly = np.sqrt(_rowdot(y, y))
        if np.any(ly <= 0):
            raise InputError("u collapses a bond to zero length; the force is undefined")
        return ly - self.length, y / ly[:, None]

    def stretch(self, u: np.ndarray) -> np.ndarray:
        """Exact stretch ``(|ξ + η| - |ξ|) / |ξ|`` per directed bond."""
        y = np.take(u, self.j, axis=0)
        y -= np.take(u, self.i, axis=0)
        y += self.xi
        return np.sqrt(_rowdot(y, y)) / self.length - 1.0

    def broken_now(
        self, u: np.ndarray, e: np.ndarray, linear: bool, alive: np.ndarray, s0: np.ndarray
    ) -> np.ndarray | None:
        """Bonds (both directions) of ``alive`` whose exact stretch exceeds ``s0``, or None."""
        s = e / self.length if not linear else self.stretch(u)
        new = (alive > 0) & (s > s0)
        if not new.any():
            return None
        return new | new[self.reverse]


#: bonds per chunk of the compiled bond-based pass (fixed: the bits do not depend on threads)
_CHUNK_BONDS = 1 << 15


def _compiled_kernels(n_bonds: int, compiled: bool | None) -> Any:
    """Return pdlin's numba kernels for a force pass over ``n_bonds`` bonds, or None (numpy).

    ``compiled=None`` decides by size: a time loop repeats the pass thousands of times, so
    from ``2^16`` bonds on (``use_numba(16 n_bonds)``) the compiled pass pays for numba's
    import; ``True`` uses them whenever numba is installed, ``False`` never.
    """
    from .._kernels import compiled_kernels, use_numba

    if compiled is None:
        return compiled_kernels() if use_numba(16 * n_bonds) else None
    return compiled_kernels() if compiled else None


class _Compiled:
    """Contiguous bond arrays, point chunks and mask checks of the compiled passes."""

    def __init__(self, g: _Geometry, bonds: Bonds) -> None:
        from .._threads import ptr_chunks

        self.indptr = np.asarray(bonds.indptr, dtype=np.int64)
        self.chunks = ptr_chunks(self.indptr, _CHUNK_BONDS)
        self.xi = np.ascontiguousarray(g.xi)
        self.unit = np.ascontiguousarray(g.unit)
        self.j = np.ascontiguousarray(g.j)
        self.rev = np.ascontiguousarray(g.reverse)
        self.none = np.zeros(1)
        self._ones: np.ndarray | None = None
        self._checked: dict[str, Any] = {}

    def ones(self) -> np.ndarray:
        """Return an all-alive mask (read only by the passes)."""
        if self._ones is None:
            self._ones = np.ones(self.j.size)
        return self._ones

    def symmetric(self, name: str, arr: np.ndarray) -> bool:
        """Whether ``arr`` is symmetric under bond reversal (cached for this array object)."""
        if self._checked.get(name) is arr:
            return True
        ok = bool(np.array_equal(arr, arr[self.rev]))
        if ok:
            self._checked[name] = arr
        return ok

    def mask_ok(self, alive: np.ndarray, binary: bool = False) -> bool:
        """Whether the passes may use ``alive`` (float64, contiguous, symmetric, 0/1)."""
        if not (alive.dtype == np.float64 and alive.flags.c_contiguous):
            return False
        if self._checked.get("alive") is alive:
            return True
        if binary and not bool(np.all((alive == 0.0) | (alive == 1.0))):
            return False
        return self.symmetric("alive", alive)


class BondKernel:
    """Bond-based force with a bond mask (see the module docstring).

    With numba installed (and ``compiled`` not False) :meth:`evaluate` and :meth:`force`
    run one compiled pass on pdlin's threads (:func:`pdlin.set_num_threads`): each point
    sums its own family in bond order (chunks of points, no atomics), so the force is
    bitwise the numpy path's for any thread count; the strain energy and the released
    energy are summed per chunk and differ from numpy's ``dot`` by round-off only.

    Parameters
    ----------
    model : BondBased
        The model.
    cloud : PointCloud
        The points.
    bonds : Bonds
        The intact bonds.
    linear : bool
        Linearized stretch (True) or the exact PMB stretch along the deformed bond.
    compiled : bool or None
        Use the numba pass: None (by size), True (whenever numba is installed), False.
    """

    conservative = True
    damage = True

    def __init__(
        self,
        model: BondBased,
        cloud: PointCloud,
        bonds: Bonds,
        linear: bool,
        compiled: bool | None = None,
    ) -> None:
        self.geo = g = _Geometry(cloud, bonds)
        self.k = np.asarray(model.bond_stiffness(cloud, bonds), dtype=float)
        self.linear = linear
        self.kern = _compiled_kernels(g.i.size, compiled)
        if self.kern is not None:
            self.fast = _Compiled(g, bonds)

    def _compiled(
        self, u: np.ndarray, alive: np.ndarray | None, s0: np.ndarray | None
    ) -> tuple[np.ndarray, float, float] | None:
        """Run the compiled pass (force, energy, released); None where numpy must run."""
        fast, g, kern = self.fast, self.geo, self.kern
        breaking = s0 is not None and alive is not None
        mask = alive is not None
        if alive is not None and not fast.mask_ok(alive):
            return None
        if s0 is not None and breaking and not fast.symmetric("s0", s0):
            return None
        from .._threads import thread_map

        uc = np.ascontiguousarray(u, dtype=float)
        f = np.empty((g.n, g.d))
        out = np.zeros((len(fast.chunks), 3))
        al = alive if alive is not None else fast.none
        s0c = np.ascontiguousarray(s0, dtype=float) if breaking else fast.none
        args = (uc, fast.j, fast.indptr, fast.xi, fast.unit, g.length, self.k, al, s0c)
        thread_map(
            lambda c: kern.bond_force_fill(
                *fast.chunks[c], *args, self.linear, mask, breaking, f, out[c],
            ),
            range(len(fast.chunks)),
        )  # fmt: skip
        if np.any(out[:, 2]):
            raise InputError("u collapses a bond to zero length; the force is undefined")
        return f, float(0.25 * np.sum(out[:, 0])), float(0.25 * np.sum(out[:, 1]))

    def force(self, u: np.ndarray, alive: np.ndarray | None) -> np.ndarray:
        """Return the nodal internal force ``(n, d)``.

        Parameters
        ----------
        u : (n, d) ndarray
            Displacement.
        alive : (n_bonds,) ndarray of float or None
            1 for a surviving bond, 0 for a broken one (None: all alive).

        Returns
        -------
        (n, d) ndarray
        """
        if self.kern is not None:
            res = self._compiled(u, alive, None)
            if res is not None:
                return res[0]
        g = self.geo
        e, m = g.extension(u, self.linear)
        k = self.k if alive is None else self.k * alive
        return _scatter(g.i, (k * e)[:, None] * m, g.n)

    def evaluate(
        self, u: np.ndarray, alive: np.ndarray | None, s0: np.ndarray | None = None
    ) -> tuple[np.ndarray, float, float]:
        """Break the bonds stretched beyond ``s0``, then return force and strain energy.

        One pass over the bonds: the extension gives the stretch, the force and the energy.

        Parameters
        ----------
        u : (n, d) ndarray
            Displacement.
        alive : (n_bonds,) ndarray of float or None
            Bond mask, updated in place (broken bonds set to 0).
        s0 : (n_bonds,) ndarray, optional
            Critical stretch per bond (None: no breaking).

        Returns
        -------
        force : (n, d) ndarray
        energy : float
            Strain energy after the breaking.
        released : float
            Strain energy the broken bonds held.
        """
        if self.kern is not None:
            res = self._compiled(u, alive, s0)
            if res is not None:
                return res
        g = self.geo
        e, m = g.extension(u, self.linear)
        released = 0.0
        if s0 is not None and alive is not None:
            new = g.broken_now(u, e, self.linear, alive, s0)
            if new is not None:
                released = float(0.25 * np.dot(self.k[new] * alive[new], e[new] ** 2))
                alive[new] = 0.0
        k = self.k if alive is None else self.k * alive
        tb = k * e
        return _scatter(g.i, tb[:, None] * m, g.n), float(0.25 * np.dot(tb, e)), released

    def energy(self, u: np.ndarray, alive: np.ndarray | None) -> float:
        """Return the strain energy ``¼ Σ_b k_b e_b²`` (directed bonds).

        Parameters
        ----------
        u : (n, d) ndarray
            Displacement.
        alive : (n_bonds,) ndarray of float or None
            Bond mask.

        Returns
        -------
        float
        """
        e, _ = self.geo.extension(u, self.linear)
        k = self.k if alive is None else self.k * alive
        return float(0.25 * np.dot(k, e * e))


class StateKernel:
    """Ordinary state-based (LPS, XOSB) force with a bond mask (see the module docstring).

    Parameters
    ----------
    model : LPS or XOSB
        The model.
    cloud : PointCloud
        The points.
    bonds : Bonds
        The intact bonds (the weights are computed on them once).
    linear : bool
        Linearized extension along the reference direction (True) or the exact one.
    compiled : bool or None
        Use the numba passes: None (by size), True (whenever numba is installed), False.

    Notes
    -----
    With numba, :meth:`evaluate` and :meth:`force` run three compiled passes over the points
    (dilatation and breaking; the force scalar of each bond; the nodal sum over
    ``t_b + t_rev(b)``), each point working on its own family: the force and the bond mask
    equal the numpy path's bitwise, the energies to round-off.
    """

    damage = True

    def __init__(
        self,
        model: OrdinaryStateBased,
        cloud: PointCloud,
        bonds: Bonds,
        linear: bool,
        compiled: bool | None = None,
    ) -> None:
        g = self.geo = _Geometry(cloud, bonds)
        self.linear = linear
        self.variant = model.linearization
        self.conservative = self.variant == "energy"
        w = model.weights(cloud, bonds)
        kappa, mu = model.moduli(g.d)
        vol = np.asarray(cloud.volumes, dtype=float)
        meas = _measure(cloud)
        kap = np.broadcast_to(np.asarray(kappa, dtype=float), (g.n,)).astype(float)
        mub = np.broadcast_to(np.asarray(mu, dtype=float), (g.n,))[g.i]
        vj = np.asarray(bonds.volume_j, dtype=float)
        r = g.length
        self.vj = vj
        self.w = vol[g.i] * vj * meas
        self.a = w.omega_h * r * vj
        self.c = 2.0 * mub * w.omega_d_force
        self.kh = kap[g.i] * w.omega_h_force * r
        self.kth = kap[g.i] * w.omega_h * r
        self.kV = kap * vol * meas
        sf = model.surface_factors(cloud, bonds)
        if sf is not None:
            alpha = np.asarray(sf.dilatation, dtype=float)
            self.c = self.c * sf.bond
            self.kh = self.kh * alpha[g.i]
            self.kth = self.kth * alpha[g.i]
            self.kV = self.kV * alpha
        self.kern = _compiled_kernels(g.i.size, compiled)
        if self.kern is not None:
            self.fast = _Compiled(g, bonds)

    def _compiled(
        self, u: np.ndarray, alive: np.ndarray | None, s0: np.ndarray | None
    ) -> tuple[np.ndarray, float, float] | None:
        """Run the compiled passes (force, energy, released); None where numpy must run."""
        fast, g, kern = self.fast, self.geo, self.kern
        breaking = s0 is not None and alive is not None
        if alive is not None and not fast.mask_ok(alive, binary=True):
            return None
        if s0 is not None and breaking and not fast.symmetric("s0", s0):
            return None
        from .._threads import thread_map

        uc = np.ascontiguousarray(u, dtype=float)
        nb = g.i.size
        al = alive if alive is not None else fast.ones()
        s0c = np.ascontiguousarray(s0, dtype=float) if breaking else fast.none
        e, ed, tw = np.empty(nb), np.empty(nb), np.empty(nb)
        broke = np.empty(nb, dtype=np.uint8)
        theta, z = np.empty(g.n), np.empty(g.n)
        out = np.zeros((len(fast.chunks), 3))
        geo = (uc, fast.j, fast.indptr, fast.xi, fast.unit, g.length)
        energy_variant = self.variant != "paper"
        thread_map(
            lambda c: kern.state_dilatation_fill(
                *fast.chunks[c], *geo, self.a, self.c, self.vj, self.w, self.kV, al, s0c,
                self.linear, breaking, energy_variant, e, ed, broke, theta, z, out[c],
            ),
            range(len(fast.chunks)),
        )  # fmt: skip
        if np.any(out[:, 2]):
            raise InputError("u collapses a bond to zero length; the force is undefined")
        thread_map(
            lambda c: kern.state_force_fill(
                *fast.chunks[c], fast.indptr, self.a, self.c, self.kth, self.kh, self.vj,
                self.w, al, g.d, energy_variant, theta, z, ed, tw,
            ),
            range(len(fast.chunks)),
        )  # fmt: skip
        f = np.empty((g.n, g.d))
        thread_map(
            lambda c: kern.state_scatter_fill(
                *fast.chunks[c], *geo, fast.rev, self.linear, tw, f
            ),
            range(len(fast.chunks)),
        )  # fmt: skip
        after = float(np.sum(out[:, 0]))
        released = float(np.sum(out[:, 1])) - after if breaking else 0.0
        return f, after, released

    def _state(
        self, u: np.ndarray, alive: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        e, m = self.geo.extension(u, self.linear)
        theta, ed = self._dilatation(e, alive)
        return e, m, theta, ed

    def _dilatation(self, e: np.ndarray, alive: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        g = self.geo
        a = self.a if alive is None else self.a * alive
        theta = np.bincount(g.i, weights=a * e, minlength=g.n)
        ed = e - np.take(theta, g.i) * g.length / g.d
        return theta, ed

    def _energy_of(self, theta: np.ndarray, ed: np.ndarray, alive: np.ndarray | None) -> float:
        c = self.c if alive is None else self.c * alive
        return float(0.5 * np.dot(self.kV, theta * theta) + 0.5 * np.dot(self.w * c, ed * ed))

    def _force_of(
        self, m: np.ndarray, theta: np.ndarray, ed: np.ndarray, alive: np.ndarray | None
    ) -> np.ndarray:
        g = self.geo
        thb = np.take(theta, g.i)
        cd = self.c * ed if alive is None else self.c * alive * ed
        if self.variant == "paper":
            t = self.kh * thb + cd
        else:
            z = np.bincount(g.i, weights=cd * g.length * self.vj, minlength=g.n)
            t = (self.kth * thb + cd) - (self.a / self.vj / g.d) * np.take(z, g.i)
        if alive is not None:
            t = t * alive
        tw = self.w * t
        tw = tw + np.take(tw, g.reverse)
        return _scatter(g.i, tw[:, None] * m, g.n)

    def evaluate(
        self, u: np.ndarray, alive: np.ndarray | None, s0: np.ndarray | None = None
    ) -> tuple[np.ndarray, float, float]:
        """Break the bonds stretched beyond ``s0``, then return force and strain energy.

        Parameters
        ----------
        u : (n, d) ndarray
            Displacement.
        alive : (n_bonds,) ndarray of float or None
            Bond mask, updated in place (broken bonds set to 0).
        s0 : (n_bonds,) ndarray, optional
            Critical stretch per bond (None: no breaking).

        Returns
        -------
        force : (n, d) ndarray
        energy : float
            Strain energy after the breaking.
        released : float
            Strain energy lost by the breaking (the energy at ``u`` before minus after).
        """
        if self.kern is not None:
            res = self._compiled(u, alive, s0)
            if res is not None:
                return res
        g = self.geo
        e, m = g.extension(u, self.linear)
        released = 0.0
        if s0 is not None and alive is not None:
            new = g.broken_now(u, e, self.linear, alive, s0)
            if new is not None:
                before = self._energy_of(*self._dilatation(e, alive), alive)
                alive[new] = 0.0
                theta, ed = self._dilatation(e, alive)
                released = before - self._energy_of(theta, ed, alive)
                return self._force_of(m, theta, ed, alive), before - released, released
        theta, ed = self._dilatation(e, alive)
        return self._force_of(m, theta, ed, alive), self._energy_of(theta, ed, alive), released

    def force(self, u: np.ndarray, alive: np.ndarray | None) -> np.ndarray:
        """Return the nodal internal force ``(n, d)``.

        Parameters
        ----------
        u : (n, d) ndarray
            Displacement.
        alive : (n_bonds,) ndarray of float or None
            1 for a surviving bond, 0 for a broken one (None: all alive).

        Returns
        -------
        (n, d) ndarray
        """
        if self.kern is not None:
            res = self._compiled(u, alive, None)
            if res is not None:
                return res[0]
        _, m, theta, ed = self._state(u, alive)
        return self._force_of(m, theta, ed, alive)

    def energy(self, u: np.ndarray, alive: np.ndarray | None) -> float:
        """Return ``Σ_i V_i W_i``, ``W_i = κθ²/2 + ½ Σ_j c (e^d)² V_j`` on the surviving bonds.

        Parameters
        ----------
        u : (n, d) ndarray
            Displacement.
        alive : (n_bonds,) ndarray of float or None
            Bond mask.

        Returns
        -------
        float
        """
        _, _, theta, ed = self._state(u, alive)
        return self._energy_of(theta, ed, alive)


class GenericKernel:
    """Any model: ``model.respond`` on the intact bonds (elastic, no damage, no history).

    Parameters
    ----------
    model : Model
        The model.
    cloud : PointCloud
        The points.
    bonds : Bonds
        The bonds.
    linear : bool
        Ignored for models with ``nonlinear = True`` (their ``respond`` decides).
    """

    conservative = False
    damage = False

    def __init__(self, model: Any, cloud: PointCloud, bonds: Bonds, linear: bool) -> None:
        self.model, self.cloud, self.bonds = model, cloud, bonds
        self.state = model.initial_state(cloud, bonds)
        self.linear = linear

    def force(self, u: np.ndarray, alive: np.ndarray | None) -> np.ndarray:
        """Return the nodal internal force ``(n, d)``.

        Parameters
        ----------
        u : (n, d) ndarray
            Displacement.
        alive : None
            Must be None (this kernel has no damage).

        Returns
        -------
        (n, d) ndarray
        """
        if getattr(self.model, "nonlinear", False):
            resp = self.model.respond(self.cloud, self.bonds, u, self.state)
            return np.asarray(resp.force, dtype=float).reshape(u.shape)
        f = self.model.internal_force(self.cloud, self.bonds, u, linear=self.linear)
        return np.asarray(f, dtype=float).reshape(u.shape)

    def evaluate(
        self, u: np.ndarray, alive: np.ndarray | None, s0: np.ndarray | None = None
    ) -> tuple[np.ndarray, None, float]:
        """Return the force, no energy (the driver integrates the work) and nothing released.

        Parameters
        ----------
        u : (n, d) ndarray
            Displacement.
        alive : None
            Must be None.
        s0 : None
            Must be None.

        Returns
        -------
        force : (n, d) ndarray
        energy : None
        released : float
            0.
        """
        return self.force(u, alive), None, 0.0

    energy = None


def force_kernel(
    model: Any, cloud: PointCloud, bonds: Bonds, *, linear: bool, compiled: bool | None = None
) -> BondKernel | StateKernel | GenericKernel:
    """Return the force kernel of ``model`` on ``bonds`` (see the module docstring).

    Parameters
    ----------
    model : Model
        Any pdlin model; :class:`pdlin.BondBased`, :class:`pdlin.LPS` and
        :class:`pdlin.XOSB` get kernels with bond damage.
    cloud : PointCloud
        The points.
    bonds : Bonds
        The intact (pre-cracked) bonds.
    linear : bool
        Linearized kinematics (True) or the exact stretch / extension along the deformed
        bond (False).
    compiled : bool or None
        :class:`BondKernel`'s numba pass: None (by size: from ``2^16`` bonds with numba
        installed), True (whenever numba is installed), False (numpy).

    Returns
    -------
    BondKernel or StateKernel or GenericKernel
        An object with ``force(u, alive)``, ``energy`` (a method, or None) and the flags
        ``damage`` (bond masks supported) and ``conservative``.

    Raises
    ------
    ModelError
        A history-dependent model (a ``material`` with an initial state), which explicit
        dynamics does not commit.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((6, 4), spacing=0.1)
    >>> bonds = pdlin.find_bonds(cloud, ratio=2.015)
    >>> model = pdlin.LPS(E=1.0, nu=0.25)
    >>> kern = force_kernel(model, cloud, bonds, linear=True)
    >>> u = np.random.default_rng(0).normal(size=(24, 2))
    >>> ref = model.internal_force(cloud, bonds, u)
    >>> bool(np.allclose(kern.force(u, None), ref, rtol=1e-13, atol=1e-15))
    True
    """
    if isinstance(model, BondBased):
        if model.kinematics == "finite":
            linear = False
        return BondKernel(model, cloud, bonds, linear, compiled)
    if isinstance(model, OrdinaryStateBased):
        return StateKernel(model, cloud, bonds, linear, compiled)
    kern = GenericKernel(model, cloud, bonds, linear)
    if kern.state:
        raise ModelError(
            f"{type(model).__name__} has a history state ({', '.join(sorted(kern.state))}); "
            "explicit dynamics supports elastic models only"
        )
    return kern
