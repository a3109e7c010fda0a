"""Crystal-plasticity finite elements (CPFE): the comparator of the CPPD particle grids.

:func:`crystal_plasticity_fem` solves a pixel-grid :class:`~pdlin.StaticProblem` whose model
carries a finite-strain material (``Correspondence(material=CrystalPlasticity(...))`` or
``SaintVenantKirchhoff``) by finite elements whose element centres are the particles:
bilinear quadrilaterals (Q4, the 2D material's plane deformation) and trilinear hexahedra
(Hex8).  It is the CPFE reference of Luo, Ramazani & Sundararaghavan (2017), Section 4
(Figs. 5, 8, 14), which validates crystal-plasticity peridynamics against it.

* **Mesh.** Element ``e`` is the pixel (voxel) of particle ``e``; the nodes are the pixel
  corners, a node cloud with the face sets ``x-``, ``x+``, ... of :func:`pdlin.grid`.  The
  problem's Dirichlet conditions are resolved on the nodes (by region name: the outer
  ring of nodes for ``'boundary'``, e.g. the velocity-gradient path of the CP scenes).
* **Integration: F-bar** (de Souza Neto, Perić, Dutko & Owen 1996, Int. J. Solids Struct.
  33, Eqs. 9-14) on 2 x 2 (x 2) Gauss points: ``F̄ = (J0/J)^(1/d) F`` with ``J0`` the
  Jacobian at the element centre, the material updated at ``F̄`` and the stress
  ``P̄ = (J/J0)^((d-1)/d) P(F̄)`` (the Cauchy stress ``σ(F̄)`` pulled back with ``F``) in
  the standard virtual work.  Slip is isochoric; with full integration the bilinear
  element locks as the plastic flow is constrained to the element's few volume-preserving
  modes (measured on a polycrystal in docs/crystal_plasticity.md).  ``integration="full"``
  is the plain 2 x 2 (x 2) rule.
* **Material and tangent.** The material's own ``update(F, state, tangent=True)`` per
  Gauss point, vectorized over every Gauss point of the mesh; the element tangent is the
  exact linearization of the F-bar force (non-symmetric, also for a symmetric material).
* **Solver.** The load stepping of :func:`pdlin.solve_nonlinear` (its predictor, Newton,
  cut-backs, ADR fallback) on the element system; the result is a
  :class:`~pdlin.nonlinear.NonlinearResult`.

Element fields: ``result.stress`` is the element Cauchy stress (Gauss-point mean, one
row per particle), ``result.homogenized_stress`` its volume average; the states hold
one row per Gauss point (element ``e``: rows ``e·g .. e·g + g - 1``, ``g = 2^d``),
:func:`element_average` averages them per element.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..constitutive.crystal_plasticity import cauchy_stress
from ..constraints import check_constraints
from ..errors import InputError, InputTypeError, ModelError, NonFiniteError
from ..geometry.cloud import PointCloud, grid
from ..models.base import Response
from ..nonlinear import NonlinearResult
from ..problem import StaticProblem
from ..solvers.options import (
    ADROptions,
    NewtonOptions,
    StepControl,
    check_keywords,
    resolve_density,
)
from ..solvers.stepping import LoadStepper, history_arrays, make_predictor, step_times
from ..system import ConstrainedSystem, constrain

__all__ = ["INTEGRATIONS", "CPFEMesh", "crystal_plasticity_fem", "element_average", "pixel_mesh"]

#: integration rules of :func:`crystal_plasticity_fem`
INTEGRATIONS = ("fbar", "full")

_G = 1.0 / math.sqrt(3.0)


@dataclass(frozen=True, eq=False)
class CPFEMesh:
    """A Q4 / Hex8 mesh whose elements are the pixels (voxels) of a particle grid.

    Attributes
    ----------
    nodes : PointCloud
        The element corners (face sets ``x-``, ``x+``, ...; volume ``h^d`` each).
    conn : (ne, 2^d) ndarray of int
        Corner nodes of each element (counter-clockwise in 2D, bottom then top face in 3D).
    grad : (ne, g, 2^d, d) ndarray
        Reference shape-function gradients ``∂N_a/∂X`` at the Gauss points.
    grad0 : (ne, 2^d, d) ndarray
        The same at the element centre (F-bar's ``J0``).
    weights : (ne, g) ndarray
        Gauss weights times ``det J`` (reference volume per Gauss point).
    """

    nodes: PointCloud
    conn: np.ndarray
    grad: np.ndarray
    grad0: np.ndarray
    weights: np.ndarray

    @property
    def dim(self) -> int:
        """Spatial dimension."""
        return int(self.conn.shape[1]).bit_length() - 1

    @property
    def n_elements(self) -> int:
        """Number of elements (= particles)."""
        return int(self.conn.shape[0])

    @property
    def n_gauss(self) -> int:
        """Gauss points per element."""
        return int(self.weights.shape[1])

    @property
    def volumes(self) -> np.ndarray:
        """Reference volume of each element ``(ne,)``."""
        return np.asarray(self.weights.sum(axis=1))


def _corners(d: int) -> np.ndarray:
    """Natural coordinates of the corners: Q4 counter-clockwise, Hex8 bottom then top."""
    sq = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    if d == 2:
        return sq
    return np.vstack([np.c_[sq, -np.ones(4)], np.c_[sq, np.ones(4)]])


def _dshape(xi: np.ndarray, d: int) -> np.ndarray:
    """Gradients ``∂N_a/∂ξ`` of the multilinear shape functions at points ``xi (m, d)``."""
    c = _corners(d)  # (nen, d)
    fac = 1.0 + xi[:, None, :] * c[None, :, :]  # (m, nen, d)
    out = np.empty_like(fac)
    for k in range(d):  # d <= 3 directions, not a loop over elements
        others = np.prod(np.delete(fac, k, axis=2), axis=2)
        out[:, :, k] = c[None, :, k] * others
    return out / 2.0**d


def pixel_mesh(cloud: PointCloud) -> CPFEMesh:
    """Build the Q4 / Hex8 mesh whose element centres are the points of a full pixel grid.

    Parameters
    ----------
    cloud : PointCloud
        A cloud of :func:`pdlin.grid` (2D or 3D, every cell holding a point).

    Returns
    -------
    CPFEMesh
        Nodes, connectivity, reference gradients and Gauss weights (2 x 2 (x 2) rule).

    Raises
    ------
    InputError
        The cloud is not a complete 2D or 3D pixel grid.

    Examples
    --------
    >>> import pdlin
    >>> mesh = pixel_mesh(pdlin.grid((3, 2), spacing=0.5))
    >>> mesh.nodes.n, mesh.conn.shape, float(mesh.volumes.sum())
    (12, (6, 4), 1.5)
    """
    lat = getattr(cloud, "lattice", None)
    if not isinstance(cloud, PointCloud) or lat is None or lat.index is not None:
        raise InputError(
            "crystal_plasticity_fem needs the cloud of a complete pixel grid (pdlin.grid), got "
            + ("a cloud without lattice" if lat is None else "a grid with missing cells")
        )
    d = cloud.dim
    if d not in (2, 3):
        raise InputError(f"crystal_plasticity_fem needs a 2D or 3D grid, got dim {d}")
    shape = tuple(int(s) for s in lat.shape)
    h = np.asarray(lat.spacing, dtype=float)
    nshape = tuple(s + 1 for s in shape)
    origin = (np.asarray(lat.origin, dtype=float) - h / 2).tolist()
    nodes = grid(nshape, spacing=h.tolist(), origin=origin)
    cells = np.indices(shape).reshape(d, -1).T  # C order = the particles' order
    offs = ((_corners(d) + 1.0) / 2.0).astype(int)  # (nen, d) in {0, 1}
    conn = np.ravel_multi_index(tuple((cells[:, None, :] + offs[None]).transpose(2, 0, 1)), nshape)
    X = nodes.points[conn]  # (ne, nen, d)
    gp = _G * _corners(d)  # Gauss points sit at the corners' directions / sqrt(3)
    dN = _dshape(gp, d)  # (g, nen, d)
    dN0 = _dshape(np.zeros((1, d)), d)[0]
    Jm = np.einsum("eai,gaj->egij", X, dN)  # dX/dξ
    J0 = np.einsum("eai,aj->eij", X, dN0)
    grad = np.einsum("gaj,egji->egai", dN, np.linalg.inv(Jm))
    grad0 = np.einsum("aj,eji->eai", dN0, np.linalg.inv(J0))
    weights = np.linalg.det(Jm)
    if np.any(weights <= 0.0):  # pragma: no cover - a pdlin grid is never inverted
        raise InputError("pixel_mesh: an element has a non-positive Jacobian")
    return CPFEMesh(nodes, conn.astype(np.intp), grad, grad0, weights)


def _gradient_matrix(grad: np.ndarray) -> np.ndarray:
    """``G[..., i*d + j, a*d + k] = δ_ik ∂N_a/∂X_j``: ``vec(F - I) = G u_e``."""
    *lead, nen, d = grad.shape
    G = np.zeros((*lead, d, d, nen, d))
    for i in range(d):  # d <= 3
        G[..., i, :, :, i] = np.swapaxes(grad, -1, -2)
    return G.reshape(*lead, d * d, nen * d)


def _material_of(model: Any) -> Any:
    material = getattr(model, "material", None)
    if material is None or not callable(getattr(material, "update", None)):
        raise InputTypeError(
            "crystal_plasticity_fem needs a problem whose model carries a finite-strain "
            "material (Correspondence(material=CrystalPlasticity(...) or "
            f"SaintVenantKirchhoff(...))), got {type(model).__name__} without one"
        )
    return material


@dataclass(frozen=True, eq=False)
class _FEDiscretization:
    """The element system on the nodes, with the interface the load stepping reads."""

    model: Any
    material: Any
    mesh: CPFEMesh
    integration: str
    state0: dict[str, np.ndarray]
    G: np.ndarray = dataclasses.field(init=False, repr=False)
    G0: np.ndarray = dataclasses.field(init=False, repr=False)

    def __post_init__(self) -> None:
        """Build the gradient matrices ``vec(F - I) = G u_e`` once."""
        object.__setattr__(self, "G", _gradient_matrix(self.mesh.grad))
        object.__setattr__(self, "G0", _gradient_matrix(self.mesh.grad0))

    @property
    def cloud(self) -> PointCloud:
        return self.mesh.nodes

    def dirichlet(self) -> list[Any]:
        return []

    def load_vector(self, loads: Sequence[Any], *, prescribed: Any = None) -> np.ndarray:
        if loads:
            raise InputError(
                "crystal_plasticity_fem supports Dirichlet conditions only (the CP scenes' "
                f"velocity-gradient paths), got {len(loads)} load(s)"
            )
        return np.zeros(self.cloud.n * self.cloud.dim)

    def check_constraints(self, dofs: np.ndarray) -> None:
        check_constraints(self.cloud, None, dofs)

    def estimate_nnz_blocks(self) -> int:
        return int(self.mesh.n_elements * self.mesh.conn.shape[1] ** 2)

    def initial_state(self) -> dict[str, np.ndarray]:
        return dict(self.state0)

    # -- kinematics -------------------------------------------------------------------
    def _gradients(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """F at the Gauss points ``(ne, g, d, d)`` and at the centres ``(ne, d, d)``."""
        m = self.mesh
        ue = np.asarray(u, dtype=float).reshape(-1, m.dim)[m.conn]  # (ne, nen, d)
        eye = np.eye(m.dim)
        F = eye + np.einsum("eai,egaj->egij", ue, m.grad)
        F0 = eye + np.einsum("eai,eaj->eij", ue, m.grad0)
        return F, F0

    def respond(self, u: Any, state: dict[str, np.ndarray], *, tangent: bool = False) -> Any:
        """Nodal force, trial state (one row per Gauss point) and tangent at ``u``."""
        m, d = self.mesh, self.mesh.dim
        ne, g, nen = m.n_elements, m.n_gauss, m.conn.shape[1]
        F, F0 = self._gradients(u)
        J = np.linalg.det(F)
        J0 = np.linalg.det(F0)
        bad = int(np.count_nonzero((J <= 0.0).any(axis=1) | (J0 <= 0.0)))
        if bad:  # the drivers cut the increment back
            raise NonFiniteError(f"{bad} element(s) inverted (det F <= 0 at a Gauss point)")
        fbar = self.integration == "fbar"
        ratio = (J0[:, None] / J) if fbar else np.ones_like(J)  # (ne, g)
        alpha = ratio ** (1.0 / d)
        Fb = alpha[..., None, None] * F
        P, trial, D = self.material.update(Fb.reshape(-1, d, d), state, tangent=tangent)
        P = np.asarray(P).reshape(ne, g, d, d)
        beta = ratio ** (-(d - 1.0) / d)  # (J/J0)^((d-1)/d)
        Pbar = beta[..., None, None] * P
        wP = (m.weights[..., None, None] * Pbar).reshape(ne, g, d * d)
        fe = np.einsum("egq,egqa->ea", wP, self.G)
        force = np.zeros((self.cloud.n, d))
        np.add.at(force, m.conn, -fe.reshape(ne, nen, d))

        def stress() -> np.ndarray:  # element Cauchy stress, read once per converged step
            sig = cauchy_stress(P.reshape(-1, d, d), Fb.reshape(-1, d, d)).reshape(ne, g, d, d)
            return np.asarray(np.einsum("eg,egij->eij", m.weights, sig) / m.volumes[:, None, None])

        K = None
        if tangent:
            K = self._tangent(np.asarray(D).reshape(ne, g, d * d, d * d), P, F, F0, alpha, beta)
        return Response(force, trial, K, stress, int(ne * g))

    def _tangent(
        self,
        D: np.ndarray,
        P: np.ndarray,
        F: np.ndarray,
        F0: np.ndarray,
        alpha: np.ndarray,
        beta: np.ndarray,
    ) -> sp.bsr_array:
        """Assemble ``K = -∂f/∂u`` (exact linearization of the F-bar force)."""
        m, d = self.mesh, self.mesh.dim
        ne, g, nen = m.n_elements, m.n_gauss, m.conn.shape[1]
        d2 = d * d
        G, G0 = self.G, self.G0  # (ne, g, d2, nen d), (ne, d2, nen d)
        w = (m.weights * beta)[..., None, None]
        if self.integration == "fbar":
            # dP̄ = β[(α D - α/d (D:F)⊗F⁻ᵀ + (d-1)/d P⊗F⁻ᵀ) dF
            #       + (α/d (D:F)⊗F0⁻ᵀ - (d-1)/d P⊗F0⁻ᵀ) dF0]
            Pv = P.reshape(ne, g, d2)
            Fv = F.reshape(ne, g, d2)
            Finv = np.swapaxes(np.linalg.inv(F), -1, -2).reshape(ne, g, d2)
            F0inv = np.swapaxes(np.linalg.inv(F0), -1, -2).reshape(ne, 1, d2)
            DF = np.einsum("egpq,egq->egp", D, Fv)
            a = alpha[..., None, None]
            c = (d - 1.0) / d
            M1 = a * D + np.einsum("egp,egq->egpq", c * Pv - a[..., 0] / d * DF, Finv)
            M2 = np.einsum(
                "egp,egq->egpq", a[..., 0] / d * DF - c * Pv, np.broadcast_to(F0inv, Fv.shape)
            )
            B = M1 @ G + M2 @ G0[:, None]
        else:
            B = D @ G
        Ke = np.einsum("egqa,egqb->eab", w * G, B)  # (ne, nen d, nen d)
        dofs = (d * m.conn[:, :, None] + np.arange(d)).reshape(ne, nen * d)
        rows = np.broadcast_to(dofs[:, :, None], Ke.shape).ravel()
        cols = np.broadcast_to(dofs[:, None, :], Ke.shape).ravel()
        n = self.cloud.n * d
        K = sp.coo_array((Ke.ravel(), (rows, cols)), shape=(n, n)).tocsr()
        K.sum_duplicates()
        return sp.bsr_array(K, blocksize=(d, d))

    # -- the rest of the Discretization interface ------------------------------------
    def internal_force(self, u: Any, *, linear: bool = True) -> np.ndarray:
        return np.asarray(self.respond(u, self.state0).force)

    def stiffness(self) -> sp.sparray:
        return self.respond(
            np.zeros(self.cloud.n * self.cloud.dim), self.state0, tangent=True
        ).tangent

    def stress(self, u: Any) -> np.ndarray:
        return np.asarray(self.respond(u, self.state0).stress)

    def deformation_gradient(self, u: Any) -> np.ndarray:
        F, _ = self._gradients(u)
        return np.asarray(
            np.einsum("eg,egij->eij", self.mesh.weights, F) / self.mesh.volumes[:, None, None]
        )


def element_average(values: Any, n_gauss: int) -> np.ndarray:
    """Average a per-Gauss-point array over each element.

    Parameters
    ----------
    values : (ne * n_gauss, ...) array_like
        One row per Gauss point, element by element (a state entry of a
        :func:`crystal_plasticity_fem` result).
    n_gauss : int
        Gauss points per element (4 in 2D, 8 in 3D).

    Returns
    -------
    (ne, ...) ndarray
        The element means (equal Gauss weights: the pixel elements are parallelograms).

    Raises
    ------
    InputError
        The row count is not a multiple of ``n_gauss``.

    Examples
    --------
    >>> element_average([1.0, 3.0, 5.0, 7.0, 0.0, 0.0, 0.0, 4.0], 4).tolist()
    [4.0, 1.0]
    """
    a = np.asarray(values, dtype=float)
    if n_gauss < 1 or a.shape[0] % n_gauss:
        raise InputError(
            f"values must have a multiple of n_gauss = {n_gauss} rows, got {a.shape[0]}"
        )
    return np.asarray(a.reshape(a.shape[0] // n_gauss, n_gauss, *a.shape[1:]).mean(axis=1))


def _gauss_state(material: Any, n: int, g: int) -> dict[str, np.ndarray]:
    """Return the material's initial state of ``n`` particles, each row repeated ``g`` times."""
    st = material.initial_state(n)
    return {
        k: (np.repeat(v, g, axis=0) if isinstance(v, np.ndarray) and v.ndim and len(v) == n else v)
        for k, v in st.items()
    }


def crystal_plasticity_fem(
    problem: StaticProblem,
    steps: int = 10,
    *,
    times: Sequence[float] | None = None,
    t_end: float | None = None,
    integration: str = "fbar",
    method: str = "newton",
    predictor: str = "auto",
    rtol: float = 1e-8,
    maxiter: int = 25,
    line_search: bool = True,
    max_cutbacks: int = 8,
    fallback_cutbacks: int = 2,
    linear_solver: str = "auto",
    e_l: float = 1e-6,
    keep_states: bool = True,
    progress: Callable[[str], None] | None = None,
) -> NonlinearResult:
    """Solve a crystal-plasticity pixel-grid problem by finite elements (CPFE).

    The comparator of crystal-plasticity peridynamics (CPPD) of Luo, Ramazani &
    Sundararaghavan (2017), Section 4: the same problem (pixel grid, material with
    per-particle orientations, Dirichlet paths on named regions) on Q4 (2D) or Hex8 (3D)
    elements centred on the particles, nodes at the pixel corners, F-bar integration (de
    Souza Neto et al. 1996) and the material's own update and consistent tangent at
    every Gauss point; load-stepped by the drivers of :func:`pdlin.solve_nonlinear`
    (same predictor, Newton, line search, cut-backs and ADR fallback).

    Parameters
    ----------
    problem : StaticProblem
        A problem on a complete :func:`pdlin.grid` whose model has a ``material``
        (``Correspondence(material=CrystalPlasticity(...))``); its Dirichlet conditions
        are resolved on the nodes by region name (the bonds and the peridynamic
        options of the model are not used).
    steps, times, t_end
        Load steps, as in :func:`pdlin.solve_nonlinear`.
    integration : {'fbar', 'full'}
        F-bar on 2 x 2 (x 2) Gauss points (default), or plain full integration.
    method, predictor, rtol, maxiter, line_search, max_cutbacks, fallback_cutbacks,
    linear_solver, e_l
        The options of :func:`pdlin.solve_nonlinear` (default ``method='newton'``;
        ADR with the Gershgorin density).
    keep_states : bool
        Keep every committed state (else only the last).
    progress : callable, optional
        Receives one line per load step.

    Returns
    -------
    NonlinearResult
        ``u`` nodal ``(k, n_nodes, d)``; ``stress`` the element Cauchy stress ``(k, ne,
        d, d)`` (element ``e`` is particle ``e``); ``homogenized_stress`` its volume
        average; ``states`` one row per Gauss point (:func:`element_average`);
        ``reactions`` on the nodes; ``system`` the element system.

    Raises
    ------
    InputTypeError
        ``problem`` is not a StaticProblem, or its model carries no material.
    InputError
        Not a complete 2D/3D grid, loads present, an unknown ``integration`` or an option
        out of range.
    ConvergenceError
        A load step fails.

    Examples
    --------
    A single crystal under pure shear equals the homogeneous material point:

    >>> import numpy as np, pdlin
    >>> from pdlin.constitutive import material_point
    >>> mat = pdlin.CrystalPlasticity("planar-2", orientation=0.0)
    >>> L = 0.002 * np.array([[0.0, 1.0], [1.0, 0.0]])
    >>> prob = pdlin.StaticProblem(pdlin.Correspondence(material=mat), pdlin.grid((3, 3)),
    ...     horizon=1.5, dirichlet=[pdlin.Dirichlet.velocity_gradient("boundary", L)])
    >>> res = crystal_plasticity_fem(prob, times=[1.0, 2.0, 3.0, 4.0])
    >>> ref = material_point(mat, "shear", steps=4)
    >>> bool(np.abs(res.homogenized_stress - ref.stress[:, 0]).max() < 1e-10)
    True
    """
    if not isinstance(problem, StaticProblem):
        raise InputTypeError(f"problem must be a StaticProblem, got {type(problem).__name__}")
    if integration not in INTEGRATIONS:
        raise InputError(f"integration must be one of {INTEGRATIONS}, got {integration!r}")
    check_keywords(
        dict(method=method, rtol=rtol, e_l=e_l, floor=1e-12, maxiter=maxiter,
             max_cutbacks=max_cutbacks, fallback_cutbacks=fallback_cutbacks, relax=0,
             progress_every=60.0, snapshot_every=300.0, damping=None, c0=1.0, polish=None,
             adr_stall=None, newton_backoff=True, adr_maxiter=None, resume=False,
             checkpoint=None, forcing="fixed", globalization="line-search",
             linear_solver=linear_solver)
    )  # fmt: skip
    for bc in problem.dirichlet:
        if not isinstance(bc.where, str):
            raise InputError(
                "crystal_plasticity_fem resolves Dirichlet conditions on the element nodes by "
                "region name ('boundary', 'x-', ...), got a where of type "
                f"{type(bc.where).__name__}"
            )
    if problem.symmetry:
        raise InputError("crystal_plasticity_fem does not support symmetry planes, got some")
    t_start = time.perf_counter()
    tt = step_times(steps, t_end, times)
    te = 1.0 if t_end is None else float(t_end)
    material = _material_of(problem.model)
    mesh = pixel_mesh(problem.cloud)
    if material.dim != mesh.dim:
        raise ModelError(f"the material is {material.dim}D but the grid is {mesh.dim}D")
    state0 = _gauss_state(material, mesh.n_elements, mesh.n_gauss)
    disc = _FEDiscretization(problem.model, material, mesh, integration, state0)
    system: ConstrainedSystem = constrain(problem, disc)
    pred = make_predictor(system, predictor, linear_solver)
    lam, adr_dt = resolve_density(system.ndof, method, "gershgorin", None)
    budget = 200 * math.ceil(system.n ** (1.0 / system.dim)) + 2000
    newton = NewtonOptions(rtol=rtol, maxiter=maxiter, line_search=line_search,
                           linear_solver=linear_solver)  # fmt: skip
    adr = ADROptions(e_l=e_l, density=lam, dt=adr_dt, maxiter=budget, stall=max(500, budget // 8))
    control = StepControl(method=method, predictor=predictor, max_cutbacks=max_cutbacks,
                          fallback_cutbacks=fallback_cutbacks, polish=method == "auto")  # fmt: skip
    hom_w = mesh.volumes
    run = LoadStepper(
        system, tt, te, control, newton, adr, pred, state0, hom_w, keep_states, None, {},
        progress, 60.0, 300.0,
    )  # fmt: skip
    timings: dict[str, Any] = {"setup": time.perf_counter() - t_start}
    for k in range(tt.size):
        run.step(k)
    records = run.records
    stress = np.stack([np.asarray(r.stress) for r in records])
    hom = np.stack([np.asarray(r.homogenized_stress) for r in records])
    cols = history_arrays(
        [dataclasses.replace(r, stress=None, homogenized_stress=None) for r in records]
    )
    cols.update(stress=stress, homogenized_stress=hom)
    return NonlinearResult.from_run(problem, run, tt, te, timings, t_start, cols)
