"""Simulated people and the Kinect-like tracker that reports them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from botstage.robots.clock import SimClock
from botstage.robots.gridmap import load
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import load_profile
from botstage.robots.sim.devices import SimPeopleTracker
from botstage.robots.sim.people import Crowd, Person
from botstage.robots.sim.world import World

MUSEUM = load("robots/maps/museum.yaml")


def run_crowd(seed: int, seconds: float, count: int = 20) -> tuple[Crowd, list[list[tuple[int, list[int]]]]]:
    crowd = Crowd.populate(MUSEUM, np.random.default_rng(seed), count)
    arrived_groups = []
    for _ in range(round(seconds / 0.1)):
        crowd.step(0.1)
        for person in crowd.people:
            assert crowd.can_stand(person.x, person.y), f"person {person.id} stands in an obstacle"
        arrived_groups.append([(g.id, list(g.members)) for g in crowd.groups if g.arrived])
    return crowd, arrived_groups


def test_same_seed_same_people() -> None:
    a, _ = run_crowd(7, 60)
    b, _ = run_crowd(7, 60)
    assert [(p.id, p.x, p.y) for p in a.people] == [(p.id, p.x, p.y) for p in b.people]


def test_groups_gather_within_the_papers_distance_and_leave() -> None:
    crowd = Crowd.populate(MUSEUM, np.random.default_rng(3), 20)
    seen_arrived, seen_left = set(), set()
    for _ in range(round(600 / 0.1)):
        crowd.step(0.1)
        current = {g.id for g in crowd.groups}
        for group in crowd.groups:
            if group.arrived:
                seen_arrived.add(group.id)
                members = [next(p for p in crowd.people if p.id == m) for m in group.members]
                assert 2 <= len(members) <= 6
                for person in members:  # everyone within 1.5 m of someone else in the group
                    assert min(math.hypot(person.x - o.x, person.y - o.y) for o in members if o is not person) <= 1.5
        seen_left |= seen_arrived - current
    assert len(seen_arrived) >= 3 and seen_left


def test_nobody_walks_through_walls_over_a_long_run() -> None:
    run_crowd(11, 300)  # asserts every position on every step


@pytest.fixture
def tracker() -> tuple[World, Crowd, SimPeopleTracker]:
    profile, _, _ = load_profile("robots/profiles/peoplebot.yaml")
    assert profile is not None
    world = World(MUSEUM, profile, Pose2D(11.0, 10.0, 0.0), seed=1)  # hall centre, facing +x
    crowd = Crowd(MUSEUM, world.rng)
    device = profile.interfaces["people"].model_copy(update={"noise": 0.0})
    return world, crowd, SimPeopleTracker(world, crowd, device, SimClock())


def place(crowd: Crowd, *spots: tuple[float, float]) -> None:
    crowd.people = [Person(i + 1, x, y, 1.0, (x, y), pause_until=1e9) for i, (x, y) in enumerate(spots)]


def test_tracker_reports_in_the_sensor_frame(tracker) -> None:
    _world, crowd, sensor = tracker
    sensor_x = 11.0 + 0.1  # the Kinect sits 0.1 m ahead of the base's centre
    place(crowd, (sensor_x + 2.0, 10.0), (sensor_x + 2.0, 9.5), (sensor_x + 3.0, 10.6))
    seen = {p.id: (round(p.x, 6), round(p.z, 6)) for p in sensor.people()}
    assert seen == {1: (0.0, 2.0), 2: (0.5, 2.0), 3: (-0.6, 3.0)}  # x is to the right


@pytest.mark.parametrize(
    ("spot", "why"),
    [
        ((10.0, 10.0), "behind the robot"),
        ((11.1 + 0.5, 10.0), "closer than 0.8 m"),
        ((11.1 + 4.5, 10.0), "beyond 4 m"),
        ((11.1 + 1.5, 12.5), "outside the 57 degree field of view"),
    ],
)
def test_tracker_limits(tracker, spot: tuple[float, float], why: str) -> None:
    _, crowd, sensor = tracker
    place(crowd, spot)
    assert sensor.people() == [], why


def test_tracker_does_not_see_through_obstacles(tracker) -> None:
    world, crowd, sensor = tracker
    world.body.pose = Pose2D(13.5, 10.0, 0.0)  # the exhibit_c plinth (x 15.4-16.6) lies ahead
    place(crowd, (17.0, 10.0), (15.0, 10.5))
    assert [p.id for p in sensor.people()] == [2]


def test_a_scripted_gathering_brings_the_nearest_free_people_and_they_stay() -> None:
    crowd = Crowd.populate(load("robots/maps/museum.yaml"), np.random.default_rng(2), 8)
    crowd.next_group_at = math.inf
    crowd.scripted = [(1.0, (13.5, 10.0), 4, 30.0)]
    for _ in range(10 * 120):
        crowd.step(0.1)
        if crowd.groups and crowd.groups[0].arrived:
            break
    (group,) = crowd.groups
    assert len(group.members) == 4 and group.arrived
    members = [p for p in crowd.people if p.id in group.members]
    assert all(math.hypot(p.x - 13.5, p.y - 10.0) < 0.7 for p in members)
    for _ in range(10 * 29):
        crowd.step(0.1)
    assert crowd.groups == [group]  # still there after 29 s
    for _ in range(10 * 2):
        crowd.step(0.1)
    assert crowd.groups == []  # they stayed 30 s once all were there, then left
