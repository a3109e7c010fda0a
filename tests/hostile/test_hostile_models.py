"""Hostile input: models, elastic constants, stiffness tensors, crystal plasticity."""

from __future__ import annotations

import numpy as np
import pytest
from hostile_util import INF, NAN, expect, problem

import pdlin
from pdlin import constitutive as cm
from pdlin.errors import InputError, InputTypeError, ModelError, NonFiniteError, ShapeError

C_ISO = cm.isotropic(E=1.0, nu=0.25)
CP = pdlin.CrystalPlasticity


def _solve_with(model):
    return pdlin.solve(problem(model=model))


CASES = [
    ("bb-E-nan", lambda: pdlin.BondBased(E=NAN), NonFiniteError, r"E must be finite, got nan"),
    ("bb-E-inf", lambda: pdlin.BondBased(E=INF), NonFiniteError, r"E must be finite, got inf"),
    ("bb-E-neg", lambda: pdlin.BondBased(E=-1), InputError, r"E must be > 0, got min -1.0"),
    ("bb-E-str", lambda: pdlin.BondBased(E="steel"), InputError, r"E must be numeric, got str"),
    (
        "bb-E-list-nan",
        lambda: pdlin.BondBased(E=[1.0, NAN]),
        NonFiniteError,
        r"E must be finite, got nan at index 1",
    ),
    (
        "bb-E-complex",
        lambda: pdlin.BondBased(E=1 + 2j),
        InputTypeError,
        r"E must be real, got complex",
    ),
    ("bb-nu-nan", lambda: pdlin.BondBased(E=1, nu=NAN), InputError, r"nu must be finite, got nan"),
    (
        "bb-nu-half",
        lambda: pdlin.BondBased(E=1, nu=0.5),
        InputError,
        r"E = 1, nu = 0.5 do not determine finite elastic moduli",
    ),
    ("bb-none", lambda: pdlin.BondBased(), InputError, r"BondBased needs E .* got none"),
    (
        "bb-plane",
        lambda: pdlin.BondBased(E=1, plane="strian"),
        InputError,
        r"plane must be 'stress' or 'strain', got 'strian'",
    ),
    (
        "bb-micromodulus-nan",
        lambda: pdlin.BondBased(micromodulus=NAN),
        NonFiniteError,
        r"micromodulus must be finite, got nan",
    ),
    (
        "bb-micromodulus-neg",
        lambda: pdlin.BondBased(micromodulus=-1.0),
        InputError,
        r"micromodulus must be >= 0 .* got min -1.0",
    ),
    (
        "bb-both",
        lambda: pdlin.BondBased(E=1, micromodulus=1.0),
        InputError,
        r"got micromodulus and E",
    ),
    (
        "bb-average",
        lambda: pdlin.BondBased(E=1, average="mean"),
        InputError,
        r"average must be 'arithmetic' or 'harmonic', got 'mean'",
    ),
    (
        "bb-kinematics",
        lambda: pdlin.BondBased(E=1, kinematics="large"),
        InputError,
        r"kinematics must be 'small' or 'finite', got 'large'",
    ),
    (
        "bb-nu-mismatch",
        lambda: _solve_with(pdlin.BondBased(E=1, nu=0.3)),
        ModelError,
        r"implies nu = 0.3333 .* got nu = 0.3",
    ),
    (
        "bb-E-per-point-len",
        lambda: _solve_with(pdlin.BondBased(E=np.ones(5))),
        ShapeError,
        r"E must be a scalar or have shape \(36,\), got \(5,\)",
    ),
    (
        "lps-nu-nan",
        lambda: pdlin.LPS(E=1, nu=NAN),
        InputError,
        r"nu must be in \(-1, 0.5\), got nan",
    ),
    (
        "lps-nu-half",
        lambda: pdlin.LPS(E=1, nu=0.5),
        InputError,
        r"nu must be in \(-1, 0.5\), got 0.5",
    ),
    (
        "lps-only-E",
        lambda: pdlin.LPS(E=1),
        InputError,
        r"LPS needs E and nu .* got E = 1, nu = None",
    ),
    (
        "lps-inconsistent",
        lambda: pdlin.LPS(E=1, nu=0.3, K=2),
        InputError,
        r"inconsistent isotropic constants: K = 2",
    ),
    (
        "lps-K-neg",
        lambda: pdlin.LPS(K=-1, G=1),
        InputError,
        r"not positive definite .* got K = -1, G = 1",
    ),
    (
        "lps-peridigm-str",
        lambda: pdlin.LPS(E=1, nu=0.3, peridigm="yes"),
        InputTypeError,
        r"peridigm must be True or False, got 'yes'",
    ),
    (
        "lps-1d",
        lambda: pdlin.solve(
            pdlin.StaticProblem(
                pdlin.LPS(E=1, nu=0.3),
                pdlin.grid(10, 0.1),
                horizon=0.301,
                dirichlet=[pdlin.Dirichlet("x-", 0.0)],
            )
        ),
        ModelError,
        r"LPS needs a 2D or 3D cloud, got dim 1",
    ),
    ("xosb-E-inf", lambda: pdlin.XOSB(E=INF, nu=0.3), NonFiniteError, r"E must be finite, got inf"),
    (
        "xosb-max-cond",
        lambda: pdlin.XOSB(E=1, nu=0.3, max_cond=-1),
        InputError,
        r"max_cond must be > 0, got -1",
    ),
    (
        "xosb-fallback-str",
        lambda: pdlin.XOSB(E=1, nu=0.3, fallback="no"),
        InputTypeError,
        r"fallback must be True or False, got 'no'",
    ),
    (
        "corr-C-nan",
        lambda: pdlin.Correspondence(np.full((3, 3), NAN)),
        NonFiniteError,
        r"C must be finite, got nan at index \(0, 0\)",
    ),
    (
        "corr-C-str",
        lambda: pdlin.Correspondence(np.array([["a"]])),
        InputTypeError,
        r"C must be a numeric array, got dtype <U1",
    ),
    (
        "corr-C-shape",
        lambda: _solve_with(pdlin.Correspondence(np.eye(4))),
        ShapeError,
        r"C must be a Voigt matrix of shape \(3, 3\) in 2D, got \(4, 4\)",
    ),
    (
        "corr-C-nonsym",
        lambda: _solve_with(pdlin.Correspondence(np.array([[1.0, 0.5, 0], [0, 1, 0], [0, 0, 1]]))),
        InputError,
        r"C must be symmetric .* got max \|C - C.T\| = 0.5",
    ),
    (
        "corr-C-not-spd",
        lambda: _solve_with(pdlin.Correspondence(-np.eye(3))),
        InputError,
        r"C must be positive definite, got smallest eigenvalue -2",
    ),
    (
        "corr-C-and-E",
        lambda: pdlin.Correspondence(C_ISO, E=1),
        InputError,
        r"exactly one of C .* got both",
    ),
    (
        "corr-control",
        lambda: pdlin.Correspondence(E=1, nu=0.3, control="zem"),
        InputError,
        r"control must be one of .* got 'zem'",
    ),
    (
        "corr-penalty-neg",
        lambda: pdlin.Correspondence(E=1, nu=0.3, control="penalty", penalty=-1),
        InputError,
        r"penalty must be a finite number >= 0, got -1",
    ),
    (
        "corr-penalty-nan",
        lambda: pdlin.Correspondence(E=1, nu=0.3, control="penalty", penalty=NAN),
        InputError,
        r"penalty must be a finite number >= 0, got nan",
    ),
    (
        "corr-seed-str",
        lambda: pdlin.Correspondence(E=1, nu=0.3, seed="x"),
        InputError,
        r"seed must be an integer, got 'x'",
    ),
    (
        "corr-max-bytes",
        lambda: pdlin.Correspondence(E=1, nu=0.3, max_bytes=-1),
        InputError,
        r"max_bytes must be an integer >= 1, got -1",
    ),
    (
        "corr-material-str",
        lambda: pdlin.Correspondence(material="steel"),
        InputTypeError,
        r"material must provide initial_state.* got str",
    ),
    (
        "corr-material-and-E",
        lambda: pdlin.Correspondence(E=1, nu=0.3, material=CP()),
        InputError,
        r"got material and E, nu",
    ),
    (
        "cp-slip",
        lambda: CP("fcc2"),
        InputError,
        r"slip must be one of \['fcc', 'hcp', 'planar-2'\], got 'fcc2'",
    ),
    (
        "cp-elastic-keys",
        lambda: CP("fcc", elastic={"C11": 2, "C13": 1}),
        InputError,
        r"elastic must give the constants \['C11', 'C12', 'C44'\].*got keys \['C11', 'C13'\]",
    ),
    (
        "cp-hardening-key",
        lambda: CP(hardening={"tau0x": 1}),
        InputError,
        r"hardening keys must be among .* got \['tau0x'\]",
    ),
    (
        "cp-orientation-nan",
        lambda: CP(orientation=NAN),
        NonFiniteError,
        r"orientation must be finite, got nan",
    ),
    (
        "cp-orientation-shape",
        lambda: CP("fcc", orientation=[1, 2]),
        ShapeError,
        r"orientation must be rotation matrices .* got shape \(2,\)",
    ),
    (
        "cp-active-set",
        lambda: CP(active_set="x"),
        InputError,
        r"active_set must be 'auto', 'reactivate' or 'prune', got 'x'",
    ),
    (
        "cp-yield-tol",
        lambda: CP(yield_tol=-1),
        InputError,
        r"yield_tol must be a finite number >= 0, got -1",
    ),
    ("cp-c-over-a", lambda: CP("hcp", c_over_a=0), InputError, r"c_over_a must be > 0, got 0.0"),
    (
        "cp-tangent-step-nan",
        lambda: CP(tangent_step=NAN),
        InputError,
        r"tangent_step must be > 0, got nan",
    ),
    (
        "svk-nan",
        lambda: pdlin.SaintVenantKirchhoff(np.full((6, 6), NAN)),
        NonFiniteError,
        r"C must be finite, got nan at index \(0, 0\)",
    ),
    (
        "svk-shape",
        lambda: pdlin.SaintVenantKirchhoff(np.ones((5, 5))),
        ShapeError,
        r"C must have shape .* got \(5, 5\)",
    ),
    (
        "svk-nonsym",
        lambda: pdlin.SaintVenantKirchhoff(C_ISO + np.triu(np.ones((6, 6)), 1)),
        InputError,
        r"C must be symmetric .* got max \|C - C.T\| = 1",
    ),
    (
        "svk-not-spd",
        lambda: pdlin.SaintVenantKirchhoff(-C_ISO),
        InputError,
        r"C must be positive definite, got smallest eigenvalue",
    ),
    (
        "mp-loading",
        lambda: pdlin.material_point(CP(), "twist"),
        InputError,
        r"loading must be one of .* got 'twist'",
    ),
    (
        "mp-steps-0",
        lambda: pdlin.material_point(CP(), steps=0),
        InputError,
        r"steps must be an integer >= 1, got 0",
    ),
    (
        "mp-steps-float",
        lambda: pdlin.material_point(CP(), steps=2.5),
        InputError,
        r"steps must be an integer >= 1, got 2.5",
    ),
    (
        "mp-eta-nan",
        lambda: pdlin.material_point(CP(), eta=NAN),
        InputError,
        r"eta must be a finite number, got nan",
    ),
    (
        "mp-loading-shape",
        lambda: pdlin.material_point(CP(), np.ones((4, 4))),
        ShapeError,
        r"loading must have shape \(2, 2\), got \(4, 4\)",
    ),
    (
        "mp-loading-nan",
        lambda: pdlin.material_point(CP(), np.full((2, 2), NAN)),
        NonFiniteError,
        r"loading must be finite, got nan",
    ),
    (
        "mp-material",
        lambda: pdlin.material_point("steel"),
        InputTypeError,
        r"material must be a CrystalPlasticity or SaintVenantKirchhoff, got str",
    ),
    (
        "mp-orientation-nan",
        lambda: pdlin.material_point(CP(), orientation=NAN),
        NonFiniteError,
        r"orientation must be finite, got nan",
    ),
    (
        "iso-const-one",
        lambda: cm.isotropic_constants(E=1),
        InputError,
        r"needs two of E, nu, .* got 1: E",
    ),
    (
        "iso-const-nu-nan",
        lambda: cm.isotropic_constants(E=1, nu=NAN),
        InputError,
        r"nu must be finite, got nan",
    ),
    (
        "iso-const-E-neg",
        lambda: cm.isotropic_constants(E=-1, nu=0.3),
        InputError,
        r"E = -1, nu = 0.3 give a material that is not positive definite",
    ),
    (
        "iso-const-str",
        lambda: cm.isotropic_constants(E="a", nu=0.3),
        InputError,
        r"E must be a number or \(n,\) array, got 'a'",
    ),
    (
        "isotropic-E-nan",
        lambda: cm.isotropic(E=NAN, nu=0.3),
        NonFiniteError,
        r"E must be finite, got nan",
    ),
    (
        "isotropic-nu-1",
        lambda: cm.isotropic(E=1.0, nu=1.0),
        InputError,
        r"nu must be in \(-1, 0.5\), got 1.0",
    ),
    (
        "isotropic-one",
        lambda: cm.isotropic(E=1.0),
        InputError,
        r"isotropic needs exactly two of .* got 1: E",
    ),
    (
        "check-stiffness-shape",
        lambda: cm.check_stiffness(np.ones((4, 4))),
        ShapeError,
        r"C must have shape .* got \(4, 4\)",
    ),
    (
        "check-stiffness-nan",
        lambda: cm.check_stiffness(np.full((6, 6), NAN)),
        NonFiniteError,
        r"C must be finite, got nan at index \(0, 0\)",
    ),
    (
        "check-stiffness-not-spd",
        lambda: cm.check_stiffness(-C_ISO),
        InputError,
        r"C must be positive definite, got smallest eigenvalue -2",
    ),
    (
        "check-stiffness-nonsym",
        lambda: cm.check_stiffness(C_ISO + np.triu(np.ones((6, 6)), 1), name="D"),
        InputError,
        r"D must be symmetric",
    ),
    (
        "check-stiffness-str",
        lambda: cm.check_stiffness("C"),
        InputError,
        r"C must be a numeric array, got str",
    ),
    (
        "how-dim-0",
        lambda: pdlin.higher_order_weights(0, 3.0),
        InputError,
        r"dim must be 1, 2 or 3, got 0",
    ),
    (
        "how-dim-str",
        lambda: pdlin.higher_order_weights("2", 3.0),
        InputTypeError,
        r"dim must be an int \(1, 2 or 3\), got str",
    ),
    (
        "how-ratio-nan",
        lambda: pdlin.higher_order_weights(2, NAN),
        InputError,
        r"horizon_ratio must be a finite number > 0, got nan",
    ),
    (
        "how-ratio-small",
        lambda: pdlin.higher_order_weights(2, 0.5),
        InputError,
        r"horizon_ratio must be >= 1 .* got 0.5",
    ),
]


@pytest.mark.parametrize(
    ("call", "exc", "pattern"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_models_reject(call, exc, pattern):
    expect(call, exc, pattern)
