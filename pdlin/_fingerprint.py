"""SHA-256 digests of the parts of a problem: the fingerprint of a nonlinear checkpoint.

A checkpoint of :func:`pdlin.solve_nonlinear` stores one digest per part (points, bonds,
model and material parameters, ...), so a resume with another problem is refused with
the parts that differ named.  Arrays are hashed by their bytes (with dtype and shape),
objects by their public attributes, recursively.
"""

from __future__ import annotations

import enum
import hashlib
import types
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["digest", "update"]

#: public attributes that record what a model did, not what it is: Correspondence's
#: ``assembly`` (how its last plan applied K) and ``symmetric`` (derived from the other
#: parameters, and for ``control='ads'`` set by the first plan)
_DIAGNOSTIC = frozenset({"assembly", "symmetric"})


def update(h: Any, obj: Any, _seen: set[int] | None = None) -> None:
    """Feed ``obj`` into the hash ``h``.

    Arrays by dtype, shape and bytes; numbers, strings, None and enums by type and repr;
    sequences and mappings item by item; functions by module, name, byte code, constants
    and captured values; other objects by class name and public attributes (names without
    a leading underscore: caches are private; ``_DIAGNOSTIC`` ones excluded).  An object
    met again is hashed as a marker.
    """
    seen = set() if _seen is None else _seen
    if obj is None or isinstance(obj, bool | int | float | complex | str | bytes | enum.Enum):
        h.update(f"{type(obj).__name__}:{obj!r};".encode())
        return
    if isinstance(obj, np.generic):
        obj = np.asarray(obj)
    if isinstance(obj, np.ndarray):
        h.update(f"nd:{obj.dtype.str}:{obj.shape};".encode())
        if obj.dtype.kind == "O":
            for item in obj.reshape(-1).tolist():  # object arrays: rare, small
                update(h, item, seen)
        else:
            h.update(np.ascontiguousarray(obj).tobytes())
        return
    if id(obj) in seen:
        h.update(b"cycle;")
        return
    seen.add(id(obj))
    if isinstance(obj, list | tuple):
        h.update(f"{type(obj).__name__}:{len(obj)};".encode())
        for item in obj:
            update(h, item, seen)
    elif isinstance(obj, Mapping):
        h.update(f"map:{len(obj)};".encode())
        for key in sorted(obj, key=repr):
            update(h, key, seen)
            update(h, obj[key], seen)
    elif isinstance(obj, set | frozenset):
        h.update(f"set:{len(obj)};".encode())
        for item in sorted(obj, key=repr):
            update(h, item, seen)
    elif isinstance(obj, types.FunctionType | types.MethodType | types.BuiltinFunctionType):
        h.update(f"fn:{getattr(obj, '__module__', '')}.{obj.__qualname__};".encode())
        code = getattr(obj, "__code__", None)
        if code is not None:
            h.update(code.co_code)
            update(h, [c for c in code.co_consts if not isinstance(c, types.CodeType)], seen)
        for cell in getattr(obj, "__closure__", None) or ():  # captured values
            update(h, cell.cell_contents, seen)
    else:
        cls = type(obj)
        h.update(f"obj:{cls.__module__}.{cls.__qualname__};".encode())
        attrs: dict[str, Any] = {}
        if hasattr(obj, "__dict__"):
            attrs.update(vars(obj))
        for klass in cls.__mro__:
            for name in getattr(klass, "__slots__", ()):
                if hasattr(obj, name):
                    attrs[name] = getattr(obj, name)
        for name in sorted(attrs):
            if name.startswith("_") or name in _DIAGNOSTIC:
                continue
            h.update(f"{name}=".encode())
            update(h, attrs[name], seen)


def digest(*objs: Any) -> str:
    """Return the SHA-256 hex digest of ``objs`` (see :func:`update`).

    Examples
    --------
    >>> import numpy as np
    >>> digest(np.arange(3.0)) == digest(np.arange(3.0)), digest(1.0) == digest(1)
    (True, False)
    >>> def scaled(c):
    ...     return lambda r, h: c * (1.0 - r / h)
    >>> digest(scaled(1.0)) == digest(scaled(1.0)), digest(scaled(1.0)) == digest(scaled(2.0))
    (True, False)
    """
    h = hashlib.sha256()
    for obj in objs:
        update(h, obj)
    return h.hexdigest()
