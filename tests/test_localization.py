"""Localisation: the pose EKF, scan matching against the map, and the Localizer on the simulator.

The drives use ``tests/bench/bench_localization.py``'s harness: the robot is steered with its
true pose and its encoders count the wheels' turning, so odometry drifts as on a real floor.
Bounds were measured (see the benchmark) and are asserted with margin; every run is seeded.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from botstage.robots.clock import SimClock
from botstage.robots.gridmap import FREE, OCCUPIED, GridMap, load
from botstage.robots.interfaces import LaserScan, Pose2D
from botstage.robots.sim.backend import SimBackend
from botstage.robots.sim.world import World
from botstage.skills.nav.ekf import PoseEKF, wrap
from botstage.skills.nav.localization import Localizer, LocalizerParams, PoseEstimate, increment
from botstage.skills.nav.scan_match import MatchResult, ScanMatcher
from tests.bench.bench_localization import drive_loop, robot_profile

MUSEUM = load("robots/maps/museum.yaml")
PEOPLEBOT = robot_profile("peoplebot")
LASER = PEOPLEBOT.interfaces["laser"]
PRIOR = np.diag([0.1**2, 0.1**2, math.radians(5) ** 2])


def scan_at(world: World) -> LaserScan:
    beams, fov = LASER.beams or 181, LASER.field_of_view or math.pi
    return LaserScan(world.time, -fov / 2, fov / (beams - 1), LASER.range_min or 0.0, 8.0, world.laser(LASER))


def offset(pose: Pose2D, dx: float, dy: float, dtheta: float) -> Pose2D:
    return Pose2D(pose.x + dx, pose.y + dy, wrap(pose.theta + dtheta))


def error(a: Pose2D, b: Pose2D) -> tuple[float, float]:
    return math.hypot(a.x - b.x, a.y - b.y), abs(wrap(a.theta - b.theta))


# -- the EKF ----------------------------------------------------------------------------------


def test_straight_prediction_follows_odometry_and_grows_the_covariance() -> None:
    ekf = PoseEKF(Pose2D(1.0, 2.0, math.pi / 2))
    traces = []
    for _ in range(100):
        ekf.predict(0.05, 0.0, gyro_d_theta=0.0, dt=0.1)
        traces.append(np.trace(ekf.covariance))
    pose = ekf.pose
    assert (pose.x, pose.y, pose.theta) == pytest.approx((1.0, 7.0, math.pi / 2), abs=1e-9)
    assert all(b > a for a, b in itertools.pairwise(traces))
    cov = ekf.covariance
    assert cov[0, 0] > cov[1, 1]  # driving along y: heading doubt spreads sideways (x) more than along


def test_turning_prediction_matches_integrated_odometry_when_the_gyro_agrees() -> None:
    # odometry of a robot on a circle of radius 1 m, integrated with diff_tf's mid-point model
    poses = [Pose2D(0.0, 0.0, 0.0)]
    for _ in range(200):
        last = poses[-1]
        d, dt = 0.02, 0.02
        poses.append(
            Pose2D(
                last.x + d * math.cos(last.theta + dt / 2),
                last.y + d * math.sin(last.theta + dt / 2),
                wrap(last.theta + dt),
            )
        )
    ekf = PoseEKF(poses[0])
    for a, b in itertools.pairwise(poses):
        distance, d_theta = increment(a, b)
        ekf.predict(distance, d_theta, gyro_d_theta=d_theta, dt=0.1)
    end, pose = poses[-1], ekf.pose
    assert error(pose, end)[0] < 1e-9 and error(pose, end)[1] < 1e-9
    assert abs(pose.theta - wrap(4.0)) < 1e-9  # went past pi: wrapped


def test_a_correction_shrinks_the_covariance_and_pulls_towards_the_fix() -> None:
    ekf = PoseEKF(Pose2D(0.0, 0.0, 0.0))
    for _ in range(200):
        ekf.predict(0.05, 0.0)
    before = ekf.covariance
    fix = Pose2D(10.2, 0.3, 0.02)
    ekf.correct(fix, np.diag([0.02**2, 0.02**2, math.radians(1) ** 2]))
    after = ekf.covariance
    assert np.all(np.linalg.eigvalsh(before - after) > -1e-12)  # no direction got more uncertain
    assert np.trace(after) < 0.5 * np.trace(before)
    pose = ekf.pose
    assert 10.0 < pose.x <= 10.2 and 0.0 < pose.y <= 0.3
    assert 0.0 < pose.theta < 0.05  # beyond the fix's 0.02: a sideways offset also says the heading was off
    assert np.allclose(after, after.T)


def test_angle_wrap_in_the_correction() -> None:
    ekf = PoseEKF(Pose2D(0.0, 0.0, math.radians(179)), np.diag([0.01, 0.01, math.radians(5) ** 2]))
    ekf.correct(Pose2D(0.0, 0.0, math.radians(-179)), np.diag([0.01, 0.01, math.radians(5) ** 2]))
    assert abs(abs(ekf.pose.theta) - math.pi) < math.radians(0.01)  # half way across +-180°, not through 0
    assert ekf.innovation(Pose2D(0.0, 0.0, math.radians(-179)), np.diag([0.01, 0.01, math.radians(5) ** 2])) < 0.1


def test_gyro_bias_is_learnt_standing_still_and_removed_when_moving() -> None:
    ekf = PoseEKF(Pose2D(0.0, 0.0, 0.0))
    bias, dt = 0.002, 0.1
    for _ in range(100):  # 10 s at rest: the wheels say 0, the gyro says bias * dt
        ekf.predict(0.0, 0.0, gyro_d_theta=bias * dt, dt=dt)
    assert ekf.pose.theta == 0.0  # at rest the wheels are exact
    assert ekf.bias == pytest.approx(bias, rel=0.01)
    for _ in range(1000):  # 100 s driving straight on slipping wheels (odometry turns a little each step)
        ekf.predict(0.06, 0.003, gyro_d_theta=bias * dt, dt=dt)
    assert abs(ekf.pose.theta) < 0.2 * 1000 * 0.003  # mostly the gyro's (straight), not the wheels' 3 rad


# -- scan matching ------------------------------------------------------------------------------


@pytest.mark.parametrize("place", ["hall_centre", "exhibit_a", "gallery_model", "gallery_corner"])
def test_scan_matcher_recovers_a_known_offset(place: str) -> None:
    world = World(MUSEUM, PEOPLEBOT, Pose2D(*MUSEUM.places[place]), seed=3)
    truth, matcher = world.body.pose, ScanMatcher(MUSEUM, LASER.pose)
    result = matcher.match(scan_at(world), offset(truth, 0.15 * 0.6, -0.15 * 0.8, math.radians(4)), PRIOR)
    assert result.accepted, result
    position, heading = error(result.pose, truth)
    assert position < 0.02 and heading < math.radians(0.5)
    assert result.covariance.shape == (3, 3) and np.all(np.linalg.eigvalsh(result.covariance) > 0)


def test_scan_matcher_does_not_fit_the_far_face_of_a_thin_wall() -> None:
    # beams reaching the gallery's partition 8 m away fit its back face as well when shifted 20 cm
    world = World(MUSEUM, PEOPLEBOT, Pose2D(14.075, 19.625, 0.9028), seed=19)
    truth = world.body.pose
    prior = offset(truth, 0.15 * math.cos(19), 0.15 * math.sin(19), math.radians(4))
    result = ScanMatcher(MUSEUM, LASER.pose).match(scan_at(world), prior, PRIOR)
    assert result.accepted and error(result.pose, truth)[0] < 0.02


def test_scan_matcher_on_a_map_with_a_rotated_origin() -> None:
    grid = GridMap(MUSEUM.data, MUSEUM.resolution, (2.0, -1.0, 0.4))
    ox, oy, yaw = grid.origin
    local = (11.0 + 0.5, 10.0 + 0.5)  # the hall's centre in the map's own frame
    x = ox + math.cos(yaw) * local[0] - math.sin(yaw) * local[1]
    y = oy + math.sin(yaw) * local[0] + math.cos(yaw) * local[1]
    world = World(grid, PEOPLEBOT, Pose2D(x, y, 1.0), seed=1)
    truth = world.body.pose
    result = ScanMatcher(grid, LASER.pose).match(scan_at(world), offset(truth, -0.1, 0.1, math.radians(-3)), PRIOR)
    assert result.accepted, result
    assert error(result.pose, truth)[0] < 0.02 and error(result.pose, truth)[1] < math.radians(0.5)


def corridor() -> GridMap:
    data = np.full((60, 1000), FREE, dtype=np.int8)  # 50 m x 3 m at 5 cm
    data[:2, :] = data[-2:, :] = OCCUPIED
    data[:, :2] = data[:, -2:] = OCCUPIED
    return GridMap(data, 0.05)


def test_scan_matcher_rejects_a_corridor_where_the_pose_is_free_along_it() -> None:
    grid = corridor()
    world = World(grid, PEOPLEBOT, Pose2D(25.0, 1.5, 0.0), seed=1)  # ends 25 m away, out of the laser's 8 m
    result = ScanMatcher(grid, LASER.pose).match(scan_at(world), offset(world.body.pose, 0.1, 0.05, 0.03), PRIOR)
    assert not result.accepted and result.reason == "ambiguous"


def test_scan_matcher_rejects_an_empty_view() -> None:
    grid = GridMap(np.full((400, 400), FREE, dtype=np.int8), 0.05)  # 20 m of open floor, no wall within 8 m
    world = World(grid, PEOPLEBOT, Pose2D(10.0, 10.0, 0.0), seed=1)
    result = ScanMatcher(grid, LASER.pose).match(scan_at(world), world.body.pose, PRIOR)
    assert not result.accepted and result.reason == "few_points"


def test_scan_matcher_rejects_a_view_mostly_blocked_by_things_not_on_the_map() -> None:
    crowded = MUSEUM.data.copy()
    centre = np.array(MUSEUM.cell(11.0, 10.0))
    rows, cols = np.indices(crowded.shape)
    ring = np.abs(np.hypot(rows - centre[0], cols - centre[1]) - 24) < 1.5  # people all round at 1.2 m
    gaps = np.abs(np.arctan2(rows - centre[0], cols - centre[1])) < 0.4  # but a gap ahead
    crowded[ring & ~gaps] = OCCUPIED
    world = World(GridMap(crowded, MUSEUM.resolution, MUSEUM.origin), PEOPLEBOT, Pose2D(11.0, 10.0, 0.0), seed=1)
    result = ScanMatcher(MUSEUM, LASER.pose).match(scan_at(world), world.body.pose, PRIOR)
    assert not result.accepted and result.reason == "few_inliers"
    assert result.inliers < result.points / 2


def test_scan_matcher_gates_a_jump_the_prior_covariance_rules_out() -> None:
    world = World(MUSEUM, PEOPLEBOT, Pose2D(*MUSEUM.places["hall_centre"]), seed=3)
    truth = world.body.pose
    confident = np.diag([0.01**2, 0.01**2, math.radians(0.5) ** 2])
    result = ScanMatcher(MUSEUM, LASER.pose).match(scan_at(world), offset(truth, 0.12, 0.0, 0.0), confident)
    assert not result.accepted and result.reason == "jump"
    assert error(result.pose, truth)[0] < 0.02  # it found the truth; the gate refused to jump there


# -- the Localizer ------------------------------------------------------------------------------


def backend(robot: str = "peoplebot", start: Pose2D = Pose2D(11.0, 10.0, 0.0)) -> tuple[SimBackend, SimClock]:
    clock = SimClock(10)
    return SimBackend(robot_profile(robot), MUSEUM, start, 4, clock), clock


def test_localizer_sources_counters_and_a_cheap_estimate() -> None:
    sim, clock = backend()
    devices = sim.devices
    wheels = Localizer.for_devices({"odometry": devices["odometry"]})
    fused = Localizer.for_devices({k: v for k, v in devices.items() if k != "laser"}, MUSEUM, PEOPLEBOT)
    mapped = Localizer.for_devices(devices, MUSEUM, PEOPLEBOT)
    assert mapped.matcher is not None and mapped.matcher.laser_pose == LASER.pose
    for _ in range(30):
        devices["drive"].cmd_vel(0.3, 0.2)
        sim.step()
        clock.next_tick()
        for localizer in (wheels, fused, mapped):
            localizer.update()
    assert wheels.estimate().source == "odometry"
    assert fused.estimate().source == "ekf"
    assert mapped.estimate().source == "map"
    estimate = mapped.estimate()
    assert isinstance(estimate, PoseEstimate) and mapped.estimate() is estimate  # one object per tick
    assert estimate.time == pytest.approx(clock.now())
    assert not estimate.covariance.flags.writeable
    summary = mapped.summary()
    assert summary["matches_accepted"] >= 10  # 3 s at most every 0.2 s, while moving
    assert summary["matches_accepted"] + summary["matches_rejected"] <= 16
    assert error(estimate.pose, sim.world.body.pose)[0] < 0.03


def test_localizer_matches_only_when_moving_or_every_two_seconds() -> None:
    sim, clock = backend()
    localizer = Localizer.for_devices(sim.devices, MUSEUM, PEOPLEBOT)
    for _ in range(100):  # 10 s at rest
        sim.step()
        clock.next_tick()
        localizer.update()
    assert localizer.matches_accepted + localizer.matches_rejected == 5  # at 0.1 s, then every 2 s


def test_localizer_starts_at_the_first_odometry_pose_and_resets() -> None:
    sim, _ = backend(start=Pose2D(4.5, 1.5, 1.57))
    localizer = Localizer(sim.devices["odometry"])
    first = localizer.estimate().pose
    assert (first.x, first.y, first.theta) == pytest.approx((4.5, 1.5, 1.57))
    localizer.reset(Pose2D(5.0, 2.0, 0.0), np.eye(3) * 0.01)
    estimate = localizer.estimate()
    assert estimate.pose == Pose2D(5.0, 2.0, 0.0) and np.allclose(estimate.covariance, np.eye(3) * 0.01)
    pending = Localizer(sim.devices["odometry"])
    pending.reset(Pose2D(1.0, 1.0, 0.0))  # before the first update: where it starts
    assert pending.update().pose == Pose2D(1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="odometry"):
        Localizer.for_devices({"imu": sim.devices.get("imu")})


def test_localizer_recovers_from_an_overconfident_wrong_pose() -> None:
    sim, clock = backend()
    localizer = Localizer.for_devices(sim.devices, MUSEUM, PEOPLEBOT, LocalizerParams())
    localizer.update()
    truth = sim.world.body.pose
    localizer.reset(offset(truth, 0.2, -0.1, math.radians(3)), np.diag([0.01**2, 0.01**2, math.radians(0.3) ** 2]))
    for _ in range(100):
        sim.devices["drive"].cmd_vel(0.2, 0.0)
        sim.step()
        clock.next_tick()
        localizer.update()
    assert localizer.rejections["jump"] >= 1  # the map disagreed with a confident estimate at first
    assert error(localizer.estimate().pose, sim.world.body.pose)[0] < 0.03


# -- driving loops ------------------------------------------------------------------------------


def test_map_corrected_peoplebot_loop_stays_within_centimetres_while_odometry_drifts() -> None:
    run = drive_loop(seed=2)
    odometry, ekf, mapped = (run.errors[name] for name in ("odometry", "ekf", "map"))
    assert run.distance_m > 40 and run.bumps == 0
    final_position, final_heading = error(run.final["map"], run.final_truth)
    assert final_position < 0.05 and final_heading < math.radians(2)
    assert max(mapped.position) < 0.05 and max(mapped.heading) < math.radians(2)
    assert max(odometry.position) > 10 * max(mapped.position)  # measured: 223 cm vs 0.85 cm
    assert max(ekf.heading) < max(odometry.heading)  # measured: 0.9° vs 14.4°
    assert run.map_localizer is not None and run.map_localizer.summary()["acceptance"] > 0.9


def test_map_corrected_loop_with_people_in_the_laser() -> None:
    run = drive_loop(seed=1, people=20)
    assert max(run.errors["map"].position) < 0.05 and max(run.errors["map"].heading) < math.radians(2)
    assert run.map_localizer is not None and run.map_localizer.rejections["few_inliers"] > 0  # people blocked views


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_chefbot_ekf_heading_beats_odometry_and_its_depth_scan_beats_both(seed: int) -> None:
    run = drive_loop(robot="chefbot", world="restaurant", seed=seed, max_linear=0.35)
    assert max(run.errors["ekf"].heading) < 0.7 * max(run.errors["odometry"].heading)
    # the depth camera's 60 degree scan (depthimage_to_laserscan) against the map
    assert max(run.errors["map"].position) < 0.5 * max(run.errors["ekf"].position)
    assert run.errors["map"].position[-1] < 0.05


def test_loops_are_deterministic() -> None:
    a = drive_loop(robot="chefbot", world="restaurant", seed=7, max_linear=0.35)
    b = drive_loop(robot="chefbot", world="restaurant", seed=7, max_linear=0.35)
    assert a.final == b.final and a.errors["ekf"].position == b.errors["ekf"].position


def test_match_result_fields() -> None:
    result = MatchResult(False, Pose2D(0, 0, 0), np.eye(3), "few_points")
    assert math.isnan(result.rms) and result.points == 0
