"""A process that drives a served robot for tests/test_ros2_robot.py, until it is killed.

``python cmd_vel_sender.py ENDPOINT V W`` connects a botstage node named ``driver`` to ENDPOINT
and publishes geometry_msgs/Twist (V forward, W turning) on ``/cmd_vel`` every 50 ms. It prints
``{"event": "ready"}`` once its publisher is declared. It never stops the robot itself: the test
SIGKILLs it, as a mission process that dies, and the robot process's watchdog must stop the drive.
A failsafe deadline ends it if nobody does.
"""

from __future__ import annotations

import json
import sys
import threading
import time

from botstage.robots.interfaces import Twist2D
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.readings import twist_message

FAILSAFE_S = 120.0
PERIOD_S = 0.05


def main() -> int:
    endpoint, v, w = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    pace = threading.Event()  # never set: paces the loop
    with Ros2Node("driver", connect=[endpoint]) as node:
        cmd_vel = node.publisher("/cmd_vel", "geometry_msgs/msg/Twist")
        print(json.dumps({"event": "ready"}), flush=True)
        deadline = time.monotonic() + FAILSAFE_S
        while time.monotonic() < deadline:
            cmd_vel.publish(twist_message(Twist2D(v, w)))
            pace.wait(PERIOD_S)
    return 0


if __name__ == "__main__":
    sys.exit(main())
