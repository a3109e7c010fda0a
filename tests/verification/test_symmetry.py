"""Symmetry planes: half / quarter / eighth models against the full model.

The reference is always the full model solved with the direct solver; a
reduced model must reproduce its displacements on the shared points to
round-off (the reduced operator is the exact restriction of the full one
to symmetric fields, see docs/symmetry.md), so the tolerances below are
round-off tolerances, not discretization errors.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

import pdlin
from pdlin.errors import FloatingBodyError, InputError, InputTypeError
from pdlin.operators.symmetry import SymmetryPlane, mirror_cloud, symmetry_reduction

RATIO = 3.015  # horizon / spacing of the task statement
ROUNDOFF = 1e-10  # relative agreement demanded between full and reduced models

X, Y, Z = SymmetryPlane("x"), SymmetryPlane("y"), SymmetryPlane("z")


def centered_grid(shape: tuple[int, ...]) -> pdlin.PointCloud:
    """Unit-spacing grid symmetric about every coordinate plane through 0."""
    return pdlin.grid(shape, spacing=1.0, origin=[-0.5 * s for s in shape])


def part(full: pdlin.PointCloud, planes: list[SymmetryPlane]) -> np.ndarray:
    """Indices of the full cloud's points on the '+' side of the planes (plane points kept)."""
    keep = np.ones(full.n, dtype=bool)
    for p in planes:
        keep &= full.points[:, int(p.axis)] > -1e-9
    return np.flatnonzero(keep)


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def symmetric_body_force(x: np.ndarray) -> np.ndarray:
    """b with b(R x) = R b(x) for reflections across every coordinate plane.

    Component k is odd in x_k and even in the other coordinates.
    """
    x2 = x**2
    out = np.empty_like(x)
    for k in range(x.shape[1]):
        out[:, k] = x[:, k] * (1.0 + 0.3 * (x2.sum(axis=1) - x2[:, k]))
    return 1e-3 * out


def symmetric_image(full: pdlin.PointCloud, red: pdlin.PointCloud, planes: list[SymmetryPlane]):
    """For each full point: its image among the reduced points and the reflection signs."""
    q = full.points.copy()
    signs = np.ones_like(q)
    for p in planes:
        k = int(p.axis)
        signs[:, k] = np.sign(q[:, k])  # 0 on the plane: no normal motion there
        q[:, k] = np.abs(q[:, k])
    dist, idx = cKDTree(red.points).query(q)
    assert dist.max() < 1e-12
    return idx, signs


def assert_face_share(res, ref, face: str, planes: list[SymmetryPlane]) -> None:
    """Total reaction on a face of the reduced model vs the full one.

    Each plane that cuts the face (its axis differs from the face's) halves
    the total reaction along the components parallel to that plane; the
    components along its normal cancel in the full model and are carried
    across the plane in the reduced one, so they are not compared.
    """
    face_axis = "xyz".index(face[0])
    cutting = [int(p.axis) for p in planes if int(p.axis) != face_axis]
    keep = [k for k in range(res.u.shape[1]) if k not in cutting]
    np.testing.assert_allclose(
        res.reaction(face)[keep],
        0.5 ** len(cutting) * ref.reaction(face)[keep],
        rtol=ROUNDOFF,
        atol=1e-14,
    )


# --------------------------------------------------------------------------
# 2D plate, even grid (no point on a plane)


def plate_bcs(full_axes: set[int]) -> list[pdlin.Dirichlet]:
    """Symmetric stretching: u_x = +-0.01 on x+-, u_y = -+0.02 on y+-.

    Faces removed by a plane (the '-' face of its axis) are left out.
    """
    out = [
        pdlin.Dirichlet("x+", 0.01, components="x"),
        pdlin.Dirichlet("y+", -0.02, components="y"),
    ]
    if 0 in full_axes:
        out.append(pdlin.Dirichlet("x-", -0.01, components="x"))
    if 1 in full_axes:
        out.append(pdlin.Dirichlet("y-", 0.02, components="y"))
    return out


@pytest.fixture(scope="module")
def plate_full():
    full = centered_grid((16, 12))
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        full,
        dirichlet=plate_bcs({0, 1}),
        loads=[pdlin.BodyForce(None, symmetric_body_force)],
        bond_options={"ratio": RATIO},
    )
    return full, pdlin.solve(prob, solver="direct")


@pytest.mark.parametrize("planes", [[X], [Y], [X, Y]], ids=["half-x", "half-y", "quarter"])
def test_plate_reduced_matches_full(plate_full, planes):
    full, ref = plate_full
    idx = part(full, planes)
    cloud = full.subset(idx)
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        dirichlet=plate_bcs({0, 1} - {int(p.axis) for p in planes}),
        loads=[pdlin.BodyForce(None, symmetric_body_force)],
        bond_options={"ratio": RATIO},
        symmetry=planes,
    )
    res = pdlin.solve(prob, solver="direct", keep_stiffness=True)
    assert rel(res.u, ref.u[idx]) < ROUNDOFF
    # no point lies on a plane, so every reduced reaction is the full one
    assert rel(res.reactions, ref.reactions[idx]) < ROUNDOFF
    assert_face_share(res, ref, "x+", planes)
    K = res.stiffness
    assert abs(K - K.T).max() <= 1e-14 * abs(K).max()
    # fields near the plane use the ghost bonds: equal to the full model's
    assert rel(res.deformation_gradient(), ref.deformation_gradient()[idx]) < ROUNDOFF
    assert rel(res.stress(), ref.stress()[idx]) < ROUNDOFF
    # ... which the real-real bonds alone would not give (this is what can fail)
    F_trunc = pdlin.deformation_gradient(cloud, res.bonds, res.u)
    assert rel(F_trunc, ref.deformation_gradient()[idx]) > 1e-3
    family = res.fields()["family_size"]
    np.testing.assert_array_equal(family, ref.bonds.family_size[idx])
    assert np.any(res.bonds.family_size < family)


# --------------------------------------------------------------------------
# 2D plate, odd grid: points on the planes (weights 1/2, 1/4)


@pytest.fixture(scope="module")
def odd_plate_full():
    full = centered_grid((15, 11))
    # rigid motions removed by conditions the symmetric solution satisfies:
    # u_x = -+a on x-+, u_y = 0 on the x+ face point on y = 0
    y0 = np.flatnonzero((np.abs(full.points[:, 1]) < 1e-9) & (full.points[:, 0] > 6.0))
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        full,
        dirichlet=[
            pdlin.Dirichlet("x-", -0.01, components="x"),
            pdlin.Dirichlet("x+", 0.01, components="x"),
            pdlin.Dirichlet(y0, 0.0, components="y"),
        ],
        loads=[pdlin.BodyForce(None, symmetric_body_force)],
        bond_options={"ratio": RATIO},
    )
    return full, pdlin.solve(prob, solver="direct")


@pytest.mark.parametrize("planes", [[X], [Y], [X, Y]], ids=["half-x", "half-y", "quarter"])
def test_plate_with_points_on_planes(odd_plate_full, planes):
    full, ref = odd_plate_full
    idx = part(full, planes)
    cloud = full.subset(idx)
    axes = {int(p.axis) for p in planes}
    dl = [pdlin.Dirichlet("x+", 0.01, components="x")]
    if 0 not in axes:
        dl.append(pdlin.Dirichlet("x-", -0.01, components="x"))
    if 1 not in axes:  # no plane y = 0: the user still removes the y translation
        pts = cloud.points
        dl.append(
            pdlin.Dirichlet(
                np.flatnonzero((np.abs(pts[:, 1]) < 1e-9) & (pts[:, 0] > 6.0)), 0.0, components="y"
            )
        )
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        dirichlet=dl,
        loads=[pdlin.BodyForce(None, symmetric_body_force)],
        bond_options={"ratio": RATIO},
        symmetry=planes,
    )
    res = pdlin.solve(prob, solver="direct", keep_stiffness=True)
    mirror = res.symmetry.mirror
    assert mirror.on_plane.any()  # 15 x 11 centered: columns / rows on x = 0 and y = 0
    assert rel(res.u, ref.u[idx]) < ROUNDOFF
    # a point on k planes belongs to the reduced model with weight 2**-k
    w = mirror.weight
    assert set(np.unique(w)) == ({1.0, 0.5, 0.25} if len(planes) == 2 else {1.0, 0.5})
    user = np.zeros_like(ref.reactions, dtype=bool)
    user.reshape(-1)[ref.prescribed_dofs] = True  # full model's prescribed dofs ...
    user = user[idx]  # ... on the shared points
    np.testing.assert_allclose(
        res.reactions[user], (w[:, None] * ref.reactions[idx])[user], rtol=0, atol=1e-12
    )
    assert_face_share(res, ref, "x+", planes)
    K = res.stiffness
    assert abs(K - K.T).max() <= 1e-14 * abs(K).max()


# --------------------------------------------------------------------------
# 3D block clamped at both ends (even grid) and free eighth model (odd grid)


@pytest.fixture(scope="module")
def block_full():
    full = centered_grid((10, 8, 6))
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        full,
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 0.0)],
        loads=[pdlin.BodyForce(None, symmetric_body_force)],
        bond_options={"ratio": RATIO},
    )
    return full, pdlin.solve(prob, solver="direct")


@pytest.mark.parametrize("planes", [[X], [X, Y], [X, Y, Z]], ids=["half", "quarter", "eighth"])
def test_block_reduced_matches_full(block_full, planes):
    full, ref = block_full
    idx = part(full, planes)
    cloud = full.subset(idx)
    # the only condition a user of the reduced model gives: the clamped x+ face
    prob = pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        dirichlet=[pdlin.Dirichlet("x+", 0.0)],
        loads=[pdlin.BodyForce(None, symmetric_body_force)],
        bond_options={"ratio": RATIO},
        symmetry=planes,
    )
    res = pdlin.solve(prob, solver="direct", keep_stiffness=True)
    assert rel(res.u, ref.u[idx]) < ROUNDOFF
    assert rel(res.reactions, ref.reactions[idx]) < ROUNDOFF
    assert_face_share(res, ref, "x+", planes)
    K = res.stiffness
    assert abs(K - K.T).max() <= 1e-14 * abs(K).max()


def test_free_eighth_of_a_block_needs_no_constraints():
    full = centered_grid((7, 7, 7))
    F = 0.05
    pts = full.points
    on = np.abs(pts) < 1e-9
    center = np.flatnonzero(on.all(axis=1))
    x_axis = np.flatnonzero(on[:, 1] & on[:, 2] & (pts[:, 0] > 0.5) & (pts[:, 0] < 1.5))
    y_axis = np.flatnonzero(on[:, 0] & on[:, 2] & (pts[:, 1] > 0.5) & (pts[:, 1] < 1.5))
    # 3-2-1 support met by the symmetric solution: it vanishes at the center,
    # has no y, z motion on the x axis and no z motion on the y axis
    ref = pdlin.solve(
        pdlin.StaticProblem(
            pdlin.BondBased(E=1.0),
            full,
            dirichlet=[
                pdlin.Dirichlet(center, 0.0),
                pdlin.Dirichlet(x_axis, 0.0, components="yz"),
                pdlin.Dirichlet(y_axis, 0.0, components="z"),
            ],
            loads=[pdlin.TotalForce("x+", [F, 0, 0]), pdlin.TotalForce("x-", [-F, 0, 0])],
            bond_options={"ratio": RATIO},
        ),
        solver="direct",
    )
    idx = part(full, [X, Y, Z])
    res = pdlin.solve(
        pdlin.StaticProblem(
            pdlin.BondBased(E=1.0),
            full.subset(idx),
            # x+ face cut into quarters by y = 0 and z = 0
            loads=[pdlin.TotalForce("x+", [F / 4, 0, 0])],
            bond_options={"ratio": RATIO},
            symmetry=[X, Y, Z],
        ),
        solver="direct",
        keep_stiffness=True,
    )
    assert rel(res.u, ref.u[idx]) < ROUNDOFF
    # the only prescribed dofs are the normal motions of the plane points
    assert np.abs(res.reactions).max() < 1e-12 * F
    K = res.stiffness
    assert abs(K - K.T).max() <= 1e-14 * abs(K).max()


# --------------------------------------------------------------------------
# the operator itself on random symmetric fields


@pytest.mark.parametrize(
    ("shape", "planes"),
    [((16, 12), [X, Y]), ((15, 11), [X, Y]), ((8, 6, 6), [X, Z]), ((7, 6, 5), [X, Y, Z])],
    ids=["2d-even", "2d-odd", "3d-even", "3d-odd"],
)
def test_reduced_operator_on_random_symmetric_field(shape, planes):
    full = centered_grid(shape)
    model = pdlin.BondBased(E=2.0)
    K_full = pdlin.assemble_stiffness(model, full, pdlin.find_bonds(full, ratio=RATIO))
    idx = part(full, planes)
    cloud = full.subset(idx)
    red = symmetry_reduction(model, cloud, planes, bond_options={"ratio": RATIO})
    u = np.random.default_rng(7).normal(size=(cloud.n, cloud.dim))
    img, signs = symmetric_image(full, cloud, planes)
    u_full = u[img] * signs  # the symmetric field whose part is u
    u_sym = u_full[idx]  # u with the normal motion of plane points removed
    K = red.stiffness()
    lhs = (K @ u.ravel()).reshape(cloud.n, -1)
    rhs = (K_full @ u_full.ravel()).reshape(full.n, -1)[idx] * red.mirror.weight[:, None]
    assert rel(lhs, rhs) < 1e-12
    assert rel(lhs, (K @ u_sym.ravel()).reshape(cloud.n, -1)) < 1e-14
    # matrix-free force of the reduced model is -K u
    assert rel(red.internal_force(u), -lhs) < 1e-12
    # energy: the reduced model holds 1/|G| of the full energy
    e_red = 0.5 * u.ravel() @ (K @ u.ravel())
    e_full = 0.5 * u_full.ravel() @ (K_full @ u_full.ravel())
    np.testing.assert_allclose(e_red, e_full / 2 ** len(planes), rtol=1e-12)
    assert abs(K - K.T).max() <= 1e-14 * abs(K).max()


def test_corner_ghosts_of_quarter_and_eighth():
    # grid((4, 4)): 4 points at distance 0.5 of each plane, one at the corner
    m = mirror_cloud(pdlin.grid((4, 4)), [X, Y], reach=1.0)
    assert m.n_ghosts == 4 + 4 + 1  # x images, y images, the corner image
    assert m.cloud.points[m.image == 3].tolist() == [[-0.5, -0.5]]
    # 3D 4^3 with reach 1: 16 per face, 4 per edge, 1 corner -> 3*16 + 3*4 + 1
    m3 = mirror_cloud(pdlin.grid((4, 4, 4)), [X, Y, Z], reach=1.0)
    assert m3.n_ghosts == 61
    np.testing.assert_array_equal(m3.signs[m3.image == 7], [[-1.0, -1.0, -1.0]])
    # a state-based model (coupling_range 2) needs a ghost layer twice as deep
    m2 = mirror_cloud(pdlin.grid((4, 4)), [X], reach=2.0)
    assert m2.n_ghosts == 8  # the two columns within 2 of x = 0


# --------------------------------------------------------------------------
# rigid modes and constraint checking


@pytest.mark.parametrize(
    ("shape", "planes", "names"),
    [
        ((6, 4), [X], ["translation y"]),
        ((6, 4), [X, Y], []),
        ((6, 5, 4), [X], ["translation y", "translation z", "rotation about x"]),
        ((6, 5, 4), [Y], ["translation x", "translation z", "rotation about y"]),
        ((6, 5, 4), [X, Y], ["translation z"]),
        ((6, 5, 4), [X, Y, Z], []),
    ],
)
def test_surviving_rigid_modes(shape, planes, names):
    # expected: a reflection across x_k = c flips translation k and the
    # rotations whose plane contains axis k (hand count)
    red = symmetry_reduction(
        pdlin.BondBased(E=1.0), pdlin.grid(shape), planes, bond_options={"ratio": RATIO}
    )
    modes, got = red.rigid_modes()
    assert got == names
    assert modes.shape == (red.cloud.ndof, len(names))
    K = red.stiffness()
    assert np.abs(K @ modes).max(initial=0.0) < 1e-12 * abs(K).max()


def _bar(planes, dirichlet):
    """Quarter/half of a bar along z pulled on z+ (planes through its axis)."""
    cloud = pdlin.grid((3, 3, 8))  # the part x, y in [0, 3] of a 6 x 6 x 8 bar
    return pdlin.StaticProblem(
        pdlin.BondBased(E=1.0),
        cloud,
        dirichlet=dirichlet,
        loads=[pdlin.TotalForce("z+", [0.0, 0.0, 1e-3])],
        bond_options={"ratio": RATIO},
        symmetry=planes,
    )


def test_quarter_bar_needs_only_an_axial_support():
    roller = [pdlin.Dirichlet("z-", 0.0, components="z")]
    res = pdlin.solve(_bar([X, Y], roller), solver="direct")
    assert res.relative_residual < 1e-10
    # without any support only the axial translation is free
    with pytest.raises(FloatingBodyError, match="translation z"):
        pdlin.solve(_bar([X, Y], []), solver="direct")
    # a half model keeps the y translation: the roller is not enough
    with pytest.raises(FloatingBodyError, match=r"free \(translation y\)"):
        pdlin.solve(_bar([X], roller), solver="direct")
    # and the same roller on the unreduced quarter leaves it floating
    prob = _bar([X, Y], roller)
    plain = pdlin.StaticProblem(
        prob.model, prob.cloud, dirichlet=roller, loads=prob.loads, bond_options=prob.bond_options
    )
    with pytest.raises(FloatingBodyError):
        pdlin.solve(plain, solver="direct")


# --------------------------------------------------------------------------
# cracks are mirrored with the points


def test_mirrored_crack_matches_full():
    full = centered_grid((12, 10))
    crack_full = [[[2.0, -3.0], [2.0, 3.0]]]  # symmetric about y = 0 only
    kw = dict(loads=[pdlin.BodyForce(None, symmetric_body_force)])
    ref = pdlin.solve(
        pdlin.StaticProblem(
            pdlin.BondBased(E=1.0),
            full,
            dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 0.0)],
            bond_options={"ratio": RATIO, "cracks": crack_full},
            **kw,
        ),
        solver="direct",
    )
    idx = part(full, [Y])
    res = pdlin.solve(
        pdlin.StaticProblem(
            pdlin.BondBased(E=1.0),
            full.subset(idx),
            dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", 0.0)],
            bond_options={"ratio": RATIO, "cracks": [[[2.0, 0.0], [2.0, 3.0]]]},
            symmetry=[Y],
            **kw,
        ),
        solver="direct",
    )
    assert rel(res.u, ref.u[idx]) < ROUNDOFF


# --------------------------------------------------------------------------
# bad input


def test_bad_input():
    cloud2 = pdlin.grid((4, 4))
    model = pdlin.BondBased(E=1.0)
    with pytest.raises(InputError, match="axis must be 0, 1, 2"):
        SymmetryPlane(3)
    with pytest.raises(InputTypeError, match="axis must be an int"):
        SymmetryPlane(True)
    with pytest.raises(InputError, match=r"axis must be < 2 for a 2D cloud, got 2"):
        mirror_cloud(cloud2, [Z], reach=1.0)
    with pytest.raises(InputError, match="distinct axes"):
        mirror_cloud(cloud2, [X, SymmetryPlane("x", 4.0)], reach=1.0)
    both_sides = r"one side of symmetry plane x = 2, got 8 point\(s\) below"
    with pytest.raises(InputError, match=both_sides):
        mirror_cloud(cloud2, [SymmetryPlane("x", 2.0)], reach=1.0)
    with pytest.raises(InputError, match="'-' side of symmetry plane x = 0"):
        mirror_cloud(cloud2, [SymmetryPlane("x", 0.0, side="-")], reach=1.0)
    with pytest.raises(InputError, match="couples nothing"):
        mirror_cloud(cloud2, [SymmetryPlane("y", -5.0)], reach=1.0)
    with pytest.raises(InputError, match="reach must be > 0"):
        mirror_cloud(cloud2, [X], reach=0.0)
    with pytest.raises(InputError, match="bonds must be None with symmetry planes"):
        pdlin.StaticProblem(model, cloud2, bonds=pdlin.find_bonds(cloud2, 1.5), symmetry=[X])
    with pytest.raises(InputTypeError, match=r"symmetry\[0\] must be a SymmetryPlane"):
        pdlin.StaticProblem(model, cloud2, horizon=1.5, symmetry=[("x", 0.0)])
    with pytest.raises(pdlin.errors.ModelError, match="micromodulus must be a scalar"):
        bonds = pdlin.find_bonds(cloud2, 1.5)
        per_bond = pdlin.BondBased(micromodulus=np.ones(bonds.n_bonds))
        symmetry_reduction(per_bond, cloud2, [X], horizon=1.5)


def test_on_plane_tolerance_and_per_point_modulus():
    # a point 1e-13 h off the plane counts as on it (ON_PLANE_RTOL = 1e-10)
    cloud = pdlin.PointCloud([[1e-13, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]], volumes=1.0)
    m = mirror_cloud(cloud, [X], reach=1.5)
    assert m.on_plane[:, 0].tolist() == [True, False, True, False]
    assert m.n_ghosts == 2  # only the column at x = 1 is mirrored
    # per-point E is carried to the ghosts (graded plate, symmetric in y)
    full = centered_grid((8, 8))
    E = 1.0 + 0.1 * full.points[:, 1] ** 2
    ref = pdlin.solve(
        pdlin.StaticProblem(
            pdlin.BondBased(E=E),
            full,
            dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [0.01, 0.0])],
            bond_options={"ratio": RATIO},
        ),
        solver="direct",
    )
    idx = part(full, [Y])
    res = pdlin.solve(
        pdlin.StaticProblem(
            pdlin.BondBased(E=E[idx]),
            full.subset(idx),
            dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [0.01, 0.0])],
            bond_options={"ratio": RATIO},
            symmetry=[Y],
        ),
        solver="direct",
    )
    assert rel(res.u, ref.u[idx]) < ROUNDOFF


class TwoHorizonBondBased(pdlin.BondBased):
    """Bond-based operator declared with the coupling range of state-based models."""

    coupling_range = 2


def test_ghost_layer_depth_follows_coupling_range_and_per_point_horizon():
    full = centered_grid((12, 10))
    # per-point horizon, symmetric about y = 0: 3.015 h, or 2.015 h for |y| > 3
    hor_full = np.where(np.abs(full.points[:, 1]) > 3.0, 2.015, RATIO)
    kw = dict(
        dirichlet=[pdlin.Dirichlet("x-", 0.0), pdlin.Dirichlet("x+", [0.01, 0.0])],
        loads=[pdlin.BodyForce(None, symmetric_body_force)],
    )
    ref = pdlin.solve(
        pdlin.StaticProblem(pdlin.BondBased(E=1.0), full, horizon=hor_full, **kw),
        solver="direct",
    )
    idx = part(full, [Y])
    depth = {}
    for model in (pdlin.BondBased(E=1.0), TwoHorizonBondBased(E=1.0)):
        res = pdlin.solve(
            pdlin.StaticProblem(model, full.subset(idx), horizon=hor_full[idx], symmetry=[Y], **kw),
            solver="direct",
        )
        assert rel(res.u, ref.u[idx]) < ROUNDOFF
        depth[model.coupling_range] = res.symmetry.mirror
    # reach = coupling_range x largest horizon (3.015): rows within 3.015 / 6.03 of y = 0
    assert depth[1].reach == pytest.approx(RATIO)
    assert depth[2].reach == pytest.approx(2 * RATIO)
    assert depth[1].n_ghosts == 12 * 3  # rows y = 0.5, 1.5, 2.5
    assert depth[2].n_ghosts == 12 * 5  # the whole half (y <= 4.5 < 6.03)
