"""Scripted leaves for tick-by-tick tests of control and decorator nodes (BT.CPP's built-ins,
Nav2's): each child returns ``S``, ``F`` or ``R`` per tick (the last repeated) and logs ``A`` when
ticked, ``A!`` when halted while running; ``run`` gives the root's status and that log per tick."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import py_trees
from py_trees.common import Status

from botstage.behaviors.kinds import LeafKind, NodeBuild

LETTERS = {"S": Status.SUCCESS, "F": Status.FAILURE, "R": Status.RUNNING}
LOG: list[str] = []


class _Scripted(py_trees.behaviour.Behaviour):
    def __init__(self, name: str, script: str) -> None:
        super().__init__(name=name)
        self.script = script
        self.ticks = 0

    def update(self) -> Status:
        LOG.append(self.name)
        letter = self.script[min(self.ticks, len(self.script) - 1)]
        self.ticks += 1
        return LETTERS[letter]

    def terminate(self, new_status: Status) -> None:
        if new_status is Status.INVALID and self.status is Status.RUNNING:
            LOG.append(self.name + "!")


class Scripted(LeafKind):
    name = "Scripted"
    description = "a test leaf that returns a scripted status each tick"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        (name, script), *_ = b.value.items()
        return _Scripted(name, script)


def leaf(name: str, script: str) -> dict[str, Any]:
    return {"Scripted": {name: script}, "name": name}


Hook = Callable[[Any, int], None]


def run(engine: Any, spec: dict[str, Any], ticks: int, halt_after: int | None = None, before: Hook | None = None):
    """(status, log) per tick; ``halt_after``: halt the tree after that many ticks; ``before(engine, n)``
    runs before tick n (the goal changes, the robot moves)."""
    engine.set_root(engine.builder().tree(spec))
    got = []
    for n in range(ticks):
        if halt_after is not None and n == halt_after:
            engine.root.stop(Status.INVALID)
            got.append(("halt", " ".join(LOG)))
            LOG.clear()
        if before is not None:
            before(engine, n)
        status = engine.tick()
        got.append((status.value[0], " ".join(LOG)))
        LOG.clear()
    return got


A, B, C = "A", "B", "C"
