"""Path following in the simulator (true pose; localisation comes separately)."""

from __future__ import annotations

import itertools
import math

import pytest

from botstage.robots.gridmap import load
from botstage.robots.interfaces import LaserScan, Pose2D
from botstage.robots.profile import load_profile
from botstage.robots.sim.world import World
from botstage.skills.nav.controller import FollowerParams, PathFollower
from botstage.skills.nav.costmap import inflated_costs
from botstage.skills.nav.planner import Planner

DT = 0.05
MUSEUM = load("robots/maps/museum.yaml")
PEOPLEBOT, _, _ = load_profile("robots/profiles/peoplebot.yaml")
PARAMS = FollowerParams(max_linear=0.6, max_angular=1.5, robot_radius=0.30, laser_x=0.16)
PLANNER = Planner(MUSEUM, inflated_costs(MUSEUM, 0.30))


def scan(world: World) -> LaserScan:
    device = PEOPLEBOT.interfaces["laser"]
    beams = device.beams or 181
    fov = device.field_of_view or math.pi
    return LaserScan(
        world.time, -fov / 2, fov / (beams - 1), device.range_min or 0.0, device.range_max or 8.0, world.laser(device)
    )


def follow(world: World, follower: PathFollower, seconds: float) -> str:
    state = "following"
    for _ in range(round(seconds / DT)):
        command = follower.command(world.body.pose, scan(world))
        state = command.state
        if state in ("arrived", "blocked"):
            world.stop()
            return state
        world.cmd_vel(command.v, command.w)
        world.step(DT)
    return state


PAIRS = list(itertools.permutations(sorted(MUSEUM.places), 2))[::7]  # 13 of the 90, spread over all places


@pytest.mark.parametrize(("a", "b"), PAIRS)
def test_follows_planned_paths_between_places(a: str, b: str) -> None:
    start, goal = MUSEUM.places[a], MUSEUM.places[b]
    world = World(MUSEUM, PEOPLEBOT, Pose2D(*start), seed=2)
    plan = PLANNER.plan(start[:2], goal[:2])
    state = follow(world, PathFollower(plan.points, goal[2], PARAMS), 180)
    pose = world.body.pose
    assert state == "arrived"
    assert math.hypot(pose.x - goal[0], pose.y - goal[1]) <= PARAMS.goal_tolerance + 0.02
    assert abs(math.remainder(pose.theta - goal[2], 2 * math.pi)) <= PARAMS.heading_tolerance + 0.02
    assert world.body.bumps == 0


def test_stops_before_an_obstacle_in_its_path() -> None:
    world = World(MUSEUM, PEOPLEBOT, Pose2D(11.0, 10.0, 0.0), seed=1)  # exhibit_c's plinth 4.4 m ahead
    state = follow(world, PathFollower([(11.0, 10.0), (17.5, 10.0)], None, PARAMS), 60)
    assert state == "blocked"
    assert world.body.bumps == 0
    gap = 15.4 - world.body.pose.x - PARAMS.robot_radius  # between the robot's edge and the plinth
    assert 0 < gap < PARAMS.stop_clearance + 0.1
