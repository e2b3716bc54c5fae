"""The operator's hand on a run: pause, resume, step, breakpoints, forced outcomes, key writes and
the e-stop.

Requests come from the web server's threads: each is checked there (a clear refusal at once) and
queued; the run's thread carries them out between two ticks (``before_tick``), where touching the
engine is safe, and holds the run there while it is paused. Every action goes into the trace as a
log line of node ``monitor``; forced outcomes are ordinary ``skill_outcome`` events and written
keys ``bb_write`` events of writer ``monitor``, so a run steered by hand replays as a scenario.

Pausing holds the simulation's clock (nothing moves in the simulated world while paused; a
simulation paced in real time has its wall clock held too), so it needs a simulated world; a real
robot's world does not pause: there, the e-stop is the way to stop it.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import py_trees

from botstage.behaviors.blackboard import normalise_key
from botstage.behaviors.machine import MachineBehaviour
from botstage.behaviors.skill_behaviour import SkillBehaviour
from botstage.missions.monitor.hub import OPERATOR, Hub
from botstage.missions.steering import ESTOP, ESTOP_RELEASED, TELEOP_ENDED, drive_one_step, stop_everything, teleop_note
from botstage.skills.base import Outcome, Skill, check_type
from botstage.skills.expression import Expression, ExpressionError, compile_expression

if TYPE_CHECKING:
    from botstage.missions.session.session import RunSession

NODE = OPERATOR
BREAK_KINDS = ("state", "node", "transition", "condition")
ESTOP_REASON = ESTOP
_WAIT_S = 0.25  # how often a held run looks up from waiting (Ctrl-C, a stopped server)
TELEOP_WATCHDOG_S = 0.5  # the robot stops when the page's teleop commands stop for this long (wall time)


class ControlError(ValueError):
    """A request the run cannot carry out, said in the operator's terms."""


class MalformedCommand(ControlError):
    """A request that is wrong whatever the run's state (a teleop speed that is not a number)."""


@dataclass
class Breakpoint:
    id: int
    kind: str
    target: str
    condition: Expression | None = None
    was_true: bool = False

    def plain(self) -> dict[str, Any]:
        return {"id": self.id, "kind": self.kind, "target": self.target}


@dataclass
class Targets:
    """What a request may name, learned when the run starts."""

    skills_by_path: dict[str, type[Skill]] = field(default_factory=dict)
    skills_by_name: dict[str, type[Skill]] = field(default_factory=dict)
    states: set[str] = field(default_factory=set)
    key_types: Mapping[str, Any] = field(default_factory=dict)


class Control:
    """See the module's docstring. ``simulated``: whether the run's clock can be held."""

    def __init__(self, hub: Hub, simulated: bool) -> None:
        self.hub = hub
        self.simulated = simulated
        self.targets = Targets()
        self._queue: queue.SimpleQueue[Callable[[RunSession], None]] = queue.SimpleQueue()
        self._wake = threading.Event()
        self._lock = threading.Lock()
        self._breakpoints: list[Breakpoint] = []
        self._next_id = 1
        self.paused = False
        self.estopped = False
        self._steps = 0
        self._hit = ""  # a breakpoint hit during the tick: the run holds before the next one
        self.closed = False
        self._emit: Callable[[str], None] = lambda message: hub.note("control", message)  # the trace, once attached
        self._teleop: tuple[float, float, float] | None = None  # v, w, wall-clock deadline
        self.teleop_state: dict[str, Any] = {"active": False, "v": 0.0, "w": 0.0}
        # called while the run is held: as the hold begins, after the operator's actions and after
        # each teleoperated step (the map, the camera and what teleop may do follow)
        self.on_change: Callable[[RunSession], None] = lambda session: None

    # -- the server's threads: check, then queue ------------------------------------------------

    def request(self, body: Mapping[str, Any]) -> str:
        """Check one request and queue it; returns what will happen, or raises ``ControlError``."""
        action = body.get("action")
        handlers: dict[str, Callable[[Mapping[str, Any]], str]] = {
            "pause": self._pause,
            "resume": self._resume,
            "step": self._step,
            "estop": self._estop,
            "release": self._release,
            "break": self._break,
            "unbreak": self._unbreak,
            "force": self._force,
            "write": self._write,
        }
        handler = handlers.get(action) if isinstance(action, str) else None
        if handler is None:
            raise ControlError(f"unknown action {action!r} (actions: {', '.join(handlers)})")
        if self.hub.flags.ended:
            raise ControlError("the run has ended")
        message = handler(body)
        self._wake.set()
        return message

    def _need_sim(self, what: str) -> None:
        if not self.simulated:
            raise ControlError(
                f"{what} needs a simulated run (its clock is held while paused); a real robot's world "
                "does not pause: use the e-stop"
            )

    def _pause(self, body: Mapping[str, Any]) -> str:
        self._need_sim("pausing")
        self._queue.put(self._pause_now)
        return "pausing before the next tick"

    def _resume(self, body: Mapping[str, Any]) -> str:
        if self.estopped:
            raise ControlError("the e-stop is on: release it first")
        self._queue.put(lambda s: self._go())
        return "resuming"

    def _step(self, body: Mapping[str, Any]) -> str:
        self._need_sim("stepping")
        if self.estopped:
            raise ControlError("the e-stop is on: release it first")
        self._queue.put(self._one_step)
        return "one tick"

    def _estop(self, body: Mapping[str, Any]) -> str:
        self._queue.put(self._stop_everything)
        return "e-stop: every skill cancelled, the drive stopped, the run held"

    def _release(self, body: Mapping[str, Any]) -> str:
        self._queue.put(self._release_estop)
        return "e-stop released: the mission starts again from its root"

    def _break(self, body: Mapping[str, Any]) -> str:
        self._need_sim("a breakpoint")
        kind, target = body.get("kind"), body.get("target")
        if kind not in BREAK_KINDS:
            raise ControlError(f"unknown breakpoint kind {kind!r} (kinds: {', '.join(BREAK_KINDS)})")
        if not isinstance(target, str) or not target.strip():
            raise ControlError("a breakpoint needs a target")
        target = target.strip()
        condition = None
        if kind == "condition":
            try:
                condition = compile_expression(target)
            except ExpressionError as exc:
                raise ControlError(f"not a condition: {exc}") from None
        elif kind == "state" and target not in self.targets.states:
            raise ControlError(
                f"no state {target!r} in this mission (states are named by path, e.g. "
                f"{next(iter(sorted(self.targets.states)), 'main/machine/state')})"
            )
        with self._lock:
            point = Breakpoint(self._next_id, kind, target, condition)
            self._next_id += 1
            self._breakpoints.append(point)
            self._publish_breakpoints()
        return f"breakpoint {point.id} on {kind} {target}"

    def _unbreak(self, body: Mapping[str, Any]) -> str:
        wanted = body.get("id")
        with self._lock:
            kept = [b for b in self._breakpoints if b.id != wanted]
            if len(kept) == len(self._breakpoints):
                raise ControlError(f"no breakpoint {wanted!r}")
            self._breakpoints = kept
            self._publish_breakpoints()
        return f"breakpoint {wanted} removed"

    def _publish_breakpoints(self) -> None:
        self.hub.set_breakpoints([b.plain() for b in self._breakpoints])

    def _force(self, body: Mapping[str, Any]) -> str:
        target, name, outputs = body.get("node"), body.get("outcome"), body.get("outputs") or {}
        if not isinstance(target, str) or not target:
            raise ControlError("force needs a node: a node's path or a skill's name")
        skill = self.targets.skills_by_path.get(target) or self.targets.skills_by_name.get(target)
        if skill is None:
            raise ControlError(f"no skill node or skill {target!r} in this mission")
        if name not in skill.all_outcomes:
            raise ControlError(
                f"{skill.name} has no outcome {name!r} (outcomes: {', '.join(sorted(skill.all_outcomes))})"
            )
        if not isinstance(outputs, Mapping):
            raise ControlError("outputs must be an object of the skill's output ports")
        checked: dict[str, Any] = {}
        for port, value in outputs.items():
            declared = skill.outputs.get(port)
            if declared is None:
                have = ", ".join(skill.outputs) or "none"
                raise ControlError(f"{skill.name} has no output {port!r} (outputs: {have})")
            try:
                checked[port] = check_type(declared.type, value, finite=True)
            except TypeError as exc:
                raise ControlError(f"output {port!r}: {exc}") from None
        outcome = Outcome(name, "forced by the operator (monitor)", checked)
        self._queue.put(lambda s: self._apply_force(s, target, outcome))
        return f"{target} ends with {name} when it next ticks"

    def _write(self, body: Mapping[str, Any]) -> str:
        key, value = body.get("key"), body.get("value")
        if not isinstance(key, str) or not key:
            raise ControlError("write needs a key")
        try:
            key = normalise_key(key)
        except ValueError as exc:
            raise ControlError(str(exc)) from None
        declared = self.targets.key_types.get(key)
        if declared is not None:
            try:
                value = check_type(declared, value, finite=True)
            except TypeError as exc:
                raise ControlError(f"key {key!r}: {exc}") from None
        self._queue.put(lambda s: self._apply_write(s, key, value))
        return f"{key} = {value!r} before the next tick"

    def teleop_allowed(self) -> tuple[bool, str]:
        """Whether the page may drive the robot now, and if not why (the page shows it)."""
        if self.hub.flags.ended:
            return False, "the run has ended"
        if not self.simulated:
            return False, "teleop from the page drives a simulated robot (a real one: botstage teleop)"
        if self.estopped:
            return False, "the e-stop is on: release it first"
        if not self.paused:
            return False, "teleop takes over only while the run is paused: pause it first"
        return True, ""

    def teleop(self, v: Any, w: Any) -> str:
        """A teleop command from the page: held for ``TELEOP_WATCHDOG_S``, then the robot stops."""
        if not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in (v, w)):
            raise MalformedCommand(f"teleop needs finite numbers v (m/s) and w (rad/s), got v={v!r} w={w!r}")
        allowed, why = self.teleop_allowed()
        if not allowed:
            raise ControlError(why)
        with self._lock:
            self._teleop = (float(v), float(w), time.monotonic() + TELEOP_WATCHDOG_S)
        self._wake.set()
        return f"driving v={v:.2f} m/s w={w:.2f} rad/s" if v or w else "stopped"

    # -- the run's thread ---------------------------------------------------------------------

    def started(self, session: RunSession) -> None:
        assert session.root is not None and session.engine is not None
        targets = self.targets
        for node in skill_nodes(session.root):
            targets.skills_by_path[node.path] = type(node.skill)
            targets.skills_by_name.setdefault(node.skill.name, type(node.skill))
        targets.key_types = dict(session.engine.blackboard.declared)
        targets.states = set(_paths_of_kind(self.hub.structure, "state"))

    def before_tick(self, session: RunSession) -> None:
        """Carry out what was asked; then hold the run while it is paused (or e-stopped)."""
        self._run_queued(session)
        if self._hit:
            self._hold(self._hit)
            self._hit = ""
        held = self.paused or self.estopped
        if held:
            self.on_change(session)
            _hold(session.clock)  # a simulation paced in real time: held time is not mission time
        while (self.paused or self.estopped) and not self.closed:
            if self._steps > 0 and not self.estopped:
                self._steps -= 1
                break
            if self._teleop is not None and not self.estopped:
                self._teleop_step(session)
            else:
                self._wake.wait(_WAIT_S)
                self._wake.clear()
            if self._run_queued(session):
                self.on_change(session)
        self._end_teleop(session)
        if held:
            _release(session.clock)

    def event(self, record: Mapping[str, Any]) -> None:
        """A breakpoint on a state, a node or a transition holds the run after this tick."""
        if not self._breakpoints or self._hit:
            return
        ev = record["ev"]
        if ev not in ("transition", "status"):
            return
        for point in self._breakpoints:
            if point.kind == "state" and ev == "transition":
                entered = f"{record['machine']}/{record['dest']}"
                left = f"{record['machine']}/{record['source']}" if record["source"] else ""
                if _within(entered, point.target) and not _within(left, point.target):
                    self._hit = f"breakpoint {point.id}: entered state {point.target}"
            elif point.kind == "transition" and ev == "transition" and _transition_matches(record, point.target):
                self._hit = f"breakpoint {point.id}: transition {point.target}"
            elif point.kind == "node" and ev == "status" and _started(record, point.target):
                self._hit = f"breakpoint {point.id}: node {point.target} started"
            if self._hit:
                return

    def after_tick(self, session: RunSession) -> None:
        """Condition breakpoints: hold when one becomes true."""
        points = [b for b in self._breakpoints if b.condition is not None]
        if not points:
            return
        assert session.engine is not None
        board = session.engine.blackboard
        for point in points:
            assert point.condition is not None
            try:
                now = point.condition.test(lambda key: board.get(key))
            except Exception:  # a key not written yet: not true yet
                now = False
            if now and not point.was_true and not self._hit:
                self._hit = f"breakpoint {point.id}: {point.target}"
            point.was_true = now

    def _teleop_step(self, session: RunSession) -> None:
        """One period of the held run's world under the page's command: the drive is told, the
        simulated world moves and the clock with it (the tree does not tick), paced in real time."""
        with self._lock:
            command = self._teleop
        if command is None:
            return
        v, w, deadline = command
        if time.monotonic() > deadline:  # the page went quiet: the watchdog stops the robot
            v = w = 0.0
        drive, backend = session.interfaces.get("drive"), session.backend
        if drive is None or backend is None:
            self._end_teleop(session)
            return
        state = self.teleop_state
        if not state["active"] or (state["v"], state["w"]) != (v, w):
            self._trace_note(teleop_note(v, w))  # each new command: a replay drives as this run did
        _release(session.clock)  # the world driven by hand moves in mission time
        drive_one_step(session, v, w)
        _hold(session.clock)
        self.hub.set_flags(t=session.clock.now())  # mission time moves on with the world, the tree held
        self.teleop_state = {"active": True, "v": v, "w": w}
        self.on_change(session)
        if v == 0.0 and w == 0.0:
            self._end_teleop(session)
        elif session.clock.simulated:
            self._wake.wait(session.clock.period)  # a simulated world driven by hand moves at its own pace
            self._wake.clear()

    def _end_teleop(self, session: RunSession) -> None:
        with self._lock:
            driven, self._teleop = self._teleop is not None, None
        if driven and self.teleop_state["active"]:
            drive = session.interfaces.get("drive")
            if drive is not None:
                drive.stop()
            self.teleop_state = {"active": False, "v": 0.0, "w": 0.0}
            self._trace_note(TELEOP_ENDED)
            self.on_change(session)

    def close(self) -> None:
        """The run is over (or the monitor goes): nothing holds it any more."""
        self.closed = True
        self._wake.set()

    # -- carrying out (the run's thread) --------------------------------------------------------

    def _run_queued(self, session: RunSession) -> bool:
        """Carry out what was asked since last time; whether there was anything."""
        done = False
        while True:
            try:
                action = self._queue.get_nowait()
            except queue.Empty:
                return done
            action(session)
            done = True

    def _hold(self, reason: str) -> None:
        if not self.paused:
            self._trace_note(reason)
        self.paused, self._steps = True, 0
        self.hub.set_flags(paused=True, pause_reason=reason)

    def _pause_now(self, session: RunSession) -> None:
        if self.simulated:
            self._hold("paused by the operator")
        else:  # asked before the run said it drives a real robot (`--paused` on hardware)
            self.hub.note("control", "not paused: a real robot's world does not pause (use the e-stop)")

    def _go(self) -> None:
        if self.paused:
            self._trace_note("resumed by the operator")
        self.paused = False
        self.hub.set_flags(paused=False, pause_reason="")

    def _one_step(self, session: RunSession) -> None:
        if not self.paused:
            self._hold("paused by the operator (step)")
        self._steps += 1

    def _stop_everything(self, session: RunSession) -> None:
        if self.estopped:
            return
        self.estopped = True
        self._trace_note(ESTOP_REASON)
        stop_everything(session, ESTOP_REASON)
        self.hub.set_flags(estopped=True, paused=True, pause_reason=ESTOP_REASON)

    def _release_estop(self, session: RunSession) -> None:
        if not self.estopped:
            return
        self.estopped = False
        self._trace_note(ESTOP_RELEASED)
        self.hub.set_flags(
            estopped=False, paused=self.paused, pause_reason="paused by the operator" if self.paused else ""
        )

    def _apply_force(self, session: RunSession, target: str, outcome: Outcome) -> None:
        assert session.engine is not None
        session.engine.forces[target] = outcome
        self._trace_note(f"forcing {target} to end with {outcome.name} {dict(outcome.outputs) or ''}".rstrip())

    def _apply_write(self, session: RunSession, key: str, value: Any) -> None:
        assert session.engine is not None
        try:
            session.engine.blackboard.set(key, value, writer=NODE)
        except Exception as exc:  # checked on request; a race with a declaration is still said
            self.hub.note("control", f"write {key} refused: {exc}")

    def _trace_note(self, message: str) -> None:
        """An action into the trace (the pages see it from there, as a control entry)."""
        self._emit(message)

    def attach(self, emit: Callable[[str], None]) -> None:
        """Where the operator's actions go in the trace (a log line of node ``monitor``)."""
        self._emit = emit


def skill_nodes(root: py_trees.behaviour.Behaviour) -> Iterator[SkillBehaviour]:
    """Every skill node under ``root``, the ones in machines' states included."""
    for node in root.iterate():
        if isinstance(node, SkillBehaviour):
            yield node
        elif isinstance(node, MachineBehaviour):
            for info in node.plan.states.values():
                if info.content is not None:
                    yield from skill_nodes(info.content)


def _paths_of_kind(item: Mapping[str, Any], kind: str) -> Iterator[str]:
    if item.get("kind") == kind:
        yield item["path"]
    for child in item.get("children", ()):
        yield from _paths_of_kind(child, kind)


def _hold(clock: Any) -> None:
    hold = getattr(clock, "hold", None)  # a WallClock; a SimClock stands still by itself
    if callable(hold):
        hold()


def _release(clock: Any) -> None:
    release = getattr(clock, "release", None)
    if callable(release):
        release()


def _started(record: Mapping[str, Any], node: str) -> bool:
    return record["node"] == node and record["new"] == "RUNNING" and record["old"] != "RUNNING"


def _within(state: str, target: str) -> bool:
    return bool(state) and (state == target or state.startswith(target + "/"))


def _transition_matches(record: Mapping[str, Any], target: str) -> bool:
    """``SOURCE->DEST`` (state paths, full or relative to their machine; ``*`` for any) or an
    outcome's trigger as the trace names it (``listening:heard``)."""
    if "->" not in target:
        return record["trigger"] == target or record["trigger"].endswith(" > " + target)
    source, _, dest = (part.strip() for part in target.partition("->"))
    machine = record["machine"] + "/"

    def same(pattern: str, state: str) -> bool:
        return pattern == "*" or pattern in (state, machine + state if state else "")

    return same(source, record["source"]) and same(dest, record["dest"])
