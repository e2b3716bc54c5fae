"""An upload's ``metadata`` field: a small JSON object, read with bounds.

Python's JSON parser recurses once per nesting level, so a deep enough document ends in a
RecursionError (a 500 and a traceback); the depth is counted first, without recursion. NaN and
infinities are refused too: the gallery's JSON answers cannot carry them, so one stored photo
with them would break `/api/photos` for everyone.
"""

from __future__ import annotations

import json
import math
from typing import Any

MAX_BYTES = 64 * 1024
MAX_DEPTH = 32


class BadMetadata(ValueError):
    """Metadata the gallery will not store; ``status`` is the HTTP answer (400, or 413 too large)."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


def nesting_depth(text: str) -> int:
    """How deep arrays and objects nest in a JSON text (strings skipped), without recursion."""
    depth = deepest = 0
    in_string = escaped = False
    for char in text:
        if in_string:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth -= 1
    return deepest


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is out of range for a number")
    return value


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


def parse_metadata(text: str, max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH) -> dict[str, Any]:
    """The metadata as a dict; raises ``BadMetadata`` with the reason."""
    size = len(text.encode("utf-8", "surrogatepass"))
    if size > max_bytes:
        raise BadMetadata(f"metadata is {size:,} bytes, over the gallery's limit of {max_bytes:,}", 413)
    if nesting_depth(text) > max_depth:
        raise BadMetadata(f"metadata nests deeper than {max_depth} levels")
    try:
        value = json.loads(text, parse_float=_finite, parse_constant=_no_constant)
    except (ValueError, RecursionError) as error:
        raise BadMetadata(f"metadata is not JSON: {error}") from None
    if not isinstance(value, dict):
        raise BadMetadata("metadata must be a JSON object")
    return value
