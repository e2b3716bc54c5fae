"""Hierarchical state machines on ``transitions``' HierarchicalMachine, ticked by the runtime.

Each state runs a skill, a tree or a nested machine; the outcome it ends with names the
transition (SMACH style). A transition may target a sibling state or one of the machine's own
outcomes, which ends the machine (or, for a nested machine, becomes the outcome of its state).
Per-state timeouts run on the mission clock; guards and preemptions are blackboard conditions.
A machine is a py_trees Behaviour, so it can sit inside a tree, and a tree can sit in a state.

Cancellation order: leaving a state (by outcome, timeout or preemption) runs its exit
callback, which halts what runs inside it (skill ``finally`` blocks run) before the next
state is entered.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Any

import py_trees
from py_trees.common import Status
from transitions.extensions.nesting import HierarchicalMachine, NestedState

from botstage.behaviors.blackboard import BlackboardError
from botstage.skills.base import Outcome
from botstage.skills.expression import EvaluationError, Expression, compile_expression

if TYPE_CHECKING:
    from botstage.behaviors.runtime import Runtime

IDLE = "__idle__"
START = "__start__"
HALT = "__halt__"
# A machine that keeps transitioning without anything left RUNNING yields after this many
# transitions in one tick, so time still advances (the machine is not failed for it).
MAX_TRANSITIONS_PER_TICK = 64


class _State(NestedState):
    separator = "/"


class _Machine(HierarchicalMachine):
    state_cls = _State


@dataclass
class Action:
    """An entry/exit action: write a value, or log a line. Runs instantly."""

    kind: str  # "set" or "log"
    key: str = ""
    value: Any = None


@dataclass
class Target:
    """Where an outcome leads. Outcomes that leave nested machines are resolved at build time
    into one direct transition: ``guards`` are the guards met on the way, ``chain`` the
    ``state:outcome`` steps (``work/place:success``, ``work:done``) it stands for."""

    state: str  # full path of the destination (a state, or a top-level outcome pseudo-state)
    guards: tuple[Expression, ...] = ()
    chain: tuple[str, ...] = ()


@dataclass
class Level:
    """One machine level as written: the top level, or the machine nested in a state."""

    prefix: str  # "" for the top level, else the path of the state holding it
    spec_path: tuple[str | int, ...]
    initial: str  # full path of the initial state
    outcomes: list[str]
    names: list[str]  # its states, as written
    preemptions: list[tuple[str, str]] = field(default_factory=list)  # (condition, target) as written

    def full(self, name: str) -> str:
        return f"{self.prefix}/{name}" if self.prefix else name


@dataclass
class StateInfo:
    path: str
    parent: str | None  # path of the enclosing nested-machine state, None at top level
    content: py_trees.behaviour.Behaviour | None = None  # None for nested machines and outcomes
    transitions: dict[str, list[Target]] = field(default_factory=dict)
    # as written, for validation and pictures: outcome -> [(target name, guard source or "")]
    written: dict[str, list[tuple[str, str]]] = field(default_factory=dict)
    possible: frozenset[str] = frozenset()  # the outcomes the state can end with
    kind: str = ""  # skill, tree, machine or outcome
    label: str = ""  # the skill's or tree's name
    spec_path: tuple[str | int, ...] = ()
    level: Level | None = None  # for states holding a nested machine
    timeout: float | None = None
    on_enter: list[Action] = field(default_factory=list)
    on_exit: list[Action] = field(default_factory=list)
    outcome: str | None = None  # set on pseudo-states that stand for a machine outcome
    initial: str | None = None  # for nested machines: path of the initial child
    preemptions: list[tuple[Expression, list[Target]]] = field(default_factory=list)  # nested machines


@dataclass
class MachinePlan:
    """Everything the builder resolved: states by path, top-level structure, outcomes."""

    initial: str
    states: dict[str, StateInfo]
    top: list[str]
    outcomes: list[str]
    preemptions: list[tuple[Expression, list[Target]]]
    level: Level
    success_on: frozenset[str]
    reads: set[str]
    writes: set[str]


class _Model:
    """The object ``transitions`` attaches its state and triggers to."""

    state: str


def outcome_of(node: py_trees.behaviour.Behaviour, kind: str = "skill") -> tuple[str, str]:
    """The outcome a finished node reports to the state holding it.

    A skill state reports the skill's own outcome; a tree state reports success or failure,
    whatever node sits at the tree's root.
    """
    outcome: Outcome | None = getattr(node, "outcome", None)
    if outcome is not None and kind == "skill":
        return outcome.name, outcome.reason
    name = "success" if node.status is Status.SUCCESS else "failure"
    return name, failure_reason(node) if name == "failure" else ""


def failure_reason(node: py_trees.behaviour.Behaviour) -> str:
    """The reason of the deepest failed node under ``node``."""
    reason = node.feedback_message
    current = node
    while True:
        failed = [c for c in current.children if c.status is Status.FAILURE]
        if not failed:
            return reason
        current = failed[-1]
        reason = current.feedback_message or reason


class MachineBehaviour(py_trees.behaviour.Behaviour):
    def __init__(self, name: str, path: str, plan: MachinePlan, runtime: Runtime) -> None:
        super().__init__(name)
        self.path = path
        self.plan = plan
        self.runtime = runtime
        self.outcome: Outcome | None = None
        self.transitions = 0  # taken since the machine was built, for reports and benchmarks
        self.access = runtime.blackboard.client(path, reads=plan.reads, writes=plan.writes)
        self.model = _Model()
        self._entered_at: dict[str, float] = {}
        self._error: str | None = None
        # preemptions by the path of the state whose machine declares them ("" for the top level)
        self._preemptions: dict[str, list[tuple[Expression, list[Target]]]] = {"": plan.preemptions} | {
            path: info.preemptions for path, info in plan.states.items() if info.preemptions
        }
        self._timed = any(info.timeout is not None for info in plan.states.values())
        self._contents = {p: i.content for p, i in plan.states.items() if i.content is not None}
        for content in self._contents.values():
            content.parent = self  # what runs in a state sits under the machine (for preemption order)
        self._watch = self._timed or any(self._preemptions.values())
        self._kinds = {p: i.kind for p, i in plan.states.items()}
        self._machine = self._build_hsm()
        self._trigger = partial(self._machine.trigger_event, self.model)

    # -- construction -----------------------------------------------------------------------

    def _state_config(self, path: str) -> dict[str, Any]:
        info = self.plan.states[path]
        config: dict[str, Any] = {"name": path.rsplit("/", 1)[-1]}
        # Callbacks cost time on every transition: register only those a state needs.
        if info.timeout is not None or info.on_enter:
            config["on_enter"] = [lambda *_a, _p=path: self._entered(_p)]
        if info.on_exit:
            config["on_exit"] = [lambda *_a, _p=path: self._exited(_p)]
        # Outcomes of nested machines are resolved into direct transitions at build time, so
        # only top-level outcomes need to exist as states.
        children = [p for p, s in self.plan.states.items() if s.parent == path and s.outcome is None]
        if children:
            config["children"] = [self._state_config(c) for c in children]
            config["initial"] = info.initial.rsplit("/", 1)[-1] if info.initial else None
        return config

    def _build_hsm(self) -> _Machine:
        plan = self.plan
        states: list[Any] = [IDLE] + [self._state_config(p) for p in plan.top]
        machine = _Machine(
            model=self.model,
            states=states,
            initial=IDLE,
            auto_transitions=False,
            ignore_invalid_triggers=False,
            model_override=False,
        )
        machine.add_transition(START, "*", plan.initial)
        machine.add_transition(HALT, "*", IDLE)
        for path, info in plan.states.items():
            for outcome, targets in info.transitions.items():
                for target in targets:
                    conditions = [self._guard_check(g) for g in target.guards] or None
                    machine.add_transition(f"{path}:{outcome}", path, target.state, conditions=conditions)
        for scope, preemptions in self._preemptions.items():
            sources = list(plan.top) if not scope else [scope]
            for index, (_, targets) in enumerate(preemptions):
                for target in targets:
                    conditions = [self._guard_check(g) for g in target.guards] or None
                    machine.add_transition(
                        f"{scope or '/'}!preempt{index}", sources, target.state, conditions=conditions
                    )
        return machine

    def _guard_check(self, guard: Expression):
        def check(*_args: Any) -> bool:
            return guard.test(self.access.get)

        return check

    # -- transitions callbacks --------------------------------------------------------------

    def _entered(self, path: str) -> None:
        self._entered_at[path] = self.runtime.clock.now()
        self._run_actions(path, self.plan.states[path].on_enter)

    def _exited(self, path: str) -> None:
        self._run_actions(path, self.plan.states[path].on_exit)

    def _halt_content(self) -> None:
        """Halt what runs in the active state (skills inside run their finally now).

        Only the leaf state has content, so this is called right before any transition that
        leaves a state early (timeout, preemption, halt); it leaves before anything is entered.
        """
        content = self._contents.get(self.model.state)
        if content is not None and content.status is Status.RUNNING:
            content.stop(Status.INVALID)

    def _blocked(self, targets: Sequence[Target], what: str) -> bool:
        """True, with the reason in ``_error``, when no guard lets any of ``targets`` be taken.

        Checked before leaving a state, so a transition that cannot happen never cancels anything.
        """
        try:
            for target in targets:
                if not target.guards or all(g.test(self.access.get) for g in target.guards):
                    return False
            self._error = f"{what} but no guard of its transitions holds"
        except (BlackboardError, EvaluationError) as exc:
            self._error = f"{what} but a guard of its transitions cannot be evaluated: {exc}"
        return True

    def _run_actions(self, path: str, actions: Sequence[Action]) -> None:
        for action in actions:
            try:
                if action.kind == "set":
                    self.access.set(action.key, action.value)
                else:
                    self.runtime.log_sink(f"{self.path}/{path}", "info", str(action.value))
            except BlackboardError as exc:
                self._error = self._error or f"action of state {path!r}: {exc}"

    # -- py_trees hooks ---------------------------------------------------------------------

    @property
    def state(self) -> str:
        """The active leaf state's path, or '' when not running."""
        state = self.model.state
        return "" if state == IDLE else state

    def initialise(self) -> None:
        self.outcome = None
        self._error = None
        self._fire(START, "start", "started")

    def update(self) -> Status:  # unused: tick() does the work, as in py_trees composites
        return self.status

    def terminate(self, new_status: Status) -> None:
        if new_status is Status.INVALID:
            self._halt_content()
            if self.outcome is None and self.model.state != IDLE:
                self._fire(HALT, "halt", self.runtime.halt_reason)

    def _fail(self) -> None:
        """End with failure: stop what runs in the active state and leave it (exit actions run)."""
        reason = self._error or "failed"
        with self.runtime.halting(reason):
            self._halt_content()
            self._fire(HALT, "halt", reason)
        self._end(Outcome("failure", reason))

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.status is not Status.RUNNING:
            self.initialise()
        for _ in range(MAX_TRANSITIONS_PER_TICK):
            if self._watch and self.outcome is None and self._error is None:
                self._preempt_or_time_out()
            if self.outcome is None and self._error is None:
                leaf = self.model.state
                content = self._contents[leaf]
                yield from content.tick()
                if content.status is Status.RUNNING:
                    break
                name, reason = outcome_of(content, self._kinds[leaf])
                self._on_outcome(leaf, name, reason)
            if self._error is not None:
                self._fail()
            if self.outcome is not None:
                break
        if self.outcome is not None:
            status = Status.SUCCESS if self.outcome.name in self.plan.success_on else Status.FAILURE
            self.feedback_message = self.outcome.reason or f"ended with outcome {self.outcome.name!r}"
            self.stop(status)
        else:
            self.status = Status.RUNNING
        yield self

    # -- stepping ---------------------------------------------------------------------------

    def _preempt_or_time_out(self) -> None:
        """Take the one preemption or timeout due now, if any.

        Levels are checked from the top down: at each level its preemptions in the order
        written, then the timeout of its active state. A transition that leaves an outer
        state makes any inner one moot, so the outermost wins; at one level a preemption is an
        interrupt and wins over the timeout.
        """
        state = self.model.state
        parts = state.split("/")
        for depth in range(len(parts)):
            if self._preempted("/".join(parts[:depth]), state):
                return
            if self._timed and self._timed_out("/".join(parts[: depth + 1])):
                return

    def _preempted(self, scope: str, state: str) -> bool:
        """Fire the first preemption of ``scope``, in the order written, whose condition holds.

        One whose condition holds while the machine is already in its target keeps it there:
        the preemptions after it wait (two that hold never bounce the machine between their
        targets). One whose way out is guarded (it leads through a guarded transition) does
        not fire while no guard holds: it waits, and the next one is tried.
        """
        for index, (condition, targets) in enumerate(self._preemptions.get(scope, ())):
            try:
                if not condition.test(self.access.get):
                    continue
                if any(_within(state, t.state) for t in targets):
                    return False
                target = self._open(targets)
            except (BlackboardError, EvaluationError) as exc:
                self._error = f"preemption {condition.source!r} cannot be evaluated: {exc}"
                return True
            if target is None:
                continue
            reason = f"preempted: {condition.source!r} holds"
            with self.runtime.halting(reason):
                self._halt_content()
                self._fire(f"{scope or '/'}!preempt{index}", f"preempt {condition.source!r}", reason)
            self._settle(reason)
            return True
        return False

    def _open(self, targets: Sequence[Target]) -> Target | None:
        """The first target whose guards all hold (the one ``transitions`` will take)."""
        for target in targets:
            if all(g.test(self.access.get) for g in target.guards):
                return target
        return None

    def _timed_out(self, path: str) -> bool:
        """Take ``path``'s timeout transition if its timeout is due."""
        timeout = self.plan.states[path].timeout
        if timeout is None or self.runtime.clock.now() - self._entered_at[path] < timeout - 1e-9:
            return False
        reason = f"state {path!r} timed out after {timeout:g} s"
        with self.runtime.halting(reason):
            self._on_outcome(path, "timeout", reason)
        return True

    def _on_outcome(self, path: str, outcome: str, reason: str) -> None:
        info = self.plan.states[path]
        if outcome not in info.transitions:
            handled = ", ".join(sorted(info.transitions)) or "none"
            self._error = (
                f"state {path!r} ended with outcome {outcome!r} but has no transition for it "
                f"(handled: {handled})" + (f"; {reason}" if reason else "")
            )
            return
        targets = info.transitions[outcome]
        if self._blocked(targets, f"state {path!r} ended with {outcome!r}"):
            return
        self._halt_content()  # running only when a timeout ends the state early
        trigger = f"{path}:{outcome}"
        self._fire(trigger, trigger, reason, targets)
        self._settle(reason)

    def _settle(self, reason: str = "") -> None:
        """If the machine now rests on one of its outcomes, it has ended with that outcome."""
        info = self.plan.states.get(self.model.state)
        if info is not None and info.outcome is not None:
            self._end(Outcome(info.outcome, reason))

    def _end(self, outcome: Outcome) -> None:
        self.outcome = outcome

    def _fire(self, trigger: str, label: str, reason: str, targets: Sequence[Target] = ()) -> bool:
        before = self.model.state
        moved = bool(self._trigger(trigger))
        if moved:
            self.transitions += 1
            after = self.model.state
            for target in targets:  # name the outcomes a resolved chain passed through
                lands = after == target.state or after.startswith(target.state + "/")
                if lands and len(target.chain) > 1:
                    label = " > ".join(target.chain)
                    break
            self.runtime.trace.emit(
                "transition",
                self.path,
                "" if before == IDLE else before,
                "" if after == IDLE else after,
                label,
                reason,
            )
        return moved


def plan_access(
    states: Mapping[str, StateInfo], preemptions: Sequence[tuple[Expression, list[Target]]]
) -> tuple[set[str], set[str]]:
    reads: set[str] = set()
    writes: set[str] = set()
    for condition, targets in preemptions:
        reads |= condition.keys
        for target in targets:
            for guard in target.guards:
                reads |= guard.keys
    for info in states.values():
        for targets in info.transitions.values():
            for target in targets:
                for guard in target.guards:
                    reads |= guard.keys
        for action in (*info.on_enter, *info.on_exit):
            if action.kind == "set":
                writes.add(action.key)
        for condition, targets in info.preemptions:
            reads |= condition.keys
            for target in targets:
                for guard in target.guards:
                    reads |= guard.keys
    return reads, writes


def _within(state: str, path: str) -> bool:
    """True when ``state`` is ``path`` or one of its descendants."""
    return state == path or state.startswith(path + "/")


class Unresolved(Exception):
    def __init__(self, state: str, outcome: str, message: str) -> None:
        super().__init__(message)
        self.state = state
        self.outcome = outcome


def resolve_outcome(
    states: Mapping[str, StateInfo],
    local: Mapping[str, Mapping[str, list[Target]]],
    path: str,
    outcome: str,
) -> list[Target]:
    """Follow ``path``'s transitions for ``outcome`` through the outcomes of enclosing machines.

    ``local`` holds each state's transitions as written (targets are siblings or outcomes of
    the enclosing machine). Returns direct targets: states, or top-level outcome pseudo-states.
    The first target whose guards hold is taken, so a later target also carries the negation
    of each earlier one's guards: once an inner choice is made, a blocked outer guard cannot
    fall through to the next inner choice.
    """
    step = f"{path}:{outcome}"
    resolved: list[Target] = []
    earlier_failed: tuple[Expression, ...] = ()
    for target in local[path][outcome]:
        for direct in resolve_target(states, local, target, (step,)):
            resolved.append(Target(direct.state, earlier_failed + direct.guards, direct.chain))
        if not target.guards:
            break  # always taken: later targets can never be reached
        both = " and ".join(f"({g.source})" for g in target.guards)
        earlier_failed += (compile_expression(f"not ({both})"),)
    return resolved


def resolve_target(
    states: Mapping[str, StateInfo],
    local: Mapping[str, Mapping[str, list[Target]]],
    target: Target,
    chain: tuple[str, ...],
) -> list[Target]:
    """A target as written, made direct: an outcome of a nested machine continues outwards."""
    info = states[target.state]
    if info.outcome is None or info.parent is None:
        return [Target(target.state, target.guards, chain)]
    parent = info.parent
    if info.outcome not in local.get(parent, {}):
        raise Unresolved(
            parent, info.outcome, f"state {parent!r} can end with outcome {info.outcome!r} but has no transition for it"
        )
    return [
        Target(outer.state, target.guards + outer.guards, chain + outer.chain)
        for outer in resolve_outcome(states, local, parent, info.outcome)
    ]
