"""Simulated people: individuals who walk and stop, and groups who gather, stay and leave.

A person walks in straight lines towards goals on free floor (a new goal when the next step
would hit something), pauses now and then, and joins a group when one forms. A group of 2 to 6
meets at a gathering point, each member standing 0.3 to 0.6 m from the point (so every member is
within 1.5 m of another, the paper's crowd definition), stays a while, then disperses. People
keep clear of the robot: a step that would touch it waits or goes around. All
randomness comes from the world's generator: the same seed gives the same people.

A scripted walker (a mission's ``walks:``, ``add_walk``) is a person who walks a given path and
nothing else: standing at its first point until the walk's time, then from point to point at the
walk's speed, ``repeat`` times round (from the last point back to the first between rounds),
``pause`` s at each point, and standing at the last point once done. Walkers draw nothing from the
generator, never join a group and are never sent elsewhere when blocked (they wait, or step
round the robot), so adding one leaves everyone else's walk as it was, and the same walk is
walked the same way run after run. Their time is exact: a walk that sets off at 2.0 s is moving
from 2.0 s, whatever the tick.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from botstage.robots.backend import ScriptedWalk
from botstage.robots.gridmap import FREE, GridMap
from botstage.robots.sim.world import inflate

PERSON_RADIUS = 0.25


@dataclass
class Person:
    id: int
    x: float
    y: float
    speed: float
    goal: tuple[float, float]
    pause_until: float = 0.0
    group: int | None = None
    route: Route | None = None  # a scripted walker's path: it walks only that


@dataclass
class Route:
    """Where a scripted walker goes: its points in order (rounds included), the next one, and how
    long it stands at each."""

    points: list[tuple[float, float]]
    pause: float = 0.0
    next: int = 1

    @property
    def done(self) -> bool:
        return self.next >= len(self.points)


def standable(grid: GridMap) -> np.ndarray:
    """Where a person's centre may be: free floor at least ``PERSON_RADIUS`` from anything else."""
    return ~inflate(grid.data != FREE, math.ceil(PERSON_RADIUS / grid.resolution))


def first_blocked(
    grid: GridMap, path: list[tuple[float, float]], room: np.ndarray | None = None
) -> tuple[int, float, float] | None:
    """Where a walk along ``path`` first leaves room for a person: (k, x, y), ``k`` the index of the
    point walked towards there (0: the first point itself has no room); None when all is clear."""
    room = standable(grid) if room is None else room

    def clear(x: float, y: float) -> bool:
        row, col = grid.cell(x, y)
        return grid.inside(row, col) and bool(room[row, col])

    if not clear(*path[0]):
        return 0, path[0][0], path[0][1]
    # two points of the map are never farther apart than its diagonal: a longer leg leaves the map
    # within that distance, so no more of it is walked (a point 1e308 m away must not overflow)
    span = math.hypot(grid.width, grid.height) * grid.resolution + grid.resolution
    for k, ((ax, ay), (bx, by)) in enumerate(itertools.pairwise(path), start=1):
        length = math.hypot(bx - ax, by - ay)
        if length > span:
            bx, by = ax + (bx - ax) / length * span, ay + (by - ay) / length * span
            length = span
        steps = max(1, math.ceil(length / (grid.resolution / 2)))
        for step in range(1, steps + 1):
            x, y = ax + (bx - ax) * step / steps, ay + (by - ay) * step / steps
            if not clear(x, y):
                return k, x, y
    return None


@dataclass
class Group:
    id: int
    centre: tuple[float, float]
    members: list[int]
    spots: dict[int, tuple[float, float]]
    leave_at: float = math.inf  # set once everyone has arrived
    arrived: bool = False
    stay: float | None = None  # s once all are there; None: a random 30-120 s


@dataclass
class Crowd:
    grid: GridMap
    rng: np.random.Generator
    people: list[Person] = field(default_factory=list)
    groups: list[Group] = field(default_factory=list)
    next_group_at: float = 5.0
    time: float = 0.0
    robot: Callable[[], tuple[float, float]] | None = None  # where the robot is, to keep clear of it
    robot_radius: float = 0.0
    scripted: list[tuple[float, tuple[float, float], int, float]] = field(default_factory=list)  # time, at, size, stay
    _next_id: int = 1

    def __post_init__(self) -> None:
        self.standable = standable(self.grid)
        self._free_cells = np.argwhere(self.standable)

    @classmethod
    def populate(
        cls,
        grid: GridMap,
        rng: np.random.Generator,
        count: int,
        avoid: tuple[float, float] | None = None,
        keep_away: float = 1.0,
    ) -> Crowd:
        crowd = cls(grid, rng)
        for _ in range(count):
            x, y = crowd.random_spot(avoid, keep_away)
            crowd.people.append(Person(crowd._new_id(), x, y, float(rng.uniform(0.6, 1.3)), crowd.random_spot()))
        return crowd

    def _new_id(self) -> int:
        self._next_id += 1
        return self._next_id - 1

    def random_spot(self, avoid: tuple[float, float] | None = None, keep_away: float = 0.0) -> tuple[float, float]:
        for _ in range(1000):
            row, col = self._free_cells[self.rng.integers(len(self._free_cells))]
            x, y = self.grid.point(int(row), int(col))
            if avoid is None or math.hypot(x - avoid[0], y - avoid[1]) >= keep_away:
                return x, y
        raise ValueError("no free floor for a person on this map")

    def can_stand(self, x: float, y: float) -> bool:
        row, col = self.grid.cell(x, y)
        return self.grid.inside(row, col) and bool(self.standable[row, col])

    def positions(self) -> np.ndarray:
        """Everyone's centre, as an (n, 2) array: what the world sees as moving obstacles."""
        return np.array([(p.x, p.y) for p in self.people], dtype=float).reshape(-1, 2)

    def _clear_of_robot(self, person: Person, x: float, y: float) -> bool:
        """A step may not bring a person into touch with the robot (stepping away is fine)."""
        if self.robot is None:
            return True
        rx, ry = self.robot()
        keep = self.robot_radius + PERSON_RADIUS + 0.05
        after = math.hypot(x - rx, y - ry)
        return after >= keep or after >= math.hypot(person.x - rx, person.y - ry)

    def _can_step(self, person: Person, x: float, y: float) -> bool:
        return self.can_stand(x, y) and self._clear_of_robot(person, x, y)

    # -- stepping ---------------------------------------------------------------------------

    def step(self, dt: float) -> None:
        self.time += dt
        if self.time >= self.next_group_at:
            self._form_group()
            self.next_group_at = self.time + float(self.rng.uniform(20.0, 60.0))
        for cue in [c for c in self.scripted if self.time >= c[0]]:
            self.scripted.remove(cue)
            if not self.gather(*cue[1:]):  # too few people free yet (in groups of their own): retry
                self.scripted.append((self.time + 1.0, *cue[1:]))
        for group in self.groups:
            if not group.arrived and all(self._at(self._person(m), group.spots[m]) for m in group.members):
                group.arrived = True
                stay = group.stay if group.stay is not None else float(self.rng.uniform(30.0, 120.0))
                group.leave_at = self.time + stay
        for group in [g for g in self.groups if self.time >= g.leave_at]:
            self.groups.remove(group)
            for member in group.members:
                person = self._person(member)
                person.group = None
                person.goal = self.random_spot()
        for person in self.people:
            if person.route is not None:
                self._follow(person, dt)
            else:
                self._walk(person, dt)

    def _person(self, pid: int) -> Person:
        return next(p for p in self.people if p.id == pid)

    @staticmethod
    def _at(person: Person, spot: tuple[float, float]) -> bool:
        return math.hypot(person.x - spot[0], person.y - spot[1]) < 0.05

    def add_walk(self, walk: ScriptedWalk) -> Person:
        """A scripted walker for ``walk`` (see the module), standing at its first point until it sets off."""
        if len(walk.path) < 2 or walk.repeat < 1 or not walk.speed > 0:
            raise ValueError("a walk needs two points or more, a speed above 0 and at least one round")
        points = [(float(x), float(y)) for x, y in walk.path] * walk.repeat
        x, y = points[0]
        person = Person(self._new_id(), x, y, walk.speed, points[1], pause_until=walk.at)
        person.route = Route(points, walk.pause)
        self.people.append(person)
        return person

    def _follow(self, person: Person, dt: float) -> None:
        """A walker's step: along its route for the part of ``dt`` it is not standing still."""
        route = person.route
        assert route is not None
        left = min(dt, self.time - person.pause_until)  # it may set off (or walk on) within this step
        while left > 1e-12 and not route.done:
            gx, gy = route.points[route.next]
            dx, dy = gx - person.x, gy - person.y
            distance = math.hypot(dx, dy)
            if distance < 1e-9:  # there: on to the next point, after the pause
                route.next += 1
                if not route.done:
                    person.goal = route.points[route.next]
                if route.pause:
                    person.pause_until = self.time - left + route.pause
                    left = min(left, self.time - person.pause_until)
                continue
            stride = min(person.speed * left, distance)
            nx, ny = person.x + dx / distance * stride, person.y + dy / distance * stride
            if not self._can_step(person, nx, ny):
                person.x, person.y = self._sidestep(person, dx / distance, dy / distance, stride)  # or wait
                return
            person.x, person.y = (gx, gy) if stride == distance else (nx, ny)
            left -= stride / person.speed

    def _form_group(self) -> None:
        free = [p for p in self.people if p.group is None and p.route is None]
        if len(free) < 2:
            return
        size = int(self.rng.integers(2, min(6, len(free)) + 1))
        centre = self.random_spot()
        spots = self._spots_around(centre, size)
        if spots is None:
            return
        order = self.rng.permutation(len(free))
        # a group that cannot all arrive (someone stuck behind an obstacle) breaks up after 90 s
        self._assemble(centre, [free[int(i)] for i in order[:size]], spots, leave_at=self.time + 90.0, stay=None)

    def gather(self, centre: tuple[float, float], size: int, stay: float = 120.0) -> bool:
        """The ``size`` nearest free people walk to ``centre`` and stay ``stay`` s once all are
        there (a scripted gathering); False when there are too few free people or no room."""
        free = sorted(
            (p for p in self.people if p.group is None and p.route is None),
            key=lambda p: math.hypot(p.x - centre[0], p.y - centre[1]),
        )
        spots = self._spots_around(centre, size) if len(free) >= size else None
        if spots is None:
            return False
        self._assemble(centre, free[:size], spots, leave_at=math.inf, stay=stay)
        return True

    def _assemble(
        self,
        centre: tuple[float, float],
        members: list[Person],
        spots: list[tuple[float, float]],
        leave_at: float,
        stay: float | None,
    ) -> None:
        group = Group(self._new_id(), centre, [m.id for m in members], {}, leave_at=leave_at, stay=stay)
        for member, spot in zip(members, spots, strict=True):
            member.group = group.id
            member.goal = spot
            member.pause_until = 0.0
            group.spots[member.id] = spot
        self.groups.append(group)

    def _spots_around(self, centre: tuple[float, float], size: int) -> list[tuple[float, float]] | None:
        start = float(self.rng.uniform(0, 2 * math.pi))
        spots = []
        for k in range(size):
            angle = start + 2 * math.pi * k / size
            radius = float(self.rng.uniform(0.3, 0.6))
            spot = (centre[0] + radius * math.cos(angle), centre[1] + radius * math.sin(angle))
            if not self.can_stand(*spot):
                return None
            spots.append(spot)
        return spots

    def _walk(self, person: Person, dt: float) -> None:
        if self.time < person.pause_until:
            return
        gx, gy = person.goal
        dx, dy = gx - person.x, gy - person.y
        distance = math.hypot(dx, dy)
        if distance < 0.05:
            person.x, person.y = gx, gy
            if person.group is None:  # an individual pauses, then walks on
                person.pause_until = self.time + float(self.rng.uniform(0.0, 8.0))
                person.goal = self.random_spot()
            return
        stride = min(person.speed * dt, distance)
        nx, ny = person.x + dx / distance * stride, person.y + dy / distance * stride
        if self._can_step(person, nx, ny):
            person.x, person.y = nx, ny
        elif not self._clear_of_robot(person, nx, ny):
            person.x, person.y = self._sidestep(person, dx / distance, dy / distance, stride)  # or wait
        elif person.group is None:
            person.goal = self.random_spot()  # blocked: pick somewhere else
        else:
            person.goal = (gx, gy)  # wait and retry: group spots are reachable floor
            person.x, person.y = self._sidestep(person, dx / distance, dy / distance, stride)

    def _sidestep(self, person: Person, ux: float, uy: float, stride: float) -> tuple[float, float]:
        for turn in (math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2):
            c, s = math.cos(turn), math.sin(turn)
            nx, ny = person.x + (c * ux - s * uy) * stride, person.y + (s * ux + c * uy) * stride
            if self._can_step(person, nx, ny):
                return nx, ny
        return person.x, person.y
