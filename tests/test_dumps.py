"""`botstage tree` and `botstage machine` in every format for every mission."""

from __future__ import annotations

import json
import os
import struct
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import pytest

from botstage.behaviors.render import FORMATS
from tests.test_cli import botstage
from tests.tools import require

MISSIONS = sorted(Path("missions/examples").glob("*.yaml"))


def parse_png(data: bytes) -> tuple[int, int]:
    """Walk every chunk, checking each CRC; returns the image size."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    position, size, seen_end = 8, None, False
    while position < len(data):
        (length,) = struct.unpack(">I", data[position : position + 4])
        kind = data[position + 4 : position + 8]
        body = data[position + 8 : position + 8 + length]
        (crc,) = struct.unpack(">I", data[position + 8 + length : position + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"bad CRC in {kind!r}"
        if kind == b"IHDR":
            size = struct.unpack(">II", body[:8])
        seen_end = kind == b"IEND"
        position += 12 + length
    assert seen_end and size is not None
    return size


def check_output(fmt: str, data: bytes) -> None:
    assert data
    if fmt == "svg":
        root = ET.fromstring(data)
        assert root.tag == "{http://www.w3.org/2000/svg}svg"
        assert len(list(root.iter())) > 10
    elif fmt == "png":
        width, height = parse_png(data)
        assert width > 50 and height > 50
    elif fmt == "json":
        assert json.loads(data)["children"]
    elif fmt == "mermaid":
        assert data.startswith(b"flowchart TD\n") and b"-->" in data
    elif fmt == "dot":
        assert data.startswith(b"digraph botstage {") and data.rstrip().endswith(b"}")
    else:
        assert len(data.decode().splitlines()) >= 3  # the root and its children


@pytest.mark.parametrize("mission", MISSIONS, ids=lambda p: p.stem)
@pytest.mark.parametrize("fmt", FORMATS)
def test_tree_in_every_format(tmp_path: Path, mission: Path, fmt: str) -> None:
    if fmt in ("svg", "png"):
        require("dot", "graphviz")
    out = tmp_path / f"picture.{fmt}"
    result = botstage("tree", str(mission), "--format", fmt, "-o", str(out))
    assert result.returncode == 0, result.stderr
    check_output(fmt, out.read_bytes())


@pytest.mark.parametrize("mission", MISSIONS, ids=lambda p: p.stem)
@pytest.mark.parametrize("fmt", FORMATS)
def test_machine_in_every_format(tmp_path: Path, mission: Path, fmt: str) -> None:
    if fmt in ("svg", "png"):
        require("dot", "graphviz")
    out = tmp_path / f"machine.{fmt}"
    result = botstage("machine", str(mission), "--format", fmt, "-o", str(out))
    assert result.returncode == 0, result.stderr
    check_output(fmt, out.read_bytes())


def test_a_machine_with_trees_is_one_picture_of_clusters() -> None:
    dot = botstage("machine", "missions/examples/hello.yaml", "--format", "dot").stdout
    assert dot.count("subgraph cluster_") == 6  # machine, 2 states, nested machine, 2 nested states
    assert 'label="wait\\nduration=2.0"' in dot
    assert 'label="success"' in dot and 'label="preempt: estop"' in dot


def test_machine_of_a_mission_without_one_draws_its_tree() -> None:
    result = botstage("machine", "missions/examples/tree_demo.yaml")
    assert result.returncode == 0
    assert result.stderr == "note: missions/examples/tree_demo.yaml has no machine; drawing the tree it runs\n"
    assert result.stdout.startswith("main: sequence")


def test_getting_started_lists_the_formats_both_verbs_draw() -> None:
    page = (Path(__file__).resolve().parent.parent / "docs" / "getting-started.md").read_text()
    listed = page.split("Formats: ", 1)[1].split(".", 1)[0]
    assert tuple(f.strip() for f in listed.replace("\n", " ").split(",")) == FORMATS


def test_machine_draws_a_machine_that_sits_in_a_tree() -> None:
    """The default mission runs its state chart beside helpers, in a parallel: that chart is drawn."""
    for fmt, start in (("ascii", "machine entertainer"), ("unicode", "machine entertainer")):
        result = botstage("machine", "--format", fmt)
        assert result.returncode == 0 and result.stderr == ""
        assert result.stdout.startswith(start) and "state wandering" in result.stdout
    data = json.loads(botstage("machine", "--format", "json").stdout)
    assert data["kind"] == "machine" and data["path"] == "main/entertainer"
    assert data["preemptions"] == [{"when": "battery_low", "to": "main/entertainer/docking"}]
    assert "main: parallel" not in botstage("machine", "--format", "ascii").stdout


TWO = """name: two
trees:
  main:
    parallel:
      - machine:
          initial: a
          states: {a: {skill: wait, inputs: {duration: 1}, transitions: {success: done, failure: done}}}
          outcomes: [done]
      - sequence:
          - log: {message: "beside"}
          - machine: other
machines:
  other:
    initial: b
    states: {b: {skill: wait, inputs: {duration: 2}, transitions: {success: over, failure: over}}}
    outcomes: [over]
"""


def test_machine_draws_every_machine_a_mission_runs_wherever_it_sits(tmp_path: Path) -> None:
    mission = tmp_path / "two.yaml"
    mission.write_text(TWO)
    text = botstage("machine", str(mission), "--format", "ascii")
    assert text.returncode == 0, text.stderr
    lines = text.stdout.splitlines()
    assert lines[0] == "2 machines of two"
    assert [line for line in lines if "state " in line] == [
        "|   |-- state a  success -> done, failure -> done",
        "    |-- state b  success -> over, failure -> over",
    ]
    assert "beside" not in text.stdout  # the trees around them are not machines
    data = json.loads(botstage("machine", str(mission), "--format", "json").stdout)
    assert [c["kind"] for c in data["children"]] == ["machine", "machine"]
    dot = botstage("machine", str(mission), "--format", "dot").stdout
    assert dot.count("subgraph cluster_") == 4  # two machines, a state each
    mermaid = botstage("machine", str(mission), "--format", "mermaid").stdout
    assert mermaid.count("subgraph") == 4


NAMED_ONLY = """name: named
trees:
  main: {log: {message: "no machine runs"}}
machines:
  other:
    initial: b
    states: {b: {skill: wait, inputs: {duration: 2}, transitions: {success: over, failure: over}}}
    outcomes: [over]
"""


def test_machine_of_a_mission_that_runs_none_draws_the_machines_it_names(tmp_path: Path) -> None:
    mission = tmp_path / "named.yaml"
    mission.write_text(NAMED_ONLY)
    result = botstage("machine", str(mission))
    assert result.returncode == 0, result.stderr
    assert result.stderr == f"note: {mission} runs no machine; drawing the machines it names\n"
    assert result.stdout.startswith("machine other") and "state b  success -> over, failure -> over" in result.stdout


def test_labels_show_bindings_and_decorators() -> None:
    text = botstage("tree", "missions/examples/tree_demo.yaml", "--format", "ascii").stdout
    assert "wait  duration={pause}" in text
    assert 'set  key="first_greeted"  value=true' in text
    assert "patrol: force success" in text and "timeout 5 s" in text and "while battery_pct > 20" in text


def test_trace_colours_nodes_by_status_at_a_tick(tmp_path: Path) -> None:
    assert botstage("run", "missions/examples/hello.yaml", "-q", "--out", str(tmp_path / "run")).returncode == 0
    trace = str(tmp_path / "run" / "trace.jsonl")
    text = botstage("tree", "missions/examples/hello.yaml", "--trace", trace, "--at", "100").stdout
    assert "state working  timeout 30 s  finished → done, timeout → done  [ACTIVE]" in text
    assert "wait  duration=4.0  [RUNNING]" in text
    assert "state greeting" in text and "state greeting  success → working, failure → stopped  [ACTIVE]" not in text
    dot = botstage("tree", "missions/examples/hello.yaml", "--trace", trace, "--at", "100", "--format", "dot").stdout
    assert "#f0ad4e" in dot and "#5cb85c" in dot
    mermaid = botstage(
        "tree", "missions/examples/hello.yaml", "--trace", trace, "--at", "100", "--format", "mermaid"
    ).stdout
    assert "classDef running fill:#f0ad4e" in mermaid


def test_without_graphviz_one_line_and_a_suggestion(tmp_path: Path) -> None:
    empty = tmp_path / "bin"
    empty.mkdir()
    import shutil
    import subprocess
    import sys

    env = {**os.environ, "PATH": str(empty)}
    exe = shutil.which("botstage")
    command = [exe] if exe else [sys.executable, "-c", "from botstage.missions.cli import app; app()"]
    result = subprocess.run(
        [*command, "tree", "--format", "svg", "-o", str(tmp_path / "x.svg")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1
    assert "Graphviz's `dot` is not installed" in result.stderr and "--format mermaid" in result.stderr
    assert "Traceback" not in result.stderr


def test_bad_arguments_are_clear(tmp_path: Path) -> None:
    result = botstage("tree", "--format", "gif")
    assert result.returncode == 2 and "unknown format 'gif'" in result.stderr
    result = botstage("tree", "missions/examples/hello.yaml", "--tree", "nope")
    assert result.returncode == 2 and "has no tree 'nope' (trees: greet, patrol)" in result.stderr
    (tmp_path / "t.jsonl").write_text("not json\n")
    result = botstage("tree", "--trace", str(tmp_path / "t.jsonl"))
    assert result.returncode == 2 and "cannot read trace" in result.stderr
    result = botstage("tree", "--format", "png")
    assert result.returncode == 2 and "png is binary" in result.stderr
