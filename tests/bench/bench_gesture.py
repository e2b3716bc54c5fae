"""The gesture controller of the book's chapter 5 (the hand's IMU over rosserial, the converter),
each figure beside a baseline measured in the same run. Run with `python -m tests.bench gesture`.

- **parser**: what the gesture sketch sends (the time request and the TopicInfo of ``/tf`` and
  ``imu_data`` after the host's topic request, then per loop an ``imu_data`` Vector3 and a
  ``/tf`` transform, a time request every 2.5 s, a device log now and then, and some line
  noise) through the driver's ``PacketDecoder`` in 64-byte reads; packets and bytes per second
  against the line's 57600-baud byte rate (target >= 100x, Bittle's). ``with_messages`` also
  deserialises every payload with rosbags, as the driver's reader thread does.
- **sample_latency**: an ``imu_data`` packet written into the pty at the Arduino's end (the
  bench plays the board: it answers the driver's topic request with the sketch's TopicInfo,
  then sends each orientation with a new yaw) until ``RosserialDriver.orientation()`` hands out
  that yaw; ``received`` says when the driver's reader thread read its last bytes (the part
  before it the pty's and pyserial's). Beside ``pty_floor``: the same packet written on the
  master and read on the slave with no driver (bench_serial's helper, the board-to-host way).
  Target p99 <= 2 ms (the serial bench's, for the Launchpad). Times on the monotonic clock.
- **converter**: the chapter's converter (``gesture_teleop.py``, written here as the baseline:
  previous yaw and pitch starting at 0, ``int()`` of the changes and of the pitch, the home
  test ``-2 < int(pitch) < 2`` with no yaw change, ``round(..., 2)``, clamps by ``if/elif``)
  against ``botstage.skills.gesture.GestureConverter`` on the same scripted hand motions, sampled as the
  sketch publishes (2.5 Hz, float32 values): a slow tilt (0.5 degrees a sample), a slow turn
  (0.75 degrees a sample), a tilt at 1.6 degrees a sample, the speed clamped while the hand
  still turns (``step_size`` 0.05, a value the chapter's yaml allows), and a turn across the
  DMP's yaw wrap at ±180 degrees. Each starts with a second at rest (level and still: both
  converters stop there and take it as the reference, and the chapter's start from 0 is washed
  out). The intended speed and turn at each sample are ``step_size`` times the pitch (yaw)
  change since the rest, the yaw's taken the short way, each clamped to its range (in the
  chapter's units: m/s and rad/s of its TurtleBot, ±4 and ±2); the figures are each
  converter's final speed and turn, and its largest and mean error over the samples after the rest.

Each figure is printed as one JSON line.
"""

from __future__ import annotations

import json
import math
import os
import random
import select
import statistics
import time
from dataclasses import dataclass
from typing import Any

from botstage.robots.drivers import rosserial_protocol as rp
from botstage.robots.drivers.rosserial import BAUD, RosserialDriver
from botstage.robots.emulators.imu_arduino import BUFFER_SIZE, IMU_TOPIC, TF_TOPIC, VECTOR3, HandScript, as_published
from botstage.skills.gesture import GestureConfig, GestureConverter
from tests.bench.bench_serial import TARGET_P99_MS, Pty, bench_pty_floor, percentile

LINE_RATE_BYTES = BAUD / 10  # 8N1: ten bits a byte
TARGET_PARSER_RATIO = 100.0
IMU_ID, TF_ID = 126, 125  # the sketch's publishers on an Uno (see botstage.robots.emulators.imu_arduino)
PERIOD_S = 0.4  # the sketch publishes at 2.5 Hz
REST_SAMPLES = 3  # a second at rest before each motion (the reference; left out of the errors)


# -- parser -----------------------------------------------------------------------------------------


def _vector3(yaw: float, pitch: float, roll: float) -> bytes:
    return rp.encode_packet(IMU_ID, rp.serialize(rp.TYPESTORE.types[VECTOR3](x=yaw, y=pitch, z=roll)))


def _tf(k: int) -> bytes:
    types = rp.TYPESTORE.types
    transform = types["geometry_msgs/msg/TransformStamped"](
        header=types["std_msgs/msg/Header"](
            seq=0, stamp=rp.time_message(1000.0 + k * PERIOD_S).data, frame_id="/base_link"
        ),
        child_frame_id="/imu_frame",
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=1.0, y=0.0, z=0.0),
            rotation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(k / 20), w=math.cos(k / 20)),
        ),
    )
    return rp.encode_packet(TF_ID, rp.serialize(types[rp.TF_MESSAGE](transforms=[transform])))


def sketch_stream(loops: int, seed: int = 0) -> bytes:
    """What the gesture sketch sends after the host's topic request, ``loops`` passes of its loop."""
    rng = random.Random(seed)
    time_request = rp.encode_packet(rp.ID_TIME, rp.serialize(rp.time_message(0.0)))
    out = [
        time_request,
        rp.encode_packet(rp.ID_PUBLISHER, rp.serialize(rp.topic_info(TF_ID, TF_TOPIC, rp.TF_MESSAGE, BUFFER_SIZE))),
        rp.encode_packet(rp.ID_PUBLISHER, rp.serialize(rp.topic_info(IMU_ID, IMU_TOPIC, VECTOR3, BUFFER_SIZE))),
    ]
    script = HandScript.default()
    for k in range(loops):
        out.append(_vector3(*as_published(script.at(k * PERIOD_S))))
        out.append(_tf(k))
        if k % 6 == 5:  # ros_lib asks for the time every 2.5 s
            out.append(time_request)
        if k % 50 == 25:
            out.append(rp.encode_packet(rp.ID_LOG, rp.serialize(rp.log_message(rp.WARN, "FIFO overflow!"))))
        if k % 40 == 10:  # line noise
            out.append(bytes(rng.randrange(256) for _ in range(rng.randint(3, 24))).replace(b"\xff", b"\x00"))
    return b"".join(out)


def bench_parser(loops: int, repeats: int) -> dict[str, Any]:
    data = sketch_stream(loops)
    best = best_messages = math.inf
    packets = 0
    decoder = rp.PacketDecoder()
    for _ in range(repeats):
        decoder = rp.PacketDecoder()
        began = time.perf_counter()
        packets = sum(len(decoder.feed(data[at : at + 64])) for at in range(0, len(data), 64))
        best = min(best, time.perf_counter() - began)
    types = {
        IMU_ID: VECTOR3,
        TF_ID: rp.TF_MESSAGE,
        rp.ID_PUBLISHER: rp.TOPIC_INFO,
        rp.ID_TIME: rp.TIME,
        rp.ID_LOG: rp.LOG,
    }
    for _ in range(repeats):
        framer = rp.PacketDecoder()
        began = time.perf_counter()
        for at in range(0, len(data), 64):
            for packet in framer.feed(data[at : at + 64]):
                rp.deserialize(packet.payload, types[packet.topic_id])
        best_messages = min(best_messages, time.perf_counter() - began)
    ratio = len(data) / best / LINE_RATE_BYTES
    return {
        "bench": "gesture_parser",
        "bytes": len(data),
        "packets": packets,
        "imu_messages": decoder.ok[f"topic_{IMU_ID}"],
        "garbage_stretches": decoder.bad["garbage"],
        "packets_per_s": round(packets / best),
        "bytes_per_s": round(len(data) / best),
        "line_rate_bytes_per_s": LINE_RATE_BYTES,
        "ratio_vs_57600_baud": round(ratio, 1),
        "with_messages_packets_per_s": round(packets / best_messages),
        "with_messages_ratio_vs_57600_baud": round(len(data) / best_messages / LINE_RATE_BYTES, 1),
        "target_ratio": TARGET_PARSER_RATIO,
        "meets_target": ratio >= TARGET_PARSER_RATIO,
    }


# -- sample latency ---------------------------------------------------------------------------------


def _read_until(fd: int, wanted: bytes, timeout: float) -> bool:
    pending = b""
    deadline = time.monotonic() + timeout
    while wanted not in pending and time.monotonic() < deadline:
        if select.select([fd], [], [], 0.05)[0]:
            pending += os.read(fd, 4096)
    return wanted in pending


def bench_sample_latency(samples: int) -> dict[str, Any]:
    pty = Pty()
    driver = RosserialDriver(pty.path, sync_timeout_s=1e9, silence_s=None)
    rng = random.Random(5)
    latencies: list[float] = []
    reads: list[float] = []
    try:
        assert driver.link.wait_connected(5), "the driver never opened the pty"
        assert _read_until(pty.master, rp.TOPIC_REQUEST, 5), "no topic request from the driver"
        os.write(
            pty.master,
            rp.encode_packet(rp.ID_PUBLISHER, rp.serialize(rp.topic_info(IMU_ID, IMU_TOPIC, VECTOR3, BUFFER_SIZE))),
        )
        assert driver.wait_until(lambda: IMU_ID in driver.publishers, 5), "the TopicInfo was not learned"
        for n in range(samples):
            pty.drain()  # what the driver wrote (nothing, unless it asked again)
            yaw = (n % 359) - 179.5  # a new yaw each sample, exact in float32
            packet = _vector3(yaw, 10.0, -3.0)
            began = time.monotonic()
            os.write(pty.master, packet)
            arrived = driver.wait_until(lambda y=yaw: (o := driver.orientation()) is not None and o.yaw == y, 1.0)
            handed = time.monotonic()
            assert arrived, "the orientation never reached the driver"
            sample = driver.orientation()
            assert sample is not None
            latencies.append((handed - began) * 1000)
            reads.append((sample.received - began) * 1000)
            time.sleep(rng.uniform(0.001, 0.005))
    finally:
        driver.close()
        pty.close()
    p99 = percentile(latencies, 99)
    return {
        "bench": "gesture_sample_latency",
        "samples": samples,
        "packet_bytes": len(_vector3(0.0, 0.0, 0.0)),
        "p50_ms": round(statistics.median(latencies), 3),
        "p99_ms": round(p99, 3),
        "max_ms": round(max(latencies), 3),
        "received_p50_ms": round(statistics.median(reads), 3),
        "received_p99_ms": round(percentile(reads, 99), 3),
        "target_p99_ms": TARGET_P99_MS,
        "meets_target": p99 <= TARGET_P99_MS,
    }


def bench_floor(samples: int) -> dict[str, Any]:
    result = bench_pty_floor(samples, data=_vector3(0.5, 10.0, -3.0), to_host=True)
    result["packet_bytes"] = len(_vector3(0.0, 0.0, 0.0))
    return result


# -- the converter ----------------------------------------------------------------------------------


@dataclass
class ChapterConverter:
    """The chapter's converter (gesture_teleop.py's ``Get_RPY`` and ``Send_Twist``), quirks
    kept: the baseline. Previous yaw and pitch start at 0; the changes and the pitch are
    truncated by ``int()``; ``round(..., 2)``; the clamps are ``if speed ... elif turn``."""

    config: GestureConfig
    speed: float = 0.0
    turn: float = 0.0
    prev_yaw: float = 0.0
    prev_pitch: float = 0.0

    def update(self, yaw: float, pitch: float) -> tuple[float, float]:
        c = self.config
        dy, dp, check_pitch = int(yaw - self.prev_yaw), int(pitch - self.prev_pitch), int(pitch)
        self.prev_yaw, self.prev_pitch = yaw, pitch
        if -2 < check_pitch < 2 and dy == 0:
            self.speed = self.turn = 0.0
        else:
            self.speed = round(self.speed + c.step_size * dp, 2)
            self.turn = round(self.turn + c.step_size * dy, 2)
            if self.speed > c.high_speed:
                self.speed = c.high_speed
            elif self.turn > c.high_turn:
                self.turn = c.high_turn
            if self.speed < c.low_speed:
                self.speed = c.low_speed
            elif self.turn < c.low_turn:
                self.turn = c.low_turn
        return self.speed, self.turn


# (name, step_size, keyframes (t, yaw, pitch, roll)): each starts with a second at rest
MOTIONS: list[tuple[str, float, list[tuple[float, float, float, float]]]] = [
    # tilted 10 degrees at once, then on to 30 at 0.5 degrees a sample (1.25 degrees/s)
    ("slow_tilt", 0.02, [(0.0, 0.0, 0.0, 0.0), (0.8, 0.0, 0.0, 0.0), (1.2, 0.0, 10.0, 0.0), (17.2, 0.0, 30.0, 0.0)]),
    # tilted 10 degrees (driving), then turned 30 degrees left at 0.75 degrees a sample
    ("slow_turn", 0.02, [(0.0, 0.0, 0.0, 0.0), (0.8, 0.0, 0.0, 0.0), (1.2, 0.0, 10.0, 0.0), (17.2, 30.0, 10.0, 0.0)]),
    # tilted 10 degrees, then on to 42 at 1.6 degrees a sample: int() keeps 1 of each 1.6
    (
        "tilt_1.6_deg_a_sample",
        0.02,
        [(0.0, 0.0, 0.0, 0.0), (0.8, 0.0, 0.0, 0.0), (1.2, 0.0, 10.0, 0.0), (9.2, 0.0, 42.0, 0.0)],
    ),
    # step 0.05: tilted to 80 (the speed's limit) while turning 30 left, then on to 90 while
    # turning on to 80 left (the turn's limit is 40): the speed is clamped as the hand turns
    (
        "clamped_speed_turning",
        0.05,
        [
            (0.0, 0.0, 0.0, 0.0),
            (0.8, 0.0, 0.0, 0.0),
            (4.8, 30.0, 80.0, 0.0),
            (8.8, 80.0, 90.0, 0.0),
            (10.0, 80.0, 90.0, 0.0),
        ],
    ),
    # resting at yaw 170 (the DMP's yaw is where the board powered up), tilted 10 degrees,
    # then 20 degrees left at 2 degrees a sample, across the wrap to -170
    (
        "yaw_wrap",
        0.02,
        [
            (0.0, 170.0, 0.0, 0.0),
            (0.8, 170.0, 0.0, 0.0),
            (1.2, 170.0, 10.0, 0.0),
            (5.2, -170.0, 10.0, 0.0),
            (6.4, -170.0, 10.0, 0.0),
        ],
    ),
]


def _clamp(value: float, low: float, high: float) -> float:
    return max(low, min(high, value))


def run_motion(step_size: float, keyframes: list[tuple[float, float, float, float]]) -> dict[str, Any]:
    """Both converters on one motion sampled at 2.5 Hz: final (speed, turn) and the errors."""
    config = GestureConfig(step_size=step_size)
    script = HandScript(keyframes, loop=False)
    chapter, fixed = ChapterConverter(config), GestureConverter(config)
    count = round(script.duration / PERIOD_S) + 1
    samples = [as_published(script.at(round(k * PERIOD_S, 9))) for k in range(count)]
    yaw0, pitch0 = samples[0][0], samples[0][1]
    turned = 0.0
    previous = yaw0
    errors: dict[str, list[float]] = {"chapter": [], "fixed": []}
    intended = (0.0, 0.0)
    for k, (yaw, pitch, _) in enumerate(samples):
        turned += math.remainder(yaw - previous, 360.0)  # the hand's motion, the short way
        previous = yaw
        intended = (
            _clamp(step_size * (pitch - pitch0), config.low_speed, config.high_speed),
            _clamp(step_size * turned, config.low_turn, config.high_turn),
        )
        for name, converter in (("chapter", chapter), ("fixed", fixed)):
            speed, turn = converter.update(yaw, pitch)
            if k >= REST_SAMPLES:
                errors[name].append(max(abs(speed - intended[0]), abs(turn - intended[1])))
    return {
        "samples": count,
        "intended": [round(v, 3) for v in intended],
        "chapter": [round(chapter.speed, 3), round(chapter.turn, 3)],
        "fixed": [round(fixed.speed, 3), round(fixed.turn, 3)],
        "chapter_error_max": round(max(errors["chapter"]), 3),
        "fixed_error_max": round(max(errors["fixed"]), 3),
        "chapter_error_mean": round(statistics.mean(errors["chapter"]), 3),
        "fixed_error_mean": round(statistics.mean(errors["fixed"]), 3),
    }


def bench_converter() -> dict[str, Any]:
    motions = {name: run_motion(step, frames) for name, step, frames in MOTIONS}
    return {
        "bench": "gesture_converter",
        "units": "final [speed m/s, turn rad/s] in the chapter's ranges (±4, ±2); error: max of |speed|, |turn| error",
        "motions": motions,
        "chapter_error_max": max(m["chapter_error_max"] for m in motions.values()),
        "fixed_error_max": max(m["fixed_error_max"] for m in motions.values()),
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    return [r["bench"] for r in results if r.get("meets_target") is False]


def main(quick: bool = False) -> list[dict[str, Any]]:
    samples = 200 if quick else 2000
    results: list[dict[str, Any]] = []
    for measure in (
        lambda: bench_parser(2000 if quick else 20000, 2 if quick else 5),
        lambda: bench_sample_latency(samples),
        lambda: bench_floor(samples),
        bench_converter,
    ):
        result = measure()
        results.append(result)
        print(json.dumps(result), flush=True)
    return results
