"""Simulation speed: sim seconds per wall second, against real time.

The PeopleBot in the museum with 20 people, stepped at 10 Hz: the world (kinematics, collisions,
encoders, battery, IMU), the crowd, a full SICK laser scan (181 beams, 8 m) and a read of the
people tracker every tick, with the robot driving in circles. Not included: camera
rendering and audio, so this is an upper bound for a robot that reads its camera every tick; a second
row measures the camera's rendering alone (milliseconds per 640x480 frame).

Run with ``python -m tests.bench sim``.
"""

from __future__ import annotations

import json
import time
from typing import Any

from botstage.robots.clock import SimClock
from botstage.robots.gridmap import MAPS_DIR, load
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import load_profile
from botstage.robots.sim.backend import SimBackend

TARGET = 200.0  # sim seconds per wall second


def bench_museum(sim_seconds: float, repeats: int) -> dict[str, Any]:
    profile, problems, _ = load_profile(MAPS_DIR.parent / "profiles" / "peoplebot.yaml")
    assert profile is not None, problems
    grid = load(MAPS_DIR / "museum.yaml")

    def once() -> tuple[float, int]:
        clock = SimClock(10)
        backend = SimBackend(profile, grid, Pose2D(*grid.places["hall_centre"]), 1, clock, people=20)
        laser, tracker, drive = backend.devices["laser"], backend.devices["people"], backend.devices["drive"]
        seen = 0
        start = time.perf_counter()
        while clock.now() < sim_seconds:
            laser.scan()
            seen += len(tracker.people())
            drive.cmd_vel(0.3, 0.3)
            backend.step()
            clock.next_tick()
        return time.perf_counter() - start, seen

    runs = [once() for _ in range(repeats)]
    wall = min(r[0] for r in runs)
    return {
        "bench": "sim_museum",
        "robot": "peoplebot",
        "people": 20,
        "rate_hz": 10,
        "laser_beams": 181,
        "sim_s": sim_seconds,
        "wall_s": round(wall, 4),
        "speedup_vs_realtime": round(sim_seconds / wall, 1),
        "target": TARGET,
        "people_sightings": runs[0][1],
        "excludes": "camera rendering, audio",
    }


def bench_camera(frames: int) -> dict[str, Any]:
    """The PeopleBot's camera (640x480, as its profile says) rendered while it drives among 20 people:
    milliseconds per frame, one render a tick, against the tick's budget at 10 Hz."""
    profile, problems, _ = load_profile(MAPS_DIR.parent / "profiles" / "peoplebot.yaml")
    assert profile is not None, problems
    grid = load(MAPS_DIR / "museum.yaml")
    clock = SimClock(10)
    backend = SimBackend(profile, grid, Pose2D(*grid.places["hall_centre"]), 1, clock, people=20)
    camera, drive = backend.devices["camera"], backend.devices["drive"]
    times: list[float] = []
    for _ in range(frames):
        drive.cmd_vel(0.3, 0.3)
        backend.step()
        clock.next_tick()
        start = time.perf_counter()
        frame = camera.frame()
        times.append((time.perf_counter() - start) * 1000)
    times.sort()
    return {
        "bench": "sim_camera_frame",
        "robot": "peoplebot",
        "people": 20,
        "resolution": f"{frame.shape[1]}x{frame.shape[0]}",
        "frames": frames,
        "median_ms": round(times[len(times) // 2], 2),
        "p90_ms": round(times[int(len(times) * 0.9)], 2),
        "max_ms": round(times[-1], 2),
        "tick_budget_ms": 100.0,
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The benches slower than their target (sim seconds per wall second)."""
    return [r["bench"] for r in results if "target" in r and r["speedup_vs_realtime"] < r["target"]]


def main(quick: bool = False) -> list[dict[str, Any]]:
    results = [bench_museum(60.0 if quick else 600.0, 2 if quick else 3), bench_camera(100 if quick else 600)]
    for result in results:
        print(json.dumps(result), flush=True)
    return results


if __name__ == "__main__":
    main()
