"""BehaviorTree.CPP v4's script language, parsed once and evaluated against botstage's blackboard.

The grammar and the type rules are BT.CPP's (``scripting/operators.hpp``, ``any_types.hpp``):

- statements separated by ``;``; each is an expression; the value of the last is the script's;
- assignment ``:=`` (creates the key), ``=`` (the key must exist), ``+= -= *= /=``;
- ``c ? a : b``; ``&&`` and ``||`` (one level, left to right, both sides evaluated as BT.CPP does);
  chained comparisons ``== != < > <= >=``; ``+ -`` and ``..`` (string concatenation), ``| ^``;
  ``* /`` and ``&``; prefix ``-``, ``~`` and ``!``; parentheses;
- literals: integers (``42``, ``0x1F``), reals (``1.5``, ``2e3``), strings in ``'`` or ``"``,
  ``true``/``false`` (the numbers 1 and 0, as in BT.CPP); names are blackboard keys, ``@name``
  the root blackboard's.

Numbers are compared and computed as doubles; an integer literal stays an integer until arithmetic
touches it. ``+`` joins two strings (BT.CPP before ``..`` existed). Comparing a string with a
number reads the string as a number (a port written in XML is text) and fails if it is not one.
Enums (``ScriptingEnumsRegistry``) are not supported: botstage registers none.

Sizes are bounded by ``botstage.robots.limits`` like botstage's own conditions.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from botstage.robots import limits


class ScriptError(ValueError):
    """A script that does not parse; ``column`` is 1-based within the script's text."""

    def __init__(self, message: str, column: int) -> None:
        super().__init__(message)
        self.message = message
        self.column = column


class ScriptRuntimeError(RuntimeError):
    """A script that failed while running (BT.CPP throws a RuntimeError there)."""


class Env(Protocol):
    """What a script reads and writes: blackboard keys by the names the script uses."""

    def exists(self, name: str) -> bool: ...
    def get(self, name: str) -> Any: ...
    def set(self, name: str, value: Any) -> None: ...


# -- tokens -----------------------------------------------------------------------------------

_TOKEN = re.compile(
    r"""
    (?P<space>[ \t\r\n]+|\\\n)
  | (?P<real>(?:\d+\.\d+(?:[eE][-+]?\d+)?|\d+[eE][-+]?\d+))
  | (?P<hex>0[xX][0-9A-Fa-f]+)
  | (?P<int>\d+)
  | (?P<string>'[^']*'|"[^"]*")
  | (?P<name>@?[^\W\d]\w*)
  | (?P<op>:=|\+=|-=|\*=|/=|==|!=|<=|>=|&&|\|\||\.\.|[-+*/&|^~!<>=?:;()])
    """,
    re.VERBOSE,
)


@dataclass(frozen=True)
class _Token:
    kind: str  # real, hex, int, string, name, op, end
    text: str
    column: int  # 1-based


def _tokens(source: str) -> list[_Token]:
    tokens: list[_Token] = []
    pos = 0
    while pos < len(source):
        match = _TOKEN.match(source, pos)
        if match is None:
            raise ScriptError(f"unexpected character {source[pos]!r}", pos + 1)
        kind = match.lastgroup or ""
        end = match.end()
        suffix = source[end : end + 2]
        if (
            kind in ("real", "hex", "int")
            and suffix[:1]
            and (suffix[0].isalnum() or suffix[0] in "._")
            and suffix != ".."
        ):
            raise ScriptError(f"invalid suffix on number literal {match.group()!r}", end + 1)
        if kind != "space":
            tokens.append(_Token(kind, match.group(), pos + 1))
        pos = end
    tokens.append(_Token("end", "", len(source) + 1))
    return tokens


# -- the tree of a script ---------------------------------------------------------------------

Node = tuple  # ("lit", value) ("name", key) ("unary", op, a) ("binary", op, a, b) ("compare", ops, operands)
#              ("if", c, a, b) ("assign", op, key, value)

_ASSIGN = {":=", "=", "+=", "-=", "*=", "/="}
_INFIX: dict[str, int] = {"||": 3, "&&": 3, "+": 5, "-": 5, "..": 5, "|": 5, "^": 5, "*": 6, "/": 6, "&": 6}
_COMPARE = {"==", "!=", "<", ">", "<=", ">="}
_PREFIX = {"-", "~", "!"}


class _Parser:
    def __init__(self, source: str) -> None:
        self.tokens = _tokens(source)
        self.index = 0
        self.nodes = 0
        self.depth = 0

    @property
    def token(self) -> _Token:
        return self.tokens[self.index]

    def take(self) -> _Token:
        token = self.tokens[self.index]
        self.index += 1
        return token

    def expect(self, text: str) -> None:
        if self.token.text != text or self.token.kind not in ("op",):
            raise ScriptError(f"expected {text!r}, found {self._shown(self.token)}", self.token.column)
        self.take()

    @staticmethod
    def _shown(token: _Token) -> str:
        return "the end of the script" if token.kind == "end" else repr(token.text)

    def _count(self, column: int) -> None:
        self.nodes += 1
        if self.nodes > limits.MAX_CONDITION_NODES:
            raise ScriptError(f"more than {limits.MAX_CONDITION_NODES} parts in one script", column)

    def statements(self) -> list[Node]:
        found: list[Node] = []
        while self.token.kind != "end":
            if self.token.text == ";":
                self.take()
                continue
            found.append(self.statement())
            if self.token.kind != "end":
                self.expect(";")
        return found

    def statement(self) -> Node:
        start = self.token
        left = self.conditional()
        if self.token.kind == "op" and self.token.text in _ASSIGN:
            op = self.take()
            if left[0] != "name":
                raise ScriptError(f"the left of {op.text!r} must be a blackboard key", start.column)
            value = self.conditional()
            self._count(op.column)
            return ("assign", op.text, left[1], value)
        return left

    def conditional(self) -> Node:
        condition = self.expression(0)
        if self.token.kind == "op" and self.token.text == "?":
            self.take()
            then = self.conditional()
            self.expect(":")
            other = self.conditional()
            return ("if", condition, then, other)
        return condition

    def expression(self, floor: int) -> Node:
        self.depth += 1
        if self.depth > limits.MAX_CONDITION_DEPTH:
            raise ScriptError(f"nested more than {limits.MAX_CONDITION_DEPTH} deep", self.token.column)
        left = self.prefix()
        while self.token.kind == "op":
            op = self.token.text
            if op in _COMPARE and floor < 4:
                ops: list[str] = []
                operands = [left]
                while self.token.kind == "op" and self.token.text in _COMPARE:
                    ops.append(self.take().text)
                    operands.append(self.expression(4))
                self._count(self.token.column)
                left = ("compare", tuple(ops), tuple(operands))
                continue
            power = _INFIX.get(op)
            if power is None or power <= floor:
                break
            column = self.take().column
            right = self.expression(power)
            self._count(column)
            left = ("binary", op, left, right)
        self.depth -= 1
        return left

    def prefix(self) -> Node:
        token = self.take()
        self._count(token.column)
        if token.kind == "op" and token.text in _PREFIX:
            return ("unary", token.text, self.prefix())
        if token.kind == "op" and token.text == "(":
            inner = self.conditional()
            self.expect(")")
            return inner
        if token.kind in ("int", "hex"):
            return ("lit", int(token.text, 16 if token.kind == "hex" else 10))
        if token.kind == "real":
            return ("lit", float(token.text))
        if token.kind == "string":
            return ("lit", token.text[1:-1])
        if token.kind == "name":
            if token.text in ("true", "false"):
                return ("lit", 1 if token.text == "true" else 0)
            return ("name", token.text)
        raise ScriptError(f"expected a value, found {self._shown(token)}", token.column)


# -- the compiled script ----------------------------------------------------------------------


@dataclass(frozen=True)
class Script:
    """A parsed script: its source, statements, and the keys it reads and writes (as written,
    ``@key`` included)."""

    source: str
    statements: tuple[Node, ...]
    reads: frozenset[str]
    writes: frozenset[str]

    @property
    def keys(self) -> frozenset[str]:
        return self.reads | self.writes

    def run(self, env: Env) -> Any:
        """Run every statement; the value of the last (None for an empty script)."""
        value = None
        for statement in self.statements:
            value = _evaluate(statement, env)
        return value

    def check(self, env: Env) -> bool:
        """Run as a condition: the value of the last statement as BT.CPP's ``cast<bool>``."""
        return as_bool(self.run(env))


def compile_script(source: str) -> Script:
    """Parse ``source``; raises ScriptError with the column of the mistake."""
    if len(source) > limits.MAX_CONDITION_CHARS:
        raise ScriptError(f"longer than {limits.MAX_CONDITION_CHARS:,} characters", 1)
    statements = tuple(_Parser(source).statements())
    reads: set[str] = set()
    writes: set[str] = set()
    for statement in statements:
        _keys(statement, reads, writes)
    return Script(source, statements, frozenset(reads), frozenset(writes))


def _keys(node: Node, reads: set[str], writes: set[str]) -> None:
    tag = node[0]
    if tag == "name":
        reads.add(node[1])
    elif tag == "assign":
        writes.add(node[2])
        if node[1] not in (":=", "="):
            reads.add(node[2])
        _keys(node[3], reads, writes)
    elif tag == "compare":
        for operand in node[2]:
            _keys(operand, reads, writes)
    else:
        for part in node[1:]:
            if isinstance(part, tuple):
                _keys(part, reads, writes)


# -- evaluation -------------------------------------------------------------------------------


def is_number(value: Any) -> bool:
    return isinstance(value, int | float)


def as_bool(value: Any) -> bool:
    """BT.CPP's ``Any::cast<bool>``: a number is true unless 0; a string must read as a boolean."""
    if is_number(value):
        return value != 0
    if isinstance(value, str):
        lowered = value.strip().lower()
        if lowered in ("true", "1"):
            return True
        if lowered in ("false", "0"):
            return False
        raise ScriptRuntimeError(f"cannot read {value!r} as a boolean")
    raise ScriptRuntimeError(f"cannot read a {type(value).__name__} as a boolean")


def as_text(value: Any) -> str:
    """A value as BT.CPP's ``toStr`` writes it: whole doubles without ``.0``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
        return str(int(value))
    return str(value)


def _number(value: Any, side: str, op: str) -> float:
    if value is None:
        raise ScriptRuntimeError(f"the {side} operand of [{op}] is not initialized")
    if is_number(value):
        return float(value)
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            pass
    raise ScriptRuntimeError(f"[{op}] needs numbers, the {side} operand is {value!r}")


def _integer(value: float, op: str) -> int:
    if not value.is_integer():
        raise ScriptRuntimeError(f"binary operator [{op}] is not allowed if one of the operands is not an integer")
    return int(value)


def _text_length(text: str) -> str:
    if len(text) > limits.MAX_SEQUENCE_LENGTH:
        raise ScriptRuntimeError(f"a string of {len(text):,} characters (at most {limits.MAX_SEQUENCE_LENGTH:,})")
    return text


_ARITHMETIC: dict[str, Callable[[float, float], float]] = {
    "+": lambda a, b: a + b,
    "-": lambda a, b: a - b,
    "*": lambda a, b: a * b,
    "/": lambda a, b: a / b if b else (math.copysign(math.inf, a) * math.copysign(1, b) if a else math.nan),
}
_BITWISE: dict[str, Callable[[int, int], int]] = {
    "&": lambda a, b: a & b,
    "|": lambda a, b: a | b,
    "^": lambda a, b: a ^ b,
}
_ORDER: dict[str, Callable[[Any, Any], bool]] = {
    "<": lambda a, b: a < b,
    ">": lambda a, b: a > b,
    "<=": lambda a, b: a <= b,
    ">=": lambda a, b: a >= b,
}
_EPSILON = 1.1920928955078125e-07  # std::numeric_limits<float>::epsilon(), BT.CPP's IsSame for doubles


def _binary(op: str, left: Any, right: Any) -> Any:
    if left is None or right is None:
        raise ScriptRuntimeError(f"the {'left' if left is None else 'right'} operand of [{op}] is not initialized")
    if op == "..":
        return _text_length(as_text(left) + as_text(right))
    if isinstance(left, str) and isinstance(right, str) and op == "+":
        return _text_length(left + right)
    if not (is_number(left) and is_number(right)):
        raise ScriptRuntimeError(f"operation [{op}] not permitted between {left!r} and {right!r}")
    a, b = float(left), float(right)
    if op in _ARITHMETIC:
        return _ARITHMETIC[op](a, b)
    if op in _BITWISE:
        return float(_BITWISE[op](_integer(a, op), _integer(b, op)))
    return float(a != 0 and b != 0) if op == "&&" else float(a != 0 or b != 0)


def _compare(op: str, left: Any, right: Any) -> bool:
    if left is None or right is None:
        raise ScriptRuntimeError(f"the {'left' if left is None else 'right'} operand of [{op}] is not initialized")
    if isinstance(left, str) and isinstance(right, str):
        a: Any = left
        b: Any = right
        if op in ("==", "!="):
            return (a == b) == (op == "==")
    else:
        if isinstance(left, str) or isinstance(right, str):
            a, b = _number(left, "left", op), _number(right, "right", op)
        elif is_number(left) and is_number(right):
            a, b = float(left), float(right)
        else:
            raise ScriptRuntimeError(f"can't mix different types in comparison: {left!r} {op} {right!r}")
        if op in ("==", "!="):
            return (abs(a - b) <= _EPSILON) == (op == "==")
    return _ORDER[op](a, b)


def _evaluate(node: Node, env: Env) -> Any:
    tag = node[0]
    if tag == "lit":
        return node[1]
    if tag == "name":
        if not env.exists(node[1]):
            raise ScriptRuntimeError(f"variable not found: {node[1]}")
        return env.get(node[1])
    if tag == "unary":
        value = _evaluate(node[2], env)
        if isinstance(value, str) or not is_number(value):
            raise ScriptRuntimeError(f"invalid operator [{node[1]}] for {value!r}")
        if node[1] == "-":
            return -float(value)
        if node[1] == "~":
            return float(~int(value))
        return float(not value)
    if tag == "binary":
        return _binary(node[1], _evaluate(node[2], env), _evaluate(node[3], env))
    if tag == "compare":
        ops, operands = node[1], node[2]
        left = _evaluate(operands[0], env)
        for op, operand in zip(ops, operands[1:], strict=True):
            right = _evaluate(operand, env)
            if not _compare(op, left, right):
                return 0.0
            left = right
        return 1.0
    if tag == "if":
        condition = _evaluate(node[1], env)
        chosen = (isinstance(condition, str) and condition != "") or (is_number(condition) and condition != 0)
        return _evaluate(node[2] if chosen else node[3], env)
    return _assign(node[1], node[2], _evaluate(node[3], env) if node[1] in (":=", "=") else node[3], env)


def _assign(op: str, key: str, value: Any, env: Env) -> Any:
    exists = env.exists(key)
    if not exists and op != ":=":
        raise ScriptRuntimeError(
            f"the blackboard entry [{key}] doesn't exist yet: use [:=] instead of [=] to create it"
        )
    if op in (":=", "="):
        if value is None:
            raise ScriptRuntimeError(f"the right operand of [{op}] is not initialized")
        result = _converted(env.get(key), value, key) if exists else value
        env.set(key, result)
        return result
    value = _evaluate(value, env)  # BT.CPP reads the right side after checking the entry
    current = env.get(key)
    if current is None:
        raise ScriptRuntimeError(f"the left operand of [{op}] is not initialized")
    if is_number(value):
        if not is_number(current) or isinstance(current, str):
            raise ScriptRuntimeError(f"[{op}] can't be used with the non-numeric {key} ({current!r})")
        result: Any = _ARITHMETIC[op[0]](float(current), float(value))
    elif isinstance(value, str) and op == "+=":
        result = _text_length(as_text(current) + value)
    else:
        raise ScriptRuntimeError(f"operator [{op}] not supported for strings")
    result = _converted(current, result, key)
    env.set(key, result)
    return result


def _converted(current: Any, value: Any, key: str) -> Any:
    """A value written to an entry that already holds one keeps the entry's type (BT.CPP's
    ``copyInto``): a whole double into an integer, a string read as a number, ..."""
    if current is None:
        return value
    if isinstance(current, bool):
        if is_number(value) and value in (0, 1):
            return bool(value)
        if isinstance(value, str):
            return as_bool(value)
    elif isinstance(current, int):
        if is_number(value) and float(value).is_integer():
            return int(value)
        if isinstance(value, str):
            try:
                return int(value.strip())
            except ValueError:
                pass
    elif isinstance(current, float):
        if is_number(value):
            return float(value)
        if isinstance(value, str):
            try:
                return float(value)
            except ValueError:
                pass
    elif isinstance(current, str):
        if isinstance(value, str):
            return value
        raise ScriptRuntimeError(f"entry [{key}] holds a string: cannot assign the number {as_text(value)} to it")
    else:
        return value
    raise ScriptRuntimeError(f"entry [{key}] holds {current!r}: {value!r} can't be converted to its type")
