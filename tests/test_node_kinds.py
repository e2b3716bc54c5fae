"""The node-kind registry: built-in kinds are entries like any plug-in's, read by the builder,
the pictures and the JSON Schema; the kinds added after it each touch one module."""

from __future__ import annotations

from typing import Annotated, Any

import py_trees
import pytest
from pydantic import Field

from botstage.behaviors.builder import SpecError
from botstage.behaviors.kinds import CompositeKind, DecoratorKind, KindOptions, NodeBuild, NodeKinds
from botstage.behaviors.render import describe, to_text
from botstage.missions.schema import json_schema
from botstage.skills.registry import Registry

BUILTIN = {
    "sequence",
    "reactive_sequence",
    "selector",
    "reactive_selector",
    "parallel",
    "inverter",
    "force_success",
    "force_failure",
    "one_shot",
    "retry",
    "repeat",
    "timeout",
    "while",
    "if",
    "delay",
    "keep_running_until_failure",
    "skill",
    "condition",
    "subtree",
    "machine",
}


def statuses(engine: Any, spec: dict[str, Any], ticks: int) -> list[str]:
    engine.set_root(engine.builder().tree(spec))
    return [engine.tick().value for _ in range(ticks)]


def test_builtin_kinds_are_registered_like_plugins() -> None:
    kinds = NodeKinds.builtin()
    assert set(kinds) == BUILTIN
    # BehaviorTree.CPP's names are aliases only: read as botstage's one kind, never listed
    assert kinds.aliases == {"fallback": "selector", "reactive_fallback": "reactive_selector"}
    assert kinds.get("fallback") is kinds.get("selector")
    assert {kinds.origin(name) for name in kinds} == {"builtin"}
    assert all(kinds.get(name).description for name in kinds)


def test_delay_waits_on_the_mission_clock_then_runs_the_child(make_engine) -> None:
    engine = make_engine(rate_hz=10)
    got = statuses(engine, {"delay": 0.3, "child": {"wait": {"duration": 0.1}}}, 6)
    # 0.0, 0.1, 0.2: waiting; 0.3: the wait starts; 0.4: it is done
    assert got == ["RUNNING", "RUNNING", "RUNNING", "RUNNING", "SUCCESS", "RUNNING"]


def test_delay_restarts_its_wait_after_a_halt(make_engine) -> None:
    engine = make_engine(rate_hz=10)
    root = engine.builder().tree({"delay": 0.2, "child": "drive"})
    engine.set_root(root)
    engine.tick()
    engine.halt("test")
    assert [engine.tick().value for _ in range(3)] == ["RUNNING", "RUNNING", "RUNNING"]
    # halted at 0.1 s: the wait starts again there, so the child starts at 0.3 s, not 0.2 s
    assert [event["t"] for event in engine.trace.of("skill_start")] == [0.3]


def test_keep_running_until_failure(make_engine) -> None:
    engine = make_engine()
    spec = {"keep_running_until_failure": {"condition": "n < 3"}, "name": "k"}
    engine.blackboard.set("n", 0, writer="test")
    engine.set_root(engine.builder().tree(spec))
    seen = []
    for n in range(5):
        engine.blackboard.set("n", n, writer="test")
        seen.append(engine.tick().value)
    assert seen == ["RUNNING", "RUNNING", "RUNNING", "FAILURE", "FAILURE"]


def test_argument_and_option_errors_are_located(make_engine) -> None:
    engine = make_engine()
    spec = {
        "sequence": [
            {"delay": -1, "child": "drive"},
            {"delay": float("nan"), "child": "drive"},
            {"sequence": ["drive"], "memory": "yes"},
            {"keep_running_until_failure": "drive", "child": "drive"},
        ]
    }
    with pytest.raises(SpecError) as info:
        engine.builder().tree(spec)
    problems = {"/".join(map(str, p.path)): p.message for p in info.value.problems}
    assert problems["sequence/0/delay"] == "delay: input should be greater than or equal to 0"
    assert problems["sequence/1/delay"] == "delay: input should be a finite number"
    assert problems["sequence/2/memory"] == "memory of 'sequence': input should be a valid boolean"
    assert problems["sequence/3/child"] == "unknown option 'child' for 'keep_running_until_failure'"


class EveryOther(CompositeKind):
    """A composite a user writes: ticks its children in turn, one per tick."""

    name = "every_other"
    description = "one child per tick, in turn"

    class Options(KindOptions):
        start: Annotated[int, Field(ge=0)] = 0

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return py_trees.composites.Sequence(name=b.name, memory=True, children=b.children)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return "every other"


class Twice(DecoratorKind):
    name = "twice"
    description = "repeat the child twice"

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        return py_trees.decorators.Repeat(name=b.name, child=b.child, num_success=2)


def test_kinds_registered_in_code_are_built_drawn_and_in_the_schema(make_engine) -> None:
    kinds = NodeKinds.builtin()
    kinds.register(EveryOther)
    kinds.register(Twice, origin="test")
    engine = make_engine(kinds=kinds)
    root = engine.builder().tree({"every_other": [{"twice": "fail"}, "drive"], "start": 1})
    picture = to_text(describe(root))
    assert picture.splitlines()[0] == "root: every other"
    assert "twice" in picture
    with pytest.raises(SpecError, match="start of 'every_other': input should be greater than or equal to 0"):
        engine.builder().tree({"every_other": ["drive"], "start": -1})
    schema = json_schema(Registry.builtin(), kinds)
    properties = schema["$defs"]["node"]["anyOf"][1]["properties"]
    assert properties["every_other"]["items"] == {"$ref": "#/$defs/node"}
    assert properties["start"]["minimum"] == 0
    assert properties["twice"] == {"$ref": "#/$defs/node"}


def test_a_kind_named_twice_is_refused() -> None:
    kinds = NodeKinds.builtin()

    class Other(Twice):
        pass

    kinds.register(Twice)
    with pytest.raises(ValueError, match="already registered"):
        kinds.register(Other)


def test_sibling_names_are_made_unique_in_linear_time(make_engine) -> None:
    engine = make_engine()
    children = [{"wait": {"duration": 1}} for _ in range(3)] + [{"wait": {"duration": 1}, "name": "wait#5"}]
    children += [{"wait": {"duration": 1}} for _ in range(3)]
    root = engine.builder().tree({"parallel": children})
    assert [c.name for c in root.children] == ["wait", "wait#2", "wait#3", "wait#5", "wait#4", "wait#6", "wait#7"]


def test_an_unknown_kind_whose_plugin_failed_to_load_says_why(make_engine) -> None:
    from botstage.robots.plugins import PluginProblem

    kinds = NodeKinds.builtin()
    kinds.problems.append(PluginProblem("unless = my_kit.kinds:Unless", "import failed: ModuleNotFoundError: no"))
    engine = make_engine(kinds=kinds)
    with pytest.raises(SpecError) as info:
        engine.builder().tree({"unless": "estop", "child": "drive"})
    (problem,) = info.value.problems
    assert problem.message == "unknown node or skill 'unless'"
    assert (
        problem.hint
        == "the plugin 'unless = my_kit.kinds:Unless' failed to load: import failed: ModuleNotFoundError: no"
    )
