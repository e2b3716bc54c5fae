"""`python -m tests.bench bittle --quick`: every figure is there and a number; timings are never asserted on."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BENCHES = ["bittle_parser", "bittle_token_latency", "pty_floor", "bittle_ack_round_trip", "bittle_gait_odometry"]


def test_the_bench_reports_every_figure() -> None:
    command = [sys.executable, "-m", "tests.bench", "bittle", "--quick"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    rows = {
        row["bench"]: row for row in (json.loads(line) for line in done.stdout.splitlines() if line.startswith("{"))
    }
    assert list(rows) == BENCHES
    assert rows["bittle_parser"]["replies_per_s"] > 0
    assert rows["bittle_token_latency"]["p99_ms"] >= rows["bittle_token_latency"]["p50_ms"] > 0
    ack = rows["bittle_ack_round_trip"]
    assert ack["driver_p50_ms"] > 0 and ack["raw_pyserial_p50_ms"] > 0
    odometry = rows["bittle_gait_odometry"]
    assert odometry["seeds"] == 3 and odometry["position_error_mean_cm"] > 0  # the body slips: never exact
    assert 0.0 <= odometry["within_95_percent_bounds"] <= 1.0
