"""Engine overhead against plain py_trees and raw transitions, measured side by side.

Prints one JSON object per line:
- ``tree_*``: per-node tick cost of a 1,001-node tree of trivial skills through the engine
  (trace recorded in memory, status changes tracked) against the same tree of plain py_trees
  Behaviours ticked by ``py_trees.trees.BehaviourTree``; once with leaves that succeed at once
  (every leaf starts and ends a skill each tick) and once with leaves that stay RUNNING.
- ``nav2_navigate_to_pose``: µs per tick of Nav2's NavigateToPose tree imported from its XML
  (``../shared/nav2``) against the same tree in YAML, the PeopleBot driving in the museum.
- ``machine``: per-trigger cost of a 3-level hierarchical machine whose states run trivial
  skills through the engine, against the same HierarchicalMachine driven with raw triggers.

Run with ``python -m tests.bench tick``. Timings take the best of several repeats to shed noise.
"""

from __future__ import annotations

import gc
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import py_trees
import yaml
from transitions.extensions.nesting import HierarchicalMachine

from botstage.behaviors.engine import Engine
from botstage.robots.clock import SimClock
from botstage.skills.base import Outcome, Skill, SkillContext, SkillRun
from botstage.skills.registry import Registry

GROUPS, LEAVES = 10, 99  # 1 root + 10 groups + 990 leaves = 1,001 nodes
TARGET = 1.2


class Noop(Skill):
    name = "noop"
    description = "Succeed at once."

    def run(self, ctx: SkillContext) -> Outcome:
        return Outcome.success()


class Spin(Skill):
    name = "keep_running"
    description = "Run forever, one yield per tick."

    def run(self, ctx: SkillContext) -> SkillRun:
        while True:
            yield


def _registry() -> Registry:
    registry = Registry.default()
    registry.register(Noop)
    registry.register(Spin)
    return registry


def _best_pair(engine: Callable[[], float], baseline: Callable[[], float], repeats: int) -> tuple[float, float]:
    """Best of ``repeats`` for each, the two interleaved so drift affects both alike."""
    engine_samples, baseline_samples = [], []
    for _ in range(repeats):
        gc.collect()
        engine_samples.append(engine())
        gc.collect()
        baseline_samples.append(baseline())
    return min(engine_samples), min(baseline_samples)


def _timed(tick: Callable[[], Any], ticks: int) -> Callable[[], float]:
    def run() -> float:
        start = time.perf_counter()
        for _ in range(ticks):
            tick()
        return (time.perf_counter() - start) / ticks

    return run


def tree_spec(leaf: str, composite: str) -> dict[str, Any]:
    """Memory-less sequences when leaves succeed, parallels when they run: every leaf ticks."""
    options = {"memory": False} if composite == "sequence" else {}
    return {composite: [{composite: [leaf] * LEAVES, **options} for _ in range(GROUPS)], **options}


def plain_tree(leaf_cls: type[py_trees.behaviour.Behaviour], composite: str) -> py_trees.trees.BehaviourTree:
    def make(name: str, children: list[py_trees.behaviour.Behaviour]) -> py_trees.behaviour.Behaviour:
        if composite == "sequence":
            return py_trees.composites.Sequence(name, memory=False, children=children)
        return py_trees.composites.Parallel(
            name, policy=py_trees.common.ParallelPolicy.SuccessOnAll(), children=children
        )

    groups = [make(f"g{g}", [leaf_cls(f"l{g}_{i}") for i in range(LEAVES)]) for g in range(GROUPS)]
    return py_trees.trees.BehaviourTree(make("root", groups))


def bench_tree(variant: str, ticks: int, repeats: int) -> dict[str, Any]:
    leaf, plain_leaf, root = {
        "instant": ("noop", py_trees.behaviours.Success, "sequence"),
        "running": ("keep_running", py_trees.behaviours.Running, "parallel"),
    }[variant]
    engine = Engine(clock=SimClock(100), registry=_registry())
    tree = engine.builder().tree(tree_spec(leaf, root))
    engine.set_root(tree)
    nodes = sum(1 for _ in tree.iterate())
    plain = plain_tree(plain_leaf, root)
    engine.tick()
    plain.tick()  # warm up both
    engine_s, plain_s = _best_pair(_timed(engine.tick, ticks), _timed(plain.tick, ticks), repeats)
    events = engine.trace.count
    engine.close()
    return {
        "bench": f"tree_{variant}",
        "nodes": nodes,
        "ticks_per_repeat": ticks,
        "repeats": repeats,
        "engine_us_per_node": round(engine_s / nodes * 1e6, 3),
        "py_trees_us_per_node": round(plain_s / nodes * 1e6, 3),
        "ratio": round(engine_s / plain_s, 3),
        "target": TARGET,
        "trace_events": events,
    }


# 3 levels: top {A, B}; A {A1, A2}; A1 {x, y}. Leaves visited in a ring that crosses levels.
RING = ["A/A1/x", "A/A1/y", "A/A2", "B"]


def machine_spec() -> dict[str, Any]:
    def leaf(nxt: str) -> dict[str, Any]:
        return {"skill": "noop", "transitions": {"success": nxt}}

    return {
        "initial": "A",
        "outcomes": ["success", "failure"],
        "states": {
            "A": {
                "machine": {
                    "initial": "A1",
                    "outcomes": ["to_b"],
                    "states": {
                        "A1": {
                            "machine": {
                                "initial": "x",
                                "outcomes": ["to_a2"],
                                "states": {"x": leaf("y"), "y": leaf("to_a2")},
                            },
                            "transitions": {"to_a2": "A2"},
                        },
                        "A2": leaf("to_b"),
                    },
                },
                "transitions": {"to_b": "B"},
            },
            "B": leaf("A"),
        },
    }


def raw_machine() -> tuple[Any, list[str]]:
    class Model:
        pass

    class State(HierarchicalMachine.state_cls):  # type: ignore[name-defined,misc]
        separator = "/"

    class Machine(HierarchicalMachine):
        state_cls = State

    states = [
        {"name": "A", "initial": "A1", "children": [{"name": "A1", "initial": "x", "children": ["x", "y"]}, "A2"]},
        "B",
    ]
    model = Model()
    machine = Machine(model=model, states=states, initial="A", auto_transitions=False)
    machine.add_transition("next", "A/A1/x", "A/A1/y")
    machine.add_transition("next", "A/A1/y", "A/A2")
    machine.add_transition("next", "A/A2", "B")
    machine.add_transition("next", "B", "A")
    return model, RING


def bench_machine(triggers: int, repeats: int) -> dict[str, Any]:
    engine = Engine(clock=SimClock(100), registry=_registry())
    machine = engine.builder().machine(machine_spec())
    engine.set_root(machine)
    engine.tick()

    def engine_run() -> float:
        first = machine.transitions
        start = time.perf_counter()
        while machine.transitions - first < triggers:
            engine.tick()
        return (time.perf_counter() - start) / (machine.transitions - first)

    model, _ = raw_machine()

    def raw_run() -> float:
        start = time.perf_counter()
        for _ in range(triggers):
            model.trigger("next")
        return (time.perf_counter() - start) / triggers

    engine_s, raw_s = _best_pair(engine_run, raw_run, repeats)
    engine.close()
    return {
        "bench": "machine",
        "levels": 3,
        "triggers_per_repeat": triggers,
        "repeats": repeats,
        "engine_us_per_trigger": round(engine_s * 1e6, 2),
        "transitions_us_per_trigger": round(raw_s * 1e6, 2),
        "ratio": round(engine_s / raw_s, 3),
        "target": TARGET,
    }


def timeouts_spec() -> dict[str, Any]:
    """A mission that does nothing but wait on 60-second timeouts, in a tree and in a machine."""
    machine = {
        "states": {
            "work": {
                "tree": {"timeout": 60, "child": {"wait": {"duration": 600}}},
                "timeout": 60,
                "transitions": {"failure": "work", "timeout": "work", "success": "success"},
            }
        }
    }
    tree = {"repeat": "forever", "child": {"force_success": {"timeout": 60, "child": {"wait": {"duration": 600}}}}}
    return {"parallel": [tree, {"machine": machine}]}


def bench_timeouts(ticks: int, repeats: int) -> dict[str, Any]:
    """Wall time of 10,000 ticks at 10 Hz (1,000 s of mission time) on the sim clock."""

    def once() -> float:
        engine = Engine(clock=SimClock(10))
        engine.set_root(engine.builder().tree(timeouts_spec()))
        start = time.perf_counter()
        engine.run(max_ticks=ticks)
        elapsed = time.perf_counter() - start
        engine.close()
        return elapsed

    wall = min(once() for _ in range(repeats))
    mission_s = ticks / 10
    return {
        "bench": "simclock_timeouts",
        "ticks": ticks,
        "mission_s": mission_s,
        "repeats": repeats,
        "wall_s": round(wall, 4),
        "speedup_vs_realtime": round(mission_s / wall, 1),
    }


# -- Nav2's NavigateToPose tree (issue 22): imported from Nav2's XML, against the same tree in YAML --

NAV2_XML = Path(__file__).resolve().parents[3] / "shared" / "nav2" / "navigate_to_pose_w_replanning_and_recovery.xml"
NAV2_YAML = Path(__file__).with_name("nav2_navigate_to_pose.yaml")


def _nav2_drive(trees: dict[str, Any], root: str, ticks: int) -> float:
    """Seconds per engine tick (the world's step not counted) of ``ticks`` ticks of the PeopleBot
    driving from the museum's entrance to exhibit_a under the tree: planning at 1 Hz, following."""
    from botstage.behaviors.kinds import NodeKinds
    from botstage.behaviors.nav2.navigator import ERROR_CODE_PREFIXES
    from tests.bench.navsim import NavSim

    sim = NavSim("museum", "peoplebot", "entrance", seed=3)
    kinds = NodeKinds.default("btcpp")  # Nav2's nodes are in BT.CPP's scope
    engine = Engine(clock=sim.clock, interfaces={**sim.sim.devices, **sim.services.interfaces}, kinds=kinds)
    engine.set_root(engine.builder(trees=trees).named_tree(root))
    engine.blackboard.update({"goal": "exhibit_a", **{f"{p}_error_code": 0 for p in ERROR_CODE_PREFIXES}})
    spent = 0.0
    for _ in range(ticks):
        start = time.perf_counter()
        engine.tick()
        spent += time.perf_counter() - start
        sim.step()
    engine.close()
    return spent / ticks


def bench_nav2(ticks: int, repeats: int) -> dict[str, Any]:
    """Nav2's NavigateToPose tree as Nav2 ships it (BT.CPP XML, imported) against the same tree
    written in botstage's YAML (tests/bench/nav2_navigate_to_pose.yaml), µs per tick on a robot."""
    from botstage.behaviors.btcpp.xml_format import load_xml
    from botstage.behaviors.kinds import NodeKinds

    row: dict[str, Any] = {"bench": "nav2_navigate_to_pose", "ticks_per_repeat": ticks, "repeats": repeats}
    if not NAV2_XML.exists():
        return {**row, "skipped": f"{NAV2_XML} is not beside this checkout"}
    loaded = load_xml(NAV2_XML)
    if loaded.data is None:
        return {**row, "skipped": "; ".join(str(p) for p in loaded.problems)}
    native = yaml.safe_load(NAV2_YAML.read_text(encoding="utf-8"))
    built = Engine(kinds=NodeKinds.default("btcpp")).builder(trees=native["trees"]).named_tree(native["root"])
    nodes = sum(1 for _ in built.iterate())
    xml_s, yaml_s = _best_pair(
        lambda: _nav2_drive(loaded.data["trees"], loaded.data["root"], ticks),
        lambda: _nav2_drive(native["trees"], native["root"], ticks),
        repeats,
    )
    return {
        **row,
        "nodes": nodes,
        "xml_us_per_tick": round(xml_s * 1e6, 1),
        "yaml_us_per_tick": round(yaml_s * 1e6, 1),
        "ratio": round(xml_s / yaml_s, 3),
        "target": TARGET,
    }


# -- end Nav2


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The benches whose engine cost over the baseline is above its target."""
    return [r["bench"] for r in results if r.get("ratio", 0) > r.get("target", float("inf"))]


def main(quick: bool = False) -> list[dict[str, Any]]:
    ticks, repeats, triggers = (20, 3, 400) if quick else (100, 15, 1500)
    results = [
        bench_tree("instant", ticks, repeats),
        bench_tree("running", ticks, repeats),
        bench_machine(triggers, repeats),
        bench_timeouts(10_000, 3 if quick else 5),
        bench_nav2(60 if quick else 300, 1 if quick else 5),  # Nav2's tree (issue 22)
    ]
    for result in results:
        print(json.dumps(result), flush=True)
    return results


if __name__ == "__main__":
    main()
