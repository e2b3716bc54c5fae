"""The limits on what botstage reads: one place, with names, so errors and docs can cite them.

A mission, profile or scenario file is input from anyone: a file that is too large, a YAML alias
bomb, a nesting too deep for a recursive walk, a condition that builds a gigabyte string must end
in a located error, never in minutes of work, gigabytes of memory or a RecursionError. Every
limit is far above what a hand-written mission needs (the shipped ones are below 1% of each).
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Field, TypeAdapter, ValidationError

# -- files ------------------------------------------------------------------------------
MAX_FILE_BYTES = 4 * 1024 * 1024  # one YAML file (mission, include, profile, scenario)
MAX_IMAGE_BYTES = 64 * 1024 * 1024  # one map image (a PGM of 8,000 x 8,000 cells)
MAX_INCLUDED_FILES = 100  # files one mission reads through `include:`, at every level
INCLUDE_PATH_ENV = "BOTSTAGE_INCLUDE_PATH"  # extra folders includes may come from (os.pathsep-separated)

# -- YAML structure ---------------------------------------------------------------------
MAX_NESTING = 100  # mappings and lists inside each other, after expanding aliases
MAX_VALUES = 500_000  # values (scalars, lists, mappings) of one mission with its includes
MAX_ALIAS_VALUES = 100_000  # of which values repeated by YAML aliases (`*anchor`, `<<: *anchor`)

# -- trees and machines -------------------------------------------------------------------
MAX_NODE_DEPTH = 100  # nodes inside nodes, counting subtrees, machines and states on the way

# -- conditions -----------------------------------------------------------------------------
MAX_CONDITION_CHARS = 2_000  # characters of one condition
MAX_CONDITION_DEPTH = 50  # operators and calls nested inside each other
MAX_CONDITION_NODES = 500  # names, literals, operators and calls in one condition
MAX_SEQUENCE_LENGTH = 100_000  # items (or characters) of a list or string a condition builds
MAX_INT_BITS = 4_096  # bits of an integer a condition's multiplication builds (about 1,233 digits)

# -- numbers ---------------------------------------------------------------------------------
MAX_SECONDS = 10_000_000.0  # any duration, timeout or time limit (about 116 days)
MAX_TIMES = 1_000_000_000  # repeat and retry counts
MAX_NAME_BYTES = 200  # a mission's name in UTF-8 (it names the run folder; file names hold 255)

Seconds = Annotated[float, Field(ge=0, le=MAX_SECONDS, allow_inf_nan=False)]
PositiveSeconds = Annotated[float, Field(gt=0, le=MAX_SECONDS, allow_inf_nan=False)]
Times = Annotated[int, Field(ge=1, le=MAX_TIMES)]

_ADAPTERS: dict[Any, TypeAdapter[Any]] = {}


def number_problem(tp: Any, value: Any) -> str:
    """Why ``value`` is not a ``tp`` (``Seconds`` ...), in pydantic's words; '' if it is one.

    For numbers checked outside a pydantic model, so every number error reads alike:
    ``input should be greater than 0``, ``input should be a finite number``.
    """
    adapter = _ADAPTERS.get(tp)
    if adapter is None:
        adapter = _ADAPTERS[tp] = TypeAdapter(tp)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return "input should be a valid number"
    try:
        adapter.validate_python(value)
    except ValidationError as exc:
        message = exc.errors()[0]["msg"]
        return message[:1].lower() + message[1:]
    return ""
