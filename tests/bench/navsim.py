"""Skills on the simulated robot without a mission: a world, the run's services and a context.

The benchmarks and the tests drive navigation and perception skills with it."""

from __future__ import annotations

import random
from typing import Any

from botstage.missions.services import RobotServices
from botstage.robots import PROFILES_DIR
from botstage.robots.clock import SimClock
from botstage.robots.gridmap import GridMap, map_path
from botstage.robots.gridmap import load as load_map
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile, load_profile
from botstage.robots.sim.backend import SimBackend
from botstage.skills.base import Outcome, Skill, SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution
from botstage.skills.testing import DictBoard as Board
from botstage.skills.workers import Workers

MAPS: dict[str, GridMap] = {}


def grid(name: str) -> GridMap:
    if name not in MAPS:
        MAPS[name] = load_map(map_path(name))  # type: ignore[arg-type]
    return MAPS[name]


class NavSim:
    def __init__(
        self,
        world: str | GridMap,
        robot: str | Profile,
        start: str | tuple[float, float, float],
        seed: int = 0,
        people: int = 0,
    ) -> None:
        if isinstance(robot, Profile):
            profile = robot
        else:
            profile, problems, _ = load_profile(PROFILES_DIR / f"{robot}.yaml")
            assert profile is not None, problems
        self.grid = grid(world) if isinstance(world, str) else world
        pose = self.grid.places[start] if isinstance(start, str) else start
        self.clock = SimClock(10)
        self.sim = SimBackend(profile, self.grid, Pose2D(*pose), seed, self.clock, people=people)
        self.services = RobotServices.for_sim(self.sim, self.clock)
        self.step = self.services.after_step(self.sim.step)
        self.board = Board()
        self.logs: list[str] = []
        self.rng = random.Random(seed)
        self.before_step: list[Any] = []  # callables run every tick (scripted people)

    @property
    def stack(self) -> Any:
        return self.services.interfaces["navigation"]

    @property
    def truth(self) -> Pose2D:
        return self.sim.world.body.pose

    def context(self, skill: Skill) -> SkillContext:
        return SkillContext(
            clock=self.clock,
            params=skill.params,
            logger=SkillLogger(skill.name, sink=lambda node, level, message: self.logs.append(f"{level}: {message}")),
            blackboard=self.board,
            workers=Workers(),
            interfaces={**self.sim.devices, **self.services.interfaces},
            rng=self.rng,
        )

    def run(self, skill: Skill, limit: float = 600.0, **inputs: Any) -> Outcome:
        """Run a skill to its end (at most ``limit`` sim seconds), the world moving every tick."""
        execution = SkillExecution(skill, self.context(skill))
        outcome = execution.start(inputs)
        deadline = self.clock.now() + limit
        while outcome is None:
            assert self.clock.now() < deadline, f"{skill.name} still running after {limit} s"
            for hook in self.before_step:
                hook(self)
            self.clock.next_tick()  # as the engine does: the tick is decided, then the world moves over it
            self.step()
            outcome = execution.step()
        return outcome
