"""The model property table, rows for the ordinary state-based models LPS and XOSB.

The model-independent checks are imported from ``test_model_properties`` and run on the ``case``
fixture defined here (they skip the energy and symmetry checks for the nonsymmetric paper
linearization ``K_p``, Liu, Chen & Skelton, XOSB, Eq. 70, and test affine fields ``coupling_range``
horizons inside the body).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from test_model_properties import (  # noqa: F401  (imported tests run on this module's cases)
    _jittered,
    test_affine_fields_give_zero_force_on_complete_families,
    test_deformation_gradient_exact_for_affine_fields,
    test_internal_force_matches_stiffness,
    test_nonlinear_force_linearizes_to_K,
    test_positive_energy_on_non_rigid_fields,
    test_rigid_body_modes_in_null_space,
    test_shape_and_blocks,
    test_symmetric,
)

import pdlin


def _lps_2d_stress() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((16, 15), spacing=0.1)
    return pdlin.LPS(E=70e9, nu=0.3, plane="stress"), c, pdlin.find_bonds(c, ratio=3.015)


def _lps_2d_strain_peridigm() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((15, 16), spacing=0.5)
    b = pdlin.find_bonds(c, ratio=3.015)
    return pdlin.LPS(E=3.0, nu=0.45, plane="strain", peridigm=True), c, b


def _lps_3d() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((11, 11, 11), spacing=0.25)
    return pdlin.LPS(E=1.0, nu=0.3), c, pdlin.find_bonds(c, ratio=2.01)


def _xosb_2d_energy() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((16, 15), spacing=0.1)
    return pdlin.XOSB(E=70e9, nu=0.33), c, pdlin.find_bonds(c, ratio=3.01)


def _xosb_2d_paper_strain() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((16, 15), spacing=0.1)
    m = pdlin.XOSB(E=2.0, nu=0.45, plane="strain", linearization="paper")
    return m, c, pdlin.find_bonds(c, ratio=3.01)


def _xosb_2d_variable_horizon() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = _jittered(2, 14)
    return pdlin.XOSB(E=5.0, nu=0.3), c, pdlin.find_bonds(c)


def _xosb_2d_graded_e() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((15, 12), spacing=0.1)
    E = np.random.default_rng(4).uniform(1.0, 5.0, c.n)  # per-point modulus (graded)
    return pdlin.XOSB(E=E, nu=0.3, plane="strain"), c, pdlin.find_bonds(c, ratio=3.01)


def _xosb_3d_energy() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((7, 7, 6), spacing=0.25)
    return pdlin.XOSB(E=1.0, nu=0.3), c, pdlin.find_bonds(c, ratio=3.01)


def _xosb_3d_paper_jittered() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = _jittered(3, 6)
    return pdlin.XOSB(E=1.0, nu=0.45, linearization="paper"), c, pdlin.find_bonds(c)


def _lps_2d_energy_correction() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((24, 24), spacing=0.1)
    m = pdlin.LPS(E=70e9, nu=0.3, surface_correction="energy")
    return m, c, pdlin.find_bonds(c, ratio=3.015)


def _lps_2d_paper_force_correction() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((16, 15), spacing=0.1)
    m = pdlin.LPS(
        E=2.0,
        nu=0.45,
        plane="strain",
        linearization="paper",
        surface_correction="force-normalization",
    )
    return m, c, pdlin.find_bonds(c, ratio=3.015)


def _lps_3d_volume_correction() -> tuple[Any, pdlin.PointCloud, pdlin.Bonds]:
    c = pdlin.grid((15, 15, 15), spacing=0.25)
    m = pdlin.LPS(E=1.0, nu=0.3, weighted_volume="discrete", surface_correction="volume")
    return m, c, pdlin.find_bonds(c, ratio=2.01)


CASES: dict[str, Callable[[], tuple[Any, pdlin.PointCloud, pdlin.Bonds]]] = {
    "lps-2d-stress": _lps_2d_stress,
    "lps-2d-strain-peridigm": _lps_2d_strain_peridigm,
    "lps-3d": _lps_3d,
    "lps-2d-energy-correction": _lps_2d_energy_correction,
    "lps-2d-paper-force-correction": _lps_2d_paper_force_correction,
    "lps-3d-volume-correction": _lps_3d_volume_correction,
    "xosb-2d-energy": _xosb_2d_energy,
    "xosb-2d-paper-strain": _xosb_2d_paper_strain,
    "xosb-2d-variable-horizon": _xosb_2d_variable_horizon,
    "xosb-2d-graded-E": _xosb_2d_graded_e,
    "xosb-3d-energy": _xosb_3d_energy,
    "xosb-3d-paper-jittered": _xosb_3d_paper_jittered,
}


@pytest.fixture(params=sorted(CASES), scope="module")
def case(request):
    model, cloud, bonds = CASES[request.param]()
    K = pdlin.assemble_stiffness(model, cloud, bonds)
    return model, cloud, bonds, K


def test_declared_coupling_range(case):
    model, cloud, bonds, K = case
    assert model.coupling_range == 2
    assert model.estimate_nnz_blocks(cloud, bonds) == K.nnz // cloud.dim**2
