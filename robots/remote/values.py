"""Values between processes as JSON text, without losing what JSON would blur.

Plain JSON turns a tuple into a list and cannot hold bytes, arrays or non-finite floats; a remote
skill that compared a pose it wrote (a tuple) with the one it read back (a list) would write it
again, and a distributed run would no longer match a local one. So tuples, bytes, numpy arrays
(dtype, shape and raw bytes), non-string dict keys, non-finite floats and the readings of
``robots.interfaces`` are tagged (``{"$tuple": [...]}`` and so on); everything else is JSON as
it is. Only data crosses: values of any other type are refused with their path, never pickled (a
pickle from the network runs code).
"""

from __future__ import annotations

import base64
import dataclasses
import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from robots import interfaces

TAG = "$"  # dicts whose only key starts with this are tags; a real dict like that is wrapped too
# the readings and values of robots.interfaces, by class name: the only classes that cross
READINGS: dict[str, type] = {
    cls.__name__: cls
    for cls in vars(interfaces).values()
    if isinstance(cls, type) and dataclasses.is_dataclass(cls) and cls.__module__ == interfaces.__name__
}
_DTYPES = frozenset("?bBhHiIlLqQefdgFD")  # numeric numpy kinds; object arrays never cross
MAX_TEXT = 16 * 1024 * 1024  # a message no skill needs; refused before parsing


class ValueCodecError(ValueError):
    """A value that cannot cross to another process, with where it is."""


def _pack(value: Any, path: str) -> Any:
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else {"$float": repr(value)}
    if isinstance(value, list):
        return [_pack(v, f"{path}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, tuple):
        return {"$tuple": [_pack(v, f"{path}[{i}]") for i, v in enumerate(value)]}
    if isinstance(value, (bytes, bytearray)):
        return {"$bytes": base64.b64encode(bytes(value)).decode("ascii")}
    if isinstance(value, Mapping):
        if all(isinstance(k, str) for k in value) and not any(k.startswith(TAG) for k in value):
            return {k: _pack(v, f"{path}.{k}") for k, v in value.items()}
        return {"$dict": [[_pack(k, f"{path} key"), _pack(v, f"{path}[{k!r}]")] for k, v in value.items()]}
    if isinstance(value, np.ndarray):
        if value.dtype.char not in _DTYPES:
            raise ValueCodecError(f"{path}: an array of {value.dtype} cannot be sent to another process")
        data = np.ascontiguousarray(value)
        return {"$nd": [data.dtype.str, list(data.shape), base64.b64encode(data.tobytes()).decode("ascii")]}
    if isinstance(value, np.generic):
        return _pack(value.item(), path)  # a numpy scalar
    if type(value).__name__ in READINGS and type(value) is READINGS[type(value).__name__]:
        fields = {f.name: _pack(getattr(value, f.name), f"{path}.{f.name}") for f in dataclasses.fields(value)}
        return {"$reading": [type(value).__name__, fields]}
    kind = type(value).__name__
    raise ValueCodecError(
        f"{path}: a {kind} cannot be sent to another process (only data, tuples, bytes, arrays and readings)"
    )


def _unpack(value: Any) -> Any:
    if isinstance(value, list):
        return [_unpack(v) for v in value]
    if not isinstance(value, dict):
        return value
    if len(value) == 1:
        ((tag, inner),) = value.items()
        if tag == "$tuple":
            return tuple(_unpack(v) for v in inner)
        if tag == "$bytes":
            return base64.b64decode(inner, validate=True)
        if tag == "$float":
            return float(inner)
        if tag == "$dict":
            return {_hashable(_unpack(k)): _unpack(v) for k, v in inner}
        if tag == "$nd":
            return _array(*inner)
        if tag == "$reading":
            name, fields = inner
            return READINGS[name](**{k: _unpack(v) for k, v in fields.items()})
    return {k: _unpack(v) for k, v in value.items()}


def _array(dtype: str, shape: list[int], data: str) -> np.ndarray:
    kind = np.dtype(dtype)
    if kind.char not in _DTYPES:
        raise ValueError(f"arrays of {kind} do not cross")
    return np.frombuffer(base64.b64decode(data, validate=True), dtype=kind).reshape(shape).copy()


def _hashable(key: Any) -> Any:
    return tuple(_hashable(k) for k in key) if isinstance(key, (list, tuple)) else key


def dumps(value: Any, what: str = "value") -> str:
    """``value`` as compact JSON text; a ValueCodecError naming the part that cannot cross."""
    return json.dumps(_pack(value, what), separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def loads(text: str, what: str = "value") -> Any:
    """The value ``dumps`` made; a ValueCodecError for text that is not one."""
    if len(text) > MAX_TEXT:
        raise ValueCodecError(f"{what}: {len(text):,} characters is more than a remote skill may send ({MAX_TEXT:,})")
    try:
        return _unpack(json.loads(text))
    except (json.JSONDecodeError, RecursionError, TypeError, ValueError, KeyError) as error:
        raise ValueCodecError(f"{what}: not a value from a remote skill: {error}") from None
