"""A second botstage process for tests/test_ros2_interop.py: echoes ``/chatter`` back on ``/echo``.

``python botstage_echo.py ENDPOINT`` opens a ``Ros2Node`` named ``echo`` that connects to
ENDPOINT, subscribes to ``/chatter`` (std_msgs/String) and publishes ``echo: <data> #<sequence>``
on ``/echo`` for each message, the sequence being the one in the received attachment. It prints
``{"event": "ready", "pub_token": ...}`` once declared, and leaves the graph and exits 0 on a line
``stop`` (or the end of input) on stdin, or after its failsafe deadline.
"""

from __future__ import annotations

import json
import sys
import threading

from botstage.robots.ros2 import types
from botstage.robots.ros2.attachment import Attachment
from botstage.robots.ros2.node import Ros2Node

FAILSAFE_S = 90.0


def watch_stdin(stop: threading.Event) -> None:
    for line in sys.stdin:
        if line.strip() == "stop":
            break
    stop.set()


def main() -> int:
    stop = threading.Event()
    String = types.message_class("std_msgs/msg/String")
    with Ros2Node("echo", connect=[sys.argv[1]]) as node:
        echo = node.publisher("/echo", "std_msgs/msg/String")

        def on_chatter(message: object, attachment: Attachment) -> None:
            echo.publish(String(data=f"echo: {message.data} #{attachment.sequence}"))  # type: ignore[attr-defined]

        node.subscription("/chatter", "std_msgs/msg/String", on_chatter)
        print(json.dumps({"event": "ready", "pub_token": echo.token}), flush=True)
        threading.Thread(target=watch_stdin, args=(stop,), daemon=True).start()
        stop.wait(FAILSAFE_S)
    print(json.dumps({"event": "done"}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
