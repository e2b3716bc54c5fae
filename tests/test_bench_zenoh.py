"""`python -m tests.bench zenoh` with tiny sample counts: every figure is there, a number, beside its
baseline; the table marks a missed target. Timings are never asserted on."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.bench import bench_zenoh

ROOT = Path(__file__).resolve().parent.parent
BENCHES = ["skill_call", "stream_scan", "stream_image", "stream_image_flat_out", "entertainer"]


def positive(*values: Any) -> bool:
    return all(isinstance(v, int | float) and not isinstance(v, bool) and v > 0 for v in values)


def test_the_bench_reports_every_figure_beside_its_baseline() -> None:
    command = [sys.executable, "-m", "tests.bench", "zenoh", "--quick"]
    command += ["--calls", "20", "--seconds", "0.3", "--until", "2"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    lines = done.stdout.splitlines()
    rows = {row["bench"]: row for row in (json.loads(line) for line in lines if line.startswith("{"))}
    assert list(rows) == BENCHES

    call = rows["skill_call"]
    assert call["calls"] == 20 and call["request_bytes"] > call["response_bytes"] > 0
    assert positive(call["botstage_p50_ms"], call["botstage_p99_ms"], call["raw_p50_ms"], call["raw_p99_ms"])
    assert positive(call["service_p50_ms"], call["local_p50_ms"], call["ratio_p50"])
    assert positive(call["floor_p50_ms"], call["floor_ratio_p50"])
    assert call["botstage_p99_ms"] >= call["botstage_p50_ms"]

    for name, size in (("stream_scan", 700), ("stream_image", 640 * 480 * 3), ("stream_image_flat_out", 640 * 480 * 3)):
        stream = rows[name]
        assert stream["bytes"] > size  # the CDR message, header and all; the raw side sends as many
        for way in ("botstage", "raw"):
            side = stream[way]
            assert 0 < side["received"] <= side["sent"], (name, way, side)
            assert positive(side["latency_p50_ms"], side["latency_p99_ms"], side["msgs_per_s"], side["mb_per_s"])
        assert positive(stream["throughput_ratio"], stream["latency_p50_ratio"])
    assert "meets_target" in rows["stream_image"] and "meets_target" not in rows["stream_image_flat_out"]

    five = rows["entertainer"]
    assert five["counters_identical"] is True  # the same run, in five processes
    assert five["mission_s"] == 2.0
    assert positive(five["one_process_s"], five["five_processes_s"], five["ratio"], five["mission_loop_five_s"])

    table = lines[lines.index(next(line for line in lines if line.startswith("bench "))) :]
    for name in BENCHES:
        assert any(line.startswith(name) for line in table), name


def test_a_missed_target_is_marked_and_listed() -> None:
    result = {
        "bench": "entertainer",
        "seed": 1,
        "mission_s": 600.0,
        "one_process_s": 12.0,
        "five_processes_s": 54.0,
        "ratio": 4.5,
        "mission_loop_one_s": 10.0,
        "mission_loop_five_s": 50.0,
        "counters_identical": True,
        "meets_target": False,
    }
    assert bench_zenoh.missed([result, {"bench": "other", "meets_target": True}]) == ["entertainer"]
    line = next(line for line in bench_zenoh.table([result]).splitlines() if line.startswith("entertainer"))
    assert "4.50x" in line and line.endswith("MISSED")
    assert "MISSED" not in bench_zenoh.table([{**result, "ratio": 1.5, "meets_target": True}])


def test_only_runs_the_benches_named() -> None:
    assert bench_zenoh.selected(None) == ["skill_call", "stream_scan", "stream_image", "entertainer"]
    assert bench_zenoh.selected(["entertainer", "skill_call, stream_scan"]) == [
        "skill_call",
        "stream_scan",
        "entertainer",
    ]
    with pytest.raises(ValueError, match="unknown bench nope"):
        bench_zenoh.selected(["skill_call,nope"])
    command = [sys.executable, "-m", "tests.bench", "zenoh", "--only", "skill_call", "--calls", "20"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600, check=False)
    rows = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    assert [row["bench"] for row in rows] == ["skill_call"], done.stdout[-3000:] + done.stderr[-3000:]
    refused = subprocess.run(
        [*command[:4], "--only", "nope"], cwd=ROOT, capture_output=True, text=True, timeout=600, check=False
    )
    assert refused.returncode != 0 and "unknown bench nope" in refused.stderr
