"""The extension guide's plug-in package (docs/guides/extending.md), installed by pip as a real
wheel, adds a skill, a decorator, a composite, a backend and a run observer through entry points
only; without touching botstage, `validate` checks the new kinds' options at their
file:line:col, `schema` includes them, `tree` and `machine` draw them, coverage counts them,
`run --backend` opens the backend, and the observer sees every trace event of the run."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from tests.tools import install_wheel

ROOT = Path(__file__).resolve().parent.parent

MISSION = """\
name: kit_demo
robot: peoplebot
world: museum
seed: 4
until: 30
blackboard: {estop: false, tired: false}
trees:
  show:
    round_robin:
      - unless: "tired"
        child: {wave: {seconds: 1.5}}
      - move: {v: 0.5, duration: 2}
machine:
  outcomes: [done, stopped]
  preemptions:
    - {when: "estop", to: stopped}
  states:
    showing: {tree: show, transitions: {success: resting, failure: stopped}}
    resting: {skill: wait, inputs: {duration: 1}, transitions: {success: done, failure: stopped}}
"""

BROKEN = """\
name: kit_broken
trees:
  main:
    round_robin:
      - unless: 3
        child: {wait: {duration: 1}}
      - wave: {seconds: 1}
    first: -1
    shuffle: true
"""

SCENARIO = """\
mission: kit_demo.yaml
expect:
  outcome: done
  states_in_order: [showing, resting, done]
"""


def readme_package() -> tuple[dict[str, str], str]:
    """The extension guide's `# my_kit/*.py` code blocks, and its entry points as entry_points.txt."""
    section = (ROOT / "docs" / "guides" / "extending.md").read_text(encoding="utf-8")
    files = {}
    for block in re.findall(r"```python\n(.*?)```", section, re.S):
        first, _, body = block.partition("\n")
        assert first.startswith("# my_kit/"), first
        files[first.removeprefix("# ")] = body
    (toml,) = re.findall(r"```toml\n(.*?)```", section, re.S)
    groups = tomllib.loads(toml)["project"]["entry-points"]
    entry_points = "".join(
        f"[{group}]\n" + "".join(f"{name} = {value}\n" for name, value in items.items()) + "\n"
        for group, items in groups.items()
    )
    return files, entry_points


@pytest.fixture(scope="module")
def kit(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """The kit installed into its own site folder; the environment that puts it on the path."""
    sources, entry_points = readme_package()
    target = install_wheel(
        tmp_path_factory.mktemp("kit"), "my-kit", {"my_kit/__init__.py": "", **sources}, entry_points
    )
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(target), str(ROOT)]), "COLUMNS": "250"}


def botstage(env: dict[str, str], cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "botstage.missions.cli", *args]
    return subprocess.run(command, capture_output=True, text=True, env=env, cwd=cwd, timeout=300)


@pytest.fixture
def missions(tmp_path: Path) -> Path:
    (tmp_path / "kit_demo.yaml").write_text(MISSION)
    (tmp_path / "kit_broken.yaml").write_text(BROKEN)
    (tmp_path / "scenario.yaml").write_text(SCENARIO)
    return tmp_path


def test_validate_checks_the_plugin_kinds_options_where_they_are_written(kit, missions: Path) -> None:
    assert botstage(kit, missions, "validate", "kit_demo.yaml").returncode == 0
    done = botstage(kit, missions, "validate", "kit_broken.yaml")
    assert done.returncode == 1
    errors = done.stderr.splitlines()
    assert (
        "kit_broken.yaml:5:9: error: unless: input should be a valid string (unless takes a condition (a string))"
        in errors
    )
    assert "kit_broken.yaml:8:5: error: first of 'round_robin': input should be greater than or equal to 0" in errors
    assert any(e.startswith("kit_broken.yaml:9:5: error: unknown option 'shuffle' for 'round_robin'") for e in errors)


def test_schema_tree_machine_and_listings_know_the_plugin(kit, missions: Path) -> None:
    schema = json.loads(botstage(kit, missions, "schema").stdout)
    properties = schema["$defs"]["node"]["anyOf"][1]["properties"]
    assert properties["round_robin"]["items"] == {"$ref": "#/$defs/node"}
    assert properties["first"]["minimum"] == 0
    assert properties["unless"]["type"] == "string"
    assert "wave" in properties
    tree = botstage(kit, missions, "tree", "kit_demo.yaml", "--tree", "show", "-f", "ascii")
    assert tree.returncode == 0, tree.stderr
    assert tree.stdout.splitlines()[:3] == [
        "show: round robin",
        "|-- unless tired",
        "|   `-- wave  seconds=1.5",
    ]
    machine = botstage(kit, missions, "machine", "kit_demo.yaml", "-f", "mermaid")
    assert machine.returncode == 0, machine.stderr
    assert "round robin" in machine.stdout and "unless tired" in machine.stdout
    nodes = botstage(kit, missions, "nodes")
    assert re.search(r"round_robin .* plugin my-kit", nodes.stdout) and re.search(
        r"unless .* plugin my-kit", nodes.stdout
    )
    backends = botstage(kit, missions, "backends")
    assert "slow_sim" in backends.stdout and "plugin my-kit" in backends.stdout


def test_coverage_counts_the_plugin_nodes(kit, missions: Path) -> None:
    done = botstage(kit, missions, "test", "scenario.yaml", "--coverage", "--coverage-file", "coverage.json")
    assert done.returncode == 0, done.stdout + done.stderr
    (figures,) = json.loads((missions / "coverage.json").read_text()).values()
    outcomes = figures["node_outcomes"]
    assert outcomes["kit_demo/showing/show"] == {"SUCCESS": 1}  # the round robin ended, as a selector does
    assert outcomes["kit_demo/showing/show/unless"] == {"SUCCESS": 1}
    assert outcomes["kit_demo/showing/show/unless/wave"] == {"success": 1}
    assert "kit_demo/showing/show/move" in figures["untested"]["nodes"]  # the robin never got to it


def test_run_opens_the_plugin_backend_and_the_observer_sees_every_event(kit, missions: Path) -> None:
    options = ["--backend", "slow_sim", "--backend-opt", "max_speed=0.1", "--observe", "tally", "-q"]
    done = botstage(kit, missions, "run", "kit_demo.yaml", "--out", "run", *options)
    assert done.returncode == 0, done.stderr
    summary = json.loads((missions / "run" / "summary.json").read_text())
    events = [json.loads(line) for line in (missions / "run" / "trace.jsonl").read_text().splitlines()]
    assert summary["backend"] == "slow_sim" and summary["outcome"] == "done"
    assert summary["tally"] == len(events)
    by_kind: dict[str, int] = {}
    for event in events:
        by_kind[event["ev"]] = by_kind.get(event["ev"], 0) + 1
    assert json.loads((missions / "run" / "tally.json").read_text()) == by_kind
    # the wave ran (a plugin skill under a plugin decorator under a plugin composite)
    assert any(e["ev"] == "skill_outcome" and e["skill"] == "wave" and e["outcome"] == "success" for e in events)
    bad = botstage(kit, missions, "run", "kit_demo.yaml", "--backend", "slow_sim", "--backend-opt", "max_speed=-1")
    assert bad.returncode == 2 and "max_speed" in bad.stderr


def test_the_round_robin_starts_after_the_child_that_ran_last(kit, missions: Path) -> None:
    """The composite's semantics, ticked by the engine (Nav2's RoundRobin)."""
    code = """
from botstage.behaviors.engine import Engine
from botstage.robots.clock import SimClock
engine = Engine(clock=SimClock(10))
engine.blackboard.set("x", 0, writer="test")
spec = {"round_robin": [{"condition": "x == 1"}, {"condition": "x == 2"}, {"condition": "x == 3"}]}
engine.set_root(engine.builder().tree(spec))
seen = []
for x in (2, 2, 1, 3, 9):
    engine.blackboard.set("x", x, writer="test")
    engine.tick()
    seen.append((engine.root.status.value, engine.root.next))
print(seen)
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=kit, timeout=120)
    assert done.returncode == 0, done.stderr
    # x=2: tries 0 (fails) then 1: success, next is 2; x=2 again: 2 fails, 0 fails, 1 succeeds;
    # x=1: starts at 2 (fails), 0 succeeds; x=3: starts at 1, fails, then 2 succeeds; x=9: all fail
    expected = [("SUCCESS", 2), ("SUCCESS", 2), ("SUCCESS", 1), ("SUCCESS", 0), ("FAILURE", 0)]
    assert done.stdout.strip() == str(expected)
