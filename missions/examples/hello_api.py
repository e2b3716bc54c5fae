"""The Python front end by example: a mission built in Python, then checked, drawn and run.

    python -m botstage.missions.examples.hello_api               # check, draw, run (folder under runs/)
    python -m botstage.missions.examples.hello_api --out DIR     # ... leaving the run folder in DIR
    python -m botstage.missions.examples.hello_api --yaml        # print it as a mission file instead

The robot says hello, then patrols lap after lap: each lap checks the battery (a condition),
walks inside a time box (a timeout decorator) and counts itself; after three laps a preemption
ends the machine with `done`. ``hello_api.yaml`` beside this file is the same mission written as
YAML: both run to the same trace, byte for byte (tests/test_api.py checks it).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from botstage.missions.api import Condition, Mission, Sequence, Skill, StateMachine, Timeout, key


def build() -> Mission:
    """The mission; `botstage`-style tools find it through this function."""
    mission = Mission(
        "hello_api",
        description="Say hello, then patrol three laps under a battery check; a preemption ends it.",
        seed=7,
        rate_hz=10,
        until=60,
        keys={"laps": {"type": "int", "default": 0, "doc": "laps walked"}},
        blackboard={"battery_pct": 80, "greeting": "hello from Python"},
        counters=["laps"],
    )
    mission.add_tree(
        "greet",
        Sequence(
            Skill("log", message=key("greeting")),  # "{greeting}": read from the blackboard
            Skill("wait", duration=1),
        ),
    )
    mission.add_tree(
        "patrol",
        Sequence(
            Condition("battery_pct > 20"),
            Timeout(5, Skill("wait", duration=2)),  # a lap that took 5 s would fail the patrol
            Skill("count", key="laps"),
        ),
    )
    machine = StateMachine(outcomes=["done", "tired"])
    machine.add_state("greeting", tree="greet", transitions={"success": "patrolling", "failure": "tired"})
    machine.add_state("patrolling", tree="patrol", transitions={"success": "patrolling", "failure": "tired"})
    machine.add_preemption("laps >= 3", to="done")  # checked every tick, whatever runs
    mission.machine = machine
    return mission


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m botstage.missions.examples.hello_api", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--out", type=Path, help="the run folder (default: runs/hello_api-<time>)")
    parser.add_argument("--yaml", action="store_true", help="print the mission as a YAML file and stop")
    args = parser.parse_args(argv)
    mission = build()
    if args.yaml:
        print(mission.to_yaml(), end="")
        return 0
    checked = mission.check()  # problems would point at the lines above, as YAML's point at theirs
    for problem in checked.problems:
        print(problem, file=sys.stderr)
    if not checked.ok:
        return 1
    print(mission.draw(machine=True))
    result = mission.run(out=args.out)
    laps = result.summary["counters"]["laps"]
    print(f"{mission.name}: outcome {result.outcome} after {laps} laps; run folder {result.folder}")
    return 0 if result.outcome == "done" else 1


if __name__ == "__main__":
    sys.exit(main())
