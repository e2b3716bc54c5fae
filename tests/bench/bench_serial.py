"""Serial benchmarks for the Chefbot's Launchpad link. Run with `python -m tests.bench serial`.

At 115200 baud 8N1 a serial line carries at most 11,520 bytes/s; the board's lines average
about 19 bytes, so at most ~600 lines/s. Targets: the driver parses at least 100x that rate,
and a velocity command's bytes are on the pty within 2 ms at the 99th percentile.

- **parser**: ``LineDecoder`` alone on a buffer of realistic lines (the firmware's mix: per
  50 Hz loop ``t``, ``e``, ``s``; ``i`` at 20 Hz, ``u`` at 10 Hz, ``b`` at 1 Hz, values from a
  robot driving about), fed in 256-byte chunks as serial reads return them; best of 5.
- **end to end**: the same buffer written into a pty's master as fast as the pty takes it,
  the real driver (pyserial, reader thread, the controller chain handling every line: odometry,
  PID, sonar, IMU) reading the slave, until its last line is parsed.
- **latency**: from calling ``cmd_vel`` to the first byte of the resulting ``s`` command being
  readable on the pty's master (what the board would receive), alternating two commands so
  each one changes the outputs; once with the board silent, once while it streams its lines at
  the firmware's rate (the reader thread busy beside the caller).
- **the pty's floor**: the same round trip with no driver at all (8 bytes written to the slave
  with ``os.write``, read on the master): what the machine itself gives.
- each latency again **under SCHED_FIFO** (``chrt -f 10``), when the OS allows it: the process
  is then not preempted by other processes, as on a robot PC that runs its driver so. The gap
  between the two says how much of the tail is the scheduler's (see the README).
"""

from __future__ import annotations

import json
import math
import os
import random
import select
import statistics
import tempfile
import threading
import time
import tty
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from botstage.robots.clock import SimClock
from botstage.robots.drivers.chefbot_base import ChefbotBase, open_chefbot
from botstage.robots.drivers.launchpad_protocol import LINE_RATE_BYTES, LineDecoder
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import load_profile, profile_path

TARGET_RATIO = 100.0
TARGET_P99_MS = 2.0


def firmware_loops(loops: int, seed: int = 0, driving: bool = True) -> list[bytes]:
    """The board's output, one entry per firmware loop at 50 Hz, as the emulator prints it:
    driving about, or (``driving=False``) straight ahead at 0.15 m/s."""
    rng = random.Random(seed)
    out = []
    left = right = 0
    yaw = 0.0
    micros = 0
    for k in range(loops):
        micros = (micros + 20_000 + rng.randint(-300, 300)) % 2**32
        v, w = (0.25 + 0.05 * math.sin(k / 80), 0.4 * math.sin(k / 50)) if driving else (0.15, 0.0)
        left += round((v - w * 0.15) * 0.02 * 15845)
        right += round((v + w * 0.15) * 0.02 * 15845)
        yaw = math.remainder(yaw + w * 0.02, 2 * math.pi)
        lines = [b"t\t%d\t%.6f\n" % (micros, 0.02), b"e\t%d\t%d\n" % (left, right)]
        if k % 5 == 0:
            lines.append(b"u\t%d\n" % rng.randint(20, 400))
        lines.append(b"s\t%d\t%d\n" % (rng.randint(120, 200), rng.randint(120, 200)))
        if k % 5 in (0, 2):
            lines.append(b"i\t0.0000\t0.0000\t%.4f\t%.4f\n" % (math.sin(yaw / 2), math.cos(yaw / 2)))
        if k % 50 == 0:
            lines.append(b"b\t%.2f\n" % (12.6 - k * 1e-5))
        out.append(b"".join(lines))
    return out


def bench_parser(data: bytes, repeats: int = 5) -> dict[str, Any]:
    lines = data.count(b"\n")
    best = math.inf
    for _ in range(repeats):
        decoder = LineDecoder()
        start = time.perf_counter()
        for i in range(0, len(data), 256):
            decoder.feed(data[i : i + 256])
        best = min(best, time.perf_counter() - start)
        assert decoder.lines_ok == lines and decoder.lines_bad == 0
    return {
        "bench": "parser",
        "bytes": len(data),
        "lines": lines,
        "mean_line_bytes": round(len(data) / lines, 1),
        "lines_per_s": round(lines / best),
        "bytes_per_s": round(len(data) / best),
        "line_rate_bytes_per_s": LINE_RATE_BYTES,
        "ratio_vs_115200_baud": round(len(data) / best / LINE_RATE_BYTES, 1),
        "target_ratio": TARGET_RATIO,
        "meets_target": len(data) / best / LINE_RATE_BYTES >= TARGET_RATIO,
    }


class Pty:
    """A pty with a stable path, the board's end (master) in the bench's hands."""

    def __init__(self) -> None:
        self.folder = tempfile.mkdtemp(prefix="botstage-bench-")
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = str(Path(self.folder) / "ttyBENCH")
        os.symlink(os.ttyname(self.slave), self.path)

    def drain(self) -> None:
        while select.select([self.master], [], [], 0)[0]:
            os.read(self.master, 65536)

    def close(self) -> None:
        os.unlink(self.path)
        os.close(self.master)
        os.close(self.slave)
        os.rmdir(self.folder)


def chefbot(pty: Pty) -> ChefbotBase:
    profile, _, _ = load_profile(profile_path("chefbot"))  # type: ignore[arg-type]
    assert profile is not None
    base = open_chefbot(pty.path, profile, SimClock(10), Pose2D(0.0, 0.0, 0.0), silence_s=3600.0)
    assert base.link.wait_connected(5)
    return base


def bench_end_to_end(data: bytes) -> dict[str, Any]:
    lines = data.count(b"\n")
    pty = Pty()
    base = chefbot(pty)
    decoder = base.link.decoder
    stop = threading.Event()

    def drain() -> None:  # what the driver sends back (PID outputs) must not fill the pty
        while not stop.is_set():
            if select.select([pty.master], [], [], 0.05)[0]:
                os.read(pty.master, 65536)

    drainer = threading.Thread(target=drain, daemon=True)
    drainer.start()
    time.sleep(0.1)
    pty.drain()
    start = time.perf_counter()
    view = memoryview(data)
    while view:
        written = os.write(pty.master, view[:65536])
        view = view[written:]
    while decoder.lines_ok + decoder.lines_bad < lines and time.perf_counter() - start < 120:
        time.sleep(0.0005)
    elapsed = time.perf_counter() - start
    parsed, bad = decoder.lines_ok, decoder.lines_bad
    stop.set()
    drainer.join()
    base.close()
    pty.close()
    return {
        "bench": "end_to_end_pty",
        "bytes": len(data),
        "lines": lines,
        "lines_parsed": parsed,
        "lines_bad": bad,
        "lines_per_s": round(parsed / elapsed),
        "bytes_per_s": round(len(data) / elapsed),
        "ratio_vs_115200_baud": round(len(data) / elapsed / LINE_RATE_BYTES, 1),
        "target_ratio": TARGET_RATIO,
        "meets_target": len(data) / elapsed / LINE_RATE_BYTES >= TARGET_RATIO and parsed == lines,
    }


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(q / 100 * len(ordered)) - 1)]


def turning(command: tuple[int, int]) -> bool:
    """Which of the two alternating commands an output answers: the turn (v 0.1, w 0.5) drives
    the right wheel far faster than the left; straight ahead (v 0.2) drives both alike."""
    return command[1] - command[0] > 40


def bench_latency(commands: int, streaming: bool) -> dict[str, Any]:
    pty = Pty()
    base = chefbot(pty)
    stop = threading.Event()
    if streaming:
        loops = firmware_loops(3000, seed=1, driving=False)  # both commands stay easy to tell apart

        def board() -> None:  # the firmware's lines at its own pace: one loop every 20 ms
            k = 0
            next_loop = time.monotonic()
            while not stop.is_set():
                os.write(pty.master, loops[k % len(loops)])
                k += 1
                next_loop += 0.02
                stop.wait(max(0.0, next_loop - time.monotonic()))

        threading.Thread(target=board, daemon=True).start()
    time.sleep(0.2)
    rng = random.Random(5)
    latencies: list[float] = []
    calls: list[float] = []  # the driver's own part: cmd_vel until its write returned
    lock_waits: list[float] = []  # how long cmd_vel would wait for the chain the reader thread holds
    for n in range(commands):
        pty.drain()
        turn = n % 2 == 0
        before = time.perf_counter()
        with base._lock:
            lock_waits.append((time.perf_counter() - before) * 1000)
        start = time.perf_counter()
        base.cmd_vel(0.1, 0.5) if turn else base.cmd_vel(0.2, 0.0)
        calls.append((time.perf_counter() - start) * 1000)
        arrived, pending = None, b""
        while arrived is None and time.perf_counter() - start < 1.0:
            if not select.select([pty.master], [], [], 0.1)[0]:
                continue
            pending += os.read(pty.master, 65536)
            now = time.perf_counter()
            *complete, pending = pending.split(b"\r")
            for part in complete:
                fields = part.split()
                if len(fields) == 3 and turning((int(fields[1]), int(fields[2]))) == turn:
                    arrived = now
                    break
        assert arrived is not None, "the command never reached the pty"
        latencies.append((arrived - start) * 1000)
        time.sleep(rng.uniform(0.001, 0.005))
    stop.set()
    base.close()
    pty.close()
    p99 = percentile(latencies, 99)
    return {
        "bench": "command_latency" + ("_while_streaming" if streaming else ""),
        "commands": commands,
        "p50_ms": round(statistics.median(latencies), 3),
        "p99_ms": round(p99, 3),
        "max_ms": round(max(latencies), 3),
        "driver_call_p50_ms": round(statistics.median(calls), 3),
        "driver_call_p99_ms": round(percentile(calls, 99), 3),
        "lock_wait_p99_ms": round(percentile(lock_waits, 99), 4),
        "lock_wait_max_ms": round(max(lock_waits), 4),
        "target_p99_ms": TARGET_P99_MS,
        "meets_target": p99 <= TARGET_P99_MS,
    }


def bench_pty_floor(commands: int, data: bytes = b"s 10 20\r", to_host: bool = False) -> dict[str, Any]:
    """The round trip with nothing of ours in it: os.write on the slave, select and read on the master
    (``to_host``: the other way, a board's bytes written on the master and read on the slave,
    until all of ``data`` is there)."""
    pty = Pty()
    rng = random.Random(5)
    latencies = []
    source, sink = (pty.master, pty.slave) if to_host else (pty.slave, pty.master)
    for _ in range(commands):
        pty.drain()
        start = time.perf_counter()
        os.write(source, data)
        got = 0
        while got < len(data) and select.select([sink], [], [], 1.0)[0]:
            got += len(os.read(sink, 4096))
        latencies.append((time.perf_counter() - start) * 1000)
        time.sleep(rng.uniform(0.001, 0.005))
    pty.close()
    return {
        "bench": "pty_floor",
        "commands": commands,
        "p50_ms": round(statistics.median(latencies), 3),
        "p99_ms": round(percentile(latencies, 99), 3),
        "max_ms": round(max(latencies), 3),
    }


@contextmanager
def fifo(priority: int = 10) -> Iterator[bool]:
    """Run the calling thread (and the threads it starts) under SCHED_FIFO if the OS allows it."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError):
        yield False
        return
    try:
        yield True
    finally:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


def under_fifo(bench: Any) -> dict[str, Any]:
    with fifo() as allowed:
        if not allowed:
            return {"bench": "sched_fifo", "skipped": "SCHED_FIFO not permitted (needs CAP_SYS_NICE)"}
        result = bench()
    result["bench"] += "_sched_fifo"
    return result


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The benches that missed their target."""
    return [r["bench"] for r in results if not r.get("meets_target", True)]


def main(quick: bool = False) -> list[dict[str, Any]]:
    data = b"".join(firmware_loops(5_000 if quick else 60_000))  # 0.3 or 3.6 MB
    results = []
    for bench in (
        lambda: bench_parser(data, 2 if quick else 5),
        lambda: bench_end_to_end(data),
        lambda: bench_pty_floor(200 if quick else 2000),
        lambda: bench_latency(200 if quick else 2000, streaming=False),
        lambda: bench_latency(200 if quick else 2000, streaming=True),
        lambda: under_fifo(lambda: bench_pty_floor(200 if quick else 2000)),
        lambda: under_fifo(lambda: bench_latency(200 if quick else 2000, streaming=False)),
        lambda: under_fifo(lambda: bench_latency(200 if quick else 2000, streaming=True)),
    ):
        result = bench()
        print(json.dumps(result), flush=True)
        results.append(result)
    return results


if __name__ == "__main__":
    main()
