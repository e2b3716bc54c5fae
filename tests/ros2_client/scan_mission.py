"""A botstage mission in its own process for tests/test_ros2_backend.py: scan_mission.yaml on the ros2 backend.

``python scan_mission.py OUT LISTEN`` runs the mission with the ``read_scan`` skill added (it
writes what the laser's latest scan holds to the blackboard), its node listening on LISTEN and
connecting nowhere: the independent client connects to it, publishes ``/scan`` and subscribes to
``/cmd_vel``. It prints ``{"event": "done", "outcome": ..., "counters": ...}`` and exits with the
run's exit status.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from botstage.missions.runner import run
from botstage.skills.base import Out, Outcome, Skill, SkillContext
from botstage.skills.registry import Registry

MISSION = Path(__file__).with_name("scan_mission.yaml")


class ReadScan(Skill):
    name = "read_scan"
    description = "Read the laser's latest scan once and give out what it holds."
    outputs = {
        "ranges": Out(list[float], doc="the ranges, m"),
        "angle_min": Out(float, doc="rad"),
        "age": Out(float, doc="s between the scan's stamp and now, on the mission's clock"),
    }

    def run(self, ctx: SkillContext) -> Outcome:
        scan = ctx.interface("laser").scan()
        ranges = [round(float(r), 6) for r in scan.ranges]
        outputs = {"ranges": ranges, "angle_min": float(scan.angle_min), "age": ctx.clock.now() - scan.stamp}
        return Outcome.success(f"{len(ranges)} ranges", **outputs)


def main() -> int:
    out, listen = Path(sys.argv[1]), sys.argv[2]
    registry = Registry.default()
    registry.register(ReadScan, origin="test")
    options = {"listen": listen, "connect": "", "ready_timeout": 60.0}
    result = run(MISSION, backend="ros2", out=out, registry=registry, backend_options=options)
    print(json.dumps({"event": "done", "outcome": result.outcome, "reason": result.reason}), flush=True)
    return result.exit_status


if __name__ == "__main__":
    sys.exit(main())
