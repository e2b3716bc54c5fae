"""A botstage process serving one SkillCall action, for tests/test_ros2_actions.py to lose.

``python botstage_skill_server.py ENDPOINT`` opens a ``Ros2Node`` named ``skills`` that connects
to ENDPOINT and serves ``/skills/hold`` (botstage_msgs/action/SkillCall): it accepts every goal,
publishes one feedback (``ticks`` 1, ``detail`` "holding") and never ends it. It prints
``{"event": "ready", "zid": ...}`` once served, and leaves the graph and exits 0 on a line ``stop``
(or the end of input) on stdin, or after its failsafe deadline. The test kills it instead.
"""

from __future__ import annotations

import json
import sys
import threading

from botstage.robots.ros2 import types
from botstage.robots.ros2.node import Ros2Node

FAILSAFE_S = 90.0


def watch_stdin(stop: threading.Event) -> None:
    for line in sys.stdin:
        if line.strip() == "stop":
            break
    stop.set()


def main() -> int:
    stop = threading.Event()
    Feedback = types.message_class("botstage_msgs/action/SkillCall_Feedback")
    with Ros2Node("skills", connect=[sys.argv[1]]) as node:
        server = node.action_server(
            "/skills/hold",
            "botstage_msgs/action/SkillCall",
            on_accepted=lambda goal_id, goal: server.publish_feedback(goal_id, Feedback(ticks=1, detail="holding")),
        )
        print(json.dumps({"event": "ready", "zid": node.zid}), flush=True)
        threading.Thread(target=watch_stdin, args=(stop,), daemon=True).start()
        stop.wait(FAILSAFE_S)
    print(json.dumps({"event": "done"}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
