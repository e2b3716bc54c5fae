"""`python -m tests.bench gesture --quick`: every figure is there and sane; timings are never asserted on."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BENCHES = ["gesture_parser", "gesture_sample_latency", "pty_floor", "gesture_converter"]


def test_the_bench_reports_every_figure() -> None:
    command = [sys.executable, "-m", "tests.bench", "gesture", "--quick"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    rows = {
        row["bench"]: row for row in (json.loads(line) for line in done.stdout.splitlines() if line.startswith("{"))
    }
    assert list(rows) == BENCHES
    parser = rows["gesture_parser"]
    assert parser["packets_per_s"] > 0 and parser["imu_messages"] == 2000  # one a loop
    assert parser["garbage_stretches"] == 50  # every 40th loop: the noise is dropped, the packets kept
    latency = rows["gesture_sample_latency"]
    assert latency["samples"] == 200 and latency["p99_ms"] >= latency["p50_ms"] > 0
    assert 0 < latency["received_p50_ms"] <= latency["p50_ms"]
    assert rows["pty_floor"]["p50_ms"] > 0 and rows["pty_floor"]["packet_bytes"] == latency["packet_bytes"]
    converter = rows["gesture_converter"]
    motions = converter["motions"]
    assert set(motions) == {"slow_tilt", "slow_turn", "tilt_1.6_deg_a_sample", "clamped_speed_turning", "yaw_wrap"}
    for motion in motions.values():  # deterministic: the fixed converter does what was meant, the chapter's not
        assert motion["fixed"] == motion["intended"] and motion["fixed_error_max"] <= 0.001
        assert motion["chapter_error_max"] > 0.1
    assert motions["slow_tilt"]["chapter"] == [0.2, 0.0]  # the half-degree steps truncated away
    assert motions["yaw_wrap"]["chapter"][1] < 0 < motions["yaw_wrap"]["intended"][1]  # turned the wrong way
    assert motions["clamped_speed_turning"]["chapter_error_max"] >= 1.0  # the turn left unclamped
