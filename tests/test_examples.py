"""The runnable examples run and give the documented results."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import numpy as np

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_bar_tension_example():
    out = _load("bar_tension").main()
    errs = [r["max_rel_error"] for r in out["graded_1d"]]
    ns = [r["N"] for r in out["graded_1d"]]
    rate = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert rate > 1.9  # O(h^2) at fixed delta/h (docs/bond_based.md)
    assert out["bar_3d"]["max_strain_error"] < 1e-9  # exact affine interior
