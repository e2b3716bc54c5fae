"""`pip install botstage` with no extras, in a fresh virtualenv: the core checks and runs `hello`
and imports none of the plug-in sets' packages; a mission that needs a set that is not installed is
told, where it uses it, which extra to install."""

from __future__ import annotations

import shutil
import subprocess
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# the plug-in sets' packages (import names); none may be installed, let alone imported, by the core
SET_PACKAGES = ["zenoh", "onnxruntime", "zmq", "fastapi", "dynamixel_sdk", "serial", "pocketsphinx", "aiml"]

LISTENING = """\
name: listening
robot: peoplebot
world: museum
until: 5
machine:
  outcomes: [done]
  states:
    hearing: {skill: listen, transitions: {success: done, failure: done, timeout: done}}
"""

RUN_IN_PROCESS = f"""
import sys
from botstage.missions.check import check
from botstage.missions.runner import run
checked = check({str(ROOT / "missions" / "examples" / "hello.yaml")!r})
assert checked.ok, checked.problems
result = run({str(ROOT / "missions" / "examples" / "hello.yaml")!r}, out=__import__("pathlib").Path(sys.argv[1]))
print("outcome", result.outcome)
print("imported", sorted(m for m in {SET_PACKAGES!r} if m in sys.modules))
"""


@pytest.fixture(scope="module")
def core(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A virtualenv with botstage installed from this checkout as a wheel, without extras."""
    base = tmp_path_factory.mktemp("core")
    source = base / "botstage"  # a copy: pip builds in the source tree, and the checkout stays clean
    source.mkdir()
    for part in ("pyproject.toml", "README.md", "behaviors", "skills", "robots", "missions"):
        if (ROOT / part).is_dir():
            shutil.copytree(ROOT / part, source / part, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(ROOT / part, source / part)
    folder = base / "venv"
    venv.create(folder, with_pip=True)
    python = folder / "bin" / "python"
    install = subprocess.run(
        [str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", str(source)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert install.returncode == 0, install.stdout + install.stderr
    return folder


def test_no_plugin_set_package_is_installed(core: Path) -> None:
    found = subprocess.run(
        [
            str(core / "bin" / "python"),
            "-c",
            f"import importlib.util as u; print([m for m in {SET_PACKAGES!r} if u.find_spec(m)])",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    assert found.stdout.strip() == "[]"


def test_validate_and_run_hello(core: Path, tmp_path: Path) -> None:
    botstage = str(core / "bin" / "botstage")
    hello = str(ROOT / "missions" / "examples" / "hello.yaml")
    checked = subprocess.run([botstage, "validate", hello], capture_output=True, text=True, timeout=120)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    ran = subprocess.run(
        [botstage, "run", hello, "-q", "--out", str(tmp_path / "run")], capture_output=True, text=True, timeout=300
    )
    assert ran.returncode == 0, ran.stdout + ran.stderr
    assert "outcome done" in ran.stdout
    assert (tmp_path / "run" / "trace.jsonl").stat().st_size > 0


def test_checking_and_running_import_no_plugin_set(core: Path, tmp_path: Path) -> None:
    done = subprocess.run(
        [str(core / "bin" / "python"), "-c", RUN_IN_PROCESS, str(tmp_path / "run")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "outcome done" in done.stdout
    assert "imported []" in done.stdout


def test_a_mission_that_needs_a_missing_set_is_told_which_extra(core: Path, tmp_path: Path) -> None:
    mission = tmp_path / "listening.yaml"
    mission.write_text(LISTENING, encoding="utf-8")
    checked = subprocess.run(
        [str(core / "bin" / "botstage"), "validate", str(mission)], capture_output=True, text=True, timeout=120
    )
    assert checked.returncode == 1
    assert f"{mission}:8:15: error: skill 'listen' is in botstage's speech set" in checked.stderr, checked.stderr
    assert "pip install 'botstage[speech]'" in checked.stderr
    assert "ros2" not in checked.stderr  # the profile's ros2: section is the ros2 backend's, not installed here
