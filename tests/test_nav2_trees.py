"""Nav2's own behaviour trees, unmodified, on botstage's simulated robots (issue 22).

The XML files are the Nav2 maintainers' (``../shared/nav2``, beside the checkout; never copied
here). Each drive is one session that takes goal after goal, as Nav2's BT navigator does
(``botstage.behaviors.nav2.navigator``), so one tree build covers every named place of a map.
"""

from __future__ import annotations

import math
import os
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from botstage.behaviors.btcpp.xml_format import load_xml, loads_xml
from botstage.behaviors.engine import Engine
from botstage.behaviors.kinds import CompositeKind, DecoratorKind, NodeKinds
from botstage.behaviors.nav2.models import check_models
from botstage.behaviors.nav2.navigator import Navigator
from botstage.missions.cli import app
from botstage.skills.registry import Registry
from tests.bench.bench_tick import NAV2_YAML
from tests.bench.navsim import NavSim

SHARED = Path(__file__).resolve().parents[2] / "shared" / "nav2"
TO_POSE = "navigate_to_pose_w_replanning_and_recovery.xml"
THROUGH_POSES = "navigate_through_poses_w_replanning_and_recovery.xml"
XY_TOLERANCE, YAW_TOLERANCE = 0.25, 0.25  # Nav2's general goal checker, FollowPath's defaults


@pytest.fixture(scope="module")
def nav2() -> Path:
    if not SHARED.is_dir():
        if os.environ.get("CI") == "true":
            pytest.fail(f"{SHARED} is missing: CI runs with ../shared beside the clone")
        pytest.skip("../shared/nav2 (Nav2's trees) is not beside this checkout")
    return SHARED


def session(nav2: Path, tree: str, sim: NavSim) -> tuple[Navigator, Engine]:
    """Nav2's tree file, imported and built once, on the simulated robot."""
    loaded = load_xml(nav2 / tree)
    assert loaded.data is not None, [str(p) for p in loaded.problems]
    engine = Engine(
        clock=sim.clock,
        interfaces={**sim.sim.devices, **sim.services.interfaces},
        kinds=NodeKinds.default(loaded.data["nodes"]),
    )
    engine.set_root(engine.builder(trees=loaded.data["trees"]).named_tree(loaded.data["root"]))
    return Navigator(engine, sim.step), engine


def skills_run(engine: Engine) -> Counter[str]:
    return Counter(event["skill"] for event in engine.trace.of("skill_start"))


def test_every_nav2_file_imports(nav2: Path) -> None:
    files = sorted(nav2.glob("*.xml"))
    assert len(files) >= 4
    for path in files:
        loaded = load_xml(path)
        assert loaded.problems == [], [str(p) for p in loaded.problems]
        assert loaded.data is not None
    # the node model file is a library of models, no tree: botstage's nodes agree with it
    model = check_models(nav2 / "nav2_tree_nodes.xml")
    assert model.problems == [], [str(p) for p in model.problems]
    for node in ("PipelineSequence", "RecoveryNode", "RoundRobin", "RateController", "FollowPath", "Spin", "BackUp"):
        assert node in model.implemented
    assert len(model.implemented) >= 40


def test_an_unknown_nav2_port_is_a_located_error(nav2: Path) -> None:
    text = (nav2 / TO_POSE).read_text().replace('spin_dist="1.57"', 'spin_distance="1.57"')
    line = next(n for n, row in enumerate(text.splitlines(), 1) if "spin_distance" in row)
    loaded = loads_xml(text, name=TO_POSE)
    assert loaded.data is None
    (problem,) = loaded.problems
    assert "no port 'spin_distance'" in str(problem) and "did you mean 'spin_dist'" in str(problem)
    assert str(problem).startswith(f"{TO_POSE}:{line}:")  # the <Spin> element's line


def shape(spec: Any, registry: Registry, kinds: NodeKinds) -> Any:
    """A tree spec as (kind, name, what it does, children): ports botstage ignores left out."""
    (kind,) = [key for key in spec if key in registry or key in kinds]
    value, children = spec[kind], []
    if kind in registry:
        inputs = registry.get(kind).inputs
        ports = {p: v for p, v in value.items() if not inputs[p].doc.startswith("ignored")}
        return (kind, spec.get("name"), ports, spec.get("outputs"), [])
    node = kinds.get(kind)
    if isinstance(node, CompositeKind):
        children = value
    elif isinstance(node, DecoratorKind):
        children = [value]
    options = {k: v for k, v in spec.items() if k not in (kind, "name")}
    return (kind, spec.get("name"), options, None, [shape(c, registry, kinds) for c in children])


def test_the_bench_yaml_is_nav2s_tree(nav2: Path) -> None:
    loaded = load_xml(nav2 / TO_POSE)
    assert loaded.data is not None
    native = yaml.safe_load(NAV2_YAML.read_text(encoding="utf-8"))
    assert native["nodes"] == loaded.data["nodes"] == "btcpp"
    registry, kinds = Registry.default(), NodeKinds.default("btcpp")
    imported = shape(loaded.data["trees"][loaded.data["root"]], registry, kinds)
    assert shape(native["trees"][native["root"]], registry, kinds) == imported


@pytest.mark.parametrize(("world", "robot"), [("museum", "peoplebot"), ("restaurant", "chefbot")])
def test_navigate_to_pose_reaches_every_place(nav2: Path, world: str, robot: str) -> None:
    sim = NavSim(world, robot, "dock", seed=3)
    places = sorted(sim.grid.places)
    navigator, engine = session(nav2, TO_POSE, sim)
    missed = []
    for place in [p for p in places if p != "dock"] + ["dock"]:
        result = navigator.navigate({"goal": place}, limit=300)
        gx, gy, gtheta = sim.grid.places[place]
        truth = sim.truth
        off = math.hypot(truth.x - gx, truth.y - gy)
        turned = abs(math.remainder(truth.theta - gtheta, math.tau))
        if not result.succeeded or off > XY_TOLERANCE + 0.05 or turned > YAW_TOLERANCE + 0.05:
            missed.append(f"{place}: {result.status.value} at {truth} ({off:.2f} m, {turned:.2f} rad off)")
    assert not missed
    assert sim.sim.world.body.bumps == 0
    runs = skills_run(engine)
    assert runs["FollowPath"] >= len(places) and runs["ComputePathToPose"] >= len(places)
    assert runs["Spin"] == runs["BackUp"] == 0  # nothing in the way: no recovery


def test_a_blocked_door_runs_nav2s_recoveries(nav2: Path) -> None:
    sim = NavSim("restaurant", "peoplebot", "table_1", people=3)
    sim.sim.crowd.next_group_at = math.inf  # they stay where they are put: in the kitchen's only door
    for person, y in zip(sim.sim.crowd.people, (6.0, 6.9, 7.8), strict=True):
        person.x, person.y, person.pause_until = 5.2, y, math.inf
        person.goal = (5.2, y)
    navigator, engine = session(nav2, TO_POSE, sim)
    result = navigator.navigate({"goal": "kitchen"}, limit=300)
    assert not result.succeeded
    runs = skills_run(engine)
    for recovery in ("ClearEntireCostmap", "Spin", "Wait", "BackUp"):
        assert runs[recovery] >= 1, runs
    order = [e["skill"] for e in engine.trace.of("skill_start") if e["skill"] in ("Spin", "Wait", "BackUp")]
    assert order[:3] == ["Spin", "Wait", "BackUp"]  # RoundRobin takes them in turn
    codes = {e["outputs"].get("error_code_id") for e in engine.trace.of("skill_outcome") if e["skill"] == "FollowPath"}
    assert 105 in codes  # FAILED_TO_MAKE_PROGRESS, as Nav2's controller server says it
    assert sim.sim.world.body.bumps == 0
    # they leave: the same session's next goal gets through
    for person in sim.sim.crowd.people:
        person.x = 12.0
    assert navigator.navigate({"goal": "kitchen"}, limit=300).succeeded


def test_navigate_through_poses_passes_every_goal(nav2: Path) -> None:
    sim = NavSim("museum", "peoplebot", "entrance", seed=3)
    goals = ["reception", "exhibit_d", "hall_centre", "exhibit_c"]
    passed: list[str] = []

    def step() -> None:
        sim.step()
        truth = sim.truth
        for goal in goals:
            x, y, _ = sim.grid.places[goal]
            if goal not in passed and math.hypot(truth.x - x, truth.y - y) < 0.7:  # the tree's radius
                passed.append(goal)

    navigator, engine = session(nav2, THROUGH_POSES, sim)
    navigator.step = step
    result = navigator.navigate({"goals": goals, "waypoint_statuses": [{"status": "pending"} for _ in goals]})
    assert result.succeeded
    assert passed == goals
    x, y, _ = sim.grid.places[goals[-1]]
    assert math.hypot(sim.truth.x - x, sim.truth.y - y) <= XY_TOLERANCE
    assert skills_run(engine)["ComputePathThroughPoses"] >= 1


def test_botstage_run_sets_the_goal_of_nav2s_xml(nav2: Path, tmp_path: Path, monkeypatch: Any) -> None:
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run"
    args = ["run", str(nav2 / TO_POSE), "--robot", "peoplebot", "--world", "museum", "-q", "--out", str(out)]
    result = CliRunner().invoke(app, [*args, "--set", "goal=[9.0, 4.5, -1.57]"])
    assert result.exit_code == 0, result.output
    assert "outcome success" in result.output
    summary = yaml.safe_load((out / "summary.json").read_text())
    assert summary["outcome"] == "success"
    bad = CliRunner().invoke(app, [*args, "--set", "goal"])
    assert bad.exit_code == 2 and "expected KEY=VALUE" in bad.output
