"""Nav2's control and decorator nodes as py_trees behaviours, tick for tick.

Each class follows Nav2's own ``tick()``/``halt()`` (nav2_behavior_tree/plugins/control/*.cpp and
plugins/decorator/*.cpp). Two translations hold throughout, as in ``botstage.behaviors.btcpp.behaviours``:

- Nav2's controls are BT.CPP's ``ControlNode`` (``botstage.behaviors.btcpp.behaviours``), with its
  one halt rule: ``haltChild`` halts a running child (its skill cancelled) and sets any child
  back to IDLE (INVALID); a node's own progress is forgotten only when it is halted while RUNNING.
- Several Nav2 decorators start afresh when they are IDLE (their parent reset them). A parent
  that is not a BT.CPP control (a botstage kind) may leave a completed child as it is, so a node
  also counts as IDLE when it was not ticked in the previous tick of the tree (``Fresh``): a node
  ticked every tick is one iteration.

Time is the run's clock, never the wall clock.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

import py_trees
from py_trees.common import Status

from botstage.behaviors.btcpp.behaviours import ControlNode, halt

if TYPE_CHECKING:
    from botstage.behaviors.blackboard import NodeAccess
    from botstage.robots.clock import Clock

Behaviour = py_trees.behaviour.Behaviour


class Fresh:
    """Whether a node is IDLE (see the module): INVALID, or not ticked in the previous tick."""

    __slots__ = ("clock", "last")

    def __init__(self, clock: Clock) -> None:
        self.clock = clock
        self.last = -2

    def __call__(self, node: Behaviour) -> bool:
        ticks = self.clock.ticks
        idle = node.status is Status.INVALID or self.last < ticks - 1
        self.last = ticks
        return idle


class GoalReader:
    """The goal and goals a node compares, from its ports or else from the blackboard's `goal` and
    `goals` (Nav2's getInputOrBlackboard); a key nobody wrote reads as None, as Nav2 leaves it empty."""

    def __init__(self, access: NodeAccess, keys: tuple[str, ...]) -> None:
        self.access = access
        self.keys = keys

    def __call__(self) -> tuple[Any, ...]:
        return tuple(self.access.get(key) if self.access.exists(key) else None for key in self.keys)


# -- controls -------------------------------------------------------------------------------


class PipelineSequence(ControlNode):
    """Ticks its children in order every tick; a child RUNNING stops the tick only when no later
    child has run yet, so earlier RUNNING children (a RateController) keep ticking with the one
    being worked on (FollowPath). A failure halts all and fails; all succeeding succeeds."""

    def __init__(self, name: str, children: list[Behaviour]) -> None:
        super().__init__(name=name, children=list(children))
        self.last = 0

    def _reset(self) -> None:
        self.last = 0

    def tick(self) -> Iterator[Behaviour]:
        for index, child in enumerate(self.children):
            self.current_child = child
            yield from child.tick()
            if child.status is Status.FAILURE:
                self.last = 0
                yield from self._end(Status.FAILURE)
                return
            if child.status is Status.RUNNING and index >= self.last:
                self.last = index
                yield from self._running()
                return
        self.last = 0
        yield from self._end(Status.SUCCESS)


class RecoveryNode(ControlNode):
    """Two children: the action and its recovery. When the action fails, the recovery runs (in
    the same tick); when that succeeds, the action is tried again, ``retries`` times at most. A
    success of the action, or a failure of the recovery, ends it."""

    def __init__(self, name: str, children: list[Behaviour], retries: int) -> None:
        super().__init__(name=name, children=list(children))
        self.retries = retries
        self.index = 0
        self.count = 0

    def _reset(self) -> None:
        self.index = self.count = 0

    def tick(self) -> Iterator[Behaviour]:
        self.status = Status.RUNNING
        while self.count <= self.retries:
            child = self.current_child = self.children[self.index]
            yield from child.tick()
            status = child.status
            if status is Status.RUNNING:
                yield from self._running()
                return
            if self.index == 0:
                if status is Status.SUCCESS:
                    self._reset()
                    yield from self._end(Status.SUCCESS)
                    return
                if self.count >= self.retries:
                    break
                halt(child)
                self.index = 1
            else:
                if status is Status.FAILURE:
                    break
                halt(child)
                self.count += 1
                self.index = 0
        self._reset()
        yield from self._end(Status.FAILURE)


class RoundRobin(ControlNode):
    """Each time it is ticked anew, the next child in turn: a success ends it (the next call goes
    on from the child after), a failure moves on to the next child in the same tick, and it fails
    when every child failed. Without ``wrap_around`` it also fails, instead of starting over at
    the first child, once every child has had its turn since it was last reset."""

    def __init__(self, name: str, children: list[Behaviour], wrap_around: bool) -> None:
        super().__init__(name=name, children=list(children))
        self.wrap_around = wrap_around
        self.index = 0
        self.failed = 0
        self.attempted = 0

    def _reset(self) -> None:
        self.index = self.failed = self.attempted = 0

    def tick(self) -> Iterator[Behaviour]:
        count = len(self.children)
        self.status = Status.RUNNING
        while self.failed < count and (self.wrap_around or self.attempted < count):
            child = self.current_child = self.children[self.index]
            yield from child.tick()
            status = child.status
            if status is Status.RUNNING:
                yield from self._running()
                return
            self.index = (self.index + 1) % count
            self.attempted += 1
            if status is Status.SUCCESS:
                self.failed = 0
                yield from self._end(Status.SUCCESS)
                return
            self.failed += 1
        self._reset()
        yield from self._end(Status.FAILURE)


class NonblockingSequence(ControlNode):
    """Ticks every child every tick, running ones or not: a failure halts all and fails; when all
    succeeded in the same tick it succeeds."""

    def tick(self) -> Iterator[Behaviour]:
        done = True
        for child in self.children:
            self.current_child = child
            yield from child.tick()
            if child.status is Status.FAILURE:
                yield from self._end(Status.FAILURE)
                return
            done = done and child.status is Status.SUCCESS
        if done:
            yield from self._end(Status.SUCCESS)
            return
        yield from self._running()


# -- decorators -----------------------------------------------------------------------------


class _Decorator(py_trees.decorators.Decorator):
    """A Nav2 decorator: its whole tick is its own."""

    def __init__(self, name: str, child: Behaviour, clock: Clock) -> None:
        super().__init__(name=name, child=child)
        self.fresh = Fresh(clock)
        self.clock = clock

    def update(self) -> Status:
        return self.status

    def _tick_child(self, done: Callable[[Status], None] | None = None) -> Iterator[Behaviour]:
        """Tick the child and end with its status (``done`` sees a completed one first)."""
        yield from self.decorated.tick()
        status = self.decorated.status
        if status is not Status.RUNNING and done is not None:
            done(status)
        self.status = status
        yield self

    def _hold(self, status: Status = Status.RUNNING) -> Iterator[Behaviour]:
        self.status = status
        yield self


class _Throttle(_Decorator):
    """RateController, DistanceController, SpeedController: the child is ticked the first time,
    while it runs, and whenever ``due()`` says so; otherwise the node is RUNNING without it."""

    def __init__(self, name: str, child: Behaviour, clock: Clock) -> None:
        super().__init__(name, child, clock)
        self.first = True

    def restart(self) -> None:
        """Start a new iteration (the node was IDLE)."""

    def due(self) -> bool:
        raise NotImplementedError

    def ticked(self) -> None:
        """The child succeeded: the next wait starts now."""

    def tick(self) -> Iterator[Behaviour]:
        if self.fresh(self):
            self.first = True
            self.restart()
        if self.first or self.decorated.status is Status.RUNNING or self.due():
            self.first = False
            yield from self._tick_child(lambda s: self.ticked() if s is Status.SUCCESS else None)
            return
        yield from self._hold()


class RateController(_Throttle):
    """Ticks its child at most ``hz`` times a second of mission time."""

    def __init__(self, name: str, child: Behaviour, clock: Clock, hz: float) -> None:
        super().__init__(name, child, clock)
        self.period = 1.0 / hz
        self.start = 0.0

    def restart(self) -> None:
        self.start = self.clock.now()

    def due(self) -> bool:
        return self.clock.now() - self.start >= self.period - 1e-9

    def ticked(self) -> None:
        self.start = self.clock.now()


class DistanceController(_Throttle):
    """Ticks its child again each time the robot has moved ``distance`` metres."""

    def __init__(self, name: str, child: Behaviour, clock: Clock, distance: float, pose: Callable[[], Any]) -> None:
        super().__init__(name, child, clock)
        self.distance = distance
        self.pose = pose
        self.start: tuple[float, float] = (0.0, 0.0)

    def _here(self) -> tuple[float, float]:
        pose = self.pose()
        return pose.x, pose.y

    def restart(self) -> None:
        self.start = self._here()

    def due(self) -> bool:
        x, y = self._here()
        return math.hypot(x - self.start[0], y - self.start[1]) >= self.distance

    def ticked(self) -> None:
        self.start = self._here()


class SpeedController(_Decorator):
    """Ticks its child at a rate between min_rate and max_rate that grows with the robot's speed
    (between min_speed and max_speed): the rate is chosen anew each time a period ran out, from
    the mean of the two rates at first. A new goal ticks the child at once."""

    def __init__(
        self,
        name: str,
        child: Behaviour,
        clock: Clock,
        rates: tuple[float, float],
        speeds: tuple[float, float],
        speed: Callable[[], float],
        goals: GoalReader,
    ) -> None:
        super().__init__(name, child, clock)
        self.rates, self.speeds = rates, speeds
        self.speed = speed
        self.goals = goals
        self.goal: tuple[Any, ...] = ()
        self.start = 0.0
        self.period = 2.0 / (rates[0] + rates[1])
        self.first = True

    def _period(self) -> float:
        (low, high), (slow, fast) = self.rates, self.speeds
        share = min(max((abs(self.speed()) - slow) / (fast - slow), 0.0), 1.0)
        return 1.0 / (low + share * (high - low))

    def _succeeded(self, status: Status) -> None:
        if status is Status.SUCCESS:
            self.start = self.clock.now()

    def tick(self) -> Iterator[Behaviour]:
        now = self.clock.now()
        if self.fresh(self):
            self.period = 2.0 / (self.rates[0] + self.rates[1])
            self.start, self.first, self.goal = now, True, self.goals()
        goal = self.goals()
        if goal != self.goal:
            self.start, self.first, self.goal = now, True, goal
        elapsed = now - self.start
        if self.first or self.decorated.status is Status.RUNNING or elapsed >= self.period - 1e-9:
            self.first = False
            if elapsed >= self.period - 1e-9:
                self.period = self._period()
            yield from self._tick_child(self._succeeded)
            return
        yield from self._hold()


class GoalUpdatedController(_Decorator):
    """Ticks its child the first time, while it runs, and when the goal (or goals) changed."""

    def __init__(self, name: str, child: Behaviour, clock: Clock, goals: GoalReader) -> None:
        super().__init__(name, child, clock)
        self.goals = goals
        self.goal: tuple[Any, ...] = ()
        self.updated = False

    def tick(self) -> Iterator[Behaviour]:
        if self.fresh(self):
            self.goal = self.goals()
            self.updated = True
        current = self.goals()
        if current != self.goal:
            self.goal, self.updated = current, True
        if self.updated or self.decorated.status is Status.RUNNING:
            self.updated = False
            yield from self._tick_child()
            return
        yield from self._hold()


class SingleTrigger(_Decorator):
    """Ticks its child to completion once per iteration; after that it fails until reset."""

    def __init__(self, name: str, child: Behaviour, clock: Clock) -> None:
        super().__init__(name, child, clock)
        self.first = True

    def tick(self) -> Iterator[Behaviour]:
        if self.fresh(self):
            self.first = True
        if self.first:
            yield from self._tick_child(lambda s: setattr(self, "first", False))
            return
        yield from self._hold(Status.FAILURE)


def path_length(path: list[list[float]]) -> float:
    return sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise(path))


class PathLongerOnApproach(_Decorator):
    """Ticks its child when, near the goal (what is left of the old path is under ``prox_len``),
    a new path to the same goal is more than ``length_factor`` times longer than the old one;
    otherwise it succeeds without it."""

    def __init__(
        self, name: str, child: Behaviour, clock: Clock, path: Callable[[], Any], prox_len: float, factor: float
    ) -> None:
        super().__init__(name, child, clock)
        self.path = path
        self.prox_len, self.factor = prox_len, factor
        self.old: list[list[float]] = []
        self.first = True

    def _longer(self, new: list[list[float]]) -> bool:
        old = self.old
        updated = bool(old) and bool(new) and new != old and list(new[-1][:2]) == list(old[-1][:2])
        return updated and path_length(old) < self.prox_len and path_length(new) > self.factor * path_length(old)

    def tick(self) -> Iterator[Behaviour]:
        if self.fresh(self):
            self.first = True
        new = self.path() or []
        if (self.decorated.status is Status.RUNNING or self._longer(new)) and not self.first:
            yield from self._tick_child(lambda s: setattr(self, "old", new))
            return
        self.old, self.first = new, False
        yield from self._hold(Status.SUCCESS)


class GoalUpdater(_Decorator):
    """Writes the goal (goals) it was given to its outputs, then is its child: botstage has no
    goal topic to take a newer one from."""

    def __init__(self, name: str, child: Behaviour, clock: Clock, copy: Callable[[], None]) -> None:
        super().__init__(name, child, clock)
        self.copy = copy

    def tick(self) -> Iterator[Behaviour]:
        self.copy()
        yield from self._tick_child()


# -- conditions -----------------------------------------------------------------------------


class Every(Behaviour):
    """TimeExpired, DistanceTraveled, PathExpiringTimer: FAILURE when ticked anew (the count
    starts), then SUCCESS each time ``amount()`` has grown by ``every`` since the count started
    (which starts it again). ``restart()`` says whether the count starts over (a new path)."""

    def __init__(
        self,
        name: str,
        clock: Clock,
        amount: Callable[[], float],
        every: float,
        restart: Callable[[], bool] | None = None,
    ) -> None:
        super().__init__(name=name)
        self.fresh = Fresh(clock)
        self.amount = amount
        self.every = every
        self.restart = restart
        self.start = 0.0

    def update(self) -> Status:
        return self.status

    def tick(self) -> Iterator[Behaviour]:
        fresh = self.fresh(self)
        now = self.amount()
        again = self.restart() if self.restart is not None else False
        if fresh or again:
            self.start = now
            self.stop(Status.FAILURE)
        elif now - self.start >= self.every - 1e-9:
            self.start = now
            self.stop(Status.SUCCESS)
        else:
            self.stop(Status.FAILURE)
        yield self


class GoalUpdated(Behaviour):
    """FAILURE when ticked anew (it notes the goal); then SUCCESS once the goal (goals) changed."""

    def __init__(self, name: str, clock: Clock, goals: GoalReader, once: bool = False) -> None:
        super().__init__(name=name)
        self.fresh = Fresh(clock)
        self.goals = goals
        self.once = once  # GlobalUpdatedGoal: noted once for the tree's life, not per iteration
        self.noted = False
        self.goal: tuple[Any, ...] = ()

    def update(self) -> Status:
        return self.status

    def tick(self) -> Iterator[Behaviour]:
        fresh = self.fresh(self)
        current = self.goals()
        if (fresh and not self.once) or not self.noted:
            self.goal, self.noted = current, True
            self.stop(Status.FAILURE)
        elif current != self.goal:
            self.goal = current
            self.stop(Status.SUCCESS)
        else:
            self.stop(Status.FAILURE)
        yield self
