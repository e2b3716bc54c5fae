"""Nav2's control and decorator nodes (and its goal conditions) as botstage node kinds, under Nav2's IDs.

A plug-in set: registered through the ``botstage.nodes`` entry points in pyproject.toml, exactly
as a third party's kinds would be. Ports are options beside the kind, named, typed and defaulted
as ``nav2_tree_nodes.xml`` declares them (``{RecoveryNode: [...], number_of_retries: 6}``,
``{RateController: NODE, hz: 1.0}``); leaves take their ports as their value
(``{GoalUpdated: {}}``). Ports that only address ROS (frames) are accepted and ignored.

GoalUpdated and GlobalUpdatedGoal are kinds here, not skills: they compare the goal with the one
they noted when their parent last started them afresh, which only the tree knows.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Annotated, Any, ClassVar

import py_trees
from pydantic import Field

from botstage.behaviors.btcpp.vocabulary import SCOPE
from botstage.behaviors.kinds.base import CompositeKind, DecoratorKind, KindOptions, LeafKind, NodeBuild
from botstage.behaviors.kinds.registry import NodeSet
from botstage.behaviors.nav2 import behaviours as nav2
from botstage.behaviors.skill_behaviour import KeyRef
from botstage.behaviors.skill_binding import parse_binding
from botstage.robots.suggest import did_you_mean

Positive = Annotated[float, Field(gt=0, le=1e6, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, le=1e6, allow_inf_nan=False)]
IGNORED = "ignored on botstage: poses are in the map frame, from the robot's navigation stack"
GOAL_DOC = "the goal to watch, usually {goal}; unset: the blackboard's `goal`"
GOALS_DOC = "the goals to watch, usually {goals}; unset: the blackboard's `goals`"


def _key(b: NodeBuild, raw: Any, port: str, mode: str, *, declared: bool = True) -> str | None:
    """The key a port names (``{key}``, remapped); its use is recorded when it was written."""
    ref = parse_binding(raw)
    if not isinstance(ref, KeyRef):
        b.problem(f"{port} of {b.kind.name} names a blackboard key: write {{{raw}}}", port)
        return None
    key = b.builder.key(ref.key, b.spec_path + (port,), b.scope)
    if key is not None and declared:
        b.builder.use(key, mode, b.spec_path + (port,), b.scope)
    return key


def _goals(b: NodeBuild, ports: Mapping[str, Any]) -> nav2.GoalReader | None:
    """Nav2's getInputOrBlackboard for `goal` and `goals`: the port's key, else the key of that name
    (read when someone wrote it, not declared as read: NavigateToPose has no `goals`)."""
    keys = []
    for port in ("goal", "goals"):
        written = ports.get(port)
        key = _key(b, written if written is not None else "{" + port + "}", port, "read", declared=written is not None)
        if key is None:
            return None
        keys.append(key)
    return nav2.GoalReader(b.runtime.blackboard.client(b.path, reads=keys), tuple(keys))


def _navigation(b: NodeBuild) -> Any:
    """The robot's navigation stack, or None with a problem (a tree run on no robot)."""
    stack = b.runtime.interfaces.get("navigation")
    if stack is None:
        b.problem(f"{b.kind.name} needs a robot with a navigation stack (a map): run it with --robot and --world")
    return stack


# -- controls -------------------------------------------------------------------------------


class PipelineSequence(CompositeKind):
    name = "PipelineSequence"
    description = "Nav2 PipelineSequence: ticks every child up to the running one each tick; a failure restarts it"
    shape = "sequence"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return nav2.PipelineSequence(b.name, b.children)


class RecoveryOptions(KindOptions):
    number_of_retries: int = Field(default=1, ge=0, le=1_000_000, description="times the action is tried again")


class RecoveryNode(CompositeKind):
    name = "RecoveryNode"
    description = "Nav2 RecoveryNode: action, recovery; on failure run the recovery and retry, number_of_retries times"
    shape = "selector"
    Options = RecoveryOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        if len(b.children) != 2:
            b.problem(f"RecoveryNode takes 2 children (the action, its recovery), got {len(b.children)}", self.name)
            return None
        return nav2.RecoveryNode(b.name, b.children, b.options.number_of_retries)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"RecoveryNode ×{node.retries}"


class RoundRobinOptions(KindOptions):
    wrap_around: bool = Field(default=False, description="after the last child, start over (else fail)")


class RoundRobin(CompositeKind):
    name = "RoundRobin"
    description = "Nav2 RoundRobin: the next child in turn each time; fails when all failed"
    shape = "selector"
    Options = RoundRobinOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return nav2.RoundRobin(b.name, b.children, b.options.wrap_around)


class NonblockingSequence(CompositeKind):
    name = "NonblockingSequence"
    description = "Nav2 NonblockingSequence: ticks every child each tick; succeeds when all succeeded at once"
    shape = "sequence"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return nav2.NonblockingSequence(b.name, b.children)


# -- decorators -----------------------------------------------------------------------------


class RateOptions(KindOptions):
    hz: Positive = Field(default=10.0, description="ticks of the child per second of mission time, at most")


class RateController(DecoratorKind):
    name = "RateController"
    description = "Nav2 RateController: tick the child at most hz times a second (RUNNING in between)"
    Options = RateOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return nav2.RateController(b.name, b.child, b.runtime.clock, b.options.hz)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return f"RateController {1 / node.period:g} Hz"


class DistanceOptions(KindOptions):
    distance: NonNegative = Field(default=1.0, description="m the robot moves between ticks of the child")
    global_frame: str | None = Field(default=None, description=IGNORED)
    robot_base_frame: str | None = Field(default=None, description=IGNORED)


class DistanceController(DecoratorKind):
    name = "DistanceController"
    description = "Nav2 DistanceController: tick the child again each `distance` metres the robot moves"
    Options = DistanceOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        stack = _navigation(b)
        if stack is None:
            return None
        return nav2.DistanceController(b.name, b.child, b.runtime.clock, b.options.distance, stack.pose)


class SpeedOptions(KindOptions):
    min_rate: Positive = Field(default=0.1, description="Hz at min_speed and below")
    max_rate: Positive = Field(default=1.0, description="Hz at max_speed and above")
    min_speed: NonNegative = Field(default=0.0, description="m/s")
    max_speed: Positive = Field(default=0.5, description="m/s")
    goal: str | None = Field(default=None, description=GOAL_DOC)
    goals: str | None = Field(default=None, description=GOALS_DOC)


def _speed(b: NodeBuild) -> Callable[[], float] | None:
    odometry = b.runtime.interfaces.get("odometry")
    if odometry is None:
        b.problem(f"{b.kind.name} needs a robot with odometry: run it with --robot")
        return None
    return lambda: odometry.read().twist.v


class SpeedController(DecoratorKind):
    name = "SpeedController"
    description = "Nav2 SpeedController: tick the child faster the faster the robot drives; a new goal ticks it"
    Options = SpeedOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        o: SpeedOptions = b.options
        if o.min_rate > o.max_rate or o.min_speed >= o.max_speed:
            b.problem("SpeedController needs min_rate ≤ max_rate and min_speed < max_speed")
            return None
        speed, goals = _speed(b), _goals(b, {"goal": o.goal, "goals": o.goals})
        if speed is None or goals is None:
            return None
        rates, speeds = (o.min_rate, o.max_rate), (o.min_speed, o.max_speed)
        return nav2.SpeedController(b.name, b.child, b.runtime.clock, rates, speeds, speed, goals)


class GoalOptions(KindOptions):
    goal: str | None = Field(default=None, description=GOAL_DOC)
    goals: str | None = Field(default=None, description=GOALS_DOC)


class GoalUpdatedController(DecoratorKind):
    name = "GoalUpdatedController"
    description = "Nav2 GoalUpdatedController: tick the child first, while it runs, and when the goal changed"
    Options = GoalOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        goals = _goals(b, {"goal": b.options.goal, "goals": b.options.goals})
        return None if goals is None else nav2.GoalUpdatedController(b.name, b.child, b.runtime.clock, goals)


class SingleTrigger(DecoratorKind):
    name = "SingleTrigger"
    description = "Nav2 SingleTrigger: run the child to completion once; fail after that until reset"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return nav2.SingleTrigger(b.name, b.child, b.runtime.clock)


class PathLongerOptions(KindOptions):
    path: str = Field(description="the path, usually {path}")
    prox_len: NonNegative = Field(default=3.0, description="m of the old path left that counts as near the goal")
    length_factor: Positive = Field(default=2.0, description="how much longer the new path must be")


class PathLongerOnApproach(DecoratorKind):
    name = "PathLongerOnApproach"
    description = "Nav2 PathLongerOnApproach: tick the child when, near the goal, the new path is much longer"
    Options = PathLongerOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        key = _key(b, b.options.path, "path", "read")
        if key is None:
            return None
        access = b.runtime.blackboard.client(b.path, reads=[key])

        def path() -> Any:
            return access.get(key) if access.exists(key) else None

        o: PathLongerOptions = b.options
        return nav2.PathLongerOnApproach(b.name, b.child, b.runtime.clock, path, o.prox_len, o.length_factor)


class GoalUpdaterOptions(KindOptions):
    input_goal: str | None = Field(default=None, description="the goal, {key}")
    input_goals: str | None = Field(default=None, description="the goals, {key}")
    output_goal: str | None = Field(default=None, description="where the goal goes, {key}")
    output_goals: str | None = Field(default=None, description="where the goals go, {key}")


class GoalUpdater(DecoratorKind):
    name = "GoalUpdater"
    description = "Nav2 GoalUpdater: copy input_goal(s) to output_goal(s), then tick the child (no goal topic here)"
    Options = GoalUpdaterOptions
    output_ports: ClassVar[tuple[str, ...]] = ("output_goal", "output_goals")

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        o: GoalUpdaterOptions = b.options
        pairs: list[tuple[str, str]] = []
        for source, target in (("input_goal", "output_goal"), ("input_goals", "output_goals")):
            raw_in, raw_out = getattr(o, source), getattr(o, target)
            if raw_in is None and raw_out is None:
                continue
            if raw_in is None or raw_out is None:
                b.problem(f"GoalUpdater: {source} and {target} go together", source if raw_in is None else target)
                return None
            read, write = _key(b, raw_in, source, "read"), _key(b, raw_out, target, "write")
            if read is None or write is None:
                return None
            pairs.append((read, write))
        access = b.runtime.blackboard.client(b.path, reads=[r for r, _ in pairs], writes=[w for _, w in pairs])

        def copy() -> None:
            for read, write in pairs:
                access.set(write, access.get(read))

        return nav2.GoalUpdater(b.name, b.child, b.runtime.clock, copy)


# -- conditions -----------------------------------------------------------------------------


class GoalUpdated(LeafKind):
    name = "GoalUpdated"
    description = "Nav2 GoalUpdated: FAILURE when started (noting the goal), SUCCESS once goal or goals changed"
    shape = "condition"
    ports: ClassVar[tuple[str, ...]] = ("goal", "goals")
    once: ClassVar[bool] = False

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        value = {} if b.value is None else b.value
        if not isinstance(value, Mapping):
            b.problem(f"{self.name} takes a mapping of its ports (goal, goals)", self.name)
            return None
        for port in value:
            if port not in self.ports:
                b.problem(f"{self.name} has no port {port!r}", self.name, port, hint=did_you_mean(port, self.ports))
                return None
        goals = _goals(b, value)
        return None if goals is None else nav2.GoalUpdated(b.name, b.runtime.clock, goals, once=self.once)

    def written(self) -> str:
        return f"{self.name}: {{goal: '{{goal}}', goals: '{{goals}}'}}"


class GlobalUpdatedGoal(GoalUpdated):
    name = "GlobalUpdatedGoal"
    description = "Nav2 GlobalUpdatedGoal: FAILURE the first time (noting the goal), SUCCESS whenever it changed since"
    once = True


def _leaf_ports(b: NodeBuild, ports: dict[str, tuple[Any, Any]]) -> dict[str, Any] | None:
    """A leaf kind's ports as written (``{TimeExpired: {seconds: 2.0}}``), checked against ``ports``
    (name -> (type, default)); None (and a problem) when wrong."""
    value = {} if b.value is None else b.value
    if not isinstance(value, Mapping):
        b.problem(f"{b.kind.name} takes a mapping of its ports ({', '.join(ports)})", b.kind.name)
        return None
    for port in value:
        if port not in ports:
            b.problem(f"{b.kind.name} has no port {port!r}", b.kind.name, port, hint=did_you_mean(port, ports))
            return None
    got = {}
    for port, (tp, default) in ports.items():
        raw = value.get(port, default)
        if tp is float and (isinstance(raw, bool) or not isinstance(raw, int | float) or not raw >= 0):
            b.problem(f"{port} of {b.kind.name} is a number ≥ 0, got {raw!r}", b.kind.name, port)
            return None
        got[port] = raw
    return got


class TimeExpired(LeafKind):
    name = "TimeExpired"
    description = "Nav2 TimeExpired: FAILURE when started, then SUCCESS every `seconds` of mission time"
    shape = "condition"
    ports: ClassVar[tuple[str, ...]] = ("seconds",)
    port_defaults: ClassVar[dict[str, Any]] = {"seconds": 1.0}

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        ports = _leaf_ports(b, {"seconds": (float, self.port_defaults["seconds"])})
        if ports is None:
            return None
        return nav2.Every(b.name, b.runtime.clock, b.runtime.clock.now, float(ports["seconds"]))


class DistanceTraveled(LeafKind):
    name = "DistanceTraveled"
    description = "Nav2 DistanceTraveled: FAILURE when started, then SUCCESS every `distance` metres driven"
    shape = "condition"
    ports: ClassVar[tuple[str, ...]] = ("distance", "global_frame", "robot_base_frame")
    port_defaults: ClassVar[dict[str, Any]] = {"distance": 1.0}

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        frames = {"global_frame": (str, None), "robot_base_frame": (str, None)}  # ignored: the map frame
        ports = _leaf_ports(b, {"distance": (float, self.port_defaults["distance"]), **frames})
        stack = _navigation(b)
        if ports is None or stack is None:
            return None
        last = [stack.pose()]
        driven = [0.0]

        def odometer() -> float:
            pose = stack.pose()
            driven[0] += math.hypot(pose.x - last[0].x, pose.y - last[0].y)
            last[0] = pose
            return driven[0]

        return nav2.Every(b.name, b.runtime.clock, odometer, float(ports["distance"]))


class PathExpiringTimer(LeafKind):
    name = "PathExpiringTimer"
    description = "Nav2 PathExpiringTimer: SUCCESS every `seconds` the path stays the same; a new path starts over"
    shape = "condition"
    ports: ClassVar[tuple[str, ...]] = ("seconds", "path")
    port_defaults: ClassVar[dict[str, Any]] = {"seconds": 1.0}

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour | None:
        ports = _leaf_ports(b, {"seconds": (float, self.port_defaults["seconds"]), "path": (str, "{path}")})
        if ports is None:
            return None
        key = _key(b, ports["path"], "path", "read")
        if key is None:
            return None
        access = b.runtime.blackboard.client(b.path, reads=[key])
        seen: list[Any] = [None]

        def new_path() -> bool:
            path = access.get(key) if access.exists(key) else None
            changed, seen[0] = path != seen[0], path
            return changed

        return nav2.Every(b.name, b.runtime.clock, b.runtime.clock.now, float(ports["seconds"]), new_path)


__all__ = [
    "DistanceController",
    "DistanceTraveled",
    "GlobalUpdatedGoal",
    "GoalUpdated",
    "GoalUpdatedController",
    "GoalUpdater",
    "NonblockingSequence",
    "PathExpiringTimer",
    "PathLongerOnApproach",
    "PipelineSequence",
    "RateController",
    "RecoveryNode",
    "RoundRobin",
    "SingleTrigger",
    "SpeedController",
    "TimeExpired",
]

# the entry point `nav2` of `botstage.nodes`: Nav2's nodes extend BT.CPP's factory, so they live in
# its scope (what an XML file sees), as upstream Nav2 registers them into BT.CPP's factory
NODE_SET = NodeSet(
    "nav2", SCOPE, tuple(globals()[name] for name in __all__), "Nav2's control, decorator and condition nodes"
)
