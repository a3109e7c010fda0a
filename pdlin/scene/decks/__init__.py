"""Peridigm and PeriLab input decks (static subset) read into a pdlin ``Scene``.

:func:`read_deck` turns a Peridigm deck (YAML or Teuchos ParameterList XML) or a
PeriLab.jl deck (YAML) into the same :class:`pdlin.scene.Scene` a TOML scene
gives, so ``pdlin run DECK.yaml`` and :func:`pdlin.solve` work unchanged.  Every
key is checked: physics pdlin does not have raises :class:`pdlin.errors.SceneError`
naming the key path and what is supported; cosmetic keys (``Verbose``, output
frequency, compute classes, ...) are accepted and logged (logger ``pdlin.io.decks``,
the name the readers had before they moved here).  The key-by-key mapping is in
``docs/decks.md``.

Modules
-------
:mod:`pdlin.scene.decks.expressions`
    The whitelisted evaluator of boundary-condition expressions ``f(x, y, z, t)``.
:mod:`pdlin.scene.decks.peridigm`
    Peridigm decks: discretizations (text, Exodus, PdQuickGrid), materials, blocks,
    bond filters, boundary conditions, solver and output lists.
:mod:`pdlin.scene.decks.perilab`
    PeriLab.jl decks: text meshes, material models, blocks, static solver, conditions.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from ...errors import SceneError
from ..scene import Scene
from ._common import _load_yaml
from .expressions import deck_expression
from .peridigm import _load_xml, _peridigm, peridigm_bond_filters, peridigm_hourglass_penalty
from .perilab import _perilab

__all__ = ["read_deck", "deck_expression", "peridigm_hourglass_penalty", "peridigm_bond_filters"]


# --------------------------------------------------------------------------------------
def read_deck(path: str | Path, *, kinematics: str = "auto") -> Scene:
    r"""Read a Peridigm (YAML / XML) or PeriLab (YAML) input deck as a pdlin scene.

    The returned ``pdlin.scene.Scene`` is what ``pdlin.scene.load_scene``
    gives for a TOML scene: ``pdlin.solve(read_deck(p).problem)`` solves it and
    ``pdlin run DECK.yaml`` runs it.  Linear models are solved once at the deck's
    ``Final Time`` (boundary values are evaluated there, also when they are nonlinear in
    ``t``).  See ``docs/decks.md`` for the key-by-key mapping.

    Parameters
    ----------
    path : str or path-like
        ``.yaml`` / ``.yml`` (needs PyYAML, ``pip install "pdlin[decks]"``) or ``.xml``.
    kinematics : {'auto', 'finite', 'linear'}
        Peridigm's ``Elastic`` / ``Elastic Plastic`` materials: ``'finite'`` runs their own
        finite kinematics through :func:`pdlin.solve_nonlinear` (``scene.nonlinear``),
        ``'linear'`` their linearization at u = 0; ``'auto'`` (default) is finite for decks
        with plasticity or several load steps, linear otherwise (``docs/decks.md``).

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        An unsupported or invalid key, named by its path.

    Examples
    --------
    >>> import pathlib, tempfile, pdlin
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "bar.txt").write_text("\n".join(
    ...     f"{0.5 * i + 0.25} 0.25 0.25 1 0.125" for i in range(6)))
    >>> _ = (d / "bar.yaml").write_text('''
    ... Peridigm:
    ...   Discretization: {Type: "Text File", Input Mesh File: "bar.txt"}
    ...   Materials:
    ...     Steel: {Material Model: "Elastic Bond Based", Density: 7.8, Bulk Modulus: 1.0}
    ...   Blocks:
    ...     All: {Block Names: "block_1", Material: "Steel", Horizon: 1.01}
    ...   Boundary Conditions:
    ...     Node Set One: "1"
    ...     Node Set Two: "6"
    ...     Fix: {Type: "Prescribed Displacement", Node Set: "Node Set One", Value: "0.0"}
    ...     Pull: {Type: "Prescribed Displacement", Node Set: "Node Set Two", Value: "0.01*t"}
    ...   Solver: {Final Time: 1.0, QuasiStatic: {Number of Load Steps: 4}}
    ... ''')
    >>> scene = pdlin.read_deck(d / "bar.yaml")
    >>> scene.cloud.n, scene.cloud.dim, type(scene.model).__name__
    (6, 3, 'BondBased')
    """
    if kinematics not in ("auto", "finite", "linear"):
        raise SceneError(
            f"kinematics must be one of ['auto', 'finite', 'linear'], got {kinematics!r}"
        )
    p = Path(path)
    if not p.exists():
        raise SceneError(f"deck file not found: {p}")
    suffix = p.suffix.lower()
    if suffix in (".yaml", ".yml"):
        data = _load_yaml(p)
    elif suffix == ".xml":
        data = _load_xml(p)
    else:
        raise SceneError(f"deck file must end with .yaml, .yml or .xml, got {p.name!r}")
    if not isinstance(data, Mapping) or len(data) != 1:
        raise SceneError(
            f"{p.name}: a deck has one top-level list, 'Peridigm' or 'PeriLab', got "
            f"{list(data) if isinstance(data, Mapping) else type(data).__name__}"
        )
    ((top, body),) = data.items()
    base = p.parent
    if top == "Peridigm":
        return _peridigm(body, base, p.stem, kinematics)
    if top == "PeriLab":
        if kinematics == "finite":
            raise SceneError("kinematics 'finite' is for Peridigm decks; PeriLab decks are linear")
        return _perilab(body, base, p.stem)
    raise SceneError(f"{p.name}: top-level list must be 'Peridigm' or 'PeriLab', got {top!r}")
