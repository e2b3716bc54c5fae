"""The gesture controller's Arduino (book ch. 5) on a pseudo-terminal: an MPU-6050 whose DMP
orientation a rosserial sketch publishes, with the hand that moves it played from a script.

Sources: qboticslabs/ros_robotics_projects ``chapter_5_codes/MPU9250_ROS_DMP/
MPU9250_ROS_DMP_Debug.ino`` (the sketch), ``chapter_5_codes/gesture_teleop/scripts/
gesture_teleop.py`` (its consumer); ros-drivers/rosserial ``rosserial_client/src/ros_lib/ros/
node_handle.h``, ``ros/msg.h``, ``tf/transform_broadcaster.h`` and ``rosserial_arduino/src/
ros_lib/ros.h`` (the device side of the protocol). Facts taken:

- The sketch publishes ``geometry_msgs/Vector3`` on ``imu_data`` with ``x = yaw``,
  ``y = pitch``, ``z = roll`` **in degrees** (``ypr[i] * 180/M_PI`` of the DMP's
  ``dmpGetYawPitchRoll``); the teleop node reads x as yaw and y as pitch. The DMP's yaw is in
  (-180, 180], its pitch and roll within ±90. On an AVR a ``double`` is a 32-bit float, which
  ros_lib widens to float64 on the wire (``serializeAvrFloat64``): values carry float32
  precision, and so do the emulator's.
- It also broadcasts TF (``tf::TransformBroadcaster``, ``tf/tfMessage`` on ``/tf``): frame
  ``/base_link`` to ``/imu_frame``, translation x = 1.0, the DMP quaternion, stamped with
  ``nh.now()``. ``broadcaster.init(nh)`` comes before ``nh.advertise(imu_pub)``, so ``/tf`` is
  the first publisher: on an ATmega328P (``NodeHandle_<ArduinoHardware, 25, 25, 280, 280>``,
  decision: the book's board is taken to be an Uno) publisher ids start at 100 + 25, so
  ``/tf`` is 125 and ``imu_data`` 126, each announced with buffer_size 280.
- The sketch (in a folder named for the MPU-9250) drives the IMU with the MPU-6050 library's
  DMP (``MPU6050_6Axis_MotionApps20.h``).
- **Rate**: each ``loop()`` publishes once, spins once and waits ``delay(200)`` twice: one
  publication every 0.4 s, **2.5 Hz** (the default ``publish_hz``; faster for tests). The
  DMP's FIFO may overflow during those delays, and the sketch's overflow branch then resets it
  without publishing, so a real board may publish less often; that is not played.
- NodeHandle (device side): publications (ids from 100) are dropped until the host's topic
  request configured it; the request is answered with a time request and one TopicInfo per
  publisher, and ends that ``spinOnce``; a time reply sets ``now()`` (the round trip's time
  added); a time request goes out every 2.5 s while configured, and 11 s without a reply
  unconfigure it; a tx stop request unconfigures it; a packet of a wrong protocol version
  heard while unconfigured is answered with a time request.

Decisions: the hand's script gives the published yaw/pitch/roll directly, linearly interpolated
between keyframes (yaw along the shorter arc); "forward", "back", "left", "right" are named
after what gesture_teleop.py makes of them (pitch up: faster; yaw up: turn left). The TF
quaternion is the ZYX one of (roll, -pitch, -yaw), which the DMP's formulas give back exactly
when one angle moves at a time, as in the default script. The USB powers the board, so
plugging it in boots it (``boot_s`` of silence, then unconfigured); the DTR reset that opening
a port gives an Uno cannot be seen on a pty and is not played.

Faults (bounded arguments, ``ValueError`` beyond): from ``PtyBoard``, ``inject_garbage``,
``drop_lines`` (here whole packets; ``drop_packets`` says so), ``unplug``/``replug``/
``disconnect``; here, ``cut_packets`` (only a head of each goes out), ``corrupt_checksums``,
``lie_about_length`` (a length field, with a valid checksum, larger than the packet) and
``log`` (a device log message, as ``nh.logwarn`` sends).
"""

from __future__ import annotations

import bisect
import itertools
import math
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from botstage.robots.drivers import rosserial_protocol as rp
from botstage.robots.emulators.pty_board import MAX_DROP, MAX_GARBAGE, MAX_UNPLUG_S, PtyBoard

__all__ = [
    "DEFAULT_KEYFRAMES",
    "MAX_DROP",
    "MAX_GARBAGE",
    "MAX_KEYFRAMES",
    "MAX_UNPLUG_S",
    "PUBLISH_HZ",
    "HandScript",
    "ImuArduino",
    "Sample",
    "as_published",
    "dmp_quaternion",
]

PUBLISH_HZ = 2.5  # the sketch: delay(200) twice per loop()
IMU_TOPIC = "imu_data"
TF_TOPIC = "/tf"
VECTOR3 = "geometry_msgs/msg/Vector3"
MAX_SUBSCRIBERS = 25  # ros.h for the ATmega328P
BUFFER_SIZE = 280  # ros.h for the ATmega328P: INPUT_SIZE = OUTPUT_SIZE = 280
SYNC_SECONDS = 5  # node_handle.h: a time request every SYNC_SECONDS * 500 ms, unconfigured after * 2200 ms
MAX_KEYFRAMES = 100_000
MAX_SCRIPT_S = 86_400.0
RX_PACKETS = 32  # packets heard and not yet handled by a spinOnce (more are lost, like a full UART buffer)

# (seconds, yaw, pitch, roll) in degrees: home, forward, back, left, right, home
DEFAULT_KEYFRAMES: tuple[tuple[float, float, float, float], ...] = (
    (0.0, 0.0, 0.0, 0.0),
    (1.0, 0.0, 0.0, 0.0),  # home
    (2.0, 0.0, 30.0, 5.0),  # tilt forward (the hand rolls a little)
    (3.0, 0.0, 30.0, 5.0),
    (4.0, 0.0, 0.0, 0.0),
    (5.0, 0.0, -30.0, -5.0),  # tilt back
    (6.0, 0.0, -30.0, -5.0),
    (7.0, 0.0, 0.0, 0.0),
    (8.0, 45.0, 0.0, 0.0),  # yaw left
    (9.0, 45.0, 0.0, 0.0),
    (11.0, -45.0, 0.0, 0.0),  # yaw right
    (12.0, -45.0, 0.0, 0.0),
    (13.0, 0.0, 0.0, 0.0),  # home
    (14.0, 0.0, 0.0, 0.0),
)


def _wrap180(degrees: float) -> float:
    """An angle in (-180, 180]."""
    wrapped = math.remainder(degrees, 360.0)
    return 180.0 if wrapped == -180.0 else wrapped


def as_published(ypr: tuple[float, float, float]) -> tuple[float, float, float]:
    """Yaw, pitch, roll as an AVR holds them (float32) and ros_lib sends them (widened exactly)."""
    return tuple(float(np.float32(v)) for v in ypr)  # type: ignore[return-value]


class HandScript:
    """A hand's orientation over time: keyframes ``(t, yaw, pitch, roll)`` (seconds, degrees),
    linearly interpolated (yaw along the shorter arc), replayed from the start when ``loop``."""

    def __init__(self, keyframes: Iterable[Sequence[float]], *, loop: bool = True) -> None:
        frames = [tuple(float(v) for v in frame) for frame in keyframes]
        if not 1 <= len(frames) <= MAX_KEYFRAMES:
            raise ValueError(f"{len(frames)} keyframes: 1 to {MAX_KEYFRAMES:,}")
        for frame in frames:
            if len(frame) != 4 or not all(math.isfinite(v) for v in frame):
                raise ValueError(f"keyframe {frame}: four finite numbers (t, yaw, pitch, roll)")
            t, yaw, pitch, roll = frame
            if not (0.0 <= t <= MAX_SCRIPT_S and -180.0 <= yaw <= 180.0 and abs(pitch) <= 90.0 and abs(roll) <= 90.0):
                raise ValueError(f"keyframe {frame}: t in 0..{MAX_SCRIPT_S:g} s, yaw in ±180, pitch and roll in ±90")
        times = [frame[0] for frame in frames]
        if any(b <= a for a, b in itertools.pairwise(times)):
            raise ValueError("keyframe times must increase")
        self.keyframes: tuple[tuple[float, float, float, float], ...] = tuple(frames)  # type: ignore[arg-type]
        self.times = times
        self.loop = loop

    @classmethod
    def default(cls) -> HandScript:
        return cls(DEFAULT_KEYFRAMES)

    @property
    def duration(self) -> float:
        return self.times[-1]

    def scaled(self, factor: float) -> HandScript:
        """The same motion ``factor`` times slower (faster below 1)."""
        if not (math.isfinite(factor) and factor > 0 and self.duration * factor <= MAX_SCRIPT_S):
            raise ValueError(f"scale {factor}: more than 0, the script at most {MAX_SCRIPT_S:g} s")
        return HandScript([(t * factor, *rest) for t, *rest in self.keyframes], loop=self.loop)

    def at(self, t: float) -> tuple[float, float, float]:
        """Yaw, pitch, roll (degrees) at ``t`` seconds from the start."""
        start = self.times[0]
        if self.loop and self.duration > start and t > self.duration:
            t = start + math.fmod(t - start, self.duration - start)
        index = bisect.bisect_right(self.times, t)
        if index == 0:
            return self.keyframes[0][1:]
        if index == len(self.times):
            return self.keyframes[-1][1:]
        (t0, y0, p0, r0), (t1, y1, p1, r1) = self.keyframes[index - 1], self.keyframes[index]
        share = (t - t0) / (t1 - t0)
        yaw = _wrap180(y0 + share * math.remainder(y1 - y0, 360.0))
        return yaw, p0 + share * (p1 - p0), r0 + share * (r1 - r0)


def dmp_quaternion(yaw: float, pitch: float, roll: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) whose DMP yaw/pitch/roll are these degrees, one angle at a time (see the module)."""
    half = [math.radians(a) / 2 for a in (roll, -pitch, -yaw)]
    (cr, cp, cy), (sr, sp, sy) = [math.cos(a) for a in half], [math.sin(a) for a in half]
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


@dataclass(frozen=True, slots=True)
class Sample:
    """One imu_data publication: the script's time (s since boot) and the values sent."""

    t: float
    ypr: tuple[float, float, float]


class ImuArduino(PtyBoard):
    """The sketch on a pty; see the module. ``start()`` (or a ``with`` block) plugs it in.

    ``lockstep``: each loop pass moves the hand by exactly one period (a deterministic sequence
    of samples, for tests); otherwise the hand moves with ``monotonic``. ``samples`` keeps the
    last ``keep_samples`` imu_data publications (what the firmware sent, before line faults).
    """

    REBOOTS_ON_PLUG = True

    def __init__(
        self,
        script: HandScript | None = None,
        *,
        publish_hz: float = PUBLISH_HZ,
        lockstep: bool = False,
        publish_tf: bool = True,
        boot_s: float = 0.0,
        keep_samples: int = 10_000,
        link_dir: Path | None = None,
        seed: int = 0,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (math.isfinite(publish_hz) and 0 < publish_hz <= 1000):
            raise ValueError(f"publish_hz {publish_hz}: more than 0, at most 1000")
        if not (math.isfinite(boot_s) and 0 <= boot_s <= MAX_UNPLUG_S):
            raise ValueError(f"boot_s {boot_s}: 0 to {MAX_UNPLUG_S:g}")
        if not 0 <= keep_samples <= 1_000_000:
            raise ValueError(f"keep_samples {keep_samples}: 0 to 1,000,000")
        super().__init__(
            name="imu-arduino",
            link_name="ttyIMU",
            loop_hz=publish_hz,
            link_dir=link_dir,
            seed=seed,
            monotonic=monotonic,
        )
        self.script = script or HandScript.default()
        self.lockstep = lockstep
        self.boot_s = boot_s
        endpoints = [(TF_TOPIC, rp.TF_MESSAGE)] if publish_tf else []
        endpoints.append((IMU_TOPIC, VECTOR3))
        first = rp.FIRST_DYNAMIC_ID + MAX_SUBSCRIBERS
        self.endpoints = {name: (first + slot, typename) for slot, (name, typename) in enumerate(endpoints)}
        self.samples: deque[Sample] = deque(maxlen=keep_samples)
        self.decoder = rp.PacketDecoder(max_payload=BUFFER_SIZE)
        self._rx: deque[rp.Packet] = deque()
        self._logs: deque[bytes] = deque(maxlen=64)
        self._cut = self._corrupt = self._lie = 0
        self._boot(monotonic())

    # -- faults -------------------------------------------------------------------------------

    def drop_packets(self, count: int) -> None:
        """The next ``count`` packets are lost."""
        self.drop_lines(count)

    def cut_packets(self, count: int) -> None:
        """Only a head of each of the next ``count`` packets goes out (the rest is lost)."""
        self._add_fault("_cut", count)

    def corrupt_checksums(self, count: int) -> None:
        """The next ``count`` packets go out with a wrong checksum."""
        self._add_fault("_corrupt", count)

    def lie_about_length(self, count: int) -> None:
        """The next ``count`` packets claim to be longer than they are (with a valid length checksum)."""
        self._add_fault("_lie", count)

    def log(self, level: int, text: str) -> None:
        """A log message from the device (``nh.loginfo`` and the like) in the next pass."""
        payload = rp.serialize(rp.log_message(level, text))
        if not rp.ROSDEBUG <= level <= rp.FATAL or len(payload) + rp.OVERHEAD > BUFFER_SIZE:
            raise ValueError(f"a log of level {level} and {len(text)} characters: level 0 to 4, it must fit 280 bytes")
        with self._fault_lock:
            self._logs.append(rp.encode_packet(rp.ID_LOG, payload))

    def set_script(self, script: HandScript) -> None:
        """Another hand motion, from its start now."""
        with self._fault_lock:
            self.script = script
            self._script_t = 0.0
            self._script_start = self.monotonic()

    def _add_fault(self, name: str, count: int) -> None:
        with self._fault_lock:
            waiting = getattr(self, name)
            if not 0 <= count <= MAX_DROP - waiting:
                raise ValueError(f"{count} packets: 0 to {MAX_DROP - waiting:,} more may wait")
            setattr(self, name, waiting + count)

    # -- what the host can see of the device ---------------------------------------------------

    @property
    def configured(self) -> bool:
        return self._configured

    def device_now(self) -> float | None:
        """``nh.now()``: the host's time as the device keeps it since its last time reply (None before)."""
        if self._time_offset is None:
            return None
        return self._millis(self.monotonic()) / 1000 + self._time_offset

    # -- the firmware -------------------------------------------------------------------------

    def _boot(self, at: float) -> None:
        self._booted_at = at
        self._booting_until = at + self.boot_s
        self._configured = False
        self._time_offset: float | None = None
        self._rt_time = 0
        self._last_sync_time = 0
        self._last_sync_receive_time = 0
        self._script_t = 0.0
        self._script_start = at
        self._version_errors = 0
        self.decoder.resync()
        self._rx.clear()

    def _millis(self, now: float) -> int:
        return int((now - self._booted_at) * 1000) % 2**32

    def _received(self, data: bytes) -> None:
        if self.monotonic() < self._booting_until:
            self.counters["bytes_unheard"] += len(data)  # a board in its bootloader hears nothing
            return
        for packet in self.decoder.feed(data):
            if len(self._rx) >= RX_PACKETS:
                self.counters["rx_overflow"] += 1
                continue
            self._rx.append(packet)

    def _loop(self, now: float, dt: float) -> None:
        if now < self._booting_until:
            return
        with self._fault_lock:
            if self.lockstep:
                t = self._script_t
                self._script_t += self.period
            else:
                t = now - self._script_start
            ypr = as_published(self.script.at(t))
            logs = list(self._logs)
            self._logs.clear()
        packets = [*logs]
        if self._configured:  # Publisher::publish: ids from 100 wait for the host
            packets.append(self._publish(IMU_TOPIC, rp.TYPESTORE.types[VECTOR3](x=ypr[0], y=ypr[1], z=ypr[2])))
            self.samples.append(Sample(t, ypr))
            if TF_TOPIC in self.endpoints:
                packets.append(self._publish(TF_TOPIC, self._transform(ypr, now)))
        packets += self._spin_once(now)
        self._send_lines(self._line_faults(packets))

    def _publish(self, topic: str, message: Any) -> bytes:
        self.counters[f"published {topic}"] += 1
        return rp.encode_packet(self.endpoints[topic][0], rp.serialize(message))

    def _transform(self, ypr: tuple[float, float, float], now: float) -> Any:
        types = rp.TYPESTORE.types
        stamp = rp.time_message(self.device_now() or self._millis(now) / 1000).data
        x, y, z, w = (float(np.float32(v)) for v in dmp_quaternion(*ypr))
        transform = types["geometry_msgs/msg/TransformStamped"](
            header=types["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id="/base_link"),
            child_frame_id="/imu_frame",
            transform=types["geometry_msgs/msg/Transform"](
                translation=types["geometry_msgs/msg/Vector3"](x=1.0, y=0.0, z=0.0),
                rotation=types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
            ),
        )
        return types[rp.TF_MESSAGE](transforms=[transform])

    def _time_request(self, now: float) -> bytes:
        self._rt_time = self._millis(now)
        self.counters["time_requests"] += 1
        return rp.encode_packet(rp.ID_TIME, rp.serialize(rp.time_message(0.0)))

    def _spin_once(self, now: float) -> list[bytes]:
        """NodeHandle::spinOnce: handle what the host sent, keep time in sync."""
        c_time = self._millis(now)
        out: list[bytes] = []
        if (c_time - self._last_sync_receive_time) % 2**32 > SYNC_SECONDS * 2200:
            self._configured = False
        version_errors = self.decoder.bad["protocol_version"]
        if version_errors > self._version_errors:
            self._version_errors = version_errors
            if not self._configured:  # tell the host which version this device speaks
                out.append(self._time_request(now))
        while self._rx:
            packet = self._rx.popleft()
            if packet.topic_id == rp.ID_PUBLISHER:
                out.append(self._time_request(now))
                out += self._negotiate_topics()
                self._last_sync_time = self._last_sync_receive_time = c_time
                self.counters["negotiations"] += 1
                return out  # SPIN_ERR: the rest waits for the next pass
            if packet.topic_id == rp.ID_TIME:
                self._sync_time(packet.payload, now)
            elif packet.topic_id == rp.ID_TX_STOP:
                self._configured = False
                self.counters["tx_stops"] += 1
            else:
                self.counters["packets_ignored"] += 1  # no subscribers in this sketch
        if self._configured and (c_time - self._last_sync_time) % 2**32 > SYNC_SECONDS * 500:
            out.append(self._time_request(now))
            self._last_sync_time = c_time
        return out

    def _negotiate_topics(self) -> list[bytes]:
        self._configured = True
        return [
            rp.encode_packet(rp.ID_PUBLISHER, rp.serialize(rp.topic_info(topic_id, name, typename, BUFFER_SIZE)))
            for name, (topic_id, typename) in self.endpoints.items()
        ]

    def _sync_time(self, payload: bytes, now: float) -> None:
        try:
            host = rp.time_seconds(rp.deserialize(payload, rp.TIME))
        except Exception:
            self.counters["bad_time_replies"] += 1
            return
        millis = self._millis(now)
        offset = ((millis - self._rt_time) % 2**32) / 1000  # the round trip, added as syncTime adds it
        self._time_offset = host + offset - millis / 1000
        self._last_sync_receive_time = millis
        self.counters["time_syncs"] += 1

    def _line_faults(self, packets: list[bytes]) -> list[bytes]:
        out = []
        with self._fault_lock:
            for packet in packets:
                if self._lie:
                    self._lie -= 1
                    self.counters["packets_lied"] += 1
                    claimed = len(packet) - rp.OVERHEAD + int(self.rng.integers(1, 64))
                    low, high = claimed & 0xFF, claimed >> 8
                    packet = packet[:2] + bytes((low, high, 255 - (low + high) % 256)) + packet[5:]
                if self._corrupt:
                    self._corrupt -= 1
                    self.counters["checksums_corrupted"] += 1
                    packet = packet[:-1] + bytes(((packet[-1] + 1) % 256,))
                if self._cut:
                    self._cut -= 1
                    self.counters["packets_cut"] += 1
                    packet = packet[: int(self.rng.integers(1, len(packet)))]
                out.append(packet)
        return out
