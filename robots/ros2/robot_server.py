"""A robot process: one backend's devices served as ROS 2 topics (``botstage serve robot``).

Each interface the profile lists becomes its topics (robots/ros2/topics.py): readings are read
from the devices and published at their rates, as ROS 2's standard messages where there is one;
commands (``cmd_vel``, ``say``, ``display``, a pan's goal) are received on Zenoh's threads, queued, and applied
by the robot's own loop, so devices are only ever touched from one thread. The drive's velocity
watchdog lives here (robots/ros2/watchdog.py): whatever happens to whoever drives, the robot
stops.

The work is split so that a lockstep mode can drive the same server from a service call:
``take_commands`` (apply what arrived, check the watchdog), then the clock moves, then ``advance``
(the backend steps over one period, and what is due is published); ``message_now`` is one
channel's "read now -> ROS message", apart from publishing. ``run`` is the real-time loop around
them, paced by a ``WallClock`` whose sleep ends at once when the server is asked to stop and wakes
on the way for the watchdog, so a stop comes within milliseconds of the watchdog's deadline,
not at the next tick.

Stamps: a simulated robot served alone runs on its own clock from 0 and says so on ``/clock``
(ROS 2 nodes with ``use_sim_time`` follow it); a real or emulated one stamps with ROS time (the
system clock) and publishes no ``/clock``.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from typing import Any

from botstage.robots.backend import Backend
from botstage.robots.clock import Clock, WallClock
from botstage.robots.interfaces import AUDIO_RATE_HZ, Twist2D
from botstage.robots.ros2 import botstage_messages as own
from botstage.robots.ros2 import readings
from botstage.robots.ros2.attachment import Attachment
from botstage.robots.ros2.names import fully_qualified_name
from botstage.robots.ros2.node import Publisher, Ros2Node
from botstage.robots.ros2.topics import CLOCK_QOS, CLOCK_TOPIC, CLOCK_TYPE, Direction, Route
from botstage.robots.ros2.watchdog import Trip, VelocityWatchdog

log = logging.getLogger(__name__)

QUEUED_MAX = 100  # say / display commands waiting for the next tick; older ones are dropped
WAKE_AFTER_DUE_S = 1e-3  # the watchdog trips strictly after its timeout: wake just past it


class Waiter:
    """How the real-time loop sleeps: on an event, so ``stop`` ends a sleep at once, and waking on
    the way whenever ``wake_in()`` (seconds, or None) says something is due, to call ``on_wake``."""

    def __init__(self) -> None:
        self.stop = threading.Event()
        self.wake_in: Callable[[], float | None] = lambda: None
        self.on_wake: Callable[[], None] = lambda: None

    def sleep(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while not self.stop.is_set():
            left = end - time.monotonic()
            if left <= 0:
                return
            due = self.wake_in()
            if due is not None and due < left:
                self.stop.wait(max(due, 0.0) + WAKE_AFTER_DUE_S)
                self.on_wake()
                continue
            self.stop.wait(left)
            return


def realtime_clock(rate_hz: float) -> tuple[WallClock, Waiter]:
    """A wall clock for a robot process, and the waiter that paces it (and stops it)."""
    waiter = Waiter()
    return WallClock(rate_hz, sleep=waiter.sleep), waiter


class RobotServer:
    """One robot's devices on a ROS 2 graph through ``node``."""

    def __init__(
        self,
        backend: Backend,
        node: Ros2Node,
        clock: Clock,
        routes: list[Route],
        *,
        publish_clock: bool,
        stamp_offset: float = 0.0,
        watchdog_s: float = 0.5,
    ) -> None:
        """``stamp_offset`` is added to the clock's time in every stamp (0 on a simulated clock; the
        epoch at the clock's start for ROS time); ``publish_clock`` publishes ``/clock`` every tick."""
        self.backend, self.node, self.clock = backend, node, clock
        self.devices = backend.devices
        self.stamp_offset = stamp_offset
        self.watchdog = VelocityWatchdog(watchdog_s)
        self.counts: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._twist: Twist2D | None = None
        self._said: deque[str] = deque(maxlen=QUEUED_MAX)
        self._shown: deque[tuple[str, dict[str, str]]] = deque(maxlen=QUEUED_MAX)
        self._pan_goal: float | None = None  # the newest goal only: a joint goes where it was last told
        self._failing: set[str] = set()  # channels whose device raised, logged once until it reads again
        self._closed = False
        self.routes = [r for r in routes if r.channel.interface in self.devices]
        self.readings = [r for r in self.routes if r.channel.direction is Direction.READING]
        self._readers = {r.key: self._reader(r) for r in self.readings}
        self._due = {r.key: clock.now() for r in self.readings}
        self.publishers: dict[str, Publisher] = {
            r.key: node.publisher(r.topic, r.channel.type_name, r.channel.qos) for r in self.readings
        }
        self.clock_publisher = node.publisher(CLOCK_TOPIC, CLOCK_TYPE, CLOCK_QOS) if publish_clock else None
        commands = {"drive": self._on_twist, "speaker": self._on_say, "display": self._on_display, "pan": self._on_pan}
        for route in self.routes:
            if route.channel.direction is Direction.COMMAND:
                node.subscription(route.topic, route.channel.type_name, commands[route.key], route.channel.qos)

    # -- topics -----------------------------------------------------------------------------------

    def topics(self) -> list[tuple[str, str, str]]:
        """(direction, full topic name, type) of everything served, for the ready line and logs."""
        served = [("out", p.topic, p.type_name) for p in self.publishers.values()]
        if self.clock_publisher is not None:
            served.append(("out", self.clock_publisher.topic, CLOCK_TYPE))
        for route in self.routes:
            if route.channel.direction is Direction.COMMAND:
                served.append(("in", self._full(route.topic), route.channel.type_name))
        return served

    def _full(self, topic: str) -> str:
        return fully_qualified_name(topic, self.node.namespace, self.node.name)

    # -- readings: read now -> ROS message ----------------------------------------------------------

    def stamp(self, seconds: float) -> float:
        """A time of the server's clock as a message stamp (never before 0)."""
        return max(0.0, seconds + self.stamp_offset)

    def _restamped(self, reading: Any) -> Any:
        return dataclasses.replace(reading, stamp=self.stamp(reading.stamp)) if self.stamp_offset else reading

    def _reader(self, route: Route) -> Callable[[], Any | None]:
        """The channel's "read the device now, as a message" (None: nothing to publish yet)."""
        device = self.devices[route.channel.interface]
        now = self.clock.now
        readers: dict[str, Callable[[], Any | None]] = {
            "odometry": lambda: readings.odometry_message(self._restamped(device.read())),
            "imu": lambda: readings.imu_message(self._restamped(device.read())),
            "laser": lambda: readings.scan_message(self._restamped(device.scan())),
            "sonar": lambda: readings.range_message(self._restamped(device.read())),
            "battery": lambda: readings.battery_message(self._restamped(device.read())),
            "camera": lambda: self._image(device.frame()),
            "people": lambda: own.people_message(
                device.people(), self.stamp(now()), device.range_min, device.range_max
            ),
            "microphone": lambda: self._audio(device.read()),
            "speaking": lambda: own.flag_message(device.busy()),
            "pan_state": lambda: self._joint_state(device.position()),
        }
        return readers[route.key]

    def _joint_state(self, position: float | None) -> Any | None:
        """The pan's position as a JointState; nothing while the servo cannot be read."""
        if position is None:
            return None
        joint = self.backend.profile.interfaces["pan"].joint
        name = joint.name if joint is not None else "pan_joint"
        return readings.joint_state_message(name, position, self.stamp(self.clock.now()))

    def _image(self, frame: Any) -> Any | None:
        return None if frame is None else readings.image_message(frame, self.stamp(self.clock.now()))

    def _audio(self, samples: Any) -> Any:
        first = self.clock.now() - len(samples) / AUDIO_RATE_HZ  # the chunk's stamp is its first sample's
        return own.audio_message(samples, self.stamp(first))

    def message_now(self, key: str) -> Any | None:
        """Channel ``key`` read now, as the message it is published as."""
        return self._readers[key]()

    # -- commands, on Zenoh's threads ---------------------------------------------------------------

    def _on_twist(self, message: Any, _: Attachment) -> None:
        try:
            twist = readings.twist_of(message)
        except ValueError as error:
            with self._lock:
                self.counts["cmd_vel_rejected"] += 1
            log.warning("cmd_vel ignored: %s", error)
            return
        with self._lock:
            self._twist = twist
            self.counts["cmd_vel"] += 1
        self.watchdog.commanded(self.clock.now())

    def _on_say(self, message: Any, _: Attachment) -> None:
        with self._lock:
            self._said.append(str(message.data))
            self.counts["say"] += 1

    def _on_display(self, message: Any, _: Attachment) -> None:
        try:
            shown = own.display_of(message)
        except ValueError as error:
            with self._lock:
                self.counts["display_rejected"] += 1
            log.warning("display message ignored: %s", error)
            return
        with self._lock:
            self._shown.append(shown)
            self.counts["display"] += 1

    def _on_pan(self, message: Any, _: Attachment) -> None:
        try:
            goal = readings.command_of(message)
        except ValueError as error:
            with self._lock:
                self.counts["pan_rejected"] += 1
            log.warning("pan command ignored: %s", error)
            return
        with self._lock:
            self._pan_goal = goal
            self.counts["pan"] += 1

    # -- the tick -----------------------------------------------------------------------------------

    def take_commands(self) -> None:
        """Apply what arrived since the last tick (the newest velocity and pan goal, every text and
        layout), then check the watchdog."""
        with self._lock:
            twist, self._twist = self._twist, None
            pan_goal, self._pan_goal = self._pan_goal, None
            said, shown = list(self._said), list(self._shown)
            self._said.clear()
            self._shown.clear()
        if twist is not None:
            self.devices["drive"].cmd_vel(twist.v, twist.w)  # the backend enforces the profile's limits
        for text in said:
            self.devices["speaker"].say(text)
            self._due["speaking"] = self.clock.now()  # say so at once: a mission waits on it
        for layout, content in shown:
            self.devices["display"].show(layout, **content)
        if pan_goal is not None:
            self.devices["pan"].move_to(pan_goal)  # the device clamps it to the joint's limits
        self.check_watchdog()

    def check_watchdog(self) -> Trip | None:
        """Stop the drive if no ``cmd_vel`` came for the watchdog's timeout; the trip, once per silence."""
        trip = self.watchdog.check(self.clock.now())
        if trip is not None:
            self.devices["drive"].stop()
            log.warning(
                "watchdog: no cmd_vel for %.3f s: drive stopped "
                "(last cmd_vel at %.6f s, stopped at %.6f s, server clock)",
                trip.silence,
                trip.last_command,
                trip.stopped_at,
            )
        return trip

    def advance(self) -> None:
        """After the clock moved one period: the backend steps over it, then what is due is published."""
        self.backend.step()
        if self.clock_publisher is not None:
            self.clock_publisher.publish(readings.clock_message(self.stamp(self.clock.now())))
        self.publish_due()

    def publish_due(self) -> None:
        """Every reading whose period has come, each read once; a device that raises is logged once."""
        now = self.clock.now()
        for route in self.readings:
            key = route.key
            if now < self._due[key] - 1e-9:
                continue
            period = route.period or 0.0
            self._due[key] = self._due[key] + period if self._due[key] + period > now else now + period
            try:
                message = self.message_now(key)
            except Exception as error:  # a device that fails must not stop the robot's loop
                self.counts[f"{key}_errors"] += 1
                if key not in self._failing:
                    self._failing.add(key)
                    log.warning("%s: reading failed: %s: %s", key, type(error).__name__, error)
                continue
            self._failing.discard(key)
            if message is not None:
                self.publishers[key].publish(message)
                self.counts[f"{key}_published"] += 1

    def run(self, waiter: Waiter) -> None:
        """Serve in real time until ``waiter.stop`` is set (a signal, a caller)."""
        if "drive" in self.devices:
            waiter.wake_in = self._watchdog_in
            waiter.on_wake = self.check_watchdog
        while not waiter.stop.is_set():
            self.take_commands()
            self.clock.next_tick()
            if waiter.stop.is_set():
                break
            self.advance()

    def _watchdog_in(self) -> float | None:
        due = self.watchdog.due()
        return None if due is None else due - self.clock.now()

    # -- the end ------------------------------------------------------------------------------------

    def close(self) -> None:
        """Zero velocity, then the backend released and the node undeclared; each runs whatever failed before."""
        if self._closed:
            return
        self._closed = True
        steps: list[Callable[[], Any]] = []
        if "drive" in self.devices:
            steps.append(self.devices["drive"].stop)
        steps += [self.backend.close, self.node.close]
        failed: BaseException | None = None
        for step in steps:
            try:
                step()
            except Exception as error:
                failed = failed or error
        if failed is not None:
            raise failed

    def summary(self) -> dict[str, Any]:
        """What it served and received, and the watchdog's trips."""
        return {
            "counts": dict(sorted(self.counts.items())),
            "watchdog_trips": [dataclasses.asdict(trip) for trip in self.watchdog.trips],
        }
