"""Run observers: what watches a run (the summary, the transcript, the report, a live monitor, a
recorder, a Groot2 publisher) without being part of its loop, as BehaviorTree.CPP's
StatusChangeLogger and py_trees' visitors and pre/post tick handlers do.

Every hook is optional: an observer defines only those it needs, and ``event`` is subscribed to
the trace only when defined (each event then becomes a dict). In phase order:

- ``started(session)``: the mission is built, nothing has ticked yet;
- ``event(record)``: every trace event, as ``{tick, t, ev, ...fields}`` (read-only; cannot stop a run);
- ``before_tick(session)`` / ``after_tick(session)``: around every tick (after the world moved and
  the services updated); ``before_tick`` may raise ``StopRun`` to end the run;
- ``finished(session, result)``: after shut-down; it may add blocks to ``result.summary`` and
  files to the run folder (listed under ``artefacts``).

An observer that is not built in and raises is detached and its error is listed under
``observer_errors`` in summary.json: it never takes the run down.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from botstage.missions.session.errors import StopRun

if TYPE_CHECKING:
    from botstage.behaviors.trace import Trace

HOOKS = ("started", "event", "before_tick", "after_tick", "finished")


class RunObserver(Protocol):
    """Any object with some of the hooks above (and, optionally, a ``name`` for messages)."""


class _Guard:
    """Calls an external observer's hooks; its first error detaches it and is recorded."""

    def __init__(self, observer: object, errors: list[str]) -> None:
        self.observer = observer
        self.errors = errors
        self.failed = False

    def wrap(self, hook: str, call: Callable[..., Any]) -> Callable[..., Any]:
        def guarded(*args: Any) -> None:
            if self.failed:
                return
            try:
                call(*args)
            except StopRun:
                raise
            except Exception as exc:
                self.failed = True
                name = getattr(self.observer, "name", "") or type(self.observer).__name__
                self.errors.append(f"{name}.{hook}: {type(exc).__name__}: {exc}")

        return guarded


class Hooks:
    """The hooks of a run's observers, per hook name, in the order the observers were added."""

    def __init__(self) -> None:
        self.calls: dict[str, list[Callable[..., Any]]] = {hook: [] for hook in HOOKS}
        self.errors: list[str] = []

    def add(self, observer: object, *, guarded: bool = False) -> None:
        guard = _Guard(observer, self.errors) if guarded else None
        for hook in HOOKS:
            call = getattr(observer, hook, None)
            if callable(call):
                self.calls[hook].append(guard.wrap(hook, call) if guard is not None else call)

    def subscribe(self, trace: Trace) -> None:
        """Give every ``event`` hook the trace's events (nothing is subscribed when none has one)."""
        for call in self.calls["event"]:
            trace.subscribe(call)

    def run(self, hook: str, *args: Any) -> None:
        for call in self.calls[hook]:
            call(*args)
