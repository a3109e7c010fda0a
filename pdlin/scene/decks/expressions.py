"""Deck expressions: a whitelisted evaluator of ``f(x, y, z, t)`` strings (never ``eval``)."""

from __future__ import annotations

import ast
import math
import operator
import re
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ...errors import SceneError

__all__ = ["deck_expression"]

_BINOPS: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_UNOPS: dict[type, Callable[[Any], Any]] = {ast.UAdd: operator.pos, ast.USub: operator.neg}
_FUNCS: dict[str, Callable[..., Any]] = {
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "asin": np.arcsin,
    "acos": np.arccos,
    "atan": np.arctan,
    "atan2": np.arctan2,
    "sinh": np.sinh,
    "cosh": np.cosh,
    "tanh": np.tanh,
    "exp": np.exp,
    "log": np.log,
    "log10": np.log10,
    "sqrt": np.sqrt,
    "abs": np.abs,
    "fabs": np.abs,
    "pow": np.power,
    "min": np.minimum,
    "max": np.maximum,
}
_CONSTS = {"pi": math.pi, "PI": math.pi, "M_PI": math.pi, "e": math.e}
_VARS = ("x", "y", "z", "t")


def _compile_expression(text: str, key: str, *, caret_power: bool) -> ast.Expression:
    src = text.strip()
    m = re.fullmatch(r"value\s*=\s*(.*?);?\s*", src, flags=re.S)
    if m:  # Peridigm's RTCompiler form "value = ..."
        src = m.group(1)
    if caret_power:  # Julia (PeriLab): ^ is the power
        src = src.replace("^", "**")
    try:
        tree = ast.parse(src, mode="eval")
    except (RecursionError, MemoryError, ValueError):
        raise SceneError(f"{key}: cannot parse expression of {len(text)} characters") from None
    except SyntaxError as exc:
        raise SceneError(
            f"{key}: cannot parse expression {text!r} ({exc.msg}); expressions use x, y, z, t, "
            f"numbers, + - * / {'^' if caret_power else '**'} and {sorted(_FUNCS)}"
        ) from None
    for node in ast.walk(tree):
        ok = isinstance(
            node,
            ast.Expression
            | ast.BinOp
            | ast.UnaryOp
            | ast.Constant
            | ast.Name
            | ast.Call
            | ast.Load
            | ast.operator
            | ast.unaryop,
        )
        if isinstance(node, ast.BinOp) and type(node.op) not in _BINOPS:
            ok = False
        if isinstance(node, ast.UnaryOp) and type(node.op) not in _UNOPS:
            ok = False
        if isinstance(node, ast.Constant) and (
            isinstance(node.value, bool) or not isinstance(node.value, int | float)
        ):
            ok = False
        if isinstance(node, ast.Name) and node.id not in (*_VARS, *_CONSTS, *_FUNCS):
            raise SceneError(
                f"{key}: unknown name {node.id!r} in expression {text!r}; allowed variables "
                f"{list(_VARS)}, constants {sorted(_CONSTS)}, functions {sorted(_FUNCS)}"
            )
        if isinstance(node, ast.Call):
            if isinstance(node.func, ast.Name) and node.func.id not in _FUNCS:
                raise SceneError(
                    f"{key}: unknown function {node.func.id!r} in expression {text!r}; allowed "
                    f"functions {sorted(_FUNCS)}"
                )
            if not isinstance(node.func, ast.Name) or node.keywords:
                ok = False
        if not ok:
            raise SceneError(
                f"{key}: unsupported construct {type(node).__name__} in expression {text!r}; "
                f"expressions use x, y, z, t, numbers, + - * / and {sorted(_FUNCS)}"
            )
    return tree


def _eval_node(node: ast.AST, env: Mapping[str, Any]) -> Any:
    if isinstance(node, ast.Expression):
        return _eval_node(node.body, env)
    if isinstance(node, ast.Constant):
        return float(node.value)  # type: ignore[arg-type]  # numbers only (checked)
    if isinstance(node, ast.Name):
        if node.id in env:
            return env[node.id]
        return _CONSTS[node.id]
    if isinstance(node, ast.BinOp):
        return _BINOPS[type(node.op)](_eval_node(node.left, env), _eval_node(node.right, env))
    if isinstance(node, ast.UnaryOp):
        return _UNOPS[type(node.op)](_eval_node(node.operand, env))
    assert isinstance(node, ast.Call) and isinstance(node.func, ast.Name)  # checked on compile
    return _FUNCS[node.func.id](*(_eval_node(a, env) for a in node.args))


def deck_expression(
    text: Any, points: Any, t: float, key: str = "Value", *, caret_power: bool = False
) -> np.ndarray:
    """Evaluate a deck ``Value`` expression in ``x, y, z, t`` at every point.

    A whitelisted AST evaluator: numbers, ``x y z t``, ``+ - * / **`` (``^`` with
    ``caret_power``), ``pi`` and the functions ``sin cos tan exp log sqrt abs pow
    ...``; Peridigm's ``value = ...`` form is accepted.  Anything else raises
    :class:`pdlin.errors.SceneError` naming ``key``.

    Parameters
    ----------
    text : str or float
        The expression (a number is returned as a constant).
    points : (m, dim) array_like of float
        Reference coordinates (missing coordinates are 0).
    t : float
        The time.
    key : str
        Key path reported in errors.
    caret_power : bool
        Read ``^`` as the power (PeriLab / Julia expressions).

    Returns
    -------
    (m,) ndarray of float

    Examples
    --------
    >>> import numpy as np
    >>> deck_expression("y*0.005*t", np.array([[0.0, 2.0, 0.0]]), 1.0).tolist()
    [0.01]
    >>> deck_expression("value = 0.1*sin(pi*x)", np.array([[0.5, 0.0, 0.0]]), 0.0).tolist()
    [0.1]
    >>> from pdlin.errors import SceneError
    >>> try:
    ...     deck_expression("__import__('os')", np.zeros((1, 3)), 0.0)
    ... except SceneError as exc:
    ...     print(str(exc).split(" in expression")[0])
    Value: unknown function '__import__'
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    m = pts.shape[0]
    if isinstance(text, bool):
        raise SceneError(f"{key} must be a number or an expression string, got {text!r}")
    if isinstance(text, int | float):
        out = np.full(m, float(text))
    else:
        if not isinstance(text, str):
            raise SceneError(f"{key} must be a number or an expression string, got {text!r}")
        tree = _compile_expression(text, key, caret_power=caret_power)
        env: dict[str, Any] = {
            name: (pts[:, k] if k < pts.shape[1] else np.zeros(m))
            for k, name in enumerate(("x", "y", "z"))
        }
        env["t"] = float(t)
        with np.errstate(all="ignore"):
            try:
                val = _eval_node(tree, env)
            except (TypeError, ValueError, ZeroDivisionError, OverflowError, RecursionError) as exc:
                raise SceneError(f"{key}: cannot evaluate {text!r}: {exc}") from None
        out = np.broadcast_to(np.asarray(val, dtype=float), (m,)).copy()
    if not np.all(np.isfinite(out)):
        k = int(np.flatnonzero(~np.isfinite(out))[0])
        raise SceneError(f"{key}: expression {text!r} is not finite at point {k} (t = {t})")
    return out
