"""Bittle's NyBoard driver and its gait odometry, each beside a baseline measured in the same run.
Run with `python -m tests.bench bittle`.

- **parser**: OpenCat replies (boot text, acknowledgements, warnings, IMU lines) through
  ``ReplyDecoder`` in 64-byte reads, against the line's 115200-baud byte rate (target >= 100x).
- **token_latency**: ``cmd_vel`` alternating between a walk and a turn, until the token's bytes
  are readable at the board's end of a pty (the test plays a silent board); beside ``pty_floor``,
  the same bytes written straight into the pty with no driver. Target p99 <= 2 ms (the serial
  bench's, for the Launchpad).
- **ack_round_trip**: a change of gait through the driver until it holds the emulated board's
  acknowledgement (``ack_delay_s`` 0: the firmware's own transition time left out), beside the
  same token written with pyserial and its echo read back from the same emulator (no driver).
- **gait_odometry**: the simulated Bittle walks a 120 s route of every gait and turn (seeded;
  the body slips 5 % a step on each side); the gait odometry's final position and heading error
  against the simulator's truth over ``seeds`` runs, and how often the truth lies within the odometry's own
  95 % bounds (its covariance's ellipse for the position, two standard deviations for the
  heading): an honest covariance gives about 90 % (0.95 squared).

Each figure is printed as one JSON line.
"""

from __future__ import annotations

import json
import math
import os
import select
import statistics
import time
from typing import Any

import numpy as np
import serial

from botstage.robots.clock import SimClock
from botstage.robots.drivers import opencat_protocol as opencat
from botstage.robots.drivers.bittle_base import BittleBase, open_bittle
from botstage.robots.emulators.nyboard import NyBoardEmulator
from botstage.robots.interfaces import Pose2D
from botstage.robots.places import robot_place
from botstage.robots.profile import Profile
from botstage.robots.sim.backend import SimBackend
from botstage.robots.sim.world import World
from tests.bench.bench_serial import Pty, bench_pty_floor, percentile

LINE_RATE_BYTES = 115200 / 10  # 8N1: ten bits a byte
TARGET_PARSER_RATIO = 100.0
TARGET_TOKEN_P99_MS = 2.0
CHI2_2D_95 = 5.991  # a 2-D Gaussian's 95 % ellipse, in squared Mahalanobis distance
ROUTE: list[tuple[float, float, float]] = [  # (v, w, seconds): every gait and both turns
    (0.05, 0.0, 15.0),
    (0.0, 0.4, 6.0),
    (0.1, 0.0, 20.0),
    (0.0, -0.4, 6.0),
    (0.2, 0.0, 15.0),
    (0.0, 0.4, 12.0),
    (0.1, 0.0, 20.0),
    (-0.06, 0.0, 10.0),
    (0.0, -0.4, 6.0),
    (0.05, 0.0, 10.0),
]


def _bittle() -> tuple[Profile, Any, Pose2D]:
    return robot_place("bittle", "restaurant", "10,7,0")


def _replies() -> bytes:
    boot = b"k\r\n\r\n* Start *\r\nBittle\r\nN_250224\r\nInit IMU\r\nSkill\r\nReady!\r\ng\r\nd\r\n"
    talk = b"G\r\nk\r\nk\r\n12.50\t-1.25\t0.75\r\nk\r\n?\r\nk\r\nLow power:6V\r\nP\r\np\r\nk\r\n"
    return (boot + talk * 20) * 200


def bench_parser(repeats: int) -> dict[str, Any]:
    data = _replies()
    best = math.inf
    replies = 0
    for _ in range(repeats):
        decoder = opencat.ReplyDecoder()
        began = time.perf_counter()
        replies = sum(len(decoder.feed(data[at : at + 64])) for at in range(0, len(data), 64))
        best = min(best, time.perf_counter() - began)
    ratio = len(data) / best / LINE_RATE_BYTES
    return {
        "bench": "bittle_parser",
        "bytes": len(data),
        "replies_per_s": round(replies / best),
        "mb_per_s": round(len(data) / best / 1e6, 2),
        "ratio_vs_115200_baud": round(ratio, 1),
        "target_ratio": TARGET_PARSER_RATIO,
        "meets_target": ratio >= TARGET_PARSER_RATIO,
    }


def bench_token_latency(commands: int) -> dict[str, Any]:
    profile, _, start = _bittle()
    pty = Pty()
    base = open_bittle(pty.path, profile, SimClock(10), start, ack_timeout_s=1e9, watchdog_s=1e9)
    assert base.link.wait_connected(5)
    latencies: list[float] = []
    try:
        for n in range(commands):
            pty.drain()
            v, w, token = (0.1, 0.0, b"kwkF\n") if n % 2 == 0 else (0.0, 0.4, b"kcrL\n")
            began = time.perf_counter()
            base.cmd_vel(v, w)
            pending = b""
            while token not in pending and time.perf_counter() - began < 1.0:
                if select.select([pty.master], [], [], 0.1)[0]:
                    pending += os.read(pty.master, 4096)
            assert token in pending, "the token never reached the pty"
            latencies.append((time.perf_counter() - began) * 1000)
    finally:
        base.close()
        pty.close()
    p99 = percentile(latencies, 99)
    return {
        "bench": "bittle_token_latency",
        "commands": commands,
        "p50_ms": round(statistics.median(latencies), 3),
        "p99_ms": round(p99, 3),
        "max_ms": round(max(latencies), 3),
        "target_p99_ms": TARGET_TOKEN_P99_MS,
        "meets_target": p99 <= TARGET_TOKEN_P99_MS,
    }


def _emulator(profile: Profile, start: Pose2D) -> NyBoardEmulator:
    grid = robot_place("bittle", "restaurant", "10,7,0")[1]
    return NyBoardEmulator(World(grid, profile, start, 0), boot_s=0.0, ack_delay_s=0.0).start()


def _acked(base: BittleBase, skill: str) -> bool:
    with base._lock:
        return base._acked == skill


def bench_ack_round_trip(changes: int) -> dict[str, Any]:
    profile, _, start = _bittle()
    board = _emulator(profile, start)
    driver_ms: list[float] = []
    raw_ms: list[float] = []
    try:
        deadline = time.monotonic() + 5
        while not board.ready and time.monotonic() < deadline:
            time.sleep(0.01)
        base = open_bittle(board.path, profile, SimClock(10), start, watchdog_s=1e9)
        try:
            assert base.link.wait_connected(5)
            for n in range(changes):
                v, w, skill = (0.1, 0.0, "wkF") if n % 2 == 0 else (0.0, 0.4, "crL")
                began = time.perf_counter()
                base.cmd_vel(v, w)
                while not _acked(base, skill) and time.perf_counter() - began < 2.0:
                    time.sleep(0.0001)
                assert _acked(base, skill), f"{skill} was never acknowledged"
                driver_ms.append((time.perf_counter() - began) * 1000)
        finally:
            base.close()
        with serial.Serial(board.path, opencat.BAUD, timeout=2.0) as port:
            port.write(opencat.REST)
            port.reset_input_buffer()
            for n in range(changes):
                token = opencat.skill_command("wkF" if n % 2 == 0 else "crL")
                began = time.perf_counter()
                port.write(token)
                while (line := port.readline()) and line.strip() != b"k":
                    pass
                assert line.strip() == b"k", "no acknowledgement"
                raw_ms.append((time.perf_counter() - began) * 1000)
    finally:
        board.close()
    return {
        "bench": "bittle_ack_round_trip",
        "changes": changes,
        "driver_p50_ms": round(statistics.median(driver_ms), 3),
        "driver_p99_ms": round(percentile(driver_ms, 99), 3),
        "raw_pyserial_p50_ms": round(statistics.median(raw_ms), 3),
        "raw_pyserial_p99_ms": round(percentile(raw_ms, 99), 3),
        "ratio_p50": round(statistics.median(driver_ms) / statistics.median(raw_ms), 2),
    }


def _walk(seed: int) -> tuple[float, float, bool]:
    """One route on the simulator: (position error m, heading error rad, truth within the 95 % bounds)."""
    profile, grid, start = _bittle()
    clock = SimClock(10.0)
    backend = SimBackend(profile, grid, start, seed, clock)
    drive, odometry = backend.devices["drive"], backend.devices["odometry"]
    for v, w, seconds in ROUTE:
        for _ in range(round(seconds / clock.period)):
            drive.cmd_vel(v, w)
            backend.step()
            clock.next_tick()
    reading = odometry.read()
    truth = backend.true_pose()
    dx, dy = reading.pose.x - truth.x, reading.pose.y - truth.y
    heading = abs(math.remainder(reading.pose.theta - truth.theta, math.tau))
    offset = np.array([dx, dy])
    mahalanobis = float(offset @ np.linalg.solve(reading.covariance[:2, :2], offset))
    within = mahalanobis <= CHI2_2D_95 and heading <= 2 * math.sqrt(reading.covariance[2, 2])
    return math.hypot(dx, dy), heading, within


def bench_gait_odometry(seeds: int) -> dict[str, Any]:
    runs = [_walk(seed) for seed in range(1, seeds + 1)]
    errors = [r[0] for r in runs]
    headings = [math.degrees(r[1]) for r in runs]
    distance = sum(abs(v) * s for v, _, s in ROUTE) + sum(0.03 * s for v, w, s in ROUTE if v == 0 and w)
    return {
        "bench": "bittle_gait_odometry",
        "seeds": seeds,
        "route_s": sum(s for _, _, s in ROUTE),
        "route_m": round(distance, 2),
        "position_error_mean_cm": round(statistics.mean(errors) * 100, 1),
        "position_error_p95_cm": round(percentile(errors, 95) * 100, 1),
        "heading_error_mean_deg": round(statistics.mean(headings), 1),
        "heading_error_p95_deg": round(percentile(headings, 95), 1),
        "within_95_percent_bounds": round(sum(r[2] for r in runs) / len(runs), 2),
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    return [r["bench"] for r in results if r.get("meets_target") is False]


def main(quick: bool = False) -> list[dict[str, Any]]:
    commands = 200 if quick else 2000
    results: list[dict[str, Any]] = []
    for measure in (
        lambda: bench_parser(2 if quick else 5),
        lambda: bench_token_latency(commands),
        lambda: bench_pty_floor(commands),
        lambda: bench_ack_round_trip(50 if quick else 500),
        lambda: bench_gait_odometry(3 if quick else 20),
    ):
        result = measure()
        results.append(result)
        print(json.dumps(result), flush=True)
    return results
