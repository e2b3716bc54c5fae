"""A small, safe expression language for conditions over blackboard values.

``battery_pct < 20 and not estop``, ``robot.mode == 'docking'``, ``len(people) >= 2``.
Expressions are parsed with Python's ``ast`` and interpreted from a whitelist of node types:
no ``eval``, no attribute access on objects, no calls except a few pure functions.
A dotted name ``robot.mode`` is the namespaced key ``robot/mode``.

Conditions come from mission files, so their size is bounded (``botstage.robots.limits``): their length,
nesting and number of parts before anything is compiled, and at evaluation the lists and strings
they build (``x * 1000000000``), the integers they multiply and the digits they round to.
"""

from __future__ import annotations

import ast
import operator
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from botstage.robots import limits

Lookup = Callable[[str], Any]
Evaluator = Callable[[Lookup], Any]

_CONSTANTS = {"true": True, "false": False, "null": None, "none": None, "True": True, "False": False, "None": None}


class _TooLarge(ValueError):
    """A value a condition would build beyond the limits: refused before it is built."""


_SEQUENCES = (str, bytes, list, tuple)


def _length(length: int) -> None:
    if length > limits.MAX_SEQUENCE_LENGTH:
        raise _TooLarge(f"it would build a list or string of {length:,} items (at most {limits.MAX_SEQUENCE_LENGTH:,})")


def _mul(a: Any, b: Any) -> Any:
    """``*``, refusing repetitions and integers too large to build."""
    if isinstance(a, int) and isinstance(b, int):
        if a.bit_length() + b.bit_length() > limits.MAX_INT_BITS:
            raise _TooLarge(f"it would build an integer of more than {limits.MAX_INT_BITS:,} bits")
    elif isinstance(a, _SEQUENCES) and isinstance(b, int):
        _length(len(a) * b)
    elif isinstance(b, _SEQUENCES) and isinstance(a, int):
        _length(len(b) * a)
    return a * b


def _add(a: Any, b: Any) -> Any:
    if isinstance(a, _SEQUENCES) and isinstance(b, _SEQUENCES):
        _length(len(a) + len(b))
    return a + b


def _mod(a: Any, b: Any) -> Any:
    if isinstance(a, str | bytes):
        raise TypeError("'%' formatting of strings is not supported in conditions")
    return a % b


def _round(number: Any, ndigits: Any = None) -> Any:
    if isinstance(ndigits, int) and abs(ndigits) > 1000:
        raise _TooLarge(f"round to {ndigits} digits (at most 1000 either way)")
    return round(number, ndigits)


_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "abs": abs,
    "min": min,
    "max": max,
    "len": len,
    "round": _round,
    "int": int,
    "float": float,
    "str": str,
    "bool": bool,
}
_BINARY = {
    ast.Add: _add,
    ast.Sub: operator.sub,
    ast.Mult: _mul,
    ast.Div: operator.truediv,
    ast.FloorDiv: operator.floordiv,
    ast.Mod: _mod,
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
        shown = self.source if len(self.source) <= 80 else self.source[:60] + "..."
        return f"{self.message} in {shown!r} (column {self.column + 1})"


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
        except _TooLarge as exc:
            raise EvaluationError(f"{self.source!r}: {exc}") from None
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


def _check_size(body: ast.expr, text: str) -> None:
    """Refuse a condition too deep or too large before compiling it (compiling recurses)."""
    count = 0
    pending = [(body, 1)]
    while pending:
        node, depth = pending.pop()
        count += 1
        if depth > limits.MAX_CONDITION_DEPTH:
            message = f"nested more than {limits.MAX_CONDITION_DEPTH} levels deep"
            raise ExpressionError(message, text, getattr(node, "col_offset", 0))
        if count > limits.MAX_CONDITION_NODES:
            message = f"more than {limits.MAX_CONDITION_NODES} names, values and operators"
            raise ExpressionError(message, text, getattr(node, "col_offset", 0))
        pending.extend((child, depth + 1) for child in ast.iter_child_nodes(node) if isinstance(child, ast.expr))


@lru_cache(maxsize=1024)
def compile_expression(source: str) -> Expression:
    """Parse ``source`` once; raises ``ExpressionError`` with the column of the problem."""
    if not isinstance(source, str) or not source.strip():
        raise ExpressionError("empty condition", str(source))
    text = source.strip()
    if len(text) > limits.MAX_CONDITION_CHARS:
        raise ExpressionError(
            f"a condition has at most {limits.MAX_CONDITION_CHARS:,} characters, this one {len(text):,}", text
        )
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(f"syntax error: {exc.msg}", text, max((exc.offset or 1) - 1, 0)) from None
    except (RecursionError, MemoryError):  # Python's own parser gives up on deep nesting
        raise ExpressionError(f"nested more than {limits.MAX_CONDITION_DEPTH} levels deep", text) from None
    _check_size(tree.body, text)
    compiler = _Compiler(text)
    evaluate = compiler.compile(tree.body)
    return Expression(text, frozenset(compiler.keys), evaluate)
