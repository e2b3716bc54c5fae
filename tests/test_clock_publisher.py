"""The mission's time on /clock: a simulated run publishes each tick's time, as a simulator does."""

from __future__ import annotations

import queue
import threading
import time
from pathlib import Path

from botstage.missions.distributed.clock import CLOCK_TOPIC, CLOCK_TYPE, ClockPublisher
from botstage.missions.runner import run
from botstage.robots.ros2.liveliness import EntityKind
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.readings import seconds_of
from tests.test_ros2_interop import listening_node

ROOT = Path(__file__).resolve().parent.parent
FAILSAFE_S = 60.0


def test_a_simulated_run_publishes_its_time_on_clock(tmp_path: Path) -> None:
    mission_node, endpoint = listening_node("mission")
    watcher = Ros2Node("watcher", connect=[endpoint])
    times: queue.Queue[float] = queue.Queue()
    try:
        watcher.subscription(CLOCK_TOPIC, CLOCK_TYPE, lambda message, _attachment: times.put(seconds_of(message.clock)))
        deadline, pace = time.monotonic() + FAILSAFE_S, threading.Event()
        while not mission_node.graph().endpoints(CLOCK_TOPIC, EntityKind.SUBSCRIPTION):  # the watcher is matched
            assert time.monotonic() < deadline, "the watcher's subscription never reached the mission's node"
            pace.wait(0.05)
        run(
            ROOT / "missions" / "examples" / "hello.yaml",
            until=3.0,
            out=tmp_path / "run",
            observers=[ClockPublisher(mission_node)],
        )
        seen = [times.get(timeout=FAILSAFE_S)]
        while len(seen) < 31:
            try:
                seen.append(times.get(timeout=2.0))
            except queue.Empty:
                break  # best effort, as /clock is: a lost one is no error
    finally:
        watcher.close()
        mission_node.close()
    assert seen == sorted(seen) and seen[0] == 0.0
    assert all(abs(t * 10 - round(t * 10)) < 1e-6 for t in seen) and max(seen) <= 3.0 + 1e-9
