"""missions/examples/face_tracker.yaml over the emulated AX-12A (`--backend emulator`): the skill's pan
commands reach the emulated servo through the real driver (dynamixel-sdk on a pty) and the
simulated camera on its shaft. Its scenarios (missions/scenarios/face_tracker/) run it on the
simulator."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_the_mission_runs_over_the_emulated_servo(tmp_path: Path) -> None:
    """`botstage run missions/examples/face_tracker.yaml --backend emulator`: in real time, a few seconds of
    it; the tracker sweeps for the visitor (no face in its first second) through the driver."""
    out = tmp_path / "run"
    command = [
        sys.executable,
        "-m",
        "botstage.missions.cli",
        "run",
        str(ROOT / "missions" / "examples" / "face_tracker.yaml"),
    ]
    command += ["--backend", "emulator", "--until", "4", "--out", str(out)]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=180, check=False)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "time_limit" and summary["backend"] == "emulator"
    emulator = summary["emulator"]
    assert emulator["board"]["instruction_write"] >= 3  # the limits, the speed, goal positions
    assert emulator["servo"]["errors"] == {} and emulator["board"]["bytes_lost"] == 0
    assert abs(emulator["pan"]["final_angle"]) > 0.05 and emulator["pan"]["held_on_close"]
    events = [json.loads(line) for line in (out / "trace.jsonl").read_text().splitlines()]
    assert any(e["ev"] == "log" and "sweeping" in e.get("message", "") for e in events)
    assert not any(e["ev"] == "skill_outcome" and e.get("outcome") == "failure" for e in events)
