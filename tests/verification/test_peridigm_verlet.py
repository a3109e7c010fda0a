"""Issue 36: Peridigm's explicit (``Solver.Verlet``) decks run through ``pdlin run DECK``.

The decks of Peridigm's ``test/regression`` and ``test/verification`` folders whose physics
pdlin has (``Elastic`` and ``Elastic Bond Based`` materials, initial velocities and
displacements, prescribed displacements, body forces, ``Critical Stretch`` damage) are kept
unchanged with their meshes, gold Exodus files and exodiff ``.comp`` files under
``tests/data/peridigm`` (Peridigm's BSD license there).  Each is read by
``pdlin.read_deck`` and integrated by ``pdlin.dynamics.solve_explicit`` with the keywords
the deck gives (what ``pdlin run`` does); the displacements of every gold output step must
lie within the deck's own ``.comp`` tolerance (Peridigm's exodiff comparison), and the
velocities of the free DOFs within its velocity tolerance.  One deck also goes through the
command line and its Exodus output is compared.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import pdlin
from pdlin.cli.main import main
from pdlin.dynamics import solve_explicit
from pdlin.dynamics.forces import force_kernel
from pdlin.errors import SceneError

netCDF4 = pytest.importorskip("netCDF4")
pytest.importorskip("yaml")

DATA = Path(__file__).resolve().parents[1] / "data" / "peridigm"

# (folder, deck, gold file, .comp file, slow): Peridigm's Verlet decks inside the mapping
DECKS = [
    ("Compression_2x1x1", "Compression_2x1x1.yaml", "Compression_2x1x1.comp", False),
    ("Compression_3x1x1", "Compression_3x1x1.yaml", "Compression_3x1x1.comp", False),
    (
        "CompressionInitDisp_2x1x1",
        "CompressionInitDisp_2x1x1.xml",
        "CompressionInitDisp_2x1x1.comp",
        False,
    ),
    (
        "BondBreakingInitialVelocity",
        "BondBreakingInitialVelocity.xml",
        "BondBreakingInitialVelocity.comp",
        False,
    ),
    ("ElasticBondBased3D", "ElasticBondBased3D.yaml", "ElasticBondBased.comp", False),
    ("Body_Force", "Body_Force_Explicit.xml", "Body_Force.comp", False),
    ("WaveInBar", "WaveInBar.xml", "WaveInBar.comp", False),
    ("WaveInBar_MultiBlock", "WaveInBar_MultiBlock.xml", "WaveInBar_MultiBlock.comp", True),
    ("DefaultBlocks", "DefaultBlocks.xml", "DefaultBlocks.comp", True),
    *[
        ("DeformationGradient", f"DeformationGradient_{k}.xml", "DeformationGradient.comp", False)
        for k in (
            "NoDeformation",
            "NoLoad",
            "PlaneStrainCompression",
            "PureShear",
            "SimpleShear",
            "SolidRotation",
        )
    ],
    ("MultipleOutputFiles", "MultipleOutputFiles.xml", "MultipleOutputFiles1.comp", False),
    ("NodalVariableOutput", "NodalVariableOutput.xml", "NodalVariableOutput.comp", False),
    (
        "Compression_QS_Explicit_3x2x2",
        "Compression_QS_Explicit_3x2x2.xml",
        "Compression_QS_Explicit_3x2x2.comp",
        False,
    ),
]


def _tolerance(comp: Path, name: str) -> float:
    """The absolute tolerance of ``name`` in an exodiff ``.comp`` file (Peridigm's)."""
    for line in comp.read_text().splitlines():
        m = re.match(rf"\s*{name}\s+absolute\s+(\S+)", line)
        if m:
            return float(m.group(1))
    raise AssertionError(f"{name} not in {comp}")


def _gold(path: Path, points: np.ndarray) -> dict[str, np.ndarray]:
    """Gold times and nodal vectors (steps, n, 3), matched to ``points`` by position."""
    with netCDF4.Dataset(path) as ds:
        names = list(netCDF4.chartostring(ds.variables["name_nod_var"][:]))
        x = np.column_stack([np.asarray(ds.variables[f"coord{c}"][:]) for c in "xyz"])
        out = {"time": np.asarray(ds.variables["time_whole"][:])}
        for field in ("Displacement", "Velocity", "Force"):
            if field + "X" in names:
                out[field] = np.stack(
                    [
                        np.asarray(ds.variables[f"vals_nod_var{names.index(field + c) + 1}"][:])
                        for c in "XYZ"
                    ],
                    axis=-1,
                )
    dist, idx = cKDTree(x).query(points)
    # Peridigm's points are the element centroids / QuickGrid cells pdlin computes
    assert dist.max() <= 1e-9 * max(np.ptp(x, axis=0).max(), 1.0)
    return {k: (v if k == "time" else v[:, idx]) for k, v in out.items()}


def _run(folder: str, deck: str):
    scene = pdlin.read_deck(DATA / folder / deck)
    assert scene.explicit is not None
    return scene, solve_explicit(scene.problem, **scene.explicit)


@pytest.mark.parametrize(
    ("folder", "deck", "comp"),
    [
        pytest.param(f, d, c, marks=pytest.mark.slow if slow else (), id=f"{f}/{d}")
        for f, d, c, slow in DECKS
    ],
)
def test_verlet_deck_matches_its_gold_file(folder, deck, comp):
    scene, res = _run(folder, deck)
    # MultipleOutputFiles writes two lists (Output1, Output2): pdlin reads Output1
    name = "MultipleOutputFiles1" if folder == "MultipleOutputFiles" else Path(deck).stem
    gold = _gold(DATA / folder / (name + "_gold.e"), scene.problem.cloud.points)
    tol_u = _tolerance(DATA / folder / comp, "DisplacementX")
    tol_v = _tolerance(DATA / folder / comp, "VelocityX")
    # the gold frames are Peridigm's output steps (Output Frequency), pdlin's the same steps;
    # a chained deck's gold starts with its quasi-static steps: compare the Verlet frames
    n = res.times.size
    if folder == "Compression_QS_Explicit_3x2x2":
        assert gold["time"].size == 21 + n  # 20 quasi-static load steps and t = 0 before
        gold = {k: v[-n:] for k, v in gold.items()}
    assert gold["time"].size == n
    t0 = float(gold["time"][0])
    np.testing.assert_allclose(res.times + t0, gold["time"], rtol=0, atol=1e-14)
    # displacements of every output step (intermediate and final) within the .comp tolerance
    gap_u = np.abs(res.u - gold["Displacement"]).max(axis=(1, 2))
    assert gap_u.max() <= tol_u, (gap_u, tol_u)
    if folder != "DeformationGradient" or "No" not in deck:  # NoLoad, NoDeformation: u = 0
        assert np.abs(gold["Displacement"][-1]).max() > 1e3 * tol_u  # the deck moves
    # velocities of the free DOFs (pdlin gives prescribed DOFs their path's velocity)
    free = scene.problem.cloud.n * 3
    mask = np.ones(free, dtype=bool)
    mask[pdlin.constraints.resolve_dirichlet(scene.problem.cloud, scene.problem.dirichlet)[0]] = (
        False
    )
    if mask.any():
        vg = gold["Velocity"].reshape(len(gold["time"]), -1)[:, mask]
        vp = res.v.reshape(res.times.size, -1)[:, mask]
        assert np.abs(vp - vg).max() <= tol_v


def test_bond_breaking_deck_breaks_the_bond_peridigm_breaks():
    """``BondBreakingInitialVelocity``: one bond (two directions) breaks, as in the gold."""
    scene, res = _run("BondBreakingInitialVelocity", "BondBreakingInitialVelocity.xml")
    with netCDF4.Dataset(
        DATA / "BondBreakingInitialVelocity" / "BondBreakingInitialVelocity_gold.e"
    ) as ds:
        names = list(netCDF4.chartostring(ds.variables["name_elem_var"][:]))
        dmg = np.asarray(ds.variables[f"vals_elem_var{names.index('Damage') + 1}eb1"][:])
    # the gold Damage (Peridigm's point order, which is QuickGrid's and pdlin's): of the two
    # y-bonds of QuickGrid's cell box (reach 0 in x, 1 in y), the faster-opening one
    # (initial velocities ±244.959 against ±244.939) breaks: damage 1 at its two points
    assert dmg[0].max() == 0.0 and np.array_equal(dmg[-1], [0.0, 1.0, 0.0, 1.0])
    assert res.critical_stretch is not None and res.broken[-1] == 2  # one bond, two directions
    np.testing.assert_array_equal(res.damage[-1], dmg[-1])
    np.testing.assert_array_equal(res.damage[0], dmg[0])


def test_bond_based_force_is_peridigms():
    """``ElasticBondBased3D``: every point is prescribed, so compare the force.

    pdlin's finite bond-based force at the gold displacements equals the gold ``Force``
    (Peridigm's ``elastic_bond_based.cxx``, ``Force = Force_Density * Volume``) within the
    deck's ``.comp`` tolerance.
    """
    scene = pdlin.read_deck(DATA / "ElasticBondBased3D" / "ElasticBondBased3D.yaml")
    prob = scene.problem
    gold = _gold(DATA / "ElasticBondBased3D" / "ElasticBondBased3D_gold.e", prob.cloud.points)
    kern = force_kernel(prob.model, prob.cloud, prob.get_bonds(), linear=False)
    tol = _tolerance(DATA / "ElasticBondBased3D" / "ElasticBondBased.comp", "ForceX")
    for k in range(1, gold["time"].size):
        f = kern.force(gold["Displacement"][k], None)
        assert np.abs(f - gold["Force"][k]).max() <= tol
        assert np.abs(gold["Force"][k]).max() > 1e3 * tol


def test_pdlin_run_writes_the_gold_steps(tmp_path):
    """``pdlin run DECK -o out.e``: the Exodus series holds the gold's displacements."""
    out = tmp_path / "wave.e"
    assert main(["run", str(DATA / "WaveInBar" / "WaveInBar.xml"), "-o", str(out)]) == 0
    scene = pdlin.read_deck(DATA / "WaveInBar" / "WaveInBar.xml")
    gold = _gold(DATA / "WaveInBar" / "WaveInBar_gold.e", scene.problem.cloud.points)
    mine = _gold(out, scene.problem.cloud.points)
    np.testing.assert_allclose(mine["time"], gold["time"], rtol=0, atol=1e-14)
    tol = _tolerance(DATA / "WaveInBar" / "WaveInBar.comp", "DisplacementX")
    assert np.abs(mine["Displacement"] - gold["Displacement"]).max() <= tol


def test_verlet_deck_mapping():
    """The scene keywords of a Verlet deck: Peridigm's step count, dt, density, frames."""
    scene = pdlin.read_deck(DATA / "WaveInBar" / "WaveInBar.xml")
    ex = scene.explicit
    # Peridigm.cpp: floor((Final Time - Initial Time) / Fixed dt) = floor(2e-5 / 9.0659e-8)
    assert ex["dt"] == 9.0659e-08 and ex["t_end"] == 220 * 9.0659e-08
    assert ex["density"] == 2200.0 and ex["output_every"] == 20 and ex["linear"] is False
    assert np.count_nonzero(ex["v0"][:, 0] == -100.0) > 0  # the deck's Initial Velocity
    assert type(scene.problem.model).__name__ == "LPS"
    assert scene.problem.model.linearization == "paper"


@pytest.mark.parametrize(
    ("edit", "pattern"),
    [
        (
            lambda r: (
                r["Materials"]["My Elastic Material"].update(
                    {"Material Model": "Elastic Correspondence", "Hourglass Coefficient": 0.02}
                )
                or r["Materials"]["My Elastic Material"].pop("Apply Shear Correction Factor")
            ),
            r"'correspondence' materials are not supported with Solver\.Verlet",
        ),
        (
            lambda r: r["Solver"]["Verlet"].pop("Fixed dt"),
            r"Solver\.Verlet\.Fixed dt is required",
        ),
        (
            lambda r: r["Solver"]["Verlet"].update({"Bogus": 1}),
            r"Solver\.Verlet\.Bogus: not supported",
        ),
        (
            lambda r: r["Boundary Conditions"]["Initial Velocity Min X Face"].update(
                {"Type": "Initial Temperature"}
            ),
            r"Initial Velocity Min X Face\.Type: 'Initial Temperature' is not supported with "
            r"Solver\.Verlet",
        ),
        (
            lambda r: r["Boundary Conditions"]["Initial Velocity Min X Face"].update(
                {"Type": "Body Force", "Value": "t"}
            ),
            r"a Body Force that changes in time is not supported",
        ),
        (
            lambda r: (
                r.update({"Damage Models": {"D": {"Damage Model": "Interface Aware"}}})
                or r["Blocks"]["My Group of Blocks"].update({"Damage Model": "D"})
            ),
            r"Damage Models\.D\.Damage Model: 'Interface Aware' is not supported",
        ),
        (
            lambda r: r["Materials"]["My Elastic Material"].pop("Density"),
            r"missing deck key Materials\.My Elastic Material\.Density",
        ),
    ],
)
def test_verlet_decks_outside_the_mapping_are_refused(tmp_path, edit, pattern):
    import yaml

    deck = yaml.safe_load((DATA / "Compression_2x1x1" / "Compression_2x1x1.yaml").read_text())
    edit(deck["Peridigm"])
    p = tmp_path / "deck.yaml"
    p.write_text(yaml.safe_dump(deck))
    with pytest.raises(SceneError, match=pattern):
        pdlin.read_deck(p)


def test_damage_and_cube_neighbourhoods_stay_refused_in_static_decks(tmp_path):
    import yaml

    deck = yaml.safe_load((DATA / "Compression_2x1x1" / "Compression_2x1x1.yaml").read_text())
    root = deck["Peridigm"]
    root["Solver"] = {"Final Time": 1.0, "QuasiStatic": {"Number of Load Steps": 1}}
    p = tmp_path / "deck.yaml"
    p.write_text(yaml.safe_dump(deck))
    with pytest.raises(SceneError, match=r"cube of cells, which pdlin reads for Solver\.Verlet"):
        pdlin.read_deck(p)
    root["Discretization"]["NeighborhoodType"] = "Spherical"
    root["Damage Models"] = {"D": {"Damage Model": "Critical Stretch", "Critical Stretch": 0.1}}
    p.write_text(yaml.safe_dump(deck))
    with pytest.raises(SceneError, match=r"Damage Models: damage is supported with Solver\.Verlet"):
        pdlin.read_deck(p)


def _peridigm_elastic_force(cloud, bonds, K, G, u, alive):
    """Peridigm's ``Elastic`` force with bond damage, written out from ``elastic.cxx``.

    Per directed bond ``(i, j)``: ``ζ = |ξ|``, ``Y = ξ + u_j - u_i``, ``e = |Y| - ζ``, weighted
    volume of the intact family ``m_i = Σ ζ² V_j``, dilatation over the unbroken bonds
    ``θ_i = 3/m_i Σ (1 - d) ζ e V_j``, scalar force
    ``t = (1 - d) (3 K θ_i ζ / m_i + 15 μ / m_i (e - θ_i ζ / 3))`` along ``Y/|Y|``;
    ``f_i += t V_j Y/|Y|``, ``f_j -= t V_i Y/|Y|`` (force densities), times ``V_i``.
    """
    i, j = np.asarray(bonds.i), np.asarray(bonds.j)
    x, vol = cloud.points, np.asarray(cloud.volumes)
    xi = x[j] - x[i]
    zeta = np.linalg.norm(xi, axis=1)
    Y = xi + u[j] - u[i]
    dY = np.linalg.norm(Y, axis=1)
    e = dY - zeta
    m = np.bincount(i, weights=zeta**2 * vol[j], minlength=cloud.n)
    theta = 3.0 / m * np.bincount(i, weights=alive * zeta * e * vol[j], minlength=cloud.n)
    t = alive * (3 * K * theta[i] * zeta / m[i] + 15 * G / m[i] * (e - theta[i] * zeta / 3))
    M = Y / dY[:, None]
    fd = np.zeros((cloud.n, 3))
    np.add.at(fd, i, (t * vol[j])[:, None] * M)
    np.add.at(fd, j, -(t * vol[i])[:, None] * M)
    return fd * vol[:, None]


def test_elastic_force_with_broken_bonds_is_peridigms():
    """The Verlet decks' ``Elastic`` kernel with a partly broken family is ``elastic.cxx``'s."""
    cloud = pdlin.grid((5, 4, 3), spacing=0.1)
    bonds = pdlin.find_bonds(cloud, ratio=2.015)
    K, G = 130e9, 60e9
    model = pdlin.LPS(K=K, G=G, peridigm=True, linearization="paper")
    kern = force_kernel(model, cloud, bonds, linear=False)
    rng = np.random.default_rng(7)
    u = 5e-3 * rng.normal(size=(cloud.n, 3))
    broken = rng.random(bonds.n_bonds) < 0.3
    broken = broken | broken[np.asarray(bonds.reverse)]  # Peridigm breaks both directions
    alive = (~broken).astype(float)
    ref = _peridigm_elastic_force(cloud, bonds, K, G, u, alive)
    mine = kern.force(u, alive.copy())
    assert 0.2 < broken.mean() < 0.6
    assert np.abs(mine - ref).max() <= 1e-12 * np.abs(ref).max()


def test_prescribed_displacement_adds_increments_to_the_initial_displacement(tmp_path):
    """Peridigm's ``DirichletIncrementBC`` (``Peridigm_BoundaryCondition.cpp``) in Verlet runs.

    The prescribed DOF's velocity is ``(g(t) - g(t - Δt)) / Δt``, so the displacement is the
    initial displacement plus ``g(t) - g(t0)``: 2e-5 + (1e-3 * 5e-5 - 1e-3 * 0) here, and a
    value nonzero at ``t0`` (``1 + 1e-3 t``) is not applied at once.
    """
    import yaml

    deck = yaml.safe_load((DATA / "Compression_2x1x1" / "Compression_2x1x1.yaml").read_text())
    bcs = deck["Peridigm"]["Boundary Conditions"]
    bcs["Initial Velocity Min X Face"] = {
        "Type": "Initial Displacement",
        "Node Set": "Min X Node Set",
        "Coordinate": "x",
        "Value": "2.0e-5",
    }
    bcs["Pull"] = {
        "Type": "Prescribed Displacement",
        "Node Set": "Min X Node Set",
        "Coordinate": "x",
        "Value": "1.0 + 1.0e-3*t",
    }
    p = tmp_path / "deck.yaml"
    p.write_text(yaml.safe_dump(deck))
    scene = pdlin.read_deck(p)
    res = solve_explicit(scene.problem, **scene.explicit)
    # atol: (1 + 1e-3 t) - 1 is exact to about 1e-16 (round-off of the value 1)
    np.testing.assert_allclose(res.u[:, 0, 0], 2.0e-5 + 1.0e-3 * res.times, rtol=0, atol=1e-15)


def test_other_solver_sequences_are_refused(tmp_path):
    import yaml

    deck = yaml.safe_load((DATA / "Compression_2x1x1" / "Compression_2x1x1.yaml").read_text())
    root = deck["Peridigm"]
    verlet = root.pop("Solver")
    root["Solver1"], root["Solver2"] = verlet, dict(verlet)  # Verlet then Verlet
    p = tmp_path / "deck.yaml"
    p.write_text(yaml.safe_dump(deck))
    with pytest.raises(SceneError, match=r"^Peridigm\.Solver1: several solvers are supported as"):
        pdlin.read_deck(p)


def test_linear_kinematics_is_refused_for_verlet_decks():
    with pytest.raises(
        SceneError, match=r"kinematics 'linear' is not available for Solver\.Verlet"
    ):
        pdlin.read_deck(DATA / "Compression_2x1x1" / "Compression_2x1x1.yaml", kinematics="linear")
