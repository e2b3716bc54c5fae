"""`python -m tests.bench facetracker --quick`: every figure is there and a number; timings are never asserted on."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BENCHES = ["facetracker_detection", "facetracker_walk", "facetracker_recentre"]


def test_the_bench_reports_every_figure() -> None:
    command = [sys.executable, "-m", "tests.bench", "facetracker", "--quick"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=900, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    rows = {
        row["bench"]: row for row in (json.loads(line) for line in done.stdout.splitlines() if line.startswith("{"))
    }
    assert list(rows) == BENCHES
    detection = rows["facetracker_detection"]
    assert detection["chapter_fps"] > 0 and detection["opencv_defaults_fps"] > 0
    assert 0 < detection["chapter_hits"] <= detection["frames_with_a_face"] <= detection["frames"]
    walk = rows["facetracker_walk"]
    for mode in ("fixed", "proportional"):
        assert walk[f"{mode}_1mps_error_p95_px"] >= walk[f"{mode}_1mps_error_mean_px"] > 0
        assert 0.0 <= walk[f"{mode}_1mps_in_dead_band"] <= 1.0
    recentre = rows["facetracker_recentre"]
    assert recentre["fixed_left_s"] > 0 and recentre["proportional_left_s"] > 0  # sim time: not a wall timing
