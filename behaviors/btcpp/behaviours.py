"""BehaviorTree.CPP v4's built-in nodes as py_trees behaviours, tick for tick.

Each class follows BT.CPP's own ``tick()``/``halt()`` (``src/controls/*.cpp``,
``src/decorators/*.cpp``, ``include/behaviortree_cpp/{actions,decorators}/*.h``), so a tree
imported from XML runs as it would under BT.CPP. Two translations hold throughout:

- BT.CPP's IDLE is py_trees' "not RUNNING": py_trees re-initialises any node that is not RUNNING
  when it is ticked, so BT.CPP's ``resetChildren()`` only has to halt children that still run.
- A tree built by BT.CPP's factory gives every node a wake-up signal (``Tree::initialize``), so
  ``requiresWakeUp()`` is always true: SequenceWithMemory, RetryUntilSuccessful and Repeat return
  RUNNING after a child that completed within the tick (it was IDLE before it), instead of looping.

Time is the run's clock (``runtime.clock``), never the wall clock. BT.CPP's SKIPPED status (from
pre-conditions, ``Precondition`` and ``RunOnce then_skip``) has no py_trees equivalent: a skipped
node ends with SUCCESS and ``skipped`` set (``was_skipped``). BT.CPP's Sequence, Fallback and their
reactive forms here treat it as BT.CPP does (move on, and SKIPPED themselves when every child
was); any other parent sees the SUCCESS, which lets a sequence move on as BT.CPP's would.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import py_trees
from py_trees.common import Status

from botstage.behaviors.blackboard import BlackboardError
from botstage.behaviors.btcpp.script import Script as CompiledScript
from botstage.behaviors.btcpp.script import ScriptRuntimeError
from botstage.behaviors.decorators import ClockTimeout

if TYPE_CHECKING:
    from botstage.behaviors.blackboard import NodeAccess
    from botstage.behaviors.runtime import Runtime

Behaviour = py_trees.behaviour.Behaviour
DONE = (Status.SUCCESS, Status.FAILURE)


def halt(node: Behaviour) -> None:
    """BT.CPP's ``haltChild``: a running node is halted (its skill cancelled), and any node is
    reset to IDLE (INVALID here), as ``src/control_node.cpp`` does for every child."""
    if node.status is not Status.INVALID:
        node.stop(Status.INVALID)


def halt_running(node: Behaviour) -> None:
    """Halt a running node and leave a completed one as it is. Only a reactive control's halting of
    its other children uses it: BT.CPP resets those to IDLE too, but a completed child restarts on
    its next tick anyway, and Nav2's GoalUpdated, which notes the goal when IDLE, must keep what it
    noted across the reactive ticks of a ReactiveFallback (tests/test_nav2_nodes.py)."""
    if node.status is Status.RUNNING:
        node.stop(Status.INVALID)


def was_skipped(node: Behaviour) -> bool:
    """Did the node end its last tick SKIPPED (BT.CPP's status, a SUCCESS to py_trees)?"""
    return node.status is Status.SUCCESS and getattr(node, "skipped", False)


def threshold(value: int, children: int) -> int:
    """BT.CPP's reading of a count where -1 means all children, -2 all but one, ..."""
    return max(children + value + 1, 0) if value < 0 else value


class ControlNode(py_trees.composites.Composite):
    """BT.CPP's ``ControlNode``, the one base of BT.CPP's controls and Nav2's (upstream Nav2's
    controls derive from it too): a control whose whole tick is its own.

    The halt rule is ``src/control_node.cpp``'s: halting the node (``stop(INVALID)`` while it
    runs) halts its running children, resets every child to IDLE and forgets the node's own
    progress (``_reset``, the subclass's ``halt()``). A node only reset to IDLE when it is not
    running keeps its fields, as BT.CPP's ``resetStatus`` does (SequenceWithMemory's index)."""

    def _reset(self) -> None:
        """Forget the node's progress (called when it is halted while running)."""

    def terminate(self, new_status: Status) -> None:
        if new_status is Status.INVALID and self.status is Status.RUNNING:
            self._reset()

    def _reset_children(self) -> None:
        for child in self.children:
            halt(child)

    def _end(self, status: Status) -> Iterator[Behaviour]:
        self._reset_children()
        self.stop(status)
        yield self

    def _running(self) -> Iterator[Behaviour]:
        self.status = Status.RUNNING
        yield self


class Sequence(ControlNode):
    """Sequence and Fallback, with or without memory.

    ``carry_on`` is the status that moves to the next child (SUCCESS for a sequence, FAILURE for a
    fallback). Without memory (Sequence, Fallback) the other completed status resets the node to its
    first child; with memory (SequenceWithMemory) it stays on the child that failed, halting only
    from there on, and a halt does not reset it either (BT.CPP leaves ``current_child_idx_`` alone).
    """

    def __init__(self, name: str, children: list[Behaviour], carry_on: Status, memory: bool = False) -> None:
        super().__init__(name=name, children=list(children))
        self.carry_on = carry_on
        self.memory = memory
        self.index = 0
        self.skipped_count = 0
        self.skipped = False

    def _reset(self) -> None:
        if not self.memory:
            self.index = 0

    def tick(self) -> Iterator[Behaviour]:
        count = len(self.children)
        self.skipped = False
        if self.status is not Status.RUNNING:
            self.skipped_count = 0
        while self.index < count:
            child = self.current_child = self.children[self.index]
            before = child.status
            yield from child.tick()
            status = child.status
            if was_skipped(child):
                self.index += 1
                self.skipped_count += 1
                continue
            if status is Status.RUNNING:
                yield from self._running()
                return
            if status is not self.carry_on:
                if self.memory:
                    for later in self.children[self.index :]:
                        halt(later)
                    self.stop(status)
                    yield self
                else:
                    self.index = 0
                    yield from self._end(status)
                return
            self.index += 1
            if self.memory and before is not Status.RUNNING and self.index < count:
                yield from self._running()  # the wake-up rule: one synchronous child per tick
                return
        self.index = 0
        all_skipped = self.skipped_count == count
        yield from self._end(Status.SUCCESS if all_skipped else self.carry_on)
        self.skipped = all_skipped


class Reactive(ControlNode):
    """ReactiveSequence and ReactiveFallback: every tick from the first child; a child that runs
    halts every other, the first child that ends the node (``decisive``) halts the rest."""

    def __init__(self, name: str, children: list[Behaviour], decisive: Status) -> None:
        super().__init__(name=name, children=list(children))
        self.decisive = decisive
        self.skipped = False

    def tick(self) -> Iterator[Behaviour]:
        self.skipped = False
        skipped = 0
        for index, child in enumerate(self.children):
            self.current_child = child
            yield from child.tick()
            if was_skipped(child):
                skipped += 1
                continue
            if child.status is Status.RUNNING:
                for other, sibling in enumerate(self.children):
                    if other != index:
                        halt_running(sibling)
                yield from self._running()
                return
            if child.status is self.decisive:
                yield from self._end(self.decisive)
                return
        all_skipped = skipped == len(self.children)
        yield from self._end(Status.SUCCESS if all_skipped or self.decisive is Status.FAILURE else Status.FAILURE)
        self.skipped = all_skipped


class Parallel(ControlNode):
    """Every child that has not completed is ticked; SUCCESS at ``success_count`` successes, FAILURE
    at ``failure_count`` failures or when success became impossible (checked after each child)."""

    def __init__(self, name: str, children: list[Behaviour], success_count: int, failure_count: int) -> None:
        super().__init__(name=name, children=list(children))
        self.success_count = success_count
        self.failure_count = failure_count
        self.completed: set[int] = set()
        self.successes = 0
        self.failures = 0

    def _reset(self) -> None:
        self.completed.clear()
        self.successes = self.failures = 0

    def tick(self) -> Iterator[Behaviour]:
        count = len(self.children)
        need_success = threshold(self.success_count, count)
        need_failure = threshold(self.failure_count, count)
        for index, child in enumerate(self.children):
            if index not in self.completed:
                self.current_child = child
                yield from child.tick()
                if child.status in DONE:
                    self.completed.add(index)
                    if child.status is Status.SUCCESS:
                        self.successes += 1
                    else:
                        self.failures += 1
            if self.successes >= need_success:
                self._reset()
                yield from self._end(Status.SUCCESS)
                return
            if count - self.failures < need_success or self.failures == need_failure:
                self._reset()
                yield from self._end(Status.FAILURE)
                return
        yield from self._running()


class ParallelAll(ControlNode):
    """Every child runs to completion; then FAILURE if at least ``max_failures`` failed."""

    def __init__(self, name: str, children: list[Behaviour], max_failures: int) -> None:
        super().__init__(name=name, children=list(children))
        self.max_failures = max_failures
        self.completed: set[int] = set()
        self.failures = 0

    def _reset(self) -> None:
        self.completed.clear()
        self.failures = 0

    def tick(self) -> Iterator[Behaviour]:
        for index, child in enumerate(self.children):
            if index in self.completed:
                continue
            self.current_child = child
            yield from child.tick()
            if child.status in DONE:
                self.completed.add(index)
                self.failures += child.status is Status.FAILURE
        if len(self.completed) < len(self.children):
            yield from self._running()
            return
        failed = self.failures >= threshold(self.max_failures, len(self.children))
        self._reset()
        yield from self._end(Status.FAILURE if failed else Status.SUCCESS)


class IfThenElse(ControlNode):
    """The condition (first child) is ticked until it completes, then the branch it chose runs to
    completion without the condition being ticked again; no else branch means FAILURE."""

    def __init__(self, name: str, children: list[Behaviour]) -> None:
        super().__init__(name=name, children=list(children))
        self.branch = 0

    def _reset(self) -> None:
        self.branch = 0

    def tick(self) -> Iterator[Behaviour]:
        if self.branch == 0:
            condition = self.current_child = self.children[0]
            yield from condition.tick()
            if condition.status is Status.RUNNING:
                yield from self._running()
                return
            if condition.status is Status.SUCCESS:
                self.branch = 1
            elif len(self.children) == 3:
                self.branch = 2
            else:
                yield from self._end(Status.FAILURE)
                return
        branch = self.current_child = self.children[self.branch]
        yield from branch.tick()
        if branch.status is Status.RUNNING:
            yield from self._running()
            return
        self.branch = 0
        yield from self._end(branch.status)


class WhileDoElse(ControlNode):
    """The condition is ticked every tick; it picks the branch to tick, halting the other one."""

    def tick(self) -> Iterator[Behaviour]:
        condition = self.current_child = self.children[0]
        yield from condition.tick()
        if condition.status is Status.RUNNING:
            yield from self._running()
            return
        three = len(self.children) == 3
        if condition.status is Status.SUCCESS:
            if three:
                halt(self.children[2])
            branch = self.children[1]
        elif three:
            halt(self.children[1])
            branch = self.children[2]
        else:
            yield from self._end(Status.FAILURE)
            return
        self.current_child = branch
        yield from branch.tick()
        if branch.status is Status.RUNNING:
            yield from self._running()
            return
        yield from self._end(branch.status)


class Switch(ControlNode):
    """The child of the first case equal to the blackboard value (the last child by default);
    a different case than the running one halts it first."""

    def __init__(
        self, name: str, children: list[Behaviour], variable: Any, cases: list[str | None], access: NodeAccess
    ) -> None:
        super().__init__(name=name, children=list(children))
        self.variable = variable  # a key name (str wrapped by the kind) or a literal
        self.cases = cases
        self.access = access
        self.running: int = -1

    def _reset(self) -> None:
        self.running = -1

    def _value(self) -> str | None:
        ref = self.variable
        if isinstance(ref, BoundKey):
            try:
                return as_text(self.access.get(ref.key))
            except BlackboardError:
                return None  # BT.CPP: no variable, jump to the default
        return ref

    def tick(self) -> Iterator[Behaviour]:
        value = self._value()
        match = len(self.cases)
        if value is not None:
            for index, case in enumerate(self.cases):
                if case is not None and same_text(value, case):
                    match = index
                    break
        if self.running not in (-1, match):
            halt(self.children[self.running])
        child = self.current_child = self.children[match]
        yield from child.tick()
        if child.status is Status.RUNNING:
            self.running = match
            yield from self._running()
            return
        self.running = -1
        yield from self._end(child.status)


class BoundKey:
    """A port bound to a blackboard key (as opposed to a literal)."""

    __slots__ = ("key",)

    def __init__(self, key: str) -> None:
        self.key = key


def as_text(value: Any) -> str:
    """A blackboard value as BT.CPP's ``toStr`` writes it (booleans are ``true``/``false``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def same_text(value: str, case: str) -> bool:
    """BT.CPP's CheckStringEquality without enums: equal strings, or equal numbers."""
    if value == case:
        return True
    try:
        return float(value) == float(case)
    except ValueError:
        return False


# -- decorators -----------------------------------------------------------------------------


class _Decorator(py_trees.decorators.Decorator):
    """A decorator whose whole tick is its own (BT.CPP's DecoratorNode)."""

    def _reset(self) -> None:
        """Forget the node's progress (called when it is halted)."""

    def terminate(self, new_status: Status) -> None:
        if new_status is Status.INVALID:
            self._reset()

    def update(self) -> Status:
        return self.status

    def _end(self, status: Status) -> Iterator[Behaviour]:
        halt(self.decorated)
        self.stop(status)
        yield self

    def _running(self) -> Iterator[Behaviour]:
        self.status = Status.RUNNING
        yield self

    def _fail(self, why: str) -> Iterator[Behaviour]:
        self.feedback_message = why
        yield from self._end(Status.FAILURE)


class Loop(_Decorator):
    """RetryUntilSuccessful (``until`` SUCCESS: a failure is retried) and Repeat (``until``
    FAILURE: a success is repeated), ``times`` attempts or cycles, -1 forever.

    A child that completes after it was RUNNING is started again in the same tick; one that
    completes within its first tick makes the node return RUNNING (BT.CPP's wake-up rule)."""

    def __init__(self, name: str, child: Behaviour, times: Number, until: Status) -> None:
        super().__init__(name=name, child=child)
        self.times = times
        self.until = until
        self.count = 0
        self.limit = 0

    def _reset(self) -> None:
        self.count = 0

    def _more(self) -> bool:
        return self.count < self.limit or self.limit == -1

    def tick(self) -> Iterator[Behaviour]:
        child = self.decorated
        if self.status is not Status.RUNNING:
            try:
                self.limit = self.times.read()
            except (BlackboardError, ValueError) as exc:
                yield from self._fail(str(exc))
                return
        looping = self._more()
        while looping:
            before = child.status
            yield from child.tick()
            if child.status is Status.RUNNING:
                yield from self._running()
                return
            if child.status is self.until:
                self.count = 0
                yield from self._end(self.until)
                return
            self.count += 1
            looping = self._more()
            if before is not Status.RUNNING and looping:
                yield from self._running()
                return
        self.count = 0
        yield from self._end(Status.FAILURE if self.until is Status.SUCCESS else Status.SUCCESS)


class RunOnce(_Decorator):
    """The child runs to completion once; afterwards its result again (``then_skip`` false) or,
    ``then_skip`` true, SUCCESS: BT.CPP returns SKIPPED there, which py_trees has not, and a
    skipped node lets a Sequence move on as a success would. Not reset by a halt (as in BT.CPP)."""

    def __init__(self, name: str, child: Behaviour, then_skip: bool) -> None:
        super().__init__(name=name, child=child)
        self.then_skip = then_skip
        self.result: Status | None = None
        self.skipped = False

    def tick(self) -> Iterator[Behaviour]:
        self.skipped = False
        if self.result is not None:
            self.stop(Status.SUCCESS if self.then_skip else self.result)
            self.skipped = self.then_skip
            yield self
            return
        yield from self.decorated.tick()
        status = self.decorated.status
        if status is Status.RUNNING:
            yield from self._running()
            return
        self.result = status
        yield from self._end(status)


class Delay(_Decorator):
    """RUNNING for ``seconds`` of run time from its first tick, then the child's status; a halt or
    the child's completion starts the wait again."""

    def __init__(self, name: str, child: Behaviour, msec: Number, runtime: Runtime) -> None:
        super().__init__(name=name, child=child)
        self.msec = msec
        self.runtime = runtime
        self.ready_at: float | None = None

    def _reset(self) -> None:
        self.ready_at = None

    def tick(self) -> Iterator[Behaviour]:
        now = self.runtime.clock.now()
        if self.ready_at is None:
            try:
                seconds = self.msec.read(minimum=0) / 1000
            except (BlackboardError, ValueError) as exc:
                yield from self._fail(str(exc))
                return
            self.ready_at = now + seconds - 1e-9
            yield from self._running()  # the timer fires after this tick at the earliest
            return
        if now < self.ready_at:
            yield from self._running()
            return
        yield from self.decorated.tick()
        if self.decorated.status is Status.RUNNING:
            yield from self._running()
            return
        self.ready_at = None
        yield from self._end(self.decorated.status)


class PassThrough(_Decorator):
    """A Timeout of 0 ms: BT.CPP starts no timer, so the child's status passes through."""

    def tick(self) -> Iterator[Behaviour]:
        yield from self.decorated.tick()
        if self.decorated.status is Status.RUNNING:
            yield from self._running()
            return
        yield from self._end(self.decorated.status)


# -- leaves ---------------------------------------------------------------------------------


class Constant(Behaviour):
    """AlwaysSuccess and AlwaysFailure."""

    def __init__(self, name: str, result: Status) -> None:
        super().__init__(name=name)
        self.result = result

    def update(self) -> Status:
        return self.result


class Sleep(Behaviour):
    """RUNNING until ``seconds`` of run time have passed since its first tick, then SUCCESS;
    0 succeeds at once."""

    def __init__(self, name: str, msec: Number, runtime: Runtime) -> None:
        super().__init__(name=name)
        self.msec = msec
        self.runtime = runtime
        self.seconds = 0.0
        self.until = 0.0
        self.problem = ""

    def initialise(self) -> None:
        self.problem = ""
        try:
            self.seconds = self.msec.read(minimum=0) / 1000
        except (BlackboardError, ValueError) as exc:
            self.problem = str(exc)
        self.until = self.runtime.clock.now() + self.seconds - 1e-9

    def update(self) -> Status:
        if self.problem:
            self.feedback_message = self.problem
            return Status.FAILURE
        if self.seconds <= 0:
            return Status.SUCCESS
        if self.status is not Status.RUNNING:
            return Status.RUNNING  # the first tick starts the timer
        return Status.RUNNING if self.runtime.clock.now() < self.until else Status.SUCCESS


class SetBlackboard(Behaviour):
    """Write ``value`` (a literal, or the value of another key) to ``output_key``; SUCCESS."""

    def __init__(self, name: str, value: Any, output_key: str, access: NodeAccess) -> None:
        super().__init__(name=name)
        self.value = value
        self.output_key = output_key
        self.access = access

    def update(self) -> Status:
        value = self.value
        try:
            if isinstance(value, BoundKey):
                value = self.access.get(value.key)
            self.access.set(self.output_key, value)
        except BlackboardError as exc:
            self.feedback_message = str(exc)
            return Status.FAILURE
        return Status.SUCCESS


# -- values read when a node starts -----------------------------------------------------------


class Number:
    """A number port: a literal, or ``{key}`` read from the blackboard when the node starts
    (BT.CPP reads such ports in ``tick()``/``onStart()``); a key's text is read as a number."""

    __slots__ = ("access", "key", "value")

    def __init__(self, value: int | BoundKey, access: NodeAccess | None = None) -> None:
        self.value = value
        self.key = value.key if isinstance(value, BoundKey) else None
        self.access = access

    def read(self, minimum: int = -1) -> int:
        if self.key is None or self.access is None:
            return int(self.value)  # type: ignore[arg-type]
        raw = self.access.get(self.key)
        try:
            if isinstance(raw, bool):
                raise ValueError
            number = float(raw.strip()) if isinstance(raw, str) else float(raw)
            if not number.is_integer() or number < minimum:
                raise ValueError
        except (TypeError, ValueError):
            raise ValueError(f"{{{self.key}}} holds {raw!r}, not a whole number ≥ {minimum}") from None
        return int(number)

    def __str__(self) -> str:
        return str(self.value) if self.key is None else "{" + self.key + "}"


class KeyedTimeout(ClockTimeout):
    """BT.CPP's Timeout whose ``msec`` is ``{key}``: read when the child starts."""

    def __init__(self, name: str, child: Behaviour, msec: Number, runtime: Runtime) -> None:
        super().__init__(name=name, child=child, duration=0.0, runtime=runtime)
        self.msec = msec
        self.problem = ""

    def initialise(self) -> None:
        self.problem = ""
        try:
            msec = self.msec.read(minimum=0)
        except (BlackboardError, ValueError) as exc:
            self.problem, msec = str(exc), 0
        self.duration = msec / 1000 if msec else float("inf")  # 0: no timeout, as in BT.CPP
        super().initialise()

    def tick(self) -> Iterator[Behaviour]:
        if self.status is not Status.RUNNING:
            self.initialise()
            if self.problem:
                self.feedback_message = self.problem
                self.stop(Status.FAILURE)
                yield self
                return
        yield from super().tick()


# -- scripts ------------------------------------------------------------------------------------


class BoundScript:
    """A compiled script bound to the blackboard: its names mapped to (remapped) keys."""

    __slots__ = ("access", "keys", "script")

    def __init__(self, script: CompiledScript, keys: dict[str, str], access: NodeAccess) -> None:
        self.script = script
        self.keys = keys
        self.access = access

    @property
    def source(self) -> str:
        return self.script.source

    def exists(self, name: str) -> bool:
        return self.access.exists(self.keys[name])

    def get(self, name: str) -> Any:
        return self.access.get(self.keys[name])

    def set(self, name: str, value: Any) -> None:
        self.access.set(self.keys[name], value)

    def run(self) -> Any:
        return self.script.run(self)

    def check(self) -> bool:
        return self.script.check(self)


SCRIPT_ERRORS = (ScriptRuntimeError, BlackboardError, ArithmeticError)


class Script(Behaviour):
    """BT.CPP's Script: run ``code``; SUCCESS. A script that fails to run is a FAILURE with its
    reason (BT.CPP throws, which stops the whole tree)."""

    def __init__(self, name: str, code: BoundScript) -> None:
        super().__init__(name=name)
        self.code = code

    def update(self) -> Status:
        try:
            self.code.run()
        except SCRIPT_ERRORS as exc:
            self.feedback_message = f"script {self.code.source!r}: {exc}"
            return Status.FAILURE
        return Status.SUCCESS


class ScriptCondition(Script):
    """BT.CPP's ScriptCondition: SUCCESS if ``code`` is true, else FAILURE."""

    def update(self) -> Status:
        try:
            return Status.SUCCESS if self.code.check() else Status.FAILURE
        except SCRIPT_ERRORS as exc:
            self.feedback_message = f"script {self.code.source!r}: {exc}"
            return Status.FAILURE


class UnsetBlackboard(Behaviour):
    """BT.CPP's UnsetBlackboard: remove ``key``; SUCCESS whether or not it was there."""

    def __init__(self, name: str, key: str, access: NodeAccess) -> None:
        super().__init__(name=name)
        self.key = key
        self.access = access

    def update(self) -> Status:
        self.access.unset(self.key)
        return Status.SUCCESS


SKIPPED = "SKIPPED"  # BT.CPP's status, for the `else` of Precondition


class Precondition(_Decorator):
    """BT.CPP's Precondition: ``if`` is checked before the child starts; false returns ``else``
    (FAILURE by default; SKIPPED is a skipped SUCCESS); once the child runs, it is not re-checked."""

    def __init__(self, name: str, child: Behaviour, condition: BoundScript, otherwise: Status | str) -> None:
        super().__init__(name=name, child=child)
        self.condition = condition
        self.otherwise = otherwise
        self.skipped = False

    def tick(self) -> Iterator[Behaviour]:
        self.skipped = False
        if self.decorated.status is not Status.RUNNING:
            try:
                go = self.condition.check()
            except SCRIPT_ERRORS as exc:
                yield from self._fail(f"if {self.condition.source!r}: {exc}")
                return
            if not go:
                if self.otherwise is Status.RUNNING:
                    yield from self._running()
                    return
                yield from self._end(Status.SUCCESS if self.otherwise == SKIPPED else self.otherwise)  # type: ignore[arg-type]
                self.skipped = self.otherwise == SKIPPED
                return
        yield from self.decorated.tick()
        if self.decorated.status is Status.RUNNING:
            yield from self._running()
            return
        yield from self._end(self.decorated.status)


class PrePost(_Decorator):
    """The pre- and post-condition attributes BT.CPP allows on any node (``tree_node.cpp``),
    around the node they were written on.

    Before a tick, if the node is idle (not RUNNING): ``_failureIf`` true gives FAILURE,
    ``_successIf`` true SUCCESS, ``_skipIf`` true or ``_while`` false SKIPPED, without ticking it
    (checked in that order, BT.CPP's). While it runs, ``_while`` false halts it: SKIPPED. After
    it: ``_onSuccess`` or ``_onFailure`` by its status, then ``_post`` (every tick). A halt of the
    running node runs ``_onHalted``. SKIPPED is a SUCCESS with ``skipped`` set; the node stays idle."""

    PRE = ("_failureIf", "_successIf", "_skipIf", "_while")

    def __init__(self, name: str, child: Behaviour, scripts: dict[str, BoundScript]) -> None:
        super().__init__(name=name, child=child)
        self.scripts = scripts
        self.skipped = False

    def _pre(self) -> Status | str | None:
        """The status a pre-condition decides, or None to tick the node."""
        idle = self.decorated.status is not Status.RUNNING
        for attr in self.PRE:
            script = self.scripts.get(attr)
            if script is None:
                continue
            if idle:
                true = script.check()
                if true and attr != "_while":
                    return {"_failureIf": Status.FAILURE, "_successIf": Status.SUCCESS}.get(attr, SKIPPED)
                if not true and attr == "_while":
                    return SKIPPED
            elif attr == "_while" and not script.check():
                self._halt_node()
                return SKIPPED
        return None

    def _halt_node(self) -> None:
        if self.decorated.status is Status.RUNNING:
            halt(self.decorated)
            self._run("_onHalted")

    def _run(self, attr: str) -> None:
        script = self.scripts.get(attr)
        if script is not None:
            script.run()

    def tick(self) -> Iterator[Behaviour]:
        self.skipped = False
        try:
            decided = self._pre()
        except SCRIPT_ERRORS as exc:
            yield from self._fail(f"pre-condition: {exc}")
            return
        if decided is None:
            yield from self.decorated.tick()
            decided = self.decorated.status
        try:
            if decided is Status.SUCCESS:
                self._run("_onSuccess")
            elif decided is Status.FAILURE:
                self._run("_onFailure")
            self._run("_post")
        except SCRIPT_ERRORS as exc:
            yield from self._fail(f"post-condition: {exc}")
            return
        if decided is Status.RUNNING:
            yield from self._running()
            return
        yield from self._end(Status.SUCCESS if decided == SKIPPED else decided)  # type: ignore[arg-type]
        self.skipped = decided == SKIPPED

    def terminate(self, new_status: Status) -> None:
        if new_status is Status.INVALID and self.status is Status.RUNNING:
            try:
                self._halt_node()
            except SCRIPT_ERRORS as exc:
                self.feedback_message = f"_onHalted: {exc}"
