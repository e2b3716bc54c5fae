"""A run as a session: observers see every trace event and are called in phase order; services
give skills their interfaces and do their after-tick work in order."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import pytest

from botstage.behaviors.trace import dumps
from botstage.missions.runner import RunError, StopRun, run
from botstage.missions.session import RunSession, observer_registry, service_registry
from botstage.missions.session.plugins import PluginRegistry
from botstage.missions.session.services import RobotService

ROOT = Path(__file__).resolve().parent.parent
HELLO = ROOT / "missions" / "examples" / "hello.yaml"
DRIVE_DEMO = ROOT / "missions" / "examples" / "drive_demo.yaml"


class Recorder:
    """Every hook, recorded in order; every event kept as it will be written."""

    name = "recorder"

    def __init__(self) -> None:
        self.calls: list[str] = []
        self.lines: list[str] = []

    def started(self, session: RunSession) -> None:
        assert session.engine is not None and session.root is not None
        self.calls.append("started")

    def event(self, record: dict[str, Any]) -> None:
        self.lines.append(dumps(record))

    def before_tick(self, session: RunSession) -> None:
        self.calls.append("before_tick")

    def after_tick(self, session: RunSession) -> None:
        self.calls.append("after_tick")

    def finished(self, session: RunSession, result: Any) -> None:
        self.calls.append("finished")
        assert result.summary["outcome"] == result.outcome  # the summary's core is there already
        result.summary["recorder"] = {"events": len(self.lines)}
        (session.folder / "recorder.txt").write_text(f"{len(self.lines)} events\n")


@pytest.mark.parametrize("mission", [HELLO, DRIVE_DEMO])
def test_an_observer_sees_every_trace_event(tmp_path: Path, mission: Path) -> None:
    recorder = Recorder()
    result = run(mission, until=8, out=tmp_path, observers=[recorder])
    written = (tmp_path / "trace.jsonl").read_text(encoding="utf-8").splitlines()
    assert len(recorder.lines) == len(written) > 100
    assert recorder.lines == written  # the same events, in the same order, with the same content
    assert result.summary["recorder"] == {"events": len(written)}
    assert "recorder.txt" in result.summary["artefacts"]
    assert json.loads((tmp_path / "summary.json").read_text()) == result.summary


def test_hooks_are_called_in_phase_order(tmp_path: Path) -> None:
    recorder = Recorder()
    result = run(HELLO, until=2, out=tmp_path, observers=[recorder])
    ticks = result.summary["ticks"]
    assert recorder.calls == ["started", *["before_tick", "after_tick"] * ticks, "finished"]


def test_an_observer_without_event_is_not_subscribed(tmp_path: Path) -> None:
    class Quiet:
        def finished(self, session: RunSession, result: Any) -> None:
            self.seen = result.outcome

    quiet = Quiet()
    session = RunSession(HELLO, until=1, out=tmp_path, observers=[quiet])
    builtin_listeners = len(RunSession(HELLO).hooks.calls["event"])
    assert len(session.hooks.calls["event"]) == builtin_listeners  # the summary's and the transcript's only
    session.run()
    assert quiet.seen == "time_limit"


def test_a_failing_observer_is_detached_and_the_run_goes_on(tmp_path: Path) -> None:
    class Faulty:
        name = "faulty"

        def __init__(self) -> None:
            self.events = 0

        def event(self, record: dict[str, Any]) -> None:
            self.events += 1
            if self.events == 3:
                raise RuntimeError("lost the connection to the monitor")

    faulty = Faulty()
    result = run(HELLO, seed=7, out=tmp_path / "a", observers=[faulty])
    plain = run(HELLO, seed=7, out=tmp_path / "b")
    assert faulty.events == 3
    assert result.summary["observer_errors"] == ["faulty.event: RuntimeError: lost the connection to the monitor"]
    assert (tmp_path / "a" / "trace.jsonl").read_bytes() == (tmp_path / "b" / "trace.jsonl").read_bytes()
    assert result.outcome == plain.outcome == "done"


def test_an_observer_can_stop_the_run(tmp_path: Path) -> None:
    class Stopper:
        def before_tick(self, session: RunSession) -> None:
            if session.clock.now() >= 3:
                raise StopRun("seen enough")

    result = run(HELLO, out=tmp_path, observers=[Stopper()])
    assert (result.outcome, result.reason) == ("stopped_by_test", "seen enough")
    assert result.summary["sim_time_s"] == 3.0


def test_observers_by_name_include_plugins_and_builtins() -> None:
    registry = observer_registry()
    assert "console" in registry and registry.origin("console") == "builtin"
    assert registry.problems == []
    with pytest.raises(LookupError, match="unknown observer 'consol' \\(did you mean 'console'\\?\\); installed: "):
        registry.get("consol")


def test_the_console_observer_prints_states_as_they_change(tmp_path: Path) -> None:
    console = observer_registry(plugins=False).create("console")
    console.stream = io.StringIO()
    run(HELLO, out=tmp_path, observers=[console])
    lines = console.stream.getvalue().splitlines()
    assert lines[:2] == ["      0.0 s  hello: - -> greeting (start)", "      0.0 s  hello/greeting/greet/log: success"]
    assert any("-> done" in line for line in lines)


# -- services -------------------------------------------------------------------------------


def test_the_builtin_services_in_their_order() -> None:
    registry = service_registry()
    assert list(registry)[:4] == ["robot", "uploads", "files", "orders"]
    assert all(registry.origin(name) == "builtin" for name in ("robot", "uploads", "files", "orders"))
    assert registry.problems == []


class Beacon:
    """A service of a plugin's: an interface for skills, after-tick work and a summary block."""

    name = "beacon"
    order: list[str] = []

    def open(self, session: RunSession) -> dict[str, Any]:
        self.ticks = 0
        self.closed = False
        return {"beacon": self}

    def after_tick(self, session: RunSession) -> None:
        self.ticks += 1
        Beacon.order.append("beacon")

    def close(self) -> None:
        self.closed = True

    def finished(self, session: RunSession, result: Any) -> None:
        result.summary["beacon"] = {"ticks": self.ticks, "closed": self.closed}


class RobotSpy(RobotService):
    def after_tick(self, session: RunSession) -> None:
        Beacon.order.append("robot")
        super().after_tick(session)


def test_a_service_gives_an_interface_and_runs_after_the_robot_services(tmp_path: Path) -> None:
    services = service_registry(plugins=False)
    services.register("robot", RobotSpy, origin="builtin", replace=True)  # same place in the order
    services.register("beacon", Beacon)
    Beacon.order.clear()
    session = RunSession(DRIVE_DEMO, until=2, out=tmp_path, services=services)
    result = session.run()
    assert session.engine is not None and session.engine.interfaces["beacon"] is session.services[-1]
    assert list(session.interfaces)[-6:] == [  # no plug-in sets' services (gallery, gesture) here
        "localization",
        "navigation",
        "uploads",
        "files",
        "orders",
        "beacon",
    ]
    assert result.summary["beacon"] == {"ticks": result.summary["ticks"], "closed": True}
    assert Beacon.order[:4] == ["robot", "beacon", "robot", "beacon"]
    assert "localization" in result.summary  # the robot service's block


def test_a_robot_less_mission_has_no_robot_services(tmp_path: Path) -> None:
    session = RunSession(HELLO, until=1, out=tmp_path)
    session.run()
    assert session.backend is None
    # the core's services, then the plug-in sets' (the web set's gallery, the hardware set's glove)
    assert list(session.interfaces) == ["uploads", "files", "orders", "gallery_server", "gesture"]


def test_plugin_registries_record_broken_entries(monkeypatch: pytest.MonkeyPatch) -> None:
    registry = PluginRegistry("botstage.services", "service")
    registry.register("files", service_registry(plugins=False).get("files"), origin="builtin")
    with pytest.raises(ValueError, match="service 'files' is already registered"):
        registry.register("files", Beacon)
    with pytest.raises(TypeError, match="is not a class or factory"):
        registry.register("nothing", 42)  # type: ignore[arg-type]


def test_a_service_that_cannot_open_is_a_run_error_and_the_others_close(tmp_path: Path) -> None:
    class Jammed:
        name = "jammed"

        def open(self, session: RunSession) -> dict[str, Any]:
            raise OSError("the lift controller does not answer")

        def close(self) -> None:
            raise AssertionError("never opened: never closed")

    services = service_registry(plugins=False)
    services.register("jammed", Jammed)
    session = RunSession(DRIVE_DEMO, until=1, out=tmp_path, services=services)
    with pytest.raises(RunError, match="service 'jammed' cannot open: OSError: the lift controller does not answer"):
        session.run()
    assert session.backend is not None and session.backend.world.wheel_targets() == (0.0, 0.0)
