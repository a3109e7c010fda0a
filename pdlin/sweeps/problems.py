"""Problem factories of the bundled trade-off problems, each with its reference.

Every factory takes keyword parameters that a sweep may vary and returns a
:class:`~pdlin.sweeps.TradeoffCase`: the problem, its closed form (``exact``) or another
reference (``reference``) and the points where the error is measured.

=====================  ====  =====================================================
factory                dim   reference
=====================  ====  =====================================================
:func:`graded_bar`     1     closed form u = αx + βH(x-½)√(x-½) [1]_
:func:`tension_bar`    2, 3  closed form: uniaxial stress, lateral faces free
:func:`affine_patch`   2, 3  closed form: any affine field (a patch test)
:func:`plate_with_hole` 2    Q4 finite elements (:mod:`pdlin.verification.fem`)
:func:`anisotropic_block` 2  closed form: uniaxial stress of an orthotropic tensor
:func:`square_hole_plate` 2  Q4 finite elements on the particles [2]_
:func:`plate_with_hole_ogrid` 2 Q4 finite elements, graded O-grid [3]_
=====================  ====  =====================================================

References
----------
.. [1] Javaheri, Luo, Lakshmanan & Sundararaghavan (2022), AIAA J.: the bar of
   Sec. III.A, Eqs. 27-28.
.. [2] Luo & Sundararaghavan (2018), IJSS 150: the plate with a square hole of
   Sec. 5.2 (the paper gives no dimensions or loads; pdlin's reconstruction,
   ``docs/theory/conventions.md``, "Plate with a square hole").
.. [3] Liu, Chen & Skelton, XOSB: the plate with a central hole of Sec. 5.1 (the mesh
   and boundary condition are pdlin's reconstruction, ``docs/theory/conventions.md``,
   "Plate with a hole").

Each paper's full reference is in ``docs/theory/references.md``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import InputError
from ..geometry.bonds import find_bonds
from ..geometry.cloud import PointCloud, grid
from ..models.base import Model
from ..operators.bc import BodyForce, Dirichlet, shadow_layer
from ..operators.symmetry import SymmetryPlane
from ..problem import StaticProblem
from .core import TradeoffCase

__all__ = [
    "make_model",
    "MODEL_NAMES",
    "graded_bar",
    "tension_bar",
    "affine_patch",
    "plate_with_hole",
    "anisotropic_block",
    "square_hole_plate",
    "plate_with_hole_ogrid",
    "FACTORIES",
]

#: model names :func:`make_model` accepts (correspondence takes ``:control``)
MODEL_NAMES = ("bb", "lps", "xosb", "correspondence")


def make_model(name: str, E: Any, nu: float | None = None, *, plane: str = "stress") -> Model:
    """Build a model from its sweep name: 'bb', 'lps', 'xosb' or 'correspondence[:control]'.

    Bond-based models take only ``E`` (their Poisson ratio is implied: 1/4 in 3D, 1/3 in
    plane stress); the others need ``nu``.

    Parameters
    ----------
    name : str
        One of :data:`MODEL_NAMES`, also ``'bond_based'`` and ``'cor'``; a correspondence
        model may name its control after a colon (``'correspondence:penalty'``; default
        no control).
    E : float or array_like
        Young's modulus, one value or one per point (units of the problem's stresses).
    nu : float, optional
        Poisson ratio; ignored by the bond-based model.
    plane : {'stress', 'strain'}
        2D assumption, passed to the model.

    Returns
    -------
    Model
        A :class:`~pdlin.BondBased`, :class:`~pdlin.LPS`,
        :class:`~pdlin.XOSB` or :class:`~pdlin.Correspondence`.

    Raises
    ------
    InputError
        When ``name`` is not a known model name.

    Examples
    --------
    >>> make_model("correspondence:penalty", 1.0, 0.25).control
    'penalty'
    >>> make_model("fem", 1.0)
    Traceback (most recent call last):
    ...
    pdlin.errors.InputError: model must be one of ('bb', 'lps', 'xosb', 'correspondence') \
(correspondence:<control>), got 'fem'
    """
    from ..models import LPS, XOSB, BondBased, Correspondence

    base, _, control = str(name).partition(":")
    base = {"bond_based": "bb", "cor": "correspondence"}.get(base, base)
    if base == "bb":
        return BondBased(E=E, plane=plane)
    if base in ("lps", "xosb"):
        cls = LPS if base == "lps" else XOSB
        return cls(E, nu, plane=plane)
    if base == "correspondence":
        return Correspondence(E=E, nu=nu, plane=plane, control=control or "none")
    raise InputError(f"model must be one of {MODEL_NAMES} (correspondence:<control>), got {name!r}")


def _two_hop(model_name: str) -> bool:
    return not str(model_name).startswith(("bb", "bond_based"))


# --- 1D graded bar (Javaheri et al. 2022, Sec. III.A) -------------------------------------

_ALPHA = 1e-3
_BETA = 4e-3 * np.sqrt(2.0)
_SIGMA = 1e-3


def _graded_modulus(x: np.ndarray) -> np.ndarray:
    r = np.clip(x - 0.5, 1e-300, None)
    return np.asarray(np.where(x <= 0.5, 1.0, 1.0 / (1.0 + 2.0 * np.sqrt(2.0) / np.sqrt(r))))


def _graded_exact(X: np.ndarray) -> np.ndarray:
    x = X[:, 0]
    return np.asarray((_ALPHA * x + _BETA * np.sqrt(np.clip(x - 0.5, 0.0, None)))[:, None])


def graded_bar(
    control: str = "higher_order",
    *,
    N: int = 500,
    m: int = 2,
    influence: str = "constant",
    model: str | None = None,
) -> TradeoffCase:
    """Build the 1D graded-modulus bar of Javaheri et al. (2022), Sec. III.A.

    Bar ``0 <= x <= 1`` of ``N`` particles (``h = 1/N``), ``E = 1`` on ``x <= ½`` and
    ``[1 + 2√2 (x - ½)^{-½}]⁻¹`` beyond, outward shadow layers of ``m = δ/h`` particles
    per end carrying the exact ``u`` and the stress σ = 1e-3.  Exact
    ``u = αx + βH(x - ½)√(x - ½)``; the error is measured on the N real particles.  The
    solution has a ``√`` singularity, so errors fall like ``h^{1/2}``.

    Parameters
    ----------
    control : str
        Correspondence control ('higher_order', 'none', 'stress_points', ...).
    N : int
        Particles in the bar.
    m : int
        Horizon ratio δ/h.
    influence : str
        Influence function name of :func:`pdlin.find_bonds`.
    model : str, optional
        'correspondence:<control>' (overrides ``control``).

    Returns
    -------
    TradeoffCase
        The problem (``N + 2m`` points, direct solver), its closed form ``exact``, the
        ``N`` real points as ``measure``, ``h = 1/N`` and ``delta = m/N``.

    Raises
    ------
    InputError
        When ``model`` is not a correspondence model, ``N < 4`` or ``m < 1``.

    Examples
    --------
    >>> case = graded_bar(N=100, m=2)
    >>> case.problem.cloud.n, case.h
    (104, 0.01)
    """
    from ..models import Correspondence

    if model is not None:
        base, _, ctl = str(model).partition(":")
        if base not in ("correspondence", "cor"):
            raise InputError(f"graded_bar supports model='correspondence:<control>', got {model!r}")
        control = ctl or "none"
    N, m = int(N), int(m)
    if N < 4 or m < 1:
        raise InputError(f"graded_bar needs N >= 4 and m >= 1, got N={N}, m={m}")
    cloud = grid((N + 2 * m,), spacing=1.0 / N, origin=[-m / N])
    bonds = find_bonds(cloud, ratio=float(m), influence=influence)
    x = cloud.points[:, 0]
    shadow = np.r_[0:m, N + m : N + 2 * m]
    mdl = Correspondence(E=_graded_modulus(x), control=control, shadow=shadow)
    f = mdl.shadow_loads(cloud, bonds, stress=np.full((2 * m, 1, 1), _SIGMA))
    real = np.arange(m, N + m)
    prob = StaticProblem(
        mdl,
        cloud,
        bonds,
        dirichlet=[Dirichlet(shadow, _graded_exact(cloud.points)[shadow])],
        loads=[BodyForce(real, f[real] / cloud.volumes[real, None])],
    )
    return TradeoffCase(
        prob, {"solver": "direct"}, exact=_graded_exact, measure=real, h=1.0 / N, delta=m / N
    )


# --- 2D/3D bar in tension -------------------------------------------------------------------


def _grid_for(lengths: tuple[float, ...], h: float, origin: np.ndarray) -> PointCloud:
    shape = tuple(max(int(round(L / h)), 1) for L in lengths)
    return grid(shape, spacing=h, origin=[float(v) for v in origin])


def tension_bar(
    model: str = "bb",
    *,
    dim: int = 3,
    h: float = 0.1,
    m: float = 3.015,
    influence: str = "constant",
    symmetry: bool = False,
    length: float = 2.0,
    width: float = 1.0,
    strain: float = 1e-3,
) -> TradeoffCase:
    """Bar in uniaxial tension, ends held by shadow layers, lateral faces free.

    The box ``length x width (x width)`` centred at the origin; inward shadow layers of
    depth ``2 δ`` (two horizons, so two-hop models see complete families) at ``x = ±L/2``
    carry the exact uniaxial-stress field ``u = (F - I) X`` with ``F = diag(1 + ε, 1 - ν ε,
    1 - ν ε)``, ν = 1/4 in 3D and 1/3 in 2D (plane stress; the bond-based values, so every
    model has the same closed form).  The lateral faces are free, so the error of the real
    points is the model's surface effect plus its discretization error.

    Parameters
    ----------
    model : str
        :func:`make_model` name.
    dim : {2, 3}
        Dimension of the bar.
    h : float
        Grid spacing.
    m : float
        Horizon ratio δ/h.
    influence : str
        Influence function of :func:`pdlin.find_bonds`.
    symmetry : bool
        Model the quarter (3D) / half (2D) ``y >= 0 (, z >= 0)`` with symmetry planes.
    length, width : float
        Bar length along x and its side across.
    strain : float
        Axial strain ε of the closed form.

    Returns
    -------
    TradeoffCase
        The problem, the closed form ``exact(X) = X (F - I)ᵀ`` and the real (non-shadow)
        points as ``measure``.

    Raises
    ------
    InputError
        When ``dim`` is not 2 or 3.

    Examples
    --------
    >>> case = tension_bar("bb", dim=2, h=0.1, m=3.015)
    >>> case.problem.cloud.n, case.measure.size
    (200, 80)
    """
    if dim not in (2, 3):
        raise InputError(f"dim must be 2 or 3, got {dim}")
    nu = 0.25 if dim == 3 else 1.0 / 3.0
    E = 1.0
    F = np.eye(dim) * (1.0 - nu * strain)
    F[0, 0] = 1.0 + strain
    lengths = (length,) + (width,) * (dim - 1)
    lo = -0.5 * np.asarray(lengths)
    if symmetry:
        lengths = (length,) + (0.5 * width,) * (dim - 1)
        lo = lo.copy()
        lo[1:] = 0.0
    cloud = _grid_for(lengths, float(h), lo)
    delta = float(m) * float(h)
    depth = 2.0 * delta
    bc, shadow = shadow_layer(cloud, F, depth, faces=["x-", "x+"])
    real = np.setdiff1d(np.arange(cloud.n), shadow)
    mdl = make_model(model, E, nu, plane="stress")
    sym = tuple(SymmetryPlane(ax, 0.0) for ax in range(1, dim)) if symmetry else ()
    prob = StaticProblem(
        mdl,
        cloud,
        horizon=delta,
        dirichlet=[bc],
        bond_options={"influence": influence},
        symmetry=sym,
    )

    def exact(X: np.ndarray) -> np.ndarray:
        return np.asarray(X @ (F - np.eye(dim)).T)

    return TradeoffCase(prob, exact=exact, measure=real, h=float(h), delta=delta)


def affine_patch(
    model: str = "bb",
    *,
    dim: int = 2,
    h: float = 0.1,
    m: float = 3.015,
    influence: str = "constant",
    size: float = 1.0,
) -> TradeoffCase:
    """Patch test: a shadow layer on every face carries an affine field, exact inside.

    ``u = (F - I) X`` with a general (stretch + shear) ``F`` on the unit box; every
    linearized model reproduces it on the real points up to the solver's tolerance,
    so the error isolates the solver (sweep ``rtol`` and ``solver``).

    Parameters
    ----------
    model : str
        :func:`make_model` name.
    dim : {2, 3}
        Dimension of the box.
    h : float
        Grid spacing.
    m : float
        Horizon ratio δ/h.
    influence : str
        Influence function of :func:`pdlin.find_bonds`.
    size : float
        Side of the box ``[0, size]^dim``.

    Returns
    -------
    TradeoffCase
        The problem, the affine closed form and the points inside the shadow layer (on
        every face, ``2 δ`` deep) as ``measure``.

    Examples
    --------
    >>> case = affine_patch("bb", dim=2, h=0.1, m=2.0)
    >>> case.measure.size   # 10 x 10 minus a shadow layer 2 δ deep
    4
    """
    nu = 0.25 if dim == 3 else 1.0 / 3.0
    F = (
        np.eye(dim)
        + 1e-3 * np.array([[1.0, 0.4, 0.2], [0.1, -0.3, 0.3], [0.2, 0.1, 0.5]])[:dim, :dim]
    )
    cloud = _grid_for((size,) * dim, float(h), np.zeros(dim))
    delta = float(m) * float(h)
    bc, shadow = shadow_layer(cloud, F, 2.0 * delta)
    real = np.setdiff1d(np.arange(cloud.n), shadow)
    prob = StaticProblem(
        make_model(model, 1.0, nu),
        cloud,
        horizon=delta,
        bond_options={"influence": influence},
        dirichlet=[bc],
    )

    def exact(X: np.ndarray) -> np.ndarray:
        return np.asarray(X @ (F - np.eye(dim)).T)

    return TradeoffCase(prob, exact=exact, measure=real, h=float(h), delta=delta)


# --- plate with a hole against Q4 ----------------------------------------------------------

_PLATE_E, _PLATE_NU, _PLATE_U0 = 70e9, 0.33, 5e-4  # Liu, Chen & Skelton, XOSB, Sec. 5.1


@functools.lru_cache(maxsize=2)
def _plate_fe(n_ang: int, n_rad: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from ..geometry.generators import plate_with_hole_mesh
    from ..verification.fem import plate_extension_q4

    mesh = plate_with_hole_mesh(n_ang, n_rad)
    quads = np.asarray(next(c.data for c in mesh.cells if c.type == "quad"))
    pts = np.asarray(mesh.points[:, :2], dtype=float)
    u = plate_extension_q4(pts, quads, _PLATE_E, _PLATE_NU, _PLATE_U0)
    return pts, quads, u


def plate_with_hole(
    model: str = "lps",
    *,
    h: float = 1.0 / 40,
    m: float = 3.015,
    influence: str = "constant",
    fe_mesh: tuple[int, int] = (32, 60),
) -> TradeoffCase:
    """Square plate (side 1) with a central hole (r = 0.1) pulled at its ends; Q4 reference.

    The plate of Liu, Chen & Skelton, XOSB, Sec. 5.1, on a cell-centred grid of spacing
    ``h`` (cells whose centre lies in the hole removed): plane stress, E = 70 GPa,
    ν = 0.33 (bond-based: ν = 1/3), the finite-element displacement
    (:func:`pdlin.verification.plate_extension_q4` on the O-grid ``4 x n_ang x n_rad`` of
    ``fe_mesh``, interpolated by :func:`pdlin.verification.evaluate_q4`) prescribed on the
    points within ``2 δ`` of the left and right edges.  The error is measured on the
    remaining points.

    Parameters
    ----------
    model : str
        :func:`make_model` name.
    h : float
        Grid spacing in m.
    m : float
        Horizon ratio δ/h.
    influence : str
        Influence function of :func:`pdlin.find_bonds`.
    fe_mesh : (int, int)
        ``(n_ang, n_rad)`` of the Q4 O-grid of the reference.

    Returns
    -------
    TradeoffCase
        The problem, the interpolated Q4 displacement ``(n, 2)`` as ``reference`` and the
        points outside the prescribed strips as ``measure``.

    Examples
    --------
    >>> case = plate_with_hole("bb", h=0.1, m=2.0, fe_mesh=(4, 6))
    >>> case.problem.cloud.n
    96
    """
    from ..verification.fem import evaluate_q4

    pts, quads, ufe = _plate_fe(*fe_mesh)
    full = grid((int(round(1.0 / h)),) * 2, spacing=float(h), origin=[-0.5, -0.5])
    keep = np.linalg.norm(full.points, axis=1) > 0.1
    cloud = full.subset(np.flatnonzero(keep)) if hasattr(full, "subset") else None
    if cloud is None:  # pragma: no cover - PointCloud without subset
        raise InputError("plate_with_hole needs PointCloud.subset")
    delta = float(m) * float(h)
    uref = evaluate_q4(pts, quads, ufe, cloud.points)
    x = cloud.points[:, 0]
    held = np.flatnonzero(np.abs(x) >= 0.5 - 2.0 * delta)
    free = np.setdiff1d(np.arange(cloud.n), held)
    nu = 1.0 / 3.0 if not _two_hop(model) else _PLATE_NU
    prob = StaticProblem(
        make_model(model, _PLATE_E, nu, plane="stress"),
        cloud,
        horizon=delta,
        bond_options={"influence": influence},
        dirichlet=[Dirichlet(held, uref[held])],
    )
    return TradeoffCase(prob, reference=uref, measure=free, h=float(h), delta=delta)


def anisotropic_block(
    model: str = "bb",
    *,
    h: float = 0.05,
    m: float = 3.015,
    anisotropy: float = 4.0,
    angle: float = 0.0,
    influence: str = "constant",
    strain: float = 1e-3,
) -> TradeoffCase:
    """Orthotropic block in uniaxial stress: calibrated bond-based or correspondence models.

    The 2D plane-stress tensor ``C11 = anisotropy · C22``, ``C12 = C66 = 0.3 C22`` (it
    satisfies the Cauchy relation ``C12 = C66``, so nonnegative bond micromoduli can
    represent it exactly on complete families), rotated by ``angle`` radians.  The block
    ``2 x 1`` is pulled along x by inward shadow layers of depth ``2 δ`` at ``x = ±1``
    carrying the closed-form uniaxial-stress field ``ε = S σ e_x⊗e_x`` (``S = C⁻¹``); the
    lateral faces are free.  ``model``: ``'bb'`` (micromoduli of the bulk family calibrated
    with :func:`pdlin.calibrate_micromoduli`, ``boundary="bulk"``: interior families exact,
    truncated ones softer, like any bond-based body) or
    ``'correspondence[:control]'`` (the tensor itself).

    Parameters
    ----------
    model : str
        ``'bb'`` or ``'correspondence[:control]'``.
    h : float
        Grid spacing.
    m : float
        Horizon ratio δ/h.
    anisotropy : float
        Ratio ``C11 / C22`` of the tensor before rotation.
    angle : float
        Rotation of the material axes, radians.
    influence : str
        Influence function of :func:`pdlin.find_bonds`.
    strain : float
        Strain along x of the closed form (the uniaxial stress σ_xx is scaled to give it).

    Returns
    -------
    TradeoffCase
        The problem, the closed-form uniaxial-stress field as ``exact`` and the real
        (non-shadow) points as ``measure``.

    Raises
    ------
    InputError
        When ``anisotropy`` is not a positive number, ``model`` is not ``'bb'`` or
        ``'correspondence[:control]'``, or the micromodulus calibration fails.

    Examples
    --------
    >>> case = anisotropic_block("correspondence:penalty", h=0.1, m=2.015)
    >>> case.problem.cloud.n, case.measure.size
    (200, 120)
    """
    from ..calibration import calibrate_micromoduli
    from ..constitutive.tensors import rotate
    from ..models.bond_based import BondBased
    from ..models.correspondence import Correspondence

    a = float(anisotropy)
    if not (np.isfinite(a) and a > 0):
        raise InputError(f"anisotropy must be a positive number, got {anisotropy!r}")
    C22 = 1.0
    C = np.array([[a * C22, 0.3 * C22, 0.0], [0.3 * C22, C22, 0.0], [0.0, 0.0, 0.3 * C22]])
    if angle:
        c, s_ = np.cos(angle), np.sin(angle)
        C = rotate(C, np.array([[c, -s_], [s_, c]]))
    S = np.linalg.inv(C)  # plain Voigt (engineering shear): ε = S σ
    eps = strain * S[:, 0] / S[0, 0]  # σ_xx chosen so that ε_xx = strain
    F = np.eye(2) + np.array([[eps[0], 0.5 * eps[2]], [0.5 * eps[2], eps[1]]])
    cloud = _grid_for((2.0, 1.0), float(h), np.array([-1.0, -0.5]))
    delta = float(m) * float(h)
    bc, shadow = shadow_layer(cloud, F, 2.0 * delta, faces=["x-", "x+"])
    real = np.setdiff1d(np.arange(cloud.n), shadow)
    bonds = find_bonds(cloud, delta, influence=influence)
    name, _, control = model.partition(":")
    mdl: Model
    if name == "bb":
        res = calibrate_micromoduli(
            C, bonds, thickness=cloud.thickness, plane="stress", boundary="bulk"
        )
        if not np.all(np.isfinite(res.micromoduli)):
            raise InputError(f"calibration failed ({res.status}): {res.message}")
        mdl = BondBased(micromodulus=res.micromoduli, plane="stress")
    elif name == "correspondence":
        mdl = Correspondence(C, plane="stress", control=control or "none")
    else:
        raise InputError(
            f"model must be 'bb' or 'correspondence[:control]' for the anisotropic block, "
            f"got {model!r}"
        )
    prob = StaticProblem(mdl, cloud, bonds, dirichlet=[bc])

    def exact(X: np.ndarray) -> np.ndarray:
        return np.asarray(X @ (F - np.eye(2)).T)

    return TradeoffCase(prob, exact=exact, measure=real, h=float(h), delta=delta)


def plate_with_hole_ogrid(
    model: str = "xosb",
    *,
    n_ang: int = 24,
    n_rad: int = 45,
    fe_refine: int = 2,
    ratio: float = 3.01,
    linearization: str = "energy",
) -> TradeoffCase:
    """Build the XOSB plate with a hole on its graded O-grid (boundary condition "B").

    The plate of Liu, Chen & Skelton, XOSB, Sec. 5.1 (the paper's 7,680-cell mesh is not
    given; this O-grid and the boundary condition are pdlin's reconstruction).  One
    particle per cell of :func:`pdlin.plate_with_hole_mesh` ``(n_ang, n_rad)``
    (``4 n_ang n_rad`` particles, horizon ``ratio · sqrt(A_i)`` per particle), plane
    stress, E = 70 GPa, ν = 0.33.  The reference is the Q4 solution
    (:func:`pdlin.verification.plate_extension_q4`: u_x = 0 / u0 = 5e-4 m on the left /
    right edge) on the same mapping ``fe_refine`` times finer, evaluated at the particles;
    it is prescribed (both components) on the outermost radial layer of the left and right
    blocks.  The error is measured on the ring (the first radial layer, ``4 n_ang``
    particles) as ``max |u - u_FE| / range_ring(u_FE)`` per component:
    XOSB ≈ 1 % / 3 %, uncorrected OSBPD (``model='lps'``) ≈ 2.4 % / 9.6 % at the default
    size (``examples/plate_with_hole_xosb.py --coarse``).

    Parameters
    ----------
    model : {'xosb', 'lps'}
        XOSB, or LPS with the analytic weighted volume (the uncorrected OSBPD).
    n_ang, n_rad : int
        O-grid cells per block side and radially.
    fe_refine : int
        FE mesh refinement factor.
    ratio : float
        Horizon / sqrt(cell area).
    linearization : {'energy', 'paper'}
        Force-state linearization (``'paper'`` is nonsymmetric: solve with GMRES).

    Returns
    -------
    TradeoffCase
        The problem (``4 n_ang n_rad`` points), the Q4 displacement ``(n, 2)`` as
        ``reference`` and the ``4 n_ang`` ring points as ``measure``.

    Raises
    ------
    InputError
        When ``model`` is not 'xosb' or 'lps', or ``n_ang < 2``, ``n_rad < 2`` or
        ``fe_refine < 1``.

    Examples
    --------
    >>> case = plate_with_hole_ogrid(n_ang=4, n_rad=6, fe_refine=1)
    >>> case.problem.cloud.n, case.measure.size
    (96, 16)
    """
    from ..geometry.generators import plate_with_hole_mesh
    from ..geometry.mesh import read_mesh
    from ..models import LPS, XOSB
    from ..verification.fem import evaluate_q4

    if model not in ("xosb", "lps"):
        raise InputError(f"model must be 'xosb' or 'lps', got {model!r}")
    n_ang, n_rad, fe_refine = int(n_ang), int(n_rad), int(fe_refine)
    if n_ang < 2 or n_rad < 2 or fe_refine < 1:
        raise InputError(
            f"need n_ang >= 2, n_rad >= 2, fe_refine >= 1, got {n_ang}, {n_rad}, {fe_refine}"
        )
    pts, quads, ufe = _plate_fe(fe_refine * n_ang, fe_refine * n_rad)
    cloud = read_mesh(plate_with_hole_mesh(n_ang, n_rad), horizon_ratio=float(ratio))
    bonds = find_bonds(cloud, cloud.horizon)
    uref = evaluate_q4(pts, quads, ufe, cloud.points)
    x, y = cloud.points.T
    ring = np.argsort(np.hypot(x, y))[: 4 * n_ang]
    side = np.flatnonzero(np.abs(x) > np.abs(y))
    right = side[np.argsort(-x[side])[:n_ang]]
    left = side[np.argsort(x[side])[:n_ang]]
    strips = np.concatenate([left, right])
    if model == "xosb":
        mdl: Model = XOSB(_PLATE_E, _PLATE_NU, linearization=linearization)
    else:
        mdl = LPS(_PLATE_E, _PLATE_NU, weighted_volume="analytic", linearization=linearization)
    solver = "direct" if linearization == "energy" else "amg-gmres"
    prob = StaticProblem(mdl, cloud, bonds, dirichlet=[Dirichlet(strips, uref[strips])])
    h = float(np.sqrt(np.median(cloud.volumes)))
    return TradeoffCase(
        prob, {"solver": solver, "rtol": 1e-10}, reference=uref, measure=np.sort(ring), h=h
    )


# --- R2D plate with a square hole (Luo & Sundararaghavan 2018, Sec. 5.2) ------------------

_SQ_E, _SQ_NU, _SQ_SIDE, _SQ_HOLE, _SQ_U = 1000.0, 0.3, 50.0, 10.0, 0.5  # MPa, mm


def square_hole_plate(
    model: str = "correspondence:stress_points",
    *,
    h: float = 2.0,
    seed: int = 0,
) -> TradeoffCase:
    """Plate [0, 50]² mm minus the square hole [0, 10)² on a node lattice; Q4 reference.

    The quarter model of Luo & Sundararaghavan (2018), Sec. 5.2, as reconstructed in
    ``examples/correspondence_controls.py``): particles at the nodes ``(i h, j h)`` with
    ``V = h²``, E = 1000 MPa, ν = 0.3, plane stress; ``u_x = 0`` on ``x = 0``,
    ``u_y = 0`` on ``y = 0``, ``u_x = 0.5`` mm on ``x = 50``, ``u_y = 0.5`` mm on
    ``y = 50`` (tangential components free); nearest-neighbour families (δ = h).  The
    reference is the Q4 solution (:func:`pdlin.verification.solve_q4`) with its nodes at
    the particles; the error is measured on every particle.

    Parameters
    ----------
    model : str
        ``'correspondence:<control>'`` (default: stress points, Luo & Sundararaghavan
        2018).
    h : float
        Lattice spacing in mm (50 / h must be an integer).
    seed : int
        Seed of the stress-point pattern.

    Returns
    -------
    TradeoffCase
        The problem (``(50/h + 1)² - (10/h)²`` points), the Q4 displacement ``(n, 2)`` in
        mm as ``reference``, measured on every point.

    Raises
    ------
    InputError
        When ``model`` is not a correspondence model or ``h`` does not divide 50 mm into
        at least 6 intervals.

    Examples
    --------
    >>> case = square_hole_plate(h=5.0)
    >>> case.problem.cloud.n, case.reference.shape
    (117, (117, 2))
    """
    from ..constraints import resolve_dirichlet
    from ..models.correspondence import Correspondence
    from ..verification.fem import solve_q4

    base, _, control = str(model).partition(":")
    if base not in ("correspondence", "cor"):
        raise InputError(
            f"square_hole_plate supports model='correspondence:<control>', got {model!r}"
        )
    h = float(h)
    n = int(round(_SQ_SIDE / h)) + 1
    if not (h > 0 and abs((n - 1) * h - _SQ_SIDE) < 1e-9 * _SQ_SIDE and n >= 7):
        raise InputError(f"h must divide 50 into at least 6 intervals, got h={h!r}")
    full = grid((n, n), spacing=h, origin=[-0.5 * h, -0.5 * h])
    tol = 1e-9 * h
    keep = np.flatnonzero(~np.all(full.points < _SQ_HOLE - tol, axis=1))
    new = np.full(full.n, -1, dtype=np.intp)
    new[keep] = np.arange(keep.size)
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij"))
    cell = ~((i * h < _SQ_HOLE - tol) & (j * h < _SQ_HOLE - tol))
    i, j = i[cell], j[cell]
    quads = np.stack(
        [new[i * n + j], new[(i + 1) * n + j], new[(i + 1) * n + j + 1], new[i * n + j + 1]],
        axis=1,
    )
    cloud = full.subset(keep)
    x, y = cloud.points.T
    t = 1e-9 * _SQ_SIDE
    bcs = [
        Dirichlet(np.flatnonzero(x < t), 0.0, components="x"),
        Dirichlet(np.flatnonzero(y < t), 0.0, components="y"),
        Dirichlet(np.flatnonzero(x > _SQ_SIDE - t), _SQ_U, components="x"),
        Dirichlet(np.flatnonzero(y > _SQ_SIDE - t), _SQ_U, components="y"),
    ]
    dofs, vals = resolve_dirichlet(cloud, bcs)
    u_fe = solve_q4(cloud.points, quads, _SQ_E, _SQ_NU, dofs, vals, plane="stress")
    bonds = find_bonds(cloud, ratio=1.0)
    kw: dict[str, Any] = {"seed": int(seed)} if (control or "none") == "stress_points" else {}
    mdl = Correspondence(E=_SQ_E, nu=_SQ_NU, plane="stress", control=control or "none", **kw)
    prob = StaticProblem(mdl, cloud, bonds, dirichlet=bcs)
    return TradeoffCase(prob, {"solver": "direct"}, reference=u_fe, h=h, delta=h)


#: bundled factories by name (``[tradeoff] problem = ...`` in scene files)
FACTORIES: dict[str, Callable[..., TradeoffCase]] = {
    "graded_bar": graded_bar,
    "tension_bar": tension_bar,
    "affine_patch": affine_patch,
    "plate_with_hole": plate_with_hole,
    "anisotropic_block": anisotropic_block,
    "square_hole_plate": square_hole_plate,
    "plate_with_hole_ogrid": plate_with_hole_ogrid,
}
