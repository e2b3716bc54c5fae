"""BehaviorTree.CPP v4 XML read as a botstage mission: the spec it gives, its located errors, and a
tree file that runs on the simulator end to end."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from botstage.behaviors.btcpp.xml_format import load_xml, loads_xml
from botstage.missions.check import check
from botstage.missions.cli import app
from botstage.missions.runner import run

NAV2 = Path(__file__).resolve().parents[2] / "shared" / "nav2"


def spec_of(xml: str) -> dict[str, Any]:
    loaded = loads_xml(xml, "tree.xml")
    assert loaded.problems == []
    assert loaded.data is not None
    return loaded.data


def errors_of(xml: str) -> list[str]:
    loaded = loads_xml(xml, "tree.xml")
    assert loaded.data is None
    return [str(p) for p in loaded.problems]


def test_one_tree_needs_no_main_tree_to_execute_and_ports_are_typed() -> None:
    data = spec_of(
        """<root BTCPP_format="4">
  <BehaviorTree ID="Only">
    <RetryUntilSuccessful num_attempts="3" name="again">
      <Sequence>
        <wait duration="0.5"/>
        <Action ID="Sleep" msec="100"/>
      </Sequence>
    </RetryUntilSuccessful>
  </BehaviorTree>
</root>"""
    )
    assert data["root"] == "Only"
    assert data["trees"]["Only"] == {
        "RetryUntilSuccessful": {"Sequence": [{"wait": {"duration": 0.5}}, {"Sleep": {"msec": 100}}]},
        "num_attempts": 3,
        "name": "again",
    }


def test_subtrees_keep_their_keys_private_unless_remapped() -> None:
    data = spec_of(
        """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <SubTree ID="Inner" target="{goal}"/>
      <SubTree ID="Inner" target="{=}"/>
      <SubTree ID="Inner" _autoremap="true"/>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="Inner">
    <Sequence>
      <SetBlackboard value="{target}" output_key="scratch"/>
      <SetBlackboard value="1" output_key="{@shared}"/>
    </Sequence>
  </BehaviorTree>
</root>"""
    )
    first, second, third = data["trees"]["Main"]["Sequence"]
    assert first == {"subtree": "Inner", "remap": {"target": "goal", "scratch": "_0_Inner/scratch"}}
    assert second == {"subtree": "Inner", "remap": {"target": "target", "scratch": "_1_Inner/scratch"}}
    assert third == {"subtree": "Inner"}  # autoremap: every key is the caller's; {@shared} is the root's anyway
    assert data["trees"]["Inner"]["Sequence"][1] == {"SetBlackboard": {"value": "1", "output_key": "{shared}"}}


@pytest.mark.parametrize(
    ("xml", "expected"),
    [
        (
            '<root BTCPP_format="4">\n  <BehaviorTree ID="T">\n    <Sequense/>\n  </BehaviorTree>\n</root>',
            "tree.xml:3:5: error: unknown node 'Sequense' (did you mean 'Sequence'?)",
        ),
        (
            '<root BTCPP_format="4">\n  <BehaviorTree ID="T">\n    <SubTree ID="Nope"/>\n  </BehaviorTree>\n</root>',
            "tree.xml:3:5: error: no BehaviorTree 'Nope' for this SubTree",
        ),
        (
            '<root BTCPP_format="4"><BehaviorTree ID="T">\n  <Repeat num_cycles="many"><AlwaysSuccess/></Repeat>'
            "</BehaviorTree></root>",
            "tree.xml:2:23: error: Repeat.num_cycles: expected a whole number, got 'many'",
        ),
        (
            '<root BTCPP_format="3"><BehaviorTree ID="T"><AlwaysSuccess/></BehaviorTree></root>',
            'tree.xml:1:1: error: BTCPP_format="3" is not supported: botstage reads version 4',
        ),
        (
            '<root BTCPP_format="4" main_tree_to_execute="A">\n<BehaviorTree ID="A"><SubTree ID="B"/></BehaviorTree>\n'
            '<BehaviorTree ID="B">\n  <SubTree ID="A"/></BehaviorTree></root>',
            "tree.xml:4:3: error: subtree recursion: A -> B -> A",
        ),
        (
            '<root BTCPP_format="4">\n  <BehaviorTree ID="T"><AlwaysSuccess></BehaviorTree></root>',
            "tree.xml:2:41: error: not well-formed XML: mismatched tag",
        ),
        (
            '<root BTCPP_format="4"><BehaviorTree ID="T">\n <wait duration="soon"/></BehaviorTree></root>',
            "tree.xml:2:2: error: input 'duration' of 'wait': cannot read 'soon' as float",
        ),
    ],
    ids=["unknown node", "unknown subtree", "malformed port", "format 3", "recursion", "not xml", "skill port"],
)
def test_errors_are_located(xml: str, expected: str) -> None:
    assert any(error.startswith(expected) for error in errors_of(xml)), errors_of(xml)


def test_every_unknown_node_is_reported_not_just_the_first() -> None:
    errors = errors_of(
        '<root BTCPP_format="4"><BehaviorTree ID="T">\n<Mystery>\n <Enigma/>\n <AlwaysSuccess/>\n</Mystery>'
        "</BehaviorTree></root>"
    )
    assert [e.split(": error: ")[0] for e in errors] == ["tree.xml:2:1", "tree.xml:3:2"]


def test_a_tree_file_checks_and_runs_on_the_simulator(tmp_path: Path) -> None:
    tree = tmp_path / "count.xml"
    tree.write_text(
        """<root BTCPP_format="4">
  <BehaviorTree ID="Count">
    <Sequence>
      <SetBlackboard value="ready" output_key="phase"/>
      <Timeout msec="2000">
        <Repeat num_cycles="3"><Sleep msec="200"/></Repeat>
      </Timeout>
      <Switch2 variable="{phase}" case_1="ready" case_2="late">
        <wait duration="0.3"/>
        <AlwaysFailure/>
        <AlwaysFailure/>
      </Switch2>
    </Sequence>
  </BehaviorTree>
</root>""",
        encoding="utf-8",
    )
    assert check(tree).problems == []
    result = run(tree, until=10, out=tmp_path / "run")
    assert result.outcome == "success"
    # Sleep 200 ms three times (a tick at 10 Hz starts each), then the 0.3 s wait of case 1
    assert 0.9 <= result.summary["sim_time_s"] <= 1.5


def test_import_writes_the_mission_yaml(tmp_path: Path) -> None:
    tree = tmp_path / "t.xml"
    tree.write_text('<root BTCPP_format="4"><BehaviorTree ID="T"><AlwaysSuccess/></BehaviorTree></root>')
    out = tmp_path / "t.yaml"
    result = CliRunner().invoke(app, ["import", str(tree), "-o", str(out), "--robot", "peoplebot"])
    assert result.exit_code == 0, result.output
    assert yaml.safe_load(out.read_text()) == {
        "name": "t",
        "robot": "peoplebot",
        "nodes": "btcpp",
        "trees": {"T": {"AlwaysSuccess": {}}},
        "root": "T",
    }
    assert check(out).problems == []


@pytest.mark.skipif(not NAV2.is_dir(), reason="../shared/nav2 is not here")
def test_nav2_trees_need_only_the_goal_nav2s_navigator_writes() -> None:
    for path in sorted(NAV2.glob("navigate*.xml")):
        for problem in check(path).problems:  # Nav2's navigator writes `goal` (`goals`): `run --set goal=...`
            assert problem.message.startswith("blackboard key 'goal' is read here but nothing writes"), problem
            assert problem.location.line > 1


# -- scripts, pre/post conditions, includes, keyed ports, SubTree literals, TreeNodesModel ---------


def test_pre_post_attributes_wrap_the_node_and_scripts_are_kept() -> None:
    data = spec_of(
        """<root BTCPP_format="4">
  <BehaviorTree ID="T">
    <Sequence>
      <Script code="count := 0"/>
      <AlwaysSuccess name="tick" _skipIf="count &gt; 2" _onSuccess="count += 1" _uid="7"/>
      <Precondition if="count == 1" else="SKIPPED"><ScriptCondition code="@flag"/></Precondition>
      <UnsetBlackboard key="count"/>
    </Sequence>
  </BehaviorTree>
</root>"""
    )
    assert data["trees"]["T"]["Sequence"] == [
        {"Script": {"code": "count := 0"}},
        {
            "PrePostConditions": {"AlwaysSuccess": {}, "name": "tick"},
            "_skipIf": "count > 2",
            "_onSuccess": "count += 1",
        },
        {"Precondition": {"ScriptCondition": {"code": "@flag"}}, "if_": "count == 1", "else": "SKIPPED"},
        {"UnsetBlackboard": {"key": "count"}},
    ]


def test_script_keys_in_a_subtree_are_private_and_at_keys_are_the_roots() -> None:
    data = spec_of(
        """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main"><SubTree ID="Inner" limit="3"/></BehaviorTree>
  <BehaviorTree ID="Inner">
    <Script code="n := limit + 1; @total := n" _post="seen := true"/>
  </BehaviorTree>
</root>"""
    )
    assert data["trees"]["Main"] == {
        "subtree": "Inner",
        "remap": {"limit": "_0_Inner/limit", "n": "_0_Inner/n", "seen": "_0_Inner/seen"},
    }
    assert data["blackboard"] == {"_0_Inner/limit": "3"}  # BT.CPP sets the literal in the subtree's blackboard


def test_a_subtree_literal_is_read_as_the_type_of_the_port_it_feeds() -> None:
    data = spec_of(
        """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main"><SubTree ID="Inner" pause="0.5" times="2"/></BehaviorTree>
  <BehaviorTree ID="Inner">
    <Repeat num_cycles="{times}"><wait duration="{pause}"/></Repeat>
  </BehaviorTree>
</root>"""
    )
    assert data["blackboard"] == {"_0_Inner/pause": 0.5, "_0_Inner/times": 2}
    assert data["trees"]["Inner"]["num_cycles"] == "{times}"


def test_tree_nodes_model_types_and_defaults_apply_to_the_nodes_it_declares() -> None:
    data = spec_of(
        """<root BTCPP_format="4">
  <BehaviorTree ID="T"><Sequence><wait/><Sleep/></Sequence></BehaviorTree>
  <TreeNodesModel>
    <Action ID="wait"><input_port name="duration" type="double" default="0.25"/></Action>
    <Action ID="Sleep"><input_port name="msec" type="unsigned" default="{nap}"/></Action>
  </TreeNodesModel>
</root>"""
    )
    assert data["trees"]["T"]["Sequence"] == [{"wait": {"duration": 0.25}}, {"Sleep": {"msec": "{nap}"}}]


@pytest.mark.parametrize(
    ("xml", "expected"),
    [
        (
            '<root BTCPP_format="4"><BehaviorTree ID="T">\n  <Script code="x := 1 +"/></BehaviorTree></root>',
            "tree.xml:2:25: error: code: expected a value, found the end of the script",
        ),
        (
            '<root BTCPP_format="4"><BehaviorTree ID="T">\n'
            '  <AlwaysSuccess _failureIf="a === b"/></BehaviorTree></root>',
            "tree.xml:2:34: error: _failureIf: expected a value, found '='",
        ),
        (
            '<root BTCPP_format="4"><BehaviorTree ID="T">\n'
            '  <Parallel success_count="{n}"><AlwaysSuccess/></Parallel></BehaviorTree></root>',
            "tree.xml:2:28: error: Parallel.success_count: BT.CPP's Parallel takes no blackboard reference here",
        ),
        (
            '<root BTCPP_format="4">\n  <include ros_pkg="nav2_bt" path="trees/a.xml"/>\n'
            '  <BehaviorTree ID="T"><AlwaysSuccess/></BehaviorTree></root>',
            "tree.xml:2:3: error: <include ros_pkg=...> looks in a ROS package, which botstage cannot",
        ),
        (
            '<root BTCPP_format="4"><BehaviorTree ID="T">\n  <Script code="a &gt; 1 &amp;&amp; ) "/>'
            "</BehaviorTree></root>",
            "tree.xml:2:37: error: code: expected a value, found ')'",  # &gt; is one character of the script
        ),
    ],
    ids=["script syntax", "condition syntax", "reference on a literal-only port", "ros_pkg", "after entities"],
)
def test_new_errors_are_located(xml: str, expected: str) -> None:
    assert any(error.startswith(expected) for error in errors_of(xml)), errors_of(xml)


def test_include_reads_trees_relative_to_the_including_file(tmp_path: Path) -> None:
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "inner.xml").write_text(
        '<root BTCPP_format="4"><include path="deeper.xml"/>'
        '<BehaviorTree ID="Inner"><SubTree ID="Deeper"/></BehaviorTree></root>'
    )
    (tmp_path / "lib" / "deeper.xml").write_text(
        '<root BTCPP_format="4"><BehaviorTree ID="Deeper"><AlwaysSuccess/></BehaviorTree></root>'
    )
    main = tmp_path / "main.xml"
    main.write_text(
        '<root BTCPP_format="4" main_tree_to_execute="Main"><include path="lib/inner.xml"/>'
        '<BehaviorTree ID="Main"><SubTree ID="Inner"/></BehaviorTree></root>'
    )
    loaded = load_xml(main)
    assert loaded.problems == []
    assert set(loaded.data["trees"]) == {"Main", "Inner", "Deeper"}
    assert loaded.files[1:] == [(tmp_path / "lib" / "inner.xml").resolve(), (tmp_path / "lib" / "deeper.xml").resolve()]


def test_include_cycles_and_missing_files_are_located(tmp_path: Path) -> None:
    (tmp_path / "a.xml").write_text(
        '<root BTCPP_format="4">\n<include path="b.xml"/>\n<BehaviorTree ID="A"><AlwaysSuccess/></BehaviorTree></root>'
    )
    (tmp_path / "b.xml").write_text(
        '<root BTCPP_format="4">\n\n  <include path="a.xml"/>\n  <include path="none.xml"/></root>'
    )
    errors = [str(p) for p in load_xml(tmp_path / "a.xml").problems]
    b = str(tmp_path / "b.xml")
    assert any(e.startswith(f"{b}:3:3: error: include cycle: ") and e.endswith("a.xml") for e in errors), errors
    assert any(e.startswith(f"{b}:4:3: error: included file 'none.xml' not found") for e in errors), errors


def test_scripted_tree_runs_end_to_end(tmp_path: Path) -> None:
    tree = tmp_path / "scripted.xml"
    tree.write_text(
        """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <Script code="laps := 0; label := 'lap'"/>
      <SubTree ID="Lap" pause_ms="100" _autoremap="true"/>
      <ScriptCondition code="laps == 3 &amp;&amp; label == 'lap3'"/>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="Lap">
    <Repeat num_cycles="3">
      <Sleep msec="{pause_ms}" _onSuccess="laps += 1; label = 'lap' .. laps"/>
    </Repeat>
  </BehaviorTree>
</root>""",
        encoding="utf-8",
    )
    assert check(tree).problems == []
    result = run(tree, until=10, out=tmp_path / "run")
    assert result.outcome == "success"


def test_keys_a_script_reads_are_checked_where_the_script_is_written(tmp_path: Path) -> None:
    tree = tmp_path / "ghosts.xml"
    tree.write_text(
        '<root BTCPP_format="4">\n  <BehaviorTree ID="T">\n    <Sequence>\n'
        '      <AlwaysSuccess _skipIf="ghost == 1"/>\n'
        '      <Precondition if="phantom"><AlwaysSuccess/></Precondition>\n'
        '      <Sleep msec="{nap}"/>\n    </Sequence>\n  </BehaviorTree>\n</root>'
    )
    problems = [(p.location.line, p.location.col, p.message.split(" is read")[0]) for p in check(tree).problems]
    assert problems == [
        (4, 31, "blackboard key 'ghost'"),
        (5, 25, "blackboard key 'phantom'"),
        (6, 20, "blackboard key 'nap'"),
    ]
