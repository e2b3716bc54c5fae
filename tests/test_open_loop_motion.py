"""Skills that drive without a plan (back_up, move, spin) never drive into what the robot's map or
sensors show, and stop at the first contact with what they do not show instead of pushing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from botstage.robots.clock import SimClock
from botstage.robots.interfaces import Pose2D
from botstage.robots.sim.world import inflate
from botstage.skills.move import Move
from botstage.skills.nav.contact import ContactWatch
from botstage.skills.nav.sweep import MARGIN, in_the_way, sweep
from botstage.skills.recoveries import BackUp, Spin
from tests.bench.navsim import NavSim

# the museum's south wall: its last occupied cells are centred on y = -0.175; the PeopleBot is 0.30 m round
SOUTH_WALL_Y = -0.175
RADIUS = 0.30


def untouched(sim: NavSim) -> bool:
    """No bump so far, and the robot's true footprint clear of everything."""
    world = sim.sim.world
    return world.body.bumps == 0 and world.body.contact_steps == 0 and not world.collides(sim.truth.x, sim.truth.y)


def test_back_up_towards_a_wall_stops_short_of_it_without_touching() -> None:
    sim = NavSim("museum", "peoplebot", (5.0, 0.9, math.pi / 2))  # facing north, the wall 1.08 m behind
    outcome = sim.run(BackUp(), distance=1.2, speed=0.25)
    assert outcome.name == "success", outcome.reason
    assert "short of an obstacle on the robot's map" in outcome.reason
    backed = 0.9 - sim.truth.y
    free = 0.9 - SOUTH_WALL_Y - RADIUS  # where the footprint would touch the wall cells' centres
    assert free - 0.035 - MARGIN - 0.05 < backed < free - 0.035  # the room there was, the margin kept
    assert untouched(sim)


def test_back_up_with_a_wall_right_behind_fails_with_a_reason_and_does_not_move() -> None:
    sim = NavSim("museum", "peoplebot", (5.0, 0.16, math.pi / 2))  # a centimetre south would touch
    outcome = sim.run(BackUp(), distance=0.5)
    assert outcome.name == "failure"
    assert outcome.reason.startswith("no room to back up: an obstacle on the robot's map is right behind")
    assert math.hypot(sim.truth.x - 5.0, sim.truth.y - 0.16) < 0.005
    assert untouched(sim)


def test_back_up_checks_the_whole_way_not_only_the_end() -> None:
    """The end point lies beyond exhibit_d's plinth, in the open: the plinth is on the way."""
    sim = NavSim("museum", "peoplebot", (11.0, 7.3, math.pi / 2))  # north of the plinth (y 5.4-6.6), facing away
    assert sim.stack.free(11.0, 7.3 - 3.0)  # the old check, of the end alone, would have let it go
    outcome = sim.run(BackUp(), distance=3.0, speed=0.25, timeout=30)
    assert outcome.name == "success" and "short of an obstacle on the robot's map" in outcome.reason
    assert 6.6 + RADIUS < sim.truth.y < 7.3 - 0.2
    assert untouched(sim)


def test_back_up_into_something_no_map_shows_stops_at_the_first_contact() -> None:
    """A bench the map does not have, behind the robot, where no sensor looks: one bump, no pushing."""
    sim = NavSim("museum", "peoplebot", (5.0, 3.0, math.pi / 2))
    world = sim.sim.world
    bench = np.zeros_like(world.hits)
    row = world.grid.cell(5.0, 2.2)[0]
    col0, col1 = world.grid.cell(4.0, 2.2)[1], world.grid.cell(6.0, 2.2)[1]
    bench[row, col0:col1] = True
    world.blocked |= inflate(bench, math.ceil(world.base.footprint_radius / world.grid.resolution))
    outcome = sim.run(BackUp(), distance=1.2, speed=0.25, timeout=15)
    assert outcome.name == "failure"
    assert "in contact with something" in outcome.reason
    assert world.body.bumps == 1 and world.body.bump_log[0].what == "wall"
    assert world.body.contact_steps <= 3  # it stopped within a few ticks, not at its timeout
    assert sim.clock.now() < 6.0


def test_move_towards_a_wall_ends_short_of_it() -> None:
    sim = NavSim("museum", "peoplebot", (5.0, 1.5, -math.pi / 2))  # facing the south wall
    outcome = sim.run(Move(), v=0.3, duration=10.0)
    assert outcome.name == "success" and "short of an obstacle on the robot's map" in outcome.reason
    assert untouched(sim)
    assert sim.truth.y - SOUTH_WALL_Y - RADIUS < 0.2  # it went most of the way


def test_move_with_no_room_fails_and_a_clear_move_runs_its_whole_time() -> None:
    sim = NavSim("museum", "peoplebot", (5.0, 0.16, -math.pi / 2))
    outcome = sim.run(Move(), v=0.2, duration=2.0)
    assert outcome.name == "failure" and outcome.reason.startswith("no room to move")
    started = sim.clock.now()
    outcome = sim.run(Move(), v=-0.2, w=0.3, duration=2.0)  # backwards and turning: away from the wall
    assert outcome.name == "success" and outcome.reason == ""
    assert sim.clock.now() - started == pytest.approx(2.0, abs=0.11)
    assert untouched(sim)


def test_spin_next_to_a_wall_turns_without_touching() -> None:
    sim = NavSim("museum", "peoplebot", (5.0, 0.17, math.pi / 2))
    outcome = sim.run(Spin(), angle=2 * math.pi)
    assert outcome.name == "success"
    assert untouched(sim)


# -- the sweep's rule --------------------------------------------------------------------------


def test_a_path_may_move_away_or_along_but_not_close_in_within_the_margin() -> None:
    radius, margin = 0.3, 0.05
    away = np.array([0.32, 0.33, 0.36, 0.5])
    along = np.array([0.33, 0.33, 0.325, 0.33])
    closing = np.array([0.5, 0.4, 0.34, 0.3, 0.2])
    inside = np.array([0.25, 0.27, 0.3, 0.4])  # the estimate starts in contact: it may get out
    assert not in_the_way(away, radius, margin).any()
    assert not in_the_way(along, radius, margin).any()
    assert list(np.nonzero(in_the_way(closing, radius, margin))[0]) == [2, 3, 4]
    assert not in_the_way(inside, radius, margin).any()
    assert list(in_the_way(np.array([0.25, 0.2]), radius, margin)) == [False, True]


def test_the_sweep_follows_the_arc_and_says_what_is_in_the_way() -> None:
    sim = NavSim("museum", "peoplebot", (5.0, 1.5, 0.0))
    stack = sim.stack
    straight = sweep(stack, Pose2D(5.0, 1.5, -math.pi / 2), 0.5, 0.0, 4.0)
    assert not straight.clear and straight.blocker == "an obstacle on the robot's map"
    assert straight.at is not None and straight.at[1] < 1.5
    # the wall's cells end 0.025 m north of their centres; a cell's corner is 0.035 m from it
    assert 0.5 * straight.time == pytest.approx(1.5 - SOUTH_WALL_Y - 0.035 - RADIUS - MARGIN, abs=0.03)
    # heading east along the wall, 1.5 m from it: clear; a tight circle to the right meets it
    assert sweep(stack, Pose2D(5.0, 1.5, 0.0), 0.5, 0.0, 4.0).clear
    circle = sweep(stack, Pose2D(5.0, 1.5, 0.0), 0.5, -0.5, 2 * math.pi / 0.5)  # radius 1 m, down to y = -0.5
    assert not circle.clear and 0.0 < circle.time < math.pi / 0.5
    assert sweep(stack, Pose2D(5.0, 0.16, 0.0), 0.0, 1.0, 6.0).clear  # turning in place sweeps nothing


# -- contact from the odometry ---------------------------------------------------------------


class Wheels:
    """A pose that moves as commanded until it is stuck."""

    def __init__(self, clock: SimClock) -> None:
        self.clock = clock
        self.pose = Pose2D(0.0, 0.0, 0.0)
        self.stuck = False
        self.v = 0.0

    def step(self) -> None:
        if not self.stuck:
            self.pose = Pose2D(self.pose.x + self.v * self.clock.period, 0.0, 0.0)


def drive(watch: ContactWatch, wheels: Wheels, v: float, ticks: int) -> list[str | None]:
    reasons = []
    for _ in range(ticks):
        reasons.append(watch.check())
        wheels.v = v
        watch.commanded(v, 0.0)
        wheels.clock.next_tick()
        wheels.step()
    return reasons


def test_the_watch_says_contact_once_the_wheels_stop_under_a_command_and_not_before() -> None:
    clock = SimClock(10)
    wheels = Wheels(clock)
    watch = ContactWatch(lambda: wheels.pose, clock)
    assert drive(watch, wheels, 0.2, 20) == [None] * 20  # moving: never
    wheels.stuck = True
    reasons = drive(watch, wheels, 0.2, 5)
    assert reasons[:2] == [None, None]  # the tick it stopped still shows headway; one tick is not enough
    assert reasons[2] is not None and "in contact" in reasons[2]
    assert drive(watch, wheels, 0.0, 5)[1:] == [None] * 4  # told to stop, it is not pushing


def test_the_watch_gives_a_motion_from_rest_time_to_start_and_ignores_stops() -> None:
    clock = SimClock(10)
    wheels = Wheels(clock)
    wheels.stuck = True  # the wheels take a while: at first nothing moves
    watch = ContactWatch(lambda: wheels.pose, clock)
    assert drive(watch, wheels, 0.0, 10) == [None] * 10  # standing still is not contact
    reasons = drive(watch, wheels, 0.2, 6)
    assert reasons[:3] == [None, None, None]  # within the grace after starting
    assert any(reasons[3:])
