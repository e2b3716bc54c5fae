"""`botstage up`: the entertainer as the paper's five processes on loopback, against one process.

With the same seed, the distributed run (lockstep, every process a real process talking over
Zenoh in ROS 2's wire format) must leave the one-process run's trace byte for byte, and so the
same summary counters and sequence of states.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from botstage.missions.runner import run

ROOT = Path(__file__).resolve().parent.parent
DEPLOYMENT = ROOT / "missions" / "deployments" / "peoplebot_five_computers.yaml"
SEED, UNTIL = 3, 240.0  # long enough for a crowd, a photo and its upload with this seed


def states(trace: Path) -> list[str]:
    events = [json.loads(line) for line in trace.read_text(encoding="utf-8").splitlines()]
    return [f"{e['machine']}:{e['dest']}" for e in events if e["ev"] == "transition"]


def test_five_processes_leave_the_one_process_trace(tmp_path: Path) -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "botstage.missions.cli",
            "up",
            str(DEPLOYMENT),
            "--seed",
            str(SEED),
            "--until",
            str(UNTIL),
            "--out",
            str(tmp_path / "five"),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    for process in ("navigation_computer", "robot_computer", "kinect_speech_computer", "upload_computer"):
        assert f"{process} " in done.stdout  # each one's log and state are shown, by name
    run(ROOT / "missions" / "examples" / "peoplebot_entertainer.yaml", seed=SEED, until=UNTIL, out=tmp_path / "one")
    five, one = (json.loads((tmp_path / r / "summary.json").read_text()) for r in ("five", "one"))
    assert five["counters"] == one["counters"]
    assert 0 < five["lockstep"]["steps"] < five["lockstep"]["skipped"]  # resting processes were not asked
    assert one["counters"]["photos_taken"] >= 1 and one["counters"]["photos_uploaded"] >= 1
    entered = states(tmp_path / "one" / "trace.jsonl")
    assert len(entered) > 3 and states(tmp_path / "five" / "trace.jsonl") == entered
    assert (tmp_path / "five" / "trace.jsonl").read_bytes() == (tmp_path / "one" / "trace.jsonl").read_bytes()
