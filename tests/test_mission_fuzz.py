"""Mutated missions end in a valid load or located errors, never a traceback (2,000 + 300 cases)."""

from __future__ import annotations

import copy
import tempfile
from pathlib import Path
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from botstage.missions.check import INTERNAL, check
from botstage.missions.loader import LIBRARY_DIR

MISSIONS = [Path("missions/examples/hello.yaml").read_text(encoding="utf-8")] + [
    p.read_text(encoding="utf-8") for p in sorted(Path("missions/examples").glob("*.yaml")) if p.name != "hello.yaml"
]


def located_in_mutant_or_library(file: str) -> bool:
    """A mutant's problems are in it, or in a file it includes from the built-in library (which a
    mission includes by name from any folder, as the shipped missions do)."""
    return file.endswith("mutant.yaml") or Path(file).resolve().parent == LIBRARY_DIR


REPLACEMENTS: list[Any] = [
    None,
    0,
    -1,
    3.5,
    True,
    "",
    "x",
    "wait",
    "{missing}",
    [],
    [1, "a"],
    {},
    {"a": None},
    {"sequence": []},
    "estop and",
    "success",
    1e308,
    float("nan"),
    float("-inf"),
    -1e308,
    "1e5",
    "電池",
    "電池 > 20 and not 停止",
    {"電池": 80},
    "x * 1000000000",
    "not " * 60 + "x",
]


def paths(data: Any, prefix: tuple = ()) -> list[tuple]:
    found = [prefix]
    if isinstance(data, dict):
        for key, value in data.items():
            found += paths(value, prefix + (key,))
    elif isinstance(data, list):
        for index, value in enumerate(data):
            found += paths(value, prefix + (index,))
    return found


def parent_and_key(data: Any, path: tuple) -> tuple[Any, Any]:
    for step in path[:-1]:
        data = data[step]
    return data, path[-1]


@st.composite
def mutated(draw: st.DrawFn) -> str:
    text = draw(st.sampled_from(MISSIONS))
    how = draw(st.sampled_from(["delete", "replace", "rename", "truncate", "duplicate", "several"]))
    if how == "truncate":
        return text[: draw(st.integers(0, len(text)))]
    data = yaml.safe_load(text)
    for _ in range(draw(st.integers(2, 5)) if how == "several" else 1):
        candidates = [p for p in paths(data) if p]
        if not candidates:
            break
        path = draw(st.sampled_from(candidates))
        parent, key = parent_and_key(data, path)
        kind = how if how != "several" else draw(st.sampled_from(["delete", "replace", "rename", "duplicate"]))
        if kind == "delete":
            del parent[key]
        elif kind == "replace":
            parent[key] = copy.deepcopy(draw(st.sampled_from(REPLACEMENTS)))
        elif kind == "rename" and isinstance(parent, dict):
            new = draw(st.sampled_from(["tres", "machnie", "states2", "inputs", "skill", "name", "wiat", "to", "if"]))
            parent[new] = parent.pop(key)
        elif kind == "duplicate" and isinstance(parent, list):
            parent.append(copy.deepcopy(parent[key]))
    return yaml.safe_dump(data, sort_keys=False)


@settings(max_examples=800, deadline=None, suppress_health_check=[HealthCheck.too_slow])  # CI's budget
@given(mutated())
def test_mutated_missions_load_or_fail_with_located_errors(text: str) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "mutant.yaml"
        path.write_text(text, encoding="utf-8")
        checked = check(path)  # must not raise
        if checked.ok:
            assert checked.mission is not None
        for problem in checked.problems:
            assert located_in_mutant_or_library(problem.location.file), problem
            assert problem.location.line >= 1 and problem.location.col >= 1
            assert str(problem).startswith(f"{problem.location.file}:{problem.location.line}:")
            assert problem.message
            assert not problem.message.startswith(INTERNAL), problem.message


TOKENS = [
    "&a ",
    "*a",
    "<<: *a",
    "!!int ",
    "!!float ",
    "!!binary ",
    "!!timestamp ",
    "!!set ",
    "!foo ",
    "? ",
    ": ",
    "- ",
    "[",
    "]",
    "{",
    "}",
    "\t",
    "\n",
    "'",
    '"',
    "%YAML 1.1\n",
    "---\n",
    "...\n",
    "#",
    "|",
    ">",
    "\\",
    "\x00",
    "\x85",
    "\ufeff",
    "電池",
    "=",
    "~",
    ".nan",
    "1e999",
    "0x",
    "9" * 5000,
    "!!python/object:os.system ",
]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(MISSIONS), st.lists(st.tuples(st.floats(0, 1), st.sampled_from(TOKENS)), min_size=1, max_size=6))
def test_missions_with_yaml_tokens_inserted_fail_with_located_errors(text: str, edits: list[tuple[float, str]]) -> None:
    """Below the data: the YAML itself broken (tabs, NULs, tags, anchors, a huge integer)."""
    for where, token in edits:
        at = int(where * len(text))
        text = text[:at] + token + text[at:]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "mutant.yaml"
        path.write_text(text, encoding="utf-8")
        for problem in check(path).problems:
            assert located_in_mutant_or_library(problem.location.file), problem
            assert problem.location.line >= 1 and problem.location.col >= 1
            assert not problem.message.startswith(INTERNAL), problem.message
