"""A small, safe expression language for conditions over blackboard values.

``battery_pct < 20 and not estop``, ``robot.mode == 'docking'``, ``len(people) >= 2``.
Expressions are parsed with Python's ``ast`` and interpreted from a whitelist of node types:
no ``eval``, no attribute access on objects, no calls except a few pure functions.
A dotted name ``robot.mode`` is the namespaced key ``robot/mode``.
"""

from __future__ import annotations

import ast
import operator
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

Lookup = Callable[[str], Any]
Evaluator = Callable[[Lookup], Any]

_CONSTANTS = {"true": True, "false": False, "null": None, "none": None, "True": True, "False": False, "None": None}
_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "abs": abs,
    "min": min,
    "max": max,
    "len": len,
    "round": round,
    "int": int,
    "float": float,
    "str": str,
    "bool": bool,
}
_BINARY = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.FloorDiv: operator.floordiv,
    ast.Mod: operator.mod,
}
_COMPARE = {
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.In: lambda a, b: a in b,
    ast.NotIn: lambda a, b: a not in b,
}


class ExpressionError(ValueError):
    """A malformed expression; ``column`` is 0-based within the expression text."""

    def __init__(self, message: str, source: str, column: int = 0) -> None:
        super().__init__(message)
        self.message = message
        self.source = source
        self.column = column

    def __str__(self) -> str:
        return f"{self.message} in {self.source!r} (column {self.column + 1})"


class EvaluationError(RuntimeError):
    """An expression that is well formed but cannot be evaluated on the current values."""


class _LookupFailed(Exception):
    def __init__(self, error: Exception) -> None:
        self.error = error


@dataclass(frozen=True, slots=True)
class Expression:
    source: str
    keys: frozenset[str]
    _evaluate: Evaluator

    def evaluate(self, lookup: Lookup) -> Any:
        """The value on the current blackboard.

        Errors of ``lookup`` (a key nobody wrote, no access) pass through as they are; any
        other error (``people[0]`` of an empty list, comparing a str with a number) becomes an
        ``EvaluationError`` naming the expression.
        """

        def guarded(key: str) -> Any:
            try:
                return lookup(key)
            except Exception as exc:
                raise _LookupFailed(exc) from exc

        try:
            return self._evaluate(guarded)
        except _LookupFailed as failed:
            raise failed.error from None
        except Exception as exc:
            raise EvaluationError(f"{self.source!r}: {type(exc).__name__}: {exc}") from None

    def test(self, lookup: Lookup) -> bool:
        return bool(self.evaluate(lookup))


def key_of(node: ast.expr) -> str | None:
    """The blackboard key a Name or dotted Attribute chain stands for, or None."""
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
        return "/".join(reversed(parts))
    return None


class _Compiler:
    def __init__(self, source: str) -> None:
        self.source = source
        self.keys: set[str] = set()

    def fail(self, node: ast.AST, message: str) -> ExpressionError:
        return ExpressionError(message, self.source, getattr(node, "col_offset", 0))

    def compile(self, node: ast.expr) -> Evaluator:
        if isinstance(node, ast.Constant):
            value = node.value
            if not isinstance(value, int | float | str | bool | type(None)):
                raise self.fail(node, f"unsupported literal {value!r}")
            return lambda _lookup: value
        if isinstance(node, ast.Name | ast.Attribute):
            key = key_of(node)
            if key is None:
                raise self.fail(node, "attributes are only allowed in namespaced keys like robot.mode")
            if key in _CONSTANTS:
                constant = _CONSTANTS[key]
                return lambda _lookup: constant
            self.keys.add(key)
            return lambda lookup: lookup(key)
        if isinstance(node, ast.BoolOp):
            parts = [self.compile(v) for v in node.values]
            if isinstance(node.op, ast.And):
                return lambda lookup: all(p(lookup) for p in parts)
            return lambda lookup: any(p(lookup) for p in parts)
        if isinstance(node, ast.UnaryOp):
            operand = self.compile(node.operand)
            if isinstance(node.op, ast.Not):
                return lambda lookup: not operand(lookup)
            if isinstance(node.op, ast.USub):
                return lambda lookup: -operand(lookup)
            if isinstance(node.op, ast.UAdd):
                return operand
            raise self.fail(node, "unsupported unary operator")
        if isinstance(node, ast.BinOp):
            op = _BINARY.get(type(node.op))
            if op is None:
                raise self.fail(node, "unsupported operator")
            left, right = self.compile(node.left), self.compile(node.right)
            return lambda lookup: op(left(lookup), right(lookup))
        if isinstance(node, ast.Compare):
            first = self.compile(node.left)
            ops = []
            for op_node, comparator in zip(node.ops, node.comparators, strict=True):
                fn = _COMPARE.get(type(op_node))
                if fn is None:
                    raise self.fail(node, "unsupported comparison (use ==, !=, <, <=, >, >=, in, not in)")
                ops.append((fn, self.compile(comparator)))

            def compare(lookup: Lookup) -> bool:
                left = first(lookup)
                for fn, right_eval in ops:
                    right = right_eval(lookup)
                    if not fn(left, right):
                        return False
                    left = right
                return True

            return compare
        if isinstance(node, ast.List | ast.Tuple | ast.Set):
            items = [self.compile(e) for e in node.elts]
            return lambda lookup: tuple(i(lookup) for i in items)
        if isinstance(node, ast.Subscript):
            target = self.compile(node.value)
            index = self.compile(node.slice)
            return lambda lookup: target(lookup)[index(lookup)]
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in _FUNCTIONS or node.keywords:
                allowed = ", ".join(sorted(_FUNCTIONS))
                raise self.fail(node, f"only these functions can be called: {allowed}")
            fn = _FUNCTIONS[node.func.id]
            args = [self.compile(a) for a in node.args]
            return lambda lookup: fn(*(a(lookup) for a in args))
        if isinstance(node, ast.IfExp):
            test, body, orelse = self.compile(node.test), self.compile(node.body), self.compile(node.orelse)
            return lambda lookup: body(lookup) if test(lookup) else orelse(lookup)
        raise self.fail(node, f"'{type(node).__name__}' is not allowed in a condition")


@lru_cache(maxsize=1024)
def compile_expression(source: str) -> Expression:
    """Parse ``source`` once; raises ``ExpressionError`` with the column of the problem."""
    if not isinstance(source, str) or not source.strip():
        raise ExpressionError("empty condition", str(source))
    text = source.strip()
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(f"syntax error: {exc.msg}", text, max((exc.offset or 1) - 1, 0)) from None
    compiler = _Compiler(text)
    evaluate = compiler.compile(tree.body)
    return Expression(text, frozenset(compiler.keys), evaluate)
