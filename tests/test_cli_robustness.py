"""Bad values on the command line, as a user or a script gives them, across the verbs: each ends in a
clean error (exit 2 for a usage error, 1 for a failure), never a traceback; `botstage run`'s exit
status says how the mission ended; the emulator's fault console outlives its bad lines; scenarios
that never ran leave no folder behind."""

from __future__ import annotations

import os
import select
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from botstage.missions.scenario import load_scenario
from botstage.missions.scenario_suite import run_in_folder
from botstage.missions.session.result import exit_status
from botstage.robots.emulators.fault_console import apply_fault
from botstage.robots.emulators.launchpad import MAX_GARBAGE, LaunchpadEmulator
from botstage.robots.places import robot_place
from botstage.robots.sim.world import World

ROOT = Path(__file__).resolve().parent.parent
HELLO = str(ROOT / "missions" / "examples" / "hello.yaml")
FAILSAFE_S = 120.0  # a bound for a process that should have ended long before; never a measurement


def botstage(*args: str, cwd: Path | None = None, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """The console script in a subprocess; wide columns, so that typer's error box never wraps."""
    environment = {**os.environ, "COLUMNS": "300", **(env or {})}
    command = [sys.executable, "-m", "botstage.missions.cli", *args]
    return subprocess.run(
        command,
        capture_output=True,
        text=True,
        cwd=cwd or ROOT,
        env=environment,
        timeout=FAILSAFE_S,
        stdin=subprocess.DEVNULL,
    )


def clean(result: subprocess.CompletedProcess, status: int) -> str:
    """The output, after checking the exit status and that no traceback was printed."""
    output = result.stdout + result.stderr
    assert result.returncode == status, output
    assert "Traceback" not in output and "internal error" not in output
    return output


# -- numbers ----------------------------------------------------------------------------------

NUMBERS = [
    (("run", HELLO), "--until", "nan", "input should be a finite number"),
    (("run", HELLO), "--until", "inf", "input should be a finite number"),
    (("run", HELLO), "--until", "-5", "input should be greater than 0"),
    (("run", HELLO), "--until", "0", "input should be greater than 0"),
    (("run", HELLO), "--until", "1e308", "input should be less than or equal to 10000000"),
    (("run", HELLO), "--seed", "-1", "input should be greater than or equal to 0"),
    (("tree", HELLO), "--at", "-3", "input should be greater than or equal to 0"),
    (("machine", HELLO), "--at", "-1", "input should be greater than or equal to 0"),
    (("gallery",), "--port", "70000", "input should be less than or equal to 65535"),
    (("gallery",), "--port", "-1", "input should be greater than or equal to 0"),
    (("gallery",), "--max-mb", "nan", "input should be a finite number"),
    (("gallery",), "--max-mb", "-1", "input should be greater than 0"),
    (("gallery",), "--max-mp", "inf", "input should be a finite number"),
    (("gallery",), "--max-mp", "0", "input should be greater than 0"),
    (("teleop",), "--rate", "nan", "input should be a finite number"),
    (("teleop",), "--rate", "0", "input should be greater than 0"),
    (("teleop",), "--rate", "1e9", "input should be less than or equal to 1000"),
    (("teleop",), "--linear-step", "-0.1", "input should be greater than 0"),
    (("teleop",), "--angular-step", "-inf", "input should be a finite number"),
    (("teleop",), "--seed", "-2", "input should be greater than or equal to 0"),
    (("emulate", "launchpad"), "--seed", "-1", "input should be greater than or equal to 0"),
    (("emulate", "launchpad"), "--counter-start", "4294967296", "input should be less than or equal to 2147483647"),
    (("chat",), "--seed", "-7", "input should be greater than or equal to 0"),
]


@pytest.mark.parametrize(("verb", "option", "value", "message"), NUMBERS, ids=lambda v: str(v))
def test_numbers_out_of_range_are_usage_errors(verb: tuple[str, ...], option: str, value: str, message: str) -> None:
    output = clean(botstage(*verb, f"{option}={value}"), 2)
    assert f"Invalid value for '{option}': {message}" in output


@pytest.mark.parametrize("start", ["nan,0,0", "0,inf,0", "1,2,-nan"])
def test_a_start_pose_must_be_finite(start: str) -> None:
    output = clean(botstage("teleop", "chefbot", "--start", start), 2)
    assert f"error: start {start!r}: x, y and theta should be finite numbers" in output


# -- paths ------------------------------------------------------------------------------------


@pytest.fixture
def afile(tmp_path: Path) -> Path:
    path = tmp_path / "afile"
    path.write_text("x")
    return path


def test_a_run_folder_that_cannot_be_one_is_refused_before_the_run(tmp_path: Path, afile: Path) -> None:
    for out, message in [
        (str(afile), "is a file, not a folder"),
        ("/dev/null", "is a special file (a device, a pipe or a socket), not a folder"),
        (str(afile / "sub"), "Not a directory"),
    ]:
        output = clean(botstage("run", HELLO, "-q", "--out", out), 2)
        assert "Invalid value for '--out': " in output and message in output
    # a folder the checks cannot foresee (the kernel's own files refuse it): said as an error, exit 1
    output = clean(botstage("run", HELLO, "-q", "--out", "/proc/botstage-nope"), 1)
    assert output.startswith("error: /proc/botstage-nope: ")


def test_paused_without_the_monitor_is_refused_before_the_run(tmp_path: Path) -> None:
    """--paused holds the run for the monitor's page: without --monitor nothing could resume it."""
    output = clean(botstage("run", HELLO, "--paused", "--out", str(tmp_path / "run")), 2)
    assert "error: --paused holds the run for the monitor: add --monitor" in output
    assert not (tmp_path / "run").exists()


def test_output_files_must_be_writable_files(tmp_path: Path, afile: Path) -> None:
    output = clean(botstage("tree", HELLO, "-o", str(tmp_path)), 2)
    assert "Invalid value for '-o' / '--output': " in output and "is a directory, not a file" in output
    output = clean(botstage("machine", HELLO, "-o", str(tmp_path / "no" / "such" / "m.txt")), 2)
    assert "no folder" in output
    normal = "missions/scenarios/hello/normal.yaml"
    output = clean(botstage("test", normal, "--coverage", "--coverage-file", str(tmp_path)), 2)
    assert output.startswith(f"error: --coverage-file: {str(tmp_path)!r} is a directory, not a file")
    trace = tmp_path / "trace.jsonl"
    trace.write_text("")
    output = clean(botstage("scenario", "from-trace", str(trace), "-o", str(afile / "s.yaml"), "--mission", HELLO), 2)
    assert "Invalid value for '-o' / '--output'" in output


@pytest.mark.parametrize(
    "args",
    [
        ("tree", HELLO, "--trace", "/dev/zero"),  # endless: it would never finish reading
        ("machine", HELLO, "--coverage", "/dev/zero"),
        ("tree", HELLO, "--trace", "{tmp}"),
        ("tree", HELLO, "--trace", "{tmp}/missing.jsonl"),
        ("scenario", "from-trace", "/dev/zero", "-o", "{tmp}/s.yaml"),
        ("scenario", "from-trace", "{tmp}/missing.jsonl", "-o", "{tmp}/s.yaml"),
        ("chat", "--aiml", "/dev/zero"),
        ("test", "/dev/null"),
    ],
    ids=lambda args: "-".join(args[:1] + args[-1:]),
)
def test_input_files_must_be_files_that_end(tmp_path: Path, args: tuple[str, ...]) -> None:
    output = clean(botstage(*(a.replace("{tmp}", str(tmp_path)) for a in args)), 2)
    assert "Invalid value for " in output
    assert any(reason in output for reason in ("not a file to read", "no such file"))


def test_speech_says_a_special_file_is_not_one_and_goes_on(tmp_path: Path) -> None:
    output = clean(botstage("speech", "recognize", "/dev/zero", str(tmp_path)), 1)
    assert "error: /dev/zero: not a file" in output and f"error: {tmp_path}: not a file" in output


def test_a_map_that_cannot_be_read_is_a_clear_error(tmp_path: Path) -> None:
    broken = tmp_path / "m.yaml"
    broken.write_text("image: nope.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    for verb in (("teleop", "chefbot"), ("emulate", "launchpad")):
        output = clean(botstage(*verb, "--world", str(broken)), 2)
        assert "error: " in output and "nope.pgm" in output


# -- exit status of a run -----------------------------------------------------------------------

FAILING = "name: f\ntrees:\n  main: {condition: 'false'}\n"
SUCCEEDING = "name: s\ntrees:\n  main: {condition: 'true'}\n"


@pytest.mark.parametrize(
    ("mission", "extra", "status", "outcome"),
    [
        (SUCCEEDING, (), 0, "success"),
        (None, (), 0, "done"),  # hello: a machine outcome that is its success
        (None, ("--until", "5"), 0, "time_limit"),
        (FAILING, (), 3, "failure"),
        ("estop", (), 3, "stopped"),  # hello with its e-stop on: a machine outcome that is not success
    ],
    ids=["success", "machine-success", "time-limit", "failure", "machine-failure"],
)
def test_run_exits_with_a_status_that_says_how_the_mission_ended(
    tmp_path: Path, mission: str | None, extra: tuple[str, ...], status: int, outcome: str
) -> None:
    path = Path(HELLO)
    if mission == "estop":
        path = tmp_path / "stop.yaml"
        path.write_text(Path(HELLO).read_text().replace("estop: false", "estop: true"))
    elif mission is not None:
        path = tmp_path / "m.yaml"
        path.write_text(mission)
    output = clean(botstage("run", str(path), "-q", "--out", str(tmp_path / "run"), *extra), status)
    assert f": outcome {outcome}" in output


def test_exit_statuses_are_distinct_for_each_ending() -> None:
    assert exit_status("time_limit", None) == 0 and exit_status("docked", True) == 0
    assert exit_status("failure", False) == exit_status("stranded", False) == 3
    assert exit_status("stopped_by_test", None) == 3  # ended early without success
    assert exit_status("error", None) == 4 and exit_status("interrupted", None) == 130


def test_an_interrupted_run_exits_130(tmp_path: Path) -> None:
    mission = tmp_path / "long.yaml"
    mission.write_text("name: long\ntrees:\n  main: {wait: {duration: 1000}}\n")
    out = tmp_path / "run"
    process = subprocess.Popen(
        [sys.executable, "-m", "botstage.missions.cli", "run", str(mission), "-q", "--realtime", "--out", str(out)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + FAILSAFE_S
        while not (out / "trace.jsonl").exists() and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)  # waiting for the run to start, not timing it
        process.send_signal(signal.SIGTERM)
        stdout, stderr = process.communicate(timeout=FAILSAFE_S)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, stderr
    assert "outcome interrupted" in stdout and "Traceback" not in stderr


# -- the emulator's fault console ------------------------------------------------------------------


@pytest.fixture
def emulator() -> LaunchpadEmulator:
    profile, grid, pose = robot_place("chefbot", "restaurant", "10,7,0")
    board = LaunchpadEmulator(World(grid, profile, pose, 0))
    yield board
    board.close()


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        ("garbage 999999999999", "999999999999 is out of range (usage: garbage N: N random bytes, 1 to 1,048,576)"),
        ("garbage -5", "-5 is out of range"),
        ("garbage 0", "0 is out of range"),
        ("garbage lots", "'lots' is not a whole number"),
        ("garbage", "wrong number of arguments"),
        ("drop 1e3", "'1e3' is not a whole number"),
        ("drop 99999999999", "out of range"),
        ("stall up", "no wheel 'up' (usage: stall left|right|none)"),
        ("unplug -5", "-5 is out of range (usage: unplug SECONDS: more than 0, at most 3600)"),
        ("unplug 0", "0 is out of range"),
        ("unplug nan", "nan is out of range"),
        ("unplug inf", "inf is out of range"),
        ("unplug 1e400", "1e400 is out of range"),
        ("reset now", "wrong number of arguments"),
    ],
)
def test_a_bad_fault_line_is_answered_and_changes_nothing(emulator: LaunchpadEmulator, line: str, reason: str) -> None:
    reply = apply_fault(emulator, line)
    assert reply == f"cannot read {line!r}: {reason}" or (reply is not None and reason in reply)
    assert emulator._garbage == b"" and emulator._drop == 0 and emulator.stalled == set()
    assert emulator.counters["unplugs"] == 0


def test_the_console_goes_on_after_bad_lines(emulator: LaunchpadEmulator) -> None:
    assert apply_fault(emulator, "frobnicate 3").startswith("unknown fault 'frobnicate'; faults: garbage N")
    assert apply_fault(emulator, "garbage 999999999999") is not None
    assert apply_fault(emulator, "garbage 10") is None and len(emulator._garbage) == 10
    assert apply_fault(emulator, f"garbage {MAX_GARBAGE}").startswith("cannot do 'garbage 1048576': ")
    assert apply_fault(emulator, "drop 3") is None and emulator._drop == 3
    assert apply_fault(emulator, "stall left") is None and emulator.stalled == {"left"}
    assert apply_fault(emulator, "  ") is None
    assert apply_fault(emulator, "status").startswith("pose 10.000 7.000")


def test_the_emulator_itself_refuses_unbounded_faults(emulator: LaunchpadEmulator) -> None:
    for fault, value in [
        (emulator.inject_garbage, MAX_GARBAGE + 1),
        (emulator.inject_garbage, -1),
        (emulator.drop_lines, -1),
        (emulator.disconnect, -5.0),
        (emulator.disconnect, float("nan")),
        (emulator.stall, "middle"),
    ]:
        with pytest.raises(ValueError):
            fault(value)


EMULATE = [sys.executable, "-m", "botstage.missions.cli", "emulate", "launchpad", "--start", "10,7,0"]


def emulator_console(command: list[str]) -> subprocess.Popen[str]:
    """``botstage emulate`` started by ``command``, its console on pipes."""
    process = subprocess.Popen(
        command,
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "COLUMNS": "300"},
    )
    assert process.stdin is not None and process.stdout is not None
    return process


def test_ctrl_c_stops_botstage_started_with_sigint_ignored() -> None:
    """A script's background job starts with SIGINT ignored (no job control): botstage takes it back."""
    process = emulator_console(["bash", "-c", f"trap '' INT; exec {shlex.join(EMULATE)}"])
    assert process.stdin is not None and process.stdout is not None
    try:
        process.stdin.write("status\n")  # its answer says the console, and so the emulator, runs
        process.stdin.flush()
        while not (line := process.stdout.readline()).startswith("pose ") and line:
            pass
        assert line.startswith("pose "), process.stderr.read()  # type: ignore[union-attr]
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=FAILSAFE_S) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_botstage_emulate_answers_every_line_of_its_console() -> None:
    process = emulator_console(EMULATE)
    assert process.stdin is not None and process.stdout is not None
    received = ""
    try:
        process.stdin.write("garbage 999999999999\nunplug -5\nstatus\n")
        process.stdin.flush()
        deadline = time.monotonic() + FAILSAFE_S  # a failsafe, never a measurement
        fd = process.stdout.fileno()
        while "\npose " not in received and time.monotonic() < deadline:
            ready, _, _ = select.select([fd], [], [], 1.0)
            if ready:
                chunk = os.read(fd, 65536)  # raw reads: a text wrapper's buffer would hide lines from select
                if not chunk:
                    break
                received += chunk.decode(errors="replace")
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=FAILSAFE_S)
    finally:
        if process.poll() is None:
            process.kill()
    seen = received.splitlines()
    text = "".join(seen)
    assert "cannot read 'garbage 999999999999'" in text and "cannot read 'unplug -5'" in text
    assert any(line.startswith("pose ") for line in seen), text  # the console outlived both
    assert "Traceback" not in stderr and "Unable to allocate" not in stderr


# -- scenario run folders --------------------------------------------------------------------------


def test_scenarios_that_never_ran_leave_no_folder(tmp_path: Path) -> None:
    temp = tmp_path / "tmp"
    temp.mkdir()
    suite = tmp_path / "scenarios"
    suite.mkdir()
    (suite / "bad_key.yaml").write_text(f"mission: {HELLO}\nbogus: 1\n")
    (suite / "no_mission.yaml").write_text("mission: nope.yaml\n")
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: broken\ntrees:\n  main: {wiat: {duration: 1}}\n")
    (suite / "invalid_mission.yaml").write_text(f"mission: {broken}\n")
    output = clean(botstage("test", str(suite), env={"TMPDIR": str(temp)}), 1)
    assert "0 passed, 3 failed" in output
    assert list(temp.iterdir()) == []


def test_a_folder_is_made_only_for_a_scenario_that_can_run(tmp_path: Path) -> None:
    made: list[Path] = []

    def folder(scenario) -> Path:
        path = tmp_path / f"run-{len(made)}"
        path.mkdir()
        made.append(path)
        return path

    bad = tmp_path / "bad.yaml"
    bad.write_text(f"mission: {HELLO}\nexpect: {{outcome: 3}}\nbogus: true\n")
    assert not run_in_folder(load_scenario(bad), folder).passed and made == []
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(f"mission: {HELLO}\nexpect: {{outcome: stopped}}\n")
    result = run_in_folder(load_scenario(wrong), folder)
    assert not result.passed and result.folder == made[0] and made[0].is_dir()  # kept for a look
    right = tmp_path / "right.yaml"
    right.write_text(f"mission: {HELLO}\nexpect: {{outcome: done}}\n")
    assert run_in_folder(load_scenario(right), folder).passed and not made[1].exists()


# -- include folders -------------------------------------------------------------------------------


def test_include_dir_widens_where_includes_may_come_from_for_every_verb(tmp_path: Path) -> None:
    library, missions = tmp_path / "library", tmp_path / "missions"
    library.mkdir()
    missions.mkdir()
    (library / "greet.yaml").write_text("trees:\n  greet: {log: {message: hello}}\n")
    mission = missions / "m.yaml"
    mission.write_text("name: m\ninclude: [../library/greet.yaml]\ntrees:\n  main: {subtree: greet}\n")
    refused = botstage("validate", str(mission))
    assert refused.returncode == 1
    assert f"{mission}:2:" in refused.stderr and "outside the folders a mission may include from" in refused.stderr
    allowed = botstage("--include-dir", str(library), "validate", str(mission))
    assert allowed.returncode == 0, allowed.stderr
    by_env = botstage(
        "run", str(mission), "-q", "--out", str(tmp_path / "run"), env={"BOTSTAGE_INCLUDE_PATH": str(library)}
    )
    assert by_env.returncode == 0, by_env.stderr
    by_name = missions / "by_name.yaml"  # a name not beside the mission is looked up in the include folders
    by_name.write_text("name: by_name\ninclude: [greet.yaml]\ntrees:\n  main: {subtree: greet}\n")
    assert botstage("--include-dir", str(library), "validate", str(by_name)).returncode == 0
    missing = botstage("--include-dir", str(tmp_path / "nowhere"), "validate", str(mission))
    assert missing.returncode == 2 and "'--include-dir'" in missing.stderr and "is not a folder" in missing.stderr
