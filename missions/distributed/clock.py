"""The mission's time on ``/clock`` (rosgraph_msgs/Clock), as a simulator publishes it.

In simulation the mission's process owns time: after each tick it publishes the new mission
time, so ROS 2 nodes run with ``use_sim_time`` follow it (the robot's process is stepped in
lockstep and publishes none). Best effort, depth 1: a late clock is worth nothing.
"""

from __future__ import annotations

from typing import Any

from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.qos import QoS, Reliability
from botstage.robots.ros2.readings import clock_message

CLOCK_TOPIC = "/clock"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
CLOCK_QOS = QoS(reliability=Reliability.BEST_EFFORT, depth=1)


class ClockPublisher:
    """A run observer that publishes the run's clock after every tick of a simulated run."""

    name = "clock"

    def __init__(self, node: Ros2Node) -> None:
        self.node = node
        self.publisher: Any = None

    def started(self, session: Any) -> None:
        if session.clock.simulated:
            self.publisher = self.node.publisher(CLOCK_TOPIC, CLOCK_TYPE, CLOCK_QOS)
            self.publisher.publish(clock_message(session.clock.now()))

    def after_tick(self, session: Any) -> None:
        if self.publisher is not None:
            self.publisher.publish(clock_message(session.clock.now()))

    def finished(self, session: Any, result: Any) -> None:
        if self.publisher is not None:
            self.publisher.close()
            self.publisher = None
