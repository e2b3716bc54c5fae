"""The command line as a user runs it: a real subprocess of the installed console script."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def botstage(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    exe = shutil.which("botstage")
    command = [exe, *args] if exe else [sys.executable, "-c", "from botstage.missions.cli import app; app()", *args]
    return subprocess.run(command, capture_output=True, text=True, cwd=cwd, timeout=300)


def bench(*args: str) -> subprocess.CompletedProcess[str]:
    """A benchmark as a developer runs it from the checkout: `python -m tests.bench NAME`."""
    return subprocess.run(
        [sys.executable, "-m", "tests.bench", *args], capture_output=True, text=True, cwd=ROOT, timeout=300
    )


HELLO = str(ROOT / "missions" / "examples" / "hello.yaml")


def test_run_a_mission_writes_a_run_folder(tmp_path: Path) -> None:
    result = botstage("run", HELLO, "--out", str(tmp_path / "run"))
    assert result.returncode == 0, result.stderr
    assert "hello: outcome done" in result.stdout
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "done"
    assert summary["sim_time_s"] == 32.1
    assert summary["artefacts"] == ["report.html", "trace.jsonl"]
    lines = (tmp_path / "run" / "trace.jsonl").read_text().splitlines()
    assert json.loads(lines[0])["ev"] == "bb_write"


def test_run_twice_gives_the_same_trace(tmp_path: Path) -> None:
    for name in ("a", "b"):
        assert botstage("run", HELLO, "--seed", "7", "--out", str(tmp_path / name)).returncode == 0
    assert (tmp_path / "a" / "trace.jsonl").read_bytes() == (tmp_path / "b" / "trace.jsonl").read_bytes()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("name: x\nmachine: [unclosed\n", "YAML syntax"),
        ("- just\n- a list\n", "a mission is a mapping"),
        (
            "name: x\nmachine: {states: {a: {skill: wait, inputs: {duration: 1}}}}\n",
            "bad.yaml:2:20: error: state 'a' can end with outcome 'success' but has no transition for it",
        ),
        ("name: x\nmachine:\n  states:\n    a: {skill: wiat}\n", "unknown skill 'wiat' (did you mean 'wait'?)"),
        ("name: x\nspeed: 3\ntrees: {t: {wait: {duration: 1}}}\n", "unknown mission key 'speed'"),
    ],
)
def test_bad_missions_give_one_line_errors_and_exit_1(tmp_path: Path, content: str, message: str) -> None:
    mission = tmp_path / "bad.yaml"
    mission.write_text(content)
    result = botstage("run", str(mission), "--out", str(tmp_path / "run"))
    assert result.returncode == 1
    assert message in result.stderr
    assert "Traceback" not in result.stderr + result.stdout


def test_missing_mission_file(tmp_path: Path) -> None:
    result = botstage("run", str(tmp_path / "nope.yaml"))
    assert result.returncode == 1
    assert result.stderr == f"{tmp_path / 'nope.yaml'}:1:1: error: no such file\n"


def test_skills_lists_the_builtin_skills() -> None:
    result = botstage("skills")
    assert result.returncode == 0
    for name in ("wait", "log", "set", "check"):
        assert name in result.stdout


def test_bench_tick_prints_json_lines() -> None:
    result = bench("tick", "--quick")
    assert result.returncode == 0, result.stderr
    rows = [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
    assert [r["bench"] for r in rows][:4] == ["tree_instant", "tree_running", "machine", "simclock_timeouts"]
    assert [r["bench"] for r in rows][4:] == ["nav2_navigate_to_pose"]  # Nav2's tree, XML vs YAML (issue 22)
    assert rows[4].get("skipped") or rows[4]["xml_us_per_tick"] > 0 < rows[4]["yaml_us_per_tick"]
    for row in rows[:3]:
        assert row["ratio"] > 0 and row["target"] == 1.2
    assert rows[0]["nodes"] == 1001
    assert rows[3]["ticks"] == 10_000 and rows[3]["wall_s"] > 0


def test_bench_sim_prints_json() -> None:
    result = bench("sim", "--quick")
    assert result.returncode == 0, result.stderr
    row = json.loads(result.stdout.splitlines()[0])
    assert row["bench"] == "sim_museum" and row["people"] == 20 and row["speedup_vs_realtime"] > 0


def test_bench_nav_prints_json() -> None:
    result = bench("nav", "--quick")
    assert result.returncode == 0, result.stderr
    row = json.loads(result.stdout.splitlines()[0])
    assert row["bench"] == "plan_1000x1000" and row["plans"] == 10 and row["median_ms"] > 0


def test_readme_and_ci_run_the_same_test_command() -> None:
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    marker = "# README test command"
    command = ci.split(marker, 1)[1].strip().splitlines()[0]
    assert command in readme
