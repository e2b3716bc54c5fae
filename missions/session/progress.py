"""The live progress a command line shows while a mission runs, as an observer of the run."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import py_trees
from py_trees.common import Status

from botstage.behaviors.machine import MachineBehaviour
from botstage.behaviors.skill_behaviour import SkillBehaviour

if TYPE_CHECKING:
    from botstage.missions.session.session import RunSession


@dataclass
class Progress:
    """What the live display shows; built on demand, a few times a second at most."""

    mission: str
    sim_time_s: float
    wall_time_s: float
    ticks: int
    state: str
    running: list[str]


ProgressCallback = Callable[[Callable[[], Progress]], None]


def running_skills(node: py_trees.behaviour.Behaviour) -> list[str]:
    """Paths of the skills running now, looking inside machine states too."""
    found: list[str] = []
    stack = [node]
    while stack:
        current = stack.pop()
        if current.status is not Status.RUNNING:
            continue
        if isinstance(current, SkillBehaviour):
            found.append(current.path)
        elif isinstance(current, MachineBehaviour):
            content = current.plan.states.get(current.model.state)
            if content is not None and content.content is not None:
                stack.append(content.content)
        else:
            stack.extend(reversed(current.children))
    return found


class ProgressObserver:
    """Hands ``show`` a snapshot maker every ``interval_s`` of wall time, and after the last tick."""

    name = "progress"

    def __init__(self, show: ProgressCallback, interval_s: float = 0.1) -> None:
        self.show = show
        self.interval_s = interval_s
        self._next = 0.0

    def after_tick(self, session: RunSession) -> None:
        now = time.monotonic()
        if now >= self._next or session.ending:
            self._next = now + self.interval_s
            self.show(lambda: snapshot(session))


def snapshot(session: RunSession) -> Progress:
    root = session.root
    state = root.state if isinstance(root, MachineBehaviour) else ""
    clock = session.clock
    return Progress(
        session.mission.name,
        clock.now(),
        time.perf_counter() - session.started_at,
        clock.ticks,
        state,
        running_skills(root) if root is not None else [],
    )
