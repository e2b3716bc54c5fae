"""Values between processes as JSON text, without losing what JSON would blur.

Plain JSON turns a tuple into a list and cannot hold bytes, arrays or non-finite floats; a remote
skill that compared a pose it wrote (a tuple) with the one it read back (a list) would write it
again, and a distributed run would no longer match a local one. So tuples, bytes, numpy arrays
(dtype, shape and raw bytes), non-string dict keys, non-finite floats and the readings of
``botstage.robots.interfaces`` are tagged (``{"$tuple": [...]}`` and so on); everything else is JSON as
it is. Only data crosses: values of any other type are refused with their path, never pickled (a
pickle from the network runs code).
"""

from __future__ import annotations

import base64
import dataclasses
import importlib
import json
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from botstage.robots import interfaces

TAG = "$"  # dicts whose only key starts with this are tags; a real dict like that is wrapped too
# the readings and values of robots.interfaces, by class name: the only classes that cross
READINGS: dict[str, type] = {
    cls.__name__: cls
    for cls in vars(interfaces).values()
    if isinstance(cls, type) and dataclasses.is_dataclass(cls) and cls.__module__ == interfaces.__name__
}
_DTYPES = frozenset("?bBhHiIlLqQefdgFD")  # numeric numpy kinds; object arrays never cross
# frozen dataclasses of botstage's own packages are values too (a people frame, a crowd); a class
# from anywhere else is never imported on a peer's say-so
DATA_PACKAGES = ("robots.", "skills.", "behaviors.", "missions.")

Other = Callable[[Any, str], Any]  # encodes what is not data (a handle to an object), or raises
MAX_TEXT = 16 * 1024 * 1024  # a message no skill needs; refused before parsing
# json.dumps with these options, without building an encoder per call
_encode = json.JSONEncoder(separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode


class ValueCodecError(ValueError):
    """A value that cannot cross to another process, with where it is."""


def _is_data_class(cls: type) -> bool:
    params = getattr(cls, "__dataclass_params__", None)
    return params is not None and params.frozen and cls.__module__.startswith(DATA_PACKAGES)


def _pack(value: Any, path: str, other: Other | None = None) -> Any:
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else {"$float": repr(value)}
    if isinstance(value, list):
        return [_pack(v, f"{path}[{i}]", other) for i, v in enumerate(value)]
    if isinstance(value, tuple):
        return {"$tuple": [_pack(v, f"{path}[{i}]", other) for i, v in enumerate(value)]}
    if isinstance(value, (bytes, bytearray)):
        return {"$bytes": base64.b64encode(bytes(value)).decode("ascii")}
    if isinstance(value, Mapping):
        if all(isinstance(k, str) for k in value) and not any(k.startswith(TAG) for k in value):
            return {k: _pack(v, f"{path}.{k}", other) for k, v in value.items()}
        return {
            "$dict": [[_pack(k, f"{path} key", other), _pack(v, f"{path}[{k!r}]", other)] for k, v in value.items()]
        }
    if isinstance(value, np.ndarray):
        if value.dtype.char not in _DTYPES:
            raise ValueCodecError(f"{path}: an array of {value.dtype} cannot be sent to another process")
        data = np.ascontiguousarray(value)
        return {"$nd": [data.dtype.str, list(data.shape), base64.b64encode(data.tobytes()).decode("ascii")]}
    if isinstance(value, np.generic):
        return _pack(value.item(), path)  # a numpy scalar
    if type(value).__name__ in READINGS and type(value) is READINGS[type(value).__name__]:
        fields = {f.name: _pack(getattr(value, f.name), f"{path}.{f.name}", other) for f in dataclasses.fields(value)}
        return {"$reading": [type(value).__name__, fields]}
    if _is_data_class(type(value)):
        cls = type(value)
        fields = {
            f.name: _pack(getattr(value, f.name), f"{path}.{f.name}", other)
            for f in dataclasses.fields(value)
            if f.init
        }
        return {"$data": [f"{cls.__module__}:{cls.__qualname__}", fields]}
    if other is not None:
        return other(value, path)
    kind = type(value).__name__
    raise ValueCodecError(
        f"{path}: a {kind} cannot be sent to another process (only data, tuples, bytes, arrays and readings)"
    )


def _plain(value: Any) -> bool:
    """Whether ``value`` is JSON as it is (nothing to tag): exact types only, so ``_pack`` would copy it unchanged."""
    kind = type(value)
    if kind is dict:
        for key, item in value.items():  # noqa: SIM110 - a loop: half the time of all() over a generator
            if type(key) is not str or key.startswith(TAG) or not _plain(item):
                return False
        return True
    if kind is str or kind is bool or kind is int or value is None:
        return True
    if kind is float:
        return math.isfinite(value)
    if kind is list:
        return all(map(_plain, value))
    return False


def _data_class(name: str) -> type:
    module, _, qualname = name.partition(":")
    if not module.startswith(DATA_PACKAGES):
        raise ValueError(f"{name} is not one of botstage's data classes")
    cls: Any = importlib.import_module(module)
    for part in qualname.split("."):
        cls = getattr(cls, part)
    if not (isinstance(cls, type) and _is_data_class(cls)):
        raise ValueError(f"{name} is not one of botstage's data classes")
    return cls


def _unpack(value: Any, other: Callable[[Any], Any] | None = None) -> Any:
    if isinstance(value, list):
        return [_unpack(v, other) for v in value]
    if not isinstance(value, dict):
        return value
    if len(value) == 1:
        ((tag, inner),) = value.items()
        if tag == "$tuple":
            return tuple(_unpack(v, other) for v in inner)
        if tag == "$bytes":
            return base64.b64decode(inner, validate=True)
        if tag == "$float":
            return float(inner)
        if tag == "$dict":
            return {_hashable(_unpack(k, other)): _unpack(v, other) for k, v in inner}
        if tag == "$nd":
            return _array(*inner)
        if tag == "$reading":
            name, fields = inner
            return READINGS[name](**{k: _unpack(v, other) for k, v in fields.items()})
        if tag == "$data":
            name, fields = inner
            return _data_class(name)(**{k: _unpack(v, other) for k, v in fields.items()})
        if tag == "$handle" and other is not None:
            return other(inner)
    return {k: _unpack(v, other) for k, v in value.items()}


def _array(dtype: str, shape: list[int], data: str) -> np.ndarray:
    kind = np.dtype(dtype)
    if kind.char not in _DTYPES:
        raise ValueError(f"arrays of {kind} do not cross")
    return np.frombuffer(base64.b64decode(data, validate=True), dtype=kind).reshape(shape).copy()


def _hashable(key: Any) -> Any:
    return tuple(_hashable(k) for k in key) if isinstance(key, (list, tuple)) else key


def dumps(value: Any, what: str = "value", other: Other | None = None) -> str:
    """``value`` as compact JSON text; a ValueCodecError naming the part that cannot cross.

    ``other(value, path)`` encodes what is not data (the device layer's handles) or raises.
    """
    packed = value if _plain(value) else _pack(value, what, other)  # most values need no tags: no copy
    return _encode(packed)


def loads(text: str, what: str = "value", other: Callable[[Any], Any] | None = None) -> Any:
    """The value ``dumps`` made; a ValueCodecError for text that is not one."""
    if len(text) > MAX_TEXT:
        raise ValueCodecError(f"{what}: {len(text):,} characters is more than a remote skill may send ({MAX_TEXT:,})")
    try:
        if '"$' not in text and '"\\u0024' not in text:  # no tag anywhere, nothing to unpack (a string
            # holding one shows as \"$, so it only takes the slower way)
            return json.loads(text)
        return _unpack(json.loads(text), other)
    except (
        json.JSONDecodeError,
        RecursionError,
        TypeError,
        ValueError,
        KeyError,
        ImportError,
        AttributeError,
    ) as error:
        raise ValueCodecError(f"{what}: not a value from a remote skill: {error}") from None
