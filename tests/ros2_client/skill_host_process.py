"""A process that serves botstage's built-in skills over /<name>/skill_tick, for tests.

``python skill_host_process.py ENDPOINT NAME`` connects to ENDPOINT (loopback), serves every
built-in skill with no robot devices, prints ``ready`` and runs until SIGINT/SIGTERM or SIGKILL.
"""

from __future__ import annotations

import signal
import sys
import threading

from botstage.robots.ros2.node import Ros2Node
from botstage.skills.registry import Registry
from botstage.skills.remote.host import SkillHost
from botstage.skills.remote.ros2_link import serve_skill_host


def main() -> None:
    endpoint, name = sys.argv[1], sys.argv[2]
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    host = SkillHost(Registry.builtin(), {})
    with Ros2Node(name, connect=[endpoint]) as node:
        serve_skill_host(node, host)
        print("ready", flush=True)
        stop.wait(300)
    host.close()


if __name__ == "__main__":
    main()
