"""Post-processing fields: nonlocal deformation gradient, strain, stress."""

from __future__ import annotations

import numpy as np

from .errors import InputError, ShapeError
from .geometry.bonds import Bonds
from .geometry.cloud import PointCloud

__all__ = [
    "shape_tensor",
    "deformation_gradient",
    "small_strain",
    "isotropic_stress",
    "von_mises",
]


def _per_point_outer(
    owner: np.ndarray,
    n: int,
    w: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    runs: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """out[p] = Σ_{bonds of p} w a ⊗ b, vectorized with one bincount per entry.

    When the bonds split into consecutive runs whose owners do not interleave (sorted
    owners, as in :class:`Bonds`, or the two half families of a point's stress points),
    fixed runs of about ``_CHUNK`` bonds are summed on the threads, each owner's sum over
    the same bonds in the same order as one global ``np.bincount``: the same bits (with
    numba, each run is one ``nogil`` pass of that arithmetic, since ``np.bincount`` holds
    the GIL and its chunks would run one at a time). ``runs = (bptr, optr)``: the bonds
    ``bptr[k]:bptr[k+1]`` have the owners ``optr[k]:optr[k+1]`` (e.g. the gradient points of
    point ``k``), so the runs are known without a pass over the owners.
    """
    d = a.shape[1]
    nb = owner.size

    def fill(out: np.ndarray, p0: int, p1: int, b0: int, b1: int) -> None:
        own = owner[b0:b1] - p0 if p0 else owner[b0:b1]
        for r in range(d):
            wa = w[b0:b1] * a[b0:b1, r]
            for c in range(d):
                out[p0:p1, r, c] = np.bincount(own, weights=wa * b[b0:b1, c], minlength=p1 - p0)

    if nb < 2 * _CHUNK:
        out = np.empty((n, d, d))
        fill(out, 0, n, 0, nb)
        return out
    from ._kernels import _kernels

    mod = _kernels()
    if mod is not None:  # one nogil pass per run (np.bincount holds the GIL): same sums
        kern = mod.outer_sums_fill
        own_c = np.ascontiguousarray(owner, dtype=np.int64)
        w_c = np.ascontiguousarray(w, dtype=np.float64)
        a_c = np.ascontiguousarray(a, dtype=np.float64)
        b_c = a_c if b is a else np.ascontiguousarray(b, dtype=np.float64)

        def fill(out: np.ndarray, p0: int, p1: int, b0: int, b1: int) -> None:
            kern(p0, p1, b0, b1, own_c, w_c, a_c, b_c, out)

    targets = np.arange(_CHUNK, nb, _CHUNK)
    if runs is not None:
        from ._threads import ptr_chunks

        bptr, optr = runs
        ends = np.array([e for _, e in ptr_chunks(bptr, _CHUNK)][:-1], dtype=np.int64)
        cuts, first = bptr[ends], optr[ends]
    elif bool(np.all(owner[1:] >= owner[:-1])):  # sorted: cut where an owner's run starts
        cuts = np.unique(np.searchsorted(owner, owner[targets], side="left"))
        cuts = cuts[cuts > 0]
        first = owner[cuts]
    else:
        # a cut before bond e is clean when every owner before it is below every one after
        pre_max = np.maximum.accumulate(owner)
        suf_min = np.minimum.accumulate(owner[::-1])[::-1]
        clean = np.flatnonzero(pre_max[:-1] < suf_min[1:]) + 1
        pick = np.searchsorted(clean, targets)
        cuts = np.unique(clean[pick[pick < clean.size]])
        first = suf_min[cuts]
    if cuts.size == 0:
        out = np.empty((n, d, d))
        fill(out, 0, n, 0, nb)
        return out
    from ._threads import thread_map

    b_edges = np.concatenate([[0], cuts, [nb]])
    p_edges = np.concatenate([[0], first, [n]])  # owners of run k: [p_k, p_{k+1})
    out = np.empty((n, d, d))
    spans = [
        (int(p_edges[k]), int(p_edges[k + 1]), int(b_edges[k]), int(b_edges[k + 1]))
        for k in range(b_edges.size - 1)
    ]

    def chunk(span: tuple[int, int, int, int]) -> None:
        fill(out, *span)

    thread_map(chunk, spans)
    return out


#: bonds per chunk of the threaded per-point sums
_CHUNK = 1 << 16


def shape_tensor(bonds: Bonds) -> np.ndarray:
    """Compute the shape tensors ``K_i = Σ_j ω ξ⊗ξ V_j``.

    Parameters
    ----------
    bonds : Bonds
        Bonds with influence values ``omega`` and neighbour volumes ``volume_j``.

    Returns
    -------
    ndarray of float, shape (n, dim, dim)
        Symmetric shape tensor per point (zero for points without bonds).
    """
    w = bonds.omega * bonds.volume_j
    return _per_point_outer(bonds.i, bonds.n_points, w, bonds.xi, bonds.xi)


def deformation_gradient(
    cloud: PointCloud, bonds: Bonds, u: np.ndarray, *, n_owners: int | None = None
) -> np.ndarray:
    """Compute the nonlocal deformation gradient ``F_i = I + [Σ ω η⊗ξ V_j] K_i⁻¹``.

    Exact for affine displacement fields at every point whose shape tensor
    is invertible, boundary points included.

    ``n_owners`` restricts the evaluation to the first points (bonds are
    owner-sorted), e.g. the real points of a cloud extended by mirror
    images; the result then has ``n_owners`` rows.

    Parameters
    ----------
    cloud : PointCloud
        The points.
    bonds : Bonds
        Bonds of ``cloud``.
    u : (n, dim) or (n * dim,) array_like of float
        Displacement per point.
    n_owners : int, optional
        Evaluate only the first ``n_owners`` points.

    Returns
    -------
    ndarray of float, shape (n, dim, dim) or (n_owners, dim, dim)
        Deformation gradient per point.

    Raises
    ------
    ShapeError
        If ``u`` does not hold ``n * dim`` values.
    InputError
        If a shape tensor is singular (a family that does not span the space).

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((4, 4), spacing=0.25)
    >>> bonds = pdlin.find_bonds(cloud, ratio=1.5)
    >>> H = np.array([[1e-3, 2e-3], [0.0, -5e-4]])
    >>> F = deformation_gradient(cloud, bonds, cloud.points @ H.T)
    >>> bool(np.allclose(F, np.eye(2) + H, atol=1e-14))
    True
    """
    d = cloud.dim
    uu = np.asarray(u, dtype=float)
    if uu.size != cloud.n * d:
        raise ShapeError(f"u must have shape ({cloud.n}, {d}), got {uu.shape}")
    uu = uu.reshape(cloud.n, d)
    n = cloud.n if n_owners is None else int(n_owners)
    end = int(bonds.indptr[n])
    i, j, xi = bonds.i[:end], bonds.j[:end], bonds.xi[:end]
    w = bonds.omega[:end] * bonds.volume_j[:end]
    K = _per_point_outer(i, n, w, xi, xi)
    det = np.linalg.det(K)
    scale = np.einsum("nii->n", K) ** d / d**d
    bad = np.flatnonzero(np.abs(det) <= 1e-12 * np.maximum(scale, 1e-300))
    if bad.size:
        raise InputError(
            f"shape tensor is singular at {bad.size} point(s) (first {int(bad[0])}, "
            f"{int(bonds.family_size[bad[0]])} bonds): its family does not span {d}D"
        )
    eta = uu[j] - uu[i]
    N = _per_point_outer(i, n, w, eta, xi)
    Kinv = np.linalg.inv(K)
    return np.eye(d)[None] + N @ Kinv


def small_strain(F: np.ndarray) -> np.ndarray:
    """Compute the small strain ``ε = sym(F) - I``.

    Parameters
    ----------
    F : (..., d, d) ndarray of float
        Deformation gradients.

    Returns
    -------
    ndarray of float, shape of ``F``
        Symmetric small-strain tensors.
    """
    d = F.shape[-1]
    return 0.5 * (F + np.swapaxes(F, -1, -2)) - np.eye(d)


def isotropic_stress(
    strain: np.ndarray, E: float | np.ndarray, nu: float, *, plane: str = "stress"
) -> np.ndarray:
    """Compute the linear isotropic Cauchy stress from small strain.

    2D uses plane stress or plane strain; 1D returns ``E ε``.

    Parameters
    ----------
    strain : (..., d, d) ndarray of float
        Small-strain tensors.
    E : float or (n,) array_like of float
        Young's modulus, scalar or per point (leading axis of ``strain``).
    nu : float
        Poisson ratio.
    plane : {'stress', 'strain'}
        2D assumption (ignored in 1D and 3D).

    Returns
    -------
    ndarray of float, shape of ``strain``
        Stress tensors (units of ``E``).

    Raises
    ------
    InputError
        If (2D or 3D) ``plane`` is not 'stress' or 'strain'.
    """
    d = strain.shape[-1]
    E = np.asarray(E, dtype=float)
    Eb = E[..., None, None] if E.ndim else E
    tr = np.einsum("...ii->...", strain)[..., None, None]
    eye = np.eye(d)
    if d == 1:
        return Eb * strain
    mu = Eb / (2.0 * (1.0 + nu))
    if d == 2 and plane == "stress":
        lam = Eb * nu / (1.0 - nu**2)
    elif d in (2, 3):
        if plane not in ("stress", "strain"):
            raise InputError(f"plane must be 'stress' or 'strain', got {plane!r}")
        lam = Eb * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return lam * tr * eye + 2.0 * mu * strain


def von_mises(stress: np.ndarray) -> np.ndarray:
    """Compute the von Mises equivalent stress.

    Parameters
    ----------
    stress : (..., d, d) ndarray of float
        Stress tensors; 2D tensors are taken with zero out-of-plane stress.

    Returns
    -------
    ndarray of float, shape ``stress.shape[:-2]``
        ``sqrt(3 J2)`` per tensor.
    """
    d = stress.shape[-1]
    tr = np.einsum("...ii->...", stress)
    dev = stress - tr[..., None, None] / 3.0 * np.eye(d)
    j2 = 0.5 * np.einsum("...ij,...ij->...", dev, dev)
    if d == 2:
        j2 = j2 + 0.5 * (tr / 3.0) ** 2  # the out-of-plane deviatoric entry
    return np.sqrt(3.0 * j2)
