"""A run observer that speaks Groot2's protocol, so Groot2 (or any client of BehaviorTree.CPP's
``Groot2Publisher``) attaches to a running mission: a ZMQ REP socket on ``port`` answers its
requests, a PUB socket on ``port + 1`` tells it when a breakpoint is reached.

Threads. The ZMQ thread answers requests from what the run's thread left for it under a lock:
the tree's XML, the status buffer, a copy of the blackboard (kept from the trace's writes), the
recorded transitions, the hooks. It never touches the engine. A hook is put on its node by the
run's thread, between two ticks (``before_tick``): the node's ``tick`` is wrapped, and when the
node is about to start (its status is not RUNNING as it is ticked) the wrapper tells the client
and, for a breakpoint, holds the run right there, inside its parent's tick and before the node's
own, as BT.CPP's pre-tick hook does, until Groot2 unlocks it. Unlocked with SUCCESS or FAILURE
(or a hook in "replace" mode), the node is not run: it ends at once with that status. Unlike
BT.CPP, a hook fires when its node starts, not on every tick while it runs, and only the PRE
position exists (as in BT.CPP's publisher, whose POST hooks are never called).

As in BT.CPP, Groot2's requests are its heartbeat: when none came for ``heartbeat_s`` (wall
time) every hook is disabled, which lets a held run go; they are enabled again when Groot2 is
back. ZMQ has no authentication here: anyone who reaches the port can hold and steer the run.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any

import py_trees
import zmq
from py_trees.common import Status

from botstage.behaviors.skill_behaviour import SkillBehaviour
from botstage.behaviors.trace import jsonable
from botstage.missions.groot2 import protocol as p
from botstage.missions.groot2.tree import GrootTree, StatusBuffer
from botstage.skills.base import Outcome

if TYPE_CHECKING:
    from botstage.missions.session.result import RunResult
    from botstage.missions.session.session import RunSession

DEFAULT_PORT = 1667
NODE = "groot2"  # the node name of its lines in the trace
MAX_TRANSITIONS = 1000  # kept while recording, as BT.CPP keeps
_POLL_MS = 100
_WAIT_S = 0.25  # how often a held run looks up (a closed publisher lets it go)


class Groot2Error(RuntimeError):
    """The publisher cannot start (a port in use, an address that cannot be bound)."""


class Groot2Publisher:
    """See the module's docstring. ``port`` 0 takes a free pair of ports (``self.port`` says which)."""

    name = "groot2"

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1", heartbeat_s: float = 5.0) -> None:
        self.host = host
        self.heartbeat_s = heartbeat_s
        self.tree_id = p.new_tree_id()
        self.tree: GrootTree | None = None
        self._xml = b""
        self._status: StatusBuffer | None = None
        self._lock = threading.Condition()  # everything both threads share; hooks wait on it
        self._board: dict[str, Any] = {}
        self._hooks: dict[int, p.Hook] = {}
        self._wrapped: dict[int, py_trees.behaviour.Behaviour] = {}  # id(behaviour) -> behaviour
        self._uids_of: dict[int, list[int]] = {}  # id(behaviour) -> the uids whose hooks it answers
        self._recording = False
        self._record_from = 0.0
        self._transitions: deque[bytes] = deque(maxlen=MAX_TRANSITIONS)
        self._t = 0.0  # mission time of the latest event
        self._closed = False
        self._session: RunSession | None = None
        self._thread: threading.Thread | None = None
        self._context = zmq.Context()
        self._server = self._context.socket(zmq.REP)
        self._publisher = self._context.socket(zmq.PUB)
        self._pub_lock = threading.Lock()  # the PUB socket is used by the run's thread only, one send at a time
        for sock in (self._server, self._publisher):
            sock.setsockopt(zmq.LINGER, 0)
            sock.setsockopt(zmq.SNDTIMEO, 1000)
        try:
            self.port = self._bind(port)
        except zmq.ZMQError as exc:
            self._context.destroy(linger=0)
            raise Groot2Error(f"Groot2 cannot listen on {host}:{port} and {port + 1}: {exc}") from None

    def _bind(self, port: int) -> int:
        if port:
            self._server.bind(f"tcp://{self.host}:{port}")
            self._publisher.bind(f"tcp://{self.host}:{port + 1}")
            return port
        for _ in range(50):  # a free port whose successor is free too
            found = self._server.bind_to_random_port(f"tcp://{self.host}", min_port=20000, max_port=60000)
            try:
                self._publisher.bind(f"tcp://{self.host}:{found + 1}")
                return found
            except zmq.ZMQError:
                self._server.unbind(self._server.getsockopt_string(zmq.LAST_ENDPOINT))
        raise zmq.ZMQError(msg="no free pair of ports")

    # -- observer hooks (the run's thread) ------------------------------------------------------

    def started(self, session: RunSession) -> None:
        assert session.root is not None and session.engine is not None
        tree = GrootTree(session.root, session.mission.name)
        board = {key: jsonable(value) for key, value in session.engine.blackboard.snapshot().items()}
        with self._lock:
            self._session = session
            self.tree = tree
            self._xml = tree.xml().encode("utf-8")
            self._status = StatusBuffer(tree)
            self._board.update(board)
            for node in tree.nodes:
                if node.behaviour is not None:
                    self._uids_of.setdefault(id(node.behaviour), []).append(node.uid)
        self._thread = threading.Thread(target=self._serve, name="groot2", daemon=True)
        self._thread.start()

    def event(self, record: Mapping[str, Any]) -> None:
        self._t = record["t"]
        kind = record["ev"]
        if kind == "bb_write":
            value = jsonable(record["new"])
            with self._lock:
                self._board[record["key"]] = value
            return
        tree = self.tree
        if tree is None or kind not in ("status", "transition"):
            return
        changes = list(tree.changes(record))
        if not changes:
            return
        with self._lock:
            assert self._status is not None
            for uid, status in changes:
                self._status.set(uid, status)
                if self._recording:
                    stamp = max(0, round((record["t"] - self._record_from) * 1e6))
                    self._transitions.append(p.pack_transition(stamp, uid, status))

    def before_tick(self, session: RunSession) -> None:
        """Put each new hook on its node: only here, between two ticks, is the tree left alone."""
        tree = self.tree
        if tree is None or not self._hooks:
            return
        with self._lock:
            behaviours = [tree.nodes[uid - 1].behaviour for uid in self._hooks]
        for behaviour in behaviours:
            if behaviour is not None and id(behaviour) not in self._wrapped:
                self._wrap(behaviour)

    def finished(self, session: RunSession, result: RunResult) -> None:
        self.close()

    def close(self) -> None:
        """Stop serving; a run held at a breakpoint goes on. Safe to call more than once."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._lock.notify_all()
        if self._thread is not None:
            self._thread.join()
        self._context.destroy(linger=0)

    # -- breakpoints (the run's thread, inside a tick) -------------------------------------------

    def _wrap(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        original: Callable[[], Iterator[py_trees.behaviour.Behaviour]] = behaviour.tick

        def tick() -> Iterator[py_trees.behaviour.Behaviour]:
            if behaviour.status is not Status.RUNNING:
                desired = self._starting(behaviour)
                if desired is not None:
                    yield from _replaced(behaviour, desired)
                    return
            yield from original()

        behaviour.tick = tick  # type: ignore[method-assign]
        self._wrapped[id(behaviour)] = behaviour

    def _starting(self, behaviour: py_trees.behaviour.Behaviour) -> int | None:
        """``behaviour`` is about to start: a hook on it fires. Returns the status it ends with
        instead of running (SUCCESS or FAILURE), or None to run it as usual."""
        with self._lock:
            hooks = [self._hooks[uid] for uid in self._uids_of.get(id(behaviour), ()) if uid in self._hooks]
            hook = next((h for h in hooks if h.enabled), None)
            if hook is None or self._closed:
                return None
            path = self.tree.nodes[hook.uid - 1].path if self.tree is not None else ""
        held = hook.mode == p.BREAKPOINT
        self._note(f"{'breakpoint' if held else 'replaced'} at {path} (Groot2 uid {hook.uid})")
        with self._pub_lock:
            header = p.RequestHeader.new(p.BREAKPOINT_REACHED).pack()
            with contextlib.suppress(zmq.ZMQError):
                self._publisher.send_multipart([header, str(hook.uid).encode()])
        if held:
            clock = self._session.clock if self._session is not None else None
            _call(clock, "hold")  # a simulation paced in real time: held time is not mission time
            try:
                with self._lock:
                    while not (hook.ready or not hook.enabled or self._closed):
                        self._lock.wait(_WAIT_S)
                    hook.ready = False
                    released = hook.enabled and not self._closed and self._hooks.get(hook.uid) is hook
            finally:
                _call(clock, "release")
            if not released:
                return None
        with self._lock:
            if hook.once and self._hooks.get(hook.uid) is hook:
                del self._hooks[hook.uid]
            desired = hook.desired_status
        if desired in (p.SUCCESS, p.FAILURE):
            self._note(f"{path} ends with {p.STATUS_NAMES[desired]} without running (Groot2)")
            return desired
        if held:
            self._note(f"{path} goes on (Groot2)")
        return None

    def _note(self, message: str) -> None:
        session = self._session
        if session is not None and session.trace is not None:
            session.trace.emit("log", NODE, "info", message)

    # -- requests (the ZMQ thread) ----------------------------------------------------------------

    def _serve(self) -> None:
        server = self._server
        last_request, connected = time.monotonic(), True
        while not self._closed:
            if server.poll(_POLL_MS):
                try:
                    parts = server.recv_multipart()
                except zmq.ZMQError:
                    continue
                last_request = time.monotonic()
                try:
                    reply = self._answer(parts)
                except p.ProtocolError as exc:
                    reply = [b"error", str(exc).encode()]
                with contextlib.suppress(zmq.ZMQError):
                    server.send_multipart(reply)
            alive = time.monotonic() - last_request < self.heartbeat_s
            if alive != connected:  # Groot2 went away, or came back
                connected = alive
                self._enable_all(alive)

    def _answer(self, parts: list[bytes]) -> list[bytes]:
        if not parts:
            raise p.ProtocolError("wrong request header")
        header = p.RequestHeader.unpack(parts[0])
        reply = [p.reply_header(header, self.tree_id)]
        kind = header.type

        def body() -> bytes:
            if len(parts) != 2:
                raise p.ProtocolError("must be 2 parts message")
            return parts[1]

        if kind == p.FULLTREE:
            reply.append(self._xml)
        elif kind == p.STATUS:
            with self._lock:
                reply.append(bytes(self._status.buffer) if self._status is not None else b"")
        elif kind == p.BLACKBOARD:
            reply.append(self._blackboards(body()))
        elif kind == p.HOOK_INSERT:
            found = p.parse_json(body())
            for js in found if isinstance(found, list) else [found]:
                self._insert(p.hook_from_json(js))
        elif kind == p.BREAKPOINT_UNLOCK:
            self._unlock(*p.unlock_from_json(p.parse_json(body())))
        elif kind == p.HOOK_REMOVE:
            self._remove(*p.uid_and_position(p.parse_json(body())))
        elif kind == p.REMOVE_ALL_HOOKS:
            with self._lock:
                for hook in self._hooks.values():
                    hook.enabled = False
                self._hooks.clear()
                self._lock.notify_all()
        elif kind == p.DISABLE_ALL_HOOKS:
            self._enable_all(False)
        elif kind == p.HOOKS_DUMP:
            with self._lock:
                dump = [hook.plain() for hook in self._hooks.values()]
            reply.append(_json(dump))
        elif kind == p.TOGGLE_RECORDING:
            reply += self._toggle_recording(body())
        elif kind == p.GET_TRANSITIONS:
            with self._lock:
                reply.append(b"".join(self._transitions))
                self._transitions.clear()
        else:
            raise p.ProtocolError("Request not recognized")
        return reply

    def _blackboards(self, names: bytes) -> bytes:
        """The blackboards asked for (``name;name``) that exist, as BT.CPP's
        ``generateBlackboardsDump``: MessagePack of ``{name: {key: value}}``. A mission has one
        blackboard, named as its ``<BehaviorTree ID>``: the mission's name."""
        wanted = names.decode("utf-8", errors="replace").split(";")
        with self._lock:
            board = dict(self._board)
        tree_id = self.tree.tree_id if self.tree is not None else None
        return p.msgpack({name: board for name in wanted if name == tree_id})

    def _node(self, uid: int) -> Any:
        tree = self.tree
        if tree is None:
            raise p.ProtocolError("the run has not started yet")
        if not 1 <= uid <= len(tree.nodes):
            raise p.ProtocolError(f"no node with uid {uid} (uids are 1 to {len(tree.nodes)})")
        return tree.nodes[uid - 1]

    def _insert(self, hook: p.Hook) -> None:
        node = self._node(hook.uid)
        if hook.position != p.PRE:
            raise p.ProtocolError("only PRE hooks (position 0) are supported")
        if node.behaviour is None:
            raise p.ProtocolError(
                f"uid {hook.uid} is {node.path!r}, a nested machine or the state holding it: put the hook on one "
                "of its states"
            )
        with self._lock:
            existing = self._hooks.get(hook.uid)
            if existing is None:
                self._hooks[hook.uid] = hook
                return
            interactive = existing.mode == p.BREAKPOINT
            existing.enabled, existing.mode, existing.once = hook.enabled, hook.mode, hook.once
            existing.desired_status = hook.desired_status
            if interactive and existing.mode == p.REPLACE:  # no longer interactive: let it go
                existing.ready = True
            self._lock.notify_all()

    def _unlock(self, uid: int, position: int, desired: int, remove: bool) -> None:
        self._node(uid)
        with self._lock:
            hook = self._hooks.get(uid)
            if hook is None or position != hook.position:
                raise p.ProtocolError("Node ID not found")
            hook.desired_status = desired
            hook.once |= remove
            if hook.mode == p.BREAKPOINT:
                hook.ready = True
                self._lock.notify_all()

    def _remove(self, uid: int, position: int) -> None:
        self._node(uid)
        with self._lock:
            hook = self._hooks.get(uid)
            if hook is None or position != hook.position:
                raise p.ProtocolError("Node ID not found")
            del self._hooks[uid]
            hook.enabled = False  # a run held on it goes on
            self._lock.notify_all()

    def _enable_all(self, enabled: bool) -> None:
        with self._lock:
            for hook in self._hooks.values():
                hook.enabled = enabled
            self._lock.notify_all()

    def _toggle_recording(self, command: bytes) -> list[bytes]:
        """``start``: record transitions from now on (timestamps in mission time since this
        moment; the reply says the moment in microseconds since the epoch, as BT.CPP's does)."""
        if command == b"start":
            with self._lock:
                self._recording, self._record_from = True, self._t
                self._transitions.clear()
            return [str(time.time_ns() // 1000).encode()]
        if command == b"stop":
            with self._lock:
                self._recording = False
            return []
        raise p.ProtocolError(f"recording is 'start' or 'stop', not {command[:40]!r}")


def _replaced(behaviour: py_trees.behaviour.Behaviour, desired: int) -> Iterator[py_trees.behaviour.Behaviour]:
    """The node ends with ``desired`` without running (BT.CPP's substituted pre-tick)."""
    reason = f"{p.STATUS_NAMES[desired].lower()} from Groot2, without running"
    if isinstance(behaviour, SkillBehaviour):  # a machine's state reads the skill's outcome
        success = desired == p.SUCCESS
        names = behaviour.success_on if success else behaviour.skill.all_outcomes - behaviour.success_on
        preferred = "success" if success else "failure"
        behaviour.outcome = Outcome(preferred if preferred in names or not names else min(names), reason)
    behaviour.feedback_message = reason
    behaviour.status = Status.SUCCESS if desired == p.SUCCESS else Status.FAILURE
    yield behaviour


def _call(clock: Any, name: str) -> None:
    method = getattr(clock, name, None)  # a WallClock holds; a SimClock stands still by itself
    if callable(method):
        method()


def _json(value: Any) -> bytes:
    return json.dumps(value).encode("utf-8")
