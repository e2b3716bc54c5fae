"""A deployment's robot process as ROS 2 topics, for whoever drives it when no mission does.

A robot process of a deployment serves its devices to the mission call by call, and in
simulation the mission's ticks move its world (missions/distributed/process.py). With ``topics:
true`` it also serves the robot's interfaces as ROS 2 topics (robots/ros2/robot_server.py:
``cmd_vel`` in; ``odom``, ``battery_state``, ``image_raw``... out), so an operator drives it with
``botstage teleop ROBOT --connect ENDPOINT`` or any ROS 2 teleop, as the Bittle article's PC did
(secured, with the operator's certificate: only it and the mission's process may publish the
robot's command topics, missions/distributed/security.py).

Who drives, decided here:

- while the mission's node is on the graph, the mission does: ``cmd_vel`` is refused (counted,
  said once per mission), nothing is read or published, the world moves with the mission's ticks;
- otherwise the robot stands still, read by nobody, until the first ``cmd_vel``: a deployment
  started whole (``botstage up``) therefore leaves the one-process run's trace, as the robot's
  world has not moved before the mission's first tick;
- from the first ``cmd_vel`` on, the robot runs in real time at the mission's rate (the world
  steps, readings are published at their rates) until a mission comes (after it, the robot
  stands still again until the next ``cmd_vel``), and the drive's velocity watchdog (the
  profile's ``control.watchdog_s``, 0.5 s) stops it when ``cmd_vel`` stops: the operator let go,
  or teleop died, or the network broke. A trip is said, and says whether the last ``cmd_vel``
  had stopped the robot already (teleop let go) or the watchdog did (teleop went away).

The devices are touched under the device host's lock, one caller at a time with the mission's
calls. The server's clock (``OperatorClock``) is the robot's own clock, moving on in real time
between its ticks, so the watchdog sees a silence as it is and not by whole ticks; a tick that
comes late (a camera frame to draw on a busy machine) delays a stop by its lateness, as the
world it moves falls behind by as much.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from botstage.robots.clock import SimClock
from botstage.robots.ros2.attachment import Attachment
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.robot_server import RobotServer, Waiter
from botstage.robots.ros2.topics import Route
from botstage.robots.ros2.watchdog import Trip

IDLE_S = 0.05  # how often a robot nobody drives looks again whether someone does


class OperatorClock:
    """The robot's ``SimClock`` paced in real time: its ticks one period apart on the wall, its time
    moving on between them (at most one period past the tick), so a deadline is seen when it comes."""

    simulated = False

    def __init__(self, robot: SimClock, sleep: Callable[[float], None], monotonic: Callable[[], float]) -> None:
        self.robot, self._sleep, self._monotonic = robot, sleep, monotonic
        self._ticked_at = monotonic()
        self._deadline = self._ticked_at + robot.period
        self._ticks = robot.ticks  # the operator's own count: never back, whatever a mission set meanwhile

    @property
    def period(self) -> float:
        return self.robot.period

    @property
    def ticks(self) -> int:
        return self.robot.ticks

    def now(self) -> float:
        return self.robot.now() + min(self.period, max(0.0, self._monotonic() - self._ticked_at))

    def restart(self) -> None:
        """Real time resumes from now (after the robot stood still, or a mission drove it)."""
        self._ticks = max(self._ticks, self.robot.ticks)
        self.robot.ticks = self._ticks
        self._ticked_at = self._monotonic()
        self._deadline = self._ticked_at + self.period

    def wait(self) -> None:
        """Until the next tick's deadline (the sleep wakes on the way when the watchdog is due)."""
        left = self._deadline - self._monotonic()
        if left > 0:
            self._sleep(left)
            self._deadline += self.period
        else:  # late: go on from now rather than run ticks back to back
            self._deadline = self._monotonic() + self.period

    def tick(self) -> None:
        self._ticks += 1
        self.robot.ticks = self._ticks
        self._ticked_at = self._monotonic()


class OperatorServer(RobotServer):
    """The robot's topics, with ``cmd_vel`` refused while ``held()`` names the mission that drives."""

    def __init__(
        self,
        backend: Any,
        node: Ros2Node,
        clock: OperatorClock,
        routes: list[Route],
        *,
        held: Callable[[], str | None],
        say: Callable[[str], None],
        stamp_offset: float = 0.0,
        watchdog_s: float = 0.5,
    ) -> None:
        self.held, self.say = held, say  # before the subscriptions: a message may come at once
        self.driven = threading.Event()
        self.moving = False  # whether the last cmd_vel taken asked for motion (a watchdog trip then stops it)
        self._refused_by: str | None = None
        super().__init__(
            backend, node, clock, routes, publish_clock=False, stamp_offset=stamp_offset, watchdog_s=watchdog_s
        )

    def _on_twist(self, message: Any, attachment: Attachment) -> None:
        holder = self.held()
        if holder is not None:
            with self._lock:
                self.counts["cmd_vel_refused"] += 1
                first, self._refused_by = self._refused_by != holder, holder
            if first:
                self.say(f"cmd_vel refused: mission {holder!r} drives the robot")
            return
        with self._lock:
            self._refused_by = None  # said again for the next mission
        super()._on_twist(message, attachment)
        self.driven.set()

    def take_commands(self) -> None:
        with self._lock:
            twist = self._twist
        if twist is not None:
            self.moving = twist.v != 0.0 or twist.w != 0.0
        super().take_commands()

    def stop_if_silent(self) -> Trip | None:
        """The watchdog's check (``check_watchdog``'s, said by the caller rather than logged)."""
        trip = self.watchdog.check(self.clock.now())
        if trip is not None:
            self.devices["drive"].stop()
        return trip


class Operator:
    """The real-time loop of a robot process with topics: runs on its own thread until ``close``."""

    def __init__(
        self,
        backend: Any,
        node: Ros2Node,
        robot_clock: SimClock,
        routes: list[Route],
        *,
        held: Callable[[], str | None],
        lock: threading.Lock,
        say: Callable[[str], None],
        stamp_offset: float = 0.0,
        watchdog_s: float = 0.5,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.held, self.lock, self.say = held, lock, say
        self.waiter = Waiter()
        self.clock = OperatorClock(robot_clock, self.waiter.sleep, monotonic)
        self.server = OperatorServer(
            backend,
            node,
            self.clock,
            routes,
            held=held,
            say=say,
            stamp_offset=stamp_offset,
            watchdog_s=watchdog_s,
        )
        self.waiter.wake_in = self._watchdog_in
        self.waiter.on_wake = self._check_watchdog
        self._thread = threading.Thread(target=self._run, name="operator", daemon=True)

    def start(self) -> Operator:
        self._thread.start()
        return self

    def topics(self) -> list[tuple[str, str, str]]:
        return self.server.topics()

    def _watchdog_in(self) -> float | None:
        due = self.server.watchdog.due()
        return None if due is None else due - self.clock.now()

    def _check_watchdog(self) -> None:
        with self.lock:
            if self.held() is None:
                self._said(self.server.stop_if_silent())

    def _said(self, trip: Trip | None) -> None:
        if trip is None:
            return
        how = "drive stopped" if self.server.moving else "drive stopped (it was told to stop already)"
        self.server.moving = False
        self.say(f"watchdog: no cmd_vel for {trip.silence:.3f} s: {how}")

    def _run(self) -> None:
        stop, running = self.waiter.stop, False
        while not stop.is_set():
            if self.held() is not None or not self.server.driven.is_set():
                if running:
                    running = False
                    self.server.driven.clear()  # after the mission, still until someone drives again
                    self.say("the mission drives the robot: real time paused")
                stop.wait(IDLE_S)
                continue
            if not running:
                running = True
                with self.lock:
                    self.clock.restart()
                self.say("cmd_vel: the robot runs in real time")
            with self.lock:
                if self.held() is not None:
                    continue
                self._said(self.server.stop_if_silent())
                before = len(self.server.watchdog.trips)
                self.server.take_commands()  # the newest cmd_vel, then the watchdog's check again
                if len(self.server.watchdog.trips) > before:  # a silence ended just now
                    self._said(self.server.watchdog.trips[-1])
            self.clock.wait()
            with self.lock:
                if stop.is_set() or self.held() is not None:
                    continue
                self.clock.tick()
                self.server.advance()

    def close(self) -> None:
        """The loop ends; the drive is stopped by whoever closes the backend."""
        self.waiter.stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)

    def summary(self) -> dict[str, Any]:
        return self.server.summary()
