"""The constrained system's functions: prescribed DOFs, loads, rigid-motion checks, elimination.

:class:`~pdlin.system.ConstrainedSystem` is built and solved with these: the
Dirichlet conditions of a problem become sorted prescribed DOFs and values
(:func:`resolve_dirichlet`), its loads a nodal force vector (:func:`load_vector`),
the prescribed DOFs are checked to remove every rigid motion
(:func:`check_constraints`) and eliminated from ``K u = f`` keeping K's block
structure (:func:`eliminate_dirichlet`, :func:`matrix_rows` for the reactions).
The PETSc backend eliminates its own rows with the same rule.  The conditions
themselves (data: :class:`~pdlin.Dirichlet`, :class:`~pdlin.BodyForce`,
:class:`~pdlin.TotalForce`) are in :mod:`pdlin.operators`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ._validation import as_float_array
from .errors import FloatingBodyError, InputError, NoNeighborsError, ShapeError
from .geometry.bonds import Bonds
from .geometry.cloud import PointCloud
from .operators.bc import BodyForce, Dirichlet, TimePath, TotalForce, parse_components
from .operators.rigid import rigid_body_modes, rigid_mode_names

if TYPE_CHECKING:
    from .models.thermal import ThermalExpansion

__all__ = [
    "resolve_dirichlet",
    "load_vector",
    "thermal_load",
    "IsolatedPoints",
    "hold_isolated",
    "check_constraints",
    "eliminate_dirichlet",
    "matrix_rows",
]


def _resolve_where(cloud: PointCloud, where: Any, what: str) -> np.ndarray:
    idx = cloud.select(where)
    if idx.size == 0:
        raise InputError(f"{what} selects no points (where={where!r})")
    return idx


def _evaluate(value: Any, pts: np.ndarray, dim: int, name: str) -> np.ndarray:
    """Value spec -> (m, dim) array."""
    m = pts.shape[0]
    if callable(value):
        out = as_float_array(value(pts), f"{name} (callable result)")
    else:
        out = as_float_array(value, name)
    if out.ndim == 0:
        return np.full((m, dim), float(out))
    if out.shape == (dim,):
        return np.broadcast_to(out, (m, dim)).copy()
    if out.shape == (m, dim):
        return out
    if dim == 1 and out.shape == (m,):
        return out[:, None]
    raise ShapeError(f"{name} must be a scalar, shape ({dim},) or ({m}, {dim}), got {out.shape}")


def _evaluate_components(
    value: Any, pts: np.ndarray, dim: int, comps: np.ndarray, name: str
) -> np.ndarray:
    """Dirichlet value spec -> ``(m, k)`` values of the ``k`` constrained components.

    Accepted: the full-vector forms of :func:`_evaluate` (scalar, ``(dim,)``,
    ``(m, dim)``) and one column per named component: ``(k,)``, ``(m, k)``,
    and ``(m,)`` when one component is named.
    """
    m, k = pts.shape[0], comps.size
    if callable(value):
        out = as_float_array(value(pts), f"{name} (callable result)")
        # a callable's result is per point first: (m, k), (m,) for one component, (m, dim)
        if out.shape == (m, k):
            return out
        if k == 1 and out.shape == (m,):
            return out[:, None]
    else:
        out = as_float_array(value, name)
        if k == 1 and m == dim != 1 and out.shape == (m,):
            raise ShapeError(
                f"{name} of shape ({m},) is ambiguous for {m} point(s) in {dim}D with one "
                f"constrained component: pass ({m}, 1) for one value per point or a scalar / "
                f"({dim},) vector for all points"
            )
    if out.ndim == 0:
        return np.full((m, k), float(out))
    if out.shape == (dim,):
        return np.broadcast_to(out[comps], (m, k)).copy()
    if out.shape == (m, dim):
        return out[:, comps]
    if out.shape == (k,):
        return np.broadcast_to(out, (m, k)).copy()
    if out.shape == (m, k):
        return out
    if k == 1 and out.shape == (m,):
        return out[:, None]
    shapes = [f"({dim},)", f"({m}, {dim})"]
    if k != dim:
        shapes += [f"({k},)", f"({m}, {k})"]
    if k == 1:
        shapes.append(f"({m},)")
    raise ShapeError(
        f"{name} must be a scalar or have shape {', '.join(dict.fromkeys(shapes))} "
        f"({m} point(s), {k} constrained component(s) of {dim}), got {out.shape}"
    )


def _path_value(value: Any, t: float) -> Any:
    if isinstance(value, TimePath):
        return lambda x: value.fn(x, t)
    return value


def resolve_dirichlet(
    cloud: PointCloud, conditions: Sequence[Dirichlet], *, t: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Collect prescribed DOFs and values; conflicting duplicates raise.

    :class:`~pdlin.operators.TimePath` values are evaluated at time ``t``.

    Parameters
    ----------
    cloud : PointCloud
        The solved points.
    conditions : sequence of Dirichlet
        The conditions (a DOF named twice must get the same value).
    t : float
        Time at which :class:`~pdlin.operators.TimePath` values are evaluated.

    Returns
    -------
    dofs : (m,) sorted ndarray of int
        Prescribed DOFs ``dim * point + component``, each once.
    values : (m,) ndarray
        Their values.

    Raises
    ------
    InputError
        For a condition that is not a Dirichlet, selects no points, or prescribes a DOF
        with two different values.
    ShapeError
        For a value of the wrong shape.
    """
    d = cloud.dim
    all_dofs = []
    all_vals = []
    for k, bc in enumerate(conditions):
        if not isinstance(bc, Dirichlet):
            raise InputError(f"dirichlet[{k}] must be a pdlin Dirichlet, got {type(bc).__name__}")
        idx = _resolve_where(cloud, bc.where, f"dirichlet[{k}]")
        comps = parse_components(bc.components, d)
        value = _path_value(bc.value, t)
        vals = _evaluate_components(value, cloud.points[idx], d, comps, f"dirichlet[{k}].value")
        all_dofs.append((d * idx[:, None] + comps[None, :]).ravel())
        all_vals.append(vals.ravel())
    if not all_dofs:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    dofs = np.concatenate(all_dofs)
    vals = np.concatenate(all_vals)
    order = np.argsort(dofs, kind="stable")
    dofs, vals = dofs[order], vals[order]
    same = np.flatnonzero(dofs[1:] == dofs[:-1])
    if same.size:
        tol = 1e-12 * max(1.0, float(np.max(np.abs(vals))))
        bad = same[np.abs(vals[same + 1] - vals[same]) > tol]
        if bad.size:
            b = int(bad[0])
            raise InputError(
                f"dirichlet conditions conflict: dof {int(dofs[b])} (point {int(dofs[b]) // d}, "
                f"component {int(dofs[b]) % d}) is prescribed as {vals[b]} and {vals[b + 1]}"
            )
        keep = np.ones(dofs.size, dtype=bool)
        keep[same + 1] = False
        dofs, vals = dofs[keep], vals[keep]
    return dofs, vals


def _describe_where(where: Any, idx: np.ndarray) -> str:
    """Short text of a point selection for messages: ``set 'x+'`` or ``12 point(s)``."""
    if isinstance(where, str):
        return f"set {where!r}"
    if where is None:
        return "all points"
    return f"{idx.size} point(s)"


def load_vector(
    cloud: PointCloud,
    loads: Sequence[Any],
    *,
    prescribed: np.ndarray | None = None,
    names: Sequence[str] | None = None,
) -> np.ndarray:
    """Nodal external force vector ``(n*dim,)`` from body forces and total forces.

    Parameters
    ----------
    cloud : PointCloud
        The loaded points (their volumes, and thickness in 2D / cross-section in 1D).
    loads : sequence of BodyForce / TotalForce
        The loads.
    prescribed : (m,) array_like of int, optional
        Prescribed DOFs (Dirichlet conditions, symmetry planes; :func:`resolve_dirichlet`).
        A force on a prescribed DOF never enters the equations of the free DOFs: it is
        balanced by the reaction there.  With them given, a load whose every nonzero nodal
        component sits on a prescribed DOF raises (it would never load the body).  A load of
        which only part does is applied as it is (see docs/boundary_conditions.md).
    names : sequence of str, optional
        Labels of the loads in messages (default ``loads[k]``).

    Returns
    -------
    (n*dim,) ndarray
        Nodal external forces, flat.

    Raises
    ------
    InputError
        A load selects no points, has a bad value or weights, or (with ``prescribed``)
        acts on prescribed DOFs only.

    Examples
    --------
    >>> import pdlin
    >>> cloud = pdlin.grid((3,))
    >>> load_vector(cloud, [TotalForce("x+", [2.0])]).tolist()
    [0.0, 0.0, 2.0]
    >>> load_vector(cloud, [TotalForce("x+", [2.0])], prescribed=[2])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    pdlin.errors.InputError: loads[0] (TotalForce on set 'x+') acts only on prescribed DOFs: ...
    """
    d = cloud.dim
    f = np.zeros((cloud.n, d))
    measure = 1.0 if d == 3 else cloud.thickness
    fixed: np.ndarray | None = None
    if prescribed is not None:
        flat = np.zeros(cloud.n * d, dtype=bool)
        flat[np.asarray(prescribed, dtype=np.intp)] = True
        fixed = flat.reshape(cloud.n, d)
    labels = [f"loads[{k}]" for k in range(len(loads))] if names is None else list(names)
    if len(labels) != len(loads):
        raise ShapeError(f"names must hold one label per load ({len(loads)}), got {len(labels)}")
    for k, ld in enumerate(loads):
        name = labels[k]
        if isinstance(ld, BodyForce):
            idx = _resolve_where(cloud, ld.where, name)
            b = _evaluate(ld.density, cloud.points[idx], d, f"{name}.density")
            part = b * (cloud.volumes[idx] * measure)[:, None]
        elif isinstance(ld, TotalForce):
            idx = _resolve_where(cloud, ld.where, name)
            total = as_float_array(ld.force, f"{name}.force")
            if total.shape != (d,):
                raise ShapeError(f"{name}.force must have shape ({d},), got {total.shape}")
            w = (
                cloud.volumes[idx]
                if ld.weights is None
                else as_float_array(ld.weights, f"{name}.weights")
            )
            if w.shape != idx.shape or np.any(w < 0) or w.sum() <= 0:
                got = (
                    f"shape {w.shape}"
                    if w.shape != idx.shape
                    else f"min {float(w.min())}, sum {float(w.sum())}"
                )
                raise InputError(
                    f"{name}.weights must be {idx.size} non-negative numbers with a "
                    f"positive sum, got {got}"
                )
            part = np.outer(w / w.sum(), total)
        else:
            raise InputError(f"{name} must be BodyForce or TotalForce, got {type(ld).__name__}")
        if fixed is not None:
            _check_load_support(ld, part, fixed[idx], f"{name} ({type(ld).__name__} on "
                                f"{_describe_where(ld.where, idx)})")  # fmt: skip
        np.add.at(f, idx, part)
    return f.ravel()


def thermal_load(
    model: Any, cloud: PointCloud, bonds: Bonds | None, thermal: ThermalExpansion
) -> np.ndarray:
    """Nodal thermal load ``(n*dim,)`` of a temperature change: ``K u = f_ext + f_th``.

    The eigenstrain load of ``pdlin.models.thermal.thermal_force`` (flat), added to
    the loads of the constrained system.

    Parameters
    ----------
    model : Model
        The (linear) model.
    cloud : PointCloud
        The points.
    bonds : Bonds or None
        Their bonds (None: a driver without the bonds, refused).
    thermal : ThermalExpansion
        Temperature change and expansion coefficient.

    Returns
    -------
    (n*dim,) ndarray
        Self-equilibrated nodal forces.

    Raises
    ------
    InputError
        Without bonds (a distributed driver that finds its own).
    ModelError
        For a model without thermal expansion (see ``pdlin.models.thermal``).

    Examples
    --------
    >>> import pdlin
    >>> from pdlin.models.thermal import ThermalExpansion
    >>> cloud = pdlin.grid((4,), spacing=1.0)
    >>> f = thermal_load(pdlin.BondBased(E=1.0), cloud, pdlin.find_bonds(cloud, 1.5),
    ...     ThermalExpansion(1.0, 1e-3))
    >>> abs(float(f.sum())) < 1e-18, float(f[0]) < 0 < float(f[-1])
    (True, True)
    """
    # imported here: pdlin.operators (which the models import) re-exports this module
    from .models.thermal import thermal_force

    if bonds is None:
        raise InputError(
            "thermal needs the bonds of the whole body; this driver has none (the PETSc "
            "backend finds its own): solve thermal problems with pdlin.solve"
        )
    return np.asarray(thermal_force(model, cloud, bonds, thermal), dtype=float).ravel()


def _check_load_support(ld: Any, part: np.ndarray, fixed: np.ndarray, label: str) -> None:
    """Refuse a load that acts on prescribed DOFs only.

    ``part`` is the load's ``(m, dim)`` nodal force on its points and ``fixed`` their
    prescribed components.
    """
    nonzero = part != 0.0
    n_nz = int(nonzero.sum())
    if n_nz == 0:  # a zero load loads nothing anywhere; not a support question
        return
    lost = nonzero & fixed
    n_lost = int(lost.sum())
    if n_lost == n_nz:
        raise InputError(
            f"{label} acts only on prescribed DOFs: all {n_nz} of its nonzero nodal "
            "components sit on displacement components fixed by Dirichlet conditions or "
            "symmetry planes, so it would go straight into the reactions and never load the "
            "body; apply it to free points or components, or drop the conflicting condition"
        )


def check_constraints(
    cloud: PointCloud,
    bonds: Bonds | None,
    dofs: np.ndarray,
    *,
    extra_modes: np.ndarray | None = None,
) -> None:
    """Raise :class:`~pdlin.errors.FloatingBodyError` if rigid motions remain unconstrained.

    Each bond-connected component must have its rigid-body modes removed
    by the prescribed DOFs: the rows of the rigid-mode basis at the
    constrained DOFs must have full column rank.

    Parameters
    ----------
    cloud : PointCloud
        The solved points.
    bonds : Bonds or None
        Their bonds (connectivity); None treats the cloud as one piece.
    dofs : (m,) ndarray of int
        Prescribed DOFs.
    extra_modes : (n*dim, k) array, optional
        Alternative basis of the motions to check (e.g. modes compatible
        with symmetry planes); it applies when the cloud is one piece.

    Raises
    ------
    FloatingBodyError
        When a piece has no prescribed DOF, or the prescribed DOFs leave a rigid motion
        (named in the message) free.
    """
    d = cloud.dim
    if bonds is not None:
        ncomp, labels = connected_components(bonds.adjacency(), directed=False)
    else:
        ncomp, labels = 1, np.zeros(cloud.n, dtype=np.intp)
    constrained = np.zeros(cloud.n * d, dtype=bool)
    constrained[dofs] = True
    point_has = constrained.reshape(cloud.n, d).any(axis=1)
    free_components = np.setdiff1d(np.arange(ncomp), np.unique(labels[point_has]))
    if free_components.size:
        c = int(free_components[0])
        members = np.flatnonzero(labels == c)
        raise FloatingBodyError(
            f"the body is floating: {free_components.size} of {ncomp} bond-connected piece(s) "
            f"have no prescribed displacement (first: {members.size} point(s) starting at index "
            f"{int(members[0])}); add Dirichlet conditions or connect the pieces"
        )
    names = rigid_mode_names(d)
    if ncomp > 50:
        comps_to_check = np.unique(labels)[:50]
    else:
        comps_to_check = np.arange(ncomp)
    for c in comps_to_check:
        members = np.flatnonzero(labels == c) if ncomp > 1 else np.arange(cloud.n)
        if extra_modes is not None and ncomp == 1:
            B = extra_modes
        else:
            B = rigid_body_modes(cloud.points[members])
            if ncomp > 1:
                full = np.zeros((cloud.n * d, B.shape[1]))
                rows = (d * members[:, None] + np.arange(d)).ravel()
                full[rows] = B
                B = full
        if B.shape[1] == 0:
            continue
        # drop modes that vanish on (or repeat other modes on) this piece: a rotation about
        # the line of collinear points moves no point, so it is not a motion to constrain
        keep = _independent_columns(B)
        B = B[:, keep]
        scale = np.linalg.norm(B, axis=0)
        Bc = B[constrained] / scale
        s = np.linalg.svd(Bc, compute_uv=False) if Bc.shape[0] else np.zeros(0)
        rank = int(np.sum(s > 1e-10 * max(1.0, s.max() if s.size else 0.0)))
        if rank < B.shape[1]:
            # name the free motions: null space of Bc
            _, _, vt = np.linalg.svd(Bc if Bc.shape[0] else np.zeros((1, B.shape[1])))
            null = vt[rank:]
            if extra_modes is None:
                labels_free = _free_mode_names(null, keep, names, d)
            else:
                labels_free = [f"mode {int(keep[int(np.argmax(np.abs(v)))])}" for v in null]
            raise FloatingBodyError(
                "the stiffness matrix is singular: constraints leave "
                f"{B.shape[1] - rank} rigid-body "
                f"motion(s) free ({', '.join(sorted(set(labels_free)))}); "
                f"{int(constrained.sum())} DOF(s) are prescribed"
            )


def _free_mode_names(null: np.ndarray, keep: np.ndarray, names: list[str], d: int) -> list[str]:
    """Names of the rigid motions spanned by ``null`` (rows: free combinations of modes).

    A free rotation about a point other than the origin is a rotation plus
    translations (one clamped point leaves the rotation about that point
    free), so the rotations are named first: as many as the rank of the
    null space's rotation part, then the pure translations of what is left.

    Examples
    --------
    >>> names = ["translation x", "translation y", "rotation about z"]
    >>> _free_mode_names(np.array([[0.6, 0.0, 0.8]]), np.arange(3), names, 2)
    ['rotation about z']
    >>> _free_mode_names(np.array([[0.0, 1.0, 0.0]]), np.arange(3), names, 2)
    ['translation y']
    """
    rot = keep >= d
    out: list[str] = []

    def pick(M: np.ndarray, cols: np.ndarray) -> tuple[list[int], int]:
        if M.size == 0 or not cols.any():
            return [], 0
        sub = M[:, cols]
        sv = np.linalg.svd(sub, compute_uv=False)
        r = int(np.sum(sv > 1e-6 * max(1.0, float(sv.max()) if sv.size else 0.0)))
        if r == 0:
            return [], 0
        _, _, piv = scipy.linalg.qr(sub, mode="economic", pivoting=True)
        return [int(keep[cols][p]) for p in piv[:r]], r

    ks, r = pick(null, rot)
    out += [names[k] if k < len(names) else f"mode {k}" for k in ks]
    if r < null.shape[0]:
        # combinations of the free motions without rotation: pure translations
        T = scipy.linalg.null_space(null[:, rot].T).T @ null if r else null
        kt, _ = pick(T, ~rot)
        out += [names[k] if k < len(names) else f"mode {k}" for k in kt]
    return out


def _independent_columns(B: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Find a maximal set of linearly independent columns of ``B`` (pivoted QR).

    Columns are normalized first; a column whose norm is below ``rtol`` times the
    largest is dropped outright.  The indices are returned in ascending order.

    Examples
    --------
    >>> B = np.array([[1.0, 0.0, 2.0], [0.0, 0.0, 0.0], [1.0, 0.0, 2.0]])
    >>> _independent_columns(B).tolist()
    [0]
    """
    norms = np.linalg.norm(B, axis=0)
    if norms.size == 0 or norms.max() == 0:
        return np.zeros(0, dtype=np.intp)
    live = np.flatnonzero(norms > rtol * norms.max())
    Q = B[:, live] / norms[live]
    _, R, piv = scipy.linalg.qr(Q, mode="economic", pivoting=True)
    diag = np.abs(np.diag(R))
    rank = int(np.sum(diag > rtol * max(1.0, float(diag[0]) if diag.size else 0.0)))
    return np.sort(live[piv[:rank]])


def matrix_rows(K: sp.sparray, rows: np.ndarray) -> sp.csr_array:
    """Take some rows of a CSR or BSR matrix as a CSR array.

    For BSR only the block rows that hold ``rows`` are converted (the reactions of a
    solve are taken from K's prescribed rows this way before an in-place elimination).

    Parameters
    ----------
    K : sparse array (CSR or BSR)
        The matrix.
    rows : (k,) array_like of int
        Scalar row indices, in the order wanted.

    Returns
    -------
    csr_array of shape (k, ncols)
        Those rows.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> K = sp.bsr_array(np.arange(16.0).reshape(4, 4), blocksize=(2, 2))
    >>> matrix_rows(K, np.array([3, 0])).toarray().tolist()
    [[12.0, 13.0, 14.0, 15.0], [0.0, 1.0, 2.0, 3.0]]
    """
    rows = np.asarray(rows, dtype=np.intp)
    if isinstance(K, sp.bsr_array | sp.bsr_matrix):
        r = K.blocksize[0]
        brows = np.unique(rows // r)
        starts, ends = K.indptr[brows], K.indptr[brows + 1]
        lengths = ends - starts
        take = np.repeat(starts - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
        indptr = np.zeros(brows.size + 1, dtype=K.indptr.dtype)
        np.cumsum(lengths, out=indptr[1:])
        sub = sp.bsr_array(
            (K.data[take], K.indices[take], indptr),
            shape=(brows.size * r, K.shape[1]),
            blocksize=K.blocksize,
        )
        local = np.searchsorted(brows, rows // r) * r + rows % r
        return sp.csr_array(sp.csr_array(sub)[local])
    return sp.csr_array(sp.csr_array(K)[rows])


def _block_positions(indptr: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions in ``data`` of the (block) rows ``rows`` of a CSR / BSR matrix, and their rows.

    Sizes proportional to those rows' entries only (no array of the matrix's size).
    """
    starts = indptr[rows]
    lengths = indptr[rows + 1] - starts
    take = np.repeat(starts - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
    return take, np.repeat(rows, lengths)


def eliminate_dirichlet(
    K: sp.sparray, f: np.ndarray, dofs: np.ndarray, values: np.ndarray, *, inplace: bool = False
) -> tuple[sp.sparray, np.ndarray]:
    """Eliminate prescribed DOFs, keeping the matrix size and block structure.

    Returns ``(A, b)`` where the prescribed rows and columns of ``K`` are
    replaced by identity rows/columns scaled to the mean diagonal
    (symmetric elimination: ``b_free = f_free - K_fc u_c``, ``b_c = s u_c``).
    The free block equals the condensed matrix ``K_ff``, so ``A`` stays SPD
    and BSR with blocksize dim, which AMG needs.

    Parameters
    ----------
    K : sparse array (CSR or BSR) of shape (ndof, ndof)
        The stiffness; a BSR K keeps its block structure and needs its diagonal blocks
        stored.
    f : (ndof,) ndarray
        External force.
    dofs : (m,) ndarray of int
        Prescribed DOFs (see :func:`resolve_dirichlet`).
    values : (m,) ndarray
        Their values.
    inplace : bool
        Overwrite K's data (saves a copy of the largest array).

    Returns
    -------
    A : sparse array of shape (ndof, ndof)
        ``K`` with the prescribed rows and columns replaced by ``s I``, ``s`` the mean
        of ``|K_ii|`` over the free DOFs (1 when none is free).
    b : (ndof,) ndarray
        ``f - K u_c`` on the free rows, ``s u_c`` on the prescribed ones.

    Raises
    ------
    ShapeError
        When ``f`` does not match ``K``.
    """
    ndof = K.shape[0]
    if f.shape != (ndof,):
        raise ShapeError(f"f must have shape ({ndof},), got {f.shape}")
    uc = np.zeros(ndof)
    uc[dofs] = values
    b = f - K @ uc
    free = np.ones(ndof, dtype=bool)
    free[dofs] = False
    A = K if inplace else K.copy()
    diag = K.diagonal()
    s = float(np.mean(np.abs(diag[free]))) if free.any() else 1.0
    if isinstance(A, sp.bsr_array | sp.bsr_matrix):
        # only the blocks in prescribed block rows or block columns change: no index or
        # mask array of K's size beyond one boolean per block (the column test)
        r, c = A.blocksize
        free_r, free_c = free.reshape(-1, r), free.reshape(-1, c)
        brows = np.flatnonzero(~free_r.all(axis=1))
        take, owner = _block_positions(A.indptr, brows)
        A.data[take] *= free_r[owner][:, :, None]
        fixed_bcol = np.asarray(~free_c.all(axis=1))
        in_fixed_col = np.flatnonzero(fixed_bcol[A.indices])
        A.data[in_fixed_col] *= free_c[A.indices[in_fixed_col]][:, None, :]
        # identity on prescribed diagonal entries
        isdiag = owner == A.indices[take]
        pos, rows = take[isdiag], owner[isdiag]
        for k in range(r):
            fixed = ~free[r * rows + k]
            A.data[pos[fixed], k, k] = s
    else:
        A = sp.csr_array(A)
        # a new data array (A may share K's index arrays, which eliminate_zeros compacts)
        keep = free[A.indices]
        keep[_block_positions(A.indptr, np.flatnonzero(~free))[0]] = False
        A.data = A.data * keep
        A.eliminate_zeros()
        A = A + sp.diags_array(np.where(free, 0.0, s), format="csr")
        A = sp.csr_array(A)
    b[~free] = s * uc[~free]
    return A, b


def _embed_bsr(K_sub: sp.sparray, keep: np.ndarray, n: int, d: int) -> sp.bsr_array:
    """Embed a BSR / CSR matrix on the kept points into the full ``(n*d, n*d)`` one.

    The rows and columns of the other points are empty, their diagonal blocks stored
    as zeros (the Dirichlet elimination writes its identity there).
    """
    Kb = sp.bsr_array(K_sub, blocksize=(d, d))
    Kb.sort_indices()
    rows = np.repeat(keep, np.diff(Kb.indptr))
    cols = keep[Kb.indices]
    data = Kb.data
    others = np.setdiff1d(np.arange(n), keep)
    rows = np.concatenate([rows, others])
    cols = np.concatenate([cols, others])
    data = np.concatenate([data, np.zeros((others.size, d, d))])
    order = np.lexsort((cols, rows))
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
    return sp.bsr_array((data[order], cols[order], indptr), shape=(n * d, n * d))


class IsolatedPoints:
    """A discretization whose points without bonds are held at rest (``u = 0``).

    Peridigm keeps points whose horizon reaches no other point (its ``Number_Of_Neighbors``
    is 0; e.g. its ``MultipleHorizons`` deck).  Their equilibrium equations are empty, so the
    model's operators are built on the other points (``drop_isolated``) and embedded: the
    isolated points' rows and columns of K are zero, their internal force is zero and
    :func:`hold_isolated` prescribes their free components to 0.  A load on such a point
    has nothing to carry it and raises.

    Parameters
    ----------
    model : Model
        The model.
    cloud : PointCloud
        All points.
    bonds : Bonds
        Their bonds (``find_bonds(..., allow_isolated=True)``).

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.PointCloud(np.array([[0.0], [1.0], [2.0], [5.0]]), np.ones(4))
    >>> bonds = pdlin.find_bonds(cloud, 1.5, allow_isolated=True)
    >>> disc = IsolatedPoints(pdlin.BondBased(E=1.0), cloud, bonds)
    >>> disc.isolated.tolist(), disc.stiffness().shape
    ([3], (4, 4))
    """

    def __init__(self, model: Any, cloud: PointCloud, bonds: Bonds) -> None:
        from .models.damage import drop_isolated
        from .system import PlainDiscretization

        self.model = model
        self.points = cloud
        self.bonds = bonds
        sub_cloud, sub_bonds, keep = drop_isolated(cloud, bonds)
        #: point indices with bonds (the inner discretization's points, in order)
        self.keep = keep
        #: point indices without bonds
        self.isolated = np.setdiff1d(np.arange(cloud.n), keep)
        self.inner = PlainDiscretization(model, sub_cloud, sub_bonds)

    # -- the Discretization protocol ---------------------------------------
    @property
    def cloud(self) -> PointCloud:
        """All points."""
        return self.points

    @property
    def real_bonds(self) -> Bonds:
        """The bonds of all points."""
        return self.bonds

    @property
    def family_size(self) -> np.ndarray:
        """Bonds per point ``(n,)`` (0 at the isolated points)."""
        return self.bonds.family_size

    def _dofs(self) -> np.ndarray:
        d = self.points.dim
        return (d * self.keep[:, None] + np.arange(d)).ravel()

    def _scatter(self, sub: np.ndarray, fill: Any = 0.0) -> np.ndarray:
        out = np.empty((self.points.n, *np.shape(sub)[1:]))
        out[...] = fill
        out[self.keep] = sub
        return out

    def _sub_u(self, u: Any) -> np.ndarray:
        d = self.points.dim
        return np.asarray(u, dtype=float).reshape(self.points.n, d)[self.keep]

    def stiffness(self) -> sp.sparray:
        """Assemble K on the points with bonds, embedded (empty isolated rows/columns).

        Returns
        -------
        bsr_array of shape (n*dim, n*dim)
        """
        d = self.points.dim
        return _embed_bsr(self.inner.stiffness(), self.keep, self.points.n, d)

    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray:
        """Return ``f_int(u)`` ``(n, dim)``: the model's on the points with bonds, 0 elsewhere.

        Parameters
        ----------
        u : (n, dim) or (n*dim,) array_like
            Displacement.
        linear : bool
            The linearized force.

        Returns
        -------
        (n, dim) ndarray
        """
        return self._scatter(self.inner.internal_force(self._sub_u(u), linear=linear))

    def load_vector(
        self, loads: Sequence[Any], *, prescribed: np.ndarray | None = None
    ) -> np.ndarray:
        """Return the external force on all points (see :func:`load_vector`).

        Parameters
        ----------
        loads : sequence of BodyForce / TotalForce
            The loads.
        prescribed : (m,) ndarray of int, optional
            Prescribed DOFs.

        Returns
        -------
        (n*dim,) ndarray
        """
        return load_vector(self.points, loads, prescribed=prescribed)

    def dirichlet(self) -> list[Dirichlet]:
        """Return no extra conditions (:func:`hold_isolated` adds the isolated points').

        Returns
        -------
        list of Dirichlet
            Empty.
        """
        return []

    def check_constraints(self, dofs: np.ndarray) -> None:
        """Check the rigid motions of every bonded piece (isolated points are held).

        Parameters
        ----------
        dofs : (m,) ndarray of int
            Prescribed DOFs (the isolated points' included).

        Raises
        ------
        FloatingBodyError
            As :func:`check_constraints` on the points with bonds.
        """
        d = self.points.dim
        local = np.full(self.points.n, -1, dtype=np.intp)
        local[self.keep] = np.arange(self.keep.size)
        pts = np.asarray(dofs, dtype=np.intp) // d
        ok = local[pts] >= 0
        sub_dofs = d * local[pts[ok]] + np.asarray(dofs)[ok] % d
        self.inner.check_constraints(np.sort(sub_dofs))

    def deformation_gradient(self, u: Any) -> np.ndarray:
        """Return ``F`` per point (the identity at isolated points).

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement.

        Returns
        -------
        (n, dim, dim) ndarray
        """
        F = self.inner.deformation_gradient(self._sub_u(u))
        return self._scatter(F, np.eye(self.points.dim))

    def stress(self, u: Any) -> np.ndarray:
        """Return the model's stress per point (0 at isolated points).

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement.

        Returns
        -------
        (n, dim, dim) ndarray
        """
        return self._scatter(self.inner.stress(self._sub_u(u)))

    def thermal_load(self, thermal: ThermalExpansion) -> np.ndarray:
        """Return the thermal load ``(n*dim,)`` (see :func:`thermal_load`; 0 at isolated points).

        Parameters
        ----------
        thermal : ThermalExpansion
            Temperature change and coefficient of all points.

        Returns
        -------
        (n*dim,) ndarray
        """
        inner = self.inner
        th = thermal.subset(self.points, self.keep)
        f = thermal_load(self.model, inner.points, inner.bonds, th)
        return self._scatter(f.reshape(self.keep.size, -1)).ravel()

    def thermal_stress(self, thermal: ThermalExpansion) -> np.ndarray:
        """Return the stress of the free thermal strain per point (0 at isolated points).

        Parameters
        ----------
        thermal : ThermalExpansion
            Temperature change and coefficient of all points.

        Returns
        -------
        (n, dim, dim) ndarray
        """
        from .models.thermal import thermal_stress

        inner = self.inner
        th = thermal.subset(self.points, self.keep)
        return self._scatter(thermal_stress(self.model, inner.points, inner.bonds, th))

    def initial_state(self) -> dict[str, np.ndarray]:
        """Refuse: the nonlinear drivers do not take isolated points.

        Raises
        ------
        InputError
            Always.
        """
        raise InputError(self._nonlinear_message())

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any:
        """Refuse: the nonlinear drivers do not take isolated points.

        Parameters
        ----------
        u : (n, dim) array_like
            Displacement.
        state : dict of str to ndarray
            Committed state.
        tangent : bool
            Also the tangent.

        Raises
        ------
        InputError
            Always.
        """
        raise InputError(self._nonlinear_message())

    def _nonlinear_message(self) -> str:
        return (
            f"points without bonds ({self.isolated.size}, first index "
            f"{int(self.isolated[0])}) are held at rest by pdlin.solve only; the nonlinear "
            "drivers need a bond at every point"
        )

    def operator(self) -> Any:
        """Return the matrix-free K on all DOFs (the inner operator, embedded).

        Returns
        -------
        LinearOperator of shape (n*dim, n*dim)
        """
        import scipy.sparse.linalg as spla

        inner = self.inner.operator()
        idx = self._dofs()
        ndof = self.points.n * self.points.dim

        def mv(x: np.ndarray) -> np.ndarray:
            y = np.zeros(ndof)
            y[idx] = inner @ np.asarray(x).ravel()[idx]
            return y

        return spla.LinearOperator((ndof, ndof), matvec=mv, dtype=float)

    def surrogate_stiffness(self) -> sp.sparray:
        """Return the inner surrogate stiffness, embedded.

        Returns
        -------
        bsr_array of shape (n*dim, n*dim)
        """
        d = self.points.dim
        return _embed_bsr(self.inner.surrogate_stiffness(), self.keep, self.points.n, d)

    def estimate_nnz_blocks(self) -> int:
        """Estimate the stored blocks of K (the inner ones and the isolated diagonals).

        Returns
        -------
        int
        """
        return int(self.inner.estimate_nnz_blocks()) + int(self.isolated.size)

    def with_model(self, model: Any) -> IsolatedPoints:
        """Return the same points and bonds under another model.

        Parameters
        ----------
        model : Model
            The other model.

        Returns
        -------
        IsolatedPoints
        """
        return IsolatedPoints(model, self.points, self.bonds)


def hold_isolated(
    cloud: PointCloud,
    isolated: np.ndarray,
    dofs: np.ndarray,
    values: np.ndarray,
    f_ext: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Prescribe ``u = 0`` on the free components of points without bonds.

    Parameters
    ----------
    cloud : PointCloud
        The points.
    isolated : (k,) ndarray of int
        Points without bonds.
    dofs, values : ndarray
        The prescribed DOFs and values (:func:`resolve_dirichlet`).
    f_ext : (n*dim,) ndarray
        The external force.

    Returns
    -------
    dofs, values : ndarray
        Sorted, with the isolated points' free components at 0.

    Raises
    ------
    NoNeighborsError
        When a load acts on a free component of such a point (no bond carries it), naming
        the points.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((3,))
    >>> hold_isolated(cloud, np.array([2]), np.array([0]), np.array([0.1]), np.zeros(3))
    (array([0, 2]), array([0.1, 0. ]))
    """
    d = cloud.dim
    cand = (d * np.asarray(isolated, dtype=np.intp)[:, None] + np.arange(d)).ravel()
    new = np.setdiff1d(cand, dofs)
    loaded = new[np.asarray(f_ext)[new] != 0.0]
    if loaded.size:
        pts = np.unique(loaded // d)
        where = ", ".join(f"{int(p)} at {np.round(cloud.points[p], 12).tolist()}" for p in pts[:5])
        more = f" (and {pts.size - 5} more)" if pts.size > 5 else ""
        raise NoNeighborsError(
            f"loads act on {pts.size} point(s) without bonds, which nothing can hold: "
            f"{where}{more}; prescribe their displacement, remove the load there or "
            "increase their horizon"
        )
    all_dofs = np.concatenate([dofs, new])
    all_vals = np.concatenate([values, np.zeros(new.size)])
    order = np.argsort(all_dofs, kind="stable")
    return all_dofs[order], all_vals[order]
