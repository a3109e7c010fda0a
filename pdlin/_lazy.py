"""Module attributes imported on first access (PEP 562 ``__getattr__``).

A package lists the names whose module is heavy to import (sympy behind the exact weights)
and resolves them on first use, so ``import pdlin`` stays cheap while ``pdlin.X`` and
``from pdlin import X`` keep working (:func:`lazy_attribute`).  A package also lists the
names that moved away from it: they keep working for one release, with a
:class:`DeprecationWarning` naming their new home (:func:`moved_attribute`).
"""

from __future__ import annotations

import importlib
import warnings
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


def moved_attribute(package: str, moved: Mapping[str, str], name: str) -> Any:
    """Resolve the deprecated alias ``package.name`` from its new home ``moved[name]``.

    Warns with a :class:`DeprecationWarning` that names the new import (pointing at the
    caller's line) and returns the object, which is not cached: every use warns.

    Parameters
    ----------
    package : str
        The package's ``__name__`` (the old home, named in the warning).
    moved : mapping of str to str
        Attribute name -> absolute name of the module that now provides it.
    name : str
        The attribute asked for.

    Returns
    -------
    object
        ``getattr(import_module(moved[name]), name)``.

    Raises
    ------
    AttributeError
        ``name`` is not one of ``moved``'s names (what a missing attribute raises).

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     f = moved_attribute("pdlin", {"grid": "pdlin.geometry"}, "grid")
    >>> f.__name__, caught[0].category.__name__
    ('grid', 'DeprecationWarning')
    >>> print(caught[0].message)  # doctest: +NORMALIZE_WHITESPACE
    pdlin.grid is deprecated and will be removed in the next release: use pdlin.geometry.grid
    (from pdlin.geometry import grid)
    """
    home = moved.get(name)
    if home is None:
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    warnings.warn(
        f"{package}.{name} is deprecated and will be removed in the next release: use "
        f"{home}.{name} (from {home} import {name})",
        DeprecationWarning,
        stacklevel=3,
    )
    return getattr(importlib.import_module(home), name)


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
