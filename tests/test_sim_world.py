"""The simulated world: kinematics, limits, collisions, watchdog, encoders, battery, IMU, laser."""

from __future__ import annotations

import math

import numpy as np
import pytest

from botstage.robots.gridmap import load
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import load_profile
from botstage.robots.sim.world import World

DT = 0.05


def world(
    robot: str = "chefbot", map_name: str = "restaurant", start: Pose2D = Pose2D(10.0, 7.0, 0.0), **kwargs: float
) -> World:
    profile, problems, _ = load_profile(f"robots/profiles/{robot}.yaml")
    assert profile is not None, problems
    return World(load(f"robots/maps/{map_name}.yaml"), profile, start, **kwargs)


def drive(w: World, v: float, omega: float, seconds: float) -> None:
    for _ in range(round(seconds / DT)):
        w.cmd_vel(v, omega)
        w.step(DT)


def test_straight_line_with_the_acceleration_ramp() -> None:
    w = world(slip_std=0.0)
    drive(w, 0.3, 0.0, 4.0)
    ramp = 0.3 / w.base.max_linear_accel  # 0.6 s to reach speed
    expected = 0.3 * (4.0 - ramp) + 0.5 * 0.3 * ramp
    assert w.body.pose.x - 10.0 == pytest.approx(expected, abs=0.02)
    assert w.body.pose.y == pytest.approx(7.0) and w.body.pose.theta == pytest.approx(0.0)


def test_a_full_circle_comes_back_to_the_start_icc_model() -> None:
    w = world(slip_std=0.0, start=Pose2D(13.0, 7.0, 0.0))
    w.cmd_vel(0.2, 0.4)
    w.body.left.speed, w.body.right.speed = w.wheel_targets()  # start already at speed
    radius = 0.2 / 0.4
    farthest = 0.0
    for _ in range(round(2 * math.pi / 0.4 / DT)):
        w.cmd_vel(0.2, 0.4)
        w.step(DT)
        farthest = max(farthest, math.hypot(w.body.pose.x - 13.0, w.body.pose.y - 7.0))
    assert farthest == pytest.approx(2 * radius, abs=0.01)  # it went round: the far side is a diameter away
    assert math.hypot(w.body.pose.x - 13.0, w.body.pose.y - 7.0) < 0.02  # and came back
    assert w.body.bumps == 0


def test_commands_are_limited_by_the_profile() -> None:
    w = world(slip_std=0.0)
    drive(w, 5.0, 0.0, 3.0)
    assert w.body.linear == pytest.approx(w.base.max_linear, rel=1e-6)
    w2 = world(slip_std=0.0)
    w2.cmd_vel(0.35, 2.0)
    left, right = w2.wheel_targets()
    assert max(abs(left), abs(right)) <= w2.base.wheel_top_speed + 1e-12


def test_the_robot_never_passes_through_a_wall() -> None:
    w = world(start=Pose2D(10.0, 2.0, 0.0), slip_std=0.0)
    drive(w, 0.35, 0.0, 40.0)  # east along y = 2: the east wall (x = 20), no door there
    assert w.body.bumps > 0 and w.body.bumped
    assert w.body.pose.x <= 20.0 - w.base.footprint_radius + 0.05
    assert not w.collides(w.body.pose.x, w.body.pose.y)
    assert w.body.left.speed == 0.0 and w.body.right.speed == 0.0


def test_table_bumps_stop_the_wheels() -> None:
    w = world(start=Pose2D(13.0, 6.5, -math.pi / 2))  # heading south, table 2 ahead at y 3.4-4.6
    drive(w, 0.3, 0.0, 10.0)
    assert w.body.bumps > 0
    assert w.body.pose.y > 4.6 + w.base.footprint_radius - 0.05


def test_the_watchdog_stops_a_robot_left_without_commands() -> None:
    w = world(slip_std=0.0)
    w.cmd_vel(0.3, 0.0)
    for _ in range(round(2.0 / DT)):
        w.step(DT)
    assert w.body.linear == 0.0
    assert w.body.pose.x - 10.0 < 0.3 * 0.5 + 0.05  # it moved for the watchdog's 0.5 s at most


def test_encoders_count_whole_ticks_of_the_real_distance() -> None:
    w = world(slip_std=0.0)
    drive(w, 0.2, 0.0, 2.0)
    per_metre = w.base.encoder_ticks_per_rev / (math.pi * w.base.wheel_diameter)
    for wheel in (w.body.left, w.body.right):
        assert isinstance(wheel.ticks, int)
        assert wheel.turned == pytest.approx(wheel.distance)  # no slip: turning is ground covered
        assert wheel.ticks == math.floor(wheel.distance * per_metre)


def test_encoders_count_turning_not_slipped_ground() -> None:
    w = world(slip_std=0.05)
    drive(w, 0.3, 0.0, 10.0)
    per_metre = w.base.encoder_ticks_per_rev / (math.pi * w.base.wheel_diameter)
    for wheel in (w.body.left, w.body.right):
        assert wheel.ticks == math.floor(wheel.turned * per_metre)
        assert wheel.turned != pytest.approx(wheel.distance, abs=1e-4)  # slip: the floor disagrees
    assert abs(w.body.left.distance - w.body.left.turned) < 0.05 * w.body.left.turned  # but not by much


def test_same_seed_same_trajectory_other_seed_other_slip() -> None:
    def trajectory(seed: int) -> list[tuple[float, float, float]]:
        w = world(seed=seed)
        poses = []
        for k in range(200):
            w.cmd_vel(0.3, 0.3 * math.sin(k / 20))
            w.step(DT)
            poses.append((w.body.pose.x, w.body.pose.y, w.body.pose.theta))
        return poses

    assert trajectory(4) == trajectory(4)
    assert trajectory(4) != trajectory(5)


def test_battery_drains_faster_when_driving() -> None:
    idle, moving = world(), world()
    for _ in range(round(60 / DT)):
        idle.step(DT)
    drive(moving, 0.3, 0.0, 60)
    assert 100 > idle.battery_percent > moving.battery_percent
    assert idle.battery_voltage > moving.battery_voltage


def test_the_imu_drifts_with_gyro_bias() -> None:
    w = world(gyro_bias=0.01)
    for _ in range(round(100 / DT)):
        w.step(DT)
    assert w.body.pose.theta == 0.0
    assert w.imu_yaw == pytest.approx(1.0, abs=0.05)  # 0.01 rad/s for 100 s


def test_laser_ranges_by_ray_casting() -> None:
    w = world("peoplebot", "museum", start=Pose2D(11.0, 10.0, 0.0))  # hall centre, facing +x
    laser = w.profile.interfaces["laser"]
    ranges = w.laser(laser)
    assert ranges.shape == (181,)
    ahead = ranges[90]  # straight ahead: the plinth at x 15.4-16.6 seen from the laser at x 11.16
    assert ahead == pytest.approx(15.4 - 11.16, abs=0.05)
    right = ranges[0]  # 90 degrees right: exhibit_d's plinth, y 5.4-6.6, straight south
    assert right == pytest.approx(10.0 - 6.6, abs=0.05)
    exact = w.laser(laser.model_copy(update={"noise": 0.0}))  # without noise: within a quarter cell
    assert exact[90] == pytest.approx(15.4 - 11.16, abs=0.0125 + 1e-9)
    assert exact[0] == pytest.approx(10.0 - 6.6, abs=0.0125 + 1e-9)
    short = laser.model_copy(update={"range_max": 2.0, "noise": 0.0})
    assert math.isinf(w.laser(short)[90])  # nothing within 2 m ahead: no return
    assert 20 < np.isfinite(ranges).sum() < 181  # most of the hall lies beyond the laser's 8 m


def test_a_start_inside_an_obstacle_is_refused() -> None:
    with pytest.raises(ValueError, match="cannot start at"):
        world(start=Pose2D(9.0, 4.0, 0.0))  # on table 1


def _diagonal_world(start: Pose2D, yaw: float = 0.0) -> World:
    from botstage.robots.gridmap import GridMap

    data = np.zeros((100, 100), dtype=np.int8)
    for i in range(100):
        data[i, 99 - i] = 100  # a wall one cell thick, running diagonally
    profile, _, _ = load_profile("robots/profiles/peoplebot.yaml")
    grid = GridMap(data, 0.05, (0.0, 0.0, yaw))
    return World(grid, profile, start, seed=0)


@pytest.mark.parametrize("offset", [k * 0.013 for k in range(11)])
def test_laser_does_not_see_through_a_thin_diagonal_wall(offset: float) -> None:
    w = _diagonal_world(Pose2D(1.0 + offset, 1.0, math.pi / 4))
    device = w.profile.interfaces["laser"].model_copy(
        update={"pose": (0.0, 0.0, 0.0), "noise": None, "beams": 1, "field_of_view": 1e-4}
    )
    # the wall is the line x + y = 4.95 (cell centres): about (4.95 - 2 - offset) / sqrt 2 away
    assert w.laser(device)[0] < 2.3


def test_laser_honours_the_maps_origin_yaw() -> None:
    from botstage.robots.gridmap import GridMap

    data = np.zeros((200, 200), dtype=np.int8)
    data[:, 150] = 100  # grid column 150: with the map turned 90 degrees, the line y = 7.5
    profile, _, _ = load_profile("robots/profiles/peoplebot.yaml")
    w = World(GridMap(data, 0.05, (0.0, 0.0, math.pi / 2)), profile, Pose2D(-5.0, 5.0, math.pi / 2), seed=0)
    device = profile.interfaces["laser"].model_copy(
        update={"pose": (0.0, 0.0, 0.0), "noise": None, "beams": 1, "field_of_view": 1e-4}
    )
    assert w.laser(device)[0] == pytest.approx(2.5, abs=0.05)


def test_reading_a_sensor_does_not_change_the_robots_path() -> None:
    def final(read: bool) -> Pose2D:
        w = world("peoplebot", "museum", start=Pose2D(11.0, 10.0, 0.0), seed=5)
        for _ in range(200):
            if read:
                w.laser(w.profile.interfaces["laser"])
            w.cmd_vel(0.3, 0.2)
            w.step(DT)
        return w.body.pose

    assert final(True) == final(False)


def test_odometry_speed_is_right_however_often_it_is_read() -> None:
    from botstage.robots.clock import SimClock
    from botstage.robots.sim.backend import SimBackend

    profile, _, _ = load_profile("robots/profiles/peoplebot.yaml")
    clock = SimClock(20)
    backend = SimBackend(profile, load("robots/maps/museum.yaml"), Pose2D(11.0, 10.0, 0.0), 0, clock)
    odometry = backend.devices["odometry"]
    for k in range(100):
        backend.devices["drive"].cmd_vel(0.3, 0.0)
        backend.step()
        clock.next_tick()
        if k == 40:
            odometry.read()  # the first read averages over the start and the acceleration: skip it
        elif k % 5 == 0 and k > 40:  # then read only every fifth tick
            assert odometry.read().twist.v == pytest.approx(0.3, abs=0.03)


def test_a_bump_is_one_event_however_long_the_robot_pushes() -> None:
    w = world(start=Pose2D(10.0, 2.0, 0.0), slip_std=0.0)
    drive(w, 0.35, 0.0, 40.0)  # into the east wall, then on against it for many steps
    body = w.body
    assert body.bumps == 1 and body.wall_bumps == 1 and body.person_bumps == 0
    assert body.contact_steps > 100  # the steps spent pushing are counted apart
    assert [b.what for b in body.bump_log] == ["wall"]
    first = body.bump_log[0]
    assert first.x == pytest.approx(body.pose.x, abs=0.03) and first.y == pytest.approx(2.0)
    assert 0 < first.t < 40.0
    drive(w, 0.0, 0.0, 1.0)  # standing still against it: still the same contact
    drive(w, 0.35, 0.0, 1.0)
    assert body.bumps == 1
    drive(w, -0.2, 0.0, 2.0)  # away from the wall, then into it again: a second bump
    assert body.contact == ""
    drive(w, 0.35, 0.0, 4.0)
    assert body.bumps == 2 and len(body.bump_log) == 2 and body.bump_log[1].t > first.t


def test_driving_into_a_person_is_a_bump_into_people() -> None:
    w = world("peoplebot", "museum", start=Pose2D(11.0, 10.0, 0.0), slip_std=0.0)
    w.movers = lambda: np.array([[12.5, 10.0]])  # someone standing 1.5 m ahead
    drive(w, 0.3, 0.0, 10.0)
    body = w.body
    assert body.bumps == 1 and body.person_bumps == 1 and body.wall_bumps == 0
    assert body.bump_log[0].what == "person"
    assert body.pose.x < 12.5 - w.base.footprint_radius - w.mover_radius + 0.03
