"""Compact ``repr`` and Jupyter ``_repr_html_`` summaries of pdlin objects.

Dataclass reprs dump every array of a result (and ``object.__repr__`` shows a memory
address); the helpers here summarize an object by its key sizes and parameters instead:
arrays appear as their shape, long texts are cut, and the whole repr stays short.
"""

from __future__ import annotations

import html
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

#: longest repr produced by :func:`compact_repr` (characters)
MAX_REPR = 300
#: longest single value shown in a repr or table cell (characters)
MAX_VALUE = 90


class Raw(str):
    """Text shown as it is (a nested repr), not quoted."""

    __slots__ = ()


def format_value(value: Any) -> str:
    """One value as short text: numbers to 4 significant digits, arrays as their shape.

    Examples
    --------
    >>> import numpy as np
    >>> format_value(70e9), format_value(np.ones((100, 2))), format_value("stress")
    ('7e+10', '<100x2 array>', "'stress'")
    >>> format_value(np.float64(0.25)), format_value(True), format_value([1, 2])
    ('0.25', 'True', '[1, 2]')
    """
    if isinstance(value, bool | np.bool_):
        return str(bool(value))
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        return f"{float(value):.4g}"
    if isinstance(value, np.ndarray):
        if value.ndim == 0:
            return format_value(value.item())
        return f"<{'x'.join(str(s) for s in value.shape)} array>"
    if isinstance(value, Raw):
        text = str(value)
    elif isinstance(value, str):
        text = repr(value)
    elif isinstance(value, Mapping):
        text = "{" + ", ".join(f"{k}: {format_value(v)}" for k, v in value.items()) + "}"
    elif isinstance(value, list | tuple) and len(value) <= 8:
        inner = ", ".join(format_value(v) for v in value)
        text = f"[{inner}]" if isinstance(value, list) else f"({inner})"
    elif isinstance(value, list | tuple):
        text = f"<{len(value)} items>"
    else:
        text = repr(value)
    limit = 2 * MAX_VALUE if isinstance(value, Raw) else MAX_VALUE
    return text if len(text) <= limit else text[: limit - 4] + "...)"


def time_span(times: Any) -> Raw | None:
    """``first .. last`` of step times (one value when they agree), None when empty.

    Examples
    --------
    >>> time_span([0.25, 0.5, 1.0]), time_span([0.0])
    ('0.25 .. 1', '0')
    """
    t = np.asarray(times, dtype=float).reshape(-1)
    if not t.size:
        return None
    if t[0] == t[-1]:
        return Raw(format_value(t[0]))
    return Raw(f"{format_value(t[0])} .. {format_value(t[-1])}")


def compact_repr(name: str, items: Mapping[str, Any]) -> str:
    """``name(key=value, ...)`` of the items that are not None, at most :data:`MAX_REPR` long.

    Examples
    --------
    >>> compact_repr("LPS", {"E": 1e9, "nu": 0.25, "peridigm": None})
    'LPS(E=1e+09, nu=0.25)'
    """
    parts = [f"{k}={format_value(v)}" for k, v in items.items() if v is not None]
    text = f"{name}({', '.join(parts)})"
    if len(text) > MAX_REPR:
        text = text[: MAX_REPR - 4] + "...)"
    return text


def html_table(title: str, rows: Iterable[tuple[str, Any]]) -> str:
    """Render ``(label, value)`` rows as an HTML ``<table>`` under a caption (Jupyter).

    Examples
    --------
    >>> html_table("StaticResult", [("converged", True), ("solver", "direct")])
    ... # doctest: +ELLIPSIS
    '<table><caption>StaticResult</caption><tr><th ...>converged</th><td ...>True</td></tr>...'
    """
    body = "".join(
        f'<tr><th style="text-align:left">{html.escape(str(k))}</th>'
        f'<td style="text-align:left">{html.escape(v if isinstance(v, str) else format_value(v))}'
        "</td></tr>"
        for k, v in rows
        if v is not None
    )
    return f"<table><caption>{html.escape(title)}</caption>{body}</table>"
