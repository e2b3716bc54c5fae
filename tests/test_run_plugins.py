"""A third-party package, installed by pip as a real wheel, adds a backend, a run observer and a
run service through entry points only; a run opens the backend by name and the observer sees
every trace event."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from botstage.missions.runner import run
from botstage.missions.session import observer_registry, service_registry
from botstage.robots.backend_registry import BackendRegistry
from tests.tools import install_wheel

ROOT = Path(__file__).resolve().parent.parent
DRIVE_DEMO = ROOT / "missions" / "examples" / "drive_demo.yaml"
MODULE = '''
import json

from pydantic import Field

from botstage.robots.backend import BackendKind, BackendOptions


class ToyKind(BackendKind):
    name = "toy"
    description = "the simulator, painted another colour"
    simulated = True

    class Options(BackendOptions):
        colour: str = Field(default="red", description="the paint")

    def open(self, request, options):
        from botstage.robots.sim.backend import SimBackend

        class Toy(SimBackend):
            def summary(self):
                return {**super().summary(), "colour": options.colour}

        return Toy(request.profile, request.grid, request.start, request.seed, request.clock)


class Tally:
    """Counts every trace event and writes the count beside the trace."""

    def __init__(self):
        self.events = 0
        self.kinds = {}

    def event(self, record):
        self.events += 1
        self.kinds[record["ev"]] = self.kinds.get(record["ev"], 0) + 1

    def finished(self, session, result):
        result.summary["tally"] = {"events": self.events}
        (session.folder / "tally.json").write_text(json.dumps(self.kinds, sort_keys=True))


class Horn:
    """A run service: a horn skills could sound."""

    name = "horn"

    def open(self, session):
        self.sounded = 0
        return {"horn": self}

    def close(self):
        pass


class NotAnObserver:
    """Has no hook at all."""
'''
ENTRY_POINTS = """
[botstage.backends]
toy = botstage_toy_robot:ToyKind
wrongname = botstage_toy_robot:ToyKind
ghost = botstage_toy_robot:Missing

[botstage.observers]
tally = botstage_toy_robot:Tally
hookless = botstage_toy_robot:NotAnObserver

[botstage.services]
horn = botstage_toy_robot:Horn
hooter = botstage_toy_robot:Horn
"""


@pytest.fixture
def toy_plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The plugin installed into a site folder on sys.path (yielded, for subprocesses)."""
    target = install_wheel(tmp_path, "botstage-toy-robot", {"botstage_toy_robot.py": MODULE}, ENTRY_POINTS)
    monkeypatch.syspath_prepend(str(target))
    yield target
    sys.modules.pop("botstage_toy_robot", None)


def test_a_plugin_backend_observer_and_service_come_from_entry_points(toy_plugin: Path, tmp_path: Path) -> None:
    backends = BackendRegistry.default()
    assert "toy" in backends and backends.origin("toy") == "plugin botstage-toy-robot"
    reasons = {p.entry_point.split(" =")[0]: p.reason for p in backends.problems}
    assert set(reasons) == {"wrongname", "ghost"}  # broken entries are reported, the others work
    assert "differs from the backend's name 'toy'" in reasons["wrongname"]
    assert "import failed" in reasons["ghost"]
    observers = observer_registry()
    assert observers.origin("tally") == "plugin botstage-toy-robot"
    reasons = {p.entry_point.split(" =")[0]: p.reason for p in observers.problems}
    assert reasons == {"hookless": "has none of the observer hooks (started, event, before_tick, after_tick, finished)"}
    services = service_registry()
    assert list(services)[-1] == "horn"
    assert [p.reason for p in services.problems] == ["entry point name differs from the service's name 'horn'"]

    tally = observers.create("tally")
    result = run(
        DRIVE_DEMO, backend="toy", backend_options={"colour": "blue"}, until=5, out=tmp_path / "run", observers=[tally]
    )
    summary = result.summary
    assert summary["backend"] == "toy" and summary["toy"]["colour"] == "blue"
    lines = (tmp_path / "run" / "trace.jsonl").read_text().splitlines()
    assert summary["tally"] == {"events": len(lines)} and tally.events == len(lines)
    assert "tally.json" in summary["artefacts"]
    assert (tmp_path / "run" / "trajectory.csv").exists()


def test_the_plugin_backend_gives_the_simulator_s_trace(toy_plugin: Path, tmp_path: Path) -> None:
    """Same seed, same world: the toy backend's run is the simulator's, byte for byte."""
    run(DRIVE_DEMO, backend="toy", seed=2, until=5, out=tmp_path / "toy")
    run(DRIVE_DEMO, backend="sim", seed=2, until=5, out=tmp_path / "sim")
    assert (tmp_path / "toy" / "trace.jsonl").read_bytes() == (tmp_path / "sim" / "trace.jsonl").read_bytes()


def test_botstage_run_opens_a_plugin_backend_and_observer_by_name(toy_plugin: Path, tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(toy_plugin), str(ROOT)])}
    command = [sys.executable, "-m", "botstage.missions.cli", "run", str(DRIVE_DEMO), "--until", "3", "-q"]
    options = ["--backend", "toy", "--backend-opt", "colour=green", "--observe", "tally", "--out", str(tmp_path / "r")]
    done = subprocess.run([*command, *options], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    lines = (tmp_path / "r" / "trace.jsonl").read_text().splitlines()
    assert summary["toy"]["colour"] == "green" and summary["tally"] == {"events": len(lines)}
    listed = subprocess.run(
        [sys.executable, "-m", "botstage.missions.cli", "backends"],
        capture_output=True,
        text=True,
        env={**env, "COLUMNS": "300"},
        timeout=300,
    )
    assert listed.returncode == 0, listed.stderr
    assert "toy" in listed.stdout and "the simulator, painted another colour" in listed.stdout
    assert "plugin botstage-toy-robot" in listed.stdout
    assert "ghost" in listed.stderr and "import failed" in listed.stderr
