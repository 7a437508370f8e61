"""The safe evaluator of ``${...}`` expressions. Never ``eval``.

An expression is parsed with :mod:`ast` and walked over a whitelist of node
types: numbers, strings, booleans, quantity literals (``180 deg``,
``2000 N*s/m``), names of parameters, attribute access on the namespaces
``params``, ``scene``, ``suture``, ``tissue``, arithmetic, comparisons,
``and``/``or``/``not``, ``x if c else y`` and the functions ``min``, ``max``,
``abs``, ``sqrt``, ``sin``, ``cos``, ``tan``, ``atan2``, ``radians``,
``degrees``. Everything else (calls of other names, subscripts, lambdas,
comprehensions, dunder attributes) is rejected before anything is evaluated.
Quantities keep their dimension through arithmetic, so ``3 N + 2 mm`` is an
error.

Examples: ``${mirror and -180 deg or 180 deg}``,
``${0.8 * suture.knot_pull_strength}``.
"""

from __future__ import annotations

import ast
import functools
import math
import operator
import re
import warnings
from collections.abc import Callable, Mapping
from typing import Any

from suture_engine.errors import SutureError
from suture_engine.language.units import (
    Dimension,
    Quantity,
    UnitError,
    dimension_name,
    parse_unit,
)

__all__ = ["ExpressionError", "Namespace", "evaluate", "find_expression", "is_expression"]

MAX_EXPRESSION_CHARS = 500
"""Longest expression accepted [characters]."""

_EXPR_RE = re.compile(r"^\s*\$\{(.*)\}\s*$", re.DOTALL)
_QLIT_RE = re.compile(
    r"(?<![\w.])((?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*"
    r"([A-Za-zµ]+(?:(?:\^|\*\*)-?\d+)?(?:[*/][A-Za-zµ]+(?:(?:\^|\*\*)-?\d+)?)*)"
)
_KEYWORDS = {"and", "or", "not", "if", "else", "in", "is", "True", "False", "None"}
_DIMLESS: Dimension = (0, 0, 0, 0)


class ExpressionError(SutureError):
    """An expression that cannot be parsed or evaluated.

    Attributes:
        expression: the expression text (without ``${}``).
    """

    code = "bad-expression"

    def __init__(self, message: str, expression: str) -> None:
        super().__init__(f"{message} in ${{{expression}}}")
        self.expression = expression


class Namespace:
    """Read-only attribute access over a mapping (``scene.tension_limit``)."""

    def __init__(self, name: str, values: Mapping[str, Any]) -> None:
        self._name = name
        self._values = dict(values)

    def get(self, attr: str, expression: str) -> Any:
        """The value of ``attr``.

        Raises:
            ExpressionError: no such attribute.
        """
        if attr not in self._values:
            known = ", ".join(sorted(self._values)) or "none"
            raise ExpressionError(f"{self._name} has no {attr!r} (known: {known})", expression)
        return self._values[attr]


def is_expression(value: Any) -> bool:
    """True if ``value`` is a string of the form ``${...}``."""
    return isinstance(value, str) and _EXPR_RE.match(value) is not None


def find_expression(value: str) -> str | None:
    """The text inside ``${...}``, or None."""
    match = _EXPR_RE.match(value)
    return match.group(1) if match else None


def _dim(x: Any) -> Dimension:
    return x.dim if isinstance(x, Quantity) else _DIMLESS


def _val(x: Any, expr: str) -> float:
    if isinstance(x, Quantity):
        return x.value
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ExpressionError(f"expected a number, found {type(x).__name__} {x!r}", expr)
    try:
        return float(x)
    except OverflowError:  # an integer literal beyond the float range
        raise ExpressionError("numeric overflow", expr) from None


def _wrap(value: float, dim: Dimension) -> Any:
    return value if dim == _DIMLESS else Quantity(value, dim)


def _same_dim(a: Any, b: Any, op: str, expr: str) -> Dimension:
    da, db = _dim(a), _dim(b)
    if da != db:
        raise ExpressionError(f"cannot {op} {dimension_name(da)} and {dimension_name(db)}", expr)
    return da


def _arith(op: ast.operator, a: Any, b: Any, expr: str) -> Any:
    if isinstance(a, str) and isinstance(b, str) and isinstance(op, ast.Add):
        if len(a) + len(b) > 10_000:
            raise ExpressionError("string too long", expr)
        return a + b
    x, y = _val(a, expr), _val(b, expr)
    try:
        if isinstance(op, (ast.Add, ast.Sub)):
            dim = _same_dim(a, b, "add" if isinstance(op, ast.Add) else "subtract", expr)
            return _wrap(x + y if isinstance(op, ast.Add) else x - y, dim)
        if isinstance(op, ast.Mult):
            da, db = _dim(a), _dim(b)
            return _wrap(x * y, (da[0] + db[0], da[1] + db[1], da[2] + db[2], da[3] + db[3]))
        if isinstance(op, ast.Div):
            da, db = _dim(a), _dim(b)
            return _wrap(x / y, (da[0] - db[0], da[1] - db[1], da[2] - db[2], da[3] - db[3]))
        if isinstance(op, ast.Mod):
            return _wrap(math.fmod(x, y), _same_dim(a, b, "take the remainder of", expr))
        if isinstance(op, ast.Pow):
            if _dim(b) != _DIMLESS or (_dim(a) != _DIMLESS and y != int(y)):
                raise ExpressionError(
                    "a power must be a plain (integer for quantities) number", expr
                )
            if abs(y) > 100:
                raise ExpressionError("exponent too large", expr)
            da = _dim(a)
            n = int(y) if _dim(a) != _DIMLESS else 0
            power = x**y
            if isinstance(power, complex):
                raise ExpressionError("a negative number to a fractional power", expr)
            return _wrap(power, (da[0] * n, da[1] * n, da[2] * n, da[3] * n))
    except ZeroDivisionError:
        raise ExpressionError("division by zero", expr) from None
    except OverflowError:
        raise ExpressionError("numeric overflow", expr) from None
    except ValueError as exc:  # math.fmod(x, 0)
        raise ExpressionError(f"invalid operation ({exc})", expr) from None
    raise ExpressionError(f"operator {type(op).__name__} is not allowed", expr)


_COMPARE: dict[type[ast.cmpop], Callable[[Any, Any], bool]] = {
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
}


def _fn1(f: Callable[[float], float], dim_in: Dimension | None) -> Callable[..., Any]:
    def call(expr: str, *args: Any) -> Any:
        if len(args) != 1:
            raise ExpressionError("expected one argument", expr)
        (a,) = args
        if dim_in is not None and _dim(a) not in (dim_in, _DIMLESS):
            raise ExpressionError(f"expected an angle, found {dimension_name(_dim(a))}", expr)
        try:
            return f(_val(a, expr))
        except (ValueError, OverflowError) as exc:
            raise ExpressionError(str(exc), expr) from None

    return call


def _minmax(pick: Callable[..., Any]) -> Callable[..., Any]:
    def call(expr: str, *args: Any) -> Any:
        if not args:
            raise ExpressionError("expected at least one argument", expr)
        for a in args[1:]:
            _same_dim(args[0], a, "compare", expr)
        return pick(args, key=lambda v: _val(v, expr))

    return call


def _abs(expr: str, *args: Any) -> Any:
    if len(args) != 1:
        raise ExpressionError("expected one argument", expr)
    return _wrap(abs(_val(args[0], expr)), _dim(args[0]))


def _sqrt(expr: str, *args: Any) -> Any:
    if len(args) != 1:
        raise ExpressionError("expected one argument", expr)
    d, v = _dim(args[0]), _val(args[0], expr)
    if any(e % 2 for e in d) or v < 0:
        raise ExpressionError("sqrt needs a non-negative value of even dimension", expr)
    return _wrap(math.sqrt(v), (d[0] // 2, d[1] // 2, d[2] // 2, d[3] // 2))


def _atan2(expr: str, *args: Any) -> Any:
    if len(args) != 2:
        raise ExpressionError("expected two arguments", expr)
    _same_dim(args[0], args[1], "compare", expr)
    return Quantity(math.atan2(_val(args[0], expr), _val(args[1], expr)), (0, 0, 0, 1))


_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "min": _minmax(min),
    "max": _minmax(max),
    "abs": _abs,
    "sqrt": _sqrt,
    "sin": _fn1(math.sin, (0, 0, 0, 1)),
    "cos": _fn1(math.cos, (0, 0, 0, 1)),
    "tan": _fn1(math.tan, (0, 0, 0, 1)),
    "atan2": _atan2,
    "radians": lambda expr, *a: (
        Quantity(math.radians(_val(a[0], expr)), (0, 0, 0, 1))
        if len(a) == 1
        else _fn1(float, None)(expr, *a)
    ),
    "degrees": lambda expr, *a: (
        math.degrees(_val(a[0], expr)) if len(a) == 1 else _fn1(float, None)(expr, *a)
    ),
}


def _substitute_quantities(text: str) -> tuple[str, dict[str, Quantity]]:
    literals: dict[str, Quantity] = {}

    def repl(match: re.Match[str]) -> str:
        unit = match.group(2)
        candidates = [unit]
        first = re.match(r"[A-Za-zµ]+", unit)
        if first is not None and first.group(0) != unit:
            candidates.append(first.group(0))
        for cand in candidates:
            if cand in _KEYWORDS:
                continue
            try:
                factor, dim = parse_unit(cand)
            except UnitError:
                continue
            name = f"_q{len(literals)}"
            literals[name] = Quantity(float(match.group(1)) * factor, dim)
            return f" {name} " + unit[len(cand) :]
        return match.group(0)

    return _QLIT_RE.sub(repl, text), literals


def evaluate(expression: str, names: Mapping[str, Any]) -> Any:
    """Evaluate an expression safely.

    Args:
        expression: the text inside ``${...}``.
        names: the top-level names: parameter values, and :class:`Namespace`
            objects for ``params``, ``scene``, ``suture``, ``tissue``.

    Returns:
        A bool, number, string, :class:`~suture_engine.language.units.Quantity` or None.

    Raises:
        ExpressionError: a syntax error, a forbidden construct, an unknown name,
            a dimension mismatch.
    """
    if len(expression) > MAX_EXPRESSION_CHARS:
        raise ExpressionError(f"longer than {MAX_EXPRESSION_CHARS} characters", expression[:40])
    try:
        tree, literals = _compiled(expression)
        scope = {**names}
        scope.update(literals)
        value = _Evaluator(expression, scope).visit(tree.body)
    except RecursionError:
        raise ExpressionError("expression nested too deeply", expression) from None
    if value is not None and not isinstance(value, bool | int | float | str | Quantity):
        raise ExpressionError(
            f"the result is a {type(value).__name__}, not a value (a namespace needs an "
            "attribute: params.NAME)",
            expression,
        )
    if isinstance(value, int) and not isinstance(value, bool):
        _val(value, expression)  # an integer beyond the float range: numeric overflow
    if isinstance(value, float) and not math.isfinite(value):
        raise ExpressionError(f"the result is not a finite number ({value})", expression)
    if isinstance(value, Quantity) and not math.isfinite(value.value):
        raise ExpressionError(f"the result is not a finite number ({value.value})", expression)
    return value


@functools.lru_cache(maxsize=4096)
def _compiled(expression: str) -> tuple[ast.Expression, tuple[tuple[str, Quantity], ...]]:
    """The expression's checked syntax tree and its unit literals, once per text.

    A procedure's expressions repeat: every ``use:`` of a sub-procedure and every
    validation pass evaluates the same texts again. The tree is only read afterwards.
    Errors are not cached (each call raises anew).
    """
    text, literals = _substitute_quantities(expression)
    try:
        with warnings.catch_warnings():  # "invalid decimal literal" and the like: not ours
            warnings.simplefilter("ignore", SyntaxWarning)
            tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, MemoryError) as exc:
        raise ExpressionError(f"syntax error: {getattr(exc, 'msg', exc)}", expression) from None
    _check_static(tree, text.strip(), expression)
    return tree, tuple(literals.items())


_ALLOWED_NODES: tuple[type[ast.AST], ...] = (
    ast.Expression, ast.Constant, ast.Name, ast.Load, ast.Attribute, ast.UnaryOp, ast.BinOp,
    ast.BoolOp, ast.Compare, ast.IfExp, ast.Call, ast.operator, ast.unaryop, ast.boolop,
    ast.cmpop,
)  # fmt: skip


def _check_static(tree: ast.AST, text: str, expr: str) -> None:
    """Reject forbidden constructs anywhere in the tree, before anything is evaluated
    (also in the branch of ``x if c else y`` that would not be taken)."""
    for node in ast.walk(tree):
        if not isinstance(node, _ALLOWED_NODES):
            raise ExpressionError(f"{type(node).__name__} is not allowed", expr)
        if isinstance(node, ast.Name | ast.Attribute):
            name = node.id if isinstance(node, ast.Name) else node.attr
            if name.startswith("_") and not (isinstance(node, ast.Name) and name.startswith("_q")):
                raise ExpressionError(f"name {name!r} is not allowed", expr)
            if not name.isascii() or not _written_as(node, name, text):
                raise ExpressionError(
                    f"identifier {name!r} is written with look-alike (non-ASCII) characters",
                    expr,
                )
        if isinstance(node, ast.Call) and (
            not isinstance(node.func, ast.Name) or node.func.id not in _FUNCTIONS
        ):
            allowed = ", ".join(sorted(_FUNCTIONS))
            raise ExpressionError(f"only these functions may be called: {allowed}", expr)


def _written_as(node: ast.Name | ast.Attribute, name: str, text: str) -> bool:
    """True if the source spells ``name`` as parsed (Python folds look-alike letters, NFKC)."""
    segment = ast.get_source_segment(text, node)
    if segment is None:
        return False
    return segment.endswith(name) if isinstance(node, ast.Attribute) else segment == name


class _Evaluator:
    def __init__(self, expr: str, scope: Mapping[str, Any]) -> None:
        self.expr = expr
        self.scope = scope

    def visit(self, node: ast.AST) -> Any:
        method = getattr(self, f"visit_{type(node).__name__}", None)
        if method is None:
            raise ExpressionError(f"{type(node).__name__} is not allowed", self.expr)
        return method(node)

    def visit_Constant(self, node: ast.Constant) -> Any:
        if isinstance(node.value, (bool, int, float, str)) or node.value is None:
            return node.value
        raise ExpressionError(f"constant {node.value!r} is not allowed", self.expr)

    def visit_Name(self, node: ast.Name) -> Any:
        if node.id not in self.scope or node.id.startswith("__"):
            known = ", ".join(sorted(k for k in self.scope if not k.startswith("_q")))
            raise ExpressionError(f"unknown name {node.id!r} (known: {known})", self.expr)
        return self.scope[node.id]

    def visit_Attribute(self, node: ast.Attribute) -> Any:
        base = self.visit(node.value)
        if not isinstance(base, Namespace) or node.attr.startswith("_"):
            raise ExpressionError(f"attribute {node.attr!r} is not allowed here", self.expr)
        return base.get(node.attr, self.expr)

    def visit_UnaryOp(self, node: ast.UnaryOp) -> Any:
        value = self.visit(node.operand)
        if isinstance(node.op, ast.Not):
            return not value
        if isinstance(node.op, (ast.USub, ast.UAdd)):
            sign = -1.0 if isinstance(node.op, ast.USub) else 1.0
            if isinstance(value, Quantity):
                return Quantity(sign * value.value, value.dim)
            v = _val(value, self.expr)
            return -value if sign < 0 and isinstance(value, int) else (v if sign > 0 else -v)
        raise ExpressionError(f"operator {type(node.op).__name__} is not allowed", self.expr)

    def visit_BinOp(self, node: ast.BinOp) -> Any:
        return _arith(node.op, self.visit(node.left), self.visit(node.right), self.expr)

    def visit_BoolOp(self, node: ast.BoolOp) -> Any:
        value: Any = None
        for operand in node.values:
            value = self.visit(operand)
            if isinstance(node.op, ast.And) and not value:
                return value
            if isinstance(node.op, ast.Or) and value:
                return value
        return value

    def visit_Compare(self, node: ast.Compare) -> Any:
        left = self.visit(node.left)
        for op, comp in zip(node.ops, node.comparators, strict=True):
            right = self.visit(comp)
            fn = _COMPARE.get(type(op))
            if fn is None:
                raise ExpressionError(f"comparison {type(op).__name__} is not allowed", self.expr)
            if isinstance(left, str) or isinstance(right, str):
                if type(op) not in (ast.Eq, ast.NotEq):
                    raise ExpressionError("strings compare only with == and !=", self.expr)
                ok = fn(left, right)
            else:
                _same_dim(left, right, "compare", self.expr)
                ok = fn(_val(left, self.expr), _val(right, self.expr))
            if not ok:
                return False
            left = right
        return True

    def visit_IfExp(self, node: ast.IfExp) -> Any:
        return self.visit(node.body) if self.visit(node.test) else self.visit(node.orelse)

    def visit_Call(self, node: ast.Call) -> Any:
        if not isinstance(node.func, ast.Name) or node.func.id not in _FUNCTIONS:
            allowed = ", ".join(sorted(_FUNCTIONS))
            raise ExpressionError(f"only these functions may be called: {allowed}", self.expr)
        if node.keywords:
            raise ExpressionError("keyword arguments are not allowed", self.expr)
        args = [self.visit(a) for a in node.args]
        return _FUNCTIONS[node.func.id](self.expr, *args)
