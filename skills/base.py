"""The skill contract: what a skill declares and what it receives when it runs.

A skill is usable from a behaviour tree, from a state of a state machine, from a scenario test
and from a remote process alike, so nothing here knows about py_trees or transitions.
"""

from __future__ import annotations

import inspect
import logging
import math
import random
import threading
from collections.abc import Callable, Generator, Mapping
from concurrent.futures import Future
from dataclasses import dataclass, field
from functools import cache
from types import MappingProxyType
from typing import Annotated, Any, ClassVar, Literal, NamedTuple, Protocol, get_args, get_origin

from pydantic import BaseModel, ConfigDict, PydanticUserError, TypeAdapter, ValidationError

from botstage.robots.clock import Clock

# port types for times: In(Seconds) refuses negatives, NaN, infinities and more than MAX_SECONDS
from botstage.robots.limits import PositiveSeconds as PositiveSeconds
from botstage.robots.limits import Seconds as Seconds

SUCCESS = "success"
FAILURE = "failure"
BASE_OUTCOMES: tuple[str, ...] = (SUCCESS, FAILURE)


class _Missing:
    __slots__ = ()

    def __repr__(self) -> str:
        return "MISSING"


MISSING: Any = _Missing()


@cache
def _adapter(tp: Any, finite: bool = False) -> TypeAdapter[Any]:
    if finite:
        try:
            return TypeAdapter(tp, config=ConfigDict(allow_inf_nan=False))
        except PydanticUserError:  # a model has its own config
            pass
    return TypeAdapter(tp)


def plain_type(tp: Any) -> Any:
    """The type without its constraints: ``Seconds`` is a ``float``."""
    return get_args(tp)[0] if get_origin(tp) is Annotated else tp


def type_name(tp: Any) -> str:
    """``float``, ``list[float]``, ``Any``: how a type reads in an error message."""
    tp = plain_type(tp)
    if tp is Any:
        return "Any"
    if get_args(tp) or not isinstance(tp, type):
        return str(tp).replace("typing.", "")
    return tp.__name__


_OUT_OF_RANGE = frozenset({"finite_number", "greater_than", "greater_than_equal", "less_than", "less_than_equal"})


def check_type(tp: Any, value: Any, *, finite: bool = False) -> Any:
    """Validate ``value`` against ``tp`` strictly (ints are accepted for floats, nothing else is coerced).

    ``finite``: refuse NaN and infinities as numbers of ``tp`` (a value written in a mission;
    a value a sensor wrote may be NaN). Returns the validated value; raises ``TypeError`` with a
    readable message.
    """
    if tp is Any or tp is object:
        return value
    try:
        return _adapter(tp, finite).validate_python(value, strict=True)
    except ValidationError as exc:
        shown = repr(value)
        if len(shown) > 60:
            shown = shown[:57] + "..."
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first.get("loc", ()))
        if first["type"] in _OUT_OF_RANGE:  # the right type, a wrong value: say only what is wrong
            message = first["msg"][:1].lower() + first["msg"][1:]
            raise TypeError(f"{where}: {message}" if where else message) from None
        detail = f" ({where}: {first['msg']})" if where else f" ({first['msg']})"
        raise TypeError(f"expected {type_name(tp)}, got {type(value).__name__} {shown}{detail}") from None


@dataclass(frozen=True, slots=True)
class Port:
    """A typed input or output of a skill.

    ``expression`` marks a string input that is a condition over blackboard keys (see
    ``botstage.skills.expression``): the engine grants the node read access to the keys it names.
    ``names_key`` marks a string input that names a blackboard key the skill reads or writes
    itself (``"read"``/``"write"``), so the engine can grant that access up front.
    """

    type: Any = Any
    default: Any = MISSING
    doc: str = ""
    expression: bool = False
    names_key: Literal["read", "write"] | None = None

    @property
    def required(self) -> bool:
        return self.default is MISSING


def In(
    type: Any = Any,
    default: Any = MISSING,
    doc: str = "",
    *,
    expression: bool = False,
    names_key: Literal["read", "write"] | None = None,
) -> Port:
    return Port(type=type, default=default, doc=doc, expression=expression, names_key=names_key)


def Out(type: Any = Any, doc: str = "") -> Port:
    return Port(type=type, doc=doc)


_NO_OUTPUTS: Mapping[str, Any] = MappingProxyType({})


class Outcome(NamedTuple):
    """How a run of a skill ended: an outcome name, the reason, and the values of output ports.

    A NamedTuple rather than a dataclass: skills create one per run, on the engine's hot path.
    """

    name: str
    reason: str = ""
    outputs: Mapping[str, Any] = _NO_OUTPUTS

    @classmethod
    def success(cls, reason: str = "", **outputs: Any) -> Outcome:
        return cls(SUCCESS, reason, outputs or _NO_OUTPUTS)

    @classmethod
    def failure(cls, reason: str, **outputs: Any) -> Outcome:
        return cls(FAILURE, reason, outputs or _NO_OUTPUTS)


class NoParams(BaseModel):
    model_config = ConfigDict(extra="forbid")


class BlackboardView(Protocol):
    """The blackboard as a skill sees it: access is checked per node by the engine."""

    def get(self, key: str) -> Any: ...

    def set(self, key: str, value: Any) -> None: ...

    def exists(self, key: str) -> bool: ...


class Submitter(Protocol):
    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]: ...


class SkillLogger:
    """A logger bound to one node; records also reach the run's trace through ``sink``."""

    __slots__ = ("_logger", "_owner", "node", "sink")

    def __init__(
        self, node: str, logger: logging.Logger | None = None, sink: Callable[[str, str, str], None] | None = None
    ) -> None:
        self.node = node
        self._logger = logger or logging.getLogger("botstage.skills")
        self.sink = sink
        self._owner = threading.get_ident()

    def log(self, level: int, message: str) -> None:
        self._logger.log(level, "[%s] %s", self.node, message)
        # Only the engine's thread writes to the trace: a line from a worker thread would land
        # at a different place in every run. Worker code logs to Python logging only.
        if self.sink is not None and threading.get_ident() == self._owner:
            self.sink(self.node, logging.getLevelName(level).lower(), message)

    def adopt(self) -> None:
        """Make the calling thread the one whose lines reach ``sink`` (a remote host steps a call
        on whichever thread brings its request)."""
        self._owner = threading.get_ident()

    def debug(self, message: str) -> None:
        self.log(logging.DEBUG, message)

    def info(self, message: str) -> None:
        self.log(logging.INFO, message)

    def warning(self, message: str) -> None:
        self.log(logging.WARNING, message)

    def error(self, message: str) -> None:
        self.log(logging.ERROR, message)


@dataclass(slots=True)
class SkillContext:
    """Everything a running skill may touch: the clock, the robot, its parameters, the blackboard.

    ``submit`` sends blocking work to the worker pool; the skill then ``yield``s the returned
    future and receives its result when it is done (on the sim clock at a deterministic tick).
    """

    clock: Clock
    params: BaseModel
    logger: SkillLogger
    blackboard: BlackboardView
    workers: Submitter
    interfaces: Mapping[str, Any] = field(default_factory=dict)
    rng: random.Random = field(default_factory=random.Random)
    node: str = ""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        return self.workers.submit(fn, *args, **kwargs)

    def interface(self, name: str) -> Any:
        try:
            return self.interfaces[name]
        except KeyError:
            have = ", ".join(sorted(self.interfaces)) or "none"
            raise LookupError(f"this robot has no '{name}' interface (it has: {have})") from None


SkillRun = Generator[Any, Any, "Outcome | str | None"]


def _non_finite(value: Any, loc: tuple[Any, ...]) -> Generator[tuple[tuple[Any, ...], float], None, None]:
    """Every NaN or infinity in a value (models, mappings and lists walked), with its place."""
    if isinstance(value, float):
        if not math.isfinite(value):
            yield loc, value
    elif isinstance(value, BaseModel):
        for name in type(value).model_fields:
            yield from _non_finite(getattr(value, name), (*loc, name))
    elif isinstance(value, Mapping):
        for key, item in value.items():
            yield from _non_finite(item, (*loc, key))
    elif isinstance(value, list | tuple):
        for index, item in enumerate(value):
            yield from _non_finite(item, (*loc, index))


class Skill:
    """Base class of every skill.

    Subclasses set ``name``, ``inputs``/``outputs`` (dicts of ``Port``), ``outcomes`` (their own,
    beyond success and failure), optionally a pydantic ``Params`` model, and implement ``run``.
    ``run(ctx, **inputs)`` is a generator that yields once per tick while running (or yields a
    future from ``ctx.submit`` to wait on it) and returns an ``Outcome``. A skill that always
    finishes within its first tick may implement ``run`` as a plain function returning an Outcome.
    Cancelling closes the generator, so ``finally:`` blocks always run.

    ``kind`` is ``"action"`` (has effects) or ``"condition"`` (reads only, finishes at once);
    the engine halts a running lower-priority branch before an action starts, never for a
    condition.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    kind: ClassVar[Literal["action", "condition"]] = "action"
    inputs: ClassVar[dict[str, Port]] = {}
    outputs: ClassVar[dict[str, Port]] = {}
    outcomes: ClassVar[tuple[str, ...]] = ()
    # the outcomes that count as success where the skill runs (a tree node's SUCCESS): a skill
    # whose own vocabulary is richer (navigate's `succeeded`) names them; nodes may override
    success_outcomes: ClassVar[tuple[str, ...]] = (SUCCESS,)
    Params: ClassVar[type[BaseModel]] = NoParams

    # Filled in by __init_subclass__.
    all_outcomes: ClassVar[frozenset[str]] = frozenset(BASE_OUTCOMES)
    is_generator: ClassVar[bool] = True

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if not cls.name:
            return  # abstract intermediate class
        problems = []
        if not cls.name.isidentifier():
            problems.append(f"name {cls.name!r} must be an identifier")
        for kind, ports in (("input", cls.inputs), ("output", cls.outputs)):
            for port_name, port in ports.items():
                if not isinstance(port, Port):
                    problems.append(f"{kind} port {port_name!r} must be declared with In()/Out()")
        if not (isinstance(cls.Params, type) and issubclass(cls.Params, BaseModel)):
            problems.append("Params must be a pydantic BaseModel subclass")
        if problems:
            raise TypeError(f"skill class {cls.__qualname__}: " + "; ".join(problems))
        if not cls.success_outcomes:
            raise TypeError(f"skill class {cls.__qualname__}: success_outcomes must name at least one outcome")
        cls.all_outcomes = frozenset({FAILURE, *cls.success_outcomes, *cls.outcomes})
        cls.is_generator = inspect.isgeneratorfunction(cls.run)

    def __init__(self, params: BaseModel | Mapping[str, Any] | None = None) -> None:
        if isinstance(params, BaseModel):
            self.params = params
        else:
            self.params = self.validate_params(params or {})

    @classmethod
    def validate_params(cls, params: Mapping[str, Any]) -> BaseModel:
        """The skill's parameters from a mission, a profile or code; raises ValidationError.

        NaN and infinities are refused wherever they are written (pydantic's own message):
        a parameter is a setting, and a NaN one silently turns every comparison off.
        """
        validated = cls.Params(**params)  # "nan" as a string becomes a NaN here: look after
        odd = [{"type": "finite_number", "loc": loc, "input": value} for loc, value in _non_finite(validated, ())]
        if odd:
            raise ValidationError.from_exception_data(cls.Params.__name__, odd)  # type: ignore[arg-type]
        return validated

    def run(self, ctx: SkillContext, **inputs: Any) -> SkillRun:
        raise NotImplementedError(f"skill {self.name!r} does not implement run()")

    @classmethod
    def describe(cls) -> dict[str, Any]:
        """A plain description of the contract (for docs, validation and remote peers)."""

        def ports(ps: dict[str, Port]) -> dict[str, Any]:
            return {
                n: {"type": type_name(p.type), "required": p.required, "doc": p.doc}
                | ({} if p.required else {"default": p.default})
                for n, p in ps.items()
            }

        return {
            "name": cls.name,
            "description": cls.description or (cls.__doc__ or "").strip().split("\n")[0],
            "kind": cls.kind,
            "inputs": ports(cls.inputs),
            "outputs": ports(cls.outputs),
            "outcomes": sorted(cls.all_outcomes),
            "success_outcomes": list(cls.success_outcomes),
            "params": cls.Params.model_json_schema(),
        }
