"""Fault drills of a deployment, with real processes (issue 18's acceptance).

Each drill starts a small deployment of tests/deployments/ as ``botstage up`` does (one
``serve process`` per process under the Supervisor, on loopback), does its harm with a signal,
and checks what the processes said and the run left. Wall-clock figures (kill to the node's
failure, kill to the drive's stop) are measured and printed, never asserted: what is asserted is
that the failure came through loss detection (the exact reason) and that the stop happened once.

- SIGKILL of the skills process mid-``listen``: the node fails with ``remote 'speech' lost``, the
  machine takes its failure transition and the mission goes on;
- SIGKILL of the mission process: the robot process stops the drive, once;
- a killed skills process restarted: the next call succeeds, and so does every call after it;
- SIGKILL of the upload process while photos wait in its outbox: after its restart every photo
  arrives in the gallery exactly once.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
import signal
import sqlite3
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from botstage.missions.cli.distributed import free_port, process_commands
from botstage.missions.deployment import check_deployment
from botstage.missions.distributed.supervisor import Supervisor

ROOT = Path(__file__).resolve().parent.parent
DEPLOYMENTS = ROOT / "tests" / "deployments"
FAILSAFE_S = 120.0  # a bound for what must happen, never a measure
UNTIL = 20000.0  # s of mission time: a safety net; each drill ends its mission itself


@dataclass(frozen=True)
class Line:
    at: float  # monotonic, when it reached this process
    process: str
    text: str


class Drill:
    """A deployment's processes under a Supervisor, each line they print kept with its arrival time."""

    def __init__(self, deployment: Path, out: Path) -> None:
        checked = check_deployment(deployment)
        assert checked.ok and checked.deployment is not None, checked.problems
        self.out = out
        self.mission = checked.mission_process
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        commands = process_commands(deployment, endpoint, out=out, until=UNTIL)
        self.lines: list[Line] = []
        self._changed = threading.Condition()
        self.supervisor = Supervisor(commands, self._keep, cwd=str(ROOT))

    def _keep(self, process: str, text: str) -> None:
        line = Line(time.monotonic(), process, text)
        print(f"{process:>8} | {text}")
        with self._changed:
            self.lines.append(line)
            self._changed.notify_all()

    def expect(self, process: str, pattern: str, after: float = 0.0) -> Line:
        """The first line of ``process`` matching ``pattern`` that arrived after ``after`` (waiting for it)."""
        found = re.compile(pattern)

        def match() -> Line | None:
            return next((x for x in self.lines if x.process == process and x.at > after and found.search(x.text)), None)

        with self._changed:
            line = self._changed.wait_for(match, FAILSAFE_S)
        assert line is not None, f"{process} never said {pattern!r}; states: {self.supervisor.states()}"
        return line

    def said(self, process: str, pattern: str) -> list[Line]:
        with self._changed:
            return [x for x in self.lines if x.process == process and re.search(pattern, x.text)]

    def kill(self, process: str) -> float:
        """SIGKILL ``process``; the monotonic time just before the signal went."""
        at = time.monotonic()
        self.supervisor.signal(process, signal.SIGKILL)
        return at

    def end_mission(self) -> int:
        """Ctrl-C to the mission's process (its run ends, its trace and summary are written); its exit code."""
        self.supervisor.signal(self.mission, signal.SIGINT)
        return self.supervisor.wait(self.mission, FAILSAFE_S)


@pytest.fixture
def drill(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Drill]:
    running = Drill(DEPLOYMENTS / request.param, tmp_path / "run")
    running.supervisor.start()
    try:
        running.expect(running.mission, "runs the mission")
        yield running
    finally:
        running.supervisor.stop()


def events(run: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run / "trace.jsonl").read_text(encoding="utf-8").splitlines()]


def outcomes_of(trace: list[dict[str, Any]], skills: set[str]) -> list[dict[str, Any]]:
    return [e for e in trace if e["ev"] == "skill_outcome" and e["skill"] in skills]


SPEECH = {"listen", "detect_crowd", "speak"}
LOST = "remote 'speech' lost"


def kill_speech_mid_listen(drill: Drill) -> tuple[float, Line]:
    """SIGKILL `speech` while its listen runs (the mission said the state after the skill started there)."""
    drill.expect("mission", r"-> listening")
    killed = drill.kill("speech")
    lost = drill.expect("mission", re.escape(f"{LOST}: "), after=killed)
    print(f"node failed with {LOST!r} {(lost.at - killed) * 1000:.0f} ms (wall) after the SIGKILL")
    return killed, lost


@pytest.mark.parametrize("drill", ["listening_three_processes.yaml"], indirect=True)
def test_a_skills_process_killed_mid_listen_fails_the_node_with_the_reason_and_the_mission_goes_on(
    drill: Drill,
) -> None:
    killed, _ = kill_speech_mid_listen(drill)
    after = drill.expect("mission", r"listening -> recovering", after=killed)
    drill.expect("mission", r"recovering -> looking", after=after.at)  # later ticks: the mission goes on
    drill.expect("mission", r"process 'speech' lost")  # lockstep goes on without it
    drill.end_mission()

    trace = events(drill.out)
    listens = [e for e in trace if e["ev"] in ("skill_start", "skill_outcome") and e["skill"] == "listen"]
    assert listens[0]["ev"] == "skill_start"
    failed = listens[1]
    assert (failed["ev"], failed["outcome"], failed["reason"]) == ("skill_outcome", "failure", LOST)
    assert failed["tick"] > listens[0]["tick"]  # it was running over there when the process died
    moved = [e for e in trace if e["ev"] == "transition" and e["tick"] >= failed["tick"]]
    assert moved[0]["source"] == "listening" and moved[0]["dest"] == "recovering"
    assert moved[0]["trigger"] == "listening:failure"
    assert max(e["tick"] for e in trace) > failed["tick"] + 10  # a second of mission time and more


@pytest.mark.parametrize("drill", ["listening_three_processes.yaml"], indirect=True)
def test_a_restarted_skills_process_serves_the_next_call(drill: Drill) -> None:
    kill_speech_mid_listen(drill)
    drill.supervisor.wait("speech", FAILSAFE_S)
    drill.supervisor.restart("speech")
    back = drill.expect("mission", r"remote 'speech' serves again")
    drill.expect("mission", r"process 'speech' is back")
    listened = drill.expect("mission", r"listening -> looking", after=back.at)  # a whole round on the new process
    drill.expect("mission", r"speaking -> listening", after=listened.at)
    drill.end_mission()

    calls = outcomes_of(events(drill.out), SPEECH)
    last_lost = max(i for i, e in enumerate(calls) if e["reason"].startswith("remote 'speech' lost"))
    since = calls[last_lost + 1 :]
    assert since, "no call after the restart"
    assert [e for e in since if e["outcome"] == "failure"] == []  # the next call succeeds, and every one after
    # the new process opened the robot's devices (listen, speak) and the mission's estimates (detect_crowd)
    assert {e["skill"] for e in since} == SPEECH


@pytest.mark.parametrize("drill", ["driving_two_processes.yaml"], indirect=True)
def test_a_killed_mission_process_has_the_robot_process_stop_the_drive(drill: Drill) -> None:
    drill.expect("mission", r"-> turning")  # the drive has been commanded by then
    killed = drill.kill("mission")
    stopped = drill.expect("robot", r"mission 'mission' lost: drive stopped", after=killed)
    found = re.search(r"monotonic (\d+\.\d+)", stopped.text)
    assert found is not None, stopped.text
    print(f"drive stopped {(float(found.group(1)) - killed) * 1000:.1f} ms after the SIGKILL (robot's clock)")
    assert drill.supervisor.states()["robot"] == "running"  # the robot process serves on
    drill.supervisor.stop()
    assert len(drill.said("robot", r"mission 'mission' (lost|left)")) == 1  # said once


def pending_in(outbox: Path) -> int | None:
    """Photos the outbox holds unsent (None while it cannot be read)."""
    database = outbox / "outbox.sqlite"
    if not database.is_file():
        return None
    try:
        with contextlib.closing(sqlite3.connect(f"file:{database}?mode=ro", uri=True, timeout=1.0)) as db:
            return int(db.execute("SELECT count(*) FROM photos WHERE state = 'pending'").fetchone()[0])
    except sqlite3.Error:
        return None


def freeze_with_photos_waiting(drill: Drill, outbox: Path) -> int:
    """Stop `upload` (SIGSTOP) at a moment its outbox holds unsent photos; how many."""
    deadline, pace = time.monotonic() + FAILSAFE_S, threading.Event()
    while time.monotonic() < deadline:
        if pending_in(outbox):
            drill.supervisor.signal("upload", signal.SIGSTOP)
            waiting = pending_in(outbox)
            if waiting:
                return waiting
            drill.supervisor.signal("upload", signal.SIGCONT)  # sent in between: the next round
        pace.wait(0.002)
    raise AssertionError("the outbox never held an unsent photo")


def hashes_of(folder: Path) -> list[str]:
    return sorted(hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.glob("*.jpg"))


@pytest.mark.parametrize("drill", ["photos_four_processes.yaml"], indirect=True)
def test_an_upload_process_killed_mid_upload_and_restarted_delivers_every_photo_once(drill: Drill) -> None:
    waiting = freeze_with_photos_waiting(drill, drill.out / "outbox")
    drill.kill("upload")
    drill.supervisor.wait("upload", FAILSAFE_S)
    print(f"upload killed with {waiting} photo(s) in its outbox")
    drill.supervisor.restart("upload")
    resumed = drill.expect("upload", r"resumed the outbox .*: \d+ photo")
    found = re.search(r": (\d+) photo", resumed.text)
    # what the killed one left unsent (and a photo it was recording, if that was on disk whole)
    assert found is not None and int(found.group(1)) >= waiting, resumed.text
    assert drill.supervisor.wait(drill.mission, FAILSAFE_S) == 0  # the mission ends by itself, done
    drill.supervisor.stop()

    summary = json.loads((drill.out / "summary.json").read_text())
    assert summary["counters"]["rounds"] == 5
    photos = hashes_of(drill.out / "photos")
    assert len(photos) == 15 == len(set(photos))  # five rounds of three distinct photos
    with contextlib.closing(sqlite3.connect(drill.out / "gallery" / "gallery.sqlite")) as db:
        in_gallery = sorted(h for (h,) in db.execute("SELECT hash FROM photos"))
    assert in_gallery == photos  # every photo, each once
    assert hashes_of(drill.out / "gallery" / "photos") == photos
    assert pending_in(drill.out / "outbox") == 0
