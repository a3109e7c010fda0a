"""Peridigm's ``Elastic Correspondence`` material: finite kinematics and its hourglass force.

:class:`PeridigmCorrespondence` is :class:`~pdlin.models.correspondence.Correspondence`
with the hypoelastic material :class:`pdlin.constitutive.hypoelastic.Hypoelastic`
(Peridigm's stress update, ``elastic_correspondence.cxx``) plus Peridigm's hourglass
force (``correspondence.cxx``, ``computeHourglassForce``), both in finite kinematics, for
:func:`pdlin.solve_nonlinear`.  Per directed bond ``b = (i → j)`` with ``ξ = x_j - x_i``,
the deformed bond ``y = ξ + u_j - u_i`` and the non-affine part
``z = y - F_i ξ = u_j - u_i - ∇u_i ξ``, Peridigm adds

    q_b = c_i V_i V_j (z·y) y / (|ξ| |y|),   c_i = 18 C_hg K / (π δ_i⁴)

to the nodal force of ``i`` and ``-q_b`` to that of ``j`` (its force densities times the
volumes; ``C_hg`` the deck's ``Hourglass Coefficient``, ``δ_i`` the horizon of ``i``).  The
tangent is written out: with ``s = c_i V_i V_j / |ξ|``,

    ∂q/∂z = s y yᵀ / |y|,
    ∂q/∂y = s [(z·y) I / |y| + y zᵀ / |y| - (z·y) y yᵀ / |y|³],

and ``z = D u - X G u`` (``D`` the bond difference, ``X`` the bond vectors acting on the
owner's gradient), so ``K_hg = Dᵀ(A + B) D - (Dᵀ A X) G``: no ``nb·d``-row matrix of
``z`` is formed.  ``K_hg`` is nonsymmetric (Peridigm's force is not the gradient of an
energy: it holds ``F_i`` as given).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ...constitutive.hypoelastic import Hypoelastic
from ...errors import InputError, ModelError
from ...geometry.bonds import Bonds
from ...geometry.cloud import PointCloud
from ..base import Response
from .gradient import _with_diagonal_blocks
from .model import Correspondence

__all__ = ["PeridigmCorrespondence", "peridigm_hourglass_force"]


def _bond_geometry(cloud: PointCloud, bonds: Bonds, K: float, C: float) -> dict[str, Any]:
    """Per-bond data of Peridigm's hourglass force: i, j, ξ, |ξ| and ``s = c V_i V_j / |ξ|``."""
    i = np.asarray(bonds.i, dtype=np.int64)
    j = np.asarray(bonds.j, dtype=np.int64)
    xi = np.asarray(bonds.xi, dtype=float)
    r = np.asarray(bonds.length, dtype=float)
    vol = np.asarray(cloud.volumes, dtype=float)
    delta = np.asarray(bonds.horizon, dtype=float)
    c = 18.0 * C * K / (np.pi * delta**4)
    return {"i": i, "j": j, "xi": xi, "r": r, "s": c[i] * vol[i] * vol[j] / r}


def peridigm_hourglass_force(
    geom: dict[str, Any], n: int, u: np.ndarray, grad: np.ndarray
) -> np.ndarray:
    """Return Peridigm's nodal hourglass force ``(n, 3)`` (``computeHourglassForce``).

    Parameters
    ----------
    geom : dict
        Bond data (``i``, ``j``, ``xi``, ``r``, ``s``) of
        :meth:`PeridigmCorrespondence.hourglass_geometry`.
    n : int
        Number of points.
    u : (n, 3) ndarray
        Nodal displacement.
    grad : (n, 3, 3) ndarray
        Displacement gradient ``F - I`` per point.

    Returns
    -------
    (n, 3) ndarray
        ``Σ_b q_b`` on ``i`` and ``-q_b`` on ``j`` (module docstring).
    """
    i, j, xi = geom["i"], geom["j"], geom["xi"]
    du = u[j] - u[i]
    y = xi + du
    z = du - np.einsum("bkl,bl->bk", grad[i], xi)
    ny = np.sqrt(np.einsum("bk,bk->b", y, y))
    q = (geom["s"] * np.einsum("bk,bk->b", z, y) / ny)[:, None] * y
    f = np.empty((n, 3))
    for k in range(3):  # three components, each one pass over the bonds
        f[:, k] = np.bincount(i, q[:, k], n) - np.bincount(j, q[:, k], n)
    return f


class PeridigmCorrespondence(Correspondence):
    """Peridigm's ``Elastic Correspondence`` with finite kinematics and its hourglass force.

    The stress is Peridigm's hypoelastic update
    (:class:`pdlin.constitutive.hypoelastic.Hypoelastic`: unrotated rate of deformation,
    Flanagan & Taylor (1987) rotation, ``P = J σ F⁻ᵀ``), the force
    ``f_i = Σ_j V_i V_j ω (P_i K_i⁻¹ + P_j K_j⁻¹) ξ`` of the correspondence model (one
    gradient point per particle, the bonds' ω), plus Peridigm's hourglass force with the
    deck's ``Hourglass Coefficient`` (module docstring).  A nonlinear, history-dependent
    model: solve it with :func:`pdlin.solve_nonlinear`, one load step per Peridigm load
    step (the update depends on the steps, as Peridigm's does).  Its linear operators
    (``stiffness``, ``apply``) are the tangent at ``u = 0``: the correspondence ``K`` of
    the isotropic ``C`` plus the linearized hourglass ``c V_i V_j (e·z) e`` (``e = ξ/|ξ|``),
    nonsymmetric.  3D only.

    Parameters
    ----------
    K, G : float
        Bulk and shear modulus.
    hourglass : float
        Peridigm's ``Hourglass Coefficient`` ``C_hg >= 0`` (0: no hourglass force).
    max_bytes : int, optional
        Memory budget of the assembly plan (see ``Correspondence``).

    Examples
    --------
    A free cube stretched affinely: no hourglass force, and the interior force of the
    uniform stress vanishes where families are complete.

    >>> import numpy as np, pdlin
    >>> from pdlin.models.correspondence import PeridigmCorrespondence
    >>> cloud = pdlin.grid((5, 5, 5), spacing=1.0)
    >>> bonds = pdlin.find_bonds(cloud, 1.6)
    >>> model = PeridigmCorrespondence(K=2.0, G=1.0, hourglass=0.04)
    >>> u = cloud.points @ np.diag([1e-3, 0.0, 0.0])
    >>> r = model.respond(cloud, bonds, u, model.initial_state(cloud, bonds), tangent=True)
    >>> float(np.abs(model.hourglass_force(cloud, bonds, u)).max())
    0.0
    >>> r.tangent.shape, model.symmetric
    ((375, 375), False)
    """

    def __init__(self, K: float, G: float, *, hourglass: float = 0.0, **kwargs: Any) -> None:
        unknown = sorted(set(kwargs) - {"max_bytes"})
        if unknown:
            raise InputError(
                f"PeridigmCorrespondence takes K, G, hourglass and max_bytes, got {unknown[0]!r}"
            )
        if isinstance(hourglass, bool) or not isinstance(hourglass, int | float | np.number):
            raise InputError(f"hourglass must be a number >= 0, got {hourglass!r}")
        if not np.isfinite(hourglass) or hourglass < 0:
            raise InputError(f"hourglass must be a finite number >= 0, got {hourglass}")
        super().__init__(material=Hypoelastic(K=K, G=G), control="none", **kwargs)
        self.hourglass = float(hourglass)
        self.symmetric = False

    # -- the hourglass term ------------------------------------------------------
    def hourglass_geometry(self, cloud: PointCloud, bonds: Bonds) -> dict[str, Any]:
        """Return the per-bond data of the hourglass force (cached per cloud and bonds).

        Parameters
        ----------
        cloud : PointCloud
            The points (3D).
        bonds : Bonds
            Their (directed) bonds.

        Returns
        -------
        dict
            ``i``, ``j``, ``xi``, ``r`` (``|ξ|``), ``s`` (``c_i V_i V_j / |ξ|``).
        """
        if cloud.dim != 3:
            raise ModelError(f"PeridigmCorrespondence is 3D (Peridigm's decks), got {cloud.dim}D")
        p = self._plan(cloud, bonds)
        if "hourglass" not in p._lazy:
            if not np.array_equal(p.gp_owner, np.arange(cloud.n)):
                raise ModelError("PeridigmCorrespondence needs one gradient point per point")
            p._lazy["hourglass"] = _bond_geometry(cloud, bonds, self.material.K, self.hourglass)
        geom: dict[str, Any] = p._lazy["hourglass"]
        return geom

    def hourglass_force(self, cloud: PointCloud, bonds: Bonds, u: np.ndarray) -> np.ndarray:
        """Return Peridigm's nodal hourglass force at ``u`` (finite kinematics).

        Parameters
        ----------
        cloud : PointCloud
            The points (3D).
        bonds : Bonds
            Their bonds.
        u : (n, 3) array_like
            Nodal displacement.

        Returns
        -------
        (n, 3) ndarray
        """
        uu = np.asarray(u, dtype=float).reshape(cloud.n, 3)
        geom = self.hourglass_geometry(cloud, bonds)
        return peridigm_hourglass_force(geom, cloud.n, uu, self.gradient(cloud, bonds, uu))

    def hourglass_tangent(
        self, cloud: PointCloud, bonds: Bonds, u: np.ndarray | None = None
    ) -> sp.csr_array:
        """Return ``K_hg = -∂f_hg/∂u`` at ``u`` (default 0: the linearization).

        Parameters
        ----------
        cloud : PointCloud
            The points (3D).
        bonds : Bonds
            Their bonds.
        u : (n, 3) array_like, optional
            Nodal displacement.

        Returns
        -------
        scipy.sparse.csr_array
            ``(3n, 3n)``, nonsymmetric.
        """
        n = cloud.n
        geom = self.hourglass_geometry(cloud, bonds)
        i, j, xi, s = geom["i"], geom["j"], geom["xi"], geom["s"]
        nb = i.size
        if u is None:
            y, z = xi, np.zeros_like(xi)
        else:
            uu = np.asarray(u, dtype=float).reshape(n, 3)
            du = uu[j] - uu[i]
            y = xi + du
            z = du - np.einsum("bkl,bl->bk", self.gradient(cloud, bonds, uu)[i], xi)
        ny = np.sqrt(np.einsum("bk,bk->b", y, y))
        zy = np.einsum("bk,bk->b", z, y)
        yy = np.einsum("bk,bl->bkl", y, y)
        A = (s / ny)[:, None, None] * yy
        B = (s / ny)[:, None, None] * (
            zy[:, None, None] * np.eye(3)
            + np.einsum("bk,bl->bkl", y, z)
            - (zy / ny**2)[:, None, None] * yy
        )
        W = A + B
        rev = np.asarray(bonds.reverse)
        # Dᵀ W D: bond b = (i → j) adds W at (i, i), (j, j) and -W at (i, j), (j, i); so
        # the block of bond (i → j) is -(W_b + W_rev(b)), the diagonal their family sum
        Ws = W + W[rev]
        K1 = _bond_pattern(bonds, -Ws, np.add.reduceat(Ws, _starts(bonds), axis=0), (3, 3))
        # Dᵀ A X (3 x 9 blocks, columns (g, k, l) of G with entries A[m, k] ξ_l): bond
        # (i → j) adds -A X at (i, i) and +A X at (j, i), i.e. the block of bond (r → q) in
        # row r is the reverse bond's A X, the diagonal minus the family sum
        AX = np.einsum("bmk,bl->bmkl", A, xi).reshape(nb, 3, 9)
        H = _bond_pattern(bonds, AX[rev], -np.add.reduceat(AX, _starts(bonds), axis=0), (3, 9))
        G = self.gradient_matrix(cloud, bonds)
        return sp.csr_array(sp.csr_array(K1) - sp.csr_array(H) @ G)

    # -- nonlinear interface -----------------------------------------------------
    def respond(
        self,
        cloud: PointCloud,
        bonds: Bonds,
        u: np.ndarray,
        state: dict[str, np.ndarray],
        *,
        tangent: bool = False,
    ) -> Response:
        """Return the force, trial state, tangent and Cauchy stress at ``u``.

        The correspondence response of the hypoelastic material
        (``Correspondence.respond``) plus Peridigm's hourglass force and its tangent.

        Parameters
        ----------
        cloud : PointCloud
            The points (3D).
        bonds : Bonds
            Their bonds.
        u : (n, 3) array_like
            Nodal displacement.
        state : dict of str -> ndarray
            Committed state (``initial_state`` or a committed trial state).
        tangent : bool
            Whether to compute ``K_T``.

        Returns
        -------
        Response
            As ``Correspondence.respond``.
        """
        r = super().respond(cloud, bonds, u, state, tangent=tangent)
        if self.hourglass > 0:
            r.force = r.force + self.hourglass_force(cloud, bonds, u)
            if tangent:
                Kt = sp.csr_array(r.tangent) + self.hourglass_tangent(cloud, bonds, u)
                r.tangent = _with_diagonal_blocks(Kt, 3)
        return r

    # -- linear operators: the tangent at u = 0 ----------------------------------
    def stiffness(self, cloud: PointCloud, bonds: Bonds) -> sp.bsr_array:
        """Return the tangent at ``u = 0``: correspondence ``K`` plus the linearized hourglass.

        Parameters
        ----------
        cloud : PointCloud
            The points (3D).
        bonds : Bonds
            Their bonds.

        Returns
        -------
        scipy.sparse.bsr_array
            ``(3n, 3n)``, blocks ``(3, 3)``, nonsymmetric when ``hourglass > 0``.
        """
        K = super().stiffness(cloud, bonds)
        if self.hourglass > 0:
            K = _with_diagonal_blocks(
                sp.csr_array(K) + self.hourglass_tangent(cloud, bonds), cloud.dim
            )
        return K

    def linear_operator(self, cloud: PointCloud, bonds: Bonds) -> spla.LinearOperator:
        """Return the assembled :meth:`stiffness` as a linear operator.

        Parameters
        ----------
        cloud : PointCloud
            The points (3D).
        bonds : Bonds
            Their bonds.

        Returns
        -------
        scipy.sparse.linalg.LinearOperator
        """
        return spla.aslinearoperator(sp.csr_array(self.stiffness(cloud, bonds)))

    def describe(self) -> dict[str, Any]:
        """Return a plain-data description of the model.

        Returns
        -------
        dict
            As ``Correspondence.describe``, with ``hourglass`` and the moduli.
        """
        out = super().describe()
        out.update(
            model="PeridigmCorrespondence",
            K=self.material.K,
            G=self.material.G,
            hourglass=self.hourglass,
        )
        return out

    def _repr_items(self) -> dict[str, Any]:
        return {"K": self.material.K, "G": self.material.G, "hourglass": self.hourglass}


def _starts(bonds: Bonds) -> np.ndarray:
    """First bond of each family (every point has bonds: checked by the plan)."""
    return np.asarray(bonds.indptr[:-1], dtype=np.int64)


def _bond_pattern(
    bonds: Bonds, off: np.ndarray, diag: np.ndarray, blocksize: tuple[int, int]
) -> sp.csr_array:
    """CSR of the bonds' block pattern plus the diagonal: ``off[b]`` at ``(i_b, j_b)``.

    Row ``r`` holds its family's blocks, then its diagonal block ``diag[r]``; built
    straight in BSR (no COO sort), returned as CSR for the sparse products.
    """
    n = bonds.n_points
    ptr = np.asarray(bonds.indptr, dtype=np.int64)
    nb = ptr[-1]
    r = np.arange(n, dtype=np.int64)
    indptr = ptr + np.arange(n + 1, dtype=np.int64)
    indices = np.empty(nb + n, dtype=np.int64)
    data = np.empty((nb + n, *blocksize))
    slot = np.arange(nb, dtype=np.int64) + np.repeat(r, np.diff(ptr))
    indices[slot] = np.asarray(bonds.j, dtype=np.int64)
    data[slot] = off
    indices[ptr[1:] + r] = r
    data[ptr[1:] + r] = diag
    br, bc = blocksize
    M = sp.bsr_array((data, indices, indptr), shape=(n * br, n * bc))
    M.sort_indices()
    return sp.csr_array(M)
