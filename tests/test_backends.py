"""Backends by name: the registry, their options (profile, --port, --backend-opt) and their protocol."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from pydantic import Field

from botstage.missions.runner import RunError, run
from botstage.robots.backend import Backend, BackendError, BackendKind, BackendOptions, OpenRequest
from botstage.robots.backend_options import OptionSources, parse_assignments, resolve
from botstage.robots.backend_registry import BackendRegistry
from botstage.robots.clock import SimClock
from botstage.robots.gridmap import load as load_map
from botstage.robots.gridmap import map_path
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import PROFILES_DIR, load_profile
from botstage.robots.sim.backend import SimBackend
from botstage.robots.sim.kind import SimKind

ROOT = Path(__file__).resolve().parent.parent
DRIVE_DEMO = ROOT / "missions" / "examples" / "drive_demo.yaml"


class Recording(SimKind):
    """The simulator under another name, remembering what it was opened with."""

    name = "recording"
    description = "the simulator, recording its options"
    opened: list[tuple[OpenRequest, BackendOptions]] = []

    class Options(BackendOptions):
        label: str = Field(default="", description="a label")
        speed: float = Field(default=1.0, gt=0, description="a speed")

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        Recording.opened.append((request, options))
        return super().open(request, options)


def chefbot_with(tmp_path: Path, backends: str) -> Path:
    """A mission on a copy of the Chefbot's profile with this ``backends:`` section."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    profile = tmp_path / "mybot.yaml"
    text = (PROFILES_DIR / "chefbot.yaml").read_text().replace("name: chefbot", "name: mybot", 1)
    profile.write_text(text.rstrip("\n") + "\n" + textwrap.dedent(backends))
    mission = tmp_path / "mission.yaml"
    mission.write_text(DRIVE_DEMO.read_text().replace("robot: chefbot", f"robot: {profile}"))
    return mission


def test_the_builtin_backends_are_registered_once_with_their_entry_points() -> None:
    registry = BackendRegistry.default()
    assert list(registry)[:3] == ["sim", "emulator", "hardware"]
    assert registry.origin("sim") == "builtin"  # the core's; the hardware set's come through its entry points
    assert all(registry.origin(name) == "plugin botstage" for name in ("emulator", "hardware"))
    assert registry.problems == []
    assert registry.get("sim").simulated and not registry.get("hardware").simulated
    described = registry.get("hardware").describe()
    assert described["options"]["port"]["required"] and "serial port" in described["options"]["port"]["description"]


def test_an_unknown_backend_lists_the_installed_ones(tmp_path: Path) -> None:
    registry = BackendRegistry.default()
    with pytest.raises(BackendError) as info:
        registry.get("simm")
    message = str(info.value)
    assert message.startswith("unknown backend 'simm' (did you mean 'sim'?); installed: sim (the built-in simulator")
    assert "emulator (the simulated robot through its emulated board" in message and "hardware (" in message
    with pytest.raises(RunError, match="unknown backend 'gpu'; installed: sim"):
        run(DRIVE_DEMO, backend="gpu", out=tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_backend_opt_values_are_yaml_scalars() -> None:
    assert parse_assignments(["ready_timeout=2.5", "port=/dev/ttyUSB0", "counter_start=7", "flag=true", "x="]) == {
        "ready_timeout": 2.5,
        "port": "/dev/ttyUSB0",
        "counter_start": 7,
        "flag": True,
        "x": "",
    }
    assert parse_assignments(["label=[1, 2]"]) == {"label": "[1, 2]"}  # options are scalars: kept as typed
    with pytest.raises(BackendError, match="--backend-opt 'port': expected key=value"):
        parse_assignments(["port"])


def test_bad_options_name_the_option_before_anything_moves(tmp_path: Path) -> None:
    with pytest.raises(RunError) as info:
        run(DRIVE_DEMO, backend="sim", backend_options={"sped": 2}, out=tmp_path / "a")
    assert str(info.value) == "backend 'sim' has no option 'sped' (from --backend-opt; options: none)"
    with pytest.raises(RunError) as info:
        run(
            DRIVE_DEMO, backend="hardware", backend_options={"port": "/dev/null", "ready_timout": 1}, out=tmp_path / "b"
        )
    assert "has no option 'ready_timout' (from --backend-opt; did you mean 'ready_timeout'?" in str(info.value)
    with pytest.raises(RunError) as info:
        run(
            DRIVE_DEMO,
            backend="hardware",
            port="/dev/null",
            backend_options={"ready_timeout": "soon"},
            out=tmp_path / "c",
        )
    assert str(info.value).startswith("backend 'hardware' option 'ready_timeout': 'soon' from --backend-opt: ")
    with pytest.raises(RunError, match="the hardware backend needs its 'port' option \\(the robot's serial port"):
        run(DRIVE_DEMO, backend="hardware", out=tmp_path / "d")
    assert not any((tmp_path / name).exists() for name in "abcd")


def test_profile_options_are_used_and_their_errors_located(tmp_path: Path) -> None:
    registry = BackendRegistry.default()
    registry.register(Recording)
    mission = chefbot_with(tmp_path, "backends:\n  recording: {label: from-profile, speed: 2}\n")
    Recording.opened.clear()
    result = run(
        mission, backend="recording", backends=registry, backend_options={"speed": 3}, until=1, out=tmp_path / "r"
    )
    assert result.summary["backend"] == "recording" and "recording" in result.summary  # its block, under its name
    request, options = Recording.opened[0]
    assert options.model_dump() == {"label": "from-profile", "speed": 3.0}  # --backend-opt wins over the profile
    assert request.grid is not None and request.start == Pose2D(*request.grid.places["dock"])

    bad = chefbot_with(tmp_path / "bad", "backends:\n  recording:\n    speed: -1\n    colour: red\n")
    with pytest.raises(RunError) as info:
        run(bad, backend="recording", backends=registry, out=tmp_path / "x")
    lines = info.value.lines()
    profile = tmp_path / "bad" / "mybot.yaml"
    assert len(lines) == 2
    assert any(
        line.endswith(
            "error: backend 'recording' has no option 'colour' (from the robot profile; options: label, speed)"
        )
        for line in lines
    )
    assert any(": error: backend 'recording' option 'speed': -1 from the robot profile: " in line for line in lines)
    assert all(line.startswith(f"{profile}:") for line in lines)
    row = next(i for i, text in enumerate(profile.read_text().splitlines(), 1) if "colour" in text)
    assert any(line.startswith(f"{profile}:{row}:5: ") for line in lines)


def test_a_profile_backends_section_must_be_a_mapping_of_mappings(tmp_path: Path) -> None:
    profile = tmp_path / "mybot.yaml"
    profile.write_text(
        (PROFILES_DIR / "chefbot.yaml").read_text().replace("name: chefbot", "name: mybot", 1)
        + "backends: {hardware: 5}\n"
    )
    loaded, problems, _ = load_profile(profile)
    assert loaded is None
    assert [p.message for p in problems] == ["backends.hardware: Input should be a valid dictionary"]
    assert str(problems[0]).startswith(f"{profile}:")


def test_port_is_a_shortcut_for_the_port_option_and_refused_where_there_is_none() -> None:
    hardware = BackendRegistry.default().get("hardware")
    given = OptionSources({"ready_timeout": 1}, port="/dev/ttyACM0")
    assert resolve(hardware, given=given).model_dump() == {
        "port": "/dev/ttyACM0",
        "ready_timeout": 1.0,
        "baud": 115200,
        "camera": None,
    }
    with pytest.raises(BackendError, match=r"backend 'sim' has no option 'port' \(from --port"):
        resolve(BackendRegistry.default().get("sim"), given=OptionSources(port="/dev/ttyACM0"))


def test_a_profile_section_for_a_backend_not_installed_is_refused_where_it_is(tmp_path: Path) -> None:
    mission = chefbot_with(tmp_path, "backends:\n  hardwre: {port: /dev/ttyACM0}\n")
    with pytest.raises(RunError) as info:
        run(mission, out=tmp_path / "r")
    lines = info.value.lines()
    row = next(i for i, text in enumerate((tmp_path / "mybot.yaml").read_text().splitlines(), 1) if "hardwre" in text)
    assert lines[0] == f"{tmp_path / 'mybot.yaml'}:{row}:3: error: unknown backend 'hardwre' (did you mean 'hardware'?)"
    assert lines[1].startswith("error: the robot profile configures backends not installed here")
    assert not (tmp_path / "r").exists()


def test_an_observer_or_service_that_cannot_be_made_is_an_error_not_a_traceback(tmp_path: Path) -> None:
    from botstage.missions.session import RunSession
    from botstage.missions.session.plugins import PluginError, PluginRegistry

    class Broken:
        def __init__(self) -> None:
            raise RuntimeError("no horn fitted")

        def open(self, session):
            return {}

        def close(self):
            pass

    services = PluginRegistry("botstage.services", "service")
    services.register("horn", Broken)
    with pytest.raises(PluginError, match="service 'horn' cannot be made: RuntimeError: no horn fitted"):
        services.create("horn")
    with pytest.raises(RunError, match="service 'horn' cannot be made"):
        RunSession(DRIVE_DEMO, services=services, out=tmp_path / "r")


def test_backends_share_one_protocol() -> None:
    profile, _, _ = load_profile(PROFILES_DIR / "chefbot.yaml")
    assert profile is not None
    grid = load_map(map_path("restaurant"))  # type: ignore[arg-type]
    request = OpenRequest(profile, Pose2D(10.0, 7.0, 0.0), SimClock(10), grid=grid)
    _, backend = BackendRegistry.default().open("sim", request)
    try:
        assert isinstance(backend, SimBackend) and isinstance(backend, Backend)
        assert backend.profile is profile and backend.grid is grid and dict(backend.faults) == {}
        backend.devices["drive"].cmd_vel(0.2, 0.0)
        for _ in range(10):
            backend.step()
            request.clock.next_tick()
        assert backend.true_pose().x > 10.0
    finally:
        backend.close()
    assert backend.world.wheel_targets() == (0.0, 0.0)  # zero velocity once closed


class Broken(BackendKind):
    name = "broken"
    description = "cannot open"
    simulated = True

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        raise ConnectionError("no robot answers on the bus")


def test_a_backend_that_cannot_open_is_a_run_error(tmp_path: Path) -> None:
    registry = BackendRegistry.builtin()
    registry.register(Broken)
    with pytest.raises(RunError, match=r"^no robot answers on the bus$"):
        run(DRIVE_DEMO, backend="broken", backends=registry, out=tmp_path / "run")
    registry.register(SimKind)  # the same class again: one backend

    class OtherSim(SimKind):
        pass

    with pytest.raises(ValueError, match="backend 'sim' is already registered"):
        registry.register(OtherSim)


def test_the_command_line_names_bad_options_and_lists_the_backends(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from botstage.missions.cli import app

    runner = CliRunner()
    run_hardware = ["run", str(DRIVE_DEMO), "-q", "--backend", "hardware", "--out", str(tmp_path / "run")]
    bad = runner.invoke(app, [*run_hardware, "--port", "/dev/null", "--backend-opt", "ready_timeout=soon"])
    assert bad.exit_code == 2
    assert bad.output.startswith("error: backend 'hardware' option 'ready_timeout': 'soon' from --backend-opt: ")
    malformed = runner.invoke(app, [*run_hardware, "--backend-opt", "port"])
    assert malformed.exit_code == 2 and "expected key=value" in malformed.output
    nobody = runner.invoke(app, ["run", str(DRIVE_DEMO), "-q", "--observe", "nobody"])
    assert nobody.exit_code == 2 and "error: unknown observer 'nobody'; installed: console" in nobody.output

    mission = chefbot_with(tmp_path / "p", "backends:\n  hardware: {port: /dev/null, ready_timeout: soon}\n")
    located = runner.invoke(app, ["run", str(mission), "-q", "--backend", "hardware", "--out", str(tmp_path / "x")])
    profile = tmp_path / "p" / "mybot.yaml"
    assert located.exit_code == 2
    assert located.output.startswith(f"{profile}:")
    assert ": error: backend 'hardware' option 'ready_timeout': 'soon' from the robot profile: " in located.output
    assert not (tmp_path / "run").exists() and not (tmp_path / "x").exists()

    from botstage.missions.cli.common import console

    width = console.width  # set when the CLI was first imported, from that process's terminal
    console.width = 300  # a table wide enough that no cell wraps
    try:
        listing = runner.invoke(app, ["backends"])
    finally:
        console.width = width
    assert listing.exit_code == 0
    for text in ("sim", "emulator", "hardware", "port (str, required)", "counter_start (int, default 0)", "builtin"):
        assert text in listing.output


def test_the_emulator_opens_through_the_registry_with_its_options_and_faults() -> None:
    from botstage.robots.clock import WallClock

    profile, _, _ = load_profile(PROFILES_DIR / "chefbot.yaml")
    assert profile is not None
    grid = load_map(map_path("restaurant"))  # type: ignore[arg-type]
    request = OpenRequest(profile, Pose2D(10.0, 7.0, 0.0), WallClock(10), seed=1, grid=grid)
    given = OptionSources({"counter_start": 2**31 - 100})
    kind, backend = BackendRegistry.default().open("emulator", request, given)
    try:
        assert not kind.simulated and isinstance(backend, Backend)
        assert backend.emulator.counter_start == 2**31 - 100  # the option reached the board
        assert set(backend.faults) == {"garbage", "drop", "stall", "unplug", "reset"}
        assert all(fault.__doc__ for fault in backend.faults.values())  # each says what it does
        backend.faults["stall"]("left")
        assert backend.emulator.stalled == {"left"}
        backend.faults["stall"](None)
        assert backend.true_pose() == Pose2D(10.0, 7.0, 0.0)
    finally:
        backend.close()
