"""Small linear-elastic Q4 and Hex8 finite-element solvers, used as verification references.

A vectorized bilinear-quadrilateral (Q4) assembly with 2 x 2 Gauss quadrature for plane
stress or plane strain, and a direct (SuperLU) or AMG-CG solve with prescribed nodal
displacements.  It is the FE reference for the plate with a central hole of Liu, Chen &
Skelton, XOSB, §5.1, used by
``tests/verification/test_xosb_plate.py`` and ``examples/plate_with_hole_xosb.py``.

Its 3D counterpart is the trilinear hexahedron (Hex8, 2 x 2 x 2 Gauss, isotropic), the
reference for the 3D brick of Luo & Sundararaghavan (2018), §5.3 (nodes at the particles),
and the extruded plate with a hole of the XOSB paper, §5.2: :func:`hex8_stiffness` and
:func:`solve_hex8`.

It is a verification utility, not part of pdlin's peridynamic API: a single homogeneous
isotropic material and no checks beyond positive Jacobians.  :func:`grid_fe_reference` builds
the FE counterpart of a grid problem (nodes at the particles, the problem's own prescribed
displacements and nodal forces): the ``reference = "fem"`` of scene sweeps.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ConvergenceError, InputError, ShapeError

__all__ = [
    "q4_stiffness",
    "solve_q4",
    "plate_extension_q4",
    "evaluate_q4",
    "hex8_stiffness",
    "solve_hex8",
    "grid_fe_reference",
]

_GAUSS = 1.0 / np.sqrt(3.0)


def _elasticity(E: float, nu: float, plane: str) -> np.ndarray:
    """3 x 3 Voigt elasticity matrix (engineering shear strain)."""
    if plane == "stress":
        return E / (1 - nu**2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    if plane == "strain":
        f = E / ((1 + nu) * (1 - 2 * nu))
        return f * np.array([[1 - nu, nu, 0], [nu, 1 - nu, 0], [0, 0, (1 - 2 * nu) / 2]])
    raise ValueError(f"plane must be 'stress' or 'strain', got {plane!r}")


def _scatter(ke: np.ndarray, conn: np.ndarray, dim: int, n: int) -> sp.csr_array:
    """Sum element matrices ``(ne, k·dim, k·dim)`` of connectivity ``(ne, k)`` into CSR."""
    ne, m = ke.shape[0], ke.shape[1]
    dofs = (dim * conn[:, :, None] + np.arange(dim)).reshape(ne, m)
    rows = np.broadcast_to(dofs[:, :, None], (ne, m, m)).ravel()
    cols = np.broadcast_to(dofs[:, None, :], (ne, m, m)).ravel()
    return sp.coo_array((ke.ravel(), (rows, cols)), shape=(dim * n, dim * n)).tocsr()


def q4_stiffness(
    points: Any,
    quads: Any,
    E: float,
    nu: float,
    *,
    plane: str = "stress",
    thickness: float = 1.0,
) -> sp.csr_array:
    """Assemble the global stiffness matrix of a Q4 mesh (2 x 2 Gauss, vectorized).

    Parameters
    ----------
    points : (n, 2) array_like
        Node coordinates (a meshio mesh's ``points[:, :2]``).
    quads : (ne, 4) array_like of int
        Node indices of each quadrilateral, counter-clockwise (meshio ``'quad'`` cells).
        Clockwise elements are accepted too (``|det J|`` is used).
    E, nu : float
        Young's modulus and Poisson's ratio.
    plane : {'stress', 'strain'}
        2D assumption.
    thickness : float
        Out-of-plane thickness multiplying the stiffness.

    Returns
    -------
    scipy.sparse.csr_array
        ``(2n, 2n)`` symmetric stiffness; DOF ``2 i + c`` is component ``c`` of node ``i``.

    Raises
    ------
    ValueError
        If ``quads`` is not ``(ne, 4)`` or an element has a zero Jacobian.

    Examples
    --------
    One unit square element: the stiffness annihilates the three rigid-body modes.

    >>> import numpy as np
    >>> pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> k = q4_stiffness(pts, [[0, 1, 2, 3]], E=1.0, nu=0.3)
    >>> k.shape
    (8, 8)
    >>> rot = np.column_stack([-pts[:, 1], pts[:, 0]]).ravel()
    >>> float(np.abs(k @ rot).max()) < 1e-14
    True
    """
    pts = np.asarray(points, dtype=float)[:, :2]
    q = np.asarray(quads, dtype=np.intp)
    if q.ndim != 2 or q.shape[1] != 4:
        raise ValueError(f"quads must have shape (ne, 4), got {q.shape}")
    n, ne = pts.shape[0], q.shape[0]
    c = _elasticity(E, nu, plane)
    xe = pts[q]  # (ne, 4, 2)
    ke = np.zeros((ne, 8, 8))
    g = _GAUSS
    for xi, eta in ((-g, -g), (g, -g), (g, g), (-g, g)):
        dn = 0.25 * np.array(
            [
                [-(1 - eta), (1 - eta), (1 + eta), -(1 + eta)],
                [-(1 - xi), -(1 + xi), (1 + xi), (1 - xi)],
            ]
        )  # (2, 4) shape-function derivatives in the reference square
        jac = np.einsum("ak,ekb->eab", dn, xe)  # (ne, 2, 2)
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        if np.any(det == 0):
            raise ValueError("degenerate quadrilateral (zero Jacobian)")
        dx = np.linalg.solve(jac, np.broadcast_to(dn, (ne, 2, 4)))  # (ne, 2, 4)
        bm = np.zeros((ne, 3, 8))
        bm[:, 0, 0::2] = dx[:, 0]
        bm[:, 1, 1::2] = dx[:, 1]
        bm[:, 2, 0::2] = dx[:, 1]
        bm[:, 2, 1::2] = dx[:, 0]
        ke += np.einsum("eai,ab,ebj,e->eij", bm, c, bm, np.abs(det))
    ke *= thickness
    return _scatter(ke, q, 2, n)


def solve_q4(
    points: Any,
    quads: Any,
    E: float,
    nu: float,
    fixed: Any,
    values: Any,
    *,
    plane: str = "stress",
    solver: str = "lu",
    rtol: float = 1e-12,
) -> np.ndarray:
    """Solve for the nodal displacements of a Q4 mesh with prescribed DOFs and no external forces.

    Parameters
    ----------
    points, quads, E, nu, plane
        As in :func:`q4_stiffness`.
    fixed : (m,) array_like of int
        Prescribed DOFs (``2 * node + component``); they must remove the rigid-body modes.
    values : float or (m,) array_like
        Their values.
    solver : {'lu', 'amg'}
        ``'lu'``: SuperLU on the free DOFs; ``'amg'``: pdlin's AMG-CG (rigid-body near-null
        space) to ``rtol``, for meshes too large for a direct solve.
    rtol : float
        Relative residual tolerance of ``'amg'``.

    Returns
    -------
    (n, 2) ndarray
        Nodal displacements.

    Examples
    --------
    Uniaxial plane-stress tension of a 2 x 1 patch: exact ``u_y = -nu u0 y / L``.

    >>> import numpy as np
    >>> pts = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], dtype=float)
    >>> quads = [[0, 1, 4, 3], [1, 2, 5, 4]]
    >>> fixed = [0, 1, 6, 4, 10]  # u = 0 at node 0, u_x = 0 at node 3, u_x = 0.02 on x = 2
    >>> u = solve_q4(pts, quads, 1.0, 0.25, fixed, [0, 0, 0, 0.02, 0.02])
    >>> np.round(u[4], 6)
    array([ 0.01  , -0.0025])
    """
    pts = np.asarray(points, dtype=float)[:, :2]
    k = q4_stiffness(pts, quads, E, nu, plane=plane)
    return _solve_prescribed(k, pts, fixed, values, solver, rtol, "Q4")


def _solve_prescribed(
    k: sp.sparray,
    pts: np.ndarray,
    fixed: Any,
    values: Any,
    solver: str,
    rtol: float,
    name: str,
    forces: np.ndarray | None = None,
) -> np.ndarray:
    """Nodal displacements ``(n, dim)`` of ``k u = f`` with ``u[fixed] = values``.

    ``solver='lu'``: SuperLU on the free DOFs, residual checked (1e-8); ``'amg'``: pdlin's
    AMG-CG to ``rtol`` (``solve_linear`` checks its true residual).
    """
    n, dim = pts.shape
    fixed = np.asarray(fixed, dtype=np.intp).ravel()
    if fixed.size and (fixed.min() < 0 or fixed.max() >= dim * n):
        raise InputError(
            f"fixed must be DOFs in [0, {dim * n}), got [{fixed.min()}, {fixed.max()}]"
        )
    vals = np.broadcast_to(np.asarray(values, dtype=float), fixed.shape).copy()
    f = np.zeros(dim * n) if forces is None else np.asarray(forces, dtype=float).reshape(-1)
    u = np.zeros(dim * n)
    u[fixed] = vals
    if solver == "amg":
        import pdlin
        from pdlin.constraints import eliminate_dirichlet
        from pdlin.solvers import solve_linear

        a, b = eliminate_dirichlet(k.tobsr(blocksize=(dim, dim)), f.copy(), fixed, vals)
        modes = pdlin.operators.rigid_body_modes(pts)
        modes[fixed] = 0.0
        info = solve_linear(a, b, "amg-cg", rtol=rtol, near_null=modes, blocksize=dim)
        u = np.array(info.x, dtype=float)
        u[fixed] = vals
        return u.reshape(n, dim)
    if solver != "lu":
        raise InputError(f"solver must be 'lu' or 'amg', got {solver!r}")
    free = np.setdiff1d(np.arange(dim * n), fixed)
    kff = sp.csc_matrix(k[free][:, free])
    rhs = f[free] - (k[free][:, fixed] @ vals)
    u[free] = spla.spsolve(kff, rhs)
    res = float(np.linalg.norm(kff @ u[free] - rhs))
    scale = float(np.linalg.norm(rhs))
    if not np.isfinite(res) or res > 1e-8 * max(scale, np.finfo(float).tiny):
        raise ConvergenceError(
            f"{name} direct solve: relative residual {res / max(scale, 1e-300):.3e} > 1e-8 "
            "(do the fixed DOFs remove the rigid-body modes?)"
        )
    return u.reshape(n, dim)


def plate_extension_q4(
    points: Any,
    quads: Any,
    E: float,
    nu: float,
    u0: float,
    *,
    length: float = 1.0,
    plane: str = "stress",
    solver: str = "lu",
) -> np.ndarray:
    """Solve the FE reference of the XOSB plate (§5.1): prescribed extension of a square plate.

    ``u_x = 0`` on the left edge ``x = -L/2``, ``u_x = u0`` on the right edge ``x = L/2``,
    ``u_y = 0`` at the two edge mid-nodes ``(±L/2, 0)``; top and bottom free.  For the
    plate with a hole, mesh it with :func:`pdlin.plate_with_hole_mesh` (pdlin's reference
    solution uses its O-grid at ``4 x 128 x 240``; the loading is pdlin's reading of the
    paper, which does not state it).

    Parameters
    ----------
    points, quads, E, nu, plane
        As in :func:`q4_stiffness`; the square is centred at the origin.
    u0 : float
        Right-edge displacement.
    length : float
        Side ``L`` of the square.
    solver : {'lu', 'amg'}
        As in :func:`solve_q4`.

    Returns
    -------
    (n, 2) ndarray
        Nodal displacements.

    Raises
    ------
    ValueError
        If the mesh has no nodes on ``x = ±L/2`` including the mid-nodes ``(±L/2, 0)``.

    Examples
    --------
    Without a hole the solution is the affine uniaxial-stress field.

    >>> import numpy as np
    >>> s = np.linspace(-0.5, 0.5, 5)
    >>> pts = np.array([(x, y) for y in s for x in s])
    >>> quads = [[5 * j + i, 5 * j + i + 1, 5 * j + i + 6, 5 * j + i + 5]
    ...          for j in range(4) for i in range(4)]
    >>> u = plate_extension_q4(pts, quads, 70e9, 0.33, 5e-4)
    >>> bool(np.allclose(u, np.column_stack([5e-4 * (pts[:, 0] + 0.5), -0.33 * 5e-4 * pts[:, 1]])))
    True
    """
    pts = np.asarray(points, dtype=float)[:, :2]
    x, y = pts[:, 0], pts[:, 1]
    half = 0.5 * length
    tol = 1e-9 * length
    left = np.flatnonzero(np.abs(x + half) <= tol)
    right = np.flatnonzero(np.abs(x - half) <= tol)
    mid = np.flatnonzero((np.abs(np.abs(x) - half) <= tol) & (np.abs(y) <= tol))
    if left.size == 0 or right.size == 0 or mid.size != 2:
        raise ValueError("the mesh needs nodes on x = ±L/2 including the mid-nodes (±L/2, 0)")
    fixed = np.concatenate([2 * left, 2 * right, 2 * mid + 1])
    vals = np.concatenate([np.zeros(left.size), np.full(right.size, u0), np.zeros(2)])
    return solve_q4(pts, quads, E, nu, fixed, vals, plane=plane, solver=solver)


def evaluate_q4(points: Any, quads: Any, u: Any, xq: Any, *, candidates: int = 8) -> np.ndarray:
    """Evaluate a nodal Q4 field at arbitrary points (the FE interpolant itself).

    Each query point is located in the element whose inverse bilinear map puts it in the
    reference square (Newton's method, among the ``candidates`` elements with the nearest
    centroids), and the field is interpolated with the bilinear shape functions.  Unlike
    ``scipy.interpolate.LinearNDInterpolator`` it needs no Delaunay triangulation (whose
    barycentric transforms are slow on large graded meshes) and reproduces the FE field.

    Parameters
    ----------
    points, quads
        As in :func:`q4_stiffness`.
    u : (n,) or (n, k) array_like
        Nodal values.
    xq : (m, 2) array_like
        Query points, inside the mesh.
    candidates : int
        Elements tried per point.

    Returns
    -------
    (m,) or (m, k) ndarray
        The interpolated values at ``xq`` (the shape of ``u`` per point).

    Raises
    ------
    ValueError
        If a query point lies in none of its candidate elements.

    Examples
    --------
    An affine field is reproduced exactly on a distorted element.

    >>> import numpy as np
    >>> pts = np.array([[0.0, 0.0], [2.0, 0.2], [1.8, 1.5], [-0.1, 1.0]])
    >>> xq = np.array([[0.5, 0.5], [1.2, 0.9]])
    >>> v = evaluate_q4(pts, [[0, 1, 2, 3]], 3 - pts[:, 0] + 4 * pts[:, 1], xq)
    >>> bool(np.allclose(v, 3 - xq[:, 0] + 4 * xq[:, 1]))
    True
    """
    from scipy.spatial import cKDTree

    pts = np.asarray(points, dtype=float)[:, :2]
    q = np.asarray(quads, dtype=np.intp)
    vals = np.asarray(u, dtype=float)
    x = np.atleast_2d(np.asarray(xq, dtype=float))[:, :2]
    m = x.shape[0]
    xe = pts[q]  # (ne, 4, 2)
    k = min(candidates, q.shape[0])
    _, cand = cKDTree(xe.mean(axis=1)).query(x, k=k)
    cand = np.asarray(cand).reshape(m, k)
    found = np.full(m, -1, dtype=np.intp)
    ref = np.zeros((m, 2))
    sx = np.array([-1.0, 1.0, 1.0, -1.0])
    sy = np.array([-1.0, -1.0, 1.0, 1.0])
    for j in range(k):
        todo = np.flatnonzero(found < 0)
        if todo.size == 0:
            break
        el = xe[cand[todo, j]]  # (t, 4, 2)
        xi = np.zeros((todo.size, 2))
        for _ in range(20):  # Newton on the bilinear map
            nv = 0.25 * (1 + sx * xi[:, :1]) * (1 + sy * xi[:, 1:])  # (t, 4)
            dxi = 0.25 * sx * (1 + sy * xi[:, 1:])
            deta = 0.25 * sy * (1 + sx * xi[:, :1])
            res = np.einsum("tk,tkd->td", nv, el) - x[todo]
            jac = np.stack(
                [np.einsum("tk,tkd->td", dxi, el), np.einsum("tk,tkd->td", deta, el)], axis=2
            )  # (t, 2, 2): d x_d / d xi_a
            step = np.linalg.solve(jac, res[:, :, None])[:, :, 0]
            xi = np.clip(xi - step, -3.0, 3.0)
            if np.abs(step).max() < 1e-13:
                break
        inside = np.all(np.abs(xi) <= 1 + 1e-9, axis=1)
        found[todo[inside]] = cand[todo[inside], j]
        ref[todo[inside]] = xi[inside]
    if np.any(found < 0):
        raise ValueError(f"{int(np.sum(found < 0))} query points are outside the mesh")
    nv = 0.25 * (1 + sx * ref[:, :1]) * (1 + sy * ref[:, 1:])  # (m, 4)
    return np.einsum("mk,mk...->m...", nv, vals[q[found]])


# Reference-cube corner signs of the meshio / VTK 'hexahedron' node ordering:
# bottom face (zeta = -1) counter-clockwise seen from +z, then the top face (zeta = +1).
_HEX8_SIGNS = np.array(
    [
        [-1, -1, -1],
        [1, -1, -1],
        [1, 1, -1],
        [-1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [1, 1, 1],
        [-1, 1, 1],
    ],
    dtype=float,
)


def _lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé constants (lambda, mu) of 3D isotropic elasticity, with argument checks."""
    E = float(E)
    nu = float(nu)
    if not np.isfinite(E) or E <= 0:
        raise InputError(f"E must be > 0, got {E}")
    if not -1.0 < nu < 0.5:
        raise InputError(f"nu must be in (-1, 0.5), got {nu}")
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def hex8_stiffness(points: Any, hexes: Any, E: float, nu: float) -> sp.csr_array:
    """Assemble the global stiffness matrix of a trilinear hexahedron (Hex8) mesh, 2 x 2 x 2 Gauss.

    The assembly is vectorized over elements (a loop over the 8 Gauss points only) and
    goes through a COO intermediate, like :func:`q4_stiffness`.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Node coordinates (a meshio mesh's ``points``).
    hexes : (ne, 8) array_like of int
        Node indices of each hexahedron in meshio / VTK ``'hexahedron'`` order: the bottom
        face counter-clockwise seen from the top, then the top face in the same order.
        Mirrored (left-handed) elements are accepted: ``|det J|`` is used.
    E, nu : float
        Young's modulus (> 0) and Poisson's ratio (in (-1, 0.5)); 3D isotropic elasticity.

    Returns
    -------
    scipy.sparse.csr_array
        ``(3n, 3n)`` symmetric stiffness; DOF ``3 i + c`` is component ``c`` of node ``i``.

    Raises
    ------
    pdlin.errors.ShapeError
        If ``points`` is not ``(n, 3)`` or ``hexes`` not ``(ne, 8)``.
    pdlin.errors.InputError
        If an element index is out of range, or the Jacobian determinant of an element is
        zero or changes sign between its Gauss points (degenerate or tangled element).

    Examples
    --------
    One unit cube: the stiffness annihilates the six rigid-body modes.

    >>> import numpy as np
    >>> pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
    ...                 [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float)
    >>> k = hex8_stiffness(pts, [list(range(8))], E=1.0, nu=0.3)
    >>> k.shape
    (24, 24)
    >>> rot_z = np.column_stack([-pts[:, 1], pts[:, 0], np.zeros(8)]).ravel()
    >>> float(np.abs(k @ rot_z).max()) < 1e-14
    True
    """
    pts = np.asarray(points, dtype=float)
    h = np.asarray(hexes, dtype=np.intp)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ShapeError(f"points must have shape (n, 3), got {pts.shape}")
    if h.ndim != 2 or h.shape[1] != 8:
        raise ShapeError(f"hexes must have shape (ne, 8), got {h.shape}")
    n, ne = pts.shape[0], h.shape[0]
    if ne and (h.min() < 0 or h.max() >= n):
        raise InputError(f"hexes must index points in [0, {n}), got [{h.min()}, {h.max()}]")
    lam, mu = _lame(E, nu)
    xe = pts[h]  # (ne, 8, 3)
    # isotropic B^T C B without forming B: for nodes a, b and components i, j,
    # k_(a i)(b j) = sum_gp |det J| (lam N_a,i N_b,j + mu N_a,j N_b,i + mu delta_ij N_a,k N_b,k)
    grads = np.empty((ne, 8, 8, 3))  # (element, Gauss point, node, component) * sqrt|det J|
    sign = np.zeros(ne)
    for p, gp in enumerate(_HEX8_SIGNS / np.sqrt(3.0)):
        # dN_a/dxi_k = s_ak / 8 * prod_{l != k} (1 + s_al xi_l)
        f = 1.0 + _HEX8_SIGNS * gp  # (8, 3)
        dn = np.empty((3, 8))
        dn[0] = _HEX8_SIGNS[:, 0] * f[:, 1] * f[:, 2] / 8
        dn[1] = _HEX8_SIGNS[:, 1] * f[:, 0] * f[:, 2] / 8
        dn[2] = _HEX8_SIGNS[:, 2] * f[:, 0] * f[:, 1] / 8
        jac = np.einsum("ka,eal->ekl", dn, xe)  # (ne, 3, 3): d x_l / d xi_k
        det = np.linalg.det(jac)
        bad = (det == 0) | (sign * det < 0)
        if np.any(bad):
            raise InputError(
                f"hexes must have a Jacobian of one sign; element {int(np.argmax(bad))} "
                "is degenerate or tangled (check the 'hexahedron' node order)"
            )
        sign = np.sign(det)
        dx = np.linalg.solve(jac, np.broadcast_to(dn, (ne, 3, 8)))  # (ne, 3, 8)
        grads[:, p] = dx.transpose(0, 2, 1) * np.sqrt(np.abs(det))[:, None, None]
    g = grads.reshape(ne, 8, 24)
    outer = np.matmul(g.transpose(0, 2, 1), g).reshape(ne, 8, 3, 8, 3)  # sum_gp N_a,i N_b,j
    dot = np.einsum("eaibi->eab", outer)  # sum_gp grad N_a . grad N_b
    ke = lam * outer + mu * outer.transpose(0, 3, 2, 1, 4)
    ke += mu * dot[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]
    ke = ke.reshape(ne, 24, 24)
    return _scatter(ke, h, 3, n)


def solve_hex8(
    points: Any,
    hexes: Any,
    E: float,
    nu: float,
    fixed: Any,
    values: Any,
    *,
    solver: str = "lu",
    rtol: float = 1e-12,
) -> np.ndarray:
    """Solve for the nodal displacements of a Hex8 mesh with prescribed DOFs and no external forces.

    The 3D counterpart of :func:`solve_q4` (same arguments, without ``plane``).

    Parameters
    ----------
    points, hexes, E, nu
        As in :func:`hex8_stiffness`.
    fixed : (m,) array_like of int
        Prescribed DOFs (``3 * node + component``); they must remove the rigid-body modes.
    values : float or (m,) array_like
        Their values.
    solver : {'lu', 'amg'}
        ``'lu'``: SuperLU on the free DOFs; ``'amg'``: pdlin's AMG-CG (smoothed
        aggregation with the six rigid-body modes as near-null space, BSR blocks 3 x 3) to
        ``rtol``, for meshes too large for a direct solve.
    rtol : float
        Relative residual tolerance of ``'amg'``.

    Returns
    -------
    (n, 3) ndarray
        Nodal displacements.

    Raises
    ------
    pdlin.errors.InputError
        On an unknown ``solver``, or ``fixed`` out of range.
    pdlin.errors.ConvergenceError
        If the true relative residual of the free equations exceeds ``1e-8`` (``'lu'``)
        or ``10 rtol`` (``'amg'``).

    Examples
    --------
    Uniaxial tension of two unit cubes along x: exact ``u_y = -nu u0 y / L``.

    >>> import numpy as np
    >>> pts = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1, 2)], float)
    >>> hexes = [[0, 1, 4, 3, 6, 7, 10, 9], [1, 2, 5, 4, 7, 8, 11, 10]]
    >>> x0 = np.flatnonzero(pts[:, 0] == 0)
    >>> x2 = np.flatnonzero(pts[:, 0] == 2)
    >>> fixed = np.concatenate([3 * x0, 3 * x2, [1, 2, 11]])  # + u_y, u_z node 0, u_z node 3
    >>> vals = np.concatenate([np.zeros(4), np.full(4, 0.02), np.zeros(3)])
    >>> u = solve_hex8(pts, hexes, 1.0, 0.25, fixed, vals)
    >>> np.round(u[11], 6)  # node (2, 1, 1)
    array([ 0.02  , -0.0025, -0.0025])
    """
    pts = np.asarray(points, dtype=float)
    k = hex8_stiffness(pts, hexes, E, nu)
    return _solve_prescribed(k, pts, fixed, values, solver, rtol, "Hex8")


def _lattice_cells(cloud: Any) -> tuple[np.ndarray, np.ndarray]:
    """Return the Q4 / Hex8 connectivity between neighbouring lattice points, and their coordinates.

    Cells are kept where all corners exist.
    """
    lat = cloud.lattice
    shape = tuple(int(v) for v in lat.shape)
    flat_node = np.full(int(np.prod(shape)), -1, dtype=np.intp)
    flat = np.arange(cloud.n) if lat.index is None else np.asarray(lat.index, dtype=np.intp)
    flat_node[flat] = np.arange(cloud.n)
    node: np.ndarray = flat_node.reshape(shape)
    if len(shape) == 2:
        corners = [node[:-1, :-1], node[1:, :-1], node[1:, 1:], node[:-1, 1:]]
    else:
        lo = [node[:-1, :-1, :-1], node[1:, :-1, :-1], node[1:, 1:, :-1], node[:-1, 1:, :-1]]
        hi = [node[:-1, :-1, 1:], node[1:, :-1, 1:], node[1:, 1:, 1:], node[:-1, 1:, 1:]]
        corners = lo + hi
    conn = np.stack([c.reshape(-1) for c in corners], axis=1)
    conn = conn[np.all(conn >= 0, axis=1)]
    return conn, np.asarray(cloud.points, dtype=float)


def grid_fe_reference(problem: Any, *, solver: str = "auto") -> np.ndarray:
    """Solve the finite-element counterpart of a grid problem: displacements at its points.

    Q4 (2D) or Hex8 (3D) elements join neighbouring lattice points (the particles are the
    nodes, cells with a missing corner — holes, voids — are left out), with the model's
    isotropic constants (``model.E`` and ``model.nu``, the implied ν for bond-based
    models), the problem's prescribed
    displacements on the same points and its nodal external forces (body and total forces,
    ``pdlin.constraints.load_vector``) as nodal loads.  The FE body is the particles'
    hull, ``h/2`` smaller on every side than the PD body, an O(h) difference that vanishes
    with refinement; it is the ``reference = "fem"`` of scene sweeps.

    Parameters
    ----------
    problem : StaticProblem
        On a :func:`pdlin.grid` (or image) cloud, 2D or 3D, homogeneous isotropic model,
        no symmetry planes.
    solver : {'auto', 'lu', 'amg'}
        'auto': SuperLU up to 60,000 DOFs, AMG-CG above.

    Returns
    -------
    (n, dim) ndarray
        FE displacement at each point of the problem's cloud.

    Raises
    ------
    InputError
        A cloud without a lattice, 1D, symmetry planes, a model without scalar isotropic
        constants, or no cell.

    Examples
    --------
    >>> import numpy as np, pdlin
    >>> cloud = pdlin.grid((20, 5), spacing=0.1)
    >>> prob = pdlin.StaticProblem(pdlin.Correspondence(E=2.0, nu=0.25, plane="stress"),
    ...     cloud, bond_options={"ratio": 2.015},
    ...     dirichlet=[pdlin.Dirichlet("x-", 0.0, "x"), pdlin.Dirichlet([0], 0.0),
    ...                pdlin.Dirichlet("x+", 0.019, "x")])      # strain 0.01 over 1.9
    >>> u = grid_fe_reference(prob)
    >>> y = cloud.points[:, 1] - cloud.points[0, 1]
    >>> bool(np.allclose(u[:, 1], -0.25 * 0.01 * y, atol=1e-14))   # uniaxial stress, exact
    True
    """
    from ..constraints import load_vector, resolve_dirichlet

    cloud = problem.cloud
    d = cloud.dim
    if getattr(cloud, "lattice", None) is None:
        raise InputError("grid_fe_reference needs a grid (lattice) cloud, got a scattered one")
    if d not in (2, 3):
        raise InputError(f"grid_fe_reference needs a 2D or 3D problem, got {d}D")
    if getattr(problem, "symmetry", None):
        raise InputError("grid_fe_reference: symmetry planes are not supported")
    if problem.thermal is not None:
        raise InputError("grid_fe_reference: thermal loads (problem.thermal) are not supported")
    model = problem.model
    E = getattr(model, "E", None)
    nu = getattr(model, "nu", None)
    if nu is None and hasattr(model, "implied_poisson_ratio"):
        nu = model.implied_poisson_ratio(d)  # bond-based: the Cauchy value of its dimension
    if (
        E is None
        or nu is None
        or np.ndim(E)
        or np.ndim(nu)
        or not (np.isfinite(E) and np.isfinite(nu))
    ):
        raise InputError(
            "grid_fe_reference needs one scalar E and nu (homogeneous isotropic), got "
            f"E = {E!r}, nu = {nu!r}"
        )
    conn, pts = _lattice_cells(cloud)
    if conn.shape[0] == 0:
        raise InputError("grid_fe_reference: the grid has no complete cell")
    if d == 2:
        plane = getattr(problem.model, "plane", "stress") or "stress"
        k = q4_stiffness(pts, conn, float(E), float(nu), plane=plane, thickness=cloud.thickness)
    else:
        k = hex8_stiffness(pts, conn, float(E), float(nu))
    dofs, vals = resolve_dirichlet(cloud, problem.dirichlet)
    f = load_vector(cloud, problem.loads)
    if solver == "auto":
        solver = "lu" if d * cloud.n <= 60_000 else "amg"
    name = "Q4" if d == 2 else "Hex8"
    return _solve_prescribed(k, pts, dofs, vals, solver, 1e-12, name, forces=f)
