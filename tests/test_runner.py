"""Running missions: the run folder, determinism, clean stops."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest

from botstage.missions.runner import WALL_CLOCK_FIELDS, MissionInvalid, RunError, run
from tests.test_cli import botstage

SUMMARY_FIELDS = {
    "mission",
    "robot",
    "backend",
    "seed",
    "outcome",
    "reason",
    "sim_time_s",
    "wall_time_s",
    "ticks",
    "states_visited",
    "skill_outcomes",
    "counters",
    "artefacts",
}


def test_hello_twice_with_seed_7_gives_identical_trace_and_summary(tmp_path: Path) -> None:
    for name in ("a", "b"):
        result = botstage("run", "missions/examples/hello.yaml", "--seed", "7", "--out", str(tmp_path / name))
        assert result.returncode == 0, result.stderr
    a, b = tmp_path / "a", tmp_path / "b"
    assert (a / "trace.jsonl").read_bytes() == (b / "trace.jsonl").read_bytes()
    summaries = [json.loads((folder / "summary.json").read_text()) for folder in (a, b)]
    for summary in summaries:
        for field in WALL_CLOCK_FIELDS:
            summary.pop(field, None)
    assert summaries[0] == summaries[1]


def test_summary_has_every_field(tmp_path: Path) -> None:
    summary = run("missions/examples/hello.yaml", out=tmp_path).summary
    assert set(summary) >= SUMMARY_FIELDS
    assert summary["states_visited"][:3] == ["greeting", "working/patrol", "working/rest"]
    assert summary["states_visited"][-1] == "done"
    assert summary["skill_outcomes"]["log"] == {"success": 1}
    assert summary["skill_outcomes"]["wait"]["cancelled"] == 1
    assert summary["artefacts"] == ["report.html", "trace.jsonl"]
    assert json.loads((tmp_path / "summary.json").read_text()) == summary


def test_counters_report_blackboard_values(tmp_path: Path) -> None:
    summary = run("missions/examples/tree_demo.yaml", out=tmp_path).summary
    assert summary["outcome"] == "success"
    assert summary["counters"] == {"first_greeted": True, "second_greeted": True}
    assert summary["states_visited"] == []


def test_default_run_folder_is_named_after_the_mission(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mission = Path("missions/examples/hello.yaml").resolve()
    monkeypatch.chdir(tmp_path)
    first = run(mission).folder
    second = run(mission).folder
    assert first.parent == second.parent == Path("runs")
    assert first.name.startswith("hello-") and first != second


@pytest.mark.parametrize("how", ["ctrl-c", "sigterm"])
def test_stopping_a_run_cancels_what_runs(tmp_path: Path, how: str) -> None:
    """The stop arrives while the mission runs; running skills are cancelled with that reason."""

    def progress(snapshot) -> None:
        if snapshot().sim_time_s >= 3.0:
            if how == "ctrl-c":
                raise KeyboardInterrupt
            os.kill(os.getpid(), signal.SIGTERM)

    before = signal.getsignal(signal.SIGTERM)
    result = run("missions/examples/hello.yaml", out=tmp_path, progress=progress, progress_interval_s=0)
    assert result.outcome == "interrupted"
    events = [json.loads(line) for line in (tmp_path / "trace.jsonl").read_text().splitlines()]
    cancels = [e for e in events if e["ev"] == "skill_cancel"]
    assert [c["reason"] for c in cancels] == ["interrupted by the operator"]
    assert cancels[0]["node"] == "hello/working/patrol/patrol/timeout/wait"
    assert (tmp_path / "report.html").exists()
    assert signal.getsignal(signal.SIGTERM) is before  # the run's SIGTERM handler is gone again


def test_until_limits_mission_time(tmp_path: Path) -> None:
    result = run("missions/examples/hello.yaml", out=tmp_path, until=5)
    assert result.outcome == "time_limit"
    assert result.summary["sim_time_s"] == 5.0
    assert result.reason == "the time limit of 5 s of mission time was reached"


def test_invalid_missions_and_backends_are_refused_before_anything_moves(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("trees:\n  main: {wiat: {duration: 1}}\n")
    with pytest.raises(MissionInvalid) as info:
        run(bad, out=tmp_path / "run")
    assert "unknown node or skill 'wiat'" in str(info.value)
    assert not (tmp_path / "run").exists()
    with pytest.raises(RunError, match="names no robot"):
        run("missions/examples/hello.yaml", backend="hardware", out=tmp_path / "hw")
    result = botstage("run", "--backend", "gpu", "--out", str(tmp_path / "x"))
    assert result.returncode == 2
    assert result.stderr.startswith("error: unknown backend 'gpu'; installed: sim (the built-in simulator")
    assert "; emulator (" in result.stderr and "; hardware (" in result.stderr and result.stderr.count("\n") == 1


def test_a_run_with_a_skill_registered_in_code_writes_its_report(tmp_path: Path) -> None:
    """The report's picture is built with the run's registry, not the default one."""
    from botstage.skills.base import Outcome, Skill
    from botstage.skills.registry import Registry

    class Nod(Skill):
        name = "nod"

        def run(self, ctx):
            yield
            return Outcome.success()

    mission = tmp_path / "nod.yaml"
    mission.write_text("name: nod\ntrees:\n  main:\n    sequence: [nod, {wait: {duration: 0.2}}]\n")
    registry = Registry.default()
    registry.register(Nod)
    result = run(mission, registry=registry, out=tmp_path / "run")
    assert result.outcome == "success"
    assert "nod" in (tmp_path / "run" / "report.html").read_text()
