"""Issue 34: Peridigm's own regression and verification decks run unchanged.

The decks of Peridigm's ``test/regression`` and ``test/verification`` folders that lie
inside pdlin's static subset (``docs/decks.md``) are kept unchanged, with their meshes and
Peridigm's gold results, under ``tests/data/peridigm`` (Peridigm's BSD license there).
Each runs through ``pdlin run DECK`` and its displacements are compared with the gold
Exodus file.

Peridigm's ``Elastic`` material (``elastic.cxx``) uses finite kinematics (extensions and
force directions of the deformed bonds) and its quasi-static solvers run Newton to that
nonlinear solution.  pdlin runs it as ``pdlin.models.PeridigmElastic`` through
``solve_nonlinear`` for decks with several load steps (``kinematics='auto'``, compared with
the gold files at their ``.comp`` tolerance in ``test_peridigm_finite.py``) and solves the
linearization at u = 0 for one-step decks (or ``kinematics='linear'``).  Here:

* the model: ``PeridigmElastic``'s force equals Peridigm's finite-kinematics LPS force
  written out below from ``elastic.cxx`` (an independent loop-free transcription), its
  tangent is the derivative of that force, and pdlin's linear stiffness is that derivative
  at u = 0 (central differences);
* the linear part: the linearized displacements against the linear part of Peridigm's
  load path (for decks with two or more load steps, the slope at t = 0 of the quadratic
  through (0, 0) and the first two gold steps, times the final time) and against the
  gold's final state; decks ``pdlin run`` solves with finite kinematics match the gold
  at the ``.comp`` tolerance.

The ``Elastic Correspondence`` deck (hourglass control, see ``docs/decks.md``) is compared
by its linear part and final state only.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import pdlin
from pdlin.cli.main import main
from pdlin.errors import SceneError
from pdlin.io.read import read_result
from pdlin.models import PeridigmElastic
from pdlin.system import constrained_system

netCDF4 = pytest.importorskip("netCDF4")
pytest.importorskip("yaml")

DATA = Path(__file__).resolve().parents[1] / "data" / "peridigm"

# (folder, deck, gold file): every deck of Peridigm's test/regression and
# test/verification (commit 82c6ad8) inside the static subset of docs/decks.md
DECKS = [
    ("Bar_OneBlock_OneMaterial_QS", "Bar.xml", "Bar_gold.e"),
    ("Bar_TwoBlocks_OneMaterial_QS", "Bar.xml", "Bar_gold.e"),
    ("Bar_TwoBlocks_TwoMaterial_QS", "Bar.xml", "Bar_gold.e"),
    ("Bar_TwoBlocks_TwoDifferentMaterial_QS", "Bar.xml", "Bar_gold.e"),
    ("Bar_TwoDisconnectedPieces_QS", "Bar.xml", "Bar_gold.e"),
    ("Body_Force", "Body_Force_QS.xml", "Body_Force_QS_gold.e"),
    ("Body_Force", "Body_Force_QS_NOX.xml", "Body_Force_QS_NOX_gold.e"),
    ("CentrifugalLoad", "CentrifugalLoad.xml", "CentrifugalLoad_gold.e"),
    ("Compression_QS_3x2x2", "Compression_QS_3x2x2.xml", "Compression_QS_3x2x2_gold.e"),
    ("Compression_QS_3x2x2_Exodus", "Compression_QS_3x2x2_Exodus.xml",
     "Compression_QS_3x2x2_Exodus_gold.e"),
    ("Compression_QS_3x2x2_TextFile", "Compression_QS_3x2x2_TextFile.xml",
     "Compression_QS_3x2x2_TextFile_gold.e"),
    ("PrecrackedPlate", "PrecrackedPlate.xml", "PrecrackedPlate_gold.e"),
    ("PrecrackedPlateTwoCracks", "PrecrackedPlate.xml", "PrecrackedPlate_gold.e"),
    ("DiskFilter", "DiskFilter.xml", "DiskFilter_gold.e"),
    ("NOX_QS", "NOX_QS_MatrixFree_3x3Prec.yaml", "NOX_QS_MatrixFree_3x3Prec_gold.e"),
    ("NOX_QS", "NOX_QS_MatrixFree_FullTangentPrec.yaml",
     "NOX_QS_MatrixFree_FullTangentPrec_gold.e"),
    ("NOX_QS", "NOX_QS_MatrixFree_NoPrec.yaml", "NOX_QS_MatrixFree_NoPrec_gold.e"),
    ("NOX_QS", "NOX_QS_Newton_AztecOOPrec.yaml", "NOX_QS_Newton_AztecOOPrec_gold.e"),
    ("NOX_QS", "NOX_QS_Newton_NoPrec.yaml", "NOX_QS_Newton_NoPrec_gold.e"),
    ("ElasticCorrespondenceQSTension", "ElasticCorrespondenceQSTension.xml",
     "ElasticCorrespondenceQSTension_gold.e"),
]  # fmt: skip
# the small decks run in the default test run, the rest with -m slow
FAST = {
    "PrecrackedPlate.xml",
    "Compression_QS_3x2x2.xml",
    "Compression_QS_3x2x2_Exodus.xml",
    "Compression_QS_3x2x2_TextFile.xml",
    "CentrifugalLoad.xml",
    "NOX_QS_Newton_NoPrec.yaml",
    "Body_Force_QS_NOX.xml",
}


def _params() -> list:
    return [
        pytest.param(
            folder,
            deck,
            gold,
            marks=() if deck in FAST and folder != "PrecrackedPlateTwoCracks" else pytest.mark.slow,
            id=f"{folder}/{deck}",
        )
        for folder, deck, gold in DECKS
    ]


def _gold(path: Path, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gold times and displacements (steps, n, 3), matched to ``points`` by position."""
    with netCDF4.Dataset(path) as ds:
        names = list(netCDF4.chartostring(ds.variables["name_nod_var"][:]))
        x = np.column_stack([np.asarray(ds.variables[f"coord{c}"][:]) for c in "xyz"])
        u = np.stack(
            [
                np.asarray(ds.variables[f"vals_nod_var{names.index('Displacement' + c) + 1}"][:])
                for c in "XYZ"
            ],
            axis=-1,
        )
        t = np.asarray(ds.variables["time_whole"][:])
    dist, idx = cKDTree(x).query(points)
    # Peridigm's points are the element centroids pdlin computes (same arithmetic)
    assert dist.max() <= 1e-9 * np.ptp(x, axis=0).max()
    return t, u[:, idx]


def _peridigm_lps_force(system, u: np.ndarray) -> np.ndarray:
    """Nodal force of Peridigm's ``Elastic`` material with finite kinematics (elastic.cxx).

    ω = 1, discrete weighted volume ``m = Σ |ξ|² V_j``, extension ``e = |ξ + η| - |ξ|``,
    dilatation ``θ = 3/m Σ |ξ| e V_j``, scalar force state
    ``t = 3 K θ |ξ| / m + 15 μ (e - θ |ξ| / 3) / m`` along the deformed bond, acting on i
    and (reaction) on j.
    """
    cloud, bonds = system.cloud, system.disc.real_bonds
    x, v, n = cloud.points, np.asarray(cloud.volumes), cloud.n
    k_mod, mu = (np.broadcast_to(np.asarray(a, float), (n,)) for a in system.model.moduli(3))
    i, j = bonds.i, bonds.j
    xi = x[j] - x[i]
    r = np.linalg.norm(xi, axis=1)
    y = xi + u[j] - u[i]
    ly = np.linalg.norm(y, axis=1)
    e = ly - r
    m = np.bincount(i, r * r * v[j], n)
    theta = np.bincount(i, 3.0 * r * e * v[j], n) / m
    t = 3.0 * k_mod[i] * theta[i] * r / m[i] + 15.0 * mu[i] * (e - theta[i] * r / 3.0) / m[i]
    pair = (t * v[i] * v[j] / ly)[:, None] * y
    f = np.stack(
        [np.bincount(i, pair[:, c], n) - np.bincount(j, pair[:, c], n) for c in range(3)], -1
    )
    return f.ravel()


def _displacement(fields: dict) -> np.ndarray:
    """The (n, 3) displacement of a result's fields, whatever writer stored them."""
    low = {k.lower(): np.asarray(v) for k, v in fields.items()}
    if "displacement" in low:
        return low["displacement"]
    # a writer that stores components (Peridigm's DisplacementX, ... in Exodus)
    return np.column_stack([low[f"displacement{c}"] for c in "xyz"])


def _run_deck(tmp_path: Path, folder: str, deck: str) -> tuple[pdlin.scene.Scene, np.ndarray]:
    """Copy the deck's folder unchanged, ``pdlin run`` it, read back its result file."""
    work = tmp_path / folder
    shutil.copytree(DATA / folder, work)
    before = set(work.iterdir())
    assert main(["run", str(work / deck), "-q"]) == 0
    written = sorted(set(work.iterdir()) - before)
    assert written, "pdlin run wrote no result file"
    scene = pdlin.read_deck(work / deck)
    res = read_result(written[0])
    u = _displacement(res.steps[-1] if res.times.size > 1 else res.fields())
    # the result file holds the deck's points in deck order
    assert np.allclose(res.points, scene.cloud.points, rtol=0, atol=1e-12)
    return scene, u


@pytest.mark.parametrize(("folder", "deck", "gold"), _params())
def test_peridigm_deck_runs_unchanged_and_matches_gold(tmp_path, folder, deck, gold):
    scene, u = _run_deck(tmp_path, folder, deck)
    t, ug = _gold(DATA / folder / gold, scene.cloud.points)
    scale = np.abs(ug[-1]).max()
    if scene.nonlinear is not None:
        # several load steps: Peridigm's finite kinematics (kinematics 'auto'); the .comp
        # tolerance is 1e-9 for these decks, measured 3e-12 (bars), 1.4e-13 (compression)
        assert np.abs(u - ug[-1]).max() <= 1e-9
        u = pdlin.solve(pdlin.read_deck(DATA / folder / deck, kinematics="linear").problem).u
    # final state: pdlin's linear solution against Peridigm's nonlinear one; measured
    # 6.8e-6 (CentrifugalLoad) .. 4.5e-3 (Compression, 5 % strain) of max|u| (docs/decks.md)
    assert np.abs(u - ug[-1]).max() <= 1e-2 * scale
    if t.size >= 3:
        # linear part of the gold path: slope at t = 0 of the quadratic through
        # (0, 0), (t1, u1), (t2, u2), times the final time
        t1, t2, u1, u2 = t[1], t[2], ug[1], ug[2]
        slope = (u1 * t2**2 - u2 * t1**2) / (t1 * t2 * (t2 - t1))
        # measured 2.2e-6 (Bar), 1.6e-6 (Compression), 2.5e-5 (ElasticCorrespondence) of
        # max|u| (docs/decks.md); the remainder is the cubic term of the gold path
        assert np.abs(u - slope * t[-1]).max() <= 1e-4 * scale


@pytest.mark.parametrize(("folder", "deck", "gold"), _params())
def test_deck_is_the_linearization_of_peridigms_nonlinear_problem(folder, deck, gold):
    scene = pdlin.read_deck(DATA / folder / deck, kinematics="linear")
    if not isinstance(scene.model, pdlin.LPS):
        pytest.skip("the finite-kinematics reference is written for Peridigm's Elastic (LPS)")
    system = constrained_system(scene.problem)
    u = np.asarray(pdlin.solve(scene.problem).u)
    stiff = system.assemble().tocsc()
    # tangent: K v = -d/ds f_NL(s v) at s = 0 (central difference cancels the s² term),
    # along v = u plus a seeded random field (u alone is a rigid motion on some decks,
    # Bar_TwoDisconnectedPieces_QS, where K u is round-off)
    v = u + 0.5 * np.abs(u).max() * np.random.default_rng(34).standard_normal(u.shape)
    s = 1e-6 / np.abs(v).max()
    f_plus = _peridigm_lps_force(system, s * v)
    f_minus = _peridigm_lps_force(system, -s * v)
    ku = stiff @ v.ravel()
    # measured 3e-11 .. 2e-10 relative (round-off of the difference quotient)
    assert np.abs(ku + (f_plus - f_minus) / (2 * s)).max() <= 1e-6 * np.abs(ku).max()
    # the library's finite-kinematics model (what pdlin runs for Peridigm's Elastic with
    # finite kinematics) is that force: at the linear solution and at a field of 5 %
    # strain amplitude (finite rotations of the bonds)
    k_mod, mu = system.model.moduli(3)
    model = PeridigmElastic(K=k_mod, G=mu)
    bonds = system.disc.real_bonds
    strained = v * (0.05 * bonds.length.min() / np.abs(v).max())
    scale = np.abs(_peridigm_lps_force(system, strained)).max()
    for w in (u, strained):
        resp = model.respond(scene.cloud, bonds, w, model.initial_state(scene.cloud, bonds))
        ref = _peridigm_lps_force(system, w)
        # the same arithmetic in another order: measured <= 3e-12 of the strained field's
        # max |f| (nodal forces are differences of much larger bond forces; u is a rigid
        # motion on Bar_TwoDisconnectedPieces_QS, where both are round-off)
        assert np.abs(resp.force.ravel() - ref).max() <= 1e-9 * scale
    # and its consistent tangent is the derivative of that force at the 5 % field
    kt = model.respond(scene.cloud, bonds, w, {}, tangent=True).tangent
    h = 1e-7 * np.abs(w).max() / np.abs(v).max()
    df = _peridigm_lps_force(system, w + h * v) - _peridigm_lps_force(system, w - h * v)
    kv = kt @ v.ravel()
    # measured <= 1e-8 relative (central difference)
    assert np.abs(kv + df / (2 * h)).max() <= 1e-6 * np.abs(kv).max()


# decks of Peridigm's test folders outside the static subset: refused by key path
OUTSIDE = [
    ("Contact_2x1x1", "Contact_2x1x1.xml", r"^Peridigm\.Contact: not supported"),
    (
        "LinearLPSBar",
        "LinearLPSBar.yaml",
        r"^Materials\.Linearized LPS Material\.Material Model: 'Linear LPS Partial Volume'",
    ),
]


@pytest.mark.parametrize(("folder", "deck", "match"), OUTSIDE, ids=[f for f, _, _ in OUTSIDE])
def test_decks_outside_the_subset_are_refused_by_key_path(folder, deck, match):
    with pytest.raises(SceneError, match=match):
        pdlin.read_deck(DATA / folder / deck)


def test_outside_deck_through_pdlin_run_is_one_error_line(tmp_path, capsys):
    shutil.copytree(DATA / "Contact_2x1x1", tmp_path / "c")
    assert main(["run", str(tmp_path / "c" / "Contact_2x1x1.xml"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Peridigm.Contact" in err[0]


# PdQuickGrid decks (Peridigm_PdQuickGridDiscretization.cpp): the cloud and the bonds
# against the gold file's coordinates and Weighted_Volume m_i = sum_j |xi|^2 V_j (elastic.cxx),
# which Peridigm writes from its own bonds and volumes (the thermal decks' solutions:
# tests/verification/test_thermal_decks.py).
QUICKGRID = [
    ("Compression_QS_3x2x2", "Compression_QS_3x2x2.xml", "Compression_QS_3x2x2_gold.e"),
    ("ThermalExpansionCube", "ThermalExpansionCube.xml", "ThermalExpansionCube_gold.e"),
    # same Discretization and Blocks lists as ThermalExpansionCube; its own gold file (937 kB)
    # holds no Weighted_Volume and is not copied
    ("ThermalExpansionCubeElasticCorrespondence", "ThermalExpansionCubeElasticCorrespondence.xml",
     "../ThermalExpansionCube/ThermalExpansionCube_gold.e"),
]  # fmt: skip


@pytest.mark.parametrize(("folder", "deck", "gold"), QUICKGRID, ids=[q[0] for q in QUICKGRID])
def test_quickgrid_discretization_is_peridigms(folder, deck, gold):
    from pdlin.scene.decks import peridigm as decks

    raw = decks._load_xml(DATA / folder / deck)["Peridigm"]
    cloud, extra = decks._quickgrid_cloud(raw["Discretization"])
    (block,) = raw["Blocks"].values()
    horizon = float(block["Horizon"])
    bonds = pdlin.find_bonds(cloud, horizon, exclude=decks._strict_sphere(horizon))
    with netCDF4.Dataset(DATA / folder / gold) as ds:
        x = np.column_stack([np.asarray(ds.variables[f"coord{c}"][:]) for c in "xyz"])
        order = np.asarray(ds.variables["elem_num_map"][:]) - 1
        names = list(netCDF4.chartostring(ds.variables["name_elem_var"][:]))
        m_gold = np.asarray(
            ds.variables[f"vals_elem_var{names.index('Weighted_Volume') + 1}eb1"][0]
        )
    # Peridigm's points in Peridigm's order (global id i + j nx + k nx ny), to the last bit
    assert np.array_equal(order, np.arange(cloud.n))
    assert np.array_equal(cloud.points, x)
    assert list(extra["blocks"]) == ["block_1"]
    # weighted volume from pdlin's bonds and volumes: the same bonds and volumes
    # (measured: equal to round-off, 1e-15 relative)
    m = np.bincount(bonds.i, bonds.length**2 * bonds.volume_j, cloud.n)
    assert np.allclose(m, m_gold, rtol=1e-12, atol=0)


# Bond Filters (src/io/pdneigh/BondFilter.cxx): the decks with filters run above against
# their gold files; here the cut bonds themselves.
FILTERED = [
    ("PrecrackedPlate", "PrecrackedPlate.xml"),
    ("PrecrackedPlateTwoCracks", "PrecrackedPlate.xml"),
    ("DiskFilter", "DiskFilter.xml"),
    ("PrecrackJIntegral", "PrecrackJIntegral.xml"),
]


def _filter_and_candidates(folder: str, deck: str):
    """The deck's combined filter and the unfiltered bonds Peridigm's search finds."""
    scene = pdlin.read_deck(DATA / folder / deck)
    exclude = scene.problem.bond_options["exclude"]
    bonds = pdlin.find_bonds(scene.cloud, scene.problem.horizon)
    return scene, exclude, bonds


@pytest.mark.parametrize(("folder", "deck"), FILTERED, ids=[f for f, _ in FILTERED])
def test_bond_filters_cut_the_same_bonds_from_either_end(folder, deck):
    # Peridigm filters each point's list from that point (p0 = x_i); pdlin drops a bond when
    # either direction is cut: the same bonds when the cut does not depend on the direction
    scene, exclude, bonds = _filter_and_candidates(folder, deck)
    x = scene.cloud.points
    fwd = exclude(x[bonds.i], x[bonds.j])
    back = exclude(x[bonds.j], x[bonds.i])
    assert fwd.any()
    assert np.array_equal(fwd, back)
    kept = pdlin.find_bonds(scene.cloud, scene.problem.horizon, **scene.problem.bond_options)
    assert kept.n_bonds == bonds.n_bonds - int(fwd.sum())


@pytest.mark.parametrize(
    ("folder", "deck", "leaks"),
    [
        ("PrecrackedPlate", "PrecrackedPlate.xml", 0),
        ("PrecrackJIntegral", "PrecrackJIntegral.xml", 0),
    ],
)
def test_rectangular_plane_is_pdlins_crack_rectangle(folder, deck, leaks):
    # a Rectangular_Plane with a unit Bottom_Unit_Vector in the plane is the rectangle
    # r0, r0 + b u_b, r0 + b u_b + a u_a, r0 + a u_a (u_a = u_b x n): pdlin's own crack
    # test (find_bonds(cracks=...), two triangles) cuts the same bonds, also the bond through
    # the triangles' shared diagonal (PrecrackJIntegral: points 63-165, crossing at
    # (-1.5, 0, -0.25), which round-off let pass both triangles before the edges got a
    # tolerance; `leaks` counts such bonds, none now)
    from pdlin.scene.decks import peridigm as decks

    raw = decks._load_xml(DATA / folder / deck)["Peridigm"]
    ((_, f),) = raw["Discretization"]["Bond Filters"].items()

    def vec(name):
        return np.array([float(f[f"{name}_{c}"]) for c in "XYZ"])

    n, r0, ub = vec("Normal"), vec("Lower_Left_Corner"), vec("Bottom_Unit_Vector")
    ua = np.cross(ub, n)
    a, b = float(f["Side_Length"]), float(f["Bottom_Length"])
    c = [r0, r0 + b * ub, r0 + b * ub + a * ua, r0 + a * ua]
    scene, exclude, bonds = _filter_and_candidates(folder, deck)
    cut_pdlin = pdlin.find_bonds(scene.cloud, scene.problem.horizon, cracks=[c[:3], [c[0], *c[2:]]])
    kept = pdlin.find_bonds(scene.cloud, scene.problem.horizon, **scene.problem.bond_options)
    assert kept.n_bonds < bonds.n_bonds
    diff = set(zip(cut_pdlin.i.tolist(), cut_pdlin.j.tolist(), strict=True)) ^ set(
        zip(kept.i.tolist(), kept.j.tolist(), strict=True)
    )
    assert len(diff) == 2 * leaks
    for i, j in diff:  # each a bond Peridigm cuts that meets the plane on the diagonal
        p, q = scene.cloud.points[i], scene.cloud.points[j]
        x = p + (np.dot(r0 - p, n) / np.dot(q - p, n)) * (q - p)
        on_diag = np.linalg.norm(np.cross(x - c[0], c[2] - c[0])) / np.linalg.norm(c[2] - c[0])
        assert exclude(p[None], q[None])[0] and on_diag < 1e-12


@pytest.mark.slow
def test_disk_filter_neighbour_counts_are_peridigms():
    scene = pdlin.read_deck(DATA / "DiskFilter" / "DiskFilter.xml")
    bonds = pdlin.find_bonds(scene.cloud, scene.problem.horizon, **scene.problem.bond_options)
    with netCDF4.Dataset(DATA / "DiskFilter" / "DiskFilter_gold.e") as ds:
        x = np.column_stack([np.asarray(ds.variables[f"coord{c}"][:]) for c in "xyz"])
        node = np.asarray(ds.variables["connect1"][:]).ravel() - 1  # one node per element
        count = np.asarray(ds.variables["vals_elem_var1eb1"][-1])  # Number_Of_Neighbors
    dist, idx = cKDTree(x[node]).query(scene.cloud.points)
    assert dist.max() == 0.0
    # Peridigm's neighbour counts after its Disk filter, point by point
    assert np.array_equal(bonds.family_size, count[idx])


def test_precrack_j_integral_deck_runs(tmp_path):
    # Peridigm ships no gold file for it (a J-integral verification): it runs unchanged
    scene, u = _run_deck(tmp_path, "PrecrackJIntegral", "PrecrackJIntegral.xml")
    assert np.isfinite(u).all() and np.abs(u).max() > 0


def test_deck_without_boundary_conditions_is_at_rest(tmp_path):
    # Peridigm's Interfaces deck has no Boundary Conditions list: nothing prescribed and no
    # load, so Peridigm's quasi-static solve stops at u = 0 (its gold file holds only the
    # interface apertures); pdlin prescribes that u = 0
    scene, u = _run_deck(tmp_path, "Interfaces", "Interfaces.xml")
    assert scene.cloud.n > 0
    assert np.array_equal(u, np.zeros_like(u))


def test_multiple_horizons_deck_holds_points_without_neighbours(tmp_path, caplog):
    # Peridigm's MultipleHorizons deck (no Boundary Conditions: u = 0) leaves points without
    # neighbours (gold Number_Of_Neighbors 0; block_4's horizon 0.765 is below the spacing
    # 1): pdlin holds them at rest, logs them and reports them in result.info
    scene, u = _run_deck(tmp_path, "MultipleHorizons", "MultipleHorizons.xml")
    t, ug = _gold(DATA / "MultipleHorizons" / "MultipleHorizons_gold.e", scene.cloud.points)
    assert np.array_equal(u, ug[-1]) and not u.any()  # Peridigm's answer: at rest
    with caplog.at_level("WARNING", logger="pdlin.system"):
        res = pdlin.solve(scene.problem)
    x = scene.cloud.points
    iso = res.info["isolated_points"]
    assert len(iso) == 5 and "without bonds held at rest" in caplog.text
    with netCDF4.Dataset(DATA / "MultipleHorizons" / "MultipleHorizons_gold.e") as ds:
        names = list(netCDF4.chartostring(ds.variables["name_elem_var"][:]))
        k = names.index("Number_Of_Neighbors") + 1
        nblk = len(ds.variables["eb_names"])
        count = np.concatenate(
            [np.asarray(ds.variables[f"vals_elem_var{k}eb{b + 1}"][-1]) for b in range(nblk)]
        )
        xc = np.concatenate(
            [np.column_stack([np.asarray(ds.variables[f"coord{c}"][:]) for c in "xyz"])[
                np.asarray(ds.variables[f"connect{b + 1}"][:]).ravel() - 1] for b in range(nblk)]
        )  # fmt: skip
    count = count[cKDTree(xc).query(x)[1]]
    # Peridigm's families are one-sided: j is i's neighbour when |xi| < delta_i (each point
    # searches with its own horizon; measured: equal to the gold counts at all 48 points)
    h = np.asarray(scene.problem.horizon)
    dist = np.linalg.norm(x[:, None] - x[None], axis=2)
    assert np.array_equal(((dist < h[:, None]) & (dist > 0)).sum(axis=1), count)
    # pdlin bonds |xi| <= max(delta_i, delta_j) (symmetric): its isolated points have no
    # neighbour in Peridigm either, and the counts agree at 30 of the 48 points (measured)
    assert (count[iso] == 0).all() and int((count == 0).sum()) == 15
    assert int((res.bonds.family_size == count).sum()) == 30


# Decks with several load steps: pdlin run solves each step at that step's prescribed
# values (one linear solve each) and writes them as one time series (.pvd for .vtu output)
SERIES = [
    ("Compression_QS_3x2x2", "Compression_QS_3x2x2.xml", "Compression_QS_3x2x2_gold.e"),
    ("Compression_QS_CyclicLoading_3x2x2", "Compression_QS_CyclicLoading_3x2x2.xml",
     "Compression_QS_CyclicLoading_3x2x2_gold.e"),
    ("Bar_OneBlock_OneMaterial_QS", "Bar.xml", "Bar_gold.e"),
    ("ElasticCorrespondenceQSTension", "ElasticCorrespondenceQSTension.xml",
     "ElasticCorrespondenceQSTension_gold.e"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("folder", "deck", "gold"),
    [
        pytest.param(*d, marks=() if d[0].startswith("Compression") else pytest.mark.slow, id=d[0])
        for d in SERIES
    ],
)
def test_load_steps_are_a_time_series_matching_gold_at_every_step(tmp_path, folder, deck, gold):
    # the linearized load steps (pdlin run --kinematics linear; 'auto' runs Peridigm's
    # finite kinematics on the Elastic decks, test_peridigm_finite.py)
    work = tmp_path / folder
    shutil.copytree(DATA / folder, work)
    assert main(["run", str(work / deck), "-q", "--kinematics", "linear"]) == 0
    scene = pdlin.read_deck(work / deck, kinematics="linear")
    res = read_result(scene.output)  # .e where the deck asks for ExodusII, else .pvd
    t, ug = _gold(DATA / folder / gold, scene.cloud.points)
    # Peridigm's step times t0 + (i + 1) (t1 - t0) / N, its initial state included (the gold
    # files' times are accumulated, t += dt, by an older Peridigm: equal to 1 ulp)
    assert res.times.shape == t.shape
    assert np.allclose(res.times, t, rtol=1e-15, atol=0)
    u = np.stack([_displacement(step) for step in res.steps])
    amp = np.abs(ug).max(axis=(1, 2))
    # every step against the gold step: the difference is Peridigm's geometric
    # nonlinearity, which grows with the step's strain; measured max over the steps of
    # max|u_k - u_gold,k| / max|u_gold,k|: 4.5e-3 (both Compression decks, at 5 % strain),
    # 2.2e-4 (Bar), 7.6e-5 (ElasticCorrespondence)
    err = np.abs(u - ug).max(axis=(1, 2))
    assert np.all(err <= 1e-2 * amp + 1e-12 * amp.max())
    # the steps are linear solves at each step's own values: u_k is u at the largest step
    # scaled by the ratio of the prescribed values there (x face: -0.1 t / T or
    # -0.1 sin(pi t / T); the bars: linear in t)
    ref = int(np.argmax(amp))
    ratio = np.array([np.abs(uk).max() for uk in u]) / np.abs(u[ref]).max()
    sign = np.sign(np.sum(u * u[ref], axis=(1, 2)))
    # measured <= 8e-16 of max|u| (round-off of the solves)
    assert np.abs(u - (sign * ratio)[:, None, None] * u[ref]).max() <= 1e-9 * np.abs(u[ref]).max()
