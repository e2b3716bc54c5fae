"""Hostile mission files end in located errors, within bounded memory, never an internal error.

Each family of robots/limits.py: alias bombs of several shapes, files that are not regular or
too large, includes outside the allowed folders, nesting too deep (YAML, subtrees, machines),
conditions too long, deep or large, repetition at evaluation, non-finite and out-of-range
numbers in every kind of field, numbers in scientific notation, non-ASCII names and keys.
The dangerous ones run in a child process whose address space is capped at 1.5 GB.
"""

from __future__ import annotations

import json
import os
import re
import resource
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from botstage.missions.check import INTERNAL, check
from botstage.missions.loader import load
from botstage.robots import limits
from botstage.robots.located_yaml import load_document
from botstage.skills.expression import EvaluationError, ExpressionError, compile_expression

MEMORY_CAP = 1536 * 1024 * 1024
WAIT = "trees:\n  main: {wait: {duration: 1}}\n"


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def messages(path: Path, **options: object) -> list[str]:
    found = check(path, **options).problems  # type: ignore[arg-type]
    assert all(not p.message.startswith(INTERNAL) for p in found), found
    return [str(p).replace(str(path.parent) + "/", "") for p in found]


# -- memory and time bombs, in a child process with a capped address space -----------------

CHILD = """
import json, sys
from botstage.missions.check import check
print(json.dumps({f: [[p.location.file, p.location.line, p.location.col, p.message] for p in check(f).problems]
                  for f in sys.argv[1:]}))
"""


def _cap_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))


def checked_in_child(paths: list[Path]) -> dict[str, list[list]]:
    done = subprocess.run(
        [sys.executable, "-c", CHILD, *map(str, paths)],
        capture_output=True,
        text=True,
        timeout=900,  # a safety net against a hang, not a measurement
        preexec_fn=_cap_memory,
        cwd=Path(__file__).parents[1],
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout)


def laughs(levels: int, width: int) -> str:
    """The classic "billion laughs": each level a list of ``width`` aliases of the one before."""
    lines = ["a0: &a0 [" + ", ".join(["lol"] * width) + "]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * width) + "]" for i in range(1, levels)]
    return "\n".join(lines) + "\n" + WAIT


def mapping_laughs(levels: int) -> str:
    lines = ["m0: &m0 {a: lol, b: lol, c: lol, d: lol, e: lol, f: lol, g: lol, h: lol}"]
    keys = "abcdefgh"
    lines += [f"m{i}: &m{i} {{" + ", ".join(f"{k}: *m{i - 1}" for k in keys) + "}" for i in range(1, levels)]
    return "\n".join(lines) + "\n" + WAIT


def merge_laughs(levels: int) -> str:
    """Merge keys copy the merged mapping's entries: ten merges of ten merges of ... ."""
    lines = ["m0: &m0 {" + ", ".join(f"k{i}: {i}" for i in range(10)) + "}"]
    lines += [f"m{i}: &m{i} {{<<: [" + ", ".join([f"*m{i - 1}"] * 10) + "]}" for i in range(1, levels)]
    return "\n".join(lines) + "\n" + WAIT


def alias_chain(length: int) -> str:
    """Each anchor one list around the one before: shallow as written, deep once expanded."""
    lines = ["c0: &c0 [x]"] + [f"c{i}: &c{i} [*c{i - 1}]" for i in range(1, length)]
    return "\n".join(lines) + "\n" + WAIT


def test_bombs_end_in_located_errors_within_bounded_memory(tmp_path: Path) -> None:
    cases = {
        "laughs.yaml": (laughs(9, 9), "YAML aliases expand to more than"),
        "wide_laughs.yaml": (laughs(4, 200), "YAML aliases expand to more than"),
        "mapping_laughs.yaml": (mapping_laughs(12), "YAML aliases expand to more than"),
        "merge_laughs.yaml": (merge_laughs(12), "YAML aliases expand to more than"),
        "key_laughs.yaml": (laughs(9, 9) + "blackboard: {? *a8 : 1}\n", "YAML aliases expand to more than"),
        "alias_chain.yaml": (alias_chain(300), f"nested more than {limits.MAX_NESTING} levels deep"),
        "deep_flow.yaml": ("trees:\n  main: " + "[" * 10_000 + "]" * 10_000 + "\n", "nested more than"),
        "deep_map.yaml": ("trees:\n  main: " + "{a: " * 10_000 + "1" + "}" * 10_000 + "\n", "nested more than"),
        "deep_block.yaml": ("x:\n" + "".join("  " * depth + "- \n" for depth in range(1, 400)), "nested more than"),
        "many_values.yaml": ("x: [" + "1," * 700_000 + "1]\n" + WAIT, "more than 500,000 values"),
    }
    paths = [write(tmp_path, name, text) for name, (text, _) in cases.items()]
    results = checked_in_child(paths)
    for path, (name, (_, expected)) in zip(paths, cases.items(), strict=True):
        found = results[str(path)]
        assert found, name
        assert any(expected in message for *_, message in found), (name, found)
        for file, line, col, message in found:
            assert file.endswith(name) and line >= 1 and col >= 1, (name, found)
            assert not message.startswith(INTERNAL), (name, message)


def test_an_alias_bomb_stops_at_the_alias_that_crosses_the_limit(tmp_path: Path) -> None:
    path = write(tmp_path, "m.yaml", laughs(9, 9))
    (problem,) = check(path).problems
    assert problem.location.line in range(2, 10)  # one of the levels of aliases, not the top of the file
    assert problem.message == f"YAML aliases expand to more than {limits.MAX_ALIAS_VALUES:,} values"


def test_aliases_and_merges_within_the_limits_still_work(tmp_path: Path) -> None:
    text = """\
        trees:
          pause: &pause {wait: {duration: 2}, name: pause}
          main:
            sequence: [*pause, {<<: *pause, name: again}, {<<: *pause, wait: {duration: 3}, name: last}]
    """
    path = write(tmp_path, "m.yaml", textwrap.dedent(text))
    checked = check(path)
    assert checked.problems == []
    assert checked.mission is not None
    assert checked.mission.trees["main"]["sequence"] == [
        {"wait": {"duration": 2}, "name": "pause"},
        {"wait": {"duration": 2}, "name": "again"},
        {"wait": {"duration": 3}, "name": "last"},  # the mapping's own keys win over merged ones
    ]


# -- files ------------------------------------------------------------------------------------


def test_only_regular_files_of_bounded_size_are_read(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    folder = tmp_path / "folder.yaml"
    folder.mkdir()
    large = write(tmp_path, "large.yaml", WAIT + "description: '" + "x" * limits.MAX_FILE_BYTES + "'\n")
    latin = tmp_path / "latin.yaml"
    latin.write_bytes(b"name: caf\xe9\n" + WAIT.encode())
    expected = {
        Path("/dev/zero"): "cannot read the file: it is a character device: only regular files are read",
        fifo: "cannot read the file: it is a named pipe: only regular files are read",
        folder: "cannot read the file: it is a directory: only regular files are read",
        large: f"cannot read the file: the file is larger than {limits.MAX_FILE_BYTES:,} bytes",
        latin: "cannot read the file: not UTF-8 text (byte 10 cannot be decoded)",
    }
    for path, message in expected.items():
        (problem,) = check(path).problems
        assert problem.location.line == 1 and problem.message.startswith(message), problem


def test_includes_of_special_files_inside_the_tree_are_refused_where_they_are(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "pipe.yaml")
    (tmp_path / "sub").mkdir()
    mission = write(tmp_path, "m.yaml", "include: [pipe.yaml, sub]\n" + WAIT)
    assert messages(mission) == [
        "pipe.yaml:1:1: error: cannot read the file: it is a named pipe: only regular files are read",
        "sub:1:1: error: cannot read the file: it is a directory: only regular files are read",
    ]


@pytest.mark.parametrize(
    "entry",
    ["/dev/zero", "/etc/passwd", "../outside/secret.yaml", "../../../../../../../../etc/passwd", "link.yaml"],
)
def test_includes_outside_the_mission_tree_are_refused_without_reading_them(tmp_path: Path, entry: str) -> None:
    write(tmp_path, "outside/secret.yaml", "trees: {SECRET_LINE: {wait: {duration: 1}}}\n")
    (tmp_path / "mission").mkdir()
    (tmp_path / "mission/link.yaml").symlink_to(tmp_path / "outside/secret.yaml")
    mission = write(tmp_path, "mission/m.yaml", f"include: {entry}\n" + WAIT)
    found = messages(mission)
    assert found == [
        f"m.yaml:1:1: error: include {entry!r} is outside the folders a mission may include from "
        f"(allowed: {tmp_path / 'mission'}, the built-in library and folders named by --include-dir "
        f"or {limits.INCLUDE_PATH_ENV})"
    ]
    assert "SECRET" not in "".join(found)


def test_include_folders_given_by_the_caller_or_the_environment(tmp_path: Path, monkeypatch) -> None:
    write(tmp_path, "shared/common.yaml", "trees: {greet: {log: {message: hi}}}\n")
    mission = write(tmp_path, "mission/m.yaml", "include: ../shared/common.yaml\n" + WAIT)
    assert "outside the folders" in messages(mission)[0]
    assert messages(mission, include_dirs=[tmp_path / "shared"]) == []
    monkeypatch.setenv(limits.INCLUDE_PATH_ENV, os.pathsep.join(["/nonexistent", str(tmp_path / "shared")]))
    assert messages(mission) == []
    # a name not beside the mission is looked up in those folders
    write(tmp_path, "mission/by_name.yaml", "include: common.yaml\ntrees:\n  main: {subtree: greet}\n")
    assert messages(tmp_path / "mission/by_name.yaml") == []


def test_the_builtin_library_is_always_allowed_and_searched(tmp_path: Path) -> None:
    loaded = load(write(tmp_path, "m.yaml", "include: greetings.yaml\n" + WAIT))
    assert loaded.problems == []
    assert loaded.data is not None and loaded.data["trees"].keys() > {"main"}
    assert Path("missions/lib/greetings.yaml").resolve() in [p.resolve() for p in loaded.files]


def test_symlinks_inside_the_tree_are_followed(tmp_path: Path) -> None:
    write(tmp_path, "lib/real.yaml", "trees: {greet: {log: {message: hi}}}\n")
    (tmp_path / "alias.yaml").symlink_to(tmp_path / "lib/real.yaml")
    assert messages(write(tmp_path, "m.yaml", "include: alias.yaml\n" + WAIT)) == []


def test_the_number_of_included_files_is_bounded(tmp_path: Path) -> None:
    count = limits.MAX_INCLUDED_FILES + 5
    for index in range(count):
        write(tmp_path, f"parts/p{index}.yaml", f"trees: {{t{index}: {{wait: {{duration: 1}}}}}}\n")
    entries = ", ".join(f"parts/p{index}.yaml" for index in range(count))
    (found,) = messages(write(tmp_path, "m.yaml", f"include: [{entries}]\n" + WAIT))
    assert found.startswith("m.yaml:1:")
    assert found.endswith(f"error: more than {limits.MAX_INCLUDED_FILES} included files")


# -- nesting of trees and machines -------------------------------------------------------------


def test_subtree_and_machine_chains_deeper_than_the_limit_are_located(tmp_path: Path) -> None:
    trees = ["trees:", "  main: {subtree: t0}"]
    trees += [f"  t{i}: {{subtree: t{i + 1}}}" for i in range(2_000)] + ["  t2000: {wait: {duration: 1}}"]
    found = messages(write(tmp_path, "trees.yaml", "\n".join(trees) + "\n"))
    assert found and all(f"nested more than {limits.MAX_NODE_DEPTH} levels deep" in m for m in found)
    assert len(found) < 2_000 // limits.MAX_NODE_DEPTH + 2  # once per chain of the limit, not once per link
    states = "transitions: {success: success, failure: failure}"
    machines = ["machine: {states: {a: {machine: m0, " + states + "}}}", "machines:"]
    machines += [f"  m{i}: {{states: {{a: {{machine: m{i + 1}, {states}}}}}}}" for i in range(1_000)]
    machines += [f"  m1000: {{states: {{a: {{skill: wait, inputs: {{duration: 1}}, {states}}}}}}}"]
    found = messages(write(tmp_path, "machines.yaml", "\n".join(machines) + "\n"))
    assert found and all("nested more than" in m for m in found)


def test_nesting_just_within_the_limits_checks_and_builds(tmp_path: Path) -> None:
    spec = "{wait: {duration: 1}}"
    for _ in range(limits.MAX_NESTING // 2 - 5):
        spec = "{inverter: " + spec + "}"
    assert messages(write(tmp_path, "m.yaml", "trees:\n  main: " + spec + "\n")) == []


# -- conditions --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("condition", "message"),
    [
        ("not " * 2_500 + "x", f"a condition has at most {limits.MAX_CONDITION_CHARS:,} characters"),
        ("-" * 9_999 + "1", f"a condition has at most {limits.MAX_CONDITION_CHARS:,} characters"),
        ("-" * 1_500 + "1", f"nested more than {limits.MAX_CONDITION_DEPTH} levels deep"),
        ("not " * 400 + "x", f"nested more than {limits.MAX_CONDITION_DEPTH} levels deep"),
        ("(" * 300 + "x" + ")" * 300, "syntax error"),
        ("x" + " + x" * 60, f"nested more than {limits.MAX_CONDITION_DEPTH} levels deep"),
        ("max(" + ", ".join(["x"] * 600) + ")", f"more than {limits.MAX_CONDITION_NODES} names"),
    ],
)
def test_conditions_too_long_deep_or_large_are_located(tmp_path: Path, condition: str, message: str) -> None:
    with pytest.raises(ExpressionError, match=re.escape(message)):
        compile_expression(condition)
    mission = write(tmp_path, "m.yaml", f'blackboard: {{x: 1}}\ntrees:\n  main: {{condition: "{condition}"}}\n')
    (found,) = messages(mission)
    assert found.startswith("m.yaml:3:10: error: ") and message in found


@pytest.mark.parametrize(
    ("condition", "values"),
    [
        ("len(x * 1000000000) > 0", {"x": "ab"}),
        ("len(1000000000 * x) > 0", {"x": [1, 2]}),
        ("len((x * 60000) + (x * 60000)) > 0", {"x": "a"}),
        ("((y * y) * (y * y)) * ((y * y) * (y * y)) > 0", {"y": 10**300}),
        ("round(y, -1000000000) == 0", {"y": 5}),
        ("len('%0999999999d' % y) > 0", {"y": 1}),
    ],
)
def test_evaluation_refuses_to_build_huge_values(condition: str, values: dict) -> None:
    expression = compile_expression(condition)
    with pytest.raises(EvaluationError, match=re.escape(repr(condition))):
        expression.evaluate(values.__getitem__)


def test_repetition_within_the_limit_evaluates() -> None:
    assert compile_expression("len(x * 1000) == 2000").evaluate({"x": "ab"}.__getitem__)
    assert compile_expression("y * y > 0").evaluate({"y": 10**300}.__getitem__)


# -- numbers -------------------------------------------------------------------------------------

STATE = "machine:\n  states:\n    a:\n      skill: wait\n      inputs: {duration: 1}\n      timeout: %s\n"
STATE += "      transitions: {success: success, failure: failure, timeout: failure}\n"
SECONDS = "10000000"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("until: .nan\n" + WAIT, "m.yaml:1:1: error: until: input should be a finite number"),
        ("until: .inf\n" + WAIT, "m.yaml:1:1: error: until: input should be a finite number"),
        ("until: -5\n" + WAIT, "m.yaml:1:1: error: until: input should be greater than 0"),
        ("until: 1e308\n" + WAIT, f"m.yaml:1:1: error: until: input should be less than or equal to {SECONDS}"),
        ("rate_hz: .nan\n" + WAIT, "m.yaml:1:1: error: rate_hz: input should be a finite number"),
        (
            "trees:\n  main: {wait: {duration: .nan}}\n",
            "m.yaml:2:17: error: input 'duration' of 'wait': input should be a finite number",
        ),
        (
            "trees:\n  main: {wait: {duration: -1}}\n",
            "m.yaml:2:17: error: input 'duration' of 'wait': input should be greater than or equal to 0",
        ),
        (
            "trees:\n  main: {wait: {duration: 1.0e308}}\n",
            f"m.yaml:2:17: error: input 'duration' of 'wait': input should be less than or equal to {SECONDS}",
        ),
        (
            "trees:\n  main: {approach: {target: [1, .inf]}}\n",
            "m.yaml:2:21: error: input 'target' of 'approach': 1: input should be a finite number",
        ),
        (
            "skill_params: {navigate: {patience: .inf}}\n" + WAIT,
            "m.yaml:1:27: error: parameter of 'navigate': Input should be a finite number",
        ),
        (
            "trees:\n  main: {wander: {}, params: {patience: .inf}}\n",
            "m.yaml:2:31: error: parameter of 'wander': Input should be a finite number",
        ),
        (
            "trees:\n  main: {timeout: .nan, child: {wait: {duration: 1}}}\n",
            "m.yaml:2:10: error: timeout: input should be a finite number "
            f"(timeout takes a positive number of seconds, at most {int(limits.MAX_SECONDS):,})",
        ),
        (
            "trees:\n  main: {delay: -1, child: {wait: {duration: 1}}}\n",
            "m.yaml:2:10: error: delay: input should be greater than or equal to 0 "
            f"(delay takes a number of seconds from 0 to {int(limits.MAX_SECONDS):,})",
        ),
        (
            "trees:\n  main: {retry: 0, child: {wait: {duration: 1}}}\n",
            "m.yaml:2:10: error: retry: input should be greater than or equal to 1 "
            f"(retry takes a whole number of times from 1 to {limits.MAX_TIMES:,})",
        ),
        (STATE % ".nan", "m.yaml:6:7: error: timeout: input should be a finite number (a positive number of seconds)"),
        (STATE % ".inf", "m.yaml:6:7: error: timeout: input should be a finite number (a positive number of seconds)"),
        (STATE % "-2", "m.yaml:6:7: error: timeout: input should be greater than 0 (a positive number of seconds)"),
        (
            STATE % "1e9",
            f"m.yaml:6:7: error: timeout: input should be less than or equal to {SECONDS} "
            "(a positive number of seconds)",
        ),
    ],
)
def test_non_finite_negative_and_huge_numbers_are_refused_where_written(
    tmp_path: Path, text: str, expected: str
) -> None:
    assert expected in messages(write(tmp_path, "m.yaml", text))


def test_numbers_of_the_simulation_settings(tmp_path: Path) -> None:
    text = (
        "robot: peoplebot\nworld: museum\npeople: 2\n"
        "gatherings: [{at: entrance, size: 2, time: .inf}]\n"
        "voices: {every: .nan, pause: -1, command_weights: {PHOTO: .inf}}\n" + WAIT
    )
    found = messages(write(tmp_path, "m.yaml", text))
    assert "m.yaml:4:38: error: gatherings.0.time: input should be a finite number" in found
    assert "m.yaml:5:10: error: voices.every: input should be a finite number" in found
    assert "m.yaml:5:23: error: voices.pause: input should be greater than or equal to 0" in found
    assert "m.yaml:5:52: error: voices.command_weights.PHOTO: input should be a finite number" in found


def test_robot_profiles_refuse_non_finite_numbers(tmp_path: Path) -> None:
    profile = Path("robots/profiles/peoplebot.yaml").read_text(encoding="utf-8")
    assert "mass: " in profile
    lines = [
        line.split("mass:")[0] + "mass: .nan" if line.strip().startswith("mass:") else line
        for line in profile.splitlines()
    ]
    write(tmp_path, "bot.yaml", "\n".join(lines).replace("name: peoplebot", "name: bot") + "\n")
    found = messages(write(tmp_path, "m.yaml", "robot: bot.yaml\n" + WAIT))
    assert any(m.startswith("bot.yaml:") and "base.mass: Input should be a finite number" in m for m in found), found


@pytest.mark.parametrize(("written", "value"), [("1e5", 1e5), ("1.0e308", 1e308), ("2E-3", 2e-3), ("-1e-2", -0.01)])
def test_scientific_notation_without_a_signed_exponent_is_a_float(tmp_path: Path, written: str, value: float) -> None:
    loaded = load_document(write(tmp_path, "any.yaml", f"x: {written}\nlist: [{written}]\n"))
    assert loaded.problems == []
    assert loaded.data == {"x": value, "list": [value]}
    assert isinstance(loaded.data["x"], float)


def test_scientific_notation_in_missions_and_strings_that_only_look_like_numbers(tmp_path: Path) -> None:
    mission = write(
        tmp_path, "m.yaml", "until: 1e3\ntrees:\n  main: {wait: {duration: 2E-1}}\nblackboard: {a: 1e, b: e5}\n"
    )
    checked = check(mission)
    assert checked.ok and checked.mission is not None and checked.mission.until == 1000.0
    assert checked.mission.blackboard == {"a": "1e", "b": "e5"}


# -- non-ASCII -----------------------------------------------------------------------------------


def test_mission_names_and_keys_in_any_script(tmp_path: Path) -> None:
    text = "name: 電池テスト\nblackboard: {電池: 80}\ntrees:\n  main:\n    sequence:\n"
    text += "      - condition: 電池 > 20\n      - set: {key: 電池, value: 10}\n      - condition: 電池 == 10\n"
    checked = check(write(tmp_path, "m.yaml", text))
    assert checked.problems == []
    assert checked.mission is not None and checked.mission.name == "電池テスト"
    assert "電池" in checked.keys_used


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("a/b", "a mission name uses letters (of any script), digits"),
        ("two words", "a mission name uses letters (of any script), digits"),
        ("電" * 70, f"a mission name has at most {limits.MAX_NAME_BYTES} bytes in UTF-8"),
    ],
)
def test_mission_names_that_cannot_name_a_folder_are_refused(tmp_path: Path, name: str, message: str) -> None:
    (found,) = messages(write(tmp_path, "m.yaml", f"name: '{name}'\n" + WAIT))
    assert found.startswith("m.yaml:1:1: error: name: " + message)


def test_keys_that_are_not_identifiers_are_located_errors(tmp_path: Path) -> None:
    text = "blackboard: {電 池: 1}\ntrees:\n  main: {set: {key: '電-池', value: 1}}\n"
    found = messages(write(tmp_path, "m.yaml", text))
    assert any(m.startswith("m.yaml:1:14: error: invalid blackboard key '電 池'") for m in found), found
    assert any(m.startswith("m.yaml:3:") and "invalid blackboard key '電-池'" in m for m in found), found
