"""BehaviorTree.CPP v4 XML export: every shipped mission goes YAML -> XML -> mission data and
comes back the same, and runs to the same trace; the XML passes the checks BT.CPP's parser makes
(``src/xml_parsing.cpp``: ``VerifyXML`` and ``createNodeFromXML``); bad input is a located error."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest

from botstage.behaviors.btcpp.export import ExportError, export_loaded, export_mission, normal_form
from botstage.behaviors.btcpp.xml_format import loads_xml
from botstage.missions.check import check
from botstage.missions.loader import load
from botstage.missions.runner import run

EXAMPLES = Path(__file__).resolve().parent.parent / "missions" / "examples"
SHIPPED = sorted(EXAMPLES.glob("*.yaml"))
# mission seconds each traced round trip runs: 20 s, less where a simulated second costs much CPU
# (measured: the face tracker renders and searches camera frames, ~2.6 CPU s per mission second;
# the Bittle's and the listener's sims ~0.3 and 0.2)
TRACED_SECONDS = {"face_tracker": 1.0, "bittle_patrol": 4.0, "listen_demo": 8.0}


def exported(path: Path) -> str:
    return export_mission(path, load)


def reread(xml: str, tmp_path: Path, name: str) -> dict[str, Any]:
    target = tmp_path / f"{name}.xml"
    target.write_text(xml, encoding="utf-8")
    loaded = load(target)
    assert [str(p) for p in loaded.problems] == []
    assert loaded.data is not None
    assert loaded.data["nodes"] == "btcpp"  # an XML file's trees are in BT.CPP's scope
    return {key: value for key, value in loaded.data.items() if key != "nodes"}


def test_shipped_missions_are_found() -> None:
    names = {p.stem for p in SHIPPED}
    assert {"hello", "peoplebot_entertainer", "chefbot_delivery", "hello_api"} <= names


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_round_trip_gives_the_same_mission(path: Path, tmp_path: Path) -> None:
    original = load(path)
    assert original.problems == []
    assert reread(exported(path), tmp_path, path.stem) == normal_form(original.data or {})


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_round_trip_runs_to_the_same_trace(path: Path, tmp_path: Path) -> None:
    xml = tmp_path / f"{path.stem}.xml"
    xml.write_text(exported(path), encoding="utf-8")
    until = TRACED_SECONDS.get(path.stem, 20.0)
    traces = []
    for source, folder in ((path, "yaml"), (xml, "xml")):
        result = run(source, until=until, out=tmp_path / folder)
        lines = (tmp_path / folder / "trace.jsonl").read_text(encoding="utf-8").splitlines()
        traces.append((result.outcome, [json.loads(line) for line in lines]))
    assert traces[0][1], "the run left an empty trace"
    assert traces[1] == traces[0]


# -- what the shipped missions do not use -----------------------------------------------------

EVERYTHING = """
name: everything
nodes: btcpp  # BT.CPP's nodes beside botstage's kinds, as an imported XML tree has them
seed: 3
until: 5
keys:
  phase: {type: str, default: idle, doc: where we are}
blackboard: {count: 0, phase: idle, items: [a, b]}
skill_params: {wait: {}}
trees:
  main:
    sequence:
      - {Sequence: [{Sleep: {msec: 100}}, {SetBlackboard: {value: "2", output_key: other}}]}
      - {RetryUntilSuccessful: {wait: {duration: 0.1}}, num_attempts: 2}
      - one_shot: {wait: {duration: 0.1}}
        policy: on_completion
      - delay: 0.25
        child: {wait: {duration: 0.1}}
      - {timeout: 0.0005, child: {wait: {duration: 0.0001}}}
      - {timeout: 1.5, child: {wait: {duration: 0.1}}}
      - {sequence: [{wait: {duration: 0.1}}], memory: false}
      - {if: "count < 10", child: {count: {key: count}}, name: counted}
      - {repeat: forever, child: {wait: {duration: 0.1}}, name: looping}
      - skill: wait
        inputs: {duration: 0.1}
        params: {}
        success_on: [success, failure]
      - {set: {key: phase, value: "{phase}"}}
      - {set: {key: items, value: [x, "y;z", 3]}}
      - parallel: [{wait: {duration: 0.1}, name: a}, {subtree: leaf, remap: {phase: phase}}]
        policy: success_on_selected
        selected: [a]
      - machine:
          initial: one
          outcomes: [ok, bad]
          success_on: [ok, bad]
          preemptions: [{when: "phase == 'a;b -> c'", to: bad}]
          states:
            one:
              skill: wait
              inputs: {duration: 0.1}
              on_enter: {set: {phase: one}}
              transitions:
                success: [{to: two, if: "count > 100"}, {to: three}]
                failure: bad
            two: {machine: named, transitions: {finished: ok}}
            three:
              tree: {sequence: [{wait: {duration: 0.1}}]}
              timeout: 2.5
              on_exit: [{log: leaving}]
              transitions: {success: ok, failure: bad, timeout: bad}
        success_on: ok
      - {machine: named, name: again}
  leaf: {condition: "phase != 'x'"}
machines:
  named:
    outcomes: [finished]
    states:
      only: {tree: leaf, transitions: {success: finished, failure: finished}}
"""


def test_every_kind_and_machine_form_round_trips_and_checks(tmp_path: Path) -> None:
    mission = tmp_path / "everything.yaml"
    mission.write_text(EVERYTHING, encoding="utf-8")
    assert check(mission).problems == []
    xml = exported(mission)
    written = {key: value for key, value in (load(mission).data or {}).items() if key != "nodes"}
    assert reread(xml, tmp_path, "everything") == normal_form(written)
    assert check(tmp_path / "everything.xml").problems == []
    verify_btcpp(xml)
    # botstage kinds with BT.CPP's behaviour are BT.CPP's nodes; the others are declared custom nodes
    root = ET.fromstring(xml)
    tags = {e.tag for e in root.iter()}
    assert {"Sequence", "Timeout", "Delay", "Repeat", "RetryUntilSuccessful"} <= tags
    assert {m.get("ID") for m in root.find("TreeNodesModel") or []} >= {"one_shot", "if", "parallel", "wait"}
    assert "timeout" in tags  # 0.5 ms is not whole milliseconds: botstage's own timeout
    assert "sequence" in tags  # memory: false is an option BT.CPP's Sequence has not


def test_the_model_declares_skill_ports_from_the_contract() -> None:
    root = ET.fromstring(exported(EXAMPLES / "hello.yaml"))
    models = {m.get("ID"): m for m in root.find("TreeNodesModel") or []}
    wait = models["wait"]
    assert wait.tag == "Action"
    (duration,) = [p for p in wait if p.get("name") == "duration"]
    assert duration.tag == "input_port" and duration.get("type") == "double"
    assert duration.text and "second" in duration.text
    assert models["condition"].tag == "Condition"
    assert models["StateMachine"].tag == "Control" and models["State"].tag == "Decorator"


# -- BT.CPP's own checks, written from src/xml_parsing.cpp (v4) ----------------------------------

CONTROL, DECORATOR, ACTION, CONDITION = "Control", "Decorator", "Action", "Condition"
# BT.CPP v4's built-in nodes (BehaviorTreeFactory's constructor) and their ports
BTCPP_NODES: dict[str, tuple[str, set[str]]] = {
    **{n: (CONTROL, set()) for n in ("Sequence", "SequenceWithMemory", "ReactiveSequence", "Fallback")},
    **{n: (CONTROL, set()) for n in ("ReactiveFallback", "IfThenElse", "WhileDoElse", "AsyncSequence")},
    "Parallel": (CONTROL, {"success_count", "failure_count"}),
    "ParallelAll": (CONTROL, {"max_failures"}),
    **{f"Switch{n}": (CONTROL, {"variable", *(f"case_{i}" for i in range(1, n + 1))}) for n in range(2, 7)},
    **{n: (DECORATOR, set()) for n in ("Inverter", "ForceSuccess", "ForceFailure", "KeepRunningUntilFailure")},
    "RetryUntilSuccessful": (DECORATOR, {"num_attempts"}),
    "Repeat": (DECORATOR, {"num_cycles"}),
    "RunOnce": (DECORATOR, {"then_skip"}),
    "Timeout": (DECORATOR, {"msec"}),
    "Delay": (DECORATOR, {"delay_msec"}),
    "Precondition": (DECORATOR, {"if", "else"}),
    **{n: (ACTION, set()) for n in ("AlwaysSuccess", "AlwaysFailure")},
    "Sleep": (ACTION, {"msec"}),
    "SetBlackboard": (ACTION, {"value", "output_key"}),
    "UnsetBlackboard": (ACTION, {"key"}),
    "Script": (ACTION, {"code"}),
    "ScriptCondition": (CONDITION, {"code"}),
}
ELEMENT_TYPES = (ACTION, CONDITION, CONTROL, DECORATOR, "SubTree")  # tags that take an ID
CONDITION_ATTRIBUTES = ("_skipIf", "_failureIf", "_successIf", "_while", "_onSuccess", "_onFailure", "_onHalted")


def is_port_name(name: str) -> bool:
    """basic_types.cpp IsAllowedPortName: starts with a letter, and is not a reserved attribute."""
    reserved = {"ID", "name", "_autoremap", *CONDITION_ATTRIBUTES, "_post"}
    return bool(name) and name[0].isalpha() and name not in reserved


def verify_btcpp(xml: str) -> None:
    """Raise AssertionError where BT.CPP's loadDocImpl/VerifyXML/createNodeFromXML would throw."""
    root = ET.fromstring(xml)
    assert root.tag == "root", "The XML must have a root node called <root>"
    assert root.get("BTCPP_format") == "4"
    models = root.findall("TreeNodesModel")
    assert len(models) <= 1, "Only a single node <TreeNodesModel> is supported"
    registered = dict(BTCPP_NODES)
    for model in models:
        for node in model:
            assert node.get("ID"), f"<{node.tag}> in TreeNodesModel: the attribute [ID] is mandatory"
            ports = {p.get("name") for p in node if p.tag in ("input_port", "output_port", "inout_port")}
            assert all(ports), f"a port of {node.get('ID')} has no name"
            if node.tag != "SubTree":
                registered[node.get("ID", "")] = (node.tag, {p for p in ports if p})
    trees = {t.get("ID"): t for t in root.findall("BehaviorTree")}
    for tree_id, tree in trees.items():
        assert tree_id or len(root) == 1, "The tag <BehaviorTree> must have the attribute [ID]"
        assert tree_id not in registered, f"BehaviorTree {tree_id}: must not use the name of a registered Node"
        assert len(tree) == 1, f"The tag <BehaviorTree> with ID '{tree_id}' must have exactly 1 child"
        _verify_node(tree[0], registered, trees)
    main = root.get("main_tree_to_execute")
    if main is not None:
        assert main in trees, "The tree specified in [main_tree_to_execute] can't be found"
    else:
        assert len(trees) == 1, "without [main_tree_to_execute] a file holds a single BehaviorTree"


def _verify_node(node: ET.Element, registered: dict[str, tuple[str, set[str]]], trees: dict[str, Any]) -> None:
    typed = node.tag in ELEMENT_TYPES
    node_id = node.get("ID", "")
    where = f"<{node.tag}{f' ID={node_id!r}' if node_id else ''}>"
    assert not typed or node_id, f"The tag {where} must have the attribute [ID]"
    assert typed or "ID" not in node.attrib, f"Attribute [ID] is not allowed in {where}"
    if node.tag == "SubTree":
        assert len(node) == 0, f"<SubTree> with ID '{node_id}' should not have any child"
        assert node_id not in registered, "The attribute [ID] of tag <SubTree> must not use a registered Node"
        assert node_id in trees, f"SubTree {node_id}: no such BehaviorTree"
        return
    lookup = node_id if typed else node.tag
    assert lookup in registered, f"Node not recognized: {lookup}"
    node_type, ports = registered[lookup]
    if node_type == DECORATOR:
        assert len(node) == 1, f"The node '{lookup}' must have exactly 1 child"
    elif node_type == CONTROL:
        assert len(node) >= 1, f"The node '{lookup}' must have 1 or more children"
    else:
        assert len(node) == 0, f"The node '{lookup}' must not have any child"
    for attribute in node.attrib:
        if is_port_name(attribute):
            assert attribute in ports, f"a port with name [{attribute}] is found in {where} but not in its model"
    for child in node:
        _verify_node(child, registered, trees)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_exported_xml_passes_btcpps_checks(path: Path) -> None:
    verify_btcpp(exported(path))


@pytest.mark.parametrize(
    ("xml", "message"),
    [
        ("<tree/>", "called <root>"),
        ('<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence/></BehaviorTree></root>', "1 or more children"),
        ('<root BTCPP_format="4"><BehaviorTree ID="T"><Inverter/></BehaviorTree></root>', "exactly 1 child"),
        ('<root BTCPP_format="4"><BehaviorTree ID="T"><Mystery/></BehaviorTree></root>', "not recognized"),
        ('<root BTCPP_format="4"><BehaviorTree ID="T"><SubTree ID="U"/></BehaviorTree></root>', "no such"),
        ('<root BTCPP_format="4"><BehaviorTree ID="T"><Sleep ms="1"/></BehaviorTree></root>', "[ms]"),
        (
            '<root BTCPP_format="4"><BehaviorTree ID="A"><AlwaysSuccess/></BehaviorTree>'
            '<BehaviorTree ID="B"><AlwaysSuccess/></BehaviorTree></root>',
            "single BehaviorTree",
        ),
    ],
)
def test_the_btcpp_check_refuses_what_btcpp_refuses(xml: str, message: str) -> None:
    with pytest.raises(AssertionError, match=message.replace("[", r"\[").replace("]", r"\]")):
        verify_btcpp(xml)


# -- located errors ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        (
            "trees:\n  wait:\n    wait: {duration: 1}\n",
            "m.yaml:3:3: error: tree 'wait' has the name of a skill",
        ),
        (
            "trees:\n  main:\n    wander: {checkpoints: ['a;b']}\n",
            "m.yaml:4:14: error: input 'checkpoints' of 'wander': ['a;b'] has no BT.CPP port text",
        ),
        (
            "machine:\n  states:\n    a:\n      skill: wait\n      transitions: {success: {to: a, if: 'x; y'}}\n",
            "m.yaml:6:21: error: a condition with ';'",
        ),
        (
            "trees:\n  main:\n    subtree: nowhere\n",
            "m.yaml:4:5: error: unknown tree 'nowhere'",
        ),
        ("trees: [\n", "m.yaml:3:1: error: "),
    ],
    ids=["tree named as a skill", "list input", "condition", "unknown subtree", "bad yaml"],
)
def test_missions_that_cannot_be_exported_say_what_and_where(tmp_path: Path, body: str, expected: str) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text("robot: peoplebot\n" + body, encoding="utf-8")
    with pytest.raises(ExportError) as raised:
        export_mission(mission, load)
    shown = [str(problem) for problem in raised.value.problems]
    assert any(expected in line for line in shown), shown
    assert all(problem.location.file.endswith("m.yaml") for problem in raised.value.problems)


def test_a_loaded_mission_with_problems_is_not_exported(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text("trees:\n  main: {wait: {duration: 1}}\ninclude: missing.yaml\n", encoding="utf-8")
    with pytest.raises(ExportError, match=r"missing\.yaml"):
        export_loaded(load(mission))


@pytest.mark.parametrize(
    ("state", "expected"),
    [
        ('<State name="a" transitions="success to b"><wait/></State>', "4:7: error: transition 'success to b'"),
        ('<State name="a" transitions="success -> b"/>', "4:7: error: a State holds exactly one node, found 0"),
        ('<State name="a" tree="t"><wait/></State>', "4:32: error: State tree='t' holds <SubTree ID=\"t\"/>"),
        ('<State name="a" colour="red"><wait/></State>', "4:7: error: <State> has no port 'colour'"),
        ("<wait/>", '4:7: error: a StateMachine\'s children are <State name="…">, not <wait>'),
    ],
    ids=["transition", "empty state", "tree state", "unknown port", "not a state"],
)
def test_bad_machines_in_xml_are_located(state: str, expected: str) -> None:
    xml = (
        '<root BTCPP_format="4">\n  <BehaviorTree ID="T">\n    <StateMachine>\n'
        f"      {state}\n    </StateMachine>\n  </BehaviorTree>\n</root>"
    )
    loaded = loads_xml(xml, "tree.xml")
    shown = [str(problem) for problem in loaded.problems]
    assert loaded.data is None
    assert any(line.startswith("tree.xml:" + expected) for line in shown), shown


def test_a_marked_node_must_match_its_tag() -> None:
    xml = '<root BTCPP_format="4">\n<BehaviorTree ID="T">\n  <Inverter _botstage="retry"><wait/></Inverter>'
    loaded = loads_xml(xml + "\n</BehaviorTree></root>", "tree.xml")
    assert [str(p) for p in loaded.problems] == ['tree.xml:3:3: error: _botstage="retry" does not go with <Inverter>']
