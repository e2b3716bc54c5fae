"""BehaviorTree.CPP v4 XML read as a botstage mission: the spec it gives, its located errors, and a
tree file that runs on the simulator end to end."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from behaviors.btcpp.to_spec import loads_xml
from missions.check import check
from missions.cli import app
from missions.runner import run

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
            "tree.xml:2:3: error: Repeat.num_cycles: expected a whole number, got 'many'",
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
        "trees": {"T": {"AlwaysSuccess": {}}},
        "root": "T",
    }
    assert check(out).problems == []


@pytest.mark.skipif(not NAV2.is_dir(), reason="../shared/nav2 is not here")
def test_nav2_trees_fail_only_on_nav2s_own_nodes_each_located() -> None:
    for path in sorted(NAV2.glob("navigate*.xml")):
        problems = check(path).problems
        assert problems, path
        for problem in problems:
            assert problem.message.startswith("unknown node "), problem
            assert problem.location.line > 1
