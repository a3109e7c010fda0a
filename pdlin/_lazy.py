"""Module attributes imported on first access (PEP 562 ``__getattr__``).

A package lists the names whose module is heavy to import (sympy behind the exact weights)
and resolves them on first use, so ``import pdlin`` stays cheap while ``pdlin.X`` and
``from pdlin import X`` keep working.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any


def lazy_attribute(
    package: str, lazy: Mapping[str, str], namespace: dict[str, Any], name: str
) -> Any:
    """Import ``name`` from its module ``lazy[name]`` (relative to ``package``), keep it.

    Parameters
    ----------
    package : str
        The package's ``__name__`` (anchor of the relative module names).
    lazy : mapping of str to str
        Attribute name -> relative module that defines it.
    namespace : dict
        The package's ``globals()``: the value is stored there, so later look-ups are
        plain attribute reads.
    name : str
        The attribute asked for.

    Raises
    ------
    AttributeError
        ``name`` is not one of ``lazy``'s names (what a missing attribute raises).

    Examples
    --------
    >>> ns = {}
    >>> lazy_attribute("pdlin", {"grid": ".geometry"}, ns, "grid").__name__
    'grid'
    >>> "grid" in ns
    True
    """
    module = lazy.get(name)
    if module is None:
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, package), name)
    namespace[name] = value
    return value


def quad(*args: Any, **kwargs: Any) -> Any:
    """:func:`scipy.integrate.quad`, imported on first use.

    ``scipy.integrate`` pulls in ``scipy.optimize`` (~0.1 s), which ``import pdlin`` does
    not need.

    Examples
    --------
    >>> round(quad(lambda x: x, 0.0, 2.0)[0], 12)
    2.0
    """
    from scipy.integrate import quad as _quad

    return _quad(*args, **kwargs)
