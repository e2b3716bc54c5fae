"""Pose drift over a loop: odometry alone vs EKF (odometry + IMU) vs map-corrected (+ laser).

The PeopleBot drives a 56 m loop through the museum (hall, entrance, reception, gallery door) on the
simulator, steered with its *true* pose (so every estimator sees the same drive), while three
estimators run side by side from the same devices: the raw odometry reading, a ``Localizer``
without the laser (the EKF with the gyro) and a ``Localizer`` with the laser and the map. Each
is compared with the true pose every tick: final and largest position error (cm) and heading
error (deg). The robot stands still for ``STILL_S`` seconds first, as a robot does when it
starts (the gyro's bias is learnt then: the simulated gyro's noise, 0.005 rad/s a 10 Hz sample,
leaves a 0.0005 rad/s bias error after 10 s, 3.5° over the two minutes of the loop). The
PeopleBot's profile has no IMU (the paper's robot lists none; its Pioneer base takes an optional
gyro), so the harness adds the simulator's IMU to it (``robot_profile``). Also: scan match time
per match (wall clock, median and p90) and the share of matches accepted; the same loop with 20
people (laser returns that are not on the map); matches from random poses with the prior 0.15 m
and 4° off; and Chefbot (odometry + IMU, no laser) on a restaurant loop.

The simulator's encoders count the wheels' turning, not the ground they covered (wheel slip),
so odometry drifts as on a real floor.

Run with ``python -m tests.bench nav`` or ``python -m tests.bench.bench_localization`` (``--quick`` for one seed).
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from botstage.robots import PROFILES_DIR
from botstage.robots.clock import SimClock
from botstage.robots.gridmap import FREE, MAPS_DIR, GridMap, load
from botstage.robots.interfaces import LaserScan, Pose2D
from botstage.robots.profile import Device, Profile, load_profile
from botstage.robots.sim.backend import SimBackend
from botstage.robots.sim.world import World
from botstage.skills.nav.controller import FollowerParams, PathFollower
from botstage.skills.nav.costmap import inflated_costs
from botstage.skills.nav.ekf import wrap
from botstage.skills.nav.localization import Localizer
from botstage.skills.nav.planner import Planner
from botstage.skills.nav.scan_match import ScanMatcher

RATE_HZ = 10.0
STILL_S = 10.0
MUSEUM_LOOP = [
    "hall_centre",
    "exhibit_a",
    "entrance",
    "reception",
    "exhibit_d",
    "gallery_door",
    "exhibit_b",
    "hall_centre",
]
RESTAURANT_LOOP = ["kitchen_door", "table_4", "table_6", "entrance", "table_3", "table_1", "kitchen_door"]
SEEDS = (1, 2, 3, 4, 5)


def robot_profile(name: str, imu: bool = True) -> Profile:
    """A shipped profile; with ``imu`` one is added where the profile has none (the PeopleBot's
    Pioneer base takes an optional gyro; the profile lists what the paper's robot carried)."""
    profile, problems, _ = load_profile(PROFILES_DIR / f"{name}.yaml")
    assert profile is not None, problems
    if imu and "imu" not in profile.interfaces:
        interfaces = {**profile.interfaces, "imu": Device(model="gyro added by the benchmark")}
        profile = profile.model_copy(update={"interfaces": interfaces})
    return profile


@dataclass
class Errors:
    """Position (m) and heading (rad) errors of one estimator against the truth, every tick."""

    position: list[float] = field(default_factory=list)
    heading: list[float] = field(default_factory=list)

    def add(self, estimate: Pose2D, truth: Pose2D) -> None:
        self.position.append(math.hypot(estimate.x - truth.x, estimate.y - truth.y))
        self.heading.append(abs(wrap(estimate.theta - truth.theta)))

    def figures(self) -> dict[str, float]:
        return {
            "final_cm": round(self.position[-1] * 100, 2),
            "max_cm": round(max(self.position) * 100, 2),
            "final_deg": round(math.degrees(self.heading[-1]), 3),
            "max_deg": round(math.degrees(max(self.heading)), 3),
        }


@dataclass
class LoopRun:
    distance_m: float
    seconds: float
    bumps: int
    errors: dict[str, Errors]
    map_localizer: Localizer | None
    ekf_localizer: Localizer
    match_times: list[float]
    final_truth: Pose2D
    final: dict[str, Pose2D]


def drive_loop(
    robot: str = "peoplebot",
    world: str = "museum",
    route: list[str] | None = None,
    seed: int = 1,
    people: int = 0,
    still_s: float = STILL_S,
    max_linear: float = 0.6,
) -> LoopRun:
    """Drive ``route`` (place names) on the true pose and track the estimators (see the module)."""
    grid: GridMap = load(MAPS_DIR / f"{world}.yaml")
    route = route or (MUSEUM_LOOP if world == "museum" else RESTAURANT_LOOP)
    profile = robot_profile(robot)
    clock = SimClock(RATE_HZ)
    start = grid.places[route[0]]
    sim = SimBackend(profile, grid, Pose2D(*start), seed, clock, people=people)
    devices = sim.devices
    with_map = Localizer.for_devices(devices, grid, profile) if "laser" in devices else None
    without_map = Localizer.for_devices({k: v for k, v in devices.items() if k != "laser"}, None, profile)
    match_times: list[float] = []
    if with_map is not None and with_map.matcher is not None:
        matcher = with_map.matcher
        plain = matcher.match

        def timed(*args: Any) -> Any:
            began = time.perf_counter()
            result = plain(*args)
            match_times.append(time.perf_counter() - began)
            return result

        matcher.match = timed  # type: ignore[method-assign]
    errors = {"odometry": Errors(), "ekf": Errors(), **({"map": Errors()} if with_map else {})}
    radius = profile.base.footprint_radius
    planner = Planner(grid, inflated_costs(grid, radius))
    params = FollowerParams(
        max_linear=min(max_linear, profile.base.max_linear),
        max_angular=1.5,
        robot_radius=radius,
        laser_x=profile.interfaces["laser"].pose[0] if "laser" in profile.interfaces else 0.0,
    )
    distance = 0.0

    def tick(v: float, w: float) -> None:
        nonlocal distance
        before = sim.world.body.pose
        sim.devices["drive"].cmd_vel(v, w)
        sim.step()
        clock.next_tick()
        truth = sim.world.body.pose
        distance += math.hypot(truth.x - before.x, truth.y - before.y)
        errors["odometry"].add(devices["odometry"].read().pose, truth)
        errors["ekf"].add(without_map.update().pose, truth)
        if with_map is not None:
            errors["map"].add(with_map.update().pose, truth)

    without_map.update()
    if with_map is not None:
        with_map.update()
    for _ in range(round(still_s * RATE_HZ)):
        tick(0.0, 0.0)
    for place in route[1:]:
        goal = grid.places[place]
        here = sim.world.body.pose
        plan = planner.plan((here.x, here.y), goal[:2])
        follower = PathFollower(plan.points, goal[2], params)
        for _ in range(round(240 * RATE_HZ)):
            sensed = devices["laser"].scan() if people and "laser" in devices else None  # people in the way
            command = follower.command(sim.world.body.pose, sensed)
            if command.state == "arrived":
                break
            tick(command.v, command.w)  # blocked: (0, 0) until the person moves on
        tick(0.0, 0.0)
    final = {"odometry": devices["odometry"].read().pose, "ekf": without_map.estimate().pose}
    if with_map is not None:
        final["map"] = with_map.estimate().pose
    return LoopRun(
        distance,
        clock.now(),
        sim.world.body.bumps,
        errors,
        with_map,
        without_map,
        match_times,
        sim.world.body.pose,
        final,
    )


def bench_drift(seeds: tuple[int, ...], people: int = 0) -> list[dict[str, Any]]:
    """The PeopleBot's museum loop per seed, and the mean over the seeds."""
    rows: list[dict[str, Any]] = []
    times: list[float] = []
    accepted = rejected = 0
    for seed in seeds:
        run = drive_loop(seed=seed, people=people)
        times += run.match_times
        assert run.map_localizer is not None
        accepted += run.map_localizer.matches_accepted
        rejected += run.map_localizer.matches_rejected
        rows.append(
            {
                "bench": "loc_drift_museum_loop",
                "seed": seed,
                "people": people,
                "distance_m": round(run.distance_m, 1),
                "sim_s": round(run.seconds, 1),
                "bumps": run.bumps,
                **{name: errors.figures() for name, errors in run.errors.items()},
                "matches": run.map_localizer.summary(),
            }
        )
    mean: dict[str, Any] = {"bench": "loc_drift_museum_loop_mean", "seeds": list(seeds), "people": people}
    for name in ("odometry", "ekf", "map"):
        mean[name] = {
            key: round(float(np.mean([row[name][key] for row in rows])), 3)
            for key in rows[0][name]  # type: ignore[index]
        }
    mean["distance_m"] = round(float(np.mean([row["distance_m"] for row in rows])), 1)
    rows.append(mean)
    if times:
        ms = np.array(times) * 1e3
        rows.append(
            {
                "bench": "loc_scan_match_time",
                "people": people,
                "matches": len(times),
                "median_ms": round(float(np.median(ms)), 3),
                "p90_ms": round(float(np.percentile(ms, 90)), 3),
                "max_ms": round(float(ms.max()), 3),
                "target_ms": 5.0,
                "acceptance": round(accepted / max(accepted + rejected, 1), 4),
            }
        )
    return rows


def bench_match_offsets(trials: int, seed: int = 0) -> dict[str, Any]:
    """Scan matches from random free poses of the museum with the prior 0.15 m and 4° off and a
    wide prior covariance (the search window at its largest): time, acceptance and error."""
    grid = load(MAPS_DIR / "museum.yaml")
    profile = robot_profile("peoplebot")
    device = profile.interfaces["laser"]
    matcher = ScanMatcher(grid, device.pose)
    prior_cov = np.diag([0.1**2, 0.1**2, math.radians(5) ** 2])
    rng = np.random.default_rng(seed)
    free = np.argwhere(grid.data == FREE)
    times, errors, reasons = [], [], Counter[str]()
    while len(times) < trials:
        x, y = grid.point(*free[rng.integers(len(free))])
        try:
            world = World(grid, profile, Pose2D(x, y, float(rng.uniform(-math.pi, math.pi))), seed=len(times))
        except ValueError:
            continue  # too close to a wall for the robot
        truth = world.body.pose
        fov = device.field_of_view or math.pi
        scan = LaserScan(0.0, -fov / 2, fov / 180, device.range_min or 0.0, 8.0, world.laser(device))
        bearing = rng.uniform(-math.pi, math.pi)
        prior = Pose2D(
            truth.x + 0.15 * math.cos(bearing), truth.y + 0.15 * math.sin(bearing), truth.theta + math.radians(4)
        )
        began = time.perf_counter()
        result = matcher.match(scan, prior, prior_cov)
        times.append(time.perf_counter() - began)
        reasons[result.reason] += 1
        if result.accepted:
            errors.append(
                (math.hypot(result.pose.x - truth.x, result.pose.y - truth.y), result.pose.theta - truth.theta)
            )
    ms = np.array(times) * 1e3
    position = np.array([e[0] for e in errors]) * 100
    heading = np.degrees(np.abs([wrap(e[1]) for e in errors]))
    return {
        "bench": "loc_scan_match_offset_0.15m_4deg",
        "trials": trials,
        "median_ms": round(float(np.median(ms)), 3),
        "p90_ms": round(float(np.percentile(ms, 90)), 3),
        "max_ms": round(float(ms.max()), 3),
        "target_ms": 5.0,
        "acceptance": round(len(errors) / trials, 4),
        "outcomes": dict(sorted(reasons.items())),
        "accepted_error_cm_mean": round(float(position.mean()), 2),
        "accepted_error_cm_max": round(float(position.max()), 2),
        "accepted_error_deg_max": round(float(heading.max()), 3),
    }


def bench_chefbot(seeds: tuple[int, ...]) -> list[dict[str, Any]]:
    """Chefbot (odometry + IMU, no laser) on a restaurant loop: the EKF's heading vs odometry's."""
    rows: list[dict[str, Any]] = []
    for seed in seeds:
        run = drive_loop(robot="chefbot", world="restaurant", seed=seed, max_linear=0.35)
        rows.append(
            {
                "bench": "loc_drift_chefbot_restaurant",
                "seed": seed,
                "distance_m": round(run.distance_m, 1),
                "sim_s": round(run.seconds, 1),
                "bumps": run.bumps,
                **{name: errors.figures() for name, errors in run.errors.items()},
                "gyro_bias": run.ekf_localizer.summary()["gyro_bias"],
            }
        )
    return rows


def main(quick: bool = False) -> list[dict[str, Any]]:
    seeds = SEEDS[:1] if quick else SEEDS
    results = bench_drift(seeds)
    results += bench_drift(seeds[:1] if quick else seeds[:3], people=20)
    results.append(bench_match_offsets(50 if quick else 300))
    results += bench_chefbot(seeds[:1] if quick else seeds[:3])
    for result in results:
        print(json.dumps(result), flush=True)
    return results


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:])
