"""Each class of mission error, from a deliberately broken file, at its exact file:line:col."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from botstage.missions.check import check


def problems(tmp_path: Path, text: str, name: str = "m.yaml", **others: str) -> list[str]:
    for other, content in others.items():
        (tmp_path / other.replace("__", ".")).write_text(textwrap.dedent(content))
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return [str(p).replace(str(tmp_path) + "/", "") for p in check(path).problems]


VALID_MACHINE = """\
    name: m
    machine:
      states:
        a:
          skill: wait
          inputs: {duration: 1}
          transitions: {success: success, failure: failure}
"""


def test_a_valid_mission_has_no_problems(tmp_path: Path) -> None:
    assert problems(tmp_path, VALID_MACHINE) == []


def test_yaml_syntax(tmp_path: Path) -> None:
    assert problems(tmp_path, "name: m\ntrees:\n  main: {wait: {duration: 1}\n") == [
        "m.yaml:4:1: error: YAML syntax: while parsing a flow mapping, expected ',' or '}', but got '<stream end>'"
    ]


def test_unknown_skill(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        """\
        trees:
          main:
            sequence:
              - wait: {duration: 1}
              - detect_crowed: {}
    """,
    ) == ["m.yaml:5:9: error: unknown node or skill 'detect_crowed' (did you mean 'detect_crowd'?)"]
    assert problems(tmp_path, VALID_MACHINE.replace("skill: wait", "skill: wiat")) == [
        "m.yaml:5:7: error: unknown skill 'wiat' (did you mean 'wait'?)"
    ]


def test_unknown_port(tmp_path: Path) -> None:
    assert problems(tmp_path, "trees:\n  main: {wait: {duration: 1, speed: 2}}\n") == [
        "m.yaml:2:30: error: skill 'wait' has no input 'speed'"
    ]
    assert problems(tmp_path, "trees:\n  main: {check: {condition: 'true'}, outputs: {ok: flag}}\n") == [
        "m.yaml:2:48: error: skill 'check' has no output 'ok'"
    ]


def test_wrong_type(tmp_path: Path) -> None:
    assert problems(tmp_path, "trees:\n  main: {wait: {duration: soon}}\n") == [
        "m.yaml:2:17: error: input 'duration' of 'wait': expected float, got str 'soon' "
        "(Input should be a valid number)"
    ]
    assert problems(tmp_path, "seed: many\ntrees:\n  main: {wait: {duration: 1}}\n") == [
        "m.yaml:1:1: error: seed: input should be a valid integer, unable to parse string as an integer"
    ]


def test_type_mismatch_between_declared_key_and_port(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        """\
        keys: {delay: str}
        blackboard: {delay: "1"}
        trees:
          main: {wait: {duration: "{delay}"}}
    """,
    ) == ["m.yaml:4:17: error: blackboard key 'delay' is declared str but is bound to an input of type float"]


def test_bad_initial_value_for_a_declared_key(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        """\
        keys:
          battery_pct: float
        blackboard:
          battery_pct: full
        trees:
          main: {check: {condition: battery_pct > 20}}
    """,
    ) == [
        "m.yaml:4:3: error: initial value of 'battery_pct' (declared float): expected float, got str 'full' "
        "(Input should be a valid number)"
    ]


def test_unknown_state(tmp_path: Path) -> None:
    text = VALID_MACHINE.replace("  states:", "  initial: b\n      states:")
    assert problems(tmp_path, text) == ["m.yaml:3:3: error: initial state 'b' is not a state"]


def test_transition_to_an_unknown_state(tmp_path: Path) -> None:
    text = VALID_MACHINE.replace("failure: failure}", "failure: retyr}") + (
        "        retry: {skill: wait, inputs: {duration: 1}, transitions: {success: a, failure: failure}}\n"
    )
    assert problems(tmp_path, text) == [
        "m.yaml:7:39: error: transition to unknown state 'retyr' (did you mean 'retry'?)",
        "m.yaml:8:5: error: state 'retry' is unreachable: no transition or preemption leads to it",
    ]


def test_unreachable_state(tmp_path: Path) -> None:
    text = (
        VALID_MACHINE + "        island: {skill: wait, inputs: {duration: 1}, transitions: {success: a, failure: a}}\n"
    )
    assert problems(tmp_path, text) == [
        "m.yaml:8:5: error: state 'island' is unreachable: no transition or preemption leads to it"
    ]
    preempted = text.replace("  states:", "  preemptions: [{when: estop, to: island}]\n      states:")
    assert problems(tmp_path, preempted.replace("name: m", "name: m\n    blackboard: {estop: false}")) == []


def test_outcome_a_state_does_not_handle(tmp_path: Path) -> None:
    assert problems(tmp_path, VALID_MACHINE.replace(", failure: failure", "")) == [
        "m.yaml:4:5: error: state 'a' can end with outcome 'failure' but has no transition for it "
        "(add `failure: <state or outcome>` to its transitions)"
    ]
    timed = VALID_MACHINE.replace("inputs: {duration: 1}", "inputs: {duration: 1}\n          timeout: 5")
    assert problems(tmp_path, timed) == [
        "m.yaml:4:5: error: state 'a' can end with outcome 'timeout' but has no transition for it "
        "(add `timeout: <state or outcome>` to its transitions)"
    ]


def test_key_read_that_nothing_writes(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        """\
        blackboard: {battery_pct: 80}
        trees:
          main:
            sequence:
              - check: {condition: "batery_pct > 20"}
              - think_about: {}
                name: x
    """,
    )[:1] == [
        "m.yaml:5:17: error: blackboard key 'batery_pct' is read here but nothing writes or initialises it "
        "(did you mean 'battery_pct'?)"
    ]
    # written by a node earlier in the mission: fine
    assert (
        problems(
            tmp_path,
            """\
        trees:
          main:
            sequence:
              - set: {key: ready, value: true}
              - while: ready
                child: {wait: {duration: 1}}
    """,
        )
        == []
    )


def test_duplicate_names(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        """\
        trees:
          main: {wait: {duration: 1}}
          main: {wait: {duration: 2}}
    """,
    ) == ["m.yaml:3:3: error: duplicate key 'main' (first defined at line 2)"]
    assert problems(
        tmp_path,
        """\
        trees:
          main:
            sequence:
              - {log: {message: a}, name: hello}
              - {log: {message: b}, name: hello}
    """,
    ) == ["m.yaml:5:29: error: duplicate node name 'hello' (sibling 0 has it too; names identify nodes in traces)"]
    assert problems(
        tmp_path,
        "include: shared.yaml\ntrees:\n  main: {subtree: greet}\n  greet: {log: {message: hi}}\n",
        shared__yaml="trees:\n  greet: {log: {message: hello}}\n",
    ) == ["shared.yaml:2:3: error: duplicate name 'greet' in trees (also defined at m.yaml:4:3)"]


def test_include_cycles(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        "include: a.yaml\ntrees:\n  main: {subtree: shared}\n",
        a__yaml="include: b.yaml\ntrees:\n  shared: {log: {message: hi}}\n",
        b__yaml="include: a.yaml\n",
    ) == ["b.yaml:1:1: error: include cycle: m.yaml -> a.yaml -> b.yaml -> a.yaml"]


def test_missing_files(tmp_path: Path) -> None:
    assert problems(tmp_path, "include: [shared/trees.yaml]\ntrees:\n  main: {log: {message: hi}}\n") == [
        "m.yaml:1:11: error: included file 'shared/trees.yaml' does not exist (looked for shared/trees.yaml)"
    ]
    missing = check(tmp_path / "absent.yaml").problems
    assert [str(p) for p in missing] == [f"{tmp_path / 'absent.yaml'}:1:1: error: no such file"]


def test_includes_bring_shared_subtrees_with_their_own_locations(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        "include: lib.yaml\ntrees:\n  main: {subtree: greet}\n",
        lib__yaml="trees:\n  greet:\n    wait: {duration: never}\n",
    ) == [
        "lib.yaml:3:12: error: input 'duration' of 'wait': expected float, got str 'never' "
        "(Input should be a valid number)"
    ]


def test_unknown_mission_key_and_declared_type(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        """\
        nmae: m
        keys: {goal: "list[flaot]"}
        trees:
          main: {log: {message: hi}}
    """,
    ) == [
        "m.yaml:1:1: error: unknown mission key 'nmae' (did you mean 'name'?)",
        "m.yaml:2:8: error: unknown type 'flaot' in 'list[flaot]' "
        "(known: any, str, int, float, bool, list, dict, none)",
    ]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("", "m.yaml:1:1: error: the file is empty"),
        ("[1, 2]\n", "m.yaml:1:1: error: a mission is a mapping (name:, trees:, machine:, ...)"),
        ("name: m\n---\nname: n\n", "m.yaml:3:1: error: one document per file, found more"),
        (
            "trees:\n  a: {log: {message: x}}\n  b: {log: {message: y}}\n",
            "m.yaml:1:1: error: several trees and no machine: say which tree runs with `root: NAME` (trees: a, b)",
        ),
    ],
)
def test_file_level_problems(tmp_path: Path, text: str, expected: str) -> None:
    assert expected in problems(tmp_path, text)


def test_every_shipped_mission_is_valid() -> None:
    for path in sorted(Path("missions/examples").glob("*.yaml")):
        assert check(path).problems == [], path


def test_gatherings_are_checked_against_the_map_and_the_people(tmp_path: Path) -> None:
    assert problems(
        tmp_path,
        """\
        robot: peoplebot
        world: museum
        start: entrance
        people: 3
        gatherings:
          - {at: lobby, size: 2}
          - {at: [13.5, 10.0], size: 3}
        trees:
          main:
            wait: {duration: 1}
    """,
    ) == [
        "m.yaml:5:1: error: the gatherings need 5 people; `people:` is 3",
        "m.yaml:6:6: error: the map has no place 'lobby'",
    ]


def test_voice_settings_are_checked_before_anything_runs(tmp_path: Path) -> None:
    found = problems(
        tmp_path,
        """\
        robot: peoplebot
        world: museum
        voices: {every: 0, command_weights: {PHOTOS: 2}}
        trees:
          main:
            wait: {duration: 1}
    """,
    )
    assert any(p.startswith("m.yaml:3:") and "voices.every" in p for p in found), found
    assert any(p.startswith("m.yaml:3:") and "no such command PHOTOS" in p for p in found), found


@pytest.mark.parametrize("far", ["1.0e+308", "-400"])
def test_a_walk_leg_that_leaves_the_map_is_located(tmp_path: Path, far: str) -> None:
    """Found by the fuzz test: a point 1e308 m away overflowed the walk's path check. A leg that
    leaves the map is blocked where it leaves it, however far it goes."""
    mission = tmp_path / "walker.yaml"
    mission.write_text(
        textwrap.dedent(
            f"""\
            name: walker
            robot: peoplebot
            world: museum
            walks:
            - path: [[13.0, 7.0], [{far}, 13.0]]
            trees:
              main: {{wait: {{duration: 1}}}}
            """
        ),
        encoding="utf-8",
    )
    problems = [str(problem) for problem in check(mission).problems]
    assert len(problems) == 1 and problems[0].startswith(f"{mission}:5:")
    assert "a person cannot walk through" in problems[0]
