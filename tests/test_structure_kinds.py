"""Structural facts about node kinds: one name per concept where a user writes it, scoped node
sets registered as plug-ins, one ControlNode halt rule for BT.CPP's and Nav2's controls, and no
fence comments left in the repository."""

from __future__ import annotations

import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import py_trees
from py_trees.common import Status

from botstage.behaviors.btcpp import behaviours as bt
from botstage.behaviors.btcpp.nodes import NODE_SET as BTCPP_SET
from botstage.behaviors.kinds import NodeKinds
from botstage.behaviors.nav2 import behaviours as nav2
from botstage.behaviors.nav2.nodes import NODE_SET as NAV2_SET
from botstage.missions.loader import YAML, format_of

ROOT = Path(__file__).resolve().parent.parent
FENCE = "# -- " + "botstage-"  # split, so this file does not hold one itself


def folded(name: str) -> str:
    return name.replace("_", "").lower()


def test_no_fence_comment_is_left() -> None:
    fenced = []
    for path in ROOT.rglob("*"):
        if ".git" in path.parts or not path.is_file() or path.suffix not in (".py", ".toml", ".md", ".yaml", ".cfg"):
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        fenced += [f"{path.relative_to(ROOT)}:{n}" for n, line in enumerate(text.splitlines(), 1) if FENCE in line]
    assert fenced == []


def listed_kinds(*args: str) -> list[str]:
    result = subprocess.run(
        [sys.executable, "-m", "botstage.missions.cli", "nodes", *args],
        capture_output=True,
        text=True,
        env={"COLUMNS": "400", "PATH": "/usr/bin:/bin"},
        check=True,
    )
    rows = [line for line in result.stdout.splitlines() if line.startswith("│")]
    return [cells.split("│")[1].strip() for cells in rows if cells.split("│")[1].strip()]


def test_botstage_nodes_lists_no_two_kinds_that_differ_only_in_case_or_underscores() -> None:
    for args in ((), ("--scope", "btcpp")):
        names = listed_kinds(*args)
        assert len(names) > 10, names
        groups: dict[str, list[str]] = defaultdict(list)
        for name in names:
            groups[folded(name)].append(name)
        assert [g for g in groups.values() if len(g) > 1] == [], args
    assert "sequence" in listed_kinds() and "Sequence" not in listed_kinds()
    assert "Sequence" in listed_kinds("--scope", "btcpp") and "sequence" not in listed_kinds("--scope", "btcpp")


def test_yaml_sees_no_btcpp_ids_and_xml_sees_btcpps() -> None:
    yaml_kinds, xml_kinds = NodeKinds.default(), NodeKinds.default("btcpp")
    btcpp_ids = {kind.name for kind in BTCPP_SET.kinds}
    nav2_ids = {kind.name for kind in NAV2_SET.kinds}
    assert not (btcpp_ids | nav2_ids) & set(yaml_kinds)
    assert not any(name in yaml_kinds for name in btcpp_ids)  # not even as an alias
    assert btcpp_ids | nav2_ids <= set(xml_kinds)
    assert set(xml_kinds.scoped()) == btcpp_ids | nav2_ids
    # one canonical name for a fallback in YAML; the other spelling is an alias, never listed
    assert "selector" in set(yaml_kinds) and "fallback" not in set(yaml_kinds)
    assert yaml_kinds.get("fallback") is yaml_kinds.get("selector")


def test_btcpp_and_nav2_register_through_entry_points_only() -> None:
    registry = (ROOT / "behaviors" / "kinds" / "registry.py").read_text(encoding="utf-8")
    assert "btcpp" not in registry.split('"""', 2)[2].split("class NodeSet")[0]  # no hard-coded module
    assert set(NodeKinds.builtin("btcpp")) == set(NodeKinds.builtin())  # without plug-ins: botstage's only
    origins = {NodeKinds.default("btcpp").origin(kind.name) for kind in (*BTCPP_SET.kinds, *NAV2_SET.kinds)}
    assert all(origin.startswith("plugin") for origin in origins), origins


def test_mission_formats_are_found_by_suffix_through_the_registry() -> None:
    loader = (ROOT / "missions" / "loader.py").read_text(encoding="utf-8")
    assert "btcpp" not in loader and "xml_format" not in loader
    assert format_of("m.yaml") is YAML and format_of("m.yml") is YAML
    assert format_of("tree.xml").name == "xml"
    assert type(format_of("tree.xml")).__module__ == "botstage.behaviors.btcpp.xml_format"


def test_no_runtime_import_cycle_in_btcpp_import_and_export() -> None:
    for name in ("to_spec", "export", "machines"):
        text = (ROOT / "behaviors" / "btcpp" / f"{name}.py").read_text(encoding="utf-8")
        lazy = re.findall(r"^[ \t]+from botstage\.behaviors\.btcpp\.\w+ import", text, re.MULTILINE)
        assert lazy == [], name
    to_spec = (ROOT / "behaviors" / "btcpp" / "to_spec.py").read_text(encoding="utf-8")
    assert "import" not in " ".join(line for line in to_spec.splitlines() if "btcpp.machines" in line)
    assert "from botstage.behaviors.btcpp.export import" not in to_spec
    machines = (ROOT / "behaviors" / "btcpp" / "machines.py").read_text(encoding="utf-8")
    assert "from botstage.behaviors.btcpp.export import" not in machines  # constants come from vocabulary


# -- one ControlNode -------------------------------------------------------------------------


class Leaf(py_trees.behaviour.Behaviour):
    """A leaf that returns the statuses it is given, and counts its halts."""

    def __init__(self, name: str, statuses: str) -> None:
        super().__init__(name)
        self.statuses = [{"S": Status.SUCCESS, "F": Status.FAILURE, "R": Status.RUNNING}[c] for c in statuses]
        self.halts = 0

    def update(self) -> Status:
        return self.statuses.pop(0) if len(self.statuses) > 1 else self.statuses[0]

    def terminate(self, new_status: Status) -> None:
        if new_status is Status.INVALID and self.status is Status.RUNNING:
            self.halts += 1


def tick(node: Any) -> Status:
    for _ in node.tick():
        pass
    return node.status


def test_nav2_controls_are_btcpps_control_node() -> None:
    for cls in (nav2.PipelineSequence, nav2.RecoveryNode, nav2.RoundRobin, nav2.NonblockingSequence):
        assert issubclass(cls, bt.ControlNode)
    assert not hasattr(nav2, "_Control") and not hasattr(bt, "_Control")


def halted_after_running(control: Any, children: list[Leaf]) -> Any:
    assert tick(control) is Status.RUNNING
    control.stop(Status.INVALID)  # BT.CPP's halt() of the control
    return control


def test_halting_a_control_halts_its_running_children_and_resets_them_all_in_both_sets() -> None:
    """control_node.cpp: halt() halts the running children and sets every child back to IDLE, and
    the node forgets its progress; BT.CPP's Sequence and Nav2's PipelineSequence alike."""
    for make in (
        lambda kids: bt.Sequence("seq", kids, Status.SUCCESS),
        lambda kids: nav2.PipelineSequence("pipe", kids),
    ):
        done, running = Leaf("done", "S"), Leaf("running", "R")
        control = halted_after_running(make([done, running]), [done, running])
        assert running.halts == 1
        assert done.status is Status.INVALID and running.status is Status.INVALID  # IDLE
        # progress forgotten: the first child runs again on the next tick
        done.statuses, running.statuses = [Status.FAILURE], [Status.RUNNING]
        assert tick(control) is Status.FAILURE


def test_a_control_reset_to_idle_when_not_running_keeps_its_progress() -> None:
    """BT.CPP's resetStatus is not halt(): SequenceWithMemory keeps the child it stopped at."""
    first, second = Leaf("first", "S"), Leaf("second", "F")
    control = bt.Sequence("mem", [first, second], Status.SUCCESS, memory=True)
    assert tick(control) is Status.RUNNING  # the wake-up rule: one synchronous child per tick
    assert tick(control) is Status.FAILURE
    control.stop(Status.INVALID)
    assert control.index == 1


def test_no_runtime_import_cycle_in_behaviors() -> None:
    from tests.import_graph import cycles, graph

    edges = graph()
    inside = {m: {t for t in targets if t.startswith("botstage.behaviors")} for m, targets in edges.items()}
    found = [c for c in cycles(inside) if all(m.startswith("botstage.behaviors") for m in c)]
    assert found == []
